//! Output files: EXR (the master) and a PNG view, both written atomically.
//!
//! **EXR layout.** One single-part scanline EXR, ZIP-compressed, all channels f32:
//! `R`, `G`, `B` (linear Rec.709 radiance) and, when AOVs were rendered, in the classic
//! OpenEXR layer naming: `normal.X/Y/Z` (first-hit shading normal turned towards the camera,
//! 0 for background), `albedo.R/G/B` (first-hit `albedo`), `depth.Z` (distance from the eye,
//! 0 for background) and `variance.R/G/B` (estimated variance of the pixel mean, sample
//! variance / spp). The header carries the attributes `prt.spp` (i32), `prt.bounces` (i32),
//! `prt.seed` (text, decimal u64), `prt.mode` (text), `prt.render_seconds` (f64),
//! `prt.tool_version` (text), `prt.invalid_samples` (i32) and `prt.noise_estimate` (f64: the
//! image's own relative noise estimate on object pixels, NaN when it has none) and
//! `prt.noise_psnr_ldr` (f64: its own estimate of its 8-bit noise ceiling, dB, likewise).
//!
//! **PNG view** (CONVENTIONS.md): radiance × 2^EV, clamped to [0, 1], sRGB curve, 8 bits.
//!
//! **Atomic writes**: data goes to a hidden temporary file in the destination's directory,
//! is flushed and fsynced, then renamed over the destination (and the directory is fsynced),
//! so readers see either the old file or the complete new one.

pub use crate::color::{srgb_encode, to_srgb8};
use crate::{Mode, RenderOutput, TracerError};
use exr::prelude::{
    AnyChannel, AnyChannels, AttributeValue, Encoding, FlatSamples, Image, Layer, LayerAttributes,
    SmallVec, Text, WritableImage,
};
use glam::Vec3;
use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

fn write_error(path: &Path, reason: impl std::fmt::Display) -> TracerError {
    TracerError::Write {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Writes `path` atomically: `fill` writes into a temporary file beside it, which is fsynced and
/// renamed over `path`.
///
/// # Errors
/// Any I/O error, or an error from `fill`; the temporary file is removed on failure.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&mut File>) -> Result<(), String>,
) -> Result<(), TracerError> {
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let name = path
        .file_name()
        .ok_or_else(|| write_error(path, "not a file path"))?;
    let tmp = dir.join(format!(
        ".{}.tmp-{}-{:?}",
        name.to_string_lossy(),
        std::process::id(),
        std::thread::current().id()
    ));
    let result: Result<(), String> = (|| {
        let mut file = File::create(&tmp).map_err(|e| e.to_string())?;
        {
            let mut w = BufWriter::new(&mut file);
            fill(&mut w)?;
            w.flush().map_err(|e| e.to_string())?;
        }
        file.sync_all().map_err(|e| e.to_string())?;
        std::fs::rename(&tmp, path).map_err(|e| e.to_string())?;
        if let Ok(d) = File::open(&dir) {
            // Persist the rename; not every platform can fsync a directory, so best effort.
            let _ = d.sync_all();
        }
        Ok(())
    })();
    if let Err(e) = result {
        let _ = std::fs::remove_file(&tmp);
        return Err(write_error(path, e));
    }
    Ok(())
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

/// An EXR image of one layer of f32 or f16 channels, as prt writes them.
pub type ExrImage = Image<Layer<AnyChannels<FlatSamples>>>;

/// Writes an EXR image atomically with its header's attributes in name order
/// ([`sort_exr_attributes`]), so that the same image is always the same bytes.
///
/// # Errors
/// When the image cannot be encoded or the file cannot be written.
pub fn write_exr_image(path: &Path, image: &ExrImage) -> Result<(), TracerError> {
    let mut buffer = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut buffer)
        .map_err(|e| write_error(path, e))?;
    let mut bytes = buffer.into_inner();
    sort_exr_attributes(&mut bytes).map_err(|e| write_error(path, e))?;
    write_atomically(path, |w| w.write_all(&bytes).map_err(|e| e.to_string()))
}

/// Puts the attributes of a single-part EXR header in name order, in place. The exr crate
/// keeps custom attributes in a `HashMap` and writes them in its iteration order, which
/// differs from process to process (and from map to map), so the same image came out as
/// different bytes. An attribute is `name\0 type\0 size(i32 LE) value`; the header ends with
/// an empty name. Reordering keeps the header's length, so the chunk offsets after it stay
/// valid.
///
/// # Errors
/// A multi-part file or a header that does not parse (neither is what the exr crate writes
/// for prt's images).
pub fn sort_exr_attributes(bytes: &mut [u8]) -> Result<(), String> {
    const MULTI_PART: u32 = 0x1000;
    let bad = || "malformed EXR header".to_string();
    let version = u32::from_le_bytes(bytes.get(4..8).ok_or_else(bad)?.try_into().unwrap());
    if version & MULTI_PART != 0 {
        return Err("multi-part EXR headers are not reordered".into());
    }
    let nul = |from: usize| -> Result<usize, String> {
        let rest = bytes.get(from..).ok_or_else(bad)?;
        Ok(from + rest.iter().position(|&b| b == 0).ok_or_else(bad)?)
    };
    let (start, mut at) = (8, 8);
    let mut attributes: Vec<(usize, usize)> = Vec::new();
    while *bytes.get(at).ok_or_else(bad)? != 0 {
        let type_end = nul(nul(at)? + 1)?;
        let size = bytes.get(type_end + 1..type_end + 5).ok_or_else(bad)?;
        let size =
            usize::try_from(i32::from_le_bytes(size.try_into().unwrap())).map_err(|_| bad())?;
        let end = type_end + 5 + size;
        if end > bytes.len() {
            return Err(bad());
        }
        attributes.push((at, end));
        at = end;
    }
    let mut sorted: Vec<&[u8]> = attributes.iter().map(|&(a, b)| &bytes[a..b]).collect();
    sorted.sort_unstable();
    let header = sorted.concat();
    bytes[start..at].copy_from_slice(&header);
    Ok(())
}

/// Writes the PNG view of the radiance (exposure in EV, 0 by default), atomically.
///
/// # Errors
/// When the file cannot be written.
pub fn write_png(path: &Path, out: &RenderOutput, exposure_ev: f32) -> Result<(), TracerError> {
    let bytes = to_srgb8(&out.radiance, exposure_ev);
    let img = image::RgbImage::from_raw(out.width, out.height, bytes)
        .ok_or_else(|| write_error(path, "image size does not match the pixel count"))?;
    write_atomically(path, |w| {
        img.write_to(w, image::ImageFormat::Png)
            .map_err(|e| e.to_string())
    })
}
