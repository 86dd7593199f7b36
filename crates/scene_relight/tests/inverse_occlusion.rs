//! `prt fit-lighting --max-occlusion F` (issue 35): the pixels an inverse-lighting fit keeps
//! are those whose cosine-weighted hemisphere is at most `F` blocked, read from a per-pixel
//! bake's transfer. Checked against the closed form of a sphere over a floor: from a floor
//! point at distance `d` from the centre of a sphere of radius `r` at height `h` (the sphere
//! wholly above the floor's plane), the blocked cosine-weighted fraction is the sphere's form
//! factor `(r/d)² cos θ = r² h / d³`.

use glam::{DMat4, DVec3};
use prt_bake::{BakeSettings, PointKind};
use prt_scene::test_util::{floor_quad, icosphere};
use prt_scene::{Camera, Environment, Material, Scene};
use prt_scene_relight::inverse::{fit_pixels, unoccluded_pixels};
use prt_scene_relight::Bound;
use prt_tracer::{Accel, PinholeCamera};

const R: f64 = 0.45;
const H: f64 = 0.8;

fn scene() -> Scene {
    let camera = Camera {
        eye: DVec3::new(0.0, 0.35, 2.4),
        target: DVec3::new(0.0, 0.0, 0.0),
        up: DVec3::Y,
        fov_y_deg: 40.0,
        width: 64,
        height: 48,
    };
    let mut s = Scene::new(camera, Environment::uniform([1.0; 3]));
    let m = s.add_material("clay", Material::Lambert { albedo: [0.8; 3] });
    s.add_mesh(floor_quad(4.0, 0.0), m);
    let mut sphere = icosphere(4);
    sphere.transform(
        &(DMat4::from_translation(DVec3::new(0.0, H, 0.0)) * DMat4::from_scale(DVec3::splat(R))),
    );
    s.add_mesh(sphere, m);
    s.validate().unwrap();
    s
}

/// Floor pixels are kept exactly where the closed form says they are unoccluded: every floor
/// pixel whose blocked fraction is below `F − m` is kept and every one above `F + m` is left
/// out, `m = 0.02` covering the bake's Monte Carlo error (4096 cosine-distributed rays per
/// pixel: a binomial standard deviation of at most `√(0.25/4096) ≈ 0.008`, 2.5 of them) and
/// the closed form's variation over a pixel's footprint (evaluated at the pixel centre).
/// Both sides must hold pixels, so the test fails if the filter keeps or drops everything.
#[test]
fn unoccluded_pixels_follow_the_form_factor_of_a_sphere_over_a_floor() {
    let s = scene();
    let accel = Accel::build(&s).unwrap();
    let settings = BakeSettings {
        order: Some(2),
        rays: 4096,
        bounces: 0,
        seed: 3,
        points: PointKind::Pixel,
        ..BakeSettings::final_quality()
    };
    let bake = prt_bake::bake(&s, &accel, &settings).unwrap().bake;
    let bound = Bound::new(&s, &accel, &bake).unwrap();
    let pixels = fit_pixels(&bound).unwrap();
    let f = 0.05;
    let kept = unoccluded_pixels(&bound, &pixels, f).unwrap();
    let cam = PinholeCamera::new(&s.camera).unwrap();
    let centre = DVec3::new(0.0, H, 0.0);
    let (mut sure_in, mut sure_out, mut floor) = (0, 0, 0);
    for &p in &pixels {
        let (x, y) = ((p % 64) as f64 + 0.5, (p / 64) as f64 + 0.5);
        let dir = cam.direction(x, y);
        let Some(hit) = accel.closest_hit(cam.eye(), dir, f32::INFINITY) else {
            continue;
        };
        if hit.mesh != 0 {
            continue;
        }
        floor += 1;
        let point = cam.eye().as_dvec3() + dir.as_dvec3() * f64::from(hit.t);
        let d = (centre - point).length();
        let blocked = R * R * H / (d * d * d);
        let is_kept = kept.contains(&p);
        if blocked < f - 0.02 {
            sure_in += 1;
            assert!(
                is_kept,
                "pixel {p}: blocked {blocked:.3} < {f} but left out"
            );
        } else if blocked > f + 0.02 {
            sure_out += 1;
            assert!(!is_kept, "pixel {p}: blocked {blocked:.3} > {f} but kept");
        }
    }
    eprintln!("{floor} floor pixels: {sure_in} surely unoccluded, {sure_out} surely occluded");
    assert!(sure_in > 100 && sure_out > 20, "{sure_in} {sure_out}");
    // A per-vertex bake cannot say it: an error, not a silent pass.
    let vertex = prt_bake::bake(
        &s,
        &accel,
        &BakeSettings {
            points: PointKind::Vertex,
            rays: 16,
            ..settings
        },
    )
    .unwrap()
    .bake;
    let bound = Bound::new(&s, &accel, &vertex).unwrap();
    let err = unoccluded_pixels(&bound, &pixels, f)
        .unwrap_err()
        .to_string();
    assert!(err.contains("per-pixel bake without bounces"), "{err}");
}
