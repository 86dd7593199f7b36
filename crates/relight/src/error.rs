//! The error type of the crate.

use prt_sh::ShError;
use thiserror::Error;

/// Everything that can go wrong when relighting: malformed inputs are reported, never panicked on.
#[derive(Debug, Error, Clone, PartialEq)]
pub enum RelightError {
    /// An error of the SH core (order out of range, bad rotation, ...).
    #[error(transparent)]
    Sh(#[from] ShError),
    /// A transfer array whose length is not a whole number of points.
    #[error("transfer of order {order} with {channels} channel(s) needs a multiple of {per_point} floats, got {len}")]
    TransferLength {
        /// Order of the transfer.
        order: usize,
        /// Channels per point.
        channels: usize,
        /// Floats per point (`channels · order²`).
        per_point: usize,
        /// Length of the array given.
        len: usize,
    },
    /// A channel count other than 1 or 3 (or other than 1 where a visibility is expected).
    #[error("{what} has {channels} channel(s); {allowed} supported")]
    Channels {
        /// What the array is.
        what: &'static str,
        /// Channels given.
        channels: usize,
        /// What is allowed.
        allowed: &'static str,
    },
    /// Two inputs whose SH orders do not fit together.
    #[error("{what} has order {got}, but order {expected} is required")]
    OrderMismatch {
        /// What the input is.
        what: &'static str,
        /// Order required.
        expected: usize,
        /// Order given.
        got: usize,
    },
    /// A coefficient list whose length is not a perfect square `n²` (n ≥ 1).
    #[error("{0} coefficients is not a perfect square n² with n ≥ 1")]
    NotSquare(usize),
    /// Per-point arrays of different lengths.
    #[error("{what} has {got} entries for {expected} points")]
    PointCount {
        /// What the array is.
        what: &'static str,
        /// Points expected.
        expected: usize,
        /// Entries given.
        got: usize,
    },
    /// A NaN or infinite parameter or coefficient.
    #[error("non-finite value in {0}")]
    NonFinite(&'static str),
    /// A parameter out of its range.
    #[error("invalid parameter: {0}")]
    InvalidParameter(String),
    /// A triangle that refers to a vertex beyond the vertex count.
    #[error(
        "triangle {triangle} refers to vertex {vertex}, but there are {vertex_count} vertices"
    )]
    VertexIndex {
        /// Triangle index.
        triangle: usize,
        /// Vertex index it holds.
        vertex: u32,
        /// Number of vertices.
        vertex_count: usize,
    },
    /// Specular shading asked of a [`crate::FrameLighting`] prepared without product matrices.
    #[error("frame lighting was prepared without the specular product matrices (use FrameLighting::new with specular = true)")]
    MissingProducts,
}
