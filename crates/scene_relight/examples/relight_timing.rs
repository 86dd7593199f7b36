//! In-process timing of adaptive against full-order relighting, for comparing builds.
//!
//! `cargo run --release -p prt-report --example relight_timing -- SCENE BAKE ORDER T [--display]
//! [--reps N] [--frames K] [--warmup W] [--cost-exponent A] [--adaptive-only]`
//!
//! Loads the scene and bake once, then `N` times (default 3) relights `K` timed frames (default
//! 9, after `W` untimed warm-up frames, default 2) adaptively (convergence stop, threshold `T` in
//! radiance, or on the display with `--display`) and at full order, alternating, and prints the
//! fastest of the `N` medians of each. Single runs on a shared machine scatter by ±10–30 %;
//! alternating and keeping minima is what `tools/relight_ab.sh` builds on to compare two builds.

use prt_relight::{AdaptiveParams, Threshold};
use prt_scene_relight::RelightOptions;
use std::path::Path;
use std::process::ExitCode;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("relight_timing: {e}");
            ExitCode::from(2)
        }
    }
}

fn run() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut positional = Vec::new();
    let (mut reps, mut frames, mut warmup) = (3usize, 9usize, 2usize);
    let (mut display, mut adaptive_only) = (false, false);
    let mut cost_exponent = AdaptiveParams::new(Threshold::Absolute(0.0)).cost_exponent;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let mut value = |name: &str| -> Result<usize, String> {
            it.next()
                .and_then(|v| v.parse().ok())
                .ok_or(format!("{name} needs a whole number"))
        };
        match a.as_str() {
            "--display" => display = true,
            "--adaptive-only" => adaptive_only = true,
            "--reps" => reps = value("--reps")?.max(1),
            "--frames" => frames = value("--frames")?.max(1),
            "--warmup" => warmup = value("--warmup")?,
            "--cost-exponent" => {
                cost_exponent = it
                    .next()
                    .and_then(|v| v.parse().ok())
                    .ok_or("--cost-exponent needs a number")?;
            }
            _ => positional.push(a.clone()),
        }
    }
    let [scene_path, bake_path, order, t] = positional.as_slice() else {
        return Err("usage: SCENE BAKE ORDER T [--display] [--reps N] [--frames K] [--warmup W] [--cost-exponent A] [--adaptive-only]".into());
    };
    let order: usize = order
        .parse()
        .map_err(|_| format!("order {order:?} is not a number"))?;
    let t: f32 = t
        .parse()
        .map_err(|_| format!("threshold {t:?} is not a number"))?;
    let scene = prt_scene::load_scene(Path::new(scene_path))
        .map_err(|e| e.to_string())?
        .scene;
    let bake = prt_bakefile::read_bake(Path::new(bake_path)).map_err(|e| e.to_string())?;
    prt_scene_relight::check_bake(&scene, &bake, Path::new(bake_path))
        .map_err(|e| e.to_string())?;
    let accel = prt_tracer::Accel::build(&scene).map_err(|e| e.to_string())?;
    let threshold = if display {
        Threshold::Display {
            t,
            exposure_ev: 0.0,
        }
    } else {
        Threshold::Absolute(t)
    };
    let mut best = [f64::INFINITY; 2];
    for _ in 0..reps {
        let params = AdaptiveParams {
            cost_exponent,
            ..AdaptiveParams::new(threshold)
        };
        for (k, adaptive) in [Some(params), None].into_iter().enumerate() {
            if k == 1 && adaptive_only {
                continue;
            }
            let opt = RelightOptions {
                order: Some(order),
                adaptive,
                rotate_y_deg: 0.0,
                timing_frames: frames,
                warmup_frames: warmup,
                rotate_y_step_deg: 0.0,
                points: None,
                ..Default::default()
            };
            let r = prt_scene_relight::relight(&scene, &accel, &bake, &opt)
                .map_err(|e| e.to_string())?;
            best[k] = best[k].min(r.stats.shade_ms);
        }
    }
    if adaptive_only {
        println!("order {order}  adaptive {:.2} ms", best[0]);
    } else {
        println!(
            "order {order}  adaptive {:.2} ms  full {:.2} ms  speed-up {:.2}",
            best[0],
            best[1],
            best[1] / best[0]
        );
    }
    Ok(())
}
