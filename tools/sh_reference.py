#!/usr/bin/env python3
"""Independent reference data for the `prt-sh` crate (crates/sh).

Regenerates every JSON file in crates/sh/tests/data/ deterministically (fixed seeds)
using mpmath / SymPy / SciPy / NumPy only -- no code is shared with the Rust crate and
no SH recurrence of ours is used.  Run from anywhere:

    tools/.venv/bin/python tools/sh_reference.py

Conventions (binding, /work/shared/CONVENTIONS.md "Spherical harmonics"):
real orthonormal SH with the Condon-Shortley phase,
    y_l^m = sqrt2 Re Y_l^|m| (m>0),  sqrt2 Im Y_l^|m| (m<0),  Y_l^0 (m=0),
Y the complex CS-phase harmonics (scipy.special.sph_harm_y, mpmath.spherharm),
theta measured from +Z, phi = atan2(y, x); flat index i = l(l+1)+m;
"order n" = n bands (l = 0..n-1, n^2 coefficients).

See tools/README.md for the layout of every file.
"""

import json
import math
import sys
import time
from fractions import Fraction
from math import comb, isqrt
from pathlib import Path

import mpmath
import numpy as np
import scipy
import scipy.special
import sympy
from mpmath import mp
from numpy.polynomial.legendre import leggauss
from sympy.physics.wigner import gaunt as sympy_gaunt

ROOT = Path(__file__).resolve().parent.parent
OUT = ROOT / "crates" / "sh" / "tests" / "data"
SQRT2 = math.sqrt(2.0)
VERSIONS = {
    "python": sys.version.split()[0],
    "numpy": np.__version__,
    "scipy": scipy.__version__,
    "sympy": sympy.__version__,
    "mpmath": mpmath.__version__,
}
CONVENTION = (
    "Real orthonormal SH with Condon-Shortley phase: y_l^m = sqrt(2) K_l^m cos(m phi) P_l^m(cos theta) (m>0), "
    "sqrt(2) K_l^m sin(|m| phi) P_l^|m|(cos theta) (m<0), K_l^0 P_l^0(cos theta) (m=0); P_l^m includes (-1)^m; "
    "theta from +Z, phi = atan2(y, x) of the world direction (x, y, z); flat index i = l(l+1)+m; "
    "order n = n bands (l = 0..n-1, n^2 coefficients)."
)


def idx(l, m):
    return l * (l + 1) + m


def lm(i):
    l = isqrt(i)
    return l, i - l * (l + 1)


def log(msg):
    print(msg, flush=True)


# ---------------------------------------------------------------------------------------
# Real SH evaluation: float64 via SciPy, high precision via mpmath, and an independent
# high-precision polynomial form (x + i y)^m d^m P_l/dz^m (the eval.json reference).
# ---------------------------------------------------------------------------------------


def real_sh_np(order, dirs):
    """Real SH (float64, SciPy) for directions dirs (N, 3) -> array (N, order^2)."""
    dirs = np.asarray(dirs, dtype=np.float64)
    x, y, z = dirs[:, 0], dirs[:, 1], dirs[:, 2]
    theta = np.arctan2(np.hypot(x, y), z)
    phi = np.arctan2(y, x)
    out = np.empty((dirs.shape[0], order * order))
    for l in range(order):
        ms = np.arange(l + 1)[:, None]
        Y = scipy.special.sph_harm_y(l, ms, theta[None, :], phi[None, :])
        out[:, idx(l, 0)] = Y[0].real
        for m in range(1, l + 1):
            out[:, idx(l, m)] = SQRT2 * Y[m].real
            out[:, idx(l, -m)] = SQRT2 * Y[m].imag
    return out


def real_sh_mp(order, d):
    """Real SH at mpmath working precision via mpmath.spherharm; d = exact float direction."""
    x, y, z = (mp.mpf(c) for c in d)
    theta = mp.atan2(mp.hypot(x, y), z)  # same as normalising d first
    phi = mp.atan2(y, x)
    s2 = mp.sqrt(2)
    out = [None] * (order * order)
    for l in range(order):
        for m in range(l + 1):
            Y = mp.spherharm(l, m, theta, phi)
            if m == 0:
                out[idx(l, 0)] = mp.re(Y)
            else:
                out[idx(l, m)] = s2 * mp.re(Y)
                out[idx(l, -m)] = s2 * mp.im(Y)
    return out


_DPOLY = {}


def _legendre_deriv_coeffs(l, m):
    """Exact coefficients (ascending powers) of d^m/dz^m P_l(z)."""
    key = (l, m)
    if key not in _DPOLY:
        c = [Fraction(0)] * (l + 1)
        for k in range(l // 2 + 1):
            c[l - 2 * k] = Fraction((-1) ** k * comb(l, k) * comb(2 * l - 2 * k, l), 2**l)
        for _ in range(m):
            c = [c[p] * p for p in range(1, len(c))] or [Fraction(0)]
        _DPOLY[key] = c
    return _DPOLY[key]


def real_sh_mp_poly(order, d):
    """Independent form: Y_l^m = K_l^m (-1)^m (x + i y)^m P_l^(m)(z) on the normalised
    direction (no angles, no hypergeometric functions)."""
    x, y, z = (mp.mpf(c) for c in d)
    r = mp.sqrt(x * x + y * y + z * z)
    x, y, z = x / r, y / r, z / r
    w = mp.mpc(x, y)
    s2 = mp.sqrt(2)
    out = [None] * (order * order)
    for l in range(order):
        for m in range(l + 1):
            coeffs = _legendre_deriv_coeffs(l, m)
            acc = mp.mpf(0)
            for c in reversed(coeffs):
                acc = acc * z + mp.mpf(c.numerator) / c.denominator
            K = mp.sqrt(mp.mpf(2 * l + 1) / (4 * mp.pi) * mp.factorial(l - m) / mp.factorial(l + m))
            Y = K * (-1) ** m * w**m * acc
            if m == 0:
                out[idx(l, 0)] = mp.re(Y)
            else:
                out[idx(l, m)] = s2 * mp.re(Y)
                out[idx(l, -m)] = s2 * mp.im(Y)
    return out


def mp_to_float(v):
    """Correctly rounded float of an mpf (via a 36-digit decimal string)."""
    return float(mp.nstr(v, 36, min_fixed=1, max_fixed=0))


def check_band1(rng):
    """The binding checks of CONVENTIONS.md on a random direction, in all three evaluators."""
    d = rng.normal(size=3)
    d /= np.linalg.norm(d)
    c = math.sqrt(3.0 / (4.0 * math.pi))
    want = [-c * d[1], c * d[2], -c * d[0]]  # y_1^{-1}, y_1^0, y_1^1
    got_np = real_sh_np(2, d[None, :])[0, 1:4]
    with mp.workdps(40):
        got_mp = [float(v) for v in real_sh_mp(2, d)[1:4]]
        got_poly = [float(v) for v in real_sh_mp_poly(2, d)[1:4]]
    for got in (got_np, got_mp, got_poly):
        for a, b in zip(got, want):
            assert abs(a - b) < 1e-15, (got, want)
    with mp.workdps(40):
        y0 = float(real_sh_mp(1, d)[0])
    assert abs(y0 - 0.5 / math.sqrt(math.pi)) < 1e-16
    log(f"check: y_1^-1 = -sqrt(3/4pi) y, y_1^0 = sqrt(3/4pi) z, y_1^1 = -sqrt(3/4pi) x hold at d = {d.tolist()}")


def write_json(name, obj):
    OUT.mkdir(parents=True, exist_ok=True)
    path = OUT / name
    text = json.dumps(obj, allow_nan=False, separators=(",", ":"))
    json.loads(text)  # valid JSON
    path.write_text(text + "\n")
    size = path.stat().st_size
    assert size < 3_000_000, (name, size)
    log(f"wrote {path.relative_to(ROOT)} ({size} bytes)")


# ---------------------------------------------------------------------------------------
# 1. eval.json
# ---------------------------------------------------------------------------------------


def eval_directions(rng):
    dirs = []  # (label, [x, y, z])

    def add(label, v):
        dirs.append((label, [float(c) for c in v]))

    add("north pole", (0.0, 0.0, 1.0))
    add("south pole", (0.0, 0.0, -1.0))
    for k, t in enumerate([1e-12, 1e-8, 1e-4, 1e-2]):
        p = 0.7 + 1.3 * k
        add(f"polar angle {t:g} from +Z, phi {p:g}", (math.sin(t) * math.cos(p), math.sin(t) * math.sin(p), math.cos(t)))
        q = -2.9 + 1.7 * k
        add(f"polar angle {t:g} from -Z, phi {q:g}", (math.sin(t) * math.cos(q), math.sin(t) * math.sin(q), -math.cos(t)))
    for p in (0.4, 2.2, -1.9):
        add(f"equator, phi {p:g}", (math.cos(p), math.sin(p), 0.0))
    add("+X", (1.0, 0.0, 0.0))
    add("-X", (-1.0, 0.0, 0.0))
    add("+Y", (0.0, 1.0, 0.0))
    add("-Y", (0.0, -1.0, 0.0))
    # exact zeros and negative zeros
    add("north pole with -0.0", (-0.0, -0.0, 1.0))
    add("south pole with -0.0", (-0.0, 0.0, -1.0))
    add("-X with -0.0", (-1.0, -0.0, 0.0))
    add("-X with -0.0 and -0.0", (-1.0, -0.0, -0.0))
    add("-Y with -0.0", (-0.0, -1.0, -0.0))
    add("xz plane with -0.0 y", (0.6, -0.0, 0.8))
    add("yz plane with -0.0 x", (-0.0, 0.6, -0.8))
    add("diagonal in xy", (math.sqrt(0.5), -math.sqrt(0.5), 0.0))
    n_random = 40 - len(dirs)
    for k in range(n_random):
        v = rng.normal(size=3)
        v /= np.linalg.norm(v)
        add(f"random {k}", v)
    return dirs


def make_eval(rng):
    order = 41
    dirs = eval_directions(rng)
    cases = []
    max_poly_dev = 0.0
    for label, d in dirs:
        with mp.workdps(40):
            chk = real_sh_mp(order, d)  # mpmath.spherharm (hypergeometric), 40 digits
        with mp.workdps(60):
            # primary: polynomial form in (x, y, z), exact zeros at the poles; the spherharm
            # cross-check gets a floor scaled by sin(theta)^|m| (tiny near-pole values are compared
            # relatively); at the exact poles 1e-38 absolute (spherharm's sin(pi) is ~1e-40, not 0)
            vals = real_sh_mp_poly(order, d)
            x, y, z = (mp.mpf(c) for c in d)
            st = mp.hypot(x, y) / mp.sqrt(x * x + y * y + z * z)
            for i in range(order * order):
                l, m = lm(i)
                floor = mp.mpf("1e-30") * st ** abs(m) if st > 0 else mp.mpf("1e-38")
                dev = abs(vals[i] - chk[i])
                assert dev <= mp.mpf("1e-25") * abs(vals[i]) + floor, (label, i, vals[i], chk[i])
                if vals[i] != 0:
                    max_poly_dev = max(max_poly_dev, float(dev / (abs(vals[i]) + floor)))
            fvals = [mp_to_float(v) for v in vals]
        cases.append({"label": label, "dir": d, "values": fvals})
    # sanity vs SciPy float64 (SciPy's own recurrence; loose tolerance)
    ref = np.array([c["values"] for c in cases])
    sp = real_sh_np(order, np.array([c["dir"] for c in cases]))
    dev_scipy = float(np.max(np.abs(ref - sp)))
    assert dev_scipy < 1e-11, dev_scipy
    log(f"eval: (x+iy)^m P_l^(m)(z) (60 digits) vs mpmath.spherharm (40 digits): max rel dev {max_poly_dev:.1e}; "
        f"vs SciPy float64: max abs dev {dev_scipy:.1e}")
    write_json("eval.json", {
        "description": (
            "Reference real SH values. order = number of bands (41: l = 0..40, 1681 values). Each case: "
            "'dir' = the direction [x, y, z] exactly as stored (float64, unit up to rounding; the reference is "
            "for that float vector normalised in extended precision), 'values' = y_i(dir) for flat index "
            "i = l(l+1)+m, i = 0..1680, computed with mpmath at 60 significant digits from the polynomial form "
            "Y_l^m = K_l^m (-1)^m (x+iy)^m d^m P_l/dz^m (z) (exact rational coefficients; exact zeros at the poles), "
            "cross-checked against mpmath.spherharm at 40 digits, then correctly rounded to "
            "float64 (values below the float64 range are 0.0). 'label' says what the direction is. Includes exact "
            "poles, near-pole directions (polar angle 1e-12..1e-2 from +Z and -Z), equator, +-X, +-Y, components "
            "with exact 0.0 and -0.0, and random directions. " + CONVENTION),
        "generator": "tools/sh_reference.py",
        "versions": VERSIONS,
        "order": order,
        "cases": cases,
    })


# ---------------------------------------------------------------------------------------
# 2. gaunt.json
# ---------------------------------------------------------------------------------------

_CG_CACHE = {}


def complex_gaunt(l1, l2, l3, m1, m2, m3):
    """sympy.physics.wigner.gaunt = integral of Y_l1^m1 Y_l2^m2 Y_l3^m3 (no conjugation),
    exact, converted to an mpf at the current precision."""
    if m1 + m2 + m3 != 0:
        return mp.mpf(0)
    key = (l1, l2, l3, m1, m2, m3)
    if key not in _CG_CACHE:
        g = sympy_gaunt(l1, l2, l3, m1, m2, m3)
        _CG_CACHE[key] = mp.mpf(0) if g == 0 else mp.mpf(str(sympy.N(g, 70)))
    return _CG_CACHE[key]


def real_to_complex(l, m):
    """y_l^m = sum over (m', c) of c * Y_l^m' (unitary complex -> real change of basis)."""
    s = 1 / mp.sqrt(2)
    if m == 0:
        return [(0, mp.mpc(1))]
    if m > 0:
        return [(m, mp.mpc(s)), (-m, mp.mpc((-1) ** m * s))]
    k = -m
    return [(k, mp.mpc(0, -s)), (-k, mp.mpc(0, (-1) ** k * s))]


def real_gaunt(i, j, k):
    (l1, m1), (l2, m2), (l3, m3) = lm(i), lm(j), lm(k)
    if not (abs(l1 - l2) <= l3 <= l1 + l2) or (l1 + l2 + l3) % 2:
        return mp.mpf(0)
    acc = mp.mpc(0)
    for a, ca in real_to_complex(l1, m1):
        for b, cb in real_to_complex(l2, m2):
            for c, cc in real_to_complex(l3, m3):
                if a + b + c == 0:
                    acc += ca * cb * cc * complex_gaunt(l1, l2, l3, a, b, c)
    assert abs(mp.im(acc)) < mp.mpf("1e-45"), (i, j, k, acc)
    return mp.re(acc)


def real_selection_rule(i, j, k):
    (l1, m1), (l2, m2), (l3, m3) = lm(i), lm(j), lm(k)
    if not (abs(l1 - l2) <= l3 <= l1 + l2) or (l1 + l2 + l3) % 2:
        return False
    if sum(1 for m in (m1, m2, m3) if m < 0) % 2:  # an odd number of sin(|m| phi) factors
        return False
    a, b, c = sorted((abs(m1), abs(m2), abs(m3)))
    return c == a + b


def quad_gaunt(triples, order):
    """Gaunt coefficients by direct quadrature: Gauss-Legendre in cos(theta) x uniform phi,
    exact for the degrees involved (product degree <= 3 (order-1))."""
    deg = 3 * (order - 1)
    n_t = deg // 2 + 2
    n_p = deg + 2
    t, w = leggauss(n_t)
    phi = 2 * np.pi * np.arange(n_p) / n_p
    T, P = np.meshgrid(t, phi, indexing="ij")
    st = np.sqrt(1 - T * T)
    dirs = np.stack([st * np.cos(P), st * np.sin(P), T], axis=-1).reshape(-1, 3)
    W = np.repeat(w * (2 * np.pi / n_p), n_p)
    Y = real_sh_np(order, dirs)
    return [float(np.sum(W * Y[:, i] * Y[:, j] * Y[:, k])) for i, j, k in triples]


def check_sympy_gaunt_convention():
    """sympy's gaunt is the integral of Y Y Y with no conjugation, CS phase (SciPy's Y)."""
    t, w = leggauss(20)
    n_p = 40
    phi = 2 * np.pi * np.arange(n_p) / n_p
    T, P = np.meshgrid(np.arccos(t), phi, indexing="ij")
    W = (w[:, None] * (2 * np.pi / n_p)) * np.ones_like(P)
    for (l1, l2, l3, m1, m2, m3) in [(1, 1, 2, 1, 1, -2), (2, 3, 3, -1, 3, -2), (2, 2, 2, 1, 1, -2), (3, 2, 1, 2, -1, -1)]:
        Y1 = scipy.special.sph_harm_y(l1, m1, T, P)
        Y2 = scipy.special.sph_harm_y(l2, m2, T, P)
        Y3 = scipy.special.sph_harm_y(l3, m3, T, P)
        num = np.sum(W * Y1 * Y2 * Y3)
        ex = float(sympy.N(sympy_gaunt(l1, l2, l3, m1, m2, m3), 30))
        assert abs(num - ex) < 1e-14, (l1, l2, l3, m1, m2, m3, num, ex)
    log("gaunt: sympy.physics.wigner.gaunt == integral of Y Y Y (no conjugation, CS phase) confirmed numerically")


def make_gaunt(rng):
    check_sympy_gaunt_convention()
    thr = mp.mpf("1e-40")
    with mp.workdps(60):
        all5 = []
        for i in range(25):
            for j in range(i, 25):
                for k in range(j, 25):
                    v = real_gaunt(i, j, k)
                    if abs(v) > thr:
                        assert real_selection_rule(i, j, k), (i, j, k, v)
                        all5.append([i, j, k, mp_to_float(v)])
        n_rule5 = sum(1 for i in range(25) for j in range(i, 25) for k in range(j, 25) if real_selection_rule(i, j, k))

        def sorted_triple():
            return sorted(int(a) for a in rng.integers(0, 256, size=3))

        nonzero, seen, accidental = [], set(), 0
        while len(nonzero) < 200:
            t = tuple(sorted_triple())
            if t in seen or not real_selection_rule(*t):
                continue
            seen.add(t)
            v = real_gaunt(*t)
            if abs(v) > thr:
                nonzero.append([*t, mp_to_float(v)])
            else:
                accidental += 1
        rand = []
        while len(rand) < 200:
            t = tuple(sorted_triple())
            if t in seen:
                continue
            seen.add(t)
            v = real_gaunt(*t)
            assert (abs(v) > thr) <= real_selection_rule(*t), t
            rand.append([*t, mp_to_float(v) if abs(v) > thr else 0.0])
        sample16 = sorted(nonzero + rand)
    n_rand_nz = sum(1 for e in rand if e[3] != 0.0)

    # cross-check by direct quadrature (float64)
    chk5 = [all5[q] for q in rng.choice(len(all5), size=8, replace=False)] + [[0, 0, 0, 1 / math.sqrt(4 * math.pi)]]
    chk16 = [sample16[q] for q in rng.choice(len(sample16), size=12, replace=False)]
    chk16 += [e for e in nonzero[:4]] + [e for e in rand if e[3] == 0.0][:2]
    worst = 0.0
    for chk, order in ((chk5, 5), (chk16, 16)):
        q = quad_gaunt([tuple(e[:3]) for e in chk], order)
        for e, v in zip(chk, q):
            assert abs(e[3] - v) < 1e-12, (e, v)
            worst = max(worst, abs(e[3] - v))
    assert abs(all5[0][3] - 1 / math.sqrt(4 * math.pi)) < 1e-16 and all5[0][:3] == [0, 0, 0]
    log(f"gaunt: order 5: {len(all5)} non-zero of {n_rule5} allowed by the selection rules; "
        f"order 16 sample: {len(nonzero)} non-zero + {len(rand)} random ({n_rand_nz} of them non-zero), "
        f"{accidental} rule-allowed triples were exactly zero; {len(chk5) + len(chk16)} entries match quadrature "
        f"to {worst:.1e}")
    write_json("gaunt.json", {
        "description": (
            "Real-basis Gaunt coefficients G_ijk = integral over the sphere of y_i y_j y_k (flat indices, "
            "i = l(l+1)+m). Entries are [i, j, k, value] with i <= j <= k (G is symmetric in i, j, k). "
            "'all_order_5': every entry with i <= j <= k < 25 whose value is non-zero (all others are exactly 0), "
            "sorted. 'sample_order_16': 400 triples with i <= j <= k < 256, sorted, drawn with a fixed seed: 200 "
            "non-zero ones chosen among triples obeying the selection rules (l triangle, l1+l2+l3 even, an even "
            "number of negative m, and the largest |m| = sum of the other two) plus 200 uniformly random triples "
            "(mostly exactly 0, stored as 0.0). Computed from sympy.physics.wigner.gaunt (exact integral of "
            "Y Y Y, no conjugation) through the unitary complex-to-real change of basis, summed with mpmath at "
            "60 digits; cross-checked against direct quadrature to 1e-12. " + CONVENTION),
        "generator": "tools/sh_reference.py",
        "versions": VERSIONS,
        "all_order_5": all5,
        "sample_order_16": sample16,
    })


# ---------------------------------------------------------------------------------------
# 3. rotation.json
# ---------------------------------------------------------------------------------------


def quat_to_matrix(q):
    x, y, z, w = q
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
        [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
        [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
    ])


def axis_angle_quat(axis, deg):
    a = math.radians(deg) / 2
    axis = np.asarray(axis, dtype=float)
    axis = axis / np.linalg.norm(axis)
    return [*(math.sin(a) * axis).tolist(), math.cos(a)]


def sh_rotation_bands(R, order):
    """Per band l, the (2l+1)^2 block of D_ij = integral y_i(w) y_j(R^-1 w) dw, by quadrature
    (Gauss-Legendre in cos(theta) x uniform phi, exact for degree 2(order-1))."""
    lmax = order - 1
    n_t = lmax + 2
    n_p = 2 * lmax + 2
    t, w = leggauss(n_t)
    phi = 2 * np.pi * np.arange(n_p) / n_p
    T, P = np.meshgrid(t, phi, indexing="ij")
    st = np.sqrt(1 - T * T)
    dirs = np.stack([st * np.cos(P), st * np.sin(P), T], axis=-1).reshape(-1, 3)
    W = np.repeat(w * (2 * np.pi / n_p), n_p)
    Rinv_dirs = dirs @ np.asarray(R)  # rows: R^T d = R^-1 d
    Y = real_sh_np(order, dirs)
    Yr = real_sh_np(order, Rinv_dirs)
    bands = []
    for l in range(order):
        s = slice(l * l, (l + 1) * (l + 1))
        bands.append((Y[:, s] * W[:, None]).T @ Yr[:, s])
    return bands


def check_orthogonal(bands, name):
    worst = 0.0
    for D in bands:
        e = np.max(np.abs(D @ D.T - np.eye(D.shape[0])))
        worst = max(worst, e)
        assert e < 1e-12, (name, D.shape, e)
    return worst


def make_rotation(rng):
    order = 12
    rots = [("rot_x_90", axis_angle_quat([1, 0, 0], 90.0)),
            ("rot_y_90", axis_angle_quat([0, 1, 0], 90.0)),
            ("rot_z_90", axis_angle_quat([0, 0, 1], 90.0))]
    for name in ("random_a", "random_b"):
        q = rng.normal(size=4)
        q /= np.linalg.norm(q)
        if q[3] < 0:
            q = -q
        rots.append((name, q.tolist()))
    exact = {"rot_x_90": [[1, 0, 0], [0, 0, -1], [0, 1, 0]],
             "rot_y_90": [[0, 0, 1], [0, 1, 0], [-1, 0, 0]],
             "rot_z_90": [[0, -1, 0], [1, 0, 0], [0, 0, 1]]}
    entries, Ds, Ms = [], {}, {}
    worst_orth = 0.0
    c1 = math.sqrt(3 / (4 * math.pi))
    # y_1 (m = -1, 0, 1) = c1 * Pm @ (x, y, z)
    Pm = np.array([[0, -1, 0], [0, 0, 1], [-1, 0, 0]], dtype=float)
    for name, q in rots:
        M = quat_to_matrix(q)
        if name in exact:
            assert np.max(np.abs(M - np.array(exact[name]))) < 1e-15
            M = np.array(exact[name], dtype=float)
        assert np.max(np.abs(M @ M.T - np.eye(3))) < 1e-15 and abs(np.linalg.det(M) - 1) < 1e-15
        bands = sh_rotation_bands(M, order)
        worst_orth = max(worst_orth, check_orthogonal(bands, name))
        # band 0 is 1; band 1 is the rotation itself in the (-y, z, -x) basis: D1 = Pm R Pm^T
        assert abs(bands[0][0, 0] - 1) < 1e-14
        assert np.max(np.abs(bands[1] - Pm @ M @ Pm.T)) < 1e-14, name
        # D applied to coefficients of f gives coefficients of f(R^-1 w): check at a point
        c = rng.normal(size=order * order)
        w0 = rng.normal(size=3)
        w0 /= np.linalg.norm(w0)
        g = np.concatenate([bands[l] @ c[l * l:(l + 1) * (l + 1)] for l in range(order)])
        lhs = real_sh_np(order, w0[None, :])[0] @ g
        rhs = real_sh_np(order, (M.T @ w0)[None, :])[0] @ c
        assert abs(lhs - rhs) < 1e-12, (name, lhs, rhs)
        Ds[name], Ms[name] = bands, M
        entries.append({
            "name": name, "matrix": M.reshape(-1).tolist(), "quat": [float(v) for v in q],
            "order": order, "bands": [{"l": l, "d": D.reshape(-1).tolist()} for l, D in enumerate(bands)],
        })
    # composition: D(R1 R2) = D(R1) D(R2)
    worst_comp = 0.0
    for n1, n2 in [("random_a", "random_b"), ("rot_x_90", "rot_y_90"), ("rot_z_90", "random_a"), ("random_b", "rot_x_90")]:
        D12 = sh_rotation_bands(Ms[n1] @ Ms[n2], order)
        for l in range(order):
            e = np.max(np.abs(D12[l] - Ds[n1][l] @ Ds[n2][l]))
            worst_comp = max(worst_comp, e)
            assert e < 1e-12, (n1, n2, l, e)
    # high order, one random rotation (the same as random_a), selected bands only
    hi_order = 31
    keep = [0, 1, 2, 10, 20, 30]
    name, q = rots[3]
    M = Ms[name]
    hb = sh_rotation_bands(M, hi_order)
    worst_orth = max(worst_orth, check_orthogonal(hb, name + " order 31"))
    for l in range(order):
        assert np.max(np.abs(hb[l] - Ds[name][l])) < 1e-13
    # composition at high order (with random_b)
    Mb = Ms["random_b"]
    hb_b = sh_rotation_bands(Mb, hi_order)
    hb_ab = sh_rotation_bands(M @ Mb, hi_order)
    for l in range(hi_order):
        e = np.max(np.abs(hb_ab[l] - hb[l] @ hb_b[l]))
        worst_comp = max(worst_comp, e)
        assert e < 1e-12, ("order 31", l, e)
    entries.append({
        "name": name + "_order31", "matrix": M.reshape(-1).tolist(), "quat": [float(v) for v in q],
        "order": hi_order, "bands": [{"l": l, "d": hb[l].reshape(-1).tolist()} for l in keep],
    })
    log(f"rotation: max |D D^T - I| = {worst_orth:.1e}, max |D(R1 R2) - D(R1) D(R2)| = {worst_comp:.1e}; "
        f"band 1 equals the 3x3 matrix in the (-y, z, -x) basis")
    write_json("rotation.json", {
        "description": (
            "Real SH rotation matrices. D is the matrix mapping the SH coefficients c of f to the coefficients "
            "of the rotated function g(w) = f(R^-1 w): D_ij = integral y_i(w) y_j(R^-1 w) dw, so "
            "g_i = sum_j D_ij c_j, and D(R1 R2) = D(R1) D(R2). D is block diagonal; 'bands' lists the blocks: "
            "{'l': l, 'd': (2l+1)^2 floats, row-major}, row r and column c of block l being flat indices "
            "l^2 + r and l^2 + c (m = r - l, c - l). Each rotation has 'matrix' (3x3 row-major, acting on "
            "column vectors: w' = R w, right-handed) and 'quat' [x, y, z, w] (unit, same rotation, w >= 0). "
            "Entries with order 12 store all bands l = 0..11; the entry '*_order31' (the same rotation as "
            "random_a) stores only bands 0, 1, 2, 10, 20, 30 of order 31. Computed by quadrature "
            "(Gauss-Legendre in cos(theta) x uniform phi, exact for the polynomial degree) with "
            "scipy.special.sph_harm_y in float64; checked orthogonal to 1e-12, D(R1 R2) = D(R1) D(R2) to 1e-12, "
            "band 1 = the 3x3 matrix in the (-y, z, -x) basis. " + CONVENTION),
        "generator": "tools/sh_reference.py",
        "versions": VERSIONS,
        "rotations": entries,
    })


# ---------------------------------------------------------------------------------------
# 4. zonal.json
# ---------------------------------------------------------------------------------------


def zonal_integral(e, l):
    """integral_0^1 x^e P_l(x) dx by mpmath.quad (tanh-sinh), split into pieces; for large e
    extra break points near x = 1 where the integrand is concentrated."""
    pts = {mp.mpf(k) / 8 for k in range(9)}
    if e >= 16:
        for k in (0.25, 0.5, 1, 2, 4, 8, 16, 32, 64, 128, 256):
            p = 1 - mp.mpf(k) / e
            if 0 < p < 1:
                pts.add(p)
    if e == 0:
        f = lambda x: mp.legendre(l, x)  # noqa: E731
    else:
        f = lambda x: x**e * mp.legendre(l, x)  # noqa: E731
    v, err = mp.quad(f, sorted(pts), error=True)
    assert err < mp.mpf("1e-40"), (e, l, err)
    return v


def make_zonal():
    lmax = 64
    exps = [0.0, 0.5, 1.0, 2.0, 7.3, 64.0, 1000.0, 10000.0]
    thr = mp.mpf("1e-38")
    with mp.workdps(50):
        def norm(l):
            return mp.sqrt(mp.mpf(2 * l + 1) / (4 * mp.pi))

        def exactly_zero(e, l):
            # integral_0^1 x^n P_l = 0 for integer n < l with l - n even
            return float(e).is_integer() and l > e and (l - int(e)) % 2 == 0

        cc = [2 * mp.pi * zonal_integral(mp.mpf(1), l) for l in range(lmax + 1)]
        for l, v in enumerate(cc):
            assert (abs(v) < thr) == exactly_zero(1.0, l), (l, v)
        cc = [mp.mpf(0) if abs(v) < thr else v for v in cc]
        pi = mp.pi
        for l, want in [(0, pi), (1, 2 * pi / 3), (2, pi / 4), (3, 0), (4, -pi / 24), (6, pi / 64)]:
            assert abs(cc[l] - want) < mp.mpf("1e-45"), (l, cc[l], want)
        clamped = {
            "band_multipliers": [mp_to_float(v) for v in cc],
            "zonal_coefficients": [mp_to_float(norm(l) * v) for l, v in enumerate(cc)],
        }
        phong = []
        for e in exps:
            em = mp.mpf(e)  # the exact float64 value (7.3 is 7.29999999999999982236431605997495...)
            mult = [(em + 1) * zonal_integral(em, l) for l in range(lmax + 1)]
            for l, v in enumerate(mult):
                assert (abs(v) < thr) == exactly_zero(e, l), (e, l, v)
            mult = [mp.mpf(0) if abs(v) < thr else v for v in mult]
            # closed forms: l = 0 -> 1, l = 1 -> (e+1)/(e+2), l = 2 -> (e+1)/2 (3/(e+3) - 1/(e+1))
            assert abs(mult[0] - 1) < mp.mpf("1e-45")
            assert abs(mult[1] - (em + 1) / (em + 2)) < mp.mpf("1e-45")
            assert abs(mult[2] - (em + 1) / 2 * (3 / (em + 3) - 1 / (em + 1))) < mp.mpf("1e-45")
            if e == 1.0:  # normalised cosine lobe = clamped cosine / pi
                for l in range(lmax + 1):
                    assert abs(mult[l] - cc[l] / pi) < mp.mpf("1e-45")
            phong.append({
                "e": e,
                "band_multipliers": [mp_to_float(v) for v in mult],
                "zonal_coefficients": [mp_to_float(norm(l) * v) for l, v in enumerate(mult)],
            })
    log(f"zonal: {len(exps) + 1} lobes x {lmax + 1} bands by mpmath.quad at 50 digits; closed forms "
        "A_0..A_6, Phong l = 0, 1, 2 and e = 1 <-> clamped cosine / pi agree to 1e-45; exact zeros as predicted")
    write_json("zonal.json", {
        "description": (
            "Zonal harmonics of lobes around +Z, l = 0..64 (65 numbers per list, index = l). 'band_multipliers' "
            "are the convolution factors (band l of a function is multiplied by them), 'zonal_coefficients' "
            "are g_l = integral f(w) y_l^0(w) dw, related by multiplier = sqrt(4 pi/(2l+1)) g_l. "
            "'clamped_cosine': f = max(cos theta, 0); multipliers A_l = 2 pi integral_0^1 x P_l(x) dx "
            "(A_0 = pi, A_1 = 2pi/3, A_2 = pi/4, odd l > 1 exactly 0). 'phong': for each exponent e (the "
            "float64 value as given), the normalised lobe f = (e+1)/(2 pi) max(cos theta, 0)^e; multipliers "
            "(e+1) integral_0^1 x^e P_l(x) dx (l = 0 gives 1). Computed by mpmath.quad (tanh-sinh, interval "
            "split, extra break points near x = 1 for large e) with mpmath.legendre at 50 digits, not from a "
            "closed form; values that are exactly zero (integer e < l, l - e even) are stored as 0.0. "
            + CONVENTION),
        "generator": "tools/sh_reference.py",
        "versions": VERSIONS,
        "lmax": lmax,
        "clamped_cosine": clamped,
        "phong": phong,
    })


# ---------------------------------------------------------------------------------------
# 5. projection.json
# ---------------------------------------------------------------------------------------


def rot_y(deg):
    a = math.radians(deg)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def texel_integrals(W, H, order, n, R=None):
    """T[row * W + col, i] = integral over texel (col, row) of y_i(R d) dw, d the lat-long
    direction, by n x n tensor Gauss-Legendre in (theta_map, phi_map) with weight sin(theta_map)."""
    x, w = leggauss(n)
    T = np.empty((W * H, order * order))
    for row in range(H):
        t0, t1 = math.pi * row / H, math.pi * (row + 1) / H
        th = 0.5 * (t1 - t0) * x + 0.5 * (t1 + t0)
        wt = 0.5 * (t1 - t0) * w * np.sin(th)
        pts, wts = [], []
        for col in range(W):
            p0, p1 = 2 * math.pi * col / W, 2 * math.pi * (col + 1) / W
            ph = 0.5 * (p1 - p0) * x + 0.5 * (p1 + p0)
            wp = 0.5 * (p1 - p0) * w
            TH, PH = np.meshgrid(th, ph, indexing="ij")
            d = np.stack([np.sin(PH) * np.sin(TH), np.cos(TH), -np.cos(PH) * np.sin(TH)], axis=-1).reshape(-1, 3)
            pts.append(d)
            wts.append(np.outer(wt, wp).reshape(-1))
        d = np.concatenate(pts)
        if R is not None:
            d = d @ np.asarray(R).T  # rows: R d
        Y = real_sh_np(order, d)
        wv = np.concatenate(wts)
        for col in range(W):
            s = slice(col * n * n, (col + 1) * n * n)
            T[row * W + col] = wv[s] @ Y[s]
    return T


def make_projection(rng):
    order = 20
    n_lo, n_hi = 48, 64
    maps = []
    worst_conv = 0.0
    vals8 = None
    for W, H in [(8, 4), (12, 6), (16, 8)]:
        vals = rng.uniform(0.05, 4.0, size=W * H)
        if W == 8:
            vals8 = vals
        T_lo = texel_integrals(W, H, order, n_lo)
        T_hi = texel_integrals(W, H, order, n_hi)
        f_lo, f_hi = vals @ T_lo, vals @ T_hi
        conv = float(np.max(np.abs(f_lo - f_hi)))
        worst_conv = max(worst_conv, conv)
        assert conv < 1e-13, (W, H, conv)
        # exact texel solid angles: y_0 = 1/sqrt(4 pi)
        omega = np.array([(2 * math.pi / W) * (math.cos(math.pi * r / H) - math.cos(math.pi * (r + 1) / H))
                          for r in range(H) for _ in range(W)])
        assert np.max(np.abs(T_lo[:, 0] - omega / math.sqrt(4 * math.pi))) < 1e-15
        # a constant map projects onto y_0 only
        ones = np.ones(W * H) @ T_lo
        assert abs(ones[0] - math.sqrt(4 * math.pi)) < 1e-14 and np.max(np.abs(ones[1:])) < 1e-13
        maps.append({"width": W, "height": H, "rotation_y_deg": 0.0, "values": vals.tolist(), "coeffs": f_lo.tolist()})
    # rotated 8x4 map: radiance towards d is map(R_y(30)^-1 d)  =>  f_i = sum_texels v integral y_i(R d') dw'
    R = rot_y(30.0)
    T_lo = texel_integrals(8, 4, order, n_lo, R)
    T_hi = texel_integrals(8, 4, order, n_hi, R)
    f_lo, f_hi = vals8 @ T_lo, vals8 @ T_hi
    conv = float(np.max(np.abs(f_lo - f_hi)))
    worst_conv = max(worst_conv, conv)
    assert conv < 1e-13, conv
    # consistency with the rotation definition: coeffs(rotated) = D(R_y 30) coeffs(unrotated)
    D = sh_rotation_bands(R, order)
    f0 = np.array(maps[0]["coeffs"])
    fr = np.concatenate([D[l] @ f0[l * l:(l + 1) * (l + 1)] for l in range(order)])
    rot_dev = float(np.max(np.abs(fr - f_lo)))
    assert rot_dev < 1e-12, rot_dev
    # where the content goes: the map's texel at u = 0 (towards -Z) is seen towards R_y(30) (0, 0, -1)
    # = (-1/2, 0, -sqrt(3)/2), i.e. at world u = -30/360 (wrapped: 330/360)
    dd = R @ np.array([0.0, 0.0, -1.0])
    assert abs((math.atan2(dd[0], -dd[2]) / (2 * math.pi)) % 1.0 - 330.0 / 360.0) < 1e-15
    maps.append({"width": 8, "height": 4, "rotation_y_deg": 30.0, "values": vals8.tolist(), "coeffs": f_lo.tolist()})
    log(f"projection: {n_lo}x{n_lo} vs {n_hi}x{n_hi} Gauss-Legendre per texel differ by at most {worst_conv:.1e}; "
        f"rotated map = D(R_y 30) x unrotated to {rot_dev:.1e}; texel solid angles exact")
    write_json("projection.json", {
        "description": (
            "Exact SH projection (order 20: 400 coefficients, flat index i = l(l+1)+m) of piecewise-constant "
            "latitude-longitude maps. Each map: 'width' W, 'height' H, 'values' W*H positive scalars row-major "
            "(index row*W + col, row 0 = top = +Y pole), 'rotation_y_deg', 'coeffs' f_i. Texel (col, row) covers "
            "phi_map in [2 pi col/W, 2 pi (col+1)/W), theta_map in [pi row/H, pi (row+1)/H), direction "
            "d = (sin phi_map sin theta_map, cos theta_map, -cos phi_map sin theta_map), "
            "dw = sin theta_map dtheta_map dphi_map. With rotation_y_deg = a, the radiance towards world "
            "direction w is the map's value at R_y(a)^-1 w (R_y the right-handed rotation about +Y: "
            "[[cos a, 0, sin a], [0, 1, 0], [-sin a, 0, cos a]]), so f_i = sum over texels of value * integral "
            "over the texel of y_i(R_y(a) d) dw. y_i is evaluated in the SH convention (theta from +Z, "
            "phi = atan2(y, x) of the world direction). Computed by 48x48 tensor Gauss-Legendre in "
            "(theta_map, phi_map) per texel with scipy.special.sph_harm_y in float64, converged: 64x64 differs "
            "by < 1e-13; rotated map checked against the rotation.json definition of D. " + CONVENTION),
        "generator": "tools/sh_reference.py",
        "versions": VERSIONS,
        "order": order,
        "maps": maps,
    })


def main():
    t0 = time.time()
    rng = np.random.default_rng(20240611)
    check_band1(rng)
    steps = [
        ("eval", lambda: make_eval(np.random.default_rng(1))),
        ("gaunt", lambda: make_gaunt(np.random.default_rng(2))),
        ("rotation", lambda: make_rotation(np.random.default_rng(3))),
        ("zonal", make_zonal),
        ("projection", lambda: make_projection(np.random.default_rng(5))),
    ]
    only = set(sys.argv[1:])
    for name, fn in steps:
        if only and name not in only:
            continue
        t = time.time()
        fn()
        log(f"  ({name}: {time.time() - t:.1f} s)")
    log(f"done in {time.time() - t0:.1f} s")


if __name__ == "__main__":
    main()
