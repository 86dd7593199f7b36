//! glTF 2.0 export of a per-vertex or per-texel bake (`prt export`): the scene's meshes exactly as baked
//! (the bake's `MESH` sections: world-space positions, the normals the bake used, triangles)
//! with each vertex's diffuse transfer vector as custom vertex attributes, one binary `.glb`
//! an engine loads with its ordinary glTF importer.
//!
//! Layout (also in `extras.prt` of every primitive, and in the bake SPEC §10): for an object
//! of order `n` and `C` channels, coefficient `i` (SH index `l(l+1)+m`) of channel `c` is
//! component `i mod 4` of the `FLOAT VEC4` attribute `_PRT_C{c}_{⌊i/4⌋}` (the last group of
//! each channel padded with zeros). Values are the bake's f32 transfer, unchanged (f32 is
//! the only float type core glTF has; the file stores exactly the bake's numbers). Exit
//! radiance of a vertex is `(albedo/π) Σ_i t_{c,i} L_{c,i}` with the environment's SH
//! coefficients `L`, which `extras.prt.environment` carries (`[coefficient][r, g, b]`, the
//! bake's projection), and `albedo` `extras.prt.albedo` — or, when the scene material varies
//! over the surface (textures, vertex colours), the vertex's `_PRT_ALBEDO` — plus the
//! view-dependent terms `prt relight` shades (SPEC §10.1): the `pbr` diffuse factor
//! `1 − s̄_d(θ_o)` and the specular lobe (Phong, or the fitted zonal lobes of the glossy
//! materials) on the visibility transfer `_PRT_V_*`. The glTF material is the scene's own
//! (a `pbr` material's factors, textures, UV sets and vertex colours), so an engine shades
//! the asset as it would without the export.
//!
//! A per-texel (lightmap) bake exports each lightmapped object's transfer as **lightmap
//! textures** instead: coefficient `i` of channel `c` is component `i mod 4` of the RGBA8 PNG
//! image `extras.prt.lightmap.textures[c][⌊i/4⌋]` (a glTF texture with bilinear filtering and
//! clamp-to-edge wrapping), read at the primitive's `TEXCOORD_0` (the lightmap UVs the bake
//! used), quantised per coefficient: `t = offset[c][i] + scale[c][i] · code / 255` with the
//! range of that coefficient over the covered texels (so the rounding error is at most
//! `scale / 510`). Texels no triangle touches are dilated from their covered neighbours (two
//! rings), so that an engine's plain bilinear filtering does not pull chart borders toward 0.
//!
//! For a GPU pipeline ([`export_glb_for`], `--target webgl2|desktop`, SPEC §10.2, [`Target`]),
//! a primitive stays within 16 vertex attributes: transfer that does not fit goes into an
//! RGBA32F data texture read by `_PRT_VERTEX_ID`. [`viewer`] writes `prt view`'s live WebGL2
//! page of an export.

mod target;
pub mod viewer;

pub use target::{Target, TexturePacking};

use image::ImageEncoder as _;
use prt_bakefile::{Bake, SampleKind};
use prt_scene::Scene;
use prt_scene_relight::SceneRelightError;
use serde_json::{json, Value};
use std::path::Path;

/// What an export wrote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ExportSummary {
    /// Objects (glTF meshes) written.
    pub objects: usize,
    /// Vertices in all.
    pub vertices: usize,
    /// Custom `VEC4` transfer attributes per vertex (all objects: the largest count).
    pub attributes: usize,
    /// Vertex attributes of a primitive, all of them (all objects: the largest count).
    pub vertex_attributes: usize,
    /// Objects whose transfer is in a data texture (SPEC §10.2).
    pub transfer_textures: usize,
    /// The target the file was written for.
    pub target: Target,
    /// File size, bytes.
    pub bytes: usize,
}

fn invalid(msg: impl Into<String>) -> SceneRelightError {
    SceneRelightError::Invalid(msg.into())
}

/// A growing binary chunk with glTF buffer views.
struct Bin {
    data: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Bin {
    /// Appends `bytes` (4-byte aligned) as a buffer view without accessor or target (an
    /// image); returns the view's index.
    fn add_view(&mut self, bytes: &[u8]) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len(),
        }));
        self.data.extend_from_slice(bytes);
        self.views.len() - 1
    }

    /// Appends `bytes` (4-byte aligned) as a buffer view with an accessor; returns the
    /// accessor's index.
    fn add(&mut self, bytes: &[u8], target: u32, accessor: Value) -> usize {
        while !self.data.len().is_multiple_of(4) {
            self.data.push(0);
        }
        let view = self.views.len();
        self.views.push(json!({
            "buffer": 0, "byteOffset": self.data.len(), "byteLength": bytes.len(), "target": target,
        }));
        self.data.extend_from_slice(bytes);
        let mut a = accessor;
        a["bufferView"] = json!(view);
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

impl Bin {
    /// Appends `bytes` as a buffer view without target (data a shader reads as a texture)
    /// with an accessor; returns the accessor's index.
    fn add_data(&mut self, bytes: &[u8], accessor: Value) -> usize {
        let view = self.add_view(bytes);
        let mut a = accessor;
        a["bufferView"] = json!(view);
        self.accessors.push(a);
        self.accessors.len() - 1
    }
}

const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;
const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;

fn f32_bytes(v: impl IntoIterator<Item = f32>) -> Vec<u8> {
    v.into_iter().flat_map(f32::to_le_bytes).collect()
}

const LINEAR: u32 = 9729;
const CLAMP_TO_EDGE: u32 = 33071;

/// glTF's code of a wrap mode.
fn wrap_code(w: prt_scene::Wrap) -> u32 {
    match w {
        prt_scene::Wrap::Repeat => 10497,
        prt_scene::Wrap::MirroredRepeat => 33648,
        prt_scene::Wrap::ClampToEdge => CLAMP_TO_EDGE,
    }
}

/// The index of `sampler` in `samplers`, added if new.
fn sampler_index(samplers: &mut Vec<Value>, sampler: Value) -> usize {
    samplers
        .iter()
        .position(|s| *s == sampler)
        .unwrap_or_else(|| {
            samplers.push(sampler);
            samplers.len() - 1
        })
}

/// A scene texture as an RGBA8 PNG: RGB sRGB-encoded when `srgb` (a base colour: the loader
/// decoded it), else linear; alpha linear. An 8-bit source image reads back unchanged.
fn texture_png(t: &prt_scene::Texture, srgb: bool) -> Result<Vec<u8>, SceneRelightError> {
    let code = |x: f32| (x.clamp(0.0, 1.0) * 255.0).round() as u8;
    let rgba: Vec<u8> = t
        .texels
        .iter()
        .flat_map(|p| {
            let c = |x: f32| {
                code(if srgb {
                    prt_tracer::output::srgb_encode(x)
                } else {
                    x
                })
            };
            [c(p[0]), c(p[1]), c(p[2]), code(p[3])]
        })
        .collect();
    let mut png = Vec::new();
    image::codecs::png::PngEncoder::new(&mut png)
        .write_image(
            &rgba,
            t.width as u32,
            t.height as u32,
            image::ExtendedColorType::Rgba8,
        )
        .map_err(|e| invalid(format!("texture {}: {e}", t.name)))?;
    Ok(png)
}

/// Adds `n2` coefficients per vertex (`rows`: vertex `p`'s at `rows[p · stride + offset..]`)
/// as `⌈n2/4⌉` `FLOAT VEC4` attributes named `name(g)` (the last group zero-padded); returns
/// their names.
#[allow(clippy::too_many_arguments)]
fn add_coefficient_groups(
    bin: &mut Bin,
    attrs: &mut serde_json::Map<String, Value>,
    rows: &[f32],
    stride: usize,
    offset: usize,
    n2: usize,
    v: usize,
    name: impl Fn(usize) -> String,
) -> Vec<String> {
    (0..n2.div_ceil(4))
        .map(|g| {
            let values = (0..v).flat_map(|p| {
                let row = &rows[p * stride + offset..p * stride + offset + n2];
                (0..4).map(move |k| row.get(4 * g + k).copied().unwrap_or(0.0))
            });
            let a = bin.add(
                &f32_bytes(values),
                ARRAY_BUFFER,
                json!({"componentType": FLOAT, "count": v, "type": "VEC4"}),
            );
            attrs.insert(name(g), json!(a));
            name(g)
        })
        .collect()
}

/// The attribute name of coefficient group `g` of channel `c`.
#[must_use]
pub fn attribute_name(channel: usize, group: usize) -> String {
    format!("_PRT_C{channel}_{group}")
}

/// A lightmapped object's transfer as quantised RGBA8 PNG images.
struct QuantisedLightmap {
    /// `[channel][group]` PNG files.
    pngs: Vec<Vec<Vec<u8>>>,
    /// `[channel][coefficient]` offsets and scales: `t = offset + scale · code / 255`.
    offset: Vec<Vec<f32>>,
    scale: Vec<Vec<f32>>,
}

/// Per texel of `lm`, `[channel][coefficient]` values (`data`: the bake's rows, one per
/// texel, SPEC §3.1) where covered, and uncovered texels dilated from their covered
/// neighbours: two rings, each texel the mean of its already-filled 8-neighbours; `None`
/// beyond.
#[must_use]
pub fn dilated_lightmap(
    lm: &prt_scene::lightmap::Lightmap,
    data: &[f32],
    row: usize,
) -> Vec<Option<Vec<f32>>> {
    let (w, h) = (lm.width as usize, lm.height as usize);
    let mut texels: Vec<Option<Vec<f32>>> = lm
        .texels
        .iter()
        .enumerate()
        .map(|(k, t)| t.as_ref().map(|_| data[k * row..(k + 1) * row].to_vec()))
        .collect();
    for _ in 0..2 {
        let before = texels.clone();
        for y in 0..h {
            for x in 0..w {
                if before[y * w + x].is_some() {
                    continue;
                }
                let mut sum = vec![0.0f64; row];
                let mut n = 0usize;
                for (dx, dy) in [
                    (-1i64, -1i64),
                    (0, -1),
                    (1, -1),
                    (-1, 0),
                    (1, 0),
                    (-1, 1),
                    (0, 1),
                    (1, 1),
                ] {
                    let (xx, yy) = (x as i64 + dx, y as i64 + dy);
                    if xx < 0 || yy < 0 || xx >= w as i64 || yy >= h as i64 {
                        continue;
                    }
                    if let Some(v) = &before[yy as usize * w + xx as usize] {
                        sum.iter_mut().zip(v).for_each(|(s, v)| *s += f64::from(*v));
                        n += 1;
                    }
                }
                if n > 0 {
                    texels[y * w + x] = Some(sum.iter().map(|s| (s / n as f64) as f32).collect());
                }
            }
        }
    }
    texels
}

fn quantise_lightmap(
    lm: &prt_scene::lightmap::Lightmap,
    data: &[f32],
    channels: usize,
    n2: usize,
) -> QuantisedLightmap {
    let row = channels * n2;
    let texels = dilated_lightmap(lm, data, row);
    // The range of each coefficient over the covered texels (the dilated ones are means of
    // covered ones, so inside it).
    let (mut lo, mut hi) = (vec![f32::INFINITY; row], vec![f32::NEG_INFINITY; row]);
    for r in data
        .chunks_exact(row)
        .zip(&lm.texels)
        .filter_map(|(r, t)| t.as_ref().map(|_| r))
    {
        for (k, &v) in r.iter().enumerate() {
            lo[k] = lo[k].min(v);
            hi[k] = hi[k].max(v);
        }
    }
    let scale: Vec<f32> = lo.iter().zip(&hi).map(|(l, h)| (h - l).max(0.0)).collect();
    let code = |k: usize, v: f32| -> u8 {
        if scale[k] > 0.0 {
            (((v - lo[k]) / scale[k]) * 255.0).round().clamp(0.0, 255.0) as u8
        } else {
            0
        }
    };
    let (w, h) = (lm.width, lm.height);
    let mut pngs = Vec::with_capacity(channels);
    for ch in 0..channels {
        let mut per_group = Vec::new();
        for g in 0..n2.div_ceil(4) {
            let mut rgba = vec![0u8; (w * h * 4) as usize];
            for (t, texel) in texels.iter().enumerate() {
                for j in 0..4 {
                    let i = 4 * g + j;
                    if i >= n2 {
                        continue;
                    }
                    let k = ch * n2 + i;
                    // Texels out of reach of the dilation: the code nearest to 0.
                    let v = texel.as_ref().map_or(0.0, |r| r[k]);
                    rgba[4 * t + j] = code(k, v);
                }
            }
            let mut png = Vec::new();
            image::codecs::png::PngEncoder::new(&mut png)
                .write_image(&rgba, w, h, image::ExtendedColorType::Rgba8)
                .expect("encoding a PNG into memory");
            per_group.push(png);
        }
        pngs.push(per_group);
    }
    let split = |v: &[f32]| v.chunks(n2).map(<[f32]>::to_vec).collect::<Vec<_>>();
    QuantisedLightmap {
        pngs,
        offset: split(
            &lo.iter()
                .map(|l| if l.is_finite() { *l } else { 0.0 })
                .collect::<Vec<_>>(),
        ),
        scale: split(&scale),
    }
}

/// Writes `bake` (per vertex, made for `scene`, already checked with
/// [`prt_scene_relight::check_bake`]) as a binary glTF 2.0 file at `path`, atomically.
///
/// # Errors
/// A per-pixel or per-texel bake or an intermediate file, an object without mesh or diffuse
/// transfer, and write errors.
pub fn export_glb(
    scene: &Scene,
    bake: &Bake,
    path: &Path,
) -> Result<ExportSummary, SceneRelightError> {
    export_glb_for(scene, bake, path, Target::Raw)
}

/// [`export_glb`] for a target (SPEC §10.2): within its vertex-attribute budget, a per-vertex
/// object keeps its transfer in vertex attributes when everything fits, else the transfer
/// (and the visibility transfer) goes into a float data texture read by vertex id.
///
/// # Errors
/// As [`export_glb`], and an object that does not fit the target even so (named, with its
/// attribute count or texture size).
pub fn export_glb_for(
    scene: &Scene,
    bake: &Bake,
    path: &Path,
    target: Target,
) -> Result<ExportSummary, SceneRelightError> {
    match bake.meta.sample_kind {
        SampleKind::Vertex => {}
        SampleKind::Pixel { .. } => {
            return Err(invalid(
                "glTF export carries per-vertex transfer: this is a per-pixel bake (bake without --per-pixel)",
            ))
        }
        SampleKind::Texel { .. } => {}
    }
    let lightmaps = prt_scene_relight::relit::lightmaps(scene, bake)?;
    // Generated atlases (SPEC §3.9.3): their objects split along the chart seams, so the
    // glTF carries the atlas as a per-vertex TEXCOORD_0.
    let (split, lightmaps, was_split) = split_atlas_objects(scene, lightmaps);
    let scene = split.as_ref().unwrap_or(scene);
    let env = bake
        .environment
        .as_ref()
        .ok_or_else(|| invalid("the bake carries no environment coefficients"))?;
    let mut bin = Bin {
        data: Vec::new(),
        views: Vec::new(),
        accessors: Vec::new(),
    };
    let mut tex = Textures::default();
    let (mut meshes, mut nodes, mut materials) = (Vec::new(), Vec::new(), Vec::new());
    let (mut vertices, mut attributes) = (0usize, 0usize);
    let (mut vertex_attributes, mut transfer_textures) = (0usize, 0usize);
    for (o, obj) in bake.objects.iter().enumerate() {
        let lightmap = lightmaps[o].as_ref();
        let placement = placement(scene, env, o, obj, lightmap, target)?;
        // A split object's geometry is the split scene mesh, not the bake's MESH.
        let split_obj;
        let obj = if was_split[o] {
            split_obj = prt_bakefile::ObjectBake {
                mesh: None,
                ..obj.clone()
            };
            &split_obj
        } else {
            obj
        };
        let done = add_object(scene, env, o, obj, lightmap, placement, &mut bin, &mut tex)?;
        if let Some(budget) = target.attribute_budget() {
            if done.vertex_attributes > budget {
                return Err(invalid(format!(
                    "object {}: {} vertex attributes, more than the {} target's {budget} even with its transfer in a data texture",
                    obj.name,
                    done.vertex_attributes,
                    target.name()
                )));
            }
        }
        attributes = attributes.max(done.attributes);
        vertex_attributes = vertex_attributes.max(done.vertex_attributes);
        transfer_textures += usize::from(placement != Placement::Attributes);
        vertices += done.vertices;
        materials.push(done.material);
        meshes.push(done.mesh);
        nodes.push(json!({"name": obj.name, "mesh": o}));
    }
    while !bin.data.len().is_multiple_of(4) {
        bin.data.push(0);
    }
    let doc = document(scene, bake, (nodes, meshes, materials), &bin, tex);
    let glb = glb_container(&doc, &bin.data)?;
    prt_tracer::output::write_atomically(path, |w| {
        std::io::Write::write_all(w, &glb).map_err(|e| e.to_string())
    })
    .map_err(|e| SceneRelightError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    })?;
    Ok(ExportSummary {
        objects: bake.objects.len(),
        vertices,
        attributes,
        vertex_attributes,
        transfer_textures,
        target,
        bytes: glb.len(),
    })
}

/// Adds a lightmapped object's transfer: its lightmap UVs as `TEXCOORD_0` and the quantised
/// coefficient textures; returns `extras.prt.lightmap` (SPEC §10).
#[allow(clippy::too_many_arguments)]
fn add_lightmap(
    bin: &mut Bin,
    tex: &mut Textures,
    attrs: &mut serde_json::Map<String, Value>,
    lm: &prt_scene::lightmap::Lightmap,
    uv: &[[f32; 2]],
    data: &[f32],
    c: usize,
    n2: usize,
) -> Value {
    let uv_acc = bin.add(
        &f32_bytes(uv.iter().flatten().copied()),
        ARRAY_BUFFER,
        json!({"componentType": FLOAT, "count": uv.len(), "type": "VEC2"}),
    );
    attrs.insert("TEXCOORD_0".into(), json!(uv_acc));
    let q = quantise_lightmap(lm, data, c, n2);
    let tex_ids: Vec<Vec<usize>> = q
        .pngs
        .iter()
        .map(|pngs| pngs.iter().map(|png| tex.add_lightmap(bin, png)).collect())
        .collect();
    json!({
        "width": lm.width, "height": lm.height, "uv": "TEXCOORD_0",
        "textures": tex_ids, "offset": q.offset, "scale": q.scale,
        "covered_texels": lm.covered(),
        "layout": "coefficient i of channel c is component i mod 4 (RGBA) of texture textures[c][floor(i/4)], sampled bilinearly at TEXCOORD_0 (texel centres at (x + 1/2)/width, image row 0 at v = 0): t = offset[c][i] + scale[c][i] * code / 255",
    })
}

/// Where a per-vertex object's transfer goes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// `_PRT_C*` / `_PRT_V_*` vertex attributes (SPEC §10).
    Attributes,
    /// A float data texture at most this many texels a side (SPEC §10.2).
    Texture(usize),
}

/// Chooses where object `o`'s transfer goes for `target`: vertex attributes when the whole
/// primitive fits the attribute budget with them (tried on a scratch buffer when the transfer
/// alone leaves room), else a data texture. Lightmapped objects keep their textures.
fn placement(
    scene: &Scene,
    env: &prt_bakefile::EnvCoefficients,
    o: usize,
    obj: &prt_bakefile::ObjectBake,
    lightmap: Option<&prt_scene::lightmap::Lightmap>,
    target: Target,
) -> Result<Placement, SceneRelightError> {
    let Some(budget) = target.attribute_budget() else {
        return Ok(Placement::Attributes);
    };
    if lightmap.is_some() {
        return Ok(Placement::Attributes);
    }
    let groups = (obj.order as usize).pow(2).div_ceil(4);
    let has_visibility = obj
        .blocks
        .iter()
        .any(|b| b.kind == prt_bakefile::TransferKind::Visibility);
    let transfer = (obj.channels as usize + usize::from(has_visibility)) * groups;
    // POSITION and NORMAL are always there.
    if transfer + 2 <= budget {
        let mut scratch = Bin {
            data: Vec::new(),
            views: Vec::new(),
            accessors: Vec::new(),
        };
        let mut scratch_tex = Textures::default();
        let trial = add_object(
            scene,
            env,
            o,
            obj,
            None,
            Placement::Attributes,
            &mut scratch,
            &mut scratch_tex,
        )?;
        if trial.vertex_attributes <= budget {
            return Ok(Placement::Attributes);
        }
    }
    Ok(Placement::Texture(target.max_texture_size()))
}

/// Adds a per-vertex object's transfer (and its visibility transfer, when given) as a float
/// data texture and the `_PRT_VERTEX_ID` attribute that indexes it; returns
/// `extras.prt.transfer_texture` (SPEC §10.2).
#[allow(clippy::too_many_arguments)]
fn add_transfer_texture(
    bin: &mut Bin,
    attrs: &mut serde_json::Map<String, Value>,
    name: &str,
    data: &[f32],
    vis: Option<&[f32]>,
    (v, c, n2): (usize, usize, usize),
    max_size: usize,
) -> Result<Value, SceneRelightError> {
    if v > 1 << 24 {
        return Err(invalid(format!(
            "object {name}: {v} vertices; a FLOAT vertex id is exact below 2^24"
        )));
    }
    let packing = TexturePacking::new(v, c, n2, vis.is_some(), max_size).ok_or_else(|| {
        invalid(format!(
            "object {name}: its transfer ({v} vertices × {} texels) does not fit a {max_size} × {max_size} texture",
            (c + usize::from(vis.is_some())) * n2.div_ceil(4)
        ))
    })?;
    let texels = packing.pack(n2, data, c * n2, c, vis.map(|x| (x, c * n2)));
    let accessor = bin.add_data(
        &f32_bytes(texels),
        json!({"componentType": FLOAT, "count": packing.width * packing.height, "type": "VEC4"}),
    );
    let ids = bin.add(
        &f32_bytes((0..v).map(|i| i as f32)),
        ARRAY_BUFFER,
        json!({"componentType": FLOAT, "count": v, "type": "SCALAR"}),
    );
    attrs.insert("_PRT_VERTEX_ID".into(), json!(ids));
    Ok(json!({
        "accessor": accessor, "format": "RGBA32F",
        "width": packing.width, "height": packing.height, "max_size": max_size,
        "texels_per_vertex": packing.texels_per_vertex, "groups": packing.groups,
        "channel_texels": (0..c).map(|ch| ch * packing.groups).collect::<Vec<_>>(),
        "visibility_texel": packing.visibility,
        "vertex_id": "_PRT_VERTEX_ID",
        "layout": "coefficient i of channel c of vertex v is component i mod 4 of texel k = v * texels_per_vertex + channel_texels[c] + floor(i/4) (visibility: visibility_texel + floor(i/4)), at column k mod width, row floor(k / width) of the accessor's texels read row by row; v = _PRT_VERTEX_ID",
    }))
}

/// The prt diffuse albedo of object `o` for `extras.prt.albedo`: one value, or, when the
/// material varies over the surface (textures, vertex colours; `per_vertex` its vertex
/// count), the `_PRT_ALBEDO` attribute it adds.
fn add_albedo(
    scene: &Scene,
    o: usize,
    per_vertex: Option<usize>,
    bin: &mut Bin,
    attrs: &mut serde_json::Map<String, Value>,
) -> Value {
    let Some(v) = per_vertex else {
        return json!(scene.materials[scene.meshes[o].material].albedo());
    };
    let colours = (0..v as u32).flat_map(|i| {
        scene
            .material_at(o, prt_scene::SurfacePoint::Vertex(i))
            .albedo()
    });
    let a = bin.add(
        &f32_bytes(colours),
        ARRAY_BUFFER,
        json!({"componentType": FLOAT, "count": v, "type": "VEC3"}),
    );
    attrs.insert("_PRT_ALBEDO".into(), json!(a));
    json!("_PRT_ALBEDO")
}

/// Object `obj`'s diffuse transfer, and its visibility transfer when the primitive has a
/// lobe, as a data texture ([`add_transfer_texture`]).
fn textured_transfer(
    obj: &prt_bakefile::ObjectBake,
    with_lobe: bool,
    (v, c, n2): (usize, usize, usize),
    max_size: usize,
    bin: &mut Bin,
    attrs: &mut serde_json::Map<String, Value>,
) -> Result<Value, SceneRelightError> {
    let block = obj
        .diffuse_block()
        .ok_or_else(|| invalid(format!("object {} has no diffuse transfer", obj.name)))?;
    let vis = obj
        .blocks
        .iter()
        .find(|b| b.kind == prt_bakefile::TransferKind::Visibility)
        .filter(|_| with_lobe);
    add_transfer_texture(
        bin,
        attrs,
        &obj.name,
        &block.data,
        vis.map(|b| b.data.as_slice()),
        (v, c, n2),
        max_size,
    )
}

/// One object's part of the export: its mesh (with `extras.prt`) and material, and counts for
/// the summary.
struct ObjectExport {
    mesh: Value,
    material: Value,
    vertices: usize,
    attributes: usize,
    vertex_attributes: usize,
}

/// The scene with every object whose lightmap is a generated atlas (per-corner UVs, SPEC
/// §3.9.3) split along its chart seams ([`prt_scene::lightmap::split_corners`]: positions,
/// normals, vertex colours and UV sets copied from each new vertex's source, the atlas UVs
/// as UV set 0 before the mesh's own), the lightmaps with those objects reading set 0, and
/// which objects were split; `None` and the lightmaps unchanged when no object has an atlas.
fn split_atlas_objects(
    scene: &Scene,
    mut lightmaps: Vec<Option<prt_scene::lightmap::Lightmap>>,
) -> (
    Option<Scene>,
    Vec<Option<prt_scene::lightmap::Lightmap>>,
    Vec<bool>,
) {
    let was_split: Vec<bool> = lightmaps
        .iter()
        .map(|l| l.as_ref().is_some_and(|l| l.corner_uvs.is_some()))
        .collect();
    if !was_split.contains(&true) {
        return (None, lightmaps, was_split);
    }
    let mut split = scene.clone();
    for (mesh, lm) in split.meshes.iter_mut().zip(lightmaps.iter_mut()) {
        let Some(corners) = lm.as_mut().and_then(|l| l.corner_uvs.take()) else {
            continue;
        };
        let (source, indices, uvs) = prt_scene::lightmap::split_corners(&mesh.indices, &corners);
        // Each per-vertex array (empty ones stay empty) at the new vertices' sources.
        fn pick<T: Copy>(v: &[T], source: &[u32]) -> Vec<T> {
            if v.is_empty() {
                return Vec::new();
            }
            source.iter().map(|&i| v[i as usize]).collect()
        }
        let (positions, normals) = (pick(&mesh.positions, &source), pick(&mesh.normals, &source));
        let colors = pick(&mesh.colors, &source);
        let mut texcoords = vec![uvs];
        texcoords.extend(mesh.texcoords.iter().map(|set| pick(set, &source)));
        (mesh.positions, mesh.normals, mesh.indices) = (positions, normals, indices);
        (mesh.colors, mesh.texcoords) = (colors, texcoords);
        if let Some(l) = lm.as_mut() {
            l.uv_set = 0;
        }
    }
    (Some(split), lightmaps, was_split)
}

/// Adds object `o` of the bake to the binary chunk and textures: geometry, transfer (vertex
/// attributes or a lightmap), albedo, the core glTF material, vertex colours and the
/// view-dependent terms (SPEC §10).
fn add_object(
    scene: &Scene,
    env: &prt_bakefile::EnvCoefficients,
    o: usize,
    obj: &prt_bakefile::ObjectBake,
    lightmap: Option<&prt_scene::lightmap::Lightmap>,
    placement: Placement,
    bin: &mut Bin,
    tex: &mut Textures,
) -> Result<ObjectExport, SceneRelightError> {
    let block = obj
        .diffuse_block()
        .ok_or_else(|| invalid(format!("object {} has no diffuse transfer", obj.name)))?;
    let scene_mesh = &scene.meshes[o];
    let geometry = obj
        .mesh
        .clone()
        .unwrap_or_else(|| prt_scene::binding::mesh_geometry(scene_mesh));
    let v = geometry.positions.len();
    // A lightmapped object's points are its texels, covered or not (SPEC §3.1).
    let points = match lightmap {
        Some(lm) => lm.texels.len(),
        None => v,
    };
    if points as u64 != obj.point_count || v == 0 {
        return Err(invalid(format!(
            "object {}: {v} vertices ({points} points) for {} points in the bake",
            obj.name, obj.point_count
        )));
    }
    let (n, c) = (obj.order as usize, obj.channels as usize);
    let n2 = n * n;
    let (mut attrs, indices) = add_geometry(bin, &geometry);
    let mut names = Vec::new();
    let lightmap_extras = match lightmap {
        Some(lm) => {
            let uv = &scene_mesh.texcoords[lm.uv_set];
            add_lightmap(bin, tex, &mut attrs, lm, uv, &block.data, c, n2)
        }
        None => Value::Null,
    };
    let in_attributes = lightmap.is_none() && placement == Placement::Attributes;
    for ch in (0..c).filter(|_| in_attributes) {
        names.extend(add_coefficient_groups(
            bin,
            &mut attrs,
            &block.data,
            c * n2,
            ch * n2,
            n2,
            v,
            |g| attribute_name(ch, g),
        ));
    }
    let material = &scene.materials[scene_mesh.material];
    // The prt diffuse albedo: one, or per vertex where the material varies over the
    // surface (textures, vertex colours) as `_PRT_ALBEDO`.
    let varies = scene.material_varies(o) && scene_mesh.positions.len() == v;
    let albedo = add_albedo(scene, o, varies.then_some(v), bin, &mut attrs);
    // The core glTF material: the scene's own where glTF has it (`pbr`: factors and
    // textures, with the asset's UV sets and vertex colours), else the diffuse albedo.
    let uv_shift = usize::from(lightmap.is_some());
    let pbr = tex.material(
        bin,
        &mut attrs,
        scene,
        scene_mesh,
        material,
        uv_shift,
        (scene_mesh.positions.len() == v).then_some(v),
        &obj.name,
    )?;
    let same_vertices = scene_mesh.positions.len() == v;
    // The asset's vertex colours, which core glTF multiplies into the base colour.
    if same_vertices && !scene_mesh.colors.is_empty() {
        let a = bin.add(
            &f32_bytes(scene_mesh.colors.iter().flatten().copied()),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "count": v, "type": "VEC3"}),
        );
        attrs.insert("COLOR_0".into(), json!(a));
    }
    // The view-dependent terms (SPEC §10.1), per-vertex objects only.
    let view = if lightmap.is_none() {
        let points: Option<Vec<prt_scene::Material>> = varies.then(|| {
            (0..v as u32)
                .map(|i| scene.material_at(o, prt_scene::SurfacePoint::Vertex(i)))
                .collect()
        });
        let order = n.min(env.order as usize);
        let vd = prt_scene_relight::relit::view_dependent(material, points.as_deref(), order)?;
        let vis = obj
            .blocks
            .iter()
            .find(|b| b.kind == prt_bakefile::TransferKind::Visibility);
        view_extras(
            &vd,
            vis.map(|b| b.data.as_slice()),
            v,
            c,
            n2,
            placement == Placement::Attributes,
            bin,
            &mut attrs,
        )
    } else {
        json!({
            "diffuse_fresnel": null, "specular": null,
            "view_dependent": "not exported for lightmapped objects: the diffuse term only",
        })
    };
    // Under a target's budget: the transfer (and the visibility transfer the lobe needs) in a
    // data texture.
    let transfer_texture = match placement {
        Placement::Texture(max_size) if lightmap.is_none() => {
            let with_lobe = !view["specular"].is_null();
            textured_transfer(obj, with_lobe, (v, c, n2), max_size, bin, &mut attrs)?
        }
        _ => Value::Null,
    };
    let storage = match (lightmap, &transfer_texture) {
        (Some(_), _) => "lightmap",
        (None, Value::Null) => "vertex",
        (None, _) => "vertex_texture",
    };
    let layout = match storage {
        "lightmap" => "see lightmap.layout; SH index l(l+1)+m",
        "vertex" => "coefficient i (SH index l(l+1)+m) of channel c is component i mod 4 of the FLOAT VEC4 attribute _PRT_C{c}_{floor(i/4)}; unused components are 0",
        _ => "see transfer_texture.layout; SH index l(l+1)+m",
    };
    let vertex_attributes = attrs.len();
    let material_json = json!({
        "name": scene.material_names.get(scene_mesh.material).cloned().unwrap_or_default(),
        "pbrMetallicRoughness": pbr,
    });
    let en2 = (env.order * env.order) as usize;
    let env_rows: Vec<[f64; 3]> = (0..n2.min(en2))
        .map(|i| [env.values[i], env.values[en2 + i], env.values[2 * en2 + i]])
        .collect();
    let mut mesh = json!({
        "name": obj.name,
        "primitives": [{
            "attributes": attrs, "indices": indices, "material": o, "mode": 4,
            "extras": {"prt": {
                "format": "prt-transfer", "version": 1,
                "kind": block.kind.name(), "order": n, "channels": c,
                "storage": storage,
                "attributes": names,
                "lightmap": lightmap_extras,
                "layout": layout,
                "sh": {"basis": "real-orthonormal", "phase": "condon-shortley", "index_order": "l(l+1)+m", "angles": "theta-from-+Z, phi=atan2(y,x)"},
                "radiance": "exit radiance of channel c = diffuse + specular (SPEC §10.1); diffuse = albedo_c * k_d / pi * sum_i t[c or 0][i] * environment[i][c], albedo = extras.prt.albedo, or the vertex attribute it names (the scene material's diffuse albedo at the vertex, textures applied)",
                "albedo": albedo,
                "albedo_in_transfer": false,
                "environment": env_rows,
                "geometry_hash": format!("0x{:016x}", obj.geometry_hash),
                "diffuse_fresnel": view["diffuse_fresnel"],
                "specular": view["specular"],
                "view_dependent": view["view_dependent"],
            }},
        }],
    });
    // Only in files with a texture (raw exports stay as they were).
    if !transfer_texture.is_null() {
        mesh["primitives"][0]["extras"]["prt"]["transfer_texture"] = transfer_texture;
    }
    Ok(ObjectExport {
        mesh,
        material: material_json,
        vertices: v,
        attributes: names.len(),
        vertex_attributes,
    })
}

/// The glTF document of the export: its scene of one node per object, the meshes, materials,
/// accessors, buffer views, textures, and the root `extras.prt` (SPEC §10).
fn document(
    scene: &Scene,
    bake: &Bake,
    (nodes, meshes, materials): (Vec<Value>, Vec<Value>, Vec<Value>),
    bin: &Bin,
    tex: Textures,
) -> Value {
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": format!("prt {}", env!("CARGO_PKG_VERSION"))},
        "scene": 0,
        "scenes": [{"nodes": (0..nodes.len()).collect::<Vec<_>>()}],
        "nodes": nodes,
        "meshes": meshes,
        "materials": materials,
        "accessors": bin.accessors,
        "bufferViews": bin.views,
        "buffers": [{"byteLength": bin.data.len()}],
        "extras": {"prt": {
            "bake_seed": bake.meta.seed.to_string(), "rays_per_point": bake.meta.rays_per_point, "bounces": bake.meta.bounces,
            // The viewpoint `prt relight` shades the view-dependent terms from (SPEC §10.1).
            "camera": {
                "eye": scene.camera.eye.as_vec3().to_array(),
                "target": scene.camera.target.as_vec3().to_array(),
                "up": scene.camera.up.as_vec3().to_array(),
                "fov_y": scene.camera.fov_y_deg,
                "resolution": [scene.camera.width, scene.camera.height],
            },
        }},
    });
    if tex.transforms {
        doc["extensionsUsed"] = json!(["KHR_texture_transform"]);
    }
    if !tex.images.is_empty() {
        doc["images"] = json!(tex.images);
        doc["textures"] = json!(tex.textures);
        doc["samplers"] = json!(tex.samplers);
    }
    doc
}

/// The accessors of an object's mesh: `POSITION` (with its bounds) and `NORMAL` attributes,
/// and the triangle indices' accessor.
fn add_geometry(
    bin: &mut Bin,
    geometry: &prt_bakefile::MeshGeometry,
) -> (serde_json::Map<String, Value>, usize) {
    let v = geometry.positions.len();
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    for p in &geometry.positions {
        for k in 0..3 {
            lo[k] = lo[k].min(p[k]);
            hi[k] = hi[k].max(p[k]);
        }
    }
    let position = bin.add(
        &f32_bytes(geometry.positions.iter().flatten().copied()),
        ARRAY_BUFFER,
        json!({"componentType": FLOAT, "count": v, "type": "VEC3", "min": lo, "max": hi}),
    );
    let normal = bin.add(
        &f32_bytes(geometry.normals.iter().flatten().copied()),
        ARRAY_BUFFER,
        json!({"componentType": FLOAT, "count": v, "type": "VEC3"}),
    );
    let indices = bin.add(
        &geometry
            .triangles
            .iter()
            .flatten()
            .flat_map(|i| i.to_le_bytes())
            .collect::<Vec<u8>>(),
        ELEMENT_ARRAY_BUFFER,
        json!({"componentType": UNSIGNED_INT, "count": 3 * geometry.triangles.len(), "type": "SCALAR"}),
    );
    let mut attrs = serde_json::Map::new();
    attrs.insert("POSITION".into(), json!(position));
    attrs.insert("NORMAL".into(), json!(normal));
    (attrs, indices)
}

/// The file's images, textures and samplers, and which scene textures are written already.
#[derive(Default)]
struct Textures {
    images: Vec<Value>,
    textures: Vec<Value>,
    samplers: Vec<Value>,
    /// Scene textures already written: (scene texture, sRGB) → glTF texture.
    written: Vec<((usize, bool), usize)>,
    /// Whether a texture reference carries a `KHR_texture_transform`.
    transforms: bool,
}

impl Textures {
    /// A texture of PNG `png` read with `sampler`; its index.
    fn add(&mut self, bin: &mut Bin, png: &[u8], name: Option<&str>, sampler: Value) -> usize {
        let view = bin.add_view(png);
        let mut image = json!({"bufferView": view, "mimeType": "image/png"});
        if let Some(n) = name {
            image["name"] = json!(n);
        }
        self.images.push(image);
        let sampler = sampler_index(&mut self.samplers, sampler);
        self.textures
            .push(json!({"sampler": sampler, "source": self.images.len() - 1}));
        self.textures.len() - 1
    }

    /// A lightmap texture: bilinear, clamp to edge — the lookup prt's image formation does,
    /// bar its renormalisation over covered texels (which the dilation stands in for).
    fn add_lightmap(&mut self, bin: &mut Bin, png: &[u8]) -> usize {
        self.add(
            bin,
            png,
            None,
            json!({"magFilter": LINEAR, "minFilter": LINEAR, "wrapS": CLAMP_TO_EDGE, "wrapT": CLAMP_TO_EDGE}),
        )
    }

    /// The `textureInfo` of scene texture `t` (written once per texture and colour space),
    /// adding the UV set it reads (shifted by `uv_shift` past a lightmap's `TEXCOORD_0`);
    /// `None` when the export's vertices are not the scene mesh's (`vertices` is `None`) or
    /// the mesh lacks that UV set.
    #[allow(clippy::too_many_arguments)]
    fn texture_info(
        &mut self,
        bin: &mut Bin,
        attrs: &mut serde_json::Map<String, Value>,
        scene: &Scene,
        mesh: &prt_scene::Mesh,
        t: Option<prt_scene::TextureRef>,
        srgb: bool,
        uv_shift: usize,
        vertices: Option<usize>,
        object: &str,
    ) -> Result<Option<Value>, SceneRelightError> {
        let (Some(t), Some(v)) = (t, vertices) else {
            return Ok(None);
        };
        if t.texcoord >= mesh.texcoords.len() {
            return Ok(None);
        }
        let index = match self.written.iter().find(|(k, _)| *k == (t.index, srgb)) {
            Some(&(_, i)) => i,
            None => {
                let tex = scene.textures.get(t.index).ok_or_else(|| {
                    invalid(format!("object {object}: texture {} is missing", t.index))
                })?;
                let i = self.add(
                    bin,
                    &texture_png(tex, srgb)?,
                    Some(&tex.name),
                    json!({"magFilter": LINEAR, "minFilter": LINEAR,
                           "wrapS": wrap_code(tex.wrap[0]), "wrapT": wrap_code(tex.wrap[1])}),
                );
                self.written.push(((t.index, srgb), i));
                i
            }
        };
        let set = t.texcoord + uv_shift;
        let name = format!("TEXCOORD_{set}");
        if !attrs.contains_key(&name) {
            let uv = &mesh.texcoords[t.texcoord];
            let acc = bin.add(
                &f32_bytes(uv.iter().flatten().copied()),
                ARRAY_BUFFER,
                json!({"componentType": FLOAT, "count": v, "type": "VEC2"}),
            );
            attrs.insert(name, json!(acc));
        }
        let mut info = json!({"index": index, "texCoord": set});
        // The asset's texture transform, as it came (SPEC §10: the core material is the
        // asset's own).
        if let Some(tr) = t.transform {
            info["extensions"] = json!({"KHR_texture_transform": {
                "offset": tr.offset, "rotation": tr.rotation, "scale": tr.scale,
            }});
            self.transforms = true;
        }
        Ok(Some(info))
    }

    /// The core glTF `pbrMetallicRoughness` of `material`: a `pbr` material's factors and
    /// textures, else its diffuse albedo as the base colour.
    #[allow(clippy::too_many_arguments)]
    fn material(
        &mut self,
        bin: &mut Bin,
        attrs: &mut serde_json::Map<String, Value>,
        scene: &Scene,
        mesh: &prt_scene::Mesh,
        material: &prt_scene::Material,
        uv_shift: usize,
        vertices: Option<usize>,
        object: &str,
    ) -> Result<Value, SceneRelightError> {
        let prt_scene::Material::Pbr {
            base_color,
            metallic,
            roughness,
            base_color_texture,
            metallic_roughness_texture,
        } = *material
        else {
            let a = material.albedo();
            return Ok(
                json!({"baseColorFactor": [a[0], a[1], a[2], 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0}),
            );
        };
        let mut m = json!({
            "baseColorFactor": [base_color[0], base_color[1], base_color[2], 1.0],
            "metallicFactor": metallic, "roughnessFactor": roughness,
        });
        for (key, t, srgb) in [
            ("baseColorTexture", base_color_texture, true),
            (
                "metallicRoughnessTexture",
                metallic_roughness_texture,
                false,
            ),
        ] {
            let info =
                self.texture_info(bin, attrs, scene, mesh, t, srgb, uv_shift, vertices, object)?;
            if let Some(info) = info {
                m[key] = info;
            }
        }
        Ok(m)
    }
}

/// A binary glTF container (12-byte header, the JSON chunk padded with spaces, the binary
/// chunk) of `doc` and `bin` (padded to 4 bytes already).
fn glb_container(doc: &Value, bin: &[u8]) -> Result<Vec<u8>, SceneRelightError> {
    let mut json_bytes = serde_json::to_vec(doc).map_err(|e| invalid(e.to_string()))?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    if u32::try_from(total).is_err() {
        return Err(invalid("the export exceeds the 4 GiB of a .glb file"));
    }
    let mut glb = Vec::with_capacity(total);
    glb.extend_from_slice(b"glTF");
    glb.extend_from_slice(&2u32.to_le_bytes());
    glb.extend_from_slice(&(total as u32).to_le_bytes());
    glb.extend_from_slice(&(json_bytes.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"JSON");
    glb.extend_from_slice(&json_bytes);
    glb.extend_from_slice(&(bin.len() as u32).to_le_bytes());
    glb.extend_from_slice(b"BIN\0");
    glb.extend_from_slice(bin);
    Ok(glb)
}

/// `extras.prt`'s `diffuse_fresnel`, `specular` and `view_dependent` of a per-vertex object
/// (SPEC §10.1), adding the attributes they name (`vis`: the visibility block's rows, one per
/// vertex, `channels × n2` coefficients each, `[channel][coefficient]` as the object has
/// `channels`; the export writes channel 0, which every channel repeats: SPEC §3.4).
fn view_extras(
    vd: &prt_scene_relight::relit::ViewDependent,
    vis: Option<&[f32]>,
    v: usize,
    channels: usize,
    n2: usize,
    vis_as_attributes: bool,
    bin: &mut Bin,
    attrs: &mut serde_json::Map<String, Value>,
) -> Value {
    let diffuse_fresnel = vd
        .diffuse_fresnel
        .as_ref()
        .map_or(Value::Null, |(e, s)| json!({"elevations": e, "values": s}));
    // The visibility transfer, when there is a lobe to shade with it.
    let vis_names = match (&vd.specular, vis) {
        (Some(_), Some(vis)) if vis_as_attributes => {
            add_coefficient_groups(bin, attrs, vis, channels * n2, 0, n2, v, |g| {
                format!("_PRT_V_{g}")
            })
        }
        _ => Vec::new(),
    };
    let mut add = |name: &str, values: Vec<f32>, kind: &str, attrs: &mut serde_json::Map<_, _>| {
        let a = bin.add(
            &f32_bytes(values),
            ARRAY_BUFFER,
            json!({"componentType": FLOAT, "count": v, "type": kind}),
        );
        attrs.insert(name.to_owned(), json!(a));
    };
    let (specular, note) = match (&vd.specular, vis) {
        (None, _) => (Value::Null, "no specular lobe".to_owned()),
        (Some(_), None) => (
            Value::Null,
            "the bake holds no visibility transfer: no specular (as prt relight)".to_owned(),
        ),
        (Some(lobe), Some(_)) => {
            let mut value = match lobe {
                prt_scene_relight::relit::ExportLobe::Phong {
                    exponent,
                    specular,
                    bands,
                } => {
                    json!({"model": "phong", "exponent": exponent, "specular": specular, "bands": bands})
                }
                prt_scene_relight::relit::ExportLobe::Fitted {
                    table_order,
                    lobes,
                    elevations,
                    roughness_levels,
                    axis,
                    bands,
                    bands_b,
                    colour_a,
                    colour_b,
                    point_roughness,
                } => {
                    let (e, k, t) = (elevations.len(), *lobes, *table_order);
                    // `[level][elevation][lobe]` and `[level][elevation][lobe][band]`.
                    let nest3 = |x: &[f32]| -> Vec<Vec<Vec<f32>>> {
                        x.chunks(e * k)
                            .map(|r| r.chunks(k).map(<[f32]>::to_vec).collect())
                            .collect()
                    };
                    let nest4 = |x: &[f32]| -> Vec<Vec<Vec<Vec<f32>>>> {
                        x.chunks(e * k * t)
                            .map(|r| {
                                r.chunks(k * t)
                                    .map(|q| q.chunks(t).map(<[f32]>::to_vec).collect())
                                    .collect()
                            })
                            .collect()
                    };
                    let mut per_vertex = |name: &str, c: &[[f32; 3]]| -> Value {
                        if c.len() == 1 {
                            json!(c[0])
                        } else {
                            add(name, c.iter().flatten().copied().collect(), "VEC3", attrs);
                            json!(name)
                        }
                    };
                    let a = per_vertex("_PRT_SPEC_A", colour_a);
                    let b = per_vertex("_PRT_SPEC_B", colour_b);
                    let roughness = if point_roughness.len() == 1 {
                        json!(point_roughness[0])
                    } else {
                        add("_PRT_ROUGHNESS", point_roughness.clone(), "SCALAR", attrs);
                        json!("_PRT_ROUGHNESS")
                    };
                    json!({
                        "model": "fitted", "table_order": t, "lobes": k,
                        "elevations": elevations, "roughness_levels": roughness_levels,
                        "axis": nest3(axis), "bands": nest4(bands),
                        "bands_b": if bands_b.is_empty() { json!([]) } else { json!(nest4(bands_b)) },
                        "colour_a": a, "colour_b": b, "roughness": roughness,
                    })
                }
            };
            value["visibility_attributes"] = json!(vis_names);
            (
                value,
                "as prt relight at full order, --glossy fitted (SPEC §10.1)".to_owned(),
            )
        }
    };
    json!({"diffuse_fresnel": diffuse_fresnel, "specular": specular, "view_dependent": note})
}

/// One object of an export read back: positions and its transfer (`[vertex][channel][coeff]`,
/// as the bake lays it out).
#[derive(Clone, Debug, PartialEq)]
pub struct ExportedObject {
    /// Mesh name.
    pub name: String,
    /// Order and channels from `extras.prt`.
    pub order: usize,
    /// Channels.
    pub channels: usize,
    /// Positions.
    pub positions: Vec<[f32; 3]>,
    /// Transfer, `[vertex][channel][coefficient]`.
    pub transfer: Vec<f32>,
    /// The diffuse albedo of the relighting formula (`extras.prt.albedo`): one value, or one
    /// per vertex (`_PRT_ALBEDO`) where the material varies over the surface.
    pub albedo: Vec<[f32; 3]>,
    /// A lightmapped object's transfer (then `transfer` is empty).
    pub lightmap: Option<ExportedLightmap>,
    /// The visibility transfer `_PRT_V_*` (`[vertex][coefficient]`) of an object with a
    /// specular lobe (SPEC §10.1).
    pub visibility: Option<Vec<f32>>,
}

/// A lightmapped object's transfer read back from its textures.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportedLightmap {
    /// Size in texels.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// Per texel (`y · width + x`), `[channel][coefficient]`, dequantised.
    pub transfer: Vec<f32>,
    /// The lightmap UVs (`TEXCOORD_0`), per vertex.
    pub uvs: Vec<[f32; 2]>,
    /// `[channel][coefficient]` quantisation steps (`scale / 255`).
    pub step: Vec<f32>,
}

/// Reads an export back with the `gltf` crate (the layout of [`export_glb`]).
///
/// # Errors
/// When the file is not a readable glTF or lacks the prt attributes.
pub fn read_export(path: &Path) -> Result<Vec<ExportedObject>, SceneRelightError> {
    let bad = |m: String| invalid(format!("{}: {m}", path.display()));
    let (doc, buffers, images) = gltf::import(path).map_err(|e| bad(e.to_string()))?;
    let floats = |acc: &gltf::Accessor| -> Result<Vec<f32>, SceneRelightError> {
        let view = acc
            .view()
            .ok_or_else(|| bad("accessor without buffer view".into()))?;
        let buf = &buffers[view.buffer().index()];
        let start = view.offset() + acc.offset();
        let len = acc.count() * acc.dimensions().multiplicity() * 4;
        let bytes = buf
            .get(start..start + len)
            .ok_or_else(|| bad("accessor beyond its buffer".into()))?;
        Ok(bytes
            .chunks_exact(4)
            .map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]]))
            .collect())
    };
    let mut out = Vec::new();
    for mesh in doc.meshes() {
        let prim = mesh
            .primitives()
            .next()
            .ok_or_else(|| bad("a mesh without primitives".into()))?;
        let extras: Value = prim
            .extras()
            .as_ref()
            .and_then(|r| serde_json::from_str(r.get()).ok())
            .ok_or_else(|| bad("a primitive without extras.prt".into()))?;
        let prt = &extras["prt"];
        let (order, channels) = (
            prt["order"].as_u64().unwrap_or(0) as usize,
            prt["channels"].as_u64().unwrap_or(0) as usize,
        );
        let n2 = order * order;
        let mut attrs = std::collections::HashMap::new();
        for (semantic, acc) in prim.attributes() {
            attrs.insert(semantic.to_string(), acc);
        }
        let position = attrs
            .get("POSITION")
            .ok_or_else(|| bad("no POSITION".into()))?;
        let positions: Vec<[f32; 3]> = floats(position)?
            .chunks_exact(3)
            .map(|c| [c[0], c[1], c[2]])
            .collect();
        let v = positions.len();
        let lightmap = match prt.get("lightmap").filter(|l| !l.is_null()) {
            Some(l) => Some(read_lightmap(
                l, channels, n2, &images, &attrs, &floats, &bad,
            )?),
            None => None,
        };
        // `n2` coefficients per vertex from the VEC4 attributes `name(g)`, `[vertex][coeff]`.
        let groups = |name: &dyn Fn(usize) -> String| -> Result<Vec<f32>, SceneRelightError> {
            let mut out = vec![0.0f32; v * n2];
            for g in 0..n2.div_ceil(4) {
                let name = name(g);
                let acc = attrs
                    .get(&name)
                    .ok_or_else(|| bad(format!("no attribute {name}")))?;
                let vals = floats(acc)?;
                if vals.len() != 4 * v {
                    return Err(bad(format!(
                        "attribute {name}: {} values for {v} vertices",
                        vals.len() / 4
                    )));
                }
                for p in 0..v {
                    for k in (0..4).filter(|k| 4 * g + k < n2) {
                        out[p * n2 + 4 * g + k] = vals[4 * p + k];
                    }
                }
            }
            Ok(out)
        };
        // The transfer and visibility: from the §10.2 data texture, or the attributes.
        let texture = prt.get("transfer_texture").filter(|t| !t.is_null());
        let (transfer, visibility) = if let Some(t) = texture {
            read_transfer_texture(t, &doc, &attrs, &floats, &bad, (v, channels, n2))?
        } else {
            let mut transfer = Vec::new();
            if lightmap.is_none() {
                let per_channel: Vec<Vec<f32>> = (0..channels)
                    .map(|ch| groups(&|g| attribute_name(ch, g)))
                    .collect::<Result<_, _>>()?;
                transfer = vec![0.0f32; v * channels * n2];
                for (ch, rows) in per_channel.iter().enumerate() {
                    for p in 0..v {
                        transfer[(p * channels + ch) * n2..][..n2]
                            .copy_from_slice(&rows[p * n2..(p + 1) * n2]);
                    }
                }
            }
            let visibility = if attrs.contains_key("_PRT_V_0") {
                Some(groups(&|g| format!("_PRT_V_{g}"))?)
            } else {
                None
            };
            (transfer, visibility)
        };
        let albedo = read_albedo(prt, &attrs, &floats, &bad, v)?;
        out.push(ExportedObject {
            name: mesh.name().unwrap_or_default().to_owned(),
            order,
            channels,
            positions,
            transfer,
            albedo,
            lightmap,
            visibility,
        });
    }
    Ok(out)
}

/// An accessor's f32 values, as `read_export` reads them.
type Floats<'a> = dyn Fn(&gltf::Accessor) -> Result<Vec<f32>, SceneRelightError> + 'a;
/// A primitive's attributes by name.
type Attributes<'a> = std::collections::HashMap<String, gltf::Accessor<'a>>;

/// The diffuse albedo of a primitive (`extras.prt.albedo`): one value, or one per vertex.
fn read_albedo(
    prt: &Value,
    attrs: &Attributes,
    floats: &Floats,
    bad: &dyn Fn(String) -> SceneRelightError,
    v: usize,
) -> Result<Vec<[f32; 3]>, SceneRelightError> {
    Ok(match &prt["albedo"] {
        Value::String(name) => {
            let acc = attrs
                .get(name)
                .ok_or_else(|| bad(format!("extras.prt.albedo names {name}, which is missing")))?;
            let vals = floats(acc)?;
            if vals.len() != 3 * v {
                return Err(bad(format!(
                    "{name}: {} values for {v} vertices",
                    vals.len() / 3
                )));
            }
            vals.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect()
        }
        other => vec![serde_json::from_value::<[f32; 3]>(other.clone())
            .map_err(|e| bad(format!("extras.prt.albedo: {e}")))?],
    })
}

/// A `vertex_texture` primitive's transfer and visibility (SPEC §10.2), `[vertex][channel]
/// [coeff]` and `[vertex][coeff]`, indexed through its `_PRT_VERTEX_ID`.
fn read_transfer_texture(
    t: &Value,
    doc: &gltf::Document,
    attrs: &Attributes,
    floats: &Floats,
    bad: &dyn Fn(String) -> SceneRelightError,
    (v, channels, n2): (usize, usize, usize),
) -> Result<(Vec<f32>, Option<Vec<f32>>), SceneRelightError> {
    let field = |k: &str| {
        t[k].as_u64()
            .map(|x| x as usize)
            .ok_or_else(|| bad(format!("transfer_texture.{k} is not a number")))
    };
    let (width, height, per_vertex) = (
        field("width")?,
        field("height")?,
        field("texels_per_vertex")?,
    );
    let acc = doc
        .accessors()
        .nth(field("accessor")?)
        .ok_or_else(|| bad("transfer_texture.accessor out of range".into()))?;
    let texels = floats(&acc)?;
    if texels.len() != 4 * width * height {
        return Err(bad(format!(
            "transfer_texture: {} texels for {width} × {height}",
            texels.len() / 4
        )));
    }
    let ids = attrs
        .get("_PRT_VERTEX_ID")
        .ok_or_else(|| bad("no _PRT_VERTEX_ID".into()))
        .and_then(floats)?;
    let channel_texels: Vec<usize> = serde_json::from_value(t["channel_texels"].clone())
        .map_err(|e| bad(format!("transfer_texture.channel_texels: {e}")))?;
    // Coefficients `n2` from texel `first` on, of vertex `id`.
    let read = |id: usize, first: usize| -> Result<&[f32], SceneRelightError> {
        let at = 4 * (id * per_vertex + first);
        texels
            .get(at..at + n2)
            .ok_or_else(|| bad(format!("vertex {id}: beyond the transfer texture")))
    };
    let mut transfer = vec![0.0f32; v * channels * n2];
    let vis_texel = t["visibility_texel"].as_u64().map(|x| x as usize);
    let mut visibility = vis_texel.map(|_| vec![0.0f32; v * n2]);
    for (p, id) in ids.iter().enumerate().take(v) {
        let id = *id as usize;
        for (c, first) in channel_texels.iter().enumerate().take(channels) {
            transfer[(p * channels + c) * n2..][..n2].copy_from_slice(read(id, *first)?);
        }
        if let (Some(first), Some(vis)) = (vis_texel, visibility.as_mut()) {
            vis[p * n2..][..n2].copy_from_slice(read(id, first)?);
        }
    }
    Ok((transfer, visibility))
}

/// Dequantises a primitive's lightmap textures (`extras.prt.lightmap`).
fn read_lightmap(
    l: &Value,
    channels: usize,
    n2: usize,
    images: &[gltf::image::Data],
    attrs: &std::collections::HashMap<String, gltf::Accessor>,
    floats: &dyn Fn(&gltf::Accessor) -> Result<Vec<f32>, SceneRelightError>,
    bad: &dyn Fn(String) -> SceneRelightError,
) -> Result<ExportedLightmap, SceneRelightError> {
    let num = |k: &str| {
        l[k].as_u64()
            .ok_or_else(|| bad(format!("lightmap.{k} is missing")))
    };
    let (w, h) = (num("width")? as u32, num("height")? as u32);
    let table = |k: &str| -> Result<Vec<Vec<f64>>, SceneRelightError> {
        serde_json::from_value(l[k].clone()).map_err(|e| bad(format!("lightmap.{k}: {e}")))
    };
    let (offset, scale) = (table("offset")?, table("scale")?);
    let tex: Vec<Vec<usize>> = serde_json::from_value(l["textures"].clone())
        .map_err(|e| bad(format!("lightmap.textures: {e}")))?;
    if offset.len() != channels
        || scale.len() != channels
        || tex.len() != channels
        || offset.iter().chain(&scale).any(|r| r.len() != n2)
        || tex.iter().any(|t| t.len() != n2.div_ceil(4))
    {
        return Err(bad(
            "lightmap tables do not match the order and channels".into()
        ));
    }
    let texels = (w * h) as usize;
    let mut transfer = vec![0.0f32; texels * channels * n2];
    for ch in 0..channels {
        for (g, &t) in tex[ch].iter().enumerate() {
            // Texture t's image: the export writes texture k with source k.
            let img = images
                .get(t)
                .ok_or_else(|| bad(format!("lightmap texture {t} is missing")))?;
            if (img.width, img.height) != (w, h) || img.format != gltf::image::Format::R8G8B8A8 {
                return Err(bad(format!(
                    "lightmap texture {t}: {}×{} {:?}, expected {w}×{h} RGBA8",
                    img.width, img.height, img.format
                )));
            }
            for p in 0..texels {
                for j in 0..4 {
                    let i = 4 * g + j;
                    if i < n2 {
                        let code = f64::from(img.pixels[4 * p + j]);
                        transfer[(p * channels + ch) * n2 + i] =
                            (offset[ch][i] + scale[ch][i] * code / 255.0) as f32;
                    }
                }
            }
        }
    }
    let uv = attrs
        .get("TEXCOORD_0")
        .ok_or_else(|| bad("a lightmapped primitive without TEXCOORD_0".into()))?;
    let uvs = floats(uv)?.chunks_exact(2).map(|c| [c[0], c[1]]).collect();
    Ok(ExportedLightmap {
        width: w,
        height: h,
        transfer,
        uvs,
        step: scale
            .iter()
            .flatten()
            .map(|s| (*s / 255.0) as f32)
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn u32_at(b: &[u8], at: usize) -> u32 {
        u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
    }

    #[test]
    fn the_container_is_a_glb_with_padded_chunks() {
        let doc = json!({"asset": {"version": "2.0"}});
        let bin = [1u8, 2, 3, 4, 5, 6, 7, 8];
        let glb = glb_container(&doc, &bin).unwrap();
        // Header: magic, version 2, total length.
        assert_eq!(&glb[..4], b"glTF");
        assert_eq!((u32_at(&glb, 4), u32_at(&glb, 8) as usize), (2, glb.len()));
        // The JSON chunk, padded with spaces to 4 bytes, parses back to the document.
        let json_len = u32_at(&glb, 12) as usize;
        assert_eq!((json_len % 4, &glb[16..20]), (0, &b"JSON"[..]));
        let text = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
        assert_eq!(serde_json::from_str::<Value>(text.trim_end()).unwrap(), doc);
        // The binary chunk follows, unchanged.
        let at = 20 + json_len;
        assert_eq!(
            (u32_at(&glb, at) as usize, &glb[at + 4..at + 8]),
            (8, &b"BIN\0"[..])
        );
        assert_eq!(&glb[at + 8..], &bin);
    }

    #[test]
    fn textures_share_samplers_and_the_buffer_keeps_its_views() {
        let mut bin = Bin {
            data: Vec::new(),
            views: Vec::new(),
            accessors: Vec::new(),
        };
        let mut tex = Textures::default();
        let a = tex.add_lightmap(&mut bin, &[0u8; 5]);
        let b = tex.add_lightmap(&mut bin, &[1u8; 7]);
        assert_eq!((a, b), (0, 1));
        // Two lightmap textures, two images, one sampler (bilinear, clamp to edge).
        assert_eq!(
            (tex.textures.len(), tex.images.len(), tex.samplers.len()),
            (2, 2, 1)
        );
        assert_eq!(tex.textures[1]["source"], 1);
        assert_eq!(tex.samplers[0]["wrapS"], CLAMP_TO_EDGE);
        // Each image is its own buffer view over the bytes it was given.
        let view = |i: usize| {
            let v = &bin.views[tex.images[i]["bufferView"].as_u64().unwrap() as usize];
            let (o, n) = (
                v["byteOffset"].as_u64().unwrap() as usize,
                v["byteLength"].as_u64().unwrap() as usize,
            );
            bin.data[o..o + n].to_vec()
        };
        assert_eq!((view(0), view(1)), (vec![0u8; 5], vec![1u8; 7]));
    }

    /// A texture reference with a `KHR_texture_transform` is written with it (the asset's own
    /// material, as it came), and the document then declares the extension.
    #[test]
    fn texture_transforms_are_written_back() {
        let mut bin = Bin {
            data: Vec::new(),
            views: Vec::new(),
            accessors: Vec::new(),
        };
        let mut scene = Scene::new(
            prt_scene::Camera::default(),
            prt_scene::Environment::uniform([1.0; 3]),
        );
        scene.textures = vec![prt_scene::Texture {
            name: "t".into(),
            width: 1,
            height: 1,
            texels: vec![[0.5; 4]],
            wrap: [prt_scene::Wrap::Repeat; 2],
        }];
        let mut mesh = prt_scene::test_util::floor_quad(1.0, 0.0);
        mesh.texcoords = vec![vec![[0.5; 2]; 4]];
        let transform = prt_scene::UvTransform {
            offset: [0.5, 0.25],
            rotation: 0.5,
            scale: [2.0, 3.0],
        };
        let t = prt_scene::TextureRef {
            index: 0,
            texcoord: 0,
            transform: Some(transform),
        };
        let mut tex = Textures::default();
        let mut attrs = serde_json::Map::new();
        let info = tex
            .texture_info(
                &mut bin,
                &mut attrs,
                &scene,
                &mesh,
                Some(t),
                true,
                0,
                Some(4),
                "o",
            )
            .unwrap()
            .unwrap();
        let ext = &info["extensions"]["KHR_texture_transform"];
        assert_eq!(ext["offset"], json!([0.5, 0.25]));
        assert_eq!(ext["rotation"], json!(0.5));
        assert_eq!(ext["scale"], json!([2.0, 3.0]));
        assert!(tex.transforms);
        let plain = prt_scene::TextureRef {
            transform: None,
            ..t
        };
        let info = Textures::default()
            .texture_info(
                &mut bin,
                &mut attrs,
                &scene,
                &mesh,
                Some(plain),
                true,
                0,
                Some(4),
                "o",
            )
            .unwrap()
            .unwrap();
        assert!(info.get("extensions").is_none());
    }
}
