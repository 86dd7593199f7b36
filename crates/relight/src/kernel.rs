//! Per-point kernels shared by the full-order and the adaptive paths, so that both sum in the
//! same order and agree bit for bit when the adaptive threshold is 0.
//!
//! Summation order (fixed, documented so results are reproducible):
//! - the **base** (bands `0..BASE_ORDER`) is one accumulator per channel, and every further band
//!   `l` adds its own contribution to a second accumulator `high` in increasing `l`;
//! - the value is `scale · (base + high)`.

/// Bands always evaluated for every point: the first three (Lee & Kim 2014, 5.1.1, after
/// Ramamoorthi & Hanrahan 2001: three bands carry almost all of the diffuse response).
pub const BASE_ORDER: usize = 3;

/// Number of vertices per parallel task.
pub(crate) const CHUNK: usize = 256;

/// Dot product of two equal-length f32 slices with 8 independent lanes (auto-vectorised; no
/// bounds checks inside the loop), then a fixed reduction tree and the scalar tail.
#[inline]
pub(crate) fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut acc = [0.0f32; 8];
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut tail = 0.0f32;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// The running sums of one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Accum {
    /// Sum over the base bands, per channel (before `scale`).
    pub base: [f32; 3],
    /// Sum over the bands `BASE_ORDER..=last_level`, per channel (before `scale`).
    pub high: [f32; 3],
    /// Output scale per channel (albedo/π, or specular · (e+2)/(e+1) · cos θ_o).
    pub scale: [f32; 3],
    /// Highest band included.
    pub last_level: u16,
    /// Coefficient products (multiply–adds of the dot products) spent on this point.
    pub products: u64,
    /// A point that is not shaded (specular facing away): radiance 0, never in an ROI.
    pub inactive: bool,
}

impl Accum {
    /// `scale · (base + high)`.
    #[inline]
    pub fn radiance(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.scale[c] * (self.base[c] + self.high[c]))
    }

    /// The accumulated high-order difference in radiance units, `scale · high`.
    #[inline]
    pub fn correction(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.scale[c] * self.high[c])
    }

    /// `max_c |scale_c · high_c|`, the significance tested against the threshold.
    #[inline]
    pub fn significance(&self) -> f32 {
        let d = self.correction();
        d[0].abs().max(d[1].abs()).max(d[2].abs())
    }
}

/// Diffuse kernel: `base_c = L_c[..b²]·T_c[..b²]`, then band by band `high_c += L_c[band]·T_c[band]`
/// from level `from` (≥ b) up to `to` inclusive, stopping after a level whose accumulated
/// correction is below `threshold` (Lee & Kim 2014, Algorithms 1–2).
pub(crate) struct DiffuseKernel<'a> {
    pub light: [&'a [f32]; 3],
    pub order: usize,
}

impl DiffuseKernel<'_> {
    /// Coefficient products of levels `0..=level` (3 channels).
    pub fn products_through(level: usize) -> u64 {
        3 * ((level + 1) * (level + 1)) as u64
    }

    /// Base of point with transfer `t` (`channels · n²` floats).
    #[inline]
    pub fn base(&self, t: &[f32], channels: usize, scale: [f32; 3]) -> Accum {
        let n2 = self.order * self.order;
        let b = BASE_ORDER.min(self.order);
        let mut acc = Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            ..Accum::default()
        };
        for c in 0..3 {
            let tc = if channels == 3 {
                &t[c * n2..(c + 1) * n2]
            } else {
                &t[..n2]
            };
            acc.base[c] = dot(&self.light[c][..b * b], &tc[..b * b]);
        }
        acc
    }

    /// Adds levels `acc.last_level + 1 ..= to`, stopping early under `threshold`.
    #[inline]
    pub fn extend(
        &self,
        acc: &mut Accum,
        t: &[f32],
        channels: usize,
        to: usize,
        threshold: Option<f32>,
    ) {
        let n2 = self.order * self.order;
        for l in (acc.last_level as usize + 1)..=to {
            let (s, e) = (l * l, (l + 1) * (l + 1));
            for c in 0..3 {
                let tc = if channels == 3 {
                    &t[c * n2..(c + 1) * n2]
                } else {
                    &t[..n2]
                };
                acc.high[c] += dot(&self.light[c][s..e], &tc[s..e]);
            }
            acc.last_level = l as u16;
            acc.products += 3 * (e - s) as u64;
            if let Some(th) = threshold {
                if acc.significance() < th {
                    break;
                }
            }
        }
    }
}

/// Specular kernel (Lee & Kim 2014, eq. 4.3–4.4 and Algorithm 3, after Sloan, Kautz & Snyder
/// 2002): the specular value is `Σ_ij w_i L̂_ij V_j` with `L̂ = M(L)` the light's product matrix
/// (`(L̂ V)_i = (L ⊛ V)_i`), `w_i = A_l y_i(r)` the Phong lobe's band multipliers times the basis
/// at the reflection direction, and `V` the visibility.
///
/// Level `l` adds exactly the terms of the incremental product that involve band `l`: the new
/// rows `i ∈ band l` against columns `j < (l+1)²`, and the new columns `j ∈ band l` against the
/// old rows `i < l²`. Since `L̂` is symmetric (the Gaunt tensor is), the second block is read as
/// rows of band `l` too, so level `l` is
/// `Σ_{i∈band l} [ w_i (L̂_i,·<(l+1)² · V) + V_i (L̂_i,·<l² · w) ]` — two contiguous dot products
/// per row, with the same multiply count as Algorithm 3 (`(2l+1)((l+1)² + l²)` per channel).
/// Only the block-lower rows are stored (packed, `row_offsets`).
pub(crate) struct SpecularKernel<'a> {
    pub products: [&'a [f32]; 3],
    pub row_offsets: &'a [usize],
    pub order: usize,
}

impl SpecularKernel<'_> {
    /// Coefficient products of level `l` (3 channels).
    pub fn products_of_level(l: usize) -> u64 {
        3 * ((2 * l + 1) * ((l + 1) * (l + 1) + l * l)) as u64
    }

    /// Coefficient products of levels `0..=level`.
    pub fn products_through(level: usize) -> u64 {
        (0..=level).map(Self::products_of_level).sum()
    }

    #[inline]
    fn level(&self, l: usize, c: usize, v: &[f32], w: &[f32]) -> f32 {
        let m = self.products[c];
        let (s, e) = (l * l, (l + 1) * (l + 1));
        let mut sum = 0.0f32;
        for i in s..e {
            let row = &m[self.row_offsets[i]..self.row_offsets[i + 1]];
            sum += w[i] * dot(row, &v[..e]) + v[i] * dot(&row[..s], &w[..s]);
        }
        sum
    }

    /// Base (levels `0..b`) of a point with visibility `v` and weights `w`.
    #[inline]
    pub fn base(&self, v: &[f32], w: &[f32], scale: [f32; 3]) -> Accum {
        let b = BASE_ORDER.min(self.order);
        let mut acc = Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            ..Accum::default()
        };
        for c in 0..3 {
            let mut s = 0.0f32;
            for l in 0..b {
                s += self.level(l, c, v, w);
            }
            acc.base[c] = s;
        }
        acc
    }

    /// Adds levels `acc.last_level + 1 ..= to`, stopping early under `threshold`.
    #[inline]
    pub fn extend(&self, acc: &mut Accum, v: &[f32], w: &[f32], to: usize, threshold: Option<f32>) {
        for l in (acc.last_level as usize + 1)..=to {
            for c in 0..3 {
                acc.high[c] += self.level(l, c, v, w);
            }
            acc.last_level = l as u16;
            acc.products += Self::products_of_level(l);
            if let Some(th) = threshold {
                if acc.significance() < th {
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_f64_sum() {
        for n in [0usize, 1, 7, 8, 9, 17, 196] {
            let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
            let b: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos()).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
            // n products of magnitude ≤ 1, summed in f32: error ≤ n·ε·Σ|a b| ≤ n² ε.
            let tol = (n * n) as f64 * f32::EPSILON as f64 + 1e-12;
            assert!((dot(&a, &b) as f64 - exact).abs() <= tol, "n = {n}");
        }
    }

    #[test]
    fn product_counts_sum_to_dense() {
        // Levels 0..n−1 of the specular kernel cover every (i, j) pair of the n²×n² matrix
        // exactly once (3 channels): Σ_l (2l+1)((l+1)² + l²) = n⁴.
        for n in 1..15usize {
            assert_eq!(
                SpecularKernel::products_through(n - 1),
                3 * (n as u64).pow(4)
            );
            assert_eq!(
                DiffuseKernel::products_through(n - 1),
                3 * (n as u64).pow(2)
            );
        }
    }
}
