//! One-dimensional transforms: the single-level analysis and synthesis steps (and the adjoint of
//! synthesis) that the 2D transform also uses, and the multi-level 1D transform.
//!
//! A step works on a contiguous signal of even length `n`: analysis reads the signal extended by
//! the boundary rule and writes `n/2` low and `n/2` high coefficients; synthesis extends the
//! coefficient bands by the matching rule and scatters them through the synthesis filters.
//!
//! Coefficient extension for [`Boundary::Symmetric`]: the whole-sample symmetric extension of
//! `x` (period `2n − 2`, mirrored about samples 0 and `n − 1`) has low coefficients
//! `c[o] = Σ_m a(m) x[2o + m]` with `c[−o] = c[o]` (the low pass is symmetric about 0) and
//! period `n − 1`, hence `c[n − 1 − o] = c[o]`; its high coefficients (high pass symmetric about
//! `m = 1`) satisfy `d[−1 − o] = d[o]` with period `n − 1`, hence `d[n − 2 − o] = d[o]`.
//! Synthesising the infinite extended bands gives back the extended signal, so the window
//! `[0, n)` is the signal itself: perfect reconstruction with `n` coefficients.

use crate::error::{check_finite, Result, WaveletError};
use crate::wavelet::{Boundary, Filter, Wavelet};

/// The four filters of a wavelet and their spans.
#[derive(Clone, Debug)]
pub(crate) struct Bank {
    pub(crate) analysis_low: Filter,
    pub(crate) analysis_high: Filter,
    pub(crate) synthesis_low: Filter,
    pub(crate) synthesis_high: Filter,
}

impl Bank {
    pub(crate) fn new(wavelet: Wavelet) -> Bank {
        Bank {
            analysis_low: wavelet.analysis_low(),
            analysis_high: wavelet.analysis_high(),
            synthesis_low: wavelet.synthesis_low(),
            synthesis_high: wavelet.synthesis_high(),
        }
    }

    fn analysis_span(&self) -> (isize, isize) {
        (
            self.analysis_low.first().min(self.analysis_high.first()),
            self.analysis_low.last().max(self.analysis_high.last()),
        )
    }

    fn synthesis_span(&self) -> (isize, isize) {
        (
            self.synthesis_low.first().min(self.synthesis_high.first()),
            self.synthesis_low.last().max(self.synthesis_high.last()),
        )
    }
}

/// Reusable buffers of the steps.
#[derive(Default, Debug)]
pub(crate) struct Scratch {
    ext: Vec<f64>,
    pub(crate) low: Vec<f64>,
    pub(crate) high: Vec<f64>,
    pub(crate) line: Vec<f64>,
}

/// Index of extended sample `i` of a signal of `n ≥ 2` samples.
fn fold_signal(i: isize, n: usize, boundary: Boundary) -> usize {
    let n = n as isize;
    match boundary {
        Boundary::Periodic => i.rem_euclid(n) as usize,
        Boundary::Symmetric => {
            let period = 2 * n - 2;
            let r = i.rem_euclid(period);
            (if r >= n { period - r } else { r }) as usize
        }
    }
}

/// Index of extended low coefficient `o` of a signal of `n ≥ 2` samples (`n/2` coefficients).
fn fold_low(o: isize, n: usize, boundary: Boundary) -> usize {
    let half = (n / 2) as isize;
    match boundary {
        Boundary::Periodic => o.rem_euclid(half) as usize,
        Boundary::Symmetric => {
            let period = n as isize - 1;
            let r = o.rem_euclid(period);
            (if r >= half { period - r } else { r }) as usize
        }
    }
}

/// Index of extended high coefficient `o` of a signal of `n ≥ 2` samples.
fn fold_high(o: isize, n: usize, boundary: Boundary) -> usize {
    let half = (n / 2) as isize;
    match boundary {
        Boundary::Periodic => o.rem_euclid(half) as usize,
        Boundary::Symmetric => {
            let period = n as isize - 1;
            let r = o.rem_euclid(period);
            (if r >= half { period - 1 - r } else { r }) as usize
        }
    }
}

fn dot(filter: &Filter, samples: &[f64], start: usize) -> f64 {
    filter
        .taps
        .iter()
        .zip(&samples[start..start + filter.taps.len()])
        .map(|(t, x)| t * x)
        .sum()
}

/// Coefficients `o` whose synthesis support `[2o + first, 2o + last]` meets `[0, n)`.
fn synthesis_range(bank: &Bank, n: usize) -> (isize, isize) {
    let (first, last) = bank.synthesis_span();
    let o_min = (-last).div_euclid(2) + isize::from((-last).rem_euclid(2) != 0);
    let o_max = (n as isize - 1 - first).div_euclid(2);
    (o_min, o_max)
}

/// One analysis level: `x` (even length `n ≥ 2`) to `low` and `high` (`n/2` each).
pub(crate) fn analysis_step(
    bank: &Bank,
    boundary: Boundary,
    x: &[f64],
    low: &mut [f64],
    high: &mut [f64],
    ext: &mut Vec<f64>,
) {
    let n = x.len();
    let (first, last) = bank.analysis_span();
    let pad_lo = (-first).max(0);
    let pad_hi = (last - 1).max(0);
    ext.clear();
    ext.extend((-pad_lo..n as isize + pad_hi).map(|i| x[fold_signal(i, n, boundary)]));
    for o in 0..n / 2 {
        let centre = (2 * o) as isize + pad_lo; // ext index of sample 2o
        low[o] = dot(
            &bank.analysis_low,
            ext,
            (centre + bank.analysis_low.offset) as usize,
        );
        high[o] = dot(
            &bank.analysis_high,
            ext,
            (centre + bank.analysis_high.offset) as usize,
        );
    }
}

/// One synthesis level: `low` and `high` (`n/2` each) to `x` (length `n`).
pub(crate) fn synthesis_step(
    bank: &Bank,
    boundary: Boundary,
    low: &[f64],
    high: &[f64],
    x: &mut [f64],
    ext: &mut Vec<f64>,
) {
    let n = x.len();
    let (first, last) = bank.synthesis_span();
    let (o_min, o_max) = synthesis_range(bank, n);
    let base = 2 * o_min + first; // sample index of ext[0]
    ext.clear();
    ext.resize((2 * o_max + last - base + 1) as usize, 0.0);
    for o in o_min..=o_max {
        let c = low[fold_low(o, n, boundary)];
        let d = high[fold_high(o, n, boundary)];
        let at = 2 * o - base;
        let lo = (at + bank.synthesis_low.offset) as usize;
        for (e, t) in ext[lo..].iter_mut().zip(&bank.synthesis_low.taps) {
            *e += t * c;
        }
        let hi = (at + bank.synthesis_high.offset) as usize;
        for (e, t) in ext[hi..].iter_mut().zip(&bank.synthesis_high.taps) {
            *e += t * d;
        }
    }
    let start = (-base) as usize;
    x.copy_from_slice(&ext[start..start + n]);
}

/// The transpose of [`synthesis_step`]: `x` (length `n`) to the inner products of `x` with
/// the synthesis functions of the level, `low` and `high` (`n/2` each).
pub(crate) fn synthesis_adjoint_step(
    bank: &Bank,
    boundary: Boundary,
    x: &[f64],
    low: &mut [f64],
    high: &mut [f64],
    ext: &mut Vec<f64>,
) {
    let n = x.len();
    let (first, last) = bank.synthesis_span();
    let (o_min, o_max) = synthesis_range(bank, n);
    let base = 2 * o_min + first;
    ext.clear();
    ext.resize((2 * o_max + last - base + 1) as usize, 0.0);
    let start = (-base) as usize;
    ext[start..start + n].copy_from_slice(x);
    low.fill(0.0);
    high.fill(0.0);
    for o in o_min..=o_max {
        let at = 2 * o - base;
        low[fold_low(o, n, boundary)] += dot(
            &bank.synthesis_low,
            ext,
            (at + bank.synthesis_low.offset) as usize,
        );
        high[fold_high(o, n, boundary)] += dot(
            &bank.synthesis_high,
            ext,
            (at + bank.synthesis_high.offset) as usize,
        );
    }
}

/// Which of the three level operations to run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Step {
    Analysis,
    Synthesis,
    SynthesisAdjoint,
}

/// Runs `step` on `data` (length `n`, even) in place: analysis and the adjoint write
/// `[low | high]`, synthesis reads it.
pub(crate) fn run_step(
    bank: &Bank,
    boundary: Boundary,
    step: Step,
    data: &mut [f64],
    scratch: &mut Scratch,
) {
    let n = data.len();
    let half = n / 2;
    let Scratch { ext, low, high, .. } = scratch;
    low.resize(half, 0.0);
    high.resize(half, 0.0);
    match step {
        Step::Analysis | Step::SynthesisAdjoint => {
            if step == Step::Analysis {
                analysis_step(bank, boundary, data, low, high, ext);
            } else {
                synthesis_adjoint_step(bank, boundary, data, low, high, ext);
            }
            data[..half].copy_from_slice(low);
            data[half..].copy_from_slice(high);
        }
        Step::Synthesis => {
            low.copy_from_slice(&data[..half]);
            high.copy_from_slice(&data[half..]);
            synthesis_step(bank, boundary, low, high, data, ext);
        }
    }
}

/// The most levels a length allows: the number of times it halves to an integer
/// (its power-of-two factor); 0 for an empty or odd length.
#[must_use]
pub fn max_levels_1d(len: usize) -> usize {
    if len == 0 {
        0
    } else {
        len.trailing_zeros() as usize
    }
}

pub(crate) fn check_levels_1d(len: usize, levels: usize) -> Result<()> {
    if len == 0 {
        return Err(WaveletError::EmptyGrid {
            width: 0,
            height: 1,
        });
    }
    let max = max_levels_1d(len);
    if levels > max {
        return Err(WaveletError::TooManySignalLevels { len, levels, max });
    }
    Ok(())
}

/// Multi-level forward transform of a 1D signal.
///
/// Output layout: `[a_L | d_L | d_{L−1} | … | d_1]` (`a_L` the `N/2^L` approximation
/// coefficients, `d_l` the `N/2^l` detail coefficients of level `l`), the concatenation of
/// PyWavelets' `wavedec(x, name, mode, level=L)`. `levels = 0` returns the signal.
///
/// # Errors
/// An empty signal, a length not divisible by `2^levels`, a non-finite sample.
pub fn forward_1d(
    wavelet: Wavelet,
    boundary: Boundary,
    signal: &[f64],
    levels: usize,
) -> Result<Vec<f64>> {
    check_levels_1d(signal.len(), levels)?;
    check_finite(signal)?;
    let mut data = signal.to_vec();
    multi_level_1d(
        &Bank::new(wavelet),
        boundary,
        Step::Analysis,
        &mut data,
        levels,
    );
    Ok(data)
}

/// Multi-level inverse transform of [`forward_1d`]'s layout.
///
/// # Errors
/// An empty array, a length not divisible by `2^levels`, a non-finite coefficient.
pub fn inverse_1d(
    wavelet: Wavelet,
    boundary: Boundary,
    coefficients: &[f64],
    levels: usize,
) -> Result<Vec<f64>> {
    check_levels_1d(coefficients.len(), levels)?;
    check_finite(coefficients)?;
    let mut data = coefficients.to_vec();
    multi_level_1d(
        &Bank::new(wavelet),
        boundary,
        Step::Synthesis,
        &mut data,
        levels,
    );
    Ok(data)
}

/// Runs `levels` levels of `step` on a valid signal: fine to coarse for analysis and the
/// adjoint, coarse to fine for synthesis.
pub(crate) fn multi_level_1d(
    bank: &Bank,
    boundary: Boundary,
    step: Step,
    data: &mut [f64],
    levels: usize,
) {
    let mut scratch = Scratch::default();
    let n = data.len();
    let lengths: Vec<usize> = (0..levels).map(|l| n >> l).collect();
    let mut run = |len: usize| run_step(bank, boundary, step, &mut data[..len], &mut scratch);
    if step == Step::Synthesis {
        lengths.iter().rev().for_each(|&len| run(len));
    } else {
        lengths.iter().for_each(|&len| run(len));
    }
}

/// The level of 1D layout position `i` of an axis of `n` samples with `levels` levels: `l` for
/// the detail band `[n/2^l, n/2^(l−1))`, `levels + 1` for the approximation `[0, n/2^levels)`.
pub(crate) fn axis_level(i: usize, n: usize, levels: usize) -> usize {
    (1..=levels).find(|&l| i >= n >> l).unwrap_or(levels + 1)
}
