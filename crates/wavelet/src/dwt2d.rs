//! The 2D transform ([`Transform2d`]).

use std::sync::{Arc, OnceLock};

use crate::dwt1d::{axis_level, max_levels_1d, run_step, Bank, Scratch, Step};
use crate::error::{check_finite, check_len, Result, WaveletError};
use crate::norms::BasisNorms;
use crate::wavelet::{Boundaries, Wavelet};

/// Which band of a level a coefficient belongs to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum BandKind {
    /// Low pass in both axes (the last level only; PyWavelets `cA`).
    Approximation,
    /// High pass in x (azimuth), low pass in y (PyWavelets `'ad'`, the `cV` of `wavedec2`).
    DetailX,
    /// Low pass in x, high pass in y (PyWavelets `'da'`, `cH`).
    DetailY,
    /// High pass in both (PyWavelets `'dd'`, `cD`).
    DetailXY,
}

/// The band of one coefficient: its level (1 = finest, `levels` = coarsest; 0 when the
/// transform has no levels) and kind.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Band {
    /// Level, 1 (finest) to the transform's level count.
    pub level: usize,
    /// Which band of the level.
    pub kind: BandKind,
}

/// A 2D multi-level wavelet transform of a `width × height` grid (row-major, `[y][x]`):
/// `pywt.wavedec2`'s decomposition, in the Mallat layout.
///
/// Each level transforms the rows (x) then the columns (y) of the current approximation band,
/// which starts as the whole grid and is the top-left quarter of the previous one after each
/// level. In place in the `width × height` array, level `l` (1 = finest) with
/// `w = width/2^l`, `h = height/2^l` leaves
///
/// ```text
///            x: 0 … w        w … 2w
/// y: 0 … h   | (next levels) | DetailX  |   DetailX:  high pass in x, low in y (pywt 'ad', cV)
/// y: h … 2h  | DetailY       | DetailXY |   DetailY:  low in x, high in y (pywt 'da', cH)
///                                             DetailXY: high in both (pywt 'dd', cD)
/// ```
///
/// and after the last level `L` the approximation ([`BandKind::Approximation`], pywt `cA`) in
/// rows `[0, height/2^L)`, columns `[0, width/2^L)`. This is
/// `pywt.coeffs_to_array(pywt.wavedec2(a, …))[0]` for the periodic boundaries.
/// [`Transform2d::band`] and [`Transform2d::band_region`] map between indices and bands.
#[derive(Clone, Debug)]
pub struct Transform2d {
    wavelet: Wavelet,
    width: usize,
    height: usize,
    levels: usize,
    boundaries: Boundaries,
    bank: Bank,
    /// Shared by clones, computed on first use.
    norms: Arc<OnceLock<BasisNorms>>,
}

impl Transform2d {
    /// A transform of `width × height` grids to `levels` levels (`None`: the most the sizes
    /// allow, [`Transform2d::max_levels`]).
    ///
    /// # Errors
    /// A zero size, a grid too large to index, or sizes not divisible by `2^levels`.
    pub fn new(
        wavelet: Wavelet,
        width: usize,
        height: usize,
        levels: Option<usize>,
        boundaries: Boundaries,
    ) -> Result<Transform2d> {
        if width == 0 || height == 0 {
            return Err(WaveletError::EmptyGrid { width, height });
        }
        if width
            .checked_mul(height)
            .is_none_or(|n| n > isize::MAX as usize / 16)
        {
            return Err(WaveletError::TooLarge { width, height });
        }
        let max = Self::max_levels(width, height);
        let levels = levels.unwrap_or(max);
        if levels > max {
            return Err(WaveletError::TooManyLevels {
                width,
                height,
                levels,
                max,
            });
        }
        Ok(Transform2d {
            wavelet,
            width,
            height,
            levels,
            boundaries,
            bank: Bank::new(wavelet),
            norms: Arc::new(OnceLock::new()),
        })
    }

    /// A transform of lat-long grids: periodic in azimuth (x), mirrored at the poles (y)
    /// ([`Boundaries::LAT_LONG`]).
    ///
    /// # Errors
    /// As [`Transform2d::new`].
    pub fn lat_long(
        wavelet: Wavelet,
        width: usize,
        height: usize,
        levels: Option<usize>,
    ) -> Result<Transform2d> {
        Self::new(wavelet, width, height, levels, Boundaries::LAT_LONG)
    }

    /// The most levels a `width × height` grid allows: both sizes must stay integers when
    /// halved, `min(trailing zeros of width, of height)` (256×64: 6, leaving a 4×1
    /// approximation).
    #[must_use]
    pub fn max_levels(width: usize, height: usize) -> usize {
        max_levels_1d(width).min(max_levels_1d(height))
    }

    /// The wavelet.
    #[must_use]
    pub fn wavelet(&self) -> Wavelet {
        self.wavelet
    }

    /// Width (x, azimuth) in samples.
    #[must_use]
    pub fn width(&self) -> usize {
        self.width
    }

    /// Height (y, polar angle) in samples.
    #[must_use]
    pub fn height(&self) -> usize {
        self.height
    }

    /// Number of levels.
    #[must_use]
    pub fn levels(&self) -> usize {
        self.levels
    }

    /// The boundary rules.
    #[must_use]
    pub fn boundaries(&self) -> Boundaries {
        self.boundaries
    }

    /// Number of samples = number of coefficients, `width × height`.
    #[must_use]
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Always false (a transform has at least one sample).
    #[must_use]
    pub fn is_empty(&self) -> bool {
        false
    }

    /// The forward transform of `values` (row-major `[y][x]`) in the Mallat layout.
    ///
    /// # Errors
    /// A wrong length or a non-finite value.
    pub fn forward(&self, values: &[f64]) -> Result<Vec<f64>> {
        let mut data = values.to_vec();
        self.forward_in_place(&mut data)?;
        Ok(data)
    }

    /// The inverse transform of Mallat-layout `coefficients`.
    ///
    /// # Errors
    /// A wrong length or a non-finite value.
    pub fn inverse(&self, coefficients: &[f64]) -> Result<Vec<f64>> {
        let mut data = coefficients.to_vec();
        self.inverse_in_place(&mut data)?;
        Ok(data)
    }

    /// [`Transform2d::forward`] in place.
    ///
    /// # Errors
    /// A wrong length or a non-finite value (the data are then left unchanged).
    pub fn forward_in_place(&self, data: &mut [f64]) -> Result<()> {
        self.check(data)?;
        self.run(Step::Analysis, data);
        Ok(())
    }

    /// [`Transform2d::inverse`] in place.
    ///
    /// # Errors
    /// A wrong length or a non-finite value (the data are then left unchanged).
    pub fn inverse_in_place(&self, data: &mut [f64]) -> Result<()> {
        self.check(data)?;
        self.run(Step::Synthesis, data);
        Ok(())
    }

    /// The coefficients of `values` against the *primal* (synthesis) basis:
    /// `c̃_i = ⟨f, Φ_i⟩ = Σ_samples f · Φ_i` with `Φ_i` = [`Transform2d::inverse`] of the unit
    /// coefficient `i`, i.e. `Sᵀ f` for the synthesis matrix `S` (the adjoint of the inverse
    /// transform, computed level by level as the forward transform is, with each synthesis step
    /// transposed — boundary folding included). [`Transform2d::forward`] gives the dual
    /// coefficients `c_i = ⟨f, Φ̃_i⟩`, so `Σ_i c_i c̃_i = ⟨f, S c⟩ = ‖f‖²` (Masselus et al.
    /// 2004, §5.2: the L2 norm "in the primal and dual wavelet space"). For Haar `c̃ = c`.
    ///
    /// # Errors
    /// A wrong length or a non-finite value.
    pub fn primal_coefficients(&self, values: &[f64]) -> Result<Vec<f64>> {
        self.check(values)?;
        let mut data = values.to_vec();
        self.run(Step::SynthesisAdjoint, &mut data);
        Ok(data)
    }

    /// The band of coefficient `index` (Mallat layout, `y · width + x`).
    ///
    /// # Errors
    /// An index outside the grid.
    pub fn band(&self, index: usize) -> Result<Band> {
        let (x, y) = self.position(index)?;
        let lx = axis_level(x, self.width, self.levels);
        let ly = axis_level(y, self.height, self.levels);
        let level = lx.min(ly);
        if level > self.levels {
            return Ok(Band {
                level: self.levels,
                kind: BandKind::Approximation,
            });
        }
        let kind = match (lx == level, ly == level) {
            (true, false) => BandKind::DetailX,
            (false, true) => BandKind::DetailY,
            _ => BandKind::DetailXY,
        };
        Ok(Band { level, kind })
    }

    /// The region of a band in the layout: `(x0, y0, width, height)`.
    ///
    /// # Errors
    /// A level of 0 or above the transform's levels, or [`BandKind::Approximation`] for a
    /// level other than the last.
    pub fn band_region(&self, band: Band) -> Result<(usize, usize, usize, usize)> {
        let l = band.level;
        let valid = match band.kind {
            BandKind::Approximation => l == self.levels,
            _ => (1..=self.levels).contains(&l),
        };
        if !valid {
            return Err(WaveletError::NoSuchBand {
                kind: format!("{:?}", band.kind),
                level: l,
                levels: self.levels,
            });
        }
        let (w, h) = (self.width >> l, self.height >> l);
        Ok(match band.kind {
            BandKind::Approximation => (0, 0, w, h),
            BandKind::DetailX => (w, 0, w, h),
            BandKind::DetailY => (0, h, w, h),
            BandKind::DetailXY => (w, h, w, h),
        })
    }

    /// `‖Φ_i‖²` for every coefficient `i` (Mallat layout): the squared L2 norm, summed over
    /// the grid's samples without weights, of the synthesis function of coefficient `i` (the
    /// [`Transform2d::inverse`] of the unit coefficient). Each `Φ_i` is a tensor product
    /// `φ_x ⊗ φ_y` of 1D synthesis functions of its level (a scaling function along an axis
    /// where the band is low pass, a wavelet where it is high pass), so
    /// `‖Φ_i‖² = ‖φ_x‖² ‖φ_y‖²`; the 1D norms are computed once per axis, level and position by
    /// inverse-transforming unit coefficients (only once per level along a periodic axis, where
    /// shifts leave them unchanged), and cached in the transform (and its clones). 1 for Haar
    /// (orthonormal).
    pub fn basis_norms_squared(&self) -> &[f64] {
        self.norms
            .get_or_init(|| {
                BasisNorms::compute(
                    &self.bank,
                    self.boundaries,
                    self.width,
                    self.height,
                    self.levels,
                )
            })
            .per_coefficient()
    }

    /// The inverse transform of data already checked (right length, finite).
    pub(crate) fn inverse_unchecked(&self, data: &mut [f64]) {
        self.run(Step::Synthesis, data);
    }

    fn position(&self, index: usize) -> Result<(usize, usize)> {
        if index >= self.len() {
            return Err(WaveletError::IndexOutOfRange {
                index,
                len: self.len(),
            });
        }
        Ok((index % self.width, index / self.width))
    }

    fn check(&self, data: &[f64]) -> Result<()> {
        check_len(data.len(), self.len())?;
        check_finite(data)
    }

    /// All levels of `step`, fine to coarse (analysis, adjoint) or coarse to fine (synthesis).
    fn run(&self, step: Step, data: &mut [f64]) {
        let mut scratch = Scratch::default();
        let mut level = |l: usize| {
            let (w, h) = (self.width >> l, self.height >> l);
            if step == Step::Synthesis {
                self.columns(step, data, w, h, &mut scratch);
                self.rows(step, data, w, h, &mut scratch);
            } else {
                self.rows(step, data, w, h, &mut scratch);
                self.columns(step, data, w, h, &mut scratch);
            }
        };
        if step == Step::Synthesis {
            (0..self.levels).rev().for_each(&mut level);
        } else {
            (0..self.levels).for_each(&mut level);
        }
    }

    fn rows(&self, step: Step, data: &mut [f64], w: usize, h: usize, scratch: &mut Scratch) {
        for y in 0..h {
            let row = &mut data[y * self.width..y * self.width + w];
            run_step(&self.bank, self.boundaries.x, step, row, scratch);
        }
    }

    fn columns(&self, step: Step, data: &mut [f64], w: usize, h: usize, scratch: &mut Scratch) {
        let mut line = std::mem::take(&mut scratch.line);
        for x in 0..w {
            line.clear();
            line.extend((0..h).map(|y| data[y * self.width + x]));
            run_step(&self.bank, self.boundaries.y, step, &mut line, scratch);
            for (y, v) in line.iter().enumerate() {
                data[y * self.width + x] = *v;
            }
        }
        scratch.line = line;
    }
}
