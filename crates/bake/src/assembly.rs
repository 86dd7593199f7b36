//! The assembly of a bake's file: each object's part as the per-vertex, per-pixel and
//! per-texel paths produce it, the metadata every file shares, the BRDF projections of the
//! materials used, and the ray statistics of distributed passes.

use crate::error::BakeError;
use crate::passes::PassInput;
use crate::plan::ObjectPlan;
use crate::report::{BakeOutput, BakeReport, ObjectReport};
use crate::rows::point_stats;
use crate::settings::{BakeSettings, PointKind};
use crate::transfer::DirectResult;
use prt_bakefile::{
    Bake, BakeMeta, BrdfProjection, Decision, GlossyBrdfTable, ObjectBake, RayStats, SampleKind,
    ShardInfo, ToolInfo,
};
use prt_scene::{Material, Scene};

/// One object's part of a bake: its file object, report row, ray statistics, and the rays its
/// own points traced (0 when they were traced with the vertices).
pub(crate) struct BakedObject {
    pub object: ObjectBake,
    pub report: ObjectReport,
    pub stats: RayStats,
    pub rays: u64,
}

/// The objects of a bake, in plan order.
pub(crate) struct Objects {
    pub objects: Vec<ObjectBake>,
    pub reports: Vec<ObjectReport>,
    pub ray_stats: Vec<RayStats>,
    /// Rays the objects' own points traced.
    pub rays: u64,
}

impl Objects {
    /// No objects yet, room for `n`.
    pub(crate) fn with_capacity(n: usize) -> Self {
        Self {
            objects: Vec::with_capacity(n),
            reports: Vec::with_capacity(n),
            ray_stats: Vec::with_capacity(n),
            rays: 0,
        }
    }

    /// Appends the next object.
    pub(crate) fn push(&mut self, o: BakedObject) {
        self.objects.push(o.object);
        self.reports.push(o.report);
        self.ray_stats.push(o.stats);
        self.rays += o.rays;
    }
}

/// The metadata every file of a bake shares (no camera, not a pass file).
pub(crate) fn bake_meta(
    settings: &BakeSettings,
    sample_kind: SampleKind,
    settings_json: serde_json::Value,
    decisions: &[Decision],
    ray_stats: Vec<RayStats>,
) -> BakeMeta {
    BakeMeta {
        sample_kind,
        rays_per_point: settings.rays,
        bounces: settings.bounces,
        seed: settings.seed,
        tool: ToolInfo {
            name: "prt".into(),
            version: env!("CARGO_PKG_VERSION").into(),
        },
        settings: settings_json,
        decisions: decisions.to_vec(),
        shard: settings
            .shard
            .map_or(ShardInfo::default(), |(index, count)| ShardInfo {
                index,
                count,
            }),
        ray_stats,
        camera: None,
        pass: None,
    }
}

/// The ray statistics of an intermediate pass file, or of the last pass of a per-vertex
/// distributed bake: they are counts over a shard's points, so that merging adds them up. Pass
/// 0 counts its own vertices' rays; later passes traced no vertex rays and only know the merged
/// total, which shard 0 carries (the others carry zeros, as [`prt_bakefile::split`] does).
pub(crate) fn intermediate_stats(
    plans: &[ObjectPlan],
    rows: &[Vec<DirectResult>],
    pass: Option<PassInput<'_>>,
    settings: &BakeSettings,
) -> Vec<RayStats> {
    if settings.points != PointKind::Vertex {
        return Vec::new();
    }
    let zero = |name: &str| RayStats {
        object: name.to_owned(),
        ..RayStats::default()
    };
    match pass.and_then(|p| p.previous) {
        None => plans
            .iter()
            .zip(rows)
            .map(|(plan, rows)| {
                let mut stats = zero(&plan.name);
                for d in rows {
                    stats.add(&point_stats(d, settings.rays));
                }
                stats
            })
            .collect(),
        Some(prev) if settings.shard.is_none_or(|(i, _)| i == 0) => prev.meta.ray_stats.clone(),
        Some(_) => plans.iter().map(|p| zero(&p.name)).collect(),
    }
}

/// The BRDF projections of every material the objects use, once each at the highest order of
/// its objects: its zonal projections, and the glossy tables of the lobes without a zonal form
/// (with a decision saying so).
pub(crate) fn brdf_projections(
    scene: &Scene,
    plans: &[ObjectPlan],
    decisions: &mut Vec<Decision>,
) -> (Vec<BrdfProjection>, Vec<GlossyBrdfTable>) {
    let mut brdfs = Vec::new();
    let mut glossy = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for plan in plans {
        let mat_index = scene.meshes[plan.mesh].material;
        if !seen.insert(mat_index) {
            continue;
        }
        let name = scene
            .material_names
            .get(mat_index)
            .cloned()
            .unwrap_or_else(|| format!("material{mat_index}"));
        let material = &scene.materials[mat_index];
        let order = plans
            .iter()
            .filter(|p| scene.meshes[p.mesh].material == mat_index)
            .map(|p| p.order)
            .max()
            .unwrap_or(plan.order);
        brdfs.extend(prt_shading::projection::zonal_projection(
            &name, material, order,
        ));
        glossy_tables(&name, material, order, &mut glossy, decisions);
    }
    (brdfs, glossy)
}

/// The glossy tables of material `name` at `order`, if its lobe has no zonal form.
fn glossy_tables(
    name: &str,
    material: &Material,
    order: usize,
    glossy: &mut Vec<GlossyBrdfTable>,
    decisions: &mut Vec<Decision>,
) {
    if let Material::Pbr {
        roughness,
        metallic_roughness_texture,
        ..
    } = *material
    {
        for c in prt_shading::projection::PbrComponent::ALL {
            let mut t = prt_shading::projection::pbr_table(roughness, c, order);
            t.material = format!("{name}{}", c.suffix());
            glossy.push(t);
        }
        let roughness_source = if metallic_roughness_texture.is_some() {
            format!(
                "its roughness comes from a texture (times the factor {roughness}): these tables, which the exact path reads, are at the factor; the fitted path (the default) follows the texture per point"
            )
        } else {
            format!("roughness {roughness}")
        };
        decisions.push(Decision {
            object: None,
            decision: format!("glossy tables for {name} (pbr: D·V, s·D·V, s/π)"),
            reason: format!("the metallic-roughness BRDF has no zonal form; {roughness_source}"),
        });
    } else if matches!(
        material,
        Material::BlinnPhong { .. } | Material::Ward { .. } | Material::CookTorrance { .. }
    ) {
        let mut t = prt_shading::projection::glossy_table(material, order);
        t.material = name.to_owned();
        decisions.push(Decision {
            object: None,
            decision: format!("glossy table for {name}"),
            reason: format!(
                "{} has no zonal form; relative projection error at order {order}: {:.3e}",
                name,
                t.projection_error.last().copied().unwrap_or(0.0)
            ),
        });
        glossy.push(t);
    }
}

/// Validates `bake` and hands it back with its report.
pub(crate) fn output(
    bake: Bake,
    reports: Vec<ObjectReport>,
    rays_traced: u64,
    start: std::time::Instant,
    decisions: Vec<Decision>,
) -> Result<BakeOutput, BakeError> {
    bake.validate()?;
    Ok(BakeOutput {
        bake,
        report: BakeReport {
            objects: reports,
            rays_traced,
            seconds: start.elapsed().as_secs_f64(),
            decisions,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The decision line of a pbr material says where its roughness comes from: the factor,
    /// or a texture that the tables (at the factor) do not hold and the fitted path follows.
    #[test]
    fn pbr_decisions_say_where_the_roughness_comes_from() {
        let pbr = |texture: Option<prt_scene::TextureRef>| Material::Pbr {
            base_color: [0.8; 3],
            metallic: 0.0,
            roughness: 0.5,
            base_color_texture: None,
            metallic_roughness_texture: texture,
        };
        let reason = |m: &Material| {
            let (mut glossy, mut decisions) = (Vec::new(), Vec::new());
            glossy_tables("m", m, 3, &mut glossy, &mut decisions);
            assert_eq!(glossy.len(), 3, "three pbr tables");
            decisions.pop().unwrap().reason
        };
        assert!(reason(&pbr(None)).ends_with("roughness 0.5"));
        let textured = reason(&pbr(Some(prt_scene::TextureRef {
            index: 0,
            texcoord: 0,
            transform: None,
        })));
        assert!(
            textured.contains("from a texture") && textured.contains("fitted path"),
            "{textured}"
        );
    }
}
