//! SPEC.md §4 rules 8–10 for the objects' geometry: each object's `MESH` (§3.10) and `CVRG`
//! (§3.11) sections, referenced by exactly their own object, and the coverage as the
//! object's mask (rule 10: no transfer where no sample hit).

use crate::error::{inconsistent, invalid, BakeFileError};
use crate::layout::{Tag, CVRG_HEADER, MESH_HEADER};
use crate::located::{Cpcas, ObjectInfo, PerObject};
use crate::model::{uncovered_nonzero, Coverage, MeshGeometry, ScalarType};
use crate::read_bytes::{rd_u32, rd_u64, Payloads};

/// Per object, its `MESH` and its `CVRG` (format 1.1), each read from the section the
/// object's record names; then every `MESH` and `CVRG` section of the file is some object's.
pub(crate) fn read_meshes_and_coverages(
    file: Payloads<'_, '_>,
    objects: &[ObjectInfo],
) -> Result<(PerObject<MeshGeometry>, PerObject<Coverage>), BakeFileError> {
    let mut meshes = Vec::with_capacity(objects.len());
    let mut coverages = Vec::with_capacity(objects.len());
    for (oi, o) in objects.iter().enumerate() {
        meshes.push(match object_section(file, oi, o.mesh_section, Tag::MESH)? {
            Some(p) => Some(read_mesh(p, oi)?),
            None => None,
        });
        coverages.push(
            match object_section(file, oi, o.coverage_section, Tag::CVRG)? {
                Some(p) => Some(read_coverage(p, oi)?),
                None => None,
            },
        );
    }
    for (tag, refs) in [
        (
            Tag::MESH,
            objects
                .iter()
                .filter_map(|o| o.mesh_section)
                .collect::<Vec<_>>(),
        ),
        (
            Tag::CVRG,
            objects.iter().filter_map(|o| o.coverage_section).collect(),
        ),
    ] {
        // Distinct objects cannot share a section (each checks the section's own object
        // index), so counting the references counts the sections used.
        let present = file.sections.iter().filter(|s| s.tag == tag).count();
        if present != refs.len() {
            return Err(inconsistent(
                format!("{tag} sections (referenced by objects / present)"),
                refs.len() as u64,
                present as u64,
            ));
        }
    }
    Ok((meshes, coverages))
}

/// The payload of section `index` that object `oi`'s record names as its `tag` section: a
/// section of that tag, of at least 16 bytes, whose object index is `oi`.
fn object_section<'a>(
    file: Payloads<'a, '_>,
    oi: usize,
    index: Option<u32>,
    tag: Tag,
) -> Result<Option<&'a [u8]>, BakeFileError> {
    let Some(i) = index else { return Ok(None) };
    let what = format!("object {oi} {tag} section");
    if file.sections.get(i as usize).is_none_or(|s| s.tag != tag) {
        return Err(invalid(what, format!("{i} is not a {tag} section")));
    }
    let p = file.get(i as usize);
    if p.len() < 16 || rd_u32(p, 0) as usize != oi {
        return Err(invalid(
            what,
            format!("section {i} does not belong to object {oi}"),
        ));
    }
    Ok(Some(p))
}

/// Reads a MESH payload (SPEC.md §3.10) whose object index was checked; the semantic rules
/// (vertex count, finite values, index range, hash) are `Bake::validate`'s.
fn read_mesh(p: &[u8], object: usize) -> Result<MeshGeometry, BakeFileError> {
    let (v, t) = (u64::from(rd_u32(p, 4)), u64::from(rd_u32(p, 8)));
    let expected = MESH_HEADER as u64 + 24 * v + 12 * t;
    if expected != p.len() as u64 {
        return Err(inconsistent(
            format!("object {object} MESH length (16 + 24 × vertices + 12 × triangles)"),
            expected,
            p.len() as u64,
        ));
    }
    let (v, t) = (v as usize, t as usize);
    let vec3 = |off: usize| -> [f32; 3] { [0, 4, 8].map(|k| f32::from_bits(rd_u32(p, off + k))) };
    let positions = (0..v).map(|i| vec3(MESH_HEADER + 12 * i)).collect();
    let normals = (0..v).map(|i| vec3(MESH_HEADER + 12 * (v + i))).collect();
    let triangles = (0..t)
        .map(|i| [0, 4, 8].map(|k| rd_u32(p, MESH_HEADER + 24 * v + 12 * i + k)))
        .collect();
    Ok(MeshGeometry {
        positions,
        normals,
        triangles,
    })
}

/// Reads a CVRG payload (SPEC.md §3.11) whose object index was checked.
fn read_coverage(p: &[u8], object: usize) -> Result<Coverage, BakeFileError> {
    let n = rd_u64(p, 8);
    let expected = n
        .checked_mul(4)
        .and_then(|b| b.checked_add(CVRG_HEADER as u64));
    if expected != Some(p.len() as u64) {
        return Err(inconsistent(
            format!("object {object} CVRG length (16 + 4 × points)"),
            expected.unwrap_or(u64::MAX),
            p.len() as u64,
        ));
    }
    Ok(Coverage {
        pixel_samples: rd_u32(p, 4),
        hits: p[CVRG_HEADER..]
            .chunks_exact(4)
            .map(|c| rd_u32(c, 0))
            .collect(),
    })
}

/// SPEC.md §4 rule 10, on the stored bits: where an object's coverage says no sample hit a
/// point, every `XFER` block of the object is zero (±0) there; compressed blocks are exempt
/// (§3.11).
pub(crate) fn check_coverage_masks(
    bytes: &[u8],
    scalar: ScalarType,
    objects: &[ObjectInfo],
    coverages: &[Option<Coverage>],
    cpcas: &Cpcas,
) -> Result<(), BakeFileError> {
    for (oi, (o, coverage)) in objects.iter().zip(coverages).enumerate() {
        let Some(c) = coverage else { continue };
        let per = usize::try_from(u64::from(o.channels) * u64::from(o.order).pow(2))
            .unwrap_or(usize::MAX);
        let size = scalar.size();
        let zero = |bi: usize, p: usize| {
            if cpcas.contains_key(&(oi, bi)) {
                // A compressed block only approximates the zeros (SPEC.md §3.11).
                return true;
            }
            let b = &o.blocks[bi];
            let data = &bytes[b.offset as usize..(b.offset + b.length) as usize];
            // Both storage types: zero is all bits clear but the sign.
            let at = p * per * size;
            data.get(at..at + per * size).is_some_and(|d| match scalar {
                ScalarType::F32 => d.chunks_exact(4).all(|v| rd_u32(v, 0) << 1 == 0),
                ScalarType::F16 => d.chunks_exact(2).all(|v| (v[0] | (v[1] & 0x7f)) == 0),
            })
        };
        if c.hits.len() as u64 == o.points_in_file {
            let found = uncovered_nonzero(o.point_first, o.blocks.len(), c, zero);
            if let Some((bi, p)) = found {
                return Err(invalid(
                    format!("object {oi} block {bi}"),
                    format!("transfer at point {p}, which its coverage says no sample hit"),
                ));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_mesh_payload_reads_back_and_its_length_is_its_counts() {
        let mut p = Vec::new();
        for v in [0u32, 2, 1, 0] {
            p.extend_from_slice(&v.to_le_bytes());
        }
        let floats = [
            0.0f32, 1.0, 2.0, 3.0, 4.0, 5.0, 0.0, 0.0, 1.0, 0.0, 1.0, 0.0,
        ];
        p.extend(floats.iter().flat_map(|f| f.to_le_bytes()));
        p.extend([1u32, 0, 1].iter().flat_map(|i| i.to_le_bytes()));
        let m = read_mesh(&p, 0).unwrap();
        assert_eq!(m.positions, [[0.0, 1.0, 2.0], [3.0, 4.0, 5.0]]);
        assert_eq!(m.normals, [[0.0, 0.0, 1.0], [0.0, 1.0, 0.0]]);
        assert_eq!(m.triangles, [[1, 0, 1]]);
        p.push(0);
        assert_eq!(
            read_mesh(&p, 3).unwrap_err().to_string(),
            "inconsistent counts: object 3 MESH length (16 + 24 × vertices + 12 × triangles): expected 76, found 77"
        );
    }

    #[test]
    fn a_coverage_payload_holds_one_count_per_point() {
        let mut p = Vec::new();
        p.extend_from_slice(&0u32.to_le_bytes());
        p.extend_from_slice(&4u32.to_le_bytes());
        p.extend_from_slice(&2u64.to_le_bytes());
        p.extend([3u32, 0].iter().flat_map(|h| h.to_le_bytes()));
        let c = read_coverage(&p, 0).unwrap();
        assert_eq!((c.pixel_samples, c.hits), (4, vec![3, 0]));
        p[8..16].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(read_coverage(&p, 0).is_err());
    }
}
