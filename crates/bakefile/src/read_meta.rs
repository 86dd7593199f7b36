//! SPEC.md §4 rule 11, as far as the binary tables decide it: the `META` section (§3.9) is
//! JSON with unique keys, every mandatory field and its types, and it agrees with the header
//! and the binary sections, field by field, in the order the reader checks them (§4.1).

use crate::error::BakeFileError;
use crate::located::BinarySections;
use crate::meta::{
    agree, check_mandatory, hash_string, MetaJson, ShConvention, COLOUR_SPACE, FORMAT_NAME,
};
use crate::model::{BrdfLobe, SampleKind};

/// Parses the `META` payload of a file of minor version `minor`: JSON syntax, unique keys,
/// the mandatory fields, the types.
pub(crate) fn read_meta(meta_bytes: &[u8], minor: u32) -> Result<MetaJson, BakeFileError> {
    let value: serde_json::Value = serde_json::from_slice(meta_bytes)
        .map_err(|e| BakeFileError::Metadata(format!("not valid JSON: {e}")))?;
    crate::meta::check_unique_keys(meta_bytes)?;
    check_mandatory(&value, minor)?;
    serde_json::from_value(value)
        .map_err(|e| BakeFileError::Metadata(format!("not valid metadata JSON: {e}")))
}

/// The metadata agrees with everything the binary sections say: the bake-wide fields, the
/// objects, then the environment and BRDF tables.
pub(crate) fn check_agreement(json: &MetaJson, b: &BinarySections) -> Result<(), BakeFileError> {
    agree_bake_fields(json, b)?;
    agree_objects(json, b)?;
    agree_scene(json, b)
}

/// The fixed values, the version, and the fields `BINF` and the header hold; a per-pixel file
/// of minor ≥ 1 has its camera.
fn agree_bake_fields(json: &MetaJson, b: &BinarySections) -> Result<(), BakeFileError> {
    let (major, minor) = b.version;
    let info = &b.info;
    agree("format", &json.format.as_str(), &FORMAT_NAME)?;
    agree("format_version", &json.format_version, &[major, minor])?;
    agree("sh", &json.sh, &ShConvention::current())?;
    agree("colour_space", &json.colour_space.as_str(), &COLOUR_SPACE)?;
    agree("scalar_type", &json.scalar_type, &b.scalar)?;
    agree("sample_kind", &json.sample_kind, &info.sample)?;
    agree("rays_per_point", &json.rays_per_point, &info.rays_per_point)?;
    agree("bounces", &json.bounces, &info.bounces)?;
    agree("seed", &json.seed, &info.seed)?;
    agree("shard", &json.shard, &info.shard)?;
    if minor >= 1 && matches!(info.sample, SampleKind::Pixel { .. }) && json.camera.is_none() {
        return Err(BakeFileError::Metadata(
            "a per-pixel bake of format 1.1 must record its camera".into(),
        ));
    }
    Ok(())
}

/// One `objects[]` entry per `OBJT` record; the ray statistics; per object its fields and
/// blocks as the tables give them; then per object its `mesh` and `coverage`.
fn agree_objects(json: &MetaJson, b: &BinarySections) -> Result<(), BakeFileError> {
    let objects = &b.objects;
    agree("objects.len()", &json.objects.len(), &objects.len())?;
    agree_ray_stats(json, b)?;
    for (j, o) in json.objects.iter().zip(objects) {
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
        for (jb, block) in j.blocks.iter().zip(&o.blocks) {
            agree(&f("blocks[].kind"), &jb.kind.as_str(), &block.kind.name())?;
            agree(&f("blocks[].bounces"), &jb.bounces, &block.kind.bounces())?;
            agree(&f("blocks[].section"), &jb.section, &block.section_index)?;
        }
    }
    for ((j, o), (mesh, coverage)) in json
        .objects
        .iter()
        .zip(objects)
        .zip(b.meshes.iter().zip(&b.coverages))
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
    Ok(())
}

/// `ray_stats`, when present: one entry per object, with its name, counting no more hits
/// than rays or points.
fn agree_ray_stats(json: &MetaJson, b: &BinarySections) -> Result<(), BakeFileError> {
    if json.ray_stats.is_empty() {
        return Ok(());
    }
    agree("ray_stats.len()", &json.ray_stats.len(), &b.objects.len())?;
    for (r, o) in json.ray_stats.iter().zip(&json.objects) {
        agree("ray_stats[].object", &r.object, &o.name)?;
        if r.backface_hits > r.rays || r.inside_rays > r.rays || r.inside_points > r.points {
            return Err(BakeFileError::Metadata(format!(
                "ray statistics of {:?} count more hits than rays or points",
                r.object
            )));
        }
    }
    Ok(())
}

/// `environment` as `ENVL` says; `brdfs` and `glossy` record by record as `BRDF` and `GLSY`.
fn agree_scene(json: &MetaJson, b: &BinarySections) -> Result<(), BakeFileError> {
    let env_json = b.environment.as_ref().map(|e| (e.order, e.precision));
    agree(
        "environment",
        &json.environment.as_ref().map(|e| (e.order, e.precision)),
        &env_json,
    )?;
    agree("brdfs.len()", &json.brdfs.len(), &b.brdfs.len())?;
    for (j, p) in json.brdfs.iter().zip(&b.brdfs) {
        let (lobe, exponent) = match p.lobe {
            BrdfLobe::ClampedCosine => ("clamped-cosine", None),
            BrdfLobe::Phong { exponent } => ("phong", Some(exponent)),
        };
        agree("brdfs[].material", &j.material, &p.material)?;
        agree("brdfs[].lobe", &j.lobe.as_str(), &lobe)?;
        agree(
            "brdfs[].exponent",
            &j.exponent.map(f64::to_bits),
            &exponent.map(f64::to_bits),
        )?;
        agree("brdfs[].order", &j.order, &p.order)?;
    }
    agree("glossy.len()", &json.glossy.len(), &b.glossy.len())?;
    for (j, g) in json.glossy.iter().zip(&b.glossy) {
        agree("glossy[].material", &j.material, &g.material)?;
        agree(
            "glossy[].elevations",
            &j.elevations,
            &(g.elevations.len() as u64),
        )?;
        agree("glossy[].order", &j.order, &g.order)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn metadata_is_json_with_unique_keys_and_its_mandatory_fields() {
        let err = |text: &str| read_meta(text.as_bytes(), 2).unwrap_err().to_string();
        assert!(
            err("{").starts_with("metadata: not valid JSON"),
            "{}",
            err("{")
        );
        assert!(err(r#"{"format": 1, "format": 2}"#).contains("format"));
        assert!(
            err("{}").starts_with("metadata: missing mandatory field"),
            "{}",
            err("{}")
        );
    }
}
