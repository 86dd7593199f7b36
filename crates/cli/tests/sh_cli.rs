//! `prt sh ...` end to end: JSON shape and precision, agreement with closed forms, and clear
//! errors with a non-zero exit for bad input.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn prt(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_prt"))
        .args(args)
        .output()
        .expect("run prt")
}

fn write_exr(path: &Path, w: usize, h: usize, f: impl Fn(usize, usize) -> [f32; 3] + Sync) {
    exr::prelude::write_rgb_file(path, w, h, |x, y| {
        let v = f(x, y);
        (v[0], v[1], v[2])
    })
    .unwrap();
}

fn repo() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../..")
}

#[test]
fn project_json_of_uniform_map_is_dc_only_with_full_precision() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("uniform.exr");
    write_exr(&path, 16, 8, |_, _| [1.0, 0.5, 0.25]);
    let out = prt(&[
        "sh",
        "project",
        path.to_str().unwrap(),
        "--order",
        "4",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(v["order"], 4);
    let c = v["coefficients"].as_array().unwrap();
    assert_eq!(c.len(), 16);
    let s = (4.0 * std::f64::consts::PI).sqrt();
    for ch in 0..3 {
        let got = c[0][ch].as_f64().unwrap();
        assert!((got - s * [1.0, 0.5, 0.25][ch]).abs() < 1e-14, "{got}");
    }
    for row in &c[1..] {
        for x in row.as_array().unwrap() {
            assert!(x.as_f64().unwrap().abs() < 1e-14);
        }
    }
}

#[test]
fn project_rotation_and_real_map() {
    // A map bright only in the column looking down −Z (u ≈ 0): band-1 direction of the
    // projection points to −Z; rotated by +90° about +Y it points to R_y(90°)(−Z) = −X.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("spot.exr");
    write_exr(&path, 64, 32, |x, y| {
        if (x == 0 || x == 63) && (14..18).contains(&y) {
            [100.0; 3]
        } else {
            [0.0; 3]
        }
    });
    let band1 = |rot: &str| {
        let out = prt(&[
            "sh",
            "project",
            path.to_str().unwrap(),
            "--order",
            "2",
            "--rotate-y",
            rot,
            "--json",
        ]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let c: Vec<f64> = (0..4)
            .map(|i| v["coefficients"][i][0].as_f64().unwrap())
            .collect();
        // y_1^{-1} ∝ −y, y_1^0 ∝ z, y_1^1 ∝ −x  ⇒  direction ∝ (−c3, −c1, c2).
        glam::DVec3::new(-c[3], -c[1], c[2]).normalize()
    };
    assert!(band1("0").dot(glam::DVec3::NEG_Z) > 0.99);
    assert!(band1("90").dot(glam::DVec3::NEG_X) > 0.99);
    // A bundled real map (lossy EXR with negative texels: a warning, not an error).
    let real = repo().join("scenes/maps/courtyard.exr");
    let out = prt(&["sh", "project", real.to_str().unwrap(), "--order", "3"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(
        String::from_utf8_lossy(&out.stdout)
            .lines()
            .filter(|l| !l.starts_with('#'))
            .count(),
        1 + 9
    );
}

#[test]
fn eval_json_matches_closed_form() {
    let out = prt(&["sh", "eval", "--order", "2", "--dir", "0,0,-2", "--json"]);
    assert!(out.status.success());
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let vals: Vec<f64> = v["values"]
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap())
        .collect();
    let k = (3.0 / (4.0 * std::f64::consts::PI)).sqrt();
    assert_eq!(vals.len(), 4);
    assert!((vals[2] + k).abs() < 1e-15 && vals[1].abs() < 1e-15 && vals[3].abs() < 1e-15);
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let nan = dir.path().join("nan.exr");
    write_exr(&nan, 8, 4, |x, y| {
        if (x, y) == (3, 2) {
            [1.0, f32::NAN, 1.0]
        } else {
            [1.0; 3]
        }
    });
    let not_image = dir.path().join("text.exr");
    std::fs::write(&not_image, "hello").unwrap();
    let ok = dir.path().join("ok.exr");
    write_exr(&ok, 8, 4, |_, _| [1.0; 3]);
    let cases: Vec<(Vec<String>, &str)> = vec![
        (
            vec![
                "sh".into(),
                "project".into(),
                dir.path().join("missing.exr").display().to_string(),
                "--order".into(),
                "3".into(),
            ],
            "missing.exr",
        ),
        (
            vec![
                "sh".into(),
                "project".into(),
                not_image.display().to_string(),
                "--order".into(),
                "3".into(),
            ],
            "text.exr",
        ),
        (
            vec![
                "sh".into(),
                "project".into(),
                nan.display().to_string(),
                "--order".into(),
                "3".into(),
            ],
            "nan.exr",
        ),
        (
            vec![
                "sh".into(),
                "project".into(),
                ok.display().to_string(),
                "--order".into(),
                "0".into(),
            ],
            "order",
        ),
        (
            vec![
                "sh".into(),
                "project".into(),
                ok.display().to_string(),
                "--order".into(),
                "100000".into(),
            ],
            "order",
        ),
        (
            vec![
                "sh".into(),
                "eval".into(),
                "--order".into(),
                "3".into(),
                "--dir".into(),
                "0,0,0".into(),
            ],
            "zero",
        ),
        (
            vec![
                "sh".into(),
                "eval".into(),
                "--order".into(),
                "3".into(),
                "--dir".into(),
                "1,nan,0".into(),
            ],
            "finite",
        ),
    ];
    for (args, needle) in cases {
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = prt(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{args:?} should fail");
        assert!(
            err.contains(needle),
            "{args:?}: message {err:?} should mention {needle:?}"
        );
        assert!(!err.contains("panicked"), "{args:?} panicked: {err}");
    }
}

/// A reader that stops early (`prt sh eval … | head -c 100`): the 2.7 MB of output cannot fit
/// in the pipe, so the write fails with a broken pipe once the reader is gone; the command
/// ends quietly with success instead of panicking in `println!`.
#[test]
fn a_closed_stdout_ends_the_command_quietly() {
    use std::io::Read;
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_prt"))
        .args(["sh", "eval", "--order", "256", "--dir", "0,1,0"])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut first = [0u8; 100];
    child
        .stdout
        .as_mut()
        .unwrap()
        .read_exact(&mut first)
        .unwrap();
    drop(child.stdout.take());
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(out.status.success(), "{:?}: {stderr}", out.status);
}
