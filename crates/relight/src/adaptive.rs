//! Locally adaptive relighting (Lee & Kim 2014, chapter 5): base bands everywhere, higher bands
//! only in a region of interest (ROI) found level by level, refined by a breadth-first search
//! and with its boundary smoothed over two tiers of neighbours.

use crate::adjacency::Adjacency;
use crate::error::RelightError;
use crate::filter::{evaluate_all, filter_pass, tally, Filtered, Tally};
use crate::input::{DiffuseParams, SpecularInput, TransferView};
use crate::kernel::{rgb, Accum, Measure, Stop};
use crate::levels::{BlockLevels, DiffuseLevels, SpecularLevels};
use crate::relighter::{check_finite3, FrameLighting, Relighter};
use crate::roi::{refine_roi, smooth_boundary};
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

/// The checked settings of one adaptive frame (see [`Relighter::adaptive`]).
struct Checked {
    /// Points of every term.
    points: usize,
    /// The threshold as given (a factor of the mean base radiance if `relative`).
    t_raw: f32,
    relative: bool,
}

/// What the finishing of each term after the filtering pass shares.
struct Finish<'a> {
    adjacency: &'a Adjacency,
    params: &'a AdaptiveParams,
    top: usize,
    /// The absolute threshold.
    threshold: f32,
    measure: Measure,
    /// The refinement's stopping rules.
    test: Stop<'static>,
    /// Whether the terms are tested on the display together (each against the other).
    seen_together: bool,
    /// Whether the filtering pass kept every point's sums.
    keep: bool,
    /// Full-order products of a point, `[diffuse, specular]`.
    full_products: [u64; 2],
}

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
        let Checked {
            points,
            t_raw,
            relative,
        } = self.check_adaptive(input, frame, params)?;
        let top = self.order() - 1;
        let b = crate::BASE_ORDER.min(self.order());
        let alpha = params.cost_exponent;
        let measure = params.threshold.measure();
        let display = matches!(measure, Measure::Display { .. });

        let diffuse_eval = input
            .diffuse
            .as_ref()
            .map(|(t, p)| DiffuseLevels::new(self, frame, *t, p.albedo_over_pi, alpha));
        let specular_eval = match &input.specular {
            None => None,
            Some(s) => Some(SpecularLevels::new(self, frame, s, alpha)?),
        };
        let terms: [Option<&dyn BlockLevels>; 2] = [
            diffuse_eval.as_ref().map(|f| f as &dyn BlockLevels),
            specular_eval.as_ref().map(|f| f as &dyn BlockLevels),
        ];

        // Bases first when the threshold is relative to the frame's mean base radiance.
        let (threshold, bases) = if relative {
            relative_threshold(points, terms, b, t_raw)
        } else {
            (t_raw, [None, None])
        };

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
        let finish = Finish {
            adjacency: input.adjacency,
            params,
            top,
            threshold,
            measure,
            test,
            seen_together,
            keep,
            full_products: [full_d, full_s],
        };
        let mut radiance: [Vec<[f32; 3]>; 2] = [Vec::new(), Vec::new()];
        let mut roi: [Vec<bool>; 2] = [Vec::new(), Vec::new()];
        let mut stats: [Option<TermStats>; 2] = [None, None];
        let sequence = if seen_together { [1, 0] } else { [0, 1] };
        for k in sequence {
            let (Some(eval), Some(f)) = (terms[k], filtered[k].take()) else {
                continue;
            };
            let (out, roi_k, st) = finish.term(k, eval, f, &filtered, &radiance);
            roi[k] = roi_k;
            radiance[k] = out;
            stats[k] = Some(st);
        }
        // The shared filtering pass is split between the terms by their products.
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

    /// Checks an adaptive frame's inputs against each other and the relighter, and its
    /// parameters.
    fn check_adaptive(
        &self,
        input: &AdaptiveInput<'_>,
        frame: &FrameLighting,
        params: &AdaptiveParams,
    ) -> Result<Checked, RelightError> {
        self.check_frame(frame)?;
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
        Ok(Checked {
            points,
            t_raw,
            relative,
        })
    }
}

/// The absolute threshold of [`Threshold::RelativeToMean`]`(t_raw)`: `t_raw` times the frame's
/// mean base radiance over points and channels (both terms, bands `0..b`), and the bases of
/// every point it was taken from, which the filtering pass continues.
fn relative_threshold(
    points: usize,
    terms: [Option<&dyn BlockLevels>; 2],
    b: usize,
    t_raw: f32,
) -> (f32, [Option<Vec<Accum>>; 2]) {
    let mut bases: [Option<Vec<Accum>>; 2] = [None, None];
    let mut sum = 0.0f64;
    for (k, eval) in terms.iter().enumerate() {
        if let Some(eval) = eval {
            let acc = evaluate_all(points, |pts, a, s| {
                eval.shade(pts, a, true, b - 1, Stop::NEVER, None, s);
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
    ((f64::from(t_raw) * mean.abs()) as f32, bases)
}

impl Finish<'_> {
    /// Finishes term `k` after the filtering pass left `f`: refines its ROI and smooths the
    /// boundary (when points were truncated), and counts. `filtered` and `radiance` hold the
    /// other term as the display test sees it (its filtered sums, or its final radiance if
    /// finished first). Returns the term's radiance, ROI flags and statistics.
    fn term(
        &self,
        k: usize,
        eval: &dyn BlockLevels,
        f: Filtered,
        filtered: &[Option<Filtered>; 2],
        radiance: &[Vec<[f32; 3]>; 2],
    ) -> (Vec<[f32; 3]>, Vec<bool>, TermStats) {
        let (params, top) = (self.params, self.top);
        let t0 = Instant::now();
        let Filtered {
            mut acc,
            radiance: mut out,
            roi: mut roi_k,
            mut tally,
        } = f;
        let mut st = TermStats::default();
        let any_truncated = tally.truncated > 0;
        debug_assert!(
            !any_truncated || self.keep,
            "truncated points need their sums"
        );
        let refine = params.refine && any_truncated;
        let initial_roi = tally.roi;
        if refine {
            let (rounds, tested) = self.refine(k, eval, &mut acc, filtered, radiance);
            st.refinement_rounds = rounds;
            st.refined_points = tested;
            (out, roi_k, tally) = self::tally(&acc, top, self.threshold, self.measure);
        }
        st.set_fractions(&tally, initial_roi, top);
        if params.smooth && any_truncated {
            let (corrections, tiers) = smooth_boundary(self.adjacency, &acc, top);
            for (v, c) in corrections {
                let a = &acc[v];
                out[v] = rgb(|ch| a.scale[ch] * a.base[ch] + c[ch]);
            }
            st.smoothed_points = tiers;
        }
        st.products = tally.products;
        st.full_order_products = self.full_products[k] * st.active_points as u64;
        st.seconds = t0.elapsed().as_secs_f64();
        (out, roi_k, st)
    }

    /// Refines term `k`'s ROI (5.2.1): tested neighbours go on to the top level, or until they
    /// converge, against what the display shows besides the term. Returns (rounds, points
    /// tested).
    fn refine(
        &self,
        k: usize,
        eval: &dyn BlockLevels,
        acc: &mut [Accum],
        filtered: &[Option<Filtered>; 2],
        radiance: &[Vec<[f32; 3]>; 2],
    ) -> (usize, usize) {
        let (seen_together, top, test) = (self.seen_together, self.top, self.test);
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
        refine_roi(
            self.adjacency,
            acc,
            top,
            self.threshold,
            self.measure,
            |pts, a, w| {
                let local: Option<Vec<[f32; 3]>> =
                    offsets.map(|o| pts.iter().map(|&v| o[v]).collect());
                eval.shade(pts, a, false, top, test, local.as_deref(), w);
            },
        )
    }
}

impl TermStats {
    /// The fractions of the term's active points in `tally` (and `initial_roi` of them after
    /// the filtering pass): per level, in the ROI, at full order, converged, and the mean order.
    fn set_fractions(&mut self, tally: &Tally, initial_roi: usize, top: usize) {
        self.active_points = tally.active;
        let denom = tally.active.max(1) as f64;
        let mut reached = 0usize;
        let mut level_fraction = vec![0.0; top + 1];
        for l in (0..=top).rev() {
            reached += tally.at_level[l];
            level_fraction[l] = reached as f64 / denom;
        }
        self.level_fraction = level_fraction;
        self.initial_roi_fraction = initial_roi as f64 / denom;
        self.roi_fraction = tally.roi as f64 / denom;
        self.full_order_fraction = tally.full as f64 / denom;
        self.converged_fraction = tally.converged as f64 / denom;
        self.filtered_out_fraction = 1.0 - self.full_order_fraction;
        self.mean_order = tally.bands as f64 / denom;
    }
}
