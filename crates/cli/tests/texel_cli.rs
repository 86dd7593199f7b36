//! `prt bake --per-texel SIZE` (issue 15, lightmap bakes) end to end: the bunny on the
//! 2-triangle floor of `scenes/hard` (whose only UVs are the floor's), baked per vertex and per
//! texel, relit and compared with the path tracer; and the refusals: a size of 0, a scene
//! whose lightmap UVs changed since the bake, glTF export of a texel bake.

mod common;

use common::{json, prt, psnr_ldr, refused, run};
use std::path::Path;

fn scene(dir: &Path, uv_scale: f32) -> std::path::PathBuf {
    let repo = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../scenes");
    // The floor with its UVs scaled (1: the repository's quad.obj).
    let quad = std::fs::read_to_string(repo.join("hard/quad.obj")).unwrap();
    let quad: String = quad
        .lines()
        .map(|l| match l.strip_prefix("vt ") {
            Some(uv) => {
                let v: Vec<f32> = uv.split_whitespace().map(|x| x.parse().unwrap()).collect();
                format!("vt {} {}\n", v[0] * uv_scale, v[1] * uv_scale)
            }
            None => format!("{l}\n"),
        })
        .collect();
    std::fs::write(dir.join("quad.obj"), quad).unwrap();
    let s = dir.join(format!("scene{uv_scale}.toml"));
    std::fs::write(
        &s,
        format!(
            r#"[camera]
eye = [0.0, 0.75, 2.4]
target = [0.0, 0.42, 0.0]
fov_y = 40.0
resolution = [64, 48]

[environment]
file = "{sky}"

[materials.clay]
type = "lambert"
albedo = [0.8, 0.8, 0.8]

[[objects]]
mesh = "{bunny}"
material = "clay"
scale = 0.1

[[objects]]
mesh = "quad.obj"
material = "clay"
scale = [2.0, 1.0, 2.0]

[render]
bounces = 0
"#,
            sky = repo.join("hard/upper_sky.hdr").display(),
            bunny = repo.join("meshes/bunny_lowres.obj").display(),
        ),
    )
    .unwrap();
    s
}

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
    fails(
        prt()
            .arg("export")
            .arg(&s)
            .arg("--bake")
            .arg(&t)
            .arg("--out")
            .arg(dir.path().join("x.glb")),
        "per-texel",
    );
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
