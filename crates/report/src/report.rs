//! `prt report`: the speed-against-error report of a scene. It path-traces the reference (and a
//! convergence series), bakes (or reuses a cached bake), relights at every order with the full
//! and the adaptive method, measures time and error, and writes tables, plots and images.
//!
//! Every figure in the report is reproducible: the reference and the bake are seeded, and the
//! same numbers come out of `prt render`, `prt bake`, `prt relight` and `prt compare` run by
//! hand with the settings printed in the report.
//!
//! [`run_report`] is the list of steps; each lives in its own file: the state they share
//! (`run.rs`), the reference and convergence (`reference.rs`), the bakes (`bakes.rs`), the
//! relighting at every order (`orders.rs`), the error budget (`budget.rs`), the figures
//! (`figures.rs`) and the written files (`outputs.rs`, `markdown.rs`).

use crate::bakes::{bake_all, bake_rays, budget_images, BudgetImages};
use crate::budget::{measure_budget, summary_sentence, BudgetRow};
pub use crate::cache::cache_dir;
use crate::cache::scene_key;
pub use crate::data::{
    ConvergencePoint, ObjectRays, OrderRow, ReferenceInfo, ReportData, ReportSettings, TargetColumn,
};
use crate::error::ReportError;
use crate::figures::write_figures;
use crate::machine::machine;
pub use crate::machine::{Machine, TimingLoad};
use crate::orders::{relight_orders, Relighting};
use crate::outputs::write_outputs;
use crate::plots::srgb_tile;
use crate::recommend::ObjectQuality;
use crate::reference::{convergence, path_traced_reference, Reference};
use crate::rf_section::{run_section, RfContext, RfSection};
use crate::run::Run;
use crate::viewer::ViewerImage;
use glam::Vec3;
use prt_bakefile::Bake;
use prt_relight::{AdaptiveParams, Threshold};
use prt_scene::Scene;
use std::path::Path;

/// Runs the whole report into `out_dir`.
pub fn run_report(
    scene_path: &Path,
    scene: &Scene,
    out_dir: &Path,
    s: &ReportSettings,
) -> Result<ReportData, ReportError> {
    let run = Run::start(scene, out_dir, s)?;
    // 1. The reference (cached) and the path tracer's convergence against it.
    let reference = path_traced_reference(&run)?;
    let convergence = convergence(&run, &reference)?;
    // 2. The bakes (cached), and the budget's per-pixel images at the highest order.
    let bakes = bake_all(&run)?;
    let budget_images = budget_images(&run, &bakes)?;
    // 3. Relight at every order, full and adaptive, timed and measured.
    let mut viewer_images = first_viewer_images(&run, &reference, budget_images.as_ref());
    let relit = relight_orders(&run, &bakes.bake, &reference.image, &mut viewer_images)?;
    // 4. The error budget of every order.
    let error_budget = error_budget(&run, &reference, &relit, budget_images.as_ref())?;
    // 4b. The reflectance-field section (after the timed relightings, so it does not load
    // them).
    let reflectance = reflectance_section(&run, &reference, &mut viewer_images)?;
    let error_budget_summary = summary_sentence(&error_budget);
    let recommendation = recommendation(
        &run,
        &bakes.bake,
        &reference,
        &relit.full_images,
        budget_images.as_ref(),
    )?;
    // 5. Plots and the image grid.
    let reference_tile = srgb_tile(
        &reference.image,
        format!("path traced, {} spp", reference.data.spp),
    );
    write_figures(
        &run,
        &relit.rows,
        &convergence,
        reference.noise_psnr,
        &error_budget,
        relit.tiles,
        reference_tile,
    )?;
    // 6. The live page of the bake (export for WebGL2), then what was measured and the files
    // that show it.
    let mut notes = relit.notes;
    let live_page = match crate::live::live_page(&run, &bakes.bake, &reference.image)? {
        Ok(page) => Some(page),
        Err(note) => {
            notes.push(note);
            None
        }
    };
    let data = ReportData {
        scene: scene_path.display().to_string(),
        machine: Machine {
            timing_load: relit.timing_load,
            ..machine()
        },
        settings: settings_json(&run),
        reference_seconds: reference.data.seconds,
        reference_noise_rmse: reference.noise_mse.sqrt(),
        reference_noise_psnr_ldr: Some(reference.noise_psnr),
        reference: reference.info,
        error_budget,
        error_budget_summary,
        recommendation,
        bake_seconds: bakes.seconds,
        bake_cached: bakes.cached,
        bake_file: bakes.path.display().to_string(),
        bake_rays: bake_rays(&bakes.bake),
        convergence,
        orders: relit.rows,
        notes,
        reflectance,
        live_page,
    };
    write_outputs(out_dir, &data, run.width, run.height, &viewer_images)?;
    Ok(data)
}

/// The viewer's first images: the reference and, with the budget, the per-pixel bake's image
/// at the highest order.
fn first_viewer_images(
    run: &Run,
    reference: &Reference,
    budget: Option<&BudgetImages>,
) -> Vec<ViewerImage> {
    let max_order = run.max_order;
    let mut viewer_images = vec![ViewerImage {
        id: "reference".into(),
        label: format!("path traced, {} spp", reference.data.spp),
        rgb: reference.image.pixels.clone(),
    }];
    if let Some(b) = budget {
        viewer_images.push(ViewerImage {
            id: format!("per_pixel_{max_order:02}"),
            label: format!("per-pixel bake, full SH order {max_order}"),
            rgb: b.pixel.iter().map(|v| v.to_array()).collect(),
        });
    }
    viewer_images
}

/// The error budget of every order (empty without the budget).
fn error_budget(
    run: &Run,
    reference: &Reference,
    relit: &Relighting,
    budget: Option<&BudgetImages>,
) -> Result<Vec<BudgetRow>, ReportError> {
    let Some(b) = budget else {
        return Ok(Vec::new());
    };
    measure_budget(
        &run.settings.orders,
        &relit.full_images,
        [b.pixel.as_slice(), b.pixel_second.as_slice()],
        &reference.data.radiance,
        run.mask.as_slice(),
        reference.noise_mse,
        |order| run.relit_image(b.vertex_second, order),
    )
}

/// The reflectance-field section, when the settings ask for it; its images join the viewer's.
fn reflectance_section(
    run: &Run,
    reference: &Reference,
    viewer_images: &mut Vec<ViewerImage>,
) -> Result<Option<RfSection>, ReportError> {
    let s = run.settings;
    let Some(rf) = &s.reflectance else {
        return Ok(None);
    };
    let out = run_section(
        &RfContext {
            scene: run.scene,
            accel: &run.accel,
            out_dir: run.out_dir,
            reference: &reference.image,
            mask: &run.mask,
            reference_noise_psnr: reference.noise_psnr,
            bounces: s.bounces,
            rays: s.rays,
            seed: s.seed,
            sh_timing_frames: s.timing_frames,
            progress: s.progress,
        },
        scene_key(run.scene),
        rf,
    )?;
    viewer_images.extend(out.viewer_images);
    Ok(Some(out.section))
}

/// Per object: quality against the path tracer at every order (from the full-order images of
/// step 3, not relit again), what meets the target, and what the budget's per-pixel bakes
/// reach.
fn recommendation(
    run: &Run,
    bake: &Bake,
    reference: &Reference,
    full_images: &[Vec<Vec3>],
    budget: Option<&BudgetImages>,
) -> Result<Vec<ObjectQuality>, ReportError> {
    let s = run.settings;
    let mut recommendation = crate::recommend::object_quality_with(
        run.scene,
        &run.accel,
        bake,
        &reference.image,
        &s.orders,
        s.target_psnr.unwrap_or(f64::INFINITY),
        |order| {
            let k = s.orders.iter().position(|&o| o == order).expect("listed");
            Ok(run.image(&full_images[k]))
        },
    )?;
    if let Some(b) = budget {
        let p_mean = run.image(
            &b.pixel
                .iter()
                .zip(&b.pixel_second)
                .map(|(a, b)| 0.5 * (*a + *b))
                .collect::<Vec<_>>(),
        );
        let psnr = crate::recommend::object_psnr(run.scene, &run.accel, &p_mean, &reference.image)?;
        for (q, p) in recommendation.iter_mut().zip(psnr) {
            q.per_pixel_psnr = p.is_finite().then_some(p);
        }
    }
    Ok(recommendation)
}

/// The settings as `report.json` records them.
fn settings_json(run: &Run) -> serde_json::Value {
    let s = run.settings;
    let (w, h) = (run.width, run.height);
    serde_json::json!({
        "orders": s.orders, "reference_spp": s.reference_spp, "rays": s.rays, "bounces": s.bounces,
        "threshold": s.threshold, "threshold_kind": if s.display_threshold { "display (8-bit view, exposure 0)" } else { "absolute (output radiance)" },
        "cost_exponent": AdaptiveParams::new(Threshold::Absolute(s.threshold)).cost_exponent, "seed": s.seed,
        "timing_frames": s.timing_frames, "image": format!("{w}x{h}"),
    })
}
