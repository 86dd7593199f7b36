//! `prt export` (issue 15, export): a per-vertex bake as binary glTF 2.0 that the Khronos
//! glTF-Validator accepts with no error and no warning, that reads back (through the `gltf`
//! crate) to exactly the bake's numbers, and whose documented relighting formula, applied to
//! the file alone, gives `prt relight`'s vertex colours.
//!
//! The validator is the npm package gltf-validator (`npm install --prefix tools
//! gltf-validator`); without it (or Node.js) that part says it is skipped, unless
//! `PRT_REQUIRE_GLTF_VALIDATOR=1` (which CI sets after installing it).

mod common;

use common::{prt, run, write_scene};
use std::path::Path;
use std::process::Command;

fn tools() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools")
}

fn validator_available() -> bool {
    tools().join("node_modules/gltf-validator").exists()
        && Command::new("node")
            .arg("--version")
            .output()
            .is_ok_and(|o| o.status.success())
}

/// `prt bake SCENE ARGS --out DIR/NAME.prtb`, then `prt export` of it to `DIR/NAME.glb`.
fn bake_and_export(
    scene: &std::path::Path,
    dir: &std::path::Path,
    name: &str,
    args: &[&str],
) -> (std::path::PathBuf, std::path::PathBuf) {
    let bake = dir.join(format!("{name}.prtb"));
    run(prt()
        .arg("bake")
        .arg(scene)
        .args(args)
        .arg("--out")
        .arg(&bake));
    let glb = dir.join(format!("{name}.glb"));
    run(prt()
        .arg("export")
        .arg(scene)
        .arg("--bake")
        .arg(&bake)
        .arg("--out")
        .arg(&glb));
    (bake, glb)
}

/// The Khronos glTF-Validator on `glb`: no error, no warning (skipped, with a line, when it is
/// not installed, unless `PRT_REQUIRE_GLTF_VALIDATOR=1`).
fn assert_validates(glb: &std::path::Path) {
    if validator_available() {
        let out = Command::new("node")
            .arg(tools().join("gltf_validate.js"))
            .arg(glb)
            .output()
            .unwrap();
        let report = String::from_utf8_lossy(&out.stdout);
        eprintln!("glTF-Validator: {report}");
        assert!(
            out.status.success(),
            "{report}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(
            report.contains("\"errors\":0") && report.contains("\"warnings\":0"),
            "{report}"
        );
    } else {
        assert!(
            std::env::var("PRT_REQUIRE_GLTF_VALIDATOR").as_deref() != Ok("1"),
            "PRT_REQUIRE_GLTF_VALIDATOR=1 but tools/node_modules/gltf-validator or node is missing"
        );
        eprintln!("skipped the validator: npm install --prefix tools gltf-validator");
    }
}

/// Mesh `mesh` of the export `glb`: its `extras.prt.environment` (`[coefficient][r, g, b]`)
/// and its material's `baseColorFactor`.
fn lighting_and_albedo(glb: &Path, mesh: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    let bytes = std::fs::read(glb).unwrap();
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc: serde_json::Value = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    let prim = &doc["meshes"][mesh]["primitives"][0];
    let env = serde_json::from_value(prim["extras"]["prt"]["environment"].clone()).unwrap();
    let albedo = serde_json::from_value(
        doc["materials"][prim["material"].as_u64().unwrap() as usize]["pbrMetallicRoughness"]
            ["baseColorFactor"]
            .clone(),
    )
    .unwrap();
    (env, albedo)
}

#[test]
fn export_validates_reads_back_and_relights() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    for (bounces, order) in [("0", "4"), ("1", "5")] {
        let (bake, glb) = bake_and_export(
            &scene,
            dir.path(),
            &format!("b{bounces}"),
            &["--rays", "64", "--order", order, "--bounces", bounces],
        );

        // Read back: the same positions and transfer, bit for bit.
        let back = prt_report::export::read_export(&glb).unwrap();
        let b = prt_bakefile::read_bake(&bake).unwrap();
        assert_eq!(back.len(), b.objects.len());
        for (e, o) in back.iter().zip(&b.objects) {
            assert_eq!(e.name, o.name);
            assert_eq!(
                (e.order, e.channels),
                (o.order as usize, o.channels as usize)
            );
            assert_eq!(e.positions, o.mesh.as_ref().unwrap().positions);
            let block = prt_bake::diffuse_block(o).unwrap();
            assert!(
                e.transfer == block.data,
                "{}: transfer differs after the round trip",
                o.name
            );
        }

        // The documented formula on the file's own numbers against prt relight.
        let colours = dir.path().join("colours.csv");
        run(prt()
            .arg("relight")
            .arg(&scene)
            .arg("--bake")
            .arg(&bake)
            .arg("--vertex-colours")
            .arg(&colours));
        let text = std::fs::read_to_string(&colours).unwrap();
        let floor = back.iter().position(|e| e.name == "floor.obj").unwrap();
        let (env, albedo) = lighting_and_albedo(&glb, floor);
        let e = &back[floor];
        let n2 = e.order * e.order;
        let u = f64::from(f32::EPSILON) / 2.0;
        let mut checked = 0;
        for line in text.lines().skip(1).filter(|l| l.starts_with("floor.obj,")) {
            let f: Vec<f64> = line
                .split(',')
                .skip(1)
                .map(|x| x.parse().unwrap())
                .collect();
            let p = f[0] as usize;
            for c in 0..3 {
                let ch = if e.channels == 3 { c } else { 0 };
                let t = &e.transfer[(p * e.channels + ch) * n2..][..n2];
                let terms = t.iter().zip(&env).map(|(&t, l)| f64::from(t) * l[c]);
                let ours: f64 = terms.clone().sum::<f64>() * albedo[c] / std::f64::consts::PI;
                let scale: f64 =
                    terms.map(f64::abs).sum::<f64>() * albedo[c] / std::f64::consts::PI;
                // f32 relighting: n² products and sums, lighting and albedo/π rounded, the
                // printed f32 (the albedo itself went through f32 in the file).
                let bound = (n2 as f64 + 4.0) * u * scale + u * f[1 + c].abs() + 1e-30;
                assert!(
                    (ours - f[1 + c]).abs() <= bound,
                    "vertex {p} channel {c}: {ours} vs {}",
                    f[1 + c]
                );
            }
            checked += 1;
        }
        assert_eq!(checked, e.positions.len());

        // The Khronos validator: no error, no warning.
        assert_validates(&glb);
    }

    // Refusals: a per-pixel bake, a bake of another scene; nothing written.
    let px = dir.path().join("px.prtb");
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args([
            "--rays",
            "16",
            "--order",
            "2",
            "--per-pixel",
            "--pixel-samples",
            "1",
            "--out",
        ])
        .arg(&px));
    let out = prt()
        .arg("export")
        .arg(&scene)
        .arg("--bake")
        .arg(&px)
        .arg("--out")
        .arg(dir.path().join("px.glb"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && e.contains("per-pixel bake"), "{e}");
    let other = dir.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    let other_scene = write_scene(&other, 4);
    let out = prt()
        .arg("export")
        .arg(&other_scene)
        .arg("--bake")
        .arg(dir.path().join("b0.prtb"))
        .arg("--out")
        .arg(dir.path().join("x.glb"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && e.contains("different geometry"),
        "{e}"
    );
    assert!(!dir.path().join("px.glb").exists() && !dir.path().join("x.glb").exists());
}

/// A textured glTF asset (Khronos BoxTextured in `scenes/box_textured.toml`): the box's
/// diffuse albedo per vertex (texture at the vertex's UV, times the factor's `(1 − m)·0.96`)
/// travels as `COLOR_0`, the untextured floor keeps its factor; the file validates cleanly.
#[test]
fn textured_asset_exports_its_vertex_albedo() {
    let scene =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/box_textured.toml");
    let dir = tempfile::tempdir().unwrap();
    let (_, glb) = bake_and_export(
        &scene,
        dir.path(),
        "box",
        &["--rays", "32", "--order", "3", "--bounces", "0"],
    );
    let back = prt_report::export::read_export(&glb).unwrap();
    let boxed = back
        .iter()
        .find(|e| e.name.starts_with("BoxTextured"))
        .unwrap();
    let colors = boxed.colors.as_ref().expect("COLOR_0 on the textured box");
    assert_eq!(colors.len(), boxed.positions.len());
    // The texture is sRGB-decoded colour in [0, 1]; the dielectric's diffuse albedo is 0.96
    // of it.
    assert!(colors
        .iter()
        .flatten()
        .all(|c| (0.0..=0.96 + 1e-6).contains(c)));
    let floor = back.iter().find(|e| e.name == "floor.obj").unwrap();
    assert!(floor.colors.is_none());
    assert_validates(&glb);
}

/// A per-texel bake (the bunny per vertex, the floor's UVs shrunk to a quarter of a 48² map so
/// that its chart has inner borders) exports its floor as lightmap textures: the file
/// validates cleanly; every covered texel reads back to the bake's transfer within half a
/// quantisation step; the documented formula on the file's numbers gives `prt relight`'s
/// per-texel radiance within the bound those steps imply; and an engine's plain bilinear
/// lookup of the exported (dilated) textures forms nearly `prt relight`'s image.
#[test]
fn lightmap_export_validates_and_relights_like_prt() {
    let dir = tempfile::tempdir().unwrap();
    let scene_path = common::write_lightmap_scene(dir.path(), 0.5);
    let (bake_path, glb) = bake_and_export(
        &scene_path,
        dir.path(),
        "t",
        &["--rays", "64", "--order", "3", "--per-texel", "48"],
    );
    assert_validates(&glb);
    let back = prt_report::export::read_export(&glb).unwrap();
    let bake = prt_bakefile::read_bake(&bake_path).unwrap();
    let scene = prt_scene::load_scene(&scene_path).unwrap().scene;
    let lightmaps = prt_report::relit::lightmaps(&scene, &bake).unwrap();
    // The bunny (no UVs) stays per vertex, bit for bit.
    let bunny = &back[0];
    assert!(bunny.lightmap.is_none());
    assert!(bunny.transfer == prt_bake::diffuse_block(&bake.objects[0]).unwrap().data);
    // The floor: its covered texels (bake point k is texel k) within half a step.
    let floor = &back[1];
    let lm = floor.lightmap.as_ref().expect("the floor is lightmapped");
    let ours = lightmaps[1].as_ref().unwrap();
    assert_eq!((lm.width, lm.height), (48, 48));
    assert_eq!(lm.uvs.len(), floor.positions.len());
    let data = &prt_bake::diffuse_block(&bake.objects[1]).unwrap().data;
    let (c, n2) = (floor.channels, floor.order * floor.order);
    let row = c * n2;
    let mut k = 0;
    let mut worst = 0.0f64;
    for (t, texel) in ours.texels.iter().enumerate() {
        if texel.is_none() {
            continue;
        }
        for i in 0..row {
            let (a, b) = (lm.transfer[t * row + i], data[t * row + i]);
            let half = f64::from(lm.step[i]) / 2.0;
            // Half a step, plus the f32 rounding of the dequantisation (offset + scale·q/255).
            let bound = half + 4.0 * f64::from(f32::EPSILON) * f64::from(a.abs().max(b.abs()));
            worst = worst.max((f64::from(a) - f64::from(b)).abs() / half.max(1e-30));
            assert!(
                (f64::from(a) - f64::from(b)).abs() <= bound,
                "texel {t} coefficient {i}: {a} vs {b} (step {})",
                lm.step[i]
            );
        }
        k += 1;
    }
    assert_eq!(k, ours.covered());
    eprintln!("worst texel error: {worst:.3} half-steps");

    // The documented formula on the file's own numbers against prt relight's texel radiance.
    let colours = dir.path().join("texels.csv");
    let image = dir.path().join("prt.exr");
    run(prt()
        .arg("relight")
        .arg(&scene_path)
        .arg("--bake")
        .arg(&bake_path)
        .arg("--vertex-colours")
        .arg(&colours)
        .arg("--out")
        .arg(&image));
    let (env, albedo) = lighting_and_albedo(&glb, 1);
    let covered: Vec<usize> = (0..ours.texels.len())
        .filter(|&t| ours.texels[t].is_some())
        .collect();
    let text = std::fs::read_to_string(&colours).unwrap();
    let first_point = bake.objects[1].point_first as usize;
    let mut checked = 0;
    let mut texel_radiance = vec![[0.0f32; 3]; ours.texels.len()];
    for t in 0..ours.texels.len() {
        for (ch, r) in texel_radiance[t].iter_mut().enumerate() {
            let tc = if c == 3 { ch } else { 0 };
            let coeffs = &lm.transfer[t * row + tc * n2..][..n2];
            let v: f64 = coeffs
                .iter()
                .zip(&env)
                .map(|(&x, l)| f64::from(x) * l[ch])
                .sum();
            *r = (v * albedo[ch] / std::f64::consts::PI) as f32;
        }
    }
    for line in text.lines().skip(1).filter(|l| l.starts_with("quad.obj,")) {
        let f: Vec<f64> = line
            .split(',')
            .skip(1)
            .map(|x| x.parse().unwrap())
            .collect();
        let t = f[0] as usize - first_point;
        if ours.texels[t].is_none() {
            continue;
        }
        for ch in 0..3 {
            let tc = if c == 3 { ch } else { 0 };
            // Each coefficient off by at most half its step: Σ ½·step·|L| · albedo/π, plus
            // f32 shading (n² products and sums) on the radiance's scale.
            let bound: f64 = (0..n2)
                .map(|i| f64::from(lm.step[tc * n2 + i]) / 2.0 * env[i][ch].abs())
                .sum::<f64>()
                * albedo[ch]
                / std::f64::consts::PI
                + 1e-5 * f[1 + ch].abs();
            let ours = f64::from(texel_radiance[t][ch]);
            assert!(
                (ours - f[1 + ch]).abs() <= bound,
                "texel {t} channel {ch}: {ours} vs {} (bound {bound})",
                f[1 + ch]
            );
        }
        checked += 1;
    }
    assert_eq!(checked, covered.len());

    // An engine: plain bilinear over every texel of the exported (dilated) maps.
    let accel = prt_tracer::Accel::build(&scene).unwrap();
    let mut relit = prt_report::relight(
        &scene,
        &accel,
        &bake,
        &prt_report::RelightOptions::default(),
    )
    .unwrap();
    let any = *ours.texels.iter().flatten().next().unwrap();
    let mut all = ours.clone();
    all.texels = vec![Some(any); all.texels.len()];
    relit.lightmaps[1] = Some(all);
    relit.radiance[1] = texel_radiance;
    let engine = prt_report::form_image(&scene, &accel, &relit, 0.0).unwrap();
    let engine_path = dir.path().join("engine.exr");
    prt_report::io::write_exr(&engine_path, &engine, &[]).unwrap();
    let psnr = common::psnr_ldr(&engine_path, &image);
    eprintln!("engine-style lookup of the export against prt relight: {psnr:.2} dB");
    assert!(psnr > 40.0, "{psnr}");
}
