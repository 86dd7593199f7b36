//! Issue 19: the report's `index.html` in a real browser. A quick report of the tiny scene is
//! opened from `file://` in headless Chromium by `tools/viewer_check.py` (Selenium), which
//! checks that it loads within a second with no console error, that the exposure, the A/B
//! choice, the tone curve and the false-colour view change the displayed pixels, that the
//! probe, sorting and chart tooltips work. Needs Debian's chromium and chromium-driver and
//! PyPI's selenium; without them the test says it is skipped, unless `PRT_REQUIRE_BROWSER=1`
//! (which CI sets after installing them), when it fails.

mod common;

use common::{prt, run};
use std::path::Path;
use std::process::Command;

fn browser_available() -> bool {
    let has = |p: &str| Path::new(p).exists();
    let selenium = Command::new("python3")
        .args(["-c", "import selenium"])
        .output()
        .is_ok_and(|o| o.status.success());
    has("/usr/bin/chromium") && has("/usr/bin/chromedriver") && selenium
}

/// Whether `tools/engine_check.py` can run: the browser, and numpy and Pillow to read the
/// canvas.
fn engine_check_available() -> bool {
    browser_available()
        && Command::new("python3")
            .args(["-c", "import numpy, PIL"])
            .output()
            .is_ok_and(|o| o.status.success())
}

#[test]
fn report_viewer_works_in_headless_chromium() {
    if !browser_available() {
        assert!(
            std::env::var("PRT_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "PRT_REQUIRE_BROWSER=1 but chromium, chromium-driver or selenium is missing"
        );
        eprintln!("skipped: no chromium + chromium-driver + selenium (see tools/viewer_check.py)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scene = common::write_scene(dir.path(), 3);
    let out = dir.path().join("report");
    run(prt()
        .arg("report")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args([
            "--orders",
            "2..4",
            "--reference-spp",
            "8",
            "--rays",
            "64",
            "--frames",
            "1",
        ]));
    let page = std::fs::read_to_string(out.join("index.html")).unwrap();
    // Self-contained: no script, style or image is fetched from anywhere.
    for needle in ["src=\"http", "href=\"http", "<link", "src=\"//"] {
        assert!(
            !page.contains(needle),
            "the page refers outside itself: {needle}"
        );
    }
    let check = Command::new("python3")
        .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/viewer_check.py"))
        .arg(out.join("index.html"))
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&check.stdout);
    eprintln!("{text}{}", String::from_utf8_lossy(&check.stderr));
    assert!(check.status.success(), "the browser check failed:\n{text}");
    assert!(text.contains("all checks passed"));
    // The report links its live page, which loads and draws in the same browser (issue 33).
    assert!(page.contains("<a href=\"live.html\">live.html</a>"));
    if engine_check_available() {
        let live = Command::new("python3")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/engine_check.py"))
            .arg(out.join("live.html"))
            .args(["--rotations", "0,90", "--out-dir"])
            .arg(dir.path().join("live"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&live.stdout);
        eprintln!("{text}{}", String::from_utf8_lossy(&live.stderr));
        assert!(
            live.status.success(),
            "the live page's check failed:\n{text}"
        );
    }
}

/// Issue 33: an order-10 bake of the bunny (Lambert, under the bundled courtyard map), at 0
/// and 1 bounce, of the default scene (the bunny on a Phong floor, whose specular the page
/// shades), of the bunny in glTF-PBR gold (fitted lobes), an order-6 1-bounce per-texel
/// bake of the bunny on a lightmapped floor, and an order-8 bake of Khronos' textured
/// BoxTextured (per-vertex albedo and lobe colours), exported for `--target webgl2` (16 vertex attributes at most: its transfer in
/// the §10.2 data texture), shown by `prt view`'s page in headless Chromium's WebGL2
/// (SwiftShader): the page loads from file:// with no console error, turning the map and the
/// exposure change the canvas, and at three rotations the canvas — the GPU's interpolation
/// of per-vertex radiance computed from the file alone, with the SH rotated in the page —
/// matches `prt relight --rotate-y`'s image of the same bake at ≥ 40 dB over the interior
/// object pixels (each with its 8 neighbours on the same object, from the page's id pass:
/// there both images see the same smooth Gouraud field, which prt box-filters over the pixel
/// and the GPU samples at its centre; the 8-bit rounding alone would allow ~59 dB). Without
/// the floor's specular the default scene's canvas is at 20–32 dB.
#[test]
fn engine_page_relights_like_prt_in_headless_chromium() {
    if !engine_check_available() {
        assert!(
            std::env::var("PRT_REQUIRE_BROWSER").as_deref() != Ok("1"),
            "PRT_REQUIRE_BROWSER=1 but chromium, chromium-driver, selenium, numpy or Pillow is missing"
        );
        eprintln!("skipped: no chromium + chromium-driver + selenium + numpy + Pillow (tools/requirements-browser.txt)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let scene = common::bunny_scene(
        dir.path(),
        "bunny",
        "type = \"lambert\"\nalbedo = [0.8, 0.7, 0.6]",
    );
    // The default scene at 160 × 120: the bunny on a Phong floor, whose specular lobe the page
    // shades too (SPEC §10.1: L ⊛ V products per frame, the lobe's bands at the mirror
    // direction).
    let default = std::fs::read_to_string(scenes.join("default.toml"))
        .unwrap()
        .replace("resolution = [320, 240]", "resolution = [160, 120]")
        .replace("\"meshes/", &format!("\"{}/meshes/", scenes.display()))
        .replace("\"maps/", &format!("\"{}/maps/", scenes.display()));
    let default_scene = dir.path().join("default.toml");
    std::fs::write(&default_scene, default).unwrap();
    // The bunny in glTF-PBR gold (roughness 0.6): all its light is the fitted lobes' (§10.1
    // "fitted": the tables per view elevation, the Schlick split into two shapes, the
    // `pbr` diffuse factor), which the page shades too.
    let gold_scene = common::bunny_scene(
        dir.path(),
        "gold",
        "type = \"pbr\"\nbase_color = [1.0, 0.78, 0.34]\nmetallic = 1.0\nroughness = 0.6",
    );
    // The bunny on a floor baked per texel (`scenes/hard/figure_on_quad.toml`, the floor's
    // UVs): the floor's transfer is in lightmap textures (§10), which the page samples.
    let hard = scenes.join("hard");
    let texel = std::fs::read_to_string(hard.join("figure_on_quad.toml"))
        .unwrap()
        .replace("resolution = [320, 240]", "resolution = [160, 120]")
        .replace("\"../", &format!("\"{}/", scenes.display()))
        .replace(
            "\"quad.obj\"",
            &format!("\"{}\"", hard.join("quad.obj").display()),
        );
    let texel_scene = dir.path().join("figure_on_quad.toml");
    std::fs::write(&texel_scene, texel).unwrap();
    // Khronos' BoxTextured (a textured glTF-PBR cube: per-vertex albedo and lobe colours,
    // `_PRT_ALBEDO`, `_PRT_SPEC_A/B`) on a pbr floor.
    let boxed = std::fs::read_to_string(scenes.join("box_textured.toml"))
        .unwrap()
        .replace("resolution = [240, 180]", "resolution = [160, 120]")
        .replace("\"gltf/", &format!("\"{}/gltf/", scenes.display()))
        .replace("\"meshes/", &format!("\"{}/meshes/", scenes.display()))
        .replace("\"maps/", &format!("\"{}/maps/", scenes.display()));
    let box_scene = dir.path().join("box_textured.toml");
    std::fs::write(&box_scene, boxed).unwrap();
    let order8: &[&str] = &["--order", "8"];
    let order10: &[&str] = &["--order", "10"];
    let lightmapped: &[&str] = &["--order", "6", "--per-texel", "48"];
    for (scene, bounces, tag, extra) in [
        (&scene, "0", "bunny", order10),
        (&scene, "1", "bunny", order10),
        (&default_scene, "0", "phong_floor", order10),
        (&gold_scene, "0", "pbr_gold", order10),
        (&texel_scene, "1", "lightmap", lightmapped),
        (&box_scene, "0", "box_textured", order8),
    ] {
        let path = |name: &str| dir.path().join(format!("{tag}_b{bounces}_{name}"));
        run(prt()
            .arg("bake")
            .arg(scene)
            .args(extra)
            .args(["--rays", "128", "--bounces", bounces, "--out"])
            .arg(path("bake.prtb")));
        let export = common::json(&run(prt()
            .arg("export")
            .arg(scene)
            .arg("--bake")
            .arg(path("bake.prtb"))
            .args(["--target", "webgl2", "--json", "--out"])
            .arg(path("asset.glb"))));
        assert!(
            export["vertex_attributes"].as_u64().unwrap() <= 16,
            "{export}"
        );
        // The Khronos glTF-Validator on the very file the page shows (when installed).
        let tools = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools");
        if tools.join("node_modules/gltf-validator").exists() {
            let v = Command::new("node")
                .arg(tools.join("gltf_validate.js"))
                .arg(path("asset.glb"))
                .output()
                .unwrap();
            let report = String::from_utf8_lossy(&v.stdout);
            assert!(
                v.status.success()
                    && report.contains("\"errors\":0")
                    && report.contains("\"warnings\":0"),
                "{tag}: {report}"
            );
        }
        run(prt()
            .arg("view")
            .arg(path("asset.glb"))
            .arg("--out")
            .arg(path("page.html")));
        let page = std::fs::read_to_string(path("page.html")).unwrap();
        for needle in ["src=\"http", "href=\"http", "<link", "src=\"//", "import "] {
            assert!(
                !page.contains(needle),
                "the page refers outside itself: {needle}"
            );
        }
        for deg in ["0", "120", "240"] {
            run(prt()
                .arg("relight")
                .arg(scene)
                .arg("--bake")
                .arg(path("bake.prtb"))
                .args(["--rotate-y", deg, "--png"])
                .arg(path(&format!("ref_{deg}.png"))));
        }
        let check = Command::new("python3")
            .arg(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/engine_check.py"))
            .arg(path("page.html"))
            .args(["--rotations", "0,120,240", "--min-psnr", "40", "--out-dir"])
            .arg(path("canvas"))
            .arg("--reference-pattern")
            .arg(path("ref_{deg}.png"))
            .output()
            .unwrap();
        let text = String::from_utf8_lossy(&check.stdout);
        eprintln!(
            "{bounces} bounce(s):\n{text}{}",
            String::from_utf8_lossy(&check.stderr)
        );
        assert!(check.status.success(), "the engine check failed:\n{text}");
        let summary: serde_json::Value =
            serde_json::from_str(text.lines().last().unwrap()).unwrap();
        for deg in ["0", "120", "240"] {
            let psnr = summary["psnr"][deg].as_f64().unwrap();
            assert!(
                psnr >= 40.0,
                "{tag}, {bounces} bounce(s), {deg}°: {psnr} dB"
            );
        }
        assert!(summary["frame_ms_median"].as_f64().unwrap() > 0.0);
    }
}
