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
    /// The smallest gain of a well-determined band: the smallest singular value of its
    /// columns with the lower bands projected out, over band 0's (for a Lambertian object
    /// seeing every normal, A_l / A_0: 1, 2/3, 1/4, 0, 1/24, …). A relative error ε in the
    /// image becomes about ε / gain in the band.
    #[arg(long, default_value_t = 0.05)]
    pub min_gain: f64,
    /// Bands of the forward model (default: the bake's order): the bands past the
    /// well-determined ones stay in the model, regularised, so that their content in the image
    /// is not pushed onto the lower bands.
    #[arg(long)]
    pub model_order: Option<usize>,
    /// Check the fit against known coefficients (a `prt sh project --json` file): prints the
    /// relative L2 error of the well-determined bands and of each band, and the model residual
    /// under the known lighting.
    #[arg(long)]
    pub truth: Option<PathBuf>,
    /// Relight the scene under the fitted lighting, turned by --rotate-y, to this EXR.
    #[arg(long)]
    pub relight_out: Option<PathBuf>,
    /// Rotation about +Y of --relight-out's lighting, degrees.
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rotate_y: f64,
    /// Also fit this material's albedo (per channel) and, for `phong`, its exponent (the
    /// lighting and material alternately; see prt_scene_relight::fit_material). The image fixes
    /// only albedo × lighting: the scale comes from objects of other materials in the image
    /// (a probe), else from the Phong material's `specular`, held; a Lambertian material
    /// alone is refused. --relight-out then relights with the fitted material.
    #[arg(long)]
    pub fit_material: Option<String>,
    /// Fit only the pixels whose surface has at most this fraction of its cosine-weighted
    /// hemisphere blocked, as a per-pixel bake without bounces says (e.g. 0.01): a cast shadow
    /// under a compact light is a product of lighting and visibility that a model of practical
    /// order cannot represent, while an unoccluded point depends on the lighting's low bands
    /// only (crates/scene_relight/README.md measures it).
    #[arg(long, value_name = "FRACTION")]
    pub max_occlusion: Option<f64>,
    /// Robust fit: iteratively reweighted least squares with Tukey's biweight, so pixels the
    /// model cannot represent (a truncated model ringing across a compact light's terminator,
    /// cast-shadow edges) lose their weight; the JSON's `downweighted` counts them.
    #[arg(long)]
    pub robust: bool,
    /// The forward model of `phong` lobes: `fitted` (the default), the light's cosine inside
    /// the integral; `frozen-cosine`, `prt relight`'s default, whose error against the path
    /// tracer (7.9 % on one Phong sphere of exponent 10) the fit would inherit
    /// (crates/scene_relight/README.md). --relight-out relights with the same model.
    #[arg(long, value_enum, default_value_t = crate::common::PhongArg::Fitted)]
    pub phong_model: crate::common::PhongArg,
    /// Look for up to this many compact sources (a sun, lamps) beside the SH lighting: each is
    /// a small cap whose image — BRDF, cosine and cast shadow — is traced exactly, which an SH
    /// model of practical order cannot represent (crates/scene_relight/README.md); a source is
    /// kept only if it lowers the residual by 2 % or more. Their projections are added to the
    /// coefficients; the JSON's `sources` lists them. 0: SH only. Default: 16 (searching stops
    /// at the first source that does not pay); not searched with --fit-material.
    #[arg(long, value_name = "N")]
    pub sources: Option<usize>,
    /// Write the fitted pixels as a mask PNG (255 fitted, 0 not): `prt compare --mask` takes it.
    #[arg(long)]
    pub mask_out: Option<PathBuf>,
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
    if !(0.0..=1.0).contains(&args.min_gain) {
        bail!("--min-gain must be in [0, 1]");
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
    let truth = args.truth.as_deref().map(read_coefficients).transpose()?;
    let opt = FitOptions {
        order: args.order,
        model_order: args.model_order,
        condition_limit: args.condition_limit,
        min_gain: args.min_gain,
        weights,
        truth,
        max_occlusion: args.max_occlusion,
        phong: args.phong_model.into(),
        robust: args.robust,
        max_sources: args
            .sources
            .unwrap_or(prt_scene_relight::sources::DEFAULT_MAX_SOURCES),
    };
    write_mask(args, &bound)?;
    if let Some(name) = &args.fit_material {
        if let Some(n @ 1..) = args.sources {
            eprintln!(
                "warning: {}: --fit-material fits SH lighting only; --sources {n} is not searched in a material fit",
                args.image.display(),
            );
        }
        return run_material(args, &bound, &image, name, &opt, weighted);
    }
    let fit = fit_lighting(&bound, &image, &opt)
        .with_context(|| format!("{}: cannot fit the lighting", args.image.display()))?;
    if let Some(out) = &args.relight_out {
        relight_out(&bound, &fit.coefficients, args, out)?;
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
    if args.robust {
        outln!(
            "robust (Tukey biweight): {} of {} equations (pixel × channel) down-weighted below ½",
            fit.downweighted,
            3 * fit.pixels
        );
    }
    outln!(
        "fitted {} bands (model {}) over {} pixels (relative residual {:.4}); {} well determined, {} singular directions dropped",
        fit.order,
        fit.model_order,
        fit.pixels,
        fit.relative_residual,
        fit.well_determined,
        fit.dropped_directions
    );
    for (l, (k, g)) in fit
        .condition_by_band
        .iter()
        .zip(&fit.gain_by_band)
        .enumerate()
    {
        let state = match (l < fit.well_determined, l < fit.order) {
            (true, _) => "well determined",
            (false, true) => "regularised",
            (false, false) => "regularised, model only",
        };
        outln!("band {l}: condition number {k:.3e}, gain {g:.3e} ({state})");
    }
    for (k, src) in fit.sources.iter().enumerate() {
        let [x, y, z] = src.direction;
        outln!(
            "source {k}: direction ({x:.4}, {y:.4}, {z:.4}), radius {:.1}°, power [{:.4}, {:.4}, {:.4}] (relative residual {:.4} → {:.4})",
            src.radius_deg,
            src.intensity[0],
            src.intensity[1],
            src.intensity[2],
            fit.residual_by_sources[k],
            fit.residual_by_sources[k + 1]
        );
    }
    if let Some(t) = &fit.truth {
        outln!(
            "against the known lighting: relative L2 {:.4} over the well-determined bands; model residual {:.4}",
            t.rel_l2_well_determined,
            t.model_residual
        );
    }
    Ok(())
}

/// `--mask-out`: the fitted pixels as a PNG.
fn write_mask(args: &FitLightingArgs, bound: &prt_scene_relight::Bound) -> Result<()> {
    let Some(out) = &args.mask_out else {
        return Ok(());
    };
    let cam = &bound.scene().camera;
    let (w, h) = (cam.width as usize, cam.height as usize);
    let mut mask = prt_scene_relight::RgbImage {
        width: w,
        height: h,
        pixels: vec![[0.0; 3]; w * h],
    };
    let mut pixels = prt_scene_relight::inverse::fit_pixels(bound)?;
    if let Some(f) = args.max_occlusion {
        pixels = prt_scene_relight::inverse::unoccluded_pixels(bound, &pixels, f)?;
    }
    for p in pixels {
        mask.pixels[p] = [1.0; 3];
    }
    prt_scene_relight::io::write_png(out, &mask, 0.0)?;
    Ok(())
}

/// `--relight-out`: the bound scene relit under `lighting` turned by `--rotate-y` degrees,
/// Phong lobes by the fit's `--phong-model`.
fn relight_out(
    bound: &prt_scene_relight::Bound,
    lighting: &[[f64; 3]],
    args: &FitLightingArgs,
    out: &std::path::Path,
) -> Result<()> {
    let rotate_y = args.rotate_y;
    let relit = bound.relight_under(
        lighting,
        &prt_scene_relight::RelightOptions {
            rotate_y_deg: rotate_y,
            timing_frames: 1,
            warmup_frames: 0,
            phong: args.phong_model.into(),
            ..Default::default()
        },
    )?;
    let img = bound.form_image(&relit, rotate_y)?;
    prt_scene_relight::io::write_exr(
        out,
        &img,
        &[
            ("kind", "relit-fitted-lighting".into()),
            ("rotate_y", rotate_y.to_string()),
        ],
    )?;
    Ok(())
}

/// `--fit-material NAME`: the lighting and the material's parameters.
fn run_material(
    args: &FitLightingArgs,
    bound: &prt_scene_relight::Bound,
    image: &prt_scene_relight::RgbImage,
    name: &str,
    opt: &FitOptions,
    weighted: bool,
) -> Result<()> {
    use prt_scene_relight::fit_material::{fit_material, fitted_scene};
    let fit = fit_material(bound, image, name, opt).with_context(|| {
        format!(
            "{}: cannot fit the lighting and material {name:?}",
            args.image.display()
        )
    })?;
    if let Some(out) = &args.relight_out {
        let scene = fitted_scene(bound.scene(), &fit);
        let refit = prt_scene_relight::Bound::new(&scene, bound.accel(), bound.bake())?;
        relight_out(&refit, &fit.coefficients, args, out)?;
    }
    if args.json {
        let mut v = serde_json::to_value(&fit)?;
        v["order"] = opt.order.into();
        v["weighted_by_variance"] = weighted.into();
        outln!("{}", serde_json::to_string(&v)?);
        return Ok(());
    }
    outln!(
        "material {name:?}: albedo [{:.4}, {:.4}, {:.4}]{} (scale fixed by {}); {} bands of lighting, {} well determined; relative residual {:.4}",
        fit.albedo[0],
        fit.albedo[1],
        fit.albedo[2],
        fit.exponent
            .map(|e| format!(", exponent {e:.3}"))
            .unwrap_or_default(),
        fit.scale_fixed_by,
        opt.order,
        fit.well_determined,
        fit.relative_residual
    );
    Ok(())
}

/// The coefficients of a `prt sh project --json` file.
fn read_coefficients(path: &std::path::Path) -> Result<Vec<[f64; 3]>> {
    #[derive(serde::Deserialize)]
    struct Projected {
        coefficients: Vec<[f64; 3]>,
    }
    let text = std::fs::read_to_string(path)
        .with_context(|| format!("{}: cannot read", path.display()))?;
    let p: Projected = serde_json::from_str(&text).with_context(|| {
        format!(
            "{}: not a `prt sh project --json` file ({{\"coefficients\": [[r, g, b], ...]}})",
            path.display()
        )
    })?;
    Ok(p.coefficients)
}
