//! Texture lookup and the resolution of textured materials at a surface point.
//!
//! Lookup follows the glTF 2.0 sampler model: UV `(0, 0)` is the top-left corner of the image
//! (row 0), texel `(i, j)` covers `[i, i+1]/W × [j, j+1]/H` and its value sits at its centre,
//! the wrap mode of each axis maps integer texel indices outside the image back into it
//! (`REPEAT`, `MIRRORED_REPEAT`, `CLAMP_TO_EDGE`), and the four nearest texels are blended
//! bilinearly (a magnification filter of `LINEAR`; no mip-mapping: a reference renderer
//! supersamples the pixel instead of prefiltering the texture).

use crate::{Material, Mesh, Scene, Texture, TextureRef, Wrap};

/// Maps texel index `i` (any integer) into `0..n` by the wrap mode.
fn wrap_index(i: i64, n: usize, wrap: Wrap) -> usize {
    let n = n as i64;
    let k = match wrap {
        Wrap::Repeat => i.rem_euclid(n),
        Wrap::ClampToEdge => i.clamp(0, n - 1),
        Wrap::MirroredRepeat => {
            let m = i.rem_euclid(2 * n);
            if m < n {
                m
            } else {
                2 * n - 1 - m
            }
        }
    };
    k as usize
}

impl Texture {
    /// The texel at integer indices wrapped by the texture's modes.
    fn texel(&self, i: i64, j: i64) -> [f32; 4] {
        let x = wrap_index(i, self.width, self.wrap[0]);
        let y = wrap_index(j, self.height, self.wrap[1]);
        self.texels[y * self.width + x]
    }

    /// Bilinear lookup at `uv` (glTF convention, see the module docs). Non-finite
    /// coordinates return texel `(0, 0)`.
    #[must_use]
    pub fn sample(&self, uv: [f32; 2]) -> [f32; 4] {
        if self.texels.is_empty() {
            return [1.0; 4];
        }
        if !(uv[0].is_finite() && uv[1].is_finite()) {
            return self.texels[0];
        }
        // Continuous texel coordinates with texel centres at integers.
        let x = f64::from(uv[0]) * self.width as f64 - 0.5;
        let y = f64::from(uv[1]) * self.height as f64 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = ((x - x0) as f32, (y - y0) as f32);
        // Texel indices far outside any image (|uv| > 2^40) are clamped before conversion.
        let (i, j) = (x0.clamp(-1e15, 1e15) as i64, y0.clamp(-1e15, 1e15) as i64);
        let (a, b) = (self.texel(i, j), self.texel(i + 1, j));
        let (c, d) = (self.texel(i, j + 1), self.texel(i + 1, j + 1));
        std::array::from_fn(|k| {
            let top = a[k] + fx * (b[k] - a[k]);
            let bottom = c[k] + fx * (d[k] - c[k]);
            top + fy * (bottom - top)
        })
    }
}

/// Interpolates a per-vertex attribute over triangle `tri` at barycentrics `(u, v)` (weights
/// of the second and third vertex).
fn interpolate<const N: usize>(values: &[[f32; N]], tri: [u32; 3], u: f32, v: f32) -> [f32; N] {
    let w = 1.0 - u - v;
    let [a, b, c] = tri.map(|i| values[i as usize]);
    std::array::from_fn(|k| w * a[k] + u * b[k] + v * c[k])
}

/// Where on a mesh a material is evaluated.
#[derive(Clone, Copy, Debug)]
pub enum SurfacePoint {
    /// A vertex.
    Vertex(u32),
    /// A point of triangle `tri` with barycentric weights `u`, `v` of its second and third
    /// vertex.
    Triangle {
        /// Triangle index in the mesh's `indices`.
        tri: u32,
        /// Weight of the second vertex.
        u: f32,
        /// Weight of the third vertex.
        v: f32,
    },
}

impl Mesh {
    pub(crate) fn attribute<const N: usize>(
        &self,
        values: &[[f32; N]],
        at: SurfacePoint,
    ) -> Option<[f32; N]> {
        if values.len() != self.positions.len() {
            return None;
        }
        Some(match at {
            SurfacePoint::Vertex(i) => *values.get(i as usize)?,
            SurfacePoint::Triangle { tri, u, v } => {
                interpolate(values, *self.indices.get(tri as usize)?, u, v)
            }
        })
    }

    /// UV set `set` at a surface point (`None` when the mesh has no such set).
    #[must_use]
    pub fn texcoord(&self, set: usize, at: SurfacePoint) -> Option<[f32; 2]> {
        self.attribute(self.texcoords.get(set)?, at)
    }

    /// The vertex colour at a surface point (`None` when the mesh has none).
    #[must_use]
    pub fn color(&self, at: SurfacePoint) -> Option<[f32; 3]> {
        self.attribute(&self.colors, at)
    }
}

impl Scene {
    /// Whether mesh `m`'s material varies over its surface (textures or vertex colours), so
    /// that [`Scene::material_at`] must be asked point by point.
    #[must_use]
    pub fn material_varies(&self, m: usize) -> bool {
        let mesh = &self.meshes[m];
        match self.materials[mesh.material] {
            Material::Pbr {
                base_color_texture,
                metallic_roughness_texture,
                ..
            } => {
                base_color_texture.is_some()
                    || metallic_roughness_texture.is_some()
                    || !mesh.colors.is_empty()
            }
            _ => false,
        }
    }

    /// Mesh `m`'s material at a surface point, with textures and vertex colours applied: a
    /// `Pbr` material comes back with its factors multiplied by the texture values (base
    /// colour × `COLOR_0` × RGB of `baseColorTexture`; metallic × B and roughness × G of
    /// `metallicRoughnessTexture`) and no texture references; other materials as they are.
    #[must_use]
    pub fn material_at(&self, m: usize, at: SurfacePoint) -> Material {
        let mesh = &self.meshes[m];
        let material = self.materials[mesh.material];
        let Material::Pbr {
            mut base_color,
            mut metallic,
            mut roughness,
            base_color_texture,
            metallic_roughness_texture,
        } = material
        else {
            return material;
        };
        let lookup = |t: Option<TextureRef>| -> Option<[f32; 4]> {
            let t = t?;
            let uv = mesh.texcoord(t.texcoord, at)?;
            let uv = t.transform.map_or(uv, |tr| tr.apply(uv));
            Some(self.textures.get(t.index)?.sample(uv))
        };
        if let Some(c) = mesh.color(at) {
            base_color = std::array::from_fn(|k| base_color[k] * c[k]);
        }
        if let Some(t) = lookup(base_color_texture) {
            base_color = std::array::from_fn(|k| base_color[k] * t[k]);
        }
        if let Some(t) = lookup(metallic_roughness_texture) {
            metallic *= t[2];
            roughness *= t[1];
        }
        let unit = |x: f32| {
            if x.is_finite() {
                x.clamp(0.0, 1.0)
            } else {
                0.0
            }
        };
        Material::Pbr {
            base_color: base_color.map(unit),
            metallic: unit(metallic),
            roughness: unit(roughness),
            base_color_texture: None,
            metallic_roughness_texture: None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tex(wrap: [Wrap; 2]) -> Texture {
        // 2×2: values 0, 1 / 2, 3 in the red channel.
        Texture {
            name: "t".into(),
            width: 2,
            height: 2,
            texels: (0..4).map(|i| [i as f32, 0.0, 0.0, 1.0]).collect(),
            wrap,
        }
    }

    #[test]
    fn texel_centres_return_texels_and_midpoints_blend() {
        let t = tex([Wrap::ClampToEdge; 2]);
        assert_eq!(t.sample([0.25, 0.25])[0], 0.0);
        assert_eq!(t.sample([0.75, 0.25])[0], 1.0);
        assert_eq!(t.sample([0.25, 0.75])[0], 2.0);
        assert_eq!(t.sample([0.5, 0.5])[0], 1.5);
        // Clamped beyond the edge.
        assert_eq!(t.sample([0.0, 0.25])[0], 0.0);
        assert_eq!(t.sample([-3.0, 0.25])[0], 0.0);
    }

    /// `metallicRoughnessTexture`: B scales metallic, G roughness (glTF 2.0, "Metallic
    /// Roughness Material"); `baseColorTexture` and `COLOR_0` scale the base colour; the
    /// result is clamped to `[0, 1]` and carries no texture references.
    #[test]
    fn material_at_applies_textures_and_vertex_colours() {
        let cam = crate::Camera::default();
        let mut scene = Scene::new(cam, crate::Environment::uniform([1.0; 3]));
        scene.textures = vec![
            Texture {
                name: "base".into(),
                width: 1,
                height: 1,
                texels: vec![[0.5, 0.25, 1.0, 1.0]],
                wrap: [Wrap::Repeat; 2],
            },
            Texture {
                name: "mr".into(),
                width: 1,
                height: 1,
                texels: vec![[0.9, 0.5, 0.25, 1.0]],
                wrap: [Wrap::Repeat; 2],
            },
        ];
        let m = scene.add_material(
            "m",
            Material::Pbr {
                base_color: [1.0, 0.8, 0.6],
                metallic: 0.8,
                roughness: 0.6,
                base_color_texture: Some(TextureRef {
                    index: 0,
                    texcoord: 0,
                    transform: None,
                }),
                metallic_roughness_texture: Some(TextureRef {
                    index: 1,
                    texcoord: 1,
                    transform: None,
                }),
            },
        );
        let mut mesh = crate::test_util::floor_quad(1.0, 0.0);
        mesh.texcoords = vec![vec![[0.5; 2]; 4], vec![[0.25; 2]; 4]];
        mesh.colors = vec![[1.0, 0.5, 0.5]; 4];
        let o = scene.add_mesh(mesh, m);
        assert!(scene.material_varies(o));
        let got = scene.material_at(
            o,
            SurfacePoint::Triangle {
                tri: 1,
                u: 0.2,
                v: 0.3,
            },
        );
        assert_eq!(
            got,
            Material::Pbr {
                base_color: [0.5, 0.8 * 0.5 * 0.25, 0.6 * 0.5],
                metallic: 0.8 * 0.25,
                roughness: 0.6 * 0.5,
                base_color_texture: None,
                metallic_roughness_texture: None,
            }
        );
        // A UV set the mesh lacks is a validation error naming it.
        scene.meshes[o].texcoords.truncate(1);
        let err = scene.validate().unwrap_err().to_string();
        assert!(err.contains("TEXCOORD_1") && err.contains("mr"), "{err}");
    }

    /// `KHR_texture_transform`: `uv' = offset + R (scale ⊙ uv)`, `R` turning +u towards +v
    /// (the extension's GLSL matrix); the lookup reads the transformed UV.
    #[test]
    fn texture_transforms_move_the_lookup() {
        let t = crate::UvTransform {
            offset: [0.5, 0.25],
            rotation: 0.0,
            scale: [2.0, 0.5],
        };
        assert_eq!(t.apply([0.25, 0.5]), [1.0, 0.5]);
        let quarter = crate::UvTransform {
            offset: [0.0; 2],
            rotation: std::f32::consts::FRAC_PI_2,
            scale: [1.0; 2],
        };
        let r = quarter.apply([1.0, 0.0]);
        assert!(r[0].abs() < 1e-7 && (r[1] - 1.0).abs() < 1e-7, "{r:?}");
        // A 2 × 1 texture, red then green; the vertices' UV (0.25, 0.5) is red, shifted by
        // half the width it is green.
        let mut scene = Scene::new(
            crate::Camera::default(),
            crate::Environment::uniform([1.0; 3]),
        );
        scene.textures = vec![Texture {
            name: "rg".into(),
            width: 2,
            height: 1,
            texels: vec![[1.0, 0.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0]],
            wrap: [Wrap::ClampToEdge; 2],
        }];
        let colour = |transform| {
            let mut scene = scene.clone();
            let m = scene.add_material(
                "m",
                Material::Pbr {
                    base_color: [1.0; 3],
                    metallic: 0.0,
                    roughness: 1.0,
                    base_color_texture: Some(TextureRef {
                        index: 0,
                        texcoord: 0,
                        transform,
                    }),
                    metallic_roughness_texture: None,
                },
            );
            let mut mesh = crate::test_util::floor_quad(1.0, 0.0);
            mesh.texcoords = vec![vec![[0.25, 0.5]; 4]];
            let o = scene.add_mesh(mesh, m);
            match scene.material_at(o, SurfacePoint::Vertex(0)) {
                Material::Pbr { base_color, .. } => base_color,
                other => panic!("{other:?}"),
            }
        };
        assert_eq!(colour(None), [1.0, 0.0, 0.0]);
        let shift = crate::UvTransform {
            offset: [0.5, 0.0],
            rotation: 0.0,
            scale: [1.0; 2],
        };
        assert_eq!(colour(Some(shift)), [0.0, 1.0, 0.0]);
    }

    #[test]
    fn wrap_modes_follow_gltf() {
        assert_eq!(wrap_index(-1, 4, Wrap::Repeat), 3);
        assert_eq!(wrap_index(5, 4, Wrap::Repeat), 1);
        assert_eq!(wrap_index(-1, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap_index(4, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(8, 4, Wrap::MirroredRepeat), 0);
        assert_eq!(wrap_index(-5, 4, Wrap::MirroredRepeat), 3);
        assert_eq!(wrap_index(9, 4, Wrap::ClampToEdge), 3);
        // Repeat: u = 0 lies between the last and the first texel.
        let t = tex([Wrap::Repeat; 2]);
        assert_eq!(t.sample([0.0, 0.25])[0], 0.5);
        assert_eq!(t.sample([1.25, 1.25])[0], t.sample([0.25, 0.25])[0]);
        // Mirrored: u in [1, 2] reads the image backwards.
        let m = tex([Wrap::MirroredRepeat; 2]);
        assert_eq!(m.sample([1.25, 0.25])[0], 1.0);
        assert_eq!(m.sample([1.75, 0.25])[0], 0.0);
    }
}
