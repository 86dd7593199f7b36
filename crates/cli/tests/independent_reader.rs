//! `tools/prtb_reader.py`, a reader of the bake format written from `SPEC.md` alone (it
//! neither imports nor calls this code), against `prt` on every kind of bake: per vertex and
//! per pixel, f32 and f16, direct and interreflected, sharded and merged, and a file of the 1.0
//! writer. The two must agree on every section (coefficients to the bit, through CRC-32s of
//! their f32 values), the reader must recompute every geometry hash from the file's meshes, and
//! its numpy relighting must match `prt relight --vertex-colours` to f32 rounding. Reflectance
//! fields (`prt reflectance`, SPEC §3.14), f32 and f16: the reader's pixels and values equal
//! prt's bit for bit, and crafted corruptions of the `RFLD` payload are refused by both readers.
//!
//! Needs Python 3 with numpy (`python3 -m pip install -r tools/requirements-reader.txt`; or
//! `PRT_PYTHON=/path/to/python`). Without it the test says so and passes, unless
//! `PRT_REQUIRE_PY_READER=1` (which CI sets after installing numpy), when it fails.

mod common;

use common::{prt, python_or_skip, reflectance_file, run, write_scene};
use prt_bakefile::{Bake, SampleKind};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;

fn reader_script() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tools/prtb_reader.py")
}

/// The Python interpreter to run the reader with, when one with numpy is there.
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
    // A field's content is compared by independent_reader_reads_reflectance_fields_like_prt.
    assert_eq!(
        d["reflectance"].is_null(),
        bake.reflectance.is_none(),
        "{what}"
    );
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
    let block = obj.diffuse_block().unwrap();
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
    let Some(py) = python_or_skip() else { return };
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
    // Per texel at 128²: the bunny (no UVs) is lightmapped through a generated atlas whose
    // per-corner UVs the file carries (SPEC 1.3, §3.9.3); the reader recomputes their hash.
    let atlas = dir.path().join("atlas.prtb");
    run(prt()
        .arg("bake")
        .arg(&hard)
        .args([
            "--rays",
            "16",
            "--order",
            "2",
            "--per-texel",
            "128",
            "--out",
        ])
        .arg(&atlas));
    let b = prt_bakefile::read_bake(&atlas).unwrap();
    assert!(
        b.meta.settings["lightmaps"][0]["atlas"].is_array(),
        "the bunny is lightmapped through an atlas"
    );
    check_dump(&py, &atlas, &dump);
    let bytes = std::fs::read(&atlas).unwrap();
    // A changed atlas UV is refused by both readers (its hash no longer matches).
    let meta = with_meta(&bytes, |m| {
        let a = &mut m["settings"]["lightmaps"][0]["atlas"][0];
        *a = (a.as_u64().unwrap() ^ 1).into();
    });
    let changed = dir.path().join("atlas_changed.prtb");
    std::fs::write(&changed, &meta).unwrap();
    let (code, err) = py_reader(&py, &changed, &[]);
    assert_eq!(code, Some(1), "{err}");
    assert!(err.contains("uv_hash"), "{err}");
    assert!(prt_bakefile::read_bake(&changed).is_err());

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

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn le_u64(b: &[u8], at: usize) -> u64 {
    u64::from_le_bytes(b[at..at + 8].try_into().unwrap())
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

/// The section with `tag` (SPEC §2.2): (table index, payload offset, payload length).
fn find_section(b: &[u8], tag: &[u8; 4]) -> (usize, usize, usize) {
    let table = le_u64(b, 32) as usize;
    (0..le_u32(b, 40) as usize)
        .map(|i| (i, table + 32 * i))
        .find(|&(_, e)| &b[e..e + 4] == tag)
        .map(|(i, e)| (i, le_u64(b, e + 8) as usize, le_u64(b, e + 16) as usize))
        .unwrap_or_else(|| panic!("no {} section", String::from_utf8_lossy(tag)))
}

/// Recomputes section `index`'s CRC (when given) and the header CRC (SPEC §2.3), in place.
fn fix_crcs(b: &mut [u8], index: Option<usize>) {
    let table = le_u64(b, 32) as usize;
    let count = le_u32(b, 40) as usize;
    if let Some(i) = index {
        let e = table + 32 * i;
        let (offset, length) = (le_u64(b, e + 8) as usize, le_u64(b, e + 16) as usize);
        let crc = crc32fast::hash(&b[offset..offset + length]);
        put_u32(b, e + 24, crc);
    }
    let mut h = crc32fast::Hasher::new();
    h.update(&b[..60]);
    h.update(&b[table..table + 32 * count]);
    let crc = h.finalize();
    put_u32(b, 60, crc);
}

/// `b` with its META JSON changed by `change` and written back at the SAME length (padded
/// with spaces, JSON whitespace), so that no section moves; CRCs repaired.
fn with_meta(b: &[u8], change: impl FnOnce(&mut Value)) -> Vec<u8> {
    let (index, offset, length) = find_section(b, b"META");
    let mut meta: Value = serde_json::from_slice(&b[offset..offset + length]).unwrap();
    change(&mut meta);
    let mut text = serde_json::to_string_pretty(&meta).unwrap().into_bytes();
    if text.len() > length {
        text = serde_json::to_string(&meta).unwrap().into_bytes();
    }
    assert!(text.len() <= length, "the changed META does not fit");
    text.resize(length, b' ');
    let mut out = b.to_vec();
    out[offset..offset + length].copy_from_slice(&text);
    fix_crcs(&mut out, Some(index));
    out
}

/// Runs the reader on `file` with `args`; (exit code, stderr).
fn py_reader(py: &str, file: &Path, args: &[&str]) -> (Option<i32>, String) {
    let o = Command::new(py)
        .arg(reader_script())
        .arg(file)
        .args(args)
        .output()
        .unwrap();
    (
        o.status.code(),
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

#[test]
fn independent_reader_reads_reflectance_fields_like_prt() {
    let Some(py) = python_or_skip() else { return };
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let dump = dir.path().join("dump.json");
    let raw = dir.path().join("field.bin");
    for (name, f16) in [("field_f32.prtb", false), ("field_f16.prtb", true)] {
        let file = dir.path().join(name);
        reflectance_file(&scene, &file, f16);
        // The general sections (no objects, the camera, BINF) as for every bake.
        check_dump(&py, &file, &dump);
        let (code, err) = py_reader(
            &py,
            &file,
            &[
                "--dump",
                dump.to_str().unwrap(),
                "--field-out",
                raw.to_str().unwrap(),
            ],
        );
        assert_eq!(code, Some(0), "{name}: {err}");
        let bake = prt_bakefile::read_bake(&file).unwrap();
        let rf = bake.reflectance.as_ref().expect("a reflectance field");
        let d: Value = serde_json::from_slice(&std::fs::read(&dump).unwrap()).unwrap();
        let jr = &d["reflectance"];
        let (w, h) = (rf.directions[0], rf.directions[1]);
        assert_eq!((w, h), (8, 4), "{name}");
        assert_eq!(jr["directions"], serde_json::json!([w, h]), "{name}");
        assert_eq!(jr["channels"], 3, "{name}");
        assert_eq!(jr["scalar_type"], if f16 { "f16" } else { "f32" }, "{name}");
        assert_eq!(d["scalar_type"], jr["scalar_type"], "{name}");
        let values = rf.values.to_f32_vec();
        let p = rf.pixels.len();
        assert!(p > 0 && p < 24 * 16, "{name}: {p} pixels held");
        assert_eq!(jr["pixels"].as_u64(), Some(p as u64), "{name}");
        assert_eq!(values.len(), 3 * (w * h) as usize * p, "{name}");
        // Pixel indices and values exactly: the reader's raw export (pixels as u32, values
        // widened to f32, which is exact for f16) against prt's own reading, bit for bit.
        let bytes = std::fs::read(&raw).unwrap();
        assert_eq!(bytes.len(), 4 * p + 4 * values.len(), "{name}");
        let theirs_pixels: Vec<u32> = (0..p).map(|i| le_u32(&bytes, 4 * i)).collect();
        assert_eq!(theirs_pixels, rf.pixels, "{name}: pixel indices");
        let theirs_values: Vec<u32> = (0..values.len())
            .map(|i| le_u32(&bytes, 4 * p + 4 * i))
            .collect();
        let ours_values: Vec<u32> = values.iter().map(|v| v.to_bits()).collect();
        assert_eq!(theirs_values, ours_values, "{name}: values");
        assert_eq!(jr["crc32_f32"].as_u64(), Some(f32_crc(&values).into()));
        let sum: f64 = values.iter().map(|&v| f64::from(v)).sum();
        let bound = 2.0 * values.len() as f64 * f64::EPSILON * sum + f64::MIN_POSITIVE;
        assert!((jr["sum"].as_f64().unwrap() - sum).abs() <= bound, "{name}");
        assert!(values.iter().any(|&v| v > 0.0), "{name}: an all-zero field");
        // Fields are not relit by the reader (SPEC §3.14 leaves the quadrature open): it says
        // so in one line.
        let csv = dir.path().join("c.csv");
        let (code, err) = py_reader(
            &py,
            &file,
            &[
                "--relight",
                "x",
                "--albedo",
                "1,1,1",
                "--colours",
                csv.to_str().unwrap(),
            ],
        );
        assert_eq!(code, Some(1), "{err}");
        assert!(
            err.contains("reflectance field") && !err.contains("Traceback"),
            "{err}"
        );
        eprintln!("{name}: {p} pixels × {w}×{h} directions agree bit for bit");
    }
}

/// Crafted corruptions of a valid field file `b` (SPEC §3.14 and the rules it leans on), CRCs
/// repaired as §2.3 says so that the semantic checks are reached: (label, bytes). Both readers
/// must refuse every one (prt enforces the `REQUIRED` mark of §3's table and
/// `settings.reflectance` of §3.14 too, since the reader found it did not).
fn field_corruptions(b: &[u8], f16: bool) -> Vec<(String, Vec<u8>)> {
    let (rfld, at, length) = find_section(b, b"RFLD");
    let (binf, binf_at, _) = find_section(b, b"BINF");
    let (w, h, p) = (le_u32(b, at), le_u32(b, at + 4), le_u64(b, at + 16));
    let image = le_u32(b, binf_at + 8) * le_u32(b, binf_at + 12);
    let size = if f16 { 2 } else { 4 };
    let values_at = at + 32 + 4 * p as usize;
    let count = 3 * (w * h) as usize * p as usize;
    assert_eq!(length, 32 + 4 * p as usize + size * count, "the valid file");
    let table = le_u64(b, 32) as usize;
    let entry = table + 32 * rfld;
    let mut cases: Vec<(String, Vec<u8>)> = Vec::new();
    let mut patch = |label: &str, section: usize, edit: &dyn Fn(&mut Vec<u8>)| {
        let mut c = b.to_vec();
        edit(&mut c);
        fix_crcs(&mut c, Some(section));
        cases.push((label.to_string(), c));
    };
    // Lengths: the section one scalar short / long of 32 + 4P + size·3WHP (file_size and the
    // table entry follow, so only the §3.14 length rule is broken), and header counts that no
    // longer match it — the huge ones must be refused before anything is allocated.
    let resize = |c: &mut Vec<u8>, delta: isize| {
        assert_eq!(at + length, c.len(), "RFLD is the last payload");
        let n = (c.len() as isize + delta) as usize;
        c.resize(n, 0);
        put_u64(c, 24, n as u64);
        put_u64(c, entry + 16, (length as isize + delta) as u64);
    };
    patch("length one scalar short", rfld, &|c| {
        resize(c, -(size as isize))
    });
    patch("length one scalar long", rfld, &|c| {
        resize(c, size as isize)
    });
    patch("P + 1", rfld, &|c| put_u64(c, at + 16, p + 1));
    patch("P - 1", rfld, &|c| put_u64(c, at + 16, p - 1));
    patch("P = 2^63", rfld, &|c| put_u64(c, at + 16, 1 << 63));
    patch("P = 2^64 - 1", rfld, &|c| put_u64(c, at + 16, u64::MAX));
    patch("W + 1", rfld, &|c| put_u32(c, at, w + 1));
    patch("W = 1", rfld, &|c| put_u32(c, at, 1));
    patch("H = 0", rfld, &|c| put_u32(c, at + 4, 0));
    patch("W×H > 2^24", rfld, &|c| put_u32(c, at, (1 << 24) / h + 1));
    patch("W = 2^32 - 1", rfld, &|c| put_u32(c, at, u32::MAX));
    patch("channels 1", rfld, &|c| put_u32(c, at + 8, 1));
    // Pixel indices: strictly increasing, inside the image.
    let px = |i: u64| at + 32 + 4 * i as usize;
    let first = le_u32(b, px(0));
    let mid = p / 2;
    let before_mid = le_u32(b, px(mid - 1));
    patch("pixels[0] > pixels[1]", rfld, &|c| {
        let second = le_u32(c, px(1));
        put_u32(c, px(0), second);
        put_u32(c, px(1), first);
    });
    patch("pixels[mid] repeats pixels[mid-1]", rfld, &|c| {
        put_u32(c, px(mid), before_mid)
    });
    patch("last pixel = image size", rfld, &|c| {
        put_u32(c, px(p - 1), image)
    });
    patch("last pixel = 2^32 - 1", rfld, &|c| {
        put_u32(c, px(p - 1), u32::MAX)
    });
    // Values: finite and ≥ 0, in the file's scalar type.
    let bad: [(&str, f32, u16); 4] = [
        ("NaN", f32::NAN, 0x7e00),
        ("+inf", f32::INFINITY, 0x7c00),
        ("-inf", f32::NEG_INFINITY, 0xfc00),
        ("-1.0", -1.0, 0xbc00),
    ];
    for (k, (label, v32, v16)) in bad.into_iter().enumerate() {
        let i = (k + 1) * count / 5 + 3;
        let pos = values_at + size * i;
        patch(&format!("value {i} = {label}"), rfld, &|c| {
            if f16 {
                c[pos..pos + 2].copy_from_slice(&v16.to_le_bytes());
            } else {
                c[pos..pos + 4].copy_from_slice(&v32.to_le_bytes());
            }
        });
    }
    // The REQUIRED flag cleared: a reader that does not know RFLD would skip the field.
    let mut c = b.to_vec();
    put_u32(&mut c, entry + 4, 0);
    fix_crcs(&mut c, None);
    cases.push(("RFLD without the REQUIRED flag".into(), c));
    // A field in a per-vertex file (BINF kind 1, image 0×0, the JSON agreeing: only the
    // "per-pixel files only" rule is broken) and in a per-texel one.
    let mut c = with_meta(b, |m| {
        m["sample_kind"] = serde_json::json!({"kind": "vertex"});
        m["camera"] = Value::Null;
    });
    put_u32(&mut c, binf_at, 1);
    put_u64(&mut c, binf_at + 8, 0);
    fix_crcs(&mut c, Some(binf));
    cases.push(("a field in a per-vertex file".into(), c));
    let mut c = with_meta(b, |m| {
        m["sample_kind"]["kind"] = "texel".into();
        m["camera"] = Value::Null;
        m["settings"]["lightmaps"] = serde_json::json!([]);
    });
    put_u32(&mut c, binf_at, 3);
    fix_crcs(&mut c, Some(binf));
    cases.push(("a field in a per-texel file".into(), c));
    // settings.reflectance (SPEC §3.14) missing, or disagreeing with the RFLD header.
    cases.push((
        "settings.reflectance missing".into(),
        with_meta(b, |m| {
            m["settings"].as_object_mut().unwrap().remove("reflectance");
        }),
    ));
    cases.push((
        "settings.reflectance.directions != RFLD's".into(),
        with_meta(b, |m| {
            m["settings"]["reflectance"]["directions"] = serde_json::json!([w + 1, h]);
        }),
    ));
    cases
}

#[test]
fn independent_reader_and_prt_refuse_crafted_reflectance_fields() {
    let Some(py) = python_or_skip() else { return };
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 3);
    let mut refused = 0;
    for (name, f16) in [("field_f32.prtb", false), ("field_f16.prtb", true)] {
        let file = dir.path().join(name);
        reflectance_file(&scene, &file, f16);
        let valid = std::fs::read(&file).unwrap();
        // Controls: the JSON re-serialised (padded to its length) and a non-zero reserved
        // field (§1: ignored by readers) are still valid for both.
        let (_, at, _) = find_section(&valid, b"RFLD");
        let mut reserved = valid.clone();
        put_u32(&mut reserved, at + 12, 7);
        fix_crcs(&mut reserved, Some(find_section(&valid, b"RFLD").0));
        for (label, bytes) in [
            ("META re-serialised", with_meta(&valid, |_| {})),
            ("reserved field non-zero", reserved),
        ] {
            let path = dir.path().join("control.prtb");
            std::fs::write(&path, &bytes).unwrap();
            let ours = prt_bakefile::read_bake(&path);
            assert!(
                ours.is_ok(),
                "{name} control {label}: prt refused: {ours:?}"
            );
            let (code, err) = py_reader(&py, &path, &[]);
            assert_eq!(
                code,
                Some(0),
                "{name} control {label}: reader refused: {err}"
            );
        }
        for (label, bytes) in field_corruptions(&valid, f16) {
            let path = dir.path().join("crafted.prtb");
            std::fs::write(&path, &bytes).unwrap();
            let ours = prt_bakefile::read_bake(&path);
            let (code, err) = py_reader(&py, &path, &[]);
            assert_eq!(code, Some(1), "{name} {label}: the reader accepted it");
            assert_eq!(err.trim_end().lines().count(), 1, "{name} {label}: {err}");
            assert!(
                err.starts_with("prtb_reader: ") && !err.contains("Traceback"),
                "{name} {label}: {err}"
            );
            let theirs = err
                .trim_end()
                .split(": ")
                .skip(2)
                .collect::<Vec<_>>()
                .join(": ");
            assert!(
                ours.is_err(),
                "{name} {label}: prt accepted it (reader: {theirs})"
            );
            eprintln!(
                "{name} {label}: prt: {} | reader: {theirs}",
                ours.unwrap_err()
            );
            refused += 1;
        }
    }
    eprintln!("{refused} crafted field files refused by both readers");
    assert_eq!(refused, 2 * 25);
}
