//! The environment as a ray that hits nothing sees it, turned about +Y: its own small file so
//! that image formation and the SHRM path's occlusion (which image formation calls through
//! relighting) can both read it without importing each other.

use glam::{DMat3, Vec3};
use prt_scene::Scene;

/// Environment radiance seen along `dir` with an extra rotation about +Y (degrees).
pub fn background_radiance(scene: &Scene, dir: Vec3, rotate_y_deg: f64) -> [f32; 3] {
    let d = if rotate_y_deg == 0.0 {
        dir
    } else {
        (DMat3::from_rotation_y(-rotate_y_deg.to_radians()) * dir.as_dvec3()).as_vec3()
    };
    scene.environment.radiance(d)
}
