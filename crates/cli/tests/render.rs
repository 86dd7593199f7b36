//! `prt render`: success on the default scene, clear errors and non-zero exits on bad input.

use exr::prelude::{read_all_flat_layers_from_file, AttributeValue, FlatSamples, Text};
use std::path::{Path, PathBuf};
use std::process::Command;

fn prt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_prt"))
}

/// `prt render` of the default scene with `args`, writing `out`.
fn run_default(args: &[&str], out: &Path) -> std::process::Output {
    prt()
        .arg("render")
        .arg(scene("default.toml"))
        .args(args)
        .arg("--out")
        .arg(out)
        .output()
        .unwrap()
}

/// `prt render` of the default scene with `args`, writing `out`; it must succeed.
fn render_default(args: &[&str], out: &Path) {
    let o = run_default(args, out);
    assert!(
        o.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
}

/// `prt render` of the default scene with `args`, writing `out`: it must fail without a
/// panic. Returns its error output.
fn render_default_fails(args: &[&str], out: &Path) -> String {
    let o = run_default(args, out);
    let stderr = String::from_utf8_lossy(&o.stderr).into_owned();
    assert!(!o.status.success(), "{args:?} should fail");
    assert!(!stderr.contains("panicked"), "{args:?}: {stderr}");
    stderr
}

/// The EXR attribute `key` of the first layer of `path`, and its `R` channel.
fn attribute_and_red(path: &Path, key: &str) -> (Option<AttributeValue>, Vec<f32>) {
    let image = read_all_flat_layers_from_file(path).unwrap();
    let layer = &image.layer_data[0];
    let red = layer
        .channel_data
        .list
        .iter()
        .find(|c| c.name.to_string() == "R")
        .expect("an R channel");
    let FlatSamples::F32(red) = &red.sample_data else {
        panic!("R is not f32");
    };
    (
        layer.attributes.other.get(&Text::from(key)).cloned(),
        red.clone(),
    )
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
    let png = png_path.display().to_string();
    render_default(
        &[
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
            "--png",
            &png,
        ],
        &exr_path,
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

    // AO and unshadowed modes run too.
    render_default(
        &["--spp", "1", "--quiet", "--ao", "--ao-distance=0.5"],
        &exr_path,
    );
    render_default(
        &["--spp", "1", "--quiet", "--unshadowed", "--bounces=-1"],
        &exr_path,
    );
}

/// `--sampler single`: an image without a noise estimate (NaN in the EXR, where the replicas'
/// image has a finite one), not the replicas' image, and the sampler named in the header.
#[test]
fn test03_single_sequence_sampler() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--spp", "2", "--bounces", "0", "--seed", "7", "--quiet"];
    let (replicas, single) = (dir.path().join("r.exr"), dir.path().join("s.exr"));
    render_default(&args, &replicas);
    render_default(&[&args[..], &["--sampler", "single"]].concat(), &single);
    let (noise_r, red_r) = attribute_and_red(&replicas, "prt.noise_estimate");
    let (noise_s, red_s) = attribute_and_red(&single, "prt.noise_estimate");
    for (path, name) in [(&replicas, "replicas"), (&single, "single")] {
        assert_eq!(
            attribute_and_red(path, "prt.sampler").0,
            Some(AttributeValue::Text(Text::from(name)))
        );
    }
    assert!(
        matches!(noise_r, Some(AttributeValue::F64(x)) if x.is_finite()),
        "{noise_r:?}"
    );
    assert!(
        matches!(noise_s, Some(AttributeValue::F64(x)) if x.is_nan()),
        "{noise_s:?}"
    );
    assert_ne!(red_r, red_s);
}

#[test]
fn test02_bad_input_fails_with_a_message() {
    let dir = tempfile::tempdir().unwrap();
    let out_path = dir.path().join("x.exr");
    // Options on the default scene that must be refused; the last: the single sequence has
    // no noise estimate to stop on.
    let bad_options: [&[&str]; 8] = [
        &["--spp", "0"],
        &["--bounces", "-2"],
        &["--threads", "0"],
        &["--ao", "--unshadowed"],
        &["--spp", "many"],
        &["--sampler", "stratified"],
        &["--sampler", "single", "--target-psnr-ldr", "40"],
        &["--sampler", "single", "--target-noise", "0.05"],
    ];
    let default = scene("default.toml").display().to_string();
    let cases: Vec<Vec<String>> =
        std::iter::once(vec![dir.path().join("missing.toml").display().to_string()])
            .chain(bad_options.iter().map(|opts| {
                std::iter::once(default.clone())
                    .chain(opts.iter().map(|o| (*o).to_string()))
                    .collect()
            }))
            .collect();
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
    let stderr = render_default_fails(
        &["--spp", "1", "--quiet"],
        &dir.path().join("no/such/dir/x.exr"),
    );
    assert!(stderr.contains("cannot write"));
    assert!(!out_path.exists());
}

/// `--env-sampling`: the default is the per-normal MIS-compensated density, `compensated`
/// the one-table one and `luminance` the plain one; the header names it, and the three give
/// different images at the same seed (the same image in expectation: `prt-tracer`'s render
/// test09).
#[test]
fn test04_env_sampling_flag() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--spp", "2", "--bounces", "0", "--seed", "7", "--quiet"];
    let mut reds = Vec::new();
    for (flag, name) in [
        (None, "per-normal"),
        (Some("compensated"), "compensated"),
        (Some("luminance"), "luminance"),
    ] {
        let out = dir.path().join(format!("{name}.exr"));
        let extra: Vec<&str> = flag.map_or(vec![], |f| vec!["--env-sampling", f]);
        render_default(&[&args[..], &extra].concat(), &out);
        let (attribute, red) = attribute_and_red(&out, "prt.env_sampling");
        assert_eq!(attribute, Some(AttributeValue::Text(Text::from(name))));
        assert!(
            reds.iter().all(|r| *r != red),
            "{name}: the same image as another"
        );
        reds.push(red);
    }
}

/// `--split-lobes` and `--split-depth`: the header names them; the default (`delta`) and
/// `mirror` split only mirror materials, so on the default scene (a Lambert bunny on a Phong
/// floor) they are `none`'s image bit for bit, while `all` splits the floor's two lobes and
/// gives another image (the same in expectation: `prt-tracer`'s render test10). A bad choice
/// is an error.
#[test]
fn test05_split_lobes_flags() {
    let dir = tempfile::tempdir().unwrap();
    let args = ["--spp", "2", "--bounces", "1", "--seed", "7", "--quiet"];
    let mut reds = Vec::new();
    for (extra, name, depth) in [
        (&[][..], "delta", 2),
        (&["--split-lobes", "none"][..], "none", 2),
        (&["--split-lobes", "mirror"][..], "mirror", 2),
        (
            &["--split-lobes", "all", "--split-depth", "1"][..],
            "all",
            1,
        ),
    ] {
        let out = dir.path().join(format!("{name}.exr"));
        render_default(&[&args[..], extra].concat(), &out);
        let (attribute, red) = attribute_and_red(&out, "prt.split_lobes");
        assert_eq!(attribute, Some(AttributeValue::Text(Text::from(name))));
        let (attribute, _) = attribute_and_red(&out, "prt.split_depth");
        assert_eq!(attribute, Some(AttributeValue::I32(depth)));
        reds.push(red);
    }
    assert_eq!(
        reds[0], reds[1],
        "no mirror in the default scene: nothing splits"
    );
    assert_eq!(reds[2], reds[1], "--split-lobes mirror: nothing splits");
    assert_ne!(reds[0], reds[3], "--split-lobes all splits the Phong floor");
    let stderr = render_default_fails(
        &["--split-lobes", "glossy", "--quiet"],
        &dir.path().join("bad.exr"),
    );
    assert!(stderr.contains("--split-lobes"));
}
