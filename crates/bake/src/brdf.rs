//! BRDF projections stored with a bake: zonal coefficients of the clamped cosine and of
//! normalised Phong lobes (closed form, `prt_sh::zonal`), and for isotropic glossy BRDFs
//! without a zonal form (Blinn–Phong, Ward, Cook–Torrance) the per-view-elevation SH
//! projections of `f_s(ω_i, ω_o) max(0, cos θ_i)` (Kautz, Sloan & Snyder 2002), where `f_s` is
//! the specular part with unit specular colour (relighting multiplies by the material's
//! `specular`; the diffuse part is the baked diffuse transfer).

use glam::{DVec3, Vec3};
use prt_bakefile::{BrdfLobe, BrdfProjection, GlossyBrdfTable};
use prt_scene::Material;
use prt_sh::quadrature::SphereQuadrature;
use prt_sh::{zonal, Basis};

/// Number of tabulated view elevations, `θ_o = (k + ½)/N · π/2`.
pub const ELEVATIONS: usize = 16;

/// Zonal projections of a material's lobes, named `<material>/diffuse` (the clamped cosine)
/// and `<material>/specular` (the normalised Phong lobe `(e+1)/(2π) cos^e`, Phong only).
#[must_use]
pub fn zonal_projection(name: &str, material: &Material, order: usize) -> Vec<BrdfProjection> {
    let cc = zonal::bands_to_zonal(&zonal::clamped_cosine_bands(order).expect("order checked"));
    let mut out = vec![BrdfProjection {
        material: format!("{name}/diffuse"),
        lobe: BrdfLobe::ClampedCosine,
        order: order as u32,
        values: cc,
    }];
    if let Material::Phong { exponent, .. } = material {
        let e = f64::from(*exponent);
        out.push(BrdfProjection {
            material: format!("{name}/specular"),
            lobe: BrdfLobe::Phong { exponent: e },
            order: order as u32,
            values: zonal::bands_to_zonal(
                &zonal::phong_lobe_bands(e, order).expect("exponent validated by the scene"),
            ),
        });
    }
    out
}

fn specular_only(material: &Material) -> Material {
    let zero = [0.0; 3];
    let one = [1.0; 3];
    match *material {
        Material::BlinnPhong { exponent, .. } => Material::BlinnPhong {
            albedo: zero,
            specular: one,
            exponent,
        },
        Material::Ward { roughness, .. } => Material::Ward {
            albedo: zero,
            specular: one,
            roughness,
        },
        Material::CookTorrance { roughness, ior, .. } => Material::CookTorrance {
            albedo: zero,
            specular: one,
            roughness,
            ior,
        },
        ref m => *m,
    }
}

/// Per-elevation projections of an isotropic glossy BRDF's specular part to `order`, with the
/// relative L2 truncation error for every order `1..=order` (RMS over elevations).
///
/// The integrand is not smooth (clamped, peaked), so the product rule is not exact; it uses
/// a rule exact to degree `max(8·order, 256)`, ~33k directions, and the error estimate is
/// measured with the same rule. For `pbr` this is the [`PbrComponent::Dv`] table.
#[must_use]
pub fn glossy_table(material: &Material, order: usize) -> GlossyBrdfTable {
    if let Material::Pbr { roughness, .. } = *material {
        return pbr_table(roughness, PbrComponent::Dv, order);
    }
    let spec = specular_only(material);
    table_of(
        |wo, wi| f64::from(prt_shading::eval(&spec, Vec3::Z, wo, wi).x),
        order,
    )
}

/// The colour-independent parts of the `pbr` BRDF's view-dependent term (see
/// [`prt_shading::pbr_terms`]), each tabulated like a glossy BRDF; relighting weights them per
/// channel by `A = 0.04(1 − m) + m·c`, `B = 0.96(1 − m) + m(1 − c)` and
/// `C = −0.96(1 − m)·c`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PbrComponent {
    /// `D·V`.
    Dv,
    /// `s·D·V`.
    SchlickDv,
    /// `s/π`, the Fresnel-dependent part of the `(1 − F)` diffuse term.
    SchlickDiffuse,
}

impl PbrComponent {
    /// All three, in the order of their table names' suffixes.
    pub const ALL: [PbrComponent; 3] = [Self::Dv, Self::SchlickDv, Self::SchlickDiffuse];

    /// The suffix of the table's material name: `""`, `"/schlick"`, `"/schlick_diffuse"`.
    #[must_use]
    pub fn suffix(self) -> &'static str {
        match self {
            Self::Dv => "",
            Self::SchlickDv => "/schlick",
            Self::SchlickDiffuse => "/schlick_diffuse",
        }
    }

    /// Channel weight of this component for base colour `c` and metallic `m`.
    #[must_use]
    pub fn weight(self, c: f32, m: f32) -> f32 {
        match self {
            Self::Dv => 0.04 * (1.0 - m) + m * c,
            Self::SchlickDv => 0.96 * (1.0 - m) + m * (1.0 - c),
            Self::SchlickDiffuse => -0.96 * (1.0 - m) * c,
        }
    }
}

/// The table of one `pbr` component at `roughness`.
#[must_use]
pub fn pbr_table(roughness: f32, component: PbrComponent, order: usize) -> GlossyBrdfTable {
    table_of(
        |wo, wi| {
            let (dv, s) = prt_shading::pbr_terms(roughness, wo, wi);
            f64::from(match component {
                PbrComponent::Dv => dv,
                PbrComponent::SchlickDv => s * dv,
                PbrComponent::SchlickDiffuse => s * std::f32::consts::FRAC_1_PI,
            })
        },
        order,
    )
}

/// Per-elevation SH projections of `f(ω_i, ω_o) max(0, cos θ_i)` (local frame).
fn table_of(f: impl Fn(Vec3, Vec3) -> f64, order: usize) -> GlossyBrdfTable {
    let q = SphereQuadrature::exact_for_degree((8 * order).max(256));
    let basis = Basis::new(order).expect("order checked");
    let n2 = order * order;
    let mut elevations = Vec::with_capacity(ELEVATIONS);
    let mut values = Vec::with_capacity(ELEVATIONS * n2);
    let mut err2 = vec![0.0; order];
    let mut y = vec![0.0; n2];
    for k in 0..ELEVATIONS {
        let theta_o = (k as f64 + 0.5) / ELEVATIONS as f64 * std::f64::consts::FRAC_PI_2;
        elevations.push(theta_o);
        let wo = DVec3::new(theta_o.sin(), 0.0, theta_o.cos()).as_vec3();
        let mut c = vec![0.0; n2];
        let mut norm2 = 0.0;
        for (d, w) in q.dirs.iter().zip(&q.weights) {
            if d.z <= 0.0 {
                continue;
            }
            let v = f(wo, d.as_vec3()) * d.z;
            if v == 0.0 {
                continue;
            }
            basis.eval_unchecked(*d, &mut y);
            for i in 0..n2 {
                c[i] += w * v * y[i];
            }
            norm2 += w * v * v;
        }
        let mut kept = 0.0;
        for o in 1..=order {
            for i in (o - 1) * (o - 1)..o * o {
                kept += c[i] * c[i];
            }
            let rel = if norm2 > 0.0 {
                ((norm2 - kept).max(0.0) / norm2).sqrt()
            } else {
                0.0
            };
            err2[o - 1] += rel * rel / ELEVATIONS as f64;
        }
        values.extend(c);
    }
    GlossyBrdfTable {
        material: String::new(),
        order: order as u32,
        elevations,
        values,
        projection_error: err2.into_iter().map(f64::sqrt).collect(),
    }
}
