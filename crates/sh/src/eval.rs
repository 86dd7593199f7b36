//! Evaluation of all real SH basis functions of an order at a direction.

use crate::index::{check_len, check_order, coefficient_count, index, ShError, MAX_ORDER};
use crate::legendre::LegendreTable;
use glam::{DVec3, Vec3};

/// Evaluates all `order²` basis functions at directions, without allocating per call.
///
/// The direction need not be normalised (it is, in f64). Build once per order and reuse:
/// ```
/// use prt_sh::Basis;
/// let basis = Basis::new(3).unwrap();
/// let mut y = vec![0.0; 9];
/// basis.eval_into(glam::DVec3::Z, &mut y).unwrap();
/// assert!((y[2] - (3.0 / (4.0 * std::f64::consts::PI)).sqrt()).abs() < 1e-15);
/// ```
#[derive(Clone, Debug)]
pub struct Basis {
    order: usize,
    table: LegendreTable,
}

impl Basis {
    /// Prepares evaluation for `order` bands (1 ≤ order ≤ [`MAX_ORDER`]).
    pub fn new(order: usize) -> Result<Self, ShError> {
        check_order(order, MAX_ORDER)?;
        Ok(Self {
            order,
            table: LegendreTable::new(order),
        })
    }

    /// The order (band count).
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Number of coefficients, `order²`.
    #[must_use]
    pub fn len(&self) -> usize {
        coefficient_count(self.order)
    }

    /// Always false (an order is at least 1).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// Fills `out` (length `order²`) with `y_i(dir)` in f64.
    pub fn eval_into(&self, dir: DVec3, out: &mut [f64]) -> Result<(), ShError> {
        check_len(self.order, out.len())?;
        self.eval_unchecked(dir, out);
        Ok(())
    }

    /// Fills `out` with `y_i(dir)`; `out.len()` must be `order²` (checked in debug builds).
    pub fn eval_unchecked(&self, dir: DVec3, out: &mut [f64]) {
        debug_assert_eq!(out.len(), self.len());
        self.eval_with(dir, |i, v| out[i] = v);
    }

    /// The one evaluation loop, in f64 whatever the output type: for each `m` the azimuthal
    /// factor `(x + iy)^m = sin^m θ e^{imφ}` is advanced once, then the Legendre column
    /// `Q_l^m`, `l = m..order`, runs and each value is written with its cos and sin factor.
    #[inline]
    fn eval_with(&self, dir: DVec3, mut write: impl FnMut(usize, f64)) {
        let d = dir.normalize_or(DVec3::Z);
        let t = &self.table;
        let n = self.order;
        let (mut c, mut s) = (1.0f64, 0.0f64);
        for m in 0..n {
            if m > 0 {
                let c_next = d.x * c - d.y * s;
                s = d.x * s + d.y * c;
                c = c_next;
            }
            let mi = m as i64;
            let mut emit = |l: usize, q: f64| {
                if m == 0 {
                    write(index(l, 0), q);
                } else {
                    write(index(l, mi), q * c);
                    write(index(l, -mi), q * s);
                }
            };
            let mut q2 = t.diag(m);
            emit(m, q2);
            if m + 1 >= n {
                continue;
            }
            let mut q1 = ((2 * m + 3) as f64).sqrt() * d.z * q2;
            emit(m + 1, q1);
            for l in (m + 2)..n {
                let (a, b) = t.ab(l, m);
                let v = a * (d.z * q1 - b * q2);
                emit(l, v);
                q2 = q1;
                q1 = v;
            }
        }
    }

    /// Returns a new vector of `y_i(dir)`.
    #[must_use]
    pub fn eval(&self, dir: DVec3) -> Vec<f64> {
        let mut out = vec![0.0; self.len()];
        self.eval_unchecked(dir, &mut out);
        out
    }

    /// Single-precision evaluation into an f32 buffer, for hot loops (bakes, relighting).
    /// Max error against f64 is below 2e-5 up to order 30 (tested).
    pub fn eval_f32_into(&self, dir: Vec3, out: &mut [f32]) -> Result<(), ShError> {
        check_len(self.order, out.len())?;
        self.eval_f32_unchecked(dir, out);
        Ok(())
    }

    /// Single-precision output; the recurrences run in f64 (they cost the same as in f32 on
    /// scalar code, and f32 recurrences lose about 1e-4 by order 30).
    pub fn eval_f32_unchecked(&self, dir: Vec3, out: &mut [f32]) {
        debug_assert_eq!(out.len(), self.len());
        self.eval_with(dir.as_dvec3(), |i, v| out[i] = v as f32);
    }

    /// Evaluates at many directions: `out` holds `dirs.len()` consecutive blocks of `order²`.
    pub fn eval_batch(&self, dirs: &[DVec3], out: &mut [f64]) -> Result<(), ShError> {
        let n2 = self.len();
        if out.len() != dirs.len() * n2 {
            return Err(ShError::BufferLength {
                order: self.order,
                expected: dirs.len() * n2,
                got: out.len(),
            });
        }
        for (d, block) in dirs.iter().zip(out.chunks_exact_mut(n2)) {
            self.eval_unchecked(*d, block);
        }
        Ok(())
    }

    /// Access to the Legendre table (θ-part), for projection code.
    pub(crate) fn legendre(&self) -> &LegendreTable {
        &self.table
    }
}

/// Highest order a [`BandCursor`] evaluates (its state lives in fixed-size arrays).
pub const BAND_CURSOR_MAX_ORDER: usize = 32;

/// Band-by-band evaluation at one direction: each call of [`BandCursor::next_band_f32`] gives
/// the next band's `2l + 1` values, so a caller that needs only the first bands of a point
/// (the adaptive relighting, which stops each point at its own level) pays only for those.
///
/// At band `l` every column `m < l − 1` takes its recurrence step `Q_l^m = a (z Q_{l−1}^m −
/// b Q_{l−2}^m)`, then `Q_l^{l−1} = sqrt(2l+1) z Q_{l−1}^{l−1}` and the seed `Q_l^l`: the same
/// arithmetic per value as [`Basis::eval_into`] (which runs column by column), so the values
/// are identical to the last bit (tested).
#[derive(Clone, Debug)]
pub struct BandCursor<'a> {
    basis: &'a Basis,
    x: f64,
    y: f64,
    z: f64,
    /// `sin^m θ cos mφ`, `sin^m θ sin mφ` for `m` below the next band (advanced one `m` per
    /// band, as `Basis::eval_with` advances them one per column).
    cm: [f64; BAND_CURSOR_MAX_ORDER],
    sm: [f64; BAND_CURSOR_MAX_ORDER],
    /// Legendre columns of the last two bands: `qs[l % 2][m] = Q_l^m` (band `l` overwrites
    /// band `l − 2`'s values in place, reading each before writing it).
    qs: [[f64; BAND_CURSOR_MAX_ORDER]; 2],
    next: usize,
}

impl<'a> BandCursor<'a> {
    /// A cursor at band 0 of `basis` (order ≤ [`BAND_CURSOR_MAX_ORDER`]) at `dir` (need not be
    /// normalised).
    #[inline]
    pub fn new(basis: &'a Basis, dir: Vec3) -> Result<Self, ShError> {
        check_order(basis.order, BAND_CURSOR_MAX_ORDER)?;
        let d = dir.as_dvec3().normalize_or(DVec3::Z);
        let mut cm = [0.0; BAND_CURSOR_MAX_ORDER];
        cm[0] = 1.0;
        Ok(Self {
            basis,
            x: d.x,
            y: d.y,
            z: d.z,
            cm,
            sm: [0.0; BAND_CURSOR_MAX_ORDER],
            qs: [[0.0; BAND_CURSOR_MAX_ORDER]; 2],
            next: 0,
        })
    }

    /// Restarts the cursor at band 0 for direction `dir`, reusing its state arrays (no
    /// re-initialisation: each band reads only values written by the bands before it).
    #[inline]
    pub fn reset(&mut self, dir: Vec3) {
        let d = dir.as_dvec3().normalize_or(DVec3::Z);
        (self.x, self.y, self.z) = (d.x, d.y, d.z);
        self.next = 0;
    }

    /// The band the next call evaluates.
    #[must_use]
    pub fn next_band(&self) -> usize {
        self.next
    }

    /// Writes band `l = self.next_band()`'s values (`m = −l..=l`) into `out[..2l + 1]` and
    /// returns `l`; `None` (and nothing written) past the basis' order or if `out` is shorter.
    #[inline]
    pub fn next_band_f32(&mut self, out: &mut [f32]) -> Option<usize> {
        self.next_band_f32_scaled(out, 1.0)
    }

    /// [`Self::next_band_f32`] with every value multiplied by `factor` in f32 after rounding
    /// (`(y as f32) * factor`, as scaling the output of [`Basis::eval_f32_unchecked`] gives).
    #[inline]
    pub fn next_band_f32_scaled(&mut self, out: &mut [f32], factor: f32) -> Option<usize> {
        if out.len() < 2 * self.next + 1 {
            return None;
        }
        let l = self.skip_band()?;
        let q = &self.qs[l % 2];
        let row = &mut out[..2 * l + 1];
        row[l] = (q[0] as f32) * factor;
        for m in 1..=l {
            row[l + m] = ((q[m] * self.cm[m]) as f32) * factor;
            row[l - m] = ((q[m] * self.sm[m]) as f32) * factor;
        }
        Some(l)
    }

    /// Advances past band `l = self.next_band()` without writing its values (the recurrence
    /// state is updated exactly as [`Self::next_band_f32`] updates it, so the bands after it are
    /// the same to the last bit); returns `l`, or `None` past the basis' order. For callers
    /// that take the first bands from elsewhere ([`eval_low_f32`]) and the rest from the cursor.
    #[inline]
    pub fn skip_band(&mut self) -> Option<usize> {
        let l = self.next;
        if l >= self.basis.order {
            return None;
        }
        if l > 0 {
            // The azimuthal factor of the new column m = l.
            let (c, s) = (self.cm[l - 1], self.sm[l - 1]);
            self.cm[l] = self.x * c - self.y * s;
            self.sm[l] = self.x * s + self.y * c;
        }
        let t = &self.basis.table;
        let z = self.z;
        let [even, odd] = &mut self.qs;
        let (q, q1) = if l.is_multiple_of(2) {
            (even, &*odd)
        } else {
            (odd, &*even)
        };
        // `q` holds band l − 2 and becomes band l.
        for m in 0..(l + 1).saturating_sub(2) {
            let (a, b) = t.ab(l, m);
            q[m] = a * (z * q1[m] - b * q[m]);
        }
        if l >= 1 {
            q[l - 1] = ((2 * (l - 1) + 3) as f64).sqrt() * z * q1[l - 1];
        }
        q[l] = t.diag(l);
        self.next += 1;
        Some(l)
    }
}

/// Bands of [`eval_low_f32`]: `0..LOW_BANDS` (`LOW_BANDS²` = 25 values).
pub const LOW_BANDS: usize = 5;

/// `√((2l+1)/4π · (l−m)!/(l+m)!)`, times `√2 (−1)^m` for `m > 0` (the Condon–Shortley phase of
/// CONVENTIONS), for `l < LOW_BANDS`, `0 ≤ m ≤ l`, at `l(l+1)/2 + m`.
fn low_norms() -> &'static [f32; 15] {
    static NORMS: std::sync::OnceLock<[f32; 15]> = std::sync::OnceLock::new();
    NORMS.get_or_init(|| {
        let fact = |n: usize| (1..=n).map(|k| k as f64).product::<f64>();
        let mut out = [0.0f32; 15];
        for l in 0..LOW_BANDS {
            for m in 0..=l {
                let k = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI) * fact(l - m)
                    / fact(l + m))
                .sqrt();
                let sign = if m % 2 == 1 { -1.0 } else { 1.0 };
                let f = if m == 0 {
                    1.0
                } else {
                    std::f64::consts::SQRT_2 * sign
                };
                out[l * (l + 1) / 2 + m] = (k * f) as f32;
            }
        }
        out
    })
}

/// The first [`LOW_BANDS`] bands (25 values, flat index `l(l+1)+m` as everywhere) at `dir`
/// (normalised here, in f32; a zero or non-finite direction gives +Z), in closed form in f32:
/// `y_l^m = N_l^m Q_l^m(z) Re/Im (x + iy)^|m|` with `Q_l^m = d^m P_l / dz^m` the Legendre
/// polynomials' derivatives (`P_2 = (3z² − 1)/2`, `P_3 = (5z³ − 3z)/2`,
/// `P_4 = (35z⁴ − 30z² + 3)/8`) and `N_l^m` the normalisation and phase. 1.4× faster than the
/// f32-output recurrences of [`Basis`] for these bands (benchmark `eval/low_bands_*`); agrees
/// with them to f32 rounding (tested: within 2e-6).
#[inline]
pub fn eval_low_f32(dir: Vec3, out: &mut [f32; 25]) {
    let d = dir.normalize_or(Vec3::Z);
    let (x, y, z) = (d.x, d.y, d.z);
    let n = low_norms();
    let z2 = z * z;
    // Re and Im of (x + iy)^m.
    let (c1, s1) = (x, y);
    let (c2, s2) = (x * c1 - y * s1, x * s1 + y * c1);
    let (c3, s3) = (x * c2 - y * s2, x * s2 + y * c2);
    let (c4, s4) = (x * c3 - y * s3, x * s3 + y * c3);
    // Q_l^m(z) per band.
    let q1 = [z, 1.0];
    let q2 = [1.5 * z2 - 0.5, 3.0 * z, 3.0];
    let q3 = [z * (2.5 * z2 - 1.5), 7.5 * z2 - 1.5, 15.0 * z, 15.0];
    let q4 = [
        (35.0 * z2 * z2 - 30.0 * z2 + 3.0) * 0.125,
        z * (17.5 * z2 - 7.5),
        52.5 * z2 - 7.5,
        105.0 * z,
        105.0,
    ];
    let cs = [(c1, s1), (c2, s2), (c3, s3), (c4, s4)];
    out[0] = n[0];
    let mut band = |l: usize, q: &[f32]| {
        let c = l * (l + 1);
        let b = l * (l + 1) / 2;
        out[c] = n[b] * q[0];
        for m in 1..=l {
            let v = n[b + m] * q[m];
            let (cm, sm) = cs[m - 1];
            out[c + m] = v * cm;
            out[c - m] = v * sm;
        }
    };
    band(1, &q1);
    band(2, &q2);
    band(3, &q3);
    band(4, &q4);
}

/// Convenience: all basis functions of `order` at `dir` (allocates).
pub fn eval_basis(order: usize, dir: DVec3) -> Result<Vec<f64>, ShError> {
    Ok(Basis::new(order)?.eval(dir))
}

/// Value of the expansion `Σ c_i y_i(dir)` (reconstruction at one direction).
pub fn reconstruct(coeffs: &[f64], order: usize, dir: DVec3) -> Result<f64, ShError> {
    check_len(order, coeffs.len())?;
    let y = eval_basis(order, dir)?;
    Ok(coeffs.iter().zip(&y).map(|(c, y)| c * y).sum())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn closed_form_low_bands_match_the_recurrences() {
        // f32 closed form against the f64 recurrences: values are at most ~1.2 in magnitude
        // (|y_4^0| ≤ 1.06) and each is a product of a few f32 roundings (relative 6e-8 each)
        // of terms up to 35·K/8 (the cancelling P_4 polynomial, K = K_4^0 = 0.85: 3.7), so
        // the error is a few 1e-7 (8.8e-7 measured over these directions); 2e-6 leaves about 2×.
        let basis = Basis::new(LOW_BANDS).unwrap();
        let mut dirs = vec![
            Vec3::Z,
            -Vec3::Z,
            Vec3::X,
            -Vec3::Y,
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(1e-7, 0.0, 1.0),
        ];
        for i in 0..500 {
            let t = i as f32 * 0.377;
            dirs.push(Vec3::new(
                (2.1 * t).sin() * (1.3 * t).cos(),
                t.cos() * 2.0,
                (0.7 * t).sin() - 0.3,
            ));
        }
        let mut got = [0.0f32; 25];
        let mut worst = 0.0f64;
        for &d in &dirs {
            eval_low_f32(d, &mut got);
            let want = basis.eval(d.as_dvec3());
            for (g, w) in got.iter().zip(&want) {
                worst = worst.max((f64::from(*g) - w).abs());
            }
        }
        println!("worst difference {worst:e}");
        assert!(worst < 2e-6, "worst difference {worst:e}");
        // Degenerate directions are +Z, as for the recurrences.
        eval_low_f32(Vec3::ZERO, &mut got);
        let z = basis.eval(glam::DVec3::Z);
        assert!(got
            .iter()
            .zip(&z)
            .all(|(g, w)| (f64::from(*g) - w).abs() < 2e-6));
    }

    #[test]
    fn skipped_bands_leave_the_later_bands_bit_identical() {
        for order in [1usize, 5, 7, 14] {
            let basis = Basis::new(order).unwrap();
            let mut want = vec![0.0f32; order * order];
            let mut band = vec![0.0f32; 2 * order - 1];
            for i in 0..50 {
                let t = i as f32 * 0.9;
                let d = Vec3::new(t.sin(), (1.7 * t).cos(), 0.4 - (0.3 * t).cos());
                basis.eval_f32_unchecked(d, &mut want);
                for skip in [0usize, 1, 5] {
                    let mut cursor = BandCursor::new(&basis, d).unwrap();
                    for l in 0..skip.min(order) {
                        assert_eq!(cursor.skip_band(), Some(l));
                    }
                    for l in skip.min(order)..order {
                        cursor.next_band_f32(&mut band).unwrap();
                        for (k, x) in band[..2 * l + 1].iter().enumerate() {
                            assert_eq!(x.to_bits(), want[l * l + k].to_bits());
                        }
                    }
                    assert_eq!(cursor.skip_band(), None);
                }
            }
        }
    }

    #[test]
    fn band_cursor_gives_the_basis_values_bit_for_bit() {
        // Directions over the sphere, the poles and unnormalised ones included.
        let mut dirs = vec![Vec3::Z, -Vec3::Z, Vec3::X, Vec3::new(0.0, 0.0, 3.0)];
        for i in 0..200 {
            let t = i as f32 * 0.731;
            dirs.push(Vec3::new(
                t.sin() * (1.3 * t).cos(),
                t.cos(),
                (0.7 * t).sin() - 0.2,
            ));
        }
        for order in [1usize, 2, 3, 5, 11, 14, 32] {
            let basis = Basis::new(order).unwrap();
            let mut want = vec![0.0f32; order * order];
            let mut band = vec![0.0f32; 2 * order - 1];
            for &d in &dirs {
                basis.eval_f32_unchecked(d, &mut want);
                let mut cursor = BandCursor::new(&basis, d).unwrap();
                for l in 0..order {
                    assert_eq!(cursor.next_band(), l);
                    assert_eq!(cursor.next_band_f32(&mut band), Some(l));
                    let got = &band[..2 * l + 1];
                    let exp = &want[l * l..(l + 1) * (l + 1)];
                    assert_eq!(
                        got.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                        exp.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                        "order {order}, band {l}, direction {d:?}"
                    );
                }
                assert_eq!(cursor.next_band_f32(&mut band), None);
                // Scaled: each value rounded to f32, then multiplied in f32; on a cursor reused
                // from another direction (`reset`).
                let mut scaled = BandCursor::new(&basis, Vec3::new(0.3, -0.9, 0.1)).unwrap();
                while scaled.next_band_f32(&mut band).is_some() {}
                scaled.reset(d);
                for l in 0..order {
                    let f = 0.37 + l as f32;
                    scaled.next_band_f32_scaled(&mut band, f).unwrap();
                    for (k, x) in band[..2 * l + 1].iter().enumerate() {
                        assert_eq!(x.to_bits(), (want[l * l + k] * f).to_bits());
                    }
                }
            }
        }
        assert!(BandCursor::new(&Basis::new(33).unwrap(), Vec3::Z).is_err());
        // A buffer too short for the band: nothing written, the cursor stays.
        let basis = Basis::new(4).unwrap();
        let mut cursor = BandCursor::new(&basis, Vec3::Y).unwrap();
        let mut one = [0.0f32; 1];
        assert_eq!(cursor.next_band_f32(&mut one), Some(0));
        assert_eq!(cursor.next_band_f32(&mut one), None);
        assert_eq!(cursor.next_band(), 1);
    }
}
