//! `prt report`: the speed-against-error report of a scene. It path-traces the reference (and a
//! convergence series), bakes (or reuses a cached bake), relights at every order with the full
//! and the adaptive method, measures time and error, and writes tables, plots and images.
//!
//! Every figure in the report is reproducible: the reference and the bake are seeded, and the
//! same numbers come out of `prt render`, `prt bake`, `prt relight` and `prt compare` run by
//! hand with the settings printed in the report.

use crate::error::ReportError;
use crate::imaging::{form_image, object_mask, roi_image, RgbImage};
use crate::io::{to_compare_image, write_exr, write_png};
use crate::plots::{image_grid, line_chart, ChartOptions, Series, Tile};
use crate::relit::{check_bake, relight, RelightOptions};
use glam::Vec3;
use plotters::style::RGBColor;
use prt_bake::{BakeSettings, PointKind};
use prt_compare::{compare, CompareOptions, ErrorImageOptions, Image, Mask};
use prt_relight::{AdaptiveParams, Threshold};
use prt_scene::Scene;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Settings of a report.
#[derive(Clone, Debug)]
pub struct ReportSettings {
    /// Orders (bands) to relight at.
    pub orders: Vec<usize>,
    /// Samples per pixel of the path-traced reference.
    pub reference_spp: u32,
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
    /// Adaptive shading time per frame (median of the timed frames), ms.
    pub adaptive_ms: f64,
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
    /// Monte Carlo noise of the reference (RMSE of one render against the truth, object pixels).
    pub reference_noise_rmse: f64,
    /// psnr_ldr ceiling implied by that noise (object pixels).
    pub reference_noise_psnr_ldr: Option<f64>,
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

/// The machine the report ran on.
#[derive(Clone, Debug, Serialize)]
pub struct Machine {
    /// Logical cores available.
    pub cores: usize,
    /// CPU model name (from /proc/cpuinfo), if known.
    pub cpu: String,
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
    }
}

fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Cache key of a bake: the geometry hashes, materials, environment texels and settings.
fn bake_key(scene: &Scene, s: &BakeSettings) -> u64 {
    let mut h = 0xcbf2_9ce4_8422_2325u64;
    for m in &scene.meshes {
        h = fnv(
            &prt_bake::geometry_hash(&m.positions, &m.indices).to_le_bytes(),
            h,
        );
        h = fnv(&(m.material as u64).to_le_bytes(), h);
    }
    h = fnv(format!("{:?}", scene.materials).as_bytes(), h);
    let env = &scene.environment;
    h = fnv(
        format!(
            "{:?} {} {}x{}",
            env.mapping, env.rotation_y_deg, env.image.width, env.image.height
        )
        .as_bytes(),
        h,
    );
    for t in &env.image.texels {
        for c in t {
            h = fnv(&c.to_le_bytes(), h);
        }
    }
    fnv(
        format!(
            "{:?} {:?} {} {} {} {}",
            s.order, s.points, s.rays, s.bounces, s.seed, s.error_target
        )
        .as_bytes(),
        h,
    )
}

fn to_image(radiance: &[Vec3], w: u32, h: u32) -> Image {
    Image {
        width: w as usize,
        height: h as usize,
        pixels: radiance.iter().map(|v| v.to_array()).collect(),
    }
}

fn srgb_tile(img: &Image, caption: String) -> Tile {
    let lin: Vec<Vec3> = img.pixels.iter().map(|p| Vec3::from_array(*p)).collect();
    let bytes = prt_tracer::output::to_srgb8(&lin, 0.0);
    Tile {
        caption,
        width: img.width as u32,
        height: img.height as u32,
        pixels: bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
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
    let opts = CompareOptions::default();

    // 1. Reference with its variance, and the convergence series (another seed).
    say(&format!(
        "path-traced reference, {} spp, {} bounce(s)",
        s.reference_spp, s.bounces
    ));
    let rs = prt_tracer::RenderSettings {
        spp: s.reference_spp,
        bounces: s.bounces as i32,
        seed: s.seed,
        aovs: true,
        progress: s.progress,
        ..Default::default()
    };
    let reference_out = prt_tracer::render(scene, &rs)?;
    prt_tracer::output::write_exr(&out_dir.join("images/reference.exr"), &reference_out)?;
    let reference = to_image(&reference_out.radiance, w, h);
    let variance = to_image(
        &reference_out.aovs.as_ref().expect("aovs asked").variance,
        w,
        h,
    );
    let noise = prt_compare::noise_from_variance(&variance, &reference, Some(&mask), &opts)?;
    let noise_masked = noise.masked.unwrap_or(noise.whole);
    let mut convergence = Vec::new();
    let mut spp = 1;
    while spp <= s.reference_spp / 2 {
        let cs = prt_tracer::RenderSettings {
            spp,
            seed: s.seed.wrapping_add(0x5eed),
            aovs: false,
            progress: false,
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

    // 2. The bake (cached).
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
    let key = bake_key(scene, &bs);
    let bake_path = out_dir.join("cache").join(format!("bake-{key:016x}.prtb"));
    let mut bake_seconds = 0.0;
    let cached = prt_bakefile::read_bake(&bake_path)
        .ok()
        .filter(|b| check_bake(scene, b, &bake_path).is_ok());
    let bake_cached = cached.is_some();
    let bake = match cached {
        Some(b) => {
            say(&format!("reusing the cached bake {}", bake_path.display()));
            b
        }
        None => {
            say(&format!(
                "baking order {max_order}, {} rays per vertex, {} bounce(s)",
                s.rays, s.bounces
            ));
            let t = Instant::now();
            let out = prt_bake::bake(scene, &accel, &bs)?;
            bake_seconds = t.elapsed().as_secs_f64();
            prt_bakefile::write_bake(&bake_path, &out.bake, prt_bakefile::ScalarType::F32)?;
            out.bake
        }
    };

    // 3. Relight at every order.
    let mut rows = Vec::new();
    let mut notes = Vec::new();
    let reference_tile = srgb_tile(&reference, format!("path traced, {} spp", s.reference_spp));
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
    for &order in &s.orders {
        say(&format!("relighting at order {order}"));
        let full_opt = RelightOptions {
            order: Some(order),
            adaptive: None,
            rotate_y_deg: 0.0,
            timing_frames: s.timing_frames,
            warmup_frames: 2,
            rotate_y_step_deg: 0.0,
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
        let (fi, ai) = (to_compare_image(&full_img), to_compare_image(&ad_img));
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
            adaptive_ms: adaptive.stats.shade_ms,
            speedup: full.stats.shade_ms / adaptive.stats.shade_ms.max(1e-9),
            psnr_adaptive_vs_full: m_af.psnr_ldr,
            psnr_full_vs_reference: m_full.psnr_ldr,
            psnr_adaptive_vs_reference: m_ad.psnr_ldr,
            rel_l2_full: m_full.rel_l2,
            rel_l2_adaptive: m_ad.rel_l2,
            roi_diffuse: adaptive.stats.roi_fraction_diffuse,
            roi_specular: adaptive.stats.roi_fraction_specular,
        });
    }
    notes.sort();
    notes.dedup();

    // 4. Plots and the image grid.
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
    let ceiling = noise_masked.psnr_ldr_ceiling;
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
        machine: machine(),
        settings: serde_json::json!({
            "orders": s.orders, "reference_spp": s.reference_spp, "rays": s.rays, "bounces": s.bounces,
            "threshold": s.threshold, "threshold_kind": if s.display_threshold { "display (8-bit view, exposure 0)" } else { "absolute (output radiance)" },
            "cost_exponent": AdaptiveParams::new(Threshold::Absolute(s.threshold)).cost_exponent, "seed": s.seed,
            "timing_frames": s.timing_frames, "image": format!("{w}x{h}"),
        }),
        reference_seconds: reference_out.seconds,
        reference_noise_rmse: noise_masked.rmse,
        reference_noise_psnr_ldr: Some(noise_masked.psnr_ldr_ceiling),
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
    };
    write_text(
        &out_dir.join("report.json"),
        &serde_json::to_string_pretty(&data).map_err(|e| ReportError::Invalid(e.to_string()))?,
    )?;
    write_text(&out_dir.join("report.csv"), &csv(&data))?;
    write_text(&out_dir.join("report.md"), &markdown(&data, false))?;
    write_text(&out_dir.join("index.html"), &html(&data))?;
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
    let mut s = String::from("order,coefficients,full_ms,adaptive_ms,speedup,psnr_adaptive_vs_full,psnr_full_vs_reference,psnr_adaptive_vs_reference,rel_l2_full,rel_l2_adaptive,roi_diffuse,roi_specular\n");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "{},{},{},{},{},{},{},{},{},{},{},{}",
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
            r.roi_specular.map_or(String::new(), |v| v.to_string())
        );
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
    let _ = writeln!(s, "Settings: `{}`.\n", d.settings);
    let _ = writeln!(
        s,
        "Reference: path traced in {:.2} s; its own Monte Carlo noise on object pixels is RMSE {:.4} (a PSNR ceiling of {} dB for any method compared with it).  ",
        d.reference_seconds,
        d.reference_noise_rmse,
        d.reference_noise_psnr_ldr.map_or("–".into(), db)
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
    let _ = writeln!(s, "| order | coefficients | full ms/frame | adaptive ms/frame | speed-up | PSNR adaptive vs full | PSNR full vs path traced | PSNR adaptive vs path traced | ROI diffuse % | ROI specular % |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} | {:.3} | {:.2}× | {} | {} | {} | {} | {} |",
            r.order,
            r.coefficients,
            r.full_ms,
            r.adaptive_ms,
            r.speedup,
            db(r.psnr_adaptive_vs_full),
            db(r.psnr_full_vs_reference),
            db(r.psnr_adaptive_vs_reference),
            pct(r.roi_diffuse),
            pct(r.roi_specular)
        );
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
    if !d.notes.is_empty() {
        let _ = writeln!(s, "\n## Notes\n");
        for n in &d.notes {
            let _ = writeln!(s, "- {n}");
        }
    }
    let img = |s: &mut String, file: &str, alt: &str| {
        if html_images {
            let _ = writeln!(s, "<p><img src=\"{file}\" alt=\"{alt}\"></p>");
        } else {
            let _ = writeln!(s, "![{alt}]({file})\n");
        }
    };
    let _ = writeln!(s, "\n## Plots and images\n");
    img(&mut s, "error_vs_time.png", "error against time");
    img(&mut s, "psnr_vs_order.png", "PSNR against order");
    img(&mut s, "roi_vs_order.png", "ROI against order");
    img(
        &mut s,
        "images.png",
        "reference, relit images, error images and ROI",
    );
    s
}

fn html(d: &ReportData) -> String {
    // The Markdown tables rendered as HTML by a tiny converter (pipes → cells), images inline.
    let md = markdown(d, true);
    let mut out = String::from("<!doctype html><html><head><meta charset=\"utf-8\"><title>prt report</title><style>body{font-family:sans-serif;max-width:1100px;margin:2em auto}table{border-collapse:collapse}td,th{border:1px solid #ccc;padding:3px 8px;text-align:right}img{max-width:100%}</style></head><body>\n");
    let mut in_table = false;
    for line in md.lines() {
        if line.starts_with('|') {
            if line.contains("---") {
                continue;
            }
            let cells: Vec<&str> = line.trim_matches('|').split('|').map(str::trim).collect();
            if !in_table {
                out.push_str("<table><tr>");
                for c in &cells {
                    let _ = write!(out, "<th>{}</th>", escape(c));
                }
                out.push_str("</tr>\n");
                in_table = true;
            } else {
                out.push_str("<tr>");
                for c in &cells {
                    let _ = write!(out, "<td>{}</td>", escape(c));
                }
                out.push_str("</tr>\n");
            }
            continue;
        }
        if in_table {
            out.push_str("</table>\n");
            in_table = false;
        }
        if let Some(t) = line.strip_prefix("## ") {
            let _ = writeln!(out, "<h2>{}</h2>", escape(t));
        } else if let Some(t) = line.strip_prefix("# ") {
            let _ = writeln!(out, "<h1>{}</h1>", escape(t));
        } else if line.starts_with("<p><img") {
            out.push_str(line);
            out.push('\n');
        } else if let Some(t) = line.strip_prefix("    ") {
            let _ = writeln!(out, "<pre>{}</pre>", escape(t));
        } else if let Some(t) = line.strip_prefix("- ") {
            let _ = writeln!(out, "<li>{}</li>", escape(t));
        } else if !line.is_empty() {
            let _ = writeln!(out, "<p>{}</p>", escape(line));
        }
    }
    if in_table {
        out.push_str("</table>\n");
    }
    out.push_str("</body></html>\n");
    out
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('`', "")
}

/// Where a report's bake cache lives.
#[must_use]
pub fn cache_dir(out_dir: &Path) -> PathBuf {
    out_dir.join("cache")
}
