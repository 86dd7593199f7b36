//! Ray/triangle acceleration over every triangle of a scene: obvhs CWBVHs with the known
//! obvhs 0.4.0 defects worked around (see `FACTS.md`), precise relative to **each object**.
//!
//! **Layout.** Objects (meshes) are put into *groups* of similar scale: an object joins a group
//! when the group's box, with the object added, is at most [`GROUP_RATIO`] times the object's own
//! extent (objects are taken largest first), so a 1 mm part on a 10 m floor gets a group of its
//! own while a bunny on a 4 m floor shares one. Each group has its own CWBVH, built and
//! traversed in the group's own space: translated to the group's centre and scaled by a power
//! of two so its largest absolute coordinate lands in `[32, 64)`. Everything that obvhs does
//! relative to the size of its space — box padding, quantisation, its fixed node `tmin` — is
//! therefore relative to the group, i.e. to the object, not to the largest object of the scene.
//! Rays visit the groups whose (f64) world boxes they cross, nearest first (the boxes are
//! clipped four at a time where the CPU has AVX2, `group_clip`, with the scalar clip's
//! numbers); a ray reaches a group's space starting at its box entry point (in f64), so the
//! local origin is as precise as the group's own coordinates however far away the ray
//! started.
//!
//! **Exact triangle tests.** obvhs only *proposes* candidates: every ray/triangle test is done
//! here in f64 on the world-space f32 vertices (exact in f64) with the world-space f32 ray
//! (Möller–Trumbore; rounding errors of order `1e-16` of the triangle's size and distance). The
//! sign of a hit distance therefore no longer depends on how large the triangle or the scene
//! is, and ray offsets only have to cover the f32 rounding of the hit point itself
//! ([`SPAWN_RELATIVE_OFFSET`]): a point on a 30 m floor next to a 1 mm part is offset by a few
//! nanometres, not by a tenth of the part (the black ring such an offset leaves around the
//! part's base is what the workspace's `tests/hard_cases.rs` pins).
//!
//! **Packets.** [`Accel::closest_hits`] traces rays eight at a time through each group they
//! reach, nearest group first (`traverse::closest_packet`; Wald et al. 2001), and tests a candidate triangle that two or
//! more of them reach against all of them at once ([`PacketRays`]: the f64 Möller–Trumbore
//! formulas lane by lane, with no fused multiply-add, so each lane gets what the scalar test
//! gets). A closest hit takes the smaller `(group, slot)` on an exact tie in `t`, so it does
//! not depend on the order candidates come in: a packet returns, bit for bit, what
//! [`Accel::closest_hit`] returns for each of its rays.
//!
//! - **Bug A** (a `-0.0` direction component misses everything): every direction is passed
//!   through `d + 0.0`, which turns `-0.0` into `+0.0` and changes nothing else.
//! - **Bug B** (`Triangle::compute_barycentric` is scaled by twice the area): barycentrics are
//!   computed here, in f64, with the Möller–Trumbore formulas.
//! - **Bug C** (the node test uses `max(slab tmin, 1e-4)` against `min(slab tmax, ray.tmax)`,
//!   so a node whose box the ray leaves before `t = 1e-4` is culled whatever it contains, and a
//!   ray with `tmax < 1e-4` finds nothing at all): in a group's space (largest coordinate `M` in
//!   `[32, 64)`) (1) the box padding of bug D is `2^-17 · M ≥ 2.4e-4`, and the local ray is
//!   within `½ ulp(64) · √3 ≈ 6.6e-6` of the exact one, so a ray that hits a triangle at `t ≥ 0`
//!   still has to cross `≥ 2.3e-4` of padding before it leaves the triangle's leaf box or any
//!   ancestor: every box on the way to a hit is left after `t > 1e-4` and is never culled;
//!   (2) obvhs gets a `tmax` of at least `2.5e-4` and hits beyond the caller's `tmax` are
//!   rejected by the exact test. Remaining limit: once a closest-hit query has found a hit
//!   closer than `1e-4` group units (`≤ 3.2e-6 · M` of the group, in world units), nodes of that
//!   group not yet visited are culled, so a second, even closer hit within that distance can be
//!   missed (the hit returned is still a true hit). The range `[32, 64)` is not larger because
//!   obvhs' own `validate` compares bounds with an absolute `1e-5`, which must stay above half
//!   an ulp of the coordinates.
//! - **Bug D** (found here): the CWBVH child bounds are quantised as
//!   `ceil((child.max − node.min) / 2^e)` in f32, whose subtraction can round *down*, so a child
//!   box can end up to half an ulp inside its primitive (a crack ~1e-8 of the node size). Every
//!   primitive box is padded by `2^-17 · M` of its group (≥ 4 ulps of any coordinate) before the
//!   build ([`AccelOptions::pad_boxes`]).

use crate::box_nodes::BoxNodes;
use crate::error::TracerError;
use crate::group_clip::{GroupBoxes, RayQuad};
use crate::traverse::{self, PACKET};
use glam::{DVec3, Vec3, Vec3A};
use obvhs::{
    aabb::Aabb,
    cwbvh::{builder::build_cwbvh, CwBvh},
    ray::Ray,
    triangle::Triangle,
    Boundable, BvhBuildParams,
};
use prt_scene::{AlphaMask, Mesh, Scene, SurfacePoint};
use smallvec::SmallVec;
use std::time::Duration;

/// Relative bound for moving a secondary ray's origin off its surface: `2^-18 ≈ 3.8e-6` of the
/// largest absolute coordinate of the hit point.
///
/// Derivation (unit roundoff `ε = 2^-24`): the triangle is exact (its f32 vertices), and every
/// ray/triangle test is done in f64 on those exact values, with errors of order `1e-16` of the
/// triangle's size — negligible. What is not exact is the f32 hit point: interpolated in f64
/// and rounded once, it lies within `√3 ε |p|∞` of the plane; the offset origin is rounded
/// again (`√3 ε |p|∞`). So the origin is on the right side of the plane once it is moved by
/// more than about `3.5 ε |p|∞`; we use `64 ε |p|∞`, 18× that. Unlike Mitsuba 3's
/// `(1 + max|p|) · 8.9e-5` there is no absolute term (a scene scaled by `2^k` behaves exactly
/// like the unit one), and unlike a bound on the triangle's own size a point of a 30 m floor
/// next to a 1 mm part is offset relative to where it is, not to how large the floor is. A
/// point at the origin gets [`spawn_offset`]'s floor relative to its triangle's size.
pub const SPAWN_RELATIVE_OFFSET: f32 = 1.0 / 262_144.0;

/// Shadow rays towards a point stop at `(1 − SHADOW_RAY_SHORTEN)` of the distance, so the
/// target's own surface is not reported as an occluder.
pub const SHADOW_RAY_SHORTEN: f32 = 1.0e-4;

/// Objects share a BVH when their union box is at most this many times the extent of each of
/// them: box padding and obvhs' fixed node `tmin` then stay below `2^-11` of any object's size.
pub const GROUP_RATIO: f64 = 64.0;

/// Padding of primitive boxes relative to the largest scaled coordinate: `2^-17`, i.e. 4 ulps
/// of a coordinate of twice that magnitude (the largest `child.max − node.min` difference).
const PAD_RELATIVE: f32 = 1.0 / 131_072.0;

/// Floor of [`spawn_offset`] relative to the triangle's extent, for hit points at (or very
/// near) the origin: `2^-20`, far above the f64 tests' `1e-16`.
const SPAWN_SIZE_FLOOR: f32 = 1.0 / 1_048_576.0;

/// Smallest `tmax` handed to obvhs, in traversal units (bug C: its node test culls everything
/// when `tmax < 1e-4`).
const MIN_TRAVERSAL_TMAX: f32 = 2.5e-4;

/// Scale groups a ray's visit list holds without a heap allocation.
const INLINE_GROUPS: usize = 8;

/// Options of [`Accel::build_with`].
#[derive(Clone, Copy, Debug)]
pub struct AccelOptions {
    /// obvhs build preset (`pre_split` is ignored: triangles are never split).
    pub build: BvhBuildParams,
    /// Trace each group in its own power-of-two rescaled, centred space (the bug C workaround).
    /// Only tests that pin the upstream defect turn this off.
    pub rescale: bool,
    /// Pad primitive boxes (the bug D workaround). Only tests turn this off.
    pub pad_boxes: bool,
    /// Groups of at most this many triangles are tested triangle by triangle instead of
    /// through their BVH (default 4: a floor quad beside objects of another scale). The BVH
    /// finds every hit the exact test finds, so the answers are the same; tests set 0 to
    /// compare.
    pub direct_triangles: usize,
    /// Give up to [`FLAT_GROUPS`] small flat meshes (at most `direct_triangles` triangles
    /// in one plane, a floor quad) groups of their own, tested directly behind their slab,
    /// instead of sharing a BVH with the objects beside them (default on; the answers are
    /// the same, `tests/accel.rs` test16).
    pub flat_groups: bool,
}

impl Default for AccelOptions {
    fn default() -> Self {
        Self {
            build: BvhBuildParams::medium_build(),
            rescale: true,
            pad_boxes: true,
            direct_triangles: DIRECT_TRIANGLES,
            flat_groups: true,
        }
    }
}

/// A primitive's (padded) bounding box, what the BVH is built over.
#[derive(Clone, Copy, Debug)]
struct PrimBox(Aabb);

impl Boundable for PrimBox {
    fn aabb(&self) -> Aabb {
        self.0
    }
}

/// A ray/triangle intersection, in world space.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Distance along the (unit) ray direction.
    pub t: f32,
    /// Index of the mesh in [`Scene::meshes`].
    pub mesh: u32,
    /// Index of the triangle in that mesh's `indices`.
    pub tri: u32,
    /// Barycentric weight of the triangle's second vertex `v1`.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex `v2`.
    pub v: f32,
    /// Unit normal of the triangle, `normalize((v1 − v0) × (v2 − v0))` (winding order, not
    /// flipped towards the ray).
    pub geometric_normal: Vec3,
    /// Interpolated vertex normal, renormalised (not flipped towards the ray).
    pub shading_normal: Vec3,
    /// Hit position, interpolated from the barycentrics.
    pub position: Vec3,
    /// Distance to move a new ray's origin off the surface along the geometric normal
    /// (see [`spawn_offset`]).
    pub offset: f32,
}

impl Hit {
    /// Origin for a new ray leaving this hit in direction `dir`: the position moved by
    /// [`Hit::offset`] along the geometric normal, to the side `dir` points to.
    #[must_use]
    pub fn spawn_origin(&self, dir: Vec3) -> Vec3 {
        offset_origin(self.position, self.geometric_normal, self.offset, dir)
    }
}

/// The spawn offset for a point `p` on a triangle `(v0, v1, v2)`:
/// `SPAWN_RELATIVE_OFFSET · max(|p|∞, 2^-20 · e)` with `e` the triangle's extent (largest
/// absolute coordinate difference of its vertices) — see [`SPAWN_RELATIVE_OFFSET`].
#[must_use]
pub fn spawn_offset(p: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> f32 {
    let extent = (v0.max(v1).max(v2) - v0.min(v1).min(v2)).max_element();
    SPAWN_RELATIVE_OFFSET * p.abs().max_element().max(SPAWN_SIZE_FLOOR * extent)
}

/// `p` moved by `offset` along the unit normal `n`, to the side of `dir` (pbrt-v4 / Mitsuba 3
/// style; a direction exactly in the plane goes to the side of `n`).
#[must_use]
pub fn offset_origin(p: Vec3, n: Vec3, offset: f32, dir: Vec3) -> Vec3 {
    if n.dot(dir) < 0.0 {
        p - n * offset
    } else {
        p + n * offset
    }
}

/// Spawn offset for a point of a surface given only its position (no triangle at hand, e.g. a
/// vertex given to [`crate::Renderer::radiance_at_points`], or a vertex of a bake):
/// `SPAWN_RELATIVE_OFFSET · 2 |p|∞`, with `1e-3 · scale` as a floor when `p` is near the
/// origin (`scale`: the extent of the point's object, or of the scene).
#[must_use]
pub fn point_offset(p: Vec3, scale: f32) -> f32 {
    SPAWN_RELATIVE_OFFSET * (2.0 * p.abs().max_element()).max(1.0e-3 * scale)
}

/// Objects of similar scale, with their BVH in their own centred, rescaled space.
struct Group {
    bvh: CwBvh,
    /// Boxes the BVH was built over (original order, group space), for `validate`.
    boxes: Vec<PrimBox>,
    /// Group-space triangles in BVH primitive order (what the boxes bound).
    local: Vec<Triangle>,
    /// World-space triangles in BVH primitive order.
    world: Vec<[Vec3; 3]>,
    /// The same triangles as the exact tests read them: first vertex and edges in f64.
    exact: Vec<ExactTri>,
    /// Each triangle's unit geometric normal, `normalize(e1 × e2)` in f64 rounded to f32 (or
    /// zero for a degenerate triangle), as hit records report it.
    normals: Vec<Vec3>,
    /// The BVH's nodes with float boxes, for single rays (empty where they do not run).
    box_nodes: BoxNodes,
    /// `(mesh, triangle)` of each BVH primitive slot.
    refs: Vec<(u32, u32)>,
    /// World position of the group space's origin.
    centre: DVec3,
    /// Power-of-two scale from world to group units.
    scale: f64,
    /// World box of the group, padded as its primitive boxes are.
    lo: DVec3,
    /// Upper corner of the world box.
    hi: DVec3,
    /// The padding in world units.
    pad_world: f64,
    /// Whether a mesh of the group has an alpha mask (only such groups test coverage).
    masked: bool,
    /// Whether the group is small enough ([`AccelOptions::direct_triangles`]) that its
    /// triangles are tested one by one instead of through its BVH.
    direct: bool,
    /// For a direct group whose triangles are flat (a floor quad): the slab they lie in, so
    /// that a ray leaving it is turned away before any triangle test.
    slab: Option<Slab>,
}

/// The slab `|n·x − d| ≤ half_width` that holds every vertex of a flat group, `n` unit.
#[derive(Clone, Copy, Debug)]
struct Slab {
    n: DVec3,
    d: f64,
    half_width: f64,
    /// A vertex of the group, and the group's extent: `|o − anchor|∞ + extent` bounds the
    /// size of the differences Möller–Trumbore forms for a ray from `o`.
    anchor: DVec3,
    extent: f64,
    /// [`SLAB_MARGIN`] times the worst `|e₁|·|e₂| / |e₁ × e₂|` of the group's triangles (how
    /// much a thin triangle magnifies the test's rounding).
    relative: f64,
}

/// A [`Slab`] is only kept if it is this thin against the group's extent.
const SLAB_FLATNESS: f64 = 1e-6;

/// How far outside a slab a ray must start, and how clearly it must point away, relative to
/// the numbers of the triangle test (see [`Slab::turns_away`]): 10⁴ times f64's unit
/// roundoff, against an error of at most about ten roundings in the test's distance.
const SLAB_MARGIN: f64 = 1e-12;

impl Slab {
    /// The slab of `tris` if they are flat to [`SLAB_FLATNESS`] of their extent.
    fn of(tris: &[[Vec3; 3]]) -> Option<Self> {
        let [a, b, c] = tris.first()?.map(Vec3::as_dvec3);
        let n = (b - a).cross(c - a).normalize_or_zero();
        if n == DVec3::ZERO {
            return None;
        }
        let d = n.dot(a);
        let points = || tris.iter().flatten().map(|v| v.as_dvec3());
        let half_width = points().map(|v| (n.dot(v) - d).abs()).fold(0.0, f64::max);
        let (lo, hi) = points().fold((a, a), |(lo, hi), v| (lo.min(v), hi.max(v)));
        let extent = (hi - lo).max_element();
        let thinness = tris
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(Vec3::as_dvec3);
                let (e1, e2) = (b - a, c - a);
                e1.length() * e2.length() / e1.cross(e2).length()
            })
            .fold(1.0, f64::max);
        (half_width <= SLAB_FLATNESS * extent && thinness.is_finite()).then_some(Self {
            n,
            d,
            half_width,
            anchor: a,
            extent,
            relative: SLAB_MARGIN * thinness,
        })
    }

    /// Whether `ray` starts outside the slab and points away from it, both by a margin:
    /// then no point of the ray at `t ≥ 0` is in the slab, so it meets none of the group's
    /// triangles. The exact test agrees: its distance `t` for a triangle is a ratio whose
    /// numerator (the origin's height over the triangle's plane) and denominator (the
    /// direction's slope against it) are each computed with an error of about ten roundings
    /// of `|o − a|·|e₁|·|e₂|` and `|e₁|·|e₂|`; the margins are about a thousand times those,
    /// so both signs, and with them `t < 0` or the miss, come out as they are.
    #[inline]
    fn turns_away(&self, ray: &WorldRay) -> bool {
        let s_o = self.n.dot(ray.origin) - self.d;
        let s_d = self.n.dot(ray.dir);
        let reach = (ray.origin - self.anchor).abs().max_element() + self.extent;
        let margin = self.half_width + self.relative * reach;
        (s_o > margin && s_d > self.relative) || (s_o < -margin && s_d < -self.relative)
    }
}

/// A world triangle as the exact tests use it: its first vertex `a` and edges `e1 = b − a`,
/// `e2 = c − a`, in f64 (the f32 vertices are exact in f64; the edges are the f64
/// differences the test would form, computed once at build instead of on every test).
#[derive(Clone, Copy, Debug)]
struct ExactTri {
    a: DVec3,
    e1: DVec3,
    e2: DVec3,
}

impl ExactTri {
    fn of(tri: &[Vec3; 3]) -> Self {
        let [a, b, c] = tri.map(Vec3::as_dvec3);
        Self {
            a,
            e1: b - a,
            e2: c - a,
        }
    }

    /// The unit geometric normal `normalize(e1 × e2)` in f32 (zero if degenerate).
    fn normal(&self) -> Vec3 {
        self.e1.cross(self.e2).normalize_or_zero().as_vec3()
    }
}

/// The ray of one query in f64 (exact copies of the caller's f32 values).
#[derive(Clone, Copy)]
struct WorldRay {
    origin: DVec3,
    dir: DVec3,
    /// The direction as obvhs gets it (bug A applied).
    dir32: Vec3A,
}

impl WorldRay {
    fn new(origin: Vec3, dir: Vec3) -> Self {
        // Bug A: `+ 0.0` maps -0.0 to +0.0 (IEEE round-to-nearest), leaving all else unchanged.
        let dir32 = Vec3A::from(dir) + Vec3A::ZERO;
        let d = Vec3::from(dir32).as_dvec3();
        Self {
            origin: origin.as_dvec3(),
            dir: d,
            dir32,
        }
    }

    /// `[t0, t1]` of the ray inside the box, if it meets it (`t0 = 0` without any division
    /// when the origin is inside, the case of every secondary ray of a one-group scene).
    fn clip(&self, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
        self.clip_with(|| DVec3::ONE / self.dir, lo, hi)
    }

    /// [`WorldRay::clip`] with the reciprocal direction from `inv` (called only when the
    /// origin is outside the box), so a ray clipped against several boxes divides once.
    #[inline]
    fn clip_with(&self, inv: impl FnOnce() -> DVec3, lo: DVec3, hi: DVec3) -> Option<(f64, f64)> {
        if self.origin.cmpge(lo).all() && self.origin.cmple(hi).all() {
            return Some((0.0, f64::INFINITY));
        }
        let inv = inv();
        let a = (lo - self.origin) * inv;
        let b = (hi - self.origin) * inv;
        // `min`/`max` drop a NaN (0 · ∞ when the origin lies on a slab plane of a zero
        // direction component), keeping the other bound.
        let t0 = a.x.min(b.x).max(a.y.min(b.y)).max(a.z.min(b.z));
        let t1 = a.x.max(b.x).min(a.y.max(b.y)).min(a.z.max(b.z));
        (t0 <= t1 && t1 >= 0.0).then_some((t0, t1))
    }

    /// Exact-input Möller–Trumbore in f64: the distance to triangle `tri` if the ray meets it
    /// with `0 ≤ t ≤ tmax`.
    #[inline]
    fn intersect(&self, tri: &ExactTri, tmax: f64) -> Option<f64> {
        self.intersect_uv(tri, tmax).map(|(t, _, _)| t)
    }

    /// [`WorldRay::intersect`] with the barycentric weights `(u, v)` of the second and third
    /// vertex at the hit.
    #[inline]
    fn intersect_uv(&self, tri: &ExactTri, tmax: f64) -> Option<(f64, f64, f64)> {
        let (a, e1, e2) = (tri.a, tri.e1, tri.e2);
        let p = self.dir.cross(e2);
        let det = e1.dot(p);
        if det == 0.0 {
            return None;
        }
        let inv = 1.0 / det;
        let tv = self.origin - a;
        let u = tv.dot(p) * inv;
        if !(0.0..=1.0).contains(&u) {
            return None;
        }
        let q = tv.cross(e1);
        let v = self.dir.dot(q) * inv;
        if v < 0.0 || u + v > 1.0 {
            return None;
        }
        let t = e2.dot(q) * inv;
        (t >= 0.0 && t <= tmax).then_some((t, u, v))
    }
}

/// Groups of at most this many triangles are tested triangle by triangle by default
/// ([`AccelOptions::direct_triangles`]): a BVH would only add the work of its root to the
/// same tests. The BVH finds every hit the exact test finds (the padding argument above), so
/// the answers are the same (`tests/accel.rs` test14). A floor quad beside objects of another
/// scale: `millimetre` renders in 0.94× the time (one thread, min of 9 rounds).
const DIRECT_TRIANGLES: usize = 4;

/// A scene's small flat meshes get groups of their own ([`AccelOptions::flat_groups`]) when
/// there are at most this many of them, so that all its groups stay few (the group walk
/// clips a ray against every group's box, four to an instruction: `group_clip`).
///
/// Why: a floor quad sharing its object's BVH makes that BVH's root span the floor, and
/// every ray leaving the floor tests the floor's two triangles in a leaf near the root. In a
/// group of its own its slab turns those rays away first (`Slab::turns_away`), and the
/// object's BVH is tight. With the group walk in AVX2 lanes and camera packets testing a
/// direct group's triangles in lanes, it saves 5.0 / 2.7 / 5.6 % of the instructions per
/// sample on `mirror` / `teapot` / `bunny_floor` (callgrind); it did not pay while the walk
/// clipped one box at a time (crates/tracer/README.md, "Lobe splitting").
pub const FLAT_GROUPS: usize = 3;

/// From this many rays of a packet on, a candidate triangle is tested against all the
/// packet's rays at once ([`PacketRays::hits`]); fewer go one by one.
const VECTOR_TESTS: u32 = 2;

/// The lanes set in `mask`, lowest first.
fn lanes_of(mut mask: u8) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        let lane = (mask != 0).then(|| mask.trailing_zeros() as usize);
        mask &= mask.wrapping_sub(1);
        lane
    })
}

/// One f64 per ray of a packet. Each operation is the IEEE operation lane by lane (no fused
/// multiply-add), so a formula written with it gives, in every lane, what the same formula
/// gives in scalar f64.
#[derive(Clone, Copy)]
struct Lanes([f64; PACKET]);

impl Lanes {
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Self([x; PACKET])
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        Self(std::array::from_fn(|i| f(self.0[i], o.0[i])))
    }

    /// Bit `i` set where `f` holds for lane `i`.
    #[inline(always)]
    fn mask(self, f: impl Fn(f64) -> bool) -> u8 {
        (0..PACKET).fold(0, |m, i| m | u8::from(f(self.0[i])) << i)
    }
}

impl std::ops::Add for Lanes {
    type Output = Self;
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self.zip(o, |a, b| a + b)
    }
}

impl std::ops::Sub for Lanes {
    type Output = Self;
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self.zip(o, |a, b| a - b)
    }
}

impl std::ops::Mul for Lanes {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self.zip(o, |a, b| a * b)
    }
}

/// `l × r` as glam's `DVec3::cross` computes it.
#[inline(always)]
fn cross(l: [Lanes; 3], r: [Lanes; 3]) -> [Lanes; 3] {
    [
        l[1] * r[2] - r[1] * l[2],
        l[2] * r[0] - r[2] * l[0],
        l[0] * r[1] - r[0] * l[1],
    ]
}

/// `l · r` as glam's `DVec3::dot` computes it.
#[inline(always)]
fn dot(l: [Lanes; 3], r: [Lanes; 3]) -> Lanes {
    l[0] * r[0] + l[1] * r[1] + l[2] * r[2]
}

/// The world rays of a packet, one component per [`Lanes`].
struct PacketRays {
    origin: [Lanes; 3],
    dir: [Lanes; 3],
}

impl PacketRays {
    fn new(rays: &[WorldRay; PACKET]) -> Self {
        let axis = |f: &dyn Fn(&WorldRay) -> f64| Lanes(std::array::from_fn(|i| f(&rays[i])));
        Self {
            origin: [
                axis(&|r| r.origin.x),
                axis(&|r| r.origin.y),
                axis(&|r| r.origin.z),
            ],
            dir: [axis(&|r| r.dir.x), axis(&|r| r.dir.y), axis(&|r| r.dir.z)],
        }
    }

    /// [`WorldRay::intersect`] of `tri` for every ray at once, each up to its `best.t`: the
    /// lanes that hit, and every lane's distance. The same operations in the same order as
    /// the scalar test, so the same lanes and the same distances.
    #[inline]
    fn hits(&self, tri: &ExactTri, best: &[Best; PACKET]) -> (u8, [f64; PACKET]) {
        #[cfg(target_arch = "x86_64")]
        if traverse::wide_node_test() {
            #[allow(unsafe_code)] // Runtime feature dispatch: AVX2 is present.
            unsafe {
                return self.hits_avx2(tri, best);
            }
        }
        self.hits_lanes(tri, best)
    }

    /// [`PacketRays::hits`] compiled for AVX2: four lanes to an instruction, the comparisons
    /// too (each the IEEE predicate of the scalar test's operator, so the same lanes).
    ///
    /// # Safety
    /// The CPU must support AVX2.
    #[cfg(target_arch = "x86_64")]
    #[allow(unsafe_code)] // `#[target_feature]` and intrinsics, called only after detection.
    #[target_feature(enable = "avx2")]
    unsafe fn hits_avx2(&self, tri: &ExactTri, best: &[Best; PACKET]) -> (u8, [f64; PACKET]) {
        use std::arch::x86_64::{_CMP_GE_OQ, _CMP_GT_OQ, _CMP_LE_OQ, _CMP_LT_OQ, _CMP_NEQ_UQ};
        let m = self.quantities(tri);
        let tmax = Lanes(std::array::from_fn(|i| best[i].t));
        let (zero, one) = (Lanes::splat(0.0), Lanes::splat(1.0));
        // `d != 0` holds for NaN (unordered, true); every other test fails on NaN (ordered).
        let hit = lane_cmp::<_CMP_NEQ_UQ>(&m.det, &zero)
            & lane_cmp::<_CMP_GE_OQ>(&m.u, &zero)
            & lane_cmp::<_CMP_LE_OQ>(&m.u, &one)
            & !(lane_cmp::<_CMP_LT_OQ>(&m.v, &zero) | lane_cmp::<_CMP_GT_OQ>(&m.uv, &one))
            & lane_cmp::<_CMP_GE_OQ>(&m.t, &zero)
            & lane_cmp::<_CMP_LE_OQ>(&m.t, &tmax);
        (hit, m.t.0)
    }

    /// The body of [`PacketRays::hits`] without AVX2.
    fn hits_lanes(&self, tri: &ExactTri, best: &[Best; PACKET]) -> (u8, [f64; PACKET]) {
        let m = self.quantities(tri);
        let within = (0..PACKET).fold(0, |w, i| w | u8::from(m.t.0[i] <= best[i].t) << i);
        let hit = m.det.mask(|d| d != 0.0)
            & m.u.mask(|u| (0.0..=1.0).contains(&u))
            & !(m.v.mask(|v| v < 0.0) | m.uv.mask(|s| s > 1.0))
            & m.t.mask(|t| t >= 0.0)
            & within;
        (hit, m.t.0)
    }

    /// The numbers of the scalar test ([`WorldRay::intersect_uv`]) for every lane, formed by
    /// the same operations in the same order.
    #[inline(always)]
    fn quantities(&self, tri: &ExactTri) -> TestLanes {
        let (a, e1, e2) = (tri.a, tri.e1, tri.e2);
        let s = |v: DVec3| [Lanes::splat(v.x), Lanes::splat(v.y), Lanes::splat(v.z)];
        let (a, e1, e2) = (s(a), s(e1), s(e2));
        let p = cross(self.dir, e2);
        let det = dot(e1, p);
        let inv = Lanes::splat(1.0).zip(det, |one, d| one / d);
        let tv = [
            self.origin[0] - a[0],
            self.origin[1] - a[1],
            self.origin[2] - a[2],
        ];
        let u = dot(tv, p) * inv;
        let q = cross(tv, e1);
        let v = dot(self.dir, q) * inv;
        let t = dot(e2, q) * inv;
        TestLanes {
            det,
            u,
            v,
            uv: u + v,
            t,
        }
    }
}

/// The per-lane numbers of a packet's triangle test: the determinant, the barycentric
/// weights `u`, `v` and their sum, the distance.
struct TestLanes {
    det: Lanes,
    u: Lanes,
    v: Lanes,
    uv: Lanes,
    t: Lanes,
}

/// Bit `i` set where `a[i] P b[i]`, `P` an AVX2 comparison predicate, eight lanes in two
/// compares.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[allow(unsafe_code)] // Intrinsics, called only after detection.
#[inline]
#[target_feature(enable = "avx2")]
unsafe fn lane_cmp<const P: i32>(a: &Lanes, b: &Lanes) -> u8 {
    use std::arch::x86_64::{_mm256_cmp_pd, _mm256_loadu_pd, _mm256_movemask_pd};
    let half = |x: &Lanes, k: usize| _mm256_loadu_pd(x.0[4 * k..4 * k + 4].as_ptr());
    let low = _mm256_movemask_pd(_mm256_cmp_pd::<P>(half(a, 0), half(b, 0)));
    let high = _mm256_movemask_pd(_mm256_cmp_pd::<P>(half(a, 1), half(b, 1)));
    (low | high << 4) as u8
}

impl Group {
    /// The obvhs ray for this group's space, starting where the ray enters the group's box
    /// (or at its origin if that is inside), and the world `t` of that start.
    fn local_ray(&self, ray: &WorldRay, t0: f64, tmax: f64) -> (Ray, f64) {
        let (start, tmax_local) = self.local_span(t0, tmax);
        let o = ((ray.origin + ray.dir * start - self.centre) * self.scale).as_vec3();
        (Ray::new(Vec3A::from(o), ray.dir32, 0.0, tmax_local), start)
    }

    /// The world `t` where [`Group::local_ray`] starts, and its `tmax` in group units.
    fn local_span(&self, t0: f64, tmax: f64) -> (f64, f32) {
        let start = (t0 - self.pad_world).max(0.0);
        let tmax_local = if tmax.is_finite() {
            ((tmax - start) * self.scale) as f32
        } else {
            f32::INFINITY
        };
        (start, tmax_local.max(MIN_TRAVERSAL_TMAX))
    }

    /// Whether the hit `(u, v)` on BVH slot `slot` is on a covered part of its mesh (always,
    /// unless the mesh has an alpha mask).
    fn covers(&self, slot: usize, u: f64, v: f64, masks: &Masks) -> bool {
        let (mesh, tri) = self.refs[slot];
        match masks.masks.get(mesh as usize) {
            Some(Some(mask)) => mask.covers(
                &masks.meshes[mesh as usize],
                SurfacePoint::Triangle {
                    tri,
                    u: u as f32,
                    v: v as f32,
                },
            ),
            _ => true,
        }
    }

    /// Where the ray enters the group's box (`0` when it starts inside), if it does by `tmax`.
    /// `inv` is the ray's reciprocal direction, computed once for all the groups.
    #[inline]
    fn entry(&self, ray: &WorldRay, inv: DVec3, tmax: f64) -> Option<f64> {
        let (t0, _) = ray.clip_with(|| inv, self.lo, self.hi)?;
        (t0 <= tmax).then_some(t0.max(0.0))
    }

    /// The exact test of candidate `slot` for a closest-hit query: updates `best` if the
    /// triangle is hit (and covered) at `t ≤ best.t` and is closer, or as close with a smaller
    /// `(group, slot)` — a rule that does not depend on the order candidates come in, so a
    /// packet and a single ray find the same hit. Returns the hit's ray-local distance (or
    /// `∞`) for the traversal.
    #[inline]
    fn consider(
        &self,
        group: usize,
        slot: usize,
        ray: &WorldRay,
        start: f64,
        best: &mut Best,
        masks: &Masks,
    ) -> f32 {
        let found = if self.masked {
            match ray.intersect_uv(&self.exact[slot], best.t) {
                Some((t, u, v)) if self.covers(slot, u, v, masks) => Some(t),
                _ => None,
            }
        } else {
            ray.intersect(&self.exact[slot], best.t)
        };
        match found {
            Some(t) => self.accept(group, slot, t, start, best),
            None => f32::INFINITY,
        }
    }

    /// A hit at world distance `t ≤ best.t` on candidate `slot`, taken as [`Group::consider`]
    /// takes it; returns its ray-local distance.
    #[inline]
    fn accept(&self, group: usize, slot: usize, t: f64, start: f64, best: &mut Best) -> f32 {
        let key = (group, slot);
        if t < best.t || best.slot.is_none_or(|b| t == best.t && key < b) {
            *best = Best { t, slot: Some(key) };
        }
        (((t - start) * self.scale) as f32).max(0.0)
    }

    /// The closest hit closer than `best.t` in this group; updates `best`.
    fn closest(&self, group: usize, ray: &WorldRay, t0: f64, best: &mut Best, masks: &Masks) {
        if self.direct {
            if self.slab.is_some_and(|s| s.turns_away(ray)) {
                return;
            }
            for slot in 0..self.world.len() {
                self.consider(group, slot, ray, 0.0, best, masks);
            }
            return;
        }
        let (local, start) = self.local_ray(ray, t0, best.t);
        let mut test = |slot| self.consider(group, slot, ray, start, best, masks);
        let touch = |slot| traverse::prefetch(&self.exact[slot]);
        if !self.box_nodes.closest(&local, &mut test, touch) {
            traverse::closest_sorted(&self.bvh, local, test, touch);
        }
    }

    /// Whether anything in this group is hit with `t ≤ tmax`.
    fn occluded(&self, ray: &WorldRay, t0: f64, tmax: f64, masks: &Masks) -> bool {
        if self.direct {
            if self.slab.is_some_and(|s| s.turns_away(ray)) {
                return false;
            }
            // The traversal's rule, for every triangle: a hit blocks if its group-space
            // distance is below the local ray's `tmax`.
            let (start, tmax_local) = self.local_span(t0, tmax);
            return (0..self.world.len())
                .any(|slot| self.blocking(slot, ray, start, tmax, masks) < tmax_local);
        }
        let (local, start) = self.local_ray(ray, t0, tmax);
        let blocking = |slot| self.blocking(slot, ray, start, tmax, masks);
        self.box_nodes
            .any(&local, |first, count| {
                (first..first + count).any(|slot| blocking(slot) < local.tmax)
            })
            .unwrap_or_else(|| traverse::any_leaves_first(&self.bvh, local, blocking))
    }

    /// The exact test of candidate `slot` for an occlusion query up to world `tmax` (with the
    /// coverage test where the group has an alpha mask): the hit's group-space distance from
    /// the local ray's start `start`, or `∞`.
    #[inline]
    fn blocking(&self, slot: usize, ray: &WorldRay, start: f64, tmax: f64, masks: &Masks) -> f32 {
        let found = if self.masked {
            match ray.intersect_uv(&self.exact[slot], tmax) {
                Some((t, u, v)) if self.covers(slot, u, v, masks) => Some(t),
                _ => None,
            }
        } else {
            ray.intersect(&self.exact[slot], tmax)
        };
        found.map_or(f32::INFINITY, |t| {
            (((t - start) * self.scale) as f32).max(0.0)
        })
    }
}

/// A group a packet reaches: its nearest entry distance over the lanes, its index, and each
/// lane's entry distance (`None`: that ray misses the group's box).
type GroupEntries = (f64, usize, [Option<f64>; PACKET]);

/// The closest hit found so far: world `t` and `(group, slot)`.
struct Best {
    t: f64,
    slot: Option<(usize, usize)>,
}

/// The meshes and their alpha masks (`alphaMode MASK`), for the coverage test of a hit.
struct Masks {
    meshes: Vec<Mesh>,
    /// One per mesh (`None`: opaque); empty when no mesh has one.
    masks: Vec<Option<AlphaMask>>,
}

/// The acceleration structure: per-scale groups of objects, each with its own CWBVH.
pub struct Accel {
    groups: Vec<Group>,
    /// The groups' world boxes in lanes of four (empty without AVX2).
    boxes: GroupBoxes,
    /// The meshes (`masks.meshes`) with their alpha masks.
    masks: Masks,
    /// Extent (largest side of the bounding box) of each mesh; 0 for empty meshes.
    extents: Vec<f32>,
    max_abs: f32,
    triangle_count: usize,
}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Accel")
            .field("triangles", &self.triangle_count)
            .field("groups", &self.groups.len())
            .finish_non_exhaustive()
    }
}

/// `2^k` for `k` in the normal f64 exponent range, exactly.
fn pow2(k: i32) -> f64 {
    f64::from_bits(((k.clamp(-1022, 1023) + 1023) as u64) << 52)
}

/// Unbiased exponent `e` with `2^e ≤ x < 2^(e+1)` for a positive normal `x`.
fn exponent_of(x: f64) -> i32 {
    ((x.to_bits() >> 52) & 0x7ff) as i32 - 1023
}

/// World bounding box of a mesh's used vertices.
fn mesh_bounds(mesh: &Mesh) -> Option<(DVec3, DVec3)> {
    let mut it = mesh.indices.iter().flatten();
    let first = mesh.positions[*it.next()? as usize].as_dvec3();
    Some(it.fold((first, first), |(lo, hi), &i| {
        let p = mesh.positions[i as usize].as_dvec3();
        (lo.min(p), hi.max(p))
    }))
}

/// Groups of mesh indices: largest mesh first; a mesh joins the first group whose box, with it
/// added, is at most `GROUP_RATIO` times the mesh's extent.
/// The meshes that get groups of their own ([`AccelOptions::flat_groups`]): those of at
/// most `direct` triangles lying in one slab ([`Slab::of`]), if there are at most
/// [`FLAT_GROUPS`] of them and some other mesh has triangles; else none.
fn small_flat_meshes(meshes: &[Mesh], direct: usize) -> Vec<usize> {
    let is_flat = |m: &Mesh| {
        (1..=direct).contains(&m.indices.len()) && {
            let tris: Vec<[Vec3; 3]> = m
                .indices
                .iter()
                .map(|idx| idx.map(|i| m.positions[i as usize]))
                .collect();
            Slab::of(&tris).is_some()
        }
    };
    let flat: Vec<usize> = (0..meshes.len()).filter(|&m| is_flat(&meshes[m])).collect();
    let with_triangles = meshes.iter().filter(|m| !m.indices.is_empty()).count();
    if flat.len() <= FLAT_GROUPS && with_triangles > flat.len() {
        flat
    } else {
        Vec::new()
    }
}

fn group_meshes(bounds: &[Option<(DVec3, DVec3)>]) -> Vec<Vec<usize>> {
    let extent = |b: &(DVec3, DVec3)| (b.1 - b.0).max_element();
    let mut order: Vec<usize> = (0..bounds.len()).filter(|&m| bounds[m].is_some()).collect();
    order.sort_by(|&a, &b| {
        let (ea, eb) = (extent(&bounds[a].unwrap()), extent(&bounds[b].unwrap()));
        eb.total_cmp(&ea).then(a.cmp(&b))
    });
    let mut groups: Vec<(Vec<usize>, DVec3, DVec3)> = Vec::new();
    for m in order {
        let (lo, hi) = bounds[m].unwrap();
        let e = extent(&(lo, hi)).max(f64::MIN_POSITIVE);
        let joined = groups
            .iter_mut()
            .find(|(_, glo, ghi)| extent(&(glo.min(lo), ghi.max(hi))) <= GROUP_RATIO * e);
        match joined {
            Some((members, glo, ghi)) => {
                members.push(m);
                *glo = glo.min(lo);
                *ghi = ghi.max(hi);
            }
            None => groups.push((vec![m], lo, hi)),
        }
    }
    let mut out: Vec<Vec<usize>> = groups
        .into_iter()
        .map(|(mut g, _, _)| {
            g.sort_unstable();
            g
        })
        .collect();
    out.sort_unstable();
    out
}

impl Accel {
    /// Builds over all triangles of `scene` with the default options (`medium_build`), with
    /// the alpha masks of its `MASK` materials ([`Scene::alpha_mask`]): every query skips
    /// the cut-out parts of those meshes.
    ///
    /// # Errors
    /// When a vertex is not finite, an index is out of range, or a mesh has a normal count
    /// different from its vertex count (an empty normal list means flat shading).
    pub fn build(scene: &Scene) -> Result<Self, TracerError> {
        Self::build_with(scene, AccelOptions::default())
    }

    /// Builds over all triangles of `scene` with explicit options (and its alpha masks, as
    /// [`Accel::build`]).
    ///
    /// # Errors
    /// As [`Accel::build`].
    pub fn build_with(scene: &Scene, options: AccelOptions) -> Result<Self, TracerError> {
        let mut accel = Self::from_meshes(&scene.meshes, options)?;
        let masks: Vec<Option<AlphaMask>> = (0..scene.meshes.len())
            .map(|m| scene.alpha_mask(m))
            .collect();
        if masks.iter().any(Option::is_some) {
            for g in &mut accel.groups {
                g.masked = g.refs.iter().any(|&(m, _)| masks[m as usize].is_some());
            }
            accel.masks.masks = masks;
        }
        Ok(accel)
    }

    /// Whether mesh `mesh` has an alpha mask (its cut-out parts are never hit).
    #[must_use]
    pub fn is_masked(&self, mesh: usize) -> bool {
        matches!(self.masks.masks.get(mesh), Some(Some(_)))
    }

    /// Builds over the triangles of `meshes` (mesh ids are positions in this slice), all
    /// opaque (no alpha masks: [`Accel::build`] adds a scene's).
    ///
    /// # Errors
    /// As [`Accel::build`].
    pub fn from_meshes(meshes: &[Mesh], options: AccelOptions) -> Result<Self, TracerError> {
        let mut max_abs = 0.0f32;
        for (mi, mesh) in meshes.iter().enumerate() {
            if !mesh.normals.is_empty() && mesh.normals.len() != mesh.positions.len() {
                return Err(TracerError::InvalidMesh {
                    mesh: mi,
                    reason: format!(
                        "{} normals for {} vertices",
                        mesh.normals.len(),
                        mesh.positions.len()
                    ),
                });
            }
            for (tri, idx) in mesh.indices.iter().enumerate() {
                for &i in idx {
                    let Some(p) = mesh.positions.get(i as usize) else {
                        return Err(TracerError::InvalidMesh {
                            mesh: mi,
                            reason: format!("triangle {tri} uses vertex {i} out of range"),
                        });
                    };
                    if !p.is_finite() {
                        return Err(TracerError::InvalidMesh {
                            mesh: mi,
                            reason: format!("vertex {i} is not finite"),
                        });
                    }
                    max_abs = max_abs.max(p.abs().max_element());
                }
            }
        }
        let bounds: Vec<Option<(DVec3, DVec3)>> = meshes.iter().map(mesh_bounds).collect();
        let extents = bounds
            .iter()
            .map(|b| b.map_or(0.0, |(lo, hi)| (hi - lo).max_element() as f32))
            .collect();
        let flat = if options.flat_groups {
            small_flat_meshes(meshes, options.direct_triangles)
        } else {
            Vec::new()
        };
        let rest: Vec<Option<(DVec3, DVec3)>> = (0..meshes.len())
            .map(|m| bounds[m].filter(|_| !flat.contains(&m)))
            .collect();
        let mut members = group_meshes(&rest);
        members.extend(flat.iter().map(|&m| vec![m]));
        members.sort_unstable();
        let groups: Vec<Group> = members
            .into_iter()
            .map(|members| Self::build_group(meshes, &bounds, &members, options))
            .collect();
        let boxes = GroupBoxes::new(&groups.iter().map(|g| (g.lo, g.hi)).collect::<Vec<_>>());
        Ok(Self {
            groups,
            boxes,
            masks: Masks {
                meshes: meshes.to_vec(),
                masks: Vec::new(),
            },
            extents,
            max_abs,
            triangle_count: meshes.iter().map(|m| m.indices.len()).sum(),
        })
    }

    fn build_group(
        meshes: &[Mesh],
        bounds: &[Option<(DVec3, DVec3)>],
        members: &[usize],
        options: AccelOptions,
    ) -> Group {
        let (lo, hi) = members
            .iter()
            .filter_map(|&m| bounds[m])
            .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
            .expect("groups hold meshes with triangles");
        let (centre, scale) = if options.rescale {
            let centre = ((lo + hi) * 0.5).as_vec3().as_dvec3();
            let m = (hi - centre).max(centre - lo).max_element();
            let scale = if m > 0.0 {
                pow2(5 - exponent_of(m))
            } else {
                1.0
            };
            (centre, scale)
        } else {
            (DVec3::ZERO, 1.0)
        };
        let mut local = Vec::new();
        let mut world = Vec::new();
        let mut refs = Vec::new();
        let mut max_local = 0.0f32;
        for &mi in members {
            let mesh = &meshes[mi];
            for (ti, idx) in mesh.indices.iter().enumerate() {
                let w = idx.map(|i| mesh.positions[i as usize]);
                let l = w.map(|p| ((p.as_dvec3() - centre) * scale).as_vec3());
                for p in l {
                    max_local = max_local.max(p.abs().max_element());
                }
                local.push(Triangle {
                    v0: l[0].into(),
                    v1: l[1].into(),
                    v2: l[2].into(),
                });
                world.push(w);
                refs.push((mi as u32, ti as u32));
            }
        }
        let pad = if options.pad_boxes {
            max_local * PAD_RELATIVE
        } else {
            0.0
        };
        let boxes: Vec<PrimBox> = local
            .iter()
            .map(|t| {
                let b = t.aabb();
                PrimBox(Aabb::new(b.min - pad, b.max + pad))
            })
            .collect();
        let mut build_time = Duration::ZERO;
        let bvh = build_cwbvh(&boxes, options.build, &mut build_time);
        let local = bvh
            .primitive_indices
            .iter()
            .map(|&i| local[i as usize])
            .collect();
        let world: Vec<[Vec3; 3]> = bvh
            .primitive_indices
            .iter()
            .map(|&i| world[i as usize])
            .collect();
        let exact: Vec<ExactTri> = world.iter().map(ExactTri::of).collect();
        let normals = exact.iter().map(ExactTri::normal).collect();
        let direct = world.len() <= options.direct_triangles;
        let slab = if direct { Slab::of(&world) } else { None };
        let refs = bvh
            .primitive_indices
            .iter()
            .map(|&i| refs[i as usize])
            .collect();
        // World box: the local boxes' extent mapped back, plus one more padding for the
        // rounding of the local coordinates (½ ulp ≪ pad).
        let pad_world = 2.0 * f64::from(pad.max(max_local * PAD_RELATIVE)) / scale;
        Group {
            box_nodes: BoxNodes::of(&bvh),
            bvh,
            boxes,
            local,
            world,
            exact,
            normals,
            refs,
            centre,
            scale,
            lo: lo - DVec3::splat(pad_world),
            hi: hi + DVec3::splat(pad_world),
            pad_world,
            masked: false,
            direct,
            slab,
        }
    }

    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// The meshes this was built from.
    #[must_use]
    pub fn meshes(&self) -> &[Mesh] {
        &self.masks.meshes
    }

    /// Largest absolute vertex coordinate (world units).
    #[must_use]
    pub fn max_abs_coordinate(&self) -> f32 {
        self.max_abs
    }

    /// Extent of mesh `mesh` (largest side of its bounding box, world units; 0 when it has no
    /// triangles).
    #[must_use]
    pub fn mesh_extent(&self, mesh: usize) -> f32 {
        self.extents.get(mesh).copied().unwrap_or(0.0)
    }

    /// Number of scale groups (each with its own BVH).
    #[must_use]
    pub fn group_count(&self) -> usize {
        self.groups.len()
    }

    /// The power-of-two scales of the groups' traversal spaces (1 when rescaling is off).
    #[must_use]
    pub fn traversal_scales(&self) -> Vec<f64> {
        self.groups.iter().map(|g| g.scale).collect()
    }

    /// The groups the ray's box test passes, with the entry `t`, nearest first (on the stack
    /// for up to [`INLINE_GROUPS`] groups: this runs once per ray). Each group goes in after
    /// the entries not farther than it, so equal entries keep the groups' order, as a stable
    /// sort would; built in place by pushes, which costs less than collecting an iterator.
    fn groups_on(&self, ray: &WorldRay, tmax: f64) -> SmallVec<[(usize, f64); INLINE_GROUPS]> {
        let inv = DVec3::ONE / ray.dir;
        let mut on = SmallVec::new();
        let mut add = |i: usize, t0: f64| {
            let at = on.partition_point(|e: &(usize, f64)| e.1.total_cmp(&t0).is_le());
            on.insert(at, (i, t0));
        };
        if self.boxes.is_wide() {
            for q in 0..self.boxes.quads() {
                let (mask, t) = self.boxes.ray_entries(q, ray.origin, inv, tmax);
                for k in lanes_of(mask) {
                    add(4 * q + k, t[k]);
                }
            }
        } else {
            for (i, g) in self.groups.iter().enumerate() {
                if let Some(t0) = g.entry(ray, inv, tmax) {
                    add(i, t0);
                }
            }
        }
        on
    }

    fn checked(origin: Vec3, dir: Vec3, tmax: f32) -> Option<f64> {
        if !(origin.is_finite() && dir.is_finite()) || tmax.is_nan() {
            return None;
        }
        Some(f64::from(tmax))
    }

    /// The closest intersection with `t ∈ [0, tmax]` along the unit direction `dir`.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let tmax = Self::checked(origin, dir, tmax)?;
        let ray = WorldRay::new(origin, dir);
        let mut best = Best {
            t: tmax,
            slot: None,
        };
        if let [g] = self.groups.as_slice() {
            let (t0, _) = ray.clip(g.lo, g.hi)?;
            g.closest(0, &ray, t0.max(0.0), &mut best, &self.masks);
        } else if self.boxes.quads() == 1 {
            // Up to four groups: their entries in one clip, visited nearest first (the first
            // group on a tie, as `groups_on` orders them).
            let inv = DVec3::ONE / ray.dir;
            let (mut left, t0) = self.boxes.ray_entries(0, ray.origin, inv, tmax);
            while let Some(k) = lanes_of(left).reduce(|a, b| if t0[b] < t0[a] { b } else { a }) {
                if t0[k] > best.t {
                    break;
                }
                left &= !(1 << k);
                self.groups[k].closest(k, &ray, t0[k], &mut best, &self.masks);
            }
        } else {
            for &(gi, t0) in &self.groups_on(&ray, tmax) {
                if t0 > best.t {
                    break;
                }
                self.groups[gi].closest(gi, &ray, t0, &mut best, &self.masks);
            }
        }
        let (gi, slot) = best.slot?;
        Some(self.hit_record(gi, slot, &ray, best.t))
    }

    /// [`Accel::closest_hit`] of many rays, `out[i]` for `origins[i]`, `dirs[i]`, all with
    /// `tmax`: the same hits, bit for bit. Rays are traced in packets of
    /// [`traverse::PACKET`] in the order given, so rays that leave from nearby points in nearby
    /// directions should come next to each other (a pixel's camera rays, a point's sorted
    /// bake rays). In scenes of several scale groups a packet visits the groups its rays'
    /// boxes reach, nearest first, each with the rays that enter it before their closest hit
    /// so far (the closest-hit rule does not depend on the order, so this is the single
    /// ray's answer too).
    ///
    /// # Panics
    /// If the three slices differ in length.
    pub fn closest_hits(
        &self,
        origins: &[Vec3],
        dirs: &[Vec3],
        tmax: f32,
        out: &mut [Option<Hit>],
    ) {
        assert!(
            origins.len() == dirs.len() && dirs.len() == out.len(),
            "closest_hits: {} origins, {} directions, {} outputs",
            origins.len(),
            dirs.len(),
            out.len()
        );
        for ((o, d), h) in origins
            .chunks(traverse::PACKET)
            .zip(dirs.chunks(traverse::PACKET))
            .zip(out.chunks_mut(traverse::PACKET))
        {
            self.closest_packet(o, d, tmax, h);
        }
    }

    /// Up to [`traverse::PACKET`] rays of [`Accel::closest_hits`].
    fn closest_packet(&self, origins: &[Vec3], dirs: &[Vec3], tmax: f32, out: &mut [Option<Hit>]) {
        let mut world = [WorldRay::new(Vec3::ZERO, Vec3::X); PACKET];
        let mut best: [Best; PACKET] = std::array::from_fn(|_| Best { t: 0.0, slot: None });
        let mut valid = 0u8;
        for (lane, (&o, &d)) in origins.iter().zip(dirs).enumerate() {
            if let Some(t) = Self::checked(o, d, tmax) {
                world[lane] = WorldRay::new(o, d);
                best[lane].t = t;
                valid |= 1 << lane;
            }
        }
        let lanes = PacketRays::new(&world);
        // Each group's entry distance per lane (`None`: the ray misses its box or is not
        // traced), and the groups in the order of their nearest entry.
        let mut entries = self.packet_entries(&world, &best, valid);
        if entries.len() > 1 {
            entries.sort_by(|a, b| a.0.total_cmp(&b.0));
        }
        // By reference: moving the list into an iterator would copy all its inline slots.
        for (_, gi, t0) in &entries {
            self.group_packet(*gi, &world, &lanes, t0, &mut best);
        }
        for (lane, h) in out.iter_mut().enumerate() {
            *h = best[lane]
                .slot
                .map(|(gi, slot)| self.hit_record(gi, slot, &world[lane], best[lane].t));
        }
    }

    /// Each group a packet's valid rays reach: the nearest entry over the lanes, the group,
    /// and each lane's entry (`None`: the ray misses the group's box, or is not traced), in
    /// the groups' order. Four rays at a time against each box where the CPU has AVX2.
    fn packet_entries(
        &self,
        world: &[WorldRay; PACKET],
        best: &[Best; PACKET],
        valid: u8,
    ) -> SmallVec<[GroupEntries; INLINE_GROUPS]> {
        const { assert!(PACKET == 8, "a packet is two quads of rays") };
        let entry_of = |gi: usize, t0: [Option<f64>; PACKET]| {
            let nearest = t0.iter().flatten().copied().reduce(f64::min)?;
            Some((nearest, gi, t0))
        };
        if self.boxes.is_wide() {
            let halves: [RayQuad; 2] = std::array::from_fn(|h| {
                RayQuad::new(
                    std::array::from_fn(|k| world[4 * h + k].origin),
                    std::array::from_fn(|k| world[4 * h + k].dir),
                )
            });
            let tmax: [[f64; 4]; 2] =
                std::array::from_fn(|h| std::array::from_fn(|k| best[4 * h + k].t));
            return (0..self.groups.len())
                .filter_map(|gi| {
                    let mut t0 = [None; PACKET];
                    for (h, rays) in halves.iter().enumerate() {
                        let (mask, t) = self.boxes.lane_entries(gi, rays, tmax[h]);
                        for k in lanes_of(mask & (valid >> (4 * h))) {
                            t0[4 * h + k] = Some(t[k]);
                        }
                    }
                    entry_of(gi, t0)
                })
                .collect();
        }
        let inv: [DVec3; PACKET] = std::array::from_fn(|lane| DVec3::ONE / world[lane].dir);
        self.groups
            .iter()
            .enumerate()
            .filter_map(|(gi, g)| {
                let t0: [Option<f64>; PACKET] = std::array::from_fn(|lane| {
                    (valid & (1 << lane) != 0)
                        .then(|| g.entry(&world[lane], inv[lane], best[lane].t))
                        .flatten()
                });
                entry_of(gi, t0)
            })
            .collect()
    }

    /// The packet's rays through group `gi`: the lanes with an entry `t0` no farther than
    /// their closest hit so far, each updating its `best`.
    fn group_packet(
        &self,
        gi: usize,
        world: &[WorldRay; PACKET],
        lanes: &PacketRays,
        t0: &[Option<f64>; PACKET],
        best: &mut [Best; PACKET],
    ) {
        let g = &self.groups[gi];
        if g.direct {
            let todo = (0..PACKET).fold(0u8, |m, lane| {
                let reaches = t0[lane].is_some_and(|t| t <= best[lane].t)
                    && !g.slab.is_some_and(|s| s.turns_away(&world[lane]));
                m | u8::from(reaches) << lane
            });
            if g.masked || todo.count_ones() < VECTOR_TESTS {
                for lane in lanes_of(todo) {
                    g.closest(gi, &world[lane], 0.0, &mut best[lane], &self.masks);
                }
                return;
            }
            // Each triangle against all the lanes at once, as a BVH candidate is: the lanes
            // get what `Group::closest` gets (the same tests, in slot order, each up to the
            // lane's closest hit so far).
            for (slot, tri) in g.exact.iter().enumerate() {
                let (hit, t) = lanes.hits(tri, best);
                for lane in lanes_of(todo & hit) {
                    g.accept(gi, slot, t[lane], 0.0, &mut best[lane]);
                }
            }
            return;
        }
        let idle = Ray::new(Vec3A::ZERO, Vec3A::X, 0.0, 0.0);
        let mut local = [idle; PACKET];
        let mut start = [0.0f64; PACKET];
        let mut active = 0u8;
        for lane in 0..PACKET {
            match t0[lane] {
                Some(t) if t <= best[lane].t => {
                    (local[lane], start[lane]) = g.local_ray(&world[lane], t, best[lane].t);
                    active |= 1 << lane;
                }
                _ => {}
            }
        }
        traverse::closest_packet(&g.bvh, &local, active, |todo, slot, tmax| {
            if g.masked || todo.count_ones() < VECTOR_TESTS {
                for lane in lanes_of(todo) {
                    let t = g.consider(
                        gi,
                        slot,
                        &world[lane],
                        start[lane],
                        &mut best[lane],
                        &self.masks,
                    );
                    tmax[lane] = tmax[lane].min(t);
                }
                return;
            }
            let (hit, t) = lanes.hits(&g.exact[slot], best);
            for lane in lanes_of(todo & hit) {
                let t = g.accept(gi, slot, t[lane], start[lane], &mut best[lane]);
                tmax[lane] = tmax[lane].min(t);
            }
        });
    }

    /// Whether anything is hit with `t ∈ [0, tmax]` along the unit direction `dir`.
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let Some(tmax) = Self::checked(origin, dir, tmax) else {
            return false;
        };
        let ray = WorldRay::new(origin, dir);
        if let [g] = self.groups.as_slice() {
            return ray.clip(g.lo, g.hi).is_some_and(|(t0, _)| {
                t0 <= tmax && g.occluded(&ray, t0.max(0.0), tmax, &self.masks)
            });
        }
        // Any order gives the same answer: no sorting.
        let inv = DVec3::ONE / ray.dir;
        if self.boxes.is_wide() {
            // A plain loop over the four bits: `lanes_of` here cost 42 instructions a sample.
            return (0..self.boxes.quads()).any(|q| {
                let (mask, t) = self.boxes.ray_entries(q, ray.origin, inv, tmax);
                (0..4).any(|k| {
                    mask & (1 << k) != 0
                        && self.groups[4 * q + k].occluded(&ray, t[k], tmax, &self.masks)
                })
            });
        }
        self.groups.iter().any(|g| {
            g.entry(&ray, inv, tmax)
                .is_some_and(|t0| g.occluded(&ray, t0, tmax, &self.masks))
        })
    }

    /// Whether the segment from `from` to `to` is blocked, stopping `SHADOW_RAY_SHORTEN` short
    /// of `to` (both points should already be offset off their surfaces).
    #[must_use]
    pub fn segment_occluded(&self, from: Vec3, to: Vec3) -> bool {
        let delta = to - from;
        let dist = delta.length();
        if dist <= 0.0 || !dist.is_finite() {
            return false;
        }
        self.occluded(from, delta / dist, dist * (1.0 - SHADOW_RAY_SHORTEN))
    }

    /// World-space vertices of triangle `tri` of mesh `mesh`.
    #[must_use]
    pub fn triangle(&self, mesh: u32, tri: u32) -> [Vec3; 3] {
        let m = &self.masks.meshes[mesh as usize];
        let idx = m.indices[tri as usize];
        idx.map(|i| m.positions[i as usize])
    }

    fn hit_record(&self, group: usize, slot: usize, ray: &WorldRay, t: f64) -> Hit {
        let g = &self.groups[group];
        let (mesh, tri) = g.refs[slot];
        let m = &self.masks.meshes[mesh as usize];
        let [v0, v1, v2] = g.world[slot];
        // Bug B: barycentrics by Möller–Trumbore in f64 (u weights v1, v weights v2).
        let ExactTri { a: a0, e1, e2 } = g.exact[slot];
        let (a1, a2) = (v1.as_dvec3(), v2.as_dvec3());
        let (o, d) = (ray.origin, ray.dir);
        let pvec = d.cross(e2);
        let det = e1.dot(pvec);
        let (mut u, mut v) = if det.abs() > 0.0 {
            let tvec = o - a0;
            let qvec = tvec.cross(e1);
            (tvec.dot(pvec) / det, d.dot(qvec) / det)
        } else {
            barycentrics_of_point(a0, a1, a2, o + d * t)
        };
        u = u.clamp(0.0, 1.0);
        v = v.clamp(0.0, 1.0);
        if u + v > 1.0 {
            let s = u + v;
            u /= s;
            v /= s;
        }
        let w = 1.0 - u - v;
        let position = (a0 * w + a1 * u + a2 * v).as_vec3();
        let ng = g.normals[slot];
        let shading_normal = if m.normals.is_empty() {
            ng
        } else {
            let idx = m.indices[tri as usize];
            let [n0, n1, n2] = idx.map(|i| m.normals[i as usize].as_dvec3());
            let n = (n0 * w + n1 * u + n2 * v).as_vec3();
            let n = n.normalize_or_zero();
            if n == Vec3::ZERO {
                ng
            } else {
                n
            }
        };
        Hit {
            t: t as f32,
            mesh,
            tri,
            u: u as f32,
            v: v as f32,
            geometric_normal: ng,
            shading_normal,
            position,
            offset: spawn_offset(position, v0, v1, v2),
        }
    }

    /// Checks the structure: the obvhs CWBVH invariants of every group (its own `validate`),
    /// that every triangle of every mesh appears exactly once, that the world triangles are
    /// the meshes' and the group-space ones their image, and that every triangle lies inside
    /// its leaf's quantised box exactly.
    ///
    /// # Errors
    /// A description of the first inconsistency found.
    pub fn validate(&self) -> Result<(), TracerError> {
        let fail = |reason: String| Err(TracerError::InvalidAccel(reason));
        let in_groups: usize = self.groups.iter().map(|g| g.refs.len()).sum();
        if in_groups != self.triangle_count {
            return fail(format!(
                "{} mesh triangles, {in_groups} in the BVHs",
                self.triangle_count
            ));
        }
        let mut seen: Vec<Vec<bool>> = self
            .masks
            .meshes
            .iter()
            .map(|m| vec![false; m.indices.len()])
            .collect();
        for (gi, g) in self.groups.iter().enumerate() {
            if g.world.len() != g.refs.len()
                || g.local.len() != g.refs.len()
                || g.exact.len() != g.refs.len()
                || g.normals.len() != g.refs.len()
            {
                return fail(format!("group {gi}: array lengths differ"));
            }
            for (slot, &(mesh, tri)) in g.refs.iter().enumerate() {
                let Some(flag) = seen
                    .get_mut(mesh as usize)
                    .and_then(|s| s.get_mut(tri as usize))
                else {
                    return fail(format!(
                        "group {gi} slot {slot} refers to missing triangle {mesh}/{tri}"
                    ));
                };
                if *flag {
                    return fail(format!("triangle {mesh}/{tri} appears twice"));
                }
                *flag = true;
                let world = self.triangle(mesh, tri);
                if g.world[slot] != world {
                    return fail(format!("group {gi} slot {slot} differs from its mesh"));
                }
                let e = ExactTri::of(&world);
                let x = &g.exact[slot];
                if (x.a, x.e1, x.e2) != (e.a, e.e1, e.e2) || g.normals[slot] != e.normal() {
                    return fail(format!("group {gi} slot {slot}: exact-test edges differ"));
                }
                let t = &g.local[slot];
                for (k, s) in [t.v0, t.v1, t.v2].into_iter().enumerate() {
                    let expect = ((world[k].as_dvec3() - g.centre) * g.scale).as_vec3();
                    if Vec3::from(s) != expect {
                        return fail(format!(
                            "group {gi} slot {slot} vertex {k} is not its group-space image"
                        ));
                    }
                    if world[k].as_dvec3().cmplt(g.lo).any()
                        || world[k].as_dvec3().cmpgt(g.hi).any()
                    {
                        return fail(format!("group {gi} slot {slot} is outside the group box"));
                    }
                }
            }
            let boxes = &g.boxes;
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                g.bvh.validate(boxes, false);
            }));
            if result.is_err() {
                return fail(format!("group {gi}: obvhs CwBvh::validate failed"));
            }
            // Stricter than obvhs (which allows 1e-5): every triangle lies inside its leaf's
            // quantised box exactly, so traversal cannot cut into it (bug D).
            for (ni, node) in g.bvh.nodes.iter().enumerate() {
                for ch in 0..8 {
                    if !node.is_leaf(ch) || node.is_child_empty(ch) {
                        continue;
                    }
                    let bounds = node.child_aabb(ch);
                    let (first, count) = node.child_primitives(ch);
                    for slot in first..first + count {
                        let Some(tri) = g.local.get(slot as usize) else {
                            return fail(format!(
                                "group {gi} node {ni} refers to primitive slot {slot}"
                            ));
                        };
                        let b = tri.aabb();
                        if b.min.cmplt(bounds.min).any() || b.max.cmpgt(bounds.max).any() {
                            return fail(format!(
                                "group {gi}: triangle in slot {slot} sticks out of its leaf box in node {ni}"
                            ));
                        }
                    }
                }
            }
        }
        if seen.iter().flatten().any(|&f| !f) {
            return fail("a triangle is missing from the BVHs".into());
        }
        Ok(())
    }
}

/// Barycentrics `(u, v)` of a point (assumed in the plane) by least squares.
fn barycentrics_of_point(a0: DVec3, a1: DVec3, a2: DVec3, p: DVec3) -> (f64, f64) {
    let (e1, e2, r) = (a1 - a0, a2 - a0, p - a0);
    let (d11, d12, d22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (r.dot(e1), r.dot(e2));
    let den = d11 * d22 - d12 * d12;
    if den.abs() <= 0.0 {
        return (0.0, 0.0);
    }
    ((d22 * r1 - d12 * r2) / den, (d11 * r2 - d12 * r1) / den)
}

#[cfg(all(test, target_arch = "x86_64"))]
mod tests {
    use super::{
        traverse, Accel, AccelOptions, Best, ExactTri, PacketRays, Vec3, WorldRay, PACKET,
    };
    use crate::group_clip::RayQuad;
    use crate::test_util::quad;
    use glam::DVec3;
    use rand::{Rng, SeedableRng};

    /// The four-lane group clips (`group_clip`) give every group's entry exactly as the
    /// scalar [`super::Group::entry`] does: which groups a ray enters by `tmax`, and the entry
    /// distance bit for bit. Six groups (two quads, the second half empty) from 10⁻⁴ to 10⁶
    /// units; random rays at every scale, axis-aligned rays (zero direction components, so
    /// `0 · ∞` where an origin lies on a box's plane), origins exactly on the boxes' planes and
    /// corners, inside the boxes; `tmax` unbounded, random, zero and negative.
    #[test]
    fn group_clips_are_the_scalar_entries() {
        let meshes: Vec<_> = (0..6)
            .map(|i| {
                let s = 10f32.powi(2 * i - 4);
                quad(
                    Vec3::new(3.0 * s, 0.5 * s, -s),
                    Vec3::X * s,
                    Vec3::new(0.0, s, s),
                )
            })
            .collect();
        let accel = Accel::from_meshes(&meshes, AccelOptions::default()).expect("builds");
        assert_eq!(accel.groups.len(), 6, "one group per scale");
        if !accel.boxes.is_wide() {
            return;
        }
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(7);
        let mut rays: Vec<WorldRay> = Vec::new();
        let axes = [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            -DVec3::X,
            -DVec3::Y,
            -DVec3::Z,
        ];
        for g in &accel.groups {
            let (lo, hi, mid) = (g.lo, g.hi, (g.lo + g.hi) * 0.5);
            let corners = [
                lo,
                hi,
                DVec3::new(lo.x, hi.y, mid.z),
                DVec3::new(mid.x, lo.y, hi.z),
            ];
            // Outside the box, on the plane of one of its faces (axis `i` at `lo` or `hi`)
            // and off it along another (`j`): there `0 · ∞` is NaN for a ray along the face.
            let size = hi - lo;
            let mut on_planes = Vec::new();
            for i in 0..3 {
                for j in (0..3).filter(|&j| j != i) {
                    for (plane, off) in [(lo[i], lo[j] - size[j]), (hi[i], hi[j] + size[j])] {
                        let mut p = mid;
                        p[i] = plane;
                        p[j] = off;
                        on_planes.push(p);
                    }
                }
            }
            let others = [mid, mid - size, mid + size];
            for origin in corners.into_iter().chain(others).chain(on_planes) {
                for &dir in &axes {
                    rays.push(WorldRay {
                        origin,
                        dir,
                        dir32: dir.as_vec3a(),
                    });
                }
                let dir = (DVec3::new(1.0, -2.0, 0.5)).normalize();
                rays.push(WorldRay {
                    origin,
                    dir,
                    dir32: dir.as_vec3a(),
                });
            }
        }
        for _ in 0..4000 {
            let scale = 10f32.powi(rng.random_range(-5..7));
            let v = |rng: &mut rand_pcg::Pcg64Mcg| {
                Vec3::new(rng.random::<f32>(), rng.random(), rng.random()) * 2.0 - Vec3::ONE
            };
            let origin = v(&mut rng) * scale * 4.0;
            let dir = v(&mut rng).normalize_or(Vec3::X);
            rays.push(WorldRay::new(origin, dir));
            // And one aimed at a point of a group's box, from outside it.
            let g = &accel.groups[rng.random_range(0..accel.groups.len())];
            let size = (g.hi - g.lo).as_vec3();
            let target = g.lo.as_vec3() + size * (v(&mut rng) + Vec3::ONE) * 0.5;
            let from = target + v(&mut rng) * size.max_element() * 8.0;
            rays.push(WorldRay::new(from, (target - from).normalize_or(Vec3::Y)));
        }
        let tmaxes = |rng: &mut rand_pcg::Pcg64Mcg| {
            [
                f64::INFINITY,
                10f64.powf(rng.random_range(-5.0..7.0)),
                0.0,
                -1.0,
            ]
        };
        let mut entered = 0;
        for (i, ray) in rays.iter().enumerate() {
            let inv = DVec3::ONE / ray.dir;
            for tmax in tmaxes(&mut rng) {
                for q in 0..accel.boxes.quads() {
                    let (mask, t) = accel.boxes.ray_entries(q, ray.origin, inv, tmax);
                    for k in 0..4 {
                        let scalar = accel
                            .groups
                            .get(4 * q + k)
                            .and_then(|g| g.entry(ray, inv, tmax));
                        let wide = (mask & (1 << k) != 0).then(|| t[k]);
                        assert_eq!(
                            wide.map(f64::to_bits),
                            scalar.map(f64::to_bits),
                            "ray {i} group {}: {wide:?} against {scalar:?}, tmax {tmax}",
                            4 * q + k
                        );
                        entered += usize::from(scalar.is_some());
                    }
                }
            }
        }
        for (i, four) in rays.chunks_exact(4).enumerate() {
            let quad_rays = RayQuad::new(
                std::array::from_fn(|k| four[k].origin),
                std::array::from_fn(|k| four[k].dir),
            );
            let tmax: [f64; 4] = std::array::from_fn(|k| tmaxes(&mut rng)[k]);
            for (gi, g) in accel.groups.iter().enumerate() {
                let (mask, t) = accel.boxes.lane_entries(gi, &quad_rays, tmax);
                for k in 0..4 {
                    let scalar = g.entry(&four[k], DVec3::ONE / four[k].dir, tmax[k]);
                    let wide = (mask & (1 << k) != 0).then(|| t[k]);
                    assert_eq!(
                        wide.map(f64::to_bits),
                        scalar.map(f64::to_bits),
                        "rays {i} lane {k} group {gi}"
                    );
                }
            }
        }
        // Both verdicts occur often (of the queries for the six real groups).
        let total = rays.len() * 4 * 6;
        assert!(
            entered > total / 50 && entered < total / 2,
            "{entered} of {total} entries"
        );
    }

    /// A triangle, a packet's rays (origin, direction) and their `tmax`.
    type Case = ([Vec3; 3], [(Vec3, Vec3); PACKET], [f64; PACKET]);

    /// The AVX2 packet test ([`PacketRays::hits_avx2`]) returns the lanes and distances of the
    /// portable one ([`PacketRays::hits_lanes`], the scalar operators lane by lane): on rays
    /// through a triangle's corners and edges exactly, just outside it, parallel to its plane
    /// (`det = 0`), with infinite and NaN components, ending exactly at the hit, and on random
    /// triangles and rays.
    #[test]
    fn avx2_lane_masks_are_the_scalar_operators() {
        if !traverse::wide_node_test() {
            return;
        }
        let tri = [Vec3::ZERO, Vec3::X, Vec3::Y];
        let down = -Vec3::Z;
        let special: Vec<(Vec3, Vec3)> = [
            (0.0, 0.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (0.5, 0.5),
            (0.5, 0.0),
            (0.0, 0.5),
            (-0.0, 0.25),
            (1.0, 1.0),
            (-1e-7, 0.5),
            (0.5, 0.500_000_1),
        ]
        .iter()
        .map(|&(x, y)| (Vec3::new(x, y, 1.0), down))
        .chain([
            (Vec3::new(0.2, 0.2, 0.0), Vec3::X),
            (
                Vec3::new(0.2, 0.2, 1.0),
                Vec3::new(f32::INFINITY, 0.0, -1.0),
            ),
            (Vec3::new(0.2, 0.2, 1.0), Vec3::new(f32::NAN, 0.0, -1.0)),
            (Vec3::new(f32::INFINITY, 0.2, 1.0), down),
            (Vec3::new(0.2, 0.2, -1.0), down),
            (Vec3::new(0.2, 0.2, 1.0), Vec3::Z),
        ])
        .collect();
        let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(32);
        let mut cases: Vec<Case> = Vec::new();
        for chunk in special.chunks(PACKET) {
            let rays: [(Vec3, Vec3); PACKET] =
                std::array::from_fn(|i| chunk.get(i).copied().unwrap_or(special[i]));
            // Unbounded, ending exactly at the plane (t = 1 for the downward rays), just short
            // of it, and NaN.
            for tmax in [f64::INFINITY, 1.0, 0.999_999_9, f64::NAN] {
                cases.push((tri, rays, [tmax; PACKET]));
            }
        }
        let mut v = |s: f32| Vec3::new(rng.random::<f32>(), rng.random(), rng.random()) * s;
        for _ in 0..2000 {
            let t = [v(2.0), v(2.0), v(2.0)];
            let rays: [(Vec3, Vec3); PACKET] = std::array::from_fn(|_| {
                (v(4.0) - Vec3::splat(1.0), (v(2.0) - Vec3::ONE).normalize())
            });
            cases.push((t, rays, [f64::INFINITY; PACKET]));
        }
        let mut hit_lanes = 0;
        let total = cases.len() * PACKET;
        for (tri, rays, tmax) in cases {
            let world: [WorldRay; PACKET] =
                std::array::from_fn(|i| WorldRay::new(rays[i].0, rays[i].1));
            let best: [Best; PACKET] = std::array::from_fn(|i| Best {
                t: tmax[i],
                slot: None,
            });
            let lanes = PacketRays::new(&world);
            let exact = ExactTri::of(&tri);
            let portable = lanes.hits_lanes(&exact, &best);
            #[allow(unsafe_code)] // AVX2 is present (checked above).
            let wide = unsafe { lanes.hits_avx2(&exact, &best) };
            assert_eq!(wide.0, portable.0, "lanes hit, {tri:?} {rays:?} {tmax:?}");
            hit_lanes += wide.0.count_ones() as usize;
            for (lane, ray) in world.iter().enumerate() {
                let single = ray.intersect(&exact, best[lane].t);
                let lane_hit = wide.0 & (1 << lane) != 0;
                assert_eq!(
                    single.map(f64::to_bits),
                    lane_hit.then(|| wide.1[lane].to_bits()),
                    "lane {lane} against the single ray, {tri:?} {:?} tmax {}",
                    rays[lane],
                    tmax[lane]
                );
            }
            assert_eq!(
                wide.1.map(f64::to_bits),
                portable.1.map(f64::to_bits),
                "distances, {tri:?} {rays:?}"
            );
        }
        // Both outcomes occur, so neither mask is trivially all ones or all zeros.
        assert!(
            hit_lanes > 0 && hit_lanes < total,
            "{hit_lanes} of {total} lanes hit"
        );
    }
}
