//! Ray/triangle acceleration over every triangle of a scene: an obvhs CWBVH with the three
//! known obvhs 0.4.0 defects worked around (see `FACTS.md`).
//!
//! - **Bug A** (a `-0.0` direction component misses everything): every direction is passed
//!   through `d + 0.0`, which turns `-0.0` into `+0.0` and changes nothing else.
//! - **Bug B** (`Triangle::compute_barycentric` is scaled by twice the area): barycentrics are
//!   computed here, in f64, with the Möller–Trumbore formulas.
//! - **Bug C** (the node test uses `max(slab tmin, 1e-4)` against `min(slab tmax, ray.tmax)`,
//!   so a node whose box the ray leaves before `t = 1e-4` is culled whatever it contains, and a
//!   ray with `tmax < 1e-4` finds nothing at all): the BVH is built and traversed in a space
//!   scaled by a power of two, chosen so the largest absolute vertex coordinate `M` lands in
//!   `[32, 64)`. Scaling by a power of two is exact in floating point, so every intersection is
//!   bit-for-bit the world-space one times the scale. In that space (1) the box padding of
//!   bug D is `2^-17 · 32 ≥ 2.4e-4`, so a ray that hits a triangle at `t ≥ 0` still has to
//!   cross the padding before it leaves the triangle's leaf box or any ancestor: every box on
//!   the way to a hit is left after `t = 2.4e-4 > 1e-4` and is never culled; (2) obvhs gets a
//!   `tmax` of at least `2.5e-4` and hits beyond the caller's `tmax` are rejected in the
//!   intersection callback. Remaining limit: once a closest-hit query has found a hit closer
//!   than `1e-4` traversal units (`≤ 3.2e-6 · M` in world units), nodes not yet visited are
//!   culled, so a second, even closer hit within that distance can be missed. The range
//!   `[32, 64)` is not larger because obvhs' own `validate` compares bounds with an absolute
//!   `1e-5`, which must stay above half an ulp of the coordinates.
//! - **Bug D** (found here): the CWBVH child bounds are quantised as
//!   `ceil((child.max − node.min) / 2^e)` in f32, whose subtraction can round *down*, so a child
//!   box can end up to half an ulp inside its primitive (a crack ~1e-8 of the node size). Every
//!   primitive box is padded by `2^-17 · M_scaled` (≥ 4 ulps of any coordinate) before the
//!   build ([`AccelOptions::pad_boxes`]).

use crate::error::TracerError;
use glam::{DVec3, Vec3, Vec3A};
use obvhs::{
    aabb::Aabb,
    cwbvh::{builder::build_cwbvh, CwBvh},
    ray::{Ray, RayHit},
    triangle::Triangle,
    Boundable, BvhBuildParams,
};
use prt_scene::{Mesh, Scene};
use std::time::Duration;

/// Relative bound for moving a secondary ray's origin off its surface: `2^-18 ≈ 3.8e-6`.
///
/// Derivation (unit roundoff `ε = 2^-24`, `M` = largest absolute coordinate of the triangle's
/// vertices and of the hit point): the hit point is interpolated from barycentrics in f64 and
/// rounded once to f32, so it lies within `√3 ε M` of the triangle's plane. Re-intersecting the
/// own triangle, obvhs' f32 Möller–Trumbore computes `n·(v0 − o)` with an error of about
/// `γ_5 |n| |v0 − o| ≤ 5ε · 2√3 M |n|`; its sign (and so the sign of `t`) is right once the
/// origin is further than that from the plane. Rounding the offset origin costs another
/// `√3 ε M`. Together about `21 ε M ≈ 1.2e-6 M`; we use about 3× that, `2^-18 M = 64 ε M`.
/// Mitsuba 3 uses `(1 + max|p|) · 8.9e-5`, a 23× larger relative offset plus an absolute floor
/// that is not scale invariant; ours has no floor because `M` includes the vertices, which
/// are never all zero for a non-degenerate triangle.
pub const SPAWN_RELATIVE_OFFSET: f32 = 1.0 / 262_144.0;

/// Shadow rays towards a point stop at `(1 − SHADOW_RAY_SHORTEN)` of the distance, so the
/// target's own surface is not reported as an occluder.
pub const SHADOW_RAY_SHORTEN: f32 = 1.0e-4;

/// Padding of primitive boxes relative to the largest scaled coordinate: `2^-17`, i.e. 4 ulps
/// of a coordinate of twice that magnitude (the largest `child.max − node.min` difference).
const PAD_RELATIVE: f32 = 1.0 / 131_072.0;

/// Smallest `tmax` handed to obvhs, in traversal units (bug C: its node test culls everything
/// when `tmax < 1e-4`).
const MIN_TRAVERSAL_TMAX: f32 = 2.5e-4;

/// Options of [`Accel::build_with`].
#[derive(Clone, Copy, Debug)]
pub struct AccelOptions {
    /// obvhs build preset (`pre_split` is ignored: triangles are never split).
    pub build: BvhBuildParams,
    /// Trace in the power-of-two rescaled space (the bug C workaround). Only tests that pin the
    /// upstream defect turn this off.
    pub rescale: bool,
    /// Pad primitive boxes (the bug D workaround). Only tests turn this off.
    pub pad_boxes: bool,
}

impl Default for AccelOptions {
    fn default() -> Self {
        Self {
            build: BvhBuildParams::medium_build(),
            rescale: true,
            pad_boxes: true,
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
    /// Distance to move a new ray's origin off the surface along the geometric normal:
    /// `SPAWN_RELATIVE_OFFSET · M` (see [`spawn_offset`]).
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
/// `SPAWN_RELATIVE_OFFSET · max(|p|∞, |v0|∞, |v1|∞, |v2|∞)`.
#[must_use]
pub fn spawn_offset(p: Vec3, v0: Vec3, v1: Vec3, v2: Vec3) -> f32 {
    let m = p
        .abs()
        .max(v0.abs())
        .max(v1.abs())
        .max(v2.abs())
        .max_element();
    SPAWN_RELATIVE_OFFSET * m
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

/// Spawn offset for a point of a surface given only its position (no triangle at hand, e.g.
/// a vertex given to [`crate::Renderer::radiance_at_points`]): `SPAWN_RELATIVE_OFFSET · 2 |p|∞`, with
/// the largest absolute coordinate of the scene as a floor when `p` is near the origin.
#[must_use]
pub fn point_offset(p: Vec3, scene_max_abs: f32) -> f32 {
    SPAWN_RELATIVE_OFFSET * (2.0 * p.abs().max_element()).max(1.0e-3 * scene_max_abs)
}

/// The acceleration structure: a CWBVH over all triangles of all meshes.
pub struct Accel {
    bvh: Option<CwBvh>,
    /// Boxes the BVH was built over (original order), for `validate`.
    boxes: Vec<PrimBox>,
    /// Scaled-space triangles in BVH primitive order.
    tris: Vec<Triangle>,
    /// `(mesh, triangle)` of each BVH primitive slot.
    refs: Vec<(u32, u32)>,
    meshes: Vec<Mesh>,
    scale: f32,
    inv_scale: f32,
    max_abs: f32,
    triangle_count: usize,
}

impl std::fmt::Debug for Accel {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Accel")
            .field("triangles", &self.triangle_count)
            .field("scale", &self.scale)
            .finish_non_exhaustive()
    }
}

/// `2^k` for `k` in the normal f32 exponent range, exactly.
fn pow2(k: i32) -> f32 {
    f32::from_bits(((k.clamp(-126, 127) + 127) as u32) << 23)
}

/// Unbiased exponent `e` with `2^e ≤ x < 2^(e+1)` for a positive normal `x`.
fn exponent_of(x: f32) -> i32 {
    ((x.to_bits() >> 23) & 0xff) as i32 - 127
}

impl Accel {
    /// Builds over all triangles of `scene` with the default options (`medium_build`).
    ///
    /// # Errors
    /// When a vertex is not finite, an index is out of range, or a mesh has a normal count
    /// different from its vertex count (an empty normal list means flat shading).
    pub fn build(scene: &Scene) -> Result<Self, TracerError> {
        Self::from_meshes(&scene.meshes, AccelOptions::default())
    }

    /// Builds over all triangles of `scene` with explicit options.
    ///
    /// # Errors
    /// As [`Accel::build`].
    pub fn build_with(scene: &Scene, options: AccelOptions) -> Result<Self, TracerError> {
        Self::from_meshes(&scene.meshes, options)
    }

    /// Builds over the triangles of `meshes` (mesh ids are positions in this slice).
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
        let scale = if options.rescale && max_abs > f32::MIN_POSITIVE {
            pow2(5 - exponent_of(max_abs))
        } else {
            1.0
        };
        let inv_scale = 1.0 / scale;

        let mut tris = Vec::new();
        let mut refs = Vec::new();
        for (mi, mesh) in meshes.iter().enumerate() {
            for (ti, idx) in mesh.indices.iter().enumerate() {
                let p = |k: usize| Vec3A::from(mesh.positions[idx[k] as usize] * scale);
                tris.push(Triangle {
                    v0: p(0),
                    v1: p(1),
                    v2: p(2),
                });
                refs.push((mi as u32, ti as u32));
            }
        }
        let triangle_count = tris.len();
        let pad = if options.pad_boxes {
            max_abs * scale * PAD_RELATIVE
        } else {
            0.0
        };
        let boxes: Vec<PrimBox> = tris
            .iter()
            .map(|t| {
                let b = t.aabb();
                PrimBox(Aabb::new(b.min - pad, b.max + pad))
            })
            .collect();
        let (bvh, tris, refs) = if tris.is_empty() {
            (None, tris, refs)
        } else {
            let mut build_time = Duration::ZERO;
            let bvh = build_cwbvh(&boxes, options.build, &mut build_time);
            let ordered: Vec<Triangle> = bvh
                .primitive_indices
                .iter()
                .map(|&i| tris[i as usize])
                .collect();
            let ordered_refs = bvh
                .primitive_indices
                .iter()
                .map(|&i| refs[i as usize])
                .collect();
            (Some(bvh), ordered, ordered_refs)
        };
        Ok(Self {
            bvh,
            boxes,
            tris,
            refs,
            meshes: meshes.to_vec(),
            scale,
            inv_scale,
            max_abs,
            triangle_count,
        })
    }

    /// Number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.triangle_count
    }

    /// The meshes this was built from.
    #[must_use]
    pub fn meshes(&self) -> &[Mesh] {
        &self.meshes
    }

    /// Largest absolute vertex coordinate (world units).
    #[must_use]
    pub fn max_abs_coordinate(&self) -> f32 {
        self.max_abs
    }

    /// The power-of-two scale of the traversal space (1 when rescaling is off).
    #[must_use]
    pub fn traversal_scale(&self) -> f32 {
        self.scale
    }

    /// The traversal ray and the true `tmax` in traversal units. The ray's own `tmax` is at
    /// least [`MIN_TRAVERSAL_TMAX`] (bug C: obvhs culls every node when `tmax < 1e-4`); hits
    /// beyond the true `tmax` are filtered in the intersection callback.
    fn ray(&self, origin: Vec3, dir: Vec3, tmax: f32) -> (Ray, f32) {
        // Bug A: `+ 0.0` maps -0.0 to +0.0 (IEEE round-to-nearest), leaving all else unchanged.
        let d = Vec3A::from(dir) + Vec3A::ZERO;
        let tmax = if tmax.is_finite() {
            tmax * self.scale
        } else {
            f32::INFINITY
        };
        let ray = Ray::new(
            Vec3A::from(origin * self.scale),
            d,
            0.0,
            tmax.max(MIN_TRAVERSAL_TMAX),
        );
        (ray, tmax)
    }

    /// The closest intersection with `t ∈ [0, tmax]` along the unit direction `dir`.
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3, tmax: f32) -> Option<Hit> {
        let bvh = self.bvh.as_ref()?;
        if !(origin.is_finite() && dir.is_finite()) || tmax.is_nan() {
            return None;
        }
        let (ray, tmax) = self.ray(origin, dir, tmax);
        let mut hit = RayHit::none();
        let tris = &self.tris;
        let found = bvh.ray_traverse(ray, &mut hit, |r, slot| {
            let t = tris[slot].intersect(r);
            if t <= tmax {
                t
            } else {
                f32::INFINITY
            }
        });
        if !found || hit.t > tmax {
            return None;
        }
        let slot = hit.primitive_id as usize;
        Some(self.hit_record(slot, origin, dir, hit.t * self.inv_scale))
    }

    /// Whether anything is hit with `t ∈ [0, tmax]` along the unit direction `dir`.
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tmax: f32) -> bool {
        let Some(bvh) = self.bvh.as_ref() else {
            return false;
        };
        if !(origin.is_finite() && dir.is_finite()) || tmax.is_nan() {
            return false;
        }
        let (ray, tmax) = self.ray(origin, dir, tmax);
        let tris = &self.tris;
        !bvh.ray_traverse_miss(ray, |r, slot| {
            let t = tris[slot].intersect(r);
            if t <= tmax {
                t
            } else {
                f32::INFINITY
            }
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
        let m = &self.meshes[mesh as usize];
        let idx = m.indices[tri as usize];
        idx.map(|i| m.positions[i as usize])
    }

    fn hit_record(&self, slot: usize, origin: Vec3, dir: Vec3, t: f32) -> Hit {
        let (mesh, tri) = self.refs[slot];
        let m = &self.meshes[mesh as usize];
        // World vertices from the traversal copy (just touched, so in cache): scaling back by
        // a power of two is exact.
        let st = &self.tris[slot];
        let [v0, v1, v2] = [st.v0, st.v1, st.v2].map(|v| Vec3::from(v) * self.inv_scale);
        // Bug B: barycentrics by Möller–Trumbore in f64 (u weights v1, v weights v2).
        let (a0, a1, a2) = (v0.as_dvec3(), v1.as_dvec3(), v2.as_dvec3());
        let (o, d) = (origin.as_dvec3(), dir.as_dvec3());
        let (e1, e2) = (a1 - a0, a2 - a0);
        let pvec = d.cross(e2);
        let det = e1.dot(pvec);
        let (mut u, mut v) = if det.abs() > 0.0 {
            let tvec = o - a0;
            let qvec = tvec.cross(e1);
            (tvec.dot(pvec) / det, d.dot(qvec) / det)
        } else {
            barycentrics_of_point(a0, a1, a2, o + d * f64::from(t))
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
        let ng = e1.cross(e2).normalize_or_zero().as_vec3();
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
            t,
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

    /// Checks the structure: the obvhs CWBVH invariants (its own `validate`), that every
    /// triangle of every mesh appears exactly once, and that the traversal-space triangles are
    /// exactly the world triangles times the scale.
    ///
    /// # Errors
    /// A description of the first inconsistency found.
    pub fn validate(&self) -> Result<(), TracerError> {
        let fail = |reason: String| Err(TracerError::InvalidAccel(reason));
        let expected: usize = self.meshes.iter().map(|m| m.indices.len()).sum();
        if expected != self.triangle_count || self.refs.len() != self.tris.len() {
            return fail(format!(
                "{expected} mesh triangles, {} in the BVH",
                self.refs.len()
            ));
        }
        let mut seen: Vec<Vec<bool>> = self
            .meshes
            .iter()
            .map(|m| vec![false; m.indices.len()])
            .collect();
        for (slot, &(mesh, tri)) in self.refs.iter().enumerate() {
            let Some(flag) = seen
                .get_mut(mesh as usize)
                .and_then(|s| s.get_mut(tri as usize))
            else {
                return fail(format!(
                    "slot {slot} refers to missing triangle {mesh}/{tri}"
                ));
            };
            if *flag {
                return fail(format!("triangle {mesh}/{tri} appears twice"));
            }
            *flag = true;
            let world = self.triangle(mesh, tri);
            let t = &self.tris[slot];
            for (k, s) in [t.v0, t.v1, t.v2].into_iter().enumerate() {
                if Vec3::from(s) != world[k] * self.scale {
                    return fail(format!("slot {slot} vertex {k} differs from its mesh"));
                }
            }
        }
        if seen.iter().flatten().any(|&f| !f) {
            return fail("a triangle is missing from the BVH".into());
        }
        if let Some(bvh) = &self.bvh {
            let boxes = &self.boxes;
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                bvh.validate(boxes, false);
            }));
            if result.is_err() {
                return fail("obvhs CwBvh::validate failed".into());
            }
            // Stricter than obvhs (which allows 1e-5): every triangle lies inside its leaf's
            // quantised box exactly, so traversal cannot cut into it (bug D).
            for (ni, node) in bvh.nodes.iter().enumerate() {
                for ch in 0..8 {
                    if !node.is_leaf(ch) || node.is_child_empty(ch) {
                        continue;
                    }
                    let bounds = node.child_aabb(ch);
                    let (first, count) = node.child_primitives(ch);
                    for slot in first..first + count {
                        let Some(tri) = self.tris.get(slot as usize) else {
                            return fail(format!("node {ni} refers to primitive slot {slot}"));
                        };
                        let b = tri.aabb();
                        if b.min.cmplt(bounds.min).any() || b.max.cmpgt(bounds.max).any() {
                            return fail(format!(
                                "triangle in slot {slot} sticks out of its leaf box in node {ni}"
                            ));
                        }
                    }
                }
            }
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
