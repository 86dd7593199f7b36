//! Lightmap atlases for meshes without UVs (`prt bake --per-texel` on such a mesh).
//!
//! A deterministic chart generator and packer in the spirit of the classic lightmap
//! parameterisations (normal-cone charts as in Sander et al., "Texture Mapping Progressive
//! Meshes", SIGGRAPH 2001, and Lévy et al., "Least Squares Conformal Maps", SIGGRAPH 2002,
//! here with a planar projection instead of a conformal solve; shelf packing as surveyed by
//! Jylänki, "A Thousand Ways to Pack the Bin", 2010):
//!
//! 1. **Charts.** Triangles are grown into charts breadth first over shared edges (vertices
//!    welded by position), seeds in triangle order, while each triangle's normal stays within
//!    [`AtlasOptions::max_angle_deg`] of the seed's normal. Each chart is projected onto the
//!    seed's plane: a triangle at angle `θ` from it is shortened by `cos θ` across the fold
//!    (bounded distortion: at most `1/cos θ`), every projected triangle keeps its orientation,
//!    and a triangle joins only if its projection overlaps none of the chart's (a separating
//!    axis test), so the map is one to one.
//! 2. **One texel density.** All charts are scaled by the same `s` texels per world unit, the
//!    largest (bisection) at which they still pack: texels cover the surface uniformly.
//! 3. **Packing.** Each chart's bounding box, rounded up to whole texels, is placed with a
//!    **gutter** of [`AtlasOptions::gutter`] texels (2 by default) between any two charts by
//!    shelf packing, tallest first; chart content is inset by `gutter / 2` in its cell, so
//!    two charts' boxes lie at least `gutter` texels apart. Why 2 is enough: the bake
//!    rasterises conservatively — a texel whose square touches a chart is baked for it — so a
//!    chart whose box ends at `x = a` claims texels up to index `⌈a⌉ − 1`, and a chart starting
//!    at `a + 2` claims from `⌊a + 2⌋ ≥ ⌈a⌉ + 1`: one empty texel at least between them, so no
//!    texel is claimed by two charts. A bilinear lookup at a point `p ≤ a` of the first chart
//!    reads texels `⌊p − ½⌋` and `⌊p − ½⌋ + 1 ≤ ⌈a⌉`, never the second chart's (the empty
//!    texel's weight is dropped by the renormalised lookup, and an engine's plain bilinear
//!    reads the dilated value there). [`check`] tests exactly this on the texel grid.
//! 4. **UVs** are quantised to multiples of 2⁻²⁴ ([`UV_QUANTUM`]): exact in f32, f64 and as
//!    JSON integers, so the bake file carries them without rounding (SPEC §3.9.3).
//!
//! No threads: the result is a pure function of the mesh and options.

mod chart;
mod pack;

use chart::{bounds, charts, overlap, Chart, ChartLimits};
use glam::{DVec2, Vec3};

/// UVs are multiples of `1 / UV_QUANTUM` (2²⁴): exact in f32 for every value in `[0, 1]`.
pub const UV_QUANTUM: u32 = 1 << 24;

/// How an atlas is generated.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtlasOptions {
    /// Lightmap width in texels.
    pub width: u32,
    /// Lightmap height in texels.
    pub height: u32,
    /// Empty texels between any two charts (and, halved, at the lightmap's border).
    pub gutter: u32,
    /// The largest angle (degrees) between a triangle's normal and its chart's seed normal.
    pub max_angle_deg: f64,
    /// The most triangles one chart holds.
    pub max_chart_triangles: usize,
}

impl AtlasOptions {
    /// The defaults for a `width × height` lightmap: gutter 2, cone 45°, charts of at most
    /// 512 triangles.
    #[must_use]
    pub fn new(width: u32, height: u32) -> Self {
        AtlasOptions {
            width,
            height,
            gutter: 2,
            max_angle_deg: 45.0,
            max_chart_triangles: 512,
        }
    }
}

/// A generated atlas: UVs per triangle corner (glTF convention, `[0, 1]²`).
#[derive(Clone, Debug, PartialEq)]
pub struct Atlas {
    /// Per triangle, its corners' UVs, each a multiple of `1 / UV_QUANTUM`.
    pub corner_uvs: Vec<[[f32; 2]; 3]>,
    /// Per triangle, its chart.
    pub chart_of: Vec<u32>,
    /// How many charts.
    pub charts: usize,
    /// Texels per world unit (the same for every chart).
    pub texels_per_unit: f64,
    /// Fraction of the lightmap's area inside triangles.
    pub utilisation: f64,
}

impl Atlas {
    /// The corner UVs as integers `n` (UV = `n / UV_QUANTUM`), triangle by triangle, `[u, v]`
    /// per corner: how the bake file stores them.
    #[must_use]
    pub fn quantised(&self) -> Vec<u32> {
        self.corner_uvs
            .iter()
            .flatten()
            .flatten()
            .map(|&c| (f64::from(c) * f64::from(UV_QUANTUM)).round() as u32)
            .collect()
    }
}

/// Why no atlas was generated.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum AtlasError {
    /// Nothing to map.
    #[error("the mesh has no triangles")]
    NoTriangles,
    /// A position that is not finite, or a vertex index out of range.
    #[error("triangle {0} has a non-finite position or a vertex index out of range")]
    BadTriangle(usize),
    /// Too many charts for the lightmap even at the smallest density.
    #[error("its {charts} charts do not fit in a {width}×{height} lightmap with a {gutter}-texel gutter: use a larger --per-texel size")]
    DoesNotFit {
        /// Charts generated.
        charts: usize,
        /// Lightmap width.
        width: u32,
        /// Lightmap height.
        height: u32,
        /// Gutter in texels.
        gutter: u32,
    },
}

/// Generates the atlas of a mesh (world-space `positions`, triangles `indices`).
///
/// # Errors
/// [`AtlasError`]: no triangles, bad triangles, or charts that do not fit.
pub fn generate(
    positions: &[Vec3],
    indices: &[[u32; 3]],
    opt: &AtlasOptions,
) -> Result<Atlas, AtlasError> {
    if indices.is_empty() {
        return Err(AtlasError::NoTriangles);
    }
    for (t, tri) in indices.iter().enumerate() {
        if tri
            .iter()
            .any(|&i| positions.get(i as usize).is_none_or(|p| !p.is_finite()))
        {
            return Err(AtlasError::BadTriangle(t));
        }
    }
    let limits = ChartLimits {
        cos_cone: opt.max_angle_deg.to_radians().cos(),
        max_triangles: opt.max_chart_triangles.max(1),
    };
    let mut charts = charts(positions, indices, limits);
    // Each chart from its bounding box's corner, wider than tall (a quarter turn keeps the
    // orientation).
    let extents: Vec<DVec2> = charts.iter_mut().map(normalise).collect();
    let fail = AtlasError::DoesNotFit {
        charts: charts.len(),
        width: opt.width,
        height: opt.height,
        gutter: opt.gutter,
    };
    let layout = |s: f64| {
        let sizes: Vec<(u32, u32)> = extents
            .iter()
            .map(|e| {
                let cell = |x: f64| ((x * s).ceil().max(1.0) as u32).saturating_add(opt.gutter);
                (cell(e.x), cell(e.y))
            })
            .collect();
        pack::shelf_pack(&sizes, opt.width, opt.height)
    };
    // Bisection on the density between one that fits (0: every chart one texel) and one
    // that cannot (the charts' boxes alone fill the map).
    let boxes: f64 = extents.iter().map(|e| e.x * e.y).sum();
    let (mut lo, mut hi) = (
        0.0f64,
        (f64::from(opt.width) * f64::from(opt.height) / boxes.max(f64::MIN_POSITIVE)).sqrt() * 1.01,
    );
    let mut best = layout(lo).ok_or(fail)?;
    if let Some(l) = layout(hi) {
        (lo, best) = (hi, l);
    } else {
        for _ in 0..40 {
            let mid = 0.5 * (lo + hi);
            match layout(mid) {
                Some(l) => (lo, best) = (mid, l),
                None => hi = mid,
            }
        }
    }
    Ok(place(&charts, &best, lo, indices.len(), opt))
}

/// Moves a chart's corners to start at its bounding box's origin, wider than tall; returns
/// the box's extent.
fn normalise(c: &mut Chart) -> DVec2 {
    let (mut lo, mut hi) = (DVec2::INFINITY, DVec2::NEG_INFINITY);
    for t in &c.corners {
        let (a, b) = bounds(t);
        (lo, hi) = (lo.min(a), hi.max(b));
    }
    let e = hi - lo;
    let turn = e.y > e.x;
    for t in &mut c.corners {
        for p in t.iter_mut() {
            let q = *p - lo;
            // A quarter turn: (x, y) → (e.y − y, x).
            *p = if turn { DVec2::new(e.y - q.y, q.x) } else { q };
        }
    }
    if turn {
        DVec2::new(e.y, e.x)
    } else {
        e
    }
}

/// The atlas of charts placed at cells `at` with density `s`.
fn place(
    charts: &[Chart],
    at: &[(u32, u32)],
    s: f64,
    triangles: usize,
    opt: &AtlasOptions,
) -> Atlas {
    let (w, h) = (f64::from(opt.width), f64::from(opt.height));
    let inset = f64::from(opt.gutter / 2);
    let q = f64::from(UV_QUANTUM);
    let mut corner_uvs = vec![[[0.0f32; 2]; 3]; triangles];
    let mut chart_of = vec![0u32; triangles];
    let mut area = 0.0;
    for (ci, (c, &(x, y))) in charts.iter().zip(at).enumerate() {
        let origin = DVec2::new(f64::from(x) + inset, f64::from(y) + inset);
        for (&t, corners) in c.triangles.iter().zip(&c.corners) {
            let texel = corners.map(|p| origin + p * s);
            area += 0.5 * chart::signed_area(&texel).abs();
            corner_uvs[t as usize] = texel.map(|p| {
                let quant = |v: f64, size: f64| ((v / size * q).round().clamp(0.0, q) / q) as f32;
                [quant(p.x, w), quant(p.y, h)]
            });
            chart_of[t as usize] = ci as u32;
        }
    }
    Atlas {
        corner_uvs,
        chart_of,
        charts: charts.len(),
        texels_per_unit: s,
        utilisation: area / (w * h),
    }
}

/// Checks an atlas independently of how it was made: every UV in `[0, 1]`, no two
/// triangles of a chart overlapping, and the texels that conservative rasterisation gives
/// each chart (texels whose square meets the chart's bounding box) at least `gutter − 1`
/// texels from any other chart's — so the 2 × 2 texels a bilinear lookup reads anywhere
/// on one chart are never baked for another.
///
/// # Errors
/// A message naming the first violation.
pub fn check(atlas: &Atlas, width: u32, height: u32, gutter: u32) -> Result<(), String> {
    let (w, h) = (f64::from(width), f64::from(height));
    let mut boxes: Vec<(DVec2, DVec2)> = vec![(DVec2::INFINITY, DVec2::NEG_INFINITY); atlas.charts];
    let mut by_chart: Vec<Vec<[DVec2; 3]>> = vec![Vec::new(); atlas.charts];
    for (t, (uv, &c)) in atlas.corner_uvs.iter().zip(&atlas.chart_of).enumerate() {
        if uv.iter().flatten().any(|v| !(0.0..=1.0).contains(v)) {
            return Err(format!("triangle {t}: UVs {uv:?} outside [0, 1]"));
        }
        let texel = uv.map(|p| DVec2::new(f64::from(p[0]) * w, f64::from(p[1]) * h));
        let (lo, hi) = bounds(&texel);
        let b = &mut boxes[c as usize];
        *b = (b.0.min(lo), b.1.max(hi));
        by_chart[c as usize].push(texel);
    }
    for (c, tris) in by_chart.iter().enumerate() {
        for i in 0..tris.len() {
            for j in 0..i {
                if overlap(&tris[i], &tris[j]) {
                    return Err(format!("chart {c}: two triangles overlap"));
                }
            }
        }
    }
    // Conservative texel ranges of each chart: [floor(lo), ceil(hi)).
    let texels: Vec<([i64; 2], [i64; 2])> = boxes
        .iter()
        .map(|(lo, hi)| {
            (
                [lo.x.floor() as i64, lo.y.floor() as i64],
                [hi.x.ceil() as i64, hi.y.ceil() as i64],
            )
        })
        .collect();
    let need = i64::from(gutter) - 1;
    for a in 0..texels.len() {
        for b in 0..a {
            let (al, ah) = texels[a];
            let (bl, bh) = texels[b];
            let gap = (bl[0] - ah[0])
                .max(al[0] - bh[0])
                .max(bl[1] - ah[1])
                .max(al[1] - bh[1]);
            if gap < need {
                return Err(format!(
                    "charts {a} and {b}: {gap} empty texels between their texels, fewer than {need}"
                ));
            }
        }
    }
    Ok(())
}
