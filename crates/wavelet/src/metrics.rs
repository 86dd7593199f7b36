//! Errors of approximations on lat-long grids: relative L2 (optionally solid-angle weighted)
//! and the relative Sobolev H¹ error of the paper's Fig. 9.

use std::f64::consts::PI;

use crate::error::{check_finite, check_len, Result, WaveletError};

fn check_grid(width: usize, height: usize) -> Result<usize> {
    if width == 0 || height == 0 {
        return Err(WaveletError::EmptyGrid { width, height });
    }
    width
        .checked_mul(height)
        .ok_or(WaveletError::TooLarge { width, height })
}

fn check_pair(reference: &[f64], approximation: &[f64], width: usize, height: usize) -> Result<()> {
    let len = check_grid(width, height)?;
    check_len(reference.len(), len)?;
    check_len(approximation.len(), len)?;
    check_finite(reference)?;
    check_finite(approximation)
}

/// `sqrt(error² / reference²)`: 0 when both are 0, an error when only the reference is.
fn ratio(error2: f64, reference2: f64) -> Result<f64> {
    if reference2 > 0.0 {
        Ok((error2 / reference2).sqrt())
    } else if error2 == 0.0 {
        Ok(0.0)
    } else {
        Err(WaveletError::ZeroReference)
    }
}

/// The exact solid angle of one texel of each row of a `width × height` lat-long map
/// (CONVENTIONS "Latitude-longitude": row `j` spans `θ ∈ [πj/H, π(j+1)/H)`):
/// `(2π/W)(cos(πj/H) − cos(π(j+1)/H))`, ∝ sin θ; they sum to 4π over the map.
///
/// # Errors
/// A zero size.
pub fn texel_solid_angles(width: usize, height: usize) -> Result<Vec<f64>> {
    check_grid(width, height)?;
    let dphi = 2.0 * PI / width as f64;
    Ok((0..height)
        .map(|j| {
            let (t0, t1) = (
                PI * j as f64 / height as f64,
                PI * (j + 1) as f64 / height as f64,
            );
            // cos t0 − cos t1 = 2 sin((t0+t1)/2) sin((t1−t0)/2), without cancellation
            dphi * 2.0 * (0.5 * (t0 + t1)).sin() * (0.5 * (t1 - t0)).sin()
        })
        .collect())
}

/// The relative L2 error `‖approximation − reference‖ / ‖reference‖` over a `width × height`
/// row-major grid, each row's squared differences weighted by `row_weights[y]` (e.g.
/// [`texel_solid_angles`], for the error on the sphere) or unweighted (`None`). 0 when both
/// are zero.
///
/// # Errors
/// A zero size, wrong lengths, non-finite values, a negative or non-finite weight, or a
/// reference of zero (weighted) norm with a non-zero difference.
pub fn relative_l2_error(
    reference: &[f64],
    approximation: &[f64],
    width: usize,
    height: usize,
    row_weights: Option<&[f64]>,
) -> Result<f64> {
    check_pair(reference, approximation, width, height)?;
    if let Some(w) = row_weights {
        check_len(w.len(), height)?;
        if let Some(row) = w.iter().position(|v| !v.is_finite() || *v < 0.0) {
            return Err(WaveletError::InvalidWeight { row, value: w[row] });
        }
    }
    let (mut error2, mut reference2) = (0.0, 0.0);
    for y in 0..height {
        let weight = row_weights.map_or(1.0, |w| w[y]);
        let row = y * width..(y + 1) * width;
        let (e, r) = reference[row.clone()]
            .iter()
            .zip(&approximation[row])
            .fold((0.0, 0.0), |(e, r), (a, b)| {
                (e + (b - a) * (b - a), r + a * a)
            });
        error2 += weight * e;
        reference2 += weight * r;
    }
    ratio(error2, reference2)
}

/// Squared discrete H¹ norm of `g` on the lat-long parameter rectangle `[0, 2π) × [0, π]`:
/// `Σ g² + Σ (Δ_x g / h_x)² + Σ (Δ_y g / h_y)²` with `h_x = 2π/W`, `h_y = π/H`, `Δ_x` the
/// forward difference periodic in x, `Δ_y` the forward difference between rows (`H − 1` per
/// column, none across the poles). The common area factor `h_x h_y` is left out (it cancels in
/// the relative error).
/// The squared discrete Sobolev H¹ norm of a `width × height` lat-long function, as
/// [`sobolev_h1_relative_error`] defines it (`g.len()` must be `width · height`; for sums of
/// norms over many functions).
#[must_use]
pub fn sobolev_h1_norm2(g: &[f64], width: usize, height: usize) -> f64 {
    h1_norm2(g, width, height)
}

fn h1_norm2(g: &[f64], width: usize, height: usize) -> f64 {
    let (hx, hy) = (2.0 * PI / width as f64, PI / height as f64);
    let mut sum = 0.0;
    for y in 0..height {
        for x in 0..width {
            let v = g[y * width + x];
            let dx = (g[y * width + (x + 1) % width] - v) / hx;
            sum += v * v + dx * dx;
            if y + 1 < height {
                let dy = (g[(y + 1) * width + x] - v) / hy;
                sum += dy * dy;
            }
        }
    }
    sum
}

/// The relative Sobolev H¹ error `‖e‖_{H¹} / ‖reference‖_{H¹}`, `e = approximation −
/// reference`, with the discrete norm: L2 of the function plus L2 of its finite-difference
/// gradient with respect to the angles, `‖g‖²_{H¹} = Σ g² + Σ (Δ_φ g / (2π/W))² +
/// Σ (Δ_θ g / (π/H))²` (periodic in azimuth x, one-sided between rows, unweighted). The
/// gradient term penalises the discontinuities that a Haar approximation introduces
/// (Masselus et al. 2004, Fig. 9). 0 when both are zero.
///
/// # Errors
/// A zero size, wrong lengths, non-finite values, or a zero reference with a non-zero
/// difference.
pub fn sobolev_h1_relative_error(
    reference: &[f64],
    approximation: &[f64],
    width: usize,
    height: usize,
) -> Result<f64> {
    check_pair(reference, approximation, width, height)?;
    let error: Vec<f64> = approximation
        .iter()
        .zip(reference)
        .map(|(a, r)| a - r)
        .collect();
    ratio(
        h1_norm2(&error, width, height),
        h1_norm2(reference, width, height),
    )
}
