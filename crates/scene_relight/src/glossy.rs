//! Specular relighting of isotropic glossy BRDFs without a zonal form (Blinn–Phong, Ward,
//! Cook–Torrance) from the bake's per-view-elevation BRDF projections (Kautz, Sloan & Snyder
//! 2002, "Fast, arbitrary BRDF shading for low-frequency lighting using spherical harmonics").
//!
//! At a point with normal `n` and view direction `ω_o`, the incident radiance is `R = L ⊛ V`
//! (the SH product of lighting and the point's visibility, Gaunt tensor), rotated into the
//! point's local frame (normal → +Z, the view's azimuth → φ = 0) with one SH rotation, and
//! dotted with the BRDF row of the view elevation `θ_o` (linear interpolation between the
//! tabulated elevations): `L_s = specular ⊙ Σ_i R^local_i b_i(θ_o)`, where `b` is the projection
//! of `f_s(ω_i, ω_o) max(0, cos θ_i)` with unit specular colour. Exact up to the truncation of
//! `R` and `b` to the order (no frozen cosine, unlike the zonal Phong path). Cost per point:
//! one Gaunt product per channel and one rotation, O(order⁵) to O(order⁴) — a reference-grade
//! path, not a real-time one.

use crate::error::SceneRelightError;
use glam::{DMat3, DVec3};
use prt_bakefile::GlossyBrdfTable;
use prt_sh::{GauntTensor, Rotation};
use rayon::prelude::*;

/// The BRDF row at view elevation `theta_o` (radians), linearly interpolated and clamped to
/// the tabulated range.
#[must_use]
pub fn table_row(table: &GlossyBrdfTable, order: usize, theta_o: f64) -> Vec<f64> {
    let n2 = (table.order * table.order) as usize;
    let k = order * order;
    let e = &table.elevations;
    let row = |i: usize| &table.values[i * n2..i * n2 + k];
    if theta_o <= e[0] {
        return row(0).to_vec();
    }
    if theta_o >= e[e.len() - 1] {
        return row(e.len() - 1).to_vec();
    }
    let i = e.partition_point(|&t| t <= theta_o) - 1;
    let t = (theta_o - e[i]) / (e[i + 1] - e[i]);
    row(i)
        .iter()
        .zip(row(i + 1))
        .map(|(a, b)| a + t * (b - a))
        .collect()
}

/// World-to-local rotation: rows are the local axes (x toward the view's azimuth, z = n).
#[must_use]
pub fn local_frame(n: DVec3, wo: DVec3) -> DMat3 {
    let z = n.normalize();
    let mut x = wo - z * wo.dot(z);
    if x.length_squared() < 1e-20 {
        x = z.any_orthonormal_vector();
    }
    let x = x.normalize();
    let y = z.cross(x);
    DMat3::from_cols(x, y, z).transpose()
}

/// Specular radiance of every point: `specular ⊙ Σ_i (D(M) (L_c ⊛ V))_i b_i(θ_o)`.
///
/// `lighting` is `[coeff][channel]` of at least `order²`; `visibility` is one channel of
/// `order²` per point; points facing away from the viewer get 0.
pub fn glossy_specular(
    table: &GlossyBrdfTable,
    order: usize,
    lighting: &[[f64; 3]],
    visibility: &[f32],
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    eye: [f32; 3],
    specular: [f32; 3],
) -> Result<Vec<[f32; 3]>, SceneRelightError> {
    let s = glossy_components(
        &[table],
        order,
        lighting,
        visibility,
        positions,
        normals,
        eye,
    )?;
    Ok(s[0]
        .iter()
        .map(|v| std::array::from_fn(|c| (f64::from(specular[c]) * v[c]).max(0.0) as f32))
        .collect())
}

/// The unweighted `Σ_i (D(M) (L_c ⊛ V))_i b^k_i(θ_o)` of every table `k` at every point
/// (one Gaunt product and one rotation per point, shared by the tables): per table, per
/// point, RGB in f64, not clamped. Points facing away get 0.
pub fn glossy_components(
    tables: &[&GlossyBrdfTable],
    order: usize,
    lighting: &[[f64; 3]],
    visibility: &[f32],
    positions: &[[f32; 3]],
    normals: &[[f32; 3]],
    eye: [f32; 3],
) -> Result<Vec<Vec<[f64; 3]>>, SceneRelightError> {
    if let Some(t) = tables
        .iter()
        .find(|t| order > t.order as usize || order > prt_sh::MAX_GAUNT_ORDER)
    {
        return Err(SceneRelightError::Invalid(format!(
            "glossy relighting at order {order}: the BRDF table has order {} (Gaunt products up to {})",
            t.order,
            prt_sh::MAX_GAUNT_ORDER
        )));
    }
    let n2 = order * order;
    let gaunt = GauntTensor::new(order)?;
    let light: Vec<Vec<f64>> = (0..3)
        .map(|c| lighting[..n2].iter().map(|v| v[c]).collect())
        .collect();
    let eye = DVec3::from_array(eye.map(f64::from));
    let per_point: Vec<Vec<[f64; 3]>> = (0..normals.len())
        .into_par_iter()
        .map(|p| {
            let mut out = vec![[0.0f64; 3]; tables.len()];
            let n = DVec3::from_array(normals[p].map(f64::from)).normalize_or_zero();
            let wo = (eye - DVec3::from_array(positions[p].map(f64::from))).normalize_or_zero();
            let cos_o = n.dot(wo);
            if cos_o.is_nan() || cos_o <= 0.0 {
                return Ok(out);
            }
            let v: Vec<f64> = visibility[p * n2..(p + 1) * n2]
                .iter()
                .map(|x| f64::from(*x))
                .collect();
            let rot = Rotation::new(order, local_frame(n, wo))?;
            let theta_o = cos_o.clamp(-1.0, 1.0).acos();
            let rows: Vec<Vec<f64>> = tables
                .iter()
                .map(|t| table_row(t, order, theta_o))
                .collect();
            for c in 0..3 {
                let r = gaunt.product(&light[c], &v)?;
                let local = rot.apply(&r)?;
                for (o, b) in out.iter_mut().zip(&rows) {
                    o[c] = local.iter().zip(b).map(|(a, b)| a * b).sum();
                }
            }
            Ok(out)
        })
        .collect::<Result<_, SceneRelightError>>()?;
    Ok((0..tables.len())
        .map(|k| per_point.iter().map(|p| p[k]).collect())
        .collect())
}
