//! Inverse lighting: the environment's SH coefficients from an image of a baked scene
//! (Ramamoorthi & Hanrahan 2001, "A signal-processing framework for inverse rendering";
//! Ramamoorthi's thesis, chapter 6 and §2.4.2 on well-posedness).
//!
//! With a bake, relighting is linear in the lighting: pixel `p`'s channel `c` is
//! `I_c(p) = Σ_i T_{c,i}(p) L_{c,i}`, whatever the material (diffuse transfer, and the glossy
//! terms through `L ⊛ V`). Column `i` of `T_c` is the image relit under the `i`-th basis
//! function alone ([`crate::Bound::relight_under`]), formed as prt forms every image, so the
//! fit inverts exactly what `prt relight` computes. Each channel is a least-squares problem
//! over the object pixels whose 3 × 3 neighbourhood lies on one object (at silhouettes the
//! image mixes in the background, which is not part of the model).
//!
//! How well the image determines the lighting is the conditioning of `T_c` (SVD): adding band
//! `l`'s `2l + 1` columns can only raise the condition number `σ_max / σ_min`, and a noise of
//! relative size ε in the image becomes an error of up to `cond · ε` in the coefficients.
//! Bands whose condition number is within the limit are **well determined**; the fit still
//! solves for every band asked (leaving a band out would push the image's content in it onto
//! the lower bands: 20–30 % errors on the bunny) but **regularises** by truncated SVD — the
//! directions with `σ < σ_max / limit` are dropped (the minimum-norm solution among those the
//! image cannot tell apart) — and reports which bands that touched. For a Lambertian object
//! the thesis predicts bands `l ≤ 2` (its transfer is close to the clamped cosine, whose bands
//! 3, 5, … vanish and 4, 6, … are small); glossy objects determine more.

use crate::bound::Bound;
use crate::error::SceneRelightError;
use crate::imaging::{object_ids, RgbImage};
use crate::relit::RelightOptions;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

/// What to fit.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Bands of lighting to fit (`n²` coefficients per channel).
    pub order: usize,
    /// The largest condition number a kept band may bring.
    pub condition_limit: f64,
    /// Per pixel, the weight of its equation (`1 / variance` where the image's noise is known);
    /// `None`: all 1.
    pub weights: Option<Vec<f64>>,
}

/// The fitted lighting and how well the image determined it.
#[derive(Clone, Debug, Serialize)]
pub struct LightingFit {
    /// Bands fitted: `coefficients` has `order²` rows.
    pub order: usize,
    /// Bands whose condition number is within the limit (`0..well_determined`).
    pub well_determined: usize,
    /// SH coefficients, `[r, g, b]` per basis function in index order `l(l+1)+m`.
    pub coefficients: Vec<[f64; 3]>,
    /// Per band `l` (asked), the condition number of the fit up to that band (the largest over
    /// the channels; infinite when a band's columns are zero, e.g. above the bake's order).
    pub condition_by_band: Vec<f64>,
    /// Bands past the limit: their coefficients are the truncated-SVD (regularised) estimate.
    pub regularised_bands: Vec<usize>,
    /// Singular directions dropped by the regularisation (the most over the channels).
    pub dropped_directions: usize,
    /// The condition-number limit used.
    pub condition_limit: f64,
    /// Pixels in the fit.
    pub pixels: usize,
    /// Per channel, the root-mean-square residual over those pixels (linear radiance).
    pub residual_rms: [f64; 3],
    /// `‖residual‖ / ‖image‖` over those pixels and channels.
    pub relative_residual: f64,
}

/// The pixels a fit uses: on an object, with the eight neighbours on the same object.
///
/// # Errors
/// A camera the tracer refuses.
pub fn fit_pixels(bound: &Bound) -> Result<Vec<usize>, SceneRelightError> {
    let ids = object_ids(bound.scene(), bound.accel())?;
    let (w, h) = (
        bound.scene().camera.width as usize,
        bound.scene().camera.height as usize,
    );
    Ok((0..w * h)
        .filter(|&p| {
            let (x, y) = (p % w, p / w);
            ids[p].is_some()
                && x > 0
                && y > 0
                && x + 1 < w
                && y + 1 < h
                && (0..9).all(|k| ids[(y + k / 3 - 1) * w + x + k % 3 - 1] == ids[p])
        })
        .collect())
}

/// The image under each basis function alone (column `i`: the lighting `e_i` in every
/// channel), at the pixels `pixels`: `[channel](pixels × n²)`.
fn design(
    bound: &Bound,
    pixels: &[usize],
    n: usize,
) -> Result<[DMatrix<f64>; 3], SceneRelightError> {
    let n2 = n * n;
    let mut a = [
        DMatrix::zeros(pixels.len(), n2),
        DMatrix::zeros(pixels.len(), n2),
        DMatrix::zeros(pixels.len(), n2),
    ];
    let once = RelightOptions {
        timing_frames: 1,
        warmup_frames: 0,
        ..RelightOptions::default()
    };
    for i in 0..n2 {
        let mut lighting = vec![[0.0; 3]; n2];
        lighting[i] = [1.0; 3];
        let relit = bound.relight_under(&lighting, &once)?;
        let image = bound.form_image(&relit, 0.0)?;
        for (row, &p) in pixels.iter().enumerate() {
            for (c, m) in a.iter_mut().enumerate() {
                m[(row, i)] = f64::from(image.pixels[p][c]);
            }
        }
    }
    Ok(a)
}

/// `σ_max / σ_min` of `m` (infinite when `σ_min` is 0).
fn condition(m: &DMatrix<f64>) -> f64 {
    let s = m.clone().singular_values();
    let (hi, lo) = (s.max(), s.min());
    if lo > 0.0 {
        hi / lo
    } else {
        f64::INFINITY
    }
}

/// Fits the lighting of `image` (of the bound scene's camera) at `opt.order` bands.
///
/// # Errors
/// An image of another size, an order of 0, weights of the wrong length, no object pixel to
/// fit, and relighting errors.
pub fn fit_lighting(
    bound: &Bound,
    image: &RgbImage,
    opt: &FitOptions,
) -> Result<LightingFit, SceneRelightError> {
    let cam = &bound.scene().camera;
    if (image.width, image.height) != (cam.width as usize, cam.height as usize) {
        return Err(SceneRelightError::Invalid(format!(
            "the image is {}×{}, the scene's camera {}×{}",
            image.width, image.height, cam.width, cam.height
        )));
    }
    if opt.order == 0 {
        return Err(SceneRelightError::Invalid("fit at least one band".into()));
    }
    let pixels = fit_pixels(bound)?;
    if pixels.is_empty() {
        return Err(SceneRelightError::Invalid(
            "no object pixel away from silhouettes to fit".into(),
        ));
    }
    let weights: Vec<f64> = match &opt.weights {
        Some(w) if w.len() != image.pixels.len() => {
            return Err(SceneRelightError::Invalid(format!(
                "{} weights for {} pixels",
                w.len(),
                image.pixels.len()
            )))
        }
        Some(w) => pixels.iter().map(|&p| w[p].max(0.0).sqrt()).collect(),
        None => vec![1.0; pixels.len()],
    };
    let mut a = design(bound, &pixels, opt.order)?;
    for m in &mut a {
        for (row, w) in weights.iter().enumerate() {
            m.row_mut(row).scale_mut(*w);
        }
    }
    let condition_by_band: Vec<f64> = (0..opt.order)
        .map(|l| {
            let cols = (l + 1) * (l + 1);
            a.iter()
                .map(|m| condition(&m.columns(0, cols).into_owned()))
                .fold(0.0, f64::max)
        })
        .collect();
    let well = condition_by_band
        .iter()
        .take_while(|&&k| k <= opt.condition_limit)
        .count();
    solve(&a, image, &pixels, &weights, well, opt, condition_by_band)
}

/// The truncated-SVD least-squares solution over every band asked (singular values below
/// `σ_max / limit` dropped), and its residual.
fn solve(
    a: &[DMatrix<f64>; 3],
    image: &RgbImage,
    pixels: &[usize],
    weights: &[f64],
    well: usize,
    opt: &FitOptions,
    condition_by_band: Vec<f64>,
) -> Result<LightingFit, SceneRelightError> {
    let cols = opt.order * opt.order;
    let mut coefficients = vec![[0.0; 3]; cols];
    let (mut residual_rms, mut r2, mut b2, mut dropped) = ([0.0; 3], 0.0, 0.0, 0);
    for c in 0..3 {
        let b = DVector::from_iterator(
            pixels.len(),
            pixels
                .iter()
                .zip(weights)
                .map(|(&p, w)| w * f64::from(image.pixels[p][c])),
        );
        let svd = a[c].clone().svd(true, true);
        let cutoff = svd.singular_values.max() / opt.condition_limit;
        dropped = dropped.max(svd.singular_values.iter().filter(|&&s| s < cutoff).count());
        let x = svd
            .solve(&b, cutoff)
            .map_err(|e| SceneRelightError::Invalid(format!("least squares: {e}")))?;
        for (i, v) in x.iter().enumerate() {
            coefficients[i][c] = *v;
        }
        let r = &a[c] * &x - &b;
        residual_rms[c] = (r.norm_squared() / pixels.len() as f64).sqrt();
        r2 += r.norm_squared();
        b2 += b.norm_squared();
    }
    Ok(LightingFit {
        order: opt.order,
        well_determined: well,
        coefficients,
        regularised_bands: (well..opt.order).collect(),
        dropped_directions: dropped,
        condition_by_band,
        condition_limit: opt.condition_limit,
        pixels: pixels.len(),
        residual_rms,
        relative_residual: if b2 > 0.0 { (r2 / b2).sqrt() } else { 0.0 },
    })
}
