//! More reconstructions of sampled reflectance functions (Masselus, Peers, Dutré & Willems,
//! "Smooth Reconstruction and Compact Representation of Reflectance Functions for Image-based
//! Relighting", EGSR 2004, §4 "Reconstruction Methods"): inverse distance weighting, a
//! biquadric polynomial per hemisphere, a spherical-harmonic fit and multilevel B-splines
//! (Lee, Wolberg & Shin, "Scattered Data Interpolation with Multilevel B-Splines", IEEE TVCG
//! 1997), beside the zero-order hold, bilinear and wavelet interpolation of [`crate::relight`].
//!
//! Each one maps the samples `R_j` of one channel of a pixel's reflectance function, taken at
//! the centres of a coarse `W × H` lat-long grid of directions, to values at the centres of a
//! fine `FW × FH` lat-long grid. Cell `(col, row)` of a `w × h` grid is centred at
//! `φ = 2π(col + ½)/w`, `θ = π(row + ½)/h`, direction `d = (sin φ sin θ, cos θ, −cos φ sin θ)`
//! (`CONVENTIONS.md`; row 0 next to +Y), with index `row·w + col`, and has the exact solid angle
//! `(2π/w)(cos(π row/h) − cos(π(row + 1)/h))`.
//!
//! All four are **linear in the samples**, `R̂ = M R`, with `M` depending on the two grids only:
//! the constructors precompute `M` in a factored, sparse form, and [`LinearReconstruction`]
//! applies `M` (per pixel) and its adjoint `Mᵀ` (once per frame, to pull the lighting back to
//! the samples: `⟨M R, ℓ⟩ = ⟨R, Mᵀ ℓ⟩`).
//!
//! | method | `M` | cost of `apply` |
//! |---|---|---|
//! | [`Idw`] | sparse rows: the `n` nearest samples (and any tied with the `n`-th) | `≈ n · FW·FH` |
//! | [`Biquadric`] | `B · P`, `P` the 6 × samples weighted pseudo-inverse of each hemisphere | `12 · (W·H + FW·FH)` |
//! | [`ShFit`] | `B · P`, `P` the `order² ×` samples weighted pseudo-inverse | `order² · (W·H + FW·FH)` |
//! | [`MultilevelBSpline`] | a product of sparse per-level operators (BA, residual, refinement, evaluation) | `≈ 32 · W·H · levels + 16 · FW·FH` |
//!
//! The least-squares fits minimise `Σ_j Δω_j (f(d_j) − R_j)²` (`Δω_j` the sample's cell's solid
//! angle: the discrete form of the paper's L2 error over the sphere, eq. 2) through a QR
//! factorisation (classical Gram–Schmidt, twice) of the weighted design matrix, and refuse
//! grids on which the fit is not determined.

use crate::error::FieldError;
use glam::DVec3;
use rayon::prelude::*;
use std::f64::consts::PI;

/// A linear map from the samples of a coarse lat-long grid to the values of a fine one.
///
/// The implementations here panic when a slice's length does not match its grid (a caller's
/// bug, not bad input: the constructors validate everything that comes from a user).
pub trait LinearReconstruction: Send + Sync {
    /// `fine[k] = Σ_j M[k][j] · samples[j]` (samples: W·H values; fine: FW·FH values)
    fn apply(&self, samples: &[f32], fine: &mut [f64]);
    /// `coarse[j] = Σ_k M[k][j] · fine[k]` (the adjoint; used to pull the lighting back)
    fn apply_transpose(&self, fine: &[f64], coarse: &mut [f64]);
}

/// Largest coarse or fine grid, in cells (as `relight_field`'s fine grid).
const MAX_CELLS: u64 = 1 << 24;

fn invalid(message: String) -> FieldError {
    FieldError::Invalid(message)
}

/// The two grids, validated.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Grids {
    coarse: [usize; 2],
    fine: [usize; 2],
}

impl Grids {
    fn new(method: &str, coarse: [u32; 2], fine: [u32; 2]) -> Result<Self, FieldError> {
        for (what, [w, h]) in [("sampled", coarse), ("fine", fine)] {
            if w == 0 || h == 0 || u64::from(w) * u64::from(h) > MAX_CELLS {
                return Err(invalid(format!(
                    "{method} reconstruction: the {what} grid {w}×{h} must have at least one cell in each direction and at most 2^24 cells"
                )));
            }
        }
        Ok(Self {
            coarse: [coarse[0] as usize, coarse[1] as usize],
            fine: [fine[0] as usize, fine[1] as usize],
        })
    }

    fn samples(&self) -> usize {
        self.coarse[0] * self.coarse[1]
    }

    fn cells(&self) -> usize {
        self.fine[0] * self.fine[1]
    }

    fn check(&self, samples: usize, fine: usize) {
        assert_eq!(
            samples,
            self.samples(),
            "{}×{} sampled grid: wrong number of samples",
            self.coarse[0],
            self.coarse[1]
        );
        assert_eq!(
            fine,
            self.cells(),
            "{}×{} fine grid: wrong number of fine values",
            self.fine[0],
            self.fine[1]
        );
    }
}

/// The centre direction of cell `k` (`row·w + col`) of a `w × h` lat-long grid.
fn centre([w, h]: [usize; 2], k: usize) -> DVec3 {
    let (col, row) = (k % w, k / w);
    let phi = 2.0 * PI * (col as f64 + 0.5) / w as f64;
    let theta = PI * (row as f64 + 0.5) / h as f64;
    DVec3::new(
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    )
}

/// The exact solid angle of a cell in row `row` of a `w × h` lat-long grid.
fn solid_angle([w, h]: [usize; 2], row: usize) -> f64 {
    2.0 * PI / w as f64
        * ((PI * row as f64 / h as f64).cos() - (PI * (row + 1) as f64 / h as f64).cos())
}

/// The angle between two unit directions, accurate also when they (nearly) coincide.
fn angle(a: DVec3, b: DVec3) -> f64 {
    a.cross(b).length().atan2(a.dot(b))
}

/// A sparse matrix stored by rows.
#[derive(Clone, Debug, Default)]
struct SparseRows {
    starts: Vec<usize>,
    cols: Vec<u32>,
    vals: Vec<f64>,
    width: usize,
}

impl SparseRows {
    fn from_rows(rows: Vec<Vec<(u32, f64)>>, width: usize) -> Self {
        let mut m = Self {
            starts: Vec::with_capacity(rows.len() + 1),
            width,
            ..Self::default()
        };
        m.starts.push(0);
        for row in rows {
            for (c, v) in row {
                m.cols.push(c);
                m.vals.push(v);
            }
            m.starts.push(m.cols.len());
        }
        m
    }

    fn height(&self) -> usize {
        self.starts.len() - 1
    }

    fn row(&self, i: usize) -> (&[u32], &[f64]) {
        let r = self.starts[i]..self.starts[i + 1];
        (&self.cols[r.clone()], &self.vals[r])
    }

    /// `y = A x`.
    fn mul<T: Copy + Into<f64>>(&self, x: &[T], y: &mut [f64]) {
        debug_assert_eq!((x.len(), y.len()), (self.width, self.height()));
        for (i, out) in y.iter_mut().enumerate() {
            let (c, v) = self.row(i);
            *out = c
                .iter()
                .zip(v)
                .map(|(&c, &v)| v * x[c as usize].into())
                .sum();
        }
    }

    /// `y −= A x`.
    fn mul_sub(&self, x: &[f64], y: &mut [f64]) {
        for (i, out) in y.iter_mut().enumerate() {
            let (c, v) = self.row(i);
            *out -= c
                .iter()
                .zip(v)
                .map(|(&c, &v)| v * x[c as usize])
                .sum::<f64>();
        }
    }

    /// `y += Aᵀ x`.
    fn mul_t_add(&self, x: &[f64], y: &mut [f64]) {
        debug_assert_eq!((x.len(), y.len()), (self.height(), self.width));
        for (i, &xi) in x.iter().enumerate() {
            if xi == 0.0 {
                continue;
            }
            let (c, v) = self.row(i);
            for (&c, &v) in c.iter().zip(v) {
                y[c as usize] += v * xi;
            }
        }
    }
}

/// `M = B · P` with a small inner dimension `rank`: `P` (`rank × samples`) fits coefficients,
/// `B` (`cells × rank`) evaluates them at the fine centres. Both dense, row-major.
#[derive(Clone, Debug)]
struct Factored {
    rank: usize,
    fit: Vec<f64>,
    basis: Vec<f64>,
}

impl Factored {
    fn apply(&self, samples: &[f32], fine: &mut [f64]) {
        let d = samples.len();
        let coeffs: Vec<f64> = self
            .fit
            .chunks_exact(d)
            .map(|row| {
                row.iter()
                    .zip(samples)
                    .map(|(p, s)| p * f64::from(*s))
                    .sum()
            })
            .collect();
        for (out, b) in fine.iter_mut().zip(self.basis.chunks_exact(self.rank)) {
            *out = b.iter().zip(&coeffs).map(|(b, c)| b * c).sum();
        }
    }

    fn apply_transpose(&self, fine: &[f64], coarse: &mut [f64]) {
        let mut coeffs = vec![0.0f64; self.rank];
        for (&y, b) in fine.iter().zip(self.basis.chunks_exact(self.rank)) {
            for (c, b) in coeffs.iter_mut().zip(b) {
                *c += b * y;
            }
        }
        coarse.fill(0.0);
        for (row, c) in self.fit.chunks_exact(coarse.len()).zip(&coeffs) {
            for (o, p) in coarse.iter_mut().zip(row) {
                *o += p * c;
            }
        }
    }
}

/// The weighted least-squares pseudo-inverse of a design matrix `a` (`rows × cols`,
/// row-major): the `cols × rows` matrix `P` with `P b = argmin_c Σ_j w_j ((a c)_j − b_j)²`,
/// i.e. `P = R⁻¹ Qᵀ W^{1/2}` for `W^{1/2} a = Q R` (nalgebra's Householder QR). `Err(i)`: the
/// fit is not determined — column `i` lies (to 1e-10 relative to the largest diagonal of `R`)
/// in the span of the columns before it.
fn weighted_pseudo_inverse(
    a: &[f64],
    rows: usize,
    cols: usize,
    weights: &[f64],
) -> Result<Vec<f64>, usize> {
    use nalgebra::DMatrix;
    let sw: Vec<f64> = weights.iter().map(|w| w.sqrt()).collect();
    let aw = DMatrix::from_fn(rows, cols, |j, i| a[j * cols + i] * sw[j]);
    let qr = aw.qr();
    let r = qr.r();
    let largest = (0..cols).map(|i| r[(i, i)].abs()).fold(0.0f64, f64::max);
    // (NaN diagonals count as lost rank.)
    let determined = |i: usize| r[(i, i)].abs() > 1e-10 * largest;
    if let Some(i) = (0..cols).find(|&i| !determined(i)) {
        return Err(i);
    }
    // R X = Qᵀ (cols × rows), then the columns scaled by √w.
    let x = r
        .solve_upper_triangular(&qr.q().transpose())
        .ok_or(cols.saturating_sub(1))?;
    let mut p = vec![0.0f64; cols * rows];
    for i in 0..cols {
        for j in 0..rows {
            p[i * rows + j] = x[(i, j)] * sw[j];
        }
    }
    Ok(p)
}

// ---------------------------------------------------------------------------------------------
// Inverse distance weighting
// ---------------------------------------------------------------------------------------------

/// **Inverse distance weighted interpolation** (Shepard's method; Masselus et al. 2004, §4
/// "Interpolation": "the angle between directions was used as a distance measure and the
/// weights … are inverse proportional to the distance …; a variation … only tak(es) into
/// account a pre-defined number of nearest neighbor directions", 32 in their figure 4.D).
///
/// At a fine centre `d`, with `a_j = ∠(d, d_j)` the angle to sample `j` (computed as
/// `atan2(|d × d_j|, d · d_j)`):
/// - if some `a_j ≤ 1e-9` rad the centre coincides with that sample and takes its value;
/// - otherwise, with `a_(n)` the `n`-th smallest angle, the neighbours are
///   `N = {j : a_j ≤ a_(n) (1 + 1e-9)}` — the `n` nearest, plus any sample tied with the
///   `n`-th (on a regular grid ties are common, and breaking them by index would make the
///   result depend on rounding and break the grid's symmetries) — and
///   `R̂(d) = Σ_{j∈N} a_j^{−p} R_j / Σ_{j∈N} a_j^{−p}`.
///
/// Weights are normalised, so constants are reproduced exactly; the result is a convex
/// combination (no overshoot), continuous except where the neighbour set changes.
#[derive(Clone, Debug)]
pub struct Idw {
    grids: Grids,
    neighbours: usize,
    power: f64,
    rows: SparseRows,
}

impl Idw {
    /// The paper's neighbour count.
    pub const DEFAULT_NEIGHBOURS: usize = 32;
    /// The paper's "inverse proportional to the distance".
    pub const DEFAULT_POWER: f64 = 1.0;

    /// Precomputes the weights of `neighbours` nearest samples with `1/angle^power`.
    ///
    /// # Errors
    /// An empty or too large grid, `neighbours` 0 or more than the samples, `power` negative
    /// or not finite.
    pub fn new(
        coarse: [u32; 2],
        fine: [u32; 2],
        neighbours: usize,
        power: f64,
    ) -> Result<Self, FieldError> {
        let grids = Grids::new("IDW", coarse, fine)?;
        let d = grids.samples();
        if neighbours == 0 || neighbours > d {
            return Err(invalid(format!(
                "IDW reconstruction: {neighbours} neighbours: give between 1 and the {d} samples of the {}×{} grid",
                coarse[0], coarse[1]
            )));
        }
        if !(power.is_finite() && power >= 0.0) {
            return Err(invalid(format!(
                "IDW reconstruction: the power {power} must be finite and at least 0"
            )));
        }
        const COINCIDENT: f64 = 1e-9;
        const TIE: f64 = 1e-9;
        let dirs: Vec<DVec3> = (0..d).map(|j| centre(grids.coarse, j)).collect();
        let rows: Vec<Vec<(u32, f64)>> = (0..grids.cells())
            .into_par_iter()
            .map(|k| {
                let c = centre(grids.fine, k);
                let dots: Vec<f64> = dirs.iter().map(|s| s.dot(c)).collect();
                let mut sorted = dots.clone();
                sorted.select_nth_unstable_by(neighbours - 1, |a, b| b.total_cmp(a));
                // Every sample within the tie tolerance of the n-th has a cosine above this
                // (the cosine is monotone in the angle; 1e-6 is far more than rounding).
                let floor = sorted[neighbours - 1] - 1e-6;
                let mut cand: Vec<(usize, f64)> = dots
                    .iter()
                    .enumerate()
                    .filter(|(_, &x)| x >= floor)
                    .map(|(j, _)| (j, angle(dirs[j], c)))
                    .collect();
                cand.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
                if cand[0].1 <= COINCIDENT {
                    return vec![(cand[0].0 as u32, 1.0)];
                }
                let nth = cand[neighbours - 1].1;
                let nearest = cand[0].1;
                cand.retain(|&(_, a)| a <= nth * (1.0 + TIE));
                // (a_min / a_j)^p: the same normalised weights without overflow for large p.
                let w: Vec<f64> = cand
                    .iter()
                    .map(|&(_, a)| (nearest / a).powf(power))
                    .collect();
                let sum: f64 = w.iter().sum();
                let mut row: Vec<(u32, f64)> = cand
                    .iter()
                    .zip(&w)
                    .map(|(&(j, _), &w)| (j as u32, w / sum))
                    .collect();
                row.sort_unstable_by_key(|e| e.0);
                row
            })
            .collect();
        Ok(Self {
            grids,
            neighbours,
            power,
            rows: SparseRows::from_rows(rows, d),
        })
    }

    /// The paper's settings: 32 nearest neighbours, weights `1/angle`.
    ///
    /// # Errors
    /// As [`Idw::new`] (a grid of fewer than 32 samples).
    pub fn paper(coarse: [u32; 2], fine: [u32; 2]) -> Result<Self, FieldError> {
        Self::new(coarse, fine, Self::DEFAULT_NEIGHBOURS, Self::DEFAULT_POWER)
    }

    /// `"idw"`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        "idw"
    }

    /// Neighbours asked for (a row holds more when samples tie with the last).
    #[must_use]
    pub fn neighbours(&self) -> usize {
        self.neighbours
    }

    /// The exponent of the inverse angle.
    #[must_use]
    pub fn power(&self) -> f64 {
        self.power
    }

    /// Stored weights (nonzeros of `M`).
    #[must_use]
    pub fn nonzeros(&self) -> usize {
        self.rows.vals.len()
    }
}

impl LinearReconstruction for Idw {
    fn apply(&self, samples: &[f32], fine: &mut [f64]) {
        self.grids.check(samples.len(), fine.len());
        self.rows.mul(samples, fine);
    }

    fn apply_transpose(&self, fine: &[f64], coarse: &mut [f64]) {
        self.grids.check(coarse.len(), fine.len());
        coarse.fill(0.0);
        self.rows.mul_t_add(fine, coarse);
    }
}

// ---------------------------------------------------------------------------------------------
// Biquadric polynomial
// ---------------------------------------------------------------------------------------------

/// **A biquadric polynomial per hemisphere** (Masselus et al. 2004, §4 "Fitting to a Biquadric
/// Polynomial", after Polynomial Texture Maps, Malzbender, Gelb & Wolters 2001).
///
/// The paper fits one polynomial over its hemisphere of light directions; this grid covers the
/// whole sphere, so the upper (rows with `θ < π/2`) and lower hemispheres are fitted
/// separately: `f(d) ≈ a0 + a1 u + a2 v + a3 u² + a4 u v + a5 v²` with `(u, v) = (d.x, d.z)`
/// (the PTM's projected light direction in the plane of the equator), by least squares weighted
/// by each sample cell's solid angle. Fine centres take their own hemisphere's polynomial; a
/// fine row centred on the equator (odd `FH`) takes the mean of the two.
///
/// A hemisphere's fit is determined when it has two rings of samples (`H ≥ 4`, `H` even so
/// that the equator is a row boundary) of at least five azimuths each (`W ≥ 5`): on one ring
/// the polynomial is a trigonometric polynomial of degree 2 in `φ` (5 coefficients, aliased
/// below 5 azimuths), and `u² + v²` is constant on a ring.
#[derive(Clone, Debug)]
pub struct Biquadric {
    grids: Grids,
    map: Factored,
}

impl Biquadric {
    /// Precomputes both hemispheres' weighted pseudo-inverses and the fine grid's monomials.
    ///
    /// # Errors
    /// An empty or too large grid; `H` odd or below 4; `W` below 5.
    pub fn new(coarse: [u32; 2], fine: [u32; 2]) -> Result<Self, FieldError> {
        let grids = Grids::new("biquadric", coarse, fine)?;
        let [cw, ch] = grids.coarse;
        if !ch.is_multiple_of(2) {
            return Err(invalid(format!(
                "biquadric reconstruction: the sampled grid's height {ch} must be even so that the equator is a row boundary"
            )));
        }
        if ch < 4 || cw < 5 {
            return Err(invalid(format!(
                "biquadric reconstruction: a {cw}×{ch} grid does not determine a biquadric per hemisphere: it needs two rows per hemisphere (height ≥ 4) of at least five azimuths (width ≥ 5)"
            )));
        }
        let d = grids.samples();
        let monomials = |p: DVec3| [1.0, p.x, p.z, p.x * p.x, p.x * p.z, p.z * p.z];
        let mut fit = vec![0.0f64; 12 * d];
        for hemi in 0..2 {
            let rows = if hemi == 0 { 0..ch / 2 } else { ch / 2..ch };
            let idx: Vec<usize> = rows
                .flat_map(|r| (0..cw).map(move |c| r * cw + c))
                .collect();
            let design: Vec<f64> = idx
                .iter()
                .flat_map(|&j| monomials(centre(grids.coarse, j)))
                .collect();
            let weights: Vec<f64> = idx
                .iter()
                .map(|&j| solid_angle(grids.coarse, j / cw))
                .collect();
            let p = weighted_pseudo_inverse(&design, idx.len(), 6, &weights).map_err(|i| {
                invalid(format!(
                    "biquadric reconstruction: the {} hemisphere's samples do not determine monomial {i}",
                    if hemi == 0 { "upper" } else { "lower" }
                ))
            })?;
            for r in 0..6 {
                for (n, &j) in idx.iter().enumerate() {
                    fit[(6 * hemi + r) * d + j] = p[r * idx.len() + n];
                }
            }
        }
        let [fw, fh] = grids.fine;
        let mut basis = vec![0.0f64; 12 * grids.cells()];
        for (k, b) in basis.chunks_exact_mut(12).enumerate() {
            let m = monomials(centre(grids.fine, k));
            // 2·row + 1 against FH: above, on or below the equator.
            let row2 = 2 * (k / fw) + 1;
            let (upper, lower) = match row2.cmp(&fh) {
                std::cmp::Ordering::Less => (1.0, 0.0),
                std::cmp::Ordering::Equal => (0.5, 0.5),
                std::cmp::Ordering::Greater => (0.0, 1.0),
            };
            for i in 0..6 {
                b[i] = upper * m[i];
                b[6 + i] = lower * m[i];
            }
        }
        Ok(Self {
            grids,
            map: Factored {
                rank: 12,
                fit,
                basis,
            },
        })
    }

    /// `"biquadric"`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        "biquadric"
    }

    /// The 12 coefficients (upper `a0..a5`, then lower) fitted to `samples`.
    ///
    /// # Panics
    /// `samples` not `W·H` long.
    #[must_use]
    pub fn coefficients(&self, samples: &[f32]) -> [f64; 12] {
        self.grids.check(samples.len(), self.grids.cells());
        let mut out = [0.0; 12];
        for (o, row) in out.iter_mut().zip(self.map.fit.chunks_exact(samples.len())) {
            *o = row
                .iter()
                .zip(samples)
                .map(|(p, s)| p * f64::from(*s))
                .sum();
        }
        out
    }
}

/// The [`LinearReconstruction`] of a least-squares fit: its `Factored` map behind the grids'
/// length checks.
macro_rules! factored_reconstruction {
    ($t:ty) => {
        impl LinearReconstruction for $t {
            fn apply(&self, samples: &[f32], fine: &mut [f64]) {
                self.grids.check(samples.len(), fine.len());
                self.map.apply(samples, fine);
            }

            fn apply_transpose(&self, fine: &[f64], coarse: &mut [f64]) {
                self.grids.check(coarse.len(), fine.len());
                self.map.apply_transpose(fine, coarse);
            }
        }
    };
}

factored_reconstruction!(Biquadric);

// ---------------------------------------------------------------------------------------------
// Spherical harmonics
// ---------------------------------------------------------------------------------------------

/// **A spherical-harmonic fit** (Masselus et al. 2004, §4 "Spherical Harmonics", after Wong et
/// al. 1997, who "used 16 or 25 coefficients"): the `order²` coefficients `c` of the real SH
/// basis of `CONVENTIONS.md` (`prt_sh::Basis`) minimising `Σ_j Δω_j (Σ_i c_i y_i(d_j) − R_j)²`,
/// evaluated at the fine centres. The grid covers the sphere, so no mirroring is needed (the
/// paper mirrored its hemisphere).
///
/// A least-squares fit, not the projection `∫ f y_i`: it reproduces every function of its
/// span (constants among them) exactly up to rounding, where a quadrature projection of the
/// samples would not. It is determined when the grid resolves every band: `W ≥ 2·order − 1`
/// azimuths (frequencies `m < order` must not alias on `W` equispaced samples) and
/// `H ≥ order` rows (each `m` has `order − m` Legendre functions to separate along `θ`),
/// which implies `W·H ≥ order²`.
#[derive(Clone, Debug)]
pub struct ShFit {
    grids: Grids,
    order: usize,
    map: Factored,
}

impl ShFit {
    /// Wong et al.'s 25 coefficients.
    pub const DEFAULT_ORDER: usize = 5;

    /// Precomputes the weighted pseudo-inverse of the sampled basis and the basis at the fine
    /// centres.
    ///
    /// # Errors
    /// An empty or too large grid; order 0 or above `prt_sh::MAX_ORDER`; fewer samples than
    /// coefficients; `W < 2·order − 1` or `H < order`; more than 2^26 stored values.
    pub fn new(coarse: [u32; 2], fine: [u32; 2], order: usize) -> Result<Self, FieldError> {
        let grids = Grids::new("SH", coarse, fine)?;
        let basis_fn =
            prt_sh::Basis::new(order).map_err(|e| invalid(format!("SH reconstruction: {e}")))?;
        let n = order * order;
        let d = grids.samples();
        let [cw, ch] = grids.coarse;
        if d < n {
            return Err(invalid(format!(
                "SH reconstruction: order {order} has {n} coefficients but the {cw}×{ch} grid only {d} samples"
            )));
        }
        if cw + 1 < 2 * order || ch < order {
            return Err(invalid(format!(
                "SH reconstruction: a {cw}×{ch} grid cannot resolve order {order}: it needs at least {} azimuths and {order} rows",
                2 * order - 1
            )));
        }
        if (n as u64) * (d as u64 + grids.cells() as u64) > 1 << 26 {
            return Err(invalid(format!(
                "SH reconstruction: order {order} on these grids would store more than 2^26 values"
            )));
        }
        let mut design = vec![0.0f64; d * n];
        for (j, row) in design.chunks_exact_mut(n).enumerate() {
            basis_fn.eval_unchecked(centre(grids.coarse, j), row);
        }
        let weights: Vec<f64> = (0..d).map(|j| solid_angle(grids.coarse, j / cw)).collect();
        let fit = weighted_pseudo_inverse(&design, d, n, &weights).map_err(|i| {
            invalid(format!(
                "SH reconstruction: the samples do not determine coefficient {i} of order {order}"
            ))
        })?;
        let mut basis = vec![0.0f64; grids.cells() * n];
        basis
            .par_chunks_exact_mut(n)
            .enumerate()
            .for_each(|(k, row)| basis_fn.eval_unchecked(centre(grids.fine, k), row));
        Ok(Self {
            grids,
            order,
            map: Factored {
                rank: n,
                fit,
                basis,
            },
        })
    }

    /// `"sh"`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        "sh"
    }

    /// The order (band count).
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// The fitted coefficients (`order²`, flat index `l(l+1) + m`).
    ///
    /// # Panics
    /// `samples` not `W·H` long.
    #[must_use]
    pub fn coefficients(&self, samples: &[f32]) -> Vec<f64> {
        self.grids.check(samples.len(), self.grids.cells());
        self.map
            .fit
            .chunks_exact(samples.len())
            .map(|row| {
                row.iter()
                    .zip(samples)
                    .map(|(p, s)| p * f64::from(*s))
                    .sum()
            })
            .collect()
    }
}

factored_reconstruction!(ShFit);

// ---------------------------------------------------------------------------------------------
// Multilevel B-splines
// ---------------------------------------------------------------------------------------------

/// Uniform cubic B-spline basis functions `B_0..B_3` at `t ∈ [0, 1]`.
fn cubic_bspline(t: f64) -> [f64; 4] {
    let (t2, t3) = (t * t, t * t * t);
    let u = 1.0 - t;
    [
        u * u * u / 6.0,
        (3.0 * t3 - 6.0 * t2 + 4.0) / 6.0,
        (-3.0 * t3 + 3.0 * t2 + 3.0 * t + 1.0) / 6.0,
        t3 / 6.0,
    ]
}

/// A control lattice of `m × n` cells over `(s, t) ∈ [0, 1)²`: `m` columns (periodic in `s`)
/// by `n + 3` rows (row `r` sits at `t = (r − 1)/n`, one row beyond each end); control point
/// `(col, row)` has index `row·m + col`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Lattice {
    m: usize,
    n: usize,
}

impl Lattice {
    fn len(&self) -> usize {
        self.m * (self.n + 3)
    }

    /// The 16 control points (index, weight `B_k(x − ⌊x⌋) B_l(y − ⌊y⌋)`) of the point `(s, t)`,
    /// `x = s·m`, `y = t·n`: columns `⌊x⌋ − 1 + k` (mod `m`), rows `⌊y⌋ + l` (positions
    /// `⌊y⌋ − 1 + l`), `k, l = 0..3`.
    fn support(&self, s: f64, t: f64) -> [(u32, f64); 16] {
        let (x, y) = (s * self.m as f64, t * self.n as f64);
        let (xi, mut yi) = (x.floor(), y.floor());
        if yi >= self.n as f64 {
            yi = self.n as f64 - 1.0; // t = 1 exactly: the last cell's end
        }
        let (bx, by) = (cubic_bspline(x - xi), cubic_bspline(y - yi));
        let (xi, yi) = (xi as i64, yi as usize);
        let mut out = [(0u32, 0.0f64); 16];
        for l in 0..4 {
            for k in 0..4 {
                let col = (xi - 1 + k as i64).rem_euclid(self.m as i64) as usize;
                out[4 * l + k] = (((yi + l) * self.m + col) as u32, bx[k] * by[l]);
            }
        }
        out
    }

    /// The refinement to the lattice of twice the resolution (Lee et al. 1997, §4.2, the
    /// subdivision of a uniform cubic B-spline): a new control point on an old one takes
    /// `(φ_{i−1} + 6φ_i + φ_{i+1})/8`, one halfway between two `(φ_i + φ_{i+1})/2`, per axis
    /// (periodic in `s`); the refined lattice's function equals this one's on the domain.
    fn refinement(&self) -> (Lattice, SparseRows) {
        let fine = Lattice {
            m: 2 * self.m,
            n: 2 * self.n,
        };
        let m = self.m;
        let col_rule = |q: usize| -> Vec<(usize, f64)> {
            let i = q / 2;
            if q.is_multiple_of(2) {
                vec![((i + m - 1) % m, 0.125), (i, 0.75), ((i + 1) % m, 0.125)]
            } else {
                vec![(i, 0.5), ((i + 1) % m, 0.5)]
            }
        };
        // Fine row b sits at coarse position (b − 1)/2, coarse row a at a − 1.
        let row_rule = |b: usize| -> Vec<(usize, f64)> {
            if !b.is_multiple_of(2) {
                let a = (b - 1) / 2 + 1;
                vec![(a - 1, 0.125), (a, 0.75), (a + 1, 0.125)]
            } else {
                vec![(b / 2, 0.5), (b / 2 + 1, 0.5)]
            }
        };
        let mut rows = Vec::with_capacity(fine.len());
        for b in 0..fine.n + 3 {
            let rr = row_rule(b);
            for q in 0..fine.m {
                let cr = col_rule(q);
                let mut row = Vec::with_capacity(9);
                for &(a, wa) in &rr {
                    for &(i, wi) in &cr {
                        row.push(((a * m + i) as u32, wa * wi));
                    }
                }
                rows.push(row);
            }
        }
        (fine, SparseRows::from_rows(rows, self.len()))
    }
}

/// One level of the hierarchy, as linear maps.
#[derive(Clone, Debug)]
struct Level {
    /// The BA rule: control values from the level's residuals (`controls × samples`).
    approximate: SparseRows,
    /// The level's function at the samples (`samples × controls`), to form the next residual.
    at_samples: SparseRows,
    /// The previous level's accumulated lattice refined to this one (`controls × previous`).
    refine: Option<SparseRows>,
}

/// **Multilevel B-spline approximation** (MBA; Lee, Wolberg & Shin 1997), the method
/// Masselus et al. 2004 recommend (§4 "B-Splines": the lowest error of their comparison,
/// smooth under moving light).
///
/// The paper's parameter domain is a paraboloid map of its hemisphere; this grid covers the
/// sphere, so the B-splines live on the lat-long domain `(s, t) = (φ/2π, θ/π) ∈ [0, 1)²`,
/// **periodic in `s`** and extended in `t` (the lattice has one row of control points beyond
/// each pole, as in Lee et al.'s `(m + 3) × (n + 3)` lattice; nothing forces the function to be
/// single-valued at a pole). The exact scheme:
///
/// - Level `k = 0 … L−1` has a uniform cubic B-spline lattice of `m_k × n_k = 4·2^k × 2·2^k`
///   cells: square cells (90° at level 0, four B-spline patches around the equator and two
///   from pole to pole — our reading of the paper's "four starting grids" on a sphere twice
///   as wide as tall), halved at every level. `f_k(s, t) = Σ_{k,l=0..3} B_k(x−⌊x⌋) B_l(y−⌊y⌋)
///   φ_{(⌊x⌋−1+k) mod m_k, ⌊y⌋−1+l}` with `x = s·m_k`, `y = t·n_k`, `B` the uniform cubic
///   B-spline basis.
/// - Residuals: `r⁰_c = R_c`; level `k` fits `r^k` with the BA rule (Lee et al. 1997, §3.2):
///   each sample `c` with weights `w_ab = B_a B_b` on its 16 control points proposes
///   `φ_c = w_ab r^k_c / Σ_{a,b} w_ab²` to each, and each control point takes
///   `φ = Σ_c w_c² φ_c / Σ_c w_c²` over the samples in its support (0 when there are none);
///   then `r^{k+1}_c = r^k_c − f_k(s_c, t_c)`.
/// - `R̂ = Σ_k f_k`, evaluated as one lattice: the sum is refined level by level
///   (`Ψ_0 = Φ_0`, `Ψ_k = refine(Ψ_{k−1}) + Φ_k`, exact B-spline subdivision, Lee et al.
///   §4.2) and the finest lattice is evaluated at the fine centres.
///
/// The weights depend on the positions only, so `M = F Σ_k (refinements) A_k T_{k−1} … T_0`
/// with `A_k` the BA rule and `T_k = I − E_k A_k` (`E_k` the evaluation at the samples); all
/// of them are stored as sparse rows, and `apply`/`apply_transpose` run through them.
///
/// Default levels ([`MultilevelBSpline::default_levels`]): until the finest lattice has at
/// least as many cells as there are samples in each direction (`m_{L−1} ≥ W`,
/// `n_{L−1} ≥ H`): 5 levels (a 64 × 32 lattice) for 64 × 32 samples; the paper used six on its
/// 1280 samples. BA is an approximation, not a projection: constants are reproduced only as
/// the levels converge.
#[derive(Clone, Debug)]
pub struct MultilevelBSpline {
    grids: Grids,
    levels: Vec<Level>,
    finest: Lattice,
    evaluate: SparseRows,
}

impl MultilevelBSpline {
    /// The level-0 lattice, cells in `s` (azimuth) and `t` (polar angle).
    pub const START_LATTICE: [usize; 2] = [4, 2];
    /// The most levels accepted (a 2048 × 1024-cell finest lattice).
    pub const MAX_LEVELS: usize = 10;

    /// Levels until the lattice is at least as fine as the samples (at most
    /// [`MultilevelBSpline::MAX_LEVELS`]).
    #[must_use]
    pub fn default_levels(coarse: [u32; 2]) -> usize {
        let [m0, n0] = Self::START_LATTICE;
        (1..=Self::MAX_LEVELS)
            .find(|&l| m0 << (l - 1) >= coarse[0] as usize && n0 << (l - 1) >= coarse[1] as usize)
            .unwrap_or(Self::MAX_LEVELS)
    }

    /// Precomputes the hierarchy of `levels` lattices.
    ///
    /// # Errors
    /// An empty or too large grid; `levels` 0 or above [`MultilevelBSpline::MAX_LEVELS`].
    pub fn new(coarse: [u32; 2], fine: [u32; 2], levels: usize) -> Result<Self, FieldError> {
        let grids = Grids::new("multilevel B-spline", coarse, fine)?;
        if levels == 0 || levels > Self::MAX_LEVELS {
            return Err(invalid(format!(
                "multilevel B-spline reconstruction: {levels} levels: give between 1 and {}",
                Self::MAX_LEVELS
            )));
        }
        let d = grids.samples();
        let param = |[w, h]: [usize; 2], k: usize| {
            (
                ((k % w) as f64 + 0.5) / w as f64,
                ((k / w) as f64 + 0.5) / h as f64,
            )
        };
        let [m0, n0] = Self::START_LATTICE;
        let mut lattice = Lattice { m: m0, n: n0 };
        let mut out = Vec::with_capacity(levels);
        for level in 0..levels {
            let refine = if level == 0 {
                None
            } else {
                let (next, r) = lattice.refinement();
                lattice = next;
                Some(r)
            };
            let supports: Vec<[(u32, f64); 16]> = (0..d)
                .map(|c| {
                    let (s, t) = param(grids.coarse, c);
                    lattice.support(s, t)
                })
                .collect();
            // BA: control p gets Σ_c w_pc² φ_c / Σ_c w_pc², φ_c = w_pc r_c / Σ_ab w_ab².
            let mut omega = vec![0.0f64; lattice.len()];
            let mut rows: Vec<Vec<(u32, f64)>> = vec![Vec::new(); lattice.len()];
            for (c, sup) in supports.iter().enumerate() {
                let sum2: f64 = sup.iter().map(|(_, w)| w * w).sum();
                // (A sample on a knot line has weight 0 on the far row or column: no entry.)
                for &(p, w) in sup.iter().filter(|e| e.1 > 0.0) {
                    omega[p as usize] += w * w;
                    rows[p as usize].push((c as u32, w * w * w / sum2));
                }
            }
            // Control points with no sample in their support keep 0 (empty rows).
            for (row, om) in rows.iter_mut().zip(&omega) {
                row.iter_mut().for_each(|e| e.1 /= om);
            }
            let at_samples =
                SparseRows::from_rows(supports.iter().map(|s| s.to_vec()).collect(), lattice.len());
            out.push(Level {
                approximate: SparseRows::from_rows(rows, d),
                at_samples,
                refine,
            });
        }
        let evaluate = SparseRows::from_rows(
            (0..grids.cells())
                .map(|k| {
                    let (s, t) = param(grids.fine, k);
                    lattice.support(s, t).to_vec()
                })
                .collect(),
            lattice.len(),
        );
        Ok(Self {
            grids,
            levels: out,
            finest: lattice,
            evaluate,
        })
    }

    /// With [`MultilevelBSpline::default_levels`].
    ///
    /// # Errors
    /// As [`MultilevelBSpline::new`].
    pub fn with_default_levels(coarse: [u32; 2], fine: [u32; 2]) -> Result<Self, FieldError> {
        Self::new(coarse, fine, Self::default_levels(coarse))
    }

    /// `"bspline"`.
    #[must_use]
    pub fn name(&self) -> &'static str {
        "bspline"
    }

    /// Number of levels.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// The finest lattice's cells, `[m, n]` (azimuth, polar angle).
    #[must_use]
    pub fn finest_lattice(&self) -> [usize; 2] {
        [self.finest.m, self.finest.n]
    }
}

impl LinearReconstruction for MultilevelBSpline {
    fn apply(&self, samples: &[f32], fine: &mut [f64]) {
        self.grids.check(samples.len(), fine.len());
        let mut residual: Vec<f64> = samples.iter().map(|&s| f64::from(s)).collect();
        let mut acc: Vec<f64> = Vec::new();
        let last = self.levels.len() - 1;
        for (k, level) in self.levels.iter().enumerate() {
            let mut phi = vec![0.0f64; level.approximate.height()];
            level.approximate.mul(&residual, &mut phi);
            if k < last {
                level.at_samples.mul_sub(&phi, &mut residual);
            }
            if let Some(r) = &level.refine {
                // phi += refine(acc)
                for (i, p) in phi.iter_mut().enumerate() {
                    let (c, v) = r.row(i);
                    *p += c
                        .iter()
                        .zip(v)
                        .map(|(&c, &v)| v * acc[c as usize])
                        .sum::<f64>();
                }
            }
            acc = phi;
        }
        self.evaluate.mul(&acc, fine);
    }

    fn apply_transpose(&self, fine: &[f64], coarse: &mut [f64]) {
        self.grids.check(coarse.len(), fine.len());
        // g_k: the adjoint of level k's lattice Φ_k (through the refinements and F).
        let mut g: Vec<Vec<f64>> = vec![Vec::new(); self.levels.len()];
        let last = self.levels.len() - 1;
        g[last] = vec![0.0; self.evaluate.width];
        self.evaluate.mul_t_add(fine, &mut g[last]);
        for k in (1..=last).rev() {
            let r = self.levels[k]
                .refine
                .as_ref()
                .expect("levels above 0 refine");
            let mut prev = vec![0.0; r.width];
            r.mul_t_add(&g[k], &mut prev);
            g[k - 1] = prev;
        }
        // a = A_Lᵀ g_L; then a ← T_kᵀ a + A_kᵀ g_k = a + A_kᵀ (g_k − E_kᵀ a), k = L−1 … 0.
        coarse.fill(0.0);
        self.levels[last].approximate.mul_t_add(&g[last], coarse);
        for k in (0..last).rev() {
            let level = &self.levels[k];
            let mut t = std::mem::take(&mut g[k]);
            let mut et = vec![0.0; level.at_samples.width];
            level.at_samples.mul_t_add(coarse, &mut et);
            t.iter_mut().zip(&et).for_each(|(a, b)| *a -= b);
            level.approximate.mul_t_add(&t, coarse);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refinement_keeps_the_function() {
        let lat = Lattice { m: 4, n: 2 };
        let phi: Vec<f64> = (0..lat.len())
            .map(|i| ((i * 7919) % 13) as f64 - 6.0)
            .collect();
        let (fine, r) = lat.refinement();
        let mut psi = vec![0.0; fine.len()];
        r.mul(&phi, &mut psi);
        let eval = |l: &Lattice, v: &[f64], s: f64, t: f64| -> f64 {
            l.support(s, t)
                .iter()
                .map(|&(p, w)| w * v[p as usize])
                .sum()
        };
        for i in 0..=40 {
            for j in 0..=20 {
                let (s, t) = (i as f64 / 40.0 * 0.999_999, j as f64 / 20.0);
                let (a, b) = (eval(&lat, &phi, s, t), eval(&fine, &psi, s, t));
                assert!((a - b).abs() < 1e-12, "({s}, {t}): {a} vs {b}");
            }
        }
    }

    #[test]
    fn bspline_basis_is_a_partition_of_unity() {
        for i in 0..=10 {
            let b = cubic_bspline(i as f64 / 10.0);
            assert!((b.iter().sum::<f64>() - 1.0).abs() < 1e-15);
        }
        let lat = Lattice { m: 8, n: 4 };
        let w: f64 = lat.support(0.37, 0.99).iter().map(|e| e.1).sum();
        assert!((w - 1.0).abs() < 1e-15);
    }

    #[test]
    fn pseudo_inverse_solves_a_weighted_fit_and_detects_rank_loss() {
        // Fit a + b x to (0, 1), (1, 3), (2, 4) with weights 1, 1, 2: normal equations
        // [4 5; 5 9] [a b]ᵀ = [12 19]ᵀ → a = 13/11, b = 16/11.
        let a = [1.0, 0.0, 1.0, 1.0, 1.0, 2.0];
        let p = weighted_pseudo_inverse(&a, 3, 2, &[1.0, 1.0, 2.0]).unwrap();
        let b = [1.0, 3.0, 4.0];
        let c: Vec<f64> = (0..2)
            .map(|i| (0..3).map(|j| p[i * 3 + j] * b[j]).sum())
            .collect();
        assert!((c[0] - 13.0 / 11.0).abs() < 1e-14 && (c[1] - 16.0 / 11.0).abs() < 1e-14);
        let dependent = [1.0, 2.0, 1.0, 2.0, 1.0, 2.0];
        assert_eq!(weighted_pseudo_inverse(&dependent, 3, 2, &[1.0; 3]), Err(1));
    }

    #[test]
    fn sparse_transpose_is_the_adjoint() {
        let m = SparseRows::from_rows(
            vec![vec![(0, 1.0), (2, -2.0)], vec![], vec![(1, 0.5), (2, 3.0)]],
            3,
        );
        let x = [1.0, 2.0, 3.0];
        let y = [0.5, 7.0, -1.0];
        let mut mx = [0.0; 3];
        m.mul(&x, &mut mx);
        let mut mty = [0.0; 3];
        m.mul_t_add(&y, &mut mty);
        let a: f64 = mx.iter().zip(&y).map(|(a, b)| a * b).sum();
        let b: f64 = x.iter().zip(&mty).map(|(a, b)| a * b).sum();
        assert!((a - b).abs() < 1e-15);
    }
}
