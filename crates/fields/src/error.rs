//! Errors of reflectance fields.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can stop sampling, reconstructing or relighting a reflectance field.
#[derive(Debug, Error)]
pub enum FieldError {
    /// Sampling settings out of range (the same words as the baker's).
    #[error("invalid bake settings: {0}")]
    InvalidSettings(String),
    /// Bad relighting or reconstruction options.
    #[error("invalid options: {0}")]
    Invalid(String),
    /// A field file that does not belong to the scene, or lacks what is asked of it.
    #[error("{path}: {reason}")]
    BakeMismatch {
        /// The field file (or `<memory>`).
        path: PathBuf,
        /// What does not match.
        reason: String,
    },
    /// From the tracer.
    #[error(transparent)]
    Tracer(#[from] prt_tracer::TracerError),
    /// From the bake file format.
    #[error(transparent)]
    File(#[from] prt_bakefile::BakeFileError),
}
