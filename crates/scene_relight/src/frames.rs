//! The frames of a relighting run: each lit by the environment rotated about +Y by one SH
//! rotation, a few untimed warm-up frames (lit as frame 0) before the timed ones, whose
//! shading times and whole per-frame work (rotation, lighting preparation, shading) are
//! summed over the objects. An object's terms are shaded at full order or adaptively on every
//! frame; the radiance kept is frame 0's.

use crate::error::SceneRelightError;
use glam::DMat3;
use prt_relight::{
    AdaptiveFrame, AdaptiveInput, AdaptiveParams, Adjacency, CpcaTransfer, DiffuseParams, Lighting,
    Relighter, SpecularInput, TransferView,
};
use prt_sh::Rotation;
use std::time::Instant;

/// The environment of a run and the rotation of each of its frames.
pub(crate) struct Frames {
    /// The environment's order.
    pub(crate) env_order: usize,
    /// The environment, RGB coefficients `[coeff][channel]`.
    pub(crate) env: Vec<[f64; 3]>,
    /// Rotation of frame 0, degrees.
    pub(crate) rotate_y_deg: f64,
    /// Rotation added per timed frame, degrees.
    pub(crate) step_deg: f64,
    /// Untimed frames before the timed ones.
    pub(crate) warmup: usize,
}

impl Frames {
    /// The SH rotation about +Y by `deg` degrees (`None` for 0).
    pub(crate) fn rotation(&self, deg: f64) -> Result<Option<Rotation>, SceneRelightError> {
        Ok(if deg == 0.0 {
            None
        } else {
            Some(Rotation::new(
                self.env_order,
                DMat3::from_rotation_y(deg.to_radians()),
            )?)
        })
    }

    /// The lighting of timed frame `k` (rotated by its own angle), and the time that took.
    fn light(&self, k: usize) -> Result<(Lighting, f64), SceneRelightError> {
        let start = Instant::now();
        let r = self.rotation(self.rotate_y_deg + self.step_deg * k as f64)?;
        let l = Lighting::from_rgb_coefficients(&self.env, r.as_ref())?;
        Ok((l, start.elapsed().as_secs_f64()))
    }
}

/// The times of a run's timed frames, summed over its objects.
pub(crate) struct Timing {
    /// Shading time of each timed frame, seconds.
    pub(crate) times: Vec<f64>,
    /// Whole per-frame work (rotation, lighting preparation, shading), for frames per second.
    pub(crate) frame_seconds: f64,
}

impl Timing {
    /// `frames` timed frames, none timed yet.
    pub(crate) fn new(frames: usize) -> Self {
        Self {
            times: vec![0.0f64; frames],
            frame_seconds: 0.0,
        }
    }

    /// Adds `seconds` spent once for the object (shading every frame alike) to every frame.
    pub(crate) fn add_to_every_frame(&mut self, seconds: f64) {
        self.times.iter_mut().for_each(|t| *t += seconds);
        self.frame_seconds += seconds * self.times.len() as f64;
    }
}

/// Radiance per point of an object's diffuse and specular terms (the latter empty without a
/// specular term).
pub(crate) struct Shaded {
    pub(crate) diffuse: Vec<[f32; 3]>,
    pub(crate) specular: Vec<[f32; 3]>,
}

/// The terms one object's frames shade.
pub(crate) struct ObjectTerms<'a> {
    pub(crate) relighter: Relighter,
    pub(crate) order: usize,
    /// The diffuse transfer and its parameters.
    pub(crate) diffuse: TransferView<'a>,
    pub(crate) dparams: DiffuseParams,
    /// The diffuse transfer in clustered-PCA form, relit from it instead (full order only).
    pub(crate) cpca: Option<CpcaTransfer<'a>>,
    /// The fitted or Phong specular.
    pub(crate) specular: Option<SpecularInput<'a>>,
    /// The specular term's visibility in clustered-PCA form, relit from it instead (full
    /// order only).
    pub(crate) visibility_cpca: Option<CpcaTransfer<'a>>,
}

impl ObjectTerms<'_> {
    /// Shades every frame adaptively over the neighbourhood `triangles` of the object's
    /// points; returns frame 0.
    pub(crate) fn adaptive_frames(
        &self,
        frames: &Frames,
        timing: &mut Timing,
        triangles: &[[u32; 3]],
        params: &AdaptiveParams,
    ) -> Result<AdaptiveFrame, SceneRelightError> {
        let relighter = &self.relighter;
        let adjacency = Adjacency::from_triangles(self.diffuse.point_count(), triangles)?;
        let input = AdaptiveInput {
            diffuse: Some((self.diffuse, self.dparams)),
            specular: self.specular,
            adjacency: &adjacency,
        };
        let mut first = None;
        for k in 0..frames.warmup + timing.times.len() {
            // Timed frame `i` after the warm-up (which is lit as frame 0).
            let timed = k.checked_sub(frames.warmup);
            let (lighting, rotate) = frames.light(timed.unwrap_or(0))?;
            let prep = Instant::now();
            let frame = relighter.frame_lighting(&lighting, self.specular.is_some())?;
            let start = Instant::now();
            let f = relighter.adaptive(&input, &frame, params)?;
            let Some(i) = timed else { continue };
            timing.times[i] += start.elapsed().as_secs_f64();
            timing.frame_seconds += rotate + prep.elapsed().as_secs_f64();
            if i == 0 {
                first = Some(f);
            }
        }
        Ok(first.expect("at least one frame"))
    }

    /// Shades every frame at full order; returns frame 0's terms.
    pub(crate) fn full_frames(
        &self,
        frames: &Frames,
        timing: &mut Timing,
    ) -> Result<Shaded, SceneRelightError> {
        let relighter = &self.relighter;
        let mut first = (Vec::new(), Vec::new());
        for k in 0..frames.warmup + timing.times.len() {
            let timed = k.checked_sub(frames.warmup);
            let (lighting, rotate) = frames.light(timed.unwrap_or(0))?;
            let prep = Instant::now();
            // The compressed glossy path forms its own cluster products (timed, below).
            let products = self.specular.is_some() && self.visibility_cpca.is_none();
            let frame = relighter.frame_lighting(&lighting, products)?;
            let start = Instant::now();
            let d = match &self.cpca {
                Some(c) => prt_relight::diffuse_cpca(self.order, c, &lighting, &self.dparams)?,
                None => relighter.diffuse(&self.diffuse, &frame, &self.dparams)?,
            };
            let s = match (&self.specular, &self.visibility_cpca) {
                (Some(si), Some(v)) => prt_relight::specular_cpca(relighter, si, v, &lighting)?,
                (Some(si), None) => relighter.specular(si, &frame)?,
                (None, _) => Vec::new(),
            };
            let Some(i) = timed else { continue };
            timing.times[i] += start.elapsed().as_secs_f64();
            timing.frame_seconds += rotate + prep.elapsed().as_secs_f64();
            if i == 0 {
                first = (d, s);
            }
        }
        let (diffuse, specular) = first;
        Ok(Shaded { diffuse, specular })
    }
}

/// Two triangles per cell of a `w × h` texel grid (texel `y·w + x`): the neighbourhood the
/// adaptive path's region-of-interest growth walks for per-texel objects.
pub(crate) fn texel_grid(w: u32, h: u32) -> Vec<[u32; 3]> {
    let mut t = Vec::with_capacity(2 * w as usize * h as usize);
    for y in 0..h.saturating_sub(1) {
        for x in 0..w.saturating_sub(1) {
            let k = y * w + x;
            t.push([k, k + 1, k + w + 1]);
            t.push([k, k + w + 1, k + w]);
        }
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn texel_grid_joins_each_cell_by_two_triangles() {
        // 3 × 2 texels: two cells, four triangles, each texel's right and lower neighbours.
        assert_eq!(
            texel_grid(3, 2),
            [[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 4]]
        );
        assert!(texel_grid(1, 5).is_empty());
        assert!(texel_grid(0, 0).is_empty());
    }

    #[test]
    fn frame_k_is_lit_by_the_environment_rotated_by_its_own_angle() {
        // An L1-only environment: coefficient `e` on y_1,1 = −c·x (Condon–Shortley phase), a
        // lobe towards −X. Frame 2 of a run starting at 30° in steps of 30° is rotated by 90°
        // about +Y, which turns −X to +Z (the sense of the scene's `rotation_y`, in which the
        // background is looked up): the lobe moves to y_1,0 = c·z (index 2).
        let mut env = vec![[0.0f64; 3]; 4];
        env[3] = [1.0, 2.0, 3.0];
        let frames = Frames {
            env_order: 2,
            env: env.clone(),
            rotate_y_deg: 30.0,
            step_deg: 30.0,
            warmup: 0,
        };
        assert!(frames.rotation(0.0).unwrap().is_none());
        let (lit, _) = frames.light(2).unwrap();
        for c in 0..3 {
            let want = [0.0, 0.0, env[3][c], 0.0];
            for (got, want) in lit.rgb[c].iter().zip(want) {
                assert!((f64::from(*got) - want).abs() < 1e-6, "{lit:?}");
            }
        }
        // Frame 0 is rotated by 30°: −X turns to (−cos 30°, 0, sin 30°).
        let (lit, _) = frames.light(0).unwrap();
        let (s, c30) = (30f64.to_radians().sin(), 30f64.to_radians().cos());
        for c in 0..3 {
            let want = [0.0, 0.0, s * env[3][c], c30 * env[3][c]];
            for (got, want) in lit.rgb[c].iter().zip(want) {
                assert!((f64::from(*got) - want).abs() < 1e-6, "{lit:?}");
            }
        }
    }
}
