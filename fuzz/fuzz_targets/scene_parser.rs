//! Fuzz target: the scene-file parser (`prt_scene::parse_scene_str`, the body of
//! `load_scene`) on arbitrary bytes must return `Ok` or an error naming the scene file, never
//! panic. The bytes are read as UTF-8 (lossily, as a text editor would). The scene's folder is
//! a temporary directory holding a tiny OBJ (`m.obj`, a tetrahedron) and a 4×2 Radiance map
//! (`env.hdr`), so inputs that name them get past the file checks into the mesh and map
//! loaders, the transforms and the material checks.
#![no_main]

use libfuzzer_sys::fuzz_target;
use std::path::PathBuf;
use std::sync::OnceLock;

const OBJ: &str = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\n\
                   f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";

/// A 4×2 flat (not run-length encoded) RGBE image of radiance 1.
fn hdr_bytes() -> Vec<u8> {
    let mut b = b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 2 +X 4\n".to_vec();
    for _ in 0..8 {
        b.extend_from_slice(&[128, 128, 128, 129]);
    }
    b
}

fn scene_path() -> &'static PathBuf {
    static DIR: OnceLock<PathBuf> = OnceLock::new();
    DIR.get_or_init(|| {
        let dir = std::env::temp_dir().join(format!("prt-fuzz-scene-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("temp dir");
        std::fs::write(dir.join("m.obj"), OBJ).expect("write m.obj");
        std::fs::write(dir.join("env.hdr"), hdr_bytes()).expect("write env.hdr");
        dir.join("scene.toml")
    })
}

fuzz_target!(|data: &[u8]| {
    let text = String::from_utf8_lossy(data);
    let path = scene_path();
    if let Err(e) = prt_scene::parse_scene_str(&text, path) {
        let message = e.to_string();
        assert!(
            message.starts_with(&*path.to_string_lossy()),
            "error does not name the scene file: {message}"
        );
    }
});
