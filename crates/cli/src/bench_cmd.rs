//! `prt bench`: timings, kept apart from the commands that make images.
//!
//! `prt bench relight` times the shading of exactly what `prt relight` with the same options
//! shades (the same library call, `prt_scene_relight::Bound::relight`), so `prt relight` itself need
//! not relight again to report a speed-up: warm-up frames first (a frame sequence runs in the
//! steady state, not in a fresh process), then `--frames` timed frames of an environment
//! turning by `--rotate-y-step`, and the median, fastest and slowest frame; with `--adaptive`
//! or `--order` below the bake's, the full order is timed the same way and the speed-up is the
//! ratio of the medians.

use crate::relight_cmd::{adaptive_params, check_args, glossy_path, prepare_sh, RelightArgs};
use anyhow::{bail, Result};
use clap::{Args, Subcommand};
use prt_scene_relight::{RelightOptions, RelightStats};

/// The timings of `prt bench`.
#[derive(Subcommand)]
pub enum BenchCommand {
    /// Time `prt relight`'s shading (per frame: SH rotation, light products, shading; not
    /// loading, setup or image formation) with the same options as `prt relight`, against
    /// the full order when the options ask for less.
    Relight(BenchRelightArgs),
}

/// Options of `prt bench relight`.
#[derive(Args)]
pub struct BenchRelightArgs {
    /// `prt relight`'s options: what to relight and how. `--frames` is the number of timed
    /// frames (at least 5: `prt relight` reports the median of 5).
    #[command(flatten)]
    pub relight: RelightArgs,
    /// Frames shaded, untimed, before the timed ones.
    #[arg(long, default_value_t = 2)]
    pub warmup: usize,
}

/// The least number of timed frames (the median of 5 is what `prt relight` prints).
const MIN_TIMED_FRAMES: usize = 5;

/// Runs `prt bench`.
pub fn run(cmd: &BenchCommand) -> Result<()> {
    match cmd {
        BenchCommand::Relight(args) => run_relight(args),
    }
}

/// `prt bench relight`.
fn run_relight(bench: &BenchRelightArgs) -> Result<()> {
    let args = &bench.relight;
    check_args(args)?;
    if args.out.is_some()
        || args.png.is_some()
        || args.roi_png.is_some()
        || args.vertex_colours.is_some()
    {
        bail!("prt bench relight only times: write images and colours with prt relight");
    }
    if args.target_psnr.is_some() || args.verify {
        bail!("--target-psnr times each frame itself: run prt relight --adaptive --target-psnr");
    }
    let scene = crate::common::load_scene(&args.scene)?;
    let bake = prt_bakefile::read_bake(&args.bake)?;
    if bake.reflectance.is_some() {
        bail!(
            "{}: a reflectance field: prt relight --frames K prints its shading time",
            args.bake.display()
        );
    }
    let (scene, accel) = prepare_sh(args, &scene, &bake)?;
    let opt = RelightOptions {
        order: args.order,
        adaptive: args.adaptive.then(|| adaptive_params(args)),
        rotate_y_deg: args.rotate_y,
        timing_frames: args.frames.max(MIN_TIMED_FRAMES),
        warmup_frames: bench.warmup,
        rotate_y_step_deg: args.rotate_y_step,
        points: None,
        glossy: glossy_path(args)?,
        phong: args.phong_model.into(),
    };
    let bound = prt_scene_relight::Bound::new(&scene, &accel, &bake)?;
    let asked = bound.relight(&opt)?.stats;
    // The full order, timed the same way, when the options shade less than it.
    let full = if args.adaptive || args.order.is_some() {
        let full_opt = RelightOptions {
            order: None,
            adaptive: None,
            ..opt.clone()
        };
        Some(bound.relight(&full_opt)?.stats)
    } else {
        None
    };
    print_bench(bench, &opt, &asked, full.as_ref())
}

/// Prints the timings: one JSON object with `--json`, else lines for a person.
fn print_bench(
    bench: &BenchRelightArgs,
    opt: &RelightOptions,
    s: &RelightStats,
    full: Option<&RelightStats>,
) -> Result<()> {
    let speedup = full.map(|f| f.shade_ms / s.shade_ms.max(1e-9));
    if bench.relight.json {
        let obj = serde_json::json!({
            "order": s.order,
            "adaptive": s.adaptive,
            "threshold": s.threshold,
            "glossy": opt.glossy,
            "points": s.points,
            "warmup": opt.warmup_frames,
            "frames": opt.timing_frames,
            "rotate_y_step": opt.rotate_y_step_deg,
            "shade_ms": s.shade_ms,
            "shade_ms_min": s.shade_ms_min,
            "shade_ms_max": s.shade_ms_max,
            "fps": s.fps,
            "full_order": full.map(|f| f.order),
            "full_shade_ms": full.map(|f| f.shade_ms),
            "full_fps": full.map(|f| f.fps),
            "speedup": speedup,
            "notes": s.notes,
        });
        outln!("{}", serde_json::to_string(&obj)?);
        return Ok(());
    }
    for n in &s.notes {
        eprintln!("note: {n}");
    }
    outln!(
        "order {}{}  points {}  {} frames after {} warm-up, {}° apart: median {:.3} ms/frame (fastest {:.3}, slowest {:.3}), {:.1} frames/s",
        s.order,
        if s.adaptive { " adaptive" } else { "" },
        s.points,
        opt.timing_frames,
        opt.warmup_frames,
        opt.rotate_y_step_deg,
        s.shade_ms,
        s.shade_ms_min,
        s.shade_ms_max,
        s.fps
    );
    if let (Some(f), Some(x)) = (full, speedup) {
        outln!(
            "full order {}: median {:.3} ms/frame ⇒ speed-up {x:.2}×",
            f.order,
            f.shade_ms
        );
    }
    Ok(())
}
