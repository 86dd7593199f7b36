//! Textured glTF materials in the path tracer: the base colour at a hit is the texture read at
//! the interpolated UV (glTF orientation: UV (0, 0) is the image's top-left texel), times
//! the factor and the vertex colour.

use glam::Vec3;
use prt_scene::{Material, Texture, TextureRef, Wrap};
use prt_tracer::{test_util, RenderSettings, Renderer};

const RED: [f32; 4] = [0.8, 0.1, 0.1, 1.0];
const GREEN: [f32; 4] = [0.1, 0.7, 0.2, 1.0];
const BLUE: [f32; 4] = [0.1, 0.2, 0.9, 1.0];
const WHITE: [f32; 4] = [0.9, 0.9, 0.9, 1.0];

/// A 4×4 texture whose 2×2 quadrants are red (top left), green (top right), blue (bottom
/// left) and white: at a quadrant's middle all four bilinear neighbours are that colour.
fn quadrants() -> Texture {
    let texels = (0..16)
        .map(|i| match (i % 4 < 2, i / 4 < 2) {
            (true, true) => RED,
            (false, true) => GREEN,
            (true, false) => BLUE,
            (false, false) => WHITE,
        })
        .collect();
    Texture {
        name: "quadrants".into(),
        width: 4,
        height: 4,
        texels,
        wrap: [Wrap::ClampToEdge; 2],
    }
}

fn pbr(base_color: [f32; 3], texture: Option<TextureRef>) -> Material {
    Material::Pbr {
        base_color,
        metallic: 0.0,
        roughness: 0.5,
        base_color_texture: texture,
        metallic_roughness_texture: None,
    }
}

fn render(material: Material, colors: Vec<[f32; 3]>) -> Vec<Vec3> {
    // A 2×2 quad facing the camera; its top-left corner (vertex 3) has UV (0, 0).
    let mut quad = test_util::quad(Vec3::new(-1.0, -1.0, 0.0), Vec3::X * 2.0, Vec3::Y * 2.0);
    quad.texcoords = vec![vec![[0.0, 1.0], [1.0, 1.0], [1.0, 0.0], [0.0, 0.0]]];
    quad.colors = colors;
    let cam = test_util::camera(Vec3::new(0.0, 0.0, 4.0), Vec3::ZERO, 28.0, 16, 16);
    let env = test_util::constant_environment([1.0, 1.0, 1.0]);
    let mut scene = test_util::scene(cam, env, vec![material], vec![quad]);
    scene.textures = vec![quadrants()];
    scene.validate().unwrap();
    let settings = RenderSettings {
        spp: 16,
        bounces: 0,
        progress: false,
        ..RenderSettings::default()
    };
    Renderer::new(&scene, settings)
        .unwrap()
        .render()
        .unwrap()
        .radiance
}

#[test]
fn texture_quadrants_land_where_their_uvs_say() {
    let tex = Some(TextureRef {
        index: 0,
        texcoord: 0,
        transform: None,
    });
    let textured = render(pbr([1.0; 3], tex), Vec::new());
    // Pixels of the image's quadrant middles (the quad spans about 14 of the 16 pixels).
    let probe = [
        (4usize, 4usize, RED),
        (11, 4, GREEN),
        (4, 11, BLUE),
        (11, 11, WHITE),
    ];
    for (x, y, c) in probe {
        let plain = render(pbr([c[0], c[1], c[2]], None), Vec::new());
        let (a, b) = (textured[y * 16 + x], plain[y * 16 + x]);
        // The same samples meet the same base colour (all four bilinear neighbours equal):
        // bit-identical.
        assert_eq!(a, b, "pixel ({x}, {y}): textured {a} vs plain {b}");
    }
    // Factor × texture × vertex colour multiply.
    let tinted = render(pbr([0.5, 1.0, 1.0], tex), vec![[1.0, 0.5, 1.0]; 4]);
    let plain = render(pbr([0.5 * RED[0], 0.5 * RED[1], RED[2]], None), Vec::new());
    assert_eq!(tinted[4 * 16 + 4], plain[4 * 16 + 4]);
}
