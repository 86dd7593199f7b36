//! `prt report` end to end on a tiny scene (issue 6): every promised output exists, one row is
//! reproduced by hand with `prt relight` and `prt compare`, and a second run reuses the cached
//! bake and gives the same figures.

mod common;

use common::{json, prt, run};
use serde_json::Value;
use std::path::{Path, PathBuf};

fn report(scene: &Path, out: &Path) -> Value {
    report_with(scene, out, &["--orders", "2..4"])
}

/// A quick report (at most 8 spp, 64 rays, 1 timed frame) with extra options; its
/// report.json.
fn report_with(scene: &Path, out: &Path, extra: &[&str]) -> Value {
    run(prt()
        .arg("report")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .args(["--reference-spp", "8", "--rays", "64", "--frames", "1"])
        .args(extra));
    serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap()).unwrap()
}

fn row(data: &Value, order: u64) -> &Value {
    data["orders"]
        .as_array()
        .unwrap()
        .iter()
        .find(|r| r["order"] == order)
        .unwrap_or_else(|| panic!("no row for order {order}"))
}

#[test]
fn report_writes_everything_and_its_figures_are_reproduced_by_hand() {
    let dir = tempfile::tempdir().unwrap();
    let scene = common::write_scene(dir.path(), 3);
    let out = dir.path().join("report");
    let first = report(&scene, &out);

    // Every promised output.
    let mut promised: Vec<String> = [
        "report.md",
        "index.html",
        "report.csv",
        "report.json",
        "error_vs_time.png",
        "psnr_vs_order.png",
        "roi_vs_order.png",
        "images.png",
        "images/reference.exr",
        "images/mask.png",
        "images/roi.png",
        "images/error_adaptive_04.png",
        "error_budget.png",
    ]
    .iter()
    .map(|s| (*s).to_string())
    .collect();
    for o in 2..=4 {
        promised.push(format!("images/full_{o:02}.exr"));
        promised.push(format!("images/adaptive_{o:02}.exr"));
        promised.push(format!("images/full_{o:02}.png"));
        promised.push(format!("images/adaptive_{o:02}.png"));
        promised.push(format!("images/error_full_{o:02}.png"));
    }
    for p in &promised {
        let path = out.join(p);
        let len = std::fs::metadata(&path)
            .unwrap_or_else(|e| panic!("{}: {e}", path.display()))
            .len();
        assert!(len > 0, "{} is empty", path.display());
    }
    for png in [
        "error_vs_time.png",
        "psnr_vs_order.png",
        "roi_vs_order.png",
        "images.png",
    ] {
        let img = image::open(out.join(png)).unwrap();
        assert!(img.width() >= 300 && img.height() >= 200, "{png} too small");
    }
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert_eq!(first["bake_cached"], false);
    // The reference: capped at 8 spp it cannot reach the 45 dB default, and says so.
    let reference = &first["reference"];
    assert_eq!(reference["spp"].as_u64(), Some(8), "{reference}");
    assert_eq!(reference["target_psnr_ldr"].as_f64(), Some(45.0));
    assert_eq!(reference["target_met"], false, "{reference}");
    let ceiling = reference["noise_psnr_ldr"].as_f64().unwrap();
    assert!(
        ceiling.is_finite() && ceiling > 10.0 && ceiling < 45.0,
        "{reference}"
    );
    assert!(md.contains("short of the 45 dB target"), "{md}");
    // The error budget: one row per order, every term present and ≥ 0, the total the
    // measured error of the row, and truncation zero at the highest order.
    let budget = first["error_budget"].as_array().expect("error_budget");
    assert_eq!(budget.len(), 3);
    for b in budget {
        let total = b["total_mse"].as_f64().unwrap();
        assert!(total > 0.0, "{b}");
        let mut sum = 0.0;
        for t in [
            "truncation",
            "interpolation",
            "bake_noise",
            "model",
            "reference_noise",
        ] {
            let v = b["terms"][t]
                .as_f64()
                .unwrap_or_else(|| panic!("{t} in {b}"));
            assert!(v >= 0.0, "{t}: {b}");
            sum += v;
        }
        // The costs add up to the total but for what a negative cost (shown as 0) leaves.
        let unaccounted = b["unaccounted"].as_f64().unwrap();
        assert!(
            (total - sum - unaccounted).abs() <= 1e-12 * total.max(1.0),
            "{b}"
        );
        assert!(unaccounted >= -1e-12 * total, "{b}");
        // The components' own sizes, and what their correlations take.
        let direct: f64 = b["direct"]
            .as_object()
            .unwrap()
            .values()
            .map(|v| v.as_f64().unwrap())
            .sum();
        let cross = b["cross_terms"].as_f64().unwrap();
        assert!(
            (total - direct - cross).abs() <= 1e-12 * total.max(1.0),
            "{b}"
        );
        let largest = b["largest"].as_str().unwrap();
        assert!(
            b["terms"]
                .as_object()
                .unwrap()
                .values()
                .all(|v| v.as_f64().unwrap() <= b["terms"][largest].as_f64().unwrap()),
            "{b}"
        );
    }
    assert_eq!(budget[2]["terms"]["truncation"].as_f64(), Some(0.0));
    // The target-quality column: every order reaches 45 dB against its own full order (0.5 dB
    // of slack for the estimate's 2σ bound), measured on the report's full-order image.
    for r in first["orders"].as_array().unwrap() {
        let t = &r["target"];
        assert_eq!(t["target_psnr"].as_f64(), Some(45.0), "{r}");
        let reached = t["psnr_actual"].as_f64().unwrap_or(f64::INFINITY);
        assert!(reached >= 44.5, "{t}");
    }
    assert!(md.contains("## Target quality"), "{md}");
    assert!(
        md.contains("## Error budget") && md.contains("largest term"),
        "{md}"
    );
    assert_eq!(first["orders"].as_array().unwrap().len(), 3);
    assert!(
        md.contains("| order |") && md.contains("prt relight"),
        "{md}"
    );
    // Per object: back-face hits and rays started inside geometry, in the JSON and the text;
    // every bake ray counted (points × rays).
    let rays = first["bake_rays"].as_array().expect("bake_rays");
    assert!(!rays.is_empty());
    for r in rays {
        assert_eq!(r["rays"].as_u64(), r["points"].as_u64().map(|p| p * 64));
        for k in ["backface_fraction", "inside_fraction"] {
            assert!((0.0..=1.0).contains(&r[k].as_f64().unwrap()), "{k}: {r}");
        }
    }
    assert!(md.contains("rays started inside geometry"), "{md}");
    let csv = std::fs::read_to_string(out.join("report.csv")).unwrap();
    assert!(
        csv.starts_with("order,")
            && csv
                .lines()
                .filter(|l| l.starts_with(['2', '3', '4']))
                .count()
                >= 3
    );
    let html = std::fs::read_to_string(out.join("index.html")).unwrap();
    assert!(html.contains("<table>") && html.contains("images.png"));

    // The bake file is the one report.json names, in DIR/cache.
    let bake = PathBuf::from(first["bake_file"].as_str().unwrap());
    assert!(bake.starts_with(out.join("cache")) && bake.exists());
    let name = bake.file_name().unwrap().to_string_lossy().to_string();
    assert!(
        name.starts_with("bake-") && name.ends_with(".prtb"),
        "{name}"
    );

    // Row 3 by hand: prt relight gives the report's image bit for bit …
    let mine = dir.path().join("mine_03.exr");
    run(prt()
        .arg("relight")
        .arg(&scene)
        .arg("--bake")
        .arg(&bake)
        .args(["--order", "3", "--out"])
        .arg(&mine));
    let same = json(&run(prt()
        .arg("compare")
        .arg(&mine)
        .arg(out.join("images/full_03.exr"))
        .arg("--json")));
    assert_eq!(same["max_abs"].as_f64(), Some(0.0), "{same}");
    // … and prt compare against the reference with the report's mask gives its PSNR.
    let m = json(&run(prt()
        .arg("compare")
        .arg(&mine)
        .arg(out.join("images/reference.exr"))
        .arg("--mask")
        .arg(out.join("images/mask.png"))
        .arg("--json")));
    let r3 = row(&first, 3);
    for (cli, rep) in [
        ("masked_psnr_ldr", "psnr_full_vs_reference"),
        ("masked_rel_l2", "rel_l2_full"),
    ] {
        let (a, b) = (m[cli].as_f64().unwrap(), r3[rep].as_f64().unwrap());
        assert!(
            (a - b).abs() <= 1e-9 * b.abs().max(1.0),
            "{cli} {a} vs report {rep} {b}"
        );
    }
    // The adaptive column the same way.
    let mine_ad = dir.path().join("mine_ad_03.exr");
    let threshold = first["settings"]["threshold"].as_f64().unwrap().to_string();
    run(prt()
        .arg("relight")
        .arg(&scene)
        .arg("--bake")
        .arg(&bake)
        .args([
            "--order",
            "3",
            "--adaptive",
            "--threshold",
            &threshold,
            "--out",
        ])
        .arg(&mine_ad));
    let same = json(&run(prt()
        .arg("compare")
        .arg(&mine_ad)
        .arg(out.join("images/adaptive_03.exr"))
        .arg("--json")));
    assert_eq!(same["max_abs"].as_f64(), Some(0.0), "{same}");

    // A second run reuses the bake and reproduces every figure but the times.
    let second = report(&scene, &out);
    assert_eq!(second["bake_cached"], true);
    assert_eq!(second["bake_file"], first["bake_file"]);
    assert_eq!(second["bake_seconds"].as_f64(), Some(0.0));
    assert_eq!(second["reference"]["cached"], true);
    let strip = |v: &Value| -> Value {
        let mut v = v.clone();
        let obj = v.as_object_mut().unwrap();
        for k in ["bake_seconds", "bake_cached"] {
            obj.remove(k);
        }
        obj["reference"].as_object_mut().unwrap().remove("cached");
        // What else ran on the machine while timing differs from run to run.
        obj["machine"]
            .as_object_mut()
            .unwrap()
            .remove("timing_load");
        for r in obj["orders"].as_array_mut().unwrap() {
            let r = r.as_object_mut().unwrap();
            for k in [
                "full_ms",
                "adaptive_ms",
                "speedup",
                "full_ms_range",
                "adaptive_ms_range",
            ] {
                r.remove(k);
            }
            if let Some(t) = r.get_mut("target").and_then(Value::as_object_mut) {
                t.remove("ms");
                t.remove("speedup");
            }
        }
        for c in obj["convergence"].as_array_mut().unwrap() {
            c.as_object_mut().unwrap().remove("ms");
        }
        v
    };
    assert_eq!(strip(&first), strip(&second));

    // The threshold on the display: the report says so, and prt relight with the same options
    // reproduces its adaptive image at order 4 (where bands are filtered) bit for bit.
    let out2 = dir.path().join("report_display");
    let third = report_with(
        &scene,
        &out2,
        &[
            "--orders",
            "4",
            "--display-threshold",
            "--threshold",
            "0.05",
        ],
    );
    assert!(
        third["settings"]["threshold_kind"]
            .as_str()
            .unwrap()
            .starts_with("display"),
        "{}",
        third["settings"]
    );
    let bake2 = PathBuf::from(third["bake_file"].as_str().unwrap());
    let mine_d = dir.path().join("mine_display_04.exr");
    run(prt()
        .arg("relight")
        .arg(&scene)
        .arg("--bake")
        .arg(&bake2)
        .args([
            "--order",
            "4",
            "--adaptive",
            "--display-threshold",
            "--threshold",
            "0.05",
            "--out",
        ])
        .arg(&mine_d));
    let same = json(&run(prt()
        .arg("compare")
        .arg(&mine_d)
        .arg(out2.join("images/adaptive_04.exr"))
        .arg("--json")));
    assert_eq!(same["max_abs"].as_f64(), Some(0.0), "{same}");
    let md = std::fs::read_to_string(out2.join("report.md")).unwrap();
    assert!(md.contains("--display-threshold"), "{md}");
}
