//! The report's reflectance-field section (`prt report --reflectance WxH`; Masselus, Peers,
//! Dutré & Willems, EGSR 2004): the scene's reflectance field sampled at `W × H` lat-long
//! directions ([`prt_fields::sample`], cached like the bakes), then
//!
//! - relit with every reconstruction of [`Reconstruction`] and compared with the path-traced
//!   reference (PSNR of the 8-bit view and relative L2 on object pixels, shading time);
//! - compressed with each wavelet (Haar, LeGall 5/3, CDF 9/7) to `K` coefficients per pixel and
//!   channel for every `K` asked, relit, and set beside per-pixel spherical harmonics with
//!   the same number of coefficients (order `⌊√K⌋`, a per-pixel bake with the same footprint
//!   samples), against the same reference;
//! - the compressed functions' own error against coefficient count (relative L2 and Sobolev H¹,
//!   the paper's Fig. 9) for `K = 16, 32, …` up to the fine grid, over an even subsample of the
//!   held pixels;
//! - relit over a map turned a little each frame, to measure each reconstruction's
//!   frame-to-frame flicker ([`flicker`]: the paper's argument for smooth reconstructions).
//!
//! It writes tables (in `report.md`, `report.json` under `reflectance`), three plots and an
//! image grid with one tile per method, and adds every relit image to the page's viewer.

use crate::error::ReportError;
use crate::plots::{image_grid, line_chart, ChartOptions, Series, Tile};
use crate::viewer::ViewerImage;
use plotters::style::RGBColor;
use prt_bake::{BakeSettings, PointKind};
use prt_bakefile::{Bake, ReflectanceField};
use prt_compare::{compare, Image, Mask};
use prt_fields::relight::{
    check_field, fine_lighting, flicker, relight_field_frames, relight_field_series, wavelet_name,
    FieldOptions, Reconstruction,
};
use prt_fields::sample::ReflectanceSettings;
use prt_scene::Scene;
use prt_scene_relight::imaging::RgbImage;
use prt_scene_relight::io::{write_exr, write_png};
use prt_scene_relight::relit::RelightOptions;
use prt_tracer::Accel;
use prt_wavelet::Wavelet;
use serde::Serialize;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

pub use prt_fields::RECONSTRUCTIONS;

/// The three wavelets of the compression tables.
pub const WAVELETS: [Wavelet; 3] = [Wavelet::Haar, Wavelet::LeGall53, Wavelet::Cdf97];

/// Settings of the section.
#[derive(Clone, Debug)]
pub struct RfSettings {
    /// Sampled directions `[W, H]`.
    pub directions: [u32; 2],
    /// Fine grid the functions are reconstructed on (`[256, 128]` by default).
    pub fine: [u32; 2],
    /// Coefficient counts of the compressed relightings (per pixel and channel); each is
    /// compared with per-pixel SH of order `⌊√K⌋`.
    pub coefficients: Vec<usize>,
    /// The reconstruction the compressed functions start from.
    pub compress_from: Reconstruction,
    /// Frames of the flicker measurement (at least 3).
    pub frames: usize,
    /// Rotation of the map about +Y between frames, degrees.
    pub rotate_step_deg: f64,
    /// Footprint samples per pixel of the field and of the per-pixel SH bake.
    pub pixel_samples: u32,
    /// The compressed functions' errors are measured over at most this many held pixels
    /// (an even subsample; every one when there are fewer).
    pub error_pixels: usize,
    /// Frames timed per field relighting (the median is reported).
    pub timing_frames: usize,
}

impl Default for RfSettings {
    fn default() -> Self {
        Self {
            directions: [64, 32],
            fine: [256, 128],
            coefficients: vec![64, 256],
            compress_from: Reconstruction::Linear,
            frames: 8,
            rotate_step_deg: 0.5,
            pixel_samples: 16,
            error_pixels: 2048,
            timing_frames: 5,
        }
    }
}

/// What the report's other parts give the section.
pub struct RfContext<'a> {
    /// The scene, its file and its BVH.
    pub scene: &'a Scene,
    /// Its BVH.
    pub accel: &'a Accel,
    /// The report's directory (images in `images/`, the cache in `cache/`).
    pub out_dir: &'a Path,
    /// The path-traced reference.
    pub reference: &'a Image,
    /// Object pixels.
    pub mask: &'a Mask,
    /// Its noise ceiling (psnr_ldr on object pixels).
    pub reference_noise_psnr: f64,
    /// Bounces, rays per path sample and seed of the report.
    pub bounces: u32,
    /// Paths per footprint sample for bounces (the report's `--rays`).
    pub rays: u32,
    /// Seed.
    pub seed: u64,
    /// Frames timed per SH relighting.
    pub sh_timing_frames: usize,
    /// Progress messages on stderr.
    pub progress: bool,
}

/// One reconstruction, relit uncompressed.
#[derive(Clone, Debug, Serialize)]
pub struct RfMethodRow {
    /// `--reconstruct` name.
    pub method: Reconstruction,
    /// Shading time of a frame (median), ms: pulling the lighting back and every pixel's dot
    /// products.
    pub shade_ms: f64,
    /// The lighting's projection onto the fine grid, ms (once per frame, any method).
    pub lighting_ms: f64,
    /// psnr_ldr against the path tracer, object pixels.
    pub psnr_ldr: f64,
    /// Relative L2 against the path tracer, object pixels.
    pub rel_l2: f64,
    /// Relative error of the object pixels' mean radiance.
    pub mean_error: f64,
    /// Frame-to-frame flicker under the rotating map ([`flicker`]).
    pub flicker: Option<f64>,
}

/// One wavelet at one coefficient count.
#[derive(Clone, Debug, Serialize)]
pub struct RfCompressedRow {
    /// `--wavelet` name.
    pub wavelet: String,
    /// Coefficients kept per pixel and channel.
    pub coefficients: usize,
    /// Mean coefficients kept (fewer where a function has fewer non-zero ones).
    pub mean_coefficients: f64,
    /// Shading time of a frame (median), ms.
    pub shade_ms: f64,
    /// psnr_ldr against the path tracer, object pixels.
    pub psnr_ldr: f64,
    /// Relative L2 against the path tracer, object pixels.
    pub rel_l2: f64,
    /// The compressed functions' relative L2 error against their uncompressed reconstruction.
    pub rf_rel_l2: f64,
    /// The same in the Sobolev H¹ norm.
    pub rf_rel_h1: f64,
}

/// Per-pixel SH with about as many coefficients.
#[derive(Clone, Debug, Serialize)]
pub struct RfShRow {
    /// Order (bands).
    pub order: usize,
    /// Coefficients per channel (`order²`).
    pub coefficients: usize,
    /// Shading time of a frame (median), ms.
    pub shade_ms: f64,
    /// psnr_ldr against the path tracer, object pixels.
    pub psnr_ldr: f64,
    /// Relative L2 against the path tracer, object pixels.
    pub rel_l2: f64,
}

/// One point of the compression error against coefficient count.
#[derive(Clone, Debug, Serialize)]
pub struct RfErrorPoint {
    /// `--wavelet` name.
    pub wavelet: String,
    /// Coefficients kept per function.
    pub coefficients: usize,
    /// Relative L2 error of the compressed functions.
    pub rf_rel_l2: f64,
    /// Relative Sobolev H¹ error.
    pub rf_rel_h1: f64,
}

/// The section's measurements (`report.json`: `reflectance`).
#[derive(Clone, Debug, Serialize)]
pub struct RfSection {
    /// Sampled directions.
    pub directions: [u32; 2],
    /// Fine grid.
    pub fine: [u32; 2],
    /// Footprint samples per pixel.
    pub pixel_samples: u32,
    /// Bounces of the field.
    pub bounces: u32,
    /// The field's file (in the cache).
    pub field_file: String,
    /// Its size, bytes.
    pub field_bytes: u64,
    /// Pixels holding a function.
    pub field_pixels: usize,
    /// Sampling time, s (0 when reused from the cache).
    pub field_seconds: f64,
    /// Whether the field came from the cache.
    pub field_cached: bool,
    /// Share of the map's energy (luminance × solid angle) in its brightest 1 % of solid
    /// angle (on the fine grid): near 1 % for a uniform sky, far more with a sun.
    pub brightest_share: f64,
    /// The reconstruction the compressed rows start from.
    pub compress_from: Reconstruction,
    /// Uncompressed reconstructions.
    pub reconstructions: Vec<RfMethodRow>,
    /// Compressed relightings.
    pub compressed: Vec<RfCompressedRow>,
    /// Per-pixel SH at the same coefficient counts (a per-pixel bake: its Monte Carlo noise
    /// included).
    pub sh: Vec<RfShRow>,
    /// Rays per pixel of that bake.
    pub sh_bake_rays: u32,
    /// SH of the same orders fitted (least squares) to the field's own samples: the basis
    /// alone, without bake noise (shaded through the samples, so its time is the field's).
    pub sh_fit: Vec<RfShRow>,
    /// The per-pixel SH bake (in the cache).
    pub sh_bake_file: String,
    /// Compression error against coefficient count.
    pub error_curve: Vec<RfErrorPoint>,
    /// Held pixels the compression errors were measured over.
    pub error_pixels: usize,
    /// Time to reconstruct, transform and rank every function once per wavelet, ms.
    pub compress_ms: Vec<(String, f64)>,
    /// What the section left out, and why.
    pub notes: Vec<String>,
    /// Frames and rotation step of the flicker measurement.
    pub flicker_frames: usize,
    /// Degrees per frame.
    pub flicker_step_deg: f64,
    /// Peak resident memory of the report process after the section, bytes (Linux `VmHWM`;
    /// the whole report's, the section included).
    pub peak_rss_bytes: Option<u64>,
}

/// What the section adds to the page: the viewer's images.
pub struct RfOutput {
    /// Measurements.
    pub section: RfSection,
    /// Relit images for the page's viewer.
    pub viewer_images: Vec<ViewerImage>,
}

/// Cache key of a field: the scene's, the camera and the sampling settings.
fn field_key(scene_key: u64, scene: &Scene, s: &ReflectanceSettings) -> u64 {
    crate::cache::fnv(
        format!(
            "field {:?} {:?} {} {} {} {}",
            scene.camera, s.directions, s.bounces, s.rays, s.pixel_samples, s.seed
        )
        .as_bytes(),
        scene_key,
    )
}

/// Peak resident set size of this process (`VmHWM`), Linux only.
#[must_use]
pub fn peak_rss_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

/// The brightest 1 % of solid angle's share of the energy, from the fine grid's `L̄ Δω`.
fn brightest_share(lighting: &[[f64; 3]], fine: [u32; 2]) -> f64 {
    let [w, h] = fine;
    let lum = |l: &[f64; 3]| 0.2126 * l[0] + 0.7152 * l[1] + 0.0722 * l[2];
    let cells: Vec<(f64, f64)> = lighting
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let row = k / w as usize;
            let (t0, t1) = (
                std::f64::consts::PI * row as f64 / f64::from(h),
                std::f64::consts::PI * (row + 1) as f64 / f64::from(h),
            );
            let dw = 2.0 * std::f64::consts::PI / f64::from(w) * (t0.cos() - t1.cos());
            // (energy, solid angle); radiance = energy / solid angle.
            (lum(l), dw)
        })
        .collect();
    let total: f64 = cells.iter().map(|c| c.0).sum();
    if total <= 0.0 {
        return 0.0;
    }
    let mut sorted = cells;
    sorted.sort_by(|a, b| (b.0 / b.1).total_cmp(&(a.0 / a.1)));
    let budget = 0.01 * 4.0 * std::f64::consts::PI;
    let (mut area, mut energy) = (0.0, 0.0);
    for (e, dw) in sorted {
        if area + dw > budget {
            energy += e * (budget - area) / dw;
            break;
        }
        area += dw;
        energy += e;
    }
    energy / total
}

/// Runs the section.
///
/// # Errors
/// Impossible settings (a grid too small for a method, `K` beyond the fine grid, fewer than 3
/// flicker frames), and everything sampling, baking and relighting can fail with.
pub fn run_section(
    cx: &RfContext<'_>,
    scene_key: u64,
    s: &RfSettings,
) -> Result<RfOutput, ReportError> {
    check_settings(s)?;
    let fine_cells = s.fine[0] as usize * s.fine[1] as usize;
    // 1. The field (cached).
    let (bake, field_path, field_seconds, field_cached) = cached_field(cx, scene_key, s)?;
    let field = check_field(cx.scene, &bake, &field_path)?;
    let field_bytes = std::fs::metadata(&field_path).map(|m| m.len()).unwrap_or(0);
    let mut sec = Section {
        cx,
        s,
        bake: &bake,
        field,
        tiles: vec![crate::plots::srgb_tile(
            cx.reference,
            "path traced (reference)".into(),
        )],
        viewer_images: Vec::new(),
    };
    // 2. Every reconstruction, uncompressed, over the rotating map.
    let reconstructions = sec.reconstructions()?;
    // 3. Each wavelet at every K, from one ranking per wavelet.
    let mut ks = s.coefficients.clone();
    ks.sort_unstable();
    ks.dedup();
    let error_stride = field.pixels.len().div_ceil(s.error_pixels.max(1)).max(1);
    let opt = FieldOptions {
        reconstruction: s.compress_from,
        fine: s.fine,
        rotate_y_deg: 0.0,
        timing_frames: s.timing_frames,
        compression: None,
    };
    let compressed = sec.compressed(&ks, &opt, error_stride)?;
    // 4. The compression error against K (the paper's Fig. 9), over the same pixels only.
    let error_curve = sec.error_curve(&opt, error_stride, fine_cells)?;
    // 5. Per-pixel SH with the same coefficient counts (one bake at the highest order), and
    // 5b. SH of the same orders fitted to the field's samples.
    let orders = sh_orders(&ks);
    let (sh, sh_path) = sec.per_pixel_sh(&orders)?;
    let (sh_fit, notes) = sec.sh_fit(&orders)?;
    // 6. Plots and the image grid.
    error_charts(cx.out_dir, &error_curve)?;
    psnr_chart(cx, &reconstructions, &compressed.rows, &sh_fit, &sh)?;
    image_grid(&cx.out_dir.join("rf_images.png"), &sec.tiles, 4, 240)?;
    Ok(RfOutput {
        section: RfSection {
            directions: s.directions,
            fine: s.fine,
            pixel_samples: s.pixel_samples,
            bounces: cx.bounces,
            field_file: field_path.display().to_string(),
            field_bytes,
            field_pixels: field.pixels.len(),
            field_seconds,
            field_cached,
            brightest_share: brightest_share(&fine_lighting(cx.scene, s.fine, 0.0), s.fine),
            compress_from: s.compress_from,
            reconstructions,
            compressed: compressed.rows,
            sh,
            sh_bake_rays: cx.rays,
            notes,
            sh_fit,
            sh_bake_file: sh_path.display().to_string(),
            error_curve,
            error_pixels: compressed.error_pixels,
            compress_ms: compressed.compress_ms,
            flicker_frames: s.frames,
            flicker_step_deg: s.rotate_step_deg,
            peak_rss_bytes: peak_rss_bytes(),
        },
        viewer_images: sec.viewer_images,
    })
}

/// Refuses settings the section cannot run with.
fn check_settings(s: &RfSettings) -> Result<(), ReportError> {
    if s.frames < 3 {
        return Err(ReportError::Invalid(
            "--rf-frames: the flicker measure needs at least 3 frames".into(),
        ));
    }
    let fine_cells = s.fine[0] as usize * s.fine[1] as usize;
    if s.coefficients.is_empty() || s.coefficients.iter().any(|&k| k == 0 || k > fine_cells) {
        return Err(ReportError::Invalid(format!(
            "--rf-coefficients: give between 1 and the fine grid's {fine_cells} coefficients"
        )));
    }
    if s.coefficients
        .iter()
        .any(|&k| (k as f64).sqrt() as usize > 32)
    {
        return Err(ReportError::Invalid(
            "--rf-coefficients: at most 1024 (per-pixel SH beside it stops at order 32)".into(),
        ));
    }
    Ok(())
}

/// The field, read from the cache when it is there and matches the scene, else sampled and
/// written there (f16: half the memory and file; its rounding, 2⁻¹¹ relative, is far below
/// every error measured here); with its file, the sampling time (0 from the cache) and
/// whether it came from the cache.
fn cached_field(
    cx: &RfContext<'_>,
    scene_key: u64,
    s: &RfSettings,
) -> Result<(Bake, PathBuf, f64, bool), ReportError> {
    let scene = cx.scene;
    let rs = ReflectanceSettings {
        directions: s.directions,
        bounces: cx.bounces,
        rays: cx.rays,
        pixel_samples: s.pixel_samples,
        seed: cx.seed,
        progress: cx.progress,
        scalar: prt_bakefile::ScalarType::F16,
    };
    let field_path = cx.out_dir.join("cache").join(format!(
        "field-{:016x}.prtb",
        field_key(scene_key, scene, &rs)
    ));
    let cached = prt_bakefile::read_bake(&field_path)
        .ok()
        .filter(|b| check_field(scene, b, &field_path).is_ok());
    if let Some(b) = cached {
        say(
            cx,
            &format!("reusing the cached field {}", field_path.display()),
        );
        return Ok((b, field_path, 0.0, true));
    }
    say(cx, &format!(
        "sampling the reflectance field: {}×{} directions, {} footprint samples per pixel, {} bounce(s)",
        s.directions[0], s.directions[1], s.pixel_samples, cx.bounces
    ));
    let t = Instant::now();
    let (field, scalar) = sample_field(cx, &rs)?;
    let seconds = t.elapsed().as_secs_f64();
    let bake = prt_fields::sample::field_bake(scene, field, &rs);
    // Held in the file's precision already: relit from exactly what the file holds, as a
    // later run from the cache and `prt relight` by hand are.
    prt_bakefile::write_bake(&field_path, &bake, scalar)?;
    Ok((bake, field_path, seconds, false))
}

/// Samples the field in f16 (half the memory and file), or again in f32 when a value is
/// beyond f16's range (65504 per sr, near-delta lobes only); with the precision it took.
fn sample_field(
    cx: &RfContext<'_>,
    rs: &ReflectanceSettings,
) -> Result<(ReflectanceField, prt_bakefile::ScalarType), ReportError> {
    let (field, _, scalar) = match prt_fields::sample::sample_field(cx.scene, cx.accel, rs) {
        Err(prt_fields::FieldError::File(prt_bakefile::BakeFileError::OutOfF16Range {
            ..
        })) => {
            let rs32 = ReflectanceSettings {
                scalar: prt_bakefile::ScalarType::F32,
                ..rs.clone()
            };
            let (f, st) = prt_fields::sample::sample_field(cx.scene, cx.accel, &rs32)?;
            (f, st, prt_bakefile::ScalarType::F32)
        }
        r => {
            let (f, st) = r?;
            (f, st, prt_bakefile::ScalarType::F16)
        }
    };
    Ok((field, scalar))
}

/// A progress message on stderr (when the report shows progress).
fn say(cx: &RfContext<'_>, m: &str) {
    if cx.progress {
        eprintln!("report: {m}");
    }
}

/// What the section's steps share: the report's context, the settings, the field, and the
/// image grid's tiles and the viewer's images they add to.
struct Section<'a> {
    cx: &'a RfContext<'a>,
    s: &'a RfSettings,
    /// The field's bake (its file's contents).
    bake: &'a Bake,
    /// The field in it.
    field: &'a ReflectanceField,
    /// The image grid: the reference first.
    tiles: Vec<Tile>,
    /// Every relit image, for the page's viewer.
    viewer_images: Vec<ViewerImage>,
}

/// The section's compressed relightings.
struct Compressed {
    /// Per wavelet and `K`.
    rows: Vec<RfCompressedRow>,
    /// Per wavelet, the time to reconstruct, transform and rank every function once, ms.
    compress_ms: Vec<(String, f64)>,
    /// Held pixels the compression errors were measured over.
    error_pixels: usize,
}

impl Section<'_> {
    fn say(&self, m: &str) {
        say(self.cx, m);
    }

    /// psnr_ldr and relative L2 against the path tracer on object pixels, and the relative
    /// error of the object pixels' mean radiance.
    fn measure(&self, img: &RgbImage) -> Result<(f64, f64, f64), ReportError> {
        let cx = self.cx;
        let ci = img;
        let m = compare(ci, cx.reference, Some(cx.mask))?
            .masked
            .expect("mask given");
        let (mut a, mut r) = (0.0f64, 0.0f64);
        for ((p, q), &on) in ci
            .pixels
            .iter()
            .zip(&cx.reference.pixels)
            .zip(cx.mask.as_slice())
        {
            if on {
                a += p.iter().map(|v| f64::from(*v)).sum::<f64>();
                r += q.iter().map(|v| f64::from(*v)).sum::<f64>();
            }
        }
        Ok((
            m.psnr_ldr,
            m.rel_l2,
            if r > 0.0 { a / r - 1.0 } else { 0.0 },
        ))
    }

    /// Writes `images/NAME.exr` and `images/NAME.png`.
    fn save(&self, name: &str, img: &RgbImage, kind: &str) -> Result<(), ReportError> {
        let out_dir = self.cx.out_dir;
        write_exr(
            &out_dir.join(format!("images/{name}.exr")),
            img,
            &[("kind", kind.to_string())],
        )?;
        Ok(write_png(
            &out_dir.join(format!("images/{name}.png")),
            img,
            0.0,
        )?)
    }

    /// Adds an image to the page's viewer.
    fn show(&mut self, id: String, label: String, img: &RgbImage) {
        self.viewer_images.push(ViewerImage {
            id,
            label,
            rgb: img.pixels.clone(),
        });
    }

    /// Step 2: every reconstruction, uncompressed, over the rotating map (its first frame
    /// measured and shown, all of them for the flicker).
    fn reconstructions(&mut self) -> Result<Vec<RfMethodRow>, ReportError> {
        let (cx, s) = (self.cx, self.s);
        let angles: Vec<f64> = (0..s.frames)
            .map(|k| k as f64 * s.rotate_step_deg)
            .collect();
        let mut reconstructions = Vec::new();
        for m in RECONSTRUCTIONS {
            let name = reconstruction_name(m);
            self.say(&format!("relighting the field: {name} reconstruction"));
            let opt = FieldOptions {
                reconstruction: m,
                fine: s.fine,
                rotate_y_deg: 0.0,
                timing_frames: s.timing_frames,
                compression: None,
            };
            let (frames, stats) =
                relight_field_frames(cx.scene, cx.accel, self.bake, self.field, &opt, &angles)?;
            let (psnr_ldr, rel_l2, mean_error) = self.measure(&frames[0])?;
            self.save(&format!("rf_{name}"), &frames[0], "reflectance field")?;
            self.tiles.push(crate::plots::srgb_tile(
                &frames[0],
                format!("field, {name}: {psnr_ldr:.2} dB"),
            ));
            self.show(
                format!("rf_{name}"),
                format!("reflectance field, {name} reconstruction"),
                &frames[0],
            );
            reconstructions.push(RfMethodRow {
                method: m,
                shade_ms: stats.shade_ms,
                lighting_ms: stats.lighting_ms,
                psnr_ldr,
                rel_l2,
                mean_error,
                flicker: flicker(&frames, cx.mask.as_slice()),
            });
        }
        Ok(reconstructions)
    }

    /// Step 3: each wavelet at every `K` of `ks` (sorted), from one ranking per wavelet; the
    /// compression errors over every `error_stride`-th held pixel.
    fn compressed(
        &mut self,
        ks: &[usize],
        opt: &FieldOptions,
        error_stride: usize,
    ) -> Result<Compressed, ReportError> {
        let cx = self.cx;
        let mut out = Compressed {
            rows: Vec::new(),
            compress_ms: Vec::new(),
            error_pixels: 0,
        };
        for wav in WAVELETS {
            let wname = wavelet_name(wav);
            self.say(&format!(
                "compressing the field with {wname} to {ks:?} coefficients"
            ));
            let series = relight_field_series(
                cx.scene,
                cx.accel,
                self.bake,
                self.field,
                opt,
                wav,
                ks,
                error_stride,
            )?;
            for (&k, (img, st)) in ks.iter().zip(&series) {
                let (psnr_ldr, rel_l2, _) = self.measure(img)?;
                self.save(
                    &format!("rf_{wname}_{k}"),
                    img,
                    "compressed reflectance field",
                )?;
                self.show(
                    format!("rf_{wname}_{k}"),
                    format!("reflectance field, {wname}, {k} coefficients"),
                    img,
                );
                if k == *ks.last().expect("non-empty") {
                    self.tiles.push(crate::plots::srgb_tile(
                        img,
                        format!("{wname}, K = {k}: {psnr_ldr:.2} dB"),
                    ));
                }
                out.error_pixels = st.rf_error_pixels.unwrap_or(0);
                out.rows.push(RfCompressedRow {
                    wavelet: wname.into(),
                    coefficients: k,
                    mean_coefficients: st.mean_coefficients.unwrap_or(0.0),
                    shade_ms: st.shade_ms,
                    psnr_ldr,
                    rel_l2,
                    rf_rel_l2: st.rf_rel_l2.unwrap_or(0.0),
                    rf_rel_h1: st.rf_rel_h1.unwrap_or(0.0),
                });
            }
            out.compress_ms.push((
                wname.to_string(),
                series.first().and_then(|s| s.1.compress_ms).unwrap_or(0.0),
            ));
        }
        Ok(out)
    }

    /// Step 4: the compression error against `K = 16, 32, …` up to the fine grid (at most
    /// 4096; the paper's Fig. 9), over the same pixels as step 3.
    fn error_curve(
        &self,
        opt: &FieldOptions,
        error_stride: usize,
        fine_cells: usize,
    ) -> Result<Vec<RfErrorPoint>, ReportError> {
        let curve_ks: Vec<usize> = std::iter::successors(Some(16usize), |k| Some(k * 2))
            .take_while(|&k| k <= fine_cells.min(4096))
            .collect();
        let mut error_curve = Vec::new();
        for wav in WAVELETS {
            let wname = wavelet_name(wav);
            self.say(&format!(
                "{wname}: compression error against coefficient count"
            ));
            for (k, e2, h1) in prt_fields::relight::compression_errors(
                self.field,
                opt,
                wav,
                &curve_ks,
                error_stride,
            )? {
                error_curve.push(RfErrorPoint {
                    wavelet: wname.into(),
                    coefficients: k,
                    rf_rel_l2: e2,
                    rf_rel_h1: h1,
                });
            }
        }
        Ok(error_curve)
    }

    /// Step 5: per-pixel SH at every order of `orders` (ascending), from one per-pixel bake
    /// (cached) at the highest; with the bake's file.
    fn per_pixel_sh(&mut self, orders: &[usize]) -> Result<(Vec<RfShRow>, PathBuf), ReportError> {
        let (cx, s) = (self.cx, self.s);
        let top = *orders.last().expect("non-empty");
        let bs = BakeSettings {
            order: Some(top),
            rays: cx.rays,
            bounces: cx.bounces,
            seed: cx.seed,
            points: PointKind::Pixel,
            pixel_samples: s.pixel_samples,
            progress: cx.progress,
            ..BakeSettings::final_quality()
        };
        let (sh_bake, sh_path, _) = crate::cache::cached_bake(
            cx.scene,
            cx.accel,
            cx.out_dir,
            &bs,
            "per-pixel SH bake (reflectance section)",
            cx.progress,
        )?;
        let mut sh = Vec::new();
        // Bound once: the bake's pixel footprints serve every order.
        let bound = prt_scene_relight::Bound::new(cx.scene, cx.accel, &sh_bake)?;
        for &order in orders {
            self.say(&format!("per-pixel SH at order {order}"));
            let r = bound.relight(&RelightOptions {
                order: Some(order),
                adaptive: None,
                timing_frames: cx.sh_timing_frames,
                warmup_frames: 2,
                points: None,
                ..Default::default()
            })?;
            let img = bound.form_image(&r, 0.0)?;
            let (psnr_ldr, rel_l2, _) = self.measure(&img)?;
            self.save(&format!("rf_sh_{order:02}"), &img, "per-pixel SH")?;
            self.show(
                format!("rf_sh_{order:02}"),
                format!("per-pixel SH, order {order}"),
                &img,
            );
            if order == top {
                self.tiles.insert(
                    1,
                    crate::plots::srgb_tile(
                        &img,
                        format!("per-pixel SH {order}: {psnr_ldr:.2} dB"),
                    ),
                );
            }
            sh.push(RfShRow {
                order,
                coefficients: order * order,
                shade_ms: r.stats.shade_ms,
                psnr_ldr,
                rel_l2,
            });
        }
        Ok((sh, sh_path))
    }

    /// Step 5b: SH of every order of `orders` fitted to the field's samples (where the
    /// sampled grid is fine enough; a note for the others).
    fn sh_fit(&mut self, orders: &[usize]) -> Result<(Vec<RfShRow>, Vec<String>), ReportError> {
        let (cx, s) = (self.cx, self.s);
        let top = *orders.last().expect("non-empty");
        let mut sh_fit = Vec::new();
        let mut notes = Vec::new();
        for &order in orders {
            let [dw, dh] = s.directions;
            if 2 * order > dw as usize + 1 || order > dh as usize {
                notes.push(format!(
                    "SH of order {order} cannot be fitted to {dw}×{dh} samples (it needs W ≥ 2n − 1 and H ≥ n): no fitted row"
                ));
                continue;
            }
            self.say(&format!("the field fitted with SH of order {order}"));
            let opt = FieldOptions {
                reconstruction: Reconstruction::ShFit(order),
                fine: s.fine,
                rotate_y_deg: 0.0,
                timing_frames: s.timing_frames,
                compression: None,
            };
            let (frames, stats) =
                relight_field_frames(cx.scene, cx.accel, self.bake, self.field, &opt, &[0.0])?;
            let (psnr_ldr, rel_l2, _) = self.measure(&frames[0])?;
            self.save(
                &format!("rf_sh_fit_{order:02}"),
                &frames[0],
                "SH fitted to the field",
            )?;
            self.show(
                format!("rf_sh_fit_{order:02}"),
                format!("SH order {order} fitted to the field's samples"),
                &frames[0],
            );
            if order == top {
                self.tiles.insert(
                    2,
                    crate::plots::srgb_tile(
                        &frames[0],
                        format!("SH {order} fitted to the field: {psnr_ldr:.2} dB"),
                    ),
                );
            }
            sh_fit.push(RfShRow {
                order,
                coefficients: order * order,
                shade_ms: stats.shade_ms,
                psnr_ldr,
                rel_l2,
            });
        }
        Ok((sh_fit, notes))
    }
}

/// The SH orders beside coefficient counts `ks` (ascending): `⌊√K⌋`, without repeats.
fn sh_orders(ks: &[usize]) -> Vec<usize> {
    let mut o: Vec<usize> = ks.iter().map(|&k| (k as f64).sqrt() as usize).collect();
    o.dedup();
    o
}

/// The colours of the section's charts, one per wavelet and then the per-pixel SH bake.
const COLOURS: [RGBColor; 4] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
];

/// `rf_error_vs_coefficients.png` and `rf_h1_vs_coefficients.png`: each wavelet's
/// compression error (relative L2, relative H¹) against coefficient count.
fn error_charts(out_dir: &Path, error_curve: &[RfErrorPoint]) -> Result<(), ReportError> {
    let curve = |f: fn(&RfErrorPoint) -> f64| -> Vec<Series> {
        WAVELETS
            .iter()
            .zip(COLOURS)
            .map(|(&wv, colour)| Series {
                label: wavelet_name(wv).into(),
                points: error_curve
                    .iter()
                    .filter(|p| p.wavelet == wavelet_name(wv))
                    .map(|p| (p.coefficients as f64, 100.0 * f(p)))
                    .collect(),
                colour,
            })
            .collect()
    };
    line_chart(
        &out_dir.join("rf_error_vs_coefficients.png"),
        "Compressed reflectance functions: relative L2 error",
        "coefficients per function, log scale",
        "relative L2 error against the uncompressed reconstruction (%)",
        &ChartOptions {
            log_x: true,
            ..ChartOptions::default()
        },
        &curve(|p| p.rf_rel_l2),
    )?;
    line_chart(
        &out_dir.join("rf_h1_vs_coefficients.png"),
        "Compressed reflectance functions: relative Sobolev H¹ error",
        "coefficients per function, log scale",
        "relative H¹ error (%)",
        &ChartOptions {
            log_x: true,
            ..ChartOptions::default()
        },
        &curve(|p| p.rf_rel_h1),
    )?;
    Ok(())
}

/// `rf_psnr_vs_coefficients.png`: PSNR against the path tracer per coefficient count of the
/// wavelet fields, SH fitted to the field and the per-pixel SH bake, with the reference's
/// noise ceiling and the best uncompressed reconstruction as lines.
fn psnr_chart(
    cx: &RfContext<'_>,
    reconstructions: &[RfMethodRow],
    compressed: &[RfCompressedRow],
    sh_fit: &[RfShRow],
    sh: &[RfShRow],
) -> Result<(), ReportError> {
    let mut series: Vec<Series> = WAVELETS
        .iter()
        .zip(COLOURS)
        .map(|(&wv, colour)| Series {
            label: format!("field, {} wavelet", wavelet_name(wv)),
            points: compressed
                .iter()
                .filter(|r| r.wavelet == wavelet_name(wv))
                .map(|r| (r.coefficients as f64, r.psnr_ldr))
                .collect(),
            colour,
        })
        .collect();
    series.push(Series {
        label: "SH fitted to the field's samples".into(),
        points: sh_fit
            .iter()
            .map(|r| (r.coefficients as f64, r.psnr_ldr))
            .collect(),
        colour: RGBColor(148, 103, 189),
    });
    series.push(Series {
        label: "per-pixel SH bake".into(),
        points: sh
            .iter()
            .map(|r| (r.coefficients as f64, r.psnr_ldr))
            .collect(),
        colour: COLOURS[3],
    });
    let best = reconstructions
        .iter()
        .max_by(|a, b| a.psnr_ldr.total_cmp(&b.psnr_ldr))
        .expect("eight rows");
    line_chart(
        &cx.out_dir.join("rf_psnr_vs_coefficients.png"),
        "Relit against the path tracer: wavelet fields and per-pixel SH",
        "coefficients per pixel and channel, log scale",
        "PSNR vs path-traced reference (dB, 8-bit sRGB, object pixels)",
        &ChartOptions {
            log_x: true,
            hlines: vec![
                (cx.reference_noise_psnr, "reference noise ceiling".into()),
                (
                    best.psnr_ldr,
                    format!("field uncompressed ({})", reconstruction_name(best.method)),
                ),
            ],
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &series,
    )?;
    Ok(())
}

/// The `--reconstruct` name of a reconstruction.
#[must_use]
pub fn reconstruction_name(m: Reconstruction) -> String {
    match m {
        // (A newtype variant serialises as an object, not a name.)
        Reconstruction::ShFit(order) => format!("sh_fit_{order}"),
        _ => serde_json::to_value(m)
            .ok()
            .and_then(|v| v.as_str().map(str::to_owned))
            .unwrap_or_default(),
    }
}

fn pct(v: f64) -> String {
    format!("{:.2} %", 100.0 * v)
}

/// The section in Markdown.
#[must_use]
pub fn markdown(r: &RfSection) -> String {
    let mut s = String::new();
    field_paragraph(&mut s, r);
    reconstructions_table(&mut s, r);
    compression_table(&mut s, r);
    error_curve_table(&mut s, r);
    s
}

/// The section's heading and what the field is.
fn field_paragraph(s: &mut String, r: &RfSection) {
    let _ = writeln!(s, "\n## Reflectance fields (Masselus et al. 2004)\n");
    let _ = writeln!(
        s,
        "Field: {}×{} directions, {} footprint samples per pixel, {} bounce(s); {} pixels hold a function; `{}` ({:.1} MB, {}). Functions reconstructed onto {}×{}. The map's brightest 1 % of solid angle holds {} of its energy (a uniform sky: 1 %; the sunrise map: 67 %, its sun alone 59 %). The field depends on the geometry, materials and camera only, not on the map.  ",
        r.directions[0],
        r.directions[1],
        r.pixel_samples,
        r.bounces,
        r.field_pixels,
        r.field_file,
        r.field_bytes as f64 / 1e6,
        if r.field_cached {
            "reused from the cache".to_string()
        } else {
            format!("sampled in {:.1} s", r.field_seconds)
        },
        r.fine[0],
        r.fine[1],
        pct(r.brightest_share),
    );
    if let Some(b) = r.peak_rss_bytes {
        let _ = writeln!(
            s,
            "Peak resident memory of the report so far: {:.2} GB.  ",
            b as f64 / 1e9
        );
    }
}

/// The uncompressed reconstructions against the path tracer, with their flicker.
fn reconstructions_table(s: &mut String, r: &RfSection) {
    let _ = writeln!(
        s,
        "\n### Reconstructions, uncompressed\n\nAgainst the path tracer on object pixels; flicker: relative RMS of the second difference in time over {} frames of the map turned {}° per frame (0 for steady change).\n",
        r.flicker_frames, r.flicker_step_deg
    );
    let _ = writeln!(
        s,
        "| reconstruction | shade ms | PSNR (dB) | rel. L2 | mean | flicker |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|");
    for m in &r.reconstructions {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {:.2} | {} | {:+.2} % | {} |",
            reconstruction_name(m.method),
            m.shade_ms,
            m.psnr_ldr,
            pct(m.rel_l2),
            100.0 * m.mean_error,
            m.flicker.map_or("—".into(), |f| format!("{f:.4}"))
        );
    }
}

/// Per `K`, each wavelet beside per-pixel and fitted SH with as many coefficients; then the
/// notes and the compression times.
fn compression_table(s: &mut String, r: &RfSection) {
    let _ = writeln!(
        s,
        "\n### Wavelet compression beside per-pixel SH\n\nK coefficients per pixel and channel ({} reconstruction, then the K largest by their L2 contribution); `rf_rel_l2`, `rf_rel_h1`: the compressed functions against the uncompressed ones over {} pixels. SH of order n has n² coefficients: the per-pixel SH bake ({} rays per pixel over {} footprint samples, its Monte Carlo noise included) and SH fitted by least squares to the field's own samples (the basis alone; shaded through the samples, so its time is the uncompressed field's).\n",
        reconstruction_name(r.compress_from),
        r.error_pixels,
        r.sh_bake_rays,
        r.pixel_samples
    );
    let _ = writeln!(
        s,
        "| method | coefficients | shade ms | PSNR (dB) | rel. L2 | rf_rel_l2 | rf_rel_h1 |"
    );
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---:|");
    let mut ks: Vec<usize> = r.compressed.iter().map(|c| c.coefficients).collect();
    ks.sort_unstable();
    ks.dedup();
    for k in ks {
        for c in r.compressed.iter().filter(|c| c.coefficients == k) {
            let _ = writeln!(
                s,
                "| field, {} | {} ({:.1} mean) | {:.1} | {:.2} | {} | {} | {} |",
                c.wavelet,
                c.coefficients,
                c.mean_coefficients,
                c.shade_ms,
                c.psnr_ldr,
                pct(c.rel_l2),
                pct(c.rf_rel_l2),
                pct(c.rf_rel_h1)
            );
        }
        let order = (k as f64).sqrt() as usize;
        for (label, rows) in [
            ("per-pixel SH bake", &r.sh),
            ("SH fitted to the field", &r.sh_fit),
        ] {
            if let Some(h) = rows.iter().find(|h| h.order == order) {
                let _ = writeln!(
                    s,
                    "| {label}, order {} | {} | {:.1} | {:.2} | {} | — | — |",
                    h.order,
                    h.coefficients,
                    h.shade_ms,
                    h.psnr_ldr,
                    pct(h.rel_l2)
                );
            }
        }
    }
    for n in &r.notes {
        let _ = writeln!(s, "\n- {n}");
    }
    let _ = writeln!(
        s,
        "\nCompressing (reconstruct, transform, rank once per wavelet): {}.\n",
        r.compress_ms
            .iter()
            .map(|(w, ms)| format!("{w} {:.1} s", ms / 1e3))
            .collect::<Vec<_>>()
            .join(", ")
    );
}

/// The compression error against `K`, per wavelet.
fn error_curve_table(s: &mut String, r: &RfSection) {
    let _ = writeln!(
        s,
        "### Compression error against coefficient count (the paper's Fig. 9)\n\nOver {} pixels' functions; relative L2 / relative Sobolev H¹.\n",
        r.error_pixels
    );
    let mut ks: Vec<usize> = r.error_curve.iter().map(|c| c.coefficients).collect();
    ks.sort_unstable();
    ks.dedup();
    let _ = writeln!(
        s,
        "| wavelet | {} |",
        ks.iter()
            .map(|k| format!("K = {k}"))
            .collect::<Vec<_>>()
            .join(" | ")
    );
    let _ = writeln!(s, "|---|{}", "---:|".repeat(ks.len()));
    for wv in WAVELETS {
        let name = wavelet_name(wv);
        let cells: Vec<String> = ks
            .iter()
            .map(|&k| {
                r.error_curve
                    .iter()
                    .find(|p| p.wavelet == name && p.coefficients == k)
                    .map_or("—".into(), |p| {
                        format!("{} / {}", pct(p.rf_rel_l2), pct(p.rf_rel_h1))
                    })
            })
            .collect();
        let _ = writeln!(s, "| {name} | {} |", cells.join(" | "));
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn refusal(s: &RfSettings) -> String {
        match check_settings(s) {
            Err(ReportError::Invalid(m)) => m,
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    #[test]
    fn impossible_section_settings_are_refused() {
        assert!(check_settings(&RfSettings::default()).is_ok());
        let s = RfSettings {
            frames: 2,
            ..RfSettings::default()
        };
        assert!(refusal(&s).starts_with("--rf-frames"));
        // The fine grid of 8×4 holds 32 coefficients per function.
        for coefficients in [vec![], vec![0], vec![33]] {
            let s = RfSettings {
                fine: [8, 4],
                coefficients,
                ..RfSettings::default()
            };
            assert_eq!(
                refusal(&s),
                "--rf-coefficients: give between 1 and the fine grid's 32 coefficients"
            );
        }
        // √1089 = 33: beyond the per-pixel SH beside it.
        let s = RfSettings {
            coefficients: vec![1024, 1089],
            ..RfSettings::default()
        };
        assert!(refusal(&s).contains("at most 1024"));
    }

    #[test]
    fn sh_beside_k_coefficients_has_order_floor_sqrt_k() {
        assert_eq!(sh_orders(&[16, 17, 24, 25, 64]), [4, 5, 8]);
        assert_eq!(sh_orders(&[1]), [1]);
    }
}
