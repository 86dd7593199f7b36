//! Criterion benchmarks of the SH core (figures in the crate README).
#![allow(missing_docs)] // `criterion_group!` generates an undocumented public function.

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::{DMat3, DQuat, DVec3};
use prt_sh::{
    eval_low_f32, project_env, Basis, EnvMapping, GauntTensor, ImageRef, Rotation, LOW_BANDS,
};
use rand::{Rng, SeedableRng};
use rand_pcg::Pcg64;
use std::hint::black_box;

fn bench_eval(c: &mut Criterion) {
    let mut g = c.benchmark_group("eval");
    let mut rng = Pcg64::seed_from_u64(0);
    let dirs: Vec<DVec3> = (0..256)
        .map(|_| {
            DVec3::new(
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
                rng.random_range(-1.0..1.0),
            )
            .normalize()
        })
        .collect();
    for order in [3usize, 10, 30] {
        let basis = Basis::new(order).unwrap();
        let mut out = vec![0.0; order * order];
        let mut out32 = vec![0.0f32; order * order];
        g.bench_with_input(BenchmarkId::new("f64", order), &order, |b, _| {
            let mut k = 0;
            b.iter(|| {
                k = (k + 1) & 255;
                basis.eval_unchecked(black_box(dirs[k]), &mut out);
                black_box(&out);
            })
        });
        g.bench_with_input(BenchmarkId::new("f32", order), &order, |b, _| {
            let mut k = 0;
            b.iter(|| {
                k = (k + 1) & 255;
                basis.eval_f32_unchecked(black_box(dirs[k].as_vec3()), &mut out32);
                black_box(&out32);
            })
        });
    }
    // The first five bands: the f32 closed form against the recurrences.
    let basis5 = Basis::new(LOW_BANDS).unwrap();
    let mut out25 = [0.0f32; 25];
    g.bench_function("low_bands_recurrence_f32", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) & 255;
            basis5.eval_f32_unchecked(black_box(dirs[k].as_vec3()), &mut out25);
            black_box(&out25);
        })
    });
    g.bench_function("low_bands_closed_form_f32", |b| {
        let mut k = 0;
        b.iter(|| {
            k = (k + 1) & 255;
            eval_low_f32(black_box(dirs[k].as_vec3()), &mut out25);
            black_box(&out25);
        })
    });
    g.finish();
}

fn bench_rotation(c: &mut Criterion) {
    let mut g = c.benchmark_group("rotation");
    let r = DMat3::from_quat(DQuat::from_xyzw(0.3, -0.2, 0.5, 0.8).normalize());
    for order in [3usize, 10, 30] {
        let coeffs: Vec<f64> = (0..order * order).map(|i| (i as f64).sin()).collect();
        let mut out = vec![0.0; order * order];
        g.bench_with_input(BenchmarkId::new("build", order), &order, |b, &o| {
            b.iter(|| Rotation::new(o, black_box(r)).unwrap())
        });
        let rot = Rotation::new(order, r).unwrap();
        g.bench_with_input(BenchmarkId::new("apply", order), &order, |b, _| {
            b.iter(|| rot.apply_into(black_box(&coeffs), &mut out).unwrap())
        });
    }
    g.finish();
}

fn bench_projection(c: &mut Criterion) {
    let mut g = c.benchmark_group("project_latlong_1024x512");
    g.sample_size(10);
    let mut rng = Pcg64::seed_from_u64(1);
    let texels: Vec<[f32; 3]> = (0..1024 * 512)
        .map(|_| [rng.random(), rng.random(), rng.random()])
        .collect();
    let img = ImageRef {
        width: 1024,
        height: 512,
        texels: &texels,
    };
    for order in [3usize, 10] {
        g.bench_with_input(BenchmarkId::from_parameter(order), &order, |b, &o| {
            b.iter(|| project_env(black_box(img), EnvMapping::LatLong, o, 0.0).unwrap())
        });
    }
    g.finish();
}

fn bench_triple(c: &mut Criterion) {
    let mut g = c.benchmark_group("triple_product");
    for order in [3usize, 6, 10] {
        let t = GauntTensor::new(order).unwrap();
        let a: Vec<f64> = (0..order * order).map(|i| (i as f64 * 0.7).sin()).collect();
        let bb: Vec<f64> = (0..order * order).map(|i| (i as f64 * 1.3).cos()).collect();
        let mut out = vec![0.0; order * order];
        g.bench_with_input(BenchmarkId::from_parameter(order), &order, |b, _| {
            b.iter(|| {
                t.product_into(black_box(&a), black_box(&bb), &mut out)
                    .unwrap()
            })
        });
    }
    g.finish();
}

criterion_group!(
    benches,
    bench_eval,
    bench_rotation,
    bench_projection,
    bench_triple
);
criterion_main!(benches);
