//! Reading files (formats, channels, errors) and the false-colour error image.

mod common;

use common::{assert_close, data};
use prt_compare::{
    read_image, read_pair, render_error_picture, srgb_eotf, viridis_rgb8, write_error_png,
    write_png_atomic, ColorChannels, CompareError, ErrorChannel, ErrorImageOptions, ErrorMeasure,
    Image, ImageError, Mask,
};

fn write_exr(
    path: &std::path::Path,
    w: usize,
    h: usize,
    f: impl Fn(usize, usize) -> (f32, f32, f32) + Sync,
) {
    exr::prelude::write_rgb_file(path, w, h, f).unwrap();
}

#[test]
fn test01_missing_and_not_an_image() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.exr");
    let err = read_image(&missing).unwrap_err();
    assert!(matches!(err, ImageError::NotFound { .. }));
    assert!(err.to_string().contains("nope.exr"), "{err}");
    let text = dir.path().join("notes.png");
    std::fs::write(&text, "hello").unwrap();
    let err = read_image(&text).unwrap_err();
    assert!(matches!(err, ImageError::NotAnImage { .. }), "{err}");
    assert!(err.to_string().contains("notes.png"));
    let empty = dir.path().join("empty.exr");
    std::fs::write(&empty, "").unwrap();
    assert!(read_image(&empty)
        .unwrap_err()
        .to_string()
        .contains("empty"));
    // A PNG signature followed by garbage: damaged, not a panic.
    let broken = dir.path().join("broken.png");
    std::fs::write(&broken, b"\x89PNG\r\n\x1a\ngarbage").unwrap();
    assert!(matches!(
        read_image(&broken),
        Err(ImageError::NotAnImage { .. })
    ));
}

#[test]
fn test02_exr_nan_names_pixel_and_file() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("nan.exr");
    write_exr(&p, 4, 3, |x, y| {
        if (x, y) == (2, 1) {
            (0.0, 0.0, f32::NAN)
        } else {
            (1.0, 2.0, 3.0)
        }
    });
    let err = read_image(&p).unwrap_err();
    assert!(
        matches!(
            err,
            ImageError::NonFinite {
                x: 2,
                y: 1,
                channel: 'B',
                ..
            }
        ),
        "{err}"
    );
    assert!(err.to_string().contains("nan.exr"));
    // An f32 EXR written by the exr crate reads back exactly, row 0 on top.
    let q = dir.path().join("ok.exr");
    write_exr(&q, 4, 3, |x, y| (x as f32, y as f32, 0.5));
    let img = read_image(&q).unwrap();
    assert_eq!(img.image.pixel(3, 2), Some([3.0, 2.0, 0.5]));
    assert!(!img.alpha_ignored);
}

#[test]
fn test03_size_and_channel_mismatch() {
    let dir = tempfile::tempdir().unwrap();
    let a = dir.path().join("a.exr");
    let b = dir.path().join("b.exr");
    write_exr(&a, 4, 3, |_, _| (1.0, 1.0, 1.0));
    write_exr(&b, 3, 4, |_, _| (1.0, 1.0, 1.0));
    let err = read_pair(&a, &b).unwrap_err();
    assert!(matches!(err, CompareError::SizeMismatch { .. }));
    let msg = err.to_string();
    assert!(
        msg.contains("4×3") && msg.contains("3×4") && msg.contains("a.exr"),
        "{msg}"
    );

    let gray = dir.path().join("gray.png");
    image::GrayImage::from_pixel(4, 3, image::Luma([128]))
        .save(&gray)
        .unwrap();
    let rgb = dir.path().join("rgb.png");
    image::RgbImage::from_pixel(4, 3, image::Rgb([128, 128, 128]))
        .save(&rgb)
        .unwrap();
    let g = read_image(&gray).unwrap();
    assert_eq!(g.channels, ColorChannels::Gray);
    assert_close(
        f64::from(g.image.pixels[0][1]),
        srgb_eotf(128.0 / 255.0),
        1e-7,
        "gray value",
    );
    let err = read_pair(&gray, &rgb).unwrap_err();
    assert!(matches!(err, CompareError::ChannelMismatch { .. }));
    assert!(err.to_string().contains("grayscale"), "{err}");
}

#[test]
fn test04_png_16_bit_and_alpha() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("deep.png");
    let img = image::ImageBuffer::<image::Rgba<u16>, _>::from_fn(2, 1, |x, _| {
        if x == 0 {
            image::Rgba([0, 65535, 32768, 1000])
        } else {
            image::Rgba([1, 2, 3, 65535])
        }
    });
    img.save(&p).unwrap();
    let loaded = read_image(&p).unwrap();
    assert_eq!(loaded.bit_depth, 16);
    assert!(loaded.alpha_ignored);
    let px = loaded.image.pixels[0];
    assert_eq!(px[0], 0.0);
    assert_eq!(px[1], 1.0);
    // 16-bit codes are decoded as v/65535 through the EOTF (not via 8 bits).
    assert_close(
        f64::from(px[2]),
        srgb_eotf(32768.0 / 65535.0),
        1e-7,
        "16-bit mid",
    );
    assert_close(
        f64::from(loaded.image.pixels[1][0]),
        1.0 / 65535.0 / 12.92,
        1e-12,
        "16-bit low",
    );
}

#[test]
fn test05_mask_from_png() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("zero.png");
    image::GrayImage::new(3, 2).save(&p).unwrap();
    assert!(matches!(
        Mask::from_file(&p),
        Err(CompareError::EmptyMask { .. })
    ));
    let q = dir.path().join("one.png");
    let mut m = image::GrayImage::new(3, 2);
    m.put_pixel(2, 1, image::Luma([1]));
    m.save(&q).unwrap();
    let mask = Mask::from_file(&q).unwrap();
    assert_eq!((mask.width(), mask.height(), mask.count()), (3, 2, 1));
    assert!(mask.contains_index(5) && !mask.contains_index(0));
    let committed = Mask::from_file(data("mask.png")).unwrap();
    assert!(committed.count() > 0);
}

#[test]
fn test06_error_picture_colours_and_scale_bar() {
    // Luminance error: pixel 0 exact, pixel 1 error 0.5 (the maximum), 2 and 3 error 0.25.
    let reference = Image::new(4, 1, vec![[0.5; 3]; 4]).unwrap();
    let test = Image::new(4, 1, vec![[0.5; 3], [1.0; 3], [0.25; 3], [0.75; 3]]).unwrap();
    let pic = render_error_picture(&test, &reference, None, &ErrorImageOptions::default()).unwrap();
    assert_eq!(pic.scale_max, 0.5);
    assert_eq!(pic.magnification, 8); // 4 px wide → ×8 (the cap)
    assert!(pic.width >= 256 && pic.height > 8);
    // Published hex values of viridis' ends: #440154 and #fde725.
    assert_eq!(viridis_rgb8(0.0), [0x44, 0x01, 0x54]);
    assert_eq!(viridis_rgb8(1.0), [0xfd, 0xe7, 0x25]);
    let at = |x: usize, y: usize| pic.pixels[y * pic.width + x];
    assert_eq!(at(0, 0), [0x44, 0x01, 0x54]);
    assert_eq!(at(8, 7), [0xfd, 0xe7, 0x25]);
    assert_eq!(at(16, 0), viridis_rgb8(0.5));
    // The colour bar (below the image) starts at the bottom colour and ends at the top one,
    // and at least some label pixels are black.
    let bar_row = 8 + 6 + 7;
    let first = (0..pic.width)
        .find(|&x| at(x, bar_row) != [255; 3])
        .unwrap();
    let last = (0..pic.width)
        .rev()
        .find(|&x| at(x, bar_row) != [255; 3])
        .unwrap();
    assert_eq!(at(first, bar_row), [0x44, 0x01, 0x54]);
    assert_eq!(at(last, bar_row), [0xfd, 0xe7, 0x25]);
    let black = pic.pixels[(bar_row + 14) * pic.width..]
        .iter()
        .filter(|p| **p == [0; 3])
        .count();
    assert!(black > 20, "ticks and labels drawn ({black} black pixels)");

    // Relative, max channel, with a mask that hides pixel 1: scale max from the mask = 0.5
    // (|0.25 − 0.5| / 0.5), and pixel 1 is gray.
    let mask = Mask::from_bools(4, 1, vec![true, false, true, true]).unwrap();
    let opts = ErrorImageOptions {
        measure: ErrorMeasure::Relative,
        channel: ErrorChannel::MaxChannel,
        ..ErrorImageOptions::default()
    };
    let pic = render_error_picture(&test, &reference, Some(&mask), &opts).unwrap();
    assert_eq!(pic.scale_max, 0.5);
    assert_eq!(pic.pixels[8], [128; 3]);
    let bad = ErrorImageOptions {
        scale_max: Some(-1.0),
        ..ErrorImageOptions::default()
    };
    assert!(render_error_picture(&test, &reference, None, &bad).is_err());
}

#[test]
fn test07_error_png_written_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("err.png");
    let (test, reference) = read_pair(data("test.exr"), data("ref.exr")).unwrap();
    let pic = write_error_png(
        &p,
        &test.image,
        &reference.image,
        None,
        &ErrorImageOptions::default(),
    )
    .unwrap();
    let back = image::open(&p).unwrap().into_rgb8();
    assert_eq!(
        (back.width() as usize, back.height() as usize),
        (pic.width, pic.height)
    );
    assert_eq!(back.get_pixel(0, 0).0, pic.pixels[0]);
    // Only the PNG is left in the directory (the temporary file was renamed).
    let names: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names, vec![std::ffi::OsString::from("err.png")]);
    // Writing into a missing directory fails with the path in the message.
    let err = write_png_atomic(&dir.path().join("no/such/dir.png"), 1, 1, &[[0; 3]]).unwrap_err();
    assert!(err.to_string().contains("dir.png"), "{err}");
}
