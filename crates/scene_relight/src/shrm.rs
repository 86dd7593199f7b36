//! Spherical harmonic reflection maps (SHRM; Ramamoorthi & Hanrahan 2002, "Frequency space
//! environment map rendering", and Ramamoorthi's thesis, ch. 5): the environment prefiltered
//! with an isotropic glossy BRDF in frequency space into a table over the reflected direction
//! `R`, the view elevation `θ_o` and the twist of the local frame about `R`, so that a sharp
//! lobe costs a table lookup per point instead of `O(order⁵)` products.
//!
//! **Reparameterisation.** At a point with normal `n` and view `ω_o` (elevation `θ_o`), the
//! specular radiance is `S = ∫ L(ω) h_{θ_o}(Wᵀω) dω` with `W = [x', y', R]` the *reflection
//! frame* (`R = 2(n·ω_o)n − ω_o`, `x'` the unit component of `n` orthogonal to `R`, so that `n`
//! sits at angle `θ_o` from `R` toward `+x'`) and `h_{θ_o}(ω') = f(ω_i, ω_o) max(0, cos θ_i)` in
//! that frame. A lobe about `R` is nearly zonal there (exactly so for Phong), so its SH
//! coefficients `b_lm(θ_o)` are concentrated at small `|m|`; isotropy makes `h` even in `y'`,
//! so only `m ≥ 0` (cosine) terms are non-zero. [`lobe_spectrum`] projects `h` to `order` bands
//! and `twist + 1` azimuthal orders by a product rule in the reflection frame (Gauss–Legendre
//! panels in `θ'` refined geometrically toward the pole, the trapezoid rule in `φ'`, exact for
//! trigonometric degree below its node count).
//!
//! **Prefiltering** ([`Shrm::prefilter`]). The table is a lat-long grid of `R` about world `+Z`:
//! texel `(θ_j, φ_k)` has the frame `T = R_z(φ_k) R_y(θ_j)`. With `Λ = Rot(Tᵀ) L` (the lighting
//! in that frame) and `W = T R_z(γ)`, `S(γ) = Σ_lm (Rot(R_z(−γ)) Λ)_lm b_lm
//! = Σ_{m=0..M} A_m cos mγ + B_m sin mγ`, `A_m = Σ_l b_lm Λ_lm`, `B_m = Σ_l b_lm Λ_l,−m`.
//! `Rot(Tᵀ) = Rot(R_y(−θ_j)) Rot(R_z(−φ_k))`: the `z` rotation is a 2×2 mix per `(l, ±m)`, the
//! `y` rotation is built once per grid row, and only its rows `|m| ≤ M` are applied — cost
//! `O(N_θ L³ + N_θ N_φ (M L² + K M L))` for `K` view elevations, against the angular-space
//! brute force ([`brute_force`]) `O(N_θ N_φ K N_env)` (thesis §5.6, Tables 5.4–5.5).
//!
//! **Lookup** ([`Shrm::lookup`]): bilinear over the four texels about `R` (each with the
//! point's twist measured in that texel's own frame, so the poles need no care), linear in
//! `θ_o`. A rotation `Q` of the same environment is a rotated lookup — `S_Q(R, W) = S(QᵀR,
//! QᵀW)` — not a new prefilter.

use crate::error::SceneRelightError;
use glam::{DMat3, DVec3};
use prt_scene::Material;
use prt_sh::{index, Basis, Rotation};
use rayon::prelude::*;
use std::f64::consts::{FRAC_PI_2, PI};

/// The BRDF an SHRM prefilters with: one or two colour-independent components of
/// `f(ω_i, ω_o) max(0, cos θ_i)` in the local frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ShrmLobe {
    /// Blinn–Phong, Ward or Cook–Torrance (or Phong) with unit specular colour and no diffuse
    /// part: one component, weighted by the material's `specular`.
    Specular(Material),
    /// The glTF material at a roughness: `D·V` and `s·D·V` (weighted per channel by
    /// `A = 0.04(1 − m) + m·c` and `B = 0.96(1 − m) + m(1 − c)`, as
    /// `prt_shading::projection::PbrComponent`).
    Pbr {
        /// Perceptual roughness (`α = roughness²`).
        roughness: f32,
    },
}

impl ShrmLobe {
    /// The lobe of `material`'s view-dependent specular term, if it has one.
    #[must_use]
    pub fn of(material: &Material) -> Option<Self> {
        let (zero, one) = ([0.0; 3], [1.0; 3]);
        Some(match *material {
            Material::Phong { exponent, .. } => Self::Specular(Material::Phong {
                albedo: zero,
                specular: one,
                exponent,
            }),
            Material::BlinnPhong { exponent, .. } => Self::Specular(Material::BlinnPhong {
                albedo: zero,
                specular: one,
                exponent,
            }),
            Material::Ward { roughness, .. } => Self::Specular(Material::Ward {
                albedo: zero,
                specular: one,
                roughness,
            }),
            Material::CookTorrance { roughness, ior, .. } => {
                Self::Specular(Material::CookTorrance {
                    albedo: zero,
                    specular: one,
                    roughness,
                    ior,
                })
            }
            Material::Pbr { roughness, .. } => Self::Pbr { roughness },
            _ => return None,
        })
    }

    /// Number of components (1, or 2 for `pbr`).
    #[must_use]
    pub fn components(&self) -> usize {
        match self {
            Self::Specular(_) => 1,
            Self::Pbr { .. } => 2,
        }
    }

    /// `f_q(ω_i, ω_o) max(0, cos θ_i)` of each component at local directions (normal `+Z`).
    #[must_use]
    pub fn eval(&self, wo: DVec3, wi: DVec3) -> [f64; 2] {
        if wi.z <= 0.0 || wo.z <= 0.0 {
            return [0.0; 2];
        }
        let (o, i) = (wo.as_vec3(), wi.as_vec3());
        match self {
            Self::Specular(m) => [
                f64::from(prt_shading::eval(m, glam::Vec3::Z, o, i).x) * wi.z,
                0.0,
            ],
            Self::Pbr { roughness } => {
                let (dv, s) = prt_shading::pbr_terms(*roughness, o, i);
                [f64::from(dv) * wi.z, f64::from(s * dv) * wi.z]
            }
        }
    }
}

/// The reflection-frame SH spectrum of a lobe at tabulated view elevations.
#[derive(Clone, Debug)]
pub struct LobeSpectrum {
    /// Components (1, or 2 for `pbr`).
    pub components: usize,
    /// SH order (bands) of the coefficients.
    pub order: usize,
    /// Largest azimuthal order `M` kept (the twist's Fourier degree).
    pub twist: usize,
    /// View elevations `θ_o` (radians), `(k + ½)/K · π/2`.
    pub elevations: Vec<f64>,
    /// `b_lm` stacked `[elevation][component][m][l]` (`m = 0..=twist`, `l = 0..order`; zero
    /// for `l < m`).
    pub coeffs: Vec<f64>,
    /// `‖h‖²` per `[elevation][component]`.
    pub norm2: Vec<f64>,
}

/// `θ'` quadrature of the reflection frame: Gauss–Legendre panels refined geometrically toward
/// the pole (where a sharp lobe sits) and uniform beyond; nodes and weights (`sin θ'`
/// included).
fn theta_nodes() -> Vec<(f64, f64)> {
    const NODES: usize = 20;
    let (x, w) = prt_sh::quadrature::gauss_legendre(NODES);
    let mut edges = vec![0.0];
    let mut e = 0.002;
    while e < PI / 16.0 {
        edges.push(e);
        e *= 2.0;
    }
    let start = *edges.last().unwrap_or(&0.0);
    let panels = ((PI - start) / (PI / 24.0)).ceil() as usize;
    edges.extend((1..=panels).map(|i| start + (PI - start) * i as f64 / panels as f64));
    let mut out = Vec::new();
    for p in edges.windows(2) {
        let (a, b) = (p[0], p[1]);
        for (xi, wi) in x.iter().zip(&w) {
            let t = 0.5 * (a + b) + 0.5 * (b - a) * xi;
            out.push((t, 0.5 * (b - a) * wi * t.sin()));
        }
    }
    out
}

/// Azimuthal nodes of the reflection-frame rule (trapezoid, exact for trigonometric degree
/// below it: the lobe's clipped edge at grazing views wants many).
const PHI_NODES: usize = 512;

/// Projects `lobe` in its reflection frame to `order` bands and azimuthal orders `0..=twist`
/// at `elevations` view elevations `(k + ½)/K · π/2`.
///
/// # Errors
/// An order the SH basis refuses.
pub fn lobe_spectrum(
    lobe: ShrmLobe,
    order: usize,
    twist: usize,
    elevations: usize,
) -> Result<LobeSpectrum, SceneRelightError> {
    spectrum_of(
        &|wo, wi| lobe.eval(wo, wi),
        lobe.components(),
        order,
        twist,
        elevations,
    )
}

/// [`lobe_spectrum`] of any lobe `h(ω_o, ω_i)` (local directions; `nq ≤ 2` components),
/// e.g. a closed form to check the projection against.
///
/// # Errors
/// An order the SH basis refuses, or more than two components.
pub fn spectrum_of(
    lobe: &(dyn Fn(DVec3, DVec3) -> [f64; 2] + Sync),
    nq: usize,
    order: usize,
    twist: usize,
    elevations: usize,
) -> Result<LobeSpectrum, SceneRelightError> {
    if !(1..=2).contains(&nq) || order == 0 || elevations == 0 {
        return Err(SceneRelightError::Invalid(format!(
            "SHRM lobe spectrum of {nq} components, order {order}, {elevations} elevations"
        )));
    }
    let basis = Basis::new(order)?;
    let twist = twist.min(order - 1);
    let thetas = theta_nodes();
    let elev: Vec<f64> = (0..elevations)
        .map(|k| (k as f64 + 0.5) / elevations as f64 * FRAC_PI_2)
        .collect();
    let rows: Vec<(Vec<f64>, Vec<f64>)> = elev
        .par_iter()
        .map(|&t_o| {
            let (s, c) = t_o.sin_cos();
            let wo = DVec3::new(s, 0.0, c);
            // Reflection frame in local coordinates: x' = (c, 0, s), y' = +Y, z' = R.
            let g = DMat3::from_cols(DVec3::new(c, 0.0, s), DVec3::Y, DVec3::new(-s, 0.0, c));
            let mut b = vec![0.0; nq * (twist + 1) * order];
            let mut norm2 = vec![0.0; nq];
            let mut y = vec![0.0; order * order];
            for &(th, wt) in &thetas {
                let (st, ct) = th.sin_cos();
                // C_m(θ') = ∫ h cos mφ' dφ' per component.
                let mut cm = vec![0.0; nq * (twist + 1)];
                for j in 0..PHI_NODES {
                    let phi = 2.0 * PI * j as f64 / PHI_NODES as f64;
                    let (sp, cp) = phi.sin_cos();
                    let v = lobe(wo, g * DVec3::new(st * cp, st * sp, ct));
                    let dphi = 2.0 * PI / PHI_NODES as f64;
                    for q in 0..nq {
                        if v[q] == 0.0 {
                            continue;
                        }
                        norm2[q] += wt * dphi * v[q] * v[q];
                        for m in 0..=twist {
                            cm[q * (twist + 1) + m] += dphi * v[q] * (m as f64 * phi).cos();
                        }
                    }
                }
                basis.eval_unchecked(DVec3::new(st, 0.0, ct), &mut y);
                for q in 0..nq {
                    for m in 0..=twist {
                        let f = wt * cm[q * (twist + 1) + m];
                        let row = &mut b[(q * (twist + 1) + m) * order..][..order];
                        for (l, r) in row.iter_mut().enumerate().skip(m) {
                            *r += f * y[index(l, m as i64)];
                        }
                    }
                }
            }
            (b, norm2)
        })
        .collect();
    let (coeffs, norm2): (Vec<Vec<f64>>, Vec<Vec<f64>>) = rows.into_iter().unzip();
    Ok(LobeSpectrum {
        components: nq,
        order,
        twist,
        elevations: elev,
        coeffs: coeffs.concat(),
        norm2: norm2.concat(),
    })
}

impl LobeSpectrum {
    /// `b_lm` of elevation row `k`, component `q`.
    #[must_use]
    pub fn b(&self, k: usize, q: usize, l: usize, m: usize) -> f64 {
        let nq = self.components;
        self.coeffs[((k * nq + q) * (self.twist + 1) + m) * self.order + l]
    }

    /// Relative L2 error of the lobe truncated to `order` bands and azimuthal orders
    /// `≤ twist` (Parseval: `1 − kept energy / ‖h‖²`), RMS over the elevation rows and the
    /// components.
    #[must_use]
    pub fn truncation_error(&self, order: usize, twist: usize) -> f64 {
        let nq = self.components;
        let mut sum = 0.0;
        let mut count = 0.0;
        for k in 0..self.elevations.len() {
            for q in 0..nq {
                let n2 = self.norm2[k * nq + q];
                if n2 <= 0.0 {
                    continue;
                }
                let mut kept = 0.0;
                for m in 0..=twist.min(self.twist) {
                    for l in m..order.min(self.order) {
                        kept += self.b(k, q, l, m).powi(2);
                    }
                }
                sum += ((n2 - kept).max(0.0) / n2).max(0.0);
                count += 1.0;
            }
        }
        (sum / f64::max(count, 1.0)).sqrt()
    }

    /// The relative RMS error of the shading under a lighting of band powers `power`
    /// (`P_l = Σ_m L_lm²`) when the lobe is cut to `order` bands and azimuthal orders
    /// `≤ twist`, averaged over the lighting's rotations: each rotated coefficient has variance
    /// `P_l / (2l + 1)`, so `E[S²] = Σ_lm b_lm² P_l / (2l + 1)` and the cut drops the terms
    /// outside the kept `(l, m)` (thesis §5.5: the error is in the product of the two spectra,
    /// not the lobe's alone — a lobe's kink at the horizon has slowly decaying coefficients a
    /// natural lighting's falling spectrum barely meets). RMS over the elevations and
    /// components; terms beyond this spectrum's own order and twist are not counted.
    #[must_use]
    pub fn shading_error(&self, order: usize, twist: usize, power: &[f64]) -> f64 {
        let nq = self.components;
        let (mut sum, mut count) = (0.0, 0.0);
        for k in 0..self.elevations.len() {
            for q in 0..nq {
                let (mut all, mut kept) = (0.0, 0.0);
                for m in 0..=self.twist {
                    for l in m..self.order.min(power.len()) {
                        let v = self.b(k, q, l, m).powi(2) * power[l] / (2 * l + 1) as f64;
                        all += v;
                        if l < order && m <= twist {
                            kept += v;
                        }
                    }
                }
                if all > 0.0 {
                    sum += (all - kept).max(0.0) / all;
                    count += 1.0;
                }
            }
        }
        (sum / f64::max(count, 1.0)).sqrt()
    }

    /// The smallest order and twist whose [`Self::shading_error`] under band powers `power`
    /// is within `tolerance / √2` each (the other at its largest), capped at this spectrum's.
    #[must_use]
    pub fn choose(&self, tolerance: f64, power: &[f64]) -> (usize, usize) {
        let t = tolerance / std::f64::consts::SQRT_2;
        let order = (1..=self.order)
            .find(|&o| self.shading_error(o, self.twist, power) <= t)
            .unwrap_or(self.order);
        let twist = (0..=self.twist)
            .find(|&m| self.shading_error(self.order, m, power) <= t)
            .unwrap_or(self.twist);
        (order, twist.min(order - 1))
    }

    /// Band powers `P_l = Σ_m L_lm²` of RGB coefficients (luminance weights), `l < order`.
    #[must_use]
    pub fn band_power(lighting: &[[f64; 3]], order: usize) -> Vec<f64> {
        (0..order)
            .map(|l| {
                lighting[l * l..((l + 1) * (l + 1)).min(lighting.len())]
                    .iter()
                    .map(|c| (0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]).powi(2))
                    .sum()
            })
            .collect()
    }

    /// The spectrum cut to `order` bands and azimuthal orders `≤ twist`.
    #[must_use]
    pub fn truncated(&self, order: usize, twist: usize) -> Self {
        let (order, twist) = (order.min(self.order), twist.min(self.twist).min(order - 1));
        let nq = self.components;
        let mut coeffs = Vec::new();
        for k in 0..self.elevations.len() {
            for q in 0..nq {
                for m in 0..=twist {
                    coeffs.extend((0..order).map(|l| self.b(k, q, l, m)));
                }
            }
        }
        Self {
            components: self.components,
            order,
            twist,
            elevations: self.elevations.clone(),
            coeffs,
            norm2: self.norm2.clone(),
        }
    }
}

/// The coefficients of `g(ω) = f(R_z(ψ)⁻¹ ω)`: per band and `m > 0`,
/// `g_m = cos mψ f_m − sin mψ f_−m`, `g_−m = sin mψ f_m + cos mψ f_−m` (the basis' azimuthal
/// factors are `cos mφ` for `m > 0` and `sin |m|φ` for `m < 0`).
pub fn rotate_z(f: &[f64], order: usize, psi: f64, out: &mut [f64]) {
    for l in 0..order {
        out[index(l, 0)] = f[index(l, 0)];
        for m in 1..=l as i64 {
            let (s, c) = (m as f64 * psi).sin_cos();
            let (a, b) = (f[index(l, m)], f[index(l, -m)]);
            out[index(l, m)] = c * a - s * b;
            out[index(l, -m)] = s * a + c * b;
        }
    }
}

/// A prefiltered SHRM: per texel of the `R` grid, per view elevation, component and channel,
/// the twist Fourier coefficients `[A_0, A_1, B_1, …, A_M, B_M]`.
#[derive(Clone, Debug)]
pub struct Shrm {
    /// SH order of the prefiltering.
    pub order: usize,
    /// Twist Fourier degree `M`.
    pub twist: usize,
    /// Grid rows over `θ_R ∈ [0, π]` (poles included).
    pub rows: usize,
    /// Grid columns over `φ_R ∈ [0, 2π)`.
    pub cols: usize,
    /// View elevations (radians).
    pub elevations: Vec<f64>,
    /// Components (1, or 2 for `pbr`).
    pub components: usize,
    /// `[texel][elevation][component][channel][2M + 1]`, texel `= row · cols + col`.
    pub table: Vec<f32>,
    /// Per grid row `(sin θ_j, cos θ_j)` and per column `(sin φ_k, cos φ_k)`: the texel
    /// frames the lookup measures the twist in, without trigonometry per lookup.
    grid_trig: (Vec<SinCos>, Vec<SinCos>),
}

/// `(sin, cos)` of an angle.
type SinCos = (f64, f64);

/// `(sin, cos)` of every grid row's `θ_j = π j / (rows − 1)` and column's `φ_k = 2π k / cols`.
fn grid_trig(rows: usize, cols: usize) -> (Vec<SinCos>, Vec<SinCos>) {
    (
        (0..rows).map(|j| grid_sin_cos(j, rows - 1, PI)).collect(),
        (0..cols).map(|k| grid_sin_cos(k, cols, 2.0 * PI)).collect(),
    )
}

/// Largest twist Fourier degree a table may have.
pub const MAX_TWIST: usize = 16;

impl Shrm {
    /// The table with its components summed under per-channel weights `w[q][c]` (one
    /// component): for a material whose colour weights are the same at every point, half the
    /// memory and lookups of the two-component `pbr` table.
    #[must_use]
    pub fn combined(&self, w: [[f32; 3]; 2]) -> Self {
        let (ne, nq, nt) = (self.elevations.len(), self.components, 2 * self.twist + 1);
        let texels = self.rows * self.cols;
        let mut table = Vec::with_capacity(texels * ne * 3 * nt);
        for chunk in self.table.chunks_exact(nq * 3 * nt) {
            for c in 0..3 {
                for t in 0..nt {
                    let v: f32 = (0..nq).map(|q| w[q][c] * chunk[(q * 3 + c) * nt + t]).sum();
                    table.push(v);
                }
            }
        }
        Self {
            components: 1,
            table,
            elevations: self.elevations.clone(),
            grid_trig: self.grid_trig.clone(),
            ..*self
        }
    }
}

/// The `R` direction of grid row `j` of `rows` and column `k` of `cols`, and its frame `T`.
#[must_use]
pub fn texel_frame(j: usize, k: usize, rows: usize, cols: usize) -> DMat3 {
    let theta = PI * j as f64 / (rows - 1) as f64;
    let phi = 2.0 * PI * k as f64 / cols as f64;
    DMat3::from_rotation_z(phi) * DMat3::from_rotation_y(theta)
}

impl Shrm {
    /// Prefilters `lighting` (RGB SH coefficients `[coeff][channel]`, at least
    /// `spectrum.order²` of them) with `spectrum` into a `rows × cols` grid.
    ///
    /// # Errors
    /// Too few lighting coefficients, a grid smaller than 3 × 4, or an order the SH rotation
    /// refuses.
    pub fn prefilter(
        spectrum: &LobeSpectrum,
        lighting: &[[f64; 3]],
        rows: usize,
        cols: usize,
    ) -> Result<Self, SceneRelightError> {
        let (order, twist) = (spectrum.order, spectrum.twist);
        if lighting.len() < order * order || rows < 3 || cols < 4 || twist > MAX_TWIST {
            return Err(SceneRelightError::Invalid(format!(
                "SHRM of order {order}, twist {twist} (at most {MAX_TWIST}) on a {rows} × {cols} grid from {} lighting coefficients",
                lighting.len()
            )));
        }
        let (ne, nq, nt) = (
            spectrum.elevations.len(),
            spectrum.components,
            2 * twist + 1,
        );
        let per_texel = ne * nq * 3 * nt;
        let light: Vec<Vec<f64>> = (0..3)
            .map(|c| lighting[..order * order].iter().map(|v| v[c]).collect())
            .collect();
        let row_tables: Vec<Vec<f32>> = (0..rows)
            .into_par_iter()
            .map(|j| {
                let theta = PI * j as f64 / (rows - 1) as f64;
                let rot = Rotation::new(order, DMat3::from_rotation_y(-theta))?;
                let mut out = vec![0.0f32; cols * per_texel];
                let mut z = vec![0.0; order * order];
                // Λ_l,±m for m ≤ M: [channel][m][l] (cos part) and sin part.
                let mut lam_c = vec![0.0; (twist + 1) * order];
                let mut lam_s = vec![0.0; (twist + 1) * order];
                for k in 0..cols {
                    let phi = 2.0 * PI * k as f64 / cols as f64;
                    for (c, lc) in light.iter().enumerate() {
                        rotate_z(lc, order, -phi, &mut z);
                        rotated_low_m(&rot, &z, order, twist, &mut lam_c, &mut lam_s);
                        for e in 0..ne {
                            for q in 0..nq {
                                let base = k * per_texel + ((e * nq + q) * 3 + c) * nt;
                                for m in 0..=twist {
                                    let (mut a, mut b) = (0.0, 0.0);
                                    for l in m..order {
                                        let w = spectrum.b(e, q, l, m);
                                        a += w * lam_c[m * order + l];
                                        b += w * lam_s[m * order + l];
                                    }
                                    if m == 0 {
                                        out[base] = a as f32;
                                    } else {
                                        out[base + 2 * m - 1] = a as f32;
                                        out[base + 2 * m] = b as f32;
                                    }
                                }
                            }
                        }
                    }
                }
                Ok(out)
            })
            .collect::<Result<_, SceneRelightError>>()?;
        Ok(Self {
            order,
            twist,
            rows,
            cols,
            elevations: spectrum.elevations.clone(),
            components: nq,
            table: row_tables.concat(),
            grid_trig: grid_trig(rows, cols),
        })
    }
}

/// Rows `|m| ≤ twist` of `rot` applied to `z`: `Λ_l,m` into `cos[m][l]`, `Λ_l,−m` into
/// `sin[m][l]` (`sin[0]` unused).
fn rotated_low_m(
    rot: &Rotation,
    z: &[f64],
    order: usize,
    twist: usize,
    cos: &mut [f64],
    sin: &mut [f64],
) {
    for l in 0..order {
        let band = rot.band(l);
        let w = 2 * l + 1;
        let zl = &z[l * l..l * l + w];
        let row = |m: i64| -> f64 {
            let r = &band[(m + l as i64) as usize * w..][..w];
            r.iter().zip(zl).map(|(a, b)| a * b).sum()
        };
        for m in 0..=twist.min(l) {
            cos[m * order + l] = row(m as i64);
            if m > 0 {
                sin[m * order + l] = row(-(m as i64));
            }
        }
    }
}

impl Shrm {
    /// The unweighted specular `S_q,c` of every component `q` at a point with normal `n`
    /// and direction to the viewer `wo` (unit, world), the environment rotated by `env` (the
    /// lookup is at `envᵀR`); zero when the point faces away.
    #[must_use]
    pub fn lookup(&self, n: DVec3, wo: DVec3, env: Option<&DMat3>) -> [[f64; 3]; 2] {
        let cos_o = n.dot(wo);
        if cos_o.is_nan() || cos_o <= 0.0 {
            return [[0.0; 3]; 2];
        }
        let (mut r, mut n) = (2.0 * cos_o * n - wo, n);
        if let Some(q) = env {
            r = q.transpose() * r;
            n = q.transpose() * n;
        }
        // x': the component of n orthogonal to R (any, at normal view).
        let mut xp = n - cos_o * r;
        if xp.length_squared() < 1e-16 {
            xp = r.any_orthonormal_vector();
        }
        let xp = xp.normalize();
        let theta_o = cos_o.min(1.0).acos();
        let (e0, te) = locate(&self.elevations, theta_o);
        let tr = r.z.clamp(-1.0, 1.0).acos() / PI * (self.rows - 1) as f64;
        let j0 = (tr.floor() as usize).min(self.rows - 2);
        let fj = tr - j0 as f64;
        let mut tp = r.y.atan2(r.x) / (2.0 * PI) * self.cols as f64;
        if tp < 0.0 {
            tp += self.cols as f64;
        }
        let k0 = (tp.floor() as usize).min(self.cols - 1);
        let fk = tp - k0 as f64;
        let nt = 2 * self.twist + 1;
        let per_texel = self.elevations.len() * self.components * 3 * nt;
        let (row_trig, col_trig) = &self.grid_trig;
        // The four texels about R: bilinear weights, where each starts, and the point's twist
        // (cos γ, sin γ) measured in that texel's own frame T = R_z(φ) R_y(θ), whose axes are
        // x = (cθ cφ, cθ sφ, −sθ), y = (−sφ, cφ, 0).
        let mut weight = [0.0f32; 4];
        let mut start = [0usize; 4];
        let (mut c1, mut s1) = ([1.0f32; 4], [0.0f32; 4]);
        for (i, (dj, dk)) in [(0, 0), (0, 1), (1, 0), (1, 1)].into_iter().enumerate() {
            let (j, k) = (j0 + dj, (k0 + dk) % self.cols);
            weight[i] = ((if dj == 0 { 1.0 - fj } else { fj })
                * (if dk == 0 { 1.0 - fk } else { fk })) as f32;
            start[i] = (j * self.cols + k) * per_texel;
            let ((st, ct), (sp, cp)) = (row_trig[j], col_trig[k]);
            let a = xp.x * ct * cp + xp.y * ct * sp - xp.z * st;
            let b = -xp.x * sp + xp.y * cp;
            let h = (a * a + b * b).sqrt();
            if h > 1e-12 {
                (c1[i], s1[i]) = ((a / h) as f32, (b / h) as f32);
            }
        }
        // [1, cos γ, sin γ, …, cos Mγ, sin Mγ] of the four texels at once (angle addition).
        let mut trig = [[1.0f32; 4]; 2 * MAX_TWIST + 1];
        let (mut c, mut s) = ([1.0f32; 4], [0.0f32; 4]);
        for m in 1..=self.twist {
            for i in 0..4 {
                (c[i], s[i]) = (c[i] * c1[i] - s[i] * s1[i], s[i] * c1[i] + c[i] * s1[i]);
            }
            (trig[2 * m - 1], trig[2 * m]) = (c, s);
        }
        // Per component and channel, the eight weighted entries (four texels, two elevations)
        // dotted with their twist terms in f32, the table's precision.
        let mut acc = [[0.0f32; 3]; 2];
        let mut g = [0.0f32; 2 * MAX_TWIST + 1];
        let entry_len = self.components * 3 * nt;
        for i in 0..4 {
            if weight[i] == 0.0 {
                continue;
            }
            for (e, we) in [(e0, 1.0 - te as f32), (e0 + 1, te as f32)] {
                if we == 0.0 {
                    continue;
                }
                let scale = weight[i] * we;
                for (gt, t) in g[..nt].iter_mut().zip(&trig[..nt]) {
                    *gt = scale * t[i];
                }
                let entry = &self.table[start[i] + e * entry_len..][..entry_len];
                for (f, a) in entry.chunks_exact(nt).zip(acc.iter_mut().flatten()) {
                    *a += dot(f, &g[..nt]);
                }
            }
        }
        acc.map(|o| o.map(f64::from))
    }
}

/// `Σ a_i b_i` in four lanes (so that it vectorises; a fixed order, so deterministic).
#[inline]
fn dot(a: &[f32], b: &[f32]) -> f32 {
    let mut lanes = [0.0f32; 4];
    let (ca, cb) = (a.chunks_exact(4), b.chunks_exact(4));
    let (ra, rb) = (ca.remainder(), cb.remainder());
    for (x, y) in ca.zip(cb) {
        for ((s, xl), yl) in lanes.iter_mut().zip(x).zip(y) {
            *s += xl * yl;
        }
    }
    let tail: f32 = ra.iter().zip(rb).map(|(x, y)| x * y).sum();
    (lanes[0] + lanes[1]) + (lanes[2] + lanes[3]) + tail
}

/// `sin` and `cos` of `i / n · span` (a grid line's angle).
#[inline]
fn grid_sin_cos(i: usize, n: usize, span: f64) -> (f64, f64) {
    (span * i as f64 / n as f64).sin_cos()
}

/// Index and fraction of `x` in the increasing `grid`, clamped to its ends.
fn locate(grid: &[f64], x: f64) -> (usize, f64) {
    if grid.len() < 2 || x <= grid[0] {
        (0, 0.0)
    } else if x >= grid[grid.len() - 1] {
        (grid.len() - 2, 1.0)
    } else {
        let i = grid.partition_point(|&g| g <= x) - 1;
        (i, (x - grid[i]) / (grid[i + 1] - grid[i]))
    }
}

/// The angular-space brute force of one table entry: `S_q,c = ∫ L_c(Wω') h_q(ω') dω'` at the
/// reflected direction of texel `(j, k)`, view elevation `theta_o` and twist `gamma`, with the
/// environment given as a function of direction (`radiance`), integrated on the reflection
/// frame's product rule (the nodes [`lobe_spectrum`] uses; no SH anywhere).
pub fn brute_force(
    lobe: ShrmLobe,
    radiance: &(dyn Fn(DVec3) -> [f64; 3] + Sync),
    frame: DMat3,
    theta_o: f64,
    gamma: f64,
) -> [[f64; 3]; 2] {
    let (s, c) = theta_o.sin_cos();
    let wo = DVec3::new(s, 0.0, c);
    let g = DMat3::from_cols(DVec3::new(c, 0.0, s), DVec3::Y, DVec3::new(-s, 0.0, c));
    let w = frame * DMat3::from_rotation_z(gamma);
    let dphi = 2.0 * PI / PHI_NODES as f64;
    let mut out = [[0.0; 3]; 2];
    for (th, wt) in theta_nodes() {
        let (st, ct) = th.sin_cos();
        for j in 0..PHI_NODES {
            let phi = dphi * j as f64;
            let d = DVec3::new(st * phi.cos(), st * phi.sin(), ct);
            let v = lobe.eval(wo, g * d);
            if v == [0.0; 2] {
                continue;
            }
            let l = radiance(w * d);
            for (o, vq) in out.iter_mut().zip(v) {
                for (oc, lc) in o.iter_mut().zip(l) {
                    *oc += wt * dphi * vq * lc;
                }
            }
        }
    }
    out
}
