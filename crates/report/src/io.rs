//! Writing relit images: EXR (linear RGB f32 with attributes) and the PNG view of
//! CONVENTIONS.md, both atomically (the tracer's temporary-file-and-rename writer).

use crate::error::ReportError;
use crate::imaging::RgbImage;
use exr::prelude::*;
use glam::Vec3;
use std::path::Path;

fn write_err(path: &Path, e: impl std::fmt::Display) -> ReportError {
    ReportError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// Writes `img` as a linear RGB f32 EXR with string attributes `prt.<key>`.
pub fn write_exr(
    path: &Path,
    img: &RgbImage,
    attributes: &[(&str, String)],
) -> std::result::Result<(), ReportError> {
    let (w, h) = (img.width as usize, img.height as usize);
    let channel = |c: usize, name: &str| {
        AnyChannel::new(
            name,
            FlatSamples::F32(img.pixels.iter().map(|p| p[c]).collect()),
        )
    };
    let mut list: SmallVec<[AnyChannel<FlatSamples>; 4]> = SmallVec::new();
    list.extend([channel(0, "R"), channel(1, "G"), channel(2, "B")]);
    let channels = AnyChannels::sort(list);
    let mut layer_attributes = LayerAttributes::default();
    for (k, v) in attributes {
        layer_attributes.other.insert(
            Text::from(format!("prt.{k}").as_str()),
            AttributeValue::Text(Text::from(v.as_str())),
        );
    }
    let image = Image::from_layer(Layer::new(
        (w, h),
        layer_attributes,
        Encoding::SMALL_LOSSLESS,
        channels,
    ));
    prt_tracer::output::write_atomically(path, |out| {
        image.write().to_buffered(out).map_err(|e| e.to_string())
    })
    .map_err(|e| write_err(path, e))
}

/// Writes the 8-bit sRGB view (exposure in EV) as PNG.
pub fn write_png(
    path: &Path,
    img: &RgbImage,
    exposure_ev: f32,
) -> std::result::Result<(), ReportError> {
    let lin: Vec<Vec3> = img.pixels.iter().map(|p| Vec3::from_array(*p)).collect();
    let bytes = prt_tracer::output::to_srgb8(&lin, exposure_ev);
    let png = image::RgbImage::from_raw(img.width, img.height, bytes)
        .ok_or_else(|| write_err(path, "size mismatch"))?;
    prt_tracer::output::write_atomically(path, |out| {
        png.write_to(out, image::ImageFormat::Png)
            .map_err(|e| e.to_string())
    })
    .map_err(|e| write_err(path, e))
}

/// The image as the comparison crate's type.
#[must_use]
pub fn to_compare_image(img: &RgbImage) -> prt_compare::Image {
    prt_compare::Image {
        width: img.width as usize,
        height: img.height as usize,
        pixels: img.pixels.clone(),
    }
}
