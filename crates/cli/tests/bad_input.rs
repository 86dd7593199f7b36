//! Bad input, end to end: every row of `docs/bad-input.md` runs the real `prt` binary on a bad
//! file or option built here in a temporary directory, and checks that
//! - the command ends within a time limit (else it is killed and the row fails as a hang),
//! - it was not killed by a signal (an abort on a huge allocation, a stack overflow),
//! - stderr has no `panicked`,
//! - an error exits non-zero and its stderr names the bad file and the problem (fragments),
//!   or a repairable problem gives a `warning:` naming the file and the command succeeds,
//! - the output directory of commands with `--out` holds exactly what it held before: no
//!   partial output, no temporary file, and a pre-existing output unchanged.
//!
//! Tests are tables, one per reader; each entry is named after its row in the catalogue.

use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::ffi::OsString;
use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, ExitStatus, Stdio};
use std::time::{Duration, Instant};

/// Every command must end within this (release build; the largest real asset loads in < 1 s).
const TIME_LIMIT: Duration = Duration::from_secs(20);

// ---------------------------------------------------------------------------------------------
// Running the binary

struct Finished {
    status: ExitStatus,
    stderr: String,
}

/// Runs `prt args…`, killing it after `limit`.
fn run_prt(args: &[OsString], limit: Duration) -> Result<Finished, String> {
    let mut child = Command::new(env!("CARGO_BIN_EXE_prt"))
        .args(args)
        .env("RUST_BACKTRACE", "0")
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .map_err(|e| format!("cannot start prt: {e}"))?;
    let drain = |mut r: Box<dyn Read + Send>| {
        std::thread::spawn(move || {
            let mut v = Vec::new();
            let _ = r.read_to_end(&mut v);
            String::from_utf8_lossy(&v).into_owned()
        })
    };
    let out = drain(Box::new(child.stdout.take().unwrap()));
    let err = drain(Box::new(child.stderr.take().unwrap()));
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().map_err(|e| e.to_string())? {
            break s;
        }
        if start.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            return Err(format!("hang: still running after {limit:?}, killed"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let _ = out.join();
    Ok(Finished {
        status,
        stderr: err.join().unwrap_or_default(),
    })
}

/// File names and contents of a directory (non-recursive).
fn snapshot(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    std::fs::read_dir(dir)
        .map(|rd| {
            rd.filter_map(Result::ok)
                .map(|e| {
                    (
                        e.file_name().to_string_lossy().into_owned(),
                        std::fs::read(e.path()).unwrap_or_default(),
                    )
                })
                .collect()
        })
        .unwrap_or_default()
}

enum Expect {
    /// Non-zero exit; stderr holds every fragment.
    Error(Vec<&'static str>),
    /// Success; stderr holds `warning:` and every fragment.
    Warning(Vec<&'static str>),
    /// Success and no warning (a real file that is clean).
    Clean,
}

/// One row of the catalogue.
struct Case {
    /// The row's name in docs/bad-input.md.
    row: &'static str,
    args: Vec<OsString>,
    /// Text stderr must contain to name the bad input (a file name or an option).
    names: String,
    expect: Expect,
    /// Directory whose contents must be the same after the command.
    out_dir: Option<PathBuf>,
}

fn case(row: &'static str, args: &[&dyn AsRefOs], names: &str, expect: Expect) -> Case {
    Case {
        row,
        args: args.iter().map(|a| a.os()).collect(),
        names: names.to_owned(),
        expect,
        out_dir: None,
    }
}

fn err(fragments: &[&'static str]) -> Expect {
    Expect::Error(fragments.to_vec())
}

fn warn(fragments: &[&'static str]) -> Expect {
    Expect::Warning(fragments.to_vec())
}

impl Case {
    fn watching(mut self, dir: &Path) -> Self {
        self.out_dir = Some(dir.to_path_buf());
        self
    }

    fn check(&self) -> Result<(), String> {
        let before = self.out_dir.as_deref().map(snapshot);
        let f = run_prt(&self.args, TIME_LIMIT).map_err(|e| format!("{}: {e}", self.row))?;
        let e = &f.stderr;
        if std::env::var_os("PRT_BAD_INPUT_LOG").is_some() {
            let (kind, frags) = match &self.expect {
                Expect::Error(f) => ("error", f.clone()),
                Expect::Warning(f) => ("warning", f.clone()),
                Expect::Clean => ("clean", Vec::new()),
            };
            eprintln!(
                "ROW\t{}\t{kind}\t{frags:?}\t{}\t{:?}\t{}",
                self.row,
                self.names,
                f.status.code(),
                e.trim_end().replace('\n', " ")
            );
        }
        let mut problems = Vec::new();
        if e.contains("panicked") {
            problems.push("panicked".to_owned());
        }
        match (&self.expect, f.status.code()) {
            (_, None) => problems.push(format!("killed by a signal: {}", f.status)),
            (Expect::Error(_), Some(0)) => problems.push("exit status 0".into()),
            (Expect::Warning(_) | Expect::Clean, Some(c)) if c != 0 => {
                problems.push(format!("exit status {c}"))
            }
            _ => {}
        }
        let fragments = match &self.expect {
            Expect::Error(f) => f.clone(),
            Expect::Warning(f) => {
                let mut f = f.clone();
                f.push("warning:");
                f
            }
            Expect::Clean => {
                if e.contains("warning:") {
                    problems.push("unexpected warning".into());
                }
                Vec::new()
            }
        };
        if !matches!(self.expect, Expect::Clean) && !e.contains(&self.names) {
            problems.push(format!("stderr does not name `{}`", self.names));
        }
        for frag in fragments {
            if !e.contains(frag) {
                problems.push(format!("stderr lacks `{frag}`"));
            }
        }
        if let (Some(dir), Some(before)) = (&self.out_dir, before) {
            let after = snapshot(dir);
            if after != before {
                problems.push(format!(
                    "output directory changed: before {:?}, after {:?}",
                    before.keys().collect::<Vec<_>>(),
                    after.keys().collect::<Vec<_>>()
                ));
            }
        }
        if problems.is_empty() {
            Ok(())
        } else {
            Err(format!(
                "{}: {}\n    args: {:?}\n    stderr: {}",
                self.row,
                problems.join("; "),
                self.args,
                e.trim_end().replace('\n', "\n            ")
            ))
        }
    }
}

/// Runs every case and fails once, listing every failing row.
fn run_table(cases: &[Case]) {
    let failures: Vec<String> = cases.iter().filter_map(|c| c.check().err()).collect();
    assert!(
        failures.is_empty(),
        "{} of {} rows failed:\n{}",
        failures.len(),
        cases.len(),
        failures.join("\n")
    );
}

/// `&str`, `String`, `PathBuf` and `&Path` as command arguments.
trait AsRefOs {
    fn os(&self) -> OsString;
}
impl AsRefOs for &str {
    fn os(&self) -> OsString {
        (*self).into()
    }
}
impl AsRefOs for String {
    fn os(&self) -> OsString {
        self.into()
    }
}
impl AsRefOs for PathBuf {
    fn os(&self) -> OsString {
        self.into()
    }
}

// ---------------------------------------------------------------------------------------------
// Building inputs

const TETRA_OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
                         f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// The first bytes of a PNG file (signature and the start of an IHDR chunk).
const PNG_BYTES: &[u8] =
    b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR\x00\x00\x00\x08\x00\x00\x00\x04\x08\x02\x00\x00\x00";

fn write(dir: &Path, name: &str, bytes: impl AsRef<[u8]>) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// A `w × h` RGB float EXR whose texel (x, y) is `f(x, y)`, with optional chromaticities.
fn write_exr(
    path: &Path,
    (w, h): (usize, usize),
    f: impl Fn(usize, usize) -> (f32, f32, f32) + Sync,
    chromaticities: Option<[[f32; 2]; 4]>,
) {
    use exr::prelude::*;
    let channels = SpecificChannels::rgb(|p: Vec2<usize>| f(p.x(), p.y()));
    let mut image = Image::from_channels((w, h), channels);
    if let Some(c) = chromaticities {
        image.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
            red: Vec2(c[0][0], c[0][1]),
            green: Vec2(c[1][0], c[1][1]),
            blue: Vec2(c[2][0], c[2][1]),
            white: Vec2(c[3][0], c[3][1]),
        });
    }
    image.write().to_file(path).unwrap();
}

fn uniform_exr(path: &Path) {
    write_exr(path, (8, 4), |_, _| (1.0, 1.0, 1.0), None);
}

/// Offset of the first occurrence of `needle` in `hay`.
fn find(hay: &[u8], needle: &[u8]) -> usize {
    hay.windows(needle.len())
        .position(|w| w == needle)
        .expect("needle")
}

/// A flat (not run-length encoded) Radiance RGBE image of `w × h` texels of radiance 1.
fn hdr_bytes(w: usize, h: usize) -> Vec<u8> {
    let mut b = format!("#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y {h} +X {w}\n").into_bytes();
    for _ in 0..w * h {
        b.extend_from_slice(&[128, 128, 128, 129]);
    }
    b
}

/// The JSON of a one-primitive glTF tetrahedron: accessor 0 positions (4 × VEC3 f32 at 0),
/// accessor 1 indices (12 × u32 at 48), accessor 2 normals (4 × VEC3 f32 at 96).
fn tetra_gltf_json() -> Value {
    json!({
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"mesh": 0}],
        "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1, "mode": 4}]}],
        "accessors": [
            {"bufferView": 0, "componentType": 5126, "count": 4, "type": "VEC3",
             "min": [0.0, 0.0, 0.0], "max": [1.0, 1.0, 1.0]},
            {"bufferView": 1, "componentType": 5125, "count": 12, "type": "SCALAR"},
            {"bufferView": 2, "componentType": 5126, "count": 4, "type": "VEC3"}
        ],
        "bufferViews": [
            {"buffer": 0, "byteOffset": 0, "byteLength": 48},
            {"buffer": 0, "byteOffset": 48, "byteLength": 48},
            {"buffer": 0, "byteOffset": 96, "byteLength": 48}
        ],
        "buffers": [{"byteLength": 144}]
    })
}

/// The binary data of [`tetra_gltf_json`].
fn tetra_bin() -> Vec<u8> {
    let p: [f32; 12] = [0., 0., 0., 1., 0., 0., 0., 1., 0., 0., 0., 1.];
    let i: [u32; 12] = [0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3];
    let n: [f32; 12] = [-0.577, -0.577, -0.577, 1., 0., 0., 0., 1., 0., 0., 0., 1.];
    let mut b = Vec::new();
    p.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    i.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    n.iter().for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
    b
}

/// A GLB file by hand: 12-byte header, JSON chunk (space padded), BIN chunk (zero padded).
fn glb(json: &Value, bin: &[u8]) -> Vec<u8> {
    let mut j = serde_json::to_vec(json).unwrap();
    j.resize(j.len().div_ceil(4) * 4, b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().div_ceil(4) * 4, 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::with_capacity(total);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(j.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&j);
    out.extend_from_slice(&(b.len() as u32).to_le_bytes());
    out.extend_from_slice(b"BIN\0");
    out.extend_from_slice(&b);
    out
}

/// A GLB tetrahedron after `edit` changed its JSON and binary data.
fn tetra_glb(edit: impl FnOnce(&mut Value, &mut Vec<u8>)) -> Vec<u8> {
    let (mut j, mut b) = (tetra_gltf_json(), tetra_bin());
    edit(&mut j, &mut b);
    glb(&j, &b)
}

/// A scene file: small camera, `env` as the map, one object per `(mesh, material)`; the
/// material `m` is a grey lambert. `extra` is appended verbatim.
fn scene_text(env: &str, objects: &[(&str, Option<&str>)], extra: &str) -> String {
    let mut s = format!(
        "[camera]\neye = [0.5, 0.5, 3.0]\ntarget = [0.2, 0.2, 0.2]\nfov_y = 40.0\n\
         resolution = [8, 6]\n\n[environment]\nfile = \"{env}\"\n\n\
         [materials.m]\ntype = \"lambert\"\nalbedo = [0.5, 0.5, 0.5]\n\n"
    );
    for (mesh, material) in objects {
        s += &format!("[[objects]]\nmesh = \"{mesh}\"\n");
        if let Some(m) = material {
            s += &format!("material = \"{m}\"\n");
        }
    }
    s + "\n[render]\nspp = 1\nbounces = 0\n" + extra
}

/// Writes `scene_<name>.toml` holding one object `mesh` (material `m` unless glTF).
fn mesh_scene(dir: &Path, name: &str, mesh: &str) -> PathBuf {
    let material = if mesh.ends_with(".obj") {
        Some("m")
    } else {
        None
    };
    write(
        dir,
        &format!("scene_{name}.toml"),
        scene_text("env.exr", &[(mesh, material)], ""),
    )
}

/// `prt render SCENE --quiet --out OUT/<row>.exr` watching `OUT`.
fn render_case(row: &'static str, scene: PathBuf, out: &Path, names: &str, e: Expect) -> Case {
    let exr = out.join(format!("{row}.exr"));
    case(
        row,
        &[
            &"render",
            &scene,
            &"--quiet",
            &"--threads",
            &"1",
            &"--out",
            &exr,
        ],
        names,
        e,
    )
    .watching(out)
}

/// The tiny scene used for bakes: a tetrahedron under a uniform 8×4 map.
fn tiny_scene(dir: &Path) -> PathBuf {
    write(dir, "tetra.obj", TETRA_OBJ);
    uniform_exr(&dir.join("env.exr"));
    write(
        dir,
        "tiny.toml",
        scene_text("env.exr", &[("tetra.obj", Some("m"))], ""),
    )
}

fn assets() -> PathBuf {
    PathBuf::from("/work/shared/assets")
}

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

// ---------------------------------------------------------------------------------------------
// OBJ

#[test]
fn obj_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    uniform_exr(&d.join("env.exr"));
    let files: &[(&str, &[u8])] = &[
        ("empty", b""),
        (
            "text",
            b"This is a README, not a mesh.\nIt has two lines.\n",
        ),
        ("png", PNG_BYTES),
        ("truncated", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2"),
        (
            "index_out_of_range",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n",
        ),
        (
            "index_huge",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 99999999999999999999\n",
        ),
        ("index_negative", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf -1 -2 -9\n"),
        ("index_zero", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n"),
        ("nan_position", b"v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("inf_position", b"v 0 0 0\nv inf 0 0\nv 0 1 0\nf 1 2 3\n"),
        ("huge_finite", b"v 0 0 0\nv 3e38 0 0\nv 0 3e38 0\nf 1 2 3\n"),
        (
            "zero_triangles",
            b"v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 1 2\nf 1 2 3\n",
        ),
        ("lines_only", b"v 0 0 0\nv 1 0 0\nv 0 1 0\nl 1 2\nl 2 3\n"),
        (
            "nan_normals",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn nan 0 0\nf 1//1 2//1 3//1\n",
        ),
        (
            "degenerate_some",
            b"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 1 2\n",
        ),
    ];
    for (name, bytes) in files {
        write(d, &format!("{name}.obj"), bytes);
        mesh_scene(d, name, &format!("{name}.obj"));
    }
    write(d, "big_scale.toml", {
        let s = scene_text("env.exr", &[("degenerate_some.obj", Some("m"))], "");
        s.replace(
            "mesh = \"degenerate_some.obj\"\n",
            "mesh = \"degenerate_some.obj\"\nscale = 1e300\n",
        )
    });
    let sc = |n: &str| d.join(format!("scene_{n}.toml"));
    let cases = vec![
        render_case(
            "obj_empty",
            sc("empty"),
            &out,
            "empty.obj",
            err(&["no faces"]),
        ),
        render_case("obj_text", sc("text"), &out, "text.obj", err(&["no faces"])),
        render_case(
            "obj_wrong_type_png",
            sc("png"),
            &out,
            "png.obj",
            err(&["not a readable OBJ file"]),
        ),
        render_case(
            "obj_truncated_face",
            sc("truncated"),
            &out,
            "truncated.obj",
            err(&["no triangles left"]),
        ),
        render_case(
            "obj_index_out_of_range",
            sc("index_out_of_range"),
            &out,
            "index_out_of_range.obj",
            err(&["index out of bounds"]),
        ),
        render_case(
            "obj_index_huge",
            sc("index_huge"),
            &out,
            "index_huge.obj",
            err(&["face parse error"]),
        ),
        render_case(
            "obj_index_negative_past_start",
            sc("index_negative"),
            &out,
            "index_negative.obj",
            err(&["index out of bounds"]),
        ),
        render_case(
            "obj_index_zero",
            sc("index_zero"),
            &out,
            "index_zero.obj",
            err(&["index out of bounds"]),
        ),
        render_case(
            "obj_nan_position",
            sc("nan_position"),
            &out,
            "nan_position.obj",
            err(&["non-finite position"]),
        ),
        render_case(
            "obj_inf_position",
            sc("inf_position"),
            &out,
            "inf_position.obj",
            err(&["non-finite position"]),
        ),
        render_case(
            "obj_huge_finite_positions",
            sc("huge_finite"),
            &out,
            "huge_finite.obj",
            Expect::Clean,
        ),
        render_case(
            "obj_scale_overflow",
            d.join("big_scale.toml"),
            &out,
            "degenerate_some.obj",
            err(&["not finite after the transform"]),
        ),
        render_case(
            "obj_zero_triangles",
            sc("zero_triangles"),
            &out,
            "zero_triangles.obj",
            err(&["no triangles left"]),
        ),
        render_case(
            "obj_lines_only",
            sc("lines_only"),
            &out,
            "lines_only.obj",
            err(&["no triangles left"]),
        ),
        render_case(
            "obj_nan_normals",
            sc("nan_normals"),
            &out,
            "nan_normals.obj",
            warn(&["normals"]),
        ),
        render_case(
            "obj_degenerate_triangles",
            sc("degenerate_some"),
            &out,
            "degenerate_some.obj",
            warn(&["degenerate"]),
        ),
    ];
    // Successful renders write their EXR: watch a separate directory for those rows.
    let (fail, ok): (Vec<Case>, Vec<Case>) = cases
        .into_iter()
        .partition(|c| matches!(c.expect, Expect::Error(_)));
    run_table(&fail);
    run_table(&ok.into_iter().map(unwatch).collect::<Vec<_>>());
}

fn unwatch(mut c: Case) -> Case {
    c.out_dir = None;
    c
}

// ---------------------------------------------------------------------------------------------
// glTF / GLB

#[test]
fn gltf_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    uniform_exr(&d.join("env.exr"));
    let valid = tetra_glb(|_, _| {});
    let mut files: Vec<(&str, Vec<u8>)> = vec![
        ("empty.glb", Vec::new()),
        ("png.glb", PNG_BYTES.to_vec()),
        ("text.glb", b"not a glTF file\n".to_vec()),
        ("truncated.glb", valid[..valid.len() / 2].to_vec()),
        ("truncated_header.glb", valid[..10].to_vec()),
        (
            "draco.glb",
            tetra_glb(|j, _| {
                j["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
                j["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
            }),
        ),
        (
            "points_only.glb",
            tetra_glb(|j, _| j["meshes"][0]["primitives"][0]["mode"] = json!(0)),
        ),
        (
            "lines_and_triangles.glb",
            tetra_glb(|j, _| {
                let mut lines = j["meshes"][0]["primitives"][0].clone();
                lines["mode"] = json!(1);
                j["meshes"][0]["primitives"]
                    .as_array_mut()
                    .unwrap()
                    .push(lines);
            }),
        ),
        (
            "sparse.glb",
            tetra_glb(|j, _| {
                j["accessors"][0]["sparse"] = json!({
                    "count": 1,
                    "indices": {"bufferView": 1, "componentType": 5125},
                    "values": {"bufferView": 0}
                });
            }),
        ),
        (
            "index_out_of_range.glb",
            tetra_glb(|_, b| b[48 + 4 * 5..48 + 4 * 6].copy_from_slice(&9u32.to_le_bytes())),
        ),
        (
            "nan_position.glb",
            tetra_glb(|_, b| b[12..16].copy_from_slice(&f32::NAN.to_le_bytes())),
        ),
        (
            "inf_position.glb",
            tetra_glb(|_, b| b[16..20].copy_from_slice(&f32::NEG_INFINITY.to_le_bytes())),
        ),
        (
            "nan_normal.glb",
            tetra_glb(|j, b| {
                j["meshes"][0]["primitives"][0]["attributes"]["NORMAL"] = json!(2);
                b[96..100].copy_from_slice(&f32::NAN.to_le_bytes());
            }),
        ),
        (
            "zero_triangles.glb",
            tetra_glb(|_, b| {
                for k in 0..12 {
                    b[48 + 4 * k..52 + 4 * k].copy_from_slice(&((k % 2) as u32).to_le_bytes());
                }
            }),
        ),
        (
            "no_primitives_in_scene.glb",
            tetra_glb(|j, _| j["scenes"][0]["nodes"] = json!([])),
        ),
        (
            "accessor_count_huge.glb",
            tetra_glb(|j, _| j["accessors"][0]["count"] = json!(4_000_000_000u64)),
        ),
        (
            "accessor_offset_past_end.glb",
            tetra_glb(|j, _| j["accessors"][1]["byteOffset"] = json!(4_000_000_000u64)),
        ),
        (
            "view_past_buffer.glb",
            tetra_glb(|j, _| j["bufferViews"][1]["byteLength"] = json!(1_000_000_000_000u64)),
        ),
        (
            "buffer_length_huge.glb",
            tetra_glb(|j, _| j["buffers"][0]["byteLength"] = json!(1_000_000_000_000_000u64)),
        ),
        (
            "stride_too_small.glb",
            tetra_glb(|j, _| j["bufferViews"][0]["byteStride"] = json!(4)),
        ),
        (
            "quantized_positions.glb",
            tetra_glb(|j, _| j["accessors"][0]["componentType"] = json!(5123)),
        ),
        (
            "node_cycle.glb",
            tetra_glb(|j, _| {
                j["nodes"] = json!([{"mesh": 0, "children": [1]}, {"children": [0]}]);
            }),
        ),
        (
            "textured.glb",
            tetra_glb(|j, _| {
                j["materials"] =
                    json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
                j["textures"] = json!([{"source": 0}]);
                j["images"] = json!([{"uri": "missing.png"}]);
                j["meshes"][0]["primitives"][0]["material"] = json!(0);
            }),
        ),
        (
            "texture_not_image.glb",
            tetra_glb(|j, _| {
                j["materials"] =
                    json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
                j["textures"] = json!([{"source": 0}]);
                j["images"] = json!([{"uri": "not_image.png"}]);
                j["meshes"][0]["primitives"][0]["material"] = json!(0);
            }),
        ),
        (
            "texture_without_uv.glb",
            tetra_glb(|j, _| {
                j["materials"] =
                    json!([{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}]);
                j["textures"] = json!([{"source": 0}]);
                j["images"] = json!([{"uri": "good.png"}]);
                j["meshes"][0]["primitives"][0]["material"] = json!(0);
            }),
        ),
    ];
    // GLB chunk lengths pointing past the end of the file.
    let mut chunk_past_end = valid.clone();
    chunk_past_end[12..16].copy_from_slice(&0x7fff_fff0u32.to_le_bytes());
    files.push(("chunk_length_past_end.glb", chunk_past_end));
    let mut total_past_end = valid.clone();
    total_past_end[8..12].copy_from_slice(&u32::MAX.to_le_bytes());
    files.push(("total_length_past_end.glb", total_past_end));
    for (name, bytes) in &files {
        write(d, name, bytes);
        mesh_scene(d, name, name);
    }
    write(d, "not_image.png", b"this is not a PNG image\n");
    image::RgbImage::from_pixel(2, 2, image::Rgb([200, 100, 50]))
        .save(d.join("good.png"))
        .unwrap();
    // A .gltf whose buffer file is missing.
    let mut j = tetra_gltf_json();
    j["buffers"][0]["uri"] = json!("missing_buffer.bin");
    write(d, "missing_bin.gltf", serde_json::to_vec(&j).unwrap());
    mesh_scene(d, "missing_bin.gltf", "missing_bin.gltf");
    // A .gltf whose buffer file is shorter than its byteLength.
    let mut j = tetra_gltf_json();
    j["buffers"][0]["uri"] = json!("short.bin");
    write(d, "short.bin", &tetra_bin()[..40]);
    write(d, "short_bin.gltf", serde_json::to_vec(&j).unwrap());
    mesh_scene(d, "short_bin.gltf", "short_bin.gltf");

    let sc = |n: &str| d.join(format!("scene_{n}.toml"));
    let e = |row, name: &str, f: &[&'static str]| render_case(row, sc(name), &out, name, err(f));
    let fail = vec![
        e("gltf_empty", "empty.glb", &["empty"]),
        e("gltf_wrong_type_png", "png.glb", &["not a readable glTF"]),
        e("gltf_wrong_type_text", "text.glb", &["not a readable glTF"]),
        e("gltf_truncated", "truncated.glb", &["not a readable glTF"]),
        e(
            "gltf_truncated_header",
            "truncated_header.glb",
            &["not a readable glTF"],
        ),
        e(
            "gltf_chunk_length_past_end",
            "chunk_length_past_end.glb",
            &["not a readable glTF"],
        ),
        e(
            "gltf_total_length_past_end",
            "total_length_past_end.glb",
            &["not a readable glTF"],
        ),
        e(
            "gltf_draco_required",
            "draco.glb",
            &["KHR_draco_mesh_compression"],
        ),
        e(
            "gltf_points_only",
            "points_only.glb",
            &["no triangle primitive"],
        ),
        e(
            "gltf_sparse_accessor",
            "sparse.glb",
            &["sparse accessors are not supported"],
        ),
        e(
            "gltf_index_out_of_range",
            "index_out_of_range.glb",
            &["uses vertex index 9", "4 vertices"],
        ),
        e(
            "gltf_nan_position",
            "nan_position.glb",
            &["non-finite position"],
        ),
        e(
            "gltf_inf_position",
            "inf_position.glb",
            &["non-finite position"],
        ),
        e(
            "gltf_zero_triangles",
            "zero_triangles.glb",
            &["no triangles left"],
        ),
        e(
            "gltf_scene_without_meshes",
            "no_primitives_in_scene.glb",
            &["no triangle primitive"],
        ),
        e(
            "gltf_accessor_count_huge",
            "accessor_count_huge.glb",
            &["past the end"],
        ),
        e(
            "gltf_accessor_offset_past_end",
            "accessor_offset_past_end.glb",
            &["past the end"],
        ),
        e(
            "gltf_view_past_buffer",
            "view_past_buffer.glb",
            &["buffer view runs past the end of its buffer"],
        ),
        e(
            "gltf_buffer_length_huge",
            "buffer_length_huge.glb",
            &["expected 1000000000000000 bytes"],
        ),
        e(
            "gltf_stride_too_small",
            "stride_too_small.glb",
            &["byte stride 4 is smaller"],
        ),
        e(
            "gltf_quantized_positions",
            "quantized_positions.glb",
            &["must be float VEC3"],
        ),
        e("gltf_node_cycle", "node_cycle.glb", &["cycle"]),
        e(
            "gltf_missing_buffer_file",
            "missing_bin.gltf",
            &["missing_buffer.bin"],
        ),
        e(
            "gltf_short_buffer_file",
            "short_bin.gltf",
            &["expected 144 bytes but received 40"],
        ),
        e(
            "gltf_texture_missing",
            "textured.glb",
            &["missing.png", "material0", "No such file"],
        ),
        e(
            "gltf_texture_not_an_image",
            "texture_not_image.glb",
            &["not_image.png", "material0", "decode"],
        ),
        e(
            "gltf_texture_without_uvs",
            "texture_without_uv.glb",
            &["material0", "no TEXCOORD_0"],
        ),
    ];
    run_table(&fail);
    let ok = vec![
        render_case(
            "gltf_lines_and_triangles",
            sc("lines_and_triangles.glb"),
            &out,
            "lines_and_triangles.glb",
            warn(&["not triangles"]),
        ),
        render_case(
            "gltf_nan_normal",
            sc("nan_normal.glb"),
            &out,
            "nan_normal.glb",
            warn(&["normals"]),
        ),
    ];
    run_table(&ok.into_iter().map(unwatch).collect::<Vec<_>>());
}

// ---------------------------------------------------------------------------------------------
// EXR and Radiance HDR environment maps (through `prt sh project` and through a scene)

#[test]
fn env_map_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    write(d, "tetra.obj", TETRA_OBJ);
    let good = d.join("good.exr");
    uniform_exr(&good);
    let good_bytes = std::fs::read(&good).unwrap();
    write(d, "empty.exr", b"");
    write(d, "png.exr", PNG_BYTES);
    write(d, "text.exr", b"a text file renamed .exr\n");
    write(d, "truncated.exr", &good_bytes[..good_bytes.len() * 2 / 3]);
    write(d, "truncated_header.exr", &good_bytes[..40]);
    write(d, "magic_only.exr", &good_bytes[..4]);
    // Data window of 1,000,000² texels (12 TB as RGB f32): must fail before allocating.
    let mut huge = good_bytes.clone();
    let at = find(&huge, b"dataWindow\0box2i\0") + 17 + 4;
    huge[at + 8..at + 12].copy_from_slice(&999_999i32.to_le_bytes());
    huge[at + 12..at + 16].copy_from_slice(&999_999i32.to_le_bytes());
    write(d, "huge_window.exr", &huge);
    // Data window 1e9 texels wide, 4 rows: the chunk count still matches the file, so only a
    // size check before allocating (48 GB as RGB f32) keeps this from aborting.
    let mut wide = good_bytes.clone();
    wide[at + 8..at + 12].copy_from_slice(&999_999_999i32.to_le_bytes());
    write(d, "huge_width.exr", &wide);
    // ZIP-compressed data with flipped bytes in its last chunk.
    {
        use exr::prelude::*;
        let channels = SpecificChannels::rgb(|p: Vec2<usize>| (p.x() as f32, p.y() as f32, 0.5));
        let image = Image::from_encoded_channels((64, 16), Encoding::SMALL_LOSSLESS, channels);
        let zipped = d.join("zip.exr");
        image.write().to_file(&zipped).unwrap();
        let mut flipped = std::fs::read(&zipped).unwrap();
        let n = flipped.len();
        for b in &mut flipped[n - 30..n - 10] {
            *b ^= 0xa5;
        }
        write(d, "flipped_data.exr", &flipped);
    }
    let mut bad_offsets = good_bytes.clone();
    // The offset table follows the header's terminating null byte: point every entry far away.
    let header_end = exr_header_end(&good_bytes);
    for k in 0..4 {
        let o = header_end + 8 * k;
        bad_offsets[o..o + 8].copy_from_slice(&(u64::MAX / 2).to_le_bytes());
    }
    write(d, "offsets_past_end.exr", &bad_offsets);
    let nan_at = |x, y| {
        move |px: usize, py: usize| {
            if (px, py) == (x, y) {
                (0.5, f32::NAN, 0.5)
            } else {
                (0.5, 0.5, 0.5)
            }
        }
    };
    write_exr(&d.join("nan.exr"), (8, 4), nan_at(3, 2), None);
    write_exr(
        &d.join("inf.exr"),
        (8, 4),
        |x, y| {
            if (x, y) == (7, 0) {
                (f32::INFINITY, 0.0, 0.0)
            } else {
                (1.0, 1.0, 1.0)
            }
        },
        None,
    );
    write_exr(
        &d.join("neg_inf.exr"),
        (8, 4),
        |x, y| {
            if (x, y) == (0, 3) {
                (0.0, 0.0, f32::NEG_INFINITY)
            } else {
                (1.0, 1.0, 1.0)
            }
        },
        None,
    );
    write_exr(
        &d.join("negative.exr"),
        (8, 4),
        |x, _| {
            if x == 2 {
                (-0.01, 0.5, 0.5)
            } else {
                (0.5, 0.5, 0.5)
            }
        },
        None,
    );
    write_exr(
        &d.join("p3.exr"),
        (8, 4),
        |_, _| (0.5, 0.5, 0.5),
        Some([[0.68, 0.32], [0.265, 0.69], [0.15, 0.06], [0.3127, 0.329]]),
    );
    write_exr(
        &d.join("big_values.exr"),
        (8, 4),
        |_, _| (3e38, 1.0, 1.0),
        None,
    );
    // Luminance only: no R, G, B channels.
    {
        use exr::prelude::*;
        let ch = AnyChannel::new("Y", FlatSamples::F32(vec![1.0; 32]));
        let layer = Layer::new(
            (8, 4),
            LayerAttributes::named("y"),
            Encoding::UNCOMPRESSED,
            AnyChannels::sort(vec![ch].into()),
        );
        Image::from_layer(layer)
            .write()
            .to_file(d.join("luminance.exr"))
            .unwrap();
    }
    write(d, "good.hdr", hdr_bytes(8, 4));
    let hdr = hdr_bytes(8, 4);
    write(d, "truncated.hdr", &hdr[..hdr.len() - 50]);
    write(d, "header_only.hdr", &hdr[..find(&hdr, b"-Y")]);
    write(
        d,
        "huge.hdr",
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1000000 +X 1000000\n\x80\x80\x80\x81",
    );
    write(
        d,
        "zero_size.hdr",
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 0\n",
    );
    write(
        d,
        "bad_resolution.hdr",
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y -5 +X nope\n",
    );
    write(
        d,
        "wrong_format.hdr",
        b"#?RADIANCE\nFORMAT=32-bit_rle_xyze\n\n-Y 4 +X 8\n",
    );
    write(
        d,
        "text.hdr",
        b"#? looks like a header but is a shell comment\necho hi\n",
    );
    let mut rle = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 16\n".to_vec();
    // A run-length scanline whose run overflows the 16-texel row.
    rle.extend_from_slice(&[2, 2, 0, 16, 255, 7, 255, 7, 255, 7, 255, 7]);
    write(d, "rle_overrun.hdr", &rle);

    let project = |row, file: &str, e: Expect| {
        case(
            row,
            &[&"sh", &"project", &d.join(file), &"--order", &"2"],
            file,
            e,
        )
    };
    let cases = vec![
        project("exr_empty", "empty.exr", err(&["empty"])),
        project(
            "exr_wrong_type_png",
            "png.exr",
            err(&["not an OpenEXR or Radiance HDR"]),
        ),
        project(
            "exr_wrong_type_text",
            "text.exr",
            err(&["not an OpenEXR or Radiance HDR"]),
        ),
        project(
            "exr_truncated",
            "truncated.exr",
            err(&["cannot decode OpenEXR"]),
        ),
        project(
            "exr_truncated_header",
            "truncated_header.exr",
            err(&["cannot decode OpenEXR"]),
        ),
        project(
            "exr_magic_only",
            "magic_only.exr",
            err(&["cannot decode OpenEXR"]),
        ),
        project(
            "exr_huge_data_window",
            "huge_window.exr",
            err(&["chunk count not matching data size"]),
        ),
        project(
            "exr_huge_width",
            "huge_width.exr",
            err(&["chunk count not matching data size"]),
        ),
        project(
            "exr_corrupt_pixel_data",
            "flipped_data.exr",
            err(&["zlib-compressed data malformed"]),
        ),
        project(
            "exr_offsets_past_end",
            "offsets_past_end.exr",
            err(&["Invalid argument"]),
        ),
        project(
            "exr_nan_texel",
            "nan.exr",
            err(&["texel (col 3, row 2) channel G is NaN"]),
        ),
        project(
            "exr_inf_texel",
            "inf.exr",
            err(&["texel (col 7, row 0) channel R is inf"]),
        ),
        project(
            "exr_neg_inf_texel",
            "neg_inf.exr",
            err(&["channel B is -inf"]),
        ),
        project(
            "exr_no_rgb_channels",
            "luminance.exr",
            err(&["no layer in the image matched"]),
        ),
        project("exr_missing_file", "missing.exr", err(&["cannot read"])),
        project(
            "exr_negative_texels",
            "negative.exr",
            warn(&["clamped 4 negative values"]),
        ),
        project(
            "exr_non_rec709_chromaticities",
            "p3.exr",
            warn(&["chromaticities", "not Rec.709"]),
        ),
        project("exr_near_f32_max_texels", "big_values.exr", Expect::Clean),
        project(
            "hdr_truncated",
            "truncated.hdr",
            err(&["cannot decode Radiance HDR"]),
        ),
        project(
            "hdr_header_only",
            "header_only.hdr",
            err(&["EOF in dimensions line"]),
        ),
        project("hdr_huge_dimensions", "huge.hdr", err(&["1000000×1000000"])),
        project("hdr_zero_size", "zero_size.hdr", err(&["no texels (0×0)"])),
        project(
            "hdr_bad_resolution_line",
            "bad_resolution.hdr",
            err(&["height dimension"]),
        ),
        project(
            "hdr_wrong_pixel_format",
            "wrong_format.hdr",
            err(&["32-bit_rle_xyze"]),
        ),
        project(
            "hdr_text_with_magic",
            "text.hdr",
            err(&["signature not found"]),
        ),
        project(
            "hdr_rle_overrun",
            "rle_overrun.hdr",
            err(&["Wrong length of decoded scanline"]),
        ),
        project("hdr_valid_flat", "good.hdr", Expect::Clean),
    ];
    run_table(&cases);

    // Through a scene: the error names the scene, the key and the map.
    let in_scene = |row, map: &str, extra: &str, e: Expect| {
        let scene = write(
            d,
            &format!("scene_{row}.toml"),
            scene_text(map, &[("tetra.obj", Some("m"))], "").replace(
                &format!("file = \"{map}\"\n"),
                &format!("file = \"{map}\"\n{extra}"),
            ),
        );
        let mut c = render_case(row, scene.clone(), &out, map, e);
        c.names = format!("scene_{row}.toml");
        c
    };
    let fail = vec![
        in_scene(
            "scene_env_nan_texel",
            "nan.exr",
            "",
            err(&["environment.file", "nan.exr", "NaN"]),
        ),
        in_scene(
            "scene_env_scale_overflow",
            "big_values.exr",
            "scale = 10.0\n",
            err(&["environment", "big_values.exr", "overflow to infinity"]),
        ),
    ];
    run_table(&fail);
    // An angular map that is not square is a warning, not an error.
    let mut ang = in_scene(
        "scene_env_angular_non_square",
        "good.exr",
        "mapping = \"angular\"\n",
        warn(&["not square"]),
    );
    ang.names = "good.exr".into();
    run_table(&[unwatch(ang)]);
}

/// Offset just past an EXR header (magic, version, attributes, terminating null byte) of a
/// single-part scan-line file.
fn exr_header_end(b: &[u8]) -> usize {
    let mut i = 8;
    loop {
        if b[i] == 0 {
            return i + 1;
        }
        let name_end = i + b[i..].iter().position(|&c| c == 0).unwrap();
        let type_end = name_end + 1 + b[name_end + 1..].iter().position(|&c| c == 0).unwrap();
        let size = u32::from_le_bytes(b[type_end + 1..type_end + 5].try_into().unwrap()) as usize;
        i = type_end + 5 + size;
    }
}

// ---------------------------------------------------------------------------------------------
// Scene TOML

#[test]
fn scene_file_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    let good = std::fs::read_to_string(tiny_scene(d)).unwrap();
    std::fs::create_dir(d.join("a_directory.obj")).unwrap();
    write(d, "mesh.ply", "ply\nformat ascii 1.0\nend_header\n");
    // `(row, scene text, fragments)`; each scene is rendered.
    let edit = |from: &str, to: &str| {
        assert!(good.contains(from), "{from}");
        good.replacen(from, to, 1)
    };
    let fail: Vec<(&'static str, String, Vec<&'static str>)> = vec![
        ("toml_empty", String::new(), vec!["missing field `camera`"]),
        (
            "toml_truncated",
            good[..good.len() / 3].to_owned(),
            vec!["invalid scene file"],
        ),
        (
            "toml_wrong_value_type",
            edit("fov_y = 40.0", "fov_y = \"wide\""),
            vec!["invalid scene file", "fov_y"],
        ),
        (
            "toml_unknown_key",
            edit("[camera]\n", "[camera]\nzoom = 2\n"),
            vec!["unknown field `zoom`"],
        ),
        (
            "toml_unknown_material_type",
            edit("\"lambert\"", "\"velvet\""),
            vec!["materials.m.type", "unknown type `velvet`"],
        ),
        (
            "toml_material_missing_parameter",
            edit("\"lambert\"", "\"phong\""),
            vec!["materials.m.specular", "required by type phong"],
        ),
        (
            "toml_material_nan_albedo",
            edit("albedo = [0.5, 0.5, 0.5]", "albedo = [nan, 0.5, 0.5]"),
            vec!["materials.m.albedo"],
        ),
        (
            "toml_material_albedo_above_one",
            edit("albedo = [0.5, 0.5, 0.5]", "albedo = [1.5, 0.5, 0.5]"),
            vec!["materials.m.albedo"],
        ),
        (
            "toml_material_negative_roughness",
            edit(
                "type = \"lambert\"",
                "type = \"ward\"\nspecular = [0.1, 0.1, 0.1]\nroughness = -1.0",
            ),
            vec!["materials.m.roughness"],
        ),
        (
            "toml_pbr_roughness_above_one",
            edit(
                "type = \"lambert\"",
                "type = \"pbr\"\nbase_color = [0.5, 0.5, 0.5]\nmetallic = 0.0\nroughness = 1.5",
            ),
            vec!["materials.m.roughness", "outside [0, 1]"],
        ),
        (
            "toml_pbr_metallic_negative",
            edit(
                "type = \"lambert\"",
                "type = \"pbr\"\nbase_color = [0.5, 0.5, 0.5]\nmetallic = -0.5\nroughness = 0.5",
            ),
            vec!["materials.m.metallic", "outside [0, 1]"],
        ),
        (
            "toml_undefined_material",
            edit("material = \"m\"", "material = \"gold\""),
            vec!["objects[0].material", "`gold` is not defined"],
        ),
        (
            "toml_missing_mesh_file",
            edit("tetra.obj", "nowhere.obj"),
            vec!["objects[0].mesh", "nowhere.obj", "does not exist"],
        ),
        (
            "toml_mesh_is_a_directory",
            edit("tetra.obj", "a_directory.obj"),
            vec!["objects[0].mesh", "is not a file"],
        ),
        (
            "toml_mesh_unknown_extension",
            edit("tetra.obj", "mesh.ply"),
            vec!["mesh.ply", "unknown mesh extension"],
        ),
        (
            "toml_missing_env_file",
            edit("env.exr", "nowhere.exr"),
            vec!["environment.file", "nowhere.exr", "does not exist"],
        ),
        (
            "toml_nan_camera",
            edit("eye = [0.5, 0.5, 3.0]", "eye = [nan, 0.5, 3.0]"),
            vec!["camera.eye", "not finite"],
        ),
        (
            "toml_camera_eye_equals_target",
            edit("eye = [0.5, 0.5, 3.0]", "eye = [0.2, 0.2, 0.2]"),
            vec!["camera.target"],
        ),
        (
            "toml_camera_fov_180",
            edit("fov_y = 40.0", "fov_y = 180.0"),
            vec!["camera.fov_y"],
        ),
        (
            "toml_camera_zero_resolution",
            edit("resolution = [8, 6]", "resolution = [0, 6]"),
            vec!["camera.resolution"],
        ),
        (
            "toml_camera_negative_resolution",
            edit("resolution = [8, 6]", "resolution = [-8, 6]"),
            vec!["invalid scene file"],
        ),
        (
            "toml_camera_huge_resolution",
            edit(
                "resolution = [8, 6]",
                "resolution = [4294967295, 4294967295]",
            ),
            vec!["camera.resolution", "too large"],
        ),
        (
            "toml_camera_direction_overflow",
            edit(
                "eye = [0.5, 0.5, 3.0]\ntarget = [0.2, 0.2, 0.2]",
                "eye = [1e308, 0.0, 0.0]\ntarget = [-1e308, 0.0, 0.0]",
            ),
            vec!["camera.target", "overflows"],
        ),
        (
            "toml_inf_translate",
            edit(
                "material = \"m\"",
                "material = \"m\"\ntranslate = [inf, 0.0, 0.0]",
            ),
            vec!["objects[0].translate", "not finite"],
        ),
        (
            "toml_zero_scale",
            edit("material = \"m\"", "material = \"m\"\nscale = 0"),
            vec!["objects[0].scale", "non-zero"],
        ),
        (
            "toml_scale_wrong_type",
            edit("material = \"m\"", "material = \"m\"\nscale = \"big\""),
            vec!["objects[0].scale"],
        ),
        (
            "toml_env_negative_scale",
            edit("[materials.m]", "scale = -1.0\n\n[materials.m]"),
            vec!["environment.scale"],
        ),
        (
            "toml_env_nan_rotation",
            edit("[materials.m]", "rotation_y = nan\n\n[materials.m]"),
            vec!["environment.rotation_y"],
        ),
        (
            "toml_env_unknown_mapping",
            edit("[materials.m]", "mapping = \"cube\"\n\n[materials.m]"),
            vec!["invalid scene file", "cube"],
        ),
        (
            "toml_spp_zero",
            edit("spp = 1", "spp = 0"),
            vec!["render.spp"],
        ),
        (
            "toml_bounces_below_minus_one",
            edit("bounces = 0", "bounces = -2"),
            vec!["render.bounces"],
        ),
        (
            "toml_deeply_nested_array",
            format!("x = {}{}\n", "[".repeat(100_000), "]".repeat(100_000)),
            vec!["invalid scene file"],
        ),
        (
            "toml_duplicate_table",
            format!("{good}\n[camera]\n"),
            vec!["invalid scene file"],
        ),
    ];
    let mut cases = Vec::new();
    for (row, text, frags) in fail {
        let scene = write(d, &format!("{row}.toml"), text);
        let mut c = render_case(
            row,
            scene,
            &out,
            &format!("{row}.toml"),
            Expect::Error(frags),
        );
        c.row = row;
        cases.push(c);
    }
    write(d, "png.toml", PNG_BYTES);
    cases.push(render_case(
        "toml_wrong_type_png",
        d.join("png.toml"),
        &out,
        "png.toml",
        err(&["cannot read"]),
    ));
    cases.push(render_case(
        "toml_missing_scene_file",
        d.join("missing.toml"),
        &out,
        "missing.toml",
        err(&["cannot read"]),
    ));
    // Bake of a scene with unlimited bounces and no --bounces.
    let unlimited = write(d, "unlimited.toml", edit("bounces = 0", "bounces = -1"));
    cases.push(
        case(
            "toml_bake_unlimited_bounces",
            &[
                &"bake",
                &unlimited,
                &"--rays",
                &"4",
                &"--out",
                &out.join("u.prtb"),
            ],
            "unlimited.toml",
            err(&["--bounces"]),
        )
        .watching(&out),
    );
    run_table(&cases);

    // Warnings: unused parameters, albedo + specular > 1, no objects.
    let warned: Vec<(&'static str, String, Vec<&'static str>)> = vec![
        (
            "toml_unused_parameter",
            edit(
                "albedo = [0.5, 0.5, 0.5]",
                "albedo = [0.5, 0.5, 0.5]\nexponent = 3.0",
            ),
            vec!["materials.m.exponent: ignored"],
        ),
        (
            "toml_albedo_plus_specular_above_one",
            edit(
                "type = \"lambert\"",
                "type = \"mirror\"\nspecular = [0.9, 0.9, 0.9]",
            ),
            vec!["exceeds 1"],
        ),
        (
            "toml_no_objects",
            good[..good.find("[[objects]]").unwrap()].to_owned(),
            vec!["no [[objects]]"],
        ),
    ];
    let mut cases = Vec::new();
    for (row, text, frags) in warned {
        let scene = write(d, &format!("{row}.toml"), text);
        cases.push(unwatch(render_case(
            row,
            scene,
            &out,
            &format!("{row}.toml"),
            Expect::Warning(frags),
        )));
    }
    run_table(&cases);
}

// ---------------------------------------------------------------------------------------------
// Bake files: `prt inspect` and `prt merge`

fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().unwrap())
}

/// Recomputes every section CRC and the header CRC (SPEC.md §2), so that a change reaches
/// the checks behind the checksums.
fn fix_crcs(b: &mut [u8]) {
    let table = u64_at(b, 32) as usize;
    let count = u32_at(b, 40) as usize;
    for i in 0..count {
        let e = table + 32 * i;
        let (off, len) = (u64_at(b, e + 8) as usize, u64_at(b, e + 16) as usize);
        let crc = crc32(&b[off..off + len]);
        b[e + 24..e + 28].copy_from_slice(&crc.to_le_bytes());
    }
    let mut h = b[..60].to_vec();
    h.extend_from_slice(&b[table..table + 32 * count]);
    let crc = crc32(&h);
    b[60..64].copy_from_slice(&crc.to_le_bytes());
}

/// CRC-32 (IEEE, reflected, as zlib), bit by bit: tiny inputs only.
fn crc32(data: &[u8]) -> u32 {
    let mut c = !0u32;
    for &byte in data {
        c ^= u32::from(byte);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                (c >> 1) ^ 0xEDB8_8320
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// Payload range of the first section tagged `tag`.
fn section(b: &[u8], tag: &[u8; 4]) -> std::ops::Range<usize> {
    let table = u64_at(b, 32) as usize;
    (0..u32_at(b, 40) as usize)
        .map(|i| table + 32 * i)
        .find(|&e| &b[e..e + 4] == tag)
        .map(|e| {
            let off = u64_at(b, e + 8) as usize;
            off..off + u64_at(b, e + 16) as usize
        })
        .expect("section")
}

fn bake(args: &[&dyn AsRefOs]) {
    let f = run_prt(&args.iter().map(|a| a.os()).collect::<Vec<_>>(), TIME_LIMIT).unwrap();
    assert!(f.status.success(), "bake failed: {}", f.stderr);
}

#[test]
fn bake_file_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let scene = tiny_scene(d);
    let base: [&dyn AsRefOs; 8] = [
        &"bake",
        &scene,
        &"--order",
        &"2",
        &"--rays",
        &"8",
        &"--bounces",
        &"0",
    ];
    let good = d.join("good.prtb");
    let with = |extra: &[&dyn AsRefOs]| {
        let mut v: Vec<&dyn AsRefOs> = base.to_vec();
        v.extend_from_slice(extra);
        bake(&v);
    };
    with(&[&"--out", &good]);
    let (s0, s1) = (d.join("s0.prtb"), d.join("s1.prtb"));
    with(&[&"--shard", &"0/2", &"--out", &s0]);
    with(&[&"--shard", &"1/2", &"--out", &s1]);
    let f16 = d.join("s1_f16.prtb");
    with(&[&"--shard", &"1/2", &"--f16", &"--out", &f16]);
    let other_seed = d.join("s1_seed9.prtb");
    with(&[&"--shard", &"1/2", &"--seed", &"9", &"--out", &other_seed]);
    let g = std::fs::read(&good).unwrap();

    let mut files: Vec<(&str, Vec<u8>)> = vec![
        ("empty.prtb", Vec::new()),
        ("text.prtb", b"a text file renamed .prtb\n".to_vec()),
        ("png.prtb", PNG_BYTES.to_vec()),
        ("truncated_half.prtb", g[..g.len() / 2].to_vec()),
        ("truncated_header.prtb", g[..20].to_vec()),
        ("truncated_last_byte.prtb", g[..g.len() - 1].to_vec()),
        ("trailing_bytes.prtb", [&g[..], b"extra"].concat()),
    ];
    let mut flipped = g.clone();
    let mid = section(&g, b"XFER").start + 2;
    flipped[mid] ^= 0x40;
    files.push(("flipped_byte.prtb", flipped));
    let mut huge_count = g.clone();
    huge_count[40..44].copy_from_slice(&u32::MAX.to_le_bytes());
    files.push(("huge_section_count.prtb", huge_count));
    let mut table_past_end = g.clone();
    table_past_end[32..40].copy_from_slice(&(u64::MAX - 7).to_le_bytes());
    files.push(("table_past_end.prtb", table_past_end));
    // A section length of 2⁶² with the CRCs recomputed over what is there.
    let mut huge_len = g.clone();
    let table = u64_at(&g, 32) as usize;
    huge_len[table + 16..table + 24].copy_from_slice(&(1u64 << 62).to_le_bytes());
    let crc = crc32(&{
        let mut h = huge_len[..60].to_vec();
        h.extend_from_slice(&huge_len[table..table + 32 * u32_at(&g, 40) as usize]);
        h
    });
    huge_len[60..64].copy_from_slice(&crc.to_le_bytes());
    files.push(("huge_section_length.prtb", huge_len));
    for (value, name) in [
        (f32::NAN, "nan_coefficient.prtb"),
        (f32::INFINITY, "inf_coefficient.prtb"),
        (f32::NEG_INFINITY, "neg_inf_coefficient.prtb"),
    ] {
        let mut b = g.clone();
        let x = section(&b, b"XFER");
        let at = x.end - 4;
        b[at..at + 4].copy_from_slice(&value.to_le_bytes());
        fix_crcs(&mut b);
        files.push((name, b));
    }
    let mut bad_version = g.clone();
    bad_version[8..10].copy_from_slice(&99u16.to_le_bytes());
    files.push(("future_major_version.prtb", bad_version));
    for (name, bytes) in &files {
        write(d, name, bytes);
    }

    let inspect =
        |row, file: &str, f: &[&'static str]| case(row, &[&"inspect", &d.join(file)], file, err(f));
    let mut cases = vec![
        inspect("bake_empty", "empty.prtb", &["truncated"]),
        inspect(
            "bake_wrong_type_text",
            "text.prtb",
            &["not a PRT bake file"],
        ),
        inspect("bake_wrong_type_png", "png.prtb", &["not a PRT bake file"]),
        inspect("bake_truncated_half", "truncated_half.prtb", &["truncated"]),
        inspect(
            "bake_truncated_header",
            "truncated_header.prtb",
            &["truncated"],
        ),
        inspect(
            "bake_truncated_last_byte",
            "truncated_last_byte.prtb",
            &["truncated"],
        ),
        inspect(
            "bake_trailing_bytes",
            "trailing_bytes.prtb",
            &["trailing bytes"],
        ),
        inspect("bake_flipped_byte", "flipped_byte.prtb", &["XFER"]),
        inspect(
            "bake_huge_section_count",
            "huge_section_count.prtb",
            &["extends past the end"],
        ),
        inspect(
            "bake_table_offset_past_end",
            "table_past_end.prtb",
            &["extends past the end"],
        ),
        inspect(
            "bake_huge_section_length",
            "huge_section_length.prtb",
            &["extends past the end"],
        ),
        inspect(
            "bake_nan_coefficient",
            "nan_coefficient.prtb",
            &["non-finite value in XFER"],
        ),
        inspect(
            "bake_inf_coefficient",
            "inf_coefficient.prtb",
            &["non-finite value in XFER"],
        ),
        inspect(
            "bake_neg_inf_coefficient",
            "neg_inf_coefficient.prtb",
            &["non-finite value in XFER"],
        ),
        inspect(
            "bake_future_major_version",
            "future_major_version.prtb",
            // The minor after "99." is the writer's (prt_bakefile::VERSION_MINOR).
            &[
                "unsupported format version 99.",
                "this reader reads major version 1",
            ],
        ),
        inspect("bake_missing_file", "missing.prtb", &["cannot read"]),
    ];
    // Merge: the output directory already holds a file at --out, which must stay as it was.
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    let merged = out.join("merged.prtb");
    std::fs::write(&merged, b"previous contents").unwrap();
    let merge = |row, shards: &[&Path], names: &str, f: &[&'static str]| {
        let mut args: Vec<&dyn AsRefOs> = vec![&"merge"];
        let owned: Vec<PathBuf> = shards.iter().map(|p| p.to_path_buf()).collect();
        for p in &owned {
            args.push(p);
        }
        args.push(&"--out");
        args.push(&merged);
        case(row, &args, names, err(f)).watching(&out)
    };
    let bad = |n: &str| d.join(n);
    cases.extend([
        merge(
            "merge_corrupt_shard",
            &[&s0, &bad("flipped_byte.prtb")],
            "flipped_byte.prtb",
            &["checksum mismatch"],
        ),
        merge(
            "merge_truncated_shard",
            &[&s0, &bad("truncated_half.prtb")],
            "truncated_half.prtb",
            &["truncated"],
        ),
        merge(
            "merge_missing_shard_file",
            &[&s0, &bad("missing.prtb")],
            "missing.prtb",
            &["cannot read"],
        ),
        merge(
            "merge_incomplete_set",
            &[&s0],
            "shard",
            &["the shards say there are 2"],
        ),
        merge(
            "merge_duplicate_shard",
            &[&s0, &s0, &s1],
            "shard",
            &["the shards say there are 2"],
        ),
        merge("merge_mixed_f16_f32", &[&s0, &f16], "s1_f16.prtb", &["f16"]),
        merge(
            "merge_mismatched_seed",
            &[&s0, &other_seed],
            "seed",
            &["different metadata"],
        ),
        merge(
            "merge_not_a_bake",
            &[&s0, &bad("text.prtb")],
            "text.prtb",
            &["not a PRT bake file"],
        ),
    ]);
    let missing_dir = d.join("no_such_dir").join("m.prtb");
    cases.push(case(
        "merge_out_in_missing_directory",
        &[&"merge", &s0, &s1, &"--out", &missing_dir],
        "no_such_dir",
        err(&["No such file or directory"]),
    ));
    run_table(&cases);
}

// ---------------------------------------------------------------------------------------------
// Impossible options

#[test]
fn option_rows() {
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    let scene = tiny_scene(d);
    let map = d.join("env.exr");
    let out = d.join("out");
    std::fs::create_dir(&out).unwrap();
    // A previous output that a failed run must leave alone.
    std::fs::write(out.join("b.prtb"), b"previous bake").unwrap();
    std::fs::write(out.join("r.exr"), b"previous render").unwrap();
    let prtb = out.join("b.prtb");
    let exr = out.join("r.exr");
    let bake = |row, opts: &[&'static str], names: &str, f: &[&'static str]| {
        let mut args: Vec<&dyn AsRefOs> = vec![&"bake", &scene];
        for o in opts {
            args.push(o);
        }
        if !opts.iter().any(|o| o.starts_with("--rays")) {
            args.extend([&"--rays" as &dyn AsRefOs, &"4"]);
        }
        if !opts.iter().any(|o| o.starts_with("--bounces")) {
            args.extend([&"--bounces" as &dyn AsRefOs, &"0"]);
        }
        args.push(&"--out");
        args.push(&prtb);
        case(row, &args, names, err(f)).watching(&out)
    };
    let render = |row, opts: &[&'static str], names: &str, f: &[&'static str]| {
        let mut args: Vec<&dyn AsRefOs> = vec![&"render", &scene, &"--quiet"];
        for o in opts {
            args.push(o);
        }
        args.push(&"--out");
        args.push(&exr);
        case(row, &args, names, err(f)).watching(&out)
    };
    let project = |row, opts: &[&'static str], names: &str, f: &[&'static str]| {
        let mut args: Vec<&dyn AsRefOs> = vec![&"sh", &"project", &map];
        for o in opts {
            args.push(o);
        }
        case(row, &args, names, err(f))
    };
    let cases = vec![
        bake(
            "opt_bake_order_0",
            &["--order", "0"],
            "order 0",
            &["between 1 and"],
        ),
        bake(
            "opt_bake_order_huge",
            &["--order", "100000"],
            "order 100000",
            &["between 1 and"],
        ),
        bake(
            "opt_bake_max_order_0",
            &["--max-order", "0"],
            "max order 0",
            &["between 1 and"],
        ),
        bake(
            "opt_bake_shard_3_of_2",
            &["--shard", "3/2"],
            "3/2",
            &["index must be below the count"],
        ),
        bake(
            "opt_bake_shard_of_0",
            &["--shard", "0/0"],
            "0/0",
            &["index must be below the count"],
        ),
        bake(
            "opt_bake_shard_not_numbers",
            &["--shard", "a/b"],
            "--shard",
            &["not a number"],
        ),
        bake(
            "opt_bake_shard_no_slash",
            &["--shard", "2"],
            "--shard",
            &["I/N"],
        ),
        bake(
            "opt_bake_shard_negative",
            &["--shard=-1/2"],
            "--shard",
            &["not a number"],
        ),
        bake("opt_bake_rays_0", &["--rays", "0"], "rays", &["at least 1"]),
        bake(
            "opt_bake_rays_negative",
            &["--rays=-5"],
            "--rays",
            &["invalid value"],
        ),
        bake(
            "opt_bake_bounces_huge",
            &["--bounces", "1000"],
            "1000 bounces",
            &["supported 64"],
        ),
        bake(
            "opt_bake_error_target_0",
            &["--error-target", "0"],
            "error target",
            &["must be in (0, 1)"],
        ),
        bake(
            "opt_bake_error_target_nan",
            &["--error-target", "NaN"],
            "error target",
            &["must be in (0, 1)"],
        ),
        render("opt_render_spp_0", &["--spp", "0"], "spp", &["at least 1"]),
        render(
            "opt_render_target_noise_0",
            &["--target-noise", "0"],
            "target noise",
            &["(0, 1)"],
        ),
        render(
            "opt_render_target_noise_negative",
            &["--target-noise", "-0.01"],
            "target noise",
            &["(0, 1)"],
        ),
        render(
            "opt_render_target_noise_nan",
            &["--target-noise", "NaN"],
            "target noise",
            &["(0, 1)"],
        ),
        render(
            "opt_render_target_psnr_ldr_0",
            &["--target-psnr-ldr", "0"],
            "target PSNR",
            &["positive, finite"],
        ),
        render(
            "opt_render_target_psnr_ldr_nan",
            &["--target-psnr-ldr", "NaN"],
            "target PSNR",
            &["positive, finite"],
        ),
        bake(
            "opt_bake_target_psnr_0",
            &["--target-psnr", "0"],
            "--target-psnr",
            &["positive, finite"],
        ),
        bake(
            "opt_bake_target_psnr_nan",
            &["--target-psnr", "NaN"],
            "--target-psnr",
            &["positive, finite"],
        ),
        bake(
            "opt_bake_target_psnr_unreachable",
            &["--target-psnr", "99", "--order", "2"],
            "--target-psnr",
            &["cannot be met", "reaches at most"],
        ),
        render(
            "opt_render_time_budget_0",
            &["--time-budget", "0"],
            "time budget",
            &["positive number of seconds"],
        ),
        render(
            "opt_render_time_budget_too_short",
            &["--time-budget", "1e-9"],
            "time budget",
            &["too short for one pass"],
        ),
        render(
            "opt_render_bounces_minus_2",
            &["--bounces", "-2"],
            "bounces",
            &["not -2"],
        ),
        render(
            "opt_render_exposure_nan",
            &["--exposure", "NaN"],
            "--exposure",
            &["finite"],
        ),
        render(
            "opt_render_ao_distance_negative",
            &["--ao", "--ao-distance=-1"],
            "distance",
            &["must be positive"],
        ),
        render(
            "opt_render_ao_distance_nan",
            &["--ao", "--ao-distance", "NaN"],
            "distance",
            &["must be positive"],
        ),
        project(
            "opt_sh_order_0",
            &["--order", "0"],
            "--order 0",
            &["out of range"],
        ),
        project(
            "opt_sh_order_huge",
            &["--order", "100000"],
            "--order 100000",
            &["out of range"],
        ),
        project(
            "opt_sh_rotate_nan",
            &["--order", "2", "--rotate-y", "NaN"],
            "--rotate-y",
            &["finite"],
        ),
        project(
            "opt_sh_angular_subsamples_0",
            &[
                "--order",
                "2",
                "--mapping",
                "angular",
                "--angular-subsamples",
                "0",
            ],
            "subsamples",
            &["between 1 and 64"],
        ),
        project(
            "opt_sh_angular_subsamples_huge",
            &[
                "--order",
                "2",
                "--mapping",
                "angular",
                "--angular-subsamples",
                "1000000000",
            ],
            "subsamples",
            &["between 1 and 64"],
        ),
        case(
            "opt_sh_eval_zero_direction",
            &[&"sh", &"eval", &"--order", &"2", &"--dir", &"0,0,0"],
            "--dir",
            err(&["zero vector"]),
        ),
        case(
            "opt_sh_eval_nan_direction",
            &[&"sh", &"eval", &"--order", &"2", &"--dir", &"nan,0,1"],
            "--dir",
            err(&["not finite"]),
        ),
        case(
            "opt_bake_out_in_missing_directory",
            &[
                &"bake",
                &scene,
                &"--rays",
                &"4",
                &"--bounces",
                &"0",
                &"--order",
                &"2",
                &"--out",
                &d.join("no_such_dir/b.prtb"),
            ],
            "no_such_dir",
            err(&["No such file or directory"]),
        ),
        case(
            "opt_render_out_in_missing_directory",
            &[
                &"render",
                &scene,
                &"--quiet",
                &"--out",
                &d.join("no_such_dir/r.exr"),
            ],
            "no_such_dir",
            err(&["cannot write"]),
        ),
    ];
    run_table(&cases);
}

// ---------------------------------------------------------------------------------------------
// The real third-party assets of /work/shared/assets (skipped where the folder is absent)

#[test]
fn real_asset_rows() {
    let a = assets();
    if !a.is_dir() {
        eprintln!("skipped: {} is absent", a.display());
        return;
    }
    let t = tempfile::tempdir().unwrap();
    let d = t.path();
    uniform_exr(&d.join("env.exr"));
    let mut cases = Vec::new();
    for name in [
        "courtyard",
        "forest",
        "interior",
        "studio",
        "sunrise",
        "sunset",
    ] {
        let map = a.join(format!("hdri/{name}.exr"));
        let row: &'static str = Box::leak(format!("asset_hdri_{name}").into_boxed_str());
        cases.push(case(
            row,
            &[&"sh", &"project", &map, &"--order", &"3"],
            &format!("{name}.exr"),
            warn(&["clamped"]),
        ));
    }
    for (row, mesh, e) in [
        (
            "asset_bunny_lowres_obj",
            "meshes/bunny_lowres.obj",
            Expect::Clean,
        ),
        ("asset_bunny_obj", "meshes/bunny.obj", Expect::Clean),
        ("asset_teapot_obj", "meshes/teapot.obj", Expect::Clean),
        ("asset_suzanne_obj", "meshes/suzanne.obj", Expect::Clean),
        (
            "asset_2cylinder_engine_glb",
            "gltf/2CylinderEngine.glb",
            warn(&["degenerate"]),
        ),
        (
            "asset_box_textured_gltf",
            "gltf/BoxTextured-glTF/BoxTextured.gltf",
            Expect::Clean,
        ),
    ] {
        let path = a.join(mesh);
        let scene = mesh_scene(d, row, &path.to_string_lossy());
        let file = path.file_name().unwrap().to_string_lossy().into_owned();
        cases.push(case(
            row,
            &[
                &"render",
                &scene,
                &"--quiet",
                &"--spp",
                &"1",
                &"--out",
                &d.join(format!("{row}.exr")),
            ],
            &file,
            e,
        ));
    }
    run_table(&cases);
}

// ---------------------------------------------------------------------------------------------
// Reliability: an interrupted bake

#[test]
fn sigint_during_bake_keeps_the_previous_output() {
    let t = tempfile::tempdir().unwrap();
    let out = t.path().join("out");
    std::fs::create_dir(&out).unwrap();
    let target = out.join("default.prtb");
    std::fs::write(&target, b"the previous bake, which must survive").unwrap();
    let before = snapshot(&out);
    let mut child = Command::new(env!("CARGO_BIN_EXE_prt"))
        .arg("bake")
        .arg(repo().join("scenes/default.toml"))
        .args(["--rays", "4096", "--threads", "2", "--out"])
        .arg(&target)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    std::thread::sleep(Duration::from_millis(500));
    assert!(
        child.try_wait().unwrap().is_none(),
        "the bake ended within 0.5 s: the test needs a longer bake"
    );
    let kill = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let start = Instant::now();
    let status = loop {
        if let Some(s) = child.try_wait().unwrap() {
            break s;
        }
        if start.elapsed() > Duration::from_secs(10) {
            let _ = child.kill();
            panic!("hang: prt bake did not stop within 10 s of SIGINT");
        }
        std::thread::sleep(Duration::from_millis(10));
    };
    assert!(!status.success(), "an interrupted bake reported success");
    assert_eq!(
        snapshot(&out),
        before,
        "the output directory changed: a temporary file was left or the old bake was replaced"
    );
}
