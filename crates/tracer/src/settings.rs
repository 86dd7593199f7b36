//! Parameters of a render, read in one place with their defaults beside them.

use crate::TracerError;
pub use prt_shading::EnvSampling;

/// What the integrator computes at the first surface a camera ray (or a given point) sees.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Mode {
    /// Unbiased path tracing of the environment light with shadows and `bounces` indirect
    /// reflections (the default).
    Path,
    /// Visibility ignored: every direction above the surface (shading-normal hemisphere) sees
    /// the environment; no secondary surface hits (the PRT "unshadowed" transfer).
    Unshadowed,
    /// Fraction of cosine-weighted directions about the shading normal that are unoccluded
    /// (within `max_distance` when given). Directions below the geometric surface count as
    /// occluded. Written as grey; background pixels are 1.
    AmbientOcclusion {
        /// Rays longer than this count as unoccluded (`None`: unlimited).
        max_distance: Option<f32>,
    },
}

/// The multiple-importance-sampling heuristic of Veach (1997) between environment sampling
/// and BRDF sampling (one sample from each strategy).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MisHeuristic {
    /// `w_a = p_a² / (p_a² + p_b²)` (the default).
    Power,
    /// `w_a = p_a / (p_a + p_b)`.
    Balance,
}

/// Which materials a path vertex samples once per lobe instead of choosing one lobe at
/// random (lobe splitting, `prt_shading::sample_lobe`; within the first
/// [`RenderSettings::split_depth`] vertices of a path).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SplitLobes {
    /// Never: one lobe chosen at random everywhere, as Mitsuba and pbrt do.
    None,
    /// Diffuse-plus-mirror materials (`Material::Mirror` with both parts), one sample of
    /// each lobe: the mirror direction is one deterministic ray whose light usually differs
    /// from what the diffuse part gathers, so the random lobe choice is most of such a
    /// pixel's noise. On the suite's chrome teapot (`tools/mitsuba_compare.py`'s `mirror`)
    /// it cuts the variance to a third for 1.2× the time.
    Mirror,
    /// Diffuse-plus-mirror materials, the default: the mirror ray is followed at every such
    /// vertex (weight `specular`), and the diffuse lobe as often as the one-sample lobe
    /// choice takes it, with the weight and density it has there. The lobe choice's noise on
    /// the mirror's light is gone for an extra ray in a fraction `1 − P` of the vertices
    /// (`P` the mirror's selection probability) instead of at all of them: on the chrome
    /// teapot 0.41 of the unsplit variance for 1.05× the time, against 0.33 for 1.2× with
    /// [`SplitLobes::Mirror`].
    Delta,
    /// Every material of two lobes, glossy ones too. Whether the second ray pays depends on
    /// the light the lobes see: cost at equal error 0.72–0.79× on the bundled `glossy` and
    /// `bunny_glossy`, 1.07–1.11× on `default` and `helmet` (see the tracer README).
    All,
}

/// How a pixel's samples take their quasi-random points ([`crate::rng::PixelKeys`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum SamplerKind {
    /// Two independent scrambled Sobol sequences, even samples from one and odd samples from
    /// the other (the default): the two half images are independent, so the image carries an
    /// unbiased estimate of its own noise ([`crate::RenderOutput::noise`]), which noise and
    /// PSNR targets need. Each half is stratified on its own, so where the integrand is
    /// smooth the variance is up to `√2` times that of one sequence of all the samples.
    Replicas,
    /// One scrambled Sobol sequence: sample `j` is point `j`, so all of a pixel's samples
    /// are stratified together (the lowest variance at a given sample count; the sampler of
    /// Cycles and pbrt-v4). Still unbiased; but its error cannot be estimated from the
    /// image itself, so the image has no noise estimate.
    Single,
}

/// Everything a render depends on besides the scene.
#[derive(Clone, Debug, PartialEq)]
pub struct RenderSettings {
    /// Samples per pixel (per point for [`crate::Renderer::radiance_at_points`]). Default 64.
    pub spp: u32,
    /// Indirect bounces per CONVENTIONS.md: `0` direct light with shadows, `B` adds `B`
    /// interreflections (Mitsuba `max_depth = B + 2`), `-1` unlimited with Russian roulette.
    /// Default 0.
    pub bounces: i32,
    /// Global seed (default 0), written into every output.
    pub seed: u64,
    /// What to compute (default [`Mode::Path`]).
    pub mode: Mode,
    /// MIS heuristic (default [`MisHeuristic::Power`]).
    pub mis: MisHeuristic,
    /// The pixel sampler's sequences (default [`SamplerKind::Replicas`]).
    pub sampler: SamplerKind,
    /// How environment samples are drawn (default [`EnvSampling::PerNormal`]: every one is
    /// combined with BRDF sampling by MIS, so the compensated densities are unbiased and have
    /// the lower variance; see [`EnvSampling`]).
    pub env_sampling: EnvSampling,
    /// Lobe splitting: which materials are sampled once per lobe, both directions followed
    /// (Veach's multi-sample MIS with the balance heuristic between the lobes; see
    /// `prt_shading::sample_lobe`), instead of one direction from a lobe chosen at random.
    /// The same expectation, less noise where the lobes see different light. Default
    /// [`SplitLobes::Delta`].
    pub split_lobes: SplitLobes,
    /// Lobe splitting happens at the first this many vertices of a path (default 2): a
    /// camera sample ends in at most `2^split_depth` paths.
    pub split_depth: u32,
    /// With `bounces = -1`: Russian roulette starts at this many indirect bounces (default 3).
    pub rr_start_bounce: u32,
    /// With `bounces = -1`: survival probability is `min(luminance(throughput), this)`
    /// (default 0.95).
    pub rr_max_survival: f32,
    /// Square tile size in pixels for parallel rendering (default 16; no effect on the image).
    pub tile_size: u32,
    /// Worker threads (`None`: rayon's current pool; no effect on the image).
    pub threads: Option<usize>,
    /// Also produce normal, albedo, depth and variance AOVs (default false).
    pub aovs: bool,
    /// Show a progress bar when stderr is a terminal (default true).
    pub progress: bool,
    /// Render in passes until the image's own estimate of its relative noise on object pixels
    /// ([`crate::RenderOutput::noise`]) is at most this (in `(0, 1)`); `spp` is then the most
    /// samples per pixel it may take. Default `None`: exactly `spp`.
    pub target_noise: Option<f64>,
    /// Render in passes while the next one fits in this many seconds (`spp` is then the most
    /// samples per pixel it may take); with `target_noise`, whichever comes first. An error
    /// when not even the first pass fits. Default `None`.
    pub time_budget: Option<f64>,
    /// Render in passes until the image's own estimate of its noise ceiling on the 8-bit view
    /// ([`crate::RenderOutput::noise_psnr_ldr`]: the PSNR of its sRGB view at exposure 0
    /// against that of its own expectation, object pixels) is at least this many dB; `spp` is
    /// then the most samples per pixel it may take. With `target_noise`, both must hold.
    /// Default `None`.
    pub target_psnr_ldr: Option<f64>,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            spp: 64,
            bounces: 0,
            seed: 0,
            mode: Mode::Path,
            mis: MisHeuristic::Power,
            sampler: SamplerKind::Replicas,
            env_sampling: EnvSampling::PerNormal,
            split_lobes: SplitLobes::Delta,
            split_depth: 2,
            rr_start_bounce: 3,
            rr_max_survival: 0.95,
            tile_size: 16,
            threads: None,
            aovs: false,
            progress: true,
            target_noise: None,
            time_budget: None,
            target_psnr_ldr: None,
        }
    }
}

impl RenderSettings {
    /// A quick look: 16 spp, one bounce.
    #[must_use]
    pub fn preview() -> Self {
        Self {
            spp: 16,
            bounces: 1,
            ..Self::default()
        }
    }

    /// A reference: 1024 spp, unlimited bounces with Russian roulette, AOVs.
    #[must_use]
    pub fn final_quality() -> Self {
        Self {
            spp: 1024,
            bounces: -1,
            aovs: true,
            ..Self::default()
        }
    }

    /// The defaults of a scene's `[render]` table.
    #[must_use]
    pub fn from_scene(render: &prt_scene::RenderSettings) -> Self {
        Self {
            spp: render.spp,
            bounces: render.bounces,
            seed: render.seed,
            ..Self::default()
        }
    }

    /// Checks the ranges.
    ///
    /// # Errors
    /// When `spp` or `tile_size` is 0, `bounces < -1`, `rr_max_survival ∉ (0, 1]`,
    /// `threads = Some(0)`, an AO distance is not positive, or a noise or PSNR target is set
    /// with [`SamplerKind::Single`].
    pub fn validate(&self) -> Result<(), TracerError> {
        let bad = |s: String| Err(TracerError::InvalidSettings(s));
        if self.spp == 0 {
            return bad("spp must be at least 1".into());
        }
        if self.bounces < -1 {
            return bad(format!(
                "bounces must be -1 (unlimited) or ≥ 0, not {}",
                self.bounces
            ));
        }
        if !(self.rr_max_survival > 0.0 && self.rr_max_survival <= 1.0) {
            return bad("rr_max_survival must be in (0, 1]".into());
        }
        if self.tile_size == 0 {
            return bad("tile_size must be at least 1".into());
        }
        if self.threads == Some(0) {
            return bad("threads must be at least 1".into());
        }
        if let Some(r) = self.target_noise {
            if !(r > 0.0 && r < 1.0) {
                return bad(format!(
                    "target noise {r} must be a relative error in (0, 1), e.g. 0.01 for 1 %"
                ));
            }
        }
        if let Some(p) = self.target_psnr_ldr {
            if !(p > 0.0 && p.is_finite()) {
                return bad(format!(
                    "target PSNR {p} must be a positive, finite number of dB"
                ));
            }
        }
        if self.sampler == SamplerKind::Single
            && (self.target_noise.is_some() || self.target_psnr_ldr.is_some())
        {
            return bad(
                "a noise or PSNR target needs the image's own noise estimate, which only the \
                 replicas sampler gives (not the single-sequence sampler)"
                    .into(),
            );
        }
        if let Some(b) = self.time_budget {
            if !(b > 0.0 && b.is_finite()) {
                return bad(format!(
                    "time budget {b} must be a positive number of seconds"
                ));
            }
        }
        if let Mode::AmbientOcclusion {
            max_distance: Some(d),
        } = self.mode
        {
            if d.is_nan() || d <= 0.0 {
                return bad(format!("AO max distance must be positive, not {d}"));
            }
        }
        Ok(())
    }
}
