//! Distributed bounced bakes: the bake split into passes, each sharded across machines.
//!
//! With `B` bounces a bake runs passes `0 … B`. Pass 0 traces the direct transfer of its
//! shard's vertices and records their ray hits; pass `k` gathers bounce `k` for its shard's
//! vertices from the merged file of pass `k − 1`, which carries every vertex's bounce levels so
//! far (SPEC §3.12); the last pass writes the shard of the final bake (per-pixel bakes: pass
//! `B` traces the shard's pixels and gathers from the vertex levels `0 … B−1`). Nothing is
//! traced twice: the rays of a vertex are traced once, in pass 0, and their hits travel in the
//! files, so the shards of all passes together trace exactly the rays of one unsharded bake,
//! and the merged last pass is byte for byte the unsharded bake (the same f32/f64 arithmetic in
//! the same order).

use crate::transfer::{DirectResult, HitRecord, MeshTransfer};
use crate::BakeError;
use prt_bakefile::{Bake, EnvCoefficients, PassHit, PassInfo, TransferKind};

/// Which pass to run, and the merged file of the pass before it.
#[derive(Clone, Copy, Debug)]
pub struct PassInput<'a> {
    /// Pass index, `0 ≤ index ≤ bounces`.
    pub index: u32,
    /// The merged result of pass `index − 1` (`None` for pass 0).
    pub previous: Option<&'a Bake>,
    /// This shard's own pass-0 file, which holds its vertices' hit records (passes that gather
    /// at vertices need it; a merged file keeps only the counts).
    pub hits: Option<&'a Bake>,
}

fn fail(msg: impl Into<String>) -> BakeError {
    BakeError::Pass(msg.into())
}

/// What this run expects a previous pass's file to agree with.
pub(crate) struct Expect<'a> {
    pub settings: &'a serde_json::Value,
    pub names: Vec<&'a str>,
    pub hashes: Vec<u64>,
    pub orders: Vec<u32>,
    pub albedo: &'a [[f32; 3]],
    pub environment: &'a EnvCoefficients,
    pub bounces: u32,
    /// Whether this pass gathers a bounce at vertices (and so needs the shard's hits).
    pub gathers_at_vertices: bool,
    /// This run's shard.
    pub shard: Option<(u32, u32)>,
    /// This shard's point range per object.
    pub ranges: Vec<(u64, u64)>,
}

/// Checks the pass index against the bake, and `previous` against this run.
pub(crate) fn check(pass: &PassInput<'_>, expect: &Expect<'_>) -> Result<(), BakeError> {
    let last = expect.bounces;
    if pass.index > last {
        return Err(fail(format!(
            "pass {} of a bake with {last} bounce(s): its passes are 0..={last}",
            pass.index
        )));
    }
    let Some(prev) = pass.previous else {
        return if pass.index == 0 {
            if pass.hits.is_some() {
                return Err(fail("pass 0 records the hits: it takes no --hits file"));
            }
            Ok(())
        } else {
            Err(fail(format!(
                "pass {} needs --previous: the merged file of pass {}",
                pass.index,
                pass.index - 1
            )))
        };
    };
    if pass.index == 0 {
        return Err(fail("pass 0 starts the bake: it takes no --previous file"));
    }
    let Some(info) = &prev.meta.pass else {
        return Err(fail(
            "the --previous file is a finished bake, not the intermediate file of a pass",
        ));
    };
    if info.index + 1 != pass.index || info.last != last {
        return Err(fail(format!(
            "the --previous file is pass {} of {} passes; pass {} of {} needs pass {}",
            info.index,
            info.last + 1,
            pass.index,
            last + 1,
            pass.index - 1
        )));
    }
    if prev.meta.shard.count != 1 {
        return Err(fail(format!(
            "the --previous file is shard {} of {} of pass {}: merge that pass's shards first (prt merge)",
            prev.meta.shard.index, prev.meta.shard.count, info.index
        )));
    }
    if &prev.meta.settings != expect.settings {
        let differ: Vec<String> =
            match (prev.meta.settings.as_object(), expect.settings.as_object()) {
                (Some(a), Some(b)) => a
                    .keys()
                    .chain(b.keys())
                    .filter(|k| a.get(*k) != b.get(*k))
                    .map(|k| format!("{k}: {} there, {} here", fmt(a.get(k)), fmt(b.get(k))))
                    .collect::<std::collections::BTreeSet<_>>()
                    .into_iter()
                    .collect(),
                _ => vec!["settings".into()],
            };
        return Err(fail(format!(
            "the --previous file was made with other settings ({})",
            differ.join("; ")
        )));
    }
    if prev.meta.tool.version != env!("CARGO_PKG_VERSION") {
        return Err(fail(format!(
            "the --previous file was made by prt {}, this is {}",
            prev.meta.tool.version,
            env!("CARGO_PKG_VERSION")
        )));
    }
    if prev.objects.len() != expect.names.len() {
        return Err(fail(format!(
            "the --previous file holds {} objects, the scene {}",
            prev.objects.len(),
            expect.names.len()
        )));
    }
    for (i, o) in prev.objects.iter().enumerate() {
        if o.name != expect.names[i]
            || o.geometry_hash != expect.hashes[i]
            || o.order != expect.orders[i]
        {
            return Err(fail(format!(
                "object {i} of the --previous file ({}, geometry {:#018x}, order {}) is not this scene's ({}, geometry {:#018x}, order {})",
                o.name, o.geometry_hash, o.order, expect.names[i], expect.hashes[i], expect.orders[i]
            )));
        }
        let levels = o
            .pass
            .as_ref()
            .map(|p| (p.levels.len(), p.partial.is_some()));
        if levels != Some((info.index as usize, true)) {
            return Err(fail(format!(
                "object {} of the --previous file lacks the bounce levels of pass {}",
                o.name, info.index
            )));
        }
    }
    if info.albedo != expect.albedo {
        return Err(fail(
            "the --previous file gathered bounces with other material albedos than this scene's",
        ));
    }
    if prev.environment.as_ref() != Some(expect.environment) {
        return Err(fail(
            "the --previous file was lit by another environment (its SH coefficients differ)",
        ));
    }
    check_hits(pass, expect, prev)
}

/// The `--hits` file: this shard's own pass-0 file, needed exactly by the passes that gather
/// at vertices.
fn check_hits(pass: &PassInput<'_>, expect: &Expect<'_>, prev: &Bake) -> Result<(), BakeError> {
    let Some(h) = pass.hits else {
        return if expect.gathers_at_vertices {
            Err(fail(format!(
                "pass {} gathers a bounce at this shard's vertices: give --hits, this shard's own pass-0 file (the merged file keeps only the hit counts)",
                pass.index
            )))
        } else {
            Ok(())
        };
    };
    if !expect.gathers_at_vertices {
        return Err(fail(format!(
            "pass {} gathers nothing at vertices: it takes no --hits file",
            pass.index
        )));
    }
    let shard = expect.shard.unwrap_or((0, 1));
    if h.meta.pass.as_ref().map(|p| (p.index, p.last)) != Some((0, expect.bounces)) {
        return Err(fail("the --hits file is not a pass-0 file of this bake"));
    }
    if (h.meta.shard.index, h.meta.shard.count) != shard {
        return Err(fail(format!(
            "the --hits file is shard {}/{}, this is shard {}/{}: each shard reads its own",
            h.meta.shard.index, h.meta.shard.count, shard.0, shard.1
        )));
    }
    if h.meta.settings != prev.meta.settings || h.meta.tool != prev.meta.tool {
        return Err(fail(
            "the --hits file was made with other settings than the --previous file",
        ));
    }
    for (i, (o, range)) in h.objects.iter().zip(&expect.ranges).enumerate() {
        let same = o.name == expect.names[i]
            && o.geometry_hash == expect.hashes[i]
            && (o.point_first, o.points_in_file) == *range
            && o.pass.as_ref().is_some_and(|p| p.records);
        if !same {
            return Err(fail(format!(
                "object {} of the --hits file does not hold this shard's points with their hits",
                o.name
            )));
        }
    }
    if h.objects.len() != expect.names.len() {
        return Err(fail("the --hits file holds other objects than the scene"));
    }
    Ok(())
}

fn fmt(v: Option<&serde_json::Value>) -> String {
    v.map_or("absent".into(), ToString::to_string)
}

/// What a pass `k ≥ 1` takes from the merged file of pass `k − 1`, for this shard.
pub(crate) struct Previous {
    /// Complete bounce levels `0 … k−1` of every object (all vertices).
    pub chain: Vec<MeshTransfer>,
    /// Per object: hits recorded by all its vertices (the object-wide count).
    pub object_hits: u64,
    /// This shard's vertices: hits, per vertex.
    pub hits: Vec<Vec<HitRecord>>,
    /// This shard's vertices: running totals (per-vertex bakes).
    pub totals: Vec<Vec<f64>>,
    /// This shard's vertices as pass 0 measured them (shadowed and visibility transfer as
    /// stored, f32 values widened exactly; the hit count is the recorded front-face hits).
    pub rows: Vec<DirectResult>,
}

/// Takes object `o`'s part of `prev` for points `first .. first + count`, and their hit
/// records from `hits` (this shard's pass-0 file; checked to hold exactly these points).
pub(crate) fn previous(
    prev: &Bake,
    hits_file: Option<&Bake>,
    o: usize,
    first: u64,
    count: u64,
) -> Previous {
    let obj = &prev.objects[o];
    let state = obj.pass.as_ref().expect("checked");
    let object_hits: u64 = state
        .hit_counts
        .iter()
        .flatten()
        .map(|&c| u64::from(c))
        .sum();
    let n2 = (obj.order * obj.order) as usize;
    let order = obj.order as usize;
    let (first, count) = (first as usize, count as usize);
    let mut chain: Vec<MeshTransfer> = state
        .levels
        .iter()
        .map(|l| MeshTransfer {
            order,
            data: l.clone(),
        })
        .collect();
    chain.push(MeshTransfer {
        order,
        data: state.partial.clone().expect("checked"),
    });
    let mut hits = Vec::with_capacity(count);
    let own = hits_file
        .and_then(|f| f.objects[o].pass.as_ref())
        .filter(|s| s.records);
    if let Some((own, counts)) = own.and_then(|s| Some(s).zip(s.hit_counts.as_ref())) {
        let mut start = 0usize;
        for &c in counts {
            let end = start + c as usize;
            hits.push(
                own.hits[start..end]
                    .iter()
                    .map(|h| HitRecord {
                        mesh: h.mesh,
                        tri: h.tri,
                        u: h.u,
                        v: h.v,
                    })
                    .collect(),
            );
            start = end;
        }
    } else {
        hits.resize(count, Vec::new());
    }
    let totals = state.totals.as_ref().map_or_else(Vec::new, |t| {
        t[first * 3 * n2..(first + count) * 3 * n2]
            .chunks_exact(3 * n2)
            .map(<[f64]>::to_vec)
            .collect()
    });
    let block = |kind: TransferKind| obj.blocks.iter().find(|b| b.kind == kind);
    let widen = |b: Option<&prt_bakefile::TransferBlock>, p: usize| {
        b.map(|b| {
            b.data[p * n2..(p + 1) * n2]
                .iter()
                .map(|&v| f64::from(v))
                .collect::<Vec<f64>>()
        })
    };
    let shadowed = block(TransferKind::ShadowedDiffuse);
    let visibility = block(TransferKind::Visibility);
    let rows = (first..first + count)
        .zip(&hits)
        .map(|(p, h)| DirectResult {
            shadowed: widen(shadowed, p).unwrap_or_default(),
            visibility: widen(visibility, p),
            hits: Vec::new(),
            hit_count: h.len() as u32,
            backface_hits: 0,
        })
        .collect();
    Previous {
        chain,
        object_hits,
        hits,
        totals,
        rows,
    }
}

/// The hits of some points as the file stores them.
pub(crate) fn file_hits(hits: &[&[HitRecord]]) -> (Vec<u32>, Vec<PassHit>) {
    let counts = hits.iter().map(|h| h.len() as u32).collect();
    let records = hits
        .iter()
        .flat_map(|h| h.iter())
        .map(|h| PassHit {
            mesh: h.mesh,
            tri: h.tri,
            u: h.u,
            v: h.v,
        })
        .collect();
    (counts, records)
}

/// The `pass` metadata of an intermediate file of pass `index`.
pub(crate) fn info(index: u32, last: u32, albedo: &[[f32; 3]]) -> PassInfo {
    PassInfo {
        index,
        last,
        albedo: albedo.to_vec(),
    }
}

/// What one distributed pass produced.
pub(crate) enum Outcome {
    /// Pass `k < last`: this shard's objects with their pass state, and the report rows.
    Intermediate(
        Vec<prt_bakefile::ObjectBake>,
        Vec<crate::report::ObjectReport>,
    ),
    /// The last pass: the bounce levels (`chain[level][object]`, complete; per-pixel bakes)
    /// and this shard's running totals (per-vertex bakes) for the final assembly.
    Final {
        chain: Vec<Vec<MeshTransfer>>,
        totals: Vec<Vec<Vec<f64>>>,
    },
}

/// The parts of the bake a distributed pass works with.
pub(crate) struct Step<'a> {
    pub scene: &'a prt_scene::Scene,
    pub plans: &'a [crate::plan::ObjectPlan],
    pub settings: &'a crate::BakeSettings,
    pub vertex_mode: bool,
    pub vertex_bounces: usize,
    pub gs: &'a crate::transfer::GatherScene<'a>,
    pub vertex_ranges: &'a [(u64, u64)],
    pub object_hits: &'a [u64],
}

/// One object's newest bounce level for this shard's vertices, with their running totals and
/// hit records.
struct ShardLevel {
    /// Level `k` of this shard's vertices (RGB, f32).
    level: Vec<f32>,
    /// Running totals per vertex (per-vertex bakes; empty otherwise).
    totals: Vec<Vec<f64>>,
    /// Hit records per vertex.
    hits: Vec<Vec<HitRecord>>,
}

/// The hit records and running totals of one object's shard vertices, from the previous file.
type Own = (Vec<Vec<HitRecord>>, Vec<Vec<f64>>);

/// The previous file's part split into the complete levels `0 … k−1` of every object, by level
/// (`levels[b][object]`), and each object's own hit records and running totals.
fn by_level(previous: Vec<Previous>, objects: usize) -> (Vec<Vec<MeshTransfer>>, Vec<Own>) {
    let mut levels: Vec<Vec<MeshTransfer>> = Vec::new();
    let mut own = Vec::with_capacity(previous.len());
    for (o, p) in previous.into_iter().enumerate() {
        for (b, level) in p.chain.into_iter().enumerate() {
            if levels.len() <= b {
                levels.push(Vec::with_capacity(objects));
            }
            debug_assert_eq!(levels[b].len(), o);
            levels[b].push(level);
        }
        own.push((p.hits, p.totals));
    }
    (levels, own)
}

impl Step<'_> {
    /// Runs pass `k` on this shard's vertices: `rows` are their direct results (traced now for
    /// pass 0, from the previous file otherwise), `previous` the previous file's part.
    pub(crate) fn run(
        &self,
        k: u32,
        rows: &[Vec<DirectResult>],
        previous: Vec<Previous>,
        bar: indicatif::ProgressBar,
    ) -> Result<Outcome, BakeError> {
        let last = self.settings.bounces;
        let k = k as usize;
        // Levels 0 … k−1 of every object, by level (moved out of the previous file's part).
        let (levels, mut own) = by_level(previous, self.plans.len());
        let vertex_pass = self.vertex_mode || k < last as usize;
        if k == last as usize && !self.vertex_mode {
            return Ok(Outcome::Final {
                chain: levels,
                totals: Vec::new(),
            });
        }
        let mut objects = Vec::with_capacity(self.plans.len());
        let mut reports = Vec::with_capacity(self.plans.len());
        let mut final_totals = Vec::with_capacity(self.plans.len());
        for o in 0..self.plans.len() {
            let shard = self.newest_level(k, o, &rows[o], &mut own, &levels, &bar);
            debug_assert!(vertex_pass);
            if k == last as usize {
                final_totals.push(shard.totals);
                continue;
            }
            let (object, report) = self.intermediate_object(k, o, &rows[o], &levels, shard);
            reports.push(report);
            objects.push(object);
        }
        bar.finish_and_clear();
        if k == last as usize {
            return Ok(Outcome::Final {
                chain: Vec::new(),
                totals: final_totals,
            });
        }
        Ok(Outcome::Intermediate(objects, reports))
    }

    /// Object `o`'s level `k` at this shard's vertices: in pass 0 the shadowed transfer of
    /// their direct results `rows_o`; later, gathered from level `k − 1` of `levels` through
    /// the hits in `own` (whose running totals it adds to, per vertex).
    fn newest_level(
        &self,
        k: usize,
        o: usize,
        rows_o: &[DirectResult],
        own: &mut [Own],
        levels: &[Vec<MeshTransfer>],
        bar: &indicatif::ProgressBar,
    ) -> ShardLevel {
        use rayon::prelude::*;
        let plan = &self.plans[o];
        if k == 0 {
            // Level 0 is the shadowed transfer, in all three channels (as unsharded).
            let level = rows_o
                .iter()
                .flat_map(|d| (0..3).flat_map(move |_| d.shadowed.iter().map(|v| *v as f32)))
                .collect();
            let totals = if self.vertex_mode {
                rows_o
                    .iter()
                    .map(|d| crate::transfer::level0_totals(&d.shadowed))
                    .collect()
            } else {
                Vec::new()
            };
            let hits = rows_o.iter().map(|d| d.hits.clone()).collect();
            return ShardLevel {
                level,
                totals,
                hits,
            };
        }
        let n2 = plan.order * plan.order;
        let (_, count) = self.vertex_ranges[o];
        let (hits, mut totals) = std::mem::take(&mut own[o]);
        let level = if self.object_hits[o] == 0 {
            vec![0.0; count as usize * 3 * n2]
        } else {
            let prev = &levels[k - 1];
            let per_point: Vec<Vec<f64>> = hits
                .par_iter()
                .with_min_len(64)
                .map(|h| {
                    bar.inc(1);
                    crate::transfer::gather(h, self.settings.rays, prev, self.gs, plan.order)
                })
                .collect();
            if self.vertex_mode {
                for (tot, g) in totals.iter_mut().zip(&per_point) {
                    tot.iter_mut().zip(g).for_each(|(t, v)| *t += v);
                }
            }
            per_point.iter().flatten().map(|v| *v as f32).collect()
        };
        ShardLevel {
            level,
            totals,
            hits,
        }
    }

    /// Object `o` of the intermediate file of pass `k`: this shard's direct transfer, the
    /// complete `levels` so far, its newest level, running totals and hits (records in pass 0,
    /// counts in every pass that still gathers at vertices), and its report row.
    fn intermediate_object(
        &self,
        k: usize,
        o: usize,
        rows_o: &[DirectResult],
        levels: &[Vec<MeshTransfer>],
        shard: ShardLevel,
    ) -> (prt_bakefile::ObjectBake, crate::report::ObjectReport) {
        let last = self.settings.bounces;
        let plan = &self.plans[o];
        let (first, count) = self.vertex_ranges[o];
        let mesh = &self.scene.meshes[plan.mesh];
        let blocks = intermediate_blocks(rows_o, self.vertex_mode && plan.needs_visibility);
        let hit_refs: Vec<&[HitRecord]> = shard.hits.iter().map(Vec::as_slice).collect();
        let record = self.vertex_bounces > k;
        // Pass 0 writes the shard's hit records (later passes read them from this file
        // with --hits); every pass writes the counts, which merge into the object-wide
        // figure the next pass needs.
        let (hit_counts, hit_records) = if record {
            let (c, r) = file_hits(&hit_refs);
            (Some(c), if k == 0 { r } else { Vec::new() })
        } else {
            (None, Vec::new())
        };
        let report = crate::report::ObjectReport {
            name: plan.name.clone(),
            order: plan.order,
            points: count,
            hit_fraction: hit_refs.iter().map(|h| h.len() as f64).sum::<f64>()
                / (count.max(1) as f64 * f64::from(self.settings.rays)),
            backface_fraction: 0.0,
            inside_fraction: 0.0,
            kinds: vec![format!("bounce level {k} (pass {k} of {})", last + 1)],
        };
        let object = prt_bakefile::ObjectBake {
            name: plan.name.clone(),
            geometry_hash: prt_scene::binding::geometry_hash(
                mesh.positions.as_slice(),
                &mesh.indices,
            ),
            point_count: mesh.positions.len() as u64,
            point_first: first,
            points_in_file: count,
            order: plan.order as u32,
            channels: 1,
            blocks,
            mesh: Some(prt_scene::binding::mesh_geometry(mesh)),
            coverage: None,
            material: Some(crate::material_binding(self.scene, plan.mesh)),
            pass: Some(prt_bakefile::PassState {
                levels: levels.iter().map(|l| l[o].data.clone()).collect(),
                partial: Some(shard.level),
                totals: self
                    .vertex_mode
                    .then(|| shard.totals.into_iter().flatten().collect()),
                hit_counts,
                records: record && k == 0,
                hits: hit_records,
            }),
        };
        (object, report)
    }
}

/// The direct transfer a final per-vertex pass needs for this shard's vertices (shadowed, and
/// visibility where traced), one channel, as the unsharded bake rounds it.
fn intermediate_blocks(
    rows: &[DirectResult],
    visibility: bool,
) -> Vec<prt_bakefile::TransferBlock> {
    let mut blocks = vec![prt_bakefile::TransferBlock {
        cpca: None,
        kind: TransferKind::ShadowedDiffuse,
        data: rows
            .iter()
            .flat_map(|d| d.shadowed.iter().map(|v| *v as f32))
            .collect(),
    }];
    if visibility {
        blocks.push(prt_bakefile::TransferBlock {
            cpca: None,
            kind: TransferKind::Visibility,
            data: rows
                .iter()
                .flat_map(|d| d.visibility.iter().flatten().map(|v| *v as f32))
                .collect(),
        });
    }
    blocks
}
