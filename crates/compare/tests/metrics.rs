//! Metrics against hand-computed values on tiny images.

mod common;

use common::assert_close;
use prt_compare::{
    compare, compare_with, ldr_value, srgb_eotf, srgb_oetf, CompareError, CompareOptions, Image,
    ImageError, Mask,
};

fn gray(v: f32) -> [f32; 3] {
    [v, v, v]
}

/// 2×2 reference and test. Linear differences: pixel 0: 0; pixel 1: (0.1, 0.1, 0.1);
/// pixel 2: (−0.5, 0, 0); pixel 3: (0, 0, 0.25).
fn pair_2x2() -> (Image, Image) {
    let reference = Image::new(
        2,
        2,
        vec![gray(0.0), gray(0.5), [1.0, 0.25, 0.25], [2.0, 1.0, 0.75]],
    )
    .unwrap();
    let test = Image::new(
        2,
        2,
        vec![gray(0.0), gray(0.6), [0.5, 0.25, 0.25], [2.0, 1.0, 1.0]],
    )
    .unwrap();
    (test, reference)
}

#[test]
fn test01_linear_metrics_2x2() {
    let (test, reference) = pair_2x2();
    let m = compare(&test, &reference, None).unwrap();
    // Σd² = 3·0.01 + 0.25 + 0.0625 = 0.3425 over N = 12 values (in f32 the 0.6−0.5 difference
    // is 0.1 to ~1e-8, hence the tolerances).
    let sum_sq = 3.0 * 0.01 + 0.25 + 0.0625;
    let mse: f64 = sum_sq / 12.0;
    assert_eq!(m.whole.pixels, 4);
    assert_close(m.whole.rmse, mse.sqrt(), 1e-7, "rmse");
    // Σb² = 3·0.25 + (1 + 2·0.0625) + (4 + 1 + 0.5625) = 7.4375
    assert_close(m.whole.rel_l2, (sum_sq / 7.4375f64).sqrt(), 1e-7, "rel_l2");
    assert_close(m.whole.mae, (0.3 + 0.5 + 0.25) / 12.0, 1e-7, "mae");
    assert_close(m.whole.max_abs, 0.5, 0.0, "max_abs");
    assert_eq!(m.whole.hdr_peak, 2.0);
    assert_close(
        m.whole.psnr_hdr,
        10.0 * (4.0 / mse).log10(),
        1e-5,
        "psnr_hdr",
    );
}

#[test]
fn test02_ldr_psnr_2x2_exact() {
    let (test, reference) = pair_2x2();
    // 8-bit views by hand (sRGB OETF, ×255, rounded):
    // 0 → 0; 0.5 → 1.055·0.5^(1/2.4) − 0.055 = 0.735357 → 187.52 → 188;
    // 0.6 → 0.797738 → 203.42 → 203; 1 and 2 → 255; 0.25 → 0.537099 → 136.96 → 137;
    // 0.75 → 0.880825 → 224.61 → 225.
    let eight = |v: f64| (srgb_oetf(v) * 255.0).round();
    assert_eq!(eight(0.5), 188.0);
    assert_eq!(eight(0.6), 203.0);
    assert_eq!(eight(0.25), 137.0);
    assert_eq!(eight(0.75), 225.0);
    // Differences: pixel 1: 3 × (203 − 188) = 15; pixel 2: R 188 − 255 = −67; pixel 3: B
    // 255 − 225 = 30. MSE₈ = (3·225 + 4489 + 900) / 12 = 6064 / 12.
    let mse8 = 6064.0 / 12.0;
    let m = compare(&test, &reference, None).unwrap();
    assert_eq!(m.whole.mse_ldr, mse8);
    assert_close(
        m.whole.psnr_ldr,
        10.0 * (255.0f64 * 255.0 / mse8).log10(),
        1e-12,
        "psnr_ldr",
    );
}

#[test]
fn test03_mask_2x2() {
    let (test, reference) = pair_2x2();
    // Pixels 1 and 3 only.
    let mask = Mask::from_bools(2, 2, vec![false, true, false, true]).unwrap();
    let m = compare(&test, &reference, Some(&mask)).unwrap();
    let s = m.masked.unwrap();
    assert_eq!(s.pixels, 2);
    let sum_sq = 0.03 + 0.0625;
    assert_close(s.rmse, (sum_sq / 6.0f64).sqrt(), 1e-7, "masked rmse");
    // Σb² over pixels 1, 3 = 0.75 + 5.5625
    assert_close(s.rel_l2, (sum_sq / 6.3125f64).sqrt(), 1e-7, "masked rel_l2");
    assert_close(s.max_abs, 0.25, 0.0, "masked max_abs");
    assert_eq!(s.hdr_peak, 2.0);
    assert_close(s.mse_ldr, (675.0 + 900.0) / 6.0, 0.0, "masked mse_ldr");
    // The whole-image numbers are unchanged by the mask.
    assert_eq!(m.whole, compare(&test, &reference, None).unwrap().whole);

    // Masking pixel 2 alone: peak of the masked reference is 1 (not the image's 2).
    let mask = Mask::from_bools(2, 2, vec![false, false, true, false]).unwrap();
    let s = compare(&test, &reference, Some(&mask))
        .unwrap()
        .masked
        .unwrap();
    assert_eq!(s.hdr_peak, 1.0);
    assert_close(
        s.psnr_hdr,
        10.0 * (1.0 / (0.25 / 3.0f64)).log10(),
        1e-9,
        "masked psnr_hdr",
    );
}

#[test]
fn test04_identical_images_infinite_psnr_and_json_null() {
    let (_, reference) = pair_2x2();
    let m = compare(&reference, &reference, None).unwrap();
    assert_eq!(m.whole.psnr_ldr, f64::INFINITY);
    assert_eq!(m.whole.psnr_hdr, f64::INFINITY);
    assert_eq!(
        (m.whole.rmse, m.whole.rel_l2, m.whole.mae, m.whole.max_abs),
        (0.0, 0.0, 0.0, 0.0)
    );
    let json = prt_compare::report_json(&m, None);
    assert!(json["psnr_ldr"].is_null() && json["psnr_hdr"].is_null());
    assert_eq!(json["rmse"], 0.0);
    // A valid JSON document (no "inf" token).
    let text = serde_json::to_string(&json).unwrap();
    assert!(serde_json::from_str::<serde_json::Value>(&text).is_ok());
}

#[test]
fn test05_black_reference() {
    let black = Image::new(1, 1, vec![gray(0.0)]).unwrap();
    let grey = Image::new(1, 1, vec![gray(0.5)]).unwrap();
    let m = compare(&grey, &black, None).unwrap();
    assert!(m.whole.psnr_hdr.is_nan(), "peak 0: undefined");
    assert_eq!(m.whole.rel_l2, f64::INFINITY);
    assert!(prt_compare::report_json(&m, None)["rel_l2"].is_null());
}

#[test]
fn test06_exposure_option() {
    // With +1 EV, 0.25 is shown as 0.5 (188) and 0.5 as 1.0 (255).
    let a = Image::new(1, 1, vec![gray(0.25)]).unwrap();
    let b = Image::new(1, 1, vec![gray(0.5)]).unwrap();
    let m = compare_with(&a, &b, None, &CompareOptions { exposure_ev: 1.0 }).unwrap();
    assert_eq!(m.whole.mse_ldr, 67.0 * 67.0);
    assert!(compare_with(
        &a,
        &b,
        None,
        &CompareOptions {
            exposure_ev: f64::NAN
        }
    )
    .is_err());
}

#[test]
fn test07_srgb_curves() {
    // Published breakpoints and values of IEC 61966-2-1.
    assert_eq!(srgb_eotf(0.0), 0.0);
    assert_close(srgb_eotf(1.0), 1.0, 1e-15, "eotf(1)");
    assert_close(srgb_eotf(0.04045), 0.04045 / 12.92, 0.0, "eotf breakpoint");
    assert_close(srgb_eotf(0.5), 0.214_041_140_482_232_5, 1e-15, "eotf(0.5)");
    for k in 0..=255u8 {
        // Every 8-bit code survives decode → view exactly (round trip of the PNG view).
        let lin = srgb_eotf(f64::from(k) / 255.0) as f32;
        assert_eq!(ldr_value(lin, 0.0), k, "code {k}");
    }
    assert_eq!(ldr_value(-1.0, 0.0), 0);
    assert_eq!(ldr_value(7.0, 0.0), 255);
}

#[test]
fn test08_errors() {
    let a = Image::new(2, 2, vec![gray(0.5); 4]).unwrap();
    let b = Image::new(2, 1, vec![gray(0.5); 2]).unwrap();
    assert!(matches!(
        compare(&a, &b, None),
        Err(CompareError::SizeMismatch { .. })
    ));
    let mut nan = a.clone();
    nan.pixels[3][1] = f32::NAN;
    let err = compare(&nan, &a, None).unwrap_err();
    match &err {
        CompareError::Image(ImageError::NonFinite { x, y, channel, .. }) => {
            assert_eq!((*x, *y, *channel), (1, 1, 'G'))
        }
        other => panic!("unexpected {other:?}"),
    }
    assert!(err.to_string().contains("x = 1, y = 1"), "{err}");
    let mut inf = a.clone();
    inf.pixels[0][2] = f32::INFINITY;
    assert!(matches!(
        compare(&a, &inf, None),
        Err(CompareError::Image(ImageError::NonFinite {
            x: 0,
            y: 0,
            channel: 'B',
            ..
        }))
    ));

    assert!(matches!(
        Mask::from_bools(2, 2, vec![false; 4]),
        Err(CompareError::EmptyMask { .. })
    ));
    assert!(matches!(
        Mask::from_bools(2, 2, vec![true; 3]),
        Err(CompareError::PixelCount { .. })
    ));
    let small = Mask::from_bools(1, 2, vec![true; 2]).unwrap();
    assert!(matches!(
        compare(&a, &a, Some(&small)),
        Err(CompareError::SizeMismatch { .. })
    ));
    assert!(Image::new(2, 2, vec![gray(0.0); 3]).is_err());
    let empty = Image::new(0, 0, vec![]).unwrap();
    assert!(matches!(
        compare(&empty, &empty, None),
        Err(CompareError::Image(ImageError::EmptyImage { .. }))
    ));
    // A hand-built image with an inconsistent pixel count is rejected, not indexed out of range.
    let bad = Image {
        width: 3,
        height: 3,
        pixels: vec![gray(0.0); 4],
    };
    assert!(compare(&bad, &bad, None).is_err());
}
