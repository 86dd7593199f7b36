//! Environment sampling tables per shading normal, for [`crate::EnvSampling::PerNormal`].
//!
//! MIS compensation (Karlík, Šik, Vévoda, Skřivan & Křivánek, "MIS Compensation", SIGGRAPH Asia
//! 2019) asks of the environment technique the density that, mixed with the BRDF technique,
//! is proportional to the integrand. For a Lambert point with normal `n` under radiance `L`,
//! one sample of each technique and the balance heuristic, the mixture
//! `½ p_env + ½ cos⁺/π` equals `L cos⁺ / (π L̄_n)` (with `L̄_n = ∫ L cos⁺ dω / π`, the
//! irradiance over `π`) when `p_env ∝ cos⁺ · (L − L̄_n / 2)`; where that is negative no
//! density can make up for it and it is clamped to zero. The normal-independent variant drops
//! the cosine and uses one constant for the whole map; keeping both gives the environment
//! samples only to directions the point sees, where the map stands out of what cosine-weighted
//! BRDF sampling covers.
//!
//! The cosine and `L̄_n` depend on the normal, so the density is tabulated for
//! `BIN_SIDE × BIN_SIDE` (1024) normals (the cell centres of an octahedral map of the sphere)
//! and a point uses the table of the cell its shading normal falls in: `O(1)` to find, and the same
//! table for its environment samples and for the pdf its BRDF samples are weighted with, which
//! is all MIS needs to stay unbiased (any density is, where BRDF sampling covers the rest).
//! Tables are over blocks of texels (at most 64 × 32 blocks, one texel each for maps that
//! small) weighted with the block's mean luminance and solid angle and the cosine at its
//! centre; inside a block a texel is drawn by luminance × solid angle (a [`BlockTable`] per
//! block too), the same for every normal. Lat-long maps only. The tables hold 16-bit CDFs (4.3 MB for the largest block
//! grid): a sample at a vertex whose normal changes from sample to sample reads its table
//! from memory, and `f32` tables (8.6 MB) took 1.12× the one-table sampler's time.

use glam::DVec3;
use prt_scene::envmap::{cell_index, latlong_direction};
use std::f64::consts::PI;

/// Normal bins per side of the octahedral map (`BIN_SIDE²` tables, about 4.3 MB for the
/// largest block grid). Measured on the suite's scenes at 256 spp: 16 per side (256 normals)
/// took one render's error from 0.00316 / 0.00410 / 0.00422 (one table) to 0.00268 / 0.00318
/// / 0.00324 on `sphere` / `bunny_floor` / `teapot`, 32 per side to 0.00239 / 0.00296 /
/// 0.00295.
pub(crate) const BIN_SIDE: usize = 32;
/// Most blocks across and down the map.
const MAX_BLOCKS: [usize; 2] = [64, 32];

/// The octahedral map's fold of the lower hemisphere onto the square's corners (its own
/// inverse on the square).
fn fold(x: f64, y: f64) -> (f64, f64) {
    ((1.0 - y.abs()) * x.signum(), (1.0 - x.abs()) * y.signum())
}

/// The octahedral cell `[0, BIN_SIDE)²` of a unit direction.
pub(crate) fn bin_of(d: DVec3) -> usize {
    let l1 = d.x.abs() + d.y.abs() + d.z.abs();
    if l1.is_nan() || l1 <= 0.0 {
        return 0;
    }
    let (mut x, mut y) = (d.x / l1, d.y / l1);
    if d.z < 0.0 {
        (x, y) = fold(x, y);
    }
    let cell = |t: f64| cell_index((t + 1.0) * 0.5 * BIN_SIDE as f64, BIN_SIDE);
    cell(y) * BIN_SIDE + cell(x)
}

/// The unit direction at the centre of octahedral cell `bin`.
pub(crate) fn bin_normal(bin: usize) -> DVec3 {
    let centre = |i: usize| (i as f64 + 0.5) / BIN_SIDE as f64 * 2.0 - 1.0;
    let (mut x, mut y) = (centre(bin % BIN_SIDE), centre(bin / BIN_SIDE));
    let z = 1.0 - x.abs() - y.abs();
    if z < 0.0 {
        (x, y) = fold(x, y);
    }
    DVec3::new(x, y, z).normalize()
}

/// Fixed-point unit of the block tables' CDFs: an entry `e` stands for `e / ONE`.
const ONE: f64 = 65536.0;

/// A piecewise-constant 2D distribution over `w × h` blocks in one compact array of 16-bit
/// fixed-point CDF entries (a thousand of them are kept and read at random, so they must be
/// small: 4.2 KB for 64 × 32 blocks, where a [`crate::Distribution2D`] takes 42 KB): the marginal CDF
/// over rows, then each row's conditional CDF over its columns. Each CDF of `n` cells keeps
/// its `n` lower edges `e_i / 2¹⁶` (`e_0 = 0`); the upper edge of the last is 1. A cell is
/// drawn by the inverse CDF (a monotone map, so stratified `u` stay stratified) and its
/// probability is `(e_{i+1} − e_i) / 2¹⁶`, exact in `f64`: the measure of the `u` that draw
/// it, so sampling and [`BlockTable::pmf`] agree exactly. Each probability is its weight's
/// share rounded to a multiple of 2⁻¹⁶ (a cell of weight 0 gets 0, unless rounding leaves the
/// last 2⁻¹⁶ to a tail of zero weights: any density is valid under MIS, only its variance
/// changes).
#[derive(Clone, Debug)]
struct BlockTable {
    w: usize,
    h: usize,
    edges: Vec<u16>,
}

impl BlockTable {
    /// The table of non-negative `weights` (row-major); `None` when they are all zero.
    fn new(weights: &[f64], w: usize, h: usize) -> Option<Self> {
        let rows: Vec<f64> = weights.chunks(w).map(|r| r.iter().sum()).collect();
        let total: f64 = rows.iter().sum();
        if total.is_nan() || total <= 0.0 {
            return None;
        }
        let mut edges = Vec::with_capacity(h + h * w);
        push_edges(&mut edges, &rows);
        for row in weights.chunks(w) {
            push_edges(&mut edges, row);
        }
        Some(Self { w, h, edges })
    }

    fn marginal(&self) -> &[u16] {
        &self.edges[..self.h]
    }

    fn row(&self, r: usize) -> &[u16] {
        let start = self.h + r * self.w;
        &self.edges[start..start + self.w]
    }

    /// Draws `((col, row), probability, u remapped into the cell)`.
    fn sample(&self, u: [f64; 2]) -> Option<((usize, usize), f64, [f64; 2])> {
        let (r, p_row, rem_row) = invert(self.marginal(), u[1])?;
        let (c, p_col, rem_col) = invert(self.row(r), u[0])?;
        Some(((c, r), p_row * p_col, [rem_col, rem_row]))
    }

    /// Probability of cell `(col, row)`.
    fn pmf(&self, col: usize, row: usize) -> f64 {
        width(self.marginal(), row) * width(self.row(row), col)
    }
}

/// Appends the lower edges of the CDF of `weights` in units of 2⁻¹⁶ (all zero: every edge 0,
/// so only the last cell can be drawn; a zero row is never drawn by its marginal).
fn push_edges(edges: &mut Vec<u16>, weights: &[f64]) {
    let total: f64 = weights.iter().sum();
    let mut acc = 0.0;
    for &x in weights {
        let e = if total > 0.0 {
            (acc / total * ONE).round().min(ONE - 1.0)
        } else {
            0.0
        };
        edges.push(e as u16);
        acc += x;
    }
}

/// Upper edge of cell `i` (in units of 2⁻¹⁶).
fn upper(edges: &[u16], i: usize) -> f64 {
    edges.get(i + 1).map_or(ONE, |&e| f64::from(e))
}

/// Probability of cell `i`.
fn width(edges: &[u16], i: usize) -> f64 {
    (upper(edges, i) - f64::from(edges[i])) / ONE
}

/// The cell `i` with `e_i ≤ u·2¹⁶ < e_{i+1}`, its probability and `u` remapped into it. The
/// edges are sorted, so `i + 1` is the number of edges `≤ u·2¹⁶`, i.e. `≤ ⌊u·2¹⁶⌋` (they are
/// integers): counted over the whole CDF without branches (one or two cache lines, loaded
/// together) rather than by a binary search whose loads wait on each other.
fn invert(edges: &[u16], u: f64) -> Option<(usize, f64, f64)> {
    let x = u * ONE;
    // `⌊x⌋` clamped to `[0, 2¹⁶ − 1]` (NaN to 0): a float-to-int cast truncates towards zero
    // and saturates, which for every `x` gives the same value without a call to libm's
    // `floor` (baseline x86-64 has no rounding instruction).
    let floor = x as u16;
    let i = count_at_most(edges, floor).checked_sub(1)?;
    let (lo, hi) = (f64::from(edges[i]), upper(edges, i));
    (hi > lo).then(|| {
        (
            i,
            (hi - lo) / ONE,
            ((x - lo) / (hi - lo)).clamp(0.0, 1.0 - f64::EPSILON),
        )
    })
}

/// How many of `edges` are `≤ x`. The count runs in 16-bit lanes, eight or sixteen edges per
/// SIMD instruction (a count in 64-bit lanes took two edges per instruction and was most of
/// a draw's time), over chunks short enough that it cannot overflow.
fn count_at_most(edges: &[u16], x: u16) -> usize {
    edges
        .chunks(u16::MAX as usize)
        .map(|chunk| usize::from(chunk.iter().map(|&e| u16::from(e <= x)).sum::<u16>()))
        .sum()
}

/// Per-normal block distributions and per-block texel distributions of a lat-long map.
#[derive(Clone, Debug)]
pub(crate) struct NormalTables {
    /// Texels per block across and down.
    block: [usize; 2],
    /// Blocks across and down.
    blocks: [usize; 2],
    /// Per normal bin: the distribution over blocks (`None`: nothing to sample).
    bins: Vec<Option<BlockTable>>,
    /// Per block: the distribution over its texels (`None` for one-texel blocks and black
    /// blocks).
    within: Vec<Option<BlockTable>>,
}

impl NormalTables {
    /// Tables for a `w × h` lat-long map with per-texel `(luminance, solid angle)`.
    pub(crate) fn new(texels: &[(f64, f64)], w: usize, h: usize) -> Self {
        let block = [
            w.div_ceil(MAX_BLOCKS[0]).max(1),
            h.div_ceil(MAX_BLOCKS[1]).max(1),
        ];
        let blocks = [w.div_ceil(block[0]), h.div_ceil(block[1])];
        let mut within = Vec::with_capacity(blocks[0] * blocks[1]);
        // Per block: luminance × solid angle, solid angle, centre direction.
        let mut summary = Vec::with_capacity(blocks[0] * blocks[1]);
        for by in 0..blocks[1] {
            for bx in 0..blocks[0] {
                let (c0, r0) = (bx * block[0], by * block[1]);
                let (bw, bh) = ((w - c0).min(block[0]), (h - r0).min(block[1]));
                let cells: Vec<(f64, f64)> = (0..bw * bh)
                    .map(|i| texels[(r0 + i / bw) * w + c0 + i % bw])
                    .collect();
                let power: f64 = cells.iter().map(|&(l, o)| l * o).sum();
                let omega: f64 = cells.iter().map(|&(_, o)| o).sum();
                let phi = 2.0 * PI * (c0 as f64 + 0.5 * bw as f64) / w as f64;
                let theta = PI * (r0 as f64 + 0.5 * bh as f64) / h as f64;
                summary.push((power, omega, latlong_direction(phi, theta)));
                let weights: Vec<f64> = cells.iter().map(|&(l, o)| l * o).collect();
                within.push(if bw * bh > 1 {
                    BlockTable::new(&weights, bw, bh)
                } else {
                    None
                });
            }
        }
        let bins = (0..BIN_SIDE * BIN_SIDE)
            .map(|b| Self::bin_table(&summary, bin_normal(b), blocks))
            .collect();
        Self {
            block,
            blocks,
            bins,
            within,
        }
    }

    /// The block distribution of the normal `n`: `cos⁺ · max(0, L_block − L̄_n/2) · Ω_block`.
    fn bin_table(
        summary: &[(f64, f64, DVec3)],
        n: DVec3,
        blocks: [usize; 2],
    ) -> Option<BlockTable> {
        let irradiance: f64 = summary
            .iter()
            .map(|&(power, _, d)| power * n.dot(d).max(0.0))
            .sum();
        let half_mean = 0.5 * irradiance / PI;
        let weights: Vec<f64> = summary
            .iter()
            .map(|&(power, omega, d)| {
                let cos = n.dot(d).max(0.0);
                if omega > 0.0 {
                    cos * (power / omega - half_mean).max(0.0) * omega
                } else {
                    0.0
                }
            })
            .collect();
        BlockTable::new(&weights, blocks[0], blocks[1])
    }

    /// Draws a texel for map-frame normal `n`: `((col, row), probability, remainder in the
    /// texel)`.
    pub(crate) fn sample(&self, n: DVec3, u: [f64; 2]) -> Option<((usize, usize), f64, [f64; 2])> {
        let dist = self.bins[bin_of(n)].as_ref()?;
        let ((bx, by), p_block, rem) = dist.sample(u)?;
        let (c0, r0) = (bx * self.block[0], by * self.block[1]);
        match &self.within[by * self.blocks[0] + bx] {
            None => Some(((c0, r0), p_block, rem)),
            Some(inner) => {
                let ((c, r), p, rem) = inner.sample(rem)?;
                Some(((c0 + c, r0 + r), p_block * p, rem))
            }
        }
    }

    /// Probability of texel `(col, row)` for map-frame normal `n`.
    pub(crate) fn pmf(&self, n: DVec3, col: usize, row: usize) -> f64 {
        let Some(dist) = self.bins[bin_of(n)].as_ref() else {
            return 0.0;
        };
        let (bx, by) = (col / self.block[0], row / self.block[1]);
        let p_block = dist.pmf(bx, by);
        match &self.within[by * self.blocks[0] + bx] {
            None => p_block,
            Some(inner) => p_block * inner.pmf(col - bx * self.block[0], row - by * self.block[1]),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// With one texel per block, a normal's texel probabilities are the closed form
    /// `cos⁺(n_b · d_t) · max(0, L_t − L̄/2) · Ω_t / Σ`, `n_b` the bin's centre normal, `d_t` the
    /// texel's centre and `L̄ = Σ L Ω cos⁺ / π`, computed here from scratch; a black
    /// hemisphere has nothing to sample.
    #[test]
    fn one_texel_blocks_match_the_closed_form() {
        let (w, h) = (16, 8);
        let texels: Vec<(f64, f64)> = (0..w * h)
            .map(|i| {
                let (c, r) = (i % w, i / w);
                let t0 = PI * r as f64 / h as f64;
                let t1 = PI * (r + 1) as f64 / h as f64;
                let omega = 2.0 * PI / w as f64 * (t0.cos() - t1.cos());
                let lum = if r < 3 { 0.5 + c as f64 * 0.1 } else { 0.0 };
                (if (c, r) == (4, 1) { 40.0 } else { lum }, omega)
            })
            .collect();
        let tables = NormalTables::new(&texels, w, h);
        assert_eq!((tables.block, tables.blocks), ([1, 1], [w, h]));
        let centre = |i: usize| {
            let (c, r) = (i % w, i / w);
            latlong_direction(
                2.0 * PI * (c as f64 + 0.5) / w as f64,
                PI * (r as f64 + 0.5) / h as f64,
            )
        };
        for n in [DVec3::Y, DVec3::new(0.3, 0.5, -0.8).normalize(), DVec3::X] {
            let nb = bin_normal(bin_of(n));
            let cos = |i: usize| nb.dot(centre(i)).max(0.0);
            let irradiance: f64 = (0..w * h).map(|i| texels[i].0 * texels[i].1 * cos(i)).sum();
            let weight =
                |i: usize| cos(i) * (texels[i].0 - 0.5 * irradiance / PI).max(0.0) * texels[i].1;
            let total: f64 = (0..w * h).map(weight).sum();
            let mut sum = 0.0;
            for i in 0..w * h {
                let p = tables.pmf(n, i % w, i / w);
                sum += p;
                // Each CDF edge is rounded to a multiple of 2⁻¹⁶ (within 2⁻¹⁷), so a width is
                // within 2⁻¹⁶ and a product of two within 2⁻¹⁵ = 3.1e-5.
                assert!((p - weight(i) / total).abs() < 3.1e-5, "{n} texel {i}: {p}");
            }
            assert!((sum - 1.0).abs() < 1e-12, "Σ = {sum}");
        }
        // Straight down sees only the black lower rows.
        assert!(tables.sample(DVec3::NEG_Y, [0.3, 0.7]).is_none());
        assert_eq!(tables.pmf(DVec3::NEG_Y, 4, 1), 0.0);
    }

    /// A block table draws each cell for exactly the share of `u` its `pmf` says: on a
    /// 512 × 512 grid of `u` every cell's count is `pmf · 512²` to within one grid line
    /// (`512` points) per CDF edge; zero rows and cells are never drawn; the returned
    /// probability is `pmf`'s.
    /// The lane count equals a plain count, on sorted and unsorted edges, at every threshold
    /// that matters, and past the 16-bit chunk length (where one chunk's sum would overflow).
    #[test]
    fn count_at_most_is_the_plain_count() {
        use rand::Rng;
        let mut rng = rand_pcg::Pcg64Mcg::new(7);
        for n in [0, 1, 7, 8, 16, 33, 64, 4096, 70_000, 140_001] {
            let edges: Vec<u16> = (0..n).map(|_| rng.random()).collect();
            let mut xs = vec![0, 1, u16::MAX - 1, u16::MAX];
            xs.extend(
                edges
                    .iter()
                    .take(20)
                    .flat_map(|&e| [e.saturating_sub(1), e]),
            );
            for x in xs {
                let plain = edges.iter().filter(|&&e| e <= x).count();
                assert_eq!(count_at_most(&edges, x), plain, "n {n}, x {x}");
            }
        }
        let all = vec![0u16; 70_000];
        assert_eq!(count_at_most(&all, 0), 70_000);
    }

    #[test]
    fn block_table_draws_its_pmf() {
        let weights = [
            0.0, 1.0, 3.0, 0.0, /**/ 0.0, 0.0, 0.0, 0.0, /**/ 2.0, 1e-3, 0.5, 7.0,
        ];
        let t = BlockTable::new(&weights, 4, 3).unwrap();
        let n = 512;
        let mut counts = [0usize; 12];
        for i in 0..n {
            for j in 0..n {
                let u = [(i as f64 + 0.5) / n as f64, (j as f64 + 0.5) / n as f64];
                let ((c, r), p, rem) = t.sample(u).unwrap();
                assert_eq!(p, t.pmf(c, r));
                assert!(weights[r * 4 + c] > 0.0 && rem.iter().all(|x| (0.0..1.0).contains(x)));
                counts[r * 4 + c] += 1;
            }
        }
        let total: f64 = weights.iter().sum();
        for (k, &count) in counts.iter().enumerate() {
            let want = weights[k] / total;
            assert!((t.pmf(k % 4, k / 4) - want).abs() < 3.1e-5);
            let expected = t.pmf(k % 4, k / 4) * (n * n) as f64;
            assert!(
                (count as f64 - expected).abs() <= 2.0 * n as f64,
                "cell {k}: {count} vs {expected}"
            );
        }
        assert!(BlockTable::new(&[0.0; 6], 3, 2).is_none());
    }

    #[test]
    fn bins_cover_the_sphere_and_their_centres_fall_in_them() {
        for b in 0..BIN_SIDE * BIN_SIDE {
            let n = bin_normal(b);
            assert!((n.length() - 1.0).abs() < 1e-12);
            assert_eq!(bin_of(n), b, "bin {b}: centre {n}");
        }
        for d in [
            DVec3::X,
            DVec3::Y,
            DVec3::Z,
            DVec3::NEG_X,
            DVec3::NEG_Y,
            DVec3::NEG_Z,
        ] {
            assert!(bin_of(d) < BIN_SIDE * BIN_SIDE);
            assert!(bin_normal(bin_of(d)).dot(d) > 0.9);
        }
    }
}
