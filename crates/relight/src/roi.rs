//! The region of interest after the filtering pass (Lee & Kim 2014, 5.2.1–5.2.2): refined by
//! a breadth-first search from its significant points over the mesh, and its boundary smoothed
//! over two tiers of truncated neighbours.

use crate::adjacency::Adjacency;
use crate::kernel::{rgb, Accum, Measure, BLOCK};
use rayon::prelude::*;

/// ROI refinement (Lee & Kim 2014, 5.2.1): breadth-first from the significant complete points
/// (shaded to the top level or converged), each round evaluates (in parallel) the truncated
/// neighbours of the points that became significant in the previous round with `full` (to the
/// top level, or until converged), and continues from those that are significant
/// (`max_c |D_c| ≥ threshold`). Tested points keep their new value. `full(points, sums,
/// scratch)` continues a block of points in place. Returns (rounds, points tested).
pub(crate) fn refine_roi(
    adjacency: &Adjacency,
    acc: &mut [Accum],
    top: usize,
    threshold: f32,
    measure: Measure,
    full: impl Fn(&[usize], &mut [Accum], &mut Vec<f32>) + Sync,
) -> (usize, usize) {
    let complete = |a: &Accum| a.complete(top);
    let significant =
        |a: &Accum| !a.inactive && a.complete(top) && a.significance_in(measure) >= threshold;
    let mut seeds: Vec<usize> = (0..acc.len()).filter(|&v| significant(&acc[v])).collect();
    let (mut rounds, mut tested) = (0, 0);
    loop {
        let mut frontier: Vec<usize> = seeds
            .iter()
            .flat_map(|&v| adjacency.neighbours(v).iter().map(|&u| u as usize))
            .filter(|&u| !complete(&acc[u]))
            .collect();
        frontier.sort_unstable();
        frontier.dedup();
        if frontier.is_empty() {
            return (rounds, tested);
        }
        rounds += 1;
        tested += frontier.len();
        let snapshot: &[Accum] = acc;
        let evaluated: Vec<Accum> = frontier
            .par_chunks(BLOCK)
            .map_init(Vec::new, |w, pts| {
                let mut a: Vec<Accum> = pts.iter().map(|&v| snapshot[v]).collect();
                full(pts, &mut a, w);
                a
            })
            .flatten_iter()
            .collect();
        seeds.clear();
        for (&v, a) in frontier.iter().zip(evaluated) {
            acc[v] = a;
            if significant(&a) {
                seeds.push(v);
            }
        }
    }
}

/// Boundary smoothing (Lee & Kim 2014, 5.2.2). Sources are the complete points (shaded to the
/// top level, or converged);
/// tier 1 are truncated points next to a source, tier 2 truncated points next to tier 1 (and
/// not in it). The extrapolated correction is the mean correction `D` of the adjacent sources
/// (tier 1) or the mean extrapolated correction of the adjacent tier-1 points (tier 2), and it
/// is blended linearly with the point's own truncated correction, fading out over the two
/// tiers: `D' = ⅔ D̄ + ⅓ D` on tier 1, `D' = ⅓ D̄ + ⅔ D` on tier 2.
/// Returns the new corrections (radiance units) and the tier sizes.
pub(crate) fn smooth_boundary(
    adjacency: &Adjacency,
    acc: &[Accum],
    top: usize,
) -> (Vec<(usize, [f32; 3])>, [usize; 2]) {
    let source = |a: &Accum| !a.inactive && a.complete(top);
    let truncated = |a: &Accum| !a.complete(top);
    let mean_of = |items: &mut dyn Iterator<Item = [f32; 3]>| {
        let (mut s, mut n) = ([0.0f32; 3], 0u32);
        for d in items {
            for c in 0..3 {
                s[c] += d[c];
            }
            n += 1;
        }
        (n > 0).then(|| s.map(|x| x / n as f32))
    };
    // Tier 1, then tier 2 (both pure per-point maps, in parallel; the order of the output
    // and of every mean is fixed, so the result does not depend on the thread count).
    let tier1: Vec<Option<[f32; 3]>> = (0..acc.len())
        .into_par_iter()
        .map(|v| {
            if !truncated(&acc[v]) {
                return None;
            }
            let nb = adjacency.neighbours(v);
            mean_of(
                &mut nb
                    .iter()
                    .map(|&u| &acc[u as usize])
                    .filter(|a| source(a))
                    .map(Accum::correction),
            )
        })
        .collect();
    let new: Vec<Option<(u8, [f32; 3])>> = (0..acc.len())
        .into_par_iter()
        .map(|v| {
            let own = acc[v].correction();
            if let Some(bar) = tier1[v] {
                Some((0, rgb(|c| (2.0 * bar[c] + own[c]) / 3.0)))
            } else if truncated(&acc[v]) {
                let nb = adjacency.neighbours(v);
                mean_of(&mut nb.iter().filter_map(|&u| tier1[u as usize]))
                    .map(|bar| (1, rgb(|c| (bar[c] + 2.0 * own[c]) / 3.0)))
            } else {
                None
            }
        })
        .collect();
    let mut out = Vec::new();
    let mut tiers = [0usize; 2];
    for (v, x) in new.into_iter().enumerate() {
        if let Some((tier, d)) = x {
            tiers[tier as usize] += 1;
            out.push((v, d));
        }
    }
    (out, tiers)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Strip of triangles `[i, i+1, i+2]`: vertex `i` is adjacent to `i±1` and `i±2`.
    fn strip(n: u32) -> Adjacency {
        let tris: Vec<[u32; 3]> = (0..n - 2).map(|i| [i, i + 1, i + 2]).collect();
        Adjacency::from_triangles(n as usize, &tris).unwrap()
    }

    fn acc(last_level: u16, high: f32) -> Accum {
        Accum {
            base: [1.0; 3],
            high: [high; 3],
            scale: [1.0; 3],
            last_level,
            products: 0,
            inactive: false,
            ..Accum::default()
        }
    }

    #[test]
    fn refinement_follows_significant_neighbours() {
        // Top level 5. After filtering only vertex 0 is at full order and significant.
        // Full-order corrections of the others, T = 0.1: 1 → 0.5 (significant), 2 → 0.05 (not),
        // 3 → 0.2 (significant), 4, 5 → 0.01, the rest 0.3 (significant, but unreachable).
        // Round 1 tests N(0) = {1, 2}; round 2 tests N(1) \ tested = {3};
        // round 3 tests N(3) \ tested = {4, 5}; then no significant point is left to expand.
        let adj = strip(12);
        let full_high = [
            1.0, 0.5, 0.05, 0.2, 0.01, 0.01, 0.3, 0.3, 0.3, 0.3, 0.3, 0.3,
        ];
        let mut a: Vec<Accum> = (0..12)
            .map(|v| if v == 0 { acc(5, 1.0) } else { acc(3, 0.0) })
            .collect();
        let (rounds, tested) = refine_roi(&adj, &mut a, 5, 0.1, Measure::Radiance, |pts, a, _| {
            for (&v, x) in pts.iter().zip(a.iter_mut()) {
                *x = acc(5, full_high[v]);
            }
        });
        assert_eq!((rounds, tested), (3, 5));
        let full: Vec<usize> = (0..12).filter(|&v| a[v].last_level == 5).collect();
        assert_eq!(full, vec![0, 1, 2, 3, 4, 5]);
        let sig: Vec<usize> = (0..12)
            .filter(|&v| a[v].last_level == 5 && a[v].significance() >= 0.1)
            .collect();
        assert_eq!(sig, vec![0, 1, 3]);
    }

    #[test]
    fn smoothing_extrapolates_over_two_tiers() {
        // Full order: 0 (D = 1), 1 (D = 3). Truncated, own D = 0 except vertex 4 (D = 0.6).
        // Tier 1 = {2 (sources 0, 1: D̄ = 2), 3 (source 1: D̄ = 3)}.
        // Tier 2 = {4 (tier-1 neighbours 2, 3: D̄ = 2.5), 5 (tier-1 neighbour 3: D̄ = 3)}.
        // D' = ⅔ D̄ + ⅓ D on tier 1, ⅓ D̄ + ⅔ D on tier 2.
        let adj = strip(9);
        let mut a: Vec<Accum> = (0..9).map(|_| acc(3, 0.0)).collect();
        a[0] = acc(5, 1.0);
        a[1] = acc(5, 3.0);
        a[4] = acc(4, 0.6);
        let (out, tiers) = smooth_boundary(&adj, &a, 5);
        assert_eq!(tiers, [2, 2]);
        let expect = [(2, 4.0 / 3.0), (3, 2.0), (4, 2.5 / 3.0 + 0.4), (5, 1.0)];
        assert_eq!(out.len(), expect.len());
        for ((v, d), (ev, ed)) in out.iter().zip(expect) {
            assert_eq!(*v, ev);
            for c in d {
                assert!((c - ed).abs() < 1e-6, "vertex {v}: {c} vs {ed}");
            }
        }
    }
}
