//! The Monte Carlo estimators.
//!
//! With `R` cosine-distributed directions `ω_k` (pdf `cos θ/π`) the shadowed diffuse transfer
//! `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω` is estimated by `(π/R) Σ_k V(ω_k) y_i(ω_k)`; with `R`
//! uniform directions over the hemisphere of `n` (pdf `1/2π`) the visibility transfer
//! `V_i = ∫ V(ω) y_i(ω) dω` (with `V = 0` below the tangent plane: light from there cannot
//! reach the front face) by `(2π/R) Σ_k V(ω_k) y_i(ω_k)`.
//!
//! Interreflection (Sloan, Kautz & Snyder 2002): a ray of point `p` that hits surface point
//! `q` brings `q`'s outgoing radiance `(a_q/π) Σ_i L_i T^{b−1}_{q,i}` with `T^{b−1}_q`
//! interpolated from `q`'s triangle vertices by the hit's barycentrics, so the next bounce is
//! `T^b_{p,i} = (π/R) Σ_{hits} (a_q/π) T^{b−1}_{q,i} = (1/R) Σ_{hits} a_q T^{b−1}_{q,i}`,
//! RGB through the albedos `a_q` (the diffuse albedo of `q`'s material at the hit, textures
//! and vertex colours applied; glossy lobes of
//! intermediate surfaces are not represented). Rays that hit the back of a surface bring
//! nothing (the transfer of `q` describes its front side) and are counted in the report.

use glam::Vec3;
use prt_sh::Basis;
use prt_shading::{sample_cosine_hemisphere, sample_uniform_hemisphere, Frame};
use prt_tracer::points::SamplePoint;
use prt_tracer::sequence::{SequencePurpose, R2};
use prt_tracer::Accel;
use std::f64::consts::PI;

/// A ray of a point that hit the scene: where, for the bounce gathering.
#[derive(Clone, Copy, Debug)]
pub struct HitRecord {
    /// Mesh index.
    pub mesh: u32,
    /// Triangle index in the mesh.
    pub tri: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
}

/// What the direct pass measured at one point.
#[derive(Clone, Debug, Default)]
pub struct DirectResult {
    /// Shadowed diffuse transfer, `order²` values.
    pub shadowed: Vec<f64>,
    /// Visibility transfer when asked for.
    pub visibility: Option<Vec<f64>>,
    /// Front-face hits (only recorded when bounces follow).
    pub hits: Vec<HitRecord>,
    /// Rays that hit something.
    pub hit_count: u32,
    /// Rays that hit the back of a surface.
    pub backface_hits: u32,
}

/// Options of [`direct`].
#[derive(Clone, Copy, Debug)]
pub struct DirectOptions<'a> {
    /// Rays per transfer kind.
    pub rays: u32,
    /// Record hits for bounces.
    pub record_hits: bool,
    /// Also estimate visibility transfer.
    pub visibility: bool,
    /// Seed.
    pub seed: u64,
    /// Key of the point's object (part of the sequence key).
    pub object: u64,
    /// Index of the first ray in the point's sequence: the rays are points
    /// `first_ray .. first_ray + rays` of it. A per-pixel bake gives each footprint sample its
    /// own contiguous block of the pixel's sequence, so that together they trace one
    /// low-discrepancy set (independent sequences per sample would be no better than random).
    pub first_ray: u32,
    /// The basis of the point's order.
    pub basis: &'a Basis,
}

/// Closest front-face hit along a ray from `point`, skipping a back face met within a few
/// offsets of the origin. Such a hit happens at vertices that lie on another surface (the
/// edge where a floor meets a wall): offsetting along the vertex's own normal leaves the
/// origin on the other surface's plane, and rays that *leave* that surface report it at
/// `t ≈ 0`. Rays that enter it (a front face at `t ≈ 0`) are genuinely blocked and kept.
pub(crate) fn trace(accel: &Accel, point: &SamplePoint, dir: Vec3) -> Option<prt_tracer::Hit> {
    let mut origin = point.origin(dir);
    for _ in 0..4 {
        let hit = accel.closest_hit(origin, dir, f32::INFINITY)?;
        let near = hit.t <= 4.0 * point.offset.max(hit.offset);
        if near && hit.shading_normal.dot(dir) > 0.0 {
            origin = hit.spawn_origin(dir);
            continue;
        }
        return Some(hit);
    }
    None
}

/// The direct pass at one point: shadowed (and visibility) transfer, hits for bounces.
#[must_use]
pub fn direct(
    accel: &Accel,
    point: &SamplePoint,
    index: u64,
    opt: &DirectOptions<'_>,
) -> DirectResult {
    direct_sided(accel, point, index, opt, None)
}

/// [`direct`] at a normal-mapped point: `point.normal` is the normal map's shading normal
/// (the cosine and the hemisphere sampled), and directions below the geometric surface
/// `geometric` (unit, on the side baked) are blocked without a ray — they would pass through
/// the surface, which is the path tracer's rule for every vertex. `None`: [`direct`].
pub(crate) fn direct_sided(
    accel: &Accel,
    point: &SamplePoint,
    index: u64,
    opt: &DirectOptions<'_>,
    geometric: Option<Vec3>,
) -> DirectResult {
    let below = |dir: Vec3| geometric.is_some_and(|g| g.dot(dir) <= 0.0);
    let n2 = opt.basis.len();
    let frame = Frame::from_normal(point.normal);
    let mut y = vec![0.0f32; n2];
    let mut sum = vec![0.0f64; n2];
    let mut res = DirectResult::default();
    let seq = R2::new(opt.seed, SequencePurpose::Diffuse, opt.object, index);
    for k in 0..opt.rays {
        let dir = frame
            .to_world(sample_cosine_hemisphere(seq.get(opt.first_ray + k)))
            .normalize();
        let blocked = below(dir)
            || match trace(accel, point, dir) {
                Some(hit) => {
                    res.hit_count += 1;
                    if hit.shading_normal.dot(dir) > 0.0 {
                        res.backface_hits += 1;
                    } else if opt.record_hits {
                        res.hits.push(HitRecord {
                            mesh: hit.mesh,
                            tri: hit.tri,
                            u: hit.u,
                            v: hit.v,
                        });
                    }
                    true
                }
                None => false,
            };
        if !blocked {
            opt.basis.eval_f32_unchecked(dir, &mut y);
            for (s, v) in sum.iter_mut().zip(&y) {
                *s += f64::from(*v);
            }
        }
    }
    let w = PI / f64::from(opt.rays);
    res.shadowed = sum.iter().map(|s| s * w).collect();
    if opt.visibility {
        let seq = R2::new(opt.seed, SequencePurpose::Visibility, opt.object, index);
        sum.iter_mut().for_each(|s| *s = 0.0);
        for k in 0..opt.rays {
            let dir = frame
                .to_world(sample_uniform_hemisphere(seq.get(opt.first_ray + k)))
                .normalize();
            if !below(dir) && trace(accel, point, dir).is_none() {
                opt.basis.eval_f32_unchecked(dir, &mut y);
                for (s, v) in sum.iter_mut().zip(&y) {
                    *s += f64::from(*v);
                }
            }
        }
        let w = 2.0 * PI / f64::from(opt.rays);
        res.visibility = Some(sum.iter().map(|s| s * w).collect());
    }
    res
}

/// RGB transfer of one bounce of every vertex of one mesh, f32, `[vertex][channel][coeff]`.
#[derive(Clone, Debug, Default)]
pub struct MeshTransfer {
    /// Order of the mesh's transfer.
    pub order: usize,
    /// `vertices × 3 × order²` values.
    pub data: Vec<f32>,
}

/// What the gathering needs to know about the meshes.
pub struct GatherScene<'a> {
    /// Triangles of each mesh.
    pub indices: Vec<&'a [[u32; 3]]>,
    /// Diffuse albedo of each mesh's material (its factors, for a textured one).
    pub albedo: Vec<[f32; 3]>,
    /// The scene, for the meshes whose material varies over the surface (textures, vertex
    /// colours): their albedo is read at each hit.
    pub scene: &'a prt_scene::Scene,
    /// Whether each mesh's material varies ([`prt_scene::Scene::material_varies`]).
    pub varies: Vec<bool>,
}

impl GatherScene<'_> {
    /// The diffuse albedo at a hit.
    fn albedo_at(&self, h: &HitRecord) -> [f32; 3] {
        let m = h.mesh as usize;
        if self.varies[m] {
            let at = prt_scene::SurfacePoint::Triangle {
                tri: h.tri,
                u: h.u,
                v: h.v,
            };
            self.scene.material_at(m, at).albedo()
        } else {
            self.albedo[m]
        }
    }
}

/// One bounce at one point: `(1/R) Σ_hits a_q T^{b−1}_q(u, v)`, RGB, `3 × order²` values
/// (`[channel][coeff]`), for a point of order `order`.
#[must_use]
pub fn gather(
    hits: &[HitRecord],
    rays: u32,
    prev: &[MeshTransfer],
    scene: &GatherScene<'_>,
    order: usize,
) -> Vec<f64> {
    let n2 = order * order;
    let mut out = vec![0.0f64; 3 * n2];
    for h in hits {
        let mt = &prev[h.mesh as usize];
        let m2 = mt.order * mt.order;
        let k = n2.min(m2);
        let tri = scene.indices[h.mesh as usize][h.tri as usize];
        let w = [1.0 - h.u - h.v, h.u, h.v];
        let a = scene.albedo_at(h);
        for (corner, wc) in tri.iter().zip(w) {
            let base = *corner as usize * 3 * m2;
            for c in 0..3 {
                let f = f64::from(a[c] * wc);
                let src = &mt.data[base + c * m2..base + c * m2 + k];
                for (o, s) in out[c * n2..c * n2 + k].iter_mut().zip(src) {
                    *o += f * f64::from(*s);
                }
            }
        }
    }
    let inv = 1.0 / f64::from(rays);
    out.iter_mut().for_each(|v| *v *= inv);
    out
}

/// The analytic unshadowed diffuse transfer at a normal: the clamped-cosine zonal lobe rotated
/// to `n` (no rays).
#[must_use]
pub fn unshadowed(order: usize, n: Vec3) -> Vec<f64> {
    let g = prt_sh::zonal::bands_to_zonal(
        &prt_sh::zonal::clamped_cosine_bands(order).expect("order checked"),
    );
    prt_sh::zonal::rotate_zonal(&g, n.as_dvec3()).expect("order checked")
}

/// The running totals a vertex's bounces start from: its shadowed transfer in each of the
/// three channels (f64, as the gathers add to it).
pub(crate) fn level0_totals(shadowed: &[f64]) -> Vec<f64> {
    shadowed
        .iter()
        .cycle()
        .take(3 * shadowed.len())
        .copied()
        .collect()
}
