//! `prt compare ...` end to end: JSON keys and values (against the scikit-image numbers of
//! `crates/compare/tests/data/expected.json`), the table, the error image, and clear errors
//! with a non-zero exit for bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn prt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_prt"))
        .arg("compare")
        .args(args)
        .output()
        .expect("run prt")
}

fn data(name: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../compare/tests/data")
        .join(name)
        .to_str()
        .unwrap()
        .to_owned()
}

fn expected() -> serde_json::Value {
    serde_json::from_str(&std::fs::read_to_string(data("expected.json")).unwrap()).unwrap()
}

fn json_of(out: &Output) -> serde_json::Map<String, serde_json::Value> {
    assert!(
        out.status.success(),
        "stderr: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout.clone()).unwrap();
    // Exactly one JSON object on stdout.
    assert_eq!(text.trim().lines().count(), 1, "{text}");
    match serde_json::from_str(&text).unwrap() {
        serde_json::Value::Object(m) => m,
        other => panic!("not an object: {other}"),
    }
}

fn close(a: &serde_json::Value, b: &serde_json::Value, what: &str) {
    let (a, b) = (a.as_f64().unwrap(), b.as_f64().unwrap());
    assert!(
        (a - b).abs() <= 1e-12 * b.abs().max(1.0),
        "{what}: {a} vs {b}"
    );
}

fn write_exr(
    path: &PathBuf,
    w: usize,
    h: usize,
    f: impl Fn(usize, usize) -> (f32, f32, f32) + Sync,
) {
    exr::prelude::write_rgb_file(path, w, h, f).unwrap();
}

const METRICS: [&str; 6] = ["psnr_ldr", "psnr_hdr", "rmse", "rel_l2", "mae", "max_abs"];

#[test]
fn test01_json_with_mask_has_all_keys_and_reference_values() {
    let out = prt(&[
        &data("test.exr"),
        &data("ref.exr"),
        "--mask",
        &data("mask.png"),
        "--json",
    ]);
    let j = json_of(&out);
    let exp = expected();
    for k in METRICS {
        close(&j[k], &exp["whole"][k], k);
        close(&j[&format!("masked_{k}")], &exp["masked"][k], k);
    }
    assert_eq!(j["width"], 32);
    assert_eq!(j["height"], 24);
    assert_eq!(j["pixels"], 768);
    assert_eq!(j["masked_pixels"], exp["masked_pixels"]);
    assert!(!j.contains_key("noise_rmse"));
    // The ignored alpha of test.exr is reported on stderr, not in the JSON.
    assert!(String::from_utf8_lossy(&out.stderr).contains("alpha"));
}

#[test]
fn test02_json_without_mask_and_exposure() {
    let j = json_of(&prt(&[
        &data("test.exr"),
        &data("ref.exr"),
        "--json",
        "--exposure",
        "1.5",
    ]));
    let exp = expected();
    for k in METRICS {
        close(&j[k], &exp["exposure_1_5"][k], k);
        assert!(!j.contains_key(&format!("masked_{k}")));
    }
    assert!(!j.contains_key("masked_pixels"));
}

#[test]
fn test03_identical_images_give_null_psnr() {
    let j = json_of(&prt(&[&data("ref.exr"), &data("ref.exr"), "--json"]));
    assert!(j["psnr_ldr"].is_null() && j["psnr_hdr"].is_null());
    assert_eq!(j["rmse"], 0.0);
}

#[test]
fn test04_noise_pair_and_variance() {
    let dir = tempfile::tempdir().unwrap();
    // Reference B = 1 everywhere, second render C = 1.2: ‖B − C‖²/(2N) = 0.02, so
    // noise_rmse = sqrt(0.02), of the mean 0.1. Test A = 1.1: rmse 0.1.
    let (a, b, c, v) = (
        dir.path().join("a.exr"),
        dir.path().join("b.exr"),
        dir.path().join("c.exr"),
        dir.path().join("v.exr"),
    );
    write_exr(&a, 3, 2, |_, _| (1.1, 1.1, 1.1));
    write_exr(&b, 3, 2, |_, _| (1.0, 1.0, 1.0));
    write_exr(&c, 3, 2, |_, _| (1.2, 1.2, 1.2));
    write_exr(&v, 3, 2, |_, _| (0.0025, 0.0025, 0.0025));
    let s = |p: &PathBuf| p.to_str().unwrap().to_owned();
    let j = json_of(&prt(&[&s(&a), &s(&b), "--noise-pair", &s(&c), "--json"]));
    assert_eq!(j["noise_method"], "pair");
    let f = |k: &str| j[k].as_f64().unwrap();
    let tol = 1e-6; // the f32 values 1.1, 1.2 are ~2e-8 off
    assert!((f("noise_rmse") - 0.02f64.sqrt()).abs() < tol);
    assert!((f("noise_rmse_of_mean") - 0.1).abs() < tol);
    assert!((f("noise_psnr_hdr_ceiling") - 10.0 * (1.0 / 0.02f64).log10()).abs() < 1e-4);
    assert!(j.contains_key("noise_psnr_ldr_ceiling"));
    // rmse 0.1 < noise rmse 0.141: the error is within the noise, corrected rmse 0.
    assert_eq!(f("noise_corrected_rmse"), 0.0);

    let j = json_of(&prt(&[&s(&a), &s(&b), "--variance", &s(&v), "--json"]));
    assert_eq!(j["noise_method"], "variance");
    assert!((j["noise_rmse"].as_f64().unwrap() - 0.05).abs() < 1e-8);
    // sqrt(0.1² − 0.05²)
    assert!((j["noise_corrected_rmse"].as_f64().unwrap() - 0.0075f64.sqrt()).abs() < 1e-6);

    // Both at once is a usage error.
    let out = prt(&[&s(&a), &s(&b), "--variance", &s(&v), "--noise-pair", &s(&c)]);
    assert!(!out.status.success());
}

#[test]
fn test05_table_and_error_png() {
    let dir = tempfile::tempdir().unwrap();
    let e = dir.path().join("err.png");
    let out = prt(&[
        &data("test.exr"),
        &data("ref.exr"),
        "--mask",
        &data("mask.png"),
        "--error-png",
        e.to_str().unwrap(),
        "--error-measure",
        "rel",
        "--error-channel",
        "max",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let text = String::from_utf8(out.stdout).unwrap();
    for word in [
        "psnr_ldr",
        "psnr_hdr",
        "rmse",
        "rel_l2",
        "mae",
        "max_abs",
        "whole image",
        "mask",
    ] {
        assert!(text.contains(word), "{word} missing from\n{text}");
    }
    let img = image::open(&e).unwrap();
    assert_eq!(img.width(), 256); // 32 px × 8
}

#[test]
fn test06_bad_input_exits_non_zero_with_clear_message() {
    let dir = tempfile::tempdir().unwrap();
    let err_of = |args: &[&str]| {
        let out = prt(args);
        assert!(!out.status.success(), "should fail: {args:?}");
        assert!(out.stdout.is_empty(), "nothing on stdout on failure");
        String::from_utf8(out.stderr).unwrap()
    };
    let missing = dir.path().join("missing.exr");
    let msg = err_of(&[missing.to_str().unwrap(), &data("ref.exr"), "--json"]);
    assert!(
        msg.contains("missing.exr") && msg.contains("no such file"),
        "{msg}"
    );

    let small = dir.path().join("small.exr");
    write_exr(&small, 4, 4, |_, _| (1.0, 1.0, 1.0));
    let msg = err_of(&[small.to_str().unwrap(), &data("ref.exr")]);
    assert!(
        msg.contains("size mismatch") && msg.contains("4×4") && msg.contains("32×24"),
        "{msg}"
    );

    let nan = dir.path().join("nan.exr");
    write_exr(&nan, 32, 24, |x, y| {
        if (x, y) == (5, 7) {
            (f32::NAN, 0.0, 0.0)
        } else {
            (1.0, 1.0, 1.0)
        }
    });
    let msg = err_of(&[nan.to_str().unwrap(), &data("ref.exr")]);
    assert!(
        msg.contains("x = 5, y = 7") && msg.contains("nan.exr"),
        "{msg}"
    );

    let empty_mask = dir.path().join("empty_mask.png");
    image::GrayImage::new(32, 24).save(&empty_mask).unwrap();
    let msg = err_of(&[
        &data("test.exr"),
        &data("ref.exr"),
        "--mask",
        empty_mask.to_str().unwrap(),
    ]);
    assert!(msg.contains("selects no pixel"), "{msg}");

    let wrong_mask = dir.path().join("wrong_mask.png");
    image::GrayImage::from_pixel(8, 8, image::Luma([255]))
        .save(&wrong_mask)
        .unwrap();
    let msg = err_of(&[
        &data("test.exr"),
        &data("ref.exr"),
        "--mask",
        wrong_mask.to_str().unwrap(),
    ]);
    assert!(msg.contains("size mismatch"), "{msg}");

    let gray = dir.path().join("gray.png");
    image::GrayImage::new(32, 24).save(&gray).unwrap();
    let msg = err_of(&[gray.to_str().unwrap(), &data("ref.png")]);
    assert!(msg.contains("grayscale"), "{msg}");

    let text = dir.path().join("text.exr");
    std::fs::write(&text, "not an image").unwrap();
    let msg = err_of(&[text.to_str().unwrap(), &data("ref.exr")]);
    assert!(msg.contains("not an image"), "{msg}");
}
