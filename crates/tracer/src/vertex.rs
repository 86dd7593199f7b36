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
    /// Whether `ns` comes from a normal map (its side then follows `ng`'s, see
    /// [`Vertex::oriented`]).
    pub mapped: bool,
    /// Radiance the surface emits (glTF emission; zero for most surfaces).
    pub le: Vec3,
    /// Spawn offset along `ng`.
    pub offset: f32,
    /// The BRDF.
    pub mat: Material,
}

impl Vertex {
    /// `(ng, ns)` turned towards `wo`. An interpolated shading normal is flipped on its own
    /// (CONVENTIONS.md). A normal-mapped one is flipped with the geometric normal (the side
    /// of the surface that is seen decides, as glTF's double-sided rule does), and if it then
    /// still faces away from `wo` — a bump seen from behind its slope — it is bent towards
    /// `wo` in the plane of `ns` and `wo` until `ns·wo = MAPPED_MIN_COS`, the smallest change
    /// that makes the view direction valid (Mitsuba 3 and pbrt-v4 instead leave such a
    /// point black or lit from below; bending keeps the image free of black speckles on
    /// steep bumps and is continuous where the normal map is).
    pub(crate) fn oriented(&self, wo: Vec3) -> (Vec3, Vec3) {
        if self.mapped {
            let (ng, ns) = if self.ng.dot(wo) < 0.0 {
                (-self.ng, -self.ns)
            } else {
                (self.ng, self.ns)
            };
            return (ng, bend_towards(ns, wo));
        }
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

/// The smallest cosine allowed between a normal-mapped shading normal and the view direction.
pub(crate) const MAPPED_MIN_COS: f32 = 0.01;

/// `ns` if `ns·wo ≥ MAPPED_MIN_COS`, else the unit vector of the plane of `ns` and `wo` at
/// that cosine from `wo`, on `ns`'s side (`wo` itself if `ns` is `−wo`).
fn bend_towards(ns: Vec3, wo: Vec3) -> Vec3 {
    let c = ns.dot(wo);
    if c >= MAPPED_MIN_COS {
        return ns;
    }
    let perp = (ns - wo * c).normalize_or_zero();
    if perp == Vec3::ZERO {
        return wo;
    }
    let sin = (1.0 - MAPPED_MIN_COS * MAPPED_MIN_COS).sqrt();
    (perp * sin + wo * MAPPED_MIN_COS).normalize()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mapped_normal_facing_away_is_bent_to_the_view() {
        let wo = Vec3::new(0.0, 0.6, 0.8);
        let ns = Vec3::new(0.0, -0.8, 0.6);
        let b = bend_towards(ns, wo);
        assert!((b.dot(wo) - MAPPED_MIN_COS).abs() < 1e-6, "{b}");
        assert!((b.length() - 1.0).abs() < 1e-6);
        assert!(
            b.cross(wo).dot(ns.cross(wo)) > 0.0,
            "stays on ns's side of wo"
        );
        assert_eq!(bend_towards(wo, wo), wo);
        assert_eq!(bend_towards(-wo, wo), wo);
    }
}
