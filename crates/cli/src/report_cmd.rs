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
    /// Add the reflectance-field section (Masselus et al. 2004): sample the scene's
    /// reflectance field at `WxH` lat-long directions (cached), relight it with every
    /// reconstruction, compress it with each wavelet, and compare it with per-pixel SH of as
    /// many coefficients, all against the path-traced reference.
    #[arg(long, value_name = "WxH")]
    pub reflectance: Option<String>,
    /// Reflectance section: the fine grid the functions are reconstructed on.
    #[arg(
        long,
        value_name = "WxH",
        default_value = "256x128",
        requires = "reflectance"
    )]
    pub rf_fine: String,
    /// Reflectance section: wavelet coefficients per pixel and channel of the compressed
    /// relightings (a comma list; each beside per-pixel SH of order ⌊√K⌋).
    #[arg(long, default_value = "64,256", requires = "reflectance")]
    pub rf_coefficients: String,
    /// Reflectance section: the reconstruction the compressed functions start from.
    #[arg(long, value_enum, default_value_t = crate::relight_cmd::ReconstructArg::Linear, requires = "reflectance")]
    pub rf_compress_from: crate::relight_cmd::ReconstructArg,
    /// Reflectance section: frames of the flicker measurement (map turned each frame).
    #[arg(long, default_value_t = 8, requires = "reflectance")]
    pub rf_frames: usize,
    /// Reflectance section: degrees the map turns about +Y between flicker frames.
    #[arg(
        long,
        default_value_t = 0.5,
        allow_negative_numbers = true,
        requires = "reflectance"
    )]
    pub rf_rotate_step: f64,
    /// Reflectance section: footprint samples per pixel of the field and of the per-pixel SH
    /// bake beside it.
    #[arg(long, default_value_t = 16, requires = "reflectance")]
    pub rf_pixel_samples: u32,
    /// Reflectance section: measure the compression errors over at most this many pixels (an
    /// even subsample).
    #[arg(long, default_value_t = 2048, requires = "reflectance")]
    pub rf_error_pixels: usize,
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

/// The reflectance section's settings from the `--rf-*` options.
fn rf_settings(args: &ReportArgs, directions: &str) -> Result<prt_report::rf_section::RfSettings> {
    let directions = crate::reflectance_cmd::parse_grid(directions, "--reflectance")?;
    let fine = crate::reflectance_cmd::parse_grid(&args.rf_fine, "--rf-fine")?;
    let coefficients = args
        .rf_coefficients
        .split(',')
        .map(|t| {
            t.trim()
                .parse::<usize>()
                .with_context(|| format!("--rf-coefficients: {t:?} is not a number"))
        })
        .collect::<Result<Vec<_>>>()?;
    if !args.rf_rotate_step.is_finite() {
        bail!("--rf-rotate-step {} must be finite", args.rf_rotate_step);
    }
    if args.rf_pixel_samples == 0 || args.rf_error_pixels == 0 {
        bail!("--rf-pixel-samples and --rf-error-pixels must be at least 1");
    }
    Ok(prt_report::rf_section::RfSettings {
        directions,
        fine,
        coefficients,
        compress_from: args.rf_compress_from.method(),
        frames: args.rf_frames,
        rotate_step_deg: args.rf_rotate_step,
        pixel_samples: args.rf_pixel_samples,
        error_pixels: args.rf_error_pixels,
        timing_frames: args.frames.min(5),
    })
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
        reflectance: match &args.reflectance {
            Some(d) => Some(rf_settings(args, d)?),
            None => None,
        },
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
