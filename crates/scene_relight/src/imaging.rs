//! Image formation for comparisons: the scene camera's rays hit the meshes and take the
//! barycentric interpolation of per-vertex radiance (Gouraud), or, for per-pixel bakes, the
//! pixel's own value (its transfer already averaged over the pixel's footprint); background
//! shows the environment as the path tracer does (piecewise-constant lookup). Per-vertex
//! images average a grid of sub-pixel rays per pixel — the path tracer's box filter, without
//! noise: `SUBPIXELS²` rays, or `EDGE_SUBPIXELS²` where those do not all see the same surface
//! ([`pixel_samples`]).

use crate::error::SceneRelightError;
use crate::relit::Relit;
use crate::shrm_path::{LookupSum, ShrmSpecular};
use glam::Vec3;
use prt_scene::Scene;
use prt_tracer::{Accel, PinholeCamera};
use rayon::prelude::*;

/// Sub-pixel rays per side of the box filter.
pub const SUBPIXELS: u32 = 3;

/// Sub-pixel rays per side of the box filter at edges ([`pixel_samples`]).
pub const EDGE_SUBPIXELS: u32 = 16;

/// The sub-pixel rays of pixel `(x, y)` and what each hits, all of equal weight: the
/// `SUBPIXELS²` grid of cell midpoints, or — where the pixel may hold an edge — the
/// `EDGE_SUBPIXELS²` grid instead. A pixel may hold an edge when its own rays, or its centre
/// ray and its eight neighbours' centre rays, do not all see the same surface: hits on
/// different objects, hits and misses, or depths more than 5 % apart (a silhouette against the background or another
/// object, or a step within one). The neighbours catch an edge that cuts only a border strip
/// of the pixel, between its outer rays and its side. A `k × k` midpoint grid measures an
/// edge's coverage of the pixel to about `1/(2k)`, and that error times the contrast across
/// the edge is the pixel's: 3 × 3 misjudged silhouettes enough to hold a gold bunny's relit
/// image at 39 dB against the path tracer when its inside matched to 45 dB
/// (crates/relight/README.md).
pub fn pixel_samples(
    cam: &PinholeCamera,
    accel: &Accel,
    x: u32,
    y: u32,
) -> Vec<(Vec3, Option<prt_tracer::Hit>)> {
    let coarse = sample_grid(cam, accel, x, y, SUBPIXELS);
    let neighbours = neighbours(cam, x, y).map(|(nx, ny)| {
        let dir = cam.direction(f64::from(nx) + 0.5, f64::from(ny) + 0.5);
        seen(accel.closest_hit(cam.eye(), dir, f32::INFINITY).as_ref())
    });
    let centre = seen(coarse[coarse.len() / 2].1.as_ref());
    if holds_edge(coarse.iter().map(|(_, h)| seen(h.as_ref())))
        || holds_edge(std::iter::once(centre).chain(neighbours))
    {
        sample_grid(cam, accel, x, y, EDGE_SUBPIXELS)
    } else {
        coarse
    }
}

/// The `k × k` grid of cell-midpoint rays of pixel `(x, y)` and their hits, row by row (for
/// odd `k` the middle one is the pixel's centre ray).
fn sample_grid(
    cam: &PinholeCamera,
    accel: &Accel,
    x: u32,
    y: u32,
    k: u32,
) -> Vec<(Vec3, Option<prt_tracer::Hit>)> {
    let eye = cam.eye();
    let mut out = Vec::with_capacity((k * k) as usize);
    for sy in 0..k {
        for sx in 0..k {
            let fx = f64::from(x) + (f64::from(sx) + 0.5) / f64::from(k);
            let fy = f64::from(y) + (f64::from(sy) + 0.5) / f64::from(k);
            let dir = cam.direction(fx, fy);
            out.push((dir, accel.closest_hit(eye, dir, f32::INFINITY)));
        }
    }
    out
}

/// The pixels around `(x, y)` inside the image.
fn neighbours(cam: &PinholeCamera, x: u32, y: u32) -> impl Iterator<Item = (u32, u32)> {
    let (w, h) = (cam.width(), cam.height());
    (y.saturating_sub(1)..(y + 2).min(h))
        .flat_map(move |ny| (x.saturating_sub(1)..(x + 2).min(w)).map(move |nx| (nx, ny)))
        .filter(move |&p| p != (x, y))
}

/// What a ray sees, for [`holds_edge`]: the object and depth, or nothing.
fn seen(hit: Option<&prt_tracer::Hit>) -> Option<(u32, f32)> {
    hit.map(|h| (h.mesh, h.t))
}

/// Whether rays that saw `seen` do not all see the same surface: different objects, hits and
/// misses, or depths more than 5 % apart.
fn holds_edge(seen: impl Iterator<Item = Option<(u32, f32)>>) -> bool {
    let mut first: Option<Option<u32>> = None;
    let (mut lo, mut hi) = (f32::INFINITY, 0.0f32);
    for s in seen {
        let object = s.map(|(m, _)| m);
        if *first.get_or_insert(object) != object {
            return true;
        }
        if let Some((_, t)) = s {
            lo = lo.min(t);
            hi = hi.max(t);
        }
    }
    hi > 1.05 * lo
}

/// The image type relighting forms: prt-image's linear RGB image (row-major from the top
/// row), the one every crate of the workspace uses.
pub use prt_image::Image as RgbImage;

pub use crate::background::background_radiance;

/// A sub-pixel ray's hit as image formation needs it: the triangle and barycentrics
/// (`mesh = u32::MAX` for a miss, which shows the background).
#[derive(Clone, Copy, Debug)]
struct Sample {
    mesh: u32,
    tri: u32,
    u: f32,
    v: f32,
}

impl Sample {
    fn of(hit: Option<&prt_tracer::Hit>) -> Self {
        hit.map_or(
            Self {
                mesh: u32::MAX,
                tri: 0,
                u: 0.0,
                v: 0.0,
            },
            |h| Self {
                mesh: h.mesh,
                tri: h.tri,
                u: h.u,
                v: h.v,
            },
        )
    }
}

/// Side of the grid of SHRM lookups per pixel: every sample of the `SUBPIXELS²` grid, blocks
/// of 4 × 4 samples of the `EDGE_SUBPIXELS²` one.
const SHRM_CELLS: u32 = 4;

/// Sub-pixel samples of edge grids kept at most (16 bytes each): past it, image formation
/// traces an edge pixel's fine grid again each time (a 4000 × 3000 image with a tenth of
/// its pixels on edges would hold 3 GB).
const MAX_CACHED_SAMPLES: usize = 1 << 24;

/// The sub-pixel rays of every pixel of the scene camera and what each hits, traced once
/// ([`pixel_samples`]' grids: `SUBPIXELS²` rays, `EDGE_SUBPIXELS²` at edges), so that forming
/// the image of any relit result of the scene is a gather: the report forms dozens of images
/// of one scene, `prt relight` two or three. The hits are what the rays of [`form_image`]
/// see, so images formed either way are the same bits.
pub struct ImageRays {
    cam: PinholeCamera,
    /// Per pixel: the grid's side (`SUBPIXELS` or `EDGE_SUBPIXELS`) and its first sample in
    /// `samples` (`u32::MAX`: an edge grid not kept, traced when needed).
    grid: Vec<(u32, u32)>,
    samples: Vec<Sample>,
}

impl ImageRays {
    /// Traces the scene camera's sub-pixel rays.
    ///
    /// # Errors
    /// A camera the tracer refuses.
    pub fn trace(scene: &Scene, accel: &Accel) -> Result<Self, SceneRelightError> {
        let cam = PinholeCamera::new(&scene.camera)?;
        let (w, h) = (cam.width(), cam.height());
        // Pass 1: every pixel's coarse grid. Pass 2: pixels that may hold an edge (their own
        // rays or their neighbours' centre rays disagree: `pixel_samples`) traced again on the
        // fine grid.
        // Per pixel: its coarse samples, what its centre ray saw, whether its own rays
        // disagree.
        type Coarse = (Vec<Sample>, Option<(u32, f32)>, bool);
        let coarse: Vec<Coarse> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let grid = sample_grid(&cam, accel, i % w, i / w, SUBPIXELS);
                let centre = seen(grid[grid.len() / 2].1.as_ref());
                let own_edge = holds_edge(grid.iter().map(|(_, h)| seen(h.as_ref())));
                let samples = grid.iter().map(|(_, h)| Sample::of(h.as_ref())).collect();
                (samples, centre, own_edge)
            })
            .collect();
        let edge: Vec<bool> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                let (x, y) = (i % w, i / w);
                let (_, centre, own_edge) = &coarse[i as usize];
                let centres =
                    neighbours(&cam, x, y).map(|(nx, ny)| coarse[(ny * w + nx) as usize].1);
                *own_edge || holds_edge(std::iter::once(*centre).chain(centres))
            })
            .collect();
        let fine_samples =
            edge.iter().filter(|e| **e).count() * (EDGE_SUBPIXELS * EDGE_SUBPIXELS) as usize;
        let keep_fine =
            fine_samples + coarse.len() * (SUBPIXELS * SUBPIXELS) as usize <= MAX_CACHED_SAMPLES;
        let fine: Vec<Option<Vec<Sample>>> = (0..w * h)
            .into_par_iter()
            .map(|i| {
                (edge[i as usize] && keep_fine).then(|| {
                    sample_grid(&cam, accel, i % w, i / w, EDGE_SUBPIXELS)
                        .iter()
                        .map(|(_, h)| Sample::of(h.as_ref()))
                        .collect()
                })
            })
            .collect();
        let mut grid = Vec::with_capacity(coarse.len());
        let mut samples = Vec::new();
        for ((c, _, _), (e, f)) in coarse.into_iter().zip(edge.into_iter().zip(fine)) {
            match (e, f) {
                (false, _) => {
                    grid.push((SUBPIXELS, samples.len() as u32));
                    samples.extend(c);
                }
                (true, Some(f)) => {
                    grid.push((EDGE_SUBPIXELS, samples.len() as u32));
                    samples.extend(f);
                }
                (true, None) => grid.push((EDGE_SUBPIXELS, u32::MAX)),
            }
        }
        Ok(Self { cam, grid, samples })
    }

    /// The mean radiance of pixel `i`'s samples ([`shade_ray`] of each, in grid order).
    fn shade(
        &self,
        scene: &Scene,
        accel: &Accel,
        relit: &Relit,
        i: u32,
        rotate_y_deg: f64,
    ) -> [f32; 3] {
        let w = self.cam.width();
        let (x, y) = (i % w, i / w);
        let (k, first) = self.grid[i as usize];
        let traced;
        let samples: &[Sample] = if first == u32::MAX {
            traced = sample_grid(&self.cam, accel, x, y, k)
                .iter()
                .map(|(_, h)| Sample::of(h.as_ref()))
                .collect::<Vec<_>>();
            &traced
        } else {
            &self.samples[first as usize..][..(k * k) as usize]
        };
        let mut sum = [0.0f32; 3];
        // `--glossy shrm` objects: the SHRM is looked up at every sample of a coarse grid (the
        // mean of lookups is what the path tracer's samples average; one lookup at a pixel's
        // mean normal measured 6–9 dB worse: the highlight varies inside a pixel), except on
        // triangles whose vertex lookups agree ([`gouraud_suffices`]), which are interpolated.
        // Fine edge grids are looked up per block of `k / SHRM_CELLS` samples on the same
        // object.
        let cells = k.min(SHRM_CELLS);
        let mut lookups: Vec<((usize, u32), LookupSum)> = Vec::new();
        for (j, s) in samples.iter().enumerate() {
            let (sx, sy) = (j as u32 % k, j as u32 / k);
            let dir = || {
                let fx = f64::from(x) + (f64::from(sx) + 0.5) / f64::from(k);
                let fy = f64::from(y) + (f64::from(sy) + 0.5) / f64::from(k);
                self.cam.direction(fx, fy)
            };
            let v = match shrm_of(relit, *s)
                .filter(|(m, _)| !gouraud_suffices(scene, relit, *m, s.tri))
            {
                Some((m, spec)) => {
                    let key = (m, (sy * cells / k) * cells + sx * cells / k);
                    let slot = match lookups.iter().position(|(o, _)| *o == key) {
                        Some(i) => i,
                        None => {
                            lookups.push((key, LookupSum::default()));
                            lookups.len() - 1
                        }
                    };
                    let mesh = &scene.meshes[m];
                    let rest =
                        spec.add_sample(mesh, s.tri as usize, s.u, s.v, &mut lookups[slot].1);
                    let e = emission(scene, relit, *s);
                    std::array::from_fn(|c| rest[c] + e[c])
                }
                None => shade_ray(scene, relit, dir, *s, rotate_y_deg),
            };
            for ch in 0..3 {
                sum[ch] += v[ch];
            }
        }
        for ((m, _), l) in &lookups {
            if let Some(Some(spec)) = relit.shrm.get(*m) {
                let v = spec.lookup_sum(l);
                (0..3).for_each(|ch| sum[ch] += v[ch]);
            }
        }
        let n = samples.len() as f32;
        sum.map(|v| v / n)
    }
}

/// Forms the image of relit radiance. Per-vertex bakes: each pixel averages a `k×k` grid of
/// sub-pixel rays, each taking the barycentric (Gouraud) interpolation of its triangle's
/// vertex radiance or the environment. Per-pixel bakes ([`Relit::footprints`] set): the sum
/// over objects of the pixel's relit value (each object's transfer is already averaged over
/// the pixel's footprint samples, with zeros where a sample sees something else), plus the
/// environment seen by the samples that hit nothing, each weighted `1/K`. Traces the camera's
/// rays; to form several images of one scene, trace them once ([`ImageRays`],
/// [`form_image_with`]).
///
/// # Errors
/// A camera the tracer refuses.
pub fn form_image(
    scene: &Scene,
    accel: &Accel,
    relit: &Relit,
    rotate_y_deg: f64,
) -> Result<RgbImage, SceneRelightError> {
    if relit.footprints.is_some() {
        let cam = PinholeCamera::new(&scene.camera)?;
        return Ok(footprint_image(
            scene,
            relit,
            cam.width(),
            cam.height(),
            rotate_y_deg,
        ));
    }
    Ok(form_image_with(
        scene,
        accel,
        &ImageRays::trace(scene, accel)?,
        relit,
        rotate_y_deg,
    ))
}

/// [`form_image`] with the camera's rays traced beforehand (`rays`, of this scene).
#[must_use]
pub fn form_image_with(
    scene: &Scene,
    accel: &Accel,
    rays: &ImageRays,
    relit: &Relit,
    rotate_y_deg: f64,
) -> RgbImage {
    let (w, h) = (rays.cam.width(), rays.cam.height());
    if relit.footprints.is_some() {
        return footprint_image(scene, relit, w, h, rotate_y_deg);
    }
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| rays.shade(scene, accel, relit, i, rotate_y_deg))
        .collect();
    RgbImage {
        width: w as usize,
        height: h as usize,
        pixels,
    }
}

/// The image of a per-pixel relit result: per pixel, the sum over objects of its relit value
/// plus the environment its footprint samples that hit nothing see and the emission at those
/// that hit ([`Relit::emission`]), each weighted `1/K`.
fn footprint_image(scene: &Scene, relit: &Relit, w: u32, h: u32, rotate_y_deg: f64) -> RgbImage {
    let fp = relit.footprints.as_ref().expect("a per-pixel relit result");
    let pixels = (0..w * h)
        .into_par_iter()
        .map(|i| {
            let mut c = [0.0f32; 3];
            for r in &relit.radiance {
                let v = r.get(i as usize).copied().unwrap_or([0.0; 3]);
                (0..3).for_each(|ch| c[ch] += v[ch]);
            }
            let samples = fp.pixel(i as usize);
            let weight = 1.0 / samples.len() as f32;
            for s in samples {
                let b = match (s.hit, s.at) {
                    (None, _) => background_radiance(scene, s.dir, rotate_y_deg),
                    // Emission at the sample's hit, as the path tracer adds it.
                    (Some((m, _)), Some(at)) if relit.emission => scene.emission_at(m, at),
                    (Some(_), _) => continue,
                };
                (0..3).for_each(|ch| c[ch] += weight * b[ch]);
            }
            c
        })
        .collect();
    RgbImage {
        width: w as usize,
        height: h as usize,
        pixels,
    }
}

/// The radiance a sub-pixel ray shows: its hit's relit radiance (per vertex, barycentric;
/// per texel, bilinear at the hit's lightmap UV) plus the emission at the hit
/// ([`Relit::emission`]: evaluated there, as the path tracer does, since an emissive texture
/// varies inside triangles), or the background.
fn shade_ray(
    scene: &Scene,
    relit: &Relit,
    dir: impl FnOnce() -> Vec3,
    hit: Sample,
    rotate_y_deg: f64,
) -> [f32; 3] {
    let mut c = relit_radiance(scene, relit, dir, hit, rotate_y_deg);
    let e = emission(scene, relit, hit);
    (0..3).for_each(|ch| c[ch] += e[ch]);
    c
}

/// The emission at a sub-pixel ray's hit ([`Relit::emission`]; 0 for a miss).
fn emission(scene: &Scene, relit: &Relit, hit: Sample) -> [f32; 3] {
    if relit.emission && hit.mesh != u32::MAX {
        let at = prt_scene::SurfacePoint::Triangle {
            tri: hit.tri,
            u: hit.u,
            v: hit.v,
        };
        scene.emission_at(hit.mesh as usize, at)
    } else {
        [0.0; 3]
    }
}

/// Largest spread of a triangle's three vertex radiances, per channel, relative to the
/// brightest of them, below which image formation interpolates them (Gouraud) instead of
/// looking the SHRM up at the sample. Measured on the order-11 bunny under the courtyard at
/// roughness 0.4 (gold / copper against the path tracer, 8-bit PSNR on the object; frame =
/// shading plus image formation, the Phong path's frame ≈ 70 ms on 2 threads): per-sample
/// lookups everywhere (0) 44.93 / 44.94 dB in 121–185 ms; 0.3: 44.47 / 44.62 dB; **0.4: 43.88
/// / 44.16 dB in 94–114 ms**; 0.5: 43.26 / 43.55 dB; 0.7: 41.85 / 42.00 dB; Gouraud
/// everywhere 41.01 / 41.00 dB in 66–89 ms (`crates/relight/README.md`).
const SHRM_GOURAUD_SPREAD: f32 = 0.4;

/// Whether triangle `tri` of object `m`'s vertex radiances (the SHRM looked up at each vertex)
/// agree to [`SHRM_GOURAUD_SPREAD`] in every channel: then no highlight peaks or turns inside
/// it that a per-sample lookup would see, up to what its vertices cannot show.
fn gouraud_suffices(scene: &Scene, relit: &Relit, m: usize, tri: u32) -> bool {
    let idx = scene
        .meshes
        .get(m)
        .and_then(|mesh| mesh.indices.get(tri as usize));
    let (Some(r), Some(idx)) = (relit.radiance.get(m), idx) else {
        return false;
    };
    let v = idx.map(|i| r.get(i as usize).copied().unwrap_or([0.0; 3]));
    let top = v.iter().flatten().fold(0.0f32, |a, &b| a.max(b));
    (0..3).all(|c| {
        let (lo, hi) = v
            .iter()
            .fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), x| {
                (lo.min(x[c]), hi.max(x[c]))
            });
        hi - lo <= SHRM_GOURAUD_SPREAD * top
    })
}

/// The object a sub-pixel ray hits and its SHRM specular, if it has one
/// ([`Relit::shrm`], per-vertex bakes).
fn shrm_of(relit: &Relit, hit: Sample) -> Option<(usize, &ShrmSpecular)> {
    let m = hit.mesh as usize;
    if hit.mesh == u32::MAX || matches!(relit.lightmaps.get(m), Some(Some(_))) {
        return None;
    }
    relit.shrm.get(m)?.as_deref().map(|s| (m, s))
}

/// [`shade_ray`] without the emission.
fn relit_radiance(
    scene: &Scene,
    relit: &Relit,
    dir: impl FnOnce() -> Vec3,
    hit: Sample,
    rotate_y_deg: f64,
) -> [f32; 3] {
    match (hit.mesh != u32::MAX).then_some(hit) {
        Some(hit) => {
            let mesh = &scene.meshes[hit.mesh as usize];
            let tri = mesh.indices[hit.tri as usize];
            let r = &relit.radiance[hit.mesh as usize];
            let wts = [1.0 - hit.u - hit.v, hit.u, hit.v];
            if let Some(Some(lm)) = relit.lightmaps.get(hit.mesh as usize) {
                // Per texel: the hit's lightmap UV, bilinear over the
                // covered texels.
                let uvs = lm.triangle_uvs(mesh, hit.tri as usize);
                let mut uv = [0.0f32; 2];
                for (t, wt) in uvs.into_iter().zip(wts) {
                    uv[0] += wt * t[0];
                    uv[1] += wt * t[1];
                }
                prt_scene::lightmap::bilinear(
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
        None => background_radiance(scene, dir(), rotate_y_deg),
    }
}

/// The object whose centre ray each pixel hits (`None`: background), row-major.
///
/// # Errors
/// A camera the tracer refuses.
pub fn object_ids(scene: &Scene, accel: &Accel) -> Result<Vec<Option<usize>>, SceneRelightError> {
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
pub fn object_mask(scene: &Scene, accel: &Accel) -> Result<Vec<bool>, SceneRelightError> {
    Ok(object_ids(scene, accel)?
        .into_iter()
        .map(|o| o.is_some())
        .collect())
}

/// The region-of-interest picture (Lee & Kim 2014, Figure 6.3(d)): ROI vertices red, others
/// light grey, interpolated over the triangles; background black.
pub fn roi_image(
    scene: &Scene,
    accel: &Accel,
    relit: &Relit,
) -> Result<RgbImage, SceneRelightError> {
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
        emission: false,
        shrm: Vec::new(),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::relit::RelightStats;
    use glam::DVec3;
    use prt_scene::test_util::floor_quad;
    use prt_scene::{Camera, EnvImage, Environment, Mapping, Material};

    const B: [f32; 3] = [0.25, 0.5, 1.0];

    /// A 2 × 2 floor at `y = 0` seen straight down from 4 above (image x along +X, image y
    /// along +Z), 16 × 16 pixels with a margin of background, under a uniform environment `B`.
    fn floor_scene() -> (Scene, Accel) {
        let cam = Camera {
            eye: DVec3::new(0.0, 4.0, 0.0),
            target: DVec3::ZERO,
            up: DVec3::NEG_Z,
            fov_y_deg: 40.0,
            width: 16,
            height: 16,
        };
        let mut scene = Scene::new(cam, Environment::uniform(B));
        let m = scene.add_material("grey", Material::Lambert { albedo: [0.5; 3] });
        scene.add_mesh(floor_quad(1.0, 0.0), m);
        let accel = Accel::build(&scene).unwrap();
        (scene, accel)
    }

    fn relit(radiance: Vec<Vec<[f32; 3]>>, roi: Vec<Vec<bool>>) -> Relit {
        Relit {
            radiance,
            roi,
            stats: RelightStats::default(),
            footprints: None,
            lightmaps: Vec::new().into(),
            emission: false,
            shrm: Vec::new(),
        }
    }

    /// Where the floor `y = 0` is hit through image point `(x, y)` (pixel units).
    fn floor_hit(cam: &PinholeCamera, x: f64, y: f64) -> Vec3 {
        let d = cam.direction(x, y);
        let eye = cam.eye();
        eye + d * (-eye.y / d.y)
    }

    /// The Gouraud test of SHRM image formation: a triangle whose vertex radiances spread by
    /// at most `SHRM_GOURAUD_SPREAD` of the brightest, in every channel, is interpolated;
    /// one more in any channel, or an unknown object or triangle, is looked up per sample.
    #[test]
    fn gouraud_suffices_where_the_vertices_agree() {
        let (scene, _) = floor_scene();
        let n = scene.meshes[0].positions.len();
        let tri = scene.meshes[0].indices[0];
        let with = |scale: f32, channel: usize| {
            let mut r = vec![[1.0f32, 0.5, 0.25]; n];
            r[tri[1] as usize][channel] *= scale;
            relit(vec![r], vec![vec![true; n]])
        };
        assert!(gouraud_suffices(&scene, &with(1.0, 0), 0, 0));
        // Red 1 → 1/(1 − τ): a spread of exactly τ of the top value (up to rounding, kept
        // inside by 0.999).
        let inside = 1.0 / (1.0 - 0.999 * SHRM_GOURAUD_SPREAD);
        assert!(gouraud_suffices(&scene, &with(inside, 0), 0, 0));
        assert!(!gouraud_suffices(
            &scene,
            &with(1.0 / (1.0 - 1.001 * SHRM_GOURAUD_SPREAD), 0),
            0,
            0
        ));
        // Blue 0.25 → 0.25 + 1.001 τ (the top value is red's 1): outside.
        assert!(!gouraud_suffices(
            &scene,
            &with(1.0 + 4.004 * SHRM_GOURAUD_SPREAD, 2),
            0,
            0
        ));
        assert!(gouraud_suffices(
            &scene,
            &with(1.0 + 3.996 * SHRM_GOURAUD_SPREAD, 2),
            0,
            0
        ));
        assert!(!gouraud_suffices(&scene, &with(1.0, 0), 1, 0));
        assert!(!gouraud_suffices(&scene, &with(1.0, 0), 0, u32::MAX));
    }

    #[test]
    fn a_linear_field_is_formed_exactly_and_the_background_is_the_environment() {
        // Per-vertex radiance linear in position: Gouraud interpolation reproduces it at every
        // hit, and with the image plane parallel to the floor the sub-pixel hits are an affine
        // image of the symmetric sub-pixel grid, so a pixel that sees only floor shows the
        // field at its centre ray's hit. A pixel that sees none of it shows the environment.
        let (scene, accel) = floor_scene();
        let field = |p: Vec3| {
            [
                0.5 + 0.2 * p.x - 0.1 * p.z,
                0.3 * p.z + 0.4,
                1.0 - 0.25 * p.x,
            ]
        };
        let r: Vec<[f32; 3]> = scene.meshes[0]
            .positions
            .iter()
            .map(|p| field(*p))
            .collect();
        let image = form_image(&scene, &accel, &relit(vec![r], vec![Vec::new()]), 0.0).unwrap();
        let cam = PinholeCamera::new(&scene.camera).unwrap();
        let (mut inside, mut outside) = (0, 0);
        for y in 0..16u32 {
            for x in 0..16u32 {
                let got = image.pixels[(y * 16 + x) as usize];
                // The pixel's square on the floor, from two opposite corners.
                let a = floor_hit(&cam, f64::from(x), f64::from(y));
                let b = floor_hit(&cam, f64::from(x + 1), f64::from(y + 1));
                let (lo, hi) = (a.min(b), a.max(b));
                if lo.x > -1.0 && hi.x < 1.0 && lo.z > -1.0 && hi.z < 1.0 {
                    inside += 1;
                    let c = field(floor_hit(&cam, f64::from(x) + 0.5, f64::from(y) + 0.5));
                    for ch in 0..3 {
                        assert!(
                            (got[ch] - c[ch]).abs() < 1e-5,
                            "({x}, {y}): {got:?} vs {c:?}"
                        );
                    }
                } else if lo.x > 1.0 || hi.x < -1.0 || lo.z > 1.0 || hi.z < -1.0 {
                    outside += 1;
                    for ch in 0..3 {
                        assert!((got[ch] - B[ch]).abs() < 1e-6, "({x}, {y}): {got:?}");
                    }
                }
            }
        }
        assert!(
            inside > 50 && outside > 50,
            "{inside} inside, {outside} outside"
        );
    }

    #[test]
    fn a_per_pixel_image_sums_the_objects_and_the_background_share() {
        // Two pixels of four footprint samples: the first with three hits, the second with
        // none. Each object's value is already the footprint's mean; the misses add `B / 4`.
        let (mut scene, accel) = floor_scene();
        scene.camera.width = 2;
        scene.camera.height = 1;
        let point = prt_tracer::points::SamplePoint {
            position: Vec3::ZERO,
            normal: Vec3::Y,
            offset_normal: Vec3::Y,
            offset: 0.0,
        };
        let sample = |hit: bool| prt_tracer::points::PixelSample {
            dir: Vec3::NEG_Y,
            hit: hit.then_some((0, point)),
            at: None,
        };
        let samples = [true, true, false, true, false, false, false, false].map(sample);
        let mut r = relit(
            vec![
                vec![[0.3, 0.2, 0.1], [0.0; 3]],
                vec![[0.01, 0.02, 0.03], [0.0; 3]],
            ],
            vec![Vec::new(); 2],
        );
        r.footprints = Some(std::sync::Arc::new(prt_tracer::points::PixelFootprints {
            width: 2,
            height: 1,
            samples_per_pixel: 4,
            samples: samples.to_vec(),
        }));
        let image = form_image(&scene, &accel, &r, 0.0).unwrap();
        let want = [
            [
                0.3 + 0.01 + 0.25 * B[0],
                0.2 + 0.02 + 0.25 * B[1],
                0.1 + 0.03 + 0.25 * B[2],
            ],
            B,
        ];
        for (got, want) in image.pixels.iter().zip(want) {
            for ch in 0..3 {
                assert!((got[ch] - want[ch]).abs() < 1e-6, "{got:?} vs {want:?}");
            }
        }
    }

    #[test]
    fn the_background_turns_with_the_environment() {
        // A 4 × 2 lat-long map of distinct texels: rotated by 90° about +Y, what was seen along
        // `a` is seen along R_y(90°)·a (the sense of the SH rotation of the lighting).
        let texels: Vec<[f32; 3]> = (0..8).map(|i| [i as f32, 0.0, 1.0]).collect();
        let mut scene = Scene::new(Camera::default(), Environment::uniform([0.0; 3]));
        scene.environment = Environment {
            image: EnvImage {
                width: 4,
                height: 2,
                texels,
            },
            mapping: Mapping::LatLong,
            rotation_y_deg: 0.0,
        };
        let turn = glam::Mat3::from_rotation_y(90f32.to_radians());
        let mut seen = Vec::new();
        for k in 0..4 {
            for y in [0.5f32, -0.5] {
                let a = glam::Mat3::from_rotation_y(k as f32 * 90f32.to_radians())
                    * Vec3::new(0.6, y, 0.3).normalize();
                let before = background_radiance(&scene, a, 0.0);
                assert_eq!(background_radiance(&scene, turn * a, 90.0), before);
                assert_eq!(background_radiance(&scene, a, 360.0), before);
                seen.push(before[0]);
            }
        }
        seen.sort_by(f32::total_cmp);
        seen.dedup();
        assert_eq!(
            seen.len(),
            8,
            "the directions see every texel once: {seen:?}"
        );
    }

    #[test]
    fn edges_are_told_by_objects_misses_and_depth_steps() {
        let same = [Some((0, 2.0)), Some((0, 2.09)), Some((0, 2.05))];
        assert!(!holds_edge(same.into_iter()));
        assert!(holds_edge([Some((0, 2.0)), Some((0, 2.2))].into_iter()));
        assert!(holds_edge([Some((0, 2.0)), Some((1, 2.0))].into_iter()));
        assert!(holds_edge([Some((0, 2.0)), None].into_iter()));
        assert!(holds_edge([None, Some((0, 2.0))].into_iter()));
        assert!(!holds_edge([None, None].into_iter()));
    }

    #[test]
    fn the_roi_picture_and_the_object_mask() {
        let (scene, accel) = floor_scene();
        let r = relit(vec![vec![[9.0; 3]; 4]], vec![vec![true; 4]]);
        let roi = roi_image(&scene, &accel, &r).unwrap();
        let mask = object_mask(&scene, &accel).unwrap();
        // The centre sees the floor, the corner the background.
        assert!(mask[8 * 16 + 8] && !mask[0]);
        assert_eq!(roi.pixels[0], [0.0; 3]);
        let centre = roi.pixels[8 * 16 + 8];
        for (got, want) in centre.iter().zip([1.0, 0.05, 0.05]) {
            assert!((got - want).abs() < 1e-6, "{centre:?}");
        }
        for (p, m) in roi.pixels.iter().zip(&mask) {
            if !m {
                assert_eq!(*p, [0.0; 3]);
            }
        }
        let ids = object_ids(&scene, &accel).unwrap();
        assert_eq!((ids[0], ids[8 * 16 + 8]), (None, Some(0)));
    }
}
