//! Reading pairs of images to compare: the reading itself is prt-image's
//! ([`read_image`](prt_image::read_image): OpenEXR and PNG as linear RGB).

use crate::error::{CompareError, Result};
use prt_image::{read_image, LoadedImage};
use std::path::Path;

/// Reads a test image and its reference and checks that they can be compared: same size and
/// both colour or both grayscale.
pub fn read_pair(
    test: impl AsRef<Path>,
    reference: impl AsRef<Path>,
) -> Result<(LoadedImage, LoadedImage)> {
    let a = read_image(test)?;
    let b = read_image(reference)?;
    check_same_kind(&a, &b)?;
    Ok((a, b))
}

/// Fails unless two loaded images have the same size and the same [`ColorChannels`](prt_image::read::ColorChannels).
pub fn check_same_kind(a: &LoadedImage, b: &LoadedImage) -> Result<()> {
    if (a.image.width, a.image.height) != (b.image.width, b.image.height) {
        return Err(CompareError::SizeMismatch {
            first: a.path.display().to_string(),
            first_width: a.image.width,
            first_height: a.image.height,
            second: b.path.display().to_string(),
            second_width: b.image.width,
            second_height: b.image.height,
        });
    }
    if a.channels != b.channels {
        return Err(CompareError::ChannelMismatch {
            first: a.path.display().to_string(),
            first_channels: a.channels.describe().into(),
            second: b.path.display().to_string(),
            second_channels: b.channels.describe().into(),
        });
    }
    Ok(())
}
