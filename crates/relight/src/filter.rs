//! The adaptive path's filtering pass (Lee & Kim 2014, Algorithms 1–3): both terms shaded
//! block by block in one sweep over the points, each block's radiance, ROI flags and counts
//! taken while its sums are in cache ([`filter_pass`], [`tally`]).

use crate::kernel::{rgb, Accum, Measure, Stop, BLOCK, CHUNK};
use crate::levels::BlockLevels;
use rayon::prelude::*;

/// Counts of one term's points after shading (see [`tally`]).
#[derive(Clone, Debug, Default)]
pub(crate) struct Tally {
    /// `[l]`: active points whose last level is `l`.
    pub(crate) at_level: Vec<usize>,
    pub(crate) active: usize,
    /// Active points shaded to the top level.
    pub(crate) full: usize,
    /// Active points converged below the top level.
    pub(crate) converged: usize,
    /// Points truncated by significance (neither complete nor inactive).
    pub(crate) truncated: usize,
    /// Points in the ROI: significant and complete.
    pub(crate) roi: usize,
    /// Bands shaded, summed over active points.
    pub(crate) bands: u64,
    /// Coefficient products, all points.
    pub(crate) products: u64,
}

impl Tally {
    fn new(top: usize) -> Self {
        Self {
            at_level: vec![0; top + 1],
            ..Self::default()
        }
    }

    fn merge(mut self, other: Self) -> Self {
        if self.at_level.len() < other.at_level.len() {
            self.at_level.resize(other.at_level.len(), 0);
        }
        for (a, b) in self.at_level.iter_mut().zip(&other.at_level) {
            *a += b;
        }
        self.active += other.active;
        self.full += other.full;
        self.converged += other.converged;
        self.truncated += other.truncated;
        self.roi += other.roi;
        self.bands += other.bands;
        self.products += other.products;
        self
    }
}

/// Radiance, ROI flag and counts of a run of points (see [`tally`]).
fn tally_into(
    acc: &[Accum],
    out: &mut [[f32; 3]],
    roi: &mut [bool],
    t: &mut Tally,
    top: usize,
    threshold: f32,
    measure: Measure,
) {
    for ((o, r), a) in out.iter_mut().zip(roi.iter_mut()).zip(acc) {
        *o = a.radiance();
        t.products += a.products;
        if a.inactive {
            *r = false;
            continue;
        }
        t.active += 1;
        t.at_level[a.last_level as usize] += 1;
        t.bands += u64::from(a.last_level) + 1;
        if a.last_level as usize == top {
            t.full += 1;
        } else if a.converged {
            t.converged += 1;
        } else {
            t.truncated += 1;
        }
        *r = a.complete(top) && a.is_significant(threshold, measure);
        t.roi += usize::from(*r);
    }
}

/// One parallel pass over a term's sums: each point's radiance, whether it is in the ROI
/// (significant and complete: shaded to the top level or converged) and the counts of the
/// frame statistics. Integer counts merged in any order give the same totals, so the result
/// does not depend on the thread count.
pub(crate) fn tally(
    acc: &[Accum],
    top: usize,
    threshold: f32,
    measure: Measure,
) -> (Vec<[f32; 3]>, Vec<bool>, Tally) {
    let mut out = vec![[0.0f32; 3]; acc.len()];
    let mut roi = vec![false; acc.len()];
    let tally = out
        .par_chunks_mut(CHUNK)
        .zip(roi.par_chunks_mut(CHUNK))
        .zip(acc.par_chunks(CHUNK))
        .map(|((out, roi), acc)| {
            let mut t = Tally::new(top);
            tally_into(acc, out, roi, &mut t, top, threshold, measure);
            t
        })
        .reduce(|| Tally::new(top), Tally::merge);
    (out, roi, tally)
}

/// What the filtering pass leaves per term.
pub(crate) struct Filtered {
    /// Every point's sums, if kept for refinement (empty otherwise).
    pub(crate) acc: Vec<Accum>,
    /// Radiance per point.
    pub(crate) radiance: Vec<[f32; 3]>,
    /// ROI flag per point.
    pub(crate) roi: Vec<bool>,
    /// Counts.
    pub(crate) tally: Tally,
}

/// The filtering pass over both terms, block by block (each block's transfers are read once,
/// while in cache): the diffuse base, the specular term (on the display against the diffuse
/// base), then the diffuse levels (on the display against the specular value); then each
/// block's radiance, ROI flags and counts while its sums are in cache. `bases` are precomputed
/// bases (relative threshold), else the bases are computed here. The sums of every point are
/// kept only with `keep` (refinement and smoothing need them); otherwise they live one block at
/// a time on the stack.
#[allow(clippy::too_many_arguments)]
pub(crate) fn filter_pass(
    points: usize,
    terms: [Option<&dyn BlockLevels>; 2],
    mut bases: [Option<Vec<Accum>>; 2],
    b: usize,
    top: usize,
    filter: Stop<'_>,
    seen_together: bool,
    keep: bool,
    threshold: f32,
) -> [Option<Filtered>; 2] {
    let fresh = [bases[0].is_none(), bases[1].is_none()];
    let present = [terms[0].is_some(), terms[1].is_some()];
    let sized = |k: usize, n: usize| if present[k] { n } else { 0 };
    let mut acc: [Vec<Accum>; 2] = [0, 1].map(|k| match bases[k].take() {
        Some(v) => v,
        None if keep => vec![Accum::default(); sized(k, points)],
        None => Vec::new(),
    });
    let mut radiance: [Vec<[f32; 3]>; 2] = [0, 1].map(|k| vec![[0.0f32; 3]; sized(k, points)]);
    let mut roi: [Vec<bool>; 2] = [0, 1].map(|k| vec![false; sized(k, points)]);
    let chunks = points.div_ceil(CHUNK);
    fn split<T>(v: &mut [T], chunks: usize) -> Vec<Option<&mut [T]>> {
        if v.is_empty() {
            (0..chunks).map(|_| None).collect()
        } else {
            v.chunks_mut(CHUNK).map(Some).collect()
        }
    }
    let pass = Pass {
        terms,
        fresh,
        present,
        b,
        top,
        filter,
        seen_together,
        threshold,
        points,
    };
    let [ad, asp] = &mut acc;
    let [rd, rs] = &mut radiance;
    let [od, os] = &mut roi;
    let work: Vec<_> = split(ad, chunks)
        .into_iter()
        .zip(split(asp, chunks))
        .zip(split(rd, chunks).into_iter().zip(split(rs, chunks)))
        .zip(split(od, chunks).into_iter().zip(split(os, chunks)))
        .collect();
    let tallies = work
        .into_par_iter()
        .enumerate()
        .map_init(Vec::new, |scratch, (ci, ((kept, rad), flags))| {
            let out = ChunkOut {
                kept: [kept.0, kept.1],
                shown: Shown {
                    radiance: [rad.0, rad.1],
                    roi: [flags.0, flags.1],
                },
            };
            pass.chunk(scratch, ci, out)
        })
        .reduce(
            || [Tally::new(top), Tally::new(top)],
            |[a0, a1], [b0, b1]| [a0.merge(b0), a1.merge(b1)],
        );
    let [t0, t1] = tallies;
    let [a0, a1] = acc;
    let [r0, r1] = radiance;
    let [o0, o1] = roi;
    [(a0, r0, o0, t0), (a1, r1, o1, t1)]
        .into_iter()
        .enumerate()
        .map(|(k, (acc, radiance, roi, tally))| {
            present[k].then_some(Filtered {
                acc,
                radiance,
                roi,
                tally,
            })
        })
        .collect::<Vec<_>>()
        .try_into()
        .unwrap_or_else(|_| unreachable!("two terms"))
}

/// What every chunk and block of one filtering pass shares (see [`filter_pass`]).
struct Pass<'a> {
    /// `[diffuse, specular]`, either absent.
    terms: [Option<&'a dyn BlockLevels>; 2],
    /// Per term: whether its sums start from the base in the pass (no precomputed bases).
    fresh: [bool; 2],
    /// Per term: whether it is shaded.
    present: [bool; 2],
    /// The base order.
    b: usize,
    top: usize,
    /// The filtering rules.
    filter: Stop<'a>,
    /// Whether the terms are tested on the display together (each against the other).
    seen_together: bool,
    threshold: f32,
    points: usize,
}

/// One chunk's share of each term's outputs: the kept sums (`None`: not kept, or the term is
/// absent), radiance and ROI flags.
struct ChunkOut<'s> {
    kept: [Option<&'s mut [Accum]>; 2],
    shown: Shown<'s>,
}

/// One chunk's share of each term's radiance and ROI flags (`None`: the term is absent).
struct Shown<'s> {
    radiance: [Option<&'s mut [[f32; 3]]>; 2],
    roi: [Option<&'s mut [bool]>; 2],
}

impl Pass<'_> {
    /// Shades chunk `ci` block by block (sums not kept live one block at a time on the
    /// stack); returns the chunk's counts per term.
    fn chunk(&self, scratch: &mut Vec<f32>, ci: usize, mut out: ChunkOut<'_>) -> [Tally; 2] {
        let (top, present) = (self.top, self.present);
        let mut tallies = [Tally::new(top), Tally::new(top)];
        let first = ci * CHUNK;
        let len = CHUNK.min(self.points - first);
        let mut local = [[Accum::default(); BLOCK]; 2];
        for lo in (0..len).step_by(BLOCK) {
            let hi = (lo + BLOCK).min(len);
            let n = hi - lo;
            let pts: [usize; BLOCK] = std::array::from_fn(|i| first + lo + i);
            let pts = &pts[..n];
            let [kd, ks] = &mut out.kept;
            let [ld, ls] = &mut local;
            let db: Option<&mut [Accum]> = present[0].then_some(match kd {
                Some(x) => &mut x[lo..hi],
                None => &mut ld[..n],
            });
            let sb: Option<&mut [Accum]> = present[1].then_some(match ks {
                Some(x) => &mut x[lo..hi],
                None => &mut ls[..n],
            });
            self.block(scratch, pts, lo..hi, [db, sb], &mut out.shown, &mut tallies);
        }
        tallies
    }

    /// Shades one block of points `pts` (at `range` of the chunk) with sums `[db, sb]`: the
    /// diffuse base when the specular test needs it, the specular term, then the diffuse
    /// levels, each term's radiance, ROI flags and counts taken right after it.
    fn block(
        &self,
        scratch: &mut Vec<f32>,
        pts: &[usize],
        range: std::ops::Range<usize>,
        [mut db, sb]: [Option<&mut [Accum]>; 2],
        shown: &mut Shown<'_>,
        tallies: &mut [Tally; 2],
    ) {
        let (rad, flags) = (&mut shown.radiance, &mut shown.roi);
        let (terms, fresh, seen_together) = (self.terms, self.fresh, self.seen_together);
        let (top, filter, threshold, measure) =
            (self.top, self.filter, self.threshold, self.filter.measure);
        let (lo, hi, n) = (range.start, range.end, pts.len());
        // The diffuse base first only when the specular test needs it (seen together on
        // the display); otherwise the diffuse term goes in one call below.
        if let (Some(eval), Some(db)) = (terms[0], db.as_deref_mut()) {
            if fresh[0] && seen_together {
                eval.shade(pts, db, true, self.b - 1, Stop::NEVER, None, scratch);
            }
        }
        let mut spec_value = [[0.0f32; 3]; BLOCK];
        if let (Some(eval), Some(sb)) = (terms[1], sb) {
            let mut base = [[0.0f32; 3]; BLOCK];
            let offsets = match (&db, seen_together) {
                (Some(db), true) => {
                    for (o, a) in base.iter_mut().zip(db.iter()) {
                        *o = rgb(|c| a.scale[c] * a.base[c]);
                    }
                    Some(&base[..n])
                }
                _ => None,
            };
            eval.shade(pts, sb, fresh[1], top, filter, offsets, scratch);
            if seen_together {
                for (o, a) in spec_value.iter_mut().zip(sb.iter()) {
                    *o = a.radiance();
                }
            }
            if let (Some(r), Some(f)) = (rad[1].as_deref_mut(), flags[1].as_deref_mut()) {
                let (r, f) = (&mut r[lo..hi], &mut f[lo..hi]);
                tally_into(sb, r, f, &mut tallies[1], top, threshold, measure);
            }
        }
        if let (Some(eval), Some(db)) = (terms[0], db) {
            let offsets = seen_together.then_some(&spec_value[..n]);
            let start = fresh[0] && !seen_together;
            eval.shade(pts, db, start, top, filter, offsets, scratch);
            if let (Some(r), Some(f)) = (rad[0].as_deref_mut(), flags[0].as_deref_mut()) {
                let (r, f) = (&mut r[lo..hi], &mut f[lo..hi]);
                tally_into(db, r, f, &mut tallies[0], top, threshold, measure);
            }
        }
    }
}

/// Runs `f(points, sums, scratch)` over every point in parallel blocks of [`BLOCK`] points,
/// from default sums.
pub(crate) fn evaluate_all(
    points: usize,
    f: impl Fn(&[usize], &mut [Accum], &mut Vec<f32>) + Sync,
) -> Vec<Accum> {
    let mut acc = vec![Accum::default(); points];
    acc.par_chunks_mut(CHUNK)
        .enumerate()
        .for_each_init(Vec::new, |scratch, (ci, chunk)| {
            for (bi, block) in chunk.chunks_mut(BLOCK).enumerate() {
                let first = ci * CHUNK + bi * BLOCK;
                let pts: Vec<usize> = (first..first + block.len()).collect();
                f(&pts, block, scratch);
            }
        });
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Mutex;

    /// One call of a term: the points, whether fresh, the level asked for and the offsets.
    type Call = (Vec<usize>, bool, usize, Option<Vec<[f32; 3]>>);

    /// A synthetic term: point `p`'s base is `base · p` (scale `scale`), and every level above
    /// the base adds 1 to `high` at once; it records its calls.
    struct Fake {
        base: f32,
        scale: f32,
        b: usize,
        calls: Mutex<Vec<Call>>,
    }

    impl Fake {
        fn new(base: f32, scale: f32, b: usize) -> Self {
            Self {
                base,
                scale,
                b,
                calls: Mutex::new(Vec::new()),
            }
        }
    }

    impl BlockLevels for Fake {
        fn shade(
            &self,
            pts: &[usize],
            accs: &mut [Accum],
            fresh: bool,
            to: usize,
            _: Stop<'_>,
            offsets: Option<&[[f32; 3]]>,
            _: &mut Vec<f32>,
        ) {
            assert!(pts.len() <= BLOCK && pts.len() == accs.len());
            for (&p, acc) in pts.iter().zip(accs.iter_mut()) {
                if fresh {
                    *acc = Accum {
                        base: [self.base * p as f32; 3],
                        scale: [self.scale; 3],
                        last_level: (self.b - 1) as u16,
                        ..Accum::default()
                    };
                }
                if to > acc.last_level as usize {
                    acc.high = [1.0; 3];
                    acc.last_level = to as u16;
                    acc.products += 10;
                }
            }
            let offsets = offsets.map(<[_]>::to_vec);
            self.calls
                .lock()
                .unwrap()
                .push((pts.to_vec(), fresh, to, offsets));
        }
    }

    #[test]
    fn the_pass_shades_every_point_once_per_term_in_blocks_within_chunks() {
        // 600 points: three chunks (256, 256, 88), blocks of at most 32 inside each.
        let (points, b, top) = (600, 3, 5);
        let diffuse = Fake::new(1.0, 1.0, b);
        let specular = Fake::new(2.0, 0.5, b);
        let stop = Stop::NEVER;
        let [d, s] = filter_pass(
            points,
            [Some(&diffuse), Some(&specular)],
            [None, None],
            b,
            top,
            stop,
            false,
            false,
            0.75,
        );
        let (d, s) = (d.unwrap(), s.unwrap());
        for (calls, out, value, roi) in [
            (&diffuse.calls, &d, 1.0, true),
            (&specular.calls, &s, 0.5, false),
        ] {
            let calls = calls.lock().unwrap();
            let mut seen: Vec<usize> = calls.iter().flat_map(|c| c.0.clone()).collect();
            seen.sort_unstable();
            assert_eq!(seen, (0..points).collect::<Vec<_>>());
            for (pts, fresh, to, offsets) in calls.iter() {
                assert!(*fresh && *to == top && offsets.is_none());
                assert_eq!(pts[0] / CHUNK, pts[pts.len() - 1] / CHUNK, "{pts:?}");
            }
            // Radiance p + 1 (diffuse) and 0.5 (2p + 1) (specular); the corrections 1 and 0.5
            // against the threshold 0.75.
            for (p, r) in out.radiance.iter().enumerate() {
                assert_eq!(r[0], p as f32 + value);
            }
            assert!(out.roi.iter().all(|&r| r == roi));
            assert!(out.acc.is_empty(), "sums not kept");
            let t = &out.tally;
            assert_eq!(
                (t.active, t.full, t.truncated, t.converged),
                (points, points, 0, 0)
            );
            assert_eq!(
                (t.roi, t.at_level[top]),
                (if roi { points } else { 0 }, points)
            );
            assert_eq!(
                (t.bands, t.products),
                (6 * points as u64, 10 * points as u64)
            );
        }
    }

    #[test]
    fn on_the_display_each_term_is_tested_against_the_other() {
        // Seen together: the diffuse base first, then the specular levels against it, then
        // the diffuse levels against the specular value; the sums kept.
        let (points, b, top) = (40, 3, 5);
        let diffuse = Fake::new(1.0, 1.0, b);
        let specular = Fake::new(2.0, 0.5, b);
        let [d, s] = filter_pass(
            points,
            [Some(&diffuse), Some(&specular)],
            [None, None],
            b,
            top,
            Stop::NEVER,
            true,
            true,
            0.75,
        );
        assert_eq!(d.unwrap().acc.len(), points);
        assert_eq!(s.unwrap().acc.len(), points);
        let dc = diffuse.calls.lock().unwrap();
        let sc = specular.calls.lock().unwrap();
        // Two blocks (32 + 8): per block a base call and a continuation of the diffuse term.
        assert_eq!((dc.len(), sc.len()), (4, 2));
        for (k, call) in sc.iter().enumerate() {
            let base = &dc[2 * k];
            assert!(base.1 && base.2 == b - 1 && base.3.is_none());
            let offsets = call.3.as_ref().unwrap();
            for (&p, o) in call.0.iter().zip(offsets) {
                assert_eq!(*o, [p as f32; 3], "the diffuse base");
            }
            let rest = &dc[2 * k + 1];
            assert!(!rest.1 && rest.2 == top);
            for (&p, o) in rest.0.iter().zip(rest.3.as_ref().unwrap()) {
                assert_eq!(*o, [p as f32 + 0.5; 3], "the specular value");
            }
        }
    }

    #[test]
    fn tallies_count_each_kind_of_point_and_merge_in_any_order() {
        let top = 5;
        let point = |last_level: u16, high: f32| Accum {
            scale: [1.0; 3],
            high: [high; 3],
            last_level,
            products: 7,
            ..Accum::default()
        };
        let acc = [
            point(5, 1.0), // full order, significant
            point(5, 0.1), // full order
            Accum {
                converged: true,
                ..point(4, 1.0) // converged, significant
            },
            point(3, 1.0), // truncated
            Accum {
                inactive: true,
                ..point(5, 1.0) // inactive: radiance but no count
            },
        ];
        let (radiance, roi, t) = tally(&acc, top, 0.5, Measure::Radiance);
        assert_eq!(roi, [true, false, true, false, false]);
        assert_eq!(radiance[3], [1.0; 3]);
        assert_eq!(
            (t.active, t.full, t.converged, t.truncated, t.roi),
            (4, 2, 1, 1, 2)
        );
        assert_eq!(t.at_level, [0, 0, 0, 1, 1, 2]);
        assert_eq!((t.bands, t.products), (6 + 6 + 5 + 4, 35));
        let mut parts = [Tally::new(top), Tally::new(top)];
        let (mut r, mut f) = ([[0.0; 3]; 5], [false; 5]);
        tally_into(
            &acc[..2],
            &mut r[..2],
            &mut f[..2],
            &mut parts[0],
            top,
            0.5,
            Measure::Radiance,
        );
        tally_into(
            &acc[2..],
            &mut r[2..],
            &mut f[2..],
            &mut parts[1],
            top,
            0.5,
            Measure::Radiance,
        );
        let [a, b] = parts;
        let merged = b.clone().merge(a.clone());
        assert_eq!(format!("{:?}", a.merge(b)), format!("{merged:?}"));
        assert_eq!(merged.at_level, t.at_level);
        assert_eq!((merged.roi, merged.products), (t.roi, t.products));
    }
}
