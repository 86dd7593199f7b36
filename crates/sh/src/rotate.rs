//! Rotation of SH coefficient vectors: band-by-band matrices by the Ivanic–Ruedenberg
//! recurrence (J. Ivanic, K. Ruedenberg, J. Phys. Chem. 100 (1996) 6342, with the 1998
//! erratum), O(n³) to build and O(n³) per vector to apply.
//!
//! Definition: for a rotation `R`, [`Rotation::apply`] maps the coefficients of `f` to those of
//! the rotated function `g(ω) = f(R⁻¹ω)`. The recurrence is run on the real basis without the
//! Condon–Shortley phase (the one the paper uses) and the result is conjugated by
//! `diag((−1)^|m|)` into this crate's basis.

use crate::index::{check_len, check_order, coefficient_count, ShError, MAX_ORDER};
use glam::{DMat3, DQuat};

/// The SH rotation matrices of one 3D rotation, for `order` bands.
#[derive(Clone, Debug)]
pub struct Rotation {
    order: usize,
    /// Band `l` matrix, row-major `(2l+1)²`, entry `[m + l][n + l]`.
    bands: Vec<Vec<f64>>,
}

struct BandView<'a> {
    l: i64,
    data: &'a [f64],
}

impl BandView<'_> {
    #[inline]
    fn at(&self, m: i64, n: i64) -> f64 {
        let w = 2 * self.l + 1;
        self.data[((m + self.l) * w + n + self.l) as usize]
    }
}

impl Rotation {
    /// Builds the band matrices of rotation matrix `r` (checked to be a proper rotation to 1e-6).
    pub fn new(order: usize, r: DMat3) -> Result<Self, ShError> {
        check_order(order, MAX_ORDER)?;
        if !r.is_finite() {
            return Err(ShError::NotARotation { error: f64::NAN });
        }
        let err = (r.transpose() * r - DMat3::IDENTITY)
            .to_cols_array()
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()))
            .max((r.determinant() - 1.0).abs());
        if err.is_nan() || err > 1e-6 {
            return Err(ShError::NotARotation { error: err });
        }
        let mut bands: Vec<Vec<f64>> = Vec::with_capacity(order);
        bands.push(vec![1.0]);
        if order > 1 {
            // Band 1 without CS phase: basis ∝ (y, z, x) for m = −1, 0, 1.
            let p = [1usize, 2, 0];
            let mut b1 = vec![0.0; 9];
            for a in 0..3 {
                for b in 0..3 {
                    b1[a * 3 + b] = r.col(p[b])[p[a]];
                }
            }
            bands.push(b1);
        }
        for l in 2..order {
            let next = {
                let r1 = BandView {
                    l: 1,
                    data: &bands[1],
                };
                let prev = BandView {
                    l: l as i64 - 1,
                    data: &bands[l - 1],
                };
                band_from_recurrence(l as i64, &r1, &prev)
            };
            bands.push(next);
        }
        // Conjugate by diag((−1)^|m|) into the Condon–Shortley basis.
        for (l, band) in bands.iter_mut().enumerate() {
            let l = l as i64;
            let w = 2 * l + 1;
            for m in -l..=l {
                for n in -l..=l {
                    if (m.abs() + n.abs()) % 2 == 1 {
                        band[((m + l) * w + n + l) as usize] *= -1.0;
                    }
                }
            }
        }
        Ok(Self { order, bands })
    }

    /// Builds the band matrices of a unit quaternion.
    pub fn from_quat(order: usize, q: DQuat) -> Result<Self, ShError> {
        Self::new(order, DMat3::from_quat(q.normalize()))
    }

    /// Order (band count).
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Band `l`'s matrix, row-major `(2l+1)×(2l+1)`, entry `[m + l][n + l]`.
    #[must_use]
    pub fn band(&self, l: usize) -> &[f64] {
        &self.bands[l]
    }

    /// Rotates a coefficient vector of this order into `out`.
    pub fn apply_into(&self, coeffs: &[f64], out: &mut [f64]) -> Result<(), ShError> {
        check_len(self.order, coeffs.len())?;
        check_len(self.order, out.len())?;
        for (l, band) in self.bands.iter().enumerate() {
            let w = 2 * l + 1;
            let start = l * l;
            let src = &coeffs[start..start + w];
            for (row, o) in out[start..start + w].iter_mut().enumerate() {
                let r = &band[row * w..(row + 1) * w];
                *o = r.iter().zip(src).map(|(a, b)| a * b).sum();
            }
        }
        Ok(())
    }

    /// Rotates a coefficient vector of this order.
    pub fn apply(&self, coeffs: &[f64]) -> Result<Vec<f64>, ShError> {
        let mut out = vec![0.0; coefficient_count(self.order)];
        self.apply_into(coeffs, &mut out)?;
        Ok(out)
    }

    /// Rotates RGB coefficients (length must be `order²`; panics otherwise, an internal misuse).
    #[must_use]
    pub fn apply_rgb(&self, coeffs: &[[f64; 3]]) -> Vec<[f64; 3]> {
        assert_eq!(
            coeffs.len(),
            coefficient_count(self.order),
            "RGB coefficient count"
        );
        let mut out = vec![[0.0; 3]; coeffs.len()];
        for (l, band) in self.bands.iter().enumerate() {
            let w = 2 * l + 1;
            let start = l * l;
            for row in 0..w {
                let r = &band[row * w..(row + 1) * w];
                let mut acc = [0.0; 3];
                for (a, c) in r.iter().zip(&coeffs[start..start + w]) {
                    for ch in 0..3 {
                        acc[ch] += a * c[ch];
                    }
                }
                out[start + row] = acc;
            }
        }
        out
    }

    /// Single-precision rotation of a coefficient vector (matrices rounded on the fly).
    pub fn apply_f32_into(&self, coeffs: &[f32], out: &mut [f32]) -> Result<(), ShError> {
        check_len(self.order, coeffs.len())?;
        check_len(self.order, out.len())?;
        for (l, band) in self.bands.iter().enumerate() {
            let w = 2 * l + 1;
            let start = l * l;
            for row in 0..w {
                let r = &band[row * w..(row + 1) * w];
                let mut acc = 0.0f64;
                for (a, c) in r.iter().zip(&coeffs[start..start + w]) {
                    acc += a * *c as f64;
                }
                out[start + row] = acc as f32;
            }
        }
        Ok(())
    }
}

fn band_from_recurrence(l: i64, r1: &BandView<'_>, prev: &BandView<'_>) -> Vec<f64> {
    let w = (2 * l + 1) as usize;
    let mut out = vec![0.0; w * w];
    for m in -l..=l {
        for n in -l..=l {
            let d = if m == 0 { 1.0 } else { 0.0 };
            let denom = if n.abs() == l {
                (2 * l * (2 * l - 1)) as f64
            } else {
                ((l + n) * (l - n)) as f64
            };
            let am = m.abs();
            let u = (((l + m) * (l - m)) as f64 / denom).sqrt();
            let v = 0.5
                * ((1.0 + d) * ((l + am - 1) * (l + am)) as f64 / denom).sqrt()
                * (1.0 - 2.0 * d);
            let wc = -0.5 * (((l - am - 1) * (l - am)) as f64 / denom).sqrt() * (1.0 - d);
            let mut value = 0.0;
            if u != 0.0 {
                value += u * p(0, l, m, n, r1, prev);
            }
            if v != 0.0 {
                value += v * big_v(l, m, n, r1, prev);
            }
            if wc != 0.0 {
                value += wc * big_w(l, m, n, r1, prev);
            }
            out[((m + l) as usize) * w + (n + l) as usize] = value;
        }
    }
    out
}

#[inline]
fn p(i: i64, l: i64, a: i64, b: i64, r1: &BandView<'_>, prev: &BandView<'_>) -> f64 {
    let ri1 = r1.at(i, 1);
    let rim1 = r1.at(i, -1);
    let ri0 = r1.at(i, 0);
    if b == l {
        ri1 * prev.at(a, l - 1) - rim1 * prev.at(a, -l + 1)
    } else if b == -l {
        ri1 * prev.at(a, -l + 1) + rim1 * prev.at(a, l - 1)
    } else {
        ri0 * prev.at(a, b)
    }
}

fn big_v(l: i64, m: i64, n: i64, r1: &BandView<'_>, prev: &BandView<'_>) -> f64 {
    if m == 0 {
        p(1, l, 1, n, r1, prev) + p(-1, l, -1, n, r1, prev)
    } else if m > 0 {
        let d: f64 = if m == 1 { 1.0 } else { 0.0 };
        p(1, l, m - 1, n, r1, prev) * (1.0 + d).sqrt() - p(-1, l, -m + 1, n, r1, prev) * (1.0 - d)
    } else {
        let d: f64 = if m == -1 { 1.0 } else { 0.0 };
        p(1, l, m + 1, n, r1, prev) * (1.0 - d) + p(-1, l, -m - 1, n, r1, prev) * (1.0 + d).sqrt()
    }
}

fn big_w(l: i64, m: i64, n: i64, r1: &BandView<'_>, prev: &BandView<'_>) -> f64 {
    if m > 0 {
        p(1, l, m + 1, n, r1, prev) + p(-1, l, -m - 1, n, r1, prev)
    } else {
        p(1, l, m - 1, n, r1, prev) - p(-1, l, -m + 1, n, r1, prev)
    }
}
