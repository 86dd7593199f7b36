//! Bake parameters, with presets, read in one place.

use crate::error::BakeError;

/// Which points a bake samples.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PointKind {
    /// Every vertex of every object.
    Vertex,
    /// The primary hit of every pixel of the scene's camera.
    Pixel,
    /// Every texel of a `width × height` lightmap per object with lightmap UVs
    /// (`prt_scene::lightmap`); objects without UVs per vertex.
    Texel {
        /// Lightmap width.
        width: u32,
        /// Lightmap height.
        height: u32,
    },
}

/// Parameters of [`crate::bake`].
#[derive(Clone, Debug)]
pub struct BakeSettings {
    /// Fixed order (bands) for every object; `None` chooses per object from `error_target`.
    pub order: Option<usize>,
    /// Largest order the automatic choice may pick.
    pub max_order: usize,
    /// Automatic order: the smallest order whose truncation loses at most this fraction of the
    /// material lobe's energy (squared L2 norm).
    pub error_target: f64,
    /// Rays per point (per transfer kind that needs rays).
    pub rays: u32,
    /// Interreflection bounces (CONVENTIONS: 0 = direct light with shadows).
    pub bounces: u32,
    /// Global seed.
    pub seed: u64,
    /// Vertices or pixels.
    pub points: PointKind,
    /// Per-pixel bakes: sub-pixel samples per pixel, stratified over the pixel's box footprint
    /// (the footprint of `prt render`); the pixel's `rays` are shared out over them, so the
    /// ray count does not grow with it. 1 samples the pixel centre only.
    pub pixel_samples: u32,
    /// Also store the analytic unshadowed diffuse transfer.
    pub unshadowed: bool,
    /// Bake only shard `index` of `count` (contiguous point ranges per object).
    pub shard: Option<(u32, u32)>,
    /// Per-vertex bakes: refine the meshes where the transfer changes fast
    /// ([`crate::subdivide`]).
    pub subdivide: Option<SubdivideOptions>,
    /// Memory the bake may use, in bytes (estimated before any work).
    pub memory_limit: u64,
    /// Show a progress bar on a terminal.
    pub progress: bool,
}

/// Default sub-pixel samples of a per-pixel bake: 16, so that a sample landing on a point the
/// reference also sees as (nearly) black — a grazing surface whose interpolated normal faces
/// away from the camera, an occlusion edge — moves its pixel by at most 1/16 of the pixel's
/// value, and creases converge to the box-filtered reference (measured in
/// `crates/scene_relight/tests/per_pixel.rs`).
pub const DEFAULT_PIXEL_SAMPLES: u32 = 16;

pub use prt_tracer::points::MAX_PIXEL_SAMPLES;

impl Default for BakeSettings {
    fn default() -> Self {
        Self::final_quality()
    }
}

impl BakeSettings {
    /// Bounce levels gathered at vertices: all of them per vertex (and per texel); in a
    /// per-pixel bake all but the last, which the pixels gather from the vertex levels.
    #[must_use]
    pub fn vertex_bounces(&self) -> usize {
        let bounces = self.bounces as usize;
        if self.points == PointKind::Pixel {
            bounces.saturating_sub(1)
        } else {
            bounces
        }
    }

    /// Whether pass `pass` of a distributed bake gathers a bounce at vertices, and so reads
    /// the shard's own hit records (`--hits`): passes `1 ..= vertex_bounces()`.
    #[must_use]
    pub fn pass_gathers_at_vertices(&self, pass: u32) -> bool {
        pass >= 1 && pass as usize <= self.vertex_bounces()
    }

    /// This run's part `(first, count)` of `count` points: all of them unsharded, else the
    /// contiguous range of shard `index` of `shards` (the shards partition the points).
    pub(crate) fn shard_range(&self, count: u64) -> (u64, u64) {
        match self.shard {
            None => (0, count),
            Some((i, n)) => {
                let (i, n) = (u64::from(i), u64::from(n));
                let first = count * i / n;
                (first, count * (i + 1) / n - first)
            }
        }
    }

    /// A progress bar over `len` steps of `what` (drawn only when `progress` is set).
    pub(crate) fn progress_bar(&self, len: u64, what: &str) -> indicatif::ProgressBar {
        prt_tracer::progress_bar(self.progress, len, what)
    }

    /// A quick look: 256 rays, automatic order up to 6, no bounces.
    #[must_use]
    pub fn preview() -> Self {
        Self {
            rays: 256,
            max_order: 6,
            bounces: 0,
            ..Self::final_quality()
        }
    }

    /// The D3DX-like default: 1024 rays, one bounce, automatic order up to 10.
    #[must_use]
    pub fn final_quality() -> Self {
        Self {
            order: None,
            max_order: 10,
            error_target: 1e-3,
            rays: 1024,
            bounces: 1,
            seed: 0,
            points: PointKind::Vertex,
            pixel_samples: DEFAULT_PIXEL_SAMPLES,
            unshadowed: false,
            shard: None,
            memory_limit: 8 << 30,
            progress: false,
            subdivide: None,
        }
    }

    /// Checks ranges.
    pub fn validate(&self) -> Result<(), BakeError> {
        let bad = |m: String| Err(BakeError::InvalidSettings(m));
        if let Some(o) = self.order {
            if o == 0 || o > prt_sh::MAX_ORDER {
                return bad(format!(
                    "order {o} must be between 1 and {}",
                    prt_sh::MAX_ORDER
                ));
            }
        }
        if self.max_order == 0 || self.max_order > prt_sh::MAX_ORDER {
            return bad(format!(
                "max order {} must be between 1 and {}",
                self.max_order,
                prt_sh::MAX_ORDER
            ));
        }
        if !(self.error_target > 0.0 && self.error_target < 1.0) {
            return bad(format!(
                "error target {} must be in (0, 1)",
                self.error_target
            ));
        }
        if self.rays == 0 {
            return bad("rays must be at least 1".into());
        }
        if self.pixel_samples == 0 || self.pixel_samples > MAX_PIXEL_SAMPLES {
            return bad(format!(
                "{} pixel samples: give between 1 and {MAX_PIXEL_SAMPLES}",
                self.pixel_samples
            ));
        }
        if self.points == PointKind::Pixel && self.pixel_samples > self.rays {
            return bad(format!(
                "{} pixel samples but {} rays per pixel: every sample needs at least one ray (the pixel's rays are shared out over its samples)",
                self.pixel_samples, self.rays
            ));
        }
        if self.bounces > 64 {
            return bad(format!(
                "{} bounces is more than the supported 64",
                self.bounces
            ));
        }
        if let Some((i, n)) = self.shard {
            if n == 0 || i >= n {
                return bad(format!("shard {i}/{n}: the index must be below the count"));
            }
        }
        if let PointKind::Texel { width, height } = self.points {
            let max = prt_scene::lightmap::MAX_LIGHTMAP_SIZE;
            if width == 0 || height == 0 || width > max || height > max {
                return bad(format!(
                    "lightmap of {width}×{height} texels: give a size between 1 and {max}"
                ));
            }
            if self.shard.is_some() {
                return bad("per-texel bakes run on one machine (no --shard/--pass)".into());
            }
        }
        Ok(())
    }
}

/// `prt bake --subdivide` options.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SubdivideOptions {
    /// Relative difference of the transfer across an edge above which it is split.
    pub error: f64,
    /// Refinement levels at most.
    pub max_levels: u32,
    /// An object stops refining once it has this many vertices.
    pub max_vertices: usize,
    /// Directions of each refinement probe (at most the bake's rays; `None`: a quarter of
    /// them, at least 128): the refinement decides with these cheap probes, and only the final
    /// vertices get the bake's full rays.
    pub probe_rays: Option<u32>,
}

impl Default for SubdivideOptions {
    fn default() -> Self {
        Self {
            error: 0.1,
            max_levels: 5,
            max_vertices: 1 << 20,
            probe_rays: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn which_passes_read_the_shards_hits() {
        let at = |points, bounces| {
            let s = BakeSettings {
                points,
                bounces,
                ..BakeSettings::preview()
            };
            (0..=bounces)
                .map(|k| s.pass_gathers_at_vertices(k))
                .collect::<Vec<_>>()
        };
        // Per vertex every bounce is gathered at vertices; per pixel the last pass traces the
        // pixels and gathers from the vertex levels instead (SPEC §3.12).
        assert_eq!(at(PointKind::Vertex, 2), [false, true, true]);
        assert_eq!(at(PointKind::Pixel, 2), [false, true, false]);
        assert_eq!(at(PointKind::Pixel, 1), [false, false]);
        assert_eq!(at(PointKind::Vertex, 0), [false]);
    }

    #[test]
    fn shards_partition_the_points_contiguously() {
        for count in [0u64, 1, 5, 7, 1000] {
            for n in 1..=6u32 {
                let mut next = 0;
                for i in 0..n {
                    let s = BakeSettings {
                        shard: Some((i, n)),
                        ..BakeSettings::preview()
                    };
                    let (first, len) = s.shard_range(count);
                    assert_eq!(
                        first, next,
                        "shard {i}/{n} of {count} starts where the last ended"
                    );
                    // Sizes differ by at most one point.
                    assert!(len == count / u64::from(n) || len == count / u64::from(n) + 1);
                    next = first + len;
                }
                assert_eq!(next, count, "{n} shards cover all {count} points");
            }
            let whole = BakeSettings::preview();
            assert_eq!(whole.shard_range(count), (0, count));
        }
    }
}
