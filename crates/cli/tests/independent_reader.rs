//! `tools/prtb_reader.py`, a reader of the bake format written from `SPEC.md` alone (it
//! neither imports nor calls this code), against `prt` on every kind of bake: per vertex and
//! per pixel, f32 and f16, direct and interreflected, sharded and merged, and a file of the 1.0
//! writer. The two must agree on every section (coefficients to the bit, through CRC-32s of
//! their f32 values), the reader must recompute every geometry hash from the file's meshes, and
//! its numpy relighting must match `prt relight --vertex-colours` to f32 rounding.
//!
//! Needs Python 3 with numpy (`python3 -m pip install -r tools/requirements-reader.txt`; or
//! `PRT_PYTHON=/path/to/python`). Without it the test says so and passes, unless
//! `PRT_REQUIRE_PY_READER=1` (which CI sets after installing numpy), when it fails.

mod common;

use common::{prt, run, write_scene};
use prt_bakefile::{Bake, SampleKind};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn reader_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/prtb_reader.py")
}

/// The Python interpreter to run the reader with, when one with numpy is there.
fn python() -> Option<String> {
    let py = std::env::var("PRT_PYTHON").unwrap_or_else(|_| "python3".into());
    let ok = Command::new(&py)
        .args(["-c", "import numpy"])
        .output()
        .is_ok_and(|o| o.status.success());
    ok.then_some(py)
}

fn f32_crc(values: &[f32]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    for v in values {
        h.update(&v.to_le_bytes());
    }
    h.finalize()
}

fn bytes_crc<T: Copy, const N: usize>(items: &[[T; N]], to_le: impl Fn(T) -> [u8; 4]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    for item in items {
        for &x in item {
            h.update(&to_le(x));
        }
    }
    h.finalize()
}

/// Runs the reader's `--dump` on `file` and checks every field against `prt_bakefile`'s decode.
fn check_dump(py: &str, file: &Path, out: &Path) {
    let o = Command::new(py)
        .arg(reader_script())
        .arg(file)
        .arg("--dump")
        .arg(out)
        .output()
        .unwrap();
    assert!(
        o.status.success(),
        "the independent reader refused {}: {}",
        file.display(),
        String::from_utf8_lossy(&o.stderr)
    );
    let d: Value = serde_json::from_slice(&std::fs::read(out).unwrap()).unwrap();
    let bytes = std::fs::read(file).unwrap();
    let view = prt_bakefile::BakeView::new(&bytes).unwrap();
    let bake: Bake = view.to_bake().unwrap();
    let what = file.display().to_string();
    let (major, minor) = view.version();
    assert_eq!(d["version"], serde_json::json!([major, minor]), "{what}");
    assert_eq!(d["scalar_type"], view.scalar_type().name(), "{what}");
    let m = &bake.meta;
    match m.sample_kind {
        SampleKind::Vertex => assert_eq!(d["sample_kind"], "vertex"),
        SampleKind::Texel { width, height } => {
            assert_eq!(d["sample_kind"], "texel");
            assert_eq!(
                (d["width"].as_u64(), d["height"].as_u64()),
                (Some(width.into()), Some(height.into()))
            );
        }
        SampleKind::Pixel { width, height } => {
            assert_eq!(d["sample_kind"], "pixel");
            assert_eq!(
                (d["width"].as_u64(), d["height"].as_u64()),
                (Some(width.into()), Some(height.into()))
            );
        }
    }
    assert_eq!(d["bounces"], m.bounces, "{what}");
    assert_eq!(d["rays_per_point"], m.rays_per_point, "{what}");
    assert_eq!(d["seed"], m.seed.to_string(), "{what}");
    assert_eq!(
        d["shard"],
        serde_json::json!([m.shard.index, m.shard.count])
    );
    assert_eq!(
        d["camera"],
        serde_json::to_value(&m.camera).unwrap(),
        "{what}"
    );
    let objects = d["objects"].as_array().unwrap();
    assert_eq!(objects.len(), bake.objects.len(), "{what}");
    for (j, o) in objects.iter().zip(&bake.objects) {
        let hash = format!("0x{:016x}", o.geometry_hash);
        assert_eq!(j["name"], o.name.as_str());
        assert_eq!(j["geometry_hash"], hash.as_str());
        for (field, v) in [
            ("point_count", o.point_count),
            ("point_first", o.point_first),
            ("points_in_file", o.points_in_file),
            ("order", o.order.into()),
            ("channels", o.channels.into()),
        ] {
            assert_eq!(j[field].as_u64(), Some(v), "{what} {} {field}", o.name);
        }
        let blocks = j["blocks"].as_array().unwrap();
        assert_eq!(blocks.len(), o.blocks.len());
        for (jb, b) in blocks.iter().zip(&o.blocks) {
            assert_eq!(jb["kind"], b.kind.name());
            assert_eq!(jb["bounces"], b.kind.bounces());
            // Every coefficient, to the bit.
            assert_eq!(
                jb["crc32_f32"].as_u64(),
                Some(f32_crc(&b.data).into()),
                "{what} {}",
                o.name
            );
            let sum: f64 = b.data.iter().map(|&v| f64::from(v)).sum();
            let scale: f64 = b.data.iter().map(|&v| f64::from(v).abs()).sum();
            // Two f64 summation orders: each within n·2⁻⁵³ of the exact sum of |values|.
            let bound = 2.0 * b.data.len() as f64 * f64::EPSILON * scale + f64::MIN_POSITIVE;
            assert!(
                (jb["sum"].as_f64().unwrap() - sum).abs() <= bound,
                "{what} sum"
            );
        }
        match &o.mesh {
            None => {
                assert!(j["mesh"].is_null());
                assert!(j["recomputed_hash"].is_null());
            }
            Some(mesh) => {
                // The reader recomputed the hash from the MESH bytes (SPEC §5).
                assert_eq!(j["recomputed_hash"], hash.as_str(), "{what} {}", o.name);
                let jm = &j["mesh"];
                assert_eq!(jm["vertices"].as_u64(), Some(mesh.positions.len() as u64));
                assert_eq!(jm["triangles"].as_u64(), Some(mesh.triangles.len() as u64));
                let f = |x: f32| x.to_le_bytes();
                assert_eq!(
                    jm["crc32_positions"].as_u64(),
                    Some(bytes_crc(&mesh.positions, f).into())
                );
                assert_eq!(
                    jm["crc32_normals"].as_u64(),
                    Some(bytes_crc(&mesh.normals, f).into())
                );
                let u = |x: u32| x.to_le_bytes();
                assert_eq!(
                    jm["crc32_triangles"].as_u64(),
                    Some(bytes_crc(&mesh.triangles, u).into())
                );
            }
        }
        match &o.coverage {
            None => assert!(j["coverage"].is_null()),
            Some(c) => {
                let jc = &j["coverage"];
                assert_eq!(jc["pixel_samples"], c.pixel_samples);
                let sum: u64 = c.hits.iter().map(|&h| u64::from(h)).sum();
                assert_eq!(jc["hits_sum"].as_u64(), Some(sum));
                let covered = c.hits.iter().filter(|&&h| h > 0).count() as u64;
                assert_eq!(jc["covered_points"].as_u64(), Some(covered));
            }
        }
    }
    match &bake.environment {
        None => assert!(d["environment"].is_null()),
        Some(e) => {
            assert_eq!(d["environment"]["order"], e.order);
            let values: Vec<f64> = d["environment"]["values"]
                .as_array()
                .unwrap()
                .iter()
                .map(|v| v.as_f64().unwrap())
                .collect();
            assert_eq!(values, e.values, "{what} environment");
        }
    }
    let brdfs = d["brdfs"].as_array().unwrap();
    assert_eq!(brdfs.len(), bake.brdfs.len());
    for (j, b) in brdfs.iter().zip(&bake.brdfs) {
        assert_eq!(j["material"], b.material.as_str());
        let values: Vec<f64> = j["values"]
            .as_array()
            .unwrap()
            .iter()
            .map(|v| v.as_f64().unwrap())
            .collect();
        assert_eq!(values, b.values);
    }
    assert_eq!(d["glossy"].as_array().unwrap().len(), bake.glossy.len());
}

/// `prt relight --vertex-colours` and the reader's numpy relighting of object `object`.
fn check_relight(py: &str, scene: &Path, file: &Path, object: &str, albedo: [f32; 3], dir: &Path) {
    let ours = dir.join("prt.csv");
    run(prt()
        .arg("relight")
        .arg(scene)
        .arg("--bake")
        .arg(file)
        .arg("--vertex-colours")
        .arg(&ours));
    let theirs = dir.join("reader.csv");
    let albedo_arg = format!("{},{},{}", albedo[0], albedo[1], albedo[2]);
    let o = Command::new(py)
        .arg(reader_script())
        .arg(file)
        .args(["--relight", object, "--albedo", &albedo_arg, "--colours"])
        .arg(&theirs)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let rows = |p: &Path, skip_object: bool| -> Vec<(u64, [f64; 3])> {
        std::fs::read_to_string(p)
            .unwrap()
            .lines()
            .skip(1)
            .filter_map(|l| {
                let mut f: Vec<&str> = l.split(',').collect();
                if skip_object {
                    if f[0] != object {
                        return None;
                    }
                    f.remove(0);
                }
                let v = |i: usize| f[i].parse::<f64>().unwrap();
                Some((f[0].parse().unwrap(), [v(1), v(2), v(3)]))
            })
            .collect()
    };
    let ours = rows(&ours, true);
    let theirs = rows(&theirs, false);
    assert_eq!(ours.len(), theirs.len(), "{object}: point counts");
    assert!(!ours.is_empty());
    // The bound of f32 relighting: a dot product of n² terms accumulated in f32 (γ = n²·u),
    // the lighting and albedo/π rounded to f32 (3u), and the printed f32 (u·|value|), with
    // u = 2⁻²⁴, scaled by Σ|t_i||L_i| of the point (the reader works in f64).
    let bake = prt_bakefile::read_bake(file).unwrap();
    let obj = bake.objects.iter().find(|o| o.name == object).unwrap();
    let block = prt_bake::diffuse_block(obj).unwrap();
    let env = bake.environment.as_ref().unwrap();
    let n = obj.order.min(env.order) as usize;
    let (n2, en2, on2) = (
        n * n,
        (env.order * env.order) as usize,
        (obj.order * obj.order) as usize,
    );
    let ch = obj.channels as usize;
    let u = f64::from(f32::EPSILON) / 2.0;
    let mut worst = 0.0f64;
    for ((p, a), (q, b)) in ours.iter().zip(&theirs) {
        assert_eq!(p, q);
        let i = (*p - obj.point_first) as usize;
        for c in 0..3 {
            let t = &block.data[(i * ch + c.min(ch - 1)) * on2..][..n2];
            let l = &env.values[c * en2..][..n2];
            let scale: f64 = t
                .iter()
                .zip(l)
                .map(|(&t, &l)| (f64::from(t) * l).abs())
                .sum::<f64>()
                * f64::from(albedo[c])
                / std::f64::consts::PI;
            let bound = (n2 as f64 + 3.0) * u * scale + u * b[c].abs() + 1e-30;
            let err = (a[c] - b[c]).abs();
            assert!(
                err <= bound,
                "{object} point {p} channel {c}: prt {} reader {} (bound {bound:e})",
                a[c],
                b[c]
            );
            worst = worst.max(err / bound);
        }
    }
    eprintln!(
        "{}: {object}: {} points agree; worst error {:.2} of its f32 bound",
        file.display(),
        ours.len(),
        worst
    );
}

#[test]
fn independent_reader_agrees_with_prt_on_every_bake_kind() {
    let Some(py) = python() else {
        assert!(
            std::env::var("PRT_REQUIRE_PY_READER").as_deref() != Ok("1"),
            "PRT_REQUIRE_PY_READER=1 but no Python 3 with numpy (install tools/requirements-reader.txt)"
        );
        eprintln!("skipped: no Python 3 with numpy for tools/prtb_reader.py (python3 -m pip install -r tools/requirements-reader.txt)");
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let bake = |name: &str, extra: &[&str]| -> PathBuf {
        let out = dir.path().join(name);
        run(prt()
            .arg("bake")
            .arg(&scene)
            .args(["--rays", "64", "--order", "4"])
            .args(extra)
            .arg("--out")
            .arg(&out));
        out
    };
    let clay = [0.8, 0.6, 0.4];
    let files = [
        bake("vertex.prtb", &["--bounces", "0"]),
        bake("vertex_f16_b1.prtb", &["--bounces", "1", "--f16"]),
        bake(
            "pixel.prtb",
            &["--bounces", "0", "--per-pixel", "--pixel-samples", "4"],
        ),
        bake(
            "pixel_f16_b1.prtb",
            &[
                "--bounces",
                "1",
                "--per-pixel",
                "--pixel-samples",
                "2",
                "--f16",
            ],
        ),
    ];
    // Sharded and merged: the reader reads each shard and the merged file.
    let shards: Vec<PathBuf> = (0..3)
        .map(|i| {
            bake(
                &format!("shard{i}.prtb"),
                &["--bounces", "1", "--f16", "--shard", &format!("{i}/3")],
            )
        })
        .collect();
    let merged = dir.path().join("merged.prtb");
    run(prt().arg("merge").args(&shards).arg("--out").arg(&merged));
    let v10 =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../bakefile/tests/data/v1_0_sample_f16.prtb");
    // Compressed (clustered PCA, SPEC §3.13): the reader reconstructs the blocks itself; its
    // CRC-32s of the reconstruction must match prt's bit for bit.
    let compressed = dir.path().join("compressed.prtb");
    run(prt()
        .arg("compress")
        .arg(&files[1])
        .args(["--clusters", "3", "--out"])
        .arg(&compressed));
    let dump = dir.path().join("dump.json");
    for f in files
        .iter()
        .chain(&shards)
        .chain([&merged, &v10, &compressed])
    {
        check_dump(&py, f, &dump);
    }
    for f in [&files[0], &files[1], &merged, &files[2], &files[3]] {
        check_relight(&py, &scene, f, "floor.obj", clay, dir.path());
    }
    // Per texel (SPEC §3.1): the lightmapped floor of scenes/hard/figure_on_quad.toml, whose
    // bunny (no UVs) stays per vertex, with one bounce.
    let hard = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hard/figure_on_quad.toml");
    let texel = dir.path().join("texel.prtb");
    run(prt()
        .arg("bake")
        .arg(&hard)
        .args(["--rays", "32", "--order", "3", "--per-texel", "16", "--out"])
        .arg(&texel));
    check_dump(&py, &texel, &dump);
    check_relight(
        &py,
        &hard,
        &texel,
        "quad.obj",
        [0.45, 0.4, 0.35],
        dir.path(),
    );

    // A damaged file: one clean line naming the file, exit status 1.
    let mut bytes = std::fs::read(&files[0]).unwrap();
    let at = bytes.len() / 2;
    bytes[at] ^= 0x20;
    let bad = dir.path().join("damaged.prtb");
    std::fs::write(&bad, &bytes).unwrap();
    let o = Command::new(&py)
        .arg(reader_script())
        .arg(&bad)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert_eq!(err.trim_end().lines().count(), 1, "{err}");
    assert!(
        err.contains("damaged.prtb") && !err.contains("Traceback"),
        "{err}"
    );
}
