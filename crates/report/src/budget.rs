//! The error budget of a report: the error of full-order SH relighting against the path
//! tracer, split into named terms, each measured by a controlled experiment on the same scene.
//!
//! All figures are mean squared errors over the object pixels in linear radiance (per channel,
//! averaged over the three channels). With `V_n` the per-vertex relighting at order `n`, `N`
//! the highest order of the bake, `V'_n` the same from a second bake with another seed, `P`
//! the mean of two per-pixel bakes at order `N` (two seeds, so its noise `ν_P` is a quarter
//! of their MSE), and `R` the path-traced reference, `ν_X` the Monte Carlo noise of image `X`
//! (its expected squared error), estimated without bias from two independent estimates
//! (`E[(X − X')²] = 2ν` for two seeds, `E[(A − B)²] = 4ν` for the two half images of one
//! render), and `s_X = MSE(X, R) − ν_X − ν_R` the systematic error of `X`:
//!
//! | term | experiment | what it costs (`terms`) | its own size (`direct`) |
//! |---|---|---|---|
//! | `truncation` | order `n` against order `N` of the same bake | `s_{V_n} − s_{V_N}` | `MSE(V_n, V_N)` |
//! | `interpolation` | per vertex against per pixel at order `N` | `s_{V_N} − s_P` | `MSE(V_N, P) − ν_V(N) − ν_P` |
//! | `bake_noise` | a second bake seed | `ν_V(n) = MSE(V_n, V'_n) / 2` | the same |
//! | `model` | the better of `V_N`, `P` against the path tracer | `min(s_{V_N}, s_P)` | `s_P` |
//! | `reference_noise` | the reference's own half images | `ν_R` | the same |
//!
//! `terms` is a waterfall: starting from the reference's noise, each experiment adds what its
//! approximation costs in error against the path tracer, so they add up to the total
//! `MSE(V_n, R)` exactly, except where a cost is negative (an approximation whose error
//! happens to cancel part of another's, e.g. low-order ringing against a model bias) and is
//! shown as 0; `unaccounted = total − Σ terms` says how much that leaves. `model` is what PRT
//! leaves out beyond the bake's bands and noise: bounces treated as Lambertian, the frozen
//! cosine of the specular term, the bands above `N`; `interpolation` is 0 when per-pixel
//! transfer is no better than per-vertex (a mesh denser than the pixels).
//!
//! `direct` gives each error component's own size, the MSE of the controlled difference; the
//! components add up to the total only when they are uncorrelated, and `cross_terms = total −
//! Σ direct` says how much their correlations take (positive when errors add, negative when
//! they cancel).

use glam::Vec3;
use serde::Serialize;

/// Names of the budget terms, in the order the report stacks them.
pub const TERMS: [&str; 5] = [
    "truncation",
    "interpolation",
    "bake_noise",
    "model",
    "reference_noise",
];

/// One-line explanations of the terms, for the report's text.
pub const TERM_HELP: [(&str, &str); 5] = [
    (
        "truncation",
        "order n against the highest order of the same bake",
    ),
    (
        "interpolation",
        "per-vertex against per-pixel transfer at the highest order, noise removed (0 when per-pixel is no better)",
    ),
    (
        "bake_noise",
        "Monte Carlo noise of the bake: half the MSE between two bake seeds",
    ),
    (
        "model",
        "the better of per-vertex and per-pixel transfer at the highest order against the path tracer, noise removed: bounces as Lambertian, frozen specular cosine, bands above the highest order",
    ),
    (
        "reference_noise",
        "the reference's own noise, from its two half images",
    ),
];

/// The budget of one order (`report.json`: `error_budget`).
#[derive(Clone, Debug, Serialize, PartialEq)]
pub struct BudgetRow {
    /// Order (bands).
    pub order: usize,
    /// `MSE(V_n, R)` over object pixels, linear radiance.
    pub total_mse: f64,
    /// What each approximation costs (see [`TERMS`] and the module docs): they add up to
    /// the total but for `unaccounted`.
    pub terms: serde_json::Map<String, serde_json::Value>,
    /// `Σ terms`.
    pub sum_mse: f64,
    /// `total − Σ terms` (non-zero only where a negative cost was shown as 0).
    pub unaccounted: f64,
    /// Each error component's own size: the MSE of its controlled difference.
    pub direct: serde_json::Map<String, serde_json::Value>,
    /// `total − Σ direct`: what the correlations between the components take.
    pub cross_terms: f64,
    /// `|total − Σ direct| / total`.
    pub cross_fraction: f64,
    /// The name of the largest term.
    pub largest: String,
}

/// The measured inputs of one order's budget.
#[derive(Clone, Copy, Debug)]
pub struct BudgetInputs {
    /// Order.
    pub order: usize,
    /// `MSE(V_n, R)`.
    pub total: f64,
    /// `MSE(V_n, V_N)`.
    pub vs_highest: f64,
    /// `MSE(V_N, P)`.
    pub vertex_vs_pixel: f64,
    /// `MSE(V_N, R)`.
    pub highest_vs_reference: f64,
    /// `MSE(V_n, V'_n)`.
    pub vertex_seeds: f64,
    /// `MSE(V_N, V'_N)`.
    pub vertex_seeds_highest: f64,
    /// Twice the noise of the per-pixel baseline `P` (`MSE(P₁, P₂) / 2` when `P` is the mean
    /// of two seeds `P₁`, `P₂`; `MSE(P, P')` for a single bake `P` and a second one `P'`).
    pub pixel_seeds: f64,
    /// `MSE(P, R)`.
    pub pixel_vs_reference: f64,
    /// `ν_R`.
    pub reference_noise: f64,
}

impl BudgetRow {
    /// The budget from the measured MSEs (see the module docs for the estimates).
    #[must_use]
    pub fn new(m: &BudgetInputs) -> Self {
        let nu_v = m.vertex_seeds / 2.0;
        let nu_v_top = m.vertex_seeds_highest / 2.0;
        let nu_p = m.pixel_seeds / 2.0;
        let nu_r = m.reference_noise;
        // Systematic errors against the path tracer.
        let s_vn = m.total - nu_v - nu_r;
        let s_top = m.highest_vs_reference - nu_v_top - nu_r;
        let s_p = m.pixel_vs_reference - nu_p - nu_r;
        let net = [
            (s_vn - s_top).max(0.0),
            (s_top - s_p).max(0.0),
            nu_v,
            s_top.min(s_p).max(0.0),
            nu_r,
        ];
        let direct = [
            m.vs_highest,
            (m.vertex_vs_pixel - nu_v_top - nu_p).max(0.0),
            nu_v,
            s_p.max(0.0),
            nu_r,
        ];
        let sum: f64 = net.iter().sum();
        let sum_direct: f64 = direct.iter().sum();
        let (largest, _) =
            TERMS.iter().zip(net).fold(
                ("", f64::MIN),
                |acc, (n, v)| if v > acc.1 { (n, v) } else { acc },
            );
        let map = |values: [f64; 5]| {
            TERMS
                .iter()
                .zip(values)
                .map(|(n, v)| ((*n).to_string(), serde_json::json!(v)))
                .collect()
        };
        Self {
            order: m.order,
            total_mse: m.total,
            terms: map(net),
            sum_mse: sum,
            unaccounted: m.total - sum,
            direct: map(direct),
            cross_terms: m.total - sum_direct,
            cross_fraction: if m.total > 0.0 {
                (m.total - sum_direct).abs() / m.total
            } else {
                0.0
            },
            largest: largest.to_string(),
        }
    }

    /// A direct size's value (0 when absent).
    #[must_use]
    pub fn direct(&self, name: &str) -> f64 {
        self.direct
            .get(name)
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(0.0)
    }

    /// A term's value (0 when absent).
    #[must_use]
    pub fn term(&self, name: &str) -> f64 {
        self.terms
            .get(name)
            .and_then(serde_json::Value::as_f64)
            .unwrap_or(0.0)
    }
}

/// Mean over the pixels where `mask` is set and the three channels of `(a − b)²`.
///
/// # Panics
/// When the lengths differ.
#[must_use]
pub fn masked_mse(a: &[Vec3], b: &[Vec3], mask: &[bool]) -> f64 {
    assert!(
        a.len() == b.len() && a.len() == mask.len(),
        "image sizes differ"
    );
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((x, y), &m) in a.iter().zip(b).zip(mask) {
        if m {
            sum += (*x - *y).as_dvec3().length_squared();
            n += 3;
        }
    }
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// Mean over the masked pixels and channels of `d²` (a reference's noise from its half
/// difference `(A − B) / 2`).
#[must_use]
pub fn masked_mean_square(d: &[Vec3], mask: &[bool]) -> f64 {
    let (sum, n) = d
        .iter()
        .zip(mask)
        .filter(|(_, &m)| m)
        .fold((0.0f64, 0usize), |(s, n), (v, _)| {
            (s + v.as_dvec3().length_squared(), n + 3)
        });
    if n == 0 {
        0.0
    } else {
        sum / n as f64
    }
}

/// The PSNR ceiling (dB, 8-bit view at exposure 0, peak 255) that an image's noise sets on
/// the masked pixels, from its radiance `x` and half difference `d = (A − B) / 2`: with the
/// half images `A = x + d`, `B = x − d`, `(sRGB(A) − sRGB(B))² / 4` estimates the squared
/// 8-bit error of `x` (to first order in the noise, like the linear estimate). Infinite for a
/// noiseless image or an empty mask.
#[must_use]
pub fn ldr_noise_psnr(x: &[Vec3], d: &[Vec3], mask: &[bool]) -> f64 {
    let view = |v: f32| 255.0 * f64::from(prt_tracer::output::srgb_encode(v.clamp(0.0, 1.0)));
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((x, d), &m) in x.iter().zip(d).zip(mask) {
        if m {
            for c in 0..3 {
                let e = (view(x[c] + d[c]) - view(x[c] - d[c])) / 2.0;
                sum += e * e;
            }
            n += 3;
        }
    }
    if n == 0 || sum == 0.0 {
        return f64::INFINITY;
    }
    20.0 * (255.0 / (sum / n as f64).sqrt()).log10()
}

/// The sentence that names the largest term of a scene's budget (at its highest order, and
/// at its lowest when that differs).
#[must_use]
pub fn summary_sentence(rows: &[BudgetRow]) -> String {
    let (Some(first), Some(last)) = (rows.first(), rows.last()) else {
        return String::new();
    };
    let share = |r: &BudgetRow| {
        if r.total_mse > 0.0 {
            100.0 * r.term(&r.largest) / r.total_mse
        } else {
            0.0
        }
    };
    let mut s = format!(
        "At order {} the largest term is {} ({:.0} % of the error against the path tracer; the error components' correlations take {:+.0} % of it)",
        last.order,
        last.largest.replace('_', " "),
        share(last),
        100.0 * last.cross_terms / last.total_mse.max(f64::MIN_POSITIVE)
    );
    if first.order != last.order && first.largest != last.largest {
        let _ = std::fmt::Write::write_fmt(
            &mut s,
            format_args!(
                "; at order {} it is {} ({:.0} %)",
                first.order,
                first.largest.replace('_', " "),
                share(first)
            ),
        );
    }
    s.push('.');
    s
}

/// Every order's budget from a report's images (linear radiance, object pixels `mask`):
/// `full[k]` the per-vertex relighting `V_n` at `orders[k]`, `pixel` the two per-pixel bakes'
/// images at the highest order `N` (their mean is `P`), `reference` the path tracer's `R`
/// with noise `ν_R = reference_noise`, and `relight_second_seed(n)` the second-seed vertex
/// bake relit at order `n`, `V'_n` (asked for `N` first, then for every other order in turn).
pub(crate) fn measure_budget<E>(
    orders: &[usize],
    full: &[Vec<Vec3>],
    pixel: [&[Vec3]; 2],
    reference: &[Vec3],
    mask: &[bool],
    reference_noise: f64,
    mut relight_second_seed: impl FnMut(usize) -> Result<Vec<Vec3>, E>,
) -> Result<Vec<BudgetRow>, E> {
    let (bits, r) = (mask, reference);
    let max_order = *orders.iter().max().expect("non-empty");
    let top_index = orders
        .iter()
        .position(|&o| o == max_order)
        .expect("the highest order is in the list");
    let top = &full[top_index];
    let v2_top = relight_second_seed(max_order)?;
    // The per-pixel baseline is the mean of the two per-pixel bakes (half the noise of
    // either); its noise is a quarter of MSE(P, P').
    let [p1, p2] = pixel;
    let p_mean: Vec<Vec3> = p1.iter().zip(p2).map(|(a, b)| 0.5 * (*a + *b)).collect();
    let highest_vs_reference = masked_mse(top, r, bits);
    let (vertex_vs_pixel, pixel_seeds, pixel_vs_reference, vertex_seeds_highest) = (
        masked_mse(top, &p_mean, bits),
        masked_mse(p1, p2, bits) / 2.0,
        masked_mse(&p_mean, r, bits),
        masked_mse(top, &v2_top, bits),
    );
    let mut rows = Vec::new();
    for (&order, img) in orders.iter().zip(full) {
        let v2_n = if order == max_order {
            v2_top.clone()
        } else {
            relight_second_seed(order)?
        };
        rows.push(BudgetRow::new(&BudgetInputs {
            order,
            total: masked_mse(img, r, bits),
            vs_highest: masked_mse(img, top, bits),
            vertex_vs_pixel,
            highest_vs_reference,
            vertex_seeds: masked_mse(img, &v2_n, bits),
            vertex_seeds_highest,
            pixel_seeds,
            pixel_vs_reference,
            reference_noise,
        }));
    }
    Ok(rows)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Synthetic images whose errors are independent by construction: the budget recovers
    /// each planted term and the terms add up.
    #[test]
    fn planted_terms_are_recovered() {
        use rand::{Rng, SeedableRng};
        let n = 200_000;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(1);
        let mut g = |s: f32| -> Vec3 {
            // A sum of 12 uniforms: near-Gaussian with variance s².
            let mut v = [0.0f32; 3];
            for c in &mut v {
                *c = ((0..12).map(|_| rng.random::<f32>()).sum::<f32>() - 6.0) * s;
            }
            Vec3::from_array(v)
        };
        // truth T; model error m; interpolation error i; truncation t; noises.
        let (sm, si, st, sv, sp, sr) = (0.04, 0.03, 0.02, 0.01, 0.015, 0.005);
        let img = |f: &mut dyn FnMut(usize) -> Vec3| (0..n).map(f).collect::<Vec<_>>();
        let truth = img(&mut |k| Vec3::splat(0.5 + 0.1 * (k as f32 * 0.001).sin()));
        let model = img(&mut |_| g(sm));
        let interp = img(&mut |_| g(si));
        let trunc = img(&mut |_| g(st));
        let nv = img(&mut |_| g(sv));
        let nv2 = img(&mut |_| g(sv));
        let np = img(&mut |_| g(sp));
        let np2 = img(&mut |_| g(sp));
        let nr = img(&mut |_| g(sr));
        let p: Vec<Vec3> = (0..n).map(|k| truth[k] + model[k] + np[k]).collect();
        let p2: Vec<Vec3> = (0..n).map(|k| truth[k] + model[k] + np2[k]).collect();
        let vn_top: Vec<Vec3> = (0..n)
            .map(|k| truth[k] + model[k] + interp[k] + nv[k])
            .collect();
        let vn_top2: Vec<Vec3> = (0..n)
            .map(|k| truth[k] + model[k] + interp[k] + nv2[k])
            .collect();
        let vn: Vec<Vec3> = (0..n).map(|k| vn_top[k] + trunc[k]).collect();
        let vn2: Vec<Vec3> = (0..n).map(|k| vn_top2[k] + trunc[k]).collect();
        let r: Vec<Vec3> = (0..n).map(|k| truth[k] + nr[k]).collect();
        let mask = vec![true; n];
        let row = BudgetRow::new(&BudgetInputs {
            order: 3,
            total: masked_mse(&vn, &r, &mask),
            vs_highest: masked_mse(&vn, &vn_top, &mask),
            vertex_vs_pixel: masked_mse(&vn_top, &p, &mask),
            highest_vs_reference: masked_mse(&vn_top, &r, &mask),
            vertex_seeds: masked_mse(&vn, &vn2, &mask),
            vertex_seeds_highest: masked_mse(&vn_top, &vn_top2, &mask),
            pixel_seeds: masked_mse(&p, &p2, &mask),
            pixel_vs_reference: masked_mse(&p, &r, &mask),
            reference_noise: f64::from(sr * sr),
        });
        // Each estimate is a mean of 600k squares: relative standard error ~ √(2/600k) for a
        // plain variance, a few times that for a difference of estimates; 5 % is > 10 σ.
        for (name, s) in [
            ("truncation", st),
            ("interpolation", si),
            ("bake_noise", sv),
            ("model", sm),
            ("reference_noise", sr),
        ] {
            let want = f64::from(s * s);
            for (kind, got) in [("cost", row.term(name)), ("direct", row.direct(name))] {
                assert!(
                    (got - want).abs() <= 0.05 * want + 2e-6,
                    "{name} ({kind}): {got} vs planted {want}"
                );
            }
        }
        // Independent components: no cross terms, and the costs add up exactly.
        assert!(row.cross_fraction < 0.02, "{row:?}");
        assert!(row.unaccounted.abs() < 1e-12, "{row:?}");
        assert_eq!(row.largest, "model");
        assert!(summary_sentence(&[row]).contains("model"));
    }

    /// A per-pixel bake that is worse than the per-vertex one (its own error `e`, a mesh
    /// denser than the pixels): interpolation costs nothing, the model term is the per-vertex
    /// error, and the costs still add up; the direct sizes show the anti-correlation.
    #[test]
    fn a_worse_per_pixel_bake_costs_no_interpolation() {
        let m = BudgetInputs {
            order: 5,
            // V_n = T + a + t, V_N = T + a, P = T + e, R = T (no noise anywhere).
            total: 3.0,                 // |a + t|², a ⟂ t, |a|² = 2, |t|² = 1
            vs_highest: 1.0,            // |t|²
            vertex_vs_pixel: 2.0 + 4.0, // |a − e|², a ⟂ e, |e|² = 4
            highest_vs_reference: 2.0,
            vertex_seeds: 0.0,
            vertex_seeds_highest: 0.0,
            pixel_seeds: 0.0,
            pixel_vs_reference: 4.0,
            reference_noise: 0.0,
        };
        let row = BudgetRow::new(&m);
        assert_eq!(row.term("interpolation"), 0.0);
        assert_eq!(row.term("model"), 2.0);
        assert_eq!(row.term("truncation"), 1.0);
        assert_eq!(row.unaccounted, 0.0);
        // Direct: 1 + 6 + 0 + 4 + 0 = 11 against a total of 3.
        assert_eq!(row.cross_terms, 3.0 - 11.0);
        assert_eq!(row.largest, "model");
    }

    #[test]
    fn mse_uses_the_mask_only() {
        let a = [Vec3::ONE, Vec3::ZERO];
        let b = [Vec3::ZERO, Vec3::splat(100.0)];
        assert_eq!(masked_mse(&a, &b, &[true, false]), 1.0);
        assert_eq!(masked_mse(&a, &b, &[false, false]), 0.0);
    }

    #[test]
    fn measure_budget_feeds_each_order_its_controlled_differences() {
        // One object pixel and one background pixel (far off, to show it is left out); every
        // offset is a power of two, so each MSE below is exact.
        let image = |v: f32| vec![Vec3::splat(v), Vec3::splat(9.0)];
        let mask = [true, false];
        let reference = image(1.0);
        // V_2 and V_4 (the highest) off by 1/2 and 1/4; V'_n a further 1/8 off; the two
        // per-pixel bakes 1/8 either side of R, so their mean is R.
        let full = vec![image(1.5), image(1.25)];
        let (p1, p2) = (image(1.125), image(0.875));
        let mut asked = Vec::new();
        let rows = measure_budget::<()>(&[2, 4], &full, [&p1, &p2], &reference, &mask, 1e-3, |n| {
            asked.push(n);
            Ok(image(if n == 4 { 1.375 } else { 1.625 }))
        })
        .unwrap();
        assert_eq!(asked, [4, 2]);
        let inputs = |order, total, vs_highest| BudgetInputs {
            order,
            total,
            vs_highest,
            vertex_vs_pixel: 0.0625,
            highest_vs_reference: 0.0625,
            vertex_seeds: 0.015625,
            vertex_seeds_highest: 0.015625,
            pixel_seeds: 0.03125,
            pixel_vs_reference: 0.0,
            reference_noise: 1e-3,
        };
        assert_eq!(
            rows,
            [
                BudgetRow::new(&inputs(2, 0.25, 0.0625)),
                BudgetRow::new(&inputs(4, 0.0625, 0.0)),
            ]
        );
    }
}
