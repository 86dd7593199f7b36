//! Shared helpers of the prt-wavelet tests: a deterministic random stream, test functions on
//! lat-long grids and the oracle data.
#![allow(dead_code)]

use std::f64::consts::PI;

use prt_wavelet::{Boundaries, Boundary};

/// SplitMix64: a small deterministic stream, enough for random test data.
pub struct Rng(u64);

impl Rng {
    pub fn new(seed: u64) -> Rng {
        Rng(seed)
    }

    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in [-1, 1).
    pub fn signed(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    }

    pub fn vec(&mut self, n: usize) -> Vec<f64> {
        (0..n).map(|_| self.signed()).collect()
    }
}

pub const ALL_BOUNDARIES: [Boundaries; 4] = [
    Boundaries::PERIODIC,
    Boundaries::LAT_LONG,
    Boundaries {
        x: Boundary::Symmetric,
        y: Boundary::Periodic,
    },
    Boundaries {
        x: Boundary::Symmetric,
        y: Boundary::Symmetric,
    },
];

pub fn max_abs(v: &[f64]) -> f64 {
    v.iter().fold(0.0, |m, x| m.max(x.abs()))
}

pub fn max_abs_diff(a: &[f64], b: &[f64]) -> f64 {
    assert_eq!(a.len(), b.len());
    a.iter().zip(b).fold(0.0, |m, (x, y)| m.max((x - y).abs()))
}

/// The direction of texel centre (x, y) of a `w × h` lat-long map (CONVENTIONS.md).
pub fn direction(x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
    let phi = 2.0 * PI * (x as f64 + 0.5) / w as f64;
    let theta = PI * (y as f64 + 0.5) / h as f64;
    [
        phi.sin() * theta.sin(),
        theta.cos(),
        -phi.cos() * theta.sin(),
    ]
}

fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn normalize(a: [f64; 3]) -> [f64; 3] {
    let n = dot(a, a).sqrt();
    [a[0] / n, a[1] / n, a[2] / n]
}

/// A reflectance-function-like test map on a `w × h` lat-long grid: a smooth broad lobe and
/// a glossy lobe (peaks 0.6 and 0.8 over 0.05), plus a sharp-edged feature of height `edge` —
/// a disc of 18° radius with a hard boundary (a highlight of an area light, or a shadow's hole).
pub fn lobes_and_disc(w: usize, h: usize, edge: f64) -> Vec<f64> {
    let broad = normalize([0.3, 0.8, -0.4]);
    let glossy = normalize([-0.5, 0.4, 0.6]);
    let disc = normalize([0.7, 0.2, 0.3]);
    let cos_radius = 18f64.to_radians().cos();
    let mut f = Vec::with_capacity(w * h);
    for y in 0..h {
        for x in 0..w {
            let d = direction(x, y, w, h);
            let smooth = 0.6 * (4.0 * (dot(d, broad) - 1.0)).exp()
                + 0.8 * (25.0 * (dot(d, glossy) - 1.0)).exp();
            let disc = if dot(d, disc) > cos_radius { edge } else { 0.0 };
            f.push(0.05 + smooth + disc);
        }
    }
    f
}

/// [`lobes_and_disc`] with a disc of height 0.1: a smooth bump plus a sharp-edged feature.
pub fn bump_and_edge(w: usize, h: usize) -> Vec<f64> {
    lobes_and_disc(w, h, 0.1)
}

/// The committed oracle data (tools/wavelet_oracle.py).
pub fn oracle() -> serde_json::Value {
    let path =
        std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/wavelet_oracle.json");
    let text = std::fs::read_to_string(&path).expect("tests/data/wavelet_oracle.json");
    serde_json::from_str(&text).expect("oracle JSON")
}

pub fn floats(v: &serde_json::Value) -> Vec<f64> {
    v.as_array()
        .expect("array")
        .iter()
        .map(|x| x.as_f64().expect("number"))
        .collect()
}

pub fn usize_of(v: &serde_json::Value) -> usize {
    v.as_u64().expect("integer") as usize
}
