//! The view-dependent terms of one object's material as relighting shades them: a Phong lobe,
//! or a glossy lobe without a zonal form on the fitted path, the exact path (the bake's
//! per-view-elevation BRDF tables) or the hybrid of the two, each against the object's baked
//! visibility; and, for `pbr` on the fitted path, the diffuse factor `1 − s̄_d(θ_o)`.

use crate::error::SceneRelightError;
use crate::lobe::{fitted_cached, FittedF32, GlossyLobe, GlossyPath, PhongModel};
use crate::points::{PointSet, Rows};
use glam::Vec3;
use prt_bakefile::{Bake, GlossyBrdfTable, TransferKind};
use prt_relight::{PhongParams, SpecularInput, Surface, TransferView, Viewer};
use prt_scene::{Material, Scene};

/// The specular terms of one object: its lobe on each path it is relit by, and the
/// visibility they are shaded against.
pub(crate) struct SpecularTerms<'b> {
    /// The `phong` material's lobe.
    phong: Option<PhongParams>,
    /// A glossy lobe without a zonal form.
    pub(crate) glossy: Option<GlossyLobe>,
    /// Its fitted table (fitted and hybrid paths).
    fitted: Option<FittedF32>,
    /// Its BRDF tables from the bake (exact and hybrid paths; one per `pbr` component).
    exact_tables: Option<Vec<&'b GlossyBrdfTable>>,
    /// The visibility rows of the points relit, when a lobe is shaded against them.
    vis_data: Option<std::borrow::Cow<'b, [f32]>>,
    /// Their low bands, for the adaptive path.
    vis_low: Option<Vec<f32>>,
}

impl<'b> SpecularTerms<'b> {
    /// The terms of object `o` of `scene` relit from `bake` along `path` (a `phong` lobe by
    /// `phong_model`), at the points `points` (whose materials are resolved per point when they
    /// vary); notes of what is not relit go to `notes`.
    pub(crate) fn new(
        scene: &Scene,
        bake: &'b Bake,
        o: usize,
        points: &PointSet,
        rows: &Rows<'_>,
        path: GlossyPath,
        phong_model: PhongModel,
        notes: &mut Vec<String>,
    ) -> Self {
        let (mesh, obj) = (&scene.meshes[o], &bake.objects[o]);
        let material = &scene.materials[mesh.material];
        let order = rows.order;
        // A Phong lobe with the cosine inside is a fitted glossy lobe, on the fitted path
        // whatever `path` says but SHRM (the bake has no per-elevation table for Phong).
        let fitted_phong = match phong_model {
            PhongModel::Fitted => GlossyLobe::phong(material),
            PhongModel::FrozenCosine => None,
        };
        let is_fitted_phong = fitted_phong.is_some();
        let path = match path {
            GlossyPath::Shrm => GlossyPath::Shrm,
            _ if is_fitted_phong => GlossyPath::Fitted,
            other => other,
        };
        let (phong, glossy) = match fitted_phong {
            Some(g) => (None, Some(g)),
            None => (
                phong_params(material, &obj.name, notes),
                GlossyLobe::of(material, points.materials.as_deref(), notes, &obj.name),
            ),
        };
        // The fitted lobe's table (built once per object, outside the timed frames).
        let fitted = match (&glossy, path) {
            (Some(g), GlossyPath::Fitted | GlossyPath::Hybrid { .. } | GlossyPath::Shrm) => {
                let tables: Vec<_> = g.levels.iter().map(|m| fitted_cached(m, order)).collect();
                Some(FittedF32::stacked(&tables))
            }
            _ => None,
        };
        // The exact path's tables from the bake.
        let material_name = scene
            .material_names
            .get(mesh.material)
            .cloned()
            .unwrap_or_default();
        let exact_tables = match (&glossy, path) {
            (Some(_), GlossyPath::Exact | GlossyPath::Hybrid { .. }) => {
                let is_pbr = matches!(material, Material::Pbr { .. });
                exact_tables(bake, &material_name, is_pbr, &obj.name, notes)
            }
            _ => None,
        };
        let vis_block = obj
            .blocks
            .iter()
            .find(|b| b.kind == TransferKind::Visibility);
        let wants_visibility = phong.is_some() || fitted.is_some() || exact_tables.is_some();
        let vis_data = match (wants_visibility, vis_block) {
            (true, Some(b)) => Some(rows.select(&b.data, 1)),
            (true, None) => {
                notes.push(format!(
                    "{}: no visibility transfer in the bake; specular not relit",
                    obj.name
                ));
                None
            }
            _ => None,
        };
        let vis_low = vis_data.as_ref().map(|v| prt_relight::low_bands(v, order));
        Self {
            phong,
            glossy,
            fitted,
            exact_tables,
            vis_data,
            vis_low,
        }
    }

    /// The fitted or Phong specular as prt-relight shades it at `order` for a viewer at
    /// `eye`, if the object has one and its visibility.
    ///
    /// # Errors
    /// A visibility the relighter refuses.
    pub(crate) fn input<'s>(
        &'s self,
        order: usize,
        points: &'s PointSet,
        eye: [f32; 3],
    ) -> Result<Option<SpecularInput<'s>>, SceneRelightError> {
        let lobe = match (self.phong, &self.fitted, &self.glossy) {
            (Some(p), _, _) => Some(prt_relight::SpecularLobe::Phong(p)),
            (None, Some(f), Some(g)) => {
                Some(prt_relight::SpecularLobe::Fitted(prt_relight::FittedLobe {
                    elevations: &f.elevations,
                    roughness: &g.level_roughness,
                    point_roughness: &g.point_roughness,
                    lobes: f.lobes,
                    axis: &f.axis,
                    order: f.order,
                    bands: &f.bands,
                    bands_b: &f.bands_b,
                    colour_a: &g.colour_a,
                    colour_b: &g.colour_b,
                }))
            }
            _ => None,
        };
        Ok(match (lobe, &self.vis_data, &self.vis_low) {
            (Some(lobe), Some(v), Some(low)) => Some(SpecularInput {
                visibility: TransferView::new(order, 1, v)?.with_low_bands(low)?,
                surface: Surface {
                    positions: &points.positions,
                    normals: &points.normals,
                },
                viewer: Viewer::Eye(eye),
                lobe,
            }),
            _ => None,
        })
    }

    /// The hybrid path's points shaded exactly (of the first `n` points): where the fit's
    /// error at the point's view elevation and roughness reaches the path's threshold, with a
    /// note of their share; `None` on the other paths.
    pub(crate) fn hybrid_exact_points(
        &self,
        path: GlossyPath,
        points: &PointSet,
        eye: [f32; 3],
        n: usize,
        object: &str,
        notes: &mut Vec<String>,
    ) -> Option<Vec<bool>> {
        let (GlossyPath::Hybrid { fit_error }, Some(f), Some(g), Some(_)) =
            (path, &self.fitted, &self.glossy, &self.exact_tables)
        else {
            return None;
        };
        let (positions, normals) = (&points.positions, &points.normals);
        // Per point: shaded exactly, and facing the viewer (the others have no
        // specular; the share is counted over those that do).
        let (chosen, facing): (Vec<bool>, Vec<bool>) = (0..n)
            .map(|p| {
                let nrm = Vec3::from_array(normals[p]);
                let wo =
                    (Vec3::from_array(eye) - Vec3::from_array(positions[p])).normalize_or_zero();
                let rough = if g.point_roughness.len() == 1 {
                    g.point_roughness[0]
                } else {
                    g.point_roughness[p]
                };
                let cos_o = nrm.dot(wo);
                (
                    f.error_at(cos_o, rough, &g.level_roughness) >= fit_error,
                    cos_o > 0.0,
                )
            })
            .unzip();
        let front = facing.iter().filter(|&&f| f).count();
        let k = chosen.iter().zip(&facing).filter(|(&c, &f)| c && f).count();
        notes.push(format!(
            "{object}: hybrid glossy path: {k} of the {front} points facing the viewer ({:.1} %), where the fit's error reaches {fit_error}, shaded exactly",
            100.0 * k as f64 / front.max(1) as f64
        ));
        Some(chosen)
    }

    /// Per-point diffuse albedo of the first `n` points (the diffuse term is relit with unit
    /// albedo when it varies): `material`'s, or the point's resolved material's, and for `pbr`
    /// on the fitted path times `1 − s̄_d(θ_o)`, the cosine-weighted mean of the `(1 − F)`
    /// factor's Schlick part (the exact path, at the points in `exact_points`, has it as a
    /// table).
    pub(crate) fn diffuse_scale(
        &self,
        material: &Material,
        points: &PointSet,
        exact_points: Option<&[bool]>,
        eye: [f32; 3],
        n: usize,
    ) -> Vec<[f32; 3]> {
        let is_pbr = matches!(material, Material::Pbr { .. });
        let albedo = material.albedo();
        (0..n)
            .map(|p| {
                let a = points.materials.as_ref().map_or(albedo, |m| m[p].albedo());
                let exact_here = exact_points.is_some_and(|e| e[p]);
                let keep = match (&self.fitted, is_pbr) {
                    (Some(f), true) if !exact_here => {
                        let nrm = Vec3::from_array(points.normals[p]);
                        let wo = (Vec3::from_array(eye) - Vec3::from_array(points.positions[p]))
                            .normalize_or_zero();
                        1.0 - f.diffuse_fresnel_at(nrm.dot(wo))
                    }
                    _ => 1.0,
                };
                a.map(|x| x * keep)
            })
            .collect()
    }

    /// The exact path at `order` for a viewer at `eye`, if the object is shaded by it (its
    /// tables and visibility are there).
    pub(crate) fn exact(&self, order: usize, eye: [f32; 3]) -> Option<ExactPath<'_>> {
        match (&self.exact_tables, &self.vis_data, &self.glossy) {
            (Some(tables), Some(vis), Some(lobe)) => Some(ExactPath {
                tables,
                vis,
                lobe,
                order,
                eye,
            }),
            _ => None,
        }
    }
}

/// The `phong` material's lobe; `None` for materials without a specular lobe or with one the
/// glossy paths shade, and a note for the others.
fn phong_params(material: &Material, object: &str, notes: &mut Vec<String>) -> Option<PhongParams> {
    match material {
        Material::Phong {
            specular, exponent, ..
        } => Some(PhongParams {
            specular: *specular,
            exponent: *exponent,
        }),
        Material::Lambert { .. }
        | Material::BlinnPhong { .. }
        | Material::Ward { .. }
        | Material::CookTorrance { .. }
        | Material::Pbr { .. } => None,
        other => {
            notes.push(format!(
                "{object}: the specular lobe of a {} material is not relit (diffuse part only)",
                other.type_name()
            ));
            None
        }
    }
}

/// The bake's BRDF tables of material `material_name` (one per component for `pbr`), or
/// `None` with a note when one is missing.
fn exact_tables<'b>(
    bake: &'b Bake,
    material_name: &str,
    is_pbr: bool,
    object: &str,
    notes: &mut Vec<String>,
) -> Option<Vec<&'b GlossyBrdfTable>> {
    let names: Vec<String> = if is_pbr {
        prt_shading::projection::PbrComponent::ALL
            .iter()
            .map(|c| format!("{material_name}{}", c.suffix()))
            .collect()
    } else {
        vec![material_name.to_owned()]
    };
    let found: Option<Vec<_>> = names
        .iter()
        .map(|n| bake.glossy.iter().find(|t| t.material == *n))
        .collect();
    if found.is_none() {
        notes.push(format!(
            "{object}: the bake has no BRDF table for {material_name}; specular not relit"
        ));
    }
    found
}

/// The exact glossy path of one object (Kautz, Sloan & Snyder 2002): the bake's
/// per-view-elevation BRDF tables, rotated per point and dotted with `L ⊛ V`.
pub(crate) struct ExactPath<'s> {
    tables: &'s [&'s GlossyBrdfTable],
    /// The visibility rows of the points relit.
    vis: &'s [f32],
    /// The colour weights of the tables' components.
    lobe: &'s GlossyLobe,
    order: usize,
    eye: [f32; 3],
}

impl ExactPath<'_> {
    /// The specular of the first `n` points lit by `env_rotated`: at the points in
    /// `exact_points` (all without it) shaded exactly, elsewhere `specular` (the fitted path's).
    ///
    /// # Errors
    /// Tables of a lower order than relit at.
    pub(crate) fn shade(
        &self,
        env_rotated: &[[f64; 3]],
        points: &PointSet,
        exact_points: Option<&[bool]>,
        specular: Vec<[f32; 3]>,
        n: usize,
    ) -> Result<Vec<[f32; 3]>, SceneRelightError> {
        let (g, order) = (self.lobe, self.order);
        // The points shaded exactly: all of them, or the hybrid path's choice.
        let chosen: Vec<usize> = match exact_points {
            Some(e) => (0..n).filter(|&p| e[p]).collect(),
            None => (0..n).collect(),
        };
        let n2 = order * order;
        let gather3 = |a: &[[f32; 3]]| -> Vec<[f32; 3]> { chosen.iter().map(|&p| a[p]).collect() };
        let vis: Vec<f32> = chosen
            .iter()
            .flat_map(|&p| self.vis[p * n2..(p + 1) * n2].iter().copied())
            .collect();
        let parts = crate::glossy::glossy_components(
            self.tables,
            order,
            env_rotated,
            &vis,
            &gather3(&points.positions),
            &gather3(&points.normals),
            self.eye,
        )?;
        let pick = |w: &[[f32; 3]], p: usize| if w.len() == 1 { w[0] } else { w[p] };
        let weights = [&g.colour_a, &g.colour_b, &g.colour_c];
        let mut s = specular;
        s.resize(n, [0.0; 3]);
        for (k, &p) in chosen.iter().enumerate() {
            s[p] = std::array::from_fn(|c| {
                let sum: f64 = parts
                    .iter()
                    .zip(weights)
                    .map(|(part, w)| f64::from(pick(w, p)[c]) * part[k][c])
                    .sum();
                sum.max(0.0) as f32
            });
        }
        Ok(s)
    }
}
