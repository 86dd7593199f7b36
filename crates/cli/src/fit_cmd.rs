//! `prt fit-lighting`: the environment's SH coefficients from an image of a baked scene
//! (`prt_scene_relight::inverse`).

use anyhow::{bail, Context, Result};
use clap::Args;
use prt_scene_relight::inverse::{fit_lighting, FitOptions};
use std::path::PathBuf;

/// Options of `prt fit-lighting`.
#[derive(Args)]
pub struct FitLightingArgs {
    /// The image (EXR, linear; or PNG, sRGB) of the scene's camera: a render, a photograph
    /// registered to the camera, or a relit image. An EXR with `variance.R/G/B` channels
    /// (`prt render --aovs`) weights each pixel by the inverse of its variance.
    pub image: PathBuf,
    /// The scene the bake was made from.
    #[arg(long)]
    pub scene: PathBuf,
    /// The bake (.prtb).
    #[arg(long)]
    pub bake: PathBuf,
    /// Bands of lighting to fit (at most the bake's order).
    #[arg(long)]
    pub order: usize,
    /// The largest condition number of a well-determined band; past it the fit is regularised
    /// (truncated SVD: singular values below σ_max / limit dropped). A noise of relative size
    /// ε in the image can become an error of limit · ε in the coefficients.
    #[arg(long, default_value_t = 1000.0)]
    pub condition_limit: f64,
    /// Relight the scene under the fitted lighting, turned by --rotate-y, to this EXR.
    #[arg(long)]
    pub relight_out: Option<PathBuf>,
    /// Rotation about +Y of --relight-out's lighting, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rotate_y: f64,
    /// Print one JSON object: `{"order": N, "coefficients": [[r, g, b], ...], ...}` (the form
    /// of `prt sh project --json`, with the conditioning and residual beside it).
    #[arg(long)]
    pub json: bool,
}

/// Runs `prt fit-lighting`.
pub fn run(args: &FitLightingArgs) -> Result<()> {
    if args.condition_limit.is_nan() || args.condition_limit < 1.0 {
        bail!("--condition-limit must be at least 1");
    }
    let scene = crate::common::load_scene(&args.scene)?;
    let bake = prt_bakefile::read_bake(&args.bake)?;
    if bake.reflectance.is_some() {
        bail!(
            "{}: a reflectance field; fit-lighting reads SH bakes",
            args.bake.display()
        );
    }
    prt_scene_relight::check_bake(&scene, &bake, &args.bake)?;
    let scene = prt_scene_relight::baked_scene(&scene, &bake)?;
    let accel = prt_tracer::Accel::build(&scene).context("building the BVH")?;
    let bound = prt_scene_relight::Bound::new(&scene, &accel, &bake)?;
    let image = prt_image::read_image(&args.image)?.image;
    // Each pixel weighted by the inverse of its noise where the image says it (the variance
    // channels `prt render --aovs` writes), floored at a millionth of the mean so that a
    // noiseless pixel does not take the whole fit.
    let weights = prt_image::read::read_variance(&args.image)?.map(|var| {
        let v: Vec<f64> = var
            .iter()
            .map(|p| p.iter().map(|&x| f64::from(x.max(0.0))).sum::<f64>() / 3.0)
            .collect();
        let floor = 1e-6 * v.iter().sum::<f64>() / v.len().max(1) as f64;
        v.iter()
            .map(|&x| 1.0 / x.max(floor).max(f64::MIN_POSITIVE))
            .collect()
    });
    let weighted = weights.is_some();
    let fit = fit_lighting(
        &bound,
        &image,
        &FitOptions {
            order: args.order,
            condition_limit: args.condition_limit,
            weights,
        },
    )
    .with_context(|| format!("{}: cannot fit the lighting", args.image.display()))?;
    if let Some(out) = &args.relight_out {
        let relit = bound.relight_under(
            &fit.coefficients,
            &prt_scene_relight::RelightOptions {
                rotate_y_deg: args.rotate_y,
                timing_frames: 1,
                warmup_frames: 0,
                ..Default::default()
            },
        )?;
        let img = bound.form_image(&relit, args.rotate_y)?;
        prt_scene_relight::io::write_exr(
            out,
            &img,
            &[
                ("kind", "relit-fitted-lighting".into()),
                ("rotate_y", args.rotate_y.to_string()),
            ],
        )?;
    }
    if args.json {
        let mut v = serde_json::to_value(&fit)?;
        v["weighted_by_variance"] = weighted.into();
        outln!("{}", serde_json::to_string(&v)?);
        return Ok(());
    }
    if weighted {
        outln!("pixels weighted by the inverse of the image's variance channels");
    }
    outln!(
        "fitted {} bands over {} pixels (relative residual {:.4}); {} well determined, {} singular directions dropped",
        fit.order,
        fit.pixels,
        fit.relative_residual,
        fit.well_determined,
        fit.dropped_directions
    );
    for (l, k) in fit.condition_by_band.iter().enumerate() {
        let state = if l < fit.well_determined {
            "well determined"
        } else {
            "regularised"
        };
        outln!("band {l}: condition number {k:.3e} ({state})");
    }
    Ok(())
}
