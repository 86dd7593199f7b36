//! `LatLongGrid` against the lat-long mapping of CONVENTIONS.md (`latlong_uv`,
//! `EnvImage::latlong_texel`): the same texel for every direction not within an f64
//! rounding of a texel edge, and in-texel directions that land back in their texel.

use glam::DVec3;
use prt_scene::envmap::{latlong_direction, latlong_uv, LatLongGrid};
use prt_scene::EnvImage;
use std::f64::consts::{PI, TAU};

/// SplitMix64 as uniform numbers in `[0, 1)` (a fixed, dependency-free stream).
struct Uniform(u64);

impl Uniform {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn direction(&mut self) -> DVec3 {
        let y = 2.0 * self.next() - 1.0;
        let phi = TAU * self.next();
        let s = (1.0 - y * y).max(0.0).sqrt();
        DVec3::new(s * phi.cos(), y, s * phi.sin())
    }
}

fn image(width: usize, height: usize) -> EnvImage {
    EnvImage {
        width,
        height,
        texels: vec![[0.0; 3]; width * height],
    }
}

/// Distance of `x · n` to the nearest integer, in units of `x` (how close a coordinate is
/// to a texel edge).
fn edge_distance(x: f64, n: usize) -> f64 {
    let s = x * n as f64;
    (s - s.round()).abs() / n as f64
}

const SIZES: [(usize, usize); 7] = [
    (7, 3),
    (16, 8),
    (64, 32),
    (37, 19),
    (100, 50),
    (1024, 512),
    (4096, 2048),
];

#[test]
fn texel_matches_the_atan2_acos_lookup() {
    let mut rng = Uniform(7);
    for (w, h) in SIZES {
        let (grid, img) = (LatLongGrid::new(w, h), image(w, h));
        let mut checked = 0;
        for _ in 0..200_000 {
            let d = rng.direction();
            let (u, v) = latlong_uv(d);
            // 1e-12 of the unit square is ~6e-12 rad: far above f64 rounding, far below
            // anything a direction in f32 can resolve.
            if edge_distance(u, w) < 1e-12 || edge_distance(v, h) < 1e-12 {
                continue;
            }
            assert_eq!(grid.texel(d), img.latlong_texel(d), "{w}×{h}, {d}");
            checked += 1;
        }
        assert!(checked > 199_000, "{checked}");
    }
}

#[test]
fn texel_at_poles_seams_and_edges() {
    for (w, h) in SIZES {
        let (grid, img) = (LatLongGrid::new(w, h), image(w, h));
        // Poles, the seam at −Z (u = 0), its negative-zero twin, ±X and +Z.
        for d in [
            DVec3::Y,
            DVec3::NEG_Y,
            DVec3::NEG_Z,
            DVec3::new(-0.0, 0.0, -1.0),
            DVec3::X,
            DVec3::NEG_X,
            DVec3::Z,
        ] {
            assert_eq!(grid.texel(d), img.latlong_texel(d), "{w}×{h}, {d}");
        }
        // Just either side of the seam: column W − 1 below it, column 0 above.
        let below = latlong_direction(TAU - 1e-9, 1.0);
        let above = latlong_direction(1e-9, 1.0);
        assert_eq!(grid.texel(below).0, w - 1, "{w}×{h}");
        assert_eq!(grid.texel(above).0, 0, "{w}×{h}");
        // On every edge the grid picks one of the two texels the edge separates.
        for c in 0..w {
            let d = latlong_direction(TAU * c as f64 / w as f64, 1.3);
            let got = grid.texel(d).0;
            assert!(
                got == c || got == (c + w - 1) % w,
                "{w}×{h} column edge {c}: {got}"
            );
        }
        for r in 1..h {
            let d = latlong_direction(0.4, PI * r as f64 / h as f64);
            let got = grid.texel(d).1;
            assert!(got == r || got + 1 == r, "{w}×{h} row edge {r}: {got}");
        }
    }
}

#[test]
fn directions_inside_a_texel_land_back_in_it() {
    let mut rng = Uniform(11);
    for (w, h) in SIZES {
        let grid = LatLongGrid::new(w, h);
        for i in 0..50_000 {
            let (c, r) = (
                (rng.next() * w as f64) as usize,
                (rng.next() * h as f64) as usize,
            );
            // Interior positions, plus the texel's corner (rem = 0) every tenth draw.
            let rem = if i % 10 == 0 {
                [0.0, 0.0]
            } else {
                [rng.next(), rng.next()]
            };
            let d = grid.direction(c, r, rem);
            assert!((d.length() - 1.0).abs() < 1e-15, "{d}");
            // The same direction as the libm formula: φ uniform over the column, cos θ
            // uniform over the row.
            let phi = TAU * (c as f64 + rem[0]) / w as f64;
            let (c0, c1) = (grid.row_cos()[r], grid.row_cos()[r + 1]);
            let cos_t = c0 + rem[1] * (c1 - c0);
            let sin_t = (1.0 - cos_t * cos_t).max(0.0).sqrt();
            let (sp, cp) = phi.sin_cos();
            let libm = DVec3::new(sp * sin_t, cos_t, -cp * sin_t);
            // A few f64 roundings of the rotation (the series itself is below 1e-15).
            assert!(
                (d - libm).length() < 2e-15,
                "{w}×{h} ({c}, {r}) {rem:?}: {d} {libm}"
            );
            if rem != [0.0, 0.0] {
                assert_eq!(grid.texel(d), (c, r), "{w}×{h} {rem:?}");
            } else {
                // The corner lies on two edges: either neighbour is a valid texel for it (and
                // row 0's corner is the pole, which every column touches).
                let (gc, gr) = grid.texel(d);
                assert!(
                    r == 0 || gc == c || gc == (c + w - 1) % w,
                    "{w}×{h} corner column"
                );
                assert!(gr == r || gr + 1 == r, "{w}×{h} corner row");
            }
        }
    }
}
