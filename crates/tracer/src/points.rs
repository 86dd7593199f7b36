//! The points a bake estimates transfer at: mesh vertices, or the primary hits of sub-pixel
//! samples of the scene camera's pixels.

use crate::sequence::{SequencePurpose, R2};
use crate::{point_offset, Accel, PinholeCamera};
use glam::Vec3;
use prt_scene::Scene;
use rayon::prelude::*;

/// Largest accepted sub-pixel sample count of a pixel footprint.
pub const MAX_PIXEL_SAMPLES: u32 = 4096;

/// A surface point to bake.
#[derive(Clone, Copy, Debug)]
pub struct SamplePoint {
    /// Position.
    pub position: Vec3,
    /// Unit shading normal (facing the side to bake).
    pub normal: Vec3,
    /// Normal used to move ray origins off the surface (geometric for pixel hits, the vertex
    /// normal for vertices).
    pub offset_normal: Vec3,
    /// Ray-origin offset distance (the tracer's rule).
    pub offset: f32,
}

impl SamplePoint {
    /// Ray origin for direction `dir` (the tracer's offset rule).
    #[must_use]
    pub fn origin(&self, dir: Vec3) -> Vec3 {
        crate::offset_origin(self.position, self.offset_normal, self.offset, dir)
    }
}

/// The vertices of mesh `mesh` as sample points.
#[must_use]
pub fn vertex_points(scene: &Scene, accel: &Accel, mesh: usize) -> Vec<SamplePoint> {
    let m = &scene.meshes[mesh];
    let extent = accel.mesh_extent(mesh);
    m.positions
        .iter()
        .zip(&m.normals)
        .map(|(p, n)| {
            let n = n.normalize_or(Vec3::Y);
            SamplePoint {
                position: *p,
                normal: n,
                offset_normal: n,
                offset: point_offset(*p, extent),
            }
        })
        .collect()
}

/// One sub-pixel sample of a pixel's footprint: the camera ray and what it hits.
#[derive(Clone, Copy, Debug)]
pub struct PixelSample {
    /// Unit direction of the camera ray from the eye.
    pub dir: Vec3,
    /// `(mesh, point)` of the primary hit, `None` when the ray sees the environment. Shading
    /// normals face the camera.
    pub hit: Option<(usize, SamplePoint)>,
    /// Where on its triangle the hit lies (for textured materials), `None` without a hit.
    pub at: Option<prt_scene::SurfacePoint>,
}

/// The box footprints of every camera pixel, `samples_per_pixel` sub-pixel samples each, the
/// same footprint as `prt render`'s box filter (`[x, x+1) × [y, y+1)` in pixel units).
///
/// With one sample per pixel the sample is the pixel centre (the point sampling of earlier
/// bakes). With `K > 1` the positions are the first `K` points of the R2 sequence with a
/// Cranley–Patterson shift keyed by (seed, [`SequencePurpose::Footprint`], pixel): each
/// position is uniformly distributed over the pixel (so averages over them are unbiased
/// estimates of the box-filtered value) and the `K` positions are well stratified for any `K`.
#[derive(Clone, Debug)]
pub struct PixelFootprints {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Sub-pixel samples per pixel, `K ≥ 1`.
    pub samples_per_pixel: u32,
    /// `width × height × K` samples, pixel-major (row-major pixels from the top row, then the
    /// pixel's `K` samples in sequence order).
    pub samples: Vec<PixelSample>,
}

impl PixelFootprints {
    /// The `K` samples of pixel `pixel` (row-major index).
    #[must_use]
    pub fn pixel(&self, pixel: usize) -> &[PixelSample] {
        let k = self.samples_per_pixel as usize;
        &self.samples[pixel * k..(pixel + 1) * k]
    }

    /// Number of pixels.
    #[must_use]
    pub fn pixel_count(&self) -> usize {
        (self.width * self.height) as usize
    }

    /// Whether every sample of pixel `pixel` hits a surface.
    #[must_use]
    pub fn fully_covered(&self, pixel: usize) -> bool {
        self.pixel(pixel).iter().all(|s| s.hit.is_some())
    }
}

/// Sub-pixel position `k` of `K` in pixel `pixel`, in `[0, 1)²` (the centre for `K = 1`).
#[must_use]
pub fn subpixel_position(seed: u64, pixel: u64, k: u32, samples_per_pixel: u32) -> [f64; 2] {
    if samples_per_pixel <= 1 {
        return [0.5, 0.5];
    }
    let p = R2::new(seed, SequencePurpose::Footprint, 0, pixel).get(k);
    [f64::from(p[0]), f64::from(p[1])]
}

/// The footprints of every pixel of the scene camera (see [`PixelFootprints`]).
pub fn pixel_footprints(
    scene: &Scene,
    accel: &Accel,
    seed: u64,
    samples_per_pixel: u32,
) -> Result<PixelFootprints, crate::TracerError> {
    let cam = PinholeCamera::new(&scene.camera)?;
    let (w, h) = (cam.width(), cam.height());
    let k = samples_per_pixel.max(1);
    let eye = cam.eye();
    let total = w as usize * h as usize * k as usize;
    let samples = (0..total)
        .into_par_iter()
        .with_min_len(256)
        .map(|i| {
            let (pixel, j) = ((i / k as usize) as u64, (i % k as usize) as u32);
            let (x, y) = (pixel % u64::from(w), pixel / u64::from(w));
            let [jx, jy] = subpixel_position(seed, pixel, j, k);
            let dir = cam.direction(x as f64 + jx, y as f64 + jy);
            let found = accel.closest_hit(eye, dir, f32::INFINITY);
            let at = found.as_ref().map(|h| prt_scene::SurfacePoint::Triangle {
                tri: h.tri,
                u: h.u,
                v: h.v,
            });
            let hit = found.map(|hit| {
                let mut n = hit.shading_normal;
                let mut ng = hit.geometric_normal;
                if ng.dot(dir) > 0.0 {
                    ng = -ng;
                }
                if n.dot(dir) > 0.0 {
                    n = -n;
                }
                (
                    hit.mesh as usize,
                    SamplePoint {
                        position: hit.position,
                        normal: n,
                        offset_normal: ng,
                        offset: hit.offset,
                    },
                )
            });
            PixelSample { dir, hit, at }
        })
        .collect();
    Ok(PixelFootprints {
        width: w,
        height: h,
        samples_per_pixel: k,
        samples,
    })
}
