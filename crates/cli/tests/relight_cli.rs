//! `prt relight`: its JSON, the bake check, bit-equality of `--adaptive --threshold 0` with full
//! order, the ROI picture, rotating-environment frames, and bad options.

mod common;

use common::{json, prt, run, write_scene};
use std::path::Path;
use std::process::Command;

fn fail(cmd: &mut Command) -> String {
    let out = cmd.output().unwrap();
    assert!(!out.status.success(), "{cmd:?} should fail");
    String::from_utf8_lossy(&out.stderr).into_owned()
}

fn bake(scene: &Path, out: &Path, extra: &[&str]) {
    run(prt()
        .arg("bake")
        .arg(scene)
        .args(["--order", "5", "--rays", "64"])
        .args(extra)
        .arg("--out")
        .arg(out));
}

fn relight(scene: &Path, bake: &Path) -> Command {
    let mut c = prt();
    c.arg("relight").arg(scene).arg("--bake").arg(bake);
    c
}

#[test]
fn relight_json_bake_check_exactness_roi_and_frames() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let b = dir.path().join("scene.prtb");
    bake(&scene, &b, &[]);

    // JSON keys, full order.
    let full = dir.path().join("full.exr");
    let j = json(&run(relight(&scene, &b)
        .args(["--order", "4", "--json", "--out"])
        .arg(&full)));
    for k in [
        "order",
        "adaptive",
        "threshold",
        "shade_ms",
        "image_ms",
        "roi_fraction_diffuse",
        "roi_fraction_specular",
    ] {
        assert!(j.get(k).is_some(), "missing {k} in {j}");
    }
    assert_eq!(j["order"], 4);
    assert_eq!(j["adaptive"], false);
    assert!(j["threshold"].is_null() && j["roi_fraction_diffuse"].is_null());
    assert!(j["shade_ms"].as_f64().unwrap() >= 0.0 && j["image_ms"].as_f64().unwrap() > 0.0);
    // The order is capped at the baked one.
    let j = json(&run(relight(&scene, &b).args(["--order", "9", "--json"])));
    assert_eq!(j["order"], 5);

    // Adaptive with T = 0 keeps every band everywhere: the same image bit for bit; the ROI
    // picture is written.
    let exact = dir.path().join("exact.exr");
    let roi = dir.path().join("roi.png");
    let j = json(&run(relight(&scene, &b)
        .args([
            "--order",
            "4",
            "--adaptive",
            "--threshold",
            "0",
            "--json",
            "--out",
        ])
        .arg(&exact)
        .arg("--roi-png")
        .arg(&roi)));
    assert_eq!(j["adaptive"], true);
    assert_eq!(j["threshold"].as_f64(), Some(0.0));
    let (rd, rs) = (
        j["roi_fraction_diffuse"].as_f64().unwrap(),
        j["roi_fraction_specular"].as_f64().unwrap(),
    );
    assert!(
        (0.0..=1.0).contains(&rd) && (0.0..=1.0).contains(&rs),
        "{j}"
    );
    let read = |p: &Path| {
        exr::prelude::read_all_flat_layers_from_file(p)
            .unwrap()
            .layer_data[0]
            .channel_data
            .list
            .iter()
            .map(|c| {
                c.sample_data
                    .values_as_f32()
                    .map(f32::to_bits)
                    .collect::<Vec<_>>()
            })
            .collect::<Vec<_>>()
    };
    assert_eq!(
        read(&full),
        read(&exact),
        "adaptive T = 0 differs from full order"
    );
    let roi_img = image::open(&roi).unwrap();
    assert_eq!((roi_img.width(), roi_img.height()), (24, 16));
    // Every stopping rule, and the threshold on the display, are exact at T = 0 too.
    for extra in [
        vec!["--stop", "significance"],
        vec!["--stop", "either"],
        vec!["--display-threshold", "--exposure", "-1"],
    ] {
        let out = dir.path().join("exact2.exr");
        let j = json(&run(relight(&scene, &b)
            .args(["--order", "4", "--adaptive", "--threshold", "0", "--json"])
            .args(&extra)
            .arg("--out")
            .arg(&out)));
        assert_eq!(read(&full), read(&out), "{extra:?}");
        assert_eq!(
            j["mean_order_diffuse"].as_f64(),
            Some(4.0),
            "{extra:?}: {j}"
        );
        assert_eq!(j["work_fraction"].as_f64(), Some(1.0), "{extra:?}: {j}");
    }
    let j = json(&run(relight(&scene, &b).args([
        "--order",
        "5",
        "--adaptive",
        "--display-threshold",
        "--threshold",
        "0.05",
        "--json",
    ])));
    assert_eq!(j["threshold_kind"], "display");
    assert_eq!(j["stop"], "convergence");
    assert!(j["work_fraction"].as_f64().unwrap() <= 1.0, "{j}");

    // A large threshold shrinks the ROI (and the image changes).
    let j = json(&run(relight(&scene, &b).args([
        "--order",
        "4",
        "--adaptive",
        "--threshold",
        "1000",
        "--json",
    ])));
    assert!(j["roi_fraction_diffuse"].as_f64().unwrap() <= rd);

    // Rotating-environment frames report frames per second.
    let j = json(&run(relight(&scene, &b).args([
        "--frames",
        "3",
        "--rotate-y-step",
        "10",
        "--json",
    ])));
    assert_eq!(j["frames"], 3);
    assert!(j["fps"].as_f64().unwrap() > 0.0, "{j}");
    // The image of a rotating run is its first frame: the same as a single frame.
    let (rot3, rot1) = (dir.path().join("rot3.exr"), dir.path().join("rot1.exr"));
    run(relight(&scene, &b)
        .args([
            "--rotate-y",
            "30",
            "--frames",
            "3",
            "--rotate-y-step",
            "10",
            "--out",
        ])
        .arg(&rot3));
    run(relight(&scene, &b)
        .args(["--rotate-y", "30", "--out"])
        .arg(&rot1));
    assert_eq!(read(&rot3), read(&rot1));
    let text = run(relight(&scene, &b).args(["--frames", "3", "--rotate-y-step", "10"]));
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(text.contains("frames/s"), "{text}");

    // --glossy hybrid runs; a negative --fit-error is refused.
    run(relight(&scene, &b).args(["--glossy", "hybrid", "--fit-error", "0.2"]));
    let err = fail(relight(&scene, &b).args(["--glossy", "hybrid", "--fit-error=-1"]));
    assert!(err.contains("--fit-error -1"), "{err}");

    // A bake of another mesh is refused, naming the bake file.
    let other_dir = dir.path().join("other");
    std::fs::create_dir(&other_dir).unwrap();
    let other = write_scene(&other_dir, 2);
    let err = fail(&mut relight(&other, &b));
    assert!(
        err.contains(&b.display().to_string()) && err.contains("different geometry"),
        "{err}"
    );

    // A per-pixel bake relights (per pixel) but cannot be relit adaptively.
    let pb = dir.path().join("pixels.prtb");
    bake(&scene, &pb, &["--per-pixel", "--bounces", "0"]);
    let j = json(&run(relight(&scene, &pb).args(["--json"])));
    assert_eq!(j["points"], 2 * 24 * 16);
    let err = fail(relight(&scene, &pb).args(["--adaptive"]));
    assert!(err.contains("per-vertex bake"), "{err}");

    // Bad options.
    for (args, needle) in [
        (vec!["--frames", "0"], "--frames"),
        (vec!["--threshold", "-1"], "--threshold"),
        (vec!["--threshold", "nan"], "--threshold"),
        (vec!["--threshold", "inf"], "--threshold"),
        (vec!["--rotate-y", "inf"], "--rotate-y"),
        (vec!["--roi-png", "x.png"], "--adaptive"),
        (vec!["--display-threshold"], "--adaptive"),
        (vec!["--adaptive", "--stop", "sometimes"], "--stop"),
        (
            vec!["--adaptive", "--display-threshold", "--relative-threshold"],
            "--relative-threshold",
        ),
        (vec!["--exposure", "nan"], "--exposure"),
        (
            vec!["--adaptive", "--cost-exponent", "-1"],
            "--cost-exponent",
        ),
        (
            vec!["--adaptive", "--cost-exponent", "nan"],
            "--cost-exponent",
        ),
        (
            vec!["--adaptive", "--cost-exponent", "9"],
            "--cost-exponent",
        ),
        (vec!["--order", "0"], "order"),
        (vec!["--order", "x"], "--order"),
        (vec!["--bogus"], "--bogus"),
    ] {
        let err = fail(relight(&scene, &b).args(&args));
        assert!(err.contains(needle), "{args:?}: {err}");
    }
    let err = fail(&mut relight(&scene, &dir.path().join("missing.prtb")));
    assert!(err.contains("missing.prtb"), "{err}");
}

/// `--target-psnr`: every frame reaches the target against full order (the run's own full-order
/// images, `--verify`), the estimate is near what is reached, the run is reproducible (its
/// decisions depend on images, not timings), and bad values are clear errors.
#[test]
fn target_psnr_meets_the_target_on_every_frame() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let b = dir.path().join("scene.prtb");
    bake(&scene, &b, &[]);
    let study = |target: &str| {
        json(&run(relight(&scene, &b).args([
            "--adaptive",
            "--target-psnr",
            target,
            "--frames",
            "4",
            "--rotate-y-step",
            "90",
            "--verify",
            "--study",
            "--json",
        ])))
    };
    for target in [35.0, 45.0] {
        let j = study(&target.to_string());
        let frames = j["frames"].as_array().unwrap();
        assert_eq!(frames.len(), 4);
        for f in frames {
            // JSON writes ∞ (full order, exact) as null.
            let actual = f["psnr_actual"].as_f64().unwrap_or(f64::INFINITY);
            // The bound is a 2σ one on a sample of pixels: 0.5 dB of slack.
            assert!(actual >= target - 0.5, "target {target}: {f}");
            let est = f["psnr_estimate"].as_f64().unwrap_or(f64::INFINITY);
            if est.is_finite() && actual.is_finite() {
                assert!((est - actual).abs() <= 3.0, "estimate far off: {f}");
            }
            assert!(f["shade_ms"].as_f64().unwrap() >= f["probe_ms"].as_f64().unwrap());
        }
        assert!(j["uniform"]["order"].as_u64().unwrap() >= 1, "{j}");
        // Reproducible: the same thresholds and estimates again.
        let again = study(&target.to_string());
        for (a, b) in frames.iter().zip(again["frames"].as_array().unwrap()) {
            assert_eq!(a["threshold"], b["threshold"]);
            assert_eq!(a["tries"], b["tries"]);
            assert_eq!(a["psnr_estimate"], b["psnr_estimate"]);
        }
    }
    for bad in ["0", "-3", "NaN", "inf"] {
        for study in [&["--study"][..], &[]] {
            let err = fail(
                relight(&scene, &b)
                    .args(["--adaptive", "--target-psnr", bad])
                    .args(study),
            );
            assert!(err.contains("--target-psnr"), "{bad}: {err}");
            assert!(!err.contains("panicked"), "{err}");
        }
    }
    let err = fail(relight(&scene, &b).args(["--target-psnr", "40", "--study"]));
    assert!(err.contains("--study needs --adaptive"), "{err}");
}

/// `--target-psnr P --out X` (issue 34): the representation chosen reaches `P` against full
/// order at every rotation tried (measured again here, on the written image, through
/// `prt compare`), costs no more than the lowest uniform order meeting it, and its image is
/// written in the same command.
#[test]
fn target_psnr_chooses_a_representation_and_writes_its_image() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let b = dir.path().join("scene.prtb");
    bake(&scene, &b, &[]);
    let out = dir.path().join("chosen.exr");
    let png = dir.path().join("chosen.png");
    let j = json(&run(relight(&scene, &b)
        .args(["--target-psnr", "40", "--target-rotations", "2", "--json"])
        .arg("--out")
        .arg(&out)
        .arg("--png")
        .arg(&png)));
    let chosen = &j["chosen"];
    // JSON writes ∞ (full order) as null.
    assert!(
        chosen["min_psnr"].as_f64().unwrap_or(f64::INFINITY) >= 40.0,
        "{j}"
    );
    assert!(
        chosen["cost"].as_f64().unwrap() <= j["best_uniform"]["cost"].as_f64().unwrap(),
        "{j}"
    );
    assert!(png.exists());
    let full = dir.path().join("full.exr");
    run(relight(&scene, &b).arg("--out").arg(&full));
    // Identical images (full order chosen) compare as ∞, which JSON writes as null.
    let cmp = json(&run(prt()
        .arg("compare")
        .arg(&out)
        .arg(&full)
        .arg("--json")));
    let psnr = cmp["psnr_ldr"].as_f64().unwrap_or(f64::INFINITY);
    assert!(psnr >= 40.0, "{psnr} dB: {j}");
    // The decision line names the choice.
    let text = String::from_utf8(
        run(relight(&scene, &b).args(["--target-psnr", "40", "--target-rotations", "2"])).stdout,
    )
    .unwrap();
    assert!(text.starts_with("decision: "), "{text}");
}

/// `--target-psnr P --candidate-bake B` (issue 34): a per-pixel bake (the reference, as
/// `--bake`) and a per-vertex bake of the same scene compete; every candidate of both is
/// measured against the per-pixel full order, the chosen one meets the target, costs no more
/// than any other candidate that met it, and its image (from its own bake) is the one written.
/// Adaptive candidates are tried on the per-vertex bake only (they walk its vertex adjacency).
#[test]
fn target_psnr_chooses_between_per_vertex_and_per_pixel_bakes() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let (px, vx) = (
        dir.path().join("pixel.prtb"),
        dir.path().join("vertex.prtb"),
    );
    bake(&scene, &px, &["--per-pixel"]);
    bake(&scene, &vx, &[]);
    let full = dir.path().join("full.exr");
    run(relight(&scene, &px).arg("--out").arg(&full));
    // At 15 dB the per-vertex bake's order 1 (its few vertices) is the cheapest; at 45 dB no
    // per-vertex representation gets close enough to the per-pixel image (interpolation
    // across the floor's large triangles: ~36 dB at its full order), so per pixel is chosen.
    for (target, winner) in [(15.0f64, 1), (45.0, 0)] {
        let out = dir.path().join(format!("chosen{target}.exr"));
        let j = json(&run(relight(&scene, &px)
            .args([
                "--target-psnr",
                &target.to_string(),
                "--target-rotations",
                "2",
            ])
            .arg("--candidate-bake")
            .arg(&vx)
            .arg("--json")
            .arg("--out")
            .arg(&out)));
        eprintln!("target {target}: {j}");
        let tried = j["tried"].as_array().unwrap();
        let psnr = |c: &serde_json::Value| c["min_psnr"].as_f64().unwrap_or(f64::INFINITY);
        assert!(tried.iter().any(|c| c["bake"] == 1), "{j}");
        let chosen = &j["chosen"];
        assert!(psnr(chosen) >= target, "{j}");
        assert_eq!(chosen["bake"], winner, "{j}");
        for c in tried.iter().filter(|c| psnr(c) >= target) {
            assert!(
                chosen["cost"].as_f64() <= c["cost"].as_f64(),
                "{c} beats {chosen}"
            );
        }
        let cmp = json(&run(prt()
            .arg("compare")
            .arg(&out)
            .arg(&full)
            .arg("--json")));
        let got = cmp["psnr_ldr"].as_f64().unwrap_or(f64::INFINITY);
        assert!(got >= target, "the written image: {got} dB");
    }
    let err = fail(relight(&scene, &px).arg("--candidate-bake").arg(&vx));
    assert!(
        err.contains("--candidate-bake is for --target-psnr"),
        "{err}"
    );
}

/// `prt bake --target-psnr P`: per object the lowest order whose PSNR against a path-traced
/// reference reaches `P` (checked here against the order-13 bake truncated by hand: the chosen
/// order reaches it and the one below does not, on the same reference); an unreachable target
/// is an error naming the best reachable figure, and leaves no file.
#[test]
fn bake_target_psnr_keeps_the_lowest_order_that_meets_it() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let out = dir.path().join("target.prtb");
    let full = dir.path().join("full.prtb");
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args([
            "--rays",
            "256",
            "--target-psnr",
            "20",
            "--order",
            "8",
            "--out",
        ])
        .arg(&out));
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args(["--rays", "256", "--order", "8", "--out"])
        .arg(&full));
    let chosen = json(&run(prt().arg("inspect").arg(&out).arg("--json")));
    let objects = chosen["objects"].as_array().unwrap();
    assert_eq!(objects.len(), 2);
    let decisions = chosen["decisions"].as_array().unwrap();
    for o in objects {
        let order = o["order"].as_u64().unwrap();
        assert!((1..=8).contains(&order), "{o}");
        let name = o["name"].as_str().unwrap();
        assert!(
            decisions.iter().any(|d| d["object"] == name
                && d["decision"] == format!("order {order}")
                && d["reason"].as_str().unwrap().contains("20 dB")),
            "{name}: {decisions:?}"
        );
    }
    // Truncation keeps a prefix of every object's coefficients: at the lowest chosen order
    // the truncated and the full bake relight to the same image, bit for bit.
    let k = objects
        .iter()
        .map(|o| o["order"].as_u64().unwrap())
        .min()
        .unwrap();
    let (a, b) = (dir.path().join("a.exr"), dir.path().join("b.exr"));
    run(relight(&scene, &out)
        .args(["--order", &k.to_string(), "--out"])
        .arg(&a));
    run(relight(&scene, &full)
        .args(["--order", &k.to_string(), "--out"])
        .arg(&b));
    let same = json(&run(prt().arg("compare").arg(&a).arg(&b).arg("--json")));
    assert_eq!(same["max_abs"].as_f64(), Some(0.0), "{same}");
    // Unreachable and bad targets.
    let bad = dir.path().join("bad.prtb");
    let err = fail(
        prt()
            .arg("bake")
            .arg(&scene)
            .args([
                "--rays",
                "256",
                "--order",
                "8",
                "--target-psnr",
                "99",
                "--out",
            ])
            .arg(&bad),
    );
    assert!(
        err.contains("cannot be met") && err.contains("reaches at most"),
        "{err}"
    );
    assert!(!bad.exists());
    // It tried per-pixel transfer too, and says what each reaches (on this scene per pixel is
    // no better: the error is not interpolation; `prt bake scenes/hard_shadow.toml
    // --target-psnr 26` is a case where the bake switches to per pixel, see the report README).
    assert!(
        err.contains("per vertex")
            && err.contains("per pixel")
            && err.matches("reaches at most").count() >= 4,
        "{err}"
    );
    for v in ["0", "-1", "NaN", "inf"] {
        let err = fail(
            prt()
                .arg("bake")
                .arg(&scene)
                .args(["--target-psnr", v, "--out"])
                .arg(&bad),
        );
        assert!(err.contains("--target-psnr"), "{v}: {err}");
    }
}

/// Issue 31: `prt relight`'s options read as groups of orthogonal options, and every command
/// line that worked before still works. The threshold's unit is one option
/// (`--threshold-unit radiance|mean|display`); the old booleans are hidden spellings of it and
/// give the same image bit for bit; the old flag combinations of the SH path still run.
#[test]
fn old_relight_command_lines_still_work() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let b = dir.path().join("scene.prtb");
    bake(&scene, &b, &[]);
    let image = |name: &str, args: &[&str]| -> Vec<u8> {
        let out = dir.path().join(format!("{name}.exr"));
        run(relight(&scene, &b).args(args).arg("--out").arg(&out));
        std::fs::read(&out).unwrap()
    };
    for (old, new) in [
        ("--relative-threshold", "mean"),
        ("--display-threshold", "display"),
    ] {
        let a = image(
            &format!("old{new}"),
            &["--adaptive", "--threshold", "0.1", old],
        );
        let n = image(
            &format!("new{new}"),
            &["--adaptive", "--threshold", "0.1", "--threshold-unit", new],
        );
        assert!(a == n, "{old} and --threshold-unit {new} differ");
    }
    // The default unit is radiance.
    assert!(
        image("plain", &["--adaptive", "--threshold", "0.1"])
            == image(
                "radiance",
                &[
                    "--adaptive",
                    "--threshold",
                    "0.1",
                    "--threshold-unit",
                    "radiance"
                ]
            )
    );
    // The other old command lines still run.
    let csv = dir.path().join("colours.csv");
    for args in [
        vec!["--adaptive", "--threshold", "0.02"],
        vec!["--adaptive", "--relative-threshold", "--threshold", "0.05"],
        vec!["--adaptive", "--display-threshold", "--exposure", "1"],
        vec!["--glossy", "exact"],
        vec!["--glossy", "hybrid", "--fit-error", "0.2"],
        vec!["--frames", "3", "--rotate-y-step", "15", "--json"],
        vec!["--vertex-colours", csv.to_str().unwrap()],
        vec![
            "--adaptive",
            "--target-psnr",
            "30",
            "--study",
            "--frames",
            "2",
            "--rotate-y-step",
            "20",
        ],
    ] {
        run(relight(&scene, &b).args(&args));
    }
    // The help groups the options and does not list the old spellings.
    let help = String::from_utf8(run(prt().args(["relight", "--help"])).stdout).unwrap();
    for heading in [
        "Adaptive (Lee & Kim 2014):",
        "Output:",
        "Rotation and frames:",
        "Glossy materials:",
        "Reflectance fields (prt reflectance):",
        "Adaptive to a PSNR target:",
    ] {
        assert!(help.contains(heading), "{help}");
    }
    assert!(help.contains("--threshold-unit"));
    assert!(!help.contains("--relative-threshold") && !help.contains("--display-threshold"));
    // The old booleans do not combine with the new option or with each other.
    fail(relight(&scene, &b).args(["--adaptive", "--relative-threshold", "--display-threshold"]));
    fail(relight(&scene, &b).args([
        "--adaptive",
        "--display-threshold",
        "--threshold-unit",
        "mean",
    ]));
}

/// `prt bench relight` times what `prt relight` with the same options shades: the order and
/// point count agree with `prt relight`'s, at least 5 frames are timed after the warm-up, the
/// median lies between the fastest and slowest frame, and with `--adaptive` the full order is
/// timed too and the speed-up is the ratio of the two medians. It refuses image outputs.
#[test]
fn bench_relight_times_what_relight_shades() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let b = dir.path().join("scene.prtb");
    bake(&scene, &b, &[]);
    let shaded = json(&run(relight(&scene, &b).args(["--order", "4", "--json"])));
    let bench = |extra: &[&str]| {
        let mut c = prt();
        c.args(["bench", "relight"])
            .arg(&scene)
            .arg("--bake")
            .arg(&b)
            .args(extra);
        c
    };
    let j = json(&run(&mut bench(&["--order", "4", "--json"])));
    assert_eq!(j["order"], shaded["order"]);
    assert_eq!(j["points"], shaded["points"]);
    assert_eq!(j["frames"], 5, "at least 5 timed frames: {j}");
    assert_eq!(j["warmup"], 2);
    let (lo, med, hi) = (
        j["shade_ms_min"].as_f64().unwrap(),
        j["shade_ms"].as_f64().unwrap(),
        j["shade_ms_max"].as_f64().unwrap(),
    );
    assert!(lo > 0.0 && lo <= med && med <= hi, "{j}");
    // --order 4 of an order-5 bake: the full order is timed as well.
    assert_eq!(j["full_order"], 5);

    let j = json(&run(&mut bench(&[
        "--adaptive",
        "--threshold",
        "0.05",
        "--frames",
        "7",
        "--warmup",
        "1",
        "--json",
    ])));
    assert_eq!(j["adaptive"], true);
    assert_eq!(j["frames"], 7);
    assert_eq!(j["warmup"], 1);
    let ratio = j["full_shade_ms"].as_f64().unwrap() / j["shade_ms"].as_f64().unwrap();
    assert!(
        (j["speedup"].as_f64().unwrap() - ratio).abs() <= 1e-9 * ratio,
        "{j}"
    );
    // Full order without --order or --adaptive: nothing to compare with.
    let j = json(&run(&mut bench(&["--json"])));
    assert!(
        j["speedup"].is_null() && j["full_shade_ms"].is_null(),
        "{j}"
    );

    let err = fail(bench(&[]).arg("--out").arg(dir.path().join("x.exr")));
    assert!(err.contains("only times"), "{err}");
}
