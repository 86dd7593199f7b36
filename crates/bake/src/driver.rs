//! The bake driver: set-up, the direct pass at vertices, the bounce chain (here or as one pass
//! of a distributed bake), the objects of the per-vertex, per-texel or per-pixel path, and the
//! file's assembly, in that order.

use crate::assembly::{self, bake_meta, intermediate_stats, Objects};
use crate::error::BakeError;
use crate::material::material_binding;
use crate::passes::{self, PassInput};
use crate::per_pixel::pixel_objects;
use crate::per_texel::TexelBake;
use crate::per_vertex::{gather_bounces, vertex_object, Levels, Vertices};
use crate::report::{BakeOutput, ObjectReport};
use crate::settings::{BakeSettings, PointKind};
use crate::setup::Setup;
use crate::subdivide;
use prt_bakefile::{Bake, BakeMeta, Decision, ObjectBake, SampleKind};
use prt_scene::binding::{camera_info, geometry_hash};
use prt_scene::Scene;
use prt_tracer::Accel;
use std::time::Instant;

/// Bakes `scene` (whose acceleration structure is `accel`) with `settings`.
pub fn bake(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
) -> Result<BakeOutput, BakeError> {
    bake_pass(scene, accel, settings, None)
}

/// Runs one pass of a distributed bounced bake ([`passes`]): pass 0 and the middle passes
/// return an intermediate file (`meta.pass` set; merge its shards with
/// [`prt_bakefile::merge`] and hand the result to the next pass), the last pass (`bounces`)
/// the shard of the final bake. `None`, or any pass of a bake without bounces, is the whole
/// bake ([`bake`]).
pub fn bake_pass(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    pass: Option<PassInput<'_>>,
) -> Result<BakeOutput, BakeError> {
    let start = Instant::now();
    settings.validate()?;
    if accel.triangle_count() == 0 {
        return Err(BakeError::EmptyScene);
    }
    if let Some(sub) = settings.subdivide {
        return bake_subdivided(scene, accel, settings, pass, &sub, start);
    }
    let (setup, mut decisions) = Setup::new(scene, accel, settings)?;
    surface_input_decisions(&setup, &mut decisions);
    if let Some(p) = &pass {
        setup.check_pass(p)?;
    }
    // Only bakes with bounces have more than one pass; pass 0 of a bake without bounces is the
    // whole (sharded) bake.
    let dist = pass.filter(|_| settings.bounces > 0);
    let dist_index = dist.map(|d| d.index);
    // Per-pixel bakes need vertices for the bounce chain only, and not in their last pass,
    // which traces pixels only (the vertex levels come in).
    let need_vertices =
        setup.vertex_mode || (settings.bounces > 0 && dist_index != Some(settings.bounces));
    let mut vertices = Vertices::trace(&setup, dist, need_vertices);

    let levels = match bounce(&setup, &mut vertices, dist_index, need_vertices)? {
        Bounced::Levels(levels) => levels,
        Bounced::Intermediate {
            index,
            objects,
            reports,
        } => {
            let pass = Intermediate {
                index,
                objects,
                reports,
                vertices: &vertices,
                dist,
            };
            return pass.output(setup, decisions, start);
        }
    };
    let (objects, sample_kind) = objects(&setup, &vertices, &levels, &mut decisions)?;

    // The file.
    let (brdfs, glossy) = assembly::brdf_projections(scene, &setup.plans, &mut decisions);
    let Objects {
        objects,
        reports,
        ray_stats,
        rays,
    } = objects;
    let meta = BakeMeta {
        camera: (!setup.vertex_mode).then(|| camera_info(&scene.camera)),
        ..bake_meta(
            settings,
            sample_kind,
            setup.settings_json,
            &decisions,
            ray_stats,
        )
    };
    let mut bake = Bake {
        reflectance: None,
        meta,
        objects,
        environment: Some(setup.environment),
        brdfs,
        glossy,
    };
    if setup.vertex_mode && dist_index.is_some_and(|k| k > 0) {
        // The vertices' rays were traced in pass 0: their counts come with the previous file.
        bake.meta.ray_stats = intermediate_stats(&setup.plans, &vertices.direct, dist, settings);
    }
    let rays_traced = vertices.rays_traced + rays;
    assembly::output(bake, reports, rays_traced, start, decisions)
}

/// What the bounce step of a run produced.
enum Bounced {
    /// The vertex levels the objects gather from (none without bounces).
    Levels(Levels),
    /// Intermediate pass `index` of a distributed bake: this shard's objects with their pass
    /// state and their report rows, the whole of its file.
    Intermediate {
        index: u32,
        objects: Vec<ObjectBake>,
        reports: Vec<ObjectReport>,
    },
}

/// The bounce chain at vertices: one level for this shard's vertices (or none) in pass
/// `dist_index` of a distributed bake, else every level the bake gathers at vertices.
fn bounce(
    setup: &Setup<'_>,
    vertices: &mut Vertices,
    dist_index: Option<u32>,
    need_vertices: bool,
) -> Result<Bounced, BakeError> {
    let settings = setup.settings;
    if let Some(k) = dist_index {
        let state = passes::Step {
            scene: setup.scene,
            plans: &setup.plans,
            settings,
            vertex_mode: setup.vertex_mode,
            vertex_bounces: settings.vertex_bounces(),
            gs: &setup.gs,
            vertex_ranges: &vertices.ranges,
            object_hits: &vertices.object_hits,
        };
        let previous = std::mem::take(&mut vertices.previous);
        let bar = settings.progress_bar(0, "gather");
        Ok(match state.run(k, &vertices.direct, previous, bar)? {
            passes::Outcome::Intermediate(objects, reports) => Bounced::Intermediate {
                index: k,
                objects,
                reports,
            },
            passes::Outcome::Final { chain, totals } => Bounced::Levels(Levels { chain, totals }),
        })
    } else if need_vertices
        && (settings.vertex_bounces() > 0 || (!setup.vertex_mode && settings.bounces > 0))
    {
        Ok(Bounced::Levels(gather_bounces(setup, vertices)))
    } else {
        Ok(Bounced::Levels(Levels::default()))
    }
}

/// The bake's objects, and the kind of their points: per vertex and per texel, or per pixel.
fn objects(
    setup: &Setup<'_>,
    vertices: &Vertices,
    levels: &Levels,
    decisions: &mut Vec<Decision>,
) -> Result<(Objects, SampleKind), BakeError> {
    if setup.vertex_mode {
        let kind = match setup.settings.points {
            PointKind::Texel { width, height } => SampleKind::Texel { width, height },
            _ => SampleKind::Vertex,
        };
        Ok((
            vertex_mode_objects(setup, vertices, levels, decisions),
            kind,
        ))
    } else {
        let (width, height) = (setup.scene.camera.width, setup.scene.camera.height);
        let objects = pixel_objects(setup, &levels.chain)?;
        Ok((objects, SampleKind::Pixel { width, height }))
    }
}

/// The objects of a per-vertex or per-texel bake: each lightmapped object per texel, the
/// others per vertex.
fn vertex_mode_objects(
    setup: &Setup<'_>,
    vertices: &Vertices,
    levels: &Levels,
    decisions: &mut Vec<Decision>,
) -> Objects {
    let mut objects = Objects::with_capacity(setup.plans.len());
    for (o, plan) in setup.plans.iter().enumerate() {
        let object = match &setup.lightmaps[o] {
            Some(lightmap) => TexelBake {
                accel: setup.accel,
                plan,
                mesh: &setup.scene.meshes[plan.mesh],
                lightmap,
                material: material_binding(setup.scene, plan.mesh),
                settings: setup.settings,
                chain: &levels.chain,
                gs: &setup.gs,
                basis: &setup.bases[o],
            }
            .run(),
            None => vertex_object(setup, vertices, &levels.totals, o, decisions),
        };
        objects.push(object);
    }
    objects
}

/// What an intermediate pass (`index < bounces`) of a distributed bake produced.
struct Intermediate<'a> {
    index: u32,
    /// This shard's objects with their pass state.
    objects: Vec<ObjectBake>,
    reports: Vec<ObjectReport>,
    vertices: &'a Vertices,
    dist: Option<PassInput<'a>>,
}

impl Intermediate<'_> {
    /// The intermediate file: this shard's vertex levels, the environment, no BRDFs.
    fn output(
        self,
        setup: Setup<'_>,
        decisions: Vec<Decision>,
        start: Instant,
    ) -> Result<BakeOutput, BakeError> {
        let settings = setup.settings;
        let ray_stats =
            intermediate_stats(&setup.plans, &self.vertices.direct, self.dist, settings);
        let meta = BakeMeta {
            camera: None,
            pass: Some(passes::info(self.index, settings.bounces, &setup.gs.albedo)),
            ..bake_meta(
                settings,
                SampleKind::Vertex,
                setup.settings_json,
                &decisions,
                ray_stats,
            )
        };
        let bake = Bake {
            reflectance: None,
            meta,
            objects: self.objects,
            environment: Some(setup.environment),
            brdfs: Vec::new(),
            glossy: Vec::new(),
        };
        assembly::output(
            bake,
            self.reports,
            self.vertices.rays_traced,
            start,
            decisions,
        )
    }
}

/// What the bake does with the glTF material inputs besides the BRDF (issue 34), one decision
/// per material: a normal map shades the transfer of each pixel or texel
/// (`Scene::shading_normal`) but cannot be held by per-vertex points (it varies inside
/// triangles); emission is not transfer at all — relighting adds it from the scene's material;
/// an occlusion map, `BLEND` and `MASK` say how they are read.
fn surface_input_decisions(setup: &Setup<'_>, decisions: &mut Vec<Decision>) {
    let scene = setup.scene;
    let mut seen = Vec::new();
    for plan in &setup.plans {
        let material = scene.meshes[plan.mesh].material;
        if seen.contains(&material) {
            continue;
        }
        seen.push(material);
        let name = scene
            .material_names
            .get(material)
            .map_or("?", String::as_str);
        let mapped: Vec<usize> = setup
            .plans
            .iter()
            .enumerate()
            .filter(|(_, p)| {
                scene.meshes[p.mesh].material == material && scene.has_normal_map(p.mesh)
            })
            .map(|(k, _)| k)
            .collect();
        if !mapped.is_empty() {
            let per_vertex = mapped.iter().any(|&k| {
                setup.settings.points == PointKind::Vertex
                    || (matches!(setup.settings.points, PointKind::Texel { .. })
                        && setup.lightmaps.get(k).is_none_or(Option::is_none))
            });
            decisions.push(if per_vertex {
                Decision {
                    object: None,
                    decision: format!("normal map of material {name} not representable per vertex"),
                    reason: "it varies inside triangles: per-vertex transfer shades with the interpolated normals; bake --per-pixel or --per-texel to include it".into(),
                }
            } else {
                Decision {
                    object: None,
                    decision: format!("normal map of material {name}: the shading normal of each point"),
                    reason: "the transfer's cosine and hemisphere use the normal-mapped normal (per pixel as the path tracer orients it towards the camera); the geometric normal decides the side, directions below it are blocked".into(),
                }
            });
        }
        let inputs = scene.surface_inputs(material);
        for (present, decision, reason) in [
            (
                inputs.occlusion_map,
                "occlusion map ignored",
                "the bake computes occlusion itself (it is in the shadowed transfer); multiplying by the asset's map would count it twice",
            ),
            (
                inputs.blend,
                "alphaMode BLEND treated as OPAQUE",
                "transparency is not modelled: the surface blocks and reflects light everywhere",
            ),
            (
                matches!(inputs.alpha, prt_scene::AlphaMode::Mask { .. }),
                "alphaMode MASK: cut out where alpha is below the cutoff",
                "cut-out texels neither block the bake's rays nor are hit by them, as in the path tracer",
            ),
        ] {
            if present {
                decisions.push(Decision {
                    object: None,
                    decision: format!("{decision} (material {name})"),
                    reason: reason.into(),
                });
            }
        }
        if inputs.emits() {
            decisions.push(Decision {
                object: None,
                decision: format!("emission of material {name} added at relight time"),
                reason: "emitted radiance is read from the scene's material at each shaded hit (not stored in the bake); light from emitters onto other surfaces is not in the transfer (environment light only)".into(),
            });
        }
    }
}

/// A per-vertex bake on meshes refined where the transfer changes fast ([`subdivide`]): the
/// refinement, then the ordinary bake of the refined scene; the file's meshes are the refined
/// ones, and `settings.subdivided_from` names each object's source mesh (SPEC §3.9).
fn bake_subdivided(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    pass: Option<PassInput<'_>>,
    sub: &subdivide::SubdivideOptions,
    start: Instant,
) -> Result<BakeOutput, BakeError> {
    if settings.points != PointKind::Vertex {
        return Err(BakeError::InvalidSettings(
            "--subdivide refines per-vertex bakes; a per-pixel bake has no mesh to refine".into(),
        ));
    }
    if pass.is_some() || settings.shard.is_some() {
        return Err(BakeError::InvalidSettings(
            "--subdivide runs on one machine: the refinement of a mesh needs all of its vertices (bake without --shard/--pass)".into(),
        ));
    }
    let (plans, _) = crate::plan::plan(scene, settings);
    let (refined, report) = subdivide::refine(scene, accel, settings, &plans, sub)?;
    let refined_accel = Accel::build(&refined)?;
    let inner = BakeSettings {
        subdivide: None,
        ..settings.clone()
    };
    let mut out = bake_pass(&refined, &refined_accel, &inner, None)?;
    let m = &mut out.bake.meta;
    m.settings["subdivide"] =
        serde_json::json!({ "error": sub.error, "max_levels": sub.max_levels });
    let mut from = serde_json::Map::new();
    for r in &report {
        let mesh = &scene.meshes[plans
            .iter()
            .find(|p| p.name == r.name)
            .map_or(0, |p| p.mesh)];
        from.insert(
            r.name.clone(),
            serde_json::json!({
                "geometry_hash": format!("0x{:016x}", geometry_hash(mesh.positions.as_slice(), &mesh.indices)),
                "vertices": r.vertices[0],
                "triangles": r.triangles[0],
            }),
        );
        let d = subdivision_decision(r, sub);
        m.decisions.push(d.clone());
        out.report.decisions.push(d);
        out.report.rays_traced += r.rays;
    }
    m.settings["subdivided_from"] = serde_json::Value::Object(from);
    out.report.seconds = start.elapsed().as_secs_f64();
    out.bake.validate()?;
    Ok(out)
}

/// The decision recording how one object was refined.
fn subdivision_decision(
    r: &subdivide::ObjectRefinement,
    sub: &subdivide::SubdivideOptions,
) -> Decision {
    Decision {
        object: Some(r.name.clone()),
        decision: format!(
            "subdivided: {} → {} vertices, {} → {} triangles",
            r.vertices[0], r.vertices[1], r.triangles[0], r.triangles[1]
        ),
        reason: if r.splits.is_empty() {
            format!(
                "no edge's transfer differed by more than {} (relative L2): nothing to refine",
                sub.error
            )
        } else {
            format!(
                "edges whose transfer differed by more than {} (relative L2) were split, level by level: {:?} edges (at most {} levels), decided from {} probes of {} rays",
                sub.error, r.splits, sub.max_levels, r.probes.iter().sum::<usize>(), r.probe_rays
            )
        },
    }
}
