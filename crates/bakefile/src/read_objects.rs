//! SPEC.md §4 rules 8–10 for the bake's info and its objects: `BINF` (§3.1), the `OBJT`
//! (§3.3) and `BLKT` (§3.4) tables, object by object, block by block, with each block's
//! `XFER` (§3.5) length and finiteness or `CPCA` (§3.13) header and length as it comes.

use std::collections::BTreeSet;

use crate::error::{inconsistent, invalid, BakeFileError};
use crate::layout::{
    Tag, BINF_SIZE, BLKT_RECORD, CPCA_HEADER, NO_SECTION, OBJT_RECORD_V10, SCALAR_CPCA,
    TABLE_HEADER_SIZE,
};
use crate::located::{BakeInfo, BlockInfo, Cpcas, ObjectInfo, SectionEntry};
use crate::model::{Cpca, SampleKind, ScalarType, ShardInfo, TransferKind};
use crate::read_bytes::{rd_f64, rd_u32, rd_u64, section_name, string, table, Payloads};

/// Reads the `BINF` section (SPEC.md §3.1): at least 40 bytes, a known sample kind.
pub(crate) fn read_binf(binf: &[u8]) -> Result<BakeInfo, BakeFileError> {
    if binf.len() < BINF_SIZE {
        return Err(inconsistent(
            "BINF length",
            BINF_SIZE as u64,
            binf.len() as u64,
        ));
    }
    Ok(BakeInfo {
        sample: sample_kind(rd_u32(binf, 0), rd_u32(binf, 8), rd_u32(binf, 12))?,
        bounces: rd_u32(binf, 4),
        rays_per_point: rd_u32(binf, 16),
        shard: ShardInfo {
            index: rd_u32(binf, 20),
            count: rd_u32(binf, 24),
        },
        seed: rd_u64(binf, 32),
    })
}

/// `BINF.sample_kind` with its image size (SPEC.md §3.1).
fn sample_kind(code: u32, width: u32, height: u32) -> Result<SampleKind, BakeFileError> {
    match (code, width, height) {
        (1, 0, 0) => Ok(SampleKind::Vertex),
        (2, w, h) if w > 0 && h > 0 => Ok(SampleKind::Pixel {
            width: w,
            height: h,
        }),
        (3, w, h) if w > 0 && h > 0 => Ok(SampleKind::Texel {
            width: w,
            height: h,
        }),
        _ => Err(invalid(
            "BINF sample kind",
            format!("code {code} with image {width}×{height}"),
        )),
    }
}

/// Reads the objects of `OBJT` and their blocks of `BLKT` (SPEC.md §3.3, §3.4): each
/// object's record, its run of blocks (which must continue where the previous object's
/// ended), each block with its `XFER` or `CPCA` section; then the runs cover `BLKT` and every
/// `XFER` and `CPCA` section is some block's.
pub(crate) fn read_objects(
    file: Payloads<'_, '_>,
    strs: &[u8],
    objt: &[u8],
    blkt: &[u8],
    scalar: ScalarType,
) -> Result<(Vec<ObjectInfo>, Cpcas), BakeFileError> {
    let (object_count, orec) = table(objt, "OBJT", OBJT_RECORD_V10)?;
    let (block_count, brec) = table(blkt, "BLKT", BLKT_RECORD)?;
    let mut blocks = Blocks {
        file,
        blkt,
        record_size: brec,
        scalar,
        used_sections: BTreeSet::new(),
        cpcas: Cpcas::new(),
    };
    let mut objects = Vec::with_capacity(object_count);
    let mut next_block = 0u64;
    for oi in 0..object_count {
        let r = &objt[TABLE_HEADER_SIZE + oi * orec..][..orec];
        let mut o = read_object_record(r, strs, oi)?;
        let first_block = u64::from(rd_u32(r, 48));
        let n_blocks = u64::from(rd_u32(r, 52));
        if first_block != next_block {
            return Err(inconsistent(
                format!("object {oi} first block"),
                next_block,
                first_block,
            ));
        }
        next_block += n_blocks;
        if next_block > block_count as u64 {
            return Err(inconsistent(
                format!("blocks of objects 0..={oi}"),
                block_count as u64,
                next_block,
            ));
        }
        if o.order == 0 || o.order > u32::from(u16::MAX) || !(o.channels == 1 || o.channels == 3) {
            return Err(invalid(
                format!("object {oi}"),
                format!("order {} / channels {}", o.order, o.channels),
            ));
        }
        for bi in first_block..next_block {
            blocks.read(bi, oi, &mut o)?;
        }
        objects.push(o);
    }
    if next_block != block_count as u64 {
        return Err(inconsistent(
            "blocks referenced by objects",
            block_count as u64,
            next_block,
        ));
    }
    let xfer_count = file
        .sections
        .iter()
        .filter(|s| s.tag == Tag::XFER || s.tag == Tag::CPCA)
        .count();
    if xfer_count != blocks.used_sections.len() {
        return Err(inconsistent(
            "XFER sections",
            blocks.used_sections.len() as u64,
            xfer_count as u64,
        ));
    }
    Ok((objects, blocks.cpcas))
}

/// Object `oi`'s `OBJT` record `r` (SPEC.md §3.3), its name read from `strs`, without its
/// blocks yet. Records of 64 bytes (1.1) name the object's MESH and CVRG sections.
fn read_object_record(r: &[u8], strs: &[u8], oi: usize) -> Result<ObjectInfo, BakeFileError> {
    let name = string(
        strs,
        rd_u32(r, 0),
        rd_u32(r, 4),
        &format!("object {oi} name"),
    )?;
    let with_sections = r.len() >= 64;
    Ok(ObjectInfo {
        name,
        geometry_hash: rd_u64(r, 8),
        point_count: rd_u64(r, 16),
        point_first: rd_u64(r, 24),
        points_in_file: rd_u64(r, 32),
        order: rd_u32(r, 40),
        channels: rd_u32(r, 44),
        blocks: Vec::new(),
        mesh_section: with_sections
            .then(|| rd_u32(r, 56))
            .filter(|&i| i != NO_SECTION),
        coverage_section: with_sections
            .then(|| rd_u32(r, 60))
            .filter(|&i| i != NO_SECTION),
    })
}

/// The `BLKT` table being read, and what its blocks have claimed so far.
struct Blocks<'a, 's, 'b> {
    file: Payloads<'a, 's>,
    blkt: &'b [u8],
    record_size: usize,
    scalar: ScalarType,
    /// The `XFER` and `CPCA` sections claimed by a block.
    used_sections: BTreeSet<u32>,
    cpcas: Cpcas,
}

impl<'s> Blocks<'_, 's, '_> {
    /// Reads block `bi` (SPEC.md §3.4) of object `oi` and appends it to `o`'s blocks: its
    /// fields agree with the object's, and its section is checked (§3.5 or §3.13).
    fn read(&mut self, bi: u64, oi: usize, o: &mut ObjectInfo) -> Result<(), BakeFileError> {
        let r =
            &self.blkt[TABLE_HEADER_SIZE + bi as usize * self.record_size..][..self.record_size];
        let what = format!("block {bi}");
        let kind = TransferKind::from_code(rd_u32(r, 4), rd_u32(r, 8)).ok_or_else(|| {
            invalid(
                format!("{what} kind"),
                format!("code {} with {} bounces", rd_u32(r, 4), rd_u32(r, 8)),
            )
        })?;
        // A block stored as clustered PCA (SPEC.md §3.13) says so in its scalar type.
        let compressed = rd_u32(r, 20) == SCALAR_CPCA;
        let stored = if compressed {
            SCALAR_CPCA
        } else {
            self.scalar.code()
        };
        let pairs = [
            ("object index", u64::from(rd_u32(r, 0)), oi as u64),
            ("channels", rd_u32(r, 12).into(), o.channels.into()),
            ("order", rd_u32(r, 16).into(), o.order.into()),
            ("scalar type", rd_u32(r, 20).into(), stored.into()),
            ("point count", rd_u64(r, 24), o.points_in_file),
        ];
        for (field, found, expected) in pairs {
            if found != expected {
                return Err(inconsistent(format!("{what} {field}"), expected, found));
            }
        }
        let section_index = rd_u32(r, 32);
        let data_length = rd_u64(r, 40);
        let s = self.claim_section(section_index, compressed, &what)?;
        if compressed {
            if data_length != s.length {
                return Err(inconsistent(
                    format!("{what} data length (= its CPCA section's length)"),
                    s.length,
                    data_length,
                ));
            }
            let c = read_cpca(self.file.get(section_index as usize), oi, &what)?;
            self.cpcas.insert((oi, o.blocks.len()), c);
        } else {
            self.check_xfer(section_index, s, data_length, o, &what)?;
        }
        o.blocks.push(BlockInfo {
            kind,
            section_index,
            offset: s.offset,
            length: s.length,
        });
        Ok(())
    }

    /// The section a block names: an `XFER` (a `CPCA` when `compressed`) that no other block
    /// has claimed.
    fn claim_section(
        &mut self,
        section_index: u32,
        compressed: bool,
        what: &str,
    ) -> Result<&'s SectionEntry, BakeFileError> {
        let want = if compressed { Tag::CPCA } else { Tag::XFER };
        let s = self
            .file
            .sections
            .get(section_index as usize)
            .filter(|s| s.tag == want)
            .ok_or_else(|| {
                invalid(
                    format!("{what} section"),
                    format!("{section_index} is not a {want} section"),
                )
            })?;
        if !self.used_sections.insert(section_index) {
            return Err(invalid(
                format!("{what} section"),
                format!("section {section_index} used by two blocks"),
            ));
        }
        Ok(s)
    }

    /// An `XFER` section (SPEC.md §3.5): the block's `data_length` and the section's length are
    /// both points × channels × order² × scalar size (rule 8), and every scalar is finite
    /// (rule 10, on the stored bits).
    fn check_xfer(
        &self,
        section_index: u32,
        s: &SectionEntry,
        data_length: u64,
        o: &ObjectInfo,
        what: &str,
    ) -> Result<(), BakeFileError> {
        let scalar = self.scalar;
        let per_point = u64::from(o.channels) * u64::from(o.order) * u64::from(o.order);
        let expected = o
            .points_in_file
            .checked_mul(per_point)
            .and_then(|n| n.checked_mul(scalar.size() as u64));
        if expected != Some(data_length) || data_length != s.length {
            return Err(inconsistent(
                format!("{what} data length (points × channels × order² × scalar size)"),
                expected.unwrap_or(u64::MAX),
                if expected == Some(data_length) {
                    s.length
                } else {
                    data_length
                },
            ));
        }
        let data = self.file.get(section_index as usize);
        let bad = match scalar {
            ScalarType::F32 => data
                .chunks_exact(4)
                .position(|c| rd_u32(c, 0) & 0x7f80_0000 == 0x7f80_0000),
            ScalarType::F16 => data
                .chunks_exact(2)
                .position(|c| u16::from_le_bytes([c[0], c[1]]) & 0x7c00 == 0x7c00),
        };
        if let Some(index) = bad {
            return Err(BakeFileError::NonFinite {
                section: section_name(Tag::XFER, section_index as usize),
                index: index as u64,
            });
        }
        Ok(())
    }
}

/// Reads a CPCA payload (SPEC.md §3.13) of block `what` of object `object`: every count is
/// checked against the payload's length before anything is allocated; the semantic rules
/// (dimension, cluster ids, finite values) are `Bake::validate`'s.
fn read_cpca(p: &[u8], object: usize, what: &str) -> Result<Cpca, BakeFileError> {
    if p.len() < CPCA_HEADER {
        return Err(inconsistent(
            format!("{what} CPCA length"),
            CPCA_HEADER as u64,
            p.len() as u64,
        ));
    }
    if rd_u32(p, 0) as usize != object {
        return Err(invalid(
            format!("{what} CPCA"),
            format!("its object index is {}, not {object}", rd_u32(p, 0)),
        ));
    }
    let (k, m, d) = (rd_u32(p, 4), rd_u32(p, 8), rd_u32(p, 12));
    let points = rd_u64(p, 16);
    let centres = u128::from(k) * (u128::from(m) + 1) * u128::from(d);
    let expected = CPCA_HEADER as u128
        + 4 * centres
        + 4 * u128::from(points)
        + 4 * u128::from(points) * u128::from(m);
    if expected != p.len() as u128 {
        return Err(inconsistent(
            format!("{what} CPCA length (32 + 4·K·(M+1)·D + 4·P + 4·P·M)"),
            u64::try_from(expected).unwrap_or(u64::MAX),
            p.len() as u64,
        ));
    }
    let f32s = |b: &[u8]| -> Vec<f32> {
        b.chunks_exact(4)
            .map(|c| f32::from_bits(rd_u32(c, 0)))
            .collect()
    };
    let a = CPCA_HEADER;
    let b = a + 4 * centres as usize;
    let c = b + 4 * points as usize;
    Ok(Cpca {
        clusters: k,
        components: m,
        dimension: d,
        rel_error: rd_f64(p, 24),
        centres: f32s(&p[a..b]),
        cluster_of: p[b..c].chunks_exact(4).map(|x| rd_u32(x, 0)).collect(),
        weights: f32s(&p[c..]),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sample_kinds_come_with_their_image_size() {
        assert_eq!(sample_kind(1, 0, 0).unwrap(), SampleKind::Vertex);
        assert_eq!(
            sample_kind(3, 4, 2).unwrap(),
            SampleKind::Texel {
                width: 4,
                height: 2
            }
        );
        for (code, w, h) in [(1, 1, 0), (2, 0, 3), (3, 3, 0), (4, 1, 1), (0, 0, 0)] {
            assert_eq!(
                sample_kind(code, w, h).unwrap_err().to_string(),
                format!("invalid BINF sample kind: code {code} with image {w}×{h}")
            );
        }
    }

    /// A CPCA payload of object 2 with K clusters, M components, D scalars and P points.
    fn cpca_bytes(k: u32, m: u32, d: u32, p: u64) -> Vec<u8> {
        let mut b = Vec::new();
        for v in [2, k, m, d] {
            b.extend_from_slice(&v.to_le_bytes());
        }
        b.extend_from_slice(&p.to_le_bytes());
        b.extend_from_slice(&0.25f64.to_le_bytes());
        let scalars = (k * (m + 1) * d) as usize;
        b.extend((0..scalars).flat_map(|i| (i as f32).to_le_bytes()));
        b.extend((0..p as u32).flat_map(|i| (i % k).to_le_bytes()));
        b.extend((0..p as usize * m as usize).flat_map(|i| (-(i as f32)).to_le_bytes()));
        b
    }

    #[test]
    fn cpca_payloads_read_back_and_their_lengths_are_checked() {
        let c = read_cpca(&cpca_bytes(2, 1, 3, 4), 2, "block 0").unwrap();
        assert_eq!((c.clusters, c.components, c.dimension), (2, 1, 3));
        assert_eq!(c.rel_error, 0.25);
        assert_eq!(
            c.centres,
            [0.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, 9.0, 10.0, 11.0]
        );
        assert_eq!(c.cluster_of, [0, 1, 0, 1]);
        assert_eq!(c.weights, [-0.0, -1.0, -2.0, -3.0]);

        let wrong_object = read_cpca(&cpca_bytes(2, 1, 3, 4), 1, "block 0").unwrap_err();
        assert_eq!(
            wrong_object.to_string(),
            "invalid block 0 CPCA: its object index is 2, not 1"
        );
        let mut long = cpca_bytes(2, 1, 3, 4);
        long.extend_from_slice(&[0; 4]);
        assert!(read_cpca(&long, 2, "b").is_err());
        // Counts whose byte total overflows u64 are refused, not wrapped.
        let mut huge = cpca_bytes(1, 0, 1, 0);
        huge[16..24].copy_from_slice(&u64::MAX.to_le_bytes());
        assert!(read_cpca(&huge, 2, "b").is_err());
        assert!(read_cpca(&[0; 31], 2, "b").is_err());
    }
}
