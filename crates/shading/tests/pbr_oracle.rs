//! The glTF metallic-roughness BRDF against an independent implementation:
//! `tools/pbr_oracle.py` (numpy, written from the glTF 2.0 specification's Appendix B without
//! reading this crate) evaluated `f`, the visible-normal sampling pdf and the directional albedo
//! in 50-digit arithmetic / converged quadrature; its output is committed in
//! `tests/data/pbr_oracle.json`.

mod common;
use common::*;
use glam::Vec3;
use prt_scene::Material;
use serde_json::Value;

fn oracle() -> Value {
    let text = std::fs::read_to_string(
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/pbr_oracle.json"),
    )
    .expect("oracle data");
    serde_json::from_str(&text).expect("oracle JSON")
}

fn v3(v: &Value) -> Vec3 {
    let a: Vec<f32> = v
        .as_array()
        .unwrap()
        .iter()
        .map(|x| x.as_f64().unwrap() as f32)
        .collect();
    Vec3::new(a[0], a[1], a[2])
}

fn f(v: &Value) -> f32 {
    v.as_f64().unwrap() as f32
}

fn material(c: &Value) -> Material {
    Material::Pbr {
        base_color: v3(&c["base_color"]).to_array(),
        metallic: f(&c["metallic"]),
        roughness: f(&c["roughness"]),
        base_color_texture: None,
        metallic_roughness_texture: None,
    }
}

/// Relative tolerance of an f32 evaluation: the inputs are rounded to f32 (relative 2⁻²⁴ each),
/// which moves the exact value by `rel_sensitivity · 2⁻²⁴` (the oracle's condition estimate),
/// taken 4× for the f32 arithmetic that follows; plus 2e-5 for the ~100 roundings of the
/// evaluation itself (each ≤ 6e-8, accumulating to ≤ 1e-5 in the worst, linear, case).
fn tolerance(c: &Value) -> f32 {
    let kappa = c["rel_sensitivity"].as_f64().unwrap_or(1.0) as f32;
    4.0 * kappa * 2f32.powi(-24) + 2e-5
}

#[test]
fn eval_matches_the_specification() {
    let o = oracle();
    let cases = o["eval"].as_array().unwrap();
    assert!(cases.len() >= 300);
    let mut worst = 0.0f32;
    for (i, c) in cases.iter().enumerate() {
        let (wo, wi) = (v3(&c["wo"]), v3(&c["wi"]));
        let want = v3(&c["f"]);
        let got = prt_shading::eval(&material(c), Vec3::Z, wo, wi);
        let tol = tolerance(c);
        for k in 0..3 {
            let err = (got[k] - want[k]).abs();
            let rel = err / want[k].abs().max(1e-30);
            if want[k] != 0.0 {
                worst = worst.max(rel / tol);
            }
            assert!(
                err <= tol * want[k].abs() + 1e-12,
                "case {i} ({}): f[{k}] = {} but the oracle says {} (relative {rel:.2e}, tolerance {tol:.2e})\n{c}",
                c["kind"],
                got[k],
                want[k]
            );
        }
    }
    println!("eval: worst error / tolerance = {worst:.3}");
}

#[test]
fn sampling_pdf_matches_visible_normal_density() {
    let o = oracle();
    let cases = o["pdf"].as_array().unwrap();
    assert!(cases.len() >= 100);
    for (i, c) in cases.iter().enumerate() {
        let (wo, wi) = (v3(&c["wo"]), v3(&c["wi"]));
        // A black metal: no diffuse term, so the specular lobe is always chosen and the
        // mixture pdf is the VNDF pdf itself.
        let mat = Material::Pbr {
            base_color: [0.0; 3],
            metallic: 1.0,
            roughness: f(&c["roughness"]),
            base_color_texture: None,
            metallic_roughness_texture: None,
        };
        let got = prt_shading::pdf(&mat, Vec3::Z, wo, wi);
        let want = f(&c["pdf"]);
        let tol = tolerance(c);
        assert!(
            (got - want).abs() <= tol * want.abs() + 1e-12,
            "case {i}: pdf {got} vs oracle {want} (tolerance {tol:.2e})\n{c}"
        );
    }
}

#[test]
fn directional_albedo_matches_converged_quadrature() {
    // Our f integrated by this crate's adaptive quadrature (absolute tolerance 1e-7 per
    // nested level) against the oracle's converged half-vector quadrature (error ≤ 1e-10).
    // 2e-4 covers the adaptive rule's error on the narrowest lobe (roughness 0.1, α = 0.01,
    // whose peak the Simpson subdivision must find) and f32 evaluation.
    let o = oracle();
    for c in o["albedo"].as_array().unwrap() {
        let r = f(&c["roughness"]);
        if r < 0.3 {
            continue; // the nested Simpson rule is slow to resolve a 0.01-wide peak
        }
        let wo = v3(&c["wo"]);
        let got = albedo_quadrature(&material(c), wo);
        let want = c["albedo"][1].as_f64().unwrap();
        assert!(
            (got - want).abs() < 2e-4,
            "albedo {got} vs oracle {want}: {c}"
        );
    }
}
