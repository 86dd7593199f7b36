//! `prt export` (issue 15, export): a per-vertex bake as binary glTF 2.0 that the Khronos
//! glTF-Validator accepts with no error and no warning, that reads back (through the `gltf`
//! crate) to exactly the bake's numbers, and whose documented relighting formula, applied to
//! the file alone, gives `prt relight`'s vertex colours.
//!
//! The validator is the npm package gltf-validator (`npm install --prefix tools
//! gltf-validator`); without it (or Node.js) that part says it is skipped, unless
//! `PRT_REQUIRE_GLTF_VALIDATOR=1` (which CI sets after installing it).

mod common;

use common::{
    gltf_relight_texels, prt, read_rows, relight_vertex_colours, run, texel_sum_gamma, write_scene,
};
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

/// A `.glb`'s JSON document and its binary chunk.
fn glb_parts(glb: &Path) -> (serde_json::Value, Vec<u8>) {
    let bytes = std::fs::read(glb).unwrap();
    let len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let doc = serde_json::from_slice(&bytes[20..20 + len]).unwrap();
    (doc, bytes[20 + len + 8..].to_vec())
}

/// `prt_scene_relight::relight` of `bake` in this process (default options), with the BVH for
/// image formation.
fn relit_here(
    scene: &prt_scene::Scene,
    bake: &prt_bakefile::Bake,
) -> (prt_tracer::Accel, prt_scene_relight::Relit) {
    let accel = prt_tracer::Accel::build(scene).unwrap();
    let relit = prt_scene_relight::relight(
        scene,
        &accel,
        bake,
        &prt_scene_relight::RelightOptions::default(),
    )
    .unwrap();
    (accel, relit)
}

/// Mesh `mesh` of the export `glb`: its `extras.prt.environment` (`[coefficient][r, g, b]`)
/// and its uniform diffuse albedo `extras.prt.albedo`.
fn lighting_and_albedo(glb: &Path, mesh: usize) -> (Vec<[f64; 3]>, Vec<f64>) {
    let (doc, _) = glb_parts(glb);
    let prim = &doc["meshes"][mesh]["primitives"][0];
    let env = serde_json::from_value(prim["extras"]["prt"]["environment"].clone()).unwrap();
    let albedo = serde_json::from_value(prim["extras"]["prt"]["albedo"].clone()).unwrap();
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
        let back = prt_gltf::read_export(&glb).unwrap();
        let b = prt_bakefile::read_bake(&bake).unwrap();
        assert_eq!(back.len(), b.objects.len());
        for (e, o) in back.iter().zip(&b.objects) {
            assert_eq!(e.name, o.name);
            assert_eq!(
                (e.order, e.channels),
                (o.order as usize, o.channels as usize)
            );
            assert_eq!(e.positions, o.mesh.as_ref().unwrap().positions);
            let block = o.diffuse_block().unwrap();
            assert!(
                e.transfer == block.data,
                "{}: transfer differs after the round trip",
                o.name
            );
        }

        // The documented formula on the file's own numbers against prt relight.
        let colours = dir.path().join("colours.csv");
        relight_vertex_colours(&scene, &bake, &colours);
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

/// `object,point,r,g,b` CSV (`prt relight --vertex-colours`, `tools/gltf_relight.py`) by
/// object name: each point's radiance, every point from 0 in order.
fn read_colours(path: &Path) -> std::collections::HashMap<String, Vec<[f64; 3]>> {
    read_rows(path)
        .into_iter()
        .map(|(name, rows)| {
            for (k, (p, _)) in rows.iter().enumerate() {
                assert_eq!(*p, k, "{}: points out of order", path.display());
            }
            (name, rows.into_iter().map(|(_, rgb)| rgb).collect())
        })
        .collect()
}

/// `tools/gltf_relight.py` on the export `glb` (`None` when there is no Python with numpy and
/// CI does not insist), checked against `prt relight`'s vertex radiance `prt_csv` of the same
/// bake at `order`: every vertex and channel within the float32 rounding bound of the
/// formula, `γ_N · M` with `M` the script's `--magnitudes` (each sum with every factor's
/// absolute value; the f64 script itself is exact to ~1e-15 of `M`) and `N = n⁴ + n² + 16 +
/// 4·4·n` the longest chain of f32 roundings in prt's sums (the `L ⊛ V` product and the
/// lobe's `n²` weights, the diffuse sum, up to four lobes of four table rows each, and the
/// scalar factors). A formula that differs from prt's by a term shows as a difference of
/// that term's size, orders above the bound. Returns the script's radiance by object.
fn gltf_relight_agrees(
    glb: &Path,
    prt_csv: &Path,
    order: usize,
    dir: &Path,
) -> Option<std::collections::HashMap<String, Vec<[f64; 3]>>> {
    let py = common::python_or_skip()?;
    let (py_csv, mag_csv) = (dir.join("py.csv"), dir.join("magnitudes.csv"));
    run(Command::new(py)
        .arg(tools().join("gltf_relight.py"))
        .arg(glb)
        .arg("--colours")
        .arg(&py_csv)
        .arg("--magnitudes")
        .arg(&mag_csv));
    let (theirs, ours, mags) = (
        read_colours(&py_csv),
        read_colours(prt_csv),
        read_colours(&mag_csv),
    );
    assert_eq!(theirs.len(), ours.len());
    let n = order;
    let gamma = (n.pow(4) + n * n + 16 + 16 * n) as f64 * f64::from(f32::EPSILON) / 2.0;
    for (name, b) in &ours {
        let (a, m) = (&theirs[name], &mags[name]);
        assert_eq!((a.len(), m.len()), (b.len(), b.len()));
        let mut worst = 0.0f64;
        for (p, ((x, y), m)) in a.iter().zip(b).zip(m).enumerate() {
            for c in 0..3 {
                let d = (x[c] - y[c]).abs();
                worst = worst.max(d / (gamma * m[c]).max(1e-30));
                assert!(
                    d <= gamma * m[c] + 1e-30,
                    "{name} vertex {p} channel {c}: gltf_relight.py {} vs prt {} (bound {})",
                    x[c],
                    y[c],
                    gamma * m[c]
                );
            }
        }
        eprintln!("{name}: worst vertex at {worst:.3} of the f32 bound");
    }
    Some(theirs)
}

/// A textured glTF asset with its own material (Khronos BoxTextured, a textured `pbr` cube, on
/// a `pbr` floor: `scenes/box_textured.toml`) exports everything `prt relight` shades it with
/// (SPEC §10.1): its own glTF material (base colour texture, UVs, sampler), the diffuse albedo
/// per vertex as `_PRT_ALBEDO` (texture at the vertex's UV times `(1 − m)·0.96`), the `pbr`
/// diffuse factor's table, the visibility transfer and the fitted
/// specular lobe with its per-vertex colours. The file validates cleanly, reads back to the
/// bake's visibility bit for bit, and `tools/gltf_relight.py` — SPEC §10 implemented from its
/// text alone, in numpy, with the `L ⊛ V` product by quadrature rather than Gaunt
/// coefficients — relights the file to `prt relight`'s radiance at every vertex, and so to
/// its image.
#[test]
fn textured_asset_export_relights_like_prt() {
    let scene_path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/box_textured.toml");
    let dir = tempfile::tempdir().unwrap();
    let (bake_path, glb) = bake_and_export(
        &scene_path,
        dir.path(),
        "box",
        &["--rays", "32", "--order", "4", "--bounces", "0"],
    );
    assert_validates(&glb);
    let back = prt_gltf::read_export(&glb).unwrap();
    let bake = prt_bakefile::read_bake(&bake_path).unwrap();
    let boxed = back
        .iter()
        .find(|e| e.name.starts_with("BoxTextured"))
        .unwrap();
    assert_eq!(boxed.albedo.len(), boxed.positions.len());
    // The texture is sRGB-decoded colour in [0, 1]; the dielectric's diffuse albedo is 0.96
    // of it.
    assert!(boxed
        .albedo
        .iter()
        .flatten()
        .all(|c| (0.0..=0.96 + 1e-6).contains(c)));
    assert_eq!(
        back.iter()
            .find(|e| e.name == "floor.obj")
            .unwrap()
            .albedo
            .len(),
        1
    );
    for (e, o) in back.iter().zip(&bake.objects) {
        let vis = o
            .blocks
            .iter()
            .find(|b| b.kind == prt_bakefile::TransferKind::Visibility)
            .expect("pbr objects bake visibility");
        assert!(
            e.visibility.as_deref() == Some(&vis.data[..]),
            "{}: visibility differs after the round trip",
            e.name
        );
    }

    // The asset's own material travels too: its base-colour texture (the scene's texels after
    // the 8-bit round trip), its wrap modes and the UV set it reads, bit for bit.
    let scene = prt_scene::load_scene(&scene_path).unwrap().scene;
    let scene = prt_scene_relight::baked_scene(&scene, &bake).unwrap();
    let o = bake
        .objects
        .iter()
        .position(|x| x.name.starts_with("BoxTextured"))
        .unwrap();
    let prt_scene::Material::Pbr {
        base_color_texture: Some(t),
        ..
    } = scene.materials[scene.meshes[o].material]
    else {
        panic!("the box's material is a textured pbr");
    };
    let source = &scene.textures[t.index];
    let (doc, bin) = glb_parts(&glb);
    let at = |v: &serde_json::Value| v.as_u64().unwrap() as usize;
    let view_bytes = |view: usize| -> &[u8] {
        let v = &doc["bufferViews"][view];
        let off = v["byteOffset"].as_u64().unwrap_or(0) as usize;
        &bin[off..off + at(&v["byteLength"])]
    };
    let prim = &doc["meshes"][o]["primitives"][0];
    let info = &doc["materials"][at(&prim["material"])]["pbrMetallicRoughness"]["baseColorTexture"];
    let texture = &doc["textures"][at(&info["index"])];
    let png = view_bytes(at(&doc["images"][at(&texture["source"])]["bufferView"]));
    let decoded = image::load_from_memory(png).unwrap().to_rgba8();
    assert_eq!(
        (decoded.width() as usize, decoded.height() as usize),
        (source.width, source.height)
    );
    // sRGB decoding (IEC 61966-2-1), as CONVENTIONS.md states it for base colours.
    let linear = |code: u8| {
        let v = f32::from(code) / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    for (p, q) in decoded.pixels().zip(&source.texels) {
        for c in 0..3 {
            assert!((linear(p[c]) - q[c]).abs() <= 1e-6, "{p:?} vs {q:?}");
        }
        assert!((f32::from(p[3]) / 255.0 - q[3]).abs() <= 1e-6);
    }
    let wrap = |w: prt_scene::Wrap| match w {
        prt_scene::Wrap::Repeat => 10497,
        prt_scene::Wrap::MirroredRepeat => 33648,
        prt_scene::Wrap::ClampToEdge => 33071,
    };
    let sampler = &doc["samplers"][at(&texture["sampler"])];
    assert_eq!(at(&sampler["wrapS"]), wrap(source.wrap[0]));
    assert_eq!(at(&sampler["wrapT"]), wrap(source.wrap[1]));
    let uv_accessor =
        &doc["accessors"][at(&prim["attributes"][format!("TEXCOORD_{}", at(&info["texCoord"]))])];
    let uvs: Vec<f32> = view_bytes(at(&uv_accessor["bufferView"]))
        .chunks_exact(4)
        .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
        .collect();
    assert_eq!(
        uvs,
        scene.meshes[o].texcoords[t.texcoord]
            .iter()
            .flatten()
            .copied()
            .collect::<Vec<f32>>()
    );

    let prt_csv = dir.path().join("prt.csv");
    relight_vertex_colours(&scene_path, &bake_path, &prt_csv);
    let Some(theirs) = gltf_relight_agrees(&glb, &prt_csv, 4, dir.path()) else {
        return;
    };
    assert_eq!(theirs.len(), back.len());
    let (accel, mut relit) = relit_here(&scene, &bake);
    let prt_colours = read_colours(&prt_csv);
    let prt_img = prt_scene_relight::form_image(&scene, &accel, &relit, 0.0).unwrap();
    let (mut vertex_peak, mut worst) = (0.0f64, 0.0f64);
    for (o, obj) in bake.objects.iter().enumerate() {
        let a = &theirs[&obj.name];
        for (x, y) in a.iter().zip(&prt_colours[&obj.name]) {
            for c in 0..3 {
                vertex_peak = vertex_peak.max(x[c].abs());
                worst = worst.max((x[c] - y[c]).abs());
            }
        }
        relit.radiance[o] = a.iter().map(|x| x.map(|v| v as f32)).collect();
    }
    // The image: each pixel interpolates its triangle's vertex radiance with weights summing to
    // one, so the two images differ by no more than the vertices do (plus the f32 rounding of
    // the interpolation, a few u of the peak).
    let theirs_img = prt_scene_relight::form_image(&scene, &accel, &relit, 0.0).unwrap();
    let max_diff = theirs_img
        .pixels
        .iter()
        .zip(&prt_img.pixels)
        .flat_map(|(a, b)| (0..3).map(move |c| (a[c] - b[c]).abs()))
        .fold(0.0f32, f32::max);
    let max_diff = f64::from(max_diff);
    eprintln!(
        "image: max difference {:.2e} of the brightest vertex (vertices: {:.2e})",
        max_diff / vertex_peak,
        worst / vertex_peak
    );
    assert!(
        max_diff <= worst + 8.0 * f64::from(f32::EPSILON) * vertex_peak,
        "{max_diff} vs the vertices' {worst} (brightest {vertex_peak})"
    );
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
    let back = prt_gltf::read_export(&glb).unwrap();
    let bake = prt_bakefile::read_bake(&bake_path).unwrap();
    let scene = prt_scene::load_scene(&scene_path).unwrap().scene;
    let lightmaps = prt_scene_relight::relit::lightmaps(&scene, &bake).unwrap();
    // The bunny (no UVs) stays per vertex, bit for bit.
    let bunny = &back[0];
    assert!(bunny.lightmap.is_none());
    assert!(bunny.transfer == bake.objects[0].diffuse_block().unwrap().data);
    // The floor: its covered texels (bake point k is texel k) within half a step.
    let floor = &back[1];
    let lm = floor.lightmap.as_ref().expect("the floor is lightmapped");
    let ours = lightmaps[1].as_ref().unwrap();
    assert_eq!((lm.width, lm.height), (48, 48));
    assert_eq!(lm.uvs.len(), floor.positions.len());
    let data = &bake.objects[1].diffuse_block().unwrap().data;
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
    let (accel, mut relit) = relit_here(&scene, &bake);
    let any = *ours.texels.iter().flatten().next().unwrap();
    let mut all = ours.clone();
    all.texels = vec![Some(any); all.texels.len()];
    std::sync::Arc::make_mut(&mut relit.lightmaps)[1] = Some(all);
    relit.radiance[1] = texel_radiance;
    let engine = prt_scene_relight::form_image(&scene, &accel, &relit, 0.0).unwrap();
    let engine_path = dir.path().join("engine.exr");
    prt_scene_relight::io::write_exr(&engine_path, &engine, &[]).unwrap();
    let psnr = common::psnr_ldr(&engine_path, &image);
    eprintln!("engine-style lookup of the export against prt relight: {psnr:.2} dB");
    assert!(psnr > 40.0, "{psnr}");
}

/// A glTF grid of `n × n` vertices over `[−1, 1]²` at `y = 0` (normals +Y, `TEXCOORD_0` the
/// unit square) whose metallic-roughness material reads its roughness (G, 0.15 → 0.95 along
/// `u`) and metallic (B, 0 → 1 along `v`) from a 4 × 4 texture: `DIR/grid.gltf` with
/// `grid.bin` and `mr.png` beside it.
fn write_rough_grid(dir: &Path, n: usize) -> std::path::PathBuf {
    let mut bin = Vec::new();
    let step = 2.0 / (n - 1) as f32;
    let at = |i: usize| -1.0 + step * i as f32;
    for z in 0..n {
        for x in 0..n {
            bin.extend([at(x), 0.0, at(z)].iter().flat_map(|v| v.to_le_bytes()));
        }
    }
    let normals = bin.len();
    for _ in 0..n * n {
        bin.extend([0.0f32, 1.0, 0.0].iter().flat_map(|v| v.to_le_bytes()));
    }
    let uvs = bin.len();
    for z in 0..n {
        for x in 0..n {
            let uv = [x as f32 / (n - 1) as f32, z as f32 / (n - 1) as f32];
            bin.extend(uv.iter().flat_map(|v| v.to_le_bytes()));
        }
    }
    let indices = bin.len();
    let mut count = 0;
    for z in 0..n - 1 {
        for x in 0..n - 1 {
            let v = (z * n + x) as u32;
            let n = n as u32;
            for i in [v, v + n, v + 1, v + 1, v + n, v + n + 1] {
                bin.extend(i.to_le_bytes());
                count += 1;
            }
        }
    }
    std::fs::write(dir.join("grid.bin"), &bin).unwrap();
    let mr = image::RgbaImage::from_fn(4, 4, |x, y| {
        image::Rgba([0, (40 + 60 * x) as u8, (85 * y) as u8, 255])
    });
    mr.save(dir.join("mr.png")).unwrap();
    let v = n * n;
    let doc = serde_json::json!({
        "asset": {"version": "2.0"},
        "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{
            "attributes": {"POSITION": 0, "NORMAL": 1, "TEXCOORD_0": 2},
            "indices": 3, "material": 0,
        }]}],
        "materials": [{"pbrMetallicRoughness": {
            "baseColorFactor": [0.9, 0.6, 0.3, 1.0], "metallicFactor": 1.0, "roughnessFactor": 1.0,
            "metallicRoughnessTexture": {"index": 0},
        }}],
        "textures": [{"source": 0}],
        "images": [{"uri": "mr.png"}],
        "buffers": [{"uri": "grid.bin", "byteLength": bin.len()}],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": normals},
            {"buffer": 0, "byteOffset": normals, "byteLength": uvs - normals},
            {"buffer": 0, "byteOffset": uvs, "byteLength": indices - uvs},
            {"buffer": 0, "byteOffset": indices, "byteLength": bin.len() - indices},
        ],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": v, "type": "VEC3",
             "min": [-1.0, 0.0, -1.0], "max": [1.0, 0.0, 1.0]},
            {"bufferView": 1, "componentType": 5126, "count": v, "type": "VEC3"},
            {"bufferView": 2, "componentType": 5126, "count": v, "type": "VEC2"},
            {"bufferView": 3, "componentType": 5125, "count": count, "type": "SCALAR"},
        ],
    });
    let path = dir.join("grid.gltf");
    std::fs::write(&path, serde_json::to_vec_pretty(&doc).unwrap()).unwrap();
    path
}

/// A `pbr` material whose roughness and metallic vary over the surface (a metallic-roughness
/// texture on a glTF grid, under the bunny): the export carries the fitted lobe at several
/// roughness levels with each vertex's roughness (`_PRT_ROUGHNESS`) and colour weights
/// (`_PRT_SPEC_A`, `_PRT_SPEC_B`), validates cleanly, and `tools/gltf_relight.py` relights it
/// to `prt relight`'s vertex radiance (the bilinear (roughness, θ_o) rows of SPEC §10.1).
#[test]
fn roughness_texture_export_relights_like_prt() {
    let dir = tempfile::tempdir().unwrap();
    write_rough_grid(dir.path(), 17);
    let bunny = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/bunny_lowres.obj");
    let map = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/maps/studio.exr");
    let scene = dir.path().join("scene.toml");
    std::fs::write(
        &scene,
        format!(
            r#"[camera]
eye = [0.4, 1.6, 2.4]
target = [0.0, 0.0, 0.0]
fov_y = 45.0
resolution = [48, 32]

[environment]
file = "{}"

[materials.clay]
type = "lambert"
albedo = [0.6, 0.6, 0.6]

[[objects]]
mesh = "grid.gltf"

[[objects]]
mesh = "{}"
material = "clay"
scale = 0.5
translate = [0.0, -0.2, 0.0]

[render]
bounces = 0
"#,
            map.display(),
            bunny.display()
        ),
    )
    .unwrap();
    let (_, glb) = bake_and_export(
        &scene,
        dir.path(),
        "rough",
        &["--rays", "32", "--order", "5", "--bounces", "0"],
    );
    assert_validates(&glb);
    let (doc, _) = glb_parts(&glb);
    let prim = &doc["meshes"][0]["primitives"][0];
    let spec = &prim["extras"]["prt"]["specular"];
    assert_eq!(spec["model"], "fitted");
    assert!(
        spec["roughness_levels"].as_array().unwrap().len() > 1,
        "{spec}"
    );
    for name in [
        "_PRT_ROUGHNESS",
        "_PRT_SPEC_A",
        "_PRT_SPEC_B",
        "_PRT_ALBEDO",
    ] {
        assert!(prim["attributes"].get(name).is_some(), "{name}");
    }
    assert!(prim["extras"]["prt"]["diffuse_fresnel"].is_object());
    assert!(doc["meshes"][1]["primitives"][0]["extras"]["prt"]["specular"].is_null());

    let prt_csv = dir.path().join("prt.csv");
    relight_vertex_colours(&scene, &dir.path().join("rough.prtb"), &prt_csv);
    let theirs = gltf_relight_agrees(&glb, &prt_csv, 5, dir.path());
    assert!(theirs.is_none_or(|t| t.len() == 2));
}

/// Bounced bakes (issue 30): with one or more bounces every object has three channels, and so
/// do its visibility blocks (every channel the same, SPEC §3.4). The export's `_PRT_V_*` must
/// be the visibility of each vertex's own point (channel 0), not the 3-channel block read with
/// a 1-channel stride (which gave vertex `v` the visibility of point `⌊v/3⌋`). On the Phong
/// wall and the Lambert floor of the tiny scene at 1 and 2 bounces, and on the textured `pbr`
/// asset at 1 bounce: the visibility reads back bit for bit, and `tools/gltf_relight.py`
/// relights the file alone to `prt relight --vertex-colours` within the f32 bound at every
/// vertex; likewise the 1-bounce bake of the tiny scene compressed by clustered PCA.
#[test]
fn bounced_exports_relight_like_prt() {
    let dir = tempfile::tempdir().unwrap();
    let tiny = write_scene(dir.path(), 6);
    let box_textured = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/box_textured.toml");
    for (scene, bounces, order) in [(&tiny, "1", 4), (&tiny, "2", 4), (&box_textured, "1", 4)] {
        let name = format!(
            "b{bounces}_{}",
            scene.file_stem().unwrap().to_string_lossy()
        );
        let (bake_path, glb) = bake_and_export(
            scene,
            dir.path(),
            &name,
            &[
                "--rays",
                "32",
                "--order",
                &order.to_string(),
                "--bounces",
                bounces,
            ],
        );
        assert_validates(&glb);
        let bake = prt_bakefile::read_bake(&bake_path).unwrap();
        let back = prt_gltf::read_export(&glb).unwrap();
        let mut with_specular = 0;
        for (e, o) in back.iter().zip(&bake.objects) {
            assert_eq!(o.channels, 3, "{name} {}: a bounced object is RGB", o.name);
            let n2 = (o.order * o.order) as usize;
            let Some(vis) = o
                .blocks
                .iter()
                .find(|b| b.kind == prt_bakefile::TransferKind::Visibility)
            else {
                assert!(e.visibility.is_none());
                continue;
            };
            // Channel 0 of each point: the block repeats it in every channel.
            let channel0: Vec<f32> = vis
                .data
                .chunks(3 * n2)
                .flat_map(|p| {
                    assert!(p[..n2] == p[n2..2 * n2] && p[..n2] == p[2 * n2..]);
                    p[..n2].to_vec()
                })
                .collect();
            if let Some(v) = &e.visibility {
                assert!(v == &channel0, "{name} {}: visibility differs", o.name);
                with_specular += 1;
            }
        }
        assert!(
            with_specular > 0,
            "{name}: no object exported a specular lobe"
        );
        let prt_csv = dir.path().join(format!("{name}.csv"));
        relight_vertex_colours(scene, &bake_path, &prt_csv);
        gltf_relight_agrees(&glb, &prt_csv, order, dir.path());
    }
    // A compressed (clustered PCA) bounced bake exports its reconstructed transfer, which prt
    // relights from the clusters' means and bases: the same radiance within the f32 bound.
    let compressed = dir.path().join("b1_cpca.prtb");
    run(prt()
        .arg("compress")
        .arg(dir.path().join(format!(
            "b1_{}.prtb",
            tiny.file_stem().unwrap().to_string_lossy()
        )))
        .args(["--clusters", "2", "--out"])
        .arg(&compressed));
    let glb = dir.path().join("b1_cpca.glb");
    run(prt()
        .arg("export")
        .arg(&tiny)
        .arg("--bake")
        .arg(&compressed)
        .arg("--out")
        .arg(&glb));
    assert_validates(&glb);
    let prt_csv = dir.path().join("b1_cpca.csv");
    relight_vertex_colours(&tiny, &compressed, &prt_csv);
    gltf_relight_agrees(&glb, &prt_csv, 4, dir.path());
}

/// Bounced per-texel bakes (issue 30): the bunny per vertex and the floor per texel, at 1 and
/// 2 bounces (every object three channels), exported and relit from the `.glb` alone by
/// `tools/gltf_relight.py` (its own PNG decoder and dequantisation, `--texels covered`: the
/// texels a UV triangle touches, by SPEC §3.1). Against `prt relight --vertex-colours` of the
/// bake (unquantised transfer): every bunny vertex within the f32 bound `γ_N · M` of
/// `gltf_relight_agrees`, and every covered floor texel within `Q + γ_N · (M + Q)`, `Q` the
/// script's bound on the 8-bit codes (half a code step per coefficient, times `|albedo/π ·
/// L_i|`) and `M` its magnitudes. The script must find exactly the bake's covered texels.
#[test]
fn bounced_lightmap_exports_relight_like_prt() {
    let Some(py) = common::python_or_skip() else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = common::write_lightmap_scene(dir.path(), 0.5);
    let order = 3usize;
    for bounces in ["1", "2"] {
        let name = format!("texel_b{bounces}");
        let (bake_path, glb) = bake_and_export(
            &scene,
            dir.path(),
            &name,
            &[
                "--rays",
                "32",
                "--order",
                &order.to_string(),
                "--per-texel",
                "32",
                "--bounces",
                bounces,
            ],
        );
        assert_validates(&glb);
        let bake = prt_bakefile::read_bake(&bake_path).unwrap();
        assert!(bake.objects.iter().all(|o| o.channels == 3));
        let coverage = bake.objects[1].coverage.as_ref().expect("floor per texel");
        let covered = coverage.hits.iter().filter(|&&h| h > 0).count();
        let csv = |s: &str| dir.path().join(format!("{name}_{s}.csv"));
        relight_vertex_colours(&scene, &bake_path, &csv("prt"));
        let ours = read_rows(&csv("prt"));
        let (theirs, mags, quant) = gltf_relight_texels(&py, &glb, csv);
        let gamma = texel_sum_gamma(order);
        for (k, o) in bake.objects.iter().enumerate() {
            let (a, m, q) = (&theirs[&o.name], &mags[&o.name], &quant[&o.name]);
            let b: std::collections::HashMap<usize, [f64; 3]> =
                ours[&o.name].iter().copied().collect();
            let expected = if k == 1 {
                covered
            } else {
                o.point_count as usize
            };
            assert_eq!(a.len(), expected, "{name} {}: rows", o.name);
            let mut worst = 0.0f64;
            for ((p, x), ((_, mp), (_, qp))) in a.iter().zip(m.iter().zip(q)) {
                let y = b[&(*p + o.point_first as usize)];
                for c in 0..3 {
                    let bound = qp[c] + gamma * (mp[c] + qp[c]) + 1e-30;
                    let d = (x[c] - y[c]).abs();
                    worst = worst.max(d / bound);
                    assert!(
                        d <= bound,
                        "{name} {} point {p} channel {c}: gltf_relight.py {} vs prt {} (bound {bound})",
                        o.name,
                        x[c],
                        y[c]
                    );
                }
            }
            eprintln!("{name} {}: worst point at {worst:.3} of its bound", o.name);
        }
    }
}

/// `tools/gltf_relight.py --self-test`: the independent relighter's own checks (SH closed
/// forms, its PNG decoder on every filter type and on malformed PNGs, dequantisation, texel
/// coverage) pass, so a disagreement in the tests above is not the script's.
#[test]
fn independent_relighter_passes_its_self_test() {
    let Some(py) = common::python_or_skip() else {
        return;
    };
    let out = run(Command::new(py)
        .arg(tools().join("gltf_relight.py"))
        .arg("--self-test"));
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(": PASS"), "{text}");
}

/// `prt export --target webgl2|desktop` (SPEC §10.2, issue 33): an order-10 bake (75 transfer
/// attributes per vertex as `raw`, three channels and visibility when bounced) fits 16 vertex
/// attributes per primitive, its transfer in a float data texture within the target's size;
/// the file validates, reads back to exactly the raw export's numbers, and
/// `tools/gltf_relight.py` (written from the SPEC alone) relights it to `prt relight`'s
/// radiance within the f32 bound, at 0 and 1 bounce and for a clustered-PCA compressed bake.
/// A low-order bake that fits is written byte for byte as `raw`.
#[test]
fn target_exports_fit_the_attribute_budget_and_relight_like_prt() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 6);
    for bounces in ["0", "1"] {
        let name = format!("o10_b{bounces}");
        let (bake_path, raw) = bake_and_export(
            &scene,
            dir.path(),
            &name,
            &["--rays", "32", "--order", "10", "--bounces", bounces],
        );
        let raw_back = prt_gltf::read_export(&raw).unwrap();
        let prt_csv = dir.path().join(format!("{name}.csv"));
        relight_vertex_colours(&scene, &bake_path, &prt_csv);
        for (target, limit) in [("webgl2", 2048u64), ("desktop", 4096)] {
            let glb = dir.path().join(format!("{name}.{target}.glb"));
            let out = common::json(&run(prt()
                .arg("export")
                .arg(&scene)
                .arg("--bake")
                .arg(&bake_path)
                .args(["--target", target, "--json", "--out"])
                .arg(&glb)));
            assert_eq!(out["target"], target);
            assert!(out["vertex_attributes"].as_u64().unwrap() <= 16, "{out}");
            assert_eq!(out["transfer_textures"], 2, "both objects: {out}");
            let (doc, _) = glb_parts(&glb);
            for mesh in doc["meshes"].as_array().unwrap() {
                let prim = &mesh["primitives"][0];
                let attributes = prim["attributes"].as_object().unwrap();
                assert!(attributes.len() <= 16, "{}", mesh["name"]);
                assert!(attributes.keys().all(|k| !k.starts_with("_PRT_C")));
                let prt = &prim["extras"]["prt"];
                assert_eq!(prt["storage"], "vertex_texture");
                let t = &prt["transfer_texture"];
                assert!(t["width"].as_u64().unwrap() <= limit);
                assert!(t["height"].as_u64().unwrap() <= limit);
                let channels = prt["channels"].as_u64().unwrap();
                let with_vis = !prt["specular"].is_null();
                assert_eq!(
                    t["texels_per_vertex"].as_u64().unwrap(),
                    (channels + u64::from(with_vis)) * 25
                );
            }
            assert_validates(&glb);
            let back = prt_gltf::read_export(&glb).unwrap();
            assert!(back == raw_back, "{name} {target}: reads back unlike raw");
            gltf_relight_agrees(&glb, &prt_csv, 10, dir.path());
        }
    }
    // A clustered-PCA compressed bounced bake: its reconstructed transfer in the data
    // texture, read back as the raw export of it and relit from the file alone like prt relight
    // relights the compressed bake (from its clusters).
    let compressed = dir.path().join("o10_b1_cpca.prtb");
    run(prt()
        .arg("compress")
        .arg(dir.path().join("o10_b1.prtb"))
        .args(["--clusters", "2", "--out"])
        .arg(&compressed));
    let export = |target: &str| {
        let glb = dir.path().join(format!("o10_b1_cpca.{target}.glb"));
        run(prt()
            .arg("export")
            .arg(&scene)
            .arg("--bake")
            .arg(&compressed)
            .args(["--target", target, "--out"])
            .arg(&glb));
        glb
    };
    let (raw, webgl2) = (export("raw"), export("webgl2"));
    assert_validates(&webgl2);
    assert!(prt_gltf::read_export(&webgl2).unwrap() == prt_gltf::read_export(&raw).unwrap());
    let prt_csv = dir.path().join("o10_b1_cpca.csv");
    relight_vertex_colours(&scene, &compressed, &prt_csv);
    gltf_relight_agrees(&webgl2, &prt_csv, 10, dir.path());

    // Order 3 fits 16 attributes (3 channels × 3 groups + visibility 3 + POSITION, NORMAL):
    // the same bytes as raw.
    let (bake_path, raw) = bake_and_export(
        &scene,
        dir.path(),
        "o3",
        &["--rays", "32", "--order", "3", "--bounces", "1"],
    );
    let glb = dir.path().join("o3.webgl2.glb");
    run(prt()
        .arg("export")
        .arg(&scene)
        .arg("--bake")
        .arg(&bake_path)
        .args(["--target", "webgl2", "--out"])
        .arg(&glb));
    assert!(std::fs::read(&glb).unwrap() == std::fs::read(&raw).unwrap());
}
