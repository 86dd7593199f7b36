//! The robust solve of `prt fit-lighting --robust` (`inverse::solve_channel_robust`): on a
//! least-squares problem with Gaussian noise and a few gross errors — the situation of pixels
//! a truncated model cannot represent — Tukey's biweight gives the errant equations no weight
//! and recovers the solution to the noise's precision, where the plain solve is pulled far
//! off; on clean data it changes the solution only at the noise's level.

use nalgebra::{DMatrix, DVector};
use prt_scene_relight::inverse::solve_channel_robust;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

/// Noise standard deviation.
const SIGMA: f64 = 1e-3;

/// 400 equations in 4 unknowns (a model of order 2, all bands well determined, so no prior):
/// rows uniform in [-0.5, 0.5)⁴, Gaussian noise of σ = [`SIGMA`] (Box–Muller), and, with
/// `outliers`, every 40th equation off by +50.
fn problem(outliers: bool) -> (DMatrix<f64>, DVector<f64>, DVector<f64>) {
    let mut rng = Pcg64::seed_from_u64(35);
    let x = DVector::from_vec(vec![1.0, -2.0, 0.5, 3.0]);
    let a = DMatrix::from_fn(400, 4, |_, _| rng.random_range(-0.5..0.5));
    let mut b = &a * &x;
    for i in 0..400 {
        let (u1, u2): (f64, f64) = (rng.random_range(f64::EPSILON..1.0), rng.random());
        b[i] += SIGMA * (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos();
        if outliers && i % 40 == 0 {
            b[i] += 50.0;
        }
    }
    (a, b, x)
}

#[test]
fn tukey_reweighting_ignores_gross_errors() {
    // The least-squares error of a coefficient with ~390 clean rows of spread 0.29 is about
    // σ / (√390 · 0.29) ≈ 1.7e-4; 1e-3 allows ~6 of those.
    let (a, b, x) = problem(true);
    let (plain, none) = solve_channel_robust(&a, &b, 2, 1e6, false).unwrap();
    assert_eq!(none, 0);
    assert!(
        (&plain.x - &x).amax() > 0.5,
        "the outliers pull the plain solve"
    );
    let (robust, low) = solve_channel_robust(&a, &b, 2, 1e6, true).unwrap();
    assert!((&robust.x - &x).amax() < 1e-3, "{} vs {x}", robust.x);
    // Every errant equation loses its weight; a clean one does when |r| > 0.54 · 4.685 σ ≈
    // 2.5 σ (weight (1 − u²)² < ½), for 1.2 % of them: about 5 of 390, more than 15 with
    // probability < 1e-4 (Poisson).
    assert!((10..=25).contains(&low), "{low} equations down-weighted");
    // On clean data the reweighting moves the solution only at the noise's level.
    let (a, b, x) = problem(false);
    let (plain, _) = solve_channel_robust(&a, &b, 2, 1e6, false).unwrap();
    let (robust, low) = solve_channel_robust(&a, &b, 2, 1e6, true).unwrap();
    assert!(low <= 15, "{low} clean equations down-weighted");
    assert!((&plain.x - &x).amax() < 1e-3 && (&robust.x - &x).amax() < 1e-3);
}
