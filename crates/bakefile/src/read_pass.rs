//! SPEC.md §4 rules 8–10 for `PASS` sections (§3.12), the state between the passes of a
//! distributed bake: one per object at most, found by the object index in its header; its
//! length the sum of its parts, its header agreeing with the object, its numbers finite.

use crate::error::{inconsistent, invalid, BakeFileError};
use crate::layout::{Tag, PASS_HEADER};
use crate::located::ObjectInfo;
use crate::model::{check_finite32, check_finite64, PassHit, PassState};
use crate::read_bytes::{rd_f64, rd_u32, rd_u64, section_name, Payloads};

/// Per object, its `PASS` section's state, if it has one; every `PASS` section names an
/// object, and no object has two.
pub(crate) fn read_passes(
    file: Payloads<'_, '_>,
    objects: &[ObjectInfo],
) -> Result<Vec<Option<PassState>>, BakeFileError> {
    let mut passes: Vec<Option<PassState>> = vec![None; objects.len()];
    for (i, s) in file.sections.iter().enumerate() {
        if s.tag != Tag::PASS {
            continue;
        }
        let p = file.get(i);
        let name = section_name(s.tag, i);
        if p.len() < PASS_HEADER {
            return Err(inconsistent(
                format!("{name} length"),
                PASS_HEADER as u64,
                p.len() as u64,
            ));
        }
        let oi = rd_u32(p, 0) as usize;
        let o = objects
            .get(oi)
            .ok_or_else(|| invalid(name.clone(), format!("object {oi} does not exist")))?;
        if passes[oi].is_some() {
            return Err(invalid(
                name,
                format!("a second PASS section of object {oi}"),
            ));
        }
        passes[oi] = Some(read_pass(p, o, &name)?);
    }
    Ok(passes)
}

/// The `flags` bits of a PASS header (SPEC.md §3.12).
const PARTIAL: u32 = 1;
const TOTALS: u32 = 2;
const HIT_COUNTS: u32 = 4;
const HIT_RECORDS: u32 = 8;

/// Reads a PASS payload (SPEC.md §3.12) of object `o`: every count is checked against the
/// payload's length before anything is allocated.
fn read_pass(p: &[u8], o: &ObjectInfo, name: &str) -> Result<PassState, BakeFileError> {
    let (levels, order, flags) = (u64::from(rd_u32(p, 4)), rd_u32(p, 8), rd_u32(p, 12));
    let (vertices, points, hits) = (rd_u64(p, 16), rd_u64(p, 24), rd_u64(p, 32));
    check_pass_header(o, name, flags, order, vertices, points)?;
    let per = 3 * u64::from(order) * u64::from(order);
    let (has_partial, has_totals, has_hits) = (
        flags & PARTIAL != 0,
        flags & TOTALS != 0,
        flags & HIT_COUNTS != 0,
    );
    // Lengths in u128: no product of u64 counts can overflow it.
    let n = |count: u64, size: u64| u128::from(count) * u128::from(per) * u128::from(size);
    let totals_len = if has_totals { n(points, 8) } else { 0 };
    let levels_len = u128::from(levels) * n(vertices, 4);
    let partial_len = if has_partial { n(points, 4) } else { 0 };
    let counts_len = if has_hits { u128::from(points) * 4 } else { 0 };
    let expected = PASS_HEADER as u128
        + totals_len
        + levels_len
        + partial_len
        + counts_len
        + u128::from(hits) * 16;
    if expected != p.len() as u128 {
        return Err(inconsistent(
            format!("{name} length"),
            u64::try_from(expected).unwrap_or(u64::MAX),
            p.len() as u64,
        ));
    }
    let mut at = PASS_HEADER;
    let mut take = |len: u128| {
        let start = at;
        at += len as usize;
        &p[start..at]
    };
    let f32s = |b: &[u8]| -> Vec<f32> {
        b.chunks_exact(4)
            .map(|c| f32::from_bits(rd_u32(c, 0)))
            .collect()
    };
    let totals: Option<Vec<f64>> = has_totals.then(|| {
        take(totals_len)
            .chunks_exact(8)
            .map(|c| rd_f64(c, 0))
            .collect()
    });
    let level_len = n(vertices, 4);
    let levels: Vec<Vec<f32>> = (0..levels).map(|_| f32s(take(level_len))).collect();
    let partial = has_partial.then(|| f32s(take(partial_len)));
    let hit_counts = has_hits.then(|| {
        take(counts_len)
            .chunks_exact(4)
            .map(|c| rd_u32(c, 0))
            .collect()
    });
    let hits: Vec<PassHit> = take(u128::from(hits) * 16)
        .chunks_exact(16)
        .map(|c| PassHit {
            mesh: rd_u32(c, 0),
            tri: rd_u32(c, 4),
            u: f32::from_bits(rd_u32(c, 8)),
            v: f32::from_bits(rd_u32(c, 12)),
        })
        .collect();
    if flags & HIT_RECORDS == 0 && !hits.is_empty() {
        return Err(invalid(
            format!("{name} flags"),
            "hit records without the records flag (bit 3)",
        ));
    }
    let state = PassState {
        levels,
        partial,
        totals,
        hit_counts,
        records: flags & HIT_RECORDS != 0,
        hits,
    };
    check_pass_finite(&state, name)?;
    Ok(state)
}

/// A PASS header's flags are known, and its order, vertex count and points are the object's.
fn check_pass_header(
    o: &ObjectInfo,
    name: &str,
    flags: u32,
    order: u32,
    vertices: u64,
    points: u64,
) -> Result<(), BakeFileError> {
    if flags & !15 != 0 {
        return Err(invalid(
            format!("{name} flags"),
            format!("unknown bits {flags:#x}"),
        ));
    }
    let agree_with = [
        ("order", u64::from(order), u64::from(o.order)),
        ("vertex count", vertices, o.point_count),
        ("points", points, o.points_in_file),
    ];
    for (what, found, expected) in agree_with {
        if found != expected {
            return Err(inconsistent(format!("{name} {what}"), expected, found));
        }
    }
    Ok(())
}

/// Every number finite (SPEC.md §4 rule 10): totals, levels, the partial level, hits.
fn check_pass_finite(state: &PassState, name: &str) -> Result<(), BakeFileError> {
    if let Some(t) = &state.totals {
        check_finite64(&format!("{name} totals"), t)?;
    }
    for l in state.levels.iter().chain(&state.partial) {
        check_finite32(&format!("{name} levels"), l)?;
    }
    if let Some(h) = state
        .hits
        .iter()
        .position(|h| !(h.u.is_finite() && h.v.is_finite()))
    {
        return Err(BakeFileError::NonFinite {
            section: format!("{name} hits"),
            index: h as u64,
        });
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn object(order: u32, points: u64) -> ObjectInfo {
        ObjectInfo {
            name: "o".into(),
            geometry_hash: 0,
            point_count: points,
            point_first: 0,
            points_in_file: points,
            order,
            channels: 1,
            blocks: Vec::new(),
            mesh_section: None,
            coverage_section: None,
        }
    }

    /// A PASS payload of order 1 over `points` points: one level, the given flags, totals and
    /// partial level when flagged, one hit count per point and `hits` records.
    fn pass(points: u64, flags: u32, hits: &[(u32, u32, f32, f32)]) -> Vec<u8> {
        let mut p = Vec::new();
        for v in [0u32, 1, 1, flags] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        for v in [points, points, hits.len() as u64, 0] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        let per = 3 * points as usize;
        if flags & TOTALS != 0 {
            (0..per).for_each(|i| p.extend_from_slice(&(i as f64).to_le_bytes()));
        }
        (0..per).for_each(|i| p.extend_from_slice(&(i as f32).to_le_bytes()));
        if flags & PARTIAL != 0 {
            (0..per).for_each(|i| p.extend_from_slice(&(-(i as f32)).to_le_bytes()));
        }
        if flags & HIT_COUNTS != 0 {
            (0..points).for_each(|i| {
                let n = if i == 0 { hits.len() as u32 } else { 0 };
                p.extend_from_slice(&n.to_le_bytes());
            });
        }
        for &(mesh, tri, u, v) in hits {
            for w in [mesh, tri, u.to_bits(), v.to_bits()] {
                p.extend_from_slice(&w.to_le_bytes());
            }
        }
        p
    }

    #[test]
    fn a_pass_payload_reads_back_in_the_order_of_its_parts() {
        let s = read_pass(&pass(2, 15, &[(1, 7, 0.25, 0.5)]), &object(1, 2), "PASS#9").unwrap();
        assert_eq!(s.totals.unwrap(), [0.0, 1.0, 2.0, 3.0, 4.0, 5.0]);
        assert_eq!(s.levels, [vec![0.0, 1.0, 2.0, 3.0, 4.0, 5.0]]);
        assert_eq!(s.partial.unwrap()[5], -5.0);
        assert_eq!(s.hit_counts.unwrap(), [1, 0]);
        assert!(s.records);
        assert_eq!((s.hits[0].mesh, s.hits[0].tri, s.hits[0].v), (1, 7, 0.5));
    }

    #[test]
    fn a_pass_payload_is_refused_in_the_order_of_its_checks() {
        let o = object(1, 2);
        let err = |p: &[u8]| read_pass(p, &o, "PASS#9").unwrap_err().to_string();
        assert_eq!(
            err(&pass(2, 16, &[])),
            "invalid PASS#9 flags: unknown bits 0x10"
        );
        assert_eq!(
            err(&pass(3, 0, &[])),
            "inconsistent counts: PASS#9 vertex count: expected 2, found 3"
        );
        let mut long = pass(2, 0, &[]);
        long.push(0);
        assert!(err(&long).starts_with("inconsistent counts: PASS#9 length"));
        assert_eq!(
            err(&pass(2, HIT_COUNTS, &[(0, 0, 0.0, 0.0)])),
            "invalid PASS#9 flags: hit records without the records flag (bit 3)"
        );
        assert_eq!(
            err(&pass(2, 15, &[(0, 0, 0.0, f32::NAN)])),
            "non-finite value in PASS#9 hits at index 0"
        );
    }
}
