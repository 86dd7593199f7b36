//! Step 5 of a report: its plots (PSNR against time and against order, the ROI against
//! order, the error budget's shares) and its image grid.

use crate::budget::{BudgetRow, TERMS};
use crate::data::{ConvergencePoint, OrderRow};
use crate::error::ReportError;
use crate::plots::{image_grid, line_chart, stacked_shares, ChartOptions, Series, Tile};
use crate::run::Run;
use plotters::style::RGBColor;

const BLUE: RGBColor = RGBColor(31, 119, 180);
const ORANGE: RGBColor = RGBColor(255, 127, 14);
const GREEN: RGBColor = RGBColor(44, 160, 44);

/// The tiles the per-order relightings add to the image grid.
#[derive(Default)]
pub(crate) struct Tiles {
    /// Full order, per shown order.
    pub full: Vec<Tile>,
    /// Adaptive, per shown order.
    pub adaptive: Vec<Tile>,
    /// `|full − reference|`, per shown order.
    pub error: Vec<Tile>,
    /// `|adaptive − reference|` at the highest order.
    pub adaptive_error: Option<Tile>,
    /// The adaptive ROI at the highest order.
    pub roi: Option<Tile>,
}

/// Where infinite PSNRs (identical images) are drawn: a little above the highest finite value
/// of the rows and the convergence series.
fn psnr_cap(rows: &[OrderRow], convergence: &[ConvergencePoint]) -> f64 {
    let finite_max = rows
        .iter()
        .flat_map(|r| {
            [
                r.psnr_full_vs_reference,
                r.psnr_adaptive_vs_reference,
                r.psnr_adaptive_vs_full,
            ]
        })
        .chain(convergence.iter().map(|c| c.psnr_ldr))
        .filter(|v| v.is_finite())
        .fold(0.0f64, f64::max);
    (finite_max / 5.0).ceil() * 5.0 + 5.0
}

fn finite_or(v: f64, cap: f64) -> f64 {
    if v.is_finite() {
        v
    } else {
        cap
    }
}

/// Writes every plot of the report and its image grid (`images.png`).
pub(crate) fn write_figures(
    run: &Run,
    rows: &[OrderRow],
    convergence: &[ConvergencePoint],
    reference_noise_psnr: f64,
    error_budget: &[BudgetRow],
    tiles: Tiles,
    reference_tile: Tile,
) -> Result<(), ReportError> {
    let cap = psnr_cap(rows, convergence);
    let ceiling_line = vec![(reference_noise_psnr, "reference noise ceiling".to_string())];
    error_vs_time(run, rows, convergence, cap, ceiling_line.clone())?;
    psnr_vs_order(run, rows, cap, ceiling_line)?;
    roi_vs_order(run, rows)?;
    if !error_budget.is_empty() {
        budget_shares(run, error_budget)?;
    }
    grid(run, tiles, reference_tile)
}

/// `error_vs_time.png`: PSNR against time of path tracing and of both SH methods.
fn error_vs_time(
    run: &Run,
    rows: &[OrderRow],
    convergence: &[ConvergencePoint],
    cap: f64,
    ceiling_line: Vec<(f64, String)>,
) -> Result<(), ReportError> {
    line_chart(
        &run.out_dir.join("error_vs_time.png"),
        "PSNR against time (object pixels)",
        "time per image (path tracing) or per frame (SH shading), ms, log scale",
        "PSNR vs path-traced reference (dB, 8-bit sRGB)",
        &ChartOptions {
            log_x: true,
            hlines: ceiling_line,
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "path tracing (spp 1, 2, 4, …)".into(),
                points: convergence
                    .iter()
                    .map(|c| (c.ms, finite_or(c.psnr_ldr, cap)))
                    .collect(),
                colour: BLUE,
            },
            Series {
                label: "full-order SH (orders in --orders)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.full_ms, finite_or(r.psnr_full_vs_reference, cap)))
                    .collect(),
                colour: ORANGE,
            },
            Series {
                label: "adaptive SH (same orders)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.adaptive_ms, finite_or(r.psnr_adaptive_vs_reference, cap)))
                    .collect(),
                colour: GREEN,
            },
        ],
    )?;
    Ok(())
}

/// `psnr_vs_order.png`: PSNR of both methods against the reference and of adaptive against
/// full, per order.
fn psnr_vs_order(
    run: &Run,
    rows: &[OrderRow],
    cap: f64,
    ceiling_line: Vec<(f64, String)>,
) -> Result<(), ReportError> {
    let any_inf = rows.iter().any(|r| !r.psnr_adaptive_vs_full.is_finite());
    line_chart(
        &run.out_dir.join("psnr_vs_order.png"),
        "PSNR against SH order",
        "order (number of SH bands)",
        "PSNR (dB, 8-bit sRGB)",
        &ChartOptions {
            integer_x: true,
            hlines: ceiling_line,
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "full vs path traced (object pixels)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_full_vs_reference, cap)))
                    .collect(),
                colour: ORANGE,
            },
            Series {
                label: "adaptive vs path traced (object pixels)".into(),
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_adaptive_vs_reference, cap)))
                    .collect(),
                colour: GREEN,
            },
            Series {
                label: if any_inf {
                    format!("adaptive vs full (whole image; identical = ∞, drawn at {cap:.0})")
                } else {
                    "adaptive vs full (whole image)".into()
                },
                points: rows
                    .iter()
                    .map(|r| (r.order as f64, finite_or(r.psnr_adaptive_vs_full, cap)))
                    .collect(),
                colour: BLUE,
            },
        ],
    )?;
    Ok(())
}

/// `roi_vs_order.png`: the adaptive method's diffuse and specular ROI per order.
fn roi_vs_order(run: &Run, rows: &[OrderRow]) -> Result<(), ReportError> {
    line_chart(
        &run.out_dir.join("roi_vs_order.png"),
        &format!(
            "Region of interest of adaptive SH (threshold T = {})",
            run.settings.threshold
        ),
        "order (number of SH bands)",
        "points in the ROI (% of active points)",
        &ChartOptions {
            integer_x: true,
            legend_upper_left: true,
            ..ChartOptions::default()
        },
        &[
            Series {
                label: "diffuse ROI".into(),
                points: rows
                    .iter()
                    .filter_map(|r| r.roi_diffuse.map(|v| (r.order as f64, 100.0 * v)))
                    .collect(),
                colour: ORANGE,
            },
            Series {
                label: "specular ROI".into(),
                points: rows
                    .iter()
                    .filter_map(|r| r.roi_specular.map(|v| (r.order as f64, 100.0 * v)))
                    .collect(),
                colour: GREEN,
            },
        ],
    )?;
    Ok(())
}

/// `error_budget.png`: per order, the budget's terms stacked as shares of the total MSE.
fn budget_shares(run: &Run, error_budget: &[BudgetRow]) -> Result<(), ReportError> {
    let colours = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
    ];
    stacked_shares(
        &run.out_dir.join("error_budget.png"),
        "Error budget of full-order SH (what each approximation costs, % of the MSE)",
        "order (number of SH bands)",
        "% of the total MSE (object pixels, linear radiance)",
        &error_budget
            .iter()
            .map(|b| {
                (
                    b.order as f64,
                    b.total_mse,
                    TERMS.iter().map(|t| b.term(t)).collect(),
                )
            })
            .collect::<Vec<_>>(),
        &TERMS
            .iter()
            .zip(colours)
            .map(|(t, c)| (t.replace('_', " "), c))
            .collect::<Vec<_>>(),
    )?;
    Ok(())
}

/// `images.png`: one column per shown order — full, adaptive, |full − reference| — then the
/// reference, the adaptive error at the highest order and the ROI picture.
fn grid(run: &Run, tiles: Tiles, reference_tile: Tile) -> Result<(), ReportError> {
    let pad = |mut v: Vec<Tile>| {
        while !v.len().is_multiple_of(3) {
            v.push(Tile::blank());
        }
        v
    };
    let mut all = Vec::new();
    all.extend(pad(tiles.full));
    all.extend(pad(tiles.adaptive));
    all.extend(pad(tiles.error));
    all.push(reference_tile);
    all.extend(tiles.adaptive_error);
    all.extend(tiles.roi);
    image_grid(&run.out_dir.join("images.png"), &all, 3, 320)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(order: usize, full: f64, adaptive: f64, adaptive_vs_full: f64) -> OrderRow {
        OrderRow {
            order,
            coefficients: order * order,
            full_ms: 1.0,
            full_ms_range: [1.0, 1.0],
            adaptive_ms: 1.0,
            adaptive_ms_range: [1.0, 1.0],
            speedup: 1.0,
            psnr_adaptive_vs_full: adaptive_vs_full,
            psnr_full_vs_reference: full,
            psnr_adaptive_vs_reference: adaptive,
            rel_l2_full: 0.0,
            rel_l2_adaptive: 0.0,
            roi_diffuse: None,
            roi_specular: None,
            target: None,
        }
    }

    #[test]
    fn infinite_psnrs_are_drawn_above_the_highest_finite_value() {
        let point = |psnr_ldr| ConvergencePoint {
            spp: 1,
            ms: 1.0,
            psnr_ldr,
            rel_l2: 0.0,
        };
        // The highest finite value, 31.2, rounds up to 35 and gains 5 dB; ∞ is left out.
        let rows = [row(2, 25.0, 24.0, f64::INFINITY), row(4, 31.2, 30.0, 31.0)];
        assert_eq!(psnr_cap(&rows, &[point(f64::INFINITY)]), 40.0);
        // A value on a multiple of 5 still gains the margin.
        assert_eq!(psnr_cap(&rows[..1], &[point(12.0)]), 30.0);
        assert_eq!(psnr_cap(&[], &[]), 5.0);
        assert_eq!(finite_or(f64::INFINITY, 45.0), 45.0);
        assert_eq!(finite_or(12.5, 45.0), 12.5);
    }
}
