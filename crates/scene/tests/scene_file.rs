//! The TOML scene file: the bundled scenes, and one test per validation rule.

use glam::{DMat3, DVec3, Vec3};
use prt_scene::{load_scene, Material, Scene};
use std::path::{Path, PathBuf};

fn scenes_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes")
}

/// Does every vertex of the scene project inside the image (with no margin)?
fn all_vertices_in_view(scene: &Scene) -> bool {
    let c = &scene.camera;
    let fwd = (c.target - c.eye).normalize();
    let right = fwd.cross(c.up).normalize();
    let up = right.cross(fwd);
    let to_cam = DMat3::from_cols(right, up, fwd).transpose();
    let tan_y = (c.fov_y_deg.to_radians() / 2.0).tan();
    let tan_x = tan_y * f64::from(c.width) / f64::from(c.height);
    scene.meshes.iter().flat_map(|m| &m.positions).all(|p| {
        let q = to_cam * (p.as_dvec3() - c.eye);
        q.z > 0.0 && (q.x / q.z).abs() <= tan_x && (q.y / q.z).abs() <= tan_y
    })
}

#[test]
fn test01_default_scene() {
    let loaded = load_scene(&scenes_dir().join("default.toml")).unwrap();
    let s = &loaded.scene;
    assert_eq!(
        s.material_names,
        vec!["clay", "glazed_floor"],
        "sorted by name"
    );
    assert!(matches!(
        s.materials[1],
        Material::Phong { exponent: 16.0, .. }
    ));
    assert_eq!(s.meshes.len(), 2);
    let bunny = &s.meshes[0];
    assert_eq!(bunny.positions.len(), 1839);
    assert_eq!(bunny.material, 0);
    // Scaled by 0.1: the file's y range [-0.003149, 9.654748] becomes [-0.000315, 0.965475].
    let (lo, hi) = bunny.bounds().unwrap();
    assert!(
        (lo.y + 0.000_315).abs() < 1e-6 && (hi.y - 0.965_475).abs() < 1e-6,
        "{lo} {hi}"
    );
    assert!(
        all_vertices_in_view(&Scene {
            meshes: vec![bunny.clone()],
            ..s.clone()
        }),
        "bunny framed"
    );
    assert_eq!((s.camera.width, s.camera.height), (320, 240));
    assert_eq!((s.render.spp, s.render.bounces, s.render.seed), (64, 1, 0));
    assert_eq!(
        (s.environment.image.width, s.environment.image.height),
        (1024, 512)
    );
    s.validate().unwrap();
    // Only the expected warning: the courtyard map's clamped negatives.
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
}

#[test]
fn test02_other_bundled_scenes() {
    for name in ["glossy.toml", "hard_shadow.toml"] {
        let loaded = load_scene(&scenes_dir().join(name)).unwrap_or_else(|e| panic!("{e}"));
        loaded.scene.validate().unwrap();
        assert!(!loaded.scene.meshes.is_empty());
    }
    let shadow = load_scene(&scenes_dir().join("hard_shadow.toml"))
        .unwrap()
        .scene;
    // The teapot is Z-up in its file; rotated -90° about X it stands on the floor y = 0.
    let (lo, hi) = shadow.meshes[0].bounds().unwrap();
    assert!(
        lo.y.abs() < 0.01 && (hi.y - 0.3 * 3.1176).abs() < 1e-3,
        "{lo} {hi}"
    );
    // The map is turned so that the sun (the brightest texel) shines from about +X.
    let env = &shadow.environment;
    let img = &env.image;
    let i = (0..img.texels.len())
        .max_by(|&a, &b| img.texels[a][1].total_cmp(&img.texels[b][1]))
        .unwrap();
    let (u, v) = ((i % img.width) as f64 + 0.5, (i / img.width) as f64 + 0.5);
    let d = prt_scene::envmap::latlong_direction(
        u / img.width as f64 * std::f64::consts::TAU,
        v / img.height as f64 * std::f64::consts::PI,
    );
    let world = env.to_world(d);
    assert!(world.x > 0.95, "sun at {world}");
    assert!(env.radiance(world.as_vec3())[1] > 1000.0);
}

const GOOD: &str = r#"
[camera]
eye = [0.0, 1.0, 3.0]
target = [0.0, 0.5, 0.0]
fov_y = 40.0
resolution = [16, 12]
[environment]
file = "env.exr"
[materials.stone]
type = "lambert"
albedo = [0.8, 0.8, 0.8]
[[objects]]
mesh = "tri.obj"
material = "stone"
"#;

/// Writes `toml` with a 2×1 map and a triangle beside it and loads it.
fn try_scene(toml: &str) -> Result<prt_scene::LoadedScene, prt_scene::SceneError> {
    let dir = tempfile::tempdir().unwrap();
    exr::prelude::write_rgb_file(dir.path().join("env.exr"), 2, 1, |c, _| {
        (c as f32, 1.0f32, 2.0f32)
    })
    .unwrap();
    std::fs::write(
        dir.path().join("tri.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    )
    .unwrap();
    let p = dir.path().join("my_scene.toml");
    std::fs::write(&p, toml).unwrap();
    load_scene(&p)
}

#[test]
fn test03_minimal_scene_and_transforms() {
    let toml = GOOD.replace(
        "material = \"stone\"",
        "material = \"stone\"\ntranslate = [1, 2, 3]\nrotate = [0, 90, 0]\nscale = [2, 1, 1]",
    ) + "[environment.extra]\n";
    // Unknown sub-table: rejected (deny_unknown_fields).
    let msg = try_scene(&toml).unwrap_err().to_string();
    assert!(
        msg.contains("my_scene.toml") && msg.contains("extra"),
        "{msg}"
    );
    let toml = toml.replace("[environment.extra]\n", "");
    let s = try_scene(&toml).unwrap().scene;
    // v = (1, 0, 0): S·v = (2, 0, 0); Ry(90°) sends +X to -Z: (0, 0, -2); + T = (1, 2, 1).
    assert!(
        (s.meshes[0].positions[1] - Vec3::new(1.0, 2.0, 1.0)).length() < 1e-6,
        "{}",
        s.meshes[0].positions[1]
    );
    assert_eq!(s.camera.up, DVec3::Y);
    assert_eq!(
        s.environment.image.texels,
        vec![[0.0, 1.0, 2.0], [1.0, 1.0, 2.0]]
    );
    assert_eq!((s.render.spp, s.render.bounces), (64, 0), "defaults");
}

/// Each broken variant must fail with a message naming the scene file and the key.
#[test]
fn test04_validation_errors_name_file_and_key() {
    let cases: &[(&str, &str, &str)] = &[
        (
            "type = \"lambert\"",
            "type = \"plastic\"",
            "materials.stone.type",
        ),
        (
            "material = \"stone\"",
            "material = \"marble\"",
            "objects[0].material",
        ),
        (
            "albedo = [0.8, 0.8, 0.8]",
            "albedo = [0.8, 1.2, 0.8]",
            "materials.stone.albedo",
        ),
        (
            "albedo = [0.8, 0.8, 0.8]",
            "albedo = [0.8, nan, 0.8]",
            "materials.stone.albedo",
        ),
        (
            "type = \"lambert\"",
            "type = \"phong\"\nspecular = [0.1, 0.1, 0.1]\nexponent = -1.0",
            "materials.stone.exponent",
        ),
        (
            "type = \"lambert\"",
            "type = \"phong\"\nexponent = 3.0",
            "materials.stone.specular",
        ),
        (
            "type = \"lambert\"",
            "type = \"ward\"\nspecular = [0.1, 0.1, 0.1]\nroughness = 0.0",
            "materials.stone.roughness",
        ),
        (
            "type = \"lambert\"",
            "type = \"cook_torrance\"\nspecular = [0.1, 0.1, 0.1]\nroughness = 0.3\nior = 1.0",
            "materials.stone.ior",
        ),
        (
            "type = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]",
            "type = \"pbr\"\nbase_color = [0.8, 0.8, 0.8]\nmetallic = 0.5\nroughness = 1.5",
            "materials.stone.roughness",
        ),
        (
            "type = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]",
            "type = \"pbr\"\nbase_color = [0.8, 0.8, 0.8]\nmetallic = -0.1\nroughness = 0.5",
            "materials.stone.metallic",
        ),
        (
            "type = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]",
            "type = \"pbr\"\nmetallic = 0.0\nroughness = 0.5",
            "materials.stone.base_color",
        ),
        ("fov_y = 40.0", "fov_y = 180.0", "camera.fov_y"),
        ("fov_y = 40.0", "fov_y = 0.0", "camera.fov_y"),
        (
            "resolution = [16, 12]",
            "resolution = [0, 12]",
            "camera.resolution",
        ),
        (
            "target = [0.0, 0.5, 0.0]",
            "target = [0.0, 1.0, 3.0]",
            "camera.target",
        ),
        (
            "target = [0.0, 0.5, 0.0]",
            "target = [0.0, 0.5, 0.0]\nup = [0.0, -1.0, -6.0]",
            "camera.up",
        ),
        (
            "mesh = \"tri.obj\"",
            "mesh = \"missing.obj\"",
            "objects[0].mesh",
        ),
        (
            "file = \"env.exr\"",
            "file = \"nope.exr\"",
            "environment.file",
        ),
        (
            "file = \"env.exr\"",
            "file = \"env.exr\"\nscale = -2.0",
            "environment.scale",
        ),
        (
            "material = \"stone\"",
            "material = \"stone\"\nscale = 0.0",
            "objects[0].scale",
        ),
        (
            "material = \"stone\"",
            "material = \"stone\"\nscale = \"big\"",
            "objects[0].scale",
        ),
        ("material = \"stone\"", "", "objects[0].material"),
        ("fov_y = 40.0", "fov_y = 40.0\nzoom = 2", "zoom"),
        ("fov_y = 40.0", "", "fov_y"),
        (
            "material = \"stone\"",
            "material = \"stone\"\n[render]\nspp = 0",
            "render.spp",
        ),
        (
            "material = \"stone\"",
            "material = \"stone\"\n[render]\nbounces = -2",
            "render.bounces",
        ),
    ];
    for (from, to, key) in cases {
        assert!(GOOD.contains(from), "{from}");
        let toml = GOOD.replacen(from, to, 1);
        match try_scene(&toml) {
            Ok(_) => panic!("`{to}` was accepted"),
            Err(e) => {
                let msg = e.to_string();
                assert!(
                    msg.contains("my_scene.toml") && msg.contains(key),
                    "`{to}`: {msg}"
                );
            }
        }
    }
}

#[test]
fn test05_warnings_for_ignored_keys_and_energy() {
    let toml = GOOD.replace(
        "albedo = [0.8, 0.8, 0.8]",
        "albedo = [0.8, 0.8, 0.8]\nexponent = 3.0\n[materials.hot]\ntype = \"mirror\"\nalbedo = [0.5, 0.5, 0.5]\nspecular = [0.6, 0.1, 0.1]",
    );
    let w = try_scene(&toml).unwrap().warnings;
    assert!(
        w.iter()
            .any(|w| w.contains("materials.stone.exponent") && w.contains("ignored")),
        "{w:?}"
    );
    assert!(
        w.iter()
            .any(|w| w.contains("materials.hot") && w.contains("exceeds 1")),
        "{w:?}"
    );
}

#[test]
fn test06_gltf_objects_bring_their_materials() {
    let Some(box_dir) = [
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets/gltf/BoxTextured-glTF"),
        PathBuf::from("/work/shared/assets/gltf/BoxTextured-glTF"),
    ]
    .into_iter()
    .find(|p| p.is_dir()) else {
        eprintln!("SKIPPED: no shared/assets folder");
        return;
    };
    let gltf = box_dir.join("BoxTextured.gltf").display().to_string();
    let toml = GOOD.replace(
        "mesh = \"tri.obj\"\nmaterial = \"stone\"",
        &format!("mesh = {gltf:?}"),
    );
    let toml = toml + &format!("[[objects]]\nmesh = {gltf:?}\ntranslate = [3, 0, 0]\n");
    let loaded = try_scene(&toml).unwrap();
    let s = &loaded.scene;
    // Both instances share one imported material (its own `pbr`, textured) and one texture.
    assert_eq!(s.material_names, vec!["stone", "BoxTextured.gltf#Texture"]);
    assert_eq!(s.meshes.len(), 2);
    assert!(s.meshes.iter().all(|m| m.material == 1));
    assert_eq!(s.textures.len(), 1);
    assert!(matches!(
        s.materials[1],
        Material::Pbr {
            base_color_texture: Some(_),
            ..
        }
    ));
    // The texture's top-left texel is light grey (220/255 sRGB); the surface point of
    // vertex 0 reads the texture at that vertex's UV.
    let m = s.material_at(1, prt_scene::SurfacePoint::Vertex(0));
    let uv = s.meshes[1]
        .texcoord(0, prt_scene::SurfacePoint::Vertex(0))
        .unwrap();
    let expect = s.textures[0].sample(uv);
    assert!(
        matches!(m, Material::Pbr { base_color, base_color_texture: None, .. }
        if (0..3).all(|k| (base_color[k] - expect[k]).abs() < 1e-7))
    );

    // A missing texture file is named with the material.
    let dir = tempfile::tempdir().unwrap();
    for f in ["BoxTextured.gltf", "BoxTextured0.bin"] {
        std::fs::copy(box_dir.join(f), dir.path().join(f)).unwrap();
    }
    let copy = dir.path().join("BoxTextured.gltf").display().to_string();
    let toml = GOOD.replace(
        "mesh = \"tri.obj\"\nmaterial = \"stone\"",
        &format!("mesh = {copy:?}"),
    );
    let err = try_scene(&toml).unwrap_err().to_string();
    assert!(
        err.contains("BoxTextured.gltf")
            && err.contains("CesiumLogoFlat.png")
            && err.contains("Texture"),
        "{err}"
    );
    // A texture that is not an image.
    std::fs::write(dir.path().join("CesiumLogoFlat.png"), b"not a png").unwrap();
    let err = try_scene(&toml).unwrap_err().to_string();
    assert!(
        err.contains("CesiumLogoFlat.png") && err.contains("decode"),
        "{err}"
    );
}

#[test]
fn test07_camera_overflow_and_huge_resolution_are_refused() {
    use prt_scene::Camera;
    // A 4294967295² image used to make `prt render` run for ever.
    let huge = Camera::look_at(DVec3::Z, DVec3::ZERO, 40.0, u32::MAX, u32::MAX);
    let (key, msg) = huge.check().unwrap_err();
    assert_eq!(key, "resolution", "{msg}");
    let wide = Camera::look_at(DVec3::Z, DVec3::ZERO, 40.0, 1 << 17, 1);
    assert_eq!(wide.check().unwrap_err().0, "resolution");
    assert!(Camera::look_at(DVec3::Z, DVec3::ZERO, 40.0, 16384, 16384)
        .check()
        .is_ok());
    // Finite eye and target whose difference overflows to infinity.
    let far = Camera::look_at(DVec3::X * 1e308, DVec3::X * -1e308, 40.0, 8, 6);
    let (key, msg) = far.check().unwrap_err();
    assert_eq!(key, "target", "{msg}");
    assert!(msg.contains("overflows"), "{msg}");
}
