//! The report's Markdown (`report.md`, and the body of `index.html`): one function per
//! section, in the order the document gives them.

use crate::budget::{TERMS, TERM_HELP};
use crate::data::ReportData;
use crate::recommend::ObjectQuality;
use std::fmt::Write as _;

fn db(v: f64) -> String {
    if v.is_finite() {
        format!("{v:.2}")
    } else {
        "∞".into()
    }
}

fn pct(v: Option<f64>) -> String {
    v.map_or("–".into(), |v| format!("{:.1}", 100.0 * v))
}

/// The report in Markdown; `html_images`: for the page, which lists the settings and shows
/// the plots itself (a list of the static files instead of the plots).
pub(crate) fn markdown(d: &ReportData, html_images: bool) -> String {
    let mut s = String::new();
    header(&mut s, d, html_images);
    bake_rays(&mut s, d);
    per_order(&mut s, d);
    target_quality(&mut s, d);
    per_object(&mut s, d);
    error_budget(&mut s, d);
    convergence(&mut s, d);
    reproducing(&mut s, d);
    if let Some(rf) = &d.reflectance {
        s.push_str(&crate::rf_section::markdown(rf));
    }
    notes(&mut s, d);
    if html_images {
        static_files(&mut s, d);
    } else {
        plots_and_images(&mut s, d);
    }
    s
}

/// The title, the machine, the settings, the reference and the bake.
fn header(s: &mut String, d: &ReportData, html_images: bool) {
    let _ = writeln!(s, "# Speed against error: `{}`\n", d.scene);
    if let Some(page) = &d.live_page {
        let _ = writeln!(
            s,
            "Live relighting in the browser (WebGL2, the bake exported with `--target webgl2`; turn the map, change the exposure, switch to the path-traced reference): [{page}]({page}).\n"
        );
    }
    let _ = writeln!(
        s,
        "Machine: {} logical cores, {}.  ",
        d.machine.cores, d.machine.cpu
    );
    if let Some(l) = &d.machine.timing_load {
        let _ = writeln!(s, "{}.  ", l.sentence(d.machine.cores));
    }
    if !html_images {
        // The HTML page lists the settings itself.
        let _ = writeln!(s, "Settings: `{}`.\n", d.settings);
    } else {
        s.push('\n');
    }
    let r = &d.reference;
    let _ = writeln!(
        s,
        "Reference: path traced, {} spp in {:.2} s{}; its own Monte Carlo noise on object pixels (from its two half images) is RMSE {:.4}, a PSNR ceiling of {} dB for any method compared with it{}.  ",
        r.spp,
        r.seconds,
        if r.cached { " (cached)" } else { "" },
        d.reference_noise_rmse,
        db(r.noise_psnr_ldr),
        match (r.target_psnr_ldr, r.target_met) {
            (Some(t), Some(false)) => format!(" — short of the {t} dB target: it stopped at the sample cap (raise --reference-spp)"),
            (Some(t), _) => format!(" (rendered to reach {t} dB)"),
            _ => String::new(),
        }
    );
    let _ = writeln!(
        s,
        "Bake: `{}` ({}).\n",
        d.bake_file,
        if d.bake_cached {
            "reused from the cache".to_string()
        } else {
            format!("baked in {:.2} s", d.bake_seconds)
        }
    );
}

/// Per object, what the bake's rays met.
fn bake_rays(s: &mut String, d: &ReportData) {
    if d.bake_rays.is_empty() {
        return;
    }
    let _ = writeln!(s, "## Bake rays per object\n");
    let _ = writeln!(s, "A closed, well-oriented mesh has no back-face hits and no rays started inside geometry; large values point at inverted normals, holes or interpenetrating objects.\n");
    let _ = writeln!(
        s,
        "| object | points | rays | back-face hits % | rays started inside geometry % (points) |\n|---|---:|---:|---:|---:|"
    );
    for r in &d.bake_rays {
        let _ = writeln!(
            s,
            "| {} | {} | {} | {:.3} | {:.3} ({}) |",
            r.object,
            r.points,
            r.rays,
            100.0 * r.backface_fraction,
            100.0 * r.inside_fraction,
            r.inside_points
        );
    }
    let _ = writeln!(s);
}

/// The per-order table: times and PSNRs of full-order and adaptive SH.
fn per_order(s: &mut String, d: &ReportData) {
    let _ = writeln!(s, "## Per order (cf. Lee & Kim 2014, Tables 6.1 and 6.2)\n");
    let _ = writeln!(s, "PSNR is `psnr_ldr` (8-bit sRGB, peak 255); against the reference it is over object pixels only, adaptive vs full over the whole image.\n");
    let _ = writeln!(
        s,
        "Times are the median of {} frames, with the fastest and slowest in brackets.\n",
        d.settings["timing_frames"]
    );
    let _ = writeln!(s, "| order | coefficients | full ms/frame | adaptive ms/frame | speed-up | PSNR adaptive vs full | PSNR full vs path traced | PSNR adaptive vs path traced | ROI diffuse % | ROI specular % |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|");
    for r in &d.orders {
        let _ = writeln!(
            s,
            "| {} | {} | {:.3} [{:.3}–{:.3}] | {:.3} [{:.3}–{:.3}] | {:.2}× | {} | {} | {} | {} | {} |",
            r.order,
            r.coefficients,
            r.full_ms,
            r.full_ms_range[0],
            r.full_ms_range[1],
            r.adaptive_ms,
            r.adaptive_ms_range[0],
            r.adaptive_ms_range[1],
            r.speedup,
            db(r.psnr_adaptive_vs_full),
            db(r.psnr_full_vs_reference),
            db(r.psnr_adaptive_vs_reference),
            pct(r.roi_diffuse),
            pct(r.roi_specular)
        );
    }
}

/// The target-quality table, when the rows have the column.
fn target_quality(s: &mut String, d: &ReportData) {
    if !d.orders.iter().any(|r| r.target.is_some()) {
        return;
    }
    let _ = writeln!(
        s,
        "\n## Target quality (adaptive relighting to a PSNR against full order)\n"
    );
    let _ = writeln!(s, "`prt relight --adaptive --target-psnr P` picks the frame's threshold from an estimate on 512 random object pixels relit at full order (their cost included); the PSNR reached is measured against the full-order image of the row. The honest baseline is the lowest uniform order that meets the same target (the PSNR-against-order plot).\n");
    let _ = writeln!(s, "| order | target dB | ms/frame | speed-up vs full | threshold | PSNR estimate | PSNR reached |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|");
    for r in &d.orders {
        if let Some(t) = &r.target {
            let _ = writeln!(
                s,
                "| {} | {} | {:.3} | {:.2}× | {} | {} | {} |",
                r.order,
                t.target_psnr,
                t.ms,
                t.speedup,
                if t.threshold > 0.0 {
                    format!("{:.4}", t.threshold)
                } else {
                    "full order".into()
                },
                db(t.psnr_estimate),
                db(t.psnr_actual)
            );
        }
    }
}

/// Per object: its PSNR per order and what it needs.
fn per_object(s: &mut String, d: &ReportData) {
    if d.recommendation.is_empty() {
        return;
    }
    let target = d
        .orders
        .iter()
        .find_map(|r| r.target.as_ref().map(|t| t.target_psnr));
    let _ = writeln!(s, "\n## Per object: what each needs\n");
    let _ = writeln!(s, "PSNR against the path tracer over each object's pixels (8-bit view) at every order of the bake; the lowest order within 0.5 dB of the object's best is where more bands stop paying; `prt bake --target-psnr P` keeps per object the lowest order that reaches P.\n");
    let _ = writeln!(s, "| object | pixels | best PSNR per vertex (order) | lowest order within 0.5 dB of it | lowest order reaching {} | per pixel at the highest order | recommendation |", target.map_or("the target".into(), |t| format!("{t} dB")));
    let _ = writeln!(s, "|---|---:|---:|---:|---:|---:|---|");
    for q in &d.recommendation {
        if q.pixels == 0 {
            let _ = writeln!(s, "| {} | 0 | – | – | not visible | – | keep the highest order (its error cannot be measured from this camera) |", q.object);
            continue;
        }
        let near = q
            .psnr_by_order
            .iter()
            .find(|(_, p)| *p >= q.best_psnr - 0.5)
            .map_or(q.best_order, |(o, _)| *o);
        let per_pixel = q.per_pixel_psnr;
        let advice = advice(q, near, target);
        let _ = writeln!(
            s,
            "| {} | {} | {} ({}) | {} | {} | {} | {} |",
            q.object,
            q.pixels,
            db(q.best_psnr),
            q.best_order,
            near,
            q.chosen.map_or_else(
                || format!("not reachable (best {})", db(q.best_psnr)),
                |o| o.to_string()
            ),
            per_pixel.map_or("–".into(), db),
            advice
        );
    }
}

/// What an object visible from the camera needs: per vertex at the order chosen for the
/// target, per pixel when only that reaches it, else the closest it gets (`near`: the lowest
/// order within 0.5 dB of its best).
fn advice(q: &ObjectQuality, near: usize, target: Option<f64>) -> String {
    match (q.chosen, q.per_pixel_psnr, target) {
        (Some(o), _, Some(t)) => format!("per vertex, order {o} (reaches {t} dB)"),
        (None, Some(pp), Some(t)) if pp >= t => {
            format!("per pixel (reaches {t} dB; per vertex cannot)")
        }
        (None, Some(pp), _) if pp > q.best_psnr + 0.5 => format!(
            "not reachable; per pixel gets closest ({}), else per vertex order {near}",
            db(pp)
        ),
        _ => format!(
            "not reachable: per vertex order {near} gets within 0.5 dB of the best this bake allows ({}); the error budget names what limits it",
            db(q.best_psnr)
        ),
    }
}

/// The error budget's tables: what each approximation costs, and each component's own size.
fn error_budget(s: &mut String, d: &ReportData) {
    if d.error_budget.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Error budget of full-order SH\n");
    let _ = writeln!(s, "{}\n", d.error_budget_summary);
    let _ = writeln!(s, "Mean squared error against the path tracer over object pixels, linear radiance, split into terms measured by controlled experiments on this scene:\n");
    for (name, help) in TERM_HELP {
        let _ = writeln!(s, "- `{name}`: {help}");
    }
    let _ = writeln!(s, "\nEach term is what that approximation costs: starting from the reference's noise, each experiment adds the error it brings, so the terms add up to the total (`unaccounted` is what a negative cost, shown as 0, leaves). `cross` is from the second table: the error components' own sizes (the MSE of each controlled difference) add up to the total only when they are uncorrelated, and cross = total − Σ sizes says how much their correlations take.\n");
    let _ = write!(s, "| order | total MSE |");
    for t in TERMS {
        let _ = write!(s, " {t} |");
    }
    let _ = writeln!(s, " unaccounted % | cross % | largest |");
    let _ = writeln!(s, "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|");
    for b in &d.error_budget {
        let pc = |v: f64| 100.0 * v / b.total_mse.max(f64::MIN_POSITIVE);
        let _ = write!(s, "| {} | {:.3e} |", b.order, b.total_mse);
        for t in TERMS {
            let _ = write!(s, " {:.2e} ({:.0} %) |", b.term(t), pc(b.term(t)));
        }
        let _ = writeln!(
            s,
            " {:+.1} | {:+.1} | {} |",
            pc(b.unaccounted),
            pc(b.cross_terms),
            b.largest
        );
    }
    let _ = writeln!(
        s,
        "\nThe error components' own sizes (MSE of each controlled difference):\n"
    );
    let _ = write!(s, "| order |");
    for t in TERMS {
        let _ = write!(s, " {t} |");
    }
    let _ = writeln!(s, "\n|---:|---:|---:|---:|---:|---:|");
    for b in &d.error_budget {
        let _ = write!(s, "| {} |", b.order);
        for t in TERMS {
            let _ = write!(s, " {:.2e} |", b.direct(t));
        }
        let _ = writeln!(s);
    }
}

/// The path tracer's convergence table.
fn convergence(s: &mut String, d: &ReportData) {
    let _ = writeln!(
        s,
        "\n## Path tracing convergence (another seed against the reference)\n"
    );
    let _ = writeln!(
        s,
        "| spp | ms | PSNR (dB) | relative L2 |\n|---:|---:|---:|---:|"
    );
    for c in &d.convergence {
        let _ = writeln!(
            s,
            "| {} | {:.1} | {} | {:.4} |",
            c.spp,
            c.ms,
            db(c.psnr_ldr),
            c.rel_l2
        );
    }
}

/// How to reproduce the first row by hand.
fn reproducing(s: &mut String, d: &ReportData) {
    let Some(r) = d.orders.first() else {
        return;
    };
    let _ = writeln!(s, "\n## Reproducing a row by hand\n");
    let _ = writeln!(
        s,
        "The relit images are `images/full_NN.exr` and `images/adaptive_NN.exr`, the object mask `images/mask.png`. For order {o}:\n",
        o = r.order
    );
    let _ = writeln!(
        s,
        "    prt relight {scene} --bake {bake} --order {o} --out full_{o:02}.exr\n    prt compare full_{o:02}.exr images/reference.exr --mask images/mask.png\n",
        scene = d.scene,
        bake = d.bake_file,
        o = r.order
    );
    let _ = writeln!(
        s,
        "gives `masked_psnr_ldr` = {} dB (the table's \"PSNR full vs path traced\"); add `--adaptive --threshold {}{}` for the adaptive column.",
        db(r.psnr_full_vs_reference),
        d.settings["threshold"],
        if d.settings["threshold_kind"].as_str().is_some_and(|k| k.starts_with("display")) {
            " --display-threshold"
        } else {
            ""
        }
    );
}

/// The relighter's notes.
fn notes(s: &mut String, d: &ReportData) {
    if d.notes.is_empty() {
        return;
    }
    let _ = writeln!(s, "\n## Notes\n");
    for n in &d.notes {
        let _ = writeln!(s, "- {n}");
    }
}

/// For the page: the list of the static files (the page's viewer and interactive charts take
/// the place of the static plots).
fn static_files(s: &mut String, d: &ReportData) {
    let _ = writeln!(
        s,
        "\n## Static files\n\nThe same plots as PNG files: error_vs_time.png, psnr_vs_order.png, roi_vs_order.png{}{}, and images.png (an image grid){}; every image as EXR in images/.",
        if d.error_budget.is_empty() { "" } else { ", error_budget.png" },
        if d.reflectance.is_none() { "" } else { ", rf_psnr_vs_coefficients.png, rf_error_vs_coefficients.png, rf_h1_vs_coefficients.png" },
        if d.reflectance.is_none() { "" } else { " and rf_images.png (one tile per reflectance-field method)" }
    );
}

/// The plots and the image grid, for `report.md`.
fn plots_and_images(s: &mut String, d: &ReportData) {
    let img = |s: &mut String, file: &str, alt: &str| {
        let _ = writeln!(s, "![{alt}]({file})\n");
    };
    let _ = writeln!(s, "\n## Plots and images\n");
    img(s, "error_vs_time.png", "error against time");
    img(s, "psnr_vs_order.png", "PSNR against order");
    img(s, "roi_vs_order.png", "ROI against order");
    if !d.error_budget.is_empty() {
        img(s, "error_budget.png", "error budget per order");
    }
    img(
        s,
        "images.png",
        "reference, relit images, error images and ROI",
    );
    if d.reflectance.is_some() {
        img(
            s,
            "rf_psnr_vs_coefficients.png",
            "reflectance fields and per-pixel SH against coefficients",
        );
        img(
            s,
            "rf_error_vs_coefficients.png",
            "compression error (L2) against coefficients",
        );
        img(
            s,
            "rf_h1_vs_coefficients.png",
            "compression error (H1) against coefficients",
        );
        img(s, "rf_images.png", "one image per reflectance-field method");
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_objects_advice_follows_what_reaches_the_target() {
        let q = |chosen, per_pixel_psnr| ObjectQuality {
            object: "teapot".into(),
            pixels: 100,
            psnr_by_order: vec![(2, 20.0), (4, 27.8), (6, 28.0)],
            best_order: 6,
            best_psnr: 28.0,
            chosen,
            per_pixel_psnr,
        };
        assert_eq!(
            advice(&q(Some(4), None), 4, Some(27.5)),
            "per vertex, order 4 (reaches 27.5 dB)"
        );
        assert_eq!(
            advice(&q(None, Some(31.0)), 4, Some(30.0)),
            "per pixel (reaches 30 dB; per vertex cannot)"
        );
        assert_eq!(
            advice(&q(None, Some(29.0)), 4, Some(30.0)),
            "not reachable; per pixel gets closest (29.00), else per vertex order 4"
        );
        // Per pixel no better than per vertex (within 0.5 dB): the lowest order near the best.
        assert!(advice(&q(None, Some(28.2)), 4, Some(30.0))
            .starts_with("not reachable: per vertex order 4 gets within 0.5 dB of the best this bake allows (28.00)"));
        assert_eq!(db(f64::INFINITY), "∞");
        assert_eq!(pct(None), "–");
        assert_eq!(pct(Some(0.125)), "12.5");
    }
}
