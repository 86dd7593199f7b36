//! Relighting a scene from its bake: per-object full-order or adaptive shading (prt-relight),
//! with the environment rotated about +Y by one SH rotation per frame.

use crate::binding::{baked_pixel_samples, environment};
use crate::error::SceneRelightError;
use crate::frames::{texel_grid, Frames, ObjectTerms, Shaded, Timing};
use crate::points::{PointSet, Rows};
use crate::shrm_occlusion::VisibilityCache;
use crate::specular::SpecularTerms;
use prt_bakefile::{Bake, ObjectBake, SampleKind, TransferBlock, TransferKind};
use prt_relight::{AdaptiveParams, DiffuseParams, FrameStats, Relighter, TransferView};
use prt_scene::lightmap::Lightmap;
use prt_scene::{Material, Scene};
use prt_tracer::points::PixelFootprints;
use serde::Serialize;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Instant;

pub use crate::binding::{baked_scene, check_bake, lightmaps};
pub use crate::lobe::{view_dependent, ExportLobe, GlossyPath, PhongModel, ViewDependent};
pub use crate::shrm_path::ShrmSpecular;

/// How to relight.
#[derive(Clone, Debug)]
pub struct RelightOptions {
    /// Order to relight at (`None`: each object's baked order); capped at the baked order.
    pub order: Option<usize>,
    /// Adaptive relighting parameters; `None` for full order.
    pub adaptive: Option<AdaptiveParams>,
    /// Environment rotation about +Y, degrees (same sense as the scene's `rotation_y`).
    pub rotate_y_deg: f64,
    /// Frames timed; the median is reported.
    pub timing_frames: usize,
    /// Frames shaded before the timed ones and not timed (lit as frame 0; results dropped),
    /// so that the timings are of the steady state a rotating-environment sequence runs in:
    /// the first frames of a process pay for fresh memory from the system and cold caches
    /// (measured on the 37k-vertex bunny: the median of the first 5 adaptive frames ~15 %
    /// above that of frames 3–17).
    pub warmup_frames: usize,
    /// Rotation about +Y added per timed frame, degrees (0: the same frame again). Frame `k`
    /// is lit by the environment rotated by `rotate_y_deg + k · step`; the radiance returned
    /// is frame 0's.
    pub rotate_y_step_deg: f64,
    /// Shade only these points of each object (vertices, or a per-pixel bake's pixels; full
    /// order only; the others come out 0): what a quality estimate relights at full order, and
    /// the fit pixels of inverse lighting's basis images. `None`: every point.
    pub points: Option<Vec<Vec<u32>>>,
    /// How glossy lobes without a zonal form (Blinn–Phong, Ward, Cook–Torrance, `pbr`) are
    /// relit.
    pub glossy: GlossyPath,
    /// How the `phong` material's lobe is relit (the light's cosine frozen at the lobe's
    /// centre, the default, or inside the integral).
    pub phong: PhongModel,
}

impl Default for RelightOptions {
    fn default() -> Self {
        Self {
            order: None,
            adaptive: None,
            rotate_y_deg: 0.0,
            timing_frames: 5,
            warmup_frames: 2,
            rotate_y_step_deg: 0.0,
            points: None,
            glossy: GlossyPath::Fitted,
            phong: PhongModel::FrozenCosine,
        }
    }
}

/// Radiance of every point of every object, and what it cost.
#[derive(Clone, Debug)]
pub struct Relit {
    /// Per object: radiance per point (diffuse + specular).
    pub radiance: Vec<Vec<[f32; 3]>>,
    /// Per object: whether each point is in the (diffuse or specular) ROI, for adaptive runs.
    pub roi: Vec<Vec<bool>>,
    /// Figures of the run.
    pub stats: RelightStats,
    /// Per-pixel bakes: the sub-pixel samples the bake averaged over (its seed and
    /// `pixel_samples`), which image formation uses for the background share of each pixel.
    /// `None` for per-vertex bakes.
    pub footprints: Option<Arc<prt_tracer::points::PixelFootprints>>,
    /// Per-texel bakes: per object its lightmap (`None` for objects relit per vertex), which
    /// image formation looks the texels' radiance up in; empty otherwise.
    pub lightmaps: Arc<Vec<Option<prt_scene::lightmap::Lightmap>>>,
    /// Whether images formed from this result add the scene's emitted radiance (glTF
    /// emission, [`Scene::emission_at`]) at each hit: it is neither in the bake nor lit by
    /// the environment, so relighting adds it from the scene's material (true for relighting
    /// under the bake's environment; false under a given lighting, whose images stay linear
    /// in it, as inverse lighting needs).
    pub emission: bool,
    /// Per object (empty when none): the `--glossy shrm` specular of a per-vertex bake relit
    /// at every point, which image formation looks up at a sub-pixel ray's interpolated
    /// normal and position, on triangles whose vertex lookups disagree, instead of
    /// interpolating `radiance` (which holds the per-vertex lookups, for everything else that
    /// reads it).
    pub shrm: Vec<Option<Arc<ShrmSpecular>>>,
}

/// Figures of one relighting run.
#[derive(Clone, Debug, Default, Serialize)]
pub struct RelightStats {
    /// Order used (the largest over objects).
    pub order: usize,
    /// Whether the adaptive path was used.
    pub adaptive: bool,
    /// Absolute threshold (adaptive only).
    pub threshold: Option<f32>,
    /// Shading time of one frame over all objects, milliseconds: the median of the timed
    /// frames (the upper median for an even count).
    pub shade_ms: f64,
    /// The fastest timed frame, ms.
    pub shade_ms_min: f64,
    /// The slowest timed frame, ms.
    pub shade_ms_max: f64,
    /// Frames per second of the whole per-frame work over the timed frames: environment
    /// rotation, per-frame lighting preparation (light product matrices) and shading.
    pub fps: f64,
    /// Points shaded.
    pub points: usize,
    /// Fraction of points in the diffuse ROI (adaptive), weighted over objects.
    pub roi_fraction_diffuse: Option<f64>,
    /// Fraction of active points in the specular ROI (adaptive), weighted over objects.
    pub roi_fraction_specular: Option<f64>,
    /// Per-level fractions of the diffuse filtering pass (adaptive), weighted over objects.
    pub level_fraction_diffuse: Vec<f64>,
    /// Per-level fractions of the specular filtering pass (adaptive), weighted over objects.
    pub level_fraction_specular: Vec<f64>,
    /// Mean number of bands a diffuse point was shaded with (adaptive), weighted over objects.
    pub mean_order_diffuse: Option<f64>,
    /// Mean number of bands an active specular point was shaded with (adaptive).
    pub mean_order_specular: Option<f64>,
    /// Coefficient products spent (adaptive, both terms, all objects).
    pub products: Option<u64>,
    /// Products the full-order path spends on the same points.
    pub full_order_products: Option<u64>,
    /// Notes (e.g. specular lobes that could not be relit).
    pub notes: Vec<String>,
}

/// Per object, its lightmap when it was baked per texel, shared by the relit results.
pub(crate) type Lightmaps = Arc<Vec<Option<Lightmap>>>;

/// What relighting `bake` needs besides a frame's lighting, computed once per binding
/// ([`crate::Bound`]): the pixel footprints of a per-pixel bake (traced), the lightmaps of a
/// per-texel one (rasterised) and the `--glossy shrm` path's traced lobe visibility (on first
/// use).
pub(crate) struct Prepared {
    /// Per-pixel bakes: the sub-pixel samples of every pixel.
    pub(crate) footprints: Option<Arc<PixelFootprints>>,
    /// Per object, its lightmap when baked per texel.
    pub(crate) lightmaps: Lightmaps,
    /// The SHRM path's traced lobe visibility, by object, lobe and eye.
    pub(crate) visibility: VisibilityCache,
}

/// [`Prepared`] for `bake` on `scene`.
///
/// # Errors
/// A camera the tracer refuses or a lightmap the rasteriser refuses.
pub(crate) fn prepare(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    bake: &Bake,
) -> Result<Prepared, SceneRelightError> {
    let footprints = if matches!(bake.meta.sample_kind, SampleKind::Pixel { .. }) {
        Some(Arc::new(prt_tracer::points::pixel_footprints(
            scene,
            accel,
            bake.meta.seed,
            baked_pixel_samples(bake),
        )?))
    } else {
        None
    };
    Ok(Prepared {
        footprints,
        lightmaps: Arc::new(lightmaps(scene, bake)?),
        visibility: VisibilityCache::default(),
    })
}

/// Relights every object of `bake` under `opt`, given what [`prepare`] computes (once, in a
/// [`crate::Bound`]).
pub(crate) fn relight_prepared(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    bake: &Bake,
    prepared: &Prepared,
    opt: &RelightOptions,
    lighting: Option<&[[f64; 3]]>,
) -> Result<Relit, SceneRelightError> {
    // The bake's environment, or the lighting asked for (rows of [r, g, b], a square count).
    let (env_order, env) = match lighting {
        None => environment(bake),
        Some(l) => ((l.len() as f64).sqrt().round() as usize, l.to_vec()),
    };
    let frames = Frames {
        env_order,
        env,
        rotate_y_deg: opt.rotate_y_deg,
        step_deg: opt.rotate_y_step_deg,
        warmup: opt.warmup_frames,
    };
    let rot = frames.rotation(opt.rotate_y_deg)?;
    let env_rotated: Vec<[f64; 3]> = match &rot {
        Some(r) => r.apply_rgb(&frames.env),
        None => frames.env.clone(),
    };
    let run = Run {
        scene,
        accel,
        bake,
        opt,
        frames,
        env_rotated,
        eye: scene.camera.eye.as_vec3().to_array(),
        per_pixel: prepared.footprints.is_some(),
        lighting,
        footprints: prepared.footprints.as_deref(),
        lightmaps: &prepared.lightmaps,
        visibility: &prepared.visibility,
    };
    let mut totals = Totals::new(opt);
    let mut radiance = Vec::new();
    let mut roi = Vec::new();
    let mut shrm = Vec::new();
    for (o, obj) in bake.objects.iter().enumerate() {
        let (r, in_roi, s) = run.object(o, obj, &mut totals)?;
        radiance.push(r);
        roi.push(in_roi);
        shrm.push(s.map(Arc::new));
    }
    Ok(Relit {
        radiance,
        roi,
        stats: totals.finish(),
        footprints: prepared.footprints.clone(),
        lightmaps: Arc::clone(&prepared.lightmaps),
        emission: lighting.is_none(),
        shrm,
    })
}

/// Relights every object of `scene` from `bake` (already checked with [`check_bake`]):
/// [`crate::Bound::new`] then [`crate::Bound::relight`]. To relight the same bake more than once, bind it
/// once.
///
/// # Errors
/// As [`crate::Bound::new`] and [`crate::Bound::relight`]: options the bake cannot honour, a subset of
/// points outside full-order per-vertex relighting, and failures of the kernels.
pub fn relight(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    bake: &Bake,
    opt: &RelightOptions,
) -> Result<Relit, SceneRelightError> {
    let prepared = prepare(scene, accel, bake)?;
    relight_prepared(scene, accel, bake, &prepared, opt, None)
}

/// An object's relit radiance per point, its points' ROI flags and its SHRM specular for
/// per-sample lookups.
type ObjectResult = (Vec<[f32; 3]>, Vec<bool>, Option<ShrmSpecular>);

/// What a per-sample SHRM lookup needs of an object's relighting: the table, the colour
/// weights (one or per point) and the occlusion factor per point and channel.
type ShrmLookup = (Arc<crate::shrm::Shrm>, [Vec<[f32; 3]>; 2], Vec<[f32; 3]>);

/// What every object of a run shares.
struct Run<'r> {
    scene: &'r Scene,
    /// The scene's BVH (the SHRM path traces its lobes' visibility).
    accel: &'r prt_tracer::Accel,
    bake: &'r Bake,
    opt: &'r RelightOptions,
    frames: Frames,
    /// The environment rotated for frame 0, for the exact glossy path.
    env_rotated: Vec<[f64; 3]>,
    /// The camera's eye, the viewer of the view-dependent terms.
    eye: [f32; 3],
    /// Whether the bake is per pixel.
    per_pixel: bool,
    /// The lighting given to the run instead of the bake's environment, if any.
    lighting: Option<&'r [[f64; 3]]>,
    /// Per-pixel bakes: the sub-pixel samples of every pixel.
    footprints: Option<&'r PixelFootprints>,
    /// Per object: its lightmap if it was baked per texel.
    lightmaps: &'r [Option<Lightmap>],
    /// The binding's traced SHRM lobe visibility.
    visibility: &'r VisibilityCache,
}

impl<'r> Run<'r> {
    /// Relights object `o` (`obj` of the bake): its radiance per point (0 outside a subset),
    /// whether each point ended in the adaptive path's ROI, and its SHRM specular for
    /// per-sample lookups (`--glossy shrm`, per-vertex bakes relit at every point).
    fn object(
        &self,
        o: usize,
        obj: &'r ObjectBake,
        totals: &mut Totals,
    ) -> Result<ObjectResult, SceneRelightError> {
        let (scene, opt, eye) = (self.scene, self.opt, self.eye);
        let material = &scene.materials[scene.meshes[o].material];
        let baked = obj.order as usize;
        let order = opt
            .order
            .unwrap_or(baked)
            .min(baked)
            .min(self.frames.env_order);
        totals.stats.order = totals.stats.order.max(order);
        let relighter = Relighter::new(order)?;
        let diffuse_block = obj
            .diffuse_block()
            .ok_or_else(|| SceneRelightError::BakeMismatch {
                path: PathBuf::from("<bake>"),
                reason: format!("object {} has no diffuse transfer", obj.name),
            })?;
        let channels = obj.channels as usize;
        let (subset, all_points) = self.subset(o, obj, diffuse_block)?;
        let rows = Rows {
            baked,
            order,
            channels,
            subset,
        };
        let diffuse_data = rows.select(&diffuse_block.data, channels);
        // Compact copies of the low bands for the adaptive path's level-by-level reading
        // (made once per run, outside the timed frames).
        let diffuse_low = prt_relight::low_bands(&diffuse_data, order);
        let diffuse_view =
            TransferView::new(order, channels, &diffuse_data)?.with_low_bands(&diffuse_low)?;
        let surface = PointSet::new(
            scene,
            o,
            self.footprints,
            self.lightmaps[o].as_ref(),
            eye,
            subset,
        );
        let is_pbr = matches!(material, Material::Pbr { .. });
        // The diffuse term is relit with unit albedo and scaled per point afterwards when the
        // albedo varies or (pbr) depends on the view.
        let per_point_diffuse = surface.materials.is_some() || is_pbr;
        let albedo = material.albedo();
        let dparams = DiffuseParams::from_albedo(if per_point_diffuse { [1.0; 3] } else { albedo });
        let cpca = self.cpca(
            obj,
            diffuse_block,
            &rows,
            "diffuse",
            &mut totals.stats.notes,
        );
        let notes = &mut totals.stats.notes;
        let name = scene.material_names.get(scene.meshes[o].material);
        let glossy = opt.glossy.for_object(
            self.bake,
            (material, name.map_or("", String::as_str)),
            baked,
            (&obj.name, notes),
        );
        let spec = SpecularTerms::new(
            scene, self.bake, o, &surface, &rows, glossy, opt.phong, notes,
        );
        let specular = spec.input(order, &surface, eye)?;
        // The SHRM path's traced occlusion and per-sample lookups need the object's vertices,
        // all of them, as its points; with the traced occlusion the fitted specular (products
        // at the bake's order) is not needed.
        let per_vertex = !self.per_pixel && self.lightmaps[o].is_none() && subset.is_none();
        let traced_occlusion = glossy == GlossyPath::Shrm
            && per_vertex
            && self.lighting.is_none()
            && spec.glossy.is_some();
        let fitted_input = specular;
        let specular = specular.filter(|_| !traced_occlusion);
        // A compressed visibility block: the glossy term is relit from its clusters.
        let vis_block = obj
            .blocks
            .iter()
            .find(|b| b.kind == TransferKind::Visibility);
        let visibility_cpca = match (&specular, vis_block) {
            (Some(_), Some(b)) => self.cpca(obj, b, &rows, "glossy", &mut totals.stats.notes),
            _ => None,
        };
        let terms = ObjectTerms {
            relighter,
            order,
            diffuse: diffuse_view,
            dparams,
            cpca,
            specular,
            visibility_cpca,
        };
        let points = diffuse_view.point_count();
        totals.stats.points += points;
        let notes = &mut totals.stats.notes;
        let exact_points =
            spec.hybrid_exact_points(glossy, &surface, eye, points, &obj.name, notes);
        let exact_points = exact_points.as_deref();
        let diffuse_scale = per_point_diffuse
            .then(|| spec.diffuse_scale(material, &surface, exact_points, eye, points));
        // The diffuse term (scaled) and the fitted or Phong specular, summed below.
        let (
            Shaded {
                diffuse: diffuse_part,
                specular: specular_part,
            },
            in_roi,
        ) = self.shade(o, &terms, points, diffuse_scale.as_deref(), totals)?;
        let specular_part = match spec.exact(order, eye) {
            Some(exact) => {
                if opt.adaptive.is_some() {
                    totals.stats.notes.push(format!(
                        "{}: the exact glossy specular is shaded at full order (the adaptive scheme covers the fitted path)",
                        obj.name
                    ));
                }
                let start = Instant::now();
                let s = exact.shade(
                    &self.env_rotated,
                    &surface,
                    exact_points,
                    specular_part,
                    points,
                )?;
                totals
                    .timing
                    .add_to_every_frame(start.elapsed().as_secs_f64());
                s
            }
            None => specular_part,
        };
        let (specular_part, per_sample) = if glossy == GlossyPath::Shrm {
            let object = (o, traced_occlusion);
            let fitted = (specular_part, fitted_input);
            self.shrm_specular(&spec, &terms, &surface, fitted, object, totals)?
        } else {
            (specular_part, None)
        };
        let result = sum_terms(&diffuse_part, &specular_part, points);
        let per_sample = per_sample.filter(|_| per_vertex).map(|(table, colour, k)| {
            let view = crate::shrm_path::view(eye, opt.rotate_y_deg);
            ShrmSpecular::new(table, colour, k, diffuse_part, view)
        });
        let (r, in_roi) = scatter(subset, all_points, result, in_roi);
        Ok((r, in_roi, per_sample))
    }

    /// The `--glossy shrm` specular of an object with a glossy lobe (others keep `shadowed`,
    /// their fitted or Phong specular): the SHRM lookup times an occlusion factor, timed into
    /// every frame (the prefilter, once per environment, and the lobes' visibility, once per
    /// relighting, are not: notes give their cost). The factor is the lobe's own traced
    /// visibility ([`crate::shrm_occlusion`]) when `object = (o, true)` (the caller's word
    /// that the points are all the vertices of mesh `o`, lit by the scene's environment);
    /// otherwise the share of the fitted lobe's lighting (`fitted`: the fitted specular,
    /// empty when not shaded, and its input) the baked visibility keeps.
    fn shrm_specular(
        &self,
        spec: &SpecularTerms<'_>,
        terms: &ObjectTerms<'_>,
        surface: &PointSet,
        fitted: (Vec<[f32; 3]>, Option<prt_relight::SpecularInput<'_>>),
        object: (usize, bool),
        totals: &mut Totals,
    ) -> Result<(Vec<[f32; 3]>, Option<ShrmLookup>), SceneRelightError> {
        let (o, traced) = object;
        let object = self.bake.objects[o].name.as_str();
        let (shadowed, input) = fitted;
        let (Some(g), Some(input)) = (&spec.glossy, input) else {
            return Ok((shadowed, None));
        };
        let notes = &mut totals.stats.notes;
        let material = match g.levels.as_slice() {
            [one] => *one,
            levels => {
                notes.push(format!(
                    "{object}: SHRM at the middle of the roughness range ({}): per-point roughness is not covered by the SHRM path",
                    g.level_roughness[levels.len() / 2]
                ));
                levels[levels.len() / 2]
            }
        };
        let Some(lobe) = crate::shrm::ShrmLobe::of(&material) else {
            return Ok((shadowed, None));
        };
        let pre = crate::shrm_path::prefiltered(self.scene, lobe, self.lighting)?;
        let traced = traced.then(|| {
            let eye = glam::Vec3::from_array(self.eye);
            self.visibility.get_or_trace(
                self.scene,
                self.accel,
                (o, lobe),
                eye,
                self.bake.meta.seed,
            )
        });
        let occlusion_note = match &traced {
            Some((_, Some(t))) => format!(
                "the lobe's own visibility, {} directions per vertex traced in {:.0} ms (once per binding of the bake: camera and geometry, not lighting)",
                crate::shrm_occlusion::OCCLUSION_SAMPLES,
                1e3 * t
            ),
            Some((_, None)) => format!(
                "the lobe's own visibility, {} directions per vertex (traced for an earlier relighting of this binding)",
                crate::shrm_occlusion::OCCLUSION_SAMPLES
            ),
            None => format!(
                "the fitted lobe's lighting with and without the baked visibility at order {} (an approximation)",
                terms.order
            ),
        };
        notes.push(format!(
            "{object}: {}; specular occlusion: {occlusion_note}",
            pre.note
        ));
        // Uniform colour weights: one combined table (half the lookups), made outside the timing.
        let (table, colour): (Arc<crate::shrm::Shrm>, [Vec<[f32; 3]>; 2]) =
            match (g.colour_a.as_slice(), g.colour_b.as_slice()) {
                ([a], [b]) => (
                    Arc::new(pre.shrm.combined([*a, *b])),
                    [vec![[1.0; 3]], vec![[0.0; 3]]],
                ),
                _ => (pre.shrm.clone(), [g.colour_a.clone(), g.colour_b.clone()]),
            };
        let start = Instant::now();
        let occlusion = match &traced {
            Some((v, _)) => {
                let n = terms.diffuse.point_count();
                let unoccluded = crate::shrm_path::lobe_integral(
                    &pre.shrm,
                    &surface.positions[..n],
                    &surface.normals[..n],
                    crate::shrm_path::view(self.eye, self.opt.rotate_y_deg),
                );
                v.occlusion_against(self.scene, self.opt.rotate_y_deg, &unoccluded)
            }
            None => self.fitted_occlusion(terms, &input, &shadowed)?,
        };
        let n = terms.diffuse.point_count();
        let s = crate::shrm_path::shade(
            &table,
            &surface.positions[..n],
            &surface.normals[..n],
            crate::shrm_path::view(self.eye, self.opt.rotate_y_deg),
            [&colour[0], &colour[1]],
            &occlusion,
        );
        totals
            .timing
            .add_to_every_frame(start.elapsed().as_secs_f64());
        Ok((s, Some((table, colour, occlusion))))
    }

    /// The fitted lobe's specular-occlusion factor per point: `lum(shadowed)` over the same
    /// lobe's unshadowed lighting at the bake's order, clamped to `[0, 1]` (1 where the
    /// unshadowed value is not positive).
    fn fitted_occlusion(
        &self,
        terms: &ObjectTerms<'_>,
        input: &prt_relight::SpecularInput<'_>,
        shadowed: &[[f32; 3]],
    ) -> Result<Vec<[f32; 3]>, SceneRelightError> {
        let env = prt_relight::Lighting::from_rgb_coefficients(&self.env_rotated, None)?
            .truncated(terms.order)?;
        let frame = terms.relighter.frame_lighting(&env, false)?;
        let unshadowed = terms.relighter.specular_unshadowed(input, &frame)?;
        let lum = |v: &[f32; 3]| 0.2126 * v[0] + 0.7152 * v[1] + 0.0722 * v[2];
        Ok(shadowed
            .iter()
            .zip(&unshadowed)
            .map(|(a, b)| {
                let (a, b) = (lum(a), lum(b));
                [if b > 0.0 {
                    (a / b).clamp(0.0, 1.0)
                } else {
                    1.0
                }; 3]
            })
            .collect())
    }

    /// The points of object `o` to shade (`None`: all of them) and how many it has.
    ///
    /// # Errors
    /// A subset asked of anything but full-order per-vertex or per-pixel relighting, or naming
    /// a point the object does not have.
    fn subset(
        &self,
        o: usize,
        obj: &ObjectBake,
        diffuse_block: &TransferBlock,
    ) -> Result<(Option<&'r [u32]>, usize), SceneRelightError> {
        let opt = self.opt;
        let (baked, channels) = (obj.order as usize, obj.channels as usize);
        let subset = opt
            .points
            .as_ref()
            .map(|p| p.get(o).map_or(&[][..], Vec::as_slice));
        let lightmap = self.lightmaps[o].as_ref();
        if subset.is_some() && (opt.adaptive.is_some() || lightmap.is_some()) {
            return Err(SceneRelightError::Invalid(
                "relighting a subset of points is for full-order per-vertex or per-pixel relighting only".into(),
            ));
        }
        let all_points = diffuse_block.data.len() / (channels * baked * baked).max(1);
        if let Some(bad) = subset.and_then(|s| s.iter().find(|&&i| i as usize >= all_points)) {
            return Err(SceneRelightError::Invalid(format!(
                "point {bad} of object {} does not exist ({all_points} points)",
                obj.name
            )));
        }
        Ok((subset, all_points))
    }

    /// A compressed block's clustered-PCA form, which non-adaptive relighting of every point
    /// relights its `what` term from (with a note of its error).
    fn cpca<'b>(
        &self,
        obj: &ObjectBake,
        block: &'b TransferBlock,
        rows: &Rows<'_>,
        what: &str,
        notes: &mut Vec<String>,
    ) -> Option<prt_relight::CpcaTransfer<'b>> {
        let cpca = block
            .cpca
            .as_ref()
            .filter(|_| rows.subset.is_none() && self.opt.adaptive.is_none());
        let cpca_view = cpca.map(|c| prt_relight::CpcaTransfer {
            order: rows.baked,
            channels: rows.channels,
            clusters: c.clusters as usize,
            components: c.components as usize,
            centres: &c.centres,
            cluster_of: &c.cluster_of,
            weights: &c.weights,
        });
        if let Some(c) = cpca {
            notes.push(format!(
                "{}: {what} relit from clustered PCA ({} clusters, {} components, relative L2 error {:.3} %)",
                obj.name,
                c.clusters,
                c.components,
                100.0 * c.rel_error
            ));
        }
        cpca_view
    }

    /// Shades object `o`'s frames adaptively or at full order (timed into `totals`): frame 0's
    /// diffuse term (times `diffuse_scale`, if given), its fitted or Phong specular, and per
    /// point whether it ended in the adaptive path's ROI.
    fn shade(
        &self,
        o: usize,
        terms: &ObjectTerms<'_>,
        points: usize,
        diffuse_scale: Option<&[[f32; 3]]>,
        totals: &mut Totals,
    ) -> Result<(Shaded, Vec<bool>), SceneRelightError> {
        let scaled = |d: &[[f32; 3]]| -> Vec<[f32; 3]> {
            match diffuse_scale {
                None => d.to_vec(),
                Some(k) => d
                    .iter()
                    .zip(k)
                    .map(|(v, k)| std::array::from_fn(|c| v[c] * k[c]))
                    .collect(),
            }
        };
        let mut in_roi = vec![false; points];
        match (&self.opt.adaptive, self.per_pixel) {
            (Some(params), false) => {
                // Texels are neighbours on the lightmap's grid (two triangles per cell).
                let grid;
                let triangles = match &self.lightmaps[o] {
                    Some(lm) => {
                        grid = texel_grid(lm.width, lm.height);
                        &grid
                    }
                    None => &self.scene.meshes[o].indices,
                };
                let f =
                    terms.adaptive_frames(&self.frames, &mut totals.timing, triangles, params)?;
                totals.add_frame_stats(&f.stats);
                for (i, r) in in_roi.iter_mut().enumerate() {
                    *r = f.roi[0].get(i).copied().unwrap_or(false)
                        || f.roi[1].get(i).copied().unwrap_or(false);
                }
                let shaded = Shaded {
                    diffuse: scaled(&f.diffuse),
                    specular: f.specular,
                };
                Ok((shaded, in_roi))
            }
            (Some(_), true) => Err(SceneRelightError::Invalid(
                "adaptive relighting walks the mesh's vertex adjacency: it needs a per-vertex bake"
                    .into(),
            )),
            (None, _) => {
                let Shaded { diffuse, specular } =
                    terms.full_frames(&self.frames, &mut totals.timing)?;
                let shaded = Shaded {
                    diffuse: scaled(&diffuse),
                    specular,
                };
                Ok((shaded, in_roi))
            }
        }
    }
}

/// An object's radiance and ROI flags over all its `all_points` points: with a subset, the
/// subset's radiance at its points (0 elsewhere) and no ROI.
fn scatter(
    subset: Option<&[u32]>,
    all_points: usize,
    result: Vec<[f32; 3]>,
    in_roi: Vec<bool>,
) -> (Vec<[f32; 3]>, Vec<bool>) {
    match subset {
        Some(sub) => {
            let mut all = vec![[0.0f32; 3]; all_points];
            for (&i, r) in sub.iter().zip(result) {
                all[i as usize] = r;
            }
            (all, vec![false; all_points])
        }
        None => (result, in_roi),
    }
}

/// What a run sums over its objects.
struct Totals {
    stats: RelightStats,
    timing: Timing,
    /// Adaptive: the diffuse term's ROI points and active points, summed over objects.
    roi_d: f64,
    n_d: f64,
    /// Likewise for the specular term.
    roi_s: f64,
    n_s: f64,
}

impl Totals {
    /// Nothing yet, for a run with options `opt`.
    fn new(opt: &RelightOptions) -> Self {
        Self {
            stats: RelightStats {
                adaptive: opt.adaptive.is_some(),
                ..RelightStats::default()
            },
            timing: Timing::new(opt.timing_frames.max(1)),
            roi_d: 0.0,
            n_d: 0.0,
            roi_s: 0.0,
            n_s: 0.0,
        }
    }

    /// Adds the figures of an object's adaptive frame: threshold, products, and the ROI
    /// fractions, mean orders and level fractions weighted by the term's active points.
    fn add_frame_stats(&mut self, f: &FrameStats) {
        let stats = &mut self.stats;
        stats.threshold = Some(f.threshold);
        let mut add_work = |t: &prt_relight::TermStats| {
            *stats.products.get_or_insert(0) += t.products;
            *stats.full_order_products.get_or_insert(0) += t.full_order_products;
        };
        if let Some(d) = &f.diffuse {
            add_work(d);
        }
        if let Some(s) = &f.specular {
            add_work(s);
        }
        if let Some(d) = &f.diffuse {
            let n = d.active_points as f64;
            self.roi_d += d.roi_fraction * n;
            self.n_d += n;
            *stats.mean_order_diffuse.get_or_insert(0.0) += d.mean_order * n;
            add_levels(&mut stats.level_fraction_diffuse, &d.level_fraction, n);
        }
        if let Some(s) = &f.specular {
            let n = s.active_points as f64;
            self.roi_s += s.roi_fraction * n;
            self.n_s += n;
            *stats.mean_order_specular.get_or_insert(0.0) += s.mean_order * n;
            add_levels(&mut stats.level_fraction_specular, &s.level_fraction, n);
        }
    }

    /// The run's figures: frame times (median, fastest, slowest), frames per second and, for
    /// adaptive runs, the weighted sums divided by their weights.
    fn finish(self) -> RelightStats {
        let Self {
            mut stats,
            timing,
            roi_d,
            n_d,
            roi_s,
            n_s,
        } = self;
        let Timing {
            mut times,
            frame_seconds,
        } = timing;
        stats.fps = times.len() as f64 / frame_seconds.max(1e-12);
        times.sort_by(f64::total_cmp);
        stats.shade_ms = 1e3 * times[times.len() / 2];
        stats.shade_ms_min = 1e3 * times[0];
        stats.shade_ms_max = 1e3 * times[times.len() - 1];
        if stats.adaptive {
            stats.roi_fraction_diffuse = (n_d > 0.0).then(|| roi_d / n_d);
            stats.roi_fraction_specular = (n_s > 0.0).then(|| roi_s / n_s);
            let total_d = n_d.max(1.0);
            let total_s = n_s.max(1.0);
            if let Some(m) = stats.mean_order_diffuse.as_mut() {
                *m /= total_d;
            }
            if let Some(m) = stats.mean_order_specular.as_mut() {
                *m /= total_s;
            }
            stats
                .level_fraction_diffuse
                .iter_mut()
                .for_each(|v| *v /= total_d);
            stats
                .level_fraction_specular
                .iter_mut()
                .for_each(|v| *v /= total_s);
        }
        stats
    }
}

fn add_levels(acc: &mut Vec<f64>, levels: &[f64], weight: f64) {
    if acc.len() < levels.len() {
        acc.resize(levels.len(), 0.0);
    }
    for (a, l) in acc.iter_mut().zip(levels) {
        *a += l * weight;
    }
}

fn sum_terms(d: &[[f32; 3]], s: &[[f32; 3]], n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| {
            let a = d.get(i).copied().unwrap_or([0.0; 3]);
            let b = s.get(i).copied().unwrap_or([0.0; 3]);
            [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::{DVec3, Vec3};
    use prt_bakefile::{EnvCoefficients, EnvPrecision, TransferKind};
    use prt_scene::{Camera, Environment, Mesh};
    use std::f64::consts::PI;

    /// `y_00`, and `c1` of band 1: `(y_1,−1, y_1,0, y_1,1) = c1 · (−y, z, −x)` (index
    /// `l² + l + m`, Condon–Shortley phase).
    const Y00: f64 = 0.282_094_791_773_878_14; // 1 / (2√π)
    const C1: f64 = 0.488_602_511_902_919_9; // √(3 / (4π))

    /// The unshadowed diffuse transfer of normal `n` at order 2, by hand: the clamped cosine's
    /// band multipliers `A_0 = π`, `A_1 = 2π/3` times the basis at `n`.
    fn transfer(n: Vec3) -> [f32; 4] {
        let a1 = 2.0 * PI / 3.0;
        let n = n.as_dvec3();
        [PI * Y00, -a1 * C1 * n.y, a1 * C1 * n.z, -a1 * C1 * n.x].map(|v| v as f32)
    }

    const NORMALS: [Vec3; 4] = [Vec3::X, Vec3::Y, Vec3::NEG_X, Vec3::NEG_Z];
    const ALBEDO: [f32; 3] = [0.8, 0.5, 0.25];
    /// Per channel: uniform radiance `k` (`L_0 = √(4π) k`) plus an L1 lobe `s · c1 · x` towards
    /// +X (`L_3 = −s`).
    const K: [f64; 3] = [1.0, 0.5, 2.0];
    const S: [f64; 3] = [0.3, -0.2, 0.6];

    /// A four-vertex mesh (one per normal of [`NORMALS`]) of `material`, and its bake at order
    /// 2 with the hand-made transfer and environment.
    fn scene_and_bake(material: Material) -> (Scene, Bake) {
        let cam = Camera::look_at(DVec3::new(0.0, 0.0, 5.0), DVec3::ZERO, 40.0, 8, 8);
        let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
        let m = scene.add_material("m", material);
        let mesh = Mesh {
            name: "quad".into(),
            positions: vec![
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(-1.0, 1.0, 0.0),
            ],
            normals: NORMALS.to_vec(),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Mesh::default()
        };
        scene.add_mesh(mesh, m);
        let mut values = vec![0.0f64; 12];
        for c in 0..3 {
            values[4 * c] = (4.0 * PI).sqrt() * K[c];
            values[4 * c + 3] = -S[c];
        }
        let bake = Bake {
            objects: vec![ObjectBake {
                name: "quad".into(),
                point_count: 4,
                points_in_file: 4,
                order: 2,
                channels: 1,
                blocks: vec![TransferBlock {
                    kind: TransferKind::ShadowedDiffuse,
                    data: NORMALS.iter().flat_map(|n| transfer(*n)).collect(),
                    cpca: None,
                }],
                ..ObjectBake::default()
            }],
            environment: Some(EnvCoefficients {
                order: 2,
                precision: EnvPrecision::F64,
                values,
            }),
            ..Bake::default()
        };
        (scene, bake)
    }

    fn run(scene: &Scene, bake: &Bake, opt: &RelightOptions) -> Result<Relit, SceneRelightError> {
        let accel = prt_tracer::Accel::build(scene).unwrap();
        relight(scene, &accel, bake, opt)
    }

    fn options() -> RelightOptions {
        RelightOptions {
            timing_frames: 1,
            warmup_frames: 0,
            ..RelightOptions::default()
        }
    }

    /// `albedo/π · Σ_i L_i T_i` for normal `n` with the L1 lobe towards `lobe` (rotated with
    /// the environment), by hand: the furnace part gives `albedo/π · √(4π) k · π y_00 =
    /// albedo · k`, the lobe `albedo/π · A_1 · c1 · s · (n · lobe)`.
    fn expected(n: Vec3, lobe: DVec3, c: usize) -> f64 {
        let rho = f64::from(ALBEDO[c]);
        rho * K[c] + rho / PI * (2.0 * PI / 3.0) * C1 * S[c] * n.as_dvec3().dot(lobe)
    }

    #[test]
    fn full_order_radiance_is_the_albedo_times_the_sh_dot_product() {
        let (scene, bake) = scene_and_bake(Material::Lambert { albedo: ALBEDO });
        let relit = run(&scene, &bake, &options()).unwrap();
        assert_eq!(relit.radiance.len(), 1);
        for (v, n) in NORMALS.iter().enumerate() {
            for c in 0..3 {
                let want = expected(*n, DVec3::X, c);
                let got = f64::from(relit.radiance[0][v][c]);
                assert!(
                    (got - want).abs() < 1e-6,
                    "vertex {v} channel {c}: {got} vs {want}"
                );
            }
        }
        let s = &relit.stats;
        assert_eq!((s.order, s.points, s.adaptive), (2, 4, false));
        assert!(s.notes.is_empty(), "{:?}", s.notes);
        assert!(s.shade_ms_min <= s.shade_ms && s.shade_ms <= s.shade_ms_max);
        assert_eq!(relit.roi, [vec![false; 4]]);
    }

    #[test]
    fn the_environment_turns_about_y_with_the_frame() {
        // 90° about +Y takes the lobe along +X to −Z: the +X vertex then sees only the
        // furnace part, the −Z vertex the whole lobe.
        let (scene, bake) = scene_and_bake(Material::Lambert { albedo: ALBEDO });
        let opt = RelightOptions {
            rotate_y_deg: 90.0,
            ..options()
        };
        let relit = run(&scene, &bake, &opt).unwrap();
        for (v, n) in NORMALS.iter().enumerate() {
            for c in 0..3 {
                let want = expected(*n, DVec3::NEG_Z, c);
                let got = f64::from(relit.radiance[0][v][c]);
                assert!(
                    (got - want).abs() < 1e-6,
                    "vertex {v} channel {c}: {got} vs {want}"
                );
            }
        }
    }

    #[test]
    fn a_subset_is_relit_alone_and_the_rest_left_black() {
        let (scene, bake) = scene_and_bake(Material::Lambert { albedo: ALBEDO });
        let all = run(&scene, &bake, &options()).unwrap();
        let opt = RelightOptions {
            points: Some(vec![vec![3, 1]]),
            ..options()
        };
        let some = run(&scene, &bake, &opt).unwrap();
        assert_eq!(some.stats.points, 2);
        let r = &some.radiance[0];
        assert_eq!(r.len(), 4);
        assert_eq!((r[0], r[2]), ([0.0; 3], [0.0; 3]));
        assert_eq!((r[1], r[3]), (all.radiance[0][1], all.radiance[0][3]));
        // A point the object does not have, and a subset of an adaptive run, are refused.
        let bad = RelightOptions {
            points: Some(vec![vec![4]]),
            ..options()
        };
        let e = run(&scene, &bake, &bad).unwrap_err().to_string();
        assert!(
            e.contains("point 4 of object quad does not exist (4 points)"),
            "{e}"
        );
        let adaptive = RelightOptions {
            adaptive: Some(AdaptiveParams::exact()),
            ..opt
        };
        let e = run(&scene, &bake, &adaptive).unwrap_err().to_string();
        assert!(
            e.contains("full-order per-vertex or per-pixel relighting only"),
            "{e}"
        );
    }

    #[test]
    fn adaptive_at_threshold_zero_is_full_order() {
        let (scene, bake) = scene_and_bake(Material::Lambert { albedo: ALBEDO });
        let full = run(&scene, &bake, &options()).unwrap();
        let opt = RelightOptions {
            adaptive: Some(AdaptiveParams::exact()),
            ..options()
        };
        let adaptive = run(&scene, &bake, &opt).unwrap();
        assert_eq!(adaptive.radiance, full.radiance);
        let s = &adaptive.stats;
        assert!(s.adaptive);
        assert_eq!(s.threshold, Some(0.0));
        assert_eq!(s.roi_fraction_specular, None);
        assert_eq!(s.products, s.full_order_products);
        // Order 2: both bands of every point (no level above the base to filter).
        assert_eq!(s.mean_order_diffuse, Some(2.0));
    }

    #[test]
    fn what_cannot_be_relit_is_refused_or_noted() {
        // A Phong lobe without a visibility transfer: the diffuse part alone, and a note.
        let phong = Material::Phong {
            albedo: ALBEDO,
            specular: [0.5; 3],
            exponent: 10.0,
        };
        let (scene, bake) = scene_and_bake(phong);
        let relit = run(&scene, &bake, &options()).unwrap();
        let (lambert, _) = scene_and_bake(Material::Lambert { albedo: ALBEDO });
        let diffuse = run(&lambert, &bake, &options()).unwrap();
        assert_eq!(relit.radiance, diffuse.radiance);
        assert_eq!(
            relit.stats.notes,
            ["quad: no visibility transfer in the bake; specular not relit"]
        );
        // A mirror's lobe is not relit at all.
        let mirror = Material::Mirror {
            albedo: ALBEDO,
            specular: [0.5; 3],
        };
        let (scene, _) = scene_and_bake(mirror);
        let relit = run(&scene, &bake, &options()).unwrap();
        assert_eq!(
            relit.stats.notes,
            ["quad: the specular lobe of a mirror material is not relit (diffuse part only)"]
        );
        // An object without a diffuse transfer.
        let mut no_diffuse = bake.clone();
        no_diffuse.objects[0].blocks[0].kind = TransferKind::Visibility;
        let e = run(&scene, &no_diffuse, &options())
            .unwrap_err()
            .to_string();
        assert!(e.contains("object quad has no diffuse transfer"), "{e}");
    }
}
