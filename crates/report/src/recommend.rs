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
use prt_scene_relight::relit::RelightOptions;
use prt_scene_relight::Bound;
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
    // Bound once: every order's image from the same footprints, lightmaps and camera rays.
    let bound = Bound::new(scene, accel, bake)?;
    object_quality_with(scene, accel, bake, reference, orders, target, |order| {
        let r = bound.relight(&RelightOptions {
            order: Some(order),
            timing_frames: 1,
            warmup_frames: 0,
            ..RelightOptions::default()
        })?;
        Ok(bound.form_image(&r, 0.0)?)
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

/// The highest order `prt bake --target-psnr` bakes and chooses below.
pub const TARGET_HIGHEST_ORDER: usize = 13;

/// The path-traced reference a quality target is measured against: rendered until its own
/// noise ceiling is 6 dB above the target (so that its noise costs the measured PSNR at most
/// about 1 dB), with its ceiling and sample count.
struct TargetReference {
    image: Image,
    noise_ceiling_db: f64,
    spp: u32,
}

fn target_reference(
    scene: &Scene,
    settings: &prt_bake::BakeSettings,
    target: f64,
) -> Result<TargetReference, ReportError> {
    eprintln!(
        "target {target} dB: path-tracing a reference to a {} dB noise ceiling",
        target + 6.0
    );
    let rs = prt_tracer::RenderSettings {
        spp: 16384,
        bounces: settings.bounces as i32,
        seed: settings.seed,
        target_psnr_ldr: Some(target + 6.0),
        progress: true,
        ..Default::default()
    };
    let reference = prt_tracer::render(scene, &rs)?;
    Ok(TargetReference {
        image: Image {
            width: reference.width as usize,
            height: reference.height as usize,
            pixels: reference.radiance.iter().map(|v| v.to_array()).collect(),
        },
        noise_ceiling_db: reference.noise_psnr_ldr.unwrap_or(f64::NAN),
        spp: reference.settings.spp,
    })
}

/// The visible objects that no order meets the target on: `(name, "NAME reaches at most P
/// dB (order N)")`.
fn shortfalls(quality: &[ObjectQuality]) -> Vec<(String, String)> {
    quality
        .iter()
        .filter(|q| q.pixels > 0 && q.chosen.is_none())
        .map(|q| {
            (
                q.object.clone(),
                format!(
                    "{} reaches at most {:.2} dB (order {})",
                    q.object, q.best_psnr, q.best_order
                ),
            )
        })
        .collect()
}

fn joined(short: &[(String, String)], sep: &str, pick: fn(&(String, String)) -> &str) -> String {
    short.iter().map(pick).collect::<Vec<_>>().join(sep)
}

/// Each object's chosen order and the decision's reason (`kind`: why the bake is per pixel,
/// empty for a per-vertex bake).
fn chosen_orders(
    quality: &[ObjectQuality],
    target: f64,
    highest: usize,
    kind: &str,
) -> (Vec<usize>, Vec<String>) {
    quality
        .iter()
        .map(|q| {
            let (n, reason) = match q.chosen {
                Some(n) => (
                    n,
                    format!(
                        "lowest order whose PSNR against a path-traced reference over its {} pixels reaches {target} dB{}: {:.2} dB (order {highest}: {:.2} dB)",
                        q.pixels,
                        kind,
                        q.psnr_by_order.iter().find(|(o, _)| *o == n).map_or(f64::NAN, |x| x.1),
                        q.psnr_by_order.last().map_or(f64::NAN, |x| x.1)
                    ),
                ),
                None => (
                    highest,
                    format!("not visible from the scene camera, so its error cannot be measured: kept at order {highest}"),
                ),
            };
            eprintln!("target: {}: order {n} ({reason})", q.object);
            (n, reason)
        })
        .unzip()
}

/// `prt bake --target-psnr P`: from a bake at the highest order (`vertex`, per vertex), the
/// lowest order per object whose relit image meets `target` dB against a path-traced
/// reference over the object's pixels ([`object_quality`]); when per-vertex transfer cannot
/// meet it on some visible object, a per-pixel bake of the same settings instead (no
/// interpolation across triangles); the chosen bake truncated to those orders
/// ([`truncate_bake`]) with every decision in its file and report.
///
/// # Errors
/// [`ReportError::TargetUnmet`] when neither per-vertex nor per-pixel transfer meets the target
/// on every visible object up to the highest order (naming each and its best PSNR); the
/// render's, bake's and relighting's errors.
pub fn bake_to_target(
    scene: &Scene,
    accel: &Accel,
    vertex: prt_bake::BakeOutput,
    settings: &prt_bake::BakeSettings,
    target: f64,
) -> Result<prt_bake::BakeOutput, ReportError> {
    let highest = settings.order.unwrap_or(TARGET_HIGHEST_ORDER);
    let reference = target_reference(scene, settings, target)?;
    let orders: Vec<usize> = (1..=highest).collect();
    let mut chosen = vertex;
    let mut quality = object_quality(
        scene,
        accel,
        &chosen.bake,
        &reference.image,
        &orders,
        target,
    )?;
    let vertex_short = shortfalls(&quality);
    // Empty for a per-vertex result; else why the bake is per pixel.
    let mut kind = String::new();
    if !vertex_short.is_empty() {
        // Per-vertex transfer cannot: try per-pixel transfer (no interpolation across
        // triangles, the pixel footprint averaged), which a bake file holds for every object.
        eprintln!(
            "target: per-vertex falls short ({}); trying a per-pixel bake",
            joined(&vertex_short, "; ", |s| &s.1)
        );
        let pixel_settings = prt_bake::BakeSettings {
            points: prt_bake::PointKind::Pixel,
            // Every footprint sample needs one of the pixel's rays.
            pixel_samples: settings.pixel_samples.min(settings.rays).max(1),
            progress: true,
            ..settings.clone()
        };
        let pixel = prt_bake::bake(scene, accel, &pixel_settings)?;
        let pixel_quality =
            object_quality(scene, accel, &pixel.bake, &reference.image, &orders, target)?;
        let pixel_short = shortfalls(&pixel_quality);
        if !pixel_short.is_empty() {
            return Err(ReportError::TargetUnmet(format!(
                "--target-psnr {target} cannot be met up to order {highest}: per vertex {}; per pixel {} (reference {} spp, noise ceiling {:.1} dB); `prt report` splits that error into its terms",
                joined(&vertex_short, ", ", |s| &s.1),
                joined(&pixel_short, ", ", |s| &s.1),
                reference.spp,
                reference.noise_ceiling_db
            )));
        }
        chosen = pixel;
        quality = pixel_quality;
        kind = format!(
            ", in a per-pixel bake (per-vertex transfer falls short on {})",
            joined(&vertex_short, ", ", |s| &s.0)
        );
    }
    let (orders_out, reasons) = chosen_orders(&quality, target, highest, &kind);
    let mut out = truncate_bake(&chosen.bake, &orders_out, &reasons)?;
    if let serde_json::Value::Object(m) = &mut out.meta.settings {
        m.insert("target_psnr".into(), target.into());
        m.insert("order".into(), serde_json::Value::Null);
    }
    // The log's per-object lines and decisions follow the chosen kind and orders.
    for (o, obj) in chosen.report.objects.iter_mut().zip(&out.objects) {
        o.order = obj.order as usize;
    }
    chosen.report.decisions = out.meta.decisions.clone();
    chosen.bake = out;
    Ok(chosen)
}
