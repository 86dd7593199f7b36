//! The regularised least-squares solve of inverse lighting, per channel: the Gaussian prior
//! over the bands past the well-determined ones, the truncated SVD, and the robust
//! (Tukey-biweight) reweighting — see [`crate::inverse`]'s docs, which describe the model,
//! and [`crate::sources`], whose columns join the SH ones undamped.

use crate::error::SceneRelightError;
use nalgebra::{DMatrix, DVector};

/// A regularised solve of one channel: `x` (model bands), the residual's squared norm, and
/// the singular directions dropped.
pub struct ChannelSolve {
    /// Coefficients over the model's bands.
    pub x: DVector<f64>,
    /// `‖A x − b‖²`.
    pub residual2: f64,
    /// Directions the truncated SVD dropped.
    pub dropped: usize,
}

/// Solves `a x ≈ b` with bands `≥ well` under the Gaussian prior of the module docs (two
/// rounds) and a truncated SVD at `limit`.
///
/// # Errors
/// A failed SVD solve.
pub fn solve_channel(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    well: usize,
    limit: f64,
) -> Result<ChannelSolve, SceneRelightError> {
    solve_channel_with(a, b, a.ncols(), well, limit)
}

/// [`solve_channel`] where only the first `sh_cols` columns of `a` are SH coefficients (the
/// prior's bands); the columns after them (compact sources, [`crate::sources`]) are not
/// regularised.
///
/// # Errors
/// A failed SVD solve.
pub fn solve_channel_with(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    sh_cols: usize,
    well: usize,
    limit: f64,
) -> Result<ChannelSolve, SceneRelightError> {
    let cols = a.ncols();
    let model = (sh_cols as f64).sqrt().round() as usize;
    let mut damping = vec![0.0; cols];
    let mut out = tsvd(a, b, &damping, limit)?;
    if well >= model {
        return Ok(out);
    }
    for _ in 0..2 {
        // Noise per (weighted) equation, from the residual.
        let dof = (a.nrows().saturating_sub(cols)).max(1) as f64;
        let noise = (out.residual2 / dof).sqrt();
        // The prior's scale from the well-determined bands (band 0 when there is no other):
        // mean over them of (l + 1)² x²_{lm}.
        let top = well.max(1);
        let s2 = (0..top * top)
            .map(|i| {
                let l = (i as f64).sqrt().floor() + 1.0;
                l * l * out.x[i] * out.x[i]
            })
            .sum::<f64>()
            / (top * top) as f64;
        if s2 <= 0.0 {
            break;
        }
        for (i, d) in damping
            .iter_mut()
            .enumerate()
            .take(sh_cols)
            .skip(well * well)
        {
            let l = (i as f64).sqrt().floor();
            *d = noise * (l + 1.0) / s2.sqrt();
        }
        out = tsvd(a, b, &damping, limit)?;
    }
    Ok(out)
}

/// Most reweighting rounds of a robust solve (it stops earlier once no weight moves by more
/// than [`ROBUST_SETTLED`]).
const ROBUST_ROUNDS: usize = 50;

/// A robust solve's weights have settled when none moved by more than this in a round.
const ROBUST_SETTLED: f64 = 1e-6;

/// Tukey's biweight constant in robust standard deviations (95 % efficiency when the residuals
/// are Gaussian noise).
const TUKEY_C: f64 = 4.685;

/// [`solve_channel`], and with `robust` then iteratively reweighted (an M-estimator; Huber &
/// Ronchetti, *Robust Statistics*, §7.8): each round gives equation `i` the weight
/// `(1 − u²)²` for `|u| < 1`, else 0, with `u = r_i / (c · σ)`, `r_i` its residual, `σ` the
/// residuals' robust scale `1.4826 · median |r|` and `c = 4.685` (95 % efficiency under Gaussian noise), and solves again
/// (the prior and truncation as [`solve_channel`]), until the weights settle. Returns the
/// solve (its `residual2` over the unweighted equations) and the equations whose final weight
/// is below ½.
///
/// # Errors
/// A failed SVD solve.
pub fn solve_channel_robust(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    well: usize,
    limit: f64,
    robust: bool,
) -> Result<(ChannelSolve, usize), SceneRelightError> {
    solve_channel_robust_with(a, b, a.ncols(), well, limit, robust)
}

/// [`solve_channel_robust`] with only the first `sh_cols` columns regularised
/// ([`solve_channel_with`]).
///
/// # Errors
/// A failed SVD solve.
pub fn solve_channel_robust_with(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    sh_cols: usize,
    well: usize,
    limit: f64,
    robust: bool,
) -> Result<(ChannelSolve, usize), SceneRelightError> {
    let mut s = solve_channel_with(a, b, sh_cols, well, limit)?;
    if !robust {
        return Ok((s, 0));
    }
    let mut weights = vec![1.0; a.nrows()];
    for _ in 0..ROBUST_ROUNDS {
        let r = a * &s.x - b;
        let mut abs: Vec<f64> = r.iter().map(|v| v.abs()).collect();
        abs.sort_unstable_by(f64::total_cmp);
        let sigma = 1.4826 * abs[abs.len() / 2];
        if sigma <= 0.0 {
            break;
        }
        let mut moved = 0.0f64;
        for (w, ri) in weights.iter_mut().zip(r.iter()) {
            let u = ri / (TUKEY_C * sigma);
            let new = if u.abs() < 1.0 {
                (1.0 - u * u).powi(2)
            } else {
                0.0
            };
            moved = moved.max((new - *w).abs());
            *w = new;
        }
        if moved <= ROBUST_SETTLED {
            break;
        }
        let mut aw = a.clone();
        let mut bw = b.clone();
        for (i, w) in weights.iter().enumerate() {
            let sw = w.sqrt();
            aw.row_mut(i).scale_mut(sw);
            bw[i] *= sw;
        }
        s = solve_channel_with(&aw, &bw, sh_cols, well, limit)?;
    }
    s.residual2 = (a * &s.x - b).norm_squared();
    Ok((s, weights.iter().filter(|w| **w < 0.5).count()))
}

/// Truncated-SVD solve of `[a; diag(damping)] x ≈ [b; 0]`.
fn tsvd(
    a: &DMatrix<f64>,
    b: &DVector<f64>,
    damping: &[f64],
    limit: f64,
) -> Result<ChannelSolve, SceneRelightError> {
    let (rows, cols) = a.shape();
    let damped: Vec<usize> = (0..cols).filter(|&i| damping[i] > 0.0).collect();
    let mut m = DMatrix::zeros(rows + damped.len(), cols);
    m.rows_mut(0, rows).copy_from(a);
    let mut rhs = DVector::zeros(rows + damped.len());
    rhs.rows_mut(0, rows).copy_from(b);
    for (k, &i) in damped.iter().enumerate() {
        m[(rows + k, i)] = damping[i];
    }
    let svd = m.svd(true, true);
    let cutoff = svd.singular_values.max() / limit;
    let dropped = svd.singular_values.iter().filter(|&&s| s < cutoff).count();
    let x = svd
        .solve(&rhs, cutoff)
        .map_err(|e| SceneRelightError::Invalid(format!("least squares: {e}")))?;
    let residual2 = (a * &x - b).norm_squared();
    Ok(ChannelSolve {
        x,
        residual2,
        dropped,
    })
}
