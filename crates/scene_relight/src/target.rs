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
//!
//! **Choosing a representation** ([`choose_representation`], `prt relight --target-psnr P
//! --out X`): instead of a per-frame threshold, one representation for the whole run — the
//! lowest uniform order that reaches `P` against full order at every rotation, or the adaptive
//! scheme at a threshold that does, whichever has the lower [`modelled_products`] (a compressed
//! bake's uniform orders are relit from its clustered-PCA blocks, at their own cost); measured
//! on the images themselves, not estimated from a probe.

use crate::bound::Bound;
use crate::error::SceneRelightError;
use crate::imaging::{background_radiance, pixel_samples, RgbImage};
use crate::relit::{RelightOptions, Relit};
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
    check_options(bake, opt)?;
    let probe = build_probe(scene, accel, opt.probe_pixels, opt.seed)?;
    let target_mse = 255.0f64 * 255.0 * 10f64.powf(-opt.target_psnr / 10.0);
    let bound = Bound::new(scene, accel, bake)?;
    let run = TargetRun {
        scene,
        bake,
        bound: &bound,
        opt,
        probe: &probe,
        target_mse,
        aim_mse: target_mse * 10f64.powf(-0.1),
    };
    let mut t = threshold_value(&opt.adaptive);
    let mut frames = Vec::new();
    let mut full_images: Vec<FullImage> = Vec::new();
    // Frames shaded straight at full order since adaptive last had to fall back to it.
    let mut full_streak: Option<usize> = None;
    let mut last_frame = None;
    for &deg in &opt.rotations {
        // Adaptive did not pay on the last attempt: stay at full order (no probe needed, it
        // is exact) and try adaptive again every `RETRY_ADAPTIVE_EVERY` frames.
        if let Some(k) = full_streak.filter(|&k| k + 1 < RETRY_ADAPTIVE_EVERY) {
            let f = bound.relight(&run.base(deg))?;
            full_streak = Some(k + 1);
            let ms = f.stats.shade_ms;
            frames.push(TargetFrame::full_order(deg, ms, opt.verify));
            if opt.verify {
                let fi = bound.form_image(&f, deg)?;
                full_images.push((fi, ms));
            }
            last_frame = Some(f);
            continue;
        }
        let (frame, adaptive, full) = run.adaptive_frame(deg, &mut t)?;
        full_streak = (frame.threshold == 0.0).then_some(0);
        full_images.extend(full);
        frames.push(frame);
        last_frame = Some(adaptive);
    }
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
        let (baseline, baseline_speedup) = run.uniform_baseline(&full_images, full_ms)?;
        uniform = Some(baseline);
        uniform_speedup = Some(baseline_speedup);
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

/// Checks the settings of a target-quality run against the bake.
///
/// # Errors
/// A target that is not a positive, finite number of dB; a per-pixel bake; no frame or no
/// probe pixel.
fn check_options(bake: &Bake, opt: &TargetOptions) -> Result<(), SceneRelightError> {
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
    Ok(())
}

/// The median of `v` (the upper one for an even count).
fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

impl TargetFrame {
    /// A frame shaded straight at full order, in `ms` (exact: no probe, no tries).
    fn full_order(deg: f64, ms: f64, verify: bool) -> Self {
        Self {
            rotate_y_deg: deg,
            threshold: 0.0,
            tries: 0,
            psnr_estimate: f64::INFINITY,
            psnr_lower: f64::INFINITY,
            shade_ms: ms,
            probe_ms: 0.0,
            psnr_actual: verify.then_some(f64::INFINITY),
            full_ms: verify.then_some(ms),
        }
    }
}

/// `--verify`: a frame's full-order image and its shading time, ms.
type FullImage = (RgbImage, f64);

/// What every frame of a target-quality run shares.
struct TargetRun<'a> {
    scene: &'a Scene,
    bake: &'a Bake,
    /// The bake bound once: every relighting and image of the study.
    bound: &'a Bound<'a>,
    opt: &'a TargetOptions,
    probe: &'a Probe,
    /// The MSE of the target PSNR.
    target_mse: f64,
    /// The MSE a new threshold aims at: 1 dB above the target.
    aim_mse: f64,
}

/// One adaptive try of a frame, as the controller sees it.
struct Try<R> {
    /// The probe's estimate of the frame's MSE against full order, and its standard error.
    mse: f64,
    se: f64,
    /// Shading time, ms.
    shade_ms: f64,
    /// Coefficient products spent, and those full order spends (the relighter's figures).
    products: Option<u64>,
    full_order_products: Option<u64>,
    /// The frame as shaded.
    relit: R,
}

/// The frame a controller's tries ended with (see [`control`]).
struct Accepted<R> {
    /// The threshold it was accepted at (0: shaded at full order).
    threshold: f32,
    tries: usize,
    psnr_estimate: f64,
    psnr_lower: f64,
    /// Shading time of every try, plus what was spent before them, ms.
    shade_ms: f64,
    /// The frame as shaded.
    relit: R,
}

/// The controller of one frame (see the module docs): `attempt(t)` shades the frame at
/// threshold `t`, from `*t` on, accepted once the bound `MSE + 2σ` meets `target_mse`, the
/// threshold otherwise scaled by `√(aim_mse / bound)` (kept within ×0.25…×0.8); once another
/// try would take the frame's products past full order's, or after [`MAX_TRIES`], the frame is
/// shaded by `full_order()` (`(frame, ms)`) instead. `*t` is left at the last threshold tried;
/// `shade_ms` is the time already spent on the frame.
fn control<R>(
    t: &mut f32,
    target_mse: f64,
    aim_mse: f64,
    mut shade_ms: f64,
    mut attempt: impl FnMut(f32) -> Result<Try<R>, SceneRelightError>,
    full_order: impl FnOnce() -> Result<(R, f64), SceneRelightError>,
) -> Result<Accepted<R>, SceneRelightError> {
    let mut tries = 0;
    // Coefficient products spent on this frame's tries (a deterministic cost measure).
    let mut spent = 0u64;
    loop {
        tries += 1;
        let a = attempt(*t)?;
        shade_ms += a.shade_ms;
        let upper = a.mse + 2.0 * a.se;
        if upper <= target_mse {
            return Ok(Accepted {
                threshold: *t,
                tries,
                psnr_estimate: psnr(a.mse),
                psnr_lower: psnr(upper),
                shade_ms,
                relit: a.relit,
            });
        }
        // Another try costs about as much as this one: past full order's cost (in
        // coefficient products, so the decision does not depend on the machine's load),
        // or out of tries, shade the frame at full order.
        let (products, full_products) = (
            a.products.unwrap_or(0),
            a.full_order_products.unwrap_or(u64::MAX),
        );
        spent += products;
        if tries >= MAX_TRIES || spent.saturating_add(products) > full_products {
            let (f, ms) = full_order()?;
            shade_ms += ms;
            return Ok(Accepted {
                threshold: 0.0,
                tries,
                psnr_estimate: f64::INFINITY,
                psnr_lower: f64::INFINITY,
                shade_ms,
                relit: f,
            });
        }
        *t *= ((aim_mse / upper).sqrt() as f32).clamp(0.25, 0.8);
    }
}

impl TargetRun<'_> {
    /// The relighting of a frame rotated by `deg`: one timed frame at full order.
    fn base(&self, deg: f64) -> RelightOptions {
        RelightOptions {
            order: self.opt.order,
            adaptive: None,
            rotate_y_deg: deg,
            timing_frames: 1,
            warmup_frames: self.opt.warmup_frames,
            rotate_y_step_deg: 0.0,
            points: None,
            ..Default::default()
        }
    }

    /// Relights the scene with `opt`.
    fn relight(&self, opt: &RelightOptions) -> Result<Relit, SceneRelightError> {
        self.bound.relight(opt)
    }

    /// Shades frame `deg` adaptively to the target from threshold `t` (which the controller
    /// leaves where the next frame starts): the frame's figures, its radiance and, with
    /// `--verify`, its full-order image and time.
    fn adaptive_frame(
        &self,
        deg: f64,
        t: &mut f32,
    ) -> Result<(TargetFrame, Relit, Option<FullImage>), SceneRelightError> {
        let full_probe = self.relight(&RelightOptions {
            points: Some(self.probe.points.clone()),
            ..self.base(deg)
        })?;
        let probe_ms = full_probe.stats.shade_ms;
        let accepted = control(
            t,
            self.target_mse,
            self.aim_mse,
            probe_ms,
            |t| self.attempt(deg, t, &full_probe),
            || {
                let f = self.relight(&self.base(deg))?;
                let ms = f.stats.shade_ms;
                Ok((f, ms))
            },
        )?;
        let mut frame = TargetFrame {
            rotate_y_deg: deg,
            threshold: accepted.threshold,
            tries: accepted.tries,
            psnr_estimate: accepted.psnr_estimate,
            psnr_lower: accepted.psnr_lower,
            shade_ms: accepted.shade_ms,
            probe_ms,
            psnr_actual: None,
            full_ms: None,
        };
        if accepted.threshold > 0.0 && accepted.psnr_estimate > self.opt.target_psnr + 3.0 {
            *t = accepted.threshold * 1.5;
        }
        let mut full = None;
        if self.opt.verify {
            let (psnr, image, ms) = self.verify(deg, &accepted.relit)?;
            frame.psnr_actual = Some(psnr);
            frame.full_ms = Some(ms);
            full = Some((image, ms));
        }
        Ok((frame, accepted.relit, full))
    }

    /// Frame `deg` shaded adaptively at threshold `t`, with the probe's estimate of its error
    /// against `full_probe` (the probe's vertices at full order).
    fn attempt(
        &self,
        deg: f64,
        t: f32,
        full_probe: &Relit,
    ) -> Result<Try<Relit>, SceneRelightError> {
        let params = with_threshold(&self.opt.adaptive, t);
        let a = self.relight(&RelightOptions {
            adaptive: Some(params),
            ..self.base(deg)
        })?;
        let (mse, se) = estimate(
            self.scene,
            self.probe,
            &a.radiance,
            &full_probe.radiance,
            deg,
        );
        Ok(Try {
            mse,
            se,
            shade_ms: a.stats.shade_ms,
            products: a.stats.products,
            full_order_products: a.stats.full_order_products,
            relit: a,
        })
    }

    /// `--verify`: frame `deg` at full order, and the PSNR `adaptive` reaches against it:
    /// `(PSNR, full-order image, full-order time in ms)`.
    fn verify(
        &self,
        deg: f64,
        adaptive: &Relit,
    ) -> Result<(f64, RgbImage, f64), SceneRelightError> {
        let full = self.relight(&self.base(deg))?;
        let fi = self.bound.form_image(&full, deg)?;
        let ai = self.bound.form_image(adaptive, deg)?;
        let m = prt_compare::compare(&ai, &fi, None)?;
        Ok((m.whole.psnr_ldr, fi, full.stats.shade_ms))
    }

    /// `--verify`: the lowest uniform order whose every frame reaches the target against the
    /// full-order images `full_images` (median time `full_ms`), and its speedup; full order
    /// itself (speedup 1) if no lower order does.
    fn uniform_baseline(
        &self,
        full_images: &[FullImage],
        full_ms: f64,
    ) -> Result<(UniformBaseline, f64), SceneRelightError> {
        let top = self
            .bake
            .objects
            .iter()
            .map(|o| o.order as usize)
            .max()
            .unwrap_or(1);
        let top = self.opt.order.map_or(top, |o| o.min(top));
        for order in 1..top {
            let (worst, times) = self.uniform_order(order, full_images)?;
            if worst >= self.opt.target_psnr {
                let ms = median(times);
                let baseline = UniformBaseline {
                    order,
                    ms,
                    min_psnr: worst,
                };
                return Ok((baseline, full_ms / ms.max(1e-9)));
            }
        }
        let baseline = UniformBaseline {
            order: top,
            ms: full_ms,
            min_psnr: f64::INFINITY,
        };
        Ok((baseline, 1.0))
    }

    /// The frames relit uniformly at `order`, until one misses the target: the lowest PSNR
    /// against `full_images` and the shading times.
    fn uniform_order(
        &self,
        order: usize,
        full_images: &[FullImage],
    ) -> Result<(f64, Vec<f64>), SceneRelightError> {
        let mut worst = f64::INFINITY;
        let mut times = Vec::new();
        for (&deg, (fi, _)) in self.opt.rotations.iter().zip(full_images) {
            let r = self.relight(&RelightOptions {
                order: Some(order),
                ..self.base(deg)
            })?;
            let img = self.bound.form_image(&r, deg)?;
            let m = prt_compare::compare(&img, fi, None)?;
            worst = worst.min(m.whole.psnr_ldr);
            times.push(r.stats.shade_ms);
            if worst < self.opt.target_psnr {
                break;
            }
        }
        Ok((worst, times))
    }
}

/// How `prt relight --target-psnr P --out X` may shade: the representations it chooses among.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub enum Representation {
    /// Every point at this order (from the clustered-PCA blocks when the bake is compressed).
    Uniform {
        /// The order.
        order: usize,
    },
    /// Locally adaptive at the bake's order with this threshold (value in the unit of the
    /// caller's adaptive parameters).
    Adaptive {
        /// The threshold.
        threshold: f32,
    },
}

/// One representation tried by [`choose_representation`].
#[derive(Clone, Debug, Serialize)]
pub struct Candidate {
    /// Which of the bakes given it relights from (0: the first, whose full order is the
    /// reference).
    pub bake: usize,
    /// What was tried.
    pub representation: Representation,
    /// Its lowest PSNR against the reference over the rotations (the first miss ends a try).
    pub min_psnr: f64,
    /// Its modelled cost: coefficient products (and their equivalents) per frame.
    pub cost: f64,
}

/// What [`choose_representation`] chose, and why.
#[derive(Clone, Debug, Serialize)]
pub struct Choice {
    /// The cheapest candidate meeting the target on every rotation.
    pub chosen: Candidate,
    /// The cheapest uniform order meeting it over the bakes (the first bake's full order when
    /// none cheaper does).
    pub best_uniform: Candidate,
    /// Every candidate tried, in order.
    pub tried: Vec<Candidate>,
    /// Whether the chosen candidate's bake has compressed blocks (uniform orders then relight
    /// from them).
    pub compressed: bool,
    /// Median shading ms per frame of the chosen representation and of the best uniform one.
    pub shade_ms: (f64, f64),
}

/// An adaptive coefficient product costs about this many uniform ones (its filter passes,
/// scattered row reads and ROI bookkeeping; `crates/relight/README.md` measures adaptive runs
/// at 0.4–0.6 of the speed their product counts promise), so adaptive wins only if it saves
/// more than that.
pub const ADAPTIVE_PRODUCT_COST: f64 = 2.0;

/// Modelled products per frame of relighting `bake` at `order` (capped per object) without
/// the adaptive scheme: per point `3n²` diffuse and `Σ_l 3(2l+1)((l+1)² + l²)` specular
/// (Algorithm 3's count) for raw blocks; for clustered-PCA blocks `3M` diffuse and
/// `3(M+1)n² + n²` specular per point plus, per frame, `3K(M+1)n²` (diffuse) or `3K(M+1)n⁴`
/// (specular) for the clusters.
#[must_use]
pub fn modelled_products(bake: &Bake, order: Option<usize>) -> f64 {
    products_model(bake, order, true)
}

/// [`modelled_products`], with `use_cpca` false as if every block were raw (the adaptive
/// path reads the reconstructed blocks).
fn products_model(bake: &Bake, order: Option<usize>, use_cpca: bool) -> f64 {
    let mut total = 0.0;
    for o in &bake.objects {
        let n = order.map_or(o.order, |k| (k as u32).min(o.order)) as f64;
        let p = o.points_in_file as f64;
        if let Some(d) = o.diffuse_block() {
            total += match d.cpca.as_ref().filter(|_| use_cpca) {
                Some(c) => {
                    let (k, m) = (f64::from(c.clusters), f64::from(c.components));
                    p * 3.0 * m + 3.0 * k * (m + 1.0) * n * n
                }
                None => p * 3.0 * n * n,
            };
        }
        if let Some(v) = o
            .blocks
            .iter()
            .find(|b| b.kind == prt_bakefile::TransferKind::Visibility)
        {
            total += match v.cpca.as_ref().filter(|_| use_cpca) {
                Some(c) => {
                    let (k, m) = (f64::from(c.clusters), f64::from(c.components));
                    p * (3.0 * (m + 1.0) + 1.0) * n * n + 3.0 * k * (m + 1.0) * n.powi(4)
                }
                None => {
                    let per: f64 = (0..n as usize)
                        .map(|l| {
                            let l = l as f64;
                            3.0 * (2.0 * l + 1.0) * ((l + 1.0).powi(2) + l * l)
                        })
                        .sum();
                    p * per
                }
            };
        }
    }
    total
}

/// Settings of [`choose_representation`].
#[derive(Clone, Debug)]
pub struct ChooseOptions {
    /// The PSNR (dB, 8-bit view, whole image) against full order every rotation must reach.
    pub target_psnr: f64,
    /// Environment rotations the target must hold at, degrees.
    pub rotations: Vec<f64>,
    /// Relighting settings besides order, threshold and rotation (the glossy path).
    pub base: RelightOptions,
    /// The adaptive parameters; their threshold is the first one tried, then halved.
    pub adaptive: AdaptiveParams,
    /// Adaptive thresholds tried at most.
    pub adaptive_tries: usize,
}

/// `prt relight --target-psnr P --out X`: relights the first bake of `bounds` at full order
/// at every rotation (the reference); then, for each bake, tries its uniform orders from 1 up
/// until one meets the target at every rotation (the first bake's full order is the reference
/// itself; another bake's full order is tried too), and the adaptive scheme at its full order
/// from the given threshold, halved after a miss; chooses the candidate of least
/// [`modelled_products`] over all bakes (adaptive ones at their counted products ×
/// [`ADAPTIVE_PRODUCT_COST`]) — the first bake's full order if nothing cheaper meets the
/// target. Bakes of the same scene and camera but another kind of points (per vertex, per
/// pixel, per texel) or compression compete this way; their images are compared with the
/// first bake's, so it should be the most faithful one. Every decision depends on the images
/// only, never on timings; the shading times of the chosen and the best uniform representation
/// are measured afterwards.
///
/// # Errors
/// A target that is not a positive, finite number of dB, no rotation or no bake; images of
/// another size than the first bake's; the relighter's errors.
pub fn choose_representation(
    bounds: &[Bound<'_>],
    opt: &ChooseOptions,
) -> Result<Choice, SceneRelightError> {
    if !(opt.target_psnr.is_finite() && opt.target_psnr > 0.0) || opt.rotations.is_empty() {
        return Err(SceneRelightError::Invalid(format!(
            "--target-psnr {} must be a positive, finite number of dB, over at least one rotation",
            opt.target_psnr
        )));
    }
    let first = bounds
        .first()
        .ok_or_else(|| SceneRelightError::Invalid("no bake to choose from".into()))?;
    let references = opt
        .rotations
        .iter()
        .map(|&deg| {
            first.form_image(
                &first.relight(&rotated(opt, deg, opt.base.order, None))?,
                deg,
            )
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut tried = Vec::new();
    let mut best_uniform: Option<Candidate> = None;
    let mut chosen: Option<Candidate> = None;
    let cheaper =
        |c: &Candidate, than: &Option<Candidate>| than.as_ref().is_none_or(|t| c.cost < t.cost);
    for (k, bound) in bounds.iter().enumerate() {
        let (uniform, adaptive) = bake_candidates(k, bound, &references, opt, &mut tried)?;
        for c in uniform.iter().chain(&adaptive) {
            if cheaper(c, &chosen) {
                chosen = Some(c.clone());
            }
        }
        if let Some(u) = uniform.filter(|u| cheaper(u, &best_uniform)) {
            best_uniform = Some(u);
        }
    }
    let top = top_order(first.bake(), opt.base.order);
    let full = Candidate {
        bake: 0,
        representation: Representation::Uniform { order: top },
        min_psnr: f64::INFINITY,
        cost: modelled_products(first.bake(), Some(top)),
    };
    let best_uniform = best_uniform.filter(|u| u.cost < full.cost).unwrap_or(full);
    let chosen = chosen
        .filter(|c| c.cost < best_uniform.cost)
        .unwrap_or_else(|| best_uniform.clone());
    let timed = |c: &Candidate| -> Result<f64, SceneRelightError> {
        let o = chosen_options(&opt.base, &c.representation, &opt.adaptive, 0.0);
        Ok(bounds[c.bake]
            .relight(&RelightOptions {
                timing_frames: 5,
                warmup_frames: 2,
                rotate_y_step_deg: 10.0,
                ..o
            })?
            .stats
            .shade_ms)
    };
    let shade_ms = (timed(&chosen)?, timed(&best_uniform)?);
    Ok(Choice {
        compressed: bounds[chosen.bake]
            .bake()
            .objects
            .iter()
            .any(|o| o.blocks.iter().any(|b| b.cpca.is_some())),
        chosen,
        best_uniform,
        tried,
        shade_ms,
    })
}

/// The relighting options of one try: `opt.base` at `deg`, `order`, `adaptive`.
fn rotated(
    opt: &ChooseOptions,
    deg: f64,
    order: Option<usize>,
    adaptive: Option<AdaptiveParams>,
) -> RelightOptions {
    RelightOptions {
        order,
        adaptive,
        rotate_y_deg: deg,
        timing_frames: 1,
        warmup_frames: 0,
        rotate_y_step_deg: 0.0,
        points: None,
        ..opt.base.clone()
    }
}

/// The highest order relit: the bake's, capped by `order`.
fn top_order(bake: &Bake, order: Option<usize>) -> usize {
    let top = bake
        .objects
        .iter()
        .map(|o| o.order as usize)
        .max()
        .unwrap_or(1);
    order.map_or(top, |k| k.min(top))
}

/// The candidates of bake `k` (appended to `tried` as they are tried): the lowest uniform
/// order meeting the target, if any (the first bake's full order is the reference and is not
/// tried), and, for a per-vertex bake, the first adaptive threshold meeting it, if any.
fn bake_candidates(
    k: usize,
    bound: &Bound<'_>,
    references: &[crate::imaging::RgbImage],
    opt: &ChooseOptions,
    tried: &mut Vec<Candidate>,
) -> Result<(Option<Candidate>, Option<Candidate>), SceneRelightError> {
    let bake = bound.bake();
    // The lowest PSNR over the rotations, stopping at the first miss; and the products the
    // adaptive runs counted (the median over the rotations tried).
    let worst = |order: Option<usize>, adaptive: Option<AdaptiveParams>| {
        let mut w = f64::INFINITY;
        let mut ratio = Vec::new();
        for (&deg, reference) in opt.rotations.iter().zip(references) {
            let r = bound.relight(&rotated(opt, deg, order, adaptive))?;
            if let (Some(p), Some(f)) = (r.stats.products, r.stats.full_order_products) {
                ratio.push(p as f64 / (f as f64).max(1.0));
            }
            let img = bound.form_image(&r, deg)?;
            w = w.min(prt_compare::compare(&img, reference, None)?.whole.psnr_ldr);
            if w < opt.target_psnr {
                break;
            }
        }
        Ok::<_, SceneRelightError>((w, (!ratio.is_empty()).then(|| median(ratio))))
    };
    let top = top_order(bake, opt.base.order);
    let last = if k == 0 { top - 1 } else { top };
    let mut uniform = None;
    for order in 1..=last {
        let (min_psnr, _) = worst(Some(order), None)?;
        let c = Candidate {
            bake: k,
            representation: Representation::Uniform { order },
            min_psnr,
            cost: modelled_products(bake, Some(order)),
        };
        tried.push(c.clone());
        if min_psnr >= opt.target_psnr {
            uniform = Some(c);
            break;
        }
    }
    // The adaptive scheme walks the mesh's vertex adjacency: per-vertex bakes only.
    if bake.meta.sample_kind != prt_bakefile::SampleKind::Vertex {
        return Ok((uniform, None));
    }
    let raw_full_cost = products_model(bake, Some(top), false);
    let mut t = threshold_value(&opt.adaptive);
    for _ in 0..opt.adaptive_tries {
        let params = with_threshold(&opt.adaptive, t);
        let (min_psnr, ratio) = worst(Some(top), Some(params))?;
        let c = Candidate {
            bake: k,
            representation: Representation::Adaptive { threshold: t },
            min_psnr,
            cost: ratio.unwrap_or(1.0) * raw_full_cost * ADAPTIVE_PRODUCT_COST,
        };
        tried.push(c.clone());
        if min_psnr >= opt.target_psnr {
            return Ok((uniform, Some(c)));
        }
        t *= 0.5;
    }
    Ok((uniform, None))
}

/// The relighting options of representation `r` rotated by `deg` (one timed frame).
#[must_use]
pub fn chosen_options(
    base: &RelightOptions,
    r: &Representation,
    adaptive: &AdaptiveParams,
    deg: f64,
) -> RelightOptions {
    let (order, adaptive) = match r {
        Representation::Uniform { order } => (Some(*order), None),
        Representation::Adaptive { threshold } => {
            (base.order, Some(with_threshold(adaptive, *threshold)))
        }
    };
    RelightOptions {
        order,
        adaptive,
        rotate_y_deg: deg,
        timing_frames: 1,
        warmup_frames: 0,
        rotate_y_step_deg: 0.0,
        points: None,
        ..base.clone()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use prt_scene::test_util::floor_quad;
    use prt_scene::{Camera, Environment, Material};

    /// The aim of the controller: 1 dB above a target of MSE 1.
    fn aim() -> f64 {
        10f64.powf(-0.1)
    }

    /// A try whose error follows `mse(t)`, with standard error `se(mse)`, costing `products` of
    /// full order's `full` and 2 ms; its "frame" is the threshold it was shaded at.
    fn synthetic(
        mse: impl Fn(f32) -> f64,
        se: impl Fn(f64) -> f64,
        products: Option<u64>,
        full: Option<u64>,
    ) -> impl FnMut(f32) -> Result<Try<f32>, SceneRelightError> {
        move |t| {
            let m = mse(t);
            Ok(Try {
                mse: m,
                se: se(m),
                shade_ms: 2.0,
                products,
                full_order_products: full,
                relit: t,
            })
        }
    }

    fn full_order() -> Result<(f32, f64), SceneRelightError> {
        Ok((-1.0, 10.0))
    }

    #[test]
    fn the_controller_scales_the_threshold_down_the_error_curve_until_the_target_is_met() {
        // Error quadratic in the threshold, MSE = 100 t², from t = 1 against MSE 1: the bound
        // 100 asks for ×0.089, kept at ×0.25; at t = 0.25 the bound 6.25 asks for
        // ×√(aim/6.25); there the MSE is the aim itself, below the target.
        let mut t = 1.0f32;
        let curve = synthetic(
            |t| 100.0 * f64::from(t).powi(2),
            |_| 0.0,
            Some(1),
            Some(1000),
        );
        let a = control(&mut t, 1.0, aim(), 5.0, curve, full_order).unwrap();
        let third = 0.25f32 * ((aim() / 6.25).sqrt() as f32);
        assert_eq!((a.tries, a.threshold, a.relit, t), (3, third, third, third));
        let mse = 100.0 * f64::from(third).powi(2);
        assert!(mse <= 1.0 && (mse - aim()).abs() < 1e-5, "{mse}");
        assert_eq!((a.psnr_estimate, a.psnr_lower), (psnr(mse), psnr(mse)));
        assert_eq!(a.shade_ms, 5.0 + 3.0 * 2.0);
    }

    #[test]
    fn the_target_is_met_by_the_upper_bound_and_steps_are_at_most_0_8() {
        // MSE 0.5 below t = 0.85 and 1.01 above, with a standard error of 40 % of the MSE: at
        // t = 1 the bound 1.818 asks for ×0.66; at 0.66 the estimate meets the target but the
        // bound 0.9 too. A bound just past the target asks for ×0.89, kept at ×0.8.
        let mut t = 1.0f32;
        let curve = synthetic(
            |t| if t > 0.85 { 1.01 } else { 0.5 },
            |m| 0.4 * m,
            None,
            None,
        );
        let a = control(&mut t, 1.0, aim(), 0.0, curve, full_order).unwrap();
        let first_bound = 1.01 + 2.0 * (0.4 * 1.01);
        let second = ((aim() / first_bound).sqrt() as f32).clamp(0.25, 0.8);
        assert_eq!((a.tries, a.threshold), (2, second));
        assert_eq!((a.psnr_estimate, a.psnr_lower), (psnr(0.5), psnr(0.9)));
        let mut t = 1.0f32;
        let curve = synthetic(|t| if t > 0.85 { 1.01 } else { 0.5 }, |_| 0.0, None, None);
        let a = control(&mut t, 1.0, aim(), 0.0, curve, full_order).unwrap();
        assert_eq!((a.tries, a.threshold), (2, 0.8));
    }

    #[test]
    fn an_unmet_target_falls_back_to_full_order() {
        // Out of tries: the threshold quartered each time, then full order (threshold 0).
        let mut t = 1.0f32;
        let curve = synthetic(|_| 1e9, |_| 0.0, None, None);
        let a = control(&mut t, 1.0, aim(), 0.0, curve, full_order).unwrap();
        assert_eq!((a.tries, a.threshold, a.relit), (MAX_TRIES, 0.0, -1.0));
        assert_eq!(
            (a.psnr_estimate, a.psnr_lower),
            (f64::INFINITY, f64::INFINITY)
        );
        assert_eq!(a.shade_ms, 2.0 * MAX_TRIES as f64 + 10.0);
        assert_eq!(t, (0..MAX_TRIES - 1).fold(1.0f32, |t, _| t * 0.25));
        // Past full order's cost: a second try of 600 products would make 1200 of 1000.
        let mut t = 1.0f32;
        let curve = synthetic(|_| 1e9, |_| 0.0, Some(600), Some(1000));
        let a = control(&mut t, 1.0, aim(), 0.0, curve, full_order).unwrap();
        assert_eq!((a.tries, a.threshold, t), (1, 0.0, 1.0));
        let curve = synthetic(|_| 1e9, |_| 0.0, Some(400), Some(1000));
        let a = control(&mut 1.0, 1.0, aim(), 0.0, curve, full_order).unwrap();
        assert_eq!(a.tries, 2);
        // A try's error ends the frame.
        let failing = |_| Err(SceneRelightError::Invalid("no".into()));
        let e = control::<f32>(&mut 1.0, 1.0, aim(), 0.0, failing, full_order);
        assert!(e.is_err());
    }

    /// The floor seen from above, 12 × 12 pixels, under a uniform environment of 0.5.
    fn floor_scene(target: DVec3) -> (Scene, prt_tracer::Accel) {
        let mut cam = Camera::look_at(DVec3::new(0.0, 4.0, 0.0), target, 40.0, 12, 12);
        cam.up = DVec3::NEG_Z;
        let mut scene = Scene::new(cam, Environment::uniform([0.5; 3]));
        let m = scene.add_material("grey", Material::Lambert { albedo: [0.5; 3] });
        scene.add_mesh(floor_quad(1.0, 0.0), m);
        let accel = prt_tracer::Accel::build(&scene).unwrap();
        (scene, accel)
    }

    #[test]
    fn the_estimate_is_the_candidates_share_of_the_mean_error_with_its_standard_error() {
        let (scene, _) = floor_scene(DVec3::ZERO);
        // Pixel 0: one vertex, white against black (8-bit error 255 in every channel). Pixel 1:
        // half background, half a vertex equal in both images (no error).
        let probe = Probe {
            pixels: vec![
                ProbePixel {
                    terms: vec![(0, 0, 1.0)],
                    background: Vec::new(),
                    weight: 1.0,
                },
                ProbePixel {
                    terms: vec![(0, 1, 0.5)],
                    background: vec![Vec3::Y],
                    weight: 0.5,
                },
            ],
            candidates: 4,
            total: 8,
            points: vec![vec![0, 1]],
        };
        let a = [vec![[1.0f32; 3], [0.3; 3]]];
        let f = [vec![[0.0f32; 3], [0.3; 3]]];
        let (mse, se) = estimate(&scene, &probe, &a, &f, 0.0);
        // Errors e = (255², 0): mean e/2, variance e²/2, finite-population correction
        // (4 − 2)/(4 − 1); the candidates are half the image.
        let e = 255.0f64 * 255.0;
        assert_eq!(mse, 0.5 * e / 2.0);
        let want_se = 0.5 * (e * e / 2.0 / 2.0 * (2.0 / 3.0)).sqrt();
        assert!((se - want_se).abs() < 1e-9 * want_se, "{se} vs {want_se}");
        assert_eq!(estimate(&scene, &probe, &f, &f, 0.0), (0.0, 0.0));
        assert_eq!(psnr(0.0), f64::INFINITY);
        assert!((psnr(e / 100.0) - 20.0).abs() < 1e-12);
    }

    #[test]
    fn the_probe_draws_pixels_that_show_an_object_and_their_vertices() {
        let (scene, accel) = floor_scene(DVec3::ZERO);
        let probe = build_probe(&scene, &accel, 5, 7).unwrap();
        assert_eq!((probe.pixels.len(), probe.total), (5, 144));
        let mask = crate::imaging::object_mask(&scene, &accel).unwrap();
        let centres = mask.iter().filter(|&&m| m).count();
        // Candidates: every pixel any of whose sub-pixel rays hits, at least those whose
        // centre does, not the corners.
        assert!(probe.candidates >= centres && probe.candidates < 144 - 4);
        for p in &probe.pixels {
            assert!(!p.terms.is_empty());
            let sum: f32 =
                p.terms.iter().map(|t| t.2).sum::<f32>() + p.weight * p.background.len() as f32;
            assert!((sum - 1.0).abs() < 1e-5, "weights sum to {sum}");
        }
        let points = &probe.points[0];
        assert!(points.windows(2).all(|w| w[0] < w[1]) && points.iter().all(|&v| v < 4));
        // The same seed draws the same pixels.
        let again = build_probe(&scene, &accel, 5, 7).unwrap();
        assert_eq!(again.points, probe.points);
        // A camera looking away sees nothing to relight.
        let (away, accel) = floor_scene(DVec3::new(0.0, 8.0, 0.1));
        let e = build_probe(&away, &accel, 5, 7).err().unwrap().to_string();
        assert!(e.contains("no pixel shows an object"), "{e}");
    }

    #[test]
    fn settings_the_run_cannot_meet_are_refused() {
        let bake = Bake::default();
        let opt = TargetOptions {
            order: None,
            adaptive: AdaptiveParams::new(Threshold::Display {
                t: 0.02,
                exposure_ev: 1.0,
            }),
            target_psnr: 40.0,
            probe_pixels: 10,
            seed: 0,
            rotations: vec![0.0],
            warmup_frames: 0,
            verify: false,
        };
        assert!(check_options(&bake, &opt).is_ok());
        for bad in [0.0, -3.0, f64::INFINITY, f64::NAN] {
            let o = TargetOptions {
                target_psnr: bad,
                ..opt.clone()
            };
            let e = check_options(&bake, &o).unwrap_err().to_string();
            assert!(e.contains("positive, finite number of dB"), "{e}");
        }
        let none = TargetOptions {
            rotations: Vec::new(),
            ..opt.clone()
        };
        assert!(check_options(&bake, &none).is_err());
        let mut per_pixel = Bake::default();
        per_pixel.meta.sample_kind = prt_bakefile::SampleKind::Pixel {
            width: 4,
            height: 4,
        };
        let e = check_options(&per_pixel, &opt).unwrap_err().to_string();
        assert!(e.contains("needs a per-vertex bake"), "{e}");
        // The threshold keeps its kind and the other settings.
        let p = with_threshold(&opt.adaptive, 0.5);
        assert_eq!(
            p.threshold,
            Threshold::Display {
                t: 0.5,
                exposure_ev: 1.0
            }
        );
        assert_eq!((p.stop, threshold_value(&p)), (opt.adaptive.stop, 0.5));
    }
}
