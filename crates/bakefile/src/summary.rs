//! A compact description of a bake for `prt inspect` (human-readable or `--json`).

use serde::Serialize;

use crate::meta::hash_string;
use crate::model::{
    Bake, BrdfLobe, CameraInfo, Decision, EnvPrecision, SampleKind, ScalarType, ShardInfo, ToolInfo,
};
use crate::view::{BakeView, Coefficients};

/// What the file itself says (present when the summary was made from a file).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileSummary {
    /// Format version `[major, minor]`.
    pub version: [u32; 2],
    /// Storage type of the transfer coefficients.
    pub scalar_type: ScalarType,
    /// File size in bytes.
    pub file_size: u64,
    /// The section table: `(tag, offset, length)`.
    pub sections: Vec<SectionSummary>,
}

/// One section-table entry.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SectionSummary {
    /// Tag, e.g. `XFER`.
    pub tag: String,
    /// Byte offset.
    pub offset: u64,
    /// Byte length.
    pub length: u64,
}

/// Statistics of one transfer block.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockSummary {
    /// Kind name, e.g. `shadowed-diffuse`.
    pub kind: String,
    /// Bounce count (interreflected diffuse only, else 0).
    pub bounces: u32,
    /// Number of scalars.
    pub scalars: u64,
    /// Smallest finite value (`None` when there is none).
    pub min: Option<f32>,
    /// Largest finite value (`None` when there is none).
    pub max: Option<f32>,
    /// Number of NaNs (always 0 in a file: the reader refuses them).
    pub nan_count: u64,
    /// Number of infinities (always 0 in a file).
    pub inf_count: u64,
    /// How the block is stored: `None` as plain coefficients (the file's scalar type), else
    /// its clustered PCA (SPEC.md §3.13); the statistics are of its reconstruction.
    pub cpca: Option<CpcaSummary>,
}

/// A block stored as clustered PCA.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CpcaSummary {
    /// Clusters `K`.
    pub clusters: u32,
    /// Basis vectors per cluster `M`.
    pub components: u32,
    /// Relative L2 error of the approximation, as the compressor measured it.
    pub rel_error: f64,
}

/// A reflectance field (SPEC.md §3.14).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FieldSummary {
    /// Lat-long directions `[W, H]` per pixel.
    pub directions: [u32; 2],
    /// Pixels held (those a surface covers).
    pub pixels: u64,
    /// Scalars stored (`3 · W · H · pixels`).
    pub scalars: u64,
}

/// One object.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ObjectSummary {
    /// Object name.
    pub name: String,
    /// Geometry hash as `0x` and 16 hex digits.
    pub geometry_hash: String,
    /// Points of the whole object.
    pub point_count: u64,
    /// First point held.
    pub point_first: u64,
    /// Points held.
    pub points_in_file: u64,
    /// SH order (band count).
    pub order: u32,
    /// 1 or 3.
    pub channels: u32,
    /// Its blocks.
    pub blocks: Vec<BlockSummary>,
    /// What its rays met, when the bake recorded it.
    pub ray_stats: Option<crate::model::RayStats>,
    /// Its mesh (format 1.1), when the file carries it.
    pub mesh: Option<MeshSummary>,
    /// Its per-pixel coverage (format 1.1 per-pixel bakes).
    pub coverage: Option<CoverageSummary>,
    /// The material it was baked for (format 1.2), when the file says.
    pub material: Option<crate::MaterialBinding>,
}

/// An object's mesh, in counts.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct MeshSummary {
    /// Vertices.
    pub vertices: u64,
    /// Triangles.
    pub triangles: u64,
}

/// An object's coverage of the pixels held.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CoverageSummary {
    /// Footprint samples per pixel.
    pub pixel_samples: u32,
    /// Pixels it covers at least partly (hits > 0).
    pub covered_points: u64,
    /// Its mean coverage over the pixels held (Σ hits / (K × points)).
    pub mean_coverage: f64,
}

/// Summary of a bake: header facts, per-object orders, kinds, counts and value statistics.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Summary {
    /// File facts, when summarised from a file ([`BakeView::summary`]).
    pub file: Option<FileSummary>,
    /// Vertex or pixel bake.
    pub sample_kind: SampleKind,
    /// Rays per point.
    pub rays_per_point: u32,
    /// Bounces.
    pub bounces: u32,
    /// Seed; in JSON a decimal string, as in the file (exact where JSON numbers are doubles).
    #[serde(serialize_with = "seed_string")]
    pub seed: u64,
    /// Shard.
    pub shard: ShardInfo,
    /// Tool.
    pub tool: ToolInfo,
    /// Decisions log.
    pub decisions: Vec<Decision>,
    /// Objects.
    pub objects: Vec<ObjectSummary>,
    /// Environment `(order, precision)`, if present.
    pub environment: Option<(u32, EnvPrecision)>,
    /// Zonal BRDF projections: `(material, lobe, order)`.
    pub brdfs: Vec<(String, String, u32)>,
    /// Glossy tables: `(material, order, elevation count)`.
    pub glossy: Vec<(String, u32, usize)>,
    /// The camera of a per-pixel bake (format 1.1).
    pub camera: Option<CameraInfo>,
    /// Intermediate files of a distributed bake: which pass.
    pub pass: Option<crate::model::PassInfo>,
    /// The reflectance field, when the file holds one.
    pub reflectance: Option<FieldSummary>,
}

fn seed_string<S: serde::Serializer>(seed: &u64, s: S) -> Result<S::Ok, S::Error> {
    s.serialize_str(&seed.to_string())
}

fn block_stats(values: impl Iterator<Item = f32>) -> (u64, Option<f32>, Option<f32>, u64, u64) {
    let (mut n, mut min, mut max, mut nan, mut inf) = (0u64, None::<f32>, None::<f32>, 0, 0);
    for v in values {
        n += 1;
        if v.is_nan() {
            nan += 1;
        } else if v.is_infinite() {
            inf += 1;
        } else {
            min = Some(min.map_or(v, |m| m.min(v)));
            max = Some(max.map_or(v, |m| m.max(v)));
        }
    }
    (n, min, max, nan, inf)
}

fn lobe_name(l: BrdfLobe) -> String {
    match l {
        BrdfLobe::ClampedCosine => "clamped-cosine".into(),
        BrdfLobe::Phong { exponent } => format!("phong (exponent {exponent})"),
    }
}

/// Summarises an in-memory bake.
#[must_use]
pub fn summary(bake: &Bake) -> Summary {
    summarise(bake, None, |oi, bi| {
        block_stats(bake.objects[oi].blocks[bi].data.iter().copied())
    })
}

fn summarise(
    bake: &Bake,
    file: Option<FileSummary>,
    stats: impl Fn(usize, usize) -> (u64, Option<f32>, Option<f32>, u64, u64),
) -> Summary {
    let m = &bake.meta;
    Summary {
        file,
        sample_kind: m.sample_kind,
        rays_per_point: m.rays_per_point,
        bounces: m.bounces,
        seed: m.seed,
        shard: m.shard,
        tool: m.tool.clone(),
        decisions: m.decisions.clone(),
        objects: bake
            .objects
            .iter()
            .enumerate()
            .map(|(oi, o)| ObjectSummary {
                name: o.name.clone(),
                geometry_hash: hash_string(o.geometry_hash),
                point_count: o.point_count,
                point_first: o.point_first,
                points_in_file: o.points_in_file,
                order: o.order,
                channels: o.channels,
                blocks: o
                    .blocks
                    .iter()
                    .enumerate()
                    .map(|(bi, b)| {
                        let (scalars, min, max, nan_count, inf_count) = stats(oi, bi);
                        BlockSummary {
                            kind: b.kind.name().into(),
                            bounces: b.kind.bounces(),
                            scalars,
                            min,
                            max,
                            nan_count,
                            inf_count,
                            cpca: b.cpca.as_ref().map(|c| CpcaSummary {
                                clusters: c.clusters,
                                components: c.components,
                                rel_error: c.rel_error,
                            }),
                        }
                    })
                    .collect(),
                ray_stats: m.ray_stats.get(oi).cloned(),
                mesh: o.mesh.as_ref().map(|g| MeshSummary {
                    vertices: g.positions.len() as u64,
                    triangles: g.triangles.len() as u64,
                }),
                coverage: o.coverage.as_ref().map(|c| CoverageSummary {
                    pixel_samples: c.pixel_samples,
                    covered_points: c.hits.iter().filter(|&&h| h > 0).count() as u64,
                    mean_coverage: c.hits.iter().map(|&h| f64::from(h)).sum::<f64>()
                        / (f64::from(c.pixel_samples) * c.hits.len().max(1) as f64),
                }),
                material: o.material.clone(),
            })
            .collect(),
        environment: bake.environment.as_ref().map(|e| (e.order, e.precision)),
        brdfs: bake
            .brdfs
            .iter()
            .map(|b| (b.material.clone(), lobe_name(b.lobe), b.order))
            .collect(),
        glossy: bake
            .glossy
            .iter()
            .map(|g| (g.material.clone(), g.order, g.elevations.len()))
            .collect(),
        camera: m.camera.clone(),
        pass: m.pass.clone(),
        reflectance: bake.reflectance.as_ref().map(|r| FieldSummary {
            directions: r.directions,
            pixels: r.pixels.len() as u64,
            scalars: 3
                * u64::from(r.directions[0])
                * u64::from(r.directions[1])
                * r.pixels.len() as u64,
        }),
    }
}

impl BakeView<'_> {
    /// Summarises the file, reading coefficients in place.
    #[must_use]
    pub fn summary(&self) -> Summary {
        let skeleton = self.skeleton();
        let file = FileSummary {
            version: [self.version().0, self.version().1],
            scalar_type: self.scalar_type(),
            file_size: self.bytes().len() as u64,
            sections: self
                .sections()
                .iter()
                .map(|s| SectionSummary {
                    tag: s.tag.to_string(),
                    offset: s.offset,
                    length: s.length,
                })
                .collect(),
        };
        summarise(&skeleton, Some(file), |oi, bi| {
            match self.coefficients(oi, bi) {
                Some(Coefficients::F32(v)) => block_stats(v.iter().copied()),
                Some(Coefficients::F16(v)) => block_stats(v.iter().map(|h| h.to_f32())),
                None => (0, None, None, 0, 0),
            }
        })
    }
}

impl std::fmt::Display for Summary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if let Some(file) = &self.file {
            writeln!(
                f,
                "PRT bake format {}.{}, {} coefficients, {} bytes, {} sections",
                file.version[0],
                file.version[1],
                file.scalar_type.name(),
                file.file_size,
                file.sections.len()
            )?;
        }
        let kind = match self.sample_kind {
            SampleKind::Vertex => "per-vertex".to_owned(),
            SampleKind::Pixel { width, height } => format!("per-pixel {width}×{height}"),
            SampleKind::Texel { width, height } => format!("per-texel {width}×{height}"),
        };
        writeln!(
            f,
            "{kind}, {} rays/point, {} bounces, seed {}, shard {}/{}, made by {} {}",
            self.rays_per_point,
            self.bounces,
            self.seed,
            self.shard.index,
            self.shard.count,
            self.tool.name,
            self.tool.version
        )?;
        for o in &self.objects {
            writeln!(
                f,
                "object {:?} hash {}: points {}..{} of {}, order {}, {} channel(s)",
                o.name,
                o.geometry_hash,
                o.point_first,
                o.point_first + o.points_in_file,
                o.point_count,
                o.order,
                o.channels
            )?;
            for b in &o.blocks {
                write!(f, "  {}", b.kind)?;
                if b.bounces > 0 {
                    write!(f, " ({} bounces)", b.bounces)?;
                }
                write!(f, ": {} scalars", b.scalars)?;
                if let (Some(lo), Some(hi)) = (b.min, b.max) {
                    write!(f, ", min {lo}, max {hi}")?;
                }
                writeln!(f, ", {} NaN, {} inf", b.nan_count, b.inf_count)?;
            }
            if let Some(r) = &o.ray_stats {
                writeln!(f, "  {r}")?;
            }
            if let Some(m) = &o.mesh {
                writeln!(f, "  {m}")?;
            }
            if let Some(c) = &o.coverage {
                writeln!(f, "  {c}")?;
            }
        }
        if let Some(c) = &self.camera {
            writeln!(f, "{}", camera_line(c))?;
        }
        if let Some((order, precision)) = self.environment {
            writeln!(f, "environment: order {order}, {precision:?}")?;
        }
        for (m, lobe, order) in &self.brdfs {
            writeln!(f, "BRDF {m:?}: {lobe}, order {order}")?;
        }
        for (m, order, n) in &self.glossy {
            writeln!(f, "glossy table {m:?}: order {order}, {n} elevations")?;
        }
        for d in &self.decisions {
            let who = d.object.as_deref().unwrap_or("(bake)");
            writeln!(f, "decision {who}: {} because {}", d.decision, d.reason)?;
        }
        Ok(())
    }
}

impl std::fmt::Display for MeshSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "mesh: {} vertices, {} triangles (its hash is the geometry hash)",
            self.vertices, self.triangles
        )
    }
}

impl std::fmt::Display for CoverageSummary {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "coverage: {} pixels touched, mean {:.2} % of the pixels held ({} footprint samples per pixel)",
            self.covered_points,
            100.0 * self.mean_coverage,
            self.pixel_samples
        )
    }
}

/// One line describing a per-pixel bake's camera.
#[must_use]
pub fn camera_line(c: &CameraInfo) -> String {
    format!(
        "camera: {} {}×{}, eye {:?}, target {:?}, up {:?}, vertical field of view {}°",
        c.model, c.width, c.height, c.eye, c.target, c.up, c.fov_y_degrees
    )
}
