//! The glossy lobes without a zonal form (Blinn–Phong, Ward, Cook–Torrance, `pbr`) as
//! relighting shades them: each object's lobe (its shape at one or several roughness levels and
//! the colour weights of its components, [`GlossyLobe`]), the lobe's zonal fit per view
//! elevation in the f32 arrays prt-relight reads ([`FittedF32`], built once per process), and
//! the view-dependent terms `prt export` writes ([`view_dependent`]).

use crate::error::SceneRelightError;
use prt_scene::Material;
use serde::Serialize;

/// The relighting path of glossy lobes without a zonal form.
#[derive(Clone, Copy, Debug, Default, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum GlossyPath {
    /// A zonal fit of the lobe per view elevation about its mean direction
    /// (`prt_shading::projection::fitted_table`), shaded by the Phong kernels: full order and adaptive,
    /// at Phong's cost.
    #[default]
    Fitted,
    /// The bake's per-view-elevation BRDF projections, rotated per point and dotted with
    /// `L ⊛ V` (Kautz, Sloan & Snyder 2002): exact up to the order, `O(order⁵)` per point —
    /// the reference the fitted path is measured against.
    Exact,
    /// The fitted path, except at the points whose view elevation (and roughness) puts the
    /// fit's relative L2 error against the lobe at `fit_error` or more
    /// (`prt_shading::projection::FittedTable::error`, interpolated as the lobe rows are): those are
    /// shaded by the exact path. A sharp lobe is far from zonal at grazing views, where the fit
    /// falls behind; the hybrid spends the exact path's cost only there. `fit_error = 0`
    /// shades every point exactly, a value above every error none.
    Hybrid {
        /// The fit error from which a point is shaded exactly.
        fit_error: f32,
    },
    /// A spherical harmonic reflection map (Ramamoorthi & Hanrahan 2002; [`crate::shrm`]):
    /// the environment prefiltered with the lobe once per distinct environment to the order
    /// the lobe needs, looked up per point at its reflected direction, view elevation and
    /// twist, times a specular-occlusion factor from the bake's visibility (the fitted lobe's
    /// shadowed over unshadowed lighting at the bake's order — an approximation). The diffuse
    /// part is the bake's shadowed transfer, as on the fitted path.
    Shrm,
    /// Per object: [`GlossyPath::Shrm`] where the material's glossy lobe (Blinn–Phong, Ward,
    /// Cook–Torrance, `pbr`) loses more of its energy beyond the baked order than the bake's
    /// error target — the bake plan's rule, stated in its decision line — and
    /// [`GlossyPath::Fitted`] elsewhere ([`sharp_lobe`]).
    Auto,
}

impl GlossyPath {
    /// This path for an object of `bake` baked at `order` in the material named `name`:
    /// [`GlossyPath::Auto`] resolved by [`sharp_lobe`] (with a note naming `object` when it
    /// picks the SHRM), any other path as it is.
    pub(crate) fn for_object(
        self,
        bake: &prt_bakefile::Bake,
        (material, name): (&Material, &str),
        order: usize,
        (object, notes): (&str, &mut Vec<String>),
    ) -> Self {
        if self != Self::Auto {
            return self;
        }
        match sharp_lobe(bake, material, name, order) {
            Some((loss, target)) => {
                notes.push(format!(
                    "{object}: --glossy auto: SHRM (its lobe loses {loss:.2e} of its energy beyond the baked order {order}, above the bake's error target {target})"
                ));
                Self::Shrm
            }
            None => Self::Fitted,
        }
    }
}

/// Whether `material` (named `name` in the scene) has a glossy lobe without a zonal form that
/// is too sharp for an object baked at `order`: the fraction of its energy beyond that order
/// (the square of the relative L2 projection error the bake's BRDF table of the material
/// records, or [`prt_shading::projection::lobe_energy_beyond`] when it has none) and the
/// bake's error target, when the fraction is above the target. The bake plan raises the order
/// until the fraction is within the target, so a lobe is sharp here exactly when its order was
/// capped (`--max-order`) or fixed (`--order`) below what it needs.
#[must_use]
pub fn sharp_lobe(
    bake: &prt_bakefile::Bake,
    material: &Material,
    name: &str,
    order: usize,
) -> Option<(f64, f64)> {
    let target = bake
        .meta
        .settings
        .get("error_target")
        .and_then(serde_json::Value::as_f64)
        .unwrap_or(DEFAULT_ERROR_TARGET);
    // The bake's own table of the material when it has one to this order (free), else the
    // same projection computed here; `None` for materials without such a lobe.
    let stored = bake
        .glossy
        .iter()
        .find(|t| t.material == name)
        .and_then(|t| t.projection_error.get(order.checked_sub(1)?))
        .map(|e| e * e)
        .filter(|_| prt_shading::projection::has_fitted_lobe(material));
    let loss = match stored {
        Some(l) => l,
        None => prt_shading::projection::lobe_energy_beyond(material, order)?,
    };
    (loss > target).then_some((loss, target))
}

/// The bake's error target when a file does not record one (prt-bake's default).
const DEFAULT_ERROR_TARGET: f64 = 1e-3;

/// How the `phong` material's specular lobe is relit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum PhongModel {
    /// The light's cosine taken out of the integral at the lobe's centre (Sloan, Kautz &
    /// Snyder 2002; Lee & Kim 2014 eq. 4.4): `specular · (e+2)/(e+1) · max(0, n·ω_o) ·
    /// Σ_lm A_l (L ⊛ V)_lm y_lm(r)`, one zonal lobe about the mirror direction `r` (prt-relight's
    /// crate docs). Exact for a uniform environment only in the limit of a sharp lobe seen
    /// along the normal; measured against the path tracer it is 7.9 % off on a single
    /// unoccluded sphere of exponent 10 (crates/scene_relight/README.md). What relighting has
    /// always done, and its default.
    #[default]
    FrozenCosine,
    /// The cosine inside the integral: `g = f_s max(0, cos θ_i)` fitted per view elevation by
    /// zonal lobes about axes in the plane of the normal and the view, exactly as the glossy
    /// lobes without a zonal form are on [`GlossyPath::Fitted`]
    /// (`prt_shading::projection::fitted_table`), and shaded by the same kernels at the same
    /// cost: `specular ⊙ Σ_k Σ_lm A^k_l(θ_o) (L ⊛ V)_lm y_lm(a_k)`. Visibility enters as on the
    /// frozen-cosine path (the product `L ⊛ V` at the relit order). What `prt fit-lighting`
    /// inverts. The bake holds no per-elevation table for Phong, so with this model a Phong
    /// lobe takes the fitted path whatever [`GlossyPath`] says, except `Shrm`, whose lookup
    /// also has the cosine inside.
    Fitted,
}

/// A glossy lobe without a zonal form at one object: the material whose lobe shape is fitted
/// (for a `pbr` material that varies, its mean roughness), and the colour weights of its
/// components per point (one entry when uniform): `a`, `b` and, for the exact path of `pbr`,
/// `c` — the weights of the `D·V`, `s·D·V` and `s/π` tables (see
/// `prt_shading::projection::PbrComponent`); for the other lobes `a` is the specular colour.
pub(crate) struct GlossyLobe {
    /// The lobe shape at each roughness level the fit is made at (one unless a texture varies
    /// a `pbr` roughness).
    pub(crate) levels: Vec<Material>,
    /// Those levels' roughness (0 for the non-`pbr` lobes: one level).
    pub(crate) level_roughness: Vec<f32>,
    /// Each point's roughness (one value when uniform).
    pub(crate) point_roughness: Vec<f32>,
    pub(crate) colour_a: Vec<[f32; 3]>,
    pub(crate) colour_b: Vec<[f32; 3]>,
    pub(crate) colour_c: Vec<[f32; 3]>,
}

impl GlossyLobe {
    /// The `phong` material's lobe as a fitted glossy lobe ([`PhongModel::Fitted`]); `None`
    /// for other materials.
    pub(crate) fn phong(material: &Material) -> Option<Self> {
        match *material {
            Material::Phong { specular, .. } => Some(Self::single(material, specular)),
            _ => None,
        }
    }

    /// One lobe shape, `material`'s, of one specular colour (no roughness levels).
    fn single(material: &Material, specular: [f32; 3]) -> Self {
        Self {
            levels: vec![*material],
            level_roughness: vec![0.0],
            point_roughness: vec![0.0],
            colour_a: vec![specular],
            colour_b: vec![[0.0; 3]],
            colour_c: vec![[0.0; 3]],
        }
    }

    /// The lobe of `material` at an object named `object` (`points`: the material resolved per
    /// point when it varies over the surface); a note when a texture varies the roughness.
    pub(crate) fn of(
        material: &Material,
        points: Option<&[Material]>,
        notes: &mut Vec<String>,
        object: &str,
    ) -> Option<Self> {
        match *material {
            Material::BlinnPhong { specular, .. }
            | Material::Ward { specular, .. }
            | Material::CookTorrance { specular, .. } => Some(Self::single(material, specular)),
            Material::Pbr { roughness, .. } => {
                let mats: Vec<Material> = points.map_or_else(|| vec![*material], <[_]>::to_vec);
                let weights = |k: prt_shading::projection::PbrComponent| -> Vec<[f32; 3]> {
                    mats.iter()
                        .map(|m| match *m {
                            Material::Pbr {
                                base_color,
                                metallic,
                                ..
                            } => base_color.map(|c| k.weight(c, metallic)),
                            _ => [0.0; 3],
                        })
                        .collect()
                };
                use prt_shading::projection::PbrComponent as C;
                let rough: Vec<f32> = mats
                    .iter()
                    .map(|m| match *m {
                        Material::Pbr { roughness, .. } => roughness,
                        _ => roughness,
                    })
                    .collect();
                let lo = rough.iter().copied().fold(f32::INFINITY, f32::min);
                let hi = rough.iter().copied().fold(f32::NEG_INFINITY, f32::max);
                // A roughness texture: the lobe fitted at ROUGHNESS_LEVELS levels over the
                // points' range, each point's lobe bilinear in (roughness, θ_o).
                let (level_roughness, point_roughness) = if hi - lo > 0.02 {
                    notes.push(format!(
                        "{object}: roughness varies over the surface ({lo:.2}–{hi:.2}); the specular lobe is fitted at {ROUGHNESS_LEVELS} levels"
                    ));
                    let levels = (0..ROUGHNESS_LEVELS)
                        .map(|i| lo + (hi - lo) * i as f32 / (ROUGHNESS_LEVELS - 1) as f32)
                        .collect();
                    (levels, rough)
                } else {
                    (vec![lo], vec![lo])
                };
                let shape = |r: f32| Material::Pbr {
                    base_color: [1.0; 3],
                    metallic: 1.0,
                    roughness: r,
                    base_color_texture: None,
                    metallic_roughness_texture: None,
                };
                Some(Self {
                    levels: level_roughness.iter().map(|&r| shape(r)).collect(),
                    level_roughness,
                    point_roughness,
                    colour_a: weights(C::Dv),
                    colour_b: weights(C::SchlickDv),
                    colour_c: weights(C::SchlickDiffuse),
                })
            }
            _ => None,
        }
    }
}

/// Roughness levels of the fit when a texture varies a `pbr` roughness.
const ROUGHNESS_LEVELS: usize = 5;

/// The view-dependent terms [`crate::relight`] shades an object with at full order on the fitted
/// glossy path (the default): what `prt export` writes so that an engine relights to the
/// same radiance (SPEC §10.1).
pub struct ViewDependent {
    /// `pbr`: the table `(elevations, s̄_d)` of the diffuse factor `1 − s̄_d(θ_o)`.
    pub diffuse_fresnel: Option<(Vec<f32>, Vec<f32>)>,
    /// The specular lobe, if the material has one [`crate::relight`] shades.
    pub specular: Option<ExportLobe>,
}

/// A specular lobe as [`crate::relight`] shades it (SPEC §10.1).
pub enum ExportLobe {
    /// The `phong` material: its exponent and colour and the lobe's band multipliers.
    Phong {
        /// The Phong exponent.
        exponent: f32,
        /// The specular colour.
        specular: [f32; 3],
        /// The lobe's zonal band multipliers, one per band.
        bands: Vec<f32>,
    },
    /// A fitted lobe: [`prt_relight::FittedLobe`]'s tables (stacked `[level][elevation]`)
    /// and its colours and roughness, one or one per point.
    Fitted {
        /// The order the tables were fitted at.
        table_order: usize,
        /// Zonal lobes per table row.
        lobes: usize,
        /// The tabulated view elevations (radians).
        elevations: Vec<f32>,
        /// The roughness of each fitted level (one level, roughness 0, unless a texture varies a
        /// `pbr` roughness).
        roughness_levels: Vec<f32>,
        /// The fitted lobes' axes, stacked `[level][elevation]` as `prt_relight::FittedLobe`
        /// reads them.
        axis: Vec<f32>,
        /// The fitted lobes' band multipliers, stacked likewise.
        bands: Vec<f32>,
        /// Likewise for the table's second term (`pbr`'s Fresnel split; see `FittedLobe`).
        bands_b: Vec<f32>,
        /// The colour weighting `bands`, one or one per point.
        colour_a: Vec<[f32; 3]>,
        /// The colour weighting `bands_b`, one or one per point.
        colour_b: Vec<[f32; 3]>,
        /// Each point's roughness (one value when uniform).
        point_roughness: Vec<f32>,
    },
}

/// The view-dependent terms of `material` relit at `order` (`points`: the material resolved
/// per point when it varies over the surface), built by the same functions [`crate::relight`] uses.
pub fn view_dependent(
    material: &Material,
    points: Option<&[Material]>,
    order: usize,
) -> Result<ViewDependent, SceneRelightError> {
    let mut notes = Vec::new();
    let glossy = GlossyLobe::of(material, points, &mut notes, "");
    let fitted = glossy.as_ref().map(|g| {
        let tables: Vec<_> = g.levels.iter().map(|m| fitted_cached(m, order)).collect();
        FittedF32::stacked(&tables)
    });
    let diffuse_fresnel = match (&fitted, material) {
        (Some(f), Material::Pbr { .. }) => Some((f.elevations.clone(), f.diffuse_fresnel.clone())),
        _ => None,
    };
    let specular = match (material, glossy, fitted) {
        (
            Material::Phong {
                specular, exponent, ..
            },
            _,
            _,
        ) => Some(ExportLobe::Phong {
            exponent: *exponent,
            specular: *specular,
            bands: prt_sh::zonal::phong_lobe_bands(f64::from(*exponent), order)
                .map_err(|e| SceneRelightError::Invalid(e.to_string()))?
                .into_iter()
                .map(|a| a as f32)
                .collect(),
        }),
        (_, Some(g), Some(f)) => Some(ExportLobe::Fitted {
            table_order: f.order,
            lobes: f.lobes,
            elevations: f.elevations,
            roughness_levels: g.level_roughness,
            axis: f.axis,
            bands: f.bands,
            bands_b: f.bands_b,
            colour_a: g.colour_a,
            colour_b: g.colour_b,
            point_roughness: g.point_roughness,
        }),
        _ => None,
    };
    Ok(ViewDependent {
        diffuse_fresnel,
        specular,
    })
}

/// The fitted table of a lobe shape at an order, built once per process (a report relights
/// the same objects at many orders and settings; a table takes ~0.5 s to fit).
pub(crate) fn fitted_cached(shape: &Material, order: usize) -> std::sync::Arc<FittedF32> {
    type Cache = std::sync::Mutex<Vec<(Material, usize, std::sync::Arc<FittedF32>)>>;
    static CACHE: std::sync::OnceLock<Cache> = std::sync::OnceLock::new();
    let cache = CACHE.get_or_init(|| std::sync::Mutex::new(Vec::new()));
    if let Ok(c) = cache.lock() {
        if let Some((_, _, t)) = c.iter().find(|(m, o, _)| m == shape && *o == order) {
            return t.clone();
        }
    }
    let t = std::sync::Arc::new(FittedF32::new(
        &prt_shading::projection::fitted_table(shape, order)
            .expect("glossy materials have a fitted table"),
    ));
    if let Ok(mut c) = cache.lock() {
        c.push((*shape, order, t.clone()));
    }
    t
}

/// A [`prt_shading::projection::FittedTable`] in the f32 arrays prt-relight reads.
pub(crate) struct FittedF32 {
    pub(crate) order: usize,
    pub(crate) lobes: usize,
    pub(crate) elevations: Vec<f32>,
    pub(crate) axis: Vec<f32>,
    pub(crate) bands: Vec<f32>,
    pub(crate) bands_b: Vec<f32>,
    pub(crate) diffuse_fresnel: Vec<f32>,
    /// `[level][elevation]` relative L2 error of the fit against the lobe.
    pub(crate) error: Vec<f32>,
}

impl FittedF32 {
    fn new(t: &prt_shading::projection::FittedTable) -> Self {
        let f = |v: &[f64]| v.iter().map(|x| *x as f32).collect();
        Self {
            order: t.order,
            lobes: t.lobes,
            elevations: f(&t.elevations),
            axis: f(&t.axis),
            bands: f(&t.bands),
            bands_b: f(&t.bands_b),
            diffuse_fresnel: f(&t.diffuse_fresnel),
            error: f(&t.error),
        }
    }

    /// The tables of several roughness levels stacked `[level][elevation]` (their elevations
    /// and diffuse Fresnel factors are the same: neither depends on roughness).
    pub(crate) fn stacked(tables: &[std::sync::Arc<FittedF32>]) -> Self {
        let first = &tables[0];
        let cat =
            |f: fn(&FittedF32) -> &Vec<f32>| tables.iter().flat_map(|t| f(t).clone()).collect();
        Self {
            order: first.order,
            lobes: first.lobes,
            elevations: first.elevations.clone(),
            axis: cat(|t| &t.axis),
            bands: cat(|t| &t.bands),
            bands_b: cat(|t| &t.bands_b),
            diffuse_fresnel: first.diffuse_fresnel.clone(),
            error: cat(|t| &t.error),
        }
    }

    /// The fit's relative L2 error at `cos θ_o` and roughness `rough` (levels
    /// `level_roughness`): bilinear between rows as the lobe rows are, clamped to the grid.
    pub(crate) fn error_at(&self, cos_o: f32, rough: f32, level_roughness: &[f32]) -> f32 {
        let ne = self.elevations.len();
        let (ie, te) = prt_relight::grid_locate(&self.elevations, view_elevation(cos_o));
        let (ir, tr) = prt_relight::grid_locate(level_roughness, rough);
        let next = usize::from(level_roughness.len() > 1);
        let row =
            |r: usize| self.error[r * ne + ie] * (1.0 - te) + self.error[r * ne + ie + 1] * te;
        row(ir) * (1.0 - tr) + row(ir + next) * tr
    }

    /// `s̄_d` at `cos θ_o` (linear between rows, clamped to the ends).
    pub(crate) fn diffuse_fresnel_at(&self, cos_o: f32) -> f32 {
        let (i, t) = prt_relight::grid_locate(&self.elevations, view_elevation(cos_o));
        let v = &self.diffuse_fresnel;
        // The last row itself beyond it (not `a + (b − a)`, which may round off `b`).
        if t == 1.0 {
            v[i + 1]
        } else {
            v[i] + t * (v[i + 1] - v[i])
        }
    }
}

/// The view elevation `θ_o` of `cos θ_o`, capped at the horizon (points facing away read the
/// tables' last row).
fn view_elevation(cos_o: f32) -> f32 {
    cos_o
        .clamp(-1.0, 1.0)
        .acos()
        .min(std::f32::consts::FRAC_PI_2)
}
