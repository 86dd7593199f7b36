//! The three wavelets, their filters and the boundary rules.
//!
//! Filters are written in *centred* form: [`Filter::at`]`(m)` is the weight of sample `x[2k + m]`
//! in coefficient `k` (analysis), or the weight with which coefficient `k` adds to `x[2k + m]`
//! (synthesis). The low passes of the two biorthogonal wavelets are symmetric about `m = 0`
//! (centred on the even samples), their high passes about `m = 1` (the odd samples): the
//! JPEG2000 arrangement, and exactly PyWavelets' periodization phase, in which
//! `c[k] = Σ_j dec_lo[j] x[(2k + F/2 − j) mod N]` (`F` the length of PyWavelets' zero-padded
//! filter arrays), so that `analysis_low.at(m) = dec_lo[F/2 − m]` and
//! `synthesis_low.at(m) = rec_lo[m + F/2 − 1]`.
//!
//! The high passes follow from the low passes by PyWavelets' quadrature-mirror relations
//! (`dec_hi[j] = (−1)^(j+1) rec_lo[j]`, `rec_hi[j] = (−1)^j dec_lo[j]`):
//! `analysis_high.at(m) = (−1)^m synthesis_low.at(1 − m)` and
//! `synthesis_high.at(m) = (−1)^m analysis_low.at(1 − m)`.
//!
//! The taps are the exact filters correctly rounded to f64 (`tools/wavelet_oracle.py` derives
//! them in 60-digit arithmetic and the tests compare). PyWavelets' `bior4.4` taps differ from
//! the exact ones by up to 6e-13 (they carry 12 digits), enough to spoil its own perfect
//! reconstruction at the 1e-12 level; these do not.

use std::f64::consts::FRAC_1_SQRT_2;
use std::fmt;
use std::str::FromStr;

use crate::error::WaveletError;

/// A wavelet with PyWavelets' normalisation (low passes sum to √2, high passes to 0).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Wavelet {
    /// The orthonormal Haar wavelet (PyWavelets `haar`).
    Haar,
    /// The LeGall 5/3 biorthogonal wavelet, two vanishing moments, linear B-spline scaling
    /// function (PyWavelets `bior2.2`; JPEG2000's reversible filter, without its rounding).
    LeGall53,
    /// The Cohen–Daubechies–Feauveau 9/7 biorthogonal wavelet, four vanishing moments
    /// (PyWavelets `bior4.4`; JPEG2000's irreversible filter).
    Cdf97,
}

/// √2 (−1/8, 1/4, 3/4, 1/4, −1/8).
const LEGALL53_ANALYSIS_LOW: [f64; 5] = [
    -0.1767766952966369,
    0.3535533905932738,
    1.0606601717798212,
    0.3535533905932738,
    -0.1767766952966369,
];
/// √2 (1/4, 1/2, 1/4).
const LEGALL53_SYNTHESIS_LOW: [f64; 3] = [0.3535533905932738, FRAC_1_SQRT_2, 0.3535533905932738];
/// √2 cos⁴(ω/2) P₄(y)/(1 − y/y₀), y = sin²(ω/2), P₄ = 1 + 4y + 10y² + 20y³, y₀ its real root.
const CDF97_ANALYSIS_LOW: [f64; 9] = [
    0.03782845550699546,
    -0.02384946501938,
    -0.1106244044184234,
    0.37740285561265374,
    0.8526986790094034,
    0.37740285561265374,
    -0.1106244044184234,
    -0.02384946501938,
    0.03782845550699546,
];
/// √2 cos⁴(ω/2) (1 − y/y₀).
const CDF97_SYNTHESIS_LOW: [f64; 7] = [
    -0.06453888262893843,
    -0.04068941760955844,
    0.4180922732222122,
    0.7884856164056644,
    0.4180922732222122,
    -0.04068941760955844,
    -0.06453888262893843,
];
const HAAR_LOW: [f64; 2] = [FRAC_1_SQRT_2, FRAC_1_SQRT_2];

impl Wavelet {
    /// All wavelets, shortest first.
    pub const ALL: [Wavelet; 3] = [Wavelet::Haar, Wavelet::LeGall53, Wavelet::Cdf97];

    /// The short name used on command lines and in files: `haar`, `legall53`, `cdf97`.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            Wavelet::Haar => "haar",
            Wavelet::LeGall53 => "legall53",
            Wavelet::Cdf97 => "cdf97",
        }
    }

    /// PyWavelets' name of the same wavelet: `haar`, `bior2.2`, `bior4.4`.
    #[must_use]
    pub const fn pywt_name(self) -> &'static str {
        match self {
            Wavelet::Haar => "haar",
            Wavelet::LeGall53 => "bior2.2",
            Wavelet::Cdf97 => "bior4.4",
        }
    }

    /// Whether the primal and dual bases coincide (only Haar).
    #[must_use]
    pub const fn is_orthonormal(self) -> bool {
        matches!(self, Wavelet::Haar)
    }

    /// The analysis (decomposition) low pass: low coefficient `k = Σ_m at(m) x[2k + m]`.
    #[must_use]
    pub fn analysis_low(self) -> Filter {
        match self {
            Wavelet::Haar => Filter::new(0, &HAAR_LOW),
            Wavelet::LeGall53 => Filter::new(-2, &LEGALL53_ANALYSIS_LOW),
            Wavelet::Cdf97 => Filter::new(-4, &CDF97_ANALYSIS_LOW),
        }
    }

    /// The synthesis (reconstruction) low pass: low coefficient `k` adds `at(m) c[k]` to
    /// `x[2k + m]`.
    #[must_use]
    pub fn synthesis_low(self) -> Filter {
        match self {
            Wavelet::Haar => Filter::new(0, &HAAR_LOW),
            Wavelet::LeGall53 => Filter::new(-1, &LEGALL53_SYNTHESIS_LOW),
            Wavelet::Cdf97 => Filter::new(-3, &CDF97_SYNTHESIS_LOW),
        }
    }

    /// The analysis high pass, `at(m) = (−1)^m synthesis_low.at(1 − m)`.
    #[must_use]
    pub fn analysis_high(self) -> Filter {
        self.synthesis_low().modulated_mirror()
    }

    /// The synthesis high pass, `at(m) = (−1)^m analysis_low.at(1 − m)`.
    #[must_use]
    pub fn synthesis_high(self) -> Filter {
        self.analysis_low().modulated_mirror()
    }
}

impl fmt::Display for Wavelet {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Wavelet::Haar => "Haar",
            Wavelet::LeGall53 => "LeGall 5/3",
            Wavelet::Cdf97 => "CDF 9/7",
        })
    }
}

impl FromStr for Wavelet {
    type Err = WaveletError;

    /// Accepts (case-insensitively) `haar`; `legall53`, `legall`, `5/3`, `53`, `bior2.2`;
    /// `cdf97`, `cdf`, `9/7`, `97`, `bior4.4`.
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s.trim().to_ascii_lowercase().as_str() {
            "haar" => Ok(Wavelet::Haar),
            "legall53" | "legall" | "5/3" | "53" | "bior2.2" => Ok(Wavelet::LeGall53),
            "cdf97" | "cdf" | "9/7" | "97" | "bior4.4" => Ok(Wavelet::Cdf97),
            _ => Err(WaveletError::UnknownWavelet(s.to_string())),
        }
    }
}

/// How a signal continues past its ends (per axis). Both are critically sampled: `N` samples
/// give `N` coefficients, `N` even at every level used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Boundary {
    /// Periodic: `x[−1] = x[N−1]`, `x[N] = x[0]` — PyWavelets' `periodization` mode, exactly.
    Periodic,
    /// Whole-sample symmetric: `x[−1] = x[1]`, `x[N] = x[N−2]` (period `2N − 2`), the JPEG2000
    /// extension for odd-length symmetric filters. The coefficients of the extended signal are
    /// themselves symmetric (the low band whole-sample at its start and half-sample at its end,
    /// the high band the reverse), which the synthesis uses, so reconstruction is perfect.
    /// Haar's taps never reach past the ends of an even-length signal, so for Haar this mode is
    /// the same as [`Boundary::Periodic`].
    Symmetric,
}

/// The boundary rule of each axis of a 2D grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Boundaries {
    /// Along x (azimuth, the row direction).
    pub x: Boundary,
    /// Along y (polar angle, the column direction).
    pub y: Boundary,
}

impl Boundaries {
    /// Lat-long grids: periodic in azimuth, mirrored at the poles (Masselus et al. 2004, §4).
    pub const LAT_LONG: Boundaries = Boundaries {
        x: Boundary::Periodic,
        y: Boundary::Symmetric,
    };
    /// Periodic in both axes: PyWavelets' `wavedec2(…, mode='periodization')`.
    pub const PERIODIC: Boundaries = Boundaries {
        x: Boundary::Periodic,
        y: Boundary::Periodic,
    };
}

/// A finite filter in centred form: tap `taps[i]` sits at offset `offset + i`.
#[derive(Clone, Debug, PartialEq)]
pub struct Filter {
    /// Offset of the first tap.
    pub offset: isize,
    /// The taps.
    pub taps: Vec<f64>,
}

impl Filter {
    fn new(offset: isize, taps: &[f64]) -> Filter {
        Filter {
            offset,
            taps: taps.to_vec(),
        }
    }

    /// The tap at offset `m` (0 outside the filter).
    #[must_use]
    pub fn at(&self, m: isize) -> f64 {
        let i = m - self.offset;
        if i >= 0 && (i as usize) < self.taps.len() {
            self.taps[i as usize]
        } else {
            0.0
        }
    }

    /// Offset of the first tap.
    #[must_use]
    pub fn first(&self) -> isize {
        self.offset
    }

    /// Offset of the last tap.
    #[must_use]
    pub fn last(&self) -> isize {
        self.offset + self.taps.len() as isize - 1
    }

    /// Sum of the absolute values of the taps (the filter's gain on bounded signals).
    #[must_use]
    pub fn l1_norm(&self) -> f64 {
        self.taps.iter().map(|t| t.abs()).sum()
    }

    /// `m ↦ (−1)^m self.at(1 − m)`.
    fn modulated_mirror(&self) -> Filter {
        let first = 1 - self.last();
        let taps = (0..self.taps.len())
            .map(|i| {
                let m = first + i as isize;
                let sign = if m.rem_euclid(2) == 0 { 1.0 } else { -1.0 };
                sign * self.at(1 - m)
            })
            .collect();
        Filter {
            offset: first,
            taps,
        }
    }
}
