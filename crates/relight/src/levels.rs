//! The adaptive path's level-by-level shading of a block of points, one term at a time: the
//! base and the low bands of every point from the compact copies, then the points that go on
//! from their full rows (hinted into cache a few points ahead), each stopping by the rules it
//! is given. The sums themselves are the kernels' ([`crate::kernel`]); what stops a point is
//! [`Stop`]'s.

use crate::error::RelightError;
use crate::input::{SpecularInput, SpecularLobe, TransferView, MAX_FITTED_LOBES};
use crate::kernel::{
    level_costs, prefetch, Accum, DiffuseKernel, SpecularKernel, Stop, Term, BLOCK,
};
use crate::relighter::{specular_point, FittedRows, FrameLighting, Relighter, SpecularPoint};
use glam::Vec3;
use prt_sh::MAX_GAUNT_ORDER;

/// Points ahead whose full rows are hinted into cache in the second pass of a block.
const PREFETCH_DISTANCE: usize = 3;
/// Floats of a full row hinted (per channel): through band 7 (`8² = 64`), the levels most of
/// the points that go on past the low bands reach.
const AHEAD_FLOATS: usize = 64;

/// One term's shading of a block of points for the adaptive path.
pub(crate) trait BlockLevels: Sync {
    /// Evaluates a block of at most [`BLOCK`] points in place: with `fresh` the sums are
    /// started from the base, otherwise continued, up to level `to` by the rules of `stop`;
    /// `offsets[k]` (if given) is what the display shows besides this term at point `k` of
    /// the block; `scratch` is the caller's per-thread buffer.
    #[allow(clippy::too_many_arguments)]
    fn shade(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        fresh: bool,
        to: usize,
        stop: Stop<'_>,
        offsets: Option<&[[f32; 3]]>,
        scratch: &mut Vec<f32>,
    );
}

/// The diffuse term: a transfer and its albedo/π.
pub(crate) struct DiffuseLevels<'a> {
    kernel: DiffuseKernel<'a>,
    transfer: TransferView<'a>,
    scale: [f32; 3],
    /// The convergence threshold's factor per level ([`level_costs`]).
    costs: Vec<f32>,
    /// The last level of the compact low-band copies.
    low_top: usize,
}

impl<'a> DiffuseLevels<'a> {
    /// The diffuse term of `relighter` lit by `frame`, with cost exponent `alpha`.
    pub(crate) fn new(
        relighter: &Relighter,
        frame: &'a FrameLighting,
        transfer: TransferView<'a>,
        albedo_over_pi: [f32; 3],
        alpha: f32,
    ) -> Self {
        Self {
            kernel: relighter.diffuse_kernel(frame),
            transfer,
            scale: albedo_over_pi,
            costs: level_costs(Term::Diffuse, relighter.order(), alpha),
            low_top: crate::LOW_ORDER.min(relighter.order()) - 1,
        }
    }

    /// Hints point `k` of the block's full row into cache.
    fn hint(&self, pts: &[usize], k: usize) {
        let t = &self.transfer;
        let row = t.point(pts[k]);
        let n2 = row.len() / t.channels;
        for c in 0..t.channels {
            prefetch(&row[c * n2..(c + 1) * n2], AHEAD_FLOATS);
        }
    }
}

impl BlockLevels for DiffuseLevels<'_> {
    fn shade(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        fresh: bool,
        to: usize,
        stop: Stop<'_>,
        offsets: Option<&[[f32; 3]]>,
        _: &mut Vec<f32>,
    ) {
        let (t, kernel, low_top) = (&self.transfer, &self.kernel, self.low_top);
        let stop = stop.with_level_scale(&self.costs);
        // Two passes: the low bands of every point from the compact copy, then the
        // points that go on from their full rows, each row hinted into cache a few
        // points ahead (see `kernel::prefetch`).
        let mut go_on = [0usize; BLOCK];
        let mut n = 0;
        for (k, (&v, acc)) in pts.iter().zip(accs.iter_mut()).enumerate() {
            let low = t.low_point(v);
            if fresh {
                *acc = kernel.base(low, t.channels, self.scale);
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
        go_on[..n]
            .iter()
            .take(PREFETCH_DISTANCE)
            .for_each(|&k| self.hint(pts, k));
        for (i, &k) in go_on[..n].iter().enumerate() {
            if let Some(&next) = go_on[..n].get(i + PREFETCH_DISTANCE) {
                self.hint(pts, next);
            }
            kernel.extend(&mut accs[k], t.point(pts[k]), t.channels, to, stop);
        }
    }
}

/// The specular term: visibility, geometry, viewer and lobe.
pub(crate) struct SpecularLevels<'a> {
    relighter: &'a Relighter,
    kernel: SpecularKernel<'a>,
    /// Phong's band multipliers (empty for a fitted lobe).
    lobe: Vec<f32>,
    input: SpecularInput<'a>,
    /// The convergence threshold's factor per level ([`level_costs`]).
    costs: Vec<f32>,
    /// The last level of the compact low-band copies.
    low_top: usize,
}

/// The points of a block that go on past the low bands, as the first pass leaves them.
struct GoOn {
    /// Their indices in the block.
    points: [usize; BLOCK],
    /// Phong's one axis per point going on (its lobe row is shared).
    axis0: [Vec3; BLOCK],
    /// Their low weights, for their second pass.
    low_w: [[f32; 25]; BLOCK],
    /// How many.
    n: usize,
}

impl<'a> SpecularLevels<'a> {
    /// The specular term of `relighter` lit by `frame`, with cost exponent `alpha`.
    ///
    /// # Errors
    /// A frame without product matrices; a Phong exponent without band multipliers.
    pub(crate) fn new(
        relighter: &'a Relighter,
        frame: &'a FrameLighting,
        input: &SpecularInput<'a>,
        alpha: f32,
    ) -> Result<Self, RelightError> {
        let kernel = relighter.specular_kernel(frame)?;
        let lobe = relighter.lobe(&input.lobe)?;
        Ok(Self {
            relighter,
            kernel,
            lobe,
            input: *input,
            costs: level_costs(Term::Specular, relighter.order(), alpha),
            low_top: crate::LOW_ORDER.min(relighter.order()) - 1,
        })
    }

    /// Hints point `k` of the block's full visibility row into cache.
    fn hint(&self, pts: &[usize], k: usize) {
        prefetch(self.input.visibility.point(pts[k]), AHEAD_FLOATS);
    }

    /// The first pass: the low bands (weights and visibility) of every point of the block;
    /// returns the points that go on.
    #[allow(clippy::too_many_arguments)]
    fn low_pass(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        fresh: bool,
        to: usize,
        stop: Stop<'_>,
        offsets: Option<&[[f32; 3]]>,
        w: &mut [f32],
        rows: &mut FittedRows,
    ) -> GoOn {
        let (s, kernel, low_top) = (&self.input, &self.kernel, self.low_top);
        let (order, top) = (self.relighter.order(), self.relighter.order() - 1);
        let mut go = GoOn {
            points: [0usize; BLOCK],
            axis0: [Vec3::ZERO; BLOCK],
            low_w: [[0.0f32; 25]; BLOCK],
            n: 0,
        };
        let low_len = (low_top + 1) * (low_top + 1);
        for (k, (&v, acc)) in pts.iter().zip(accs.iter_mut()).enumerate() {
            let g = specular_point(s, v, &self.lobe, order, rows);
            if !g.active {
                *acc = Accum {
                    last_level: top as u16,
                    inactive: true,
                    ..Accum::default()
                };
                continue;
            }
            self.relighter.point_weights_low(&g, w);
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
                let n = go.n;
                go.points[n] = k;
                go.axis0[n] = g.axes[0];
                go.low_w[n][..low_len].copy_from_slice(&w[..low_len]);
                go.n += 1;
            }
        }
        go
    }

    /// Continues a point whose weights past the low bands come band by band from `fill`: the
    /// bands already shaded are formed again first (`w` is the block's scratch), then each
    /// further level is formed and added until `to` or a rule stops the point.
    fn extend_band_by_band(
        &self,
        acc: &mut Accum,
        row: &[f32],
        w: &mut [f32],
        to: usize,
        stop: Stop<'_>,
        mut fill: impl FnMut(usize, &mut [f32]),
    ) {
        for l in (self.low_top + 1)..=acc.last_level as usize {
            fill(l, w);
        }
        for l in (acc.last_level as usize + 1)..=to {
            fill(l, w);
            if self.kernel.extend(acc, row, w, l, stop) {
                break;
            }
        }
    }

    /// The second pass of a Phong lobe: one axis and the shared lobe row, one cursor for the
    /// block's points, restarted per point.
    fn phong_pass(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        go: &GoOn,
        to: usize,
        stop: Stop<'_>,
        w: &mut [f32],
    ) {
        let (n, low_top, lobe) = (go.n, self.low_top, &self.lobe);
        let low_len = (low_top + 1) * (low_top + 1);
        let mut cursor = (n > 0)
            .then(|| prt_sh::BandCursor::new(self.relighter.basis(), Vec3::Z).ok())
            .flatten();
        for (i, &k) in go.points[..n].iter().enumerate() {
            if let Some(&next) = go.points[..n].get(i + PREFETCH_DISTANCE) {
                self.hint(pts, next);
            }
            let (acc, row) = (&mut accs[k], self.input.visibility.point(pts[k]));
            // The weights band by band, only as far as the point goes
            // (most stop within a few levels of the low ones).
            match cursor.as_mut() {
                Some(cursor) => {
                    // (`w` is the block's scratch: the bands shaded so far
                    // are this point's again first.) The low bands as the
                    // first pass formed them (the cursor steps over them),
                    // then the rest from the cursor.
                    w[..low_len].copy_from_slice(&go.low_w[i][..low_len]);
                    cursor.reset(go.axis0[i]);
                    for _ in 0..=low_top {
                        cursor.skip_band();
                    }
                    self.extend_band_by_band(acc, row, w, to, stop, |l, w| {
                        // `y_i(r) A_l`, as `weights` forms it.
                        cursor.next_band_f32_scaled(&mut w[l * l..], lobe[l]);
                    });
                }
                // (Orders above the cursor's limit have no specular anyway.)
                None => {
                    self.relighter.weights(lobe, go.axis0[i], w);
                    self.kernel.extend(acc, row, w, to, stop);
                }
            }
        }
    }

    /// The second pass of a fitted lobe of `lobes` axes: one cursor per lobe axis (a fixed
    /// array: no allocation per block), restarted per point; the point's lobe state formed
    /// again (cheaper than keeping a block of them).
    #[allow(clippy::too_many_arguments)]
    fn fitted_pass(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        go: &GoOn,
        lobes: usize,
        to: usize,
        stop: Stop<'_>,
        w: &mut [f32],
        rows: &mut FittedRows,
    ) {
        let (n, low_top) = (go.n, self.low_top);
        let order = self.relighter.order();
        let n2 = order * order;
        let low_len = (low_top + 1) * (low_top + 1);
        let lobes = if n > 0 { lobes } else { 0 };
        let mut cursors: [Option<prt_sh::BandCursor<'_>>; MAX_FITTED_LOBES] =
            std::array::from_fn(|j| {
                (j < lobes)
                    .then(|| prt_sh::BandCursor::new(self.relighter.basis(), Vec3::Z).ok())
                    .flatten()
            });
        let have_cursors = lobes > 0 && cursors[..lobes].iter().all(Option::is_some);
        for (i, &k) in go.points[..n].iter().enumerate() {
            if let Some(&next) = go.points[..n].get(i + PREFETCH_DISTANCE) {
                self.hint(pts, next);
            }
            let (acc, row) = (&mut accs[k], self.input.visibility.point(pts[k]));
            let g = &specular_point(&self.input, pts[k], &self.lobe, order, rows);
            match have_cursors {
                true => {
                    // (`w` is the block's scratch: the bands shaded so far
                    // are this point's again first.) The low bands as the first
                    // pass formed them (the cursors step over them), then the
                    // rest from the cursors, one per lobe axis, summed.
                    w[..low_len].copy_from_slice(&go.low_w[i][..low_len]);
                    for (c, axis) in cursors.iter_mut().flatten().zip(&g.axes[..g.count]) {
                        c.reset(*axis);
                        for _ in 0..=low_top {
                            c.skip_band();
                        }
                    }
                    let mut band = [0.0f32; 2 * MAX_GAUNT_ORDER];
                    self.extend_band_by_band(acc, row, w, to, stop, |l, w| {
                        fill_fitted_band(&mut cursors, g, l, w, &mut band);
                    });
                }
                // (Orders above the cursor's limit have no specular anyway.)
                false => {
                    let mut scratch = vec![0.0f32; n2];
                    self.relighter.point_weights(g, w, &mut scratch);
                    self.kernel.extend(acc, row, w, to, stop);
                }
            }
        }
    }
}

/// Band `l` of a fitted point's weights `Σ_k y_i(a_k) A^k_l`, as `point_weights` forms it, from
/// the cursors of its axes (`band`: scratch for one axis' band).
fn fill_fitted_band(
    cursors: &mut [Option<prt_sh::BandCursor<'_>>; MAX_FITTED_LOBES],
    g: &SpecularPoint<'_>,
    l: usize,
    w: &mut [f32],
    band: &mut [f32; 2 * MAX_GAUNT_ORDER],
) {
    let out = &mut w[l * l..];
    let mut each = cursors.iter_mut().flatten();
    if let Some(c) = each.next() {
        c.next_band_f32_scaled(out, g.lobe(0)[l]);
    }
    for (j, c) in each.enumerate().take(g.count - 1) {
        c.next_band_f32_scaled(band, g.lobe(j + 1)[l]);
        for (a, b) in out[..2 * l + 1].iter_mut().zip(band.iter()) {
            *a += b;
        }
    }
}

impl BlockLevels for SpecularLevels<'_> {
    fn shade(
        &self,
        pts: &[usize],
        accs: &mut [Accum],
        fresh: bool,
        to: usize,
        stop: Stop<'_>,
        offsets: Option<&[[f32; 3]]>,
        w: &mut Vec<f32>,
    ) {
        let order = self.relighter.order();
        let stop = stop.with_level_scale(&self.costs);
        w.resize(order * order, 0.0);
        // Two passes as for diffuse: the low bands (weights and visibility) of
        // every point, then the points that go on, rows hinted ahead.
        let mut rows = [[0.0; MAX_GAUNT_ORDER]; MAX_FITTED_LOBES];
        let go = self.low_pass(pts, accs, fresh, to, stop, offsets, w, &mut rows);
        go.points[..go.n]
            .iter()
            .take(PREFETCH_DISTANCE)
            .for_each(|&k| self.hint(pts, k));
        match self.input.lobe {
            SpecularLobe::Phong(_) => self.phong_pass(pts, accs, &go, to, stop, w),
            SpecularLobe::Fitted(f) => {
                self.fitted_pass(pts, accs, &go, f.lobes, to, stop, w, &mut rows);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::input::{DiffuseParams, Lighting};

    /// Deterministic values in (−1, 1).
    fn numbers(n: usize, seed: u32) -> Vec<f32> {
        let mut s = seed;
        (0..n)
            .map(|_| {
                s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
                (s >> 8) as f32 / (1 << 23) as f32 - 1.0
            })
            .collect()
    }

    #[test]
    fn diffuse_levels_continue_where_they_stopped_and_end_at_full_order() {
        let (order, points) = (9, 20);
        let relighter = Relighter::new(order).unwrap();
        let env: Vec<[f64; 3]> = numbers(3 * order * order, 1)
            .chunks(3)
            .map(|c| [f64::from(c[0]), f64::from(c[1]), f64::from(c[2])])
            .collect();
        let lighting = Lighting::from_rgb_coefficients(&env, None).unwrap();
        let frame = relighter.frame_lighting(&lighting, false).unwrap();
        let data = numbers(points * 3 * order * order, 2);
        let low = crate::low_bands(&data, order);
        let view = TransferView::new(order, 3, &data)
            .unwrap()
            .with_low_bands(&low)
            .unwrap();
        let params = DiffuseParams::from_albedo([0.9, 0.6, 0.3]);
        let full = relighter.diffuse(&view, &frame, &params).unwrap();
        let levels = DiffuseLevels::new(&relighter, &frame, view, params.albedo_over_pi, 1.0);
        let pts: Vec<usize> = (0..points).collect();
        let top = order - 1;
        // In one call, from the base to the top level.
        let mut once = vec![Accum::default(); points];
        levels.shade(
            &pts,
            &mut once,
            true,
            top,
            Stop::NEVER,
            None,
            &mut Vec::new(),
        );
        // The base, then to level 6 (past the low-band copies), then the rest.
        let mut steps = vec![Accum::default(); points];
        for (fresh, to) in [(true, 2), (false, 6), (false, top)] {
            levels.shade(
                &pts,
                &mut steps,
                fresh,
                to,
                Stop::NEVER,
                None,
                &mut Vec::new(),
            );
            assert!(steps.iter().all(|a| a.last_level as usize == to));
        }
        assert_eq!(once, steps);
        let radiance: Vec<[f32; 3]> = once.iter().map(Accum::radiance).collect();
        assert_eq!(radiance, full, "bit for bit the full-order path");
    }
}
