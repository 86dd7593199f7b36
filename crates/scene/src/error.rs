//! The one error type of this crate. Every variant that comes from a file names that file.

use std::path::{Path, PathBuf};
use thiserror::Error;

/// Everything that can go wrong while loading or validating a scene.
///
/// Messages start with the file they are about (or `scene` for an in-memory
/// [`crate::Scene`] that fails [`crate::Scene::validate`]) so that a user can act on them.
#[derive(Debug, Error)]
pub enum SceneError {
    /// The file could not be opened or read (missing, a directory, no permission, ...).
    #[error("{}: cannot read the file: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// What the operating system said.
        #[source]
        source: std::io::Error,
    },
    /// The file is not in a format this crate reads, or its contents could not be decoded.
    #[error("{}: {message}", path.display())]
    Format {
        /// The file.
        path: PathBuf,
        /// What is wrong, in words.
        message: String,
    },
    /// An image has a NaN or infinite texel value.
    #[error(
        "{}: texel (col {col}, row {row}) channel {channel} is {value}: environment maps must be finite",
        path.display()
    )]
    NonFiniteTexel {
        /// The file.
        path: PathBuf,
        /// Column of the first bad texel in row-major order (0 = left).
        col: usize,
        /// Row of the first bad texel (0 = top).
        row: usize,
        /// `'R'`, `'G'` or `'B'`.
        channel: char,
        /// The bad value (NaN or ±inf).
        value: f32,
    },
    /// A mesh file is readable but its geometry is unusable (bad indices, NaN positions,
    /// no triangles left, unsupported glTF features, ...).
    #[error("{}: {message}", path.display())]
    Mesh {
        /// The mesh file.
        path: PathBuf,
        /// What is wrong, in words.
        message: String,
    },
    /// A scene file key has an invalid value (or a required key is missing).
    #[error("{}: `{key}`: {message}", path.display())]
    Invalid {
        /// The scene file.
        path: PathBuf,
        /// The TOML key, e.g. `materials.stone.albedo` or `objects[2].mesh`.
        key: String,
        /// What is wrong, in words.
        message: String,
    },
    /// A file referenced by a scene-file key failed to load.
    #[error("{}: `{key}`: {source}", path.display())]
    Referenced {
        /// The scene file.
        path: PathBuf,
        /// The key that names the failing file.
        key: String,
        /// The error of the referenced file (it names that file).
        #[source]
        source: Box<SceneError>,
    },
    /// An in-memory scene failed [`crate::Scene::validate`].
    #[error("scene: {0}")]
    Validation(String),
}

impl SceneError {
    /// A [`SceneError::Format`] for `path`.
    pub(crate) fn format(path: &Path, message: impl Into<String>) -> Self {
        Self::Format {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    /// A [`SceneError::Mesh`] for `path`.
    pub(crate) fn mesh(path: &Path, message: impl Into<String>) -> Self {
        Self::Mesh {
            path: path.to_path_buf(),
            message: message.into(),
        }
    }

    /// A [`SceneError::Io`] for `path`.
    pub(crate) fn io(path: &Path, source: std::io::Error) -> Self {
        Self::Io {
            path: path.to_path_buf(),
            source,
        }
    }

    /// A [`SceneError::Invalid`] for scene file `path` and `key`.
    pub(crate) fn invalid(path: &Path, key: impl Into<String>, message: impl Into<String>) -> Self {
        Self::Invalid {
            path: path.to_path_buf(),
            key: key.into(),
            message: message.into(),
        }
    }
}
