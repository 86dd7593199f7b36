//! Traces a file of rays through [`Accel`] and reports the rays per second, for comparing the
//! tracer with another one on exactly the same rays (`tools/ray_peer_probe.py` runs it next to
//! Mitsuba 3's Embree-backed `ray_intersect_preliminary` and `ray_test`).
//!
//! ```text
//! cargo run --release -p prt-tracer --example trace_rays -- MESH.obj RAYS.f32 THREADS REPEATS HITS.u8
//! ```
//!
//! `RAYS.f32` holds little-endian `f32`s, six per ray: origin x, y, z, then direction x, y, z
//! (unit length). Each ray is traced with `tmax = ∞`, `REPEATS` times per kind over the whole
//! batch in parallel on `THREADS` threads (rayon), by:
//! - `closest`: [`Accel::closest_hit`], which also builds the full hit record;
//! - `closest_packets`: [`Accel::closest_hits`] on packets of [`PACKET`] consecutive rays, as
//!   the renderer traces a pixel's camera rays (the same answers);
//! - `occluded`: [`Accel::occluded`];
//! - `obvhs_closest`, `obvhs_occluded`: plain obvhs on the same triangles
//!   ([`test_util::PlainObvhs`]: its own traversals and f32 triangle test), the library
//!   `Accel` is built on.
//!
//! One JSON line per kind goes to stdout with the fastest repeat's seconds and the rays per
//! second; `HITS.u8` receives one byte per ray and kind, in that order (1 hit, 0 miss), so
//! that the caller can check that the tracers answered the same queries.

use glam::{DMat4, Vec3};
use prt_tracer::test_util::{self, PlainObvhs};
use prt_tracer::{Accel, AccelOptions};
use rayon::prelude::*;
use std::path::Path;
use std::process::ExitCode;
use std::time::Instant;

/// The command line, parsed.
struct Args {
    mesh: String,
    rays: String,
    threads: usize,
    repeats: u32,
    hits: String,
}

fn parse_args() -> Result<Args, String> {
    let a: Vec<String> = std::env::args().skip(1).collect();
    let [mesh, rays, threads, repeats, hits] = a.as_slice() else {
        return Err("usage: trace_rays MESH.obj RAYS.f32 THREADS REPEATS HITS.u8".into());
    };
    let number = |s: &str, what: &str| {
        s.parse::<u32>()
            .ok()
            .filter(|&n| n > 0)
            .ok_or(format!("{what} must be a positive integer, not {s:?}"))
    };
    Ok(Args {
        mesh: mesh.clone(),
        rays: rays.clone(),
        threads: number(threads, "THREADS")? as usize,
        repeats: number(repeats, "REPEATS")?,
        hits: hits.clone(),
    })
}

/// The rays of `path`: `(origin, direction)` pairs.
fn read_rays(path: &str) -> Result<Vec<(Vec3, Vec3)>, String> {
    let bytes = std::fs::read(path).map_err(|e| format!("{path}: {e}"))?;
    if bytes.is_empty() || bytes.len() % 24 != 0 {
        return Err(format!(
            "{path}: {} bytes is not a whole, non-zero number of rays (24 bytes each)",
            bytes.len()
        ));
    }
    let f: Vec<f32> = bytes
        .chunks_exact(4)
        .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]]))
        .collect();
    let rays: Vec<(Vec3, Vec3)> = f
        .chunks_exact(6)
        .map(|r| (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5])))
        .collect();
    if let Some(i) = rays
        .iter()
        .position(|(o, d)| !(o.is_finite() && d.is_finite() && d.length_squared() > 0.0))
    {
        return Err(format!(
            "{path}: ray {i} is not finite or has a zero direction"
        ));
    }
    Ok(rays)
}

/// Rays per packet of the `closest_packets` kind (the renderer's packet width).
const PACKET: usize = 8;

/// The fastest of `repeats` passes of `query` over `rays` (seconds) and its answers. `query`
/// answers a chunk of at most [`PACKET`] consecutive rays into the chunk's bytes of the answer
/// buffer (1 hit, 0 miss), which is allocated once, outside the timing.
fn time_kind(
    rays: &[(Vec3, Vec3)],
    repeats: u32,
    query: impl Fn(&[(Vec3, Vec3)], &mut [u8]) + Sync,
) -> (f64, Vec<u8>) {
    let mut best = f64::INFINITY;
    let mut answers = vec![0u8; rays.len()];
    for _ in 0..repeats {
        let start = Instant::now();
        answers
            .par_chunks_mut(PACKET)
            .zip(rays.par_chunks(PACKET))
            .for_each(|(out, chunk)| query(chunk, out));
        best = best.min(start.elapsed().as_secs_f64());
    }
    (best, answers)
}

/// [`time_kind`] of a query that takes one ray at a time (compiled for each query, no
/// indirect call per ray).
fn one_by_one(
    rays: &[(Vec3, Vec3)],
    repeats: u32,
    query: impl Fn(Vec3, Vec3) -> bool + Sync,
) -> (f64, Vec<u8>) {
    time_kind(rays, repeats, |chunk, out| {
        for (a, &(o, d)) in out.iter_mut().zip(chunk) {
            *a = u8::from(query(o, d));
        }
    })
}

/// [`Accel::closest_hits`] on one packet of rays.
fn closest_packet(accel: &Accel, rays: &[(Vec3, Vec3)], out: &mut [u8]) {
    let n = rays.len();
    let mut origins = [Vec3::ZERO; PACKET];
    let mut dirs = [Vec3::ZERO; PACKET];
    for (i, &(o, d)) in rays.iter().enumerate() {
        (origins[i], dirs[i]) = (o, d);
    }
    let mut hits = [None; PACKET];
    accel.closest_hits(&origins[..n], &dirs[..n], f32::INFINITY, &mut hits[..n]);
    for (a, h) in out.iter_mut().zip(&hits) {
        *a = u8::from(h.is_some());
    }
}

fn run(args: &Args) -> Result<(), String> {
    let loaded =
        prt_scene::load_mesh(Path::new(&args.mesh), &DMat4::IDENTITY).map_err(|e| e.to_string())?;
    let rays = read_rays(&args.rays)?;
    let accel = Accel::from_meshes(&loaded.meshes, AccelOptions::default())
        .map_err(|e| format!("{}: {e}", args.mesh))?;
    let plain = PlainObvhs::new(&test_util::merge(&loaded.meshes, "all"));
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads)
        .build()
        .map_err(|e| format!("thread pool: {e}"))?;
    let kinds = pool.install(|| {
        [
            (
                "closest",
                one_by_one(&rays, args.repeats, |o, d| {
                    accel.closest_hit(o, d, f32::INFINITY).is_some()
                }),
            ),
            (
                "closest_packets",
                time_kind(&rays, args.repeats, |chunk, out| {
                    closest_packet(&accel, chunk, out);
                }),
            ),
            (
                "occluded",
                one_by_one(&rays, args.repeats, |o, d| {
                    accel.occluded(o, d, f32::INFINITY)
                }),
            ),
            (
                "obvhs_closest",
                one_by_one(&rays, args.repeats, |o, d| plain.closest_hit(o, d)),
            ),
            (
                "obvhs_occluded",
                one_by_one(&rays, args.repeats, |o, d| plain.occluded(o, d)),
            ),
        ]
    });
    let hits: Vec<u8> = kinds
        .iter()
        .flat_map(|(_, (_, a))| a.iter().copied())
        .collect();
    std::fs::write(&args.hits, &hits).map_err(|e| format!("{}: {e}", args.hits))?;
    for (kind, (seconds, answers)) in &kinds {
        let count = answers.iter().filter(|&&h| h == 1).count();
        println!(
            "{{\"kind\": \"{kind}\", \"rays\": {}, \"hits\": {count}, \"seconds\": {seconds:.6}, \"mrays_per_s\": {:.4}}}",
            rays.len(),
            rays.len() as f64 / seconds / 1e6
        );
    }
    Ok(())
}

fn main() -> ExitCode {
    match parse_args().and_then(|a| run(&a)) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("trace_rays: {e}");
            ExitCode::FAILURE
        }
    }
}
