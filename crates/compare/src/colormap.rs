//! The viridis colour map: perceptually uniform, readable in gray and by colour-blind viewers.
//!
//! Viridis was designed by Stéfan van der Walt and Nathaniel Smith for matplotlib (2015,
//! released under CC0). The 33 stops below are entries `round(255 k / 32)`, k = 0…32, of its
//! published 256-entry table (as shipped in matplotlib 3.11,
//! `matplotlib.colormaps["viridis"].colors`), placed at `t = index / 255`; between stops the
//! map is linear in sRGB-encoded values. The linear interpolation stays within 0.007 (under
//! 2/255) of the full table; the tests check this against the whole table, written by
//! `tools/compare_reference.py`. (17 stops would be 0.023 off near the top end, where the
//! blue channel passes through its minimum.)

/// `(t, [r, g, b])` stops of viridis, sRGB-encoded components in [0, 1].
pub const VIRIDIS_STOPS: [(f64, [f64; 3]); 33] = [
    (0.0 / 255.0, [0.267004, 0.004874, 0.329415]),
    (8.0 / 255.0, [0.277018, 0.050344, 0.375715]),
    (16.0 / 255.0, [0.282327, 0.094955, 0.417331]),
    (24.0 / 255.0, [0.282884, 0.13592, 0.453427]),
    (32.0 / 255.0, [0.278826, 0.17549, 0.483397]),
    (40.0 / 255.0, [0.270595, 0.214069, 0.507052]),
    (48.0 / 255.0, [0.258965, 0.251537, 0.524736]),
    (56.0 / 255.0, [0.244972, 0.287675, 0.53726]),
    (64.0 / 255.0, [0.229739, 0.322361, 0.545706]),
    (72.0 / 255.0, [0.214298, 0.355619, 0.551184]),
    (80.0 / 255.0, [0.19943, 0.387607, 0.554642]),
    (88.0 / 255.0, [0.185556, 0.41857, 0.556753]),
    (96.0 / 255.0, [0.172719, 0.448791, 0.557885]),
    (104.0 / 255.0, [0.160665, 0.47854, 0.558115]),
    (112.0 / 255.0, [0.149039, 0.508051, 0.55725]),
    (120.0 / 255.0, [0.13777, 0.537492, 0.554906]),
    (128.0 / 255.0, [0.127568, 0.566949, 0.550556]),
    (135.0 / 255.0, [0.121148, 0.592739, 0.544641]),
    (143.0 / 255.0, [0.120081, 0.622161, 0.534946]),
    (151.0 / 255.0, [0.130067, 0.651384, 0.521608]),
    (159.0 / 255.0, [0.153894, 0.680203, 0.504172]),
    (167.0 / 255.0, [0.19109, 0.708366, 0.482284]),
    (175.0 / 255.0, [0.239374, 0.735588, 0.455688]),
    (183.0 / 255.0, [0.296479, 0.761561, 0.424223]),
    (191.0 / 255.0, [0.360741, 0.785964, 0.387814]),
    (199.0 / 255.0, [0.430983, 0.808473, 0.346476]),
    (207.0 / 255.0, [0.506271, 0.828786, 0.300362]),
    (215.0 / 255.0, [0.585678, 0.846661, 0.249897]),
    (223.0 / 255.0, [0.668054, 0.861999, 0.196293]),
    (231.0 / 255.0, [0.751884, 0.874951, 0.143228]),
    (239.0 / 255.0, [0.83527, 0.886029, 0.102646]),
    (247.0 / 255.0, [0.916242, 0.896091, 0.100717]),
    (1.0, [0.993248, 0.906157, 0.143936]),
];

/// Viridis at `t` (clamped to [0, 1]; NaN maps to 0), sRGB-encoded components in [0, 1].
#[must_use]
pub fn viridis(t: f64) -> [f64; 3] {
    let t = if t.is_nan() { 0.0 } else { t.clamp(0.0, 1.0) };
    let i = VIRIDIS_STOPS
        .iter()
        .rposition(|&(s, _)| s <= t)
        .unwrap_or(0)
        .min(VIRIDIS_STOPS.len() - 2);
    let (t0, c0) = VIRIDIS_STOPS[i];
    let (t1, c1) = VIRIDIS_STOPS[i + 1];
    let w = ((t - t0) / (t1 - t0)).clamp(0.0, 1.0);
    [0, 1, 2].map(|k| c0[k] + w * (c1[k] - c0[k]))
}

/// Viridis at `t` as 8-bit sRGB.
#[must_use]
pub fn viridis_rgb8(t: f64) -> [u8; 3] {
    viridis(t).map(|v| (v * 255.0).round().clamp(0.0, 255.0) as u8)
}
