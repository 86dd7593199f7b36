//! Closed-form and consistency checks of the BRDFs: pdf normalisation, sample weights,
//! reciprocity, directional albedo against closed forms, white-furnace estimates, and the
//! lobe-splitting estimator.

mod common;
use common::*;
use glam::Vec3;
use prt_scene::Material;
use prt_shading::*;
use rand::{Rng, SeedableRng};

fn all_materials() -> Vec<Material> {
    let mut v = vec![
        Material::Lambert {
            albedo: [0.8, 0.5, 0.2],
        },
        Material::Mirror {
            albedo: grey(0.4),
            specular: grey(0.5),
        },
    ];
    for e in [1.0, 20.0, 500.0] {
        v.push(phong(0.3, 0.6, e));
    }
    for e in [1.0, 50.0, 2000.0] {
        v.push(blinn(0.3, 0.6, e));
    }
    for a in [0.05, 0.3] {
        v.push(ward(0.3, 0.6, a));
    }
    for m in [0.05, 0.3, 0.8] {
        v.push(cook(0.3, 0.6, m));
    }
    for r in [0.1, 0.5, 1.0] {
        v.push(pbr(0.7, 0.0, r));
        v.push(pbr(0.7, 1.0, r));
    }
    v.push(Material::Pbr {
        base_color: [0.9, 0.4, 0.1],
        metallic: 0.5,
        roughness: 0.3,
        base_color_texture: None,
        metallic_roughness_texture: None,
    });
    v
}

fn random_dir_above(rng: &mut impl Rng) -> Vec3 {
    loop {
        let d = sample_uniform_hemisphere([rng.random(), rng.random()]);
        if d.z > 1e-3 {
            return d;
        }
    }
}

#[test]
fn test01_pdf_integrates_to_at_most_one() {
    for mat in all_materials() {
        for t in [0.0f32, 30.0, 60.0, 85.0] {
            let wo = dir_at(t);
            let total = hemisphere_integral(|wi| f64::from(pdf(&mat, Vec3::Z, wo, wi)), 1e-8);
            assert!(total <= 1.0 + 1e-4, "{mat:?} θo={t}: ∫pdf = {total}");
            // Mass can only be lost by the specular lobe below the horizon.
            let ps = f64::from(specular_selection_probability(&mat, Vec3::Z, wo));
            assert!(
                total >= 1.0 - ps - 1e-4,
                "{mat:?} θo={t}: ∫pdf = {total}, p_spec = {ps}"
            );
            let exact_one = matches!(mat, Material::Lambert { .. })
                || (matches!(mat, Material::Phong { .. }) && t == 0.0);
            if exact_one {
                assert!((total - 1.0).abs() < 1e-4, "{mat:?} θo={t}: ∫pdf = {total}");
            }
            if matches!(mat, Material::Mirror { .. }) {
                assert!(
                    (total - (1.0 - ps)).abs() < 1e-4,
                    "mirror: diffuse part must integrate to 1 − P_delta"
                );
            }
        }
    }
}

#[test]
fn test02_sample_weight_is_eval_cos_over_pdf() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
    let n = Vec3::new(0.2, 0.9, -0.3).normalize();
    let frame = Frame::from_normal(n);
    for mat in all_materials() {
        let mut count = 0;
        for _ in 0..20_000 {
            let wo = frame.to_world(random_dir_above(&mut rng));
            let Some(s) = sample(&mat, n, wo, [rng.random(), rng.random(), rng.random()]) else {
                continue;
            };
            assert!((s.wi.length() - 1.0).abs() < 1e-4);
            assert!(s.wi.dot(n) > 0.0);
            if s.is_delta {
                let r = 2.0 * wo.dot(n) * n - wo;
                assert!((s.wi - r).length() < 1e-4);
                continue;
            }
            count += 1;
            let p = pdf(&mat, n, wo, s.wi);
            assert!(
                (p - s.pdf).abs() <= 1e-3 * s.pdf,
                "{mat:?}: pdf {p} vs sample {}",
                s.pdf
            );
            let expect = eval(&mat, n, wo, s.wi) * s.wi.dot(n) / s.pdf;
            assert!(
                (expect - s.weight).abs().max_element() <= 1e-3 * expect.max_element().max(1e-3),
                "{mat:?}: {expect} vs {}",
                s.weight
            );
        }
        assert!(count > 1000, "{mat:?}: too few non-delta samples");
    }
}

#[test]
fn test03_reciprocity() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(12);
    let n = Vec3::new(-0.4, 0.1, 0.9).normalize();
    let frame = Frame::from_normal(n);
    for mat in all_materials() {
        for _ in 0..20_000 {
            let (a, b) = (
                frame.to_world(random_dir_above(&mut rng)),
                frame.to_world(random_dir_above(&mut rng)),
            );
            let (f1, f2) = (eval(&mat, n, a, b), eval(&mat, n, b, a));
            assert!(
                (f1 - f2).abs().max_element() <= 2e-3 * f1.max_element().max(1e-6),
                "{mat:?}: {f1} vs {f2}"
            );
        }
        // Below the surface everything is zero.
        assert_eq!(eval(&mat, n, -n, n), Vec3::ZERO);
        assert_eq!(pdf(&mat, n, n, -n), 0.0);
        assert!(sample(&mat, n, -n, [0.5, 0.5, 0.5]).is_none());
    }
}

/// Closed form of the Blinn–Phong `(e+8)/(8π)` lobe's directional albedo at normal incidence:
/// with `θ_h = θ_i/2`, `∫ (e+8)/(8π) cos^e(θ_i/2) cos θ_i dω = (e+8)[(2−q)/(e+4) − (1−q)/(e+2)]`,
/// `q = 2^{−(e+2)/2}`.
fn blinn_albedo_normal(e: f64) -> f64 {
    let q = 2f64.powf(-(e + 2.0) / 2.0);
    (e + 8.0) * ((2.0 - q) / (e + 4.0) - (1.0 - q) / (e + 2.0))
}

#[test]
fn test04_directional_albedo_closed_forms() {
    // Phong at normal incidence: ∫ (e+2)/(2π) cos^e θ cos θ dω = 1 exactly.
    for e in [0.0, 1.0, 20.0, 500.0] {
        let a = albedo_quadrature(&phong(0.0, 1.0, e), Vec3::Z);
        assert!((a - 1.0).abs() < 1e-4, "Phong e={e}: albedo {a}");
    }
    for e in [0.0, 1.0, 10.0, 50.0, 2000.0] {
        let a = albedo_quadrature(&blinn(0.0, 1.0, e), Vec3::Z);
        let c = blinn_albedo_normal(f64::from(e));
        assert!(
            (a - c).abs() < 1e-4,
            "Blinn e={e}: albedo {a} vs closed form {c}"
        );
    }
    // The closed form exceeds 1 for 0 < e (maximum ≈ 1.075 near e = 10), tends to 1 as e → ∞.
    assert!((blinn_albedo_normal(0.0) - 1.0).abs() < 1e-12);
    assert!(blinn_albedo_normal(10.0) > 1.07 && (blinn_albedo_normal(1e6) - 1.0).abs() < 1e-4);
    // Lambert: albedo.
    let a = albedo_quadrature(&Material::Lambert { albedo: grey(0.7) }, dir_at(40.0));
    assert!((a - 0.7).abs() < 1e-5);
}

#[test]
fn test05_energy_and_white_furnace() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(13);
    println!("directional albedo (albedo 0, specular 1), quadrature | sampled mean ± 1σ");
    let mats = [
        ("phong e=1", phong(0.0, 1.0, 1.0)),
        ("phong e=20", phong(0.0, 1.0, 20.0)),
        ("phong e=500", phong(0.0, 1.0, 500.0)),
        ("blinn e=1", blinn(0.0, 1.0, 1.0)),
        ("blinn e=50", blinn(0.0, 1.0, 50.0)),
        ("blinn e=2000", blinn(0.0, 1.0, 2000.0)),
        ("ward a=0.05", ward(0.0, 1.0, 0.05)),
        ("ward a=0.3", ward(0.0, 1.0, 0.3)),
        ("ct m=0.05", cook(0.0, 1.0, 0.05)),
        ("ct m=0.3", cook(0.0, 1.0, 0.3)),
        ("ct m=0.8", cook(0.0, 1.0, 0.8)),
        ("mix phong", phong(0.3, 0.6, 20.0)),
        ("mix ct", cook(0.5, 0.5, 0.3)),
        ("pbr metal r=0.1", pbr(1.0, 1.0, 0.1)),
        ("pbr metal r=0.5", pbr(1.0, 1.0, 0.5)),
        ("pbr metal r=1", pbr(1.0, 1.0, 1.0)),
        ("pbr diel r=0.3", pbr(0.8, 0.0, 0.3)),
        ("pbr half r=0.6", pbr(0.5, 0.5, 0.6)),
    ];
    for (name, mat) in &mats {
        for t in [0.0f32, 30.0, 60.0, 85.0] {
            let wo = dir_at(t);
            let q = albedo_quadrature(mat, wo);
            let n = 200_000;
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let w = sample(mat, Vec3::Z, wo, [rng.random(), rng.random(), rng.random()])
                    .map_or(0.0, |s| f64::from(s.weight.y));
                sum += w;
                sum2 += w * w;
            }
            let mean = sum / n as f64;
            let sigma = ((sum2 / n as f64 - mean * mean).max(0.0) / n as f64).sqrt();
            println!("{name:>13} θo={t:>2}: {q:.5} | {mean:.5} ± {sigma:.5}");
            // 5σ (plus quadrature slack) for each of 72 estimates: false alarms are negligible.
            assert!(
                (mean - q).abs() < 5.0 * sigma + 1e-4,
                "{name} θo={t}: furnace {mean} ± {sigma} vs quadrature {q}"
            );
            // Blinn–Phong's (e+8)/(8π) is only approximately normalised: its albedo at normal
            // incidence exceeds 1 by up to ~7% (closed form in test04). Ward stays below 1 here.
            // The glTF dielectric is not energy conserving at grazing view either: its `(1 − F)`
            // diffuse term and `F·D·V` specular use the Fresnel of each ω_i's half vector, and
            // with base colour 0.8 the sum reaches 1.10 at θo = 85° (measured here, and by the
            // independent oracle in pbr_oracle.rs). Its metals are bounded.
            let is_bounded = !matches!(mat, Material::BlinnPhong { .. })
                && !matches!(mat, Material::Pbr { metallic, .. } if *metallic < 1.0);
            if is_bounded {
                assert!(q <= 1.0 + 1e-4, "{name} θo={t}: albedo {q} > 1");
            }
        }
    }
}

#[test]
fn test06_pure_delta_means_zero_eval_everywhere() {
    let pure = Material::Mirror {
        albedo: grey(0.0),
        specular: grey(0.8),
    };
    assert!(is_pure_delta(&pure));
    let mut rng = rand_pcg::Pcg64::seed_from_u64(6);
    for _ in 0..10_000 {
        let (wo, wi) = (random_dir_above(&mut rng), random_dir_above(&mut rng));
        assert_eq!(eval(&pure, Vec3::Z, wo, wi), Vec3::ZERO);
    }
    // Every other material has a non-delta part that light sampling must see.
    for mat in all_materials() {
        assert!(!is_pure_delta(&mat), "{mat:?}");
    }
}

/// Where a BRDF is non-zero, BRDF sampling can draw the direction: `pdf > 0` wherever
/// `eval ≥ MISSED = 1e-30`, for every material here and for purely specular lobes (no diffuse part), at
/// 20,000 random direction pairs each, plus pairs around the mirror direction of the sharp
/// lobes. MIS-compensated environment sampling ([`EnvSampling::Compensated`]) gives pdf 0 to
/// the map below its mean and relies on BRDF sampling alone there: a BRDF that failed this
/// would make the compensated render too dark. Below `MISSED` the two only part in f32
/// underflow far out in a sharp lobe's tail (`cos⁵⁰` of a wide angle: `f` = 1e-45 with pdf
/// 0): 2⁻¹⁰⁰ of any lobe's peak, lost in the rounding of any pixel.
#[test]
fn test07_sampling_covers_the_brdf() {
    const MISSED: f32 = 1e-30;
    let mut mats = all_materials();
    mats.extend([
        phong(0.0, 0.6, 20.0),
        blinn(0.0, 0.6, 50.0),
        ward(0.0, 0.6, 0.1),
    ]);
    mats.extend([cook(0.0, 0.6, 0.3), pbr(0.7, 1.0, 0.2), pbr(0.0, 1.0, 0.05)]);
    let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
    for mat in &mats {
        for i in 0..20_000 {
            let wo = random_dir_above(&mut rng);
            let wi = if i % 2 == 0 {
                random_dir_above(&mut rng)
            } else {
                // Near the mirror direction, where sharp lobes are non-zero.
                let m = Vec3::new(-wo.x, -wo.y, wo.z);
                let j = 0.05 * (random_dir_above(&mut rng) - Vec3::Z);
                (m + j).normalize()
            };
            if wi.z <= 1e-3 {
                continue;
            }
            let f = eval(mat, Vec3::Z, wo, wi);
            if pdf(mat, Vec3::Z, wo, wi) == 0.0 {
                assert!(
                    f.max_element() < MISSED,
                    "{mat:?}: f = {f} but pdf 0 at wo {wo}, wi {wi}"
                );
            }
        }
    }
}

/// Lobe splitting (`sample_lobe`, one direction per lobe from the same two numbers, as the
/// tracer draws them) estimates the whole material: the mean of the summed weights over
/// 100,000 draws is the directional albedo by quadrature (plus `specular` for the mirror's
/// delta lobe), within 5 standard errors (plus the quadrature's 1e-4) for each of the 4 views
/// of each two-lobe material; and every non-delta split sample's weight and pdf are
/// `eval · cos / split_pdf` and `split_pdf`. One-lobe materials are never split.
#[test]
fn test08_split_lobes_estimate_the_whole_material() {
    let mut rng = rand_pcg::Pcg64::seed_from_u64(8);
    let n = 100_000;
    let mut split_count = 0;
    for mat in all_materials() {
        for t in [0.0f32, 30.0, 60.0, 85.0] {
            let wo = dir_at(t);
            if !splits(&mat, Vec3::Z, wo) {
                let ps = specular_selection_probability(&mat, Vec3::Z, wo);
                assert!(
                    ps == 0.0 || ps == 1.0,
                    "{mat:?} θo={t}: two lobes not split"
                );
                continue;
            }
            split_count += 1;
            let q = albedo_quadrature(&mat, wo)
                + match mat {
                    Material::Mirror { specular, .. } => f64::from(specular[1]),
                    _ => 0.0,
                };
            let (mut sum, mut sum2) = (0.0f64, 0.0f64);
            for _ in 0..n {
                let u = [rng.random(), rng.random()];
                let mut w = 0.0f64;
                for lobe in SPLIT_LOBES {
                    let Some(s) = sample_lobe(&mat, Vec3::Z, wo, lobe, u) else {
                        continue;
                    };
                    w += f64::from(s.weight.y);
                    if s.is_delta {
                        assert_eq!(s.wi, Vec3::new(-wo.x, -wo.y, wo.z));
                        continue;
                    }
                    let p = split_pdf(&mat, Vec3::Z, wo, s.wi);
                    assert!(
                        (p - s.pdf).abs() <= 1e-3 * s.pdf,
                        "{mat:?}: pdf {p} vs {}",
                        s.pdf
                    );
                    let expect = eval(&mat, Vec3::Z, wo, s.wi).y * s.wi.z / p;
                    assert!(
                        (expect - s.weight.y).abs() <= 1e-3 * expect.max(1e-3),
                        "{mat:?}: weight {} vs {expect}",
                        s.weight.y
                    );
                }
                sum += w;
                sum2 += w * w;
            }
            let mean = sum / f64::from(n);
            let sigma = ((sum2 / f64::from(n) - mean * mean).max(0.0) / f64::from(n)).sqrt();
            assert!(
                (mean - q).abs() < 5.0 * sigma + 1e-4,
                "{mat:?} θo={t}: split estimate {mean} ± {sigma} vs albedo {q}"
            );
        }
    }
    // The mirror, 4 Phong/Blinn/Ward/CT mixtures of 11, and the 4 PBR dielectrics, at 4 views.
    assert_eq!(split_count, 4 * (1 + 11 + 4));
    for mat in [
        Material::Lambert { albedo: grey(0.5) },
        Material::Mirror {
            albedo: grey(0.0),
            specular: grey(0.8),
        },
        phong(0.0, 0.6, 20.0),
        pbr(0.7, 1.0, 0.3),
    ] {
        assert!(!splits(&mat, Vec3::Z, dir_at(30.0)), "{mat:?} is one lobe");
    }
}
