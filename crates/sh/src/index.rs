//! Flat indexing `i = l(l+1) + m` and order bookkeeping ("order n" = n bands).

use thiserror::Error;

/// Largest order (band count) this crate evaluates. Recurrences stay finite and accurate far
/// beyond it; the bound only keeps buffers (order² values) and Gaunt tensors sane.
pub const MAX_ORDER: usize = 256;

/// Errors of the SH crate.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum ShError {
    /// Order 0 or beyond [`MAX_ORDER`].
    #[error("SH order {order} is out of range: it must be between 1 and {max} (order = number of bands)")]
    OrderOutOfRange {
        /// The order asked for.
        order: usize,
        /// The largest supported order for this operation.
        max: usize,
    },
    /// A buffer of the wrong length was passed.
    #[error("buffer holds {got} values but order {order} needs {expected}")]
    BufferLength {
        /// Order of the operation.
        order: usize,
        /// Required length.
        expected: usize,
        /// Length given.
        got: usize,
    },
    /// An image whose size does not match its texel count, or is empty.
    #[error("image of {width}×{height} texels has {texels} values")]
    ImageSize {
        /// Width in texels.
        width: usize,
        /// Height in texels.
        height: usize,
        /// Number of texels given.
        texels: usize,
    },
    /// A texel or coefficient that is NaN or infinite.
    #[error("non-finite value at texel (col {col}, row {row}), channel {channel}")]
    NonFinite {
        /// Column.
        col: usize,
        /// Row.
        row: usize,
        /// Channel.
        channel: usize,
    },
    /// A rotation matrix that is not orthonormal with determinant +1.
    #[error("matrix is not a proper rotation (orthonormality error {error:e})")]
    NotARotation {
        /// Largest deviation of RᵀR from the identity, or of det R from 1.
        error: f64,
    },
    /// An invalid parameter (negative exponent, zero width, ...).
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
}

/// Number of coefficients of an order-`order` expansion: `order²`.
#[inline]
#[must_use]
pub const fn coefficient_count(order: usize) -> usize {
    order * order
}

/// Flat index of `(l, m)`: `l(l+1) + m`.
#[inline]
#[must_use]
pub const fn index(l: usize, m: i64) -> usize {
    ((l * (l + 1)) as i64 + m) as usize
}

/// Inverse of [`index`]: the `(l, m)` of a flat index.
#[inline]
#[must_use]
pub fn degree_and_order(i: usize) -> (usize, i64) {
    let l = (i as f64).sqrt() as usize;
    // Guard against rounding of the square root.
    let l = if (l + 1) * (l + 1) <= i {
        l + 1
    } else if l * l > i {
        l - 1
    } else {
        l
    };
    (l, i as i64 - (l * (l + 1)) as i64)
}

/// Checks `1 ≤ order ≤ max`.
pub fn check_order(order: usize, max: usize) -> Result<(), ShError> {
    if order == 0 || order > max {
        Err(ShError::OrderOutOfRange { order, max })
    } else {
        Ok(())
    }
}

/// Checks that a buffer holds `order²` values.
pub fn check_len(order: usize, got: usize) -> Result<(), ShError> {
    let expected = coefficient_count(order);
    if got != expected {
        Err(ShError::BufferLength {
            order,
            expected,
            got,
        })
    } else {
        Ok(())
    }
}
