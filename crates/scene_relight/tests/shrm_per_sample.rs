//! Image formation of the `--glossy shrm` path: the SHRM looked up at each sub-pixel ray's
//! interpolated normal and position (`prt_scene_relight::ShrmSpecular`) instead of
//! interpolating per-vertex lookups.

use glam::{DVec3, Vec3};
use prt_bake::{bake, BakeSettings};
use prt_scene::{Camera, Environment, Material, Scene};
use prt_scene_relight::shrm::ShrmLobe;
use prt_scene_relight::{GlossyPath, RelightOptions, Relit};
use std::sync::Arc;

const ROUGHNESS: f32 = 0.6;

fn metal() -> Material {
    Material::Pbr {
        base_color: [1.0; 3],
        metallic: 1.0,
        roughness: ROUGHNESS,
        base_color_texture: None,
        metallic_roughness_texture: None,
    }
}

/// A white metal floor (two triangles, open to the whole upper hemisphere) under a uniform
/// environment of radiance 1, seen from low so that the view elevation runs from ~15° to
/// ~80° across it, baked at order 6.
fn floor_bake() -> (Scene, prt_tracer::Accel, prt_bakefile::Bake) {
    let cam = Camera::look_at(DVec3::new(0.0, 0.35, 1.6), DVec3::ZERO, 60.0, 24, 16);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("metal", metal());
    scene.add_mesh(prt_scene::test_util::floor_quad(1.0, 0.0), m);
    let (accel, bake) = baked(&scene, 6, 256);
    (scene, accel, bake)
}

/// `scene`'s BVH and its bake at `order` with `rays` rays per point, no bounces.
fn baked(scene: &Scene, order: usize, rays: u32) -> (prt_tracer::Accel, prt_bakefile::Bake) {
    let accel = prt_tracer::Accel::build(scene).unwrap();
    let settings = BakeSettings {
        order: Some(order),
        rays,
        bounces: 0,
        ..BakeSettings::final_quality()
    };
    let out = bake(scene, &accel, &settings).unwrap();
    (accel, out.bake)
}

/// Relighting options of the SHRM path, one untimed frame, the environment turned by `deg`.
fn shrm_options(deg: f64) -> RelightOptions {
    RelightOptions {
        glossy: GlossyPath::Shrm,
        timing_frames: 1,
        warmup_frames: 0,
        rotate_y_deg: deg,
        ..Default::default()
    }
}

/// [`floor_bake`] relit by the SHRM path.
fn floor_scene() -> (Scene, prt_tracer::Accel, Relit) {
    let (scene, accel, bake) = floor_bake();
    let relit = prt_scene_relight::relight(&scene, &accel, &bake, &shrm_options(0.0)).unwrap();
    (scene, accel, relit)
}

/// The lobes' visibility depends on the camera and the geometry, not the lighting: a binding
/// traces it on its first SHRM relighting and every later one (here with the environment
/// turned) reads that trace — its note says so — and gives what a fresh binding gives.
#[test]
fn a_binding_traces_the_lobe_visibility_once() {
    let (scene, accel, bake) = floor_bake();
    let bound = prt_scene_relight::Bound::new(&scene, &accel, &bake).unwrap();
    let notes = |r: &Relit| r.stats.notes.join(" ");
    let first = bound.relight(&shrm_options(0.0)).unwrap();
    assert!(notes(&first).contains("traced in"), "{}", notes(&first));
    let again = bound.relight(&shrm_options(90.0)).unwrap();
    assert!(
        notes(&again).contains("traced for an earlier relighting of this binding"),
        "{}",
        notes(&again)
    );
    let fresh = prt_scene_relight::relight(&scene, &accel, &bake, &shrm_options(90.0)).unwrap();
    assert_eq!(again.radiance, fresh.radiance);
    let k = |r: &Relit| r.shrm[0].as_ref().unwrap().occlusion().to_vec();
    assert_eq!(k(&again), k(&fresh));
}

/// At a triangle's corners the per-sample value is the vertex's own lookup, bit for bit, and
/// the per-vertex radiance the relighting returns is the same lookup (one function for both).
#[test]
fn per_sample_lookup_is_the_vertex_lookup_at_corners() {
    let (scene, _, relit) = floor_scene();
    let s = relit.shrm[0]
        .as_ref()
        .expect("the SHRM path keeps its lookups");
    let mesh = &scene.meshes[0];
    let vertex = s.vertex_radiance(mesh);
    assert_eq!(vertex, relit.radiance[0]);
    // Nothing stands above the floor: every traced lobe direction is open, k = 1 exactly.
    assert!(s.occlusion().iter().all(|k| *k == [1.0; 3]));
    for (t, tri) in mesh.indices.iter().enumerate() {
        for (corner, (u, v)) in [(0.0, 0.0), (1.0, 0.0), (0.0, 1.0)].into_iter().enumerate() {
            let at = s.at(mesh, t, u, v);
            assert_eq!(
                at, vertex[tri[corner] as usize],
                "triangle {t} corner {corner}"
            );
        }
    }
}

/// `∫ f cos θ_i dω_i` of the unit-colour metal at view elevation `t` (the radiance under a
/// uniform environment of 1 where nothing is occluded), on a product rule as
/// `tests/shrm.rs` integrates it (smooth at roughness 0.6).
fn albedo(lobe: &ShrmLobe, t: f64) -> f64 {
    let q = prt_sh::quadrature::SphereQuadrature::exact_for_degree(300);
    let wo = DVec3::new(t.sin(), 0.0, t.cos());
    q.dirs
        .iter()
        .zip(&q.weights)
        .map(|(d, w)| w * lobe.eval(wo, *d)[0])
        .sum()
}

/// Inside the triangles, the unoccluded per-sample value is the directional albedo at that
/// point's own view elevation: a uniform environment keeps only `b_00`, so the table is
/// exact over `R` and interpolates linearly between its 16 view elevations, which errs by
/// at most the albedo's change across the bracket (it is monotone there); f32 storage adds
/// ~1e-6. (With base colour 1 the Fresnel component's weight `1 − c` is 0.)
#[test]
fn per_sample_lookup_follows_the_view_elevation_inside_triangles() {
    let (scene, _, relit) = floor_scene();
    let s = relit.shrm[0].as_ref().unwrap().unoccluded();
    let lobe = ShrmLobe::of(&metal()).unwrap();
    let mesh = &scene.meshes[0];
    let elevations: Vec<f64> = (0..16)
        .map(|k| (k as f64 + 0.5) / 16.0 * std::f64::consts::FRAC_PI_2)
        .collect();
    let eye = scene.camera.eye;
    let mut checked = 0;
    for (t, tri) in mesh.indices.iter().enumerate() {
        for (u, v) in [(0.2, 0.3), (0.6, 0.1), (0.3, 0.6), (0.45, 0.45), (0.1, 0.1)] {
            let w = [1.0 - u - v, u, v];
            let p: Vec3 = (0..3).map(|i| w[i] * mesh.positions[tri[i] as usize]).sum();
            let theta_o = (eye - p.as_dvec3()).normalize().y.acos();
            let j = elevations.partition_point(|&e| e <= theta_o);
            if j == 0 || j == elevations.len() {
                continue;
            }
            let (a0, a1) = (
                albedo(&lobe, elevations[j - 1]),
                albedo(&lobe, elevations[j]),
            );
            let bound = (a0 - a1).abs() + 1e-5;
            let got = f64::from(s.at(mesh, t, u, v)[0]);
            let truth = albedo(&lobe, theta_o);
            assert!(
                (got - truth).abs() <= bound,
                "triangle {t} ({u}, {v}): θo {theta_o:.3}: {got} against {truth} (bound {bound})"
            );
            checked += 1;
        }
    }
    assert!(checked >= 6, "only {checked} points checked");
}

/// Relighting (the traced occlusion included) and images formed with per-sample lookups are
/// bit-identical on 1 and 2 threads. Image formation looks the SHRM up per sample only on
/// triangles whose vertex radiances spread by more than 40 % of the brightest in some
/// channel: on this evenly lit floor (uniform map, the lobe's albedo changing slowly with the
/// view) none do and the image is the Gouraud image of the same result; with one vertex made
/// three times as bright (a spread of 2/3) the triangles around it are looked up per sample
/// and the image differs from Gouraud's.
#[test]
fn per_sample_image_is_deterministic_and_used() {
    let pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
    };
    let run = |threads: usize| {
        pool(threads).install(|| {
            let (scene, accel, relit) = floor_scene();
            let image = prt_scene_relight::form_image(&scene, &accel, &relit, 0.0).unwrap();
            (scene, accel, relit, image)
        })
    };
    let (_, _, relit_one, one) = run(1);
    let (scene, accel, relit, two) = run(2);
    assert_eq!(relit_one.radiance, relit.radiance);
    let k = |r: &Relit| r.shrm[0].as_ref().unwrap().occlusion().to_vec();
    assert_eq!(k(&relit_one), k(&relit));
    assert_eq!(one.pixels, two.pixels);
    let gouraud = Relit {
        shrm: Vec::new(),
        ..relit.clone()
    };
    let form = |r: &Relit| prt_scene_relight::form_image(&scene, &accel, r, 0.0).unwrap();
    assert_eq!(form(&gouraud).pixels, two.pixels);
    let mut uneven = relit.clone();
    uneven.radiance[0][0] = uneven.radiance[0][0].map(|v| 3.0 * v);
    let uneven_gouraud = Relit {
        shrm: Vec::new(),
        ..uneven.clone()
    };
    assert_ne!(form(&uneven_gouraud).pixels, form(&uneven).pixels);
    let unoccluded = Relit {
        shrm: vec![Some(Arc::new(relit.shrm[0].as_ref().unwrap().unoccluded()))],
        ..relit
    };
    let u2 = form(&unoccluded);
    let u1 = pool(1).install(|| form(&unoccluded));
    assert_eq!(u1.pixels, u2.pixels);
}

/// Inside a closed box every direction the floor's lobe is traced along is blocked, so the
/// occlusion factor `k = 1 − B/U` compares two estimates of the same directional albedo `ρ`
/// of the unit-colour lobe under the uniform map: `B` a mean of `N = 1024` weights
/// `f cos / pdf = G₂/G₁ ∈ [0, 1]` (standard error ≤ 0.5/√N = 0.016; 4σ = 0.0625) and `U` the
/// table's, within its interpolation between elevations (≤ 0.01 at this roughness, as the
/// floor test measures). With `ρ ≥ 0.6` here (GGX at α = 0.36 seen at under 80°),
/// `k ≤ 0.0725 / 0.6 < 0.125`, and the specular (the metal has no diffuse term) is `k` times
/// `U ≤ 1`.
#[test]
fn enclosed_floor_has_no_specular() {
    let cam = Camera::look_at(DVec3::new(0.0, 0.5, 0.8), DVec3::ZERO, 60.0, 8, 8);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("metal", metal());
    scene.add_mesh(prt_scene::test_util::floor_quad(0.5, 0.0), m);
    let walls = prt_scene::test_util::axis_box(Vec3::new(-1.0, -0.5, -1.0), Vec3::splat(1.0));
    scene.add_mesh(walls, m);
    let (accel, bake) = baked(&scene, 4, 64);
    let relit = prt_scene_relight::relight(&scene, &accel, &bake, &shrm_options(0.0)).unwrap();
    let s = relit.shrm[0].as_ref().unwrap();
    assert!(s.occlusion().iter().flatten().all(|k| *k <= 0.125));
    assert!(relit.radiance[0].iter().flatten().all(|v| *v <= 0.125));
}

/// `--glossy auto` picks the SHRM for a lobe too sharp for the baked order — the metal at
/// roughness 0.6 loses more than the bake's 10⁻³ of its energy beyond order 6 (it needs 14
/// bands for 1 %: prt-bake's plan test) — and then relights exactly as `--glossy shrm`, with
/// a note; a diffuse material is never sent there.
#[test]
fn auto_sends_a_lobe_too_sharp_for_the_baked_order_to_the_shrm() {
    let (scene, accel, bake) = floor_bake();
    let (loss, target) = prt_scene_relight::sharp_lobe(&bake, &metal(), "metal", 6)
        .expect("roughness 0.6 is too sharp for order 6");
    assert!(loss > target && target == 1e-3, "{loss} {target}");
    let lambert = Material::Lambert { albedo: [0.5; 3] };
    assert!(prt_scene_relight::sharp_lobe(&bake, &lambert, "metal", 6).is_none());
    let auto = RelightOptions {
        glossy: GlossyPath::Auto,
        ..shrm_options(0.0)
    };
    let a = prt_scene_relight::relight(&scene, &accel, &bake, &auto).unwrap();
    let s = prt_scene_relight::relight(&scene, &accel, &bake, &shrm_options(0.0)).unwrap();
    assert!(a.shrm[0].is_some());
    assert_eq!(a.radiance, s.radiance);
    let notes = a.stats.notes.join(" ");
    assert!(notes.contains("--glossy auto: SHRM"), "{notes}");
}
