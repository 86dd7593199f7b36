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
}
