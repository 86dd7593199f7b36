//! Accel: correctness against brute force, the obvhs bug pins (A, B, C) and robust spawning.

use glam::{Vec3, Vec3A};
use obvhs::{cwbvh::builder::build_cwbvh_from_tris, ray::Ray, triangle::Triangle, BvhBuildParams};
use prt_scene::Mesh;
use prt_tracer::box_nodes::BoxNodes;
use prt_tracer::{test_util, Accel, AccelOptions};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::time::Duration;

fn accel(meshes: &[Mesh]) -> Accel {
    Accel::from_meshes(meshes, AccelOptions::default()).expect("valid meshes")
}

/// The structure of `meshes` with every group traversed through its BVH, even groups small
/// enough to be tested triangle by triangle (what those are compared against).
fn through_bvhs(meshes: &[Mesh]) -> Accel {
    Accel::from_meshes(
        meshes,
        AccelOptions {
            direct_triangles: 0,
            ..AccelOptions::default()
        },
    )
    .unwrap()
}

fn unit_dir(rng: &mut Pcg64) -> Vec3 {
    let z: f32 = rng.random_range(-1.0..1.0);
    let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * phi.cos(), r * phi.sin(), z)
}

/// A unit sphere and a smaller one overlapping it (rings and segments of each), in an open box.
fn spheres_in_a_box(big: (u32, u32), small: (u32, u32)) -> Vec<Mesh> {
    vec![
        test_util::uv_sphere(Vec3::ZERO, 1.0, big.0, big.1, true),
        test_util::uv_sphere(Vec3::new(0.5, 0.3, 0.2), 0.7, small.0, small.1, true),
        test_util::open_box(Vec3::new(0.0, -0.5, 0.0), 2.0),
    ]
}

/// The meshes' triangles and a plain obvhs CWBVH over them (`medium_build`).
fn plain_bvh(meshes: &[Mesh]) -> (Vec<Triangle>, obvhs::cwbvh::CwBvh) {
    let mut tris: Vec<Triangle> = Vec::new();
    for m in meshes {
        for idx in &m.indices {
            let [v0, v1, v2] = idx.map(|i| Vec3A::from(m.positions[i as usize]));
            tris.push(Triangle { v0, v1, v2 });
        }
    }
    let bvh = build_cwbvh_from_tris(
        &tris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    (tris, bvh)
}

/// Reference: closest Möller–Trumbore hit over every triangle, in f64.
fn brute_force(meshes: &[Mesh], o: Vec3, d: Vec3) -> Option<(f64, u32, u32)> {
    let (o, d) = (o.as_dvec3(), d.as_dvec3());
    let mut best: Option<(f64, u32, u32)> = None;
    for (mi, m) in meshes.iter().enumerate() {
        for (ti, idx) in m.indices.iter().enumerate() {
            let [a, b, c] = idx.map(|i| m.positions[i as usize].as_dvec3());
            let (e1, e2) = (b - a, c - a);
            let p = d.cross(e2);
            let det = e1.dot(p);
            if det.abs() < 1e-300 {
                continue;
            }
            let tv = o - a;
            let u = tv.dot(p) / det;
            let q = tv.cross(e1);
            let v = d.dot(q) / det;
            let t = e2.dot(q) / det;
            if u >= 0.0 && v >= 0.0 && u + v <= 1.0 && t > 0.0 && best.is_none_or(|bb| t < bb.0) {
                best = Some((t, mi as u32, ti as u32));
            }
        }
    }
    best
}

#[test]
fn test01_validate_every_preset() {
    let meshes = vec![
        test_util::uv_sphere(Vec3::ZERO, 1.0, 12, 24, true),
        test_util::open_box(Vec3::new(3.0, 0.0, 0.0), 1.0),
    ];
    for build in [
        BvhBuildParams::fastest_build(),
        BvhBuildParams::fast_build(),
        BvhBuildParams::medium_build(),
        BvhBuildParams::slow_build(),
    ] {
        let a = Accel::from_meshes(
            &meshes,
            AccelOptions {
                build,
                ..AccelOptions::default()
            },
        )
        .unwrap();
        a.validate().unwrap();
    }
}

#[test]
fn test02_closest_hit_matches_brute_force() {
    let meshes = spheres_in_a_box((10, 20), (8, 16));
    let a = accel(&meshes);
    let mut rng = Pcg64::seed_from_u64(1);
    let (mut hits, mut agree) = (0, 0);
    for _ in 0..4000 {
        let o = unit_dir(&mut rng) * rng.random_range(0.0f32..5.0);
        let d = unit_dir(&mut rng);
        let got = a.closest_hit(o, d, f32::INFINITY);
        let want = brute_force(&meshes, o, d);
        assert_eq!(
            got.is_some(),
            want.is_some(),
            "hit/miss disagree for {o} {d}"
        );
        if let (Some(h), Some((t, mesh, tri))) = (got, want) {
            hits += 1;
            // Relative t agreement to 1e-4: the f32 intersection's error is a few ulps of the
            // coordinates (≤ 5, so ~1e-6 relative); ids may differ only on shared edges.
            assert!(
                (f64::from(h.t) - t).abs() <= 1e-4 * (1.0 + t),
                "t {} vs {t}",
                h.t
            );
            if (h.mesh, h.tri) == (mesh, tri) {
                agree += 1;
            }
            assert!((h.position - (o + d * h.t)).length() < 1e-4);
            assert!(a.occluded(o, d, f32::INFINITY));
            assert!(!a.occluded(o, d, h.t * 0.999 - 1e-4) || (h.mesh, h.tri) != (mesh, tri));
        }
    }
    assert!(hits > 1000);
    // Edge ties: at most a handful of 4000 rays land within rounding of a shared edge.
    assert!(agree >= hits - 10, "{agree} of {hits} ids agree");
}

/// Bug A: a `-0.0` direction component. The wrapper must hit; the raw obvhs CWBVH misses
/// (the second half shows this test really exercises the defect).
#[test]
fn test03_bug_a_negative_zero_direction() {
    let floor = test_util::quad(
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 0.0),
    );
    let meshes = vec![
        floor,
        test_util::uv_sphere(Vec3::new(0.0, 2.0, 0.0), 0.5, 8, 16, true),
    ];
    let a = accel(&meshes);
    let dirs = [
        Vec3::new(-0.0, -1.0, -0.0),
        Vec3::new(-0.0, -1.0, 0.0),
        Vec3::new(0.0, -1.0, -0.0),
    ];
    for d in dirs {
        let o = Vec3::new(0.1, 1.0, 0.2);
        let h = a
            .closest_hit(o, d, f32::INFINITY)
            .expect("bug A workaround: must hit the floor");
        assert!((h.t - 1.0).abs() < 1e-6);
        assert!(a.occluded(o, d, f32::INFINITY));
    }
    // Upstream behaviour (pins that the workaround is needed).
    let tris: Vec<Triangle> = meshes[0]
        .indices
        .iter()
        .map(|t| {
            let p = t.map(|i| Vec3A::from(meshes[0].positions[i as usize]));
            Triangle {
                v0: p[0],
                v1: p[1],
                v2: p[2],
            }
        })
        .collect();
    let bvh = build_cwbvh_from_tris(
        &tris,
        BvhBuildParams::medium_build(),
        &mut Duration::default(),
    );
    let ray = Ray::new_inf(Vec3A::new(0.1, 1.0, 0.2), Vec3A::new(-0.0, -1.0, -0.0));
    let mut hit = obvhs::ray::RayHit::none();
    let raw = bvh.ray_traverse(ray, &mut hit, |r, i| {
        tris[bvh.primitive_indices[i] as usize].intersect(r)
    });
    assert!(
        !raw,
        "obvhs no longer misses -0.0 rays: bug A fixed upstream?"
    );
}

/// Bug B: barycentrics against the closed form for a triangle of area 4 (obvhs' own
/// `compute_barycentric` is scaled by twice the area, 8).
#[test]
fn test04_bug_b_barycentrics() {
    let m = Mesh {
        name: "tri".into(),
        positions: vec![
            Vec3::ZERO,
            Vec3::new(4.0, 0.0, 0.0),
            Vec3::new(0.0, 2.0, 0.0),
        ],
        normals: vec![Vec3::X, Vec3::Y, Vec3::Z],
        indices: vec![[0, 1, 2]],
        material: 0,
        ..Default::default()
    };
    let a = accel(std::slice::from_ref(&m));
    let mut rng = Pcg64::seed_from_u64(4);
    for _ in 0..200 {
        let (x, y): (f32, f32) = (rng.random_range(0.0..4.0), rng.random_range(0.0..2.0));
        if x / 4.0 + y / 2.0 > 1.0 {
            continue;
        }
        let o = Vec3::new(x, y, 3.0);
        let h = a.closest_hit(o, Vec3::NEG_Z, f32::INFINITY).unwrap();
        // Closed form: the point (x, y) = u·v1 + v·v2, so u = x/4, v = y/2.
        assert!(
            (h.u - x / 4.0).abs() < 1e-6 && (h.v - y / 2.0).abs() < 1e-6,
            "{h:?}"
        );
        assert_eq!(h.geometric_normal, Vec3::Z);
        let w = 1.0 - h.u - h.v;
        let n = (Vec3::X * w + Vec3::Y * h.u + Vec3::Z * h.v).normalize();
        assert!((h.shading_normal - n).length() < 1e-6);
    }
    let tri = Triangle {
        v0: Vec3A::ZERO,
        v1: Vec3A::new(4.0, 0.0, 0.0),
        v2: Vec3A::new(0.0, 2.0, 0.0),
    };
    let raw = tri.compute_barycentric(&Ray::new_inf(Vec3A::new(1.0, 0.5, 3.0), Vec3A::NEG_Z));
    assert!(
        (raw.x - 0.25).abs() > 0.5,
        "obvhs barycentrics now unscaled: bug B fixed upstream?"
    );
}

/// Bug C: a triangle 3e-5 away (tiny-scale scene). The wrapper hits it; without the
/// rescaling workaround the fixed 1e-4 node tmin culls it.
#[test]
fn test05_bug_c_tiny_scene() {
    let s = 1e-5;
    let tri = test_util::quad(
        Vec3::new(-s, -s, -3.0 * s),
        Vec3::new(2.0 * s, 0.0, 0.0),
        Vec3::new(0.0, 2.0 * s, 0.0),
    );
    let meshes = vec![
        tri,
        test_util::uv_sphere(Vec3::new(0.0, 0.0, 5.0 * s), s, 6, 12, true),
    ];
    let o = Vec3::ZERO;
    let a = accel(&meshes);
    let h = a
        .closest_hit(o, Vec3::NEG_Z, f32::INFINITY)
        .expect("bug C workaround: must hit");
    assert!((h.t - 3e-5).abs() < 1e-11);
    assert!(a.occluded(o, Vec3::NEG_Z, f32::INFINITY));
    let h2 = a
        .closest_hit(o, Vec3::Z, f32::INFINITY)
        .expect("sphere at 4e-5");
    assert!((h2.t - 4e-5).abs() < 1e-10);
    // Through obvhs' traversal as it is: no rescaling, and the quad in the sphere's BVH (a
    // flat group of its own would be tested without a traversal).
    let raw = Accel::from_meshes(
        &meshes,
        AccelOptions {
            rescale: false,
            flat_groups: false,
            ..AccelOptions::default()
        },
    )
    .unwrap();
    assert!(
        raw.closest_hit(o, Vec3::NEG_Z, f32::INFINITY).is_none(),
        "bug C fixed upstream?"
    );
}

/// No speckles: AO rays spawned from real hits on a convex (flat-shaded) sphere never hit the
/// sphere again. Every sample is a Bernoulli trial whose true probability is exactly 0, so a
/// single occluded ray is a failure. Checked for a sphere scaled by 1e-3 and one at 1e4.
#[test]
fn test06_no_self_occlusion_at_extreme_scales() {
    for (center, radius) in [
        (Vec3::ZERO, 1e-3f32),
        (Vec3::new(1e4, -1e4, 1e4), 1.0),
        (Vec3::ZERO, 1.0),
    ] {
        let sphere = test_util::uv_sphere(center, radius, 24, 48, false);
        let a = accel(&[sphere]);
        let mut rng = Pcg64::seed_from_u64(6);
        let (mut rays, mut blocked, mut naive_blocked) = (0u32, 0u32, 0u32);
        while rays < 100_000 {
            let o = center + unit_dir(&mut rng) * (3.0 * radius);
            let target = center + unit_dir(&mut rng) * (0.9 * radius);
            let d = (target - o).normalize();
            let Some(h) = a.closest_hit(o, d, f32::INFINITY) else {
                continue;
            };
            let n = h.geometric_normal * -h.geometric_normal.dot(d).signum();
            // Cosine-weighted direction about the outward normal (Malley's method).
            let (r, phi) = (
                rng.random::<f32>().sqrt(),
                rng.random_range(0.0..std::f32::consts::TAU),
            );
            let local = Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - r * r).max(0.0).sqrt());
            let (t1, t2) = n.any_orthonormal_pair();
            let w = (t1 * local.x + t2 * local.y + n * local.z).normalize();
            if w.dot(n) <= 0.0 {
                continue;
            }
            rays += 1;
            if a.occluded(h.spawn_origin(w), w, f32::INFINITY) {
                blocked += 1;
            }
            if rays <= 2000 && a.occluded(h.position, w, f32::INFINITY) {
                naive_blocked += 1;
            }
        }
        assert_eq!(
            blocked, 0,
            "false self-occlusion at centre {center} radius {radius}"
        );
        // Sensitivity check: without the offset, rounding puts about half the origins below
        // the surface, so many of 2000 rays are blocked.
        assert!(
            naive_blocked > 100,
            "unoffset rays blocked only {naive_blocked} times"
        );
    }
}

#[test]
fn test07_segment_stops_short_and_bad_input() {
    let floor = test_util::quad(
        Vec3::new(-1.0, 0.0, -1.0),
        Vec3::new(0.0, 0.0, 2.0),
        Vec3::new(2.0, 0.0, 0.0),
    );
    let a = accel(&[floor]);
    // A segment ending exactly on the floor is not blocked by it; one passing through is.
    assert!(!a.segment_occluded(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.3, 0.0, 0.2)));
    assert!(a.segment_occluded(Vec3::new(0.0, 1.0, 0.0), Vec3::new(0.3, -0.1, 0.2)));
    assert!(a.closest_hit(Vec3::NAN, Vec3::Y, 1.0).is_none());
    assert!(!a.occluded(Vec3::ZERO, Vec3::NAN, 1.0));
    let empty = Accel::from_meshes(&[], AccelOptions::default()).unwrap();
    assert!(empty
        .closest_hit(Vec3::ZERO, Vec3::Y, f32::INFINITY)
        .is_none());
    empty.validate().unwrap();
    let bad = Mesh {
        positions: vec![Vec3::ZERO],
        indices: vec![[0, 1, 2]],
        ..Mesh::default()
    };
    assert!(Accel::from_meshes(&[bad], AccelOptions::default()).is_err());
    let nan = Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::NAN],
        indices: vec![[0, 1, 2]],
        ..Mesh::default()
    };
    assert!(Accel::from_meshes(&[nan], AccelOptions::default()).is_err());
}

/// Bug D: without padded primitive boxes, obvhs' quantised child bounds cut into a primitive
/// by up to half an ulp (the exact containment check of `Accel::validate` fails; obvhs' own
/// check allows 1e-5 and misses it). With padding every triangle is inside its leaf box.
#[test]
fn test08_bug_d_box_quantisation() {
    let sphere = test_util::uv_sphere(Vec3::ZERO, 1.0, 24, 48, false);
    let unpadded = std::panic::catch_unwind(|| {
        let options = AccelOptions {
            pad_boxes: false,
            ..AccelOptions::default()
        };
        Accel::from_meshes(std::slice::from_ref(&sphere), options)
            .unwrap()
            .validate()
    });
    assert!(!matches!(unpadded, Ok(Ok(()))), "bug D fixed upstream?");
    accel(std::slice::from_ref(&sphere)).validate().unwrap();
}

/// Bug C, the general case: in a unit-size scene (a 2×2 quad), a 1e-8 triangle hit from 2e-8
/// away is found: rescaling plus box padding keep every box on the way to a hit open past the
/// fixed 1e-4 node tmin (argument in `src/accel.rs`).
#[test]
fn test09_bug_c_tiny_feature_in_unit_scene() {
    let big = test_util::quad(
        Vec3::new(-1.0, -1.0, 0.0),
        Vec3::new(2.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
    );
    let s = 1e-8f32;
    let tiny = Mesh {
        name: "tiny".into(),
        positions: vec![
            Vec3::new(0.0, 0.0, s),
            Vec3::new(s, 0.0, s),
            Vec3::new(0.0, s, s),
        ],
        normals: vec![],
        indices: vec![[0, 1, 2]],
        material: 0,
        ..Default::default()
    };
    let a = accel(&[big, tiny]);
    let o = Vec3::new(0.2 * s, 0.2 * s, 3.0 * s);
    let h = a
        .closest_hit(o, Vec3::NEG_Z, f32::INFINITY)
        .expect("tiny triangle");
    assert_eq!(h.mesh, 1);
    assert!((h.t - 2.0 * s).abs() < 1e-12);
    assert!(a.occluded(o, Vec3::NEG_Z, 2.5 * s));
    // Hitting the big quad from 1e-8 above works too.
    let h = a
        .closest_hit(Vec3::new(0.5, 0.5, s), Vec3::NEG_Z, f32::INFINITY)
        .expect("quad");
    assert_eq!(h.mesh, 0);
}

/// The AVX2 node test (`prt_tracer::traverse`) accepts exactly the children obvhs' own node
/// test accepts, on every node of a CWBVH and rays of every kind — zero direction components
/// (infinite reciprocals, NaN slab distances), origins inside boxes, short and infinite
/// `tmax` — and a whole traversal proposes the same candidate slots in the same order, so hits
/// and images cannot depend on which test ran. On a CPU without AVX2 both sides are obvhs'
/// test and the comparison is vacuous (said on stderr).
#[test]
fn test10_wide_node_test_matches_obvhs() {
    use prt_tracer::traverse;
    if !traverse::wide_node_test() {
        eprintln!("no AVX2 on this CPU: the wide node test is not used, nothing to compare");
    }
    let (tris, bvh) = plain_bvh(&[
        test_util::uv_sphere(Vec3::ZERO, 1.0, 16, 32, true),
        test_util::open_box(Vec3::new(1.5, 0.0, 0.0), 1.0),
    ]);
    let mut rng = Pcg64::seed_from_u64(10);
    let (mut accepted, mut candidates) = (0u64, 0usize);
    for i in 0..20_000 {
        let o = unit_dir(&mut rng) * rng.random_range(0.0f32..4.0);
        // Aimed at a point of the objects' box, or (every other ray) in any direction.
        let target = Vec3::new(
            rng.random_range(-1.0..2.5),
            rng.random_range(-1.0..1.0),
            rng.random_range(-1.0..1.0),
        );
        let mut d = if i % 2 == 0 {
            unit_dir(&mut rng)
        } else {
            (target - o).normalize_or(Vec3::Z)
        };
        // Every third ray has an exactly zero component (+0.0: bug A is the caller's business).
        if i % 3 == 0 {
            d[i % 9 / 3] = 0.0;
        }
        let tmax = [f32::INFINITY, 2.5e-4, 0.7, 3.0][i % 4];
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d), 0.0, tmax);
        let oct_inv4 = bvh.new_traversal(ray.direction).oct_inv4;
        for node in &bvh.nodes {
            let want = node.intersect_ray(&ray, oct_inv4);
            assert_eq!(traverse::node_hits(node, &ray, oct_inv4), want, "ray {i}");
            accepted += u64::from(want.count_ones());
        }
        let (mut ours, mut theirs) = (Vec::new(), Vec::new());
        let record = |seen: &mut Vec<usize>, slot: usize, r: &Ray| {
            seen.push(slot);
            tris[bvh.primitive_indices[slot] as usize].intersect(r)
        };
        let mut shortened = ray;
        traverse::closest(&bvh, ray, |slot| {
            let t = record(&mut ours, slot, &shortened);
            shortened.tmax = shortened.tmax.min(t);
            t
        });
        bvh.ray_traverse(ray, &mut obvhs::ray::RayHit::none(), |r, slot| {
            record(&mut theirs, slot, r)
        });
        assert_eq!(ours, theirs, "closest-hit candidates of ray {i}");
        candidates += ours.len();
        let any_ours = traverse::any(&bvh, ray, |slot| {
            tris[bvh.primitive_indices[slot] as usize].intersect(&ray)
        });
        let any_theirs = !bvh.ray_traverse_miss(ray, |r, slot| {
            tris[bvh.primitive_indices[slot] as usize].intersect(r)
        });
        assert_eq!(any_ours, any_theirs, "any-hit of ray {i}");
    }
    // The rays reach deep into the tree (not a comparison of empty masks).
    assert!(
        accepted > 50_000 && candidates > 15_000,
        "{accepted} {candidates}"
    );
}

/// Packets (`Accel::closest_hits`, `traverse::closest_packet`) against single rays: without
/// shortening, every lane reaches exactly the candidates its single-ray traversal reaches (the
/// same node tests); with it, every lane's hit is the single ray's, bit for bit, on coherent
/// packets (a bake point's rays, a pixel's camera rays), incoherent ones, partial packets and
/// finite `tmax`.
#[test]
fn test11_packets_match_single_rays() {
    use prt_tracer::traverse::{self, PACKET};
    let meshes = spheres_in_a_box((24, 48), (12, 24));
    let a = accel(&meshes);
    let mut rng = Pcg64::seed_from_u64(11);
    let hits = packets_against_single_rays(&a, &mut rng, Vec3::ZERO, 1.2);
    assert!(hits > 20_000, "{hits} hits");

    // The node tests: candidates per lane without shortening.
    let (_, bvh) = plain_bvh(&meshes);
    let mut candidates = 0;
    for case in 0..2000 {
        let o = unit_dir(&mut rng) * rng.random_range(0.0f32..3.0);
        let axis = unit_dir(&mut rng);
        let spread = [0.05f32, 0.5, 3.0][case % 3];
        let rays: [Ray; PACKET] = std::array::from_fn(|_| {
            let mut d = (axis + unit_dir(&mut rng) * spread).normalize_or(Vec3::Z);
            if case % 5 == 0 {
                d.y = 0.0;
            }
            Ray::new(
                Vec3A::from(o),
                Vec3A::from(d),
                0.0,
                [f32::INFINITY, 1.0][case % 2],
            )
        });
        let active = if case % 7 == 0 { 0b1010_0110 } else { 0xff };
        let mut packet = vec![Vec::new(); PACKET];
        traverse::closest_packet(&bvh, &rays, active, |lanes, slot, _| {
            for (lane, seen) in packet.iter_mut().enumerate() {
                if lanes & (1 << lane) != 0 {
                    seen.push(slot);
                }
            }
        });
        for (lane, ray) in rays.iter().enumerate() {
            let mut single = Vec::new();
            if active & (1 << lane) != 0 {
                traverse::closest(&bvh, *ray, |slot| {
                    single.push(slot);
                    f32::INFINITY
                });
            }
            packet[lane].sort_unstable();
            single.sort_unstable();
            assert_eq!(packet[lane], single, "case {case}, lane {lane}");
            candidates += single.len();
        }
    }
    assert!(candidates > 20_000, "{candidates} candidates");
}

/// `Accel::closest_hits` against `Accel::closest_hit` ray by ray (the same `Hit`, bit for
/// bit) on 3000 packets around `centre` (bake-point cones, camera rays aimed within `reach`
/// of it, incoherent rays; full and partial packets; finite and infinite `tmax`). Returns the
/// number of hits.
fn packets_against_single_rays(a: &Accel, rng: &mut Pcg64, centre: Vec3, reach: f32) -> usize {
    use prt_tracer::traverse::PACKET;
    let mut hits = 0;
    for case in 0..3000 {
        let n = [PACKET, 3, 11, 64][case % 4];
        let (mut origins, mut dirs) = (Vec::new(), Vec::new());
        let from = centre + unit_dir(rng) * rng.random_range(0.0f32..2.5 * reach);
        let axis = unit_dir(rng);
        for _ in 0..n {
            let (o, d) = match case % 3 {
                // A bake point: one origin, directions in a narrow cone.
                0 => (from, (axis + unit_dir(rng) * 0.15).normalize()),
                // Camera rays: one origin, aimed at the objects.
                1 => {
                    let eye = centre + axis * 3.3 * reach;
                    let target = centre + unit_dir(rng) * rng.random_range(0.0f32..reach);
                    (eye, (target - eye).normalize())
                }
                // Incoherent.
                _ => (
                    centre + unit_dir(rng) * rng.random_range(0.0f32..2.5 * reach),
                    unit_dir(rng),
                ),
            };
            origins.push(o);
            dirs.push(d);
        }
        let tmax = [f32::INFINITY, 0.4 * reach, 1.6 * reach][case / 4 % 3];
        let mut got = vec![None; n];
        a.closest_hits(&origins, &dirs, tmax, &mut got);
        for i in 0..n {
            let want = a.closest_hit(origins[i], dirs[i], tmax);
            assert_eq!(got[i], want, "case {case}, ray {i} of {n}");
            hits += usize::from(want.is_some());
        }
    }
    hits
}

/// The scene of test 11 with a 2 mm sphere (at the returned centre) and a 2 km floor quad
/// beside it: three scale groups, the floor one of two triangles.
fn three_scale_groups() -> (Vec<Mesh>, Vec3) {
    let tiny = Vec3::new(1.3, 0.2, 0.1);
    let mut meshes = spheres_in_a_box((24, 48), (12, 24));
    meshes.push(test_util::uv_sphere(tiny, 1.0e-3, 12, 24, true));
    meshes.push(test_util::quad(
        Vec3::new(-1000.0, -1.6, -1000.0),
        Vec3::new(0.0, 0.0, 2000.0),
        Vec3::new(2000.0, 0.0, 0.0),
    ));
    (meshes, tiny)
}

/// Packets in a scene of three scale groups (a 2 mm sphere and a 2 km floor beside the unit
/// scene of test 11): each packet visits the groups its rays reach, nearest first, and every
/// lane's hit is still the single ray's, bit for bit, around the unit scene and around the
/// tiny sphere.
#[test]
fn test12_packets_across_scale_groups() {
    let (meshes, tiny) = three_scale_groups();
    let a = accel(&meshes);
    assert_eq!(a.group_count(), 3);
    let mut rng = Pcg64::seed_from_u64(12);
    let hits = packets_against_single_rays(&a, &mut rng, Vec3::ZERO, 1.2);
    assert!(hits > 20_000, "{hits} hits around the unit scene");
    let hits = packets_against_single_rays(&a, &mut rng, tiny, 2.0e-3);
    assert!(hits > 5_000, "{hits} hits around the tiny sphere");
}

/// The nearest-first traversal (`traverse::closest_sorted`, which `Accel` uses for single
/// closest-hit rays) against obvhs' order (`traverse::closest`): the same closest hit, `t` and
/// slot, with ties broken by the smaller slot, on rays from outside, from surface points
/// (where a ray passes many boxes near its origin) and with finite `tmax`; and it tests fewer
/// candidates in all (the point of it). The leaves-first any-hit traversal gives
/// `traverse::any`'s answer on the same rays. The float-box traversals (`BoxNodes`, which
/// `Accel` uses for single rays where the CPU has AVX2 and FMA) give the same closest hit and
/// the same any-hit answer.
#[test]
fn test13_own_traversals_find_the_same_hits() {
    use prt_tracer::traverse;
    let (tris, bvh) = plain_bvh(&[
        test_util::uv_sphere(Vec3::ZERO, 1.0, 24, 48, true),
        test_util::uv_sphere(Vec3::new(0.5, 0.3, 0.2), 0.7, 12, 24, true),
        test_util::open_box(Vec3::new(0.0, -0.5, 0.0), 2.0),
    ]);
    // The float-box nodes run where the CPU has AVX2 and FMA; elsewhere they are empty and
    // their rows of this test are skipped.
    let boxes = BoxNodes::of(&bvh);
    #[derive(Clone, Copy, PartialEq)]
    enum Walk {
        Obvhs,
        Sorted,
        Boxes,
    }
    let closest = |ray: Ray, walk: Walk| {
        let (mut best, mut tested) = ((f32::INFINITY, usize::MAX), 0usize);
        let test = |slot: usize| {
            tested += 1;
            let t = tris[bvh.primitive_indices[slot] as usize].intersect(&ray);
            if t < best.0 || (t == best.0 && t.is_finite() && slot < best.1) {
                best = (t, slot);
            }
            t
        };
        match walk {
            Walk::Obvhs => traverse::closest(&bvh, ray, test),
            Walk::Sorted => traverse::closest_sorted(&bvh, ray, test, |_| {}),
            Walk::Boxes => assert!(boxes.closest(&ray, test, |_| {}), "nodes decoded"),
        }
        (best, tested)
    };
    let mut rng = Pcg64::seed_from_u64(13);
    let (mut hits, mut tested_obvhs, mut tested_sorted) = (0, 0, 0);
    for i in 0..20_000 {
        let (o, d) = if i % 2 == 0 {
            (unit_dir(&mut rng) * 3.0, unit_dir(&mut rng))
        } else {
            // From a point just off a random triangle, into its front hemisphere.
            let t = &tris[rng.random_range(0..tris.len())];
            let n = Vec3::from((t.v1 - t.v0).cross(t.v2 - t.v0)).normalize_or(Vec3::Y);
            let c = Vec3::from(t.v0 + t.v1 + t.v2) / 3.0;
            let mut d = unit_dir(&mut rng);
            if d.dot(n) < 0.0 {
                d = -d;
            }
            (c + n * 1e-3, d)
        };
        let tmax = [f32::INFINITY, 0.3, 2.0][i % 3];
        let ray = Ray::new(Vec3A::from(o), Vec3A::from(d + Vec3::ZERO), 0.0, tmax);
        let (want, n_obvhs) = closest(ray, Walk::Obvhs);
        let (got, n_sorted) = closest(ray, Walk::Sorted);
        assert_eq!(got, want, "ray {i}");
        let test = |slot: usize| tris[bvh.primitive_indices[slot] as usize].intersect(&ray);
        let any = traverse::any(&bvh, ray, test);
        assert_eq!(
            traverse::any_leaves_first(&bvh, ray, test),
            any,
            "any-hit of ray {i}"
        );
        if !boxes.is_empty() {
            assert_eq!(closest(ray, Walk::Boxes).0, want, "float boxes, ray {i}");
            let leaf = |first: usize, count: usize| {
                (first..first + count).any(|slot| test(slot) < ray.tmax)
            };
            assert_eq!(
                boxes.any(&ray, leaf),
                Some(any),
                "float boxes, any-hit of ray {i}"
            );
        }
        hits += usize::from(want.0.is_finite());
        tested_obvhs += n_obvhs;
        tested_sorted += n_sorted;
    }
    assert!(hits > 5_000, "{hits} hits");
    eprintln!("candidates tested: obvhs order {tested_obvhs}, nearest first {tested_sorted}");
    assert!(
        tested_sorted < tested_obvhs,
        "{tested_sorted} vs {tested_obvhs}"
    );
}

/// Groups of a few triangles are tested triangle by triangle (`AccelOptions::direct_triangles`)
/// instead of through their BVH: the same answers, bit for bit, as the BVH gives, in the
/// three-group scene of test12 (whose 2 km floor quad is such a group): closest hits, packets
/// and occlusion, with infinite and finite `tmax`, from random points and from points spawned
/// off the floor and the spheres (where a wrong rule would show as self-hits).
#[test]
fn test14_small_groups_tested_directly_give_the_bvh_answers() {
    let (meshes, _) = three_scale_groups();
    let direct = accel(&meshes);
    let bvh = through_bvhs(&meshes);
    assert_eq!(direct.group_count(), 3);
    let mut rng = Pcg64::seed_from_u64(14);
    let (mut floor_hits, mut blocked) = (0, 0);
    for case in 0..20_000 {
        let mut o = unit_dir(&mut rng) * rng.random_range(0.0f32..3.0);
        let d = unit_dir(&mut rng);
        if case % 2 == 1 {
            // From a surface point: the hit of a ray towards the floor or the spheres.
            let towards = Vec3::new(d.x, -d.y.abs(), d.z);
            if let Some(h) = bvh.closest_hit(o, towards, f32::INFINITY) {
                floor_hits += usize::from(h.mesh == 4);
                o = h.spawn_origin(d);
            }
        }
        let tmax = [f32::INFINITY, 0.5, 5.0][case % 3];
        assert_eq!(
            direct.closest_hit(o, d, tmax),
            bvh.closest_hit(o, d, tmax),
            "case {case}"
        );
        let b = bvh.occluded(o, d, tmax);
        assert_eq!(direct.occluded(o, d, tmax), b, "case {case}");
        blocked += usize::from(b);
    }
    // Packets of camera-like rays towards the floor.
    let (eye, floor) = (Vec3::new(0.0, 1.0, 4.0), Vec3::new(0.0, -1.6, 0.0));
    same_camera_packets(&direct, &bvh, &mut rng, 500, (eye, 1.0), (floor, 3.0));
    eprintln!("{floor_hits} rays from the floor, {blocked} blocked");
    assert!(floor_hits > 2_000, "{floor_hits} rays from the floor");
    assert!(blocked > 2_000 && blocked < 18_000, "{blocked} blocked");
}

/// `cases` packets of eight camera-like rays, each from an eye within `eye.1` of `eye.0`
/// towards points within `target.1` of `target.0`: `a` and `b` return the same hits, bit for
/// bit.
fn same_camera_packets(
    a: &Accel,
    b: &Accel,
    rng: &mut Pcg64,
    cases: usize,
    eye: (Vec3, f32),
    target: (Vec3, f32),
) {
    for case in 0..cases {
        let from = eye.0 + unit_dir(rng) * eye.1;
        let dirs: Vec<Vec3> = (0..8)
            .map(|_| (target.0 + unit_dir(rng) * target.1 - from).normalize())
            .collect();
        let (mut got_a, mut got_b) = (vec![None; 8], vec![None; 8]);
        a.closest_hits(&[from; 8], &dirs, f32::INFINITY, &mut got_a);
        b.closest_hits(&[from; 8], &dirs, f32::INFINITY, &mut got_b);
        assert_eq!(got_a, got_b, "packet {case}");
    }
}

/// A flat group tested directly turns away rays that start outside its slab and leave it
/// before any triangle test (`Slab::turns_away`); that must never change an answer. A tilted
/// quad far from the origin (its f32 corners are not exactly coplanar) beside a small
/// sphere: rays from points spawned off the quad, from points on its plane and a few
/// rounding steps either side of it, in grazing and steep directions, with infinite and
/// finite `tmax`: closest hits and occlusion, bit for bit, as through the quad's BVH.
#[test]
fn test15_flat_groups_turn_away_rays_with_the_same_answers() {
    let corner = Vec3::new(300.0, -40.0, 120.0);
    let (eu, ev) = (Vec3::new(50.0, 3.0, -7.0), Vec3::new(-4.0, 2.0, 45.0));
    let n = eu.cross(ev).normalize();
    let mut sphere = test_util::uv_sphere(corner + 0.5 * (eu + ev) + n * 0.05, 0.04, 8, 16, true);
    sphere.material = 1;
    let meshes = vec![test_util::quad(corner, eu, ev), sphere];
    let direct = accel(&meshes);
    let bvh = through_bvhs(&meshes);
    assert_eq!(direct.group_count(), 2);
    let mut rng = Pcg64::seed_from_u64(15);
    let mut hits = 0;
    for case in 0..40_000 {
        let p = corner + eu * rng.random::<f32>() + ev * rng.random::<f32>();
        let mut d = unit_dir(&mut rng);
        if case % 4 == 0 {
            // Grazing: nearly in the plane, on either side.
            d = (d - n * d.dot(n) + n * rng.random_range(-1e-4f32..1e-4)).normalize();
        }
        let o = match case % 3 {
            0 => {
                let h = bvh.closest_hit(p + n * 10.0, -n, f32::INFINITY);
                h.map_or(p, |h| h.spawn_origin(d))
            }
            1 => p,
            _ => p + n * rng.random_range(-1e-4f32..1e-4) * p.abs().max_element() * 1e-3,
        };
        let tmax = [f32::INFINITY, 0.01, 80.0][case % 3];
        let hit = bvh.closest_hit(o, d, tmax);
        hits += usize::from(hit.is_some());
        assert_eq!(direct.closest_hit(o, d, tmax), hit, "case {case}");
        assert_eq!(
            direct.occluded(o, d, tmax),
            bvh.occluded(o, d, tmax),
            "case {case}"
        );
    }
    assert!(hits > 5_000, "{hits} hits");
}

/// Small flat meshes in groups of their own (`AccelOptions::flat_groups`, the default) give
/// the answers of the same scene in one BVH: a sphere resting on a floor quad beside a wall
/// quad, closest hits bit for bit (single rays and packets) and occlusion, from points on
/// the floor, the wall and the sphere (where rays leave a flat group's slab) and from
/// anywhere, with infinite and finite `tmax`. A scene of more than `FLAT_GROUPS` such quads
/// keeps them with the rest.
#[test]
fn test16_flat_groups_give_the_answers_of_one_bvh() {
    use prt_tracer::FLAT_GROUPS;
    let floor = test_util::quad(
        Vec3::new(-2.0, 0.0, -2.0),
        Vec3::new(0.0, 0.0, 4.0),
        Vec3::new(4.0, 0.0, 0.0),
    );
    let wall = test_util::quad(
        Vec3::new(-2.0, 0.0, -1.5),
        Vec3::new(4.0, 0.0, 0.0),
        Vec3::new(0.0, 2.0, 0.0),
    );
    let sphere = test_util::uv_sphere(Vec3::new(0.2, 0.5, 0.1), 0.5, 24, 48, true);
    let meshes = vec![floor.clone(), sphere.clone(), wall];
    let split = accel(&meshes);
    let joined = Accel::from_meshes(
        &meshes,
        AccelOptions {
            flat_groups: false,
            ..AccelOptions::default()
        },
    )
    .unwrap();
    assert_eq!((split.group_count(), joined.group_count()), (3, 1));
    split.validate().unwrap();
    let mut rng = Pcg64::seed_from_u64(16);
    let (mut from_flat, mut blocked, mut hits) = (0, 0, 0);
    for case in 0..30_000 {
        let mut o = Vec3::new(0.0, 1.0, 0.0) + unit_dir(&mut rng) * rng.random_range(0.0f32..3.0);
        let d = unit_dir(&mut rng);
        if case % 2 == 1 {
            // From a surface point: where a ray from `o` lands, spawned off it towards `d`.
            if let Some(h) = joined.closest_hit(o, unit_dir(&mut rng), f32::INFINITY) {
                from_flat += usize::from(h.mesh != 1);
                o = h.spawn_origin(d);
            }
        }
        let tmax = [f32::INFINITY, 0.5, 5.0][case % 3];
        let want = joined.closest_hit(o, d, tmax);
        assert_eq!(split.closest_hit(o, d, tmax), want, "case {case}");
        hits += usize::from(want.is_some());
        let b = joined.occluded(o, d, tmax);
        assert_eq!(split.occluded(o, d, tmax), b, "case {case}");
        blocked += usize::from(b);
    }
    let eye = Vec3::new(0.0, 1.5, 3.0);
    same_camera_packets(
        &split,
        &joined,
        &mut rng,
        2_000,
        (eye, 0.5),
        (Vec3::ZERO, 1.5),
    );
    eprintln!("{from_flat} rays from the quads, {hits} hits, {blocked} blocked");
    assert!(from_flat > 3_000, "{from_flat} rays from the quads");
    assert!(hits > 5_000 && hits < 28_000, "{hits} hits");
    assert!(blocked > 5_000 && blocked < 28_000, "{blocked} blocked");
    // More small flat meshes than FLAT_GROUPS: they stay with the sphere.
    let mut many = vec![sphere];
    many.extend(
        (0..=FLAT_GROUPS)
            .map(|k| test_util::transformed(&floor, |p| p + Vec3::new(0.0, -0.1 * k as f32, 0.0))),
    );
    assert_eq!(accel(&many).group_count(), 1);
}
