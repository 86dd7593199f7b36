//! The error type of this crate.

use std::path::PathBuf;

/// Everything that can go wrong in the tracer.
#[derive(Debug, thiserror::Error)]
pub enum TracerError {
    /// A mesh cannot be traced.
    #[error("mesh {mesh}: {reason}")]
    InvalidMesh {
        /// Index of the mesh in the scene.
        mesh: usize,
        /// What is wrong.
        reason: String,
    },
    /// The acceleration structure is inconsistent (from [`crate::Accel::validate`]).
    #[error("acceleration structure: {0}")]
    InvalidAccel(String),
    /// A render setting or input is out of range.
    #[error("invalid setting: {0}")]
    InvalidSettings(String),
    /// A mesh refers to a material the scene does not have.
    #[error("mesh {mesh} uses material {material}, but the scene has {count}")]
    MissingMaterial {
        /// Mesh index.
        mesh: usize,
        /// Material index it names.
        material: usize,
        /// Number of materials.
        count: usize,
    },
    /// Writing an output file failed.
    #[error("cannot write {path}: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}
