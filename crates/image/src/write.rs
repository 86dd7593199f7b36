//! Writing images: the atomic writer every output of prt goes through, EXR (linear f32, its
//! header's attributes in name order so that the same image is always the same bytes) and the
//! PNG view.

use crate::error::{ImageError, Result};
use crate::image::Image;
use exr::prelude as x;
use exr::prelude::WritableImage as _;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

fn write_error(path: &Path, reason: impl std::fmt::Display) -> ImageError {
    ImageError::Write {
        path: path.to_path_buf(),
        reason: reason.to_string(),
    }
}

/// Writes `path` atomically: `fill` writes into a temporary file beside it, which is fsynced and
/// renamed over `path`.
///
/// # Errors
/// [`ImageError::Write`] for any I/O error or an error from `fill`; the temporary file is
/// removed on failure and `path` keeps what it held.
pub fn write_atomically(
    path: &Path,
    fill: impl FnOnce(&mut BufWriter<&mut File>) -> std::result::Result<(), String>,
) -> Result<()> {
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
    let result: std::result::Result<(), String> = (|| {
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

/// An EXR image of one layer of f32 or f16 channels, as prt writes them.
pub type ExrImage = x::Image<x::Layer<x::AnyChannels<x::FlatSamples>>>;

/// Writes an EXR image atomically with its header's attributes in name order
/// ([`sort_exr_attributes`]), so that the same image is always the same bytes.
///
/// # Errors
/// [`ImageError::Write`] when the image cannot be encoded or the file cannot be written.
pub fn write_exr_image(path: &Path, image: &ExrImage) -> Result<()> {
    let mut buffer = std::io::Cursor::new(Vec::new());
    image
        .write()
        .to_buffered(&mut buffer)
        .map_err(|e| write_error(path, e))?;
    let mut bytes = buffer.into_inner();
    sort_exr_attributes(&mut bytes).map_err(|e| write_error(path, e))?;
    write_atomically(path, |w| w.write_all(&bytes).map_err(|e| e.to_string()))
}

/// Writes `image` as a linear RGB f32 EXR (channels `R`, `G`, `B`, lossless compression) with
/// the given header attributes, atomically.
///
/// # Errors
/// [`ImageError::Write`].
pub fn write_exr(
    path: &Path,
    image: &Image,
    attributes: Vec<(String, x::AttributeValue)>,
) -> Result<()> {
    let channel = |c: usize, name: &str| {
        x::AnyChannel::new(
            name,
            x::FlatSamples::F32(image.pixels.iter().map(|p| p[c]).collect()),
        )
    };
    let mut list: x::SmallVec<[x::AnyChannel<x::FlatSamples>; 4]> = x::SmallVec::new();
    list.extend([channel(0, "R"), channel(1, "G"), channel(2, "B")]);
    let mut layer_attributes = x::LayerAttributes::default();
    for (k, v) in attributes {
        layer_attributes.other.insert(x::Text::from(k.as_str()), v);
    }
    let exr = x::Image::from_layer(x::Layer::new(
        (image.width, image.height),
        layer_attributes,
        x::Encoding::SMALL_LOSSLESS,
        x::AnyChannels::sort(list),
    ));
    write_exr_image(path, &exr)
}

/// Writes the 8-bit PNG view of `image` ([`to_srgb8`](crate::srgb::to_srgb8), exposure in
/// EV), atomically.
///
/// # Errors
/// [`ImageError::Write`].
pub fn write_png(path: &Path, image: &Image, exposure_ev: f32) -> Result<()> {
    let bytes = crate::srgb::to_srgb8(&image.pixels, exposure_ev);
    write_png_bytes(path, image.width, image.height, bytes)
}

/// Writes row-major 8-bit RGB bytes as a PNG, atomically.
///
/// # Errors
/// [`ImageError::Write`], also when `bytes` is not `3 × width × height` long.
pub fn write_png_bytes(path: &Path, width: usize, height: usize, bytes: Vec<u8>) -> Result<()> {
    let size = |v: usize| u32::try_from(v).map_err(|_| write_error(path, "image too large"));
    let png = ::image::RgbImage::from_raw(size(width)?, size(height)?, bytes)
        .ok_or_else(|| write_error(path, "image size does not match the pixel count"))?;
    write_atomically(path, |w| {
        png.write_to(w, ::image::ImageFormat::Png)
            .map_err(|e| e.to_string())
    })
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
pub fn sort_exr_attributes(bytes: &mut [u8]) -> std::result::Result<(), String> {
    const MULTI_PART: u32 = 0x1000;
    let bad = || "malformed EXR header".to_string();
    let version = u32::from_le_bytes(bytes.get(4..8).ok_or_else(bad)?.try_into().unwrap());
    if version & MULTI_PART != 0 {
        return Err("multi-part EXR headers are not reordered".into());
    }
    let nul = |from: usize| -> std::result::Result<usize, String> {
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

#[cfg(test)]
mod tests {
    use super::*;

    /// An EXR written here reads back to the same pixels, with its attributes; a PNG reads back
    /// to the 8-bit view's codes decoded; a failed write leaves the old file.
    #[test]
    fn written_images_read_back() {
        let dir = tempfile::tempdir().unwrap();
        let img = Image::from_fn(5, 3, |x, y| [x as f32 * 0.25, y as f32 * 0.5, 0.125]);
        let exr = dir.path().join("a.exr");
        let attrs = vec![
            (
                "prt.b".to_string(),
                x::AttributeValue::Text(x::Text::from("2")),
            ),
            (
                "prt.a".to_string(),
                x::AttributeValue::Text(x::Text::from("1")),
            ),
        ];
        write_exr(&exr, &img, attrs.clone()).unwrap();
        let first = std::fs::read(&exr).unwrap();
        assert_eq!(crate::read_image(&exr).unwrap().image, img);
        assert!(
            crate::read::read_variance(&exr).unwrap().is_none(),
            "no variance channels"
        );
        // Same image and attributes: the same bytes (attributes sorted by name).
        write_exr(&exr, &img, attrs.into_iter().rev().collect()).unwrap();
        assert_eq!(std::fs::read(&exr).unwrap(), first);

        let png = dir.path().join("a.png");
        write_png(&png, &img, 0.0).unwrap();
        let back = crate::read_image(&png).unwrap().image;
        let codes = crate::srgb::to_srgb8(&img.pixels, 0.0);
        for (p, c) in back.pixels.iter().flatten().zip(codes) {
            assert_eq!(*p, crate::srgb_eotf(f64::from(c) / 255.0) as f32);
        }

        let err = write_atomically(&exr, |_| Err("refused".into())).unwrap_err();
        assert!(err.to_string().contains("refused"), "{err}");
        assert_eq!(std::fs::read(&exr).unwrap(), first);
        assert_eq!(
            std::fs::read_dir(dir.path()).unwrap().count(),
            2,
            "no temporary left"
        );
    }
}
