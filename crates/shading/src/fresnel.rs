//! Fresnel reflectance of a smooth dielectric interface.

/// s- and p-polarised amplitude reflection coefficients `(r_s, r_p)` for light arriving at
/// `cos_i` on an interface of relative index `ior` (Hecht, Optics, §4.6). Returns `None` under
/// total internal reflection (possible only for `ior < 1`).
#[must_use]
pub fn fresnel_amplitudes(cos_i: f32, ior: f32) -> Option<(f32, f32)> {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (ior * ior);
    if sin2_t >= 1.0 {
        return None;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - ior * cos_t) / (cos_i + ior * cos_t);
    let rp = (ior * cos_i - cos_t) / (ior * cos_i + cos_t);
    Some((rs, rp))
}

/// Exact unpolarised dielectric Fresnel reflectance `(r_s² + r_p²)/2` (ior relative, cos_i ≥ 0).
/// Returns 1 under total internal reflection.
#[must_use]
pub fn fresnel_dielectric(cos_i: f32, ior: f32) -> f32 {
    match fresnel_amplitudes(cos_i, ior) {
        Some((rs, rp)) => 0.5 * (rs * rs + rp * rp),
        None => 1.0,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn normal_incidence_matches_closed_form() {
        for ior in [1.0f32, 1.33, 1.5, 2.4, 0.7] {
            let expect = ((ior - 1.0) / (ior + 1.0)).powi(2);
            assert!(
                (fresnel_dielectric(1.0, ior) - expect).abs() < 1e-6,
                "{ior}"
            );
        }
    }

    #[test]
    fn brewster_angle_zeroes_p_component() {
        for ior in [1.33f32, 1.5, 2.4] {
            let theta_b = ior.atan();
            let (rs, rp) = fresnel_amplitudes(theta_b.cos(), ior).unwrap();
            assert!(rp.abs() < 1e-5, "ior {ior}: r_p = {rp}");
            assert!(rs.abs() > 0.1);
            // F there is r_s²/2 only.
            assert!((fresnel_dielectric(theta_b.cos(), ior) - 0.5 * rs * rs).abs() < 1e-6);
        }
    }

    #[test]
    fn grazing_is_one_and_monotone_from_outside() {
        for ior in [1.2f32, 1.5, 3.0] {
            assert!((fresnel_dielectric(0.0, ior) - 1.0).abs() < 1e-6);
            let mut prev = fresnel_dielectric(1.0, ior);
            for k in (0..1000).rev() {
                let f = fresnel_dielectric(k as f32 / 1000.0, ior);
                assert!(f >= prev - 1e-6 && f <= 1.0, "F must grow towards grazing");
                prev = f;
            }
        }
        // Total internal reflection from inside a denser medium (relative index < 1).
        let critical = (1.0f32 / 1.5).asin();
        assert_eq!(fresnel_dielectric((critical + 0.01).cos(), 1.0 / 1.5), 1.0);
        assert!(fresnel_dielectric((critical - 0.01).cos(), 1.0 / 1.5) < 1.0);
    }
}
