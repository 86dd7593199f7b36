//! Environment image loading: the bundled real maps and synthetic EXR/HDR files with every
//! kind of bad texel and bad file.

use exr::prelude::*;
use prt_scene::{load_env_image, load_environment, Mapping, SceneError};
use std::path::{Path, PathBuf};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

/// A 4×3 test pattern whose texel (c, r) is (c, r, c + r) / 8 + 0.125: distinct, exact in f32.
fn pattern(c: usize, r: usize) -> (f32, f32, f32) {
    (
        c as f32 / 8.0 + 0.125,
        r as f32 / 8.0 + 0.125,
        (c + r) as f32 / 8.0 + 0.125,
    )
}

fn write_exr(path: &Path, w: usize, h: usize, f: impl Sync + Fn(usize, usize) -> (f32, f32, f32)) {
    write_rgb_file(path, w, h, f).unwrap();
}

#[test]
fn test01_real_maps_load_with_one_negative_clamp_warning() {
    for name in ["courtyard", "studio", "sunrise"] {
        let path = scenes_dir().join(format!("maps/{name}.exr"));
        let loaded = load_env_image(&path).unwrap();
        assert_eq!(
            (loaded.image.width, loaded.image.height),
            (1024, 512),
            "{name}"
        );
        assert_eq!(loaded.image.texels.len(), 1024 * 512);
        assert!(loaded
            .image
            .texels
            .iter()
            .flatten()
            .all(|v| v.is_finite() && *v >= 0.0));
        // README of the assets: DWAB decoding leaves small negatives in every one of these.
        assert_eq!(loaded.warnings.len(), 1, "{name}: {:?}", loaded.warnings);
        assert!(loaded.warnings[0].contains("clamped") && loaded.warnings[0].contains(name));
    }
}

#[test]
fn test02_exr_values_round_trip_exactly() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.exr");
    write_exr(&path, 4, 3, pattern);
    let loaded = load_env_image(&path).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    assert_eq!((loaded.image.width, loaded.image.height), (4, 3));
    for r in 0..3 {
        for c in 0..4 {
            let (a, b, d) = pattern(c, r);
            assert_eq!(
                loaded.image.texel(c, r),
                [a, b, d],
                "texel ({c}, {r}): row-major, row 0 on top"
            );
        }
    }
}

#[test]
fn test03_nan_and_inf_name_the_first_bad_texel_and_channel() {
    let dir = tempfile::tempdir().unwrap();
    for (bad, channel) in [
        (f32::NAN, 'G'),
        (f32::INFINITY, 'B'),
        (f32::NEG_INFINITY, 'R'),
    ] {
        let path = dir.path().join("bad.exr");
        // Bad values at (2, 1) and, later in row-major order, (0, 2): the first is reported.
        write_exr(&path, 4, 3, move |c, r| {
            let (x, y, z) = pattern(c, r);
            let put = |ch: char| {
                if (c, r) == (2, 1) || (c, r) == (0, 2) {
                    ch == channel
                } else {
                    false
                }
            };
            (
                if put('R') { bad } else { x },
                if put('G') { bad } else { y },
                if put('B') { bad } else { z },
            )
        });
        match load_env_image(&path) {
            Err(e @ SceneError::NonFiniteTexel { col: 2, row: 1, .. }) => {
                let msg = e.to_string();
                assert!(
                    msg.contains("bad.exr") && msg.contains(&format!("channel {channel}")),
                    "{msg}"
                );
            }
            other => panic!("expected NonFiniteTexel at (2, 1), got {other:?}"),
        }
    }
}

#[test]
fn test04_negative_texels_are_clamped_and_counted_once() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("neg.exr");
    // Texel (1, 0) has two negative channels, texel (3, 2) one: 3 values in 2 texels.
    write_exr(&path, 4, 3, |c, r| match (c, r) {
        (1, 0) => (-0.5, -0.25, 1.0),
        (3, 2) => (2.0, 3.0, -1e-3),
        _ => pattern(c, r),
    });
    let loaded = load_env_image(&path).unwrap();
    assert_eq!(loaded.image.texel(1, 0), [0.0, 0.0, 1.0]);
    assert_eq!(loaded.image.texel(3, 2), [2.0, 3.0, 0.0]);
    assert_eq!(loaded.warnings.len(), 1);
    assert!(
        loaded.warnings[0].contains("clamped 3 negative values in 2 of 12 texels"),
        "{:?}",
        loaded.warnings
    );
}

fn write_exr_with_chromaticities(path: &Path, c: [[f32; 2]; 4]) {
    let channels = SpecificChannels::rgb(|_p: Vec2<usize>| (0.5f32, 0.5f32, 0.5f32));
    let mut image = Image::from_channels((2, 2), channels);
    image.attributes.chromaticities = Some(exr::meta::attribute::Chromaticities {
        red: Vec2(c[0][0], c[0][1]),
        green: Vec2(c[1][0], c[1][1]),
        blue: Vec2(c[2][0], c[2][1]),
        white: Vec2(c[3][0], c[3][1]),
    });
    image.write().to_file(path).unwrap();
}

#[test]
fn test05_non_rec709_chromaticities_warn() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("chroma.exr");
    write_exr_with_chromaticities(&path, prt_scene::REC709_CHROMATICITIES);
    assert!(load_env_image(&path).unwrap().warnings.is_empty());
    // ACES AP0 primaries: clearly not Rec.709.
    write_exr_with_chromaticities(
        &path,
        [
            [0.7347, 0.2653],
            [0.0, 1.0],
            [0.0001, -0.077],
            [0.32168, 0.33767],
        ],
    );
    let w = load_env_image(&path).unwrap().warnings;
    assert_eq!(w.len(), 1);
    assert!(
        w[0].contains("chroma.exr") && w[0].contains("not Rec.709"),
        "{w:?}"
    );
}

#[test]
fn test06_radiance_hdr_reads_within_rgbe_precision() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.hdr");
    let mut img = image::Rgb32FImage::new(4, 3);
    for (c, r, p) in img.enumerate_pixels_mut() {
        let (a, b, d) = pattern(c as usize, r as usize);
        *p = image::Rgb([a * 100.0, b, d]);
    }
    image::DynamicImage::ImageRgb32F(img).save(&path).unwrap();
    let loaded = load_env_image(&path).unwrap();
    assert_eq!((loaded.image.width, loaded.image.height), (4, 3));
    for r in 0..3 {
        for c in 0..4 {
            let (a, b, d) = pattern(c, r);
            let want = [a * 100.0, b, d];
            let got = loaded.image.texel(c, r);
            // RGBE keeps 8 mantissa bits for the largest channel of a texel: the absolute error
            // of every channel is below max channel · 2^-7 (rounding or truncation).
            let tol = want.iter().cloned().fold(0.0f32, f32::max) / 128.0;
            for k in 0..3 {
                assert!(
                    (got[k] - want[k]).abs() <= tol,
                    "({c}, {r}) ch {k}: {got:?} vs {want:?}"
                );
            }
        }
    }
}

#[test]
fn test07_bad_files_give_clear_errors() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("missing.exr");
    assert!(matches!(
        load_env_image(&missing),
        Err(SceneError::Io { .. })
    ));

    let empty = dir.path().join("empty.exr");
    std::fs::write(&empty, b"").unwrap();
    let msg = load_env_image(&empty).unwrap_err().to_string();
    assert!(msg.contains("empty.exr") && msg.contains("empty"), "{msg}");

    let text = dir.path().join("notes.hdr");
    std::fs::write(&text, b"hello, not an image").unwrap();
    let msg = load_env_image(&text).unwrap_err().to_string();
    assert!(
        msg.contains("notes.hdr") && msg.contains("not an OpenEXR or Radiance HDR"),
        "{msg}"
    );

    let real = std::fs::read(scenes_dir().join("maps/courtyard.exr")).unwrap();
    for keep in [3, 100, real.len() / 2, real.len() - 10] {
        let cut = dir.path().join("truncated.exr");
        std::fs::write(&cut, &real[..keep]).unwrap();
        match load_env_image(&cut) {
            Err(e @ SceneError::Format { .. }) => {
                assert!(e.to_string().contains("truncated.exr"), "{e}")
            }
            other => panic!("{keep} bytes: expected a format error, got {other:?}"),
        }
    }

    let zero = dir.path().join("zero.hdr");
    std::fs::write(&zero, b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 0 +X 0\n").unwrap();
    let msg = load_env_image(&zero).unwrap_err().to_string();
    assert!(msg.contains("zero.hdr"), "{msg}");
}

#[test]
fn test08_load_environment_applies_scale_and_checks_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("p.exr");
    write_exr(&path, 4, 3, pattern);
    let (env, warnings) = load_environment(&path, Mapping::LatLong, 30.0, 2.5).unwrap();
    assert!(warnings.is_empty());
    assert_eq!(env.rotation_y_deg, 30.0);
    let (a, b, d) = pattern(3, 2);
    // Products of these dyadic values by 2.5 are exact in f32.
    assert_eq!(env.image.texel(3, 2), [a * 2.5, b * 2.5, d * 2.5]);
    assert!(load_environment(&path, Mapping::LatLong, 0.0, -1.0).is_err());
    assert!(load_environment(&path, Mapping::LatLong, f64::NAN, 1.0).is_err());
    // A non-square angular probe is accepted with a warning.
    let (_, w) = load_environment(&path, Mapping::Angular, 0.0, 1.0).unwrap();
    assert_eq!(w.len(), 1, "{w:?}");
}

#[test]
fn test09_hdr_header_with_huge_size_is_refused_before_allocating() {
    // 10⁶ × 10⁶ texels would be a 12 TB allocation: the process used to abort.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("huge.hdr");
    std::fs::write(
        &path,
        b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1000000 +X 1000000\n\x80\x80\x80\x81",
    )
    .unwrap();
    let msg = load_env_image(&path).unwrap_err().to_string();
    assert!(
        msg.contains("huge.hdr") && msg.contains("1000000×1000000"),
        "{msg}"
    );
}
