//! The report's `index.html`: one self-contained page (no network, works from `file://`) with
//! an HDR image viewer over every result (reference, full and adaptive SH per order, per-pixel
//! where made) — A/B flip and wipe, exposure and tone curves applied to the linear data,
//! zoom and pan with nearest-neighbour pixels, false-colour absolute and relative error with
//! its scale, a pixel probe showing every method's value — interactive SVG charts, sortable
//! tables and the settings as a list. The JavaScript and CSS are hand-written
//! (`assets/viewer.js`, `assets/viewer.css`); images travel as base64 little-endian f16
//! (half the size of f32, 11 bits of mantissa: 0.05 % relative, far below what an 8-bit view
//! or a probe reading shows).

use base64::Engine;
use serde::Serialize;
use std::fmt::Write;

/// One image the viewer offers: linear RGB, row-major from the top row.
#[derive(Clone, Debug)]
pub struct ViewerImage {
    /// Short identifier, e.g. `full_08`.
    pub id: String,
    /// What the menus and the probe call it.
    pub label: String,
    /// Linear RGB radiance, `width × height`.
    pub rgb: Vec<[f32; 3]>,
}

#[derive(Serialize)]
struct ImageJson<'a> {
    id: &'a str,
    label: &'a str,
}

#[derive(Serialize)]
struct ImagesJson<'a> {
    width: u32,
    height: u32,
    images: Vec<ImageJson<'a>>,
}

/// Largest finite f16; brighter values (a visible sun) are stored as this.
const F16_MAX: f32 = 65504.0;

fn encode_f16(rgb: &[[f32; 3]]) -> String {
    let mut bytes = Vec::with_capacity(rgb.len() * 6);
    for v in rgb.iter().flatten() {
        let x = if v.is_finite() {
            v.clamp(-F16_MAX, F16_MAX)
        } else {
            0.0
        };
        bytes.extend_from_slice(&half::f16::from_f32(x).to_le_bytes());
    }
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// JSON that can sit inside `<script type="application/json">`: `</` never appears.
fn script_json<T: Serialize>(v: &T) -> String {
    serde_json::to_string(v)
        .unwrap_or_else(|_| "null".into())
        .replace("</", "<\\/")
}

/// The page: `title`, a line about the machine's load while timing (`noisy` marks it),
/// `report_json` (the report data), the images, and `body_html` (the tables and text, whose
/// `<table class="sortable">` become sortable).
#[must_use]
pub fn page(
    title: &str,
    load_note: (&str, bool),
    report_json: &serde_json::Value,
    width: u32,
    height: u32,
    images: &[ViewerImage],
    body_html: &str,
) -> String {
    let images_json = ImagesJson {
        width,
        height,
        images: images
            .iter()
            .map(|im| ImageJson {
                id: &im.id,
                label: &im.label,
            })
            .collect(),
    };
    let mut s = String::with_capacity(images.len() * (width * height) as usize * 8 + 65536);
    let _ = writeln!(
        s,
        "<!doctype html><html lang=\"en\"><head><meta charset=\"utf-8\"><meta name=\"viewport\" content=\"width=device-width\"><title>{}</title><style>{}</style></head><body>",
        escape(title),
        include_str!("../assets/viewer.css")
    );
    let _ = writeln!(s, "<h1>{}</h1>", escape(title));
    let _ = writeln!(
        s,
        "<p class=\"load{}\">{}</p>",
        if load_note.1 { " noisy" } else { "" },
        escape(load_note.0)
    );
    s.push_str(VIEWER_HTML);
    s.push_str(body_html);
    s.push_str(
        "<div id=\"tooltip\" hidden></div>\n<script id=\"prt-report\" type=\"application/json\">",
    );
    s.push_str(&script_json(report_json));
    s.push_str("</script>\n<script id=\"prt-images\" type=\"application/json\">");
    s.push_str(&script_json(&images_json));
    s.push_str("</script>\n");
    // Each image's pixels in an element of its own, decoded only when first shown (the page
    // does not parse megabytes of JSON before it can draw).
    for (i, im) in images.iter().enumerate() {
        let _ = writeln!(
            s,
            "<script id=\"prt-image-{i}\" type=\"application/octet-stream\">{}</script>",
            encode_f16(&im.rgb)
        );
    }
    s.push_str("<script>");
    s.push_str(include_str!("../assets/viewer.js"));
    s.push_str("</script>\n</body></html>\n");
    s
}

/// The viewer's controls and the places the script fills.
const VIEWER_HTML: &str = r#"<h2>Images</h2>
<div class="controls">
<label>A <select id="pick-a"></select></label>
<label>B <select id="pick-b"></select></label>
<button id="swap" type="button">swap A/B</button>
<label>view <select id="mode"><option value="a">A</option><option value="b">B</option><option value="flip">flip A/B</option><option value="wipe">wipe A | B</option><option value="diff">|A − B|, false colour</option><option value="rel">relative error, false colour</option></select></label>
<button id="flip" type="button">flip (F)</button>
<label>wipe <input id="wipe" type="range" min="0" max="1" step="0.01" value="0.5"></label>
</div>
<div class="controls">
<label>exposure <input id="ev" type="range" min="-10" max="10" step="0.1" value="0"> <span id="ev-value"></span></label>
<label>tone curve <select id="tone"></select></label>
<label>error scale <input id="scale" size="8" placeholder="auto"></label>
<button id="fit" type="button">fit</button> <span id="zoom-level"></span>
</div>
<div class="viewer">
<div><div class="stage"><canvas id="view" width="640" height="480"></canvas></div>
<div id="caption"></div>
<div id="legend" hidden><span id="legend-min"></span><canvas id="legend-bar" width="240" height="12"></canvas><span id="legend-max"></span> <span id="legend-label"></span></div>
<p class="hint">Wheel: zoom about the cursor (nearest-neighbour pixels); drag: pan; F: flip A and B. Exposure and tone curve apply to the linear radiance (Rec. 709 primaries); the probe shows every image's linear value at the pixel under the cursor.</p></div>
<div class="probe"><div id="probe-xy">move the mouse over the image</div><table><thead><tr><th>image</th><th>R</th><th>G</th><th>B</th></tr></thead><tbody id="probe-body"></tbody></table></div>
</div>
<h2>Charts</h2>
<p>Hover a point or bar for its row.</p>
<div id="charts"></div>
<h2>Settings</h2>
<dl id="settings"></dl>
"#;

/// HTML escaping for text.
#[must_use]
pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f16_encoding_round_trips_within_half_precision_and_clamps() {
        let rgb = vec![
            [0.0, 1.0, 0.333_333],
            [1e-3, 70000.0, -2.5],
            [f32::NAN, 5.0, 65504.0],
        ];
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(encode_f16(&rgb))
            .unwrap();
        let back: Vec<f32> = bytes
            .chunks_exact(2)
            .map(|c| half::f16::from_le_bytes([c[0], c[1]]).to_f32())
            .collect();
        let want = [0.0, 1.0, 0.333_333, 1e-3, 65504.0, -2.5, 0.0, 5.0, 65504.0];
        for (b, w) in back.iter().zip(want) {
            // f16 keeps 11 significant bits: relative error ≤ 2⁻¹¹.
            assert!((b - w).abs() <= w.abs() * 2f32.powi(-11), "{b} vs {w}");
        }
    }

    #[test]
    fn embedded_json_cannot_close_its_script_element() {
        let v = serde_json::json!({ "note": "a </script><script>alert(1)</script>" });
        let s = script_json(&v);
        assert!(!s.contains("</"));
        let back: serde_json::Value = serde_json::from_str(&s).unwrap();
        assert_eq!(back, v);
    }
}
