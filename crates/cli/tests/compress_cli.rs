//! `prt compress` end to end (issues 15 and 34, compression): clustered PCA of every transfer
//! block of a bake (diffuse and the glossy path's visibility), relit straight from the
//! compressed form, the error it reports is the error it has, the relit-image target it is
//! given is the PSNR its images reach, and what it refuses.

mod common;

use common::{json, prt, run, write_scene};

#[test]
fn compress_relight_and_refusals() {
    let dir = tempfile::tempdir().unwrap();
    let scene = write_scene(dir.path(), 6);
    let bake = dir.path().join("bake.prtb");
    run(prt()
        .arg("bake")
        .arg(&scene)
        .args(["--rays", "128", "--order", "6", "--bounces", "1", "--out"])
        .arg(&bake));
    let small = dir.path().join("small.prtb");
    let report = json(&run(prt()
        .arg("compress")
        .arg(&bake)
        .args(["--clusters", "4", "--error", "0.02", "--json", "--out"])
        .arg(&small)));
    let blocks = report["blocks"].as_array().unwrap();
    // Every block of every object: the glossy objects' visibility too.
    let full = prt_bakefile::read_bake(&bake).unwrap();
    let comp = prt_bakefile::read_bake(&small).unwrap();
    let pairs: Vec<_> = full
        .objects
        .iter()
        .zip(&comp.objects)
        .flat_map(|(fo, co)| fo.blocks.iter().zip(&co.blocks))
        .collect();
    assert_eq!(blocks.len(), pairs.len(), "{report}");
    assert!(
        pairs
            .iter()
            .any(|(b, _)| b.kind == prt_bakefile::TransferKind::Visibility),
        "the scene has a glossy object"
    );
    // The error each block reports is the error its stored form has, measured here from the
    // files themselves: ‖t − t̃‖ / ‖t‖ over the block.
    for (b, (fb, cb)) in blocks.iter().zip(&pairs) {
        assert_eq!(b["kind"].as_str(), Some(fb.kind.name()));
        let cpca = cb.cpca.as_ref().expect("every block is compressed");
        // Round trip: the reader's data is the stored form's reconstruction (SPEC §3.13).
        assert_eq!(cpca.reconstruct(), cb.data);
        let num: f64 = fb
            .data
            .iter()
            .zip(&cb.data)
            .map(|(a, b)| f64::from(a - b).powi(2))
            .sum();
        let den: f64 = fb.data.iter().map(|a| f64::from(*a).powi(2)).sum();
        let measured = (num / den).sqrt();
        let stated = b["rel_error"].as_f64().unwrap();
        assert!(
            (measured - stated).abs() <= 1e-6 + 1e-4 * stated,
            "{measured} vs {stated}"
        );
        assert!((cpca.rel_error - stated).abs() <= 1e-12);
        // The default component count meets the 2 % target.
        assert!(stated <= 0.02 + 1e-6, "{stated}");
    }
    assert!(std::fs::metadata(&small).unwrap().len() < std::fs::metadata(&bake).unwrap().len());
    // Relit from the compressed form: the relighter says so, and the image stays close to the
    // uncompressed one.
    let relit = |b: &std::path::Path, exr: &str| {
        json(&run(prt()
            .arg("relight")
            .arg(&scene)
            .arg("--bake")
            .arg(b)
            .arg("--json")
            .arg("--out")
            .arg(dir.path().join(exr))))
    };
    relit(&bake, "full.exr");
    let r = relit(&small, "small.exr");
    let notes = r["notes"].to_string();
    assert!(
        notes.contains("diffuse relit from clustered PCA")
            && notes.contains("glossy relit from clustered PCA"),
        "{notes}"
    );
    let cmp = json(&run(prt()
        .arg("compare")
        .arg(dir.path().join("small.exr"))
        .arg(dir.path().join("full.exr"))
        .arg("--json")));
    let psnr = cmp["psnr_ldr"].as_f64().unwrap();
    assert!(
        psnr > 35.0,
        "compressed relighting PSNR {psnr} dB against uncompressed"
    );

    // To a relit-image target (the scene given): the smallest stored form whose images reach
    // 40 dB against the uncompressed bake's at 2 rotations. Measured again here through
    // `prt relight` and `prt compare` at one of them (0°): the same images, so ≥ 40 dB.
    let target = dir.path().join("target.prtb");
    let t = json(&run(prt()
        .arg("compress")
        .arg(&bake)
        .arg("--scene")
        .arg(&scene)
        .args(["--clusters", "4", "--rotations", "2", "--json", "--out"])
        .arg(&target)));
    assert!(t["min_psnr"].as_f64().unwrap() >= 40.0, "{t}");
    assert!(t["shade_ms_after"].as_f64().unwrap() > 0.0, "{t}");
    assert!(t["size_ratio"].as_f64().unwrap() < 1.0, "{t}");
    relit(&target, "target.exr");
    let psnr = common::psnr_ldr(&dir.path().join("target.exr"), &dir.path().join("full.exr"));
    assert!(psnr >= 40.0, "{psnr} dB");

    // Refusals: compressing twice, impossible options.
    let again = prt()
        .arg("compress")
        .arg(&small)
        .arg("--out")
        .arg(dir.path().join("again.prtb"))
        .output()
        .unwrap();
    let e = String::from_utf8_lossy(&again.stderr);
    assert!(
        !again.status.success() && e.contains("already compressed") && e.contains("small.prtb"),
        "{e}"
    );
    for bad in [
        &["--clusters", "0"][..],
        &["--error", "0"],
        &["--components", "99999"],
    ] {
        let out = prt()
            .arg("compress")
            .arg(&bake)
            .args(bad)
            .arg("--out")
            .arg(dir.path().join("bad.prtb"))
            .output()
            .unwrap();
        assert!(!out.status.success(), "{bad:?} accepted");
        assert!(!String::from_utf8_lossy(&out.stderr).contains("panicked"));
    }
    assert!(!dir.path().join("again.prtb").exists() && !dir.path().join("bad.prtb").exists());
}
