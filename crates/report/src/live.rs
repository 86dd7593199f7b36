//! The report's live page (`live.html`): its bake exported for WebGL2 (`prt export --target
//! webgl2`, SPEC §10.2, as `live.glb`) and shown by `prt view`'s page, with the path-traced
//! reference (`images/reference.png`) to switch to. `index.html` links to it.

use crate::error::ReportError;
use crate::run::Run;
use prt_bakefile::Bake;
use prt_compare::Image;

/// Writes `live.glb`, `images/reference.png` and `live.html`; returns the page's name, or a
/// note saying why there is none (an export refused: the page is an extra, the report's
/// numbers do not need it).
pub(crate) fn live_page(
    run: &Run,
    bake: &Bake,
    reference: &Image,
) -> Result<Result<String, String>, ReportError> {
    run.say("writing the live WebGL2 page (live.html)");
    let glb = run.out_dir.join("live.glb");
    if let Err(e) = prt_gltf::export_glb_for(run.scene, bake, &glb, prt_gltf::Target::Webgl2) {
        return Ok(Err(format!("no live page: the bake does not export ({e})")));
    }
    let png = run.out_dir.join("images/reference.png");
    prt_image::write_png(&png, reference, 0.0).map_err(|e| ReportError::Write {
        path: png.clone(),
        reason: e.to_string(),
    })?;
    let still = prt_gltf::viewer::Still {
        label: "path traced (the report's reference)".into(),
        png: std::fs::read(&png).map_err(|e| ReportError::Write {
            path: png.clone(),
            reason: e.to_string(),
        })?,
    };
    let page = run.out_dir.join("live.html");
    prt_gltf::viewer::write_page(&glb, &[still], &page).map_err(|e| ReportError::Write {
        path: page,
        reason: e.to_string(),
    })?;
    Ok(Ok("live.html".into()))
}
