//! `test_util` shapes, scenes built in code, `Scene::validate`, `memory_estimate`, and the
//! environment-map parametrisations of CONVENTIONS.md.

use glam::{DVec3, Vec3};
use prt_scene::envmap::{angular_ab, angular_direction, latlong_direction, latlong_uv};
use prt_scene::test_util::{axis_box, floor_quad, icosphere};
use prt_scene::{Camera, EnvImage, Environment, Mapping, Material, Mesh, Scene};
use std::collections::HashMap;
use std::f64::consts::PI;

/// Every undirected edge is used by exactly two triangles, once in each direction: the mesh is
/// closed and consistently oriented.
fn assert_closed_and_oriented(m: &Mesh) {
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for t in &m.indices {
        for k in 0..3 {
            *directed.entry((t[k], t[(k + 1) % 3])).or_default() += 1;
        }
    }
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "{}: edge {a}->{b} used {n} times", m.name);
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "{}: edge {a}->{b} has no twin",
            m.name
        );
    }
}

#[test]
fn test01_icosphere() {
    let mut last_area = 0.0;
    for s in 0..5 {
        let m = icosphere(s);
        let f = 20 * 4usize.pow(s);
        assert_eq!(m.indices.len(), f);
        assert_eq!(m.positions.len(), 10 * 4usize.pow(s) + 2);
        assert_closed_and_oriented(&m);
        for (p, n) in m.positions.iter().zip(&m.normals) {
            assert!((p.length() - 1.0).abs() < 1e-6 && p == n);
        }
        for t in 0..f {
            let c: Vec3 = m.indices[t]
                .iter()
                .map(|&i| m.positions[i as usize])
                .sum::<Vec3>();
            assert!(m.face_normal(t).dot(c) > 0.0, "outward");
        }
        // An inscribed polyhedron: its area grows with s and stays below 4π.
        let area = m.surface_area();
        assert!(area > last_area && area < 4.0 * PI);
        last_area = area;
    }
    // Level 4 (5120 faces): the deficit shrinks about 4× per level from 24% at level 0.
    assert!(last_area > 0.995 * 4.0 * PI, "{last_area}");
}

#[test]
fn test02_box_and_floor() {
    let b = axis_box(Vec3::new(-1.0, 0.0, -2.0), Vec3::new(1.0, 3.0, 2.0));
    assert_eq!((b.positions.len(), b.indices.len()), (24, 12));
    assert_eq!(
        b.bounds(),
        Some((Vec3::new(-1.0, 0.0, -2.0), Vec3::new(1.0, 3.0, 2.0)))
    );
    // Area 2(2·3 + 2·4 + 3·4) = 52.
    assert!((b.surface_area() - 52.0).abs() < 1e-9);
    for t in 0..12 {
        let n = b.normals[b.indices[t][0] as usize];
        assert_eq!(
            b.face_normal(t),
            n,
            "vertex normals are the outward face normals"
        );
    }
    let f = floor_quad(2.0, -1.0);
    assert!((f.surface_area() - 16.0).abs() < 1e-9);
    assert_eq!((f.face_normal(0), f.face_normal(1)), (Vec3::Y, Vec3::Y));
}

fn tiny_scene() -> Scene {
    let mut scene = Scene::new(Camera::default(), Environment::uniform([0.5, 1.0, 2.0]));
    let grey = scene.add_material("grey", Material::Lambert { albedo: [0.5; 3] });
    scene.add_mesh(icosphere(1), grey);
    scene
}

#[test]
fn test03_uniform_environment_is_constant() {
    let env = Environment::uniform([0.5, 1.0, 2.0]);
    for d in [
        Vec3::X,
        Vec3::NEG_Y,
        Vec3::new(0.3, -0.4, 0.866).normalize(),
        Vec3::Z,
    ] {
        assert_eq!(env.radiance(d), [0.5, 1.0, 2.0]);
    }
}

#[test]
fn test04_validate_catches_broken_scenes() {
    let good = tiny_scene();
    good.validate().unwrap();
    type Breaker = fn(&mut Scene);
    let breakers: [(Breaker, &str); 10] = [
        (|s| s.meshes[0].normals.truncate(3), "normals"),
        (|s| s.meshes[0].indices[3][1] = 9999, "triangle 3"),
        (|s| s.meshes[0].positions[5].x = f32::NAN, "vertex 5"),
        (|s| s.meshes[0].normals[2] *= 2.0, "vertex 2 normal"),
        (|s| s.meshes[0].material = 1, "material index"),
        (
            |s| {
                s.materials[0] = Material::Lambert {
                    albedo: [0.5, 1.5, 0.5],
                }
            },
            "albedo",
        ),
        (|s| s.camera.target = s.camera.eye, "camera target"),
        (|s| s.environment.image.texels[0][2] = -1.0, "environment"),
        (|s| s.environment.image = EnvImage::default(), "environment"),
        (|s| s.render.spp = 0, "spp"),
    ];
    for (k, (breaker, needle)) in breakers.iter().enumerate() {
        let mut s = good.clone();
        breaker(&mut s);
        let msg = s.validate().expect_err(needle).to_string();
        assert!(msg.contains(needle), "case {k}: {msg}");
    }
}

#[test]
fn test05_memory_estimate_and_hash() {
    let s = tiny_scene();
    // icosphere(1): 42 vertices, 80 triangles; name "icosphere(1)" is 12 bytes; 1×1 map.
    let want = 42 * 12 * 2 + 80 * 12 + 12 + std::mem::size_of::<Material>() + "grey".len() + 12;
    assert_eq!(s.memory_estimate(), want);
    let mut two = s.clone();
    two.add_mesh(floor_quad(3.0, -2.0), 0);
    // The floor is wider and lower than the unit sphere; the sphere is higher (its top
    // vertex is below y = 1: no icosphere vertex lies on the axis).
    let (_, sphere_hi) = s.meshes[0].bounds().unwrap();
    assert!(sphere_hi.y > 0.8 && sphere_hi.y < 1.0);
    assert_eq!(
        two.bounds(),
        Some((
            Vec3::new(-3.0, -2.0, -3.0),
            Vec3::new(3.0, sphere_hi.y, 3.0)
        ))
    );
    assert_eq!(two.triangle_count(), 80 + 2);
    let h = s.geometry_hash();
    let mut moved = s.clone();
    moved.meshes[0].positions[0].z += 1e-3;
    assert_ne!(moved.geometry_hash(), h);
    assert_eq!(s.clone().geometry_hash(), h, "deterministic");
}

#[test]
fn test06_envmap_parametrisations_round_trip() {
    // CONVENTIONS.md: u = 0 looks down -Z, u = 0.25 down +X, u = 0.5 down +Z; row 0 is +Y.
    let (u, v) = latlong_uv(DVec3::X);
    assert!((u - 0.25).abs() < 1e-12 && (v - 0.5).abs() < 1e-12);
    assert!((latlong_uv(DVec3::Z).0 - 0.5).abs() < 1e-12);
    assert!(latlong_uv(DVec3::NEG_Z).0.abs() < 1e-12);
    for i in 0..200 {
        let (phi, theta) = (
            i as f64 * 0.031 % (2.0 * PI),
            0.01 + (i as f64 * 0.0157) % (PI - 0.02),
        );
        let d = latlong_direction(phi, theta);
        let (u, v) = latlong_uv(d);
        assert!(
            (u * 2.0 * PI - phi).abs() < 1e-9 && (v * PI - theta).abs() < 1e-9,
            "{phi} {theta}"
        );
        let (a, b) = angular_ab(d);
        let back = angular_direction(a, b).unwrap();
        assert!((back - d).length() < 1e-9, "{d} {back}");
    }
    assert_eq!(angular_direction(0.8, 0.8), None, "outside the disc");
    // A 2×1 lat-long map: +X (u = 0.25) is in texel 0, -X (u = 0.75) in texel 1.
    let env = Environment {
        image: EnvImage {
            width: 2,
            height: 1,
            texels: vec![[1.0; 3], [2.0; 3]],
        },
        mapping: Mapping::LatLong,
        rotation_y_deg: 0.0,
    };
    assert_eq!(env.radiance(Vec3::X), [1.0; 3]);
    assert_eq!(env.radiance(Vec3::NEG_X), [2.0; 3]);
    // Rotated by 180° about +Y, world +X looks at the map's -X.
    let turned = Environment {
        rotation_y_deg: 180.0,
        ..env
    };
    assert_eq!(
        turned.radiance(Vec3::new(1.0, 0.1, 0.05).normalize()),
        [2.0; 3]
    );
}
