//! Pearson chi-square goodness-of-fit test of a direction sampler against its pdf.
//!
//! The sphere is cut into `cos_bins × phi_bins` cells, equal in `cos θ = z ∈ [−1, 1]` and
//! `φ = atan2(y, x) ∈ [0, 2π)` (so equal in solid angle). Expected counts are
//! `samples × ∫_cell pdf dω` by nested adaptive Simpson quadrature in `(z, φ)`
//! (`dω = dz dφ`). Samples the sampler rejects (`None`) form one extra cell whose expected
//! count is `samples × (1 − ∫ pdf dω)`: a pdf that loses mass below the horizon must reject
//! exactly that often. Cells with expected counts below `min_expected` (default 5) are pooled
//! into one cell (pbrt's rule); a cell with (practically) zero expected count that receives
//! samples fails the test outright. The p-value is the upper tail of the χ² distribution,
//! `Q(dof/2, stat/2)`, with the regularised incomplete gamma function written here
//! (series and Lentz continued fraction, Numerical Recipes §6.2). Use [`sidak`] to turn a
//! suite-wide significance (0.01 in this workspace) into the per-test level.
//!
//! ```
//! use prt_shading::chi2::{sidak, Chi2Test};
//! use prt_shading::{sample_uniform_sphere, uniform_sphere_pdf};
//! let test = Chi2Test { samples: 100_000, seed: 1, ..Chi2Test::default() };
//! let report = test.run(|u| Some(sample_uniform_sphere([u[0], u[1]])), |_| f64::from(uniform_sphere_pdf()));
//! report.assert_passes(sidak(0.01, 1), "uniform sphere");
//! ```

use glam::{DVec3, Vec3};
use prt_scene::Material;
use rand::{Rng, SeedableRng};
use std::f64::consts::TAU;

/// Parameters of a chi-square test over the sphere.
#[derive(Clone, Debug)]
pub struct Chi2Test {
    /// Number of cells in `cos θ` (z from −1 to 1).
    pub cos_bins: usize,
    /// Number of cells in `φ`.
    pub phi_bins: usize,
    /// Number of sampler calls.
    pub samples: usize,
    /// Seed of the PCG stream of uniform numbers.
    pub seed: u64,
    /// Cells with a smaller expected count are pooled.
    pub min_expected: f64,
    /// Absolute tolerance of the quadrature of each cell's probability.
    pub quadrature_tolerance: f64,
}

impl Default for Chi2Test {
    fn default() -> Self {
        Self {
            cos_bins: 16,
            phi_bins: 32,
            samples: 1_000_000,
            seed: 0,
            min_expected: 5.0,
            quadrature_tolerance: 1e-9,
        }
    }
}

/// Result of [`Chi2Test::run`].
#[derive(Clone, Debug)]
pub struct Chi2Report {
    /// Pearson statistic after pooling.
    pub statistic: f64,
    /// Degrees of freedom (cells after pooling − 1).
    pub dof: usize,
    /// Upper-tail probability of the statistic.
    pub p_value: f64,
    /// Observed counts per cell (`cos_bins × phi_bins`, row = z cell), before pooling.
    pub observed: Vec<f64>,
    /// Expected counts per cell, before pooling.
    pub expected: Vec<f64>,
    /// Number of rejected samples (`None`).
    pub rejected: usize,
    /// `∫ pdf dω` over the sphere by quadrature.
    pub pdf_integral: f64,
    /// Set when the test failed outright (samples where the pdf is zero, pdf integral > 1).
    pub error: Option<String>,
}

impl Chi2Report {
    /// True when there is no outright error and `p_value ≥ alpha`.
    #[must_use]
    pub fn passes(&self, alpha: f64) -> bool {
        self.error.is_none() && self.p_value >= alpha
    }

    /// Panics with a readable summary (and the worst cells) when the test fails at level `alpha`.
    pub fn assert_passes(&self, alpha: f64, name: &str) {
        if self.passes(alpha) {
            return;
        }
        let mut worst: Vec<(usize, f64)> = self
            .observed
            .iter()
            .zip(&self.expected)
            .enumerate()
            .map(|(i, (o, e))| (i, (o - e) * (o - e) / e.max(1e-300)))
            .collect();
        worst.sort_by(|a, b| b.1.total_cmp(&a.1));
        let cells: Vec<String> = worst
            .iter()
            .take(6)
            .map(|&(i, c)| {
                format!(
                    "cell {i} obs {} exp {:.1} (χ² {c:.1})",
                    self.observed[i], self.expected[i]
                )
            })
            .collect();
        panic!(
            "{name}: chi-square test failed: {} statistic {:.2}, dof {}, p = {:.3e} < {alpha:.3e}; \
             ∫pdf = {:.6}, rejected {}; worst: {}",
            self.error.as_deref().unwrap_or(""),
            self.statistic,
            self.dof,
            self.p_value,
            self.pdf_integral,
            self.rejected,
            cells.join("; ")
        );
    }
}

impl Chi2Test {
    /// Cell of a unit direction.
    #[must_use]
    pub fn cell(&self, d: Vec3) -> usize {
        let z = f64::from(d.z).clamp(-1.0, 1.0);
        let row = (((z + 1.0) * 0.5 * self.cos_bins as f64) as usize).min(self.cos_bins - 1);
        let mut phi = f64::from(d.y).atan2(f64::from(d.x));
        if phi < 0.0 {
            phi += TAU;
        }
        let col = ((phi / TAU * self.phi_bins as f64) as usize).min(self.phi_bins - 1);
        row * self.phi_bins + col
    }

    /// `∫_cell pdf dω` for every cell, by nested adaptive Simpson quadrature.
    #[must_use]
    pub fn cell_probabilities(&self, pdf: impl Fn(Vec3) -> f64) -> Vec<f64> {
        let (nz, nphi) = (self.cos_bins, self.phi_bins);
        let mut out = Vec::with_capacity(nz * nphi);
        for row in 0..nz {
            let z0 = -1.0 + 2.0 * row as f64 / nz as f64;
            let z1 = -1.0 + 2.0 * (row + 1) as f64 / nz as f64;
            for col in 0..nphi {
                let p0 = TAU * col as f64 / nphi as f64;
                let p1 = TAU * (col + 1) as f64 / nphi as f64;
                let tol = self.quadrature_tolerance;
                // The inner integral is 10× tighter (absolute and relative) than the outer one,
                // so its own error does not look like structure to the outer recursion.
                let inner_tol = 0.1 * tol / (z1 - z0);
                let v = integrate_rel(
                    |z| {
                        let s = (1.0 - z * z).max(0.0).sqrt();
                        integrate_rel(
                            |phi| pdf(DVec3::new(s * phi.cos(), s * phi.sin(), z).as_vec3()),
                            p0,
                            p1,
                            inner_tol,
                            1e-6,
                        )
                    },
                    z0,
                    z1,
                    tol,
                    1e-5,
                );
                out.push(v);
            }
        }
        out
    }

    /// Runs the test: `sample` maps three uniform numbers to a direction (or `None`), `pdf` is
    /// the claimed solid-angle density (it may integrate to less than 1; see module docs).
    pub fn run(
        &self,
        mut sample: impl FnMut([f32; 3]) -> Option<Vec3>,
        pdf: impl Fn(Vec3) -> f64,
    ) -> Chi2Report {
        let n = self.samples as f64;
        let cells = self.cos_bins * self.phi_bins;
        let mut observed = vec![0.0; cells];
        let mut rejected = 0usize;
        let mut rng = rand_pcg::Pcg64::seed_from_u64(self.seed);
        let mut error = None;
        for _ in 0..self.samples {
            let u = [
                rng.random::<f32>(),
                rng.random::<f32>(),
                rng.random::<f32>(),
            ];
            match sample(u) {
                Some(d) if d.is_finite() && (d.length() - 1.0).abs() < 1e-3 => {
                    observed[self.cell(d)] += 1.0
                }
                Some(d) => {
                    error.get_or_insert(format!("sampler returned a non-unit direction {d}"));
                }
                None => rejected += 1,
            }
        }
        let probs = self.cell_probabilities(pdf);
        let pdf_integral: f64 = probs.iter().sum();
        let expected: Vec<f64> = probs.iter().map(|p| p * n).collect();
        if pdf_integral > 1.0 + 1e-4 {
            error.get_or_insert(format!("pdf integrates to {pdf_integral} > 1"));
        }
        let mut obs_all = observed.clone();
        let mut exp_all = expected.clone();
        obs_all.push(rejected as f64);
        exp_all.push(n * (1.0 - pdf_integral).max(0.0));
        let (statistic, dof) = match pearson(&obs_all, &exp_all, self.min_expected) {
            Ok(v) => v,
            Err(e) => {
                error.get_or_insert(e);
                (f64::INFINITY, 1)
            }
        };
        let p_value = if dof == 0 {
            1.0
        } else {
            chi2_p_value(statistic, dof)
        };
        Chi2Report {
            statistic,
            dof,
            p_value,
            observed,
            expected,
            rejected,
            pdf_integral,
            error,
        }
    }

    /// Chi-square test of [`crate::sample`] against [`crate::pdf`] for `mat` at normal `n` and
    /// outgoing `wo`. Delta-lobe samples count as rejected, since `pdf` excludes them.
    pub fn run_bsdf(&self, mat: &Material, n: Vec3, wo: Vec3) -> Chi2Report {
        self.run(
            |u| {
                crate::sample(mat, n, wo, u)
                    .filter(|s| !s.is_delta)
                    .map(|s| s.wi)
            },
            |wi| f64::from(crate::pdf(mat, n, wo, wi)),
        )
    }

    /// Chi-square test of lobe splitting ([`crate::sample_lobe`]) for `mat` at normal `n` and
    /// outgoing `wo`: a lobe of [`crate::SPLIT_LOBES`] chosen with probability ½ each (by
    /// `u[0]`), then sampled alone, has the density `split_pdf / 2` if [`crate::split_pdf`]
    /// is the sum of the lobes' own densities, as the split estimator's weights assume.
    /// Delta-lobe samples count as rejected, since `split_pdf` excludes them.
    pub fn run_split(&self, mat: &Material, n: Vec3, wo: Vec3) -> Chi2Report {
        self.run(
            |u| {
                let lobe = crate::SPLIT_LOBES[usize::from(u[0] >= 0.5)];
                crate::sample_lobe(mat, n, wo, lobe, [u[1], u[2]])
                    .filter(|s| !s.is_delta)
                    .map(|s| s.wi)
            },
            |wi| 0.5 * f64::from(crate::split_pdf(mat, n, wo, wi)),
        )
    }
}

/// Pearson statistic and degrees of freedom of counts against expected counts, after pooling
/// the cells with expected count below `min_expected`. Errors when a cell with expected count
/// below 1e-4 received samples.
pub fn pearson(
    observed: &[f64],
    expected: &[f64],
    min_expected: f64,
) -> Result<(f64, usize), String> {
    let mut order: Vec<usize> = (0..observed.len()).collect();
    order.sort_by(|&a, &b| expected[a].total_cmp(&expected[b]));
    let (mut pool_o, mut pool_e) = (0.0, 0.0);
    let mut stat = 0.0;
    let mut kept = 0usize;
    let mut smallest_kept: Option<(f64, f64)> = None;
    for &i in &order {
        let (o, e) = (observed[i], expected[i]);
        if e < 1e-4 && o > 0.0 {
            return Err(format!(
                "cell {i} has expected count {e:.2e} but {o} samples"
            ));
        }
        if e < min_expected {
            pool_o += o;
            pool_e += e;
        } else {
            if smallest_kept.is_none() {
                smallest_kept = Some((o, e));
            }
            stat += (o - e) * (o - e) / e;
            kept += 1;
        }
    }
    if pool_e > 0.0 {
        if pool_e >= min_expected || kept == 0 {
            stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
            kept += 1;
        } else if let Some((o, e)) = smallest_kept {
            // Merge the small pool into the smallest kept cell.
            stat -= (o - e) * (o - e) / e;
            let (o2, e2) = (o + pool_o, e + pool_e);
            stat += (o2 - e2) * (o2 - e2) / e2;
        }
    }
    Ok((stat, kept.saturating_sub(1)))
}

/// Per-test significance that keeps the family-wise level `alpha` over `tests` independent
/// tests (Šidák): `1 − (1 − alpha)^(1/tests)`.
#[must_use]
pub fn sidak(alpha: f64, tests: usize) -> f64 {
    1.0 - (1.0 - alpha).powf(1.0 / tests.max(1) as f64)
}

/// Upper-tail probability `P(χ²_dof ≥ stat) = Q(dof/2, stat/2)`.
#[must_use]
pub fn chi2_p_value(stat: f64, dof: usize) -> f64 {
    if !stat.is_finite() {
        return 0.0;
    }
    gamma_q(0.5 * dof as f64, 0.5 * stat.max(0.0))
}

/// `ln Γ(x)` for `x > 0`: Stirling's series after shifting `x` above 20 with `Γ(x+1) = xΓ(x)`.
#[must_use]
pub fn ln_gamma(x: f64) -> f64 {
    let mut shift = 0.0;
    let mut x = x;
    while x < 20.0 {
        shift += x.ln();
        x += 1.0;
    }
    let inv = 1.0 / x;
    let inv2 = inv * inv;
    let series = inv * (1.0 / 12.0 - inv2 * (1.0 / 360.0 - inv2 * (1.0 / 1260.0 - inv2 / 1680.0)));
    (x - 0.5) * x.ln() - x + 0.5 * (TAU).ln() + series - shift
}

/// Regularised lower incomplete gamma `P(a, x)`.
#[must_use]
pub fn gamma_p(a: f64, x: f64) -> f64 {
    1.0 - gamma_q(a, x)
}

/// Regularised upper incomplete gamma `Q(a, x) = Γ(a, x)/Γ(a)`, `a > 0`, `x ≥ 0`.
#[must_use]
pub fn gamma_q(a: f64, x: f64) -> f64 {
    if x <= 0.0 {
        return 1.0;
    }
    let log_prefactor = -x + a * x.ln() - ln_gamma(a);
    if x < a + 1.0 {
        // Series: P = e^{-x} x^a / Γ(a+1) Σ x^k / ((a+1)…(a+k)).
        let mut term = 1.0 / a;
        let mut sum = term;
        let mut ap = a;
        for _ in 0..10_000 {
            ap += 1.0;
            term *= x / ap;
            sum += term;
            if term.abs() < sum.abs() * 1e-16 {
                break;
            }
        }
        (1.0 - sum * log_prefactor.exp()).clamp(0.0, 1.0)
    } else {
        // Continued fraction for Q (modified Lentz).
        const TINY: f64 = 1e-300;
        let mut b = x + 1.0 - a;
        let mut c = 1.0 / TINY;
        let mut d = 1.0 / b;
        let mut h = d;
        for i in 1..10_000 {
            let an = -(i as f64) * (i as f64 - a);
            b += 2.0;
            d = an * d + b;
            if d.abs() < TINY {
                d = TINY;
            }
            c = b + an / c;
            if c.abs() < TINY {
                c = TINY;
            }
            d = 1.0 / d;
            let delta = d * c;
            h *= delta;
            if (delta - 1.0).abs() < 1e-16 {
                break;
            }
        }
        (log_prefactor.exp() * h).clamp(0.0, 1.0)
    }
}

/// Adaptive Simpson quadrature of `f` over `[a, b]` to absolute tolerance `tol`, or relative
/// tolerance 1e-6 where that is larger (pdfs are evaluated in f32, whose rounding noise would
/// otherwise drive the recursion to its depth limit everywhere). Starts from 4 panels, depth at
/// most 16 below them.
pub fn integrate(f: impl Fn(f64) -> f64, a: f64, b: f64, tol: f64) -> f64 {
    integrate_rel(f, a, b, tol, 1e-6)
}

/// [`integrate`] with an explicit relative tolerance.
pub fn integrate_rel(f: impl Fn(f64) -> f64, a: f64, b: f64, tol: f64, rel: f64) -> f64 {
    const PANELS: usize = 4;
    let h = (b - a) / PANELS as f64;
    let mut total = 0.0;
    for k in 0..PANELS {
        let (x0, x1) = (a + h * k as f64, a + h * (k + 1) as f64);
        let xm = 0.5 * (x0 + x1);
        let (f0, fm, f1) = (f(x0), f(xm), f(x1));
        let whole = (x1 - x0) / 6.0 * (f0 + 4.0 * fm + f1);
        total += simpson_step(
            &f,
            [x0, x1],
            [f0, fm, f1],
            whole,
            tol / PANELS as f64,
            rel,
            16,
        );
    }
    total
}

fn simpson_step(
    f: &impl Fn(f64) -> f64,
    [a, b]: [f64; 2],
    [fa, fm, fb]: [f64; 3],
    whole: f64,
    tol: f64,
    rel: f64,
    depth: u32,
) -> f64 {
    let m = 0.5 * (a + b);
    let (lm, rm) = (0.5 * (a + m), 0.5 * (m + b));
    let (flm, frm) = (f(lm), f(rm));
    let left = (m - a) / 6.0 * (fa + 4.0 * flm + fm);
    let right = (b - m) / 6.0 * (fm + 4.0 * frm + fb);
    let both = left + right;
    let err = both - whole;
    if depth == 0 || err.abs() <= 15.0 * tol.max(rel * both.abs()) {
        return both + err / 15.0;
    }
    simpson_step(f, [a, m], [fa, flm, fm], left, 0.5 * tol, rel, depth - 1)
        + simpson_step(f, [m, b], [fm, frm, fb], right, 0.5 * tol, rel, depth - 1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn incomplete_gamma_closed_forms() {
        assert!((ln_gamma(0.5) - std::f64::consts::PI.sqrt().ln()).abs() < 1e-12);
        assert!((ln_gamma(5.0) - 24f64.ln()).abs() < 1e-12);
        assert!((ln_gamma(30.0) - (1..30).map(|k| (k as f64).ln()).sum::<f64>()).abs() < 1e-10);
        for x in [0.01f64, 0.5, 1.0, 2.5, 7.0, 30.0, 200.0] {
            // Q(1, x) = e^{-x}; Q(2, x) = e^{-x}(1 + x); Q(3, x) = e^{-x}(1 + x + x²/2).
            let e = (-x).exp();
            assert!((gamma_q(1.0, x) - e).abs() < 1e-12, "Q(1,{x})");
            assert!((gamma_q(2.0, x) - e * (1.0 + x)).abs() < 1e-12, "Q(2,{x})");
            assert!(
                (gamma_q(3.0, x) - e * (1.0 + x + 0.5 * x * x)).abs() < 1e-12,
                "Q(3,{x})"
            );
        }
        // Median of χ²₁ ≈ 0.454936; 99th percentile of χ²₁₀ = 23.2093.
        assert!((chi2_p_value(0.454_936_4, 1) - 0.5).abs() < 1e-6);
        assert!((chi2_p_value(23.209_25, 10) - 0.01).abs() < 1e-6);
    }

    #[test]
    fn sidak_and_quadrature() {
        assert!((sidak(0.01, 1) - 0.01).abs() < 1e-15);
        assert!((1.0 - (1.0 - sidak(0.01, 50)).powi(50) - 0.01).abs() < 1e-12);
        let v = integrate_rel(|x| x.sin(), 0.0, std::f64::consts::PI, 1e-12, 1e-12);
        assert!((v - 2.0).abs() < 1e-10);
        // Discontinuous integrand.
        let v = integrate(|x| if x < 0.3 { 1.0 } else { 0.0 }, 0.0, 1.0, 1e-9);
        assert!((v - 0.3).abs() < 1e-6, "{v}");
    }

    #[test]
    fn pearson_detects_mismatch_and_support_errors() {
        let exp = vec![100.0; 10];
        let obs = vec![100.0; 10];
        assert_eq!(pearson(&obs, &exp, 5.0).unwrap(), (0.0, 9));
        assert!(pearson(&[1.0, 99.0], &[0.0, 100.0], 5.0).is_err());
        // Pooling: two small cells merge into the smallest kept cell → 2 cells, dof 1.
        let (_, dof) = pearson(&[1.0, 2.0, 50.0, 50.0], &[1.0, 2.0, 50.0, 50.0], 5.0).unwrap();
        assert_eq!(dof, 1);
    }
}
