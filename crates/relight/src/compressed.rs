//! Diffuse relighting straight from clustered-PCA transfer (Sloan, Hall, Hart & Snyder 2003):
//! exit radiance is linear in the transfer vector, so per frame each cluster's mean and basis
//! vectors are relit once (`K × (M + 1)` dot products of `order²` terms per colour), and each
//! point costs `M` multiply-adds per colour — instead of `order²` for the full vectors.

use crate::error::RelightError;
use crate::input::{DiffuseParams, Lighting};
use rayon::prelude::*;

/// A diffuse transfer block in clustered-PCA form (the bake file's `CPCA` section): point `p`
/// of cluster `k` is `mean_k + Σ_j weights[p][j] · basis_{k,j}`, each row `channels × order²`
/// scalars laid out `[channel][coefficient]`.
#[derive(Clone, Copy, Debug)]
pub struct CpcaTransfer<'a> {
    /// SH order of the stored rows.
    pub order: usize,
    /// 1 (the same transfer for the three colours) or 3.
    pub channels: usize,
    /// Clusters `K`.
    pub clusters: usize,
    /// Basis vectors per cluster `M`.
    pub components: usize,
    /// `K × (M + 1)` rows: per cluster its mean, then its basis vectors.
    pub centres: &'a [f32],
    /// Per point, its cluster.
    pub cluster_of: &'a [u32],
    /// `points × M` weights.
    pub weights: &'a [f32],
}

/// Points per parallel chunk.
const CHUNK: usize = 1024;

/// Checks a clustered-PCA block for relighting at `order` under lighting of `lighting_order`:
/// the order within both, 1 or 3 channels, the table and weight sizes, the cluster indices.
pub(crate) fn check_cpca(
    order: usize,
    t: &CpcaTransfer<'_>,
    lighting_order: usize,
) -> Result<(), RelightError> {
    let d = t.channels * t.order * t.order;
    let rows = t.clusters * (t.components + 1);
    if order == 0 || order > t.order || order > lighting_order {
        return Err(RelightError::InvalidParameter(format!(
            "order {order} for transfer of order {} under lighting of order {lighting_order}",
            t.order
        )));
    }
    if !(t.channels == 1 || t.channels == 3)
        || t.centres.len() != rows * d
        || t.weights.len() != t.cluster_of.len() * t.components
    {
        return Err(RelightError::InvalidParameter(format!(
            "clustered PCA of {} clusters × {} components with {} values for dimension {d}, {} weights for {} points",
            t.clusters,
            t.components,
            t.centres.len(),
            t.weights.len(),
            t.cluster_of.len()
        )));
    }
    if let Some(p) = t.cluster_of.iter().position(|&k| k as usize >= t.clusters) {
        return Err(RelightError::InvalidParameter(format!(
            "point {p} is in cluster {} of {}",
            t.cluster_of[p], t.clusters
        )));
    }
    Ok(())
}

/// Relights every point of `t` at order `order` (at most the transfer's and the lighting's)
/// under `lighting`: `(albedo/π) · (L · t̃_p)` per colour, with `t̃_p` the clustered-PCA
/// approximation — equal, up to f32 rounding, to relighting the reconstructed vectors.
///
/// # Errors
/// Inconsistent sizes, an order beyond the transfer's or the lighting's, a cluster index out
/// of range, or non-finite parameters.
pub fn diffuse_cpca(
    order: usize,
    t: &CpcaTransfer<'_>,
    lighting: &Lighting,
    params: &DiffuseParams,
) -> Result<Vec<[f32; 3]>, RelightError> {
    check_cpca(order, t, lighting.order)?;
    let (b2, n2) = (t.order * t.order, order * order);
    let d = t.channels * b2;
    let rows = t.clusters * (t.components + 1);
    if params.albedo_over_pi.iter().any(|a| !a.is_finite()) {
        return Err(RelightError::NonFinite("albedo/π"));
    }
    // Each cluster row relit once: table[row][colour].
    let table: Vec<[f32; 3]> = (0..rows)
        .map(|r| {
            let row = &t.centres[r * d..(r + 1) * d];
            let mut v = [0.0f32; 3];
            for (c, out) in v.iter_mut().enumerate() {
                let ch = if t.channels == 3 { c } else { 0 };
                let coeffs = &row[ch * b2..ch * b2 + n2];
                *out = coeffs
                    .iter()
                    .zip(&lighting.rgb[c][..n2])
                    .map(|(a, b)| a * b)
                    .sum::<f32>()
                    * params.albedo_over_pi[c];
            }
            v
        })
        .collect();
    let m = t.components;
    let mut out = vec![[0.0f32; 3]; t.cluster_of.len()];
    out.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each(|(ci, chunk)| {
            for (i, o) in chunk.iter_mut().enumerate() {
                let p = ci * CHUNK + i;
                let base = t.cluster_of[p] as usize * (m + 1);
                let mut v = table[base];
                for (j, &w) in t.weights[p * m..(p + 1) * m].iter().enumerate() {
                    let b = table[base + 1 + j];
                    for c in 0..3 {
                        v[c] += w * b[c];
                    }
                }
                *o = v;
            }
        });
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Relighter, TransferView};

    /// The compressed path equals relighting the reconstructed vectors with the full kernel,
    /// within the f32 rounding of both: `(n² + 2M + 4)·u` times the sum of the magnitudes of
    /// the products involved (u = 2⁻²⁴), for 1- and 3-channel transfer and a lower order.
    #[test]
    fn equals_relighting_the_reconstruction() {
        let (k, m, baked) = (3usize, 4usize, 5usize);
        let b2 = baked * baked;
        for channels in [1usize, 3] {
            let d = channels * b2;
            let centres: Vec<f32> = (0..k * (m + 1) * d)
                .map(|i| ((i * 37 % 101) as f32 / 101.0 - 0.5) * 2.0)
                .collect();
            let points = 50;
            let cluster_of: Vec<u32> = (0..points).map(|p| (p * 7 % k) as u32).collect();
            let weights: Vec<f32> = (0..points * m)
                .map(|i| ((i * 13 % 17) as f32 - 8.0) / 4.0)
                .collect();
            // The reconstruction, as SPEC §3.13 computes it.
            let mut data = Vec::new();
            for (p, &c) in cluster_of.iter().enumerate() {
                let row = |r: usize| &centres[(c as usize * (m + 1) + r) * d..][..d];
                let start = data.len();
                data.extend_from_slice(row(0));
                for j in 0..m {
                    for (o, &b) in data[start..].iter_mut().zip(row(1 + j)) {
                        *o += weights[p * m + j] * b;
                    }
                }
            }
            let coeffs: Vec<[f64; 3]> = (0..b2)
                .map(|i| [1.0 / (1.0 + i as f64), 0.5 - 0.05 * i as f64, 0.3])
                .collect();
            let lighting = Lighting::from_rgb_coefficients(&coeffs, None).unwrap();
            let params = DiffuseParams::from_albedo([0.8, 0.5, 0.3]);
            for order in [baked, 3] {
                let t = CpcaTransfer {
                    order: baked,
                    channels,
                    clusters: k,
                    components: m,
                    centres: &centres,
                    cluster_of: &cluster_of,
                    weights: &weights,
                };
                let fast = diffuse_cpca(order, &t, &lighting, &params).unwrap();
                let lit = lighting.truncated(order).unwrap();
                let relighter = Relighter::new(order).unwrap();
                let frame = relighter.frame_lighting(&lit, false).unwrap();
                let truncated: Vec<f32> = data
                    .chunks_exact(b2)
                    .flat_map(|ch| ch[..order * order].iter().copied())
                    .collect();
                let view = TransferView::new(order, channels, &truncated).unwrap();
                let full = relighter.diffuse(&view, &frame, &params).unwrap();
                let u = f64::from(f32::EPSILON) / 2.0;
                for p in 0..points {
                    let c = cluster_of[p] as usize;
                    for col in 0..3 {
                        let ch = if channels == 3 { col } else { 0 };
                        let mag: f64 = (0..order * order)
                            .map(|i| {
                                let at = |r: usize| {
                                    f64::from(centres[(c * (m + 1) + r) * d + ch * b2 + i]).abs()
                                };
                                (at(0)
                                    + (0..m)
                                        .map(|j| f64::from(weights[p * m + j]).abs() * at(1 + j))
                                        .sum::<f64>())
                                    * f64::from(lighting.rgb[col][i]).abs()
                            })
                            .sum::<f64>()
                            * f64::from(params.albedo_over_pi[col]);
                        let bound = ((order * order + 2 * m + 4) as f64) * u * mag + 1e-30;
                        let err = f64::from((fast[p][col] - full[p][col]).abs());
                        assert!(err <= bound, "channels {channels} order {order} point {p}: {} vs {} (bound {bound:e})", fast[p][col], full[p][col]);
                    }
                }
            }
        }
    }

    #[test]
    fn bad_input_is_an_error() {
        let lighting = Lighting::from_rgb_coefficients(&[[1.0; 3]; 4], None).unwrap();
        let params = DiffuseParams::from_albedo([1.0; 3]);
        let centres = vec![0.0f32; 2 * 4];
        let t = CpcaTransfer {
            order: 2,
            channels: 1,
            clusters: 1,
            components: 1,
            centres: &centres,
            cluster_of: &[1],
            weights: &[0.0],
        };
        assert!(diffuse_cpca(2, &t, &lighting, &params).is_err());
        let t = CpcaTransfer {
            cluster_of: &[0],
            ..t
        };
        assert!(diffuse_cpca(2, &t, &lighting, &params).is_ok());
        assert!(diffuse_cpca(3, &t, &lighting, &params).is_err());
    }
}
