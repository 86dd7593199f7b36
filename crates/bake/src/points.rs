//! The points a bake estimates transfer at: mesh vertices, or the primary hits of the scene
//! camera's pixel centres.

use glam::Vec3;
use prt_scene::Scene;
use prt_tracer::{point_offset, Accel, PinholeCamera};

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
        prt_tracer::offset_origin(self.position, self.offset_normal, self.offset, dir)
    }
}

/// The vertices of mesh `mesh` as sample points.
#[must_use]
pub fn vertex_points(scene: &Scene, accel: &Accel, mesh: usize) -> Vec<SamplePoint> {
    let m = &scene.meshes[mesh];
    let max_abs = accel.max_abs_coordinate();
    m.positions
        .iter()
        .zip(&m.normals)
        .map(|(p, n)| {
            let n = n.normalize_or(Vec3::Y);
            SamplePoint {
                position: *p,
                normal: n,
                offset_normal: n,
                offset: point_offset(*p, max_abs),
            }
        })
        .collect()
}

/// The primary hit of every pixel centre: `(mesh, point, barycentric hit)` or `None` for
/// background pixels, row-major from the top row. Shading normals face the camera.
pub fn pixel_points(
    scene: &Scene,
    accel: &Accel,
) -> Result<Vec<Option<(usize, SamplePoint)>>, prt_tracer::TracerError> {
    let cam = PinholeCamera::new(&scene.camera)?;
    let (w, h) = (cam.width(), cam.height());
    let eye = cam.eye();
    let mut out = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let dir = cam.direction(f64::from(x) + 0.5, f64::from(y) + 0.5);
            out.push(accel.closest_hit(eye, dir, f32::INFINITY).map(|hit| {
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
            }));
        }
    }
    Ok(out)
}
