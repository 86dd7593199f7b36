//! glTF surface inputs in bakes and relighting (issue 34): a normal map shades the transfer of
//! each pixel of a per-pixel bake, so its relit image agrees with the path tracer's (which
//! shades with the map, tested against closed forms in `prt-tracer`'s `gltf_materials.rs`);
//! a per-vertex bake cannot hold the map and says so; and emission is added by relighting at
//! each hit, as the path tracer adds it.
//!
//! The quad: `prt_scene::test_util::write_gltf_quad`, a 2×2 glTF quad facing the camera on +Z,
//! with a striped normal map (8 stripes along `u`, alternately tilted 35° up and down, i.e.
//! towards ±Y) under a sky brighter above than below. Its lighting is a polynomial of degree 1
//! in the direction, so relighting at order 4 holds it exactly up to the piecewise-constant
//! texels: the stripes facing up are brighter than those facing down, in the path tracer and in
//! a bake that reads the map; a bake that ignored the map would shade every stripe alike.

use glam::{DVec3, Vec3};
use prt_bake::{BakeSettings, PointKind};
use prt_scene::test_util::{gltf_scene, gltf_texture_root, write_gltf_quad};
use prt_scene::{Camera, Environment, Material, Scene};
use prt_scene_relight::{form_image, relight, RelightOptions};
use prt_tracer::Accel;
use std::path::Path;

const W: u32 = 32;
const ORDER: usize = 4;

/// A lat-long sky whose texels sample `1 + 0.6 y + 0.2 x` (brighter above): band-limited to
/// order 2 up to the piecewise-constant texels.
fn sky() -> Environment {
    Environment::latlong_from_fn(128, 64, |d| [(1.0 + 0.6 * d.y + 0.2 * d.x) as f32; 3])
}

fn camera() -> Camera {
    Camera {
        eye: DVec3::new(0.0, 0.0, 4.0),
        target: DVec3::ZERO,
        up: DVec3::Y,
        fov_y_deg: 28.0,
        width: W,
        height: W,
    }
}

/// The quad under `env` with a Lambert material (albedo 0.5), with the striped normal map
/// or without any.
fn striped_quad(dir: &Path, with_map: bool, env: Environment) -> Scene {
    let img = image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::from_fn(8, 8, |x, _| {
        let g = if x % 2 == 0 { 0.5 + 0.35 } else { 0.5 - 0.35 };
        image::Rgba([32768, (g * 65535.0) as u16, 65535, 65535])
    });
    img.save(dir.join("n.png")).unwrap();
    let (material, root) = if with_map {
        (
            r#","normalTexture":{"index":0}"#,
            gltf_texture_root(&["n.png"], ""),
        )
    } else {
        ("", String::new())
    };
    let path = write_gltf_quad(dir, material, &root, None);
    let mut scene = gltf_scene(&path, camera(), env);
    scene.materials[0] = Material::Lambert { albedo: [0.5; 3] };
    scene
}

fn bake(scene: &Scene, accel: &Accel, points: PointKind, seed: u64) -> prt_bake::BakeOutput {
    let settings = BakeSettings {
        order: Some(ORDER),
        rays: 512,
        bounces: 0,
        seed,
        points,
        ..BakeSettings::final_quality()
    };
    prt_bake::bake(scene, accel, &settings).expect("bake")
}

fn relit(scene: &Scene, accel: &Accel, bake: &prt_bakefile::Bake) -> Vec<[f32; 3]> {
    let opt = RelightOptions {
        order: Some(ORDER),
        timing_frames: 1,
        warmup_frames: 0,
        ..RelightOptions::default()
    };
    let r = relight(scene, accel, bake, &opt).expect("relight");
    form_image(scene, accel, &r, 0.0).expect("image").pixels
}

/// The central 16×16 pixels, all inside the quad (it spans about 25 of the 32 pixels).
fn centre() -> impl Iterator<Item = usize> {
    (8..24).flat_map(|y| (8..24).map(move |x| (y * W + x) as usize))
}

/// Relative L2 over the centre of `a` against `b` (red channel; the sky is grey).
fn rel_l2(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let (mut num, mut den) = (0.0, 0.0);
    for i in centre() {
        num += (f64::from(a[i][0]) - f64::from(b[i][0])).powi(2);
        den += f64::from(b[i][0]).powi(2);
    }
    (num / den).sqrt()
}

/// Per-pixel bakes of the striped quad against the path tracer, with the tolerance of
/// `pixel_footprint.rs`: `e ≤ √(e_ref² + e_bake²)(1 + 4/√(2N)) + 0.01` (`e_ref` from the
/// tracer's variance AOV, `e_bake` from two bake seeds, `N` the pixels; the 0.01 for the
/// texels' departure from a band-limited sky and the footprint's finite samples). The bake
/// that ignores the map (the same quad without it) must miss the reference by far more: the
/// stripes differ by ~35 % in the reference.
#[test]
fn per_pixel_bakes_shade_with_the_normal_map_like_the_path_tracer() {
    let dir = tempfile::tempdir().unwrap();
    let scene = striped_quad(dir.path(), true, sky());
    let accel = Accel::build(&scene).unwrap();
    let rs = prt_tracer::RenderSettings {
        spp: 1024,
        bounces: 0,
        seed: 5,
        aovs: true,
        progress: false,
        ..Default::default()
    };
    let out = prt_tracer::render(&scene, &rs).unwrap();
    let reference: Vec<[f32; 3]> = out.radiance.iter().map(|v| v.to_array()).collect();
    let var = &out.aovs.as_ref().unwrap().variance;
    let ref_norm = centre()
        .map(|i| f64::from(reference[i][0]).powi(2))
        .sum::<f64>()
        .sqrt();
    let e_ref = centre().map(|i| f64::from(var[i].x)).sum::<f64>().sqrt() / ref_norm;
    let stripes = centre()
        .map(|i| reference[i][0])
        .fold((f32::MAX, 0.0f32), |(a, b), x| (a.min(x), b.max(x)));
    assert!(stripes.1 > 1.3 * stripes.0, "stripes {stripes:?}");

    let a = relit(
        &scene,
        &accel,
        &bake(&scene, &accel, PointKind::Pixel, 0).bake,
    );
    let b = relit(
        &scene,
        &accel,
        &bake(&scene, &accel, PointKind::Pixel, 1).bake,
    );
    let e = rel_l2(&a, &reference);
    let e_bake = rel_l2(&a, &b) / 2f64.sqrt();
    let n = centre().count() as f64;
    let allowed = (e_ref * e_ref + e_bake * e_bake).sqrt() * (1.0 + 4.0 / (2.0 * n).sqrt()) + 0.01;

    let plain = striped_quad(dir.path(), false, sky());
    let plain_accel = Accel::build(&plain).unwrap();
    let ignored = relit(
        &plain,
        &plain_accel,
        &bake(&plain, &plain_accel, PointKind::Pixel, 0).bake,
    );
    let e_ignored = rel_l2(&ignored, &reference);
    eprintln!(
        "normal-mapped per-pixel bake: e = {e:.4} (allowed {allowed:.4}: e_ref {e_ref:.4}, e_bake {e_bake:.4}); without the map e = {e_ignored:.4}"
    );
    assert!(e <= allowed, "rel. L2 {e:.4} exceeds {allowed:.4}");
    assert!(
        e_ignored > 3.0 * allowed,
        "the map's effect ({e_ignored:.4}) is not above the tolerance ({allowed:.4})"
    );
}

/// A per-vertex bake of the normal-mapped quad cannot hold the map (it varies inside the
/// triangles) and says so in a decision naming the material; a per-pixel bake says the map
/// shades each point. An occlusion map (ignored: the bake computes occlusion) and `alphaMode
/// BLEND` (read as opaque) each get a decision line too.
#[test]
fn bakes_say_what_they_do_with_each_material_input() {
    let dir = tempfile::tempdir().unwrap();
    let mut scene = striped_quad(dir.path(), true, sky());
    let accel = Accel::build(&scene).unwrap();
    let said = |scene: &Scene, points| {
        let out = bake(scene, &accel, points, 0);
        serde_json::to_string(&out.bake.meta.decisions).unwrap()
    };
    let vertex = said(&scene, PointKind::Vertex);
    assert!(
        vertex.contains("normal map of material quad.gltf#quad not representable per vertex"),
        "{vertex}"
    );
    let pixel = said(&scene, PointKind::Pixel);
    assert!(
        pixel.contains("normal map of material quad.gltf#quad: the shading normal of each point"),
        "{pixel}"
    );
    assert!(
        !pixel.contains("occlusion map") && !pixel.contains("BLEND"),
        "{pixel}"
    );
    let path = write_gltf_quad(
        dir.path(),
        r#","occlusionTexture":{"index":0},"alphaMode":"BLEND""#,
        &gltf_texture_root(&["n.png"], ""),
        None,
    );
    scene = gltf_scene(&path, camera(), sky());
    let both = said(&scene, PointKind::Vertex);
    assert!(
        both.contains("occlusion map ignored (material quad.gltf#quad)")
            && both.contains("alphaMode BLEND treated as OPAQUE (material quad.gltf#quad)"),
        "{both}"
    );
}

/// Emission under a black environment: relighting adds `emissiveFactor × strength` at each
/// hit, so every pixel of the quad shows exactly that (the transfer times a black lighting
/// is 0), per pixel and per vertex, as the path tracer shows it.
#[test]
fn relighting_adds_the_emission_the_path_tracer_shows() {
    let dir = tempfile::tempdir().unwrap();
    let material = r#","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0,"roughnessFactor":1},"emissiveFactor":[1.0,0.8,0.5],"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":2.0}}"#;
    let root = r#""extensionsUsed":["KHR_materials_emissive_strength"],"#;
    let path = write_gltf_quad(dir.path(), material, root, None);
    let scene = gltf_scene(&path, camera(), Environment::uniform([0.0; 3]));
    let accel = Accel::build(&scene).unwrap();
    let expect = [2.0f32, 1.6, 1.0];
    let traced = prt_tracer::render(
        &scene,
        &prt_tracer::RenderSettings {
            spp: 4,
            bounces: 0,
            progress: false,
            ..Default::default()
        },
    )
    .unwrap()
    .radiance;
    for points in [PointKind::Pixel, PointKind::Vertex] {
        let img = relit(&scene, &accel, &bake(&scene, &accel, points, 0).bake);
        for i in centre() {
            for c in 0..3 {
                assert!(
                    (img[i][c] - expect[c]).abs() <= 1e-5 * expect[c],
                    "{points:?} pixel {i} channel {c}: {:?}",
                    img[i]
                );
            }
            assert!((traced[i] - Vec3::from(expect)).abs().max_element() <= 1e-5 * 2.0);
        }
    }
}
