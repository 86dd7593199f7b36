//! The report's cache of references and bakes (`DIR/cache/`): each result is keyed by a hash of
//! everything it depends on (geometry, materials, environment texels, settings, the crate
//! version and [`CACHE_EPOCH`]), so a second run reuses what did not change and never what
//! different code or inputs made.

use crate::error::ReportError;
use prt_bake::{BakeSettings, PointKind};
use prt_bakefile::Bake;
use prt_scene::Scene;
use prt_scene_relight::relit::check_bake;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// FNV-1a 64 of `bytes`, continuing from `h`.
pub(crate) fn fnv(bytes: &[u8], mut h: u64) -> u64 {
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0000_0100_0000_01b3);
    }
    h
}

/// Bumped whenever the tracer or the baker changes what they compute for the same inputs, so a
/// report never reuses a cached reference or bake made by different code (with the crate
/// version, part of every cache key). 2: per-pixel bakes share one sequence per pixel.
pub(crate) const CACHE_EPOCH: u32 = 2;

/// Cache key of a bake: the geometry hashes, materials, environment texels and settings.
pub(crate) fn bake_key(scene: &Scene, s: &BakeSettings) -> u64 {
    let h = scene_key(scene);
    let h = if s.points == PointKind::Pixel {
        fnv(
            format!("{:?} {}", scene.camera, s.pixel_samples).as_bytes(),
            h,
        )
    } else {
        h
    };
    fnv(
        format!(
            "{:?} {:?} {} {} {} {}",
            s.order, s.points, s.rays, s.bounces, s.seed, s.error_target
        )
        .as_bytes(),
        h,
    )
}

/// Cache key of a reference render: the scene, its camera and the render settings.
pub(crate) fn reference_key(scene: &Scene, r: &prt_tracer::RenderSettings) -> u64 {
    fnv(
        format!(
            "{:?} {} {} {} {:?} {:?} {:?}",
            scene.camera, r.spp, r.bounces, r.seed, r.mode, r.mis, r.target_psnr_ldr
        )
        .as_bytes(),
        scene_key(scene),
    )
}

/// Hash of what every cached result depends on: geometry, materials, environment texels.
pub(crate) fn scene_key(scene: &Scene) -> u64 {
    let mut h = fnv(
        format!("{} {CACHE_EPOCH}", env!("CARGO_PKG_VERSION")).as_bytes(),
        0xcbf2_9ce4_8422_2325u64,
    );
    for m in &scene.meshes {
        h = fnv(
            &prt_scene::binding::geometry_hash(&m.positions, &m.indices).to_le_bytes(),
            h,
        );
        h = fnv(&(m.material as u64).to_le_bytes(), h);
    }
    h = fnv(format!("{:?}", scene.materials).as_bytes(), h);
    let env = &scene.environment;
    h = fnv(
        format!(
            "{:?} {} {}x{}",
            env.mapping, env.rotation_y_deg, env.image.width, env.image.height
        )
        .as_bytes(),
        h,
    );
    for t in &env.image.texels {
        for c in t {
            h = fnv(&c.to_le_bytes(), h);
        }
    }
    h
}

/// A bake from the report's cache (`DIR/cache/bake-KEY.prtb`), or baked and cached: the bake,
/// its file and the bake time (`None` when reused).
pub(crate) fn cached_bake(
    scene: &Scene,
    accel: &prt_tracer::Accel,
    out_dir: &Path,
    bs: &BakeSettings,
    what: &str,
    progress: bool,
) -> Result<(Bake, PathBuf, Option<f64>), ReportError> {
    let key = bake_key(scene, bs);
    let path = out_dir.join("cache").join(format!("bake-{key:016x}.prtb"));
    if let Some(b) = prt_bakefile::read_bake(&path)
        .ok()
        .filter(|b| check_bake(scene, b, &path).is_ok())
    {
        if progress {
            eprintln!("report: reusing the cached {what} {}", path.display());
        }
        return Ok((b, path, None));
    }
    if progress {
        eprintln!(
            "report: baking the {what}: order {}, {} rays per point, {} bounce(s)",
            bs.order.map_or("auto".into(), |o| o.to_string()),
            bs.rays,
            bs.bounces
        );
    }
    let t = Instant::now();
    let out = prt_bake::bake(scene, accel, bs)?;
    let seconds = t.elapsed().as_secs_f64();
    prt_bakefile::write_bake(&path, &out.bake, prt_bakefile::ScalarType::F32)?;
    Ok((out.bake, path, Some(seconds)))
}

/// Where a report's bake cache lives.
#[must_use]
pub fn cache_dir(out_dir: &Path) -> PathBuf {
    out_dir.join("cache")
}

#[cfg(test)]
mod tests {
    use super::fnv;

    #[test]
    fn fnv_is_fnv1a_64() {
        // The published FNV-1a 64 vectors, from the offset basis.
        let basis = 0xcbf2_9ce4_8422_2325u64;
        assert_eq!(fnv(b"", basis), basis);
        assert_eq!(fnv(b"a", basis), 0xaf63_dc4c_8601_ec8c);
        assert_eq!(fnv(b"foobar", basis), 0x8594_4171_f739_67e8);
        // Continuing from a hash is hashing the concatenation.
        assert_eq!(fnv(b"bar", fnv(b"foo", basis)), fnv(b"foobar", basis));
    }
}
