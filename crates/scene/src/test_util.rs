//! Tiny analytic shapes and environments for tests, examples and doctests of every crate.
//!
//! All shapes are counter-clockwise seen from outside (geometric normals point out), with unit
//! vertex normals, material index 0, and no degenerate triangles.
//!
//! ```
//! use prt_scene::test_util::{floor_quad, icosphere};
//! use prt_scene::{Camera, Environment, Material, Scene};
//!
//! let mut scene = Scene::new(Camera::default(), Environment::uniform([1.0; 3]));
//! let grey = scene.add_material("grey", Material::Lambert { albedo: [0.5; 3] });
//! scene.add_mesh(icosphere(2), grey);
//! scene.add_mesh(floor_quad(10.0, -1.0), grey);
//! scene.validate().unwrap();
//! assert_eq!(scene.triangle_count(), 20 * 16 + 2);
//! ```

use crate::{EnvImage, Environment, Mapping, Mesh, Rgb};
use glam::Vec3;
use std::collections::HashMap;

impl Environment {
    /// A uniform environment: a 1×1 lat-long image of radiance `rgb` from every direction,
    /// no rotation.
    #[must_use]
    pub fn uniform(rgb: Rgb) -> Self {
        Self {
            image: EnvImage {
                width: 1,
                height: 1,
                texels: vec![rgb],
            },
            mapping: Mapping::LatLong,
            rotation_y_deg: 0.0,
        }
    }
}

/// Unit-radius sphere centred at the origin: an icosahedron whose faces are split in 4
/// `subdivisions` times (20·4^s triangles, 10·4^s + 2 vertices), every vertex on the sphere and
/// its normal equal to its position.
#[must_use]
pub fn icosphere(subdivisions: u32) -> Mesh {
    let t = (1.0 + 5f32.sqrt()) / 2.0;
    let mut positions: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|p| Vec3::from_array(*p).normalize())
    .collect();
    let mut indices: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..subdivisions {
        let mut midpoints: HashMap<(u32, u32), u32> = HashMap::new();
        let mut mid = |a: u32, b: u32, positions: &mut Vec<Vec3>| -> u32 {
            *midpoints.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let p = (positions[a as usize] + positions[b as usize]).normalize();
                positions.push(p);
                positions.len() as u32 - 1
            })
        };
        let mut next = Vec::with_capacity(indices.len() * 4);
        for [a, b, c] in indices {
            let ab = mid(a, b, &mut positions);
            let bc = mid(b, c, &mut positions);
            let ca = mid(c, a, &mut positions);
            next.extend([[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]);
        }
        indices = next;
    }
    Mesh {
        name: format!("icosphere({subdivisions})"),
        normals: positions.clone(),
        positions,
        indices,
        material: 0,
        ..Default::default()
    }
}

/// A square in the plane `y = height`, `[-half_size, half_size]` in x and z, facing +Y
/// (two triangles, four vertices).
#[must_use]
pub fn floor_quad(half_size: f32, height: f32) -> Mesh {
    let s = half_size;
    Mesh {
        name: "floor_quad".into(),
        positions: vec![
            Vec3::new(-s, height, -s),
            Vec3::new(-s, height, s),
            Vec3::new(s, height, s),
            Vec3::new(s, height, -s),
        ],
        normals: vec![Vec3::Y; 4],
        indices: vec![[0, 1, 2], [0, 2, 3]],
        material: 0,
        ..Default::default()
    }
}

/// An axis-aligned box from `min` to `max` with flat faces: 6 faces × 4 vertices (each with
/// its face's outward normal), 12 triangles.
#[must_use]
pub fn axis_box(min: Vec3, max: Vec3) -> Mesh {
    let mut mesh = Mesh {
        name: "axis_box".into(),
        ..Mesh::default()
    };
    // For each outward normal, two in-plane axes u, v with u × v = normal (counter-clockwise).
    let faces = [
        (Vec3::X, Vec3::NEG_Z, Vec3::Y),
        (Vec3::NEG_X, Vec3::Z, Vec3::Y),
        (Vec3::Y, Vec3::X, Vec3::NEG_Z),
        (Vec3::NEG_Y, Vec3::X, Vec3::Z),
        (Vec3::Z, Vec3::X, Vec3::Y),
        (Vec3::NEG_Z, Vec3::NEG_X, Vec3::Y),
    ];
    let centre = (min + max) * 0.5;
    let half = (max - min) * 0.5;
    for (n, u, v) in faces {
        let base = mesh.positions.len() as u32;
        for (su, sv) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            mesh.positions.push(centre + (n + u * su + v * sv) * half);
            mesh.normals.push(n);
        }
        mesh.indices
            .extend([[base, base + 1, base + 2], [base, base + 2, base + 3]]);
    }
    mesh
}
