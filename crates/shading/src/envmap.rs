//! Importance sampling of a distant environment map with exactly the pdf of its
//! piecewise-constant radiance.
//!
//! A texel is chosen from a [`Distribution2D`] (marginal over rows, conditional over columns)
//! with weight `luminance × solid angle`, then a direction inside it:
//!
//! * **Lat-long**: uniform in `φ` and in `cos θ` over the texel's range, which is uniform in
//!   solid angle, so `pdf(ω) = p_texel / Ω_texel` with the exact
//!   `Ω_texel = (2π/W)(cos θ₀ − cos θ₁)`. Then `radiance / pdf = Σ_k L_k Ω_k · rgb / lum`:
//!   constant over the sphere when the colour is the same everywhere (exact proportional
//!   sampling).
//! * **Angular probe**: uniform in `(a, b)` over the part of the texel inside the unit disc
//!   (texels entirely outside have zero weight; rim texels are sampled in their clipped part
//!   by inverting the exact clipped-area function in `a`, then uniformly in `b`). With
//!   `r = √(a²+b²)` and `θ = πr`, `dω = sin θ dθ dψ = π sin(πr) dr dψ` and `da db = r dr dψ`, so
//!   the Jacobian is `dω = π sin(πr)/r · da db` and `pdf(ω) = p_texel / (A_texel · π sin(πr)/r)`,
//!   `A_texel` the clipped area in `(a, b)`. The texel weight uses its solid angle
//!   `∫ π sin(πr)/r da db` by Gauss–Legendre quadrature; only proportionality depends on that
//!   quadrature, the pdf stays exact. The pdf grows without bound towards the rim (−Z), where
//!   the map squeezes a whole ring of texels into one direction.
//!
//! Texels of zero luminance get zero probability.
//!
//! **MIS compensation** ([`EnvSampling::Compensated`]; Karlík, Šik, Vévoda, Skřivan & Křivánek,
//! "MIS Compensation: Optimizing Sampling Techniques in Multiple Importance Sampling", ACM TOG
//! 38(6), SIGGRAPH Asia 2019, their normal-independent variant; pbrt-v4's image infinite light
//! does the same): when every environment sample is combined by MIS with BRDF sampling, the
//! texel weight `max(0, luminance − L̄) × solid angle`, `L̄` the map's mean luminance over the
//! sphere (raised by a relative 2⁻²⁰, so that a constant map stays constant after rounding),
//! lowers the variance: BRDF sampling already covers the dim, nearly uniform part of the map
//! well, so environment samples are better spent on what stands out of it. Texels at or
//! below `L̄` then have pdf 0 and are reached by BRDF sampling alone (MIS weight 1), which stays
//! unbiased as long as the BRDF's sampling pdf is positive wherever it is; a constant map has
//! no texel above its mean and is not sampled at all. Used on its own (without MIS) this
//! sampler would be biased: [`EnvSampling::Luminance`] is the plain one.
//!
//! **Per shading normal** ([`EnvSampling::PerNormal`], the renderer's default): the same
//! compensation with the cosine and the mean of the point's own hemisphere,
//! `cos⁺ × max(0, luminance − L̄_n / 2)`, tabulated for 1024 normals (`normal_tables.rs`
//! derives it); [`EnvSampler::sample_at`] and [`EnvSampler::radiance_and_pdf_at`] take the
//! point's shading normal.
//!
//! Sampling happens in the map frame and is
//! rotated by `rotation_y_deg` to the world ([`Environment::to_world`]); `pdf` and `radiance`
//! undo the rotation first.

use crate::normal_tables::NormalTables;
use crate::{luminance, Distribution2D};
use glam::{DVec3, Vec3};
use prt_scene::envmap::{angular_direction, LatLongGrid};
use prt_scene::{Environment, Mapping};
use std::f64::consts::{PI, TAU};

/// A direction drawn by [`EnvSampler::sample`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EnvSample {
    /// World direction towards the environment (unit).
    pub dir: Vec3,
    /// Radiance arriving from `dir` (RGB): that of the texel drawn, which is
    /// [`EnvSampler::radiance`] at `dir` unless rounding put `dir` across a texel edge.
    pub radiance: Vec3,
    /// Solid-angle pdf: [`EnvSampler::pdf`] at `dir`, with the same texel-edge proviso.
    pub pdf: f32,
}

/// Relative margin above the mean luminance for the compensated densities.
const COMPENSATION_MARGIN: f64 = 1.0 / (1u64 << 20) as f64;

/// How [`EnvSampler`] weights a texel. The compensated density (Karlík, Šik, Vévoda, Skřivan
/// & Křivánek, "MIS Compensation", SIGGRAPH Asia 2019, their normal-independent variant) is
/// for estimators that combine every environment sample with BRDF sampling by MIS: BRDF
/// sampling already covers the part of the map near its mean, so environment samples go only
/// where the map stands out of it. Texels at or below the mean then have pdf 0 and are reached
/// by BRDF sampling alone (MIS weight 1), unbiased wherever the BRDF's sampling pdf is positive
/// where the BRDF is.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum EnvSampling {
    /// `luminance × solid angle`: proportional to the map, for an estimator on its own.
    Luminance,
    /// `max(0, luminance − mean luminance) × solid angle`: only for estimators that combine
    /// every environment sample with BRDF sampling by MIS (Karlík et al. 2019).
    Compensated,
    /// Per shading normal `n`: `cos⁺ × max(0, luminance − L̄_n / 2) × solid angle`, with `L̄_n`
    /// the map's cosine-weighted mean over `n`'s hemisphere, tabulated for 1024 normal
    /// directions ([`EnvSampler::sample_at`]): the density that makes the MIS mixture with
    /// cosine-weighted BRDF sampling proportional to a Lambert integrand. Only for estimators
    /// that combine every environment sample with BRDF sampling by MIS. Lat-long maps; an
    /// angular map gets [`EnvSampling::Compensated`].
    #[default]
    PerNormal,
}

/// Importance sampler of a distant environment (see the module docs for the exact pdf).
#[derive(Clone, Debug)]
pub struct EnvSampler {
    env: Environment,
    sampling: EnvSampling,
    dist: Option<Distribution2D>,
    /// Lat-long: solid angle of each row's texels. Angular: clipped `(a, b)` area of each texel.
    measure: Vec<f64>,
    /// Lat-long: the texel edges, for lookups without `atan2`/`acos` and samples without
    /// trigonometry in `θ` and libm in `φ`. `None` for angular maps.
    grid: Option<LatLongGrid>,
    total_power: f64,
    /// [`EnvSampling::PerNormal`] on a lat-long map: the tables per normal.
    per_normal: Option<NormalTables>,
}

/// Solid angle of a lat-long texel of row `row` in a `w × h` map.
fn latlong_row_solid_angle(row: usize, w: usize, h: usize) -> f64 {
    let t0 = PI * row as f64 / h as f64;
    let t1 = PI * (row + 1) as f64 / h as f64;
    // cos t0 − cos t1 = 2 sin((t0+t1)/2) sin((t1−t0)/2), accurate near the poles.
    TAU / w as f64 * 2.0 * (0.5 * (t0 + t1)).sin() * (0.5 * (t1 - t0)).sin()
}

/// `(a0, a1, b0, b1)` of angular texel `(col, row)`: `a` rightwards, `b` upwards.
fn angular_rect(col: usize, row: usize, w: usize, h: usize) -> (f64, f64, f64, f64) {
    let a0 = 2.0 * col as f64 / w as f64 - 1.0;
    let a1 = 2.0 * (col + 1) as f64 / w as f64 - 1.0;
    let b0 = 1.0 - 2.0 * (row + 1) as f64 / h as f64;
    let b1 = 1.0 - 2.0 * row as f64 / h as f64;
    (a0, a1, b0, b1)
}

/// `∫ sqrt(1 − t²) dt`.
fn half_disc_antiderivative(t: f64) -> f64 {
    let t = t.clamp(-1.0, 1.0);
    0.5 * (t * (1.0 - t * t).max(0.0).sqrt() + t.asin())
}

/// `[max(b0, −s), min(b1, s)]` at `a = t`, `s = sqrt(1 − t²)`: the texel column inside the disc.
fn clipped_b_range(t: f64, b0: f64, b1: f64) -> (f64, f64) {
    let s = (1.0 - t * t).max(0.0).sqrt();
    (b0.max(-s), b1.min(s))
}

/// Area of `{(a, b) : a0 ≤ a ≤ x, b0 ≤ b ≤ b1, a² + b² ≤ 1}` in closed form, split where the
/// clipping changes (`a = ±sqrt(1 − b0²)`, `±sqrt(1 − b1²)`).
fn clipped_area(a0: f64, x: f64, b0: f64, b1: f64) -> f64 {
    let mut pts = [a0, x, 0.0, 0.0, 0.0, 0.0];
    let mut n = 2;
    for b in [b0, b1] {
        if b.abs() < 1.0 {
            let t = (1.0 - b * b).sqrt();
            for p in [t, -t] {
                if p > a0 && p < x {
                    pts[n] = p;
                    n += 1;
                }
            }
        }
    }
    let pts = &mut pts[..n];
    pts.sort_by(f64::total_cmp);
    let mut area = 0.0;
    for w in pts.windows(2) {
        let (p, q) = (w[0], w[1]);
        if q <= p {
            continue;
        }
        let m = 0.5 * (p + q);
        let s = (1.0 - m * m).max(0.0).sqrt();
        let (lo, hi) = clipped_b_range(m, b0, b1);
        if hi <= lo {
            continue;
        }
        let ds = half_disc_antiderivative(q) - half_disc_antiderivative(p);
        let upper = if s <= b1 { ds } else { b1 * (q - p) };
        let lower = if -s >= b0 { -ds } else { b0 * (q - p) };
        area += upper - lower;
    }
    area.max(0.0)
}

/// `dω / (da db) = π sin(πr)/r` of the angular mapping.
fn angular_jacobian(r: f64) -> f64 {
    if r < 1e-8 {
        PI * PI
    } else {
        PI * (PI * r).sin() / r
    }
}

/// Solid angle of an angular texel's part inside the disc (4×4 Gauss–Legendre, clipped in `b`).
fn angular_texel_solid_angle(a0: f64, a1: f64, b0: f64, b1: f64) -> f64 {
    const X: [f64; 4] = [
        -0.861_136_311_594_052_6,
        -0.339_981_043_584_856_3,
        0.339_981_043_584_856_3,
        0.861_136_311_594_052_6,
    ];
    const W: [f64; 4] = [
        0.347_854_845_137_453_9,
        0.652_145_154_862_546_1,
        0.652_145_154_862_546_1,
        0.347_854_845_137_453_9,
    ];
    let mut total = 0.0;
    for (xa, wa) in X.iter().zip(W) {
        let a = 0.5 * (a0 + a1) + 0.5 * (a1 - a0) * xa;
        let (lo, hi) = clipped_b_range(a, b0, b1);
        if hi <= lo {
            continue;
        }
        let mut inner = 0.0;
        for (xb, wb) in X.iter().zip(W) {
            let b = 0.5 * (lo + hi) + 0.5 * (hi - lo) * xb;
            inner += wb * angular_jacobian((a * a + b * b).sqrt().min(1.0));
        }
        total += wa * 0.5 * (a1 - a0) * inner * 0.5 * (hi - lo);
    }
    total
}

impl EnvSampler {
    /// Builds the sampling distribution of `env` proportional to luminance
    /// ([`EnvSampling::Luminance`]; clones the environment).
    #[must_use]
    pub fn new(env: &Environment) -> Self {
        Self::with_sampling(env, EnvSampling::Luminance)
    }

    /// Builds the sampling distribution of `env` with the texel weights of `sampling`
    /// (clones the environment).
    #[must_use]
    pub fn with_sampling(env: &Environment, sampling: EnvSampling) -> Self {
        let img = &env.image;
        let (w, h) = (img.width, img.height);
        let lum =
            |c: usize, r: usize| f64::from(luminance(Vec3::from_array(img.texel(c, r)))).max(0.0);
        // Per texel: luminance and solid angle (0 outside an angular probe's disc).
        let mut texels = vec![(0.0f64, 0.0f64); w * h];
        let measure = match env.mapping {
            Mapping::LatLong => {
                let measure: Vec<f64> = (0..h).map(|r| latlong_row_solid_angle(r, w, h)).collect();
                for (i, t) in texels.iter_mut().enumerate() {
                    *t = (lum(i % w, i / w), measure[i / w]);
                }
                measure
            }
            Mapping::Angular => {
                let mut measure = vec![0.0; w * h];
                for (i, t) in texels.iter_mut().enumerate() {
                    let (a0, a1, b0, b1) = angular_rect(i % w, i / w, w, h);
                    measure[i] = clipped_area(a0, a1, b0, b1);
                    if measure[i] > 0.0 {
                        *t = (lum(i % w, i / w), angular_texel_solid_angle(a0, a1, b0, b1));
                    }
                }
                measure
            }
        };
        let total_power: f64 = texels.iter().map(|&(l, omega)| l * omega).sum();
        // The mean luminance, a relative 2⁻²⁰ higher so that the rounding of a constant
        // map's sum leaves no texel above it (any floor ≥ 0 keeps the estimator unbiased).
        let floor = match sampling {
            EnvSampling::Luminance => 0.0,
            EnvSampling::Compensated | EnvSampling::PerNormal => {
                total_power / (4.0 * PI) * (1.0 + COMPENSATION_MARGIN)
            }
        };
        let per_normal =
            (sampling == EnvSampling::PerNormal && env.mapping == Mapping::LatLong && w * h > 0)
                .then(|| NormalTables::new(&texels, w, h));
        let weights: Vec<f64> = texels
            .iter()
            .map(|&(l, omega)| (l - floor).max(0.0) * omega)
            .collect();
        let dist = if w * h > 0 && weights.iter().any(|&x| x > 0.0) {
            Some(Distribution2D::new(&weights, w, h))
        } else {
            None
        };
        let grid = match env.mapping {
            Mapping::LatLong if w * h > 0 => Some(LatLongGrid::new(w, h)),
            _ => None,
        };
        Self {
            env: env.clone(),
            sampling,
            dist,
            measure,
            grid,
            total_power,
            per_normal,
        }
    }

    /// The environment this samples.
    #[must_use]
    pub fn environment(&self) -> &Environment {
        &self.env
    }

    /// How texels are weighted.
    #[must_use]
    pub fn sampling(&self) -> EnvSampling {
        self.sampling
    }

    /// Probability of choosing texel `(col, row)`.
    #[must_use]
    pub fn texel_probability(&self, col: usize, row: usize) -> f64 {
        self.dist.as_ref().map_or(0.0, |d| d.pmf(col, row))
    }

    /// Draws a direction; `None` for an all-black map (or a sample that rounds into a texel of
    /// zero probability).
    #[must_use]
    pub fn sample(&self, u: [f32; 2]) -> Option<EnvSample> {
        let dist = self.dist.as_ref()?;
        let ((c, r), p, rem) = dist.sample_discrete([f64::from(u[0]), f64::from(u[1])])?;
        let (w, h) = (self.env.image.width, self.env.image.height);
        match self.env.mapping {
            Mapping::LatLong => self.latlong_sample((c, r), p, rem),
            Mapping::Angular => {
                let (a0, a1, b0, b1) = angular_rect(c, r, w, h);
                let area = self.measure[r * w + c];
                let full = (a1 - a0) * (b1 - b0);
                let (a, b) = if area >= full * (1.0 - 1e-12) {
                    (a0 + rem[0] * (a1 - a0), b0 + rem[1] * (b1 - b0))
                } else {
                    // Invert the clipped area in `a` by bisection, then uniform in `b`.
                    let target = rem[0] * area;
                    let (mut lo, mut hi) = (a0, a1);
                    for _ in 0..64 {
                        let mid = 0.5 * (lo + hi);
                        if clipped_area(a0, mid, b0, b1) < target {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    let a = 0.5 * (lo + hi);
                    let (blo, bhi) = clipped_b_range(a, b0, b1);
                    (a, blo + rem[1] * (bhi - blo).max(0.0))
                };
                let map_dir = angular_direction(a, b).unwrap_or(DVec3::NEG_Z);
                let dir = self.env.to_world(map_dir).as_vec3().normalize();
                // The angular pdf varies inside a texel (the Jacobian), so it is evaluated at
                // the direction itself.
                let (radiance, pdf) = self.radiance_and_pdf(dir);
                if !(pdf.is_finite() && pdf > 0.0) {
                    return None;
                }
                Some(EnvSample { dir, radiance, pdf })
            }
        }
    }

    /// Solid-angle pdf of [`Self::sample`] at world direction `dir` (unit).
    #[must_use]
    pub fn pdf(&self, dir: Vec3) -> f32 {
        self.radiance_and_pdf(dir).1
    }

    /// [`Self::radiance`] and [`Self::pdf`] of one direction with one texel lookup (what an
    /// environment sample and a BRDF-sampled ray that escapes both need).
    #[must_use]
    pub fn radiance_and_pdf(&self, dir: Vec3) -> (Vec3, f32) {
        let m = self.env.to_map_frame(dir.as_dvec3());
        let img = &self.env.image;
        let (c, r) = self.texel(m);
        let radiance = Vec3::from_array(img.texel(c, r));
        let Some(dist) = self.dist.as_ref() else {
            return (radiance, 0.0);
        };
        let pdf = match self.env.mapping {
            Mapping::LatLong => (dist.pmf(c, r) / self.measure[r]) as f32,
            Mapping::Angular => {
                let area = self.measure[r * img.width + c];
                let p = dist.pmf(c, r);
                if area <= 0.0 || p <= 0.0 {
                    return (radiance, 0.0);
                }
                // r = θ/π and sin(πr) = sin θ from atan2 of the exact components: unlike
                // acos(z), this stays accurate next to −Z, where the pdf is steepest.
                let len = m.length();
                let hxy = (m.x * m.x + m.y * m.y).sqrt();
                let theta = hxy.atan2(m.z);
                let jac = if theta < 1e-8 {
                    PI * PI
                } else {
                    PI * (hxy / len) / (theta / PI)
                };
                if jac.is_nan() || jac <= 0.0 {
                    return (radiance, 0.0);
                }
                (p / (area * jac)) as f32
            }
        };
        (radiance, pdf)
    }

    /// [`Self::sample`] for a surface point with world shading normal `n` (unit): with
    /// [`EnvSampling::PerNormal`] from `n`'s table, otherwise the same as `sample`.
    #[must_use]
    pub fn sample_at(&self, n: Vec3, u: [f32; 2]) -> Option<EnvSample> {
        let Some(tables) = &self.per_normal else {
            return self.sample(u);
        };
        let m = self.env.to_map_frame(n.as_dvec3());
        let (texel, p, rem) = tables.sample(m, [f64::from(u[0]), f64::from(u[1])])?;
        self.latlong_sample(texel, p, rem)
    }

    /// The sample of lat-long texel `(c, r)` drawn with probability `p`, at remainder `rem`
    /// inside it: uniform in `φ` and in `cos θ` over the texel (the grid's exact edges, `φ`'s
    /// sine and cosine by rotating the column edge: no libm call). Its pdf and radiance are
    /// the texel's: the values a lookup of the direction gives, except where f32 rounding of
    /// the direction crosses a texel edge (a set of measure zero, so the estimator is
    /// unchanged).
    fn latlong_sample(&self, (c, r): (usize, usize), p: f64, rem: [f64; 2]) -> Option<EnvSample> {
        let grid = self.grid.as_ref()?;
        let dir = self
            .env
            .to_world(grid.direction(c, r, rem))
            .as_vec3()
            .normalize();
        let pdf = (p / self.measure[r]) as f32;
        (pdf.is_finite() && pdf > 0.0).then(|| EnvSample {
            dir,
            radiance: Vec3::from_array(self.env.image.texel(c, r)),
            pdf,
        })
    }

    /// [`Self::radiance_and_pdf`] for a surface point with world shading normal `n`: the pdf
    /// of [`Self::sample_at`] with the same `n`.
    #[must_use]
    pub fn radiance_and_pdf_at(&self, n: Vec3, dir: Vec3) -> (Vec3, f32) {
        let Some(tables) = &self.per_normal else {
            return self.radiance_and_pdf(dir);
        };
        let (c, r) = self.texel(self.env.to_map_frame(dir.as_dvec3()));
        let radiance = Vec3::from_array(self.env.image.texel(c, r));
        let m = self.env.to_map_frame(n.as_dvec3());
        (radiance, (tables.pmf(m, c, r) / self.measure[r]) as f32)
    }

    /// The pdf of [`Self::sample_at`] with normal `n` at `dir`.
    #[must_use]
    pub fn pdf_at(&self, n: Vec3, dir: Vec3) -> f32 {
        self.radiance_and_pdf_at(n, dir).1
    }

    /// Radiance arriving from world direction `dir` (the piecewise-constant texel value).
    #[must_use]
    pub fn radiance(&self, dir: Vec3) -> Vec3 {
        let (c, r) = self.texel(self.env.to_map_frame(dir.as_dvec3()));
        Vec3::from_array(self.env.image.texel(c, r))
    }

    /// The texel `(col, row)` holding map-frame direction `m`: [`LatLongGrid::texel`] for a
    /// lat-long map (the same texel as [`prt_scene::Environment::radiance`] looks up, except
    /// within an f64 rounding of an edge), the angular mapping otherwise.
    fn texel(&self, m: DVec3) -> (usize, usize) {
        match (&self.grid, self.env.mapping) {
            (Some(grid), Mapping::LatLong) => grid.texel(m),
            (_, Mapping::LatLong) => self.env.image.latlong_texel(m),
            (_, Mapping::Angular) => self.env.image.angular_texel(m),
        }
    }

    /// `∫ luminance dω` over the sphere (exact for lat-long, by quadrature for angular probes).
    #[must_use]
    pub fn total_power(&self) -> f64 {
        self.total_power
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clipped_area_matches_disc_and_quadrants() {
        // Whole square [-1,1]² clipped to the disc is π; a quadrant is π/4.
        assert!((clipped_area(-1.0, 1.0, -1.0, 1.0) - PI).abs() < 1e-12);
        assert!((clipped_area(0.0, 1.0, 0.0, 1.0) - PI / 4.0).abs() < 1e-12);
        assert!((clipped_area(-1.0, 0.0, -1.0, 0.0) - PI / 4.0).abs() < 1e-12);
        // Interior rectangle unchanged.
        assert!((clipped_area(-0.1, 0.2, -0.3, 0.1) - 0.3 * 0.4).abs() < 1e-12);
        // Outside.
        assert_eq!(clipped_area(0.9, 1.0, 0.9, 1.0), 0.0);
        // Sum over a grid of texels equals π.
        let n = 37;
        let mut sum = 0.0;
        let mut omega = 0.0;
        for r in 0..n {
            for c in 0..n {
                let (a0, a1, b0, b1) = angular_rect(c, r, n, n);
                sum += clipped_area(a0, a1, b0, b1);
                omega += angular_texel_solid_angle(a0, a1, b0, b1);
            }
        }
        assert!((sum - PI).abs() < 1e-10, "{sum}");
        // Solid angle of the whole probe is 4π (quadrature; rim texels are approximate).
        assert!((omega - 4.0 * PI).abs() < 0.02, "{omega}");
    }
}
