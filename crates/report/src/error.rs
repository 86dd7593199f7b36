//! Errors of the pipeline crate.

use std::path::PathBuf;
use thiserror::Error;

/// Everything that can stop a relight or a report.
#[derive(Debug, Error)]
pub enum ReportError {
    /// `prt bake --target-psnr`: no bake meets the target (the message says how far each
    /// object falls short).
    #[error("{0}")]
    TargetUnmet(String),
    /// Bad options.
    #[error("invalid options: {0}")]
    Invalid(String),
    /// Writing an output failed.
    #[error("{path}: cannot write: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// From scene-level relighting and image formation.
    #[error(transparent)]
    SceneRelight(#[from] prt_scene_relight::SceneRelightError),
    /// From the tracer.
    #[error(transparent)]
    Tracer(#[from] prt_tracer::TracerError),
    /// From reflectance fields.
    #[error(transparent)]
    Field(#[from] prt_fields::FieldError),
    /// From the baker.
    #[error(transparent)]
    Bake(#[from] prt_bake::BakeError),
    /// From the bake file format.
    #[error(transparent)]
    BakeFile(#[from] prt_bakefile::BakeFileError),
    /// From the comparison crate.
    #[error(transparent)]
    Compare(#[from] prt_compare::CompareError),
}
