//! Piecewise-constant 1D and 2D distributions with `sample` / `pdf` / `invert`, built in f64.
//!
//! A [`Distribution1D`] over `n` cells of `[0, 1)` draws cell `i` with probability
//! `f_i / Σ f` and a point uniformly inside it, so its density on `[0, 1)` is
//! `n f_i / Σ f`. Cells of zero weight are never drawn. A [`Distribution2D`] is a marginal
//! distribution over rows and one conditional distribution over columns per row.
//!
//! Sampling is the inverse CDF (a monotone map of `u`, so stratified or quasi-random `u`
//! stay stratified in the cells). The search for the cell starts from a *guide table*
//! (the cutpoint method of Chen and Asau, 1974): for each of `G` equal buckets of `u`, the
//! range of CDF entries that `u` in the bucket can fall between, so a draw reads one guide
//! entry and searches a few neighbouring CDF entries instead of all of them. The cell drawn
//! is exactly the one the plain binary search over the whole CDF gives.

/// Piecewise-constant distribution over `n` equal cells of `[0, 1)`.
#[derive(Clone, Debug)]
pub struct Distribution1D {
    func: Vec<f64>,
    cdf: Vec<f64>,
    sum: f64,
    /// `guide[j]` = number of CDF entries `≤ j / G` for `j = 0 ..= G`, with `G =
    /// guide.len() − 1` a power of two; empty when the CDF is not finite (the whole CDF is
    /// searched then).
    guide: Vec<u32>,
}

/// Guide ranges up to this long are counted entry by entry (no mispredicted branches); longer
/// ones, where many cells of tiny weight share a bucket, by binary search.
const SHORT_RANGE: usize = 8;

/// The guide table of a CDF (see [`Distribution1D`]'s `guide`): `G` is the power of two at
/// or above the number of cells, so a bucket holds about one cell on average.
fn guide_table(cdf: &[f64]) -> Vec<u32> {
    if cdf.iter().any(|c| !c.is_finite()) || u32::try_from(cdf.len()).is_err() {
        return Vec::new();
    }
    let g = cdf.len().saturating_sub(1).max(1).next_power_of_two();
    let mut guide = Vec::with_capacity(g + 1);
    let mut i = 0;
    for j in 0..=g {
        // `j / g` is exact (g is a power of two); the CDF is non-decreasing.
        let x = j as f64 / g as f64;
        while i < cdf.len() && cdf[i] <= x {
            i += 1;
        }
        guide.push(i as u32);
    }
    guide
}

impl Distribution1D {
    /// Builds the distribution of non-negative weights (negative and NaN weights count as 0).
    #[must_use]
    pub fn new(weights: &[f64]) -> Self {
        let func: Vec<f64> = weights
            .iter()
            .map(|&w| if w > 0.0 { w } else { 0.0 })
            .collect();
        let mut cdf = Vec::with_capacity(func.len() + 1);
        let mut acc = 0.0;
        cdf.push(0.0);
        for &f in &func {
            acc += f;
            cdf.push(acc);
        }
        let sum = acc;
        if sum > 0.0 {
            for c in &mut cdf {
                *c /= sum;
            }
            // Exact 1 at the end, and at every trailing zero cell.
            let last_nonzero = func.iter().rposition(|&f| f > 0.0).unwrap_or(0);
            for c in &mut cdf[last_nonzero + 1..] {
                *c = 1.0;
            }
        }
        let guide = guide_table(&cdf);
        Self {
            func,
            cdf,
            sum,
            guide,
        }
    }

    /// Number of CDF entries `≤ u` (`u ∈ [0, 1]`): `cdf.partition_point(|&c| c <= u)`,
    /// searched only between the guide entries of `u`'s bucket. With `G` a power of two,
    /// `u · G` and `j / G` are exact, so `j / G ≤ u ≤ (j + 1) / G` and every entry below
    /// `guide[j]` is `≤ u` and every entry from `guide[j + 1]` on is `> u`.
    fn entries_at_most(&self, u: f64) -> usize {
        if self.guide.len() < 2 {
            return self.cdf.partition_point(|&c| c <= u);
        }
        let g = self.guide.len() - 1;
        let j = ((u * g as f64) as usize).min(g - 1);
        let (lo, hi) = (self.guide[j] as usize, self.guide[j + 1] as usize);
        let range = &self.cdf[lo..hi];
        if range.len() <= SHORT_RANGE {
            // A count without branches on the data: the entries are sorted, so the number
            // `≤ u` is where the binary search would stop.
            return lo + range.iter().map(|&c| usize::from(c <= u)).sum::<usize>();
        }
        lo + range.partition_point(|&c| c <= u)
    }

    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.func.len()
    }

    /// True when there are no cells.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.func.is_empty()
    }

    /// Sum of the weights; 0 means nothing can be sampled.
    #[must_use]
    pub fn sum(&self) -> f64 {
        self.sum
    }

    /// Weight of cell `i` (after clamping negatives to 0).
    #[must_use]
    pub fn weight(&self, i: usize) -> f64 {
        self.func[i]
    }

    /// Draws a cell for `u ∈ [0, 1)`: `(cell, probability, u remapped to [0, 1) inside the cell)`.
    /// `None` if all weights are zero.
    #[must_use]
    pub fn sample_discrete(&self, u: f64) -> Option<(usize, f64, f64)> {
        if self.sum <= 0.0 {
            return None;
        }
        let u = u.clamp(0.0, 1.0);
        // Last i with cdf[i] <= u; it always has a positive weight for u < 1.
        let mut i = self.entries_at_most(u).saturating_sub(1);
        i = i.min(self.func.len() - 1);
        while self.func[i] <= 0.0 && i > 0 {
            i -= 1; // only reachable for u == 1
        }
        let width = self.cdf[i + 1] - self.cdf[i];
        let rem = if width > 0.0 {
            ((u - self.cdf[i]) / width).clamp(0.0, 1.0 - f64::EPSILON)
        } else {
            0.5
        };
        Some((i, self.func[i] / self.sum, rem))
    }

    /// Probability of drawing cell `i`.
    #[must_use]
    pub fn pmf(&self, i: usize) -> f64 {
        if self.sum > 0.0 {
            self.func[i] / self.sum
        } else {
            0.0
        }
    }

    /// Draws a point of `[0, 1)`: `(x, density at x, cell)`.
    #[must_use]
    pub fn sample_continuous(&self, u: f64) -> Option<(f64, f64, usize)> {
        let (i, p, rem) = self.sample_discrete(u)?;
        let n = self.func.len() as f64;
        Some(((i as f64 + rem) / n, p * n, i))
    }

    /// Density on `[0, 1)` at `x`.
    #[must_use]
    pub fn pdf(&self, x: f64) -> f64 {
        let n = self.func.len();
        let i = ((x * n as f64).floor().max(0.0) as usize).min(n - 1);
        self.pmf(i) * n as f64
    }

    /// The `u` that [`Self::sample_continuous`] maps to `x` (for `x` in a cell of positive weight).
    #[must_use]
    pub fn invert(&self, x: f64) -> f64 {
        let n = self.func.len();
        let xn = x * n as f64;
        let i = (xn.floor().max(0.0) as usize).min(n - 1);
        let frac = (xn - i as f64).clamp(0.0, 1.0);
        self.cdf[i] + frac * (self.cdf[i + 1] - self.cdf[i])
    }

    /// The `u` range `[cdf_i, cdf_{i+1})` that selects cell `i`.
    #[must_use]
    pub fn cell_range(&self, i: usize) -> (f64, f64) {
        (self.cdf[i], self.cdf[i + 1])
    }
}

/// Piecewise-constant distribution over a `width × height` grid of cells (row-major weights):
/// a marginal over rows, then a conditional over the columns of the chosen row.
#[derive(Clone, Debug)]
pub struct Distribution2D {
    rows: Vec<Distribution1D>,
    marginal: Distribution1D,
}

impl Distribution2D {
    /// Builds from `width * height` non-negative row-major weights.
    ///
    /// # Panics
    /// If `weights.len() != width * height` or a dimension is zero.
    #[must_use]
    pub fn new(weights: &[f64], width: usize, height: usize) -> Self {
        assert!(
            width > 0 && height > 0 && weights.len() == width * height,
            "bad grid"
        );
        let rows: Vec<Distribution1D> = weights
            .chunks_exact(width)
            .map(Distribution1D::new)
            .collect();
        let marginal =
            Distribution1D::new(&rows.iter().map(Distribution1D::sum).collect::<Vec<_>>());
        Self { rows, marginal }
    }

    /// Width (columns).
    #[must_use]
    pub fn width(&self) -> usize {
        self.rows[0].len()
    }

    /// Height (rows).
    #[must_use]
    pub fn height(&self) -> usize {
        self.rows.len()
    }

    /// Sum of all weights.
    #[must_use]
    pub fn sum(&self) -> f64 {
        self.marginal.sum()
    }

    /// Draws a cell: `((col, row), probability, [u_col, u_row] remapped to [0,1) in the cell)`.
    /// `u[0]` picks the column, `u[1]` the row.
    #[must_use]
    pub fn sample_discrete(&self, u: [f64; 2]) -> Option<((usize, usize), f64, [f64; 2])> {
        let (row, p_row, rem_row) = self.marginal.sample_discrete(u[1])?;
        let (col, p_col, rem_col) = self.rows[row].sample_discrete(u[0])?;
        Some(((col, row), p_row * p_col, [rem_col, rem_row]))
    }

    /// Probability of drawing cell `(col, row)`.
    #[must_use]
    pub fn pmf(&self, col: usize, row: usize) -> f64 {
        let s = self.marginal.sum();
        if s > 0.0 {
            self.rows[row].weight(col) / s
        } else {
            0.0
        }
    }

    /// Draws a point of `[0,1)²` (`x` along columns): `([x, y], density)`.
    #[must_use]
    pub fn sample_continuous(&self, u: [f64; 2]) -> Option<([f64; 2], f64)> {
        let ((c, r), p, rem) = self.sample_discrete(u)?;
        let (w, h) = (self.width() as f64, self.height() as f64);
        Some((
            [(c as f64 + rem[0]) / w, (r as f64 + rem[1]) / h],
            p * w * h,
        ))
    }

    /// Density on `[0,1)²` at `[x, y]`.
    #[must_use]
    pub fn pdf(&self, p: [f64; 2]) -> f64 {
        let (w, h) = (self.width(), self.height());
        let c = ((p[0] * w as f64).floor().max(0.0) as usize).min(w - 1);
        let r = ((p[1] * h as f64).floor().max(0.0) as usize).min(h - 1);
        self.pmf(c, r) * (w * h) as f64
    }

    /// The `u` that [`Self::sample_continuous`] maps to `[x, y]`.
    #[must_use]
    pub fn invert(&self, p: [f64; 2]) -> [f64; 2] {
        let h = self.height();
        let r = ((p[1] * h as f64).floor().max(0.0) as usize).min(h - 1);
        [self.rows[r].invert(p[0]), self.marginal.invert(p[1])]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn one_d_probabilities_and_zero_cells() {
        let d = Distribution1D::new(&[0.0, 1.0, 0.0, 3.0, 0.0]);
        assert_eq!(d.pmf(1), 0.25);
        assert_eq!(d.pmf(3), 0.75);
        for k in 0..=1000 {
            let u = k as f64 / 1000.0 * (1.0 - 1e-12);
            let (i, p, rem) = d.sample_discrete(u).unwrap();
            assert!(i == 1 || i == 3, "zero cell {i} drawn at u = {u}");
            assert!(p > 0.0 && (0.0..1.0).contains(&rem));
        }
        assert_eq!(d.sample_discrete(0.0).unwrap().0, 1);
        assert_eq!(d.sample_discrete(0.25).unwrap().0, 3);
        assert!(Distribution1D::new(&[0.0, 0.0])
            .sample_discrete(0.5)
            .is_none());
        // Density integrates to 1.
        let total: f64 = (0..5).map(|i| d.pdf((i as f64 + 0.5) / 5.0) / 5.0).sum();
        assert!((total - 1.0).abs() < 1e-12);
    }

    #[test]
    fn guided_search_is_the_plain_binary_search() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(7);
        let peaked: Vec<f64> = (0..1000)
            .map(|i| if i == 500 { 1e6 } else { f64::from(i % 3) })
            .collect();
        let tiny: Vec<f64> = (0..37).map(|i| if i < 30 { 1e-9 } else { 1.0 }).collect();
        let random: Vec<f64> = (0..64)
            .map(|_| {
                let x: f64 = rng.random();
                if x < 0.2 {
                    0.0
                } else {
                    x
                }
            })
            .collect();
        for w in [vec![1.0], vec![0.0, 2.0, 0.0], peaked, tiny, random] {
            let d = Distribution1D::new(&w);
            assert_eq!(d.guide.len(), d.len().next_power_of_two() + 1);
            let g = (d.guide.len() - 1) as f64;
            let mut us: Vec<f64> = (0..=4 * d.guide.len())
                .map(|k| k as f64 / (4.0 * g))
                .collect();
            us.extend(d.cdf.iter().copied());
            us.extend(
                d.cdf
                    .iter()
                    .filter(|&&c| c > 0.0)
                    .map(|&c| f64::from_bits(c.to_bits() - 1)),
            );
            us.extend((0..2000).map(|_| rng.random::<f64>()));
            for u in us {
                let plain = d.cdf.partition_point(|&c| c <= u);
                assert_eq!(d.entries_at_most(u), plain, "u = {u}");
            }
        }
        assert!(Distribution1D::new(&[f64::INFINITY, 1.0]).guide.is_empty());
    }

    #[test]
    fn two_d_sample_pdf_invert_round_trip() {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(3);
        let (w, h) = (13, 7);
        let weights: Vec<f64> = (0..w * h)
            .map(|i| if i % 5 == 0 { 0.0 } else { rng.random::<f64>() })
            .collect();
        let d = Distribution2D::new(&weights, w, h);
        let sum: f64 = weights.iter().sum();
        for _ in 0..10_000 {
            let u = [rng.random::<f64>(), rng.random::<f64>()];
            let (p, density) = d.sample_continuous(u).unwrap();
            assert!((d.pdf(p) - density).abs() <= 1e-9 * density);
            let c = (p[0] * w as f64) as usize;
            let r = (p[1] * h as f64) as usize;
            assert!((density - weights[r * w + c] / sum * (w * h) as f64).abs() < 1e-9 * density);
            let back = d.invert(p);
            assert!(
                (back[0] - u[0]).abs() < 1e-9 && (back[1] - u[1]).abs() < 1e-9,
                "{u:?} {back:?}"
            );
        }
    }
}
