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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_srgb_curve_meets_its_closed_form() {
        assert_eq!(srgb_encode(0.0), 0.0);
        assert!((srgb_encode(1.0) - 1.0).abs() < 1e-6);
        // The two pieces meet at the threshold (continuity to f32 rounding).
        let t = 0.003_130_8f32;
        assert!((12.92 * t - (1.055 * t.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
        // Mid grey: 0.214041… encodes to 0.5 (IEC 61966-2-1).
        assert!((srgb_encode(0.214_041_14) - 0.5).abs() < 1e-6);
    }

    #[test]
    fn the_8_bit_view_applies_exposure_clamps_and_rounds() {
        let px = [Vec3::new(0.5, -1.0, 2.0), Vec3::new(0.107_020_57, 0.0, 1.0)];
        // +1 EV doubles: 0.5 → 1.0 → 255; negative → 0; above 1 → 255.
        assert_eq!(to_srgb8(&px[..1], 1.0), [255, 0, 255]);
        // At 0 EV, 0.107… is half of mid grey's linear value; at +1 EV it is mid grey: 128.
        assert_eq!(to_srgb8(&px[1..], 1.0)[0], 128);
        assert_eq!(to_srgb8(&px[1..], 0.0)[1..], [0, 255]);
    }
}
