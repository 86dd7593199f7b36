//! Lightmaps of meshes without UVs through a generated atlas (issue 34, `prt-atlas`): suzanne
//! (no UVs) on the UV'd floor of `scenes/hard` baked `--per-texel`, exported, validated and
//! relit from the `.glb` alone by `tools/gltf_relight.py` to `prt relight`'s texel radiance;
//! the same bytes on 1 and 2 threads; and, on a smooth case (a sphere alone under the sky),
//! the per-texel bake against the per-vertex bake within a derived bound.

mod common;

use common::{
    gltf_relight_texels, json, prt, read_rows, relight_vertex_colours, run, texel_sum_gamma,
};
use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

/// A scene of `objects` (TOML `[[objects]]` blocks) under `scenes/hard`'s gradient sky.
fn scene(dir: &Path, objects: &str) -> PathBuf {
    let sky = repo().join("scenes/hard/gradient_sky.hdr");
    let s = dir.join("scene.toml");
    std::fs::write(
        &s,
        format!(
            "[camera]\neye = [0.0, 0.9, 2.6]\ntarget = [0.0, 0.35, 0.0]\nfov_y = 40.0\nresolution = [64, 48]\n\n[environment]\nfile = {sky:?}\n\n[materials.clay]\ntype = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]\n\n[materials.brick]\ntype = \"lambert\"\nalbedo = [0.8, 0.45, 0.25]\n\n{objects}"
        ),
    )
    .unwrap();
    s
}

/// Suzanne (no UVs) in `material` on the UV'd floor in `floor`.
fn suzanne_on_floor(dir: &Path, material: &str, floor: &str) -> PathBuf {
    let m = repo().join("scenes/meshes/suzanne.obj");
    let q = repo().join("scenes/hard/quad.obj");
    scene(
        dir,
        &format!("[[objects]]\nmesh = {m:?}\nmaterial = \"{material}\"\nscale = 0.4\ntranslate = [0.0, 0.4, 0.0]\n\n[[objects]]\nmesh = {q:?}\nmaterial = \"{floor}\"\nscale = [2.0, 1.0, 2.0]\n"),
    )
}

/// `object,point,r,g,b` CSV rows by object name, each with its point index.
/// Suzanne has no UVs: `--per-texel` generates her atlas (the decision says so with its
/// charts, density and utilisation), the file carries it (SPEC §3.9.3), the bake is the same
/// on 1 and 2 threads, and the export is an atlas-UV'd lightmap that the glTF validator
/// accepts and `tools/gltf_relight.py` relights — with its own conservative rasteriser of the
/// exported `TEXCOORD_0`, PNG decoder and dequantisation — to `prt relight`'s texel radiance:
/// every covered texel within `Q + γ_N·(M + Q)` (`Q` the script's bound for the 8-bit codes,
/// `M` its magnitudes, `γ_N` the f32 rounding of prt's sums, as in export_cli.rs), and the
/// script finds exactly the bake's covered texels.
#[test]
fn a_mesh_without_uvs_bakes_exports_and_relights_through_its_atlas() {
    let dir = tempfile::tempdir().unwrap();
    let s = suzanne_on_floor(dir.path(), "clay", "clay");
    let bake = |threads: &str, name: &str| {
        let path = dir.path().join(name);
        let out = run(prt()
            .arg("bake")
            .arg(&s)
            .args(["--rays", "32", "--order", "3", "--per-texel", "192"])
            .args(["--threads", threads, "--json", "--out"])
            .arg(&path));
        (path, json(&out))
    };
    let (t1, report) = bake("1", "t1.prtb");
    let (t2, _) = bake("2", "t2.prtb");
    assert!(
        std::fs::read(&t1).unwrap() == std::fs::read(&t2).unwrap(),
        "the atlas bake differs between 1 and 2 threads"
    );
    let decisions = report["decisions"].to_string();
    assert!(
        decisions.contains("per texel through a generated atlas") && decisions.contains("charts"),
        "{decisions}"
    );
    let b = prt_bakefile::read_bake(&t1).unwrap();
    let entry = &b.meta.settings["lightmaps"][0];
    assert!(
        entry["atlas"].is_array() && entry.get("uv_set").is_none(),
        "{entry}"
    );
    assert!(covered(&b, 0) > 1000, "{}", covered(&b, 0));
    // On a lightmap too coarse for her (fewer texels than vertices) she stays per vertex,
    // and the decision says why.
    let out = run(prt()
        .arg("bake")
        .arg(&s)
        .args([
            "--rays",
            "4",
            "--order",
            "3",
            "--per-texel",
            "48",
            "--json",
            "--out",
        ])
        .arg(dir.path().join("coarse.prtb")));
    let d = json(&out)["decisions"].to_string();
    assert!(
        d.contains("fewer than its") && d.contains("vertices"),
        "{d}"
    );

    export_and_relight(dir.path(), &s, &t1, 3);
}

/// The covered texels of object `o`'s lightmap.
fn covered(b: &prt_bakefile::Bake, o: usize) -> usize {
    b.objects[o]
        .coverage
        .as_ref()
        .unwrap()
        .hits
        .iter()
        .filter(|&&h| h > 0)
        .count()
}

/// Exports the per-texel bake `bake` (order `order`) of scene `s`, validates the `.glb` and
/// relights it with `tools/gltf_relight.py` from the file alone against `prt relight`'s texel
/// radiance: every covered texel within `Q + γ_N·(M + Q)` (`Q` the script's bound for the
/// 8-bit codes, `M` its magnitudes, `γ_N` the f32 rounding of prt's sums, as in
/// export_cli.rs), and the script finds exactly the bake's covered texels.
fn export_and_relight(dir: &Path, s: &Path, bake: &Path, order: usize) {
    let b = prt_bakefile::read_bake(bake).unwrap();
    let glb = dir.join("t.glb");
    run(prt()
        .arg("export")
        .arg(s)
        .arg("--bake")
        .arg(bake)
        .arg("--out")
        .arg(&glb));
    validate(&glb);
    let Some(py) = common::python_or_skip() else {
        return;
    };
    let csv = |n: &str| dir.join(format!("{n}.csv"));
    relight_vertex_colours(s, bake, &csv("prt"));
    let ours = read_rows(&csv("prt"));
    let (theirs, mags, quant) = gltf_relight_texels(&py, &glb, csv);
    let gamma = texel_sum_gamma(order);
    for (k, o) in b.objects.iter().enumerate() {
        let (a, m, q) = (&theirs[&o.name], &mags[&o.name], &quant[&o.name]);
        let mine: std::collections::HashMap<usize, [f64; 3]> =
            ours[&o.name].iter().copied().collect();
        assert_eq!(a.len(), covered(&b, k), "{}: covered texels", o.name);
        let mut worst = 0.0f64;
        for ((p, x), ((_, mp), (_, qp))) in a.iter().zip(m.iter().zip(q)) {
            let y = mine[&(*p + o.point_first as usize)];
            for c in 0..3 {
                let bound = qp[c] + gamma * (mp[c] + qp[c]) + 1e-30;
                let d = (x[c] - y[c]).abs();
                worst = worst.max(d / bound);
                assert!(
                    d <= bound,
                    "{} texel {p} channel {c}: gltf_relight.py {} vs prt {} (bound {bound})",
                    o.name,
                    x[c],
                    y[c]
                );
            }
        }
        eprintln!("{}: worst texel at {worst:.3} of its bound", o.name);
    }
}

/// The other kinds of bake an engine reads through an atlas: one bounce between a coloured
/// suzanne and a grey floor makes the transfer differ per channel (three transfer channels,
/// SPEC §3.9), and that file too exports, validates and relights from the `.glb` alone to
/// prt's texel radiance.
#[test]
fn a_bounced_multichannel_atlas_bake_relights_from_the_glb_alone() {
    let dir = tempfile::tempdir().unwrap();
    let s = suzanne_on_floor(dir.path(), "brick", "clay");
    let path = dir.path().join("bounced.prtb");
    run(prt()
        .arg("bake")
        .arg(&s)
        .args(["--rays", "16", "--order", "3", "--bounces", "1"])
        .args(["--per-texel", "192", "--out"])
        .arg(&path));
    let b = prt_bakefile::read_bake(&path).unwrap();
    assert!(
        b.objects.iter().all(|o| o.channels == 3),
        "a bounced coloured scene has per-channel transfer"
    );
    assert!(b.meta.settings["lightmaps"][0]["atlas"].is_array());
    export_and_relight(dir.path(), &s, &path, 3);
}

/// The Khronos glTF-Validator on `glb` (skipped, with a line, when it is not installed):
/// no error, no warning.
fn validate(glb: &Path) {
    let tools = repo().join("tools");
    let node = Command::new("node").arg("--version").output();
    if !tools.join("node_modules/gltf-validator").exists()
        || !node.is_ok_and(|o| o.status.success())
    {
        assert!(
            std::env::var("PRT_REQUIRE_GLTF_VALIDATOR").as_deref() != Ok("1"),
            "PRT_REQUIRE_GLTF_VALIDATOR=1 but tools/node_modules/gltf-validator or node is missing"
        );
        eprintln!("skipped the validator: npm install --prefix tools gltf-validator");
        return;
    }
    let out = Command::new("node")
        .arg(tools.join("gltf_validate.js"))
        .arg(glb)
        .output()
        .unwrap();
    let report = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success()
            && report.contains("\"errors\":0")
            && report.contains("\"warnings\":0"),
        "{report}"
    );
}

/// A smooth case: a unit sphere alone under the sky (convex: no shadows or bounces, so every
/// point's radiance is the same degree-2 spherical polynomial `E(n)` of its normal at order
/// 3, plus Monte Carlo noise). Each covered texel of the per-texel bake (through its
/// generated atlas) is compared with the per-vertex bake interpolated at the texel's surface
/// point. The bound, per channel:
/// * interpolation: the vertex bake interpolates `E` linearly over a triangle whose vertex
///   normals span at most `h` radians, while the texel holds `E` at the normalised
///   interpolated normal. By Bernstein's inequality for spherical polynomials of degree 2,
///   `E`'s first and second derivatives along great circles are at most `2·‖E − c‖` and
///   `4·‖E − c‖`, i.e. `R` and `2R` with `R` the range (max − min) of `E`; the linear
///   interpolation error is at most `½·2R·h²` and the normalisation moves the point by at
///   most `h²/2` radians (`R·h²/2`): `1.5·R·h²` in all;
/// * noise: both bakes trace the same number of rays per point with independent streams
///   (texels and vertices have their own keys); the largest difference between two seeds of
///   the per-vertex bake over its 2112 vertices bounds one point's noise (it is about 5
///   standard deviations of one bake at the noisiest vertex), and the texel and the
///   interpolated vertices add two such terms.
#[test]
fn per_texel_through_an_atlas_agrees_with_per_vertex_on_a_smooth_sphere() {
    let dir = tempfile::tempdir().unwrap();
    let m = repo().join("scenes/hard/sphere.obj");
    let s = scene(
        dir.path(),
        &format!("[[objects]]\nmesh = {m:?}\nmaterial = \"clay\"\n"),
    );
    let bake = |name: &str, args: &[&str]| {
        let path = dir.path().join(format!("{name}.prtb"));
        run(prt()
            .arg("bake")
            .arg(&s)
            .args(["--rays", "512", "--order", "3"])
            .args(args)
            .arg("--out")
            .arg(&path));
        let csv = dir.path().join(format!("{name}.csv"));
        relight_vertex_colours(&s, &path, &csv);
        let rows = read_rows(&csv).into_values().next().unwrap();
        (path, rows.into_iter().map(|(_, c)| c).collect::<Vec<_>>())
    };
    let (_, v1) = bake("v1", &["--seed", "1"]);
    let (_, v2) = bake("v2", &["--seed", "2"]);
    let (tp, texels) = bake("t", &["--seed", "1", "--per-texel", "96"]);
    let scene = prt_scene::load_scene(&s).unwrap().scene;
    let tb = prt_bakefile::read_bake(&tp).unwrap();
    let lm = prt_scene_relight::relit::lightmaps(&scene, &tb).unwrap()[0]
        .clone()
        .expect("the sphere is lightmapped through its atlas");
    assert!(lm.corner_uvs.is_some());
    let mesh = &scene.meshes[0];
    let h = mesh
        .indices
        .iter()
        .map(|t| {
            let n = t.map(|i| mesh.normals[i as usize].as_dvec3());
            [(0, 1), (1, 2), (2, 0)]
                .map(|(a, b)| n[a].angle_between(n[b]))
                .into_iter()
                .fold(0.0f64, f64::max)
        })
        .fold(0.0f64, f64::max);
    let mut worst = 0.0f64;
    for c in 0..3 {
        let range = v1.iter().map(|v| v[c]).fold(f64::NEG_INFINITY, f64::max)
            - v1.iter().map(|v| v[c]).fold(f64::INFINITY, f64::min);
        let noise = v1
            .iter()
            .zip(&v2)
            .map(|(a, b)| (a[c] - b[c]).abs())
            .fold(0.0f64, f64::max);
        let bound = 1.5 * range * h * h + 2.0 * noise;
        for (k, t) in lm.texels.iter().enumerate() {
            let Some(t) = t else { continue };
            let tri = mesh.indices[t.triangle as usize];
            let interp: f64 = (0..3)
                .map(|i| f64::from(t.bary[i]) * v1[tri[i] as usize][c])
                .sum();
            let d = (texels[k][c] - interp).abs();
            worst = worst.max(d / bound);
            assert!(
                d <= bound,
                "texel {k} channel {c}: per texel {} vs per vertex {interp} (bound {bound}: range {range}, h {h}, noise {noise})",
                texels[k][c]
            );
        }
        eprintln!(
            "channel {c}: range {range:.4}, h {h:.4} rad, noise {noise:.2e}, bound {bound:.2e}"
        );
    }
    eprintln!("{} texels, worst at {worst:.3} of the bound", lm.covered());
}
