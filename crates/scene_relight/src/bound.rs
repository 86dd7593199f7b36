//! A bake bound to its scene ([`Bound`]): the set-up relighting and image formation share
//! across calls, computed once per command.

use crate::error::SceneRelightError;
use crate::imaging::{form_image, form_image_with, ImageRays, RgbImage};
use crate::relit::{prepare, relight_prepared, Prepared, RelightOptions, Relit};
use prt_bakefile::Bake;
use prt_scene::Scene;
use std::sync::OnceLock;

/// A bake bound to its scene: what relighting needs besides the lighting of a frame,
/// computed once — the pixel footprints of a per-pixel bake (traced) and the lightmaps of a
/// per-texel bake (rasterised), and on first use the `--glossy shrm` path's traced lobe
/// visibility (camera and geometry, not lighting) — so that a command or a report relighting the same bake
/// several times (full order and adaptive, every order, every frame of a study) pays for
/// them once, and the camera's sub-pixel rays that image formation traces. [`Bound::relight`]
/// is then [`crate::relight`] without that set-up, and [`Bound::form_image`] a gather.
pub struct Bound<'a> {
    scene: &'a Scene,
    accel: &'a prt_tracer::Accel,
    bake: &'a Bake,
    /// Footprints, lightmaps and the SHRM path's traced lobe visibility.
    prepared: Prepared,
    /// The camera's sub-pixel rays, traced when the first image is formed.
    rays: OnceLock<ImageRays>,
}

impl<'a> Bound<'a> {
    /// Binds `bake` (already checked with [`crate::check_bake`]) to `scene` and its BVH.
    ///
    /// # Errors
    /// A per-pixel bake whose footprints cannot be traced (a camera the tracer refuses) or a
    /// lightmap the rasteriser refuses.
    pub fn new(
        scene: &'a Scene,
        accel: &'a prt_tracer::Accel,
        bake: &'a Bake,
    ) -> Result<Self, SceneRelightError> {
        let prepared = prepare(scene, accel, bake)?;
        Ok(Self {
            scene,
            accel,
            bake,
            prepared,
            rays: OnceLock::new(),
        })
    }

    /// The image of `relit` (a result of [`Bound::relight`]) under the environment turned by
    /// `rotate_y_deg`: [`form_image`], with the camera's rays traced once for
    /// every image of this binding.
    ///
    /// # Errors
    /// A camera the tracer refuses.
    pub fn form_image(
        &self,
        relit: &Relit,
        rotate_y_deg: f64,
    ) -> Result<RgbImage, SceneRelightError> {
        if relit.footprints.is_some() {
            return form_image(self.scene, self.accel, relit, rotate_y_deg);
        }
        let rays = self.image_rays()?;
        Ok(form_image_with(
            self.scene,
            self.accel,
            rays,
            relit,
            rotate_y_deg,
        ))
    }

    /// The camera's sub-pixel rays of per-vertex and per-texel image formation, traced on
    /// first use (to time [`Bound::form_image`] without them, call this first).
    ///
    /// # Errors
    /// A camera the tracer refuses.
    pub fn image_rays(&self) -> Result<&ImageRays, SceneRelightError> {
        Ok(match self.rays.get() {
            Some(r) => r,
            None => {
                let traced = ImageRays::trace(self.scene, self.accel)?;
                self.rays.get_or_init(|| traced)
            }
        })
    }

    /// The scene.
    #[must_use]
    pub fn scene(&self) -> &'a Scene {
        self.scene
    }

    /// The scene's BVH.
    #[must_use]
    pub fn accel(&self) -> &'a prt_tracer::Accel {
        self.accel
    }

    /// The pixel footprints of a per-pixel bake (`None` for other bakes).
    #[must_use]
    pub fn footprints(&self) -> Option<&prt_tracer::points::PixelFootprints> {
        self.prepared.footprints.as_deref()
    }

    /// The bake.
    #[must_use]
    pub fn bake(&self) -> &'a Bake {
        self.bake
    }

    /// Relights every object under `opt`.
    ///
    /// # Errors
    /// As [`crate::relight`].
    pub fn relight(&self, opt: &RelightOptions) -> Result<Relit, SceneRelightError> {
        relight_prepared(self.scene, self.accel, self.bake, &self.prepared, opt, None)
    }

    /// [`Bound::relight`] under `lighting` (SH coefficients, rows of `[r, g, b]`, `n²` of them)
    /// instead of the bake's environment: relighting is linear in the lighting, which is what
    /// fitting the lighting to an image rests on.
    ///
    /// # Errors
    /// As [`crate::relight`], and a row count that is not a square.
    pub fn relight_under(
        &self,
        lighting: &[[f64; 3]],
        opt: &RelightOptions,
    ) -> Result<Relit, SceneRelightError> {
        let n = (lighting.len() as f64).sqrt().round() as usize;
        if n == 0 || n * n != lighting.len() {
            return Err(SceneRelightError::Invalid(format!(
                "{} lighting coefficients: not the n² of an order",
                lighting.len()
            )));
        }
        relight_prepared(
            self.scene,
            self.accel,
            self.bake,
            &self.prepared,
            opt,
            Some(lighting),
        )
    }
}
