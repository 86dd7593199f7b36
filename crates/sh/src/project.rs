//! Projection of environment maps and functions onto the SH basis, and reconstruction.
//!
//! Lat-long maps are projected **exactly** as piecewise-constant functions: for texel
//! `(col, row)` the integral `∫_texel y_i dω` separates, in the map's own polar frame, into an
//! azimuthal integral of `cos mφ` / `sin mφ` (closed form) and a polar integral of
//! `N_l^m(cos θ) sin θ`, a trigonometric polynomial of degree ≤ `order`, integrated by
//! Gauss–Legendre with a node count chosen from the Taylor remainder bound so that the
//! quadrature error is below 1e-18 of the integrand's size (i.e. exact to rounding). The
//! coefficients in the map frame are then turned into world coefficients by the exact SH
//! rotation of the frame change (map pole +Y, seam −Z) and the environment rotation.

use crate::eval::Basis;
use crate::index::{check_len, check_order, coefficient_count, index, ShError, MAX_ORDER};
use crate::quadrature::{gauss_legendre, SphereQuadrature};
use crate::rotate::Rotation;
use glam::{DMat3, DVec3};
use rayon::prelude::*;
use std::f64::consts::PI;

/// Largest [`EnvMapping::Angular`] subsample count per texel side: 64² = 4096 evaluations
/// per texel. Far more (say 10⁹, i.e. 10¹⁸ per texel) would run for ever.
pub const MAX_ANGULAR_SUBSAMPLES: usize = 64;

/// RGB coefficients: `order²` triples in index order.
pub type RgbCoefficients = Vec<[f64; 3]>;

/// How an environment image maps to directions (CONVENTIONS.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EnvMapping {
    /// Equirectangular: row 0 is +Y, `u = 0` looks down −Z, `u = 0.25` down +X.
    LatLong,
    /// Debevec angular probe: centre +Z, rim −Z, `θ = π r`.
    Angular {
        /// Subsamples per texel side (k×k midpoint rule per texel).
        subsamples: usize,
    },
}

/// A borrowed RGB image (row-major, row 0 on top).
#[derive(Clone, Copy, Debug)]
pub struct ImageRef<'a> {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// `width × height` linear RGB texels.
    pub texels: &'a [[f32; 3]],
}

impl ImageRef<'_> {
    fn validate(&self) -> Result<(), ShError> {
        if self.width == 0 || self.height == 0 || self.texels.len() != self.width * self.height {
            return Err(ShError::ImageSize {
                width: self.width,
                height: self.height,
                texels: self.texels.len(),
            });
        }
        for (i, t) in self.texels.iter().enumerate() {
            for (channel, v) in t.iter().enumerate() {
                if !v.is_finite() {
                    return Err(ShError::NonFinite {
                        col: i % self.width,
                        row: i / self.width,
                        channel,
                    });
                }
            }
        }
        Ok(())
    }
}

/// Rotation taking the lat-long map's polar frame (z' = +Y pole, x' = seam −Z, φ' = −φ_map)
/// to world space, before the environment's own rotation about +Y.
#[must_use]
pub fn latlong_frame() -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, 0.0, -1.0),
        DVec3::new(-1.0, 0.0, 0.0),
        DVec3::Y,
    )
}

/// Projects an environment image to `order` bands, with the environment rotated by
/// `rotation_y_deg` about +Y (radiance towards `d` is the map's value at `R_y⁻¹ d`).
pub fn project_env(
    image: ImageRef<'_>,
    mapping: EnvMapping,
    order: usize,
    rotation_y_deg: f64,
) -> Result<RgbCoefficients, ShError> {
    check_order(order, MAX_ORDER)?;
    image.validate()?;
    let env_rotation = DMat3::from_rotation_y(rotation_y_deg.to_radians());
    match mapping {
        EnvMapping::LatLong => {
            let frame_coeffs = project_latlong_frame(image, order);
            let rot = Rotation::new(order, env_rotation * latlong_frame())?;
            Ok(rot.apply_rgb(&frame_coeffs))
        }
        EnvMapping::Angular { subsamples } => {
            if !(1..=MAX_ANGULAR_SUBSAMPLES).contains(&subsamples) {
                return Err(ShError::InvalidParameter(format!(
                    "angular subsamples {subsamples} must be between 1 and \
                     {MAX_ANGULAR_SUBSAMPLES} (the work grows as its square)"
                )));
            }
            let c = project_angular_frame(image, order, subsamples);
            if rotation_y_deg == 0.0 {
                Ok(c)
            } else {
                Ok(Rotation::new(order, env_rotation)?.apply_rgb(&c))
            }
        }
    }
}

/// Gauss–Legendre node count that integrates a trigonometric polynomial of degree `degree`
/// over an interval of length `h` to a relative error below 1e-18: the smallest `n` with
/// `t^{2n} / (2n)! < 1e-18`, `t = degree · h / 2` (Taylor remainder about the midpoint of the
/// terms GL does not integrate exactly).
#[must_use]
pub fn nodes_for_trig_degree(degree: usize, h: f64) -> usize {
    let t = (degree as f64 * h * 0.5).max(1e-300);
    let mut n = 1;
    loop {
        let k = 2 * n;
        let log_term = k as f64 * t.ln() - ln_factorial(k);
        if log_term < (1e-18f64).ln() || n > 4096 {
            return n.max(2);
        }
        n += 1;
    }
}

fn ln_factorial(k: usize) -> f64 {
    (1..=k).map(|i| (i as f64).ln()).sum()
}

/// Exact projection in the map's polar frame.
fn project_latlong_frame(image: ImageRef<'_>, order: usize) -> RgbCoefficients {
    let (w, h) = (image.width, image.height);
    let n2 = coefficient_count(order);
    // Azimuthal integrals per column and m ≥ 0: φ' ∈ [−2π(col+1)/W, −2π col/W].
    let half = PI / w as f64;
    let mut phi_cos = vec![0.0; w * order];
    let mut phi_sin = vec![0.0; w * order];
    for col in 0..w {
        let mid = -2.0 * PI * (col as f64 + 0.5) / w as f64;
        phi_cos[col * order] = 2.0 * half;
        for m in 1..order {
            let mf = m as f64;
            let k = 2.0 * (mf * half).sin() / mf;
            let (s, c) = (mf * mid).sin_cos();
            phi_cos[col * order + m] = c * k;
            phi_sin[col * order + m] = s * k;
        }
    }
    let dtheta = PI / h as f64;
    let nodes = nodes_for_trig_degree(order, dtheta);
    let (gx, gw) = gauss_legendre(nodes);
    let basis = Basis::new(order).expect("order checked");
    let rows: Vec<RgbCoefficients> = (0..h)
        .into_par_iter()
        .map(|row| {
            let t0 = dtheta * row as f64;
            // Polar integrals Θ_l^m = ∫ N_l^m(cos θ) sin θ dθ over the row.
            let mut theta_int = vec![0.0; n2];
            let mut buf = vec![0.0; n2];
            for (x, wq) in gx.iter().zip(&gw) {
                let theta = t0 + 0.5 * dtheta * (x + 1.0);
                let (s, z) = theta.sin_cos();
                basis.legendre().fill_with_sin(z, s, &mut buf);
                let f = wq * 0.5 * dtheta * s;
                for l in 0..order {
                    for m in 0..=l {
                        let i = index(l, m as i64);
                        theta_int[i] += f * buf[i];
                    }
                }
            }
            // Azimuthal sums of the row's texels.
            let mut a = vec![[0.0f64; 3]; order];
            let mut b = vec![[0.0f64; 3]; order];
            let texels = &image.texels[row * w..(row + 1) * w];
            for (col, t) in texels.iter().enumerate() {
                let v = [t[0] as f64, t[1] as f64, t[2] as f64];
                let pc = &phi_cos[col * order..(col + 1) * order];
                let ps = &phi_sin[col * order..(col + 1) * order];
                for m in 0..order {
                    for ch in 0..3 {
                        a[m][ch] += v[ch] * pc[m];
                        b[m][ch] += v[ch] * ps[m];
                    }
                }
            }
            let mut out = vec![[0.0f64; 3]; n2];
            for l in 0..order {
                for m in 0..=l {
                    let th = theta_int[index(l, m as i64)];
                    for ch in 0..3 {
                        out[index(l, m as i64)][ch] += th * a[m][ch];
                        if m > 0 {
                            out[index(l, -(m as i64))][ch] += th * b[m][ch];
                        }
                    }
                }
            }
            out
        })
        .collect();
    sum_in_order(rows, n2)
}

fn sum_in_order(parts: Vec<RgbCoefficients>, n2: usize) -> RgbCoefficients {
    let mut total = vec![[0.0f64; 3]; n2];
    for p in parts {
        for (t, v) in total.iter_mut().zip(p) {
            for ch in 0..3 {
                t[ch] += v[ch];
            }
        }
    }
    total
}

/// Angular probe: each texel integrated by a k×k midpoint rule in `(a, b)` with the Jacobian
/// `dω = π sin(π r)/r da db`; subsamples outside the unit disc contribute nothing.
fn project_angular_frame(image: ImageRef<'_>, order: usize, k: usize) -> RgbCoefficients {
    let (w, h) = (image.width, image.height);
    let n2 = coefficient_count(order);
    let basis = Basis::new(order).expect("order checked");
    let da = 2.0 / w as f64;
    let db = 2.0 / h as f64;
    let area = da * db / (k * k) as f64;
    let rows: Vec<RgbCoefficients> = (0..h)
        .into_par_iter()
        .map(|row| {
            let mut out = vec![[0.0f64; 3]; n2];
            let mut y = vec![0.0; n2];
            for col in 0..w {
                let t = image.texels[row * w + col];
                if t == [0.0; 3] {
                    continue;
                }
                for sy in 0..k {
                    for sx in 0..k {
                        let a = -1.0 + da * (col as f64 + (sx as f64 + 0.5) / k as f64);
                        let b = 1.0 - db * (row as f64 + (sy as f64 + 0.5) / k as f64);
                        let r = (a * a + b * b).sqrt();
                        if r > 1.0 {
                            continue;
                        }
                        let (dir, jac) = if r == 0.0 {
                            (DVec3::Z, PI * PI)
                        } else {
                            let theta = PI * r;
                            let s = theta.sin();
                            (DVec3::new(a / r * s, b / r * s, theta.cos()), PI * s / r)
                        };
                        basis.eval_unchecked(dir, &mut y);
                        let wgt = jac * area;
                        for i in 0..n2 {
                            let f = wgt * y[i];
                            for ch in 0..3 {
                                out[i][ch] += f * t[ch] as f64;
                            }
                        }
                    }
                }
            }
            out
        })
        .collect();
    sum_in_order(rows, n2)
}

/// Projects a scalar function given by a closure with a product rule exact for spherical
/// polynomials up to `degree` (pick `degree ≥ 2·(order−1)` plus the function's own degree;
/// for non-polynomial functions this is a high-order quadrature, not exact).
pub fn project_fn(
    order: usize,
    degree: usize,
    f: impl Fn(DVec3) -> f64,
) -> Result<Vec<f64>, ShError> {
    check_order(order, MAX_ORDER)?;
    let q = SphereQuadrature::exact_for_degree(degree.max(2 * (order - 1)));
    let basis = Basis::new(order)?;
    let n2 = basis.len();
    let mut out = vec![0.0; n2];
    let mut y = vec![0.0; n2];
    for (d, w) in q.dirs.iter().zip(&q.weights) {
        let v = f(*d) * w;
        basis.eval_unchecked(*d, &mut y);
        for i in 0..n2 {
            out[i] += v * y[i];
        }
    }
    Ok(out)
}

/// Reconstructs a lat-long image (texel centres) from RGB coefficients, with the same
/// orientation and rotation convention as [`project_env`].
pub fn reconstruct_latlong(
    coeffs: &[[f64; 3]],
    order: usize,
    width: usize,
    height: usize,
    rotation_y_deg: f64,
) -> Result<Vec<[f32; 3]>, ShError> {
    check_order(order, MAX_ORDER)?;
    check_len(order, coeffs.len())?;
    let basis = Basis::new(order)?;
    let rot = DMat3::from_rotation_y(rotation_y_deg.to_radians());
    let n2 = basis.len();
    let rows: Vec<Vec<[f32; 3]>> = (0..height)
        .into_par_iter()
        .map(|row| {
            let mut y = vec![0.0; n2];
            let theta = PI * (row as f64 + 0.5) / height as f64;
            (0..width)
                .map(|col| {
                    let phi = 2.0 * PI * (col as f64 + 0.5) / width as f64;
                    let map_dir = DVec3::new(
                        phi.sin() * theta.sin(),
                        theta.cos(),
                        -phi.cos() * theta.sin(),
                    );
                    basis.eval_unchecked(rot * map_dir, &mut y);
                    let mut v = [0.0f64; 3];
                    for i in 0..n2 {
                        for ch in 0..3 {
                            v[ch] += coeffs[i][ch] * y[i];
                        }
                    }
                    [v[0] as f32, v[1] as f32, v[2] as f32]
                })
                .collect()
        })
        .collect();
    Ok(rows.into_iter().flatten().collect())
}

/// Reconstructs RGB radiance at one direction.
pub fn reconstruct_rgb(coeffs: &[[f64; 3]], order: usize, dir: DVec3) -> Result<[f64; 3], ShError> {
    check_len(order, coeffs.len())?;
    let y = Basis::new(order)?.eval(dir);
    let mut v = [0.0; 3];
    for (c, y) in coeffs.iter().zip(&y) {
        for ch in 0..3 {
            v[ch] += c[ch] * y;
        }
    }
    Ok(v)
}
