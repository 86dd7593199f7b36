//! Tiny shapes and scenes with known answers, shared by tests, benchmarks and examples.

use glam::{DVec3, Vec3};
use obvhs::cwbvh::{builder::build_cwbvh_from_tris, CwBvh};
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;
use obvhs::BvhBuildParams;
use prt_scene::{Camera, Environment, Material, Mesh, RenderSettings, Rgb, Scene};
use std::f32::consts::PI;
use std::time::Duration;

/// A UV sphere (`rings ≥ 2` latitude bands, `segments ≥ 3` longitude bands), outward winding.
/// `smooth` gives radial vertex normals; otherwise every triangle has its own three vertices
/// with the face normal, so shading and geometric normals agree exactly.
#[must_use]
pub fn uv_sphere(center: Vec3, radius: f32, rings: u32, segments: u32, smooth: bool) -> Mesh {
    let (rings, segments) = (rings.max(2), segments.max(3));
    let dir = |r: u32, s: u32| {
        let theta = PI * r as f32 / rings as f32;
        let phi = 2.0 * PI * s as f32 / segments as f32;
        Vec3::new(
            theta.sin() * phi.cos(),
            theta.cos(),
            -theta.sin() * phi.sin(),
        )
    };
    let mut quads = Vec::new();
    for r in 0..rings {
        for s in 0..segments {
            let a = dir(r, s);
            let b = dir(r + 1, s);
            let c = dir(r + 1, s + 1);
            let d = dir(r, s + 1);
            if r != 0 {
                quads.push([a, b, d]);
            }
            if r + 1 != rings {
                quads.push([b, c, d]);
            }
        }
    }
    let mut mesh = Mesh {
        name: "uv_sphere".into(),
        ..Mesh::default()
    };
    for tri in quads {
        let p = tri.map(|d| center + d * radius);
        let n = if smooth {
            tri
        } else {
            let f = (p[1] - p[0]).cross(p[2] - p[0]).normalize();
            [f; 3]
        };
        let base = mesh.positions.len() as u32;
        mesh.positions.extend_from_slice(&p);
        mesh.normals.extend_from_slice(&n);
        mesh.indices.push([base, base + 1, base + 2]);
    }
    mesh
}

/// A parallelogram `corner + a·edge_u + b·edge_v`, `a, b ∈ [0, 1]`, two triangles, normal
/// `normalize(edge_u × edge_v)`.
#[must_use]
pub fn quad(corner: Vec3, edge_u: Vec3, edge_v: Vec3) -> Mesh {
    let n = edge_u.cross(edge_v).normalize();
    Mesh {
        name: "quad".into(),
        positions: vec![
            corner,
            corner + edge_u,
            corner + edge_u + edge_v,
            corner + edge_v,
        ],
        normals: vec![n; 4],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: 0,
        ..Default::default()
    }
}

/// An axis-aligned box of half-size `half` centred at `center`, open at the top (+Y): five
/// faces with inward normals (a concave shape).
#[must_use]
pub fn open_box(center: Vec3, half: f32) -> Mesh {
    let h = half;
    let c = center - Vec3::splat(h);
    let s = 2.0 * h;
    let faces = [
        quad(c, Vec3::new(0.0, 0.0, s), Vec3::new(s, 0.0, 0.0)), // floor, normal +Y
        quad(c, Vec3::new(0.0, s, 0.0), Vec3::new(0.0, 0.0, s)), // x = min, normal +X
        quad(
            c + Vec3::new(s, 0.0, 0.0),
            Vec3::new(0.0, 0.0, s),
            Vec3::new(0.0, s, 0.0),
        ),
        quad(c, Vec3::new(s, 0.0, 0.0), Vec3::new(0.0, s, 0.0)), // z = min, normal +Z
        quad(
            c + Vec3::new(0.0, 0.0, s),
            Vec3::new(0.0, s, 0.0),
            Vec3::new(s, 0.0, 0.0),
        ),
    ];
    merge(&faces, "open_box")
}

/// All meshes merged into one (material of the first).
#[must_use]
pub fn merge(meshes: &[Mesh], name: &str) -> Mesh {
    let mut out = Mesh {
        name: name.into(),
        ..Mesh::default()
    };
    for m in meshes {
        let base = out.positions.len() as u32;
        out.positions.extend_from_slice(&m.positions);
        out.normals.extend_from_slice(&m.normals);
        out.indices
            .extend(m.indices.iter().map(|t| t.map(|i| i + base)));
    }
    out.material = meshes.first().map_or(0, |m| m.material);
    out
}

/// The same mesh with every vertex mapped by `f` (normals unchanged).
#[must_use]
pub fn transformed(mesh: &Mesh, f: impl Fn(Vec3) -> Vec3) -> Mesh {
    Mesh {
        positions: mesh.positions.iter().map(|&p| f(p)).collect(),
        ..mesh.clone()
    }
}

/// A lat-long environment of constant radiance.
#[must_use]
pub fn constant_environment(radiance: Rgb) -> Environment {
    Environment::latlong(4, 2, vec![radiance; 8])
}

/// A lat-long environment from texels (`width × height`, row 0 at +Y).
#[must_use]
pub fn latlong_environment(width: usize, height: usize, texels: Vec<Rgb>) -> Environment {
    Environment::latlong(width, height, texels)
}

/// A camera at `eye` looking at `target`, +Y up.
#[must_use]
pub fn camera(eye: Vec3, target: Vec3, fov_y_deg: f64, width: u32, height: u32) -> Camera {
    Camera {
        eye: eye.as_dvec3(),
        target: target.as_dvec3(),
        up: DVec3::Y,
        fov_y_deg,
        width,
        height,
    }
}

/// A scene from its parts (material names `m0`, `m1`, …; default `[render]` settings).
#[must_use]
pub fn scene(
    camera: Camera,
    environment: Environment,
    materials: Vec<Material>,
    meshes: Vec<Mesh>,
) -> Scene {
    let material_names = (0..materials.len()).map(|i| format!("m{i}")).collect();
    Scene {
        camera,
        environment,
        material_sources: vec![None; materials.len()],
        materials,
        material_names,
        meshes,
        render: RenderSettings::default(),
        textures: Vec::new(),
        surface_inputs: Vec::new(),
        tangents: Vec::new(),
    }
}

/// Plain obvhs, the reference for the tracer's speed: a CWBVH (`medium_build`) over a mesh's
/// world-space triangles, in the BVH's primitive order, traversed by obvhs' own
/// `ray_traverse` / `ray_traverse_miss` with its own f32 Möller–Trumbore test. Directions
/// must not have `-0.0` components (obvhs bug A: such a ray misses; add `+ 0.0`).
pub struct PlainObvhs {
    bvh: CwBvh,
    tris: Vec<Triangle>,
}

impl PlainObvhs {
    /// Builds the BVH over `mesh`'s triangles.
    #[must_use]
    pub fn new(mesh: &Mesh) -> Self {
        let tris: Vec<Triangle> = mesh
            .indices
            .iter()
            .map(|idx| {
                let [v0, v1, v2] = idx.map(|i| mesh.positions[i as usize].into());
                Triangle { v0, v1, v2 }
            })
            .collect();
        let mut build_time = Duration::ZERO;
        let bvh = build_cwbvh_from_tris(&tris, BvhBuildParams::medium_build(), &mut build_time);
        let tris = bvh
            .primitive_indices
            .iter()
            .map(|&i| tris[i as usize])
            .collect();
        Self { bvh, tris }
    }

    fn ray(origin: Vec3, dir: Vec3) -> Ray {
        Ray::new_inf(origin.into(), dir.into())
    }

    /// Whether the unbounded ray hits a triangle (closest-hit traversal).
    #[must_use]
    pub fn closest_hit(&self, origin: Vec3, dir: Vec3) -> bool {
        let mut hit = RayHit::none();
        self.bvh
            .ray_traverse(Self::ray(origin, dir), &mut hit, |r, id| {
                self.tris[id].intersect(r)
            })
    }

    /// Whether the unbounded ray hits a triangle (any-hit traversal).
    #[must_use]
    pub fn occluded(&self, origin: Vec3, dir: Vec3) -> bool {
        !self
            .bvh
            .ray_traverse_miss(Self::ray(origin, dir), |r, id| self.tris[id].intersect(r))
    }
}
