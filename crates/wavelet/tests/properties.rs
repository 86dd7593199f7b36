//! Properties that hold whatever the reference data: perfect reconstruction for every wavelet,
//! boundary rule and level count; the adjoint behind the primal coefficients; the cached basis
//! norms against brute force; interpolation keeping constants; bad input giving errors.

mod common;
use common::*;

use prt_wavelet::{
    forward_1d, interpolate, inverse_1d, max_levels_1d, Band, BandKind, Boundaries, Boundary,
    Transform2d, Wavelet, WaveletError,
};

/// Perfect reconstruction: |x − S A x| ≤ 1e-12 · max|x|. (A few hundred roundings along any
/// path, each ≤ 2⁻⁵³ relative, amplified by the filters' gains: observed ≤ 1e-15.)
const PR_TOLERANCE: f64 = 1e-12;

#[test]
fn test01_1d_perfect_reconstruction() {
    let mut rng = Rng::new(1);
    let mut worst = 0.0f64;
    for w in Wavelet::ALL {
        for b in [Boundary::Periodic, Boundary::Symmetric] {
            for n in [2usize, 4, 6, 8, 10, 12, 16, 24, 64, 256] {
                let x = rng.vec(n);
                for levels in 0..=max_levels_1d(n) {
                    let c = forward_1d(w, b, &x, levels).unwrap();
                    let back = inverse_1d(w, b, &c, levels).unwrap();
                    let e = max_abs_diff(&x, &back) / max_abs(&x);
                    assert!(e <= PR_TOLERANCE, "{w} {b:?} N={n} L={levels}: {e:.2e}");
                    worst = worst.max(e);
                }
            }
        }
    }
    println!("1D perfect reconstruction: worst relative error {worst:.2e}");
}

#[test]
fn test02_2d_perfect_reconstruction() {
    let mut rng = Rng::new(2);
    let mut worst = 0.0f64;
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            for (width, height) in [
                (256, 64),
                (64, 32),
                (64, 16),
                (16, 8),
                (8, 8),
                (12, 4),
                (2, 2),
            ] {
                let x = rng.vec(width * height);
                for levels in 0..=Transform2d::max_levels(width, height) {
                    let t = Transform2d::new(w, width, height, Some(levels), boundaries).unwrap();
                    let back = t.inverse(&t.forward(&x).unwrap()).unwrap();
                    let e = max_abs_diff(&x, &back) / max_abs(&x);
                    assert!(
                        e <= PR_TOLERANCE,
                        "{w} {boundaries:?} {width}×{height} L={levels}: {e:.2e}"
                    );
                    worst = worst.max(e);
                }
            }
        }
    }
    println!("2D perfect reconstruction: worst relative error {worst:.2e}");
}

#[test]
fn test03_haar_symmetric_equals_periodic() {
    let mut rng = Rng::new(3);
    let x = rng.vec(64 * 16);
    let a = Transform2d::new(Wavelet::Haar, 64, 16, None, Boundaries::PERIODIC).unwrap();
    let b = Transform2d::lat_long(Wavelet::Haar, 64, 16, None).unwrap();
    assert_eq!(a.forward(&x).unwrap(), b.forward(&x).unwrap());
}

#[test]
fn test04_primal_coefficients_are_the_adjoint_of_the_inverse() {
    // ⟨S c, f⟩ = ⟨c, Sᵀ f⟩ for random c, f: relative 1e-13 of Σ|terms| (two sums of 2048
    // products, each ≤ ~1e-15 relative from the transforms).
    let mut rng = Rng::new(4);
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            let t = Transform2d::new(w, 64, 32, None, boundaries).unwrap();
            let (c, f) = (rng.vec(t.len()), rng.vec(t.len()));
            let sc = t.inverse(&c).unwrap();
            let stf = t.primal_coefficients(&f).unwrap();
            let lhs: f64 = sc.iter().zip(&f).map(|(a, b)| a * b).sum();
            let rhs: f64 = c.iter().zip(&stf).map(|(a, b)| a * b).sum();
            let size: f64 = sc.iter().zip(&f).map(|(a, b)| (a * b).abs()).sum();
            assert!(
                (lhs - rhs).abs() <= 1e-13 * size,
                "{w} {boundaries:?}: {lhs} vs {rhs}"
            );
        }
    }
    // Haar is orthonormal: primal and dual coefficients coincide.
    let t = Transform2d::lat_long(Wavelet::Haar, 32, 16, None).unwrap();
    let f = rng.vec(t.len());
    let d = max_abs_diff(&t.forward(&f).unwrap(), &t.primal_coefficients(&f).unwrap());
    assert!(d < 1e-14, "{d}");
}

#[test]
fn test05_basis_norms_match_brute_force() {
    // Every coefficient's ‖Φ_i‖² against the inverse transform of its unit vector: the
    // separable product of 1D norms differs only by rounding (1e-13 relative).
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            for (width, height, levels) in [(16, 8, None), (16, 8, Some(1)), (8, 4, Some(0))] {
                let t = Transform2d::new(w, width, height, levels, boundaries).unwrap();
                let norms = t.basis_norms_squared();
                for i in 0..t.len() {
                    let mut unit = vec![0.0; t.len()];
                    unit[i] = 1.0;
                    let phi = t.inverse(&unit).unwrap();
                    let brute: f64 = phi.iter().map(|v| v * v).sum();
                    assert!(
                        (norms[i] - brute).abs() <= 1e-13 * brute,
                        "{w} {boundaries:?} {width}×{height} {levels:?} i={i}: {} vs {brute}",
                        norms[i]
                    );
                }
            }
        }
        if w == Wavelet::Haar {
            let t = Transform2d::lat_long(w, 64, 16, None).unwrap();
            assert!(t
                .basis_norms_squared()
                .iter()
                .all(|n| (n - 1.0).abs() < 1e-14));
        }
    }
}

#[test]
fn test06_bands_and_regions_agree() {
    let t = Transform2d::lat_long(Wavelet::Cdf97, 256, 64, None).unwrap();
    assert_eq!(t.levels(), 6);
    let mut seen = vec![0u8; t.len()];
    let mut bands = vec![Band {
        level: 6,
        kind: BandKind::Approximation,
    }];
    for level in 1..=6 {
        for kind in [BandKind::DetailX, BandKind::DetailY, BandKind::DetailXY] {
            bands.push(Band { level, kind });
        }
    }
    for band in bands {
        let (x0, y0, w, h) = t.band_region(band).unwrap();
        for y in y0..y0 + h {
            for x in x0..x0 + w {
                let i = y * 256 + x;
                assert_eq!(t.band(i).unwrap(), band, "index {i}");
                seen[i] += 1;
            }
        }
    }
    assert!(seen.iter().all(|&s| s == 1), "bands tile the layout");
    assert_eq!(
        t.band_region(Band {
            level: 6,
            kind: BandKind::Approximation
        })
        .unwrap(),
        (0, 0, 4, 1)
    );
    assert!(t
        .band_region(Band {
            level: 3,
            kind: BandKind::Approximation
        })
        .is_err());
    assert!(t
        .band_region(Band {
            level: 7,
            kind: BandKind::DetailX
        })
        .is_err());
    assert!(t.band(t.len()).is_err());
}

#[test]
fn test07_interpolation_keeps_constants() {
    // A constant goes through √2 per pass and the synthesis low pass (whose even and odd taps
    // each sum to 1/√2): equal to the constant up to a few roundings per pass.
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            for (cw, ch) in [(64, 16), (64, 32), (256, 64)] {
                let coarse = vec![0.37; cw * ch];
                let fine = interpolate(w, boundaries, &coarse, cw, ch, 256, 64).unwrap();
                assert_eq!(fine.len(), 256 * 64);
                let e = fine.iter().fold(0.0f64, |m, v| m.max((v - 0.37).abs()));
                assert!(e <= 1e-14, "{w} {boundaries:?} {cw}×{ch}: {e:.2e}");
            }
        }
    }
}

#[test]
fn test08_legall_interpolation_is_linear_interpolation() {
    // The 5/3 scaling function is the linear B-spline: refined samples pass through the coarse
    // ones and the new samples are midpoints (periodic in x; at the lower pole the mirrored
    // extension repeats the last row).
    let mut rng = Rng::new(8);
    let (cw, ch) = (16, 8);
    let coarse = rng.vec(cw * ch);
    let fine = interpolate(
        Wavelet::LeGall53,
        Boundaries::LAT_LONG,
        &coarse,
        cw,
        ch,
        2 * cw,
        2 * ch,
    )
    .unwrap();
    let c = |x: usize, y: usize| coarse[y.min(ch - 1) * cw + x % cw];
    for y in 0..ch {
        for x in 0..cw {
            let f = |dx: usize, dy: usize| fine[(2 * y + dy) * 2 * cw + 2 * x + dx];
            assert!((f(0, 0) - c(x, y)).abs() < 1e-15);
            assert!((f(1, 0) - 0.5 * (c(x, y) + c(x + 1, y))).abs() < 1e-15);
            assert!((f(0, 1) - 0.5 * (c(x, y) + c(x, y + 1))).abs() < 1e-15);
        }
    }
    // Haar repeats samples.
    let fine = interpolate(
        Wavelet::Haar,
        Boundaries::LAT_LONG,
        &coarse,
        cw,
        ch,
        4 * cw,
        2 * ch,
    )
    .unwrap();
    for (i, v) in fine.iter().enumerate() {
        let (x, y) = (i % (4 * cw), i / (4 * cw));
        assert!((v - coarse[(y / 2) * cw + x / 4]).abs() < 1e-15);
    }
}

#[test]
fn test09_interpolated_grid_transforms_back_to_the_coarse_one() {
    // Forward-transforming the refined grid gives the scaled coarse grid as its approximation
    // band and zero details (perfect reconstruction, seen from the other side).
    let mut rng = Rng::new(9);
    let coarse = rng.vec(64 * 16);
    for w in Wavelet::ALL {
        let fine = interpolate(w, Boundaries::LAT_LONG, &coarse, 64, 16, 256, 64).unwrap();
        let t = Transform2d::lat_long(w, 256, 64, Some(2)).unwrap();
        let c = t.forward(&fine).unwrap();
        for (i, v) in c.iter().enumerate() {
            let (x, y) = (i % 256, i / 256);
            let expected = if x < 64 && y < 16 {
                4.0 * coarse[y * 64 + x]
            } else {
                0.0
            };
            assert!(
                (v - expected).abs() < 1e-13,
                "{w} ({x}, {y}): {v} vs {expected}"
            );
        }
    }
}

#[test]
fn test10_bad_input_gives_errors() {
    let w = Wavelet::Cdf97;
    let lat = Boundaries::LAT_LONG;
    assert!(matches!(
        Transform2d::new(w, 0, 8, None, lat),
        Err(WaveletError::EmptyGrid { .. })
    ));
    assert!(matches!(
        Transform2d::new(w, 8, 0, Some(0), lat),
        Err(WaveletError::EmptyGrid { .. })
    ));
    assert!(matches!(
        Transform2d::new(w, usize::MAX / 2, 4, Some(0), lat),
        Err(WaveletError::TooLarge { .. })
    ));
    assert_eq!(
        Transform2d::new(w, 256, 64, Some(7), lat).unwrap_err(),
        WaveletError::TooManyLevels {
            width: 256,
            height: 64,
            levels: 7,
            max: 6
        }
    );
    assert_eq!(
        Transform2d::new(w, 24, 16, Some(4), lat).unwrap_err(),
        WaveletError::TooManyLevels {
            width: 24,
            height: 16,
            levels: 4,
            max: 3
        }
    );
    assert!(Transform2d::new(w, 7, 5, Some(1), lat).is_err());
    let odd = Transform2d::new(w, 7, 5, None, lat).unwrap();
    assert_eq!(odd.levels(), 0, "odd sizes allow no level");
    let message = Transform2d::new(w, 256, 64, Some(7), lat)
        .unwrap_err()
        .to_string();
    assert!(
        message.contains("256×64") && message.contains("at most 6"),
        "{message}"
    );

    let t = Transform2d::lat_long(w, 16, 8, None).unwrap();
    assert_eq!(
        t.forward(&[0.0; 10]).unwrap_err(),
        WaveletError::LengthMismatch {
            expected: 128,
            actual: 10
        }
    );
    assert!(t.inverse(&[0.0; 129]).is_err());
    let mut nan = vec![0.0; 128];
    nan[5] = f64::NAN;
    assert!(matches!(
        t.forward(&nan),
        Err(WaveletError::NonFinite { index: 5, .. })
    ));
    assert!(matches!(
        t.primal_coefficients(&nan),
        Err(WaveletError::NonFinite { index: 5, .. })
    ));
    assert!(t.rank(&nan).is_err());
    let mut inf = vec![1.0; 128];
    inf[127] = f64::INFINITY;
    let before = inf.clone();
    assert!(t.inverse_in_place(&mut inf).is_err());
    assert_eq!(inf, before, "data untouched on error");

    assert!(matches!(
        forward_1d(w, Boundary::Symmetric, &[1.0; 12], 3),
        Err(WaveletError::TooManySignalLevels {
            len: 12,
            levels: 3,
            max: 2
        })
    ));
    assert!(forward_1d(w, Boundary::Periodic, &[], 0).is_err());
    assert!(inverse_1d(w, Boundary::Periodic, &[1.0, f64::NAN], 1).is_err());

    assert!(matches!(
        t.reconstruct_sparse(&[(128, 1.0)]),
        Err(WaveletError::IndexOutOfRange {
            index: 128,
            len: 128
        })
    ));
    assert!(t.reconstruct_sparse(&[(3, f64::NAN)]).is_err());

    let c = vec![1.0; 64 * 16];
    for (fw, fh) in [(255, 64), (192, 64), (256, 48), (32, 16)] {
        assert!(
            matches!(
                interpolate(w, lat, &c, 64, 16, fw, fh),
                Err(WaveletError::InterpolationSize { .. })
            ),
            "{fw}×{fh}"
        );
    }
    assert!(interpolate(w, lat, &c, 0, 16, 256, 64).is_err());
    assert!(interpolate(w, lat, &c[..100], 64, 16, 256, 64).is_err());
    assert!(
        interpolate(w, lat, &c, 64, 16, 64, 16).is_ok(),
        "factor 1 is the identity"
    );

    assert_eq!("9/7".parse::<Wavelet>().unwrap(), Wavelet::Cdf97);
    assert_eq!("bior2.2".parse::<Wavelet>().unwrap(), Wavelet::LeGall53);
    assert_eq!("HAAR".parse::<Wavelet>().unwrap(), Wavelet::Haar);
    assert!(matches!(
        "db4".parse::<Wavelet>(),
        Err(WaveletError::UnknownWavelet(_))
    ));
}
