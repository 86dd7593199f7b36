//! `prt report`: the speed-against-error report of a scene (reference, bake, relighting at
//! every order, tables, plots and images).

use anyhow::{bail, Context, Result};
use clap::Args;
use prt_report::ReportSettings;
use std::path::PathBuf;

/// Options of `prt report`.
#[derive(Args)]
pub struct ReportArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// Output directory (created; the bake cache lives in DIR/cache).
    #[arg(long)]
    pub out: PathBuf,
    /// Orders to relight at, `A..B` (inclusive) or a comma list.
    #[arg(long, default_value = "2..13")]
    pub orders: String,
    /// Samples per pixel of the path-traced reference.
    #[arg(long, default_value_t = 256)]
    pub reference_spp: u32,
    /// Rays per vertex of the bake.
    #[arg(long, default_value_t = 1024)]
    pub rays: u32,
    /// Bounces (default: the scene's `[render] bounces`).
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Adaptive threshold T (absolute, output radiance units; the thesis uses 0.02).
    #[arg(long, default_value_t = 0.02, allow_negative_numbers = true)]
    pub threshold: f32,
    /// Measure --threshold on the 8-bit view (as psnr_ldr) instead of in radiance.
    #[arg(long)]
    pub display_threshold: bool,
    /// Frames timed per relighting (median).
    #[arg(long, default_value_t = 5)]
    pub frames: usize,
}

fn parse_orders(text: &str) -> Result<Vec<usize>> {
    let orders: Vec<usize> = if let Some((a, b)) = text.split_once("..") {
        let a: usize = a
            .trim()
            .parse()
            .with_context(|| format!("--orders {text:?}: {a:?} is not a number"))?;
        let b: usize = b
            .trim()
            .trim_start_matches('=')
            .parse()
            .with_context(|| format!("--orders {text:?}: {b:?} is not a number"))?;
        if a > b {
            bail!("--orders {text:?}: the range is empty");
        }
        (a..=b).collect()
    } else {
        text.split(',')
            .map(|t| {
                t.trim()
                    .parse::<usize>()
                    .with_context(|| format!("--orders: {t:?} is not a number"))
            })
            .collect::<Result<_>>()?
    };
    if orders.iter().any(|&o| o == 0 || o > 32) {
        bail!("--orders {text:?}: every order must be between 1 and 32");
    }
    Ok(orders)
}

/// Runs `prt report`.
pub fn run(args: &ReportArgs) -> Result<()> {
    let orders = parse_orders(&args.orders)?;
    let scene = crate::common::load_scene(&args.scene)?;
    let bounces = crate::common::bake_bounces(args.bounces, &scene, &args.scene)?;
    let settings = ReportSettings {
        orders,
        reference_spp: args.reference_spp,
        rays: args.rays,
        bounces,
        threshold: args.threshold,
        display_threshold: args.display_threshold,
        seed: scene.render.seed,
        timing_frames: args.frames,
        progress: true,
    };
    let data = prt_report::run_report(&args.scene, &scene, &args.out, &settings)?;
    println!("order  full ms  adaptive ms  speed-up  PSNR ad/full  PSNR full/PT  PSNR ad/PT  ROI diff %  ROI spec %");
    for r in &data.orders {
        println!(
            "{:>5} {:>8.3} {:>12.3} {:>9.2} {:>13.2} {:>13.2} {:>11.2} {:>11} {:>11}",
            r.order,
            r.full_ms,
            r.adaptive_ms,
            r.speedup,
            r.psnr_adaptive_vs_full,
            r.psnr_full_vs_reference,
            r.psnr_adaptive_vs_reference,
            r.roi_diffuse
                .map_or("-".into(), |v| format!("{:.1}", 100.0 * v)),
            r.roi_specular
                .map_or("-".into(), |v| format!("{:.1}", 100.0 * v)),
        );
    }
    println!(
        "wrote {}/report.md, index.html, report.csv, report.json, plots and images",
        args.out.display()
    );
    Ok(())
}
