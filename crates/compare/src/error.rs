//! The error type of the crate.

/// Everything that can go wrong when reading, checking or comparing images.
///
/// Every message names the file (or the role of the in-memory image: `"test image"`,
/// `"reference"`, `"mask"`) so that a user comparing many images knows which one is at fault.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// Reading or checking an image (prt-image).
    #[error(transparent)]
    Image(#[from] prt_image::ImageError),
    /// Two images (or an image and a mask) that must be the same size are not.
    #[error("size mismatch: {first} is {first_width}×{first_height} but {second} is {second_width}×{second_height}; both must have the same size")]
    SizeMismatch {
        /// Name of the first image.
        first: String,
        /// Its width in pixels.
        first_width: usize,
        /// Its height in pixels.
        first_height: usize,
        /// Name of the second image.
        second: String,
        /// Its width in pixels.
        second_width: usize,
        /// Its height in pixels.
        second_height: usize,
    },
    /// One image is grayscale and the other RGB.
    #[error("channel mismatch: {first} has {first_channels} but {second} has {second_channels}; a grayscale image cannot be compared with an RGB one (its single channel would be compared with each of R, G and B as if the image were gray); convert one of them so both are RGB or both grayscale")]
    ChannelMismatch {
        /// Name of the first image.
        first: String,
        /// Its channels, described ("1 channel (grayscale)").
        first_channels: String,
        /// Name of the second image.
        second: String,
        /// Its channels, described.
        second_channels: String,
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
    /// A mask with no pixel inside: the masked metrics would be undefined.
    #[error("{what}: the mask selects no pixel (every value is zero); masked metrics need at least one pixel")]
    EmptyMask {
        /// The file or the role of the mask.
        what: String,
    },
    /// An option is out of its range.
    #[error("invalid option: {0}")]
    InvalidOption(String),
}

/// Shorthand for results of this crate.
pub type Result<T, E = CompareError> = std::result::Result<T, E>;
