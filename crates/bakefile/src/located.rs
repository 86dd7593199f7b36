//! What the reader finds in a file's header and binary sections (SPEC.md §2, §3) before it
//! reads the metadata: the section table, the objects and where their blocks lie, the
//! reflectance field's place, and the decoded small sections.

use std::collections::BTreeMap;

use crate::layout::Tag;
use crate::model::{
    BrdfProjection, Coverage, Cpca, EnvCoefficients, GlossyBrdfTable, MeshGeometry, PassState,
    SampleKind, ScalarType, ShardInfo, TransferKind,
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

/// A validated `RFLD` section (SPEC.md §3.14): its structure, and where its values lie in the
/// file (they are checked in place and never decoded by the view).
#[derive(Debug, Clone)]
pub(crate) struct FieldLocation {
    pub(crate) directions: [u32; 2],
    pub(crate) pixels: Vec<u32>,
    /// Byte range of the values in the file.
    pub(crate) values: std::ops::Range<usize>,
}

/// The clustered-PCA blocks of a file (SPEC.md §3.13), by (object, block within the object).
pub(crate) type Cpcas = BTreeMap<(usize, usize), Cpca>;

/// Per object, in object order, what it has of an optional section.
pub(crate) type PerObject<T> = Vec<Option<T>>;

/// The `BINF` section's fields (SPEC.md §3.1).
#[derive(Debug, Clone, Copy)]
pub(crate) struct BakeInfo {
    pub(crate) sample: SampleKind,
    pub(crate) bounces: u32,
    pub(crate) rays_per_point: u32,
    pub(crate) shard: ShardInfo,
    pub(crate) seed: u64,
}

/// Everything the header and the binary sections say, read under SPEC.md §4 rules 1–10: what
/// the metadata must agree with (rule 11).
#[derive(Debug)]
pub(crate) struct BinarySections {
    /// Format version `(major, minor)` from the header.
    pub(crate) version: (u32, u32),
    /// The header's scalar type.
    pub(crate) scalar: ScalarType,
    pub(crate) info: BakeInfo,
    pub(crate) objects: Vec<ObjectInfo>,
    pub(crate) cpcas: Cpcas,
    /// Per object, its MESH (1.1).
    pub(crate) meshes: PerObject<MeshGeometry>,
    /// Per object, its CVRG (1.1).
    pub(crate) coverages: PerObject<Coverage>,
    pub(crate) reflectance: Option<FieldLocation>,
    pub(crate) environment: Option<EnvCoefficients>,
    pub(crate) brdfs: Vec<BrdfProjection>,
    pub(crate) glossy: Vec<GlossyBrdfTable>,
    /// Per object, its PASS (1.1).
    pub(crate) passes: PerObject<PassState>,
}
