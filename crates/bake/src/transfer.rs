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
//!
//! A point's rays are traced as packets of eight (`Accel::closest_hits`) in the order of the
//! Morton cell of their sample points, so that a packet's directions lie close together; the
//! hits come back in the sequence's order and are summed in it, so the estimate is the same,
//! bit for bit, as tracing the rays one by one.

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

/// The closest front-face hit along `dir` from `point`, given the first hit from the point's
/// own origin: a back face met within a few offsets of the origin is skipped. Such a hit
/// happens at vertices that lie on another surface (the edge where a floor meets a wall):
/// offsetting along the vertex's own normal leaves the origin on the other surface's plane,
/// and rays that *leave* that surface report it at `t ≈ 0`. Rays that enter it (a front face
/// at `t ≈ 0`) are genuinely blocked and kept.
fn resolve(
    accel: &Accel,
    point: &SamplePoint,
    dir: Vec3,
    first: Option<prt_tracer::Hit>,
) -> Option<prt_tracer::Hit> {
    let leaving = |h: &prt_tracer::Hit| {
        h.t <= 4.0 * point.offset.max(h.offset) && h.shading_normal.dot(dir) > 0.0
    };
    let mut hit = first?;
    for _ in 1..4 {
        if !leaving(&hit) {
            return Some(hit);
        }
        hit = accel.closest_hit(hit.spawn_origin(dir), dir, f32::INFINITY)?;
    }
    (!leaving(&hit)).then_some(hit)
}

/// The hits of many rays of one point, as [`resolve`] takes them: `out[k]` for `dirs[k]`
/// (`None` also where `skip[k]`), the same hits, bit for bit, as one ray at a time. The rays are traced in packets in the order of the cells
/// `cells[k]` of their sample points (a Morton index of the unit square, so that a packet's
/// directions lie close together and share most of the BVH nodes they visit).
pub(crate) fn trace_point(
    accel: &Accel,
    point: &SamplePoint,
    dirs: &[Vec3],
    cells: &[u8],
    skip: &[bool],
    scratch: &mut TraceScratch,
) {
    let TraceScratch {
        order,
        origins,
        sorted,
        hits,
        out,
    } = scratch;
    // A counting sort by cell: stable, so equal cells keep the sequence's order.
    let mut start = [0u32; 257];
    for (&c, &s) in cells.iter().zip(skip) {
        if !s {
            start[usize::from(c) + 1] += 1;
        }
    }
    for i in 0..256 {
        start[i + 1] += start[i];
    }
    order.resize(start[256] as usize, 0);
    for (k, (&c, &s)) in cells.iter().zip(skip).enumerate() {
        if !s {
            let slot = &mut start[usize::from(c)];
            order[*slot as usize] = k as u32;
            *slot += 1;
        }
    }
    origins.clear();
    sorted.clear();
    for &k in order.iter() {
        let d = dirs[k as usize];
        origins.push(point.origin(d));
        sorted.push(d);
    }
    hits.clear();
    hits.resize(order.len(), None);
    accel.closest_hits(origins, sorted, f32::INFINITY, hits);
    out.clear();
    out.resize(dirs.len(), None);
    for (&k, &h) in order.iter().zip(hits.iter()) {
        out[k as usize] = resolve(accel, point, dirs[k as usize], h);
    }
}

/// Buffers of [`trace_point`], reused from point to point.
#[derive(Default)]
pub(crate) struct TraceScratch {
    order: Vec<u32>,
    origins: Vec<Vec3>,
    sorted: Vec<Vec3>,
    hits: Vec<Option<prt_tracer::Hit>>,
    /// The result: the hit of each ray, in the rays' order.
    pub(crate) out: Vec<Option<prt_tracer::Hit>>,
}

/// The Morton index of the 16 × 16 cell of the unit square that `u` falls in.
pub(crate) fn morton_cell(u: [f32; 2]) -> u8 {
    let spread = |x: f32| {
        let v = ((x * 16.0) as u32).min(15);
        (v & 1) | (v & 2) << 1 | (v & 4) << 2 | (v & 8) << 3
    };
    (spread(u[0]) | spread(u[1]) << 1) as u8
}

/// The directions of a point's rays (`warp` of the sequence's points), their cells and
/// whether each is blocked without a ray (`below`).
fn point_rays(
    frame: &Frame,
    seq: &R2,
    first: u32,
    rays: u32,
    warp: fn([f32; 2]) -> Vec3,
    below: impl Fn(Vec3) -> bool,
) -> (Vec<Vec3>, Vec<u8>, Vec<bool>) {
    let mut dirs = Vec::with_capacity(rays as usize);
    let mut cells = Vec::with_capacity(rays as usize);
    let mut skip = Vec::with_capacity(rays as usize);
    for k in 0..rays {
        let u = seq.get(first + k);
        let dir = frame.to_world(warp(u)).normalize();
        dirs.push(dir);
        cells.push(morton_cell(u));
        skip.push(below(dir));
    }
    (dirs, cells, skip)
}

/// The rays `first .. first + count` of `seq` (directions by `warp` in `frame`) traced from
/// `point` into `scratch.out`; returns their directions and which are blocked without a ray
/// (`below`).
fn trace_rays(
    accel: &Accel,
    point: &SamplePoint,
    frame: &Frame,
    (seq, first, count): (&R2, u32, u32),
    warp: fn([f32; 2]) -> Vec3,
    below: impl Fn(Vec3) -> bool,
    scratch: &mut TraceScratch,
) -> (Vec<Vec3>, Vec<bool>) {
    let (dirs, cells, skip) = point_rays(frame, seq, first, count, warp, below);
    trace_point(accel, point, &dirs, &cells, &skip, scratch);
    (dirs, skip)
}

/// Adds the basis functions at `dir` to `sum` (`y`: scratch of the basis' length).
fn add_basis(basis: &Basis, dir: Vec3, y: &mut [f32], sum: &mut [f64]) {
    basis.eval_f32_unchecked(dir, y);
    for (s, v) in sum.iter_mut().zip(y.iter()) {
        *s += f64::from(*v);
    }
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
    let mut scratch = TraceScratch::default();
    let mut traced = |purpose: SequencePurpose, warp: fn([f32; 2]) -> Vec3| {
        let seq = R2::new(opt.seed, purpose, opt.object, index);
        let rays = (&seq, opt.first_ray, opt.rays);
        let (dirs, skip) = trace_rays(accel, point, &frame, rays, warp, below, &mut scratch);
        (dirs, skip, std::mem::take(&mut scratch.out))
    };
    let (dirs, skip, hits) = traced(SequencePurpose::Diffuse, sample_cosine_hemisphere);
    for ((&dir, &below), hit) in dirs.iter().zip(&skip).zip(&hits) {
        let blocked = below
            || match hit {
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
            add_basis(opt.basis, dir, &mut y, &mut sum);
        }
    }
    let w = PI / f64::from(opt.rays);
    res.shadowed = sum.iter().map(|s| s * w).collect();
    if opt.visibility {
        sum.iter_mut().for_each(|s| *s = 0.0);
        let (dirs, skip, hits) = traced(SequencePurpose::Visibility, sample_uniform_hemisphere);
        for ((&dir, &below), hit) in dirs.iter().zip(&skip).zip(&hits) {
            if !below && hit.is_none() {
                add_basis(opt.basis, dir, &mut y, &mut sum);
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
    #[cfg(target_arch = "x86_64")]
    if std::arch::is_x86_feature_detected!("avx2") {
        #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
        unsafe {
            return gather_avx2(hits, rays, prev, scene, order);
        }
    }
    gather_body(hits, rays, prev, scene, order)
}

/// [`gather`] compiled for AVX2 (four f64 multiply-adds to an instruction; the same separate
/// multiplies and adds, so the same sums).
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // `#[target_feature]`, called only after detection.
#[target_feature(enable = "avx2")]
unsafe fn gather_avx2(
    hits: &[HitRecord],
    rays: u32,
    prev: &[MeshTransfer],
    scene: &GatherScene<'_>,
    order: usize,
) -> Vec<f64> {
    gather_body(hits, rays, prev, scene, order)
}

/// The body of [`gather`].
#[inline(always)]
fn gather_body(
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
