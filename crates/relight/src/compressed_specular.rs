//! Glossy relighting straight from a clustered-PCA visibility block (Sloan, Hall, Hart &
//! Snyder 2003, §4: the lighting is pushed through each cluster's mean and basis once per
//! frame, and a point only combines its cluster's results with its weights).
//!
//! The specular radiance of a point is `scale_c · wᵀ (L_c ⊛ V)` with `w` the point's lobe
//! weights (Phong: `A_l y_lm(r)`; a fitted lobe: `Σ_k A^k_l y_lm(a_k)`). The product `L ⊛ V`
//! is linear in `V`, so with `V_p ≈ mean_k + Σ_j a_pj basis_kj`:
//!
//! `wᵀ (L ⊛ V_p) = wᵀ R_k0 + Σ_j a_pj · wᵀ R_kj`, `R_kr = L̂_c · row_kr`,
//!
//! where `L̂_c` is the (symmetric) product matrix of the lighting. Per frame the `K·(M+1)`
//! vectors `R_kr` cost `3 K (M+1) n⁴` multiply-adds; per point `3 (M+1) n²` instead of the
//! `≈ 3 n⁴` of the full product — the point's lobe weights are formed as in the full path.

use crate::compressed::{check_cpca, CpcaTransfer};
use crate::error::RelightError;
use crate::input::{Lighting, SpecularInput};
use crate::relighter::{specular_point, Relighter};
use prt_sh::MAX_GAUNT_ORDER;
use rayon::prelude::*;

/// Points per parallel chunk.
const CHUNK: usize = 256;

/// `Σ a_i b_i` in eight lanes (summed lane by lane in a fixed order, so the result does not
/// depend on the thread count).
#[inline]
pub(crate) fn dot8(a: &[f32], b: &[f32]) -> f32 {
    let mut acc = [0.0f32; 8];
    let (ca, ra) = a.as_chunks::<8>();
    let (cb, rb) = b.as_chunks::<8>();
    for (x, y) in ca.iter().zip(cb) {
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

/// Full-order glossy specular radiance per point (the same approximation as
/// [`Relighter::specular`], see the crate docs) with the visibility taken from its
/// clustered-PCA form `vis` (its channel 0; the relighter's order, at most the block's),
/// under `lighting`. `input.visibility` is only used for its point count (it may hold the
/// reconstruction; it is not read).
///
/// # Errors
/// The checks of [`Relighter::specular`]; a clustered-PCA block of another point count or
/// inconsistent sizes; an order above the Gaunt tensor's limit.
pub fn specular_cpca(
    relighter: &Relighter,
    input: &SpecularInput<'_>,
    vis: &CpcaTransfer<'_>,
    lighting: &Lighting,
) -> Result<Vec<[f32; 3]>, RelightError> {
    let order = relighter.order();
    let n = relighter.check_specular(input)?;
    check_cpca(order, vis, lighting.order)?;
    if vis.cluster_of.len() != n {
        return Err(RelightError::PointCount {
            what: "clustered-PCA visibility",
            expected: n,
            got: vis.cluster_of.len(),
        });
    }
    let table = cluster_products(relighter, vis, lighting)?;
    let lobe = relighter.lobe(&input.lobe)?;
    let (n2, m) = (order * order, vis.components);
    let mut out = vec![[0.0f32; 3]; n];
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(ci, chunk)| {
            let mut w = vec![0.0f32; n2];
            let mut scratch = vec![0.0f32; n2];
            let mut rows = [[0.0; MAX_GAUNT_ORDER]; crate::input::MAX_FITTED_LOBES];
            for (i, o) in chunk.iter_mut().enumerate() {
                let p = ci * CHUNK + i;
                let g = specular_point(input, p, &lobe, order, &mut rows);
                if !g.active {
                    continue;
                }
                relighter.point_weights(&g, &mut w, &mut scratch);
                let base = vis.cluster_of[p] as usize * (m + 1);
                let weights = &vis.weights[p * m..(p + 1) * m];
                for c in 0..3 {
                    let at = |r: usize| &table[((base + r) * 3 + c) * n2..][..n2];
                    let mut s = dot8(&w, at(0));
                    for (j, &a) in weights.iter().enumerate() {
                        s += a * dot8(&w, at(1 + j));
                    }
                    o[c] = g.scale[c] * s;
                }
            }
        });
    Ok(out)
}

/// Per cluster row `r` (mean, basis vectors) and colour `c`: `L̂_c · row_r` truncated to the
/// relighter's order, `[row][colour][n²]`.
fn cluster_products(
    relighter: &Relighter,
    vis: &CpcaTransfer<'_>,
    lighting: &Lighting,
) -> Result<Vec<f32>, RelightError> {
    let order = relighter.order();
    let gaunt = relighter.gaunt().ok_or(RelightError::OrderMismatch {
        what: "specular relighter (Gaunt tensor limit)",
        expected: MAX_GAUNT_ORDER,
        got: order,
    })?;
    let lit = lighting.truncated(order)?;
    let n2 = order * order;
    let b2 = vis.order * vis.order;
    let d = vis.channels * b2;
    let dense: Vec<Vec<f32>> = (0..3)
        .map(|c| {
            let l64: Vec<f64> = lit.rgb[c].iter().map(|&v| f64::from(v)).collect();
            gaunt
                .product_matrix(&l64)
                .map(|m| m.into_iter().map(|v| v as f32).collect())
        })
        .collect::<Result<_, _>>()?;
    let rows = vis.clusters * (vis.components + 1);
    let mut table = vec![0.0f32; rows * 3 * n2];
    table
        .par_chunks_mut(3 * n2)
        .enumerate()
        .for_each(|(r, out)| {
            // Channel 0 of the row (visibility does not depend on colour).
            let row = &vis.centres[r * d..r * d + n2];
            for (c, m) in dense.iter().enumerate() {
                for (i, o) in out[c * n2..(c + 1) * n2].iter_mut().enumerate() {
                    *o = dot8(&m[i * n2..(i + 1) * n2], row);
                }
            }
        });
    Ok(table)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::{PhongParams, SpecularLobe, Surface, TransferView, Viewer};

    /// The compressed path equals [`Relighter::specular`] on the reconstructed visibility,
    /// within f32 rounding: both form `wᵀ L̂ V` from the same f32 `L̂` (rounded from the same
    /// f64 product matrix), in different summation orders. The bound is `(2n² + 2M + 8)·u`
    /// times the sum of the magnitudes of every product `|w_i| |L̂_ij| (|mean_j| + Σ |a_j|
    /// |basis_j|)` times the scale (`u = 2⁻²⁴`; the reconstruction's own two roundings per
    /// term are inside the same sum).
    #[test]
    fn equals_the_full_path_on_the_reconstruction() {
        let (k, m, order) = (3usize, 4usize, 6usize);
        let n2 = order * order;
        let centres: Vec<f32> = (0..k * (m + 1) * n2)
            .map(|i| ((i * 37 % 101) as f32 / 101.0 - 0.5) * 2.0)
            .collect();
        let points = 40;
        let cluster_of: Vec<u32> = (0..points).map(|p| (p * 5 % k) as u32).collect();
        let weights: Vec<f32> = (0..points * m)
            .map(|i| ((i * 13 % 17) as f32 - 8.0) / 4.0)
            .collect();
        let vis = CpcaTransfer {
            order,
            channels: 1,
            clusters: k,
            components: m,
            centres: &centres,
            cluster_of: &cluster_of,
            weights: &weights,
        };
        let mut data = Vec::new();
        for (p, &c) in cluster_of.iter().enumerate() {
            let row = |r: usize| &centres[(c as usize * (m + 1) + r) * n2..][..n2];
            let start = data.len();
            data.extend_from_slice(row(0));
            for j in 0..m {
                for (o, &b) in data[start..].iter_mut().zip(row(1 + j)) {
                    *o += weights[p * m + j] * b;
                }
            }
        }
        let normals: Vec<[f32; 3]> = (0..points)
            .map(|p| {
                let t = p as f32 * 0.37;
                let v = glam::Vec3::new(t.cos(), 0.5 + 0.3 * t.sin(), (2.0 * t).sin());
                v.normalize().to_array()
            })
            .collect();
        let positions = vec![[0.0f32; 3]; points];
        let coeffs: Vec<[f64; 3]> = (0..n2)
            .map(|i| [1.0 / (1.0 + i as f64), 0.4 - 0.03 * i as f64, 0.2])
            .collect();
        let lighting = Lighting::from_rgb_coefficients(&coeffs, None).unwrap();
        let relighter = Relighter::new(order).unwrap();
        let input = SpecularInput {
            visibility: TransferView::new(order, 1, &data).unwrap(),
            surface: Surface {
                positions: &positions,
                normals: &normals,
            },
            viewer: Viewer::Eye([0.3, 2.0, 1.0]),
            lobe: SpecularLobe::Phong(PhongParams {
                specular: [0.3, 0.5, 0.7],
                exponent: 20.0,
            }),
        };
        let frame = relighter.frame_lighting(&lighting, true).unwrap();
        let full = relighter.specular(&input, &frame).unwrap();
        let fast = specular_cpca(&relighter, &input, &vis, &lighting).unwrap();
        // The magnitudes: |w| |L̂| |t| with |t| the sum of magnitudes of its terms.
        let gaunt = prt_sh::GauntTensor::new(order).unwrap();
        let lobe = relighter.lobe(&input.lobe).unwrap();
        let u = f64::from(f32::EPSILON) / 2.0;
        let mut active = 0;
        for p in 0..points {
            let mut rows = [[0.0; MAX_GAUNT_ORDER]; crate::input::MAX_FITTED_LOBES];
            let g = specular_point(&input, p, &lobe, order, &mut rows);
            if !g.active {
                assert_eq!(fast[p], [0.0; 3]);
                continue;
            }
            active += 1;
            let mut w = vec![0.0f32; n2];
            let mut s = vec![0.0f32; n2];
            relighter.point_weights(&g, &mut w, &mut s);
            let c = cluster_of[p] as usize;
            let tmag: Vec<f64> = (0..n2)
                .map(|i| {
                    let at = |r: usize| f64::from(centres[(c * (m + 1) + r) * n2 + i]).abs();
                    at(0)
                        + (0..m)
                            .map(|j| f64::from(weights[p * m + j]).abs() * at(1 + j))
                            .sum::<f64>()
                })
                .collect();
            for col in 0..3 {
                let l64: Vec<f64> = lighting.rgb[col].iter().map(|&v| f64::from(v)).collect();
                let dense = gaunt.product_matrix(&l64).unwrap();
                let mag: f64 = (0..n2)
                    .map(|i| {
                        f64::from(w[i]).abs()
                            * (0..n2)
                                .map(|j| dense[i * n2 + j].abs() * tmag[j])
                                .sum::<f64>()
                    })
                    .sum::<f64>()
                    * f64::from(g.scale[col]).abs();
                let bound = ((2 * n2 + 2 * m + 8) as f64) * u * mag + 1e-30;
                let err = f64::from((fast[p][col] - full[p][col]).abs());
                assert!(
                    err <= bound,
                    "point {p} colour {col}: {} vs {} (bound {bound:e})",
                    fast[p][col],
                    full[p][col]
                );
            }
        }
        assert!(active > points / 4, "{active} active points");
        // Another point count is refused.
        let short = CpcaTransfer {
            cluster_of: &cluster_of[1..],
            weights: &weights[m..],
            ..vis
        };
        assert!(specular_cpca(&relighter, &input, &short, &lighting).is_err());
    }

    #[test]
    fn dot8_is_the_dot_product() {
        let a: Vec<f32> = (0..21).map(|i| i as f32 * 0.5).collect();
        let b: Vec<f32> = (0..21).map(|i| 2.0 - i as f32 * 0.25).collect();
        let want: f64 = a
            .iter()
            .zip(&b)
            .map(|(x, y)| f64::from(*x) * f64::from(*y))
            .sum();
        // Small integers and halves: every product and partial sum is exact in f32.
        assert_eq!(f64::from(dot8(&a, &b)), want);
    }
}
