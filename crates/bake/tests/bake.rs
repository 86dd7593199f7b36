//! Bakes against closed forms (furnace, unshadowed transfer), the path tracer, and the
//! reproducibility rules (threads, shards).

use glam::{DVec3, Vec3};
use prt_bake::{bake, BakeSettings, PointKind};
use prt_bakefile::{encode, merge, ScalarType, TransferKind};
use prt_scene::test_util::icosphere;
use prt_scene::{Camera, Environment, Material, Mesh, Scene};
use prt_tracer::{Accel, Renderer, SurfacePoint};

fn white() -> Material {
    Material::Lambert { albedo: [1.0; 3] }
}

fn furnace_scene(meshes: Vec<Mesh>, material: Material) -> Scene {
    let cam = Camera::look_at(DVec3::new(0.0, 0.5, 4.0), DVec3::ZERO, 40.0, 16, 12);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("white", material);
    for mesh in meshes {
        scene.add_mesh(mesh, m);
    }
    scene
}

fn transformed(mut mesh: Mesh, scale: f32, translate: Vec3) -> Mesh {
    for p in &mut mesh.positions {
        *p = *p * scale + translate;
    }
    mesh
}

/// An open box (no top), faces facing inward, each face an `n×n` grid: a concave shape.
fn open_box(n: usize) -> Mesh {
    let mut mesh = Mesh {
        name: "open_box".into(),
        ..Mesh::default()
    };
    // (origin, u axis, v axis, inward normal) of the five faces of [-1,1]³ without +Y.
    let faces = [
        (
            Vec3::new(-1.0, -1.0, -1.0),
            Vec3::X * 2.0,
            Vec3::Z * 2.0,
            Vec3::Y,
        ),
        (
            Vec3::new(-1.0, -1.0, -1.0),
            Vec3::Y * 2.0,
            Vec3::X * 2.0,
            Vec3::Z,
        ),
        (
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::X * 2.0,
            Vec3::Y * 2.0,
            -Vec3::Z,
        ),
        (
            Vec3::new(-1.0, -1.0, -1.0),
            Vec3::Z * 2.0,
            Vec3::Y * 2.0,
            Vec3::X,
        ),
        (
            Vec3::new(1.0, -1.0, -1.0),
            Vec3::Y * 2.0,
            Vec3::Z * 2.0,
            -Vec3::X,
        ),
    ];
    for (o, u, v, nrm) in faces {
        let base = mesh.positions.len() as u32;
        for j in 0..=n {
            for i in 0..=n {
                mesh.positions
                    .push(o + u * (i as f32 / n as f32) + v * (j as f32 / n as f32));
                mesh.normals.push(nrm);
            }
        }
        let w = n as u32 + 1;
        for j in 0..n as u32 {
            for i in 0..n as u32 {
                let a = base + j * w + i;
                let (b, c, d) = (a + 1, a + w, a + w + 1);
                // Wind so that (v1−v0)×(v2−v0) points along the inward normal.
                let tri1 = [a, b, d];
                let g = (mesh.positions[b as usize] - mesh.positions[a as usize])
                    .cross(mesh.positions[d as usize] - mesh.positions[a as usize]);
                if g.dot(nrm) > 0.0 {
                    mesh.indices.push(tri1);
                    mesh.indices.push([a, d, c]);
                } else {
                    mesh.indices.push([a, d, b]);
                    mesh.indices.push([a, c, d]);
                }
            }
        }
    }
    mesh
}

/// Diffuse radiance of every vertex of object `o` (the library's f64 reference relighting).
fn relit(out: &prt_bake::BakeOutput, o: usize, albedo: f32) -> Vec<[f64; 3]> {
    prt_bake::relit_diffuse(&out.bake, o, [albedo; 3], None).unwrap()
}

#[test]
fn furnace_convex_sphere_relights_to_one_everywhere_even_tiny_and_far() {
    // A convex object sees the whole hemisphere at every vertex: the estimator (π/R) Σ y_0
    // equals π y_0 exactly, so radiance = (1/π) √(4π) · π y_0 = 1 up to f32 rounding. Any
    // self-occluded ray (a "speckle") would lower a vertex by ≥ 1/R = 1/256.
    for (scale, translate) in [
        (1.0f32, Vec3::ZERO),
        (1e-3, Vec3::ZERO),
        (1.0, Vec3::splat(1e4)),
    ] {
        let scene = furnace_scene(vec![transformed(icosphere(3), scale, translate)], white());
        let accel = Accel::build(&scene).unwrap();
        let settings = BakeSettings {
            order: Some(3),
            rays: 256,
            bounces: 0,
            ..BakeSettings::final_quality()
        };
        let out = bake(&scene, &accel, &settings).unwrap();
        for (v, rgb) in relit(&out, 0, 1.0).iter().enumerate() {
            assert!(
                (rgb[0] - 1.0).abs() < 1e-5,
                "scale {scale} translate {translate}: vertex {v} radiance {}",
                rgb[0]
            );
        }
    }
}

#[test]
fn convex_shadowed_equals_unshadowed_to_monte_carlo_accuracy() {
    let scene = furnace_scene(vec![icosphere(2)], white());
    let accel = Accel::build(&scene).unwrap();
    let rays = 1024;
    let settings = BakeSettings {
        order: Some(4),
        rays,
        bounces: 0,
        unshadowed: true,
        ..BakeSettings::final_quality()
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    let obj = &out.bake.objects[0];
    let sh = &obj
        .blocks
        .iter()
        .find(|b| b.kind == TransferKind::ShadowedDiffuse)
        .unwrap()
        .data;
    let un = &obj
        .blocks
        .iter()
        .find(|b| b.kind == TransferKind::UnshadowedDiffuse)
        .unwrap()
        .data;
    // Plain Monte Carlo bound: each term π y_i(ω) has |π y_i| ≤ π·1.2 for l < 4, so the
    // estimator's standard deviation is ≤ 3.8/√R ≈ 0.12; 4σ = 0.47 is what independent samples
    // would allow. The R2 sequence is stratified, so we also require the RMS over all entries
    // to be far below the i.i.d. figure (a sign that stratification works).
    let mut sq = 0.0;
    for (a, b) in sh.iter().zip(un) {
        assert!((a - b).abs() < 0.47, "{a} vs {b}");
        sq += f64::from(a - b).powi(2);
    }
    let rms = (sq / sh.len() as f64).sqrt();
    assert!(
        rms < 0.12 / 4.0,
        "RMS {rms} not better than a quarter of i.i.d. σ"
    );
    assert!(out
        .report
        .decisions
        .iter()
        .all(|d| !d.decision.contains("bounce")));
}

#[test]
fn furnace_concave_box_approaches_one_with_bounces_and_matches_path_tracer() {
    // Albedo 1 in a uniform environment of radiance 1: the true radiance is 1 everywhere for
    // unlimited bounces; with B bounces it is the probability that a path escapes within B+1
    // segments, increasing in B. Compare each step with the path tracer at the same bounce
    // count on the vertices (mean over vertices).
    let scene = furnace_scene(vec![open_box(6)], white());
    let accel = Accel::build(&scene).unwrap();
    // Compare on the vertices inside the faces: a vertex on an edge of the box lies on two
    // surfaces at once, where the path tracer's first ray (offset along one normal only) is
    // not defined the same way as the baker's (which skips a back face met at t ≈ 0).
    let verts = &scene.meshes[0];
    let interior: Vec<usize> = (0..verts.positions.len())
        .filter(|&i| {
            verts.positions[i]
                .to_array()
                .iter()
                .filter(|c| c.abs() > 0.999)
                .count()
                == 1
        })
        .collect();
    let points: Vec<SurfacePoint> = interior
        .iter()
        .map(|&i| SurfacePoint {
            position: verts.positions[i],
            normal: verts.normals[i],
            view_dir: verts.normals[i],
            material: white(),
        })
        .collect();
    let mut previous = 0.0;
    for b in [0u32, 1, 2, 4] {
        let settings = BakeSettings {
            order: Some(3),
            rays: 512,
            bounces: b,
            ..BakeSettings::final_quality()
        };
        let out = bake(&scene, &accel, &settings).unwrap();
        let radiance = relit(&out, 0, 1.0);
        let mean_bake =
            interior.iter().map(|&i| radiance[i][0]).sum::<f64>() / interior.len() as f64;
        let rs = prt_tracer::RenderSettings {
            spp: 512,
            bounces: b as i32,
            ..Default::default()
        };
        let tracer = Renderer::new(&scene, rs).unwrap();
        let pt = tracer.radiance_at_points(&points, 512).unwrap();
        let mean_pt = pt.iter().map(|c| f64::from(c.x)).sum::<f64>() / pt.len() as f64;
        // Tolerance: the path tracer's mean over 125 vertices × 512 paths of values in [0,1]
        // has σ ≤ 0.5/√(64k) ≈ 0.002; the bake's mean is stratified (smaller). Order 3 holds
        // the constant environment exactly, but bounce gathering interpolates transfer linearly
        // over 1/3-unit triangles (Sloan et al.'s vertex approximation), which we allow 2 %.
        assert!(
            (mean_bake - mean_pt).abs() < 0.02 + 4.0 * 0.002,
            "B={b}: bake {mean_bake:.4} vs path tracer {mean_pt:.4}"
        );
        assert!(
            mean_bake > previous,
            "B={b}: {mean_bake} must exceed {previous}"
        );
        if b > 0 {
            assert!(
                mean_bake - previous < previous + 1e-9,
                "B={b}: increments must shrink"
            );
        }
        assert!(mean_bake <= 1.0 + 1e-3);
        previous = mean_bake;
        eprintln!("open box, B = {b}: bake {mean_bake:.4}, path tracer {mean_pt:.4}");
    }
    // Each bounce adds less than the one before (the escape probability per segment is
    // about 0.2 here, so B = 4 is only ≈ 1 − 0.8⁵ ≈ 0.67 of the way).
}

#[test]
fn bit_identical_on_one_and_two_threads_and_after_shard_merge() {
    let mut scene = furnace_scene(vec![open_box(3)], white());
    let red = scene.add_material(
        "red",
        Material::Phong {
            albedo: [0.7, 0.2, 0.2],
            specular: [0.2; 3],
            exponent: 20.0,
        },
    );
    scene.add_mesh(
        transformed(icosphere(1), 0.4, Vec3::new(0.0, -0.5, 0.0)),
        red,
    );
    let accel = Accel::build(&scene).unwrap();
    let settings = BakeSettings {
        rays: 64,
        bounces: 1,
        ..BakeSettings::final_quality()
    };
    let run = |threads: usize, s: &BakeSettings| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| encode(&bake(&scene, &accel, s).unwrap().bake, ScalarType::F32).unwrap())
    };
    let one = run(1, &settings);
    let two = run(2, &settings);
    assert!(one == two, "1 and 2 threads differ");
    let shards: Vec<_> = (0..3)
        .map(|i| {
            let s = BakeSettings {
                shard: Some((i, 3)),
                ..settings.clone()
            };
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(2)
                .build()
                .unwrap();
            pool.install(|| bake(&scene, &accel, &s).unwrap().bake)
        })
        .collect();
    let merged = encode(&merge(&shards).unwrap(), ScalarType::F32).unwrap();
    assert!(
        merged == one,
        "merged shards differ from the unsharded bake"
    );
}

#[test]
fn decisions_name_what_was_skipped_and_why() {
    let mut scene = furnace_scene(
        vec![icosphere(1)],
        Material::Mirror {
            albedo: [0.2; 3],
            specular: [0.8; 3],
        },
    );
    let phong = scene.add_material(
        "shiny",
        Material::Phong {
            albedo: [0.5; 3],
            specular: [0.5; 3],
            exponent: 1e4,
        },
    );
    scene.add_mesh(
        transformed(icosphere(1), 0.5, Vec3::new(3.0, 0.0, 0.0)),
        phong,
    );
    let accel = Accel::build(&scene).unwrap();
    let settings = BakeSettings {
        rays: 16,
        bounces: 1,
        max_order: 8,
        ..BakeSettings::final_quality()
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    let text: Vec<String> = out
        .report
        .decisions
        .iter()
        .map(|d| format!("{:?} {} {}", d.object, d.decision, d.reason))
        .collect();
    let all = text.join("\n");
    assert!(all.contains("mirror"), "{all}");
    assert!(
        all.contains("capped at the maximum 8"),
        "near-delta Phong must say it was capped: {all}"
    );
    // Two separated spheres: neither sees the other... they might; the mirror sphere at the
    // origin and the small one at x = 3 see each other, so gathering is done for both.
    assert_eq!(out.bake.objects[1].order, 8);
    assert!(out.bake.objects[1]
        .blocks
        .iter()
        .any(|b| b.kind == TransferKind::Visibility));
    // A lone convex object never hits anything: no bounce gathering, and the log says so.
    let lone = furnace_scene(vec![icosphere(2)], white());
    let accel = Accel::build(&lone).unwrap();
    let out = bake(&lone, &accel, &settings).unwrap();
    assert!(out
        .report
        .decisions
        .iter()
        .any(|d| d.decision == "no bounce gathering"));
    assert_eq!(
        out.bake.objects[0].blocks[0].kind,
        TransferKind::ShadowedDiffuse
    );
}

#[test]
fn pixel_bake_has_one_point_per_pixel_and_furnace_value() {
    let scene = furnace_scene(vec![icosphere(3)], white());
    let accel = Accel::build(&scene).unwrap();
    let settings = BakeSettings {
        order: Some(3),
        rays: 64,
        bounces: 0,
        points: PointKind::Pixel,
        pixel_samples: 1,
        ..BakeSettings::final_quality()
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    let obj = &out.bake.objects[0];
    assert_eq!(obj.point_count, 16 * 12);
    assert_eq!(out.bake.meta.settings["pixel_samples"], 1);
    // The file says the albedo/π factor is not in the transfer, and the check below (which
    // applies it itself) agrees with the path tracer only if that is so.
    assert_eq!(out.bake.meta.settings["albedo_in_transfer"], false);
    let radiance = relit(&out, 0, 1.0);
    let covered: Vec<f64> = radiance
        .iter()
        .map(|c| c[0])
        .filter(|v| *v != 0.0)
        .collect();
    assert!(covered.len() > 10);
    // At a pixel hit the shading normal (interpolated) and the facet's plane differ by up to
    // α: cosine-distributed directions about the shading normal that dip below the facet's
    // plane go into the surface. That lune of angle α has projected solid angle
    // ∫₀^α∫₀^π sin²φ sin ψ dφ dψ = (π/2)(1 − cos α), i.e. a fraction (1 − cos α)/2 of the
    // cosine-weighted hemisphere; the R2 points resolve it to about 2/R.
    let mesh = &scene.meshes[0];
    let mut alpha: f32 = 0.0;
    for t in &mesh.indices {
        let [a, b, c] = t.map(|i| mesh.positions[i as usize]);
        let ng = (b - a).cross(c - a).normalize();
        for i in t {
            alpha = alpha.max(mesh.normals[*i as usize].dot(ng).clamp(-1.0, 1.0).acos());
        }
    }
    let allowed = (1.0 - f64::from(alpha).cos()) / 2.0 + 2.0 / 64.0;
    for v in covered {
        assert!(
            v <= 1.0 + 1e-5 && 1.0 - v <= allowed,
            "{v} (allowed deficit {allowed})"
        );
    }

    // With a footprint of 16 samples (64 rays each) a pixel's transfer is the mean over its
    // samples, 0 for those that see the background: relit value + background share (the
    // furnace's background is 1 too) must again be 1, within the mean of the samples' own lune
    // deficits, silhouettes included. A sample's α is the angle between its camera-facing
    // shading normal and its camera-facing facet normal: near a silhouette the interpolated
    // normal can face away from the camera, and turned towards it, it points into the surface
    // (α > 90°, a deficit near 1: such a sample is dark in the path tracer too).
    let k = 16;
    let settings = BakeSettings {
        rays: 64 * k,
        pixel_samples: k,
        ..settings
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    assert_eq!(out.bake.meta.settings["pixel_samples"], k);
    let fp = prt_tracer::points::pixel_footprints(&scene, &accel, settings.seed, k).unwrap();
    let radiance = relit(&out, 0, 1.0);
    let (mut partial, mut inward) = (0, 0);
    for (px, c) in radiance.iter().enumerate() {
        let hits: Vec<_> = fp.pixel(px).iter().filter_map(|s| s.hit).collect();
        if hits.is_empty() {
            assert_eq!(c[0], 0.0, "pixel {px} sees nothing but has transfer");
            continue;
        }
        partial += usize::from(hits.len() < k as usize);
        let deficit: f64 = hits
            .iter()
            .map(|(_, p)| {
                let cos = f64::from(p.normal.dot(p.offset_normal).clamp(-1.0, 1.0));
                inward += usize::from(cos < 0.0);
                (1.0 - cos) / 2.0 + 2.0 / 64.0
            })
            .sum::<f64>()
            / f64::from(k);
        let v = c[0] + (k as usize - hits.len()) as f64 / f64::from(k);
        assert!(
            v <= 1.0 + 1e-5 && 1.0 - v <= deficit,
            "pixel {px}: {v} with {}/{k} samples on the sphere (allowed deficit {deficit})",
            hits.len()
        );
    }
    eprintln!("{partial} silhouette pixels, {inward} samples with inward shading normals");
    assert!(partial > 4, "{partial} silhouette pixels");
}

#[test]
fn bad_settings_are_errors() {
    let scene = furnace_scene(vec![icosphere(1)], white());
    let accel = Accel::build(&scene).unwrap();
    for s in [
        BakeSettings {
            rays: 0,
            ..BakeSettings::preview()
        },
        BakeSettings {
            order: Some(0),
            ..BakeSettings::preview()
        },
        BakeSettings {
            shard: Some((3, 3)),
            ..BakeSettings::preview()
        },
        BakeSettings {
            memory_limit: 1024,
            bounces: 1,
            ..BakeSettings::preview()
        },
        BakeSettings {
            points: PointKind::Pixel,
            pixel_samples: 0,
            ..BakeSettings::preview()
        },
        BakeSettings {
            points: PointKind::Pixel,
            rays: 8,
            pixel_samples: 16,
            ..BakeSettings::preview()
        },
    ] {
        assert!(bake(&scene, &accel, &s).is_err());
    }
}

#[test]
fn ray_statistics_show_a_point_inside_geometry() {
    // A small sphere enclosed by a large one (interpenetrating or nested geometry, the way a
    // broken asset shows it). Exact expectations: every ray of the inner sphere's vertices hits
    // the back of the outer sphere (back-face fraction 1, and every point counts as started
    // inside geometry); the outer sphere is convex with outward normals, so its rays hit
    // nothing (0 and 0).
    let scene = furnace_scene(
        vec![
            icosphere(2),
            transformed(icosphere(1), 0.3, Vec3::new(0.1, 0.0, 0.0)),
        ],
        white(),
    );
    let accel = Accel::build(&scene).unwrap();
    let settings = BakeSettings {
        order: Some(2),
        rays: 64,
        bounces: 0,
        ..BakeSettings::final_quality()
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    let stats = &out.bake.meta.ray_stats;
    assert_eq!(stats.len(), 2);
    assert_eq!(stats[0].object, out.bake.objects[0].name);
    assert_eq!(stats[0].rays, 162 * 64);
    assert_eq!((stats[0].backface_hits, stats[0].inside_points), (0, 0));
    assert_eq!(stats[1].points, 42);
    assert_eq!(stats[1].backface_hits, stats[1].rays);
    assert_eq!(stats[1].inside_points, 42);
    assert_eq!(out.report.objects[1].inside_fraction, 1.0);
    assert_eq!(out.report.objects[0].backface_fraction, 0.0);
    // `prt inspect` shows them.
    let text = prt_bakefile::summary(&out.bake).to_string();
    assert!(
        text.contains("back-face hits 100.000 %, started inside geometry 100.000 % (42 points)"),
        "{text}"
    );
}
