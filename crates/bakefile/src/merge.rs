//! Sharded bakes: splitting a bake into shards and merging shards back.

use crate::error::BakeFileError;
use crate::model::{
    Bake, BakeMeta, Coverage, ObjectBake, PassState, RayStats, ShardInfo, TransferBlock,
};

fn fail(msg: impl Into<String>) -> BakeFileError {
    BakeFileError::Merge(msg.into())
}

/// Merges the shards of one bake into the unsharded bake.
///
/// The shards may come in any order. They must all be valid, carry the same shard count with
/// each index exactly once, identical metadata apart from [`crate::ShardInfo`] (settings, seed,
/// tool, decisions, ...), identical objects (name, geometry hash, point count, order,
/// channels, block kinds) and identical global sections; for every object the shards' point
/// ranges must tile `0..point_count` without gap or overlap.
///
/// The result encodes to exactly the bytes of the same bake made without sharding.
///
/// # Errors
/// [`BakeFileError::Merge`] naming the first disagreement; validation errors of a shard.
pub fn merge(shards: &[Bake]) -> Result<Bake, BakeFileError> {
    let first = shards.first().ok_or_else(|| fail("no shards"))?;
    check_mergeable(shards)?;
    check_shard_indices(shards, first.meta.shard.count)?;
    let mut meta = shared_meta(shards, first)?;
    let objects = first
        .objects
        .iter()
        .enumerate()
        .map(|(oi, o0)| merge_object(shards, oi, o0))
        .collect::<Result<Vec<_>, _>>()?;
    meta.ray_stats = merged_ray_stats(shards, first)?;
    let merged = Bake {
        reflectance: None,
        meta,
        objects,
        environment: first.environment.clone(),
        brdfs: first.brdfs.clone(),
        glossy: first.glossy.clone(),
    };
    merged.validate()?;
    Ok(merged)
}

/// Shards that can be merged: no reflectance field, no compressed block, each valid.
fn check_mergeable(shards: &[Bake]) -> Result<(), BakeFileError> {
    if shards.iter().any(|s| s.reflectance.is_some()) {
        return Err(fail(
            "a reflectance field (prt reflectance) is made whole, not in shards",
        ));
    }
    if shards.iter().any(|s| {
        s.objects
            .iter()
            .any(|o| o.blocks.iter().any(|b| b.cpca.is_some()))
    }) {
        return Err(fail(
            "a shard holds compressed (clustered PCA) blocks: merge the shards first, then compress",
        ));
    }
    for (i, s) in shards.iter().enumerate() {
        s.validate()
            .map_err(|e| fail(format!("shard at position {i} is invalid: {e}")))?;
    }
    Ok(())
}

/// `count` shards, all saying there are `count`, each index once.
fn check_shard_indices(shards: &[Bake], count: u32) -> Result<(), BakeFileError> {
    if shards.len() as u64 != u64::from(count) {
        return Err(fail(format!(
            "{} shards given, the shards say there are {count}",
            shards.len()
        )));
    }
    let mut seen = vec![false; shards.len()];
    for s in shards {
        if s.meta.shard.count != count {
            return Err(fail("shards disagree on the shard count"));
        }
        let slot = &mut seen[s.meta.shard.index as usize];
        if *slot {
            return Err(fail(format!(
                "shard index {} given twice",
                s.meta.shard.index
            )));
        }
        *slot = true;
    }
    Ok(())
}

/// The metadata all shards share (all but the shard and the ray statistics, which must be
/// the same in every shard), once every shard has the same global sections and object count.
fn shared_meta(shards: &[Bake], first: &Bake) -> Result<BakeMeta, BakeFileError> {
    let mut meta = first.meta.clone();
    meta.shard = ShardInfo::default();
    meta.ray_stats.clear();
    for s in shards {
        let mut m = s.meta.clone();
        m.shard = ShardInfo::default();
        m.ray_stats.clear();
        if m != meta {
            return Err(fail(format!(
                "shard {} has different metadata (settings, seed, tool, decisions, ...)",
                s.meta.shard.index
            )));
        }
        if s.environment != first.environment || s.brdfs != first.brdfs || s.glossy != first.glossy
        {
            return Err(fail(format!(
                "shard {} has different environment or BRDF sections",
                s.meta.shard.index
            )));
        }
        if s.objects.len() != first.objects.len() {
            return Err(fail(format!(
                "shard {} has a different object count",
                s.meta.shard.index
            )));
        }
    }
    Ok(meta)
}

/// Object `oi` (`o0` in the first shard) made whole: the same object in every shard, their
/// point ranges tiling the object; transfer, coverage and pass state concatenated in point
/// order.
fn merge_object(shards: &[Bake], oi: usize, o0: &ObjectBake) -> Result<ObjectBake, BakeFileError> {
    let mut parts: Vec<&ObjectBake> = Vec::with_capacity(shards.len());
    for s in shards {
        let o = &s.objects[oi];
        let same = o.name == o0.name
            && o.geometry_hash == o0.geometry_hash
            && o.point_count == o0.point_count
            && o.order == o0.order
            && o.channels == o0.channels
            && o.blocks.len() == o0.blocks.len()
            && o.blocks
                .iter()
                .zip(&o0.blocks)
                .all(|(a, b)| a.kind == b.kind)
            && o.mesh == o0.mesh
            && o.coverage.as_ref().map(|c| c.pixel_samples)
                == o0.coverage.as_ref().map(|c| c.pixel_samples)
            && o.pass.as_ref().map(pass_shape) == o0.pass.as_ref().map(pass_shape);
        if !same {
            return Err(fail(format!(
                "object {oi} ({:?}) differs between shards (name, geometry, mesh, counts, order, channels, kinds or coverage)",
                o0.name
            )));
        }
        parts.push(o);
    }
    parts.sort_by_key(|o| (o.point_first, o.points_in_file));
    check_tiling(o0, &parts)?;
    let blocks = o0
        .blocks
        .iter()
        .enumerate()
        .map(|(bi, b)| TransferBlock {
            cpca: None,
            kind: b.kind,
            data: parts
                .iter()
                .flat_map(|p| p.blocks[bi].data.iter().copied())
                .collect(),
        })
        .collect();
    // Every shard carries the whole mesh (checked equal above); coverage is per point,
    // concatenated like the transfer.
    let coverage = o0.coverage.as_ref().map(|c| Coverage {
        pixel_samples: c.pixel_samples,
        hits: parts
            .iter()
            .flat_map(|p| p.coverage.iter().flat_map(|c| c.hits.iter().copied()))
            .collect(),
    });
    Ok(ObjectBake {
        name: o0.name.clone(),
        geometry_hash: o0.geometry_hash,
        point_count: o0.point_count,
        point_first: 0,
        points_in_file: o0.point_count,
        order: o0.order,
        channels: o0.channels,
        blocks,
        mesh: o0.mesh.clone(),
        coverage,
        material: o0.material.clone(),
        pass: o0.pass.as_ref().map(|p0| merge_pass(p0, &parts)),
    })
}

/// The shards' parts of object `o0`, sorted by first point, cover its points without gap or
/// overlap.
fn check_tiling(o0: &ObjectBake, parts: &[&ObjectBake]) -> Result<(), BakeFileError> {
    let mut next = 0u64;
    for p in parts {
        if p.point_first != next {
            return Err(fail(format!(
                "object {:?}: points {}..{} are {}",
                o0.name,
                next.min(p.point_first),
                next.max(p.point_first),
                if p.point_first > next {
                    "in no shard"
                } else {
                    "in two shards"
                }
            )));
        }
        next += p.points_in_file;
    }
    if next != o0.point_count {
        return Err(fail(format!(
            "object {:?}: shards cover {next} of {} points",
            o0.name, o0.point_count
        )));
    }
    Ok(())
}

/// The merged ray statistics: counts over each shard's points, they add up (all shards or
/// none carry them, for every object); empty when none does.
fn merged_ray_stats(shards: &[Bake], first: &Bake) -> Result<Vec<RayStats>, BakeFileError> {
    let with_stats = shards
        .iter()
        .filter(|s| !s.meta.ray_stats.is_empty())
        .count();
    if with_stats != 0 && with_stats != shards.len() {
        return Err(fail("some shards carry ray statistics and some do not"));
    }
    if with_stats == 0 {
        return Ok(Vec::new());
    }
    let mut total: Vec<RayStats> = first
        .meta
        .ray_stats
        .iter()
        .map(|r| RayStats {
            object: r.object.clone(),
            ..RayStats::default()
        })
        .collect();
    for s in shards {
        for (t, r) in total.iter_mut().zip(&s.meta.ray_stats) {
            t.add(r);
        }
    }
    Ok(total)
}

/// Splits an unsharded bake into `shard_count` shards: shard `k` holds points
/// `⌊k·N/count⌋ .. ⌊(k+1)·N/count⌋` of every object (N its point count). The inverse of
/// [`merge`]; useful to test a sharded baker against an unsharded one.
///
/// # Errors
/// [`BakeFileError::InvalidBake`] if `bake` is invalid, already a shard, or `shard_count` is 0.
pub fn split(bake: &Bake, shard_count: u32) -> Result<Vec<Bake>, BakeFileError> {
    bake.validate()?;
    if bake.reflectance.is_some() {
        return Err(BakeFileError::InvalidBake(
            "a reflectance field (prt reflectance) cannot be split".into(),
        ));
    }
    if bake
        .objects
        .iter()
        .any(|o| o.blocks.iter().any(|b| b.cpca.is_some()))
    {
        return Err(BakeFileError::InvalidBake(
            "a compressed (clustered PCA) bake cannot be split".into(),
        ));
    }
    if shard_count == 0 || bake.meta.shard.count != 1 {
        return Err(BakeFileError::InvalidBake(
            "split needs an unsharded bake and at least one shard".into(),
        ));
    }
    let count = u128::from(shard_count);
    Ok((0..shard_count)
        .map(|k| {
            let mut meta = bake.meta.clone();
            meta.shard = ShardInfo {
                index: k,
                count: shard_count,
            };
            // The counts cannot be split by point: shard 0 keeps them, the others count 0, so
            // merging adds them back exactly.
            if k > 0 {
                for r in &mut meta.ray_stats {
                    *r = RayStats {
                        object: r.object.clone(),
                        ..RayStats::default()
                    };
                }
            }
            let objects = bake
                .objects
                .iter()
                .map(|o| {
                    let n = u128::from(o.point_count);
                    let start = (u128::from(k) * n / count) as u64;
                    let end = ((u128::from(k) + 1) * n / count) as u64;
                    let per = o.scalars_per_point() as usize;
                    ObjectBake {
                        point_first: start,
                        points_in_file: end - start,
                        blocks: o
                            .blocks
                            .iter()
                            .map(|b| TransferBlock {
                                cpca: None,
                                kind: b.kind,
                                data: b.data[start as usize * per..end as usize * per].to_vec(),
                            })
                            .collect(),
                        coverage: o.coverage.as_ref().map(|c| Coverage {
                            pixel_samples: c.pixel_samples,
                            hits: c.hits[start as usize..end as usize].to_vec(),
                        }),
                        pass: o.pass.as_ref().map(|p| {
                            split_pass(
                                p,
                                start as usize,
                                end as usize,
                                3 * (o.order * o.order) as usize,
                            )
                        }),
                        ..o.clone_without_data()
                    }
                })
                .collect();
            Bake {
                reflectance: None,
                meta,
                objects,
                environment: bake.environment.clone(),
                brdfs: bake.brdfs.clone(),
                glossy: bake.glossy.clone(),
            }
        })
        .collect())
}

impl ObjectBake {
    fn clone_without_data(&self) -> ObjectBake {
        ObjectBake {
            name: self.name.clone(),
            geometry_hash: self.geometry_hash,
            point_count: self.point_count,
            point_first: self.point_first,
            points_in_file: self.points_in_file,
            order: self.order,
            channels: self.channels,
            blocks: Vec::new(),
            mesh: self.mesh.clone(),
            coverage: None,
            material: self.material.clone(),
            pass: None,
        }
    }
}

/// What must agree between shards' pass states: the complete levels themselves and which
/// per-point arrays are present.
fn pass_shape(p: &PassState) -> (&[Vec<f32>], bool, bool, bool) {
    (
        &p.levels,
        p.partial.is_some(),
        p.totals.is_some(),
        p.hit_counts.is_some(),
    )
}

/// Joins the per-point arrays of the shards' pass states (in point order; the complete levels
/// were checked equal).
fn merge_pass(p0: &PassState, parts: &[&ObjectBake]) -> PassState {
    let states: Vec<&PassState> = parts.iter().filter_map(|p| p.pass.as_ref()).collect();
    let join_f32 = |get: fn(&PassState) -> Option<&Vec<f32>>| {
        get(p0).map(|_| {
            states
                .iter()
                .filter_map(|s| get(s))
                .flatten()
                .copied()
                .collect()
        })
    };
    PassState {
        levels: p0.levels.clone(),
        partial: join_f32(|s| s.partial.as_ref()),
        totals: p0.totals.as_ref().map(|_| {
            states
                .iter()
                .filter_map(|s| s.totals.as_ref())
                .flatten()
                .copied()
                .collect()
        }),
        hit_counts: p0.hit_counts.as_ref().map(|_| {
            states
                .iter()
                .filter_map(|s| s.hit_counts.as_ref())
                .flatten()
                .copied()
                .collect()
        }),
        // Each shard keeps its own hit records in its pass-0 file (later passes read them
        // with `--hits`); the merged file keeps only the counts (SPEC §3.12).
        records: false,
        hits: Vec::new(),
    }
}

/// Points `start..end` of a pass state (`per` values per point).
fn split_pass(p: &PassState, start: usize, end: usize, per: usize) -> PassState {
    let (first_hit, last_hit) = match &p.hit_counts {
        Some(c) => {
            let before: u64 = c[..start].iter().map(|&n| u64::from(n)).sum();
            let within: u64 = c[start..end].iter().map(|&n| u64::from(n)).sum();
            (before as usize, (before + within) as usize)
        }
        None => (0, 0),
    };
    PassState {
        levels: p.levels.clone(),
        partial: p
            .partial
            .as_ref()
            .map(|v| v[start * per..end * per].to_vec()),
        totals: p
            .totals
            .as_ref()
            .map(|v| v[start * per..end * per].to_vec()),
        hit_counts: p.hit_counts.as_ref().map(|c| c[start..end].to_vec()),
        records: p.records,
        hits: if p.records {
            p.hits[first_hit..last_hit].to_vec()
        } else {
            Vec::new()
        },
    }
}
