//! The state every step of a report shares ([`Run`]): the scene and its BVH, the report's
//! directory, the settings and the object mask, with the few helpers the steps all use.

use crate::data::ReportSettings;
use crate::error::ReportError;
use glam::Vec3;
use prt_bakefile::Bake;
use prt_compare::{Image, Mask};
use prt_scene::Scene;
use prt_scene_relight::imaging::{form_image_with, object_mask, ImageRays, RgbImage};
use prt_scene_relight::io::write_png;
use prt_scene_relight::relit::{relight, RelightOptions, Relit};
use prt_tracer::Accel;
use std::path::Path;
use std::sync::OnceLock;

/// What every step of a report reads.
pub(crate) struct Run<'a> {
    /// The scene.
    pub scene: &'a Scene,
    /// Its BVH.
    pub accel: Accel,
    /// The report's directory (images in `images/`, the cache in `cache/`).
    pub out_dir: &'a Path,
    /// The report's settings.
    pub settings: &'a ReportSettings,
    /// Image width (the camera's).
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Object pixels (the pixels compared with the reference).
    pub mask: Mask,
    /// The highest order of the settings' orders: the bake's order.
    pub max_order: usize,
    /// The camera's sub-pixel rays, traced for the first image formed and kept for every
    /// other (the report forms several images per order).
    rays: OnceLock<ImageRays>,
}

impl<'a> Run<'a> {
    /// Checks the settings, creates `images/` and `cache/`, builds the BVH and writes the
    /// object mask (`images/mask.png`).
    pub fn start(
        scene: &'a Scene,
        out_dir: &'a Path,
        settings: &'a ReportSettings,
    ) -> Result<Self, ReportError> {
        check_settings(settings)?;
        for dir in ["images", "cache"] {
            std::fs::create_dir_all(out_dir.join(dir)).map_err(|e| ReportError::Write {
                path: out_dir.to_path_buf(),
                reason: e.to_string(),
            })?;
        }
        let accel = prt_tracer::Accel::build(scene)?;
        let (w, h) = (scene.camera.width, scene.camera.height);
        let mask_bits = object_mask(scene, &accel)?;
        let mask_png = RgbImage {
            width: w as usize,
            height: h as usize,
            pixels: mask_bits
                .iter()
                .map(|&m| if m { [1.0; 3] } else { [0.0; 3] })
                .collect(),
        };
        write_png(&out_dir.join("images/mask.png"), &mask_png, 0.0)?;
        let mask = Mask::from_bools(w as usize, h as usize, mask_bits)?;
        Ok(Run {
            scene,
            accel,
            out_dir,
            settings,
            width: w,
            height: h,
            mask,
            max_order: *settings.orders.iter().max().expect("non-empty"),
            rays: OnceLock::new(),
        })
    }

    /// A progress message on stderr (when the settings ask for progress).
    pub fn say(&self, m: &str) {
        if self.settings.progress {
            eprintln!("report: {m}");
        }
    }

    /// Linear radiance of the camera's size as a comparison image.
    pub fn image(&self, radiance: &[Vec3]) -> Image {
        Image {
            width: self.width as usize,
            height: self.height as usize,
            pixels: radiance.iter().map(|v| v.to_array()).collect(),
        }
    }

    /// The image of `bake` relit once at `order`, full order, in linear radiance.
    pub fn relit_image(&self, bake: &Bake, order: usize) -> Result<Vec<Vec3>, ReportError> {
        let once = RelightOptions {
            order: Some(order),
            adaptive: None,
            rotate_y_deg: 0.0,
            timing_frames: 1,
            warmup_frames: 0,
            rotate_y_step_deg: 0.0,
            points: None,
            ..Default::default()
        };
        let r = relight(self.scene, &self.accel, bake, &once)?;
        Ok(linear(&self.form(&r)?))
    }

    /// The image of a relit result of the scene, unrotated, with the camera's rays traced
    /// once per report ([`ImageRays`]).
    pub fn form(&self, relit: &Relit) -> Result<RgbImage, ReportError> {
        let rays = match self.rays.get() {
            Some(r) => r,
            None => {
                let traced = ImageRays::trace(self.scene, &self.accel)?;
                self.rays.get_or_init(|| traced)
            }
        };
        Ok(form_image_with(self.scene, &self.accel, rays, relit, 0.0))
    }
}

/// An image's pixels as linear radiance vectors.
pub(crate) fn linear(img: &RgbImage) -> Vec<Vec3> {
    img.pixels.iter().map(|p| Vec3::from_array(*p)).collect()
}

/// Refuses settings no report can run with.
fn check_settings(s: &ReportSettings) -> Result<(), ReportError> {
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
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> ReportSettings {
        ReportSettings {
            orders: vec![2, 4],
            reference_spp: 4,
            reference_psnr: None,
            budget: false,
            target_psnr: None,
            rays: 8,
            bounces: 0,
            threshold: 0.02,
            display_threshold: false,
            seed: 1,
            timing_frames: 1,
            progress: false,
            reflectance: None,
        }
    }

    fn refusal(s: &ReportSettings) -> String {
        match check_settings(s) {
            Err(ReportError::Invalid(m)) => m,
            other => panic!("expected a refusal, got {other:?}"),
        }
    }

    #[test]
    fn impossible_settings_are_refused_before_anything_runs() {
        assert!(check_settings(&settings()).is_ok());
        for orders in [vec![], vec![0, 2], vec![2, 33]] {
            let s = ReportSettings {
                orders,
                ..settings()
            };
            assert_eq!(refusal(&s), "orders must be between 1 and 32");
        }
        let s = ReportSettings {
            timing_frames: 0,
            ..settings()
        };
        assert!(refusal(&s).starts_with("--reference-spp, --rays"));
        for threshold in [-0.1, f32::NAN, f32::INFINITY] {
            let s = ReportSettings {
                threshold,
                ..settings()
            };
            assert_eq!(refusal(&s), "--threshold must be finite and ≥ 0");
        }
    }
}
