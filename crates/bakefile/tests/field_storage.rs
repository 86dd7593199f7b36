//! Reflectance fields held in the precision of their file (`FieldValues`): round trips through
//! `write_bake` / `read_bake` in both precisions, zero-copy reading, values checked on their
//! bits, and the streamed writer producing exactly `encode`'s bytes.

mod common;

use common::*;
use half::f16;
use prt_bakefile::*;
use rand::Rng;

const IMAGE: (u32, u32) = (6, 5);

/// A per-pixel file holding only `field` (SPEC.md §3.14: no objects).
fn field_bake(field: ReflectanceField) -> Bake {
    let (width, height) = IMAGE;
    Bake {
        meta: BakeMeta {
            sample_kind: SampleKind::Pixel { width, height },
            rays_per_point: 1,
            bounces: 0,
            seed: 3,
            tool: ToolInfo {
                name: "prt".into(),
                version: "0.1.0".into(),
            },
            settings: serde_json::json!({
                "points": "pixel",
                "pixel_samples": 2,
                "reflectance": {
                    "directions": field.directions, "bounces": 0, "rays": 1, "pixel_samples": 2,
                    "geometry": [{"object": "floor", "geometry_hash": "0x0123456789abcdef"}],
                },
            }),
            decisions: Vec::new(),
            shard: ShardInfo::default(),
            ray_stats: Vec::new(),
            camera: Some(CameraInfo {
                model: CameraInfo::PINHOLE.into(),
                eye: [0.0, 1.0, 0.0],
                target: [0.0, 0.0, 0.0],
                up: [0.0, 0.0, 1.0],
                fov_y_degrees: 30.0,
                width,
                height,
            }),
            pass: None,
        },
        objects: Vec::new(),
        environment: None,
        brdfs: Vec::new(),
        glossy: Vec::new(),
        reflectance: Some(field),
    }
}

const PIXELS: [u32; 4] = [0, 7, 8, 29];

/// Random f16-representable values for `PIXELS` at `directions` (some zeros, -0, subnormals and
/// the largest f16), as f32.
fn f16_values(directions: [u32; 2], seed: u64) -> Vec<f32> {
    let mut r = rng(seed);
    let n = PIXELS.len() * 3 * (directions[0] * directions[1]) as usize;
    let mut v: Vec<f32> = (0..n)
        .map(|_| f16::from_f32(r.random_range(0.0f32..30.0).powi(3)).to_f32())
        .collect();
    v[0] = 0.0;
    v[1] = -0.0;
    v[2] = f16::from_bits(1).to_f32();
    v[3] = 65504.0;
    v
}

fn field(directions: [u32; 2], values: FieldValues) -> ReflectanceField {
    ReflectanceField {
        directions,
        pixels: PIXELS.to_vec(),
        values,
    }
}

fn bits(v: &[f32]) -> Vec<u32> {
    v.iter().map(|x| x.to_bits()).collect()
}

#[test]
fn f16_and_f32_fields_round_trip_bit_exactly_through_files() {
    let dir = tempfile::tempdir().unwrap();
    let directions = [8, 4];
    let exact = f16_values(directions, 1);
    // f32 values that f16 cannot hold: only an f32 file keeps them.
    let mut r = rng(2);
    let fine: Vec<f32> = exact
        .iter()
        .map(|&x| x * (1.0 + r.random_range(1e-6f32..1e-4)))
        .collect();
    let halves: Vec<f16> = exact.iter().map(|&x| f16::from_f32(x)).collect();
    let storages = [
        ("f32 storage", FieldValues::from_f32(&exact)),
        ("f16 storage", FieldValues::from_f16(&halves)),
    ];
    assert_eq!(storages[0].1, storages[1].1, "equality compares values");
    for (name, values) in &storages {
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let path = dir.path().join(format!("{name}-{}.prtb", scalar.name()));
            let bake = field_bake(field(directions, values.clone()));
            write_bake(&path, &bake, scalar).unwrap();
            let back = read_bake(&path).unwrap();
            let f = back.reflectance.as_ref().unwrap();
            assert_eq!(
                f.values.scalar(),
                scalar,
                "{name}: held in the file's precision"
            );
            assert_eq!(f.pixels, PIXELS);
            assert_eq!(
                bits(&f.values.to_f32_vec()),
                bits(&exact),
                "{name} as {scalar:?}"
            );
            assert_eq!(back, bake, "{name} as {scalar:?}");
            // decode (borrowed bytes) and the view agree with read_bake.
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(decode(&bytes).unwrap(), back);
            let view = BakeView::new(&bytes).unwrap();
            assert_eq!(
                view.reflectance_bytes().unwrap(),
                f.values.as_le_bytes(),
                "{name} as {scalar:?}"
            );
        }
    }
    // Values beyond f16: bit-exact in an f32 file, rounded to nearest in an f16 file.
    let bake = field_bake(field(directions, FieldValues::from_f32(&fine)));
    let path = dir.path().join("fine32.prtb");
    write_bake(&path, &bake, ScalarType::F32).unwrap();
    let back = read_bake(&path).unwrap();
    assert_eq!(
        bits(&back.reflectance.unwrap().values.to_f32_vec()),
        bits(&fine)
    );
    let path = dir.path().join("fine16.prtb");
    write_bake(&path, &bake, ScalarType::F16).unwrap();
    let back = read_bake(&path).unwrap();
    let rounded: Vec<f32> = fine.iter().map(|&x| f16::from_f32(x).to_f32()).collect();
    assert_eq!(
        bits(&back.reflectance.unwrap().values.to_f32_vec()),
        bits(&rounded)
    );
    assert_ne!(bits(&rounded), bits(&fine), "the test values need f32");
}

#[test]
fn function_gives_the_same_values_for_both_storages() {
    let directions = [5, 3];
    let exact = f16_values(directions, 4);
    let halves: Vec<f16> = exact.iter().map(|&x| f16::from_f32(x)).collect();
    let a = field(directions, FieldValues::from_f32(&exact));
    let b = field(directions, FieldValues::from_f16(&halves));
    let c = field(
        directions,
        FieldValues::from_f32_as(&exact, ScalarType::F16).unwrap(),
    );
    assert_eq!(b.values.as_le_bytes(), c.values.as_le_bytes());
    let n = 3 * 15;
    let mut out = vec![0.0; n];
    for i in 0..PIXELS.len() {
        let want = bits(&exact[i * n..(i + 1) * n]);
        for f in [&a, &b, &c] {
            let mut scratch = Vec::new();
            assert_eq!(bits(f.function(i, &mut scratch)), want, "pixel {i}");
            f.function_into(i, &mut out);
            assert_eq!(bits(&out), want, "pixel {i}");
        }
    }
    // An f32 field lends its values in place (its bytes are aligned in a fresh vector).
    let mut scratch = Vec::new();
    let f = a.function(1, &mut scratch);
    assert_eq!(
        f.as_ptr().cast::<u8>(),
        a.values.as_le_bytes()[4 * n..].as_ptr()
    );
    assert!(scratch.is_empty());
}

#[test]
fn reading_hands_the_file_buffer_over_to_the_field() {
    // Big enough that the bytes before the values are a small part (no shrink_to_fit).
    let directions = [64, 32];
    let halves: Vec<f16> = f16_values(directions, 5)
        .iter()
        .map(|&x| f16::from_f32(x))
        .collect();
    let bake = field_bake(field(directions, FieldValues::from_f16(&halves)));
    let bytes = encode(&bake, ScalarType::F16).unwrap();
    let ptr = bytes.as_ptr();
    let back = decode_owned(bytes).unwrap();
    let values = &back.reflectance.as_ref().unwrap().values;
    assert_eq!(
        values.as_le_bytes().as_ptr(),
        ptr,
        "the field's values are the file's buffer"
    );
    assert_eq!(back, bake);
}

/// The file of `bake` as `scalar` with value `index` of its field replaced by `raw` (the
/// scalar's little-endian bytes), CRCs fixed.
fn with_value(bake: &Bake, scalar: ScalarType, index: usize, raw: &[u8]) -> Vec<u8> {
    let mut b = encode(bake, scalar).unwrap();
    let (off, _) = find(&b, b"RFLD");
    let n = u64::from_le_bytes(b[off + 16..off + 24].try_into().unwrap()) as usize;
    let at = off + 32 + 4 * n + index * scalar.size();
    b[at..at + raw.len()].copy_from_slice(raw);
    fix_crcs(&mut b);
    b
}

#[test]
fn corrupt_field_values_are_refused_on_their_bits() {
    let dir = tempfile::tempdir().unwrap();
    let directions = [4, 2];
    let bake = field_bake(field(
        directions,
        FieldValues::from_f32(&f16_values(directions, 6)),
    ));
    let k = 37;
    // NaN, ±infinity, negative normal and subnormal values, as the message shows them.
    let cases16 = [0x7e00u16, 0x7c00, 0xfc00, 0xbc00, 0x8001];
    let cases32 = [
        f32::NAN.to_bits(),
        f32::INFINITY.to_bits(),
        (-2.5f32).to_bits(),
        0x8000_0001,
    ];
    let raws = cases16
        .iter()
        .map(|b| {
            let shown = f16::from_bits(*b).to_f32().to_string();
            (ScalarType::F16, b.to_le_bytes().to_vec(), shown)
        })
        .chain(cases32.iter().map(|b| {
            let shown = f32::from_bits(*b).to_string();
            (ScalarType::F32, b.to_le_bytes().to_vec(), shown)
        }));
    for (scalar, raw, shown) in raws {
        let b = with_value(&bake, scalar, k, &raw);
        let want = format!("value {k} is {shown} (finite and non-negative)");
        let e = decode(&b).unwrap_err().to_string();
        assert!(
            e.contains("RFLD") && e.contains(&want),
            "{scalar:?} {raw:?}: {e}"
        );
        let path = dir.path().join("bad.prtb");
        std::fs::write(&path, &b).unwrap();
        let e = read_bake(&path).unwrap_err().to_string();
        assert!(e.contains(&want) && e.contains("bad.prtb"), "{e}");
        assert!(BakeView::new(&b).is_err());
    }
    // -0 is zero, not negative.
    for (scalar, raw) in [
        (ScalarType::F16, 0x8000u16.to_le_bytes().to_vec()),
        (ScalarType::F32, (-0.0f32).to_le_bytes().to_vec()),
    ] {
        let b = with_value(&bake, scalar, k, &raw);
        let back = decode(&b).unwrap();
        assert_eq!(back.reflectance.unwrap().values.get(k), Some(0.0));
    }
}

#[test]
fn the_writer_refuses_bad_values_in_either_storage() {
    let directions = [4, 2];
    let n = PIXELS.len() * 3 * 8;
    let mut halves = vec![f16::from_f32(0.5); n];
    halves[9] = f16::NAN;
    let e = encode(
        &field_bake(field(directions, FieldValues::from_f16(&halves))),
        ScalarType::F16,
    )
    .unwrap_err();
    assert!(
        matches!(&e, BakeFileError::NonFinite { section, index: 9 } if section == "RFLD"),
        "{e}"
    );
    halves[9] = f16::from_f32(-3.0);
    let e = encode(
        &field_bake(field(directions, FieldValues::from_f16(&halves))),
        ScalarType::F32,
    )
    .unwrap_err();
    assert!(
        e.to_string()
            .contains("reflectance value 9 is negative (-3)"),
        "{e}"
    );
    // Beyond f16: refused when written as f16, and when pushed into f16 storage.
    let mut v = vec![1.0f32; n];
    v[11] = 70000.0;
    let bake = field_bake(field(directions, FieldValues::from_f32(&v)));
    encode(&bake, ScalarType::F32).unwrap();
    let e = encode(&bake, ScalarType::F16).unwrap_err();
    assert!(
        matches!(&e, BakeFileError::OutOfF16Range { section, index: 11, .. } if section == "RFLD"),
        "{e}"
    );
    let mut values = FieldValues::from_f32_as(&v[..8], ScalarType::F16).unwrap();
    let e = values.push_f32(&v[8..]).unwrap_err();
    assert!(
        matches!(&e, BakeFileError::OutOfF16Range { section, index: 11, value } if section == "RFLD" && *value == 70000.0),
        "{e}"
    );
    assert_eq!(values.len(), 8, "nothing appended");
}

#[test]
fn write_bake_streams_exactly_the_bytes_of_encode() {
    let dir = tempfile::tempdir().unwrap();
    let directions = [16, 8];
    let v = f16_values(directions, 8);
    let halves: Vec<f16> = v.iter().map(|&x| f16::from_f32(x)).collect();
    let mut bakes = vec![
        ("sample bake", sample_bake()),
        ("random bake", random_bake(&mut rng(9))),
        (
            "f32 field",
            field_bake(field(directions, FieldValues::from_f32(&v))),
        ),
        (
            "f16 field",
            field_bake(field(directions, FieldValues::from_f16(&halves))),
        ),
    ];
    // A field without pixels, and one whose values need f32.
    bakes.push((
        "empty field",
        field_bake(ReflectanceField {
            directions,
            pixels: Vec::new(),
            values: FieldValues::new(ScalarType::F16),
        }),
    ));
    let mut r = rng(10);
    let fine: Vec<f32> = v
        .iter()
        .map(|&x| x * r.random_range(1.0f32..1.001))
        .collect();
    bakes.push((
        "fine f32 field",
        field_bake(field(directions, FieldValues::from_f32(&fine))),
    ));
    let mut beyond = fine.clone();
    beyond[100] = 70000.0;
    bakes.push((
        "f32 field beyond f16",
        field_bake(field(directions, FieldValues::from_f32(&beyond))),
    ));
    for (name, bake) in &bakes {
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let path = dir.path().join(format!("{name}-{}.prtb", scalar.name()));
            let want = match encode(bake, scalar) {
                Ok(b) => b,
                Err(e) => {
                    // Refused alike, and no file left.
                    let w = write_bake(&path, bake, scalar).unwrap_err();
                    assert!(w.to_string().contains(&e.to_string()), "{w} / {e}");
                    assert!(!path.exists());
                    continue;
                }
            };
            write_bake(&path, bake, scalar).unwrap();
            let got = std::fs::read(&path).unwrap();
            assert_eq!(got.len(), want.len(), "{name} as {scalar:?}");
            assert!(got == want, "{name} as {scalar:?}: the bytes differ");
            if scalar == ScalarType::F32 || name.starts_with("f16") {
                assert_eq!(&decode(&got).unwrap(), bake, "{name} as {scalar:?}");
            }
        }
    }
}

/// `settings.reflectance` (SPEC §3.14) is there exactly when the field is, and agrees with it
/// and with the file: each departure is refused by the writer's validation, naming it.
#[test]
fn settings_reflectance_must_describe_the_field() {
    let good = field_bake(field([2, 1], FieldValues::from_f32(&[0.5; 24])));
    assert!(encode(&good, ScalarType::F32).is_ok());
    let refused = |edit: &dyn Fn(&mut Bake), needle: &str| {
        let mut b = good.clone();
        edit(&mut b);
        let e = encode(&b, ScalarType::F32).unwrap_err().to_string();
        assert!(e.contains(needle), "{needle}: {e}");
    };
    refused(
        &|b| {
            b.meta
                .settings
                .as_object_mut()
                .unwrap()
                .remove("reflectance");
        },
        "without settings.reflectance",
    );
    refused(
        &|b| b.meta.settings["reflectance"]["directions"] = serde_json::json!([4, 1]),
        "directions [2, 1]",
    );
    refused(
        &|b| b.meta.settings["reflectance"]["bounces"] = 2.into(),
        "bounces 0",
    );
    refused(
        &|b| b.meta.settings["reflectance"]["geometry"] = serde_json::json!([]),
        "geometry must list",
    );
    refused(
        &|b| {
            b.meta.settings["reflectance"]["geometry"][0]["geometry_hash"] = "0x0123".into();
        },
        "16 lower-case hex digits",
    );
    refused(
        &|b| b.reflectance = None,
        "settings.reflectance in a file without",
    );
}
