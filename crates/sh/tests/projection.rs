//! Projection, reconstruction, irradiance and windowing checked against brute-force
//! integration that shares no code path with the library (per-texel 2D Gauss–Legendre in the
//! map's own angles, directions built from CONVENTIONS.md's formula).

use glam::{DMat3, DVec3};
use prt_sh::quadrature::gauss_legendre;
use prt_sh::window::{dering, window, WindowKind};
use prt_sh::{irradiance, project_env, reconstruct_rgb, Basis, EnvMapping, ImageRef, Rotation};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::f64::consts::PI;

fn random_map(w: usize, h: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut rng = Pcg64::seed_from_u64(seed);
    (0..w * h)
        .map(|_| {
            [
                rng.random_range(0.0..4.0),
                rng.random_range(0.0..1.0),
                rng.random_range(0.0..0.25),
            ]
        })
        .collect()
}

/// CONVENTIONS.md: d = (sin φ sin θ, cos θ, −cos φ sin θ).
fn map_dir(phi: f64, theta: f64) -> DVec3 {
    DVec3::new(
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    )
}

/// Brute force: every texel integrated by an n×n tensor Gauss–Legendre rule in (θ, φ) of the
/// map, with `rot` applied to the direction (radiance towards `rot·d` is the texel's value).
fn brute_force(
    texels: &[[f32; 3]],
    w: usize,
    h: usize,
    order: usize,
    n: usize,
    rot: DMat3,
) -> Vec<[f64; 3]> {
    let (gx, gw) = gauss_legendre(n);
    let basis = Basis::new(order).unwrap();
    let mut out = vec![[0.0; 3]; order * order];
    for row in 0..h {
        for col in 0..w {
            let t = texels[row * w + col];
            let (t0, t1) = (PI * row as f64 / h as f64, PI * (row + 1) as f64 / h as f64);
            let (p0, p1) = (
                2.0 * PI * col as f64 / w as f64,
                2.0 * PI * (col + 1) as f64 / w as f64,
            );
            for (xa, wa) in gx.iter().zip(&gw) {
                let theta = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * xa;
                for (xb, wb) in gx.iter().zip(&gw) {
                    let phi = 0.5 * (p0 + p1) + 0.5 * (p1 - p0) * xb;
                    let wgt = wa * wb * 0.25 * (t1 - t0) * (p1 - p0) * theta.sin();
                    let y = basis.eval(rot * map_dir(phi, theta));
                    for i in 0..order * order {
                        for ch in 0..3 {
                            out[i][ch] += wgt * y[i] * t[ch] as f64;
                        }
                    }
                }
            }
        }
    }
    out
}

fn max_abs_diff(a: &[[f64; 3]], b: &[[f64; 3]]) -> f64 {
    a.iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (x[c] - y[c]).abs()))
        .fold(0.0, f64::max)
}

fn max_abs(a: &[[f64; 3]]) -> f64 {
    a.iter()
        .flat_map(|x| x.iter())
        .fold(0.0f64, |m, v| m.max(v.abs()))
}

#[test]
fn latlong_projection_is_exact_for_small_maps_to_order_30() {
    // The 8×4 map at order 30 is the hardest case: a texel spans π/4 in θ, the integrand has
    // degree 30. 36×36 GL per texel converges to rounding (Taylor bound (30·π/8)^72/72! ≈ 1e-32).
    for (w, h, order) in [(8usize, 4usize, 30usize), (12, 6, 20), (16, 8, 12)] {
        let texels = random_map(w, h, (w * h) as u64);
        let img = ImageRef {
            width: w,
            height: h,
            texels: &texels,
        };
        let got = project_env(img, EnvMapping::LatLong, order, 0.0).unwrap();
        let want = brute_force(&texels, w, h, order, 36, DMat3::IDENTITY);
        let err = max_abs_diff(&got, &want) / max_abs(&want);
        // Both sides are exact to rounding; 1e-12 leaves room for summation order (~1e4 terms).
        assert!(err < 1e-12, "{w}×{h} order {order}: relative error {err:e}");
    }
}

#[test]
fn rotation_option_follows_mitsuba_sense() {
    // Radiance towards world d is the map's value at R_y(α)⁻¹ d, i.e. the map's direction m is
    // seen at world direction R_y(α) m.
    let (w, h, order) = (8, 4, 8);
    let texels = random_map(w, h, 9);
    let img = ImageRef {
        width: w,
        height: h,
        texels: &texels,
    };
    let got = project_env(img, EnvMapping::LatLong, order, 30.0).unwrap();
    let want = brute_force(
        &texels,
        w,
        h,
        order,
        24,
        DMat3::from_rotation_y(30f64.to_radians()),
    );
    assert!(max_abs_diff(&got, &want) / max_abs(&want) < 1e-12);
    // And it equals rotating the unrotated coefficients.
    let base = project_env(img, EnvMapping::LatLong, order, 0.0).unwrap();
    let rot = Rotation::new(order, DMat3::from_rotation_y(30f64.to_radians()))
        .unwrap()
        .apply_rgb(&base);
    assert!(max_abs_diff(&got, &rot) < 1e-13);
}

#[test]
fn uniform_map_projects_to_dc_only() {
    let texels = vec![[1.0f32, 2.0, 0.5]; 64 * 32];
    let img = ImageRef {
        width: 64,
        height: 32,
        texels: &texels,
    };
    let c = project_env(img, EnvMapping::LatLong, 10, 17.0).unwrap();
    let s = (4.0 * PI).sqrt();
    for ch in 0..3 {
        assert!((c[0][ch] - s * [1.0, 2.0, 0.5][ch]).abs() < 1e-13);
    }
    for v in &c[1..] {
        for x in v {
            assert!(x.abs() < 1e-13);
        }
    }
}

#[test]
fn bad_images_are_errors() {
    let mut texels = vec![[1.0f32; 3]; 8 * 4];
    texels[13][1] = f32::NAN;
    let img = ImageRef {
        width: 8,
        height: 4,
        texels: &texels,
    };
    let err = project_env(img, EnvMapping::LatLong, 3, 0.0).unwrap_err();
    assert_eq!(
        err,
        prt_sh::ShError::NonFinite {
            col: 5,
            row: 1,
            channel: 1
        }
    );
    let img = ImageRef {
        width: 8,
        height: 3,
        texels: &texels,
    };
    assert!(project_env(img, EnvMapping::LatLong, 3, 0.0).is_err());
    let img = ImageRef {
        width: 0,
        height: 0,
        texels: &[],
    };
    assert!(project_env(img, EnvMapping::LatLong, 3, 0.0).is_err());
    let ok = vec![[1.0f32; 3]; 8 * 4];
    let img = ImageRef {
        width: 8,
        height: 4,
        texels: &ok,
    };
    assert!(project_env(img, EnvMapping::LatLong, 0, 0.0).is_err());
    assert!(project_env(img, EnvMapping::LatLong, prt_sh::MAX_ORDER + 1, 0.0).is_err());
}

/// An angular probe sampled from a smooth function at texel centres.
fn angular_probe(size: usize, f: impl Fn(DVec3) -> f64) -> Vec<[f32; 3]> {
    let mut t = vec![[0.0f32; 3]; size * size];
    for row in 0..size {
        for col in 0..size {
            let a = 2.0 * (col as f64 + 0.5) / size as f64 - 1.0;
            let b = 1.0 - 2.0 * (row as f64 + 0.5) / size as f64;
            let r = (a * a + b * b).sqrt();
            if r <= 1.0 {
                let th = PI * r;
                let d = DVec3::new(a / r * th.sin(), b / r * th.sin(), th.cos());
                let v = f(d) as f32;
                t[row * size + col] = [v, v, v];
            }
        }
    }
    t
}

#[test]
fn angular_projection_converges_with_subsamples_and_resolution() {
    // f = 1 + 0.5 z + 0.3 x y is band-limited (order 3). The piecewise-constant probe differs
    // from f by O(texel size) and the rim is only partly covered, so the projection of a
    // 256² probe must be within a few 1e-3 of f's coefficients; the per-texel midpoint rule
    // with k = 4 must agree with k = 16 (≈ exact texel integrals) to 1e-3 of ‖c‖.
    let f = |d: DVec3| 1.0 + 0.5 * d.z + 0.3 * d.x * d.y;
    let exact = prt_sh::project_fn(3, 4, f).unwrap();
    let probe = angular_probe(256, f);
    let img = ImageRef {
        width: 256,
        height: 256,
        texels: &probe,
    };
    let c4 = project_env(img, EnvMapping::Angular { subsamples: 4 }, 3, 0.0).unwrap();
    let c16 = project_env(img, EnvMapping::Angular { subsamples: 16 }, 3, 0.0).unwrap();
    let norm = exact.iter().map(|v| v * v).sum::<f64>().sqrt();
    let sub_err = c4
        .iter()
        .zip(&c16)
        .map(|(a, b)| (a[0] - b[0]).powi(2))
        .sum::<f64>()
        .sqrt()
        / norm;
    let disc_err = c16
        .iter()
        .zip(&exact)
        .map(|(a, b)| (a[0] - b).powi(2))
        .sum::<f64>()
        .sqrt()
        / norm;
    assert!(sub_err < 1e-3, "subsampling error {sub_err:e}");
    assert!(disc_err < 5e-3, "discretisation error {disc_err:e}");
}

#[test]
fn reconstruction_of_band_limited_function_is_exact() {
    let f = |d: DVec3| 0.2 + d.x - 0.7 * d.y * d.z + 0.25 * d.z * d.z * d.x;
    let c = prt_sh::project_fn(4, 6, f).unwrap();
    let rgb: Vec<[f64; 3]> = c.iter().map(|v| [*v, 2.0 * v, -v]).collect();
    for d in [DVec3::Z, -DVec3::Y, DVec3::new(0.3, 0.4, -0.5).normalize()] {
        let v = reconstruct_rgb(&rgb, 4, d).unwrap();
        assert!((v[0] - f(d)).abs() < 1e-14 && (v[1] - 2.0 * f(d)).abs() < 1e-13);
    }
    let img = prt_sh::reconstruct_latlong(&rgb, 4, 16, 8, 0.0).unwrap();
    let (col, row) = (3usize, 5usize);
    let d = map_dir(2.0 * PI * 3.5 / 16.0, PI * 5.5 / 8.0);
    assert!((img[row * 16 + col][0] as f64 - f(d)).abs() < 1e-6);
}

#[test]
fn irradiance_equals_exact_hemisphere_integral_for_band_limited_radiance() {
    // L of order 3; E(n) = ∫_{n·ω>0} L(ω) n·ω dω by a rule in the frame of n that is exact for
    // polynomials (GL in cos θ on [0,1] × uniform φ), so any difference is the library's.
    let mut rng = Pcg64::seed_from_u64(11);
    let l: Vec<[f64; 3]> = (0..9)
        .map(|_| {
            [
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                1.0,
            ]
        })
        .collect();
    let basis = Basis::new(3).unwrap();
    let (gx, gw) = gauss_legendre(6);
    for _ in 0..10 {
        let n = DVec3::new(
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        )
        .normalize();
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let mut e = [0.0; 3];
        for (x, w) in gx.iter().zip(&gw) {
            let ct = 0.5 * (x + 1.0);
            let st = (1.0 - ct * ct).sqrt();
            for j in 0..16 {
                let phi = 2.0 * PI * j as f64 / 16.0;
                let d = n * ct + t * (st * phi.cos()) + b * (st * phi.sin());
                let y = basis.eval(d);
                for ch in 0..3 {
                    let lv: f64 = (0..9).map(|i| l[i][ch] * y[i]).sum();
                    e[ch] += 0.5 * w * (2.0 * PI / 16.0) * lv * ct;
                }
            }
        }
        let got = irradiance::irradiance(&l, 3, n).unwrap();
        let rh = irradiance::irradiance_rh9(&l, n).unwrap();
        let scale = l[0][2].abs() * PI;
        for ch in 0..3 {
            assert!(
                (got[ch] - e[ch]).abs() < 1e-13,
                "order-3 irradiance {} vs {}",
                got[ch],
                e[ch]
            );
            // c1..c5 are rounded to 6 significant digits: relative 1e-6 of each term.
            assert!(
                (rh[ch] - e[ch]).abs() < 1e-5 * (1.0 + scale),
                "RH9 {} vs {}",
                rh[ch],
                e[ch]
            );
        }
    }
}

#[test]
fn windows_and_deringing_of_a_bright_sun() {
    let h = window(WindowKind::Hann, 10, 10.0).unwrap();
    assert_eq!(h[0], 1.0);
    assert!((h[5] - 0.5).abs() < 1e-15);
    let s = window(WindowKind::Lanczos, 10, 10.0).unwrap();
    assert!((s[5] - 2.0 / PI).abs() < 1e-15);
    // A 64×32 sky of radiance 1 with one texel 10⁴ brighter: its order-10 projection rings
    // negative; the deringing search must find a window that is ≥ 0 everywhere on its grid,
    // report the cost, and be the widest such window within the bisection tolerance.
    let mut texels = vec![[1.0f32; 3]; 64 * 32];
    texels[10 * 64 + 20] = [1e4; 3];
    let img = ImageRef {
        width: 64,
        height: 32,
        texels: &texels,
    };
    let c = project_env(img, EnvMapping::LatLong, 10, 0.0).unwrap();
    for kind in [WindowKind::Hann, WindowKind::Lanczos] {
        let r = dering(&c, 10, kind).unwrap();
        assert!(r.min_before < 0.0, "the sun should ring negative");
        assert!(r.min_after >= -1e-9, "min after deringing {}", r.min_after);
        assert!(r.relative_l2_cost > 0.0 && r.relative_l2_cost < 1.0);
        let wider =
            prt_sh::window::apply_window_rgb(&c, &window(kind, 10, r.width * 1.05).unwrap())
                .unwrap();
        let still = dering(&wider, 10, kind).unwrap();
        assert!(still.min_before < 0.0, "a 5% wider window must still ring");
    }
}

#[test]
fn angular_subsample_count_is_bounded() {
    // 10⁹ subsamples per texel side used to run for ever (10¹⁸ evaluations per texel).
    let texels = vec![[1.0f32; 3]; 4];
    let img = ImageRef {
        width: 2,
        height: 2,
        texels: &texels,
    };
    for k in [0, prt_sh::MAX_ANGULAR_SUBSAMPLES + 1, 1_000_000_000] {
        let e = project_env(img, EnvMapping::Angular { subsamples: k }, 2, 0.0).unwrap_err();
        assert!(e.to_string().contains("angular subsamples"), "{e}");
    }
    let max = prt_sh::MAX_ANGULAR_SUBSAMPLES;
    assert!(project_env(img, EnvMapping::Angular { subsamples: max }, 2, 0.0).is_ok());
}
