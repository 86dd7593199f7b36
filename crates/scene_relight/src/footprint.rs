//! What the footprint samples of a per-pixel bake's pixels see of an object: the surface point
//! its view-dependent terms are shaded at and its material, each a mean over the pixel's
//! samples that hit the object (the bake's transfer is such a mean too). Relighting and image
//! formation both read them.

use glam::Vec3;
use prt_scene::{Material, Scene};
use prt_tracer::points::PixelFootprints;

/// A surface point as `(position, unit normal)`.
pub type PointAndNormal = ([f32; 3], [f32; 3]);

/// Per pixel, the position and camera-facing normal of object `o` that the specular term of a
/// per-pixel bake is shaded at: the mean position and the normalised mean normal of the
/// pixel's footprint samples that hit `o` (a normal-mapped sample's the map's normal, as the
/// bake shaded its transfer with) (the pixel centre when the bake sampled centres
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
                        let normal = seen_normal(scene, m, s.at, s.dir).unwrap_or(sp.normal);
                        p += sp.position.as_dvec3();
                        n += normal.as_dvec3();
                        count += 1;
                        first.get_or_insert(normal);
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

/// The normal-mapped shading normal a footprint sample sees (`None`: not normal mapped, the
/// sample's interpolated normal shades), as the bake and the path tracer orient it
/// ([`Scene::seen_normal_mapped`]).
pub(crate) fn seen_normal(
    scene: &Scene,
    m: usize,
    at: Option<prt_scene::SurfacePoint>,
    dir: Vec3,
) -> Option<Vec3> {
    match at? {
        prt_scene::SurfacePoint::Triangle { tri, u, v } => {
            scene.seen_normal_mapped(m, tri, u, v, dir)
        }
        prt_scene::SurfacePoint::Vertex(_) => None,
    }
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
