//! The image of prt: linear RGB pixels (Rec.709 primaries, f32), the sRGB curve of IEC
//! 61966-2-1 and the 8-bit view of CONVENTIONS.md "Colour and images" (exposure, clamp to
//! [0, 1], sRGB, 8 bits), reading OpenEXR and PNG files into it, and writing EXR and PNG
//! files atomically (a temporary file beside the target, fsynced and renamed).
//!
//! Every crate that makes or reads pictures uses this one type and these writers: the path
//! tracer's renders, relit images, reflectance-field frames, the report's figures and the
//! comparison tool. EXR headers are written with their attributes in name order, so the same
//! image is always the same bytes (the exr crate keeps them in a hash map).

mod error;
mod image;
pub mod read;
pub mod srgb;
pub mod write;

pub use crate::error::ImageError;
pub use crate::image::Image;
pub use crate::read::{read_image, ColorChannels, ImageFormat, LoadedImage};
pub use crate::srgb::{ldr_value, ldr_view, srgb_eotf, srgb_oetf};
pub use crate::write::{write_atomically, write_exr, write_exr_image, write_png, ExrImage};
