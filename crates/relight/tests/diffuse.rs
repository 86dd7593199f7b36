//! Full-order diffuse relighting against closed forms and invariants.

mod common;

use glam::{DMat3, DVec3};
use prt_relight::{DiffuseParams, Lighting, RelightError, Relighter, TransferView};
use prt_sh::{zonal, Rotation};
use std::f64::consts::PI;

const EPS: f64 = f32::EPSILON as f64;

/// Unshadowed diffuse transfer of normal `n`: the clamped cosine about `n`, `T_i = A_l y_i(n)`.
fn cosine_transfer(order: usize, n: DVec3) -> Vec<f64> {
    zonal::rotate_zonal(
        &zonal::bands_to_zonal(&zonal::clamped_cosine_bands(order).unwrap()),
        n,
    )
    .unwrap()
}

fn f32s(v: &[f64]) -> Vec<f32> {
    v.iter().map(|x| *x as f32).collect()
}

#[test]
fn test01_uniform_environment_gives_albedo_times_radiance() {
    // L(ω) = c ⇒ L_0 = c√(4π), all else 0; T_0 = A_0 y_0 = π/√(4π) for any normal. So
    // L·T = cπ (the irradiance) and the radiance is albedo/π · cπ = albedo · c. The only error
    // is the f32 rounding of L_0, T_0, albedo/π and two products: ≤ 6ε relative.
    let c = [1.0, 2.0, 3.0];
    let albedo = [0.2f32, 0.5, 0.9];
    let params = DiffuseParams::from_albedo(albedo);
    for order in 1..=9 {
        let mut env = vec![[0.0; 3]; order * order];
        env[0] = c.map(|v| v * (4.0 * PI).sqrt());
        let relighter = Relighter::new(order).unwrap();
        let frame = relighter
            .frame_lighting(&Lighting::from_rgb_coefficients(&env, None).unwrap(), false)
            .unwrap();
        let normals = [DVec3::Z, DVec3::new(1.0, -2.0, 0.5).normalize(), -DVec3::Y];
        let data: Vec<f32> = normals
            .iter()
            .flat_map(|n| f32s(&cosine_transfer(order, *n)))
            .collect();
        let out = relighter
            .diffuse(
                &TransferView::new(order, 1, &data).unwrap(),
                &frame,
                &params,
            )
            .unwrap();
        for rgb in &out {
            for ch in 0..3 {
                let expect = f64::from(albedo[ch]) * c[ch];
                assert!(
                    (f64::from(rgb[ch]) - expect).abs() <= 6.0 * EPS * expect,
                    "order {order}: {} vs {expect}",
                    rgb[ch]
                );
            }
        }
    }
}

#[test]
fn test02_unshadowed_transfer_gives_ramamoorthi_hanrahan_irradiance() {
    // With an order-3 environment, L·T (T the clamped cosine about n) is the irradiance,
    // computed independently by the quadratic form of Ramamoorthi & Hanrahan 2001
    // (prt_sh::irradiance::irradiance_rh9, whose constants are given to 6 digits: relative
    // 1e-6 of each term). f32 rounding adds ≤ 12ε Σ|L_i T_i|.
    let order = 3;
    let env = common::sun_sky(order, DVec3::new(0.3, 0.8, -0.5));
    let albedo = [0.7f32, 0.6, 0.5];
    let relighter = Relighter::new(order).unwrap();
    let frame = relighter
        .frame_lighting(&Lighting::from_rgb_coefficients(&env, None).unwrap(), false)
        .unwrap();
    let normals: Vec<DVec3> = (0..40)
        .map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / 40.0;
            let phi = k as f64 * 2.399963;
            let s = (1.0 - z * z).sqrt();
            DVec3::new(s * phi.cos(), s * phi.sin(), z)
        })
        .collect();
    let transfers: Vec<Vec<f64>> = normals.iter().map(|n| cosine_transfer(order, *n)).collect();
    let data: Vec<f32> = transfers.iter().flat_map(|t| f32s(t)).collect();
    let out = relighter
        .diffuse(
            &TransferView::new(order, 1, &data).unwrap(),
            &frame,
            &DiffuseParams::from_albedo(albedo),
        )
        .unwrap();
    for (k, n) in normals.iter().enumerate() {
        let e = prt_sh::irradiance::irradiance_rh9(&env, *n).unwrap();
        for ch in 0..3 {
            let mag: f64 = (0..9).map(|i| (env[i][ch] * transfers[k][i]).abs()).sum();
            let expect = f64::from(albedo[ch]) / PI * e[ch];
            let tol = f64::from(albedo[ch]) / PI * (12.0 * EPS + 2e-6) * mag;
            assert!(
                (f64::from(out[k][ch]) - expect).abs() <= tol,
                "normal {k} ch {ch}"
            );
        }
    }
}

struct Scene {
    order: usize,
    transfer: Vec<f32>,
}

fn sphere_scene(order: usize) -> Scene {
    let mesh = prt_scene::test_util::icosphere(2);
    let (transfer, _) = common::synthetic_transfer(&mesh.positions, &mesh.normals, order);
    Scene { order, transfer }
}

fn shade(r: &Relighter, s: &Scene, env: &[[f64; 3]], rot: Option<&Rotation>) -> Vec<[f32; 3]> {
    let frame = r
        .frame_lighting(&Lighting::from_rgb_coefficients(env, rot).unwrap(), false)
        .unwrap();
    r.diffuse(
        &TransferView::new(s.order, 1, &s.transfer).unwrap(),
        &frame,
        &DiffuseParams::from_albedo([0.8, 0.6, 0.4]),
    )
    .unwrap()
}

/// Bound on the f32 error of `albedo/π Σ L_i T_i` (n² terms): 2 n² ε Σ |L_i T_i| · albedo/π
/// (recursive summation bound, doubled for input rounding).
fn dot_bound(env: &[[f64; 3]], t: &[f32], ch: usize, albedo: f32) -> f64 {
    let n2 = t.len() as f64;
    let mag: f64 = env
        .iter()
        .zip(t)
        .map(|(l, x)| (l[ch] * f64::from(*x)).abs())
        .sum();
    2.0 * n2 * EPS * mag * f64::from(albedo) / PI + 1e-30
}

#[test]
fn test03_linear_in_the_lighting() {
    let order = 8;
    let s = sphere_scene(order);
    let r = Relighter::new(order).unwrap();
    let l1 = common::sun_sky(order, DVec3::new(0.3, 0.8, -0.5));
    let l2 = common::sun_sky(order, DVec3::new(-0.9, 0.1, 0.4));
    let (a, b) = (2.0, -0.5);
    let mix: Vec<[f64; 3]> = l1
        .iter()
        .zip(&l2)
        .map(|(x, y)| [0, 1, 2].map(|c| a * x[c] + b * y[c]))
        .collect();
    let (o1, o2, om) = (
        shade(&r, &s, &l1, None),
        shade(&r, &s, &l2, None),
        shade(&r, &s, &mix, None),
    );
    let albedo = [0.8f32, 0.6, 0.4];
    let n2 = order * order;
    for v in 0..o1.len() {
        let t = &s.transfer[v * n2..(v + 1) * n2];
        for ch in 0..3 {
            let lin = a * f64::from(o1[v][ch]) + b * f64::from(o2[v][ch]);
            let tol = a.abs() * dot_bound(&l1, t, ch, albedo[ch])
                + b.abs() * dot_bound(&l2, t, ch, albedo[ch])
                + dot_bound(&mix, t, ch, albedo[ch]);
            assert!(
                (f64::from(om[v][ch]) - lin).abs() <= tol,
                "vertex {v} ch {ch}"
            );
        }
    }
}

#[test]
fn test04_rotating_lighting_and_transfer_together_changes_nothing() {
    // (R L)·(R T) = L·T for a rotation R of both (band matrices are orthogonal). The lighting
    // is rotated by Lighting::from_rgb_coefficients, the transfer by prt_sh directly.
    let order = 7;
    let s = sphere_scene(order);
    let r = Relighter::new(order).unwrap();
    let env = common::sun_sky(order, DVec3::new(0.3, 0.8, -0.5));
    let rot = Rotation::new(
        order,
        DMat3::from_axis_angle(DVec3::new(1.0, 2.0, -0.5).normalize(), 1.1),
    )
    .unwrap();
    let n2 = order * order;
    let rotated_transfer: Vec<f32> = s
        .transfer
        .chunks_exact(n2)
        .flat_map(|t| {
            let t64: Vec<f64> = t.iter().map(|x| f64::from(*x)).collect();
            f32s(&rot.apply(&t64).unwrap())
        })
        .collect();
    let rotated = Scene {
        order,
        transfer: rotated_transfer,
    };
    let a = shade(&r, &s, &env, None);
    let b = shade(&r, &rotated, &env, Some(&rot));
    let albedo = [0.8f32, 0.6, 0.4];
    for v in 0..a.len() {
        let t = &s.transfer[v * n2..(v + 1) * n2];
        for ch in 0..3 {
            // Both sides carry the dot bound, plus the f32 rounding of the rotated vectors.
            let tol = 4.0 * dot_bound(&env, t, ch, albedo[ch]);
            assert!(
                (a[v][ch] - b[v][ch]).abs() as f64 <= tol,
                "vertex {v} ch {ch}: {} vs {}",
                a[v][ch],
                b[v][ch]
            );
        }
    }
}

#[test]
fn test05_one_channel_equals_three_identical_channels_and_threads_do_not_matter() {
    let order = 6;
    let s = sphere_scene(order);
    let n2 = order * order;
    let three: Vec<f32> = s
        .transfer
        .chunks_exact(n2)
        .flat_map(|t| t.iter().chain(t).chain(t).copied())
        .collect();
    let r = Relighter::new(order).unwrap();
    let env = common::sun_sky(order, DVec3::new(0.3, 0.8, -0.5));
    let frame = r
        .frame_lighting(&Lighting::from_rgb_coefficients(&env, None).unwrap(), false)
        .unwrap();
    let p = DiffuseParams::from_albedo([0.8, 0.6, 0.4]);
    let one = r
        .diffuse(
            &TransferView::new(order, 1, &s.transfer).unwrap(),
            &frame,
            &p,
        )
        .unwrap();
    let tri = r
        .diffuse(&TransferView::new(order, 3, &three).unwrap(), &frame, &p)
        .unwrap();
    assert_eq!(one, tri);
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let single = pool.install(|| {
        r.diffuse(
            &TransferView::new(order, 1, &s.transfer).unwrap(),
            &frame,
            &p,
        )
        .unwrap()
    });
    assert_eq!(one, single);
}

#[test]
fn test06_bad_inputs_are_errors() {
    let r = Relighter::new(3).unwrap();
    let env = vec![[1.0; 3]; 9];
    let frame = r
        .frame_lighting(&Lighting::from_rgb_coefficients(&env, None).unwrap(), false)
        .unwrap();
    let p = DiffuseParams::from_albedo([0.5; 3]);
    let data = vec![0.0f32; 20];
    assert!(matches!(
        TransferView::new(3, 1, &data),
        Err(RelightError::TransferLength { .. })
    ));
    assert!(matches!(
        TransferView::new(3, 2, &data[..18]),
        Err(RelightError::Channels { .. })
    ));
    let wrong_order = TransferView::new(2, 1, &data[..8]).unwrap();
    assert!(matches!(
        r.diffuse(&wrong_order, &frame, &p),
        Err(RelightError::OrderMismatch { .. })
    ));
    let ok = TransferView::new(3, 1, &data[..18]).unwrap();
    let nan = DiffuseParams {
        albedo_over_pi: [f32::NAN, 0.0, 0.0],
    };
    assert!(matches!(
        r.diffuse(&ok, &frame, &nan),
        Err(RelightError::NonFinite(_))
    ));
    assert!(matches!(
        Lighting::from_rgb_coefficients(&env[..8], None),
        Err(RelightError::NotSquare(8))
    ));
    let mut bad = env.clone();
    bad[3][1] = f64::INFINITY;
    assert!(Lighting::from_rgb_coefficients(&bad, None).is_err());
    // Lighting of a lower order than the relighter.
    let low = Lighting::from_rgb_coefficients(&env[..4], None).unwrap();
    assert!(matches!(
        r.frame_lighting(&low, false),
        Err(RelightError::OrderMismatch { .. })
    ));
    // Specular asked of a diffuse-only frame is reported, not panicked on.
    assert!(!frame.has_specular());
}
