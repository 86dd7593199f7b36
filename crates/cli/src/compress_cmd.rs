//! `prt compress`: clustered-PCA compression (Sloan, Hall, Hart & Snyder 2003) of every
//! transfer block of a bake, to a PSNR target on the relit image when the scene is given.

use anyhow::{Context, Result};
use clap::Args;
use prt_bake::compress::{BakeFit, BlockCompression, Components, CompressPolicy};
use prt_bakefile::{Bake, BakeView};
use prt_scene_relight::{Bound, RelightOptions};
use std::path::{Path, PathBuf};

/// Options of `prt compress`.
#[derive(Args)]
pub struct CompressArgs {
    /// The bake to compress (.prtb).
    pub input: PathBuf,
    /// Output file (.prtb).
    #[arg(long)]
    pub out: PathBuf,
    /// The scene the bake was made from: the error target then applies to the relit image
    /// (--target-psnr against the uncompressed bake's image, over --rotations turns of the
    /// environment), and the shading time of both bakes is measured. Without it the target
    /// is the coefficients' relative L2 error (--error).
    #[arg(long)]
    pub scene: Option<PathBuf>,
    /// With --scene: the PSNR (dB, 8-bit view, whole image) the compressed bake's relit image
    /// must reach against the uncompressed bake's at every rotation; the smallest file that
    /// does is written.
    #[arg(long, default_value_t = 40.0)]
    pub target_psnr: f64,
    /// With --scene: environment rotations (evenly spaced about +Y) the target must hold at.
    #[arg(long, default_value_t = 8)]
    pub rotations: usize,
    /// Clusters per object (default: one per 256 points, 1 to 64).
    #[arg(long)]
    pub clusters: Option<usize>,
    /// Basis vectors per cluster (default: from the target).
    #[arg(long)]
    pub components: Option<usize>,
    /// Without --scene: the relative L2 error of the compressed coefficients that the default
    /// --components aims at. With --scene: the error whose component count the clusters are
    /// refined for (the image target then picks the stored size).
    #[arg(long, default_value_t = 0.01)]
    pub error: f64,
    /// Print one JSON object.
    #[arg(long)]
    pub json: bool,
}

/// Relative L2 errors (of the coefficients) tried per block, loosest first: each ≈ 1/√2 of
/// the one before, so the stored size moves in small steps.
const LADDER: [f64; 14] = [
    0.4, 0.28, 0.2, 0.14, 0.1, 0.07, 0.05, 0.035, 0.025, 0.018, 0.0125, 0.009, 0.006, 0.004,
];

/// Runs `prt compress`.
pub fn run(args: &CompressArgs) -> Result<()> {
    let bytes = std::fs::read(&args.input)
        .with_context(|| format!("{}: cannot read", args.input.display()))?;
    let view = BakeView::new(&bytes).map_err(|e| e.in_file(&args.input))?;
    let scalar = view.scalar_type();
    let original = view.to_bake().map_err(|e| e.in_file(&args.input))?;
    let policy = CompressPolicy {
        clusters: args.clusters,
        components: args.components,
        error_target: args.error,
    };
    let about_file = |e: prt_bake::compress::CompressError| match e.is_about_the_file() {
        true => anyhow::anyhow!("{}: {e}", args.input.display()),
        false => anyhow::anyhow!("{e}"),
    };
    let fit = prt_bake::compress::fit_bake(&original, &policy).map_err(about_file)?;
    let (bake, rows, image) = match &args.scene {
        None => {
            eprintln!(
                "warning: {}: no --scene, so the error target is the coefficients' relative L2 error (--error {}), not the relit image",
                args.input.display(),
                args.error
            );
            let mut bake = original.clone();
            let choice = args
                .components
                .map_or(Components::Error(args.error), Components::Fixed);
            let rows = fit.apply(&mut bake, choice, choice, scalar.size(), policy.describe());
            (bake, rows, None)
        }
        Some(scene) => {
            let (bake, rows, image) = to_image_target(args, scene, &original, &fit, scalar)?;
            (bake, rows, Some(image))
        }
    };
    prt_bakefile::write_bake(&args.out, &bake, scalar)?;
    let size_in = bytes.len() as u64;
    let size_out = std::fs::metadata(&args.out).map(|m| m.len()).unwrap_or(0);
    report(args, &rows, size_in, size_out, image.as_ref())
}

/// What the image target measured.
struct ImageFigures {
    /// Lowest PSNR over the rotations against the uncompressed bake's image.
    min_psnr: f64,
    /// The coefficient errors chosen: diffuse blocks, visibility blocks.
    errors: (f64, f64),
    /// Median shading ms per frame: uncompressed, compressed.
    shade_ms: (f64, f64),
}

/// The scene and BVH of a bake (subdivided objects on the bake's refined meshes).
fn bind_scene(path: &Path, bake: &Bake) -> Result<(prt_scene::Scene, prt_tracer::Accel)> {
    let scene = crate::common::load_scene(path)?;
    prt_scene_relight::check_bake(&scene, bake, path)?;
    let scene = prt_scene_relight::baked_scene(&scene, bake)?;
    let accel = prt_tracer::Accel::build(&scene).context("building the BVH")?;
    Ok((scene, accel))
}

/// One relighting at full order, rotated by `deg`, with `timed` timed frames 10° apart.
fn full(deg: f64, timed: usize) -> RelightOptions {
    RelightOptions {
        rotate_y_deg: deg,
        timing_frames: timed,
        warmup_frames: if timed > 1 { 2 } else { 0 },
        rotate_y_step_deg: if timed > 1 { 10.0 } else { 0.0 },
        ..Default::default()
    }
}

/// The image target: the loosest common coefficient error whose relit images reach the
/// target at every rotation, then each kind (diffuse, visibility) loosened on its own while
/// they still do; the compressed bake, its blocks and the figures.
fn to_image_target(
    args: &CompressArgs,
    scene_path: &Path,
    original: &Bake,
    fit: &BakeFit,
    scalar: prt_bakefile::ScalarType,
) -> Result<(Bake, Vec<BlockCompression>, ImageFigures)> {
    anyhow::ensure!(
        args.target_psnr.is_finite() && args.target_psnr > 0.0,
        "--target-psnr {} must be a positive, finite number of dB",
        args.target_psnr
    );
    anyhow::ensure!(args.rotations >= 1, "--rotations must be at least 1");
    let (scene, accel) = bind_scene(scene_path, original)?;
    let rotations: Vec<f64> = (0..args.rotations)
        .map(|k| 360.0 * k as f64 / args.rotations as f64)
        .collect();
    let bound = Bound::new(&scene, &accel, original)?;
    let references = rotations
        .iter()
        .map(|&deg| bound.form_image(&bound.relight(&full(deg, 1))?, deg))
        .collect::<Result<Vec<_>, _>>()?;
    // The lowest PSNR of a candidate over the rotations (stopping at the first miss).
    let try_errors = |ed: f64, ev: f64| -> Result<(Bake, Vec<BlockCompression>, f64)> {
        let mut bake = original.clone();
        let (d, v) = match args.components {
            Some(m) => (Components::Fixed(m), Components::Fixed(m)),
            None => (Components::Error(ed), Components::Error(ev)),
        };
        let reason = format!(
            "prt compress: clusters {}, the loosest coefficient errors (diffuse {ed}, visibility {ev}) whose relit images reach {} dB against the uncompressed bake's at {} rotations",
            args.clusters.map_or("per object (points/256, 1..64)".into(), |k| k.to_string()),
            args.target_psnr,
            rotations.len()
        );
        let rows = fit.apply(&mut bake, d, v, scalar.size(), reason);
        let b = Bound::new(&scene, &accel, &bake)?;
        let mut worst = f64::INFINITY;
        for (&deg, reference) in rotations.iter().zip(&references) {
            let img = b.form_image(&b.relight(&full(deg, 1))?, deg)?;
            worst = worst.min(prt_compare::compare(&img, reference, None)?.whole.psnr_ldr);
            if worst < args.target_psnr {
                break;
            }
        }
        Ok((bake, rows, worst))
    };
    let meets = |p: f64| p >= args.target_psnr;
    // A common error first (the loosest that meets the target; the tightest otherwise).
    let mut chosen = None;
    for &e in &LADDER {
        let c = try_errors(e, e)?;
        let ok = meets(c.2);
        chosen = Some(((e, e), c));
        if ok || args.components.is_some() {
            break;
        }
    }
    let Some(((mut ed, mut ev), mut best)) = chosen else {
        unreachable!("the ladder is not empty")
    };
    // Then each kind loosened alone while the images still meet the target.
    if meets(best.2) && args.components.is_none() {
        for kind in [1, 0] {
            for &e in LADDER
                .iter()
                .filter(|&&e| e > if kind == 1 { ev } else { ed })
            {
                let (d, v) = if kind == 1 { (ed, e) } else { (e, ev) };
                let c = try_errors(d, v)?;
                if meets(c.2) {
                    (ed, ev, best) = (d, v, c);
                    break;
                }
            }
        }
    }
    let (bake, rows, min_psnr) = best;
    if !meets(min_psnr) {
        eprintln!(
            "warning: {}: no stored size tried reaches {} dB (best {min_psnr:.2} dB at coefficient error {ed}); writing that one",
            args.input.display(),
            args.target_psnr
        );
    }
    // Shading speed, both bakes as `prt bench relight` times them (10 warm frames, median).
    let before = bound.relight(&full(0.0, 10))?.stats.shade_ms;
    let after = Bound::new(&scene, &accel, &bake)?
        .relight(&full(0.0, 10))?
        .stats
        .shade_ms;
    Ok((
        bake,
        rows,
        ImageFigures {
            min_psnr,
            errors: (ed, ev),
            shade_ms: (before, after),
        },
    ))
}

/// Prints what was done.
fn report(
    args: &CompressArgs,
    rows: &[BlockCompression],
    size_in: u64,
    size_out: u64,
    image: Option<&ImageFigures>,
) -> Result<()> {
    if args.json {
        outln!(
            "{}",
            serde_json::to_string(&serde_json::json!({
                "input": args.input.display().to_string(), "output": args.out.display().to_string(),
                "file_bytes_before": size_in, "file_bytes_after": size_out,
                "size_ratio": size_out as f64 / size_in.max(1) as f64,
                "target_psnr": image.map(|_| args.target_psnr),
                "min_psnr": image.map(|i| i.min_psnr),
                "rotations": image.map(|_| args.rotations),
                "error_diffuse": image.map(|i| i.errors.0),
                "error_visibility": image.map(|i| i.errors.1),
                "shade_ms_before": image.map(|i| i.shade_ms.0),
                "shade_ms_after": image.map(|i| i.shade_ms.1),
                "blocks": rows.iter().map(|r| serde_json::json!({
                    "object": r.object, "kind": r.kind, "points": r.points, "dimension": r.dimension,
                    "clusters": r.clusters, "components": r.components, "rel_error": r.rel_error,
                    "bytes_before": r.bytes_before, "bytes_after": r.bytes_after,
                })).collect::<Vec<_>>(),
            }))?
        );
        return Ok(());
    }
    for r in rows {
        outln!(
            "{} {}: {} points × {} → {} clusters × {} components, relative L2 error {:.3} %, {} → {} bytes",
            r.object, r.kind, r.points, r.dimension, r.clusters, r.components,
            100.0 * r.rel_error, r.bytes_before, r.bytes_after
        );
    }
    outln!(
        "{}: {size_in} bytes → {}: {size_out} bytes ({:.3}× the size)",
        args.input.display(),
        args.out.display(),
        size_out as f64 / size_in.max(1) as f64
    );
    if let Some(i) = image {
        outln!(
            "relit image: lowest PSNR {:.2} dB against the uncompressed bake over {} rotations (target {} dB; coefficient errors chosen: diffuse {}, visibility {})",
            i.min_psnr, args.rotations, args.target_psnr, i.errors.0, i.errors.1
        );
        outln!(
            "shading: {:.3} ms/frame uncompressed, {:.3} ms/frame compressed ({:.2}× as fast; median of 10 frames 10° apart)",
            i.shade_ms.0,
            i.shade_ms.1,
            i.shade_ms.0 / i.shade_ms.1.max(1e-9)
        );
    }
    Ok(())
}
