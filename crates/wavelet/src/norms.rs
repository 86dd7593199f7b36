//! Squared L2 norms of the synthesis basis functions, for ranking coefficients by their share
//! of the L2 error.

use crate::dwt1d::{axis_level, multi_level_1d, Bank, Step};
use crate::wavelet::{Boundaries, Boundary};

/// Squared norms of the 1D synthesis functions of one axis: `scaling[l − 1][k]` of the level-`l`
/// scaling function `k`, `wavelet[l − 1][k]` of the level-`l` wavelet `k`.
#[derive(Clone, Debug)]
struct AxisNorms {
    scaling: Vec<Vec<f64>>,
    wavelet: Vec<Vec<f64>>,
}

impl AxisNorms {
    fn compute(bank: &Bank, boundary: Boundary, n: usize, levels: usize) -> AxisNorms {
        let mut scaling = Vec::with_capacity(levels);
        let mut wavelet = Vec::with_capacity(levels);
        for l in 1..=levels {
            let m = n >> l;
            // The synthesis function of layout position `pos` with `l` levels: the inverse of a
            // unit coefficient.
            let norm = |pos: usize| {
                let mut v = vec![0.0; n];
                v[pos] = 1.0;
                multi_level_1d(bank, boundary, Step::Synthesis, &mut v, l);
                v.iter().map(|x| x * x).sum::<f64>()
            };
            match boundary {
                // Shifting a coefficient by one shifts its function by 2^l samples, cyclically.
                Boundary::Periodic => {
                    scaling.push(vec![norm(0); m]);
                    wavelet.push(vec![norm(m); m]);
                }
                Boundary::Symmetric => {
                    scaling.push((0..m).map(norm).collect());
                    wavelet.push((0..m).map(|k| norm(m + k)).collect());
                }
            }
        }
        AxisNorms { scaling, wavelet }
    }

    /// Squared norm of the 1D factor at layout position `i` for a band of level `level`
    /// (`is_detail`: the band is high pass along this axis).
    fn factor(&self, i: usize, n: usize, level: usize, is_detail: bool) -> f64 {
        if level == 0 {
            return 1.0;
        }
        if is_detail {
            self.wavelet[level - 1][i - (n >> level)]
        } else {
            self.scaling[level - 1][i]
        }
    }
}

/// `‖Φ_i‖²` for every coefficient of a transform, in the Mallat layout.
#[derive(Clone, Debug)]
pub(crate) struct BasisNorms {
    per_coefficient: Vec<f64>,
}

impl BasisNorms {
    /// The norms of a `w × h` transform of `levels` levels with filter `bank` and
    /// `boundaries`.
    pub(crate) fn compute(
        bank: &Bank,
        boundaries: Boundaries,
        w: usize,
        h: usize,
        levels: usize,
    ) -> BasisNorms {
        let x_norms = AxisNorms::compute(bank, boundaries.x, w, levels);
        let y_norms = if h == w && boundaries.x == boundaries.y {
            x_norms.clone()
        } else {
            AxisNorms::compute(bank, boundaries.y, h, levels)
        };
        let mut per_coefficient = Vec::with_capacity(w * h);
        for y in 0..h {
            let ly = axis_level(y, h, levels);
            for x in 0..w {
                let lx = axis_level(x, w, levels);
                let level = lx.min(ly).min(levels);
                let fx = x_norms.factor(x, w, level, lx == level);
                let fy = y_norms.factor(y, h, level, ly == level);
                per_coefficient.push(fx * fy);
            }
        }
        BasisNorms { per_coefficient }
    }

    pub(crate) fn per_coefficient(&self) -> &[f64] {
        &self.per_coefficient
    }
}
