//! `prt reflectance`: sample a scene's reflectance field (Masselus et al. 2004) into a bake
//! file (SPEC §3.14), and the `prt relight` path that relights one.

use anyhow::{bail, Context, Result};
use clap::Args;
use prt_bakefile::ScalarType;
use prt_fields::sample::{ReflectanceSettings, MAX_DIRECTIONS};
use std::path::PathBuf;

/// Options of `prt reflectance`.
#[derive(Args)]
pub struct ReflectanceArgs {
    /// The scene file.
    pub scene: PathBuf,
    /// The lat-long grid of light directions, `WxH` (azimuth × polar angle), e.g. 64x32; a
    /// directional light from the centre of each cell, as a light stage samples.
    #[arg(long, value_name = "WxH")]
    pub directions: String,
    /// Interreflection bounces (default: the scene's `[render] bounces`). Each costs
    /// --rays paths per footprint sample with a shadow ray to every direction at every vertex.
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Paths per footprint sample for the bounces.
    #[arg(long, default_value_t = 16)]
    pub rays: u32,
    /// Footprint samples per pixel (the box footprint of `prt render`; per-pixel bakes'
    /// default: fewer leave the coverage of silhouettes against a bright background coarse).
    #[arg(long, default_value_t = prt_bake::DEFAULT_PIXEL_SAMPLES)]
    pub pixel_samples: u32,
    /// Seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Store the values as f16 (half the file; the field is sampled straight into f16, so
    /// half the memory too).
    #[arg(long)]
    pub f16: bool,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Output file (.prtb).
    #[arg(long)]
    pub out: PathBuf,
}

/// Parses `WxH`.
pub fn parse_grid(text: &str, what: &str) -> Result<[u32; 2]> {
    let Some((w, h)) = text.split_once(['x', 'X']) else {
        bail!("{what} {text:?}: give WxH, e.g. 64x32");
    };
    let (w, h): (u32, u32) = (
        w.trim()
            .parse()
            .with_context(|| format!("{what} {text:?}: width"))?,
        h.trim()
            .parse()
            .with_context(|| format!("{what} {text:?}: height"))?,
    );
    Ok([w, h])
}

/// Runs `prt reflectance`.
pub fn run(args: &ReflectanceArgs) -> Result<()> {
    let directions = parse_grid(&args.directions, "--directions")?;
    let scene = crate::common::load_scene(&args.scene)?;
    let bounces = crate::common::bake_bounces(args.bounces, &scene, &args.scene)?;
    let scalar = if args.f16 {
        ScalarType::F16
    } else {
        ScalarType::F32
    };
    let settings = ReflectanceSettings {
        directions,
        bounces,
        rays: args.rays,
        pixel_samples: args.pixel_samples,
        seed: args.seed.unwrap_or(scene.render.seed),
        progress: true,
        // Sampled straight into the file's precision: an f16 field is never held as f32.
        scalar,
    };
    let dirs = u64::from(directions[0]) * u64::from(directions[1]);
    if dirs > MAX_DIRECTIONS || directions[0] < 2 || directions[1] < 1 {
        bail!(
            "--directions {}: give at least 2x1 and at most {MAX_DIRECTIONS} directions",
            args.directions
        );
    }
    // The file's size: every pixel could hold a function.
    let pixels = u64::from(scene.camera.width) * u64::from(scene.camera.height);
    let bytes = pixels * 3 * dirs * if args.f16 { 2 } else { 4 };
    if bytes > 8 << 30 {
        bail!(
            "--directions {} at {}×{} pixels would write up to {} GiB: use fewer directions or a smaller image",
            args.directions,
            scene.camera.width,
            scene.camera.height,
            bytes >> 30
        );
    }
    if !args.json {
        eprintln!(
            "sampling {}×{} directions per pixel: at most {:.3e} shadow rays",
            directions[0],
            directions[1],
            prt_fields::sample::shadow_ray_estimate(&scene, &settings) as f64
        );
    }
    let accel = prt_tracer::Accel::build(&scene).context("building the BVH")?;
    let (field, stats) = prt_fields::sample::sample_field(&scene, &accel, &settings)?;
    let bake = prt_fields::sample::field_bake(&scene, field, &settings);
    prt_bakefile::write_bake(&args.out, &bake, scalar)?;
    if args.json {
        outln!(
            "{}",
            serde_json::json!({
                "directions": directions,
                "bounces": bounces,
                "pixels": stats.pixels,
                "shadow_rays": stats.shadow_rays,
                "seconds": stats.seconds,
            })
        );
    } else {
        outln!(
            "{} pixels × {}×{} directions, {} shadow rays in {:.2} s ({:.2} Mrays/s); wrote {}",
            stats.pixels,
            directions[0],
            directions[1],
            stats.shadow_rays,
            stats.seconds,
            stats.shadow_rays as f64 / stats.seconds.max(1e-9) / 1e6,
            args.out.display()
        );
    }
    Ok(())
}
