//! Inputs as plain in-memory arrays, laid out the way a bake stores them.

use crate::error::RelightError;
use prt_sh::Rotation;

/// Per-vertex (or per-pixel) transfer of one object: order `n`, `channels` (1 or 3), data
/// `[point][channel][coeff]` in f32, length `points · channels · n²`.
///
/// For diffuse shading this is the transfer vector `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω` of a
/// shadowed bake, or the interreflected transfer (whose bounces already include the albedo/π of
/// the *other* surfaces). In both cases it **excludes the receiving point's own albedo/π**,
/// which [`DiffuseParams`] applies once. For specular shading it is the visibility
/// `V_i = ∫ vis(ω) y_i(ω) dω` (1 channel, no cosine).
#[derive(Clone, Copy, Debug)]
pub struct TransferView<'a> {
    /// SH order (number of bands).
    pub order: usize,
    /// Channels per point: 1 (used for all three colours) or 3.
    pub channels: usize,
    /// `[point][channel][coeff]`.
    pub data: &'a [f32],
    /// Optional compact copy of the first [`LOW_ORDER`] bands, `[point][channel][coeff < 25]`
    /// (see [`TransferView::with_low_bands`]): the adaptive path reads it for the base and the
    /// first levels, and a point's full row only if it goes on past them.
    pub low: Option<&'a [f32]>,
}

/// Bands held by a transfer's compact low-band copy ([`TransferView::with_low_bands`]): the
/// base (3) and the two levels every point of the adaptive path evaluates before its first
/// convergence test.
pub const LOW_ORDER: usize = 5;

/// The compact low-band copy of `[point][channel][coeff]` data of order `order`: the first
/// `min(order, LOW_ORDER)²` coefficients of every point and channel (for
/// [`TransferView::with_low_bands`]; make it once, not per frame).
#[must_use]
pub fn low_bands(data: &[f32], order: usize) -> Vec<f32> {
    // Rows of `order²` floats are (point, channel) pairs.
    let (n2, k) = (order * order, LOW_ORDER.min(order).pow(2));
    data.chunks_exact(n2.max(1))
        .flat_map(|row| row[..k].iter().copied())
        .collect()
}

impl<'a> TransferView<'a> {
    /// A checked view (see [`TransferView::validate`]).
    pub fn new(order: usize, channels: usize, data: &'a [f32]) -> Result<Self, RelightError> {
        let view = Self {
            order,
            channels,
            data,
            low: None,
        };
        view.validate()?;
        Ok(view)
    }

    /// The view with its compact low-band copy (from [`low_bands`] of the same data): the
    /// adaptive path then reads `min(order, 5)²` floats per point and channel for every point
    /// and the full row only for points that go on (a layout for level-by-level reading: with
    /// rows of `order²` floats the memory traffic of the first levels is that of the whole
    /// row). Results are identical with and without it.
    pub fn with_low_bands(mut self, low: &'a [f32]) -> Result<Self, RelightError> {
        let k = LOW_ORDER.min(self.order).pow(2) * self.channels;
        if low.len() != self.point_count() * k {
            return Err(RelightError::InvalidParameter(format!(
                "low-band copy holds {} floats, expected {} ({} points × {k})",
                low.len(),
                self.point_count() * k,
                self.point_count()
            )));
        }
        self.low = Some(low);
        Ok(self)
    }

    /// The low-band floats of point `p` if there is a copy, else its full row.
    #[must_use]
    pub(crate) fn low_point(&self, p: usize) -> &'a [f32] {
        match self.low {
            Some(low) => {
                let k = LOW_ORDER.min(self.order).pow(2) * self.channels;
                &low[p * k..(p + 1) * k]
            }
            None => self.point(p),
        }
    }

    /// Checks the order (≥ 1), the channel count (1 or 3) and that the data is a whole number
    /// of points. Values are not scanned (a bake reader validates them once).
    pub fn validate(&self) -> Result<(), RelightError> {
        prt_sh::check_order(self.order, prt_sh::MAX_ORDER)?;
        if self.channels != 1 && self.channels != 3 {
            return Err(RelightError::Channels {
                what: "transfer",
                channels: self.channels,
                allowed: "1 or 3",
            });
        }
        let per_point = self.floats_per_point();
        if (self.data.len() / per_point) * per_point != self.data.len() {
            return Err(RelightError::TransferLength {
                order: self.order,
                channels: self.channels,
                per_point,
                len: self.data.len(),
            });
        }
        Ok(())
    }

    /// `channels · order²`.
    #[must_use]
    pub fn floats_per_point(&self) -> usize {
        self.channels * self.order * self.order
    }

    /// Number of points (vertices or pixels).
    #[must_use]
    pub fn point_count(&self) -> usize {
        self.data.len() / self.floats_per_point().max(1)
    }

    /// The `channels · order²` floats of point `p` (panics if `p` is out of range).
    #[must_use]
    pub fn point(&self, p: usize) -> &'a [f32] {
        let k = self.floats_per_point();
        &self.data[p * k..(p + 1) * k]
    }
}

/// Lighting: RGB SH coefficients of the distant environment (already rotated), f32, stored per
/// channel (`rgb[c][i]`, `order²` each) so that dot products with a transfer vectorise.
#[derive(Clone, Debug, PartialEq)]
pub struct Lighting {
    /// SH order (number of bands).
    pub order: usize,
    /// `rgb[channel][coeff]`.
    pub rgb: [Vec<f32>; 3],
}

impl Lighting {
    /// Lighting from RGB coefficients `[coeff][channel]` (as `prt_sh::project_env` returns them),
    /// rotated by `rotation` if given (the rotation's order must be at least the coefficients'
    /// order; its first bands are used). The rotation is applied in f64, then rounded to f32.
    pub fn from_rgb_coefficients(
        coeffs: &[[f64; 3]],
        rotation: Option<&Rotation>,
    ) -> Result<Self, RelightError> {
        let order = order_of_len(coeffs.len())?;
        if coeffs.iter().flatten().any(|v| !v.is_finite()) {
            return Err(RelightError::NonFinite("lighting coefficients"));
        }
        let rotated;
        let coeffs = match rotation {
            None => coeffs,
            Some(rot) => {
                if rot.order() < order {
                    return Err(RelightError::OrderMismatch {
                        what: "lighting rotation",
                        expected: order,
                        got: rot.order(),
                    });
                }
                rotated = rotate_rgb(rot, coeffs, order);
                &rotated[..]
            }
        };
        let channel = |c: usize| coeffs.iter().map(|v| v[c] as f32).collect::<Vec<f32>>();
        Ok(Self {
            order,
            rgb: [channel(0), channel(1), channel(2)],
        })
    }

    /// Checks the order and that every channel holds `order²` finite values.
    pub fn validate(&self) -> Result<(), RelightError> {
        prt_sh::check_order(self.order, prt_sh::MAX_ORDER)?;
        for ch in &self.rgb {
            if ch.len() != self.order * self.order {
                return Err(RelightError::Sh(prt_sh::ShError::BufferLength {
                    order: self.order,
                    expected: self.order * self.order,
                    got: ch.len(),
                }));
            }
            if ch.iter().any(|v| !v.is_finite()) {
                return Err(RelightError::NonFinite("lighting coefficients"));
            }
        }
        Ok(())
    }

    /// The first `order` bands (errors if this lighting has fewer).
    pub fn truncated(&self, order: usize) -> Result<Self, RelightError> {
        self.validate()?;
        if order == 0 || order > self.order {
            return Err(RelightError::OrderMismatch {
                what: "lighting",
                expected: order,
                got: self.order,
            });
        }
        let n2 = order * order;
        Ok(Self {
            order,
            rgb: [
                self.rgb[0][..n2].to_vec(),
                self.rgb[1][..n2].to_vec(),
                self.rgb[2][..n2].to_vec(),
            ],
        })
    }
}

/// `n` with `n² = len`, n ≥ 1.
pub(crate) fn order_of_len(len: usize) -> Result<usize, RelightError> {
    let n = (len as f64).sqrt().round() as usize;
    if n == 0 || n * n != len {
        return Err(RelightError::NotSquare(len));
    }
    Ok(n)
}

/// Applies the first `order` band matrices of `rot` to RGB coefficients.
fn rotate_rgb(rot: &Rotation, coeffs: &[[f64; 3]], order: usize) -> Vec<[f64; 3]> {
    let mut out = vec![[0.0; 3]; coeffs.len()];
    for l in 0..order {
        let band = rot.band(l);
        let w = 2 * l + 1;
        let start = l * l;
        for row in 0..w {
            let mut acc = [0.0f64; 3];
            for (a, c) in band[row * w..(row + 1) * w]
                .iter()
                .zip(&coeffs[start..start + w])
            {
                for ch in 0..3 {
                    acc[ch] += a * c[ch];
                }
            }
            out[start + row] = acc;
        }
    }
    out
}

/// The diffuse material of the receiving points.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DiffuseParams {
    /// `albedo / π` per channel, applied once to `L · T` (the transfer excludes it).
    pub albedo_over_pi: [f32; 3],
}

impl DiffuseParams {
    /// From the albedo of `CONVENTIONS.md` (`f = albedo/π`).
    #[must_use]
    pub fn from_albedo(albedo: [f32; 3]) -> Self {
        Self {
            albedo_over_pi: albedo.map(|a| a / std::f32::consts::PI),
        }
    }
}

/// The specular part of the `phong` material of `CONVENTIONS.md`:
/// `specular · (e+2)/(2π) · max(0, r·ω_i)^e`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PhongParams {
    /// Specular reflectance per channel.
    pub specular: [f32; 3],
    /// Phong exponent `e ≥ 0`.
    pub exponent: f32,
}

/// Where the shaded points are.
#[derive(Clone, Copy, Debug)]
pub struct Surface<'a> {
    /// World-space positions (used with [`Viewer::Eye`]).
    pub positions: &'a [[f32; 3]],
    /// Unit shading normals.
    pub normals: &'a [[f32; 3]],
}

/// Where the viewer is.
#[derive(Clone, Copy, Debug)]
pub enum Viewer<'a> {
    /// A pinhole at this world position: `ω_o = normalize(eye − position)`.
    Eye([f32; 3]),
    /// One unit direction `ω_o` toward the viewer per point.
    Directions(&'a [[f32; 3]]),
}

/// Most zonal lobes a [`FittedLobe`] may sum per elevation.
pub const MAX_FITTED_LOBES: usize = 4;

/// A glossy lobe (Blinn–Phong, Ward, Cook–Torrance, the glTF metallic-roughness BRDF)
/// approximated, per view elevation `θ_o`, by a sum of `K` zonal lobes about axes in the plane
/// of the normal and the view (Ramamoorthi 2002, ch. 5: reparameterised about the reflection
/// direction, a microfacet lobe is nearly zonal; where it is not — grazing views — further
/// lobes beside the first capture its asymmetry). With `g(ω_i) = f_s(ω_i, ω_o) max(0, cos θ_i)`
/// the table holds, per elevation, the axes `a_k` and the multipliers `A^k_l` of the
/// least-squares fit `Σ_k Σ_l (2l+1)/(4π) A^k_l P_l(a_k·ω)` of `g` above the horizon, so the
/// specular radiance is `scale_c Σ_lm w_lm (L ⊛ V)_lm` with `w_lm = Σ_k A^k_l y_lm(a_k)` — the
/// products of the Phong path, with a per-point lobe whose weights cost `K` basis evaluations.
/// Tables are linear in `θ_o` between rows.
///
/// Colour: with one lobe shape the radiance is `a_c` times it. With two (`bands_b`), channel
/// `c` wants `a_c·A + b_c·B` — a shape per channel, where the kernels take one: the point's
/// shape is the luminance mix `α·A + β·B` (`α = lum(a)`, `β = lum(b)`) and each channel is
/// scaled to its own energy, `(a_c E_A + b_c E_B) / (α E_A + β E_B)` with `E` a lobe's
/// integral (`Σ_k A^k_0`). Exact when `a` and `b` are proportional across channels — every
/// dielectric of the glTF material (`a = 0.04`, `b = 0.96`) and grey metals.
#[derive(Clone, Copy, Debug)]
pub struct FittedLobe<'a> {
    /// View elevations `θ_o` in radians, strictly increasing, at least 2.
    pub elevations: &'a [f32],
    /// Roughness levels the table holds, increasing (one level: a single table). The rows
    /// below are stacked `[level][elevation]`; a point's row is bilinear in (its roughness,
    /// `θ_o`), clamped to the grid.
    pub roughness: &'a [f32],
    /// Each point's roughness, or one for all points.
    pub point_roughness: &'a [f32],
    /// Zonal lobes per elevation, `1..=MAX_FITTED_LOBES`.
    pub lobes: usize,
    /// `[elevation][lobe]` axis angles from the normal toward the mirror direction (radians;
    /// `θ_o` is the mirror direction itself).
    pub axis: &'a [f32],
    /// Order of the table's rows (at least the relighter's).
    pub order: usize,
    /// `[elevation][lobe][band]` multipliers `A^k_l`.
    pub bands: &'a [f32],
    /// Empty, or a second lobe on the same axes (`[elevation][lobe][band]`) for materials
    /// whose colour weights two lobe shapes (the glTF material: `A·(D·V) + B·(s·D·V)`).
    pub bands_b: &'a [f32],
    /// Colour weight `a` per point, or one for all points.
    pub colour_a: &'a [[f32; 3]],
    /// Colour weight `b` of `bands_b` per point, or one for all points (ignored without it).
    pub colour_b: &'a [[f32; 3]],
}

/// A specular lobe the relighter can shade.
#[derive(Clone, Copy, Debug)]
pub enum SpecularLobe<'a> {
    /// The `phong` material's lobe (zonal about the reflection direction; cosine frozen).
    Phong(PhongParams),
    /// A tabulated zonal fit of a glossy lobe ([`FittedLobe`]).
    Fitted(FittedLobe<'a>),
}

/// Everything specular shading needs besides the lighting.
#[derive(Clone, Copy, Debug)]
pub struct SpecularInput<'a> {
    /// Visibility transfer `V_i = ∫ vis(ω) y_i(ω) dω`, 1 channel.
    pub visibility: TransferView<'a>,
    /// Positions and normals.
    pub surface: Surface<'a>,
    /// The viewer.
    pub viewer: Viewer<'a>,
    /// The material's specular lobe.
    pub lobe: SpecularLobe<'a>,
}
