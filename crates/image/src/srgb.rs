//! The sRGB curve (IEC 61966-2-1) and the 8-bit view of CONVENTIONS.md "Colour and images":
//! radiance × 2^EV, clamped to [0, 1], the sRGB curve, 8 bits. One curve, written once: its
//! constants are below, evaluated in f64 ([`srgb_oetf`], [`ldr_value`]: the comparison's
//! PSNR and the report's views) or in f32 ([`srgb_encode`], [`to_srgb8`]: the PNG views of
//! `prt render` and `prt relight` and the noise ceilings measured on them, and the glTF
//! export's re-encoded textures). The two evaluations of the same formula may round a value
//! to neighbouring 8-bit codes (a test bounds that to one code).

use crate::image::Image;

/// Linear values at or below this are encoded by the linear segment.
pub const LINEAR_KNEE: f64 = 0.003_130_8;
/// Encoded values at or below this are decoded by the linear segment (`12.92 × LINEAR_KNEE`).
pub const ENCODED_KNEE: f64 = 0.040_45;
/// The slope of the linear segment.
pub const LINEAR_SLOPE: f64 = 12.92;
/// The exponent of the power segment.
pub const GAMMA: f64 = 2.4;
/// The offset `a` of the power segment `(1 + a) x^(1/γ) − a`.
pub const OFFSET: f64 = 0.055;

/// The sRGB electro-optical transfer function (IEC 61966-2-1): encoded value in [0, 1] → linear.
///
/// `v ≤ 0.04045 → v / 12.92`, otherwise `((v + 0.055) / 1.055)^2.4`.
#[must_use]
pub fn srgb_eotf(encoded: f64) -> f64 {
    if encoded <= ENCODED_KNEE {
        encoded / LINEAR_SLOPE
    } else {
        ((encoded + OFFSET) / (1.0 + OFFSET)).powf(GAMMA)
    }
}

/// The sRGB opto-electronic transfer function (the inverse of [`srgb_eotf`]): linear in [0, 1] →
/// encoded.
///
/// `x ≤ 0.0031308 → 12.92 x`, otherwise `1.055 x^(1/2.4) − 0.055`.
#[must_use]
pub fn srgb_oetf(linear: f64) -> f64 {
    if linear <= LINEAR_KNEE {
        LINEAR_SLOPE * linear
    } else {
        (1.0 + OFFSET) * linear.powf(1.0 / GAMMA) - OFFSET
    }
}

/// One linear value in the 8-bit PNG view of CONVENTIONS "Colour and images": scale by
/// `2^exposure_ev`, clamp to [0, 1], apply the sRGB curve, round to the nearest of 0…255
/// (halves away from zero). Computed in f64.
#[must_use]
pub fn ldr_value(linear: f32, exposure_ev: f64) -> u8 {
    let scaled = f64::from(linear) * exposure_ev.exp2();
    let clamped = if scaled.is_nan() {
        0.0
    } else {
        scaled.clamp(0.0, 1.0)
    };
    // In [0, 255] after the clamp, so the cast cannot truncate.
    (srgb_oetf(clamped) * 255.0).round() as u8
}

/// The 8-bit sRGB PNG view of an image: [`ldr_value`] of every channel, row-major RGB bytes.
#[must_use]
pub fn ldr_view(image: &Image, exposure_ev: f64) -> Vec<[u8; 3]> {
    image
        .pixels
        .iter()
        .map(|p| p.map(|v| ldr_value(v, exposure_ev)))
        .collect()
}

/// [`srgb_oetf`] evaluated in f32 (the constants rounded to f32): linear in [0, 1] → encoded.
#[must_use]
pub fn srgb_encode(linear: f32) -> f32 {
    if linear <= LINEAR_KNEE as f32 {
        LINEAR_SLOPE as f32 * linear
    } else {
        (1.0 + OFFSET) as f32 * linear.powf((1.0 / GAMMA) as f32) - OFFSET as f32
    }
}

/// The 8-bit view of linear radiance in f32, as `prt render` and `prt relight` write their
/// PNGs: `× 2^exposure_ev`, clamp to [0, 1] (NaN to 0), [`srgb_encode`], `⌊255 v + ½⌋`;
/// row-major RGB bytes.
#[must_use]
pub fn to_srgb8(radiance: &[[f32; 3]], exposure_ev: f32) -> Vec<u8> {
    let k = exposure_ev.exp2();
    radiance
        .iter()
        .flatten()
        .map(|&x| {
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
        // The two pieces meet at the knee (continuity to f32 rounding).
        let t = 0.003_130_8f32;
        assert!((12.92 * t - (1.055 * t.powf(1.0 / 2.4) - 0.055)).abs() < 1e-6);
        // Mid grey: 0.214041… encodes to 0.5 (IEC 61966-2-1).
        assert!((srgb_encode(0.214_041_14) - 0.5).abs() < 1e-6);
        assert!((srgb_oetf(0.214_041_140_482_232_5) - 0.5).abs() < 1e-15);
        // The decoding knee is the encoding knee's image.
        assert!((LINEAR_SLOPE * LINEAR_KNEE - ENCODED_KNEE).abs() < 1e-6);
        for k in 0..=255 {
            let v = f64::from(k) / 255.0;
            assert!((srgb_oetf(srgb_eotf(v)) - v).abs() < 1e-12, "code {k}");
        }
    }

    #[test]
    fn the_8_bit_view_applies_exposure_clamps_and_rounds() {
        let px = [[0.5, -1.0, 2.0], [0.107_020_57, 0.0, 1.0]];
        // +1 EV doubles: 0.5 → 1.0 → 255; negative → 0; above 1 → 255.
        assert_eq!(to_srgb8(&px[..1], 1.0), [255, 0, 255]);
        // At 0 EV, 0.107… is half of mid grey's linear value; at +1 EV it is mid grey: 128.
        assert_eq!(to_srgb8(&px[1..], 1.0)[0], 128);
        assert_eq!(to_srgb8(&px[1..], 0.0)[1..], [0, 255]);
        assert_eq!(to_srgb8(&[[f32::NAN; 3]], 0.0), [0, 0, 0]);
    }

    /// The f32 and f64 evaluations of the one curve give the same 8-bit code, or a neighbour
    /// where the value lies within f32 rounding of a half code, over a dense sweep of [0, 1].
    #[test]
    fn the_f32_and_f64_views_differ_by_at_most_one_code() {
        let mut differ = 0;
        for i in 0..=1_000_000u32 {
            let x = i as f32 / 1_000_000.0;
            let a = to_srgb8(&[[x; 3]], 0.0)[0];
            let b = ldr_value(x, 0.0);
            assert!(a.abs_diff(b) <= 1, "x = {x}: {a} against {b}");
            differ += usize::from(a != b);
        }
        assert!(differ < 100, "{differ} of 10^6 values round differently");
    }
}
