//! Locally adaptive relighting (Lee & Kim 2014, ch. 5) on a synthetic sphere: exactness at
//! T = 0, monotone error and work in T, statistics.

mod common;

use glam::DVec3;
use prt_relight::{
    AdaptiveInput, AdaptiveParams, Adjacency, DiffuseParams, FrameLighting, Lighting, PhongParams,
    RelightError, Relighter, SpecularInput, Surface, Threshold, TransferView, Viewer,
};

struct Scene {
    order: usize,
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    diffuse: Vec<f32>,
    visibility: Vec<f32>,
    adjacency: Adjacency,
    relighter: Relighter,
    frame: FrameLighting,
}

fn scene(order: usize, subdivisions: u32) -> Scene {
    let mesh = prt_scene::test_util::icosphere(subdivisions);
    let (positions, normals) = common::arrays(&mesh);
    let (diffuse, visibility) = common::synthetic_transfer(&mesh.positions, &mesh.normals, order);
    let adjacency = Adjacency::from_triangles(positions.len(), &mesh.indices).unwrap();
    adjacency.validate().unwrap();
    let relighter = Relighter::new(order).unwrap();
    let env = common::sun_sky(order, DVec3::new(0.5, 0.7, 0.5));
    let frame = relighter
        .frame_lighting(&Lighting::from_rgb_coefficients(&env, None).unwrap(), true)
        .unwrap();
    Scene {
        order,
        positions,
        normals,
        diffuse,
        visibility,
        adjacency,
        relighter,
        frame,
    }
}

const ALBEDO: [f32; 3] = [0.8, 0.7, 0.6];

impl Scene {
    fn input(&self) -> AdaptiveInput<'_> {
        AdaptiveInput {
            diffuse: Some((
                TransferView::new(self.order, 1, &self.diffuse).unwrap(),
                DiffuseParams::from_albedo(ALBEDO),
            )),
            specular: Some(SpecularInput {
                visibility: TransferView::new(self.order, 1, &self.visibility).unwrap(),
                surface: Surface {
                    positions: &self.positions,
                    normals: &self.normals,
                },
                viewer: Viewer::Eye([0.4, 0.8, 3.0]),
                phong: PhongParams {
                    specular: [0.5; 3],
                    exponent: 40.0,
                },
            }),
            adjacency: &self.adjacency,
        }
    }

    fn full(&self) -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let i = self.input();
        let (t, p) = i.diffuse.unwrap();
        (
            self.relighter.diffuse(&t, &self.frame, &p).unwrap(),
            self.relighter
                .specular(&i.specular.unwrap(), &self.frame)
                .unwrap(),
        )
    }
}

fn rms(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let s: f64 = a
        .iter()
        .zip(b)
        .flat_map(|(x, y)| (0..3).map(move |c| f64::from(x[c] - y[c]).powi(2)))
        .sum();
    (s / (3 * a.len()) as f64).sqrt()
}

#[test]
fn test01_threshold_zero_is_bit_identical_to_full_order() {
    for order in [2usize, 3, 4, 9] {
        let s = scene(order, 2);
        let (fd, fs) = s.full();
        let out = s
            .relighter
            .adaptive(&s.input(), &s.frame, &AdaptiveParams::exact())
            .unwrap();
        assert_eq!(out.diffuse, fd, "order {order}");
        assert_eq!(out.specular, fs, "order {order}");
        for st in [out.stats.diffuse.unwrap(), out.stats.specular.unwrap()] {
            assert_eq!(st.full_order_fraction, 1.0);
            assert_eq!(st.products, st.full_order_products);
            assert_eq!(st.refined_points, 0);
            assert_eq!(st.smoothed_points, [0, 0]);
        }
    }
}

#[test]
fn test02_error_grows_and_work_falls_with_the_threshold() {
    let s = scene(10, 3);
    let (fd, fs) = s.full();
    let mean: f64 = fd
        .iter()
        .chain(&fs)
        .flatten()
        .map(|v| f64::from(*v))
        .sum::<f64>()
        / (3 * fd.len()) as f64;
    println!("mean radiance {mean:.4}");
    println!("refine smooth T | rms_diffuse rms_specular | work_d/full work_s/full | full_frac_d full_frac_s");
    for (refine, smooth) in [(false, false), (true, false), (true, true)] {
        let mut last: Option<(f64, f64, u64, u64)> = None;
        for t in [0.0f32, 0.001, 0.003, 0.01, 0.03, 0.1, 0.3] {
            let p = AdaptiveParams {
                threshold: Threshold::Absolute(t),
                refine,
                smooth,
            };
            let out = s.relighter.adaptive(&s.input(), &s.frame, &p).unwrap();
            let (d, sp) = (out.stats.diffuse.unwrap(), out.stats.specular.unwrap());
            let (ed, es) = (rms(&out.diffuse, &fd), rms(&out.specular, &fs));
            println!(
                "{refine} {smooth} {t} | {ed:.2e} {es:.2e} | {:.3} {:.3} | {:.3} {:.3}",
                d.products as f64 / d.full_order_products as f64,
                sp.products as f64 / sp.full_order_products as f64,
                d.full_order_fraction,
                sp.full_order_fraction
            );
            // The level fractions: every active point has the base bands; the rest fall.
            for st in [&d, &sp] {
                assert!(st.level_fraction[..3].iter().all(|f| *f == 1.0));
                assert!(st.level_fraction.windows(2).all(|w| w[1] <= w[0]));
            }
            if let Some((led, les, lwd, lws)) = last {
                assert!(
                    d.products <= lwd && sp.products <= lws,
                    "work must not grow with T"
                );
                assert!(
                    ed >= led && es >= les,
                    "error must not fall as T grows (T = {t})"
                );
            }
            last = Some((ed, es, d.products, sp.products));
        }
        // At the largest threshold some work must have been saved.
        let (_, _, wd, ws) = last.unwrap();
        let full = s
            .relighter
            .adaptive(&s.input(), &s.frame, &AdaptiveParams::exact())
            .unwrap()
            .stats;
        assert!(wd < full.diffuse.unwrap().products && ws < full.specular.unwrap().products);
    }
}

#[test]
fn test03_relative_threshold_resolves_to_the_mean_base_radiance() {
    let s = scene(6, 2);
    let rel = AdaptiveParams {
        threshold: Threshold::RelativeToMean(0.05),
        refine: true,
        smooth: true,
    };
    let a = s.relighter.adaptive(&s.input(), &s.frame, &rel).unwrap();
    // The mean base radiance recomputed independently in f64: diffuse albedo/π Σ_{i<9} L_i T_i;
    // specular (e+2)/(e+1) cos θ_o · ks Σ_{i,j<9} A_l y_i(r) M(L)_ij V_j, with M(L) the order-6
    // product matrix (the lighting's bands 3..6 do reach the low bands of L ⊛ V).
    let order = 6;
    let n2 = order * order;
    let gaunt = prt_sh::GauntTensor::new(order).unwrap();
    let basis = prt_sh::Basis::new(order).unwrap();
    let lobe = prt_sh::zonal::phong_lobe_bands(40.0, order).unwrap();
    let light: Vec<Vec<f64>> = (0..3)
        .map(|c| {
            s.frame.lighting.rgb[c]
                .iter()
                .map(|v| f64::from(*v))
                .collect()
        })
        .collect();
    let mats: Vec<Vec<f64>> = light
        .iter()
        .map(|l| gaunt.product_matrix(l).unwrap())
        .collect();
    let eye = DVec3::new(0.4, 0.8, 3.0);
    let mut sum = 0.0f64;
    for v in 0..s.positions.len() {
        let t = &s.diffuse[v * n2..(v + 1) * n2];
        let vis = &s.visibility[v * n2..(v + 1) * n2];
        let n = DVec3::from(s.normals[v].map(f64::from)).normalize();
        let wo = (eye - DVec3::from(s.positions[v].map(f64::from))).normalize();
        let cos_o = n.dot(wo);
        let y = basis.eval(2.0 * cos_o * n - wo);
        for c in 0..3 {
            sum += f64::from(ALBEDO[c]) / std::f64::consts::PI
                * (0..9).map(|i| light[c][i] * f64::from(t[i])).sum::<f64>();
            if cos_o > 0.0 {
                let mut spec = 0.0;
                for i in 0..9 {
                    let w = lobe[prt_sh::degree_and_order(i).0] * y[i];
                    for j in 0..9 {
                        spec += w * mats[c][i * n2 + j] * f64::from(vis[j]);
                    }
                }
                sum += 0.5 * 42.0 / 41.0 * cos_o * spec;
            }
        }
    }
    let mean = sum / (3 * s.positions.len()) as f64;
    let t = a.stats.threshold;
    assert!(
        (f64::from(t) - 0.05 * mean).abs() <= 1e-5 * 0.05 * mean,
        "{t} vs {}",
        0.05 * mean
    );
    let abs = AdaptiveParams {
        threshold: Threshold::Absolute(t),
        ..rel
    };
    let b = s.relighter.adaptive(&s.input(), &s.frame, &abs).unwrap();
    assert_eq!(a.diffuse, b.diffuse);
    assert_eq!(a.specular, b.specular);
    let json = serde_json::to_value(&a.stats).unwrap();
    assert!(json["specular"]["level_fraction"].as_array().unwrap().len() == 6);
    assert!(json["diffuse"]["products"].as_u64().unwrap() > 0);
}

#[test]
fn test04_bad_inputs_are_errors() {
    let s = scene(4, 1);
    let other = Adjacency::from_triangles(3, &[[0, 1, 2]]).unwrap();
    let mut i = s.input();
    i.adjacency = &other;
    assert!(matches!(
        s.relighter
            .adaptive(&i, &s.frame, &AdaptiveParams::thesis()),
        Err(RelightError::PointCount { .. })
    ));
    let p = AdaptiveParams {
        threshold: Threshold::Absolute(f32::NAN),
        refine: false,
        smooth: false,
    };
    assert!(matches!(
        s.relighter.adaptive(&s.input(), &s.frame, &p),
        Err(RelightError::InvalidParameter(_))
    ));
}

#[test]
fn test05_adaptive_result_does_not_depend_on_the_thread_count() {
    let s = scene(8, 3);
    let p = AdaptiveParams::thesis();
    let a = s.relighter.adaptive(&s.input(), &s.frame, &p).unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let b = pool.install(|| s.relighter.adaptive(&s.input(), &s.frame, &p).unwrap());
    assert_eq!(a.diffuse, b.diffuse);
    assert_eq!(a.specular, b.specular);
    let (mut sa, mut sb) = (a.stats, b.stats);
    for st in [&mut sa, &mut sb] {
        st.seconds = 0.0;
        for t in [&mut st.diffuse, &mut st.specular].into_iter().flatten() {
            t.seconds = 0.0;
        }
    }
    assert_eq!(sa, sb);
}
