//! Step 2 of a report: the bakes (cached): the one relit at every order and, for the error
//! budget, a second vertex bake with another seed and two per-pixel bakes, with the images
//! the budget compares at the highest order.

use crate::cache::cached_bake;
use crate::data::ObjectRays;
use crate::error::ReportError;
use crate::run::Run;
use glam::Vec3;
use prt_bake::{BakeSettings, PointKind};
use prt_bakefile::Bake;
use prt_scene_relight::imaging::RgbImage;
use prt_scene_relight::io::write_exr;
use std::path::PathBuf;

/// Sub-pixel positions of the budget's per-pixel bakes (the bake's rays are shared out over
/// them): enough that the pixel footprint's own sampling noise (silhouettes, contact edges)
/// stays well below the interpolation error it is compared with.
const BUDGET_PIXEL_SAMPLES: u32 = 256;

/// The bakes of a report.
pub(crate) struct Bakes {
    /// The per-vertex bake at the highest order, relit at every order.
    pub bake: Bake,
    /// Its file (in the cache).
    pub path: PathBuf,
    /// Bake time, s (0 when reused from the cache).
    pub seconds: f64,
    /// Whether it came from the cache.
    pub cached: bool,
    /// The error budget's bakes, when the budget is asked for.
    pub budget: Option<BudgetBakes>,
}

/// The error budget's bakes.
pub(crate) struct BudgetBakes {
    /// The per-vertex bake with the second seed.
    pub vertex_second: Bake,
    /// The per-pixel bake.
    pub pixel: Bake,
    /// The per-pixel bake with the second seed.
    pub pixel_second: Bake,
}

/// The error budget's per-pixel images at the highest order (linear radiance), and the
/// second-seed vertex bake its other experiments relight.
pub(crate) struct BudgetImages<'b> {
    /// The per-pixel bake's image.
    pub pixel: Vec<Vec3>,
    /// The second-seed per-pixel bake's image.
    pub pixel_second: Vec<Vec3>,
    /// The per-vertex bake with the second seed.
    pub vertex_second: &'b Bake,
}

/// Reads every bake the report needs from the cache, or bakes it.
pub(crate) fn bake_all(run: &Run) -> Result<Bakes, ReportError> {
    let s = run.settings;
    let bs = BakeSettings {
        order: Some(run.max_order),
        rays: s.rays,
        bounces: s.bounces,
        seed: s.seed,
        points: PointKind::Vertex,
        progress: s.progress,
        ..BakeSettings::final_quality()
    };
    let cached_bake = |bs: &BakeSettings, what: &str| {
        cached_bake(run.scene, &run.accel, run.out_dir, bs, what, s.progress)
    };
    let (bake, path, baked) = cached_bake(&bs, "bake")?;
    let second_seed = s.seed ^ 0x0b0d_9e75_eed5_eed5;
    let budget = if s.budget {
        let (vertex_second, _, _) = cached_bake(
            &BakeSettings {
                seed: second_seed,
                ..bs.clone()
            },
            "second-seed bake (error budget)",
        )?;
        let pixel = BakeSettings {
            points: PointKind::Pixel,
            pixel_samples: BUDGET_PIXEL_SAMPLES.min(s.rays),
            ..bs.clone()
        };
        let (p1, _, _) = cached_bake(&pixel, "per-pixel bake (error budget)")?;
        let (p2, _, _) = cached_bake(
            &BakeSettings {
                seed: second_seed,
                ..pixel
            },
            "second-seed per-pixel bake (error budget)",
        )?;
        Some(BudgetBakes {
            vertex_second,
            pixel: p1,
            pixel_second: p2,
        })
    } else {
        None
    };
    Ok(Bakes {
        bake,
        path,
        seconds: baked.unwrap_or(0.0),
        cached: baked.is_none(),
        budget,
    })
}

/// The per-pixel images at the highest order (the first also written to
/// `images/per_pixel_NN.exr`), when the budget is asked for.
pub(crate) fn budget_images<'b>(
    run: &Run,
    bakes: &'b Bakes,
) -> Result<Option<BudgetImages<'b>>, ReportError> {
    let Some(b) = &bakes.budget else {
        return Ok(None);
    };
    let max_order = run.max_order;
    let pixel = run.relit_image(&b.pixel, max_order)?;
    write_exr(
        &run.out_dir
            .join(format!("images/per_pixel_{max_order:02}.exr")),
        &RgbImage {
            width: run.width as usize,
            height: run.height as usize,
            pixels: pixel.iter().map(|v| v.to_array()).collect(),
        },
        &[
            ("kind", "per-pixel".into()),
            ("order", max_order.to_string()),
        ],
    )?;
    Ok(Some(BudgetImages {
        pixel,
        pixel_second: run.relit_image(&b.pixel_second, max_order)?,
        vertex_second: &b.vertex_second,
    }))
}

/// Per object, what the bake's rays met (from its ray statistics).
pub(crate) fn bake_rays(bake: &Bake) -> Vec<ObjectRays> {
    bake.meta
        .ray_stats
        .iter()
        .map(|r| ObjectRays {
            object: r.object.clone(),
            points: r.points,
            rays: r.rays,
            backface_fraction: r.backface_fraction(),
            inside_fraction: r.inside_fraction(),
            inside_points: r.inside_points,
        })
        .collect()
}
