//! Zonal harmonics: closed-form lobes, rotation to an axis, and convolution.
//!
//! A zonal function `f(ω) = g(ω·a)` about axis `a` has coefficients `f_l^m = √(4π/(2l+1)) g_l
//! y_l^m(a)`, where `g_l` is its zonal coefficient (`m = 0`). Convolving a function with a zonal
//! kernel multiplies band `l` by `Λ_l g_l`, `Λ_l = √(4π/(2l+1))` (Funk–Hecke; Ramamoorthi &
//! Hanrahan 2001). This module works with the **band multipliers** `A_l = Λ_l g_l` and converts.
//!
//! Normalised Phong lobe `(e+1)/(2π) max(0, cos θ)^e` (unit integral): `A_l = (e+1) I_l(e)` with
//! `I_l(e) = ∫₀¹ x^e P_l(x) dx`, which satisfies `I_0 = 1/(e+1)`, `I_1 = 1/(e+2)` and
//! `I_{l+2} = I_l (e − l)/(e + l + 3)` (from the Gamma-function closed form
//! `I_l = √π Γ(e+1) / (2^{e+1} Γ(1 + (e−l)/2) Γ((e+l+3)/2))`). Each step multiplies by a
//! factor of modulus ≤ 1, so the recurrence is stable for every real `e ≥ 0` and every `l`
//! (no Gamma functions of large arguments, no cancellation). The clamped cosine is the case
//! `e = 1` scaled by `2π/(e+1) = π`: `A_0 = π`, `A_1 = 2π/3`, `A_2 = π/4`, odd `A_l = 0` for `l > 1`.

use crate::eval::Basis;
use crate::index::{check_len, check_order, index, ShError, MAX_ORDER};
use glam::DVec3;
use std::f64::consts::PI;

/// `Λ_l = √(4π/(2l+1))`.
#[inline]
#[must_use]
pub fn lambda(l: usize) -> f64 {
    (4.0 * PI / (2 * l + 1) as f64).sqrt()
}

/// Band multipliers `A_l` of the normalised Phong lobe `(e+1)/(2π) max(0, cos θ)^e`,
/// `l = 0..order`. Errors on a negative or non-finite exponent.
pub fn phong_lobe_bands(exponent: f64, order: usize) -> Result<Vec<f64>, ShError> {
    check_order(order, MAX_ORDER)?;
    if !exponent.is_finite() || exponent < 0.0 {
        return Err(ShError::InvalidParameter(format!(
            "Phong exponent {exponent} must be finite and ≥ 0"
        )));
    }
    let e = exponent;
    let mut a = vec![0.0; order];
    // Work with A_l = (e+1) I_l directly: A_0 = 1, A_1 = (e+1)/(e+2).
    a[0] = 1.0;
    if order > 1 {
        a[1] = (e + 1.0) / (e + 2.0);
    }
    for l in 2..order {
        let lp = (l - 2) as f64;
        a[l] = a[l - 2] * (e - lp) / (e + lp + 3.0);
    }
    Ok(a)
}

/// Band multipliers `A_l` of the clamped cosine `max(0, cos θ)` (Lambert):
/// `A_l = π · (normalised lobe with e = 1)`.
pub fn clamped_cosine_bands(order: usize) -> Result<Vec<f64>, ShError> {
    let mut a = phong_lobe_bands(1.0, order)?;
    for v in &mut a {
        *v *= PI;
    }
    // Exact zeros for odd l > 1 (the recurrence gives 0·… already; make it explicit).
    for (l, v) in a.iter_mut().enumerate() {
        if l > 1 && l % 2 == 1 {
            *v = 0.0;
        }
    }
    Ok(a)
}

/// Converts band multipliers `A_l` into zonal coefficients `g_l = A_l / Λ_l`.
#[must_use]
pub fn bands_to_zonal(bands: &[f64]) -> Vec<f64> {
    bands
        .iter()
        .enumerate()
        .map(|(l, a)| a / lambda(l))
        .collect()
}

/// Converts zonal coefficients `g_l` into band multipliers `A_l = Λ_l g_l`.
#[must_use]
pub fn zonal_to_bands(zonal: &[f64]) -> Vec<f64> {
    zonal
        .iter()
        .enumerate()
        .map(|(l, g)| g * lambda(l))
        .collect()
}

/// Coefficients of the zonal function with zonal coefficients `zonal` (`g_l`, `order` of them)
/// rotated so its axis is `axis`: `f_l^m = Λ_l g_l y_l^m(axis)`. O(order²).
pub fn rotate_zonal(zonal: &[f64], axis: DVec3) -> Result<Vec<f64>, ShError> {
    let order = zonal.len();
    let basis = Basis::new(order)?;
    let mut y = basis.eval(axis);
    for l in 0..order {
        let s = lambda(l) * zonal[l];
        for m in -(l as i64)..=(l as i64) {
            y[index(l, m)] *= s;
        }
    }
    Ok(y)
}

/// Convolves coefficients with a zonal kernel given by its zonal coefficients `g_l`
/// (band `l` multiplied by `Λ_l g_l`). `coeffs.len()` must be `zonal.len()²`.
pub fn convolve_zonal(coeffs: &[f64], zonal: &[f64]) -> Result<Vec<f64>, ShError> {
    let order = zonal.len();
    check_len(order, coeffs.len())?;
    let mut out = coeffs.to_vec();
    for l in 0..order {
        let s = lambda(l) * zonal[l];
        for v in &mut out[l * l..(l + 1) * (l + 1)] {
            *v *= s;
        }
    }
    Ok(out)
}

/// Multiplies band `l` of RGB coefficients by `bands[l]` (convolution with band multipliers).
pub fn convolve_bands_rgb(coeffs: &[[f64; 3]], bands: &[f64]) -> Result<Vec<[f64; 3]>, ShError> {
    let order = bands.len();
    check_len(order, coeffs.len())?;
    let mut out = coeffs.to_vec();
    for l in 0..order {
        for v in &mut out[l * l..(l + 1) * (l + 1)] {
            for c in v.iter_mut() {
                *c *= bands[l];
            }
        }
    }
    Ok(out)
}

/// The fraction of a zonal lobe's energy (squared L2 norm, Parseval) beyond `order` bands,
/// given its zonal coefficients up to a larger order: `Σ_{l≥order} g_l² / Σ g_l²`.
#[must_use]
pub fn energy_beyond(zonal: &[f64], order: usize) -> f64 {
    let total: f64 = zonal.iter().map(|g| g * g).sum();
    if total == 0.0 {
        return 0.0;
    }
    zonal.iter().skip(order).map(|g| g * g).sum::<f64>() / total
}

/// Smallest order whose truncation keeps all but `max_fraction` of a normalised Phong lobe's
/// energy (searched up to [`MAX_ORDER`]; `None` if even that is not enough, e.g. near-delta
/// lobes, so callers can say so instead of truncating silently).
#[must_use]
pub fn phong_order_for_energy(exponent: f64, max_fraction: f64) -> Option<usize> {
    let g = bands_to_zonal(&phong_lobe_bands(exponent, MAX_ORDER).ok()?);
    // The tail of Σ g_l² converges like Σ (2l+1) A_l² / 4π; beyond MAX_ORDER we estimate it by
    // the asymptotic Gaussian A_l ≈ exp(−l(l+1)/(2e)) to decide whether MAX_ORDER suffices.
    let tail_estimate: f64 = (MAX_ORDER..4 * MAX_ORDER)
        .map(|l| {
            let a = (-((l * (l + 1)) as f64) / (2.0 * exponent.max(1e-12))).exp();
            (2 * l + 1) as f64 / (4.0 * PI) * a * a
        })
        .sum();
    let known: f64 = g.iter().map(|v| v * v).sum();
    let total = known + tail_estimate;
    let mut tail = total;
    for (order, v) in g.iter().enumerate() {
        if tail / total <= max_fraction {
            return Some(order.max(1));
        }
        tail -= v * v;
    }
    if tail / total <= max_fraction {
        Some(MAX_ORDER)
    } else {
        None
    }
}
