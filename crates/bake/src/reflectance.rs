//! Reflectance fields (Masselus, Peers, Dutré & Willems, "Relighting with 4D Incident Light
//! Fields" / "Smooth Reconstruction and Compact Representation of Reflectance Functions for
//! Image-based Relighting", EGSR 2004): per camera pixel, the pixel's response to a distant
//! light from each direction of a `W × H` latitude-longitude grid — a virtual light stage.
//!
//! For pixel `p` with footprint samples `k = 1 … K` (the box footprint of `prt render`, as
//! per-pixel bakes use) that hit surface points `x_k` seen from `ω_o,k`, the sampled value at
//! grid direction `ω_j` (the centre of lat-long cell `j`, CONVENTIONS.md's mapping) is
//!
//! `R_p(ω_j) = (1/K) Σ_k [ f(x_k, ω_o,k, ω_j) max(0, n·ω_j) V(x_k, ω_j) + indirect_k(ω_j) ]`
//!
//! in 1/sr, so that the pixel under a distant light `L` is `∫ R_p(ω) L(ω) dω` plus the
//! environment its background samples see. Direct light has exact visibility (one shadow ray
//! per sample and direction). With `B ≥ 1` bounces, `indirect_k` follows `rays` BSDF-sampled
//! paths of up to `B` bounces from `x_k` and, at every path vertex `y`, adds the path
//! throughput times `f(y, ·, ω_j) max(0, n_y·ω_j) V(y, ω_j)` for every `j` at once (next-event
//! estimation towards each grid direction), so every direction shares the same paths. Delta
//! lobes (mirrors) have no value at a grid direction: their reflections are not represented.

use crate::error::BakeError;
use crate::points::{pixel_footprints, SamplePoint};
use glam::Vec3;
use prt_bakefile::ReflectanceField;
use prt_scene::{Material, Scene};
use prt_shading::{eval, sample};
use prt_tracer::Accel;
use rand::{Rng, SeedableRng};
use rayon::prelude::*;

/// The largest direction grid `prt reflectance` samples (`W · H`).
pub const MAX_DIRECTIONS: u64 = 1 << 16;

/// Settings of [`sample_field`].
#[derive(Clone, Debug)]
pub struct ReflectanceSettings {
    /// Direction grid `[W, H]` (azimuth, polar), `W ≥ 2`, `H ≥ 1`.
    pub directions: [u32; 2],
    /// Interreflection bounces (0: direct light only).
    pub bounces: u32,
    /// Paths per footprint sample for the bounces.
    pub rays: u32,
    /// Footprint samples per pixel.
    pub pixel_samples: u32,
    /// Global seed.
    pub seed: u64,
    /// Show a progress bar on a terminal.
    pub progress: bool,
}

/// The unit direction at the centre of cell `j = row · W + column` of a `W × H` lat-long grid
/// (CONVENTIONS.md: `φ = 2π(column + ½)/W`, `θ = π(row + ½)/H`,
/// `d = (sin φ sin θ, cos θ, −cos φ sin θ)`).
#[must_use]
pub fn grid_direction(w: u32, h: u32, j: usize) -> Vec3 {
    let (col, row) = (j % w as usize, j / w as usize);
    let phi = 2.0 * std::f64::consts::PI * (col as f64 + 0.5) / f64::from(w);
    let theta = std::f64::consts::PI * (row as f64 + 0.5) / f64::from(h);
    glam::DVec3::new(
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    )
    .as_vec3()
}

/// Shadow rays the field costs: `pixels · K · (1 + rays · B) · W · H` at most.
#[must_use]
pub fn shadow_ray_estimate(scene: &Scene, s: &ReflectanceSettings) -> u64 {
    let pixels = u64::from(scene.camera.width) * u64::from(scene.camera.height);
    let dirs = u64::from(s.directions[0]) * u64::from(s.directions[1]);
    pixels
        .saturating_mul(u64::from(s.pixel_samples.max(1)))
        .saturating_mul(1 + u64::from(s.rays) * u64::from(s.bounces))
        .saturating_mul(dirs)
}

/// What [`sample_field`] measured.
#[derive(Clone, Copy, Debug, Default)]
pub struct FieldStats {
    /// Pixels held (some footprint sample hit a surface).
    pub pixels: u64,
    /// Shadow rays traced.
    pub shadow_rays: u64,
    /// Seconds.
    pub seconds: f64,
}

/// Samples the reflectance field of `scene`'s camera image.
///
/// # Errors
/// Impossible settings (a grid smaller than 2 × 1 or above [`MAX_DIRECTIONS`], no footprint
/// samples), and the tracer's camera errors.
pub fn sample_field(
    scene: &Scene,
    accel: &Accel,
    s: &ReflectanceSettings,
) -> Result<(ReflectanceField, FieldStats), BakeError> {
    let start = std::time::Instant::now();
    let [w, h] = s.directions;
    let dirs = u64::from(w) * u64::from(h);
    if w < 2 || h < 1 || dirs > MAX_DIRECTIONS {
        return Err(BakeError::InvalidSettings(format!(
            "--directions {w}x{h}: give at least 2x1 and at most {MAX_DIRECTIONS} directions"
        )));
    }
    if s.pixel_samples == 0 || s.pixel_samples > crate::MAX_PIXEL_SAMPLES {
        return Err(BakeError::InvalidSettings(format!(
            "{} pixel samples: give between 1 and {}",
            s.pixel_samples,
            crate::MAX_PIXEL_SAMPLES
        )));
    }
    if s.bounces > 0 && s.rays == 0 {
        return Err(BakeError::InvalidSettings(
            "bounces need at least one path per sample (--rays)".into(),
        ));
    }
    let d = dirs as usize;
    let directions: Vec<Vec3> = (0..d).map(|j| grid_direction(w, h, j)).collect();
    let fp = pixel_footprints(scene, accel, s.seed, s.pixel_samples)?;
    let k = s.pixel_samples as usize;
    let bar = crate::progress_bar(s.progress, fp.pixel_count() as u64, "pixels");
    // Per pixel: its function (3 × D) or None when no sample hits a surface.
    let rows: Vec<(Option<Vec<f32>>, u64)> = (0..fp.pixel_count())
        .into_par_iter()
        .with_min_len(4)
        .map(|px| {
            let mut acc = vec![0.0f64; 3 * d];
            let mut any = false;
            let mut rays = 0u64;
            for (ki, smp) in fp.pixel(px).iter().enumerate() {
                let (Some((mesh, point)), Some(at)) = (smp.hit, smp.at) else {
                    continue;
                };
                any = true;
                let mat = scene.material_at(mesh, at);
                let wo = -smp.dir;
                rays += add_direct(accel, &point, &mat, wo, &directions, 1.0, &mut acc);
                if s.bounces > 0 {
                    let key = [s.seed, px as u64, ki as u64];
                    rays += add_indirect(
                        scene,
                        accel,
                        (&point, &mat, wo),
                        &directions,
                        s,
                        key,
                        &mut acc,
                    );
                }
            }
            bar.inc(1);
            let scale = 1.0 / k as f64;
            (
                any.then(|| acc.iter().map(|v| (v * scale) as f32).collect()),
                rays,
            )
        })
        .collect();
    bar.finish_and_clear();
    let mut pixels = Vec::new();
    let mut values = Vec::new();
    let mut shadow_rays = 0u64;
    for (px, (row, rays)) in rows.into_iter().enumerate() {
        shadow_rays += rays;
        if let Some(r) = row {
            pixels.push(px as u32);
            values.extend(r);
        }
    }
    let stats = FieldStats {
        pixels: pixels.len() as u64,
        shadow_rays,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((
        ReflectanceField {
            directions: [w, h],
            pixels,
            values: prt_bakefile::FieldValues::from_f32(&values),
        },
        stats,
    ))
}

/// Adds `weight · f(ω_o, ω_j) max(0, n·ω_j) V(ω_j)` for every grid direction to `acc`
/// (`[channel][direction]`); returns the shadow rays traced.
fn add_direct(
    accel: &Accel,
    p: &SamplePoint,
    mat: &Material,
    wo: Vec3,
    directions: &[Vec3],
    weight: f64,
    acc: &mut [f64],
) -> u64 {
    let d = directions.len();
    let mut rays = 0;
    for (j, &wi) in directions.iter().enumerate() {
        let cos = p.normal.dot(wi);
        if cos <= 0.0 || p.offset_normal.dot(wi) <= 0.0 {
            continue;
        }
        let f = eval(mat, p.normal, wo, wi);
        if f == Vec3::ZERO {
            continue;
        }
        rays += 1;
        if accel.occluded(p.origin(wi), wi, f32::INFINITY) {
            continue;
        }
        let v = f * cos;
        for c in 0..3 {
            acc[c * d + j] += weight * f64::from(v[c]);
        }
    }
    rays
}

/// Indirect light of one footprint sample: `rays` BSDF-sampled paths of up to `bounces`
/// bounces, next-event estimation towards every grid direction at each vertex.
fn add_indirect(
    scene: &Scene,
    accel: &Accel,
    start: (&SamplePoint, &Material, Vec3),
    directions: &[Vec3],
    s: &ReflectanceSettings,
    key: [u64; 3],
    acc: &mut [f64],
) -> u64 {
    let mut rng = rand_pcg::Pcg64Mcg::seed_from_u64(
        key[0]
            ^ 0x7265_666c_6563_7400
            ^ key[1].wrapping_mul(0x9e37_79b9_7f4a_7c15)
            ^ key[2].wrapping_mul(0xc2b2_ae3d_27d4_eb4f),
    );
    let mut rays = 0;
    let per_path = 1.0 / f64::from(s.rays);
    for _ in 0..s.rays {
        let (mut point, mut mat, mut wo) = (*start.0, *start.1, start.2);
        let mut beta = Vec3::ONE;
        for _ in 0..s.bounces {
            let u = [
                rng.random::<f32>(),
                rng.random::<f32>(),
                rng.random::<f32>(),
            ];
            let Some(bs) = sample(&mat, point.normal, wo, u) else {
                break;
            };
            if bs.is_delta || point.offset_normal.dot(bs.wi) <= 0.0 {
                break;
            }
            beta *= bs.weight;
            if beta == Vec3::ZERO || !beta.is_finite() {
                break;
            }
            let Some(hit) = accel.closest_hit(point.origin(bs.wi), bs.wi, f32::INFINITY) else {
                break;
            };
            let at = prt_scene::SurfacePoint::Triangle {
                tri: hit.tri,
                u: hit.u,
                v: hit.v,
            };
            mat = scene.material_at(hit.mesh as usize, at);
            wo = -bs.wi;
            // Both normals turned towards where the path came from (two-sided surfaces, as
            // the path tracer shades them).
            let toward = |n: Vec3| if n.dot(wo) < 0.0 { -n } else { n };
            point = SamplePoint {
                position: hit.position,
                normal: toward(hit.shading_normal),
                offset_normal: toward(hit.geometric_normal),
                offset: hit.offset,
            };
            let b = [f64::from(beta.x), f64::from(beta.y), f64::from(beta.z)];
            // Per channel throughput: add_direct weights one scalar, so run it per channel
            // only when the throughput is grey.
            if b[0] == b[1] && b[1] == b[2] {
                rays += add_direct(accel, &point, &mat, wo, directions, per_path * b[0], acc);
            } else {
                let d = directions.len();
                let mut tmp = vec![0.0f64; 3 * d];
                rays += add_direct(accel, &point, &mat, wo, directions, per_path, &mut tmp);
                for c in 0..3 {
                    for j in 0..d {
                        acc[c * d + j] += b[c] * tmp[c * d + j];
                    }
                }
            }
        }
    }
    rays
}

/// The file of a sampled field (SPEC §3.14): a per-pixel file without objects whose `RFLD`
/// section holds `field`; `settings.reflectance` records the settings and the scene's mesh
/// hashes.
#[must_use]
pub fn field_bake(
    scene: &Scene,
    field: ReflectanceField,
    s: &ReflectanceSettings,
) -> prt_bakefile::Bake {
    let geometry: Vec<serde_json::Value> = scene
        .meshes
        .iter()
        .map(|m| {
            serde_json::json!({
                "object": m.name,
                "geometry_hash": format!("{:#018x}", crate::geometry_hash(&m.positions, &m.indices)),
            })
        })
        .collect();
    let settings = serde_json::json!({
        "points": "pixel",
        "seed": s.seed.to_string(),
        "pixel_samples": s.pixel_samples,
        "reflectance": {
            "directions": s.directions,
            "bounces": s.bounces,
            "rays": s.rays,
            "pixel_samples": s.pixel_samples,
            "geometry": geometry,
        },
    });
    prt_bakefile::Bake {
        meta: prt_bakefile::BakeMeta {
            sample_kind: prt_bakefile::SampleKind::Pixel {
                width: scene.camera.width,
                height: scene.camera.height,
            },
            rays_per_point: s.rays,
            bounces: s.bounces,
            seed: s.seed,
            tool: prt_bakefile::ToolInfo {
                name: "prt".into(),
                version: env!("CARGO_PKG_VERSION").into(),
            },
            settings,
            decisions: Vec::new(),
            shard: prt_bakefile::ShardInfo::default(),
            ray_stats: Vec::new(),
            camera: Some(crate::camera_info(&scene.camera)),
            pass: None,
        },
        objects: Vec::new(),
        environment: None,
        brdfs: Vec::new(),
        glossy: Vec::new(),
        reflectance: Some(field),
    }
}
