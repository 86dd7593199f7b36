//! Issue 14, "per-pixel bakes have speck pixels" and "pixel footprint": a per-pixel bake relit
//! under a map band-limited to order 4 must equal a converged path-traced render of the same
//! scene within the reference's noise (+1 %) on every fully covered pixel, with no speck.
//!
//! **The cause of the specks.** A per-pixel bake used to estimate the transfer of the one
//! surface point seen through the pixel *centre*. Where that point lies on a grazing triangle
//! whose interpolated (shading) normal faces away from the camera while its geometric normal
//! faces it — near the silhouettes of every smooth, coarsely tessellated closed mesh — the
//! shading normal is turned towards the viewer (CONVENTIONS.md), i.e. into the surface, and
//! almost all of its cosine lobe lies below the geometric surface, where nothing arrives: the
//! point's radiance is ≈ 0, in the path tracer (and in Mitsuba 3, whose BSDFs return 0 when
//! `ω_o` is below the shading frame) as much as in the bake. The path tracer averages its
//! samples over the pixel's box, so such a point is one sample among many and the pixel stays
//! bright; the bake gave the whole pixel that one point's value (exactly 0 on the Stanford
//! bunny, 4 of ~31,000 covered pixels at 256²; 100 on the teapot). The same point sampling
//! made creases and occlusion edges inside covered pixels 30–80 % off. The fix is the
//! footprint itself: the bake averages the transfer of `K` sub-pixel samples spread over the
//! box (R2, randomly shifted per pixel, so each is uniform over the pixel and the average is an
//! unbiased estimate of the box-filtered transfer; transfer is linear in the lighting, so the
//! relit pixel then estimates the box-filtered radiance), and image formation adds the
//! environment seen by the samples that hit nothing.
//!
//! The scene: the low-resolution Stanford bunny (1,839 vertices, a real scanned mesh with
//! grazing, bent-normal regions) with a finely tessellated sphere in front of it (occlusion
//! edges inside covered pixels), 128 × 112 pixels, under (a) a smooth map whose texels sample a
//! polynomial of degree 3 in the direction (band-limited to order 4 up to the
//! piecewise-constant texels), direct light and one bounce, and (b) a white furnace with four
//! bounces. Measured (printed with `--nocapture`): rel. L2 over the 4,644 covered pixels 0.009–0.014 (centre-sampled: 0.010–0.019)
//! against allowances of 0.019–0.025, no speck, where the centre-sampled bake has 6 specks
//! (relit 0.003–0.06 where the reference is 0.73–0.97: silhouette pixels whose centre ray grazes
//! the bunny in front of the bright background).
//!
//! Tolerances. On the fully covered pixels `P` (every footprint sample and a 4×4 grid of rays
//! hit a surface): `e = ‖relit − ref‖ / ‖ref‖` must satisfy
//! `e ≤ √(e_ref² + e_bake²) · (1 + 4/√(2N)) + 0.01`, with `e_ref² = Σ var(ref) / Σ ref²` from
//! the tracer's variance AOV, `e_bake = ‖A − B‖ / (√2 ‖ref‖)` from two bakes with different
//! seeds, `N` = pixels × channels (four standard deviations of a realised sum of squares), and
//! the 0.01 the issue grants for what remains of the model (e.g. inner bounces gathered from
//! Gouraud-interpolated vertex transfer). A speck is a pixel whose centre sees a surface
//! (silhouettes included) more than 80 % off the
//! reference where the reference itself is known to 10 % (its standard error under 10 % of
//! its value): there must be none with the footprint, and the centre-sampled bake of the same
//! scene (`--pixel-samples 1`) must show some — the test fails without the fix.

use glam::{DMat4, DVec3, Vec3};
use prt_bake::{BakeSettings, PointKind};
use prt_scene::test_util::icosphere;
use prt_scene::{Camera, Environment, Material, Scene};
use prt_scene_relight::{form_image, relight, RelightOptions};
use prt_tracer::{Accel, PinholeCamera};
use std::path::Path;

const W: u32 = 128;
const H: u32 = 112;
const ORDER: usize = 4;

/// A positive polynomial of degree 3 in the direction: band-limited to order 4.
fn band_limited(d: DVec3) -> [f64; 3] {
    let (x, y, z) = (d.x, d.y, d.z);
    let base = 1.0 + 0.45 * y + 0.25 * x + 0.2 * x * z + 0.1 * (3.0 * y * y - 1.0)
        - 0.12 * x * (x * x - 3.0 * z * z);
    [base, 0.9 * base + 0.1 * y, 0.8 * base - 0.15 * x]
}

fn sky() -> Environment {
    Environment::latlong_from_fn(256, 128, |d| {
        let c = band_limited(d);
        [c[0] as f32, c[1] as f32, c[2] as f32]
    })
}

fn scene(environment: Environment, albedo: f32) -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.1, 0.6, 2.6),
        target: DVec3::new(0.0, 0.45, 0.0),
        up: DVec3::Y,
        fov_y_deg: 30.0,
        width: W,
        height: H,
    };
    let mut s = Scene::new(camera, environment);
    let m = s.add_material(
        "clay",
        Material::Lambert {
            albedo: [albedo; 3],
        },
    );
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/bunny_lowres.obj");
    let bunny = prt_scene::load_mesh(&path, &DMat4::from_scale(DVec3::splat(0.1)))
        .expect("bunny_lowres.obj")
        .meshes;
    for mesh in bunny {
        s.add_mesh(mesh, m);
    }
    // A finely tessellated sphere in front of the bunny: occlusion edges inside covered pixels.
    let mut sphere = icosphere(3);
    sphere.transform(
        &(DMat4::from_translation(DVec3::new(-0.32, 0.28, 0.5))
            * DMat4::from_scale(DVec3::splat(0.2))),
    );
    s.add_mesh(sphere, m);
    s.validate().expect("valid scene");
    s
}

struct Case {
    name: &'static str,
    scene: Scene,
    bounces: u32,
    spp: u32,
}

fn relit_image(scene: &Scene, accel: &Accel, bounces: u32, seed: u64, k: u32) -> Vec<[f32; 3]> {
    let settings = BakeSettings {
        order: Some(ORDER),
        rays: 1024,
        bounces,
        seed,
        points: PointKind::Pixel,
        pixel_samples: k,
        ..BakeSettings::final_quality()
    };
    let bake = prt_bake::bake(scene, accel, &settings).expect("bake").bake;
    let opt = RelightOptions {
        order: Some(ORDER),
        timing_frames: 1,
        warmup_frames: 0,
        ..RelightOptions::default()
    };
    let relit = relight(scene, accel, &bake, &opt).expect("relight");
    form_image(scene, accel, &relit, 0.0).expect("image").pixels
}

/// Pixels fully covered by surfaces: a 4×4 grid of rays and every footprint sample hit.
fn covered(scene: &Scene, accel: &Accel) -> Vec<bool> {
    let cam = PinholeCamera::new(&scene.camera).unwrap();
    let fp = prt_tracer::points::pixel_footprints(scene, accel, 0, 16).unwrap();
    (0..W * H)
        .map(|i| {
            let (x, y) = (f64::from(i % W), f64::from(i / W));
            let grid = (0..16).all(|k| {
                let (sx, sy) = (f64::from(k % 4) / 3.0, f64::from(k / 4) / 3.0);
                let dir = cam.direction(x + 0.01 + 0.98 * sx, y + 0.01 + 0.98 * sy);
                accel.closest_hit(cam.eye(), dir, f32::INFINITY).is_some()
            });
            grid && fp.fully_covered(i as usize)
        })
        .collect()
}

fn sq(a: &[f32; 3], b: &[f32; 3]) -> f64 {
    (0..3)
        .map(|c| (f64::from(a[c]) - f64::from(b[c])).powi(2))
        .sum()
}

fn norm_sq(a: &[f32; 3]) -> f64 {
    a.iter().map(|v| f64::from(*v).powi(2)).sum()
}

/// Pixels of `mask` (silhouettes included) more than 80 % off the reference where the reference is known to 10 %.
fn specks(img: &[[f32; 3]], reference: &[[f32; 3]], var: &[Vec3], mask: &[bool]) -> Vec<usize> {
    (0..img.len())
        .filter(|&i| {
            let r = f64::from(reference[i][0]);
            let known = f64::from(var[i].x).sqrt() < 0.1 * r;
            mask[i] && known && (f64::from(img[i][0]) - r).abs() > 0.8 * r
        })
        .collect()
}

fn check(case: &Case) {
    let scene = &case.scene;
    let accel = Accel::build(scene).unwrap();
    let mask = covered(scene, &accel);
    let n = mask.iter().filter(|&&m| m).count();
    assert!(n > 700, "{}: {n} covered pixels", case.name);

    let rs = prt_tracer::RenderSettings {
        spp: case.spp,
        bounces: case.bounces as i32,
        seed: 11,
        aovs: true,
        progress: false,
        ..Default::default()
    };
    let out = prt_tracer::render(scene, &rs).unwrap();
    let reference: Vec<[f32; 3]> = out.radiance.iter().map(|v| v.to_array()).collect();
    let var = &out.aovs.as_ref().unwrap().variance;
    let sel = |f: &dyn Fn(usize) -> f64| (0..mask.len()).filter(|&i| mask[i]).map(f).sum::<f64>();
    let ref_norm = sel(&|i| norm_sq(&reference[i])).sqrt();
    let e_ref = sel(&|i| f64::from(var[i].x + var[i].y + var[i].z)).sqrt() / ref_norm;

    let a = relit_image(
        scene,
        &accel,
        case.bounces,
        0,
        prt_bake::DEFAULT_PIXEL_SAMPLES,
    );
    let b = relit_image(
        scene,
        &accel,
        case.bounces,
        1,
        prt_bake::DEFAULT_PIXEL_SAMPLES,
    );
    let e = sel(&|i| sq(&a[i], &reference[i])).sqrt() / ref_norm;
    let e_bake = (sel(&|i| sq(&a[i], &b[i])) / 2.0).sqrt() / ref_norm;
    let slack = 4.0 / (2.0 * 3.0 * n as f64).sqrt();
    let allowed = (e_ref * e_ref + e_bake * e_bake).sqrt() * (1.0 + slack) + 0.01;

    let centre = relit_image(scene, &accel, case.bounces, 0, 1);
    let e_centre = sel(&|i| sq(&centre[i], &reference[i])).sqrt() / ref_norm;
    // Specks are looked for on every pixel whose centre sees a surface, silhouettes included:
    // that is where the centre-sampled bake has them (a grazing point in front of a bright
    // background fills the whole pixel).
    let seen = prt_scene_relight::object_mask(scene, &accel).unwrap();
    let specks_fp = specks(&a, &reference, var, &seen);
    let specks_centre = specks(&centre, &reference, var, &seen);
    eprintln!(
        "{}: {n} covered pixels; e = {e:.4} (allowed {allowed:.4}: e_ref {e_ref:.4}, e_bake {e_bake:.4}); \
         specks {}; centre-sampled bake: e = {e_centre:.4}, specks {}",
        case.name,
        specks_fp.len(),
        specks_centre.len()
    );
    assert!(
        e <= allowed,
        "{}: rel. L2 {e:.4} over the covered pixels exceeds {allowed:.4}",
        case.name
    );
    assert!(
        specks_fp.is_empty(),
        "{}: speck pixels {:?} (relit {:?}, reference {:?})",
        case.name,
        specks_fp,
        specks_fp.iter().map(|&i| a[i][0]).collect::<Vec<_>>(),
        specks_fp
            .iter()
            .map(|&i| reference[i][0])
            .collect::<Vec<_>>()
    );
    assert!(
        !specks_centre.is_empty(),
        "{}: the centre-sampled bake shows no speck: the scene no longer tests the footprint",
        case.name
    );
}

#[test]
fn band_limited_direct_light() {
    check(&Case {
        name: "band-limited map, 0 bounces",
        scene: scene(sky(), 0.8),
        bounces: 0,
        spp: 1024,
    });
}

#[test]
fn band_limited_one_bounce() {
    check(&Case {
        name: "band-limited map, 1 bounce",
        scene: scene(sky(), 0.8),
        bounces: 1,
        spp: 1024,
    });
}

#[test]
fn white_furnace_four_bounces() {
    check(&Case {
        name: "white furnace, 4 bounces",
        scene: scene(Environment::uniform([1.0; 3]), 1.0),
        bounces: 4,
        spp: 1024,
    });
}
