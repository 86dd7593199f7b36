//! The reader: validates a whole file once, then lends coefficient arrays in place.

use std::borrow::Cow;
use std::collections::BTreeSet;

use half::f16;

use crate::encode::header_crc;
use crate::error::{inconsistent, invalid, BakeFileError};
use crate::field::{first_breaking, FieldValues, Rule};
use crate::layout::{
    Tag, BINF_SIZE, BLKT_RECORD, BRDF_RECORD, CPCA_HEADER, CVRG_HEADER, ENVL_HEADER, GLSY_RECORD,
    HEADER_SIZE, MAGIC, MESH_HEADER, MUST_UNDERSTAND_FLAGS, NO_SECTION, OBJT_RECORD_V10,
    PASS_HEADER, RFLD_HEADER, SCALAR_CPCA, SECTION_ENTRY_SIZE, SECTION_FLAG_REQUIRED,
    TABLE_HEADER_SIZE, VERSION_MAJOR,
};
use crate::meta::{
    agree, check_mandatory, hash_string, MetaJson, ShConvention, COLOUR_SPACE, FORMAT_NAME,
};
use crate::model::{
    check_finite64, Bake, BakeMeta, BrdfLobe, BrdfProjection, Coverage, Cpca, EnvCoefficients,
    EnvPrecision, GlossyBrdfTable, MeshGeometry, ObjectBake, PassHit, PassState, ReflectanceField,
    SampleKind, ScalarType, ShardInfo, TransferBlock, TransferKind,
};

/// One entry of the section table, as read (and checked) from the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SectionEntry {
    /// Section tag.
    pub tag: Tag,
    /// Section flags.
    pub flags: u32,
    /// Byte offset of the payload from the start of the file.
    pub offset: u64,
    /// Payload length in bytes.
    pub length: u64,
    /// CRC-32 of the payload.
    pub crc32: u32,
}

/// One transfer block as located in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockInfo {
    /// What transport the block describes.
    pub kind: TransferKind,
    /// Index of its XFER section in the section table.
    pub section_index: u32,
    /// Byte offset of the coefficients from the start of the file.
    pub offset: u64,
    /// Byte length of the coefficients.
    pub length: u64,
}

/// One object as located in the file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ObjectInfo {
    /// Object name.
    pub name: String,
    /// Geometry hash ([`crate::geometry_hash`]).
    pub geometry_hash: u64,
    /// Points of the whole object.
    pub point_count: u64,
    /// First point held in this file.
    pub point_first: u64,
    /// Points held in this file.
    pub points_in_file: u64,
    /// SH order (band count).
    pub order: u32,
    /// 1 or 3.
    pub channels: u32,
    /// Its transfer blocks.
    pub blocks: Vec<BlockInfo>,
    /// Index of its MESH section (1.1), if it has one.
    pub mesh_section: Option<u32>,
    /// Index of its CVRG section (1.1, per-pixel bakes), if it has one.
    pub coverage_section: Option<u32>,
}

/// Coefficients of one block, borrowed from the file bytes when they are suitably aligned
/// (and the host is little-endian), copied otherwise.
#[derive(Debug, Clone, PartialEq)]
pub enum Coefficients<'a> {
    /// Stored as f32.
    F32(Cow<'a, [f32]>),
    /// Stored as f16.
    F16(Cow<'a, [f16]>),
}

impl Coefficients<'_> {
    /// Is this a view into the file bytes rather than a copy?
    #[must_use]
    pub fn is_borrowed(&self) -> bool {
        matches!(
            self,
            Coefficients::F32(Cow::Borrowed(_)) | Coefficients::F16(Cow::Borrowed(_))
        )
    }

    /// Number of scalars.
    #[must_use]
    pub fn len(&self) -> usize {
        match self {
            Coefficients::F32(v) => v.len(),
            Coefficients::F16(v) => v.len(),
        }
    }

    /// True when there are no scalars.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The values widened to f32 (exact for both storage types).
    #[must_use]
    pub fn to_f32_vec(&self) -> Vec<f32> {
        match self {
            Coefficients::F32(v) => v.to_vec(),
            Coefficients::F16(v) => v.iter().map(|h| h.to_f32()).collect(),
        }
    }
}

/// A validated bake file, borrowing its bytes.
///
/// [`BakeView::new`] checks everything [`decode`] checks (structure, checksums, counts,
/// metadata agreement, finiteness); afterwards coefficient slices are lent without copying
/// when the bytes are aligned.
#[derive(Debug, Clone)]
pub struct BakeView<'a> {
    bytes: &'a [u8],
    version: (u32, u32),
    scalar: ScalarType,
    sections: Vec<SectionEntry>,
    meta: BakeMeta,
    objects: Vec<ObjectInfo>,
    meshes: Vec<Option<MeshGeometry>>,
    coverages: Vec<Option<Coverage>>,
    passes: Vec<Option<PassState>>,
    cpcas: std::collections::BTreeMap<(usize, usize), Cpca>,
    /// Per object, its material binding (1.2), from the metadata.
    materials: Vec<Option<crate::MaterialBinding>>,
    environment: Option<EnvCoefficients>,
    brdfs: Vec<BrdfProjection>,
    glossy: Vec<GlossyBrdfTable>,
    reflectance: Option<FieldLocation>,
}

/// A validated `RFLD` section: its structure, and where its values lie in the file (they are
/// checked in place and never decoded by the view).
#[derive(Debug, Clone)]
struct FieldLocation {
    directions: [u32; 2],
    pixels: Vec<u32>,
    /// Byte range of the values in the file.
    values: std::ops::Range<usize>,
}

/// Decodes and validates a whole bake file held in memory.
///
/// Nothing in the input is trusted before it is checked: every count and offset is checked
/// against the actual byte length before it is used, so no allocation is sized by an
/// unchecked field, and no input makes it panic.
///
/// # Errors
/// A typed [`BakeFileError`] for every way the bytes can be malformed.
pub fn decode(bytes: &[u8]) -> Result<Bake, BakeFileError> {
    BakeView::new(bytes)?.into_bake()
}

/// [`decode`] of a buffer given away: a reflectance field's values (SPEC.md §3.14) become
/// the buffer itself — the bytes before them are shifted out (a `memmove`, no allocation) and
/// those after them cut off — so decoding a file that is mostly a field needs no memory beyond
/// the file's. This is what [`crate::read_bake`] does.
///
/// # Errors
/// As [`decode`].
pub fn decode_owned(mut bytes: Vec<u8>) -> Result<Bake, BakeFileError> {
    let (mut bake, located) = {
        let view = BakeView::new(&bytes)?;
        let range = view.reflectance.as_ref().map(|r| r.values.clone());
        (
            view.bake_with_empty_field(),
            range.map(|r| (r, view.scalar)),
        )
    };
    if let (Some(field), Some((range, scalar))) = (bake.reflectance.as_mut(), located) {
        bytes.truncate(range.end);
        bytes.drain(..range.start);
        // The spare capacity is the header, table, small sections and pixel indices (a few
        // hundred kB for a full image); give it back only when it is a sizeable part.
        if bytes.capacity() - bytes.len() > bytes.len() / 8 {
            bytes.shrink_to_fit();
        }
        field.values = FieldValues::from_le_bytes(scalar, bytes);
    }
    Ok(bake)
}

fn rd_u32(b: &[u8], off: usize) -> u32 {
    u32::from_le_bytes(b[off..off + 4].try_into().expect("4 bytes"))
}

fn rd_u64(b: &[u8], off: usize) -> u64 {
    u64::from_le_bytes(b[off..off + 8].try_into().expect("8 bytes"))
}

fn rd_f64(b: &[u8], off: usize) -> f64 {
    f64::from_bits(rd_u64(b, off))
}

fn section_name(tag: Tag, index: usize) -> String {
    format!("{tag}#{index}")
}

/// Reads a table section's 16-byte header and checks its length; returns (count, record size).
fn table(payload: &[u8], name: &str, min_record: usize) -> Result<(usize, usize), BakeFileError> {
    if payload.len() < TABLE_HEADER_SIZE {
        return Err(inconsistent(
            format!("{name} length"),
            TABLE_HEADER_SIZE as u64,
            payload.len() as u64,
        ));
    }
    let count = rd_u32(payload, 0) as usize;
    let record = rd_u32(payload, 4) as usize;
    if record < min_record {
        return Err(invalid(
            format!("{name} record size"),
            format!("{record} < {min_record}"),
        ));
    }
    let records_end = (count as u64) * (record as u64) + TABLE_HEADER_SIZE as u64;
    if records_end > payload.len() as u64 {
        return Err(inconsistent(
            format!("{name} length for {count} records"),
            records_end,
            payload.len() as u64,
        ));
    }
    Ok((count, record))
}

fn string(strs: &[u8], off: u32, len: u32, field: &str) -> Result<String, BakeFileError> {
    let end = u64::from(off) + u64::from(len);
    if end > strs.len() as u64 {
        return Err(invalid(
            field,
            format!("string {off}+{len} beyond the {}-byte pool", strs.len()),
        ));
    }
    std::str::from_utf8(&strs[off as usize..end as usize])
        .map(str::to_owned)
        .map_err(|e| invalid(field, format!("not UTF-8: {e}")))
}

/// Reads `count` f64 at byte `off` of `payload`, which must be exactly `expected_off`.
fn f64s(
    payload: &[u8],
    off: u64,
    expected_off: u64,
    count: u64,
    name: &str,
) -> Result<Vec<f64>, BakeFileError> {
    if off != expected_off {
        return Err(inconsistent(format!("{name} offset"), expected_off, off));
    }
    let end = count
        .checked_mul(8)
        .and_then(|n| n.checked_add(off))
        .filter(|&e| e <= payload.len() as u64)
        .ok_or_else(|| {
            inconsistent(
                format!("{name}: bytes for {count} f64 at offset {off}"),
                count.saturating_mul(8).saturating_add(off),
                payload.len() as u64,
            )
        })?;
    let v: Vec<f64> = payload[off as usize..end as usize]
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
        .collect();
    check_finite64(name, &v)?;
    Ok(v)
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

/// Reads a PASS payload (SPEC.md §3.12) of object `o`: every count is checked against the
/// payload's length before anything is allocated.
fn read_pass(p: &[u8], o: &ObjectInfo, name: &str) -> Result<PassState, BakeFileError> {
    let (levels, order, flags) = (u64::from(rd_u32(p, 4)), rd_u32(p, 8), rd_u32(p, 12));
    let (vertices, points, hits) = (rd_u64(p, 16), rd_u64(p, 24), rd_u64(p, 32));
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
    let per = 3 * u64::from(order) * u64::from(order);
    let (has_partial, has_totals, has_hits) = (flags & 1 != 0, flags & 2 != 0, flags & 4 != 0);
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
    if flags & 8 == 0 && !hits.is_empty() {
        return Err(invalid(
            format!("{name} flags"),
            "hit records without the records flag (bit 3)",
        ));
    }
    // Every number finite (SPEC.md §4 rule 10): totals, levels, the partial level, hits.
    if let Some(t) = &totals {
        crate::model::check_finite64(&format!("{name} totals"), t)?;
    }
    for l in levels.iter().chain(&partial) {
        crate::model::check_finite32(&format!("{name} levels"), l)?;
    }
    if let Some(h) = hits
        .iter()
        .position(|h| !(h.u.is_finite() && h.v.is_finite()))
    {
        return Err(BakeFileError::NonFinite {
            section: format!("{name} hits"),
            index: h as u64,
        });
    }
    Ok(PassState {
        levels,
        partial,
        totals,
        hit_counts,
        records: flags & 8 != 0,
        hits,
    })
}

/// Reads an RFLD payload (SPEC.md §3.14) that starts at byte `offset` of the file: lengths
/// checked before anything is allocated, values finite and non-negative (checked in place, on
/// their bits: nothing is decoded).
fn read_reflectance(
    p: &[u8],
    scalar: ScalarType,
    offset: usize,
) -> Result<FieldLocation, BakeFileError> {
    if p.len() < RFLD_HEADER {
        return Err(inconsistent(
            "RFLD length (at least its header)",
            RFLD_HEADER as u64,
            p.len() as u64,
        ));
    }
    let (w, h, channels, n) = (rd_u32(p, 0), rd_u32(p, 4), rd_u32(p, 8), rd_u64(p, 16));
    if channels != 3 || w < 2 || h < 1 || u64::from(w) * u64::from(h) > 1 << 24 {
        return Err(invalid(
            "RFLD",
            format!("{w}×{h} directions of {channels} channels (3 channels, at least 2×1, at most 2^24 directions)"),
        ));
    }
    let values = n.checked_mul(3 * u64::from(w) * u64::from(h));
    let expected = values
        .and_then(|v| v.checked_mul(scalar.size() as u64))
        .and_then(|v| v.checked_add(RFLD_HEADER as u64))
        .and_then(|v| v.checked_add(n.checked_mul(4)?));
    if expected != Some(p.len() as u64) {
        return Err(inconsistent(
            "RFLD length (32 + 4 × pixels + scalars × 3 × W × H × pixels)",
            expected.unwrap_or(u64::MAX),
            p.len() as u64,
        ));
    }
    let n = n as usize;
    let pixels: Vec<u32> = p[RFLD_HEADER..RFLD_HEADER + 4 * n]
        .chunks_exact(4)
        .map(|c| rd_u32(c, 0))
        .collect();
    let data = &p[RFLD_HEADER + 4 * n..];
    if let Some(i) = first_breaking(scalar, data, Rule::Valid) {
        let s = scalar.size();
        let v = FieldValues::from_le_bytes(scalar, data[i * s..(i + 1) * s].to_vec());
        return Err(invalid(
            "RFLD",
            format!(
                "value {i} is {} (finite and non-negative)",
                v.get(0).unwrap_or(f32::NAN)
            ),
        ));
    }
    let start = offset + RFLD_HEADER + 4 * n;
    Ok(FieldLocation {
        directions: [w, h],
        pixels,
        values: start..start + data.len(),
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

/// The rule of SPEC.md §4 that error `e`, raised while the checks of rule `phase` ran,
/// breaks: a non-finite value is always rule 10, a length or truncation found while the
/// tables and payloads are read (rule 9's phase) rule 8; otherwise the phase's rule.
fn rule_of(e: &BakeFileError, phase: u8) -> u8 {
    match e.root() {
        BakeFileError::NonFinite { .. } => 10,
        BakeFileError::Truncated { .. } if phase == 9 => 8,
        BakeFileError::InconsistentCounts { what, .. } if phase == 9 && what.contains("length") => {
            8
        }
        _ => phase,
    }
}

impl<'a> BakeView<'a> {
    /// Validates `bytes` as a bake file (everything [`decode`] checks) without copying the
    /// coefficient arrays.
    ///
    /// # Errors
    /// A typed [`BakeFileError`] for every way the bytes can be malformed, wrapped in
    /// [`BakeFileError::Rule`]: the rule of SPEC.md §4 it breaks.
    pub fn new(bytes: &'a [u8]) -> Result<Self, BakeFileError> {
        let mut rule = 1;
        Self::read(bytes, &mut rule).map_err(|e| {
            let r = rule_of(&e, rule);
            e.in_rule(r)
        })
    }

    /// [`BakeView::new`], checking in the order of SPEC.md §4 and keeping in `rule` the rule
    /// whose checks are running (each error names the rule it breaks: [`rule_of`]).
    #[allow(clippy::too_many_lines)] // One pass down §4's list; each step is commented.
    fn read(bytes: &'a [u8], rule: &mut u8) -> Result<Self, BakeFileError> {
        let len = bytes.len() as u64;
        // Magic, version, size: in this order, so that every prefix of a valid file is
        // reported as Truncated and every future major version as UnsupportedVersion.
        let head = &bytes[..bytes.len().min(8)];
        if head != &MAGIC[..head.len()] {
            return Err(BakeFileError::BadMagic {
                found: head.to_vec(),
            });
        }
        *rule = 2;
        if bytes.len() < HEADER_SIZE {
            return Err(BakeFileError::Truncated {
                needed: HEADER_SIZE as u64,
                available: len,
            });
        }
        let (major, minor) = (rd_u32(bytes, 8), rd_u32(bytes, 12));
        if major != VERSION_MAJOR {
            return Err(BakeFileError::UnsupportedVersion {
                major,
                minor,
                supported: VERSION_MAJOR,
            });
        }
        *rule = 3;
        let file_size = rd_u64(bytes, 24);
        if len < file_size {
            return Err(BakeFileError::Truncated {
                needed: file_size,
                available: len,
            });
        }
        if len > file_size {
            return Err(inconsistent("file size (trailing bytes)", file_size, len));
        }
        *rule = 4;
        let table_off = rd_u64(bytes, 32);
        let section_count = rd_u32(bytes, 40) as u64;
        let table_end = section_count
            .checked_mul(SECTION_ENTRY_SIZE as u64)
            .and_then(|n| n.checked_add(table_off))
            .filter(|&e| table_off >= HEADER_SIZE as u64 && table_off % 8 == 0 && e <= len)
            .ok_or_else(|| BakeFileError::OutOfBounds {
                section: "section table".into(),
                offset: table_off,
                length: section_count.saturating_mul(SECTION_ENTRY_SIZE as u64),
                file_size: len,
            })?;
        let table_bytes = &bytes[table_off as usize..table_end as usize];
        let stored = rd_u32(bytes, 60);
        let computed = header_crc(&bytes[..HEADER_SIZE], table_bytes);
        if stored != computed {
            return Err(BakeFileError::ChecksumMismatch {
                section: "header".into(),
                stored,
                computed,
            });
        }
        // The header is now known to be what the writer wrote.
        *rule = 5;
        let header_size = rd_u32(bytes, 16);
        if header_size as usize != HEADER_SIZE {
            return Err(inconsistent(
                "header size",
                HEADER_SIZE as u64,
                header_size.into(),
            ));
        }
        let entry_size = rd_u32(bytes, 44);
        if entry_size as usize != SECTION_ENTRY_SIZE {
            return Err(inconsistent(
                "section entry size",
                SECTION_ENTRY_SIZE as u64,
                entry_size.into(),
            ));
        }
        let flags = rd_u32(bytes, 20);
        if flags & MUST_UNDERSTAND_FLAGS != 0 {
            return Err(BakeFileError::UnsupportedFlags {
                location: "header".into(),
                flags: flags & MUST_UNDERSTAND_FLAGS,
            });
        }
        let alignment = u64::from(rd_u32(bytes, 48));
        if !alignment.is_power_of_two() || !(16..=4096).contains(&alignment) {
            return Err(invalid(
                "payload alignment",
                format!("{alignment} is not a power of two in 16..=4096"),
            ));
        }
        let scalar_code = rd_u32(bytes, 52);
        let scalar = ScalarType::from_code(scalar_code)
            .ok_or_else(|| invalid("scalar type", format!("unknown code {scalar_code}")))?;

        // Section table: tags, flags, alignment, bounds, overlap, padding, checksums.
        *rule = 6;
        let mut sections = Vec::with_capacity(section_count as usize);
        for (i, e) in table_bytes.chunks_exact(SECTION_ENTRY_SIZE).enumerate() {
            let s = SectionEntry {
                tag: Tag(e[0..4].try_into().expect("4 bytes")),
                flags: rd_u32(e, 4),
                offset: rd_u64(e, 8),
                length: rd_u64(e, 16),
                crc32: rd_u32(e, 24),
            };
            let name = section_name(s.tag, i);
            // Printable ASCII, no space: a zeroed entry (a `section_count` one too many, over
            // the padding) is not read as an empty optional section.
            if !s.tag.0.iter().all(|b| (0x21..=0x7e).contains(b)) {
                return Err(invalid(
                    format!("section table entry {i}"),
                    format!(
                        "tag bytes {:02x?} are not four printable ASCII characters",
                        s.tag.0
                    ),
                ));
            }
            let unknown = s.flags & MUST_UNDERSTAND_FLAGS & !SECTION_FLAG_REQUIRED;
            if unknown != 0 {
                return Err(BakeFileError::UnsupportedFlags {
                    location: name,
                    flags: unknown,
                });
            }
            if s.offset % alignment != 0 {
                return Err(BakeFileError::Misaligned {
                    section: name,
                    offset: s.offset,
                    alignment,
                });
            }
            if s.offset.checked_add(s.length).is_none_or(|end| end > len) {
                return Err(BakeFileError::OutOfBounds {
                    section: name,
                    offset: s.offset,
                    length: s.length,
                    file_size: len,
                });
            }
            sections.push(s);
        }
        let mut regions: Vec<(u64, u64, String)> = vec![
            (0, HEADER_SIZE as u64, "file header".into()),
            (table_off, table_end, "section table".into()),
        ];
        for (i, s) in sections.iter().enumerate() {
            if s.length > 0 {
                regions.push((s.offset, s.offset + s.length, section_name(s.tag, i)));
            }
        }
        regions.sort();
        let mut covered = 0u64;
        let mut last = String::new();
        for (start, end, name) in &regions {
            if *start < covered {
                return Err(BakeFileError::Overlap {
                    first: last,
                    second: name.clone(),
                });
            }
            if bytes[covered as usize..*start as usize]
                .iter()
                .any(|&b| b != 0)
            {
                return Err(invalid(
                    "padding",
                    format!("non-zero byte between offsets {covered} and {start}"),
                ));
            }
            covered = *end;
            last.clone_from(name);
        }
        if bytes[covered as usize..].iter().any(|&b| b != 0) {
            return Err(invalid("padding", "non-zero byte after the last section"));
        }
        for (i, s) in sections.iter().enumerate() {
            let computed =
                crc32fast::hash(&bytes[s.offset as usize..(s.offset + s.length) as usize]);
            if computed != s.crc32 {
                return Err(BakeFileError::ChecksumMismatch {
                    section: section_name(s.tag, i),
                    stored: s.crc32,
                    computed,
                });
            }
        }

        // Find the sections by tag.
        *rule = 7;
        let mut single: [(Tag, Option<usize>, bool); 9] = [
            (Tag::BINF, None, true),
            (Tag::STRS, None, true),
            (Tag::OBJT, None, true),
            (Tag::BLKT, None, true),
            (Tag::META, None, true),
            (Tag::ENVL, None, false),
            (Tag::BRDF, None, false),
            (Tag::GLSY, None, false),
            (Tag::RFLD, None, false),
        ];
        for (i, s) in sections.iter().enumerate() {
            if let Some(slot) = single.iter_mut().find(|(t, _, _)| *t == s.tag) {
                if slot.1.is_some() {
                    return Err(BakeFileError::DuplicateSection(s.tag.to_string()));
                }
                slot.1 = Some(i);
            } else if ![Tag::XFER, Tag::MESH, Tag::CVRG, Tag::PASS, Tag::CPCA].contains(&s.tag)
                && s.flags & SECTION_FLAG_REQUIRED != 0
            {
                return Err(BakeFileError::UnknownRequiredSection(section_name(
                    s.tag, i,
                )));
            }
        }
        for (tag, index, required) in &single {
            if *required && index.is_none() {
                return Err(BakeFileError::MissingSection(tag.to_string()));
            }
        }
        // Every section of §3's table but MESH and CVRG is REQUIRED: a reader that skipped
        // an unmarked PASS, CPCA or RFLD would misread the file and not know it.
        for (i, s) in sections.iter().enumerate() {
            let known = single.iter().any(|(t, _, _)| *t == s.tag)
                || [Tag::XFER, Tag::PASS, Tag::CPCA].contains(&s.tag);
            if known && s.flags & SECTION_FLAG_REQUIRED == 0 {
                return Err(invalid(
                    section_name(s.tag, i),
                    format!(
                        "a {} section without the REQUIRED flag (every section of SPEC §3's table but MESH and CVRG carries it)",
                        s.tag
                    ),
                ));
            }
        }
        let payload = |i: usize| {
            let s = &sections[i];
            &bytes[s.offset as usize..(s.offset + s.length) as usize]
        };
        let get = |k: usize| single[k].1.map(payload);
        let (binf, strs, objt, blkt, meta_bytes) = (
            get(0).unwrap_or_default(),
            get(1).unwrap_or_default(),
            get(2).unwrap_or_default(),
            get(3).unwrap_or_default(),
            get(4).unwrap_or_default(),
        );

        // Each table and payload: lengths before use (rule 8), then cross-references and
        // counts (rule 9); values' finiteness is rule 10 wherever it is checked.
        *rule = 9;
        // BINF
        if binf.len() < BINF_SIZE {
            return Err(inconsistent(
                "BINF length",
                BINF_SIZE as u64,
                binf.len() as u64,
            ));
        }
        let sample = sample_kind(rd_u32(binf, 0), rd_u32(binf, 8), rd_u32(binf, 12))?;
        let bounces = rd_u32(binf, 4);
        let rays_per_point = rd_u32(binf, 16);
        let shard = ShardInfo {
            index: rd_u32(binf, 20),
            count: rd_u32(binf, 24),
        };
        let seed = rd_u64(binf, 32);

        // OBJT, BLKT
        let (object_count, orec) = table(objt, "OBJT", OBJT_RECORD_V10)?;
        let (block_count, brec) = table(blkt, "BLKT", BLKT_RECORD)?;
        let mut used_sections = BTreeSet::new();
        let mut cpcas: std::collections::BTreeMap<(usize, usize), Cpca> =
            std::collections::BTreeMap::new();
        let mut objects = Vec::with_capacity(object_count);
        let mut next_block = 0u64;
        for oi in 0..object_count {
            let r = &objt[TABLE_HEADER_SIZE + oi * orec..][..orec];
            let name = string(
                strs,
                rd_u32(r, 0),
                rd_u32(r, 4),
                &format!("object {oi} name"),
            )?;
            let mut o = ObjectInfo {
                name,
                geometry_hash: rd_u64(r, 8),
                point_count: rd_u64(r, 16),
                point_first: rd_u64(r, 24),
                points_in_file: rd_u64(r, 32),
                order: rd_u32(r, 40),
                channels: rd_u32(r, 44),
                blocks: Vec::new(),
                // 1.1 records (64 bytes) name the object's MESH and CVRG sections.
                mesh_section: (orec >= 64)
                    .then(|| rd_u32(r, 56))
                    .filter(|&i| i != NO_SECTION),
                coverage_section: (orec >= 64)
                    .then(|| rd_u32(r, 60))
                    .filter(|&i| i != NO_SECTION),
            };
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
            if o.order == 0
                || o.order > u32::from(u16::MAX)
                || !(o.channels == 1 || o.channels == 3)
            {
                return Err(invalid(
                    format!("object {oi}"),
                    format!("order {} / channels {}", o.order, o.channels),
                ));
            }
            let per_point = u64::from(o.channels) * u64::from(o.order) * u64::from(o.order);
            for bi in first_block..next_block {
                let r = &blkt[TABLE_HEADER_SIZE + bi as usize * brec..][..brec];
                let what = format!("block {bi}");
                let kind =
                    TransferKind::from_code(rd_u32(r, 4), rd_u32(r, 8)).ok_or_else(|| {
                        invalid(
                            format!("{what} kind"),
                            format!("code {} with {} bounces", rd_u32(r, 4), rd_u32(r, 8)),
                        )
                    })?;
                // A block stored as clustered PCA (SPEC.md §3.13) says so in its scalar type.
                let compressed = rd_u32(r, 20) == SCALAR_CPCA;
                let pairs = [
                    ("object index", u64::from(rd_u32(r, 0)), oi as u64),
                    ("channels", rd_u32(r, 12).into(), o.channels.into()),
                    ("order", rd_u32(r, 16).into(), o.order.into()),
                    (
                        "scalar type",
                        rd_u32(r, 20).into(),
                        if compressed {
                            SCALAR_CPCA
                        } else {
                            scalar.code()
                        }
                        .into(),
                    ),
                    ("point count", rd_u64(r, 24), o.points_in_file),
                ];
                for (field, found, expected) in pairs {
                    if found != expected {
                        return Err(inconsistent(format!("{what} {field}"), expected, found));
                    }
                }
                let section_index = rd_u32(r, 32);
                let data_length = rd_u64(r, 40);
                let want = if compressed { Tag::CPCA } else { Tag::XFER };
                let s = sections
                    .get(section_index as usize)
                    .filter(|s| s.tag == want)
                    .ok_or_else(|| {
                        invalid(
                            format!("{what} section"),
                            format!("{section_index} is not a {want} section"),
                        )
                    })?;
                if !used_sections.insert(section_index) {
                    return Err(invalid(
                        format!("{what} section"),
                        format!("section {section_index} used by two blocks"),
                    ));
                }
                if compressed {
                    if data_length != s.length {
                        return Err(inconsistent(
                            format!("{what} data length (= its CPCA section's length)"),
                            s.length,
                            data_length,
                        ));
                    }
                    let c = read_cpca(payload(section_index as usize), oi, &what)?;
                    cpcas.insert((oi, o.blocks.len()), c);
                    o.blocks.push(BlockInfo {
                        kind,
                        section_index,
                        offset: s.offset,
                        length: s.length,
                    });
                    continue;
                }
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
                let data = payload(section_index as usize);
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
                o.blocks.push(BlockInfo {
                    kind,
                    section_index,
                    offset: s.offset,
                    length: s.length,
                });
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
        let xfer_count = sections
            .iter()
            .filter(|s| s.tag == Tag::XFER || s.tag == Tag::CPCA)
            .count();
        if xfer_count != used_sections.len() {
            return Err(inconsistent(
                "XFER sections",
                used_sections.len() as u64,
                xfer_count as u64,
            ));
        }

        // MESH, CVRG (1.1): each referenced by exactly its own object.
        let mut meshes = Vec::with_capacity(objects.len());
        let mut coverages = Vec::with_capacity(objects.len());
        for (oi, o) in objects.iter().enumerate() {
            let located = |index: Option<u32>, tag: Tag| -> Result<Option<&[u8]>, BakeFileError> {
                let Some(i) = index else { return Ok(None) };
                let what = format!("object {oi} {tag} section");
                if sections.get(i as usize).is_none_or(|s| s.tag != tag) {
                    return Err(invalid(what, format!("{i} is not a {tag} section")));
                }
                let p = payload(i as usize);
                if p.len() < 16 || rd_u32(p, 0) as usize != oi {
                    return Err(invalid(
                        what,
                        format!("section {i} does not belong to object {oi}"),
                    ));
                }
                Ok(Some(p))
            };
            meshes.push(match located(o.mesh_section, Tag::MESH)? {
                Some(p) => Some(read_mesh(p, oi)?),
                None => None,
            });
            coverages.push(match located(o.coverage_section, Tag::CVRG)? {
                Some(p) => Some(read_coverage(p, oi)?),
                None => None,
            });
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
            let present = sections.iter().filter(|s| s.tag == tag).count();
            if present != refs.len() {
                return Err(inconsistent(
                    format!("{tag} sections (referenced by objects / present)"),
                    refs.len() as u64,
                    present as u64,
                ));
            }
        }

        // ENVL
        let reflectance = single[8]
            .1
            .map(|i| read_reflectance(payload(i), scalar, sections[i].offset as usize))
            .transpose()?;
        let environment = match get(5) {
            None => None,
            Some(p) => {
                if p.len() < ENVL_HEADER {
                    return Err(inconsistent(
                        "ENVL length",
                        ENVL_HEADER as u64,
                        p.len() as u64,
                    ));
                }
                let order = rd_u32(p, 0);
                let channels = rd_u32(p, 4);
                let (precision, size) = match rd_u32(p, 8) {
                    1 => (EnvPrecision::F32, 4),
                    3 => (EnvPrecision::F64, 8),
                    c => return Err(invalid("ENVL precision", format!("unknown code {c}"))),
                };
                if channels != 3 || order == 0 || order > u32::from(u16::MAX) {
                    return Err(invalid(
                        "ENVL",
                        format!("order {order}, {channels} channels"),
                    ));
                }
                let n = 3 * u64::from(order) * u64::from(order);
                let expected = ENVL_HEADER as u64 + n * size;
                if expected != p.len() as u64 {
                    return Err(inconsistent("ENVL length", expected, p.len() as u64));
                }
                let values: Vec<f64> = match precision {
                    EnvPrecision::F32 => p[ENVL_HEADER..]
                        .chunks_exact(4)
                        .map(|c| f64::from(f32::from_bits(rd_u32(c, 0))))
                        .collect(),
                    EnvPrecision::F64 => p[ENVL_HEADER..]
                        .chunks_exact(8)
                        .map(|c| rd_f64(c, 0))
                        .collect(),
                };
                check_finite64("ENVL", &values)?;
                Some(EnvCoefficients {
                    order,
                    precision,
                    values,
                })
            }
        };

        // BRDF
        let mut brdfs = Vec::new();
        if let Some(p) = get(6) {
            let (count, rec) = table(p, "BRDF", BRDF_RECORD)?;
            let mut off = (TABLE_HEADER_SIZE + count * rec) as u64;
            for i in 0..count {
                let r = &p[TABLE_HEADER_SIZE + i * rec..][..rec];
                let what = format!("BRDF record {i}");
                let material = string(
                    strs,
                    rd_u32(r, 0),
                    rd_u32(r, 4),
                    &format!("{what} material"),
                )?;
                let exponent = rd_f64(r, 16);
                let lobe = match rd_u32(r, 8) {
                    1 if exponent == 0.0 => BrdfLobe::ClampedCosine,
                    2 if exponent.is_finite() && exponent >= 0.0 => BrdfLobe::Phong { exponent },
                    c => {
                        return Err(invalid(
                            format!("{what} lobe"),
                            format!("code {c}, exponent {exponent}"),
                        ))
                    }
                };
                let order = rd_u32(r, 12);
                let values = f64s(p, rd_u64(r, 24), off, order.into(), &what)?;
                off += 8 * u64::from(order);
                brdfs.push(BrdfProjection {
                    material,
                    lobe,
                    order,
                    values,
                });
            }
            if off != p.len() as u64 {
                return Err(inconsistent("BRDF length", off, p.len() as u64));
            }
        }

        // GLSY
        let mut glossy = Vec::new();
        if let Some(p) = get(7) {
            let (count, rec) = table(p, "GLSY", GLSY_RECORD)?;
            let mut off = (TABLE_HEADER_SIZE + count * rec) as u64;
            for i in 0..count {
                let r = &p[TABLE_HEADER_SIZE + i * rec..][..rec];
                let what = format!("GLSY record {i}");
                let material = string(
                    strs,
                    rd_u32(r, 0),
                    rd_u32(r, 4),
                    &format!("{what} material"),
                )?;
                let n_elev = u64::from(rd_u32(r, 8));
                let order = rd_u32(r, 12);
                let elevations =
                    f64s(p, rd_u64(r, 16), off, n_elev, &format!("{what} elevations"))?;
                off += 8 * n_elev;
                let n_values = n_elev
                    .checked_mul(u64::from(order) * u64::from(order))
                    .ok_or_else(|| invalid(what.clone(), "too many values"))?;
                let values = f64s(p, rd_u64(r, 24), off, n_values, &format!("{what} values"))?;
                off += 8 * n_values;
                let projection_error = f64s(
                    p,
                    rd_u64(r, 32),
                    off,
                    order.into(),
                    &format!("{what} errors"),
                )?;
                off += 8 * u64::from(order);
                glossy.push(GlossyBrdfTable {
                    material,
                    order,
                    elevations,
                    values,
                    projection_error,
                });
            }
            if off != p.len() as u64 {
                return Err(inconsistent("GLSY length", off, p.len() as u64));
            }
        }

        // PASS (intermediate files of distributed bakes): one per object at most, found by the
        // object index in its header.
        let mut passes: Vec<Option<PassState>> = vec![None; objects.len()];
        for (i, s) in sections.iter().enumerate() {
            if s.tag != Tag::PASS {
                continue;
            }
            let p = payload(i);
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

        // The coverage is the object's mask: no transfer where no sample hit it.
        *rule = 10;
        for (oi, (o, coverage)) in objects.iter().zip(&coverages).enumerate() {
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
                let found = crate::model::uncovered_nonzero(o.point_first, o.blocks.len(), c, zero);
                if let Some((bi, p)) = found {
                    return Err(invalid(
                        format!("object {oi} block {bi}"),
                        format!("transfer at point {p}, which its coverage says no sample hit"),
                    ));
                }
            }
        }

        // META, and its agreement with everything above.
        *rule = 11;
        let value: serde_json::Value = serde_json::from_slice(meta_bytes)
            .map_err(|e| BakeFileError::Metadata(format!("not valid JSON: {e}")))?;
        crate::meta::check_unique_keys(meta_bytes)?;
        check_mandatory(&value, minor)?;
        let json: MetaJson = serde_json::from_value(value)
            .map_err(|e| BakeFileError::Metadata(format!("not valid metadata JSON: {e}")))?;
        agree("format", &json.format.as_str(), &FORMAT_NAME)?;
        agree("format_version", &json.format_version, &[major, minor])?;
        agree("sh", &json.sh, &ShConvention::current())?;
        agree("colour_space", &json.colour_space.as_str(), &COLOUR_SPACE)?;
        agree("scalar_type", &json.scalar_type, &scalar)?;
        agree("sample_kind", &json.sample_kind, &sample)?;
        agree("rays_per_point", &json.rays_per_point, &rays_per_point)?;
        agree("bounces", &json.bounces, &bounces)?;
        agree("seed", &json.seed, &seed)?;
        agree("shard", &json.shard, &shard)?;
        if minor >= 1 && matches!(sample, SampleKind::Pixel { .. }) && json.camera.is_none() {
            return Err(BakeFileError::Metadata(
                "a per-pixel bake of format 1.1 must record its camera".into(),
            ));
        }
        agree("objects.len()", &json.objects.len(), &objects.len())?;
        if !json.ray_stats.is_empty() {
            agree("ray_stats.len()", &json.ray_stats.len(), &objects.len())?;
            for (r, o) in json.ray_stats.iter().zip(&json.objects) {
                agree("ray_stats[].object", &r.object, &o.name)?;
                if r.backface_hits > r.rays || r.inside_rays > r.rays || r.inside_points > r.points
                {
                    return Err(BakeFileError::Metadata(format!(
                        "ray statistics of {:?} count more hits than rays or points",
                        r.object
                    )));
                }
            }
        }
        for (j, o) in json.objects.iter().zip(&objects) {
            let f = |x: &str| format!("objects[{:?}].{x}", o.name);
            agree(&f("name"), &j.name, &o.name)?;
            agree(
                &f("geometry_hash"),
                &j.geometry_hash,
                &hash_string(o.geometry_hash),
            )?;
            agree(&f("point_count"), &j.point_count, &o.point_count)?;
            agree(&f("point_first"), &j.point_first, &o.point_first)?;
            agree(&f("points_in_file"), &j.points_in_file, &o.points_in_file)?;
            agree(&f("order"), &j.order, &o.order)?;
            agree(&f("channels"), &j.channels, &o.channels)?;
            agree(&f("blocks.len()"), &j.blocks.len(), &o.blocks.len())?;
            for (jb, b) in j.blocks.iter().zip(&o.blocks) {
                agree(&f("blocks[].kind"), &jb.kind.as_str(), &b.kind.name())?;
                agree(&f("blocks[].bounces"), &jb.bounces, &b.kind.bounces())?;
                agree(&f("blocks[].section"), &jb.section, &b.section_index)?;
            }
        }
        for ((j, o), (mesh, coverage)) in json
            .objects
            .iter()
            .zip(&objects)
            .zip(meshes.iter().zip(&coverages))
        {
            let f = |x: &str| format!("objects[{:?}].{x}", o.name);
            agree(
                &f("mesh"),
                &j.mesh
                    .as_ref()
                    .map(|m| (m.section, m.vertices, m.triangles)),
                &o.mesh_section
                    .zip(mesh.as_ref())
                    .map(|(s, m)| (s, m.positions.len() as u32, m.triangles.len() as u32)),
            )?;
            agree(
                &f("coverage"),
                &j.coverage.as_ref().map(|c| (c.section, c.pixel_samples)),
                &o.coverage_section
                    .zip(coverage.as_ref())
                    .map(|(s, c)| (s, c.pixel_samples)),
            )?;
        }
        let env_json = environment.as_ref().map(|e| (e.order, e.precision));
        agree(
            "environment",
            &json.environment.as_ref().map(|e| (e.order, e.precision)),
            &env_json,
        )?;
        agree("brdfs.len()", &json.brdfs.len(), &brdfs.len())?;
        for (j, b) in json.brdfs.iter().zip(&brdfs) {
            let (lobe, exponent) = match b.lobe {
                BrdfLobe::ClampedCosine => ("clamped-cosine", None),
                BrdfLobe::Phong { exponent } => ("phong", Some(exponent)),
            };
            agree("brdfs[].material", &j.material, &b.material)?;
            agree("brdfs[].lobe", &j.lobe.as_str(), &lobe)?;
            agree(
                "brdfs[].exponent",
                &j.exponent.map(f64::to_bits),
                &exponent.map(f64::to_bits),
            )?;
            agree("brdfs[].order", &j.order, &b.order)?;
        }
        agree("glossy.len()", &json.glossy.len(), &glossy.len())?;
        for (j, g) in json.glossy.iter().zip(&glossy) {
            agree("glossy[].material", &j.material, &g.material)?;
            agree(
                "glossy[].elevations",
                &j.elevations,
                &(g.elevations.len() as u64),
            )?;
            agree("glossy[].order", &j.order, &g.order)?;
        }

        let view = BakeView {
            bytes,
            version: (major, minor),
            scalar,
            sections,
            meta: BakeMeta {
                sample_kind: sample,
                rays_per_point,
                bounces,
                seed,
                tool: json.tool,
                settings: json.settings,
                decisions: json.decisions,
                shard,
                ray_stats: json.ray_stats,
                camera: json.camera,
                pass: json.pass,
            },
            objects,
            meshes,
            coverages,
            passes,
            cpcas,
            environment,
            brdfs,
            glossy,
            reflectance,
            materials: json.objects.iter().map(|o| o.material.clone()).collect(),
        };
        // The semantic rules (unique names, shard ranges, ...), checked on a skeleton
        // without the coefficient data.
        view.skeleton().validate_structure()?;
        Ok(view)
    }

    pub(crate) fn skeleton(&self) -> Bake {
        Bake {
            // The structure only: the values stay in the view (`to_bake` copies them,
            // `into_bake` moves them) instead of being cloned for validation.
            reflectance: self.reflectance.as_ref().map(|r| ReflectanceField {
                directions: r.directions,
                pixels: r.pixels.clone(),
                values: FieldValues::new(self.scalar),
            }),
            meta: self.meta.clone(),
            objects: self
                .objects
                .iter()
                .zip(self.meshes.iter().zip(&self.coverages))
                .zip(&self.passes)
                .enumerate()
                .map(|(oi, ((o, (mesh, coverage)), pass))| ObjectBake {
                    name: o.name.clone(),
                    geometry_hash: o.geometry_hash,
                    point_count: o.point_count,
                    point_first: o.point_first,
                    points_in_file: o.points_in_file,
                    order: o.order,
                    channels: o.channels,
                    blocks: o
                        .blocks
                        .iter()
                        .enumerate()
                        .map(|(bi, b)| TransferBlock {
                            cpca: self.cpcas.get(&(oi, bi)).cloned(),
                            kind: b.kind,
                            data: Vec::new(),
                        })
                        .collect(),
                    mesh: mesh.clone(),
                    coverage: coverage.clone(),
                    material: self.materials[oi].clone(),
                    pass: pass.clone(),
                })
                .collect(),
            environment: self.environment.clone(),
            brdfs: self.brdfs.clone(),
            glossy: self.glossy.clone(),
        }
    }

    /// Object `i`'s material binding (format 1.2, SPEC.md §3.9.1): `None` when the file
    /// does not say (older files, or a writer that did not know it).
    #[must_use]
    pub fn material(&self, i: usize) -> Option<&crate::MaterialBinding> {
        self.materials.get(i).and_then(Option::as_ref)
    }

    /// The reflectance field (section `RFLD`), if the file holds one: a copy of its values in
    /// the file's precision (see [`BakeView::reflectance_bytes`] for them in place).
    #[must_use]
    pub fn reflectance(&self) -> Option<ReflectanceField> {
        self.reflectance.as_ref().map(|r| ReflectanceField {
            directions: r.directions,
            pixels: r.pixels.clone(),
            values: FieldValues::from_le_bytes(self.scalar, self.bytes[r.values.clone()].to_vec()),
        })
    }

    /// The reflectance field's values as the file stores them (`[pixel held][channel]
    /// [direction]`, little-endian [`BakeView::scalar_type`]), in place; `None` without a field.
    #[must_use]
    pub fn reflectance_bytes(&self) -> Option<&'a [u8]> {
        self.reflectance
            .as_ref()
            .map(|r| &self.bytes[r.values.clone()])
    }

    /// Format version `(major, minor)` of the file.
    #[must_use]
    pub fn version(&self) -> (u32, u32) {
        self.version
    }

    /// How transfer coefficients are stored.
    #[must_use]
    pub fn scalar_type(&self) -> ScalarType {
        self.scalar
    }

    /// The section table.
    #[must_use]
    pub fn sections(&self) -> &[SectionEntry] {
        &self.sections
    }

    /// Bake-wide metadata.
    #[must_use]
    pub fn meta(&self) -> &BakeMeta {
        &self.meta
    }

    /// The objects and where their blocks are.
    #[must_use]
    pub fn objects(&self) -> &[ObjectInfo] {
        &self.objects
    }

    /// The mesh of object `object` (1.1 files), `None` when it has none or the index is out
    /// of range.
    #[must_use]
    pub fn mesh(&self, object: usize) -> Option<&MeshGeometry> {
        self.meshes.get(object)?.as_ref()
    }

    /// The per-pixel coverage of object `object` (1.1 per-pixel bakes), `None` when it has
    /// none or the index is out of range.
    #[must_use]
    pub fn coverage(&self, object: usize) -> Option<&Coverage> {
        self.coverages.get(object)?.as_ref()
    }

    /// Environment lighting, if present.
    #[must_use]
    pub fn environment(&self) -> Option<&EnvCoefficients> {
        self.environment.as_ref()
    }

    /// Zonal BRDF projections.
    #[must_use]
    pub fn brdfs(&self) -> &[BrdfProjection] {
        &self.brdfs
    }

    /// Tabulated glossy BRDF projections.
    #[must_use]
    pub fn glossy(&self) -> &[GlossyBrdfTable] {
        &self.glossy
    }

    /// The whole file.
    #[must_use]
    pub fn bytes(&self) -> &'a [u8] {
        self.bytes
    }

    /// The raw little-endian bytes of block `block` of object `object`; `None` when either
    /// index is out of range.
    #[must_use]
    pub fn block_bytes(&self, object: usize, block: usize) -> Option<&'a [u8]> {
        let b = self.objects.get(object)?.blocks.get(block)?;
        Some(&self.bytes[b.offset as usize..(b.offset + b.length) as usize])
    }

    /// The clustered-PCA form of block `block` of object `object`, if it is stored so.
    #[must_use]
    pub fn cpca(&self, object: usize, block: usize) -> Option<&Cpca> {
        self.cpcas.get(&(object, block))
    }

    /// The coefficients of block `block` of object `object`, `[point][channel][coefficient]`;
    /// borrowed in place when the bytes are aligned for the scalar type (and the host is
    /// little-endian), copied otherwise; a compressed block's reconstruction (SPEC.md §3.13).
    /// `None` when either index is out of range.
    #[must_use]
    pub fn coefficients(&self, object: usize, block: usize) -> Option<Coefficients<'a>> {
        if let Some(c) = self.cpca(object, block) {
            return Some(Coefficients::F32(Cow::Owned(c.reconstruct())));
        }
        let raw = self.block_bytes(object, block)?;
        Some(match self.scalar {
            ScalarType::F32 => Coefficients::F32(
                if cfg!(target_endian = "little") {
                    bytemuck::try_cast_slice::<u8, f32>(raw)
                        .ok()
                        .map(Cow::Borrowed)
                } else {
                    None
                }
                .unwrap_or_else(|| {
                    Cow::Owned(
                        raw.chunks_exact(4)
                            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
                            .collect(),
                    )
                }),
            ),
            ScalarType::F16 => Coefficients::F16(
                if cfg!(target_endian = "little") {
                    bytemuck::try_cast_slice::<u8, f16>(raw)
                        .ok()
                        .map(Cow::Borrowed)
                } else {
                    None
                }
                .unwrap_or_else(|| {
                    Cow::Owned(
                        raw.chunks_exact(2)
                            .map(|c| f16::from_le_bytes([c[0], c[1]]))
                            .collect(),
                    )
                }),
            ),
        })
    }

    /// Copies everything into an owned [`Bake`] (coefficients widened to f32, exactly; a
    /// reflectance field's values copied in the file's precision). [`decode_owned`] takes a
    /// buffer instead and copies no field.
    ///
    /// # Errors
    /// None in practice (the view is already validated); kept fallible for future checks.
    pub fn to_bake(&self) -> Result<Bake, BakeFileError> {
        let mut bake = self.bake_with_empty_field();
        bake.reflectance = self.reflectance();
        Ok(bake)
    }

    /// [`BakeView::to_bake`], consuming the view. The view holds no decoded field values (it
    /// checks them in place), so this copies the field's values once, in the file's precision,
    /// out of the borrowed bytes; to avoid even that copy, give the buffer to
    /// [`decode_owned`].
    ///
    /// # Errors
    /// As [`BakeView::to_bake`].
    pub fn into_bake(self) -> Result<Bake, BakeFileError> {
        self.to_bake()
    }

    /// The skeleton with every block's coefficients and the field's structure, its values empty.
    fn bake_with_empty_field(&self) -> Bake {
        let mut bake = self.skeleton();
        for (oi, o) in bake.objects.iter_mut().enumerate() {
            for (bi, b) in o.blocks.iter_mut().enumerate() {
                b.data = self
                    .coefficients(oi, bi)
                    .map(|c| c.to_f32_vec())
                    .unwrap_or_default();
            }
        }
        bake
    }
}
