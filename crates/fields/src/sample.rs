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

use crate::error::FieldError;
use glam::Vec3;
use prt_bakefile::{FieldValues, ReflectanceField, ScalarType};
use prt_scene::{Material, Scene};
use prt_shading::{eval, sample};
use prt_tracer::points::{pixel_footprints, SamplePoint};
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
    /// The precision the values are held in: the scalar type of the file they go to (the
    /// field is never held as f32 when the file is f16).
    pub scalar: ScalarType,
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

/// f32 values sampled per batch of pixels before they are appended to the field (converted
/// to its precision): 32 MB, whatever the image.
const BATCH_VALUES: usize = 8 << 20;

/// Samples the reflectance field of `scene`'s camera image, its values held as `s.scalar`.
///
/// Pixels are sampled in batches (about `BATCH_VALUES` values each, in pixel order, each
/// batch in parallel); a batch's functions are appended to the field converted to its
/// precision and dropped, so no f32 copy of an f16 field ever exists. Each pixel's function
/// depends only on the pixel, so the field is bit-identical for any thread count.
///
/// # Errors
/// Impossible settings (a grid smaller than 2 × 1 or above [`MAX_DIRECTIONS`], no footprint
/// samples), the tracer's camera errors, and [`prt_bakefile::BakeFileError::OutOfF16Range`]
/// (as [`FieldError::File`]) when the field is held as f16 and a value rounds beyond ±65504.
pub fn sample_field(
    scene: &Scene,
    accel: &Accel,
    s: &ReflectanceSettings,
) -> Result<(ReflectanceField, FieldStats), FieldError> {
    let d = (u64::from(s.directions[0]) * u64::from(s.directions[1])).max(1) as usize;
    sample_in_batches(scene, accel, s, (BATCH_VALUES / (3 * d)).max(64))
}

/// [`sample_field`] with `batch` pixels per batch.
fn sample_in_batches(
    scene: &Scene,
    accel: &Accel,
    s: &ReflectanceSettings,
    batch: usize,
) -> Result<(ReflectanceField, FieldStats), FieldError> {
    let start = std::time::Instant::now();
    let [w, h] = s.directions;
    let dirs = u64::from(w) * u64::from(h);
    if w < 2 || h < 1 || dirs > MAX_DIRECTIONS {
        return Err(FieldError::InvalidSettings(format!(
            "--directions {w}x{h}: give at least 2x1 and at most {MAX_DIRECTIONS} directions"
        )));
    }
    if s.pixel_samples == 0 || s.pixel_samples > prt_tracer::points::MAX_PIXEL_SAMPLES {
        return Err(FieldError::InvalidSettings(format!(
            "{} pixel samples: give between 1 and {}",
            s.pixel_samples,
            prt_tracer::points::MAX_PIXEL_SAMPLES
        )));
    }
    if s.bounces > 0 && s.rays == 0 {
        return Err(FieldError::InvalidSettings(
            "bounces need at least one path per sample (--rays)".into(),
        ));
    }
    let d = dirs as usize;
    let directions: Vec<Vec3> = (0..d).map(|j| grid_direction(w, h, j)).collect();
    let fp = pixel_footprints(scene, accel, s.seed, s.pixel_samples)?;
    let k = s.pixel_samples as usize;
    let bar = prt_tracer::progress_bar(s.progress, fp.pixel_count() as u64, "pixels");
    let mut pixels = Vec::new();
    let mut values = FieldValues::new(s.scalar);
    let mut shadow_rays = 0u64;
    let mut first = 0;
    while first < fp.pixel_count() {
        let last = (first + batch.max(1)).min(fp.pixel_count());
        // Per pixel: its function (3 × D) or None when no sample hits a surface.
        let rows: Vec<(Option<Vec<f32>>, u64)> = (first..last)
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
        for (px, (row, rays)) in (first..).zip(rows) {
            shadow_rays += rays;
            if let Some(r) = row {
                pixels.push(px as u32);
                values.push_f32(&r)?;
            }
        }
        first = last;
    }
    bar.finish_and_clear();
    let stats = FieldStats {
        pixels: pixels.len() as u64,
        shadow_rays,
        seconds: start.elapsed().as_secs_f64(),
    };
    Ok((
        ReflectanceField {
            directions: [w, h],
            pixels,
            values,
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
                "geometry_hash": format!("{:#018x}", prt_scene::binding::geometry_hash(&m.positions, &m.indices)),
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
            camera: Some(prt_scene::binding::camera_info(&scene.camera)),
            pass: None,
        },
        objects: Vec::new(),
        environment: None,
        brdfs: Vec::new(),
        glossy: Vec::new(),
        reflectance: Some(field),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;
    use prt_scene::{Camera, EnvImage, Environment, Mapping, Mesh};

    /// A floor with a floating square above it (shadows, and a second surface for the
    /// bounces), seen at an angle so that some pixels see only the sky.
    fn scene() -> Scene {
        let env = Environment {
            image: EnvImage {
                width: 2,
                height: 1,
                texels: vec![[1.0; 3]; 2],
            },
            mapping: Mapping::LatLong,
            rotation_y_deg: 0.0,
        };
        let cam = Camera::look_at(DVec3::new(0.0, 1.5, 3.0), DVec3::ZERO, 50.0, 14, 9);
        let mut s = Scene::new(cam, env);
        let quad = |name: &str, y: f32, r: f32| Mesh {
            name: name.into(),
            positions: vec![
                Vec3::new(-r, y, -r),
                Vec3::new(r, y, -r),
                Vec3::new(r, y, r),
                Vec3::new(-r, y, r),
            ],
            normals: vec![Vec3::Y; 4],
            indices: vec![[0, 2, 1], [0, 3, 2]],
            ..Mesh::default()
        };
        let floor = s.add_material(
            "floor",
            Material::Lambert {
                albedo: [0.7, 0.5, 0.3],
            },
        );
        let top = s.add_material(
            "top",
            Material::Lambert {
                albedo: [0.2, 0.9, 0.4],
            },
        );
        s.add_mesh(quad("floor", 0.0, 1.5), floor);
        s.add_mesh(quad("top", 0.6, 0.4), top);
        s
    }

    fn settings(scalar: ScalarType) -> ReflectanceSettings {
        ReflectanceSettings {
            directions: [8, 4],
            bounces: 1,
            rays: 2,
            pixel_samples: 2,
            seed: 11,
            progress: false,
            scalar,
        }
    }

    fn in_pool<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(f)
    }

    /// Bit-identical on 1, 2 and 3 threads and in batches of any size, in f32 and in f16; the
    /// f16 field is the f32 one rounded to nearest.
    #[test]
    fn fields_are_bit_identical_for_any_thread_count_and_batch_size() {
        let s = scene();
        let accel = Accel::build(&s).unwrap();
        let mut f32_field = None;
        for scalar in [ScalarType::F32, ScalarType::F16] {
            let st = settings(scalar);
            let (base, stats) = in_pool(1, || sample_field(&s, &accel, &st)).unwrap();
            let count = (s.camera.width * s.camera.height) as usize;
            assert!(
                base.pixels.len() > 10 && base.pixels.len() < count,
                "some pixels see the floor, some only the sky: {}",
                base.pixels.len()
            );
            assert_eq!(stats.pixels, base.pixels.len() as u64);
            assert_eq!(base.values.scalar(), scalar);
            assert_eq!(base.values.len(), base.pixels.len() * 3 * 32);
            for threads in [2, 3] {
                let (f, _) = in_pool(threads, || sample_field(&s, &accel, &st)).unwrap();
                assert_eq!(f.pixels, base.pixels, "{threads} threads");
                assert!(
                    f.values.as_le_bytes() == base.values.as_le_bytes(),
                    "{scalar:?} on {threads} threads: the values differ"
                );
            }
            for batch in [1, 5, 37] {
                let (f, _) = in_pool(2, || sample_in_batches(&s, &accel, &st, batch)).unwrap();
                assert_eq!(f.pixels, base.pixels, "batches of {batch}");
                assert!(
                    f.values.as_le_bytes() == base.values.as_le_bytes(),
                    "{scalar:?} in batches of {batch}: the values differ"
                );
            }
            match scalar {
                ScalarType::F32 => f32_field = Some(base),
                ScalarType::F16 => {
                    let f32_field = f32_field.take().unwrap();
                    assert_eq!(f32_field.pixels, base.pixels);
                    let rounded =
                        FieldValues::from_f32_as(&f32_field.values.to_f32_vec(), ScalarType::F16)
                            .unwrap();
                    assert!(
                        rounded.as_le_bytes() == base.values.as_le_bytes(),
                        "the f16 field is the f32 one rounded"
                    );
                    assert!(base.values.to_f32_vec().iter().any(|&v| v > 0.0));
                }
            }
        }
    }
}
