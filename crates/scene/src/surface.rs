//! A glTF material's inputs besides its BRDF, resolved at a surface point: the normal map
//! (tangent space from the mesh's tangents), emission and alpha coverage (`MASK`); and the
//! MikkTSpace tangents the glTF loader generates when a primitive has no `TANGENT`.
//!
//! Normal mapping follows the glTF 2.0 specification (§3.9.3, "normalTexture"): the texel
//! `c` gives the tangent-space normal `normalize((2c − 1) ⊙ (scale, scale, 1))`, in the frame
//! `(t, b, n)` of the interpolated vertex normal `n`, the interpolated tangent `t`
//! (Gram–Schmidt against `n`) and the bitangent `b = w · n × t`, `w` the tangent's handedness.
//! The image's +Y is "up", towards decreasing `v` (glTF UVs start at the top-left), which is
//! why MikkTSpace is fed `(u, 1 − v)` (MikkTSpace's bitangent follows increasing `t`).

use crate::{AlphaMode, Mesh, Rgb, Scene, SurfaceInputs, SurfacePoint, Texture, TextureRef};
use glam::Vec3;

impl Scene {
    /// The non-BRDF inputs of material `material` (none when the scene has no entry).
    #[must_use]
    pub fn surface_inputs(&self, material: usize) -> SurfaceInputs {
        self.surface_inputs
            .get(material)
            .copied()
            .unwrap_or_default()
    }

    /// Sets material `material`'s normal map, emission and alpha mode.
    pub fn set_surface_inputs(&mut self, material: usize, inputs: SurfaceInputs) {
        if self.surface_inputs.len() <= material {
            self.surface_inputs
                .resize(material + 1, SurfaceInputs::default());
        }
        self.surface_inputs[material] = inputs;
    }

    /// Sets mesh `mesh`'s per-vertex tangents (see [`Scene::tangents`]).
    pub fn set_tangents(&mut self, mesh: usize, tangents: Vec<[f32; 4]>) {
        if self.tangents.len() <= mesh {
            self.tangents.resize(mesh + 1, Vec::new());
        }
        self.tangents[mesh] = tangents;
    }

    /// Whether mesh `m` is normal mapped: its material has a normal map and the mesh has one
    /// tangent per vertex.
    #[must_use]
    pub fn has_normal_map(&self, m: usize) -> bool {
        let mesh = &self.meshes[m];
        self.surface_inputs(mesh.material).normal_map.is_some()
            && self
                .tangents
                .get(m)
                .is_some_and(|t| !t.is_empty() && t.len() == mesh.positions.len())
    }

    /// The texel of texture reference `t` at a surface point of `mesh` (its UV set and
    /// `KHR_texture_transform` applied); `None` when the mesh lacks the set.
    fn texel(&self, mesh: &Mesh, t: TextureRef, at: SurfacePoint) -> Option<[f32; 4]> {
        let uv = mesh.texcoord(t.texcoord, at)?;
        let uv = t.transform.map_or(uv, |tr| tr.apply(uv));
        Some(self.textures.get(t.index)?.sample(uv))
    }

    /// The normal-mapped shading normal of mesh `m` at `at`, given the interpolated vertex
    /// normal `n` there (unit, the file's orientation): `None` when the mesh is not normal
    /// mapped ([`Scene::has_normal_map`]) or its tangent is degenerate at the point (parallel
    /// to `n`, or zero), in which case `n` is the shading normal.
    #[must_use]
    pub fn normal_mapped(&self, m: usize, at: SurfacePoint, n: Vec3) -> Option<Vec3> {
        if !self.has_normal_map(m) {
            return None;
        }
        let mesh = &self.meshes[m];
        let map = self.surface_inputs(mesh.material).normal_map?;
        let t4 = mesh.attribute(&self.tangents[m], at)?;
        let c = self.texel(mesh, map.texture, at)?;
        let local = Vec3::new(
            (2.0 * c[0] - 1.0) * map.scale,
            (2.0 * c[1] - 1.0) * map.scale,
            2.0 * c[2] - 1.0,
        )
        .normalize_or_zero();
        let t = Vec3::new(t4[0], t4[1], t4[2]);
        let t = (t - n * n.dot(t)).normalize_or_zero();
        if t == Vec3::ZERO || local == Vec3::ZERO {
            return None;
        }
        let b = n.cross(t) * if t4[3] < 0.0 { -1.0 } else { 1.0 };
        let out = (t * local.x + b * local.y + n * local.z).normalize_or_zero();
        (out != Vec3::ZERO && out.is_finite()).then_some(out)
    }

    /// The shading normal of mesh `m` at point `(u, v)` of triangle `tri` (barycentric
    /// weights of its second and third vertex): the interpolated vertex normal (the
    /// triangle's own normal for a mesh without normals), perturbed by the material's normal
    /// map when it has one. Unit length, in the file's orientation (not turned towards any
    /// viewer); zero for a triangle index out of range. This is what the path tracer shades
    /// with; bakes can read it per point.
    #[must_use]
    pub fn shading_normal(&self, m: usize, tri: u32, u: f32, v: f32) -> Vec3 {
        let mesh = &self.meshes[m];
        let at = SurfacePoint::Triangle { tri, u, v };
        let face = || {
            if (tri as usize) < mesh.indices.len() {
                mesh.face_normal(tri as usize)
            } else {
                Vec3::ZERO
            }
        };
        let n = match mesh.indices.get(tri as usize) {
            Some(idx) if mesh.normals.len() == mesh.positions.len() => {
                let [a, b, c] = idx.map(|i| mesh.normals[i as usize]);
                let n = (a * (1.0 - u - v) + b * u + c * v).normalize_or_zero();
                if n == Vec3::ZERO {
                    face()
                } else {
                    n
                }
            }
            _ => face(),
        };
        self.normal_mapped(m, at, n).unwrap_or(n)
    }

    /// The normal-mapped shading normal of mesh `m` at point `(u, v)` of triangle `tri` as a
    /// camera ray of direction `dir` sees it, oriented as the path tracer orients it
    /// (`prt_tracer`'s `Vertex::oriented`): flipped with the triangle's geometric normal to
    /// the side that is seen, then, where a bump faces away from the viewer, bent towards the
    /// view in the plane of the normal and the view until their cosine is 0.01. `None` where [`Scene::normal_mapped`] is (the interpolated normal
    /// shades). Bakes and relighting of per-pixel points read it, so that they shade with
    /// the normal the path tracer shades with.
    #[must_use]
    pub fn seen_normal_mapped(
        &self,
        m: usize,
        tri: u32,
        u: f32,
        v: f32,
        dir: Vec3,
    ) -> Option<Vec3> {
        if !self.has_normal_map(m) || tri as usize >= self.meshes[m].indices.len() {
            return None;
        }
        let ns = self.shading_normal(m, tri, u, v);
        let wo = -dir.normalize_or_zero();
        let ng = self.meshes[m].face_normal(tri as usize);
        let ns = if ng.dot(wo) < 0.0 { -ns } else { ns };
        let c = ns.dot(wo);
        if c >= MAPPED_MIN_COS {
            return Some(ns);
        }
        let perp = (ns - wo * c).normalize_or_zero();
        if perp == Vec3::ZERO {
            return Some(wo);
        }
        let sin = (1.0 - MAPPED_MIN_COS * MAPPED_MIN_COS).sqrt();
        Some((perp * sin + wo * MAPPED_MIN_COS).normalize())
    }

    /// Radiance emitted by mesh `m` at `at` (the same towards every direction and from both
    /// sides, like the rest of our two-sided shading): `emissiveFactor × strength × RGB of
    /// emissiveTexture` (sRGB-decoded), zero for a material without emission.
    #[must_use]
    pub fn emission_at(&self, m: usize, at: SurfacePoint) -> Rgb {
        let mesh = &self.meshes[m];
        let s = self.surface_inputs(mesh.material);
        if !s.emits() {
            return [0.0; 3];
        }
        match s.emissive_texture {
            None => s.emissive,
            Some(t) => match self.texel(mesh, t, at) {
                Some(c) => std::array::from_fn(|k| s.emissive[k] * c[k].max(0.0)),
                None => s.emissive,
            },
        }
    }

    /// Whether mesh `m` exists at `at` for rays: always, except under `alphaMode MASK` where
    /// the alpha (factor × A of the base-colour texture) is below the cutoff.
    #[must_use]
    pub fn alpha_covers(&self, m: usize, at: SurfacePoint) -> bool {
        self.alpha_mask(m)
            .is_none_or(|mask| mask.covers(&self.meshes[m], at))
    }

    /// Mesh `m`'s alpha mask (`None` unless its material is `MASK`), holding a copy of the
    /// texture it reads so that a BVH can test coverage without the scene.
    #[must_use]
    pub fn alpha_mask(&self, m: usize) -> Option<AlphaMask> {
        let AlphaMode::Mask {
            cutoff,
            factor,
            texture,
        } = self.surface_inputs(self.meshes[m].material).alpha
        else {
            return None;
        };
        Some(AlphaMask {
            cutoff,
            factor,
            texture: texture.and_then(|t| Some((t, self.textures.get(t.index)?.clone()))),
        })
    }
}

/// The smallest cosine allowed between a normal-mapped shading normal and the view direction
/// (the path tracer's, `prt_tracer`'s `MAPPED_MIN_COS`; see [`Scene::seen_normal_mapped`]).
const MAPPED_MIN_COS: f32 = 0.01;

/// A mesh's `alphaMode MASK` coverage test, with its own copy of the alpha texture.
#[derive(Clone, Debug)]
pub struct AlphaMask {
    /// `alphaCutoff`.
    pub cutoff: f32,
    /// `baseColorFactor`'s alpha.
    pub factor: f32,
    /// The base-colour texture (its A channel) and how the mesh reads it.
    pub texture: Option<(TextureRef, Texture)>,
}

impl AlphaMask {
    /// Whether the surface exists at `at` of `mesh`: `factor × A ≥ cutoff` (glTF: "rendered
    /// fully opaque if greater than or equal to the alpha cutoff"). A point whose UV set is
    /// missing counts as covered.
    #[must_use]
    pub fn covers(&self, mesh: &Mesh, at: SurfacePoint) -> bool {
        let a = match &self.texture {
            None => 1.0,
            Some((t, tex)) => match mesh.texcoord(t.texcoord, at) {
                Some(uv) => tex.sample(t.transform.map_or(uv, |tr| tr.apply(uv)))[3],
                None => 1.0,
            },
        };
        self.factor * a >= self.cutoff
    }
}

/// MikkTSpace tangents of `mesh` (world space) for the UVs `uv` (one per vertex, already
/// through the normal texture's `KHR_texture_transform`), through `bevy_mikktspace` (a
/// byte-for-byte port of Mikkelsen's reference code, which is what glTF asks for when
/// `TANGENT` is absent). MikkTSpace writes a tangent per triangle corner; corners of one
/// vertex agree except where the mesh should have been split, and the last one written
/// wins. A vertex MikkTSpace leaves without a tangent gets `[0, 0, 0, 1]` (no normal
/// mapping there). `None` if the generator reports an error.
pub(crate) fn mikktspace_tangents(mesh: &Mesh, uv: &[[f32; 2]]) -> Option<Vec<[f32; 4]>> {
    struct Geometry<'a> {
        mesh: &'a Mesh,
        uv: &'a [[f32; 2]],
        out: Vec<[f32; 4]>,
    }
    impl Geometry<'_> {
        fn vertex(&self, face: usize, vert: usize) -> usize {
            self.mesh.indices[face][vert] as usize
        }
    }
    impl bevy_mikktspace::Geometry for Geometry<'_> {
        fn num_faces(&self) -> usize {
            self.mesh.indices.len()
        }
        fn num_vertices_of_face(&self, _face: usize) -> usize {
            3
        }
        fn position(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.positions[self.vertex(face, vert)].to_array()
        }
        fn normal(&self, face: usize, vert: usize) -> [f32; 3] {
            self.mesh.normals[self.vertex(face, vert)].to_array()
        }
        fn tex_coord(&self, face: usize, vert: usize) -> [f32; 2] {
            let [u, v] = self.uv[self.vertex(face, vert)];
            [u, 1.0 - v]
        }
        fn set_tangent(
            &mut self,
            tangent_space: Option<bevy_mikktspace::TangentSpace>,
            face: usize,
            vert: usize,
        ) {
            if let Some(ts) = tangent_space {
                let i = self.vertex(face, vert);
                self.out[i] = ts.tangent_encoded();
            }
        }
    }
    if uv.len() != mesh.positions.len() || mesh.normals.len() != mesh.positions.len() {
        return None;
    }
    let mut g = Geometry {
        mesh,
        uv,
        out: vec![[0.0, 0.0, 0.0, 1.0]; mesh.positions.len()],
    };
    bevy_mikktspace::generate_tangents(&mut g).ok()?;
    Some(g.out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{Camera, Environment, Material, NormalMap, Wrap};

    /// A unit square in the XY plane facing +Z, UV (0, 0) at its top-left corner (glTF).
    fn square() -> Mesh {
        Mesh {
            name: "square".into(),
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(1.0, 0.0, 0.0),
                Vec3::new(1.0, 1.0, 0.0),
                Vec3::new(0.0, 1.0, 0.0),
            ],
            normals: vec![Vec3::Z; 4],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            material: 0,
            texcoords: vec![vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]],
            colors: Vec::new(),
        }
    }

    /// On a square whose `u` runs along +X and whose image "up" (decreasing `v`) is +Y,
    /// MikkTSpace's tangent is +X with handedness +1 under glTF's convention
    /// (`b = w · n × t = +Y`, the image's up).
    #[test]
    fn mikktspace_tangents_follow_gltf_handedness() {
        let mesh = square();
        let t = mikktspace_tangents(&mesh, &mesh.texcoords[0]).unwrap();
        for v in t {
            assert!(
                (Vec3::new(v[0], v[1], v[2]) - Vec3::X).length() < 1e-6,
                "{v:?}"
            );
            assert_eq!(v[3], 1.0);
        }
        // Mirrored UVs (u running along −X) flip the tangent, and v flipped the handedness.
        let mut mirrored = square();
        mirrored.texcoords[0] = vec![[1.0, 0.0], [0.0, 0.0], [0.0, 1.0], [1.0, 1.0]];
        let t = mikktspace_tangents(&mirrored, &mirrored.texcoords[0]).unwrap();
        for v in t {
            assert!(
                (Vec3::new(v[0], v[1], v[2]) + Vec3::X).length() < 1e-6,
                "{v:?}"
            );
            assert_eq!(
                v[3], 1.0,
                "both axes mirrored is a rotation: same handedness"
            );
        }
    }

    /// A constant normal-map texel `c` tilts the normal to `normalize(t·x + b·y + n·z)` with
    /// `(x, y, z) = (2c − 1) ⊙ (scale, scale, 1)`.
    #[test]
    fn normal_map_tilts_in_the_tangent_frame() {
        let mut scene = Scene::new(Camera::default(), Environment::uniform([1.0; 3]));
        scene.textures.push(Texture {
            name: "n".into(),
            width: 1,
            height: 1,
            texels: vec![[0.75, 0.5, 1.0, 1.0]],
            wrap: [Wrap::Repeat; 2],
        });
        let m = scene.add_material("m", Material::Lambert { albedo: [0.5; 3] });
        let texture = TextureRef {
            index: 0,
            texcoord: 0,
            transform: None,
        };
        scene.set_surface_inputs(
            m,
            SurfaceInputs {
                normal_map: Some(NormalMap {
                    texture,
                    scale: 2.0,
                }),
                ..SurfaceInputs::default()
            },
        );
        let o = scene.add_mesh(square(), m);
        assert!(!scene.has_normal_map(o), "no tangents yet");
        assert_eq!(scene.shading_normal(o, 0, 0.2, 0.3), Vec3::Z);
        scene.set_tangents(o, vec![[1.0, 0.0, 0.0, -1.0]; 4]);
        // (2·0.75 − 1)·2 = 1 along t = +X, 0 along b, 1 along n: 45° towards +X.
        let n = scene.shading_normal(o, 0, 0.2, 0.3);
        let expect = Vec3::new(1.0, 0.0, 1.0).normalize();
        assert!((n - expect).length() < 1e-6, "{n}");
        // A green tilt follows the handedness: b = −(n × t) = −Y.
        scene.textures[0].texels[0] = [0.5, 1.0, 1.0, 1.0];
        let n = scene.shading_normal(o, 1, 0.2, 0.3);
        let expect = Vec3::new(0.0, -2.0, 1.0).normalize();
        assert!((n - expect).length() < 1e-6, "{n}");
    }

    /// Emission: factor × sRGB-decoded texel; MASK: factor × A against the cutoff.
    #[test]
    fn emission_and_alpha_at_a_point() {
        let mut scene = Scene::new(Camera::default(), Environment::uniform([1.0; 3]));
        scene.textures.push(Texture {
            name: "e".into(),
            width: 2,
            height: 1,
            texels: vec![[1.0, 0.5, 0.0, 1.0], [0.0, 0.0, 0.0, 0.2]],
            wrap: [Wrap::ClampToEdge; 2],
        });
        let m = scene.add_material("m", Material::Lambert { albedo: [0.5; 3] });
        let t = TextureRef {
            index: 0,
            texcoord: 0,
            transform: None,
        };
        scene.set_surface_inputs(
            m,
            SurfaceInputs {
                emissive: [2.0, 4.0, 8.0],
                emissive_texture: Some(t),
                alpha: AlphaMode::Mask {
                    cutoff: 0.5,
                    factor: 0.9,
                    texture: Some(t),
                },
                ..SurfaceInputs::default()
            },
        );
        let mut mesh = square();
        mesh.texcoords = vec![vec![[0.25, 0.5]; 4]];
        let lit = scene.add_mesh(mesh.clone(), m);
        mesh.texcoords = vec![vec![[0.75, 0.5]; 4]];
        let dark = scene.add_mesh(mesh, m);
        let at = SurfacePoint::Vertex(0);
        assert_eq!(scene.emission_at(lit, at), [2.0, 2.0, 0.0]);
        assert_eq!(scene.emission_at(dark, at), [0.0; 3]);
        assert!(scene.alpha_covers(lit, at), "0.9 · 1 ≥ 0.5");
        assert!(!scene.alpha_covers(dark, at), "0.9 · 0.2 < 0.5");
    }
}
