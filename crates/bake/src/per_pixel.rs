//! The per-pixel path: at the primary hits of every pixel's footprint samples, direct rays
//! plus the last bounce gathered from the vertex chain, averaged over the footprint per object.
//! At a normal-mapped hit the map's shading normal (as the path tracer orients it towards the
//! camera) is the transfer's cosine and hemisphere, and directions below the geometric surface
//! are blocked.

use crate::assembly::{BakedObject, Objects};
use crate::error::BakeError;
use crate::material::material_binding;
use crate::report::ObjectReport;
use crate::rows::{add_scaled, point_blocks, point_stats, store};
use crate::setup::Setup;
use crate::transfer::{self, direct_sided, gather, DirectOptions, MeshTransfer};
use prt_bakefile::{Coverage, ObjectBake, RayStats};
use prt_scene::binding::{geometry_hash, mesh_geometry};
use prt_scene::SurfacePoint;
use prt_tracer::points::{PixelFootprints, SamplePoint};
use rayon::prelude::*;

/// The footprint-averaged transfer of one object in one pixel (`1/K` times the sum over the
/// pixel's samples that hit the object; samples that hit another object or nothing add 0).
struct PixelTransfer {
    mesh: usize,
    /// `channels × order²`.
    diffuse: Vec<f64>,
    /// `order²` (the same for every channel).
    visibility: Option<Vec<f64>>,
    /// `order²`.
    unshadowed: Option<Vec<f64>>,
    hits: u64,
    /// Over the samples that hit the object.
    stats: RayStats,
}

impl PixelTransfer {
    fn new(
        mesh: usize,
        diffuse: usize,
        visibility: Option<usize>,
        unshadowed: Option<usize>,
    ) -> Self {
        Self {
            mesh,
            diffuse: vec![0.0; diffuse],
            visibility: visibility.map(|n| vec![0.0; n]),
            unshadowed: unshadowed.map(|n| vec![0.0; n]),
            hits: 0,
            stats: RayStats::default(),
        }
    }
}

/// A per-pixel bake's objects: every object's transfer at this shard's pixels, gathering the
/// last bounce from the vertex levels `chain`.
pub(crate) fn pixel_objects(
    setup: &Setup<'_>,
    chain: &[Vec<MeshTransfer>],
) -> Result<Objects, BakeError> {
    let settings = setup.settings;
    let k = settings.pixel_samples;
    let footprints =
        prt_tracer::points::pixel_footprints(setup.scene, setup.accel, settings.seed, k)?;
    let (first, count) = settings.shard_range(footprints.pixel_count() as u64);
    let pixels = Pixels {
        setup,
        chain,
        footprints: &footprints,
        first: first as usize,
        count: count as usize,
        channels: if settings.bounces > 0 { 3 } else { 1 },
    };
    let bar = settings.progress_bar(count, "pixels");
    // Per pixel: the footprint-averaged transfer of every object its samples hit.
    let results: Vec<Vec<PixelTransfer>> = (pixels.first..pixels.first + pixels.count)
        .into_par_iter()
        .with_min_len(4)
        .map(|px| {
            let objects = pixels.trace(px);
            bar.inc(1);
            objects
        })
        .collect();
    bar.finish_and_clear();
    let mut objects = Objects::with_capacity(setup.plans.len());
    for o in 0..setup.plans.len() {
        objects.push(pixels.object(o, &results));
    }
    Ok(objects)
}

/// What the pixels of a per-pixel bake share.
struct Pixels<'a> {
    setup: &'a Setup<'a>,
    chain: &'a [Vec<MeshTransfer>],
    footprints: &'a PixelFootprints,
    /// This shard's pixels.
    first: usize,
    count: usize,
    /// Colour channels of the diffuse transfer: RGB with bounces, else one.
    channels: usize,
}

impl Pixels<'_> {
    /// The footprint-averaged transfer of every object the samples of pixel `px` hit, in the
    /// order of their first sample.
    fn trace(&self, px: usize) -> Vec<PixelTransfer> {
        let mut objects: Vec<PixelTransfer> = Vec::new();
        for (j, sample) in self.footprints.pixel(px).iter().enumerate() {
            let Some((mesh, p)) = sample.hit else {
                continue;
            };
            // A normal-mapped hit: the map's normal as the path tracer orients it shades
            // (cosine and hemisphere); the geometric normal still decides the side.
            let mapped = sample.at.and_then(|at| match at {
                SurfacePoint::Triangle { tri, u, v } => self
                    .setup
                    .scene
                    .seen_normal_mapped(mesh, tri, u, v, sample.dir),
                SurfacePoint::Vertex(_) => None,
            });
            let p = SamplePoint {
                normal: mapped.unwrap_or(p.normal),
                ..p
            };
            let geometric = mapped.map(|_| p.offset_normal);
            self.add_sample(&mut objects, px, j as u32, mesh, &p, geometric);
        }
        objects
    }

    /// Traces sample `j` of pixel `px` (point `p` on `mesh`; `geometric`: its geometric normal
    /// when `p.normal` comes from a normal map, see [`direct_sided`]) and adds its `1/K` share
    /// to the pixel's entry for `mesh`.
    fn add_sample(
        &self,
        objects: &mut Vec<PixelTransfer>,
        px: usize,
        j: u32,
        mesh: usize,
        p: &SamplePoint,
        geometric: Option<glam::Vec3>,
    ) {
        let (settings, channels) = (self.setup.settings, self.channels);
        let bounces = settings.bounces as usize;
        let k = settings.pixel_samples;
        let plan = &self.setup.plans[mesh];
        let n2 = plan.order * plan.order;
        // The pixel's R rays are shared out over its K samples: sample j takes the next
        // contiguous block of the pixel's low-discrepancy sequence.
        let (base, extra) = (settings.rays / k, settings.rays % k);
        let rays = base + u32::from(j < extra);
        let opt = DirectOptions {
            rays,
            record_hits: bounces > 0,
            visibility: plan.needs_visibility,
            seed: settings.seed,
            object: plan.mesh as u64 | (1 << 32),
            first_ray: j * base + j.min(extra),
            basis: &self.setup.bases[mesh],
        };
        let d = direct_sided(self.setup.accel, p, px as u64, &opt, geometric);
        let entry = match objects.iter().position(|t| t.mesh == mesh) {
            Some(i) => &mut objects[i],
            None => {
                objects.push(PixelTransfer::new(
                    mesh,
                    channels * n2,
                    plan.needs_visibility.then_some(n2),
                    settings.unshadowed.then_some(n2),
                ));
                objects.last_mut().expect("just pushed")
            }
        };
        let weight = 1.0 / f64::from(k);
        for c in 0..channels {
            add_scaled(
                &mut entry.diffuse[c * n2..(c + 1) * n2],
                &d.shadowed,
                weight,
            );
        }
        for b in 1..=bounces {
            let g = gather(
                &d.hits,
                rays,
                &self.chain[b - 1],
                &self.setup.gs,
                plan.order,
            );
            add_scaled(&mut entry.diffuse, &g, weight);
        }
        if let (Some(v), Some(src)) = (entry.visibility.as_mut(), &d.visibility) {
            add_scaled(v, src, weight);
        }
        if let Some(u) = entry.unshadowed.as_mut() {
            add_scaled(u, &transfer::unshadowed(plan.order, p.normal), weight);
        }
        entry.hits += u64::from(d.hit_count);
        entry.stats.add(&point_stats(&d, rays));
    }

    /// Object `o`'s part of the file from every pixel's `results`.
    fn object(&self, o: usize, results: &[Vec<PixelTransfer>]) -> BakedObject {
        let (scene, settings, channels) = (self.setup.scene, self.setup.settings, self.channels);
        let plan = &self.setup.plans[o];
        let mesh = &scene.meshes[plan.mesh];
        let n2 = plan.order * plan.order;
        let stride = channels * n2;
        let count = self.count;
        let mut diffuse = vec![0.0f32; count * stride];
        let mut vis = plan.needs_visibility.then(|| vec![0.0f32; count * stride]);
        let mut unsh = settings.unshadowed.then(|| vec![0.0f32; count * stride]);
        let (mut npts, mut hits) = (0u64, 0u64);
        let mut stats = RayStats {
            object: plan.name.clone(),
            ..RayStats::default()
        };
        for (px, objs) in results.iter().enumerate() {
            let Some(t) = objs.iter().find(|t| t.mesh == o) else {
                continue;
            };
            npts += 1;
            hits += t.hits;
            stats.add(&t.stats);
            let base = px * stride;
            store(&mut diffuse[base..base + stride], &t.diffuse);
            for c in 0..channels {
                let dst = base + c * n2..base + (c + 1) * n2;
                if let (Some(v), Some(src)) = (vis.as_mut(), &t.visibility) {
                    store(&mut v[dst.clone()], src);
                }
                if let (Some(u), Some(src)) = (unsh.as_mut(), &t.unshadowed) {
                    store(&mut u[dst], src);
                }
            }
        }
        let rays = stats.rays * (1 + u64::from(plan.needs_visibility));
        let blocks = point_blocks(settings.bounces, diffuse, vis, unsh);
        let report = ObjectReport {
            name: plan.name.clone(),
            order: plan.order,
            points: npts,
            hit_fraction: hits as f64 / stats.rays.max(1) as f64,
            backface_fraction: stats.backface_fraction(),
            inside_fraction: stats.inside_fraction(),
            kinds: blocks.iter().map(|b| b.kind.name().to_owned()).collect(),
        };
        let (first, count) = (self.first, self.count);
        let object = ObjectBake {
            name: plan.name.clone(),
            geometry_hash: geometry_hash(mesh.positions.as_slice(), &mesh.indices),
            point_count: u64::from(scene.camera.width) * u64::from(scene.camera.height),
            point_first: first as u64,
            points_in_file: count as u64,
            order: plan.order as u32,
            channels: channels as u32,
            blocks,
            mesh: Some(mesh_geometry(mesh)),
            // The object's share of each pixel's footprint samples (SPEC §3.11).
            coverage: Some(Coverage {
                pixel_samples: settings.pixel_samples,
                hits: (first..first + count)
                    .map(|px| {
                        let samples = self.footprints.pixel(px).iter();
                        samples
                            .filter(|s| s.hit.is_some_and(|(m, _)| m == plan.mesh))
                            .count() as u32
                    })
                    .collect(),
            }),
            material: Some(material_binding(scene, plan.mesh)),
            pass: None,
        };
        BakedObject {
            object,
            report,
            stats,
            rays,
        }
    }
}
