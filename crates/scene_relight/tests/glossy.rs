//! Glossy-table specular relighting (Ward) against direct numerical integration, with a
//! tolerance derived from the bake's own figures.

use glam::{DVec3, Vec3};
use prt_bake::{bake, BakeSettings};
use prt_bakefile::TransferKind;
use prt_scene::test_util::icosphere;
use prt_scene::{Camera, Environment, Material, Scene};
use prt_sh::quadrature::SphereQuadrature;
use prt_sh::zonal;

/// `∫ f_s(ω_i, ω_o) max(0, cos θ_i) dω_i` at view elevation `θ_o` (local frame, n = +Z), and
/// `‖f_s cos‖₂`, by a dense product rule (the integrand is smooth for α = 0.3).
fn albedo_and_norm(m: &Material, theta_o: f64) -> (f64, f64) {
    let q = SphereQuadrature::exact_for_degree(400);
    let wo = DVec3::new(theta_o.sin(), 0.0, theta_o.cos()).as_vec3();
    let (mut a, mut n2) = (0.0, 0.0);
    for (d, w) in q.dirs.iter().zip(&q.weights) {
        if d.z <= 0.0 {
            continue;
        }
        let v = f64::from(prt_shading::eval(m, Vec3::Z, wo, d.as_vec3()).x) * d.z;
        a += w * v;
        n2 += w * v * v;
    }
    (a, n2.sqrt())
}

#[test]
fn ward_specular_from_the_brdf_table_matches_the_integral() {
    let ward = Material::Ward {
        albedo: [0.0; 3],
        specular: [1.0; 3],
        roughness: 0.3,
    };
    check(ward, prt_scene_relight::GlossyPath::Exact);
}

#[test]
fn fitted_lobes_match_the_integral_within_their_fit_error() {
    let ward = Material::Ward {
        albedo: [0.0; 3],
        specular: [1.0; 3],
        roughness: 0.3,
    };
    check(ward, prt_scene_relight::GlossyPath::Fitted);
    // A white metal: f = D·V exactly (Schlick's term vanishes with base colour 1).
    let metal = Material::Pbr {
        base_color: [1.0; 3],
        metallic: 1.0,
        roughness: 0.6,
        base_color_texture: None,
        metallic_roughness_texture: None,
    };
    check(metal, prt_scene_relight::GlossyPath::Fitted);
    check(metal, prt_scene_relight::GlossyPath::Exact);
}

/// Relights a sphere under a uniform environment by `path` and checks every vertex against
/// the lobe's directional albedo with a bound derived from the bake's and the table's own
/// error figures.
fn check(material: Material, path: prt_scene_relight::GlossyPath) {
    // Albedo 0, specular 1: the image is the specular lobe alone. A convex sphere under a
    // uniform environment of radiance 1: R = L ⊛ V = V exactly (a product with a constant),
    // and the true radiance is the lobe's directional albedo ρ(θ_o) = ∫ V f_s cos, with V the
    // hemisphere of n. The relit value is Σ_i V̂_i b̂_i (baked V̂, table row b̂). Its error is
    //   |Σ V̂ b̂ − ∫ V f cos| ≤ ‖V̂ − V_n‖ ‖b̂‖ + |∫ V (P_n(f cos) − f cos)| + interpolation
    // where the middle term is ≤ ‖V‖ · e_n ‖f cos‖ (Cauchy–Schwarz; e_n is the table's relative
    // projection error at the order, stored in the bake; ‖V‖ = √(2π)), and linear
    // interpolation between tabulated elevations errs by at most the albedo's change between
    // the two neighbouring elevations.
    //
    // The fitted path (`GlossyPath::Fitted`) relights `Σ_i V̂_i w_i` with `w` the fitted lobe
    // `ĝ = Σ_k Σ_l c_kl P_l(a_k·ω)`: its error is `≤ ‖V̂ − V_n‖ ‖w‖ + √(2π) e_fit ‖f cos‖`
    // (Cauchy–Schwarz over the hemisphere, `e_fit` the fit's relative error above the horizon,
    // the larger of the two neighbouring elevations) plus the same interpolation term.
    let ward = material;
    let cam = Camera::look_at(DVec3::new(0.0, 0.0, 4.0), DVec3::ZERO, 40.0, 16, 16);
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("ward", ward);
    scene.add_mesh(icosphere(2), m);
    let accel = prt_tracer::Accel::build(&scene).unwrap();
    let order = 8;
    let out = bake(
        &scene,
        &accel,
        &BakeSettings {
            order: Some(order),
            rays: 4096,
            bounces: 0,
            ..BakeSettings::final_quality()
        },
    )
    .unwrap();
    let table = &out.bake.glossy[0];
    let e_n = table.projection_error[order - 1];
    let fitted = prt_shading::projection::fitted_table(&ward, order).unwrap();
    let relit = prt_scene_relight::relight(
        &scene,
        &accel,
        &out.bake,
        &prt_scene_relight::RelightOptions {
            order: Some(order),
            timing_frames: 1,
            warmup_frames: 0,
            glossy: path,
            ..Default::default()
        },
    )
    .unwrap();
    let obj = &out.bake.objects[0];
    let vis = &obj
        .blocks
        .iter()
        .find(|b| b.kind == TransferKind::Visibility)
        .unwrap()
        .data;
    let n2 = order * order;
    let ch = obj.channels as usize;
    // Exact V_n of the hemisphere about n: 2π × the normalised e = 0 lobe rotated to n.
    let hemi = zonal::bands_to_zonal(&zonal::phong_lobe_bands(0.0, order).unwrap());
    let mesh = &scene.meshes[0];
    let eye = scene.camera.eye;
    let mut checked = 0;
    let mut worst = 0.0f64;
    for (p, (pos, nrm)) in mesh.positions.iter().zip(&mesh.normals).enumerate() {
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
        let (rho, f_norm) = albedo_and_norm(&ward, theta_o);
        let bound = match path {
            prt_scene_relight::GlossyPath::Exact => {
                let b = prt_scene_relight::glossy::table_row(table, order, theta_o);
                let b_norm = b.iter().map(|x| x * x).sum::<f64>().sqrt();
                let el = &table.elevations;
                let i = el.partition_point(|&t| t <= theta_o).clamp(1, el.len() - 1);
                let interp =
                    (albedo_and_norm(&ward, el[i - 1]).0 - albedo_and_norm(&ward, el[i]).0).abs();
                dv * b_norm + (2.0 * std::f64::consts::PI).sqrt() * e_n * f_norm + interp
            }
            prt_scene_relight::GlossyPath::Hybrid { .. }
            | prt_scene_relight::GlossyPath::Shrm
            | prt_scene_relight::GlossyPath::Auto => {
                unreachable!("checked by their own tests")
            }
            prt_scene_relight::GlossyPath::Fitted => {
                let el = &fitted.elevations;
                let i = el.partition_point(|&t| t <= theta_o).clamp(1, el.len() - 1);
                let e_fit = fitted.error[i - 1].max(fitted.error[i]);
                // ‖w‖ ≤ Σ_k ‖A^k_l y(a_k)‖ = Σ_k √(Σ_l (2l+1)/(4π) (A^k_l)²), either row.
                let k = fitted.lobes;
                let w_norm = [i - 1, i]
                    .iter()
                    .map(|&e| {
                        (0..k)
                            .map(|j| {
                                let row = &fitted.bands[(e * k + j) * order..][..order];
                                row.iter()
                                    .enumerate()
                                    .map(|(l, a)| {
                                        (2 * l + 1) as f64 / (4.0 * std::f64::consts::PI) * a * a
                                    })
                                    .sum::<f64>()
                                    .sqrt()
                            })
                            .sum::<f64>()
                    })
                    .fold(0.0, f64::max);
                let interp =
                    (albedo_and_norm(&ward, el[i - 1]).0 - albedo_and_norm(&ward, el[i]).0).abs();
                dv * w_norm + (2.0 * std::f64::consts::PI).sqrt() * e_fit * f_norm + interp
            }
        };
        let got = f64::from(relit.radiance[0][p][0]);
        assert!(
            (got - rho).abs() <= bound,
            "vertex {p}: θ_o {theta_o:.3}: relit {got} vs ρ {rho} (bound {bound})"
        );
        worst = worst.max((got - rho).abs() / rho);
        checked += 1;
        if checked > 40 {
            break;
        }
    }
    assert!(checked > 10, "only {checked} vertices checked");
    eprintln!("{} {path:?}, order {order}: worst relative error {worst:.4} over {checked} vertices (table error e_n = {e_n:.4})", ward.type_name());
}

/// The hybrid glossy path is the fitted path where the fit is good and the exact path where it
/// is not, point by point: at `fit_error = 0` every point is shaded exactly (the image is the
/// exact path's, bit for bit, `pbr` diffuse factor included), above every fit error it is the
/// fitted path's, and in between each point's radiance is one of the two, exact where the
/// fit's error at its view elevation reaches the threshold. A grey metal at roughness 0.4 on a
/// sphere under a two-tone sky, seen from the side so that every view elevation occurs.
#[test]
fn hybrid_glossy_path_is_exact_where_the_fit_is_poor_and_fitted_elsewhere() {
    let metal = Material::Pbr {
        base_color: [0.9, 0.8, 0.6],
        metallic: 0.7,
        roughness: 0.4,
        base_color_texture: None,
        metallic_roughness_texture: None,
    };
    let cam = Camera::look_at(DVec3::new(0.0, 0.0, 4.0), DVec3::ZERO, 40.0, 16, 16);
    // Lat-long, 16 × 8: the upper four rows a bright sky, the lower four a dark ground.
    let sky = Environment {
        image: prt_scene::EnvImage {
            width: 16,
            height: 8,
            texels: (0..128)
                .map(|i| if i < 64 { [2.0, 1.8, 1.5] } else { [0.3; 3] })
                .collect(),
        },
        mapping: prt_scene::Mapping::LatLong,
        rotation_y_deg: 0.0,
    };
    let mut scene = Scene::new(cam, sky);
    let m = scene.add_material("metal", metal);
    scene.add_mesh(icosphere(2), m);
    let accel = prt_tracer::Accel::build(&scene).unwrap();
    let order = 6;
    let out = bake(
        &scene,
        &accel,
        &BakeSettings {
            order: Some(order),
            rays: 256,
            bounces: 0,
            ..BakeSettings::final_quality()
        },
    )
    .unwrap();
    let run = |glossy| {
        let opt = prt_scene_relight::RelightOptions {
            glossy,
            ..Default::default()
        };
        prt_scene_relight::relight(&scene, &accel, &out.bake, &opt).unwrap()
    };
    let exact = run(prt_scene_relight::GlossyPath::Exact);
    let fitted = run(prt_scene_relight::GlossyPath::Fitted);
    assert!(
        exact.radiance[0] != fitted.radiance[0],
        "the paths differ here"
    );
    let all = run(prt_scene_relight::GlossyPath::Hybrid { fit_error: 0.0 });
    assert!(
        all.radiance[0] == exact.radiance[0],
        "fit_error 0: the exact path"
    );
    let none = run(prt_scene_relight::GlossyPath::Hybrid { fit_error: 10.0 });
    assert!(
        none.radiance[0] == fitted.radiance[0],
        "fit_error 10: the fitted path"
    );
    // In between: exact exactly where the fit's error at the point's view elevation reaches the
    // threshold (the table's errors, linear in θ_o between its elevations); the threshold is
    // the median of the visible points' errors, so both sets are large.
    let table = prt_shading::projection::fitted_table(&metal, order).unwrap();
    let eye = Vec3::new(0.0, 0.0, 4.0);
    let mesh = &scene.meshes[0];
    let errors: Vec<f64> = (0..mesh.positions.len())
        .map(|p| {
            let n = mesh.normals[p].normalize();
            let cos_o = n.dot((eye - mesh.positions[p]).normalize());
            let theta = f64::from(cos_o.clamp(-1.0, 1.0).acos()).min(std::f64::consts::FRAC_PI_2);
            let el = &table.elevations;
            if theta <= el[0] {
                table.error[0]
            } else if theta >= el[el.len() - 1] {
                table.error[el.len() - 1]
            } else {
                let i = el.partition_point(|&x| x <= theta) - 1;
                let w = (theta - el[i]) / (el[i + 1] - el[i]);
                table.error[i] * (1.0 - w) + table.error[i + 1] * w
            }
        })
        .collect();
    // (Over the points facing the camera: those facing away all sit at the last elevation.)
    let mut sorted: Vec<f64> = errors
        .iter()
        .zip(&mesh.positions)
        .zip(&mesh.normals)
        .filter(|((_, x), n)| n.normalize().dot((eye - **x).normalize()) > 0.05)
        .map(|((e, _), _)| *e)
        .collect();
    sorted.sort_by(f64::total_cmp);
    let t = sorted[sorted.len() / 2] as f32;
    let mid = run(prt_scene_relight::GlossyPath::Hybrid { fit_error: t });
    let (mut n_exact, mut n_fitted) = (0, 0);
    for (p, (r, &e)) in mid.radiance[0].iter().zip(&errors).enumerate() {
        // Away from the threshold (f32 interpolation in prt, f64 here).
        if (e - f64::from(t)).abs() < 1e-4 {
            continue;
        }
        if e >= f64::from(t) {
            assert_eq!(
                *r, exact.radiance[0][p],
                "point {p}: fit error {e:.3}, exact"
            );
            n_exact += 1;
        } else {
            assert_eq!(
                *r, fitted.radiance[0][p],
                "point {p}: fit error {e:.3}, fitted"
            );
            n_fitted += 1;
        }
    }
    eprintln!("hybrid at {t}: {n_exact} points exact, {n_fitted} fitted");
    assert!(
        n_exact > 10 && n_fitted > 10,
        "{n_exact} exact, {n_fitted} fitted"
    );
}
