//! Where the `--glossy shrm` path's error against the path tracer comes from
//! (crates/relight/README.md, "Spherical harmonic reflection maps").
//!
//! `cargo run --release -p prt-scene-relight --example shrm_diagnose -- SCENE BAKE REF REF2 UNSHADOWED`
//!
//! `REF` and `REF2` are `prt render` images of the scene with two seeds, `UNSHADOWED` one made
//! with `--unshadowed`. Relights the bake once with `--glossy shrm` and forms four images: the
//! SHRM looked up per vertex and interpolated (Gouraud) or looked up at every sub-pixel ray's
//! interpolated normal and position, each with the occlusion factor `k` and without it. On
//! the object's pixels, split by the pixel's interpolated `k`, it prints `psnr_ldr` (8-bit
//! sRGB, peak 255) and each class's share of the squared error: the shadowed images against
//! `REF`, the unoccluded ones against `UNSHADOWED` (the SHRM and image formation without the
//! occlusion), `REF2` against `REF` (the references' own noise: one reference's MSE against
//! the truth is half of the pair's), the unoccluded per-sample image times each pixel's true
//! luminance ratio `lum(REF)/lum(UNSHADOWED)` against `REF` (the best a scalar occlusion
//! factor per pixel could do), and the time of forming each image.

use prt_scene_relight::{Bound, GlossyPath, RelightOptions, Relit, RgbImage};
use std::path::Path;
use std::process::ExitCode;
use std::sync::Arc;
use std::time::Instant;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("shrm_diagnose: {e}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (Some([scene, bake, reference, reference2, unshadowed]), phong) =
        (args.get(..5), args.get(5..7))
    else {
        return Err("usage: SCENE BAKE REF REF2 UNSHADOWED [PHONG_SCENE PHONG_BAKE]".into());
    };
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let scene = prt_scene::load_scene(Path::new(scene))
        .map_err(|e| err(&e))?
        .scene;
    let bake = prt_bakefile::read_bake(Path::new(bake)).map_err(|e| err(&e))?;
    let read = |p: &String| -> Result<Vec<[f32; 3]>, String> {
        Ok(prt_image::read_image(p).map_err(|e| err(&e))?.image.pixels)
    };
    let (r0, r1, u0) = (read(reference)?, read(reference2)?, read(unshadowed)?);
    prt_scene_relight::check_bake(&scene, &bake, Path::new("bake")).map_err(|e| err(&e))?;
    let accel = prt_tracer::Accel::build(&scene).map_err(|e| err(&e))?;
    let bound = Bound::new(&scene, &accel, &bake).map_err(|e| err(&e))?;
    let opt = RelightOptions {
        glossy: GlossyPath::Shrm,
        timing_frames: 1,
        warmup_frames: 0,
        ..RelightOptions::default()
    };
    let relit = bound.relight(&opt).map_err(|e| err(&e))?;
    let mask = prt_scene_relight::object_mask(&scene, &accel).map_err(|e| err(&e))?;
    let form = |r: &Relit| -> Result<(RgbImage, f64), String> {
        bound.form_image(r, 0.0).map_err(|e| err(&e))?; // rays traced, caches warm
        let start = Instant::now();
        let img = bound.form_image(r, 0.0).map_err(|e| err(&e))?;
        Ok((img, 1e3 * start.elapsed().as_secs_f64()))
    };
    let variants = |unocc: bool| -> Relit {
        let mut r = relit.clone();
        for (o, s) in r.shrm.iter_mut().enumerate() {
            if let Some(s) = s {
                if unocc {
                    *s = Arc::new(s.unoccluded());
                }
                r.radiance[o] = s.vertex_radiance(&scene.meshes[o]);
            }
        }
        r
    };
    let gouraud = |r: &Relit| Relit {
        shrm: Vec::new(),
        ..r.clone()
    };
    let (shadowed, unoccluded) = (variants(false), variants(true));
    if shadowed.shrm.iter().all(Option::is_none) {
        return Err("no object was relit by the SHRM path".into());
    }
    // Each pixel's interpolated occlusion factor.
    let mut k_relit = gouraud(&shadowed);
    for (o, s) in shadowed.shrm.iter().enumerate() {
        if let Some(s) = s {
            k_relit.radiance[o] = s.occlusion().to_vec();
        }
    }
    let k = form(&k_relit)?.0.pixels;
    let classes = classes(&mask, &k);
    let (a, ta) = form(&gouraud(&shadowed))?;
    let (b, tb) = form(&shadowed)?;
    let (c, tc) = form(&gouraud(&unoccluded))?;
    let (d, td) = form(&unoccluded)?;
    let lum = |v: &[f32; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
    let oracle: Vec<[f32; 3]> = d
        .pixels
        .iter()
        .zip(r0.iter().zip(&u0))
        .map(|(v, (r, u))| {
            let t = if lum(u) > 0.0 { lum(r) / lum(u) } else { 1.0 };
            v.map(|x| x * t)
        })
        .collect();
    println!("notes: {:?}", relit.stats.notes);
    if let Some([ps, pb]) = phong {
        let (a, b) = timings(&bound, ps, pb)?;
        println!("shade_ms, median of 5 frames, best of 3 alternating runs: SHRM {a:.1}, Phong (fitted) {b:.1}");
    }
    println!(
        "shade_ms (per-vertex relighting, 1 frame): {:.1}",
        relit.stats.shade_ms
    );
    println!("form ms: gouraud {ta:.1}, per-sample {tb:.1} (unoccluded: {tc:.1}, {td:.1})");
    let header: Vec<String> = classes
        .iter()
        .map(|(n, px)| format!("{n} ({} px)", px.len()))
        .collect();
    println!("| image / reference | {} |", header.join(" | "));
    let rows: [Row<'_>; 6] = [
        ("per-vertex (Gouraud), k / ref", &a.pixels, &r0),
        ("per-sample, k / ref", &b.pixels, &r0),
        ("per-vertex, k = 1 / unshadowed ref", &c.pixels, &u0),
        ("per-sample, k = 1 / unshadowed ref", &d.pixels, &u0),
        ("per-sample × true lum ratio / ref", &oracle, &r0),
        ("ref seed 2 / ref", &r1, &r0),
    ];
    for (name, x, y) in rows {
        let total = sq_error(x, y, &classes[0].1);
        let cells: Vec<String> = classes
            .iter()
            .map(|(_, px)| {
                let e = sq_error(x, y, px);
                format!("{:.2} dB ({:.0} %)", psnr(e, px.len()), 100.0 * e / total)
            })
            .collect();
        println!("| {name} | {} |", cells.join(" | "));
    }
    Ok(())
}

/// A row of the table: its name, the image and the reference.
type Row<'a> = (&'a str, &'a [[f32; 3]], &'a [[f32; 3]]);

/// Median shading times (ms, 5 frames after 2 warm-up frames; the fastest of 3 alternating
/// runs) of `bound` by the SHRM path and of the Phong scene `ps` with bake `pb` by the fitted
/// path.
fn timings(bound: &Bound<'_>, ps: &str, pb: &str) -> Result<(f64, f64), String> {
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let scene = prt_scene::load_scene(Path::new(ps))
        .map_err(|e| err(&e))?
        .scene;
    let bake = prt_bakefile::read_bake(Path::new(pb)).map_err(|e| err(&e))?;
    let accel = prt_tracer::Accel::build(&scene).map_err(|e| err(&e))?;
    let phong = Bound::new(&scene, &accel, &bake).map_err(|e| err(&e))?;
    let opt = |glossy| RelightOptions {
        glossy,
        timing_frames: 5,
        warmup_frames: 2,
        ..RelightOptions::default()
    };
    let (mut a, mut b) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..3 {
        let s = bound.relight(&opt(GlossyPath::Shrm)).map_err(|e| err(&e))?;
        a = a.min(s.stats.shade_ms);
        let p = phong
            .relight(&opt(GlossyPath::Fitted))
            .map_err(|e| err(&e))?;
        b = b.min(p.stats.shade_ms);
    }
    Ok((a, b))
}

/// The object's pixels, all and split by the interpolated occlusion factor `k`.
fn classes(mask: &[bool], k: &[[f32; 3]]) -> Vec<(&'static str, Vec<usize>)> {
    let pick = |f: &dyn Fn(f32) -> bool| -> Vec<usize> {
        (0..mask.len()).filter(|&i| mask[i] && f(k[i][1])).collect()
    };
    vec![
        ("all", pick(&|_| true)),
        ("k >= 0.99", pick(&|k| k >= 0.99)),
        ("0.7 <= k < 0.99", pick(&|k| (0.7..0.99).contains(&k))),
        ("k < 0.7", pick(&|k| k < 0.7)),
    ]
}

/// Sum of squared differences of the 8-bit sRGB views (0 EV) of `x` and `y` over `pixels`.
fn sq_error(x: &[[f32; 3]], y: &[[f32; 3]], pixels: &[usize]) -> f64 {
    let ldr = |v: f32| f64::from(prt_image::srgb::ldr_value(v, 0.0));
    pixels
        .iter()
        .flat_map(|&i| (0..3).map(move |c| (ldr(x[i][c]) - ldr(y[i][c])).powi(2)))
        .sum()
}

/// PSNR (peak 255) of a summed squared error over `n` pixels' three channels.
fn psnr(sum: f64, n: usize) -> f64 {
    10.0 * (255.0f64 * 255.0 * 3.0 * n as f64 / sum).log10()
}
