#!/usr/bin/env python3
"""Independent reference values ("oracle") for the glTF 2.0 metallic-roughness BRDF.

Writes crates/shading/tests/data/pbr_oracle.json (run from the repository root):

    python3 tools/pbr_oracle.py              # regenerate the JSON (~60 s, including verification)
    python3 tools/pbr_oracle.py --check      # recompute (~20 s) and compare with the committed JSON
    python3 tools/pbr_oracle.py --no-verify  # regenerate without the verification runs

Needs only the Python standard library and numpy. Deterministic (numpy seed SEED).

What it computes
----------------
* "eval" (300 cases): f(wo, wi) RGB, not multiplied by cos, for random materials (base colour in
  [0,1]^3, metallic in {0, 1, uniform}, roughness in {0.05, 0.1, 0.3, 0.5, 0.8, 1, uniform in
  [0.02, 1]}) and directions: 150 random, 50 grazing (n.w in [1e-3, 0.1]), 78 near-specular
  (wi = reflect(wo) rotated by k alpha, k in {0, 0.01, 0.1, 0.3, 1, 3}), 12 special, 10 below the
  horizon (f = 0).
* "pdf" (100 cases): the GGX visible-normal (VNDF) sampling pdf of the reflected direction.
* "albedo" (64 cases): R(wo) = integral over the upper hemisphere of f(wo, wi) (n.wi) d omega_i.
* "meta": formulas, command line, numpy version, notes on ambiguities, verification results.

Definitions
-----------
The glTF 2.0 specification, Appendix B (sections "Specular BRDF", "Diffuse BRDF", "Fresnel",
"Metal BRDF and Dielectric BRDF"), with the project's one-sided convention (f = 0 when n.wi <= 0 or
n.wo <= 0); the formulas are spelled out in FORMULAS below and in meta.formulas. The spec's
visibility term is the height-correlated Smith one; CONVENTIONS.md's line writes the separable one; the
spec's is used for "f"/"albedo", the separable one is also given as "f_separable_smith" /
"albedo_separable_smith" (see NOTES). The pdf is that of Heitz (2018), "Sampling the GGX
Distribution of Visible Normals", JCGT 7(4): h has density D_wo(h) = G1(wo) max(0, wo.h) D(h) / n.wo,
wi = reflect(wo, h) = 2 (wo.h) h - wo has d omega_i = 4 |wo.h| d omega_h, hence
pdf(wi) = G1(wo) D(h) / (4 n.wo) with Smith G1(w) = 2 n.w / (n.w + sqrt(alpha^2 + (1 - alpha^2)(n.w)^2)).

How accuracy was checked
------------------------
* eval/pdf are evaluated in 50-digit decimal arithmetic from the exact f64 inputs and rounded to f64;
  an independent float64 numpy implementation (the one the quadratures use) agrees to 3.4e-10
  relative (f) and 2.3e-11 (pdf); the residual is the f64 cancellation in (n.h)^2 (alpha^2 - 1) + 1
  at tiny alpha, not an error of the reference.
* albedo: quadrature in half-vector space (see meta.albedo_quadrature): the horizon n.wi = 0 is the
  coordinate line theta_h = theta_cut(phi), so the integrand is smooth on a rectangle; periodic
  trapezoid in phi, composite Gauss-Legendre on geometric panels (first panel alpha/4) in theta_h.
  Three levels with doubled nodes and refined panels: max |level1 - level0| = 1.5e-7 and
  max |level2 - level1| = 9.0e-11 (roughness 0.1, theta_o 80 deg; <= 1e-13 for roughness >= 0.3);
  abs_error_bound = max(|level2 - level1|, 1e-12) per case. Cross-checks: closed form for roughness 1,
  metallic 1, white (R = 1 - c ln(1 + 1/c), c = cos theta_o; separable: 2 (1 - ln 2)/(1 + c)) to
  2.3e-15; an independent (theta_i, phi_i) product quadrature for roughness >= 0.3 to 1.4e-8;
  Monte Carlo (VNDF/cosine mixture, 4e5 samples per case) within 2.1 standard errors; the same panels
  integrate D(h)(n.h) to 1 within 1.8e-10.
* pdf / sampler: the VNDF sampler written from the paper (sample_vndf) was run (2e6 samples each) for
  roughness {0.05, 0.1, 0.3, 0.6, 1} x theta_o {0, 45, 80, 89} deg; chi^2 of the histogram of wi
  against the pdf integrated over the bins (bins tiling the upper hemisphere via half-vector
  coordinates, plus one bin for "below the horizon"; and, for roughness >= 0.3, theta_o <= 80,
  equal-solid-angle bins in wi) gives p-values >= 0.03 over 29 tests; the integral of the pdf over
  the upper hemisphere matches 1 - (fraction of samples below the horizon) within 2.7 standard
  errors (the largest, 2.7 at roughness 0.05, theta_o 45 deg, came down to 0.8 in a one-off run
  with 4e7 samples, not part of this script). Also checked: Smith normalisation
  integral (wo.h)+ D(h) d omega_h = n.wo / G1(wo) to 2.8e-12 relative, and the reflection Jacobian
  4 |wo.h| by finite differences to 2.2e-10.
"""

import argparse
import json
import math
import os
import platform
import sys
import time
from decimal import Decimal, localcontext

import numpy as np

SEED = 20250217
OUT_REL = os.path.join("crates", "shading", "tests", "data", "pbr_oracle.json")
REPO_ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
COMMAND = "python3 tools/pbr_oracle.py"

DPREC = 50  # decimal digits of the reference evaluation of "eval" and "pdf"
PI_STR = "3.14159265358979323846264338327950288419716939937510582097494459"
ROUGHNESS_CHOICES = [0.05, 0.1, 0.3, 0.5, 0.8, 1.0, None]  # None: uniform in [0.02, 1]

# Albedo quadrature levels: (phi nodes, Gauss-Legendre nodes per panel, panel ratio).
ALBEDO_LEVELS = [(128, 16, 2.0), (256, 32, 2.0 ** 0.5), (512, 48, 2.0 ** (1.0 / 3.0))]
ALBEDO_BOUND_FLOOR = 1e-12

FORMULAS = """\
Local frame: n = +Z; wo (view) and wi (light) unit, pointing away from the surface.
alpha = roughness^2. h = normalize(wi + wo). s = (1 - |wo.h|)^5 (= (1 - |wi.h|)^5, wo.h = wi.h).
f = 0 if n.wi <= 0 or n.wo <= 0 (one-sided reflection; the spec's chi+(n.h) chi+(h.wi) chi+(h.wo) are then all 1).
D = alpha^2 / (pi ((n.h)^2 (alpha^2 - 1) + 1)^2)                                   [glTF 2.0 App. B, Specular BRDF]
V (field f, glTF spec, height-correlated Smith):
  V = 1 / (2 (|n.wo| sqrt(alpha^2 + (1 - alpha^2)(n.wi)^2) + |n.wi| sqrt(alpha^2 + (1 - alpha^2)(n.wo)^2)))
V (field f_separable_smith, the CONVENTIONS.md line's formula = separable Smith G1(wi) G1(wo) / (4 |n.wi| |n.wo|)):
  V = 1 / ((|n.wi| + sqrt(alpha^2 + (1 - alpha^2)(n.wi)^2)) (|n.wo| + sqrt(alpha^2 + (1 - alpha^2)(n.wo)^2)))
spec = D V
dielectric = (1 - F_d) base_color / pi + F_d spec,  F_d = 0.04 + 0.96 s                 [fresnel_mix, ior 1.5]
metal = spec (base_color + (1 - base_color) s)                                          [conductor_fresnel]
f = (1 - metallic) dielectric + metallic metal   (RGB, not multiplied by n.wi)
VNDF pdf of the reflected direction (Heitz 2018): G1(w) = 2 (n.w) / ((n.w) + sqrt(alpha^2 + (1 - alpha^2)(n.w)^2)),
  pdf(wi) = G1(wo) max(0, wo.h) D(h) / (n.wo) / (4 wo.h) = G1(wo) D(h) / (4 n.wo) = D(h) / (2 (n.wo + sqrt(alpha^2 + (1 - alpha^2)(n.wo)^2)))
  for n.wi > 0 (and n.wo > 0); pdf = 0 when n.wi <= 0.
Albedo: R(wo) = integral over n.wi > 0 of f(wo, wi) (n.wi) d omega_i, wo = (sin theta_o, 0, cos theta_o).
"""

NOTES = [
    "Visibility: the CONVENTIONS.md line's V = 1/((|n.wi| + sqrt(..wi)) (|n.wo| + sqrt(..wo))) is the separable "
    "(uncorrelated) Smith term G1(wi) G1(wo) / (4 |n.wi| |n.wo|); glTF 2.0 Appendix B specifies the "
    "height-correlated V = 1/(2 (|n.wo| sqrt(..wi) + |n.wi| sqrt(..wo))). The two agree only when n.wi = 1 "
    "or n.wo = 1. Following 'the glTF spec wins', eval.f / albedo.albedo use the spec; CONVENTIONS.md's form is "
    "given as f_separable_smith / albedo_separable_smith.",
    "Absolute values vs clamping: the spec writes |N.L|, |N.V|, |V.H| with Heaviside factors chi+(N.H), "
    "chi+(H.L), chi+(H.V) and does not itself say the BRDF is zero below the horizon (taken literally, "
    "abs() would give non-zero values for some wi below the horizon). The data follow the project's "
    "one-sided convention f = 0 when n.wi <= 0 or n.wo <= 0; for both directions above the horizon "
    "abs/clamp/Heaviside are all no-ops (h = normalize(wi + wo) then has n.h > 0 and wo.h = wi.h > 0).",
    "Fresnel argument: the spec uses (1 - |V.H|)^5 with V = view = wo; for the reflection half vector "
    "wo.h = wi.h exactly, so wo.h vs wi.h does not matter.",
    "Dielectric f0: the spec's ((1 - ior)/(1 + ior))^2 with ior = 1.5 is exactly 0.04.",
    "Energy: fresnel_mix is not energy conserving (the spec says so); the white dielectric's albedo exceeds "
    "1 at grazing view (see the albedo section), so a test must not assert albedo <= 1 for metallic < 1.",
    "pdf below the horizon: the VNDF sampler does produce reflected directions with n.wi <= 0 (probability "
    "1 - integral of pdf over the upper hemisphere: 50% for roughness 1 at normal incidence); the pdf is "
    "reported as 0 there and such samples must count as zero-valued, not be renormalised.",
    "Numerics: near the specular peak with small roughness the literal (n.h)^2 (alpha^2 - 1) + 1 cancels; "
    "in f64 a literal implementation is off by up to ~3e-10 relative (meta.verification), in f32 by up to "
    "~20% at roughness 0.02 and ~6% at roughness 0.05 (near_specular/special cases). For unit h the "
    "identity (n.h)^2 (alpha^2 - 1) + 1 = alpha^2 h_z^2 + h_x^2 + h_y^2 avoids the cancellation.",
]


# ----------------------------------------------------------------------------------------------
# Reference evaluation in 50-digit decimal arithmetic (inputs are the exact f64 values).
# ----------------------------------------------------------------------------------------------

def _dvec(v):
    return [Decimal(float(x)) for x in v]


def _ddot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


def brdf_dec(base_color, metallic, roughness, wo, wi):
    """Returns {"correlated": [fr, fg, fb], "separable": [...]} as Decimals."""
    with localcontext() as ctx:
        ctx.prec = DPREC
        zero = {"correlated": [Decimal(0)] * 3, "separable": [Decimal(0)] * 3}
        wo = _dvec(wo)
        wi = _dvec(wi)
        nwo, nwi = wo[2], wi[2]
        if nwo <= 0 or nwi <= 0:
            return zero
        pi = Decimal(PI_STR)
        r = Decimal(float(roughness))
        a = r * r
        a2 = a * a
        hs = [wo[k] + wi[k] for k in range(3)]
        hl = _ddot(hs, hs).sqrt()
        h = [x / hl for x in hs]
        nh = h[2]
        woh = _ddot(wo, h)
        wih = _ddot(wi, h)
        if not (nh > 0 and woh > 0 and wih > 0):  # spec's Heaviside factors; never hit above
            return zero
        t = nh * nh * (a2 - 1) + 1
        d = a2 / (pi * t * t)
        lam_i = (a2 + (1 - a2) * nwi * nwi).sqrt()
        lam_o = (a2 + (1 - a2) * nwo * nwo).sqrt()
        vis = {
            "correlated": 1 / (2 * (abs(nwo) * lam_i + abs(nwi) * lam_o)),
            "separable": 1 / ((abs(nwi) + lam_i) * (abs(nwo) + lam_o)),
        }
        s = (1 - abs(woh)) ** 5
        fd = Decimal("0.04") + Decimal("0.96") * s
        m = Decimal(float(metallic))
        out = {}
        for name, v in vis.items():
            spec = d * v
            f = []
            for c in range(3):
                b = Decimal(float(base_color[c]))
                diel = (1 - fd) * b / pi + fd * spec
                metal = spec * (b + (1 - b) * s)
                f.append((1 - m) * diel + m * metal)
            out[name] = f
        return out


def pdf_dec(roughness, wo, wi):
    with localcontext() as ctx:
        ctx.prec = DPREC
        wo = _dvec(wo)
        wi = _dvec(wi)
        nwo, nwi = wo[2], wi[2]
        if nwo <= 0 or nwi <= 0:
            return Decimal(0)
        pi = Decimal(PI_STR)
        r = Decimal(float(roughness))
        a2 = (r * r) ** 2
        hs = [wo[k] + wi[k] for k in range(3)]
        hl = _ddot(hs, hs).sqrt()
        h = [x / hl for x in hs]
        nh = h[2]
        t = nh * nh * (a2 - 1) + 1
        d = a2 / (pi * t * t)
        g1 = 2 * nwo / (nwo + (a2 + (1 - a2) * nwo * nwo).sqrt())
        return g1 * d / (4 * nwo)


def _perturbed_inputs(wo, wi, roughness, eps):
    """Yields (wo', wi', roughness') pairs (+eps, -eps) for each scalar input, in Decimal."""
    with localcontext() as ctx:
        ctx.prec = DPREC
        wo = _dvec(wo)
        wi = _dvec(wi)
        r = Decimal(float(roughness))
        for which in (0, 1):
            for k in range(3):
                pair = []
                for sgn in (1, -1):
                    v = list(wo if which == 0 else wi)
                    v[k] += sgn * eps
                    ln = _ddot(v, v).sqrt()
                    v = [x / ln for x in v]
                    pair.append((v, wi, r) if which == 0 else (wo, v, r))
                yield pair
        yield [(wo, wi, r * (1 + eps)), (wo, wi, r * (1 - eps))]


def rel_sensitivity(fun, wo, wi, roughness):
    """max over inputs of |d f / d x| / max|f|: x = a direction component (vector renormalised)
    or log(roughness). Central differences in 50-digit arithmetic (linear regime)."""
    eps = Decimal("1e-15")
    base = fun(_dvec(wo), _dvec(wi), Decimal(float(roughness)))
    scale = max(abs(x) for x in base)
    if scale == 0:
        return 0.0
    worst = Decimal(0)
    with localcontext() as ctx:
        ctx.prec = DPREC
        for (a, b) in _perturbed_inputs(wo, wi, roughness, eps):
            fa = fun(*a)
            fb = fun(*b)
            for x, y in zip(fa, fb):
                worst = max(worst, abs(x - y) / (2 * eps) / scale)
    return float(worst)


def _brdf_dec_exact(base_color, metallic):
    """f as a function of Decimal (wo, wi, roughness) without rounding the inputs to f64."""
    def fun(wo, wi, r):
        with localcontext() as ctx:
            ctx.prec = DPREC
            nwo, nwi = wo[2], wi[2]
            if nwo <= 0 or nwi <= 0:
                return [Decimal(0)] * 3
            pi = Decimal(PI_STR)
            a2 = (r * r) ** 2
            hs = [wo[k] + wi[k] for k in range(3)]
            hl = _ddot(hs, hs).sqrt()
            h = [x / hl for x in hs]
            t = h[2] * h[2] * (a2 - 1) + 1
            d = a2 / (pi * t * t)
            lam_i = (a2 + (1 - a2) * nwi * nwi).sqrt()
            lam_o = (a2 + (1 - a2) * nwo * nwo).sqrt()
            spec = d / (2 * (nwo * lam_i + nwi * lam_o))
            s = (1 - abs(_ddot(wo, h))) ** 5
            fd = Decimal("0.04") + Decimal("0.96") * s
            m = Decimal(float(metallic))
            out = []
            for c in range(3):
                bc = Decimal(float(base_color[c]))
                out.append((1 - m) * ((1 - fd) * bc / pi + fd * spec)
                           + m * spec * (bc + (1 - bc) * s))
            return out
    return fun


def _pdf_dec_exact(wo, wi, r):
    with localcontext() as ctx:
        ctx.prec = DPREC
        nwo, nwi = wo[2], wi[2]
        if nwo <= 0 or nwi <= 0:
            return [Decimal(0)]
        pi = Decimal(PI_STR)
        a2 = (r * r) ** 2
        hs = [wo[k] + wi[k] for k in range(3)]
        hl = _ddot(hs, hs).sqrt()
        nh = hs[2] / hl
        t = nh * nh * (a2 - 1) + 1
        d = a2 / (pi * t * t)
        return [d / (2 * (nwo + (a2 + (1 - a2) * nwo * nwo).sqrt()))]


# ----------------------------------------------------------------------------------------------
# Vectorised float64 evaluation (used by the quadratures and the Monte Carlo checks).
# ----------------------------------------------------------------------------------------------

def brdf_np(base_color, metallic, roughness, wo, wi, smith="correlated"):
    wo = np.asarray(wo, dtype=np.float64)
    wi = np.asarray(wi, dtype=np.float64)
    bc = np.asarray(base_color, dtype=np.float64)
    a2 = float(roughness) ** 4
    with np.errstate(invalid="ignore", divide="ignore"):
        hs = wo + wi
        h = hs / np.linalg.norm(hs, axis=-1, keepdims=True)
        nwo = wo[..., 2]
        nwi = wi[..., 2]
        nh = h[..., 2]
        woh = np.sum(wo * h, axis=-1)
        t = nh * nh * (a2 - 1.0) + 1.0
        d = a2 / (math.pi * t * t)
        lam_i = np.sqrt(a2 + (1.0 - a2) * nwi * nwi)
        lam_o = np.sqrt(a2 + (1.0 - a2) * nwo * nwo)
        if smith == "correlated":
            vis = 1.0 / (2.0 * (np.abs(nwo) * lam_i + np.abs(nwi) * lam_o))
        else:
            vis = 1.0 / ((np.abs(nwi) + lam_i) * (np.abs(nwo) + lam_o))
        spec = d * vis
        s = (1.0 - np.abs(woh)) ** 5
        fd = 0.04 + 0.96 * s
        diel = (1.0 - fd)[..., None] * bc / math.pi + (fd * spec)[..., None]
        metal = spec[..., None] * (bc + (1.0 - bc) * s[..., None])
        f = (1.0 - metallic) * diel + metallic * metal
        valid = (nwo > 0) & (nwi > 0) & (nh > 0) & (woh > 0)
    return np.where(valid[..., None], f, 0.0)


def ggx_d_np(alpha, nh):
    a2 = alpha * alpha
    t = nh * nh * (a2 - 1.0) + 1.0
    return np.where(nh > 0, a2 / (math.pi * t * t), 0.0)


def smith_g1_np(alpha, nw):
    a2 = alpha * alpha
    return 2.0 * nw / (nw + np.sqrt(a2 + (1.0 - a2) * nw * nw))


def pdf_np(roughness, wo, wi, clamp_horizon=True):
    """VNDF reflected-direction pdf; with clamp_horizon=False the density of the sampler's
    output over the whole sphere (directions below the horizon included)."""
    alpha = float(roughness) ** 2
    wo = np.asarray(wo, dtype=np.float64)
    wi = np.asarray(wi, dtype=np.float64)
    with np.errstate(invalid="ignore", divide="ignore"):
        hs = wo + wi
        h = hs / np.linalg.norm(hs, axis=-1, keepdims=True)
        nwo = wo[..., 2]
        p = smith_g1_np(alpha, nwo) * ggx_d_np(alpha, h[..., 2]) / (4.0 * nwo)
        ok = nwo > 0
        if clamp_horizon:
            ok = ok & (wi[..., 2] > 0)
        return np.where(ok & np.isfinite(p), p, 0.0)


def sample_vndf(wo, alpha, u1, u2):
    """Heitz 2018, "Sampling the GGX Distribution of Visible Normals" (JCGT 7(4)), isotropic
    alpha: stretch the view vector, sample the projected hemisphere (disk, warped for the
    visible half), unstretch. Returns (h, wi = reflect(wo, h))."""
    vh = np.array([alpha * wo[0], alpha * wo[1], wo[2]])
    vh /= np.linalg.norm(vh)
    lensq = vh[0] ** 2 + vh[1] ** 2
    t1v = np.array([-vh[1], vh[0], 0.0]) / math.sqrt(lensq) if lensq > 0 else np.array([1.0, 0.0, 0.0])
    t2v = np.cross(vh, t1v)
    r = np.sqrt(u1)
    ph = 2.0 * math.pi * u2
    t1 = r * np.cos(ph)
    t2 = r * np.sin(ph)
    s = 0.5 * (1.0 + vh[2])
    t2 = (1.0 - s) * np.sqrt(1.0 - t1 * t1) + s * t2
    t3 = np.sqrt(np.maximum(0.0, 1.0 - t1 * t1 - t2 * t2))
    nh = t1[:, None] * t1v + t2[:, None] * t2v + t3[:, None] * vh
    ne = np.stack([alpha * nh[:, 0], alpha * nh[:, 1], np.maximum(0.0, nh[:, 2])], axis=-1)
    ne /= np.linalg.norm(ne, axis=-1, keepdims=True)
    woh = ne @ wo
    wi = 2.0 * woh[:, None] * ne - wo
    return ne, wi


# ----------------------------------------------------------------------------------------------
# Half-vector-space quadrature over the set {h : reflect(wo, h) above the horizon}.
# ----------------------------------------------------------------------------------------------

def wo_from_theta(theta_o_deg):
    t = math.radians(theta_o_deg)
    return np.array([math.sin(t), 0.0, math.cos(t)])


def theta_cut(wo, phi):
    """For h = (sin th cos phi, sin th sin phi, cos th) and wo = (sin to, 0, cos to):
    n.wi = 2 (wo.h)(n.h) - n.wo > 0  <=>  th < pi/4 + atan2(sin to cos phi, cos to) / 2."""
    return 0.25 * math.pi + 0.5 * np.arctan2(wo[0] * np.cos(phi), wo[2])


def gl_panels(edges, n):
    x, w = np.polynomial.legendre.leggauss(n)
    nodes, weights = [], []
    for a, b in zip(edges[:-1], edges[1:]):
        nodes.append(a + (b - a) * 0.5 * (x + 1.0))
        weights.append((b - a) * 0.5 * w)
    return np.concatenate(nodes), np.concatenate(weights)


def tau_edges(alpha, wo, ratio):
    """Panel edges in tau = theta_h / theta_cut(phi) in [0, 1]: first panel at most alpha/4 wide
    in theta_h, then geometric growth by `ratio` (resolves the GGX peak of width ~alpha at h = n
    and its 1/theta^4 tail)."""
    thc_max = 0.25 * math.pi + 0.5 * math.atan2(wo[0], wo[2])
    e = alpha / (4.0 * thc_max)
    edges = [0.0]
    while e < 1.0 / ratio ** 0.5:
        edges.append(e)
        e *= ratio
    edges.append(1.0)
    return np.array(edges)


def hspace_integral(wo, alpha, integrand, n_phi, n_gl, ratio, chunk=64):
    """Sum over nodes of integrand(h, wi) * weight ~ integral over {h: n.wi > 0} d omega_h.
    phi: periodic trapezoid (midpoints); theta_h = tau * theta_cut(phi): composite Gauss-Legendre
    on geometric panels in tau. integrand returns (..., k)."""
    phi_all = 2.0 * math.pi * (np.arange(n_phi) + 0.5) / n_phi
    wphi = 2.0 * math.pi / n_phi
    tau, wtau = gl_panels(tau_edges(alpha, wo, ratio), n_gl)
    total = None
    for i0 in range(0, n_phi, chunk):
        phi = phi_all[i0:i0 + chunk]
        thc = theta_cut(wo, phi)
        th = thc[:, None] * tau[None, :]
        w = wphi * thc[:, None] * wtau[None, :] * np.sin(th)
        st = np.sin(th)
        h = np.stack([st * np.cos(phi)[:, None], st * np.sin(phi)[:, None], np.cos(th)], axis=-1)
        woh = h @ wo
        wi = 2.0 * woh[..., None] * h - wo
        val = integrand(h, wi, woh)
        part = np.sum(val * w[..., None], axis=(0, 1))
        total = part if total is None else total + part
    return total


def albedo_hspace(base_color, metallic, roughness, theta_o_deg, level, smith="correlated"):
    wo = wo_from_theta(theta_o_deg)
    alpha = roughness ** 2
    n_phi, n_gl, ratio = ALBEDO_LEVELS[level]

    def integrand(h, wi, woh):
        f = brdf_np(base_color, metallic, roughness, wo, wi, smith)
        # d omega_i = 4 (wo.h) d omega_h
        return f * (wi[..., 2] * 4.0 * woh)[..., None]

    return hspace_integral(wo, alpha, integrand, n_phi, n_gl, ratio)


def albedo_wispace(base_color, metallic, roughness, theta_o_deg, n_theta=384, n_phi=768):
    """Plain (theta_i, phi_i) product rule: GL in theta_i on [0, pi/2], trapezoid in phi_i.
    Only accurate for moderately rough lobes; used as an independent cross-check."""
    wo = wo_from_theta(theta_o_deg)
    th, wth = gl_panels(np.linspace(0.0, 0.5 * math.pi, 9), n_theta // 8)
    phi = 2.0 * math.pi * (np.arange(n_phi) + 0.5) / n_phi
    st = np.sin(th)
    wi = np.stack([st[:, None] * np.cos(phi)[None, :], st[:, None] * np.sin(phi)[None, :],
                   np.broadcast_to(np.cos(th)[:, None], (th.size, n_phi))], axis=-1)
    f = brdf_np(base_color, metallic, roughness, wo, wi)
    w = (wth * st)[:, None] * (2.0 * math.pi / n_phi) * np.cos(th)[:, None]
    return np.sum(f * w[..., None], axis=(0, 1))


# ----------------------------------------------------------------------------------------------
# Case generation.
# ----------------------------------------------------------------------------------------------

def unit(v):
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def dir_z_phi(z, phi):
    s = math.sqrt(max(0.0, 1.0 - z * z))
    return unit([s * math.cos(phi), s * math.sin(phi), z])


def rand_upper(rng, grazing=False):
    z = 10.0 ** rng.uniform(-3.0, -1.0) if grazing else rng.uniform(1e-3, 1.0)
    return dir_z_phi(z, rng.uniform(0.0, 2.0 * math.pi))


def rand_material(rng):
    bc = rng.random(3)
    k = int(rng.integers(3))
    metallic = [0.0, 1.0, None][k]
    if metallic is None:
        metallic = float(rng.random())
    k = int(rng.integers(len(ROUGHNESS_CHOICES)))
    rough = ROUGHNESS_CHOICES[k]
    if rough is None:
        rough = float(rng.uniform(0.02, 1.0))
    return [float(x) for x in bc], metallic, rough


def near_specular(rng, wo, alpha, k_offset):
    """wi = reflect(wo) about n, rotated by k_offset * alpha radians in a random tangent direction."""
    r = np.array([-wo[0], -wo[1], wo[2]])
    delta = k_offset * alpha
    if delta == 0.0:
        return r
    for _ in range(100):
        t = rng.normal(size=3)
        t = unit(t - np.dot(t, r) * r)
        wi = unit(math.cos(delta) * r + math.sin(delta) * t)
        if wi[2] > 0:
            return wi
    raise RuntimeError("could not find an upper-hemisphere near-specular direction")


NEAR_SPEC_K = [0.0, 0.01, 0.1, 0.3, 1.0, 3.0]


def gen_eval_inputs(rng):
    cases = []

    def add(kind, bc, m, r, wo, wi):
        cases.append({"kind": kind, "base_color": [float(x) for x in bc], "metallic": float(m),
                      "roughness": float(r), "wo": [float(x) for x in wo],
                      "wi": [float(x) for x in wi]})

    for _ in range(150):
        bc, m, r = rand_material(rng)
        add("random", bc, m, r, rand_upper(rng), rand_upper(rng))
    for i in range(50):
        bc, m, r = rand_material(rng)
        which = i % 3  # 0: wo grazing, 1: wi grazing, 2: both
        wo = rand_upper(rng, grazing=which in (0, 2))
        wi = rand_upper(rng, grazing=which in (1, 2))
        add("grazing", bc, m, r, wo, wi)
    for i in range(78):
        bc, m, r = rand_material(rng)
        wo = rand_upper(rng, grazing=(i % 4 == 3))
        add("near_specular", bc, m, r, wo, near_specular(rng, wo, r * r, NEAR_SPEC_K[i % 6]))
    z = [0.0, 0.0, 1.0]
    g = 0.5 ** 0.5
    grey = [0.5, 0.5, 0.5]
    special = [
        (grey, 0.0, 0.05, z, z),
        (grey, 1.0, 0.05, z, z),
        ([0.9, 0.6, 0.3], 0.5, 0.5, z, z),
        ([1.0, 1.0, 1.0], 0.0, 1.0, z, [g, 0.0, g]),
        ([0.0, 0.0, 0.0], 0.0, 0.3, [g, 0.0, g], [-g, 0.0, g]),
        ([0.0, 0.0, 0.0], 1.0, 0.3, [g, 0.0, g], [-g, 0.0, g]),
        ([1.0, 1.0, 1.0], 1.0, 0.02, [0.6, 0.0, 0.8], [-0.6, 0.0, 0.8]),
        ([0.2, 0.4, 0.6], 0.0, 0.1, dir_z_phi(1e-3, 0.3), dir_z_phi(1e-3, 0.3 + math.pi)),
        ([0.2, 0.4, 0.6], 1.0, 0.1, dir_z_phi(1e-3, 0.3), dir_z_phi(1e-3, 0.3)),
        ([0.7, 0.1, 0.4], 0.3, 0.8, dir_z_phi(0.37, 1.1), dir_z_phi(0.37, 1.1)),
        ([0.7, 0.1, 0.4], 1.0, 0.6, dir_z_phi(1e-3, 0.0), z),
        ([0.3, 0.3, 0.9], 0.0, 1.0, dir_z_phi(1e-3, 2.0), dir_z_phi(1e-3, 0.5)),
    ]
    for bc, m, r, wo, wi in special:
        add("special", bc, m, r, unit(wo), unit(wi))
    below = [
        (rand_upper(rng), unit([0.3, 0.2, -0.5])),
        (unit([0.1, -0.4, -0.9]), rand_upper(rng)),
        (unit([0.1, -0.4, -0.9]), unit([0.5, 0.5, -0.2])),
        (rand_upper(rng), [0.6, 0.8, 0.0]),
        ([1.0, 0.0, 0.0], rand_upper(rng)),
        (rand_upper(rng), dir_z_phi(-1e-3, 1.0)),
        (dir_z_phi(-1e-3, 4.0), rand_upper(rng)),
        ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]),
        (unit([0.2, 0.3, 0.9]), unit([-0.2, -0.3, -0.9])),
        ([0.0, 0.0, -1.0], [0.0, 0.0, -1.0]),
    ]
    for wo, wi in below:
        bc, m, r = rand_material(rng)
        add("below_horizon", bc, m, r, wo, wi)
    return cases


def gen_pdf_inputs(rng):
    cases = []

    def add(kind, r, wo, wi):
        cases.append({"kind": kind, "roughness": float(r), "wo": [float(x) for x in wo],
                      "wi": [float(x) for x in wi]})

    def rough():
        k = int(rng.integers(len(ROUGHNESS_CHOICES)))
        return ROUGHNESS_CHOICES[k] if ROUGHNESS_CHOICES[k] is not None else float(rng.uniform(0.02, 1.0))

    for _ in range(55):
        add("random", rough(), rand_upper(rng), rand_upper(rng))
    for i in range(15):
        add("grazing", rough(), rand_upper(rng, grazing=i % 3 != 1), rand_upper(rng, grazing=i % 3 != 0))
    for i in range(18):
        r = rough()
        wo = rand_upper(rng, grazing=(i % 4 == 3))
        add("near_specular", r, wo, near_specular(rng, wo, r * r, NEAR_SPEC_K[i % 6]))
    add("special", 0.05, [0.0, 0.0, 1.0], [0.0, 0.0, 1.0])
    add("special", 1.0, [0.0, 0.0, 1.0], unit([1.0, 0.0, 1.0]))
    for wo, wi in [(rand_upper(rng), unit([0.3, 0.2, -0.5])), (rand_upper(rng), [0.6, 0.8, 0.0]),
                   (rand_upper(rng), dir_z_phi(-1e-3, 1.0)), ([0.0, 0.0, 1.0], [0.0, 0.0, -1.0]),
                   (unit([0.6, 0.0, 0.8]), unit([-0.6, 0.0, -0.8])),
                   (dir_z_phi(1e-3, 0.0), dir_z_phi(-1e-3, math.pi)),
                   (rand_upper(rng, grazing=True), unit([0.0, 0.3, -0.1])),
                   (rand_upper(rng), unit([-0.5, 0.5, -0.7])),
                   (rand_upper(rng), dir_z_phi(0.0, 2.5)),
                   (dir_z_phi(0.5, 0.2), dir_z_phi(-0.5, 0.2 + math.pi))]:
        add("below_horizon", rough(), wo, wi)
    return cases


ALBEDO_BASE = [[1.0, 1.0, 1.0], [0.5, 0.2, 0.8]]
ALBEDO_METALLIC = [0.0, 1.0]
ALBEDO_ROUGH = [0.1, 0.3, 0.6, 1.0]
ALBEDO_THETA = [0.0, 30.0, 60.0, 80.0]


def albedo_inputs():
    out = []
    for bc in ALBEDO_BASE:
        for m in ALBEDO_METALLIC:
            for r in ALBEDO_ROUGH:
                for t in ALBEDO_THETA:
                    out.append({"base_color": bc, "metallic": m, "roughness": r, "theta_o_deg": t,
                                "wo": [float(x) for x in wo_from_theta(t)]})
    return out


# ----------------------------------------------------------------------------------------------
# Computing the outputs.
# ----------------------------------------------------------------------------------------------

def compute_eval(cases):
    for c in cases:
        res = brdf_dec(c["base_color"], c["metallic"], c["roughness"], c["wo"], c["wi"])
        c["f"] = [float(x) for x in res["correlated"]]
        c["f_separable_smith"] = [float(x) for x in res["separable"]]
        c["rel_sensitivity"] = rel_sensitivity(_brdf_dec_exact(c["base_color"], c["metallic"]),
                                               c["wo"], c["wi"], c["roughness"])
    return cases


def compute_pdf(cases):
    for c in cases:
        c["pdf"] = float(pdf_dec(c["roughness"], c["wo"], c["wi"]))
        c["rel_sensitivity"] = rel_sensitivity(_pdf_dec_exact, c["wo"], c["wi"], c["roughness"])
    return cases


def compute_albedo(cases, log=print):
    for c in cases:
        vals = {}
        for smith in ("correlated", "separable"):
            lv = [albedo_hspace(c["base_color"], c["metallic"], c["roughness"], c["theta_o_deg"], k, smith)
                  for k in range(len(ALBEDO_LEVELS))]
            d01 = float(np.max(np.abs(lv[1] - lv[0])))
            d12 = float(np.max(np.abs(lv[2] - lv[1])))
            vals[smith] = (lv[2], d01, d12)
        a, d01, d12 = vals["correlated"]
        c["albedo"] = [float(x) for x in a]
        c["abs_error_bound"] = max(d12, ALBEDO_BOUND_FLOOR)
        c["convergence"] = {"level1_minus_level0": d01, "level2_minus_level1": d12}
        a_s, _, d12s = vals["separable"]
        c["albedo_separable_smith"] = [float(x) for x in a_s]
        c["abs_error_bound_separable_smith"] = max(d12s, ALBEDO_BOUND_FLOOR)
        log("albedo bc=%s m=%g r=%g th=%g: %s  |L1-L0|=%.2e |L2-L1|=%.2e"
            % (c["base_color"], c["metallic"], c["roughness"], c["theta_o_deg"],
               ["%.10f" % x for x in a], d01, d12))
    return cases


# ----------------------------------------------------------------------------------------------
# Verification (results go into meta.verification).
# ----------------------------------------------------------------------------------------------

def chi2_pvalue(chi2, dof):
    """Upper tail of chi^2 via the Wilson-Hilferty normal approximation."""
    if dof <= 0:
        return float("nan")
    z = ((chi2 / dof) ** (1.0 / 3.0) - (1.0 - 2.0 / (9.0 * dof))) / math.sqrt(2.0 / (9.0 * dof))
    return 0.5 * math.erfc(z / math.sqrt(2.0))


def pooled_chi2(obs, exp, min_exp=20.0):
    obs = np.asarray(obs, dtype=np.float64).ravel()
    exp = np.asarray(exp, dtype=np.float64).ravel()
    big = exp >= min_exp
    o = list(obs[big])
    e = list(exp[big])
    if np.any(~big):
        o.append(obs[~big].sum())
        e.append(exp[~big].sum())
    o = np.array(o)
    e = np.array(e)
    keep = e > 0
    chi2 = float(np.sum((o[keep] - e[keep]) ** 2 / e[keep]))
    dof = int(keep.sum()) - 1
    return chi2, dof, chi2_pvalue(chi2, dof)


def vndf_samples(rng, wo, alpha, n, chunk=500000):
    for i0 in range(0, n, chunk):
        m = min(chunk, n - i0)
        yield sample_vndf(wo, alpha, rng.random(m), rng.random(m))


def verify_vndf(log=print, n_samples=2000000):
    """Histogram of the VNDF sampler's reflected directions vs the pdf formula."""
    rng = np.random.default_rng(SEED + 1)
    results = []
    n_phi_bins = 16
    for r in (0.05, 0.1, 0.3, 0.6, 1.0):
        alpha = r * r
        for theta_o in (0.0, 45.0, 80.0, 89.0):
            wo = wo_from_theta(theta_o)
            # (A) bins in half-vector space (tau = theta_h / theta_cut(phi_h), phi_h); the bins'
            # images in wi space exactly tile the upper hemisphere; one extra bin "below horizon".
            tedges = tau_edges(alpha, wo, 2.0)
            pedges = np.linspace(0.0, 2.0 * math.pi, n_phi_bins + 1)
            xg, wg = np.polynomial.legendre.leggauss(16)
            exp_a = np.zeros((len(tedges) - 1, n_phi_bins))
            for j in range(n_phi_bins):
                phi = pedges[j] + (pedges[j + 1] - pedges[j]) * 0.5 * (xg + 1.0)
                wphi = (pedges[j + 1] - pedges[j]) * 0.5 * wg
                thc = theta_cut(wo, phi)
                for i in range(len(tedges) - 1):
                    tau = tedges[i] + (tedges[i + 1] - tedges[i]) * 0.5 * (xg + 1.0)
                    wtau = (tedges[i + 1] - tedges[i]) * 0.5 * wg
                    th = thc[:, None] * tau[None, :]
                    st = np.sin(th)
                    h = np.stack([st * np.cos(phi)[:, None], st * np.sin(phi)[:, None], np.cos(th)], -1)
                    woh = h @ wo
                    wi = 2.0 * woh[..., None] * h - wo
                    val = pdf_np(r, wo, wi) * 4.0 * woh * st * thc[:, None]
                    exp_a[i, j] = np.sum(val * wphi[:, None] * wtau[None, :])
            p_upper_bins = float(exp_a.sum())
            n_phi_q, n_gl_q, ratio_q = ALBEDO_LEVELS[-1]
            p_upper = float(hspace_integral(
                wo, alpha, lambda h, wi, woh: (pdf_np(r, wo, wi) * 4.0 * woh)[..., None],
                n_phi_q, n_gl_q, ratio_q)[0])
            # (B) bins in wi space: 16 equal-solid-angle bands in n.wi x 16 azimuth bins.
            xg24, wg24 = np.polynomial.legendre.leggauss(24)
            zedges = np.linspace(0.0, 1.0, 17)
            thedges = np.arccos(zedges)[::-1]  # increasing theta_i
            exp_b = np.zeros((16, n_phi_bins))
            # (wi-space bins cannot resolve the lobe at theta_o = 89 deg: there |wo + wi| ~ 2 n.wo,
            # so the lobe is only ~alpha * 2 n.wo wide in elevation; nor the narrow lobes r < 0.3.)
            do_b = r >= 0.3 and theta_o <= 80.0
            for i in range(16 if do_b else 0):
                th = thedges[i] + (thedges[i + 1] - thedges[i]) * 0.5 * (xg24 + 1.0)
                wth = (thedges[i + 1] - thedges[i]) * 0.5 * wg24
                for j in range(n_phi_bins):
                    phi = pedges[j] + (pedges[j + 1] - pedges[j]) * 0.5 * (xg24 + 1.0)
                    wphi = (pedges[j + 1] - pedges[j]) * 0.5 * wg24
                    st = np.sin(th)
                    wi = np.stack([st[:, None] * np.cos(phi)[None, :], st[:, None] * np.sin(phi)[None, :],
                                   np.broadcast_to(np.cos(th)[:, None], (th.size, phi.size))], -1)
                    exp_b[i, j] = np.sum(pdf_np(r, wo, wi) * (wth * st)[:, None] * wphi[None, :])
            obs_a = np.zeros_like(exp_a)
            obs_b = np.zeros_like(exp_b)
            n_below = 0
            for h, wi in vndf_samples(rng, wo, alpha, n_samples):
                up = wi[:, 2] > 0
                n_below += int(np.sum(~up))
                wiu = wi[up]
                hh = wo + wiu
                hh /= np.linalg.norm(hh, axis=-1, keepdims=True)
                th = np.arctan2(np.hypot(hh[:, 0], hh[:, 1]), hh[:, 2])
                ph = np.mod(np.arctan2(hh[:, 1], hh[:, 0]), 2.0 * math.pi)
                tau = np.clip(th / theta_cut(wo, ph), 0.0, 1.0)
                ia = np.clip(np.searchsorted(tedges, tau, side="right") - 1, 0, len(tedges) - 2)
                ja = np.clip((ph / (2.0 * math.pi) * n_phi_bins).astype(int), 0, n_phi_bins - 1)
                np.add.at(obs_a, (ia, ja), 1)
                phw = np.mod(np.arctan2(wiu[:, 1], wiu[:, 0]), 2.0 * math.pi)
                ib = np.clip((16 * (1.0 - wiu[:, 2])).astype(int), 0, 15)
                jb = np.clip((phw / (2.0 * math.pi) * n_phi_bins).astype(int), 0, n_phi_bins - 1)
                np.add.at(obs_b, (ib, jb), 1)
            n = float(n_samples)
            frac_below = n_below / n
            se_below = math.sqrt(max(frac_below * (1.0 - frac_below), 1.0 / n) / n)
            chi_a = pooled_chi2(np.append(obs_a.ravel(), n_below), np.append(exp_a.ravel() * n, (1.0 - p_upper) * n))
            res = {"roughness": r, "theta_o_deg": theta_o, "samples": n_samples,
                   "int_pdf_upper_hspace": p_upper,
                   "int_pdf_upper_hspace_bin_sum_minus_quadrature": p_upper_bins - p_upper,
                   "frac_below_horizon_mc": frac_below, "frac_below_horizon_mc_std_err": se_below,
                   "z_score_one_minus_int_pdf_vs_frac_below": ((1.0 - p_upper) - frac_below) / se_below,
                   "chi2_hspace_bins": {"chi2": chi_a[0], "dof": chi_a[1], "p_value": chi_a[2]}}
            if do_b:
                p_upper_b = float(exp_b.sum())
                chi_b = pooled_chi2(np.append(obs_b.ravel(), n_below),
                                    np.append(exp_b.ravel() * n, (1.0 - p_upper_b) * n))
                res["int_pdf_upper_wispace"] = p_upper_b
                res["chi2_wispace_bins"] = {"chi2": chi_b[0], "dof": chi_b[1], "p_value": chi_b[2]}
            results.append(res)
            log("vndf r=%g th=%g: int_H+ pdf=%.6f (wi-space %s) below MC=%.6f+-%.1e z=%.2f chi2 %s %s"
                % (r, theta_o, p_upper, res.get("int_pdf_upper_wispace", "-"), frac_below, se_below,
                   res["z_score_one_minus_int_pdf_vs_frac_below"], chi_a, res.get("chi2_wispace_bins", "")))
    return results


def verify_g1_normalisation(log=print):
    """integral over {wo.h > 0} of (wo.h) D(h) d omega_h == n.wo / G1(wo)  (defines Smith G1)."""
    worst = 0.0
    xg, wg = np.polynomial.legendre.leggauss(64)
    for r in (0.05, 0.1, 0.3, 0.6, 1.0):
        alpha = r * r
        for theta_o in (0.0, 30.0, 60.0, 80.0, 89.0):
            wo = wo_from_theta(theta_o)
            tot = 0.0
            for pa, pb in ((0.0, 0.5 * math.pi), (0.5 * math.pi, math.pi)):
                phi = pa + (pb - pa) * 0.5 * (xg + 1.0)
                wphi = 2.0 * (pb - pa) * 0.5 * wg  # x2: phi -> -phi symmetry
                cphi = np.cos(phi)
                thu = np.where(cphi >= 0, 0.5 * math.pi, np.arctan2(wo[2], -wo[0] * cphi))
                e = alpha / 8.0
                edges = [0.0]
                while e < 0.7:
                    edges.append(e)
                    e *= 2.0 ** 0.5
                edges.append(1.0)
                tau, wtau = gl_panels(np.array(edges), 32)
                th = thu[:, None] * tau[None, :]
                st = np.sin(th)
                h = np.stack([st * cphi[:, None], st * np.sin(phi)[:, None], np.cos(th)], -1)
                woh = np.maximum(h @ wo, 0.0)
                val = woh * ggx_d_np(alpha, h[..., 2]) * st * thu[:, None]
                tot += float(np.sum(val * wphi[:, None] * wtau[None, :]))
            expect = wo[2] / float(smith_g1_np(alpha, wo[2]))
            worst = max(worst, abs(tot / expect - 1.0))
    log("G1 normalisation: max relative error %.2e" % worst)
    return worst


def verify_jacobian(log=print):
    """d omega_i / d omega_h = 4 |wo.h| for wi = reflect(wo, h), by finite differences."""
    rng = np.random.default_rng(SEED + 2)
    worst = 0.0
    for _ in range(200):
        wo = rand_upper(rng)
        h = rand_upper(rng)
        if np.dot(wo, h) < 0.05:
            continue
        e1 = unit(np.cross(h, [0.3, 0.5, 0.7]))
        e2 = np.cross(h, e1)
        eps = 1e-6

        def refl(hv):
            hv = unit(hv)
            return 2.0 * np.dot(wo, hv) * hv - wo
        a = (refl(h + eps * e1) - refl(h - eps * e1)) / (2 * eps)
        b = (refl(h + eps * e2) - refl(h - eps * e2)) / (2 * eps)
        ratio = np.linalg.norm(np.cross(a, b)) / (4.0 * np.dot(wo, h))
        worst = max(worst, abs(ratio - 1.0))
    log("reflection Jacobian: max relative error %.2e" % worst)
    return worst


def verify_eval_numpy(eval_cases):
    """The float64 numpy BRDF used by the quadratures vs the 50-digit reference values."""
    worst = 0.0
    for c in eval_cases:
        for smith, key in (("correlated", "f"), ("separable", "f_separable_smith")):
            fn = brdf_np(c["base_color"], c["metallic"], c["roughness"], np.array(c["wo"]), np.array(c["wi"]), smith)
            ref = np.array(c[key])
            scale = max(np.max(np.abs(ref)), 1e-300)
            worst = max(worst, float(np.max(np.abs(fn - ref)) / scale))
    return worst


def verify_pdf_numpy(pdf_cases):
    worst = 0.0
    for c in pdf_cases:
        p = float(pdf_np(c["roughness"], np.array(c["wo"]), np.array(c["wi"])))
        worst = max(worst, abs(p - c["pdf"]) / max(abs(c["pdf"]), 1e-300))
    return worst


def verify_albedo(albedo_cases, log=print, n_mc=400000):
    """(a) plain (theta_i, phi_i) quadrature for roughness >= 0.3; (b) Monte Carlo, one-sample
    mixture of the VNDF sampler and cosine-weighted sampling, estimator f cos / pdf_mix."""
    rng = np.random.default_rng(SEED + 3)
    worst_wi = 0.0
    worst_z = 0.0
    worst_mc_abs = 0.0
    for c in albedo_cases:
        ref = np.array(c["albedo"])
        if c["roughness"] >= 0.3:
            a = albedo_wispace(c["base_color"], c["metallic"], c["roughness"], c["theta_o_deg"])
            worst_wi = max(worst_wi, float(np.max(np.abs(a - ref))))
        wo = np.array(c["wo"])
        alpha = c["roughness"] ** 2
        acc = np.zeros(3)
        acc2 = np.zeros(3)
        for i0 in range(0, n_mc, 200000):
            m = min(200000, n_mc - i0)
            # one-sample mixture: cosine-weighted hemisphere or VNDF reflection, probability 1/2 each
            _, wi = sample_vndf(wo, alpha, rng.random(m), rng.random(m))
            u1, u2 = rng.random(m), rng.random(m)
            rr = np.sqrt(u1)
            wc = np.stack([rr * np.cos(2 * math.pi * u2), rr * np.sin(2 * math.pi * u2), np.sqrt(1.0 - u1)], -1)
            wi = np.where((rng.random(m) < 0.5)[:, None], wc, wi)
            p = 0.5 * pdf_np(c["roughness"], wo, wi) + 0.5 * np.maximum(wi[:, 2], 0.0) / math.pi
            f = brdf_np(c["base_color"], c["metallic"], c["roughness"], wo, wi)
            with np.errstate(invalid="ignore", divide="ignore"):
                wgt = np.where((p > 0)[:, None], f * (wi[:, 2] / p)[:, None], 0.0)
            acc += wgt.sum(0)
            acc2 += (wgt * wgt).sum(0)
        mean = acc / n_mc
        se = np.sqrt(np.maximum(acc2 / n_mc - mean * mean, 0.0) / n_mc)
        z = np.abs(mean - ref) / np.maximum(se, 1e-300)
        worst_z = max(worst_z, float(np.max(z)))
        worst_mc_abs = max(worst_mc_abs, float(np.max(np.abs(mean - ref))))
    log("albedo: max |wi-space - h-space| (roughness >= 0.3) = %.2e; MC max |z| = %.2f, max |MC - quad| = %.2e"
        % (worst_wi, worst_z, worst_mc_abs))
    return {"max_abs_diff_wispace_quadrature_roughness_ge_0.3": worst_wi,
            "mc_samples_per_case": n_mc, "mc_max_abs_z_score": worst_z, "mc_max_abs_diff": worst_mc_abs}


def verify_d_normalisation():
    """integral of D(h) (n.h) over the hemisphere == 1, with the same kind of geometric panels."""
    worst = 0.0
    for r in (0.02, 0.05, 0.1, 0.3, 0.6, 1.0):
        alpha = r * r
        edges = [0.0]
        e = alpha / 4.0
        while e < 0.5 * math.pi / 2.0 ** (1.0 / 6.0):
            edges.append(e)
            e *= 2.0 ** (1.0 / 3.0)
        edges.append(0.5 * math.pi)
        th, w = gl_panels(np.array(edges), 48)
        val = ggx_d_np(alpha, np.cos(th)) * np.cos(th) * np.sin(th) * 2.0 * math.pi
        worst = max(worst, abs(float(np.sum(val * w)) - 1.0))
    return worst


def verify_albedo_closed_form(albedo_cases):
    """roughness 1 (alpha = 1, D = 1/pi), metallic 1, base colour 1 (Fresnel = 1):
    correlated: R = int_0^1 mu / (c + mu) d mu = 1 - c ln(1 + 1/c);
    separable:  R = int_0^1 2 mu / ((1 + mu)(1 + c)) d mu = 2 (1 - ln 2) / (1 + c);   c = cos theta_o."""
    worst = 0.0
    for a in albedo_cases:
        if a["roughness"] == 1.0 and a["metallic"] == 1.0 and a["base_color"] == [1.0, 1.0, 1.0]:
            c = a["wo"][2]
            exact_c = 1.0 - c * math.log1p(1.0 / c)
            exact_s = 2.0 * (1.0 - math.log(2.0)) / (1.0 + c)
            worst = max(worst, max(abs(x - exact_c) for x in a["albedo"]),
                        max(abs(x - exact_s) for x in a["albedo_separable_smith"]))
    return worst


# ----------------------------------------------------------------------------------------------
# Output.
# ----------------------------------------------------------------------------------------------

CASE_KEY_ORDER = ["kind", "base_color", "metallic", "roughness", "theta_o_deg", "wo", "wi", "f",
                  "f_separable_smith", "pdf", "albedo", "abs_error_bound", "convergence",
                  "albedo_separable_smith", "abs_error_bound_separable_smith", "rel_sensitivity"]


def ordered(c):
    return {k: c[k] for k in CASE_KEY_ORDER if k in c}


def dump(doc, path):
    lines = ["{"]
    lines.append(' "meta": ' + json.dumps(doc["meta"], indent=1).replace("\n", "\n ") + ",")
    for si, sec in enumerate(("eval", "pdf", "albedo")):
        lines.append(' "%s": [' % sec)
        items = [json.dumps(ordered(c), separators=(",", ":")) for c in doc[sec]]
        lines.append(",\n".join("  " + s for s in items))
        lines.append(" ]" + ("," if si < 2 else ""))
    lines.append("}")
    text = "\n".join(lines) + "\n"
    json.loads(text)  # sanity
    os.makedirs(os.path.dirname(path), exist_ok=True)
    with open(path, "w") as fh:
        fh.write(text)
    return len(text)


def build(log=print, verify=True):
    rng = np.random.default_rng(SEED)
    t0 = time.time()
    eval_cases = compute_eval(gen_eval_inputs(rng))
    pdf_cases = compute_pdf(gen_pdf_inputs(rng))
    log("eval/pdf: %.1f s" % (time.time() - t0))
    albedo_cases = compute_albedo(albedo_inputs(), log)
    log("albedo: %.1f s" % (time.time() - t0))
    meta = {
        "description": "Independent reference values for the glTF 2.0 metallic-roughness BRDF "
                       "(glTF 2.0 specification, Appendix B) and the GGX VNDF reflected-direction pdf. "
                       "Generated by tools/pbr_oracle.py; see its docstring.",
        "formulas": FORMULAS,
        "command": COMMAND,
        "check_command": COMMAND + " --check",
        "seed": SEED,
        "numpy_version": np.__version__,
        "python_version": platform.python_version(),
        "eval_precision": "f and pdf evaluated in %d-digit decimal arithmetic from the exact f64 inputs, "
                          "then rounded to the nearest f64" % DPREC,
        "fields": {
            "eval.f": "glTF Appendix B BRDF (height-correlated Smith visibility), RGB, not multiplied by n.wi",
            "eval.f_separable_smith": "same but with the separable Smith visibility of the CONVENTIONS.md line "
                                      "(1/((|n.wi|+..)(|n.wo|+..))); informational, differs from the spec",
            "eval.rel_sensitivity": "max over inputs x of |df/dx| / max_c|f_c|, x = one component of wo or wi "
                                    "(vector renormalised) or log(roughness); an implementation working in "
                                    "precision eps should expect relative errors of order rel_sensitivity * eps "
                                    "from input rounding alone (f32: eps ~ 6e-8)",
            "eval.kind": "random | grazing (n.w in [1e-3, 0.1]) | near_specular (wi = reflect(wo) rotated by "
                         "k*alpha, k in %s) | special | below_horizon (f = 0)" % NEAR_SPEC_K,
            "pdf.pdf": "VNDF reflected-direction pdf G1(wo) D(h) / (4 n.wo), 0 when n.wi <= 0",
            "albedo.albedo": "R(wo) = integral over the upper hemisphere of f (n.wi) d omega_i, f as eval.f",
            "albedo.abs_error_bound": "max(|level2 - level1|, %g) over RGB: observed change between the two finest "
                                      "quadrature levels" % ALBEDO_BOUND_FLOOR,
            "albedo.albedo_separable_smith": "same integral for eval.f_separable_smith",
        },
        "notes": NOTES,
        "albedo_quadrature": "Half-vector space: wi = 2 (wo.h) h - wo, d omega_i = 4 (wo.h) d omega_h. "
                             "h = (sin th cos phi, sin th sin phi, cos th) with th = tau * theta_cut(phi), "
                             "theta_cut(phi) = pi/4 + atan2(sin theta_o cos phi, cos theta_o)/2 being exactly "
                             "the horizon n.wi = 0, so the domain is the rectangle tau in [0,1], phi in [0,2pi) "
                             "and the integrand is smooth (it vanishes linearly at tau = 1). phi: periodic "
                             "trapezoid rule; tau: composite Gauss-Legendre on panels starting at "
                             "theta = alpha/4 and growing geometrically, which resolves the GGX peak at h = n "
                             "and its tail. Levels (n_phi, GL nodes per panel, panel ratio): %s; the values are "
                             "level 2." % ALBEDO_LEVELS,
    }
    if verify:
        v = {}
        v["eval_numpy_f64_vs_decimal_max_rel_diff"] = verify_eval_numpy(eval_cases)
        v["pdf_numpy_f64_vs_decimal_max_rel_diff"] = verify_pdf_numpy(pdf_cases)
        log("numpy vs decimal: eval %.2e pdf %.2e" % (v["eval_numpy_f64_vs_decimal_max_rel_diff"],
                                                      v["pdf_numpy_f64_vs_decimal_max_rel_diff"]))
        v["ggx_d_normalisation_max_abs_err"] = verify_d_normalisation()
        v["albedo_closed_form_max_abs_err"] = verify_albedo_closed_form(albedo_cases)
        log("albedo closed form (r=1, metal, white): %.2e" % v["albedo_closed_form_max_abs_err"])
        v["smith_g1_normalisation_max_rel_err"] = verify_g1_normalisation(log)
        v["reflection_jacobian_max_rel_err"] = verify_jacobian(log)
        v["albedo"] = verify_albedo(albedo_cases, log)
        v["vndf_sampler_vs_pdf"] = verify_vndf(log)
        meta["verification"] = v
        log("verification: %.1f s" % (time.time() - t0))
    return {"meta": meta, "eval": eval_cases, "pdf": pdf_cases, "albedo": albedo_cases}


def check(path, log=print):
    with open(path) as fh:
        old = json.load(fh)
    rng = np.random.default_rng(SEED)
    ok = True

    def fail(msg):
        nonlocal ok
        ok = False
        log("MISMATCH: " + msg)

    # Regenerated inputs must match the committed ones (up to libm differences).
    for sec, gen in (("eval", gen_eval_inputs), ("pdf", gen_pdf_inputs)):
        new_in = gen(rng)
        if len(new_in) != len(old[sec]):
            fail("%s: %d cases, regenerated %d" % (sec, len(old[sec]), len(new_in)))
            continue
        for i, (a, b) in enumerate(zip(old[sec], new_in)):
            for k in ("base_color", "metallic", "roughness", "wo", "wi"):
                if k in b and not np.allclose(a[k], b[k], rtol=0, atol=1e-14):
                    fail("%s[%d].%s: %s vs regenerated %s" % (sec, i, k, a[k], b[k]))
    # Outputs recomputed from the committed inputs.
    ev = compute_eval([{k: c[k] for k in ("kind", "base_color", "metallic", "roughness", "wo", "wi")}
                       for c in old["eval"]])
    for i, (a, b) in enumerate(zip(old["eval"], ev)):
        for k in ("f", "f_separable_smith"):
            if not np.allclose(a[k], b[k], rtol=1e-13, atol=0):
                fail("eval[%d].%s: %s vs %s" % (i, k, a[k], b[k]))
    pd = compute_pdf([{k: c[k] for k in ("kind", "roughness", "wo", "wi")} for c in old["pdf"]])
    for i, (a, b) in enumerate(zip(old["pdf"], pd)):
        if not np.isclose(a["pdf"], b["pdf"], rtol=1e-13, atol=0):
            fail("pdf[%d]: %r vs %r" % (i, a["pdf"], b["pdf"]))
    al = compute_albedo(albedo_inputs(), log=lambda *_: None)
    if len(al) != len(old["albedo"]):
        fail("albedo: %d cases, recomputed %d" % (len(old["albedo"]), len(al)))
    for i, (a, b) in enumerate(zip(old["albedo"], al)):
        for k in ("base_color", "metallic", "roughness", "theta_o_deg"):
            if a[k] != b[k]:
                fail("albedo[%d].%s: %s vs %s" % (i, k, a[k], b[k]))
        for k in ("albedo", "albedo_separable_smith"):
            if not np.allclose(a[k], b[k], rtol=0, atol=1e-12):
                fail("albedo[%d].%s: %s vs %s" % (i, k, a[k], b[k]))
        if a["abs_error_bound"] < 0.5 * b["abs_error_bound"] or a["abs_error_bound"] > 2 * b["abs_error_bound"]:
            fail("albedo[%d].abs_error_bound: %r vs %r" % (i, a["abs_error_bound"], b["abs_error_bound"]))
    log("check: %s (%d eval, %d pdf, %d albedo cases)" % ("OK" if ok else "FAILED", len(old["eval"]),
                                                         len(old["pdf"]), len(old["albedo"])))
    return ok


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--check", action="store_true",
                    help="recompute and compare with the committed JSON instead of writing it")
    ap.add_argument("--no-verify", action="store_true",
                    help="skip the (slow, ~minutes) verification runs; meta.verification is then omitted")
    ap.add_argument("--out", default=os.path.join(REPO_ROOT, OUT_REL))
    args = ap.parse_args(argv)
    log = lambda *a: print(*a, file=sys.stderr, flush=True)
    if args.check:
        return 0 if check(args.out, log) else 1
    doc = build(log, verify=not args.no_verify)
    size = dump(doc, args.out)
    log("wrote %s (%d bytes): %d eval, %d pdf, %d albedo cases"
        % (args.out, size, len(doc["eval"]), len(doc["pdf"]), len(doc["albedo"])))
    return 0


if __name__ == "__main__":
    sys.exit(main())
