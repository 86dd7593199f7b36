//! Locally adaptive relighting (Lee & Kim 2014, chapter 5): base bands everywhere, higher bands
//! only in a region of interest (ROI) found level by level, refined by a breadth-first search
//! and with its boundary smoothed over two tiers of neighbours.

use crate::adjacency::Adjacency;
use crate::error::RelightError;
use crate::input::{DiffuseParams, SpecularInput, TransferView};
use crate::kernel::{level_costs, prefetch, rgb, Accum, Measure, Stop, Term, BLOCK, CHUNK};
use crate::relighter::{check_finite3, specular_point, FrameLighting, Relighter};
use crate::MAX_FITTED_LOBES;
use prt_sh::MAX_GAUNT_ORDER;
use rayon::prelude::*;
use serde::Serialize;
use std::time::Instant;

/// The threshold `T` of the stopping tests ([`StopRule`]): on the accumulated high-order
/// difference `D` of a point, or on the change of its last two levels.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub enum Threshold {
    /// `T` in units of output radiance. Lee & Kim use `T = 0.02` on colours normalised to
    /// `[0, 1]` from 8 bits (5.2.2), i.e. `Absolute(0.02)` when radiance 1 is displayed white
    /// (exposure 0, before the sRGB curve).
    Absolute(f32),
    /// `T = factor × ` the frame's mean base radiance (over points and channels, diffuse plus
    /// specular, bands `0..3` — the only frame-wide figure known before the adaptive levels).
    RelativeToMean(f32),
    /// `t` on the display, in the units of the 8-bit view normalised to [0, 1] (CONVENTIONS:
    /// radiance times `2^exposure_ev`, clamped to [0, 1], sRGB curve; one 8-bit step is
    /// 1/255): a change counts by how much it changes the shown colour, so changes above white
    /// count for nothing and changes in the dark count more. This is the reading of the
    /// thesis' "T = 0.02 on 8-bit normalised values" closest to what `psnr_ldr` measures. The
    /// shown colour is diffuse plus specular: the specular term is filtered against the diffuse
    /// base, then the diffuse term against the final specular.
    Display {
        /// `T`, as a fraction of the display range.
        t: f32,
        /// Exposure of the display, stops.
        exposure_ev: f32,
    },
}

impl Threshold {
    /// How the tests measure changes.
    fn measure(self) -> Measure {
        match self {
            Self::Display { exposure_ev, .. } => Measure::Display {
                scale: exposure_ev.exp2(),
            },
            _ => Measure::Radiance,
        }
    }
}

/// The largest accepted [`AdaptiveParams::cost_exponent`] (at 4 the specular test deciding level 6
/// already asks for a change of 7.4 T, and the one deciding level 10 for 2 300 T).
pub const MAX_COST_EXPONENT: f32 = 4.0;

/// Parameters of the adaptive path.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct AdaptiveParams {
    /// The ROI threshold.
    pub threshold: Threshold,
    /// Refine the ROI by breadth-first search over neighbours (5.2.1).
    pub refine: bool,
    /// Smooth the ROI boundary over two tiers of neighbours (5.2.2).
    pub smooth: bool,
    /// When a point stops adding levels.
    pub stop: StopRule,
    /// How the convergence threshold grows with the price of the next level, `α ≥ 0`: the test
    /// after level `l` compares the change of the last two levels with
    /// `T · (c(l + 1) / c(5))^α`, `c(k)` being the term's coefficient products of level `k`
    /// (diffuse `3(2k + 1)`, specular `3(2k + 1)((k + 1)² + k²)`). The first test (after level
    /// 4) is against `T` itself; a later level is paid for only by a change that grows with
    /// its price — a specular level 9 costs 5.1× level 5. `α = 1` (recommended): change per
    /// product, the marginal rule for absolute error; `α = 1/2`: squared change per product,
    /// the marginal rule for squared error; `α = 0`: the same `T` at every level. Only the
    /// convergence test is scaled (not the significance test of Algorithm 1).
    pub cost_exponent: f32,
}

/// When a point stops adding levels (each test is made after every level above the base).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum StopRule {
    /// Lee & Kim's Algorithm 1: stop after the first level where the accumulated high-order
    /// difference from the base is insignificant, `max_c |D_c| < T` (the point leaves the ROI).
    /// Points whose difference stays significant go on to the target order.
    Significance,
    /// Stop once the last two levels together changed the point's value by less than `T`
    /// (`max_c scale_c (|δ_l,c| + |δ_l−1,c|) < T`, from level 4 on): the value has converged and
    /// the remaining bands are estimated to matter less than `T`. Two levels, because one band
    /// alone can vanish while the next does not (the clamped cosine has no odd bands ≥ 3).
    /// Nothing is truncated by significance, so refinement and smoothing have nothing to do.
    Convergence,
    /// Whichever of the two comes first; refinement continues the insignificant points
    /// until they converge.
    Either,
}

impl StopRule {
    /// The kernel's stopping rules for threshold `t` in the filtering pass and in refinement.
    pub(crate) fn rules(self, t: f32, measure: Measure) -> (Stop<'static>, Stop<'static>) {
        let converged = matches!(self, Self::Convergence | Self::Either).then_some(t);
        let insignificant = matches!(self, Self::Significance | Self::Either).then_some(t);
        (
            Stop {
                insignificant,
                converged,
                level_scale: &[],
                measure,
            },
            Stop {
                insignificant: None,
                converged,
                level_scale: &[],
                measure,
            },
        )
    }
}

impl AdaptiveParams {
    /// The recommended setting for threshold `threshold`: [`StopRule::Convergence`] (each
    /// point gets its own order, level by level, and stops once its value has settled), with
    /// refinement and smoothing on (they act only on points truncated by significance, so
    /// they matter with [`StopRule::Either`] or [`StopRule::Significance`]).
    #[must_use]
    pub const fn new(threshold: Threshold) -> Self {
        Self {
            threshold,
            refine: true,
            smooth: true,
            stop: StopRule::Convergence,
            cost_exponent: 1.0,
        }
    }

    /// The thesis' setting: `T = 0.02` absolute, [`StopRule::Significance`], refinement and
    /// smoothing on.
    #[must_use]
    pub const fn thesis() -> Self {
        Self {
            threshold: Threshold::Absolute(0.02),
            refine: true,
            smooth: true,
            stop: StopRule::Significance,
            cost_exponent: 0.0,
        }
    }

    /// `T = 0`: every point keeps every band; the result equals the full-order one bit for bit.
    #[must_use]
    pub const fn exact() -> Self {
        Self {
            threshold: Threshold::Absolute(0.0),
            refine: true,
            smooth: true,
            stop: StopRule::Either,
            cost_exponent: 0.0,
        }
    }
}

/// The inputs of one adaptive frame; either term may be absent.
#[derive(Clone, Copy, Debug)]
pub struct AdaptiveInput<'a> {
    /// Diffuse transfer and material.
    pub diffuse: Option<(TransferView<'a>, DiffuseParams)>,
    /// Specular visibility, geometry, viewer and material.
    pub specular: Option<SpecularInput<'a>>,
    /// Vertex adjacency of the mesh (same vertex count as the transfers).
    pub adjacency: &'a Adjacency,
}

/// Per-term statistics of one frame (fractions are of the term's active points: all points
/// for diffuse, points facing the viewer for specular).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct TermStats {
    /// Points evaluated (specular: facing the viewer).
    pub active_points: usize,
    /// `[l]`: fraction whose filtering pass (Algorithm 1, before refinement) evaluated band `l`.
    pub level_fraction: Vec<f64>,
    /// Fraction significant at full order after the filtering pass (the initial ROI).
    pub initial_roi_fraction: f64,
    /// Fraction significant at full order after refinement (the final ROI).
    pub roi_fraction: f64,
    /// Fraction shaded up to the top level in the end (ROI plus neighbours tested by the
    /// refinement, less the points that converged earlier).
    pub full_order_fraction: f64,
    /// Fraction whose value converged below the top level ([`StopRule::Convergence`]).
    pub converged_fraction: f64,
    /// `1 − full_order_fraction`: the thesis' "filtering ratio" (Table 6.1).
    pub filtered_out_fraction: f64,
    /// Mean number of bands shaded per active point (the order a point ended at, averaged).
    pub mean_order: f64,
    /// Points tested at full order by the refinement.
    pub refined_points: usize,
    /// Breadth-first rounds of the refinement.
    pub refinement_rounds: usize,
    /// Points given an extrapolated correction in the first / second tier.
    pub smoothed_points: [usize; 2],
    /// Coefficient products (multiply–adds) spent, the deterministic proxy for time.
    pub products: u64,
    /// Products the full-order path spends on the same points.
    pub full_order_products: u64,
    /// Wall time of this term, seconds.
    pub seconds: f64,
}

/// Statistics of one adaptive frame.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct FrameStats {
    /// SH order.
    pub order: usize,
    /// Number of points.
    pub points: usize,
    /// The absolute threshold applied (after resolving [`Threshold::RelativeToMean`]).
    pub threshold: f32,
    /// Diffuse term, if shaded.
    pub diffuse: Option<TermStats>,
    /// Specular term, if shaded.
    pub specular: Option<TermStats>,
    /// Wall time of the whole adaptive shading of the frame, seconds.
    pub seconds: f64,
}

/// Result of [`Relighter::adaptive`]: radiance per point (empty for an absent term) and stats.
#[derive(Clone, Debug)]
pub struct AdaptiveFrame {
    /// Diffuse radiance per point.
    pub diffuse: Vec<[f32; 3]>,
    /// Specular radiance per point.
    pub specular: Vec<[f32; 3]>,
    /// Per point, whether it ended in the region of interest (significant at full order after
    /// refinement): `[diffuse, specular]`, empty for an absent term (Figure 6.3(d) of the thesis).
    pub roi: [Vec<bool>; 2],
    /// Frame statistics.
    pub stats: FrameStats,
}

/// Points ahead whose full rows are hinted into cache in the second pass of a block.
const PREFETCH_DISTANCE: usize = 3;
/// Floats of a full row hinted (per channel): through band 7 (`8² = 64`), the levels most of
/// the points that go on past the low bands reach.
const AHEAD_FLOATS: usize = 64;

/// Evaluates a block of at most [`BLOCK`] points in place: `(points, sums, fresh, last level, stopping rules,
/// offsets, scratch)`; with `fresh` the sums are started from the base, otherwise continued;
/// `offsets[k]` (if given) is what the display shows besides this term at point `k` of the
/// block.
type Eval<'a> = dyn Fn(&[usize], &mut [Accum], bool, usize, Stop<'_>, Option<&[[f32; 3]]>, &mut Vec<f32>)
    + Sync
    + 'a;

impl Relighter {
    /// Shades one frame adaptively (Lee & Kim 2014, Algorithms 1–3, 5.2.1, 5.2.2), diffuse and
    /// specular with separate ROIs. With threshold 0 the result is bit-identical to
    /// [`Relighter::diffuse`] and [`Relighter::specular`].
    pub fn adaptive(
        &self,
        input: &AdaptiveInput<'_>,
        frame: &FrameLighting,
        params: &AdaptiveParams,
    ) -> Result<AdaptiveFrame, RelightError> {
        let start = Instant::now();
        self.check_frame(frame)?;
        let top = self.order() - 1;
        let b = crate::BASE_ORDER.min(self.order());
        let mut counts: Vec<(&'static str, usize)> = Vec::new();
        if let Some((t, p)) = &input.diffuse {
            self.check_transfer(t, "diffuse transfer")?;
            check_finite3(p.albedo_over_pi, "albedo/π")?;
            counts.push(("diffuse transfer", t.point_count()));
        }
        if let Some(s) = &input.specular {
            counts.push(("specular visibility", self.check_specular(s)?));
        }
        counts.push(("adjacency", input.adjacency.vertex_count()));
        let points = counts[0].1;
        if let Some(&(what, got)) = counts.iter().find(|c| c.1 != points) {
            return Err(RelightError::PointCount {
                what,
                expected: points,
                got,
            });
        }
        let (t_raw, relative) = match params.threshold {
            Threshold::Absolute(t) | Threshold::Display { t, .. } => (t, false),
            Threshold::RelativeToMean(t) => (t, true),
        };
        if t_raw.is_nan() || t_raw < 0.0 || t_raw.is_infinite() {
            return Err(RelightError::InvalidParameter(format!(
                "threshold {t_raw} must be finite and ≥ 0"
            )));
        }
        if let Threshold::Display { exposure_ev, .. } = params.threshold {
            if !exposure_ev.is_finite() || exposure_ev.abs() > 64.0 {
                return Err(RelightError::InvalidParameter(format!(
                    "display exposure {exposure_ev} EV must be finite and within ±64 stops"
                )));
            }
        }
        let alpha = params.cost_exponent;
        if !(0.0..=MAX_COST_EXPONENT).contains(&alpha) {
            return Err(RelightError::InvalidParameter(format!(
                "cost exponent {alpha} must be within [0, {MAX_COST_EXPONENT}]"
            )));
        }
        let measure = params.threshold.measure();
        let display = matches!(measure, Measure::Display { .. });

        let n2 = self.order() * self.order();
        let low_top = crate::LOW_ORDER.min(self.order()) - 1;
        let diffuse_eval = input.diffuse.as_ref().map(|(t, p)| {
            let kernel = self.diffuse_kernel(frame);
            let (t, scale) = (*t, p.albedo_over_pi);
            let costs = level_costs(Term::Diffuse, self.order(), alpha);
            move |pts: &[usize],
                  accs: &mut [Accum],
                  fresh: bool,
                  to: usize,
                  stop: Stop<'_>,
                  offsets: Option<&[[f32; 3]]>,
                  _: &mut Vec<f32>| {
                let stop = stop.with_level_scale(&costs);
                // Two passes: the low bands of every point from the compact copy, then the
                // points that go on from their full rows, each row hinted into cache a few
                // points ahead (see `kernel::prefetch`).
                let mut go_on = [0usize; BLOCK];
                let mut n = 0;
                for (k, (&v, acc)) in pts.iter().zip(accs.iter_mut()).enumerate() {
                    let low = t.low_point(v);
                    if fresh {
                        *acc = kernel.base(low, t.channels, scale);
                    }
                    if let Some(o) = offsets {
                        acc.offset = o[k];
                    }
                    let mut stopped = false;
                    if (acc.last_level as usize) < low_top {
                        stopped = kernel.extend(acc, low, t.channels, to.min(low_top), stop);
                    }
                    if !stopped && to > acc.last_level as usize {
                        go_on[n] = k;
                        n += 1;
                    }
                }
                let hint = |k: usize| {
                    let row = t.point(pts[k]);
                    let n2 = row.len() / t.channels;
                    for c in 0..t.channels {
                        prefetch(&row[c * n2..(c + 1) * n2], AHEAD_FLOATS);
                    }
                };
                go_on[..n]
                    .iter()
                    .take(PREFETCH_DISTANCE)
                    .for_each(|&k| hint(k));
                for (i, &k) in go_on[..n].iter().enumerate() {
                    if let Some(&next) = go_on[..n].get(i + PREFETCH_DISTANCE) {
                        hint(next);
                    }
                    kernel.extend(&mut accs[k], t.point(pts[k]), t.channels, to, stop);
                }
            }
        });
        let specular_eval = match &input.specular {
            None => None,
            Some(s) => {
                let kernel = self.specular_kernel(frame)?;
                let lobe = self.lobe(&s.lobe)?;
                let order = self.order();
                let s = *s;
                let costs = level_costs(Term::Specular, self.order(), alpha);
                Some(
                    move |pts: &[usize],
                          accs: &mut [Accum],
                          fresh: bool,
                          to: usize,
                          stop: Stop<'_>,
                          offsets: Option<&[[f32; 3]]>,
                          w: &mut Vec<f32>| {
                        let stop = stop.with_level_scale(&costs);
                        w.resize(n2, 0.0);
                        // Two passes as for diffuse: the low bands (weights and visibility) of
                        // every point, then the points that go on, rows hinted ahead.
                        let mut go_on = [0usize; BLOCK];
                        let mut rows = [[0.0; MAX_GAUNT_ORDER]; MAX_FITTED_LOBES];
                        // Phong's one axis per point going on (its lobe row is shared).
                        let mut axis0 = [glam::Vec3::ZERO; BLOCK];
                        // The low weights of the points that go on, for their second pass.
                        let low_len = (low_top + 1) * (low_top + 1);
                        let mut low_w = [[0.0f32; 25]; BLOCK];
                        let mut n = 0;
                        for (k, (&v, acc)) in pts.iter().zip(accs.iter_mut()).enumerate() {
                            let g = specular_point(&s, v, &lobe, order, &mut rows);
                            if !g.active {
                                *acc = Accum {
                                    last_level: top as u16,
                                    inactive: true,
                                    ..Accum::default()
                                };
                                continue;
                            }
                            self.point_weights_low(&g, w);
                            let low = s.visibility.low_point(v);
                            if fresh {
                                *acc = kernel.base(low, w, g.scale);
                            }
                            if let Some(o) = offsets {
                                acc.offset = o[k];
                            }
                            let mut stopped = false;
                            if (acc.last_level as usize) < low_top {
                                stopped = kernel.extend(acc, low, w, to.min(low_top), stop);
                            }
                            if !stopped && to > acc.last_level as usize {
                                go_on[n] = k;
                                axis0[n] = g.axes[0];
                                low_w[n][..low_len].copy_from_slice(&w[..low_len]);
                                n += 1;
                            }
                        }
                        let hint = |k: usize| prefetch(s.visibility.point(pts[k]), AHEAD_FLOATS);
                        go_on[..n]
                            .iter()
                            .take(PREFETCH_DISTANCE)
                            .for_each(|&k| hint(k));
                        let fitted_lobes = match s.lobe {
                            crate::SpecularLobe::Phong(_) => None,
                            crate::SpecularLobe::Fitted(f) => Some(f.lobes),
                        };
                        let Some(lobes) = fitted_lobes else {
                            // Phong: one axis and the shared lobe row, one cursor for the
                            // block's points, restarted per point.
                            let mut cursor = (n > 0)
                                .then(|| prt_sh::BandCursor::new(self.basis(), glam::Vec3::Z).ok())
                                .flatten();
                            for (i, &k) in go_on[..n].iter().enumerate() {
                                if let Some(&next) = go_on[..n].get(i + PREFETCH_DISTANCE) {
                                    hint(next);
                                }
                                let (acc, row) = (&mut accs[k], s.visibility.point(pts[k]));
                                // The weights band by band, only as far as the point goes
                                // (most stop within a few levels of the low ones).
                                match cursor.as_mut() {
                                    Some(cursor) => {
                                        // (`w` is the block's scratch: the bands shaded so far
                                        // are this point's again first.) The low bands as the
                                        // first pass formed them (the cursor steps over them),
                                        // then the rest from the cursor.
                                        w[..low_len].copy_from_slice(&low_w[i][..low_len]);
                                        cursor.reset(axis0[i]);
                                        for _ in 0..=low_top {
                                            cursor.skip_band();
                                        }
                                        let mut fill = |l: usize, w: &mut [f32]| {
                                            // `y_i(r) A_l`, as `weights` forms it.
                                            cursor.next_band_f32_scaled(&mut w[l * l..], lobe[l]);
                                        };
                                        for l in (low_top + 1)..=acc.last_level as usize {
                                            fill(l, w);
                                        }
                                        for l in (acc.last_level as usize + 1)..=to {
                                            fill(l, w);
                                            if kernel.extend(acc, row, w, l, stop) {
                                                break;
                                            }
                                        }
                                    }
                                    // (Orders above the cursor's limit have no specular anyway.)
                                    None => {
                                        self.weights(&lobe, axis0[i], w);
                                        kernel.extend(acc, row, w, to, stop);
                                    }
                                }
                            }
                            return;
                        };
                        // Fitted lobes: one cursor per lobe axis (a fixed array: no
                        // allocation per block), restarted per point; the point's lobe state
                        // formed again (cheaper than keeping a block of them).
                        let lobes = if n > 0 { lobes } else { 0 };
                        let mut cursors: [Option<prt_sh::BandCursor<'_>>; MAX_FITTED_LOBES] =
                            std::array::from_fn(|j| {
                                (j < lobes)
                                    .then(|| {
                                        prt_sh::BandCursor::new(self.basis(), glam::Vec3::Z).ok()
                                    })
                                    .flatten()
                            });
                        let have_cursors =
                            lobes > 0 && cursors[..lobes].iter().all(Option::is_some);
                        for (i, &k) in go_on[..n].iter().enumerate() {
                            if let Some(&next) = go_on[..n].get(i + PREFETCH_DISTANCE) {
                                hint(next);
                            }
                            let (acc, row) = (&mut accs[k], s.visibility.point(pts[k]));
                            let g = &specular_point(&s, pts[k], &lobe, order, &mut rows);
                            match have_cursors {
                                true => {
                                    // (`w` is the block's scratch: the bands shaded so far
                                    // are this point's again first.) The low bands as the first
                                    // pass formed them (the cursors step over them), then the
                                    // rest from the cursors, one per lobe axis, summed.
                                    w[..low_len].copy_from_slice(&low_w[i][..low_len]);
                                    for (c, axis) in
                                        cursors.iter_mut().flatten().zip(&g.axes[..g.count])
                                    {
                                        c.reset(*axis);
                                        for _ in 0..=low_top {
                                            c.skip_band();
                                        }
                                    }
                                    let mut band = [0.0f32; 2 * MAX_GAUNT_ORDER];
                                    let mut fill = |l: usize, w: &mut [f32]| {
                                        // `Σ_k y_i(a_k) A^k_l`, as `point_weights` forms it.
                                        let out = &mut w[l * l..];
                                        let mut each = cursors.iter_mut().flatten();
                                        if let Some(c) = each.next() {
                                            c.next_band_f32_scaled(out, g.lobe(0)[l]);
                                        }
                                        for (j, c) in each.enumerate().take(g.count - 1) {
                                            c.next_band_f32_scaled(&mut band, g.lobe(j + 1)[l]);
                                            for (a, b) in out[..2 * l + 1].iter_mut().zip(&band) {
                                                *a += b;
                                            }
                                        }
                                    };
                                    for l in (low_top + 1)..=acc.last_level as usize {
                                        fill(l, w);
                                    }
                                    for l in (acc.last_level as usize + 1)..=to {
                                        fill(l, w);
                                        if kernel.extend(acc, row, w, l, stop) {
                                            break;
                                        }
                                    }
                                }
                                // (Orders above the cursor's limit have no specular anyway.)
                                false => {
                                    let mut scratch = vec![0.0f32; n2];
                                    self.point_weights(g, w, &mut scratch);
                                    kernel.extend(acc, row, w, to, stop);
                                }
                            }
                        }
                    },
                )
            }
        };
        let terms: [Option<&Eval<'_>>; 2] = [
            diffuse_eval.as_ref().map(|f| f as &Eval<'_>),
            specular_eval.as_ref().map(|f| f as &Eval<'_>),
        ];

        // Bases first when the threshold is relative to the frame's mean base radiance.
        let mut bases: [Option<Vec<Accum>>; 2] = [None, None];
        let threshold = if relative {
            let mut sum = 0.0f64;
            for (k, eval) in terms.iter().enumerate() {
                if let Some(eval) = eval {
                    let acc = evaluate_all(points, |pts, a, s| {
                        eval(pts, a, true, b - 1, Stop::NEVER, None, s)
                    });
                    sum += acc
                        .iter()
                        .map(|a| {
                            (0..3)
                                .map(|c| f64::from(a.scale[c] * a.base[c]))
                                .sum::<f64>()
                        })
                        .sum::<f64>();
                    bases[k] = Some(acc);
                }
            }
            let mean = if points > 0 {
                sum / (3 * points) as f64
            } else {
                0.0
            };
            (f64::from(t_raw) * mean.abs()) as f32
        } else {
            t_raw
        };

        let mut radiance: [Vec<[f32; 3]>; 2] = [Vec::new(), Vec::new()];
        let mut roi: [Vec<bool>; 2] = [Vec::new(), Vec::new()];
        let mut stats: [Option<TermStats>; 2] = [None, None];
        let (full_d, full_s) = self.full_products();
        let (filter, test) = params.stop.rules(threshold, measure);
        let both = terms[0].is_some() && terms[1].is_some();
        let seen_together = display && both;
        // The filtering pass (Algorithms 1–3): both terms block by block in one sweep.
        let t0 = Instant::now();
        // Every point's sums are kept only if the filtering rule can truncate points, for
        // refinement and smoothing to work on.
        let keep = filter.insignificant.is_some() && (params.refine || params.smooth);
        let mut filtered = filter_pass(
            points,
            terms,
            bases,
            b,
            top,
            filter,
            seen_together,
            keep,
            threshold,
        );
        let pass_seconds = t0.elapsed().as_secs_f64();
        let sequence = if seen_together { [1, 0] } else { [0, 1] };
        for k in sequence {
            let (Some(eval), Some(f)) = (terms[k], filtered[k].take()) else {
                continue;
            };
            let t0 = Instant::now();
            let Filtered {
                mut acc,
                radiance: mut out,
                roi: mut roi_k,
                mut tally,
            } = f;
            let mut st = TermStats::default();
            let any_truncated = tally.truncated > 0;
            debug_assert!(!any_truncated || keep, "truncated points need their sums");
            let refine = params.refine && any_truncated;
            let initial_roi = tally.roi;
            if refine {
                // What the display test adds to this term in refinement: the other term, as in
                // the filtering pass (the diffuse base for specular, which is shaded first, the
                // specular value for diffuse).
                let diffuse_base: Option<Vec<[f32; 3]>> = (seen_together && k == 1).then(|| {
                    filtered[0]
                        .iter()
                        .flat_map(|f| &f.acc)
                        .map(|a| rgb(|c| a.scale[c] * a.base[c]))
                        .collect()
                });
                let offsets: Option<&[[f32; 3]]> = match (seen_together, k) {
                    (false, _) => None,
                    (true, 1) => diffuse_base.as_deref(),
                    (true, _) => Some(&radiance[1]),
                };
                // Tested neighbours go on to the top level, or until they converge.
                let (rounds, tested) = refine_roi(
                    input.adjacency,
                    &mut acc,
                    top,
                    threshold,
                    measure,
                    |pts, a, w| {
                        let local: Option<Vec<[f32; 3]>> =
                            offsets.map(|o| pts.iter().map(|&v| o[v]).collect());
                        eval(pts, a, false, top, test, local.as_deref(), w);
                    },
                );
                st.refinement_rounds = rounds;
                st.refined_points = tested;
                (out, roi_k, tally) = self::tally(&acc, top, threshold, measure);
            }
            roi[k] = roi_k;
            st.active_points = tally.active;
            let denom = tally.active.max(1) as f64;
            let mut reached = 0usize;
            let mut level_fraction = vec![0.0; top + 1];
            for l in (0..=top).rev() {
                reached += tally.at_level[l];
                level_fraction[l] = reached as f64 / denom;
            }
            st.level_fraction = level_fraction;
            st.initial_roi_fraction = initial_roi as f64 / denom;
            st.roi_fraction = tally.roi as f64 / denom;
            st.full_order_fraction = tally.full as f64 / denom;
            st.converged_fraction = tally.converged as f64 / denom;
            st.filtered_out_fraction = 1.0 - st.full_order_fraction;
            st.mean_order = tally.bands as f64 / denom;
            if params.smooth && any_truncated {
                let (corrections, tiers) = smooth_boundary(input.adjacency, &acc, top);
                for (v, c) in corrections {
                    let a = &acc[v];
                    out[v] = rgb(|ch| a.scale[ch] * a.base[ch] + c[ch]);
                }
                st.smoothed_points = tiers;
            }
            st.products = tally.products;
            let full_each = if k == 0 { full_d } else { full_s };
            st.full_order_products = full_each * st.active_points as u64;
            // The shared filtering pass is split between the terms by their products.
            st.seconds = t0.elapsed().as_secs_f64();
            radiance[k] = out;
            stats[k] = Some(st);
        }
        let total: u64 = stats.iter().flatten().map(|s| s.products).sum();
        for st in stats.iter_mut().flatten() {
            st.seconds += pass_seconds * st.products as f64 / total.max(1) as f64;
        }
        let [diffuse, specular] = radiance;
        let [diffuse_stats, specular_stats] = stats;
        Ok(AdaptiveFrame {
            diffuse,
            specular,
            roi,
            stats: FrameStats {
                order: self.order(),
                points,
                threshold,
                diffuse: diffuse_stats,
                specular: specular_stats,
                seconds: start.elapsed().as_secs_f64(),
            },
        })
    }
}

/// Counts of one term's points after shading (see [`tally`]).
#[derive(Clone, Debug, Default)]
struct Tally {
    /// `[l]`: active points whose last level is `l`.
    at_level: Vec<usize>,
    active: usize,
    /// Active points shaded to the top level.
    full: usize,
    /// Active points converged below the top level.
    converged: usize,
    /// Points truncated by significance (neither complete nor inactive).
    truncated: usize,
    /// Points in the ROI: significant and complete.
    roi: usize,
    /// Bands shaded, summed over active points.
    bands: u64,
    /// Coefficient products, all points.
    products: u64,
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
fn tally(
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
struct Filtered {
    /// Every point's sums, if kept for refinement (empty otherwise).
    acc: Vec<Accum>,
    /// Radiance per point.
    radiance: Vec<[f32; 3]>,
    /// ROI flag per point.
    roi: Vec<bool>,
    /// Counts.
    tally: Tally,
}

/// The filtering pass over both terms, block by block (each block's transfers are read once,
/// while in cache): the diffuse base, the specular term (on the display against the diffuse
/// base), then the diffuse levels (on the display against the specular value); then each
/// block's radiance, ROI flags and counts while its sums are in cache. `bases` are precomputed
/// bases (relative threshold), else the bases are computed here. The sums of every point are
/// kept only with `keep` (refinement and smoothing need them); otherwise they live one block at
/// a time on the stack.
#[allow(clippy::too_many_arguments)]
fn filter_pass(
    points: usize,
    terms: [Option<&Eval<'_>>; 2],
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
    let measure = filter.measure;
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
            let mut kept = [kept.0, kept.1];
            let mut rad = [rad.0, rad.1];
            let mut flags = [flags.0, flags.1];
            let mut tallies = [Tally::new(top), Tally::new(top)];
            let first = ci * CHUNK;
            let len = CHUNK.min(points - first);
            let mut local = [[Accum::default(); BLOCK]; 2];
            for lo in (0..len).step_by(BLOCK) {
                let hi = (lo + BLOCK).min(len);
                let n = hi - lo;
                let pts: [usize; BLOCK] = std::array::from_fn(|i| first + lo + i);
                let pts = &pts[..n];
                let [kd, ks] = &mut kept;
                let [ld, ls] = &mut local;
                let mut db: Option<&mut [Accum]> = present[0].then_some(match kd {
                    Some(x) => &mut x[lo..hi],
                    None => &mut ld[..n],
                });
                let sb: Option<&mut [Accum]> = present[1].then_some(match ks {
                    Some(x) => &mut x[lo..hi],
                    None => &mut ls[..n],
                });
                // The diffuse base first only when the specular test needs it (seen together on
                // the display); otherwise the diffuse term goes in one call below.
                if let (Some(eval), Some(db)) = (terms[0], db.as_deref_mut()) {
                    if fresh[0] && seen_together {
                        eval(pts, db, true, b - 1, Stop::NEVER, None, scratch);
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
                    eval(pts, sb, fresh[1], top, filter, offsets, scratch);
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
                    eval(pts, db, start, top, filter, offsets, scratch);
                    if let (Some(r), Some(f)) = (rad[0].as_deref_mut(), flags[0].as_deref_mut()) {
                        let (r, f) = (&mut r[lo..hi], &mut f[lo..hi]);
                        tally_into(db, r, f, &mut tallies[0], top, threshold, measure);
                    }
                }
            }
            tallies
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

/// Runs `f(points, sums, scratch)` over every point in parallel blocks of [`BLOCK`] points,
/// from default sums.
fn evaluate_all(
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
