//! `prt report`: the speed-against-error report of a scene. It path-traces the reference (and a
//! convergence series), bakes (or reuses a cached bake), relights at every order with the full
//! and the adaptive method, measures time and error, and writes tables, plots and images.
//!
//! Every figure in the report is reproducible: the reference and the bake are seeded, and the
//! same numbers come out of `prt render`, `prt bake`, `prt relight` and `prt compare` run by
//! hand with the settings printed in the report.

use crate::budget::{
    ldr_noise_psnr, masked_mean_square, masked_mse, summary_sentence, BudgetInputs, BudgetRow,
};
pub use crate::cache::cache_dir;
use crate::cache::{cached_bake, reference_key, scene_key};
use crate::error::ReportError;
use crate::plots::{image_grid, line_chart, srgb_tile, stacked_shares, ChartOptions, Series, Tile};
use crate::viewer::ViewerImage;
use glam::Vec3;
use plotters::style::RGBColor;
use prt_bake::{BakeSettings, PointKind};
use prt_bakefile::Bake;
use prt_compare::{compare, ErrorImageOptions, Image, Mask};
use prt_relight::{AdaptiveParams, Threshold};
use prt_scene::Scene;
use prt_scene_relight::imaging::{form_image, object_mask, roi_image, RgbImage};
use prt_scene_relight::io::{
    read_reference, to_compare_image, write_exr, write_png, write_reference, CachedReference,
};
use prt_scene_relight::relit::{relight, RelightOptions};
use serde::Serialize;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Instant;

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

/// Sub-pixel positions of the budget's per-pixel bakes (the bake's rays are shared out over
/// them): enough that the pixel footprint's own sampling noise (silhouettes, contact edges)
/// stays well below the interpolation error it is compared with.
const BUDGET_PIXEL_SAMPLES: u32 = 256;

/// The most samples per pixel of the path-tracing convergence series.
const MAX_CONVERGENCE_SPP: u32 = 256;

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

/// The machine the report ran on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Logical cores available.
    pub cores: usize,
    /// CPU model name (from /proc/cpuinfo), if known.
    pub cpu: String,
    /// What else ran while the report relit and timed every order (Linux: from `/proc`).
    pub timing_load: Option<TimingLoad>,
}

/// The machine's load while the report was timing: how much of the CPU time went to other
/// processes (and, on a virtual machine, was stolen by the host). Timings taken while others
/// used the cores are noisy; the report says so.
#[derive(Clone, Copy, Debug, Serialize)]
pub struct TimingLoad {
    /// Wall-clock seconds of the timed section.
    pub seconds: f64,
    /// Fraction of all cores' time used by other processes.
    pub other_cpu_fraction: f64,
    /// Fraction of all cores' time stolen by the hypervisor.
    pub steal_fraction: f64,
    /// 1-minute load average at the start and the end (all processes, this one included).
    pub load_average: [f64; 2],
}

/// Counters of `/proc/stat` (all cores) and `/proc/self/stat` at one instant, in clock ticks.
#[derive(Clone, Copy, Debug)]
struct CpuSnapshot {
    at: std::time::Instant,
    total: u64,
    busy: u64,
    steal: u64,
    own: u64,
    load: f64,
}

fn cpu_snapshot() -> Option<CpuSnapshot> {
    let stat = std::fs::read_to_string("/proc/stat").ok()?;
    let cpu: Vec<u64> = stat
        .lines()
        .next()?
        .split_whitespace()
        .skip(1)
        .take(8)
        .map(|v| v.parse().unwrap_or(0))
        .collect();
    if cpu.len() < 8 {
        return None;
    }
    // user nice system idle iowait irq softirq steal
    let busy = cpu[0] + cpu[1] + cpu[2] + cpu[5] + cpu[6] + cpu[7];
    let me = std::fs::read_to_string("/proc/self/stat").ok()?;
    let after = me.rsplit_once(')')?.1;
    let fields: Vec<u64> = after
        .split_whitespace()
        .map(|v| v.parse().unwrap_or(0))
        .collect();
    // Fields 14 and 15 of /proc/[pid]/stat (utime, stime) are 11 and 12 after the name.
    let own = fields.get(11)? + fields.get(12)?;
    let load = std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|l| l.split_whitespace().next()?.parse().ok())
        .unwrap_or(0.0);
    Some(CpuSnapshot {
        at: std::time::Instant::now(),
        total: cpu.iter().sum(),
        busy,
        steal: cpu[7],
        own,
        load,
    })
}

impl TimingLoad {
    fn between(a: CpuSnapshot, b: CpuSnapshot) -> Self {
        let total = b.total.saturating_sub(a.total).max(1) as f64;
        let busy = b.busy.saturating_sub(a.busy);
        let own = b.own.saturating_sub(a.own);
        TimingLoad {
            seconds: (b.at - a.at).as_secs_f64(),
            other_cpu_fraction: busy.saturating_sub(own) as f64 / total,
            steal_fraction: b.steal.saturating_sub(a.steal) as f64 / total,
            load_average: [a.load, b.load],
        }
    }

    /// Other processes (or the hypervisor) took more than 5 % of the cores' time.
    #[must_use]
    pub fn noisy(&self) -> bool {
        self.other_cpu_fraction > 0.05 || self.steal_fraction > 0.05
    }

    /// One sentence for the report.
    #[must_use]
    pub fn sentence(&self, cores: usize) -> String {
        format!(
            "Machine load while timing ({:.0} s): other processes used {:.1} % of the {cores} cores' time and the hypervisor stole {:.1} % (1-minute load average {:.2} → {:.2}); {}",
            self.seconds,
            100.0 * self.other_cpu_fraction,
            100.0 * self.steal_fraction,
            self.load_average[0],
            self.load_average[1],
            if self.noisy() {
                "the timings are noisy: rerun on a quiet machine before comparing them"
            } else {
                "the machine was quiet"
            }
        )
    }
}

fn machine() -> Machine {
    let cpu = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("model name"))
                .and_then(|l| l.split(':').nth(1))
                .map(|s| s.trim().to_owned())
        })
        .unwrap_or_else(|| "unknown".into());
    Machine {
        cores: std::thread::available_parallelism().map_or(1, |n| n.get()),
        cpu,
        timing_load: None,
    }
}

fn to_image(radiance: &[Vec3], w: u32, h: u32) -> Image {
    Image {
        width: w as usize,
        height: h as usize,
        pixels: radiance.iter().map(|v| v.to_array()).collect(),
    }
}

fn finite_or(v: f64, cap: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        cap
    }
}

/// Runs the whole report into `out_dir`.
pub fn run_report(
    scene_path: &Path,
    scene: &Scene,
    out_dir: &Path,
    s: &ReportSettings,
) -> Result<ReportData, ReportError> {
    if s.orders.is_empty() || s.orders.iter().any(|&o| o == 0 || o > 32) {
        return Err(ReportError::Invalid(
            "orders must be between 1 and 32".into(),
        ));
    }
    if s.reference_spp == 0 || s.rays == 0 || s.timing_frames == 0 {
        return Err(ReportError::Invalid(
            "--reference-spp, --rays and the frame count must be at least 1".into(),
        ));
    }
    if !s.threshold.is_finite() || s.threshold < 0.0 {
        return Err(ReportError::Invalid(
            "--threshold must be finite and ≥ 0".into(),
        ));
    }
    std::fs::create_dir_all(out_dir.join("images")).map_err(|e| ReportError::Write {
        path: out_dir.to_path_buf(),
        reason: e.to_string(),
    })?;
    std::fs::create_dir_all(out_dir.join("cache")).map_err(|e| ReportError::Write {
        path: out_dir.to_path_buf(),
        reason: e.to_string(),
    })?;
    let say = |m: &str| {
        if s.progress {
            eprintln!("report: {m}");
        }
    };
    let accel = prt_tracer::Accel::build(scene)?;
    let (w, h) = (scene.camera.width, scene.camera.height);
    let mask_bits = object_mask(scene, &accel)?;
    let mask_png = RgbImage {
        width: w,
        height: h,
        pixels: mask_bits
            .iter()
            .map(|&m| if m { [1.0; 3] } else { [0.0; 3] })
            .collect(),
    };
    write_png(&out_dir.join("images/mask.png"), &mask_png, 0.0)?;
    let mask = Mask::from_bools(w as usize, h as usize, mask_bits)?;

    // 1. The reference (cached): rendered until its own noise ceiling reaches the target,
    // with the half difference of its two half images, which estimates its error per pixel.
    let reference_spp = s.reference_spp + s.reference_spp % 2;
    let rs = prt_tracer::RenderSettings {
        spp: reference_spp,
        bounces: s.bounces as i32,
        seed: s.seed,
        aovs: true,
        progress: s.progress,
        target_psnr_ldr: s.reference_psnr,
        ..Default::default()
    };
    let reference_path = out_dir
        .join("cache")
        .join(format!("reference-{:016x}.bin", reference_key(scene, &rs)));
    let (reference_data, reference_cached) = match read_reference(&reference_path) {
        Ok(r) if r.width == w && r.height == h => {
            say(&format!(
                "reusing the cached reference {}",
                reference_path.display()
            ));
            (r, true)
        }
        _ => {
            say(&format!(
                "path-traced reference, {} bounce(s), {}",
                s.bounces,
                s.reference_psnr
                    .map_or(format!("{reference_spp} spp"), |p| format!(
                    "until its 8-bit noise ceiling reaches {p} dB (at most {reference_spp} spp)"
                ))
            ));
            let out = prt_tracer::render(scene, &rs)?;
            let r = CachedReference {
                width: w,
                height: h,
                spp: out.settings.spp,
                seconds: out.seconds,
                radiance: out.radiance,
                half_difference: out.aovs.expect("aovs asked").half_difference,
            };
            write_reference(&reference_path, &r)?;
            (r, false)
        }
    };
    let reference = to_image(&reference_data.radiance, w, h);
    write_exr(
        &out_dir.join("images/reference.exr"),
        &RgbImage {
            width: w,
            height: h,
            pixels: reference.pixels.clone(),
        },
        &[
            ("kind", "reference".into()),
            ("spp", reference_data.spp.to_string()),
            ("seed", s.seed.to_string()),
        ],
    )?;
    let reference_noise_mse = masked_mean_square(&reference_data.half_difference, mask.as_slice());
    let reference_noise_psnr = ldr_noise_psnr(
        &reference_data.radiance,
        &reference_data.half_difference,
        mask.as_slice(),
    );
    let reference_info = ReferenceInfo {
        spp: reference_data.spp,
        seconds: reference_data.seconds,
        cached: reference_cached,
        file: reference_path.display().to_string(),
        noise_mse: reference_noise_mse,
        noise_psnr_ldr: reference_noise_psnr,
        target_psnr_ldr: s.reference_psnr,
        target_met: s.reference_psnr.map(|p| reference_noise_psnr >= p),
    };
    if let Some(p) = s.reference_psnr {
        if reference_noise_psnr < p {
            say(&format!(
                "the reference stopped at the cap of {} spp with a noise ceiling of {reference_noise_psnr:.1} dB, short of {p} dB (raise --reference-spp)",
                reference_data.spp
            ));
        }
    }
    let mut convergence = Vec::new();
    let mut spp = 1;
    while spp <= (reference_data.spp / 2).min(MAX_CONVERGENCE_SPP) {
        let cs = prt_tracer::RenderSettings {
            spp,
            seed: s.seed.wrapping_add(0x5eed),
            aovs: false,
            progress: false,
            target_psnr_ldr: None,
            ..rs.clone()
        };
        let t = Instant::now();
        let out = prt_tracer::render(scene, &cs)?;
        let ms = t.elapsed().as_secs_f64() * 1e3;
        let m = compare(&to_image(&out.radiance, w, h), &reference, Some(&mask))?;
        let mm = m.masked.expect("mask given");
        convergence.push(ConvergencePoint {
            spp,
            ms,
            psnr_ldr: mm.psnr_ldr,
            rel_l2: mm.rel_l2,
        });
        spp *= 2;
    }

    // 2. The bakes (cached): the one relit at every order, and for the budget a second
    // vertex bake with another seed and two per-pixel bakes.
    let max_order = *s.orders.iter().max().expect("non-empty");
    let bs = BakeSettings {
        order: Some(max_order),
        rays: s.rays,
        bounces: s.bounces,
        seed: s.seed,
        points: PointKind::Vertex,
        progress: s.progress,
        ..BakeSettings::final_quality()
    };
    let cached_bake =
        |bs: &BakeSettings, what: &str| cached_bake(scene, &accel, out_dir, bs, what, s.progress);
    let (bake, bake_path, baked) = cached_bake(&bs, "bake")?;
    let bake_seconds = baked.unwrap_or(0.0);
    let bake_cached = baked.is_none();
    let second_seed = s.seed ^ 0x0b0d_9e75_eed5_eed5;
    let budget_bakes = if s.budget {
        let (v2, _, _) = cached_bake(
            &BakeSettings {
                seed: second_seed,
                ..bs.clone()
            },
            "second-seed bake (error budget)",
        )?;
        let pixel = BakeSettings {
            points: PointKind::Pixel,
            pixel_samples: BUDGET_PIXEL_SAMPLES.min(s.rays),
            ..bs.clone()
        };
        let (p1, _, _) = cached_bake(&pixel, "per-pixel bake (error budget)")?;
        let (p2, _, _) = cached_bake(
            &BakeSettings {
                seed: second_seed,
                ..pixel
            },
            "second-seed per-pixel bake (error budget)",
        )?;
        Some((v2, p1, p2))
    } else {
        None
    };
    let linear =
        |img: &RgbImage| -> Vec<Vec3> { img.pixels.iter().map(|p| Vec3::from_array(*p)).collect() };
    let once = |order: usize| RelightOptions {
        order: Some(order),
        adaptive: None,
        rotate_y_deg: 0.0,
        timing_frames: 1,
        warmup_frames: 0,
        rotate_y_step_deg: 0.0,
        points: None,
        ..Default::default()
    };
    let relit_image = |b: &Bake, order: usize| -> Result<Vec<Vec3>, ReportError> {
        let r = relight(scene, &accel, b, &once(order))?;
        Ok(linear(&form_image(scene, &accel, &r, 0.0)?))
    };
    // The per-pixel images at the highest order, and the per-vertex one from both seeds.
    let budget_images = match &budget_bakes {
        Some((v2, p1, p2)) => {
            let p1_img = relit_image(p1, max_order)?;
            write_exr(
                &out_dir.join(format!("images/per_pixel_{max_order:02}.exr")),
                &RgbImage {
                    width: w,
                    height: h,
                    pixels: p1_img.iter().map(|v| v.to_array()).collect(),
                },
                &[
                    ("kind", "per-pixel".into()),
                    ("order", max_order.to_string()),
                ],
            )?;
            Some((p1_img, relit_image(p2, max_order)?, v2))
        }
        None => None,
    };

    // 3. Relight at every order.
    let mut rows = Vec::new();
    let mut full_images: Vec<Vec<Vec3>> = Vec::new();
    let mut notes = Vec::new();
    let reference_tile = srgb_tile(
        &reference,
        format!("path traced, {} spp", reference_data.spp),
    );
    let (mut full_tiles, mut ad_tiles, mut error_tiles) = (Vec::new(), Vec::new(), Vec::new());
    let mut ad_error_tile = None;
    let mut roi_tile = None;
    let show: Vec<usize> = {
        let mut v = vec![s.orders[0], s.orders[s.orders.len() / 2], max_order];
        v.dedup();
        v
    };
    let err_opts = ErrorImageOptions {
        scale_max: Some(0.25),
        ..ErrorImageOptions::default()
    };
    let mut viewer_images = vec![ViewerImage {
        id: "reference".into(),
        label: format!("path traced, {} spp", reference_data.spp),
        rgb: reference.pixels.clone(),
    }];
    if let Some((p1, _, _)) = &budget_images {
        viewer_images.push(ViewerImage {
            id: format!("per_pixel_{max_order:02}"),
            label: format!("per-pixel bake, full SH order {max_order}"),
            rgb: p1.iter().map(|v| v.to_array()).collect(),
        });
    }
    let load_start = cpu_snapshot();
    for &order in &s.orders {
        say(&format!("relighting at order {order}"));
        let full_opt = RelightOptions {
            order: Some(order),
            adaptive: None,
            rotate_y_deg: 0.0,
            timing_frames: s.timing_frames,
            warmup_frames: 2,
            rotate_y_step_deg: 0.0,
            points: None,
            ..Default::default()
        };
        let full = relight(scene, &accel, &bake, &full_opt)?;
        let ad_opt = RelightOptions {
            adaptive: Some(AdaptiveParams::new(if s.display_threshold {
                Threshold::Display {
                    t: s.threshold,
                    exposure_ev: 0.0,
                }
            } else {
                Threshold::Absolute(s.threshold)
            })),
            ..full_opt.clone()
        };
        let adaptive = relight(scene, &accel, &bake, &ad_opt)?;
        notes.extend(full.stats.notes.iter().cloned());
        let full_img = form_image(scene, &accel, &full, 0.0)?;
        let ad_img = form_image(scene, &accel, &adaptive, 0.0)?;
        viewer_images.push(ViewerImage {
            id: format!("full_{order:02}"),
            label: format!("full SH, order {order}"),
            rgb: full_img.pixels.clone(),
        });
        viewer_images.push(ViewerImage {
            id: format!("adaptive_{order:02}"),
            label: format!("adaptive SH, order {order}"),
            rgb: ad_img.pixels.clone(),
        });
        full_images.push(linear(&full_img));
        let (fi, ai) = (to_compare_image(&full_img), to_compare_image(&ad_img));
        let target = match s.target_psnr {
            Some(p) => {
                let params = ad_opt.adaptive.expect("adaptive options");
                let study = prt_scene_relight::target::relight_to_target(
                    scene,
                    &accel,
                    &bake,
                    &prt_scene_relight::target::TargetOptions {
                        order: Some(order),
                        adaptive: params,
                        target_psnr: p,
                        probe_pixels: 512,
                        seed: s.seed,
                        rotations: vec![0.0],
                        warmup_frames: 1,
                        verify: false,
                    },
                )?;
                let f = &study.frames[0];
                let shaded = study.last_frame.as_ref().expect("one frame shaded");
                let img = form_image(scene, &accel, shaded, 0.0)?;
                let m = compare(&to_compare_image(&img), &fi, None)?.whole;
                Some(TargetColumn {
                    target_psnr: p,
                    ms: f.shade_ms,
                    threshold: f.threshold,
                    psnr_estimate: f.psnr_estimate,
                    psnr_actual: m.psnr_ldr,
                    speedup: full.stats.shade_ms / f.shade_ms.max(1e-9),
                })
            }
            None => None,
        };
        let m_full = compare(&fi, &reference, Some(&mask))?.masked.expect("mask");
        let m_ad = compare(&ai, &reference, Some(&mask))?.masked.expect("mask");
        let m_af = compare(&ai, &fi, None)?.whole;
        write_exr(
            &out_dir.join(format!("images/full_{order:02}.exr")),
            &full_img,
            &[("kind", "full".into()), ("order", order.to_string())],
        )?;
        write_exr(
            &out_dir.join(format!("images/adaptive_{order:02}.exr")),
            &ad_img,
            &[
                ("kind", "adaptive".into()),
                ("order", order.to_string()),
                ("threshold", s.threshold.to_string()),
            ],
        )?;
        write_png(
            &out_dir.join(format!("images/full_{order:02}.png")),
            &full_img,
            0.0,
        )?;
        write_png(
            &out_dir.join(format!("images/adaptive_{order:02}.png")),
            &ad_img,
            0.0,
        )?;
        if show.contains(&order) {
            full_tiles.push(srgb_tile(&fi, format!("full SH, order {order}")));
            ad_tiles.push(srgb_tile(&ai, format!("adaptive SH, order {order}")));
            let pic = prt_compare::render_error_picture(&fi, &reference, Some(&mask), &err_opts)?;
            prt_compare::write_png_atomic(
                &out_dir.join(format!("images/error_full_{order:02}.png")),
                pic.width,
                pic.height,
                &pic.pixels,
            )?;
            error_tiles.push(Tile {
                caption: format!("|full {order} − path traced|, luminance"),
                width: pic.width as u32,
                height: pic.height as u32,
                pixels: pic.pixels,
            });
        }
        if order == max_order {
            let pic = prt_compare::render_error_picture(&ai, &reference, Some(&mask), &err_opts)?;
            prt_compare::write_png_atomic(
                &out_dir.join(format!("images/error_adaptive_{order:02}.png")),
                pic.width,
                pic.height,
                &pic.pixels,
            )?;
            ad_error_tile = Some(Tile {
                caption: format!("|adaptive {order} − path traced|, luminance"),
                width: pic.width as u32,
                height: pic.height as u32,
                pixels: pic.pixels,
            });
            let roi = roi_image(scene, &accel, &adaptive)?;
            write_png(&out_dir.join("images/roi.png"), &roi, 0.0)?;
            roi_tile = Some(srgb_tile(
                &to_compare_image(&roi),
                format!("ROI, order {order}: red all bands, grey fewer"),
            ));
        }
        rows.push(OrderRow {
            order,
            coefficients: order * order,
            full_ms: full.stats.shade_ms,
            full_ms_range: [full.stats.shade_ms_min, full.stats.shade_ms_max],
            adaptive_ms: adaptive.stats.shade_ms,
            adaptive_ms_range: [adaptive.stats.shade_ms_min, adaptive.stats.shade_ms_max],
            speedup: full.stats.shade_ms / adaptive.stats.shade_ms.max(1e-9),
            psnr_adaptive_vs_full: m_af.psnr_ldr,
            psnr_full_vs_reference: m_full.psnr_ldr,
            psnr_adaptive_vs_reference: m_ad.psnr_ldr,
            rel_l2_full: m_full.rel_l2,
            rel_l2_adaptive: m_ad.rel_l2,
            roi_diffuse: adaptive.stats.roi_fraction_diffuse,
            roi_specular: adaptive.stats.roi_fraction_specular,
            target,
        });
    }

    let timing_load = load_start
        .zip(cpu_snapshot())
        .map(|(a, b)| TimingLoad::between(a, b));

    // 4. The error budget of every order.
    let mut error_budget = Vec::new();
    if let Some((p1, p2, v2)) = &budget_images {
        let bits = mask.as_slice();
        let r = &reference_data.radiance;
        let top_index = s
            .orders
            .iter()
            .position(|&o| o == max_order)
            .expect("the highest order is in the list");
        let top = &full_images[top_index];
        let v2_top = relit_image(v2, max_order)?;
        // The per-pixel baseline is the mean of the two per-pixel bakes (half the noise of
        // either); its noise is a quarter of MSE(P, P').
        let p_mean: Vec<Vec3> = p1.iter().zip(p2).map(|(a, b)| 0.5 * (*a + *b)).collect();
        let highest_vs_reference = masked_mse(top, r, bits);
        let (vertex_vs_pixel, pixel_seeds, pixel_vs_reference, vertex_seeds_highest) = (
            masked_mse(top, &p_mean, bits),
            masked_mse(p1, p2, bits) / 2.0,
            masked_mse(&p_mean, r, bits),
            masked_mse(top, &v2_top, bits),
        );
        for (&order, img) in s.orders.iter().zip(&full_images) {
            let v2_n = if order == max_order {
                v2_top.clone()
            } else {
                relit_image(v2, order)?
            };
            error_budget.push(BudgetRow::new(&BudgetInputs {
                order,
                total: masked_mse(img, r, bits),
                vs_highest: masked_mse(img, top, bits),
                vertex_vs_pixel,
                highest_vs_reference,
                vertex_seeds: masked_mse(img, &v2_n, bits),
                vertex_seeds_highest,
                pixel_seeds,
                pixel_vs_reference,
                reference_noise: reference_noise_mse,
            }));
        }
    }
    notes.sort();
    notes.dedup();

    // 4b. The reflectance-field section (after the timed relightings, so it does not load
    // them).
    let reflectance = match &s.reflectance {
        Some(rf) => {
            let out = crate::rf_section::run_section(
                &crate::rf_section::RfContext {
                    scene,
                    accel: &accel,
                    out_dir,
                    reference: &reference,
                    mask: &mask,
                    reference_noise_psnr,
                    bounces: s.bounces,
                    rays: s.rays,
                    seed: s.seed,
                    sh_timing_frames: s.timing_frames,
                    progress: s.progress,
                },
                scene_key(scene),
                rf,
            )?;
            viewer_images.extend(out.viewer_images);
            Some(out.section)
        }
        None => None,
    };

    let error_budget_summary = summary_sentence(&error_budget);
    // Per object: quality against the path tracer at every order, and what meets the target.
    // (from the full-order images of step 3, not relit again)
    let mut recommendation = crate::recommend::object_quality_with(
        scene,
        &accel,
        &bake,
        &reference,
        &s.orders,
        s.target_psnr.unwrap_or(f64::INFINITY),
        |order| {
            let k = s.orders.iter().position(|&o| o == order).expect("listed");
            Ok(to_image(&full_images[k], w, h))
        },
    )?;
    if let Some((p1, p2, _)) = &budget_images {
        let p_mean = to_image(
            &p1.iter()
                .zip(p2)
                .map(|(a, b)| 0.5 * (*a + *b))
                .collect::<Vec<_>>(),
            w,
            h,
        );
        let psnr = crate::recommend::object_psnr(scene, &accel, &p_mean, &reference)?;
        for (q, p) in recommendation.iter_mut().zip(psnr) {
            q.per_pixel_psnr = p.is_finite().then_some(p);
        }
    }

    // 5. Plots and the image grid.
    let blue = RGBColor(31, 119, 180);
    let orange = RGBColor(255, 127, 14);
    let green = RGBColor(44, 160, 44);
    // Identical images have infinite PSNR: drawn a little above the highest finite value.
    let finite_max = rows
        .iter()
        .flat_map(|r| {
            [
                r.psnr_full_vs_reference,
                r.psnr_adaptive_vs_reference,
                r.psnr_adaptive_vs_full,
            ]
        })
        .chain(convergence.iter().map(|c| c.psnr_ldr))
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    let cap = (finite_max / 5.0).ceil() * 5.0 + 5.0;
    let any_inf = rows.iter().any(|r| !r.psnr_adaptive_vs_full.is_finite());
    let ceiling = reference_noise_psnr;
    let ceiling_line = vec![(ceiling, "reference noise ceiling".to_string())];
    line_chart(
        &out_dir.join("error_vs_time.png"),
        "PSNR against time (object pixels)",
        "time per image (path tracing) or per frame (SH shading), ms, log scale",
        "PSNR vs path-traced reference (dB, 8-bit sRGB)",
        &ChartOptions {
            log_x: true,
            hlines: ceiling_line.clone(),
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "path tracing (spp 1, 2, 4, …)".into(),
                points: convergence
                    .iter()
                    .map(|c| (c.ms, finite_or(c.psnr_ldr, cap)))
                    .collect(),
                colour: blue,
            },
            Series {
                label: "full-order SH (orders in --orders)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.full_ms, finite_or(r.psnr_full_vs_reference, cap)))
                    .collect(),
                colour: orange,
            },
            Series {
                label: "adaptive SH (same orders)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.adaptive_ms, finite_or(r.psnr_adaptive_vs_reference, cap)))
                    .collect(),
                colour: green,
            },
        ],
    )?;
    line_chart(
        &out_dir.join("psnr_vs_order.png"),
        "PSNR against SH order",
        "order (number of SH bands)",
        "PSNR (dB, 8-bit sRGB)",
        &ChartOptions {
            integer_x: true,
            hlines: ceiling_line,
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "full vs path traced (object pixels)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_full_vs_reference, cap)))
                    .collect(),
                colour: orange,
            },
            Series {
                label: "adaptive vs path traced (object pixels)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_adaptive_vs_reference, cap)))
                    .collect(),
                colour: green,
            },
            Series {
                label: if any_inf {
                    format!("adaptive vs full (whole image; identical = ∞, drawn at {cap:.0})")
                } else {
                    "adaptive vs full (whole image)".into()
                },
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_adaptive_vs_full, cap)))
                    .collect(),
                colour: blue,
            },
        ],
    )?;
    line_chart(
        &out_dir.join("roi_vs_order.png"),
        &format!(
            "Region of interest of adaptive SH (threshold T = {})",
            s.threshold
        ),
        "order (number of SH bands)",
        "points in the ROI (% of active points)",
        &ChartOptions {
            integer_x: true,
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "diffuse ROI".into(),
                points: rows
                    .iter()
                    .filter_map(|r| r.roi_diffuse.map(|v| (r.order as f64, 100.0 * v)))
                    .collect(),
                colour: orange,
            },
            Series {
                label: "specular ROI".into(),
                points: rows
                    .iter()
                    .filter_map(|r| r.roi_specular.map(|v| (r.order as f64, 100.0 * v)))
                    .collect(),
                colour: green,
            },
        ],
    )?;
    if !error_budget.is_empty() {
        let colours = [
            RGBColor(31, 119, 180),
            RGBColor(255, 127, 14),
            RGBColor(44, 160, 44),
            RGBColor(214, 39, 40),
            RGBColor(148, 103, 189),
        ];
        stacked_shares(
            &out_dir.join("error_budget.png"),
            "Error budget of full-order SH (what each approximation costs, % of the MSE)",
            "order (number of SH bands)",
            "% of the total MSE (object pixels, linear radiance)",
            &error_budget
                .iter()
                .map(|b| {
                    (
                        b.order as f64,
                        b.total_mse,
                        crate::budget::TERMS.iter().map(|t| b.term(t)).collect(),
                    )
                })
                .collect::<Vec<_>>(),
            &crate::budget::TERMS
                .iter()
                .zip(colours)
                .map(|(t, c)| (t.replace('_', " "), c))
                .collect::<Vec<_>>(),
        )?;
    }
    // Grid: one column per shown order — full, adaptive, |full − reference| — then the
    // reference, the adaptive error at the highest order and the ROI picture.
    let pad = |mut v: Vec<Tile>| {
        while !v.len().is_multiple_of(3) {
            v.push(Tile::blank());
        }
        v
    };
    let mut tiles = Vec::new();
    tiles.extend(pad(full_tiles));
    tiles.extend(pad(ad_tiles));
    tiles.extend(pad(error_tiles));
    tiles.push(reference_tile);
    tiles.extend(ad_error_tile);
    tiles.extend(roi_tile);
    image_grid(&out_dir.join("images.png"), &tiles, 3, 320)?;

    let data = ReportData {
        scene: scene_path.display().to_string(),
        machine: Machine {
            timing_load,
            ..machine()
        },
        settings: serde_json::json!({
            "orders": s.orders, "reference_spp": s.reference_spp, "rays": s.rays, "bounces": s.bounces,
            "threshold": s.threshold, "threshold_kind": if s.display_threshold { "display (8-bit view, exposure 0)" } else { "absolute (output radiance)" },
            "cost_exponent": AdaptiveParams::new(Threshold::Absolute(s.threshold)).cost_exponent, "seed": s.seed,
            "timing_frames": s.timing_frames, "image": format!("{w}x{h}"),
        }),
        reference_seconds: reference_data.seconds,
        reference_noise_rmse: reference_noise_mse.sqrt(),
        reference_noise_psnr_ldr: Some(reference_noise_psnr),
        reference: reference_info,
        error_budget,
        error_budget_summary,
        recommendation,
        bake_seconds,
        bake_cached,
        bake_file: bake_path.display().to_string(),
        bake_rays: bake
            .meta
            .ray_stats
            .iter()
            .map(|r| ObjectRays {
                object: r.object.clone(),
                points: r.points,
                rays: r.rays,
                backface_fraction: r.backface_fraction(),
                inside_fraction: r.inside_fraction(),
                inside_points: r.inside_points,
            })
            .collect(),
        convergence,
        orders: rows,
        notes,
        reflectance,
    };
    write_text(
        &out_dir.join("report.json"),
        &serde_json::to_string_pretty(&data).map_err(|e| ReportError::Invalid(e.to_string()))?,
    )?;
    write_text(&out_dir.join("report.csv"), &csv(&data))?;
    write_text(&out_dir.join("report.md"), &markdown(&data, false))?;
    write_text(
        &out_dir.join("index.html"),
        &html(&data, w, h, &viewer_images),
    )?;
    Ok(data)
}

fn write_text(path: &Path, text: &str) -> Result<(), ReportError> {
    prt_tracer::output::write_atomically(path, |w| {
        std::io::Write::write_all(w, text.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(|e| ReportError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })
}

fn db(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "∞".into()
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{:.1}", 100.0 * v))
}

fn csv(d: &ReportData) -> String {
    let mut s = String::from("order,coefficients,full_ms,adaptive_ms,speedup,psnr_adaptive_vs_full,psnr_full_vs_reference,psnr_adaptive_vs_reference,rel_l2_full,rel_l2_adaptive,roi_diffuse,roi_specular,full_ms_min,full_ms_max,adaptive_ms_min,adaptive_ms_max,target_psnr,target_ms,target_threshold,target_psnr_estimate,target_psnr_actual\n");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}",
            r.order,
            r.coefficients,
            r.full_ms,
            r.adaptive_ms,
            r.speedup,
            r.psnr_adaptive_vs_full,
            r.psnr_full_vs_reference,
            r.psnr_adaptive_vs_reference,
            r.rel_l2_full,
            r.rel_l2_adaptive,
            r.roi_diffuse.map_or(String::new(), |v| v.to_string()),
            r.roi_specular.map_or(String::new(), |v| v.to_string()),
            r.full_ms_range[0],
            r.full_ms_range[1],
            r.adaptive_ms_range[0],
            r.adaptive_ms_range[1],
            r.target.as_ref().map_or(",,,,".to_string(), |t| format!(
                "{},{},{},{},{}",
                t.target_psnr, t.ms, t.threshold, t.psnr_estimate, t.psnr_actual
            ))
        );
    }
    if !d.error_budget.is_empty() {
        let _ = writeln!(
            s,
            "\norder,total_mse,{},unaccounted,{},cross_terms",
            crate::budget::TERMS.join(","),
            crate::budget::TERMS
                .map(|t| format!("direct_{t}"))
                .join(",")
        );
        for b in &d.error_budget {
            let _ = write!(s, "{},{}", b.order, b.total_mse);
            for t in crate::budget::TERMS {
                let _ = write!(s, ",{}", b.term(t));
            }
            let _ = write!(s, ",{}", b.unaccounted);
            for t in crate::budget::TERMS {
                let _ = write!(s, ",{}", b.direct(t));
            }
            let _ = writeln!(s, ",{}", b.cross_terms);
        }
    }
    s.push_str("\nspp,ms,psnr_ldr,rel_l2\n");
    for c in &d.convergence {
        let _ = writeln!(s, "{},{},{},{}", c.spp, c.ms, c.psnr_ldr, c.rel_l2);
    }
    s
}

fn markdown(d: &ReportData, html_images: bool) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Speed against error: `{}`\n", d.scene);
    let _ = writeln!(
        s,
        "Machine: {} logical cores, {}.  ",
        d.machine.cores, d.machine.cpu
    );
    if let Some(l) = &d.machine.timing_load {
        let _ = writeln!(s, "{}.  ", l.sentence(d.machine.cores));
    }
    if !html_images {
        // The HTML page lists the settings itself.
        let _ = writeln!(s, "Settings: `{}`.\n", d.settings);
    } else {
        s.push('\n');
    }
    let r = &d.reference;
    let _ = writeln!(
        s,
        "Reference: path traced, {} spp in {:.2} s{}; its own Monte Carlo noise on object pixels (from its two half images) is RMSE {:.4}, a PSNR ceiling of {} dB for any method compared with it{}.  ",
        r.spp,
        r.seconds,
        if r.cached { " (cached)" } else { "" },
        d.reference_noise_rmse,
        db(r.noise_psnr_ldr),
        match (r.target_psnr_ldr, r.target_met) {
            (Some(t), Some(false)) => format!(" — short of the {t} dB target: it stopped at the sample cap (raise --reference-spp)"),
            (Some(t), _) => format!(" (rendered to reach {t} dB)"),
            _ => String::new(),
        }
    );
    let _ = writeln!(
        s,
        "Bake: `{}` ({}).\n",
        d.bake_file,
        if d.bake_cached {
            "reused from the cache".to_string()
        } else {
            format!("baked in {:.2} s", d.bake_seconds)
        }
    );
    if !d.bake_rays.is_empty() {
        let _ = writeln!(s, "## Bake rays per object\n");
        let _ = writeln!(s, "A closed, well-oriented mesh has no back-face hits and no rays started inside geometry; large values point at inverted normals, holes or interpenetrating objects.\n");
        let _ = writeln!(
            s,
            "| object | points | rays | back-face hits % | rays started inside geometry % (points) |\n|---|---:|---:|---:|---:|"
        );
        for r in &d.bake_rays {
            let _ = writeln!(
                s,
                "| {} | {} | {} | {:.3} | {:.3} ({}) |",
                r.object,
                r.points,
                r.rays,
                100.0 * r.backface_fraction,
                100.0 * r.inside_fraction,
                r.inside_points
            );
        }
        let _ = writeln!(s);
    }
    let _ = writeln!(s, "## Per order (cf. Lee & Kim 2014, Tables 6.1 and 6.2)\n");
    let _ = writeln!(s, "PSNR is `psnr_ldr` (8-bit sRGB, peak 255); against the reference it is over object pixels only, adaptive vs full over the whole image.\n");
    let _ = writeln!(
        s,
        "Times are the median of {} frames, with the fastest and slowest in brackets.\n",
        d.settings["timing_frames"]
    );
    let _ = writeln!(s, "| order | coefficients | full ms/frame | adaptive ms/frame | speed-up | PSNR adaptive vs full | PSNR full vs path traced | PSNR adaptive vs path traced | ROI diffuse % | ROI specular % |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} [{:.3}–{:.3}] | {:.3} [{:.3}–{:.3}] | {:.2}× | {} | {} | {} | {} | {} |",
            r.order,
            r.coefficients,
            r.full_ms,
            r.full_ms_range[0],
            r.full_ms_range[1],
            r.adaptive_ms,
            r.adaptive_ms_range[0],
            r.adaptive_ms_range[1],
            r.speedup,
            db(r.psnr_adaptive_vs_full),
            db(r.psnr_full_vs_reference),
            db(r.psnr_adaptive_vs_reference),
            pct(r.roi_diffuse),
            pct(r.roi_specular)
        );
    }
    if d.orders.iter().any(|r| r.target.is_some()) {
        let _ = writeln!(
            s,
            "\n## Target quality (adaptive relighting to a PSNR against full order)\n"
        );
        let _ = writeln!(s, "`prt relight --adaptive --target-psnr P` picks the frame's threshold from an estimate on 512 random object pixels relit at full order (their cost included); the PSNR reached is measured against the full-order image of the row. The honest baseline is the lowest uniform order that meets the same target (the PSNR-against-order plot).\n");
        let _ = writeln!(s, "| order | target dB | ms/frame | speed-up vs full | threshold | PSNR estimate | PSNR reached |");
        let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|");
        for r in &d.orders {
            if let Some(t) = &r.target {
                let _ = writeln!(
                    s,
                    "| {} | {} | {:.3} | {:.2}× | {} | {} | {} |",
                    r.order,
                    t.target_psnr,
                    t.ms,
                    t.speedup,
                    if t.threshold > 0.0 {
                        format!("{:.4}", t.threshold)
                    } else {
                        "full order".into()
                    },
                    db(t.psnr_estimate),
                    db(t.psnr_actual)
                );
            }
        }
    }
    if !d.recommendation.is_empty() {
        let target = d
            .orders
            .iter()
            .find_map(|r| r.target.as_ref().map(|t| t.target_psnr));
        let _ = writeln!(s, "\n## Per object: what each needs\n");
        let _ = writeln!(s, "PSNR against the path tracer over each object's pixels (8-bit view) at every order of the bake; the lowest order within 0.5 dB of the object's best is where more bands stop paying; `prt bake --target-psnr P` keeps per object the lowest order that reaches P.\n");
        let _ = writeln!(s, "| object | pixels | best PSNR per vertex (order) | lowest order within 0.5 dB of it | lowest order reaching {} | per pixel at the highest order | recommendation |", target.map_or("the target".into(), |t| format!("{t} dB")));
        let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---|");
        for q in &d.recommendation {
            if q.pixels == 0 {
                let _ = writeln!(s, "| {} | 0 | – | – | not visible | – | keep the highest order (its error cannot be measured from this camera) |", q.object);
                continue;
            }
            let near = q
                .psnr_by_order
                .iter()
                .find(|(_, p)| *p >= q.best_psnr - 0.5)
                .map_or(q.best_order, |(o, _)| *o);
            let per_pixel = q.per_pixel_psnr;
            let advice = match (q.chosen, per_pixel, target) {
                (Some(o), _, Some(t)) => format!("per vertex, order {o} (reaches {t} dB)"),
                (None, Some(pp), Some(t)) if pp >= t => {
                    format!("per pixel (reaches {t} dB; per vertex cannot)")
                }
                (None, Some(pp), _) if pp > q.best_psnr + 0.5 => format!(
                    "not reachable; per pixel gets closest ({}), else per vertex order {near}",
                    db(pp)
                ),
                _ => format!(
                    "not reachable: per vertex order {near} gets within 0.5 dB of the best this bake allows ({}); the error budget names what limits it",
                    db(q.best_psnr)
                ),
            };
            let _ = writeln!(
                s,
                "| {} | {} | {} ({}) | {} | {} | {} | {} |",
                q.object,
                q.pixels,
                db(q.best_psnr),
                q.best_order,
                near,
                q.chosen.map_or_else(
                    || format!("not reachable (best {})", db(q.best_psnr)),
                    |o| o.to_string()
                ),
                per_pixel.map_or("–".into(), db),
                advice
            );
        }
    }
    if !d.error_budget.is_empty() {
        let _ = writeln!(s, "\n## Error budget of full-order SH\n");
        let _ = writeln!(s, "{}\n", d.error_budget_summary);
        let _ = writeln!(s, "Mean squared error against the path tracer over object pixels, linear radiance, split into terms measured by controlled experiments on this scene:\n");
        for (name, help) in crate::budget::TERM_HELP {
            let _ = writeln!(s, "- `{name}`: {help}");
        }
        let _ = writeln!(s, "\nEach term is what that approximation costs: starting from the reference's noise, each experiment adds the error it brings, so the terms add up to the total (`unaccounted` is what a negative cost, shown as 0, leaves). `cross` is from the second table: the error components' own sizes (the MSE of each controlled difference) add up to the total only when they are uncorrelated, and cross = total − Σ sizes says how much their correlations take.\n");
        let _ = write!(s, "| order | total MSE |");
        for t in crate::budget::TERMS {
            let _ = write!(s, " {t} |");
        }
        let _ = writeln!(s, " unaccounted % | cross % | largest |");
        let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
        for b in &d.error_budget {
            let pc = |v: f64| 100.0 * v / b.total_mse.max(f64::MIN_POSITIVE);
            let _ = write!(s, "| {} | {:.3e} |", b.order, b.total_mse);
            for t in crate::budget::TERMS {
                let _ = write!(s, " {:.2e} ({:.0} %) |", b.term(t), pc(b.term(t)));
            }
            let _ = writeln!(
                s,
                " {:+.1} | {:+.1} | {} |",
                pc(b.unaccounted),
                pc(b.cross_terms),
                b.largest
            );
        }
        let _ = writeln!(
            s,
            "\nThe error components' own sizes (MSE of each controlled difference):\n"
        );
        let _ = write!(s, "| order |");
        for t in crate::budget::TERMS {
            let _ = write!(s, " {t} |");
        }
        let _ = writeln!(s, "\n|---:|---:|---:|---:|---:|---:|");
        for b in &d.error_budget {
            let _ = write!(s, "| {} |", b.order);
            for t in crate::budget::TERMS {
                let _ = write!(s, " {:.2e} |", b.direct(t));
            }
            let _ = writeln!(s);
        }
    }
    let _ = writeln!(
        s,
        "\n## Path tracing convergence (another seed against the reference)\n"
    );
    let _ = writeln!(
        s,
        "| spp | ms | PSNR (dB) | relative L2 |\n|---:|---:|---:|---:|"
    );
    for c in &d.convergence {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {} | {:.4} |",
            c.spp,
            c.ms,
            db(c.psnr_ldr),
            c.rel_l2
        );
    }
    if let Some(r) = d.orders.first() {
        let _ = writeln!(s, "\n## Reproducing a row by hand\n");
        let _ = writeln!(
            s,
            "The relit images are `images/full_NN.exr` and `images/adaptive_NN.exr`, the object mask `images/mask.png`. For order {o}:\n",
            o = r.order
        );
        let _ = writeln!(
            s,
            "    prt relight {scene} --bake {bake} --order {o} --out full_{o:02}.exr\n    prt compare full_{o:02}.exr images/reference.exr --mask images/mask.png\n",
            scene = d.scene,
            bake = d.bake_file,
            o = r.order
        );
        let _ = writeln!(
            s,
            "gives `masked_psnr_ldr` = {} dB (the table's \"PSNR full vs path traced\"); add `--adaptive --threshold {}{}` for the adaptive column.",
            db(r.psnr_full_vs_reference),
            d.settings["threshold"],
            if d.settings["threshold_kind"].as_str().is_some_and(|k| k.starts_with("display")) {
                " --display-threshold"
            } else {
                ""
            }
        );
    }
    if let Some(rf) = &d.reflectance {
        s.push_str(&crate::rf_section::markdown(rf));
    }
    if !d.notes.is_empty() {
        let _ = writeln!(s, "\n## Notes\n");
        for n in &d.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    if html_images {
        // The page's viewer and interactive charts take the place of the static plots.
        let _ = writeln!(
            s,
            "\n## Static files\n\nThe same plots as PNG files: error_vs_time.png, psnr_vs_order.png, roi_vs_order.png{}{}, and images.png (an image grid){}; every image as EXR in images/.",
            if d.error_budget.is_empty() { "" } else { ", error_budget.png" },
            if d.reflectance.is_none() { "" } else { ", rf_psnr_vs_coefficients.png, rf_error_vs_coefficients.png, rf_h1_vs_coefficients.png" },
            if d.reflectance.is_none() { "" } else { " and rf_images.png (one tile per reflectance-field method)" }
        );
        return s;
    }
    let img = |s: &mut String, file: &str, alt: &str| {
        let _ = writeln!(s, "![{alt}]({file})\n");
    };
    let _ = writeln!(s, "\n## Plots and images\n");
    img(&mut s, "error_vs_time.png", "error against time");
    img(&mut s, "psnr_vs_order.png", "PSNR against order");
    img(&mut s, "roi_vs_order.png", "ROI against order");
    if !d.error_budget.is_empty() {
        img(&mut s, "error_budget.png", "error budget per order");
    }
    img(
        &mut s,
        "images.png",
        "reference, relit images, error images and ROI",
    );
    if d.reflectance.is_some() {
        img(
            &mut s,
            "rf_psnr_vs_coefficients.png",
            "reflectance fields and per-pixel SH against coefficients",
        );
        img(
            &mut s,
            "rf_error_vs_coefficients.png",
            "compression error (L2) against coefficients",
        );
        img(
            &mut s,
            "rf_h1_vs_coefficients.png",
            "compression error (H1) against coefficients",
        );
        img(
            &mut s,
            "rf_images.png",
            "one image per reflectance-field method",
        );
    }
    s
}

fn html(d: &ReportData, w: u32, h: u32, images: &[ViewerImage]) -> String {
    // The Markdown body as HTML by a tiny converter (pipes → sortable tables), after the
    // viewer, the interactive charts and the settings list of `viewer::page`.
    let md = markdown(d, true);
    let mut body = String::new();
    let mut in_table = false;
    let mut title = String::from("prt report");
    for line in md.lines() {
        if line.starts_with('|') {
            if line.contains("---") {
                continue;
            }
            let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
            if !in_table {
                body.push_str("<table class=\"sortable\"><tr>");
                for c in &cells {
                    let _ = write!(body, "<th>{}</th>", escape(c));
                }
                body.push_str("</tr>\n");
                in_table = true;
            } else {
                body.push_str("<tr>");
                for c in &cells {
                    let _ = write!(body, "<td>{}</td>", escape(c));
                }
                body.push_str("</tr>\n");
            }
            continue;
        }
        if in_table {
            body.push_str("</table>\n");
            in_table = false;
        }
        if let Some(t) = line.strip_prefix("## ") {
            let _ = writeln!(body, "<h2>{}</h2>", escape(t));
        } else if let Some(t) = line.strip_prefix("# ") {
            title = t.replace('`', "");
        } else if let Some(t) = line.strip_prefix("    ") {
            let _ = writeln!(body, "<pre>{}</pre>", escape(t));
        } else if let Some(t) = line.strip_prefix("- ") {
            let _ = writeln!(body, "<li>{}</li>", escape(t));
        } else if !line.is_empty() {
            let _ = writeln!(body, "<p>{}</p>", escape(line));
        }
    }
    if in_table {
        body.push_str("</table>\n");
    }
    let load = d.machine.timing_load.as_ref().map_or_else(
        || {
            (
                "Machine load while timing: not measured on this system.".to_owned(),
                false,
            )
        },
        |l| (l.sentence(d.machine.cores), l.noisy()),
    );
    let json = serde_json::to_value(d).unwrap_or(serde_json::Value::Null);
    crate::viewer::page(&title, (&load.0, load.1), &json, w, h, images, &body)
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('`', "")
}
