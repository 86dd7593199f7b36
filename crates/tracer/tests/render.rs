//! Whole-image properties: camera and environment orientation, determinism across thread
//! counts and tile sizes, and the Monte Carlo convergence rate.

use glam::Vec3;
use prt_scene::{Material, Scene};
use prt_tracer::{test_util, Mode, RenderSettings, Renderer};

fn quiet(spp: u32, bounces: i32, seed: u64) -> RenderSettings {
    RenderSettings {
        spp,
        bounces,
        seed,
        progress: false,
        ..RenderSettings::default()
    }
}

/// A 6×3 lat-long map whose texel (col, row) has radiance (col, row, 1).
fn labelled_map() -> prt_scene::Environment {
    let texels = (0..18)
        .map(|i| [(i % 6) as f32, (i / 6) as f32, 1.0])
        .collect();
    test_util::latlong_environment(6, 3, texels)
}

/// Background pixels show the environment with CONVENTIONS' orientation: +X is `u = 0.25`
/// (column 1 of 6), the horizon row 1 of 3; the top image row looks up (row 0), the left
/// column towards −Z (column 0) and the right towards +Z (column 2) for a camera looking +X.
#[test]
fn test01_camera_and_environment_orientation() {
    let env = labelled_map();
    let narrow = test_util::camera(Vec3::ZERO, Vec3::X, 10.0, 5, 5);
    let scene = test_util::scene(narrow, env.clone(), vec![], vec![]);
    let out = Renderer::new(&scene, quiet(4, 0, 0))
        .unwrap()
        .render()
        .unwrap();
    assert!(
        out.radiance.iter().all(|l| *l == Vec3::new(1.0, 1.0, 1.0)),
        "{:?}",
        out.radiance
    );

    let wide = test_util::camera(Vec3::ZERO, Vec3::X, 100.0, 9, 9);
    let scene = test_util::scene(wide, env, vec![], vec![]);
    let out = Renderer::new(&scene, quiet(1, 0, 0))
        .unwrap()
        .render()
        .unwrap();
    let px = |x: usize, y: usize| out.radiance[y * 9 + x];
    assert_eq!(px(4, 0).y, 0.0, "top row looks up");
    assert_eq!(px(4, 8).y, 2.0, "bottom row looks down");
    assert_eq!(px(0, 4).x, 0.0, "left column looks towards -Z");
    assert_eq!(px(8, 4).x, 2.0, "right column looks towards +Z");
}

fn test_scene(width: u32, height: u32) -> Scene {
    let texels = (0..32)
        .map(|i| {
            let (c, r) = ((i % 8) as f32, (i / 8) as f32);
            [2.0 - 0.5 * r + 0.1 * c, 1.5 - 0.3 * r, 1.0 + 0.05 * c]
        })
        .collect();
    let cam = test_util::camera(
        Vec3::new(0.0, 1.2, 3.0),
        Vec3::new(0.0, 0.5, 0.0),
        45.0,
        width,
        height,
    );
    let floor = test_util::quad(
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 0.0),
    );
    let mut sphere = test_util::uv_sphere(Vec3::new(0.0, 0.6, 0.0), 0.6, 16, 32, true);
    sphere.material = 1;
    let mut mirror = test_util::uv_sphere(Vec3::new(1.0, 0.3, 0.5), 0.3, 12, 24, true);
    mirror.material = 2;
    test_util::scene(
        cam,
        test_util::latlong_environment(8, 4, texels),
        vec![
            Material::Lambert {
                albedo: [0.6, 0.5, 0.4],
            },
            Material::Phong {
                albedo: [0.3, 0.3, 0.5],
                specular: [0.4; 3],
                exponent: 30.0,
            },
            Material::Mirror {
                albedo: [0.1; 3],
                specular: [0.8; 3],
            },
        ],
        vec![floor, sphere, mirror],
    )
}

/// Same image, bit for bit, on 1 or 2 threads and with different tile sizes, in every mode.
#[test]
fn test02_deterministic_across_threads_and_tiles() {
    let scene = test_scene(23, 17);
    for mode in [
        Mode::Path,
        Mode::Unshadowed,
        Mode::AmbientOcclusion { max_distance: None },
    ] {
        let run = |threads: usize, tile_size: u32| {
            let s = RenderSettings {
                threads: Some(threads),
                tile_size,
                mode,
                aovs: true,
                ..quiet(8, -1, 5)
            };
            Renderer::new(&scene, s).unwrap().render().unwrap()
        };
        let (a, b, c) = (run(1, 16), run(2, 16), run(2, 5));
        let bits = |o: &prt_tracer::RenderOutput| -> Vec<u32> {
            o.radiance
                .iter()
                .flat_map(|l| l.to_array())
                .map(f32::to_bits)
                .collect()
        };
        assert_eq!(bits(&a), bits(&b), "{mode:?}: 1 vs 2 threads");
        assert_eq!(bits(&a), bits(&c), "{mode:?}: tile 16 vs 5");
        let var = |o: &prt_tracer::RenderOutput| o.aovs.as_ref().unwrap().variance.clone();
        assert_eq!(var(&a), var(&c));
        // Also with rayon pools built outside the renderer.
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let s = RenderSettings {
            mode,
            aovs: true,
            ..quiet(8, -1, 5)
        };
        let d = pool.install(|| Renderer::new(&scene, s).unwrap().render().unwrap());
        assert_eq!(bits(&a), bits(&d));
    }
    // A different seed gives a different image.
    let a = Renderer::new(&scene, quiet(4, 1, 0))
        .unwrap()
        .render()
        .unwrap();
    let b = Renderer::new(&scene, quiet(4, 1, 1))
        .unwrap()
        .render()
        .unwrap();
    assert_ne!(a.radiance, b.radiance);
}

/// RMSE falls as spp^(−1/2). Reference: 4096 spp; its own noise is removed from each MSE by
/// subtracting the mean of its variance AOV. Error images at spp 4…256 use other seeds, so the
/// seven MSEs are independent. Each MSE averages 16·12·3 = 576 squared errors, so ln RMSE has
/// a standard deviation near 1/sqrt(2·576) ≈ 0.03 (more with heavy tails); the least-squares
/// slope over ln spp (Σ(x − x̄)² = 28 (ln 2)²) then has a standard error ≈ 0.03/3.67 ≈ 0.008.
/// Tolerance 0.06: about 7 standard errors, leaving room for heavier-than-Gaussian tails.
#[test]
fn test03_rmse_falls_as_inverse_sqrt_spp() {
    let scene = test_scene(16, 12);
    let reference = Renderer::new(
        &scene,
        RenderSettings {
            aovs: true,
            ..quiet(4096, 1, 1000)
        },
    )
    .unwrap()
    .render()
    .unwrap();
    let ref_noise = reference
        .aovs
        .as_ref()
        .unwrap()
        .variance
        .iter()
        .map(|v| f64::from(v.element_sum()))
        .sum::<f64>()
        / (3 * reference.radiance.len()) as f64;
    let mut xs = Vec::new();
    let mut ys = Vec::new();
    for (k, spp) in [4u32, 8, 16, 32, 64, 128, 256].into_iter().enumerate() {
        let img = Renderer::new(&scene, quiet(spp, 1, k as u64 + 1))
            .unwrap()
            .render()
            .unwrap();
        let mse = img
            .radiance
            .iter()
            .zip(&reference.radiance)
            .map(|(a, b)| f64::from((*a - *b).length_squared()))
            .sum::<f64>()
            / (3 * img.radiance.len()) as f64;
        xs.push(f64::from(spp).ln());
        ys.push(0.5 * (mse - ref_noise).ln());
    }
    let n = xs.len() as f64;
    let (mx, my) = (xs.iter().sum::<f64>() / n, ys.iter().sum::<f64>() / n);
    let slope = xs
        .iter()
        .zip(&ys)
        .map(|(x, y)| (x - mx) * (y - my))
        .sum::<f64>()
        / xs.iter().map(|x| (x - mx).powi(2)).sum::<f64>();
    eprintln!("RMSE slope {slope:.4} (ln RMSE {ys:?})");
    assert!((slope + 0.5).abs() < 0.06, "slope {slope}, ln RMSE {ys:?}");
}

/// Bad input is an error, not a panic.
#[test]
fn test04_bad_settings_and_camera_are_errors() {
    let scene = test_scene(8, 8);
    assert!(Renderer::new(&scene, quiet(0, 0, 0)).is_err());
    assert!(Renderer::new(&scene, quiet(1, -2, 0)).is_err());
    let mut bad = scene.clone();
    bad.camera.fov_y_deg = 0.0;
    assert!(Renderer::new(&bad, quiet(1, 0, 0))
        .unwrap()
        .render()
        .is_err());
    bad.camera = scene.camera.clone();
    bad.camera.target = bad.camera.eye;
    assert!(Renderer::new(&bad, quiet(1, 0, 0))
        .unwrap()
        .render()
        .is_err());
    let mut bad = scene.clone();
    bad.meshes[0].material = 9;
    assert!(Renderer::new(&bad, quiet(1, 0, 0)).is_err());
}
