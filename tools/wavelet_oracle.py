#!/usr/bin/env python3
"""Independent reference values ("oracle") for the prt-wavelet crate (crates/wavelet).

Writes crates/wavelet/tests/data/wavelet_oracle.json (run from the repository root):

    tools/.venv/bin/pip install -r tools/requirements.txt     # numpy, PyWavelets (and the SH tools' deps)
    tools/.venv/bin/python tools/wavelet_oracle.py            # regenerate the JSON (~1 s)
    tools/.venv/bin/python tools/wavelet_oracle.py --check    # recompute and compare with the committed JSON

Needs numpy and PyWavelets only (plus the standard library's `decimal`). Deterministic (numpy seed
SEED). Nothing of the Rust crate is read or imported.

Wavelets and PyWavelets names: Haar = 'haar', LeGall 5/3 = 'bior2.2', CDF 9/7 = 'bior4.4'.

What it computes
----------------
* "filters": the exact filters, from their closed form in 60-digit `decimal` arithmetic, rounded
  to f64 (Daubechies, Ten Lectures, section 8.3: with y = sin^2(w/2), the 2N-vanishing-moment pair
  factors cos^(2N)(w/2) P_N(y), P_N(y) = sum_k binom(N-1+k, k) y^k; 5/3: N = 2, the 5-tap
  analysis low pass cos^2 (1 + 2y), the 3-tap synthesis low pass cos^2; 9/7: N = 4, P_4 = 1 + 4y
  + 10y^2 + 20y^3 has one real root y0, the 9-tap analysis low pass is cos^4 P_4(y)/(1 - y/y0), the
  7-tap synthesis low pass cos^4 (1 - y/y0); taps scaled by sqrt(2), PyWavelets' normalisation).
  Stored in the crate's centred convention: `analysis_low[m]`, m = offset .. offset+len-1, is the
  weight of x[2k+m] in the low-pass coefficient k; `synthesis_low[m]` the weight with which low-pass
  coefficient k adds to x[2k+m]. The high passes follow (PyWavelets' quadrature-mirror relations
  dec_hi[j] = (-1)^(j+1) rec_lo[j], rec_hi[j] = (-1)^j dec_lo[j]): analysis_high[m] = (-1)^m
  synthesis_low[1-m], synthesis_high[m] = (-1)^m analysis_low[1-m]. PyWavelets' pywt arrays index
  the same taps as dec_lo[F/2 - m] and rec_lo[m + F/2 - 1] (F = filter length), i.e. its
  periodization mode computes c[k] = sum_j dec_lo[j] x[(2k + F/2 - j) mod N] (checked below).
  "pywt_max_tap_deviation" = max |PyWavelets' tap - exact tap|: 0 for haar, ~1e-16 for bior2.2,
  6e-13 for bior4.4 (PyWavelets' bior4.4 constants carry 12 digits), so the periodization vectors
  below, which are PyWavelets' own output, carry that error; the tests derive their tolerance from it.
* "signals_1d" (random, 6 decimals, so that every reader parses the same f64) and, per wavelet,
  "periodization_1d": np.concatenate(pywt.wavedec(x, name, mode='periodization', level=L)) for
  L = 1, 2 and the largest L with len/2^L an integer (PyWavelets warns above its own
  dwt_max_level; the transform is still exactly circular, which the script checks);
  "symmetric_1d": the same layout for the whole-sample symmetric, critically sampled mode
  (x[-1] = x[1], x[N] = x[N-2]; JPEG2000), computed by the independent numpy implementation
  below (extend, np.convolve with the filters, keep the low pass at even and the high pass at odd
  centres). Checks of that implementation: its coefficients whose support lies inside the signal
  equal PyWavelets' periodization ones (the phase); all its coefficients equal a slice of
  PyWavelets' own whole-sample symmetric mode, 'reflect' (not critically sampled: it returns
  (N + F - 1)//2 coefficients; ours are its entries (F/2 - 1)/2 + k, k < N/2), level by level,
  down to length 2;
  its inverse (interleave low/high at even/odd positions, extend whole-sample symmetrically,
  upsample-convolve with the synthesis filters, the JPEG2000 procedure) reconstructs the signal.
* "arrays_2d" (row-major [y][x], height x width) and per wavelet "periodization_2d":
  pywt.coeffs_to_array(pywt.wavedec2(a, name, mode='periodization', level=L))[0] (the Mallat
  layout: LL top left, per level the x-detail/y-approximation band 'ad' to the right, 'da' below,
  'dd' diagonally), and "latlong_2d": the same layout with x periodic and y whole-sample
  symmetric (numpy implementation; its x part is checked against PyWavelets' periodization).
* "interpolation": coarse grids upsampled by inverse transforms with zero details, the coarse
  values scaled by sqrt(2) per 1D level (so that constants stay constants): periodic in both axes
  by pywt.waverec2 (equal level counts) or pywt.idwt per axis (unequal), and lat-long (x
  periodic, y symmetric) with the numpy implementation.
"""

import argparse
import json
import sys
import warnings
from decimal import Decimal, getcontext

import numpy as np
import pywt

SEED = 20040621
OUT = "crates/wavelet/tests/data/wavelet_oracle.json"
COMMAND = "tools/.venv/bin/python tools/wavelet_oracle.py"
WAVELETS = [("haar", "haar"), ("legall53", "bior2.2"), ("cdf97", "bior4.4")]

# --------------------------------------------------------------------------------------------
# Exact filters (60-digit decimal arithmetic)
# --------------------------------------------------------------------------------------------

getcontext().prec = 60


def _polymul(a, b):
    out = {}
    for i, x in a.items():
        for j, y in b.items():
            out[i + j] = out.get(i + j, Decimal(0)) + x * y
    return out


_COS2 = {-1: Decimal(1) / 4, 0: Decimal(2) / 4, 1: Decimal(1) / 4}  # cos^2(w/2), z = e^{iw}
_SIN2 = {-1: -Decimal(1) / 4, 0: Decimal(2) / 4, 1: -Decimal(1) / 4}  # y = sin^2(w/2)


def _poly_in_y(coeffs):
    out, power = {0: Decimal(0)}, {0: Decimal(1)}
    for c in coeffs:
        for k, v in power.items():
            out[k] = out.get(k, Decimal(0)) + c * v
        power = _polymul(power, _SIN2)
    return out


def _taps(laurent):
    s2 = Decimal(2).sqrt()
    keys = sorted(k for k, v in laurent.items() if abs(v) > Decimal(10) ** -50)
    return keys[0], [laurent[k] * s2 for k in range(keys[0], keys[-1] + 1)]


def exact_filters():
    """{name: (analysis_low (offset, [Decimal]), synthesis_low (offset, [Decimal]))}."""
    half = Decimal(1) / 2  # _taps scales by sqrt(2): 1/sqrt(2) per tap
    haar = (_taps({0: half, 1: half}), _taps({0: half, 1: half}))
    c2 = _COS2
    legall = (_taps(_polymul(c2, _poly_in_y([Decimal(1), Decimal(2)]))), _taps(c2))
    y = Decimal("-0.34")  # real root of 20y^3 + 10y^2 + 4y + 1 by Newton
    for _ in range(200):
        y -= (((20 * y + 10) * y + 4) * y + 1) / ((60 * y + 20) * y + 4)
    assert abs(((20 * y + 10) * y + 4) * y + 1) < Decimal(10) ** -55
    b1 = 10 + 20 * y
    b0 = 4 + b1 * y
    q = [-y * b0, -y * b1, -y * 20]  # P_4(y) / (1 - y/y0)
    c4 = _polymul(c2, c2)
    cdf = (_taps(_polymul(c4, _poly_in_y(q))), _taps(_polymul(c4, _poly_in_y([Decimal(1), -1 / y]))))
    return {"haar": haar, "legall53": legall, "cdf97": cdf}


EXACT = exact_filters()


def pywt_layout(key):
    """The exact filters as f64 arrays in PyWavelets' layout (dec_lo, dec_hi, rec_lo, rec_hi)."""
    name = dict(WAVELETS)[key]
    F = pywt.Wavelet(name).dec_len
    (ao, a), (so, s) = EXACT[key]
    dec_lo, dec_hi, rec_lo, rec_hi = (np.zeros(F) for _ in range(4))
    for i, v in enumerate(a):
        dec_lo[F // 2 - (ao + i)] = float(v)
    for i, v in enumerate(s):
        rec_lo[(so + i) + F // 2 - 1] = float(v)
    j = np.arange(F)
    dec_hi[:] = (-1.0) ** (j + 1) * rec_lo
    rec_hi[:] = (-1.0) ** j * dec_lo
    return dec_lo, dec_hi, rec_lo, rec_hi


def check_filters(log):
    devs = {}
    for key, name in WAVELETS:
        w = pywt.Wavelet(name)
        ours = pywt_layout(key)
        theirs = [np.array(w.dec_lo), np.array(w.dec_hi), np.array(w.rec_lo), np.array(w.rec_hi)]
        dev = max(float(np.abs(a - b).max()) for a, b in zip(ours, theirs))
        assert dev < 1e-12, (key, dev)
        # biorthogonality of the exact taps in decimal: sum_m a[m] s[m - 2k] = delta_k
        (ao, a), (so, s) = EXACT[key]
        for k in range(-5, 6):
            acc = sum(a[i] * s[ao + i - 2 * k - so] for i in range(len(a)) if 0 <= ao + i - 2 * k - so < len(s))
            assert abs(acc - (1 if k == 0 else 0)) < Decimal(10) ** -50, (key, k, acc)
        devs[key] = dev
        log("filters %-8s PyWavelets max tap deviation from exact: %.3g" % (key, dev))
    return devs


# --------------------------------------------------------------------------------------------
# Independent numpy implementation (np.convolve on extended signals)
# --------------------------------------------------------------------------------------------


def fold_whole(i, n):
    """Whole-sample symmetric index folding: x[-1] = x[1], x[n] = x[n-2] (period 2n-2)."""
    if n == 1:
        return np.zeros_like(i)
    p = 2 * n - 2
    r = np.mod(i, p)
    return np.where(r >= n, p - r, r)


def dwt_np(x, key, mode):
    """One level; x 1D, even length. Low pass centred at even samples, high pass at odd ones."""
    dec_lo, dec_hi, _, _ = pywt_layout(key)
    n, F = len(x), len(dec_lo)
    P = 2 * F + 2 * n  # generous margin (short signals fold several times)
    idx = np.arange(-P, n + P)
    xe = x[np.mod(idx, n)] if mode == "periodic" else x[fold_whole(idx, n)]
    lo, hi = np.convolve(xe, dec_lo), np.convolve(xe, dec_hi)  # full: y[k] = sum_j f[j] xe[k - j]
    keep = 2 * np.arange(n // 2) + F // 2 + P  # c[o] = sum_j f[j] x[2o + F/2 - j]
    return lo[keep], hi[keep]


def idwt_np(lo, hi, key, mode):
    """Inverse of dwt_np (JPEG2000 procedure: interleave, extend, upsample-convolve)."""
    _, _, rec_lo, rec_hi = pywt_layout(key)
    m = len(lo)
    n, F = 2 * m, len(rec_lo)
    y = np.zeros(n)
    y[0::2], y[1::2] = lo, hi  # low coefficient k sits at sample 2k, high at 2k+1
    P = 2 * F + 2 * n
    idx = np.arange(-P, n + P)
    ye = y[np.mod(idx, n)] if mode == "periodic" else y[fold_whole(idx, n)]
    ue_lo = np.where(np.mod(idx, 2) == 0, ye, 0.0)
    ue_hi = np.where(np.mod(idx, 2) == 1, ye, 0.0)
    # x[n] = sum_k rec[j] coef[k] with n = 2k + j - (F/2 - 1) for the low pass (coefficient at 2k);
    # the high-pass coefficient k sits at 2k+1, so n = (2k+1) + j - F/2.
    out_lo = np.convolve(ue_lo, rec_lo)  # out[t] = sum_j rec[j] ue[t - j], ue index t - j <-> sample t - j - P
    out_hi = np.convolve(ue_hi, rec_hi)
    t = np.arange(n)
    return out_lo[t + P + F // 2 - 1] + out_hi[t + P + F // 2]


def wavedec_np(x, key, mode, levels):
    out, a = [], np.array(x, dtype=float)
    for _ in range(levels):
        a, d = dwt_np(a, key, mode)
        out.insert(0, d)
    return np.concatenate([a] + out)


def along(axis, f, arr):
    return np.apply_along_axis(f, axis, arr)


def dwt2_level(a, key, mode_x, mode_y):
    """One 2D level in the Mallat layout: rows (x) then columns (y)."""
    def one(mode):
        return lambda v: np.concatenate(dwt_np(v, key, mode))

    return along(0, one(mode_y), along(1, one(mode_x), a))


def wavedec2_np(a, key, mode_x, mode_y, levels):
    out = np.array(a, dtype=float)
    h, w = out.shape
    for _ in range(levels):
        out[:h, :w] = dwt2_level(out[:h, :w], key, mode_x, mode_y)
        h, w = h // 2, w // 2
    return out


def upsample_np(coarse, key, mode_x, mode_y, levels_x, levels_y):
    """Inverse transform with zero details: levels_x 1D levels along x, levels_y along y."""
    f = np.array(coarse, dtype=float) * np.sqrt(2.0) ** (levels_x + levels_y)
    for _ in range(levels_x):
        f = along(1, lambda v: idwt_np(v, np.zeros_like(v), key, mode_x), f)
    for _ in range(levels_y):
        f = along(0, lambda v: idwt_np(v, np.zeros_like(v), key, mode_y), f)
    return f


# --------------------------------------------------------------------------------------------
# Generation
# --------------------------------------------------------------------------------------------


def rand(rng, *shape):
    return np.round(rng.uniform(-1.0, 1.0, size=shape), 6)


def levels_for(n):
    top = int(np.log2(n & -n))
    return sorted({1, min(2, top), top})


def support(key):
    """Smallest and largest sample offset m (x[2k+m]) read by the analysis low or high pass."""
    (ao, a), (so, s) = EXACT[key]
    return min(ao, 1 - (so + len(s) - 1)), max(ao + len(a) - 1, 1 - so)


def compare_symmetric_with_pywt(x, key, name, log, bound):
    """Our symmetric mode against PyWavelets' 'reflect' (same extension, not critically sampled)."""
    F = pywt.Wavelet(name).dec_len
    lo, hi = dwt_np(x, key, "symmetric")
    plo, phi = pywt.dwt(x, name, mode="reflect")
    # PyWavelets' 'reflect' output k reads xe[2k + 1 - j] (xe the whole-sample extension), so
    # ours (x[2o + F/2 - j]) is its entry k = o + (F/2 - 1)/2: F = 2, 6, 10 -> 0, 1, 2.
    s = (F // 2 - 1) // 2
    d = max(np.abs(lo - plo[s:s + len(lo)]).max(), np.abs(hi - phi[s:s + len(hi)]).max())
    assert d <= bound, (key, len(x), d)
    # interior coefficients equal the periodization ones (the phase)
    clo, chi = pywt.dwt(x, name, mode="periodization")
    first, last = support(key)
    n = len(x)
    inner = [o for o in range(n // 2) if 2 * o + first >= 0 and 2 * o + last <= n - 1]
    if inner:
        d2 = max(np.abs(lo[inner] - clo[inner]).max(), np.abs(hi[inner] - chi[inner]).max())
        assert d2 <= bound, (key, len(x), d2)
    else:
        d2 = 0.0
    return d, d2


def generate(log):
    rng = np.random.default_rng(SEED)
    devs = check_filters(log)
    warnings.simplefilter("ignore")  # PyWavelets warns for levels above its dwt_max_level

    signals = [rand(rng, n) for n in (2, 8, 32, 64)]
    arrays = [rand(rng, 8, 16), rand(rng, 16, 32)]
    coarse = {"4x2": rand(rng, 2, 4), "4x4": rand(rng, 4, 4)}  # -> 16x8
    out = {
        "description": __doc__,
        "generator": COMMAND,
        "check_command": COMMAND + " --check",
        "versions": {"python": sys.version.split()[0], "numpy": np.__version__, "pywt": pywt.__version__},
        "seed": SEED,
        "filters": {},
        "signals_1d": [s.tolist() for s in signals],
        "arrays_2d": [{"width": a.shape[1], "height": a.shape[0], "values": a.ravel().tolist()} for a in arrays],
        "cases": {},
    }
    checks = {}
    for key, name in WAVELETS:
        (ao, a), (so, s) = EXACT[key]
        out["filters"][key] = {
            "pywt_name": name,
            "analysis_low": {"offset": ao, "taps": [float(v) for v in a]},
            "synthesis_low": {"offset": so, "taps": [float(v) for v in s]},
            "analysis_low_decimal": [str(+v) for v in a],
            "synthesis_low_decimal": [str(+v) for v in s],
            "pywt_max_tap_deviation": devs[key],
        }
        # bound for the cross-checks: PyWavelets' tap error times the l1 growth over levels, plus rounding
        bound = 64 * (devs[key] + 1e-15) * 2.0 ** 6
        case = {"periodization_1d": [], "symmetric_1d": [], "periodization_2d": [], "latlong_2d": [],
                "interpolation": []}
        worst = {"periodic_np_vs_pywt": 0.0, "reflect_slice": 0.0, "interior": 0.0, "pr_np": 0.0,
                 "latlong_x_vs_pywt": 0.0, "layout": 0.0, "interp_np_vs_pywt": 0.0}
        for si, x in enumerate(signals):
            for L in levels_for(len(x)):
                c = np.concatenate(pywt.wavedec(x, name, mode="periodization", level=L))
                ours = wavedec_np(x, key, "periodic", L)
                worst["periodic_np_vs_pywt"] = max(worst["periodic_np_vs_pywt"], float(np.abs(c - ours).max()))
                assert np.abs(c - ours).max() <= bound
                case["periodization_1d"].append({"signal": si, "levels": L, "coefficients": c.tolist()})
                sym = wavedec_np(x, key, "symmetric", L)
                case["symmetric_1d"].append({"signal": si, "levels": L, "coefficients": sym.tolist()})
            # level-by-level cross-checks of the symmetric mode against PyWavelets
            a_ = x.copy()
            while len(a_) >= 2 and len(a_) % 2 == 0:
                d, d2 = compare_symmetric_with_pywt(a_, key, name, log, bound)
                worst["reflect_slice"] = max(worst["reflect_slice"], d)
                worst["interior"] = max(worst["interior"], d2)
                lo, hi = dwt_np(a_, key, "symmetric")
                worst["pr_np"] = max(worst["pr_np"], float(np.abs(idwt_np(lo, hi, key, "symmetric") - a_).max()))
                lo_p, hi_p = dwt_np(a_, key, "periodic")
                worst["pr_np"] = max(worst["pr_np"], float(np.abs(idwt_np(lo_p, hi_p, key, "periodic") - a_).max()))
                a_ = lo
        for ai, arr in enumerate(arrays):
            h, w = arr.shape
            top = min(int(np.log2(h)), int(np.log2(w)))
            for L in sorted({1, top}):
                coeffs = pywt.wavedec2(arr, name, mode="periodization", level=L)
                c = pywt.coeffs_to_array(coeffs)[0]
                ours = wavedec2_np(arr, key, "periodic", "periodic", L)
                worst["layout"] = max(worst["layout"], float(np.abs(c - ours).max()))
                assert np.abs(c - ours).max() <= bound
                case["periodization_2d"].append({"array": ai, "levels": L, "coefficients": c.ravel().tolist()})
                ll = wavedec2_np(arr, key, "periodic", "symmetric", L)
                # x part alone against PyWavelets: one level of rows
                xa, xd = pywt.dwt(arr, name, mode="periodization", axis=1)
                xo = along(1, lambda v: np.concatenate(dwt_np(v, key, "periodic")), arr)
                worst["latlong_x_vs_pywt"] = max(worst["latlong_x_vs_pywt"],
                                                 float(np.abs(np.concatenate([xa, xd], axis=1) - xo).max()))
                case["latlong_2d"].append({"array": ai, "levels": L, "coefficients": ll.ravel().tolist()})
        for cname, cgrid in coarse.items():
            ch, cw = cgrid.shape
            lx, ly = 2, (2 if cname == "4x2" else 1)
            if lx == ly:
                coeffs = [cgrid * 2.0 ** lx] + [tuple(np.zeros((ch * 2 ** k, cw * 2 ** k)) for _ in range(3))
                                                for k in range(lx)]
                fine = pywt.waverec2(coeffs, name, mode="periodization")
            else:
                fine = cgrid * np.sqrt(2.0) ** (lx + ly)
                for _ in range(lx):
                    fine = pywt.idwt(fine, None, name, mode="periodization", axis=1)
                for _ in range(ly):
                    fine = pywt.idwt(fine, None, name, mode="periodization", axis=0)
            ours = upsample_np(cgrid, key, "periodic", "periodic", lx, ly)
            worst["interp_np_vs_pywt"] = max(worst["interp_np_vs_pywt"], float(np.abs(fine - ours).max()))
            assert np.abs(fine - ours).max() <= bound
            for mode_y, values in (("periodic", fine), ("symmetric", upsample_np(cgrid, key, "periodic", "symmetric", lx, ly))):
                case["interpolation"].append({
                    "coarse": cname, "boundary_x": "periodic", "boundary_y": mode_y,
                    "coarse_width": cw, "coarse_height": ch, "width": cw * 2 ** lx, "height": ch * 2 ** ly,
                    "fine": values.ravel().tolist(),
                })
        out["cases"][key] = case
        checks[key] = worst
        log("checks %-8s %s" % (key, ", ".join("%s %.2g" % kv for kv in worst.items())))
        assert worst["pr_np"] < 1e-13, worst
    out["coarse_grids"] = {k: {"width": v.shape[1], "height": v.shape[0], "values": v.ravel().tolist()}
                           for k, v in coarse.items()}
    out["self_checks"] = checks
    return out


def flatten(v, path=""):
    if isinstance(v, dict):
        for k in sorted(v):
            yield from flatten(v[k], path + "/" + k)
    elif isinstance(v, list):
        for i, x in enumerate(v):
            yield from flatten(x, "%s[%d]" % (path, i))
    else:
        yield path, v


def check(path, log):
    with open(path) as f:
        old = json.load(f)
    new = json.loads(json.dumps(generate(lambda *_: None)))
    a, b = dict(flatten(old)), dict(flatten(new))
    ok = True
    if set(a) != set(b):
        log("check: different structure (%d vs %d entries)" % (len(a), len(b)))
        return False
    worst = 0.0
    for k, v in a.items():
        if k.startswith("/versions") or k.startswith("/description") or k.startswith("/self_checks"):
            continue
        w = b[k]
        if isinstance(v, float) and isinstance(w, (int, float)):
            d = abs(v - w)
            worst = max(worst, d)
            if d > 1e-13 * max(1.0, abs(v)):
                log("check: %s differs: %r vs %r" % (k, v, w))
                ok = False
        elif v != w:
            log("check: %s differs: %r vs %r" % (k, v, w))
            ok = False
    log("check: %s (%d values, largest difference %.3g)" % ("OK" if ok else "FAILED", len(a), worst))
    return ok


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="recompute and compare with the committed JSON")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    if args.check:
        return 0 if check(args.out, print) else 1
    data = generate(print)
    text = json.dumps(data, separators=(",", ":"))
    with open(args.out, "w") as f:
        f.write(text + "\n")
    print("wrote %s (%d bytes)" % (args.out, len(text) + 1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
