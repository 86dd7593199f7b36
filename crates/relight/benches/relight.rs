//! Full-order vs locally adaptive relighting per frame (diffuse + Phong specular) for orders
//! 2..=14 on an icosphere of 40 962 vertices with synthetic transfer (clamped cosine times a
//! visibility cap, `tests/common`), and the `memory_bound` figure: reading the transfer array
//! once (summing all floats) vs full-order diffuse shading.
//!
//! Before measuring, prints per order the adaptive statistics and the PSNR (8-bit sRGB, peak
//! 255) of the adaptive frame against the full-order one, as in Lee & Kim 2014, Table 6.2.

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

#[path = "../tests/common/mod.rs"]
mod common;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::DVec3;
use prt_relight::{
    AdaptiveInput, AdaptiveParams, Adjacency, DiffuseParams, FrameLighting, Lighting, PhongParams,
    Relighter, SpecularInput, SpecularLobe, Surface, TransferView, Viewer,
};
use rayon::prelude::*;
use std::hint::black_box;
use std::time::Instant;

const MAX_ORDER: usize = 14;
const SUBDIVISIONS: u32 = 6;

struct Bench {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    diffuse: Vec<f32>,
    visibility: Vec<f32>,
    adjacency: Adjacency,
    env: Vec<[f64; 3]>,
}

fn setup() -> Bench {
    let t = Instant::now();
    let mesh = prt_scene::test_util::icosphere(SUBDIVISIONS);
    let (positions, normals) = common::arrays(&mesh);
    let (diffuse, visibility) =
        common::synthetic_transfer(&mesh.positions, &mesh.normals, MAX_ORDER);
    let adjacency = Adjacency::from_triangles(positions.len(), &mesh.indices).unwrap();
    let env = common::sun_sky(MAX_ORDER, DVec3::new(0.5, 0.7, 0.5));
    eprintln!(
        "setup: {} vertices, order {MAX_ORDER} synthetic transfer in {:.1} s",
        positions.len(),
        t.elapsed().as_secs_f64()
    );
    Bench {
        positions,
        normals,
        diffuse,
        visibility,
        adjacency,
        env,
    }
}

struct Level<'a> {
    relighter: Relighter,
    lighting: Lighting,
    diffuse: Vec<f32>,
    visibility: Vec<f32>,
    b: &'a Bench,
}

impl Level<'_> {
    fn input(&self) -> AdaptiveInput<'_> {
        let order = self.relighter.order();
        AdaptiveInput {
            diffuse: Some((
                TransferView::new(order, 1, &self.diffuse).unwrap(),
                DiffuseParams::from_albedo([0.8, 0.7, 0.6]),
            )),
            specular: Some(SpecularInput {
                visibility: TransferView::new(order, 1, &self.visibility).unwrap(),
                surface: Surface {
                    positions: &self.b.positions,
                    normals: &self.b.normals,
                },
                viewer: Viewer::Eye([0.4, 0.8, 3.0]),
                lobe: SpecularLobe::Phong(PhongParams {
                    specular: [0.5; 3],
                    exponent: 40.0,
                }),
            }),
            adjacency: &self.b.adjacency,
        }
    }

    fn frame(&self) -> FrameLighting {
        self.relighter.frame_lighting(&self.lighting, true).unwrap()
    }

    fn full(&self) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let frame = self.frame();
        let i = self.input();
        let (t, p) = i.diffuse.unwrap();
        (
            self.relighter.diffuse(&t, &frame, &p).unwrap(),
            self.relighter
                .specular(&i.specular.unwrap(), &frame)
                .unwrap(),
        )
    }

    fn adaptive(&self) -> prt_relight::AdaptiveFrame {
        let frame = self.frame();
        self.relighter
            .adaptive(&self.input(), &frame, &AdaptiveParams::thesis())
            .unwrap()
    }
}

fn level(b: &Bench, order: usize) -> Level<'_> {
    let lighting = Lighting::from_rgb_coefficients(&b.env[..order * order], None).unwrap();
    Level {
        relighter: Relighter::new(order).unwrap(),
        lighting,
        diffuse: common::truncate_points(&b.diffuse, MAX_ORDER, order),
        visibility: common::truncate_points(&b.visibility, MAX_ORDER, order),
        b,
    }
}

fn srgb8(v: f32) -> f64 {
    let x = v.clamp(0.0, 1.0);
    let s = if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as f64
}

fn psnr_ldr(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let mse = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| (srgb8(x[c]) - srgb8(y[c])).powi(2)))
        .sum::<f64>()
        / (3 * a.len()) as f64;
    20.0 * (255.0 / mse.sqrt()).log10()
}

fn sum_radiance(d: &[[f32; 3]], s: &[[f32; 3]]) -> Vec<[f32; 3]> {
    d.iter()
        .zip(s)
        .map(|(x, y)| [x[0] + y[0], x[1] + y[1], x[2] + y[2]])
        .collect()
}

fn report(b: &Bench) {
    println!("order coeffs | filtered_out_diffuse filtered_out_specular | products_ratio_d products_ratio_s | adaptive_stats_s | psnr_ldr");
    for order in 2..=MAX_ORDER {
        let l = level(b, order);
        let (fd, fs) = l.full();
        let a = l.adaptive();
        let (d, s) = (
            a.stats.diffuse.clone().unwrap(),
            a.stats.specular.clone().unwrap(),
        );
        println!(
            "{order} {} | {:.3} {:.3} | {:.3} {:.3} | {:.4} | {:.2}",
            order * order,
            d.filtered_out_fraction,
            s.filtered_out_fraction,
            d.products as f64 / d.full_order_products as f64,
            s.products as f64 / s.full_order_products as f64,
            a.stats.seconds,
            psnr_ldr(
                &sum_radiance(&a.diffuse, &a.specular),
                &sum_radiance(&fd, &fs)
            )
        );
    }
}

fn benches(c: &mut Criterion) {
    let b = setup();
    report(&b);
    let mut g = c.benchmark_group("frame");
    g.sample_size(10);
    g.warm_up_time(std::time::Duration::from_millis(500));
    g.measurement_time(std::time::Duration::from_secs(3));
    for order in 2..=MAX_ORDER {
        let l = level(&b, order);
        g.bench_with_input(BenchmarkId::new("full", order), &l, |bench, l| {
            bench.iter(|| black_box(l.full()))
        });
        g.bench_with_input(BenchmarkId::new("adaptive", order), &l, |bench, l| {
            bench.iter(|| black_box(l.adaptive()))
        });
    }
    g.finish();

    // The per-frame light product matrices L̂_c = M(L_c) (included in every frame above).
    let mut g = c.benchmark_group("frame_lighting");
    g.sample_size(10);
    g.warm_up_time(std::time::Duration::from_millis(300));
    g.measurement_time(std::time::Duration::from_secs(1));
    for order in [6usize, 10, 14] {
        let l = level(&b, order);
        g.bench_with_input(BenchmarkId::from_parameter(order), &l, |bench, l| {
            bench.iter(|| black_box(l.relighter.frame_lighting(&l.lighting, true).unwrap()))
        });
    }
    g.finish();

    let mut g = c.benchmark_group("memory_bound");
    g.sample_size(20);
    g.warm_up_time(std::time::Duration::from_millis(500));
    g.measurement_time(std::time::Duration::from_secs(2));
    for order in [4usize, 8, 10, 14] {
        let l = level(&b, order);
        let frame = l.relighter.frame_lighting(&l.lighting, false).unwrap();
        g.bench_with_input(BenchmarkId::new("read_transfer", order), &l, |bench, l| {
            bench.iter(|| {
                let s: f32 = l
                    .diffuse
                    .par_chunks(256 * order * order)
                    .map(|c| c.iter().sum::<f32>())
                    .sum();
                black_box(s)
            })
        });
        g.bench_with_input(BenchmarkId::new("full_diffuse", order), &l, |bench, l| {
            let i = l.input();
            let (t, p) = i.diffuse.unwrap();
            bench.iter(|| black_box(l.relighter.diffuse(&t, &frame, &p).unwrap()))
        });
    }
    g.finish();
}

criterion_group!(relight, benches);
criterion_main!(relight);
