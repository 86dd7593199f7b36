//! The metadata JSON section (META): its schema, and its agreement with the binary tables.

use serde::{Deserialize, Serialize};

use crate::error::BakeFileError;
use crate::model::{
    CameraInfo, Decision, PassInfo, RayStats, SampleKind, ScalarType, ShardInfo, ToolInfo,
};

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
    /// 1.1; absent in 1.0 files (read as `None`), always written.
    #[serde(default)]
    pub mesh: Option<MeshJson>,
    /// 1.1; absent in 1.0 files (read as `None`), always written.
    #[serde(default)]
    pub coverage: Option<CoverageJson>,
    /// 1.2; absent in older files (read as `None`), always written.
    #[serde(default)]
    pub material: Option<crate::MaterialBinding>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct MeshJson {
    pub section: u32,
    pub vertices: u32,
    pub triangles: u32,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub(crate) struct CoverageJson {
    pub section: u32,
    pub pixel_samples: u32,
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
    #[serde(with = "seed_json")]
    pub seed: u64,
    pub shard: ShardInfo,
    pub tool: ToolInfo,
    /// 1.1; absent in 1.0 files (read as `None`), always written.
    #[serde(default)]
    pub camera: Option<CameraInfo>,
    pub settings: serde_json::Value,
    pub decisions: Vec<Decision>,
    pub objects: Vec<ObjectJson>,
    pub environment: Option<EnvJson>,
    pub brdfs: Vec<BrdfJson>,
    pub glossy: Vec<GlossyJson>,
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub ray_stats: Vec<RayStats>,
    /// Intermediate pass files only (absent from every final bake).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub pass: Option<PassInfo>,
}

/// `seed` in the JSON: a decimal string since 1.1 (exact in every JSON parser), a number in
/// 1.0 files (still read).
mod seed_json {
    use serde::{Deserialize, Deserializer, Serializer};

    pub fn serialize<S: Serializer>(seed: &u64, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_str(&seed.to_string())
    }

    #[derive(Deserialize)]
    #[serde(untagged)]
    enum Seed {
        Number(u64),
        Text(String),
    }

    pub fn deserialize<'de, D: Deserializer<'de>>(d: D) -> Result<u64, D::Error> {
        match Seed::deserialize(d)? {
            Seed::Number(n) => Ok(n),
            Seed::Text(t) => {
                let canonical = !t.is_empty()
                    && t.bytes().all(|b| b.is_ascii_digit())
                    && (t == "0" || !t.starts_with('0'));
                t.parse::<u64>().ok().filter(|_| canonical).ok_or_else(|| {
                    serde::de::Error::custom(format!(
                        "seed {t:?} is not a decimal u64 without sign or leading zeros"
                    ))
                })
            }
        }
    }
}

/// The fields every file's metadata has (SPEC.md §3.9, "Mandatory fields"), top level and per
/// object: a reader refuses a file missing one (serde alone would read a missing optional
/// value as `null`).
pub(crate) const MANDATORY_FIELDS: [&str; 17] = [
    "format",
    "format_version",
    "sh",
    "colour_space",
    "scalar_type",
    "sample_kind",
    "rays_per_point",
    "bounces",
    "seed",
    "shard",
    "tool",
    "settings",
    "decisions",
    "objects",
    "environment",
    "brdfs",
    "glossy",
];

/// Mandatory fields of each `objects[]` entry.
pub(crate) const MANDATORY_OBJECT_FIELDS: [&str; 8] = [
    "name",
    "geometry_hash",
    "point_count",
    "point_first",
    "points_in_file",
    "order",
    "channels",
    "blocks",
];

/// Checks that the metadata of a file of minor version `minor` has every mandatory field
/// (types are checked by parsing it): since 1.2 every object's `material` too.
pub(crate) fn check_mandatory(value: &serde_json::Value, minor: u32) -> Result<(), BakeFileError> {
    let missing = |what: String| BakeFileError::Metadata(format!("missing mandatory field {what}"));
    let obj = value
        .as_object()
        .ok_or_else(|| BakeFileError::Metadata("the metadata is not a JSON object".into()))?;
    for f in MANDATORY_FIELDS {
        if !obj.contains_key(f) {
            return Err(missing(format!("`{f}`")));
        }
    }
    if let Some(objects) = obj.get("objects").and_then(serde_json::Value::as_array) {
        for (i, o) in objects.iter().enumerate() {
            for f in MANDATORY_OBJECT_FIELDS {
                if o.get(f).is_none() {
                    return Err(missing(format!("`objects[{i}].{f}`")));
                }
            }
            if minor >= 2 && o.get("material").is_none() {
                return Err(missing(format!(
                    "`objects[{i}].material` (format 1.2; null when unknown)"
                )));
            }
        }
    }
    Ok(())
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

/// Refuses metadata in which some JSON object has two members with the same key (SPEC.md §4
/// rule 11): RFC 8259 leaves such a document's meaning to the parser (most keep the last,
/// some the first), so two readers could read two different bakes from one file.
pub(crate) fn check_unique_keys(bytes: &[u8]) -> Result<(), BakeFileError> {
    use serde::de::DeserializeSeed;
    let mut de = serde_json::Deserializer::from_slice(bytes);
    UniqueKeys
        .deserialize(&mut de)
        .and_then(|()| de.end())
        .map_err(|e| BakeFileError::Metadata(format!("not valid metadata JSON: {e}")))
}

/// A walk over any JSON value that fails on a repeated key.
struct UniqueKeys;

impl<'de> serde::de::DeserializeSeed<'de> for UniqueKeys {
    type Value = ();
    fn deserialize<D: serde::Deserializer<'de>>(self, d: D) -> Result<(), D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for UniqueKeys {
    type Value = ();
    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("a JSON value")
    }
    fn visit_bool<E>(self, _: bool) -> Result<(), E> {
        Ok(())
    }
    fn visit_i64<E>(self, _: i64) -> Result<(), E> {
        Ok(())
    }
    fn visit_u64<E>(self, _: u64) -> Result<(), E> {
        Ok(())
    }
    fn visit_f64<E>(self, _: f64) -> Result<(), E> {
        Ok(())
    }
    fn visit_str<E>(self, _: &str) -> Result<(), E> {
        Ok(())
    }
    fn visit_unit<E>(self) -> Result<(), E> {
        Ok(())
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<(), A::Error> {
        while seq.next_element_seed(UniqueKeys)?.is_some() {}
        Ok(())
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<(), A::Error> {
        let mut seen = std::collections::BTreeSet::new();
        while let Some(key) = map.next_key::<String>()? {
            if !seen.insert(key.clone()) {
                return Err(serde::de::Error::custom(format!(
                    "the key {key:?} appears twice in one JSON object"
                )));
            }
            map.next_value_seed(UniqueKeys)?;
        }
        Ok(())
    }
}
