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
//! **Which bands an image determines.** Per band `l`, the *gain* is the smallest singular
//! value of band `l`'s columns once the lower bands' columns are projected out, over the norm
//! of band 0's column. For a Lambertian object whose normals cover the sphere it is the
//! thesis' `A_l / A_0` (1, 2/3, 1/4, 0, −1/24, 0, 1/64: bands 3, 5, … vanish, 4, 6, … are
//! small), so a Lambertian image determines bands `l ≤ 2` (§2.4.2); a glossy lobe keeps the
//! gain up to higher bands. A relative error ε in the image becomes about ε / gain in that
//! band. Bands whose gain is at least `min_gain` and whose cumulative condition number
//! (`σ_max / σ_min` of the columns up to the band) is within `condition_limit` are **well
//! determined** (the first band failing either ends them).
//!
//! **The bands past them are part of the model, not left out.** The image holds the lighting
//! at every frequency the transfer passes; leaving bands out of the model pushes their content
//! onto the lower bands through the columns they share (one view of an object sees only the
//! normals facing the camera, where `1`, `z` and `z²` look alike). So the forward model runs to
//! `model_order` (by default the bake's) and every band past the well-determined ones is
//! **regularised** by a Gaussian prior (Tikhonov): coefficient variance `s² / (l + 1)²` (the
//! `1/l²` power spectrum of natural illumination), its scale `s` from the well-determined
//! bands, the noise from the fit's own residual (two rounds: fit, estimate, refit), then a
//! truncated SVD at `condition_limit` on the whole. The coefficients returned are bands
//! `< order`; the regularised ones among them are listed.
//!
//! **Robust fits** (`FitOptions::robust`, `prt fit-lighting --robust`): the solve is repeated
//! with Tukey's biweight on the residuals ([`solve_channel_robust`]), so pixels the model
//! cannot represent lose their weight. It helps where that error sits in few pixels (a sun's
//! terminator ringing: sunrise 2.18 → 1.60 %) and not where it is spread (a softbox: studio
//! 13.1 → 16.0 %), so it is off by default (crates/scene_relight/README.md).
//!
//! **Compact sources** ([`crate::sources`], `FitOptions::max_sources`, on by default): a sun's
//! or a lamp's cast shadows and terminators are frequencies the SH model cannot hold, so up to
//! `max_sources` small caps, each imaged through the exact transfer (traced), are fitted
//! beside the SH lighting where they pay, and their projections added to the coefficients
//! (studio map, Lambertian probe: 13.1 → 1.6 %; README).

use crate::bound::Bound;
use crate::error::SceneRelightError;
use crate::imaging::{object_ids, RgbImage};
use crate::lobe::PhongModel;
use crate::relit::RelightOptions;
use nalgebra::{DMatrix, DVector};
use serde::Serialize;

pub use crate::solve::{
    solve_channel, solve_channel_robust, solve_channel_robust_with, solve_channel_with,
    ChannelSolve,
};

/// What to fit.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Bands of lighting to return (`n²` coefficients per channel).
    pub order: usize,
    /// Bands of the forward model (at least `order`; `None`: the bake's largest order).
    pub model_order: Option<usize>,
    /// The largest cumulative condition number of a well-determined band, and the
    /// truncated-SVD cutoff `σ_max / limit` of the solve.
    pub condition_limit: f64,
    /// The smallest gain (relative to band 0) of a well-determined band.
    pub min_gain: f64,
    /// Per pixel, the weight of its equation (`1 / variance` where the image's noise is known);
    /// `None`: all 1.
    pub weights: Option<Vec<f64>>,
    /// Known coefficients to check the fit against (e.g. `prt sh project` of the map that lit
    /// the image), rows of `[r, g, b]`.
    pub truth: Option<Vec<[f64; 3]>>,
    /// Fit only the pixels whose surface has at most this fraction of its cosine-weighted
    /// hemisphere blocked ([`unoccluded_pixels`]; per-pixel bakes without bounces); `None`:
    /// every object pixel.
    pub max_occlusion: Option<f64>,
    /// The forward model of `phong` lobes: by default the light's cosine inside the integral
    /// ([`PhongModel::Fitted`]); relighting's default, the cosine frozen at the lobe's centre,
    /// is 7.9 % off the path tracer on one unoccluded Phong sphere (exponent 10), an error a
    /// fit through it inherits (crates/scene_relight/README.md).
    pub phong: PhongModel,
    /// Iteratively reweighted least squares with Tukey's biweight ([`solve_channel_robust`]):
    /// pixels the forward model cannot represent (ringing of a truncated model across the
    /// terminator of a compact light, cast-shadow edges) lose their weight instead of pulling
    /// the coefficients.
    pub robust: bool,
    /// Compact sources to look for beside the SH lighting ([`crate::sources`]): at most this
    /// many, each kept only where it pays; 0: SH only.
    pub max_sources: usize,
}

impl FitOptions {
    /// Options with the defaults of `prt fit-lighting` (condition limit 1000, minimum gain
    /// 0.05, the bake's order as the model's, no weights, no truth, up to
    /// [`crate::sources::DEFAULT_MAX_SOURCES`] compact sources).
    #[must_use]
    pub fn new(order: usize) -> Self {
        Self {
            order,
            model_order: None,
            condition_limit: 1000.0,
            min_gain: 0.05,
            weights: None,
            truth: None,
            max_occlusion: None,
            phong: PhongModel::Fitted,
            robust: false,
            max_sources: crate::sources::DEFAULT_MAX_SOURCES,
        }
    }
}

/// The fitted lighting and how well the image determined it.
#[derive(Clone, Debug, Serialize)]
pub struct LightingFit {
    /// Bands returned: `coefficients` has `order²` rows.
    pub order: usize,
    /// Bands of the forward model.
    pub model_order: usize,
    /// The forward model of `phong` lobes.
    pub phong_model: PhongModel,
    /// Bands the image determines (`0..well_determined`; see the module docs).
    pub well_determined: usize,
    /// SH coefficients, `[r, g, b]` per basis function in index order `l(l+1)+m`.
    pub coefficients: Vec<[f64; 3]>,
    /// Per band `l` of the model, the condition number of the columns up to that band (the
    /// largest over the channels; infinite when a band's columns are zero).
    pub condition_by_band: Vec<f64>,
    /// Per band `l` of the model, its gain relative to band 0 (the smallest over the channels).
    pub gain_by_band: Vec<f64>,
    /// Bands `< order` past the well-determined ones: their coefficients are regularised.
    pub regularised_bands: Vec<usize>,
    /// Singular directions the final truncated SVD dropped (the most over the channels).
    pub dropped_directions: usize,
    /// The condition-number limit used.
    pub condition_limit: f64,
    /// The minimum gain used.
    pub min_gain: f64,
    /// Pixels in the fit.
    pub pixels: usize,
    /// Per channel, the root-mean-square residual over those pixels (linear radiance).
    pub residual_rms: [f64; 3],
    /// `‖residual‖ / ‖image‖` over those pixels and channels (weighted).
    pub relative_residual: f64,
    /// Robust fits: equations (pixel and channel) whose final weight is below ½, of
    /// `3 × pixels`; 0 otherwise.
    pub downweighted: usize,
    /// Against the known coefficients, when given.
    pub truth: Option<TruthCheck>,
    /// Compact sources fitted beside the SH part (their projections are in `coefficients`).
    pub sources: Vec<crate::sources::Source>,
    /// `‖residual‖ / ‖image‖` of the SH-only fit, then after each source found (weighted):
    /// what each source explained. Empty without a source search.
    pub residual_by_sources: Vec<f64>,
}

/// The fit against known coefficients.
#[derive(Clone, Debug, Serialize)]
pub struct TruthCheck {
    /// Relative L2 error over the well-determined bands (all channels).
    pub rel_l2_well_determined: f64,
    /// Per band `< order`, the relative L2 error of that band's coefficients.
    pub rel_l2_by_band: Vec<f64>,
    /// `‖T·L_true − image‖ / ‖image‖` (weighted, bands of the model the truth has): what the
    /// forward model misses (model error and noise); compare with `relative_residual`.
    pub model_residual: f64,
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

/// The pixels of `pixels` whose surface has at most `max_occlusion` of its cosine-weighted
/// hemisphere blocked, read from a per-pixel bake without bounces: there a pixel's diffuse
/// transfer has `T₀₀ = ∫ Y₀₀ V cos dω = π Y₀₀ · (visible cosine-weighted fraction)` per
/// footprint sample on the object (`Y₀₀ = 1/(2√π)`; radiance is `albedo/π · T·L`), so the
/// fraction is `T₀₀ K / (π Y₀₀ hits)`.
/// Why: a cast shadow under a compact light is a high-frequency product of lighting and
/// visibility that a model of any practical order misses (the model residual of the
/// README's table), while at an unoccluded Lambertian point the image depends on the lighting
/// through its lowest bands only (the thesis' analysis, which assumes no cast shadows).
///
/// # Errors
/// A bake that is not per pixel or has bounces (its transfer then holds interreflection too),
/// a fraction outside `[0, 1]`.
pub fn unoccluded_pixels(
    bound: &Bound,
    pixels: &[usize],
    max_occlusion: f64,
) -> Result<Vec<usize>, SceneRelightError> {
    let bake = bound.bake();
    if !(0.0..=1.0).contains(&max_occlusion) {
        return Err(SceneRelightError::Invalid(format!(
            "an occlusion limit of {max_occlusion}: a fraction in [0, 1]"
        )));
    }
    if !matches!(
        bake.meta.sample_kind,
        prt_bakefile::SampleKind::Pixel { .. }
    ) || bake.meta.bounces > 0
    {
        return Err(SceneRelightError::Invalid(
            "leaving occluded pixels out needs a per-pixel bake without bounces (its transfer says how much of each pixel's hemisphere is blocked)".into(),
        ));
    }
    let ids = object_ids(bound.scene(), bound.accel())?;
    // π Y₀₀: the transfer's DC coefficient where nothing is blocked.
    let open = 0.5 * std::f64::consts::PI.sqrt();
    let visible = |p: usize| -> Option<f64> {
        let o = &bake.objects[ids[p]?];
        let block = o.diffuse_block()?;
        let cov = o.coverage.as_ref()?;
        let local = p.checked_sub(o.point_first as usize)?;
        let hits = f64::from(*cov.hits.get(local)?);
        let n2 = (o.order * o.order) as usize;
        let t00 = f64::from(*block.data.get(local * o.channels as usize * n2)?);
        (hits > 0.0).then(|| t00 * f64::from(cov.pixel_samples) / (open * hits))
    };
    Ok(pixels
        .iter()
        .copied()
        .filter(|&p| visible(p).is_some_and(|v| v >= 1.0 - max_occlusion))
        .collect())
}

/// The image under each basis function alone (column `i`: the lighting `e_i` in every
/// channel), `phong` lobes relit by `phong`, at the pixels `pixels`, each row scaled by
/// `sqrt_weights`: `[channel](pixels × n²)`.
///
/// # Errors
/// Relighting errors.
pub fn basis_images(
    bound: &Bound,
    pixels: &[usize],
    sqrt_weights: &[f64],
    n: usize,
    phong: PhongModel,
) -> Result<[DMatrix<f64>; 3], SceneRelightError> {
    let n2 = n * n;
    let mut a = [
        DMatrix::zeros(pixels.len(), n2),
        DMatrix::zeros(pixels.len(), n2),
        DMatrix::zeros(pixels.len(), n2),
    ];
    // A per-pixel bake's points are the image's pixels: only the fit's are relit (the
    // others come out 0 and are not read).
    let subset = bound.footprints().map(|_| {
        let fit: Vec<u32> = pixels.iter().map(|&p| p as u32).collect();
        vec![fit; bound.scene().meshes.len()]
    });
    let once = RelightOptions {
        timing_frames: 1,
        warmup_frames: 0,
        phong,
        points: subset,
        ..RelightOptions::default()
    };
    for i in 0..n2 {
        let mut lighting = vec![[0.0; 3]; n2];
        lighting[i] = [1.0; 3];
        let relit = bound.relight_under(&lighting, &once)?;
        let image = bound.form_image(&relit, 0.0)?;
        for (row, (&p, w)) in pixels.iter().zip(sqrt_weights).enumerate() {
            for (c, m) in a.iter_mut().enumerate() {
                m[(row, i)] = w * f64::from(image.pixels[p][c]);
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

/// Per band, the cumulative condition number and the gain (module docs), worst channel.
#[must_use]
pub fn conditioning(a: &[DMatrix<f64>; 3], order: usize) -> (Vec<f64>, Vec<f64>) {
    let cond = (0..order)
        .map(|l| {
            let cols = (l + 1) * (l + 1);
            a.iter()
                .map(|m| condition(&m.columns(0, cols).into_owned()))
                .fold(0.0, f64::max)
        })
        .collect();
    let gain = (0..order)
        .map(|l| {
            a.iter()
                .map(|m| band_gain(m, l))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    (cond, gain)
}

/// Band `l`'s gain in `m`: the smallest singular value of its columns with the lower bands'
/// span projected out, over the norm of column 0.
fn band_gain(m: &DMatrix<f64>, l: usize) -> f64 {
    let base = m.column(0).norm();
    if base == 0.0 {
        return 0.0;
    }
    let mut band = m.columns(l * l, 2 * l + 1).into_owned();
    if l > 0 {
        let lower = m.columns(0, l * l).into_owned();
        let svd = lower.svd(true, false);
        let cutoff = svd.singular_values.max() * 1e-12;
        let u = svd.u.expect("asked for U");
        for (k, s) in svd.singular_values.iter().enumerate() {
            if *s > cutoff {
                let uk = u.column(k);
                let proj = uk.transpose() * &band;
                band -= uk * proj;
            }
        }
    }
    band.singular_values().min() / base
}

/// The well-determined bands: up to the first band whose gain is below `min_gain` or whose
/// condition number exceeds `limit`.
#[must_use]
pub fn well_determined(cond: &[f64], gain: &[f64], limit: f64, min_gain: f64) -> usize {
    cond.iter()
        .zip(gain)
        .take_while(|(&k, &g)| k <= limit && g >= min_gain)
        .count()
}

/// The fit's pixels, their square-root weights and the weighted image per channel.
pub type Prepared = (Vec<usize>, Vec<f64>, [DVector<f64>; 3]);

/// The fit's pixels (with `max_occlusion`, only the unoccluded ones: [`unoccluded_pixels`]),
/// their square-root weights and the weighted image: checked against the bound scene's camera.
///
/// # Errors
/// An image of another size, weights of the wrong length, no object pixel.
pub fn prepare_pixels(
    bound: &Bound,
    image: &RgbImage,
    weights: Option<&[f64]>,
    max_occlusion: Option<f64>,
) -> Result<Prepared, SceneRelightError> {
    let cam = &bound.scene().camera;
    if (image.width, image.height) != (cam.width as usize, cam.height as usize) {
        return Err(SceneRelightError::Invalid(format!(
            "the image is {}×{}, the scene's camera {}×{}",
            image.width, image.height, cam.width, cam.height
        )));
    }
    let mut pixels = fit_pixels(bound)?;
    if let Some(f) = max_occlusion {
        pixels = unoccluded_pixels(bound, &pixels, f)?;
    }
    if pixels.is_empty() {
        return Err(SceneRelightError::Invalid(
            "no object pixel away from silhouettes to fit".into(),
        ));
    }
    let sqrt_w: Vec<f64> = match weights {
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
    let b = [0, 1, 2].map(|c| {
        DVector::from_iterator(
            pixels.len(),
            pixels
                .iter()
                .zip(&sqrt_w)
                .map(|(&p, w)| w * f64::from(image.pixels[p][c])),
        )
    });
    Ok((pixels, sqrt_w, b))
}

/// The model order of `opt` for `bound`'s bake, checked.
///
/// # Errors
/// An order of 0, or a model order below it.
pub fn model_order(bound: &Bound, opt: &FitOptions) -> Result<usize, SceneRelightError> {
    if opt.order == 0 {
        return Err(SceneRelightError::Invalid("fit at least one band".into()));
    }
    let baked = bound
        .bake()
        .objects
        .iter()
        .map(|o| o.order as usize)
        .max()
        .unwrap_or(1);
    let m = opt.model_order.unwrap_or(baked).max(opt.order);
    if opt.model_order.is_some_and(|m| m < opt.order) {
        return Err(SceneRelightError::Invalid(format!(
            "a model order of {} below the fitted order {}",
            opt.model_order.unwrap_or(0),
            opt.order
        )));
    }
    Ok(m)
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
    let model = model_order(bound, opt)?;
    let (pixels, sqrt_w, b) =
        prepare_pixels(bound, image, opt.weights.as_deref(), opt.max_occlusion)?;
    let a = basis_images(bound, &pixels, &sqrt_w, model, opt.phong)?;
    if opt.max_sources == 0 {
        return fit_from_design(&a, &b, pixels.len(), opt, model);
    }
    let conditioned = conditioning(&a, model);
    let well = well_bands(&conditioned, opt);
    let imgs = crate::sources::SourceImages::new(bound, &pixels, &sqrt_w)?;
    let found = crate::sources::find_sources(
        &imgs,
        &a,
        &b,
        well,
        opt.condition_limit,
        opt.max_sources,
        if opt.weights.is_some() {
            crate::sources::NOISE_FLOOR
        } else {
            0.0
        },
    )?;
    let b2: f64 = b.iter().map(DVector::norm_squared).sum();
    let mut fit = fit_with_sources(&a, &b, pixels.len(), opt, conditioned, &found)?;
    fit.residual_by_sources = found
        .residual2
        .iter()
        .map(|r| if b2 > 0.0 { (r / b2).sqrt() } else { 0.0 })
        .collect();
    Ok(fit)
}

/// Per band of the model, the condition number and the gain ([`conditioning`]).
type Conditioning = (Vec<f64>, Vec<f64>);

/// The well-determined bands under `opt` (at most `opt.order`) of a design conditioned as
/// `cond`.
fn well_bands(cond: &Conditioning, opt: &FitOptions) -> usize {
    well_determined(&cond.0, &cond.1, opt.condition_limit, opt.min_gain).min(opt.order)
}

/// [`fit_lighting`] from the weighted basis images `a` and weighted image `b`.
///
/// # Errors
/// A failed solve.
pub fn fit_from_design(
    a: &[DMatrix<f64>; 3],
    b: &[DVector<f64>; 3],
    pixels: usize,
    opt: &FitOptions,
    model: usize,
) -> Result<LightingFit, SceneRelightError> {
    let none = crate::sources::FoundSources::default();
    fit_with_sources(a, b, pixels, opt, conditioning(a, model), &none)
}

/// [`fit_from_design`] with the columns of `found`'s sources beside the SH ones: the SH part
/// regularised as before, the sources' intensities free, the returned coefficients the SH
/// part plus the sources' projections. `conditioned` is [`conditioning`] of `a`.
fn fit_with_sources(
    a: &[DMatrix<f64>; 3],
    b: &[DVector<f64>; 3],
    pixels: usize,
    opt: &FitOptions,
    conditioned: Conditioning,
    found: &crate::sources::FoundSources,
) -> Result<LightingFit, SceneRelightError> {
    let well = well_bands(&conditioned, opt);
    let (condition_by_band, gain_by_band) = conditioned;
    let model = (a[0].ncols() as f64).sqrt().round() as usize;
    let design = crate::sources::with_sources(a, &found.columns);
    let sh_cols = model * model;
    let mut full = vec![[0.0; 3]; sh_cols];
    let mut sources = found.sources.clone();
    let (mut residual_rms, mut r2, mut b2, mut dropped) = ([0.0; 3], 0.0, 0.0, 0);
    let mut downweighted = 0;
    for c in 0..3 {
        let (s, low) = solve_channel_robust_with(
            &design[c],
            &b[c],
            sh_cols,
            well,
            opt.condition_limit,
            opt.robust,
        )?;
        downweighted += low;
        for (i, v) in s.x.iter().take(sh_cols).enumerate() {
            full[i][c] = *v;
        }
        for (k, src) in sources.iter_mut().enumerate() {
            let power = s.x[sh_cols + k];
            src.intensity[c] = power;
            for (f, y) in full.iter_mut().zip(&found.sh[k]) {
                f[c] += power * y;
            }
        }
        residual_rms[c] = (s.residual2 / pixels as f64).sqrt();
        r2 += s.residual2;
        b2 += b[c].norm_squared();
        dropped = dropped.max(s.dropped);
    }
    let truth = opt
        .truth
        .as_ref()
        .map(|t| truth_check(a, b, t, &full[..opt.order * opt.order], well));
    Ok(LightingFit {
        order: opt.order,
        model_order: model,
        phong_model: opt.phong,
        well_determined: well,
        coefficients: full[..opt.order * opt.order].to_vec(),
        regularised_bands: (well..opt.order).collect(),
        dropped_directions: dropped,
        condition_by_band,
        gain_by_band,
        condition_limit: opt.condition_limit,
        min_gain: opt.min_gain,
        pixels,
        residual_rms,
        relative_residual: if b2 > 0.0 { (r2 / b2).sqrt() } else { 0.0 },
        downweighted,
        truth,
        sources,
        residual_by_sources: Vec::new(),
    })
}

/// Relative L2 error of `got` against `want` over rows `from..to` (all channels).
#[must_use]
pub fn rel_l2(got: &[[f64; 3]], want: &[[f64; 3]], from: usize, to: usize) -> f64 {
    let (mut e, mut n) = (0.0, 0.0);
    for i in from..to.min(got.len()).min(want.len()) {
        for c in 0..3 {
            e += (got[i][c] - want[i][c]).powi(2);
            n += want[i][c] * want[i][c];
        }
    }
    if n > 0.0 {
        (e / n).sqrt()
    } else {
        e.sqrt()
    }
}

/// The fit against known coefficients `truth`.
fn truth_check(
    a: &[DMatrix<f64>; 3],
    b: &[DVector<f64>; 3],
    truth: &[[f64; 3]],
    got: &[[f64; 3]],
    well: usize,
) -> TruthCheck {
    let order = (got.len() as f64).sqrt().round() as usize;
    let cols = a[0].ncols().min(truth.len());
    let (mut r2, mut b2) = (0.0, 0.0);
    for c in 0..3 {
        let x = DVector::from_iterator(cols, truth[..cols].iter().map(|t| t[c]));
        r2 += (a[c].columns(0, cols) * x - &b[c]).norm_squared();
        b2 += b[c].norm_squared();
    }
    TruthCheck {
        rel_l2_well_determined: rel_l2(got, truth, 0, well * well),
        rel_l2_by_band: (0..order)
            .map(|l| rel_l2(got, truth, l * l, (l + 1) * (l + 1)))
            .collect(),
        model_residual: if b2 > 0.0 { (r2 / b2).sqrt() } else { 0.0 },
    }
}
