//! EXR and PNG output: round trips, metadata, the sRGB view, atomic writes.

use exr::prelude::*;
use glam::Vec3;
use prt_tracer::{output, test_util, RenderOutput, RenderSettings, Renderer};

fn small_render() -> RenderOutput {
    let cam = test_util::camera(Vec3::new(0.0, 0.0, 3.0), Vec3::ZERO, 40.0, 7, 5);
    let sphere = test_util::uv_sphere(Vec3::ZERO, 1.0, 8, 16, true);
    let env = test_util::latlong_environment(2, 1, vec![[0.25, 0.5, 2.0], [1.0, 0.0, 0.5]]);
    let scene = test_util::scene(
        cam,
        env,
        vec![prt_scene::Material::Lambert { albedo: [0.5; 3] }],
        vec![sphere],
    );
    let s = RenderSettings {
        spp: 4,
        seed: 12345678901234,
        aovs: true,
        progress: false,
        ..RenderSettings::default()
    };
    Renderer::new(&scene, s).unwrap().render().unwrap()
}

#[test]
fn test01_exr_round_trip_with_aovs_and_metadata() {
    let out = small_render();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("img.exr");
    output::write_exr(&path, &out).unwrap();
    let image = read_all_flat_layers_from_file(&path).unwrap();
    let layer = &image.layer_data[0];
    assert_eq!(layer.size, Vec2(7, 5));
    let get = |name: &str| -> Vec<f32> {
        let ch = layer
            .channel_data
            .list
            .iter()
            .find(|c| c.name.to_string() == name)
            .unwrap_or_else(|| panic!("{name}"));
        ch.sample_data.values_as_f32().collect()
    };
    let (r, b) = (get("R"), get("B"));
    for (i, l) in out.radiance.iter().enumerate() {
        assert_eq!(r[i], l.x);
        assert_eq!(b[i], l.z);
    }
    let aovs = out.aovs.as_ref().unwrap();
    assert_eq!(get("depth.Z"), aovs.depth);
    assert_eq!(
        get("normal.Y"),
        aovs.normal.iter().map(|n| n.y).collect::<Vec<_>>()
    );
    assert_eq!(
        get("variance.G"),
        aovs.variance.iter().map(|n| n.y).collect::<Vec<_>>()
    );
    let attrs = &layer.attributes.other;
    assert_eq!(
        attrs.get(&Text::from("prt.spp")),
        Some(&AttributeValue::I32(4))
    );
    assert_eq!(
        attrs.get(&Text::from("prt.seed")),
        Some(&AttributeValue::Text(Text::from("12345678901234")))
    );
    assert!(attrs.contains_key(&Text::from("prt.render_seconds")));
    assert!(attrs.contains_key(&Text::from("prt.tool_version")));
    // Only the destination is left in the directory.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

#[test]
fn test02_png_view_is_clamped_srgb() {
    let mut out = small_render();
    out.radiance = vec![Vec3::new(0.0, 0.5, 1.0), Vec3::new(2.0, -1.0, 0.001)];
    out.width = 2;
    out.height = 1;
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("img.png");
    output::write_png(&path, &out, 0.0).unwrap();
    let img = image::open(&path).unwrap().to_rgb8();
    // sRGB(0.5) = 1.055·0.5^(1/2.4) − 0.055 = 0.7354 → 187.5 → 188; sRGB(0.001) = 0.01292 → 3.
    assert_eq!(img.get_pixel(0, 0).0, [0, 188, 255]);
    assert_eq!(img.get_pixel(1, 0).0, [255, 0, 3]);
    // One stop down halves the linear value: 1.0 → 0.5 → 188.
    output::write_png(&path, &out, -1.0).unwrap();
    assert_eq!(
        image::open(&path).unwrap().to_rgb8().get_pixel(0, 0).0[2],
        188
    );
}

#[test]
fn test03_unwritable_destination_is_an_error() {
    let out = small_render();
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no/such/dir/img.exr");
    assert!(output::write_exr(&missing, &out).is_err());
    assert!(output::write_png(&missing.with_extension("png"), &out, 0.0).is_err());
    // A failed write leaves an existing destination untouched.
    let path = dir.path().join("keep.exr");
    std::fs::write(&path, b"old").unwrap();
    let bad = output::write_atomically(&path, |_| Err("simulated failure".into()));
    assert!(bad.is_err());
    assert_eq!(std::fs::read(&path).unwrap(), b"old");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
}

/// The same image is the same bytes (determinism): the exr crate writes custom attributes in
/// a hash map's order, which differs between maps, so `write_exr_image` sorts them. Written
/// twice from two maps with ten attributes: identical files, attributes in name order, and
/// the exr crate reads back every attribute and pixel.
#[test]
fn exr_files_are_the_same_bytes_whatever_the_attribute_map_order() {
    let dir = tempfile::tempdir().unwrap();
    let pixels: Vec<f32> = (0..12).map(|i| i as f32 * 0.25).collect();
    let write = |name: &str| {
        let mut attributes = LayerAttributes::default();
        for k in 0..10 {
            attributes.other.insert(
                Text::from(format!("prt.key{k}").as_str()),
                AttributeValue::Text(Text::from(format!("value {k}").as_str())),
            );
        }
        let channels = AnyChannels::sort(
            [AnyChannel::new("R", FlatSamples::F32(pixels.clone()))]
                .into_iter()
                .collect(),
        );
        let image = Image::from_layer(Layer::new(
            (4, 3),
            attributes,
            Encoding::SMALL_LOSSLESS,
            channels,
        ));
        let path = dir.path().join(name);
        prt_tracer::output::write_exr_image(&path, &image).unwrap();
        path
    };
    let (a, b) = (write("a.exr"), write("b.exr"));
    let bytes = std::fs::read(&a).unwrap();
    assert_eq!(bytes, std::fs::read(&b).unwrap());
    let at = |k: usize| {
        let name = format!("prt.key{k}\0");
        bytes
            .windows(name.len())
            .position(|w| w == name.as_bytes())
            .unwrap()
    };
    assert!((0..9).all(|k| at(k) < at(k + 1)), "attributes out of order");
    let back = read_all_flat_layers_from_file(&a).unwrap();
    let layer = &back.layer_data[0];
    for k in 0..10 {
        assert_eq!(
            layer
                .attributes
                .other
                .get(&Text::from(format!("prt.key{k}").as_str())),
            Some(&AttributeValue::Text(Text::from(
                format!("value {k}").as_str()
            )))
        );
    }
    match &layer.channel_data.list[0].sample_data {
        FlatSamples::F32(v) => assert_eq!(v, &pixels),
        other => panic!("{other:?}"),
    }
}

#[test]
fn malformed_exr_headers_are_refused_not_reordered() {
    use prt_tracer::output::sort_exr_attributes;
    let mut truncated = b"v/1\x01\x02\x00\x00\x00name\0".to_vec();
    assert!(sort_exr_attributes(&mut truncated).is_err());
    let mut multi = b"v/1\x01\x02\x10\x00\x00\0".to_vec();
    assert!(sort_exr_attributes(&mut multi).is_err());
    let mut oversize = b"v/1\x01\x02\x00\x00\x00a\0int\0\xff\x00\x00\x00\0".to_vec();
    assert!(sort_exr_attributes(&mut oversize).is_err());
}
