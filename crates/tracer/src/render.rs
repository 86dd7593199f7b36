//! The renderer: images in parallel tiles, and radiance at given surface points.

use crate::accel::{point_offset, Accel, Hit};
use crate::camera::PinholeCamera;
use crate::integrator::Vertex;
use crate::rng::{stream, Purpose};
use crate::settings::{Mode, RenderSettings};
use crate::TracerError;
use glam::{DVec3, Vec3};
use indicatif::{ProgressBar, ProgressStyle};
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
    /// Estimated variance of the pixel mean: sample variance / spp, per channel.
    pub variance: Vec<Vec3>,
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
}

/// Renders `scene` with `settings`: the one-call entry point.
///
/// # Errors
/// Invalid settings, camera, meshes or material references.
pub fn render(scene: &Scene, settings: &RenderSettings) -> Result<RenderOutput, TracerError> {
    Renderer::new(scene, settings.clone())?.render()
}

struct TileOut {
    x0: u32,
    y0: u32,
    w: u32,
    h: u32,
    radiance: Vec<Vec3>,
    aovs: Aovs,
    invalid: u64,
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
        let env = EnvSampler::new(&scene.environment);
        Ok(Self {
            scene,
            accel,
            env,
            settings,
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

    pub(crate) fn vertex(&self, hit: &Hit) -> Vertex<'s> {
        let mesh = &self.scene.meshes[hit.mesh as usize];
        Vertex {
            p: hit.position,
            ng: hit.geometric_normal,
            ns: hit.shading_normal,
            offset: hit.offset,
            mat: &self.scene.materials[mesh.material],
        }
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

    /// Renders the scene's camera view.
    ///
    /// # Errors
    /// An invalid camera, or a thread pool that cannot be built.
    pub fn render(&self) -> Result<RenderOutput, TracerError> {
        let cam = PinholeCamera::new(&self.scene.camera)?;
        let (width, height) = (cam.width(), cam.height());
        let ts = self.settings.tile_size;
        let mut tiles = Vec::new();
        for y0 in (0..height).step_by(ts as usize) {
            for x0 in (0..width).step_by(ts as usize) {
                tiles.push((x0, y0, ts.min(width - x0), ts.min(height - y0)));
            }
        }
        let bar = self.progress(tiles.len() as u64, "render");
        let start = Instant::now();
        let outs: Vec<TileOut> = self.run(|| {
            tiles
                .par_iter()
                .map(|&(x0, y0, w, h)| {
                    let t = self.render_tile(&cam, x0, y0, w, h);
                    bar.inc(1);
                    t
                })
                .collect()
        })?;
        let seconds = start.elapsed().as_secs_f64();
        bar.finish_and_clear();

        let n = (width * height) as usize;
        let mut radiance = vec![Vec3::ZERO; n];
        let mut aovs = Aovs {
            normal: vec![Vec3::ZERO; n],
            albedo: vec![Vec3::ZERO; n],
            depth: vec![0.0; n],
            variance: vec![Vec3::ZERO; n],
        };
        let mut invalid_samples = 0;
        for t in outs {
            invalid_samples += t.invalid;
            for ty in 0..t.h {
                for tx in 0..t.w {
                    let src = (ty * t.w + tx) as usize;
                    let dst = ((t.y0 + ty) * width + t.x0 + tx) as usize;
                    radiance[dst] = t.radiance[src];
                    if self.settings.aovs {
                        aovs.normal[dst] = t.aovs.normal[src];
                        aovs.albedo[dst] = t.aovs.albedo[src];
                        aovs.depth[dst] = t.aovs.depth[src];
                        aovs.variance[dst] = t.aovs.variance[src];
                    }
                }
            }
        }
        Ok(RenderOutput {
            width,
            height,
            radiance,
            aovs: self.settings.aovs.then_some(aovs),
            settings: self.settings.clone(),
            seconds,
            invalid_samples,
        })
    }

    fn render_tile(&self, cam: &PinholeCamera, x0: u32, y0: u32, w: u32, h: u32) -> TileOut {
        let spp = self.settings.spp;
        let n = (w * h) as usize;
        let aov = self.settings.aovs;
        let mut out = TileOut {
            x0,
            y0,
            w,
            h,
            radiance: Vec::with_capacity(n),
            aovs: Aovs::default(),
            invalid: 0,
        };
        let eye = cam.eye();
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                let pixel = u64::from(y) * u64::from(cam.width()) + u64::from(x);
                let (mut sum, mut sum_sq) = (DVec3::ZERO, DVec3::ZERO);
                let (mut normal, mut albedo, mut depth) = (DVec3::ZERO, DVec3::ZERO, 0.0f64);
                for sample in 0..spp {
                    let mut s =
                        stream(self.settings.seed, Purpose::Pixel, pixel, u64::from(sample));
                    let [jx, jy] = s.next_2d();
                    let dir =
                        cam.direction(f64::from(x) + f64::from(jx), f64::from(y) + f64::from(jy));
                    let mut l = match self.accel.closest_hit(eye, dir, f32::INFINITY) {
                        None => self.background(dir),
                        Some(hit) => {
                            let v = self.vertex(&hit);
                            if aov {
                                let ns = if v.ns.dot(dir) > 0.0 { -v.ns } else { v.ns };
                                normal += ns.as_dvec3();
                                albedo += Vec3::from_array(v.mat.albedo()).as_dvec3();
                                depth += f64::from(hit.t);
                            }
                            self.li_surface(v, -dir, &mut s)
                        }
                    };
                    if !l.is_finite() {
                        out.invalid += 1;
                        l = Vec3::ZERO;
                    }
                    let l = l.as_dvec3();
                    sum += l;
                    sum_sq += l * l;
                }
                let k = f64::from(spp);
                out.radiance.push((sum / k).as_vec3());
                if aov {
                    out.aovs.normal.push((normal / k).as_vec3());
                    out.aovs.albedo.push((albedo / k).as_vec3());
                    out.aovs.depth.push((depth / k) as f32);
                    let var = if spp > 1 {
                        ((sum_sq - sum * sum / k) / (k - 1.0)).max(DVec3::ZERO) / k
                    } else {
                        DVec3::ZERO
                    };
                    out.aovs.variance.push(var.as_vec3());
                }
            }
        }
        out
    }

    /// Radiance leaving each point towards its `view_dir` (or the AO fraction, per the mode),
    /// estimated with `spp` samples from streams `(seed, Point, point index, sample)`: the
    /// same estimator as an image pixel whose camera ray hits the point. The first vertex's
    /// spawn offset is [`point_offset`] since no triangle is known.
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
                        offset: point_offset(p.position, max_abs),
                        mat: &p.material,
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
