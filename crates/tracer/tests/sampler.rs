//! The pixel sampler (`rng::pixel_sampler`): scrambled Sobol points must be a (0, m, 2)-net in
//! every pair of dimensions of a replica (the stratification that lowers the variance), uniform
//! across pixels (chi-square), and the two replicas independent (what keeps the half-image noise
//! estimate unbiased); the single-sequence sampler a net of all of a pixel's samples.

use prt_tracer::rng::{pixel_sampler, PixelKeys, QMC_DIMENSIONS};
use prt_tracer::SamplerKind;

/// The first `2^m` samples of replica `replica` of a pixel, all QMC dimensions.
fn points(seed: u64, pixel: u64, replica: u64, m: u32) -> Vec<Vec<f32>> {
    (0..1u64 << m)
        .map(|j| {
            let mut s = pixel_sampler(seed, pixel, 2 * j + replica);
            (0..QMC_DIMENSIONS).map(|_| s.next_f32()).collect()
        })
        .collect()
}

/// Where the (0, m, 2)-net property of `pts` (2^m points) fails in some dimension pair: for
/// every split a + b = m, each of the 2^a × 2^b elementary boxes must hold exactly one point.
fn net_violation(pts: &[Vec<f32>], m: u32) -> Option<String> {
    for pair in 0..(QMC_DIMENSIONS / 2) as usize {
        for a in 0..=m {
            let b = m - a;
            let mut seen = vec![false; 1 << m];
            for p in pts {
                let (x, y) = (p[2 * pair], p[2 * pair + 1]);
                let cx = (x * (1u32 << a) as f32) as usize;
                let cy = (y * (1u32 << b) as f32) as usize;
                let cell = (cx << b) | cy;
                if seen[cell] {
                    return Some(format!("pair {pair}, split {a}+{b}: two points in one box"));
                }
                seen[cell] = true;
            }
        }
    }
    None
}

/// The single-sequence sampler (`SamplerKind::Single`): the first 2^m samples of a pixel, all
/// of them together, are a (0, m, 2)-net in every dimension pair (with the replicas sampler
/// only each replica's half is), and the replicas sampler of `PixelKeys` is `pixel_sampler`.
#[test]
fn test03_single_sequence_stratifies_all_samples_together() {
    let m = 8;
    for (seed, pixel) in [(0u64, 0u64), (7, 12_345), (u64::MAX, 3)] {
        let keys = PixelKeys::new(seed, pixel);
        let pts: Vec<Vec<f32>> = (0..1u64 << m)
            .map(|j| {
                let mut s = keys.sampler_of(SamplerKind::Single, j);
                (0..QMC_DIMENSIONS).map(|_| s.next_f32()).collect()
            })
            .collect();
        let bad = net_violation(&pts, m);
        assert!(bad.is_none(), "single, seed {seed}, pixel {pixel}: {bad:?}");
        // The replicas' 2^m samples are two nets of 2^(m-1) points, not one of 2^m: some
        // elementary box of the finest split holds two (or the test above would not tell
        // the two samplers apart).
        let both: Vec<Vec<f32>> = (0..1u64 << m)
            .map(|j| {
                let mut s = keys.sampler_of(SamplerKind::Replicas, j);
                let mut r = pixel_sampler(seed, pixel, j);
                let p: Vec<f32> = (0..QMC_DIMENSIONS).map(|_| s.next_f32()).collect();
                let q: Vec<f32> = (0..QMC_DIMENSIONS).map(|_| r.next_f32()).collect();
                assert_eq!(p, q);
                p
            })
            .collect();
        assert!(
            net_violation(&both, m).is_some(),
            "replicas: one net of all samples?"
        );
    }
}

#[test]
fn test01_every_dimension_pair_is_a_0_m_2_net() {
    // Owen scrambling and the scrambled point order keep the net property of the 2D Sobol
    // sequence: for every split a + b = m, each of the 2^a × 2^b elementary boxes holds exactly
    // one of the first 2^m points. Exact (a wrong direction number or a scramble that is not
    // nested breaks it at once).
    let m = 8;
    for (seed, pixel, replica) in [(0, 0, 0), (7, 12_345, 1), (u64::MAX, 3, 0)] {
        let bad = net_violation(&points(seed, pixel, replica, m), m);
        assert!(
            bad.is_none(),
            "seed {seed}, pixel {pixel}, replica {replica}: {bad:?}"
        );
    }
}

/// Pearson chi-square of counts against a uniform expectation; returns the statistic.
fn chi_square(counts: &[u32], total: u32) -> f64 {
    let e = f64::from(total) / counts.len() as f64;
    counts.iter().map(|&c| (f64::from(c) - e).powi(2) / e).sum()
}

#[test]
fn test02_points_are_uniform_across_pixels_and_replicas_independent() {
    // One sample per pixel over 40,000 pixels, a 16 × 16 histogram per pair of dimensions:
    // chi-square with 255 degrees of freedom; the 1e-4 upper quantile is about 353
    // (Wilson–Hilferty), so a correct sampler fails with probability < 1e-4 per histogram.
    // Replicas: the correlation of the same dimension of samples 0 and 1 of a pixel over
    // 40,000 pixels has a standard deviation of 1/√40000 = 0.005; allow 5 of those.
    let pixels = 40_000u64;
    let mut counts = vec![vec![0u32; 256]; (QMC_DIMENSIONS / 2) as usize];
    let (mut sxy, mut sx, mut sy) = (0.0f64, 0.0f64, 0.0f64);
    for p in 0..pixels {
        let mut s0 = pixel_sampler(3, p, 0);
        let mut s1 = pixel_sampler(3, p, 1);
        for (pair, c) in counts.iter_mut().enumerate() {
            let (x, y) = (s0.next_f32(), s0.next_f32());
            c[(x * 16.0) as usize * 16 + (y * 16.0) as usize] += 1;
            let z = s1.next_f32();
            let _ = s1.next_f32();
            if pair == 0 {
                sxy += f64::from(x) * f64::from(z);
                sx += f64::from(x);
                sy += f64::from(z);
            }
        }
    }
    for (pair, c) in counts.iter().enumerate() {
        let chi2 = chi_square(c, pixels as u32);
        assert!(
            chi2 < 353.0,
            "pair {pair}: chi-square {chi2:.1} over 255 dof"
        );
    }
    let n = pixels as f64;
    let cov = sxy / n - (sx / n) * (sy / n);
    let corr = cov / (1.0 / 12.0);
    assert!(corr.abs() < 0.025, "replica correlation {corr}");
}

/// `next_3d_tail` is `next_3d` without its first number: the same two numbers and the same
/// numbers afterwards, whether it starts on an even dimension, on an odd one (after a lone
/// `next_f32`), or past the quasi-random dimensions (PCG), for both sampler kinds.
#[test]
fn test04_next_3d_tail_skips_only_the_lobe_number() {
    for kind in [SamplerKind::Replicas, SamplerKind::Single] {
        for sample in 0..64u64 {
            for lead in 0..QMC_DIMENSIONS + 6 {
                let keys = PixelKeys::new(9, 1234 + sample);
                let (mut a, mut b) = (keys.sampler_of(kind, sample), keys.sampler_of(kind, sample));
                for _ in 0..lead {
                    assert_eq!(a.next_f32().to_bits(), b.next_f32().to_bits());
                }
                let full = a.next_3d();
                let tail = b.next_3d_tail();
                assert_eq!([full[1], full[2]], tail, "lead {lead}, sample {sample}");
                for _ in 0..8 {
                    assert_eq!(
                        a.next_2d(),
                        b.next_2d(),
                        "after: lead {lead}, sample {sample}"
                    );
                    assert_eq!(a.next_f32().to_bits(), b.next_f32().to_bits());
                }
            }
        }
    }
}
