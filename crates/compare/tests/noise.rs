//! The Monte Carlo noise estimators on synthetic renders of known noise.

mod common;

use common::assert_close;
use prt_compare::{
    compare, noise_corrected_rmse, noise_from_pair, noise_from_variance, CompareOptions, Image,
    Mask, NoiseMethod,
};
use rand::Rng;
use rand::SeedableRng;

/// Standard normal samples by the Box–Muller transform.
fn gaussian(rng: &mut rand_pcg::Pcg64) -> f64 {
    let u1: f64 = 1.0 - rng.random::<f64>(); // (0, 1]
    let u2: f64 = rng.random();
    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
}

fn truth(w: usize, h: usize) -> Image {
    Image::from_fn(w, h, |x, y| {
        let u = (x as f32 + 0.5) / w as f32;
        let v = (y as f32 + 0.5) / h as f32;
        [2.0 + u, 2.0 + v, 2.0 + u * v]
    })
}

fn noisy(truth: &Image, sigma: f64, seed: u64) -> Image {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    Image::from_fn(truth.width, truth.height, |x, y| {
        truth
            .pixel(x, y)
            .unwrap()
            .map(|v| (f64::from(v) + sigma * gaussian(&mut rng)) as f32)
    })
}

#[test]
fn test01_pair_estimate_within_statistical_tolerance() {
    let (w, h, sigma) = (64, 64, 0.05);
    let t = truth(w, h);
    let a = noisy(&t, sigma, 1);
    let b = noisy(&t, sigma, 2);
    let report = noise_from_pair(&a, &b, None, &CompareOptions::default()).unwrap();
    assert_eq!(report.method, NoiseMethod::Pair);
    // σ̂² = Σd²/(2N) with d ~ N(0, 2σ²): Var(d²) = 8σ⁴, so sd(σ̂²) = σ²·sqrt(2/N) and
    // sd(σ̂)/σ ≈ 1/sqrt(2N). N = 3·64·64 = 12288: 0.64 %. Allow 5 sd.
    let n = 3.0 * (w * h) as f64;
    let tol = 5.0 * sigma / (2.0 * n).sqrt();
    assert_close(report.whole.rmse, sigma, tol, "noise rmse");
    assert_close(
        report.whole.rmse_of_mean.unwrap(),
        sigma / 2f64.sqrt(),
        tol / 2f64.sqrt(),
        "rmse of the mean",
    );
    // The ceiling uses the reference's (a's) peak.
    let peak = a
        .pixels
        .iter()
        .flatten()
        .fold(f64::MIN, |m, &v| m.max(f64::from(v)));
    assert_close(
        report.whole.psnr_hdr_ceiling,
        10.0 * (peak * peak / (report.whole.rmse * report.whole.rmse)).log10(),
        1e-9,
        "ceiling",
    );
    // Consistency with compare(): a perfect test image (the truth) measured against the noisy
    // reference has rmse ≈ σ, and the noise-corrected rmse ≈ 0 within the noise of both
    // estimates (each ~σ/sqrt(2N) relative), i.e. ≲ σ·sqrt(2·5/sqrt(2N)).
    let m = compare(&t, &a, None).unwrap();
    assert_close(
        m.whole.rmse,
        sigma,
        5.0 * sigma / (2.0 * n).sqrt(),
        "rmse vs reference",
    );
    let corrected = noise_corrected_rmse(m.whole.rmse, report.whole.rmse);
    assert!(
        corrected < sigma * (10.0 / (2.0 * n).sqrt()).sqrt(),
        "corrected {corrected}"
    );
}

#[test]
fn test02_pair_masked_region_has_its_own_noise() {
    // Noise σ₁ on the left half, σ₂ on the right; the mask is the right half.
    let (w, h) = (64, 32);
    let t = truth(w, h);
    let left = noisy(&t, 0.02, 3);
    let right = noisy(&t, 0.2, 4);
    let pick = |l: &Image, r: &Image| {
        Image::from_fn(w, h, |x, y| {
            if x < w / 2 {
                l.pixel(x, y).unwrap()
            } else {
                r.pixel(x, y).unwrap()
            }
        })
    };
    let a = pick(&left, &right);
    let b = pick(&noisy(&t, 0.02, 5), &noisy(&t, 0.2, 6));
    let mask = Mask::from_bools(w, h, (0..w * h).map(|i| i % w >= w / 2).collect()).unwrap();
    let r = noise_from_pair(&a, &b, Some(&mask), &CompareOptions::default()).unwrap();
    let masked = r.masked.unwrap();
    let nm = 3.0 * mask.count() as f64;
    assert_close(
        masked.rmse,
        0.2,
        5.0 * 0.2 / (2.0 * nm).sqrt(),
        "masked noise",
    );
    // Whole image: mean variance (0.02² + 0.2²)/2.
    let whole = ((0.02f64.powi(2) + 0.2f64.powi(2)) / 2.0).sqrt();
    // The right half dominates; its relative sd per value is sqrt(2/Nm) on σ̂², so on σ̂ of the
    // whole ≈ (1/2)·sqrt(2/Nm)·(σ₂²/2)/whole² relative. Allow 5 sd.
    let n_half = nm;
    let rel = 0.5 * (2.0 / n_half).sqrt() * (0.04 / 2.0) / whole.powi(2);
    assert_close(r.whole.rmse, whole, 5.0 * rel * whole, "whole noise");
}

#[test]
fn test03_variance_image() {
    // Constant variance v in every channel: rmse = sqrt(v) exactly.
    let reference = Image::new(2, 1, vec![[0.5, 0.5, 0.5], [2.0, 0.25, 0.0]]).unwrap();
    let var = Image::new(2, 1, vec![[1e-4; 3]; 2]).unwrap();
    let r = noise_from_variance(&var, &reference, None, &CompareOptions::default()).unwrap();
    assert_eq!(r.method, NoiseMethod::Variance);
    assert_close(r.whole.rmse, 1e-2, 1e-9, "rmse");
    assert_close(
        r.whole.psnr_hdr_ceiling,
        10.0 * (4.0 / 1e-4f64).log10(),
        1e-5,
        "ceiling",
    );
    assert!(r.whole.rmse_of_mean.is_none());
    // LDR (delta method by hand): slopes 255·f'(x), f'(x) = 1.055/2.4·x^(1/2.4−1) for
    // x = 0.5, 0.5, 0.5, 0.25; 0 for the clamped 2.0; 255·12.92 for 0 (linear segment).
    let fp = |x: f64| 1.055 / 2.4 * x.powf(1.0 / 2.4 - 1.0);
    let slopes2 =
        3.0 * (255.0 * fp(0.5)).powi(2) + (255.0 * fp(0.25)).powi(2) + (255.0 * 12.92f64).powi(2);
    let mse8 = slopes2 * 1e-4 / 6.0;
    assert_close(
        r.whole.psnr_ldr_ceiling,
        10.0 * (255.0f64.powi(2) / mse8).log10(),
        1e-6,
        "ldr ceiling",
    );
    let mut neg = var.clone();
    neg.pixels[1][0] = -1.0;
    assert!(noise_from_variance(&neg, &reference, None, &CompareOptions::default()).is_err());
}
