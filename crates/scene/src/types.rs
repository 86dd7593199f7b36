//! The in-memory scene: what every later stage (tracer, bakes, relighting) reads.

use glam::{DVec3, Vec3};

/// An RGB radiance or reflectance triple, linear Rec.709.
pub type Rgb = [f32; 3];

/// How an environment image maps to directions (see CONVENTIONS.md).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Mapping {
    /// Equirectangular: row 0 is +Y, `u = 0` looks down -Z, `u = 0.25` down +X.
    #[default]
    LatLong,
    /// Debevec's angular light probe: centre +Z, rim -Z.
    Angular,
}

/// A linear RGB image of an environment, row-major, row 0 at the top.
#[derive(Clone, Debug, Default)]
pub struct EnvImage {
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// `width * height` texels, row-major.
    pub texels: Vec<Rgb>,
}

/// A distant environment: an image, its mapping, a rotation about +Y and a radiance scale.
#[derive(Clone, Debug)]
pub struct Environment {
    /// The texels (already scaled by `scale`; negative texels already clamped to 0).
    pub image: EnvImage,
    /// How texels map to directions.
    pub mapping: Mapping,
    /// Rotation about +Y in degrees, same sense as Mitsuba's `to_world` rotate:
    /// radiance towards world direction `d` is the map's value at `R_y(rotation_y)^-1 d`.
    pub rotation_y_deg: f64,
}

/// A texture used by a material: which of [`Scene::textures`] and which UV set of the mesh.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TextureRef {
    /// Index into [`Scene::textures`] (or into [`LoadedMeshes::textures`] before a scene
    /// takes the file's textures over).
    pub index: usize,
    /// The mesh's UV set (`TEXCOORD_n`).
    pub texcoord: usize,
    /// `KHR_texture_transform` of the texture reference, applied to the UVs before lookup.
    pub transform: Option<UvTransform>,
}

/// A texture reference's UV transform (`KHR_texture_transform`): `uv' = offset + R (scale ⊙ uv)`
/// with `R = [[cos r, −sin r], [sin r, cos r]]`, the extension's
/// `translation · rotation · scale` matrix.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct UvTransform {
    /// `offset`.
    pub offset: [f32; 2],
    /// `rotation`, radians.
    pub rotation: f32,
    /// `scale`.
    pub scale: [f32; 2],
}

impl UvTransform {
    /// The transformed UV.
    #[must_use]
    pub fn apply(&self, uv: [f32; 2]) -> [f32; 2] {
        let (s, c) = self.rotation.sin_cos();
        let (x, y) = (self.scale[0] * uv[0], self.scale[1] * uv[1]);
        [
            self.offset[0] + c * x - s * y,
            self.offset[1] + s * x + c * y,
        ]
    }
}

/// How a texture coordinate outside `[0, 1]` wraps (glTF sampler `wrapS` / `wrapT`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum Wrap {
    /// `REPEAT` (glTF's default).
    #[default]
    Repeat,
    /// `MIRRORED_REPEAT`.
    MirroredRepeat,
    /// `CLAMP_TO_EDGE`.
    ClampToEdge,
}

/// A decoded texture: linear values (sRGB images decoded when the texture holds colours),
/// row 0 at the top (glTF's UV origin), sampled bilinearly with its wrap modes.
#[derive(Clone, Debug, Default)]
pub struct Texture {
    /// For messages: the image's file or glTF name and index.
    pub name: String,
    /// Width in texels.
    pub width: usize,
    /// Height in texels.
    pub height: usize,
    /// `width * height` RGBA texels, row-major, linear.
    pub texels: Vec<[f32; 4]>,
    /// Wrap mode along `u` (S) and `v` (T).
    pub wrap: [Wrap; 2],
}

/// A BRDF, with the parameters of CONVENTIONS.md. All glossy types include `albedo/π`
/// (`Pbr` has its own diffuse term).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Material {
    /// `albedo/π`.
    Lambert {
        /// Diffuse reflectance.
        albedo: Rgb,
    },
    /// Normalised modified Phong: `albedo/π + specular (e+2)/(2π) max(0, r·ω_i)^e`.
    Phong {
        /// Diffuse reflectance.
        albedo: Rgb,
        /// Specular reflectance.
        specular: Rgb,
        /// Exponent `e ≥ 0`.
        exponent: f32,
    },
    /// `albedo/π + specular (e+8)/(8π) max(0, n·h)^e`.
    BlinnPhong {
        /// Diffuse reflectance.
        albedo: Rgb,
        /// Specular reflectance.
        specular: Rgb,
        /// Exponent `e ≥ 0`.
        exponent: f32,
    },
    /// Isotropic Ward.
    Ward {
        /// Diffuse reflectance.
        albedo: Rgb,
        /// Specular reflectance.
        specular: Rgb,
        /// Roughness `α > 0`.
        roughness: f32,
    },
    /// Cook–Torrance with Beckmann distribution, V-groove masking and dielectric Fresnel.
    CookTorrance {
        /// Diffuse reflectance.
        albedo: Rgb,
        /// Specular reflectance.
        specular: Rgb,
        /// Beckmann roughness `m > 0`.
        roughness: f32,
        /// Index of refraction (default 1.5).
        ior: f32,
    },
    /// The glTF 2.0 metallic-roughness material (glTF 2.0 specification, Appendix B): GGX
    /// `D`, height-correlated Smith `V`, Schlick Fresnel, `(1 − F)` diffuse; see
    /// CONVENTIONS.md. The factors multiply the textures and the mesh's `COLOR_0`;
    /// [`Scene::material_at`] resolves them at a surface point.
    Pbr {
        /// `baseColorFactor` (RGB, linear).
        base_color: Rgb,
        /// `metallicFactor` in `[0, 1]`.
        metallic: f32,
        /// `roughnessFactor` in `[0, 1]` (`α = roughness²`).
        roughness: f32,
        /// `baseColorTexture` (sRGB-decoded RGB multiplies `base_color`).
        base_color_texture: Option<TextureRef>,
        /// `metallicRoughnessTexture` (B multiplies `metallic`, G `roughness`).
        metallic_roughness_texture: Option<TextureRef>,
    },
    /// `albedo/π` plus a perfect mirror of reflectance `specular`.
    Mirror {
        /// Diffuse reflectance.
        albedo: Rgb,
        /// Mirror reflectance.
        specular: Rgb,
    },
}

/// How a material's alpha decides coverage (glTF `alphaMode`).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub enum AlphaMode {
    /// Opaque everywhere (`OPAQUE`, and our reading of `BLEND`, which is warned about).
    #[default]
    Opaque,
    /// `MASK`: the surface exists where `alpha ≥ cutoff` and is cut out (no hit for any ray)
    /// elsewhere, with `alpha = factor × A of the base-colour texture`.
    Mask {
        /// `alphaCutoff` (glTF default 0.5).
        cutoff: f32,
        /// `baseColorFactor`'s alpha.
        factor: f32,
        /// The texture whose A channel is the alpha (`baseColorTexture`), if any.
        texture: Option<TextureRef>,
    },
}

/// A tangent-space normal map (glTF `normalTexture`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NormalMap {
    /// The texture (linear RGB, `n = 2·rgb − 1`).
    pub texture: TextureRef,
    /// `normalTexture.scale`: multiplies the X and Y of the tangent-space normal.
    pub scale: f32,
}

/// What a glTF material has besides its BRDF, read at a surface point by
/// [`Scene::shading_normal`], [`Scene::emission_at`] and [`Scene::alpha_covers`]: a normal
/// map, emission and the alpha mode. The default is none of them (every material of a scene
/// file, and OBJ).
#[derive(Clone, Copy, Debug, PartialEq, Default)]
pub struct SurfaceInputs {
    /// `normalTexture`, used with the mesh's tangents ([`Scene::tangents`]).
    pub normal_map: Option<NormalMap>,
    /// `emissiveFactor × KHR_materials_emissive_strength` (linear RGB radiance, W/(m² sr)
    /// in the scene's units).
    pub emissive: Rgb,
    /// `emissiveTexture` (sRGB-decoded RGB multiplies `emissive`).
    pub emissive_texture: Option<TextureRef>,
    /// `alphaMode` (`BLEND` is stored as `Opaque`, with a warning).
    pub alpha: AlphaMode,
    /// The material has an `occlusionTexture`, which nothing reads: the path tracer and the
    /// bakes compute occlusion themselves (kept so that bakes can say so).
    pub occlusion_map: bool,
    /// The material's `alphaMode` is `BLEND`, read as opaque (kept so that bakes can say so).
    pub blend: bool,
}

impl SurfaceInputs {
    /// Whether the material emits light anywhere (a non-zero emissive factor).
    #[must_use]
    pub fn emits(&self) -> bool {
        self.emissive.iter().any(|&e| e > 0.0)
    }

    /// Whether any input is present.
    #[must_use]
    pub fn is_none(&self) -> bool {
        *self == Self::default()
    }
}

/// The glTF asset a material came from (a bake records it, SPEC §3.9.1, so that an engine can
/// find the asset's own textures and vertex colours).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MaterialSource {
    /// The asset's path as the scene file names it (`[[objects]] mesh`).
    pub asset: String,
    /// Index of the material in the asset's `materials`.
    pub material: usize,
}

/// A triangle mesh in world space (transform already applied).
#[derive(Clone, Debug, Default)]
pub struct Mesh {
    /// Name for messages (file name, plus glTF node/mesh names).
    pub name: String,
    /// World-space vertex positions.
    pub positions: Vec<Vec3>,
    /// Unit world-space shading normals, one per vertex.
    pub normals: Vec<Vec3>,
    /// Triangles as vertex index triples (degenerate triangles already dropped).
    pub indices: Vec<[u32; 3]>,
    /// Index into [`Scene::materials`].
    pub material: usize,
    /// Texture coordinate sets (`TEXCOORD_0`, `TEXCOORD_1`, ...; OBJ `vt` is set 0), one
    /// `[u, v]` per vertex each; empty when the file has none.
    pub texcoords: Vec<Vec<[f32; 2]>>,
    /// Vertex colours (`COLOR_0`, linear RGB; alpha dropped), one per vertex, or empty.
    pub colors: Vec<[f32; 3]>,
}

/// A pinhole camera.
#[derive(Clone, Debug)]
pub struct Camera {
    /// Eye position.
    pub eye: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Up vector (default +Y).
    pub up: DVec3,
    /// Vertical field of view in degrees.
    pub fov_y_deg: f64,
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
}

/// Defaults of the `[render]` table.
#[derive(Clone, Debug)]
pub struct RenderSettings {
    /// Samples per pixel.
    pub spp: u32,
    /// Indirect bounces; `-1` means unlimited with Russian roulette.
    pub bounces: i32,
    /// Global seed.
    pub seed: u64,
}

impl Default for RenderSettings {
    fn default() -> Self {
        Self {
            spp: 64,
            bounces: 0,
            seed: 0,
        }
    }
}

/// A loaded scene.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The camera.
    pub camera: Camera,
    /// The distant environment.
    pub environment: Environment,
    /// Materials, referenced by index from meshes.
    pub materials: Vec<Material>,
    /// Textures, referenced by [`TextureRef::index`] from materials.
    pub textures: Vec<Texture>,
    /// Material names, parallel to `materials`.
    pub material_names: Vec<String>,
    /// Where each material was defined, parallel to `materials`: `None` for the scene file's
    /// own `[materials.*]`, else the glTF asset that brought it.
    pub material_sources: Vec<Option<MaterialSource>>,
    /// Meshes in world space, one per `[[objects]]` entry (glTF files may add several).
    pub meshes: Vec<Mesh>,
    /// The non-BRDF inputs of each material (normal map, emission, alpha), parallel to
    /// `materials`; a missing entry means none ([`Scene::surface_inputs`]).
    pub surface_inputs: Vec<SurfaceInputs>,
    /// Per-vertex world-space tangents `(x, y, z, w)` of each mesh (`w = ±1` the handedness,
    /// bitangent `w · n × t`, glTF's `TANGENT`), parallel to `meshes`; empty (or missing) for
    /// meshes whose material has no normal map. Set by the glTF loader from `TANGENT` or
    /// MikkTSpace; [`Scene::set_tangents`] sets them in code.
    pub tangents: Vec<Vec<[f32; 4]>>,
    /// `[render]` defaults.
    pub render: RenderSettings,
}

/// Meshes read from one mesh file, with the materials the file defines and the warnings.
#[derive(Clone, Debug, Default)]
pub struct LoadedMeshes {
    /// World-space meshes; `material` indexes `materials` (OBJ: 0, and `materials` is empty).
    pub meshes: Vec<Mesh>,
    /// Materials defined by the file (glTF only), `(name, material)`; their texture
    /// references index `textures`.
    pub materials: Vec<(String, Material)>,
    /// Parallel to `materials`: each one's index in the glTF file's `materials` (`None` for
    /// glTF's default material, used by primitives that name none).
    pub material_indices: Vec<Option<usize>>,
    /// Parallel to `materials`: each one's normal map, emission and alpha mode.
    pub surface_inputs: Vec<SurfaceInputs>,
    /// Parallel to `meshes`: world-space tangents (empty when the material has no normal map).
    pub tangents: Vec<Vec<[f32; 4]>>,
    /// Textures of the file's materials (glTF only).
    pub textures: Vec<Texture>,
    /// Things a user should know; each names the file.
    pub warnings: Vec<String>,
}

/// A scene read from a TOML scene file, with the warnings of every file it read.
#[derive(Clone, Debug)]
pub struct LoadedScene {
    /// The scene, valid ([`Scene::validate`] passes).
    pub scene: Scene,
    /// Things a user should know; each names the file it is about.
    pub warnings: Vec<String>,
}
