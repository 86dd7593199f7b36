//! A minimal reader written only from SPEC.md (the way an engine programmer would), checked
//! against the crate's writer: if SPEC.md and the code disagree on a byte, this fails.

mod common;

use common::*;
use prt_bakefile::*;

fn u32_(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}
fn u64_(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().unwrap())
}
fn f64_(b: &[u8], o: usize) -> f64 {
    f64::from_bits(u64_(b, o))
}

struct Section {
    tag: [u8; 4],
    offset: usize,
    length: usize,
}

fn spec_read(bytes: &[u8]) -> Bake {
    // §2.1 header
    assert_eq!(
        &bytes[0..8],
        &[0x50, 0x52, 0x54, 0x42, 0x41, 0x4B, 0x45, 0x00]
    );
    assert_eq!(u32_(bytes, 8), 1);
    assert_eq!(u32_(bytes, 16), 64);
    assert_eq!(u64_(bytes, 24), bytes.len() as u64);
    let t = u64_(bytes, 32) as usize;
    let n = u32_(bytes, 40) as usize;
    assert_eq!(u32_(bytes, 44), 32);
    let align = u32_(bytes, 48) as usize;
    let scalar = u32_(bytes, 52);
    // §2.3 header CRC: bytes [0, 60) then the table.
    let mut stream = bytes[..60].to_vec();
    stream.extend_from_slice(&bytes[t..t + 32 * n]);
    assert_eq!(crc32fast::hash(&stream), u32_(bytes, 60));
    // §2.2 table
    let sections: Vec<Section> = (0..n)
        .map(|i| {
            let e = t + 32 * i;
            let s = Section {
                tag: bytes[e..e + 4].try_into().unwrap(),
                offset: u64_(bytes, e + 8) as usize,
                length: u64_(bytes, e + 16) as usize,
            };
            assert_eq!(s.offset % align, 0);
            assert_eq!(
                crc32fast::hash(&bytes[s.offset..s.offset + s.length]),
                u32_(bytes, e + 24)
            );
            s
        })
        .collect();
    let sec = |tag: &[u8; 4]| {
        sections
            .iter()
            .find(|s| &s.tag == tag)
            .map(|s| &bytes[s.offset..s.offset + s.length])
    };
    let strs = sec(b"STRS").unwrap();
    let string =
        |o: u32, l: u32| String::from_utf8(strs[o as usize..(o + l) as usize].to_vec()).unwrap();
    // §3.1
    let binf = sec(b"BINF").unwrap();
    let sample_kind = match u32_(binf, 0) {
        1 => SampleKind::Vertex,
        2 => SampleKind::Pixel {
            width: u32_(binf, 8),
            height: u32_(binf, 12),
        },
        k => panic!("sample kind {k}"),
    };
    // §3.9 (only the fields that are not in the tables)
    let meta: serde_json::Value = serde_json::from_slice(sec(b"META").unwrap()).unwrap();
    let meta = BakeMeta {
        sample_kind,
        bounces: u32_(binf, 4),
        rays_per_point: u32_(binf, 16),
        shard: ShardInfo {
            index: u32_(binf, 20),
            count: u32_(binf, 24),
        },
        seed: u64_(binf, 32),
        tool: serde_json::from_value(meta["tool"].clone()).unwrap(),
        settings: meta["settings"].clone(),
        decisions: serde_json::from_value(meta["decisions"].clone()).unwrap(),
        ray_stats: serde_json::from_value(
            meta.get("ray_stats")
                .cloned()
                .unwrap_or(serde_json::json!([])),
        )
        .unwrap(),
        // 1.1: null for per-vertex bakes, the camera object for per-pixel ones.
        camera: serde_json::from_value(meta["camera"].clone()).unwrap(),
        pass: None,
    };
    // §3.3, §3.4, §3.5
    let objt = sec(b"OBJT").unwrap();
    let blkt = sec(b"BLKT").unwrap();
    let (orec, brec) = (u32_(objt, 4) as usize, u32_(blkt, 4) as usize);
    let objects = (0..u32_(objt, 0) as usize)
        .map(|o| {
            let r = 16 + o * orec;
            let order = u32_(objt, r + 40);
            let channels = u32_(objt, r + 44);
            let points = u64_(objt, r + 32);
            let first = u32_(objt, r + 48);
            let blocks = (first..first + u32_(objt, r + 52))
                .map(|b| {
                    let k = 16 + b as usize * brec;
                    let s = &sections[u32_(blkt, k + 32) as usize];
                    assert_eq!(&s.tag, b"XFER");
                    let size = if scalar == 1 { 4 } else { 2 };
                    let len = points as usize * (channels * order * order) as usize * size;
                    assert_eq!(u64_(blkt, k + 40) as usize, len);
                    assert_eq!(s.length, len);
                    let raw = &bytes[s.offset..s.offset + len];
                    let data = if scalar == 1 {
                        raw.chunks_exact(4)
                            .map(|c| f32::from_le_bytes(c.try_into().unwrap()))
                            .collect()
                    } else {
                        raw.chunks_exact(2)
                            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
                            .collect()
                    };
                    let kind = match (u32_(blkt, k + 4), u32_(blkt, k + 8)) {
                        (1, 0) => TransferKind::UnshadowedDiffuse,
                        (2, 0) => TransferKind::ShadowedDiffuse,
                        (3, 0) => TransferKind::Visibility,
                        (4, b) => TransferKind::InterreflectedDiffuse { bounces: b },
                        k => panic!("kind {k:?}"),
                    };
                    TransferBlock {
                        kind,
                        data,
                        cpca: None,
                    }
                })
                .collect();
            // §3.3 (1.1 fields), §3.10, §3.11
            assert_eq!(orec, 64);
            let section = |field: usize, tag: &[u8; 4]| {
                let i = u32_(objt, r + field);
                (i != 0xFFFF_FFFF).then(|| {
                    let s = &sections[i as usize];
                    assert_eq!(&s.tag, tag);
                    let p = &bytes[s.offset..s.offset + s.length];
                    assert_eq!(u32_(p, 0) as usize, o);
                    p
                })
            };
            let mesh = section(56, b"MESH").map(|p| {
                let (v, t) = (u32_(p, 4) as usize, u32_(p, 8) as usize);
                assert_eq!(p.len(), 16 + 24 * v + 12 * t);
                let f = |at: usize| f32::from_bits(u32_(p, at));
                let vec3s = |base: usize| {
                    (0..v)
                        .map(|i| [0, 4, 8].map(|k| f(base + 12 * i + k)))
                        .collect()
                };
                // §5: the hash is FNV-1a over the position bytes, then the triangle bytes.
                let mut h: u64 = 0xcbf2_9ce4_8422_2325;
                for &b in p[16..16 + 12 * v].iter().chain(&p[16 + 24 * v..]) {
                    h = (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
                }
                assert_eq!(h, u64_(objt, r + 8), "geometry hash of object {o}");
                MeshGeometry {
                    positions: vec3s(16),
                    normals: vec3s(16 + 12 * v),
                    triangles: (0..t)
                        .map(|i| [0, 4, 8].map(|k| u32_(p, 16 + 24 * v + 12 * i + k)))
                        .collect(),
                }
            });
            let coverage = section(60, b"CVRG").map(|p| {
                let n = u64_(p, 8) as usize;
                assert_eq!(n as u64, points);
                assert_eq!(p.len(), 16 + 4 * n);
                Coverage {
                    pixel_samples: u32_(p, 4),
                    hits: (0..n).map(|i| u32_(p, 16 + 4 * i)).collect(),
                }
            });
            ObjectBake {
                name: string(u32_(objt, r), u32_(objt, r + 4)),
                geometry_hash: u64_(objt, r + 8),
                point_count: u64_(objt, r + 16),
                point_first: u64_(objt, r + 24),
                points_in_file: points,
                order,
                channels,
                blocks,
                mesh,
                coverage,
                material: None,
                pass: None,
            }
        })
        .collect();
    // §3.6
    let environment = sec(b"ENVL").map(|p| {
        let order = u32_(p, 0);
        assert_eq!(u32_(p, 4), 3);
        let n = 3 * (order * order) as usize;
        let (precision, values) = match u32_(p, 8) {
            1 => (
                EnvPrecision::F32,
                (0..n)
                    .map(|i| f64::from(f32::from_bits(u32_(p, 16 + 4 * i))))
                    .collect(),
            ),
            3 => (
                EnvPrecision::F64,
                (0..n).map(|i| f64_(p, 16 + 8 * i)).collect(),
            ),
            c => panic!("precision {c}"),
        };
        EnvCoefficients {
            order,
            precision,
            values,
        }
    });
    // §3.7
    let brdfs = sec(b"BRDF")
        .map(|p| {
            (0..u32_(p, 0) as usize)
                .map(|i| {
                    let r = 16 + i * u32_(p, 4) as usize;
                    let order = u32_(p, r + 12);
                    let off = u64_(p, r + 24) as usize;
                    BrdfProjection {
                        material: string(u32_(p, r), u32_(p, r + 4)),
                        lobe: match u32_(p, r + 8) {
                            1 => BrdfLobe::ClampedCosine,
                            _ => BrdfLobe::Phong {
                                exponent: f64_(p, r + 16),
                            },
                        },
                        order,
                        values: (0..order as usize).map(|j| f64_(p, off + 8 * j)).collect(),
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    // §3.8
    let glossy = sec(b"GLSY")
        .map(|p| {
            (0..u32_(p, 0) as usize)
                .map(|i| {
                    let r = 16 + i * u32_(p, 4) as usize;
                    let e = u32_(p, r + 8) as usize;
                    let order = u32_(p, r + 12);
                    let arr = |off: usize, n: usize| (0..n).map(|j| f64_(p, off + 8 * j)).collect();
                    GlossyBrdfTable {
                        material: string(u32_(p, r), u32_(p, r + 4)),
                        order,
                        elevations: arr(u64_(p, r + 16) as usize, e),
                        values: arr(u64_(p, r + 24) as usize, e * (order * order) as usize),
                        projection_error: arr(u64_(p, r + 32) as usize, order as usize),
                    }
                })
                .collect()
        })
        .unwrap_or_default();
    Bake {
        reflectance: None,
        meta,
        objects,
        environment,
        brdfs,
        glossy,
    }
}

#[test]
fn test01_spec_reader_reads_what_the_writer_writes() {
    let mut r = rng(5);
    let mut bakes = vec![sample_bake()];
    bakes.extend((0..40).map(|_| random_bake(&mut r)));
    for (i, bake) in bakes.iter().enumerate() {
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let bytes = encode(bake, scalar).unwrap();
            assert_eq!(
                spec_read(&bytes),
                decode(&bytes).unwrap(),
                "bake {i}, {scalar:?}"
            );
        }
    }
}

#[test]
fn test02_crc_check_value() {
    // SPEC.md §2.3: CRC-32/ISO-HDLC check value.
    assert_eq!(crc32fast::hash(b"123456789"), 0xCBF4_3926);
}
