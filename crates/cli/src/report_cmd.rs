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
    /// Samples per pixel of the path-traced reference: the most it may take to reach
    /// --reference-psnr (exactly this with --reference-psnr 0).
    #[arg(long, default_value_t = 16384)]
    pub reference_spp: u32,
    /// Render the reference until its own estimate of its noise ceiling on object pixels
    /// (8-bit view, psnr_ldr) reaches this many dB; 0 for exactly --reference-spp samples.
    /// The reference is cached in DIR/cache like the bake.
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub reference_psnr: f64,
    /// The quality target of the report's "target quality" column: adaptive relighting to
    /// this PSNR against full order at each order (0: no column).
    #[arg(long, default_value_t = 45.0, allow_negative_numbers = true)]
    pub target_psnr: f64,
    /// Skip the error budget (it needs a second vertex bake and two per-pixel bakes, cached).
    #[arg(long)]
    pub no_budget: bool,
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
    /// Frames timed per relighting (the median is reported, with the fastest and slowest).
    #[arg(long, default_value_t = 15)]
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
    if !(args.target_psnr.is_finite() && args.target_psnr >= 0.0) {
        bail!(
            "--target-psnr {} must be a number of dB ≥ 0 (0: no target-quality column)",
            args.target_psnr
        );
    }
    if !(args.reference_psnr.is_finite() && args.reference_psnr >= 0.0) {
        bail!(
            "--reference-psnr {} must be a number of dB ≥ 0 (0: a fixed sample count)",
            args.reference_psnr
        );
    }
    let settings = ReportSettings {
        orders,
        reference_spp: args.reference_spp,
        reference_psnr: (args.reference_psnr > 0.0).then_some(args.reference_psnr),
        budget: !args.no_budget,
        target_psnr: (args.target_psnr > 0.0).then_some(args.target_psnr),
        rays: args.rays,
        bounces,
        threshold: args.threshold,
        display_threshold: args.display_threshold,
        seed: scene.render.seed,
        timing_frames: args.frames,
        progress: true,
    };
    let data = prt_report::run_report(&args.scene, &scene, &args.out, &settings)?;
    outln!("order  full ms  adaptive ms  speed-up  PSNR ad/full  PSNR full/PT  PSNR ad/PT  ROI diff %  ROI spec %");
    for r in &data.orders {
        outln!(
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
    if !data.error_budget.is_empty() {
        outln!("\nerror budget (what each approximation costs; MSE over object pixels, linear radiance):");
        outln!(
            "order  total       {}  cross %",
            prt_report::budget::TERMS
                .iter()
                .map(|t| format!("{t:>15}"))
                .collect::<String>()
        );
        for b in &data.error_budget {
            outln!(
                "{:>5}  {:<10.3e}  {}  {:>6.1}",
                b.order,
                b.total_mse,
                prt_report::budget::TERMS
                    .iter()
                    .map(|t| format!("{:>15.3e}", b.term(t)))
                    .collect::<String>(),
                100.0 * b.cross_terms / b.total_mse.max(f64::MIN_POSITIVE)
            );
        }
        outln!("{}", data.error_budget_summary);
    }
    outln!(
        "reference: {} spp, noise ceiling {:.1} dB{}",
        data.reference.spp,
        data.reference.noise_psnr_ldr,
        data.reference
            .target_psnr_ldr
            .map_or(String::new(), |t| format!(
                " (target {t} dB{})",
                if data.reference.target_met == Some(false) {
                    ", not reached: raise --reference-spp"
                } else {
                    ""
                }
            ))
    );
    outln!(
        "wrote {}/report.md, index.html, report.csv, report.json, plots and images",
        args.out.display()
    );
    Ok(())
}
