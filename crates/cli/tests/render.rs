//! `prt render`: success on the default scene, clear errors and non-zero exits on bad input.

use std::path::PathBuf;
use std::process::Command;

fn prt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_prt"))
}

fn scene(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("../../scenes")
        .join(name)
}

#[test]
fn test01_renders_default_scene_to_exr_and_png() {
    let dir = tempfile::tempdir().unwrap();
    let (exr_path, png_path) = (dir.path().join("x.exr"), dir.path().join("x.png"));
    let out = prt()
        .arg("render")
        .arg(scene("default.toml"))
        .args([
            "--spp",
            "2",
            "--bounces",
            "0",
            "--seed",
            "7",
            "--threads",
            "2",
            "--quiet",
            "--aovs",
        ])
        .arg("--out")
        .arg(&exr_path)
        .arg("--png")
        .arg(&png_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let image = exr::prelude::read_all_flat_layers_from_file(&exr_path).unwrap();
    let layer = &image.layer_data[0];
    let attr = |k: &str| {
        layer
            .attributes
            .other
            .get(&exr::prelude::Text::from(k))
            .cloned()
    };
    assert_eq!(attr("prt.spp"), Some(exr::prelude::AttributeValue::I32(2)));
    assert_eq!(
        attr("prt.bounces"),
        Some(exr::prelude::AttributeValue::I32(0))
    );
    assert_eq!(
        attr("prt.seed"),
        Some(exr::prelude::AttributeValue::Text(
            exr::prelude::Text::from("7")
        ))
    );
    assert!(layer
        .channel_data
        .list
        .iter()
        .any(|c| c.name.to_string() == "variance.R"));
    let png = image::open(&png_path).unwrap();
    assert_eq!(
        (png.width() as usize, png.height() as usize),
        (layer.size.0, layer.size.1)
    );

    // The single-sequence sampler: an image without a noise estimate (NaN in the EXR), not
    // the replicas' image.
    let single_path = dir.path().join("single.exr");
    let out = prt()
        .arg("render")
        .arg(scene("default.toml"))
        .args([
            "--spp",
            "2",
            "--bounces",
            "0",
            "--seed",
            "7",
            "--quiet",
            "--sampler",
            "single",
        ])
        .arg("--out")
        .arg(&single_path)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let single = exr::prelude::read_all_flat_layers_from_file(&single_path).unwrap();
    let noise = single.layer_data[0]
        .attributes
        .other
        .get(&exr::prelude::Text::from("prt.noise_estimate"))
        .cloned();
    assert!(
        matches!(noise, Some(exr::prelude::AttributeValue::F64(x)) if x.is_nan()),
        "{noise:?}"
    );
    assert!(matches!(
        attr("prt.noise_estimate"),
        Some(exr::prelude::AttributeValue::F64(x)) if x.is_finite()
    ));
    let red = |img: &exr::prelude::FlatImage| {
        let c = img.layer_data[0]
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == "R")
            .expect("an R channel");
        match &c.sample_data {
            exr::prelude::FlatSamples::F32(v) => v.clone(),
            other => panic!("{other:?}"),
        }
    };
    assert_ne!(red(&single), red(&image));

    // AO and unshadowed modes run too.
    for mode in [
        ["--ao", "--ao-distance=0.5"],
        ["--unshadowed", "--bounces=-1"],
    ] {
        let out = prt()
            .arg("render")
            .arg(scene("default.toml"))
            .args(["--spp", "1", "--quiet"])
            .args(mode)
            .arg("--out")
            .arg(&exr_path)
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{mode:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
}

#[test]
fn test02_bad_input_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.exr");
    let cases: Vec<Vec<String>> = vec![
        vec![dir.path().join("missing.toml").display().to_string()],
        vec![
            scene("default.toml").display().to_string(),
            "--spp".into(),
            "0".into(),
        ],
        vec![
            scene("default.toml").display().to_string(),
            "--bounces".into(),
            "-2".into(),
        ],
        vec![
            scene("default.toml").display().to_string(),
            "--threads".into(),
            "0".into(),
        ],
        vec![
            scene("default.toml").display().to_string(),
            "--ao".into(),
            "--unshadowed".into(),
        ],
        vec![
            scene("default.toml").display().to_string(),
            "--spp".into(),
            "many".into(),
        ],
        vec![
            scene("default.toml").display().to_string(),
            "--sampler".into(),
            "stratified".into(),
        ],
        // The single sequence has no noise estimate to stop on.
        vec![
            scene("default.toml").display().to_string(),
            "--sampler".into(),
            "single".into(),
            "--target-noise".into(),
            "0.05".into(),
        ],
    ];
    for args in cases {
        let out = prt()
            .arg("render")
            .args(&args)
            .arg("--quiet")
            .arg("--out")
            .arg(&out_path)
            .output()
            .unwrap();
        assert!(!out.status.success(), "{args:?} should fail");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(stderr.contains("error"), "{args:?}: no message in {stderr}");
        assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    }
    // An unwritable destination.
    let out = prt()
        .arg("render")
        .arg(scene("default.toml"))
        .args(["--spp", "1", "--quiet", "--out"])
        .arg(dir.path().join("no/such/dir/x.exr"))
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("cannot write"));
    assert!(!out_path.exists());
}
