//! `prt view`: a self-contained HTML page that relights an export live with WebGL2 from the
//! file alone (SPEC §10, §10.2): the `.glb` is embedded (base64) in `viewer.html`, whose
//! script parses it, rotates the environment's SH about +Y on the CPU each frame (by
//! quadrature: projecting the rotated function back onto the bands, exact for band-limited
//! functions), and shades each vertex's diffuse term (§10.1: transfer, albedo, the `pbr`
//! diffuse factor) and specular lobes (Phong and the fitted lobes: the `L ⊛ V` product
//! matrices built per frame on the CPU by quadrature, the lobes' bands at their axes) in a
//! vertex shader reading the transfer through one float texture — the §10.2 data texture, or
//! the `_PRT_C*`/`_PRT_V_*` attributes packed into that layout; lightmapped objects from
//! their coefficient textures (layers of one texture array, sampled bilinearly, offset and
//! scale folded into the frame's lighting). Path-traced stills can be embedded to switch to. `window.prtView` lets scripts turn the map, set the exposure
//! and read frame times (`tools/engine_check.py`).

use base64::Engine as _;
use std::path::Path;

/// The page, with `PRT_TITLE`, `PRT_GLB_BASE64` and `PRT_STILLS_JSON` to fill in.
const TEMPLATE: &str = include_str!("viewer.html");

/// A picture the page can show instead of the live relighting (a path-traced reference).
pub struct Still {
    /// What the page's menu calls it.
    pub label: String,
    /// A PNG file's bytes.
    pub png: Vec<u8>,
}

/// The page for the export `glb` (its bytes) titled `title`, with `stills`.
#[must_use]
pub fn page(glb: &[u8], title: &str, stills: &[Still]) -> String {
    let b64 = |bytes: &[u8]| base64::engine::general_purpose::STANDARD.encode(bytes);
    let stills: Vec<serde_json::Value> = stills
        .iter()
        .map(|s| {
            serde_json::json!({
                "label": s.label,
                "png": format!("data:image/png;base64,{}", b64(&s.png)),
            })
        })
        .collect();
    // `</` cannot close the script element from inside a JSON string.
    let stills_json = serde_json::to_string(&stills)
        .expect("JSON of strings")
        .replace("</", "<\\/");
    TEMPLATE
        .replace("PRT_TITLE", &html_escape(title))
        .replace("PRT_STILLS_JSON", &stills_json)
        .replace("PRT_GLB_BASE64", &b64(glb))
}

/// `text` safe inside HTML element content and attribute values.
fn html_escape(text: &str) -> String {
    text.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// Writes the page of the export at `glb_path` to `out`, atomically.
///
/// # Errors
/// The export cannot be read, is not a binary glTF 2.0 file with `extras.prt` (checked by
/// [`crate::read_export`]), or the page cannot be written.
pub fn write_page(
    glb_path: &Path,
    stills: &[Still],
    out: &Path,
) -> Result<(), prt_scene_relight::SceneRelightError> {
    let glb = std::fs::read(glb_path).map_err(|e| {
        prt_scene_relight::SceneRelightError::Invalid(format!("{}: {e}", glb_path.display()))
    })?;
    // Refuse what the page could not show, with the file named, before writing anything.
    crate::read_export(glb_path)?;
    let title = glb_path
        .file_name()
        .map_or_else(String::new, |n| n.to_string_lossy().into_owned());
    let html = page(&glb, &title, stills);
    prt_image::write_atomically(out, |w| {
        std::io::Write::write_all(w, html.as_bytes()).map_err(|e| e.to_string())
    })
    .map_err(|e| prt_scene_relight::SceneRelightError::Write {
        path: out.to_path_buf(),
        reason: e.to_string(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every placeholder is filled, the GLB travels as base64 that decodes to its bytes, and
    /// neither a title nor a still label can end the script or inject markup.
    #[test]
    fn the_page_embeds_the_file_and_escapes_what_it_quotes() {
        let glb = b"glTF\x02\x00\x00\x00 any bytes </script>";
        let page = page(
            glb,
            "<b>&",
            &[Still {
                label: "</script><script>alert(1)".into(),
                png: vec![0x89, b'P', b'N', b'G'],
            }],
        );
        assert!(!page.contains("PRT_TITLE") && !page.contains("PRT_GLB_BASE64"));
        assert!(!page.contains("PRT_STILLS_JSON"));
        assert!(page.contains("&lt;b&gt;&amp;"));
        assert!(!page.contains("</script><script>alert(1)"));
        let b64 = base64::engine::general_purpose::STANDARD.encode(glb);
        assert!(page.contains(&format!("\"{b64}\"")));
        assert_eq!(
            page.matches("</script>").count(),
            1,
            "only the page's own script ends"
        );
    }
}
