//! Output files: EXR (the master) and a PNG view, both written atomically.
//!
//! **EXR layout.** One single-part scanline EXR, ZIP-compressed, all channels f32:
//! `R`, `G`, `B` (linear Rec.709 radiance) and, when AOVs were rendered, in the classic
//! OpenEXR layer naming: `normal.X/Y/Z` (first-hit shading normal turned towards the camera,
//! 0 for background), `albedo.R/G/B` (first-hit `albedo`), `depth.Z` (distance from the eye,
//! 0 for background) and `variance.R/G/B` (estimated variance of the pixel mean, sample
//! variance / spp). The header carries the attributes `prt.spp` (i32), `prt.bounces` (i32),
//! `prt.seed` (text, decimal u64), `prt.mode` (text), `prt.sampler` (text: `replicas` or
//! `single`, the pixel sampler's sequences), `prt.render_seconds` (f64),
//! `prt.tool_version` (text), `prt.invalid_samples` (i32) and `prt.noise_estimate` (f64: the
//! image's own relative noise estimate on object pixels, NaN when it has none) and
//! `prt.noise_psnr_ldr` (f64: its own estimate of its 8-bit noise ceiling, dB, likewise).
//!
//! **PNG view** (CONVENTIONS.md): radiance × 2^EV, clamped to [0, 1], sRGB curve, 8 bits.
//!
//! **Atomic writes**: data goes to a hidden temporary file in the destination's directory,
//! is flushed and fsynced, then renamed over the destination (and the directory is fsynced),
//! so readers see either the old file or the complete new one.
//!
//! The writers, the sRGB curve and the 8-bit view are prt-image's (one of each for the
//! workspace); this module adds the render's channels and metadata and the tracer's error.

use crate::{EnvSampling, Mode, RenderOutput, SamplerKind, SplitLobes, TracerError};
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    SmallVec, Text,
};
use glam::Vec3;
pub use prt_image::srgb::srgb_encode;
pub use prt_image::write::{sort_exr_attributes, ExrImage};
use std::collections::HashMap;
use std::fs::File;
use std::io::BufWriter;
use std::path::{Path, PathBuf};

/// Converts prt-image's write error to the tracer's (same path, same reason).
fn from_image(e: prt_image::ImageError) -> TracerError {
    match e {
        prt_image::ImageError::Write { path, reason } => TracerError::Write { path, reason },
        other => TracerError::Write {
            path: PathBuf::new(),
            reason: other.to_string(),
        },
    }
}

/// Writes `path` atomically ([`prt_image::write_atomically`]): `fill` writes into a temporary
/// file beside it, which is fsynced and renamed over `path`.
///
/// # Errors
/// Any I/O error, or an error from `fill`; the temporary file is removed on failure.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), String>,
) -> Result<(), TracerError> {
    prt_image::write_atomically(path, fill).map_err(from_image)
}

/// The 8-bit sRGB view of linear radiance ([`prt_image::srgb::to_srgb8`]): `× 2^exposure_ev`,
/// clamp to [0, 1], sRGB, round.
#[must_use]
pub fn to_srgb8(radiance: &[Vec3], exposure_ev: f32) -> Vec<u8> {
    let pixels: Vec<[f32; 3]> = radiance.iter().map(|v| v.to_array()).collect();
    prt_image::srgb::to_srgb8(&pixels, exposure_ev)
}

fn mode_name(mode: Mode) -> String {
    match mode {
        Mode::Path => "path".into(),
        Mode::Unshadowed => "unshadowed".into(),
        Mode::AmbientOcclusion { max_distance: None } => "ambient_occlusion".into(),
        Mode::AmbientOcclusion {
            max_distance: Some(d),
        } => format!("ambient_occlusion(max_distance={d})"),
    }
}

/// The metadata attributes written into the EXR header.
#[must_use]
pub fn metadata(out: &RenderOutput) -> Vec<(String, AttributeValue)> {
    let s = &out.settings;
    vec![
        (
            "prt.spp".into(),
            AttributeValue::I32(i32::try_from(s.spp).unwrap_or(i32::MAX)),
        ),
        ("prt.bounces".into(), AttributeValue::I32(s.bounces)),
        (
            "prt.seed".into(),
            AttributeValue::Text(Text::from(s.seed.to_string().as_str())),
        ),
        (
            "prt.mode".into(),
            AttributeValue::Text(Text::from(mode_name(s.mode).as_str())),
        ),
        (
            "prt.sampler".into(),
            AttributeValue::Text(Text::from(match s.sampler {
                SamplerKind::Replicas => "replicas",
                SamplerKind::Single => "single",
            })),
        ),
        (
            "prt.env_sampling".into(),
            AttributeValue::Text(Text::from(match s.env_sampling {
                EnvSampling::Luminance => "luminance",
                EnvSampling::Compensated => "compensated",
                EnvSampling::PerNormal => "per-normal",
            })),
        ),
        (
            "prt.split_lobes".into(),
            AttributeValue::Text(Text::from(match s.split_lobes {
                SplitLobes::None => "none",
                SplitLobes::Mirror => "mirror",
                SplitLobes::Delta => "delta",
                SplitLobes::All => "all",
            })),
        ),
        (
            "prt.split_depth".into(),
            AttributeValue::I32(i32::try_from(s.split_depth).unwrap_or(i32::MAX)),
        ),
        (
            "prt.render_seconds".into(),
            AttributeValue::F64(out.seconds),
        ),
        (
            "prt.tool_version".into(),
            AttributeValue::Text(Text::from(concat!(
                "prt-tracer ",
                env!("CARGO_PKG_VERSION")
            ))),
        ),
        (
            "prt.invalid_samples".into(),
            AttributeValue::I32(i32::try_from(out.invalid_samples).unwrap_or(i32::MAX)),
        ),
        (
            "prt.noise_estimate".into(),
            AttributeValue::F64(out.noise.unwrap_or(f64::NAN)),
        ),
        (
            "prt.noise_psnr_ldr".into(),
            AttributeValue::F64(out.noise_psnr_ldr.unwrap_or(f64::NAN)),
        ),
    ]
}

fn channel(name: &str, values: Vec<f32>) -> AnyChannel<FlatSamples> {
    AnyChannel::new(name, FlatSamples::F32(values))
}

fn split(v: &[Vec3], prefix: &str, names: [&str; 3]) -> Vec<AnyChannel<FlatSamples>> {
    (0..3)
        .map(|c| {
            channel(
                &format!("{prefix}{}", names[c]),
                v.iter().map(|x| x[c]).collect(),
            )
        })
        .collect()
}

/// Writes the render (and its AOVs, if any) as an EXR with metadata (layout in the module
/// docs), atomically.
///
/// # Errors
/// When the file cannot be written.
pub fn write_exr(path: &Path, out: &RenderOutput) -> Result<(), TracerError> {
    let mut channels: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    channels.extend(split(&out.radiance, "", ["R", "G", "B"]));
    if let Some(a) = &out.aovs {
        channels.extend(split(&a.normal, "normal.", ["X", "Y", "Z"]));
        channels.extend(split(&a.albedo, "albedo.", ["R", "G", "B"]));
        channels.extend(split(&a.variance, "variance.", ["R", "G", "B"]));
        channels.push(channel("depth.Z", a.depth.clone()));
    }
    let attributes = LayerAttributes {
        other: metadata(out)
            .into_iter()
            .map(|(k, v)| (Text::from(k.as_str()), v))
            .collect::<HashMap<_, _>>(),
        ..LayerAttributes::default()
    };
    let layer = Layer::new(
        (out.width as usize, out.height as usize),
        attributes,
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(channels),
    );
    write_exr_image(path, &Image::from_layer(layer))
}

/// Writes an EXR image atomically with its header's attributes in name order
/// ([`prt_image::write_exr_image`]), so that the same image is always the same bytes.
///
/// # Errors
/// When the image cannot be encoded or the file cannot be written.
pub fn write_exr_image(path: &Path, image: &ExrImage) -> Result<(), TracerError> {
    prt_image::write_exr_image(path, image).map_err(from_image)
}

/// Writes the PNG view of the radiance (exposure in EV, 0 by default), atomically.
///
/// # Errors
/// When the file cannot be written.
pub fn write_png(path: &Path, out: &RenderOutput, exposure_ev: f32) -> Result<(), TracerError> {
    let bytes = to_srgb8(&out.radiance, exposure_ev);
    prt_image::write::write_png_bytes(path, out.width as usize, out.height as usize, bytes)
        .map_err(from_image)
}
