//! glTF 2.0 (`.gltf` with external or embedded buffers, and binary `.glb`) through the `gltf`
//! crate. Images are never decoded: textures are ignored (with a warning).
//!
//! - Every node reachable from the default scene (the first scene when none is marked default)
//!   is visited with its world transform (parent × node, `matrix` or TRS); each of its mesh's
//!   primitives becomes one [`Mesh`]. A mesh used by several nodes is instanced as several.
//! - `TRIANGLES`, `TRIANGLE_STRIP` and `TRIANGLE_FAN` are read (strips and fans triangulated
//!   with the winding rule of the glTF specification, §3.7.2.1); `POINTS` and `LINE*` primitives
//!   are skipped with a warning.
//! - `POSITION` must be float VEC3; `NORMAL` (float VEC3) is used when present.
//! - Errors: a required extension other than `KHR_texture_transform` and
//!   `KHR_materials_emissive_strength` (which do not affect geometry or our material mapping),
//!   sparse accessors, accessors that run past their buffer, out-of-range indices and
//!   non-finite positions.
//! - Materials: see [`map_material`].

use crate::mesh::{finish_mesh, RawMesh, Repairs};
use crate::obj::file_name;
use crate::{LoadedMeshes, Material, Mesh, SceneError};
use ::gltf::accessor::{DataType, Dimensions};
use ::gltf::mesh::{Mode, Semantic};
use glam::{DMat4, Mat4, Vec3};
use std::path::Path;

/// Required extensions that can be honoured by ignoring them.
const IGNORABLE_REQUIRED_EXTENSIONS: [&str; 2] =
    ["KHR_texture_transform", "KHR_materials_emissive_strength"];

/// Maps a glTF metallic-roughness material to one of our BRDFs. With `c` = baseColorFactor
/// (RGB; alpha and textures ignored), `m` = metallicFactor and `r` = roughnessFactor (each
/// clamped to `[0, 1]`), the rule is:
/// - `m < 0.5` and `r ≥ 0.8` (a rough dielectric, whose specular lobe is weak and wide):
///   `lambert { albedo = c }`;
/// - otherwise `cook_torrance { albedo = (1 − m)·c, specular = m·c + (1 − m)·(1, 1, 1),
///   roughness = max(r², 0.01), ior = 1.5 + 18.5·m }`: `r²` is the usual GGX α that Beckmann's
///   `m` approximates, and the index rises from 1.5 (normal-incidence reflectance 0.04) for a
///   dielectric to 20 (0.82) for a metal, since our Fresnel term is a dielectric's.
#[must_use]
pub fn map_material(base_color: [f32; 3], metallic: f32, roughness: f32) -> Material {
    let c = base_color.map(|v| {
        if v.is_finite() {
            v.clamp(0.0, 1.0)
        } else {
            0.0
        }
    });
    let m = if metallic.is_finite() {
        metallic.clamp(0.0, 1.0)
    } else {
        0.0
    };
    let r = if roughness.is_finite() {
        roughness.clamp(0.0, 1.0)
    } else {
        1.0
    };
    if m < 0.5 && r >= 0.8 {
        return Material::Lambert { albedo: c };
    }
    Material::CookTorrance {
        albedo: c.map(|v| (1.0 - m) * v),
        specular: c.map(|v| (m * v + (1.0 - m)).clamp(0.0, 1.0)),
        roughness: (r * r).max(0.01),
        ior: 1.5 + 18.5 * m,
    }
}

/// Reads a `.gltf` or `.glb` file, transforms it by `to_world` (applied after the node
/// transforms) and cleans every primitive (see [`crate::load_mesh`]).
///
/// Material indices of the meshes refer to the returned `materials` list, named
/// `"<file>#<material name or index>"`; primitives without a material get glTF's default
/// material (white, metallic 1, roughness 1).
///
/// # Errors
/// [`SceneError::Io`] if a file cannot be read, [`SceneError::Mesh`] for everything listed in
/// the module docs and when no triangle is found.
pub fn load_gltf(path: &Path, to_world: &DMat4) -> Result<LoadedMeshes, SceneError> {
    let bytes = std::fs::read(path).map_err(|e| SceneError::io(path, e))?;
    if bytes.is_empty() {
        return Err(SceneError::mesh(path, "the file is empty (0 bytes)"));
    }
    let unchecked = ::gltf::Gltf::from_slice_without_validation(&bytes)
        .map_err(|e| SceneError::mesh(path, format!("not a readable glTF 2.0 file: {e}")))?;
    let unsupported: Vec<&str> = unchecked
        .extensions_required()
        .filter(|e| !IGNORABLE_REQUIRED_EXTENSIONS.contains(e))
        .collect();
    if !unsupported.is_empty() {
        return Err(SceneError::mesh(
            path,
            format!(
                "requires unsupported extension(s) {}; decode or convert the file first \
                 (e.g. remove Draco/meshopt compression)",
                unsupported.join(", ")
            ),
        ));
    }
    drop(unchecked);
    let gltf = ::gltf::Gltf::from_slice(&bytes)
        .map_err(|e| SceneError::mesh(path, format!("invalid glTF 2.0 file: {e}")))?;
    let buffers = ::gltf::import_buffers(&gltf.document, path.parent(), gltf.blob.clone())
        .map_err(|e| {
            // The gltf crate's I/O errors do not say which file: name the external ones.
            let external: Vec<String> = gltf
                .buffers()
                .filter_map(|b| match b.source() {
                    ::gltf::buffer::Source::Uri(u) if !u.starts_with("data:") => {
                        Some(format!("`{u}`"))
                    }
                    _ => None,
                })
                .collect();
            let files = if external.is_empty() {
                String::new()
            } else {
                format!(
                    " (buffer files {} in {})",
                    external.join(", "),
                    path.parent().unwrap_or(Path::new(".")).display()
                )
            };
            SceneError::mesh(path, format!("cannot load buffers: {e}{files}"))
        })?;
    let scene = gltf
        .default_scene()
        .or_else(|| gltf.scenes().next())
        .ok_or_else(|| SceneError::mesh(path, "the file has no scene"))?;

    let mut out = Loader {
        path,
        file: file_name(path),
        buffers: &buffers,
        meshes: Vec::new(),
        materials: Vec::new(),
        repairs: Repairs::default(),
        warnings: Vec::new(),
        textured: 0,
    };
    let mut stack: Vec<(::gltf::Node, DMat4, usize)> =
        scene.nodes().map(|n| (n, *to_world, 0)).collect();
    let node_count = gltf.nodes().len();
    while let Some((node, parent, depth)) = stack.pop() {
        if depth > node_count {
            return Err(SceneError::mesh(path, "the node hierarchy has a cycle"));
        }
        let local = Mat4::from_cols_array_2d(&node.transform().matrix()).as_dmat4();
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            for prim in mesh.primitives() {
                out.primitive(&node, &mesh, &prim, &world)?;
            }
        }
        stack.extend(node.children().map(|c| (c, world, depth + 1)));
    }
    if out.meshes.is_empty() {
        return Err(SceneError::mesh(
            path,
            "the default scene has no triangle primitive",
        ));
    }
    let mut warnings = out.warnings;
    warnings.extend(out.repairs.warnings(path));
    if out.textured > 0 {
        warnings.push(format!(
            "{}: {} material(s) have textures, which are ignored (factors only)",
            path.display(),
            out.textured
        ));
    }
    let mut order: Vec<(usize, Mesh)> = out.meshes;
    order.sort_by_key(|(k, _)| *k);
    Ok(LoadedMeshes {
        meshes: order.into_iter().map(|(_, m)| m).collect(),
        materials: out.materials.into_iter().map(|(_, n, m)| (n, m)).collect(),
        warnings,
    })
}

/// State while walking the node tree.
struct Loader<'a> {
    path: &'a Path,
    file: String,
    buffers: &'a [::gltf::buffer::Data],
    /// (node index × 65536 + primitive, mesh): sorted at the end so the order is the file's.
    meshes: Vec<(usize, Mesh)>,
    /// (glTF material index or None, name, material).
    materials: Vec<(Option<usize>, String, Material)>,
    repairs: Repairs,
    warnings: Vec<String>,
    textured: usize,
}

impl Loader<'_> {
    fn primitive(
        &mut self,
        node: &::gltf::Node,
        mesh: &::gltf::Mesh,
        prim: &::gltf::Primitive,
        world: &DMat4,
    ) -> Result<(), SceneError> {
        let name = format!(
            "{}#node{}{}/mesh{}/prim{}",
            self.file,
            node.index(),
            node.name().map(|n| format!("({n})")).unwrap_or_default(),
            mesh.index(),
            prim.index()
        );
        let mode = prim.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            self.warnings.push(format!(
                "{}: skipped {name}: mode {mode:?} is not triangles",
                self.path.display()
            ));
            return Ok(());
        }
        let positions_acc = prim
            .get(&Semantic::Positions)
            .ok_or_else(|| SceneError::mesh(self.path, format!("{name}: no POSITION attribute")))?;
        let positions = self.read_vec3(&positions_acc, &name, "POSITION")?;
        let mut normals = None;
        if let Some(acc) = prim.get(&Semantic::Normals) {
            match self.read_vec3(&acc, &name, "NORMAL") {
                Ok(n) if n.len() == positions.len() => normals = Some(n),
                Ok(_) => self.warnings.push(format!(
                    "{}: {name}: NORMAL count differs from POSITION count; normals computed",
                    self.path.display()
                )),
                Err(e) => self.warnings.push(format!("{e}; normals computed")),
            }
        }
        let vertex_order: Vec<u32> = match prim.indices() {
            Some(acc) => self.read_indices(&acc, &name)?,
            None => (0..positions.len() as u32).collect(),
        };
        let v = &vertex_order;
        let indices: Vec<[u32; 3]> = match mode {
            Mode::Triangles => v.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
            Mode::TriangleStrip => (0..v.len().saturating_sub(2))
                .map(|i| {
                    if i % 2 == 0 {
                        [v[i], v[i + 1], v[i + 2]]
                    } else {
                        [v[i + 1], v[i], v[i + 2]]
                    }
                })
                .collect(),
            _ => (1..v.len().saturating_sub(1))
                .map(|i| [v[i], v[i + 1], v[0]])
                .collect(),
        };
        let material = self.material(prim.material());
        let raw = RawMesh {
            name,
            positions,
            normals,
            indices,
        };
        let (mesh, repairs) = finish_mesh(self.path, raw, world, material)?;
        self.repairs.add(repairs);
        self.meshes
            .push((node.index() * 65536 + prim.index(), mesh));
        Ok(())
    }

    /// Index of `m` in `self.materials`, adding it on first use.
    fn material(&mut self, m: ::gltf::Material) -> usize {
        if let Some(k) = self.materials.iter().position(|(i, _, _)| *i == m.index()) {
            return k;
        }
        let pbr = m.pbr_metallic_roughness();
        if pbr.base_color_texture().is_some() || pbr.metallic_roughness_texture().is_some() {
            self.textured += 1;
        }
        let [r, g, b, _] = pbr.base_color_factor();
        let mat = map_material([r, g, b], pbr.metallic_factor(), pbr.roughness_factor());
        let label = match (m.index(), m.name()) {
            (_, Some(n)) => n.to_owned(),
            (Some(i), None) => format!("material{i}"),
            (None, None) => "default".to_owned(),
        };
        self.materials
            .push((m.index(), format!("{}#{label}", self.file), mat));
        self.materials.len() - 1
    }

    /// The bytes of accessor `acc`: (data from its first element, stride, element size, count).
    fn accessor_bytes(
        &self,
        acc: &::gltf::Accessor,
        what: &str,
    ) -> Result<(&[u8], usize, usize, usize), SceneError> {
        let err = |msg: String| {
            SceneError::mesh(
                self.path,
                format!("{what} (accessor {}): {msg}", acc.index()),
            )
        };
        if acc.sparse().is_some() {
            return Err(err("sparse accessors are not supported".into()));
        }
        let view = acc
            .view()
            .ok_or_else(|| err("accessor has no buffer view".into()))?;
        let data = self
            .buffers
            .get(view.buffer().index())
            .ok_or_else(|| err("buffer not loaded".into()))?;
        let elem = acc.size();
        let stride = view.stride().unwrap_or(elem);
        if stride < elem {
            return Err(err(format!(
                "byte stride {stride} is smaller than the element ({elem} bytes)"
            )));
        }
        let view_end = view.offset().checked_add(view.length());
        let view_bytes = view_end
            .and_then(|end| data.get(view.offset()..end))
            .ok_or_else(|| err("buffer view runs past the end of its buffer".into()))?;
        let count = acc.count();
        if count == 0 {
            return Ok((&[], stride, elem, 0));
        }
        let needed = (count - 1)
            .checked_mul(stride)
            .and_then(|x| x.checked_add(elem));
        let bytes = needed
            .and_then(|n| acc.offset().checked_add(n))
            .and_then(|end| view_bytes.get(acc.offset()..end))
            .ok_or_else(|| {
                err(format!(
                    "{count} elements run past the end of the buffer view"
                ))
            })?;
        Ok((bytes, stride, elem, count))
    }

    fn read_vec3(
        &self,
        acc: &::gltf::Accessor,
        name: &str,
        what: &str,
    ) -> Result<Vec<Vec3>, SceneError> {
        let label = format!("{name} {what}");
        if acc.data_type() != DataType::F32 || acc.dimensions() != Dimensions::Vec3 {
            return Err(SceneError::mesh(
                self.path,
                format!(
                    "{label}: must be float VEC3, found {:?} {:?} (quantized meshes are not supported)",
                    acc.data_type(),
                    acc.dimensions()
                ),
            ));
        }
        let (bytes, stride, _, count) = self.accessor_bytes(acc, &label)?;
        let f = |b: &[u8], k: usize| {
            f32::from_le_bytes([b[4 * k], b[4 * k + 1], b[4 * k + 2], b[4 * k + 3]])
        };
        Ok((0..count)
            .map(|i| {
                let e = &bytes[i * stride..i * stride + 12];
                Vec3::new(f(e, 0), f(e, 1), f(e, 2))
            })
            .collect())
    }

    fn read_indices(&self, acc: &::gltf::Accessor, name: &str) -> Result<Vec<u32>, SceneError> {
        let label = format!("{name} indices");
        if acc.dimensions() != Dimensions::Scalar
            || !matches!(
                acc.data_type(),
                DataType::U8 | DataType::U16 | DataType::U32
            )
        {
            return Err(SceneError::mesh(
                self.path,
                format!(
                    "{label}: must be unsigned SCALAR, found {:?} {:?}",
                    acc.data_type(),
                    acc.dimensions()
                ),
            ));
        }
        let (bytes, stride, elem, count) = self.accessor_bytes(acc, &label)?;
        Ok((0..count)
            .map(|i| {
                let e = &bytes[i * stride..i * stride + elem];
                match elem {
                    1 => u32::from(e[0]),
                    2 => u32::from(u16::from_le_bytes([e[0], e[1]])),
                    _ => u32::from_le_bytes([e[0], e[1], e[2], e[3]]),
                }
            })
            .collect())
    }
}
