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
    /// Bake per texel of a SIZE×SIZE lightmap for every object with lightmap UVs (glTF
    /// TEXCOORD_1, else TEXCOORD_0; OBJ vt), one point per texel at the surface under its
    /// centre (texels a triangle only touches at its nearest point); objects without UVs get a
    /// generated atlas (per vertex when it does not fit or has fewer texels than vertices).
    /// Relit through bilinear lookup of the texels. UVs outside [0, 1] or
    /// overlapping charts are errors.
    #[arg(long, value_name = "SIZE", conflicts_with_all = ["per_pixel", "shard", "pass", "subdivide", "target_psnr"])]
    pub per_texel: Option<u32>,
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
    /// Distributed bounced bakes: run pass K of 0..=bounces. Pass 0 traces the direct transfer
    /// of the shard's vertices and records their ray hits; pass K ≥ 1 gathers bounce K for
    /// them from --previous (the merged file of pass K − 1) and --hits (the shard's own pass-0
    /// file); the last pass (K = bounces) writes
    /// the shard of the final bake (per-pixel bakes: it traces the shard's pixels). Merge each
    /// pass's shards with `prt merge` before the next pass. The merged last pass is byte for
    /// byte the unsharded bake, and all passes together trace the rays of one bake.
    /// Intermediate files are always stored as f32.
    #[arg(long, conflicts_with = "target_psnr")]
    pub pass: Option<u32>,
    /// The merged file of the previous pass (with --pass K ≥ 1).
    #[arg(long, requires = "pass")]
    pub previous: Option<PathBuf>,
    /// This shard's own pass-0 file (with --pass K ≥ 1 while bounces are gathered at
    /// vertices): it holds the shard's ray hits, which merged files do not carry.
    #[arg(long, requires = "pass")]
    pub hits: Option<PathBuf>,
    /// Per-vertex bakes: refine the meshes where the transfer changes fast (after D3DX's
    /// adaptive subdivision): split every edge whose midpoint's transfer (or whose triangle's
    /// centroid's) differs from the interpolation of the corners by more than
    /// --subdivide-error, repeat up to --max-subdivision levels, deciding from cheap probes
    /// (--subdivide-probe-rays), then bake the refined meshes with the full rays. The file
    /// holds the refined meshes; relight and export use them.
    #[arg(long, conflicts_with_all = ["per_pixel", "shard", "pass", "target_psnr"])]
    pub subdivide: bool,
    /// Relative difference between the transfer at a midpoint (or centroid) and its
    /// interpolation, bands 0–2, above which --subdivide splits (0: split everything).
    #[arg(long, default_value_t = 0.1, requires = "subdivide")]
    pub subdivide_error: f64,
    /// Refinement levels at most (each can double a region's vertex density).
    #[arg(long, default_value_t = 5, requires = "subdivide")]
    pub max_subdivision: u32,
    /// Directions of each probe --subdivide decides with (default: --rays / 4, at least 128;
    /// at most --rays; about half are traced): every point of an object probes the same world
    /// directions, so probes agree exactly where the points see the same sky.
    #[arg(long, requires = "subdivide", value_parser = clap::value_parser!(u32).range(1..))]
    pub subdivide_probe_rays: Option<u32>,
    /// Worker threads (default: all cores).
    #[arg(long)]
    pub threads: Option<usize>,
    /// Print the bake report as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// Output file (.prtb).
    #[arg(long, required_unless_present = "plan_shards")]
    pub out: Option<PathBuf>,
    /// Plan a distributed bake of these options in N shards per pass instead of baking: the
    /// expected time of each pass's slowest shard and merge and the sizes of its files, for a
    /// node like this machine. Measured by running the whole distributed bake (every pass,
    /// shard and merge) at two small ray counts and extrapolating linearly in the rays
    /// (--plan-probe-rays R: R and 2R rays per point).
    #[arg(long, value_name = "N", conflicts_with_all = ["shard", "pass", "previous", "hits", "per_texel", "subdivide", "target_psnr", "out"])]
    pub plan_shards: Option<u32>,
    /// With --plan-shards: the smaller of the two ray counts measured (default: 1/32 of
    /// --rays, at least 4).
    #[arg(long, value_name = "R", requires = "plan_shards")]
    pub plan_probe_rays: Option<u32>,
    /// With --plan-shards: where the measured bakes write their files (removed afterwards;
    /// default: the system's temporary directory). Give the shared file system the bake will
    /// use: reading and writing the files is part of each pass's time.
    #[arg(long, value_name = "DIR", requires = "plan_shards")]
    pub plan_dir: Option<PathBuf>,
    /// Model each object with only what it needs: path-trace a reference (to a noise ceiling
    /// 6 dB above this), bake per vertex at --order (default 13), and keep per object the
    /// lowest SH order whose PSNR against the reference over its pixels (8-bit view) reaches
    /// this many dB. An error that names the best reachable figure when an object cannot.
    #[arg(long, allow_negative_numbers = true, conflicts_with_all = ["per_pixel", "shard"])]
    pub target_psnr: Option<f64>,
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
    let loading = std::time::Instant::now();
    let scene = crate::common::load_scene(&args.scene)?;
    let load_seconds = loading.elapsed().as_secs_f64();
    let bounces = crate::common::bake_bounces(args.bounces, &scene, &args.scene)?;
    if let Some(p) = args.target_psnr {
        if !(p.is_finite() && p > 0.0) {
            bail!("--target-psnr {p} must be a positive, finite number of dB");
        }
    }
    let settings = BakeSettings {
        order: if args.target_psnr.is_some() {
            Some(
                args.order
                    .unwrap_or(prt_report::recommend::TARGET_HIGHEST_ORDER),
            )
        } else {
            args.order
        },
        max_order: args.max_order,
        error_target: args.error_target,
        rays: args.rays,
        bounces,
        seed: args.seed.unwrap_or(scene.render.seed),
        points: match (args.per_pixel, args.per_texel) {
            (true, _) => PointKind::Pixel,
            (false, Some(size)) => PointKind::Texel {
                width: size,
                height: size,
            },
            (false, None) => PointKind::Vertex,
        },
        pixel_samples: args.pixel_samples,
        unshadowed: args.unshadowed,
        shard: args.shard.as_deref().map(parse_shard).transpose()?,
        subdivide: args
            .subdivide
            .then_some(prt_bake::subdivide::SubdivideOptions {
                error: args.subdivide_error,
                max_levels: args.max_subdivision,
                probe_rays: args.subdivide_probe_rays,
                ..prt_bake::subdivide::SubdivideOptions::default()
            }),
        progress: true,
        ..BakeSettings::final_quality()
    };
    settings.validate()?;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build()?;
    if let Some(shards) = args.plan_shards {
        let probe = args.plan_probe_rays.unwrap_or((settings.rays / 32).max(4));
        let dir = args.plan_dir.clone().unwrap_or_else(std::env::temp_dir);
        return pool.install(|| {
            run_plan(
                &scene,
                &settings,
                shards,
                probe,
                load_seconds,
                &dir,
                args.json,
            )
        });
    }
    let out_path = args.out.as_ref().context("--out is required")?;
    let previous = match &args.previous {
        Some(p) => Some(prt_bakefile::read_bake(p)?),
        None => None,
    };
    let hits = match &args.hits {
        Some(p) => Some(prt_bakefile::read_bake(p)?),
        None => None,
    };
    let pass = args.pass.map(|index| prt_bake::PassInput {
        index,
        previous: previous.as_ref(),
        hits: hits.as_ref(),
    });
    let out = pool.install(|| -> Result<_> {
        let accel = prt_tracer::Accel::build(&scene)?;
        let out = prt_bake::bake_pass(&scene, &accel, &settings, pass).map_err(|e| {
            // Name the file the message is about.
            let file = match (&e, &args.hits, &args.previous) {
                (prt_bake::BakeError::Pass(m), Some(h), _) if m.contains("--hits file") => Some(h),
                (prt_bake::BakeError::Pass(_), _, Some(p)) => Some(p),
                _ => None,
            };
            match file {
                Some(f) => anyhow::anyhow!("{}: {e}", f.display()),
                None => e.into(),
            }
        })?;
        Ok(match args.target_psnr {
            Some(p) => prt_report::recommend::bake_to_target(&scene, &accel, out, &settings, p)
                .map_err(|e| match e {
                    prt_report::ReportError::TargetUnmet(m) => {
                        anyhow::anyhow!("{}: {m}", args.scene.display())
                    }
                    e => e.into(),
                })?,
            None => out,
        })
    })?;
    let intermediate = out.bake.meta.pass.clone();
    let scalar = if args.f16 && intermediate.is_none() {
        ScalarType::F16
    } else {
        ScalarType::F32
    };
    prt_bakefile::write_bake(out_path, &out.bake, scalar)?;
    if let Some(p) = &intermediate {
        eprintln!(
            "pass {} of passes 0..={}: an intermediate file; merge this pass's shards (prt merge), then run --pass {} --previous MERGED",
            p.index,
            p.last,
            p.index + 1
        );
    }
    if args.json {
        outln!("{}", serde_json::to_string(&out.report)?);
    } else {
        for d in &out.report.decisions {
            let who = d.object.as_deref().unwrap_or("bake");
            eprintln!("decision: {who}: {} ({})", d.decision, d.reason);
        }
        for o in &out.report.objects {
            outln!(
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
        outln!(
            "{} rays in {:.2} s ({:.2} Mrays/s); wrote {}",
            out.report.rays_traced,
            out.report.seconds,
            out.report.rays_traced as f64 / out.report.seconds.max(1e-9) / 1e6,
            out_path.display()
        );
    }
    Ok(())
}

/// `prt bake --plan-shards N`: prints the plan of the distributed bake of `settings`.
fn run_plan(
    scene: &prt_scene::Scene,
    settings: &BakeSettings,
    shards: u32,
    probe: u32,
    load_seconds: f64,
    dir: &std::path::Path,
    json: bool,
) -> Result<()> {
    // What each shard process pays before baking: the scene and its BVH.
    let start = std::time::Instant::now();
    let accel = prt_tracer::Accel::build(scene)?;
    let startup = load_seconds + start.elapsed().as_secs_f64();
    let plan =
        prt_bake::shard_plan::plan_shards(scene, &accel, settings, shards, probe, startup, dir)?;
    if json {
        outln!("{}", serde_json::to_string(&plan)?);
        return Ok(());
    }
    let mb = |b: f64| b / 1e6;
    outln!(
        "plan: {} shards per pass, {} rays per point, passes 0..={} (measured here at {} and {} rays in {:.1} s, extrapolated linearly; times for a node like this machine with {} threads)",
        plan.shards,
        plan.rays,
        settings.bounces,
        plan.probe_rays[0],
        plan.probe_rays[1],
        plan.probe_seconds,
        rayon::current_num_threads()
    );
    for p in &plan.passes {
        outln!(
            "pass {}: slowest shard {:.2} s, merge {:.2} s, {:.3e} rays; shard files up to {:.1} MB ({:.1} MB in all), merged {:.1} MB",
            p.pass,
            p.slowest_shard_seconds,
            p.merge_seconds,
            p.rays,
            mb(p.largest_shard_bytes),
            mb(p.shard_bytes),
            mb(p.merged_bytes)
        );
    }
    outln!(
        "expected wall time {:.1} s plus scheduling (about 1.3 s per job on an idle Slurm, 2 jobs per pass: tools/distributed/README.md)",
        plan.wall_seconds()
    );
    Ok(())
}

/// Runs `prt inspect`.
pub fn run_inspect(args: &InspectArgs) -> Result<()> {
    let bytes = std::fs::read(&args.file)
        .with_context(|| format!("{}: cannot read", args.file.display()))?;
    let view = BakeView::new(&bytes).map_err(|e| e.in_file(&args.file))?;
    let summary = view.summary();
    if args.json {
        outln!("{}", serde_json::to_string(&summary)?);
    } else {
        print_summary(&args.file, &summary)?;
    }
    Ok(())
}

fn print_summary(path: &std::path::Path, s: &Summary) -> Result<()> {
    outln!("{}", path.display());
    if let Some(f) = &s.file {
        outln!(
            "  format {}.{}, {}, {} bytes, {} sections",
            f.version[0],
            f.version[1],
            f.scalar_type.name(),
            f.file_size,
            f.sections.len()
        );
    }
    outln!(
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
        outln!("  environment: order {order} ({precision:?})");
    }
    for (m, lobe, order) in &s.brdfs {
        outln!("  BRDF {m}: {lobe}, order {order}");
    }
    for (m, order, n) in &s.glossy {
        outln!("  glossy table {m}: order {order}, {n} view elevations");
    }
    for o in &s.objects {
        outln!(
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
            outln!(
                "    {:<24} {:>10} scalars  min {:>12}  max {:>12}  NaN {}  inf {}",
                b.kind,
                b.scalars,
                b.min.map_or("-".into(), |v| format!("{v:.5e}")),
                b.max.map_or("-".into(), |v| format!("{v:.5e}")),
                b.nan_count,
                b.inf_count
            );
            if let Some(c) = &b.cpca {
                outln!(
                    "      stored as clustered PCA: {} clusters × {} components, relative L2 error {:.3e}",
                    c.clusters, c.components, c.rel_error
                );
            }
        }
        if let Some(r) = &o.ray_stats {
            outln!("    {r}");
        }
        if let Some(m) = &o.mesh {
            outln!("    {m}");
        }
        if let Some(c) = &o.coverage {
            outln!("    {c}");
        }
        if let Some(m) = &o.material {
            outln!("    {}", prt_bakefile::material_line(m));
        }
    }
    if let Some(c) = &s.camera {
        outln!("  {}", prt_bakefile::camera_line(c));
    }
    if let Some(r) = &s.reflectance {
        outln!(
            "  reflectance field: {} pixels × {}×{} directions ({} scalars)",
            r.pixels,
            r.directions[0],
            r.directions[1],
            r.scalars
        );
    }
    if let Some(p) = &s.pass {
        outln!(
            "  intermediate file of pass {} of a distributed bake (passes 0..={}), not a finished bake",
            p.index, p.last
        );
    }
    for d in &s.decisions {
        outln!(
            "  decision: {}: {} ({})",
            d.object.as_deref().unwrap_or("bake"),
            d.decision,
            d.reason
        );
    }
    Ok(())
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
    outln!("merged {} shards into {}", shards.len(), args.out.display());
    Ok(())
}

/// Options of `prt export`.
#[derive(Args)]
pub struct ExportArgs {
    /// The scene file the bake was made from.
    pub scene: PathBuf,
    /// The per-vertex or per-texel bake (.prtb).
    #[arg(long)]
    pub bake: PathBuf,
    /// Output binary glTF (.glb).
    #[arg(long)]
    pub out: PathBuf,
    /// What the file must fit (SPEC §10.2): `raw`, every coefficient a vertex attribute;
    /// `webgl2` (16 vertex attributes, textures ≤ 2048²) and `desktop` (16, ≤ 4096²), the
    /// transfer in vertex attributes when the primitive fits, else in a float data texture
    /// read by vertex id.
    #[arg(long, value_enum, default_value_t = TargetArg::Raw)]
    pub target: TargetArg,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// `prt export --target` values (see [`prt_gltf::Target`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum TargetArg {
    /// No limits (SPEC §10).
    Raw,
    /// WebGL 2.0.
    Webgl2,
    /// Desktop OpenGL 4.x / Vulkan 1.0.
    Desktop,
}

/// Runs `prt export`.
pub fn run_export(args: &ExportArgs) -> Result<()> {
    let scene = crate::common::load_scene(&args.scene)?;
    let bake = prt_bakefile::read_bake(&args.bake)?;
    prt_scene_relight::check_bake(&scene, &bake, &args.bake)?;
    let scene = prt_scene_relight::baked_scene(&scene, &bake)?;
    let target = match args.target {
        TargetArg::Raw => prt_gltf::Target::Raw,
        TargetArg::Webgl2 => prt_gltf::Target::Webgl2,
        TargetArg::Desktop => prt_gltf::Target::Desktop,
    };
    let summary = prt_gltf::export_glb_for(&scene, &bake, &args.out, target)
        .with_context(|| format!("{}: cannot export", args.bake.display()))?;
    if args.json {
        outln!("{}", serde_json::to_string(&summary)?);
    } else {
        outln!(
            "wrote {}: {} objects, {} vertices, {} transfer attributes (VEC4) per vertex, {} bytes",
            args.out.display(),
            summary.objects,
            summary.vertices,
            summary.attributes,
            summary.bytes
        );
        if target != prt_gltf::Target::Raw {
            outln!(
                "target {}: at most {} vertex attributes per primitive; {} objects with their transfer in a data texture",
                target.name(),
                summary.vertex_attributes,
                summary.transfer_textures
            );
        }
    }
    Ok(())
}
