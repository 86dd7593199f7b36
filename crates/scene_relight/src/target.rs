//! Adaptive relighting to a quality target: `prt relight --adaptive --target-psnr P` picks the
//! adaptive threshold of every frame so that the frame's PSNR against full order (8-bit view,
//! whole image, as `psnr_ldr`) is at least `P`, without rendering full order.
//!
//! **The estimate.** Once per run, `probe_pixels` pixels are drawn from the pixels that show an
//! object (any of their image-formation sub-pixel rays hits a mesh; every other pixel is the
//! same in both images), one uniformly from each of as many runs of consecutive such pixels
//! (stratified by position, so every pixel has the same chance of being drawn). Each probe pixel is a
//! fixed linear combination of the radiance of a few vertices (the Gouraud weights of its
//! sub-pixel rays) plus its background share. Per frame those vertices alone are relit at full
//! order, so the probe pixels' exact full-order and adaptive 8-bit values are known; with `M`
//! candidate pixels of `W·H`, `(M / WH) · mean(e)` (`e` the pixel's squared 8-bit error
//! averaged over its channels) is an unbiased estimate of the image's MSE, and its standard
//! error (the simple-random-sampling formula with the finite-population correction, which
//! over-states the error of a stratified draw) gives an upper bound `+2σ`, whose PSNR must
//! reach `P`.
//!
//! **The controller.** A frame starts from the previous frame's threshold; when the bound
//! misses the target, the threshold is scaled by `√(MSE_aim / MSE_bound)` (error grows about
//! quadratically with the threshold; aiming 1 dB above the target; kept within ×0.25…×0.8)
//! and the frame relit, up to [`MAX_TRIES`] times. A frame whose tries would cost more
//! coefficient products than full order is shaded at full order instead, which meets any
//! target; the next frames are then shaded straight at full order, and adaptive is tried again
//! every [`RETRY_ADAPTIVE_EVERY`] frames. Every decision depends on the images only, never on timings, so a run is
//! reproducible. When the estimate beats the target by more than
//! 3 dB the next frame starts 1.5× higher. The cost of a frame (`shade_ms`) is the shading time
//! of every try plus that of the probe's full-order vertices.

use crate::error::SceneRelightError;
use crate::imaging::{background_radiance, pixel_samples, RgbImage};
use crate::relit::{relight, RelightOptions};
use glam::Vec3;
use prt_bakefile::Bake;
use prt_relight::{AdaptiveParams, Threshold};
use prt_scene::Scene;
use prt_tracer::PinholeCamera;
use rand::{Rng, SeedableRng};
use serde::Serialize;

/// Retries of a frame at lower thresholds before it falls back to full order.
pub const MAX_TRIES: usize = 6;

/// After a frame fell back to full order, the next frames are shaded at full order directly;
/// adaptive is tried again on every this-many-th frame.
pub const RETRY_ADAPTIVE_EVERY: usize = 4;

/// Settings of a target-quality run.
#[derive(Clone, Debug)]
pub struct TargetOptions {
    /// Order to relight at (`None`: each object's baked order).
    pub order: Option<usize>,
    /// The adaptive parameters; the threshold's value is where the first frame starts.
    pub adaptive: AdaptiveParams,
    /// PSNR (dB, 8-bit view, whole image) against full order that every frame must reach.
    pub target_psnr: f64,
    /// Probe pixels per run.
    pub probe_pixels: usize,
    /// Seed of the probe's pixel draw.
    pub seed: u64,
    /// Environment rotation of each frame, degrees.
    pub rotations: Vec<f64>,
    /// Frames shaded untimed before each timed one (see [`RelightOptions::warmup_frames`]).
    pub warmup_frames: usize,
    /// Also relight every frame at full order (and at every lower order) to measure the
    /// PSNR actually reached and the best uniform truncation that meets the target.
    pub verify: bool,
}

/// One frame of a target-quality run.
#[derive(Clone, Debug, Serialize)]
pub struct TargetFrame {
    /// Environment rotation, degrees.
    pub rotate_y_deg: f64,
    /// The threshold the frame was accepted at (0: shaded at full order).
    pub threshold: f32,
    /// Adaptive shadings the frame took.
    pub tries: usize,
    /// Estimated PSNR against full order.
    pub psnr_estimate: f64,
    /// Its 97.7 % lower bound.
    pub psnr_lower: f64,
    /// Shading time of the frame, ms: every try plus the probe.
    pub shade_ms: f64,
    /// Of which the probe's full-order vertices, ms.
    pub probe_ms: f64,
    /// `--verify`: the PSNR against full order actually reached.
    pub psnr_actual: Option<f64>,
    /// `--verify`: full-order shading time of the frame, ms.
    pub full_ms: Option<f64>,
}

/// The best uniform truncation that meets the target on every frame (`--verify`).
#[derive(Clone, Debug, Serialize)]
pub struct UniformBaseline {
    /// The lowest order whose every frame reaches the target.
    pub order: usize,
    /// Its median shading time per frame, ms.
    pub ms: f64,
    /// Its lowest PSNR against full order over the frames.
    pub min_psnr: f64,
}

/// A target-quality run.
#[derive(Clone, Debug, Serialize)]
pub struct TargetStudy {
    /// The target, dB.
    pub target_psnr: f64,
    /// Probe pixels, of the candidate (object) pixels.
    pub probe_pixels: usize,
    /// Candidate pixels.
    pub candidate_pixels: usize,
    /// Vertices the probe relights at full order each frame.
    pub probe_points: usize,
    /// Per frame.
    pub frames: Vec<TargetFrame>,
    /// Median `shade_ms`.
    pub median_shade_ms: f64,
    /// `--verify`: median full-order time over median `shade_ms`.
    pub speedup: Option<f64>,
    /// `--verify`: the lowest PSNR actually reached.
    pub min_psnr_actual: Option<f64>,
    /// `--verify`: uniform truncation at the same target.
    pub uniform: Option<UniformBaseline>,
    /// `--verify`: median full-order time over the uniform baseline's.
    pub uniform_speedup: Option<f64>,
    /// The radiance of the last frame as shaded (what a caller shows or measures).
    #[serde(skip)]
    pub last_frame: Option<crate::relit::Relit>,
}

/// One probe pixel: the vertices its value is made of and its background directions.
struct ProbePixel {
    /// `(object, vertex, weight)`.
    terms: Vec<(usize, usize, f32)>,
    /// Directions of its sub-pixel rays that miss.
    background: Vec<Vec3>,
    /// The weight of each sub-pixel ray (`1 / rays`: [`crate::imaging::pixel_samples`]).
    weight: f32,
}

/// The probe of a run: its pixels and, per object, the vertices they need.
struct Probe {
    pixels: Vec<ProbePixel>,
    candidates: usize,
    total: usize,
    points: Vec<Vec<u32>>,
}

/// `p` with its threshold's value set to `t` (same kind).
#[must_use]
pub fn with_threshold(p: &AdaptiveParams, t: f32) -> AdaptiveParams {
    let threshold = match p.threshold {
        Threshold::Absolute(_) => Threshold::Absolute(t),
        Threshold::RelativeToMean(_) => Threshold::RelativeToMean(t),
        Threshold::Display { exposure_ev, .. } => Threshold::Display { t, exposure_ev },
    };
    AdaptiveParams { threshold, ..*p }
}

fn threshold_value(p: &AdaptiveParams) -> f32 {
    match p.threshold {
        Threshold::Absolute(t) | Threshold::RelativeToMean(t) | Threshold::Display { t, .. } => t,
    }
}

fn build_probe(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    count: usize,
    seed: u64,
) -> Result<Probe, SceneRelightError> {
    let cam = PinholeCamera::new(&scene.camera)?;
    let (w, h) = (cam.width(), cam.height());
    // The pixel as image formation forms it: the same sub-pixel rays.
    let trace = |i: u32| -> ProbePixel {
        let samples = pixel_samples(&cam, accel, i % w, i / w);
        let weight = 1.0 / samples.len() as f32;
        let mut p = ProbePixel {
            terms: Vec::new(),
            background: Vec::new(),
            weight,
        };
        for (dir, hit) in samples {
            match hit {
                Some(hit) => {
                    let o = hit.mesh as usize;
                    let tri = scene.meshes[o].indices[hit.tri as usize];
                    let wts = [1.0 - hit.u - hit.v, hit.u, hit.v];
                    for (v, b) in tri.iter().zip(wts) {
                        p.terms.push((o, *v as usize, b * weight));
                    }
                }
                None => p.background.push(dir),
            }
        }
        p
    };
    let candidates: Vec<u32> = (0..w * h).filter(|&i| !trace(i).terms.is_empty()).collect();
    if candidates.is_empty() {
        return Err(SceneRelightError::Invalid(
            "no pixel shows an object: there is nothing to relight".into(),
        ));
    }
    // Stratified by image position: one pixel drawn uniformly from each of `n` runs of
    // consecutive candidates (row-major), so bright, clustered errors (highlights) are
    // covered evenly; every candidate keeps the same chance `n / M` of being drawn.
    let n = count.clamp(1, candidates.len());
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    let m = candidates.len();
    let pixels: Vec<ProbePixel> = (0..n)
        .map(|j| {
            let (lo, hi) = (j * m / n, (j + 1) * m / n);
            trace(candidates[rng.random_range(lo..hi)])
        })
        .collect();
    let mut points = vec![Vec::new(); scene.meshes.len()];
    for p in &pixels {
        for &(o, v, _) in &p.terms {
            points[o].push(v as u32);
        }
    }
    for p in &mut points {
        p.sort_unstable();
        p.dedup();
    }
    Ok(Probe {
        pixels,
        candidates: candidates.len(),
        total: (w * h) as usize,
        points,
    })
}

/// `(MSE estimate, its standard error)` of the 8-bit image of `a` against that of `f` over the
/// whole image, from the probe pixels.
fn estimate(
    scene: &Scene,
    probe: &Probe,
    a: &[Vec<[f32; 3]>],
    f: &[Vec<[f32; 3]>],
    rotate_y_deg: f64,
) -> (f64, f64) {
    let errors: Vec<f64> = probe
        .pixels
        .iter()
        .map(|p| {
            let mut bg = [0.0f32; 3];
            for d in &p.background {
                let b = background_radiance(scene, *d, rotate_y_deg);
                (0..3).for_each(|c| bg[c] += p.weight * b[c]);
            }
            let (mut va, mut vf) = (bg, bg);
            for &(o, v, w) in &p.terms {
                (0..3).for_each(|c| {
                    va[c] += w * a[o][v][c];
                    vf[c] += w * f[o][v][c];
                });
            }
            (0..3)
                .map(|c| {
                    let d = f64::from(prt_compare::ldr_value(va[c], 0.0))
                        - f64::from(prt_compare::ldr_value(vf[c], 0.0));
                    d * d
                })
                .sum::<f64>()
                / 3.0
        })
        .collect();
    let n = errors.len() as f64;
    let mean = errors.iter().sum::<f64>() / n;
    let var = if errors.len() > 1 {
        errors.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1.0)
    } else {
        0.0
    };
    let m = probe.candidates as f64;
    let fpc = if m > 1.0 {
        ((m - n) / (m - 1.0)).max(0.0)
    } else {
        0.0
    };
    let share = m / probe.total as f64;
    (share * mean, share * (var / n * fpc).sqrt())
}

fn psnr(mse: f64) -> f64 {
    if mse <= 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

/// Runs target-quality relighting over the frames of `opt` (see the module docs).
///
/// # Errors
/// A target that is not a positive, finite number of dB; a per-pixel bake; the relighter's
/// errors.
pub fn relight_to_target(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    bake: &Bake,
    opt: &TargetOptions,
) -> Result<TargetStudy, SceneRelightError> {
    if !(opt.target_psnr.is_finite() && opt.target_psnr > 0.0) {
        return Err(SceneRelightError::Invalid(format!(
            "--target-psnr {} must be a positive, finite number of dB (against full order, every frame can reach any finite target: at threshold 0 it is full order)",
            opt.target_psnr
        )));
    }
    if matches!(
        bake.meta.sample_kind,
        prt_bakefile::SampleKind::Pixel { .. }
    ) {
        return Err(SceneRelightError::Invalid(
            "--target-psnr drives adaptive relighting, which walks the mesh's vertex adjacency: it needs a per-vertex bake".into(),
        ));
    }
    if opt.rotations.is_empty() || opt.probe_pixels == 0 {
        return Err(SceneRelightError::Invalid(
            "a target-quality run needs at least one frame and one probe pixel".into(),
        ));
    }
    let probe = build_probe(scene, accel, opt.probe_pixels, opt.seed)?;
    let target_mse = 255.0f64 * 255.0 * 10f64.powf(-opt.target_psnr / 10.0);
    let aim_mse = target_mse * 10f64.powf(-0.1);
    let base = |deg: f64| RelightOptions {
        order: opt.order,
        adaptive: None,
        rotate_y_deg: deg,
        timing_frames: 1,
        warmup_frames: opt.warmup_frames,
        rotate_y_step_deg: 0.0,
        points: None,
        ..Default::default()
    };
    let mut t = threshold_value(&opt.adaptive);
    let mut frames = Vec::new();
    let mut full_images: Vec<(RgbImage, f64)> = Vec::new();
    // Frames shaded straight at full order since adaptive last had to fall back to it.
    let mut full_streak: Option<usize> = None;
    let mut last_frame = None;
    for &deg in &opt.rotations {
        // Adaptive did not pay on the last attempt: stay at full order (no probe needed, it
        // is exact) and try adaptive again every `RETRY_ADAPTIVE_EVERY` frames.
        if let Some(k) = full_streak.filter(|&k| k + 1 < RETRY_ADAPTIVE_EVERY) {
            let f = relight(scene, accel, bake, &base(deg))?;
            full_streak = Some(k + 1);
            let ms = f.stats.shade_ms;
            frames.push(TargetFrame {
                rotate_y_deg: deg,
                threshold: 0.0,
                tries: 0,
                psnr_estimate: f64::INFINITY,
                psnr_lower: f64::INFINITY,
                shade_ms: ms,
                probe_ms: 0.0,
                psnr_actual: opt.verify.then_some(f64::INFINITY),
                full_ms: opt.verify.then_some(ms),
            });
            if opt.verify {
                let fi = crate::imaging::form_image(scene, accel, &f, deg)?;
                full_images.push((fi, ms));
            }
            last_frame = Some(f);
            continue;
        }
        let full_probe = relight(
            scene,
            accel,
            bake,
            &RelightOptions {
                points: Some(probe.points.clone()),
                ..base(deg)
            },
        )?;
        let probe_ms = full_probe.stats.shade_ms;
        let mut shade_ms = probe_ms;
        let mut tries = 0;
        // Coefficient products spent on this frame's tries (a deterministic cost measure).
        let mut spent = 0u64;
        let (accepted_t, est, lower, adaptive) = loop {
            tries += 1;
            let params = with_threshold(&opt.adaptive, t);
            let a = relight(
                scene,
                accel,
                bake,
                &RelightOptions {
                    adaptive: Some(params),
                    ..base(deg)
                },
            )?;
            shade_ms += a.stats.shade_ms;
            let (mse, se) = estimate(scene, &probe, &a.radiance, &full_probe.radiance, deg);
            let upper = mse + 2.0 * se;
            if upper <= target_mse {
                break (t, psnr(mse), psnr(upper), a);
            }
            // Another try costs about as much as this one: past full order's cost (in
            // coefficient products, so the decision does not depend on the machine's load),
            // or out of tries, shade the frame at full order.
            let (products, full_products) = (
                a.stats.products.unwrap_or(0),
                a.stats.full_order_products.unwrap_or(u64::MAX),
            );
            spent += products;
            if tries >= MAX_TRIES || spent.saturating_add(products) > full_products {
                let f = relight(scene, accel, bake, &base(deg))?;
                shade_ms += f.stats.shade_ms;
                break (0.0, f64::INFINITY, f64::INFINITY, f);
            }
            t *= ((aim_mse / upper).sqrt() as f32).clamp(0.25, 0.8);
        };
        let mut frame = TargetFrame {
            rotate_y_deg: deg,
            threshold: accepted_t,
            tries,
            psnr_estimate: est,
            psnr_lower: lower,
            shade_ms,
            probe_ms,
            psnr_actual: None,
            full_ms: None,
        };
        if accepted_t > 0.0 && est > opt.target_psnr + 3.0 {
            t = accepted_t * 1.5;
        }
        full_streak = (accepted_t == 0.0).then_some(0);
        if opt.verify {
            let full = relight(scene, accel, bake, &base(deg))?;
            let fi = crate::imaging::form_image(scene, accel, &full, deg)?;
            let ai = crate::imaging::form_image(scene, accel, &adaptive, deg)?;
            let m = prt_compare::compare(
                &crate::io::to_compare_image(&ai),
                &crate::io::to_compare_image(&fi),
                None,
            )?;
            frame.psnr_actual = Some(m.whole.psnr_ldr);
            frame.full_ms = Some(full.stats.shade_ms);
            full_images.push((fi, full.stats.shade_ms));
        }
        frames.push(frame);
        last_frame = Some(adaptive);
    }
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let median_shade_ms = median(frames.iter().map(|f| f.shade_ms).collect());
    let (mut speedup, mut min_psnr_actual, mut uniform, mut uniform_speedup) =
        (None, None, None, None);
    if opt.verify {
        let full_ms = median(full_images.iter().map(|(_, ms)| *ms).collect());
        speedup = Some(full_ms / median_shade_ms.max(1e-9));
        min_psnr_actual = frames
            .iter()
            .filter_map(|f| f.psnr_actual)
            .min_by(f64::total_cmp);
        let top = bake
            .objects
            .iter()
            .map(|o| o.order as usize)
            .max()
            .unwrap_or(1);
        let top = opt.order.map_or(top, |o| o.min(top));
        for order in 1..top {
            let mut worst = f64::INFINITY;
            let mut times = Vec::new();
            for (&deg, (fi, _)) in opt.rotations.iter().zip(&full_images) {
                let r = relight(
                    scene,
                    accel,
                    bake,
                    &RelightOptions {
                        order: Some(order),
                        ..base(deg)
                    },
                )?;
                let img = crate::imaging::form_image(scene, accel, &r, deg)?;
                let m = prt_compare::compare(
                    &crate::io::to_compare_image(&img),
                    &crate::io::to_compare_image(fi),
                    None,
                )?;
                worst = worst.min(m.whole.psnr_ldr);
                times.push(r.stats.shade_ms);
                if worst < opt.target_psnr {
                    break;
                }
            }
            if worst >= opt.target_psnr {
                let ms = median(times);
                uniform_speedup = Some(full_ms / ms.max(1e-9));
                uniform = Some(UniformBaseline {
                    order,
                    ms,
                    min_psnr: worst,
                });
                break;
            }
        }
        if uniform.is_none() {
            uniform = Some(UniformBaseline {
                order: top,
                ms: full_ms,
                min_psnr: f64::INFINITY,
            });
            uniform_speedup = Some(1.0);
        }
    }
    Ok(TargetStudy {
        target_psnr: opt.target_psnr,
        probe_pixels: probe.pixels.len(),
        candidate_pixels: probe.candidates,
        probe_points: probe.points.iter().map(Vec::len).sum(),
        frames,
        median_shade_ms,
        speedup,
        min_psnr_actual,
        uniform,
        uniform_speedup,
        last_frame,
    })
}
