//! Throughput of the tracer on the 37k-vertex Stanford bunny (`scenes/meshes/bunny.obj`):
//! incoherent closest-hit and occlusion rays per second (rays from a deterministic PCG stream,
//! origins on a sphere around the bunny aimed at random points inside its bounds, traced in
//! parallel over both cores with rayon), and camera samples per second of a full render.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use prt_scene::{Material, Mesh};
use prt_tracer::{test_util, Accel, AccelOptions, RenderSettings, Renderer};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use rayon::prelude::*;
use std::path::PathBuf;

fn bunny() -> Mesh {
    let path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../scenes/meshes/bunny.obj");
    let (models, _) = tobj::load_obj(&path, &tobj::GPU_LOAD_OPTIONS).expect("bunny.obj loads");
    let mesh = &models[0].mesh;
    Mesh {
        name: "bunny".into(),
        positions: mesh
            .positions
            .chunks(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect(),
        normals: Vec::new(),
        indices: mesh.indices.chunks(3).map(|t| [t[0], t[1], t[2]]).collect(),
        material: 0,
    }
}

fn rays(n: usize, center: Vec3, radius: f32) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg64::seed_from_u64(7);
    let dir = |rng: &mut Pcg64| {
        let z: f32 = rng.random_range(-1.0..1.0);
        let phi: f32 = rng.random_range(0.0..std::f32::consts::TAU);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * phi.cos(), r * phi.sin(), z)
    };
    (0..n)
        .map(|_| {
            let o = center + dir(&mut rng) * (2.0 * radius);
            let t = center + dir(&mut rng) * (0.5 * radius * rng.random::<f32>());
            (o, (t - o).normalize())
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let mesh = bunny();
    let (lo, hi) = mesh
        .positions
        .iter()
        .fold((Vec3::MAX, Vec3::MIN), |(lo, hi), &p| {
            (lo.min(p), hi.max(p))
        });
    let (center, radius) = ((lo + hi) * 0.5, (hi - lo).length() * 0.5);
    let accel = Accel::from_meshes(std::slice::from_ref(&mesh), AccelOptions::default()).unwrap();
    let batch = rays(1 << 16, center, radius);

    let mut g = c.benchmark_group("bunny_rays");
    g.throughput(Throughput::Elements(batch.len() as u64));
    g.bench_function("build_medium", |b| {
        b.iter(|| Accel::from_meshes(std::slice::from_ref(&mesh), AccelOptions::default()))
    });
    g.bench_function("closest_hit", |b| {
        b.iter(|| {
            batch
                .par_iter()
                .filter(|(o, d)| accel.closest_hit(*o, *d, f32::INFINITY).is_some())
                .count()
        })
    });
    g.bench_function("occluded", |b| {
        b.iter(|| {
            batch
                .par_iter()
                .filter(|(o, d)| accel.occluded(*o, *d, f32::INFINITY))
                .count()
        })
    });
    g.finish();

    // A full render: bunny on a floor, lat-long sky, 64×48 pixels, 4 spp, 1 bounce.
    let floor = test_util::quad(
        Vec3::new(-2.0 * radius, lo.y, -2.0 * radius),
        Vec3::new(0.0, 0.0, 4.0 * radius),
        Vec3::new(4.0 * radius, 0.0, 0.0),
    );
    let texels = (0..32 * 16)
        .map(|i| {
            let row = (i / 32) as f32 / 16.0;
            [1.5 - row, 1.2 - row * 0.8, 1.0 - row * 0.5]
        })
        .collect();
    let eye = center + Vec3::new(0.0, 0.3 * radius, 2.5 * radius);
    let scene = test_util::scene(
        test_util::camera(eye, center, 40.0, 64, 48),
        test_util::latlong_environment(32, 16, texels),
        vec![Material::Lambert {
            albedo: [0.7, 0.7, 0.7],
        }],
        vec![mesh, floor],
    );
    let settings = RenderSettings {
        spp: 4,
        bounces: 1,
        progress: false,
        ..RenderSettings::default()
    };
    let renderer = Renderer::new(&scene, settings).unwrap();
    let mut g = c.benchmark_group("render");
    g.throughput(Throughput::Elements(64 * 48 * 4));
    g.sample_size(10);
    g.bench_function("bunny_64x48_4spp_1bounce", |b| {
        b.iter(|| renderer.render().unwrap())
    });
    g.finish();
}

mod groups {
    #![allow(missing_docs)]
    use super::*;
    criterion_group!(benches, bench);
}
use groups::benches;
criterion_main!(benches);
