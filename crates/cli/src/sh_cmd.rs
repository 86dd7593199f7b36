//! `prt sh ...`: spherical-harmonic utilities.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand, ValueEnum};
use glam::DVec3;
use prt_sh::{EnvMapping, ImageRef, MAX_ORDER};
use std::path::PathBuf;

/// Spherical-harmonic subcommands.
#[derive(Subcommand)]
pub enum ShCommand {
    /// Project an environment map (EXR or HDR) onto SH to a given order (band count).
    Project(ProjectArgs),
    /// Evaluate all basis functions of an order at a direction.
    Eval(EvalArgs),
}

/// Environment-map parametrisation.
#[derive(Clone, Copy, ValueEnum)]
pub enum MappingArg {
    /// Equirectangular (CONVENTIONS.md).
    Latlong,
    /// Debevec angular light probe.
    Angular,
}

/// Options of `prt sh project`.
#[derive(Args)]
pub struct ProjectArgs {
    /// The map: .exr or Radiance .hdr, linear RGB.
    pub map: PathBuf,
    /// Order = number of bands (order² coefficients).
    #[arg(long)]
    pub order: usize,
    /// How the image maps to directions.
    #[arg(long, value_enum, default_value = "latlong")]
    pub mapping: MappingArg,
    /// Rotation of the environment about +Y, degrees (Mitsuba's to_world sense).
    #[arg(long, default_value_t = 0.0, allow_negative_numbers = true)]
    pub rotate_y: f64,
    /// Subsamples per texel side for angular maps (k×k midpoint rule).
    #[arg(long, default_value_t = 4)]
    pub angular_subsamples: usize,
    /// Print one JSON object `{"order": N, "coefficients": [[r,g,b], ...]}`.
    #[arg(long)]
    pub json: bool,
}

/// Options of `prt sh eval`.
#[derive(Args)]
pub struct EvalArgs {
    /// Order = number of bands.
    #[arg(long)]
    pub order: usize,
    /// Direction `X,Y,Z` (normalised before evaluation).
    #[arg(long, allow_hyphen_values = true)]
    pub dir: String,
    /// Print one JSON object `{"order": N, "values": [...]}`.
    #[arg(long)]
    pub json: bool,
}

/// Runs an `sh` subcommand.
pub fn run(cmd: ShCommand) -> Result<()> {
    match cmd {
        ShCommand::Project(args) => project(&args),
        ShCommand::Eval(args) => eval(&args),
    }
}

fn check_order(order: usize) -> Result<()> {
    if order == 0 || order > MAX_ORDER {
        bail!("--order {order} is out of range: it must be between 1 and {MAX_ORDER} (order = number of bands)");
    }
    Ok(())
}

fn project(args: &ProjectArgs) -> Result<()> {
    check_order(args.order)?;
    if !args.rotate_y.is_finite() {
        bail!("--rotate-y must be a finite number of degrees");
    }
    let loaded = prt_scene::load_env_image(&args.map)?;
    for w in &loaded.warnings {
        eprintln!("warning: {w}");
    }
    let img = &loaded.image;
    let mapping = match args.mapping {
        MappingArg::Latlong => EnvMapping::LatLong,
        MappingArg::Angular => EnvMapping::Angular {
            subsamples: args.angular_subsamples,
        },
    };
    let image = ImageRef {
        width: img.width,
        height: img.height,
        texels: &img.texels,
    };
    let coeffs = prt_sh::project_env(image, mapping, args.order, args.rotate_y)
        .with_context(|| format!("projecting {}", args.map.display()))?;
    if args.json {
        let obj = serde_json::json!({ "order": args.order, "coefficients": coeffs });
        outln!("{}", serde_json::to_string(&obj)?);
    } else {
        outln!(
            "# SH projection of {} to order {} ({} coefficients)",
            args.map.display(),
            args.order,
            coeffs.len()
        );
        outln!(
            "{:>5} {:>4} {:>5} {:>16} {:>16} {:>16}",
            "index",
            "l",
            "m",
            "red",
            "green",
            "blue"
        );
        for (i, c) in coeffs.iter().enumerate() {
            let (l, m) = prt_sh::degree_and_order(i);
            outln!(
                "{i:>5} {l:>4} {m:>5} {:>16.9e} {:>16.9e} {:>16.9e}",
                c[0],
                c[1],
                c[2]
            );
        }
    }
    Ok(())
}

fn parse_dir(text: &str) -> Result<DVec3> {
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    if parts.len() != 3 {
        bail!("--dir must be three comma-separated numbers X,Y,Z, got {text:?}");
    }
    let mut v = [0.0; 3];
    for (slot, p) in v.iter_mut().zip(&parts) {
        *slot = p
            .parse::<f64>()
            .with_context(|| format!("--dir component {p:?} is not a number"))?;
        if !slot.is_finite() {
            bail!("--dir component {p:?} is not finite");
        }
    }
    let d = DVec3::from_array(v);
    if d.length() == 0.0 {
        bail!("--dir must not be the zero vector");
    }
    Ok(d)
}

fn eval(args: &EvalArgs) -> Result<()> {
    check_order(args.order)?;
    let d = parse_dir(&args.dir)?;
    let values = prt_sh::eval_basis(args.order, d)?;
    if args.json {
        let obj = serde_json::json!({ "order": args.order, "values": values });
        outln!("{}", serde_json::to_string(&obj)?);
    } else {
        for (i, v) in values.iter().enumerate() {
            let (l, m) = prt_sh::degree_and_order(i);
            outln!("{i:>5} {l:>4} {m:>5} {v:>24.17e}");
        }
    }
    Ok(())
}
