//! Byte-level constants of format version 1.2 (the binary layout of 1.1): every number here is in SPEC.md.

/// The 8 magic bytes that open every bake file.
pub const MAGIC: [u8; 8] = *b"PRTBAKE\0";
/// Major format version written and read by this crate. Readers refuse any other.
pub const VERSION_MAJOR: u32 = 1;
/// Minor format version written by this crate. Readers accept any minor of their major.
pub const VERSION_MINOR: u32 = 3;
/// Size of the file header in bytes.
pub const HEADER_SIZE: usize = 64;
/// Size of one section-table entry in bytes.
pub const SECTION_ENTRY_SIZE: usize = 32;
/// Alignment of every section payload, in bytes from the start of the file.
pub const PAYLOAD_ALIGNMENT: usize = 64;
/// Size of the header that opens the OBJT, BLKT, BRDF and GLSY table sections.
pub(crate) const TABLE_HEADER_SIZE: usize = 16;
/// Minimum size of the BINF section.
pub(crate) const BINF_SIZE: usize = 40;
/// Size of an OBJT record written by this crate (1.1: with the mesh and coverage sections).
pub(crate) const OBJT_RECORD: usize = 64;
/// Size of a 1.0 OBJT record, the smallest a reader accepts (no mesh or coverage fields).
pub(crate) const OBJT_RECORD_V10: usize = 56;
/// `OBJT.mesh_section` / `coverage_section` value for "none".
pub(crate) const NO_SECTION: u32 = u32::MAX;
/// Size of the header of a MESH section.
pub(crate) const MESH_HEADER: usize = 16;
/// Size of the header of a CVRG section.
pub(crate) const CVRG_HEADER: usize = 16;
/// Size of the header of an RFLD section.
pub(crate) const RFLD_HEADER: usize = 32;
/// Size of the header of a CPCA section.
pub(crate) const CPCA_HEADER: usize = 32;
/// `BLKT.scalar_type` of a block stored as a CPCA section.
pub(crate) const SCALAR_CPCA: u32 = 3;
/// Size of the header of a PASS section.
pub(crate) const PASS_HEADER: usize = 48;
/// Size of a BLKT record.
pub(crate) const BLKT_RECORD: usize = 48;
/// Size of the ENVL header.
pub(crate) const ENVL_HEADER: usize = 16;
/// Size of a BRDF record.
pub(crate) const BRDF_RECORD: usize = 32;
/// Size of a GLSY record.
pub(crate) const GLSY_RECORD: usize = 40;

/// Section flag bit 0: a reader that does not know the section's tag must refuse the file.
pub const SECTION_FLAG_REQUIRED: u32 = 1;
/// Flag bits (header or section) that a reader must understand: it refuses a file that sets
/// one it does not know. Bits 16–31 are optional and ignored when unknown.
pub const MUST_UNDERSTAND_FLAGS: u32 = 0x0000_ffff;

/// A section tag: four ASCII bytes, stored in file order (read as a little-endian u32).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Tag(pub [u8; 4]);

impl Tag {
    /// Bake info: sample kind, image size, rays, bounces, shard, seed.
    pub const BINF: Tag = Tag(*b"BINF");
    /// String pool (UTF-8, referenced by offset and length).
    pub const STRS: Tag = Tag(*b"STRS");
    /// Object table.
    pub const OBJT: Tag = Tag(*b"OBJT");
    /// Transfer-block table.
    pub const BLKT: Tag = Tag(*b"BLKT");
    /// Metadata JSON.
    pub const META: Tag = Tag(*b"META");
    /// Environment SH coefficients.
    pub const ENVL: Tag = Tag(*b"ENVL");
    /// Zonal BRDF projections.
    pub const BRDF: Tag = Tag(*b"BRDF");
    /// Tabulated glossy BRDF projections.
    pub const GLSY: Tag = Tag(*b"GLSY");
    /// One transfer block's coefficients.
    pub const XFER: Tag = Tag(*b"XFER");
    /// One object's mesh: positions, normals, triangles (1.1).
    pub const MESH: Tag = Tag(*b"MESH");
    /// One object's per-pixel coverage (1.1).
    pub const CVRG: Tag = Tag(*b"CVRG");
    /// One object's state between passes of a distributed bounced bake (1.1, intermediate
    /// files only).
    pub const PASS: Tag = Tag(*b"PASS");
    /// One transfer block compressed by clustered PCA (1.1), in place of its XFER.
    pub const CPCA: Tag = Tag(*b"CPCA");
    /// A sampled reflectance field (1.1, `prt reflectance`).
    pub const RFLD: Tag = Tag(*b"RFLD");

    /// The tag as the little-endian u32 stored in the section table.
    #[must_use]
    pub const fn as_u32(self) -> u32 {
        u32::from_le_bytes(self.0)
    }

    /// Is this one of the tags of format 1.1?
    #[must_use]
    pub fn is_known(self) -> bool {
        [
            Tag::BINF,
            Tag::STRS,
            Tag::OBJT,
            Tag::BLKT,
            Tag::META,
            Tag::ENVL,
            Tag::BRDF,
            Tag::GLSY,
            Tag::XFER,
            Tag::MESH,
            Tag::CVRG,
            Tag::PASS,
            Tag::CPCA,
            Tag::RFLD,
        ]
        .contains(&self)
    }
}

impl std::fmt::Display for Tag {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.0.iter().all(|b| b.is_ascii_alphanumeric()) {
            write!(f, "{}", String::from_utf8_lossy(&self.0))
        } else {
            write!(f, "0x{:08x}", self.as_u32())
        }
    }
}

/// Rounds `x` up to a multiple of `align` (a power of two).
pub(crate) const fn align_up(x: u64, align: u64) -> u64 {
    (x + align - 1) & !(align - 1)
}
