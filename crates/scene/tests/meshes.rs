//! OBJ and glTF loading: every real asset, and small synthetic files with known answers.

use glam::{DMat4, DVec3, Vec3};
use prt_scene::{
    load_mesh, map_material, object_transform, LoadedMeshes, Material, SceneError, TextureRef, Wrap,
};
use std::path::Path;

/// The shared asset folder: `shared/assets` beside the checkout (as in CI), else
/// `/work/shared/assets`; `None` (tests that need it print SKIPPED) when neither exists.
fn assets() -> Option<std::path::PathBuf> {
    let beside = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets");
    [beside, "/work/shared/assets".into()]
        .into_iter()
        .find(|p| p.join("README.md").is_file())
}

fn scenes_dir() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn load_text(name: &str, text: &str, to_world: &DMat4) -> Result<LoadedMeshes, SceneError> {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), name, text.as_bytes());
    load_mesh(&p, to_world)
}

/// Every normal is unit (within f32 rounding of a renormalised f64 vector, 1e-5 is ample).
fn assert_unit_normals(m: &prt_scene::Mesh) {
    assert_eq!(m.normals.len(), m.positions.len());
    for n in &m.normals {
        assert!((n.length() - 1.0).abs() < 1e-5, "{}: normal {n}", m.name);
    }
}

#[test]
fn test01_every_real_asset_loads_quickly() {
    let Some(assets) = assets() else {
        eprintln!("SKIPPED: no shared/assets folder");
        return;
    };
    let start = std::time::Instant::now();
    let mut found = 0;
    for dir in ["meshes", "gltf", "gltf/BoxTextured-glTF"] {
        let Ok(entries) = std::fs::read_dir(assets.join(dir)) else {
            continue;
        };
        for e in entries {
            let p = e.unwrap().path();
            let ext = p
                .extension()
                .map(|e| e.to_string_lossy().to_string())
                .unwrap_or_default();
            if !["obj", "gltf", "glb"].contains(&ext.as_str()) {
                continue;
            }
            let loaded = load_mesh(&p, &DMat4::IDENTITY).unwrap_or_else(|e| panic!("{e}"));
            assert!(!loaded.meshes.is_empty());
            for m in &loaded.meshes {
                assert_unit_normals(m);
                assert!(m
                    .indices
                    .iter()
                    .flatten()
                    .all(|&i| (i as usize) < m.positions.len()));
            }
            found += 1;
        }
    }
    assert_eq!(found, 6, "4 OBJ, 1 GLB, 1 glTF");
    // Measured about 0.25 s for all of them (the 37,706-vertex bunny dominates): 5 s leaves
    // room for a loaded machine while still catching an accidental quadratic step.
    assert!(start.elapsed().as_secs_f64() < 5.0, "{:?}", start.elapsed());
}

#[test]
fn test02_real_asset_counts() {
    let bunny = load_mesh(
        &scenes_dir().join("meshes/bunny_lowres.obj"),
        &DMat4::IDENTITY,
    )
    .unwrap();
    assert_eq!(bunny.meshes.len(), 1);
    assert_eq!(bunny.meshes[0].positions.len(), 1839);
    assert!(bunny.materials.is_empty());

    let Some(assets) = assets() else {
        eprintln!("SKIPPED: no shared/assets folder");
        return;
    };
    let engine = load_mesh(&assets.join("gltf/2CylinderEngine.glb"), &DMat4::IDENTITY).unwrap();
    // 29 meshes instanced by the nodes: more primitives in the world than meshes in the file.
    assert!(engine.meshes.len() > 29, "{}", engine.meshes.len());
    // All materials are metallicFactor 0 with default roughness 1 and no textures: the file's
    // own metallic-roughness material with those factors.
    assert!(engine.materials.iter().all(|(_, m)| matches!(
        m,
        Material::Pbr {
            metallic: 0.0,
            roughness: 1.0,
            base_color_texture: None,
            metallic_roughness_texture: None,
            ..
        }
    )));
    assert!(engine.textures.is_empty());
    assert!(engine
        .materials
        .iter()
        .any(|(n, m)| n == "2CylinderEngine.glb#Material_18"
            && matches!(m, Material::Pbr { base_color, .. } if *base_color == [0.85, 0.0, 0.0])));

    let box_path = assets.join("gltf/BoxTextured-glTF/BoxTextured.gltf");
    let boxed = load_mesh(&box_path, &DMat4::IDENTITY).unwrap();
    assert_eq!(boxed.meshes.len(), 1);
    assert_eq!(
        (
            boxed.meshes[0].positions.len(),
            boxed.meshes[0].indices.len()
        ),
        (24, 12)
    );
    // Its material's base colour texture: the 211×211 palette PNG, sRGB-decoded, with the
    // file's sampler (wrapS MIRRORED_REPEAT, wrapT CLAMP_TO_EDGE) and UV set 0.
    assert_eq!(boxed.textures.len(), 1);
    let t = &boxed.textures[0];
    assert_eq!((t.width, t.height), (211, 211));
    assert_eq!(t.wrap, [Wrap::MirroredRepeat, Wrap::ClampToEdge]);
    assert!(matches!(
        boxed.materials[0].1,
        Material::Pbr {
            metallic: 0.0,
            roughness: 1.0,
            base_color_texture: Some(TextureRef {
                index: 0,
                texcoord: 0,
                transform: None
            }),
            metallic_roughness_texture: None,
            ..
        }
    ));
    assert_eq!(boxed.meshes[0].texcoords.len(), 1);
    assert_eq!(boxed.meshes[0].texcoords[0].len(), 24);
    // Texels read by PIL (tools/.venv): (0,0) = (220,220,220), (100,50) = (108,173,223),
    // (150,180) = (92,135,39), 8-bit sRGB; decoded with the IEC 61966-2-1 curve.
    let srgb = |v: f32| {
        let v = v / 255.0;
        if v <= 0.04045 {
            v / 12.92
        } else {
            ((v + 0.055) / 1.055).powf(2.4)
        }
    };
    for ((x, y), rgb) in [
        ((0, 0), [220.0, 220.0, 220.0]),
        ((100, 50), [108.0, 173.0, 223.0]),
        ((150, 180), [92.0, 135.0, 39.0]),
    ] {
        let got = t.texels[y * 211 + x];
        for k in 0..3 {
            assert!(
                (got[k] - srgb(rgb[k])).abs() < 1e-6,
                "texel ({x},{y}): {got:?}"
            );
        }
        assert_eq!(got[3], 1.0);
    }
    // The root node turns the file's Z-up box to Y-up; it stays a unit cube about the origin.
    let (lo, hi) = boxed.meshes[0].bounds().unwrap();
    assert!(
        (lo + Vec3::splat(0.5)).abs().max_element() < 1e-6
            && (hi - Vec3::splat(0.5)).abs().max_element() < 1e-6
    );
    // A closed box has its face normals pointing away from the centre.
    let m = &boxed.meshes[0];
    for t in 0..m.indices.len() {
        let c = m.indices[t]
            .iter()
            .map(|&i| m.positions[i as usize])
            .sum::<Vec3>()
            / 3.0;
        assert!(m.face_normal(t).dot(c) > 0.0, "triangle {t} faces inward");
    }
}

const TWO_TRIANGLES: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n";

#[test]
fn test03_obj_transform_and_normals() {
    // v' = T + Rz·Ry·Rx·(S·v) with S = (2, 3, 4), Rx = 90°, T = (1, 2, 3):
    // v = (0, 1, 0) → S·v = (0, 3, 0) → Rx(90°) sends +Y to +Z: (0, 0, 3) → (1, 2, 6).
    let m = object_transform(
        DVec3::new(1.0, 2.0, 3.0),
        DVec3::new(90.0, 0.0, 0.0),
        DVec3::new(2.0, 3.0, 4.0),
    );
    let loaded = load_text("t.obj", TWO_TRIANGLES, &m).unwrap();
    let mesh = &loaded.meshes[0];
    assert!(
        (mesh.positions[2] - Vec3::new(1.0, 2.0, 6.0)).length() < 1e-6,
        "{}",
        mesh.positions[2]
    );
    // The plane z = 0 (normal +Z) becomes y = 2 with normal Rx(90°)·(+Z) = -Y.
    for n in &mesh.normals {
        assert!((*n - Vec3::NEG_Y).length() < 1e-6, "{n}");
    }
    assert!((mesh.face_normal(0) - Vec3::NEG_Y).length() < 1e-6);
}

#[test]
fn test04_file_normals_use_the_inverse_transpose() {
    // A plane x + y = 1 written with its normal (1, 1, 0)/√2, scaled by (2, 1, 1): the plane
    // becomes x/2 + y = 1, normal ∝ (1/2, 1, 0) — the inverse transpose, not S·n ∝ (2, 1, 0).
    let text = "v 1 0 0\nv 0 1 0\nv 1 0 1\nvn 1 1 0\nf 1//1 2//1 3//1\n";
    let m = object_transform(DVec3::ZERO, DVec3::ZERO, DVec3::new(2.0, 1.0, 1.0));
    let mesh = &load_text("p.obj", text, &m).unwrap().meshes[0];
    let want = Vec3::new(0.5, 1.0, 0.0).normalize();
    for n in &mesh.normals {
        assert!((*n - want).length() < 1e-6, "{n} vs {want}");
    }
    // The file normal agrees with the winding (face normal of 1,2,3 is +(1,1,0)): so must the result.
    assert!(mesh.face_normal(0).dot(want) > 0.999);
}

#[test]
fn test05_mirror_transform_reverses_winding() {
    let m = object_transform(DVec3::ZERO, DVec3::ZERO, DVec3::new(1.0, 1.0, -1.0));
    let text = "v 0 0 1\nv 1 0 1\nv 0 1 1\nvn 0 0 1\nf 1//1 2//1 3//1\n";
    let mesh = &load_text("m.obj", text, &m).unwrap().meshes[0];
    // z → -z: the plane's normal becomes -Z; the winding is reversed so the face agrees.
    assert!((mesh.normals[0] - Vec3::NEG_Z).length() < 1e-6);
    assert!((mesh.face_normal(0) - Vec3::NEG_Z).length() < 1e-6);
}

#[test]
fn test06_angle_weighted_normals() {
    // The corner of a cube at the origin: faces x = 0, y = 0, z = 0 (outward -X, -Y, -Z). The
    // z = 0 face is split into two triangles at the corner (angles 45° + 45°), the others are
    // single right triangles (90°). Angle weighting gives (-1, -1, -1)/√3; a plain sum of
    // face normals would weight -Z twice.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nv 1 1 0\n\
                f 1 3 2\nf 1 4 3\nf 1 2 4\n";
    let base = load_text("c.obj", text, &DMat4::IDENTITY).unwrap();
    let want = Vec3::splat(-1.0).normalize();
    assert!(
        (base.meshes[0].normals[0] - want).length() < 1e-6,
        "{}",
        base.meshes[0].normals[0]
    );
    let split = text.replace("f 1 3 2\n", "f 1 5 2\nf 1 3 5\n");
    let split = load_text("c.obj", &split, &DMat4::IDENTITY).unwrap();
    assert!(
        (split.meshes[0].normals[0] - want).length() < 1e-6,
        "{}",
        split.meshes[0].normals[0]
    );
}

#[test]
fn test07_degenerate_triangles_dropped_and_counted() {
    // Triangle 2 repeats an index, triangle 3 is three collinear points.
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nf 1 2 3\nf 1 1 3\nf 1 2 4\n";
    let loaded = load_text("d.obj", text, &DMat4::IDENTITY).unwrap();
    assert_eq!(loaded.meshes[0].indices, vec![[0, 1, 2]]);
    assert_eq!(loaded.warnings.len(), 1);
    assert!(
        loaded.warnings[0].contains("dropped 2 of 3"),
        "{:?}",
        loaded.warnings
    );
    let all_bad = "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n";
    let msg = load_text("z.obj", all_bad, &DMat4::IDENTITY)
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("z.obj") && msg.contains("no triangles left"),
        "{msg}"
    );
}

#[test]
fn test08_bad_obj_files() {
    let cases = [
        (
            "nan.obj",
            "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
            "non-finite",
        ),
        (
            "range.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 7\n",
            "range.obj",
        ),
        ("empty.obj", "", "no faces"),
        ("words.obj", "this is not\nan obj file\n", "words.obj"),
    ];
    for (name, text, needle) in cases {
        let msg = load_text(name, text, &DMat4::IDENTITY)
            .unwrap_err()
            .to_string();
        assert!(msg.contains(name) && msg.contains(needle), "{name}: {msg}");
    }
    let unknown = load_text("mesh.ply", "ply", &DMat4::IDENTITY)
        .unwrap_err()
        .to_string();
    assert!(unknown.contains("mesh.ply") && unknown.contains("unknown mesh extension"));
}

#[test]
fn test09_zero_file_normals_replaced_with_warning() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nvn 0 0 0\nf 1//1 2//2 3//1\n";
    let loaded = load_text("n.obj", text, &DMat4::IDENTITY).unwrap();
    let mesh = &loaded.meshes[0];
    assert!(mesh.normals.iter().all(|n| (*n - Vec3::Z).length() < 1e-6));
    assert!(
        loaded
            .warnings
            .iter()
            .any(|w| w.contains("replaced 1 zero")),
        "{:?}",
        loaded.warnings
    );
}

/// A GLB holding `json` and a binary chunk `bin` (padded to 4 bytes).
fn glb(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut j = json.as_bytes().to_vec();
    j.resize(j.len().div_ceil(4) * 4, b' ');
    let mut b = bin.to_vec();
    b.resize(b.len().div_ceil(4) * 4, 0);
    let total = 12 + 8 + j.len() + 8 + b.len();
    let mut out = Vec::new();
    out.extend(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((j.len() as u32).to_le_bytes());
    out.extend(b"JSON");
    out.extend(j);
    out.extend((b.len() as u32).to_le_bytes());
    out.extend(b"BIN\0");
    out.extend(b);
    out
}

/// Positions as f32 LE bytes followed by u16 indices; returns (bin, byte length of positions).
fn bin_of(positions: &[[f32; 3]], indices: &[u16]) -> (Vec<u8>, usize) {
    let mut b: Vec<u8> = positions
        .iter()
        .flatten()
        .flat_map(|f| f.to_le_bytes())
        .collect();
    let plen = b.len();
    b.extend(indices.iter().flat_map(|i| i.to_le_bytes()));
    (b, plen)
}

/// A one-primitive glTF with `mode`, optional extra JSON for the root, node and accessor 0.
fn gltf_json(
    p: &[[f32; 3]],
    idx: &[u16],
    mode: u32,
    root_extra: &str,
    node_extra: &str,
    acc_extra: &str,
) -> Vec<u8> {
    gltf_json_with_material(p, idx, mode, root_extra, node_extra, acc_extra, "")
}

/// [`gltf_json`] with extra JSON in its material (`"shiny"`).
fn gltf_json_with_material(
    p: &[[f32; 3]],
    idx: &[u16],
    mode: u32,
    root_extra: &str,
    node_extra: &str,
    acc_extra: &str,
    material_extra: &str,
) -> Vec<u8> {
    let (bin, plen) = bin_of(p, idx);
    // Extra material JSON with its own pbrMetallicRoughness replaces the default one.
    let default_pbr = if material_extra.contains("pbrMetallicRoughness") {
        String::new()
    } else {
        r#","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.25,1.0,1.0],"metallicFactor":1.0,"roughnessFactor":0.5}"#.to_owned()
    };
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},{root_extra}"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"mesh":0{node_extra}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0}},"indices":1,"mode":{mode},"material":0}}]}}],
        "materials":[{{"name":"shiny"{material_extra}{default_pbr}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{},"type":"VEC3","min":[-9,-9,-9],"max":[9,9,9]{acc_extra}}},
                     {{"bufferView":1,"componentType":5123,"count":{},"type":"SCALAR"}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{plen}}},{{"buffer":0,"byteOffset":{plen},"byteLength":{}}}],
        "buffers":[{{"byteLength":{}}}]}}"#,
        p.len(),
        idx.len(),
        idx.len() * 2,
        bin.len()
    );
    glb(&json, &bin)
}

const SQUARE: [[f32; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [0.0, 1.0, 0.0],
    [1.0, 1.0, 0.0],
];

fn load_glb(bytes: &[u8]) -> Result<LoadedMeshes, SceneError> {
    let dir = tempfile::tempdir().unwrap();
    let p = write(dir.path(), "t.glb", bytes);
    load_mesh(&p, &DMat4::IDENTITY)
}

#[test]
fn test10_gltf_strips_and_fans_keep_winding() {
    // Strip 0,1,2,3 → (0,1,2), (2,1,3); fan 0,1,3,2 → (0,1,3), (0,3,2): all facing +Z.
    for (mode, idx) in [
        (5u32, vec![0u16, 1, 2, 3]),
        (6, vec![0, 1, 3, 2]),
        (4, vec![0, 1, 2, 2, 1, 3]),
    ] {
        let loaded = load_glb(&gltf_json(&SQUARE, &idx, mode, "", "", "")).unwrap();
        let m = &loaded.meshes[0];
        assert_eq!(m.indices.len(), 2, "mode {mode}");
        for t in 0..2 {
            assert!(
                (m.face_normal(t) - Vec3::Z).length() < 1e-6,
                "mode {mode} triangle {t}"
            );
        }
        assert!((m.surface_area() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn test11_gltf_node_transform_and_material() {
    // Node translation (0, 0, 5) and scale 2: vertex (1, 1, 0) → (2, 2, 5).
    let node = r#","translation":[0,0,5],"scale":[2,2,2]"#;
    let loaded = load_glb(&gltf_json(&SQUARE, &[0, 1, 2, 2, 1, 3], 4, "", node, "")).unwrap();
    let m = &loaded.meshes[0];
    assert!((m.positions[3] - Vec3::new(2.0, 2.0, 5.0)).length() < 1e-6);
    assert_eq!(loaded.materials.len(), 1);
    assert_eq!(loaded.materials[0].0, "t.glb#shiny");
    assert_eq!(
        loaded.materials[0].1,
        Material::Pbr {
            base_color: [0.5, 0.25, 1.0],
            metallic: 1.0,
            roughness: 0.5,
            base_color_texture: None,
            metallic_roughness_texture: None,
        }
    );
}

#[test]
fn test12_gltf_material_rule() {
    assert_eq!(
        map_material([0.2, 0.4, 0.6], 0.0, 1.0),
        Material::Lambert {
            albedo: [0.2, 0.4, 0.6]
        }
    );
    assert_eq!(
        map_material([0.2, 0.4, 0.6], 0.49, 0.8),
        Material::Lambert {
            albedo: [0.2, 0.4, 0.6]
        }
    );
    // metallic 1, roughness 0.5: albedo 0, specular = base colour, m = 0.25, ior = 20.
    assert_eq!(
        map_material([0.5, 0.25, 1.0], 1.0, 0.5),
        Material::CookTorrance {
            albedo: [0.0; 3],
            specular: [0.5, 0.25, 1.0],
            roughness: 0.25,
            ior: 20.0
        }
    );
    // A smooth dielectric: full albedo, white specular, roughness floored at 0.01, ior 1.5.
    assert_eq!(
        map_material([0.2, 0.4, 0.6], 0.0, 0.0),
        Material::CookTorrance {
            albedo: [0.2, 0.4, 0.6],
            specular: [1.0; 3],
            roughness: 0.01,
            ior: 1.5
        }
    );
    for m in [0.0, 0.3, 0.7, 1.0] {
        for r in [0.0, 0.2, 0.79, 0.8, 1.0] {
            assert!(map_material([0.9, 0.5, 0.1], m, r).check().is_ok());
        }
    }
}

#[test]
fn test13_gltf_errors_and_skips() {
    let draco = r#""extensionsUsed":["KHR_draco_mesh_compression"],"extensionsRequired":["KHR_draco_mesh_compression"],"#;
    let msg = load_glb(&gltf_json(&SQUARE, &[0, 1, 2], 4, draco, "", ""))
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("t.glb") && msg.contains("KHR_draco_mesh_compression"),
        "{msg}"
    );

    let sparse = r#","sparse":{"count":1,"indices":{"bufferView":1,"componentType":5123},"values":{"bufferView":0}}"#;
    let msg = load_glb(&gltf_json(&SQUARE, &[0, 1, 2], 4, "", "", sparse))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("t.glb") && msg.contains("sparse"), "{msg}");

    let msg = load_glb(&gltf_json(&SQUARE, &[0, 1, 9], 4, "", "", ""))
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("t.glb") && msg.contains("vertex index 9"),
        "{msg}"
    );

    let nan = [[0.0, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let msg = load_glb(&gltf_json(&nan, &[0, 1, 2], 4, "", "", ""))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("t.glb") && msg.contains("non-finite"), "{msg}");

    // Points are skipped with a warning; with nothing else, the file has no triangles.
    let msg = load_glb(&gltf_json(&SQUARE, &[0, 1, 2], 0, "", "", ""))
        .unwrap_err()
        .to_string();
    assert!(msg.contains("no triangle primitive"), "{msg}");

    // An accessor that claims more elements than its buffer view holds.
    let mut bytes = gltf_json(&SQUARE, &[0, 1, 2], 4, "", "", "");
    let text = String::from_utf8_lossy(&bytes).replace(r#""count":4"#, r#""count":40"#);
    bytes = text.into_bytes();
    let msg = load_glb(&bytes).unwrap_err().to_string();
    assert!(msg.contains("t.glb"), "{msg}");

    for garbage in [&b""[..], b"glTF", b"{not json"] {
        let msg = load_glb(garbage).unwrap_err().to_string();
        assert!(msg.contains("t.glb"), "{msg}");
    }
}

#[test]
fn test14_geometry_hash_is_fnv1a_of_the_documented_bytes() {
    let mesh = prt_scene::Mesh {
        positions: vec![Vec3::ZERO, Vec3::X, Vec3::Y],
        normals: vec![Vec3::Z; 3],
        indices: vec![[0, 1, 2]],
        ..Default::default()
    };
    // Computed independently (Python) over u64 3, u64 1, nine f32 and three u32, all LE; the
    // same script gives the published FNV-1a 64 test vector fnv("a") = 0xaf63dc4c8601ec8c.
    assert_eq!(mesh.geometry_hash(), 0xa37e_0ccc_ee0a_7884);
    let mut moved = mesh.clone();
    moved.positions[2].y = 1.0 + f32::EPSILON;
    assert_ne!(moved.geometry_hash(), mesh.geometry_hash());
    let mut renamed = mesh.clone();
    renamed.name = "other".into();
    renamed.normals = vec![Vec3::NEG_Z; 3];
    assert_eq!(
        renamed.geometry_hash(),
        mesh.geometry_hash(),
        "names and normals are not hashed"
    );
}

#[test]
fn test15_gltf_missing_buffer_file_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = write(
        dir.path(),
        "t.gltf",
        br#"{"asset": {"version": "2.0"}, "buffers": [{"uri": "gone.bin", "byteLength": 12}]}"#,
    );
    let msg = load_mesh(&gltf, &DMat4::IDENTITY).unwrap_err().to_string();
    assert!(
        msg.contains("t.gltf") && msg.contains("`gone.bin`"),
        "{msg}"
    );
}

/// Issue 34: a glTF material's inputs. The normal map, emission (factor, texture,
/// `KHR_materials_emissive_strength`) and `alphaMode MASK` are read into the material's
/// [`prt_scene::SurfaceInputs`] without a warning; what nothing models — the occlusion map,
/// `alphaMode BLEND` (treated as opaque), an extension the loader does not read — gets a
/// warning naming the file, the material (or extension) and the feature; a plain material
/// gets none.
#[test]
fn test16_gltf_material_inputs_read_or_warned() {
    // A 2 × 1 RGBA PNG (red, green), embedded.
    let png = "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAIAAAABCAYAAAD0In+KAAAADklEQVR4nGP4z8DwHwQBEPgD/U6VwW8AAAAASUVORK5CYII=";
    let textures = format!(
        r#""extensionsUsed":["KHR_materials_emissive_strength","KHR_materials_clearcoat"],"textures":[{{"source":0}}],"images":[{{"uri":"{png}"}}],"#
    );
    let extra = r#","normalTexture":{"index":0,"scale":0.5},"occlusionTexture":{"index":0},"emissiveFactor":[1.0,0.5,0.0],"emissiveTexture":{"index":0},"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":4.0}},"alphaMode":"MASK","alphaCutoff":0.3"#;
    let err = load_glb(&gltf_json_with_material(
        &SQUARE,
        &[0, 1, 2],
        4,
        &textures,
        "",
        "",
        extra,
    ))
    .unwrap_err()
    .to_string();
    // The square has no UVs: the texture's set is named.
    assert!(err.contains("TEXCOORD_0"), "{err}");
    let loaded = load_glb(&gltf_json_with_material(
        &SQUARE,
        &[0, 1, 2],
        4,
        &textures,
        "",
        "",
        &extra
            .replace(r#""emissiveTexture":{"index":0},"#, "")
            .replace(r#""normalTexture":{"index":0,"scale":0.5},"#, ""),
    ))
    .unwrap();
    let w = loaded.warnings.join("\n");
    for needle in ["occlusionTexture is ignored", "KHR_materials_clearcoat"] {
        assert!(w.contains(needle), "no warning about {needle}:\n{w}");
    }
    for modelled in ["emissi", "alphaMode", "normalTexture"] {
        assert!(!w.contains(modelled), "{modelled} is modelled:\n{w}");
    }
    assert!(loaded.warnings.iter().all(|l| l.contains("t.glb")), "{w}");
    assert!(
        loaded
            .warnings
            .iter()
            .any(|l| l.contains("`shiny`") && l.contains("occlusionTexture")),
        "{w}"
    );
    let inputs = loaded.surface_inputs[0];
    assert_eq!(inputs.emissive, [4.0, 2.0, 0.0]);
    assert_eq!(
        inputs.alpha,
        prt_scene::AlphaMode::Mask {
            cutoff: 0.3,
            factor: 1.0,
            texture: None
        }
    );
    let blend = load_glb(&gltf_json_with_material(
        &SQUARE,
        &[0, 1, 2],
        4,
        "",
        "",
        "",
        r#","alphaMode":"BLEND""#,
    ))
    .unwrap();
    assert!(blend
        .warnings
        .iter()
        .any(|l| l.contains("alphaMode BLEND is treated as OPAQUE")));
    let plain = load_glb(&gltf_json(&SQUARE, &[0, 1, 2], 4, "", "", "")).unwrap();
    assert!(plain.warnings.is_empty(), "{:?}", plain.warnings);
}

/// `KHR_texture_transform` on a base-colour texture is honoured, not warned about: its
/// `texCoord` overrides the texture info's (the primitive here has no UVs, so the loader's
/// refusal names the set it reads: TEXCOORD_0 of the extension, not TEXCOORD_1 of the info).
/// (The transform of the UVs is tested where the lookup applies it: `texture.rs`.)
#[test]
fn test17_gltf_texture_transform_is_honoured() {
    // A 2 × 1 RGBA PNG (red, green), embedded.
    let png = "data:image/png;base64,iVBORw0KGgoAAAANSUhEUgAAAAIAAAABCAYAAAD0In+KAAAADklEQVR4nGP4z8DwHwQBEPgD/U6VwW8AAAAASUVORK5CYII=";
    let root = format!(
        r#""extensionsUsed":["KHR_texture_transform"],"textures":[{{"source":0}}],"images":[{{"uri":"{png}"}}],"#
    );
    let material = r#","pbrMetallicRoughness":{"baseColorTexture":{"index":0,"texCoord":1,"extensions":{"KHR_texture_transform":{"offset":[0.5,0.25],"rotation":0.5,"scale":[2.0,3.0],"texCoord":0}}}}"#;
    let bytes = gltf_json_with_material(&SQUARE, &[0, 1, 2], 4, &root, "", "", material);
    let err = load_glb(&bytes).unwrap_err().to_string();
    assert!(
        err.contains("TEXCOORD_0") && !err.contains("TEXCOORD_1"),
        "{err}"
    );
}
