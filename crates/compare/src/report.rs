//! The comparison report: one flat JSON object, or a table for people.

use crate::metrics::{ErrorStats, Metrics};
use crate::noise::{noise_corrected_rmse, NoiseEstimate, NoiseReport};
use serde_json::{Map, Value};

/// A number as JSON: non-finite values (infinite PSNR of identical images, undefined PSNR
/// against a black reference) become `null`, since JSON has no infinity.
#[must_use]
pub fn json_number(v: f64) -> Value {
    serde_json::Number::from_f64(v).map_or(Value::Null, Value::Number)
}

fn put_stats(map: &mut Map<String, Value>, prefix: &str, s: &ErrorStats) {
    for (key, v) in [
        ("psnr_ldr", s.psnr_ldr),
        ("psnr_hdr", s.psnr_hdr),
        ("rmse", s.rmse),
        ("rel_l2", s.rel_l2),
        ("mae", s.mae),
        ("max_abs", s.max_abs),
    ] {
        map.insert(format!("{prefix}{key}"), json_number(v));
    }
}

fn put_noise(map: &mut Map<String, Value>, prefix: &str, n: &NoiseEstimate, rmse: f64) {
    map.insert(format!("{prefix}noise_rmse"), json_number(n.rmse));
    if let Some(m) = n.rmse_of_mean {
        map.insert(format!("{prefix}noise_rmse_of_mean"), json_number(m));
    }
    map.insert(
        format!("{prefix}noise_psnr_hdr_ceiling"),
        json_number(n.psnr_hdr_ceiling),
    );
    map.insert(
        format!("{prefix}noise_psnr_ldr_ceiling"),
        json_number(n.psnr_ldr_ceiling),
    );
    map.insert(
        format!("{prefix}noise_corrected_rmse"),
        json_number(noise_corrected_rmse(rmse, n.rmse)),
    );
}

/// The report as one flat JSON object.
///
/// Keys: `psnr_ldr`, `psnr_hdr`, `rmse`, `rel_l2`, `mae`, `max_abs`, `width`, `height`,
/// `pixels`, `exposure_ev`, `psnr_hdr_peak`; with a mask also `masked_pixels` and the six
/// metrics prefixed `masked_`; with a noise estimate `noise_method`, `noise_rmse`,
/// `noise_rmse_of_mean` (pair method), `noise_psnr_hdr_ceiling`, `noise_psnr_ldr_ceiling`,
/// `noise_corrected_rmse` (and `masked_` versions). A PSNR is `null` when it is infinite
/// (identical images: then `rmse` is 0) or undefined (black reference).
#[must_use]
pub fn report_json(metrics: &Metrics, noise: Option<&NoiseReport>) -> Value {
    let mut map = Map::new();
    put_stats(&mut map, "", &metrics.whole);
    map.insert("width".into(), metrics.width.into());
    map.insert("height".into(), metrics.height.into());
    map.insert("pixels".into(), metrics.whole.pixels.into());
    map.insert("exposure_ev".into(), json_number(metrics.exposure_ev));
    map.insert("psnr_hdr_peak".into(), json_number(metrics.whole.hdr_peak));
    if let Some(m) = &metrics.masked {
        map.insert("masked_pixels".into(), m.pixels.into());
        put_stats(&mut map, "masked_", m);
        map.insert("masked_psnr_hdr_peak".into(), json_number(m.hdr_peak));
    }
    if let Some(n) = noise {
        map.insert("noise_method".into(), n.method.name().into());
        put_noise(&mut map, "", &n.whole, metrics.whole.rmse);
        if let (Some(nm), Some(m)) = (&n.masked, &metrics.masked) {
            put_noise(&mut map, "masked_", nm, m.rmse);
        }
    }
    Value::Object(map)
}

fn fmt_db(v: f64) -> String {
    if v.is_infinite() && v > 0.0 {
        "inf (identical)".into()
    } else if v.is_nan() {
        "undefined".into()
    } else {
        format!("{v:.3} dB")
    }
}

fn fmt_val(v: f64) -> String {
    // Seven significant digits; plain decimals for ordinary magnitudes.
    let a = v.abs();
    if v == 0.0 {
        "0".into()
    } else if !v.is_finite() {
        format!("{v}")
    } else if (1e-3..1e5).contains(&a) {
        let decimals = (6 - a.log10().floor() as i32).max(0) as usize;
        format!("{v:.decimals$}")
    } else {
        format!("{v:.6e}")
    }
}

/// The report as a text table for people: one column for the whole image, one for the mask.
#[must_use]
pub fn report_table(metrics: &Metrics, noise: Option<&NoiseReport>) -> String {
    let mut rows: Vec<(String, String, Option<String>)> = Vec::new();
    let w = &metrics.whole;
    let m = metrics.masked.as_ref();
    let mut row = |name: &str, f: &dyn Fn(&ErrorStats) -> String| {
        rows.push((name.into(), f(w), m.map(f)));
    };
    row("pixels", &|s| s.pixels.to_string());
    row("psnr_ldr (8-bit sRGB, peak 255)", &|s| fmt_db(s.psnr_ldr));
    row("psnr_hdr (linear, peak = ref max)", &|s| fmt_db(s.psnr_hdr));
    row("  peak", &|s| fmt_val(s.hdr_peak));
    row("rmse", &|s| fmt_val(s.rmse));
    row("rel_l2", &|s| fmt_val(s.rel_l2));
    row("mae", &|s| fmt_val(s.mae));
    row("max_abs", &|s| fmt_val(s.max_abs));
    if let Some(n) = noise {
        let nm = n.masked.as_ref();
        let mut nrow = |name: &str, f: &dyn Fn(&NoiseEstimate, &ErrorStats) -> String| {
            rows.push((name.into(), f(&n.whole, w), nm.zip(m).map(|(a, b)| f(a, b))));
        };
        nrow(
            &format!("reference noise rmse ({})", n.method.name()),
            &|e, _| fmt_val(e.rmse),
        );
        if n.whole.rmse_of_mean.is_some() {
            nrow("  rmse of the pair's mean", &|e, _| {
                e.rmse_of_mean.map_or("-".into(), fmt_val)
            });
        }
        nrow("  psnr_hdr ceiling", &|e, _| fmt_db(e.psnr_hdr_ceiling));
        nrow("  psnr_ldr ceiling (approx.)", &|e, _| {
            fmt_db(e.psnr_ldr_ceiling)
        });
        nrow("rmse corrected for noise", &|e, s| {
            fmt_val(noise_corrected_rmse(s.rmse, e.rmse))
        });
    }
    let name_w = rows.iter().map(|r| r.0.chars().count()).max().unwrap_or(0);
    let col_w = rows
        .iter()
        .map(|r| r.1.chars().count())
        .max()
        .unwrap_or(0)
        .max("whole image".len());
    let mut out = format!(
        "{} × {} pixels, LDR view at {} EV\n",
        metrics.width, metrics.height, metrics.exposure_ev
    );
    out += &format!("{:name_w$}  {:>col_w$}", "", "whole image");
    if m.is_some() {
        out += "  mask";
    }
    out.push('\n');
    for (name, whole, masked) in rows {
        out += &format!("{name:name_w$}  {whole:>col_w$}");
        if let Some(v) = masked {
            out += &format!("  {v}");
        }
        out.push('\n');
    }
    out
}
