//! Plots of the report (plotters, PNG, with the embedded DejaVu Sans so no system fonts are
//! needed): error against time, PSNR against order, ROI fraction against order, and the image
//! grid.

use crate::error::ReportError;
use glam::Vec3;
use plotters::prelude::*;
use plotters::style::{register_font, FontStyle};
use prt_compare::Image;
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

/// Layout options of [`line_chart`].
#[derive(Clone, Debug, Default)]
pub struct ChartOptions {
    /// Logarithmic x axis.
    pub log_x: bool,
    /// Integer x ticks (orders).
    pub integer_x: bool,
    /// Horizontal dashed reference lines `(y, label)`, drawn grey and named in the legend.
    pub hlines: Vec<(f64, String)>,
    /// Legend in the upper left instead of the lower right.
    pub legend_upper_left: bool,
}

/// Whether a point can be drawn: finite, and `x > 0` on a logarithmic axis.
fn plottable(p: (f64, f64), log_x: bool) -> bool {
    p.0.is_finite() && p.1.is_finite() && (!log_x || p.0 > 0.0)
}

/// The axis ranges `((x0, x1), (y0, y1))` of a chart: every drawable point and every finite
/// reference line strictly inside, with a margin (and headroom for an upper-left legend).
/// `None` when nothing can be drawn.
#[must_use]
pub fn chart_ranges(series: &[Series], opt: &ChartOptions) -> Option<((f64, f64), (f64, f64))> {
    let log_x = opt.log_x;
    let pts: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.points.iter().copied())
        .filter(|&p| plottable(p, log_x))
        .collect();
    let &(x_any, _) = pts.first()?;
    let lines = opt
        .hlines
        .iter()
        .filter(|h| h.0.is_finite())
        .map(|h| (x_any, h.0));
    let all: Vec<(f64, f64)> = pts.iter().copied().chain(lines).collect();
    let (mut x0, mut x1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.0), b.max(p.0)));
    let (mut y0, mut y1) = all
        .iter()
        .fold((f64::MAX, f64::MIN), |(a, b), p| (a.min(p.1), b.max(p.1)));
    if log_x {
        x0 /= 1.5;
        x1 = x1.max(x0 * 2.0) * 1.5;
    } else {
        let pad = ((x1 - x0) * 0.05).max(0.5);
        x0 -= pad;
        x1 += pad;
    }
    let pad = ((y1 - y0) * 0.08).max(0.5);
    y0 -= pad;
    y1 += pad;
    if opt.legend_upper_left {
        // Headroom for the legend above the data.
        y1 += (y1 - y0) * 0.4;
    }
    Some(((x0, x1), (y0, y1)))
}

/// Stacked bars of shares: for each `(x, total, parts)`, the parts as percentages of `total`
/// stacked from 0 (so a gap under or a bar over the dashed 100 % line shows what the parts do
/// not account for), one colour per part with the legend from `parts`.
pub fn stacked_shares(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    bars: &[(f64, f64, Vec<f64>)],
    parts: &[(String, RGBColor)],
) -> Result<(), ReportError> {
    font();
    if bars.is_empty() {
        return Err(ReportError::Invalid(format!(
            "{}: nothing to plot",
            path.display()
        )));
    }
    let share = |v: f64, total: f64| if total > 0.0 { 100.0 * v / total } else { 0.0 };
    let top = bars
        .iter()
        .map(|(_, t, p)| share(p.iter().map(|v| v.max(0.0)).sum(), *t))
        .fold(100.0f64, f64::max);
    let (x0, x1) = bars.iter().fold((f64::MAX, f64::MIN), |(a, b), (x, _, _)| {
        (a.min(*x), b.max(*x))
    });
    let (x0, x1) = (x0 - 0.7, x1 + 0.7);
    // Headroom for the legend.
    let y1 = top * 1.45;
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (900, 560)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, ("sans-serif", 22))
            .margin(16)
            .x_label_area_size(48)
            .y_label_area_size(70)
            .build_cartesian_2d(x0..x1, 0.0..y1)
            .map_err(|e| err(path, e))?;
        let ticks = ((x1 - x0).round() as usize + 1).clamp(2, 40);
        chart
            .configure_mesh()
            .x_desc(x_label)
            .y_desc(y_label)
            .x_labels(ticks)
            .x_label_formatter(&|x: &f64| {
                if (x - x.round()).abs() < 1e-6 {
                    format!("{x:.0}")
                } else {
                    String::new()
                }
            })
            .y_label_formatter(&|y: &f64| format!("{y:.0}"))
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .draw()
            .map_err(|e| err(path, e))?;
        for (k, (label, colour)) in parts.iter().enumerate() {
            let colour = *colour;
            let rects: Vec<Rectangle<(f64, f64)>> = bars
                .iter()
                .map(|(x, total, p)| {
                    let below: f64 = p[..k].iter().map(|v| share(v.max(0.0), *total)).sum();
                    let h = share(p[k].max(0.0), *total);
                    Rectangle::new([(x - 0.35, below), (x + 0.35, below + h)], colour.filled())
                })
                .collect();
            chart
                .draw_series(rects)
                .map_err(|e| err(path, e))?
                .label(label.clone())
                .legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 14, y + 5)], colour.filled())
                });
        }
        let grey = RGBColor(90, 90, 90);
        chart
            .draw_series(LineSeries::new(
                vec![(x0, 100.0), (x1, 100.0)],
                grey.stroke_width(2),
            ))
            .map_err(|e| err(path, e))?
            .label("total MSE (100 %)")
            .legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2))
            });
        chart
            .configure_series_labels()
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .label_font(("sans-serif", 15))
            .position(SeriesLabelPosition::UpperLeft)
            .draw()
            .map_err(|e| err(path, e))?;
        root.present().map_err(|e| err(path, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| err(path, e))
}

/// A line chart with markers: title, axis labels (with units), legend.
pub fn line_chart(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    opt: &ChartOptions,
    series: &[Series],
) -> Result<(), ReportError> {
    let log_x = opt.log_x;
    font();
    let Some(((x0, x1), (y0, y1))) = chart_ranges(series, opt) else {
        return Err(ReportError::Invalid(format!(
            "{}: nothing to plot",
            path.display()
        )));
    };
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
                let x_fmt = |x: &f64| {
                    if opt.integer_x {
                        if (x - x.round()).abs() < 1e-6 {
                            format!("{x:.0}")
                        } else {
                            String::new()
                        }
                    } else if x.abs() >= 10.0 {
                        format!("{x:.0}")
                    } else {
                        format!("{x}")
                    }
                };
                let x_ticks = if opt.integer_x {
                    ((x1 - x0).round() as usize + 1).clamp(2, 40)
                } else {
                    10
                };
                chart
                    .configure_mesh()
                    .x_desc(x_label)
                    .y_desc(y_label)
                    .x_labels(x_ticks)
                    .x_label_formatter(&x_fmt)
                    .y_label_formatter(&|y: &f64| format!("{y:.0}"))
                    .label_style(("sans-serif", 15))
                    .axis_desc_style(("sans-serif", 17))
                    .draw()
                    .map_err(|e| err(path, e))?;
                for (y, label) in &opt.hlines {
                    if !y.is_finite() {
                        continue;
                    }
                    let grey = RGBColor(110, 110, 110);
                    let (a, b) = (x0, x1);
                    let n = 60;
                    let dashes: Vec<Vec<(f64, f64)>> = (0..n)
                        .step_by(2)
                        .map(|k| {
                            let f = |k: usize| {
                                if log_x {
                                    a * (b / a).powf(k as f64 / n as f64)
                                } else {
                                    a + (b - a) * k as f64 / n as f64
                                }
                            };
                            vec![(f(k), *y), (f(k + 1), *y)]
                        })
                        .collect();
                    let mut first = true;
                    for d in dashes {
                        let anno = chart
                            .draw_series(LineSeries::new(d, grey.stroke_width(2)))
                            .map_err(|e| err(path, e))?;
                        if first {
                            anno.label(label.clone()).legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 20, y)], grey.stroke_width(2))
                            });
                            first = false;
                        }
                    }
                }
                for s in series {
                    let colour = s.colour;
                    let data: Vec<(f64, f64)> = s
                        .points
                        .iter()
                        .copied()
                        .filter(|&p| plottable(p, log_x))
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
                    .position(if opt.legend_upper_left {
                        SeriesLabelPosition::UpperLeft
                    } else {
                        SeriesLabelPosition::LowerRight
                    })
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

impl Tile {
    /// An empty cell.
    #[must_use]
    pub fn blank() -> Self {
        Self {
            caption: String::new(),
            width: 0,
            height: 0,
            pixels: Vec::new(),
        }
    }
}

/// Draws tiles in a grid of `columns`, each scaled to `tile_width` pixels wide (nearest) at its
/// own aspect ratio (so error pictures keep their colour bar), with captions. A tile of width 0
/// leaves its cell empty.
pub fn image_grid(
    path: &Path,
    tiles: &[Tile],
    columns: usize,
    tile_width: u32,
) -> Result<(), ReportError> {
    font();
    if tiles.iter().all(|t| t.width == 0) || columns == 0 {
        return Err(ReportError::Invalid("empty image grid".into()));
    }
    let shown_h = |t: &Tile| {
        if t.width == 0 {
            0
        } else {
            (f64::from(tile_width) * f64::from(t.height) / f64::from(t.width)).round() as u32
        }
    };
    let caption_h = 26;
    let row_h: Vec<u32> = tiles
        .chunks(columns)
        .map(|row| row.iter().map(shown_h).max().unwrap_or(0) + caption_h)
        .collect();
    let (w, h) = (
        columns as u32 * (tile_width + 8) + 8,
        row_h.iter().map(|r| r + 8).sum::<u32>() + 8,
    );
    let tmp = path.with_extension("tmp.png");
    {
        let root = BitMapBackend::new(&tmp, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(path, e))?;
        let mut y_top = 8;
        for (r, row) in tiles.chunks(columns).enumerate() {
            for (c, t) in row.iter().enumerate() {
                if t.width == 0 || t.height == 0 {
                    continue;
                }
                let (cx, cy) = (c as u32 * (tile_width + 8) + 8, y_top);
                let th = shown_h(t);
                for y in 0..th {
                    for x in 0..tile_width {
                        let sx = (u64::from(x) * u64::from(t.width) / u64::from(tile_width)) as u32;
                        let sy = (u64::from(y) * u64::from(t.height) / u64::from(th.max(1))) as u32;
                        let p = t.pixels
                            [(sy.min(t.height - 1) * t.width + sx.min(t.width - 1)) as usize];
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
                    (cx as i32, (cy + th + 5) as i32),
                )
                .map_err(|e| err(path, e))?;
            }
            y_top += row_h[r] + 8;
        }
        root.present().map_err(|e| err(path, e))?;
    }
    std::fs::rename(&tmp, path).map_err(|e| err(path, e))
}

/// The 8-bit sRGB view of a linear image (exposure 0) as a tile of the image grid.
pub(crate) fn srgb_tile(img: &Image, caption: String) -> Tile {
    let lin: Vec<Vec3> = img.pixels.iter().map(|p| Vec3::from_array(*p)).collect();
    let bytes = prt_tracer::output::to_srgb8(&lin, 0.0);
    Tile {
        caption,
        width: img.width as u32,
        height: img.height as u32,
        pixels: bytes.chunks_exact(3).map(|c| [c[0], c[1], c[2]]).collect(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn inside(r: ((f64, f64), (f64, f64)), p: (f64, f64)) -> bool {
        p.0 > r.0 .0 && p.0 < r.0 .1 && p.1 > r.1 .0 && p.1 < r.1 .1
    }

    /// Every drawable point and reference line lies strictly inside the axes, on linear and
    /// logarithmic x, with points that cannot be drawn (0 ms on a log axis, NaN, ∞) left out
    /// rather than stretching or escaping the axes.
    #[test]
    fn every_drawn_point_is_inside_the_axes() {
        let series = vec![
            Series {
                label: "a".into(),
                points: vec![(0.0, 31.0), (0.12, 20.0), (5.7, 33.0), (f64::NAN, 1.0)],
                colour: RGBColor(0, 0, 0),
            },
            Series {
                label: "b".into(),
                points: vec![(27.0, 8.7), (1500.0, 36.2), (3.0, f64::INFINITY)],
                colour: RGBColor(0, 0, 0),
            },
        ];
        for log_x in [false, true] {
            let opt = ChartOptions {
                log_x,
                hlines: vec![(45.3, "ceiling".into()), (f64::INFINITY, "none".into())],
                legend_upper_left: true,
                ..ChartOptions::default()
            };
            let r = chart_ranges(&series, &opt).expect("points");
            for s in &series {
                for &p in &s.points {
                    if plottable(p, log_x) {
                        assert!(inside(r, p), "{p:?} outside {r:?} (log_x {log_x})");
                    }
                }
            }
            assert!(inside(r, (1.0, 45.3)), "ceiling line outside {r:?}");
            assert!(log_x == (r.0 .0 > 0.0), "{r:?}");
        }
        let empty = [Series {
            label: "c".into(),
            points: vec![(0.0, 1.0)],
            colour: RGBColor(0, 0, 0),
        }];
        let opt = ChartOptions {
            log_x: true,
            ..ChartOptions::default()
        };
        assert!(chart_ranges(&empty, &opt).is_none());
    }
}
