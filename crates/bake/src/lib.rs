//! Monte Carlo precomputed radiance transfer (Sloan, Kautz & Snyder, "Precomputed Radiance
//! Transfer for Real-Time Rendering in Dynamic, Low-Frequency Lighting Environments",
//! SIGGRAPH 2002), baked with the same ray tracer as the reference images.
//!
//! For every vertex of every object (or, in pixel mode, the primary hit of every pixel of the
//! scene camera; in texel mode, the surface point of every texel of each object's lightmap,
//! `prt_scene::lightmap`) the baker estimates, to an order chosen per object:
//! - **shadowed diffuse transfer** `T_i = ∫ V(ω) max(0, n·ω) y_i(ω) dω` with cosine-distributed
//!   rays from the R2 low-discrepancy sequence, Cranley–Patterson shifted per point;
//! - **visibility** `V_i = ∫ V(ω) y_i(ω) dω` for materials with a glossy lobe (relit as
//!   `(L ⊛ V)` convolved with the lobe, Lee & Kim 2014 eq. 4.3);
//! - **interreflected diffuse transfer** with `B` bounces: each bounce gathers the previous
//!   bounce's transfer at the hit points, interpolated by barycentrics, times the hit
//!   surface's albedo/π (see [`transfer`]);
//! - optionally the analytic **unshadowed** transfer (the clamped cosine rotated to `n`);
//! - the environment's exact SH projection and the BRDF projections of the materials used
//!   (`prt_shading::projection`: zonal clamped-cosine and Phong lobes; per-view-elevation tables for
//!   Blinn–Phong, Ward and Cook–Torrance, after Kautz, Sloan & Snyder 2002).
//!
//! A bake with bounces can run as sharded passes across machines ([`passes`]: each ray traced
//! once, the merged result byte-identical to one unsharded bake), and a finished bake can be
//! compressed by clustered PCA ([`compress`]: Sloan, Hall, Hart & Snyder, "Clustered Principal
//! Components for Precomputed Radiance Transfer", SIGGRAPH 2003).
//!
//! Conventions: the diffuse transfer **excludes the receiving point's own albedo/π**; the
//! outgoing diffuse radiance is `(albedo/π) Σ_i L_i T_i`. Every random number comes from a
//! stream keyed by (seed, purpose, object, point), so bakes are bit-identical for any thread
//! count and for sharded-then-merged bakes. Only what the scene needs is baked, and every
//! such decision is written to the bake's metadata ([`plan`]).

pub mod compress;
mod error;
mod material;
pub mod passes;
pub mod plan;
mod report;
mod settings;
pub mod shard_plan;
pub mod subdivide;
pub mod transfer;

pub use error::BakeError;
pub use material::material_binding;
pub use passes::PassInput;
pub use report::{BakeOutput, BakeReport, ObjectReport};
pub use settings::{BakeSettings, PointKind, DEFAULT_PIXEL_SAMPLES, MAX_PIXEL_SAMPLES};

use indicatif::ProgressBar;
use prt_bakefile::{
    Bake, BakeMeta, Coverage, Decision, EnvCoefficients, EnvPrecision, ObjectBake, RayStats,
    SampleKind, ShardInfo, ToolInfo, TransferBlock, TransferKind,
};
use prt_scene::binding::{camera_info, geometry_hash, mesh_geometry};
use prt_scene::{Mapping, Material, Mesh, Scene};
use prt_sh::{Basis, EnvMapping, ImageRef};
use prt_tracer::progress_bar;
use prt_tracer::Accel;
use rayon::prelude::*;
use transfer::{direct, gather, DirectOptions, DirectResult, GatherScene, MeshTransfer};

fn shard_range(count: u64, shard: Option<(u32, u32)>) -> (u64, u64) {
    match shard {
        None => (0, count),
        Some((i, n)) => {
            let (i, n) = (u64::from(i), u64::from(n));
            let first = count * i / n;
            (first, count * (i + 1) / n - first)
        }
    }
}

fn progress(settings: &BakeSettings, len: u64, what: &str) -> ProgressBar {
    progress_bar(settings.progress, len, what)
}

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
    let start = std::time::Instant::now();
    settings.validate()?;
    if accel.triangle_count() == 0 {
        return Err(BakeError::EmptyScene);
    }
    if let Some(sub) = settings.subdivide {
        return bake_subdivided(scene, accel, settings, pass, &sub, start);
    }
    let (plans, mut decisions) = plan::plan(scene, settings);
    let max_order = plans.iter().map(|p| p.order).max().unwrap_or(1);
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
    let bounces = settings.bounces as usize;
    let vertex_bounces = settings.vertex_bounces();
    let mut need_vertices = vertex_mode || bounces > 0;
    let mut rays_traced = 0u64;
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
    if !vertex_mode {
        settings_json["pixel_samples"] = settings.pixel_samples.into();
    }
    if let PointKind::Texel { width, height } = settings.points {
        // Which UV set each lightmapped object used, and a hash of those UVs, so that
        // relighting refuses a scene whose lightmap UVs changed (SPEC §3.9).
        settings_json["lightmaps"] = plans
            .iter()
            .zip(&lightmaps)
            .map(|(p, l)| match l {
                Some(l) => serde_json::json!({
                    "object": p.name,
                    "width": width,
                    "height": height,
                    "uv_set": l.uv_set,
                    "uv_hash": prt_bakefile::uv_hash(&scene.meshes[p.mesh].texcoords[l.uv_set]).to_string(),
                }),
                None => serde_json::Value::Null,
            })
            .collect();
    }
    // The environment's projection (also what a distributed pass checks its input against).
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
    let environment = EnvCoefficients {
        order: max_order as u32,
        precision: EnvPrecision::F64,
        values: (0..3)
            .flat_map(|c| coeffs.iter().map(move |v| v[c]))
            .collect(),
    };

    // ---- Distributed bounced bakes: which pass, and its input.
    let last_pass = settings.bounces;
    if let Some(p) = &pass {
        let expect = passes::Expect {
            settings: &settings_json,
            names: plans.iter().map(|p| p.name.as_str()).collect(),
            hashes: plans
                .iter()
                .map(|p| {
                    let m = &scene.meshes[p.mesh];
                    geometry_hash(m.positions.as_slice(), &m.indices)
                })
                .collect(),
            orders: plans.iter().map(|p| p.order as u32).collect(),
            albedo: &gs.albedo,
            environment: &environment,
            bounces: last_pass,
            gathers_at_vertices: settings.pass_gathers_at_vertices(p.index),
            shard: settings.shard,
            ranges: plans
                .iter()
                .map(|plan| {
                    shard_range(
                        scene.meshes[plan.mesh].positions.len() as u64,
                        settings.shard,
                    )
                })
                .collect(),
        };
        passes::check(p, &expect)?;
    }
    // Only bakes with bounces have more than one pass; pass 0 of a bake without bounces is the
    // whole (sharded) bake.
    let dist = pass.filter(|_| bounces > 0);
    let dist_index = dist.map(|d| d.index);
    if !vertex_mode && dist_index == Some(last_pass) {
        // The last pass of a per-pixel bake traces pixels only; the vertex levels come in.
        need_vertices = false;
    }

    // ---- Direct pass at vertices.
    let vertex_points: Vec<Vec<prt_tracer::points::SamplePoint>> = (0..scene.meshes.len())
        .map(|m| prt_tracer::points::vertex_points(scene, accel, m))
        .collect();
    let vertex_ranges: Vec<(u64, u64)> = vertex_points
        .iter()
        .map(|p| {
            // A distributed pass works on its shard's vertices only.
            if (vertex_mode && bounces == 0) || dist.is_some() {
                shard_range(p.len() as u64, settings.shard)
            } else {
                (0, p.len() as u64)
            }
        })
        .zip(&lightmaps)
        // A lightmapped object's vertices are traced only for the bounce chain.
        .map(|(r, l)| {
            if l.is_some() && bounces == 0 {
                (0, 0)
            } else {
                r
            }
        })
        .collect();
    let mut vertex_direct: Vec<Vec<DirectResult>> = vec![Vec::new(); plans.len()];
    // Pass k ≥ 1: this shard's part of the previous pass's merged file.
    let previous: Vec<passes::Previous> = match dist {
        Some(PassInput {
            previous: Some(prev),
            hits,
            ..
        }) => (0..plans.len())
            .map(|o| passes::previous(prev, hits, o, vertex_ranges[o].0, vertex_ranges[o].1))
            .collect(),
        _ => Vec::new(),
    };
    if need_vertices && dist_index.is_some_and(|k| k > 0) {
        for (o, p) in previous.iter().enumerate() {
            vertex_direct[o] = p.rows.clone();
        }
    } else if need_vertices {
        let jobs: Vec<(usize, u64)> = plans
            .iter()
            .enumerate()
            .flat_map(|(o, _)| {
                let (first, count) = vertex_ranges[o];
                (first..first + count).map(move |v| (o, v))
            })
            .collect();
        let bar = progress(settings, jobs.len() as u64, "vertices");
        let results: Vec<DirectResult> = jobs
            .par_iter()
            .with_min_len(16)
            .map(|&(o, v)| {
                let plan = &plans[o];
                let opt = DirectOptions {
                    rays: settings.rays,
                    record_hits: vertex_bounces > 0,
                    // (A lightmapped object's vertices only feed the bounce chain.)
                    visibility: vertex_mode && plan.needs_visibility && lightmaps[o].is_none(),
                    seed: settings.seed,
                    object: plan.mesh as u64,
                    first_ray: 0,
                    basis: &bases[o],
                };
                let r = direct(accel, &vertex_points[o][v as usize], v, &opt);
                bar.inc(1);
                r
            })
            .collect();
        bar.finish_and_clear();
        let mut it = results.into_iter();
        for (o, out) in vertex_direct.iter_mut().enumerate() {
            out.extend(it.by_ref().take(vertex_ranges[o].1 as usize));
            let vis = u64::from(vertex_mode && plans[o].needs_visibility && lightmaps[o].is_none());
            rays_traced += vertex_ranges[o].1 * u64::from(settings.rays) * (1 + vis);
        }
    }

    // ---- Bounce chain at vertices: chain[b][mesh] = T^b (RGB, f32).
    let object_hits: Vec<u64> = if previous.is_empty() {
        vertex_direct
            .iter()
            .map(|r| r.iter().map(|d| d.hits.len() as u64).sum())
            .collect()
    } else {
        previous.iter().map(|p| p.object_hits).collect()
    };
    let mut chain: Vec<Vec<MeshTransfer>> = Vec::new();
    let mut vertex_totals: Vec<Vec<Vec<f64>>> = Vec::new();
    if let Some(k) = dist_index {
        // A distributed pass: one bounce level for this shard's vertices, or none.
        let state = passes::Step {
            scene,
            plans: &plans,
            settings,
            vertex_mode,
            vertex_bounces,
            gs: &gs,
            vertex_ranges: &vertex_ranges,
            object_hits: &object_hits,
        };
        match state.run(k, &vertex_direct, previous, progress(settings, 0, "gather"))? {
            passes::Outcome::Intermediate(objects, reports) => {
                let ray_stats = intermediate_stats(&plans, &vertex_direct, dist, settings);
                let meta = BakeMeta {
                    camera: None,
                    pass: Some(passes::info(k, last_pass, &gs.albedo)),
                    ..bake_meta(
                        settings,
                        SampleKind::Vertex,
                        settings_json,
                        &decisions,
                        ray_stats,
                    )
                };
                let bake = Bake {
                    reflectance: None,
                    meta,
                    objects,
                    environment: Some(environment),
                    brdfs: Vec::new(),
                    glossy: Vec::new(),
                };
                bake.validate()?;
                return Ok(BakeOutput {
                    bake,
                    report: BakeReport {
                        objects: reports,
                        rays_traced,
                        seconds: start.elapsed().as_secs_f64(),
                        decisions,
                    },
                });
            }
            passes::Outcome::Final { chain: c, totals } => {
                chain = c;
                vertex_totals = totals;
            }
        }
    } else if need_vertices && (vertex_bounces > 0 || (!vertex_mode && bounces > 0)) {
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
        vertex_totals = vertex_direct
            .iter()
            .map(|r| {
                r.iter()
                    .map(|d| transfer::level0_totals(&d.shadowed))
                    .collect()
            })
            .collect();
        chain.push(t0);
        for b in 1..=vertex_bounces {
            let bar = progress(
                settings,
                vertex_direct.iter().map(|r| r.len() as u64).sum(),
                &format!("bounce {b}"),
            );
            let next: Vec<MeshTransfer> = plans
                .iter()
                .enumerate()
                .map(|(o, p)| {
                    let n2 = p.order * p.order;
                    if object_hits[o] == 0 {
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
                            gather(&d.hits, settings.rays, &chain[b - 1], &gs, p.order)
                        })
                        .collect();
                    for (tot, g) in vertex_totals[o].iter_mut().zip(&per_point) {
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
    }

    // ---- Assemble objects.
    let mut objects = Vec::with_capacity(plans.len());
    let mut ray_stats = Vec::with_capacity(plans.len());
    let mut reports = Vec::with_capacity(plans.len());
    let sample_kind;
    if vertex_mode {
        sample_kind = match settings.points {
            PointKind::Texel { width, height } => SampleKind::Texel { width, height },
            _ => SampleKind::Vertex,
        };
        for (o, plan) in plans.iter().enumerate() {
            let mesh = &scene.meshes[plan.mesh];
            if let Some(lm) = &lightmaps[o] {
                let t = TexelBake {
                    accel,
                    plan,
                    mesh,
                    lightmap: lm,
                    material: material_binding(scene, plan.mesh),
                    settings,
                    chain: &chain,
                    gs: &gs,
                    basis: &bases[o],
                };
                let (object, report, stats, rays) = t.run();
                objects.push(object);
                reports.push(report);
                ray_stats.push(stats);
                rays_traced += rays;
                continue;
            }
            let (first, count) = shard_range(mesh.positions.len() as u64, settings.shard);
            let n2 = plan.order * plan.order;
            let direct_rows = &vertex_direct[o];
            // When all points were traced (bounces), crop to the shard.
            let offset = (first - vertex_ranges[o].0) as usize;
            let rows = &direct_rows[offset..offset + count as usize];
            let interreflected = bounces > 0 && object_hits[o] > 0;
            if bounces > 0 && object_hits[o] == 0 {
                decisions.push(Decision {
                    object: Some(plan.name.clone()),
                    decision: "no bounce gathering".into(),
                    reason: "none of the object's rays hit the scene: interreflected transfer equals shadowed transfer".into(),
                });
            }
            let channels = if interreflected { 3 } else { 1 };
            let mut blocks = Vec::new();
            let mut kinds = Vec::new();
            if interreflected {
                let tot = &vertex_totals[o][offset..offset + count as usize];
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
                let pts = &vertex_points[o][first as usize..(first + count) as usize];
                blocks.push(TransferBlock {
                    cpca: None,
                    kind: TransferKind::UnshadowedDiffuse,
                    data: pts
                        .iter()
                        .flat_map(|p| {
                            let u = transfer::unshadowed(plan.order, p.normal);
                            (0..channels).flat_map(move |_| u.clone().into_iter().map(|x| x as f32))
                        })
                        .collect(),
                });
            }
            blocks.sort_by_key(|b| b.kind);
            kinds.extend(blocks.iter().map(|b| b.kind.name().to_owned()));
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
            reports.push(ObjectReport {
                name: plan.name.clone(),
                order: plan.order,
                points: count,
                hit_fraction: hits as f64 / denom,
                backface_fraction: stats.backface_fraction(),
                inside_fraction: stats.inside_fraction(),
                kinds,
            });
            ray_stats.push(stats);
            objects.push(ObjectBake {
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
            });
        }
    } else {
        let (w, h) = (scene.camera.width, scene.camera.height);
        sample_kind = SampleKind::Pixel {
            width: w,
            height: h,
        };
        let k = settings.pixel_samples;
        let footprints = prt_tracer::points::pixel_footprints(scene, accel, settings.seed, k)?;
        let (first, count) = shard_range(footprints.pixel_count() as u64, settings.shard);
        let channels = if bounces > 0 { 3 } else { 1 };
        let bar = progress(settings, count, "pixels");
        // Per pixel: the footprint-averaged transfer of every object its samples hit.
        let results: Vec<Vec<PixelTransfer>> = (first as usize..(first + count) as usize)
            .into_par_iter()
            .with_min_len(4)
            .map(|px| {
                let mut objects: Vec<PixelTransfer> = Vec::new();
                for (j, sample) in footprints.pixel(px).iter().enumerate() {
                    let Some((mesh, p)) = sample.hit else {
                        continue;
                    };
                    let plan = &plans[mesh];
                    let n2 = plan.order * plan.order;
                    // The pixel's R rays are shared out over its K samples: sample j takes
                    // the next contiguous block of the pixel's low-discrepancy sequence.
                    let j = j as u32;
                    let (base, extra) = (settings.rays / k, settings.rays % k);
                    let rays = base + u32::from(j < extra);
                    let opt = DirectOptions {
                        rays,
                        record_hits: bounces > 0,
                        visibility: plan.needs_visibility,
                        seed: settings.seed,
                        object: plan.mesh as u64 | (1 << 32),
                        first_ray: j * base + j.min(extra),
                        basis: &bases[mesh],
                    };
                    let d = direct(accel, &p, px as u64, &opt);
                    let entry = match objects.iter().position(|t| t.mesh == mesh) {
                        Some(i) => &mut objects[i],
                        None => {
                            objects.push(PixelTransfer::new(
                                mesh,
                                channels * n2,
                                plan.needs_visibility.then_some(n2),
                                settings.unshadowed.then_some(n2),
                            ));
                            objects.last_mut().expect("just pushed")
                        }
                    };
                    let weight = 1.0 / f64::from(k);
                    for c in 0..channels {
                        add_scaled(
                            &mut entry.diffuse[c * n2..(c + 1) * n2],
                            &d.shadowed,
                            weight,
                        );
                    }
                    for b in 1..=bounces {
                        let g = gather(&d.hits, rays, &chain[b - 1], &gs, plan.order);
                        add_scaled(&mut entry.diffuse, &g, weight);
                    }
                    if let (Some(v), Some(src)) = (entry.visibility.as_mut(), &d.visibility) {
                        add_scaled(v, src, weight);
                    }
                    if let Some(u) = entry.unshadowed.as_mut() {
                        add_scaled(u, &transfer::unshadowed(plan.order, p.normal), weight);
                    }
                    entry.hits += u64::from(d.hit_count);
                    entry.stats.add(&point_stats(&d, rays));
                }
                bar.inc(1);
                objects
            })
            .collect();
        bar.finish_and_clear();
        for (o, plan) in plans.iter().enumerate() {
            let mesh = &scene.meshes[plan.mesh];
            let n2 = plan.order * plan.order;
            let stride = channels * n2;
            let mut diffuse = vec![0.0f32; count as usize * stride];
            let mut vis = plan
                .needs_visibility
                .then(|| vec![0.0f32; count as usize * stride]);
            let mut unsh = settings
                .unshadowed
                .then(|| vec![0.0f32; count as usize * stride]);
            let (mut npts, mut hits) = (0u64, 0u64);
            let mut stats = RayStats {
                object: plan.name.clone(),
                ..RayStats::default()
            };
            for (px, objs) in results.iter().enumerate() {
                let Some(t) = objs.iter().find(|t| t.mesh == o) else {
                    continue;
                };
                npts += 1;
                hits += t.hits;
                stats.add(&t.stats);
                let base = px * stride;
                store(&mut diffuse[base..base + stride], &t.diffuse);
                for c in 0..channels {
                    let dst = base + c * n2..base + (c + 1) * n2;
                    if let (Some(v), Some(src)) = (vis.as_mut(), &t.visibility) {
                        store(&mut v[dst.clone()], src);
                    }
                    if let (Some(u), Some(src)) = (unsh.as_mut(), &t.unshadowed) {
                        store(&mut u[dst], src);
                    }
                }
            }
            rays_traced += stats.rays * (1 + u64::from(plan.needs_visibility));
            let blocks = point_blocks(settings.bounces, diffuse, vis, unsh);
            reports.push(ObjectReport {
                name: plan.name.clone(),
                order: plan.order,
                points: npts,
                hit_fraction: hits as f64 / stats.rays.max(1) as f64,
                backface_fraction: stats.backface_fraction(),
                inside_fraction: stats.inside_fraction(),
                kinds: blocks.iter().map(|b| b.kind.name().to_owned()).collect(),
            });
            ray_stats.push(stats);
            objects.push(ObjectBake {
                name: plan.name.clone(),
                geometry_hash: geometry_hash(mesh.positions.as_slice(), &mesh.indices),
                point_count: u64::from(w) * u64::from(h),
                point_first: first,
                points_in_file: count,
                order: plan.order as u32,
                channels: channels as u32,
                blocks,
                mesh: Some(mesh_geometry(mesh)),
                // The object's share of each pixel's footprint samples (SPEC §3.11).
                coverage: Some(Coverage {
                    pixel_samples: k,
                    hits: (first as usize..(first + count) as usize)
                        .map(|px| {
                            let samples = footprints.pixel(px).iter();
                            samples
                                .filter(|s| s.hit.is_some_and(|(m, _)| m == plan.mesh))
                                .count() as u32
                        })
                        .collect(),
                }),
                material: Some(material_binding(scene, plan.mesh)),
                pass: None,
            });
        }
    }

    // ---- BRDF projections.
    let mut brdfs = Vec::new();
    let mut glossy = Vec::new();
    let mut seen = std::collections::BTreeSet::new();
    for plan in &plans {
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
        if let Material::Pbr { roughness, .. } = *material {
            for c in prt_shading::projection::PbrComponent::ALL {
                let mut t = prt_shading::projection::pbr_table(roughness, c, order);
                t.material = format!("{name}{}", c.suffix());
                glossy.push(t);
            }
            decisions.push(Decision {
                object: None,
                decision: format!("glossy tables for {name} (pbr: D·V, s·D·V, s/π)"),
                reason: format!(
                    "the metallic-roughness BRDF has no zonal form; roughness factor {roughness} (a roughness texture is not in the tables)"
                ),
            });
        } else if matches!(
            material,
            Material::BlinnPhong { .. } | Material::Ward { .. } | Material::CookTorrance { .. }
        ) {
            let mut t = prt_shading::projection::glossy_table(material, order);
            t.material = name.clone();
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

    let meta = BakeMeta {
        camera: (!vertex_mode).then(|| camera_info(&scene.camera)),
        ..bake_meta(settings, sample_kind, settings_json, &decisions, ray_stats)
    };
    let mut bake = Bake {
        reflectance: None,
        meta,
        objects,
        environment: Some(environment),
        brdfs,
        glossy,
    };
    if vertex_mode && dist_index.is_some_and(|k| k > 0) {
        // The vertices' rays were traced in pass 0: their counts come with the previous file.
        bake.meta.ray_stats = intermediate_stats(&plans, &vertex_direct, dist, settings);
    }
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

/// The footprint-averaged transfer of one object in one pixel (`1/K` times the sum over the
/// pixel's samples that hit the object; samples that hit another object or nothing add 0).
struct PixelTransfer {
    mesh: usize,
    /// `channels × order²`.
    diffuse: Vec<f64>,
    /// `order²` (the same for every channel).
    visibility: Option<Vec<f64>>,
    /// `order²`.
    unshadowed: Option<Vec<f64>>,
    hits: u64,
    /// Over the samples that hit the object.
    stats: RayStats,
}

impl PixelTransfer {
    fn new(
        mesh: usize,
        diffuse: usize,
        visibility: Option<usize>,
        unshadowed: Option<usize>,
    ) -> Self {
        Self {
            mesh,
            diffuse: vec![0.0; diffuse],
            visibility: visibility.map(|n| vec![0.0; n]),
            unshadowed: unshadowed.map(|n| vec![0.0; n]),
            hits: 0,
            stats: RayStats::default(),
        }
    }
}

/// The ray statistics of one point that traced `rays` diffuse rays: it started inside
/// geometry when more than half of them hit the back of a surface.
fn point_stats(d: &DirectResult, rays: u32) -> RayStats {
    let inside = 2 * d.backface_hits > rays;
    RayStats {
        object: String::new(),
        points: 1,
        rays: u64::from(rays),
        backface_hits: u64::from(d.backface_hits),
        inside_points: u64::from(inside),
        inside_rays: if inside { u64::from(rays) } else { 0 },
    }
}

/// `dst += weight · src` element-wise.
fn add_scaled(dst: &mut [f64], src: &[f64], weight: f64) {
    dst.iter_mut().zip(src).for_each(|(d, s)| *d += weight * s);
}

/// `dst = src` rounded to f32.
fn store(dst: &mut [f32], src: &[f64]) {
    dst.iter_mut().zip(src).for_each(|(d, s)| *d = *s as f32);
}

/// Diffuse radiance of every point of object `object` relit in f64 from the bake's own
/// environment coefficients: `(albedo/π) Σ_{i<order²} L_i T_i` per channel, with `T` the
/// object's interreflected (or else shadowed) diffuse transfer and `order` at most the baked
/// one (`None`: the baked order). A reference-precision check of a bake; the fast f32 path is
/// `prt-relight`.
pub fn relit_diffuse(
    bake: &Bake,
    object: usize,
    albedo: [f32; 3],
    order: Option<usize>,
) -> Result<Vec<[f64; 3]>, BakeError> {
    let bad = |m: String| BakeError::InvalidSettings(m);
    let obj = bake
        .objects
        .get(object)
        .ok_or_else(|| bad(format!("the bake has no object {object}")))?;
    let env = bake
        .environment
        .as_ref()
        .ok_or_else(|| bad("the bake has no environment coefficients".into()))?;
    let n2 = (obj.order * obj.order) as usize;
    let en2 = (env.order * env.order) as usize;
    let k = order.map_or(n2, |o| o * o);
    if k == 0 || k > n2 || k > en2 {
        return Err(bad(format!(
            "relighting order {order:?} exceeds the object's order {} or the environment's {}",
            obj.order, env.order
        )));
    }
    let block = obj
        .diffuse_block()
        .ok_or_else(|| bad(format!("object {} has no diffuse transfer", obj.name)))?;
    let ch = obj.channels as usize;
    Ok((0..obj.points_in_file as usize)
        .map(|p| {
            let mut rgb = [0.0; 3];
            for (c, out) in rgb.iter_mut().enumerate() {
                let t = &block.data[(p * ch + c.min(ch - 1)) * n2..][..k];
                let l = &env.values[c * en2..][..k];
                *out = f64::from(albedo[c]) / std::f64::consts::PI
                    * t.iter().zip(l).map(|(a, b)| f64::from(*a) * b).sum::<f64>();
            }
            rgb
        })
        .collect())
}

/// The lightmap of every object of a per-texel bake (`None` for objects without UVs, baked
/// per vertex, with a decision saying so); all `None` for other bakes.
fn lightmaps(
    scene: &Scene,
    plans: &[plan::ObjectPlan],
    settings: &BakeSettings,
    decisions: &mut Vec<Decision>,
) -> Result<Vec<Option<prt_scene::lightmap::Lightmap>>, BakeError> {
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
            Err(prt_scene::lightmap::LightmapError::NoUvs) => {
                decisions.push(Decision {
                    object: Some(p.name.clone()),
                    decision: "per vertex".into(),
                    reason: "no texture coordinates for a lightmap (glTF TEXCOORD_1 or TEXCOORD_0, OBJ vt)".into(),
                });
                out.push(None);
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
            "--per-texel: no object has texture coordinates for a lightmap (glTF TEXCOORD_1 or TEXCOORD_0, OBJ vt); bake per vertex instead".into(),
        ));
    }
    Ok(out)
}

/// The blocks of a per-pixel or per-texel object, in block order: its diffuse transfer
/// (interreflected with bounces, else shadowed) and the optional visibility and unshadowed
/// transfer.
fn point_blocks(
    bounces: u32,
    diffuse: Vec<f32>,
    visibility: Option<Vec<f32>>,
    unshadowed: Option<Vec<f32>>,
) -> Vec<TransferBlock> {
    let kind = if bounces > 0 {
        TransferKind::InterreflectedDiffuse { bounces }
    } else {
        TransferKind::ShadowedDiffuse
    };
    let block = |kind, data| TransferBlock {
        cpca: None,
        kind,
        data,
    };
    let mut blocks = vec![block(kind, diffuse)];
    blocks.extend(visibility.map(|v| block(TransferKind::Visibility, v)));
    blocks.extend(unshadowed.map(|u| block(TransferKind::UnshadowedDiffuse, u)));
    blocks.sort_by_key(|b| b.kind);
    blocks
}

/// One lightmapped object of a per-texel bake: direct transfer at every covered texel's
/// surface point, plus the bounces gathered from the vertex chain (as per-pixel bakes do).
struct TexelBake<'a> {
    accel: &'a Accel,
    plan: &'a plan::ObjectPlan,
    mesh: &'a Mesh,
    lightmap: &'a prt_scene::lightmap::Lightmap,
    /// What the object's material is (SPEC §3.9.1).
    material: prt_bakefile::MaterialBinding,
    settings: &'a BakeSettings,
    chain: &'a [Vec<MeshTransfer>],
    gs: &'a GatherScene<'a>,
    basis: &'a Basis,
}

impl TexelBake<'_> {
    /// The object's bake, report, ray statistics and rays traced.
    fn run(&self) -> (ObjectBake, ObjectReport, RayStats, u64) {
        let (plan, settings) = (self.plan, self.settings);
        let bounces = settings.bounces as usize;
        let n2 = plan.order * plan.order;
        let channels = if bounces > 0 { 3 } else { 1 };
        let stride = channels * n2;
        let extent = self.accel.mesh_extent(plan.mesh);
        let bar = progress(settings, self.lightmap.texels.len() as u64, "texels");
        struct Row {
            diffuse: Vec<f64>,
            visibility: Option<Vec<f64>>,
            unshadowed: Option<Vec<f64>>,
            stats: RayStats,
            hits: u64,
        }
        let rows: Vec<Option<Row>> = self
            .lightmap
            .texels
            .par_iter()
            .enumerate()
            .with_min_len(16)
            .map(|(k, t)| {
                bar.inc(1);
                let t = t.as_ref()?;
                let point = prt_tracer::points::SamplePoint {
                    position: t.position,
                    normal: t.normal,
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
                let d = direct(self.accel, &point, k as u64, &opt);
                let mut diffuse = vec![0.0f64; stride];
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
                let per_channel = |v: &[f64]| -> Vec<f64> {
                    (0..channels).flat_map(|_| v.iter().copied()).collect()
                };
                let mut stats = RayStats::default();
                stats.add(&point_stats(&d, settings.rays));
                Some(Row {
                    diffuse,
                    visibility: d.visibility.as_deref().map(per_channel),
                    unshadowed: settings
                        .unshadowed
                        .then(|| per_channel(&transfer::unshadowed(plan.order, t.normal))),
                    stats,
                    hits: u64::from(d.hit_count),
                })
            })
            .collect();
        bar.finish_and_clear();
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
        (object, report, stats, rays)
    }
}

/// The ray statistics of an intermediate pass file, or of the last pass of a per-vertex
/// distributed bake: they are counts over a shard's points, so that merging adds them up. Pass
/// 0 counts its own vertices' rays; later passes traced no vertex rays and only know the merged
/// total, which shard 0 carries (the others carry zeros, as [`prt_bakefile::split`] does).
fn intermediate_stats(
    plans: &[plan::ObjectPlan],
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

/// A per-vertex bake on meshes refined where the transfer changes fast ([`subdivide`]): the
/// refinement, then the ordinary bake of the refined scene; the file's meshes are the refined
/// ones, and `settings.subdivided_from` names each object's source mesh (SPEC §3.9).
fn bake_subdivided(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    pass: Option<PassInput<'_>>,
    sub: &subdivide::SubdivideOptions,
    start: std::time::Instant,
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
    let (plans, _) = plan::plan(scene, settings);
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
        let d = Decision {
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
                    "edges whose transfer differed by more than {} (relative L2) were split, level by level: {:?} edges (at most {} levels)",
                    sub.error, r.splits, sub.max_levels
                )
            },
        };
        m.decisions.push(d.clone());
        out.report.decisions.push(d);
        out.report.rays_traced += r.rays;
    }
    m.settings["subdivided_from"] = serde_json::Value::Object(from);
    out.report.seconds = start.elapsed().as_secs_f64();
    out.bake.validate()?;
    Ok(out)
}

/// The metadata every file of a bake shares (no camera, not a pass file).
fn bake_meta(
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
