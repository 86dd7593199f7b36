//! The crate's error type.

use thiserror::Error;

/// Everything that can go wrong in this crate: all of it is bad input, reported instead of a
/// panic.
#[derive(Debug, Clone, PartialEq, Error)]
#[non_exhaustive]
pub enum WaveletError {
    /// A grid or signal without samples.
    #[error("empty grid: {width}×{height} samples")]
    EmptyGrid {
        /// Width (x, azimuth) in samples.
        width: usize,
        /// Height (y, polar angle) in samples.
        height: usize,
    },
    /// `width × height` does not fit in memory indices.
    #[error("grid of {width}×{height} samples is too large")]
    TooLarge {
        /// Width in samples.
        width: usize,
        /// Height in samples.
        height: usize,
    },
    /// A 2D grid that cannot be decomposed to the asked number of levels (every level halves
    /// both sizes, which must be even at every level used).
    #[error(
        "a {width}×{height} grid cannot be decomposed to {levels} levels: both sizes must be \
         divisible by 2^{levels}; this grid allows at most {max}"
    )]
    TooManyLevels {
        /// Width in samples.
        width: usize,
        /// Height in samples.
        height: usize,
        /// Levels asked for.
        levels: usize,
        /// Most levels the sizes allow.
        max: usize,
    },
    /// A 1D signal that cannot be decomposed to the asked number of levels.
    #[error(
        "a signal of {len} samples cannot be decomposed to {levels} levels: its length must be \
         divisible by 2^{levels}; it allows at most {max}"
    )]
    TooManySignalLevels {
        /// Signal length.
        len: usize,
        /// Levels asked for.
        levels: usize,
        /// Most levels the length allows.
        max: usize,
    },
    /// An array of the wrong length.
    #[error("expected {expected} values, got {actual}")]
    LengthMismatch {
        /// Length the transform or grid needs.
        expected: usize,
        /// Length given.
        actual: usize,
    },
    /// A NaN or infinite input value.
    #[error("value at index {index} is not finite ({value})")]
    NonFinite {
        /// Index of the first offending value.
        index: usize,
        /// The value.
        value: f64,
    },
    /// A sparse coefficient whose index lies outside the coefficient array.
    #[error("coefficient index {index} is outside the {len} coefficients of the transform")]
    IndexOutOfRange {
        /// The index.
        index: usize,
        /// Number of coefficients.
        len: usize,
    },
    /// A relative-error target that is negative, NaN or infinite.
    #[error("relative error target {0} must be finite and non-negative")]
    InvalidErrorTarget(f64),
    /// A row weight that is negative, NaN or infinite.
    #[error("row weight {row} is {value}: weights must be finite and non-negative")]
    InvalidWeight {
        /// Row of the weight.
        row: usize,
        /// The weight.
        value: f64,
    },
    /// A relative error against a reference of zero norm (and a non-zero difference).
    #[error("the reference has zero norm, so the relative error is undefined")]
    ZeroReference,
    /// Interpolation sizes that are not the coarse sizes times powers of two.
    #[error(
        "cannot interpolate {coarse_width}×{coarse_height} to {width}×{height}: each fine size \
         must be the coarse size times a power of two (1, 2, 4, …)"
    )]
    InterpolationSize {
        /// Coarse width.
        coarse_width: usize,
        /// Coarse height.
        coarse_height: usize,
        /// Fine width asked for.
        width: usize,
        /// Fine height asked for.
        height: usize,
    },
    /// A band that the transform does not have (level 0 or above its levels, or an
    /// approximation band other than the last level's).
    #[error("the transform has no {kind} band at level {level} (it has {levels} levels)")]
    NoSuchBand {
        /// The band kind, as text.
        kind: String,
        /// The level asked for.
        level: usize,
        /// The transform's levels.
        levels: usize,
    },
    /// A wavelet name that [`crate::Wavelet::from_str`](std::str::FromStr) does not know.
    #[error(
        "unknown wavelet {0:?}: expected haar, legall53 (5/3, bior2.2) or cdf97 (9/7, bior4.4)"
    )]
    UnknownWavelet(String),
}

/// `Result` with [`WaveletError`].
pub type Result<T, E = WaveletError> = std::result::Result<T, E>;

/// The first non-finite value of `values`, as an error.
pub(crate) fn check_finite(values: &[f64]) -> Result<()> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(WaveletError::NonFinite {
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

/// `actual == expected`, or a [`WaveletError::LengthMismatch`].
pub(crate) fn check_len(actual: usize, expected: usize) -> Result<()> {
    if actual == expected {
        Ok(())
    } else {
        Err(WaveletError::LengthMismatch { expected, actual })
    }
}
