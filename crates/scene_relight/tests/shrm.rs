//! Spherical harmonic reflection maps (`prt_scene_relight::shrm`): the frequency-space
//! prefilter against the angular-space brute force and closed forms, the lookup's rotation.

use glam::{DMat3, DVec3};
use prt_scene_relight::shrm::{
    brute_force, lobe_spectrum, rotate_z, spectrum_of, texel_frame, Shrm, ShrmLobe,
};
use prt_sh::{reconstruct_rgb, Rotation};

/// A band-limited environment: order-4 RGB coefficients (deterministic, positive mean).
fn env4() -> Vec<[f64; 3]> {
    (0..16)
        .map(|i| {
            let x = i as f64;
            if i == 0 {
                [3.0, 2.5, 2.0]
            } else {
                [
                    (0.7 * x).sin(),
                    (1.3 * x).cos() * 0.8,
                    (0.4 * x + 1.0).sin() * 0.6,
                ]
            }
        })
        .collect()
}

fn pad(c: &[[f64; 3]], order: usize) -> Vec<[f64; 3]> {
    let mut v = c.to_vec();
    v.resize(order * order, [0.0; 3]);
    v
}

#[test]
fn rotate_z_is_the_sh_rotation_about_z() {
    let order = 8;
    let f: Vec<f64> = (0..order * order)
        .map(|i| (i as f64 * 0.37).sin())
        .collect();
    let psi = 0.83;
    let want = Rotation::new(order, DMat3::from_rotation_z(psi))
        .unwrap()
        .apply(&f)
        .unwrap();
    let mut got = vec![0.0; order * order];
    rotate_z(&f, order, psi, &mut got);
    for (a, b) in got.iter().zip(&want) {
        // Both exact; the recurrence rounds at 1e-15 per step.
        assert!((a - b).abs() < 1e-12, "{a} vs {b}");
    }
}

/// The prefilter at a texel equals the brute-force integral there: the environment is
/// band-limited to order 4, so with `order ≥ 4` and `twist ≥ 3` the SH route drops nothing
/// (the lighting in any frame has `|m| ≤ 3`) and both sides use the same product rule for the
/// lobe; what is left is the table's f32 rounding (≤ 1e-7 relative to the largest term).
#[test]
fn prefilter_matches_the_angular_brute_force() {
    let env = env4();
    let order = 6;
    let lobe = ShrmLobe::Pbr { roughness: 0.5 };
    let spec = lobe_spectrum(lobe, order, 5, 4).unwrap();
    let (rows, cols) = (7, 12);
    let shrm = Shrm::prefilter(&spec, &pad(&env, order), rows, cols).unwrap();
    let radiance = |d: DVec3| reconstruct_rgb(&env, 4, d).unwrap();
    let nt = 2 * shrm.twist + 1;
    let per_texel = spec.elevations.len() * 2 * 3 * nt;
    for (j, k) in [(0, 0), (2, 5), (3, 11), (6, 3)] {
        for (e, &theta_o) in spec.elevations.iter().enumerate() {
            for gamma in [0.0, 1.1, -2.5] {
                let want = brute_force(
                    lobe,
                    &radiance,
                    texel_frame(j, k, rows, cols),
                    theta_o,
                    gamma,
                );
                let texel = &shrm.table[(j * cols + k) * per_texel..][..per_texel];
                for q in 0..2 {
                    for c in 0..3 {
                        let f = &texel[((e * 2 + q) * 3 + c) * nt..][..nt];
                        let mut got = f64::from(f[0]);
                        for m in 1..=shrm.twist {
                            let (s, co) = (m as f64 * gamma).sin_cos();
                            got += f64::from(f[2 * m - 1]) * co + f64::from(f[2 * m]) * s;
                        }
                        let scale = want[q][c].abs().max(1e-3);
                        assert!(
                            (got - want[q][c]).abs() < 1e-5 * scale + 1e-7,
                            "texel ({j},{k}) θo {theta_o:.2} γ {gamma} comp {q} ch {c}: {got} vs {}",
                            want[q][c]
                        );
                    }
                }
            }
        }
    }
}

/// A constant environment `c` gives `c` times the lobe's directional albedo
/// `∫ f cos θ_i dω_i` at every point (only `b_00` survives), here measured by an independent
/// rule: a 2000 × 4000 midpoint grid over the local hemisphere (roughness 0.6: the lobe spans
/// ~0.5 rad, resolved to well under 1e-4).
#[test]
fn constant_environment_gives_the_directional_albedo() {
    let lobe = ShrmLobe::Pbr { roughness: 0.6 };
    let order = 8;
    let spec = lobe_spectrum(lobe, order, 4, 8).unwrap();
    let mut env = vec![[0.0; 3]; order * order];
    env[0] = [2.0 * (std::f64::consts::PI).sqrt(), 0.0, 0.0]; // radiance 1 in red
    let shrm = Shrm::prefilter(&spec, &env, 9, 16).unwrap();
    let theta_o = spec.elevations[3];
    let wo_local = DVec3::new(theta_o.sin(), 0.0, theta_o.cos());
    let (nt, np) = (2000, 4000);
    let mut albedo = [0.0; 2];
    for i in 0..nt {
        let th = (i as f64 + 0.5) / nt as f64 * std::f64::consts::FRAC_PI_2;
        for j in 0..np {
            let ph = (j as f64 + 0.5) / np as f64 * std::f64::consts::TAU;
            let d = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
            let v = lobe.eval(wo_local, d);
            let dw = th.sin()
                * (std::f64::consts::FRAC_PI_2 / nt as f64)
                * (std::f64::consts::TAU / np as f64);
            albedo[0] += v[0] * dw;
            albedo[1] += v[1] * dw;
        }
    }
    // An arbitrary point whose view elevation is a tabulated one.
    let n = DVec3::new(0.3, -0.5, 0.8).normalize();
    let t = n.any_orthonormal_vector();
    let wo = n * theta_o.cos() + t * theta_o.sin();
    let got = shrm.lookup(n, wo, None);
    for q in 0..2 {
        assert!(
            (got[q][0] - albedo[q]).abs() < 2e-4 * albedo[q].max(1e-3),
            "{q}: {} vs {}",
            got[q][0],
            albedo[q]
        );
        assert!(got[q][1].abs() < 1e-6 && got[q][2].abs() < 1e-6);
    }
}

/// A lobe zonal about `R`, the normalised Phong `(e+1)/(2π) cos^e θ'`, has the closed-form
/// coefficients `b_l0 = √((2l+1)/(4π)) Λ_l` with `Λ_l` its band multipliers
/// (`prt_sh::zonal::phong_lobe_bands`), and no `m > 0` terms. The product rule integrates the
/// smooth integrand to ~1e-12.
#[test]
fn phong_lobe_has_its_closed_form_coefficients() {
    let e = 20.0;
    let order = 12;
    let lobe = |wo: DVec3, wi: DVec3| -> [f64; 2] {
        let r = DVec3::new(-wo.x, -wo.y, wo.z);
        let c = r.dot(wi).max(0.0);
        [(e + 1.0) / std::f64::consts::TAU * c.powf(e), 0.0]
    };
    let spec = spectrum_of(&lobe, 1, order, 3, 3).unwrap();
    let bands = prt_sh::zonal::phong_lobe_bands(e, order).unwrap();
    for k in 0..3 {
        for l in 0..order {
            let want = ((2 * l + 1) as f64 / (4.0 * std::f64::consts::PI)).sqrt() * bands[l];
            assert!(
                (spec.b(k, 0, l, 0) - want).abs() < 1e-9,
                "l {l}: {} vs {want}",
                spec.b(k, 0, l, 0)
            );
            for m in 1..=3.min(l) {
                assert!(spec.b(k, 0, l, m).abs() < 1e-9);
            }
        }
    }
    assert!(spec.truncation_error(order, 0) < 0.2);
}

/// A rotation of the environment is a rotated lookup: the SHRM of `Rot(Q) L` at a point
/// equals the SHRM of `L` looked up with `Q`. For `Q` about the table's pole by a whole number
/// of columns the texels coincide and the two agree to f32 rounding; for `Q` about +Y (the
/// relighting's rotation) they interpolate at different places, each within bilinear error of
/// the exact value: `h²/8 · |∂²S|` with `h = π/64` and `|∂²S| ≤ l(l+1) max|S| ≤ 12 max|S|`
/// for a band-limited order-4 environment — under 2.5e-3 max|S| per side.
#[test]
fn rotated_environment_is_a_rotated_lookup() {
    let env = env4();
    let order = 6;
    let lobe = ShrmLobe::Specular(prt_scene::Material::Ward {
        albedo: [0.0; 3],
        specular: [1.0; 3],
        roughness: 0.3,
    });
    let spec = lobe_spectrum(lobe, order, 5, 8).unwrap();
    let (rows, cols) = (65, 128);
    let base = Shrm::prefilter(&spec, &pad(&env, order), rows, cols).unwrap();
    let max = base.table.iter().fold(0.0f32, |a, v| a.max(v.abs())) as f64;
    for (q, tol) in [
        (
            DMat3::from_rotation_z(3.0 * std::f64::consts::TAU / cols as f64),
            1e-5,
        ),
        (DMat3::from_rotation_y(0.7), 5e-3),
    ] {
        let rotated = Rotation::new(4, q).unwrap().apply_rgb(&env);
        let other = Shrm::prefilter(&spec, &pad(&rotated, order), rows, cols).unwrap();
        for p in 0..20 {
            let x = p as f64;
            let n = DVec3::new((1.7 * x).sin(), (0.9 * x).cos(), (2.3 * x + 0.5).sin()).normalize();
            let wo = (n + 0.6 * DVec3::new((0.5 * x).cos(), (1.1 * x).sin(), 0.3)).normalize();
            let a = base.lookup(n, wo, Some(&q));
            let b = other.lookup(n, wo, None);
            for c in 0..3 {
                assert!(
                    (a[0][c] - b[0][c]).abs() < tol * max,
                    "point {p}: {} vs {}",
                    a[0][c],
                    b[0][c]
                );
            }
        }
    }
}

/// Determinism: the table is bit-identical on 1 and 2 threads.
#[test]
fn prefilter_is_deterministic_across_threads() {
    let order = 8;
    let spec = lobe_spectrum(ShrmLobe::Pbr { roughness: 0.4 }, order, 4, 4).unwrap();
    let env = pad(&env4(), order);
    let run = |t: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(t)
            .build()
            .unwrap()
            .install(|| {
                let s = lobe_spectrum(ShrmLobe::Pbr { roughness: 0.4 }, order, 4, 4).unwrap();
                (s.coeffs, Shrm::prefilter(&spec, &env, 9, 16).unwrap().table)
            })
    };
    assert_eq!(run(1), run(2));
}

/// The `--glossy shrm` path against the exact path and the truth on an unoccluded convex case:
/// a sphere (no self-shadowing) in a metal at roughness 0.6 under a uniform environment of
/// radiance 1, where the true radiance is the lobe's directional albedo `ρ(θ_o)`.
///
/// SHRM: the table gives `ρ` linearly interpolated between its view elevations (a constant
/// environment keeps only `b_00`), times the occlusion factor. Per vertex the factor is
/// the lobe's own traced visibility, 1 on a convex sphere; the bound below is the one of the
/// fitted factor (`k = Σ w V̂ / Σ w L`, what the path falls back to without the vertices),
/// which holds a fortiori. For that factor, `w` the
/// fitted lobe `ĝ` (and `L ⊛ V = V̂` for `L = 1`); with `V` the hemisphere of `n`,
/// `1 − k = (∫ ĝ (1 − V) + ∫ ĝ (V − V̂)) / ∫ ĝ`, so
/// `|1 − k| ≤ (|∫_below ĝ| + ‖w‖ ‖V̂ − V_n‖) / ∫ ĝ` (Cauchy–Schwarz; ĝ is band-limited to the
/// order, so `V`'s higher bands do not meet it), and `|S − ρ| ≤ |1 − k| ρ + interp` with `interp`
/// the albedo's change between the table's neighbouring elevations. The exact path's bound
/// is `tests/glossy.rs`'s; the two paths differ by at most the sum.
#[test]
fn shrm_path_matches_the_exact_path_on_an_unoccluded_sphere() {
    use prt_bake::{bake, BakeSettings};
    use prt_scene::{Camera, Environment, Scene};
    use prt_scene_relight::GlossyPath;
    use prt_sh::zonal;
    let metal = prt_scene::Material::Pbr {
        base_color: [1.0; 3],
        metallic: 1.0,
        roughness: 0.6,
        base_color_texture: None,
        metallic_roughness_texture: None,
    };
    let lobe = ShrmLobe::of(&metal).unwrap();
    let cam = Camera::look_at(DVec3::new(0.0, 0.0, 4.0), DVec3::ZERO, 40.0, 16, 16);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("metal", metal);
    scene.add_mesh(prt_scene::test_util::icosphere(2), m);
    let accel = prt_tracer::Accel::build(&scene).unwrap();
    let order = 8;
    let settings = BakeSettings {
        order: Some(order),
        rays: 4096,
        bounces: 0,
        ..BakeSettings::final_quality()
    };
    let out = bake(&scene, &accel, &settings).unwrap();
    let run = |glossy| {
        let opt = prt_scene_relight::RelightOptions {
            glossy,
            timing_frames: 1,
            warmup_frames: 0,
            ..Default::default()
        };
        prt_scene_relight::relight(&scene, &accel, &out.bake, &opt).unwrap()
    };
    let (shrm, exact) = (run(GlossyPath::Shrm), run(GlossyPath::Exact));
    let table = &out.bake.glossy[0];
    let e_n = table.projection_error[order - 1];
    let fitted = prt_shading::projection::fitted_table(&metal, order).unwrap();
    let obj = &out.bake.objects[0];
    let vis = &obj
        .blocks
        .iter()
        .find(|b| b.kind == prt_bakefile::TransferKind::Visibility)
        .unwrap()
        .data;
    let (n2, ch) = (order * order, obj.channels as usize);
    let hemi = zonal::bands_to_zonal(&zonal::phong_lobe_bands(0.0, order).unwrap());
    let albedo = |t: f64| -> (f64, f64) {
        // ∫ h and ‖h‖ on a dense product rule (the integrand is smooth at roughness 0.6).
        let q = prt_sh::quadrature::SphereQuadrature::exact_for_degree(400);
        let wo = DVec3::new(t.sin(), 0.0, t.cos());
        let (mut a, mut n2) = (0.0, 0.0);
        for (d, w) in q.dirs.iter().zip(&q.weights) {
            let v = lobe.eval(wo, *d)[0];
            a += w * v;
            n2 += w * v * v;
        }
        (a, n2.sqrt())
    };
    let shrm_elevations: Vec<f64> = (0..16)
        .map(|k| (k as f64 + 0.5) / 16.0 * std::f64::consts::FRAC_PI_2)
        .collect();
    let eye = scene.camera.eye;
    let mut checked = 0;
    for (p, (pos, nrm)) in scene.meshes[0]
        .positions
        .iter()
        .zip(&scene.meshes[0].normals)
        .enumerate()
    {
        let n = nrm.as_dvec3().normalize();
        let wo = (eye - pos.as_dvec3()).normalize();
        let cos_o = n.dot(wo);
        if !(0.3..0.97).contains(&cos_o) {
            continue;
        }
        let theta_o = cos_o.acos();
        let v_hat = &vis[p * ch * n2..p * ch * n2 + n2];
        let v_exact = zonal::rotate_zonal(&hemi, n).unwrap();
        let dv = v_hat
            .iter()
            .zip(&v_exact)
            .map(|(a, b)| (f64::from(*a) - 2.0 * std::f64::consts::PI * b).powi(2))
            .sum::<f64>()
            .sqrt();
        let (rho, f_norm) = albedo(theta_o);
        // The fitted lobe's rows about θ_o: |1 − k| bound (the worse row).
        let el = &fitted.elevations;
        let i = el.partition_point(|&t| t <= theta_o).clamp(1, el.len() - 1);
        let one_minus_k = [i - 1, i]
            .iter()
            .map(|&e| fitted_occlusion_bound(&fitted, e, order, dv))
            .fold(0.0, f64::max);
        let j = shrm_elevations
            .partition_point(|&t| t <= theta_o)
            .clamp(1, 15);
        let interp_shrm = (albedo(shrm_elevations[j - 1]).0 - albedo(shrm_elevations[j]).0).abs();
        let bound_shrm = one_minus_k * rho + interp_shrm;
        let b = prt_scene_relight::glossy::table_row(table, order, theta_o);
        let b_norm = b.iter().map(|x| x * x).sum::<f64>().sqrt();
        let te = &table.elevations;
        let k = te.partition_point(|&t| t <= theta_o).clamp(1, te.len() - 1);
        let interp = (albedo(te[k - 1]).0 - albedo(te[k]).0).abs();
        let bound_exact = dv * b_norm + (2.0 * std::f64::consts::PI).sqrt() * e_n * f_norm + interp;
        let (s, x) = (
            f64::from(shrm.radiance[0][p][0]),
            f64::from(exact.radiance[0][p][0]),
        );
        assert!(
            (s - rho).abs() <= bound_shrm,
            "vertex {p}: θo {theta_o:.3}: SHRM {s} vs ρ {rho} (bound {bound_shrm})"
        );
        assert!(
            (s - x).abs() <= bound_shrm + bound_exact,
            "vertex {p}: SHRM {s} vs exact {x}"
        );
        checked += 1;
    }
    assert!(checked > 10, "only {checked} vertices checked");
}

/// `(|∫_below ĝ| + ‖w‖ dv) / ∫ ĝ` of fitted row `e` (local frame: axes at their angles from the
/// normal toward the mirror direction, in the plane of the view), the lower hemisphere
/// integrated on a product rule exact for the lobe's degree.
fn fitted_occlusion_bound(
    f: &prt_shading::projection::FittedTable,
    e: usize,
    order: usize,
    dv: f64,
) -> f64 {
    let k = f.lobes;
    let q = prt_sh::quadrature::SphereQuadrature::exact_for_degree(2 * order + 2);
    let mut below = 0.0;
    let mut total = 0.0;
    let mut w2 = 0.0;
    for j in 0..k {
        let a = f.axis[e * k + j];
        let axis = DVec3::new(-a.sin(), 0.0, a.cos());
        let bands = &f.bands[(e * k + j) * order..][..order];
        total += bands[0];
        w2 += bands
            .iter()
            .enumerate()
            .map(|(l, a)| (2 * l + 1) as f64 / (4.0 * std::f64::consts::PI) * a * a)
            .sum::<f64>()
            .sqrt();
        for (d, wt) in q.dirs.iter().zip(&q.weights) {
            if d.z >= 0.0 {
                continue;
            }
            let x = axis.dot(*d);
            let (mut p0, mut p1) = (1.0, x);
            let mut g = bands[0] / (4.0 * std::f64::consts::PI);
            for (l, al) in bands.iter().enumerate().skip(1) {
                g += (2 * l + 1) as f64 / (4.0 * std::f64::consts::PI) * al * p1;
                let p2 = ((2 * l + 1) as f64 * x * p1 - l as f64 * p0) / (l + 1) as f64;
                (p0, p1) = (p1, p2);
            }
            below += wt * g;
        }
    }
    (below.abs() + w2 * dv) / total
}
