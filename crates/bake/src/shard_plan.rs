//! Sizing a distributed bake before submitting it (`prt bake --plan-shards N`): the expected
//! wall time of each pass and the sizes of its files, measured rather than guessed.
//!
//! The plan runs the whole distributed bake — every pass, every shard, every merge, in this
//! process — twice, at two small ray counts `r` and `2r`, and fits each measured quantity
//! linearly in the rays: a shard's time is a fixed part (loading the previous file, assembling,
//! encoding) plus a part proportional to its rays (tracing in pass 0 and in the last pass of a
//! per-pixel bake, gathering over the recorded hits in the others, whose count is proportional
//! to the rays); a file's size is its levels and transfer (fixed) plus its hit records
//! (proportional). Evaluated at the bake's own ray count, the fit gives each pass's slowest
//! shard, its merge and its file sizes. A shard's time includes reading the files it reads
//! (the previous merged file, its own pass-0 file) and writing its own, on the file system
//! given, and the caller's start-up time (scene and BVH); not the network. Times are for a node like this
//! machine with the same `--threads`; the merged files' sizes do not depend on the rays, so
//! they are exact.

use crate::{bake_pass, BakeError, BakeSettings, PassInput};
use prt_bakefile::{merge, read_bake, write_bake, ScalarType};
use prt_scene::Scene;
use prt_tracer::Accel;
use serde::Serialize;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// What one pass of the planned bake costs.
#[derive(Clone, Debug, Serialize)]
pub struct PassPlan {
    /// Pass index `0 ..= bounces`.
    pub pass: u32,
    /// Expected seconds of the slowest shard.
    pub slowest_shard_seconds: f64,
    /// Expected seconds of the merge.
    pub merge_seconds: f64,
    /// Expected rays traced by all shards together.
    pub rays: f64,
    /// Expected bytes of the largest shard file.
    pub largest_shard_bytes: f64,
    /// Expected bytes of all shard files together.
    pub shard_bytes: f64,
    /// Bytes of the merged file (the final bake for the last pass).
    pub merged_bytes: f64,
}

/// The plan of a distributed bake ([`plan_shards`]).
#[derive(Clone, Debug, Serialize)]
pub struct ShardPlan {
    /// Shards per pass.
    pub shards: u32,
    /// The bake's rays per point.
    pub rays: u32,
    /// The two ray counts the bake was measured at.
    pub probe_rays: [u32; 2],
    /// Seconds the two measurements took here.
    pub probe_seconds: f64,
    /// Per pass.
    pub passes: Vec<PassPlan>,
}

impl ShardPlan {
    /// Expected wall time of the whole bake: every pass's slowest shard and merge, in turn
    /// (scheduling and file transfer not included).
    #[must_use]
    pub fn wall_seconds(&self) -> f64 {
        self.passes
            .iter()
            .map(|p| p.slowest_shard_seconds + p.merge_seconds)
            .sum()
    }
}

/// One pass measured at one ray count: per shard its seconds, rays and bytes, and the merge.
struct Measured {
    shard_seconds: Vec<f64>,
    shard_rays: Vec<f64>,
    shard_bytes: Vec<f64>,
    merge_seconds: f64,
    merged_bytes: f64,
}

/// Runs every pass of the bake in `shards` shards at `rays` rays per point, as the shard and
/// merge processes would: each shard reads the previous merged file and its own pass-0 file
/// from `dir` and writes its file there; each merge reads the pass's shard files and writes the
/// merged file.
fn measure(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    shards: u32,
    rays: u32,
    dir: &Path,
) -> Result<Vec<Measured>, BakeError> {
    let file = |name: String| dir.join(format!("{name}-{rays}.prtb"));
    let mut passes = Vec::new();
    for index in 0..=settings.bounces {
        let mut m = Measured {
            shard_seconds: Vec::new(),
            shard_rays: Vec::new(),
            shard_bytes: Vec::new(),
            merge_seconds: 0.0,
            merged_bytes: 0.0,
        };
        let reads_hits = settings.pass_gathers_at_vertices(index);
        let shard_files: Vec<PathBuf> = (0..shards)
            .map(|i| file(format!("pass{index}-shard{i}")))
            .collect();
        for (shard, out_path) in (0..shards).zip(&shard_files) {
            let s = BakeSettings {
                rays,
                shard: Some((shard, shards)),
                progress: false,
                ..settings.clone()
            };
            let start = Instant::now();
            let previous = (index > 0)
                .then(|| read_bake(&file(format!("pass{}", index - 1))))
                .transpose()?;
            let hits = reads_hits
                .then(|| read_bake(&file(format!("pass0-shard{shard}"))))
                .transpose()?;
            let input = PassInput {
                index,
                previous: previous.as_ref(),
                hits: hits.as_ref(),
            };
            let out = bake_pass(scene, accel, &s, Some(input))?;
            write_bake(out_path, &out.bake, ScalarType::F32)?;
            m.shard_seconds.push(start.elapsed().as_secs_f64());
            m.shard_rays.push(out.report.rays_traced as f64);
            m.shard_bytes.push(file_size(out_path)?);
        }
        let start = Instant::now();
        let files = shard_files
            .iter()
            .map(|p| read_bake(p))
            .collect::<Result<Vec<_>, _>>()?;
        let merged_path = file(format!("pass{index}"));
        write_bake(&merged_path, &merge(&files)?, ScalarType::F32)?;
        m.merge_seconds = start.elapsed().as_secs_f64();
        m.merged_bytes = file_size(&merged_path)?;
        passes.push(m);
    }
    Ok(passes)
}

fn file_size(path: &Path) -> Result<f64, BakeError> {
    let meta = std::fs::metadata(path)
        .map_err(|e| BakeError::File(prt_bakefile::BakeFileError::from(e).in_file(path)))?;
    Ok(meta.len() as f64)
}

/// The straight line through `(x0, y0)` and `(x1, y1)` at `x`, never below 0.
fn extrapolate(x0: f64, y0: f64, x1: f64, y1: f64, x: f64) -> f64 {
    (y0 + (y1 - y0) / (x1 - x0) * (x - x0)).max(0.0)
}

/// Plans the bake of `settings` split into `shards` shards per pass (every pass of its
/// `bounces`): measures it at `probe_rays` and twice that many rays per point and extrapolates
/// linearly to `settings.rays` (module docs). `startup_seconds` is what a shard process pays
/// before it bakes (loading the scene and building its BVH), added to every shard. The
/// measured bakes write their files under `work_dir` (in a directory removed afterwards): give
/// it the file system the bake will use, since reading and writing the files is part of the
/// time.
///
/// # Errors
/// Bad settings (a shard count of 0 or more shards than some object has points is refused by
/// the bake itself), or a failure of the measured bakes.
pub fn plan_shards(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    shards: u32,
    probe_rays: u32,
    startup_seconds: f64,
    work_dir: &Path,
) -> Result<ShardPlan, BakeError> {
    if shards == 0 {
        return Err(BakeError::InvalidSettings(
            "--plan-shards: give at least 1 shard".into(),
        ));
    }
    let probe = [probe_rays.max(1), probe_rays.max(1) * 2];
    let start = Instant::now();
    let dir = tempfile::Builder::new()
        .prefix("prt-plan-")
        .tempdir_in(work_dir)
        .map_err(|e| BakeError::File(prt_bakefile::BakeFileError::from(e).in_file(work_dir)))?;
    let low = measure(scene, accel, settings, shards, probe[0], dir.path())?;
    let high = measure(scene, accel, settings, shards, probe[1], dir.path())?;
    let (x0, x1, x) = (
        f64::from(probe[0]),
        f64::from(probe[1]),
        f64::from(settings.rays),
    );
    let at = |a: f64, b: f64| extrapolate(x0, a, x1, b, x);
    let passes = low
        .iter()
        .zip(&high)
        .zip(0..)
        .map(|((a, b), pass)| {
            let per_shard = |va: &[f64], vb: &[f64]| -> Vec<f64> {
                va.iter().zip(vb).map(|(&p, &q)| at(p, q)).collect()
            };
            let seconds = per_shard(&a.shard_seconds, &b.shard_seconds);
            let bytes = per_shard(&a.shard_bytes, &b.shard_bytes);
            let rays = per_shard(&a.shard_rays, &b.shard_rays);
            PassPlan {
                pass,
                slowest_shard_seconds: startup_seconds
                    + seconds.iter().copied().fold(0.0, f64::max),
                merge_seconds: at(a.merge_seconds, b.merge_seconds),
                rays: rays.iter().sum(),
                largest_shard_bytes: bytes.iter().copied().fold(0.0, f64::max),
                shard_bytes: bytes.iter().sum(),
                merged_bytes: at(a.merged_bytes, b.merged_bytes),
            }
        })
        .collect();
    Ok(ShardPlan {
        shards,
        rays: settings.rays,
        probe_rays: probe,
        probe_seconds: start.elapsed().as_secs_f64(),
        passes,
    })
}

#[cfg(test)]
mod tests {
    use super::extrapolate;

    #[test]
    fn extrapolation_is_the_line_through_the_two_measurements() {
        assert_eq!(extrapolate(16.0, 3.0, 32.0, 5.0, 1024.0), 3.0 + 2.0 * 63.0);
        assert_eq!(extrapolate(16.0, 7.0, 32.0, 7.0, 4096.0), 7.0);
        // Noise that makes a size fall with the rays never extrapolates below zero.
        assert_eq!(extrapolate(16.0, 5.0, 32.0, 4.0, 4096.0), 0.0);
    }
}
