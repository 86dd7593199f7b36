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

use crate::{Camera, EnvImage, Environment, Mapping, Mesh, Rgb, Scene};
use glam::Vec3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};

impl Environment {
    /// A `width × height` lat-long environment of the given texels (row-major, row 0 at +Y),
    /// no rotation.
    #[must_use]
    pub fn latlong(width: usize, height: usize, texels: Vec<Rgb>) -> Self {
        Self {
            image: EnvImage {
                width,
                height,
                texels,
            },
            mapping: Mapping::LatLong,
            rotation_y_deg: 0.0,
        }
    }

    /// A uniform environment: a 1×1 lat-long image of radiance `rgb` from every direction,
    /// no rotation.
    #[must_use]
    pub fn uniform(rgb: Rgb) -> Self {
        Self::latlong(1, 1, vec![rgb])
    }

    /// A `width × height` lat-long environment, no rotation, whose texel `(i, j)` holds
    /// `radiance(d)` at its centre direction `d` (`φ = 2π (i + ½)/width`, `θ = π (j + ½)/height`,
    /// [`crate::envmap::latlong_direction`]).
    #[must_use]
    pub fn latlong_from_fn(
        width: usize,
        height: usize,
        radiance: impl Fn(glam::DVec3) -> Rgb,
    ) -> Self {
        let texels = (0..height)
            .flat_map(|j| (0..width).map(move |i| (i, j)))
            .map(|(i, j)| {
                let phi = 2.0 * std::f64::consts::PI * (i as f64 + 0.5) / width as f64;
                let theta = std::f64::consts::PI * (j as f64 + 0.5) / height as f64;
                radiance(crate::envmap::latlong_direction(phi, theta))
            })
            .collect();
        Self::latlong(width, height, texels)
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

/// A 2×2 quad in the plane z = 0 facing +Z, UV (0, 0) at its top-left corner `(−1, 1)`
/// (glTF), written as `quad.gltf` + `quad.bin` + the given PNGs into `dir`. `root` is extra
/// top-level JSON (textures, images, samplers, extensionsUsed), each entry ending in a comma.
///
/// # Panics
/// When the files cannot be written.
pub fn write_gltf_quad(
    dir: &Path,
    material: &str,
    root: &str,
    tangent: Option<[f32; 4]>,
) -> PathBuf {
    let p: [[f32; 3]; 4] = [
        [-1.0, -1.0, 0.0],
        [1.0, -1.0, 0.0],
        [1.0, 1.0, 0.0],
        [-1.0, 1.0, 0.0],
    ];
    let mut bin: Vec<u8> = Vec::new();
    let mut floats = |v: &[f32]| {
        let at = bin.len();
        for x in v {
            bin.extend_from_slice(&x.to_le_bytes());
        }
        at
    };
    let pos = floats(&p.concat());
    let nrm = floats(&[0.0, 0.0, 1.0].repeat(4));
    let uv: Vec<f32> = p
        .iter()
        .flat_map(|v| [(v[0] + 1.0) / 2.0, (1.0 - v[1]) / 2.0])
        .collect();
    let uvs = floats(&uv);
    let tan = tangent.map(|t| floats(&t.repeat(4)));
    let idx = bin.len();
    for i in [0u16, 1, 2, 0, 2, 3] {
        bin.extend_from_slice(&i.to_le_bytes());
    }
    std::fs::write(dir.join("quad.bin"), &bin).unwrap();
    let view = |offset: usize, len: usize| {
        format!(r#"{{"buffer":0,"byteOffset":{offset},"byteLength":{len}}}"#)
    };
    let mut views = vec![view(pos, 48), view(nrm, 48), view(uvs, 32), view(idx, 12)];
    let mut accessors = vec![
        r#"{"bufferView":0,"componentType":5126,"count":4,"type":"VEC3","min":[-1,-1,0],"max":[1,1,0]}"#.to_owned(),
        r#"{"bufferView":1,"componentType":5126,"count":4,"type":"VEC3"}"#.to_owned(),
        r#"{"bufferView":2,"componentType":5126,"count":4,"type":"VEC2"}"#.to_owned(),
        r#"{"bufferView":3,"componentType":5123,"count":6,"type":"SCALAR"}"#.to_owned(),
    ];
    let mut attributes = r#""POSITION":0,"NORMAL":1,"TEXCOORD_0":2"#.to_owned();
    if let Some(t) = tan {
        views.push(view(t, 64));
        accessors.push(r#"{"bufferView":4,"componentType":5126,"count":4,"type":"VEC4"}"#.into());
        attributes += r#","TANGENT":4"#;
    }
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},{root}"scene":0,"scenes":[{{"nodes":[0]}}],"nodes":[{{"mesh":0}}],
"meshes":[{{"primitives":[{{"attributes":{{{attributes}}},"indices":3,"material":0}}]}}],
"materials":[{{"name":"quad"{material}}}],
"buffers":[{{"uri":"quad.bin","byteLength":{}}}],"bufferViews":[{}],"accessors":[{}]}}"#,
        bin.len(),
        views.join(","),
        accessors.join(",")
    );
    let path = dir.join("quad.gltf");
    std::fs::write(&path, json).unwrap();
    path
}

/// Textures, samplers (clamp to edge) and images of one PNG per name, as [`write_gltf_quad`]'s
/// `root`.
pub fn gltf_texture_root(names: &[&str], extensions: &str) -> String {
    let textures: Vec<String> = (0..names.len())
        .map(|i| format!(r#"{{"source":{i},"sampler":0}}"#))
        .collect();
    let images: Vec<String> = names
        .iter()
        .map(|n| format!(r#"{{"uri":"{n}"}}"#))
        .collect();
    format!(
        r#"{extensions}"textures":[{}],"images":[{}],"samplers":[{{"wrapS":33071,"wrapT":33071}}],"#,
        textures.join(","),
        images.join(",")
    )
}

/// The scene of one glTF file as the scene loader builds it (its materials with their surface
/// inputs, meshes with their tangents), seen by `camera` under `environment`.
///
/// # Panics
/// When the file does not load or the scene is invalid.
#[must_use]
pub fn gltf_scene(path: &Path, camera: Camera, environment: Environment) -> Scene {
    let loaded = crate::load_gltf(path, &glam::DMat4::IDENTITY).expect("a loadable glTF");
    let mut scene = Scene::new(camera, environment);
    scene.textures = loaded.textures;
    for (k, (name, m)) in loaded.materials.into_iter().enumerate() {
        let i = scene.add_material(&name, m);
        scene.set_surface_inputs(i, loaded.surface_inputs[k]);
    }
    for (mesh, t) in loaded.meshes.into_iter().zip(loaded.tangents) {
        let material = mesh.material;
        let o = scene.add_mesh(mesh, material);
        scene.set_tangents(o, t);
    }
    scene.validate().expect("a valid scene");
    scene
}
