//! Bake throughput on the 37k-vertex Stanford bunny (`cargo bench -p prt-bake`): rays per
//! second and vertices per second at orders 3, 6 and 10 with 1024 rays per vertex, and the
//! whole order-6 bake with one bounce. One timed run per configuration after a warm-up (each
//! run traces ~39 M rays, long enough that run-to-run spread is a few per cent); figures in
//! the crate README.

use prt_bake::{bake, BakeSettings};
use prt_scene::{Camera, Environment, Material, Scene};
use std::path::Path;
use std::time::Instant;

fn main() {
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/assets/meshes/bunny.obj");
    let path = if path.exists() {
        path
    } else {
        Path::new("/work/shared/assets/meshes/bunny.obj").to_path_buf()
    };
    let loaded = match prt_scene::load_obj(&path, &glam::DMat4::IDENTITY) {
        Ok(l) => l,
        Err(e) => {
            eprintln!("skipping the bake benchmark: {e}");
            return;
        }
    };
    let cam = Camera::look_at(
        glam::DVec3::new(0.0, 0.1, 0.35),
        glam::DVec3::new(0.0, 0.1, 0.0),
        40.0,
        160,
        120,
    );
    let mut scene = Scene::new(cam, Environment::uniform([1.0; 3]));
    let m = scene.add_material("clay", Material::Lambert { albedo: [0.8; 3] });
    for mesh in loaded.meshes {
        scene.add_mesh(mesh, m);
    }
    let vertices: usize = scene.meshes.iter().map(|m| m.positions.len()).sum();
    let t = Instant::now();
    let accel = prt_tracer::Accel::build(&scene).expect("build");
    println!(
        "bunny: {vertices} vertices, BVH built in {:.3} s",
        t.elapsed().as_secs_f64()
    );
    let threads = rayon::current_num_threads();
    println!("| order | rays/vertex | bounces | seconds | Mrays/s | vertices/s | threads |");
    println!("|---|---|---|---|---|---|---|");
    let _ = bake(
        &scene,
        &accel,
        &BakeSettings {
            order: Some(3),
            rays: 64,
            bounces: 0,
            ..BakeSettings::final_quality()
        },
    );
    for (order, bounces) in [(3usize, 0u32), (6, 0), (10, 0), (6, 1)] {
        let s = BakeSettings {
            order: Some(order),
            rays: 1024,
            bounces,
            ..BakeSettings::final_quality()
        };
        let t = Instant::now();
        let out = bake(&scene, &accel, &s).expect("bake");
        let secs = t.elapsed().as_secs_f64();
        println!(
            "| {order} | 1024 | {bounces} | {secs:.2} | {:.2} | {:.0} | {threads} |",
            out.report.rays_traced as f64 / secs / 1e6,
            vertices as f64 / secs
        );
    }
}
