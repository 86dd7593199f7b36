//! Atlases of real meshes without UVs (the repository's suzanne and teapot) and of shapes
//! with known answers: valid charts (UVs in the unit square, no overlap, the gutter kept,
//! checked by [`prt_atlas::check`] independently of the generator), one texel density with
//! bounded distortion, and the same atlas on every run.

use glam::Vec3;
use prt_atlas::{check, generate, Atlas, AtlasError, AtlasOptions};
use std::path::Path;

/// The `v` and `f` lines of an OBJ file (faces fan-triangulated; `v/vt/vn` takes `v`).
fn obj(name: &str) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes/meshes")
        .join(name);
    let text = std::fs::read_to_string(&path).unwrap();
    let (mut v, mut f) = (Vec::new(), Vec::new());
    for line in text.lines() {
        let mut w = line.split_whitespace();
        match w.next() {
            Some("v") => {
                let p: Vec<f32> = w.take(3).map(|x| x.parse().unwrap()).collect();
                v.push(Vec3::new(p[0], p[1], p[2]));
            }
            Some("f") => {
                let i: Vec<u32> = w
                    .map(|x| x.split('/').next().unwrap().parse::<u32>().unwrap() - 1)
                    .collect();
                for k in 1..i.len() - 1 {
                    f.push([i[0], i[k], i[k + 1]]);
                }
            }
            _ => {}
        }
    }
    (v, f)
}

/// Twice the area of a triangle in world units and of its UVs in texels.
fn areas(p: &[Vec3], t: [u32; 3], uv: &[[f32; 2]; 3], w: f64, h: f64) -> (f64, f64) {
    let q = t.map(|i| p[i as usize].as_dvec3());
    let world = (q[1] - q[0]).cross(q[2] - q[0]).length();
    let u = uv.map(|c| glam::DVec2::new(f64::from(c[0]) * w, f64::from(c[1]) * h));
    (world, (u[1] - u[0]).perp_dot(u[2] - u[0]))
}

/// Every check on one mesh: validity, one density with the cone's distortion bound (each
/// triangle's texel area is `s²` times its world area times `cos θ ∈ [cos 45°, 1]`, up to the
/// 2⁻²⁴ UV quantisation), and determinism.
fn valid(name: &str, size: u32) -> Atlas {
    let (p, f) = obj(name);
    let opt = AtlasOptions::new(size, size);
    let a = generate(&p, &f, &opt).unwrap();
    check(&a, size, size, opt.gutter).unwrap_or_else(|e| panic!("{name}: {e}"));
    assert_eq!(a.corner_uvs.len(), f.len());
    let s2 = a.texels_per_unit * a.texels_per_unit;
    let cos = opt.max_angle_deg.to_radians().cos();
    let s = f64::from(size);
    for (t, uv) in f.iter().zip(&a.corner_uvs) {
        let (world, texel) = areas(&p, *t, uv, s, s);
        if world * s2 < 1e-3 {
            continue; // below a thousandth of a texel the quantisation dominates
        }
        let ratio = texel / (world * s2);
        // Quantisation: each corner moves ≤ 2⁻²⁵·size texels; relative area error ≲ that
        // times the perimeter over the area — bounded here by 1e-3 for the triangles kept.
        assert!(
            ratio >= cos - 1e-3 && ratio <= 1.0 + 1e-3,
            "{name}: texel/world area ratio {ratio} outside [cos 45°, 1]"
        );
    }
    assert_eq!(
        generate(&p, &f, &opt).unwrap(),
        a,
        "{name}: not deterministic"
    );
    eprintln!(
        "{name} at {size}²: {} triangles, {} charts, {:.3} texels per unit, {:.1} % utilisation",
        f.len(),
        a.charts,
        a.texels_per_unit,
        100.0 * a.utilisation
    );
    a
}

#[test]
fn suzanne_and_teapot_get_valid_deterministic_atlases() {
    let a = valid("suzanne.obj", 256);
    assert!(a.utilisation > 0.2, "{}", a.utilisation);
    valid("teapot.obj", 256);
    valid("bunny_lowres.obj", 512);
}

#[test]
fn a_cube_maps_to_six_square_charts_at_one_density() {
    // A unit cube, two triangles per face, counter-clockwise from outside.
    let p: Vec<Vec3> = (0..8)
        .map(|i| Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32))
        .collect();
    let quads = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    let f: Vec<[u32; 3]> = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    let a = generate(&p, &f, &AtlasOptions::new(64, 64)).unwrap();
    check(&a, 64, 64, 2).unwrap();
    assert_eq!(a.charts, 6);
    // Each face a square of side s texels: 6 s² texels of triangles. Shelf packing of six
    // (s + 2)² cells in 64²: three per row, two rows → s + 2 ≤ 21, s ≈ 19 (the density is
    // found by bisection to within its 2⁻⁴⁰ relative step, and cells are whole texels).
    let s = a.texels_per_unit;
    assert!((18.0..=19.0).contains(&s), "{s}");
    assert!((a.utilisation - 6.0 * s * s / 4096.0).abs() < 1e-6);
    for (t, uv) in f.iter().zip(&a.corner_uvs) {
        let (world, texel) = areas(&p, *t, uv, 64.0, 64.0);
        assert!(
            (texel / (world * s * s) - 1.0).abs() < 1e-4,
            "a flat face is not distorted"
        );
    }
}

#[test]
fn too_many_charts_for_the_lightmap_are_refused() {
    let (p, f) = obj("suzanne.obj");
    let e = generate(&p, &f, &AtlasOptions::new(8, 8)).unwrap_err();
    assert!(matches!(e, AtlasError::DoesNotFit { width: 8, .. }), "{e}");
    assert!(e.to_string().contains("larger --per-texel"));
    assert_eq!(
        generate(&p, &[], &AtlasOptions::new(8, 8)).unwrap_err(),
        AtlasError::NoTriangles
    );
    assert_eq!(
        generate(&p[..2], &f, &AtlasOptions::new(8, 8)).unwrap_err(),
        AtlasError::BadTriangle(0)
    );
}
