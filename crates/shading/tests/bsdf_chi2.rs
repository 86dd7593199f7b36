//! Chi-square tests of every BRDF sampler (and the warps) against its pdf.
//!
//! Family-wise significance 0.01 over all `SUITE_TESTS` tests of this file (Šidák).

mod common;
use common::*;
use glam::Vec3;
use prt_scene::Material;
use prt_shading::chi2::{sidak, Chi2Test};
use prt_shading::*;

const ANGLES: [f32; 4] = [0.0, 30.0, 60.0, 85.0];
/// warps 2, Lambert + Mirror 8, Phong 12 + pure + tilted, Blinn 12 + 1, Ward 8 + 1, CT 12 + 1,
/// PBR 24 + tilted, lobe splitting 7 materials × 3 angles.
const SUITE_TESTS: usize = 2 + 8 + 14 + 13 + 9 + 13 + 25 + 21;

fn alpha() -> f64 {
    sidak(ALPHA, SUITE_TESTS)
}

fn check(mat: &Material, n: Vec3, theta_o: f32, seed: u64) {
    let wo = dir_at(theta_o);
    let wo = if n == Vec3::Z {
        wo
    } else {
        Frame::from_normal(n).to_world(wo)
    };
    let test = Chi2Test {
        seed,
        ..Chi2Test::default()
    };
    let report = test.run_bsdf(mat, n, wo);
    report.assert_passes(alpha(), &format!("{mat:?} θo={theta_o}"));
}

#[test]
fn test01_warps() {
    let test = Chi2Test::default();
    test.run(
        |u| Some(sample_cosine_hemisphere([u[0], u[1]])),
        |d| f64::from(cosine_hemisphere_pdf(d.z)),
    )
    .assert_passes(alpha(), "cosine hemisphere");
    test.run(
        |u| Some(sample_uniform_sphere([u[0], u[1]])),
        |_| f64::from(uniform_sphere_pdf()),
    )
    .assert_passes(alpha(), "uniform sphere");
}

#[test]
fn test02_lambert_and_mirror() {
    for (k, t) in ANGLES.iter().enumerate() {
        check(
            &Material::Lambert {
                albedo: [0.8, 0.5, 0.2],
            },
            Vec3::Z,
            *t,
            k as u64,
        );
        check(
            &Material::Mirror {
                albedo: grey(0.4),
                specular: grey(0.5),
            },
            Vec3::Z,
            *t,
            10 + k as u64,
        );
    }
}

#[test]
fn test03_phong() {
    for e in [1.0, 20.0, 500.0] {
        for (k, t) in ANGLES.iter().enumerate() {
            check(&phong(0.3, 0.6, e), Vec3::Z, *t, 100 + k as u64);
        }
    }
    check(&phong(0.0, 1.0, 20.0), Vec3::Z, 60.0, 120);
    // A tilted normal exercises the frame.
    check(
        &phong(0.3, 0.6, 20.0),
        Vec3::new(0.3, -0.5, 0.8).normalize(),
        40.0,
        121,
    );
}

#[test]
fn test04_blinn_phong() {
    for e in [1.0, 50.0, 2000.0] {
        for (k, t) in ANGLES.iter().enumerate() {
            check(&blinn(0.3, 0.6, e), Vec3::Z, *t, 200 + k as u64);
        }
    }
    check(&blinn(0.0, 1.0, 50.0), Vec3::Z, 60.0, 220);
}

#[test]
fn test05_ward() {
    for a in [0.05, 0.3] {
        for (k, t) in ANGLES.iter().enumerate() {
            check(&ward(0.3, 0.6, a), Vec3::Z, *t, 300 + k as u64);
        }
    }
    check(&ward(0.0, 1.0, 0.3), Vec3::Z, 60.0, 320);
}

#[test]
fn test06_cook_torrance() {
    for m in [0.05, 0.3, 0.8] {
        for (k, t) in ANGLES.iter().enumerate() {
            check(&cook(0.3, 0.6, m), Vec3::Z, *t, 400 + k as u64);
        }
    }
    check(&cook(0.0, 1.0, 0.3), Vec3::Z, 60.0, 420);
}

#[test]
fn test07_pbr() {
    // Dielectric (diffuse + specular mixture) and metal (pure VNDF), narrow to wide.
    for (i, r) in [0.1f32, 0.4, 1.0].iter().enumerate() {
        for (k, t) in ANGLES.iter().enumerate() {
            let seed = 500 + 10 * i as u64 + k as u64;
            check(&pbr(0.6, 0.0, *r), Vec3::Z, *t, seed);
            check(&pbr(0.8, 1.0, *r), Vec3::Z, *t, seed + 100);
        }
    }
    check(
        &pbr(0.5, 0.5, 0.3),
        Vec3::new(0.3, -0.5, 0.8).normalize(),
        40.0,
        700,
    );
}

/// Lobe splitting: each lobe sampled alone has its own density, and `split_pdf` is their sum
/// (`Chi2Test::run_split`), for every kind of two-lobe material, at normal, oblique and
/// grazing view. The mirror's delta lobe counts as rejected samples (half of them).
#[test]
fn test08_split_lobes() {
    let mats = [
        Material::Mirror {
            albedo: grey(0.4),
            specular: grey(0.5),
        },
        phong(0.3, 0.6, 30.0),
        blinn(0.3, 0.6, 50.0),
        ward(0.3, 0.6, 0.2),
        cook(0.3, 0.6, 0.3),
        pbr(0.6, 0.0, 0.4),
        pbr(0.5, 0.5, 0.3),
    ];
    for (i, mat) in mats.iter().enumerate() {
        for (k, t) in [0.0f32, 60.0, 85.0].iter().enumerate() {
            let wo = dir_at(*t);
            assert!(splits(mat, Vec3::Z, wo), "{mat:?} has two lobes");
            let test = Chi2Test {
                seed: 800 + 10 * i as u64 + k as u64,
                ..Chi2Test::default()
            };
            test.run_split(mat, Vec3::Z, wo)
                .assert_passes(alpha(), &format!("split {mat:?} θo={t}"));
        }
    }
}
