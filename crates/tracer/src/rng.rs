//! Deterministic random streams: one PCG stream per (seed, purpose, index, sample).
//!
//! The four numbers are combined by a chain of SplitMix64 finalisers (Steele, Lea & Flood
//! 2014; the mixer of `java.util.SplittableRandom`):
//! `h = mix(mix(mix(mix(seed) ^ purpose) ^ index) ^ sample)`, and the PCG-XSH-RR 64/32
//! generator ([`Pcg32`], O'Neill 2014) is started with state `h` and stream selector
//! `mix(h ^ 0x9E37_79B9_7F4A_7C15)`. Because a stream depends only on these four numbers,
//! an image or a set of point estimates is bit-identical for any thread count or tile order.

use rand::Rng;
use rand_pcg::Pcg32;

/// What a random stream is used for (part of the seed, so purposes never share streams).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u64)]
pub enum Purpose {
    /// Camera paths of an image render (index = pixel index `y·width + x`).
    Pixel = 0x7069_7865_6c00_0001,
    /// Paths leaving given surface points (index = point index).
    Point = 0x706f_696e_7400_0002,
}

/// The SplitMix64 finaliser: a bijection of `u64` with full avalanche.
#[must_use]
pub fn mix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The stream for `(seed, purpose, index, sample)` (see the module docs for the mixer).
#[must_use]
pub fn stream(seed: u64, purpose: Purpose, index: u64, sample: u64) -> Sampler {
    let h = mix64(mix64(mix64(mix64(seed) ^ purpose as u64) ^ index) ^ sample);
    Sampler(Pcg32::new(h, mix64(h ^ 0x9E37_79B9_7F4A_7C15)))
}

/// Uniform numbers in `[0, 1)` from one PCG stream.
#[derive(Clone, Debug)]
pub struct Sampler(Pcg32);

impl Sampler {
    /// One number in `[0, 1)` (24 random bits, so never rounds up to 1).
    pub fn next_f32(&mut self) -> f32 {
        (self.0.random::<u32>() >> 8) as f32 * (1.0 / 16_777_216.0)
    }

    /// Two numbers.
    pub fn next_2d(&mut self) -> [f32; 2] {
        [self.next_f32(), self.next_f32()]
    }

    /// Three numbers.
    pub fn next_3d(&mut self) -> [f32; 3] {
        [self.next_f32(), self.next_f32(), self.next_f32()]
    }
}
