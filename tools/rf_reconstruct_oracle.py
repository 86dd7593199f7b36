#!/usr/bin/env python3
"""Independent reference values ("oracle") for crates/fields/src/reconstruct.rs.

Writes crates/fields/tests/data/rf_reconstruct_oracle.json (run from the repository root):

    tools/.venv/bin/pip install numpy scipy
    tools/.venv/bin/python tools/rf_reconstruct_oracle.py            # regenerate the JSON (~1 s)
    tools/.venv/bin/python tools/rf_reconstruct_oracle.py --check    # recompute and compare

Written from the papers' formulas, not from the Rust code (nothing of it is read or imported):
Masselus, Peers, Dutre & Willems, EGSR 2004, section 4 (IDW, biquadric polynomial, spherical
harmonics, multilevel B-splines) and Lee, Wolberg & Shin, IEEE TVCG 1997 (the BA rule and the
multilevel hierarchy), with the lat-long mapping and SH basis of CONVENTIONS.md.

Grids: cell (col, row) of a w x h lat-long grid is centred at phi = 2 pi (col + 1/2)/w,
theta = pi (row + 1/2)/h, d = (sin phi sin theta, cos theta, -cos phi sin theta), index
row*w + col; its solid angle is (2 pi/w)(cos(pi row/h) - cos(pi (row+1)/h)).

Methods (each maps the samples R_j at the coarse centres to values at the fine centres):
* idw(n, p): angles a_j between the fine centre and the samples (arctan2(|d x d_j|, d . d_j));
  if min a_j <= 1e-9 the centre takes that sample; otherwise the neighbours are the samples with
  a_j <= a_(n) (1 + 1e-9), a_(n) the n-th smallest angle (the n nearest plus any tied with the
  n-th), weighted a_j^-p and normalised. Nearest candidates come from scipy.spatial.cKDTree on
  the unit vectors (chord distance is monotone in the angle).
* biquadric: per hemisphere (coarse rows with theta < pi/2, and the rest; H even) a weighted
  least-squares fit (numpy.linalg.lstsq on sqrt(solid angle)-scaled rows) of
  a0 + a1 u + a2 v + a3 u^2 + a4 u v + a5 v^2, (u, v) = (d.x, d.z); fine centres with
  theta < pi/2 take the upper fit, theta > pi/2 the lower, theta = pi/2 (odd FH) the mean.
* sh(order): weighted least squares (lstsq) with the real orthonormal SH of CONVENTIONS.md
  (Condon-Shortley phase; theta from +Z, phi = atan2(y, x); index l(l+1)+m), built here from
  scipy.special.lpmv and factorials and checked against scipy.special.sph_harm_y
  (y_l^m = sqrt2 Re Y_l^m, y_l^-m = sqrt2 Im Y_l^m for m > 0) and against CONVENTIONS' check
  values.
* bspline(levels): multilevel B-spline approximation on (s, t) = (phi/2pi, theta/pi): level k
  has a (4*2^k) x (2*2^k)-cell uniform cubic B-spline lattice, periodic in s (m columns),
  extended in t (n + 3 rows of control points, row r at t-position r - 1 in cell units);
  f(x, y) = sum_{k,l} B_k(x - floor x) B_l(y - floor y) phi[floor(y) + l, (floor(x) - 1 + k) mod m]
  with x = s m, y = t n. Level k fits the residual r^k (r^0 = R, r^{k+1} = r^k - f_k at the
  samples) by Lee et al.'s BA rule: phi_c = w_ab r_c / sum w^2 per sample, each control point the
  w^2-weighted mean of its proposals (0 without samples). The result is sum_k f_k evaluated at
  the fine centres level by level (no lattice refinement, unlike the Rust code: an independent
  route to the same function). Default levels: the fewest whose last lattice has at least W x H
  cells. The B-spline evaluation is checked against scipy.interpolate.BSpline.design_matrix.

For the tests' tolerances each least-squares result carries "condition": the 2-norm condition
number of its sqrt(weight)-scaled design matrix (largest over the two hemispheres).
"""

import argparse
import json
import math
import sys

import numpy as np
from scipy.interpolate import BSpline
from scipy.spatial import cKDTree
from scipy.special import lpmv, sph_harm_y

SEED = 20040621
OUT = "crates/fields/tests/data/rf_reconstruct_oracle.json"
COMMAND = "tools/.venv/bin/python tools/rf_reconstruct_oracle.py"


# --------------------------------------------------------------------------------------------
# Grids
# --------------------------------------------------------------------------------------------

def grid(w, h):
    """(directions (w*h, 3), phi, theta, row) of the cell centres, index row*w + col."""
    row, col = np.divmod(np.arange(w * h), w)
    phi = 2 * np.pi * (col + 0.5) / w
    theta = np.pi * (row + 0.5) / h
    d = np.stack([np.sin(phi) * np.sin(theta), np.cos(theta), -np.cos(phi) * np.sin(theta)], 1)
    return d, phi, theta, row


def solid_angles(w, h):
    row = np.arange(w * h) // w
    return 2 * np.pi / w * (np.cos(np.pi * row / h) - np.cos(np.pi * (row + 1) / h))


def angles(a, b):
    """Angles between the unit rows of a and the unit vector b."""
    return np.arctan2(np.linalg.norm(np.cross(a, b), axis=-1), a @ b)


# --------------------------------------------------------------------------------------------
# Methods
# --------------------------------------------------------------------------------------------

def idw(coarse, fine, samples, n, p):
    cd = grid(*coarse)[0]
    fd = grid(*fine)[0]
    tree = cKDTree(cd)
    total = len(cd)
    out = np.empty(len(fd))
    for k, f in enumerate(fd):
        kq = min(total, n + 8)
        while True:
            _, idx = tree.query(f, k=kq)
            idx = np.atleast_1d(idx)
            a = angles(cd[idx], f)
            order = np.argsort(a, kind="stable")
            idx, a = idx[order], a[order]
            # Enough candidates when the last one is beyond the tie band of the n-th.
            if kq == total or a[-1] > a[n - 1] * (1 + 1e-9):
                break
            kq = min(total, kq * 2)
        if a[0] <= 1e-9:
            out[k] = samples[idx[0]]
            continue
        keep = a <= a[n - 1] * (1 + 1e-9)
        w = a[keep] ** (-p)
        out[k] = np.sum(w * samples[idx[keep]]) / np.sum(w)
    return out


def weighted_lstsq(design, b, weights):
    sw = np.sqrt(weights)
    a = design * sw[:, None]
    coef = np.linalg.lstsq(a, b * sw, rcond=None)[0]
    return coef, np.linalg.cond(a)


def biquadric(coarse, fine, samples):
    w, h = coarse
    assert h % 2 == 0
    cd, _, _, crow = grid(w, h)
    wt = solid_angles(w, h)
    mono = lambda d: np.stack([np.ones(len(d)), d[:, 0], d[:, 2], d[:, 0] ** 2, d[:, 0] * d[:, 2], d[:, 2] ** 2], 1)
    fd, _, _, frow = grid(*fine)
    fits, cond = [], 0.0
    for upper in (True, False):
        sel = crow < h // 2 if upper else crow >= h // 2
        coef, c = weighted_lstsq(mono(cd[sel]), samples[sel].astype(np.float64), wt[sel])
        fits.append(mono(fd) @ coef)
        cond = max(cond, c)
    twice = 2 * frow + 1
    out = np.where(twice < fine[1], fits[0], np.where(twice > fine[1], fits[1], 0.5 * (fits[0] + fits[1])))
    return out, cond


def real_sh(order, d):
    """(len(d), order^2) real SH of CONVENTIONS.md."""
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    ct = np.clip(z, -1.0, 1.0)
    ph = np.arctan2(y, x)
    out = np.empty((len(d), order * order))
    for l in range(order):
        for m in range(-l, l + 1):
            am = abs(m)
            k = math.sqrt((2 * l + 1) / (4 * math.pi) * math.factorial(l - am) / math.factorial(l + am))
            p = lpmv(am, l, ct)  # includes the Condon-Shortley phase (-1)^m
            if m > 0:
                v = math.sqrt(2) * k * np.cos(m * ph) * p
            elif m < 0:
                v = math.sqrt(2) * k * np.sin(am * ph) * p
            else:
                v = k * p
            out[:, l * (l + 1) + m] = v
    return out


def check_real_sh():
    rng = np.random.default_rng(1)
    d = rng.normal(size=(50, 3))
    d /= np.linalg.norm(d, axis=1)[:, None]
    ours = real_sh(6, d)
    theta = np.arccos(np.clip(d[:, 2], -1, 1))
    phi = np.arctan2(d[:, 1], d[:, 0])
    for l in range(6):
        for m in range(-l, l + 1):
            ref = sph_harm_y(l, abs(m), theta, phi)
            ref = ref.real if m == 0 else math.sqrt(2) * (ref.real if m > 0 else ref.imag)
            assert np.max(np.abs(ours[:, l * (l + 1) + m] - ref)) < 1e-13, (l, m)
    c = math.sqrt(3 / (4 * math.pi))
    assert np.allclose(ours[:, 1], -c * d[:, 1], atol=1e-14)
    assert np.allclose(ours[:, 2], c * d[:, 2], atol=1e-14)
    assert np.allclose(ours[:, 3], -c * d[:, 0], atol=1e-14)


def sh_fit(coarse, fine, samples, order):
    cd = grid(*coarse)[0]
    coef, cond = weighted_lstsq(real_sh(order, cd), samples.astype(np.float64), solid_angles(*coarse))
    return real_sh(order, grid(*fine)[0]) @ coef, cond


def cubic_weights(u):
    """Uniform cubic B-spline weights B_0..B_3 at u in [0, 1], shape (len(u), 4)."""
    return np.stack([(1 - u) ** 3, 3 * u ** 3 - 6 * u ** 2 + 4, -3 * u ** 3 + 3 * u ** 2 + 3 * u + 1, u ** 3], 1) / 6


def lattice_terms(m, n, s, t):
    """For points (s, t): rows (P, 4) and cols (P, 4) of the control points, and weights (P, 4, 4)
    indexed [l, k] (row offset l, column offset k)."""
    x, y = s * m, t * n
    xi, yi = np.floor(x), np.floor(y)
    yi = np.minimum(yi, n - 1)
    wx, wy = cubic_weights(x - xi), cubic_weights(y - yi)
    cols = (xi[:, None].astype(int) - 1 + np.arange(4)[None, :]) % m
    rows = yi[:, None].astype(int) + np.arange(4)[None, :]
    return rows, cols, wy[:, :, None] * wx[:, None, :]


def evaluate(phi, m, n, s, t):
    rows, cols, w = lattice_terms(m, n, s, t)
    vals = phi[rows[:, :, None], cols[:, None, :]]
    return np.sum(w * vals, axis=(1, 2))


def evaluate_scipy(phi, m, n, s, t):
    """The same tensor-product spline through scipy's B-spline design matrices: coefficient p
    (p = -1..m+1 in s, -1..n+1 in t) is the centred cubic B-spline at lattice position p, i.e.
    knots p-2..p+2; s columns folded mod m (periodic)."""
    ks = np.arange(-3, m + 4, dtype=float)
    kt = np.arange(-3, n + 4, dtype=float)
    ds = BSpline.design_matrix(s * m, ks, 3).toarray()  # (P, m+3), column c <-> p = c - 1
    dt = BSpline.design_matrix(t * n, kt, 3).toarray()  # (P, n+3), column r <-> storage row r
    fold = np.zeros((m + 3, m))
    for c in range(m + 3):
        fold[c, (c - 1) % m] = 1.0
    ds = ds @ fold
    return np.einsum("pr,rc,pc->p", dt, phi, ds)


def ba(m, n, s, t, z):
    rows, cols, w = lattice_terms(m, n, s, t)
    w2 = w * w
    phi_c = w * (z / np.sum(w2, axis=(1, 2)))[:, None, None]
    delta = np.zeros((n + 3, m))
    omega = np.zeros((n + 3, m))
    rr = np.broadcast_to(rows[:, :, None], w.shape)
    cc = np.broadcast_to(cols[:, None, :], w.shape)
    np.add.at(delta, (rr, cc), w2 * phi_c)
    np.add.at(omega, (rr, cc), w2)
    out = np.zeros_like(delta)
    nz = omega > 0
    out[nz] = delta[nz] / omega[nz]
    return out


def default_levels(coarse):
    levels = 1
    while 4 * 2 ** (levels - 1) < coarse[0] or 2 * 2 ** (levels - 1) < coarse[1]:
        levels += 1
    return levels


def bspline(coarse, fine, samples, levels):
    w, h = coarse
    row, col = np.divmod(np.arange(w * h), w)
    s, t = (col + 0.5) / w, (row + 0.5) / h
    fw, fh = fine
    frow, fcol = np.divmod(np.arange(fw * fh), fw)
    fs, ft = (fcol + 0.5) / fw, (frow + 0.5) / fh
    residual = samples.astype(np.float64)
    out = np.zeros(fw * fh)
    for k in range(levels):
        m, n = 4 * 2 ** k, 2 * 2 ** k
        phi = ba(m, n, s, t, residual)
        if k == 0:  # the evaluation against scipy's B-splines, once per call
            assert np.max(np.abs(evaluate(phi, m, n, fs, ft) - evaluate_scipy(phi, m, n, fs, ft))) < 1e-13
        residual = residual - evaluate(phi, m, n, s, t)
        out += evaluate(phi, m, n, fs, ft)
    return out


# --------------------------------------------------------------------------------------------
# Cases
# --------------------------------------------------------------------------------------------

def sample_sets(coarse, names):
    rng = np.random.default_rng(SEED + coarse[0] * 100 + coarse[1])
    d = grid(*coarse)[0]
    a = np.array([0.3, 0.8, -0.5])
    a /= np.linalg.norm(a)
    sets = {
        "random": rng.random(len(d)),
        # A glossy lobe over a dim floor with a shadow edge.
        "lobe": 0.1 + np.maximum(0.0, d @ a) ** 8 + 0.3 * (d[:, 0] > 0.2),
        "impulse": np.eye(len(d))[len(d) // 3 + 1],
    }
    return {k: sets[k].astype(np.float32) for k in names}


CASES = [
    # (coarse, fine, sets, [(method, params, sets it runs on or None for all)])
    ([16, 8], [32, 16], ["random", "lobe", "impulse"], [
        ("idw", {"neighbours": 32, "power": 1.0}, None),
        ("idw", {"neighbours": 6, "power": 2.0}, ["random"]),
        ("biquadric", {}, None),
        ("sh", {"order": 5}, None),
        ("sh", {"order": 3}, ["random"]),
        ("bspline", {"levels": None}, None),
        ("bspline", {"levels": 1}, ["random"]),
        # A lattice finer than the samples: samples on knot lines (zero weights, empty supports).
        ("bspline", {"levels": 4}, ["random"]),
    ]),
    # Fine 3x the coarse: every sample's centre is a fine centre (IDW's coincidence rule).
    ([12, 6], [36, 18], ["random", "lobe"], [
        ("idw", {"neighbours": 32, "power": 1.0}, None),
        ("biquadric", {}, None),
        ("sh", {"order": 5}, None),
        ("bspline", {"levels": None}, None),
    ]),
    # Odd fine height (a fine row on the equator), a non-power-of-two lattice ratio.
    ([10, 4], [20, 9], ["random"], [
        ("idw", {"neighbours": 8, "power": 1.0}, None),
        ("biquadric", {}, None),
        ("sh", {"order": 3}, None),
        ("bspline", {"levels": None}, None),
    ]),
]


def run(coarse, fine, method, params, samples):
    if method == "idw":
        return idw(coarse, fine, samples, params["neighbours"], params["power"]), None
    if method == "biquadric":
        return biquadric(coarse, fine, samples)
    if method == "sh":
        return sh_fit(coarse, fine, samples, params["order"])
    if method == "bspline":
        return bspline(coarse, fine, samples, params["levels"]), None
    raise ValueError(method)


def build():
    check_real_sh()
    cases = []
    for coarse, fine, set_names, methods in CASES:
        sets = sample_sets(coarse, set_names)
        results = []
        for method, params, only in methods:
            params = dict(params)
            if method == "bspline" and params["levels"] is None:
                params["levels"] = default_levels(coarse)
            for name in only or set_names:
                values, cond = run(coarse, fine, method, params, sets[name])
                r = {"method": method, "params": params, "set": name, "values": values.tolist()}
                if cond is not None:
                    r["condition"] = float(cond)
                results.append(r)
        cases.append({
            "coarse": coarse,
            "fine": fine,
            "samples": {k: v.astype(np.float64).tolist() for k, v in sets.items()},
            "results": results,
        })
    return {
        "generator": COMMAND,
        "description": "Fine-grid values of the four reconstructions of rf_reconstruct.rs, "
                       "computed independently (see the script's docstring).",
        "cases": cases,
    }


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true", help="recompute and compare with " + OUT)
    args = ap.parse_args()
    data = build()
    if args.check:
        with open(OUT) as f:
            old = json.load(f)
        worst = 0.0
        for a, b in zip(old["cases"], data["cases"]):
            assert a["coarse"] == b["coarse"] and a["fine"] == b["fine"]
            assert a["samples"] == b["samples"], "samples differ"
            for ra, rb in zip(a["results"], b["results"]):
                assert (ra["method"], ra["params"], ra["set"]) == (rb["method"], rb["params"], rb["set"])
                va, vb = np.array(ra["values"]), np.array(rb["values"])
                scale = max(1.0, np.max(np.abs(vb)))
                worst = max(worst, np.max(np.abs(va - vb)) / scale)
        ok = len(old["cases"]) == len(data["cases"]) and worst <= 1e-12
        print(f"{'OK' if ok else 'MISMATCH'}: largest relative difference {worst:.3e}")
        sys.exit(0 if ok else 1)
    text = json.dumps(data, separators=(",", ":"))
    with open(OUT, "w") as f:
        f.write(text + "\n")
    print(f"wrote {OUT} ({len(text) / 1024:.0f} KB)")


if __name__ == "__main__":
    main()
