//! `prt report --reflectance` (issue 16's report section) end to end on the tiny "L" scene under
//! a map with a sun texel: every promised output exists; the compressed relighting that keeps
//! every coefficient is the uncompressed one; the series' rows (ranked once per wavelet) are
//! what `prt relight --wavelet W --coefficients K` gives by hand, image and `rf_rel_l2`; a
//! second run reuses the cached field and reproduces every figure.

mod common;

use common::{json, prt, run};
use serde_json::Value;
use std::path::Path;

const FINE: &str = "32x16";
/// Every coefficient of the 32 × 16 fine grid.
const ALL: u64 = 512;

fn report(scene: &Path, out: &Path) -> Value {
    run(prt()
        .arg("report")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .args([
            "--orders",
            "2,3",
            "--reference-spp",
            "16",
            "--reference-psnr",
            "0",
        ])
        .args([
            "--rays",
            "32",
            "--frames",
            "1",
            "--no-budget",
            "--target-psnr",
            "0",
        ])
        .args(["--bounces", "0", "--reflectance", "16x8", "--rf-fine", FINE])
        .args(["--rf-coefficients", "16,512", "--rf-frames", "4"])
        .args(["--rf-pixel-samples", "4", "--rf-error-pixels", "100000"]));
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

fn compressed<'a>(rf: &'a Value, wavelet: &str, k: u64) -> &'a Value {
    rf["compressed"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["wavelet"] == wavelet && r["coefficients"] == k)
        .unwrap_or_else(|| panic!("no {wavelet} row at K = {k}: {rf}"))
}

/// `prt compare A B --json`'s largest absolute difference.
fn max_abs(a: &Path, b: &Path) -> f64 {
    json(&run(prt().arg("compare").arg(a).arg(b).arg("--json")))["max_abs"]
        .as_f64()
        .expect("max_abs is a number")
}

#[test]
fn the_reflectance_section_is_complete_and_reproduced_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::write_scene(dir.path(), 3);
    let out = dir.path().join("report");
    let first = report(&scene, &out);
    let rf = &first["reflectance"];
    assert_eq!(rf["field_cached"], false, "{rf}");

    // Every promised output.
    for p in [
        "rf_psnr_vs_coefficients.png",
        "rf_error_vs_coefficients.png",
        "rf_h1_vs_coefficients.png",
        "rf_images.png",
        "images/rf_nearest.exr",
        "images/rf_bspline.png",
        "images/rf_cdf97_16.exr",
        "images/rf_haar_512.exr",
        "images/rf_sh_04.exr",
        "images/rf_sh_22.exr",
        "images/rf_sh_fit_04.exr",
    ] {
        let len = std::fs::metadata(out.join(p))
            .unwrap_or_else(|e| panic!("{p}: {e}"))
            .len();
        assert!(len > 0, "{p} is empty");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(md.contains("## Reflectance fields"), "{md}");
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(
        html.contains("rf_cdf97_16"),
        "the viewer lists the field images"
    );

    // One row per reconstruction, each with a finite PSNR and a flicker figure.
    let methods: Vec<&str> = rf["reconstructions"]
        .as_array()
        .unwrap()
        .iter()
        .map(|r| {
            assert!(r["psnr_ldr"].as_f64().unwrap().is_finite(), "{r}");
            assert!(r["flicker"].as_f64().unwrap() >= 0.0, "{r}");
            r["method"].as_str().unwrap()
        })
        .collect();
    assert_eq!(
        methods,
        [
            "nearest",
            "linear",
            "legall53",
            "cdf97",
            "idw",
            "biquadric",
            "sh25",
            "bspline"
        ]
    );
    let linear = &rf["reconstructions"][1];
    // SH fitted to the 16 × 8 samples: order 4 fits (W ≥ 7, H ≥ 4), order 22 cannot.
    let fit = rf["sh_fit"].as_array().unwrap();
    assert_eq!(fit.len(), 1, "{rf}");
    assert_eq!(fit[0]["order"], 4);
    assert!(
        rf["notes"][0].as_str().unwrap().contains("order 22"),
        "{rf}"
    );
    let k = rf["sh"].as_array().unwrap();
    assert_eq!(k.len(), 2, "SH orders 4 and 22 (⌊√512⌋): {rf}");
    assert_eq!(k[1]["order"], 22);

    for w in ["haar", "legall53", "cdf97"] {
        // Keeping all 512 coefficients is no compression: the functions come back to rounding
        // (f32 coefficients: relative 1e-6 per value) and so does the image.
        let all = compressed(rf, w, ALL);
        assert!(all["rf_rel_l2"].as_f64().unwrap() < 1e-5, "{all}");
        let (a, b) = (
            all["psnr_ldr"].as_f64().unwrap(),
            linear["psnr_ldr"].as_f64().unwrap(),
        );
        assert!((a - b).abs() < 0.05, "{w}: {a} vs uncompressed {b}");
        // Sixteen coefficients lose something, and the curve falls from 16 to the whole grid.
        let few = compressed(rf, w, 16);
        assert!(few["rf_rel_l2"].as_f64().unwrap() > 1e-3, "{few}");
        let curve: Vec<f64> = rf["error_curve"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|p| p["wavelet"] == w)
            .map(|p| p["rf_rel_l2"].as_f64().unwrap())
            .collect();
        assert_eq!(curve.len(), 6, "K = 16 … 512: {curve:?}");
        assert!(curve[0] > curve[5] && curve[5] < 1e-5, "{w}: {curve:?}");
    }
    // Haar is orthogonal: keeping more of the largest coefficients never increases the error.
    let haar: Vec<f64> = rf["error_curve"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["wavelet"] == "haar")
        .map(|p| p["rf_rel_l2"].as_f64().unwrap())
        .collect();
    assert!(haar.windows(2).all(|p| p[1] <= p[0] + 1e-12), "{haar:?}");

    // A row by hand: the field file, relit by `prt relight` with one wavelet and K.
    let field = rf["field_file"].as_str().unwrap();
    let by_hand = dir.path().join("cdf97_16.exr");
    let j = json(&run(prt()
        .arg("relight")
        .arg(&scene)
        .args(["--bake", field, "--reconstruct", "linear", "--fine", FINE])
        .args([
            "--wavelet",
            "cdf97",
            "--coefficients",
            "16",
            "--json",
            "--out",
        ])
        .arg(&by_hand)));
    let row = compressed(rf, "cdf97", 16);
    let (a, b) = (
        j["rf_rel_l2"].as_f64().unwrap(),
        row["rf_rel_l2"].as_f64().unwrap(),
    );
    assert!(
        (a - b).abs() <= 1e-9 * b,
        "rf_rel_l2 {a} by hand, {b} in the report"
    );
    assert_eq!(
        max_abs(&by_hand, &out.join("images/rf_cdf97_16.exr")),
        0.0,
        "the report's image is prt relight's"
    );
    // --rf-error-pixels: the error over a subsample, the same coefficients and image.
    let sub = dir.path().join("cdf97_16_sub.exr");
    let js = json(&run(prt()
        .arg("relight")
        .arg(&scene)
        .args(["--bake", field, "--reconstruct", "linear", "--fine", FINE])
        .args(["--wavelet", "cdf97", "--coefficients", "16"])
        .args(["--rf-error-pixels", "5", "--json", "--out"])
        .arg(&sub)));
    let (measured, all) = (
        js["rf_error_pixels"].as_u64().unwrap(),
        j["rf_error_pixels"].as_u64().unwrap(),
    );
    assert!(measured <= 5 && measured < all, "{measured} of {all}");
    assert!(js["rf_rel_l2"].as_f64().unwrap() > 0.0);
    assert_eq!(
        max_abs(&sub, &by_hand),
        0.0,
        "the subsample changes only the measurement"
    );
    common::refused(
        prt()
            .arg("relight")
            .arg(&scene)
            .args([
                "--bake",
                field,
                "--wavelet",
                "cdf97",
                "--coefficients",
                "16",
            ])
            .args(["--rf-error-pixels", "0"]),
        "--rf-error-pixels 0",
    );

    // A second run: the field from the cache, the same figures.
    let second = report(&scene, &out);
    let rf2 = &second["reflectance"];
    assert_eq!(rf2["field_cached"], true);
    for (a, b) in rf["compressed"]
        .as_array()
        .unwrap()
        .iter()
        .zip(rf2["compressed"].as_array().unwrap())
    {
        assert_eq!(a["psnr_ldr"], b["psnr_ldr"]);
        assert_eq!(a["rf_rel_l2"], b["rf_rel_l2"]);
    }
}

#[test]
fn impossible_reflectance_options_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::write_scene(dir.path(), 2);
    let base = |extra: &[&str]| {
        let mut c = prt();
        c.arg("report")
            .arg(&scene)
            .arg("--out")
            .arg(dir.path().join("r"))
            .args([
                "--orders",
                "2",
                "--reference-spp",
                "2",
                "--reference-psnr",
                "0",
            ])
            .args(["--rays", "8", "--no-budget", "--target-psnr", "0"])
            .args(extra);
        c
    };
    common::refused(&mut base(&["--reflectance", "16"]), "WxH");
    common::refused(
        &mut base(&["--reflectance", "16x8", "--rf-coefficients", "0"]),
        "--rf-coefficients",
    );
    common::refused(
        &mut base(&["--reflectance", "16x8", "--rf-frames", "2"]),
        "at least 3 frames",
    );
    // (Without --reflectance the --rf-* options mean nothing.)
    common::refused(&mut base(&["--rf-frames", "4"]), "--reflectance");
}
