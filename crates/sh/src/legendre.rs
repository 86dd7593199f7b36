//! Normalised associated Legendre functions by stable recurrences.
//!
//! The crate evaluates `Q_l^m(x) = c_m K_l^m P_l^m(x) / sin^m θ` (with `c_0 = 1`, `c_m = √2`,
//! Condon–Shortley phase included in `P_l^m`) so that the real basis function is
//! `y_l^{±m} = Q_l^m(z) · Re/Im (x + i y)^m`. Dividing out `sin^m θ` removes every square root
//! of `1 − z²` and every division by `sin θ`: the poles are ordinary points and `(x + iy)^m`
//! carries the azimuth exactly. The recurrences (for normalised functions, no factorials):
//!
//! - `Q_0^0 = 1/√(4π)`, `Q_1^1 = −√3 Q_0^0`, `Q_m^m = −√((2m+1)/(2m)) Q_{m−1}^{m−1}` (m ≥ 2);
//! - `Q_{m+1}^m = √(2m+3) z Q_m^m`;
//! - `Q_l^m = a_l^m (z Q_{l−1}^m − b_l^m Q_{l−2}^m)`, `a = √((4l²−1)/(l²−m²))`,
//!   `b = √(((l−1)²−m²)/(4(l−1)²−1))`.
//!
//! Every coefficient is O(1) and the column recurrence in `l` is the forward-stable one, so the
//! relative error grows only linearly with the degree.

use crate::index::index;

/// Precomputed recurrence coefficients for orders up to `order`.
#[derive(Clone, Debug)]
pub struct LegendreTable {
    order: usize,
    /// `a_l^m` at flat index `index(l, m)` (m ≥ 0 entries used).
    a: Vec<f64>,
    /// `b_l^m` at flat index `index(l, m)`.
    b: Vec<f64>,
    /// Diagonal seeds `Q_m^m`.
    diag: Vec<f64>,
}

impl LegendreTable {
    /// Builds the table for `order` bands.
    #[must_use]
    pub fn new(order: usize) -> Self {
        let n2 = order * order;
        let mut a = vec![0.0; n2];
        let mut b = vec![0.0; n2];
        let mut diag = vec![0.0; order];
        if order > 0 {
            diag[0] = 0.5 / std::f64::consts::PI.sqrt();
        }
        for m in 1..order {
            let factor = if m == 1 {
                -(3.0f64).sqrt()
            } else {
                -(((2 * m + 1) as f64) / ((2 * m) as f64)).sqrt()
            };
            diag[m] = factor * diag[m - 1];
        }
        for l in 0..order {
            for m in 0..=l {
                if l >= m + 2 {
                    let (lf, mf) = (l as f64, m as f64);
                    let i = index(l, m as i64);
                    a[i] = ((4.0 * lf * lf - 1.0) / (lf * lf - mf * mf)).sqrt();
                    let l1 = lf - 1.0;
                    b[i] = ((l1 * l1 - mf * mf) / (4.0 * l1 * l1 - 1.0)).sqrt();
                }
            }
        }
        Self { order, a, b, diag }
    }

    /// Diagonal seed `Q_m^m`.
    #[inline]
    #[must_use]
    pub fn diag(&self, m: usize) -> f64 {
        self.diag[m]
    }

    /// Recurrence coefficients `(a_l^m, b_l^m)` for `l ≥ m + 2`.
    #[inline]
    #[must_use]
    pub fn ab(&self, l: usize, m: usize) -> (f64, f64) {
        let i = index(l, m as i64);
        (self.a[i], self.b[i])
    }

    /// Order this table serves.
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Fills `q[index(l, m)]` (m ≥ 0 slots only) with `Q_l^m(z)` for all `l < order`.
    /// Slots with m < 0 are left untouched.
    pub fn fill(&self, z: f64, q: &mut [f64]) {
        let n = self.order;
        for m in 0..n {
            let mut q_lm2 = self.diag[m];
            q[index(m, m as i64)] = q_lm2;
            if m + 1 >= n {
                break;
            }
            let mut q_lm1 = ((2 * m + 3) as f64).sqrt() * z * q_lm2;
            q[index(m + 1, m as i64)] = q_lm1;
            for l in (m + 2)..n {
                let i = index(l, m as i64);
                let v = self.a[i] * (z * q_lm1 - self.b[i] * q_lm2);
                q[i] = v;
                q_lm2 = q_lm1;
                q_lm1 = v;
            }
        }
    }

    /// Fills `out[index(l, m)]` (m ≥ 0 slots) with `N_l^m(z) = Q_l^m(z) sin^m θ` given
    /// `sin θ = s ≥ 0`: the θ-dependent factor of `y_l^{±m}` (so `y_l^m = N cos mφ`,
    /// `y_l^{−m} = N sin mφ`).
    pub fn fill_with_sin(&self, z: f64, s: f64, out: &mut [f64]) {
        self.fill(z, out);
        let mut sm = 1.0;
        for m in 0..self.order {
            for l in m..self.order {
                out[index(l, m as i64)] *= sm;
            }
            sm *= s;
        }
    }
}
