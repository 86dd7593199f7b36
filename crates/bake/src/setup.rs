//! What a bake settles before it traces a ray: the per-object plans, the memory check, the SH
//! bases, the lightmaps of a per-texel bake, the record of its settings, the environment's
//! projection, and the check of a distributed pass's input against all of these.

use crate::error::BakeError;
use crate::passes::{self, PassInput};
use crate::per_texel::lightmaps;
use crate::plan::{self, ObjectPlan};
use crate::settings::{BakeSettings, PointKind};
use crate::transfer::GatherScene;
use prt_bakefile::{Decision, EnvCoefficients, EnvPrecision};
use prt_scene::binding::geometry_hash;
use prt_scene::lightmap::Lightmap;
use prt_scene::{Mapping, Scene};
use prt_sh::{Basis, EnvMapping, ImageRef};
use prt_tracer::Accel;

/// Estimated peak memory in bytes of a bake (hit records dominate when bounces are asked).
#[must_use]
pub fn memory_estimate(scene: &Scene, settings: &BakeSettings, max_order: usize) -> u64 {
    let vertices: u64 = scene.meshes.iter().map(|m| m.positions.len() as u64).sum();
    let pixels = match settings.points {
        PointKind::Pixel => u64::from(scene.camera.width) * u64::from(scene.camera.height),
        // Every object's lightmap, as if all had UVs (an upper bound).
        PointKind::Texel { width, height } => {
            u64::from(width) * u64::from(height) * scene.meshes.len() as u64
        }
        PointKind::Vertex => 0,
    };
    let points = vertices + pixels;
    let n2 = (max_order * max_order) as u64;
    let hits = if settings.bounces > 0 {
        points * u64::from(settings.rays) * 16
    } else {
        0
    };
    // Direct results (f64, shadowed + visibility), bounce chain (f32 RGB per bounce) and the
    // output blocks (f32 RGB, per object for pixel bakes).
    let transfer = points * n2 * 8 * 2 + vertices * 3 * n2 * 4 * (u64::from(settings.bounces) + 2);
    let pixel_blocks = pixels * scene.meshes.len() as u64 * 3 * n2 * 4 * 3;
    hits + transfer + pixel_blocks
}

/// Refuses a bake whose [`memory_estimate`] exceeds `settings.memory_limit`.
fn check_memory(scene: &Scene, settings: &BakeSettings, max_order: usize) -> Result<(), BakeError> {
    let estimate = memory_estimate(scene, settings, max_order);
    if estimate > settings.memory_limit {
        return Err(BakeError::TooLarge {
            estimate_mib: estimate >> 20,
            limit_mib: settings.memory_limit >> 20,
            what: format!(
                "{} rays per point with {} bounce(s) at order {max_order} (hit records: 16 bytes per ray that hits)",
                settings.rays, settings.bounces
            ),
        });
    }
    Ok(())
}

/// Everything the steps of a bake share, settled before any ray is traced.
pub(crate) struct Setup<'a> {
    pub scene: &'a Scene,
    pub accel: &'a Accel,
    pub settings: &'a BakeSettings,
    /// Per object: what to bake, and at which order.
    pub plans: Vec<ObjectPlan>,
    /// Per object: the SH basis of its order.
    pub bases: Vec<Basis>,
    /// What bounce gathering reads of the meshes.
    pub gs: GatherScene<'a>,
    /// Per object: its lightmap in a per-texel bake (`None` elsewhere and without UVs).
    pub lightmaps: Vec<Option<Lightmap>>,
    /// Per-vertex or per-texel (whose bounce chain lives at vertices), not per-pixel.
    pub vertex_mode: bool,
    /// The settings as the file records them (SPEC §3.9).
    pub settings_json: serde_json::Value,
    /// The environment's exact SH projection at the highest order of the objects.
    pub environment: EnvCoefficients,
}

impl<'a> Setup<'a> {
    /// Plans the bake of `scene` with `settings`, and the decisions that took.
    pub(crate) fn new(
        scene: &'a Scene,
        accel: &'a Accel,
        settings: &'a BakeSettings,
    ) -> Result<(Self, Vec<Decision>), BakeError> {
        let (plans, mut decisions) = plan::plan(scene, settings);
        let max_order = plans.iter().map(|p| p.order).max().unwrap_or(1);
        check_memory(scene, settings, max_order)?;
        let bases: Vec<Basis> = plans
            .iter()
            .map(|p| Basis::new(p.order))
            .collect::<Result<_, _>>()?;
        let gs = GatherScene {
            indices: scene.meshes.iter().map(|m| m.indices.as_slice()).collect(),
            albedo: scene
                .meshes
                .iter()
                .map(|m| scene.materials[m.material].albedo())
                .collect(),
            scene,
            varies: (0..scene.meshes.len())
                .map(|m| scene.material_varies(m))
                .collect(),
        };
        // Per-texel bakes run as per-vertex ones (the bounce chain lives at vertices) with the
        // lightmapped objects' points replaced by their texels at assembly.
        let vertex_mode = settings.points != PointKind::Pixel;
        let lightmaps = lightmaps(scene, &plans, settings, &mut decisions)?;
        let settings_json = settings_record(scene, settings, &plans, &lightmaps);
        let environment = environment(scene, max_order)?;
        let setup = Self {
            scene,
            accel,
            settings,
            plans,
            bases,
            gs,
            lightmaps,
            vertex_mode,
            settings_json,
            environment,
        };
        Ok((setup, decisions))
    }

    /// Checks a distributed pass's index and previous file against this bake.
    pub(crate) fn check_pass(&self, pass: &PassInput<'_>) -> Result<(), BakeError> {
        let (scene, settings) = (self.scene, self.settings);
        let expect = passes::Expect {
            settings: &self.settings_json,
            names: self.plans.iter().map(|p| p.name.as_str()).collect(),
            hashes: self
                .plans
                .iter()
                .map(|p| {
                    let m = &scene.meshes[p.mesh];
                    geometry_hash(m.positions.as_slice(), &m.indices)
                })
                .collect(),
            orders: self.plans.iter().map(|p| p.order as u32).collect(),
            albedo: &self.gs.albedo,
            environment: &self.environment,
            bounces: settings.bounces,
            gathers_at_vertices: settings.pass_gathers_at_vertices(pass.index),
            shard: settings.shard,
            ranges: self
                .plans
                .iter()
                .map(|plan| settings.shard_range(scene.meshes[plan.mesh].positions.len() as u64))
                .collect(),
        };
        passes::check(pass, &expect)
    }
}

/// The settings as the file records them (SPEC §3.9): what a relighting, a merge and a
/// distributed pass check a bake against.
fn settings_record(
    scene: &Scene,
    settings: &BakeSettings,
    plans: &[ObjectPlan],
    lightmaps: &[Option<Lightmap>],
) -> serde_json::Value {
    let settings_json = serde_json::json!({
        "order": settings.order,
        "max_order": settings.max_order,
        "error_target": settings.error_target,
        "rays": settings.rays,
        "bounces": settings.bounces,
        // A string, like the JSON `seed` (SPEC §3.9): exact in every JSON parser.
        "seed": settings.seed.to_string(),
        "points": match settings.points {
            PointKind::Vertex => "vertex",
            PointKind::Pixel => "pixel",
            PointKind::Texel { .. } => "texel",
        },
        "unshadowed": settings.unshadowed,
    });
    let mut settings_json = settings_json;
    // The diffuse transfer excludes the receiving point's albedo/π (SPEC §3.4).
    settings_json["albedo_in_transfer"] = false.into();
    if settings.points == PointKind::Pixel {
        settings_json["pixel_samples"] = settings.pixel_samples.into();
    }
    if let PointKind::Texel { width, height } = settings.points {
        // Which UV set each lightmapped object used, and a hash of those UVs, so that
        // relighting refuses a scene whose lightmap UVs changed (SPEC §3.9).
        settings_json["lightmaps"] = plans
            .iter()
            .zip(lightmaps)
            .map(|(p, l)| match l {
                Some(l) => match &l.corner_uvs {
                    // A generated atlas: its corner UVs in the file (SPEC §3.9.3).
                    Some(c) => serde_json::json!({
                        "object": p.name,
                        "width": width,
                        "height": height,
                        "atlas": prt_bakefile::atlas_integers(c),
                        "uv_hash": prt_bakefile::uv_hash(&c.concat()).to_string(),
                    }),
                    None => serde_json::json!({
                        "object": p.name,
                        "width": width,
                        "height": height,
                        "uv_set": l.uv_set,
                        "uv_hash": prt_bakefile::uv_hash(&scene.meshes[p.mesh].texcoords[l.uv_set]).to_string(),
                    }),
                },
                None => serde_json::Value::Null,
            })
            .collect();
    }
    settings_json
}

/// The environment's exact SH projection to `max_order` (also what a distributed pass checks
/// its input against).
fn environment(scene: &Scene, max_order: usize) -> Result<EnvCoefficients, BakeError> {
    let env = &scene.environment;
    let mapping = match env.mapping {
        Mapping::LatLong => EnvMapping::LatLong,
        Mapping::Angular => EnvMapping::Angular { subsamples: 4 },
    };
    let img = ImageRef {
        width: env.image.width,
        height: env.image.height,
        texels: &env.image.texels,
    };
    let coeffs = prt_sh::project_env(img, mapping, max_order, env.rotation_y_deg)?;
    Ok(EnvCoefficients {
        order: max_order as u32,
        precision: EnvPrecision::F64,
        values: (0..3)
            .flat_map(|c| coeffs.iter().map(move |v| v[c]))
            .collect(),
    })
}
