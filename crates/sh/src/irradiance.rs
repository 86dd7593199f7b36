//! Irradiance from SH radiance: Ramamoorthi & Hanrahan's 9-coefficient quadratic form
//! ("An Efficient Representation for Irradiance Environment Maps", SIGGRAPH 2001) and, at any
//! order, convolution with the clamped cosine (`E = Σ A_l L_lm y_lm(n)`).

use crate::eval::Basis;
use crate::index::{check_len, index, ShError};
use crate::zonal::{clamped_cosine_bands, convolve_bands_rgb};
use glam::DVec3;

/// Constants of the quadratic form (Ramamoorthi & Hanrahan 2001, eq. 13).
pub const RH_C: [f64; 5] = [0.429043, 0.511664, 0.743125, 0.886227, 0.247708];

/// Irradiance at unit normal `n` from the first 9 RGB radiance coefficients, by the quadratic
/// form of Ramamoorthi & Hanrahan. Their basis has no Condon–Shortley phase, so the
/// coefficients with odd `|m|` change sign on the way in. The constants are rounded to six
/// digits in the paper; [`irradiance`] at order 3 is the exact counterpart.
pub fn irradiance_rh9(radiance: &[[f64; 3]], n: DVec3) -> Result<[f64; 3], ShError> {
    if radiance.len() < 9 {
        return Err(ShError::BufferLength {
            order: 3,
            expected: 9,
            got: radiance.len(),
        });
    }
    let n = n.normalize();
    let (x, y, z) = (n.x, n.y, n.z);
    let [c1, c2, c3, c4, c5] = RH_C;
    let mut e = [0.0; 3];
    for ch in 0..3 {
        let l = |l: usize, m: i64| {
            let v = radiance[index(l, m)][ch];
            if m.abs() % 2 == 1 {
                -v
            } else {
                v
            }
        };
        e[ch] = c1 * l(2, 2) * (x * x - y * y) + c3 * l(2, 0) * z * z + c4 * l(0, 0) - c5 * l(2, 0)
            + 2.0 * c1 * (l(2, -2) * x * y + l(2, 1) * x * z + l(2, -1) * y * z)
            + 2.0 * c2 * (l(1, 1) * x + l(1, -1) * y + l(1, 0) * z);
    }
    Ok(e)
}

/// SH coefficients of the irradiance function: radiance convolved with the clamped cosine.
pub fn irradiance_coefficients(
    radiance: &[[f64; 3]],
    order: usize,
) -> Result<Vec<[f64; 3]>, ShError> {
    check_len(order, radiance.len())?;
    convolve_bands_rgb(radiance, &clamped_cosine_bands(order)?)
}

/// Irradiance `∫ L(ω) max(0, n·ω) dω` at unit normal `n` for band-limited radiance of `order`.
pub fn irradiance(radiance: &[[f64; 3]], order: usize, n: DVec3) -> Result<[f64; 3], ShError> {
    let e = irradiance_coefficients(radiance, order)?;
    let y = Basis::new(order)?.eval(n);
    let mut out = [0.0; 3];
    for (c, y) in e.iter().zip(&y) {
        for ch in 0..3 {
            out[ch] += c[ch] * y;
        }
    }
    Ok(out)
}
