//! Reading environment images: OpenEXR (any compression the `exr` crate decodes, DWAA/DWAB
//! included; half or float RGB channels of the first layer that has them, alpha ignored) and
//! Radiance `.hdr` (RGBE, through the `image` crate).
//!
//! The format is chosen from the file's first bytes (EXR magic `76 2f 31 01`, Radiance `#?`),
//! not its extension. Policy for texel values:
//! - NaN or ±inf anywhere is an error naming the file, the first bad texel in row-major order
//!   and its channel: a map with such a texel would poison every integral over the sphere.
//! - Negative values (lossy EXR compression such as DWAB leaves small ones) are clamped to 0,
//!   and one warning counts them.
//! - An EXR `chromaticities` attribute other than Rec.709/sRGB primaries with a D65 white gives
//!   a warning: the texels are used as they are (as if Rec.709), not converted.

use crate::{EnvImage, Environment, Mapping, Rgb, SceneError};
use std::io::Read;
use std::path::Path;

/// An image read from a file, with the warnings that reading it produced.
#[derive(Clone, Debug)]
pub struct LoadedImage {
    /// The texels, finite and non-negative.
    pub image: EnvImage,
    /// Things a user should know (clamped negatives, unexpected chromaticities, ...). Each
    /// message names the file.
    pub warnings: Vec<String>,
}

/// Rec.709 primaries and D65 white point (CIE xy), what every texel is taken to be in.
pub const REC709_CHROMATICITIES: [[f32; 2]; 4] =
    [[0.64, 0.33], [0.30, 0.60], [0.15, 0.06], [0.3127, 0.3290]];

/// Tolerance on each CIE xy coordinate when comparing chromaticities with Rec.709: files write
/// the primaries with 3 to 4 decimals, so 1e-3 accepts every spelling of Rec.709 and rejects
/// any other standard set (the nearest, P3-D65 and Adobe RGB, differ by more than 0.05).
const CHROMATICITY_TOLERANCE: f32 = 1e-3;

/// Reads an environment image from an OpenEXR or Radiance `.hdr` file.
///
/// # Errors
/// [`SceneError::Io`] when the file cannot be read, [`SceneError::Format`] when it is empty,
/// not an EXR/HDR image, truncated or corrupt, has no R, G, B channels, or has zero texels,
/// and [`SceneError::NonFiniteTexel`] for a NaN or infinite texel.
pub fn load_env_image(path: &Path) -> Result<LoadedImage, SceneError> {
    let mut magic = [0u8; 4];
    let read = {
        let mut file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
        read_up_to(&mut file, &mut magic).map_err(|e| SceneError::io(path, e))?
    };
    if read == 0 {
        return Err(SceneError::format(
            path,
            "the file is empty (0 bytes), not an image",
        ));
    }
    let mut warnings = Vec::new();
    let (width, height, texels) = if read == 4 && magic == [0x76, 0x2f, 0x31, 0x01] {
        read_exr(path, &mut warnings)?
    } else if magic.starts_with(b"#?") {
        read_hdr(path)?
    } else {
        return Err(SceneError::format(
            path,
            "not an OpenEXR or Radiance HDR image (unrecognised first bytes)",
        ));
    };
    if width == 0 || height == 0 || texels.len() != width * height {
        return Err(SceneError::format(
            path,
            format!("the image has no texels ({width}×{height})"),
        ));
    }
    let mut image = EnvImage {
        width,
        height,
        texels,
    };
    check_and_clamp(path, &mut image, &mut warnings)?;
    Ok(LoadedImage { image, warnings })
}

/// Reads an environment map and wraps it as an [`Environment`]: texels multiplied by `scale`.
///
/// For [`Mapping::Angular`] only texels whose centre lies inside the inscribed disc are part of
/// the map (see CONVENTIONS.md); the others are kept in the image but no direction maps to them,
/// so they are ignored by lookup, sampling and projection. A non-square angular image gives a
/// warning (its disc is then an ellipse in texel units).
///
/// # Errors
/// Those of [`load_env_image`], and [`SceneError::Format`] when `scale` is negative or not
/// finite or `rotation_y_deg` is not finite.
pub fn load_environment(
    path: &Path,
    mapping: Mapping,
    rotation_y_deg: f64,
    scale: f32,
) -> Result<(Environment, Vec<String>), SceneError> {
    if !(scale.is_finite() && scale >= 0.0) {
        return Err(SceneError::format(
            path,
            format!("radiance scale {scale} must be finite and ≥ 0"),
        ));
    }
    if !rotation_y_deg.is_finite() {
        return Err(SceneError::format(
            path,
            format!("rotation {rotation_y_deg}° is not finite"),
        ));
    }
    let LoadedImage {
        mut image,
        mut warnings,
    } = load_env_image(path)?;
    if mapping == Mapping::Angular && image.width != image.height {
        warnings.push(format!(
            "{}: angular map is {}×{}, not square: its disc is stretched to the image's aspect",
            path.display(),
            image.width,
            image.height
        ));
    }
    if scale != 1.0 {
        for t in &mut image.texels {
            for c in t.iter_mut() {
                *c *= scale;
            }
        }
        if let Some(col) = image.texels.iter().flatten().position(|c| !c.is_finite()) {
            let (texel, channel) = (col / 3, col % 3);
            return Err(SceneError::format(
                path,
                format!(
                    "scale {scale} makes texel (col {}, row {}) channel {} overflow to infinity",
                    texel % image.width,
                    texel / image.width,
                    ['R', 'G', 'B'][channel]
                ),
            ));
        }
    }
    Ok((
        Environment {
            image,
            mapping,
            rotation_y_deg,
        },
        warnings,
    ))
}

/// Reads as many bytes as fit in `buf` (fewer only at end of file).
fn read_up_to(file: &mut std::fs::File, buf: &mut [u8]) -> std::io::Result<usize> {
    let mut n = 0;
    while n < buf.len() {
        match file.read(&mut buf[n..])? {
            0 => break,
            k => n += k,
        }
    }
    Ok(n)
}

type Texels = (usize, usize, Vec<Rgb>);

/// Largest Radiance HDR image read: 2²⁸ texels (16384 × 16384, 3 GiB as RGB f32).
const MAX_TEXELS: u64 = 1 << 28;

fn read_exr(path: &Path, warnings: &mut Vec<String>) -> Result<Texels, SceneError> {
    use exr::prelude::*;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            |resolution, _channels: &RgbaChannels| {
                (
                    resolution.width(),
                    vec![[0.0f32; 3]; resolution.width() * resolution.height()],
                )
            },
            |(width, texels): &mut (usize, Vec<Rgb>), pos, (r, g, b, _a): (f32, f32, f32, f32)| {
                texels[pos.y() * *width + pos.x()] = [r, g, b];
            },
        )
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| match e {
            exr::error::Error::Io(io) if io.kind() != std::io::ErrorKind::UnexpectedEof => {
                SceneError::io(path, io)
            }
            exr::error::Error::Io(_) => {
                SceneError::format(path, "OpenEXR file is truncated (unexpected end of file)")
            }
            other => SceneError::format(path, format!("cannot decode OpenEXR: {other}")),
        })?;
    if let Some(c) = image.attributes.chromaticities {
        let found = [
            [c.red.x(), c.red.y()],
            [c.green.x(), c.green.y()],
            [c.blue.x(), c.blue.y()],
            [c.white.x(), c.white.y()],
        ];
        let same = found
            .iter()
            .zip(REC709_CHROMATICITIES.iter())
            .all(|(f, r)| {
                (f[0] - r[0]).abs() <= CHROMATICITY_TOLERANCE
                    && (f[1] - r[1]).abs() <= CHROMATICITY_TOLERANCE
            });
        if !same {
            warnings.push(format!(
                "{}: the EXR declares chromaticities R{:?} G{:?} B{:?} white{:?}, not Rec.709 \
                 (R[0.64, 0.33] G[0.3, 0.6] B[0.15, 0.06] white[0.3127, 0.329]); texels are used \
                 as Rec.709 without conversion",
                path.display(),
                found[0],
                found[1],
                found[2],
                found[3]
            ));
        }
    }
    let size = image.layer_data.size;
    let (_, texels) = image.layer_data.channel_data.pixels;
    Ok((size.width(), size.height(), texels))
}

fn read_hdr(path: &Path) -> Result<Texels, SceneError> {
    let file = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let decoder = image::codecs::hdr::HdrDecoder::new(std::io::BufReader::new(file))
        .map_err(|e| SceneError::format(path, format!("cannot decode Radiance HDR: {e}")))?;
    // The decoder allocates the whole image from the header's size before reading a texel: a
    // hostile or corrupt header (say 10⁶ × 10⁶) would abort the process.
    let (w, h) = image::ImageDecoder::dimensions(&decoder);
    if u64::from(w) * u64::from(h) > MAX_TEXELS {
        return Err(SceneError::format(
            path,
            format!("the header declares {w}×{h} texels, more than the {MAX_TEXELS} this reader accepts"),
        ));
    }
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(|e| SceneError::format(path, format!("cannot decode Radiance HDR: {e}")))?
        .into_rgb32f();
    let (w, h) = (img.width() as usize, img.height() as usize);
    let texels = img.pixels().map(|p| p.0).collect();
    Ok((w, h, texels))
}

/// Errors on the first non-finite texel; clamps negatives to 0 and counts them in one warning.
fn check_and_clamp(
    path: &Path,
    image: &mut EnvImage,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let mut negative_values = 0usize;
    let mut negative_texels = 0usize;
    let mut most_negative = 0.0f32;
    for (i, t) in image.texels.iter_mut().enumerate() {
        let mut any = false;
        for (ch, v) in t.iter_mut().enumerate() {
            if !v.is_finite() {
                return Err(SceneError::NonFiniteTexel {
                    path: path.to_path_buf(),
                    col: i % image.width,
                    row: i / image.width,
                    channel: ['R', 'G', 'B'][ch],
                    value: *v,
                });
            }
            if *v < 0.0 {
                most_negative = most_negative.min(*v);
                negative_values += 1;
                any = true;
                *v = 0.0;
            } else if *v == 0.0 {
                *v = 0.0; // -0.0 becomes +0.0
            }
        }
        negative_texels += usize::from(any);
    }
    if negative_values > 0 {
        warnings.push(format!(
            "{}: clamped {negative_values} negative values in {negative_texels} of {} texels to 0 \
             (most negative {most_negative}; lossy EXR compression leaves such values)",
            path.display(),
            image.texels.len()
        ));
    }
    Ok(())
}
