//! Relighting from a sampled reflectance field (Masselus, Peers, Dutré & Willems 2004; the
//! file's `RFLD` section, `prt reflectance`): each pixel's reflectance function, sampled at the
//! centres of a coarse `W × H` lat-long grid of directions, is reconstructed on a fine lat-long
//! grid and integrated against the environment:
//! `pixel = Σ_k R̂(ω_k) L̄_k Δω_k + (background share)`, where `L̄_k` is the environment's mean
//! radiance over fine cell `k` and `Δω_k` its exact solid angle.
//!
//! Every reconstruction here is linear in the samples, `R̂ = M R`, so the sum is evaluated as
//! `Σ_j R_j (Mᵀ(L̄ Δω))_j`: the lighting is pulled back to the coarse grid once per frame and
//! each pixel costs `3 · W · H` multiply-adds whatever the fine grid — the same result as
//! reconstructing every function on the fine grid (tested), without holding any fine-grid
//! function in memory.
//!
//! **Compression** (§5 of the paper): each reconstructed function is transformed into a
//! wavelet basis on the fine grid (Haar, LeGall 5/3 or CDF 9/7; periodic in azimuth, mirrored at
//! the poles, `prt-wavelet`) and only its most important coefficients are kept — a fixed number
//! `K` per function, or the fewest whose exact relative L2 error is at most `E` — ranked by
//! `c_i² ‖Φ_i‖²` (their contribution to the L2 norm through the synthesis functions `Φ_i`).
//! Relighting is then a sparse dot product: with `R̂ = S c` (`S` the synthesis), `⟨R̂, ℓ⟩ =
//! ⟨c, Sᵀℓ⟩`, so the frame's lighting `ℓ = L̄ Δω` is projected once (`Sᵀℓ`, the primal
//! coefficients) and each pixel costs one multiply-add per kept coefficient. Functions are
//! reconstructed, transformed and truncated one pixel at a time (in parallel): no fine-grid
//! function is held beyond its pixel.
//!
//! Reconstructions: **nearest** (zero-order hold: a fine cell takes the sample of the coarse
//! cell that contains its centre — on a regular lat-long grid the coarse cells are the Voronoi
//! cells of the samples up to the poles' crowding) and **linear** (bilinear in `(φ, θ)`
//! between the four surrounding samples, periodic in azimuth, held constant beyond the first
//! and last rows' centres at the poles).

use crate::error::FieldError;
use glam::Vec3;
use prt_bakefile::{Bake, ReflectanceField};
use prt_scene::Scene;
use prt_scene_relight::imaging::{background_radiance, RgbImage};
use prt_tracer::Accel;
use rayon::prelude::*;
use serde::Serialize;
use std::f64::consts::PI;

/// How a sampled reflectance function becomes a function on the fine grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Reconstruction {
    /// Zero-order hold.
    Nearest,
    /// Bilinear in `(φ, θ)`, periodic in azimuth.
    Linear,
    /// Wavelet interpolation with LeGall 5/3 (the samples as the approximation band of the
    /// fine grid, details zero; periodic in azimuth, mirrored at the poles). Needs fine sizes
    /// that are power-of-two multiples of the sampled ones.
    #[serde(rename = "legall53")]
    LeGall53,
    /// Wavelet interpolation with CDF 9/7 (smoother, cubic-spline-like; may ring at sharp
    /// features).
    #[serde(rename = "cdf97")]
    Cdf97,
    /// Inverse-distance weighting of the 32 angularly nearest samples (Shepard's method,
    /// [`crate::reconstruct::Idw`]).
    Idw,
    /// A biquadric polynomial per hemisphere, least squares ([`crate::reconstruct::Biquadric`]).
    Biquadric,
    /// Spherical harmonics with 25 coefficients, least squares
    /// ([`crate::reconstruct::ShFit`]).
    #[serde(rename = "sh25")]
    Sh25,
    /// Multilevel B-splines (Lee, Wolberg & Shin 1997; [`crate::reconstruct::MultilevelBSpline`]).
    #[serde(rename = "bspline")]
    BSpline,
    /// Spherical harmonics of this order (order² coefficients), least squares from the
    /// samples ([`crate::reconstruct::ShFit`]): the report's noise-free SH of a given
    /// coefficient count, fitted to the same samples as the other reconstructions.
    #[serde(rename = "sh_fit")]
    ShFit(usize),
}

/// A reconstruction set up for one pair of grids: the built-in ones are evaluated directly,
/// the others ([`crate::reconstruct`]) precompute their linear map once.
pub struct Prepared {
    method: Reconstruction,
    coarse: [u32; 2],
    fine: [u32; 2],
    op: Option<Box<dyn crate::reconstruct::LinearReconstruction>>,
}

impl Prepared {
    /// Sets `method` up for `coarse → fine`.
    ///
    /// # Errors
    /// Grids the method cannot work with.
    pub fn new(
        method: Reconstruction,
        coarse: [u32; 2],
        fine: [u32; 2],
    ) -> Result<Self, FieldError> {
        use crate::reconstruct as rf;
        let op: Option<Box<dyn rf::LinearReconstruction>> = match method {
            Reconstruction::Nearest
            | Reconstruction::Linear
            | Reconstruction::LeGall53
            | Reconstruction::Cdf97 => None,
            Reconstruction::Idw => Some(Box::new(rf::Idw::paper(coarse, fine)?)),
            Reconstruction::Biquadric => Some(Box::new(rf::Biquadric::new(coarse, fine)?)),
            Reconstruction::Sh25 => Some(Box::new(rf::ShFit::new(
                coarse,
                fine,
                rf::ShFit::DEFAULT_ORDER,
            )?)),
            Reconstruction::ShFit(order) => Some(Box::new(rf::ShFit::new(coarse, fine, order)?)),
            Reconstruction::BSpline => Some(Box::new(rf::MultilevelBSpline::new(
                coarse,
                fine,
                rf::MultilevelBSpline::default_levels(coarse),
            )?)),
        };
        Ok(Self {
            method,
            coarse,
            fine,
            op,
        })
    }

    /// One channel's samples on the fine grid.
    ///
    /// # Errors
    /// As [`reconstruct`].
    pub fn apply(&self, samples: &[f32], out: &mut [f64]) -> Result<(), FieldError> {
        match &self.op {
            Some(op) => {
                op.apply(samples, out);
                Ok(())
            }
            None => reconstruct(self.method, self.coarse, samples, self.fine, out),
        }
    }

    /// `Mᵀ ℓ` per channel.
    ///
    /// # Errors
    /// As [`pulled_back_lighting`].
    pub fn pull_back(&self, lighting: &[[f64; 3]]) -> Result<Vec<[f64; 3]>, FieldError> {
        let Some(op) = &self.op else {
            return pulled_back_lighting(self.method, self.coarse, self.fine, lighting);
        };
        let d = self.coarse[0] as usize * self.coarse[1] as usize;
        let mut out = vec![[0.0f64; 3]; d];
        let mut coarse = vec![0.0f64; d];
        for c in 0..3 {
            let l: Vec<f64> = lighting.iter().map(|v| v[c]).collect();
            op.apply_transpose(&l, &mut coarse);
            for (o, v) in out.iter_mut().zip(&coarse) {
                o[c] = *v;
            }
        }
        Ok(out)
    }
}

impl Reconstruction {
    /// The wavelet of a wavelet interpolation.
    fn wavelet(self) -> Option<prt_wavelet::Wavelet> {
        match self {
            Reconstruction::LeGall53 => Some(prt_wavelet::Wavelet::LeGall53),
            Reconstruction::Cdf97 => Some(prt_wavelet::Wavelet::Cdf97),
            _ => None,
        }
    }
}

/// How many wavelet coefficients a function keeps.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Budget {
    /// A fixed number per function (per pixel and channel).
    Coefficients(usize),
    /// The fewest whose exact relative L2 error (over the fine grid) is at most this.
    RelativeError(f64),
}

/// Non-linear wavelet approximation of the reconstructed functions.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Compression {
    /// The wavelet.
    pub wavelet: prt_wavelet::Wavelet,
    /// Coefficients kept.
    pub budget: Budget,
    /// Measure `rf_rel_l2` and `rf_rel_h1` over an even subsample of at most this many held
    /// pixels (every `⌈pixels / N⌉`-th) instead of all: each measured function costs one
    /// inverse transform, most of the compression's time at full coverage. What is kept is
    /// the same either way.
    pub error_pixels: Option<usize>,
}

/// Options of [`relight_field`].
#[derive(Clone, Debug)]
pub struct FieldOptions {
    /// Reconstruction method.
    pub reconstruction: Reconstruction,
    /// Fine grid `[W, H]` the functions are reconstructed on.
    pub fine: [u32; 2],
    /// Environment rotation about +Y, degrees.
    pub rotate_y_deg: f64,
    /// Timed frames (the median is reported).
    pub timing_frames: usize,
    /// Wavelet compression, or `None` to relight the reconstructed functions as they are.
    pub compression: Option<Compression>,
}

/// What a field relighting measured.
#[derive(Clone, Debug, Serialize)]
pub struct FieldStats {
    /// Shading time of one frame (pulling the lighting back and every pixel's dot products),
    /// ms, median of the timed frames.
    pub shade_ms: f64,
    /// The lighting's projection onto the fine grid (once per frame), ms.
    pub lighting_ms: f64,
    /// Pixels with a function.
    pub pixels: usize,
    /// Coarse directions.
    pub directions: [u32; 2],
    /// Fine grid.
    pub fine: [u32; 2],
    /// Reconstruction.
    pub reconstruction: Reconstruction,
    /// The wavelet (`haar`, `legall53`, `cdf97`) when compressed.
    pub wavelet: Option<String>,
    /// Mean wavelet coefficients kept per pixel and channel, when compressed.
    pub mean_coefficients: Option<f64>,
    /// Relative L2 error of the compressed functions against their uncompressed
    /// reconstruction, over all pixels and channels (`sqrt(Σ‖f − f_K‖² / Σ‖f‖²)` on the fine
    /// grid), when compressed.
    pub rf_rel_l2: Option<f64>,
    /// The same in the discrete Sobolev H¹ norm (the function and its angular gradient;
    /// Masselus et al. 2004, Fig. 9), when compressed.
    pub rf_rel_h1: Option<f64>,
    /// Held pixels whose functions `rf_rel_l2` and `rf_rel_h1` were measured over (all of
    /// them unless [`Compression::error_pixels`] asks for an even subsample, as the report's
    /// series do), when compressed.
    pub rf_error_pixels: Option<usize>,
    /// Time to reconstruct, transform and truncate every function (once, not per frame), ms.
    pub compress_ms: Option<f64>,
}

/// Every held pixel's compressed functions: per pixel and channel, `(index, coefficient)`.
struct Sparse {
    transform: prt_wavelet::Transform2d,
    /// `[pixel][channel]` runs into `entries`.
    runs: Vec<[(u32, u32); 3]>,
    entries: Vec<(u32, f32)>,
    kept: u64,
    /// Squared L2 norms of the errors and of the functions, over the measured pixels.
    error2: f64,
    norm2: f64,
    /// Squared Sobolev H¹ norms of the errors and of the functions (`prt_wavelet`'s discrete
    /// norm), over the measured pixels.
    h1_error2: f64,
    h1_norm2: f64,
    /// Held pixels whose functions' errors were measured.
    error_pixels: usize,
    ms: f64,
}

impl Sparse {
    fn rel_l2(&self) -> f64 {
        if self.norm2 > 0.0 {
            (self.error2 / self.norm2).sqrt()
        } else {
            0.0
        }
    }

    fn rel_h1(&self) -> f64 {
        if self.h1_norm2 > 0.0 {
            (self.h1_error2 / self.h1_norm2).sqrt()
        } else {
            0.0
        }
    }
}

/// The indices of the `k` most important coefficients, most important first: ranked by
/// `c_i² ‖Φ_i‖²`, ties by index (so the `K` kept for a smaller `K` are always the first `K` of
/// a larger one's, and the choice does not depend on the sort's internals).
fn rank_top(coef: &[f64], norms: &[f64], k: usize) -> Vec<u32> {
    let weight = |i: u32| coef[i as usize].powi(2) * norms[i as usize];
    let order = |a: &u32, b: &u32| weight(*b).total_cmp(&weight(*a)).then(a.cmp(b));
    let mut idx: Vec<u32> = (0..coef.len() as u32).collect();
    if k < idx.len() {
        idx.select_nth_unstable_by(k - 1, order);
        idx.truncate(k);
    }
    idx.sort_unstable_by(order);
    idx
}

/// Reconstructs, transforms and truncates every function of `field`.
fn compress(
    field: &ReflectanceField,
    prepared: &Prepared,
    fine: [u32; 2],
    c: Compression,
) -> Result<Sparse, FieldError> {
    let stride = c
        .error_pixels
        .map_or(1, |n| field.pixels.len().div_ceil(n.max(1)).max(1));
    let mut v = compress_series(field, prepared, fine, c.wavelet, &[c.budget], stride, false)?;
    Ok(v.remove(0))
}

/// [`compress`] for several budgets of one wavelet in one pass: each function is reconstructed
/// and transformed once, its coefficients ranked once, and every fixed budget `K` keeps the
/// first `K` of that ranking. The errors are exact (one sparse inverse transform per function
/// and budget) over every `error_stride`-th held pixel (1: all of them); the time is the
/// whole pass's.
fn compress_series(
    field: &ReflectanceField,
    prepared: &Prepared,
    fine: [u32; 2],
    wavelet: prt_wavelet::Wavelet,
    budgets: &[Budget],
    error_stride: usize,
    only_measured: bool,
) -> Result<Vec<Sparse>, FieldError> {
    let start = std::time::Instant::now();
    let wav = |e: prt_wavelet::WaveletError| FieldError::Invalid(format!("wavelet: {e}"));
    let transform =
        prt_wavelet::Transform2d::lat_long(wavelet, fine[0] as usize, fine[1] as usize, None)
            .map_err(wav)?;
    let n = transform.len();
    for b in budgets {
        match *b {
            Budget::Coefficients(k) if k == 0 || k > n => {
                return Err(FieldError::Invalid(format!(
                    "--coefficients {k}: give between 1 and the fine grid's {n}"
                )))
            }
            Budget::RelativeError(e) if !(e > 0.0 && e < 1.0) => {
                return Err(FieldError::Invalid(format!(
                    "--rf-error {e}: give a relative error in (0, 1)"
                )))
            }
            _ => {}
        }
    }
    let error_stride = error_stride.max(1);
    let max_k = budgets
        .iter()
        .filter_map(|b| match b {
            Budget::Coefficients(k) => Some(*k),
            Budget::RelativeError(_) => None,
        })
        .max();
    let norms = transform.basis_norms_squared();
    let d = field.direction_count();
    // Per pixel and budget: three channels' kept coefficients, the squared errors and norms.
    type PixelOut = Vec<(Vec<Vec<(u32, f32)>>, [f64; 4])>;
    let len = field.pixels.len();
    let mut out: Vec<Sparse> = budgets
        .iter()
        .map(|b| Sparse {
            transform: transform.clone(),
            runs: Vec::with_capacity(len),
            // Fixed budgets: at most K per function, reserved once (no growth by doubling).
            entries: Vec::with_capacity(match *b {
                Budget::Coefficients(k) if !only_measured => 3 * len * k,
                _ => 0,
            }),
            kept: 0,
            error2: 0.0,
            norm2: 0.0,
            h1_error2: 0.0,
            h1_norm2: 0.0,
            error_pixels: len.div_ceil(error_stride),
            ms: 0.0,
        })
        .collect();
    // Pixels in chunks, each appended before the next is compressed: the kept coefficients
    // are held once (and one chunk's twice), not per pixel and again in the one array.
    const CHUNK: usize = 4096;
    for first in (0..len).step_by(CHUNK) {
        let per_pixel: Vec<PixelOut> = (first..(first + CHUNK).min(len))
            .into_par_iter()
            .map_init(Vec::new, |scratch, i| -> Result<PixelOut, FieldError> {
                let measure = i % error_stride == 0;
                if only_measured && !measure {
                    return Ok(vec![(vec![Vec::new(); 3], [0.0; 4]); budgets.len()]);
                }
                let f = field.function(i, scratch);
                let mut fine_f = vec![0.0f64; n];
                let mut out: PixelOut = vec![(Vec::with_capacity(3), [0.0; 4]); budgets.len()];
                let (fw, fh) = (fine[0] as usize, fine[1] as usize);
                for ch in 0..3 {
                    prepared.apply(&f[ch * d..(ch + 1) * d], &mut fine_f)?;
                    let norm2: f64 = fine_f.iter().map(|v| v * v).sum();
                    if norm2 == 0.0 {
                        out.iter_mut().for_each(|o| o.0.push(Vec::new()));
                        continue;
                    }
                    let h1n = if measure {
                        prt_wavelet::sobolev_h1_norm2(&fine_f, fw, fh)
                    } else {
                        0.0
                    };
                    let coef = match max_k {
                        Some(_) => transform.forward(&fine_f).map_err(wav)?,
                        None => Vec::new(),
                    };
                    let ranked = max_k.map(|k| rank_top(&coef, norms, k));
                    for (b, o) in budgets.iter().zip(out.iter_mut()) {
                        let kept: Vec<(usize, f64)> = match *b {
                            Budget::Coefficients(k) => ranked.as_ref().expect("ranked")[..k]
                                .iter()
                                .map(|&i| (i as usize, coef[i as usize]))
                                .collect(),
                            Budget::RelativeError(e) => transform
                                .rank(&fine_f)
                                .map_err(wav)?
                                .keep_for_exact_error(e)
                                .map_err(wav)?,
                        };
                        if measure {
                            // The exact error of what is kept: one sparse inverse transform.
                            let approx = transform.reconstruct_sparse(&kept).map_err(wav)?;
                            let err: Vec<f64> =
                                approx.iter().zip(&fine_f).map(|(a, b)| a - b).collect();
                            o.1[0] += err.iter().map(|e| e * e).sum::<f64>();
                            o.1[1] += norm2;
                            o.1[2] += prt_wavelet::sobolev_h1_norm2(&err, fw, fh);
                            o.1[3] += h1n;
                        }
                        let mut kept: Vec<(u32, f32)> =
                            kept.iter().map(|&(i, v)| (i as u32, v as f32)).collect();
                        kept.sort_unstable_by_key(|e| e.0);
                        o.0.push(kept);
                    }
                }
                Ok(out)
            })
            .collect::<Result<_, _>>()?;
        for pixel in per_pixel {
            for (sp, (chans, [e2, n2, h1e, h1n])) in out.iter_mut().zip(pixel) {
                sp.error2 += e2;
                sp.norm2 += n2;
                sp.h1_error2 += h1e;
                sp.h1_norm2 += h1n;
                let mut r = [(0u32, 0u32); 3];
                for (ch, kept) in chans.into_iter().enumerate() {
                    r[ch] = (sp.entries.len() as u32, kept.len() as u32);
                    sp.entries.extend(kept);
                }
                sp.runs.push(r);
            }
        }
    }
    let ms = start.elapsed().as_secs_f64() * 1e3;
    for sp in &mut out {
        sp.kept = sp.entries.len() as u64;
        sp.ms = ms;
    }
    Ok(out)
}

/// Per fine cell, `L̄_k Δω_k` (RGB): the environment (rotated by `rotate_y_deg`) averaged over
/// the cell with `S × S` samples stratified in `(φ, cos θ)` (equal solid angle each), times
/// the cell's exact solid angle `(2π/W)(cos θ₀ − cos θ₁)`.
#[must_use]
pub fn fine_lighting(scene: &Scene, fine: [u32; 2], rotate_y_deg: f64) -> Vec<[f64; 3]> {
    const S: usize = 8;
    let [w, h] = fine;
    (0..(w * h) as usize)
        .into_par_iter()
        .map(|k| {
            let (col, row) = (k % w as usize, k / w as usize);
            let (c0, c1) = (
                (PI * row as f64 / f64::from(h)).cos(),
                (PI * (row + 1) as f64 / f64::from(h)).cos(),
            );
            let solid = 2.0 * PI / f64::from(w) * (c0 - c1);
            let mut sum = [0.0f64; 3];
            for a in 0..S {
                for b in 0..S {
                    let phi = 2.0 * PI * (col as f64 + (a as f64 + 0.5) / S as f64) / f64::from(w);
                    let cos_t = c0 + (c1 - c0) * (b as f64 + 0.5) / S as f64;
                    let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
                    let d = Vec3::new(
                        (phi.sin() * sin_t) as f32,
                        cos_t as f32,
                        (-phi.cos() * sin_t) as f32,
                    );
                    let l = background_radiance(scene, d, rotate_y_deg);
                    for c in 0..3 {
                        sum[c] += f64::from(l[c]);
                    }
                }
            }
            let n = (S * S) as f64;
            sum.map(|s| s / n * solid)
        })
        .collect()
}

/// The coarse samples (index, weight) fine cell `k` reconstructs from.
fn weights(
    method: Reconstruction,
    coarse: [u32; 2],
    fine: [u32; 2],
    k: usize,
) -> ([(usize, f64); 4], usize) {
    let (cw, ch) = (coarse[0] as usize, coarse[1] as usize);
    let (fw, fh) = (fine[0] as usize, fine[1] as usize);
    let (col, row) = (k % fw, k / fw);
    // Fine cell centre in coarse cell units.
    let x = (col as f64 + 0.5) / fw as f64 * cw as f64;
    let y = (row as f64 + 0.5) / fh as f64 * ch as f64;
    let mut out = [(0usize, 0.0f64); 4];
    match method {
        Reconstruction::Nearest => {
            let i = (x.floor() as usize).min(cw - 1);
            let j = (y.floor() as usize).min(ch - 1);
            out[0] = (j * cw + i, 1.0);
            (out, 1)
        }
        _ => {
            // Sample centres at half-integers.
            let xs = x - 0.5;
            let ys = (y - 0.5).clamp(0.0, (ch - 1) as f64);
            let (x0, y0) = (xs.floor(), ys.floor());
            let (tx, ty) = (xs - x0, ys - y0);
            let i0 = (x0 as i64).rem_euclid(cw as i64) as usize;
            let i1 = (i0 + 1) % cw;
            let j0 = y0 as usize;
            let j1 = (j0 + 1).min(ch - 1);
            out = [
                (j0 * cw + i0, (1.0 - tx) * (1.0 - ty)),
                (j0 * cw + i1, tx * (1.0 - ty)),
                (j1 * cw + i0, (1.0 - tx) * ty),
                (j1 * cw + i1, tx * ty),
            ];
            (out, 4)
        }
    }
}

/// Reconstructs one channel's coarse samples on the fine grid (`out`: `fine W × H` values).
///
/// # Errors
/// Wavelet interpolation between sizes that are not power-of-two multiples.
pub fn reconstruct(
    method: Reconstruction,
    coarse: [u32; 2],
    samples: &[f32],
    fine: [u32; 2],
    out: &mut [f64],
) -> Result<(), FieldError> {
    if matches!(
        method,
        Reconstruction::Idw
            | Reconstruction::Biquadric
            | Reconstruction::Sh25
            | Reconstruction::ShFit(_)
            | Reconstruction::BSpline
    ) {
        return Err(FieldError::Invalid(format!(
            "{method:?} reconstruction precomputes its map: use Prepared"
        )));
    }
    if let Some(w) = method.wavelet() {
        let c: Vec<f64> = samples.iter().map(|v| f64::from(*v)).collect();
        let f = prt_wavelet::interpolate(
            w,
            prt_wavelet::Boundaries::LAT_LONG,
            &c,
            coarse[0] as usize,
            coarse[1] as usize,
            fine[0] as usize,
            fine[1] as usize,
        )
        .map_err(|e| FieldError::Invalid(format!("--reconstruct {method:?}: {e}")))?;
        // The synthesis puts coarse sample k on fine sample F·k (F = 2^levels per axis: the
        // low band sits on even samples at every level), whose cell centre lies (F − 1)/2 fine
        // cells before the coarse cell's centre, where the sample was taken. Read the refined
        // function back at the fine cells' own centres: index j − (F − 1)/2, linearly,
        // periodic in azimuth, held at the poles.
        let (fw, fh) = (fine[0] as usize, fine[1] as usize);
        let sx = (fw / coarse[0] as usize - 1) as f64 / 2.0;
        let sy = (fh / coarse[1] as usize - 1) as f64 / 2.0;
        for (k, o) in out.iter_mut().enumerate() {
            let (col, row) = (k % fw, k / fw);
            let x = col as f64 - sx;
            let y = (row as f64 - sy).clamp(0.0, (fh - 1) as f64);
            let (x0, y0) = (x.floor(), y.floor());
            let (tx, ty) = (x - x0, y - y0);
            let i0 = (x0 as i64).rem_euclid(fw as i64) as usize;
            let i1 = (i0 + 1) % fw;
            let j0 = y0 as usize;
            let j1 = (j0 + 1).min(fh - 1);
            *o = (1.0 - ty) * ((1.0 - tx) * f[j0 * fw + i0] + tx * f[j0 * fw + i1])
                + ty * ((1.0 - tx) * f[j1 * fw + i0] + tx * f[j1 * fw + i1]);
        }
        return Ok(());
    }
    for (k, o) in out.iter_mut().enumerate() {
        let (w, n) = weights(method, coarse, fine, k);
        *o = w[..n]
            .iter()
            .map(|&(j, wt)| wt * f64::from(samples[j]))
            .sum();
    }
    Ok(())
}

/// `Mᵀ (L̄ Δω)`: the fine lighting pulled back to the coarse samples, RGB. For wavelet
/// interpolation, `(Mᵀℓ)_j = ⟨M e_j, ℓ⟩` with `M e_j` the interpolation of a unit sample.
///
/// # Errors
/// As [`reconstruct`].
pub fn pulled_back_lighting(
    method: Reconstruction,
    coarse: [u32; 2],
    fine: [u32; 2],
    lighting: &[[f64; 3]],
) -> Result<Vec<[f64; 3]>, FieldError> {
    if method.wavelet().is_some() {
        let d = coarse[0] as usize * coarse[1] as usize;
        let n = lighting.len();
        return (0..d)
            .into_par_iter()
            .map(|j| {
                let mut unit = vec![0.0f32; d];
                unit[j] = 1.0;
                let mut m = vec![0.0f64; n];
                reconstruct(method, coarse, &unit, fine, &mut m)?;
                let mut s = [0.0f64; 3];
                for (a, l) in m.iter().zip(lighting) {
                    for c in 0..3 {
                        s[c] += a * l[c];
                    }
                }
                Ok(s)
            })
            .collect();
    }
    let mut out = vec![[0.0f64; 3]; coarse[0] as usize * coarse[1] as usize];
    for (k, l) in lighting.iter().enumerate() {
        let (w, n) = weights(method, coarse, fine, k);
        for &(j, wt) in &w[..n] {
            for c in 0..3 {
                out[j][c] += wt * l[c];
            }
        }
    }
    Ok(out)
}

/// Temporal coherence of a sequence of frames under a steadily rotating map (the paper's
/// argument for smooth reconstructions: a shadow or highlight should glide, not jump from one
/// sampled direction to the next): the relative RMS of the second difference in time over the
/// masked pixels, `sqrt(Σ_k ‖I_{k+1} − 2 I_k + I_{k−1}‖² / Σ_k ‖I_k‖²)` (k over the inner
/// frames). Smooth motion at a constant speed gives a value near 0; steps give large ones.
/// `None` with fewer than 3 frames.
#[must_use]
pub fn flicker(frames: &[RgbImage], mask: &[bool]) -> Option<f64> {
    if frames.len() < 3 {
        return None;
    }
    let (mut num, mut den) = (0.0f64, 0.0f64);
    for k in 1..frames.len() - 1 {
        let (a, b, c) = (&frames[k - 1], &frames[k], &frames[k + 1]);
        for (i, m) in mask.iter().enumerate() {
            if !m {
                continue;
            }
            for ch in 0..3 {
                let d = f64::from(c.pixels[i][ch]) - 2.0 * f64::from(b.pixels[i][ch])
                    + f64::from(a.pixels[i][ch]);
                num += d * d;
                den += f64::from(b.pixels[i][ch]).powi(2);
            }
        }
    }
    Some(if den > 0.0 { (num / den).sqrt() } else { 0.0 })
}

/// Checks that the file holds a reflectance field made for `scene` (the meshes' geometry
/// hashes of `settings.reflectance.geometry`).
///
/// # Errors
/// No field, or another scene's.
pub fn check_field<'b>(
    scene: &Scene,
    bake: &'b Bake,
    path: &std::path::Path,
) -> Result<&'b ReflectanceField, FieldError> {
    let bad = |reason: String| FieldError::BakeMismatch {
        path: path.to_path_buf(),
        reason,
    };
    let field = bake
        .reflectance
        .as_ref()
        .ok_or_else(|| bad("the file holds no reflectance field".into()))?;
    let geometry = bake
        .meta
        .settings
        .pointer("/reflectance/geometry")
        .and_then(serde_json::Value::as_array)
        .ok_or_else(|| bad("settings.reflectance.geometry is missing".into()))?;
    if geometry.len() != scene.meshes.len() {
        return Err(bad(format!(
            "the field was sampled for {} meshes, the scene has {}",
            geometry.len(),
            scene.meshes.len()
        )));
    }
    for (g, m) in geometry.iter().zip(&scene.meshes) {
        let want = format!(
            "{:#018x}",
            prt_scene::binding::geometry_hash(&m.positions, &m.indices)
        );
        if g.get("geometry_hash").and_then(serde_json::Value::as_str) != Some(want.as_str()) {
            return Err(bad(format!(
                "mesh {} differs from the one the field was sampled for: re-sample it",
                m.name
            )));
        }
    }
    let cam = &scene.camera;
    if bake.meta.sample_kind
        != (prt_bakefile::SampleKind::Pixel {
            width: cam.width,
            height: cam.height,
        })
    {
        return Err(bad(format!(
            "the field's image is not the scene camera's {}×{}",
            cam.width, cam.height
        )));
    }
    Ok(field)
}

/// Relights the field in `bake` (checked with [`check_field`]) under `scene`'s environment.
///
/// # Errors
/// A fine grid smaller than the coarse one or empty; the tracer's camera errors.
pub fn relight_field(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    field: &ReflectanceField,
    opt: &FieldOptions,
) -> Result<(RgbImage, FieldStats), FieldError> {
    let (mut images, stats) =
        relight_field_frames(scene, accel, bake, field, opt, &[opt.rotate_y_deg])?;
    Ok((images.remove(0), stats))
}

/// [`relight_field`] for several rotations of the map about +Y (degrees; `opt.rotate_y_deg`
/// is ignored): the functions are reconstructed (and compressed) once, each frame relit from
/// them. The timing is of the first frame (`opt.timing_frames` repetitions).
///
/// # Errors
/// As [`relight_field`]; no angles.
pub fn relight_field_frames(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    field: &ReflectanceField,
    opt: &FieldOptions,
    angles: &[f64],
) -> Result<(Vec<RgbImage>, FieldStats), FieldError> {
    if angles.is_empty() {
        return Err(FieldError::Invalid("no frames to relight".into()));
    }
    check_fine(field, opt.fine)?;
    let prepared = Prepared::new(opt.reconstruction, field.directions, opt.fine)?;
    let sparse = opt
        .compression
        .map(|c| compress(field, &prepared, opt.fine, c))
        .transpose()?;
    let (images, shade_ms, lighting_ms) = shade_frames(
        scene,
        accel,
        bake,
        field,
        &prepared,
        sparse.as_ref(),
        opt,
        angles,
    )?;
    let wavelet = opt.compression.map(|c| c.wavelet);
    Ok((
        images,
        field_stats(field, opt, wavelet, sparse.as_ref(), shade_ms, lighting_ms),
    ))
}

/// Checks the fine grid against the field's.
fn check_fine(field: &ReflectanceField, fine: [u32; 2]) -> Result<(), FieldError> {
    let [fw, fh] = fine;
    let [cw, ch] = field.directions;
    if fw < cw || fh < ch || u64::from(fw) * u64::from(fh) > 1 << 24 {
        return Err(FieldError::Invalid(format!(
            "the fine grid {fw}×{fh} must be at least the sampled grid {cw}×{ch} in each direction (and at most 2^24 cells)"
        )));
    }
    Ok(())
}

/// One wavelet at several coefficient counts `ks` (the report's error-against-coefficients
/// series): the functions are reconstructed (`opt.reconstruction`), transformed and ranked
/// once, each `K` keeps the first `K` coefficients of every function's ranking (the same
/// coefficients [`relight_field`] keeps with `--coefficients K`) and relights the frame at
/// `opt.rotate_y_deg`. `rf_rel_l2` and `rf_rel_h1` are exact over every `error_stride`-th
/// held pixel's functions (1: all; `FieldStats::rf_error_pixels` says how many);
/// `compress_ms` is the one pass's. `opt.compression` is ignored.
///
/// # Errors
/// As [`relight_field`]; a `K` of 0 or beyond the fine grid.
pub fn relight_field_series(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    field: &ReflectanceField,
    opt: &FieldOptions,
    wavelet: prt_wavelet::Wavelet,
    ks: &[usize],
    error_stride: usize,
) -> Result<Vec<(RgbImage, FieldStats)>, FieldError> {
    check_fine(field, opt.fine)?;
    let prepared = Prepared::new(opt.reconstruction, field.directions, opt.fine)?;
    let budgets: Vec<Budget> = ks.iter().map(|&k| Budget::Coefficients(k)).collect();
    let series = compress_series(
        field,
        &prepared,
        opt.fine,
        wavelet,
        &budgets,
        error_stride,
        false,
    )?;
    let mut out = Vec::with_capacity(ks.len());
    for sp in series {
        let (mut images, shade_ms, lighting_ms) = shade_frames(
            scene,
            accel,
            bake,
            field,
            &prepared,
            Some(&sp),
            opt,
            &[opt.rotate_y_deg],
        )?;
        let stats = field_stats(field, opt, Some(wavelet), Some(&sp), shade_ms, lighting_ms);
        out.push((images.remove(0), stats));
    }
    Ok(out)
}

/// The compression error against coefficient count (Masselus et al. 2004, Fig. 9) of the
/// functions of every `stride`-th held pixel, reconstructed with `opt.reconstruction` onto
/// `opt.fine`: per `K` of `ks`, `(K, relative L2, relative Sobolev H¹)` of the `K`-term
/// approximations against the uncompressed functions (exact: one inverse transform each).
///
/// # Errors
/// A `K` of 0 or beyond the fine grid; grids the reconstruction cannot work with.
pub fn compression_errors(
    field: &ReflectanceField,
    opt: &FieldOptions,
    wavelet: prt_wavelet::Wavelet,
    ks: &[usize],
    stride: usize,
) -> Result<Vec<(usize, f64, f64)>, FieldError> {
    check_fine(field, opt.fine)?;
    let prepared = Prepared::new(opt.reconstruction, field.directions, opt.fine)?;
    let budgets: Vec<Budget> = ks.iter().map(|&k| Budget::Coefficients(k)).collect();
    let series = compress_series(field, &prepared, opt.fine, wavelet, &budgets, stride, true)?;
    Ok(ks
        .iter()
        .zip(series)
        .map(|(&k, sp)| (k, sp.rel_l2(), sp.rel_h1()))
        .collect())
}

/// The frames at `angles`, with the median shading time of the first (ms) and the lighting's
/// projection time (ms).
#[allow(clippy::too_many_arguments)]
fn shade_frames(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    field: &ReflectanceField,
    prepared: &Prepared,
    sparse: Option<&Sparse>,
    opt: &FieldOptions,
    angles: &[f64],
) -> Result<(Vec<RgbImage>, f64, f64), FieldError> {
    let d = field.direction_count();
    let mut times = Vec::new();
    let mut lighting_ms = 0.0;
    let k = bake
        .meta
        .settings
        .pointer("/reflectance/pixel_samples")
        .and_then(serde_json::Value::as_u64)
        .unwrap_or(1)
        .clamp(1, u64::from(prt_tracer::points::MAX_PIXEL_SAMPLES)) as u32;
    let fp = prt_tracer::points::pixel_footprints(scene, accel, bake.meta.seed, k)?;
    let mut images = Vec::with_capacity(angles.len());
    for (ai, &angle) in angles.iter().enumerate() {
        let mut values = vec![[0.0f32; 3]; field.pixels.len()];
        let repeats = if ai == 0 { opt.timing_frames.max(1) } else { 1 };
        for _ in 0..repeats {
            let t0 = std::time::Instant::now();
            let lighting = fine_lighting(scene, opt.fine, angle);
            lighting_ms = t0.elapsed().as_secs_f64() * 1e3;
            let t = std::time::Instant::now();
            if let Some(sp) = sparse {
                // The lighting's primal coefficients Sᵀℓ per channel, then sparse dot products.
                let lc: Vec<Vec<f32>> = (0..3)
                    .map(|c| {
                        let l: Vec<f64> = lighting.iter().map(|v| v[c]).collect();
                        sp.transform
                            .primal_coefficients(&l)
                            .map(|p| p.iter().map(|v| *v as f32).collect())
                            .map_err(|e| FieldError::Invalid(format!("wavelet: {e}")))
                    })
                    .collect::<Result<_, _>>()?;
                values.par_iter_mut().enumerate().for_each(|(i, v)| {
                    for c in 0..3 {
                        let (start, len) = sp.runs[i][c];
                        let run = &sp.entries[start as usize..(start + len) as usize];
                        let s: f64 = run
                            .iter()
                            .map(|&(k, a)| f64::from(a) * f64::from(lc[c][k as usize]))
                            .sum();
                        v[c] = s as f32;
                    }
                });
                if ai == 0 {
                    times.push(t.elapsed().as_secs_f64() * 1e3);
                }
                continue;
            }
            let pulled = prepared.pull_back(&lighting)?;
            // f32 lighting per channel for the per-pixel dot products (f64 accumulation).
            let lc: Vec<Vec<f32>> = (0..3)
                .map(|c| pulled.iter().map(|l| l[c] as f32).collect())
                .collect();
            let rows = values.par_iter_mut().enumerate();
            rows.for_each_init(Vec::new, |scratch, (i, v)| {
                let f = field.function(i, scratch);
                for c in 0..3 {
                    let r = &f[c * d..(c + 1) * d];
                    let s: f64 = r
                        .iter()
                        .zip(&lc[c])
                        .map(|(a, b)| f64::from(*a) * f64::from(*b))
                        .sum();
                    v[c] = s as f32;
                }
            });
            if ai == 0 {
                times.push(t.elapsed().as_secs_f64() * 1e3);
            }
        }
        // The image: held pixels' values plus every pixel's background share.
        let (w, h) = (scene.camera.width, scene.camera.height);
        let mut pixels = vec![[0.0f32; 3]; (w * h) as usize];
        for (&p, v) in field.pixels.iter().zip(&values) {
            pixels[p as usize] = *v;
        }
        pixels.par_iter_mut().enumerate().for_each(|(px, c)| {
            let samples = fp.pixel(px);
            let weight = 1.0 / samples.len() as f32;
            for s in samples.iter().filter(|s| s.hit.is_none()) {
                let b = background_radiance(scene, s.dir, angle);
                (0..3).for_each(|ch| c[ch] += weight * b[ch]);
            }
        });
        images.push(RgbImage {
            width: w as usize,
            height: h as usize,
            pixels,
        });
    }
    times.sort_by(f64::total_cmp);
    Ok((images, times[times.len() / 2], lighting_ms))
}

/// What a relighting measured.
fn field_stats(
    field: &ReflectanceField,
    opt: &FieldOptions,
    wavelet: Option<prt_wavelet::Wavelet>,
    sparse: Option<&Sparse>,
    shade_ms: f64,
    lighting_ms: f64,
) -> FieldStats {
    FieldStats {
        shade_ms,
        lighting_ms,
        pixels: field.pixels.len(),
        directions: field.directions,
        fine: opt.fine,
        reconstruction: opt.reconstruction,
        wavelet: wavelet.map(|w| wavelet_name(w).to_owned()),
        mean_coefficients: sparse.map(|s| s.kept as f64 / (3.0 * field.pixels.len().max(1) as f64)),
        rf_rel_l2: sparse.map(Sparse::rel_l2),
        rf_rel_h1: sparse.map(Sparse::rel_h1),
        rf_error_pixels: sparse.map(|s| s.error_pixels),
        compress_ms: sparse.map(|s| s.ms),
    }
}

/// The command-line name of a wavelet (`--wavelet`).
#[must_use]
pub fn wavelet_name(w: prt_wavelet::Wavelet) -> &'static str {
    match w {
        prt_wavelet::Wavelet::Haar => "haar",
        prt_wavelet::Wavelet::LeGall53 => "legall53",
        prt_wavelet::Wavelet::Cdf97 => "cdf97",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn pulling_the_lighting_back_equals_reconstructing_on_the_fine_grid() {
        // (16 × 8 samples: enough for order-5 SH, IDW's 32 neighbours and the biquadric.)
        let (coarse, fine) = ([16u32, 8u32], [32u32, 16u32]);
        let samples: Vec<f32> = (0..128).map(|i| ((i * 37) % 11) as f32 * 0.3).collect();
        let lighting: Vec<[f64; 3]> = (0..512)
            .map(|k| [(k % 7) as f64, (k % 5) as f64 * 0.5, 1.0])
            .collect();
        // Every reconstruction of the report, and an SH fit of another order.
        for m in crate::RECONSTRUCTIONS
            .into_iter()
            .chain([Reconstruction::ShFit(3)])
        {
            let p = Prepared::new(m, coarse, fine).unwrap();
            let mut f = vec![0.0; 512];
            p.apply(&samples, &mut f).unwrap();
            let direct: f64 = f.iter().zip(&lighting).map(|(a, l)| a * l[0]).sum();
            let pulled = p.pull_back(&lighting).unwrap();
            let via: f64 = samples
                .iter()
                .zip(&pulled)
                .map(|(s, l)| f64::from(*s) * l[0])
                .sum();
            assert!(
                (direct - via).abs() <= 1e-12 * direct.abs(),
                "{m:?}: {direct} vs {via}"
            );
        }
    }

    #[test]
    fn flicker_is_zero_for_steady_change_and_large_for_a_jump() {
        let img = |v: f32| RgbImage {
            width: 2,
            height: 1,
            pixels: vec![[v; 3], [2.0 * v; 3]],
        };
        let mask = [true, true];
        // Brightening at a constant rate: no second difference.
        let steady: Vec<RgbImage> = (0..6).map(|k| img(1.0 + 0.1 * k as f32)).collect();
        assert!(flicker(&steady, &mask).unwrap() < 1e-7);
        // One step of 0.5 in the middle: (0.5² · 2 frames) over the frames' energy.
        let jump: Vec<RgbImage> = [1.0, 1.0, 1.0, 1.5, 1.5, 1.5].map(img).into();
        let f = flicker(&jump, &mask).unwrap();
        // Σ (Δ²)² over the inner frames k = 1..4: 0, 0.5, −0.5, 0 (times 1 and 2 per pixel,
        // 3 channels); Σ I² over the same frames: (1 + 1 + 1.5 + 1.5)² terms.
        let num: f64 = 2.0 * 0.25 * (1.0 + 4.0) * 3.0;
        let den = (1.0 + 1.0 + 2.25 + 2.25) * (1.0 + 4.0) * 3.0;
        assert!((f - (num / den).sqrt()).abs() < 1e-6, "{f}");
        assert!(flicker(&steady[..2], &mask).is_none());
    }

    #[test]
    fn legall53_interpolation_is_linear_interpolation_away_from_the_poles() {
        // The 5/3 scaling function is the linear B-spline: with the samples read back at the
        // fine cells' centres, wavelet interpolation equals bilinear interpolation between
        // sample centres except within a coarse cell of the poles (the transform mirrors
        // about the first and last samples where the bilinear one holds them).
        let (coarse, fine) = ([16u32, 8u32], [64u32, 32u32]);
        let samples: Vec<f32> = (0..128)
            .map(|i| (i as f32 * 0.37).sin() + 0.1 * (i % 16) as f32)
            .collect();
        let (mut a, mut b) = (vec![0.0; 2048], vec![0.0; 2048]);
        reconstruct(Reconstruction::LeGall53, coarse, &samples, fine, &mut a).unwrap();
        reconstruct(Reconstruction::Linear, coarse, &samples, fine, &mut b).unwrap();
        for row in 4..28 {
            for col in 0..64 {
                let k = row * 64 + col;
                assert!(
                    (a[k] - b[k]).abs() < 1e-12,
                    "row {row} col {col}: {} vs {}",
                    a[k],
                    b[k]
                );
            }
        }
    }

    #[test]
    fn reconstructions_keep_constants_and_linear_interpolates_between_centres() {
        let (coarse, fine) = ([4u32, 2u32], [8u32, 4u32]);
        for m in [
            Reconstruction::Nearest,
            Reconstruction::Linear,
            Reconstruction::LeGall53,
            Reconstruction::Cdf97,
        ] {
            let mut f = vec![0.0; 32];
            reconstruct(m, coarse, &[2.5; 8], fine, &mut f).unwrap();
            assert!(f.iter().all(|v| (*v - 2.5).abs() < 1e-12), "{m:?}");
        }
        // Along azimuth, samples 0,1,2,3 in row 0: the fine cell centred a quarter of a
        // coarse cell past sample 0's centre gets ¾·s0 + ¼·s1; periodic past the last.
        let s = [0.0f32, 4.0, 8.0, 12.0, 0.0, 4.0, 8.0, 12.0];
        let mut f = vec![0.0; 32];
        reconstruct(Reconstruction::Linear, coarse, &s, fine, &mut f).unwrap();
        assert!((f[1] - 1.0).abs() < 1e-12, "{}", f[1]);
        // Fine cell 0 lies a quarter cell before sample 0: ¾·s0 + ¼·s3 (wrapping).
        assert!((f[0] - 3.0).abs() < 1e-12, "{}", f[0]);
    }
}
