//! Every typed error, triggered by a constructed corrupt file. Where a corruption must get
//! past the checksums to reach a deeper check, the CRCs are recomputed with the test's own
//! implementation of SPEC.md (`common::fix_crcs`).

mod common;

use common::*;
use prt_bakefile::*;

fn valid(scalar: ScalarType) -> Vec<u8> {
    encode(&sample_bake(), scalar).unwrap()
}

fn err(bytes: &[u8]) -> BakeFileError {
    let e = decode(bytes).expect_err("corrupt file accepted");
    // The view must refuse exactly as decode does.
    let v = BakeView::new(bytes).expect_err("view accepted a corrupt file");
    assert_eq!(v.to_string(), e.to_string());
    // Every refusal names the SPEC §4 rule it breaks.
    assert!(e.rule().is_some(), "{e}");
    e.into_root()
}

#[test]
fn test01_flipped_byte_in_each_section_is_a_checksum_error() {
    let bytes = valid(ScalarType::F32);
    let secs = sections(&bytes);
    // 8 fixed sections, 8 XFER, a MESH per object (2).
    assert_eq!(secs.len(), 18);
    for (i, (tag, off, len, _)) in secs.iter().enumerate() {
        for pos in [*off, off + len / 2, off + len - 1] {
            let mut b = bytes.clone();
            b[pos] ^= 0x10;
            match err(&b) {
                BakeFileError::ChecksumMismatch { section, .. } => {
                    assert_eq!(section, format!("{}#{i}", String::from_utf8_lossy(tag)));
                }
                e => panic!("section {i}: {e}"),
            }
        }
    }
    // The header and the section table are covered by the header CRC.
    for pos in [
        16,
        20,
        32,
        40,
        44,
        48,
        52,
        56,
        60,
        64,
        64 + 5,
        64 + 32 * 16 - 1,
    ] {
        let mut b = bytes.clone();
        b[pos] ^= if pos == 32 { 0x08 } else { 0x01 };
        assert!(
            matches!(err(&b), BakeFileError::ChecksumMismatch { ref section, .. } if section == "header"),
            "byte {pos}: {}",
            err(&b)
        );
    }
    // The file size is checked before the header CRC (so that a cut file reads as
    // Truncated), and a changed version before anything else.
    for (pos, bit) in [(24, 0x01), (28, 0x01), (24, 0x80)] {
        let mut b = bytes.clone();
        b[pos] ^= bit;
        let e = err(&b);
        assert!(
            matches!(
                e,
                BakeFileError::Truncated { .. } | BakeFileError::InconsistentCounts { .. }
            ),
            "byte {pos}: {e}"
        );
    }
    let mut b = bytes.clone();
    b[8] ^= 0x04;
    assert!(matches!(err(&b), BakeFileError::UnsupportedVersion { .. }));
    // Padding between sections is not covered by a CRC but must be zero.
    let (boff, blen) = find(&bytes, b"BINF");
    assert_eq!(blen, 40);
    let mut b = bytes.clone();
    b[boff + blen + 3] = 1;
    assert!(matches!(err(&b), BakeFileError::InvalidValue { ref field, .. } if field == "padding"));
}

#[test]
fn test02_every_truncation_is_reported_as_truncated() {
    for scalar in [ScalarType::F32, ScalarType::F16] {
        let bytes = valid(scalar);
        for n in 0..bytes.len() {
            match err(&bytes[..n]) {
                BakeFileError::Truncated { available, needed } => {
                    assert_eq!(available, n as u64);
                    assert!(needed > n as u64);
                }
                e => panic!("prefix of {n} bytes: {e}"),
            }
        }
        assert!(decode(&bytes).is_ok());
        // Trailing bytes are refused too.
        let mut longer = bytes.clone();
        longer.push(0);
        assert!(matches!(
            err(&longer),
            BakeFileError::InconsistentCounts { .. }
        ));
    }
}

#[test]
fn test03_magic_and_version() {
    let bytes = valid(ScalarType::F32);
    let mut b = bytes.clone();
    b[0] = b'Q';
    assert!(matches!(err(&b), BakeFileError::BadMagic { .. }));
    assert!(matches!(err(b"GIF89a"), BakeFileError::BadMagic { .. }));
    assert!(matches!(err(b""), BakeFileError::Truncated { .. }));

    // Unknown major versions are refused before anything else is looked at.
    for major in [0, 2, 7, u32::MAX] {
        let mut b = bytes.clone();
        put_u32(&mut b, 8, major);
        match err(&b) {
            BakeFileError::UnsupportedVersion {
                major: m,
                minor: VERSION_MINOR,
                supported: 1,
            } => assert_eq!(m, major),
            e => panic!("{e}"),
        }
        // Even when the rest of the file is garbage.
        b[64..].fill(0xAB);
        assert!(matches!(err(&b), BakeFileError::UnsupportedVersion { .. }));
    }

    // A later minor version of major 1 is read (the JSON says the same version).
    let mut b = bytes.clone();
    let (off, len) = find(&b, b"META");
    let text = std::str::from_utf8(&b[off..off + len]).unwrap().to_owned();
    let needle = "\"format_version\": [\n    1,\n    3\n  ]";
    let at = off + text.find(needle).expect("pretty-printed version");
    let zero = at + needle.len() - 5;
    assert_eq!(b[zero], b'3');
    b[zero] = b'4';
    put_u32(&mut b, 12, 4);
    fix_crcs(&mut b);
    let view = BakeView::new(&b).unwrap();
    assert_eq!(view.version(), (1, 4));
    // ... but header and JSON must agree.
    put_u32(&mut b, 12, 5);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::Metadata(_)));
}

#[test]
fn test04_huge_counts_are_refused_without_allocation() {
    let bytes = valid(ScalarType::F32);
    let (objt, _) = find(&bytes, b"OBJT");
    let (blkt, _) = find(&bytes, b"BLKT");
    let (envl, _) = find(&bytes, b"ENVL");
    let (glsy, _) = find(&bytes, b"GLSY");
    let (brdf, _) = find(&bytes, b"BRDF");
    // (what, patch) pairs; each must give a typed error, never an attempt to allocate.
    // (what, byte offset, value, width); each must give a typed error, never an allocation.
    let patches = [
        ("object count", objt, u64::from(u32::MAX), 4),
        ("object record size", objt + 4, u64::from(u32::MAX), 4),
        ("block count", blkt, u64::from(u32::MAX), 4),
        ("object point count", objt + 16 + 32, u64::MAX, 8),
        ("object order", objt + 16 + 40, u64::from(u32::MAX), 4),
        ("object order 65535", objt + 16 + 40, 65535, 4),
        ("object block count", objt + 16 + 52, u64::from(u32::MAX), 4),
        ("block point count", blkt + 16 + 24, u64::MAX, 8),
        ("block data length", blkt + 16 + 40, u64::MAX, 8),
        ("block section", blkt + 16 + 32, u64::from(u32::MAX), 4),
        ("name length", objt + 16 + 4, u64::from(u32::MAX), 4),
        ("name offset", objt + 16, u64::from(u32::MAX), 4),
        ("environment order", envl, u64::from(u32::MAX), 4),
        ("glossy elevations", glsy + 16 + 8, u64::from(u32::MAX), 4),
        ("glossy order", glsy + 16 + 12, u64::from(u32::MAX), 4),
        ("glossy values offset", glsy + 16 + 24, u64::MAX, 8),
        ("brdf order", brdf + 16 + 12, u64::from(u32::MAX), 4),
        ("brdf count", brdf, u64::from(u32::MAX), 4),
    ];
    for (what, at, value, width) in patches {
        let mut b = bytes.clone();
        b[at..at + width].copy_from_slice(&value.to_le_bytes()[..width]);
        fix_crcs(&mut b);
        let e = err(&b);
        assert!(
            matches!(
                e,
                BakeFileError::InconsistentCounts { .. } | BakeFileError::InvalidValue { .. }
            ),
            "{what}: {e}"
        );
    }
    // Section table entries: a huge section count, offset or length.
    let mut b = bytes.clone();
    put_u32(&mut b, 40, u32::MAX);
    assert!(
        matches!(err(&b), BakeFileError::OutOfBounds { .. }),
        "{}",
        err(&b)
    );
    let xfer = sections(&bytes).iter().find(|s| &s.0 == b"XFER").unwrap().3;
    for (field, value) in [(16, u64::MAX), (16, 1 << 40), (8, u64::MAX - 63)] {
        let mut b = bytes.clone();
        put_u64(&mut b, xfer + field, value);
        fix_crcs(&mut b);
        assert!(
            matches!(err(&b), BakeFileError::OutOfBounds { .. }),
            "{}",
            err(&b)
        );
    }
}

#[test]
fn test05_non_finite_values_are_refused() {
    for scalar in [ScalarType::F32, ScalarType::F16] {
        let bytes = valid(scalar);
        let secs = sections(&bytes);
        let (i, (_, off, _, _)) = secs
            .iter()
            .enumerate()
            .filter(|(_, s)| &s.0 == b"XFER")
            .nth(2)
            .unwrap();
        for (index, nan) in [(0usize, true), (7, false), (20, true)] {
            let mut b = bytes.clone();
            let at = off + index * scalar.size();
            match (scalar, nan) {
                (ScalarType::F32, true) => b[at..at + 4].copy_from_slice(&f32::NAN.to_le_bytes()),
                (ScalarType::F32, false) => {
                    b[at..at + 4].copy_from_slice(&f32::NEG_INFINITY.to_le_bytes())
                }
                (ScalarType::F16, true) => b[at..at + 2].copy_from_slice(&0x7e00u16.to_le_bytes()),
                (ScalarType::F16, false) => b[at..at + 2].copy_from_slice(&0xfc00u16.to_le_bytes()),
            }
            fix_crcs(&mut b);
            match err(&b) {
                BakeFileError::NonFinite {
                    section,
                    index: got,
                } => {
                    assert_eq!(section, format!("XFER#{i}"));
                    assert_eq!(got, index as u64);
                }
                e => panic!("{e}"),
            }
        }
    }
    // NaN in the f64 sections.
    let bytes = valid(ScalarType::F32);
    for (tag, at) in [
        (b"ENVL", 16 + 8 * 5),
        (b"BRDF", 16 + 2 * 32 + 8),
        (b"GLSY", 16 + 40 + 8),
    ] {
        let (off, _) = find(&bytes, tag);
        let mut b = bytes.clone();
        b[off + at..off + at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        fix_crcs(&mut b);
        assert!(
            matches!(err(&b), BakeFileError::NonFinite { .. }),
            "{}",
            err(&b)
        );
    }
    // And in memory: the encoder refuses NaN too.
    let mut bake = sample_bake();
    bake.objects[1].blocks[0].data[3] = f32::NAN;
    assert!(matches!(
        encode(&bake, ScalarType::F32),
        Err(BakeFileError::NonFinite { index: 3, .. })
    ));
}

#[test]
fn test06_layout_errors() {
    let bytes = valid(ScalarType::F32);
    let secs = sections(&bytes);
    // Overlap: section 2 placed where section 1 is.
    let mut b = bytes.clone();
    put_u64(&mut b, secs[2].3 + 8, secs[1].1 as u64);
    fix_crcs(&mut b);
    assert!(
        matches!(err(&b), BakeFileError::Overlap { .. }),
        "{}",
        err(&b)
    );
    // Overlap with the section table.
    let mut b = bytes.clone();
    put_u64(&mut b, secs[0].3 + 8, 64);
    fix_crcs(&mut b);
    assert!(
        matches!(err(&b), BakeFileError::Overlap { .. }),
        "{}",
        err(&b)
    );
    // Misaligned payload.
    let mut b = bytes.clone();
    put_u64(&mut b, secs[3].3 + 8, secs[3].1 as u64 + 8);
    fix_crcs(&mut b);
    assert!(
        matches!(err(&b), BakeFileError::Misaligned { .. }),
        "{}",
        err(&b)
    );
    // Duplicate, missing and unknown required sections.
    let mut b = bytes.clone();
    b[secs[4].3..secs[4].3 + 4].copy_from_slice(b"BINF");
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::DuplicateSection(ref t) if t == "BINF"));
    let meta = secs.iter().position(|s| &s.0 == b"META").unwrap();
    let mut b = bytes.clone();
    b[secs[meta].3..secs[meta].3 + 4].copy_from_slice(b"ZZZZ");
    fix_crcs(&mut b);
    assert!(
        matches!(err(&b), BakeFileError::UnknownRequiredSection(_)),
        "{}",
        err(&b)
    );
    put_u32(&mut b, secs[meta].3 + 4, 0); // no longer required: ignored, so META is missing
    fix_crcs(&mut b);
    assert!(
        matches!(err(&b), BakeFileError::MissingSection(ref t) if t == "META"),
        "{}",
        err(&b)
    );
    // Unknown must-understand flags; unknown optional flags are ignored.
    let mut b = bytes.clone();
    put_u32(&mut b, 20, 0x0000_0002);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::UnsupportedFlags { .. }));
    put_u32(&mut b, 20, 0x0001_0000);
    put_u32(&mut b, secs[5].3 + 4, 0x8000_0001);
    fix_crcs(&mut b);
    assert!(decode(&b).is_ok());
    put_u32(&mut b, secs[5].3 + 4, 0x0000_0004);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::UnsupportedFlags { .. }));
    // Unknown enum codes.
    let (blkt, _) = find(&bytes, b"BLKT");
    let mut b = bytes.clone();
    put_u32(&mut b, blkt + 16 + 4, 9);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::InvalidValue { .. }));
    let mut b = bytes.clone();
    put_u32(&mut b, 52, 3);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::InvalidValue { .. }));
}

#[test]
fn test07_binary_tables_and_json_must_agree() {
    let bytes = valid(ScalarType::F32);
    let (binf, _) = find(&bytes, b"BINF");
    let (objt, _) = find(&bytes, b"OBJT");
    for (at, what) in [
        (binf + 32, "seed"),
        (binf + 16, "rays_per_point"),
        (objt + 16 + 8, "geometry_hash"),
    ] {
        let mut b = bytes.clone();
        b[at] ^= 1;
        fix_crcs(&mut b);
        match err(&b) {
            BakeFileError::Metadata(m) => assert!(m.contains(what), "{m}"),
            e => panic!("{what}: {e}"),
        }
    }
    // Broken JSON.
    let (meta, _) = find(&bytes, b"META");
    let mut b = bytes.clone();
    b[meta] = b'[';
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::Metadata(_)));
    // A different SH convention is refused.
    let mut b = bytes.clone();
    let (_, meta_len) = find(&bytes, b"META");
    let text = String::from_utf8(b[meta..meta + meta_len].to_vec()).unwrap();
    let at = meta + text.find("condon-shortley").unwrap();
    b[at..at + 6].copy_from_slice(b"CONDON");
    fix_crcs(&mut b);
    match err(&b) {
        BakeFileError::Metadata(m) => assert!(m.contains("sh"), "{m}"),
        e => panic!("{e}"),
    }
}

#[test]
fn test08_unknown_optional_section_is_ignored_and_table_may_move() {
    // Append an unknown, optional section and move the section table to the end of the file
    // (SPEC.md allows both): the bake reads as before.
    let bytes = valid(ScalarType::F16);
    let old = sections(&bytes);
    let mut b = bytes.clone();
    let new_payload = b"future data".to_vec();
    let payload_off = b.len().div_ceil(64) * 64;
    b.resize(payload_off, 0);
    b.extend_from_slice(&new_payload);
    let table_off = b.len().div_ceil(8) * 8;
    b.resize(table_off, 0);
    let old_table = bytes[64..64 + 32 * old.len()].to_vec();
    b.extend_from_slice(&old_table);
    let mut entry = [0u8; 32];
    entry[..4].copy_from_slice(b"FUTR");
    entry[8..16].copy_from_slice(&(payload_off as u64).to_le_bytes());
    entry[16..24].copy_from_slice(&(new_payload.len() as u64).to_le_bytes());
    b.extend_from_slice(&entry);
    b[64..64 + 32 * old.len()].fill(0);
    let len = b.len() as u64;
    put_u64(&mut b, 24, len);
    put_u64(&mut b, 32, table_off as u64);
    put_u32(&mut b, 40, old.len() as u32 + 1);
    fix_crcs(&mut b);
    assert_eq!(decode(&b).unwrap(), decode(&bytes).unwrap());
    // The same section marked required is refused.
    let e = table_off + 32 * old.len();
    put_u32(&mut b, e + 4, 1);
    fix_crcs(&mut b);
    assert!(matches!(err(&b), BakeFileError::UnknownRequiredSection(_)));
}

#[test]
fn test09_errors_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("broken.prtbake");
    let mut b = valid(ScalarType::F32);
    let n = b.len();
    b[n - 1] ^= 0xff;
    std::fs::write(&path, &b).unwrap();
    let e = read_bake(&path).unwrap_err();
    assert!(e.to_string().contains("broken.prtbake"), "{e}");
    assert!(matches!(e.root(), BakeFileError::ChecksumMismatch { .. }));
    let e = read_bake(&dir.path().join("missing.prtbake")).unwrap_err();
    assert!(e.to_string().contains("missing.prtbake"), "{e}");
    assert!(matches!(e.root(), BakeFileError::Io(_)));
}

/// Format 1.1's MESH and CVRG sections: every rule of SPEC.md §3.10–3.11 that a file can
/// break, each caught with a message that says what is wrong.
#[test]
fn test10_mesh_and_coverage_rules() {
    let bytes = valid(ScalarType::F32);
    let secs = sections(&bytes);
    let mesh_of = |i: usize| secs.iter().filter(|s| &s.0 == b"MESH").nth(i).unwrap().1;
    let (objt, _) = find(&bytes, b"OBJT");
    let record = |o: usize| objt + 16 + 64 * o;
    let message = |b: &mut Vec<u8>| {
        fix_crcs(b);
        err(b).to_string()
    };

    // A moved vertex no longer hashes to the object's geometry hash.
    let mut b = bytes.clone();
    b[mesh_of(0) + 16] ^= 0x01;
    assert!(message(&mut b).contains("hashes to"));
    // A triangle index beyond the vertices.
    let mut b = bytes.clone();
    let v = u32_at(&b, mesh_of(1) + 4) as usize;
    put_u32(&mut b, mesh_of(1) + 16 + 24 * v, v as u32);
    assert!(message(&mut b).contains("beyond its"));
    // A non-finite normal.
    let mut b = bytes.clone();
    put_u32(&mut b, mesh_of(1) + 16 + 12 * v, 0x7fc0_0000);
    assert!(message(&mut b).contains("not finite"));
    // A normal that is not unit length (normals are not hashed).
    let mut b = bytes.clone();
    put_u32(&mut b, mesh_of(1) + 16 + 12 * v, 2.0f32.to_bits());
    assert!(message(&mut b).contains("not 1"));
    // Object 1 pointing at object 0's mesh; a mesh no object points at.
    let mut b = bytes.clone();
    let m0 = u32_at(&b, record(0) + 56);
    put_u32(&mut b, record(1) + 56, m0);
    assert!(message(&mut b).contains("does not belong"));
    let mut b = bytes.clone();
    put_u32(&mut b, record(0) + 56, u32::MAX);
    let e = message(&mut b);
    assert!(e.contains("MESH sections"), "{e}");
    // A MESH index that names an XFER section.
    let mut b = bytes.clone();
    put_u32(&mut b, record(0) + 56, 8);
    assert!(message(&mut b).contains("is not a MESH section"));
    // Coverage in a per-vertex bake: point object 0's coverage field at its mesh.
    let mut b = bytes.clone();
    put_u32(&mut b, record(0) + 60, m0);
    assert!(message(&mut b).contains("is not a CVRG section"));
    // The vertex count of a per-vertex bake's mesh must be its point count.
    let mut b = bytes.clone();
    put_u32(&mut b, mesh_of(0) + 4, 1);
    assert!(message(&mut b).contains("MESH length"));

    // Per-pixel: hits beyond K, and objects whose hits add up to more than K.
    let mut bake = sample_bake();
    bake.meta.sample_kind = SampleKind::Pixel {
        width: 1,
        height: 1,
    };
    bake.meta.settings["pixel_samples"] = serde_json::json!(4);
    let camera = CameraInfo {
        model: "pinhole".into(),
        eye: [0.0, 1.0, 3.0],
        target: [0.0; 3],
        up: [0.0, 1.0, 0.0],
        fov_y_degrees: 40.0,
        width: 1,
        height: 1,
    };
    bake.objects.truncate(1);
    bake.meta.ray_stats.truncate(1);
    let o = &mut bake.objects[0];
    o.point_count = 1;
    o.points_in_file = 1;
    for b in &mut o.blocks {
        b.data.truncate(25);
    }
    o.coverage = Some(Coverage {
        pixel_samples: 4,
        hits: vec![3],
    });
    let mut second = o.clone();
    second.name = "second".into();
    let no_camera = encode(&bake, ScalarType::F32).unwrap_err().to_string();
    assert!(no_camera.contains("records its camera"), "{no_camera}");
    bake.meta.camera = Some(camera);
    let ok = encode(&bake, ScalarType::F32).unwrap();
    assert_eq!(decode(&ok).unwrap(), bake);
    let (cvrg, _) = find(&ok, b"CVRG");
    let mut b = ok.clone();
    put_u32(&mut b, cvrg + 16, 5);
    assert!(message(&mut b).contains("is hit by 5 of 4"));
    // Transfer in a pixel its coverage says no sample hit.
    let mut b = ok.clone();
    put_u32(&mut b, cvrg + 16, 0);
    assert!(message(&mut b).contains("which its coverage says no sample hit"));
    let mut b = ok.clone();
    put_u32(&mut b, cvrg + 4, 3);
    // The JSON still says K = 4: caught as a disagreement of the tables and the JSON.
    let e = message(&mut b);
    assert!(
        e.contains("coverage is Some((") && e.contains(", 4))"),
        "{e}"
    );
    bake.objects.push(second);
    bake.meta.ray_stats.clear();
    let e = encode(&bake, ScalarType::F32).unwrap_err().to_string();
    assert!(e.contains("adds up to more than 4"), "{e}");
    // K must be the bake's settings.pixel_samples.
    bake.objects.pop();
    bake.objects[0].coverage.as_mut().unwrap().pixel_samples = 3;
    let e = encode(&bake, ScalarType::F32).unwrap_err().to_string();
    assert!(e.contains("the bake's pixel_samples is 4"), "{e}");
}
