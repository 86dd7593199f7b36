//! Benchmarks on the 37k-vertex Stanford bunny (`scenes/meshes/bunny.obj`).
//!
//! - `build/build_medium`: building [`Accel`] with the default options (`medium_build`).
//! - `rays/{coherent,incoherent,shadow}/{prt,obvhs}`: ray throughput of [`Accel`] next to plain
//!   obvhs (`build_cwbvh_from_tris` with `medium_build` over the same world-space triangles,
//!   reordered once into the BVH's primitive order) on exactly the same rays, traced in parallel
//!   over the batch with rayon:
//!   - `coherent`: closest hit of the camera rays through the pixel centres of a 256×256 pinhole
//!     grid (40° vertical field of view) looking at the bunny, in row-major order;
//!   - `incoherent`: closest hit of 65,536 random rays (a deterministic PCG stream; origins on a
//!     sphere around the bunny aimed at random points inside its bounds);
//!   - `shadow`: the incoherent rays as occlusion queries (any hit: [`Accel::occluded`] vs
//!     `CwBvh::ray_traverse_miss`), unbounded.
//!
//!   Every direction gets `+ 0.0` (obvhs bug A: a `-0.0` component misses), for both sides.
//!   Before timing, the setup asserts that both agree on hit/miss for all but at most 0.1 % of
//!   each batch (rays grazing triangle edges) and prints the disagreement counts. The prt side
//!   also builds its full [`prt_tracer::Hit`] record; the obvhs side only finds `t` and the id.
//! - `packets/{pixels,bake,incoherent}/{single,packet}`: [`Accel::closest_hit`] one ray at a
//!   time against [`Accel::closest_hits`] (packets of eight) on the same rays, in parallel over
//!   chunks of 1024 rays:
//!   - `pixels`: eight jittered camera rays per pixel of a 128×128 grid, a pixel's together;
//!   - `bake`: 1024 cosine-distributed rays from each of 128 bunny triangle centroids
//!     (offset along the face normal), ordered along a Morton curve over the 32×32 strata they come from, as the
//!     bake orders them;
//!   - `incoherent`: the incoherent rays above in packets (the worst case).
//! - `render/bunny_64x48_4spp_1bounce`: camera samples per second of a full render.

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use glam::Vec3;
use prt_scene::{Material, Mesh};
use prt_tracer::test_util::{self, PlainObvhs};
use prt_tracer::{Accel, AccelOptions, PinholeCamera, RenderSettings, Renderer};
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
        ..Default::default()
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

/// Camera rays through the pixel centres of a `size`×`size` pinhole grid, row by row.
fn camera_rays(eye: Vec3, target: Vec3, size: u32) -> Vec<(Vec3, Vec3)> {
    let cam = PinholeCamera::new(&test_util::camera(eye, target, 40.0, size, size))
        .expect("valid camera");
    (0..size)
        .flat_map(|y| (0..size).map(move |x| (x, y)))
        .map(|(x, y)| {
            let d = cam.direction(f64::from(x) + 0.5, f64::from(y) + 0.5);
            (eye, d)
        })
        .collect()
}

/// The three ray kinds of the `rays` group.
#[derive(Clone, Copy)]
enum Kind {
    Coherent,
    Incoherent,
    Shadow,
}

impl Kind {
    fn name(self) -> &'static str {
        match self {
            Kind::Coherent => "coherent",
            Kind::Incoherent => "incoherent",
            Kind::Shadow => "shadow",
        }
    }

    fn prt(self, accel: &Accel, o: Vec3, d: Vec3) -> bool {
        match self {
            Kind::Shadow => accel.occluded(o, d, f32::INFINITY),
            _ => accel.closest_hit(o, d, f32::INFINITY).is_some(),
        }
    }

    fn obvhs(self, plain: &PlainObvhs, o: Vec3, d: Vec3) -> bool {
        match self {
            Kind::Shadow => plain.occluded(o, d),
            _ => plain.closest_hit(o, d),
        }
    }
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
    let plain = PlainObvhs::new(&mesh);
    let eye = center + Vec3::new(0.0, 0.3 * radius, 2.5 * radius);
    // `+ 0.0` turns -0.0 components into +0.0 (obvhs bug A), for both sides alike.
    let no_neg_zero = |rays: Vec<(Vec3, Vec3)>| -> Vec<(Vec3, Vec3)> {
        rays.into_iter().map(|(o, d)| (o, d + Vec3::ZERO)).collect()
    };
    let coherent = no_neg_zero(camera_rays(eye, center, 256));
    let incoherent = no_neg_zero(rays(1 << 16, center, radius));
    let kinds = [
        (Kind::Coherent, &coherent),
        (Kind::Incoherent, &incoherent),
        (Kind::Shadow, &incoherent),
    ];

    // Equal work: both must agree on hit/miss except for a few edge rays.
    for (kind, batch) in kinds {
        let (hits, disagree) = batch
            .par_iter()
            .map(|&(o, d)| {
                let (a, b) = (kind.prt(&accel, o, d), kind.obvhs(&plain, o, d));
                (usize::from(a), usize::from(a != b))
            })
            .reduce(|| (0, 0), |x, y| (x.0 + y.0, x.1 + y.1));
        println!(
            "rays/{}: {} rays, {hits} prt hits, hit/miss disagreements prt vs obvhs: {disagree}",
            kind.name(),
            batch.len()
        );
        assert!(
            disagree * 1000 <= batch.len(),
            "{}: prt and obvhs disagree on {disagree} of {} rays",
            kind.name(),
            batch.len()
        );
    }

    let mut g = c.benchmark_group("build");
    g.bench_function("build_medium", |b| {
        b.iter(|| Accel::from_meshes(std::slice::from_ref(&mesh), AccelOptions::default()))
    });
    g.finish();

    let mut g = c.benchmark_group("rays");
    for (kind, batch) in kinds {
        g.throughput(Throughput::Elements(batch.len() as u64));
        g.bench_function(format!("{}/prt", kind.name()), |b| {
            b.iter(|| {
                batch
                    .par_iter()
                    .filter(|&&(o, d)| kind.prt(&accel, o, d))
                    .count()
            })
        });
        g.bench_function(format!("{}/obvhs", kind.name()), |b| {
            b.iter(|| {
                batch
                    .par_iter()
                    .filter(|&&(o, d)| kind.obvhs(&plain, o, d))
                    .count()
            })
        });
    }
    g.finish();

    packets(c, &accel, &mesh, eye, center, &incoherent);

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

/// Eight jittered camera rays per pixel of a `size`×`size` grid, a pixel's rays together.
fn pixel_rays(eye: Vec3, target: Vec3, size: u32) -> Vec<(Vec3, Vec3)> {
    let cam = PinholeCamera::new(&test_util::camera(eye, target, 40.0, size, size))
        .expect("valid camera");
    let mut rng = Pcg64::seed_from_u64(8);
    let mut out = Vec::new();
    for y in 0..size {
        for x in 0..size {
            for _ in 0..8 {
                let (jx, jy): (f64, f64) = (rng.random(), rng.random());
                let d = cam.direction(f64::from(x) + jx, f64::from(y) + jy);
                out.push((eye, d + Vec3::ZERO));
            }
        }
    }
    out
}

/// 1024 cosine-distributed rays from the centroids of `points` triangles of `mesh`, jittered in 32×32
/// strata of the unit square taken along a Morton curve.
fn bake_rays(mesh: &Mesh, points: usize) -> Vec<(Vec3, Vec3)> {
    let mut rng = Pcg64::seed_from_u64(9);
    let morton = |i: u32| -> (u32, u32) {
        let bits = |v: u32| (0..5).fold(0, |acc, b| acc | ((v >> (2 * b)) & 1) << b);
        (bits(i), bits(i >> 1))
    };
    let step = mesh.indices.len() / points;
    let mut out = Vec::new();
    for p in 0..points {
        let [a, b, c] = mesh.indices[p * step].map(|i| mesh.positions[i as usize]);
        let (pos, n) = ((a + b + c) / 3.0, (b - a).cross(c - a).normalize());
        let t = n.any_orthonormal_vector();
        let b = n.cross(t);
        let origin = pos + n * 1e-4;
        for i in 0..1024 {
            let (sx, sy) = morton(i);
            let u0 = (sx as f32 + rng.random::<f32>()) / 32.0;
            let u1 = (sy as f32 + rng.random::<f32>()) / 32.0;
            let (s, c) = (std::f32::consts::TAU * u1).sin_cos();
            let r = u0.sqrt();
            let d = (t * (r * c) + b * (r * s) + n * (1.0 - u0).max(0.0).sqrt()).normalize();
            out.push((origin, d + Vec3::ZERO));
        }
    }
    out
}

fn packets(
    c: &mut Criterion,
    accel: &Accel,
    mesh: &Mesh,
    eye: Vec3,
    center: Vec3,
    incoherent: &[(Vec3, Vec3)],
) {
    let batches = [
        ("pixels", pixel_rays(eye, center, 128)),
        ("bake", bake_rays(mesh, 128)),
        ("incoherent", incoherent.to_vec()),
    ];
    let mut g = c.benchmark_group("packets");
    for (name, batch) in &batches {
        let (origins, dirs): (Vec<Vec3>, Vec<Vec3>) = batch.iter().copied().unzip();
        // The same hits either way (tests/accel.rs checks it bit for bit; here: a count).
        let count = |packets: bool| {
            origins
                .par_chunks(1024)
                .zip(dirs.par_chunks(1024))
                .map(|(o, d)| {
                    if packets {
                        let mut out = vec![None; o.len()];
                        accel.closest_hits(o, d, f32::INFINITY, &mut out);
                        out.iter().filter(|h| h.is_some()).count()
                    } else {
                        o.iter()
                            .zip(d)
                            .filter(|&(&o, &d)| accel.closest_hit(o, d, f32::INFINITY).is_some())
                            .count()
                    }
                })
                .sum::<usize>()
        };
        assert_eq!(count(false), count(true), "{name}");
        g.throughput(Throughput::Elements(batch.len() as u64));
        g.bench_function(format!("{name}/single"), |b| b.iter(|| count(false)));
        g.bench_function(format!("{name}/packet"), |b| b.iter(|| count(true)));
    }
    g.finish();
}

mod groups {
    #![allow(missing_docs)]
    use super::*;
    criterion_group!(benches, bench);
}
use groups::benches;
criterion_main!(benches);
