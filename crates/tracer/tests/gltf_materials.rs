//! glTF material inputs in the path tracer (issue 34): emission, normal maps and alpha MASK,
//! each on a generated glTF quad read by the real loader, against closed forms; and the
//! DamagedHelmet scene, whose image changes when its normal map and emission are switched off.

use glam::{DMat4, DVec3, Vec3};
use prt_scene::test_util::{gltf_texture_root, write_gltf_quad};
use prt_scene::{load_gltf, Environment, Material, Scene};
use prt_tracer::{test_util, Accel, RenderSettings, Renderer};
use std::path::Path;

/// The scene of one glTF file (its materials, their inputs and the tangents), seen by a
/// 16×16 camera on +Z.
fn scene_of(path: &Path, env: Environment) -> Scene {
    let cam = test_util::camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 28.0, 16, 16);
    prt_scene::test_util::gltf_scene(path, cam, env)
}

fn render(scene: &Scene, spp: u32) -> Vec<Vec3> {
    let settings = RenderSettings {
        spp,
        bounces: 0,
        progress: false,
        ..RenderSettings::default()
    };
    Renderer::new(scene, settings)
        .unwrap()
        .render()
        .unwrap()
        .radiance
}

/// The inverse of the sRGB curve (IEC 61966-2-1), for the expected emission.
fn srgb_to_linear(c: u8) -> f32 {
    let v = f32::from(c) / 255.0;
    if v <= 0.04045 {
        v / 12.92
    } else {
        ((v + 0.055) / 1.055).powf(2.4)
    }
}

/// Emission under a black environment: a pixel of an emissive texel shows exactly
/// `emissiveFactor × emissiveStrength × texel` (linear; the texel sRGB-decoded), one of a
/// black texel shows 0. The 4×4 texture's top-left 2×2 quadrant is emissive: at a
/// quadrant's middle all four bilinear neighbours are that quadrant's, and a pixel there
/// (1/14 of the quad wide) stays inside the constant region (the middle ± 1/8 of the quad).
/// Nothing else lights the quad, so the only error is f32 rounding.
#[test]
fn emissive_texels_emit_their_closed_form_radiance() {
    let dir = tempfile::tempdir().unwrap();
    let texel = [255u8, 128, 64];
    let img = image::RgbaImage::from_fn(4, 4, |x, y| {
        if x < 2 && y < 2 {
            image::Rgba([texel[0], texel[1], texel[2], 255])
        } else {
            image::Rgba([0, 0, 0, 255])
        }
    });
    img.save(dir.path().join("e.png")).unwrap();
    let material = r#","pbrMetallicRoughness":{"baseColorFactor":[0.5,0.5,0.5,1],"metallicFactor":0,"roughnessFactor":1},"emissiveFactor":[1.0,0.8,0.5],"emissiveTexture":{"index":0},"extensions":{"KHR_materials_emissive_strength":{"emissiveStrength":3.0}}"#;
    let root = gltf_texture_root(
        &["e.png"],
        r#""extensionsUsed":["KHR_materials_emissive_strength"],"#,
    );
    let path = write_gltf_quad(dir.path(), material, &root, None);
    let loaded = load_gltf(&path, &DMat4::IDENTITY).unwrap();
    assert!(loaded.warnings.is_empty(), "{:?}", loaded.warnings);
    let scene = scene_of(&path, Environment::uniform([0.0; 3]));
    let image = render(&scene, 8);
    let expect = [1.0f32, 0.8, 0.5]
        .iter()
        .zip(texel)
        .map(|(f, c)| f * 3.0 * srgb_to_linear(c))
        .collect::<Vec<f32>>();
    let lit = image[4 * 16 + 4];
    for k in 0..3 {
        assert!(
            (lit[k] - expect[k]).abs() <= 1e-5 * expect[k],
            "channel {k}: {lit} vs {expect:?}"
        );
    }
    for (x, y) in [(11, 4), (4, 11), (11, 11)] {
        assert_eq!(image[y * 16 + x], Vec3::ZERO, "pixel ({x}, {y})");
    }
    // The lookup API bakes and relighting can use gives the same radiance.
    let at = prt_scene::SurfacePoint::Vertex(3);
    let corner = scene.emission_at(0, at);
    assert!((corner[0] - expect[0]).abs() < 1e-6, "{corner:?}");
}

/// A lat-long map, black but for a 2×2 block of texels of radiance 50 about `u = 0.375`,
/// `v ≈ 0.3` (a small bright sun up, in front and 45° to the +X side), and the texels'
/// indices.
fn sun() -> (Environment, Vec<(usize, usize)>) {
    let (w, h) = (64, 32);
    let block = vec![(23, 9), (24, 9), (23, 10), (24, 10)];
    let mut texels = vec![[0.0; 3]; w * h];
    for &(i, j) in &block {
        texels[j * w + i] = [50.0; 3];
    }
    (test_util::latlong_environment(w, h, texels), block)
}

/// `∫ L(ω) max(0, n·ω) dω` over the sun's texels, by a 64×64 midpoint rule per texel in
/// (θ, φ) with CONVENTIONS.md's mapping `d = (sin φ sin θ, cos θ, −cos φ sin θ)`,
/// `dω = sin θ dθ dφ` (written here independently of the tracer's sampler).
fn sun_irradiance(n: DVec3, block: &[(usize, usize)]) -> f64 {
    let (w, h, k) = (64.0, 32.0, 64);
    let mut sum = 0.0;
    for &(i, j) in block {
        for a in 0..k {
            for b in 0..k {
                let phi = 2.0 * std::f64::consts::PI * (i as f64 + (a as f64 + 0.5) / k as f64) / w;
                let theta = std::f64::consts::PI * (j as f64 + (b as f64 + 0.5) / k as f64) / h;
                let d = DVec3::new(
                    phi.sin() * theta.sin(),
                    theta.cos(),
                    -phi.cos() * theta.sin(),
                );
                let dw =
                    theta.sin() * (std::f64::consts::PI / h) * (2.0 * std::f64::consts::PI / w)
                        / (k * k) as f64;
                sum += 50.0 * n.dot(d).max(0.0) * dw;
            }
        }
    }
    sum
}

/// The central 8×8 pixels (all on the quad).
fn centre(image: &[Vec3]) -> Vec<f32> {
    (4..12)
        .flat_map(|y| (4..12).map(move |x| (x, y)))
        .map(|(x, y)| image[y * 16 + x].x)
        .collect()
}

/// A 16-bit normal map of one constant texel `c` (in `[0, 65535]`), saved as `n.png`.
fn constant_normal_map(dir: &Path, c: [u16; 3]) {
    let img = image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::from_fn(2, 2, |_, _| {
        image::Rgba([c[0], c[1], c[2], 65535])
    });
    img.save(dir.join("n.png")).unwrap();
}

/// The quad with `normalTexture` `n.png` and the given `TANGENT` (or none: MikkTSpace), its
/// material replaced by Lambert (albedo 0.5): the normal map is a surface input, any BRDF
/// shades with it.
fn normal_mapped_quad(dir: &Path, tangent: Option<[f32; 4]>, with_map: bool) -> Scene {
    let material = if with_map {
        r#","normalTexture":{"index":0}"#
    } else {
        ""
    };
    let root = if with_map {
        gltf_texture_root(&["n.png"], "")
    } else {
        String::new()
    };
    let path = write_gltf_quad(dir, material, &root, tangent);
    let mut scene = scene_of(&path, sun().0);
    scene.materials[0] = Material::Lambert { albedo: [0.5; 3] };
    scene
}

/// A constant tilted normal map with a given `TANGENT = (1, 0, 0, 1)`: texel
/// `(0.75, 0.5, 1)` is the tangent-space normal `(0.5, 0, 1)`, so the shading normal is
/// `normalize(0.5, 0, 1)` (towards +X), and the Lambert radiance is
/// `albedo/π · ∫ L max(0, n·ω) dω` for that normal. The pixels are independent unbiased
/// estimates of it, so their mean lies within 5 standard errors (sample deviation / 8)
/// — plus 1e-4 relative for the 16-bit texel (`2·49151/65535 − 1 = 0.49998`).
#[test]
fn a_tilted_normal_map_shades_like_its_closed_form() {
    let dir = tempfile::tempdir().unwrap();
    constant_normal_map(dir.path(), [49151, 32768, 65535]);
    let block = sun().1;
    let check = |scene: &Scene, n: DVec3| {
        let px = centre(&render(scene, 32));
        let mean = px.iter().map(|&x| f64::from(x)).sum::<f64>() / px.len() as f64;
        let var = px
            .iter()
            .map(|&x| (f64::from(x) - mean).powi(2))
            .sum::<f64>()
            / (px.len() - 1) as f64;
        let expect = 0.5 / std::f64::consts::PI * sun_irradiance(n, &block);
        let tol = 5.0 * (var / px.len() as f64).sqrt() + 1e-4 * expect;
        assert!(
            (mean - expect).abs() <= tol,
            "normal {n}: mean {mean} expected {expect} ± {tol}"
        );
        mean
    };
    let tilted = normal_mapped_quad(dir.path(), Some([1.0, 0.0, 0.0, 1.0]), true);
    let n = tilted.shading_normal(0, 0, 0.25, 0.25);
    assert!(
        (n - Vec3::new(0.5, 0.0, 1.0).normalize()).length() < 1e-4,
        "{n}"
    );
    let lit = check(&tilted, DVec3::new(0.5, 0.0, 1.0).normalize());
    let flat = check(
        &normal_mapped_quad(dir.path(), None, false),
        DVec3::new(0.0, 0.0, 1.0),
    );
    assert!(lit > 1.2 * flat, "tilted towards the sun: {lit} vs {flat}");
    // Handedness: with w = −1 a green tilt turns the other way; with MikkTSpace tangents
    // (no TANGENT) on this quad the frame is t = +X, b = +Y (the image's up).
    constant_normal_map(dir.path(), [32768, 49151, 65535]);
    let up = normal_mapped_quad(dir.path(), None, true).shading_normal(0, 1, 0.3, 0.3);
    let down = normal_mapped_quad(dir.path(), Some([1.0, 0.0, 0.0, -1.0]), true)
        .shading_normal(0, 1, 0.3, 0.3);
    assert!(
        (up - Vec3::new(0.0, 0.5, 1.0).normalize()).length() < 1e-4,
        "{up}"
    );
    assert!(
        (down - Vec3::new(0.0, -0.5, 1.0).normalize()).length() < 1e-4,
        "{down}"
    );
}

/// A bumpy normal map (stripes tilted ±X) shades the flat quad non-uniformly under the sun,
/// while a flat normal map (0.5, 0.5, 1) matches the quad without one: same samples, and a
/// 16-bit texel 32768/65535 tilts the normal by 2·10⁻⁵ rad, so pixels agree to 1e-3.
#[test]
fn bumpy_normal_maps_shade_non_uniformly_and_flat_ones_change_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let plain = centre(&render(&normal_mapped_quad(dir.path(), None, false), 16));
    let spread = |px: &[f32]| {
        let (lo, hi) = px
            .iter()
            .fold((f32::MAX, 0.0f32), |(a, b), &x| (a.min(x), b.max(x)));
        hi / lo
    };
    assert!(spread(&plain) < 1.05, "plain quad: {}", spread(&plain));
    // 8 stripes along u, alternately tilted 35° towards +X and −X.
    let img = image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::from_fn(8, 8, |x, _| {
        let r = if x % 2 == 0 { 0.5 + 0.35 } else { 0.5 - 0.35 };
        image::Rgba([(r * 65535.0) as u16, 32768, 65535, 65535])
    });
    img.save(dir.path().join("n.png")).unwrap();
    let bumpy = centre(&render(&normal_mapped_quad(dir.path(), None, true), 16));
    assert!(spread(&bumpy) > 1.5, "bumpy quad: {}", spread(&bumpy));
    constant_normal_map(dir.path(), [32768, 32768, 65535]);
    let flat = centre(&render(&normal_mapped_quad(dir.path(), None, true), 16));
    for (a, b) in flat.iter().zip(&plain) {
        assert!((a - b).abs() <= 1e-3 * b, "{a} vs {b}");
    }
}

/// alphaMode MASK: the base colour's alpha is 1 on the left half of the quad and 0 on the
/// right (cutoff 0.5). Camera rays through the right half see the environment exactly (1),
/// through the left half the shaded quad; shadow (occlusion) rays and closest-hit rays pass
/// through the right half only.
#[test]
fn mask_cutouts_pass_camera_and_shadow_rays() {
    let dir = tempfile::tempdir().unwrap();
    let img = image::RgbaImage::from_fn(2, 1, |x, _| {
        image::Rgba([200, 200, 200, if x == 0 { 255 } else { 0 }])
    });
    img.save(dir.path().join("a.png")).unwrap();
    let material = r#","pbrMetallicRoughness":{"baseColorTexture":{"index":0},"metallicFactor":0,"roughnessFactor":1},"alphaMode":"MASK","alphaCutoff":0.5"#;
    let path = write_gltf_quad(
        dir.path(),
        material,
        &gltf_texture_root(&["a.png"], ""),
        None,
    );
    let loaded = load_gltf(&path, &DMat4::IDENTITY).unwrap();
    assert!(
        loaded.warnings.is_empty(),
        "MASK is modelled: {:?}",
        loaded.warnings
    );
    let scene = scene_of(&path, Environment::uniform([1.0; 3]));
    let image = render(&scene, 8);
    for y in [4, 8, 11] {
        assert_eq!(image[y * 16 + 12], Vec3::ONE, "cut out: the environment");
        assert!(
            image[y * 16 + 3].x < 0.9,
            "opaque half: {}",
            image[y * 16 + 3]
        );
    }
    let accel = Accel::build(&scene).unwrap();
    assert!(accel.is_masked(0));
    let up = Vec3::Z;
    for (x, blocked) in [(-0.5f32, true), (0.5, false)] {
        let origin = Vec3::new(x, 0.1, -1.0);
        assert_eq!(
            accel.occluded(origin, up, f32::INFINITY),
            blocked,
            "x = {x}"
        );
        assert_eq!(
            accel.closest_hit(origin, up, f32::INFINITY).is_some(),
            blocked
        );
    }
    // Without the scene's materials (`from_meshes`) the quad is opaque everywhere.
    let opaque = Accel::from_meshes(&scene.meshes, prt_tracer::AccelOptions::default()).unwrap();
    assert!(opaque.occluded(Vec3::new(0.5, 0.1, -1.0), up, f32::INFINITY));
}

/// The DamagedHelmet scene loads (JPEG textures, MikkTSpace tangents, an occlusion-map
/// warning and none about the normal map, emission or alpha), and a tiny render differs
/// from the same render with its normal map and emission switched off (through the API, and
/// by the scene file's `[render] normal_maps = false`, `emission = false`).
#[test]
fn damaged_helmet_renders_with_normal_map_and_emission() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/helmet.toml");
    let loaded = prt_scene::load_scene(&path).unwrap();
    let w = loaded.warnings.join("\n");
    assert!(w.contains("occlusionTexture is ignored"), "{w}");
    for absent in ["normalTexture", "emissi", "alphaMode"] {
        assert!(!w.contains(absent), "{absent}: {w}");
    }
    let mut scene = loaded.scene;
    let helmet = scene
        .meshes
        .iter()
        .position(|m| m.name.contains("DamagedHelmet"))
        .unwrap();
    assert!(scene.has_normal_map(helmet));
    let inputs = scene.surface_inputs(scene.meshes[helmet].material);
    assert!(inputs.emits() && inputs.emissive_texture.is_some());
    scene.camera.width = 32;
    scene.camera.height = 24;
    let both = render(&scene, 4);
    let mut no_emission = scene.clone();
    for s in &mut no_emission.surface_inputs {
        s.emissive = [0.0; 3];
        s.emissive_texture = None;
    }
    let mapped = render(&no_emission, 4);
    let mut neither = no_emission.clone();
    for s in &mut neither.surface_inputs {
        s.normal_map = None;
    }
    let plain = render(&neither, 4);
    // The scene file's switches do the same as clearing the inputs through the API.
    let text = std::fs::read_to_string(&path).unwrap().replace(
        "[render]\n",
        "[render]\nnormal_maps = false\nemission = false\n",
    );
    let mut switched = prt_scene::parse_scene_str(&text, &path).unwrap();
    assert!(switched
        .warnings
        .iter()
        .any(|w| w.contains("normal maps off")));
    switched.scene.camera = scene.camera.clone();
    assert_eq!(render(&switched.scene, 4), plain);
    // Pixels that change by more than 10 % of their value.
    let changed = |a: &[Vec3], b: &[Vec3]| {
        a.iter()
            .zip(b)
            .filter(|(x, y)| (**x - **y).abs().element_sum() > 0.1 * y.element_sum())
            .count()
    };
    eprintln!(
        "helmet 32×24: pixels changed by > 10 %: emission {}, normal map {}",
        changed(&both, &mapped),
        changed(&mapped, &plain)
    );
    // Emission changes no sample's path (same seeds), it only adds light: no pixel gets
    // darker (beyond f32 rounding of the sums), and the panels' pixels get brighter.
    for (a, b) in both.iter().zip(&mapped) {
        assert!(a.cmpge(*b - 1e-5 * b.abs()).all(), "{a} < {b}");
    }
    assert!(changed(&both, &mapped) >= 10, "30 when written");
    // The normal map moves the helmet's highlights and shadows: a fair share of the helmet's
    // pixels (about a third of the 768) change by more than 10 % (61 when written).
    assert!(changed(&mapped, &plain) >= 30);
}

/// `KHR_texture_transform` on a `normalTexture` (which the `gltf` crate does not parse there)
/// moves where the normal map is read: a 2×1 map tilted +X on the left and −X on the right
/// (clamped), read at `u = 0.25`, gives +X; shifted by half the width it gives −X.
#[test]
fn normal_texture_transform_moves_the_lookup() {
    let dir = tempfile::tempdir().unwrap();
    let img = image::ImageBuffer::<image::Rgba<u16>, Vec<u16>>::from_fn(2, 1, |x, _| {
        let r = if x == 0 { 49151 } else { 16384 };
        image::Rgba([r, 32768, 65535, 65535])
    });
    img.save(dir.path().join("n.png")).unwrap();
    let tilt = |transform: &str| {
        let material = format!(r#","normalTexture":{{"index":0{transform}}}"#);
        let root = gltf_texture_root(&["n.png"], r#""extensionsUsed":["KHR_texture_transform"],"#);
        let path = write_gltf_quad(dir.path(), &material, &root, Some([1.0, 0.0, 0.0, 1.0]));
        let scene = scene_of(&path, Environment::uniform([1.0; 3]));
        // Triangle 1 is (v0, v2, v3) with UVs (0, 1), (1, 0), (0, 0): weights (0.25, 0.5)
        // of v2 and v3 put the point at UV (0.25, 0.25), the left texel's centre.
        let at = prt_scene::SurfacePoint::Triangle {
            tri: 1,
            u: 0.25,
            v: 0.5,
        };
        assert_eq!(scene.meshes[0].texcoord(0, at), Some([0.25, 0.25]));
        scene.shading_normal(0, 1, 0.25, 0.5)
    };
    let plain = tilt("");
    let shifted = tilt(r#","extensions":{"KHR_texture_transform":{"offset":[0.5,0.0]}}"#);
    assert!(plain.x > 0.4, "{plain}");
    assert!(shifted.x < -0.4, "{shifted}");
}
