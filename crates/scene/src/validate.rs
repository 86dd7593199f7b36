//! Checks of in-memory scenes ([`Scene::validate`], [`Material::check`]) and small
//! constructors for building scenes in code.

use crate::mesh::Fnv1a;
use crate::{
    Camera, EnvImage, Environment, Material, Mesh, RenderSettings, Rgb, Scene, SceneError,
};
use glam::DVec3;

/// Tolerance on `|n| − 1` for a stored unit normal: normals are renormalised in f64 and stored
/// in f32, whose rounding leaves `|n|` within a few 1e-7 of 1; 1e-3 only catches real mistakes.
const UNIT_TOLERANCE: f32 = 1e-3;

/// Sine of the smallest angle allowed between `up` and the view direction (about 0.06°).
const MIN_UP_SINE: f64 = 1e-3;

/// Largest image side, in pixels.
const MAX_SIDE: u32 = 1 << 16;

/// Largest pixel count (16384 × 16384): a render keeps several f32 buffers of this size, and
/// a resolution of 4294967295² used to run for ever instead of failing.
const MAX_PIXELS: u64 = 1 << 28;

impl Material {
    /// The CONVENTIONS.md name of the type (`lambert`, `phong`, `blinn_phong`, `ward`,
    /// `cook_torrance`, `mirror`).
    #[must_use]
    pub fn type_name(&self) -> &'static str {
        match self {
            Material::Lambert { .. } => "lambert",
            Material::Phong { .. } => "phong",
            Material::BlinnPhong { .. } => "blinn_phong",
            Material::Ward { .. } => "ward",
            Material::CookTorrance { .. } => "cook_torrance",
            Material::Mirror { .. } => "mirror",
            Material::Pbr { .. } => "pbr",
        }
    }

    /// The diffuse reflectance (every type has one). For `pbr` it is the Lambertian part of
    /// the `(1 − F)` diffuse term, `(1 − metallic) · 0.96 · base_color` (the Fresnel-dependent
    /// rest, `−(1 − metallic) · 0.96 · s · base_color/π`, belongs to the view-dependent part).
    #[must_use]
    pub fn albedo(&self) -> Rgb {
        match *self {
            Material::Pbr {
                base_color,
                metallic,
                ..
            } => base_color.map(|c| (1.0 - metallic) * 0.96 * c),
            Material::Lambert { albedo }
            | Material::Phong { albedo, .. }
            | Material::BlinnPhong { albedo, .. }
            | Material::Ward { albedo, .. }
            | Material::CookTorrance { albedo, .. }
            | Material::Mirror { albedo, .. } => albedo,
        }
    }

    /// The specular reflectance (`None` for Lambert; for `pbr`, the reflectance at normal
    /// incidence `F0 = 0.04 (1 − metallic) + metallic · base_color`).
    #[must_use]
    pub fn specular(&self) -> Option<Rgb> {
        match *self {
            Material::Lambert { .. } => None,
            Material::Pbr {
                base_color,
                metallic,
                ..
            } => Some(base_color.map(|c| 0.04 * (1.0 - metallic) + metallic * c)),
            Material::Phong { specular, .. }
            | Material::BlinnPhong { specular, .. }
            | Material::Ward { specular, .. }
            | Material::CookTorrance { specular, .. }
            | Material::Mirror { specular, .. } => Some(specular),
        }
    }

    /// Checks the parameters against CONVENTIONS.md: `albedo`, `specular` in `[0, 1]`,
    /// `exponent ≥ 0`, `roughness > 0`, `ior > 1`, all finite.
    ///
    /// # Errors
    /// `(parameter name, message)` of the first bad parameter.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        if let Material::Pbr {
            base_color,
            metallic,
            roughness,
            ..
        } = *self
        {
            check_rgb("base_color", base_color)?;
            for (name, v) in [("metallic", metallic), ("roughness", roughness)] {
                if !(0.0..=1.0).contains(&v) {
                    return Err((name, format!("{v} is outside [0, 1]")));
                }
            }
            return Ok(());
        }
        check_rgb("albedo", self.albedo())?;
        if let Some(s) = self.specular() {
            check_rgb("specular", s)?;
        }
        match *self {
            Material::Phong { exponent, .. } | Material::BlinnPhong { exponent, .. } => {
                if !(exponent.is_finite() && exponent >= 0.0) {
                    return Err(("exponent", format!("{exponent} must be finite and ≥ 0")));
                }
            }
            Material::Ward { roughness, .. } => check_roughness(roughness)?,
            Material::CookTorrance { roughness, ior, .. } => {
                check_roughness(roughness)?;
                if !(ior.is_finite() && ior > 1.0) {
                    return Err(("ior", format!("{ior} must be finite and > 1")));
                }
            }
            Material::Lambert { .. } | Material::Mirror { .. } | Material::Pbr { .. } => {}
        }
        Ok(())
    }
}

fn check_rgb(name: &'static str, c: Rgb) -> Result<(), (&'static str, String)> {
    for (k, v) in c.iter().enumerate() {
        if !(0.0..=1.0).contains(v) {
            return Err((name, format!("component {k} is {v}, outside [0, 1]")));
        }
    }
    Ok(())
}

fn check_roughness(r: f32) -> Result<(), (&'static str, String)> {
    if r.is_finite() && r > 0.0 {
        Ok(())
    } else {
        Err(("roughness", format!("{r} must be finite and > 0")))
    }
}

impl Camera {
    /// A camera at `eye` looking at `target` with up +Y.
    #[must_use]
    pub fn look_at(eye: DVec3, target: DVec3, fov_y_deg: f64, width: u32, height: u32) -> Self {
        Self {
            eye,
            target,
            up: DVec3::Y,
            fov_y_deg,
            width,
            height,
        }
    }

    /// Checks the camera: finite vectors and view direction, `eye ≠ target`, `up` not parallel
    /// to the view direction, `fov_y` in (0, 180) degrees, non-zero resolution of at most 65536
    /// per side and 2²⁸ pixels.
    ///
    /// # Errors
    /// `(key, message)` with the scene-file key of the bad value (`eye`, `up`, `fov_y`, ...).
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        for (key, v) in [("eye", self.eye), ("target", self.target), ("up", self.up)] {
            if !v.is_finite() {
                return Err((key, format!("{v} is not finite")));
            }
        }
        let dir = self.target - self.eye;
        if !dir.length_squared().is_finite() {
            return Err((
                "target",
                format!("target − eye = {dir} overflows: the view direction is undefined"),
            ));
        }
        if dir.length_squared() == 0.0 {
            return Err((
                "target",
                "equals eye: the view direction is undefined".into(),
            ));
        }
        let up = self.up.normalize_or_zero();
        if up == DVec3::ZERO {
            return Err(("up", "is the zero vector".into()));
        }
        if dir.normalize().cross(up).length() < MIN_UP_SINE {
            return Err((
                "up",
                format!("{} is parallel to the view direction {dir}", self.up),
            ));
        }
        if !(self.fov_y_deg > 0.0 && self.fov_y_deg < 180.0) {
            return Err(("fov_y", format!("{}° is outside (0, 180)", self.fov_y_deg)));
        }
        if self.width == 0 || self.height == 0 {
            return Err((
                "resolution",
                format!("{}×{} has a zero side", self.width, self.height),
            ));
        }
        if self.width > MAX_SIDE
            || self.height > MAX_SIDE
            || u64::from(self.width) * u64::from(self.height) > MAX_PIXELS
        {
            return Err((
                "resolution",
                format!(
                    "{}×{} is too large: at most {MAX_SIDE} per side and {MAX_PIXELS} pixels",
                    self.width, self.height
                ),
            ));
        }
        Ok(())
    }
}

impl Default for Camera {
    /// At (0, 0, 3) looking at the origin, 40° vertical field of view, 160×120.
    fn default() -> Self {
        Self::look_at(DVec3::new(0.0, 0.0, 3.0), DVec3::ZERO, 40.0, 160, 120)
    }
}

impl Scene {
    /// An empty scene (no materials, no meshes, default render settings).
    #[must_use]
    pub fn new(camera: Camera, environment: Environment) -> Self {
        Self {
            camera,
            environment,
            materials: Vec::new(),
            material_names: Vec::new(),
            material_sources: Vec::new(),
            textures: Vec::new(),
            meshes: Vec::new(),
            surface_inputs: Vec::new(),
            tangents: Vec::new(),
            render: RenderSettings::default(),
        }
    }

    /// Adds a material and returns its index.
    pub fn add_material(&mut self, name: &str, material: Material) -> usize {
        self.materials.push(material);
        self.material_names.push(name.to_owned());
        self.material_sources.push(None);
        self.materials.len() - 1
    }

    /// Adds a mesh whose `material` is set to `material`; returns the mesh index.
    pub fn add_mesh(&mut self, mut mesh: Mesh, material: usize) -> usize {
        mesh.material = material;
        self.meshes.push(mesh);
        self.meshes.len() - 1
    }

    /// Axis-aligned bounds `(min, max)` of every mesh vertex; `None` without vertices.
    /// Useful to scale ray offsets to the scene.
    #[must_use]
    pub fn bounds(&self) -> Option<(glam::Vec3, glam::Vec3)> {
        self.meshes
            .iter()
            .filter_map(Mesh::bounds)
            .reduce(|(a, b), (c, d)| (a.min(c), b.max(d)))
    }

    /// Total number of triangles.
    #[must_use]
    pub fn triangle_count(&self) -> usize {
        self.meshes.iter().map(|m| m.indices.len()).sum()
    }

    /// Hash of all meshes in order: FNV-1a 64 over the mesh count as u64 little-endian followed,
    /// for each mesh, by the byte string described in [`Mesh::geometry_hash`].
    #[must_use]
    pub fn geometry_hash(&self) -> u64 {
        let mut h = Fnv1a::new();
        h.write(&(self.meshes.len() as u64).to_le_bytes());
        for m in &self.meshes {
            m.hash_into(&mut h);
        }
        h.0
    }

    /// Bytes held by the scene's arrays: 12 per position, normal, triangle and environment
    /// texel, plus names and materials (`Vec` headers and spare capacity not counted).
    #[must_use]
    pub fn memory_estimate(&self) -> usize {
        let meshes: usize = self
            .meshes
            .iter()
            .map(|m| {
                m.positions.len() * 12 + m.normals.len() * 12 + m.indices.len() * 12 + m.name.len()
            })
            .sum();
        let materials = self.materials.len() * std::mem::size_of::<Material>()
            + self.material_names.iter().map(String::len).sum::<usize>();
        meshes + materials + self.environment.image.texels.len() * 12
    }

    /// Checks every invariant later stages rely on: the camera ([`Camera::check`]), an
    /// environment image of `width × height > 0` finite non-negative texels with a finite
    /// rotation, valid materials ([`Material::check`]) with one name each, and meshes with
    /// finite positions, one finite unit normal per position, in-range indices, at least one
    /// triangle and a valid material index; `spp ≥ 1` and `bounces ≥ -1`.
    ///
    /// # Errors
    /// [`SceneError::Validation`] naming the first problem.
    pub fn validate(&self) -> Result<(), SceneError> {
        let fail = |m: String| Err(SceneError::Validation(m));
        if let Err((key, m)) = self.camera.check() {
            return fail(format!("camera {key}: {m}"));
        }
        if let Err(m) = check_environment(&self.environment) {
            return fail(format!("environment: {m}"));
        }
        if self.material_names.len() != self.materials.len()
            || self.material_sources.len() != self.materials.len()
        {
            return fail(format!(
                "{} material names and {} sources for {} materials",
                self.material_names.len(),
                self.material_sources.len(),
                self.materials.len()
            ));
        }
        for (i, mat) in self.materials.iter().enumerate() {
            if let Err((key, m)) = mat.check() {
                return fail(format!(
                    "material {i} (`{}`) {key}: {m}",
                    self.material_names[i]
                ));
            }
        }
        for (i, mesh) in self.meshes.iter().enumerate() {
            if let Err(m) = check_mesh(mesh, self.materials.len()) {
                return fail(format!("mesh {i} (`{}`): {m}", mesh.name));
            }
            let t = self.tangents.get(i).map_or(&[][..], Vec::as_slice);
            if !t.is_empty() && t.len() != mesh.positions.len() {
                return fail(format!(
                    "mesh {i} (`{}`): {} tangents for {} vertices",
                    mesh.name,
                    t.len(),
                    mesh.positions.len()
                ));
            }
            if t.iter().flatten().any(|x| !x.is_finite()) {
                return fail(format!(
                    "mesh {i} (`{}`): a tangent is not finite",
                    mesh.name
                ));
            }
            if let Err(m) = self.check_textures_of(mesh) {
                return fail(format!(
                    "mesh {i} (`{}`), material `{}`: {m}",
                    mesh.name, self.material_names[mesh.material]
                ));
            }
        }
        for t in &self.textures {
            if t.width == 0 || t.height == 0 || t.texels.len() != t.width * t.height {
                return fail(format!(
                    "texture `{}`: {}×{} with {} texels",
                    t.name,
                    t.width,
                    t.height,
                    t.texels.len()
                ));
            }
            if let Some(k) = t
                .texels
                .iter()
                .position(|v| !v.iter().all(|x| x.is_finite()))
            {
                return fail(format!("texture `{}`: texel {k} is not finite", t.name));
            }
        }
        if self.render.spp == 0 {
            return fail("render spp is 0".into());
        }
        if self.render.bounces < -1 {
            return fail(format!("render bounces {} < -1", self.render.bounces));
        }
        Ok(())
    }
}

impl Scene {
    /// The texture references of `mesh`'s material must name a texture and a UV set the mesh
    /// has; vertex attributes must have one value per vertex, all finite.
    fn check_textures_of(&self, mesh: &Mesh) -> Result<(), String> {
        let n = mesh.positions.len();
        for (set, uv) in mesh.texcoords.iter().enumerate() {
            if uv.len() != n {
                return Err(format!(
                    "TEXCOORD_{set} has {} values for {n} vertices",
                    uv.len()
                ));
            }
            if let Some(k) = uv
                .iter()
                .position(|v| !(v[0].is_finite() && v[1].is_finite()))
            {
                return Err(format!("TEXCOORD_{set} of vertex {k} is not finite"));
            }
        }
        if !mesh.colors.is_empty() && mesh.colors.len() != n {
            return Err(format!(
                "COLOR_0 has {} values for {n} vertices",
                mesh.colors.len()
            ));
        }
        if let Some(k) = mesh
            .colors
            .iter()
            .position(|c| !c.iter().all(|x| x.is_finite()))
        {
            return Err(format!("COLOR_0 of vertex {k} is not finite"));
        }
        let inputs = self.surface_inputs(mesh.material);
        let mut refs = vec![
            ("normalTexture", inputs.normal_map.map(|n| n.texture)),
            ("emissiveTexture", inputs.emissive_texture),
        ];
        if let Material::Pbr {
            base_color_texture,
            metallic_roughness_texture,
            ..
        } = self.materials[mesh.material]
        {
            refs.extend([
                ("baseColorTexture", base_color_texture),
                ("metallicRoughnessTexture", metallic_roughness_texture),
            ]);
        }
        if let crate::AlphaMode::Mask { texture, .. } = inputs.alpha {
            refs.push(("alpha (baseColorTexture)", texture));
        }
        {
            for (what, t) in refs {
                let Some(t) = t else { continue };
                if t.index >= self.textures.len() {
                    return Err(format!(
                        "{what} is texture {} but there are {} textures",
                        t.index,
                        self.textures.len()
                    ));
                }
                if t.texcoord >= mesh.texcoords.len() {
                    return Err(format!(
                        "{what} (`{}`) reads TEXCOORD_{} but the mesh has {} UV set(s)",
                        self.textures[t.index].name,
                        t.texcoord,
                        mesh.texcoords.len()
                    ));
                }
            }
        }
        Ok(())
    }
}

fn check_environment(env: &Environment) -> Result<(), String> {
    let EnvImage {
        width,
        height,
        texels,
    } = &env.image;
    if *width == 0 || *height == 0 || texels.len() != width * height {
        return Err(format!(
            "{width}×{height} image with {} texels",
            texels.len()
        ));
    }
    if let Some(i) = texels
        .iter()
        .position(|t| t.iter().any(|v| !(v.is_finite() && *v >= 0.0)))
    {
        return Err(format!(
            "texel (col {}, row {}) is {:?}: must be finite and ≥ 0",
            i % width,
            i / width,
            texels[i]
        ));
    }
    if !env.rotation_y_deg.is_finite() {
        return Err(format!("rotation {} is not finite", env.rotation_y_deg));
    }
    Ok(())
}

fn check_mesh(mesh: &Mesh, materials: usize) -> Result<(), String> {
    if mesh.material >= materials {
        return Err(format!(
            "material index {} but {materials} materials",
            mesh.material
        ));
    }
    if mesh.indices.is_empty() {
        return Err("no triangles".into());
    }
    if mesh.normals.len() != mesh.positions.len() {
        return Err(format!(
            "{} normals for {} positions",
            mesh.normals.len(),
            mesh.positions.len()
        ));
    }
    if let Some(i) = mesh.positions.iter().position(|p| !p.is_finite()) {
        return Err(format!(
            "vertex {i} position {} is not finite",
            mesh.positions[i]
        ));
    }
    if let Some(i) = mesh
        .normals
        .iter()
        .position(|n| !(n.is_finite() && (n.length() - 1.0).abs() <= UNIT_TOLERANCE))
    {
        return Err(format!(
            "vertex {i} normal {} is not unit length",
            mesh.normals[i]
        ));
    }
    let n = mesh.positions.len();
    if let Some(t) = mesh
        .indices
        .iter()
        .position(|t| t.iter().any(|&i| i as usize >= n))
    {
        return Err(format!(
            "triangle {t} {:?} indexes past {n} vertices",
            mesh.indices[t]
        ));
    }
    Ok(())
}
