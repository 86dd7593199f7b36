//! Metrics against scikit-image on the committed pair written by `tools/compare_reference.py`.

mod common;

use common::{assert_close, data, expected};
use prt_compare::{
    compare_with, read_image, read_pair, viridis, ColorChannels, CompareOptions, ErrorStats,
    ImageFormat, Mask, VIRIDIS_STOPS,
};

/// Tolerances: scikit-image works in f64 on the same f32 values, and we accumulate in f64,
/// so the linear metrics agree to summation-order rounding (~1e-15 relative; 1e-12 allowed).
/// The 8-bit views are integers, so `psnr_ldr` agrees to the same rounding.
fn check(actual: &ErrorStats, expected: &serde_json::Value, what: &str) {
    let e = |k: &str| {
        expected[k]
            .as_f64()
            .unwrap_or_else(|| panic!("{what}: {k}"))
    };
    assert_eq!(actual.pixels as f64, e("pixels"), "{what}: pixels");
    for (name, a) in [
        ("psnr_ldr", actual.psnr_ldr),
        ("psnr_hdr", actual.psnr_hdr),
        ("rmse", actual.rmse),
        ("rel_l2", actual.rel_l2),
        ("mae", actual.mae),
        ("max_abs", actual.max_abs),
        ("hdr_peak", actual.hdr_peak),
    ] {
        let x = e(name);
        assert_close(a, x, 1e-12 * x.abs().max(1.0), &format!("{what}: {name}"));
    }
}

#[test]
fn test01_exr_pair_whole_and_masked() {
    let exp = expected();
    let (test, reference) = read_pair(data("test.exr"), data("ref.exr")).unwrap();
    assert_eq!(test.format, ImageFormat::Exr);
    assert_eq!(test.channels, ColorChannels::Rgb);
    assert!(test.alpha_ignored, "test.exr has an A channel");
    assert!(!reference.alpha_ignored);
    assert_eq!(reference.bit_depth, 32);
    assert_eq!(
        (reference.image.width, reference.image.height),
        (
            exp["width"].as_u64().unwrap() as usize,
            exp["height"].as_u64().unwrap() as usize
        )
    );
    let mask = Mask::from_file(data("mask.png")).unwrap();
    assert_eq!(mask.count() as u64, exp["masked_pixels"].as_u64().unwrap());
    let m = compare_with(
        &test.image,
        &reference.image,
        Some(&mask),
        &CompareOptions::default(),
    )
    .unwrap();
    check(&m.whole, &exp["whole"], "whole");
    check(m.masked.as_ref().unwrap(), &exp["masked"], "masked");

    let m = compare_with(
        &test.image,
        &reference.image,
        None,
        &CompareOptions { exposure_ev: 1.5 },
    )
    .unwrap();
    check(&m.whole, &exp["exposure_1_5"], "exposure +1.5 EV");
}

#[test]
fn test02_png_views_decode_by_exact_eotf() {
    let exp = expected();
    let (test, reference) = read_pair(data("test.png"), data("ref.png")).unwrap();
    assert_eq!(test.format, ImageFormat::Png);
    assert_eq!(test.bit_depth, 8);
    let m = compare_with(
        &test.image,
        &reference.image,
        None,
        &CompareOptions::default(),
    )
    .unwrap();
    check(&m.whole, &exp["png"], "png");
    // The PNG view of the EXR equals the PNG bytes, so psnr_ldr is the same either way.
    assert_close(
        m.whole.psnr_ldr,
        exp["whole"]["psnr_ldr"].as_f64().unwrap(),
        1e-12,
        "png psnr_ldr",
    );
    let exr = read_image(data("ref.exr")).unwrap();
    assert_eq!(
        prt_compare::ldr_view(&exr.image, 0.0),
        prt_compare::ldr_view(&reference.image, 0.0)
    );
}

#[test]
fn test03_viridis_against_matplotlib_table() {
    let exp = expected();
    let table: Vec<[f64; 3]> = exp["viridis_table"]
        .as_array()
        .unwrap()
        .iter()
        .map(|c| {
            let c = c.as_array().unwrap();
            [0, 1, 2].map(|k| c[k].as_f64().unwrap())
        })
        .collect();
    assert_eq!(table.len(), 256);
    // Endpoints: the published first and last entries of viridis.
    assert_eq!(viridis(0.0), [0.267004, 0.004874, 0.329415]);
    assert_eq!(viridis(1.0), [0.993248, 0.906157, 0.143936]);
    assert_eq!(viridis(-3.0), viridis(0.0));
    assert_eq!(viridis(f64::NAN), viridis(0.0));
    assert_eq!(viridis(7.0), viridis(1.0));
    // Every stop is exactly the table entry it names.
    for (t, rgb) in VIRIDIS_STOPS {
        let i = (t * 255.0).round() as usize;
        assert_eq!(rgb, table[i], "stop {i}");
    }
    // Between stops, linear interpolation over 8-entry intervals stays within 0.007 of the
    // table: the chord error is about (8²/8)·max|second difference per entry|, and viridis'
    // largest second difference (blue, near the top, 8.4e-4) gives 6.7e-3.
    let mut worst: f64 = 0.0;
    for (i, rgb) in table.iter().enumerate() {
        let v = viridis(i as f64 / 255.0);
        for k in 0..3 {
            worst = worst.max((v[k] - rgb[k]).abs());
        }
    }
    assert!(worst < 0.007, "worst deviation from the table {worst}");
}
