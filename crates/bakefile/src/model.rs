//! The in-memory data model of a bake, and the rules it must satisfy (`Bake::validate`).

use std::collections::BTreeSet;

use serde::{Deserialize, Serialize};

use crate::error::BakeFileError;
use crate::field::{FieldValues, Rule};
pub use crate::scalar::ScalarType;

/// What a "point" of an object is.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase", tag = "kind")]
pub enum SampleKind {
    /// One point per mesh vertex, in the mesh's vertex order.
    Vertex,
    /// One point per texel of a `width × height` image per object, row-major, row 0 first
    /// (point index `y * width + x`).
    Pixel {
        /// Image width in texels (≥ 1).
        width: u32,
        /// Image height in texels (≥ 1).
        height: u32,
    },
    /// Per-texel (lightmap) bakes: an object with coverage (`CVRG`, `K = 1`) has one point
    /// per texel of its own `width × height` lightmap, row-major from the top row (point index
    /// `y * width + x`, texel centre at UV `((x + ½)/width, (y + ½)/height)`); an object
    /// without coverage (no lightmap UVs) has one point per vertex.
    Texel {
        /// Lightmap width in texels (≥ 1).
        width: u32,
        /// Lightmap height in texels (≥ 1).
        height: u32,
    },
}

impl SampleKind {
    /// The u32 code used in the binary tables (1 = vertex, 2 = pixel, 3 = texel).
    #[must_use]
    pub const fn code(self) -> u32 {
        match self {
            SampleKind::Vertex => 1,
            SampleKind::Pixel { .. } => 2,
            SampleKind::Texel { .. } => 3,
        }
    }
}

/// The kind of light transport a block of transfer coefficients describes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "kind")]
pub enum TransferKind {
    /// Clamped cosine only, visibility ignored (code 1).
    UnshadowedDiffuse,
    /// Clamped cosine times visibility (code 2).
    ShadowedDiffuse,
    /// Visibility alone, no cosine (code 3).
    Visibility,
    /// Shadowed diffuse plus `bounces` interreflections (code 4), `1 ≤ bounces ≤ meta.bounces`.
    InterreflectedDiffuse {
        /// Number of indirect bounces included.
        bounces: u32,
    },
}

impl TransferKind {
    /// The u32 kind code of SPEC.md.
    #[must_use]
    pub const fn code(self) -> u32 {
        match self {
            TransferKind::UnshadowedDiffuse => 1,
            TransferKind::ShadowedDiffuse => 2,
            TransferKind::Visibility => 3,
            TransferKind::InterreflectedDiffuse { .. } => 4,
        }
    }

    /// The bounce count stored beside the code (0 except for interreflected diffuse).
    #[must_use]
    pub const fn bounces(self) -> u32 {
        match self {
            TransferKind::InterreflectedDiffuse { bounces } => bounces,
            _ => 0,
        }
    }

    /// Builds a kind from its code and bounce field; `None` for an unknown code or a
    /// bounce count that the code does not allow.
    #[must_use]
    pub const fn from_code(code: u32, bounces: u32) -> Option<Self> {
        match (code, bounces) {
            (1, 0) => Some(TransferKind::UnshadowedDiffuse),
            (2, 0) => Some(TransferKind::ShadowedDiffuse),
            (3, 0) => Some(TransferKind::Visibility),
            (4, b) if b > 0 => Some(TransferKind::InterreflectedDiffuse { bounces: b }),
            _ => None,
        }
    }

    /// The name used in the metadata JSON.
    #[must_use]
    pub const fn name(self) -> &'static str {
        match self {
            TransferKind::UnshadowedDiffuse => "unshadowed-diffuse",
            TransferKind::ShadowedDiffuse => "shadowed-diffuse",
            TransferKind::Visibility => "visibility",
            TransferKind::InterreflectedDiffuse { .. } => "interreflected-diffuse",
        }
    }
}

/// The program that made the bake.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct ToolInfo {
    /// Program name, e.g. `prt-bake`.
    pub name: String,
    /// Program version, e.g. `0.1.0`.
    pub version: String,
}

/// One entry of the decisions log: what the baker chose for an object (or globally) and why.
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct Decision {
    /// The object's name, or `None` for a decision about the whole bake.
    pub object: Option<String>,
    /// What was decided, e.g. `"order 6"` or `"skip interreflected-diffuse"`.
    pub decision: String,
    /// Why, in words a person can check.
    pub reason: String,
}

/// What one object's rays met during a bake: numbers that make a broken mesh visible
/// (inverted normals, interpenetrating or unclosed geometry). Counts over this file's points,
/// so shards add up ([`crate::merge`]).
#[derive(Debug, Clone, PartialEq, Eq, Default, Serialize, Deserialize)]
pub struct RayStats {
    /// The object's name (the same order as [`Bake::objects`]).
    pub object: String,
    /// Points whose rays are counted (per-pixel bakes: footprint samples).
    pub points: u64,
    /// Diffuse-transfer rays traced from them.
    pub rays: u64,
    /// Rays whose first hit is the back of a surface.
    pub backface_hits: u64,
    /// Points more than half of whose rays hit the back of a surface: rays *started inside
    /// geometry* (a point enclosed by another closed object, or by its own inverted mesh).
    pub inside_points: u64,
    /// Rays traced from those points.
    pub inside_rays: u64,
}

impl RayStats {
    /// Fraction of rays whose first hit is a back face (0 when no rays).
    #[must_use]
    pub fn backface_fraction(&self) -> f64 {
        self.backface_hits as f64 / self.rays.max(1) as f64
    }

    /// Fraction of rays started inside geometry (0 when no rays).
    #[must_use]
    pub fn inside_fraction(&self) -> f64 {
        self.inside_rays as f64 / self.rays.max(1) as f64
    }

    /// Adds another shard's counts of the same object.
    ///
    /// (Printed by its `Display`: `rays R from P points: back-face hits x %, started inside
    /// geometry y % (K points)`.)
    pub fn add(&mut self, other: &RayStats) {
        self.points += other.points;
        self.rays += other.rays;
        self.backface_hits += other.backface_hits;
        self.inside_points += other.inside_points;
        self.inside_rays += other.inside_rays;
    }
}

impl std::fmt::Display for RayStats {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "rays {} from {} points: back-face hits {:.3} %, started inside geometry {:.3} % ({} points)",
            self.rays,
            self.points,
            100.0 * self.backface_fraction(),
            100.0 * self.inside_fraction(),
            self.inside_points
        )
    }
}

/// Which part of a sharded bake a file holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShardInfo {
    /// Index of this shard, `0 ≤ index < count`.
    pub index: u32,
    /// Number of shards; 1 for an unsharded (or merged) bake.
    pub count: u32,
}

impl Default for ShardInfo {
    fn default() -> Self {
        ShardInfo { index: 0, count: 1 }
    }
}

/// Bake-wide metadata.
///
/// Nothing here may depend on the time, the machine, the thread count or the shard layout
/// (except [`BakeMeta::shard`] itself): merged shards must encode to the same bytes as an
/// unsharded bake. See SPEC.md, "Determinism".
#[derive(Debug, Clone, PartialEq)]
pub struct BakeMeta {
    /// Per-vertex or per-pixel.
    pub sample_kind: SampleKind,
    /// Rays traced per point.
    pub rays_per_point: u32,
    /// Bounces of the light transport (CONVENTIONS.md, "Light paths").
    pub bounces: u32,
    /// The global seed of every random stream.
    pub seed: u64,
    /// The program that made the bake.
    pub tool: ToolInfo,
    /// Creation settings as given to the baker: a JSON object (free-form, but deterministic).
    pub settings: serde_json::Value,
    /// The baker's decisions log.
    pub decisions: Vec<Decision>,
    /// Which shard this is.
    pub shard: ShardInfo,
    /// Per object, what its rays met (empty when the writer did not record it; otherwise one
    /// entry per object, in object order).
    pub ray_stats: Vec<RayStats>,
    /// Per-pixel bakes: the camera whose image the pixel grid is (format 1.1; `None` in 1.0
    /// files and in per-vertex bakes).
    pub camera: Option<CameraInfo>,
    /// Intermediate files of a distributed bounced bake only (SPEC.md §3.12): which pass made
    /// the file. `None` in every bake an engine is meant to read.
    pub pass: Option<PassInfo>,
}

/// Which pass of a distributed bounced bake made an intermediate file (SPEC.md §3.12).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PassInfo {
    /// This pass, `0 ≤ index < last` (pass `last` writes the final bake, without this).
    pub index: u32,
    /// The last pass: the bake's bounce count.
    pub last: u32,
    /// Per object, the albedo the bounces were gathered with (so a later pass can refuse a
    /// scene whose materials changed).
    pub albedo: Vec<[f32; 3]>,
}

/// One recorded ray hit of a bounced bake (SPEC.md §3.12).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PassHit {
    /// Object (mesh) hit.
    pub mesh: u32,
    /// Triangle of that mesh.
    pub tri: u32,
    /// Barycentric weight of the triangle's second vertex.
    pub u: f32,
    /// Barycentric weight of the triangle's third vertex.
    pub v: f32,
}

/// The state a distributed bounced bake hands from one pass to the next, per object
/// (SPEC.md §3.12): every bounce level computed so far for all vertices, this file's points'
/// newest level, running totals and recorded hits.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PassState {
    /// Complete bounce levels `0 … L−1`, each `vertex_count × 3 × order²` f32
    /// (`[vertex][channel][coefficient]`).
    pub levels: Vec<Vec<f32>>,
    /// Level `L` for this file's points (`points_in_file × 3 × order²`), if computed.
    pub partial: Option<Vec<f32>>,
    /// Running sum of the levels so far for this file's points, in f64 (per-vertex bakes).
    pub totals: Option<Vec<f64>>,
    /// Hits recorded per point of this file (`points_in_file` counts), when bounces follow.
    pub hit_counts: Option<Vec<u32>>,
    /// Whether `hits` holds the records: in the files of pass 0 (each shard keeps its own;
    /// later passes read them with `--hits`), not in merged files, which keep the counts only.
    pub records: bool,
    /// The hits themselves, point by point (`Σ hit_counts` records when `records`, else none).
    pub hits: Vec<PassHit>,
}

/// The pinhole camera of a per-pixel bake (SPEC.md §3.9, "Camera"): the ray through
/// image-plane position `(x, y)` (pixels, `(0, 0)` the top-left corner, `y` down) leaves `eye`
/// in direction `normalize(f + (2x/w − 1)·t·(w/h)·r + (1 − 2y/h)·t·u)` with
/// `f = normalize(target − eye)`, `r = normalize(f × up)`, `u = r × f`, `t = tan(fov_y/2)`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CameraInfo {
    /// `"pinhole"`, the only model.
    pub model: String,
    /// Eye position (world space).
    pub eye: [f64; 3],
    /// Point looked at.
    pub target: [f64; 3],
    /// Up vector (need not be unit or orthogonal to the view direction).
    pub up: [f64; 3],
    /// Vertical field of view, degrees, in (0, 180).
    pub fov_y_degrees: f64,
    /// Image width in pixels (= the bake's image width).
    pub width: u32,
    /// Image height in pixels (= the bake's image height).
    pub height: u32,
}

impl CameraInfo {
    /// The camera model name of format 1.1.
    pub const PINHOLE: &'static str = "pinhole";
}

/// An object's geometry exactly as the baker saw it (format 1.1, section `MESH`): world-space
/// positions, unit shading normals and triangles. For per-vertex bakes, vertex `p` is point
/// `p`; [`crate::geometry_hash`] of `positions` and `triangles` is the object's hash.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct MeshGeometry {
    /// Vertex positions, world space.
    pub positions: Vec<[f32; 3]>,
    /// Unit shading normals, one per vertex (the hemisphere of the bake's cosine term).
    pub normals: Vec<[f32; 3]>,
    /// Triangles as vertex index triples, counter-clockwise seen from the front.
    pub triangles: Vec<[u32; 3]>,
}

/// How much of each pixel's footprint an object covers (format 1.1, section `CVRG`).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Coverage {
    /// Footprint samples per pixel `K` (the bake's `settings.pixel_samples`).
    pub pixel_samples: u32,
    /// Per point held in the file: how many of the `K` samples first hit this object.
    pub hits: Vec<u32>,
}

impl Default for BakeMeta {
    fn default() -> Self {
        BakeMeta {
            sample_kind: SampleKind::Vertex,
            rays_per_point: 0,
            bounces: 0,
            seed: 0,
            tool: ToolInfo::default(),
            settings: serde_json::Value::Object(serde_json::Map::new()),
            decisions: Vec::new(),
            shard: ShardInfo::default(),
            ray_stats: Vec::new(),
            camera: None,
            pass: None,
        }
    }
}

/// One block of transfer coefficients of one object.
#[derive(Debug, Clone, PartialEq)]
pub struct TransferBlock {
    /// What transport the block describes.
    pub kind: TransferKind,
    /// `points_in_file × channels × order²` scalars, laid out `[point][channel][coefficient]`:
    /// the scalar of point `p`, channel `c`, SH index `i` is at
    /// `(p * channels + c) * order² + i`. For a compressed block, its reconstruction
    /// ([`Cpca::reconstruct`]).
    pub data: Vec<f32>,
    /// The block's clustered-PCA form (SPEC.md §3.13), when it is stored compressed; `data` then
    /// holds exactly its reconstruction.
    pub cpca: Option<Cpca>,
}

/// A transfer block compressed by clustered principal component analysis (Sloan, Hall, Hart
/// & Snyder 2003; SPEC.md §3.13): point `p` of cluster `k` is
/// `mean_k + Σ_j w_{p,j} basis_{k,j}`.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Cpca {
    /// Clusters `K ≥ 1`.
    pub clusters: u32,
    /// Basis vectors per cluster `M`.
    pub components: u32,
    /// Scalars per point `D` (channels × order²).
    pub dimension: u32,
    /// Relative L2 error of the approximation over the block, as the compressor measured it.
    pub rel_error: f64,
    /// `K × (M + 1) × D` scalars: per cluster its mean, then its `M` basis vectors.
    pub centres: Vec<f32>,
    /// Per point, its cluster (`< K`).
    pub cluster_of: Vec<u32>,
    /// `points × M` weights.
    pub weights: Vec<f32>,
}

impl Cpca {
    /// Points described.
    #[must_use]
    pub fn points(&self) -> usize {
        self.cluster_of.len()
    }

    /// Row `r` of cluster `k` (0: the mean; `1 + j`: basis vector `j`).
    #[must_use]
    pub fn row(&self, k: usize, r: usize) -> &[f32] {
        let d = self.dimension as usize;
        let m1 = self.components as usize + 1;
        &self.centres[(k * m1 + r) * d..(k * m1 + r + 1) * d]
    }

    /// The approximated transfer, `[point][d]`, computed in f32 exactly as SPEC.md §3.13 says
    /// (the mean, then each weighted basis vector added in order).
    #[must_use]
    pub fn reconstruct(&self) -> Vec<f32> {
        let (d, m) = (self.dimension as usize, self.components as usize);
        let mut out = Vec::with_capacity(self.points() * d);
        for (p, &k) in self.cluster_of.iter().enumerate() {
            let start = out.len();
            out.extend_from_slice(self.row(k as usize, 0));
            for j in 0..m {
                let w = self.weights[p * m + j];
                for (o, &b) in out[start..].iter_mut().zip(self.row(k as usize, 1 + j)) {
                    *o += w * b;
                }
            }
        }
        out
    }

    /// Checks counts and values (SPEC.md §3.13).
    pub(crate) fn check(
        &self,
        points: u64,
        dimension: u64,
        what: &str,
    ) -> Result<(), BakeFileError> {
        let (k, m, d) = (
            u64::from(self.clusters),
            u64::from(self.components),
            u64::from(self.dimension),
        );
        let ok = k >= 1
            && d == dimension
            && self.cluster_of.len() as u64 == points
            && Some(self.centres.len() as u64)
                == k.checked_mul(m + 1).and_then(|x| x.checked_mul(d))
            && Some(self.weights.len() as u64) == points.checked_mul(m);
        if !ok {
            return Err(bad(format!(
                "{what}: clustered PCA of {} points, K {k}, M {m}, D {d} does not fit {points} points of dimension {dimension}",
                self.cluster_of.len()
            )));
        }
        if let Some(p) = self.cluster_of.iter().position(|&c| c >= self.clusters) {
            return Err(bad(format!(
                "{what}: point {p} is in cluster {} of {k}",
                self.cluster_of[p]
            )));
        }
        check_finite32(&format!("{what} clustered PCA"), &self.centres)?;
        check_finite32(&format!("{what} clustered PCA weights"), &self.weights)?;
        if !(self.rel_error.is_finite() && self.rel_error >= 0.0) {
            return Err(BakeFileError::NonFinite {
                section: format!("{what} clustered PCA error"),
                index: 0,
            });
        }
        Ok(())
    }
}

/// The transfer of one object (mesh).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ObjectBake {
    /// Object name, unique within the bake, not empty.
    pub name: String,
    /// [`crate::geometry_hash`] of the object's positions and indices.
    pub geometry_hash: u64,
    /// Number of points of the whole object (vertices, or `width × height` texels).
    pub point_count: u64,
    /// First point held here: 0 unless this is a shard.
    pub point_first: u64,
    /// Number of points held here, starting at `point_first`; `point_count` unless a shard.
    pub points_in_file: u64,
    /// SH order n (band count): `n²` coefficients per channel. At least 1.
    pub order: u32,
    /// Channels per point: 1 (scalar) or 3 (RGB).
    pub channels: u32,
    /// The transfer blocks; each kind (with its bounce count) at most once.
    pub blocks: Vec<TransferBlock>,
    /// The mesh the object was baked on (format 1.1; `None` in 1.0 files). Every shard
    /// carries the whole mesh.
    pub mesh: Option<MeshGeometry>,
    /// Per-pixel bakes: the object's coverage of each pixel held here (format 1.1; `None` in
    /// 1.0 files, never in per-vertex bakes).
    pub coverage: Option<Coverage>,
    /// The material the object was baked for (format 1.2, SPEC.md §3.9.1; `None` in older
    /// files, or when the writer did not know it).
    pub material: Option<crate::MaterialBinding>,
    /// Intermediate files of a distributed bounced bake: what the next pass needs.
    pub pass: Option<PassState>,
}

impl ObjectBake {
    /// The diffuse transfer block relighting uses (SPEC §10): the first interreflected block
    /// in block order if the object has one, else the shadowed one.
    #[must_use]
    pub fn diffuse_block(&self) -> Option<&TransferBlock> {
        self.blocks
            .iter()
            .find(|b| matches!(b.kind, TransferKind::InterreflectedDiffuse { .. }))
            .or_else(|| {
                self.blocks
                    .iter()
                    .find(|b| b.kind == TransferKind::ShadowedDiffuse)
            })
    }

    /// Scalars per point of every block: `channels × order²`.
    #[must_use]
    pub fn scalars_per_point(&self) -> u64 {
        u64::from(self.channels) * u64::from(self.order) * u64::from(self.order)
    }
}

/// Storage precision of the environment coefficients.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum EnvPrecision {
    /// Stored as f32 (code 1): values are rounded to f32 on encoding.
    F32,
    /// Stored as f64 (code 3).
    F64,
}

impl EnvPrecision {
    /// The u32 code of SPEC.md.
    #[must_use]
    pub const fn code(self) -> u32 {
        match self {
            EnvPrecision::F32 => 1,
            EnvPrecision::F64 => 3,
        }
    }
}

/// SH projection of the environment lighting (RGB radiance).
#[derive(Debug, Clone, PartialEq)]
pub struct EnvCoefficients {
    /// SH order n (band count), at least 1.
    pub order: u32,
    /// How the values are stored in the file.
    pub precision: EnvPrecision,
    /// `3 × order²` values laid out `[channel][coefficient]` (R row, then G, then B).
    pub values: Vec<f64>,
}

/// The lobe of a zonal BRDF projection.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case", tag = "lobe")]
pub enum BrdfLobe {
    /// `max(0, cos θ)` (code 1): the Lambert transfer lobe.
    ClampedCosine,
    /// The unit-integral Phong lobe `(e+1)/(2π) max(0, cos θ)^e` about the reflection direction
    /// (code 2); CONVENTIONS.md's BRDF is `specular · (e+2)/(2π) max(0, r·ω_i)^e`.
    Phong {
        /// The exponent `e ≥ 0`.
        exponent: f64,
    },
}

/// Zonal-harmonic projection of a material's BRDF lobe.
#[derive(Debug, Clone, PartialEq)]
pub struct BrdfProjection {
    /// Material name, unique among the zonal projections.
    pub material: String,
    /// The lobe projected.
    pub lobe: BrdfLobe,
    /// SH order n: `values` holds `g_0 … g_{n-1}`.
    pub order: u32,
    /// The `order` zonal coefficients `g_l` (CONVENTIONS.md, "Zonal harmonics").
    pub values: Vec<f64>,
}

/// Per-view-elevation SH projections of an isotropic glossy BRDF.
///
/// In the local frame (normal +Z), for view elevation `θ_o` the view direction is
/// `(sin θ_o, 0, cos θ_o)`; row `e` holds the projection over `ω_i` of
/// `f(ω_i, ω_o) max(0, cos θ_i)`.
#[derive(Debug, Clone, PartialEq)]
pub struct GlossyBrdfTable {
    /// Material name, unique among the tables.
    pub material: String,
    /// SH order n of each row.
    pub order: u32,
    /// View elevations `θ_o` in radians, one per row.
    pub elevations: Vec<f64>,
    /// `elevations.len() × order²` values laid out `[elevation][coefficient]`.
    pub values: Vec<f64>,
    /// `order` numbers: `projection_error[k-1]` is the relative L2 error of the projection
    /// truncated to order `k`, as measured by the baker.
    pub projection_error: Vec<f64>,
}

/// A whole bake: what a `.prtb` file holds.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Bake {
    /// Bake-wide metadata.
    pub meta: BakeMeta,
    /// Per-object transfer.
    pub objects: Vec<ObjectBake>,
    /// Environment lighting, if the bake carries it.
    pub environment: Option<EnvCoefficients>,
    /// Zonal BRDF projections per material.
    pub brdfs: Vec<BrdfProjection>,
    /// Tabulated glossy BRDF projections per material.
    pub glossy: Vec<GlossyBrdfTable>,
    /// A sampled reflectance field (section `RFLD`, `prt reflectance`), or `None`.
    pub reflectance: Option<ReflectanceField>,
}

/// A sampled reflectance field (Masselus, Peers, Dutré & Willems 2004; section `RFLD`): per
/// pixel of a per-pixel file's image, its reflectance function `R(ω)` — the radiance toward
/// the camera through the pixel per unit radiance arriving from direction `ω`, per steradian,
/// so that the pixel under a distant light `L` is `∫ R(ω) L(ω) dω` — sampled at the centres of
/// a `W × H` latitude-longitude grid of directions (CONVENTIONS.md's mapping: direction `j =
/// row·W + column` at `φ = 2π(column + ½)/W`, `θ = π(row + ½)/H`).
#[derive(Clone, Debug, PartialEq)]
pub struct ReflectanceField {
    /// Direction grid `[W, H]` (azimuth, polar), `W ≥ 2`, `H ≥ 1`.
    pub directions: [u32; 2],
    /// The pixels held, strictly increasing (`y · width + x`); pixels whose footprint
    /// samples all see the environment have a zero function and are left out.
    pub pixels: Vec<u32>,
    /// `[pixel held][channel (3)][direction]`, non-negative and finite, in 1/sr, held in the
    /// precision of the file (f32 or f16; [`crate::read_bake`] hands the file's own buffer
    /// over, [`crate::write_bake`] writes them out as they are when the precisions agree).
    pub values: FieldValues,
}

impl ReflectanceField {
    /// Directions per function (`W · H`).
    #[must_use]
    pub fn direction_count(&self) -> usize {
        self.directions[0] as usize * self.directions[1] as usize
    }

    /// The three channels' functions of held pixel `i`, `3 · W · H` values as f32: lent in
    /// place when the field is stored as f32 (and aligned), otherwise decoded into `scratch`
    /// (one buffer per thread, reused from pixel to pixel, makes this allocation-free).
    ///
    /// # Panics
    /// When `i` is not a held pixel's index (`i ≥ pixels.len()`).
    #[must_use]
    pub fn function<'a>(&'a self, i: usize, scratch: &'a mut Vec<f32>) -> &'a [f32] {
        let n = 3 * self.direction_count();
        self.values.slice(i * n..(i + 1) * n, scratch)
    }

    /// [`ReflectanceField::function`] decoded into `out` (`3 · W · H` values).
    ///
    /// # Panics
    /// When `i` is not a held pixel's index or `out` is not `3 · W · H` long.
    pub fn function_into(&self, i: usize, out: &mut [f32]) {
        let n = 3 * self.direction_count();
        assert_eq!(out.len(), n, "a function is 3 · W · H values");
        self.values.read_into(i * n, out);
    }

    /// Structure: a per-pixel file, directions, increasing pixels in the image, and (with
    /// `with_values`) the value count.
    fn check(&self, kind: SampleKind, with_values: bool) -> Result<(), BakeFileError> {
        let SampleKind::Pixel { width, height } = kind else {
            return Err(bad("a reflectance field belongs to a per-pixel file"));
        };
        let [w, h] = self.directions;
        if w < 2 || h < 1 || u64::from(w) * u64::from(h) > 1 << 24 {
            return Err(bad(format!(
                "reflectance directions {w}×{h} (at least 2×1, at most 2^24)"
            )));
        }
        let pixels = u64::from(width) * u64::from(height);
        if !self.pixels.windows(2).all(|p| p[0] < p[1])
            || self.pixels.last().is_some_and(|&p| u64::from(p) >= pixels)
        {
            return Err(bad(format!(
                "reflectance pixels must increase and lie in the {width}×{height} image"
            )));
        }
        let want = (self.pixels.len() as u64)
            .checked_mul(3 * self.direction_count() as u64)
            .ok_or_else(|| bad("reflectance field too large"))?;
        if with_values && self.values.len() as u64 != want {
            return Err(BakeFileError::InconsistentCounts {
                what: "RFLD values".into(),
                expected: want,
                found: self.values.len() as u64,
            });
        }
        Ok(())
    }
}

/// `"0x"` and 16 lower-case hexadecimal digits: how the metadata writes a geometry hash.
fn is_hash_string(h: &str) -> bool {
    h.len() == 18
        && h.starts_with("0x")
        && h[2..]
            .bytes()
            .all(|c| c.is_ascii_digit() || (b'a'..=b'f').contains(&c))
}

fn bad(msg: impl Into<String>) -> BakeFileError {
    BakeFileError::InvalidBake(msg.into())
}

pub(crate) fn check_finite64(section: &str, values: &[f64]) -> Result<(), BakeFileError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(BakeFileError::NonFinite {
            section: section.to_owned(),
            index: i as u64,
        }),
        None => Ok(()),
    }
}

pub(crate) fn check_finite32(section: &str, values: &[f32]) -> Result<(), BakeFileError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(i) => Err(BakeFileError::NonFinite {
            section: section.to_owned(),
            index: i as u64,
        }),
        None => Ok(()),
    }
}

/// How far a MESH normal's length may be from 1 (SPEC.md §3.10): a unit vector rounded to
/// f32 is within ~2·10⁻⁷ of it.
pub(crate) const MAX_NORMAL_LENGTH_ERROR: f64 = 1e-5;

/// The first point whose transfer is not zero although its coverage says no footprint sample
/// hit it (SPEC.md §3.11), as `(block, point)`: `blocks` blocks over the points
/// `point_first …` that `coverage` describes, `is_zero(block, point in file)` telling.
pub(crate) fn uncovered_nonzero(
    point_first: u64,
    blocks: usize,
    coverage: &Coverage,
    is_zero: impl Fn(usize, usize) -> bool,
) -> Option<(usize, u64)> {
    for bi in 0..blocks {
        for (p, &h) in coverage.hits.iter().enumerate() {
            if h == 0 && !is_zero(bi, p) {
                return Some((bi, point_first + p as u64));
            }
        }
    }
    None
}

/// The rules of an object's pass state (SPEC.md §3.12).
fn check_pass(
    o: &ObjectBake,
    m: &BakeMeta,
    what: &str,
    with_data: bool,
) -> Result<(), BakeFileError> {
    let Some(p) = &o.pass else {
        return if m.pass.is_some() {
            Err(bad(format!(
                "{what}: an intermediate pass file without pass state"
            )))
        } else {
            Ok(())
        };
    };
    if m.pass.is_none() || m.sample_kind != SampleKind::Vertex {
        return Err(bad(format!(
            "{what}: pass state outside an intermediate (per-vertex) pass file"
        )));
    }
    let per = 3 * sq(o.order);
    let whole = o.point_count.checked_mul(per);
    let held = o.points_in_file.checked_mul(per);
    if p.levels.iter().any(|l| Some(l.len() as u64) != whole)
        || p.partial
            .as_ref()
            .is_some_and(|l| Some(l.len() as u64) != held)
        || p.totals
            .as_ref()
            .is_some_and(|l| Some(l.len() as u64) != held)
    {
        return Err(bad(format!(
            "{what}: pass levels or totals of the wrong length for {} points (order {})",
            o.point_count, o.order
        )));
    }
    match &p.hit_counts {
        None if !p.hits.is_empty() || p.records => {
            return Err(bad(format!("{what}: hits without per-point counts")));
        }
        _ if !p.records && !p.hits.is_empty() => {
            return Err(bad(format!(
                "{what}: hit records in a file that says it holds none"
            )));
        }
        Some(c)
            if c.len() as u64 != o.points_in_file
                || (p.records
                    && c.iter().map(|&n| u64::from(n)).sum::<u64>() != p.hits.len() as u64) =>
        {
            return Err(bad(format!(
                "{what}: hit counts do not add up to the {} hits held",
                p.hits.len()
            )));
        }
        _ => {}
    }
    if with_data {
        for l in p.levels.iter().chain(&p.partial) {
            check_finite32(&format!("{what} pass level"), l)?;
        }
        if let Some(t) = &p.totals {
            check_finite64(&format!("{what} pass totals"), t)?;
        }
        if let Some(h) = p
            .hits
            .iter()
            .position(|h| !(h.u.is_finite() && h.v.is_finite()))
        {
            return Err(BakeFileError::NonFinite {
                section: format!("{what} pass hits"),
                index: h as u64,
            });
        }
    }
    Ok(())
}

/// The rules of an object's coverage (SPEC.md §3.11): per-pixel bakes, or per-texel with
/// `K = 1`; one count per point held, each at most `K`.
fn check_object_coverage(
    o: &ObjectBake,
    kind: SampleKind,
    what: &str,
) -> Result<(), BakeFileError> {
    if let Some(c) = &o.coverage {
        match kind {
            SampleKind::Pixel { .. } => {}
            SampleKind::Texel { .. } if c.pixel_samples == 1 => {}
            SampleKind::Texel { .. } => {
                return Err(bad(format!(
                    "{what}: texel coverage with K = {} (texels have one sample)",
                    c.pixel_samples
                )))
            }
            SampleKind::Vertex => {
                return Err(bad(format!("{what}: coverage in a per-vertex bake")))
            }
        }
        if c.pixel_samples == 0 || c.hits.len() as u64 != o.points_in_file {
            return Err(bad(format!(
                "{what}: coverage of {} points with K = {} ({} points held)",
                c.hits.len(),
                c.pixel_samples,
                o.points_in_file
            )));
        }
        if let Some(p) = c.hits.iter().position(|&h| h > c.pixel_samples) {
            return Err(bad(format!(
                "{what}: point {} is hit by {} of {} footprint samples",
                o.point_first + p as u64,
                c.hits[p],
                c.pixel_samples
            )));
        }
    }
    Ok(())
}

/// The rules of an object's mesh (SPEC.md §3.10).
fn check_mesh(o: &ObjectBake, kind: SampleKind, what: &str) -> Result<(), BakeFileError> {
    let Some(mesh) = &o.mesh else { return Ok(()) };
    let v = mesh.positions.len();
    if mesh.normals.len() != v || u32::try_from(v).is_err() {
        return Err(bad(format!(
            "{what}: mesh with {v} positions and {} normals",
            mesh.normals.len()
        )));
    }
    if u32::try_from(mesh.triangles.len()).is_err() {
        return Err(bad(format!("{what}: more than 2^32 - 1 triangles")));
    }
    let per_vertex = match kind {
        SampleKind::Vertex => true,
        SampleKind::Pixel { .. } => false,
        SampleKind::Texel { .. } => o.coverage.is_none(),
    };
    if per_vertex && v as u64 != o.point_count {
        return Err(bad(format!(
            "{what}: mesh of {v} vertices for {} points of a per-vertex bake",
            o.point_count
        )));
    }
    let finite = |a: &[[f32; 3]]| a.iter().position(|p| !p.iter().all(|x| x.is_finite()));
    if let Some(i) = finite(&mesh.positions).or(finite(&mesh.normals)) {
        return Err(bad(format!("{what}: mesh vertex {i} is not finite")).in_rule(10));
    }
    let length = |n: &[f32; 3]| n.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt();
    if let Some(i) = mesh
        .normals
        .iter()
        .position(|n| (length(n) - 1.0).abs() > MAX_NORMAL_LENGTH_ERROR)
    {
        return Err(bad(format!(
            "{what}: mesh normal {i} has length {}, not 1",
            length(&mesh.normals[i])
        )));
    }
    if let Some(t) = mesh
        .triangles
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= v))
    {
        return Err(bad(format!(
            "{what}: mesh triangle {t} indexes beyond its {v} vertices"
        )));
    }
    let h = crate::hash::geometry_hash(&mesh.positions, &mesh.triangles);
    if h != o.geometry_hash {
        return Err(bad(format!(
            "{what}: the mesh hashes to {h:#018x}, the object says {:#018x}",
            o.geometry_hash
        ))
        .in_rule(10));
    }
    Ok(())
}

fn sq(order: u32) -> u64 {
    u64::from(order) * u64::from(order)
}

impl Bake {
    /// Checks every rule of the format that the in-memory data can break (SPEC.md,
    /// "Validity rules"). [`crate::encode`] calls it; [`crate::decode`] calls it on what it read.
    pub fn validate(&self) -> Result<(), BakeFileError> {
        self.check(true)
    }

    /// [`Bake::validate`] without looking at the transfer data (for skeletons read from files
    /// whose data was checked in place).
    pub(crate) fn validate_structure(&self) -> Result<(), BakeFileError> {
        self.check(false)
    }

    /// The camera of a per-pixel bake (SPEC.md §3.9): present only there, the image's size,
    /// a pinhole with finite values.
    fn check_camera(&self) -> Result<(), BakeFileError> {
        let Some(c) = &self.meta.camera else {
            return Ok(());
        };
        let SampleKind::Pixel { width, height } = self.meta.sample_kind else {
            return Err(bad("a per-vertex bake with a camera"));
        };
        if c.model != CameraInfo::PINHOLE {
            return Err(bad(format!(
                "camera model {:?} (only \"pinhole\")",
                c.model
            )));
        }
        if (c.width, c.height) != (width, height) {
            return Err(bad(format!(
                "camera image {}×{} for a {width}×{height} bake",
                c.width, c.height
            )));
        }
        let all = c.eye.iter().chain(&c.target).chain(&c.up);
        let finite = all.copied().chain([c.fov_y_degrees]).all(f64::is_finite);
        if !(finite && c.fov_y_degrees > 0.0 && c.fov_y_degrees < 180.0) {
            return Err(bad(
                "camera values not finite, or fov_y outside (0, 180) degrees",
            ));
        }
        Ok(())
    }

    /// The `settings` fields a reader checks besides `lightmaps` and `reflectance` (SPEC.md
    /// §3.9, §4 rule 11): `albedo_in_transfer` a boolean; `pixel_samples` absent from
    /// per-vertex files, absent or 1 in per-texel ones, absent or an integer in
    /// `1..=2³²−1` in per-pixel ones; `subdivide` and `subdivided_from` together, in
    /// per-vertex files, naming the file's objects; a `pass` field only in a per-vertex file
    /// without a reflectance field.
    fn check_settings(&self) -> Result<(), BakeFileError> {
        let m = &self.meta;
        let s = &m.settings;
        if s.get("albedo_in_transfer").is_some_and(|v| !v.is_boolean()) {
            return Err(bad(format!(
                "settings.albedo_in_transfer must be a boolean, not {}",
                s["albedo_in_transfer"]
            )));
        }
        let k = s.get("pixel_samples");
        // Intermediate files of a distributed per-pixel bake are per-vertex but carry the
        // final bake's settings.
        let k_ok = match (m.sample_kind, k) {
            (_, None) => true,
            (SampleKind::Vertex, Some(_)) if m.pass.is_some() => true,
            (SampleKind::Vertex, Some(_)) => false,
            (SampleKind::Texel { .. }, Some(v)) => v.as_u64() == Some(1),
            (SampleKind::Pixel { .. }, Some(v)) => v
                .as_u64()
                .is_some_and(|k| (1..=u64::from(u32::MAX)).contains(&k)),
        };
        if !k_ok {
            return Err(bad(format!(
                "settings.pixel_samples {} in a {} bake (per-vertex: none; per-texel: 1; per-pixel: an integer 1 to 2^32-1)",
                k.map_or_else(String::new, ToString::to_string),
                match m.sample_kind {
                    SampleKind::Vertex => "per-vertex",
                    SampleKind::Pixel { .. } => "per-pixel",
                    SampleKind::Texel { .. } => "per-texel",
                }
            )));
        }
        self.check_subdivide_settings()?;
        if m.pass.is_some() && (m.sample_kind != SampleKind::Vertex || self.reflectance.is_some()) {
            return Err(bad(
                "a `pass` field outside a per-vertex intermediate file (it marks files with PASS sections)",
            ));
        }
        Ok(())
    }

    /// `settings.subdivide` (`{"error": number ≥ 0, "max_levels": integer}`) and
    /// `settings.subdivided_from` (per object name of the file: `{"geometry_hash": "0x…",
    /// "vertices", "triangles"}`, u32 integers) come together, in per-vertex bakes.
    fn check_subdivide_settings(&self) -> Result<(), BakeFileError> {
        let s = &self.meta.settings;
        let (sub, from) = (s.get("subdivide"), s.get("subdivided_from"));
        let (Some(sub), Some(from)) = (sub, from) else {
            return if sub.is_some() || from.is_some() {
                Err(bad(
                    "settings.subdivide and settings.subdivided_from come together (one is missing)",
                ))
            } else {
                Ok(())
            };
        };
        let u32_of = |v: &serde_json::Value, k: &str| {
            v.get(k)
                .and_then(serde_json::Value::as_u64)
                .is_some_and(|x| x <= u64::from(u32::MAX))
        };
        let error_ok = sub
            .get("error")
            .and_then(serde_json::Value::as_f64)
            .is_some_and(|e| e >= 0.0);
        if self.meta.sample_kind != SampleKind::Vertex || !error_ok || !u32_of(sub, "max_levels") {
            return Err(bad(format!(
                "settings.subdivide {sub} must be {{\"error\": number >= 0, \"max_levels\": integer}} in a per-vertex bake"
            )));
        }
        let Some(from) = from.as_object() else {
            return Err(bad("settings.subdivided_from must be an object"));
        };
        for (name, v) in from {
            let hash_ok = v
                .get("geometry_hash")
                .and_then(serde_json::Value::as_str)
                .is_some_and(is_hash_string);
            if !self.objects.iter().any(|o| &o.name == name)
                || !hash_ok
                || !u32_of(v, "vertices")
                || !u32_of(v, "triangles")
            {
                return Err(bad(format!(
                    "settings.subdivided_from[{name:?}] = {v}: must name an object of the file, with a geometry hash \"0x\" + 16 hex digits and u32 vertices and triangles"
                )));
            }
        }
        Ok(())
    }

    /// Per pixel, the hits of all objects' coverage add up to at most `K`, and every object's
    /// `K` is the bake's `settings.pixel_samples` (SPEC.md §3.11).
    fn check_coverage_sums(&self) -> Result<(), BakeFileError> {
        if let SampleKind::Texel { .. } = self.meta.sample_kind {
            // Each object's lightmap is its own image: coverage is 0 or 1 per texel.
            return Ok(());
        }
        let k = self
            .meta
            .settings
            .get("pixel_samples")
            .and_then(serde_json::Value::as_u64)
            .unwrap_or(1);
        let mut sums: std::collections::HashMap<u64, u64> = std::collections::HashMap::new();
        for o in &self.objects {
            let Some(c) = &o.coverage else { continue };
            if u64::from(c.pixel_samples) != k {
                return Err(bad(format!(
                    "object {:?}: coverage of K = {} samples, the bake's pixel_samples is {k}",
                    o.name, c.pixel_samples
                )));
            }
            for (p, &h) in c.hits.iter().enumerate() {
                let pixel = o.point_first + p as u64;
                let s = sums.entry(pixel).or_default();
                *s += u64::from(h);
                if *s > k {
                    return Err(bad(format!(
                        "pixel {pixel}: the objects' coverage adds up to more than {k} samples"
                    )));
                }
            }
        }
        Ok(())
    }

    /// Reflectance fields (SPEC §3.14): `settings.reflectance` is present exactly when the
    /// file holds a field, and then names the field's directions, the file's bounces and rays
    /// per point, its `pixel_samples`, and a non-empty `geometry` list of uniquely named
    /// meshes with `0x`-prefixed 16-digit lower-case hashes.
    fn check_reflectance_settings(&self) -> Result<(), BakeFileError> {
        let settings = &self.meta.settings;
        let s = settings.get("reflectance");
        let (r, s) = match (&self.reflectance, s) {
            (None, None) => return Ok(()),
            (None, Some(_)) => {
                return Err(bad(
                    "settings.reflectance in a file without a reflectance field",
                ))
            }
            (Some(_), None) => return Err(bad("a reflectance field without settings.reflectance")),
            (Some(r), Some(s)) => (r, s),
        };
        let u64_of = |k: &str| s.get(k).and_then(serde_json::Value::as_u64);
        let dirs = s
            .get("directions")
            .and_then(serde_json::Value::as_array)
            .map(|a| a.iter().map(serde_json::Value::as_u64).collect::<Vec<_>>());
        let want_dirs = Some(vec![
            Some(u64::from(r.directions[0])),
            Some(u64::from(r.directions[1])),
        ]);
        let pixel_samples = settings
            .get("pixel_samples")
            .and_then(serde_json::Value::as_u64);
        if dirs != want_dirs
            || u64_of("bounces") != Some(u64::from(self.meta.bounces))
            || u64_of("rays") != Some(u64::from(self.meta.rays_per_point))
            || pixel_samples.is_none()
            || u64_of("pixel_samples") != pixel_samples
        {
            return Err(bad(format!(
                "settings.reflectance must name the field's directions [{}, {}], the file's bounces {} and rays per point {}, and settings.pixel_samples: {s}",
                r.directions[0], r.directions[1], self.meta.bounces, self.meta.rays_per_point
            )));
        }
        let geometry = s
            .get("geometry")
            .and_then(serde_json::Value::as_array)
            .filter(|g| !g.is_empty())
            .ok_or_else(|| bad("settings.reflectance.geometry must list the scene's meshes"))?;
        let mut names = std::collections::HashSet::new();
        for (i, g) in geometry.iter().enumerate() {
            let name = g.get("object").and_then(serde_json::Value::as_str);
            let hash = g.get("geometry_hash").and_then(serde_json::Value::as_str);
            let hash_ok = hash.is_some_and(is_hash_string);
            if !name.is_some_and(|n| !n.is_empty() && names.insert(n)) || !hash_ok {
                return Err(bad(format!(
                    "settings.reflectance.geometry[{i}] must be {{\"object\": a unique name, \"geometry_hash\": \"0x\" + 16 lower-case hex digits}}: {g}"
                )));
            }
        }
        Ok(())
    }

    /// Per-texel bakes (SPEC §3.9): `settings.lightmaps` has one entry per object, `null`
    /// exactly for objects without coverage, else the object's name, the file's lightmap size,
    /// a `uv_set` (u32) or a generated `atlas` (§3.9.3, its UVs hashing to `uv_hash`) and a
    /// `uv_hash` (u64 as a decimal string without sign or leading
    /// zeros); `settings.pixel_samples`, if present, is 1.
    fn check_lightmaps(&self) -> Result<(), BakeFileError> {
        let SampleKind::Texel { width, height } = self.meta.sample_kind else {
            return Ok(());
        };
        let settings = &self.meta.settings;
        if let Some(k) = settings.get("pixel_samples") {
            if k.as_u64() != Some(1) {
                return Err(bad(format!(
                    "settings.pixel_samples {k} in a per-texel bake (texels have one sample)"
                )));
            }
        }
        let Some(all) = settings
            .get("lightmaps")
            .and_then(serde_json::Value::as_array)
        else {
            return Err(bad("a per-texel bake without settings.lightmaps"));
        };
        if all.len() != self.objects.len() {
            return Err(bad(format!(
                "settings.lightmaps has {} entries for {} objects",
                all.len(),
                self.objects.len()
            )));
        }
        for (i, (e, o)) in all.iter().zip(&self.objects).enumerate() {
            let what = format!("settings.lightmaps[{i}]");
            match (e.is_null(), o.coverage.is_some()) {
                (true, false) => continue,
                (true, true) => {
                    return Err(bad(format!(
                        "{what} is null, but object {:?} has texels",
                        o.name
                    )))
                }
                (false, false) => {
                    return Err(bad(format!(
                        "{what} is not null, but object {:?} is per vertex",
                        o.name
                    )))
                }
                (false, true) => {}
            }
            let u64_of = |k: &str| e.get(k).and_then(serde_json::Value::as_u64);
            // A generated atlas (SPEC §3.9.3) in place of a UV set: one or the other.
            if let Some(a) = e.get("atlas") {
                if e.get("uv_set").is_some() {
                    return Err(bad(format!("{what} has both `uv_set` and `atlas`")));
                }
                let triangles = o.mesh.as_ref().map(|m| m.triangles.len());
                let uvs = crate::atlas_uv::atlas_corner_uvs(a, triangles)
                    .map_err(|m| bad(format!("{what}: {m}")))?;
                let h = crate::hash::uv_hash(&uvs.concat()).to_string();
                if e.get("uv_hash").and_then(serde_json::Value::as_str) != Some(h.as_str()) {
                    return Err(bad(format!(
                        "{what}: `uv_hash` is not the hash of its atlas UVs ({h})"
                    )));
                }
            }
            let uv_set_ok = e.get("atlas").is_some()
                || u64_of("uv_set").is_some_and(|k| k <= u64::from(u32::MAX));
            let hash = e.get("uv_hash").and_then(serde_json::Value::as_str);
            let hash_ok =
                hash.is_some_and(|h| h.parse::<u64>().is_ok() && (h == "0" || !h.starts_with('0')));
            if e.get("object").and_then(serde_json::Value::as_str) != Some(o.name.as_str())
                || u64_of("width") != Some(u64::from(width))
                || u64_of("height") != Some(u64::from(height))
                || !uv_set_ok
                || !hash_ok
            {
                return Err(bad(format!(
                    "{what} must be {{\"object\": {:?}, \"width\": {width}, \"height\": {height}, \"uv_set\": u32 (or \"atlas\": [u32]), \"uv_hash\": decimal u64 string}}: {e}",
                    o.name
                )));
            }
        }
        Ok(())
    }

    /// Every rule of [`Bake::validate`], in the order of SPEC.md §4.1 step 4; `with_data`
    /// false skips the transfer data and the field's values (a view's skeleton).
    fn check(&self, with_data: bool) -> Result<(), BakeFileError> {
        self.check_bake_fields()?;
        self.check_camera()?;
        self.check_reflectance_field(with_data)?;
        self.check_pass_info()?;
        let mut names = BTreeSet::new();
        for (oi, o) in self.objects.iter().enumerate() {
            self.check_object(oi, o, &mut names, with_data)?;
        }
        self.check_coverage_sums().map_err(|e| e.in_rule(9))?;
        self.check_lightmaps().map_err(|e| e.in_rule(9))?;
        self.check_reflectance_settings()?;
        self.check_settings()?;
        self.check_environment()?;
        self.check_brdfs()?;
        self.check_glossy()
    }

    /// The bake-wide fields (SPEC.md §4 rule 11): a shard of a known count, `settings` an
    /// object, one ray statistic per object with its name and counts within their totals, a
    /// non-empty image.
    fn check_bake_fields(&self) -> Result<(), BakeFileError> {
        let m = &self.meta;
        if m.shard.count == 0 || m.shard.index >= m.shard.count {
            return Err(bad(format!(
                "shard index {} of {} shards",
                m.shard.index, m.shard.count
            )));
        }
        if !m.settings.is_object() {
            return Err(bad("settings must be a JSON object"));
        }
        if !m.ray_stats.is_empty() {
            if m.ray_stats.len() != self.objects.len() {
                return Err(bad(format!(
                    "{} ray statistics for {} objects",
                    m.ray_stats.len(),
                    self.objects.len()
                )));
            }
            for (r, o) in m.ray_stats.iter().zip(&self.objects) {
                if r.object != o.name
                    || r.backface_hits > r.rays
                    || r.inside_rays > r.rays
                    || r.inside_points > r.points
                {
                    return Err(bad(format!(
                        "ray statistics of {:?} do not fit object {:?} (or count more hits than rays)",
                        r.object, o.name
                    )));
                }
            }
        }
        if let SampleKind::Pixel { width, height } | SampleKind::Texel { width, height } =
            m.sample_kind
        {
            if width == 0 || height == 0 {
                return Err(bad("pixel or texel bake with an empty image"));
            }
        }
        Ok(())
    }

    /// The reflectance field's structure (SPEC.md §3.14, rule 9) and, `with_data`, its values
    /// finite and non-negative (rule 10).
    fn check_reflectance_field(&self, with_data: bool) -> Result<(), BakeFileError> {
        let Some(r) = &self.reflectance else {
            return Ok(());
        };
        // (A view's skeleton carries the field's structure without its values.)
        r.check(self.meta.sample_kind, with_data)
            .map_err(|e| e.in_rule(9))?;
        if with_data {
            // On the stored bits: no f32 copy of an f16 field.
            if let Some(i) = r.values.first_breaking(Rule::Finite) {
                return Err(BakeFileError::NonFinite {
                    section: "RFLD".to_owned(),
                    index: i as u64,
                });
            }
            if let Some(i) = r.values.first_breaking(Rule::NonNegative) {
                return Err(bad(format!(
                    "reflectance value {i} is negative ({})",
                    r.values.get(i).unwrap_or(f32::NAN)
                )));
            }
        }
        Ok(())
    }

    /// The `pass` field (SPEC.md §3.12): a pass before the last, one albedo per object.
    fn check_pass_info(&self) -> Result<(), BakeFileError> {
        if let Some(p) = &self.meta.pass {
            if p.index >= p.last || p.albedo.len() != self.objects.len() {
                return Err(bad(format!(
                    "pass {} of a {}-pass bake with {} albedos for {} objects",
                    p.index,
                    p.last + 1,
                    p.albedo.len(),
                    self.objects.len()
                )));
            }
        }
        Ok(())
    }

    /// Object `oi` (SPEC.md §4.1 step 4, per object): its name (unique among `names`), order,
    /// channels and point ranges (rule 11); its mesh, pass state and coverage (rule 9);
    /// its material; its blocks; and, `with_data`, its coverage mask (rule 10).
    fn check_object<'b>(
        &self,
        oi: usize,
        o: &'b ObjectBake,
        names: &mut BTreeSet<&'b str>,
        with_data: bool,
    ) -> Result<(), BakeFileError> {
        let m = &self.meta;
        let what = format!("object {oi} ({:?})", o.name);
        if o.name.is_empty() || !names.insert(o.name.as_str()) {
            return Err(bad(format!("{what}: name empty or not unique")));
        }
        if o.order == 0 || o.order > u32::from(u16::MAX) {
            return Err(bad(format!("{what}: order {} out of 1..=65535", o.order)));
        }
        if o.channels != 1 && o.channels != 3 {
            return Err(bad(format!("{what}: {} channels (1 or 3)", o.channels)));
        }
        self.check_object_points(o, &what)?;
        // Cross-references and counts (SPEC.md §4 rule 9; values: rule 10).
        check_mesh(o, m.sample_kind, &what).map_err(|e| e.in_rule(9))?;
        check_pass(o, m, &what, with_data).map_err(|e| e.in_rule(9))?;
        check_object_coverage(o, m.sample_kind, &what).map_err(|e| e.in_rule(9))?;
        if let Some(material) = &o.material {
            material.check(&o.name)?;
        }
        self.check_blocks(o, &what, with_data)?;
        if with_data {
            check_coverage_mask(o, &what)?;
        }
        Ok(())
    }

    /// An object's point counts: an image's worth where its points are pixels or texels, the
    /// points held within the object's, all of them in an unsharded bake.
    fn check_object_points(&self, o: &ObjectBake, what: &str) -> Result<(), BakeFileError> {
        let m = &self.meta;
        let image = match m.sample_kind {
            SampleKind::Pixel { width, height } => Some((width, height)),
            SampleKind::Texel { width, height } if o.coverage.is_some() => Some((width, height)),
            _ => None,
        };
        if let Some((width, height)) = image {
            if o.point_count != u64::from(width) * u64::from(height) {
                return Err(bad(format!(
                    "{what}: {} points in a {width}×{height} pixel bake",
                    o.point_count
                )));
            }
        }
        let end = o.point_first.checked_add(o.points_in_file);
        if end.is_none_or(|e| e > o.point_count) {
            return Err(bad(format!(
                "{what}: points {}+{} beyond {}",
                o.point_first, o.points_in_file, o.point_count
            )));
        }
        if m.shard.count == 1 && (o.point_first != 0 || o.points_in_file != o.point_count) {
            return Err(bad(format!("{what}: unsharded bake holds a partial range")));
        }
        Ok(())
    }

    /// An object's blocks: each kind (each bounce count) once, interreflection within the
    /// bake's bounces, a clustered-PCA form's structure (rule 9); `with_data`, the data's
    /// length, finiteness, and agreement with its clustered-PCA form.
    fn check_blocks(
        &self,
        o: &ObjectBake,
        what: &str,
        with_data: bool,
    ) -> Result<(), BakeFileError> {
        let expected_len = o.points_in_file.checked_mul(o.scalars_per_point());
        let mut kinds = BTreeSet::new();
        for (bi, b) in o.blocks.iter().enumerate() {
            if !kinds.insert(b.kind) {
                return Err(bad(format!("{what}: kind {:?} twice", b.kind)));
            }
            if let TransferKind::InterreflectedDiffuse { bounces } = b.kind {
                if bounces == 0 || bounces > self.meta.bounces {
                    return Err(bad(format!(
                        "{what}: interreflected block with {bounces} bounces in a {}-bounce bake",
                        self.meta.bounces
                    )));
                }
            }
            if let Some(c) = &b.cpca {
                c.check(
                    o.points_in_file,
                    o.scalars_per_point(),
                    &format!("{what} block {bi}"),
                )
                .map_err(|e| e.in_rule(9))?;
            }
            if !with_data {
                continue;
            }
            if expected_len != Some(b.data.len() as u64) {
                return Err(BakeFileError::InconsistentCounts {
                    what: format!("{what} block {bi}: points × channels × order² scalars"),
                    expected: expected_len.unwrap_or(u64::MAX),
                    found: b.data.len() as u64,
                });
            }
            check_finite32(&format!("{what} block {bi}"), &b.data)?;
            if b.cpca.as_ref().is_some_and(|c| c.reconstruct() != b.data) {
                return Err(bad(format!(
                    "{what} block {bi}: its data is not the reconstruction of its clustered PCA"
                )));
            }
        }
        Ok(())
    }

    /// The environment (SPEC.md §3.6): order 1 … 65535, `3n²` finite values, finite also as
    /// f32 when stored so.
    fn check_environment(&self) -> Result<(), BakeFileError> {
        let Some(env) = &self.environment else {
            return Ok(());
        };
        if env.order == 0 || env.order > u32::from(u16::MAX) {
            return Err(bad(format!("environment order {}", env.order)));
        }
        if env.values.len() as u64 != 3 * sq(env.order) {
            return Err(bad("environment: values.len() != 3 × order²"));
        }
        check_finite64("environment", &env.values)?;
        if env.precision == EnvPrecision::F32 {
            if let Some(i) = env.values.iter().position(|&v| !(v as f32).is_finite()) {
                return Err(BakeFileError::NonFinite {
                    section: "environment (as f32)".into(),
                    index: i as u64,
                });
            }
        }
        Ok(())
    }

    /// The BRDF projections (SPEC.md §3.7): unique non-empty materials, a valid Phong
    /// exponent, order ≥ 1 with as many finite values.
    fn check_brdfs(&self) -> Result<(), BakeFileError> {
        let mut names = BTreeSet::new();
        for b in &self.brdfs {
            let what = format!("BRDF projection {:?}", b.material);
            if b.material.is_empty() || !names.insert(b.material.as_str()) {
                return Err(bad(format!("{what}: material name empty or not unique")));
            }
            if let BrdfLobe::Phong { exponent } = b.lobe {
                if !(exponent.is_finite() && exponent >= 0.0) {
                    return Err(bad(format!("{what}: Phong exponent {exponent}")));
                }
            }
            if b.order == 0 || b.values.len() as u64 != u64::from(b.order) {
                return Err(bad(format!(
                    "{what}: order {} with {} values",
                    b.order,
                    b.values.len()
                )));
            }
            check_finite64(&what, &b.values)?;
        }
        Ok(())
    }

    /// The glossy tables (SPEC.md §3.8): unique non-empty materials, order 1 … 65535, at
    /// least one elevation, array lengths as order and elevations say, finite values.
    fn check_glossy(&self) -> Result<(), BakeFileError> {
        let mut names = BTreeSet::new();
        for g in &self.glossy {
            let what = format!("glossy table {:?}", g.material);
            if g.material.is_empty() || !names.insert(g.material.as_str()) {
                return Err(bad(format!("{what}: material name empty or not unique")));
            }
            if g.order == 0 || g.order > u32::from(u16::MAX) || g.elevations.is_empty() {
                return Err(bad(format!(
                    "{what}: order {} with {} elevations",
                    g.order,
                    g.elevations.len()
                )));
            }
            if g.values.len() as u64 != g.elevations.len() as u64 * sq(g.order)
                || g.projection_error.len() as u64 != u64::from(g.order)
            {
                return Err(bad(format!(
                    "{what}: array lengths do not match order and elevations"
                )));
            }
            check_finite64(&format!("{what} elevations"), &g.elevations)?;
            check_finite64(&format!("{what} values"), &g.values)?;
            check_finite64(&format!("{what} projection_error"), &g.projection_error)?;
        }
        Ok(())
    }
}

/// No transfer where an object's coverage says no sample hit (SPEC.md §3.11, §4 rule 10);
/// compressed blocks only approximate the zeros and are exempt.
fn check_coverage_mask(o: &ObjectBake, what: &str) -> Result<(), BakeFileError> {
    let per = o.scalars_per_point() as usize;
    let zero = |bi: usize, p: usize| {
        o.blocks[bi].cpca.is_some()
            || o.blocks[bi].data[p * per..(p + 1) * per]
                .iter()
                .all(|&v| v == 0.0)
    };
    let found = o
        .coverage
        .as_ref()
        .and_then(|c| uncovered_nonzero(o.point_first, o.blocks.len(), c, zero));
    if let Some((bi, p)) = found {
        return Err(bad(format!(
            "{what} block {bi}: transfer at point {p}, which its coverage says no sample hit"
        ))
        .in_rule(10));
    }
    Ok(())
}
