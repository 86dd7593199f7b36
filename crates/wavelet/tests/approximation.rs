//! Non-linear approximation: keeping all coefficients is exact, the error falls as more are
//! kept, the primal/dual energy identity and error estimate, the error metrics, and the paper's
//! comparison of the three wavelets (Masselus et al. 2004, §5.2, Fig. 9).

mod common;
use common::*;

use prt_wavelet::{
    relative_l2_error, sobolev_h1_relative_error, texel_solid_angles, Boundaries,
    RankedCoefficients, Transform2d, Wavelet, WaveletError,
};

fn error_of(t: &Transform2d, f: &[f64], ranked: &RankedCoefficients, count: usize) -> f64 {
    let approx = t.reconstruct_sparse(&ranked.keep(count)).unwrap();
    relative_l2_error(f, &approx, t.width(), t.height(), None).unwrap()
}

#[test]
fn test01_keeping_every_coefficient_is_exact() {
    let f = bump_and_edge(64, 16);
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            let t = Transform2d::new(w, 64, 16, None, boundaries).unwrap();
            let ranked = t.rank(&f).unwrap();
            assert_eq!(ranked.len(), 1024);
            let kept = ranked.keep(usize::MAX);
            assert_eq!(kept.len(), 1024);
            let e = error_of(&t, &f, &ranked, 1024);
            assert!(e < 1e-14, "{w} {boundaries:?}: {e:.2e}");
            assert_eq!(ranked.estimated_relative_error(1024), 0.0);
            let k = ranked.count_for_exact_error(0.0).unwrap();
            assert!(ranked.relative_error(k) < 1e-14);
        }
    }
}

#[test]
fn test02_error_decreases_with_more_coefficients() {
    // Haar is orthonormal: each added coefficient removes its own |c|² from the squared error,
    // so the error is non-increasing at every step (up to rounding). For the biorthogonal
    // wavelets adding c_i Φ_i changes the squared error by c_i² ‖Φ_i‖² − 2 c_i ⟨e, Φ_i⟩, which
    // a non-orthogonal Φ_i can make positive; the ranking keeps this rare and small, and the
    // error falls over every doubling of K.
    let (w_, h_) = (64, 16);
    let f = bump_and_edge(w_, h_);
    for w in Wavelet::ALL {
        let t = Transform2d::lat_long(w, w_, h_, None).unwrap();
        let ranked = t.rank(&f).unwrap();
        let errors: Vec<f64> = (0..=t.len())
            .map(|k| error_of(&t, &f, &ranked, k))
            .collect();
        assert!((errors[0] - 1.0).abs() < 1e-15);
        let rises: Vec<(usize, f64)> = (1..errors.len())
            .filter(|&k| errors[k] > errors[k - 1] + 1e-15)
            .map(|k| (k, errors[k] - errors[k - 1]))
            .collect();
        let largest_rise = rises.iter().fold(0.0f64, |m, r| m.max(r.1));
        println!(
            "{w}: error rises at {} of {} steps (largest rise {largest_rise:.2e})",
            rises.len(),
            t.len()
        );
        if w == Wavelet::Haar {
            assert!(rises.is_empty(), "{rises:?}");
        }
        let mut k = 1;
        while 2 * k <= t.len() {
            assert!(errors[2 * k] < errors[k], "{w}: K={} vs {k}", 2 * k);
            k *= 2;
        }
    }
}

#[test]
fn test03_primal_dual_energy_identity() {
    // Σ c_i c̃_i = ‖f‖² (relative 1e-13: two transforms and two sums of ≤ 16384 terms).
    let mut rng = Rng::new(3);
    for w in Wavelet::ALL {
        for boundaries in ALL_BOUNDARIES {
            for f in [bump_and_edge(256, 64), rng.vec(256 * 64)] {
                let t = Transform2d::new(w, 256, 64, None, boundaries).unwrap();
                let ranked = t.rank(&f).unwrap();
                let norm2: f64 = f.iter().map(|v| v * v).sum();
                let e = (ranked.energy() - norm2).abs() / norm2;
                assert!(e < 1e-13, "{w} {boundaries:?}: {e:.2e}");
            }
        }
    }
}

#[test]
fn test04_error_estimate_and_counts_for_a_target() {
    for (w_, h_, edge) in [(64, 32, 0.1), (64, 32, 0.5), (256, 64, 0.1)] {
        let f = lobes_and_disc(w_, h_, edge);
        for w in Wavelet::ALL {
            let t = Transform2d::lat_long(w, w_, h_, None).unwrap();
            let ranked = t.rank(&f).unwrap();
            let label = format!("{w} {w_}×{h_} disc {edge}");
            for k in [1, 16, 256, 1024] {
                let exact = ranked.relative_error(k);
                // Same quantity, summed in another order.
                assert!((exact - error_of(&t, &f, &ranked, k)).abs() <= 1e-12 * exact);
                let estimate = ranked.estimated_relative_error(k);
                if w == Wavelet::Haar {
                    // Orthonormal: the estimate is the error (both ~1e-16 relative computations).
                    assert!(
                        (estimate - exact).abs() < 1e-12,
                        "{label} K={k}: {estimate} vs {exact}"
                    );
                }
                println!("{label}: K={k:5} exact {exact:.4e} primal/dual estimate {estimate:.4e}");
            }
            for target in [0.2, 0.05, 0.01, 1e-3, 0.0] {
                // The estimate's count: the smallest K whose estimate meets the target.
                let k = ranked.count_for_error(target).unwrap();
                assert!(ranked.estimated_relative_error(k) <= target);
                assert!((0..k).all(|j| ranked.estimated_relative_error(j) > target));
                assert_eq!(ranked.keep_for_error(target).unwrap(), ranked.keep(k));
                // The exact count meets the target, one fewer does not.
                let exact_k = ranked.count_for_exact_error(target).unwrap();
                assert!(exact_k == t.len() || ranked.relative_error(exact_k) <= target);
                assert!(exact_k == 0 || ranked.relative_error(exact_k - 1) > target);
                assert_eq!(ranked.keep_for_exact_error(target).unwrap().len(), exact_k);
                println!(
                    "{label}: target {target}: estimate keeps {k} (exact error {:.4e}), \
                     exact rule keeps {exact_k} (exact error {:.4e})",
                    ranked.relative_error(k),
                    ranked.relative_error(exact_k),
                );
            }
        }
    }
}

#[test]
fn test05_primal_dual_estimate_fails_at_small_targets() {
    // The paper's estimate ⟨f − f_K, f⟩/‖f‖² carries the cross term ⟨f − f_K, f_K⟩, which for
    // the biorthogonal wavelets dominates once the error is small: on this smooth map the
    // dropped primal/dual sum reaches 0 — an estimated error of exactly 0 — with a quarter or
    // less of the coefficients kept, while the exact error is still 0.08 % (9/7) and 0.6 %
    // (5/3). Recorded here so that a change of the rule is a conscious one.
    let f = bump_and_edge(256, 64);
    for w in [Wavelet::LeGall53, Wavelet::Cdf97] {
        let t = Transform2d::lat_long(w, 256, 64, None).unwrap();
        let ranked = t.rank(&f).unwrap();
        let k = ranked.count_for_error(0.0).unwrap();
        let exact = ranked.relative_error(k);
        println!(
            "{w}: the estimate reaches 0 at {k} of {} coefficients; exact error there {:.3} %",
            t.len(),
            100.0 * exact
        );
        assert!(k < t.len() / 4 && exact > 5e-4, "{w}: {k} {exact}");
    }
}

#[test]
fn test06_zero_function_and_bad_targets() {
    let t = Transform2d::lat_long(Wavelet::LeGall53, 32, 16, None).unwrap();
    let zero = vec![0.0; t.len()];
    let ranked = t.rank(&zero).unwrap();
    assert_eq!(ranked.energy(), 0.0);
    assert_eq!(ranked.count_for_error(0.0).unwrap(), 0);
    assert_eq!(ranked.estimated_relative_error(0), 0.0);
    assert_eq!(ranked.relative_error(0), 0.0);
    assert_eq!(ranked.count_for_exact_error(0.0).unwrap(), 0);
    assert_eq!(relative_l2_error(&zero, &zero, 32, 16, None).unwrap(), 0.0);
    assert_eq!(
        relative_l2_error(&zero, &vec![1.0; t.len()], 32, 16, None).unwrap_err(),
        WaveletError::ZeroReference
    );
    for bad in [-0.1, f64::NAN, f64::INFINITY] {
        assert!(matches!(
            ranked.count_for_error(bad),
            Err(WaveletError::InvalidErrorTarget(_))
        ));
    }
}

#[test]
fn test07_metrics() {
    let (w, h) = (64, 32);
    let omega = texel_solid_angles(w, h).unwrap();
    let total: f64 = omega.iter().sum::<f64>() * w as f64;
    assert!(
        (total - 4.0 * std::f64::consts::PI).abs() < 1e-13,
        "{total}"
    );
    assert!((omega[0] - omega[h - 1]).abs() < 1e-15 && omega[h / 2] > 10.0 * omega[0]);

    let f = bump_and_edge(w, h);
    let g: Vec<f64> = f
        .iter()
        .enumerate()
        .map(|(i, v)| v + 0.01 * ((i * 7) % 5) as f64)
        .collect();
    let plain = relative_l2_error(&f, &g, w, h, None).unwrap();
    let uniform = relative_l2_error(&f, &g, w, h, Some(&vec![2.5; h])).unwrap();
    assert!((plain - uniform).abs() < 1e-15 * plain.max(1.0));
    let weighted = relative_l2_error(&f, &g, w, h, Some(&omega)).unwrap();
    assert!(
        weighted > 0.0 && (weighted - plain).abs() > 1e-6,
        "{weighted} {plain}"
    );
    assert_eq!(relative_l2_error(&f, &f, w, h, Some(&omega)).unwrap(), 0.0);

    let mut bad = omega.clone();
    bad[3] = -1.0;
    assert!(matches!(
        relative_l2_error(&f, &g, w, h, Some(&bad)),
        Err(WaveletError::InvalidWeight { row: 3, .. })
    ));
    assert!(relative_l2_error(&f, &g, w, h, Some(&omega[1..])).is_err());
    assert!(relative_l2_error(&f, &g[1..], w, h, None).is_err());
    assert!(sobolev_h1_relative_error(&f, &g, w + 1, h).is_err());

    // H¹ of a constant offset: the gradient of the error vanishes, so the H¹ error is below the
    // L2 one (the reference has gradient energy); a checkerboard error of the same L2 size is
    // far larger in H¹.
    let offset: Vec<f64> = f.iter().map(|v| v + 0.01).collect();
    let checker: Vec<f64> = f
        .iter()
        .enumerate()
        .map(|(i, v)| {
            v + if (i % w + i / w) % 2 == 0 {
                0.01
            } else {
                -0.01
            }
        })
        .collect();
    let l2 = relative_l2_error(&f, &offset, w, h, None).unwrap();
    assert!((l2 - relative_l2_error(&f, &checker, w, h, None).unwrap()).abs() < 1e-15);
    let h1_offset = sobolev_h1_relative_error(&f, &offset, w, h).unwrap();
    let h1_checker = sobolev_h1_relative_error(&f, &checker, w, h).unwrap();
    assert!(
        h1_offset < l2 && h1_checker > 3.0 * l2,
        "{h1_offset} {h1_checker} {l2}"
    );
    assert_eq!(sobolev_h1_relative_error(&f, &f, w, h).unwrap(), 0.0);
}

#[test]
fn test08_paper_ordering_at_256_coefficients() {
    // Masselus et al. 2004, §5.2: on 256×64 lat-long reflectance functions (smooth multilevel
    // B-spline reconstructions), 256 coefficients leave a relative error of 7.05 % (Haar),
    // 2.12 % (5/3), 1.88 % (9/7). Here, on two smooth lobes plus a hard-edged disc of height
    // 0.1, the ordering Haar > 5/3 > 9/7 must hold (measured 7.7 %, 1.47 %, 1.36 %). With a
    // taller disc (0.5) the hard edge dominates and 5/3 edges out 9/7 (3.07 % vs 3.20 %):
    // the 9/7's advantage is on smooth functions, as in the paper; printed, not asserted.
    let (w, h) = (256, 64);
    let omega = texel_solid_angles(w, h).unwrap();
    for edge in [0.1, 0.5] {
        let f = lobes_and_disc(w, h, edge);
        let mut l2 = Vec::new();
        for wavelet in Wavelet::ALL {
            let t = Transform2d::lat_long(wavelet, w, h, None).unwrap();
            let ranked = t.rank(&f).unwrap();
            let approx = t.reconstruct_sparse(&ranked.keep(256)).unwrap();
            let e = relative_l2_error(&f, &approx, w, h, None).unwrap();
            let e_sphere = relative_l2_error(&f, &approx, w, h, Some(&omega)).unwrap();
            let e_h1 = sobolev_h1_relative_error(&f, &approx, w, h).unwrap();
            println!(
                "disc {edge}: {wavelet:>10}: K=256 relative L2 {:.2} % (solid-angle weighted \
                 {:.2} %), H¹ {:.2} %; {} coefficients for an exact 2 %",
                100.0 * e,
                100.0 * e_sphere,
                100.0 * e_h1,
                ranked.count_for_exact_error(0.02).unwrap(),
            );
            l2.push(e);
        }
        if edge == 0.1 {
            assert!(
                l2[0] > l2[1] && l2[1] > l2[2],
                "Haar > 5/3 > 9/7 expected: {l2:?}"
            );
        }
    }
}

#[test]
fn test09_lat_long_boundaries_pay_off() {
    // Periodic in azimuth and mirrored at the poles (the paper's choice) represents a lat-long
    // function no worse than periodic in both axes, which sees a jump between the poles.
    let (w, h) = (256, 64);
    let f = bump_and_edge(w, h);
    for wavelet in [Wavelet::LeGall53, Wavelet::Cdf97] {
        let mut errors = Vec::new();
        for boundaries in [Boundaries::LAT_LONG, Boundaries::PERIODIC] {
            let t = Transform2d::new(wavelet, w, h, None, boundaries).unwrap();
            let ranked = t.rank(&f).unwrap();
            errors.push(error_of(&t, &f, &ranked, 256));
        }
        println!(
            "{wavelet}: K=256 lat-long {:.3e}, periodic {:.3e}",
            errors[0], errors[1]
        );
        assert!(errors[0] <= errors[1], "{wavelet}: {errors:?}");
    }
}
