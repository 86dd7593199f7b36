//! The transforms against independent reference values: `tools/wavelet_oracle.py` (PyWavelets
//! for the periodization mode, an independent numpy implementation — extend, `np.convolve`,
//! downsample — for the whole-sample symmetric mode, itself checked against PyWavelets'
//! `reflect` mode), committed in `tests/data/wavelet_oracle.json`.

mod common;
use common::*;

use prt_wavelet::{forward_1d, interpolate, Boundaries, Boundary, Filter, Transform2d, Wavelet};
use serde_json::Value;

/// f64 unit roundoff, 2⁻⁵³.
const U: f64 = f64::EPSILON / 2.0;

fn key(w: Wavelet) -> &'static str {
    w.name()
}

/// Largest l1 norm (gain on bounded data) among a wavelet's analysis or synthesis filters.
fn gain(w: Wavelet, synthesis: bool) -> f64 {
    let f: [Filter; 2] = if synthesis {
        [w.synthesis_low(), w.synthesis_high()]
    } else {
        [w.analysis_low(), w.analysis_high()]
    };
    f.iter().map(Filter::l1_norm).fold(0.0, f64::max)
}

/// Bound on |ours − reference| after `passes` filtering passes (a 1D level is one pass, a 2D
/// level two) over data of largest magnitude `scale`:
/// - each pass forms dot products of at most T = 9 taps; f64 rounding adds at most
///   `T·u·gain·|input|` per output (u = 2⁻⁵³), and errors already present grow by at most the
///   filters' gain G per pass (G = largest l1 norm of the filters, ≤ 2.2), so after P passes
///   ours is within `P·G^P·T·u·scale` of exact arithmetic;
/// - the reference (numpy or PyWavelets, also f64) carries the same bound, and PyWavelets'
///   taps differ from the exact ones by up to δ per tap (`pywt_max_tap_deviation`: 6e-13 for
///   bior4.4, 0 for the others), which moves each pass by at most `T·δ·|input|` more;
/// - plus 2 ulp of the value for the JSON round trip.
///
/// The bound is worst-case (every rounding in the same direction); the measured differences,
/// printed, are far below it.
fn tolerance(passes: usize, growth: f64, scale: f64, deviation: f64, value: f64) -> f64 {
    let p = passes as f64;
    let taps = 9.0;
    p * growth.powi(passes as i32) * scale * taps * (2.0 * U + deviation)
        + 2.0 * f64::EPSILON * value.abs()
}

fn deviation(o: &Value, w: Wavelet, pywt_reference: bool) -> f64 {
    if pywt_reference {
        o["filters"][key(w)]["pywt_max_tap_deviation"]
            .as_f64()
            .unwrap()
    } else {
        0.0
    }
}

/// Compares and returns the largest |difference| / tolerance (printing the largest
/// |difference|).
fn compare(label: &str, ours: &[f64], reference: &[f64], tol: impl Fn(f64) -> f64) -> f64 {
    assert_eq!(ours.len(), reference.len(), "{label}: length");
    println!(
        "  {label}: largest |Δ| {:.2e}",
        max_abs_diff(ours, reference)
    );
    let mut worst = 0.0f64;
    for (i, (a, b)) in ours.iter().zip(reference).enumerate() {
        let t = tol(*b);
        let d = (a - b).abs();
        assert!(
            d <= t,
            "{label}: coefficient {i}: {a} vs {b} (|Δ| {d:.3e} > {t:.3e})"
        );
        worst = worst.max(d / t);
    }
    worst
}

#[test]
fn test01_filter_taps_are_the_exact_ones() {
    let o = oracle();
    for w in Wavelet::ALL {
        let f = &o["filters"][key(w)];
        assert_eq!(f["pywt_name"].as_str().unwrap(), w.pywt_name());
        for (ours, name) in [
            (w.analysis_low(), "analysis_low"),
            (w.synthesis_low(), "synthesis_low"),
        ] {
            assert_eq!(ours.offset, f[name]["offset"].as_i64().unwrap() as isize);
            let exact = floats(&f[name]["taps"]);
            // Correctly rounded in the oracle; equal here up to the JSON parse (≤ 1 ulp).
            for (a, b) in ours.taps.iter().zip(&exact) {
                assert!(
                    (a - b).abs() <= f64::EPSILON * b.abs(),
                    "{w} {name}: {a} vs {b}"
                );
            }
            assert_eq!(ours.taps.len(), exact.len());
        }
    }
}

#[test]
fn test02_filters_are_biorthogonal_with_vanishing_moments() {
    for (w, moments) in [
        (Wavelet::Haar, 1),
        (Wavelet::LeGall53, 2),
        (Wavelet::Cdf97, 4),
    ] {
        let (al, ah, sl, sh) = (
            w.analysis_low(),
            w.analysis_high(),
            w.synthesis_low(),
            w.synthesis_high(),
        );
        // ⟨analysis_a(· − 2k), synthesis_b⟩ = δ_ab δ_k: perfect reconstruction of the bank.
        for k in -5isize..=5 {
            let corr =
                |a: &Filter, s: &Filter| (-12..=12).map(|m| a.at(m) * s.at(m - 2 * k)).sum::<f64>();
            let delta = if k == 0 { 1.0 } else { 0.0 };
            assert!((corr(&al, &sl) - delta).abs() < 8.0 * U, "{w} low k={k}");
            assert!((corr(&ah, &sh) - delta).abs() < 8.0 * U, "{w} high k={k}");
            assert!(corr(&al, &sh).abs() < 8.0 * U, "{w} cross k={k}");
            assert!(corr(&ah, &sl).abs() < 8.0 * U, "{w} cross k={k}");
        }
        // PyWavelets' normalisation: low passes sum to √2.
        for f in [&al, &sl] {
            assert!((f.taps.iter().sum::<f64>() - std::f64::consts::SQRT_2).abs() < 8.0 * U);
        }
        // Both high passes annihilate polynomials of degree < moments (taken about their
        // centre m = 1 for conditioning): zero up to the taps' rounding and the sum's, each at
        // most a few u times the sum of the terms' magnitudes.
        for (f, name) in [(&ah, "analysis"), (&sh, "synthesis")] {
            for p in 0..moments {
                let terms: Vec<f64> = (f.first()..=f.last())
                    .map(|m| f.at(m) * ((m - 1) as f64).powi(p))
                    .collect();
                let s: f64 = terms.iter().sum();
                let size: f64 = terms.iter().map(|t| t.abs()).sum();
                assert!(s.abs() <= 16.0 * U * size, "{w} {name} moment {p}: {s}");
            }
        }
    }
}

#[test]
fn test03_1d_periodization_matches_pywavelets() {
    let o = oracle();
    let signals: Vec<Vec<f64>> = o["signals_1d"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    for w in Wavelet::ALL {
        let dev = deviation(&o, w, true);
        let mut worst = 0.0f64;
        for case in o["cases"][key(w)]["periodization_1d"].as_array().unwrap() {
            let x = &signals[usize_of(&case["signal"])];
            let levels = usize_of(&case["levels"]);
            let ours = forward_1d(w, Boundary::Periodic, x, levels).unwrap();
            let scale = max_abs(x);
            worst = worst.max(compare(
                &format!("{w} periodization N={} L={levels}", x.len()),
                &ours,
                &floats(&case["coefficients"]),
                |v| tolerance(levels, gain(w, false), scale, dev, v),
            ));
        }
        println!("{w}: 1D periodization, largest |Δ|/tolerance {worst:.2e}");
    }
}

#[test]
fn test04_1d_symmetric_matches_the_independent_implementation() {
    let o = oracle();
    let signals: Vec<Vec<f64>> = o["signals_1d"]
        .as_array()
        .unwrap()
        .iter()
        .map(floats)
        .collect();
    for w in Wavelet::ALL {
        let mut worst = 0.0f64;
        for case in o["cases"][key(w)]["symmetric_1d"].as_array().unwrap() {
            let x = &signals[usize_of(&case["signal"])];
            let levels = usize_of(&case["levels"]);
            let ours = forward_1d(w, Boundary::Symmetric, x, levels).unwrap();
            let scale = max_abs(x);
            worst = worst.max(compare(
                &format!("{w} symmetric N={} L={levels}", x.len()),
                &ours,
                &floats(&case["coefficients"]),
                |v| tolerance(levels, gain(w, false), scale, 0.0, v),
            ));
        }
        println!("{w}: 1D symmetric, largest |Δ|/tolerance {worst:.2e}");
    }
}

fn arrays(o: &Value) -> Vec<(usize, usize, Vec<f64>)> {
    o["arrays_2d"]
        .as_array()
        .unwrap()
        .iter()
        .map(|a| {
            (
                usize_of(&a["width"]),
                usize_of(&a["height"]),
                floats(&a["values"]),
            )
        })
        .collect()
}

fn compare_2d(o: &Value, set: &str, boundaries: Boundaries, pywt_reference: bool) {
    let arrays = arrays(o);
    for w in Wavelet::ALL {
        let dev = deviation(o, w, pywt_reference);
        let mut worst = 0.0f64;
        for case in o["cases"][key(w)][set].as_array().unwrap() {
            let (width, height, values) = &arrays[usize_of(&case["array"])];
            let levels = usize_of(&case["levels"]);
            let t = Transform2d::new(w, *width, *height, Some(levels), boundaries).unwrap();
            let ours = t.forward(values).unwrap();
            let scale = max_abs(values);
            worst = worst.max(compare(
                &format!("{w} {set} {width}×{height} L={levels}"),
                &ours,
                &floats(&case["coefficients"]),
                |v| tolerance(2 * levels, gain(w, false), scale, dev, v),
            ));
        }
        println!("{w}: {set}, largest |Δ|/tolerance {worst:.2e}");
    }
}

#[test]
fn test05_2d_periodization_matches_pywavelets_wavedec2_layout() {
    compare_2d(&oracle(), "periodization_2d", Boundaries::PERIODIC, true);
}

#[test]
fn test06_2d_lat_long_matches_the_independent_implementation() {
    compare_2d(&oracle(), "latlong_2d", Boundaries::LAT_LONG, false);
}

#[test]
fn test07_interpolation_matches_pywavelets_waverec2() {
    let o = oracle();
    for w in Wavelet::ALL {
        let mut worst = 0.0f64;
        for case in o["cases"][key(w)]["interpolation"].as_array().unwrap() {
            let coarse = floats(&o["coarse_grids"][case["coarse"].as_str().unwrap()]["values"]);
            let boundary = |s: &Value| match s.as_str().unwrap() {
                "periodic" => Boundary::Periodic,
                _ => Boundary::Symmetric,
            };
            let boundaries = Boundaries {
                x: boundary(&case["boundary_x"]),
                y: boundary(&case["boundary_y"]),
            };
            let (cw, ch) = (
                usize_of(&case["coarse_width"]),
                usize_of(&case["coarse_height"]),
            );
            let (fw, fh) = (usize_of(&case["width"]), usize_of(&case["height"]));
            let ours = interpolate(w, boundaries, &coarse, cw, ch, fw, fh).unwrap();
            let passes = ((fw / cw).trailing_zeros() + (fh / ch).trailing_zeros()) as usize;
            // The scaled coarse values (√2 per pass) are the inputs of the synthesis passes.
            let scale = max_abs(&coarse) * 2f64.sqrt().powi(passes as i32);
            let dev = deviation(&o, w, boundaries == Boundaries::PERIODIC);
            worst = worst.max(compare(
                &format!("{w} interpolation {cw}×{ch} → {fw}×{fh} {boundaries:?}"),
                &ours,
                &floats(&case["fine"]),
                |v| tolerance(passes, gain(w, true), scale, dev, v),
            ));
        }
        println!("{w}: interpolation, largest |Δ|/tolerance {worst:.2e}");
    }
}
