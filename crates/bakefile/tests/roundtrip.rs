//! Round trips: f32 exact, f16 within its rounding bound, random bakes, zero-copy views.

mod common;

use common::*;
use prt_bakefile::*;

#[test]
fn test01_f32_round_trip_is_exact_and_canonical() {
    let bake = sample_bake();
    let bytes = encode(&bake, ScalarType::F32).unwrap();
    let back = decode(&bytes).unwrap();
    assert_eq!(back, bake);
    // Canonical: re-encoding what was read gives the same bytes; encoding is deterministic.
    assert_eq!(encode(&back, ScalarType::F32).unwrap(), bytes);
    assert_eq!(encode(&bake, ScalarType::F32).unwrap(), bytes);
    assert_eq!(&bytes[..8], b"PRTBAKE\0");
    assert_eq!(
        bytes.len() as u64,
        u64::from_le_bytes(bytes[24..32].try_into().unwrap())
    );
}

/// Round-to-nearest binary16: relative error at most 2^-11 (half an ulp, 10 stored mantissa
/// bits) in the normal range |x| ≥ 2^-14; absolute error at most 2^-25 (half the subnormal
/// spacing 2^-24) below it.
fn f16_bound(x: f32) -> f32 {
    (x.abs() * 2f32.powi(-11)).max(2f32.powi(-25))
}

#[test]
fn test02_f16_round_trip_within_rounding_bound() {
    let mut bake = sample_bake();
    // Include subnormal-range, tiny and near-maximum values.
    bake.objects[0].blocks[0].data[..6]
        .copy_from_slice(&[1e-7, -3e-6, 6.1e-5, 65504.0, -65500.0, 0.0]);
    let bytes = encode(&bake, ScalarType::F16).unwrap();
    let back = decode(&bytes).unwrap();
    let mut worst = 0.0f32;
    let mut any_inexact = false;
    for (o, ob) in bake.objects.iter().zip(&back.objects) {
        for (b, bb) in o.blocks.iter().zip(&ob.blocks) {
            for (&x, &y) in b.data.iter().zip(&bb.data) {
                let err = (x - y).abs();
                assert!(
                    err <= f16_bound(x),
                    "{x} -> {y}: error {err} > {}",
                    f16_bound(x)
                );
                worst = worst.max(err / f16_bound(x));
                any_inexact |= x != y;
            }
        }
    }
    assert!(any_inexact, "f16 storage should round something");
    assert!(
        worst > 0.5,
        "bound not approached (ratio {worst}): test would not catch a looser writer"
    );
    // Everything else is untouched, and f16 files are canonical too.
    assert_eq!(back.meta, bake.meta);
    assert_eq!(back.environment, bake.environment);
    assert_eq!(encode(&back, ScalarType::F16).unwrap(), bytes);
    // f16 coefficients take half the bytes of f32 ones: the files differ by 2 bytes per
    // transfer scalar, up to 8 bytes of section alignment per block.
    let f32_len = encode(&bake, ScalarType::F32).unwrap().len();
    let blocks: Vec<&TransferBlock> = bake.objects.iter().flat_map(|o| &o.blocks).collect();
    let scalars: usize = blocks.iter().map(|b| b.data.len()).sum();
    let saved = f32_len - bytes.len();
    assert!(
        saved + 8 * blocks.len() >= 2 * scalars && saved <= 2 * scalars + 8 * blocks.len(),
        "{} vs {f32_len} bytes for {scalars} scalars",
        bytes.len()
    );
}

#[test]
fn test03_f16_overflow_is_an_error_not_infinity() {
    let mut bake = sample_bake();
    bake.objects[1].blocks[2].data[5] = 65520.0; // rounds to +inf in binary16
    match encode(&bake, ScalarType::F16) {
        Err(BakeFileError::OutOfF16Range { index, value, .. }) => {
            assert_eq!(index, 5);
            assert_eq!(value, 65520.0);
        }
        other => panic!("expected OutOfF16Range, got {other:?}"),
    }
    // 65519 still rounds to 65504 (the largest binary16): accepted.
    bake.objects[1].blocks[2].data[5] = 65519.0;
    let back = decode(&encode(&bake, ScalarType::F16).unwrap()).unwrap();
    assert_eq!(back.objects[1].blocks[2].data[5], 65504.0);
    // f32 storage takes the large value as is.
    bake.objects[1].blocks[2].data[5] = 1e30;
    assert!(encode(&bake, ScalarType::F32).is_ok());
}

#[test]
fn test04_random_bakes_round_trip() {
    let mut r = rng(2024);
    for case in 0..300 {
        let bake = random_bake(&mut r);
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let bytes = encode(&bake, scalar).unwrap_or_else(|e| panic!("case {case}: {e}"));
            let back = decode(&bytes).unwrap_or_else(|e| panic!("case {case}: {e}"));
            assert_eq!(
                encode(&back, scalar).unwrap(),
                bytes,
                "case {case}: not canonical"
            );
            assert_eq!(back.meta, bake.meta, "case {case}");
            assert_eq!(back.environment, bake.environment, "case {case}");
            assert_eq!(back.brdfs, bake.brdfs, "case {case}");
            assert_eq!(back.glossy, bake.glossy, "case {case}");
            if scalar == ScalarType::F32 {
                assert_eq!(back, bake, "case {case}");
            } else {
                for (o, ob) in bake.objects.iter().zip(&back.objects) {
                    for (b, bb) in o.blocks.iter().zip(&ob.blocks) {
                        assert_eq!(b.kind, bb.kind);
                        for (&x, &y) in b.data.iter().zip(&bb.data) {
                            assert!((x - y).abs() <= f16_bound(x), "case {case}: {x} -> {y}");
                        }
                    }
                }
            }
            // Every payload starts on a 64-byte boundary.
            for (tag, off, _, _) in sections(&bytes) {
                assert_eq!(
                    off % 64,
                    0,
                    "case {case}: {:?}",
                    String::from_utf8_lossy(&tag)
                );
            }
        }
    }
}

#[test]
fn test05_zero_copy_view_agrees_with_decode() {
    let bake = sample_bake();
    for scalar in [ScalarType::F32, ScalarType::F16] {
        let bytes = encode(&bake, scalar).unwrap();
        // Copy into u64-aligned storage so the zero-copy path is guaranteed to be taken.
        let mut storage = vec![0u64; bytes.len().div_ceil(8) + 1];
        let aligned: &mut [u8] = &mut bytemuck::cast_slice_mut(&mut storage)[..bytes.len()];
        aligned.copy_from_slice(&bytes);
        let aligned: &[u8] = aligned;
        let view = BakeView::new(aligned).unwrap();
        let decoded = decode(&bytes).unwrap();
        assert_eq!(view.scalar_type(), scalar);
        assert_eq!(view.version(), (1, 3));
        assert_eq!(view.meta(), &decoded.meta);
        assert_eq!(view.to_bake().unwrap(), decoded);
        for (oi, o) in decoded.objects.iter().enumerate() {
            assert_eq!(view.objects()[oi].name, o.name);
            for (bi, b) in o.blocks.iter().enumerate() {
                let c = view.coefficients(oi, bi).unwrap();
                assert!(c.is_borrowed(), "aligned data must not be copied");
                assert_eq!(c.to_f32_vec(), b.data);
                // The borrowed slice points into the file bytes.
                let raw = view.block_bytes(oi, bi).unwrap();
                assert!(aligned.as_ptr_range().contains(&raw.as_ptr()) || raw.is_empty());
            }
        }
        assert!(view.coefficients(99, 0).is_none());
        assert!(view.coefficients(0, 99).is_none());

        // Unaligned bytes: the same values, through a copy.
        let mut shifted = vec![0u8; bytes.len() + 1];
        shifted[1..].copy_from_slice(&bytes);
        let view = BakeView::new(&shifted[1..]).unwrap();
        let c = view.coefficients(0, 0).unwrap();
        assert!(!c.is_borrowed(), "misaligned data cannot be borrowed");
        assert_eq!(c.to_f32_vec(), decoded.objects[0].blocks[0].data);
    }
}

#[test]
fn test06_summary_counts_and_serialises() {
    let mut bake = sample_bake();
    bake.objects[0].blocks[1].data[3] = f32::NAN;
    bake.objects[0].blocks[1].data[4] = f32::INFINITY;
    let s = summary(&bake);
    let b = &s.objects[0].blocks[1];
    assert_eq!((b.nan_count, b.inf_count), (1, 1));
    assert_eq!(b.kind, "shadowed-diffuse");
    let finite = bake.objects[0].blocks[1]
        .data
        .iter()
        .copied()
        .filter(|v| v.is_finite());
    assert_eq!(b.max, finite.clone().reduce(f32::max));
    assert_eq!(b.min, finite.reduce(f32::min));
    assert!(s.file.is_none());

    let bake = sample_bake();
    let bytes = encode(&bake, ScalarType::F32).unwrap();
    let view = BakeView::new(&bytes).unwrap();
    let fs = view.summary();
    assert_eq!(fs.objects, summary(&bake).objects);
    let file = fs.file.as_ref().unwrap();
    assert_eq!(file.file_size, bytes.len() as u64);
    assert_eq!(file.sections.len(), 8 + 8 + 2);
    let json = serde_json::to_value(&fs).unwrap();
    assert_eq!(json["objects"][1]["order"], 3);
    assert_eq!(
        json["objects"][1]["blocks"][3]["kind"],
        "interreflected-diffuse"
    );
    let text = fs.to_string();
    assert!(text.contains("object \"bunny\""), "{text}");
    assert!(
        text.contains("interreflected-diffuse (2 bounces)"),
        "{text}"
    );
}

#[test]
fn test07_metadata_json_is_self_describing() {
    let bytes = encode(&sample_bake(), ScalarType::F16).unwrap();
    let (off, len) = find(&bytes, b"META");
    let meta: serde_json::Value = serde_json::from_slice(&bytes[off..off + len]).unwrap();
    assert_eq!(meta["format"], "prt-bake");
    assert_eq!(meta["format_version"], serde_json::json!([1, 3]));
    assert_eq!(meta["sh"]["basis"], "real-orthonormal");
    assert_eq!(meta["sh"]["phase"], "condon-shortley");
    assert_eq!(meta["sh"]["index_order"], "l(l+1)+m");
    assert_eq!(meta["colour_space"], "linear-rec709");
    assert_eq!(meta["scalar_type"], "f16");
    // 1.1: the u64 seed as a decimal string (a double cannot hold it: 0x0123456789abcdef
    // as f64 is 81985529216486896).
    assert_eq!(meta["seed"], "81985529216486895");
    assert_eq!(meta["camera"], serde_json::Value::Null);
    assert_eq!(meta["objects"][0]["blocks"][0]["section"], 8);
    // The meshes follow the 8 XFER sections; no coverage in a per-vertex bake.
    assert_eq!(
        meta["objects"][1]["mesh"],
        serde_json::json!({"section": 17, "vertices": 11, "triangles": meta["objects"][1]["mesh"]["triangles"]})
    );
    assert_eq!(meta["objects"][1]["coverage"], serde_json::Value::Null);
    assert_eq!(meta["settings"]["weights"][2], 0.30000000000000004);
    assert_eq!(
        meta["decisions"][0]["reason"],
        "relative error 0.8% < 1% target at order 5"
    );
}

#[test]
fn test08_geometry_hash_worked_example() {
    // The example of SPEC.md, "Geometry hash".
    let h = geometry_hash(
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]],
        &[[0, 1, 2]],
    );
    assert_eq!(h, 0x8810_ae12_e1b0_c5a6);
    assert_eq!(geometry_hash(&[], &[]), 0xcbf2_9ce4_8422_2325);
}

/// Files written by the 1.0 writer (commit 9e5754a, `sample_bake()` of that commit with
/// `settings.albedo_in_transfer = false`, in `tests/data/`) still read: 56-byte OBJT records,
/// a numeric JSON seed, no meshes, coverage or camera.
#[test]
fn test09_format_1_0_files_still_read() {
    for (name, scalar) in [
        ("v1_0_sample_f32.prtb", ScalarType::F32),
        ("v1_0_sample_f16.prtb", ScalarType::F16),
    ] {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("tests/data")
            .join(name);
        let bytes = std::fs::read(&path).unwrap();
        let view = BakeView::new(&bytes).unwrap();
        assert_eq!(view.version(), (1, 0), "{name}");
        assert_eq!(view.scalar_type(), scalar);
        let old = view.to_bake().unwrap();
        let new = sample_bake();
        assert_eq!(old.meta.seed, new.meta.seed);
        assert_eq!(old.meta.camera, None);
        assert_eq!(old.environment, new.environment);
        assert_eq!(old.brdfs, new.brdfs);
        assert_eq!(old.glossy, new.glossy);
        for (o, n) in old.objects.iter().zip(&new.objects) {
            assert_eq!((o.mesh.as_ref(), o.coverage.as_ref()), (None, None));
            assert_eq!(
                (&o.name, o.point_count, o.order),
                (&n.name, n.point_count, n.order)
            );
            if scalar == ScalarType::F32 {
                // The same generator made the coefficients (its stream also drew the 1.0
                // geometry hash, so the values differ; their count and kinds agree).
                assert_eq!(o.blocks.len(), n.blocks.len());
            }
        }
        // Re-encoding writes 1.1 and reads back to the same bake.
        let again = decode(&encode(&old, scalar).unwrap()).unwrap();
        assert_eq!(again, old);
    }
}

/// The JSON `seed`: a canonical decimal string in 1.1; a number is still read (1.0); a
/// string with a sign, leading zero or beyond u64 is refused; and it must equal BINF's.
#[test]
fn test10_seed_forms() {
    let bytes = encode(&sample_bake(), ScalarType::F32).unwrap();
    // Replaces the seed in place, keeping META's length (JSON whitespace absorbs the
    // difference), so that no section moves.
    let with_seed = |text: &str| {
        let mut b = bytes.clone();
        let (off, len) = find(&b, b"META");
        let meta = std::str::from_utf8(&b[off..off + len]).unwrap();
        let mut new = meta.replace(
            "\"seed\": \"81985529216486895\"",
            &format!("\"seed\": {text}"),
        );
        assert!(new.contains(&format!("\"seed\": {text}")));
        while new.len() > len {
            new = new.replacen("\n  ", "\n ", 1);
        }
        while new.len() < len {
            new.push(' ');
        }
        b[off..off + len].copy_from_slice(new.as_bytes());
        fix_crcs(&mut b);
        b
    };
    for (text, ok) in [
        ("\"81985529216486895\"", true),
        ("81985529216486895", true),
        ("\"081985529216486895\"", false),
        ("\"+81985529216486895\"", false),
        ("\"81985529216486896\"", false),
        ("\"99999999999999999999\"", false),
        ("81985529216486896", false),
    ] {
        let b = with_seed(text);
        let r = decode(&b);
        assert_eq!(r.is_ok(), ok, "seed {text}: {r:?}");
        if let Err(e) = r {
            assert!(e.to_string().contains("seed"), "{e}");
        }
    }
}

/// SPEC §3.9: `exponent` is null exactly for the clamped cosine; a Phong lobe of exponent 0
/// (the uniform hemispherical lobe) is a number, and reads back (it was refused once).
#[test]
fn test11_brdf_exponent_null_and_zero() {
    let mut bake = sample_bake();
    bake.brdfs[1].lobe = BrdfLobe::Phong { exponent: 0.0 };
    let bytes = encode(&bake, ScalarType::F32).unwrap();
    assert_eq!(decode(&bytes).unwrap(), bake);
    let (off, len) = find(&bytes, b"META");
    let meta: serde_json::Value = serde_json::from_slice(&bytes[off..off + len]).unwrap();
    assert_eq!(meta["brdfs"][0]["exponent"], serde_json::Value::Null);
    assert_eq!(meta["brdfs"][1]["exponent"], 0.0);
    assert!(BakeView::new(&bytes)
        .unwrap()
        .summary()
        .to_string()
        .contains("phong (exponent 0)"));
}

/// A block stored as clustered PCA (SPEC §3.13): it survives encoding, decodes to its f32
/// reconstruction, its BLKT record says scalar type 3, and a wrong cluster index, a data
/// array that is not the reconstruction, or a merge of compressed shards are refused.
#[test]
fn test12_cpca_blocks() {
    let mut bake = sample_bake();
    let o = &mut bake.objects[1];
    let d = o.scalars_per_point() as usize;
    let points = o.points_in_file as usize;
    let (k, m) = (2usize, 3usize);
    let centres: Vec<f32> = (0..k * (m + 1) * d)
        .map(|i| ((i * 7 % 13) as f32 - 6.0) / 8.0)
        .collect();
    let cpca = Cpca {
        clusters: k as u32,
        components: m as u32,
        dimension: d as u32,
        rel_error: 0.0125,
        centres,
        cluster_of: (0..points).map(|p| (p % k) as u32).collect(),
        weights: (0..points * m)
            .map(|i| (i % 5) as f32 * 0.25 - 0.5)
            .collect(),
    };
    o.blocks[1].data = cpca.reconstruct();
    o.blocks[1].cpca = Some(cpca.clone());
    for scalar in [ScalarType::F32, ScalarType::F16] {
        let bytes = encode(&bake, scalar).unwrap();
        let back = decode(&bytes).unwrap();
        assert_eq!(back.objects[1].blocks[1].cpca.as_ref(), Some(&cpca));
        assert_eq!(back.objects[1].blocks[1].data, cpca.reconstruct());
        let view = BakeView::new(&bytes).unwrap();
        assert_eq!(view.cpca(1, 1), Some(&cpca));
        assert_eq!(
            view.coefficients(1, 1).unwrap().to_f32_vec(),
            cpca.reconstruct()
        );
        let secs = sections(&bytes);
        assert_eq!(secs.iter().filter(|s| &s.0 == b"CPCA").count(), 1);
        if scalar == ScalarType::F32 {
            assert_eq!(back, bake);
        }
    }
    // The reconstruction formula by hand for one point and one scalar.
    let p = 3;
    let c = cpca.cluster_of[p] as usize;
    let mut v = cpca.row(c, 0)[5];
    for j in 0..m {
        v += cpca.weights[p * m + j] * cpca.row(c, 1 + j)[5];
    }
    assert_eq!(cpca.reconstruct()[p * d + 5], v);

    // Refusals.
    let mut bad = bake.clone();
    bad.objects[1].blocks[1].data[0] += 1.0;
    assert!(encode(&bad, ScalarType::F32)
        .unwrap_err()
        .to_string()
        .contains("not the reconstruction"));
    let bytes = encode(&bake, ScalarType::F32).unwrap();
    let (off, len) = find(&bytes, b"CPCA");
    let ids = off + 32 + 4 * k * (m + 1) * d;
    let mut b = bytes.clone();
    b[ids..ids + 4].copy_from_slice(&7u32.to_le_bytes());
    fix_crcs(&mut b);
    assert!(decode(&b)
        .unwrap_err()
        .to_string()
        .contains("is in cluster 7 of 2"));
    let mut b = bytes.clone();
    b[off + 12..off + 16].copy_from_slice(&(d as u32 + 1).to_le_bytes());
    fix_crcs(&mut b);
    assert!(decode(&b).is_err());
    assert!(len > 32);
    assert!(merge(&[bake.clone()])
        .unwrap_err()
        .to_string()
        .contains("merge the shards first, then compress"));
}
