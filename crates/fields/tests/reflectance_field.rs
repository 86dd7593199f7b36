//! Reflectance fields (issue 16) against a closed form: a Lambertian floor that nothing
//! shadows, seen from above, under a lat-long map with a bright "sun" texel. Each pixel is
//! `(a/π) ∫ L(ω) max(0, cos θ) dω`, exactly `(a/π) Σ_texels L_t Δφ (sin²θ₁ − sin²θ₀)/2` over the
//! texels above the horizon — computed here per texel, sharing no code with the sampler.

use glam::{DVec3, Vec3};
use prt_fields::relight::{relight_field, FieldOptions, Reconstruction};
use prt_fields::sample::{field_bake, sample_field, ReflectanceSettings};
use prt_scene::{Camera, EnvImage, Environment, Mapping, Material, Mesh, Scene};
use prt_tracer::Accel;
use std::f64::consts::PI;

const ALBEDO: f32 = 0.6;

fn scene(env_w: usize, env_h: usize) -> Scene {
    // A sky gradient plus one sun texel 40 times brighter, above the horizon.
    let texels = (0..env_w * env_h)
        .map(|k| {
            let (c, r) = (k % env_w, k / env_w);
            let sky = 0.5 + 0.5 * (c as f32 / env_w as f32) + 0.25 * (r as f32 / env_h as f32);
            let sun = if (c, r) == (env_w / 3, env_h / 5) {
                40.0
            } else {
                0.0
            };
            [sky + sun, 0.8 * sky + sun, 0.6 * sky + 0.5 * sun]
        })
        .collect();
    let env = Environment {
        image: EnvImage {
            width: env_w,
            height: env_h,
            texels,
        },
        mapping: Mapping::LatLong,
        rotation_y_deg: 0.0,
    };
    // Looking straight down at a floor much larger than the view.
    let cam = Camera {
        up: DVec3::Z,
        ..Camera::look_at(DVec3::new(0.0, 1.0, 0.0), DVec3::ZERO, 30.0, 8, 6)
    };
    let mut s = Scene::new(cam, env);
    let m = s.add_material(
        "floor",
        Material::Lambert {
            albedo: [ALBEDO; 3],
        },
    );
    let p = [
        [-10.0, 0.0, -10.0],
        [10.0, 0.0, -10.0],
        [10.0, 0.0, 10.0],
        [-10.0, 0.0, 10.0],
    ];
    s.add_mesh(
        Mesh {
            name: "floor".into(),
            positions: p.iter().map(|v| Vec3::from_array(*v)).collect(),
            normals: vec![Vec3::Y; 4],
            indices: vec![[0, 2, 1], [0, 3, 2]],
            ..Mesh::default()
        },
        m,
    );
    s
}

/// Direct light only, one path per sample (unused without bounces).
fn direct(directions: [u32; 2], pixel_samples: u32, seed: u64) -> ReflectanceSettings {
    ReflectanceSettings {
        directions,
        bounces: 0,
        rays: 1,
        pixel_samples,
        seed,
        progress: false,
        scalar: prt_bakefile::ScalarType::F32,
    }
}

/// `(a/π) ∫ L cos⁺ dω` per channel, exactly for the piecewise-constant map.
fn exact(s: &Scene) -> [f64; 3] {
    let img = &s.environment.image;
    let mut e = [0.0f64; 3];
    for r in 0..img.height / 2 {
        let (t0, t1) = (
            PI * r as f64 / img.height as f64,
            PI * (r + 1) as f64 / img.height as f64,
        );
        let w = 2.0 * PI / img.width as f64 * (t1.sin().powi(2) - t0.sin().powi(2)) / 2.0;
        for c in 0..img.width {
            let l = img.texels[r * img.width + c];
            for ch in 0..3 {
                e[ch] += f64::from(l[ch]) * w;
            }
        }
    }
    e.map(|v| v * f64::from(ALBEDO) / PI)
}

#[test]
fn an_unshadowed_lambert_floor_relights_to_its_irradiance() {
    // The direction grid and the fine grid are the map's texel grid: every fine cell holds one
    // texel (so the lighting integral over it is exact) and the sampled R = (a/π) cos θ at the
    // cell centre. What remains is the midpoint rule for cos θ over a cell: over a row
    // ∫ cos θ dω = sin 2θ_c sin Δθ / 2 · Δφ while cos θ_c Δω = sin 2θ_c sin(Δθ/2) Δφ, a ratio of
    // exactly cos(Δθ/2) in every row above the horizon (a row boundary here). So the relit
    // value is the exact one divided by cos(Δθ/2), to f32 rounding (1e-5 relative allowed).
    let (w, h) = (64usize, 32usize);
    let s = scene(w, h);
    let accel = Accel::build(&s).unwrap();
    let settings = direct([w as u32, h as u32], 2, 7);
    let (field, stats) = sample_field(&s, &accel, &settings).unwrap();
    assert_eq!(stats.pixels, 48, "every pixel sees the floor");
    let bake = field_bake(&s, field, &settings);
    // Through the file format and back.
    let bytes = prt_bakefile::encode(&bake, prt_bakefile::ScalarType::F32).unwrap();
    let bake = prt_bakefile::decode(&bytes).unwrap();
    let field = prt_fields::relight::check_field(&s, &bake, std::path::Path::new("t"))
        .unwrap()
        .clone();
    let want = exact(&s);
    let dtheta = PI / h as f64;
    for method in [Reconstruction::Linear, Reconstruction::Nearest] {
        let opt = FieldOptions {
            reconstruction: method,
            fine: [w as u32, h as u32],
            rotate_y_deg: 0.0,
            timing_frames: 1,
            compression: None,
        };
        let (img, _) = relight_field(&s, &accel, &bake, &field, &opt).unwrap();
        for p in &img.pixels {
            for c in 0..3 {
                let got = f64::from(p[c]);
                let expect = want[c] / (dtheta / 2.0).cos();
                let tol = expect * 1e-5;
                assert!(
                    (got - expect).abs() <= tol,
                    "{method:?} channel {c}: {got} vs {expect} (exact {}, tolerance {tol:.2e})",
                    want[c]
                );
            }
        }
    }
    // On a 4× finer integration grid the reconstruction is linear interpolation of cos θ
    // between the samples (error ≤ Δθ²/8, relative to cos θ's range) plus the constant held
    // beyond the first row's centre at the pole (1 − cos(Δθ/2) ≈ Δθ²/8) and the fine cells'
    // own midpoint rule (Δθ²/128): within Δθ²/4 of the exact value, relative.
    // Wavelet interpolation: 5/3 is linear interpolation away from the poles; 9/7 is a
    // smoother refinement of the same samples, held to the same bound on cos θ.
    for method in [
        Reconstruction::Linear,
        Reconstruction::LeGall53,
        Reconstruction::Cdf97,
    ] {
        let opt = FieldOptions {
            reconstruction: method,
            fine: [4 * w as u32, 4 * h as u32],
            rotate_y_deg: 0.0,
            timing_frames: 1,
            compression: None,
        };
        let (img, _) = relight_field(&s, &accel, &bake, &field, &opt).unwrap();
        let got = f64::from(img.pixels[0][0]);
        let rel = (got - want[0]).abs() / want[0];
        eprintln!(
            "{method:?}, 4× finer grid: relative error {rel:.2e} (Δθ²/4 = {:.2e})",
            dtheta * dtheta / 4.0
        );
        assert!(
            rel <= dtheta * dtheta / 4.0,
            "{method:?}: {got} vs {}",
            want[0]
        );
    }
}

#[test]
fn a_field_of_another_scene_or_a_bad_grid_is_refused() {
    let s = scene(16, 8);
    let accel = Accel::build(&s).unwrap();
    let settings = direct([16, 8], 1, 1);
    let (field, _) = sample_field(&s, &accel, &settings).unwrap();
    let bake = field_bake(&s, field, &settings);
    let mut other = s.clone();
    other.meshes[0].positions[0].x += 1.0;
    let e = prt_fields::relight::check_field(&other, &bake, std::path::Path::new("f.prtb"))
        .unwrap_err();
    assert!(e.to_string().contains("re-sample"), "{e}");
    let field = bake.reflectance.clone().unwrap();
    let opt = FieldOptions {
        reconstruction: Reconstruction::Linear,
        fine: [8, 8],
        rotate_y_deg: 0.0,
        timing_frames: 1,
        compression: None,
    };
    let e = relight_field(&s, &accel, &bake, &field, &opt).unwrap_err();
    assert!(e.to_string().contains("at least the sampled grid"), "{e}");
    for bad in [[1, 8], [16, 0]] {
        let st = ReflectanceSettings {
            directions: bad,
            ..settings.clone()
        };
        assert!(sample_field(&s, &accel, &st).is_err());
    }
}

#[test]
fn wavelet_compression_is_exact_with_every_coefficient_and_bounded_by_its_error() {
    use prt_fields::relight::{fine_lighting, reconstruct, Budget, Compression};
    let (w, h) = (16usize, 8usize);
    let s = scene(w, h);
    let accel = Accel::build(&s).unwrap();
    let settings = direct([w as u32, h as u32], 1, 3);
    let (field, _) = sample_field(&s, &accel, &settings).unwrap();
    let bake = field_bake(&s, field.clone(), &settings);
    let fine = [32u32, 16u32];
    let run = |compression| {
        let opt = FieldOptions {
            reconstruction: Reconstruction::Linear,
            fine,
            rotate_y_deg: 0.0,
            timing_frames: 1,
            compression,
        };
        relight_field(&s, &accel, &bake, &field, &opt).unwrap()
    };
    let (full, _) = run(None);
    let n = (fine[0] * fine[1]) as usize;
    // The lighting's and a function's L2 norms on the fine grid, for the bound below.
    let lighting = fine_lighting(&s, fine, 0.0);
    let mut f = vec![0.0; n];
    reconstruct(
        Reconstruction::Linear,
        field.directions,
        &field.function(0, &mut Vec::new())[..w * h],
        fine,
        &mut f,
    )
    .unwrap();
    let f_norm = f.iter().map(|v| v * v).sum::<f64>().sqrt();
    let l_norm = lighting.iter().map(|l| l[0] * l[0]).sum::<f64>().sqrt();
    for wavelet in prt_wavelet::Wavelet::ALL {
        // Every coefficient: the relit image is the uncompressed one (f32 rounding of the
        // coefficients and of the lighting's projection: a few 1e-7 relative).
        let (all, stats) = run(Some(Compression {
            wavelet,
            budget: Budget::Coefficients(n),
            error_pixels: None,
        }));
        assert!(stats.rf_rel_l2.unwrap() < 1e-12, "{wavelet:?}");
        assert!(stats.rf_rel_h1.unwrap() < 1e-12, "{wavelet:?}");
        for (a, b) in all.pixels.iter().zip(&full.pixels) {
            assert!(
                (a[0] - b[0]).abs() <= 1e-5 * b[0],
                "{wavelet:?}: {} vs {}",
                a[0],
                b[0]
            );
        }
        // 24 coefficients: each pixel's error is ⟨f − f_K, ℓ⟩ ≤ ‖f − f_K‖ ‖ℓ‖ (Cauchy–Schwarz),
        // and every pixel holds the same function (an unshadowed floor seen from above), so
        // ‖f − f_K‖ = rf_rel_l2 · ‖f‖.
        let (some, stats) = run(Some(Compression {
            wavelet,
            budget: Budget::Coefficients(24),
            error_pixels: None,
        }));
        let e = stats.rf_rel_l2.unwrap();
        assert!(e > 0.0 && e < 1.0, "{wavelet:?}: {e}");
        // The H¹ error exists and is finite (its value is a measurement, not a bound).
        let h1 = stats.rf_rel_h1.unwrap();
        assert!(h1 > 0.0 && h1.is_finite(), "{wavelet:?}: H¹ {h1}");
        assert_eq!(stats.mean_coefficients, Some(24.0));
        // The error measured over a subsample of 7 pixels: the same functions kept (the same
        // image, bit for bit) and, as every pixel holds the same function, the same error.
        let (sub, sub_stats) = run(Some(Compression {
            wavelet,
            budget: Budget::Coefficients(24),
            error_pixels: Some(7),
        }));
        assert!(sub.pixels == some.pixels, "{wavelet:?}");
        let (measured, all_pixels) = (
            sub_stats.rf_error_pixels.unwrap(),
            stats.rf_error_pixels.unwrap(),
        );
        assert!(
            measured <= 7 && measured < all_pixels,
            "{measured} of {all_pixels}"
        );
        assert!(
            (sub_stats.rf_rel_l2.unwrap() - e).abs() <= 1e-9 * e,
            "{wavelet:?}"
        );
        let bound = e * f_norm * l_norm * 1.0001 + 1e-6;
        for (a, b) in some.pixels.iter().zip(&full.pixels) {
            assert!(
                f64::from((a[0] - b[0]).abs()) <= bound,
                "{wavelet:?}: {} vs {} (bound {bound})",
                a[0],
                b[0]
            );
        }
        // An error target is met, with fewer coefficients than the grid.
        let (_, stats) = run(Some(Compression {
            wavelet,
            budget: Budget::RelativeError(0.01),
            error_pixels: None,
        }));
        assert!(stats.rf_rel_l2.unwrap() <= 0.01, "{wavelet:?}");
        assert!(stats.mean_coefficients.unwrap() < n as f64);
    }
}
