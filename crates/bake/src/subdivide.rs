//! Adaptive subdivision of per-vertex bakes (after D3DX's PRT engine): a coarse mesh cannot
//! hold the shadow a figure casts on a 4-vertex floor, so the baker splits the edges across
//! which the transfer changes by more than an error target, and repeats, up to a number of
//! levels; then the refined mesh is baked like any other. Edges across which the transfer does
//! not change are never split, so open, evenly lit regions keep their triangles.
//!
//! What interpolation gets wrong is what matters: the transfer is probed at each edge's
//! midpoint and at each triangle's centroid, and an edge is split when its midpoint's transfer
//! differs from the average of its ends' by more than `E` — `‖t_m − (t_a + t_b)/2‖ /
//! max(‖t_m‖, f) > E` — and all three edges of a triangle when its centroid's differs so from
//! the average of its corners' (a shadow inside a large triangle whose corners all see the
//! sky). Vectors are compared on bands 0–2 (what diffuse lighting weighs), and `f` is the
//! object's mean ‖t‖, so small differences in dark regions do not split.
//!
//! The decisions cost a fraction of the bake: every transfer compared is a cheap probe
//! (`crate::probe`: `SubdivideOptions::probe_rays` directions, bands 0–2 only), and all probes
//! of an object trace the same world directions (common random numbers), so
//! `t_m − (t_a + t_b)/2` carries no sampling noise where the three points see the same sky,
//! only what visibility and the normal do between them. A probe depends on its point alone, so
//! an edge or triangle a level leaves intact keeps its probe: each level probes only the edges
//! and triangles the previous one made. No probe goes into the file: the refined meshes are
//! then baked with the full rays and each vertex's own key, as a plain bake of them would be.
//!
//! A split edge gets its midpoint (position averaged in f64, normal the normalised sum of its
//! ends'); a triangle with 1, 2 or 3 split edges becomes 2, 3 or 4 triangles with the same
//! winding (red–green refinement: both triangles of a shared edge split it, so the mesh stays
//! conforming, without T-junctions). The new surface is the old one exactly: every new
//! triangle lies in its parent's plane.

use crate::plan::ObjectPlan;
use crate::probe::Probe;
use crate::{BakeError, BakeSettings};
use glam::Vec3;
use prt_scene::{Mesh, Scene};
use prt_tracer::Accel;
use rayon::prelude::*;
use std::collections::HashMap;

pub use crate::settings::SubdivideOptions;

/// What refinement did to one object.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ObjectRefinement {
    /// Object name.
    pub name: String,
    /// Vertices before and after.
    pub vertices: [usize; 2],
    /// Triangles before and after.
    pub triangles: [usize; 2],
    /// Edges split at each level.
    pub splits: Vec<usize>,
    /// Points probed: the source mesh's vertices, then at each level the midpoints and
    /// centroids of the edges and triangles that level made.
    pub probes: Vec<usize>,
    /// Directions of each probe (about half of them, those above its horizon, are traced).
    pub probe_rays: u32,
    /// Rays traced to decide (every probe's rays above its horizon).
    pub rays: u64,
}

/// Coefficients compared: bands 0–2.
const COMPARED: usize = 9;

/// `‖t − mean of others‖ / max(‖t‖, floor)` on the compared coefficients.
fn deviation(t: &[f64], others: &[&[f64]], floor: f64) -> f64 {
    let k = t.len().min(COMPARED);
    let n = others.len() as f64;
    let (mut d, mut nt) = (0.0f64, 0.0f64);
    for i in 0..k {
        let avg = others.iter().map(|o| o[i]).sum::<f64>() / n;
        d += (t[i] - avg).powi(2);
        nt += t[i] * t[i];
    }
    d.sqrt() / nt.sqrt().max(floor).max(f64::MIN_POSITIVE)
}

/// Splits the marked edges of `indices` (keys `(min, max)` → midpoint vertex) into new
/// triangles with the same winding.
fn split_triangles(indices: &[[u32; 3]], mid: &HashMap<(u32, u32), u32>) -> Vec<[u32; 3]> {
    let key = |a: u32, b: u32| (a.min(b), a.max(b));
    let mut out = Vec::with_capacity(indices.len() * 2);
    for &t in indices {
        let m: [Option<u32>; 3] = [0, 1, 2].map(|e| mid.get(&key(t[e], t[(e + 1) % 3])).copied());
        match m.iter().filter(|x| x.is_some()).count() {
            0 => out.push(t),
            3 => {
                let [ab, bc, ca] = m.map(|x| x.expect("three splits"));
                let [a, b, c] = t;
                out.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
            }
            1 => {
                // Rotate so that the split edge is (a, b).
                let e = m.iter().position(Option::is_some).expect("one split");
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let ab = m[e].expect("split");
                out.extend([[a, ab, c], [ab, b, c]]);
            }
            _ => {
                // Rotate so that the unsplit edge is (c, a): (a, b) and (b, c) are split.
                let e = (m.iter().position(Option::is_none).expect("one unsplit") + 1) % 3;
                let (a, b, c) = (t[e], t[(e + 1) % 3], t[(e + 2) % 3]);
                let (ab, bc) = (m[e].expect("split"), m[(e + 1) % 3].expect("split"));
                out.extend([[ab, b, bc], [a, ab, bc], [a, bc, c]]);
            }
        }
    }
    out
}

/// Refines every mesh of `scene` (per-vertex bakes) and returns the scene with the refined
/// meshes, and what was done. `accel` is `scene`'s. The decisions come from cheap probes
/// (`opt.probe_rays` directions each); no transfer of the refinement goes into the bake: the caller
/// bakes the refined scene with the full rays.
///
/// # Errors
/// Invalid options.
pub fn refine(
    scene: &Scene,
    accel: &Accel,
    settings: &BakeSettings,
    plans: &[ObjectPlan],
    opt: &SubdivideOptions,
) -> Result<(Scene, Vec<ObjectRefinement>), BakeError> {
    if !(opt.error.is_finite() && opt.error >= 0.0) || opt.max_levels > 16 {
        return Err(BakeError::InvalidSettings(format!(
            "subdivision error {} must be a finite number ≥ 0 and levels {} at most 16",
            opt.error, opt.max_levels
        )));
    }
    let mut refined = scene.clone();
    let mut report = Vec::with_capacity(plans.len());
    for plan in plans {
        let mesh: &mut Mesh = &mut refined.meshes[plan.mesh];
        report.push(refine_mesh(mesh, accel, settings, plan, opt)?);
    }
    Ok((refined, report))
}

/// Refines the mesh of one object in place, level by level, until no edge needs splitting,
/// `opt.max_levels` levels were done or the mesh has `opt.max_vertices` vertices.
///
/// Every decision is made from cheap probes (`opt.probe_rays` directions, bands 0–2 only) that
/// all trace the same world directions: where the points of an edge see the same sky, their
/// probes differ only by the cosine, so the probes' own noise does not split. A probe depends
/// only on its point, so an edge or triangle that survives a level keeps its probe and is not
/// probed again: each level probes only the new edges and triangles.
fn refine_mesh(
    mesh: &mut Mesh,
    accel: &Accel,
    settings: &BakeSettings,
    plan: &ObjectPlan,
    opt: &SubdivideOptions,
) -> Result<ObjectRefinement, BakeError> {
    let probe_rays = probe_rays(opt, settings.rays);
    let probe = Probe::new(accel, plan.mesh, plan.order, probe_rays, settings.seed)?;
    let vertices: Vec<u32> = (0..mesh.positions.len() as u32).collect();
    let (mut transfer, _, mut rays) = probed(
        &vertices,
        &mut HashMap::new(),
        |&v| (mesh.positions[v as usize], mesh.normals[v as usize]),
        &probe,
    );
    let mut probes = vec![mesh.positions.len()];
    let (v0, t0) = (mesh.positions.len(), mesh.indices.len());
    let mut splits = Vec::new();
    let mut edge_cache: HashMap<Edge, Vec<f64>> = HashMap::new();
    let mut tri_cache: HashMap<[u32; 3], Vec<f64>> = HashMap::new();
    for _ in 0..opt.max_levels {
        if mesh.positions.len() >= opt.max_vertices {
            break;
        }
        let (edges, seen) = unique_edges(&mesh.indices);
        let (at_edges, new_edges, edge_rays) =
            probed(&edges, &mut edge_cache, |&e| midpoint(mesh, e), &probe);
        let (at_tris, new_tris, tri_rays) =
            probed(&mesh.indices, &mut tri_cache, |t| centroid(mesh, t), &probe);
        probes.push(new_edges + new_tris);
        rays += edge_rays + tri_rays;
        let deviations = Deviations {
            transfer: &transfer,
            at_edges: &at_edges,
            at_tris: &at_tris,
            floor: mean_norm(&transfer),
            error: opt.error,
        };
        let chosen = deviations.edges_to_split(&mesh.indices, &edges, &seen);
        if chosen.is_empty() {
            break;
        }
        splits.push(chosen.len());
        split_edges(mesh, &edges, &chosen, &at_edges, &mut transfer)?;
    }
    Ok(ObjectRefinement {
        name: plan.name.clone(),
        vertices: [v0, mesh.positions.len()],
        triangles: [t0, mesh.indices.len()],
        splits,
        probes,
        probe_rays,
        rays,
    })
}

/// The directions of each probe: `opt.probe_rays`, by default a quarter of the bake's rays but
/// at least 128, never more than the bake's rays and at least 1. A probe traces the half of
/// its directions above its horizon, and the first level probes about 6 points per vertex
/// (the vertex, ~3 edge midpoints, ~2 triangle centroids), so by default the probes trace
/// about ¾ of the rays of the source mesh's direct bake; below 128 directions (64 traced) the
/// probes' noise starts to split edges on curved meshes (measured in the crate README).
fn probe_rays(opt: &SubdivideOptions, rays: u32) -> u32 {
    opt.probe_rays
        .unwrap_or((rays / 4).max(128))
        .min(rays)
        .max(1)
}

/// The probes at the points of `items` (edges' midpoints or triangles' centroids, placed by
/// `point`), in item order: those already in `cache` reused, the others probed; `cache` is left
/// holding exactly `items`' probes. Also returns how many were probed, and the rays traced.
fn probed<K, F>(
    items: &[K],
    cache: &mut HashMap<K, Vec<f64>>,
    point: F,
    probe: &Probe<'_>,
) -> (Vec<Vec<f64>>, usize, u64)
where
    K: Copy + Eq + std::hash::Hash + Sync,
    F: Fn(&K) -> (Vec3, Vec3) + Sync,
{
    let mut old = std::mem::take(cache);
    let mut values: Vec<Option<Vec<f64>>> = items.iter().map(|k| old.remove(k)).collect();
    let missing: Vec<usize> = (0..items.len()).filter(|&i| values[i].is_none()).collect();
    let fresh: Vec<(Vec<f64>, u64)> = missing
        .par_iter()
        .map(|&i| {
            let (p, n) = point(&items[i]);
            probe.at(p, n)
        })
        .collect();
    let mut rays = 0;
    for (&i, (t, r)) in missing.iter().zip(fresh) {
        values[i] = Some(t);
        rays += r;
    }
    let values: Vec<Vec<f64>> = values.into_iter().flatten().collect();
    *cache = items.iter().copied().zip(values.iter().cloned()).collect();
    (values, missing.len(), rays)
}

/// The mean over points of `‖t‖` on the compared coefficients: the floor of [`deviation`].
fn mean_norm(transfer: &[Vec<f64>]) -> f64 {
    transfer
        .iter()
        .map(|t| {
            t[..t.len().min(COMPARED)]
                .iter()
                .map(|x| x * x)
                .sum::<f64>()
                .sqrt()
        })
        .sum::<f64>()
        / transfer.len().max(1) as f64
}

/// An edge's vertices `(min, max)`.
type Edge = (u32, u32);

/// Every edge of `indices` once, in the order triangles first meet it, and each edge's index
/// in that list.
fn unique_edges(indices: &[[u32; 3]]) -> (Vec<Edge>, HashMap<Edge, usize>) {
    let mut edges: Vec<(u32, u32)> = Vec::new();
    let mut seen: HashMap<(u32, u32), usize> = HashMap::new();
    for t in indices {
        for e in 0..3 {
            let (a, b) = (t[e], t[(e + 1) % 3]);
            let k = (a.min(b), a.max(b));
            if let std::collections::hash_map::Entry::Vacant(slot) = seen.entry(k) {
                slot.insert(edges.len());
                edges.push(k);
            }
        }
    }
    (edges, seen)
}

/// The midpoint of edge `(a, b)`: position averaged in f64, normal the normalised sum of its
/// ends' (`a`'s if they cancel).
fn midpoint(mesh: &Mesh, (a, b): (u32, u32)) -> (Vec3, Vec3) {
    let p = ((mesh.positions[a as usize].as_dvec3() + mesh.positions[b as usize].as_dvec3()) * 0.5)
        .as_vec3();
    let n = (mesh.normals[a as usize] + mesh.normals[b as usize])
        .normalize_or(mesh.normals[a as usize]);
    (p, n)
}

/// The centroid of triangle `t`: position averaged in f64, normal the normalised sum of its
/// corners' (the first corner's if they cancel).
fn centroid(mesh: &Mesh, t: &[u32; 3]) -> (Vec3, Vec3) {
    let p = (t
        .iter()
        .map(|&i| mesh.positions[i as usize].as_dvec3())
        .sum::<glam::DVec3>()
        / 3.0)
        .as_vec3();
    let n = t
        .iter()
        .map(|&i| mesh.normals[i as usize])
        .sum::<Vec3>()
        .normalize_or(mesh.normals[t[0] as usize]);
    (p, n)
}

/// One level's transfer at the vertices, edge midpoints and triangle centroids, and what
/// counts as too large a deviation from interpolation.
struct Deviations<'a> {
    transfer: &'a [Vec<f64>],
    at_edges: &'a [Vec<f64>],
    at_tris: &'a [Vec<f64>],
    floor: f64,
    error: f64,
}

impl Deviations<'_> {
    /// The edges to split, in edge order: those whose midpoint deviates from the average of
    /// their ends, and all three of each triangle whose centroid deviates from the average of
    /// its corners.
    fn edges_to_split(
        &self,
        indices: &[[u32; 3]],
        edges: &[(u32, u32)],
        seen: &HashMap<(u32, u32), usize>,
    ) -> Vec<usize> {
        let transfer = self.transfer;
        let mut split = vec![false; edges.len()];
        for (i, &(a, b)) in edges.iter().enumerate() {
            let ends = [
                transfer[a as usize].as_slice(),
                transfer[b as usize].as_slice(),
            ];
            split[i] = deviation(&self.at_edges[i], &ends, self.floor) > self.error;
        }
        for (t, at) in indices.iter().zip(self.at_tris) {
            let corners = t.map(|i| transfer[i as usize].as_slice());
            if deviation(at, &corners, self.floor) > self.error {
                for e in 0..3 {
                    let (a, b) = (t[e], t[(e + 1) % 3]);
                    split[seen[&(a.min(b), a.max(b))]] = true;
                }
            }
        }
        (0..edges.len()).filter(|&i| split[i]).collect()
    }
}

/// Splits the `chosen` edges of `mesh`: a new vertex at each one's midpoint (with its UVs and
/// colour averaged, and its probe `at_edges[i]` as its transfer estimate), then the triangles.
fn split_edges(
    mesh: &mut Mesh,
    edges: &[(u32, u32)],
    chosen: &[usize],
    at_edges: &[Vec<f64>],
    transfer: &mut Vec<Vec<f64>>,
) -> Result<(), BakeError> {
    let new_points: Vec<(Vec3, Vec3)> = chosen.iter().map(|&i| midpoint(mesh, edges[i])).collect();
    let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
    for (&i, (p, n)) in chosen.iter().zip(new_points) {
        let index = u32::try_from(mesh.positions.len())
            .map_err(|_| BakeError::InvalidSettings("subdivision beyond 2^32 vertices".into()))?;
        mesh.positions.push(p);
        mesh.normals.push(n);
        // UVs and vertex colours at the midpoint (the texture is read there).
        let (a, b) = (edges[i].0 as usize, edges[i].1 as usize);
        for uv in &mut mesh.texcoords {
            uv.push([0.5 * (uv[a][0] + uv[b][0]), 0.5 * (uv[a][1] + uv[b][1])]);
        }
        if !mesh.colors.is_empty() {
            let (ca, cb) = (mesh.colors[a], mesh.colors[b]);
            mesh.colors
                .push(std::array::from_fn(|k| 0.5 * (ca[k] + cb[k])));
        }
        mid.insert(edges[i], index);
        // The midpoint's probe is its transfer estimate for the next level.
        transfer.push(at_edges[i].clone());
    }
    mesh.indices = split_triangles(&mesh.indices, &mid);
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn area(p: &[Vec3], t: &[[u32; 3]]) -> Vec3 {
        t.iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| p[i as usize]);
                0.5 * (b - a).cross(c - a)
            })
            .sum()
    }

    /// Every pattern of split edges keeps the area vector (same surface, same winding) and
    /// leaves no T-junction: every edge of the result is shared by at most two triangles, and
    /// a split edge's halves appear on both sides.
    #[test]
    fn split_patterns_keep_surface_and_winding_and_conform() {
        // Two triangles sharing edge (1, 2).
        let p = vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
            Vec3::new(1.0, 1.0, 0.0),
        ];
        let tris = vec![[0u32, 1, 2], [1, 3, 2]];
        let edges = [(0u32, 1u32), (1, 2), (0, 2), (1, 3), (2, 3)];
        for mask in 0u32..32 {
            let mut mid = HashMap::new();
            let mut pts = p.clone();
            for (i, &(a, b)) in edges.iter().enumerate() {
                if mask & (1 << i) != 0 {
                    mid.insert((a.min(b), a.max(b)), pts.len() as u32);
                    pts.push((p[a as usize] + p[b as usize]) * 0.5);
                }
            }
            let out = split_triangles(&tris, &mid);
            assert!(
                (area(&pts, &out) - area(&p, &tris)).length() < 1e-6,
                "mask {mask}"
            );
            for t in &out {
                let [a, b, c] = t.map(|i| pts[i as usize]);
                assert!(
                    (b - a).cross(c - a).z > 0.0,
                    "mask {mask}: winding flipped or degenerate"
                );
            }
            let mut count: HashMap<(u32, u32), usize> = HashMap::new();
            for t in &out {
                for e in 0..3 {
                    let (a, b) = (t[e], t[(e + 1) % 3]);
                    *count.entry((a.min(b), a.max(b))).or_default() += 1;
                }
            }
            assert!(count.values().all(|&c| c <= 2), "mask {mask}");
            // The shared edge: split on one side means split on the other (no T-junction).
            assert!(!count.contains_key(&(1, 2)) || !mid.contains_key(&(1, 2)));
        }
    }

    #[test]
    fn probes_take_a_quarter_of_the_rays_at_least_128_at_most_all() {
        let auto = SubdivideOptions::default();
        assert_eq!(probe_rays(&auto, 2048), 512);
        assert_eq!(probe_rays(&auto, 256), 128);
        assert_eq!(probe_rays(&auto, 16), 16);
        let set = |r| SubdivideOptions {
            probe_rays: Some(r),
            ..auto
        };
        assert_eq!(probe_rays(&set(100), 2048), 100);
        assert_eq!(probe_rays(&set(4096), 2048), 2048);
        assert_eq!(probe_rays(&set(0), 2048), 1);
    }

    #[test]
    fn edges_are_listed_once_in_the_order_triangles_meet_them() {
        let (edges, seen) = unique_edges(&[[0, 1, 2], [2, 1, 3]]);
        assert_eq!(edges, [(0, 1), (1, 2), (0, 2), (1, 3), (2, 3)]);
        for (i, e) in edges.iter().enumerate() {
            assert_eq!(seen[e], i);
        }
    }

    #[test]
    fn the_noise_floor_is_the_mean_norm_of_the_compared_bands() {
        // Only the first 9 coefficients count: the tenth is ignored.
        let t = vec![
            vec![3.0, 4.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 100.0],
            vec![0.0; 10],
        ];
        assert_eq!(mean_norm(&t), 2.5);
        assert_eq!(mean_norm(&[]), 0.0);
    }
}
