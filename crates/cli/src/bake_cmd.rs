//! `prt bake`, `prt inspect`, `prt merge`: PRT bakes and their files.

use anyhow::{bail, Context, Result};
use clap::Args;
use prt_bake::{BakeSettings, PointKind};
use prt_bakefile::{BakeView, ScalarType, Summary};
use std::path::PathBuf;

/// Options of `prt bake`.
#[derive(Args)]
pub struct BakeArgs {
    /// The scene file (TOML).
    pub scene: PathBuf,
    /// Fixed order (bands) for every object; by default chosen per object from its material.
    #[arg(long)]
    pub order: Option<usize>,
    /// Largest order the automatic choice may pick.
    #[arg(long, default_value_t = 10)]
    pub max_order: usize,
    /// Automatic order: fraction of the material lobe's energy the truncation may lose.
    #[arg(long, default_value_t = 1e-3)]
    pub error_target: f64,
    /// Rays per point.
    #[arg(long, default_value_t = 1024)]
    pub rays: u32,
    /// Interreflection bounces (default: the scene's `[render] bounces`).
    #[arg(long)]
    pub bounces: Option<u32>,
    /// Bake the primary hit of every camera pixel instead of every vertex.
    #[arg(long)]
    pub per_pixel: bool,
    /// Per-pixel bakes: sub-pixel samples per pixel, stratified over the pixel's box (the
    /// footprint of `prt render`); the pixel's rays are shared out over them. 1 samples the
    /// pixel centre only.
    #[arg(long, requires = "per_pixel", default_value_t = prt_bake::DEFAULT_PIXEL_SAMPLES)]
    pub pixel_samples: u32,
    /// Seed (default: the scene's `[render] seed`).
    #[arg(long)]
    pub seed: Option<u64>,
    /// Store coefficients as f16.
    #[arg(long)]
    pub f16: bool,
    /// Also store the analytic unshadowed transfer.
    #[arg(long)]
    pub unshadowed: bool,
    /// Bake only shard I of N (`I/N`); `prt merge` joins the shards.
    #[arg(long)]
    pub shard: Option<String>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print the bake report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Output file (.prtb).
    #[arg(long)]
    pub out: PathBuf,
}

/// Options of `prt inspect`.
#[derive(Args)]
pub struct InspectArgs {
    /// A bake file.
    pub file: PathBuf,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Options of `prt merge`.
#[derive(Args)]
pub struct MergeArgs {
    /// The shard files, in any order.
    #[arg(required = true)]
    pub shards: Vec<PathBuf>,
    /// Output file.
    #[arg(long)]
    pub out: PathBuf,
}

fn parse_shard(text: &str) -> Result<(u32, u32)> {
    let (i, n) = text
        .split_once('/')
        .with_context(|| format!("--shard {text:?} must look like I/N, e.g. 0/4"))?;
    let i: u32 = i
        .trim()
        .parse()
        .with_context(|| format!("--shard index {i:?} is not a number"))?;
    let n: u32 = n
        .trim()
        .parse()
        .with_context(|| format!("--shard count {n:?} is not a number"))?;
    if n == 0 || i >= n {
        bail!("--shard {i}/{n}: the index must be below the count");
    }
    Ok((i, n))
}

/// Runs `prt bake`.
pub fn run_bake(args: &BakeArgs) -> Result<()> {
    let scene = crate::common::load_scene(&args.scene)?;
    let bounces = crate::common::bake_bounces(args.bounces, &scene, &args.scene)?;
    let settings = BakeSettings {
        order: args.order,
        max_order: args.max_order,
        error_target: args.error_target,
        rays: args.rays,
        bounces,
        seed: args.seed.unwrap_or(scene.render.seed),
        points: if args.per_pixel {
            PointKind::Pixel
        } else {
            PointKind::Vertex
        },
        pixel_samples: args.pixel_samples,
        unshadowed: args.unshadowed,
        shard: args.shard.as_deref().map(parse_shard).transpose()?,
        progress: true,
        ..BakeSettings::final_quality()
    };
    settings.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()?;
    let out = pool.install(|| -> Result<_> {
        let accel = prt_tracer::Accel::build(&scene)?;
        Ok(prt_bake::bake(&scene, &accel, &settings)?)
    })?;
    let scalar = if args.f16 {
        ScalarType::F16
    } else {
        ScalarType::F32
    };
    prt_bakefile::write_bake(&args.out, &out.bake, scalar)?;
    if args.json {
        println!("{}", serde_json::to_string(&out.report)?);
    } else {
        for d in &out.report.decisions {
            let who = d.object.as_deref().unwrap_or("bake");
            eprintln!("decision: {who}: {} ({})", d.decision, d.reason);
        }
        for o in &out.report.objects {
            println!(
                "{:<24} order {:>2}  points {:>8}  ray hits {:>5.1}%  back faces {:>4.1}%  started inside {:>4.1}%  kinds {}",
                o.name,
                o.order,
                o.points,
                100.0 * o.hit_fraction,
                100.0 * o.backface_fraction,
                100.0 * o.inside_fraction,
                o.kinds.join(", ")
            );
        }
        println!(
            "{} rays in {:.2} s ({:.2} Mrays/s); wrote {}",
            out.report.rays_traced,
            out.report.seconds,
            out.report.rays_traced as f64 / out.report.seconds.max(1e-9) / 1e6,
            args.out.display()
        );
    }
    Ok(())
}

/// Runs `prt inspect`.
pub fn run_inspect(args: &InspectArgs) -> Result<()> {
    let bytes = std::fs::read(&args.file)
        .with_context(|| format!("{}: cannot read", args.file.display()))?;
    let view = BakeView::new(&bytes).map_err(|e| e.in_file(&args.file))?;
    let summary = view.summary();
    if args.json {
        println!("{}", serde_json::to_string(&summary)?);
    } else {
        print_summary(&args.file, &summary);
    }
    Ok(())
}

fn print_summary(path: &std::path::Path, s: &Summary) {
    println!("{}", path.display());
    if let Some(f) = &s.file {
        println!(
            "  format {}.{}, {}, {} bytes, {} sections",
            f.version[0],
            f.version[1],
            f.scalar_type.name(),
            f.file_size,
            f.sections.len()
        );
    }
    println!(
        "  {:?}; {} rays per point, {} bounces, seed {}, shard {}/{}; made by {} {}",
        s.sample_kind,
        s.rays_per_point,
        s.bounces,
        s.seed,
        s.shard.index,
        s.shard.count,
        s.tool.name,
        s.tool.version
    );
    if let Some((order, precision)) = s.environment {
        println!("  environment: order {order} ({precision:?})");
    }
    for (m, lobe, order) in &s.brdfs {
        println!("  BRDF {m}: {lobe}, order {order}");
    }
    for (m, order, n) in &s.glossy {
        println!("  glossy table {m}: order {order}, {n} view elevations");
    }
    for o in &s.objects {
        println!(
            "  object {}: order {}, {} channel(s), points {}..{} of {}, geometry {}",
            o.name,
            o.order,
            o.channels,
            o.point_first,
            o.point_first + o.points_in_file,
            o.point_count,
            o.geometry_hash
        );
        for b in &o.blocks {
            println!(
                "    {:<24} {:>10} scalars  min {:>12}  max {:>12}  NaN {}  inf {}",
                b.kind,
                b.scalars,
                b.min.map_or("-".into(), |v| format!("{v:.5e}")),
                b.max.map_or("-".into(), |v| format!("{v:.5e}")),
                b.nan_count,
                b.inf_count
            );
        }
        if let Some(r) = &o.ray_stats {
            println!("    {r}");
        }
    }
    for d in &s.decisions {
        println!(
            "  decision: {}: {} ({})",
            d.object.as_deref().unwrap_or("bake"),
            d.decision,
            d.reason
        );
    }
}

/// Runs `prt merge`.
pub fn run_merge(args: &MergeArgs) -> Result<()> {
    let mut shards = Vec::with_capacity(args.shards.len());
    let mut scalar = None;
    for p in &args.shards {
        let bytes = std::fs::read(p).with_context(|| format!("{}: cannot read", p.display()))?;
        let view = BakeView::new(&bytes).map_err(|e| e.in_file(p))?;
        match scalar {
            None => scalar = Some(view.scalar_type()),
            Some(s) if s != view.scalar_type() => bail!(
                "{}: stored as {} but the first shard is {}",
                p.display(),
                view.scalar_type().name(),
                s.name()
            ),
            _ => {}
        }
        shards.push(prt_bakefile::decode(&bytes).map_err(|e| e.in_file(p))?);
    }
    let merged = prt_bakefile::merge(&shards)?;
    prt_bakefile::write_bake(&args.out, &merged, scalar.unwrap_or(ScalarType::F32))?;
    println!("merged {} shards into {}", shards.len(), args.out.display());
    Ok(())
}
