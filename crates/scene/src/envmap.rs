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
        let col = cell_index(u * self.width as f64, self.width);
        let row = cell_index(v * self.height as f64, self.height);
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

/// Fast exact texel lookup and in-texel directions of a `W × H` lat-long map.
///
/// [`EnvImage::latlong_texel`] pays an f64 `atan2` and `acos` per direction, which a path
/// tracer calls for every camera ray that escapes and every BRDF sample. This grid keeps the
/// texels' edges instead — `cos θ_r` of the row edges `θ_r = πr/H` and `(cos φ_c, sin φ_c)` of
/// the column edges `φ_c = 2πc/W` — guesses the texel from cheap polynomial approximations
/// of `acos` and `atan2` (Abramowitz & Stegun 4.4.45 and 4.4.49, errors below 7e-5 rad) and
/// then settles it by exact comparisons against the edges: `cos θ_{r+1} < y ≤ cos θ_r` for the
/// row, and the sign of the cross product of `(−z, x)` with the column edges for the column.
/// The approximations only choose where the comparisons start, so the texel is the one whose
/// (rounded) edges bound the direction, the same as `latlong_texel` except within an f64
/// rounding of an edge. [`LatLongGrid::direction`] turns a texel and a position inside it,
/// uniform in `φ` and `cos θ`, into a direction that this lookup puts back in that texel, with
/// `φ`'s sine and cosine from the column edge rotated by a short Taylor series instead of a
/// libm call.
#[derive(Clone, Debug)]
pub struct LatLongGrid {
    width: usize,
    height: usize,
    /// `cos(πr/H)` for `r = 0..=H` (decreasing from 1 to −1).
    row_cos: Vec<f64>,
    /// `(cos φ_c, sin φ_c)` for `c = 0..W`.
    col_edge: Vec<[f64; 2]>,
}

/// Below this width the column walk's half-plane tests could span more than half a turn, and
/// the rotation's series more than `2π/16`: such maps use the libm formulas.
const GRID_MIN_WIDTH: usize = 16;

/// `(x as usize).min(n - 1)`, the cell of a scaled coordinate, for `1 ≤ n ≤ 2³²`: the same
/// value for every `x` (both casts truncate, send NaN and negatives to 0 and saturate above),
/// through a 32-bit conversion. Rust's saturating `f64`-to-`usize` cast takes about fifteen
/// instructions on x86-64 (no unsigned 64-bit conversion before AVX-512), the `u32` one five;
/// texel and table lookups take two per sample.
#[must_use]
#[inline]
pub fn cell_index(x: f64, n: usize) -> usize {
    debug_assert!(n >= 1 && n - 1 <= u32::MAX as usize);
    (x as u32 as usize).min(n - 1)
}

/// `acos(y)` to within 6.7e-5 rad (Abramowitz & Stegun 4.4.45), for `y ∈ [−1, 1]`.
fn acos_guess(y: f64) -> f64 {
    let a = y.abs();
    let r = (1.0 - a).max(0.0).sqrt()
        * (1.570_728_8 + a * (-0.212_114_4 + a * (0.074_261_0 - a * 0.018_729_3)));
    if y < 0.0 {
        PI - r
    } else {
        r
    }
}

/// `atan2(y, x)` in `[0, 2π)` to within about 1e-5 rad (Abramowitz & Stegun 4.4.49 on
/// `[0, 1]`, then the octant), for `(x, y) ≠ 0`.
fn atan2_guess(y: f64, x: f64) -> f64 {
    let (ax, ay) = (x.abs(), y.abs());
    let t = ax.min(ay) / ax.max(ay);
    let t2 = t * t;
    let mut a = t
        * (0.999_866_0
            + t2 * (-0.330_299_5 + t2 * (0.180_141_0 + t2 * (-0.085_133_0 + t2 * 0.020_835_1))));
    if ay > ax {
        a = std::f64::consts::FRAC_PI_2 - a;
    }
    if x < 0.0 {
        a = PI - a;
    }
    if y < 0.0 {
        a = TAU - a;
    }
    a
}

/// `(sin δ, cos δ)` for `0 ≤ δ ≤ 2π/16` by Taylor series to `δ¹³` and `δ¹⁴` (truncation below
/// 1e-15 there), in Horner form with the reciprocal factorials as constants (no division).
fn small_sin_cos(d: f64) -> (f64, f64) {
    const S: [f64; 6] = [
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
    ];
    const C: [f64; 7] = [
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
        -1.0 / 87_178_291_200.0,
    ];
    let d2 = d * d;
    let s = d * (1.0 + d2 * S.iter().rev().fold(0.0, |acc, &k| k + d2 * acc));
    let c = 1.0 + d2 * C.iter().rev().fold(0.0, |acc, &k| k + d2 * acc);
    (s, c)
}

impl LatLongGrid {
    /// The grid of a `width × height` map (both at least 1).
    #[must_use]
    pub fn new(width: usize, height: usize) -> Self {
        let (w, h) = (width.max(1), height.max(1));
        Self {
            width: w,
            height: h,
            row_cos: (0..=h).map(|r| (PI * r as f64 / h as f64).cos()).collect(),
            col_edge: (0..w)
                .map(|c| {
                    let (s, co) = (TAU * c as f64 / w as f64).sin_cos();
                    [co, s]
                })
                .collect(),
        }
    }

    /// `cos θ` at the row edges, `cos(πr/H)` for `r = 0..=H`.
    #[must_use]
    pub fn row_cos(&self) -> &[f64] {
        &self.row_cos
    }

    /// The row whose edges bound `cos θ = y`: `cos θ_{r+1} < y ≤ cos θ_r` (row 0 holds `y = 1`,
    /// the last row `y = −1`).
    #[must_use]
    pub fn row(&self, y: f64) -> usize {
        let h = self.height;
        let y = y.clamp(-1.0, 1.0);
        let mut r = cell_index(acos_guess(y) * (h as f64 / PI), h);
        while r > 0 && y > self.row_cos[r] {
            r -= 1;
        }
        while r + 1 < h && y <= self.row_cos[r + 1] {
            r += 1;
        }
        r
    }

    /// Whether the point `(px, py)` of the `(−z, x)` plane lies at or counter-clockwise of
    /// column edge `c` (within half a turn).
    #[inline]
    fn after_edge(&self, c: usize, px: f64, py: f64) -> bool {
        let [ec, es] = self.col_edge[c];
        ec * py - es * px >= 0.0
    }

    /// The column whose edges bound `φ = atan2(x, −z)` taken in `[0, 2π)`.
    #[must_use]
    pub fn column(&self, x: f64, z: f64) -> usize {
        let w = self.width;
        let (px, py) = (-z, x);
        if w < GRID_MIN_WIDTH || (px == 0.0 && py == 0.0) || !(px.is_finite() && py.is_finite()) {
            let (u, _) = latlong_uv(DVec3::new(x, 0.0, z));
            return cell_index(u * w as f64, w);
        }
        let mut c = cell_index(atan2_guess(py, px) * (w as f64 / TAU), w);
        // The guess is within a column of the answer for any width below 60 000; the walk
        // needs no bound for correctness, only the loop guard.
        for _ in 0..w {
            if !self.after_edge(c, px, py) {
                c = if c == 0 { w - 1 } else { c - 1 };
                continue;
            }
            let next = if c + 1 == w { 0 } else { c + 1 };
            // Column `W − 1` ends at `φ = 2π`, where column 0 starts again: a point past edge 0
            // with `sin φ ≥ 0` is in column 0, a point with `sin φ < 0` still in column W − 1.
            let past_next = if next == 0 {
                py >= 0.0
            } else {
                self.after_edge(next, px, py)
            };
            if !past_next {
                break;
            }
            c = next;
        }
        c
    }

    /// `(col, row)` of the texel holding unit direction `d` (map frame).
    #[must_use]
    pub fn texel(&self, d: DVec3) -> (usize, usize) {
        (self.column(d.x, d.z), self.row(d.y))
    }

    /// The direction at `rem ∈ [0, 1)²` inside texel `(col, row)`, uniform in `φ` and `cos θ`
    /// over the texel (so uniform in solid angle); `map` frame, unit length up to rounding.
    #[must_use]
    pub fn direction(&self, col: usize, row: usize, rem: [f64; 2]) -> DVec3 {
        let (c0, c1) = (self.row_cos[row], self.row_cos[row + 1]);
        let cos_t = (c0 + rem[1] * (c1 - c0)).clamp(-1.0, 1.0);
        let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
        let (sp, cp) = if self.width < GRID_MIN_WIDTH {
            (TAU * (col as f64 + rem[0]) / self.width as f64).sin_cos()
        } else {
            let (sd, cd) = small_sin_cos(TAU * rem[0] / self.width as f64);
            let [ec, es] = self.col_edge[col];
            (es * cd + ec * sd, ec * cd - es * sd)
        };
        DVec3::new(sp * sin_t, cos_t, -cp * sin_t)
    }
}

#[cfg(test)]
mod tests {
    use super::cell_index;

    /// The 32-bit path gives what the plain cast gives, for the values where casts differ:
    /// NaN, infinities, negatives, values at and around integers and around `2³¹`, `2³²`
    /// and `2⁶⁴`, for cell counts from 1 to `2³²`.
    #[test]
    fn cell_index_is_the_usize_cast() {
        let mut xs = vec![
            f64::NAN,
            -f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::MAX,
            f64::MIN,
            f64::MIN_POSITIVE,
            -0.0,
            0.0,
            1e300,
            -1e300,
        ];
        for k in [
            0.0,
            1.0,
            2.0,
            31.0,
            32.0,
            63.0,
            64.0,
            2f64.powi(31),
            2f64.powi(32),
            2f64.powi(64),
        ] {
            for d in [-1.0, -0.5, -f64::EPSILON, 0.0, f64::EPSILON, 0.5, 1.0] {
                xs.push(k + d * k.max(1.0) * f64::EPSILON);
                xs.push(k + d);
                xs.push(-(k + d));
            }
        }
        for n in [
            1usize,
            2,
            31,
            32,
            64,
            1 << 20,
            1 << 31,
            (1 << 32) - 1,
            1 << 32,
        ] {
            for &x in &xs {
                assert_eq!(
                    cell_index(x, n),
                    (x as usize).min(n - 1),
                    "x = {x:e}, n = {n}"
                );
            }
        }
    }
}
