//! The error type of the crate.

use std::path::PathBuf;

/// Everything that can go wrong when reading, checking or writing an image. Every message
/// names the file (or the role of an in-memory image: `"test image"`, `"reference"`).
#[derive(Debug, thiserror::Error)]
pub enum ImageError {
    /// The file does not exist.
    #[error("{}: no such file", path.display())]
    NotFound {
        /// The path that was asked for.
        path: PathBuf,
    },
    /// The file exists but could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// The file.
        path: PathBuf,
        /// The underlying error.
        #[source]
        source: std::io::Error,
    },
    /// The file is neither an OpenEXR nor a PNG file, or it is damaged.
    #[error("{}: not an image this tool reads: {reason}", path.display())]
    NotAnImage {
        /// The file.
        path: PathBuf,
        /// What was found instead.
        reason: String,
    },
    /// The image has channels that cannot be read as RGB (for example an EXR without R, G, B).
    #[error("{}: {reason}", path.display())]
    UnsupportedChannels {
        /// The file.
        path: PathBuf,
        /// Which channels were found and why they cannot be used.
        reason: String,
    },
    /// A pixel value is NaN or infinite.
    #[error(
        "{what}: pixel (x = {x}, y = {y}) channel {channel} is {value}; every value must be finite"
    )]
    NonFinite {
        /// The file or the role of the image.
        what: String,
        /// Column, from the left, starting at 0.
        x: usize,
        /// Row, from the top, starting at 0.
        y: usize,
        /// `'R'`, `'G'` or `'B'`.
        channel: char,
        /// The offending value.
        value: f32,
    },
    /// The pixel buffer does not have `width × height` entries.
    #[error("{what}: {len} pixels given for a {width}×{height} image")]
    PixelCount {
        /// The role of the image.
        what: String,
        /// Number of pixels given.
        len: usize,
        /// Declared width.
        width: usize,
        /// Declared height.
        height: usize,
    },
    /// An image with no pixels at all.
    #[error("{what}: the image has no pixels (0×0)")]
    EmptyImage {
        /// The file or the role of the image.
        what: String,
    },
    /// A file could not be written (nothing is left at the path but what was there before).
    #[error("cannot write {}: {reason}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// Shorthand for results of this crate.
pub type Result<T, E = ImageError> = std::result::Result<T, E>;
