//! The relighter of one SH order, per-frame lighting, and full-order diffuse and specular shading.

use crate::error::RelightError;
use crate::input::{
    DiffuseParams, FittedLobe, Lighting, SpecularInput, SpecularLobe, TransferView, Viewer,
    MAX_FITTED_LOBES,
};
use crate::kernel::{DiffuseKernel, SpecularKernel, Stop, CHUNK};
use glam::Vec3;
use prt_sh::{zonal, Basis, GauntTensor, MAX_GAUNT_ORDER};
use rayon::prelude::*;

/// Relighting at one SH order: holds the bases, the Gaunt tensor (for specular) and the column
/// layout of the light product matrices. Build once, shade many frames.
#[derive(Clone, Debug)]
pub struct Relighter {
    order: usize,
    basis: Basis,
    gaunt: Option<GauntTensor>,
    /// Band `l`'s column block of the level kernel's layout is
    /// `column_offsets[l]..column_offsets[l+1]` (`(l+1)²` columns of `lanes(l)` floats).
    column_offsets: Vec<usize>,
}

/// The lighting of one frame, prepared for a [`Relighter`]: the f32 coefficients truncated to
/// the relighter's order and (for specular) the three light product matrices `L̂ = M(L)`.
#[derive(Clone, Debug)]
pub struct FrameLighting {
    /// The lighting, truncated to the relighter's order.
    pub lighting: Lighting,
    /// The lighting interleaved by coefficient, `[L_0,i, L_1,i, L_2,i, 0]`, for the diffuse
    /// kernel.
    light4: Vec<[f32; 4]>,
    /// The `b² × b²` corner of the three `L̂_c` (`b = min(order, BASE_ORDER)`) by column, for
    /// the base (layout at `SpecularKernel::base_columns`).
    base_corner: Option<Vec<f32>>,
    /// Band `l`'s rows of the three `L̂_c` stored by column for the level kernel: for each
    /// column `j < (l+1)²`, channel by channel, `lanes(l)` floats (rows `l²..(l+1)²`,
    /// zero-padded to a multiple of 4); band blocks at `Relighter::column_offsets`.
    columns: Option<Vec<f32>>,
}

impl FrameLighting {
    /// Whether the specular product matrices were built.
    #[must_use]
    pub fn has_specular(&self) -> bool {
        self.base_corner.is_some() && self.columns.is_some()
    }
}

/// Per-point specular geometry: `w_i = Σ_k A^k_l y_i(a_k)` is formed from `axes` and `lobes`.
#[derive(Clone, Copy, Debug)]
pub(crate) struct SpecularPoint<'a> {
    /// The lobe axes: for Phong one, the reflection of the view direction, not normalised (the
    /// basis evaluations normalise); a fitted lobe's axes.
    pub axes: [Vec3; MAX_FITTED_LOBES],
    /// Phong: `specular_c · (e+2)/(e+1) · cos θ_o`; fitted: the colour of [`FittedLobe`]; zero
    /// when the point faces away.
    pub scale: [f32; 3],
    pub active: bool,
    /// The band multipliers `A^k_l` of each axis (the first `order` are used).
    rows: LobeRows<'a>,
    /// Axes in use.
    pub count: usize,
}

/// A point's band multipliers: Phong's one row shared by every point, or a fitted lobe's rows
/// interpolated for this point into the caller's [`FittedRows`]. (Borrowed either way: the
/// point state stays a few words, cheap to return and keep per block.)
#[derive(Clone, Copy, Debug)]
enum LobeRows<'a> {
    Shared(&'a [f32]),
    Fitted(&'a FittedRows),
}

/// Scratch for a fitted point's band multipliers, one row per axis.
pub(crate) type FittedRows = [[f32; MAX_GAUNT_ORDER]; MAX_FITTED_LOBES];

impl Relighter {
    /// A relighter of `order` bands. Specular shading needs `order ≤ MAX_GAUNT_ORDER` (32);
    /// beyond it only diffuse shading is available.
    pub fn new(order: usize) -> Result<Self, RelightError> {
        let basis = Basis::new(order)?;
        let gaunt = if order <= MAX_GAUNT_ORDER {
            Some(GauntTensor::new(order)?)
        } else {
            None
        };
        let mut column_offsets = vec![0usize];
        for l in 0..order {
            let last = *column_offsets.last().unwrap_or(&0);
            column_offsets.push(last + 3 * (l + 1) * (l + 1) * crate::kernel::lanes(l));
        }
        Ok(Self {
            order,
            basis,
            gaunt,
            column_offsets,
        })
    }

    /// Order (number of bands).
    #[must_use]
    pub fn order(&self) -> usize {
        self.order
    }

    /// Prepares one frame's lighting (of order ≥ this relighter's; extra bands are dropped).
    /// With `specular`, also builds the light product matrices (`O(order⁵)`, once per frame).
    pub fn frame_lighting(
        &self,
        lighting: &Lighting,
        specular: bool,
    ) -> Result<FrameLighting, RelightError> {
        let lighting = lighting.truncated(self.order)?;
        let (base_corner, columns) = if specular {
            let gaunt = self.gaunt.as_ref().ok_or(RelightError::OrderMismatch {
                what: "specular relighter (Gaunt tensor limit)",
                expected: MAX_GAUNT_ORDER,
                got: self.order,
            })?;
            let n2 = self.order * self.order;
            let bb = crate::BASE_ORDER.min(self.order).pow(2);
            let lanes = crate::kernel::BASE_LANES;
            let mut corner = vec![0.0f32; bb * 3 * lanes];
            let pair = if self.order > crate::kernel::PAIR_TOP {
                crate::kernel::PAIR_FLOATS
            } else {
                0
            };
            let mut cols = vec![0.0f32; self.column_offsets[self.order] + pair];
            for c in 0..3 {
                let l64: Vec<f64> = lighting.rgb[c].iter().map(|v| f64::from(*v)).collect();
                let dense = gaunt.product_matrix(&l64)?;
                for j in 0..bb {
                    for r in 0..bb {
                        corner[(3 * j + c) * lanes + r] = dense[r * n2 + j] as f32;
                    }
                }
                for l in 0..self.order {
                    let (s, e) = (l * l, (l + 1) * (l + 1));
                    let block = &mut cols[self.column_offsets[l]..self.column_offsets[l + 1]];
                    for j in 0..e {
                        for r in 0..2 * l + 1 {
                            block[crate::kernel::column_index(l, j, c, r)] =
                                dense[(s + r) * n2 + j] as f32;
                        }
                    }
                }
                if pair > 0 {
                    let block = &mut cols[self.column_offsets[self.order]..];
                    crate::kernel::fill_pair_block(block, c, |i, j| dense[i * n2 + j] as f32);
                }
            }
            (Some(corner), Some(cols))
        } else {
            (None, None)
        };
        let light4 = (0..self.order * self.order)
            .map(|i| {
                let [r, g, b] = &lighting.rgb;
                [r[i], g[i], b[i], 0.0]
            })
            .collect();
        Ok(FrameLighting {
            lighting,
            light4,
            base_corner,
            columns,
        })
    }

    pub(crate) fn check_transfer(
        &self,
        transfer: &TransferView<'_>,
        what: &'static str,
    ) -> Result<(), RelightError> {
        transfer.validate()?;
        if transfer.order != self.order {
            return Err(RelightError::OrderMismatch {
                what,
                expected: self.order,
                got: transfer.order,
            });
        }
        Ok(())
    }

    pub(crate) fn check_frame(&self, frame: &FrameLighting) -> Result<(), RelightError> {
        frame.lighting.validate()?;
        if frame.lighting.order != self.order {
            return Err(RelightError::OrderMismatch {
                what: "frame lighting",
                expected: self.order,
                got: frame.lighting.order,
            });
        }
        Ok(())
    }

    pub(crate) fn diffuse_kernel<'a>(&self, frame: &'a FrameLighting) -> DiffuseKernel<'a> {
        DiffuseKernel {
            light4: &frame.light4,
            order: self.order,
        }
    }

    pub(crate) fn specular_kernel<'a>(
        &'a self,
        frame: &'a FrameLighting,
    ) -> Result<SpecularKernel<'a>, RelightError> {
        let (Some(corner), Some(cols)) = (&frame.base_corner, &frame.columns) else {
            return Err(RelightError::MissingProducts);
        };
        Ok(SpecularKernel::new(
            corner,
            cols,
            &self.column_offsets,
            self.order,
        ))
    }

    /// Full-order diffuse radiance per point: `albedo/π ⊙ (L_c · T_c)` for each channel `c`
    /// (a 1-channel transfer serves all three). Parallel over chunks of points; the result does
    /// not depend on the thread count.
    pub fn diffuse(
        &self,
        transfer: &TransferView<'_>,
        frame: &FrameLighting,
        params: &DiffuseParams,
    ) -> Result<Vec<[f32; 3]>, RelightError> {
        self.check_transfer(transfer, "diffuse transfer")?;
        self.check_frame(frame)?;
        check_finite3(params.albedo_over_pi, "albedo/π")?;
        let kernel = self.diffuse_kernel(frame);
        let top = self.order - 1;
        let mut out = vec![[0.0f32; 3]; transfer.point_count()];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                for (k, o) in chunk.iter_mut().enumerate() {
                    let t = transfer.point(ci * CHUNK + k);
                    let mut acc = kernel.base(t, transfer.channels, params.albedo_over_pi);
                    kernel.extend(&mut acc, t, transfer.channels, top, Stop::NEVER);
                    *o = acc.radiance();
                }
            });
        Ok(out)
    }

    /// Checks a specular input against this relighter and returns its point count.
    pub(crate) fn check_specular(&self, input: &SpecularInput<'_>) -> Result<usize, RelightError> {
        self.check_transfer(&input.visibility, "specular visibility")?;
        if input.visibility.channels != 1 {
            return Err(RelightError::Channels {
                what: "specular visibility",
                channels: input.visibility.channels,
                allowed: "1",
            });
        }
        let n = input.visibility.point_count();
        let check_len = |what: &'static str, got: usize| {
            if got == n {
                Ok(())
            } else {
                Err(RelightError::PointCount {
                    what,
                    expected: n,
                    got,
                })
            }
        };
        check_len("normals", input.surface.normals.len())?;
        match input.viewer {
            Viewer::Eye(eye) => {
                check_len("positions", input.surface.positions.len())?;
                check_finite3(eye, "eye position")?;
            }
            Viewer::Directions(d) => check_len("view directions", d.len())?,
        }
        match input.lobe {
            SpecularLobe::Phong(p) => {
                check_finite3(p.specular, "specular reflectance")?;
                if p.exponent.is_nan() || p.exponent < 0.0 || p.exponent.is_infinite() {
                    return Err(RelightError::InvalidParameter(format!(
                        "Phong exponent {} must be finite and ≥ 0",
                        p.exponent
                    )));
                }
            }
            SpecularLobe::Fitted(f) => check_fitted(&f, self.order, n)?,
        }
        Ok(n)
    }

    /// Band multipliers of the normalised Phong lobe `(e+1)/(2π) cos^e`, f32 (empty for a
    /// fitted lobe, whose multipliers come per point).
    pub(crate) fn lobe(&self, lobe: &SpecularLobe<'_>) -> Result<Vec<f32>, RelightError> {
        match lobe {
            SpecularLobe::Phong(phong) => Ok(zonal::phong_lobe_bands(
                f64::from(phong.exponent),
                self.order,
            )?
            .into_iter()
            .map(|a| a as f32)
            .collect()),
            SpecularLobe::Fitted(_) => Ok(Vec::new()),
        }
    }

    /// The Gaunt tensor (orders up to `MAX_GAUNT_ORDER`).
    pub(crate) fn gaunt(&self) -> Option<&GauntTensor> {
        self.gaunt.as_ref()
    }

    /// The basis of the relighter's order.
    pub(crate) fn basis(&self) -> &Basis {
        &self.basis
    }

    /// Fills `w_i = A_l y_i(r)`: the first `min(order, LOW_ORDER)` bands as
    /// [`Self::weights_low`], the others from the recurrences (the values a
    /// [`prt_sh::BandCursor`] gives past its skipped low bands, as the adaptive path takes them).
    #[inline]
    pub(crate) fn weights(&self, lobe: &[f32], reflection: Vec3, w: &mut [f32]) {
        self.basis.eval_f32_unchecked(reflection, w);
        let low = crate::LOW_ORDER.min(self.order);
        for (l, a) in lobe.iter().enumerate().skip(low) {
            for v in &mut w[l * l..(l + 1) * (l + 1)] {
                *v *= a;
            }
        }
        self.weights_low(lobe, reflection, w);
    }

    /// Fills `w = Σ_k A^k_l y(a_k)` of a point, all bands (`scratch`: `order²` floats).
    #[inline]
    pub(crate) fn point_weights(&self, g: &SpecularPoint, w: &mut [f32], scratch: &mut [f32]) {
        self.weights(&g.lobe(0)[..self.order], g.axes[0], w);
        for k in 1..g.count {
            self.weights(&g.lobe(k)[..self.order], g.axes[k], scratch);
            for (a, b) in w.iter_mut().zip(scratch.iter()) {
                *a += b;
            }
        }
    }

    /// [`Self::point_weights`] for the first `min(order, LOW_ORDER)²` weights only.
    #[inline]
    pub(crate) fn point_weights_low(&self, g: &SpecularPoint, w: &mut [f32]) {
        self.weights_low(&g.lobe(0)[..self.order], g.axes[0], w);
        let low = crate::LOW_ORDER.min(self.order);
        let mut tmp = [0.0f32; 25];
        for k in 1..g.count {
            self.weights_low(&g.lobe(k)[..self.order], g.axes[k], &mut tmp);
            for (a, b) in w[..low * low].iter_mut().zip(&tmp) {
                *a += b;
            }
        }
    }

    /// Fills the first `min(order, LOW_ORDER)²` weights only (the rest of `w` is untouched),
    /// from the closed-form f32 basis of the low bands ([`prt_sh::eval_low_f32`]).
    #[inline]
    pub(crate) fn weights_low(&self, lobe: &[f32], reflection: Vec3, w: &mut [f32]) {
        const { assert!(crate::LOW_ORDER <= prt_sh::LOW_BANDS) };
        let low = crate::LOW_ORDER.min(self.order);
        let mut y = [0.0f32; 25];
        prt_sh::eval_low_f32(reflection, &mut y);
        for (l, a) in lobe.iter().enumerate().take(low) {
            let band = l * l..(l + 1) * (l + 1);
            for (v, y) in w[band.clone()].iter_mut().zip(&y[band]) {
                *v = y * a;
            }
        }
    }

    /// Full-order Phong specular radiance per point (see the crate docs for the approximation):
    /// `specular ⊙ (e+2)/(e+1) · max(0, n·ω_o) · Σ_lm A_l (L ⊛ V)_lm y_lm(r)` per channel.
    pub fn specular(
        &self,
        input: &SpecularInput<'_>,
        frame: &FrameLighting,
    ) -> Result<Vec<[f32; 3]>, RelightError> {
        let n = self.check_specular(input)?;
        self.check_frame(frame)?;
        let kernel = self.specular_kernel(frame)?;
        let lobe = self.lobe(&input.lobe)?;
        let n2 = self.order * self.order;
        let top = self.order - 1;
        let mut out = vec![[0.0f32; 3]; n];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                let mut w = vec![0.0f32; n2];
                let mut scratch = vec![0.0f32; n2];
                let mut rows = [[0.0; MAX_GAUNT_ORDER]; MAX_FITTED_LOBES];
                for (k, o) in chunk.iter_mut().enumerate() {
                    let p = ci * CHUNK + k;
                    let g = specular_point(input, p, &lobe, self.order, &mut rows);
                    if !g.active {
                        continue;
                    }
                    self.point_weights(&g, &mut w, &mut scratch);
                    let v = input.visibility.point(p);
                    let mut acc = kernel.base(v, &w, g.scale);
                    kernel.extend(&mut acc, v, &w, top, Stop::NEVER);
                    *o = acc.radiance();
                }
            });
        Ok(out)
    }

    /// The specular of [`Self::specular`] without visibility, `scale ⊙ Σ_i w_i L_i` (`L ⊛ 1 =
    /// L`): what a specular-occlusion factor divides the shadowed specular by. One basis
    /// evaluation per lobe axis and one dot product per channel per point; `frame` needs no
    /// product matrices.
    ///
    /// # Errors
    /// As [`Self::specular`], and a frame of another order.
    pub fn specular_unshadowed(
        &self,
        input: &SpecularInput<'_>,
        frame: &FrameLighting,
    ) -> Result<Vec<[f32; 3]>, RelightError> {
        let n = self.check_specular(input)?;
        self.check_frame(frame)?;
        let lobe = self.lobe(&input.lobe)?;
        let n2 = self.order * self.order;
        let light = &frame.lighting.rgb;
        let mut out = vec![[0.0f32; 3]; n];
        out.par_chunks_mut(CHUNK)
            .enumerate()
            .for_each(|(ci, chunk)| {
                let mut w = vec![0.0f32; n2];
                let mut scratch = vec![0.0f32; n2];
                let mut rows = [[0.0; MAX_GAUNT_ORDER]; MAX_FITTED_LOBES];
                for (k, o) in chunk.iter_mut().enumerate() {
                    let g = specular_point(input, ci * CHUNK + k, &lobe, self.order, &mut rows);
                    if !g.active {
                        continue;
                    }
                    self.point_weights(&g, &mut w, &mut scratch);
                    *o = std::array::from_fn(|c| {
                        g.scale[c] * w.iter().zip(&light[c]).map(|(a, b)| a * b).sum::<f32>()
                    });
                }
            });
        Ok(out)
    }

    /// Full-order products of a point: diffuse and specular (3 channels).
    pub(crate) fn full_products(&self) -> (u64, u64) {
        (
            DiffuseKernel::products_through(self.order - 1),
            SpecularKernel::products_through(self.order - 1),
        )
    }
}

impl SpecularPoint<'_> {
    /// A point facing away: no lobe, zero scale.
    pub(crate) const INACTIVE: SpecularPoint<'static> = SpecularPoint {
        axes: [Vec3::ZERO; MAX_FITTED_LOBES],
        scale: [0.0; 3],
        active: false,
        rows: LobeRows::Shared(&[]),
        count: 0,
    };

    /// The band multipliers of axis `j` (`j < count`).
    #[inline]
    pub(crate) fn lobe(&self, j: usize) -> &[f32] {
        match &self.rows {
            LobeRows::Shared(row) => row,
            LobeRows::Fitted(rows) => &rows[j],
        }
    }
}

/// View direction, reflection and scale of point `p`: `ω_o` toward the viewer, `r = 2(n·ω_o)n − ω_o`,
/// scale `specular · (e+2)/(e+1) · n·ω_o` and the Phong lobe `phong_lobe` (or, for a fitted
/// lobe, its axis, table row and colour at this point's `θ_o`); inactive (zero) if
/// `n·ω_o ≤ 0` or degenerate. A fitted lobe's rows are formed in `fitted_rows`.
pub(crate) fn specular_point<'a>(
    input: &SpecularInput<'_>,
    p: usize,
    phong_lobe: &'a [f32],
    order: usize,
    fitted_rows: &'a mut FittedRows,
) -> SpecularPoint<'a> {
    let inactive = SpecularPoint::INACTIVE;
    let n_raw = Vec3::from_array(input.surface.normals[p]);
    let wo_raw = match input.viewer {
        Viewer::Eye(eye) => Vec3::from_array(eye) - Vec3::from_array(input.surface.positions[p]),
        Viewer::Directions(d) => Vec3::from_array(d[p]),
    };
    // Facing away (or degenerate: zero or non-finite vectors): inactive before any square
    // root. About half the points of a closed mesh.
    let d = n_raw.dot(wo_raw);
    if d.is_nan() || d <= 0.0 {
        return inactive;
    }
    // Without normalising either vector: cos θ_o = n·ω / (|n| |ω|) (the two square roots are
    // independent), and the reflection `2 (n·ω)/(n·n) n − ω` is `|ω| r`, the same direction
    // (the basis evaluations normalise it).
    let nn = n_raw.length_squared();
    let cos_o = d / (nn.sqrt() * wo_raw.length_squared().sqrt());
    if cos_o.is_nan() || cos_o <= 0.0 {
        return inactive;
    }
    let reflection = (2.0 * d / nn) * n_raw - wo_raw;
    match input.lobe {
        SpecularLobe::Phong(phong) => {
            let e = phong.exponent;
            let k = (e + 2.0) / (e + 1.0) * cos_o.min(1.0);
            let mut axes = [Vec3::ZERO; MAX_FITTED_LOBES];
            axes[0] = reflection;
            SpecularPoint {
                axes,
                scale: phong.specular.map(|s| s * k),
                active: true,
                rows: LobeRows::Shared(&phong_lobe[..order]),
                count: 1,
            }
        }
        SpecularLobe::Fitted(f) => {
            let theta_o = cos_o.min(1.0).acos();
            let ne = f.elevations.len();
            let (ie, te) = grid_locate(f.elevations, theta_o);
            let rough = if f.point_roughness.len() == 1 {
                f.point_roughness[0]
            } else {
                f.point_roughness.get(p).copied().unwrap_or(0.0)
            };
            let (ir, tr) = grid_locate(f.roughness, rough);
            // The table rows and bilinear weights of (roughness, θ_o).
            let r_next = usize::from(f.roughness.len() > 1);
            let rows = [
                (ir * ne + ie, (1.0 - tr) * (1.0 - te)),
                (ir * ne + ie + 1, (1.0 - tr) * te),
                ((ir + r_next) * ne + ie, tr * (1.0 - te)),
                ((ir + r_next) * ne + ie + 1, tr * te),
            ];
            let k = f.lobes;
            let lobes = fitted_rows;
            for row in lobes.iter_mut().take(k) {
                row[..order].fill(0.0);
            }
            let mut axes = [Vec3::ZERO; MAX_FITTED_LOBES];
            // The axes: `θ_k` from the normal toward the mirror direction, in the plane of
            // the normal and the view (the normal itself when the view is along it).
            let n = n_raw / nn.sqrt();
            let tangent = reflection - reflection.dot(n) * n;
            let len = tangent.length();
            let t_hat = if len > 1e-6 * reflection.length() {
                tangent / len
            } else {
                n.any_orthonormal_vector()
            };
            let pick = |v: &[[f32; 3]]| if v.len() == 1 { v[0] } else { v[p] };
            let (a, b) = (pick(f.colour_a), pick(f.colour_b));
            let two = !f.bands_b.is_empty();
            let lum = |c: [f32; 3]| 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2];
            let (alpha, beta) = if two { (lum(a), lum(b)) } else { (1.0, 0.0) };
            // Energies of the two shapes (Σ_k A^k_0) for the per-channel scale.
            let (mut e_a, mut e_b) = (0.0f32, 0.0f32);
            for j in 0..k {
                let mut theta = 0.0f32;
                for &(row, w) in &rows {
                    if w == 0.0 {
                        continue;
                    }
                    let o = (row * k + j) * f.order;
                    let r = &f.bands[o..o + order];
                    for l in 0..order {
                        lobes[j][l] += w * alpha * r[l];
                    }
                    e_a += w * r[0];
                    if two {
                        let q = &f.bands_b[o..o + order];
                        for l in 0..order {
                            lobes[j][l] += w * beta * q[l];
                        }
                        e_b += w * q[0];
                    }
                    theta += w * f.axis[row * k + j];
                }
                let (s, c) = theta.sin_cos();
                axes[j] = c * n + s * t_hat;
            }
            let scale = if two {
                let mixed = alpha * e_a + beta * e_b;
                std::array::from_fn(|c| {
                    if mixed.abs() > 0.0 {
                        (a[c] * e_a + b[c] * e_b) / mixed
                    } else {
                        0.0
                    }
                })
            } else {
                a
            };
            SpecularPoint {
                axes,
                scale,
                active: true,
                rows: LobeRows::Fitted(lobes),
                count: k,
            }
        }
    }
}

/// The interval of `x` in the increasing `grid` and its linear weight there, as a
/// [`FittedLobe`]'s rows are interpolated: `(i, t)` for the value `(1 − t)·v[i] + t·v[i+1]`,
/// clamped to the grid's ends (`(0, 0)` below, `(len − 2, 1)` above; a grid of one value is
/// `(0, 0)`, that value).
#[must_use]
pub fn grid_locate(grid: &[f32], x: f32) -> (usize, f32) {
    if grid.len() < 2 || x <= grid[0] {
        (0, 0.0)
    } else if x >= grid[grid.len() - 1] {
        (grid.len() - 2, 1.0)
    } else {
        let i = grid.partition_point(|&g| g <= x) - 1;
        (i, (x - grid[i]) / (grid[i + 1] - grid[i]))
    }
}

/// A fitted lobe's table must cover the order, have matching lengths, finite values and
/// increasing elevations; colours one or one per point.
fn check_fitted(f: &FittedLobe<'_>, order: usize, points: usize) -> Result<(), RelightError> {
    let bad = |m: String| Err(RelightError::InvalidParameter(format!("fitted lobe: {m}")));
    let e = f.elevations.len() * f.roughness.len().max(1);
    let k = f.lobes;
    if f.roughness.is_empty() || !f.roughness.windows(2).all(|w| w[0] < w[1]) {
        return bad("roughness levels must be at least one, increasing".into());
    }
    if f.point_roughness.len() != 1 && f.point_roughness.len() != points {
        return bad(format!(
            "{} roughness values for {points} points",
            f.point_roughness.len()
        ));
    }
    if !(1..=MAX_FITTED_LOBES).contains(&k) {
        return bad(format!("{k} lobes (1 to {MAX_FITTED_LOBES})"));
    }
    if f.elevations.len() < 2
        || f.axis.len() != e * k
        || f.bands.len() != e * k * f.order
        || !(f.bands_b.is_empty() || f.bands_b.len() == f.bands.len())
    {
        return bad(format!(
            "{e} elevations of {k} lobes, {} axes, {} + {} band values of order {}",
            f.axis.len(),
            f.bands.len(),
            f.bands_b.len(),
            f.order
        ));
    }
    if f.order > MAX_GAUNT_ORDER {
        return bad(format!("table order {} above {MAX_GAUNT_ORDER}", f.order));
    }
    if f.order < order {
        return bad(format!(
            "table order {} below the relighter's {order}",
            f.order
        ));
    }
    if !f.elevations.windows(2).all(|w| w[0] < w[1]) {
        return bad("elevations must increase".into());
    }
    let finite = |v: &[f32]| v.iter().all(|x| x.is_finite());
    if !(finite(f.elevations)
        && finite(f.axis)
        && finite(f.bands)
        && finite(f.bands_b)
        && finite(f.point_roughness))
    {
        return Err(RelightError::NonFinite("fitted lobe table"));
    }
    for (what, c) in [("colour a", f.colour_a), ("colour b", f.colour_b)] {
        if c.len() != 1 && c.len() != points {
            return bad(format!("{} {what} values for {points} points", c.len()));
        }
        if !c.iter().all(|v| v.iter().all(|x| x.is_finite())) {
            return Err(RelightError::NonFinite("fitted lobe colour"));
        }
    }
    Ok(())
}

pub(crate) fn check_finite3(v: [f32; 3], what: &'static str) -> Result<(), RelightError> {
    if v.iter().all(|x| x.is_finite()) {
        Ok(())
    } else {
        Err(RelightError::NonFinite(what))
    }
}
