//! `prt bake --subdivide` (issue 15, adaptive subdivision): a floor lit evenly is never split,
//! a floor with a wall's contact shadow is, the refined meshes travel in the bake, and relight
//! and export use them; relit against a path-traced reference the refined bake is closer.

mod common;

use common::{prt, psnr_ldr, run, write_scene};

fn decisions(bake: &std::path::Path) -> String {
    let b = prt_bakefile::read_bake(bake).unwrap();
    b.meta
        .decisions
        .iter()
        .map(|d| format!("{:?}: {} ({})", d.object, d.decision, d.reason))
        .collect::<Vec<_>>()
        .join("\n")
}

#[test]
fn subdivision_refines_where_the_transfer_changes_and_nowhere_else() {
    let dir = tempfile::tempdir().unwrap();
    // A lone quad under a uniform sky: its transfer is the same everywhere, nothing splits.
    let hard = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes/hard");
    std::fs::copy(hard.join("quad.obj"), dir.path().join("quad.obj")).unwrap();
    std::fs::copy(hard.join("uniform.hdr"), dir.path().join("uniform.hdr")).unwrap();
    let lone = dir.path().join("lone.toml");
    std::fs::write(
        &lone,
        "[camera]\neye = [0.0, 2.0, 2.0]\ntarget = [0.0, 0.0, 0.0]\nfov_y = 45.0\nresolution = [16, 12]\n\n[environment]\nfile = \"uniform.hdr\"\n\n[materials.white]\ntype = \"lambert\"\nalbedo = [0.8, 0.8, 0.8]\n\n[[objects]]\nmesh = \"quad.obj\"\nmaterial = \"white\"\n\n[render]\nbounces = 0\n",
    )
    .unwrap();
    let b = dir.path().join("lone.prtb");
    run(prt()
        .arg("bake")
        .arg(&lone)
        .args(["--rays", "256", "--order", "3", "--subdivide", "--out"])
        .arg(&b));
    let d = decisions(&b);
    assert!(
        d.contains("4 → 4 vertices") && d.contains("nothing to refine"),
        "{d}"
    );

    // The L: a floor meeting a wall, with the shadow and occlusion along their corner.
    let scene = write_scene(dir.path(), 2);
    let (plain, sub) = (dir.path().join("plain.prtb"), dir.path().join("sub.prtb"));
    let common = ["--rays", "512", "--order", "4", "--bounces", "0"];
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args(common)
        .arg("--out")
        .arg(&plain));
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args(common)
        .args(["--subdivide", "--max-subdivision", "3", "--out"])
        .arg(&sub));
    let d = decisions(&sub);
    assert!(d.contains("subdivided") && d.contains("were split"), "{d}");
    let (pb, sb) = (
        prt_bakefile::read_bake(&plain).unwrap(),
        prt_bakefile::read_bake(&sub).unwrap(),
    );
    let grew = pb
        .objects
        .iter()
        .zip(&sb.objects)
        .any(|(p, s)| s.point_count > p.point_count);
    assert!(grew, "no object gained vertices:\n{d}");
    for o in &sb.objects {
        // The refined mesh is in the file, and its points are its vertices.
        assert_eq!(
            o.mesh.as_ref().unwrap().positions.len() as u64,
            o.point_count
        );
        assert!(sb.meta.settings["subdivided_from"][&o.name]["geometry_hash"].is_string());
    }

    // Relight and export use the refined meshes.
    let colours = dir.path().join("c.csv");
    let relit = |b: &std::path::Path, exr: &str| {
        run(prt()
            .arg("relight")
            .arg(&scene)
            .arg("--bake")
            .arg(b)
            .arg("--out")
            .arg(dir.path().join(exr))
            .arg("--vertex-colours")
            .arg(&colours));
        std::fs::read_to_string(&colours).unwrap().lines().count() - 1
    };
    assert_eq!(
        relit(&plain, "plain.exr") as u64,
        pb.objects.iter().map(|o| o.point_count).sum::<u64>()
    );
    assert_eq!(
        relit(&sub, "sub.exr") as u64,
        sb.objects.iter().map(|o| o.point_count).sum::<u64>()
    );
    run(prt()
        .arg("export")
        .arg(&scene)
        .arg("--bake")
        .arg(&sub)
        .arg("--out")
        .arg(dir.path().join("sub.glb")));

    // Against the path tracer (bounces 0 like the bakes): the refined bake is closer.
    run(prt()
        .arg("render")
        .arg(&scene)
        .args(["--spp", "1024", "--bounces", "0", "--out"])
        .arg(dir.path().join("ref.exr")));
    let psnr = |exr: &str| psnr_ldr(&dir.path().join(exr), &dir.path().join("ref.exr"));
    let (p0, p1) = (psnr("plain.exr"), psnr("sub.exr"));
    eprintln!("against the path tracer: plain {p0:.2} dB, subdivided {p1:.2} dB");
    assert!(
        p1 > p0 + 0.5,
        "subdivision did not help: {p0:.2} → {p1:.2} dB"
    );

    // Refused: per-pixel and sharded subdivision.
    for bad in [&["--per-pixel"][..], &["--shard", "0/2"]] {
        let out = prt()
            .arg("bake")
            .arg(&scene)
            .args(common)
            .arg("--subdivide")
            .args(bad)
            .arg("--out")
            .arg(dir.path().join("x.prtb"))
            .output()
            .unwrap();
        assert!(!out.status.success(), "{bad:?} accepted");
    }
}
