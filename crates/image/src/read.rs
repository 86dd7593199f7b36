//! Reading OpenEXR and PNG files into linear RGB [`Image`]s.
//!
//! - **OpenEXR**: linear RGB. The first layer (part) that has channels named `R`, `G` and `B`
//!   (also with a layer prefix such as `diffuse.R`, all three with the same prefix) is read;
//!   f16, f32 and u32 samples become f32. An `A` channel is ignored and reported in
//!   [`LoadedImage::alpha_ignored`]. A layer with only a `Y` channel is read as grayscale.
//! - **PNG**: 8- or 16-bit, sRGB-encoded; each value `v/255` (or `v/65535`) is decoded with
//!   the exact sRGB EOTF ([`crate::srgb_eotf`]). Gray and gray+alpha PNGs are read
//!   as grayscale (the value copied to R, G, B); alpha is ignored and reported.
//!
//! The format is recognised by the file's first bytes, not by its name.

use crate::error::{ImageError, Result};
use crate::image::Image;
use crate::srgb::srgb_eotf;
use std::path::{Path, PathBuf};

/// The file format an image was read from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ImageFormat {
    /// OpenEXR (linear).
    Exr,
    /// PNG (sRGB-encoded, 8 or 16 bits per channel).
    Png,
}

/// Whether the file held colour or a single gray channel.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ColorChannels {
    /// One channel (PNG gray, EXR `Y`), copied to R, G and B.
    Gray,
    /// Red, green and blue.
    Rgb,
}

impl ColorChannels {
    /// A description for messages, e.g. `"1 channel (grayscale)"`.
    #[must_use]
    pub fn describe(self) -> &'static str {
        match self {
            ColorChannels::Gray => "1 colour channel (grayscale)",
            ColorChannels::Rgb => "3 colour channels (RGB)",
        }
    }
}

/// An image read from a file, with what was learnt about the file.
#[derive(Debug, Clone)]
pub struct LoadedImage {
    /// The file it was read from.
    pub path: PathBuf,
    /// The pixels, linear RGB.
    pub image: Image,
    /// The file format.
    pub format: ImageFormat,
    /// Colour or grayscale in the file.
    pub channels: ColorChannels,
    /// True when the file had an alpha channel, which was ignored.
    pub alpha_ignored: bool,
    /// Bits per channel in the file (8 or 16 for PNG; 16 or 32 for EXR).
    pub bit_depth: u8,
}

const EXR_MAGIC: [u8; 4] = [0x76, 0x2f, 0x31, 0x01];
const PNG_MAGIC: [u8; 8] = [0x89, b'P', b'N', b'G', 0x0d, 0x0a, 0x1a, 0x0a];

fn open_bytes(path: &Path) -> Result<Vec<u8>> {
    std::fs::read(path).map_err(|source| {
        if source.kind() == std::io::ErrorKind::NotFound {
            ImageError::NotFound {
                path: path.to_path_buf(),
            }
        } else {
            ImageError::Io {
                path: path.to_path_buf(),
                source,
            }
        }
    })
}

/// Reads an OpenEXR or PNG file as linear RGB; fails with a message naming the file when it
/// is missing, not an image, has no usable colour channels, or has a NaN or infinite value.
///
/// # Errors
/// As said: [`ImageError`] names the file and the problem.
pub fn read_image(path: impl AsRef<Path>) -> Result<LoadedImage> {
    let path = path.as_ref();
    let bytes = open_bytes(path)?;
    let loaded = if bytes.starts_with(&EXR_MAGIC) {
        read_exr_bytes(path, &bytes)?
    } else if bytes.starts_with(&PNG_MAGIC) {
        read_png_bytes(path, &bytes)?
    } else {
        let reason = if bytes.is_empty() {
            "the file is empty".to_string()
        } else {
            "it starts neither like an OpenEXR file nor like a PNG file (only .exr and .png are read)"
                .to_string()
        };
        return Err(ImageError::NotAnImage {
            path: path.to_path_buf(),
            reason,
        });
    };
    loaded.image.validate(&path.display().to_string())?;
    Ok(loaded)
}

fn not_an_image(path: &Path, reason: impl std::fmt::Display) -> ImageError {
    ImageError::NotAnImage {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// An OpenEXR file's layers with all their channels (flat, largest resolution level).
type ExrLayers =
    exr::prelude::Image<exr::prelude::Layers<exr::prelude::AnyChannels<exr::prelude::FlatSamples>>>;

fn parse_exr(path: &Path, bytes: &[u8]) -> Result<ExrLayers> {
    use exr::prelude::{read, ReadChannels, ReadLayers};
    read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_buffered(std::io::Cursor::new(bytes))
        .map_err(|e| not_an_image(path, format!("damaged or unsupported OpenEXR file: {e}")))
}

fn read_exr_bytes(path: &Path, bytes: &[u8]) -> Result<LoadedImage> {
    use exr::prelude::{FlatSamples, Vec2};
    let image = parse_exr(path, bytes)?;

    let mut seen = Vec::new();
    for layer in &image.layer_data {
        let channels = &layer.channel_data.list;
        let names: Vec<String> = channels.iter().map(|c| c.name.to_string()).collect();
        seen.extend(names.iter().cloned());
        let find = |wanted: &str| names.iter().position(|n| n == wanted);
        // Candidate prefixes: "" and every "prefix." of a channel ending in ".R".
        let mut prefixes = vec![String::new()];
        for n in &names {
            if let Some(p) = n.strip_suffix(".R") {
                prefixes.push(format!("{p}."));
            }
        }
        let (width, height) = (layer.size.width(), layer.size.height());
        let to_f32 = |i: usize| -> Result<Vec<f32>> {
            let ch = &channels[i];
            if ch.sampling != Vec2(1, 1) {
                return Err(ImageError::UnsupportedChannels {
                    path: path.to_path_buf(),
                    reason: format!(
                        "channel {} is subsampled ({}×{}); only full-resolution channels are read",
                        ch.name, ch.sampling.0, ch.sampling.1
                    ),
                });
            }
            Ok(ch.sample_data.values_as_f32().collect())
        };
        for prefix in &prefixes {
            let (Some(r), Some(g), Some(b)) = (
                find(&format!("{prefix}R")),
                find(&format!("{prefix}G")),
                find(&format!("{prefix}B")),
            ) else {
                continue;
            };
            let (rv, gv, bv) = (to_f32(r)?, to_f32(g)?, to_f32(b)?);
            let pixels = (0..width * height).map(|i| [rv[i], gv[i], bv[i]]).collect();
            let alpha_ignored = find(&format!("{prefix}A")).is_some();
            let bit_depth = match channels[r].sample_data {
                FlatSamples::F16(_) => 16,
                _ => 32,
            };
            return Ok(LoadedImage {
                path: path.to_path_buf(),
                image: Image::new(width, height, pixels)?,
                format: ImageFormat::Exr,
                channels: ColorChannels::Rgb,
                alpha_ignored,
                bit_depth,
            });
        }
        if let Some(y) = find("Y") {
            let yv = to_f32(y)?;
            let pixels = yv.iter().map(|&v| [v, v, v]).collect();
            return Ok(LoadedImage {
                path: path.to_path_buf(),
                image: Image::new(width, height, pixels)?,
                format: ImageFormat::Exr,
                channels: ColorChannels::Gray,
                alpha_ignored: find("A").is_some(),
                bit_depth: match channels[y].sample_data {
                    FlatSamples::F16(_) => 16,
                    _ => 32,
                },
            });
        }
    }
    Err(ImageError::UnsupportedChannels {
        path: path.to_path_buf(),
        reason: format!(
            "no layer has R, G and B channels (nor a Y channel); channels found: [{}]",
            seen.join(", ")
        ),
    })
}

fn read_png_bytes(path: &Path, bytes: &[u8]) -> Result<LoadedImage> {
    use image::DynamicImage as D;
    let decoded = image::load_from_memory_with_format(bytes, image::ImageFormat::Png)
        .map_err(|e| not_an_image(path, format!("damaged or unsupported PNG file: {e}")))?;
    let (width, height) = (decoded.width() as usize, decoded.height() as usize);
    // Lookup tables for the exact EOTF of every 8-bit code; 16-bit codes are decoded directly.
    let lut8: Vec<f32> = (0..=255u32)
        .map(|v| srgb_eotf(f64::from(v) / 255.0) as f32)
        .collect();
    let dec16 = |v: u16| srgb_eotf(f64::from(v) / 65535.0) as f32;
    let (pixels, channels, alpha_ignored, bit_depth): (Vec<[f32; 3]>, _, _, _) = match &decoded {
        D::ImageLuma8(im) => (
            im.pixels().map(|p| [lut8[p.0[0] as usize]; 3]).collect(),
            ColorChannels::Gray,
            false,
            8,
        ),
        D::ImageLumaA8(im) => (
            im.pixels().map(|p| [lut8[p.0[0] as usize]; 3]).collect(),
            ColorChannels::Gray,
            true,
            8,
        ),
        D::ImageRgb8(im) => (
            im.pixels().map(|p| p.0.map(|v| lut8[v as usize])).collect(),
            ColorChannels::Rgb,
            false,
            8,
        ),
        D::ImageRgba8(im) => (
            im.pixels()
                .map(|p| [p.0[0], p.0[1], p.0[2]].map(|v| lut8[v as usize]))
                .collect(),
            ColorChannels::Rgb,
            true,
            8,
        ),
        D::ImageLuma16(im) => (
            im.pixels().map(|p| [dec16(p.0[0]); 3]).collect(),
            ColorChannels::Gray,
            false,
            16,
        ),
        D::ImageLumaA16(im) => (
            im.pixels().map(|p| [dec16(p.0[0]); 3]).collect(),
            ColorChannels::Gray,
            true,
            16,
        ),
        D::ImageRgb16(im) => (
            im.pixels().map(|p| p.0.map(dec16)).collect(),
            ColorChannels::Rgb,
            false,
            16,
        ),
        D::ImageRgba16(im) => (
            im.pixels()
                .map(|p| [p.0[0], p.0[1], p.0[2]].map(dec16))
                .collect(),
            ColorChannels::Rgb,
            true,
            16,
        ),
        other => {
            return Err(ImageError::UnsupportedChannels {
                path: path.to_path_buf(),
                reason: format!("unsupported PNG pixel type {:?}", other.color()),
            })
        }
    };
    Ok(LoadedImage {
        path: path.to_path_buf(),
        image: Image::new(width, height, pixels)?,
        format: ImageFormat::Png,
        channels,
        alpha_ignored,
        bit_depth,
    })
}

/// Reads a mask file: its size and, per pixel, `true` where any colour channel (not alpha) is
/// nonzero (PNG codes as they are, EXR values after the checks of [`read_image`]).
///
/// # Errors
/// A missing or unreadable file, or one that is not a PNG or OpenEXR image.
pub fn nonzero_mask(path: &Path) -> Result<(usize, usize, Vec<bool>)> {
    let bytes = open_bytes(path)?;
    if bytes.starts_with(&PNG_MAGIC) {
        let decoded = image::load_from_memory_with_format(&bytes, image::ImageFormat::Png)
            .map_err(|e| not_an_image(path, format!("damaged or unsupported PNG file: {e}")))?;
        let (w, h) = (decoded.width() as usize, decoded.height() as usize);
        // Alpha is ignored: only the colour (or gray) channels decide.
        let rgba = decoded.into_rgba16();
        let bits = rgba
            .pixels()
            .map(|p| p.0[0] != 0 || p.0[1] != 0 || p.0[2] != 0)
            .collect();
        Ok((w, h, bits))
    } else if bytes.starts_with(&EXR_MAGIC) {
        let loaded = read_exr_bytes(path, &bytes)?;
        loaded.image.validate(&path.display().to_string())?;
        let bits = loaded
            .image
            .pixels
            .iter()
            .map(|p| p.iter().any(|&v| v != 0.0))
            .collect();
        Ok((loaded.image.width, loaded.image.height, bits))
    } else {
        Err(not_an_image(
            path,
            "a mask must be a PNG (or OpenEXR) file; nonzero pixels are inside",
        ))
    }
}

/// The per-pixel variance an OpenEXR carries beside its image (`variance.R`, `variance.G`,
/// `variance.B`: `prt render --aovs` writes the variance of each pixel's mean), or `None` when
/// the file has no such channels (or is not an EXR).
///
/// # Errors
/// A file that cannot be read, or an EXR that does not parse.
pub fn read_variance(path: impl AsRef<Path>) -> Result<Option<Vec<[f32; 3]>>> {
    let path = path.as_ref();
    let bytes = open_bytes(path)?;
    if !bytes.starts_with(&EXR_MAGIC) {
        return Ok(None);
    }
    let image = parse_exr(path, &bytes)?;
    for layer in &image.layer_data {
        let channels = &layer.channel_data.list;
        let find = |name: &str| channels.iter().find(|c| c.name.to_string() == name);
        if let (Some(r), Some(g), Some(b)) =
            (find("variance.R"), find("variance.G"), find("variance.B"))
        {
            let [r, g, b]: [Vec<f32>; 3] =
                [r, g, b].map(|c| c.sample_data.values_as_f32().collect());
            return Ok(Some(
                r.iter()
                    .zip(&g)
                    .zip(&b)
                    .map(|((r, g), b)| [*r, *g, *b])
                    .collect(),
            ));
        }
    }
    Ok(None)
}
