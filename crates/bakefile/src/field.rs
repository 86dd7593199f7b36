//! The values of a sampled reflectance field (section `RFLD`, SPEC.md §3.14), held in the
//! precision of its file.
//!
//! A fully covered 320 × 240 image at 64 × 32 directions holds 472 M values: 0.94 GB as f16,
//! 1.9 GB as f32. [`FieldValues`] keeps them as the file stores them — little-endian f32 or
//! f16 bytes — so that [`crate::read_bake`] can hand the file's own buffer over to the field
//! (no decoded copy), [`crate::write_bake`] can write them straight out, and a sampler can
//! append each batch of functions already converted. Readers decode one function at a time
//! ([`FieldValues::slice`], [`FieldValues::read_into`]); f32 values that are aligned in memory
//! (the usual case) are lent without decoding.
//!
//! Why bytes and not `Vec<f16>` / `Vec<f32>`: a `Vec<u8>` read from a file cannot become a
//! `Vec<f16>` or `Vec<f32>` without a copy (a vector must be freed with the alignment it was
//! allocated with), so only a byte buffer can be both the file's buffer and the field's.

use std::fmt;
use std::ops::Range;

use half::f16;
use half::slice::HalfFloatSliceExt;

use crate::error::BakeFileError;
use crate::scalar::ScalarType;

/// Values converted per step when converting between precisions.
pub(crate) const CHUNK: usize = 1 << 14;

/// The values of a reflectance field in the precision of its file (little-endian f32 or f16
/// bytes; see the module documentation for why bytes).
///
/// Equality compares the values as f32 (as `Vec<f32>` does), whatever the storage: an f16
/// field equals an f32 field holding the same (f16-representable) numbers.
#[derive(Clone)]
pub struct FieldValues {
    scalar: ScalarType,
    bytes: Vec<u8>,
}

impl FieldValues {
    /// No values, stored as `scalar`.
    #[must_use]
    pub fn new(scalar: ScalarType) -> Self {
        Self {
            scalar,
            bytes: Vec::new(),
        }
    }

    /// No values, stored as `scalar`, with room for `values` of them.
    #[must_use]
    pub fn with_capacity(scalar: ScalarType, values: usize) -> Self {
        Self {
            scalar,
            bytes: Vec::with_capacity(values.saturating_mul(scalar.size())),
        }
    }

    /// f32 values, stored as f32 (exactly; the values are copied).
    #[must_use]
    pub fn from_f32(values: &[f32]) -> Self {
        let mut v = Self::with_capacity(ScalarType::F32, values.len());
        extend_f32_le(&mut v.bytes, values);
        v
    }

    /// f16 values, stored as f16 (the values are copied).
    #[must_use]
    pub fn from_f16(values: &[f16]) -> Self {
        let mut v = Self::with_capacity(ScalarType::F16, values.len());
        extend_f16_le(&mut v.bytes, values);
        v
    }

    /// f32 values stored as `scalar` (rounded to nearest when f16).
    ///
    /// # Errors
    /// [`BakeFileError::OutOfF16Range`] when `scalar` is f16 and a value rounds beyond ±65504.
    pub fn from_f32_as(values: &[f32], scalar: ScalarType) -> Result<Self, BakeFileError> {
        let mut v = Self::with_capacity(scalar, values.len());
        v.push_f32(values)?;
        Ok(v)
    }

    /// Takes `bytes` (little-endian values of `scalar`, a whole number of them) as they are.
    pub(crate) fn from_le_bytes(scalar: ScalarType, bytes: Vec<u8>) -> Self {
        debug_assert_eq!(bytes.len() % scalar.size(), 0);
        Self { scalar, bytes }
    }

    /// How the values are stored.
    #[must_use]
    pub fn scalar(&self) -> ScalarType {
        self.scalar
    }

    /// Number of values.
    #[must_use]
    pub fn len(&self) -> usize {
        self.bytes.len() / self.scalar.size()
    }

    /// True when there are no values.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.bytes.is_empty()
    }

    /// The values as the file stores them: little-endian f32 or f16.
    #[must_use]
    pub fn as_le_bytes(&self) -> &[u8] {
        &self.bytes
    }

    /// Appends `values`, converted to the storage precision (f16: rounded to nearest, even).
    ///
    /// # Errors
    /// [`BakeFileError::OutOfF16Range`] (section `RFLD`, the index among all the field's
    /// values) when stored as f16 and a value rounds beyond ±65504; nothing is appended then.
    pub fn push_f32(&mut self, values: &[f32]) -> Result<(), BakeFileError> {
        match self.scalar {
            ScalarType::F32 => {
                extend_f32_le(&mut self.bytes, values);
                Ok(())
            }
            ScalarType::F16 => {
                let (base, start) = (self.len(), self.bytes.len());
                let r = f32_to_f16_le(&mut self.bytes, values, base, || "RFLD".into());
                if r.is_err() {
                    self.bytes.truncate(start);
                }
                r
            }
        }
    }

    /// Value `i` widened to f32 (exact), `None` beyond the end.
    #[must_use]
    pub fn get(&self, i: usize) -> Option<f32> {
        let s = self.scalar.size();
        let b = self.bytes.get(i.checked_mul(s)?..(i + 1).checked_mul(s)?)?;
        Some(match self.scalar {
            ScalarType::F32 => f32::from_le_bytes([b[0], b[1], b[2], b[3]]),
            ScalarType::F16 => f16::from_le_bytes([b[0], b[1]]).to_f32(),
        })
    }

    /// Values `start .. start + out.len()` widened to f32 (exact) into `out`.
    ///
    /// # Panics
    /// When the range goes beyond the values.
    pub fn read_into(&self, start: usize, out: &mut [f32]) {
        let s = self.scalar.size();
        let raw = &self.bytes[start * s..(start + out.len()) * s];
        le_to_f32(self.scalar, raw, out);
    }

    /// Values `range` as f32: lent in place when stored as f32 and aligned in memory (on a
    /// little-endian host), otherwise decoded into `scratch` (resized as needed).
    ///
    /// # Panics
    /// When the range goes beyond the values.
    #[must_use]
    pub fn slice<'a>(&'a self, range: Range<usize>, scratch: &'a mut Vec<f32>) -> &'a [f32] {
        let s = self.scalar.size();
        let raw = &self.bytes[range.start * s..range.end * s];
        if self.scalar == ScalarType::F32 && cfg!(target_endian = "little") {
            if let Ok(v) = bytemuck::try_cast_slice::<u8, f32>(raw) {
                return v;
            }
        }
        scratch.resize(range.len(), 0.0);
        le_to_f32(self.scalar, raw, scratch);
        scratch
    }

    /// All values widened to f32 (a copy of the whole field: for tests and small fields).
    #[must_use]
    pub fn to_f32_vec(&self) -> Vec<f32> {
        let mut out = vec![0.0; self.len()];
        self.read_into(0, &mut out);
        out
    }
}

impl PartialEq for FieldValues {
    fn eq(&self, other: &Self) -> bool {
        if self.len() != other.len() {
            return false;
        }
        if self.scalar == other.scalar && self.bytes == other.bytes {
            return true;
        }
        let (mut a, mut b) = (vec![0.0f32; CHUNK], vec![0.0f32; CHUNK]);
        let mut start = 0;
        while start < self.len() {
            let n = CHUNK.min(self.len() - start);
            self.read_into(start, &mut a[..n]);
            other.read_into(start, &mut b[..n]);
            if a[..n] != b[..n] {
                return false;
            }
            start += n;
        }
        true
    }
}

impl fmt::Debug for FieldValues {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        struct Values<'a>(&'a FieldValues);
        impl fmt::Debug for Values<'_> {
            fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
                f.debug_list()
                    .entries((0..self.0.len()).filter_map(|i| self.0.get(i)))
                    .finish()
            }
        }
        f.debug_struct("FieldValues")
            .field("scalar", &self.scalar)
            .field("values", &Values(self))
            .finish()
    }
}

/// Decodes little-endian `scalar` values `raw` into `out` (`out.len()` of them).
fn le_to_f32(scalar: ScalarType, raw: &[u8], out: &mut [f32]) {
    debug_assert_eq!(raw.len(), out.len() * scalar.size());
    match scalar {
        ScalarType::F32 => {
            for (o, c) in out.iter_mut().zip(raw.chunks_exact(4)) {
                *o = f32::from_le_bytes([c[0], c[1], c[2], c[3]]);
            }
        }
        ScalarType::F16 => {
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx")
                && std::arch::is_x86_feature_detected!("f16c")
            {
                // SAFETY: the CPU has AVX and F16C (checked just above).
                #[allow(unsafe_code)]
                unsafe {
                    f16_to_f32_f16c(raw, out);
                }
                return;
            }
            for (o, c) in out.iter_mut().zip(raw.chunks_exact(2)) {
                *o = f16::from_le_bytes([c[0], c[1]]).to_f32();
            }
        }
    }
}

/// Little-endian f16 `raw` to f32 `out`, eight at a time with F16C's `vcvtph2ps` (exact, as
/// the software conversion). Relighting decodes every function of an f16 field per frame;
/// with `half`'s slice conversion `prt relight`'s linear shading of a 0.94 GB field took a
/// median 288 ms, with this 262 ms (f32 values in place: 215 ms).
///
/// # Safety
/// The CPU must support AVX and F16C; `raw.len() == 2 * out.len()`.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx,f16c")]
#[allow(unsafe_code)] // Runtime feature dispatch, as prt-relight's AVX2 kernels.
unsafe fn f16_to_f32_f16c(raw: &[u8], out: &mut [f32]) {
    use std::arch::x86_64::{__m128i, _mm256_cvtph_ps, _mm256_storeu_ps, _mm_loadu_si128};
    assert_eq!(raw.len(), 2 * out.len());
    let n = out.len() / 8 * 8;
    for i in (0..n).step_by(8) {
        // SAFETY: i + 8 ≤ out.len(), so bytes [2i, 2i + 16) of `raw` and floats [i, i + 8) of
        // `out` are in bounds; both intrinsics take unaligned addresses.
        unsafe {
            let h = _mm_loadu_si128(raw.as_ptr().add(2 * i).cast::<__m128i>());
            _mm256_storeu_ps(out.as_mut_ptr().add(i), _mm256_cvtph_ps(h));
        }
    }
    for (o, c) in out[n..].iter_mut().zip(raw[2 * n..].chunks_exact(2)) {
        *o = f16::from_le_bytes([c[0], c[1]]).to_f32();
    }
}

pub(crate) fn extend_f32_le(bytes: &mut Vec<u8>, values: &[f32]) {
    if cfg!(target_endian = "little") {
        bytes.extend_from_slice(bytemuck::cast_slice(values));
    } else {
        bytes.reserve(4 * values.len());
        values
            .iter()
            .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    }
}

fn extend_f16_le(bytes: &mut Vec<u8>, values: &[f16]) {
    if cfg!(target_endian = "little") {
        bytes.extend_from_slice(bytemuck::cast_slice(values));
    } else {
        bytes.reserve(2 * values.len());
        values
            .iter()
            .for_each(|v| bytes.extend_from_slice(&v.to_le_bytes()));
    }
}

/// Appends `values` rounded to f16 (nearest, ties to even, as `f16::from_f32`) to `bytes`,
/// little-endian. A value that becomes infinite is refused as
/// [`BakeFileError::OutOfF16Range`] in `section()` at index `base + i`; `bytes` may then hold
/// part of the values.
pub(crate) fn f32_to_f16_le(
    bytes: &mut Vec<u8>,
    values: &[f32],
    base: usize,
    section: impl Fn() -> String,
) -> Result<(), BakeFileError> {
    bytes.reserve(2 * values.len());
    let mut h = vec![f16::ZERO; CHUNK.min(values.len())];
    for (ci, src) in values.chunks(CHUNK).enumerate() {
        let h = &mut h[..src.len()];
        h.convert_from_f32_slice(src);
        if let Some(i) = h.iter().position(|v| v.is_infinite()) {
            return Err(BakeFileError::OutOfF16Range {
                section: section(),
                index: (base + ci * CHUNK + i) as u64,
                value: src[i],
            });
        }
        extend_f16_le(bytes, h);
    }
    Ok(())
}

/// What a reflectance value must be (SPEC.md §3.14): finite and not negative (`-0` is zero).
#[derive(Clone, Copy)]
pub(crate) enum Rule {
    /// Not NaN nor infinite.
    Finite,
    /// Sign bit clear, or the value is zero.
    NonNegative,
    /// Both.
    Valid,
}

/// The first of the little-endian `scalar` values `raw` that breaks `rule`, judged on the
/// bits (no f32 copy of f16 values).
pub(crate) fn first_breaking(scalar: ScalarType, raw: &[u8], rule: Rule) -> Option<usize> {
    // Exponent all ones: infinite or NaN. Sign set on a non-zero magnitude: negative (a NaN
    // with its sign set counts as both).
    let (finite_f32, sign_f32) = (
        |b: u32| b & 0x7f80_0000 != 0x7f80_0000,
        |b: u32| b & 0x8000_0000 == 0 || b & 0x7fff_ffff == 0,
    );
    let (finite_f16, sign_f16) = (
        |b: u16| b & 0x7c00 != 0x7c00,
        |b: u16| b & 0x8000 == 0 || b & 0x7fff == 0,
    );
    match scalar {
        ScalarType::F32 => {
            let mut bits = raw
                .chunks_exact(4)
                .map(|c| u32::from_le_bytes([c[0], c[1], c[2], c[3]]));
            match rule {
                Rule::Finite => bits.position(|b| !finite_f32(b)),
                Rule::NonNegative => bits.position(|b| !sign_f32(b)),
                Rule::Valid => bits.position(|b| !(finite_f32(b) && sign_f32(b))),
            }
        }
        ScalarType::F16 => {
            let mut bits = raw
                .chunks_exact(2)
                .map(|c| u16::from_le_bytes([c[0], c[1]]));
            match rule {
                Rule::Finite => bits.position(|b| !finite_f16(b)),
                Rule::NonNegative => bits.position(|b| !sign_f16(b)),
                Rule::Valid => bits.position(|b| !(finite_f16(b) && sign_f16(b))),
            }
        }
    }
}

impl FieldValues {
    /// [`first_breaking`] over the values.
    pub(crate) fn first_breaking(&self, rule: Rule) -> Option<usize> {
        first_breaking(self.scalar, &self.bytes, rule)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The slice conversion (F16C where present) rounds exactly as `f16::from_f32`, the
    /// encoder's scalar conversion before, on edge values and a sweep of bit patterns.
    #[test]
    fn slice_rounding_equals_scalar_rounding() {
        let mut v: Vec<f32> = vec![
            0.0, -0.0, 1.0, 65504.0, 65519.99, 65520.0, 6.1e-5, 5.96e-8, 2.98e-8, 1e-10,
        ];
        let mut x = 0x3000_0000u32;
        while x < 0x4780_0000 {
            v.push(f32::from_bits(x));
            x += 0x0000_1235;
        }
        let mut bytes = Vec::new();
        let r = f32_to_f16_le(&mut bytes, &v, 0, String::new);
        let Err(BakeFileError::OutOfF16Range { index, .. }) = r else {
            panic!("65520 rounds to infinity: {r:?}");
        };
        assert_eq!(index, 5);
        let ok: Vec<f32> = v.iter().copied().filter(|x| x.abs() < 65520.0).collect();
        let mut bytes = Vec::new();
        f32_to_f16_le(&mut bytes, &ok, 0, String::new).unwrap();
        for (i, &x) in ok.iter().enumerate() {
            let want = f16::from_f32(x).to_le_bytes();
            assert_eq!(bytes[2 * i..2 * i + 2], want, "{x:e}");
        }
    }

    /// Decoding (F16C where the CPU has it) is exact: every f16 bit pattern, at every
    /// offset of an 8-lane step, equals `f16::to_f32`.
    #[test]
    fn f16_decoding_is_exact_for_every_bit_pattern() {
        let raw: Vec<u8> = (0..=u16::MAX).flat_map(u16::to_le_bytes).collect();
        for skip in [0usize, 1, 3] {
            let raw = &raw[2 * skip..];
            let mut out = vec![0.0f32; raw.len() / 2];
            le_to_f32(ScalarType::F16, raw, &mut out);
            for (k, &v) in out.iter().enumerate() {
                let want = f16::from_bits((k + skip) as u16).to_f32();
                assert!(
                    v.to_bits() == want.to_bits() || (v.is_nan() && want.is_nan()),
                    "{:#06x}: {v} vs {want}",
                    k + skip
                );
            }
        }
    }

    #[test]
    fn rules_judge_bits() {
        let f16s = |v: &[u16]| v.iter().flat_map(|b| b.to_le_bytes()).collect::<Vec<u8>>();
        let raw = f16s(&[0x3c00, 0x8000, 0x0001, 0x8001, 0x7c00, 0x7e00, 0xfc00]);
        let s = ScalarType::F16;
        assert_eq!(first_breaking(s, &raw, Rule::Finite), Some(4));
        assert_eq!(first_breaking(s, &raw, Rule::NonNegative), Some(3));
        assert_eq!(first_breaking(s, &raw, Rule::Valid), Some(3));
        assert_eq!(first_breaking(s, &raw[..6], Rule::Valid), None);
        let raw: Vec<u8> = [1.0f32, -0.0, 1e-45, f32::INFINITY, -1e-45, f32::NAN]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect();
        let s = ScalarType::F32;
        assert_eq!(first_breaking(s, &raw, Rule::Finite), Some(3));
        assert_eq!(first_breaking(s, &raw, Rule::NonNegative), Some(4));
        assert_eq!(first_breaking(s, &raw, Rule::Valid), Some(3));
    }
}
