//! Shared helpers of the integration tests: bake generators and a CRC fixer written from
//! SPEC.md (independently of the crate's writer).
#![allow(dead_code)]

use prt_bakefile::*;
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;

pub fn rng(seed: u64) -> Pcg64 {
    Pcg64::seed_from_u64(seed)
}

/// A random mesh of `vertices` vertices (with some triangles when it has any), its normals
/// unit vectors, and the geometry hash that goes with it.
pub fn random_mesh(r: &mut Pcg64, vertices: usize) -> (MeshGeometry, u64) {
    let positions: Vec<[f32; 3]> = (0..vertices)
        .map(|_| [0; 3].map(|_| r.random_range(-10.0f32..10.0)))
        .collect();
    let normals = (0..vertices)
        .map(|_| {
            let v = [0; 3].map(|_| r.random_range(-1.0f32..1.0));
            let l = v.iter().map(|x| x * x).sum::<f32>().sqrt().max(1e-3);
            v.map(|x| x / l)
        })
        .collect();
    let triangles = if vertices == 0 {
        Vec::new()
    } else {
        (0..r.random_range(1..2 * vertices + 2))
            .map(|_| [0; 3].map(|_| r.random_range(0..vertices as u32)))
            .collect()
    };
    let hash = geometry_hash(&positions, &triangles);
    (
        MeshGeometry {
            positions,
            normals,
            triangles,
        },
        hash,
    )
}

/// A small bake with every section and every transfer kind.
pub fn sample_bake() -> Bake {
    let mut r = rng(7);
    let object = |name: &str, points: u64, order: u32, channels: u32, r: &mut Pcg64| {
        let n = (points * u64::from(channels * order * order)) as usize;
        let (mesh, geometry_hash) = random_mesh(r, points as usize);
        let kinds = [
            TransferKind::UnshadowedDiffuse,
            TransferKind::ShadowedDiffuse,
            TransferKind::Visibility,
            TransferKind::InterreflectedDiffuse { bounces: 2 },
        ];
        ObjectBake {
            name: name.into(),
            geometry_hash,
            point_count: points,
            point_first: 0,
            points_in_file: points,
            order,
            channels,
            blocks: kinds
                .iter()
                .map(|&kind| TransferBlock {
                    cpca: None,
                    kind,
                    data: (0..n).map(|_| r.random_range(-4.0f32..4.0)).collect(),
                })
                .collect(),
            mesh: Some(mesh),
            coverage: None,
            material: None,
            pass: None,
        }
    };
    Bake {
        reflectance: None,
        meta: BakeMeta {
            sample_kind: SampleKind::Vertex,
            rays_per_point: 1024,
            bounces: 2,
            seed: 0x0123_4567_89ab_cdef,
            tool: ToolInfo {
                name: "prt-bake".into(),
                version: "0.1.0".into(),
            },
            settings: serde_json::json!({
                "scene": "scenes/cornell.gltf",
                "rays": 1024,
                "ray_offset": 1.0e-4,
                "weights": [0.1, 0.2, 0.30000000000000004],
            }),
            decisions: vec![
                Decision {
                    object: Some("bunny".into()),
                    decision: "order 5".into(),
                    reason: "relative error 0.8% < 1% target at order 5".into(),
                },
                Decision {
                    object: None,
                    decision: "skip glossy transfer".into(),
                    reason: "no glossy material".into(),
                },
            ],
            shard: ShardInfo::default(),
            ray_stats: vec![
                RayStats {
                    object: "bunny".into(),
                    points: 37,
                    rays: 37 * 1024,
                    backface_hits: 91,
                    inside_points: 1,
                    inside_rays: 1024,
                },
                RayStats {
                    object: "floor".into(),
                    points: 11,
                    rays: 11 * 1024,
                    ..RayStats::default()
                },
            ],
            camera: None,
            pass: None,
        },
        objects: vec![
            object("bunny", 37, 5, 1, &mut r),
            object("floor", 11, 3, 3, &mut r),
        ],
        environment: Some(EnvCoefficients {
            order: 3,
            precision: EnvPrecision::F64,
            values: (0..27).map(|i| f64::from(i) * 0.1 - 1.0).collect(),
        }),
        brdfs: vec![
            BrdfProjection {
                material: "white".into(),
                lobe: BrdfLobe::ClampedCosine,
                order: 3,
                values: vec![0.886, 1.023, 0.495],
            },
            BrdfProjection {
                material: "plastic".into(),
                lobe: BrdfLobe::Phong { exponent: 32.5 },
                order: 4,
                values: vec![0.28, 0.48, 0.61, 0.7],
            },
        ],
        glossy: vec![GlossyBrdfTable {
            material: "plastic".into(),
            order: 2,
            elevations: vec![0.1, 0.7, 1.3],
            values: (0..12).map(|i| f64::from(i) / 7.0).collect(),
            projection_error: vec![0.4, 0.05],
        }],
    }
}

/// A random valid bake: random counts, orders, channels, kinds, sections and values.
pub fn random_bake(r: &mut Pcg64) -> Bake {
    let pixel = r.random_bool(0.3);
    let (w, h) = (r.random_range(1..6u32), r.random_range(1..6u32));
    let bounces = r.random_range(0..4u32);
    let object_count = r.random_range(0..4usize);
    // Per-pixel bakes: K footprint samples, shared out so the objects' hits of a pixel add up
    // to at most K.
    let k = r.random_range(1..9u32);
    let share = k / object_count.max(1) as u32;
    let objects = (0..object_count)
        .map(|i| {
            let points = if pixel {
                u64::from(w * h)
            } else {
                r.random_range(0..30u64)
            };
            let order = r.random_range(1..7u32);
            let channels = if r.random_bool(0.5) { 1 } else { 3 };
            let mut kinds = vec![
                TransferKind::UnshadowedDiffuse,
                TransferKind::ShadowedDiffuse,
                TransferKind::Visibility,
            ];
            if bounces > 0 {
                kinds.push(TransferKind::InterreflectedDiffuse {
                    bounces: r.random_range(1..=bounces),
                });
            }
            kinds.retain(|_| r.random_bool(0.6));
            let n = (points * u64::from(channels * order * order)) as usize;
            let scale = [1e-6f32, 1.0, 1e3][r.random_range(0..3)];
            let vertices = if pixel {
                r.random_range(0..8usize)
            } else {
                points as usize
            };
            let (mesh, hash) = random_mesh(r, vertices);
            let with_mesh = r.random_bool(0.7);
            let coverage = (pixel && r.random_bool(0.7)).then(|| Coverage {
                pixel_samples: k,
                hits: (0..points).map(|_| r.random_range(0..=share)).collect(),
            });
            let mut blocks: Vec<TransferBlock> = kinds
                .into_iter()
                .map(|kind| TransferBlock {
                    cpca: None,
                    kind,
                    data: (0..n)
                        .map(|_| r.random_range(-1.0f32..1.0) * scale)
                        .collect(),
                })
                .collect();
            // No transfer where the coverage says no sample hit (SPEC §3.11).
            if let Some(c) = &coverage {
                let per = (channels * order * order) as usize;
                for b in &mut blocks {
                    for (p, &h) in c.hits.iter().enumerate() {
                        if h == 0 {
                            b.data[p * per..(p + 1) * per].fill(0.0);
                        }
                    }
                }
            }
            ObjectBake {
                name: format!("object-{i}-{}", ["a", "ü", "名"][r.random_range(0..3)]),
                geometry_hash: if with_mesh { hash } else { r.random() },
                point_count: points,
                point_first: 0,
                points_in_file: points,
                order,
                channels,
                blocks,
                mesh: with_mesh.then_some(mesh),
                coverage,
                material: None,
                pass: None,
            }
        })
        .collect();
    let camera = pixel.then(|| CameraInfo {
        model: "pinhole".into(),
        eye: [r.random(), r.random(), r.random()],
        target: [r.random::<f64>() + 2.0, 0.5, -1.0],
        up: [0.0, 1.0, 0.0],
        fov_y_degrees: r.random_range(1.0..179.0),
        width: w,
        height: h,
    });
    let environment = r.random_bool(0.5).then(|| {
        let order = r.random_range(1..5u32);
        let precision = if r.random_bool(0.5) {
            EnvPrecision::F32
        } else {
            EnvPrecision::F64
        };
        EnvCoefficients {
            order,
            precision,
            values: (0..3 * order * order)
                .map(|_| {
                    let v: f64 = r.random_range(-3.0..3.0);
                    // Exactly representable when stored as f32, so the round trip is exact.
                    if precision == EnvPrecision::F32 {
                        f64::from(v as f32)
                    } else {
                        v
                    }
                })
                .collect(),
        }
    });
    let brdfs = (0..r.random_range(0..3))
        .map(|i| {
            let order = r.random_range(1..8u32);
            BrdfProjection {
                material: format!("m{i}"),
                lobe: if r.random_bool(0.5) {
                    BrdfLobe::ClampedCosine
                } else {
                    BrdfLobe::Phong {
                        exponent: r.random_range(0.0..200.0),
                    }
                },
                order,
                values: (0..order).map(|_| r.random()).collect(),
            }
        })
        .collect();
    let glossy = (0..r.random_range(0..3))
        .map(|i| {
            let order = r.random_range(1..5u32);
            let e = r.random_range(1..5usize);
            GlossyBrdfTable {
                material: format!("g{i}"),
                order,
                elevations: (0..e).map(|_| r.random_range(0.0..1.5)).collect(),
                values: (0..e * (order * order) as usize)
                    .map(|_| r.random())
                    .collect(),
                projection_error: (0..order).map(|_| r.random()).collect(),
            }
        })
        .collect();
    Bake {
        reflectance: None,
        meta: BakeMeta {
            sample_kind: if pixel {
                SampleKind::Pixel {
                    width: w,
                    height: h,
                }
            } else {
                SampleKind::Vertex
            },
            rays_per_point: r.random(),
            bounces,
            seed: r.random(),
            tool: ToolInfo {
                name: "random".into(),
                version: format!("{}", r.random::<u16>()),
            },
            settings: if pixel {
                serde_json::json!({ "x": r.random::<f64>(), "pixel_samples": k })
            } else {
                serde_json::json!({ "x": r.random::<f64>(), "n": r.random::<u32>() })
            },
            decisions: vec![],
            ray_stats: vec![],
            shard: ShardInfo::default(),
            camera,
            pass: None,
        },
        objects,
        environment,
        brdfs,
        glossy,
    }
}

pub fn u32_at(b: &[u8], o: usize) -> u32 {
    u32::from_le_bytes(b[o..o + 4].try_into().unwrap())
}

fn u64_at(b: &[u8], o: usize) -> u64 {
    u64::from_le_bytes(b[o..o + 8].try_into().unwrap())
}

/// The section table as (tag, offset, length, entry offset).
pub fn sections(b: &[u8]) -> Vec<([u8; 4], usize, usize, usize)> {
    let table = u64_at(b, 32) as usize;
    (0..u32_at(b, 40) as usize)
        .map(|i| {
            let e = table + 32 * i;
            (
                b[e..e + 4].try_into().unwrap(),
                u64_at(b, e + 8) as usize,
                u64_at(b, e + 16) as usize,
                e,
            )
        })
        .collect()
}

/// Payload of the first section with `tag`: (offset, length).
pub fn find(b: &[u8], tag: &[u8; 4]) -> (usize, usize) {
    let s = sections(b)
        .into_iter()
        .find(|s| &s.0 == tag)
        .expect("section");
    (s.1, s.2)
}

/// Recomputes every section CRC and the header CRC, as SPEC.md defines them.
pub fn fix_crcs(b: &mut [u8]) {
    for (_, off, len, e) in sections(b) {
        let Some(payload) = off.checked_add(len).and_then(|end| b.get(off..end)) else {
            continue;
        };
        let crc = crc32fast::hash(payload);
        b[e + 24..e + 28].copy_from_slice(&crc.to_le_bytes());
    }
    let table = u64_at(b, 32) as usize;
    let end = table + 32 * u32_at(b, 40) as usize;
    let mut h = crc32fast::Hasher::new();
    h.update(&b[..60]);
    h.update(&b[table..end]);
    let crc = h.finalize();
    b[60..64].copy_from_slice(&crc.to_le_bytes());
}

pub fn put_u32(b: &mut [u8], o: usize, v: u32) {
    b[o..o + 4].copy_from_slice(&v.to_le_bytes());
}

pub fn put_u64(b: &mut [u8], o: usize, v: u64) {
    b[o..o + 8].copy_from_slice(&v.to_le_bytes());
}
