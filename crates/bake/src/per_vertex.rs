//! The per-vertex path: the direct pass at vertices, the bounce chain gathered there (which
//! per-pixel and per-texel bakes gather from too), and the objects of a per-vertex bake.

use crate::assembly::BakedObject;
use crate::material::material_binding;
use crate::passes::{self, PassInput};
use crate::report::ObjectReport;
use crate::rows::point_stats;
use crate::setup::Setup;
use crate::transfer::{self, direct, gather, DirectOptions, DirectResult, MeshTransfer};
use prt_bakefile::{Decision, ObjectBake, RayStats, TransferBlock, TransferKind};
use prt_scene::binding::{geometry_hash, mesh_geometry};
use prt_tracer::points::SamplePoint;
use rayon::prelude::*;

/// The vertices of a bake as its direct pass left them.
pub(crate) struct Vertices {
    /// Per object: every vertex's sample point.
    pub points: Vec<Vec<SamplePoint>>,
    /// Per object: the vertices this run works on, `(first, count)`.
    pub ranges: Vec<(u64, u64)>,
    /// Per object: the direct results of those vertices (empty when none are needed).
    pub direct: Vec<Vec<DirectResult>>,
    /// Pass k ≥ 1 of a distributed bake: this shard's part of the previous pass's merged
    /// file, per object (empty otherwise).
    pub previous: Vec<passes::Previous>,
    /// Per object: the hits its vertices recorded (all of them, not only this shard's).
    pub object_hits: Vec<u64>,
    /// Rays this run traced from vertices.
    pub rays_traced: u64,
}

impl Vertices {
    /// The direct pass at the vertices of every object: traced now (`need`: the bake needs
    /// vertices at all), or taken from the previous file of distributed pass `dist`.
    pub(crate) fn trace(setup: &Setup<'_>, dist: Option<PassInput<'_>>, need: bool) -> Self {
        let (scene, settings) = (setup.scene, setup.settings);
        let bounces = settings.bounces as usize;
        let points: Vec<Vec<SamplePoint>> = (0..scene.meshes.len())
            .map(|m| prt_tracer::points::vertex_points(scene, setup.accel, m))
            .collect();
        let ranges: Vec<(u64, u64)> = points
            .iter()
            .map(|p| {
                // A distributed pass works on its shard's vertices only.
                if (setup.vertex_mode && bounces == 0) || dist.is_some() {
                    settings.shard_range(p.len() as u64)
                } else {
                    (0, p.len() as u64)
                }
            })
            .zip(&setup.lightmaps)
            // A lightmapped object's vertices are traced only for the bounce chain.
            .map(|(r, l)| {
                if l.is_some() && bounces == 0 {
                    (0, 0)
                } else {
                    r
                }
            })
            .collect();
        let mut direct: Vec<Vec<DirectResult>> = vec![Vec::new(); setup.plans.len()];
        // Pass k ≥ 1: this shard's part of the previous pass's merged file.
        let previous: Vec<passes::Previous> = match dist {
            Some(PassInput {
                previous: Some(prev),
                hits,
                ..
            }) => (0..setup.plans.len())
                .map(|o| passes::previous(prev, hits, o, ranges[o].0, ranges[o].1))
                .collect(),
            _ => Vec::new(),
        };
        let mut rays_traced = 0u64;
        if need && dist.is_some_and(|d| d.index > 0) {
            for (o, p) in previous.iter().enumerate() {
                direct[o] = p.rows.clone();
            }
        } else if need {
            rays_traced = trace_direct(setup, &points, &ranges, &mut direct);
        }
        let object_hits: Vec<u64> = if previous.is_empty() {
            direct
                .iter()
                .map(|r| r.iter().map(|d| d.hits.len() as u64).sum())
                .collect()
        } else {
            previous.iter().map(|p| p.object_hits).collect()
        };
        Self {
            points,
            ranges,
            direct,
            previous,
            object_hits,
            rays_traced,
        }
    }
}

/// Traces the direct transfer of every object's vertices in `ranges` into `direct` (one job
/// per vertex, objects in turn); the rays traced.
fn trace_direct(
    setup: &Setup<'_>,
    points: &[Vec<SamplePoint>],
    ranges: &[(u64, u64)],
    direct_rows: &mut [Vec<DirectResult>],
) -> u64 {
    let (plans, settings, vertex_mode) = (&setup.plans, setup.settings, setup.vertex_mode);
    let vertex_bounces = settings.vertex_bounces();
    let jobs: Vec<(usize, u64)> = plans
        .iter()
        .enumerate()
        .flat_map(|(o, _)| {
            let (first, count) = ranges[o];
            (first..first + count).map(move |v| (o, v))
        })
        .collect();
    let bar = settings.progress_bar(jobs.len() as u64, "vertices");
    let results: Vec<DirectResult> = jobs
        .par_iter()
        .with_min_len(16)
        .map(|&(o, v)| {
            let plan = &plans[o];
            let opt = DirectOptions {
                rays: settings.rays,
                record_hits: vertex_bounces > 0,
                // (A lightmapped object's vertices only feed the bounce chain.)
                visibility: vertex_mode && plan.needs_visibility && setup.lightmaps[o].is_none(),
                seed: settings.seed,
                object: plan.mesh as u64,
                first_ray: 0,
                basis: &setup.bases[o],
            };
            let r = direct(setup.accel, &points[o][v as usize], v, &opt);
            bar.inc(1);
            r
        })
        .collect();
    bar.finish_and_clear();
    let mut rays_traced = 0u64;
    let mut it = results.into_iter();
    for (o, out) in direct_rows.iter_mut().enumerate() {
        out.extend(it.by_ref().take(ranges[o].1 as usize));
        let vis =
            u64::from(vertex_mode && plans[o].needs_visibility && setup.lightmaps[o].is_none());
        rays_traced += ranges[o].1 * u64::from(settings.rays) * (1 + vis);
    }
    rays_traced
}

/// The bounce levels at vertices, `chain[b][object] = T^b` (RGB, f32), and each vertex's
/// running total `T^0 + … + T^B` in f64.
#[derive(Default)]
pub(crate) struct Levels {
    pub chain: Vec<Vec<MeshTransfer>>,
    pub totals: Vec<Vec<Vec<f64>>>,
}

/// Gathers `settings.vertex_bounces()` bounces at the vertices, level by level, each from the
/// level before.
pub(crate) fn gather_bounces(setup: &Setup<'_>, vertices: &Vertices) -> Levels {
    let (plans, settings) = (&setup.plans, setup.settings);
    let vertex_direct = &vertices.direct;
    let t0: Vec<MeshTransfer> = plans
        .iter()
        .enumerate()
        .map(|(o, p)| {
            let n2 = p.order * p.order;
            let mut data = Vec::with_capacity(vertex_direct[o].len() * 3 * n2);
            for d in &vertex_direct[o] {
                for _ in 0..3 {
                    data.extend(d.shadowed.iter().map(|v| *v as f32));
                }
            }
            MeshTransfer {
                order: p.order,
                data,
            }
        })
        .collect();
    let mut totals: Vec<Vec<Vec<f64>>> = vertex_direct
        .iter()
        .map(|r| {
            r.iter()
                .map(|d| transfer::level0_totals(&d.shadowed))
                .collect()
        })
        .collect();
    let mut chain = vec![t0];
    for b in 1..=settings.vertex_bounces() {
        let bar = settings.progress_bar(
            vertex_direct.iter().map(|r| r.len() as u64).sum(),
            &format!("bounce {b}"),
        );
        let next: Vec<MeshTransfer> = plans
            .iter()
            .enumerate()
            .map(|(o, p)| {
                let n2 = p.order * p.order;
                if vertices.object_hits[o] == 0 {
                    return MeshTransfer {
                        order: p.order,
                        data: vec![0.0; vertex_direct[o].len() * 3 * n2],
                    };
                }
                let per_point: Vec<Vec<f64>> = vertex_direct[o]
                    .par_iter()
                    .with_min_len(64)
                    .map(|d| {
                        bar.inc(1);
                        gather(&d.hits, settings.rays, &chain[b - 1], &setup.gs, p.order)
                    })
                    .collect();
                for (tot, g) in totals[o].iter_mut().zip(&per_point) {
                    tot.iter_mut().zip(g).for_each(|(t, v)| *t += v);
                }
                MeshTransfer {
                    order: p.order,
                    data: per_point.iter().flatten().map(|v| *v as f32).collect(),
                }
            })
            .collect();
        bar.finish_and_clear();
        chain.push(next);
    }
    Levels { chain, totals }
}

/// Object `o` of a per-vertex bake: this shard's vertices' transfer (interreflected from
/// `totals` with bounces, else shadowed), visibility and unshadowed transfer.
pub(crate) fn vertex_object(
    setup: &Setup<'_>,
    vertices: &Vertices,
    totals: &[Vec<Vec<f64>>],
    o: usize,
    decisions: &mut Vec<Decision>,
) -> BakedObject {
    let (scene, settings) = (setup.scene, setup.settings);
    let plan = &setup.plans[o];
    let mesh = &scene.meshes[plan.mesh];
    let (first, count) = settings.shard_range(mesh.positions.len() as u64);
    let n2 = plan.order * plan.order;
    // When all points were traced (bounces), crop to the shard.
    let offset = (first - vertices.ranges[o].0) as usize;
    let rows = &vertices.direct[o][offset..offset + count as usize];
    let interreflected = settings.bounces > 0 && vertices.object_hits[o] > 0;
    if settings.bounces > 0 && vertices.object_hits[o] == 0 {
        decisions.push(Decision {
            object: Some(plan.name.clone()),
            decision: "no bounce gathering".into(),
            reason: "none of the object's rays hit the scene: interreflected transfer equals shadowed transfer".into(),
        });
    }
    let channels = if interreflected { 3 } else { 1 };
    let totals = interreflected.then(|| &totals[o][offset..offset + count as usize]);
    let points = &vertices.points[o][first as usize..(first + count) as usize];
    let blocks = vertex_blocks(setup, o, rows, totals, points);
    debug_assert!(blocks
        .iter()
        .all(|b| b.data.len() == count as usize * channels * n2));
    let hits: u64 = rows.iter().map(|d| u64::from(d.hit_count)).sum();
    let mut stats = RayStats {
        object: plan.name.clone(),
        ..RayStats::default()
    };
    for d in rows {
        stats.add(&point_stats(d, settings.rays));
    }
    let denom = stats.rays.max(1) as f64;
    let report = ObjectReport {
        name: plan.name.clone(),
        order: plan.order,
        points: count,
        hit_fraction: hits as f64 / denom,
        backface_fraction: stats.backface_fraction(),
        inside_fraction: stats.inside_fraction(),
        kinds: blocks.iter().map(|b| b.kind.name().to_owned()).collect(),
    };
    let object = ObjectBake {
        name: plan.name.clone(),
        geometry_hash: geometry_hash(mesh.positions.as_slice(), &mesh.indices),
        point_count: mesh.positions.len() as u64,
        point_first: first,
        points_in_file: count,
        order: plan.order as u32,
        channels: channels as u32,
        blocks,
        mesh: Some(mesh_geometry(mesh)),
        coverage: None,
        material: Some(material_binding(scene, plan.mesh)),
        pass: None,
    };
    BakedObject {
        object,
        report,
        stats,
        // The vertices' rays are counted with the direct pass.
        rays: 0,
    }
}

/// The blocks of object `o` of a per-vertex bake, in block order: its diffuse transfer (the
/// running `totals` when interreflected, RGB; else the shadowed transfer of `rows`), its
/// visibility and its unshadowed transfer (at `points`), with as many channels as the diffuse.
fn vertex_blocks(
    setup: &Setup<'_>,
    o: usize,
    rows: &[DirectResult],
    totals: Option<&[Vec<f64>]>,
    points: &[SamplePoint],
) -> Vec<TransferBlock> {
    let (plan, settings) = (&setup.plans[o], setup.settings);
    let channels = if totals.is_some() { 3 } else { 1 };
    let mut blocks = Vec::new();
    if let Some(tot) = totals {
        blocks.push(TransferBlock {
            cpca: None,
            kind: TransferKind::InterreflectedDiffuse {
                bounces: settings.bounces,
            },
            data: tot.iter().flatten().map(|v| *v as f32).collect(),
        });
    } else {
        blocks.push(TransferBlock {
            cpca: None,
            kind: TransferKind::ShadowedDiffuse,
            data: rows
                .iter()
                .flat_map(|d| d.shadowed.iter().map(|v| *v as f32))
                .collect(),
        });
    }
    if plan.needs_visibility {
        blocks.push(TransferBlock {
            cpca: None,
            kind: TransferKind::Visibility,
            data: rows
                .iter()
                .flat_map(|d| {
                    let v = d.visibility.as_ref().expect("visibility traced");
                    (0..channels).flat_map(move |_| v.iter().map(|x| *x as f32))
                })
                .collect(),
        });
    }
    if settings.unshadowed {
        blocks.push(TransferBlock {
            cpca: None,
            kind: TransferKind::UnshadowedDiffuse,
            data: points
                .iter()
                .flat_map(|p| {
                    let u = transfer::unshadowed(plan.order, p.normal);
                    (0..channels).flat_map(move |_| u.clone().into_iter().map(|x| x as f32))
                })
                .collect(),
        });
    }
    blocks.sort_by_key(|b| b.kind);
    blocks
}
