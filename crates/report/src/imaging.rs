//! Image formation for comparisons: the scene camera's rays hit the meshes and take the
//! barycentric interpolation of per-vertex radiance (Gouraud), or, for per-pixel bakes, the
//! pixel's own value (its transfer already averaged over the pixel's footprint); background
//! shows the environment as the path tracer does (piecewise-constant lookup). Per-vertex
//! images average a fixed `k×k` grid of sub-pixel rays per pixel — the path tracer's box
//! filter, without noise.

use crate::error::ReportError;
use crate::relit::Relit;
use glam::{DMat3, Vec3};
use prt_bake::points::PixelFootprints;
use prt_scene::{Material, Scene};
use prt_tracer::{Accel, PinholeCamera};
use rayon::prelude::*;

/// Sub-pixel rays per side of the box filter.
pub const SUBPIXELS: u32 = 3;

/// An RGB image, row-major from the top row.
#[derive(Clone, Debug)]
pub struct RgbImage {
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Linear radiance.
    pub pixels: Vec<[f32; 3]>,
}

/// Environment radiance seen along `dir` with an extra rotation about +Y (degrees).
pub(crate) fn background_radiance(scene: &Scene, dir: Vec3, rotate_y_deg: f64) -> [f32; 3] {
    let d = if rotate_y_deg == 0.0 {
        dir
    } else {
        (DMat3::from_rotation_y(-rotate_y_deg.to_radians()) * dir.as_dvec3()).as_vec3()
    };
    scene.environment.radiance(d)
}

/// A surface point as `(position, unit normal)`.
pub type PointAndNormal = ([f32; 3], [f32; 3]);

/// Per pixel, the position and camera-facing normal of object `o` that the specular term of a
/// per-pixel bake is shaded at: the mean position and the normalised mean normal of the
/// pixel's footprint samples that hit `o` (the pixel centre when the bake sampled centres
/// only). The bake stores the visibility averaged over the footprint, so the lobe must be
/// placed once per pixel; taking one sample's normal instead (as before) made the specular
/// term of a curved glossy surface as noisy as a one-sample render of its footprint. Where the
/// normals cancel (a sliver seen from both sides) the first sample's normal is used. Pixels
/// where no sample hits `o` get a placeholder facing away from the camera (their transfer for
/// `o` is zero).
#[must_use]
pub fn pixel_surface(scene: &Scene, footprints: &PixelFootprints, o: usize) -> Vec<PointAndNormal> {
    let eye = scene.camera.eye.as_vec3();
    (0..footprints.pixel_count())
        .map(|px| {
            let (mut p, mut n, mut count) = (glam::DVec3::ZERO, glam::DVec3::ZERO, 0u32);
            let mut first = None;
            for s in footprints.pixel(px) {
                if let Some((m, sp)) = s.hit {
                    if m == o {
                        p += sp.position.as_dvec3();
                        n += sp.normal.as_dvec3();
                        count += 1;
                        first.get_or_insert(sp.normal);
                    }
                }
            }
            let Some(first) = first else {
                return ((eye + Vec3::Y).to_array(), Vec3::Y.to_array());
            };
            let mean_n = if n.length() > 1e-6 * f64::from(count) {
                n.normalize().as_vec3()
            } else {
                first
            };
            (
                (p / f64::from(count)).as_vec3().to_array(),
                mean_n.to_array(),
            )
        })
        .collect()
}

/// Object `o`'s material resolved per pixel (textures, vertex colours): the mean of the
/// resolved `pbr` parameters over the pixel's footprint samples that hit `o` (the transfer is
/// such a mean too); pixels that do not see `o` get the material's factors.
#[must_use]
pub fn pixel_materials(scene: &Scene, footprints: &PixelFootprints, o: usize) -> Vec<Material> {
    let factors = scene.materials[scene.meshes[o].material];
    (0..footprints.pixel_count())
        .map(|px| {
            let (mut c, mut m, mut r, mut k) = ([0.0f64; 3], 0.0f64, 0.0f64, 0u32);
            for s in footprints.pixel(px) {
                let (Some((mesh, _)), Some(at)) = (s.hit, s.at) else {
                    continue;
                };
                if mesh != o {
                    continue;
                }
                if let Material::Pbr {
                    base_color,
                    metallic,
                    roughness,
                    ..
                } = scene.material_at(o, at)
                {
                    for (a, b) in c.iter_mut().zip(base_color) {
                        *a += f64::from(b);
                    }
                    m += f64::from(metallic);
                    r += f64::from(roughness);
                    k += 1;
                }
            }
            if k == 0 {
                return factors;
            }
            let n = f64::from(k);
            Material::Pbr {
                base_color: c.map(|v| (v / n) as f32),
                metallic: (m / n) as f32,
                roughness: (r / n) as f32,
                base_color_texture: None,
                metallic_roughness_texture: None,
            }
        })
        .collect()
}

/// Forms the image of relit radiance. Per-vertex bakes: each pixel averages a `k×k` grid of
/// sub-pixel rays, each taking the barycentric (Gouraud) interpolation of its triangle's
/// vertex radiance or the environment. Per-pixel bakes ([`Relit::footprints`] set): the sum
/// over objects of the pixel's relit value (each object's transfer is already averaged over
/// the pixel's footprint samples, with zeros where a sample sees something else), plus the
/// environment seen by the samples that hit nothing, each weighted `1/K`.
pub fn form_image(
    scene: &Scene,
    accel: &Accel,
    relit: &Relit,
    rotate_y_deg: f64,
) -> Result<RgbImage, ReportError> {
    let cam = PinholeCamera::new(&scene.camera)?;
    let (w, h) = (cam.width(), cam.height());
    let eye = cam.eye();
    let k = SUBPIXELS;
    let pixels: Vec<[f32; 3]> = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let (x, y) = (i % w, i / w);
            if let Some(fp) = &relit.footprints {
                let mut c = [0.0f32; 3];
                for r in &relit.radiance {
                    let v = r.get(i as usize).copied().unwrap_or([0.0; 3]);
                    (0..3).for_each(|ch| c[ch] += v[ch]);
                }
                let samples = fp.pixel(i as usize);
                let weight = 1.0 / samples.len() as f32;
                for s in samples.iter().filter(|s| s.hit.is_none()) {
                    let b = background_radiance(scene, s.dir, rotate_y_deg);
                    (0..3).for_each(|ch| c[ch] += weight * b[ch]);
                }
                return c;
            }
            let mut sum = [0.0f32; 3];
            for sy in 0..k {
                for sx in 0..k {
                    let fx = f64::from(x) + (f64::from(sx) + 0.5) / f64::from(k);
                    let fy = f64::from(y) + (f64::from(sy) + 0.5) / f64::from(k);
                    let dir = cam.direction(fx, fy);
                    let v = match accel.closest_hit(eye, dir, f32::INFINITY) {
                        Some(hit) => {
                            let mesh = &scene.meshes[hit.mesh as usize];
                            let tri = mesh.indices[hit.tri as usize];
                            let r = &relit.radiance[hit.mesh as usize];
                            let wts = [1.0 - hit.u - hit.v, hit.u, hit.v];
                            if let Some(Some(lm)) = relit.lightmaps.get(hit.mesh as usize) {
                                // Per texel: the hit's lightmap UV, bilinear over the
                                // covered texels.
                                let uvs = &mesh.texcoords[lm.uv_set];
                                let mut uv = [0.0f32; 2];
                                for (vi, wt) in tri.iter().zip(wts) {
                                    let t = uvs[*vi as usize];
                                    uv[0] += wt * t[0];
                                    uv[1] += wt * t[1];
                                }
                                prt_bake::texels::bilinear(
                                    lm.width,
                                    lm.height,
                                    |k| lm.texels[k].is_some(),
                                    |k| r[k],
                                    uv,
                                )
                                .unwrap_or([0.0; 3])
                            } else {
                                let mut c = [0.0f32; 3];
                                for (vi, wt) in tri.iter().zip(wts) {
                                    let rv = r[*vi as usize];
                                    for ch in 0..3 {
                                        c[ch] += wt * rv[ch];
                                    }
                                }
                                c
                            }
                        }
                        None => background_radiance(scene, dir, rotate_y_deg),
                    };
                    for ch in 0..3 {
                        sum[ch] += v[ch];
                    }
                }
            }
            let n = (k * k) as f32;
            [sum[0] / n, sum[1] / n, sum[2] / n]
        })
        .collect();
    Ok(RgbImage {
        width: w,
        height: h,
        pixels,
    })
}

/// The object whose centre ray each pixel hits (`None`: background), row-major.
///
/// # Errors
/// A camera the tracer refuses.
pub fn object_ids(scene: &Scene, accel: &Accel) -> Result<Vec<Option<usize>>, ReportError> {
    let cam = PinholeCamera::new(&scene.camera)?;
    let (w, h) = (cam.width(), cam.height());
    let eye = cam.eye();
    Ok((0..w * h)
        .into_par_iter()
        .map(|i| {
            let dir = cam.direction(f64::from(i % w) + 0.5, f64::from(i / w) + 0.5);
            accel
                .closest_hit(eye, dir, f32::INFINITY)
                .map(|hit| hit.mesh as usize)
        })
        .collect())
}

/// The object mask: pixels whose centre ray hits a mesh.
pub fn object_mask(scene: &Scene, accel: &Accel) -> Result<Vec<bool>, ReportError> {
    Ok(object_ids(scene, accel)?
        .into_iter()
        .map(|o| o.is_some())
        .collect())
}

/// The region-of-interest picture (Lee & Kim 2014, Figure 6.3(d)): ROI vertices red, others
/// light grey, interpolated over the triangles; background black.
pub fn roi_image(scene: &Scene, accel: &Accel, relit: &Relit) -> Result<RgbImage, ReportError> {
    let colours = Relit {
        radiance: relit
            .roi
            .iter()
            .map(|r| {
                r.iter()
                    .map(|&inside| {
                        if inside {
                            [1.0, 0.05, 0.05]
                        } else {
                            [0.75, 0.75, 0.75]
                        }
                    })
                    .collect()
            })
            .collect(),
        roi: relit.roi.clone(),
        stats: relit.stats.clone(),
        footprints: None,
        lightmaps: relit.lightmaps.clone(),
    };
    let mut img = form_image(scene, accel, &colours, 0.0)?;
    let mask = object_mask(scene, accel)?;
    for (p, m) in img.pixels.iter_mut().zip(mask) {
        if !m {
            *p = [0.0; 3];
        }
    }
    Ok(img)
}
