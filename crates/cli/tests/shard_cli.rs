//! `prt bake --shard I/N` + `prt merge` end to end: the merged file is byte for byte the file
//! of the unsharded bake (README "Distributed bakes", bakefile SPEC §7).

use std::path::{Path, PathBuf};
use std::process::Command;

fn prt() -> Command {
    Command::new(env!("CARGO_BIN_EXE_prt"))
}

fn run(cmd: &mut Command) {
    let out = cmd.output().unwrap();
    assert!(
        out.status.success(),
        "{cmd:?} failed:\n{}",
        String::from_utf8_lossy(&out.stderr)
    );
}

/// An "L": a 4×4-quad floor facing +Y and a 4×4-quad wall facing +Z standing on its back edge,
/// so that rays of one hit the other (bounce gathering has work to do). 50 vertices.
fn write_obj(path: &Path) {
    let mut text = String::from("# floor and wall\n");
    let n = 4;
    for j in 0..=n {
        for i in 0..=n {
            let (x, z) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32 - 0.5);
            text += &format!("v {x} 0 {z}\n");
        }
    }
    for j in 0..=n {
        for i in 0..=n {
            let (x, y) = (i as f32 / n as f32 - 0.5, j as f32 / n as f32);
            text += &format!("v {x} {y} -0.5\n");
        }
    }
    let w = n + 1;
    for base in [1, 1 + w * w] {
        for j in 0..n {
            for i in 0..n {
                let a = base + j * w + i;
                let (b, c, d) = (a + 1, a + w, a + w + 1);
                // Floor: (b − a) × (c − a) = +X × +Z = −Y, so wind a, c, b for +Y; wall:
                // +X × +Y = +Z, so a, b, c.
                if base == 1 {
                    text += &format!("f {a} {c} {b}\nf {b} {c} {d}\n");
                } else {
                    text += &format!("f {a} {b} {c}\nf {b} {d} {c}\n");
                }
            }
        }
    }
    std::fs::write(path, text).unwrap();
}

fn write_scene(dir: &Path) -> PathBuf {
    write_obj(&dir.join("l.obj"));
    // 8 × 4 lat-long map: a bright sky row, darker below, some colour across.
    exr::prelude::write_rgb_file(dir.join("env.exr"), 8, 4, |x, y| {
        let sky = if y == 0 { 4.0 } else { 1.0 / (y as f32 + 1.0) };
        (sky, sky * (0.5 + x as f32 / 16.0), sky * 0.8)
    })
    .unwrap();
    let scene = dir.join("scene.toml");
    std::fs::write(
        &scene,
        r#"[camera]
eye = [0.0, 0.6, 2.0]
target = [0.0, 0.3, 0.0]
fov_y = 40.0
resolution = [8, 6]

[environment]
file = "env.exr"

[materials.clay]
type = "lambert"
albedo = [0.8, 0.6, 0.4]

[[objects]]
mesh = "l.obj"
material = "clay"

[render]
bounces = 0
"#,
    )
    .unwrap();
    scene
}

#[test]
fn three_shards_merge_to_the_unsharded_file_byte_for_byte() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path());
    for bounces in ["0", "1"] {
        let bake = |extra: &[&str], out: &Path| {
            run(prt()
                .arg("bake")
                .arg(&scene)
                .args(["--order", "4", "--rays", "64", "--bounces", bounces])
                .args(extra)
                .arg("--out")
                .arg(out));
        };
        let whole = dir.path().join(format!("whole-{bounces}.prtb"));
        bake(&["--threads", "2"], &whole);
        let mut shards = Vec::new();
        for i in 0..3 {
            let shard = dir.path().join(format!("shard-{bounces}-{i}.prtb"));
            // One thread for the shards: thread count must not matter either.
            bake(&["--threads", "1", "--shard", &format!("{i}/3")], &shard);
            shards.push(shard);
        }
        let merged = dir.path().join(format!("merged-{bounces}.prtb"));
        // Shards in any order.
        run(prt()
            .arg("merge")
            .args([&shards[2], &shards[0], &shards[1]])
            .arg("--out")
            .arg(&merged));
        let (a, b) = (
            std::fs::read(&whole).unwrap(),
            std::fs::read(&merged).unwrap(),
        );
        let first_shard = std::fs::read(&shards[0]).unwrap();
        assert!(
            first_shard.len() < a.len(),
            "bounces {bounces}: a shard should hold fewer points than the whole bake"
        );
        assert!(
            a == b,
            "bounces {bounces}: merged shards ({} bytes) differ from the unsharded bake ({} \
             bytes)",
            b.len(),
            a.len()
        );
        // The ray statistics (summed by the merge, so byte equality above covers the sum) are
        // shown by `prt inspect`: every one of the 50 vertices' 64 rays counted.
        let out = prt()
            .arg("inspect")
            .arg(&merged)
            .arg("--json")
            .output()
            .unwrap();
        let json: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let stats = &json["objects"][0]["ray_stats"];
        assert_eq!(stats["points"], 50, "{json}");
        assert_eq!(stats["rays"], 50 * 64, "{json}");
        let text = prt().arg("inspect").arg(&merged).output().unwrap();
        let text = String::from_utf8_lossy(&text.stdout);
        assert!(
            text.contains("rays 3200 from 50 points: back-face hits"),
            "{text}"
        );
    }
}
