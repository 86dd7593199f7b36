//! Plots of the report (plotters, PNG, with the embedded DejaVu Sans so no system fonts are
//! needed): error against time, PSNR against order, ROI fraction against order, and the image
//! grid.

use crate::error::ReportError;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use std::path::Path;
use std::sync::Once;

static FONT: Once = Once::new();

fn font() {
    FONT.call_once(|| {
        // The bytes are a valid TTF shipped with the crate; registration only fails on invalid data.
        let _ = register_font(
            "sans-serif",
            FontStyle::Normal,
            include_bytes!("../assets/DejaVuSans.ttf"),
        );
    });
}

fn err(path: &Path, e: impl std::fmt::Display) -> ReportError {
    ReportError::Write {
        path: path.to_path_buf(),
        reason: e.to_string(),
    }
}

/// One named series of `(x, y)` points.
pub struct Series {
    /// Legend label.
    pub label: String,
    /// Points.
    pub points: Vec<(f64, f64)>,
    /// Colour.
    pub colour: RGBColor,
}

/// A line chart with markers: title, axis labels (with units), optional log-x, legend.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    log_x: bool,
    series: &[Series],
) -> Result<(), ReportError> {
    font();
    let pts: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|p| p.0.is_finite() && p.1.is_finite())
        .collect();
    if pts.is_empty() {
        return Err(ReportError::Invalid(format!(
            "{}: nothing to plot",
            path.display()
        )));
    }
    let (mut x0, mut x1) = pts
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (mut y0, mut y1) = pts
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    if log_x {
        x0 = x0.max(1e-6) / 1.5;
        x1 = x1.max(x0 * 2.0) * 1.5;
    } else {
        let pad = ((x1 - x0) * 0.05).max(0.5);
        x0 -= pad;
        x1 += pad;
    }
    let pad = ((y1 - y0) * 0.08).max(0.5);
    y0 -= pad;
    y1 += pad;
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let mut builder = ChartBuilder::on(&root);
        builder
            .caption(title, ("sans-serif", 24))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(70);
        macro_rules! draw {
            ($chart:expr) => {{
                let mut chart = $chart;
                chart
                    .configure_mesh()
                    .x_desc(x_label)
                    .y_desc(y_label)
                    .label_style(("sans-serif", 15))
                    .axis_desc_style(("sans-serif", 17))
                    .draw()
                    .map_err(|e| err(path, e))?;
                for s in series {
                    let colour = s.colour;
                    let data: Vec<(f64, f64)> = s
                        .points
                        .iter()
                        .copied()
                        .filter(|p| p.0.is_finite() && p.1.is_finite())
                        .collect();
                    chart
                        .draw_series(LineSeries::new(data.clone(), colour.stroke_width(2)))
                        .map_err(|e| err(path, e))?
                        .label(s.label.clone())
                        .legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(3))
                        });
                    chart
                        .draw_series(data.into_iter().map(|p| Circle::new(p, 4, colour.filled())))
                        .map_err(|e| err(path, e))?;
                }
                chart
                    .configure_series_labels()
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 16))
                    .position(SeriesLabelPosition::LowerRight)
                    .draw()
                    .map_err(|e| err(path, e))?;
            }};
        }
        if log_x {
            draw!(builder
                .build_cartesian_2d((x0..x1).log_scale(), y0..y1)
                .map_err(|e| err(path, e))?);
        } else {
            draw!(builder
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| err(path, e))?);
        }
        root.present().map_err(|e| err(path, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| err(path, e))
}

/// One tile of the image grid: 8-bit sRGB pixels and a caption.
pub struct Tile {
    /// Caption under the tile.
    pub caption: String,
    /// Width.
    pub width: u32,
    /// Height.
    pub height: u32,
    /// RGB8 pixels.
    pub pixels: Vec<[u8; 3]>,
}

/// Draws tiles in a grid of `columns`, each scaled to `tile_width` pixels wide (nearest), with
/// captions.
pub fn image_grid(
    path: &Path,
    tiles: &[Tile],
    columns: usize,
    tile_width: u32,
) -> Result<(), ReportError> {
    font();
    if tiles.is_empty() {
        return Err(ReportError::Invalid("empty image grid".into()));
    }
    let rows = tiles.len().div_ceil(columns);
    let aspect = tiles[0].height as f64 / tiles[0].width as f64;
    let tile_h = (f64::from(tile_width) * aspect).round() as u32;
    let cell_h = tile_h + 30;
    let (w, h) = (
        columns as u32 * (tile_width + 8) + 8,
        rows as u32 * cell_h + 8,
    );
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        for (k, t) in tiles.iter().enumerate() {
            let (cx, cy) = (
                (k % columns) as u32 * (tile_width + 8) + 8,
                (k / columns) as u32 * cell_h + 8,
            );
            let th = (f64::from(tile_width) * t.height as f64 / t.width as f64).round() as u32;
            for y in 0..th.min(tile_h) {
                for x in 0..tile_width {
                    let sx = (x as u64 * t.width as u64 / tile_width as u64) as u32;
                    let sy = (y as u64 * t.height as u64 / th.max(1) as u64) as u32;
                    let p =
                        t.pixels[(sy.min(t.height - 1) * t.width + sx.min(t.width - 1)) as usize];
                    root.draw_pixel(
                        ((cx + x) as i32, (cy + y) as i32),
                        &RGBColor(p[0], p[1], p[2]),
                    )
                    .map_err(|e| err(path, e))?;
                }
            }
            root.draw_text(
                &t.caption,
                &("sans-serif", 15).into_text_style(&root),
                ((cx) as i32, (cy + tile_h + 6) as i32),
            )
            .map_err(|e| err(path, e))?;
        }
        root.present().map_err(|e| err(path, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| err(path, e))
}
