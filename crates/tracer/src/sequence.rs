//! Per-point sample sequences: the R2 low-discrepancy sequence (Roberts 2018, the 2D
//! generalisation of the golden-ratio sequence) with a per-point random Cranley–Patterson
//! shift from a PCG stream keyed by (seed, purpose, object, point) — deterministic, and
//! well stratified for any ray count (not only squares).

use crate::rng::mix64;

/// What a point's sequence is for; part of the key so purposes never share shifts.
#[derive(Clone, Copy, Debug)]
#[repr(u64)]
pub enum SequencePurpose {
    /// Cosine-weighted directions for diffuse transfer.
    Diffuse = 0x6261_6b65_6466_0001,
    /// Uniform-hemisphere directions for visibility.
    Visibility = 0x6261_6b65_7669_0002,
    /// Sub-pixel positions of a per-pixel bake's footprint.
    Footprint = 0x6261_6b65_6670_0003,
}

/// 1 / plastic number and its square: the R2 increments.
const A1: f64 = 0.754_877_666_246_692_7;
const A2: f64 = 0.569_840_290_998_053_3;

/// The shifted R2 points of one point.
#[derive(Clone, Copy, Debug)]
pub struct R2 {
    shift: [f64; 2],
}

impl R2 {
    /// The sequence of (seed, purpose, object, point).
    #[must_use]
    pub fn new(seed: u64, purpose: SequencePurpose, object: u64, point: u64) -> Self {
        let h = mix64(mix64(mix64(mix64(seed) ^ purpose as u64) ^ object) ^ point);
        let h2 = mix64(h);
        let to_unit = |x: u64| (x >> 11) as f64 * (1.0 / (1u64 << 53) as f64);
        Self {
            shift: [to_unit(h), to_unit(h2)],
        }
    }

    /// Sample `k` in `[0, 1)²` (rounded to f32 below 1).
    #[must_use]
    pub fn get(&self, k: u32) -> [f32; 2] {
        let kf = k as f64;
        let u = (0.5 + kf * A1 + self.shift[0]).fract();
        let v = (0.5 + kf * A2 + self.shift[1]).fract();
        [(u as f32).min(0.999_999_94), (v as f32).min(0.999_999_94)]
    }
}
