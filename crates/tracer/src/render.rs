//! The renderer: images in parallel tiles, and radiance at given surface points.

use crate::accel::{point_offset, Accel, Hit};
use crate::camera::PinholeCamera;
use crate::rng::{stream, PixelKeys, Purpose, Sampler};
use crate::settings::{Mode, RenderSettings, SamplerKind};
use crate::traverse;
use crate::vertex::Vertex;
use crate::TracerError;
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
use prt_image::srgb::srgb_encode;
use prt_scene::{Material, Scene};
use prt_shading::EnvSampler;
use rayon::prelude::*;
use std::io::IsTerminal;
use std::time::Instant;

/// A scene prepared for rendering: its BVH, its environment sampler and the settings.
pub struct Renderer<'s> {
    pub(crate) scene: &'s Scene,
    pub(crate) accel: Accel,
    pub(crate) env: EnvSampler,
    pub(crate) settings: RenderSettings,
    /// Whether any mesh's material emits (glTF emission): otherwise a path's last ray only
    /// has to find out whether it escapes.
    pub(crate) emissive: bool,
}

/// A surface point given directly (e.g. a mesh vertex), for [`Renderer::radiance_at_points`].
#[derive(Clone, Debug, PartialEq)]
pub struct SurfacePoint {
    /// World position on the surface.
    pub position: Vec3,
    /// Unit shading normal (also used as the geometric normal for side checks).
    pub normal: Vec3,
    /// Unit direction towards the viewer (`ω_o`).
    pub view_dir: Vec3,
    /// The BRDF at the point.
    pub material: Material,
}

/// Per-pixel extra outputs (averages over the pixel's samples, box filter).
#[derive(Clone, Debug, Default)]
pub struct Aovs {
    /// Shading normal at the first hit, turned towards the camera (0 for background).
    pub normal: Vec<Vec3>,
    /// `albedo` of the first hit's material (0 for background).
    pub albedo: Vec<Vec3>,
    /// Distance from the eye to the first hit (0 for background).
    pub depth: Vec<f32>,
    /// Estimated variance of the pixel mean: sample variance / spp, per channel (i.i.d.
    /// samples; it over-states the error of the scrambled Sobol samples where the integrand
    /// is smooth).
    pub variance: Vec<Vec3>,
    /// `(A − B) / 2` with `A`, `B` the means of the even and odd samples (two independent
    /// replicas): its square estimates the squared error of the pixel without bias, whatever
    /// the sampler's convergence rate. Zero with an odd sample count.
    pub half_difference: Vec<Vec3>,
}

/// A rendered image with its provenance.
#[derive(Clone, Debug)]
pub struct RenderOutput {
    /// Width in pixels.
    pub width: u32,
    /// Height in pixels.
    pub height: u32,
    /// Linear RGB radiance, row-major, row 0 at the top.
    pub radiance: Vec<Vec3>,
    /// Present when [`RenderSettings::aovs`] was set.
    pub aovs: Option<Aovs>,
    /// The settings used.
    pub settings: RenderSettings,
    /// Wall-clock seconds spent rendering (BVH build excluded).
    pub seconds: f64,
    /// Samples that came out NaN or infinite and were counted as zero (should be 0).
    pub invalid_samples: u64,
    /// The image's own estimate of its relative noise on object pixels (pixels whose camera
    /// rays hit a surface at least half the time): `‖error‖ / ‖image‖` estimated from its
    /// two half images (even and odd samples). `None` with an odd sample count, no object
    /// pixel, or the single-sequence sampler ([`crate::SamplerKind::Single`], whose half
    /// images are not independent).
    pub noise: Option<f64>,
    /// The image's own estimate of its noise ceiling on the 8-bit view: the PSNR (dB, peak
    /// 255) of its sRGB view at exposure 0 against that of its expectation, over the same
    /// object pixels and from the same half images as `noise`. `None` likewise.
    pub noise_psnr_ldr: Option<f64>,
}

/// Renders `scene` with `settings`: the one-call entry point.
///
/// # Errors
/// Invalid settings, camera, meshes or material references.
pub fn render(scene: &Scene, settings: &RenderSettings) -> Result<RenderOutput, TracerError> {
    Renderer::new(scene, settings.clone())?.render()
}

/// Per-pixel running sums over the samples taken so far (in sample order, so a render
/// continued pass after pass sums exactly as one run of the same total would).
#[derive(Clone, Copy, Default)]
struct PixelSums {
    sum: DVec3,
    sum_sq: DVec3,
    /// Sum over the even-numbered samples: with the odd ones, two independent half images.
    sum_even: DVec3,
    normal: DVec3,
    albedo: DVec3,
    depth: f64,
    /// Samples whose camera ray hit a surface.
    hits: u32,
    invalid: u64,
}

/// The sums of one tile's pixels, row-major within the tile.
struct TileSums {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    pixels: Vec<PixelSums>,
}

/// First pass of a render that stops on noise or time: enough samples (an even number) for
/// both half images to estimate the noise.
pub const FIRST_PASS_SPP: u32 = 8;

/// The image's own noise estimates, from its two half images (even and odd samples).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct NoiseEstimate {
    /// Relative noise `‖error‖ / ‖image‖` of the object pixels (linear radiance).
    relative: Option<f64>,
    /// RMS error of the object pixels' 8-bit sRGB view (exposure 0), in 8-bit levels.
    ldr_rmse: Option<f64>,
}

/// One of the [`NoiseEstimate`] figures, for a stopping target.
type NoiseMeasure = fn(&NoiseEstimate) -> Option<f64>;

/// PSNR (peak 255) of an 8-bit RMS error.
fn psnr_of_rmse(rmse: f64) -> f64 {
    20.0 * (255.0 / rmse).log10()
}

/// The noise of the object pixels of an image made of `k` samples per pixel (`k` even),
/// estimated from its two half images (even and odd samples): with `A`, `B` their means,
/// `E[(A − B)²] = 4 Var(mean)`, so `Σ (A − B)² / 4` estimates the squared error of the whole
/// image without bias; on the 8-bit view the same holds to first order for
/// `(sRGB(A) − sRGB(B))² / 4` (the curve's slope carries the linear error to the display;
/// clamped channels carry none). Over pixels whose camera rays hit a surface at least half
/// the time. `None` when there is no such pixel or `k < 2`.
fn noise_estimate(tiles: &[TileSums], k: u32) -> NoiseEstimate {
    if k < 2 || !k.is_multiple_of(2) {
        return NoiseEstimate::default();
    }
    let (half, kf) = (f64::from(k / 2), f64::from(k));
    let (mut err, mut norm, mut ldr, mut count) = (0.0f64, 0.0f64, 0.0f64, 0u64);
    for p in tiles.iter().flat_map(|t| &t.pixels) {
        if 2 * p.hits < k {
            continue;
        }
        let a = p.sum_even / half;
        let b = (p.sum - p.sum_even) / half;
        err += (a - b).length_squared() / 4.0;
        norm += (p.sum / kf).length_squared();
        for c in 0..3 {
            let view = |x: f64| 255.0 * f64::from(srgb_encode((x as f32).clamp(0.0, 1.0)));
            let d = view(a[c]) - view(b[c]);
            ldr += d * d / 4.0;
        }
        count += 3;
    }
    NoiseEstimate {
        relative: (norm > 0.0).then(|| (err / norm).sqrt()),
        ldr_rmse: (count > 0).then(|| (ldr / count as f64).sqrt()),
    }
}

impl<'s> Renderer<'s> {
    /// Checks the settings and material references, builds the BVH and the environment
    /// sampler.
    ///
    /// # Errors
    /// Invalid settings, meshes or material references.
    pub fn new(scene: &'s Scene, settings: RenderSettings) -> Result<Self, TracerError> {
        let accel = Accel::build(scene)?;
        Self::with_accel(scene, accel, settings)
    }

    /// As [`Renderer::new`] with a BVH built already (from the same scene's meshes).
    ///
    /// # Errors
    /// Invalid settings or material references.
    pub fn with_accel(
        scene: &'s Scene,
        accel: Accel,
        settings: RenderSettings,
    ) -> Result<Self, TracerError> {
        settings.validate()?;
        for (mesh, m) in scene.meshes.iter().enumerate() {
            if m.material >= scene.materials.len() {
                return Err(TracerError::MissingMaterial {
                    mesh,
                    material: m.material,
                    count: scene.materials.len(),
                });
            }
        }
        let env = EnvSampler::with_sampling(&scene.environment, settings.env_sampling);
        let emissive = scene
            .meshes
            .iter()
            .any(|m| scene.surface_inputs(m.material).emits());
        Ok(Self {
            scene,
            accel,
            env,
            settings,
            emissive,
        })
    }

    /// The BVH.
    #[must_use]
    pub fn accel(&self) -> &Accel {
        &self.accel
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &RenderSettings {
        &self.settings
    }

    pub(crate) fn vertex(&self, hit: &Hit) -> Vertex {
        self.vertex_emitting(hit, self.emitted(hit))
    }

    /// [`Renderer::vertex`] with the hit's emitted radiance already looked up.
    pub(crate) fn vertex_emitting(&self, hit: &Hit, le: Vec3) -> Vertex {
        // Textures and vertex colours resolved at the hit (a copy of the material otherwise).
        let at = prt_scene::SurfacePoint::Triangle {
            tri: hit.tri,
            u: hit.u,
            v: hit.v,
        };
        let m = hit.mesh as usize;
        let mapped = self.scene.normal_mapped(m, at, hit.shading_normal);
        Vertex {
            p: hit.position,
            ng: hit.geometric_normal,
            ns: mapped.unwrap_or(hit.shading_normal),
            mapped: mapped.is_some(),
            le,
            offset: hit.offset,
            mat: self.scene.material_at(m, at),
        }
    }

    /// Radiance the surface emits at a hit (zero, after one table lookup, for surfaces
    /// without emission).
    pub(crate) fn emitted(&self, hit: &Hit) -> Vec3 {
        let at = prt_scene::SurfacePoint::Triangle {
            tri: hit.tri,
            u: hit.u,
            v: hit.v,
        };
        Vec3::from_array(self.scene.emission_at(hit.mesh as usize, at))
    }

    fn run<T: Send>(&self, job: impl FnOnce() -> T + Send) -> Result<T, TracerError> {
        match self.settings.threads {
            None => Ok(job()),
            Some(n) => {
                let pool = rayon::ThreadPoolBuilder::new()
                    .num_threads(n)
                    .build()
                    .map_err(|e| TracerError::InvalidSettings(format!("thread pool: {e}")))?;
                Ok(pool.install(job))
            }
        }
    }

    fn progress(&self, len: u64, what: &str) -> ProgressBar {
        if !(self.settings.progress && std::io::stderr().is_terminal()) {
            return ProgressBar::hidden();
        }
        let bar = ProgressBar::new(len);
        if let Ok(style) = ProgressStyle::with_template(
            "{msg} [{elapsed_precise}] {wide_bar} {pos}/{len} ({eta} left)",
        ) {
            bar.set_style(style);
        }
        bar.set_message(what.to_string());
        bar
    }

    /// Renders the scene's camera view: `spp` samples per pixel, or, with
    /// [`RenderSettings::target_noise`] or [`RenderSettings::time_budget`], passes of samples
    /// until the image's own noise estimate ([`RenderOutput::noise`]) is below the target or
    /// the next pass would not fit in the budget (`spp` is then the most it may take). A pass
    /// continues the per-pixel sample sequences, so a render that stops at `k` samples is
    /// bit-identical to a render of `k` samples; the number of passes depends only on noise
    /// estimates of the image (never on which thread did what) unless a time budget decides.
    ///
    /// # Errors
    /// An invalid camera, a thread pool that cannot be built, or a time budget shorter than
    /// the first pass.
    pub fn render(&self) -> Result<RenderOutput, TracerError> {
        let cam = PinholeCamera::new(&self.scene.camera)?;
        let (width, height) = (cam.width(), cam.height());
        let ts = self.settings.tile_size;
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(ts as usize) {
            for x0 in (0..width).step_by(ts as usize) {
                let (w, h) = (ts.min(width - x0), ts.min(height - y0));
                tiles.push(TileSums {
                    x0,
                    y0,
                    w,
                    h,
                    pixels: vec![PixelSums::default(); (w * h) as usize],
                });
            }
        }
        let max_spp = self.settings.spp;
        // The noise targets, each as (measure, target) in the units of `NoiseEstimate`.
        let targets: Vec<(NoiseMeasure, f64)> = [
            self.settings.target_noise.map(|r| {
                (
                    (|e: &NoiseEstimate| e.relative) as fn(&NoiseEstimate) -> Option<f64>,
                    r,
                )
            }),
            self.settings.target_psnr_ldr.map(|p| {
                (
                    (|e: &NoiseEstimate| e.ldr_rmse) as NoiseMeasure,
                    255.0 * 10f64.powf(-p / 20.0),
                )
            }),
        ]
        .into_iter()
        .flatten()
        .collect();
        let budget = self.settings.time_budget;
        let progressive = !targets.is_empty() || budget.is_some();
        let pixels = u64::from(width) * u64::from(height);
        let mut next = if progressive {
            FIRST_PASS_SPP.min(max_spp)
        } else {
            max_spp
        };
        let bar = self.progress(pixels * u64::from(next), "render");
        let start = Instant::now();
        let mut done = 0u32;
        let mut noise = NoiseEstimate::default();
        // (spp, noise) of the previous pass.
        let mut previous: Option<(u32, NoiseEstimate)> = None;
        loop {
            let (from, to) = (done, next);
            self.run(|| {
                tiles.par_iter_mut().for_each(|t| {
                    self.render_tile(&cam, t, from, to);
                    bar.inc(u64::from(t.w * t.h) * u64::from(to - from));
                });
            })?;
            if done > 0 {
                previous = Some((done, noise));
            }
            done = to;
            if self.settings.sampler == SamplerKind::Replicas {
                noise = noise_estimate(&tiles, done);
            }
            let elapsed = start.elapsed().as_secs_f64();
            if !progressive || done >= max_spp {
                break;
            }
            if let Some(b) = budget {
                if done == FIRST_PASS_SPP.min(max_spp) && elapsed > b {
                    bar.finish_and_clear();
                    return Err(TracerError::InvalidSettings(format!(
                        "the time budget of {b} s is too short for one pass of {done} samples per pixel (it took {elapsed:.2} s)"
                    )));
                }
            }
            // Samples still needed to reach every target (2 % more, so the last pass lands
            // just under it), at most 4× per pass while the estimate is young. Without a
            // target (budget only), double.
            let want = if targets.is_empty() {
                2 * u64::from(done)
            } else {
                let mut want = 0u64;
                let mut met = true;
                for (measure, r) in &targets {
                    let w = match measure(&noise) {
                        Some(e) if e <= *r => continue,
                        Some(e) => {
                            // Noise falls as spp^-α: α = ½ for Monte Carlo, more for the
                            // scrambled Sobol samples where the integrand is smooth;
                            // measured between the last two passes and kept within [½, ¾]
                            // so a young estimate cannot overshoot.
                            let alpha = match previous.and_then(|(k0, p)| Some((k0, measure(&p)?)))
                            {
                                Some((k0, e0)) if e0 > e => ((e0 / e).ln()
                                    / (f64::from(done) / f64::from(k0)).ln())
                                .clamp(0.5, 0.75),
                                _ => 0.5,
                            };
                            let need = f64::from(done) * (e / r).powf(1.0 / alpha) * 1.02;
                            need.min(4.0 * f64::from(done)).ceil() as u64
                        }
                        None => 4 * u64::from(done),
                    };
                    met = false;
                    want = want.max(w);
                }
                if met {
                    break;
                }
                want
            };
            // At least one more pair of samples, at most the cap (which may be odd: the last
            // pass then stops one short, keeping the sample count even for the estimate).
            let mut want = want.max(u64::from(done) + 2).min(u64::from(max_spp)) as u32;
            if let Some(b) = budget {
                let per_sample = elapsed / f64::from(done);
                let fits = ((b - elapsed) / per_sample).floor().max(0.0) as u64;
                want = want.min((u64::from(done) + fits).min(u64::from(max_spp)) as u32);
            }
            want -= want % 2;
            if want <= done {
                break;
            }
            next = want;
            bar.set_length(pixels * u64::from(next));
            if let Some(e) = noise.relative {
                let target = self.settings.target_noise;
                bar.set_message(format!(
                    "render: {done} spp, noise {:.3} %{}{}",
                    100.0 * e,
                    target.map_or(String::new(), |r| format!(" (target {:.3} %)", 100.0 * r)),
                    match (noise.ldr_rmse, self.settings.target_psnr_ldr) {
                        (Some(m), Some(p)) =>
                            format!(", ceiling {:.1} dB (target {p} dB)", psnr_of_rmse(m)),
                        _ => String::new(),
                    }
                ));
            }
        }
        let seconds = start.elapsed().as_secs_f64();
        bar.finish_and_clear();

        let n = (width * height) as usize;
        let aov = self.settings.aovs;
        let mut radiance = vec![Vec3::ZERO; n];
        let mut aovs = Aovs {
            normal: vec![Vec3::ZERO; n],
            albedo: vec![Vec3::ZERO; n],
            depth: vec![0.0; n],
            variance: vec![Vec3::ZERO; n],
            half_difference: vec![Vec3::ZERO; n],
        };
        let mut invalid_samples = 0;
        let k = f64::from(done);
        for t in &tiles {
            for ty in 0..t.h {
                for tx in 0..t.w {
                    let p = &t.pixels[(ty * t.w + tx) as usize];
                    let dst = ((t.y0 + ty) * width + t.x0 + tx) as usize;
                    invalid_samples += p.invalid;
                    radiance[dst] = (p.sum / k).as_vec3();
                    if aov {
                        aovs.normal[dst] = (p.normal / k).as_vec3();
                        aovs.albedo[dst] = (p.albedo / k).as_vec3();
                        aovs.depth[dst] = (p.depth / k) as f32;
                        let var = if done > 1 {
                            ((p.sum_sq - p.sum * p.sum / k) / (k - 1.0)).max(DVec3::ZERO) / k
                        } else {
                            DVec3::ZERO
                        };
                        aovs.variance[dst] = var.as_vec3();
                        if done >= 2 && done.is_multiple_of(2) {
                            let half = k / 2.0;
                            let (a, b) = (p.sum_even / half, (p.sum - p.sum_even) / half);
                            aovs.half_difference[dst] = ((a - b) / 2.0).as_vec3();
                        }
                    }
                }
            }
        }
        Ok(RenderOutput {
            width,
            height,
            radiance,
            aovs: aov.then_some(aovs),
            settings: RenderSettings {
                spp: done,
                ..self.settings.clone()
            },
            seconds,
            invalid_samples,
            noise: noise.relative,
            noise_psnr_ldr: noise.ldr_rmse.map(psnr_of_rmse),
        })
    }

    /// Adds samples `from..to` of every pixel of the tile to its sums. A pixel's camera rays
    /// are traced [`traverse::PACKET`] at a time ([`Accel::closest_hits`]: the same hits as
    /// one by one), then each sample's path goes on alone, in sample order.
    fn render_tile(&self, cam: &PinholeCamera, t: &mut TileSums, from: u32, to: u32) {
        let eye = cam.eye();
        let eyes = [eye; traverse::PACKET];
        let mut dirs = [Vec3::ZERO; traverse::PACKET];
        let mut hits = [None; traverse::PACKET];
        for ty in 0..t.h {
            for tx in 0..t.w {
                let (x, y) = (t.x0 + tx, t.y0 + ty);
                let pixel = u64::from(y) * u64::from(cam.width()) + u64::from(x);
                let p = &mut t.pixels[(ty * t.w + tx) as usize];
                let keys = PixelKeys::new(self.settings.seed, pixel);
                let mut first = from;
                while first < to {
                    let n = (to - first).min(traverse::PACKET as u32) as usize;
                    let mut samplers: [Sampler; traverse::PACKET] = std::array::from_fn(|i| {
                        keys.sampler_of(
                            self.settings.sampler,
                            u64::from(first) + (i as u64).min(n as u64 - 1),
                        )
                    });
                    for (s, d) in samplers.iter_mut().zip(&mut dirs).take(n) {
                        let [jx, jy] = s.next_2d();
                        *d = cam
                            .direction(f64::from(x) + f64::from(jx), f64::from(y) + f64::from(jy));
                    }
                    self.accel
                        .closest_hits(&eyes[..n], &dirs[..n], f32::INFINITY, &mut hits[..n]);
                    for (i, s) in samplers.iter_mut().enumerate().take(n) {
                        self.add_sample(p, first + i as u32, dirs[i], hits[i], s);
                    }
                    first += n as u32;
                }
            }
        }
    }

    /// One camera sample's radiance added to its pixel's sums: the path from the camera ray's
    /// hit (or the background along `dir`), with the sampler after the pixel jitter.
    fn add_sample(
        &self,
        p: &mut PixelSums,
        sample: u32,
        dir: Vec3,
        hit: Option<Hit>,
        s: &mut Sampler,
    ) {
        let mut l = match hit {
            None => self.background(dir),
            Some(hit) => {
                let v = self.vertex(&hit);
                p.hits += 1;
                if self.settings.aovs {
                    let (_, ns) = v.oriented(-dir);
                    p.normal += ns.as_dvec3();
                    p.albedo += Vec3::from_array(v.mat.albedo()).as_dvec3();
                    p.depth += f64::from(hit.t);
                }
                self.li_surface(v, -dir, s)
            }
        };
        if !l.is_finite() {
            p.invalid += 1;
            l = Vec3::ZERO;
        }
        let l = l.as_dvec3();
        p.sum += l;
        p.sum_sq += l * l;
        if sample.is_multiple_of(2) {
            p.sum_even += l;
        }
    }

    /// Radiance leaving each point towards its `view_dir` (or the AO fraction, per the mode),
    /// estimated with `spp` samples from streams `(seed, Point, point index, sample)`: the
    /// same estimator as an image pixel whose camera ray hits the point, except that a given
    /// point emits nothing (it names no mesh; emission reaching it from other surfaces is
    /// counted). The first vertex's spawn offset is [`point_offset`] since no triangle is
    /// known.
    ///
    /// # Errors
    /// When `spp` is 0, a point or direction is not finite, or the thread pool fails.
    pub fn radiance_at_points(
        &self,
        points: &[SurfacePoint],
        spp: u32,
    ) -> Result<Vec<Vec3>, TracerError> {
        if spp == 0 {
            return Err(TracerError::InvalidSettings(
                "spp must be at least 1".into(),
            ));
        }
        for (i, p) in points.iter().enumerate() {
            let ok = p.position.is_finite()
                && p.normal.is_finite()
                && p.normal.length_squared() > 0.0
                && p.view_dir.is_finite()
                && p.view_dir.length_squared() > 0.0;
            if !ok {
                return Err(TracerError::InvalidSettings(format!(
                    "point {i}: position, normal and view direction must be finite and non-zero"
                )));
            }
        }
        let max_abs = self.accel.max_abs_coordinate();
        let bar = self.progress(points.len() as u64, "points");
        let result = self.run(|| {
            points
                .par_iter()
                .enumerate()
                .map(|(i, p)| {
                    let n = p.normal.normalize();
                    let v = Vertex {
                        p: p.position,
                        ng: n,
                        ns: n,
                        mapped: false,
                        le: Vec3::ZERO,
                        offset: point_offset(p.position, max_abs),
                        mat: p.material,
                    };
                    let wo = p.view_dir.normalize();
                    let mut sum = DVec3::ZERO;
                    for sample in 0..spp {
                        let mut s = stream(
                            self.settings.seed,
                            Purpose::Point,
                            i as u64,
                            u64::from(sample),
                        );
                        let l = self.li_surface(v, wo, &mut s);
                        if l.is_finite() {
                            sum += l.as_dvec3();
                        }
                    }
                    bar.inc(1);
                    (sum / f64::from(spp)).as_vec3()
                })
                .collect()
        });
        bar.finish_and_clear();
        result
    }

    /// The mode in use.
    #[must_use]
    pub fn mode(&self) -> Mode {
        self.settings.mode
    }
}
