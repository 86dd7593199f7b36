//! Writing relit images: EXR (linear RGB f32 with attributes) and the PNG view of
//! CONVENTIONS.md, both atomically (the tracer's temporary-file-and-rename writer).

use crate::error::SceneRelightError;
use crate::imaging::RgbImage;
use exr::prelude::*;
use glam::Vec3;
use std::path::Path;

fn write_err(path: &Path, e: impl std::fmt::Display) -> SceneRelightError {
    SceneRelightError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// Writes `img` as a linear RGB f32 EXR with string attributes `prt.<key>`
/// ([`prt_image::write_exr`]).
pub fn write_exr(
    path: &Path,
    img: &RgbImage,
    attributes: &[(&str, String)],
) -> std::result::Result<(), SceneRelightError> {
    let attributes = attributes
        .iter()
        .map(|(k, v)| {
            (
                format!("prt.{k}"),
                AttributeValue::Text(Text::from(v.as_str())),
            )
        })
        .collect();
    prt_image::write_exr(path, img, attributes).map_err(|e| write_err(path, e))
}

/// Writes the 8-bit sRGB view (exposure in EV) as PNG ([`prt_image::write_png`]).
pub fn write_png(
    path: &Path,
    img: &RgbImage,
    exposure_ev: f32,
) -> std::result::Result<(), SceneRelightError> {
    prt_image::write_png(path, img, exposure_ev).map_err(|e| write_err(path, e))
}

/// A path-traced reference kept in the report's cache: its radiance and the half difference
/// `(A − B) / 2` of its two half images (which estimates its error per pixel).
#[derive(Clone, Debug, PartialEq)]
pub struct CachedReference {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Samples per pixel taken.
    pub spp: u32,
    /// Render seconds.
    pub seconds: f64,
    /// Linear radiance, row-major.
    pub radiance: Vec<Vec3>,
    /// `(A − B) / 2` per pixel.
    pub half_difference: Vec<Vec3>,
}

const REFERENCE_MAGIC: &[u8; 8] = b"PRTREF01";

/// Writes `r` atomically: magic, width, height, spp (u32 LE), seconds (f64 LE), the radiance
/// and the half difference (f32 LE RGB, row-major), then the CRC-32 of all that.
///
/// # Errors
/// When the file cannot be written.
pub fn write_reference(
    path: &Path,
    r: &CachedReference,
) -> std::result::Result<(), SceneRelightError> {
    let mut bytes = Vec::with_capacity(32 + 24 * r.radiance.len());
    bytes.extend_from_slice(REFERENCE_MAGIC);
    for v in [r.width, r.height, r.spp] {
        bytes.extend_from_slice(&v.to_le_bytes());
    }
    bytes.extend_from_slice(&r.seconds.to_le_bytes());
    for v in r.radiance.iter().chain(&r.half_difference) {
        for c in v.to_array() {
            bytes.extend_from_slice(&c.to_le_bytes());
        }
    }
    let crc = crc32fast::hash(&bytes);
    bytes.extend_from_slice(&crc.to_le_bytes());
    prt_tracer::output::write_atomically(path, |out| {
        std::io::Write::write_all(out, &bytes).map_err(|e| e.to_string())
    })
    .map_err(|e| write_err(path, e))
}

/// Reads a reference written by [`write_reference`]; `Err` with the reason when the file is
/// missing, truncated, corrupt or of another size.
///
/// # Errors
/// As above (the report then renders the reference again).
pub fn read_reference(path: &Path) -> std::result::Result<CachedReference, String> {
    let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
    if bytes.len() < 32 || &bytes[..8] != REFERENCE_MAGIC {
        return Err("not a cached reference".into());
    }
    let (body, crc) = bytes.split_at(bytes.len() - 4);
    if crc32fast::hash(body).to_le_bytes() != crc {
        return Err("checksum mismatch".into());
    }
    let u32_at = |o: usize| u32::from_le_bytes(body[o..o + 4].try_into().expect("4 bytes"));
    let (width, height, spp) = (u32_at(8), u32_at(12), u32_at(16));
    let seconds = f64::from_le_bytes(body[20..28].try_into().expect("8 bytes"));
    let n = width as usize * height as usize;
    if body.len() != 28 + 24 * n {
        return Err(format!("{} bytes for {width}×{height} pixels", body.len()));
    }
    let floats: Vec<f32> = body[28..]
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().expect("4 bytes")))
        .collect();
    let vecs: Vec<Vec3> = floats.chunks_exact(3).map(Vec3::from_slice).collect();
    let (radiance, half_difference) = vecs.split_at(n);
    Ok(CachedReference {
        width,
        height,
        spp,
        seconds,
        radiance: radiance.to_vec(),
        half_difference: half_difference.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reference() -> CachedReference {
        CachedReference {
            width: 3,
            height: 2,
            spp: 64,
            seconds: 1.25,
            radiance: (0..6).map(|i| Vec3::splat(i as f32 * 0.5)).collect(),
            half_difference: (0..6).map(|i| Vec3::new(0.0, -(i as f32), 1e-3)).collect(),
        }
    }

    #[test]
    fn a_cached_reference_reads_back_exactly_and_damage_is_refused() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("ref.bin");
        let r = reference();
        write_reference(&path, &r).unwrap();
        let back = read_reference(&path).unwrap();
        assert_eq!((back.width, back.height, back.spp), (3, 2, 64));
        assert_eq!(back.seconds, 1.25);
        assert_eq!(
            (back.radiance, back.half_difference),
            (r.radiance, r.half_difference)
        );
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[40] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        assert_eq!(read_reference(&path).unwrap_err(), "checksum mismatch");
        std::fs::write(&path, &bytes[..20]).unwrap();
        assert!(read_reference(&path).is_err());
    }

    #[test]
    fn an_exr_reads_back_with_its_pixels_and_attributes() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("img.exr");
        let img = RgbImage {
            width: 2,
            height: 2,
            pixels: vec![
                [0.0, 0.5, 1.0],
                [2.0, 3.0, 4.0],
                [-1.0, 0.25, 8.0],
                [1e-3, 1e3, 0.0],
            ],
        };
        write_exr(&path, &img, &[("order", "6".into())]).unwrap();
        let back = read_all_flat_layers_from_file(&path).unwrap();
        let layer = &back.layer_data[0];
        assert_eq!(
            layer.attributes.other.get(&Text::from("prt.order")),
            Some(&AttributeValue::Text(Text::from("6")))
        );
        for (c, name) in ["R", "G", "B"].iter().enumerate() {
            let ch = layer
                .channel_data
                .list
                .iter()
                .find(|ch| ch.name == **name)
                .unwrap();
            let FlatSamples::F32(v) = &ch.sample_data else {
                panic!("{name} is not f32")
            };
            let expected: Vec<f32> = img.pixels.iter().map(|p| p[c]).collect();
            assert_eq!(v, &expected);
        }
    }
}
