//! `prt render`: a path-traced reference image of a scene file.

use anyhow::{bail, Context, Result};
use clap::{Args, ValueEnum};
use prt_tracer::{
    output, EnvSampling, MisHeuristic, Mode, RenderSettings, Renderer, SamplerKind, SplitLobes,
};
use std::path::PathBuf;

/// MIS heuristic names on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum MisArg {
    /// Veach's power heuristic (exponent 2).
    Power,
    /// Veach's balance heuristic.
    Balance,
}

/// Environment sampling densities on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum EnvSamplingArg {
    /// Proportional to luminance × solid angle.
    Luminance,
    /// MIS compensation (Karlík et al. 2019): max(0, luminance − the map's mean) × solid
    /// angle; lower variance, same expectation.
    Compensated,
    /// MIS compensation per shading normal: cos⁺ × max(0, luminance − half the mean over the
    /// normal's hemisphere) × solid angle, tabulated for 1024 normals; the lowest variance.
    PerNormal,
}

/// Pixel sampler names on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SamplerArg {
    /// Two independent scrambled Sobol sequences (even and odd samples): the image's own
    /// unbiased noise estimate, needed by --target-noise and --target-psnr-ldr.
    Replicas,
    /// One scrambled Sobol sequence of all the samples: lower variance at the same sample
    /// count (up to 1/√2 of the error where the image is smooth), no noise estimate.
    Single,
}

/// Lobe-splitting choices on the command line.
#[derive(Clone, Copy, Debug, ValueEnum)]
pub enum SplitLobesArg {
    /// Never split: one lobe chosen at random, as Mitsuba and pbrt do.
    None,
    /// Diffuse-plus-mirror materials: the mirror ray and a diffuse sample at every such
    /// vertex (the lowest noise per sample).
    Mirror,
    /// Diffuse-plus-mirror materials (the default): the mirror ray at every such vertex, the
    /// diffuse lobe as often as a one-sample lobe choice takes it (nearly the same noise for
    /// a fifth of the extra time).
    Delta,
    /// Every material of two lobes, glossy ones too (pays where the lobes see different
    /// light; measure your scene).
    All,
}

/// Options of `prt render`.
#[derive(Args, Debug)]
pub struct RenderArgs {
    /// Scene file (TOML).
    pub scene: PathBuf,
    /// Samples per pixel (default: the scene's `[render] spp`). With --target-noise or
    /// --time-budget: the most it may take (default: unlimited).
    #[arg(long)]
    pub spp: Option<u32>,
    /// Keep sampling until the image's own estimate of its relative noise on object pixels
    /// (from its two half images) is below this, e.g. 0.01 for 1 %; printed with the result.
    #[arg(long, allow_hyphen_values = true)]
    pub target_noise: Option<f64>,
    /// Keep sampling until the image's own estimate of its noise ceiling on the 8-bit view
    /// (PSNR of its sRGB view at 0 EV against its expectation, object pixels) reaches this
    /// many dB, e.g. 45; printed with the result. With --target-noise, both must hold.
    #[arg(long, allow_hyphen_values = true)]
    pub target_psnr_ldr: Option<f64>,
    /// Stop when the next pass of samples would not fit in this many seconds (with
    /// --target-noise: whichever comes first). An error if not even the first pass (8 spp)
    /// fits.
    #[arg(long, allow_hyphen_values = true)]
    pub time_budget: Option<f64>,
    /// Indirect bounces: 0 = direct light with shadows, -1 = unlimited (Russian roulette)
    /// (default: the scene's `[render] bounces`).
    #[arg(long, allow_hyphen_values = true)]
    pub bounces: Option<i32>,
    /// Global seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Worker threads (default: all cores). The image does not depend on it.
    #[arg(long)]
    pub threads: Option<usize>,
    /// Output EXR (linear RGB f32 with metadata) (default: the scene file's name with .exr).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Also write an 8-bit sRGB PNG view here.
    #[arg(long)]
    pub png: Option<PathBuf>,
    /// Exposure of the PNG view in EV.
    #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
    pub exposure: f32,
    /// Ignore visibility: every direction above the surface sees the environment.
    #[arg(long, conflicts_with = "ao")]
    pub unshadowed: bool,
    /// Render ambient occlusion instead of radiance.
    #[arg(long)]
    pub ao: bool,
    /// With --ao: occluders further than this do not count.
    #[arg(long, requires = "ao")]
    pub ao_distance: Option<f32>,
    /// Add AOV channels to the EXR (normal, albedo, depth, variance).
    #[arg(long)]
    pub aovs: bool,
    /// MIS heuristic between environment and BRDF sampling.
    #[arg(long, value_enum, default_value_t = MisArg::Power)]
    pub mis: MisArg,
    /// Pixel sampler: `replicas` keeps the image's own noise estimate, `single` gives the
    /// lower error per sample.
    #[arg(long, value_enum, default_value_t = SamplerArg::Replicas)]
    pub sampler: SamplerArg,
    /// Environment sampling density: `per-normal` (MIS compensation per shading normal, the
    /// lowest variance), `compensated` (one MIS-compensated table) or `luminance`
    /// (proportional to the map); the same image in expectation.
    #[arg(long, value_enum, default_value_t = EnvSamplingArg::PerNormal)]
    pub env_sampling: EnvSamplingArg,
    /// Lobe splitting: which materials of two lobes follow more than the one lobe a random
    /// choice takes (the same image in expectation, less noise where the lobes see
    /// different light).
    #[arg(long, value_enum, default_value_t = SplitLobesArg::Delta)]
    pub split_lobes: SplitLobesArg,
    /// Lobe splitting happens at the first N vertices of a path (a camera sample ends in at
    /// most 2^N paths).
    #[arg(long, value_name = "N", default_value_t = 2)]
    pub split_depth: u32,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// Runs `prt render`.
///
/// # Errors
/// Unreadable or invalid scene, invalid settings, unwritable outputs.
pub fn run(args: &RenderArgs) -> Result<()> {
    let loaded = prt_scene::load_scene(&args.scene)
        .with_context(|| format!("cannot load scene {}", args.scene.display()))?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let scene = loaded.scene;
    let mut settings = RenderSettings::from_scene(&scene.render);
    settings.target_noise = args.target_noise;
    settings.time_budget = args.time_budget;
    settings.target_psnr_ldr = args.target_psnr_ldr;
    if args.target_noise.is_some() || args.time_budget.is_some() || args.target_psnr_ldr.is_some() {
        settings.spp = u32::MAX;
    }
    if let Some(spp) = args.spp {
        settings.spp = spp;
    }
    if let Some(b) = args.bounces {
        settings.bounces = b;
    }
    if let Some(s) = args.seed {
        settings.seed = s;
    }
    settings.threads = args.threads;
    settings.aovs = args.aovs;
    settings.progress = !args.quiet;
    settings.mis = match args.mis {
        MisArg::Power => MisHeuristic::Power,
        MisArg::Balance => MisHeuristic::Balance,
    };
    settings.sampler = match args.sampler {
        SamplerArg::Replicas => SamplerKind::Replicas,
        SamplerArg::Single => SamplerKind::Single,
    };
    settings.split_lobes = match args.split_lobes {
        SplitLobesArg::None => SplitLobes::None,
        SplitLobesArg::Mirror => SplitLobes::Mirror,
        SplitLobesArg::Delta => SplitLobes::Delta,
        SplitLobesArg::All => SplitLobes::All,
    };
    settings.split_depth = args.split_depth;
    settings.env_sampling = match args.env_sampling {
        EnvSamplingArg::Luminance => EnvSampling::Luminance,
        EnvSamplingArg::Compensated => EnvSampling::Compensated,
        EnvSamplingArg::PerNormal => EnvSampling::PerNormal,
    };
    settings.mode = if args.ao {
        Mode::AmbientOcclusion {
            max_distance: args.ao_distance,
        }
    } else if args.unshadowed {
        Mode::Unshadowed
    } else {
        Mode::Path
    };
    if !args.exposure.is_finite() {
        bail!("--exposure must be a finite number of stops");
    }
    let out_path = match &args.out {
        Some(p) => p.clone(),
        None => {
            let stem = args
                .scene
                .file_stem()
                .map_or("render".into(), |s| s.to_string_lossy().into_owned());
            PathBuf::from(format!("{stem}.exr"))
        }
    };

    let renderer = Renderer::new(&scene, settings).context("cannot prepare the scene")?;
    let image = renderer.render().context("render failed")?;
    output::write_exr(&out_path, &image)?;
    if let Some(png) = &args.png {
        output::write_png(png, &image, args.exposure)?;
    }
    let samples = f64::from(image.width) * f64::from(image.height) * f64::from(image.settings.spp);
    let noise = image.noise.map_or(String::new(), |e| {
        format!(
            ", noise {:.3} %{}{}",
            100.0 * e,
            args.target_noise
                .map_or(String::new(), |r| format!(" (target {:.3} %)", 100.0 * r)),
            image.noise_psnr_ldr.map_or(String::new(), |p| format!(
                ", 8-bit noise ceiling {p:.1} dB{}",
                args.target_psnr_ldr
                    .map_or(String::new(), |t| format!(" (target {t} dB)"))
            ))
        )
    });
    eprintln!(
        "rendered {}×{} at {} spp, bounces {}, seed {} in {:.2} s ({:.0} samples/s){noise} → {}",
        image.width,
        image.height,
        image.settings.spp,
        image.settings.bounces,
        image.settings.seed,
        image.seconds,
        samples / image.seconds.max(1e-9),
        out_path.display()
    );
    if image.invalid_samples > 0 {
        eprintln!(
            "warning: {} samples were NaN or infinite and counted as 0",
            image.invalid_samples
        );
    }
    Ok(())
}
