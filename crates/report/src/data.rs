//! What a report runs with ([`ReportSettings`]) and what it measured ([`ReportData`], written as
//! `report.json`): the reference, the bake, the per-order rows and the path tracer's
//! convergence.

use crate::budget::BudgetRow;
use crate::machine::Machine;
use serde::Serialize;

/// Settings of a report.
#[derive(Clone, Debug)]
pub struct ReportSettings {
    /// Orders (bands) to relight at.
    pub orders: Vec<usize>,
    /// Samples per pixel of the path-traced reference: the most it may take when
    /// `reference_psnr` is set, exactly this otherwise (rounded up to even, so its two half
    /// images estimate its noise).
    pub reference_spp: u32,
    /// Render the reference until its own estimate of its 8-bit noise ceiling on object
    /// pixels reaches this many dB ([`prt_tracer::RenderSettings::target_psnr_ldr`]).
    pub reference_psnr: Option<f64>,
    /// Measure the error budget (a second vertex bake and two per-pixel bakes, all cached).
    pub budget: bool,
    /// The quality target of the "target quality" column (dB against full order; `None`:
    /// no column).
    pub target_psnr: Option<f64>,
    /// Rays per vertex of the bake.
    pub rays: u32,
    /// Bounces of both the reference and the bake.
    pub bounces: u32,
    /// Adaptive threshold `T` (absolute, output radiance units; or on the display, see
    /// `display_threshold`). The adaptive runs use the convergence stop
    /// ([`prt_relight::AdaptiveParams::new`]).
    pub threshold: f32,
    /// Measure `threshold` on the 8-bit view (exposure 0, as `psnr_ldr`) instead of in radiance.
    pub display_threshold: bool,
    /// Seed of the reference and the bake.
    pub seed: u64,
    /// Frames timed per relighting (the median is reported).
    pub timing_frames: usize,
    /// Show progress bars.
    pub progress: bool,
    /// The reflectance-field section ([`crate::rf_section`]), or `None` to leave it out.
    pub reflectance: Option<crate::rf_section::RfSettings>,
}

/// One row of the per-order table.
#[derive(Clone, Debug, Serialize)]
pub struct OrderRow {
    /// Order (bands).
    pub order: usize,
    /// Coefficients per channel.
    pub coefficients: usize,
    /// Full-order shading time per frame (median of the timed frames), ms.
    pub full_ms: f64,
    /// Fastest and slowest timed full-order frame, ms.
    pub full_ms_range: [f64; 2],
    /// Adaptive shading time per frame (median of the timed frames), ms.
    pub adaptive_ms: f64,
    /// Fastest and slowest timed adaptive frame, ms.
    pub adaptive_ms_range: [f64; 2],
    /// `full_ms / adaptive_ms`.
    pub speedup: f64,
    /// psnr_ldr of adaptive against full order (whole image).
    pub psnr_adaptive_vs_full: f64,
    /// psnr_ldr of full order against the path-traced reference, object pixels.
    pub psnr_full_vs_reference: f64,
    /// psnr_ldr of adaptive against the reference, object pixels.
    pub psnr_adaptive_vs_reference: f64,
    /// Relative L2 error of full order against the reference, object pixels.
    pub rel_l2_full: f64,
    /// Relative L2 error of adaptive against the reference, object pixels.
    pub rel_l2_adaptive: f64,
    /// Diffuse ROI fraction.
    pub roi_diffuse: Option<f64>,
    /// Specular ROI fraction.
    pub roi_specular: Option<f64>,
    /// Adaptive relighting to the report's quality target (`--target-psnr`, against full
    /// order at this order): the frame's cost, threshold and PSNR.
    pub target: Option<TargetColumn>,
}

/// The "target quality" column of a row.
#[derive(Clone, Debug, Serialize)]
pub struct TargetColumn {
    /// The target, dB against full order.
    pub target_psnr: f64,
    /// Shading time of the frame, probe and retries included, ms.
    pub ms: f64,
    /// The threshold it settled on (0: full order).
    pub threshold: f32,
    /// Its estimate of the PSNR.
    pub psnr_estimate: f64,
    /// The PSNR against full order it reached (measured on the report's full-order image).
    pub psnr_actual: f64,
    /// `full_ms / ms`.
    pub speedup: f64,
}

/// One point of the path-tracing convergence series.
#[derive(Clone, Debug, Serialize)]
pub struct ConvergencePoint {
    /// Samples per pixel.
    pub spp: u32,
    /// Render time, ms.
    pub ms: f64,
    /// psnr_ldr against the reference, object pixels.
    pub psnr_ldr: f64,
    /// Relative L2 against the reference, object pixels.
    pub rel_l2: f64,
}

/// Everything the report measured (`report.json`).
#[derive(Clone, Debug, Serialize)]
pub struct ReportData {
    /// The scene file.
    pub scene: String,
    /// Machine: logical cores and CPU model.
    pub machine: Machine,
    /// Settings as used.
    pub settings: serde_json::Value,
    /// Reference render time, s.
    pub reference_seconds: f64,
    /// Monte Carlo noise of the reference (RMSE against its expectation, object pixels,
    /// linear radiance), from its two half images.
    pub reference_noise_rmse: f64,
    /// psnr_ldr ceiling implied by that noise (object pixels).
    pub reference_noise_psnr_ldr: Option<f64>,
    /// The reference: how it was made and how noisy it is.
    pub reference: ReferenceInfo,
    /// Per order, the error against the path tracer split into named terms
    /// ([`crate::budget`]); empty without `budget`.
    pub error_budget: Vec<BudgetRow>,
    /// The sentence naming the largest term.
    pub error_budget_summary: String,
    /// Per object: PSNR against the path tracer at every order and the lowest order meeting
    /// the report's `target_psnr` ([`crate::recommend`]).
    pub recommendation: Vec<crate::recommend::ObjectQuality>,
    /// Bake time, s (0 when reused from the cache).
    pub bake_seconds: f64,
    /// Whether the bake came from the cache.
    pub bake_cached: bool,
    /// The bake file used.
    pub bake_file: String,
    /// Per object, what the bake's rays met (a broken mesh shows up here).
    pub bake_rays: Vec<ObjectRays>,
    /// Path-tracing convergence.
    pub convergence: Vec<ConvergencePoint>,
    /// Per-order rows.
    pub orders: Vec<OrderRow>,
    /// Notes from the relighter.
    pub notes: Vec<String>,
    /// The reflectance-field section, when asked for (`--reflectance`).
    pub reflectance: Option<crate::rf_section::RfSection>,
    /// The live WebGL2 page of the bake (`live.html`), when the bake exports.
    pub live_page: Option<String>,
}

/// The path-traced reference of a report (`report.json`: `reference`).
#[derive(Clone, Debug, Serialize)]
pub struct ReferenceInfo {
    /// Samples per pixel taken.
    pub spp: u32,
    /// Render seconds (of the run that made it, when cached).
    pub seconds: f64,
    /// Whether it came from the cache.
    pub cached: bool,
    /// The cache file.
    pub file: String,
    /// Its noise: mean squared error against its expectation over object pixels, linear
    /// radiance, per channel (from its two half images).
    pub noise_mse: f64,
    /// The PSNR ceiling its noise sets on the 8-bit view (object pixels): no method compared
    /// with it can score much above this.
    pub noise_psnr_ldr: f64,
    /// The ceiling it was rendered to reach.
    pub target_psnr_ldr: Option<f64>,
    /// Whether it reached it (false: it stopped at the sample cap).
    pub target_met: Option<bool>,
}

/// What one object's bake rays met (from the bake file's ray statistics).
#[derive(Clone, Debug, Serialize)]
pub struct ObjectRays {
    /// Object name.
    pub object: String,
    /// Points baked.
    pub points: u64,
    /// Diffuse rays traced from them.
    pub rays: u64,
    /// Fraction of rays whose first hit is the back of a surface.
    pub backface_fraction: f64,
    /// Fraction of rays traced from points inside geometry (more than half of their rays hit
    /// a back face).
    pub inside_fraction: f64,
    /// Points inside geometry.
    pub inside_points: u64,
}
