//! Chart segmentation: triangles grown into charts over shared edges while their normals stay
//! within a cone around the seed's normal, each chart projected onto the seed's plane, and a
//! triangle joins only if its projection overlaps none of the chart's (so every chart is a
//! one-to-one, orientation-preserving map of its triangles).

use glam::{DVec2, DVec3, Vec3};
use std::collections::{HashMap, VecDeque};

/// One chart: its triangles (mesh indices, ascending order of joining) and their corners
/// projected onto the seed triangle's plane, in world units.
#[derive(Clone, Debug)]
pub(crate) struct Chart {
    /// Mesh triangle indices.
    pub triangles: Vec<u32>,
    /// Projected corners of each of `triangles`.
    pub corners: Vec<[DVec2; 3]>,
}

/// What the charts may hold.
#[derive(Clone, Copy, Debug)]
pub(crate) struct ChartLimits {
    /// Cosine of the largest angle between a triangle's normal and its chart's seed normal.
    pub cos_cone: f64,
    /// The most triangles a chart holds (bounds the quadratic overlap test).
    pub max_triangles: usize,
}

/// Segments the mesh into charts, seeds in triangle order, growth breadth first.
pub(crate) fn charts(positions: &[Vec3], indices: &[[u32; 3]], limits: ChartLimits) -> Vec<Chart> {
    let neighbours = neighbours(positions, indices);
    let tri_pos = |t: usize| indices[t].map(|i| positions[i as usize].as_dvec3());
    let normals: Vec<DVec3> = (0..indices.len())
        .map(|t| {
            let p = tri_pos(t);
            (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero()
        })
        .collect();
    let mut assigned = vec![false; indices.len()];
    let mut out = Vec::new();
    for seed in 0..indices.len() {
        if assigned[seed] {
            continue;
        }
        let n0 = if normals[seed] == DVec3::ZERO {
            DVec3::Y
        } else {
            normals[seed]
        };
        let (tu, tv) = n0.any_orthonormal_pair();
        let project = |t: usize| tri_pos(t).map(|p| DVec2::new(p.dot(tu), p.dot(tv)));
        let mut chart = Chart {
            triangles: vec![seed as u32],
            corners: vec![project(seed)],
        };
        assigned[seed] = true;
        let mut queue = VecDeque::from([seed]);
        while let Some(t) = queue.pop_front() {
            for &nb in &neighbours[t] {
                let nb = nb as usize;
                if assigned[nb]
                    || chart.triangles.len() >= limits.max_triangles
                    || normals[nb].dot(n0) < limits.cos_cone
                {
                    continue;
                }
                let c = project(nb);
                if signed_area(&c) <= 0.0 || chart.corners.iter().any(|o| overlap(o, &c)) {
                    continue;
                }
                assigned[nb] = true;
                chart.triangles.push(nb as u32);
                chart.corners.push(c);
                queue.push_back(nb);
            }
        }
        out.push(chart);
    }
    out
}

/// Per triangle, the triangles sharing one of its edges (vertices welded by exact position, so
/// that seams of normals or UVs in the source do not cut charts), ascending per edge.
fn neighbours(positions: &[Vec3], indices: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let mut weld: HashMap<[u32; 3], u32> = HashMap::new();
    let id: Vec<u32> = positions
        .iter()
        .map(|p| {
            let n = weld.len() as u32;
            *weld.entry(p.to_array().map(f32::to_bits)).or_insert(n)
        })
        .collect();
    let key = |a: u32, b: u32| {
        let (a, b) = (id[a as usize], id[b as usize]);
        (a.min(b), a.max(b))
    };
    let mut edges: HashMap<(u32, u32), Vec<u32>> = HashMap::new();
    for (t, tri) in indices.iter().enumerate() {
        for k in 0..3 {
            edges
                .entry(key(tri[k], tri[(k + 1) % 3]))
                .or_default()
                .push(t as u32);
        }
    }
    indices
        .iter()
        .enumerate()
        .map(|(t, tri)| {
            let mut n = Vec::new();
            for k in 0..3 {
                let e = &edges[&key(tri[k], tri[(k + 1) % 3])];
                n.extend(e.iter().copied().filter(|&o| o as usize != t));
            }
            n
        })
        .collect()
}

/// Twice the signed area of a 2D triangle (positive counter-clockwise).
pub(crate) fn signed_area(c: &[DVec2; 3]) -> f64 {
    (c[1] - c[0]).perp_dot(c[2] - c[0])
}

/// Whether the interiors of two 2D triangles overlap (separating-axis test over the six edge
/// normals; triangles that only touch along an edge or at a corner do not overlap, within a
/// rounding tolerance relative to their size).
pub(crate) fn overlap(a: &[DVec2; 3], b: &[DVec2; 3]) -> bool {
    let lo = a.iter().chain(b).fold(DVec2::INFINITY, |m, p| m.min(*p));
    let hi = a
        .iter()
        .chain(b)
        .fold(DVec2::NEG_INFINITY, |m, p| m.max(*p));
    let tol = 1e-9 * (hi - lo).max_element().max(f64::MIN_POSITIVE);
    // Bounding boxes first.
    let (alo, ahi) = bounds(a);
    let (blo, bhi) = bounds(b);
    if ahi.x <= blo.x + tol || bhi.x <= alo.x + tol || ahi.y <= blo.y + tol || bhi.y <= alo.y + tol
    {
        return false;
    }
    for tri in [a, b] {
        for k in 0..3 {
            let axis = (tri[(k + 1) % 3] - tri[k]).perp();
            let len = axis.length();
            if len == 0.0 {
                continue;
            }
            let range = |t: &[DVec2; 3]| {
                let d = t.map(|p| p.dot(axis) / len);
                (d[0].min(d[1]).min(d[2]), d[0].max(d[1]).max(d[2]))
            };
            let ((a0, a1), (b0, b1)) = (range(a), range(b));
            if a1 <= b0 + tol || b1 <= a0 + tol {
                return false;
            }
        }
    }
    true
}

/// The bounding box of a 2D triangle.
pub(crate) fn bounds(c: &[DVec2; 3]) -> (DVec2, DVec2) {
    (c[0].min(c[1]).min(c[2]), c[0].max(c[1]).max(c[2]))
}
