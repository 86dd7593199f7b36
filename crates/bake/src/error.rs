//! Errors of the baker.

use thiserror::Error;

/// Everything that can stop a bake.
#[derive(Debug, Error)]
pub enum BakeError {
    /// An option out of range or inconsistent with the scene.
    #[error("invalid bake settings: {0}")]
    InvalidSettings(String),
    /// The bake would need more memory than allowed (estimate given).
    #[error("the bake would need about {estimate_mib} MiB (limit {limit_mib} MiB): {what}")]
    TooLarge {
        /// Estimated memory in MiB.
        estimate_mib: u64,
        /// The limit in MiB.
        limit_mib: u64,
        /// What dominates the estimate.
        what: String,
    },
    /// A pass of a distributed bounced bake that cannot run (wrong pass, or a previous pass's
    /// file that does not belong to this bake).
    #[error("distributed bake: {0}")]
    Pass(String),
    /// The scene has no geometry to bake.
    #[error("the scene has no triangles to bake")]
    EmptyScene,

    /// An object's lightmap UVs cannot be baked per texel.
    #[error("object {object}: {reason}")]
    Lightmap {
        /// The object (mesh name).
        object: String,
        /// What is wrong, and how much.
        reason: String,
    },
    /// From the SH core.
    #[error(transparent)]
    Sh(#[from] prt_sh::ShError),
    /// From the ray tracer.
    #[error(transparent)]
    Tracer(#[from] prt_tracer::TracerError),
    /// From the bake file format.
    #[error(transparent)]
    File(#[from] prt_bakefile::BakeFileError),
}
