//! BVH ray tracing and the ground-truth path tracer of `prt`.
//!
//! - [`Accel`]: closest-hit and occlusion queries over every triangle of a scene, on an obvhs
//!   CWBVH, with the three obvhs 0.4.0 defects of `FACTS.md` worked around and pinned by tests
//!   (direction `-0.0`, barycentric scale, fixed node `tmin`) and a fourth found here
//!   (non-conservative quantisation of child bounds); see [`AccelOptions`] and `src/accel.rs`.
//! - Robust secondary rays in the style of pbrt-v4 and Mitsuba 3: origins move off the surface
//!   along the geometric normal, to the side of the new direction, by a bound proportional to
//!   the magnitude of the coordinates ([`SPAWN_RELATIVE_OFFSET`], derived from f32 rounding);
//!   shadow rays to a point stop [`SHADOW_RAY_SHORTEN`] short of it.
//! - [`Renderer`] / [`render`](fn@render): an unbiased path tracer of distant environment light. Next-event
//!   estimation samples the environment map (`prt_shading::EnvSampler`), the BRDF is importance
//!   sampled (`prt_shading::sample`), and the two are combined with Veach's multiple importance
//!   sampling (power heuristic by default, balance on request; Veach & Guibas 1995). Delta
//!   (mirror) lobes take no MIS weight. At the first vertices of a path, diffuse-plus-mirror
//!   materials follow their mirror ray every time and their diffuse lobe as often as the
//!   one-sample lobe choice takes it ([`SplitLobes::Delta`], the default), or a sample of each
//!   lobe (lobe splitting, [`SplitLobes::Mirror`]; Veach's multi-sample MIS with the balance
//!   heuristic between the lobes; glossy two-lobe materials on request). Bounces count as in
//!   CONVENTIONS.md (`-1`: unlimited
//!   with Russian roulette). Modes: [`Mode::Path`], [`Mode::Unshadowed`],
//!   [`Mode::AmbientOcclusion`]; and radiance at given points ([`Renderer::radiance_at_points`]).
//! - glTF material inputs (issue 34): shading with the normal-mapped shading normal
//!   (`prt_scene::Scene::normal_mapped`), emitted radiance where camera and BRDF-sampled rays
//!   hit emissive surfaces (weight 1: no next-event estimation towards them, so unbiased),
//!   and `alphaMode MASK` cut-outs skipped by every [`Accel`] query of a scene's BVH.
//! - Determinism: every random number comes from a PCG32 stream keyed by (seed, purpose,
//!   pixel or point, sample) through SplitMix64 mixing ([`rng`]); images are bit-identical for
//!   any thread count.
//! - Output ([`output`]): EXR (linear f32, metadata attributes, optional AOV channels) and a PNG
//!   view, both written atomically.
//! - The points a bake or a relight samples ([`points`]): mesh vertices, and the sub-pixel
//!   footprints of the scene camera's pixels (per-pixel bakes, their relighting and image
//!   formation), whose positions come from the shifted R2 sequences of [`sequence`].

mod accel;
pub mod box_nodes;
mod camera;
mod error;
mod group_clip;
mod integrator;
pub mod output;
pub mod points;
mod progress;
mod render;
pub mod rng;
pub mod sequence;
mod settings;
pub mod test_util;
pub mod traverse;
mod vertex;

pub use accel::{
    offset_origin, point_offset, spawn_offset, Accel, AccelOptions, Hit, FLAT_GROUPS,
    SHADOW_RAY_SHORTEN, SPAWN_RELATIVE_OFFSET,
};
pub use camera::PinholeCamera;
pub use error::TracerError;
pub use obvhs::BvhBuildParams;
pub use progress::progress_bar;
pub use render::{render, Aovs, RenderOutput, Renderer, SurfacePoint, FIRST_PASS_SPP};
pub use settings::{EnvSampling, MisHeuristic, Mode, RenderSettings, SamplerKind, SplitLobes};
