//! Deterministic random streams: one PCG stream per (seed, purpose, index, sample).
//!
//! The four numbers are combined by a chain of SplitMix64 finalisers (Steele, Lea & Flood
//! 2014; the mixer of `java.util.SplittableRandom`):
//! `h = mix(mix(mix(mix(seed) ^ purpose) ^ index) ^ sample)`, and the PCG-XSH-RR 64/32
//! generator ([`Pcg32`], O'Neill 2014) is started with state `h` and stream selector
//! `mix(h ^ 0x9E37_79B9_7F4A_7C15)`. Because a stream depends only on these four numbers,
//! an image or a set of point estimates is bit-identical for any thread count or tile order.

use crate::settings::SamplerKind;
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
    stream_from_pixel_hash(mix64(mix64(mix64(seed) ^ purpose as u64) ^ index), sample)
}

/// [`stream`] from the hash of its first three numbers (`mix(mix(mix(seed) ^ purpose) ^ index)`).
fn stream_from_pixel_hash(index_hash: u64, sample: u64) -> Sampler {
    Sampler {
        pcg: Lazy::Pending(mix64(index_hash ^ sample)),
        qmc: None,
    }
}

/// A PCG stream started on first use: a camera path of a few bounces draws all its numbers
/// from the quasi-random dimensions and never needs it.
#[derive(Clone, Debug)]
enum Lazy {
    /// Not started; holds `h`.
    Pending(u64),
    Started(Pcg32),
}

impl Lazy {
    fn next_u32(&mut self) -> u32 {
        if let Lazy::Pending(h) = *self {
            *self = Lazy::Started(Pcg32::new(h, mix64(h ^ 0x9E37_79B9_7F4A_7C15)));
        }
        match self {
            Lazy::Started(pcg) => pcg.random::<u32>(),
            Lazy::Pending(_) => unreachable!("started above"),
        }
    }
}

/// Dimensions of a camera path taken from the scrambled Sobol points (camera jitter, then
/// about five per bounce); later ones come from the sample's PCG stream.
pub const QMC_DIMENSIONS: u32 = 24;

/// The sampler of sample `sample` of pixel `pixel`: randomised quasi-Monte Carlo. Samples
/// alternate between two independent *replicas* (even samples are replica 0, odd ones replica
/// 1); within a replica, sample `j` takes point `j` of the 2D Sobol (0,2)-sequence for each
/// consecutive pair of dimensions, with a hash-based Owen scrambling (nested uniform
/// scrambling, Owen 1995; the hash of Burley 2020, "Practical Hash-based Owen Scrambling")
/// and a scrambled point order, both keyed by (seed, pixel, replica, pair). Every point is
/// uniform in `[0, 1)²` (so estimates stay unbiased), the points of a replica are stratified
/// in every 2D projection of a pair, and the two replicas are independent, so the half images
/// of even and odd samples give an unbiased estimate of the error
/// ([`crate::RenderOutput::noise`]). Dimensions past [`QMC_DIMENSIONS`] are PCG numbers.
/// [`PixelKeys::sampler_of`] also gives the single-sequence sampler
/// ([`SamplerKind::Single`]).
#[must_use]
pub fn pixel_sampler(seed: u64, pixel: u64, sample: u64) -> Sampler {
    PixelKeys::new(seed, pixel).sampler(sample)
}

/// The hashes of `(seed, pixel)` that every sample of a pixel starts from, computed once per
/// pixel: `PixelKeys::new(seed, pixel).sampler(j)` is [`pixel_sampler`]`(seed, pixel, j)`.
#[derive(Clone, Copy, Debug)]
pub struct PixelKeys {
    /// `mix(mix(mix(seed) ^ Pixel) ^ pixel)`: the PCG streams' hash before the sample.
    stream: u64,
    /// The scrambling keys of replicas 0 and 1.
    qmc: [u64; 2],
}

impl PixelKeys {
    /// The keys of pixel `pixel` (index `y·width + x`) under `seed`.
    #[must_use]
    pub fn new(seed: u64, pixel: u64) -> Self {
        let ms = mix64(seed);
        let key = mix64(mix64(ms ^ Purpose::Pixel as u64 ^ 0x5142_4d43) ^ pixel);
        Self {
            stream: mix64(mix64(ms ^ Purpose::Pixel as u64) ^ pixel),
            qmc: [mix64(key), mix64(key ^ 1)],
        }
    }

    /// The sampler of sample `sample` of this pixel.
    #[must_use]
    pub fn sampler(&self, sample: u64) -> Sampler {
        self.sampler_of(SamplerKind::Replicas, sample)
    }

    /// The sampler of sample `sample` of this pixel for the sequences of `kind`: with
    /// [`SamplerKind::Replicas`], [`PixelKeys::sampler`]; with [`SamplerKind::Single`],
    /// point `sample` of the one sequence of replica 0's keys (so all of a pixel's samples
    /// are stratified together, and its PCG dimensions are those of the same sample).
    #[must_use]
    pub fn sampler_of(&self, kind: SamplerKind, sample: u64) -> Sampler {
        let (key, index) = match kind {
            SamplerKind::Replicas => (self.qmc[(sample & 1) as usize], sample >> 1),
            SamplerKind::Single => (self.qmc[0], sample),
        };
        let mut s = stream_from_pixel_hash(self.stream, sample);
        s.qmc = Some(Qmc {
            key,
            reversed_index: (index as u32).reverse_bits(),
            dim: 0,
            pending: 0,
        });
        s
    }
}

/// The quasi-random part of a pixel sampler.
#[derive(Clone, Debug)]
struct Qmc {
    key: u64,
    /// The sample's index in the sequence, bit-reversed (what the scrambling works on).
    reversed_index: u32,
    /// Next dimension.
    dim: u32,
    /// The second component of the pair whose first one was just taken.
    pending: u32,
}

/// Direction numbers of the second dimension of the Sobol sequence (the first is the bit
/// reversal of the index): `v_0 = 2^31`, `v_{k+1} = v_k ⊕ (v_k >> 1)` (Kollig & Keller 2002).
const fn sobol_dim1_directions() -> [u32; 32] {
    let mut v = [0u32; 32];
    v[0] = 1 << 31;
    let mut k = 1;
    while k < 32 {
        v[k] = v[k - 1] ^ (v[k - 1] >> 1);
        k += 1;
    }
    v
}

/// The second Sobol dimension is linear over GF(2) in the index bits: one table of the XOR of
/// the direction numbers per byte value and byte position.
const SOBOL_DIM1_BYTES: [[u32; 256]; 4] = {
    let v = sobol_dim1_directions();
    let mut t = [[0u32; 256]; 4];
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            let mut r = 0u32;
            let mut bit = 0;
            while bit < 8 {
                if value & (1 << bit) != 0 {
                    r ^= v[byte * 8 + bit];
                }
                bit += 1;
            }
            t[byte][value] = r;
            value += 1;
        }
        byte += 1;
    }
    t
};

/// [`SOBOL_DIM1_BYTES`] with every entry bit-reversed: bit reversal is linear over GF(2)
/// too, so these give the reversed second dimension without reversing it afterwards.
const SOBOL_DIM1_REVERSED_BYTES: [[u32; 256]; 4] = {
    let mut t = SOBOL_DIM1_BYTES;
    let mut byte = 0;
    while byte < 4 {
        let mut value = 0;
        while value < 256 {
            t[byte][value] = t[byte][value].reverse_bits();
            value += 1;
        }
        byte += 1;
    }
    t
};

/// Second dimension of the Sobol sequence for index `i`, bit-reversed.
fn sobol_dim1_reversed(i: u32) -> u32 {
    let b = i.to_le_bytes();
    SOBOL_DIM1_REVERSED_BYTES[0][b[0] as usize]
        ^ SOBOL_DIM1_REVERSED_BYTES[1][b[1] as usize]
        ^ SOBOL_DIM1_REVERSED_BYTES[2][b[2] as usize]
        ^ SOBOL_DIM1_REVERSED_BYTES[3][b[3] as usize]
}

/// The Laine–Karras permutation (Burley 2020): adding the seed and multiplying by even
/// constants only carry information towards more significant bits, so on bit-reversed values
/// every bit is flipped by a hash of the bits above it — a nested uniform (Owen) scrambling.
fn laine_karras(mut v: u32, seed: u32) -> u32 {
    v = v.wrapping_add(seed);
    v ^= v.wrapping_mul(0x6c50_b47c);
    v ^= v.wrapping_mul(0xb82f_1e52);
    v ^= v.wrapping_mul(0xc7af_e638);
    v ^= v.wrapping_mul(0x8d22_f6e6);
    v
}

impl Qmc {
    /// Both components of dimension pair `pair` of this sample, in 32-bit fixed point.
    fn pair(&self, pair: u32) -> (u32, u32) {
        let h = mix64(self.key ^ u64::from(pair));
        let (shuffle, scramble) = (h as u32, (h >> 32) as u32);
        // The point order, shuffled by a nested uniform (Owen) scrambling of the index's bits,
        // most significant first, i.e. `reverse(laine_karras(reverse(index)))` (any aligned
        // block of 2^k consecutive samples keeps its set of points).
        let i = laine_karras(self.reversed_index, shuffle).reverse_bits();
        // Each component is Owen-scrambled the same way: the first Sobol dimension is the
        // bit reversal of `i`, so its scrambling reverses `i` twice, i.e. not at all.
        (
            laine_karras(i, scramble).reverse_bits(),
            laine_karras(sobol_dim1_reversed(i), scramble ^ 0x9e37_79b9).reverse_bits(),
        )
    }
}

/// Uniform numbers in `[0, 1)`: scrambled Sobol points for the first dimensions of a pixel
/// sample ([`pixel_sampler`]), PCG otherwise.
#[derive(Clone, Debug)]
pub struct Sampler {
    pcg: Lazy,
    qmc: Option<Qmc>,
}

impl Sampler {
    /// One number in `[0, 1)` (24 bits, so never rounds up to 1).
    pub fn next_f32(&mut self) -> f32 {
        let bits = match &mut self.qmc {
            Some(q) if q.dim < QMC_DIMENSIONS => {
                let d = q.dim;
                q.dim += 1;
                if d % 2 == 0 {
                    let (x, y) = q.pair(d / 2);
                    q.pending = y;
                    x
                } else {
                    q.pending
                }
            }
            _ => self.pcg.next_u32(),
        };
        to_unit(bits)
    }

    /// Two numbers: one whole pair of quasi-random dimensions (a component left over by
    /// [`Sampler::next_f32`] is skipped, so 2D samples keep the 2D stratification).
    pub fn next_2d(&mut self) -> [f32; 2] {
        if let Some(q) = &mut self.qmc {
            q.dim += q.dim % 2;
            if q.dim < QMC_DIMENSIONS {
                let (x, y) = q.pair(q.dim / 2);
                q.dim += 2;
                return [to_unit(x), to_unit(y)];
            }
        }
        [self.next_f32(), self.next_f32()]
    }

    /// The last two of [`Sampler::next_3d`]'s numbers, without computing the first: the
    /// sequence moves on exactly as after `next_3d` (past the quasi-random dimensions a PCG
    /// number is still drawn), so what comes next is the same. For a BRDF with no lobe to
    /// choose.
    pub fn next_3d_tail(&mut self) -> [f32; 2] {
        match &mut self.qmc {
            // `next_f32` would compute this dimension's pair for its first component (or
            // return the pending second one); `next_2d` then starts at the next even
            // dimension either way, so nothing reads the skipped value.
            Some(q) if q.dim < QMC_DIMENSIONS => q.dim += 1,
            _ => {
                self.pcg.next_u32();
            }
        }
        self.next_2d()
    }

    /// Three numbers: one, then a 2D pair (how BRDF sampling uses them: lobe, then direction).
    pub fn next_3d(&mut self) -> [f32; 3] {
        let a = self.next_f32();
        let [b, c] = self.next_2d();
        [a, b, c]
    }
}

/// The top 24 bits of `bits` as a number in `[0, 1)`.
fn to_unit(bits: u32) -> f32 {
    (bits >> 8) as f32 * (1.0 / 16_777_216.0)
}
