//! SHRM prefiltering cost (Ramamoorthi's thesis §5.6, Tables 5.4–5.5): the frequency-space
//! prefilter of a whole table ([`Shrm::prefilter`], at the order, twist and grid the SHRM path
//! chooses for each lobe) against the angular-space brute force of one table entry
//! ([`brute_force`]: the environment times the lobe integrated directly, here on the
//! reflection frame's product rule with a 512 × 256 lat-long texel lookup per node). The
//! brute force of a whole table is the per-entry time times `rows · cols · elevations ·
//! (2M + 1)` entries (one per Fourier term it has to resolve): printed, not run (hours).
//!
//! The lookup ([`Shrm::lookup`]) is timed on the table the path builds for gold at roughness
//! 0.4 under the courtyard map (order 45, twist 7, 136 × 270 texels, 16 elevations, one
//! combined component, 106 MB): a sphere's normals seen in raster order (as image formation
//! looks up: neighbours share texels) and the same points shuffled.
//!
//! `cargo bench -p prt-scene-relight --bench shrm`

// criterion_group! generates an undocumented public function.
#![allow(missing_docs)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion};
use glam::{DMat3, DVec3};
use prt_scene_relight::shrm::{brute_force, lobe_spectrum, LobeSpectrum, Shrm, ShrmLobe};
use std::hint::black_box;
use std::time::Instant;

/// As `prt_scene_relight`'s SHRM path: lobe tolerance, elevations, rows per band.
const TOLERANCE: f64 = 0.01;
const ELEVATIONS: usize = 16;
const ROWS_PER_BAND: usize = 3;

/// A synthetic lighting of `order` bands with a 1/(l + 1) spectrum (the cost does not depend
/// on the content).
fn lighting(order: usize) -> Vec<[f64; 3]> {
    (0..order * order)
        .map(|i| {
            let l = (i as f64).sqrt().floor();
            let s = 1.0 / (l + 1.0);
            let x = i as f64;
            [
                s * (0.7 * x).sin(),
                s * (1.3 * x).cos(),
                s * (0.4 * x + 1.0).sin(),
            ]
        })
        .collect()
}

fn bench(c: &mut Criterion) {
    let (w, h) = (512usize, 256usize);
    let image: Vec<[f64; 3]> = (0..w * h)
        .map(|i| {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            [
                1.0 + (0.05 * x).sin() * (0.07 * y).cos(),
                1.0,
                0.5 + 0.001 * x,
            ]
        })
        .collect();
    let radiance = move |d: DVec3| -> [f64; 3] {
        let u = (d.y.atan2(d.x) / std::f64::consts::TAU + 0.5) * w as f64;
        let v = d.z.clamp(-1.0, 1.0).acos() / std::f64::consts::PI * h as f64;
        image[(v as usize).min(h - 1) * w + (u as usize).min(w - 1)]
    };
    let mut group = c.benchmark_group("shrm_prefilter");
    group.sample_size(10);
    for roughness in [0.8f32, 0.6, 0.4] {
        let lobe = ShrmLobe::Pbr { roughness };
        let t = Instant::now();
        let full = lobe_spectrum(lobe, 64, 8, ELEVATIONS).expect("spectrum");
        let spectrum_s = t.elapsed().as_secs_f64();
        let power = LobeSpectrum::band_power(&lighting(64), 64);
        let (order, twist) = full.choose(TOLERANCE, &power);
        let spec = full.truncated(order, twist);
        let rows = ROWS_PER_BAND * order + 1;
        let cols = 2 * (rows - 1);
        let env = lighting(order);
        let t = Instant::now();
        black_box(brute_force(lobe, &radiance, DMat3::IDENTITY, 0.6, 0.3));
        let entry_s = t.elapsed().as_secs_f64();
        let entries = rows * cols * ELEVATIONS * (2 * twist + 1);
        println!(
            "roughness {roughness}: order {order}, twist {twist}, {rows} × {cols} × {ELEVATIONS} table; lobe spectrum {spectrum_s:.2} s; brute force {entry_s:.3} s per entry × {entries} entries ≈ {:.0} s",
            entry_s * entries as f64
        );
        let id = BenchmarkId::new("frequency_space", roughness);
        group.bench_with_input(id, &roughness, |b, _| {
            b.iter(|| black_box(Shrm::prefilter(&spec, &env, rows, cols).expect("prefilter")));
        });
        let id = BenchmarkId::new("brute_force_entry", roughness);
        group.bench_with_input(id, &roughness, |b, _| {
            b.iter(|| black_box(brute_force(lobe, &radiance, DMat3::IDENTITY, 0.6, 0.3)));
        });
    }
    group.finish();
}

/// Points of a unit sphere seen from `(0, 0, 3)` on a `side × side` raster: normals and the
/// direction to the eye.
fn sphere_points(side: usize) -> Vec<(DVec3, DVec3)> {
    let eye = DVec3::new(0.0, 0.0, 3.0);
    let mut out = Vec::new();
    for y in 0..side {
        for x in 0..side {
            let (u, v) = (
                2.0 * (x as f64 + 0.5) / side as f64 - 1.0,
                2.0 * (y as f64 + 0.5) / side as f64 - 1.0,
            );
            let r2 = u * u + v * v;
            if r2 < 1.0 {
                let n = DVec3::new(u, v, (1.0 - r2).sqrt());
                out.push((n, (eye - n).normalize()));
            }
        }
    }
    out
}

fn lookup(c: &mut Criterion) {
    let (order, twist, rows) = match std::env::var("SHRM_BENCH_SMALL") {
        Ok(_) => (10, 7, 31),
        Err(_) => (45, 7, 136),
    };
    let full = lobe_spectrum(ShrmLobe::Pbr { roughness: 0.4 }, order, twist, ELEVATIONS)
        .expect("spectrum");
    let table = Shrm::prefilter(&full, &lighting(order), rows, 2 * (rows - 1))
        .expect("prefilter")
        .combined([[1.0; 3], [0.5; 3]]);
    // About the 200 000 lookups of a 320 × 240 image of the bunny (9 per object pixel).
    let raster = sphere_points(500);
    let mut shuffled = raster.clone();
    let mut state = 0x2545_f491_4f6c_dd1du64;
    for i in (1..shuffled.len()).rev() {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        shuffled.swap(i, (state % (i as u64 + 1)) as usize);
    }
    let mut group = c.benchmark_group("shrm_lookup");
    group.sample_size(10);
    for (name, points) in [("raster", &raster), ("shuffled", &shuffled)] {
        group.throughput(criterion::Throughput::Elements(points.len() as u64));
        group.bench_function(name, |b| {
            b.iter(|| {
                let mut sum = 0.0;
                for (n, wo) in points {
                    sum += table.lookup(*n, *wo, None)[0][0];
                }
                black_box(sum)
            });
        });
    }
    group.finish();
}

criterion_group!(benches, bench, lookup);
criterion_main!(benches);
