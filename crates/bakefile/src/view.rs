//! The reader: validates a whole file once, then lends coefficient arrays in place.
//!
//! [`BakeView::new`] runs the checks of SPEC.md §4 in the order of §4.1, one step per rule
//! or section: the header and section table (`read_header`, rules 1–7), the binary
//! sections (`read_objects`, `read_geometry`, `read_scene`, `read_pass`: rules 8–10), the
//! metadata (`read_meta`, rule 11), then [`Bake::validate`]'s rules on the decoded structure.

use std::borrow::Cow;

use half::f16;

use crate::error::BakeFileError;
use crate::field::FieldValues;
use crate::located::{BakeInfo, BinarySections, Cpcas, FieldLocation, ObjectInfo, SectionEntry};
use crate::meta::MetaJson;
use crate::model::{
    Bake, BakeMeta, BrdfProjection, Coverage, Cpca, EnvCoefficients, GlossyBrdfTable, MeshGeometry,
    ObjectBake, PassState, ReflectanceField, ScalarType, TransferBlock,
};
use crate::read_bytes::Payloads;
use crate::read_geometry::{check_coverage_masks, read_meshes_and_coverages};
use crate::read_header::{
    check_file_size, check_header_fields, check_magic, check_size_and_version, find_sections,
    locate_section_table, read_section_table, FoundSections,
};
use crate::read_meta::{check_agreement, read_meta};
use crate::read_objects::{read_binf, read_objects};
use crate::read_pass::read_passes;
use crate::read_scene::{read_brdfs, read_environment, read_glossy, read_reflectance};

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
    cpcas: Cpcas,
    /// Per object, its material binding (1.2), from the metadata.
    materials: Vec<Option<crate::MaterialBinding>>,
    environment: Option<EnvCoefficients>,
    brdfs: Vec<BrdfProjection>,
    glossy: Vec<GlossyBrdfTable>,
    reflectance: Option<FieldLocation>,
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

/// SPEC.md §4.1 step 1: one pass over the binary sections, rules 8–10 — `BINF`; `OBJT` and
/// `BLKT` with each block's `XFER` or `CPCA`; `MESH` and `CVRG`; `RFLD`; `ENVL`; `BRDF`;
/// `GLSY`; `PASS` — each length just before the structure it bounds.
fn read_binary_sections(
    file: Payloads<'_, '_>,
    found: &FoundSections,
    version: (u32, u32),
    scalar: ScalarType,
) -> Result<BinarySections, BakeFileError> {
    let strs = file.get(found.strs);
    let info = read_binf(file.get(found.binf))?;
    let (objects, cpcas) = read_objects(
        file,
        strs,
        file.get(found.objt),
        file.get(found.blkt),
        scalar,
    )?;
    let (meshes, coverages) = read_meshes_and_coverages(file, &objects)?;
    let reflectance = found
        .rfld
        .map(|i| read_reflectance(file.get(i), scalar, file.sections[i].offset as usize))
        .transpose()?;
    let environment = found
        .envl
        .map(|i| read_environment(file.get(i)))
        .transpose()?;
    let brdfs = found
        .brdf
        .map(|i| read_brdfs(file.get(i), strs))
        .transpose()?
        .unwrap_or_default();
    let glossy = found
        .glsy
        .map(|i| read_glossy(file.get(i), strs))
        .transpose()?
        .unwrap_or_default();
    let passes = read_passes(file, &objects)?;
    Ok(BinarySections {
        version,
        scalar,
        info,
        objects,
        cpcas,
        meshes,
        coverages,
        reflectance,
        environment,
        brdfs,
        glossy,
        passes,
    })
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
    fn read(bytes: &'a [u8], rule: &mut u8) -> Result<Self, BakeFileError> {
        // Magic, version, size: in this order, so that every prefix of a valid file is
        // reported as Truncated and every future major version as UnsupportedVersion.
        check_magic(bytes)?;
        *rule = 2;
        let version = check_size_and_version(bytes)?;
        *rule = 3;
        check_file_size(bytes)?;
        *rule = 4;
        let table = locate_section_table(bytes)?;
        // The header is now known to be what the writer wrote.
        *rule = 5;
        let (alignment, scalar) = check_header_fields(bytes)?;
        *rule = 6;
        let sections = read_section_table(bytes, &table, alignment)?;
        *rule = 7;
        let found = find_sections(&sections)?;

        // Each table and payload: lengths before use (rule 8), then cross-references and
        // counts (rule 9); values' finiteness is rule 10 wherever it is checked.
        *rule = 9;
        let file = Payloads {
            bytes,
            sections: &sections,
        };
        let binary = read_binary_sections(file, &found, version, scalar)?;

        // The coverage is the object's mask: no transfer where no sample hit it.
        *rule = 10;
        check_coverage_masks(
            bytes,
            scalar,
            &binary.objects,
            &binary.coverages,
            &binary.cpcas,
        )?;

        // META, and its agreement with everything above.
        *rule = 11;
        let json = read_meta(file.get(found.meta), version.1)?;
        check_agreement(&json, &binary)?;

        let view = Self::assemble(bytes, sections, binary, json);
        // The semantic rules (unique names, shard ranges, ...), checked on a skeleton
        // without the coefficient data.
        view.skeleton().validate_structure()?;
        Ok(view)
    }

    /// The view of a file whose binary sections and metadata were read and agree.
    fn assemble(
        bytes: &'a [u8],
        sections: Vec<SectionEntry>,
        binary: BinarySections,
        json: MetaJson,
    ) -> Self {
        let BinarySections {
            version,
            scalar,
            info:
                BakeInfo {
                    sample,
                    bounces,
                    rays_per_point,
                    shard,
                    seed,
                },
            objects,
            cpcas,
            meshes,
            coverages,
            reflectance,
            environment,
            brdfs,
            glossy,
            passes,
        } = binary;
        BakeView {
            bytes,
            version,
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
        }
    }

    /// The skeleton of the bake: everything but the transfer coefficients and the field's
    /// values.
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
