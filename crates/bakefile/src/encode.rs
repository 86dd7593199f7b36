//! The writer: `Bake` → bytes of format 1.1, canonical layout (SPEC.md §3 and §7).

use std::io::{Seek, SeekFrom, Write};

use crate::error::BakeFileError;
use crate::field::{extend_f32_le, f32_to_f16_le, CHUNK};
use crate::layout::{
    align_up, Tag, BLKT_RECORD, BRDF_RECORD, GLSY_RECORD, HEADER_SIZE, MAGIC, NO_SECTION,
    OBJT_RECORD, PAYLOAD_ALIGNMENT, RFLD_HEADER, SCALAR_CPCA, SECTION_ENTRY_SIZE,
    SECTION_FLAG_REQUIRED, TABLE_HEADER_SIZE, VERSION_MAJOR, VERSION_MINOR,
};
use crate::meta::{
    hash_string, BlockJson, BrdfJson, CoverageJson, EnvJson, GlossyJson, MeshJson, MetaJson,
    ObjectJson, ShConvention, COLOUR_SPACE, FORMAT_NAME,
};
use crate::model::{
    Bake, BakeMeta, BrdfLobe, BrdfProjection, Coverage, EnvCoefficients, EnvPrecision,
    GlossyBrdfTable, ObjectBake, ReflectanceField, SampleKind, ScalarType, TransferBlock,
};

fn u32_of(x: usize, what: &str) -> Result<u32, BakeFileError> {
    u32::try_from(x).map_err(|_| BakeFileError::InvalidBake(format!("{what} exceeds u32")))
}

#[derive(Default)]
struct Buf(Vec<u8>);

impl Buf {
    fn u32(&mut self, v: u32) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn u64(&mut self, v: u64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn f64(&mut self, v: f64) {
        self.0.extend_from_slice(&v.to_le_bytes());
    }
    fn table_header(&mut self, count: usize, record_size: usize) -> Result<(), BakeFileError> {
        self.u32(u32_of(count, "table record count")?);
        self.u32(record_size as u32);
        self.u64(0);
        Ok(())
    }
}

/// A string pool under construction.
#[derive(Default)]
struct Strings(Vec<u8>);

impl Strings {
    fn add(&mut self, s: &str) -> Result<(u32, u32), BakeFileError> {
        let off = u32_of(self.0.len(), "string pool size")?;
        let len = u32_of(s.len(), "string length")?;
        self.0.extend_from_slice(s.as_bytes());
        u32_of(self.0.len(), "string pool size")?;
        Ok((off, len))
    }
}

enum Payload {
    Bytes(Vec<u8>),
    Block {
        object: usize,
        block: usize,
    },
    /// The `RFLD` section: its header and pixel indices, then the field's values.
    Field(Vec<u8>),
}

struct Planned {
    tag: Tag,
    payload: Payload,
    length: u64,
}

/// Encodes a bake into the bytes of a format-1.1 file, transfer coefficients stored as
/// `scalar`.
///
/// The output is canonical: the same `Bake` and `scalar` always give the same bytes, and
/// `encode(&decode(bytes)?, scalar)` reproduces a canonical file exactly.
///
/// # Errors
/// [`BakeFileError::InvalidBake`] / [`BakeFileError::NonFinite`] /
/// [`BakeFileError::InconsistentCounts`] when the bake breaks a rule of the format
/// (see [`Bake::validate`]), [`BakeFileError::OutOfF16Range`] when `scalar` is f16 and a value
/// rounds beyond ±65504.
pub fn encode(bake: &Bake, scalar: ScalarType) -> Result<Vec<u8>, BakeFileError> {
    let plan = Plan::new(bake, scalar)?;
    let total = usize::try_from(plan.file_size)
        .map_err(|_| BakeFileError::InvalidBake("file too large for this machine".into()))?;
    let mut out = std::io::Cursor::new(Vec::with_capacity(total));
    plan.write_to(&mut out)?;
    let out = out.into_inner();
    debug_assert_eq!(out.len(), total);
    Ok(out)
}

/// A file laid out but not yet written: the small payloads built, the large ones (transfer
/// blocks, a reflectance field's values) referenced in the bake, every offset known.
pub(crate) struct Plan<'b> {
    bake: &'b Bake,
    scalar: ScalarType,
    sections: Vec<Planned>,
    offsets: Vec<u64>,
    file_size: u64,
}

impl<'b> Plan<'b> {
    /// Validates `bake` and lays out its file.
    pub(crate) fn new(bake: &'b Bake, scalar: ScalarType) -> Result<Self, BakeFileError> {
        plan(bake, scalar)
    }
}

/// Validates `bake` and lays out its file (SPEC.md §2, §3; canonical layout, §7): the small
/// payloads built, every section in canonical order, every offset known.
fn plan(bake: &Bake, scalar: ScalarType) -> Result<Plan<'_>, BakeFileError> {
    bake.validate()?;
    let m = &bake.meta;
    if matches!(m.sample_kind, SampleKind::Pixel { .. }) && m.camera.is_none() {
        return Err(BakeFileError::InvalidBake(
            "a per-pixel bake of format 1.1 records its camera, and this one has none (a bake read from a 1.0 file: re-bake it)".into(),
        ));
    }
    let mut strings = Strings::default();
    let fixed_sections = 5
        + usize::from(bake.environment.is_some())
        + usize::from(!bake.brdfs.is_empty())
        + usize::from(!bake.glossy.is_empty());
    let binf = binf_bytes(m);
    let objects = ObjectTables::new(bake, scalar, fixed_sections, &mut strings)?;
    let envl = bake.environment.as_ref().map(envl_bytes);
    let brdf = brdf_bytes(&bake.brdfs, &mut strings)?;
    let glsy = glsy_bytes(&bake.glossy, &mut strings)?;
    let meta = meta_json(bake, scalar, objects.json);
    let meta_bytes = serde_json::to_vec_pretty(&meta)
        .map_err(|e| BakeFileError::Metadata(format!("cannot serialise: {e}")))?;

    // Section plan, in canonical order.
    let mut plan = vec![
        planned_bytes(Tag::BINF, binf),
        planned_bytes(Tag::STRS, strings.0),
        planned_bytes(Tag::OBJT, objects.objt.0),
        planned_bytes(Tag::BLKT, objects.blkt.0),
    ];
    if let Some(v) = envl {
        plan.push(planned_bytes(Tag::ENVL, v));
    }
    if let Some(v) = brdf {
        plan.push(planned_bytes(Tag::BRDF, v));
    }
    if let Some(v) = glsy {
        plan.push(planned_bytes(Tag::GLSY, v));
    }
    plan.push(planned_bytes(Tag::META, meta_bytes));
    debug_assert_eq!(plan.len(), fixed_sections);
    plan.extend(objects.xfer);
    plan.extend(
        objects
            .meshes
            .into_iter()
            .map(|v| planned_bytes(Tag::MESH, v)),
    );
    plan.extend(
        objects
            .coverages
            .into_iter()
            .map(|v| planned_bytes(Tag::CVRG, v)),
    );
    for (oi, o) in bake.objects.iter().enumerate() {
        if let Some(p) = &o.pass {
            plan.push(planned_bytes(Tag::PASS, bytes_of_pass(oi as u32, o, p)));
        }
    }
    if let Some(r) = &bake.reflectance {
        plan.push(planned_field(r, scalar)?);
    }
    u32_of(plan.len(), "section count")?;
    let (offsets, file_size) = lay_out(&plan)?;
    Ok(Plan {
        bake,
        scalar,
        sections: plan,
        offsets,
        file_size,
    })
}

/// A section whose payload is built in memory.
fn planned_bytes(tag: Tag, v: Vec<u8>) -> Planned {
    Planned {
        tag,
        length: v.len() as u64,
        payload: Payload::Bytes(v),
    }
}

/// The `RFLD` section (SPEC.md §3.14): its head built, its values left in the field.
fn planned_field(r: &ReflectanceField, scalar: ScalarType) -> Result<Planned, BakeFileError> {
    let head = reflectance_head(r);
    let length = (r.values.len() as u64)
        .checked_mul(scalar.size() as u64)
        .and_then(|v| v.checked_add(head.len() as u64))
        .ok_or_else(|| BakeFileError::InvalidBake("reflectance field too large".into()))?;
    Ok(Planned {
        tag: Tag::RFLD,
        payload: Payload::Field(head),
        length,
    })
}

/// Every payload's offset, each the first multiple of the payload alignment after the one
/// before it, the first after the header and table (SPEC.md §2); and the file's size.
fn lay_out(plan: &[Planned]) -> Result<(Vec<u64>, u64), BakeFileError> {
    let align = PAYLOAD_ALIGNMENT as u64;
    let table_end = (HEADER_SIZE + plan.len() * SECTION_ENTRY_SIZE) as u64;
    let mut cursor = table_end;
    let mut offsets = Vec::with_capacity(plan.len());
    for p in plan {
        let off = align_up(cursor, align);
        offsets.push(off);
        cursor = off
            .checked_add(p.length)
            .ok_or_else(|| BakeFileError::InvalidBake("file too large".into()))?;
    }
    Ok((offsets, cursor))
}

/// The `BINF` payload (SPEC.md §3.1).
fn binf_bytes(m: &BakeMeta) -> Vec<u8> {
    let mut binf = Buf::default();
    let (width, height) = match m.sample_kind {
        SampleKind::Vertex => (0, 0),
        SampleKind::Pixel { width, height } | SampleKind::Texel { width, height } => {
            (width, height)
        }
    };
    binf.u32(m.sample_kind.code());
    binf.u32(m.bounces);
    binf.u32(width);
    binf.u32(height);
    binf.u32(m.rays_per_point);
    binf.u32(m.shard.index);
    binf.u32(m.shard.count);
    binf.u32(0);
    binf.u64(m.seed);
    binf.0
}

/// The object and block tables (SPEC.md §3.3, §3.4) being built, with what they reference:
/// the `XFER`/`CPCA` sections, `MESH` and `CVRG` payloads, and the objects' JSON entries.
struct ObjectTables {
    objt: Buf,
    blkt: Buf,
    json: Vec<ObjectJson>,
    /// One section per block, in block order.
    xfer: Vec<Planned>,
    meshes: Vec<Vec<u8>>,
    coverages: Vec<Vec<u8>>,
}

/// Where the sections that objects reference start in the canonical order: after the
/// `fixed` ones come the blocks', then the meshes, then the coverages.
#[derive(Clone, Copy)]
struct SectionCounts {
    fixed: usize,
    blocks: usize,
    meshes: usize,
}

impl ObjectTables {
    /// The tables of `bake`'s objects, names added to `strings`.
    fn new(
        bake: &Bake,
        scalar: ScalarType,
        fixed_sections: usize,
        strings: &mut Strings,
    ) -> Result<Self, BakeFileError> {
        let counts = SectionCounts {
            fixed: fixed_sections,
            blocks: bake.objects.iter().map(|o| o.blocks.len()).sum(),
            meshes: bake.objects.iter().filter(|o| o.mesh.is_some()).count(),
        };
        let mut objt = Buf::default();
        objt.table_header(bake.objects.len(), OBJT_RECORD)?;
        let mut blkt = Buf::default();
        blkt.table_header(counts.blocks, BLKT_RECORD)?;
        let mut t = ObjectTables {
            objt,
            blkt,
            json: Vec::with_capacity(bake.objects.len()),
            xfer: Vec::with_capacity(counts.blocks),
            meshes: Vec::with_capacity(counts.meshes),
            coverages: Vec::new(),
        };
        for (oi, o) in bake.objects.iter().enumerate() {
            t.add_object(oi, o, scalar, counts, strings)?;
        }
        Ok(t)
    }

    /// Object `oi`'s record, its MESH and CVRG payloads, its blocks and its JSON entry.
    fn add_object(
        &mut self,
        oi: usize,
        o: &ObjectBake,
        scalar: ScalarType,
        counts: SectionCounts,
        strings: &mut Strings,
    ) -> Result<(), BakeFileError> {
        let (name_off, name_len) = strings.add(&o.name)?;
        let objt = &mut self.objt;
        objt.u32(name_off);
        objt.u32(name_len);
        objt.u64(o.geometry_hash);
        objt.u64(o.point_count);
        objt.u64(o.point_first);
        objt.u64(o.points_in_file);
        objt.u32(o.order);
        objt.u32(o.channels);
        objt.u32(u32_of(self.xfer.len(), "block count")?);
        objt.u32(u32_of(o.blocks.len(), "block count")?);
        let object_index = u32_of(oi, "object count")?;
        let mesh_json = match &o.mesh {
            Some(m) => {
                let section = u32_of(counts.fixed + counts.blocks + self.meshes.len(), "sections")?;
                self.meshes.push(bytes_of_mesh(object_index, m));
                Some(MeshJson {
                    section,
                    vertices: m.positions.len() as u32,
                    triangles: m.triangles.len() as u32,
                })
            }
            None => None,
        };
        let coverage_json = match &o.coverage {
            Some(c) => {
                let section = u32_of(
                    counts.fixed + counts.blocks + counts.meshes + self.coverages.len(),
                    "sections",
                )?;
                self.coverages.push(bytes_of_coverage(object_index, c));
                Some(CoverageJson {
                    section,
                    pixel_samples: c.pixel_samples,
                })
            }
            None => None,
        };
        self.objt
            .u32(mesh_json.as_ref().map_or(NO_SECTION, |m| m.section));
        self.objt
            .u32(coverage_json.as_ref().map_or(NO_SECTION, |c| c.section));
        let mut blocks_json = Vec::with_capacity(o.blocks.len());
        for (bi, b) in o.blocks.iter().enumerate() {
            blocks_json.push(self.add_block(oi, bi, o, b, scalar, counts.fixed)?);
        }
        self.json.push(ObjectJson {
            name: o.name.clone(),
            geometry_hash: hash_string(o.geometry_hash),
            point_count: o.point_count,
            point_first: o.point_first,
            points_in_file: o.points_in_file,
            order: o.order,
            channels: o.channels,
            blocks: blocks_json,
            mesh: mesh_json,
            coverage: coverage_json,
            material: o.material.clone(),
        });
        Ok(())
    }

    /// Block `bi` of object `oi`: its `BLKT` record and its section — an `XFER` referencing
    /// the coefficients in the bake, or a built `CPCA` payload (SPEC.md §3.13).
    fn add_block(
        &mut self,
        oi: usize,
        bi: usize,
        o: &ObjectBake,
        b: &TransferBlock,
        scalar: ScalarType,
        fixed_sections: usize,
    ) -> Result<BlockJson, BakeFileError> {
        let section = u32_of(fixed_sections + self.xfer.len(), "section count")?;
        let cpca_bytes = b.cpca.as_ref().map(|c| bytes_of_cpca(oi as u32, c));
        let length = match &cpca_bytes {
            Some(v) => v.len() as u64,
            None => (b.data.len() as u64)
                .checked_mul(scalar.size() as u64)
                .ok_or_else(|| BakeFileError::InvalidBake("block too large".into()))?,
        };
        let blkt = &mut self.blkt;
        blkt.u32(u32_of(oi, "object count")?);
        blkt.u32(b.kind.code());
        blkt.u32(b.kind.bounces());
        blkt.u32(o.channels);
        blkt.u32(o.order);
        blkt.u32(if cpca_bytes.is_some() {
            SCALAR_CPCA
        } else {
            scalar.code()
        });
        blkt.u64(o.points_in_file);
        blkt.u32(section);
        blkt.u32(0);
        blkt.u64(length);
        self.xfer.push(match cpca_bytes {
            Some(v) => Planned {
                tag: Tag::CPCA,
                payload: Payload::Bytes(v),
                length,
            },
            None => Planned {
                tag: Tag::XFER,
                payload: Payload::Block {
                    object: oi,
                    block: bi,
                },
                length,
            },
        });
        Ok(BlockJson {
            kind: b.kind.name().to_owned(),
            bounces: b.kind.bounces(),
            section,
        })
    }
}

/// The `ENVL` payload (SPEC.md §3.6).
fn envl_bytes(env: &EnvCoefficients) -> Vec<u8> {
    let mut b = Buf::default();
    b.u32(env.order);
    b.u32(3);
    b.u32(env.precision.code());
    b.u32(0);
    for &v in &env.values {
        match env.precision {
            EnvPrecision::F32 => b.0.extend_from_slice(&(v as f32).to_le_bytes()),
            EnvPrecision::F64 => b.f64(v),
        }
    }
    b.0
}

/// The `BRDF` payload (SPEC.md §3.7), `None` without projections; material names added to
/// `strings`.
fn brdf_bytes(
    brdfs: &[BrdfProjection],
    strings: &mut Strings,
) -> Result<Option<Vec<u8>>, BakeFileError> {
    if brdfs.is_empty() {
        return Ok(None);
    }
    let mut b = Buf::default();
    b.table_header(brdfs.len(), BRDF_RECORD)?;
    let mut values_off = (TABLE_HEADER_SIZE + brdfs.len() * BRDF_RECORD) as u64;
    for p in brdfs {
        let (off, len) = strings.add(&p.material)?;
        let (code, exponent) = match p.lobe {
            BrdfLobe::ClampedCosine => (1, 0.0),
            BrdfLobe::Phong { exponent } => (2, exponent),
        };
        b.u32(off);
        b.u32(len);
        b.u32(code);
        b.u32(p.order);
        b.f64(exponent);
        b.u64(values_off);
        values_off += 8 * p.values.len() as u64;
    }
    for p in brdfs {
        p.values.iter().for_each(|&v| b.f64(v));
    }
    Ok(Some(b.0))
}

/// The `GLSY` payload (SPEC.md §3.8), `None` without tables; material names added to
/// `strings`.
fn glsy_bytes(
    glossy: &[GlossyBrdfTable],
    strings: &mut Strings,
) -> Result<Option<Vec<u8>>, BakeFileError> {
    if glossy.is_empty() {
        return Ok(None);
    }
    let mut b = Buf::default();
    b.table_header(glossy.len(), GLSY_RECORD)?;
    let mut off = (TABLE_HEADER_SIZE + glossy.len() * GLSY_RECORD) as u64;
    for g in glossy {
        let (name_off, name_len) = strings.add(&g.material)?;
        b.u32(name_off);
        b.u32(name_len);
        b.u32(u32_of(g.elevations.len(), "elevation count")?);
        b.u32(g.order);
        b.u64(off);
        off += 8 * g.elevations.len() as u64;
        b.u64(off);
        off += 8 * g.values.len() as u64;
        b.u64(off);
        off += 8 * g.projection_error.len() as u64;
    }
    for g in glossy {
        g.elevations.iter().for_each(|&v| b.f64(v));
        g.values.iter().for_each(|&v| b.f64(v));
        g.projection_error.iter().for_each(|&v| b.f64(v));
    }
    Ok(Some(b.0))
}

/// The `META` JSON (SPEC.md §3.9) of `bake` stored as `scalar`, with the objects' entries.
fn meta_json(bake: &Bake, scalar: ScalarType, objects: Vec<ObjectJson>) -> MetaJson {
    let m = &bake.meta;
    MetaJson {
        format: FORMAT_NAME.to_owned(),
        format_version: [VERSION_MAJOR, VERSION_MINOR],
        sh: ShConvention::current(),
        colour_space: COLOUR_SPACE.to_owned(),
        scalar_type: scalar,
        sample_kind: m.sample_kind,
        rays_per_point: m.rays_per_point,
        bounces: m.bounces,
        seed: m.seed,
        shard: m.shard,
        tool: m.tool.clone(),
        camera: m.camera.clone(),
        settings: m.settings.clone(),
        decisions: m.decisions.clone(),
        ray_stats: m.ray_stats.clone(),
        pass: m.pass.clone(),
        objects,
        environment: bake.environment.as_ref().map(|e| EnvJson {
            order: e.order,
            precision: e.precision,
        }),
        brdfs: bake
            .brdfs
            .iter()
            .map(|p| BrdfJson {
                material: p.material.clone(),
                lobe: match p.lobe {
                    BrdfLobe::ClampedCosine => "clamped-cosine".into(),
                    BrdfLobe::Phong { .. } => "phong".into(),
                },
                exponent: match p.lobe {
                    BrdfLobe::ClampedCosine => None,
                    BrdfLobe::Phong { exponent } => Some(exponent),
                },
                order: p.order,
            })
            .collect(),
        glossy: bake
            .glossy
            .iter()
            .map(|g| GlossyJson {
                material: g.material.clone(),
                elevations: g.elevations.len() as u64,
                order: g.order,
            })
            .collect(),
    }
}

impl Plan<'_> {
    /// Writes the file to `w`, which starts empty at position 0: a zeroed header and section
    /// table, then every payload in order (converted to the file's scalar type a chunk at a
    /// time, its CRC-32 computed as it goes, alignment padding zero), then the header and
    /// table over the zeros. No payload is held whole beyond what the bake holds, so writing a
    /// reflectance field does not copy it.
    ///
    /// # Errors
    /// I/O errors of `w`; [`BakeFileError::OutOfF16Range`] when a value does not fit f16.
    pub(crate) fn write_to<W: Write + Seek>(&self, w: &mut W) -> Result<(), BakeFileError> {
        let scalar = self.scalar;
        let table_end = HEADER_SIZE + self.sections.len() * SECTION_ENTRY_SIZE;
        let mut head = vec![0u8; table_end];
        w.write_all(&head)?;
        let mut pos = table_end as u64;
        let mut buf = Vec::new();
        let mut values = Vec::new();
        for (i, (p, &off)) in self.sections.iter().zip(&self.offsets).enumerate() {
            // Padding: fewer than PAYLOAD_ALIGNMENT zeros.
            w.write_all(&[0u8; PAYLOAD_ALIGNMENT][..(off - pos) as usize])?;
            let mut crc = crc32fast::Hasher::new();
            let mut written = 0u64;
            let mut out = |bytes: &[u8]| -> std::io::Result<()> {
                for piece in bytes.chunks(WRITE_PIECE) {
                    crc.update(piece);
                    w.write_all(piece)?;
                }
                written += bytes.len() as u64;
                Ok(())
            };
            match &p.payload {
                Payload::Bytes(v) => out(v)?,
                Payload::Block { object, block } => {
                    let data = &self.bake.objects[*object].blocks[*block].data;
                    for (ci, chunk) in data.chunks(CHUNK).enumerate() {
                        buf.clear();
                        match scalar {
                            ScalarType::F32 => extend_f32_le(&mut buf, chunk),
                            ScalarType::F16 => f32_to_f16_le(&mut buf, chunk, ci * CHUNK, || {
                                format!("object {object} block {block}")
                            })?,
                        }
                        out(&buf)?;
                    }
                }
                Payload::Field(field_head) => {
                    out(field_head)?;
                    let v = &self
                        .bake
                        .reflectance
                        .as_ref()
                        .expect("planned from the field")
                        .values;
                    if v.scalar() == scalar {
                        out(v.as_le_bytes())?;
                    } else {
                        values.resize(CHUNK.min(v.len()), 0.0f32);
                        for start in (0..v.len()).step_by(CHUNK) {
                            let n = CHUNK.min(v.len() - start);
                            v.read_into(start, &mut values[..n]);
                            buf.clear();
                            match scalar {
                                ScalarType::F32 => extend_f32_le(&mut buf, &values[..n]),
                                ScalarType::F16 => {
                                    f32_to_f16_le(&mut buf, &values[..n], start, || "RFLD".into())?;
                                }
                            }
                            out(&buf)?;
                        }
                    }
                }
            }
            debug_assert_eq!(written, p.length, "{}", p.tag);
            let e = HEADER_SIZE + i * SECTION_ENTRY_SIZE;
            let entry = &mut head[e..e + SECTION_ENTRY_SIZE];
            entry[0..4].copy_from_slice(&p.tag.0);
            // MESH and CVRG (1.1) are not REQUIRED: a 1.0 reader skips them.
            let flags = if [Tag::MESH, Tag::CVRG].contains(&p.tag) {
                0
            } else {
                SECTION_FLAG_REQUIRED
            };
            entry[4..8].copy_from_slice(&flags.to_le_bytes());
            entry[8..16].copy_from_slice(&off.to_le_bytes());
            entry[16..24].copy_from_slice(&p.length.to_le_bytes());
            entry[24..28].copy_from_slice(&crc.finalize().to_le_bytes());
            pos = off + p.length;
        }
        debug_assert_eq!(pos, self.file_size);

        // Header.
        let section_count = self.sections.len() as u32;
        let h = &mut head[..HEADER_SIZE];
        h[0..8].copy_from_slice(&MAGIC);
        h[8..12].copy_from_slice(&VERSION_MAJOR.to_le_bytes());
        h[12..16].copy_from_slice(&VERSION_MINOR.to_le_bytes());
        h[16..20].copy_from_slice(&(HEADER_SIZE as u32).to_le_bytes());
        h[20..24].copy_from_slice(&0u32.to_le_bytes());
        h[24..32].copy_from_slice(&self.file_size.to_le_bytes());
        h[32..40].copy_from_slice(&(HEADER_SIZE as u64).to_le_bytes());
        h[40..44].copy_from_slice(&section_count.to_le_bytes());
        h[44..48].copy_from_slice(&(SECTION_ENTRY_SIZE as u32).to_le_bytes());
        h[48..52].copy_from_slice(&(PAYLOAD_ALIGNMENT as u32).to_le_bytes());
        h[52..56].copy_from_slice(&scalar.code().to_le_bytes());
        let crc = header_crc(&head[..HEADER_SIZE], &head[HEADER_SIZE..]);
        head[60..64].copy_from_slice(&crc.to_le_bytes());
        w.seek(SeekFrom::Start(0))?;
        w.write_all(&head)?;
        w.seek(SeekFrom::Start(self.file_size))?;
        Ok(())
    }
}

/// Bytes hashed and written per step (so the CRC reads them while they are in cache).
const WRITE_PIECE: usize = 1 << 20;

/// The payload of a CPCA section (SPEC.md §3.13); counts were checked by `validate`.
fn bytes_of_cpca(object: u32, c: &crate::model::Cpca) -> Vec<u8> {
    let mut b = Buf::default();
    b.u32(object);
    b.u32(c.clusters);
    b.u32(c.components);
    b.u32(c.dimension);
    b.u64(c.cluster_of.len() as u64);
    b.f64(c.rel_error);
    for &v in &c.centres {
        b.0.extend_from_slice(&v.to_le_bytes());
    }
    for &k in &c.cluster_of {
        b.u32(k);
    }
    for &v in &c.weights {
        b.0.extend_from_slice(&v.to_le_bytes());
    }
    b.0
}

/// The payload of a CVRG section (SPEC.md §3.11).
fn bytes_of_coverage(object: u32, c: &Coverage) -> Vec<u8> {
    let mut b = Buf::default();
    b.u32(object);
    b.u32(c.pixel_samples);
    b.u64(c.hits.len() as u64);
    c.hits.iter().for_each(|&h| b.u32(h));
    b.0
}

/// The payload of a MESH section (SPEC.md §3.10); counts were checked by `validate`.
fn bytes_of_mesh(object: u32, m: &crate::model::MeshGeometry) -> Vec<u8> {
    let mut b = Buf::default();
    b.0.reserve(16 + 24 * m.positions.len() + 12 * m.triangles.len());
    b.u32(object);
    b.u32(m.positions.len() as u32);
    b.u32(m.triangles.len() as u32);
    b.u32(0);
    for v in m.positions.iter().chain(&m.normals) {
        v.iter()
            .for_each(|x| b.0.extend_from_slice(&x.to_le_bytes()));
    }
    for t in &m.triangles {
        t.iter().for_each(|&i| b.u32(i));
    }
    b.0
}

/// The payload of a PASS section (SPEC.md §3.12); lengths were checked by `validate`.
fn bytes_of_pass(
    object: u32,
    o: &crate::model::ObjectBake,
    p: &crate::model::PassState,
) -> Vec<u8> {
    let mut b = Buf::default();
    let flags = u32::from(p.partial.is_some())
        | u32::from(p.totals.is_some()) << 1
        | u32::from(p.hit_counts.is_some()) << 2
        | u32::from(p.records) << 3;
    b.u32(object);
    b.u32(p.levels.len() as u32);
    b.u32(o.order);
    b.u32(flags);
    b.u64(o.point_count);
    b.u64(o.points_in_file);
    b.u64(p.hits.len() as u64);
    b.u64(0);
    for &v in p.totals.iter().flatten() {
        b.f64(v);
    }
    for &v in p.levels.iter().flatten().chain(p.partial.iter().flatten()) {
        b.0.extend_from_slice(&v.to_le_bytes());
    }
    for &c in p.hit_counts.iter().flatten() {
        b.u32(c);
    }
    for h in &p.hits {
        b.u32(h.mesh);
        b.u32(h.tri);
        b.0.extend_from_slice(&h.u.to_le_bytes());
        b.0.extend_from_slice(&h.v.to_le_bytes());
    }
    b.0
}

/// CRC-32 of header bytes `[0, 60)` followed by the section table.
pub(crate) fn header_crc(header: &[u8], table: &[u8]) -> u32 {
    let mut h = crc32fast::Hasher::new();
    h.update(&header[..60]);
    h.update(table);
    h.finalize()
}

/// The start of the `RFLD` payload (SPEC §3.14): header and pixel indices; the values follow.
fn reflectance_head(r: &ReflectanceField) -> Vec<u8> {
    let mut b = Buf::default();
    b.u32(r.directions[0]);
    b.u32(r.directions[1]);
    b.u32(3);
    b.u32(0);
    b.u64(r.pixels.len() as u64);
    b.u64(0);
    debug_assert_eq!(b.0.len(), RFLD_HEADER);
    for &p in &r.pixels {
        b.u32(p);
    }
    b.0
}
