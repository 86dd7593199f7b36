//! Environment-map parametrisations of CONVENTIONS.md and piecewise-constant lookup.
//!
//! Both mappings are exact inverses of each other up to rounding; lookup returns the texel
//! whose region contains the direction (no filtering), which is the function that importance
//! sampling and SH projection use too.

use crate::{EnvImage, Environment, Mapping, Rgb};
use glam::{DMat3, DVec3, Vec3};
use std::f64::consts::{PI, TAU};

/// Lat-long `(u, v)` in `[0,1)×[0,1]` of a unit direction: `u = atan2(x, -z)/2π`, `v = acos(y)/π`.
#[must_use]
pub fn latlong_uv(d: DVec3) -> (f64, f64) {
    let mut u = d.x.atan2(-d.z) / TAU;
    if u < 0.0 {
        u += 1.0;
    }
    if u >= 1.0 {
        u = 0.0;
    }
    let v = d.y.clamp(-1.0, 1.0).acos() / PI;
    (u, v)
}

/// Unit direction of lat-long angles `φ = 2πu`, `θ = πv`: `(sin φ sin θ, cos θ, −cos φ sin θ)`.
#[must_use]
pub fn latlong_direction(phi: f64, theta: f64) -> DVec3 {
    let (sp, cp) = phi.sin_cos();
    let (st, ct) = theta.sin_cos();
    DVec3::new(sp * st, ct, -cp * st)
}

/// Angular-probe coordinates `(a, b)` in the unit disc of a unit direction (centre +Z, rim −Z).
#[must_use]
pub fn angular_ab(d: DVec3) -> (f64, f64) {
    let r = d.z.clamp(-1.0, 1.0).acos() / PI;
    let h = (d.x * d.x + d.y * d.y).sqrt();
    if h <= 0.0 {
        // On the axis: centre for +Z; any rim point for -Z (choose (r, 0)).
        return (r, 0.0);
    }
    (r * d.x / h, r * d.y / h)
}

/// Unit direction of angular-probe coordinates `(a, b)`; `None` outside the unit disc.
#[must_use]
pub fn angular_direction(a: f64, b: f64) -> Option<DVec3> {
    let r = (a * a + b * b).sqrt();
    if r > 1.0 {
        return None;
    }
    if r == 0.0 {
        return Some(DVec3::Z);
    }
    let theta = PI * r;
    let s = theta.sin();
    Some(DVec3::new(a / r * s, b / r * s, theta.cos()))
}

/// Rotation matrix about +Y by `deg` degrees (right-handed).
#[must_use]
pub fn rotation_y(deg: f64) -> DMat3 {
    DMat3::from_rotation_y(deg.to_radians())
}

impl EnvImage {
    /// Texel index `(col, row)` containing lat-long direction `d` (map frame).
    #[must_use]
    pub fn latlong_texel(&self, d: DVec3) -> (usize, usize) {
        let (u, v) = latlong_uv(d);
        let col = ((u * self.width as f64) as usize).min(self.width - 1);
        let row = ((v * self.height as f64) as usize).min(self.height - 1);
        (col, row)
    }

    /// Texel index `(col, row)` containing angular-probe direction `d` (map frame).
    #[must_use]
    pub fn angular_texel(&self, d: DVec3) -> (usize, usize) {
        let (a, b) = angular_ab(d);
        // a = 2(col+0.5)/W - 1  =>  col = floor((a+1) W / 2)
        let col =
            (((a + 1.0) * 0.5 * self.width as f64).floor().max(0.0) as usize).min(self.width - 1);
        let row =
            (((1.0 - b) * 0.5 * self.height as f64).floor().max(0.0) as usize).min(self.height - 1);
        (col, row)
    }

    /// The texel at `(col, row)`.
    #[must_use]
    pub fn texel(&self, col: usize, row: usize) -> Rgb {
        self.texels[row * self.width + col]
    }
}

impl Environment {
    /// Direction in the map's own frame for a world direction (undoes `rotation_y`).
    #[must_use]
    pub fn to_map_frame(&self, world: DVec3) -> DVec3 {
        if self.rotation_y_deg == 0.0 {
            world
        } else {
            rotation_y(-self.rotation_y_deg) * world
        }
    }

    /// World direction of a map-frame direction (applies `rotation_y`).
    #[must_use]
    pub fn to_world(&self, map: DVec3) -> DVec3 {
        if self.rotation_y_deg == 0.0 {
            map
        } else {
            rotation_y(self.rotation_y_deg) * map
        }
    }

    /// Radiance arriving from world direction `d` (unit): the piecewise-constant texel value.
    #[must_use]
    pub fn radiance(&self, d: Vec3) -> Rgb {
        let m = self.to_map_frame(d.as_dvec3());
        let (c, r) = match self.mapping {
            Mapping::LatLong => self.image.latlong_texel(m),
            Mapping::Angular => self.image.angular_texel(m),
        };
        self.image.texel(c, r)
    }
}
