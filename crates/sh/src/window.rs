//! Windowing against ringing (Gibbs): Hann and Lanczos (σ-factor) windows and a search for the
//! mildest window that makes a reconstruction non-negative everywhere (the idea of Sloan,
//! "Stupid Spherical Harmonics Tricks", 2008, §deringing), with the error it costs.

use crate::eval::Basis;
use crate::index::{check_len, coefficient_count, ShError};
use crate::quadrature::SphereQuadrature;
use std::f64::consts::PI;

/// A window family.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WindowKind {
    /// `w_l = ½(1 + cos(π l / h))` for `l < h`, 0 beyond.
    Hann,
    /// Lanczos σ-factors `w_l = sinc(l / h)` for `l < h`, 0 beyond.
    Lanczos,
}

/// Per-band weights `w_l`, `l = 0..order`, of a window of width `h > 0` (in degrees `l`).
pub fn window(kind: WindowKind, order: usize, width: f64) -> Result<Vec<f64>, ShError> {
    if width.is_nan() || width <= 0.0 {
        return Err(ShError::InvalidParameter(format!(
            "window width {width} must be > 0"
        )));
    }
    Ok((0..order)
        .map(|l| {
            let x = l as f64 / width;
            if x >= 1.0 {
                0.0
            } else {
                match kind {
                    WindowKind::Hann => 0.5 * (1.0 + (PI * x).cos()),
                    WindowKind::Lanczos => {
                        if l == 0 {
                            1.0
                        } else {
                            (PI * x).sin() / (PI * x)
                        }
                    }
                }
            }
        })
        .collect())
}

/// Multiplies band `l` of RGB coefficients by `weights[l]`.
pub fn apply_window_rgb(coeffs: &[[f64; 3]], weights: &[f64]) -> Result<Vec<[f64; 3]>, ShError> {
    crate::zonal::convolve_bands_rgb(coeffs, weights)
}

/// Result of [`dering`].
#[derive(Clone, Debug)]
pub struct DeringResult {
    /// Window width `h` chosen (`f64::INFINITY` when no window was needed).
    pub width: f64,
    /// The band weights applied.
    pub weights: Vec<f64>,
    /// Windowed coefficients.
    pub coefficients: Vec<[f64; 3]>,
    /// Minimum of the reconstruction over the check grid, before (over all channels).
    pub min_before: f64,
    /// Minimum after windowing (≥ 0 up to rounding).
    pub min_after: f64,
    /// Relative L2 error the window costs: `‖c − c_w‖ / ‖c‖` (Parseval: the function-space error).
    pub relative_l2_cost: f64,
}

/// Finds the widest window of `kind` (the least smoothing) whose reconstruction is non-negative
/// on a dense check grid (a product rule exact to degree `4·order`, i.e. several points per
/// lobe of the highest band), by bisection on the width. Requires a non-negative mean
/// (`c_0 ≥ 0` in every channel), otherwise no window can help and an error is returned.
pub fn dering(
    coeffs: &[[f64; 3]],
    order: usize,
    kind: WindowKind,
) -> Result<DeringResult, ShError> {
    check_len(order, coeffs.len())?;
    if coeffs[0].iter().any(|&c| c < 0.0) {
        return Err(ShError::InvalidParameter(
            "the mean (c_0) is negative: no window makes it non-negative".into(),
        ));
    }
    let grid = SphereQuadrature::exact_for_degree(4 * order);
    let basis = Basis::new(order)?;
    let n2 = coefficient_count(order);
    let ys: Vec<f64> = grid.dirs.iter().flat_map(|d| basis.eval(*d)).collect();
    let min_of = |c: &[[f64; 3]]| -> f64 {
        let mut min = f64::INFINITY;
        for y in ys.chunks_exact(n2) {
            let mut v = [0.0; 3];
            for i in 0..n2 {
                for ch in 0..3 {
                    v[ch] += c[i][ch] * y[i];
                }
            }
            min = min.min(v[0]).min(v[1]).min(v[2]);
        }
        min
    };
    let norm = |c: &[[f64; 3]]| {
        c.iter()
            .flat_map(|v| v.iter())
            .map(|x| x * x)
            .sum::<f64>()
            .sqrt()
    };
    let min_before = min_of(coeffs);
    // Tolerance for "non-negative": rounding of the sums, relative to the mean radiance.
    let tol = -1e-12 * coeffs[0].iter().fold(0.0f64, |a, b| a.max(*b)).max(1e-300);
    if min_before >= tol {
        return Ok(DeringResult {
            width: f64::INFINITY,
            weights: vec![1.0; order],
            coefficients: coeffs.to_vec(),
            min_before,
            min_after: min_before,
            relative_l2_cost: 0.0,
        });
    }
    let (mut lo, mut hi) = (1.0f64, 64.0 * order as f64);
    for _ in 0..48 {
        let mid = (lo * hi).sqrt();
        let c = apply_window_rgb(coeffs, &window(kind, order, mid)?)?;
        if min_of(&c) >= tol {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    let weights = window(kind, order, lo)?;
    let coefficients = apply_window_rgb(coeffs, &weights)?;
    let diff: Vec<[f64; 3]> = coeffs
        .iter()
        .zip(&coefficients)
        .map(|(a, b)| [a[0] - b[0], a[1] - b[1], a[2] - b[2]])
        .collect();
    let n = norm(coeffs);
    Ok(DeringResult {
        width: lo,
        weights,
        min_after: min_of(&coefficients),
        coefficients,
        min_before,
        relative_l2_cost: if n > 0.0 { norm(&diff) / n } else { 0.0 },
    })
}
