//! Lightmap texels: the surface points of a per-texel bake (`prt bake --per-texel SIZE`).
//!
//! An object's lightmap UVs are its glTF `TEXCOORD_1`, else `TEXCOORD_0` (OBJ `vt`, stored as
//! `(u, 1 − v)` so that every set has glTF's top-left origin). Texel `(x, y)` of a `W × H`
//! lightmap covers `u ∈ [x/W, (x+1)/W]`, `v ∈ [y/H, (y+1)/H]`; its point index is `y·W + x`.
//!
//! Each triangle is rasterised in UV space. A texel whose centre lies in a triangle is baked at
//! the surface point under its centre (barycentric position, interpolated shading normal). A
//! texel that a triangle only touches (conservative rasterisation: the interior of the texel's
//! square meets the triangle — a contact along an edge or at a corner does not count —, its
//! centre does not) is baked at the point of the touching triangles nearest to its centre
//! (the first triangle wins a tie; the point may lie outside the square) — still on the surface, so the edge texels a bilinear lookup reads are real
//! transfer, not zero. Texels no triangle touches are empty (coverage 0); lookups renormalise
//! the bilinear weights over the covered texels, which dilates the charts by a texel at their
//! seams. Two triangles whose interiors both hold a texel centre are overlapping charts, an
//! error (a lightmap needs a unique parameterisation), as are UVs outside `[0, 1]`.
//!
//! Meshes without UVs get a generated atlas (`prt-atlas`), UVs per triangle corner
//! ([`lightmap_from_corners`]), rasterised the same way; [`split_corners`] turns them into
//! per-vertex UVs for glTF.

use crate::Mesh;
use glam::{DVec2, DVec3, Vec3};

/// The largest lightmap side `--per-texel` accepts.
pub const MAX_LIGHTMAP_SIZE: u32 = 8192;

/// Which UV set an object's lightmap uses: `TEXCOORD_1` when the mesh has it, else set 0;
/// `None` without UVs.
#[must_use]
pub fn lightmap_uv_set(mesh: &Mesh) -> Option<usize> {
    match mesh.texcoords.len() {
        0 => None,
        1 => Some(0),
        _ => Some(1),
    }
}

/// The surface point a texel is baked at.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TexelPoint {
    /// The triangle it lies on.
    pub triangle: u32,
    /// Its barycentric coordinates on that triangle (corners 0, 1, 2), each in `[0, 1]`.
    pub bary: [f32; 3],
    /// World-space position.
    pub position: Vec3,
    /// Unit shading normal (the corners' normals interpolated).
    pub normal: Vec3,
    /// Unit geometric normal of the triangle, on the shading normal's side.
    pub geometric_normal: Vec3,
    /// Whether the texel's centre lies in the triangle (otherwise the nearest point of a
    /// triangle that touches the texel).
    pub centre_inside: bool,
}

/// An object's lightmap: one optional surface point per texel, row-major from the top row.
#[derive(Clone, Debug)]
pub struct Lightmap {
    /// Width in texels.
    pub width: u32,
    /// Height in texels.
    pub height: u32,
    /// The UV set used (meaningless when `corner_uvs` is set).
    pub uv_set: usize,
    /// Generated atlas UVs (`prt-atlas`), per triangle corner, used instead of the mesh's UV
    /// set `uv_set` (a mesh without UVs; SPEC §3.9.3). `None`: the mesh's own UVs.
    pub corner_uvs: Option<Vec<[[f32; 2]; 3]>>,
    /// Per texel `y·width + x`: its surface point, `None` where no triangle touches it.
    pub texels: Vec<Option<TexelPoint>>,
}

impl Lightmap {
    /// Texels with a surface point.
    #[must_use]
    pub fn covered(&self) -> usize {
        self.texels.iter().filter(|t| t.is_some()).count()
    }

    /// The lightmap UVs of triangle `tri`'s corners: the generated atlas's, else the mesh's
    /// UV set `uv_set`.
    #[must_use]
    pub fn triangle_uvs(&self, mesh: &Mesh, tri: usize) -> [[f32; 2]; 3] {
        match &self.corner_uvs {
            Some(c) => c[tri],
            None => mesh.indices[tri].map(|i| mesh.texcoords[self.uv_set][i as usize]),
        }
    }
}

/// The vertices of a mesh split along the seams of per-corner UVs, for formats whose UVs are
/// per vertex (glTF): one vertex per distinct (source vertex, UV bit pattern), numbered in
/// order of first use by the triangles' corners. Returns each new vertex's source vertex, the
/// triangles on the new vertices (same order) and the new vertices' UVs.
#[must_use]
pub fn split_corners(
    indices: &[[u32; 3]],
    corner_uvs: &[[[f32; 2]; 3]],
) -> (Vec<u32>, Vec<[u32; 3]>, Vec<[f32; 2]>) {
    let mut ids: std::collections::HashMap<(u32, [u32; 2]), u32> = std::collections::HashMap::new();
    let (mut source, mut uvs) = (Vec::new(), Vec::new());
    let tris = indices
        .iter()
        .zip(corner_uvs)
        .map(|(t, c)| {
            [0, 1, 2].map(|k| {
                let key = (t[k], c[k].map(f32::to_bits));
                *ids.entry(key).or_insert_with(|| {
                    source.push(t[k]);
                    uvs.push(c[k]);
                    (source.len() - 1) as u32
                })
            })
        })
        .collect();
    (source, tris, uvs)
}

/// Rasterises generated per-corner UVs (`corner_uvs[t][k]`: corner `k` of triangle `t`) into a
/// `width × height` lightmap, exactly as [`lightmap`] does a UV set.
///
/// # Errors
/// UVs outside `[0, 1]` (counted per corner) or overlapping charts ([`LightmapError`]).
pub fn lightmap_from_corners(
    mesh: &Mesh,
    corner_uvs: Vec<[[f32; 2]; 3]>,
    width: u32,
    height: u32,
) -> Result<Lightmap, LightmapError> {
    if corner_uvs.len() != mesh.indices.len() {
        return Err(LightmapError::OutOfRange {
            vertices: mesh.indices.len().abs_diff(corner_uvs.len()),
            of: mesh.indices.len(),
            worst: f64::INFINITY,
        });
    }
    let all: Vec<[f32; 2]> = corner_uvs.iter().flatten().copied().collect();
    check_range(&all)?;
    let texels = rasterise(mesh, |t, k| corner_uvs[t][k], width, height)?;
    Ok(Lightmap {
        width,
        height,
        uv_set: 0,
        corner_uvs: Some(corner_uvs),
        texels,
    })
}

/// UVs outside `[0, 1]` (or not finite): how many, and the farthest excursion.
fn check_range<'a>(uvs: impl IntoIterator<Item = &'a [f32; 2]>) -> Result<(), LightmapError> {
    let (mut outside, mut worst, mut of) = (0usize, 0.0f64, 0usize);
    for uv in uvs {
        of += 1;
        let mut bad = false;
        for &c in uv {
            let c = f64::from(c);
            let d = if c.is_finite() {
                (-c).max(c - 1.0).max(0.0)
            } else {
                f64::INFINITY
            };
            if d > 0.0 {
                bad = true;
                worst = worst.max(d);
            }
        }
        outside += usize::from(bad);
    }
    if outside > 0 {
        return Err(LightmapError::OutOfRange {
            vertices: outside,
            of,
            worst,
        });
    }
    Ok(())
}

/// Why a mesh cannot be lightmapped.
#[derive(Clone, Debug, PartialEq)]
pub enum LightmapError {
    /// The mesh has no texture coordinates.
    NoUvs,
    /// UVs outside `[0, 1]`: how many vertices, and the farthest excursion.
    OutOfRange {
        /// Vertices with a coordinate outside `[0, 1]` (or not finite).
        vertices: usize,
        /// Of all vertices.
        of: usize,
        /// The largest distance of a coordinate outside `[0, 1]` (infinite for NaN).
        worst: f64,
    },
    /// Texel centres inside two triangles' interiors.
    Overlap {
        /// Texels covered twice.
        texels: usize,
        /// Of the texels covered.
        of: usize,
    },
}

impl std::fmt::Display for LightmapError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            LightmapError::NoUvs => write!(
                f,
                "has no texture coordinates for a lightmap (glTF TEXCOORD_1 or TEXCOORD_0, OBJ vt); it is baked per vertex"
            ),
            LightmapError::OutOfRange { vertices, of, worst } => write!(
                f,
                "{vertices} of {of} lightmap UVs lie outside [0, 1] (up to {worst:.4} outside): a lightmap needs every chart inside the unit square"
            ),
            LightmapError::Overlap { texels, of } => write!(
                f,
                "its lightmap charts overlap: {texels} of {of} covered texels ({:.2} %) lie inside two triangles; a lightmap needs a unique parameterisation",
                100.0 * *texels as f64 / (*of).max(1) as f64
            ),
        }
    }
}

/// Rasterises `mesh`'s lightmap UVs into a `width × height` lightmap.
///
/// # Errors
/// No UVs, UVs outside `[0, 1]` or overlapping charts ([`LightmapError`]).
pub fn lightmap(mesh: &Mesh, width: u32, height: u32) -> Result<Lightmap, LightmapError> {
    let uv_set = lightmap_uv_set(mesh).ok_or(LightmapError::NoUvs)?;
    let uvs = &mesh.texcoords[uv_set];
    // Range check on the vertices the triangles use.
    let mut used = vec![false; uvs.len()];
    for t in &mesh.indices {
        for &i in t {
            if let Some(u) = used.get_mut(i as usize) {
                *u = true;
            }
        }
    }
    check_range(uvs.iter().zip(&used).filter(|(_, u)| **u).map(|(uv, _)| uv))?;
    let texels = rasterise(mesh, |t, k| uvs[mesh.indices[t][k] as usize], width, height)?;
    Ok(Lightmap {
        width,
        height,
        uv_set,
        corner_uvs: None,
        texels,
    })
}

/// Rasterises the triangles of `mesh` at UVs `uv(triangle, corner)` (checked to lie in
/// `[0, 1]`): each texel's surface point, or an overlap error.
fn rasterise(
    mesh: &Mesh,
    uv: impl Fn(usize, usize) -> [f32; 2],
    width: u32,
    height: u32,
) -> Result<Vec<Option<TexelPoint>>, LightmapError> {
    let (w, h) = (width as usize, height as usize);
    let scale = DVec2::new(f64::from(width), f64::from(height));
    let mut texels: Vec<Option<TexelPoint>> = vec![None; w * h];
    // Distance (texels, UV space) of each edge texel's point from its centre: the nearest
    // touching triangle wins; 0 for centres inside.
    let mut dist = vec![f64::INFINITY; w * h];
    let mut inside_count = vec![0u8; w * h];
    for ti in 0..mesh.indices.len() {
        let [a, b, c] = [0, 1, 2].map(|k| DVec2::from(uv(ti, k).map(f64::from)) * scale);
        let area = (b - a).perp_dot(c - a);
        if area.abs() <= f64::EPSILON * scale.max_element().powi(2) {
            continue; // degenerate in UV space: covers no texel
        }
        let lo = a.min(b).min(c);
        let hi = a.max(b).max(c);
        // Every texel whose closed square the triangle's bounding box meets; `overlaps`
        // keeps those whose open square the triangle meets.
        let x0 = (lo.x.ceil() as i64 - 1).clamp(0, w as i64 - 1) as usize;
        let x1 = (hi.x.floor() as i64).clamp(0, w as i64 - 1) as usize;
        let y0 = (lo.y.ceil() as i64 - 1).clamp(0, h as i64 - 1) as usize;
        let y1 = (hi.y.floor() as i64).clamp(0, h as i64 - 1) as usize;
        for y in y0..=y1 {
            for x in x0..=x1 {
                if !overlaps([a, b, c], lo, hi, x as f64, y as f64) {
                    continue;
                }
                let centre = DVec2::new(x as f64 + 0.5, y as f64 + 0.5);
                let l = barycentric(a, b, c, area, centre);
                let k = y * w + x;
                // Strictly inside (beyond rounding): counts for overlap.
                let eps = 1e-7;
                if l.iter().all(|&v| v > eps) {
                    inside_count[k] = inside_count[k].saturating_add(1);
                }
                let (bary, d) = if l.iter().all(|&v| v >= 0.0) {
                    (l, 0.0)
                } else {
                    // Touching: the nearest point of the triangle to the centre.
                    let q = closest_point(a, b, c, centre);
                    let off = q - centre;
                    let l = barycentric(a, b, c, area, q).map(|v| v.clamp(0.0, 1.0));
                    let s = l[0] + l[1] + l[2];
                    (l.map(|v| v / s), off.length())
                };
                if d < dist[k] {
                    dist[k] = d;
                    texels[k] = Some(surface_point(mesh, ti, bary, d == 0.0));
                }
            }
        }
    }
    let twice = inside_count.iter().filter(|&&n| n > 1).count();
    if twice > 0 {
        return Err(LightmapError::Overlap {
            texels: twice,
            of: texels.iter().filter(|t| t.is_some()).count(),
        });
    }
    Ok(texels)
}

/// Whether triangle `t` (texel units; bounding box `lo`–`hi`) meets the interior of texel
/// `(x, y)`'s square `(x, x+1) × (y, y+1)`: separating axes (the square's two, the triangle's
/// three edge normals), a contact along an edge or at a corner not counting (SPEC §3.1).
fn overlaps(t: [DVec2; 3], lo: DVec2, hi: DVec2, x: f64, y: f64) -> bool {
    if !(x < hi.x && x + 1.0 > lo.x && y < hi.y && y + 1.0 > lo.y) {
        return false;
    }
    for (i, j, k) in [(0, 1, 2), (1, 2, 0), (2, 0, 1)] {
        let (nx, ny) = (t[i].y - t[j].y, t[j].x - t[i].x);
        let d_edge = nx * t[i].x + ny * t[i].y;
        let d_opp = nx * t[k].x + ny * t[k].y;
        let (t_lo, t_hi) = (d_edge.min(d_opp), d_edge.max(d_opp));
        let base = nx * x + ny * y;
        let b_lo = base + nx.min(0.0) + ny.min(0.0);
        let b_hi = base + nx.max(0.0) + ny.max(0.0);
        if b_hi <= t_lo || b_lo >= t_hi {
            return false;
        }
    }
    true
}

/// Barycentric coordinates of `p` on triangle `abc` (signed doubled area `area`).
fn barycentric(a: DVec2, b: DVec2, c: DVec2, area: f64, p: DVec2) -> [f64; 3] {
    let l1 = (p - a).perp_dot(c - a) / area;
    let l2 = (b - a).perp_dot(p - a) / area;
    // l1: weight of b; l2: weight of c.
    [1.0 - l1 - l2, l1, l2]
}

/// The point of triangle `abc` nearest to `p` (2D).
fn closest_point(a: DVec2, b: DVec2, c: DVec2, p: DVec2) -> DVec2 {
    let seg = |s: DVec2, e: DVec2| {
        let d = e - s;
        let t = ((p - s).dot(d) / d.length_squared().max(f64::MIN_POSITIVE)).clamp(0.0, 1.0);
        s + t * d
    };
    [seg(a, b), seg(b, c), seg(c, a)]
        .into_iter()
        .min_by(|x, y| {
            (*x - p)
                .length_squared()
                .total_cmp(&(*y - p).length_squared())
        })
        .unwrap_or(a)
}

fn surface_point(mesh: &Mesh, tri: usize, bary: [f64; 3], centre_inside: bool) -> TexelPoint {
    let t = mesh.indices[tri];
    let p = t.map(|i| mesh.positions[i as usize].as_dvec3());
    let n = t.map(|i| {
        mesh.normals
            .get(i as usize)
            .copied()
            .unwrap_or(Vec3::Y)
            .as_dvec3()
    });
    let position = p[0] * bary[0] + p[1] * bary[1] + p[2] * bary[2];
    let shading = (n[0] * bary[0] + n[1] * bary[1] + n[2] * bary[2]).normalize_or(DVec3::ZERO);
    let geometric = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or(DVec3::Y);
    let normal = if shading == DVec3::ZERO {
        geometric
    } else {
        shading
    };
    let geometric = if geometric.dot(normal) < 0.0 {
        -geometric
    } else {
        geometric
    };
    TexelPoint {
        triangle: tri as u32,
        bary: bary.map(|v| v as f32),
        position: position.as_vec3(),
        normal: normal.as_vec3(),
        geometric_normal: geometric.as_vec3(),
        centre_inside,
    }
}

/// Bilinear lookup of per-texel values at `uv` (texel centres at `(x + ½)/W`), over the covered
/// texels only: the weights of empty texels are dropped and the rest renormalised (a
/// one-texel dilation at chart seams); clamped at the lightmap's border. `None` when none of
/// the four texels is covered.
#[must_use]
pub fn bilinear(
    width: u32,
    height: u32,
    covered: impl Fn(usize) -> bool,
    value: impl Fn(usize) -> [f32; 3],
    uv: [f32; 2],
) -> Option<[f32; 3]> {
    let (w, h) = (width as i64, height as i64);
    let fx = f64::from(uv[0]) * w as f64 - 0.5;
    let fy = f64::from(uv[1]) * h as f64 - 0.5;
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = ((fx - x0) as f32, (fy - y0) as f32);
    let (x0, y0) = (x0 as i64, y0 as i64);
    let mut sum = [0.0f32; 3];
    let mut wsum = 0.0f32;
    for (dy, wy) in [(0, 1.0 - ty), (1, ty)] {
        for (dx, wx) in [(0, 1.0 - tx), (1, tx)] {
            let x = (x0 + dx).clamp(0, w - 1) as usize;
            let y = (y0 + dy).clamp(0, h - 1) as usize;
            let k = y * width as usize + x;
            let wt = wx * wy;
            if wt <= 0.0 || !covered(k) {
                continue;
            }
            let v = value(k);
            for c in 0..3 {
                sum[c] += wt * v[c];
            }
            wsum += wt;
        }
    }
    (wsum > 0.0).then(|| sum.map(|s| s / wsum))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit square in the XZ plane (normal +Y) with UVs `(x, z)`, two triangles.
    fn square(uv_scale: f32) -> Mesh {
        let p = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 0.0, 1.0],
            [0.0, 0.0, 1.0],
        ];
        Mesh {
            name: "square".into(),
            positions: p.iter().map(|v| Vec3::from_array(*v)).collect(),
            normals: vec![Vec3::Y; 4],
            indices: vec![[0, 2, 1], [0, 3, 2]],
            material: 0,
            texcoords: vec![p
                .iter()
                .map(|v| [v[0] * uv_scale, v[2] * uv_scale])
                .collect()],
            colors: Vec::new(),
        }
    }

    #[test]
    fn a_square_filling_the_unit_square_covers_every_texel_at_its_centre() {
        let lm = lightmap(&square(1.0), 8, 4).unwrap();
        assert_eq!(lm.covered(), 32);
        for y in 0..4 {
            for x in 0..8 {
                let t = lm.texels[y * 8 + x].unwrap();
                // The surface point under the texel centre: (u, v) = (x, z).
                let want = Vec3::new((x as f32 + 0.5) / 8.0, 0.0, (y as f32 + 0.5) / 4.0);
                assert!(
                    (t.position - want).length() < 1e-6,
                    "{x},{y}: {}",
                    t.position
                );
                assert!(t.centre_inside);
                assert_eq!(t.normal, Vec3::Y);
            }
        }
    }

    #[test]
    fn edge_texels_are_covered_conservatively_on_the_surface() {
        // UVs over [0, 0.42]²: in an 8×8 lightmap the square reaches texel coordinate 3.36,
        // so texel 3's centre (3.5) lies outside while its square meets the triangles.
        let lm = lightmap(&square(0.42), 8, 8).unwrap();
        let covered: Vec<usize> = (0..64).filter(|&k| lm.texels[k].is_some()).collect();
        assert_eq!(covered.len(), 16, "{covered:?}");
        let edge = lm.texels[3].unwrap();
        assert!(!edge.centre_inside);
        // Nearest surface point: u clamped to 0.42 → x = 1.
        assert!((edge.position.x - 1.0).abs() < 1e-6, "{}", edge.position);
        assert!(edge.bary.iter().all(|b| (0.0..=1.0).contains(b)));
        assert!(lm.texels[4].is_none());
    }

    #[test]
    fn uvs_outside_the_unit_square_and_overlaps_are_errors() {
        let e = lightmap(&square(1.25), 8, 8).unwrap_err();
        assert_eq!(
            e,
            LightmapError::OutOfRange {
                vertices: 3,
                of: 4,
                worst: 0.25
            }
        );
        // Two copies of the square on the same UVs: every texel covered twice, except the 4
        // whose centres lie on the diagonal edge (inside no triangle's interior).
        let mut m = square(1.0);
        m.indices.extend([[0, 2, 1], [0, 3, 2]]);
        match lightmap(&m, 4, 4).unwrap_err() {
            LightmapError::Overlap { texels, of } => assert_eq!((texels, of), (12, 16)),
            other => panic!("{other:?}"),
        }
        let mut m = square(1.0);
        m.texcoords.clear();
        assert_eq!(lightmap(&m, 4, 4).unwrap_err(), LightmapError::NoUvs);
    }

    #[test]
    fn a_triangle_clipping_a_texel_corner_covers_it_and_edge_contacts_do_not() {
        // Texel units (4×4 map): a sliver whose edge from (1.97, 2.05) to (2.1, 1.4) crosses the
        // interior of texel (1, 1)'s square (1, 2)² near its corner (2, 2), while its point
        // nearest to that texel's centre (1.5, 1.5) is (2.058, 1.612), outside the square.
        let mut m = square(1.0);
        let uv = |p: [f32; 2]| [p[0] / 4.0, p[1] / 4.0];
        let corners = vec![
            [uv([1.97, 2.05]), uv([2.1, 1.4]), uv([2.5, 1.8])],
            [uv([0.0, 3.0]), uv([1.0, 3.0]), uv([1.0, 4.0])],
        ];
        let lm = lightmap_from_corners(&m, corners.clone(), 4, 4).unwrap();
        let t = lm.texels[4 + 1].expect("texel (1, 1) is touched");
        assert!(!t.centre_inside);
        // Its point: the nearest point of the triangle, on the edge, outside the texel.
        let p = DVec2::new(1.5, 1.5);
        let want = closest_point(
            DVec2::new(1.97, 2.05),
            DVec2::new(2.1, 1.4),
            DVec2::new(2.5, 1.8),
            p,
        );
        assert!(want.x > 2.0, "{want}");
        // The second triangle only meets texel (1, 3) and (0, 2) along an edge or a corner.
        assert!(lm.texels[3 * 4].is_some());
        assert!(lm.texels[3 * 4 + 1].is_none() && lm.texels[2 * 4].is_none());
        // One corner UV per triangle corner: split into 6 vertices (no shared UVs).
        let (source, tris, uvs) = split_corners(&m.indices, &corners);
        assert_eq!(source, vec![0, 2, 1, 0, 3, 2]);
        assert_eq!(tris, vec![[0, 1, 2], [3, 4, 5]]);
        assert_eq!(uvs[4], corners[1][1]);
        // Corners sharing a vertex and a UV are one vertex.
        let same = vec![
            [[0.0, 0.0], [1.0, 1.0], [1.0, 0.0]],
            [[0.0, 0.0], [0.0, 1.0], [1.0, 1.0]],
        ];
        let (source, tris, _) = split_corners(&m.indices, &same);
        assert_eq!((source.len(), tris[1]), (4, [0, 3, 1]));
        m.indices.pop();
        assert!(lightmap_from_corners(&m, same, 4, 4).is_err());
    }

    #[test]
    fn bilinear_lookup_interpolates_and_renormalises_over_covered_texels() {
        // A 2×1 map with values 0 and 1: halfway between the centres gives 0.5, at a centre
        // its value, beyond the border the edge texel.
        let v = |k: usize| [k as f32; 3];
        let all = |_| true;
        assert_eq!(bilinear(2, 1, all, v, [0.5, 0.5]).unwrap()[0], 0.5);
        assert_eq!(bilinear(2, 1, all, v, [0.25, 0.5]).unwrap()[0], 0.0);
        assert_eq!(bilinear(2, 1, all, v, [1.0, 0.5]).unwrap()[0], 1.0);
        // Texel 0 empty: the lookup takes texel 1 alone.
        assert_eq!(bilinear(2, 1, |k| k == 1, v, [0.4, 0.5]).unwrap()[0], 1.0);
        assert!(bilinear(2, 1, |_| false, v, [0.4, 0.5]).is_none());
    }
}
