//! `prt bake --per-texel SIZE` (issue 15, lightmap bakes) end to end: the bunny on the
//! 2-triangle floor of `scenes/hard` (whose only UVs are the floor's), baked per vertex and per
//! texel, relit and compared with the path tracer; and the refusals: a size of 0, a scene
//! whose lightmap UVs changed since the bake, UVs outside the unit square. (Their glTF export:
//! export_cli.rs.)

mod common;

use common::{json, prt, psnr_ldr, refused, run, write_lightmap_scene as scene};
use std::path::Path;

#[test]
fn per_texel_bakes_hold_the_contact_shadow_a_coarse_floor_misses() {
    let dir = tempfile::tempdir().unwrap();
    let s = scene(dir.path(), 1.0);
    let (v, t) = (dir.path().join("v.prtb"), dir.path().join("t.prtb"));
    let common = ["--rays", "256", "--order", "3"];
    run(prt().arg("bake").arg(&s).args(common).arg("--out").arg(&v));
    let out = run(prt()
        .arg("bake")
        .arg(&s)
        .args(common)
        .args(["--per-texel", "48", "--json", "--out"])
        .arg(&t));
    let report = json(&out);
    // The bunny has no UVs: per vertex; the floor: 48² texels.
    let points: Vec<u64> = report["objects"]
        .as_array()
        .unwrap()
        .iter()
        .map(|o| o["points"].as_u64().unwrap())
        .collect();
    assert_eq!(points[1], 48 * 48, "{report}");
    let b = prt_bakefile::read_bake(&t).unwrap();
    assert!(b.objects[0].coverage.is_none() && b.objects[1].coverage.is_some());
    let relit = |bake: &Path, exr: &str| {
        run(prt()
            .arg("relight")
            .arg(&s)
            .arg("--bake")
            .arg(bake)
            .arg("--out")
            .arg(dir.path().join(exr)));
    };
    relit(&v, "v.exr");
    relit(&t, "t.exr");
    run(prt()
        .arg("render")
        .arg(&s)
        .args(["--spp", "512", "--out"])
        .arg(dir.path().join("ref.exr")));
    let psnr = |exr: &str| psnr_ldr(&dir.path().join(exr), &dir.path().join("ref.exr"));
    let (pv, pt) = (psnr("v.exr"), psnr("t.exr"));
    eprintln!("against the path tracer: per vertex {pv:.2} dB, per texel {pt:.2} dB");
    // The floor's 4 vertices cannot hold the bunny's contact shadow and occlusion; 48² texels
    // can (measured 10.4 dB apart here: 26.96 → 37.41 dB; the bound leaves room for noise).
    assert!(
        pt > pv + 5.0,
        "per texel {pt:.2} dB vs per vertex {pv:.2} dB"
    );

    // Refusals, each naming the problem.
    let fails = refused;
    fails(
        prt()
            .arg("bake")
            .arg(&s)
            .args(["--per-texel", "0", "--out"])
            .arg(dir.path().join("x.prtb")),
        "lightmap of 0×0 texels",
    );
    assert!(!dir.path().join("x.prtb").exists());
    // The floor's UVs halved after baking: the texels no longer belong to the asset.
    let moved = scene(dir.path(), 0.5);
    fails(
        prt()
            .arg("relight")
            .arg(&moved)
            .arg("--bake")
            .arg(&t)
            .arg("--out")
            .arg(dir.path().join("x.exr")),
        "lightmap UVs (set 0) differ",
    );
    // UVs beyond the unit square are refused at bake time, naming the object.
    let outside = scene(dir.path(), 1.5);
    fails(
        prt()
            .arg("bake")
            .arg(&outside)
            .args(["--per-texel", "8", "--out"])
            .arg(dir.path().join("x.prtb")),
        "quad.obj: 3 of 4 lightmap UVs lie outside [0, 1]",
    );
}
