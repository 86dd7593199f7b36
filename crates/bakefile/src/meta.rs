//! The metadata JSON section (META): its schema, and its agreement with the binary tables.

use serde::{Deserialize, Serialize};

use crate::error::BakeFileError;
use crate::model::{Decision, RayStats, SampleKind, ScalarType, ShardInfo, ToolInfo};

/// Value of `"format"`.
pub(crate) const FORMAT_NAME: &str = "prt-bake";

/// The SH convention every bake of this format uses (CONVENTIONS.md, "Spherical harmonics").
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ShConvention {
    /// `"real-orthonormal"`.
    pub basis: String,
    /// `"condon-shortley"`: the `(-1)^m` factor is included.
    pub phase: String,
    /// `"l(l+1)+m"`: flat coefficient index.
    pub index_order: String,
    /// `"theta-from-+Z, phi=atan2(y,x)"`.
    pub angles: String,
    /// `"band-count"`: order n means bands `l = 0 … n-1`, `n²` coefficients.
    pub order: String,
}

impl ShConvention {
    /// The one convention of format 1.x.
    #[must_use]
    pub fn current() -> Self {
        ShConvention {
            basis: "real-orthonormal".into(),
            phase: "condon-shortley".into(),
            index_order: "l(l+1)+m".into(),
            angles: "theta-from-+Z, phi=atan2(y,x)".into(),
            order: "band-count".into(),
        }
    }
}

/// Value of `"colour_space"`.
pub(crate) const COLOUR_SPACE: &str = "linear-rec709";

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct BlockJson {
    pub kind: String,
    pub bounces: u32,
    pub section: u32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct ObjectJson {
    pub name: String,
    pub geometry_hash: String,
    pub point_count: u64,
    pub point_first: u64,
    pub points_in_file: u64,
    pub order: u32,
    pub channels: u32,
    pub blocks: Vec<BlockJson>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct EnvJson {
    pub order: u32,
    pub precision: crate::model::EnvPrecision,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct BrdfJson {
    pub material: String,
    pub lobe: String,
    pub exponent: Option<f64>,
    pub order: u32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct GlossyJson {
    pub material: String,
    pub elevations: u64,
    pub order: u32,
}

/// The whole META document. Unknown fields are ignored on reading (minor versions may add).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MetaJson {
    pub format: String,
    pub format_version: [u32; 2],
    pub sh: ShConvention,
    pub colour_space: String,
    pub scalar_type: ScalarType,
    pub sample_kind: SampleKind,
    pub rays_per_point: u32,
    pub bounces: u32,
    pub seed: u64,
    pub shard: ShardInfo,
    pub tool: ToolInfo,
    pub settings: serde_json::Value,
    pub decisions: Vec<Decision>,
    pub objects: Vec<ObjectJson>,
    pub environment: Option<EnvJson>,
    pub brdfs: Vec<BrdfJson>,
    pub glossy: Vec<GlossyJson>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ray_stats: Vec<RayStats>,
}

pub(crate) fn hash_string(h: u64) -> String {
    format!("0x{h:016x}")
}

/// Compares one field of the JSON with the binary tables.
pub(crate) fn agree<T: PartialEq + std::fmt::Debug>(
    field: &str,
    json: &T,
    binary: &T,
) -> Result<(), BakeFileError> {
    if json == binary {
        Ok(())
    } else {
        Err(BakeFileError::Metadata(format!(
            "{field} is {json:?} in the JSON but {binary:?} in the binary tables"
        )))
    }
}
