//! Compact sources in an inverse-lighting fit: the lighting as SH plus a few small bright
//! caps (a sun, a softbox, a studio lamp), each seen by the image through the scene's exact
//! transfer — the BRDF, the cosine and the cast shadow traced per footprint sample — instead
//! of through the bake's truncated SH.
//!
//! **Why.** A cast shadow or a terminator under a compact light is a product of lighting and
//! visibility at frequencies no practical SH order holds: under the studio map (three lamps
//! of about 0.1 % of the sphere carrying 60 % of the energy) the nine-sphere probe's image
//! misses the order-12 model by 7.6 % (relative L2 over the fitted pixels), and by 2.0 % once
//! the lamps' texels are rendered exactly and only the rest goes through the model
//! (crates/scene_relight/README.md). Marschner & Greenberg 1997 (inverse lighting) and Sato,
//! Sato & Ikeuchi 1999 ("Illumination from shadows") recover light sources from exactly this
//! signal; here they join the SH fit of Ramamoorthi & Hanrahan 2001.
//!
//! **How** ([`find_sources`]). The images of a unit delta source at each of a Fibonacci grid
//! of directions ([`CANDIDATES`], about 3.2° apart) are traced once (one footprint sample per
//! pixel), with their parts outside the span of the SH columns. For each new source the SH
//! fit's residual picks the grid direction whose column explains most of it; a pattern search
//! refines it with every footprint sample, then its angular radius (a uniform cap,
//! [`RADII_DEG`]) and, for a cap, the axis again at that radius. The source joins the fit as
//! undamped columns beside the SH ones (its power per channel is linear), and it is kept only
//! if its powers are positive and the weighted residual's squared norm falls by at least
//! [`MIN_GAIN`]. The search stops at `max_sources` or at the first source that does not pay.
//! The SH coefficients returned are the SH part plus the sources' own projections (the mean
//! of `Y_lm` over the directions their columns were traced with), so the output is the
//! lighting's SH as before, and the sources are listed beside it.

use crate::bound::Bound;
use crate::error::SceneRelightError;
use glam::{DVec3, Vec3};
use nalgebra::{DMatrix, DVector};
use prt_scene::{Material, Scene};
use prt_tracer::points::PixelFootprints;
use rayon::prelude::*;
use serde::Serialize;

/// Candidate directions of the first search: a Fibonacci sphere of this many points (about
/// 3.2° apart, `sqrt(4π / N)`).
pub const CANDIDATES: usize = 4096;

/// Sources `prt fit-lighting` looks for by default ([`crate::inverse::FitOptions::new`]).
pub const DEFAULT_MAX_SOURCES: usize = 16;

/// Angular radii (degrees) tried for a found source: a uniform cap of each, the best kept.
pub const RADII_DEG: [f64; 8] = [0.0, 0.5, 1.0, 2.0, 3.0, 4.0, 6.0, 8.0];

/// A source is kept only if it lowers the weighted residual's squared norm by at least this
/// fraction: below it, a "source" fits the model's other errors or the noise.
pub const MIN_GAIN: f64 = 0.02;

/// A source must also explain at least this fraction of the image's squared norm (0.1 % in
/// L2): below it lies the rounding of the image's own storage (half-float EXR: a relative
/// 2⁻¹¹ ≈ 4.9·10⁻⁴ per value), so an image the SH part explains exactly gets no source.
pub const MIN_EXPLAINED: f64 = 1e-6;

/// With the image's noise known (equations weighted by the inverse variance, so unit noise
/// per equation), a source must also lower the residual's squared norm by this much: pure
/// noise explains, through the best of [`CANDIDATES`] columns of three channels, a `χ²₃`
/// variable maximised over 4096 draws, which exceeds 50 with probability about
/// `4096 · 8·10⁻¹¹ ≈ 3·10⁻⁷` (and the refinement's three shape parameters add little).
pub const NOISE_FLOOR: f64 = 50.0;

/// Directions a cap's column is traced with (a delta source: 1).
pub const CAP_DIRECTIONS: usize = 24;

/// Footprint samples per pixel of a cap's column during the search ([`search_samples`]).
const CAP_SEARCH_SAMPLES: usize = 4;

/// A compact source found by the fit.
#[derive(Clone, Debug, Serialize)]
pub struct Source {
    /// Unit direction towards the source's centre (world space).
    pub direction: [f64; 3],
    /// Angular radius of the uniform cap, degrees (0: a direction).
    pub radius_deg: f64,
    /// Per channel, the source's power `∫ L dω` over its cap (radiance × solid angle).
    pub intensity: [f64; 3],
}

/// One footprint sample of a fit pixel, as the path tracer shades it.
#[derive(Clone, Copy)]
struct Shade {
    position: Vec3,
    /// Geometric normal facing the viewer (ray origins are moved off along it).
    ng: Vec3,
    /// Shading normal facing the viewer.
    ns: Vec3,
    offset: f32,
    wo: Vec3,
    material: Material,
}

/// The fit pixels' footprint samples, ready to be lit by a source.
pub struct SourceImages<'a> {
    bound: &'a Bound<'a>,
    /// Per fit pixel, its samples that hit an object (weight `1/K` each).
    samples: Vec<Vec<Shade>>,
    /// `K`: footprint samples per pixel.
    per_pixel: usize,
    /// Per fit pixel, the square root of its equation's weight.
    sqrt_w: Vec<f64>,
}

impl<'a> SourceImages<'a> {
    /// The footprint samples of `pixels` (those of a per-pixel bake, else 16 per pixel on the
    /// same box footprint), each row weighted by `sqrt_w`.
    ///
    /// # Errors
    /// A camera the tracer refuses.
    pub fn new(
        bound: &'a Bound<'a>,
        pixels: &[usize],
        sqrt_w: &[f64],
    ) -> Result<Self, SceneRelightError> {
        let traced;
        let fp: &PixelFootprints = match bound.footprints() {
            Some(f) => f,
            None => {
                traced = prt_tracer::points::pixel_footprints(
                    bound.scene(),
                    bound.accel(),
                    bound.bake().meta.seed,
                    16,
                )?;
                &traced
            }
        };
        let scene = bound.scene();
        let samples = pixels
            .iter()
            .map(|&p| fp.pixel(p).iter().filter_map(|s| shade(scene, s)).collect())
            .collect();
        Ok(Self {
            bound,
            samples,
            per_pixel: fp.samples_per_pixel as usize,
            sqrt_w: sqrt_w.to_vec(),
        })
    }

    /// The weighted image of a source of unit power in every channel spread uniformly over
    /// `dirs`, per channel, over the first `samples` footprint samples of each pixel (all:
    /// `usize::MAX`).
    #[must_use]
    pub fn column(&self, dirs: &[Vec3], samples: usize) -> [DVector<f64>; 3] {
        let rows: Vec<DVec3> = (0..self.samples.len())
            .into_par_iter()
            .map(|p| self.lit(p, dirs, samples))
            .collect();
        [0, 1, 2].map(|c| DVector::from_iterator(rows.len(), rows.iter().map(|r| r[c])))
    }

    /// Fit pixel `p`'s weighted radiance under a source of unit power spread uniformly over
    /// `dirs`, over its first `samples` footprint samples: `f · cos · V` per sample and
    /// direction, as the path tracer's next-event estimate shades it, averaged.
    fn lit(&self, p: usize, dirs: &[Vec3], samples: usize) -> DVec3 {
        let accel = self.bound.accel();
        let used = samples.min(self.per_pixel).max(1);
        let mut sum = DVec3::ZERO;
        for s in self.samples[p].iter().take(used) {
            for &d in dirs {
                let cos = s.ns.dot(d);
                if cos <= 0.0 || s.ng.dot(d) <= 0.0 {
                    continue;
                }
                let f = prt_shading::eval(&s.material, s.ns, s.wo, d);
                if f == Vec3::ZERO {
                    continue;
                }
                let o = prt_tracer::offset_origin(s.position, s.ng, s.offset, d);
                if !accel.occluded(o, d, f32::INFINITY) {
                    sum += (f * cos).as_dvec3();
                }
            }
        }
        // Samples off every object add nothing but still count in the box mean.
        sum * (self.sqrt_w[p] / (used * dirs.len()) as f64)
    }
}

/// A footprint sample as the path tracer shades it; `None` when it sees no object.
fn shade(scene: &Scene, s: &prt_tracer::points::PixelSample) -> Option<Shade> {
    let (m, sp) = s.hit?;
    let wo = -s.dir;
    let ng = if sp.offset_normal.dot(wo) < 0.0 {
        -sp.offset_normal
    } else {
        sp.offset_normal
    };
    let ns = crate::footprint::seen_normal(scene, m, s.at, s.dir).unwrap_or(sp.normal);
    let material = match s.at {
        Some(at) => scene.material_at(m, at),
        None => scene.materials[scene.meshes[m].material],
    };
    Some(Shade {
        position: sp.position,
        ng,
        ns,
        offset: sp.offset,
        wo,
        material,
    })
}

/// The `i`-th of `n` points of a Fibonacci sphere (uniform in area, deterministic).
#[must_use]
pub fn fibonacci(i: usize, n: usize) -> Vec3 {
    let (z, x, y) = spiral(i, n, -1.0);
    DVec3::new(x, z, y).as_vec3()
}

/// Point `i` of an `n`-point Fibonacci spiral on the cap `z ≥ cos_max` about +z (uniform in
/// solid angle; `cos_max = −1`: the whole sphere), as `(z, r cos φ, r sin φ)`.
fn spiral(i: usize, n: usize, cos_max: f64) -> (f64, f64, f64) {
    let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
    let z = 1.0 - (1.0 - cos_max) * (i as f64 + 0.5) / n as f64;
    let r = (1.0 - z * z).max(0.0).sqrt();
    let phi = golden * i as f64;
    (z, r * phi.cos(), r * phi.sin())
}

/// The directions a cap of angular radius `radius_deg` about `axis` is traced with: its
/// centre for a delta, else [`CAP_DIRECTIONS`] points of a Fibonacci spiral on the cap
/// (uniform in solid angle).
#[must_use]
pub fn cap_directions(axis: Vec3, radius_deg: f64) -> Vec<Vec3> {
    if radius_deg <= 0.0 {
        return vec![axis];
    }
    let axis = axis.as_dvec3().normalize();
    let (t, b) = axis.any_orthonormal_pair();
    let cos_max = radius_deg.to_radians().cos();
    (0..CAP_DIRECTIONS)
        .map(|i| {
            let (z, x, y) = spiral(i, CAP_DIRECTIONS, cos_max);
            (axis * z + t * x + b * y).normalize().as_vec3()
        })
        .collect()
}

/// The SH coefficients (`n²`, index `l(l+1)+m`) of a source of unit power spread uniformly
/// over `dirs`: the mean of `Y_lm` over them.
///
/// # Errors
/// An order the SH crate refuses.
pub fn source_sh(dirs: &[Vec3], n: usize) -> Result<Vec<f64>, SceneRelightError> {
    let basis = prt_sh::Basis::new(n)?;
    let mut out = vec![0.0; n * n];
    for d in dirs {
        for (o, v) in out.iter_mut().zip(basis.eval(d.as_dvec3())) {
            *o += v / dirs.len() as f64;
        }
    }
    Ok(out)
}

/// The orthonormal basis of a matrix's column space (thin QR; columns of zero norm dropped).
fn column_space(a: &DMatrix<f64>) -> DMatrix<f64> {
    a.clone().qr().q()
}

/// `v` with its part in the span of `q` (orthonormal columns) removed.
fn project_out(q: &DMatrix<f64>, v: &DVector<f64>) -> DVector<f64> {
    v - q * (q.transpose() * v)
}

/// How much of `residual` a source column explains once the SH columns are projected out:
/// `Σ_c (d⊥_c · r_c)² / |d⊥_c|²`, where the fitted intensity `d⊥·r / |d⊥|²` is positive.
fn score(q: &[DMatrix<f64>; 3], col: &[DVector<f64>; 3], residual: &[DVector<f64>; 3]) -> f64 {
    (0..3)
        .map(|c| {
            let d = project_out(&q[c], &col[c]);
            let dd = d.norm_squared();
            let dr = d.dot(&residual[c]);
            if dd > 0.0 && dr > 0.0 {
                dr * dr / dd
            } else {
                0.0
            }
        })
        .sum()
}

/// A source's axis and radius while it is searched for.
#[derive(Clone, Copy)]
struct Candidate {
    axis: Vec3,
    radius_deg: f64,
}

/// The images of a unit delta source at each of the [`CANDIDATES`] grid directions, traced
/// once per fit (one footprint sample per pixel: the scan only ranks directions), with the
/// squared norms of their parts outside the SH columns' span.
struct Scan {
    /// Per channel, `pixels × CANDIDATES`.
    d: [DMatrix<f64>; 3],
    /// Per channel and candidate, `|d⊥|²`.
    perp2: [DVector<f64>; 3],
}

impl Scan {
    fn new(imgs: &SourceImages, q: &[DMatrix<f64>; 3]) -> Self {
        let dirs: Vec<Vec3> = (0..CANDIDATES).map(|i| fibonacci(i, CANDIDATES)).collect();
        let rows: Vec<Vec<[f64; 3]>> = (0..imgs.samples.len())
            .into_par_iter()
            .map(|p| {
                dirs.iter()
                    .map(|&d| imgs.lit(p, &[d], 1).to_array())
                    .collect()
            })
            .collect();
        let d = [0, 1, 2].map(|c| DMatrix::from_fn(rows.len(), CANDIDATES, |p, j| rows[p][j][c]));
        let perp2 = [0, 1, 2].map(|c| {
            let qd = q[c].transpose() * &d[c];
            DVector::from_fn(CANDIDATES, |j, _| {
                (d[c].column(j).norm_squared() - qd.column(j).norm_squared()).max(0.0)
            })
        });
        Self { d, perp2 }
    }

    /// The grid direction whose column, outside the SH span, explains most of `residual`.
    fn best(&self, q: &[DMatrix<f64>; 3], residual: &[DVector<f64>; 3]) -> Vec3 {
        let dots = [0, 1, 2].map(|c| {
            let perp = project_out(&q[c], &residual[c]);
            self.d[c].transpose() * perp
        });
        let score = |j: usize| -> f64 {
            (0..3)
                .map(|c| {
                    let (dr, dd) = (dots[c][j], self.perp2[c][j]);
                    if dd > 0.0 && dr > 0.0 {
                        dr * dr / dd
                    } else {
                        0.0
                    }
                })
                .sum()
        };
        let best = (0..CANDIDATES)
            .map(|j| (score(j), j))
            .fold((f64::NEG_INFINITY, 0), |a, b| if b.0 > a.0 { b } else { a });
        fibonacci(best.1, CANDIDATES)
    }
}

/// Footprint samples per pixel a candidate's column is traced with while searching: all for
/// a direction (one ray per sample), [`CAP_SEARCH_SAMPLES`] for a cap (whose
/// [`CAP_DIRECTIONS`] rays per sample already average over the cap); the kept source's
/// column uses them all.
fn search_samples(c: Candidate) -> usize {
    if c.radius_deg > 0.0 {
        CAP_SEARCH_SAMPLES
    } else {
        usize::MAX
    }
}

/// The direction and radius whose column best explains `residual`: the scan's best grid
/// direction refined as a direction (a pattern search whose step halves from the grid's
/// spacing to 0.05°), then the best radius of [`RADII_DEG`] there, and for a cap the axis
/// refined again at that radius (the best direction for a delta is not a cap's centre where
/// its penumbra is partly blocked) and the radius chosen again.
fn best_candidate(
    imgs: &SourceImages,
    scan: &Scan,
    q: &[DMatrix<f64>; 3],
    residual: &[DVector<f64>; 3],
) -> Candidate {
    let eval = |c: Candidate| {
        score(
            q,
            &imgs.column(&cap_directions(c.axis, c.radius_deg), search_samples(c)),
            residual,
        )
    };
    let grid_step = (4.0 * std::f64::consts::PI / CANDIDATES as f64).sqrt();
    let delta = Candidate {
        axis: scan.best(q, residual),
        radius_deg: 0.0,
    };
    let mut best = refine_axis(delta, grid_step, &eval);
    best.radius_deg = best_radius(best.axis, &eval);
    if best.radius_deg > 0.0 {
        best = refine_axis(best, 0.5f64.to_radians(), &eval);
        best.radius_deg = best_radius(best.axis, &eval);
    }
    best
}

/// `start` with its axis moved by a pattern search (four moves along a tangent frame; the
/// step halves when none improves `eval`, from `step` to 0.05°).
fn refine_axis(start: Candidate, step: f64, eval: &impl Fn(Candidate) -> f64) -> Candidate {
    let mut best = (eval(start), start);
    let mut step = step;
    while step > 0.05f64.to_radians() {
        let (t, b) = best.1.axis.any_orthonormal_pair();
        let mut moved = false;
        for (dt, db) in [(1.0, 0.0), (-1.0, 0.0), (0.0, 1.0), (0.0, -1.0)] {
            let trial = Candidate {
                axis: (best.1.axis + (t * dt + b * db) * step as f32).normalize(),
                ..best.1
            };
            let s = eval(trial);
            if s > best.0 {
                best = (s, trial);
                moved = true;
            }
        }
        if !moved {
            step *= 0.5;
        }
    }
    best.1
}

/// The radius of [`RADII_DEG`] whose cap about `axis` scores best.
fn best_radius(axis: Vec3, eval: &impl Fn(Candidate) -> f64) -> f64 {
    RADII_DEG
        .iter()
        .map(|&radius_deg| (eval(Candidate { axis, radius_deg }), radius_deg))
        .fold(
            (f64::NEG_INFINITY, 0.0),
            |a, b| if b.0 > a.0 { b } else { a },
        )
        .1
}

/// The SH design `a` (weighted, per channel) with the sources' columns appended.
pub(crate) fn with_sources(a: &[DMatrix<f64>; 3], cols: &[[DVector<f64>; 3]]) -> [DMatrix<f64>; 3] {
    [0, 1, 2].map(|c| {
        let (rows, n) = a[c].shape();
        let mut m = DMatrix::zeros(rows, n + cols.len());
        m.columns_mut(0, n).copy_from(&a[c]);
        for (k, col) in cols.iter().enumerate() {
            m.set_column(n + k, &col[c]);
        }
        m
    })
}

/// Per channel, a joint solve's coefficients (SH part, then the sources) and its residual.
type JointSolve = [(DVector<f64>, DVector<f64>); 3];

/// The joint solve: SH part regularised as [`crate::solve::solve_channel`], sources free.
/// Returns per channel the solution and the residual vector.
fn solve(
    a: &[DMatrix<f64>; 3],
    cols: &[[DVector<f64>; 3]],
    b: &[DVector<f64>; 3],
    well: usize,
    limit: f64,
) -> Result<JointSolve, SceneRelightError> {
    let full = with_sources(a, cols);
    let sh = a[0].ncols();
    let mut out: JointSolve = Default::default();
    for (c, o) in out.iter_mut().enumerate() {
        let s = crate::solve::solve_channel_with(&full[c], &b[c], sh, well, limit)?;
        let r = &b[c] - &full[c] * &s.x;
        *o = (s.x, r);
    }
    Ok(out)
}

/// Sources found in an image, the columns they were fitted with and the SH they add.
#[derive(Default)]
pub struct FoundSources {
    /// The sources, in the order found.
    pub sources: Vec<Source>,
    /// Their weighted columns at full footprint sampling (to append to the SH design).
    pub columns: Vec<[DVector<f64>; 3]>,
    /// Per source, its SH coefficients per unit power (`n²` of the model order).
    pub sh: Vec<Vec<f64>>,
    /// Weighted squared residual (all channels) after each accepted source, the SH-only fit's
    /// first.
    pub residual2: Vec<f64>,
}

/// Finds up to `max_sources` compact sources in the residual of the SH fit of `b` by the
/// weighted design `a` (module docs), whose bands `≥ well` are regularised; a source must
/// lower the residual's squared norm by [`MIN_GAIN`] of it, by [`MIN_EXPLAINED`] of the
/// image's and by at least `min_drop`
/// ([`NOISE_FLOOR`] where the equations are weighted by the inverse of the image's variance,
/// else 0).
///
/// # Errors
/// A failed solve.
pub fn find_sources(
    imgs: &SourceImages,
    a: &[DMatrix<f64>; 3],
    b: &[DVector<f64>; 3],
    well: usize,
    limit: f64,
    max_sources: usize,
    min_drop: f64,
) -> Result<FoundSources, SceneRelightError> {
    let model = (a[0].ncols() as f64).sqrt().round() as usize;
    let q = [0, 1, 2].map(|c| column_space(&a[c]));
    let scan = Scan::new(imgs, &q);
    let mut found = FoundSources {
        sources: Vec::new(),
        columns: Vec::new(),
        sh: Vec::new(),
        residual2: Vec::new(),
    };
    let b2: f64 = b.iter().map(DVector::norm_squared).sum();
    let mut fit = solve(a, &found.columns, b, well, limit)?;
    let r2 = |f: &JointSolve| f.iter().map(|x| x.1.norm_squared()).sum();
    found.residual2.push(r2(&fit));
    while found.sources.len() < max_sources {
        let residual = [0, 1, 2].map(|c| fit[c].1.clone());
        let cand = best_candidate(imgs, &scan, &q, &residual);
        let dirs = cap_directions(cand.axis, cand.radius_deg);
        let mut cols = found.columns.clone();
        cols.push(imgs.column(&dirs, usize::MAX));
        let trial = solve(a, &cols, b, well, limit)?;
        let k = a[0].ncols() + cols.len() - 1;
        let intensity = [0, 1, 2].map(|c| trial[c].0[k]);
        let before: f64 = *found.residual2.last().unwrap_or(&0.0);
        let after: f64 = r2(&trial);
        let gain = before - after;
        if intensity.iter().any(|&i| i <= 0.0)
            || gain < MIN_GAIN * before
            || gain < min_drop
            || gain < MIN_EXPLAINED * b2
        {
            break;
        }
        found.columns = cols;
        found.sh.push(source_sh(&dirs, model)?);
        found.sources.push(Source {
            direction: cand.axis.as_dvec3().normalize().to_array(),
            radius_deg: cand.radius_deg,
            intensity,
        });
        found.residual2.push(after);
        fit = trial;
    }
    Ok(found)
}
