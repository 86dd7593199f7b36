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

use glam::Vec4;

/// Number of vertices per parallel task.
pub(crate) const CHUNK: usize = 256;

/// Number of vertices the adaptive filtering pass takes through both terms together (their
/// transfers stay in cache between the diffuse base, the specular term and the diffuse levels).
pub(crate) const BLOCK: usize = 32;

/// `[f(0), f(1), f(2)]`, always inlined (`[0, 1, 2].map(f)` was left as an out-of-line call
/// in the hot paths).
#[inline(always)]
pub(crate) fn rgb<T>(mut f: impl FnMut(usize) -> T) -> [T; 3] {
    [f(0), f(1), f(2)]
}

/// Asks the CPU to bring the cache lines of `row[..floats]` toward L1 (a hint: no effect on
/// results, never faults). The adaptive path knows which points go on past the low bands only
/// after their first levels, and their full rows are scattered through memory: without the
/// hint each such point stalls on a main-memory miss (measured: a quarter of the specular
/// level kernel's time and half of the diffuse one's on the 37k-vertex bunny).
#[inline]
pub(crate) fn prefetch(row: &[f32], floats: usize) {
    #[cfg(target_arch = "x86_64")]
    {
        let n = floats.min(row.len());
        // One hint per 64-byte line, plus the line of the last float (rows are not aligned).
        let mut k = 0;
        while k < n {
            prefetch_line(&row[k]);
            k += 16;
        }
        if n > 0 {
            prefetch_line(&row[n - 1]);
        }
    }
    #[cfg(not(target_arch = "x86_64"))]
    let _ = (row, floats);
}

#[cfg(target_arch = "x86_64")]
#[inline(always)]
fn prefetch_line(x: &f32) {
    use std::arch::x86_64::{_mm_prefetch, _MM_HINT_T0};
    // SAFETY: SSE is part of the x86_64 baseline, and a prefetch hint never dereferences its
    // address (`x` is a valid reference anyway).
    #[allow(unsafe_code)]
    unsafe {
        _mm_prefetch::<_MM_HINT_T0>(std::ptr::from_ref(x).cast());
    }
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
#[allow(unsafe_code)] // Runtime feature dispatch (this and `prefetch_line` are the crate's only kinds of unsafe code).
unsafe fn level3_avx2(l: usize, block: &[f32], v: &[f32], w: &[f32]) -> [f32; 3] {
    level3_lanes(l, block, v, w)
}

/// [`level1_any`] compiled for AVX2; bit-identical as [`level3_avx2`].
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)] // Runtime feature dispatch (this and `prefetch_line` are the crate's only kinds of unsafe code).
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
    rgb(|c| band_sum(l, &p[c], &q[c], v, w))
}

/// `Σ_r w_{l²+r} p_r + v_{l²+r} q_r` over band `l`'s `2l + 1` rows.
#[inline(always)]
fn band_sum<const NL: usize>(l: usize, p: &[f32; NL], q: &[f32; NL], v: &[f32], w: &[f32]) -> f32 {
    // The terms lane-wise (vectorised), then summed in row order; `t` has the band's lane
    // count (zeroing a larger scratch per call cost more than the sum).
    let (s, n) = (l * l, 2 * l + 1);
    let (w, v, p, q) = (&w[s..s + n], &v[s..s + n], &p[..n], &q[..n]);
    let mut t = [0.0f32; NL];
    for r in 0..n {
        t[r] = w[r] * p[r] + v[r] * q[r];
    }
    let mut sum = 0.0f32;
    for x in &t[..n] {
        sum += x;
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

/// Levels 3 and 4 of the specular kernel in one sweep (every specular point evaluates both
/// before its first convergence test): the rows of bands 3 and 4 (`9..25`, 16 of them, one pair
/// of AVX registers without padding) against the columns `j < 25`. Band 3's rows take `v_j`
/// only for `j < 16` and `w_j` only for `j < 9`, band 4's `v_j` for `j < 25` and `w_j` for
/// `j < 16` (Algorithm 3's ranges), so the block holds, per column `j` and channel, 16 lanes
/// (band 3's 7 rows, then band 4's 9) with band 3's lanes zero for `j ≥ 16`, and for
/// `9 ≤ j < 16` a second copy with band 3's lanes zero for the `w` sweep. The same sums as
/// [`SpecularKernel::level`] at levels 3 and 4, in the same order per row (the zero lanes add
/// exact zeros).
pub(crate) const PAIR_TOP: usize = 4;
const PAIR_LANES: usize = 16;
/// Floats of the pair block: 25 columns, then the 7 `w`-sweep copies, × 3 channels × 16 lanes.
pub(crate) const PAIR_FLOATS: usize = (25 + 7) * 3 * PAIR_LANES;

/// Fills channel `c` of the pair block (see [`PAIR_TOP`]) from `m(i, j) = L̂_c[i][j]`.
pub(crate) fn fill_pair_block(block: &mut [f32], c: usize, m: impl Fn(usize, usize) -> f32) {
    let lane = |i: usize| if i < 16 { i - 9 } else { 7 + (i - 16) };
    for j in 0..25 {
        for i in 9..25 {
            let on = i >= 16 || j < 16;
            block[(3 * j + c) * PAIR_LANES + lane(i)] = if on { m(i, j) } else { 0.0 };
        }
    }
    for j in 9..16 {
        for i in 9..25 {
            let on = i >= 16;
            block[(3 * (25 + j - 9) + c) * PAIR_LANES + lane(i)] = if on { m(i, j) } else { 0.0 };
        }
    }
}

/// Levels 3 and 4, three channels, baseline instruction set.
fn pair_any(block: &[f32], v: &[f32], w: &[f32]) -> [[f32; 3]; 2] {
    pair_in(block, v, w)
}

/// [`pair_any`] compiled for AVX2; bit-identical as [`level3_avx2`].
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
#[allow(unsafe_code)] // Runtime feature dispatch, as `level3_avx2`.
unsafe fn pair_avx2(block: &[f32], v: &[f32], w: &[f32]) -> [[f32; 3]; 2] {
    pair_in(block, v, w)
}

#[inline(always)]
fn pair_in(block: &[f32], v: &[f32], w: &[f32]) -> [[f32; 3]; 2] {
    const NL: usize = PAIR_LANES;
    let (v, w) = (&v[..25], &w[..25]);
    let (main, wcopy) = block.split_at(25 * 3 * NL);
    let mut p = [[0.0f32; NL]; 3];
    let mut q = [[0.0f32; NL]; 3];
    let (cols, _) = main.as_chunks::<{ 3 * NL }>();
    let (zcols, _) = wcopy.as_chunks::<{ 3 * NL }>();
    for (cols, (vj, wj)) in cols[..9].iter().zip(v[..9].iter().zip(&w[..9])) {
        for c in 0..3 {
            for k in 0..NL {
                p[c][k] += vj * cols[c * NL + k];
                q[c][k] += wj * cols[c * NL + k];
            }
        }
    }
    for ((cols, zcols), (vj, wj)) in cols[9..16]
        .iter()
        .zip(zcols)
        .zip(v[9..16].iter().zip(&w[9..16]))
    {
        for c in 0..3 {
            for k in 0..NL {
                p[c][k] += vj * cols[c * NL + k];
                q[c][k] += wj * zcols[c * NL + k];
            }
        }
    }
    for (cols, vj) in cols[16..25].iter().zip(&v[16..25]) {
        for c in 0..3 {
            for k in 0..NL {
                p[c][k] += vj * cols[c * NL + k];
            }
        }
    }
    // Band sums as `band_sum`: the terms `w_i p_i + v_i q_i` lane-wise (lane k is row 9 + k),
    // then each band's rows summed in order.
    let (w16, v16) = (&w[9..25], &v[9..25]);
    let mut out = [[0.0f32; 3]; 2];
    for c in 0..3 {
        let mut t = [0.0f32; NL];
        for k in 0..NL {
            t[k] = w16[k] * p[c][k] + v16[k] * q[c][k];
        }
        let (mut s3, mut s4) = (0.0f32, 0.0f32);
        for x in &t[..7] {
            s3 += x;
        }
        for x in &t[7..] {
            s4 += x;
        }
        out[0][c] = s3;
        out[1][c] = s4;
    }
    out
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
        rgb(|c| self.scale[c] * (self.base[c] + self.high[c]))
    }

    /// The accumulated high-order difference in radiance units, `scale · high`.
    #[inline]
    pub fn correction(&self) -> [f32; 3] {
        rgb(|c| self.scale[c] * self.high[c])
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
    /// correction too small to reach it at the encoding's largest slope over its span
    /// ([`slope_from`]) is rejected without evaluating the curve (the same answer, cheaper).
    #[inline]
    pub fn is_significant(&self, threshold: f32, measure: Measure) -> bool {
        if let Measure::Display { scale } = measure {
            let table = &*SRGB_TABLE;
            let x = self.radiance();
            let d = self.correction();
            let mut bound = 0.0f32;
            for c in 0..3 {
                let y = scale * (x[c] + self.offset[c]);
                let step = scale * d[c];
                let b = step.abs() * slope_from(table, y.min(y - step));
                bound = if b > bound { b } else { bound };
            }
            if bound + DISPLAY_ROUNDING < threshold {
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
                let y = rgb(|c| scale * (x[c] + self.offset[c]));
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

    /// Whether [`Self::spread`] of `m` is below `th`, deciding from slope bounds where they
    /// suffice (the same answer as the exact test, which is evaluated only when they do not).
    #[inline]
    fn spread_below(&self, m: [f32; 3], measure: Measure, th: f32) -> bool {
        // (`m` is finite and ≥ 0: plain comparisons instead of the NaN-aware `f32::max`.)
        let larger = |a: f32, b: f32| if b > a { b } else { a };
        let largest = larger(larger(m[0], m[1]), m[2]);
        match measure {
            Measure::Radiance => largest < th,
            Measure::Display { scale } => {
                let table = &*SRGB_TABLE;
                // Upper and lower bounds of each channel's spread from the slopes over its span
                // `[y − m, y + m]` (computed without branches); the exact curve is evaluated
                // only if they straddle `th`.
                let x = self.radiance();
                let (mut upper, mut lower) = (0.0f32, 0.0f32);
                for c in 0..3 {
                    let y = scale * (x[c] + self.offset[c]);
                    let h = scale * m[c];
                    upper = larger(upper, h * slope_from(table, y - h));
                    let low = h * least_to(table, y + h);
                    lower = larger(lower, if y - h >= 0.0 { low } else { 0.0 });
                }
                if upper + DISPLAY_ROUNDING < th {
                    return true;
                }
                if lower - DISPLAY_ROUNDING >= th {
                    return false;
                }
                self.spread(m, measure) < th
            }
        }
    }

    /// Adds level `l`'s contribution `delta` (per channel, before `scale`), which cost
    /// `products` multiply–adds, and applies the stopping rules; returns whether to stop.
    #[inline]
    fn add_level(&mut self, l: usize, delta: [f32; 3], products: u64, stop: Stop<'_>) -> bool {
        for c in 0..3 {
            self.high[c] += delta[c];
        }
        self.products += products;
        self.step(l, delta, stop)
    }

    /// Records the contribution `delta` (per channel, before `scale`) of level `l` and applies
    /// the stopping rules; returns whether to stop.
    #[inline]
    fn step(&mut self, l: usize, delta: [f32; 3], stop: Stop<'_>) -> bool {
        // Convergence: the last two levels together moved the value by less than the
        // threshold. Two levels, because one band alone can vanish while the next does not
        // (the clamped cosine has no odd bands ≥ 3); so it needs two levels above the base.
        let last = self.last_delta;
        self.last_delta = delta;
        self.last_level = l as u16;
        if let Some(th) = stop.converged {
            if l > BASE_ORDER {
                let th = th * stop.level_scale.get(l).copied().unwrap_or(1.0);
                let moved = rgb(|c| self.scale[c].abs() * (delta[c].abs() + last[c].abs()));
                if self.spread_below(moved, stop.measure, th) {
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
/// The display encoding sampled on [0, 1] (4096 intervals), and a slope bound per interval.
struct DisplayTable {
    /// `f(i / 4096)`, the sRGB curve.
    value: Vec<f32>,
    /// `slope[i] ≥` every chord slope of the interpolated table on `[i/256, 1]`: for
    /// `i/256 ≤ a ≤ b`, `|display(b) − display(a)| ≤ slope[i] (b − a)`; `slope[256] = 0`.
    slope: Vec<f32>,
    /// `least[i] ≤` every chord slope on `[0, (i+1)/256]`: for `0 ≤ a ≤ b ≤ (i+1)/256`,
    /// `display(b) − display(a) ≥ least[i] (b − a)`; `least[256] = 0`.
    least: Vec<f32>,
}

/// prt-image's sRGB curve (the one of the PNG views), tabulated for the display measure.
static SRGB_TABLE: std::sync::LazyLock<DisplayTable> = std::sync::LazyLock::new(|| {
    let value: Vec<f32> = (0..=SRGB_STEPS)
        .map(|i| prt_image::srgb_oetf(i as f64 / SRGB_STEPS as f64) as f32)
        .collect();
    // Chord slopes of the f32 table in f64 (so the bounds hold for the interpolation actually
    // evaluated); per coarse interval `i` (of `SLOPE_STEPS`), the largest chord slope on
    // `[i/256, 1]` (a running maximum from the right) and the smallest on `[0, (i+1)/256]` (a
    // running minimum from the left), rounded outward by a relative 1e-6. Coarse, so the two
    // bound tables stay in L1 (2 KiB) while the tested values land anywhere on [0, 1].
    let chord = |j: usize| (f64::from(value[j + 1]) - f64::from(value[j])) * SRGB_STEPS as f64;
    let per = SRGB_STEPS / SLOPE_STEPS;
    let mut slope = vec![0.0f32; SLOPE_STEPS + 1];
    let mut max = 0.0f64;
    for i in (0..SLOPE_STEPS).rev() {
        max = (i * per..(i + 1) * per).map(chord).fold(max, f64::max);
        slope[i] = (max * (1.0 + 1e-6)) as f32;
    }
    // Entry 256 (b ≥ 1, where the display clamps) is 0.
    let mut least = vec![0.0f32; SLOPE_STEPS + 1];
    let mut min = f64::INFINITY;
    for i in 0..SLOPE_STEPS {
        min = (i * per..(i + 1) * per).map(chord).fold(min, f64::min);
        least[i] = (min * (1.0 - 1e-6)) as f32;
    }
    DisplayTable {
        value,
        slope,
        least,
    }
});
const SRGB_STEPS: usize = 4096;
/// Intervals of the slope-bound tables.
const SLOPE_STEPS: usize = 256;

/// Absolute allowance for the f32 rounding of [`display`] differences (a few ulps of 1) in the
/// slope bounds, so a bound below a threshold always implies the exact difference is too.
const DISPLAY_ROUNDING: f32 = 4e-6;

/// The display encoding of a (scaled) radiance `y`: clamp to [0, 1], sRGB curve; linear
/// interpolation in a 4097-entry table (error < 2e-5, far below one 8-bit step, 3.9e-3).
#[inline]
pub(crate) fn display(y: f32) -> f32 {
    let t = &SRGB_TABLE.value;
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

/// A lower bound on the slope of [`display`] over `[0, b]` (0 if `b ≥ 1`, where the display
/// clamps): for `0 ≤ x ≤ y ≤ b`, `display(y) − display(x) ≥ least_to(b) (y − x)` (up to
/// [`DISPLAY_ROUNDING`]).
#[inline]
fn least_to(table: &DisplayTable, b: f32) -> f32 {
    // Branch-free: the float-to-integer cast saturates (negative and NaN give interval 0),
    // and entry 256 (b ≥ 1) is 0.
    table.least[((b * SLOPE_STEPS as f32) as usize).min(SLOPE_STEPS)]
}

/// A bound on the slope of [`display`] over `[a, ∞)`: for `a ≤ x ≤ y`,
/// `display(y) − display(x) ≤ slope_from(a) (y − x)` (up to [`DISPLAY_ROUNDING`]).
#[inline]
fn slope_from(table: &DisplayTable, a: f32) -> f32 {
    // Branch-free as `least_to`: a ≤ 0 and NaN give the steepest (first) interval's slope,
    // a ≥ 1 entry 256, 0.
    table.slope[((a * SLOPE_STEPS as f32) as usize).min(SLOPE_STEPS)]
}

/// When a point stops adding levels.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct Stop<'a> {
    /// Lee & Kim's Algorithm 1: stop after the first level where the accumulated high-order
    /// difference `max_c |D_c|` is below this (the point leaves the ROI, truncated).
    pub insignificant: Option<f32>,
    /// Stop once the last two levels together changed `max_c` of the value by less than this
    /// times `level_scale[l]` (the point's value has converged; it keeps its ROI status).
    pub converged: Option<f32>,
    /// Factor of the convergence threshold at level `l` (the term's cost growth, see
    /// [`level_costs`]); 1 beyond its end (empty: 1 everywhere).
    pub level_scale: &'a [f32],
    /// How both tests measure.
    pub measure: Measure,
}

impl<'a> Stop<'a> {
    /// Never stop: every level up to the requested one.
    pub const NEVER: Stop<'static> = Stop {
        insignificant: None,
        converged: None,
        level_scale: &[],
        measure: Measure::Radiance,
    };

    /// The same rules with the convergence threshold scaled per level by `level_scale`.
    #[must_use]
    pub fn with_level_scale(self, level_scale: &'a [f32]) -> Stop<'a> {
        Stop {
            level_scale,
            ..self
        }
    }
}

/// Which term's levels [`level_costs`] prices.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Term {
    /// `3 (2l + 1)` products per level ([`DiffuseKernel`]).
    Diffuse,
    /// `3 (2l + 1) ((l + 1)² + l²)` products per level ([`SpecularKernel`]).
    Specular,
}

/// The convergence threshold's factor per level `l < order` for cost exponent `alpha`:
/// `(c(l + 1) / c(BASE_ORDER + 2))^alpha`, with `c(k)` the coefficient products of the term's
/// level `k`. The test after level `l` decides whether to pay for level `l + 1`; the first test
/// (after level `BASE_ORDER + 1`) keeps factor 1, so `T` keeps its meaning there, and each
/// later level must be bought by a change that grows with its price (`alpha = 1`: change per
/// product; `alpha = 1/2`: squared change per product). `alpha = 0`: 1 everywhere.
pub(crate) fn level_costs(term: Term, order: usize, alpha: f32) -> Vec<f32> {
    // The kernels' own counts of the products of level `l`.
    let cost = |l: usize| -> f64 {
        (match term {
            Term::Diffuse => {
                DiffuseKernel::products_through(l) - DiffuseKernel::products_through(l - 1)
            }
            Term::Specular => SpecularKernel::products_of_level(l),
        }) as f64
    };
    let reference = cost(BASE_ORDER + 2);
    (0..order)
        .map(|l| {
            if l <= BASE_ORDER || alpha == 0.0 {
                1.0
            } else {
                (cost(l + 1) / reference).powf(f64::from(alpha)) as f32
            }
        })
        .collect()
}

/// Diffuse kernel: `base_c = L_c[..b²]·T_c[..b²]`, then band by band `high_c += L_c[band]·T_c[band]`
/// up to level `to` inclusive, stopping early by the rules of [`Stop`] (Lee & Kim 2014,
/// Algorithms 1–2, plus the convergence stop).
///
/// The light is read interleaved, `[L_0,i, L_1,i, L_2,i, 0]` per coefficient `i`, so the three
/// channels of a band are one 4-lane multiply–add per coefficient (a 1-channel transfer is
/// broadcast): one pass over the band instead of three short dot products with their tails.
pub(crate) struct DiffuseKernel<'a> {
    /// `[L_0,i, L_1,i, L_2,i, 0]` per coefficient (`FrameLighting::light4`).
    pub light4: &'a [[f32; 4]],
    pub order: usize,
}

/// `Σ_{i∈s..e} T_i ⊙ L4_i` over the three channels, with four partial sums (coefficients
/// `i ≡ k mod 4` into sum `k`, combined as `(s0 + s1) + (s2 + s3)`); `CH` is the transfer's
/// channel count (1: `T_i` serves all three), rows of `n2` floats per channel.
#[inline(always)]
fn band_dot<const CH: usize>(
    light4: &[[f32; 4]],
    t: &[f32],
    n2: usize,
    s: usize,
    e: usize,
) -> [f32; 3] {
    let tv = |i: usize| -> [f32; 4] {
        if CH == 1 {
            [t[i]; 4]
        } else {
            [t[i], t[n2 + i], t[2 * n2 + i], 0.0]
        }
    };
    let mut a = [[0.0f32; 4]; 4];
    let mut i = s;
    while i + 4 <= e {
        for (k, ak) in a.iter_mut().enumerate() {
            let (x, y) = (tv(i + k), light4[i + k]);
            for c in 0..4 {
                ak[c] += x[c] * y[c];
            }
        }
        i += 4;
    }
    for (k, ak) in a.iter_mut().enumerate().take(e - i) {
        let (x, y) = (tv(i + k), light4[i + k]);
        for c in 0..4 {
            ak[c] += x[c] * y[c];
        }
    }
    rgb(|c| (a[0][c] + a[1][c]) + (a[2][c] + a[3][c]))
}

impl DiffuseKernel<'_> {
    /// Coefficient products of levels `0..=level` (3 channels).
    pub fn products_through(level: usize) -> u64 {
        3 * ((level + 1) * (level + 1)) as u64
    }

    /// `Σ_{i∈s..e} T_c,i L_c,i` per channel for point row `t` (`channels · n²` floats).
    #[inline(always)]
    fn range(&self, t: &[f32], channels: usize, s: usize, e: usize) -> [f32; 3] {
        // (Division by the constant 3, not by `channels`: this runs per level.)
        if channels == 3 {
            band_dot::<3>(self.light4, t, t.len() / 3, s, e)
        } else {
            band_dot::<1>(self.light4, t, t.len(), s, e)
        }
    }

    /// Base of point with transfer `t` (`channels · n²` floats).
    #[inline]
    pub fn base(&self, t: &[f32], channels: usize, scale: [f32; 3]) -> Accum {
        // `t` is a full row or a low-band copy: its coefficients per channel.
        let b = BASE_ORDER.min(self.order);
        // (The usual case with constant bounds, so the compiler unrolls it.)
        let base = if b == BASE_ORDER {
            self.range(t, channels, 0, BASE_ORDER * BASE_ORDER)
        } else {
            self.range(t, channels, 0, b * b)
        };
        Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            base,
            ..Accum::default()
        }
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
        stop: Stop<'_>,
    ) -> bool {
        // `t` is a full row or a low-band copy: its coefficients per channel.
        let mut first = acc.last_level as usize + 1;
        // Levels 3 and 4, which every point evaluates before its first convergence test, with
        // constant bounds (unrolled); the same sums as the loop below.
        if first == PAIR_TOP - 1 && to >= PAIR_TOP && self.order > PAIR_TOP {
            let deltas = [
                self.range(t, channels, 9, 16),
                self.range(t, channels, 16, 25),
            ];
            for (k, delta) in deltas.into_iter().enumerate() {
                let l = PAIR_TOP - 1 + k;
                if acc.add_level(l, delta, 3 * (2 * l + 1) as u64, stop) {
                    return true;
                }
            }
            first = PAIR_TOP + 1;
        }
        for l in first..=to {
            let (s, e) = (l * l, (l + 1) * (l + 1));
            let delta = self.range(t, channels, s, e);
            if acc.add_level(l, delta, 3 * (e - s) as u64, stop) {
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
    /// The `b² × b²` corner of the three `L̂_c` (`b` = the base order) by column, for
    /// [`Self::base`]: column `j`, channel `c`, rows `0..BASE_LANES` at `(3j + c)·BASE_LANES`
    /// (rows `≥ b²` zero).
    base_columns: &'a [f32],
}

/// Lanes of a column of the base corner: its `BASE_ORDER² = 9` rows padded to 12.
pub(crate) const BASE_LANES: usize = 12;

impl<'a> SpecularKernel<'a> {
    /// The kernel over a frame's column layout and base corner.
    pub fn new(
        base_columns: &'a [f32],
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
            base_columns,
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
        rgb(|c| {
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
    /// per-row overhead of rows 1–9 long), as `u_c = Σ_j v_j L̂_c[·, j]` over the corner's
    /// columns (three channels of 12 lanes per column), then `Σ_r w_r u_c,r`.
    #[inline]
    pub fn base(&self, v: &[f32], w: &[f32], scale: [f32; 3]) -> Accum {
        let b = BASE_ORDER.min(self.order);
        let bb = b * b;
        // The three channels' 12 lanes as nine 4-lane vectors (explicit: left to itself the
        // compiler unrolls this sweep into scalar code).
        let mut u = [Vec4::ZERO; 3 * BASE_LANES / 4];
        let (cols, _) = self.base_columns.as_chunks::<{ 3 * BASE_LANES }>();
        for (col, vj) in cols.iter().zip(&v[..bb]) {
            let vj = Vec4::splat(*vj);
            for (g, ug) in u.iter_mut().enumerate() {
                *ug += vj * Vec4::from_slice(&col[4 * g..4 * g + 4]);
            }
        }
        // `Σ_r w_r u_c,r` lane-wise (rows ≥ b² are zero in `u`, and in this copy of `w`), then
        // the lanes summed.
        let mut wl = [0.0f32; BASE_LANES];
        wl[..bb].copy_from_slice(&w[..bb]);
        let wv = [0, 1, 2].map(|g| Vec4::from_slice(&wl[4 * g..4 * g + 4]));
        let base = rgb(|c| {
            let g = 3 * c;
            (wv[0] * u[g] + wv[1] * u[g + 1] + wv[2] * u[g + 2]).element_sum()
        });
        Accum {
            scale,
            last_level: (b - 1) as u16,
            products: Self::products_through(b - 1),
            base,
            ..Accum::default()
        }
    }

    /// Adds levels `acc.last_level + 1 ..= to`, stopping early by the rules of `stop`; returns
    /// whether a rule stopped the point.
    #[inline]
    pub fn extend(&self, acc: &mut Accum, v: &[f32], w: &[f32], to: usize, stop: Stop<'_>) -> bool {
        let mut first = acc.last_level as usize + 1;
        // Levels 3 and 4 together when both are due (see `PAIR_TOP`).
        let pair = first == PAIR_TOP - 1 && to >= PAIR_TOP && self.order > PAIR_TOP;
        let mut pair_deltas = None;
        if pair {
            let block = &self.columns[self.column_offsets[self.order]..];
            #[cfg(target_arch = "x86_64")]
            if self.avx2 {
                // SAFETY: `avx2` is set only when the CPU reports AVX2 (`Self::new`).
                #[allow(unsafe_code)]
                let d = unsafe { pair_avx2(block, v, w) };
                pair_deltas = Some(d);
            }
            if pair_deltas.is_none() {
                pair_deltas = Some(pair_any(block, v, w));
            }
        }
        if let Some(deltas) = pair_deltas {
            for (k, delta) in deltas.into_iter().enumerate() {
                let l = PAIR_TOP - 1 + k;
                if acc.add_level(l, delta, Self::products_of_level(l), stop) {
                    return true;
                }
            }
            first = PAIR_TOP + 1;
        }
        for l in first..=to {
            let delta = self.level(l, v, w);
            if acc.add_level(l, delta, Self::products_of_level(l), stop) {
                return true;
            }
        }
        false
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Xorshift numbers in [-1, 1) for the property tests below.
    fn numbers(seed: u32) -> impl FnMut() -> f32 {
        let mut x = seed.max(1);
        move || {
            x ^= x << 13;
            x ^= x >> 17;
            x ^= x << 5;
            (x as f32 / u32::MAX as f32) * 2.0 - 1.0
        }
    }

    #[test]
    fn diffuse_band_sums_match_f64() {
        let mut next = numbers(7);
        let light4: Vec<[f32; 4]> = (0..196).map(|_| [next(), next(), next(), 0.0]).collect();
        for channels in [1usize, 3] {
            let t: Vec<f32> = (0..196 * channels).map(|_| next()).collect();
            let kernel = DiffuseKernel {
                light4: &light4,
                order: 14,
            };
            for (s, e) in [
                (0, 0),
                (0, 1),
                (1, 4),
                (0, 9),
                (9, 16),
                (25, 36),
                (169, 196),
                (0, 196),
            ] {
                let got = kernel.range(&t, channels, s, e);
                for c in 0..3 {
                    let tc = |i: usize| f64::from(t[if channels == 3 { c * 196 + i } else { i }]);
                    let exact: f64 = (s..e).map(|i| tc(i) * f64::from(light4[i][c])).sum();
                    // (e − s) products of magnitude ≤ 1 summed in f32.
                    let tol = ((e - s) * (e - s)) as f64 * f64::from(f32::EPSILON) + 1e-12;
                    assert!((f64::from(got[c]) - exact).abs() <= tol, "{s}..{e} c {c}");
                }
            }
        }
    }

    #[test]
    fn specular_base_is_the_dense_corner_product() {
        // w[..9]ᵀ M_c v[..9] against f64, M_c stored by column as `FrameLighting` does.
        let mut next = numbers(11);
        let m: Vec<[[f64; 9]; 9]> = (0..3)
            .map(|_| [[0.0; 9]; 9].map(|row| row.map(|_: f64| f64::from(next()))))
            .collect();
        let mut corner = vec![0.0f32; 9 * 3 * BASE_LANES];
        for (c, mc) in m.iter().enumerate() {
            for j in 0..9 {
                for r in 0..9 {
                    corner[(3 * j + c) * BASE_LANES + r] = mc[r][j] as f32;
                }
            }
        }
        let v: Vec<f32> = (0..9).map(|_| next()).collect();
        let w: Vec<f32> = (0..9).map(|_| next()).collect();
        let kernel = SpecularKernel::new(&corner, &[], &[], 3);
        let acc = kernel.base(&v, &w, [1.0; 3]);
        for (c, mc) in m.iter().enumerate() {
            let exact: f64 = (0..9)
                .flat_map(|r| (0..9).map(move |j| (r, j)))
                .map(|(r, j)| f64::from(w[r]) * f64::from(mc[r][j] as f32) * f64::from(v[j]))
                .sum();
            // 81 products of magnitude ≤ 1, two levels of f32 sums.
            assert!(
                (f64::from(acc.base[c]) - exact).abs() < 81.0 * 4.0 * 1.2e-7,
                "c {c}"
            );
        }
    }

    #[test]
    fn display_slope_bounds_hold_on_the_interpolated_table() {
        let mut next = numbers(3);
        for _ in 0..200_000 {
            // Points over [-0.2, 1.2], biased toward the toe.
            let mut pick = || {
                let u = next();
                if u > 0.0 {
                    1.4 * u - 0.2
                } else {
                    0.01 * u.abs()
                }
            };
            let (p, q) = (pick(), pick());
            let (a, b) = (p.min(q), p.max(q));
            let diff = display(b) - display(a);
            assert!(
                diff <= slope_from(&SRGB_TABLE, a) * (b - a) + DISPLAY_ROUNDING,
                "{a} {b}"
            );
            if a >= 0.0 {
                assert!(
                    diff >= least_to(&SRGB_TABLE, b) * (b - a) - DISPLAY_ROUNDING,
                    "{a} {b}"
                );
            }
        }
    }

    #[test]
    fn bounded_display_tests_decide_as_the_exact_ones() {
        // The slope bounds only skip evaluations: every decision equals the exact test's.
        let mut next = numbers(5);
        for k in 0..100_000 {
            let scale = [1.0f32, 0.25, 4.0][k % 3];
            let measure = Measure::Display { scale };
            let a = Accum {
                base: [
                    0.5 * (next() + 1.0),
                    0.3 * (next() + 1.0),
                    0.01 * (next() + 1.0),
                ],
                high: [0.1 * next(), 0.01 * next(), 0.002 * next()],
                scale: [1.0, 0.7, 2.0],
                offset: [0.2 * (next() + 1.0), 0.0, 0.001],
                ..Accum::default()
            };
            let m = [
                0.05 * (next() + 1.0),
                0.005 * (next() + 1.0),
                0.0005 * (next() + 1.0),
            ];
            for th in [1e-3f32, 5e-3, 0.02, 0.05] {
                assert_eq!(
                    a.spread_below(m, measure, th),
                    a.spread(m, measure) < th,
                    "{a:?} {m:?} {th}"
                );
                assert_eq!(
                    a.is_significant(th, measure),
                    a.significance_in(measure) >= th,
                    "{a:?} {th}"
                );
            }
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
        let mut next = numbers(0x9e37_79b9);
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
    fn paired_levels_3_and_4_equal_the_single_levels() {
        // A random symmetric 25×25 block of L̂ per channel, laid out both ways.
        let mut next = numbers(17);
        let m: Vec<Vec<f32>> = (0..3)
            .map(|_| {
                let mut a = vec![0.0f32; 625];
                for i in 0..25 {
                    for j in 0..=i {
                        let x = next();
                        a[i * 25 + j] = x;
                        a[j * 25 + i] = x;
                    }
                }
                a
            })
            .collect();
        let mut singles = Vec::new();
        for l in 3..5usize {
            let (s, e, nl) = (l * l, (l + 1) * (l + 1), lanes(l));
            let mut block = vec![0.0f32; 3 * e * nl];
            for (c, mc) in m.iter().enumerate() {
                for j in 0..e {
                    for r in 0..2 * l + 1 {
                        block[column_index(l, j, c, r)] = mc[(s + r) * 25 + j];
                    }
                }
            }
            singles.push(block);
        }
        let mut pair = vec![0.0f32; PAIR_FLOATS];
        for (c, mc) in m.iter().enumerate() {
            fill_pair_block(&mut pair, c, |i, j| mc[i * 25 + j]);
        }
        for _ in 0..50 {
            let v: Vec<f32> = (0..25).map(|_| next()).collect();
            let w: Vec<f32> = (0..25).map(|_| next()).collect();
            let want = [
                level3_any(3, &singles[0], &v, &w),
                level3_any(4, &singles[1], &v, &w),
            ];
            assert_eq!(pair_any(&pair, &v, &w), want);
            #[cfg(target_arch = "x86_64")]
            if std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: AVX2 checked.
                #[allow(unsafe_code)]
                let got = unsafe { pair_avx2(&pair, &v, &w) };
                assert_eq!(
                    got.map(|d| d.map(f32::to_bits)),
                    want.map(|d| d.map(f32::to_bits))
                );
            }
        }
    }

    #[test]
    fn level_costs_price_levels_by_their_products() {
        // The factor after level l is (products of level l + 1 / products of level 5)^α with
        // the closed forms of the two kernels' level costs (Algorithm 3 for specular):
        // 3(2l+1) and 3(2l+1)((l+1)² + l²); 1 up to the first test (level 4) and for α = 0.
        let diffuse_level = |l: usize| (3 * (2 * l + 1)) as f64;
        let specular_level = |l: usize| (3 * (2 * l + 1) * ((l + 1) * (l + 1) + l * l)) as f64;
        for (term, cost) in [
            (Term::Diffuse, &diffuse_level as &dyn Fn(usize) -> f64),
            (Term::Specular, &specular_level),
        ] {
            for alpha in [0.0f32, 0.5, 1.0, 2.0] {
                let f = level_costs(term, 14, alpha);
                assert_eq!(f.len(), 14);
                for (l, &x) in f.iter().enumerate() {
                    let want = if l <= BASE_ORDER {
                        1.0
                    } else {
                        (cost(l + 1) / cost(BASE_ORDER + 2)).powf(f64::from(alpha))
                    };
                    assert!(
                        (f64::from(x) - want).abs() <= 1e-6 * want,
                        "{term:?} α {alpha} level {l}: {x} vs {want}"
                    );
                    // Levels only get dearer: the factor never falls below 1 or with l.
                    assert!(x >= 1.0 && (l == 0 || x >= f[l - 1]));
                }
            }
        }
        // A specular level 9 costs 5.1× level 5 (the figure the docs quote): 19·181 / 11·61.
        let f = level_costs(Term::Specular, 10, 1.0);
        assert!((f[8] - 19.0 * 181.0 / (11.0 * 61.0)).abs() < 1e-5);
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
