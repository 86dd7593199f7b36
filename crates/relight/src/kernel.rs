//! Per-point kernels shared by the full-order and the adaptive paths, so that both sum in the
//! same order and agree bit for bit when the adaptive threshold is 0.
//!
//! Summation order (fixed, documented so results are reproducible):
//! - the **base** (bands `0..BASE_ORDER`) is one accumulator per channel, and every further band
//!   `l` adds its own contribution to a second accumulator `high` in increasing `l`;
//! - the value is `scale · (base + high)`;
//! - inside a specular level, each lane's column sum runs over the columns in increasing
//!   order, whatever the instruction set (see `level3_avx2`).

/// Bands always evaluated for every point: the first three (Lee & Kim 2014, 5.1.1, after
/// Ramamoorthi & Hanrahan 2001: three bands carry almost all of the diffuse response).
pub const BASE_ORDER: usize = 3;

/// Number of vertices per parallel task.
pub(crate) const CHUNK: usize = 256;

/// Number of vertices the adaptive filtering pass takes through both terms together (their
/// transfers stay in cache between the diffuse base, the specular term and the diffuse levels).
pub(crate) const BLOCK: usize = 32;

/// Dot product of two equal-length f32 slices with 8 independent lanes (auto-vectorised; no
/// bounds checks inside the loop), then a fixed reduction tree and the scalar tail.
#[inline]
pub(crate) fn dot(a: &[f32], b: &[f32]) -> f32 {
    let n = a.len().min(b.len());
    let (a, b) = (&a[..n], &b[..n]);
    let ca = a.chunks_exact(8);
    let cb = b.chunks_exact(8);
    let (ra, rb) = (ca.remainder(), cb.remainder());
    let mut acc = [0.0f32; 8];
    for (x, y) in ca.zip(cb) {
        for k in 0..8 {
            acc[k] += x[k] * y[k];
        }
    }
    let mut tail = 0.0f32;
    for (x, y) in ra.iter().zip(rb) {
        tail += x * y;
    }
    ((acc[0] + acc[4]) + (acc[1] + acc[5])) + ((acc[2] + acc[6]) + (acc[3] + acc[7])) + tail
}

/// Lanes of band `l` in the column layout: its `2l + 1` rows rounded up to a multiple of 4
/// (one SSE register; 8 would waste up to 78 % on padding at band 4).
#[inline]
pub(crate) const fn lanes(l: usize) -> usize {
    (2 * l + 1).div_ceil(4) * 4
}

/// Level of the three channels of a band of at most 16 lanes, baseline instruction set.
fn level3_any(l: usize, block: &[f32], v: &[f32], w: &[f32]) -> [f32; 3] {
    level3_lanes(l, block, v, w)
}

/// One channel's level of a band of more than 16 lanes, baseline instruction set.
fn level1_any(l: usize, cols: &[f32], v: &[f32], w: &[f32]) -> f32 {
    level1_lanes(l, cols, v, w)
}

/// [`level3_any`] compiled for AVX2 (8-lane registers). The arithmetic is the same
/// element-wise multiply and add in the same order (Rust never fuses them into FMA on its
/// own), so the results are bit-identical — tested.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)] // Runtime feature dispatch: the only unsafe code of the crate.
unsafe fn level3_avx2(l: usize, block: &[f32], v: &[f32], w: &[f32]) -> [f32; 3] {
    level3_lanes(l, block, v, w)
}

/// [`level1_any`] compiled for AVX2; bit-identical as [`level3_avx2`].
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)] // Runtime feature dispatch: the only unsafe code of the crate.
unsafe fn level1_avx2(l: usize, cols: &[f32], v: &[f32], w: &[f32]) -> f32 {
    level1_lanes(l, cols, v, w)
}

/// Dispatch on the lane count (≤ 16), so each instance keeps its accumulators in registers.
#[inline(always)]
fn level3_lanes(l: usize, block: &[f32], v: &[f32], w: &[f32]) -> [f32; 3] {
    match lanes(l) {
        4 => level_in::<4>(l, block, v, w),
        8 => level_in::<8>(l, block, v, w),
        12 => level_in::<12>(l, block, v, w),
        _ => level_in::<16>(l, block, v, w),
    }
}

/// Dispatch on the lane count (> 16).
#[inline(always)]
fn level1_lanes(l: usize, cols: &[f32], v: &[f32], w: &[f32]) -> f32 {
    match lanes(l) {
        20 => level_channel::<20>(l, cols, v, w),
        24 => level_channel::<24>(l, cols, v, w),
        28 => level_channel::<28>(l, cols, v, w),
        32 => level_channel::<32>(l, cols, v, w),
        36 => level_channel::<36>(l, cols, v, w),
        40 => level_channel::<40>(l, cols, v, w),
        44 => level_channel::<44>(l, cols, v, w),
        48 => level_channel::<48>(l, cols, v, w),
        52 => level_channel::<52>(l, cols, v, w),
        56 => level_channel::<56>(l, cols, v, w),
        60 => level_channel::<60>(l, cols, v, w),
        _ => level_channel::<64>(l, cols, v, w),
    }
}

/// The three channels' level of a band of `NL = lanes(l) ≤ 16` lanes; `block` is the band's
/// columns with the channels side by side (see [`column_index`]), summed in one sweep (`v_j`,
/// `w_j` loaded once, 6 accumulators of ≤ 16 lanes). Wider bands go channel by channel
/// ([`level_channel`]): three channels' accumulators would not fit in registers.
#[inline(always)]
fn level_in<const NL: usize>(l: usize, block: &[f32], v: &[f32], w: &[f32]) -> [f32; 3] {
    let (s, e) = (l * l, (l + 1) * (l + 1));
    let (old, new) = block.split_at(s * 3 * NL);
    let mut p = [[0.0f32; NL]; 3];
    let mut q = [[0.0f32; NL]; 3];
    for ((cols, vj), wj) in old.chunks_exact(3 * NL).zip(&v[..s]).zip(&w[..s]) {
        for c in 0..3 {
            let col = &cols[c * NL..(c + 1) * NL];
            for k in 0..NL {
                p[c][k] += vj * col[k];
                q[c][k] += wj * col[k];
            }
        }
    }
    for (cols, vj) in new.chunks_exact(3 * NL).zip(&v[s..e]) {
        for c in 0..3 {
            let col = &cols[c * NL..(c + 1) * NL];
            for k in 0..NL {
                p[c][k] += vj * col[k];
            }
        }
    }
    [0, 1, 2].map(|c| band_sum(l, &p[c], &q[c], v, w))
}

/// `Σ_r w_{l²+r} p_r + v_{l²+r} q_r` over band `l`'s `2l + 1` rows.
#[inline(always)]
fn band_sum(l: usize, p: &[f32], q: &[f32], v: &[f32], w: &[f32]) -> f32 {
    let s = l * l;
    let mut sum = 0.0f32;
    for r in 0..2 * l + 1 {
        sum += w[s + r] * p[r] + v[s + r] * q[r];
    }
    sum
}

/// One channel of [`level_in`] over its contiguous columns.
#[inline(always)]
fn level_channel<const NL: usize>(l: usize, cols: &[f32], v: &[f32], w: &[f32]) -> f32 {
    let (s, e) = (l * l, (l + 1) * (l + 1));
    let (old, new) = cols.split_at(s * NL);
    let mut p = [0.0f32; NL];
    let mut q = [0.0f32; NL];
    for ((col, vj), wj) in old.chunks_exact(NL).zip(&v[..s]).zip(&w[..s]) {
        for k in 0..NL {
            p[k] += vj * col[k];
            q[k] += wj * col[k];
        }
    }
    for (col, vj) in new.chunks_exact(NL).zip(&v[s..e]) {
        for k in 0..NL {
            p[k] += vj * col[k];
        }
    }
    band_sum(l, &p, &q, v, w)
}

/// Index of row `l² + r` of band `l`, column `j`, channel `c` in band `l`'s block of the column
/// layout: channels side by side per column up to 16 lanes, channel-major above.
#[inline]
pub(crate) const fn column_index(l: usize, j: usize, c: usize, r: usize) -> usize {
    let nl = lanes(l);
    if nl <= 16 {
        (3 * j + c) * nl + r
    } else {
        (c * (l + 1) * (l + 1) + j) * nl + r
    }
}

/// The running sums of one point.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Accum {
    /// Sum over the base bands, per channel (before `scale`).
    pub base: [f32; 3],
    /// Sum over the bands `BASE_ORDER..=last_level`, per channel (before `scale`).
    pub high: [f32; 3],
    /// Output scale per channel (albedo/π, or specular · (e+2)/(e+1) · cos θ_o).
    pub scale: [f32; 3],
    /// Highest band included.
    pub last_level: u16,
    /// Coefficient products (multiply–adds of the dot products) spent on this point.
    pub products: u64,
    /// A point that is not shaded (specular facing away): radiance 0, never in an ROI.
    pub inactive: bool,
    /// The last level's own contribution per channel (before `scale`), for the convergence test.
    pub last_delta: [f32; 3],
    /// The point stopped before the top level because its last two levels together changed it
    /// by less than the threshold ([`Stop::converged`]): its value is final, not truncated.
    pub converged: bool,
    /// Radiance the point shows besides this term's (the other term's), for tests made on the
    /// display.
    pub offset: [f32; 3],
}

impl Accum {
    /// `scale · (base + high)`.
    #[inline]
    pub fn radiance(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.scale[c] * (self.base[c] + self.high[c]))
    }

    /// The accumulated high-order difference in radiance units, `scale · high`.
    #[inline]
    pub fn correction(&self) -> [f32; 3] {
        [0, 1, 2].map(|c| self.scale[c] * self.high[c])
    }

    /// `max_c |scale_c · high_c|`, the significance tested against the threshold.
    #[inline]
    pub fn significance(&self) -> f32 {
        let d = self.correction();
        d[0].abs().max(d[1].abs()).max(d[2].abs())
    }

    /// Whether the point's value is final: shaded to the top level `top`, converged, or inactive.
    #[inline]
    pub fn complete(&self, top: usize) -> bool {
        self.inactive || self.converged || self.last_level as usize >= top
    }

    /// The significance measured as `measure` says: in radiance, `max_c |D_c|`; on the display,
    /// `max_c |f(x_c) − f(x_c − D_c)|` with `x` the point's shown radiance (this term plus
    /// `offset`) and `f` the display encoding.
    #[inline]
    pub fn significance_in(&self, measure: Measure) -> f32 {
        match measure {
            Measure::Radiance => self.significance(),
            Measure::Display { scale } => {
                let x = self.radiance();
                let d = self.correction();
                (0..3)
                    .map(|c| {
                        let y = scale * (x[c] + self.offset[c]);
                        (display(y) - display(y - scale * d[c])).abs()
                    })
                    .fold(0.0, f32::max)
            }
        }
    }

    /// Whether the significance (as `measure` says) reaches `threshold`; on the display a
    /// correction too small to reach it at the encoding's steepest slope (12.92) is rejected
    /// without evaluating the curve.
    #[inline]
    pub fn is_significant(&self, threshold: f32, measure: Measure) -> bool {
        if let Measure::Display { scale } = measure {
            if self.significance() * scale * 12.92 < threshold {
                return false;
            }
        }
        self.significance_in(measure) >= threshold
    }

    /// `max_c` of a change `m_c` about the point's value: in radiance `m_c`; on the display
    /// `(f(x_c + m_c) − f(x_c − m_c)) / 2`, the mean slope of the encoding over the span.
    #[inline]
    fn spread(&self, m: [f32; 3], measure: Measure) -> f32 {
        let largest = m[0].max(m[1]).max(m[2]);
        match measure {
            Measure::Radiance => largest,
            Measure::Display { scale } => {
                // The encoding's slope is at most 12.92 (its linear toe).
                if largest * scale * 12.92 == 0.0 {
                    return 0.0;
                }
                let x = self.radiance();
                let y = [0, 1, 2].map(|c| scale * (x[c] + self.offset[c]));
                // Shown white whatever the change: nothing moves on the display.
                if (0..3).all(|c| y[c] - scale * m[c] >= 1.0) {
                    return 0.0;
                }
                (0..3)
                    .map(|c| 0.5 * (display(y[c] + scale * m[c]) - display(y[c] - scale * m[c])))
                    .fold(0.0, f32::max)
            }
        }
    }

    /// Records the contribution `delta` (per channel, before `scale`) of level `l` and applies
    /// the stopping rules; returns whether to stop.
    #[inline]
    fn step(&mut self, l: usize, delta: [f32; 3], stop: Stop) -> bool {
        // Convergence: the last two levels together moved the value by less than the
        // threshold. Two levels, because one band alone can vanish while the next does not
        // (the clamped cosine has no odd bands ≥ 3); so it needs two levels above the base.
        let moved =
            [0, 1, 2].map(|c| self.scale[c].abs() * (delta[c].abs() + self.last_delta[c].abs()));
        self.last_delta = delta;
        self.last_level = l as u16;
        if let Some(th) = stop.converged {
            if l > BASE_ORDER {
                let largest = moved[0].max(moved[1]).max(moved[2]);
                let cheap = match stop.measure {
                    Measure::Radiance => largest < th,
                    // A bound from the largest slope, before the exact test.
                    Measure::Display { scale } => largest * scale * 12.92 < th,
                };
                if cheap || self.spread(moved, stop.measure) < th {
                    self.converged = true;
                    return true;
                }
            }
        }
        matches!(stop.insignificant, Some(th) if !self.is_significant(th, stop.measure))
    }
}

/// How the stopping tests measure a change.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) enum Measure {
    /// In output radiance.
    #[default]
    Radiance,
    /// On the display: radiance times `scale = 2^exposure`, clamped to [0, 1], sRGB-encoded
    /// (CONVENTIONS' 8-bit view before quantisation; 1 = white).
    Display {
        /// `2^exposure_ev`.
        scale: f32,
    },
}

/// Samples of the sRGB encoding on [0, 1] (4096 intervals).
static SRGB_TABLE: std::sync::LazyLock<Vec<f32>> = std::sync::LazyLock::new(|| {
    (0..=SRGB_STEPS)
        .map(|i| {
            let y = i as f64 / SRGB_STEPS as f64;
            let v = if y <= 0.003_130_8 {
                12.92 * y
            } else {
                1.055 * y.powf(1.0 / 2.4) - 0.055
            };
            v as f32
        })
        .collect()
});
const SRGB_STEPS: usize = 4096;

/// The display encoding of a (scaled) radiance `y`: clamp to [0, 1], sRGB curve; linear
/// interpolation in a 4097-entry table (error < 2e-5, far below one 8-bit step, 3.9e-3).
#[inline]
pub(crate) fn display(y: f32) -> f32 {
    let t = &*SRGB_TABLE;
    if y.is_nan() || y <= 0.0 {
        return 0.0;
    }
    if y >= 1.0 {
        return 1.0;
    }
    let u = y * SRGB_STEPS as f32;
    let i = (u as usize).min(SRGB_STEPS - 1);
    let f = u - i as f32;
    t[i] + f * (t[i + 1] - t[i])
}

/// When a point stops adding levels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Stop {
    /// Lee & Kim's Algorithm 1: stop after the first level where the accumulated high-order
    /// difference `max_c |D_c|` is below this (the point leaves the ROI, truncated).
    pub insignificant: Option<f32>,
    /// Stop once the last two levels together changed `max_c` of the value by less than this
    /// (the point's value has converged; it keeps its ROI status).
    pub converged: Option<f32>,
    /// How both tests measure.
    pub measure: Measure,
}

impl Stop {
    /// Never stop: every level up to the requested one.
    pub const NEVER: Stop = Stop {
        insignificant: None,
        converged: None,
        measure: Measure::Radiance,
    };
}

/// Diffuse kernel: `base_c = L_c[..b²]·T_c[..b²]`, then band by band `high_c += L_c[band]·T_c[band]`
/// up to level `to` inclusive, stopping early by the rules of [`Stop`] (Lee & Kim 2014,
/// Algorithms 1–2, plus the convergence stop).
pub(crate) struct DiffuseKernel<'a> {
    pub light: [&'a [f32]; 3],
    pub order: usize,
}

impl DiffuseKernel<'_> {
    /// Coefficient products of levels `0..=level` (3 channels).
    pub fn products_through(level: usize) -> u64 {
        3 * ((level + 1) * (level + 1)) as u64
    }

    /// Base of point with transfer `t` (`channels · n²` floats).
    #[inline]
    pub fn base(&self, t: &[f32], channels: usize, scale: [f32; 3]) -> Accum {
        // `t` is a full row or a low-band copy: its coefficients per channel.
        let n2 = t.len() / channels;
        let b = BASE_ORDER.min(self.order);
        let mut acc = Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            ..Accum::default()
        };
        for c in 0..3 {
            let tc = if channels == 3 {
                &t[c * n2..(c + 1) * n2]
            } else {
                &t[..n2]
            };
            acc.base[c] = dot(&self.light[c][..b * b], &tc[..b * b]);
        }
        acc
    }

    /// Adds levels `acc.last_level + 1 ..= to`, stopping early by the rules of `stop`; returns
    /// whether a rule stopped the point (rather than reaching `to`).
    #[inline]
    pub fn extend(
        &self,
        acc: &mut Accum,
        t: &[f32],
        channels: usize,
        to: usize,
        stop: Stop,
    ) -> bool {
        // `t` is a full row or a low-band copy: its coefficients per channel.
        let n2 = t.len() / channels;
        for l in (acc.last_level as usize + 1)..=to {
            let (s, e) = (l * l, (l + 1) * (l + 1));
            let mut delta = [0.0f32; 3];
            for (c, d) in delta.iter_mut().enumerate() {
                let tc = if channels == 3 {
                    &t[c * n2..(c + 1) * n2]
                } else {
                    &t[..n2]
                };
                *d = dot(&self.light[c][s..e], &tc[s..e]);
                acc.high[c] += *d;
            }
            acc.products += 3 * (e - s) as u64;
            if acc.step(l, delta, stop) {
                return true;
            }
        }
        false
    }
}

/// Specular kernel (Lee & Kim 2014, eq. 4.3–4.4 and Algorithm 3, after Sloan, Kautz & Snyder
/// 2002): the specular value is `Σ_ij w_i L̂_ij V_j` with `L̂ = M(L)` the light's product matrix
/// (`(L̂ V)_i = (L ⊛ V)_i`), `w_i = A_l y_i(r)` the Phong lobe's band multipliers times the basis
/// at the reflection direction, and `V` the visibility.
///
/// Level `l` adds exactly the terms of the incremental product that involve band `l`: the new
/// rows `i ∈ band l` against columns `j < (l+1)²`, and the new columns `j ∈ band l` against the
/// old rows `i < l²`. Since `L̂` is symmetric (the Gaunt tensor is), the second block is read as
/// rows of band `l` too, so level `l` is
/// `Σ_{i∈band l} [ w_i (L̂_i,·<(l+1)² · V) + V_i (L̂_i,·<l² · w) ]`, with the multiply count of
/// Algorithm 3 (`(2l+1)((l+1)² + l²)` per channel, plus the padding of the rows to 4 lanes).
/// Only band `l`'s rows are read, stored by column ([`column_index`]); the base uses a dense
/// copy of the `9 × 9` corner.
pub(crate) struct SpecularKernel<'a> {
    /// Band `l`'s rows of the three `L̂_c` by column (see `FrameLighting::columns`).
    columns: &'a [f32],
    column_offsets: &'a [usize],
    pub order: usize,
    /// Whether the CPU has AVX2 (the level kernel then runs its AVX2 instance).
    avx2: bool,
    /// The dense `b² × b²` corner of each `L̂_c` (`b` = the base order), for [`Self::base`].
    base_dense: [&'a [f32]; 3],
}

impl<'a> SpecularKernel<'a> {
    /// The kernel over a frame's column layout and dense base corners.
    pub fn new(
        base_dense: [&'a [f32]; 3],
        columns: &'a [f32],
        column_offsets: &'a [usize],
        order: usize,
    ) -> Self {
        #[cfg(target_arch = "x86_64")]
        let avx2 = std::arch::is_x86_feature_detected!("avx2");
        #[cfg(not(target_arch = "x86_64"))]
        let avx2 = false;
        Self {
            columns,
            column_offsets,
            order,
            base_dense,
            avx2,
        }
    }
}

impl SpecularKernel<'_> {
    /// Coefficient products of level `l` (3 channels).
    pub fn products_of_level(l: usize) -> u64 {
        3 * ((2 * l + 1) * ((l + 1) * (l + 1) + l * l)) as u64
    }

    /// Coefficient products of levels `0..=level`.
    pub fn products_through(level: usize) -> u64 {
        (0..=level).map(Self::products_of_level).sum()
    }

    /// Level `l` of the three channels: `Σ_{i∈band l} [w_i (L̂_i,·<e · v) + v_i (L̂_i,·<s · w)]`
    /// (`s = l²`, `e = (l+1)²`). The band's rows are stored by column, so both matrix–vector
    /// products are sums of columns scaled by `v_j` and `w_j` over the band's `2l+1` rows at
    /// once (rows zero-padded to [`lanes`]), and the level is one dot product over the band: no
    /// per-row reductions or tails, which dominated at the low levels where rows are short.
    #[inline]
    fn level(&self, l: usize, v: &[f32], w: &[f32]) -> [f32; 3] {
        let block = &self.columns[self.column_offsets[l]..self.column_offsets[l + 1]];
        let nl = lanes(l);
        if nl <= 16 {
            #[cfg(target_arch = "x86_64")]
            if self.avx2 {
                // SAFETY: `avx2` is set only when the CPU reports AVX2 (`Self::new`).
                #[allow(unsafe_code)]
                return unsafe { level3_avx2(l, block, v, w) };
            }
            return level3_any(l, block, v, w);
        }
        let e = (l + 1) * (l + 1);
        [0, 1, 2].map(|c| {
            let cols = &block[c * e * nl..(c + 1) * e * nl];
            #[cfg(target_arch = "x86_64")]
            if self.avx2 {
                // SAFETY: as above.
                #[allow(unsafe_code)]
                return unsafe { level1_avx2(l, cols, v, w) };
            }
            level1_any(l, cols, v, w)
        })
    }

    /// Base (levels `0..b`) of a point with visibility `v` and weights `w`: the dense
    /// `w[..b²]ᵀ L̂ v[..b²]` (the same products as levels `0..b` of Algorithm 3, without the
    /// per-row overhead of rows 1–9 long).
    #[inline]
    pub fn base(&self, v: &[f32], w: &[f32], scale: [f32; 3]) -> Accum {
        let b = BASE_ORDER.min(self.order);
        let bb = b * b;
        let mut acc = Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            ..Accum::default()
        };
        for c in 0..3 {
            let m = self.base_dense[c];
            let mut u = [0.0f32; 9];
            for (i, wi) in w[..bb].iter().enumerate() {
                for (uj, mij) in u[..bb].iter_mut().zip(&m[i * bb..(i + 1) * bb]) {
                    *uj += wi * mij;
                }
            }
            acc.base[c] = dot(&u[..bb], &v[..bb]);
        }
        acc
    }

    /// Adds levels `acc.last_level + 1 ..= to`, stopping early by the rules of `stop`; returns
    /// whether a rule stopped the point.
    #[inline]
    pub fn extend(&self, acc: &mut Accum, v: &[f32], w: &[f32], to: usize, stop: Stop) -> bool {
        for l in (acc.last_level as usize + 1)..=to {
            let delta = self.level(l, v, w);
            for c in 0..3 {
                acc.high[c] += delta[c];
            }
            acc.products += Self::products_of_level(l);
            if acc.step(l, delta, stop) {
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn dot_matches_f64_sum() {
        for n in [0usize, 1, 7, 8, 9, 17, 196] {
            let a: Vec<f32> = (0..n).map(|i| (i as f32 * 0.37).sin()).collect();
            let b: Vec<f32> = (0..n).map(|i| (i as f32 * 0.11).cos()).collect();
            let exact: f64 = a.iter().zip(&b).map(|(x, y)| *x as f64 * *y as f64).sum();
            // n products of magnitude ≤ 1, summed in f32: error ≤ n·ε·Σ|a b| ≤ n² ε.
            let tol = (n * n) as f64 * f32::EPSILON as f64 + 1e-12;
            assert!((dot(&a, &b) as f64 - exact).abs() <= tol, "n = {n}");
        }
    }

    #[test]
    fn display_table_matches_the_srgb_curve() {
        // The exact curve in f64 at points between and on the table's samples.
        for i in 0..=20_000 {
            let y = i as f64 / 20_000.0;
            let exact = if y <= 0.003_130_8 {
                12.92 * y
            } else {
                1.055 * y.powf(1.0 / 2.4) - 0.055
            };
            // Interpolation error ≤ h²/8 · max|f''| ≈ (1/4096)²/8 · 2.4e3 = 1.8e-5 next to the
            // toe; f32 rounding adds ~1e-7.
            assert!((f64::from(display(y as f32)) - exact).abs() < 2e-5, "{y}");
        }
        assert_eq!(display(-1.0), 0.0);
        assert_eq!(display(f32::NAN), 0.0);
        assert_eq!(display(7.0), 1.0);
    }

    #[test]
    fn display_measure_ignores_changes_above_white() {
        let a = Accum {
            base: [2.0; 3],
            high: [0.5; 3],
            scale: [1.0; 3],
            ..Accum::default()
        };
        let display = Measure::Display { scale: 1.0 };
        // 2.5 shown, 2.0 at the base: both clip to white.
        assert_eq!(a.significance_in(display), 0.0);
        assert_eq!(a.significance_in(Measure::Radiance), 0.5);
        // Half the exposure: 1.25 vs 1.0 — still both white.
        assert_eq!(a.significance_in(Measure::Display { scale: 0.5 }), 0.0);
        // A quarter: 0.625 vs 0.5 on the sRGB curve.
        let f = |y: f64| 1.055 * y.powf(1.0 / 2.4) - 0.055;
        let want = f(0.625) - f(0.5);
        let got = f64::from(a.significance_in(Measure::Display { scale: 0.25 }));
        assert!((got - want).abs() < 5e-5, "{got} vs {want}");
    }

    #[test]
    #[cfg(target_arch = "x86_64")]
    fn avx2_level_is_bit_identical_to_the_baseline() {
        if !std::arch::is_x86_feature_detected!("avx2") {
            return;
        }
        // Pseudo-random band blocks and vectors, every band up to 31.
        let mut x = 0x9e37_79b9_u32;
        let mut next = || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x as f32 / u32::MAX as f32) * 2.0 - 1.0
        };
        for l in 0..32usize {
            let e = (l + 1) * (l + 1);
            let nl = lanes(l);
            // Padding lanes (r ≥ 2l+1 of each nl) are zero in either layout.
            let block: Vec<f32> = (0..3 * e * nl)
                .map(|k| if k % nl < 2 * l + 1 { next() } else { 0.0 })
                .collect();
            let v: Vec<f32> = (0..e).map(|_| next()).collect();
            let w: Vec<f32> = (0..e).map(|_| next()).collect();
            let (a, b) = if nl <= 16 {
                // SAFETY: AVX2 checked above.
                #[allow(unsafe_code)]
                let b = unsafe { level3_avx2(l, &block, &v, &w) };
                (level3_any(l, &block, &v, &w), b)
            } else {
                let part = |c: usize| &block[c * e * nl..(c + 1) * e * nl];
                // SAFETY: AVX2 checked above.
                #[allow(unsafe_code)]
                let b = [0, 1, 2].map(|c| unsafe { level1_avx2(l, part(c), &v, &w) });
                ([0, 1, 2].map(|c| level1_any(l, part(c), &v, &w)), b)
            };
            assert_eq!(a.map(f32::to_bits), b.map(f32::to_bits), "band {l}");
            // And both equal the row-by-row definition in f64 to rounding.
            let s = l * l;
            for c in 0..3 {
                let mut exact = 0.0f64;
                for r in 0..2 * l + 1 {
                    let row = |j: usize| f64::from(block[column_index(l, j, c, r)]);
                    let pv: f64 = (0..e).map(|j| row(j) * f64::from(v[j])).sum();
                    let qw: f64 = (0..s).map(|j| row(j) * f64::from(w[j])).sum();
                    exact += f64::from(w[s + r]) * pv + f64::from(v[s + r]) * qw;
                }
                // (2l+1)·2e terms of magnitude ≤ 1 summed in f32.
                let tol = ((2 * l + 1) * 2 * e) as f64 * 4.0 * f64::from(f32::EPSILON);
                assert!(
                    (f64::from(a[c]) - exact).abs() <= tol,
                    "band {l}, channel {c}: {} vs {exact}",
                    a[c]
                );
            }
        }
    }

    #[test]
    fn product_counts_sum_to_dense() {
        // Levels 0..n−1 of the specular kernel cover every (i, j) pair of the n²×n² matrix
        // exactly once (3 channels): Σ_l (2l+1)((l+1)² + l²) = n⁴.
        for n in 1..15usize {
            assert_eq!(
                SpecularKernel::products_through(n - 1),
                3 * (n as u64).pow(4)
            );
            assert_eq!(
                DiffuseKernel::products_through(n - 1),
                3 * (n as u64).pow(2)
            );
        }
    }
}
