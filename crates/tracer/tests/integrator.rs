//! The path tracer against closed forms and quadrature: white furnace, direct lighting of a
//! convex object with every BRDF, ambient occlusion under a sphere, the unshadowed mode.
//!
//! Tolerances: a Monte Carlo mean is compared with `Z · SE`, `SE` the standard error measured
//! from independent replicas (the same point repeated under different stream indices), and
//! `Z = 5` (two-sided p ≈ 6e-7 per comparison; all comparisons here together stay below 1e-4).
//! Quadrature error of the references is bounded separately and added.

use glam::Vec3;
use prt_scene::{Environment, Material, Scene};
use prt_tracer::{test_util, MisHeuristic, Mode, RenderSettings, Renderer, SurfacePoint};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

const Z: f64 = 5.0;

fn settings(mode: Mode, bounces: i32) -> RenderSettings {
    RenderSettings {
        mode,
        bounces,
        progress: false,
        ..RenderSettings::default()
    }
}

/// Mean and standard error of `replicas` independent estimates of each point's radiance
/// (each with `spp` samples).
fn estimate(r: &Renderer, point: &SurfacePoint, replicas: usize, spp: u32) -> (Vec3, Vec3) {
    let points = vec![point.clone(); replicas];
    let est = r.radiance_at_points(&points, spp).unwrap();
    let n = replicas as f32;
    let mean = est.iter().copied().sum::<Vec3>() / n;
    let var = est.iter().map(|e| (*e - mean) * (*e - mean)).sum::<Vec3>() / (n - 1.0);
    (mean, (var / n).map(f32::sqrt))
}

fn small_map() -> Environment {
    // An arbitrary 8×4 map, colours varying strongly between texels.
    let mut rng = Pcg64::seed_from_u64(99);
    let texels = (0..32)
        .map(|_| {
            [
                rng.random_range(0.0..3.0),
                rng.random_range(0.0..2.0),
                rng.random_range(0.0..1.0),
            ]
        })
        .collect();
    test_util::latlong_environment(8, 4, texels)
}

/// `Σ_texels L_texel ∫_texel f(ωi, ωo) cos⁺θi dω` with `sub × sub` equal-solid-angle cells per
/// texel (midpoints in φ and cos θ), plus the mirror's delta lobe.
fn quadrature(env: &Environment, mat: &Material, n: Vec3, wo: Vec3, sub: usize) -> Vec3 {
    let (w, h) = (env.image.width, env.image.height);
    let mut sum = glam::DVec3::ZERO;
    for j in 0..h {
        let (c0, c1) = (
            (PI * j as f64 / h as f64).cos(),
            (PI * (j + 1) as f64 / h as f64).cos(),
        );
        for i in 0..w {
            let l = Vec3::from_array(env.image.texel(i, j)).as_dvec3();
            let mut acc = glam::DVec3::ZERO;
            for a in 0..sub {
                let phi = 2.0 * PI * (i as f64 + (a as f64 + 0.5) / sub as f64) / w as f64;
                for b in 0..sub {
                    let ct = c0 + (c1 - c0) * (b as f64 + 0.5) / sub as f64;
                    let st = (1.0 - ct * ct).max(0.0).sqrt();
                    let d = glam::DVec3::new(phi.sin() * st, ct, -phi.cos() * st).as_vec3();
                    let cos = n.dot(d);
                    if cos > 0.0 {
                        acc += (prt_shading::eval(mat, n, wo, d) * cos).as_dvec3();
                    }
                }
            }
            let solid = (2.0 * PI / w as f64) * (c0 - c1) / (sub * sub) as f64;
            sum += l * acc * solid;
        }
    }
    if let Material::Mirror { specular, .. } = mat {
        let r = 2.0 * n.dot(wo) * n - wo;
        sum += (Vec3::from_array(*specular) * Vec3::from_array(env.radiance(r))).as_dvec3();
    }
    sum.as_vec3()
}

fn materials() -> Vec<Material> {
    let (a, s) = ([0.5, 0.4, 0.3], [0.4, 0.45, 0.5]);
    vec![
        Material::Lambert {
            albedo: [0.9, 0.6, 0.3],
        },
        Material::Phong {
            albedo: a,
            specular: s,
            exponent: 20.0,
        },
        Material::BlinnPhong {
            albedo: a,
            specular: s,
            exponent: 30.0,
        },
        Material::Ward {
            albedo: a,
            specular: s,
            roughness: 0.3,
        },
        Material::CookTorrance {
            albedo: a,
            specular: s,
            roughness: 0.3,
            ior: 1.5,
        },
        Material::Mirror {
            albedo: [0.2, 0.3, 0.1],
            specular: [0.7, 0.6, 0.5],
        },
        Material::Pbr {
            base_color: [0.8, 0.5, 0.3],
            metallic: 0.0,
            roughness: 0.4,
            base_color_texture: None,
            metallic_roughness_texture: None,
        },
        Material::Pbr {
            base_color: [0.9, 0.7, 0.4],
            metallic: 1.0,
            roughness: 0.6,
            base_color_texture: None,
            metallic_roughness_texture: None,
        },
    ]
}

fn scene_with(env: Environment, meshes: Vec<prt_scene::Mesh>) -> Scene {
    let cam = test_util::camera(Vec3::new(0.0, 0.0, 5.0), Vec3::ZERO, 40.0, 8, 8);
    test_util::scene(cam, env, materials(), meshes)
}

fn sphere_points(mat: &Material) -> Vec<SurfacePoint> {
    let sphere = test_util::uv_sphere(Vec3::ZERO, 1.0, 8, 16, true);
    [3usize, 17, 40, 61, 90]
        .iter()
        .map(|&k| {
            let p = sphere.positions[k % sphere.positions.len()];
            let n = p.normalize();
            // A view direction 50° off the normal, in a varying azimuth.
            let t = n.any_orthonormal_vector();
            let view = (n * 0.64 + t * 0.77).normalize();
            SurfacePoint {
                position: p,
                normal: n,
                view_dir: view,
                material: *mat,
            }
        })
        .collect()
}

/// Bounces 0 on a convex object: the estimate equals quadrature over the map's texels.
/// Quadrature with 48×48 cells per texel is within 2e-3 relative of the integral for these
/// lobes (checked: doubling to 96 changes it by less than 5e-4 relative), added to the tolerance.
#[test]
fn test01_direct_light_matches_texel_quadrature_every_brdf() {
    let env = small_map();
    let sphere = test_util::uv_sphere(Vec3::ZERO, 1.0, 8, 16, true);
    let scene = scene_with(env.clone(), vec![sphere]);
    let runs = [
        (Mode::Path, MisHeuristic::Power),
        (Mode::Path, MisHeuristic::Balance),
        (Mode::Unshadowed, MisHeuristic::Power),
    ];
    for (mode, mis) in runs {
        let r = Renderer::new(
            &scene,
            RenderSettings {
                mis,
                ..settings(mode, 0)
            },
        )
        .unwrap();
        for mat in materials() {
            for p in sphere_points(&mat) {
                let want = quadrature(&env, &mat, p.normal, p.view_dir, 48);
                let (got, se) = estimate(&r, &p, 64, 64);
                for c in 0..3 {
                    let tol = Z * f64::from(se[c]) + 2e-3 * f64::from(want[c]) + 1e-6;
                    assert!(
                        f64::from((got[c] - want[c]).abs()) <= tol,
                        "{mode:?} {mis:?} {mat:?} at {:?}: got {got} want {want} (se {se})",
                        p.position
                    );
                }
            }
        }
    }
}

/// Unshadowed ignores visibility: a floor point under a sphere gets the unoccluded integral,
/// while the shadowed estimate is clearly smaller.
#[test]
fn test02_unshadowed_ignores_occluders() {
    let env = small_map();
    let sphere = test_util::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 1.0, 32, 64, true);
    let scene = scene_with(env.clone(), vec![sphere]);
    let mat = Material::Lambert {
        albedo: [0.8, 0.8, 0.8],
    };
    let p = SurfacePoint {
        position: Vec3::ZERO,
        normal: Vec3::Y,
        view_dir: Vec3::new(0.0, 0.6, 0.8),
        material: mat,
    };
    let want = quadrature(&env, &mat, Vec3::Y, p.view_dir, 48);
    let r = Renderer::new(&scene, settings(Mode::Unshadowed, 0)).unwrap();
    let (got, se) = estimate(&r, &p, 64, 64);
    for c in 0..3 {
        assert!(
            f64::from((got[c] - want[c]).abs()) <= Z * f64::from(se[c]) + 2e-3 * f64::from(want[c])
        );
    }
    let shadowed = Renderer::new(&scene, settings(Mode::Path, 0)).unwrap();
    let (got, _) = estimate(&shadowed, &p, 16, 64);
    assert!(got.element_sum() < 0.9 * want.element_sum());
}

/// Ambient occlusion at a floor point under a sphere of radius R centred at height d: the
/// occluded cosine-weighted fraction is (R/d)² (the sphere subtends a cap of half-angle
/// asin(R/d) around the normal, and ∫cap cos/π dω = sin²(asin(R/d))). The tessellated sphere
/// (64 × 128) is inscribed: its silhouette radius is at least R cos(π/64), so the fraction is
/// low by at most 2(1 − cos(π/64)) (R/d)² ≈ 0.24% of it, added to the tolerance. The standard
/// error is binomial, sqrt(p(1−p)/N).
#[test]
fn test03_ambient_occlusion_under_sphere() {
    let (radius, height) = (0.5f32, 1.25f32);
    let floor = test_util::quad(
        Vec3::new(-5.0, 0.0, -5.0),
        Vec3::new(0.0, 0.0, 10.0),
        Vec3::new(10.0, 0.0, 0.0),
    );
    let sphere = test_util::uv_sphere(Vec3::new(0.0, height, 0.0), radius, 64, 128, true);
    let scene = scene_with(
        test_util::constant_environment([1.0; 3]),
        vec![floor, sphere],
    );
    let mat = Material::Lambert { albedo: [1.0; 3] };
    let p = SurfacePoint {
        position: Vec3::ZERO,
        normal: Vec3::Y,
        view_dir: Vec3::Y,
        material: mat,
    };
    let r = Renderer::new(
        &scene,
        settings(Mode::AmbientOcclusion { max_distance: None }, 0),
    )
    .unwrap();
    let n = 200_000usize;
    let est = r
        .radiance_at_points(&vec![p.clone(); n / 100], 100)
        .unwrap();
    let visible = est.iter().map(|e| f64::from(e.x)).sum::<f64>() / (n / 100) as f64;
    let occluded_want = f64::from((radius / height).powi(2));
    let se = (occluded_want * (1.0 - occluded_want) / n as f64).sqrt();
    let bias = 2.0 * (1.0 - (PI / 64.0).cos()) * occluded_want;
    let err = (1.0 - visible) - occluded_want;
    assert!(
        err.abs() <= Z * se + bias,
        "occluded {} want {occluded_want} (se {se})",
        1.0 - visible
    );
    // Within a max distance shorter than the gap to the sphere nothing is occluded.
    let short = Renderer::new(
        &scene,
        settings(
            Mode::AmbientOcclusion {
                max_distance: Some(0.7),
            },
            0,
        ),
    )
    .unwrap();
    let est = short.radiance_at_points(&vec![p; 100], 100).unwrap();
    assert!(est.iter().all(|e| *e == Vec3::ONE));
}

/// White furnace: albedo-1 Lambert under uniform radiance 1 reflects exactly 1 everywhere, for
/// a convex sphere and a concave open box (interreflections), with unlimited bounces and
/// Russian roulette. Flat shading makes shading and geometric normals agree, so no energy is
/// lost at grazing angles. Checked per image pixel mean (all pixels, radiance 1) with the
/// standard error from the renderer's own variance AOV: |mean − 1| ≤ Z · sqrt(Σ var_i) / N.
#[test]
fn test04_white_furnace_convex_and_concave() {
    let white = Material::Lambert { albedo: [1.0; 3] };
    let shapes = [
        test_util::uv_sphere(Vec3::ZERO, 1.0, 16, 32, false),
        test_util::open_box(Vec3::ZERO, 1.0),
    ];
    for (k, shape) in shapes.into_iter().enumerate() {
        // Looking down into the box (or at the sphere) from above and to the side.
        let cam = test_util::camera(Vec3::new(0.6, 3.0, 1.5), Vec3::ZERO, 45.0, 24, 24);
        let scene = test_util::scene(
            cam,
            test_util::constant_environment([1.0; 3]),
            vec![white],
            vec![shape],
        );
        let s = RenderSettings {
            spp: 64,
            bounces: -1,
            aovs: true,
            progress: false,
            ..RenderSettings::default()
        };
        let out = Renderer::new(&scene, s).unwrap().render().unwrap();
        let aovs = out.aovs.unwrap();
        let n = out.radiance.len() as f64;
        let hits = aovs.depth.iter().filter(|d| **d > 0.0).count();
        assert!(
            hits > out.radiance.len() / 3,
            "shape {k}: only {hits} pixels see it"
        );
        for c in 0..3 {
            let mean = out.radiance.iter().map(|l| f64::from(l[c])).sum::<f64>() / n;
            let se = aovs
                .variance
                .iter()
                .map(|v| f64::from(v[c]))
                .sum::<f64>()
                .sqrt()
                / n;
            assert!(
                (mean - 1.0).abs() <= Z * se + 1e-6,
                "shape {k} channel {c}: mean {mean} se {se}"
            );
        }
        // Every pixel individually is within 6 of its own standard errors (max over 576
        // pixels of |z| with 64-sample variance estimates).
        for (l, v) in out.radiance.iter().zip(&aovs.variance) {
            assert!(
                (l.x - 1.0).abs() <= 6.0 * v.x.sqrt() + 1e-5,
                "pixel {l} var {v}"
            );
        }
        assert_eq!(out.invalid_samples, 0);
    }
}

/// Bounce counting: in the open box under uniform light with albedo 1, each extra bounce adds
/// the energy of one more interreflection, so the mean radiance increases strictly with B and
/// B = -1 (unlimited) reaches 1.
#[test]
fn test05_bounces_increase_monotonically_to_furnace() {
    let white = Material::Lambert { albedo: [1.0; 3] };
    let cam = test_util::camera(Vec3::new(0.3, 3.0, 0.5), Vec3::ZERO, 30.0, 16, 16);
    let scene = test_util::scene(
        cam,
        test_util::constant_environment([1.0; 3]),
        vec![white],
        vec![test_util::open_box(Vec3::ZERO, 1.0)],
    );
    let mut means = Vec::new();
    for b in [0, 1, 2, -1] {
        let s = RenderSettings {
            spp: 64,
            bounces: b,
            progress: false,
            ..RenderSettings::default()
        };
        let out = Renderer::new(&scene, s).unwrap().render().unwrap();
        means.push(
            out.radiance.iter().map(|l| f64::from(l.y)).sum::<f64>() / out.radiance.len() as f64,
        );
    }
    assert!(
        means[0] < means[1] && means[1] < means[2] && means[2] < means[3],
        "{means:?}"
    );
    assert!(means[0] < 0.9 && (means[3] - 1.0).abs() < 0.01, "{means:?}");
}

/// Vertex AO without speckles: at every vertex of a smooth convex sphere (radial normals, which
/// lie in each vertex's normal cone, so nothing is above the tangent plane) every AO ray must
/// escape: AO is exactly 1. Checked with the sphere scaled by 1e-3 and translated to 1e4, the
/// way a bake calls `radiance_at_points`.
#[test]
fn test06_vertex_ambient_occlusion_has_no_speckles() {
    for (center, radius) in [
        (Vec3::ZERO, 1e-3f32),
        (Vec3::new(1e4, 1e4, -1e4), 1.0),
        (Vec3::ZERO, 1.0),
    ] {
        let sphere = test_util::uv_sphere(center, radius, 24, 48, true);
        let points: Vec<SurfacePoint> = sphere
            .positions
            .iter()
            .zip(&sphere.normals)
            .step_by(3)
            .map(|(&p, &n)| SurfacePoint {
                position: p,
                normal: n,
                view_dir: n,
                material: Material::Lambert { albedo: [1.0; 3] },
            })
            .collect();
        let scene = scene_with(test_util::constant_environment([1.0; 3]), vec![sphere]);
        let r = Renderer::new(
            &scene,
            settings(Mode::AmbientOcclusion { max_distance: None }, 0),
        )
        .unwrap();
        let ao = r.radiance_at_points(&points, 64).unwrap();
        let speckles = ao.iter().filter(|a| a.x != 1.0).count();
        assert_eq!(
            speckles,
            0,
            "{speckles} of {} vertices self-occluded at {center} × {radius}",
            ao.len()
        );
    }
}
