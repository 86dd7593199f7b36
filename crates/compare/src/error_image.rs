//! False-colour error images with a scale bar, written atomically as PNG.

use crate::colormap::viridis_rgb8;
use crate::error::{CompareError, Result};
use crate::font::{draw_text, format_number, text_width, GLYPH_HEIGHT};
use crate::mask::Mask;
use crate::metrics::check_pair;
use prt_image::Image;
use std::path::Path;

/// Absolute or relative error per pixel.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ErrorMeasure {
    /// `|a − b|` (of the chosen [`ErrorChannel`] quantity).
    #[default]
    Absolute,
    /// `|a − b| / max(|b|, floor)`, `b` the reference's quantity.
    Relative,
}

/// Which per-pixel quantity the error is taken of.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ErrorChannel {
    /// Rec.709 luminance `Y = 0.2126 R + 0.7152 G + 0.0722 B`: error `|Y(a) − Y(b)|`,
    /// relative to `|Y(b)|`.
    #[default]
    Luminance,
    /// The largest channel difference `max_c |a_c − b_c|`, relative to `max_c |b_c|`.
    MaxChannel,
}

/// Options of the error image.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorImageOptions {
    /// Absolute or relative error.
    pub measure: ErrorMeasure,
    /// Luminance or largest channel.
    pub channel: ErrorChannel,
    /// The error shown at the top of the colour map; `None`: the largest error over the mask
    /// (or the image), or 1 when that is 0.
    pub scale_max: Option<f64>,
    /// Denominator floor of relative errors (avoids dividing by black pixels). Default 1e-3.
    pub relative_floor: f64,
}

impl Default for ErrorImageOptions {
    fn default() -> Self {
        Self {
            measure: ErrorMeasure::Absolute,
            channel: ErrorChannel::Luminance,
            scale_max: None,
            relative_floor: 1e-3,
        }
    }
}

/// An 8-bit sRGB picture: the false-colour error image above its scale bar.
#[derive(Debug, Clone, PartialEq)]
pub struct ErrorPicture {
    /// Width in pixels.
    pub width: usize,
    /// Height in pixels.
    pub height: usize,
    /// Row-major RGB8 pixels.
    pub pixels: Vec<[u8; 3]>,
    /// The error value at the top of the colour map.
    pub scale_max: f64,
    /// Integer magnification of the error image (small images are enlarged).
    pub magnification: usize,
}

const LUMA: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// Per-pixel errors of `a` against `reference` (row-major), as chosen by `options`.
pub fn error_values(a: &Image, reference: &Image, options: &ErrorImageOptions) -> Result<Vec<f64>> {
    check_pair(a, "test image", reference, "reference", None)?;
    if !(options.relative_floor > 0.0 && options.relative_floor.is_finite()) {
        return Err(CompareError::InvalidOption(format!(
            "relative floor must be positive and finite, got {}",
            options.relative_floor
        )));
    }
    Ok(a.pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(pa, pb)| {
            let (pa, pb) = (pa.map(f64::from), pb.map(f64::from));
            let (err, base) = match options.channel {
                ErrorChannel::Luminance => {
                    let ya: f64 = (0..3).map(|c| LUMA[c] * pa[c]).sum();
                    let yb: f64 = (0..3).map(|c| LUMA[c] * pb[c]).sum();
                    ((ya - yb).abs(), yb.abs())
                }
                ErrorChannel::MaxChannel => (
                    (0..3).map(|c| (pa[c] - pb[c]).abs()).fold(0.0, f64::max),
                    pb.iter().map(|v| v.abs()).fold(0.0, f64::max),
                ),
            };
            match options.measure {
                ErrorMeasure::Absolute => err,
                ErrorMeasure::Relative => err / base.max(options.relative_floor),
            }
        })
        .collect())
}

/// Renders the false-colour error image: each pixel's error divided by the scale maximum,
/// through [`viridis`](crate::viridis); pixels outside the mask are mid gray. Below it a
/// colour bar with ticks and labels at 0, half and the maximum. Images narrower than 256
/// pixels are enlarged by an integer factor (at most 8).
pub fn render_error_picture(
    a: &Image,
    reference: &Image,
    mask: Option<&Mask>,
    options: &ErrorImageOptions,
) -> Result<ErrorPicture> {
    let errors = error_values(a, reference, options)?;
    if let Some(m) = mask {
        m.check_size("reference", reference.width, reference.height)?;
    }
    let inside = |i: usize| mask.is_none_or(|m| m.contains_index(i));
    let scale_max = match options.scale_max {
        Some(s) if s > 0.0 && s.is_finite() => s,
        Some(s) => {
            return Err(CompareError::InvalidOption(format!(
                "error scale maximum must be positive and finite, got {s}"
            )))
        }
        None => {
            let m = errors
                .iter()
                .enumerate()
                .filter(|&(i, _)| inside(i))
                .map(|(_, &e)| e)
                .fold(0.0, f64::max);
            if m > 0.0 {
                m
            } else {
                1.0
            }
        }
    };

    let (w, h) = (reference.width, reference.height);
    let magnification = 256usize.div_ceil(w).clamp(1, 8);
    let label_scale = if w * magnification >= 480 { 2 } else { 1 };
    let width = (w * magnification).max(256);
    let margin = 6 * label_scale;
    let bar_height = 14 * label_scale;
    let tick = 4 * label_scale;
    let bar_top = h * magnification + margin;
    let label_top = bar_top + bar_height + tick + 2;
    let height = label_top + GLYPH_HEIGHT * label_scale + margin;
    let white = [255u8; 3];
    let black = [0u8; 3];
    let mut pixels = vec![white; width * height];

    for y in 0..h * magnification {
        for x in 0..w * magnification {
            let i = (y / magnification) * w + x / magnification;
            pixels[y * width + x] = if inside(i) {
                viridis_rgb8(errors[i] / scale_max)
            } else {
                [128, 128, 128]
            };
        }
    }

    // The colour bar spans the canvas less a margin on each side for the end labels.
    let bar_left = margin;
    let bar_len = width - 2 * margin;
    for x in 0..bar_len {
        let c = viridis_rgb8(x as f64 / (bar_len - 1).max(1) as f64);
        for y in bar_top..bar_top + bar_height {
            pixels[y * width + bar_left + x] = c;
        }
    }
    for (k, frac) in [0.0, 0.5, 1.0].into_iter().enumerate() {
        let x = bar_left + (frac * (bar_len - 1) as f64).round() as usize;
        for y in bar_top + bar_height..bar_top + bar_height + tick {
            for dx in 0..label_scale {
                if x + dx < width {
                    pixels[y * width + x + dx] = black;
                }
            }
        }
        let text = format_number(frac * scale_max);
        let tw = text_width(&text, label_scale);
        // Centred under the tick; the last one ends at the tick so it stays on the canvas.
        let x0 = if k < 2 {
            x.saturating_sub(tw / 2)
        } else {
            (x + label_scale).saturating_sub(tw)
        };
        let x0 = x0.min(width.saturating_sub(tw));
        draw_text(&mut pixels, width, x0, label_top, &text, label_scale, black);
    }

    Ok(ErrorPicture {
        width,
        height,
        pixels,
        scale_max,
        magnification,
    })
}

/// Writes RGB8 pixels as a PNG atomically (prt-image's writer: a temporary file in the same
/// directory, renamed over `path`, so a reader never sees a partial file).
///
/// # Errors
/// [`CompareError::PixelCount`] when `pixels` is not `width × height` long, and write errors.
pub fn write_png_atomic(
    path: &Path,
    width: usize,
    height: usize,
    pixels: &[[u8; 3]],
) -> Result<()> {
    if pixels.len() != width * height {
        return Err(CompareError::PixelCount {
            what: path.display().to_string(),
            len: pixels.len(),
            width,
            height,
        });
    }
    let bytes: Vec<u8> = pixels.iter().flatten().copied().collect();
    prt_image::write::write_png_bytes(path, width, height, bytes)?;
    Ok(())
}

/// Renders the error picture ([`render_error_picture`]) and writes it to `path` as a PNG
/// ([`write_png_atomic`]); returns the picture.
pub fn write_error_png(
    path: impl AsRef<Path>,
    a: &Image,
    reference: &Image,
    mask: Option<&Mask>,
    options: &ErrorImageOptions,
) -> Result<ErrorPicture> {
    let picture = render_error_picture(a, reference, mask, options)?;
    write_png_atomic(
        path.as_ref(),
        picture.width,
        picture.height,
        &picture.pixels,
    )?;
    Ok(picture)
}
