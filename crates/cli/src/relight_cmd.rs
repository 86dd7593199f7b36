//! `prt relight`: relight a bake under the (rotated) environment, full order or adaptive.

use anyhow::{bail, Context, Result};
use clap::Args;
use prt_relight::{AdaptiveParams, StopRule, Threshold, MAX_COST_EXPONENT};
use prt_scene_relight::{RelightOptions, RelightStats};
use std::path::PathBuf;
use std::time::Instant;

/// Options of `prt relight`.
#[derive(Args)]
pub struct RelightArgs {
    /// The scene file the bake was made from.
    pub scene: PathBuf,
    /// The bake (.prtb).
    #[arg(long)]
    pub bake: PathBuf,
    /// Relight at this order (default: each object's baked order; never above it).
    #[arg(long)]
    pub order: Option<usize>,
    /// Locally adaptive relighting (Lee & Kim 2014).
    #[arg(long, help_heading = "Adaptive (Lee & Kim 2014)")]
    pub adaptive: bool,
    /// Adaptive: the ROI threshold T, in the unit of --threshold-unit (the thesis: 0.02 on
    /// [0, 1] display values; crates/relight/README.md measures speed against error for others,
    /// e.g. 0.09 radiance: 3.3× at 45.4 dB at order 10 and 4.3× at order 11 on the bunny).
    #[arg(
        long,
        default_value_t = 0.02,
        allow_negative_numbers = true,
        help_heading = "Adaptive (Lee & Kim 2014)"
    )]
    pub threshold: f32,
    /// Adaptive: what --threshold measures. `radiance`: output radiance; `mean`: a fraction of
    /// the frame's mean radiance; `display`: the [0, 1] colour of the PNG view (its --exposure,
    /// clamp, sRGB), diffuse and specular seen together.
    #[arg(long, value_enum, default_value_t = ThresholdUnit::Radiance, help_heading = "Adaptive (Lee & Kim 2014)")]
    pub threshold_unit: ThresholdUnit,
    /// Old spelling of `--threshold-unit mean`.
    #[arg(long, hide = true, conflicts_with_all = ["display_threshold", "threshold_unit"])]
    pub relative_threshold: bool,
    /// Old spelling of `--threshold-unit display`.
    #[arg(long, hide = true, conflicts_with = "threshold_unit")]
    pub display_threshold: bool,
    /// Exposure of the PNG view (and so of `--threshold-unit display`), stops.
    #[arg(
        long,
        help_heading = "Output",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub exposure: f32,
    /// Adaptive: when a vertex stops adding levels. `convergence`: once its last two levels
    /// changed it by less than T; `significance`: Lee & Kim's Algorithm 1, at the first level
    /// where its accumulated difference from the base is below T; `either`: whichever first.
    #[arg(long, help_heading = "Adaptive (Lee & Kim 2014)", value_enum, default_value_t = StopArg::Convergence)]
    pub stop: StopArg,
    /// Adaptive, convergence stop: how the threshold grows with the price of the next level.
    /// After level l the change of the last two levels is compared with T·(c(l+1)/c(5))^A,
    /// c(k) being the products of the term's level k: 1 (the default) asks each level for a
    /// change in proportion to its price, 0.5 for the square of it, 0 for T at every level.
    #[arg(
        long,
        help_heading = "Adaptive (Lee & Kim 2014)",
        default_value_t = 1.0,
        allow_negative_numbers = true
    )]
    pub cost_exponent: f32,
    /// Rotate the environment about +Y by this many degrees.
    #[arg(
        long,
        help_heading = "Rotation and frames",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub rotate_y: f64,
    /// Shade this many frames of a rotating environment and report frames per second (SH
    /// bakes; `prt bench relight` is the timing command, with warm-up, median, fastest and
    /// slowest frame). With --target-psnr: the frames of the study; for a reflectance field:
    /// the frames whose flicker is measured.
    #[arg(long, help_heading = "Rotation and frames", default_value_t = 1)]
    pub frames: usize,
    /// Rotation step between frames, degrees.
    #[arg(
        long,
        help_heading = "Rotation and frames",
        default_value_t = 10.0,
        allow_negative_numbers = true
    )]
    pub rotate_y_step: f64,
    /// Output EXR (linear RGB).
    #[arg(long, help_heading = "Output")]
    pub out: Option<PathBuf>,
    /// Output PNG view.
    #[arg(long, help_heading = "Output")]
    pub png: Option<PathBuf>,
    /// PNG of the region of interest (ROI vertices red), adaptive only.
    #[arg(long, help_heading = "Adaptive (Lee & Kim 2014)")]
    pub roi_png: Option<PathBuf>,
    /// Write the relit radiance of every point as CSV (`object,point,r,g,b`, linear RGB, each
    /// value the shortest decimal that reads back to the same f32): per vertex, or per pixel
    /// and object for per-pixel bakes. What an engine computes from the bake alone, for
    /// checking a reader of the format (tools/prtb_reader.py --relight).
    #[arg(long, help_heading = "Output")]
    pub vertex_colours: Option<PathBuf>,
    /// How glossy lobes without a zonal form (Blinn–Phong, Ward, Cook–Torrance, glTF `pbr`)
    /// are relit: `fitted`, a zonal fit of the lobe per view elevation shaded at Phong's cost
    /// (full order and adaptive); `exact`, the bake's per-elevation BRDF projections rotated
    /// per point (O(order⁵) per point, full order; the reference for `fitted`); `hybrid`, the
    /// fit, and the exact path at the points whose view elevation puts the fit's relative L2
    /// error against the lobe at --fit-error or more (sharp lobes at grazing views); `shrm`,
    /// a spherical harmonic reflection map of the environment prefiltered with the lobe once
    /// per environment, looked up per sub-pixel sample (per vertex for exports and reports),
    /// times a specular occlusion traced along the lobe's own directions once per run
    /// (per-vertex bakes; otherwise the bake's visibility at its order) — an approximation;
    /// crates/relight/README.md, "Spherical harmonic reflection maps"; `auto`, per object
    /// `shrm` where the lobe loses more of its energy beyond the baked order than the bake's
    /// error target (the bake's decision line says so: its order was capped or fixed below
    /// what the lobe needs), `fitted` elsewhere.
    #[arg(long, help_heading = "Glossy materials", value_enum, default_value_t = GlossyArg::Fitted)]
    pub glossy: GlossyArg,
    /// With --glossy hybrid: the fit error (relative L2, against the lobe) from which a point
    /// is shaded by the exact path; 0 shades every point exactly.
    #[arg(long, help_heading = "Glossy materials", default_value_t = 0.1)]
    pub fit_error: f32,
    /// How the `phong` material's lobe is relit: `frozen-cosine`, the light's cosine taken
    /// out of the integral at the lobe's centre (Sloan et al. 2002; exact only at normal view:
    /// 7.9 % off the path tracer on a sphere of exponent 10); `fitted`, the cosine inside,
    /// fitted per view elevation as --glossy fitted fits the other lobes and shaded at the
    /// same cost (what `prt fit-lighting` inverts; crates/scene_relight/README.md measures
    /// both). With `fitted`, --glossy exact and hybrid shade Phong by the fit (the bake holds
    /// no per-elevation table for it).
    #[arg(long, help_heading = "Glossy materials", value_enum, default_value_t = crate::common::PhongArg::FrozenCosine)]
    pub phong_model: crate::common::PhongArg,
    /// Reflectance fields (`prt reflectance`): how each pixel's sampled function is
    /// reconstructed on the fine grid (`nearest`: zero-order hold; `linear`: bilinear,
    /// periodic in azimuth; `legall53` / `cdf97`: wavelet interpolation, periodic in azimuth
    /// and mirrored at the poles; `idw`, `biquadric`, `sh25`, `bspline`: the paper's other
    /// methods).
    #[arg(long, help_heading = "Reflectance fields (prt reflectance)", value_enum, default_value_t = ReconstructArg::Linear)]
    pub reconstruct: ReconstructArg,
    /// Reflectance fields: the fine lat-long grid `WxH` the functions are reconstructed on and
    /// the environment is integrated over.
    #[arg(
        long,
        help_heading = "Reflectance fields (prt reflectance)",
        value_name = "WxH",
        default_value = "256x128"
    )]
    pub fine: String,
    /// Reflectance fields: compress each reconstructed function by non-linear wavelet
    /// approximation on the fine grid (with --coefficients K or --rf-error E) and relight as
    /// sparse dot products with the lighting's wavelet coefficients.
    #[arg(
        long,
        help_heading = "Reflectance fields (prt reflectance)",
        value_enum
    )]
    pub wavelet: Option<WaveletArg>,
    /// With --wavelet: keep this many coefficients per pixel and channel.
    #[arg(
        long,
        help_heading = "Reflectance fields (prt reflectance)",
        requires = "wavelet",
        conflicts_with = "rf_error"
    )]
    pub coefficients: Option<usize>,
    /// With --wavelet: keep per function the fewest coefficients whose relative L2 error is at
    /// most E (exact, on the fine grid).
    #[arg(
        long,
        help_heading = "Reflectance fields (prt reflectance)",
        requires = "wavelet"
    )]
    pub rf_error: Option<f64>,
    /// With --wavelet: measure rf_rel_l2 and rf_rel_h1 over an even subsample of at most N
    /// pixels (every ⌈P/N⌉-th of the P held pixels) instead of all of them. Each measured
    /// function costs an inverse transform: at full coverage (124k pixels, 256×128) that is
    /// most of the run. The coefficients kept and the image do not change.
    #[arg(
        long,
        help_heading = "Reflectance fields (prt reflectance)",
        value_name = "N",
        requires = "wavelet"
    )]
    pub rf_error_pixels: Option<usize>,
    /// Print one JSON object.
    #[arg(long, help_heading = "Output")]
    pub json: bool,
    /// Relight with the cheapest representation whose image reaches this PSNR against full
    /// order (8-bit view, whole image) at --target-rotations turns of the environment: uniform
    /// order truncation, the adaptive scheme (from --threshold, halved; per-vertex bakes), or —
    /// for a compressed bake — its clustered-PCA blocks, over --bake and every
    /// --candidate-bake (per vertex against per pixel); says which in a decision line and
    /// writes the image
    /// (--out, --png) at --rotate-y. With --study (and --adaptive): instead pick each frame's
    /// adaptive threshold from a random sample of pixels relit at full order, over the
    /// --frames frames (rotated by --rotate-y-step), and print each frame's threshold,
    /// estimate and time.
    #[arg(
        long,
        help_heading = "Adaptive to a PSNR target",
        allow_negative_numbers = true
    )]
    pub target_psnr: Option<f64>,
    /// Pixels of the --target-psnr estimate.
    #[arg(
        long,
        help_heading = "Adaptive to a PSNR target",
        default_value_t = 512
    )]
    pub probe_pixels: usize,
    /// With --target-psnr: also relight every frame at full order and at each lower order, to
    /// print the PSNR reached and the best uniform truncation meeting the same target.
    #[arg(long, help_heading = "Adaptive to a PSNR target")]
    pub verify: bool,
    /// With --target-psnr: the environment rotations (evenly spaced about +Y from --rotate-y)
    /// the chosen representation must reach the target at.
    #[arg(long, help_heading = "Adaptive to a PSNR target", default_value_t = 8)]
    pub target_rotations: usize,
    /// With --target-psnr: another bake of the same scene and camera (per vertex, per pixel,
    /// per texel, compressed or not) whose representations compete with --bake's; repeat for
    /// more. Every image is compared with --bake's full order, so give the most faithful bake
    /// (e.g. the per-pixel one) as --bake.
    #[arg(long, help_heading = "Adaptive to a PSNR target", value_name = "BAKE")]
    pub candidate_bake: Vec<PathBuf>,
    /// With --target-psnr and --adaptive: the per-frame study of adaptive relighting to the
    /// target (no image) instead of choosing a representation.
    #[arg(long, help_heading = "Adaptive to a PSNR target")]
    pub study: bool,
}

/// `--glossy` values (see [`prt_scene_relight::GlossyPath`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum GlossyArg {
    /// Zonal fit per view elevation (fast).
    Fitted,
    /// Per-elevation BRDF projections from the bake (reference).
    Exact,
    /// The fit, and the exact path where the fit's error reaches --fit-error.
    Hybrid,
    /// Spherical harmonic reflection map lookup with specular occlusion.
    Shrm,
    /// Per object: shrm where the lobe is too sharp for the baked order, fitted elsewhere.
    Auto,
}

/// `--stop` values (see [`StopRule`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum StopArg {
    /// The value has converged (the default).
    Convergence,
    /// Lee & Kim's Algorithm 1.
    Significance,
    /// Whichever comes first.
    Either,
}

/// `--threshold-unit` values: what the adaptive threshold measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum ThresholdUnit {
    /// Output radiance.
    Radiance,
    /// A fraction of the frame's mean radiance.
    Mean,
    /// The [0, 1] colour of the PNG view.
    Display,
}

impl RelightArgs {
    /// The threshold's unit, from `--threshold-unit` or its old spellings.
    fn unit(&self) -> ThresholdUnit {
        match (self.relative_threshold, self.display_threshold) {
            (true, _) => ThresholdUnit::Mean,
            (_, true) => ThresholdUnit::Display,
            _ => self.threshold_unit,
        }
    }
}

/// Runs `prt relight`.
pub fn run(args: &RelightArgs) -> Result<()> {
    check_args(args)?;
    let loaded = crate::common::load_scene(&args.scene)?;
    let bake = prt_bakefile::read_bake(&args.bake)?;
    if bake.reflectance.is_some() {
        return run_field(args, &loaded, &bake);
    }
    if !args.candidate_bake.is_empty() && (args.target_psnr.is_none() || args.study) {
        bail!("--candidate-bake is for --target-psnr without --study");
    }
    let (scene, accel) = prepare_sh(args, &loaded, &bake)?;
    let adaptive = args.adaptive.then(|| adaptive_params(args));
    if let Some(target) = args.target_psnr {
        if !args.study {
            if args.verify {
                bail!("--verify is for the --study of --target-psnr");
            }
            let candidates = candidate_bakes(args, &loaded)?;
            let mut bakes = vec![(&scene, &accel, &bake, args.bake.as_path())];
            bakes.extend(
                candidates
                    .iter()
                    .zip(&args.candidate_bake)
                    .map(|((s, a, b), p)| (s, a, b, p.as_path())),
            );
            return run_choose(args, &bakes, target);
        }
        let Some(params) = adaptive else {
            bail!("--study needs --adaptive");
        };
        if args.out.is_some() || args.png.is_some() || args.roi_png.is_some() {
            bail!("--study prints a per-frame study; without --study, --target-psnr writes the image of the representation it chooses");
        }
        return run_target(args, &scene, &accel, &bake, params, target);
    }
    if args.verify || args.study {
        bail!("--verify and --study need --target-psnr");
    }
    let mut opt = RelightOptions {
        order: args.order,
        adaptive,
        rotate_y_deg: args.rotate_y,
        timing_frames: 5,
        warmup_frames: 2,
        rotate_y_step_deg: 0.0,
        points: None,
        glossy: glossy_path(args)?,
        phong: args.phong_model.into(),
    };
    // Bound once: a per-pixel bake's footprints, a per-texel bake's lightmaps and the
    // camera's rays serve every relighting and image of the command.
    let bound = prt_scene_relight::Bound::new(&scene, &accel, &bake)?;
    let relit = bound.relight(&opt)?;
    let full_stats: Option<RelightStats> = if args.adaptive {
        let full = RelightOptions {
            adaptive: None,
            ..opt.clone()
        };
        Some(bound.relight(&full)?.stats)
    } else {
        None
    };
    // image_ms times image formation alone: the camera's rays are traced before it.
    if relit.footprints.is_none() {
        bound.image_rays()?;
    }
    let t = Instant::now();
    let image = bound.form_image(&relit, args.rotate_y)?;
    let image_ms = t.elapsed().as_secs_f64() * 1e3;
    let mut attrs = vec![
        ("kind", "relit".to_string()),
        ("order", relit.stats.order.to_string()),
        ("adaptive", args.adaptive.to_string()),
        ("rotate_y", args.rotate_y.to_string()),
    ];
    if let Some(t) = relit.stats.threshold {
        attrs.push(("threshold", t.to_string()));
    }
    if let Some(p) = &args.out {
        prt_scene_relight::io::write_exr(p, &image, &attrs)?;
    }
    if let Some(p) = &args.png {
        prt_scene_relight::io::write_png(p, &image, args.exposure)?;
    }
    if let Some(p) = &args.roi_png {
        let roi = prt_scene_relight::roi_image(&scene, &accel, &relit)?;
        prt_scene_relight::io::write_png(p, &roi, 0.0)?;
    }
    if let Some(p) = &args.vertex_colours {
        write_point_colours(p, &bake, &relit.radiance)?;
    }
    // Rotating-environment frames: one SH rotation per frame, then shading.
    let mut fps = None;
    if args.frames > 1 {
        // One call, K timed frames each lit by its own rotation: the rate covers the per-frame
        // work only (rotation, light product matrices, shading), not loading or setup.
        opt.timing_frames = args.frames;
        opt.rotate_y_step_deg = args.rotate_y_step;
        fps = Some(bound.relight(&opt)?.stats.fps);
    }
    print_summary(
        args,
        &relit.stats,
        full_stats.as_ref(),
        opt.glossy,
        image_ms,
        fps,
    )?;
    Ok(())
}

/// Checks an SH bake against the scene (and `args` against an SH bake) and returns the scene
/// it relights on (subdivided objects on the bake's refined meshes) with its BVH.
pub(crate) fn prepare_sh(
    args: &RelightArgs,
    scene: &prt_scene::Scene,
    bake: &prt_bakefile::Bake,
) -> Result<(prt_scene::Scene, prt_tracer::Accel)> {
    if args.wavelet.is_some()
        || args.coefficients.is_some()
        || args.rf_error.is_some()
        || args.rf_error_pixels.is_some()
    {
        bail!(
            "{}: --wavelet, --coefficients, --rf-error and --rf-error-pixels compress reflectance fields (prt reflectance); this is an SH bake",
            args.bake.display()
        );
    }
    prt_scene_relight::check_bake(scene, bake, &args.bake)?;
    // Subdivided objects relight on the bake's refined meshes.
    let scene = prt_scene_relight::baked_scene(scene, bake)?;
    let accel = prt_tracer::Accel::build(&scene).context("building the BVH")?;
    Ok((scene, accel))
}

/// Refuses option values and combinations `prt relight` cannot honour, before any file is read.
pub(crate) fn check_args(args: &RelightArgs) -> Result<()> {
    if args.frames == 0 {
        bail!("--frames must be at least 1");
    }
    if !args.threshold.is_finite() || args.threshold < 0.0 {
        bail!("--threshold must be a finite number ≥ 0");
    }
    if !args.rotate_y.is_finite() || !args.rotate_y_step.is_finite() {
        bail!("--rotate-y and --rotate-y-step must be finite");
    }
    if !args.exposure.is_finite() || args.exposure.abs() > 64.0 {
        bail!("--exposure must be a finite number of stops within ±64");
    }
    if !(0.0..=MAX_COST_EXPONENT).contains(&args.cost_exponent) {
        bail!("--cost-exponent must be a number within [0, {MAX_COST_EXPONENT}]");
    }
    if args.unit() == ThresholdUnit::Display && !args.adaptive {
        bail!("--threshold-unit display (--display-threshold) needs --adaptive");
    }
    if args.roi_png.is_some() && !args.adaptive {
        bail!("--roi-png needs --adaptive");
    }
    Ok(())
}

/// The adaptive relighting parameters of `--adaptive` (its threshold in the unit asked for).
pub(crate) fn adaptive_params(args: &RelightArgs) -> AdaptiveParams {
    AdaptiveParams {
        stop: match args.stop {
            StopArg::Convergence => StopRule::Convergence,
            StopArg::Significance => StopRule::Significance,
            StopArg::Either => StopRule::Either,
        },
        cost_exponent: args.cost_exponent,
        ..AdaptiveParams::new(match args.unit() {
            ThresholdUnit::Mean => Threshold::RelativeToMean(args.threshold),
            ThresholdUnit::Display => Threshold::Display {
                t: args.threshold,
                exposure_ev: args.exposure,
            },
            ThresholdUnit::Radiance => Threshold::Absolute(args.threshold),
        })
    }
}

/// The glossy path of `--glossy` (and `--fit-error`).
pub(crate) fn glossy_path(args: &RelightArgs) -> Result<prt_scene_relight::GlossyPath> {
    Ok(match args.glossy {
        GlossyArg::Fitted => prt_scene_relight::GlossyPath::Fitted,
        GlossyArg::Exact => prt_scene_relight::GlossyPath::Exact,
        GlossyArg::Shrm => prt_scene_relight::GlossyPath::Shrm,
        GlossyArg::Auto => prt_scene_relight::GlossyPath::Auto,
        GlossyArg::Hybrid => {
            if !(args.fit_error >= 0.0 && args.fit_error.is_finite()) {
                bail!(
                    "--fit-error {}: give a relative error of 0 or more",
                    args.fit_error
                );
            }
            prt_scene_relight::GlossyPath::Hybrid {
                fit_error: args.fit_error,
            }
        }
    })
}

/// Prints the run's figures: one JSON object with `--json`, else lines for a person.
fn print_summary(
    args: &RelightArgs,
    s: &RelightStats,
    full_stats: Option<&RelightStats>,
    glossy: prt_scene_relight::GlossyPath,
    image_ms: f64,
    fps: Option<f64>,
) -> Result<()> {
    if args.json {
        let threshold_kind = match args.unit() {
            ThresholdUnit::Mean => "relative to mean radiance",
            ThresholdUnit::Display => "display",
            ThresholdUnit::Radiance => "absolute radiance",
        };
        let obj = serde_json::json!({
            "order": s.order,
            "adaptive": s.adaptive,
            "threshold": s.threshold,
            "shade_ms": s.shade_ms,
            "full_shade_ms": full_stats.map_or(s.shade_ms, |f| f.shade_ms),
            "image_ms": image_ms,
            "roi_fraction_diffuse": s.roi_fraction_diffuse,
            "roi_fraction_specular": s.roi_fraction_specular,
            "level_fraction_diffuse": s.level_fraction_diffuse,
            "level_fraction_specular": s.level_fraction_specular,
            "mean_order_diffuse": s.mean_order_diffuse,
            "mean_order_specular": s.mean_order_specular,
            "work_fraction": s.products.zip(s.full_order_products).map(|(p, f)| p as f64 / f.max(1) as f64),
            "stop": args.adaptive.then(|| format!("{:?}", args.stop).to_lowercase()),
            "threshold_kind": args.adaptive.then_some(threshold_kind),
            "cost_exponent": args.adaptive.then_some(args.cost_exponent),
            "points": s.points,
            "glossy": glossy,
            "frames": args.frames,
            "fps": fps,
            "notes": s.notes,
        });
        outln!("{}", serde_json::to_string(&obj)?);
    } else {
        for n in &s.notes {
            eprintln!("note: {n}");
        }
        outln!(
            "order {}  points {}  shading {:.3} ms/frame (median of 5)  image {:.1} ms",
            s.order,
            s.points,
            s.shade_ms,
            image_ms
        );
        if let Some(f) = full_stats {
            outln!(
                "adaptive: threshold {:.4}, diffuse ROI {:.1}%, specular ROI {}, full order {:.3} ms ⇒ speed-up {:.2}×",
                s.threshold.unwrap_or(0.0),
                100.0 * s.roi_fraction_diffuse.unwrap_or(0.0),
                s.roi_fraction_specular.map_or("-".into(), |v| format!("{:.1}%", 100.0 * v)),
                f.shade_ms,
                f.shade_ms / s.shade_ms.max(1e-9)
            );
        }
        if let Some(fps) = fps {
            outln!(
                "{} frames of a rotating environment: {fps:.1} frames/s",
                args.frames
            );
        }
    }
    Ok(())
}

/// `--wavelet`.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum WaveletArg {
    /// Haar.
    Haar,
    /// LeGall 5/3.
    Legall53,
    /// CDF (Daubechies) 9/7.
    Cdf97,
}

/// How `--reconstruct` rebuilds a sampled reflectance function.
#[derive(Clone, Copy, Debug, clap::ValueEnum)]
pub enum ReconstructArg {
    /// Zero-order hold.
    Nearest,
    /// Bilinear in (φ, θ), periodic in azimuth.
    Linear,
    /// Wavelet interpolation, LeGall 5/3 (fine sizes: power-of-two multiples of the sampled).
    Legall53,
    /// Wavelet interpolation, CDF 9/7.
    Cdf97,
    /// Inverse-distance weighting of the 32 nearest samples (Shepard).
    Idw,
    /// A biquadric polynomial per hemisphere, least squares.
    Biquadric,
    /// Spherical harmonics, 25 coefficients, least squares.
    Sh25,
    /// Multilevel B-splines (Lee, Wolberg & Shin 1997).
    Bspline,
}

impl ReconstructArg {
    /// The reconstruction it names.
    pub fn method(self) -> prt_fields::relight::Reconstruction {
        use prt_fields::relight::Reconstruction as R;
        match self {
            ReconstructArg::Nearest => R::Nearest,
            ReconstructArg::Linear => R::Linear,
            ReconstructArg::Legall53 => R::LeGall53,
            ReconstructArg::Cdf97 => R::Cdf97,
            ReconstructArg::Idw => R::Idw,
            ReconstructArg::Biquadric => R::Biquadric,
            ReconstructArg::Sh25 => R::Sh25,
            ReconstructArg::Bspline => R::BSpline,
        }
    }
}

/// `prt relight` of a reflectance field.
fn run_field(
    args: &RelightArgs,
    scene: &prt_scene::Scene,
    bake: &prt_bakefile::Bake,
) -> Result<()> {
    if args.adaptive || args.order.is_some() || args.vertex_colours.is_some() {
        bail!("{}: a reflectance field relights per pixel: --adaptive, --order and --vertex-colours are for SH bakes", args.bake.display());
    }
    let field = prt_fields::relight::check_field(scene, bake, &args.bake)?;
    let accel = prt_tracer::Accel::build(scene).context("building the BVH")?;
    let opt = prt_fields::relight::FieldOptions {
        reconstruction: args.reconstruct.method(),
        fine: crate::reflectance_cmd::parse_grid(&args.fine, "--fine")?,
        rotate_y_deg: args.rotate_y,
        timing_frames: 5,
        compression: match (args.wavelet, args.coefficients, args.rf_error) {
            (None, ..) => None,
            (Some(w), k, e) => Some(prt_fields::relight::Compression {
                wavelet: match w {
                    WaveletArg::Haar => prt_wavelet::Wavelet::Haar,
                    WaveletArg::Legall53 => prt_wavelet::Wavelet::LeGall53,
                    WaveletArg::Cdf97 => prt_wavelet::Wavelet::Cdf97,
                },
                budget: match (k, e) {
                    (Some(k), None) => prt_fields::relight::Budget::Coefficients(k),
                    (None, Some(e)) => prt_fields::relight::Budget::RelativeError(e),
                    _ => bail!("--wavelet needs --coefficients K or --rf-error E"),
                },
                error_pixels: match args.rf_error_pixels {
                    Some(0) => bail!("--rf-error-pixels 0: measure at least one pixel"),
                    n => n,
                },
            }),
        },
    };
    // A rotating map: --frames K frames --rotate-y-step apart, relit from functions
    // reconstructed (and compressed) once; the first frame is the image written.
    let angles: Vec<f64> = (0..args.frames)
        .map(|k| args.rotate_y + args.rotate_y_step * k as f64)
        .collect();
    let (mut frames, stats) =
        prt_fields::relight::relight_field_frames(scene, &accel, bake, field, &opt, &angles)?;
    let flicker = if frames.len() > 2 {
        let mask = prt_scene_relight::object_mask(scene, &accel)?;
        prt_fields::relight::flicker(&frames, &mask)
    } else {
        None
    };
    let image = frames.swap_remove(0);
    let attrs = vec![
        ("kind", "relit-reflectance-field".to_string()),
        ("rotate_y", args.rotate_y.to_string()),
    ];
    if let Some(p) = &args.out {
        prt_scene_relight::io::write_exr(p, &image, &attrs)?;
    }
    if let Some(p) = &args.png {
        prt_scene_relight::io::write_png(p, &image, args.exposure)?;
    }
    if args.json {
        let mut v = serde_json::to_value(&stats)?;
        v["flicker"] = serde_json::json!(flicker);
        v["frames"] = args.frames.into();
        outln!("{}", serde_json::to_string(&v)?);
    } else {
        if let Some(f) = flicker {
            outln!(
                "{} frames {}° apart: flicker (relative RMS of the second difference in time, object pixels) {:.4}",
                args.frames,
                args.rotate_y_step,
                f
            );
        }
        if let (Some(w), Some(k), Some(e)) =
            (&stats.wavelet, stats.mean_coefficients, stats.rf_rel_l2)
        {
            outln!(
                "{w}: {k:.1} coefficients per pixel and channel, relative L2 error {:.3} % against the uncompressed functions ({:.0} ms to compress)",
                100.0 * e,
                stats.compress_ms.unwrap_or(0.0)
            );
        }
        outln!(
            "{} pixels × {}×{} directions, {:?} reconstruction on {}×{}: shading {:.3} ms/frame (median of 5), lighting {:.1} ms",
            stats.pixels,
            stats.directions[0],
            stats.directions[1],
            stats.reconstruction,
            stats.fine[0],
            stats.fine[1],
            stats.shade_ms,
            stats.lighting_ms
        );
    }
    Ok(())
}

/// Writes `object,point,r,g,b` rows for `--vertex-colours`, atomically.
fn write_point_colours(
    path: &std::path::Path,
    bake: &prt_bakefile::Bake,
    radiance: &[Vec<[f32; 3]>],
) -> Result<()> {
    use std::io::Write;
    prt_tracer::output::write_atomically(path, |w| {
        let mut rows = || -> std::io::Result<()> {
            writeln!(w, "object,point,r,g,b")?;
            for (o, values) in bake.objects.iter().zip(radiance) {
                // Names are written as they are unless they need CSV quoting.
                let name = if o.name.contains([',', '"', '\n', '\r']) {
                    format!("\"{}\"", o.name.replace('"', "\"\""))
                } else {
                    o.name.clone()
                };
                for (p, [r, g, b]) in values.iter().enumerate() {
                    writeln!(w, "{name},{},{r},{g},{b}", o.point_first + p as u64)?;
                }
            }
            Ok(())
        };
        rows().map_err(|e| e.to_string())
    })?;
    Ok(())
}

/// The bakes of `--candidate-bake`, each checked against the scene, with the scene it
/// relights (its refined meshes, if subdivided) and that scene's BVH.
fn candidate_bakes(
    args: &RelightArgs,
    loaded: &prt_scene::Scene,
) -> Result<Vec<(prt_scene::Scene, prt_tracer::Accel, prt_bakefile::Bake)>> {
    args.candidate_bake
        .iter()
        .map(|path| {
            let bake = prt_bakefile::read_bake(path)?;
            if bake.reflectance.is_some() {
                bail!(
                    "{}: a reflectance field is not an SH bake: --candidate-bake takes SH bakes",
                    path.display()
                );
            }
            prt_scene_relight::check_bake(loaded, &bake, path)?;
            let scene = prt_scene_relight::baked_scene(loaded, &bake)
                .with_context(|| path.display().to_string())?;
            let accel = prt_tracer::Accel::build(&scene).context("building the BVH")?;
            Ok((scene, accel, bake))
        })
        .collect()
}

/// The kind of points of a bake, for the decision line.
fn point_kind(bake: &prt_bakefile::Bake) -> &'static str {
    match bake.meta.sample_kind {
        prt_bakefile::SampleKind::Vertex => "per vertex",
        prt_bakefile::SampleKind::Pixel { .. } => "per pixel",
        prt_bakefile::SampleKind::Texel { .. } => "per texel",
    }
}

/// A bake to choose from: its scene, BVH, bake and path.
type ChoiceBake<'a> = (
    &'a prt_scene::Scene,
    &'a prt_tracer::Accel,
    &'a prt_bakefile::Bake,
    &'a std::path::Path,
);

/// `prt relight --target-psnr P`: the cheapest representation meeting the target at the
/// rotations over the bakes given (`--bake` first, then `--candidate-bake`), a decision line
/// saying which, and its image.
fn run_choose(args: &RelightArgs, bakes: &[ChoiceBake<'_>], target: f64) -> Result<()> {
    use prt_scene_relight::target::{Candidate, Representation};
    anyhow::ensure!(
        args.target_rotations >= 1,
        "--target-rotations must be at least 1"
    );
    let n = args.target_rotations;
    let base = RelightOptions {
        order: args.order,
        glossy: glossy_path(args)?,
        phong: args.phong_model.into(),
        ..Default::default()
    };
    let adaptive = adaptive_params(args);
    let opt = prt_scene_relight::target::ChooseOptions {
        target_psnr: target,
        rotations: (0..n)
            .map(|k| args.rotate_y + 360.0 * k as f64 / n as f64)
            .collect(),
        base: base.clone(),
        adaptive,
        adaptive_tries: 4,
    };
    let bounds = bakes
        .iter()
        .map(|(s, a, b, _)| prt_scene_relight::Bound::new(s, a, b))
        .collect::<Result<Vec<_>, _>>()?;
    let choice = prt_scene_relight::target::choose_representation(&bounds, &opt)
        .with_context(|| format!("{}", args.bake.display()))?;
    let several = bakes.len() > 1;
    let name = |c: &Candidate| {
        let compressed = bakes[c.bake]
            .2
            .objects
            .iter()
            .any(|o| o.blocks.iter().any(|b| b.cpca.is_some()));
        let what = match c.representation {
            Representation::Uniform { order } if compressed => {
                format!("clustered-PCA blocks at order {order}")
            }
            Representation::Uniform { order } => format!("uniform order {order}"),
            Representation::Adaptive { threshold } => format!("adaptive, threshold {threshold}"),
        };
        if several {
            let (_, _, b, p) = bakes[c.bake];
            format!("{what}, {} ({})", point_kind(b), p.display())
        } else {
            what
        }
    };
    let bound = &bounds[choice.chosen.bake];
    let relit = bound.relight(&prt_scene_relight::target::chosen_options(
        &base,
        &choice.chosen.representation,
        &adaptive,
        args.rotate_y,
    ))?;
    let image = bound.form_image(&relit, args.rotate_y)?;
    let attrs = vec![
        ("kind", "relit".to_string()),
        ("order", relit.stats.order.to_string()),
        ("representation", name(&choice.chosen)),
        ("target_psnr", target.to_string()),
        ("rotate_y", args.rotate_y.to_string()),
    ];
    if let Some(p) = &args.out {
        prt_scene_relight::io::write_exr(p, &image, &attrs)?;
    }
    if let Some(p) = &args.png {
        prt_scene_relight::io::write_png(p, &image, args.exposure)?;
    }
    if args.json {
        outln!("{}", serde_json::to_string(&choice)?);
        return Ok(());
    }
    let figures = |c: &Candidate| {
        format!(
            "{}: lowest {:.2} dB, {:.3e} products/frame",
            name(c),
            c.min_psnr,
            c.cost
        )
    };
    outln!(
        "decision: {} — the cheapest representation whose image reaches {target} dB against {} at {n} rotations ({:.2} dB lowest, {:.3e} modelled products/frame)",
        name(&choice.chosen),
        if several { format!("the full order of {} ({})", args.bake.display(), point_kind(bakes[0].2)) } else { "full order".into() },
        choice.chosen.min_psnr,
        choice.chosen.cost
    );
    for c in &choice.tried {
        outln!("  tried {}", figures(c));
    }
    if !bakes.iter().any(|(_, _, b, _)| {
        b.objects
            .iter()
            .any(|o| o.blocks.iter().any(|x| x.cpca.is_some()))
    }) {
        outln!(
            "  compressed: not a candidate (no bake given is compressed; `prt compress --scene` makes one, which --candidate-bake adds)"
        );
    }
    if !several {
        outln!(
            "  per vertex or per pixel: not compared (one bake given; bake the other kind and add it with --candidate-bake)"
        );
    }
    outln!(
        "shading: {:.3} ms/frame chosen, {:.3} ms/frame the best uniform order ({}; median of 5 frames)",
        choice.shade_ms.0,
        choice.shade_ms.1,
        name(&choice.best_uniform)
    );
    Ok(())
}

/// `prt relight --adaptive --target-psnr P --study`: the per-frame study.
fn run_target(
    args: &RelightArgs,
    scene: &prt_scene::Scene,
    accel: &prt_tracer::Accel,
    bake: &prt_bakefile::Bake,
    adaptive: AdaptiveParams,
    target: f64,
) -> Result<()> {
    let opt = prt_scene_relight::target::TargetOptions {
        order: args.order,
        adaptive,
        target_psnr: target,
        probe_pixels: args.probe_pixels,
        seed: bake.meta.seed,
        rotations: (0..args.frames)
            .map(|k| args.rotate_y + args.rotate_y_step * k as f64)
            .collect(),
        warmup_frames: 1,
        verify: args.verify,
    };
    let study = prt_scene_relight::target::relight_to_target(scene, accel, bake, &opt)
        .with_context(|| format!("{}", args.bake.display()))?;
    if args.json {
        outln!("{}", serde_json::to_string(&study)?);
        return Ok(());
    }
    outln!(
        "target {target} dB against full order; probe: {} of {} object pixels, {} vertices at full order per frame",
        study.probe_pixels, study.candidate_pixels, study.probe_points
    );
    outln!("rotate°  threshold  tries  PSNR est.  lower   actual   shade ms  probe ms  full ms");
    for f in &study.frames {
        outln!(
            "{:>7.1} {:>10.4} {:>6} {:>10.2} {:>6.2} {:>8} {:>10.3} {:>9.3} {:>8}",
            f.rotate_y_deg,
            f.threshold,
            f.tries,
            f.psnr_estimate,
            f.psnr_lower,
            f.psnr_actual.map_or("-".into(), |p| format!("{p:.2}")),
            f.shade_ms,
            f.probe_ms,
            f.full_ms.map_or("-".into(), |m| format!("{m:.3}")),
        );
    }
    if let (Some(s), Some(u), Some(us), Some(min)) = (
        study.speedup,
        &study.uniform,
        study.uniform_speedup,
        study.min_psnr_actual,
    ) {
        outln!(
            "median {:.3} ms/frame: {s:.2}× faster than full order, lowest PSNR reached {min:.2} dB; uniform truncation at order {} meets the target at {:.3} ms ({us:.2}×, lowest {:.2} dB)",
            study.median_shade_ms, u.order, u.ms, u.min_psnr
        );
    } else {
        outln!("median {:.3} ms/frame", study.median_shade_ms);
    }
    Ok(())
}
