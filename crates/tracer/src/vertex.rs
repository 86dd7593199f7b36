//! A surface point being shaded by the path tracer.

use crate::accel::offset_origin;
use glam::Vec3;
use prt_scene::Material;

/// A surface point being shaded.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Vertex {
    /// Position.
    pub p: Vec3,
    /// Unit geometric normal (any orientation).
    pub ng: Vec3,
    /// Unit shading normal (any orientation).
    pub ns: Vec3,
    /// Spawn offset along `ng`.
    pub offset: f32,
    /// The BRDF.
    pub mat: Material,
}

impl Vertex {
    /// `(ng, ns)` turned towards `wo`.
    pub(crate) fn oriented(&self, wo: Vec3) -> (Vec3, Vec3) {
        let ng = if self.ng.dot(wo) < 0.0 {
            -self.ng
        } else {
            self.ng
        };
        let ns = if self.ns.dot(wo) < 0.0 {
            -self.ns
        } else {
            self.ns
        };
        (ng, ns)
    }

    pub(crate) fn spawn(&self, ng: Vec3, dir: Vec3) -> Vec3 {
        offset_origin(self.p, ng, self.offset, dir)
    }
}
