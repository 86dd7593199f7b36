//! Identities that need no reference data: orthonormality, the addition theorem, known
//! low-order closed forms, rotation composition and agreement with re-projection, Gaunt
//! entries against quadrature, Funk–Hecke for zonal lobes.

use glam::{DMat3, DQuat, DVec3};
use prt_sh::quadrature::{gauss_legendre, SphereQuadrature};
use prt_sh::{index, zonal, Basis, GauntTensor, Rotation};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

fn random_dir(rng: &mut Pcg64) -> DVec3 {
    loop {
        let v = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let l = v.length();
        if l > 0.1 && l < 1.0 {
            return v / l;
        }
    }
}

fn random_rotation(rng: &mut Pcg64) -> DMat3 {
    let q = DQuat::from_xyzw(
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
        rng.random_range(-1.0..1.0),
    )
    .normalize();
    DMat3::from_quat(q)
}

#[test]
fn gauss_legendre_integrates_monomials_exactly() {
    for n in [1usize, 2, 5, 16, 33, 64] {
        let (x, w) = gauss_legendre(n);
        for k in 0..(2 * n) {
            let got: f64 = x.iter().zip(&w).map(|(x, w)| w * x.powi(k as i32)).sum();
            let exact = if k % 2 == 1 {
                0.0
            } else {
                2.0 / (k as f64 + 1.0)
            };
            assert!((got - exact).abs() < 1e-14, "n={n} k={k}: {got} vs {exact}");
        }
    }
}

#[test]
fn low_order_closed_forms() {
    // CONVENTIONS.md check values, and the l = 2 functions of Sloan's table.
    let c1 = (3.0 / (4.0 * PI)).sqrt();
    let mut rng = Pcg64::seed_from_u64(1);
    let basis = Basis::new(3).unwrap();
    for _ in 0..100 {
        let d = random_dir(&mut rng);
        let y = basis.eval(d);
        let (x, yy, z) = (d.x, d.y, d.z);
        let k2 = 0.5 * (15.0 / PI).sqrt();
        let expect = [
            0.5 / PI.sqrt(),
            -c1 * yy,
            c1 * z,
            -c1 * x,
            k2 * x * yy,
            -k2 * yy * z,
            0.25 * (5.0 / PI).sqrt() * (3.0 * z * z - 1.0),
            -k2 * x * z,
            0.5 * k2 * (x * x - yy * yy),
        ];
        for i in 0..9 {
            assert!(
                (y[i] - expect[i]).abs() < 1e-15,
                "i={i}: {} vs {}",
                y[i],
                expect[i]
            );
        }
    }
}

#[test]
fn orthonormal_by_exact_quadrature_order_20() {
    // Products y_i y_j have degree ≤ 38; the rule is exact to degree 39, so the Gram matrix
    // must be the identity to rounding (~1e-13 after ~800 weighted terms).
    let order = 20;
    let q = SphereQuadrature::exact_for_degree(2 * order - 1);
    let basis = Basis::new(order).unwrap();
    let n2 = order * order;
    let mut gram = vec![0.0; n2 * n2];
    let mut y = vec![0.0; n2];
    for (d, w) in q.dirs.iter().zip(&q.weights) {
        basis.eval_into(*d, &mut y).unwrap();
        for i in 0..n2 {
            for j in 0..n2 {
                gram[i * n2 + j] += w * y[i] * y[j];
            }
        }
    }
    for i in 0..n2 {
        for j in 0..n2 {
            let e = if i == j { 1.0 } else { 0.0 };
            assert!(
                (gram[i * n2 + j] - e).abs() < 1e-12,
                "gram[{i}][{j}] = {}",
                gram[i * n2 + j]
            );
        }
    }
}

#[test]
fn addition_theorem_to_order_64() {
    // Σ_m y_l^m(a) y_l^m(b) = (2l+1)/(4π) P_l(a·b), P_l by its own three-term recurrence.
    let order = 64;
    let basis = Basis::new(order).unwrap();
    let mut rng = Pcg64::seed_from_u64(2);
    let mut dirs = vec![DVec3::Z, -DVec3::Z, DVec3::new(1e-9, 0.0, 1.0).normalize()];
    dirs.extend((0..20).map(|_| random_dir(&mut rng)));
    for a in &dirs {
        for b in dirs.iter().take(8) {
            let ya = basis.eval(*a);
            let yb = basis.eval(*b);
            let t = a.dot(*b).clamp(-1.0, 1.0);
            let (mut p0, mut p1) = (1.0, t);
            for l in 0..order {
                let p = if l == 0 { 1.0 } else { p1 };
                let sum: f64 = (-(l as i64)..=(l as i64))
                    .map(|m| ya[index(l, m)] * yb[index(l, m)])
                    .sum();
                let expect = (2 * l + 1) as f64 / (4.0 * PI) * p;
                // |sum| ≤ (2l+1)/4π; rounding of 2l+1 products of magnitude ≤ that bound.
                assert!(
                    (sum - expect).abs() < 1e-12 * (2 * l + 1) as f64,
                    "l={l}: {sum} vs {expect}"
                );
                if l >= 1 {
                    let lf = l as f64;
                    let p2 = ((2.0 * lf + 1.0) * t * p1 - lf * p0) / (lf + 1.0);
                    p0 = p1;
                    p1 = p2;
                }
            }
        }
    }
}

#[test]
fn f32_evaluation_within_2e5_of_f64_to_order_30() {
    let basis = Basis::new(30).unwrap();
    let mut rng = Pcg64::seed_from_u64(3);
    let mut y32 = vec![0.0f32; 900];
    let mut worst = 0.0f64;
    let mut dirs: Vec<DVec3> = (0..2000).map(|_| random_dir(&mut rng)).collect();
    dirs.extend([
        DVec3::Z,
        -DVec3::Z,
        DVec3::X,
        DVec3::new(1e-4, 0.0, -1.0).normalize(),
    ]);
    for d in dirs {
        let d32 = d.as_vec3();
        let y64 = basis.eval(d32.as_dvec3());
        basis.eval_f32_into(d32, &mut y32).unwrap();
        for (a, b) in y32.iter().zip(&y64) {
            worst = worst.max((*a as f64 - b).abs());
        }
    }
    assert!(worst < 2e-5, "worst f32 error {worst}");
}

#[test]
fn rotation_matches_rotated_function_and_composes() {
    let order = 12;
    let mut rng = Pcg64::seed_from_u64(4);
    let basis = Basis::new(order).unwrap();
    for _ in 0..5 {
        let r = random_rotation(&mut rng);
        let rot = Rotation::new(order, r).unwrap();
        let c: Vec<f64> = (0..order * order)
            .map(|_| rng.random_range(-1.0..1.0))
            .collect();
        let rc = rot.apply(&c).unwrap();
        for _ in 0..20 {
            let d = random_dir(&mut rng);
            let g: f64 = rc.iter().zip(basis.eval(d)).map(|(a, b)| a * b).sum();
            let f: f64 = c
                .iter()
                .zip(basis.eval(r.transpose() * d))
                .map(|(a, b)| a * b)
                .sum();
            assert!((g - f).abs() < 1e-11, "g(d) = {g} but f(R⁻¹d) = {f}");
        }
        // Composition D(R1 R2) = D(R1) D(R2).
        let r2 = random_rotation(&mut rng);
        let a = Rotation::new(order, r * r2).unwrap().apply(&c).unwrap();
        let b = rot
            .apply(&Rotation::new(order, r2).unwrap().apply(&c).unwrap())
            .unwrap();
        for (x, y) in a.iter().zip(&b) {
            assert!((x - y).abs() < 1e-12);
        }
    }
}

#[test]
fn rotation_orthogonal_at_order_30_and_quaternion_agrees() {
    let order = 31;
    let mut rng = Pcg64::seed_from_u64(5);
    let r = random_rotation(&mut rng);
    let rot = Rotation::new(order, r).unwrap();
    for l in 0..order {
        let w = 2 * l + 1;
        let b = rot.band(l);
        for i in 0..w {
            for j in 0..w {
                let dot: f64 = (0..w).map(|k| b[k * w + i] * b[k * w + j]).sum();
                let e = if i == j { 1.0 } else { 0.0 };
                assert!((dot - e).abs() < 1e-10, "band {l}: (DᵀD)[{i}][{j}] = {dot}");
            }
        }
    }
    let q = Rotation::from_quat(order, DQuat::from_mat3(&r)).unwrap();
    for l in 0..order {
        for (a, b) in q.band(l).iter().zip(rot.band(l)) {
            assert!((a - b).abs() < 1e-11);
        }
    }
}

#[test]
fn rotation_rejects_non_rotations() {
    assert!(Rotation::new(3, DMat3::from_diagonal(DVec3::new(1.0, 1.0, -1.0))).is_err());
    assert!(Rotation::new(3, DMat3::from_diagonal(DVec3::splat(2.0))).is_err());
    assert!(Rotation::new(3, DMat3::from_cols_array(&[f64::NAN; 9])).is_err());
}

#[test]
fn zonal_rotation_matches_lobe_evaluated_directly() {
    // A normalised Phong lobe of exponent 3 is a polynomial of degree 3 in cos: exactly
    // band-limited to order 4 on the upper half... no — clamping makes it infinite. Use the
    // unclamped cos^2, which is exactly band-limited to order 3: g(t) = t².
    let order = 3;
    let zonal_g = {
        // g_l = 2π ∫ t² y_l^0 dt: by quadrature exact for degree 4.
        let (x, w) = gauss_legendre(4);
        (0..order)
            .map(|l| {
                let y = Basis::new(order).unwrap();
                x.iter()
                    .zip(&w)
                    .map(|(t, w)| {
                        let s = (1.0 - t * t).sqrt();
                        2.0 * PI * w * t * t * y.eval(DVec3::new(s, 0.0, *t))[index(l, 0)]
                    })
                    .sum::<f64>()
            })
            .collect::<Vec<_>>()
    };
    let axis = DVec3::new(0.3, -0.5, 0.81).normalize();
    let c = zonal::rotate_zonal(&zonal_g, axis).unwrap();
    let basis = Basis::new(order).unwrap();
    let mut rng = Pcg64::seed_from_u64(6);
    for _ in 0..50 {
        let d = random_dir(&mut rng);
        let v: f64 = c.iter().zip(basis.eval(d)).map(|(a, b)| a * b).sum();
        let t = d.dot(axis);
        assert!((v - t * t).abs() < 1e-13);
    }
}

#[test]
fn gaunt_entries_match_product_quadrature() {
    // Direct quadrature of y_i y_j y_k with a rule exact to degree 3(order-1).
    let order = 6;
    let g = GauntTensor::new(order).unwrap();
    let q = SphereQuadrature::exact_for_degree(3 * (order - 1));
    let basis = Basis::new(order).unwrap();
    let ys: Vec<Vec<f64>> = q.dirs.iter().map(|d| basis.eval(*d)).collect();
    let n2 = order * order;
    let mut max_err = 0.0f64;
    for i in 0..n2 {
        for j in 0..n2 {
            for k in 0..n2 {
                let direct: f64 = ys
                    .iter()
                    .zip(&q.weights)
                    .map(|(y, w)| w * y[i] * y[j] * y[k])
                    .sum();
                max_err = max_err.max((direct - g.get(i, j, k)).abs());
            }
        }
    }
    assert!(max_err < 1e-13, "max error {max_err}");
    // Products with the constant function: y_0 = 1/√(4π) so a ⊛ (√(4π) e_0) = a.
    let mut rng = Pcg64::seed_from_u64(7);
    let a: Vec<f64> = (0..n2).map(|_| rng.random_range(-1.0..1.0)).collect();
    let mut one = vec![0.0; n2];
    one[0] = (4.0 * PI).sqrt();
    let c = g.product(&a, &one).unwrap();
    for (x, y) in a.iter().zip(&c) {
        assert!((x - y).abs() < 1e-13);
    }
    // Product matrix agrees with the product.
    let b: Vec<f64> = (0..n2).map(|_| rng.random_range(-1.0..1.0)).collect();
    let m = g.product_matrix(&a).unwrap();
    let ab = g.product(&a, &b).unwrap();
    for k in 0..n2 {
        let mb: f64 = (0..n2).map(|j| m[k * n2 + j] * b[j]).sum();
        assert!((mb - ab[k]).abs() < 1e-13);
    }
}

#[test]
fn product_of_band_limited_functions_is_exact_when_order_suffices() {
    // f of order 3 times g of order 3 is band-limited to order 5: the order-5 product of their
    // padded coefficient vectors must reproduce f·g pointwise.
    let order = 5;
    let g = GauntTensor::new(order).unwrap();
    let mut rng = Pcg64::seed_from_u64(8);
    let mut a = vec![0.0; 25];
    let mut b = vec![0.0; 25];
    for i in 0..9 {
        a[i] = rng.random_range(-1.0..1.0);
        b[i] = rng.random_range(-1.0..1.0);
    }
    let c = g.product(&a, &b).unwrap();
    let basis = Basis::new(order).unwrap();
    for _ in 0..50 {
        let y = basis.eval(random_dir(&mut rng));
        let f: f64 = a.iter().zip(&y).map(|(p, q)| p * q).sum();
        let h: f64 = b.iter().zip(&y).map(|(p, q)| p * q).sum();
        let fh: f64 = c.iter().zip(&y).map(|(p, q)| p * q).sum();
        assert!((f * h - fh).abs() < 1e-13);
    }
}

#[test]
fn phong_lobe_matches_numerical_integration_and_tends_to_delta() {
    // A_l = (e+1) ∫_0^1 x^e P_l(x) dx by composite Gauss–Legendre on a graded mesh.
    let order = 65;
    for &e in &[0.0, 0.5, 1.0, 2.0, 7.3, 64.0, 1000.0] {
        let a = zonal::phong_lobe_bands(e, order).unwrap();
        for l in [0usize, 1, 2, 3, 5, 10, 33, 64] {
            let exact = (e + 1.0) * integrate_xe_pl(e, l);
            assert!(
                (a[l] - exact).abs() < 1e-11,
                "e={e} l={l}: {} vs {exact}",
                a[l]
            );
        }
    }
    // As e → ∞ every band multiplier → 1 (the lobe tends to the delta).
    let a = zonal::phong_lobe_bands(1e9, 10).unwrap();
    for v in a {
        assert!((v - 1.0).abs() < 1e-6);
    }
    let a = zonal::phong_lobe_bands(1e4, 65).unwrap();
    // Asymptotically A_l ≈ exp(−l(l+1)/(2e)).
    for (l, v) in a.iter().enumerate() {
        let approx = (-((l * (l + 1)) as f64) / 2e4).exp();
        assert!((v - approx).abs() < 5e-3, "l={l}");
    }
}

fn integrate_xe_pl(e: f64, l: usize) -> f64 {
    // Graded panels toward x = 1 where x^e concentrates; 40-point GL per panel.
    let (gx, gw) = gauss_legendre(40);
    // Also graded toward 0, where x^e has a singular derivative for non-integer e.
    let mut edges = vec![0.0];
    let mut h = 1e-16;
    while h < 0.5 {
        edges.push(h);
        h *= 2.0;
    }
    let mut h = 0.5;
    while h > 1e-9 {
        h *= 0.5;
        edges.push(1.0 - h);
    }
    edges.push(1.0);
    let mut sum = 0.0;
    for w in edges.windows(2) {
        let (a, b) = (w[0], w[1]);
        for (x, wt) in gx.iter().zip(&gw) {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * x;
            let (mut p0, mut p1) = (1.0, t);
            let p = if l == 0 {
                1.0
            } else {
                for k in 1..l {
                    let kf = k as f64;
                    let p2 = ((2.0 * kf + 1.0) * t * p1 - kf * p0) / (kf + 1.0);
                    p0 = p1;
                    p1 = p2;
                }
                p1
            };
            sum += 0.5 * (b - a) * wt * t.powf(e) * p;
        }
    }
    sum
}

#[test]
fn clamped_cosine_values() {
    let a = zonal::clamped_cosine_bands(65).unwrap();
    assert!((a[0] - PI).abs() < 1e-15);
    assert!((a[1] - 2.0 * PI / 3.0).abs() < 1e-15);
    assert!((a[2] - PI / 4.0).abs() < 1e-15);
    for l in (3..65).step_by(2) {
        assert_eq!(a[l], 0.0);
    }
    // Even l: closed form 2π (−1)^{l/2+1} (l−2)! / (2^l (l/2−1)! (l/2+1)!) in log space.
    for l in (4..65).step_by(2) {
        let lnf = |n: usize| (1..=n).map(|k| (k as f64).ln()).sum::<f64>();
        let mag = (lnf(l - 2) - (l as f64) * 2f64.ln() - lnf(l / 2 - 1) - lnf(l / 2 + 1)).exp();
        let sign = if (l / 2 + 1) % 2 == 0 { 1.0 } else { -1.0 };
        let expect = 2.0 * PI * sign * mag;
        assert!(
            (a[l] - expect).abs() < 1e-14 + 1e-12 * expect.abs(),
            "l={l}"
        );
    }
}
