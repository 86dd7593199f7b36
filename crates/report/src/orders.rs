//! Step 3 of a report: relighting at every order with full-order and adaptive SH, each timed
//! and measured against the path-traced reference (and, with a quality target, relit to it),
//! with the images, error pictures and ROI picture each order writes.

use crate::data::{OrderRow, TargetColumn};
use crate::error::ReportError;
use crate::figures::Tiles;
use crate::machine::{cpu_snapshot, TimingLoad};
use crate::plots::{srgb_tile, Tile};
use crate::run::{linear, Run};
use crate::viewer::ViewerImage;
use glam::Vec3;
use prt_bakefile::Bake;
use prt_compare::{compare, ErrorImageOptions, ErrorStats, Image};
use prt_relight::{AdaptiveParams, Threshold};
use prt_scene_relight::imaging::{roi_image, RgbImage};
use prt_scene_relight::io::{write_exr, write_png};
use prt_scene_relight::relit::{relight, RelightOptions, RelightStats, Relit};

/// What relighting at every order gave.
pub(crate) struct Relighting {
    /// One row per order.
    pub rows: Vec<OrderRow>,
    /// The full-order images (linear radiance), in the order of the settings' orders.
    pub full_images: Vec<Vec<Vec3>>,
    /// The relighter's notes, sorted, without repeats.
    pub notes: Vec<String>,
    /// The tiles of the image grid.
    pub tiles: Tiles,
    /// What else ran on the machine while every order was relit and timed.
    pub timing_load: Option<TimingLoad>,
}

/// Relights `bake` at every order of the settings, adding the images to the page's viewer.
pub(crate) fn relight_orders(
    run: &Run,
    bake: &Bake,
    reference: &Image,
    viewer_images: &mut Vec<ViewerImage>,
) -> Result<Relighting, ReportError> {
    let orders = &run.settings.orders;
    let show = shown_orders(orders, run.max_order);
    let mut out = Relighting {
        rows: Vec::new(),
        full_images: Vec::new(),
        notes: Vec::new(),
        tiles: Tiles::default(),
        timing_load: None,
    };
    let load_start = cpu_snapshot();
    for &order in orders {
        relight_order(
            run,
            bake,
            reference,
            order,
            show.contains(&order),
            viewer_images,
            &mut out,
        )?;
    }
    out.timing_load = load_start
        .zip(cpu_snapshot())
        .map(|(a, b)| TimingLoad::between(a, b));
    out.notes.sort();
    out.notes.dedup();
    Ok(out)
}

/// The orders the image grid shows: the first, the middle one of the list and the highest.
fn shown_orders(orders: &[usize], max_order: usize) -> Vec<usize> {
    let mut v = vec![orders[0], orders[orders.len() / 2], max_order];
    v.dedup();
    v
}

/// Relights at one order, full and adaptive (and to the quality target), measures both
/// against the reference, writes their images and adds the order's row, full-order image,
/// notes and, when the order is `shown` or the highest, its tiles.
fn relight_order(
    run: &Run,
    bake: &Bake,
    reference: &Image,
    order: usize,
    shown: bool,
    viewer_images: &mut Vec<ViewerImage>,
    out: &mut Relighting,
) -> Result<(), ReportError> {
    let (scene, accel, s) = (run.scene, &run.accel, run.settings);
    run.say(&format!("relighting at order {order}"));
    let full_opt = RelightOptions {
        order: Some(order),
        adaptive: None,
        rotate_y_deg: 0.0,
        timing_frames: s.timing_frames,
        warmup_frames: 2,
        rotate_y_step_deg: 0.0,
        points: None,
        ..Default::default()
    };
    let full = relight(scene, accel, bake, &full_opt)?;
    let ad_opt = RelightOptions {
        adaptive: Some(AdaptiveParams::new(if s.display_threshold {
            Threshold::Display {
                t: s.threshold,
                exposure_ev: 0.0,
            }
        } else {
            Threshold::Absolute(s.threshold)
        })),
        ..full_opt.clone()
    };
    let adaptive = relight(scene, accel, bake, &ad_opt)?;
    out.notes.extend(full.stats.notes.iter().cloned());
    let full_img = run.form(&full)?;
    let ad_img = run.form(&adaptive)?;
    viewer_images.push(ViewerImage {
        id: format!("full_{order:02}"),
        label: format!("full SH, order {order}"),
        rgb: full_img.pixels.clone(),
    });
    viewer_images.push(ViewerImage {
        id: format!("adaptive_{order:02}"),
        label: format!("adaptive SH, order {order}"),
        rgb: ad_img.pixels.clone(),
    });
    out.full_images.push(linear(&full_img));
    let (fi, ai) = (full_img.clone(), ad_img.clone());
    let target = match s.target_psnr {
        Some(p) => {
            let params = ad_opt.adaptive.expect("adaptive options");
            Some(target_column(
                run,
                bake,
                order,
                p,
                params,
                &fi,
                full.stats.shade_ms,
            )?)
        }
        None => None,
    };
    let m_full = compare(&fi, reference, Some(&run.mask))?
        .masked
        .expect("mask");
    let m_ad = compare(&ai, reference, Some(&run.mask))?
        .masked
        .expect("mask");
    let m_af = compare(&ai, &fi, None)?.whole;
    write_order_images(run, order, &full_img, &ad_img)?;
    if shown {
        out.tiles
            .full
            .push(srgb_tile(&fi, format!("full SH, order {order}")));
        out.tiles
            .adaptive
            .push(srgb_tile(&ai, format!("adaptive SH, order {order}")));
        out.tiles
            .error
            .push(error_picture(run, reference, &fi, "full", order)?);
    }
    if order == run.max_order {
        out.tiles.adaptive_error = Some(error_picture(run, reference, &ai, "adaptive", order)?);
        out.tiles.roi = Some(roi_picture(run, &adaptive, order)?);
    }
    out.rows.push(order_row(
        order,
        &full.stats,
        &adaptive.stats,
        [&m_af, &m_full, &m_ad],
        target,
    ));
    Ok(())
}

/// Adaptive relighting at `order` to the quality target `target_psnr` (against full order):
/// its cost, threshold and PSNR, measured against the full-order image `full`.
fn target_column(
    run: &Run,
    bake: &Bake,
    order: usize,
    target_psnr: f64,
    adaptive: AdaptiveParams,
    full: &Image,
    full_ms: f64,
) -> Result<TargetColumn, ReportError> {
    let study = prt_scene_relight::target::relight_to_target(
        run.scene,
        &run.accel,
        bake,
        &prt_scene_relight::target::TargetOptions {
            order: Some(order),
            adaptive,
            target_psnr,
            probe_pixels: 512,
            seed: run.settings.seed,
            rotations: vec![0.0],
            warmup_frames: 1,
            verify: false,
        },
    )?;
    let f = &study.frames[0];
    let shaded = study.last_frame.as_ref().expect("one frame shaded");
    let img = run.form(shaded)?;
    let m = compare(&img, full, None)?.whole;
    Ok(TargetColumn {
        target_psnr,
        ms: f.shade_ms,
        threshold: f.threshold,
        psnr_estimate: f.psnr_estimate,
        psnr_actual: m.psnr_ldr,
        speedup: full_ms / f.shade_ms.max(1e-9),
    })
}

/// Writes the order's full and adaptive images, as EXR and as PNG.
fn write_order_images(
    run: &Run,
    order: usize,
    full_img: &RgbImage,
    ad_img: &RgbImage,
) -> Result<(), ReportError> {
    let out_dir = run.out_dir;
    write_exr(
        &out_dir.join(format!("images/full_{order:02}.exr")),
        full_img,
        &[("kind", "full".into()), ("order", order.to_string())],
    )?;
    write_exr(
        &out_dir.join(format!("images/adaptive_{order:02}.exr")),
        ad_img,
        &[
            ("kind", "adaptive".into()),
            ("order", order.to_string()),
            ("threshold", run.settings.threshold.to_string()),
        ],
    )?;
    write_png(
        &out_dir.join(format!("images/full_{order:02}.png")),
        full_img,
        0.0,
    )?;
    write_png(
        &out_dir.join(format!("images/adaptive_{order:02}.png")),
        ad_img,
        0.0,
    )?;
    Ok(())
}

/// The luminance error of `image` (the `method`'s relighting at `order`) against the
/// reference on object pixels, written to `images/error_METHOD_NN.png`, as a grid tile.
fn error_picture(
    run: &Run,
    reference: &Image,
    image: &Image,
    method: &str,
    order: usize,
) -> Result<Tile, ReportError> {
    let err_opts = ErrorImageOptions {
        scale_max: Some(0.25),
        ..ErrorImageOptions::default()
    };
    let pic = prt_compare::render_error_picture(image, reference, Some(&run.mask), &err_opts)?;
    prt_compare::write_png_atomic(
        &run.out_dir
            .join(format!("images/error_{method}_{order:02}.png")),
        pic.width,
        pic.height,
        &pic.pixels,
    )?;
    Ok(Tile {
        caption: format!("|{method} {order} − path traced|, luminance"),
        width: pic.width as u32,
        height: pic.height as u32,
        pixels: pic.pixels,
    })
}

/// The adaptive relighting's ROI, written to `images/roi.png`, as a grid tile.
fn roi_picture(run: &Run, adaptive: &Relit, order: usize) -> Result<Tile, ReportError> {
    let roi = roi_image(run.scene, &run.accel, adaptive)?;
    write_png(&run.out_dir.join("images/roi.png"), &roi, 0.0)?;
    Ok(srgb_tile(
        &roi,
        format!("ROI, order {order}: red all bands, grey fewer"),
    ))
}

/// The order's row from the two relightings' figures and the errors (adaptive against full,
/// full and adaptive against the reference).
fn order_row(
    order: usize,
    full: &RelightStats,
    adaptive: &RelightStats,
    [adaptive_vs_full, full_vs_reference, adaptive_vs_reference]: [&ErrorStats; 3],
    target: Option<TargetColumn>,
) -> OrderRow {
    OrderRow {
        order,
        coefficients: order * order,
        full_ms: full.shade_ms,
        full_ms_range: [full.shade_ms_min, full.shade_ms_max],
        adaptive_ms: adaptive.shade_ms,
        adaptive_ms_range: [adaptive.shade_ms_min, adaptive.shade_ms_max],
        speedup: full.shade_ms / adaptive.shade_ms.max(1e-9),
        psnr_adaptive_vs_full: adaptive_vs_full.psnr_ldr,
        psnr_full_vs_reference: full_vs_reference.psnr_ldr,
        psnr_adaptive_vs_reference: adaptive_vs_reference.psnr_ldr,
        rel_l2_full: full_vs_reference.rel_l2,
        rel_l2_adaptive: adaptive_vs_reference.rel_l2,
        roi_diffuse: adaptive.roi_fraction_diffuse,
        roi_specular: adaptive.roi_fraction_specular,
        target,
    }
}

#[cfg(test)]
mod tests {
    use super::shown_orders;

    #[test]
    fn the_grid_shows_the_first_middle_and_highest_orders_once() {
        assert_eq!(shown_orders(&[2, 3, 4, 5, 6], 6), [2, 4, 6]);
        assert_eq!(shown_orders(&[2, 4], 4), [2, 4]);
        assert_eq!(shown_orders(&[7], 7), [7]);
        // The highest need not be last (only neighbours repeat, and the grid skips none).
        assert_eq!(shown_orders(&[8, 2, 3], 8), [8, 2, 8]);
    }
}
