#!/usr/bin/env python3
"""Independent relighter of `prt export` glTF files (per-vertex objects).

Written from `crates/bakefile/SPEC.md` §1 (SH convention), §10 (glTF export), §10.1
(view-dependent shading) and `CONVENTIONS.md` ("Spherical harmonics") ALONE: no Rust source of
prt was read, and nothing of prt is imported or called, so a disagreement with `prt relight`
points at a bug in one of them or at a gap in the SPEC. Needs Python 3 and numpy only.

For every mesh whose primitive has `extras.prt.storage == "vertex"` it computes each vertex's
radiance `D_c + S_c` (§10.1):
  * diffuse `D_c = albedo_c · k_d · (1/π) Σ_i t[c or 0][i] · environment[i][c]`, albedo =
    `extras.prt.albedo` (RGB, or the name of a per-vertex VEC3 attribute), `k_d = 1 − s̄_d(θ_o)` (piecewise linear in θ_o) or 1;
  * specular `S_c = scale_c · Σ_i w_i (L_c ⊛ V)_i` for lobe models "phong" and "fitted".
    The SH product `L ⊛ V` is NOT computed from Gaunt coefficients but by quadrature: the
    truncated lighting and visibility are evaluated on a Gauss–Legendre (cos θ) × uniform-φ
    grid that integrates polynomials of degree 3(n−1) exactly, multiplied and projected back
    (per channel as the matrix M_c[i][k] = Σ_q w_q y_i L_c y_k, then M_c V per vertex).
Real SH (orthonormal, Condon–Shortley phase, index l(l+1)+m, θ from +Z, φ = atan2(y, x)) come
from a normalised associated-Legendre recurrence times Re/Im (x + iy)^m (no atan2, stable at
the poles). All arithmetic is float64. Lightmapped meshes are skipped (note on stderr).

Usage:
    python3 tools/gltf_relight.py ASSET.glb --colours OUT.csv [--eye X,Y,Z]
            [--compare REF.csv] [--magnitudes MAG.csv] [--no-specular] [--no-fresnel]
    python3 tools/gltf_relight.py --self-test
OUT.csv has prt's layout: `object,point,r,g,b`, one row per vertex (floats as repr()).
`--magnitudes` writes, in the same layout, each sum with every factor replaced by its absolute
value: a float32 evaluation of the formula is within γ_N = N·2⁻²⁴ of those (N the longest chain
of roundings), which is how a test bounds the difference from prt. `--compare` prints, per object, the max |ours − ref| relative to the max of ref per channel
and the worst vertices; `--no-specular` / `--no-fresnel` drop S_c / k_d (for diagnosis).
Exit status 1 on a malformed file (one line naming the file), 2 when `--compare` finds a
relative difference >= 1e-3, 0 otherwise.
"""
import argparse
import json
import math
import struct
import sys

import numpy as np

FOUR_PI = 4.0 * math.pi


class GlbError(Exception):
    """A malformed file or a missing field/attribute."""


# ----------------------------------------------------------------------------------------------
# Real spherical harmonics (§1, CONVENTIONS.md)
# ----------------------------------------------------------------------------------------------
def sh_eval(dirs, n):
    """y_i(d) for i < n², d (..., 3) normalised here; returns (..., n²) float64."""
    d = np.asarray(dirs, dtype=np.float64)
    shape = d.shape[:-1]
    d = d.reshape(-1, 3)
    d = d / np.linalg.norm(d, axis=1, keepdims=True)
    x, y, z = d[:, 0], d[:, 1], d[:, 2]
    out = np.zeros((d.shape[0], n * n))
    qmm = np.full(d.shape[0], 1.0 / math.sqrt(FOUR_PI))   # K_m^m P_m^m / sin^m θ (CS phase)
    cm, sm = np.ones_like(x), np.zeros_like(x)             # Re, Im of (x + iy)^m
    for m in range(n):
        if m > 0:
            qmm = -math.sqrt((2 * m + 1) / (2.0 * m)) * qmm
            cm, sm = x * cm - y * sm, x * sm + y * cm
        q2, q1 = None, qmm
        for l in range(m, n):
            if l == m + 1:
                q2, q1 = q1, math.sqrt(2 * m + 3) * z * q1
            elif l > m + 1:
                a = math.sqrt((4 * l * l - 1) / (l * l - m * m))
                b = math.sqrt(((l - 1) ** 2 - m * m) / (4 * (l - 1) ** 2 - 1))
                q2, q1 = q1, a * (z * q1 - b * q2)
            c = l * (l + 1)
            if m == 0:
                out[:, c] = q1
            else:
                out[:, c + m] = math.sqrt(2) * q1 * cm
                out[:, c - m] = math.sqrt(2) * q1 * sm
    return out.reshape(shape + (n * n,))


def band_of(n):
    """l of every flat index i < n²."""
    return np.concatenate([np.full(2 * l + 1, l) for l in range(n)])


def sphere_grid(degree):
    """Directions and weights integrating every spherical polynomial of `degree` exactly."""
    nt = degree // 2 + 1                        # Gauss–Legendre: exact to degree 2·nt − 1
    nphi = degree + 1                           # uniform φ: exact for |k| ≤ degree
    zt, wt = np.polynomial.legendre.leggauss(nt)
    phi = 2.0 * math.pi * (np.arange(nphi) + 0.5) / nphi
    s = np.sqrt(np.maximum(0.0, 1.0 - zt * zt))
    dirs = np.stack([np.outer(s, np.cos(phi)), np.outer(s, np.sin(phi)),
                     np.outer(zt, np.ones(nphi))], axis=-1).reshape(-1, 3)
    w = np.outer(wt, np.full(nphi, 2.0 * math.pi / nphi)).reshape(-1)
    return dirs, w


def product_matrices(light, n):
    """M[c][i][k] = ∫ y_i · (Σ_j L_{c,j} y_j) · y_k by quadrature (light: (n², C))."""
    dirs, w = sphere_grid(3 * (n - 1))
    y = sh_eval(dirs, n)                        # (Q, n²)
    lg = y @ light                              # truncated lighting on the grid, (Q, C)
    return np.stack([y.T @ (y * (w * lg[:, c])[:, None]) for c in range(light.shape[1])])


def phong_bands(e, n, nodes=400):
    """A_l = 2π ∫_0^1 (e+1)/(2π) x^e P_l(x) dx by Gauss–Legendre on [0, 1] (§10.1)."""
    t, w = np.polynomial.legendre.leggauss(nodes)
    x, w = 0.5 * (t + 1.0), 0.5 * w
    return np.array([(e + 1.0) * np.sum(w * x ** e * np.polynomial.legendre.legval(
        x, [0.0] * l + [1.0])) for l in range(n)])


def locate(grid, x):
    """§10.1 step 1 for an array x: (index, weight) in an increasing grid."""
    g = np.asarray(grid, dtype=np.float64)
    x = np.asarray(x, dtype=np.float64)
    if len(g) < 2:
        return np.zeros(x.shape, dtype=int), np.zeros(x.shape)
    i = np.clip(np.searchsorted(g, x, side="right") - 1, 0, len(g) - 2)
    t = (x - g[i]) / (g[i + 1] - g[i])
    t = np.where(x <= g[0], 0.0, np.where(x >= g[-1], 1.0, t))
    i = np.where(x <= g[0], 0, np.where(x >= g[-1], len(g) - 2, i))
    return i, t


def lum(c):
    return 0.2126 * c[..., 0] + 0.7152 * c[..., 1] + 0.0722 * c[..., 2]


# ----------------------------------------------------------------------------------------------
# .glb container
# ----------------------------------------------------------------------------------------------
COMPONENTS = {5126: ("<f4", 4), 5125: ("<u4", 4), 5123: ("<u2", 2), 5121: ("u1", 1)}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4}
F = 5126


def need(obj, key, where):
    if not isinstance(obj, dict) or key not in obj:
        raise GlbError(f"missing field '{key}' in {where}")
    return obj[key]


class Glb:
    def __init__(self, data):
        if len(data) < 12:
            raise GlbError("shorter than the 12-byte glTF header")
        magic, version, length = struct.unpack_from("<III", data, 0)
        if magic != 0x46546C67 or version != 2:
            raise GlbError(f"not a binary glTF 2 file (magic {magic:#x}, version {version})")
        if length != len(data):
            raise GlbError(f"header length {length} but the file has {len(data)} bytes")
        chunks, pos = [], 12
        while pos < length:
            if pos + 8 > length:
                raise GlbError("truncated chunk header")
            clen, ctype = struct.unpack_from("<II", data, pos)
            if pos + 8 + clen > length or clen % 4:
                raise GlbError(f"chunk at byte {pos} runs past the end or is not 4-aligned")
            chunks.append((ctype, data[pos + 8:pos + 8 + clen]))
            pos += 8 + clen
        if not chunks or chunks[0][0] != 0x4E4F534A:
            raise GlbError("first chunk is not JSON")
        try:
            self.json = json.loads(chunks[0][1].decode("utf-8"))
        except (UnicodeDecodeError, ValueError) as exc:
            raise GlbError(f"JSON chunk does not parse: {exc}") from None
        if not isinstance(self.json, dict):
            raise GlbError("JSON chunk is not an object")
        self.bin = chunks[1][1] if len(chunks) > 1 and chunks[1][0] == 0x004E4942 else b""

    def _item(self, kind, idx):
        items = self.json.get(kind)
        if not isinstance(items, list) or not isinstance(idx, int) or not 0 <= idx < len(items):
            raise GlbError(f"{kind}[{idx}] does not exist")
        return items[idx]

    def accessor(self, idx, types, what):
        acc = self._item("accessors", idx)
        where = f"accessor {idx} ({what})"
        ctype, atype = need(acc, "componentType", where), need(acc, "type", where)
        count = need(acc, "count", where)
        if (ctype, atype) not in types:
            raise GlbError(f"{where} is {atype} of component type {ctype}, expected {types}")
        if "sparse" in acc:
            raise GlbError(f"{where} is sparse (not supported)")
        (dtype, size), width = COMPONENTS[ctype], WIDTH[atype]
        if "bufferView" not in acc:
            return np.zeros((count, width))
        bv = self._item("bufferViews", acc["bufferView"])
        if need(bv, "buffer", "bufferView") != 0 or not self.bin:
            raise GlbError(f"{where}: buffer is not the GLB BIN chunk")
        bv_off, bv_len = bv.get("byteOffset", 0), need(bv, "byteLength", "bufferView")
        stride = bv.get("byteStride", size * width)
        off = acc.get("byteOffset", 0)
        if bv_off + bv_len > len(self.bin) or (count and off + stride * (count - 1)
                                                  + size * width > bv_len):
            raise GlbError(f"{where} runs past its bufferView or the BIN chunk")
        out = np.ndarray((count, width), dtype=dtype, buffer=self.bin, offset=bv_off + off,
                         strides=(stride, size)).astype(np.float64)
        if not np.all(np.isfinite(out)):
            raise GlbError(f"{where} holds a non-finite value")
        return out



def attribute(glb, prim, name, atype, count, where):
    attrs = need(prim, "attributes", where)
    if name not in attrs:
        raise GlbError(f"{where}: missing vertex attribute {name}")
    types = [(F, t) for t in ((atype,) if isinstance(atype, str) else atype)]
    a = glb.accessor(attrs[name], types, f"{where} {name}")
    if count is not None and a.shape[0] != count:
        raise GlbError(f"{where}: {name} has {a.shape[0]} elements, POSITION has {count}")
    return a


def floats(value, shape, what):
    try:
        a = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise GlbError(f"{what} is not an array of numbers") from None
    if shape is not None and (a.ndim != len(shape) or any(
            s is not None and s != d for s, d in zip(shape, a.shape))):
        raise GlbError(f"{what} has shape {a.shape}, expected {shape}")
    return a


# ----------------------------------------------------------------------------------------------
# Relighting (§10, §10.1)
# ----------------------------------------------------------------------------------------------
def relight_primitive(glb, mesh_name, prim, eye, specular=True, fresnel=True, mag_out=None):
    """(nv, 3) radiance of a per-vertex primitive. With a list `mag_out`, also appends the
    (nv, 3) magnitudes of the terms summed — the same sums with every factor replaced by its
    absolute value — on which a float32 evaluation of the formula rounds (error analysis
    of a sum of products: |fl(Σ) − Σ| ≤ γ_N Σ|terms|)."""
    where = f"mesh '{mesh_name}'"
    ext = need(need(prim, "extras", where), "prt", where + " extras")
    n, nch = need(ext, "order", where + " extras.prt"), need(ext, "channels", where)
    if not isinstance(n, int) or n < 1 or nch not in (1, 3):
        raise GlbError(f"{where}: bad order {n} or channels {nch}")
    nn = n * n
    pos = attribute(glb, prim, "POSITION", "VEC3", None, where)
    nv, groups = pos.shape[0], (nn + 3) // 4
    nrm = attribute(glb, prim, "NORMAL", "VEC3", nv, where)
    if "indices" in prim:
        idx = glb.accessor(prim["indices"], [(5125, "SCALAR"), (5123, "SCALAR"),
                                             (5121, "SCALAR")], where + " indices")
        if idx.size and idx.max() >= nv:
            raise GlbError(f"{where}: an index is past the {nv} vertices")
    t = np.stack([np.concatenate([attribute(glb, prim, f"_PRT_C{c}_{g}", "VEC4", nv, where)
                                  for g in range(groups)], axis=1)[:, :nn] for c in range(nch)])
    env = floats(need(ext, "environment", where), (None, 3), where + " environment")
    if env.shape[0] < nn:
        raise GlbError(f"{where}: environment has {env.shape[0]} coefficients, need {nn}")
    light = env[:nn]                                            # (n², 3)
    alb = need(ext, "albedo", where)
    if isinstance(alb, str):
        albedo = attribute(glb, prim, alb, "VEC3", nv, where)
    else:
        albedo = np.broadcast_to(floats(alb, (3,), where + " albedo"), (nv, 3)).copy()

    nh = nrm / np.linalg.norm(nrm, axis=1, keepdims=True)
    wo = eye[None, :] - pos
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    co = np.sum(nh * wo, axis=1)
    theta = np.minimum(np.arccos(np.clip(co, -1.0, 1.0)), math.pi / 2)

    kd = np.ones(nv)
    dfr = ext.get("diffuse_fresnel")
    if dfr is not None and fresnel:
        el = floats(need(dfr, "elevations", where + " diffuse_fresnel"), (None,), "elevations")
        va = floats(need(dfr, "values", where + " diffuse_fresnel"), (len(el),), "values")
        if len(el) == 0 or np.any(np.diff(el) <= 0):
            raise GlbError(f"{where}: diffuse_fresnel elevations empty or not increasing")
        kd = 1.0 - np.interp(theta, el, va)       # clamps to the end values outside
    rad = np.stack([albedo[:, c] * kd / math.pi * (t[c if nch == 3 else 0] @ light[:, c])
                    for c in range(3)], axis=1)
    mag = np.stack([np.abs(albedo[:, c] * kd) / math.pi
                    * (np.abs(t[c if nch == 3 else 0]) @ np.abs(light[:, c]))
                    for c in range(3)], axis=1)
    if mag_out is not None:
        mag_out.append(mag)

    spec = ext.get("specular")
    if spec is None or not specular:
        return rad
    ws = where + " specular"
    vnames = need(spec, "visibility_attributes", ws)
    if not isinstance(vnames, list) or len(vnames) != groups:
        raise GlbError(f"{ws}: visibility_attributes must name {groups} attributes")
    vis = np.concatenate([attribute(glb, prim, nm, "VEC4", nv, where) for nm in vnames],
                         axis=1)[:, :nn]
    pm = product_matrices(light, n)
    lv = np.einsum("cik,vk->cvi", pm, vis)                               # (3, nv, n²)
    rvec = 2.0 * co[:, None] * nh - wo
    bands = band_of(n)
    model = need(spec, "model", ws)
    if model == "phong":
        e = float(need(spec, "exponent", ws))
        ks = floats(need(spec, "specular", ws), (3,), ws + " specular")
        a_l = floats(need(spec, "bands", ws), (None,), ws + " bands")
        if len(a_l) < n:
            raise GlbError(f"{ws}: {len(a_l)} bands for order {n}")
        w = a_l[bands][None, :] * sh_eval(rvec, n)                        # (nv, n²)
        w_abs = np.abs(w)
        scale = ks[None, :] * ((e + 2) / (e + 1) * np.minimum(co, 1.0))[:, None]
    elif model == "fitted":
        w, scale, w_abs = fitted_lobes(glb, prim, spec, nh, rvec, theta, n, nv, ws)
    else:
        raise GlbError(f"{ws}: unknown model {model!r}")
    s = scale * np.einsum("vi,cvi->vc", w, lv)
    if mag_out is not None:
        s_abs = np.abs(scale) * np.einsum("vi,cvi->vc", w_abs,
                                          np.einsum("cik,vk->cvi", np.abs(pm), np.abs(vis)))
        mag_out[-1] = mag + np.where(co[:, None] > 0.0, s_abs, 0.0)
    return rad + np.where(co[:, None] > 0.0, s, 0.0)


def fitted_lobes(glb, prim, spec, nh, rvec, theta, n, nv, ws):
    """§10.1 "fitted": per-vertex weights w (nv, n²) and scale (nv, 3)."""
    el = floats(need(spec, "elevations", ws), (None,), ws + " elevations")
    rl = floats(need(spec, "roughness_levels", ws), (None,), ws + " roughness_levels")
    ne, nr = len(el), len(rl)
    axis = floats(need(spec, "axis", ws), (nr, ne, None), ws + " axis")
    k = axis.shape[2]
    ta = floats(need(spec, "bands", ws), (nr, ne, k, None), ws + " bands")
    bb = need(spec, "bands_b", ws)
    two = bb is not None and len(bb) > 0
    tb = floats(bb, ta.shape, ws + " bands_b") if two else np.zeros_like(ta)
    if ne == 0 or nr == 0 or ta.shape[3] < n:
        raise GlbError(f"{ws}: empty grid or table order {ta.shape[3]} below order {n}")
    if spec.get("lobes", k) != k or spec.get("table_order", ta.shape[3]) != ta.shape[3]:
        raise GlbError(f"{ws}: 'lobes'/'table_order' disagree with the shape of the tables")
    if np.any(np.diff(el) <= 0) or np.any(np.diff(rl) <= 0):
        raise GlbError(f"{ws}: elevations or roughness_levels not increasing")

    def per_vertex(key, atype):
        v = need(spec, key, ws)
        if isinstance(v, str):
            return attribute(glb, prim, v, atype, nv, ws)
        return np.broadcast_to(floats(v, (3,) if atype == "VEC3" else (), ws + " " + key),
                               (nv, 3) if atype == "VEC3" else (nv,))

    rough = per_vertex("roughness", "SCALAR").reshape(nv)
    ca = per_vertex("colour_a", "VEC3")
    cb = per_vertex("colour_b", "VEC3") if two else np.zeros((nv, 3))
    ie, te = locate(el, theta)
    ir, tr = locate(rl, rough)
    ir2 = ir + 1 if nr >= 2 else ir
    ie2 = np.minimum(ie + 1, ne - 1)              # a one-value grid: weight 0, any valid row
    rows = [(ir, ie, (1 - tr) * (1 - te)), (ir, ie2, (1 - tr) * te),
            (ir2, ie, tr * (1 - te)), (ir2, ie2, tr * te)]
    alpha = lum(ca) if two else np.ones(nv)
    beta = lum(cb) if two else np.zeros(nv)
    ahat, thk, ea, eb = np.zeros((nv, k, n)), np.zeros((nv, k)), np.zeros(nv), np.zeros(nv)
    ahat_abs = np.zeros((nv, k, n))
    for r_i, e_i, wgt in rows:
        ahat += wgt[:, None, None] * (alpha[:, None, None] * ta[r_i, e_i, :, :n]
                                      + beta[:, None, None] * tb[r_i, e_i, :, :n])
        ahat_abs += np.abs(wgt[:, None, None]) * (
            np.abs(alpha[:, None, None] * ta[r_i, e_i, :, :n])
            + np.abs(beta[:, None, None] * tb[r_i, e_i, :, :n]))
        thk += wgt[:, None] * axis[r_i, e_i]
        ea += wgt * ta[r_i, e_i, :, 0].sum(axis=1)
        eb += wgt * tb[r_i, e_i, :, 0].sum(axis=1)
    tv = rvec - np.sum(rvec * nh, axis=1, keepdims=True) * nh
    # A view along the normal: Duff et al. 2017's first basis vector ⟂ n̂ (§10.1 step 3).
    short = np.linalg.norm(tv, axis=1, keepdims=True) < 1e-6 * np.linalg.norm(rvec, axis=1,
                                                                                keepdims=True)
    sgn = np.where(np.signbit(nh[:, 2]), -1.0, 1.0)
    a = -1.0 / (sgn + nh[:, 2])
    duff = np.stack([nh[:, 0] * nh[:, 1] * a, sgn + nh[:, 1] ** 2 * a, -nh[:, 1]], axis=1)
    tv = np.where(short, duff, tv)
    that = tv / np.linalg.norm(tv, axis=1, keepdims=True)
    ax = (np.cos(thk)[:, :, None] * nh[:, None, :] + np.sin(thk)[:, :, None] * that[:, None, :])
    y_ax = sh_eval(ax, n)
    w = np.einsum("vki,vki->vi", ahat[:, :, band_of(n)], y_ax)
    w_abs = np.einsum("vki,vki->vi", ahat_abs[:, :, band_of(n)], np.abs(y_ax))
    if two:
        den = (alpha * ea + beta * eb)[:, None]
        num = ca * ea[:, None] + cb * eb[:, None]
        scale = np.where(den == 0.0, 0.0, num / np.where(den == 0.0, 1.0, den))
    else:
        scale = np.array(ca, dtype=np.float64)
    return w, scale, w_abs


def relight_file(path, eye=None, specular=True, fresnel=True, log=sys.stderr, mags=None):
    """[(mesh name, (nv, 3) radiance)] for every per-vertex mesh of a .glb (with a list
    `mags`, also appends [(mesh name, (nv, 3) magnitudes)]: see relight_primitive)."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise GlbError(f"cannot read: {exc.strerror}") from None
    glb = Glb(data)
    if eye is None:
        cam = need(need(need(glb.json, "extras", "the root"), "prt", "root extras"), "camera",
                   "root extras.prt")
        eye = need(cam, "eye", "extras.prt.camera")
    eye = floats(eye, (3,), "camera eye")
    out = []
    meshes = glb.json.get("meshes")
    if not isinstance(meshes, list) or not meshes:
        raise GlbError("no meshes")
    for mi, mesh in enumerate(meshes):
        name = mesh.get("name", f"mesh{mi}")
        prims = need(mesh, "primitives", f"mesh '{name}'")
        if not isinstance(prims, list) or len(prims) != 1:
            raise GlbError(f"mesh '{name}' must have exactly one primitive")
        ext = need(need(prims[0], "extras", f"mesh '{name}'"), "prt", f"mesh '{name}' extras")
        storage = need(ext, "storage", f"mesh '{name}' extras.prt")
        if storage == "lightmap":
            print(f"gltf_relight: {path}: mesh '{name}' is lightmapped: skipped", file=log)
            continue
        if storage != "vertex":
            raise GlbError(f"mesh '{name}': unknown storage {storage!r}")
        m = [] if mags is not None else None
        out.append((name, relight_primitive(glb, name, prims[0], eye, specular, fresnel, m)))
        if mags is not None:
            mags.append((name, m[0]))
    return out


def write_csv(path, results):
    with open(path, "w") as fh:
        fh.write("object,point,r,g,b\n")
        for name, rad in results:
            for i, (r, g, b) in enumerate(rad.tolist()):
                fh.write(f"{name},{i},{r!r},{g!r},{b!r}\n")


def compare(results, ref_path, worst=3):
    ref = {}
    with open(ref_path) as fh:
        next(fh)
        for line in fh:
            name, idx, r, g, b = line.rstrip("\n").rsplit(",", 4)
            ref.setdefault(name, {})[int(idx)] = (float(r), float(g), float(b))
    overall = 0.0
    for name, rad in results:
        if name not in ref or len(ref[name]) != len(rad):
            print(f"  {name}: {len(rad)} vertices, reference has {len(ref.get(name, {}))}")
            overall = math.inf
            continue
        rr = np.array([ref[name][i] for i in range(len(rad))])
        peak = np.maximum(np.abs(rr).max(axis=0), 1e-300)
        rel = np.abs(rad - rr) / peak                                 # (nv, 3)
        per = rel.max(axis=1)
        overall = max(overall, per.max())
        print(f"  {name}: {len(rad)} vertices, max rel diff r/g/b = "
              + "/".join(f"{v:.2e}" for v in rel.max(axis=0)) + f" (peak {peak.max():.4g})")
        for v in np.argsort(-per)[:worst]:
            print(f"    vertex {v}: ours {rad[v].tolist()} prt {rr[v].tolist()}")
    return overall


# ----------------------------------------------------------------------------------------------
# Self-test
# ----------------------------------------------------------------------------------------------
def sh_closed_form(dirs, n):
    """y_i from the textbook formula (factorials, Legendre-polynomial derivatives, atan2)."""
    d = dirs / np.linalg.norm(dirs, axis=1, keepdims=True)
    z, phi, st = d[:, 2], np.arctan2(d[:, 1], d[:, 0]), np.hypot(d[:, 0], d[:, 1])
    out = np.zeros((len(d), n * n))
    for l in range(n):
        for m in range(l + 1):
            dp = np.polynomial.legendre.legder([0.0] * l + [1.0], m) if m else [0.0] * l + [1.0]
            p = (-1) ** m * st ** m * np.polynomial.legendre.legval(z, dp)
            k = math.sqrt((2 * l + 1) / FOUR_PI * math.factorial(l - m) / math.factorial(l + m))
            c = l * (l + 1)
            if m == 0:
                out[:, c] = k * p
            else:
                out[:, c + m] = math.sqrt(2) * k * p * np.cos(m * phi)
                out[:, c - m] = math.sqrt(2) * k * p * np.sin(m * phi)
    return out


def make_glb(doc, binary):
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = struct.pack("<II", len(js), 0x4E4F534A) + js + struct.pack("<II", len(binary),
                                                                         0x004E4942) + binary
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


def self_test():
    fails, checks = [], 0

    def check(ok, what):
        nonlocal checks
        checks += 1
        if not ok:
            fails.append(what)

    rng = np.random.default_rng(7)
    # SH basis: orthonormal under the quadrature at order 12, and against closed forms.
    dirs, w = sphere_grid(3 * 11)
    y = sh_eval(dirs, 12)
    check(np.abs(y.T @ (y * w[:, None]) - np.eye(144)).max() < 1e-12, "orthonormality order 12")
    pts = rng.normal(size=(50, 3))
    pts = np.concatenate([pts, [[0, 0, 1.0], [0, 0, -1.0], [1e-9, 0, 1.0], [1.0, 0, 0]]])
    check(np.abs(sh_eval(pts, 11) - sh_closed_form(pts, 11)).max() < 1e-11,
          "recurrence vs factorial closed form, l <= 10")
    u = pts[0] / np.linalg.norm(pts[0])
    x, yy, z = u
    ys = sh_eval(u, 4)
    c1 = math.sqrt(3 / FOUR_PI)
    known = {0: 0.5 / math.sqrt(math.pi), 1: -c1 * yy, 2: c1 * z, 3: -c1 * x,
             4: 0.5 * math.sqrt(15 / math.pi) * x * yy,                       # y_2^-2
             7: -0.5 * math.sqrt(15 / math.pi) * x * z,                       # y_2^1
             8: 0.25 * math.sqrt(15 / math.pi) * (x * x - yy * yy),           # y_2^2
             9: -0.25 * math.sqrt(35 / (2 * math.pi)) * yy * (3 * x * x - yy * yy),   # y_3^-3
             14: 0.25 * math.sqrt(105 / math.pi) * z * (x * x - yy * yy)}     # y_3^2
    for i, v in known.items():
        check(abs(ys[i] - v) < 1e-14, f"y_{i} closed form")
    # SH product by quadrature: a constant light (c, 2c, 3c per channel) times V = c/(2√π) V.
    for n in (1, 3, 6):
        v, lc = rng.normal(size=n * n), np.zeros((n * n, 3))
        lc[0] = [1.7, 3.4, 5.1]
        got = product_matrices(lc, n) @ v
        check(np.abs(got - lc[0][:, None] / (2 * math.sqrt(math.pi)) * v).max() < 1e-13,
              f"constant x V, order {n}")

    def sh_product(a, b, n):
        return product_matrices(a[:, None], n)[0] @ b

    lr, vr = rng.normal(size=36), rng.normal(size=36)   # exactness: the grid of degree 15
    dirs, w = sphere_grid(3 * 5 + 12)                     # agrees with a much finer one
    yf = sh_eval(dirs, 6)
    fine = yf.T @ (w * (yf @ lr) * (yf @ vr))
    check(np.abs(sh_product(lr, vr, 6) - fine).max() < 1e-13, "product grid is exact")
    zc = np.zeros(9)
    zc[2] = math.sqrt(FOUR_PI / 3)                     # the function z
    want = np.zeros(9)
    want[0] = math.sqrt(FOUR_PI) / 3                   # 1/3
    want[6] = 2 / 3 * math.sqrt(FOUR_PI / 5)           # (2/3) P_2(z)
    check(np.abs(sh_product(zc, zc, 3) - want).max() < 1e-14, "z*z = 1/3 + 2/3 P2")
    check(np.abs(sh_product(zc[:4], zc[:4], 2) - want[:4]).max() < 1e-14, "z*z truncated")
    xc, yc = np.zeros(9), np.zeros(9)
    xc[3], yc[1] = -math.sqrt(FOUR_PI / 3), -math.sqrt(FOUR_PI / 3)
    want = np.zeros(9)
    want[4] = 2 * math.sqrt(math.pi / 15)              # xy = y_2^-2 / (½√(15/π))
    check(np.abs(sh_product(xc, yc, 3) - want).max() < 1e-14, "x*y = y_2^-2 multiple")
    # Phong band multipliers: closed forms for l = 0, 1, 2 (∫ x^e P_l) and e = 1 exactly.
    for e in (0.0, 1.0, 2.0, 7.0, 30.0):
        a = phong_bands(e, 3)
        cf = [1.0, (e + 1) / (e + 2), (e + 1) / 2 * (3 / (e + 3) - 1 / (e + 1))]
        check(np.abs(a - cf).max() < 1e-12, f"phong bands e={e}")
    a = phong_bands(1.0, 5)                            # e = 1: cosine lobe / π
    check(np.abs(a - [1, 2 / 3, 1 / 4, 0, -1 / 24]).max() < 1e-13, "phong e=1 = A_l/π")
    # Bilinear locate (§10.1 step 1) edge cases.
    g = [0.0, 0.5, 1.0, 2.0]
    i, t = locate(g, [-1.0, 0.0, 0.25, 0.5, 1.5, 2.0, 3.0])
    check(i.tolist() == [0, 0, 0, 1, 2, 2, 2], f"locate index {i.tolist()}")
    check(np.allclose(t, [0, 0, 0.5, 0, 0.5, 1, 1], atol=0, rtol=1e-15), f"locate t {t}")
    i, t = locate([0.3], [-5.0, 0.3, 9.0])
    check(i.tolist() == [0, 0, 0] and t.tolist() == [0, 0, 0], "locate one-value grid")
    i, t = locate([1.0, 2.0], [1.0, 1.999, 2.0])
    check(i.tolist() == [0, 0, 0] and abs(t[1] - 0.999) < 1e-12 and t[2] == 1, "locate 2 pts")
    # A tiny synthetic .glb: parsing, diffuse with k_d, Phong with full visibility (vis = 1).
    nn = 4
    posn = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], dtype="<f4")
    nrm = np.array([[0, 0, 1]] * 3, dtype="<f4")
    tr = rng.uniform(0.1, 1, size=(3, nn)).astype("<f4")
    vis = np.zeros((3, nn), dtype="<f4")
    vis[:, 0] = 2 * math.sqrt(math.pi)                 # vis = 1 everywhere
    blobs = [posn, nrm, tr, vis, np.array([0, 1, 2], dtype="<u4")]
    binary, views, accs = b"", [], []
    kinds = [("VEC3", F), ("VEC3", F), ("VEC4", F), ("VEC4", F), ("SCALAR", 5125)]
    for b, (typ, ct) in zip(blobs, kinds):
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": b.nbytes})
        accs.append({"bufferView": len(views) - 1, "componentType": ct,
                     "count": b.shape[0], "type": typ})
        binary += b.tobytes()
    env = rng.uniform(-1, 1, size=(9, 3)).tolist()
    prt = {"order": 2, "channels": 1, "storage": "vertex", "environment": env,
           "albedo": [0.8, 0.5, 0.2],
           "diffuse_fresnel": {"elevations": [0.0, 1.0], "values": [0.1, 0.3]},
           "specular": {"model": "phong", "exponent": 3.0, "specular": [0.5, 0.25, 1.0],
                        "bands": phong_bands(3.0, 2).tolist(),
                        "visibility_attributes": ["_PRT_V_0"]}}
    doc = {"asset": {"version": "2.0"}, "extras": {"prt": {"camera": {"eye": [0, 0, 2.0]}}},
           "buffers": [{"byteLength": len(binary)}], "bufferViews": views, "accessors": accs,
           "materials": [{"pbrMetallicRoughness": {"baseColorFactor": [0.8, 0.5, 0.2, 1]}}],
           "meshes": [{"name": "tri", "primitives": [{
               "attributes": {"POSITION": 0, "NORMAL": 1, "_PRT_C0_0": 2, "_PRT_V_0": 3},
               "indices": 4, "material": 0, "extras": {"prt": prt}}]}]}
    glb = Glb(make_glb(doc, binary))
    rad = relight_primitive(glb, "tri", doc["meshes"][0]["primitives"][0], np.array([0, 0, 2.]))
    p = posn[1].astype(float)
    wo = np.array([0, 0, 2.0]) - p
    wo /= np.linalg.norm(wo)
    co = wo[2]
    kd = 1 - (0.1 + 0.2 * math.acos(co))
    r = 2 * co * np.array([0, 0, 1.0]) - wo
    yr = sh_eval(r, 2) * phong_bands(3.0, 2)[[0, 1, 1, 1]] * (float(vis[1, 0]) / FOUR_PI ** .5)
    d = np.array([0.8, 0.5, 0.2]) * kd / math.pi * (tr[1].astype(float) @ np.array(env)[:nn])
    s = np.array([0.5, 0.25, 1.0]) * 5 / 4 * co * (yr @ np.array(env)[:nn])
    check(np.abs(rad[1] - d - s).max() < 1e-13, "synthetic vertex, phong")
    # The same lobe as a "fitted" table (one elevation, axis = this vertex's θ_o), one shape,
    # then two identical shapes (α = β = lum(a): twice the lobe).
    ka = (np.array([0.5, 0.25, 1.0]) * 5 / 4 * co).tolist()
    prt["specular"] = {"model": "fitted", "elevations": [0.3], "roughness_levels": [0.5],
                       "axis": [[[math.acos(co)]]], "bands": [[[phong_bands(3.0, 2).tolist()]]],
                       "bands_b": [], "colour_a": ka, "colour_b": None, "roughness": 0.5,
                       "visibility_attributes": ["_PRT_V_0"]}
    rad = relight_primitive(glb, "tri", doc["meshes"][0]["primitives"][0], np.array([0, 0, 2.]))
    check(np.abs(rad[1] - d - s).max() < 1e-13, "synthetic vertex, fitted one shape")
    prt["specular"].update(bands_b=prt["specular"]["bands"], colour_b=ka)
    rad = relight_primitive(glb, "tri", doc["meshes"][0]["primitives"][0], np.array([0, 0, 2.]))
    check(np.abs(rad[1] - d - 2 * s).max() < 1e-13, "synthetic vertex, fitted two shapes")
    sp = prt["specular"]                 # two roughness levels, the second lobe 0: half of it
    sp.update(roughness_levels=[0.2, 0.8], axis=sp["axis"] * 2, bands=sp["bands"] + [[[[0, 0]]]],
              bands_b=sp["bands"] + [[[[0, 0]]]])
    rad = relight_primitive(glb, "tri", doc["meshes"][0]["primitives"][0], np.array([0, 0, 2.]))
    check(np.abs(rad[1] - d - s).max() < 1e-13, "synthetic vertex, fitted roughness bilinear")
    good = make_glb(doc, binary)
    for bad, what in [(good[:-4], "truncated"), (b"glTX" + good[4:], "magic"),
                      (good[:16] + b"X" + good[17:], "chunk type")]:
        try:
            Glb(bad)
            check(False, f"malformed file accepted ({what})")
        except GlbError:
            check(True, what)
    del doc["meshes"][0]["primitives"][0]["attributes"]["_PRT_V_0"]
    try:
        g2 = Glb(make_glb(doc, binary))
        relight_primitive(g2, "tri", doc["meshes"][0]["primitives"][0], np.array([0, 0, 2.]))
        check(False, "missing _PRT_V_0 accepted")
    except GlbError:
        check(True, "missing attribute")
    status = "PASS" if not fails else "FAIL (" + "; ".join(fails) + ")"
    print(f"gltf_relight self-test: {checks - len(fails)}/{checks} checks passed: {status}")
    return 0 if not fails else 1


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("glb", nargs="?")
    ap.add_argument("--colours", help="write per-vertex radiance CSV here")
    ap.add_argument("--eye", help="X,Y,Z (default: root extras.prt.camera.eye)")
    ap.add_argument("--compare", help="prt's CSV to compare with")
    ap.add_argument("--magnitudes", help="write per-vertex term magnitudes (same CSV layout): "
                    "the sums with every factor's absolute value, for float32 error bounds")
    ap.add_argument("--no-specular", action="store_true")
    ap.add_argument("--no-fresnel", action="store_true")
    ap.add_argument("--self-test", action="store_true")
    args = ap.parse_args(argv)
    if args.self_test:
        return self_test()
    if not args.glb or not (args.colours or args.compare):
        ap.error("need ASSET.glb and --colours OUT.csv (or --compare REF.csv)")
    eye = None
    if args.eye:
        try:
            eye = [float(v) for v in args.eye.split(",")]
            assert len(eye) == 3
        except (ValueError, AssertionError):
            ap.error("--eye takes X,Y,Z")
    try:
        mags = [] if args.magnitudes else None
        res = relight_file(args.glb, eye, not args.no_specular, not args.no_fresnel,
                           mags=mags)
    except GlbError as exc:
        print(f"gltf_relight: {args.glb}: {exc}", file=sys.stderr)
        return 1
    except (KeyError, TypeError, ValueError, IndexError, AttributeError) as exc:
        print(f"gltf_relight: {args.glb}: malformed ({type(exc).__name__}: {exc})",
              file=sys.stderr)
        return 1
    if args.colours:
        write_csv(args.colours, res)
    if args.magnitudes:
        write_csv(args.magnitudes, mags)
    if args.compare:
        print(f"{args.glb} vs {args.compare}:")
        worst = compare(res, args.compare)
        if worst >= 1e-3:
            print(f"gltf_relight: {args.glb}: differs from {args.compare} by {worst:.3g} "
                  "(relative, >= 1e-3)", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
