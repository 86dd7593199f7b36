//! Scene loading for `prt`: TOML scene files, OBJ and glTF 2.0 meshes, OpenEXR and Radiance
//! HDR environment maps, and the in-memory [`Scene`] every later stage reads.
//! [`lightmap`] rasterises an object's lightmap UVs into texels (per-texel bakes and their
//! relighting); [`binding`] is how a scene mesh binds to a bake file (geometry hash, `MESH`).
//!
//! Entry points: [`load_scene`] (a whole scene), [`load_mesh`] / [`load_obj`] / [`load_gltf`]
//! (one mesh file), [`load_env_image`] / [`load_environment`] (one map). Each returns the
//! warnings it produced next to its result; a caller prints them. Scenes built in code use
//! [`Scene::new`], [`Scene::add_material`], [`Scene::add_mesh`] and the shapes of
//! [`test_util`]; [`Scene::validate`] checks any scene.
//!
//! # Scene file
//! ```toml
//! [camera]
//! eye = [0.0, 1.0, 3.0]
//! target = [0.0, 0.5, 0.0]
//! up = [0.0, 1.0, 0.0]        # optional, default +Y
//! fov_y = 40.0                # vertical field of view, degrees, in (0, 180)
//! resolution = [160, 120]     # width, height
//!
//! [environment]
//! file = "env.exr"            # .exr or Radiance .hdr, linear RGB, relative to the TOML file
//! mapping = "latlong"         # or "angular"; default "latlong"
//! rotation_y = 0.0            # degrees about +Y, optional (Mitsuba's to_world rotate)
//! scale = 1.0                 # radiance multiplier ≥ 0, optional
//!
//! [materials.stone]           # lambert | phong | blinn_phong | ward | cook_torrance | mirror
//! type = "lambert"
//! albedo = [0.8, 0.8, 0.8]
//!
//! [[objects]]
//! mesh = "bunny.obj"          # .obj, .gltf or .glb, relative to the TOML file
//! material = "stone"          # required for OBJ; optional for glTF (its materials are used)
//! translate = [0.0, 0.0, 0.0] # optional
//! rotate = [0.0, 0.0, 0.0]    # optional, degrees: v' = Rz·Ry·Rx·v
//! scale = 1.0                 # optional, number or [sx, sy, sz], non-zero
//!
//! [render]                    # optional
//! spp = 64                    # ≥ 1
//! bounces = 0                 # -1 = unlimited (Russian roulette)
//! seed = 0
//! normal_maps = true          # false: glTF normal maps switched off (for comparisons)
//! emission = true             # false: glTF emission switched off
//! ```
//! World position = `translate + R·(S·v)`; normals transform by the inverse transpose. A
//! mirroring scale (negative determinant) also reverses the triangles' winding.
//!
//! Material parameters (CONVENTIONS.md): every type needs `albedo`; `phong` and `blinn_phong`
//! need `specular` and `exponent ≥ 0`; `ward` needs `specular` and `roughness > 0`;
//! `cook_torrance` needs `specular`, `roughness > 0` and takes `ior > 1` (default 1.5);
//! `mirror` needs `specular`. Colours are in `[0, 1]`. A parameter that the type does not use
//! gives a warning, and so does `albedo + specular > 1` in a channel. Materials are stored
//! sorted by name.
//!
//! `pbr` needs `base_color`, `metallic` and `roughness`, each in `[0, 1]`.
//!
//! # glTF materials
//! A glTF object whose scene entry names no material uses the file's own metallic-roughness
//! material as `pbr`: its factors, `baseColorTexture` (sRGB), `metallicRoughnessTexture`
//! (B metallic, G roughness) and `COLOR_0`, resolved at a surface point by
//! [`Scene::material_at`]. Textures are decoded once (PNG, JPEG) and sampled bilinearly with
//! the glTF sampler's wrap modes (see [`Texture::sample`]); a texture that is missing, not an
//! image, or reads a UV set the primitive lacks is an error naming the file and the material.
//! The older factor-only mapping to our own BRDFs is still available as [`map_material`].
//!
//! Besides its BRDF a glTF material brings [`SurfaceInputs`] (in [`Scene::surface_inputs`],
//! parallel to the materials): `normalTexture` with the mesh's tangents
//! ([`Scene::tangents`]: `TANGENT`, or MikkTSpace's when absent), emission
//! (`emissiveFactor`, `emissiveTexture`, `KHR_materials_emissive_strength`) and
//! `alphaMode MASK`, resolved at a surface point by [`Scene::shading_normal`] /
//! [`Scene::normal_mapped`], [`Scene::emission_at`] and [`Scene::alpha_covers`] /
//! [`Scene::alpha_mask`]. `occlusionTexture` and `alphaMode BLEND` (treated as opaque) are
//! warned about.
//!
//! # Meshes
//! Positions must be finite and indices in range; degenerate triangles (a repeated index or
//! exactly zero area) are dropped and counted in a warning; a mesh with no triangle left is an
//! error. File normals (OBJ `vn`, glTF `NORMAL`) are used when every vertex has one; otherwise
//! angle-weighted vertex normals are computed ([`angle_weighted_normals`]); zero or NaN file
//! normals are replaced by computed ones with a warning.
//!
//! # Error policy
//! Nothing in this crate panics on bad input. Every error is a [`SceneError`] whose message
//! starts with the file it is about; scene-file errors also name the key
//! (`materials.stone.albedo`, `objects[2].mesh`); an error in a file that the scene names is
//! wrapped with the scene file and key. Problems that have an obvious, harmless repair
//! (negative texels from lossy compression, degenerate triangles, bad normals, skipped line
//! primitives, ignored textures or keys, unexpected chromaticities) are repaired and reported
//! as warnings instead; anything that would change the picture silently (NaN texels, NaN
//! positions, bad indices, unsupported required glTF extensions, sparse accessors) is an error.

pub mod binding;
pub mod envmap;
mod envmap_io;
mod error;
mod gltf_io;
pub mod lightmap;
mod load;
mod mesh;
mod obj;
mod scene_file;
mod surface;
pub mod test_util;
mod texture;
mod types;
mod validate;

pub use envmap_io::{load_env_image, load_environment, LoadedImage, REC709_CHROMATICITIES};
pub use error::SceneError;
pub use gltf_io::{load_gltf, map_material};
pub use load::load_mesh;
pub use mesh::{angle_weighted_normals, normal_matrix, object_transform};
pub use obj::load_obj;
pub use scene_file::{load_scene, parse_scene_str};
pub use surface::AlphaMask;
pub use texture::SurfacePoint;
pub use types::*;
