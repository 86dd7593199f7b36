//! Relighting a scene from its bake file: what `prt relight`, `prt export`, the report and the
//! hard-case tests share. It takes a scene and a bake file, never the baker: the binding of
//! the two is checked once ([`check_bake`], by geometry and UV hashes), each object's points
//! are relit ([`relight`]: full-order or locally adaptive SH, with the view-dependent terms
//! of glossy materials, [`glossy`]), and the result is formed into an image comparable with
//! the path tracer's ([`imaging`]): Gouraud interpolation of per-vertex radiance over the
//! triangles hit by the scene camera's rays, bilinear lookups of per-texel bakes at each hit's
//! lightmap UV, or per-pixel radiance directly. [`target`] relights adaptively to a PSNR
//! target frame by frame; [`io`] writes the images. [`Bound`] binds a bake once per command
//! (footprints, lightmaps, the camera's rays) for every relighting and image after it, and
//! [`inverse`] fits the lighting to an image (Ramamoorthi & Hanrahan 2001, inverse
//! rendering), relighting being linear in it, and [`fit_material`] a material's albedo and
//! Phong exponent with it.
//!
//! The relighting follows Sloan, Kautz & Snyder 2002 (diffuse PRT) and Lee & Kim 2014
//! (specular PRT through SH products and locally adaptive SH), whose scene-free kernels are
//! `prt-relight`'s, and, for Blinn–Phong, Ward and Cook–Torrance, Kautz, Sloan & Snyder 2002
//! (per-view-elevation BRDF projections, `prt_shading::projection`). Sharp glossy lobes may
//! instead be looked up in spherical harmonic reflection maps ([`shrm`]; Ramamoorthi &
//! Hanrahan 2002, "Frequency space environment map rendering", `--glossy shrm`), with the
//! sharp lobe's own traced visibility as its occlusion and the lookup made per sub-pixel
//! sample at image formation ([`ShrmSpecular`]).

mod background;
mod binding;
mod bound;
mod error;
pub mod fit_material;
pub mod footprint;
mod frames;
pub mod glossy;
pub mod imaging;
pub mod inverse;
pub mod io;
mod lobe;
mod points;
pub mod relit;
pub mod shrm;
mod shrm_occlusion;
mod shrm_path;
mod solve;
pub mod sources;
mod specular;
pub mod target;

pub use bound::Bound;
pub use error::SceneRelightError;
pub use imaging::{form_image, form_image_with, object_mask, roi_image, ImageRays, RgbImage};
pub use lobe::sharp_lobe;
pub use relit::{
    baked_scene, check_bake, relight, GlossyPath, PhongModel, RelightOptions, RelightStats, Relit,
    ShrmSpecular,
};
