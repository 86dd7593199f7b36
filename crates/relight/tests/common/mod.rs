//! Synthetic scenes shared by the tests and the benchmark: a sun-and-sky environment and
//! analytic transfer (clamped cosine about the normal times a visibility cap).
#![allow(dead_code)]

use glam::{DVec3, Vec3};
use prt_sh::{zonal, GauntTensor};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Legendre polynomials `P_0..P_lmax+1` at `x`.
pub fn legendre(x: f64, count: usize) -> Vec<f64> {
    let mut p = vec![0.0; count.max(2)];
    p[0] = 1.0;
    p[1] = x;
    for l in 1..count.max(2) - 1 {
        p[l + 1] = ((2 * l + 1) as f64 * x * p[l] - l as f64 * p[l - 1]) / (l + 1) as f64;
    }
    p.truncate(count);
    p
}

/// Zonal coefficients `g_l` of the indicator of the cap `ω·a ≥ cos_alpha`:
/// `g_l = 2π K_l ∫_{x0}^1 P_l(x) dx`, `K_l = √((2l+1)/4π)`, with `∫_{x0}^1 P_0 = 1 − x0` and
/// `∫_{x0}^1 P_l = (P_{l−1}(x0) − P_{l+1}(x0))/(2l+1)` for `l ≥ 1`.
pub fn cap_zonal(order: usize, cos_alpha: f64) -> Vec<f64> {
    let p = legendre(cos_alpha, order + 1);
    (0..order)
        .map(|l| {
            let k = ((2 * l + 1) as f64 / (4.0 * PI)).sqrt();
            let integral = if l == 0 {
                1.0 - cos_alpha
            } else {
                (p[l - 1] - p[l + 1]) / (2 * l + 1) as f64
            };
            2.0 * PI * k * integral
        })
        .collect()
}

/// Sun and sky: a sky of radiance `(0.25, 0.3, 0.4)·(1 + 0.6 ω_y)` (+Y up) and a sun, a
/// normalised Phong lobe of exponent 400 about `sun_dir` with total power `(2, 1.8, 1.5)`,
/// band-limited to `order`. Coefficients `[coeff][rgb]`.
pub fn sun_sky(order: usize, sun_dir: DVec3) -> Vec<[f64; 3]> {
    let sky = [0.25, 0.3, 0.4];
    let sun = [2.0, 1.8, 1.5];
    let mut c = vec![[0.0; 3]; order * order];
    let sun_bands = zonal::phong_lobe_bands(400.0, order).unwrap();
    let y = prt_sh::Basis::new(order).unwrap().eval(sun_dir.normalize());
    for i in 0..order * order {
        let (l, _) = prt_sh::degree_and_order(i);
        for ch in 0..3 {
            c[i][ch] = sun[ch] * sun_bands[l] * y[i];
        }
    }
    for ch in 0..3 {
        c[0][ch] += sky[ch] * (4.0 * PI).sqrt();
        // ω_y = −√(4π/3) y_1^{-1}.
        if order > 1 {
            c[1][ch] += -sky[ch] * 0.6 * (4.0 * PI / 3.0).sqrt();
        }
    }
    c
}

/// The visibility cap of a vertex: axis tilted from the normal toward +Y, half-angle varying
/// smoothly over the surface between 50° and 85°.
pub fn cap_of(p: Vec3, n: Vec3) -> (DVec3, f64) {
    let axis = (n.as_dvec3() + DVec3::new(0.0, 0.4, 0.0)).normalize();
    let s = 0.5 + 0.5 * (4.0 * f64::from(p.x) + 3.0 * f64::from(p.z)).sin();
    let alpha = (50.0 + 35.0 * s).to_radians();
    (axis, alpha.cos())
}

/// Synthetic transfer of `order` for each vertex, 1 channel:
/// visibility `V = cap` and diffuse `T = (clamped cosine about n) ⊛ V` (Gaunt product at this
/// order). Returns `(diffuse, visibility)`, `[vertex][coeff]` flattened.
pub fn synthetic_transfer(
    positions: &[Vec3],
    normals: &[Vec3],
    order: usize,
) -> (Vec<f32>, Vec<f32>) {
    let gaunt = GauntTensor::new(order).unwrap();
    let cosine = zonal::bands_to_zonal(&zonal::clamped_cosine_bands(order).unwrap());
    let n2 = order * order;
    let per_vertex: Vec<(Vec<f32>, Vec<f32>)> = positions
        .par_iter()
        .zip(normals)
        .map(|(p, n)| {
            let (axis, cos_alpha) = cap_of(*p, *n);
            let vis = zonal::rotate_zonal(&cap_zonal(order, cos_alpha), axis).unwrap();
            let cos = zonal::rotate_zonal(&cosine, n.as_dvec3()).unwrap();
            let t = gaunt.product(&cos, &vis).unwrap();
            (
                t.iter().map(|v| *v as f32).collect(),
                vis.iter().map(|v| *v as f32).collect(),
            )
        })
        .collect();
    let mut d = Vec::with_capacity(positions.len() * n2);
    let mut v = Vec::with_capacity(positions.len() * n2);
    for (a, b) in per_vertex {
        d.extend(a);
        v.extend(b);
    }
    (d, v)
}

/// Keeps the first `order²` of every `from²` coefficients.
pub fn truncate_points(data: &[f32], from: usize, order: usize) -> Vec<f32> {
    data.chunks_exact(from * from)
        .flat_map(|c| c[..order * order].iter().copied())
        .collect()
}

/// Vertex arrays of a mesh as `[f32; 3]`.
pub fn arrays(mesh: &prt_scene::Mesh) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
    (
        mesh.positions.iter().map(|p| p.to_array()).collect(),
        mesh.normals.iter().map(|n| n.to_array()).collect(),
    )
}
