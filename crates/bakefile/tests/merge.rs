//! Sharded bakes: merged shards are bit-identical to the unsharded bake; bad shard sets are
//! refused.

mod common;

use common::*;
use prt_bakefile::*;

#[test]
fn test01_merged_shards_encode_bit_identically() {
    let bake = sample_bake();
    for scalar in [ScalarType::F32, ScalarType::F16] {
        let whole = encode(&bake, scalar).unwrap();
        for count in [1, 2, 3, 5, 40] {
            let shards = split(&bake, count).unwrap();
            assert_eq!(shards.len(), count as usize);
            // Through files, in reverse order, as a sharded bake would arrive.
            let mut read: Vec<Bake> = shards
                .iter()
                .map(|s| decode(&encode(s, scalar).unwrap()).unwrap())
                .collect();
            read.reverse();
            if count > 1 {
                assert_ne!(encode(&read[0], scalar).unwrap(), whole);
                assert_eq!(read[0].meta.shard.count, count);
            }
            let merged = merge(&read).unwrap();
            assert_eq!(
                encode(&merged, scalar).unwrap(),
                whole,
                "{count} shards, {scalar:?}"
            );
        }
    }
}

#[test]
fn test02_random_bakes_merge_back() {
    let mut r = rng(11);
    for case in 0..50 {
        let bake = random_bake(&mut r);
        let whole = encode(&bake, ScalarType::F32).unwrap();
        let shards = split(&bake, 1 + case % 4).unwrap();
        assert_eq!(
            encode(&merge(&shards).unwrap(), ScalarType::F32).unwrap(),
            whole,
            "case {case}"
        );
    }
}

fn merge_err(shards: &[Bake]) -> String {
    match merge(shards) {
        Err(BakeFileError::Merge(m)) => m,
        other => panic!("expected a merge error, got {other:?}"),
    }
}

#[test]
fn test03_incomplete_overlapping_or_mismatched_shards_are_refused() {
    let bake = sample_bake();
    let shards = split(&bake, 3).unwrap();
    assert!(merge_err(&[]).contains("no shards"));
    // Missing shard.
    assert!(merge_err(&shards[..2]).contains("2 shards given"));
    // The same shard twice.
    let twice = [shards[0].clone(), shards[1].clone(), shards[1].clone()];
    assert!(merge_err(&twice).contains("twice"));
    // Overlapping ranges: shard 1 claims one point more at its start.
    let mut overlap = shards.clone();
    for o in &mut overlap[1].objects {
        o.point_first -= 1;
        o.points_in_file += 1;
        let per = o.scalars_per_point() as usize;
        for b in &mut o.blocks {
            b.data.splice(0..0, std::iter::repeat_n(0.0, per));
        }
    }
    assert!(merge_err(&overlap).contains("in two shards"));
    // A gap: shard 2 misses its last point.
    let mut gap = shards.clone();
    for o in &mut gap[2].objects {
        o.points_in_file -= 1;
        let per = o.scalars_per_point() as usize;
        for b in &mut o.blocks {
            b.data.truncate(b.data.len() - per);
        }
    }
    assert!(merge_err(&gap).contains("cover"));
    // Different settings, seed, geometry, order.
    let mut other = shards.clone();
    other[1].meta.seed += 1;
    assert!(merge_err(&other).contains("metadata"));
    let mut other = shards.clone();
    other[2].meta.settings["rays"] = serde_json::json!(2048);
    assert!(merge_err(&other).contains("metadata"));
    let mut other = shards.clone();
    other[0].objects[1].geometry_hash ^= 1;
    other[0].objects[1].mesh = None;
    assert!(merge_err(&other).contains("differs"));
    // A mesh that differs (one vertex moved, hash kept consistent) is refused too.
    let mut other = shards.clone();
    let o = &mut other[1].objects[0];
    let m = o.mesh.as_mut().unwrap();
    m.positions[0][1] += 1.0;
    o.geometry_hash = geometry_hash(&m.positions, &m.triangles);
    assert!(merge_err(&other).contains("differs"));
    // The shard's mesh must hash to the object's geometry hash.
    let mut other = shards.clone();
    other[2].objects[0].mesh.as_mut().unwrap().positions[0][0] += 1.0;
    assert!(merge_err(&other).contains("mesh hashes to"));
    let mut other = shards.clone();
    other[0].environment = None;
    assert!(merge_err(&other).contains("environment"));
    // Shard counts that disagree.
    let mut other = shards.clone();
    other[2].meta.shard.count = 4;
    other[2].meta.shard.index = 3;
    assert!(!merge_err(&other).is_empty());
}

#[test]
fn test04_split_refuses_nonsense() {
    let bake = sample_bake();
    assert!(split(&bake, 0).is_err());
    let shards = split(&bake, 2).unwrap();
    assert!(split(&shards[0], 2).is_err());
    // A shard alone is a valid file.
    assert!(decode(&encode(&shards[1], ScalarType::F32).unwrap()).is_ok());
}

/// An intermediate file of a distributed bounced bake (SPEC §3.12): its pass state survives
/// encoding, splits by point and merges back to the same bytes; shards of different passes or
/// with different complete levels are refused.
#[test]
fn test05_pass_files_split_and_merge_back() {
    use rand::Rng;
    let mut r = rng(11);
    let mut bake = sample_bake();
    bake.glossy.clear();
    bake.meta.pass = Some(PassInfo {
        index: 1,
        last: 2,
        albedo: vec![[0.8, 0.6, 0.4], [0.5, 0.5, 0.5]],
    });
    for (oi, o) in bake.objects.iter_mut().enumerate() {
        let per = 3 * (o.order * o.order) as usize;
        let points = o.point_count as usize;
        let values = |r: &mut rand_pcg::Pcg64, n: usize| -> Vec<f32> {
            (0..n).map(|_| r.random_range(-1.0f32..1.0)).collect()
        };
        let hit_counts: Vec<u32> = (0..points).map(|_| r.random_range(0..5)).collect();
        let hits = (0..hit_counts.iter().sum::<u32>())
            .map(|_| PassHit {
                mesh: r.random_range(0..2),
                tri: r.random_range(0..3),
                u: r.random(),
                v: r.random(),
            })
            .collect();
        o.pass = Some(PassState {
            levels: vec![values(&mut r, points * per); oi + 1],
            partial: Some(values(&mut r, points * per)),
            totals: Some((0..points * per).map(|_| r.random::<f64>()).collect()),
            hit_counts: Some(hit_counts),
            records: true,
            hits,
        });
    }
    let bytes = encode(&bake, ScalarType::F32).unwrap();
    assert_eq!(decode(&bytes).unwrap(), bake);
    let shards = split(&bake, 3).unwrap();
    // A shard keeps its own points' hit records through encoding ...
    let shard_bytes = encode(&shards[1], ScalarType::F32).unwrap();
    assert_eq!(decode(&shard_bytes).unwrap(), shards[1]);
    assert!(shards[1].objects[1].pass.as_ref().unwrap().records);
    // ... and the merge keeps every point's state but only the counts of the hits: each shard
    // reads its own records from its own pass-0 file (SPEC §3.12).
    let merged = merge(&shards).unwrap();
    let mut expected = bake.clone();
    for o in &mut expected.objects {
        let p = o.pass.as_mut().unwrap();
        p.records = false;
        p.hits.clear();
    }
    assert_eq!(
        encode(&merged, ScalarType::F32).unwrap(),
        encode(&expected, ScalarType::F32).unwrap()
    );
    assert!(encode(&expected, ScalarType::F32).unwrap().len() < bytes.len());
    // Shards of different passes, or with different complete levels, do not merge.
    let mut other = shards.clone();
    other[1].meta.pass.as_mut().unwrap().index = 0;
    assert!(merge_err(&other).contains("metadata"));
    let mut other = shards.clone();
    other[2].objects[0].pass.as_mut().unwrap().levels[0][0] += 1.0;
    assert!(merge_err(&other).contains("differs"));
    // A hit count that does not add up is refused on encoding.
    let mut bad = bake.clone();
    bad.objects[0].pass.as_mut().unwrap().hits.pop();
    assert!(encode(&bad, ScalarType::F32).is_err());
    // A pass file's PASS sections are REQUIRED: a reader that does not know them must refuse
    // the file rather than take it for a bake.
    let secs = sections(&bytes);
    let pass = secs.iter().find(|s| &s.0 == b"PASS").unwrap();
    assert_eq!(
        u32::from_le_bytes(bytes[pass.3 + 4..pass.3 + 8].try_into().unwrap()) & 1,
        1
    );
}
