//! Helpers shared by the CLI tests that build a tiny scene: an "L" of a floor and a wall under a
//! small lat-long map, and running `prt`.
#![allow(dead_code)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

pub fn prt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_prt"))
}

pub fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

pub fn json(out: &Output) -> Value {
    serde_json::from_slice(&out.stdout)
        .unwrap_or_else(|e| panic!("not JSON ({e}): {}", String::from_utf8_lossy(&out.stdout)))
}

/// `prt compare IMAGE REFERENCE --json`'s `psnr_ldr` (8-bit sRGB view).
pub fn psnr_ldr(image: &Path, reference: &Path) -> f64 {
    json(&run(prt()
        .arg("compare")
        .arg(image)
        .arg(reference)
        .arg("--json")))["psnr_ldr"]
        .as_f64()
        .expect("psnr_ldr is a number")
}

/// Runs `cmd`, which must fail with a message on stderr containing `needle`.
pub fn refused(cmd: &mut Command, needle: &str) {
    let o = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        !o.status.success() && err.contains(needle),
        "{cmd:?}: expected a refusal mentioning {needle:?}:\n{err}"
    );
}

/// An "L": a 3×3-quad floor facing +Y and a 3×3-quad wall facing +Z (32 vertices), the wall
/// glossy so that the specular path runs too.
pub fn write_obj(path: &Path, n: usize) {
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
pub fn write_scene(dir: &Path, n: usize) -> PathBuf {
    write_obj(&dir.join("x.obj"), n);
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

/// The bunny on the 2-triangle floor of `scenes/hard` (whose only UVs are the floor's, planar
/// over the unit square, here scaled by `uv_scale`) under the upper-sky map, 64 × 48 pixels,
/// bounces 0: `DIR/scene{uv_scale}.toml`.
pub fn write_lightmap_scene(dir: &Path, uv_scale: f32) -> std::path::PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    // The floor with its UVs scaled (1: the repository's quad.obj).
    let quad = std::fs::read_to_string(repo.join("hard/quad.obj")).unwrap();
    let quad: String = quad
        .lines()
        .map(|l| match l.strip_prefix("vt ") {
            Some(uv) => {
                let v: Vec<f32> = uv.split_whitespace().map(|x| x.parse().unwrap()).collect();
                format!("vt {} {}\n", v[0] * uv_scale, v[1] * uv_scale)
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(dir.join("quad.obj"), quad).unwrap();
    let s = dir.join(format!("scene{uv_scale}.toml"));
    std::fs::write(
        &s,
        format!(
            r#"[camera]
eye = [0.0, 0.75, 2.4]
target = [0.0, 0.42, 0.0]
fov_y = 40.0
resolution = [64, 48]

[environment]
file = "{sky}"

[materials.clay]
type = "lambert"
albedo = [0.8, 0.8, 0.8]

[[objects]]
mesh = "{bunny}"
material = "clay"
scale = 0.1

[[objects]]
mesh = "quad.obj"
material = "clay"
scale = [2.0, 1.0, 2.0]

[render]
bounces = 0
"#,
            sky = repo.join("hard/upper_sky.hdr").display(),
            bunny = repo.join("meshes/bunny_lowres.obj").display(),
        ),
    )
    .unwrap();
    s
}

/// Python 3 with numpy for the independent tools in `tools/` (`PRT_PYTHON`, else `python3`),
/// or `None` (the test is skipped, with a line) when there is none and CI does not insist on
/// it (`PRT_REQUIRE_PY_READER=1`, set after installing tools/requirements-reader.txt).
pub fn python_or_skip() -> Option<String> {
    let py = std::env::var("PRT_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = Command::new(&py)
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    if !ok {
        assert!(
            std::env::var("PRT_REQUIRE_PY_READER").as_deref() != Ok("1"),
            "PRT_REQUIRE_PY_READER=1 but no Python 3 with numpy (install tools/requirements-reader.txt)"
        );
        eprintln!("skipped: no Python 3 with numpy for the tools/ scripts (python3 -m pip install -r tools/requirements-reader.txt)");
    }
    ok.then_some(py)
}

/// `prt reflectance` on the tiny scene: an 8×4 grid of directions, one footprint sample, no
/// bounces (SPEC §3.14).
pub fn reflectance_file(scene: &Path, out: &Path, f16: bool) {
    let mut cmd = prt();
    cmd.arg("reflectance").arg(scene).args([
        "--directions",
        "8x4",
        "--pixel-samples",
        "1",
        "--bounces",
        "0",
    ]);
    if f16 {
        cmd.arg("--f16");
    }
    run(cmd.arg("--out").arg(out));
}

/// The low-resolution bunny of `scenes/` under the bundled courtyard map, 160 × 120, in the
/// material whose TOML body is `material` (named `m`), written as `DIR/NAME.toml`.
pub fn bunny_scene(dir: &Path, name: &str, material: &str) -> PathBuf {
    let scenes = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    let scene = dir.join(format!("{name}.toml"));
    std::fs::write(
        &scene,
        format!(
            r#"[camera]
eye = [0.0, 0.55, 1.6]
target = [0.0, 0.42, 0.0]
up = [0.0, 1.0, 0.0]
fov_y = 40.0
resolution = [160, 120]

[environment]
file = "{}"

[materials.m]
{material}

[[objects]]
mesh = "{}"
material = "m"
scale = 0.1
"#,
            scenes.join("maps/courtyard.exr").display(),
            scenes.join("meshes/bunny_lowres.obj").display()
        ),
    )
    .unwrap();
    scene
}

/// Per object name, the `object,point,r,g,b` rows of a CSV (`prt relight --vertex-colours`,
/// `tools/gltf_relight.py`), each with its point index (rows need not be consecutive:
/// `tools/gltf_relight.py --texels covered` writes only the covered texels).
pub type Rows = std::collections::HashMap<String, Vec<(usize, [f64; 3])>>;

/// Reads a CSV of [`Rows`].
pub fn read_rows(path: &Path) -> Rows {
    let mut out = Rows::new();
    for line in std::fs::read_to_string(path).unwrap().lines().skip(1) {
        let f: Vec<&str> = line.rsplitn(5, ',').collect();
        let rgb = [f[2], f[1], f[0]].map(|x| x.parse::<f64>().unwrap());
        out.entry(f[4].to_owned())
            .or_default()
            .push((f[3].parse().unwrap(), rgb));
    }
    out
}

/// `prt relight SCENE --bake BAKE --vertex-colours CSV`: every point's radiance as prt relights
/// it.
pub fn relight_vertex_colours(scene: &Path, bake: &Path, csv: &Path) {
    run(prt()
        .arg("relight")
        .arg(scene)
        .arg("--bake")
        .arg(bake)
        .arg("--vertex-colours")
        .arg(csv));
}

/// `tools/gltf_relight.py GLB --texels covered` (the relighter written from SPEC §10 alone) with
/// `python`: its radiance, magnitudes and quantisation bounds per covered texel, written to
/// `csv("py")`, `csv("mag")` and `csv("q")` and read back, in that order.
pub fn gltf_relight_texels(
    python: &str,
    glb: &Path,
    csv: impl Fn(&str) -> PathBuf,
) -> (Rows, Rows, Rows) {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/gltf_relight.py");
    run(Command::new(python)
        .arg(script)
        .arg(glb)
        .args(["--texels", "covered", "--colours"])
        .arg(csv("py"))
        .arg("--magnitudes")
        .arg(csv("mag"))
        .arg("--quantisation")
        .arg(csv("q")));
    (
        read_rows(&csv("py")),
        read_rows(&csv("mag")),
        read_rows(&csv("q")),
    )
}

/// The relative f32 rounding `γ_N` of prt's sums at SH order `order` (its products and the
/// 16-term bilinear and colour sums), the factor of `Q + γ_N (M + Q)` in the texel bounds.
pub fn texel_sum_gamma(order: usize) -> f64 {
    (order.pow(4) + order * order + 16 + 16 * order) as f64 * f64::from(f32::EPSILON) / 2.0
}
