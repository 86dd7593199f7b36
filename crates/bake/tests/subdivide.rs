//! Probe-driven adaptive subdivision (`prt_bake::subdivide`): a floor under a low plate is
//! refined along the plate's shadow and nowhere else, the plate (which sees the whole sky) not
//! at all; the refinement is the same on any thread count; and the subdivided bake's transfer
//! is exactly a full-ray bake of the refined meshes (the cheap probes decide, they are never
//! baked).

use glam::{DVec3, Vec3};
use prt_bake::subdivide::{refine, SubdivideOptions};
use prt_bake::{bake, BakeSettings};
use prt_bakefile::TransferKind;
use prt_scene::{Camera, Environment, Material, Mesh, Scene};
use prt_tracer::Accel;

/// A square grid of `n × n` cells over `[-h, h]²` in the plane `y`, facing `up` (±Y).
fn grid(name: &str, n: u32, h: f32, y: f32, up: bool) -> Mesh {
    let mut mesh = Mesh {
        name: name.into(),
        ..Mesh::default()
    };
    for j in 0..=n {
        for i in 0..=n {
            let at = |k: u32| -h + 2.0 * h * k as f32 / n as f32;
            mesh.positions.push(Vec3::new(at(i), y, at(j)));
            mesh.normals.push(if up { Vec3::Y } else { Vec3::NEG_Y });
        }
    }
    let v = |i: u32, j: u32| j * (n + 1) + i;
    for j in 0..n {
        for i in 0..n {
            let (a, b, c, d) = (v(i, j), v(i + 1, j), v(i + 1, j + 1), v(i, j + 1));
            // Counter-clockwise seen from +Y is (a, d, c): x × z points to −Y.
            if up {
                mesh.indices.extend([[a, d, c], [a, c, b]]);
            } else {
                mesh.indices.extend([[a, c, d], [a, b, c]]);
            }
        }
    }
    mesh
}

/// An 8 × 8-cell floor over `[-4, 4]²` (vertices at the integers) and a 1.4-wide plate 0.1
/// above its centre, facing up (its own transfer sees the whole sky).
fn plate_scene() -> Scene {
    let cam = Camera::look_at(DVec3::new(0.0, 3.0, 5.0), DVec3::ZERO, 40.0, 16, 12);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("white", Material::Lambert { albedo: [0.5; 3] });
    scene.add_mesh(grid("floor", 8, 4.0, 0.0, true), m);
    scene.add_mesh(grid("plate", 2, 0.7, 0.1, true), m);
    scene
}

fn settings() -> BakeSettings {
    BakeSettings {
        order: Some(3),
        rays: 256,
        bounces: 0,
        ..BakeSettings::final_quality()
    }
}

fn options() -> SubdivideOptions {
    SubdivideOptions {
        max_levels: 3,
        probe_rays: Some(64),
        ..SubdivideOptions::default()
    }
}

#[test]
fn probes_refine_along_the_shadow_and_nowhere_else() {
    let scene = plate_scene();
    let accel = Accel::build(&scene).unwrap();
    let (plans, _) = prt_bake::plan::plan(&scene, &settings());
    let (refined, report) = refine(&scene, &accel, &settings(), &plans, &options()).unwrap();
    let floor = &refined.meshes[0];
    assert!(
        floor.positions.len() > 81 + 8,
        "the floor under the plate was hardly refined: {report:?}"
    );
    // Where the floor's transfer varies: within reach of the plate. A floor point at
    // horizontal distance d ≥ 2 from the plate's centre sees the plate (area 1.96, 0.1 up)
    // under a cosine-weighted solid angle of about A·(0.1/d)²/(π d²) ≤ 4·10⁻⁴ of the
    // hemisphere: 250× below the 0.1 relative error target, so no edge whose midpoint and
    // ends all lie past 2 is split. A split edge touching the shadow region has its midpoint at
    // most half a cell (0.5) out, so every new vertex lies within 2.5 of the centre (the
    // Chebyshev distance, which bounds the Euclidean one from below).
    for p in &floor.positions[81..] {
        assert!(
            p.x.abs().max(p.z.abs()) <= 2.5,
            "a vertex at {p} was added where the floor's transfer is flat"
        );
    }
    // Refinement is local: the floor's triangles with every corner at |x| or |z| ≥ 3 (the
    // outer ring of 28 cells' 56, and 2 more whose diagonals cut inner corners) are all kept.
    let far = |t: &[u32; 3]| {
        t.iter().all(|&i| {
            let p = floor.positions[i as usize];
            p.x.abs().max(p.z.abs()) >= 3.0
        })
    };
    assert_eq!(
        scene.meshes[0].indices.iter().filter(|t| far(t)).count(),
        58
    );
    assert_eq!(floor.indices.iter().filter(|t| far(t)).count(), 58);
    // The plate sees the whole sky from every point: the probes agree exactly, nothing splits.
    assert_eq!(refined.meshes[1].positions.len(), 9, "{report:?}");
    assert!(report[1].splits.is_empty());
    // The source mesh's vertices are probed, then the first level probes every edge midpoint
    // and triangle centroid (8·9·2 + 64 edges, 128 triangles); each later level only what the
    // previous one made, fewer than the whole mesh it probes.
    let r = &report[0];
    assert_eq!(r.probes[..2], [81, 208 + 128]);
    let (mut edges, mut tris) = (208, 128);
    for (level, &split) in r.splits.iter().enumerate().take(r.probes.len() - 2) {
        // After `split` edge splits the mesh has more edges and triangles than before: each
        // split adds a vertex, and (Euler, fixed boundary topology) 3 edges and 2 triangles
        // per interior vertex at most; the level's probes stay below the new totals.
        edges += 3 * split;
        tris += 2 * split;
        assert!(r.probes[level + 2] < edges + tris, "{r:?}");
    }
    // A probe traces its directions above the horizon: about half of them (a flat floor: the
    // same ones everywhere).
    let directions = r.probes.iter().sum::<usize>() as u64 * u64::from(r.probe_rays);
    assert!(
        r.rays > directions * 2 / 5 && r.rays < directions * 3 / 5,
        "{r:?}"
    );
}

#[test]
fn the_refinement_is_the_same_on_any_thread_count() {
    let scene = plate_scene();
    let accel = Accel::build(&scene).unwrap();
    let (plans, _) = prt_bake::plan::plan(&scene, &settings());
    let run = |threads| {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap();
        pool.install(|| refine(&scene, &accel, &settings(), &plans, &options()).unwrap())
    };
    let (a, b) = (run(1), run(3));
    for (ma, mb) in a.0.meshes.iter().zip(&b.0.meshes) {
        assert_eq!(ma.positions, mb.positions);
        assert_eq!(ma.normals, mb.normals);
        assert_eq!(ma.indices, mb.indices);
    }
}

#[test]
fn every_final_vertex_is_baked_with_the_full_rays() {
    let scene = plate_scene();
    let accel = Accel::build(&scene).unwrap();
    let sub = BakeSettings {
        subdivide: Some(options()),
        ..settings()
    };
    let out = bake(&scene, &accel, &sub).unwrap();
    // The same refinement, then a plain bake of the refined scene: by construction every
    // vertex of it gets `rays` rays with its own key, and the subdivided bake must be that
    // bake exactly (not the probes' transfer at the new vertices).
    let (plans, _) = prt_bake::plan::plan(&scene, &settings());
    let (refined, report) = refine(&scene, &accel, &settings(), &plans, &options()).unwrap();
    let plain = bake(&refined, &Accel::build(&refined).unwrap(), &settings()).unwrap();
    assert_eq!(out.bake.objects.len(), plain.bake.objects.len());
    for (o, p) in out.bake.objects.iter().zip(&plain.bake.objects) {
        assert_eq!(o.point_count, p.point_count);
        let block = |b: &prt_bakefile::ObjectBake| {
            b.blocks
                .iter()
                .find(|k| k.kind == TransferKind::ShadowedDiffuse)
                .unwrap()
                .data
                .clone()
        };
        assert!(block(o) == block(p), "{}: transfer differs", o.name);
    }
    // Rays: the full bake's plus the probes', nothing else.
    let probe_rays: u64 = report.iter().map(|r| r.rays).sum();
    assert_eq!(
        out.report.rays_traced,
        plain.report.rays_traced + probe_rays
    );
    let points: u64 = plain.bake.objects.iter().map(|o| o.point_count).sum();
    assert_eq!(plain.report.rays_traced, points * 256);
}
