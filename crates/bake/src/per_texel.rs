//! The per-texel path: the lightmap of each object (from its UVs, or through an atlas that
//! `prt-atlas` generates for a mesh without UVs), and the transfer at every
//! covered texel's surface point (direct rays, plus the bounces gathered from the vertex chain,
//! as per-pixel bakes do).

use crate::assembly::BakedObject;
use crate::error::BakeError;
use crate::plan::ObjectPlan;
use crate::report::ObjectReport;
use crate::rows::{add_scaled, point_blocks, point_stats, store};
use crate::settings::{BakeSettings, PointKind};
use crate::transfer::{self, direct_sided, gather, DirectOptions, GatherScene, MeshTransfer};
use prt_bakefile::{Coverage, Decision, ObjectBake, RayStats};
use prt_scene::binding::{geometry_hash, mesh_geometry};
use prt_scene::lightmap::{Lightmap, LightmapError, TexelPoint};
use prt_scene::{Mesh, Scene};
use prt_sh::Basis;
use prt_tracer::Accel;
use rayon::prelude::*;

/// The lightmap of every object of a per-texel bake: from its UVs, or, for a mesh without UVs,
/// through a generated atlas (`None`, baked per vertex with a decision saying why, when the
/// atlas does not fit); all `None` for other bakes.
pub(crate) fn lightmaps(
    scene: &Scene,
    plans: &[ObjectPlan],
    settings: &BakeSettings,
    decisions: &mut Vec<Decision>,
) -> Result<Vec<Option<Lightmap>>, BakeError> {
    let PointKind::Texel { width, height } = settings.points else {
        return Ok(vec![None; plans.len()]);
    };
    let mut out = Vec::with_capacity(plans.len());
    for p in plans {
        let mesh = &scene.meshes[p.mesh];
        match prt_scene::lightmap::lightmap(mesh, width, height) {
            Ok(l) => {
                let covered = l.covered();
                if covered == 0 {
                    return Err(BakeError::Lightmap {
                        object: p.name.clone(),
                        reason: format!(
                            "its lightmap UVs cover none of the {width}×{height} texels (every triangle is degenerate in UV space)"
                        ),
                    });
                }
                decisions.push(Decision {
                    object: Some(p.name.clone()),
                    decision: format!("per texel: {covered} of {width}×{height} texels"),
                    reason: format!(
                        "lightmap UVs from {} ({:.1} % of the lightmap covered)",
                        match (l.uv_set, mesh.texcoords.len()) {
                            (1, _) => "TEXCOORD_1".to_owned(),
                            (k, _) => format!("UV set {k} (TEXCOORD_{k} / OBJ vt)"),
                        },
                        100.0 * covered as f64 / (f64::from(width) * f64::from(height))
                    ),
                });
                out.push(Some(l));
            }
            Err(LightmapError::NoUvs) => {
                let l = atlas_lightmap(mesh, &p.name, width, height, decisions)?;
                out.push(l);
            }
            Err(e) => {
                return Err(BakeError::Lightmap {
                    object: p.name.clone(),
                    reason: e.to_string(),
                })
            }
        }
    }
    if out.iter().all(Option::is_none) {
        return Err(BakeError::InvalidSettings(
            "--per-texel: no object could be lightmapped (none has texture coordinates — glTF TEXCOORD_1 or TEXCOORD_0, OBJ vt — and their generated atlases do not fit the lightmap: use a larger size); bake per vertex instead".into(),
        ));
    }
    Ok(out)
}

/// The lightmap of a mesh without UVs through a generated atlas (`prt-atlas`), with a decision
/// saying so (charts, texel density, utilisation); per vertex, with a decision saying why,
/// when its charts do not fit the lightmap or cover fewer texels than the mesh has vertices
/// (a lightmap coarser than the vertices).
fn atlas_lightmap(
    mesh: &Mesh,
    name: &str,
    width: u32,
    height: u32,
    decisions: &mut Vec<Decision>,
) -> Result<Option<Lightmap>, BakeError> {
    let opt = prt_atlas::AtlasOptions::new(width, height);
    let atlas = match prt_atlas::generate(&mesh.positions, &mesh.indices, &opt) {
        Ok(a) => a,
        Err(e @ prt_atlas::AtlasError::DoesNotFit { .. }) => {
            decisions.push(Decision {
                object: Some(name.to_owned()),
                decision: "per vertex".into(),
                reason: format!("no texture coordinates, and a generated lightmap atlas: {e}"),
            });
            return Ok(None);
        }
        Err(e) => {
            return Err(BakeError::Lightmap {
                object: name.to_owned(),
                reason: format!("no lightmap atlas: {e}"),
            })
        }
    };
    let (charts, density, used) = (atlas.charts, atlas.texels_per_unit, atlas.utilisation);
    let l = prt_scene::lightmap::lightmap_from_corners(mesh, atlas.corner_uvs, width, height)
        .map_err(|e| BakeError::Lightmap {
            object: name.to_owned(),
            reason: format!("its generated atlas: {e}"),
        })?;
    let covered = l.covered();
    let vertices = mesh.positions.len();
    if covered < vertices {
        // Fewer texels than vertices: the lightmap would be coarser than the vertices.
        decisions.push(Decision {
            object: Some(name.to_owned()),
            decision: "per vertex".into(),
            reason: format!(
                "no texture coordinates, and its generated atlas ({charts} charts) covers only {covered} texels of {width}×{height}, fewer than its {vertices} vertices: a larger --per-texel size lightmaps it"
            ),
        });
        return Ok(None);
    }
    decisions.push(Decision {
        object: Some(name.to_owned()),
        decision: format!("per texel through a generated atlas: {covered} of {width}×{height} texels"),
        reason: format!(
            "no texture coordinates: {charts} charts (normals within {}° of each chart's seed, projected to its plane), {density:.4} texels per unit, {:.1} % of the lightmap inside triangles, gutter {} texels (SPEC §3.9.3)",
            opt.max_angle_deg,
            100.0 * used,
            opt.gutter
        ),
    });
    Ok(Some(l))
}

/// One lightmapped object of a per-texel bake: direct transfer at every covered texel's
/// surface point, plus the bounces gathered from the vertex chain (as per-pixel bakes do).
pub(crate) struct TexelBake<'a> {
    pub accel: &'a Accel,
    pub plan: &'a ObjectPlan,
    pub mesh: &'a Mesh,
    pub lightmap: &'a Lightmap,
    /// What the object's material is (SPEC §3.9.1).
    pub material: prt_bakefile::MaterialBinding,
    pub settings: &'a BakeSettings,
    pub chain: &'a [Vec<MeshTransfer>],
    pub gs: &'a GatherScene<'a>,
    pub basis: &'a Basis,
}

/// What one covered texel measured: its transfer (`channels × order²` each) in f64.
struct Row {
    diffuse: Vec<f64>,
    visibility: Option<Vec<f64>>,
    unshadowed: Option<Vec<f64>>,
    stats: RayStats,
    hits: u64,
}

impl TexelBake<'_> {
    /// Colour channels of the diffuse transfer: RGB with bounces, else one.
    fn channels(&self) -> usize {
        if self.settings.bounces > 0 {
            3
        } else {
            1
        }
    }

    /// The object's bake, report, ray statistics and rays traced.
    pub(crate) fn run(&self) -> BakedObject {
        let bar = self
            .settings
            .progress_bar(self.lightmap.texels.len() as u64, "texels");
        let extent = self.accel.mesh_extent(self.plan.mesh);
        let rows: Vec<Option<Row>> = self
            .lightmap
            .texels
            .par_iter()
            .enumerate()
            .with_min_len(16)
            .map(|(k, t)| {
                bar.inc(1);
                let t = t.as_ref()?;
                Some(self.trace(k, t, extent))
            })
            .collect();
        bar.finish_and_clear();
        self.assemble(&rows)
    }

    /// Traces texel `k` (surface point `t`; `extent` sizes its ray offset) and gathers its
    /// bounces.
    fn trace(&self, k: usize, t: &TexelPoint, extent: f32) -> Row {
        let (plan, settings) = (self.plan, self.settings);
        let bounces = settings.bounces as usize;
        let n2 = plan.order * plan.order;
        let channels = self.channels();
        // A normal-mapped texel: the map's normal shades (cosine and hemisphere), the
        // geometric normal still decides the side (`direct_sided`).
        let scene = self.gs.scene;
        let mapped = scene.has_normal_map(plan.mesh).then(|| {
            let n = scene.shading_normal(plan.mesh, t.triangle, t.bary[1], t.bary[2]);
            // The lightmap's normals face the side baked; the map's follows it.
            if n.dot(t.normal) < 0.0 {
                -n
            } else {
                n
            }
        });
        let point = prt_tracer::points::SamplePoint {
            position: t.position,
            normal: mapped.unwrap_or(t.normal),
            offset_normal: t.geometric_normal,
            offset: prt_tracer::point_offset(t.position, extent),
        };
        let opt = DirectOptions {
            rays: settings.rays,
            record_hits: bounces > 0,
            visibility: plan.needs_visibility,
            seed: settings.seed,
            // Texel streams: their own key space beside vertices and pixels.
            object: plan.mesh as u64 | (2 << 32),
            first_ray: 0,
            basis: self.basis,
        };
        let geometric = mapped.map(|_| t.geometric_normal);
        let d = direct_sided(self.accel, &point, k as u64, &opt, geometric);
        let mut diffuse = vec![0.0f64; channels * n2];
        for c in 0..channels {
            add_scaled(&mut diffuse[c * n2..(c + 1) * n2], &d.shadowed, 1.0);
        }
        for b in 1..=bounces {
            let g = gather(
                &d.hits,
                settings.rays,
                &self.chain[b - 1],
                self.gs,
                plan.order,
            );
            add_scaled(&mut diffuse, &g, 1.0);
        }
        let per_channel =
            |v: &[f64]| -> Vec<f64> { (0..channels).flat_map(|_| v.iter().copied()).collect() };
        let mut stats = RayStats::default();
        stats.add(&point_stats(&d, settings.rays));
        Row {
            diffuse,
            visibility: d.visibility.as_deref().map(per_channel),
            unshadowed: settings
                .unshadowed
                .then(|| per_channel(&transfer::unshadowed(plan.order, point.normal))),
            stats,
            hits: u64::from(d.hit_count),
        }
    }

    /// The object's part of the file from its texels' rows (`None`: texel not covered).
    fn assemble(&self, rows: &[Option<Row>]) -> BakedObject {
        let (plan, settings) = (self.plan, self.settings);
        let channels = self.channels();
        let stride = channels * plan.order * plan.order;
        let texels = rows.len();
        let mut diffuse = vec![0.0f32; texels * stride];
        let mut vis = plan.needs_visibility.then(|| vec![0.0f32; texels * stride]);
        let mut unsh = settings.unshadowed.then(|| vec![0.0f32; texels * stride]);
        let mut stats = RayStats {
            object: plan.name.clone(),
            ..RayStats::default()
        };
        let mut hits = 0u64;
        for (k, r) in rows.iter().enumerate() {
            let Some(r) = r else { continue };
            let dst = k * stride..(k + 1) * stride;
            store(&mut diffuse[dst.clone()], &r.diffuse);
            if let (Some(v), Some(src)) = (vis.as_mut(), &r.visibility) {
                store(&mut v[dst.clone()], src);
            }
            if let (Some(u), Some(src)) = (unsh.as_mut(), &r.unshadowed) {
                store(&mut u[dst], src);
            }
            stats.add(&r.stats);
            hits += r.hits;
        }
        let rays = stats.rays * (1 + u64::from(plan.needs_visibility));
        let blocks = point_blocks(settings.bounces, diffuse, vis, unsh);
        let covered = rows.iter().filter(|r| r.is_some()).count() as u64;
        let report = ObjectReport {
            name: plan.name.clone(),
            order: plan.order,
            points: covered,
            hit_fraction: hits as f64 / stats.rays.max(1) as f64,
            backface_fraction: stats.backface_fraction(),
            inside_fraction: stats.inside_fraction(),
            kinds: blocks.iter().map(|b| b.kind.name().to_owned()).collect(),
        };
        let object = ObjectBake {
            name: plan.name.clone(),
            geometry_hash: geometry_hash(self.mesh.positions.as_slice(), &self.mesh.indices),
            point_count: texels as u64,
            point_first: 0,
            points_in_file: texels as u64,
            order: plan.order as u32,
            channels: channels as u32,
            blocks,
            mesh: Some(mesh_geometry(self.mesh)),
            // One sample per texel: 1 where the texel has a surface point (SPEC §3.11).
            coverage: Some(Coverage {
                pixel_samples: 1,
                hits: rows.iter().map(|r| u32::from(r.is_some())).collect(),
            }),
            material: Some(self.material.clone()),
            pass: None,
        };
        BakedObject {
            object,
            report,
            stats,
            rays,
        }
    }
}
