//! `prt report` end to end on a tiny scene (issue 6): every promised output exists, one row is
//! reproduced by hand with `prt relight` and `prt compare`, and a second run reuses the cached
//! bake and gives the same figures.

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn prt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_prt"))
}

fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn json(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

/// An "L": a 3×3-quad floor facing +Y and a 3×3-quad wall facing +Z (32 vertices), the wall
/// glossy so that the specular path runs too.
fn write_obj(path: &Path, n: usize) {
    let mut floor = String::from("# floor\n");
    let mut wall = String::from("# wall\n");
    for j in 0..=n {
        for i in 0..=n {
            let (u, v) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32);
            floor += &format!("v {u} 0 {}\n", v - 0.5);
            wall += &format!("v {u} {v} -0.5\n");
        }
    }
    let w = n + 1;
    for j in 0..n {
        for i in 0..n {
            let a = 1 + j * w + i;
            let (b, c, d) = (a + 1, a + w, a + w + 1);
            floor += &format!("f {a} {c} {b}\nf {b} {c} {d}\n");
            wall += &format!("f {a} {b} {c}\nf {b} {d} {c}\n");
        }
    }
    std::fs::write(path.with_file_name("floor.obj"), floor).unwrap();
    std::fs::write(path.with_file_name("wall.obj"), wall).unwrap();
}

/// The tiny scene: 24×16 pixels, a 16×8 lat-long map with a bright patch.
fn write_scene(dir: &Path) -> PathBuf {
    write_obj(&dir.join("x.obj"), 3);
    exr::prelude::write_rgb_file(dir.join("env.exr"), 16, 8, |x, y| {
        let sky = if y < 4 { 1.0 + 0.1 * x as f32 } else { 0.3 };
        let sun = if (x, y) == (5, 2) { 20.0 } else { 0.0 };
        (sky + sun, 0.9 * sky + sun, 0.7 * sky + sun)
    })
    .unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        r#"[camera]
eye = [0.3, 0.7, 1.8]
target = [0.0, 0.3, 0.0]
fov_y = 45.0
resolution = [24, 16]

[environment]
file = "env.exr"

[materials.clay]
type = "lambert"
albedo = [0.8, 0.6, 0.4]

[materials.gloss]
type = "phong"
albedo = [0.3, 0.3, 0.5]
specular = [0.4, 0.4, 0.4]
exponent = 12.0

[[objects]]
mesh = "floor.obj"
material = "clay"

[[objects]]
mesh = "wall.obj"
material = "gloss"

[render]
bounces = 1
"#,
    )
    .unwrap();
    scene
}

fn report(scene: &Path, out: &Path) -> Value {
    run(prt().arg("report").arg(scene).arg("--out").arg(out).args([
        "--orders",
        "2..4",
        "--reference-spp",
        "8",
        "--rays",
        "64",
        "--frames",
        "1",
    ]));
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
    let scene = write_scene(dir.path());
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
    assert_eq!(first["bake_cached"], false);
    assert_eq!(first["orders"].as_array().unwrap().len(), 3);
    let md = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        md.contains("| order |") && md.contains("prt relight"),
        "{md}"
    );
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
    let strip = |v: &Value| -> Value {
        let mut v = v.clone();
        let obj = v.as_object_mut().unwrap();
        for k in ["reference_seconds", "bake_seconds", "bake_cached"] {
            obj.remove(k);
        }
        for r in obj["orders"].as_array_mut().unwrap() {
            let r = r.as_object_mut().unwrap();
            for k in ["full_ms", "adaptive_ms", "speedup"] {
                r.remove(k);
            }
        }
        for c in obj["convergence"].as_array_mut().unwrap() {
            c.as_object_mut().unwrap().remove("ms");
        }
        v
    };
    assert_eq!(strip(&first), strip(&second));
}
