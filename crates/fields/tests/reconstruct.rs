//! The reconstructions of `prt_fields::reconstruct` (Masselus et al. 2004, §4; Lee,
//! Wolberg & Shin 1997): against the independent numpy/SciPy oracle
//! (`tools/rf_reconstruct_oracle.py`, `tests/data/rf_reconstruct_oracle.json`), the adjoint
//! identity, constants, functions in each fit's span, convergence of the multilevel B-splines,
//! and bad parameters.

use glam::DVec3;
use prt_fields::reconstruct::{Biquadric, Idw, LinearReconstruction, MultilevelBSpline, ShFit};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use serde_json::Value;
use std::f64::consts::PI;

const EPS: f64 = f64::EPSILON;

fn oracle() -> Value {
    let path = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/tests/data/rf_reconstruct_oracle.json"
    );
    serde_json::from_str(&std::fs::read_to_string(path).expect("oracle JSON")).expect("JSON")
}

fn pair(v: &Value) -> [u32; 2] {
    [v[0].as_u64().unwrap() as u32, v[1].as_u64().unwrap() as u32]
}

fn floats(v: &Value) -> Vec<f64> {
    v.as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect()
}

fn build(
    method: &str,
    params: &Value,
    coarse: [u32; 2],
    fine: [u32; 2],
) -> Box<dyn LinearReconstruction> {
    let usize_of = |k: &str| params[k].as_u64().unwrap() as usize;
    match method {
        "idw" => Box::new(
            Idw::new(
                coarse,
                fine,
                usize_of("neighbours"),
                params["power"].as_f64().unwrap(),
            )
            .unwrap(),
        ),
        "biquadric" => Box::new(Biquadric::new(coarse, fine).unwrap()),
        "sh" => Box::new(ShFit::new(coarse, fine, usize_of("order")).unwrap()),
        "bspline" => Box::new(MultilevelBSpline::new(coarse, fine, usize_of("levels")).unwrap()),
        m => panic!("unknown method {m}"),
    }
}

/// Centre direction of cell `k` of a `w × h` lat-long grid (CONVENTIONS.md), written out here.
fn centre([w, h]: [u32; 2], k: usize) -> DVec3 {
    let (col, row) = ((k % w as usize) as f64, (k / w as usize) as f64);
    let (phi, theta) = (
        2.0 * PI * (col + 0.5) / f64::from(w),
        PI * (row + 0.5) / f64::from(h),
    );
    DVec3::new(
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    )
}

fn cells([w, h]: [u32; 2]) -> usize {
    (w * h) as usize
}

/// `max_k Σ_j |M[k][j]|` (the ∞-norm: how much `M` can amplify a perturbation of the samples),
/// column by column through unit samples.
fn inf_norm(m: &dyn LinearReconstruction, coarse: [u32; 2], fine: [u32; 2]) -> f64 {
    let mut rows = vec![0.0f64; cells(fine)];
    let mut unit = vec![0.0f32; cells(coarse)];
    let mut col = vec![0.0f64; cells(fine)];
    for j in 0..unit.len() {
        unit[j] = 1.0;
        m.apply(&unit, &mut col);
        unit[j] = 0.0;
        rows.iter_mut().zip(&col).for_each(|(r, c)| *r += c.abs());
    }
    rows.into_iter().fold(0.0, f64::max)
}

#[test]
fn test01_every_method_matches_the_independent_oracle() {
    let data = oracle();
    let mut checked = 0;
    for case in data["cases"].as_array().unwrap() {
        let (coarse, fine) = (pair(&case["coarse"]), pair(&case["fine"]));
        for r in case["results"].as_array().unwrap() {
            let method = r["method"].as_str().unwrap();
            let set = r["set"].as_str().unwrap();
            let samples: Vec<f32> = floats(&case["samples"][set])
                .iter()
                .map(|&v| v as f32)
                .collect();
            let want = floats(&r["values"]);
            let m = build(method, &r["params"], coarse, fine);
            let mut got = vec![0.0; want.len()];
            m.apply(&samples, &mut got);
            let scale = samples
                .iter()
                .fold(0.0f64, |a, &s| a.max(f64::from(s).abs()));
            // Tolerances: both sides compute in f64 from the same f32 samples (exact in the
            // JSON), so they differ by rounding only.
            let tol = match method {
                // A normalised combination of at most ~40 samples whose weights carry a few ε
                // each (atan2, powf, the sum): |Δ| ≤ c·ε·max|R| with c ≈ 2·(40 + 10); 128.
                "idw" => 128.0 * EPS * scale,
                // Backward-stable least squares on both sides (Gram–Schmidt twice here,
                // LAPACK's SVD there): the coefficients' relative error is at most
                // ~ε(2κ + κ²·tanθ) (Golub & Van Loan §5.3.8), κ the weighted design's
                // condition number (stored by the oracle), times the fine basis' size; 10³
                // covers the dimension factors (√samples, √coefficients, the basis' ≤ 1.5).
                "biquadric" | "sh" => {
                    let kappa = r["condition"].as_f64().unwrap();
                    1e3 * EPS * kappa * kappa * scale
                }
                // Two routes to the same sum of B-splines (refined lattices here, each level
                // evaluated there): per level a BA average of ≤ 16 terms per control point, an
                // evaluation of 16 terms, a refinement of ≤ 9, each ≤ 16 ε relative, on values
                // within a few times max|R| (the BA rule's φ_c = w r / Σw² is at most
                // max w / min Σw² = (2/3)² / 0.46² ≈ 2.1 times the residual, and residuals
                // shrink); 64 · levels · 5 · ε · max|R| rounds that up.
                "bspline" => {
                    let levels = r["params"]["levels"].as_f64().unwrap();
                    64.0 * levels * 5.0 * EPS * scale
                }
                _ => unreachable!(),
            };
            let worst = got
                .iter()
                .zip(&want)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0, f64::max);
            assert!(
                worst <= tol,
                "{method} {} on {set}, {coarse:?} → {fine:?}: max |Δ| {worst:e} > {tol:e}",
                r["params"]
            );
            eprintln!(
                "{method:9} {:28} {set:8} {coarse:?} → {fine:?}: max |Δ| {worst:.2e} (tolerance {tol:.2e})",
                r["params"].to_string()
            );
            checked += 1;
        }
    }
    assert_eq!(checked, 28);
}

fn all_methods(coarse: [u32; 2], fine: [u32; 2]) -> Vec<(String, Box<dyn LinearReconstruction>)> {
    let idw = Idw::new(coarse, fine, 24, 1.0).unwrap();
    let bq = Biquadric::new(coarse, fine).unwrap();
    let sh = ShFit::new(coarse, fine, 4).unwrap();
    let mba = MultilevelBSpline::with_default_levels(coarse, fine).unwrap();
    vec![
        (idw.name().to_owned(), Box::new(idw)),
        (bq.name().to_owned(), Box::new(bq)),
        (sh.name().to_owned(), Box::new(sh)),
        (mba.name().to_owned(), Box::new(mba)),
    ]
}

#[test]
fn test02_apply_transpose_is_the_adjoint() {
    let mut rng = Pcg64::seed_from_u64(7);
    for (coarse, fine) in [([16, 8], [40, 20]), ([12, 6], [36, 18]), ([10, 4], [20, 9])] {
        for (name, m) in all_methods(coarse, fine) {
            for signed in [false, true] {
                let lo: f64 = if signed { -1.0 } else { 0.0 };
                let x: Vec<f32> = (0..cells(coarse))
                    .map(|_| rng.random_range(lo..1.0) as f32)
                    .collect();
                let y: Vec<f64> = (0..cells(fine))
                    .map(|_| rng.random_range(lo..1.0))
                    .collect();
                let mut mx = vec![0.0; cells(fine)];
                m.apply(&x, &mut mx);
                let mut mty = vec![0.0; cells(coarse)];
                m.apply_transpose(&y, &mut mty);
                let a: f64 = mx.iter().zip(&y).map(|(a, b)| a * b).sum();
                let b: f64 = x.iter().zip(&mty).map(|(a, b)| f64::from(*a) * b).sum();
                // Relative to the sum of magnitudes (what rounding scales with; with signed
                // data the inner product itself may nearly cancel).
                let scale: f64 = mx.iter().zip(&y).map(|(a, b)| (a * b).abs()).sum();
                assert!(
                    (a - b).abs() <= 1e-12 * scale,
                    "{name} {coarse:?} → {fine:?}: ⟨Mx, y⟩ = {a} but ⟨x, Mᵀy⟩ = {b}"
                );
            }
        }
    }
}

#[test]
fn test03_idw_biquadric_and_sh_reproduce_constants() {
    // IDW's weights are normalised; the constant is a0 of each hemisphere's polynomial and
    // √(4π)·y_0^0 in SH, in the span of both least-squares fits, which reproduce their span
    // exactly (the residual is zero) up to rounding. 0.75 is exact in f32.
    let (coarse, fine) = ([16u32, 8u32], [40u32, 21u32]);
    for (name, m) in all_methods(coarse, fine) {
        let mut f = vec![0.0; cells(fine)];
        m.apply(&vec![0.75f32; cells(coarse)], &mut f);
        let worst = f.iter().map(|v| (v - 0.75).abs()).fold(0.0, f64::max);
        if name == "bspline" {
            // Not a projection: the BA rule averages, and the levels only converge to the
            // data. The constant is approached, not reproduced.
            assert!(worst < 0.05 * 0.75, "{name}: {worst}");
            eprintln!("bspline: constant 0.75 reproduced to {worst:.2e}");
        } else {
            assert!(worst < 1e-13, "{name}: constant reproduced to {worst:e}");
        }
    }
}

#[test]
fn test04_biquadric_reproduces_a_quadratic_per_hemisphere() {
    // Different quadratics in (u, v) = (d.x, d.z) above and below the equator. The samples
    // are rounded to f32 (|δ_j| ≤ 2^-24 |R_j|), and the fit maps that rounding to at most
    // ‖M‖_∞ · max|δ| at a fine centre; everything else is f64 rounding (≤ 1e-13 here).
    let (coarse, fine) = ([16u32, 8u32], [48u32, 25u32]);
    let up = [0.4, 0.3, -0.2, 0.5, 0.25, -0.35];
    let low = [0.1, -0.6, 0.15, 0.2, -0.45, 0.3];
    let q = |a: &[f64; 6], d: DVec3| {
        a[0] + a[1] * d.x + a[2] * d.z + a[3] * d.x * d.x + a[4] * d.x * d.z + a[5] * d.z * d.z
    };
    let exact = |grid: [u32; 2], k: usize| {
        let d = centre(grid, k);
        let row2 = 2 * (k / grid[0] as usize) + 1;
        match row2.cmp(&(grid[1] as usize)) {
            std::cmp::Ordering::Less => q(&up, d),
            std::cmp::Ordering::Greater => q(&low, d),
            std::cmp::Ordering::Equal => 0.5 * (q(&up, d) + q(&low, d)),
        }
    };
    let samples: Vec<f32> = (0..cells(coarse))
        .map(|j| exact(coarse, j) as f32)
        .collect();
    let m = Biquadric::new(coarse, fine).unwrap();
    let rounding = (0..cells(coarse))
        .map(|j| (f64::from(samples[j]) - exact(coarse, j)).abs())
        .fold(0.0, f64::max);
    let tol = inf_norm(&m, coarse, fine) * rounding + 1e-13;
    let mut f = vec![0.0; cells(fine)];
    m.apply(&samples, &mut f);
    let worst = (0..f.len())
        .map(|k| (f[k] - exact(fine, k)).abs())
        .fold(0.0, f64::max);
    assert!(worst <= tol, "biquadric: {worst:e} > {tol:e}");
    // And the coefficients themselves.
    let c = m.coefficients(&samples);
    for i in 0..6 {
        assert!(
            (c[i] - up[i]).abs() < 1e-5 && (c[6 + i] - low[i]).abs() < 1e-5,
            "{c:?}"
        );
    }
}

#[test]
fn test05_sh_reproduces_a_band_limited_function() {
    // A random order-5 function sampled at the coarse centres (rounded to f32, which the fit
    // carries to the fine grid amplified by at most ‖M‖_∞), reconstructed at the fine centres.
    let (coarse, fine) = ([12u32, 6u32], [40u32, 20u32]);
    let order = 5;
    let mut rng = Pcg64::seed_from_u64(11);
    let coeffs: Vec<f64> = (0..order * order)
        .map(|_| rng.random_range(-1.0..1.0))
        .collect();
    let f = |d: DVec3| prt_sh::reconstruct(&coeffs, order, d).unwrap();
    let samples: Vec<f32> = (0..cells(coarse))
        .map(|j| f(centre(coarse, j)) as f32)
        .collect();
    let rounding = (0..cells(coarse))
        .map(|j| (f64::from(samples[j]) - f(centre(coarse, j))).abs())
        .fold(0.0, f64::max);
    let m = ShFit::new(coarse, fine, order).unwrap();
    let tol = inf_norm(&m, coarse, fine) * rounding + 1e-12;
    let mut out = vec![0.0; cells(fine)];
    m.apply(&samples, &mut out);
    let worst = (0..out.len())
        .map(|k| (out[k] - f(centre(fine, k))).abs())
        .fold(0.0, f64::max);
    assert!(worst <= tol, "SH: {worst:e} > {tol:e}");
    let fitted = m.coefficients(&samples);
    let cerr = fitted
        .iter()
        .zip(&coeffs)
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(cerr < 1e-5, "coefficients off by {cerr:e}");
    eprintln!("SH order 5 on 12×6: fine error {worst:.2e} (tolerance {tol:.2e})");
}

#[test]
fn test06_multilevel_bsplines_converge_on_a_smooth_function() {
    // A smooth function on the sphere (a broad lobe plus a tilt), sampled on 32 × 16 and
    // compared at the 128 × 64 fine centres, solid-angle-weighted RMS: each level must lower
    // the error, and the default (4 levels: a 32 × 16 lattice) gets within 1 % of the range.
    let (coarse, fine) = ([32u32, 16u32], [128u32, 64u32]);
    let a = DVec3::new(0.5, 0.6, -0.62).normalize();
    let f = |d: DVec3| 0.3 + 0.2 * d.y + (2.0 * (d.dot(a) - 1.0)).exp();
    let samples: Vec<f32> = (0..cells(coarse))
        .map(|j| f(centre(coarse, j)) as f32)
        .collect();
    let default = MultilevelBSpline::default_levels(coarse);
    assert_eq!(default, 4);
    let mut previous = f64::INFINITY;
    for levels in 1..=default + 1 {
        let m = MultilevelBSpline::new(coarse, fine, levels).unwrap();
        let mut out = vec![0.0; cells(fine)];
        m.apply(&samples, &mut out);
        let (mut e2, mut w2) = (0.0, 0.0);
        for (k, v) in out.iter().enumerate() {
            let theta = PI * ((k / 128) as f64 + 0.5) / 64.0;
            e2 += theta.sin() * (v - f(centre(fine, k))).powi(2);
            w2 += theta.sin();
        }
        let rms = (e2 / w2).sqrt();
        eprintln!(
            "bspline, {levels} levels (lattice {:?}): RMS error {rms:.3e}",
            m.finest_lattice()
        );
        assert!(rms < previous, "{levels} levels: {rms} ≥ {previous}");
        if levels == default {
            assert!(rms < 0.01, "{rms}");
        }
        previous = rms;
    }
}

#[test]
fn test07_bad_parameters_are_errors() {
    let ok = [16u32, 8u32];
    let fine = [32u32, 16u32];
    let errors: Vec<(&str, Result<(), prt_fields::FieldError>)> = vec![
        ("empty coarse", Idw::new([0, 8], fine, 4, 1.0).map(|_| ())),
        ("empty fine", Idw::new(ok, [32, 0], 4, 1.0).map(|_| ())),
        (
            "huge fine",
            Idw::new(ok, [1 << 13, 1 << 12], 4, 1.0).map(|_| ()),
        ),
        ("no neighbours", Idw::new(ok, fine, 0, 1.0).map(|_| ())),
        (
            "neighbours > samples",
            Idw::new(ok, fine, 129, 1.0).map(|_| ()),
        ),
        ("32 > 24 samples", Idw::paper([6, 4], fine).map(|_| ())),
        ("negative power", Idw::new(ok, fine, 4, -1.0).map(|_| ())),
        ("NaN power", Idw::new(ok, fine, 4, f64::NAN).map(|_| ())),
        (
            "infinite power",
            Idw::new(ok, fine, 4, f64::INFINITY).map(|_| ()),
        ),
        ("odd H", Biquadric::new([16, 7], fine).map(|_| ())),
        (
            "one ring per hemisphere",
            Biquadric::new([16, 2], fine).map(|_| ()),
        ),
        ("four azimuths", Biquadric::new([4, 8], fine).map(|_| ())),
        ("biquadric empty", Biquadric::new([0, 0], fine).map(|_| ())),
        ("order 0", ShFit::new(ok, fine, 0).map(|_| ())),
        ("order 300", ShFit::new(ok, fine, 300).map(|_| ())),
        (
            "more coefficients than samples",
            ShFit::new([10, 4], fine, 7).map(|_| ()),
        ),
        ("too few azimuths", ShFit::new([8, 16], fine, 5).map(|_| ())),
        ("too few rows", ShFit::new([64, 4], fine, 5).map(|_| ())),
        ("no levels", MultilevelBSpline::new(ok, fine, 0).map(|_| ())),
        (
            "too many levels",
            MultilevelBSpline::new(ok, fine, 11).map(|_| ()),
        ),
        (
            "bspline empty",
            MultilevelBSpline::new([3, 0], fine, 2).map(|_| ()),
        ),
    ];
    for (what, r) in errors {
        match r {
            Err(prt_fields::FieldError::Invalid(msg)) => eprintln!("{what}: {msg}"),
            other => panic!("{what}: expected an Invalid error, got {other:?}"),
        }
    }
    // The smallest grids each method accepts.
    assert!(Idw::new([1, 1], [1, 1], 1, 1.0).is_ok());
    assert!(Biquadric::new([5, 4], [1, 1]).is_ok());
    assert!(ShFit::new([9, 5], [1, 1], 5).is_ok());
    assert!(ShFit::new([1, 1], [2, 2], 1).is_ok());
    assert!(MultilevelBSpline::new([1, 1], [1, 1], 1).is_ok());
}

#[test]
fn test08_names() {
    let (c, f) = ([16u32, 8u32], [32u32, 16u32]);
    assert_eq!(Idw::paper(c, f).unwrap().name(), "idw");
    assert_eq!(Biquadric::new(c, f).unwrap().name(), "biquadric");
    assert_eq!(ShFit::new(c, f, 5).unwrap().name(), "sh");
    assert_eq!(
        MultilevelBSpline::with_default_levels(c, f).unwrap().name(),
        "bspline"
    );
}

#[test]
fn test09_idw_takes_coincident_samples_and_keeps_grid_symmetry() {
    // Fine 3× the coarse: every coarse centre is a fine centre and must come back exactly.
    let (coarse, fine) = ([12u32, 6u32], [36u32, 18u32]);
    let m = Idw::paper(coarse, fine).unwrap();
    let mut rng = Pcg64::seed_from_u64(3);
    let s: Vec<f32> = (0..72).map(|_| rng.random()).collect();
    let mut f = vec![0.0; cells(fine)];
    m.apply(&s, &mut f);
    for j in 0..72 {
        let (c, r) = (j % 12, j / 12);
        assert_eq!(f[(3 * r + 1) * 36 + 3 * c + 1], f64::from(s[j]));
    }
    // Samples constant along each row: the grid is symmetric under rotations by one coarse
    // column (three fine ones) and ties are kept whole, so the fine field repeats every three
    // fine columns.
    let rows: Vec<f32> = (0..72).map(|j| (j / 12) as f32 * 0.25).collect();
    m.apply(&rows, &mut f);
    for r in 0..18 {
        for c in 3..36 {
            let (a, b) = (f[r * 36 + c], f[r * 36 + c % 3]);
            assert!((a - b).abs() < 1e-14, "row {r} col {c}: {a} vs {b}");
        }
    }
}

#[test]
fn test10_timings_64x32_to_256x128() {
    // Prints construction, apply (per pixel) and apply_transpose (per frame) times; run with
    // `--nocapture` to see them. Asserts nothing about time.
    let (coarse, fine) = ([64u32, 32u32], [256u32, 128u32]);
    let mut rng = Pcg64::seed_from_u64(5);
    let s: Vec<f32> = (0..cells(coarse)).map(|_| rng.random()).collect();
    let l: Vec<f64> = (0..cells(fine)).map(|_| rng.random()).collect();
    let timed = |name: &str, build: &dyn Fn() -> Box<dyn LinearReconstruction>| {
        let t = std::time::Instant::now();
        let m = build();
        let build_ms = t.elapsed().as_secs_f64() * 1e3;
        let mut f = vec![0.0; cells(fine)];
        let mut c = vec![0.0; cells(coarse)];
        m.apply(&s, &mut f);
        let runs = 20;
        let t = std::time::Instant::now();
        for _ in 0..runs {
            m.apply(&s, &mut f);
        }
        let apply_ms = t.elapsed().as_secs_f64() * 1e3 / f64::from(runs);
        let t = std::time::Instant::now();
        for _ in 0..runs {
            m.apply_transpose(&l, &mut c);
        }
        let transpose_ms = t.elapsed().as_secs_f64() * 1e3 / f64::from(runs);
        eprintln!(
            "{name:28} build {build_ms:8.1} ms   apply {apply_ms:7.3} ms   apply_transpose {transpose_ms:7.3} ms"
        );
        assert!(f.iter().all(|v| v.is_finite()) && c.iter().all(|v| v.is_finite()));
    };
    timed("idw (32 neighbours, p = 1)", &|| {
        let m = Idw::paper(coarse, fine).unwrap();
        eprintln!(
            "idw: {:.1} weights per fine cell",
            m.nonzeros() as f64 / cells(fine) as f64
        );
        Box::new(m)
    });
    timed("biquadric", &|| {
        Box::new(Biquadric::new(coarse, fine).unwrap())
    });
    timed("sh (order 5)", &|| {
        Box::new(ShFit::new(coarse, fine, 5).unwrap())
    });
    timed("bspline (5 levels, 64×32)", &|| {
        Box::new(MultilevelBSpline::with_default_levels(coarse, fine).unwrap())
    });
    timed("bspline (6 levels, 128×64)", &|| {
        Box::new(MultilevelBSpline::new(coarse, fine, 6).unwrap())
    });
}
