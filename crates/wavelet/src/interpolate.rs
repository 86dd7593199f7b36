//! Wavelet interpolation ([`interpolate`]).

use std::f64::consts::SQRT_2;

use crate::dwt1d::{run_step, Bank, Scratch, Step};
use crate::error::{check_finite, check_len, Result, WaveletError};
use crate::wavelet::{Boundaries, Wavelet};

/// Refines a `coarse_width × coarse_height` grid (row-major `[y][x]`) to `width × height` by
/// inverse transforms with zero details; each fine size must be the coarse one times a power of
/// two (1 leaves that axis unchanged).
///
/// Wavelet interpolation (Masselus et al. 2004, §4 "Wavelet Transform"): a sampled function is
/// refined by "repeatedly inserting additional samples halfway between each sample point", i.e.
/// by taking the samples as the approximation band of a finer grid and inverse-transforming with
/// all detail coefficients set to zero.
///
/// With PyWavelets' normalisation a constant `a` has approximation coefficients `√2 a` after one
/// 1D level (the analysis low pass sums to √2, the high pass to 0), so the coarse samples are
/// scaled by `√2` per 1D level (`2` per 2D level) before the synthesis: constants stay
/// constants. The synthesis is separable, so the two axes may be refined by different factors
/// (64×32 → 256×64: two levels along x, one along y); with equal factors this is exactly
/// `pywt.waverec2([2^L · coarse, zeros…], …)`. For LeGall 5/3 (linear B-spline scaling
/// function) the result interpolates linearly between the coarse samples; CDF 9/7 gives a smoother
/// (cubic-spline-like) refinement that rings slightly at sharp features; Haar repeats samples.
///
/// # Errors
/// A zero size, sizes that are not power-of-two multiples, a wrong `coarse` length, a
/// non-finite value, or a fine grid too large to index.
pub fn interpolate(
    wavelet: Wavelet,
    boundaries: Boundaries,
    coarse: &[f64],
    coarse_width: usize,
    coarse_height: usize,
    width: usize,
    height: usize,
) -> Result<Vec<f64>> {
    let size_error = WaveletError::InterpolationSize {
        coarse_width,
        coarse_height,
        width,
        height,
    };
    if coarse_width == 0 || coarse_height == 0 {
        return Err(WaveletError::EmptyGrid {
            width: coarse_width,
            height: coarse_height,
        });
    }
    let factor = |fine: usize, coarse: usize| {
        (fine.is_multiple_of(coarse) && (fine / coarse).is_power_of_two())
            .then(|| (fine / coarse).trailing_zeros() as usize)
    };
    let (Some(levels_x), Some(levels_y)) =
        (factor(width, coarse_width), factor(height, coarse_height))
    else {
        return Err(size_error);
    };
    if width
        .checked_mul(height)
        .is_none_or(|n| n > isize::MAX as usize / 16)
    {
        return Err(WaveletError::TooLarge { width, height });
    }
    check_len(coarse.len(), coarse_width * coarse_height)?;
    check_finite(coarse)?;

    let bank = Bank::new(wavelet);
    let mut scratch = Scratch::default();
    let (mut w, mut h) = (coarse_width, coarse_height);
    let mut grid = coarse.to_vec();
    let mut line = Vec::new();
    for _ in 0..levels_x {
        let mut finer = vec![0.0; 2 * w * h];
        for y in 0..h {
            line.clear();
            line.extend(grid[y * w..(y + 1) * w].iter().map(|v| v * SQRT_2));
            line.resize(2 * w, 0.0);
            run_step(
                &bank,
                boundaries.x,
                Step::Synthesis,
                &mut line,
                &mut scratch,
            );
            finer[y * 2 * w..(y + 1) * 2 * w].copy_from_slice(&line);
        }
        grid = finer;
        w *= 2;
    }
    for _ in 0..levels_y {
        let mut finer = vec![0.0; w * 2 * h];
        for x in 0..w {
            line.clear();
            line.extend((0..h).map(|y| grid[y * w + x] * SQRT_2));
            line.resize(2 * h, 0.0);
            run_step(
                &bank,
                boundaries.y,
                Step::Synthesis,
                &mut line,
                &mut scratch,
            );
            for (y, v) in line.iter().enumerate() {
                finer[y * w + x] = *v;
            }
        }
        grid = finer;
        h *= 2;
    }
    Ok(grid)
}
