//! The sRGB curve of every 8-bit view prt writes (CONVENTIONS.md: radiance × 2^EV, clamped to
//! [0, 1], sRGB, 8 bits), and of the noise ceilings measured on that view.

use glam::Vec3;

/// The sRGB transfer curve of a linear value in [0, 1].
#[must_use]
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= 0.003_130_8 {
        12.92 * linear
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    }
}

/// The 8-bit sRGB view of linear radiance: `× 2^exposure_ev`, clamp to [0, 1], sRGB, round.
#[must_use]
pub fn to_srgb8(radiance: &[Vec3], exposure_ev: f32) -> Vec<u8> {
    let k = exposure_ev.exp2();
    radiance
        .iter()
        .flat_map(|l| l.to_array())
        .map(|x| {
            let x = if x.is_nan() {
                0.0
            } else {
                (x * k).clamp(0.0, 1.0)
            };
            (srgb_encode(x) * 255.0 + 0.5).floor() as u8
        })
        .collect()
}
