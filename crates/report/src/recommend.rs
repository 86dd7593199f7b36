//! Modelling each object with only what it needs: per object, the PSNR against the path tracer
//! at every SH order of a bake (over the pixels the object covers), the lowest order that meets
//! a quality target, and the bake truncated to those orders (`prt bake --target-psnr P`).
//!
//! Truncation is exact: an order-`n` bake is the first `n²` coefficients of each channel of a
//! higher-order one (the bake estimates every coefficient from the same rays), so choosing
//! orders after baking at the highest costs one bake, not one per candidate. An object's pixels
//! depend on its own transfer only (interreflected light from other objects is already inside
//! it), so each object's order is chosen independently.

use crate::error::ReportError;
use prt_bakefile::{Bake, Decision};
use prt_compare::{compare, Image, Mask};
use prt_scene::Scene;
use prt_scene_relight::imaging::form_image;
use prt_scene_relight::io::to_compare_image;
use prt_scene_relight::relit::{relight, RelightOptions};
use prt_tracer::Accel;
use serde::Serialize;

/// One object's quality against the path tracer.
#[derive(Clone, Debug, Serialize)]
pub struct ObjectQuality {
    /// Object name.
    pub object: String,
    /// Pixels whose centre ray hits it.
    pub pixels: usize,
    /// `(order, psnr_ldr)` over its pixels, for every order tried.
    pub psnr_by_order: Vec<(usize, f64)>,
    /// The order with the highest PSNR (the lowest of equals).
    pub best_order: usize,
    /// That PSNR.
    pub best_psnr: f64,
    /// The lowest order that meets the target, if any.
    pub chosen: Option<usize>,
    /// The PSNR a per-pixel bake at the highest order reaches over the same pixels (the
    /// report's error-budget bake), when measured.
    pub per_pixel_psnr: Option<f64>,
}

/// Per object, the PSNR (8-bit view) of `image` against `reference` over the pixels whose
/// centre ray hits the object (NaN for an object no pixel shows).
///
/// # Errors
/// A camera the tracer refuses, or images of another size.
pub fn object_psnr(
    scene: &Scene,
    accel: &Accel,
    image: &Image,
    reference: &Image,
) -> Result<Vec<f64>, ReportError> {
    object_masks(scene, accel, reference)?
        .iter()
        .map(|m| {
            if m.count() == 0 {
                return Ok(f64::NAN);
            }
            Ok(compare(image, reference, Some(m))?
                .masked
                .map_or(f64::NAN, |s| s.psnr_ldr))
        })
        .collect()
}

pub use prt_scene_relight::imaging::object_ids;

/// Per object, the PSNR (8-bit view, its pixels) of full-order relighting of `bake` at each of
/// `orders` against `reference`, and the lowest order that reaches `target` dB.
///
/// # Errors
/// Relighting or comparison errors; an empty order list.
pub fn object_quality(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    reference: &Image,
    orders: &[usize],
    target: f64,
) -> Result<Vec<ObjectQuality>, ReportError> {
    object_quality_with(scene, accel, bake, reference, orders, target, |order| {
        let r = relight(
            scene,
            accel,
            bake,
            &RelightOptions {
                order: Some(order),
                timing_frames: 1,
                warmup_frames: 0,
                ..RelightOptions::default()
            },
        )?;
        Ok(to_compare_image(&form_image(scene, accel, &r, 0.0)?))
    })
}

/// [`object_quality`] with the image of each order from `image_at` (a caller that already
/// relit every order passes its images instead of relighting again).
///
/// # Errors
/// Errors of `image_at` or of the comparison; an empty order list.
pub fn object_quality_with(
    scene: &Scene,
    accel: &Accel,
    bake: &Bake,
    reference: &Image,
    orders: &[usize],
    target: f64,
    mut image_at: impl FnMut(usize) -> Result<Image, ReportError>,
) -> Result<Vec<ObjectQuality>, ReportError> {
    if orders.is_empty() {
        return Err(ReportError::Invalid("no order to evaluate".into()));
    }
    let masks = object_masks(scene, accel, reference)?;
    let mut quality: Vec<ObjectQuality> = bake
        .objects
        .iter()
        .zip(&masks)
        .map(|(obj, m)| ObjectQuality {
            object: obj.name.clone(),
            pixels: m.count(),
            psnr_by_order: Vec::new(),
            best_order: 0,
            best_psnr: f64::NEG_INFINITY,
            chosen: None,
            per_pixel_psnr: None,
        })
        .collect();
    for &order in orders {
        let img = image_at(order)?;
        for (q, m) in quality.iter_mut().zip(&masks) {
            if q.pixels == 0 {
                continue;
            }
            let p = compare(&img, reference, Some(m))?
                .masked
                .map_or(f64::NAN, |s| s.psnr_ldr);
            q.psnr_by_order.push((order, p));
            if p > q.best_psnr {
                q.best_psnr = p;
                q.best_order = order;
            }
            if q.chosen.is_none() && p >= target {
                q.chosen = Some(order);
            }
        }
    }
    Ok(quality)
}

/// Per object, the mask of the pixels whose centre ray hits it.
fn object_masks(scene: &Scene, accel: &Accel, like: &Image) -> Result<Vec<Mask>, ReportError> {
    let ids = object_ids(scene, accel)?;
    (0..scene.meshes.len())
        .map(|o| {
            Ok(Mask::from_bools(
                like.width,
                like.height,
                ids.iter().map(|&i| i == Some(o)).collect(),
            )?)
        })
        .collect()
}

/// `bake` with object `o` truncated to `orders[o]` (≤ its baked order) and a decision
/// recorded for each object that changed.
///
/// # Errors
/// An order of 0 or above the object's baked order, or a length mismatch.
pub fn truncate_bake(
    bake: &Bake,
    orders: &[usize],
    reasons: &[String],
) -> Result<Bake, ReportError> {
    if orders.len() != bake.objects.len() || reasons.len() != orders.len() {
        return Err(ReportError::Invalid(
            "one order and one reason per object".into(),
        ));
    }
    let mut out = bake.clone();
    for ((obj, &n), reason) in out.objects.iter_mut().zip(orders).zip(reasons) {
        let from = obj.order as usize;
        if n == 0 || n > from {
            return Err(ReportError::Invalid(format!(
                "object {}: order {n} is not between 1 and its baked order {from}",
                obj.name
            )));
        }
        let (f2, t2, ch) = (from * from, n * n, obj.channels as usize);
        for block in &mut obj.blocks {
            let points = block.data.len() / (ch * f2).max(1);
            let mut data = Vec::with_capacity(points * ch * t2);
            for p in 0..points {
                for c in 0..ch {
                    let s = (p * ch + c) * f2;
                    data.extend_from_slice(&block.data[s..s + t2]);
                }
            }
            block.data = data;
        }
        obj.order = n as u32;
        // This decision replaces the order the plan chose.
        out.meta.decisions.retain(|d| {
            !(d.object.as_deref() == Some(obj.name.as_str()) && d.decision.starts_with("order "))
        });
        out.meta.decisions.push(Decision {
            object: Some(obj.name.clone()),
            decision: format!("order {n}"),
            reason: reason.clone(),
        });
    }
    Ok(out)
}
