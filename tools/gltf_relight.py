#!/usr/bin/env python3
"""Independent relighter of `prt export` glTF files (per-vertex and lightmapped objects).

Written from `crates/bakefile/SPEC.md` §1 (SH convention), §10 (glTF export), §10.1
(view-dependent shading), §10.2 (GPU targets: the data-texture layout) and `CONVENTIONS.md`
("Spherical harmonics") ALONE (plus §3.1's definition of a covered texel, for `--texels
covered`): no Rust source of prt was read, and nothing of prt is imported or called, so a
disagreement with `prt relight` points at a bug in one of them or at a gap in the SPEC. Needs
Python 3 and numpy only (PNGs are decoded here with zlib).

Per-vertex meshes (`extras.prt.storage == "vertex"`, or "vertex_texture" below): each vertex's
radiance `D_c + S_c` (§10.1):
  * diffuse `D_c = albedo_c · k_d · (1/π) Σ_i t[c or 0][i] · environment[i][c]` (one channel:
    `_PRT_C0_*` for R, G and B; three channels, a bounced bake: `_PRT_C{c}_*` against
    environment channel c), albedo = `extras.prt.albedo` (RGB, or the name of a per-vertex VEC3
    attribute), `k_d = 1 − s̄_d(θ_o)` (piecewise linear in θ_o) or 1;
  * specular `S_c = scale_c · Σ_i w_i (L_c ⊛ V)_i` for lobe models "phong" and "fitted", V the
    ONE-channel visibility `_PRT_V_*` whatever the object's channels.
    The SH product `L ⊛ V` is NOT computed from Gaunt coefficients but by quadrature: the
    truncated lighting and visibility are evaluated on a Gauss–Legendre (cos θ) × uniform-φ
    grid that integrates polynomials of degree 3(n−1) exactly, multiplied and projected back
    (per channel as the matrix M_c[i][k] = Σ_q w_q y_i L_c y_k, then M_c V per vertex).
  * an environment with fewer rows than n² (order n_e < n, §10) is summed over its rows and
    the view-dependent terms are shaded at order min(n, n_e).
  * `storage == "vertex_texture"` (§10.2, `--target webgl2|desktop`): the same object, relit
    by the same formulas, but t and V come from the FLOAT VEC4 accessor of W·H texels named
    by `extras.prt.transfer_texture`: coefficient i of channel c of the vertex whose
    `_PRT_VERTEX_ID` (the attribute `vertex_id` names) is v is component i mod 4 of texel
    k = v·P + channel_texels[c] + ⌊i/4⌋ (column k mod W, row ⌊k/W⌋; V at visibility_texel).
    The ids must be exact integers in 0 … nv−1 (rows index the texture by their id, not by
    their position); the layout must agree with order and channels (G = ⌈n²/4⌉,
    channel_texels = c·G, visibility_texel = C·G exactly when there is a lobe, P = C·G (+G)),
    the accessor must hold W·H texels, W ≤ V·P and H = ⌈V·P/W⌉ (the target's limit is not in
    the file), padding (components past n², texels past V·P) must be 0 and there must be no
    `_PRT_C*`/`_PRT_V_*` attributes — else the file is refused naming the mesh.
Lightmapped meshes (`storage == "lightmap"`, §10 "Per-texel (lightmap) bakes"): the RGBA8 PNG
of `lightmap.textures[c][g]` is decoded (own decoder: chunk CRCs, IDAT inflated with zlib,
filter types 0–4; anything but 8-bit colour type 6, not interlaced, is refused naming the
image), texel (x, y) = PNG row y, column x, component j = coefficient 4g + j, dequantised as
`t = offset[c][i] + scale[c][i]·code/255`, and relit with the diffuse formula only
(`albedo_c/π Σ_i t[c or 0][i] env[i][c]`: lightmapped objects have no view-dependent terms).
Its rows have `point` = texel index `y·W + x`.
  * Which texels? The glb stores only the COUNT of covered texels (`covered_texels`), and the
    uncovered ones are dilated from their neighbours, so the textures do not tell them apart.
    `--texels all` (the default) writes every texel. `--texels covered` writes the texels a
    `TEXCOORD_0` triangle touches, by §3.1's conservative rasterisation (texel (x, y) the closed
    square [x/W, (x+1)/W] × [y/H, (y+1)/H], exact separating-axis test). §3.1 does not say
    whether a triangle touching a square only along its edge or at a corner covers it: when
    the closed count differs from `covered_texels` and the count without such contacts equals
    it, that stricter set is used (noted on stderr); when neither agrees, stderr says so and
    the closed set is written.
  * A per-vertex albedo (`"_PRT_ALBEDO"`) is interpolated at the texel's surface point as §3.1
    defines it (the centre if a triangle holds it, else the nearest point of a touching
    triangle; for an uncovered texel the nearest point of any triangle) — an approximation:
    the SPEC does not say which albedo prt shades a texel with.
Real SH (orthonormal, Condon–Shortley phase, index l(l+1)+m, θ from +Z, φ = atan2(y, x)) come
from a normalised associated-Legendre recurrence times Re/Im (x + iy)^m (no atan2, stable at
the poles). All arithmetic is float64.

Usage:
    python3 tools/gltf_relight.py ASSET.glb --colours OUT.csv [--eye X,Y,Z]
            [--compare REF.csv] [--magnitudes MAG.csv] [--quantisation Q.csv]
            [--texels all|covered] [--no-specular] [--no-fresnel]
    python3 tools/gltf_relight.py --self-test
Every CSV has prt's layout `object,point,r,g,b` (header line, floats as repr()): per mesh in
file order, one row per vertex (point = vertex index) or per selected texel (point = y·W + x,
increasing); the three files list the same rows in the same order.
  * `--colours`: the radiance.
  * `--magnitudes`: each sum with every factor replaced by its absolute value: a float32
    evaluation of the formula is within γ_N = N·2⁻²⁴ of those (N the longest chain of
    roundings), which is how a test bounds the difference from prt. For texels the sums use
    the dequantised t (prt's unquantised |t| is at most scale/510 larger: bound the f32 error by
    γ_N·(MAG + Q)).
  * `--quantisation`: per texel and channel `Σ_i (scale[c][i]/510)·|albedo_c/π · env[i][c]|`,
    the bound on |radiance error| due to the 8-bit codes (half a code step per coefficient,
    assuming prt rounds to nearest); 0.0 for per-vertex rows. So |ours − prt's unquantised
    texel radiance| ≤ Q + γ_N·(MAG + Q) (+ our float64 rounding).
`--compare` prints, per object, the max |ours − ref| relative to the max of ref per channel and
the worst points. Vertices must match one to one; lightmapped objects are compared on the texels
both files hold (ours missing from the reference are counted; the reference's missing from ours
must be 0 — a texel no triangle touches has zero transfer). `--no-specular` / `--no-fresnel`
drop S_c / k_d (for diagnosis); `--eye` replaces the root `extras.prt.camera.eye`.
Exit status 1 on a malformed file (one line naming the file; a bad PNG names its image), 2 when
`--compare` finds a relative difference >= 1e-3 (or points that do not match), 0 otherwise.
"""
import argparse
import json
import math
import os
import struct
import sys
import tempfile
import zlib

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

    def view_bytes(self, idx, what):
        """The bytes of bufferView `idx` (in the BIN chunk)."""
        bv = self._item("bufferViews", idx)
        if need(bv, "buffer", f"bufferView {idx}") != 0 or not self.bin:
            raise GlbError(f"{what}: buffer is not the GLB BIN chunk")
        off, length = bv.get("byteOffset", 0), need(bv, "byteLength", f"bufferView {idx}")
        if not isinstance(off, int) or not isinstance(length, int) or off < 0 or length < 0 \
                or off + length > len(self.bin):
            raise GlbError(f"{what}: bufferView {idx} runs past the BIN chunk")
        return self.bin[off:off + length]

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
    if ext.get("storage", "vertex") == "vertex_texture":            # §10.2
        t, vis_tex = vertex_texture(glb, prim, ext, n, nch, nv, where)
    else:
        t = np.stack([np.concatenate([attribute(glb, prim, f"_PRT_C{c}_{g}", "VEC4", nv, where)
                                      for g in range(groups)], axis=1)[:, :nn]
                      for c in range(nch)])
        vis_tex = None
    light, ns = environment(ext, n, where)                      # (min(n², n_e²), 3)
    ne = light.shape[0]
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
    rad = np.stack([albedo[:, c] * kd / math.pi * (t[c if nch == 3 else 0][:, :ne] @ light[:, c])
                    for c in range(3)], axis=1)
    mag = np.stack([np.abs(albedo[:, c] * kd) / math.pi
                    * (np.abs(t[c if nch == 3 else 0][:, :ne]) @ np.abs(light[:, c]))
                    for c in range(3)], axis=1)
    if mag_out is not None:
        mag_out.append(mag)

    spec = ext.get("specular")
    if spec is None or not specular:
        return rad
    # The view-dependent terms are at order ns = min(n, n_e) (§10 "Environment with fewer
    # coefficients"); `visibility_attributes` then names ⌈ns²/4⌉ groups (up to ⌈n²/4⌉ are
    # accepted: the SPEC does not say how many).
    ws = where + " specular"
    n, nn = ns, ns * ns
    if vis_tex is not None:                     # §10.2: n² (object order) coefficients
        vis = vis_tex[:, :nn]
    else:
        vnames = need(spec, "visibility_attributes", ws)
        if not isinstance(vnames, list) or not (nn + 3) // 4 <= len(vnames) <= groups:
            raise GlbError(f"{ws}: visibility_attributes must name {(nn + 3) // 4} attributes")
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


def vertex_texture(glb, prim, ext, n, nch, nv, where):
    """§10.2 `storage: "vertex_texture"`: (t (nch, nv, n²), visibility (nv, n²) or None) read
    from the RGBA32F data texture `extras.prt.transfer_texture` (a FLOAT VEC4 accessor of W·H
    texels, row by row): coefficient i of channel c of the vertex whose `_PRT_VERTEX_ID` is v
    is component i mod 4 of texel k = v·P + channel_texels[c] + ⌊i/4⌋ (column k mod W, row
    ⌊k/W⌋), the visibility's of texel v·P + visibility_texel + ⌊i/4⌋. Row r of the primitive
    reads the texels of its id, which must be an exact integer in 0 … nv−1 (§10.2 makes it
    the vertex index; that it equals r is not assumed). Refused (GlbError naming the mesh):
    a field missing or inconsistent with order and channels (G = ⌈n²/4⌉, channel_texels[c] =
    c·G, visibility_texel = C·G exactly when there is a specular lobe, P = C·G (+ G)), an
    accessor count other than W·H, W·H < V·P or H ≠ ⌈V·P/W⌉ (the target's limit is not in
    the file, so W = min(limit, V·P) is checked only as W ≤ V·P), non-zero padding
    (components past n², texels past V·P), and `_PRT_C*` / `_PRT_V_*` attributes or
    non-empty `attributes` / `visibility_attributes` (§10.2: they are `[]`)."""
    tw = where + " extras.prt.transfer_texture"
    tt = need(ext, "transfer_texture", where + " extras.prt")
    if not isinstance(tt, dict):
        raise GlbError(f"{tw} is not an object (storage 'vertex_texture' needs one)")

    def integer(key, lo):
        v = need(tt, key, tw)
        if not isinstance(v, int) or isinstance(v, bool) or v < lo:
            raise GlbError(f"{tw}: {key} {v!r} is not an integer >= {lo}")
        return v

    nn = n * n
    g_want = (nn + 3) // 4
    width, height = integer("width", 1), integer("height", 1)
    p_tex, groups = integer("texels_per_vertex", 1), integer("groups", 1)
    fmt = need(tt, "format", tw)
    if fmt != "RGBA32F":
        raise GlbError(f"{tw}: format {fmt!r}, expected 'RGBA32F'")
    if groups != g_want:
        raise GlbError(f"{tw}: groups {groups}, but order {n} needs G = ceil({nn}/4) = {g_want}")
    ct = need(tt, "channel_texels", tw)
    ct_want = [c * groups for c in range(nch)]
    if not isinstance(ct, list) or any(isinstance(v, bool) or not isinstance(v, int)
                                       for v in ct) or ct != ct_want:
        raise GlbError(f"{tw}: channel_texels {ct!r}, expected {ct_want} (c·G for the {nch} "
                       "channels)")
    vt = need(tt, "visibility_texel", tw)
    spec = ext.get("specular")
    if vt is None:
        if spec is not None:
            raise GlbError(f"{tw}: visibility_texel is null but the primitive has a specular "
                           "lobe, which needs the visibility transfer (§10.1)")
    else:
        if isinstance(vt, bool) or not isinstance(vt, int) or vt != nch * groups:
            raise GlbError(f"{tw}: visibility_texel {vt!r}, expected C·G = {nch * groups} (the "
                           f"G texels after the {nch} channels' within P)")
        if spec is None:
            raise GlbError(f"{tw}: visibility_texel {vt} but specular is null (§10.2: the "
                           "visibility is in the texture only with a specular lobe)")
    p_want = nch * groups + (groups if vt is not None else 0)
    if p_tex != p_want:
        raise GlbError(f"{tw}: texels_per_vertex {p_tex}, expected {p_want} (C·G"
                       + (" + G with visibility)" if vt is not None else ", no visibility)"))
    used = nv * p_tex
    if width * height < used or width > used or height != -(-used // width):
        raise GlbError(f"{tw}: {width}x{height} texels for {nv} vertices of {p_tex} texels "
                       f"(§10.2: W = min(limit, V·P) <= {used}, H = ceil(V·P/W))")
    acc = need(tt, "accessor", tw)
    texels = glb.accessor(acc, [(F, "VEC4")], f"{where} transfer_texture")
    if texels.shape[0] != width * height:
        raise GlbError(f"{tw}: accessor {acc} has {texels.shape[0]} texels, W·H = "
                       f"{width}x{height} = {width * height}")
    if np.any(texels[used:] != 0.0):
        k = used + int(np.flatnonzero(np.any(texels[used:] != 0.0, axis=1))[0])
        raise GlbError(f"{tw}: texel {k} past the last vertex's (V·P = {used}) is not 0")
    attrs = need(prim, "attributes", where)
    extra = sorted(a for a in attrs if a.startswith("_PRT_C") or a.startswith("_PRT_V_"))
    if extra or ext.get("attributes", []) != []:
        raise GlbError(f"{where}: storage 'vertex_texture' with transfer attributes "
                       f"{extra or ext.get('attributes')} (§10.2: none, `attributes` is [])")
    if spec is not None and spec.get("visibility_attributes", []) != []:
        raise GlbError(f"{where} specular: visibility_attributes "
                       f"{spec['visibility_attributes']!r} with storage 'vertex_texture' "
                       "(§10.2: [])")
    name = need(tt, "vertex_id", tw)
    if not isinstance(name, str):
        raise GlbError(f"{tw}: vertex_id {name!r} is not an attribute name")
    vid = attribute(glb, prim, name, "SCALAR", nv, where).reshape(nv)
    bad = np.flatnonzero((vid != np.floor(vid)) | (vid < 0) | (vid >= nv))
    if len(bad):
        raise GlbError(f"{where}: {name} of vertex {bad[0]} is {float(vid[bad[0]])!r}, not an "
                       f"integer vertex index in 0..{nv - 1}")
    grid = texels.reshape(height, width, 4)

    def slot(ids, first):
        """(len(ids), 4G) components of texels id·P + first + g, g < G (column k mod W,
        row ⌊k/W⌋)."""
        k = ids[:, None] * p_tex + first + np.arange(groups)[None, :]
        return grid[k // width, k % width].reshape(len(ids), 4 * groups)

    slots = [("channel", c, ct[c]) for c in range(nch)]
    slots += [("visibility", 0, vt)] if vt is not None else []
    every = np.arange(nv)
    for kind, c, first in slots:                 # padding: components past n² are 0
        pad = slot(every, first)[:, nn:]
        if np.any(pad != 0.0):
            v = int(np.flatnonzero(np.any(pad != 0.0, axis=1))[0])
            raise GlbError(f"{tw}: vertex {v}'s {kind} {c} texels hold a non-zero component "
                           f"past coefficient {nn - 1} (n² = {nn})")
    ids = vid.astype(np.int64)
    t = np.stack([slot(ids, ct[c])[:, :nn] for c in range(nch)])
    vis = slot(ids, vt)[:, :nn] if vt is not None else None
    return t, vis


def environment(ext, n, where):
    """(extras.prt.environment truncated to n² rows, ns): an environment of order n_e < n holds
    only n_e² rows (§10), and the sums run over them (missing coefficients count as 0); ns =
    min(n, n_e) is the order of the view-dependent terms."""
    env = floats(need(ext, "environment", where), (None, 3), where + " environment")
    if not np.all(np.isfinite(env)):
        raise GlbError(f"{where}: environment holds a non-finite value")
    nn = n * n
    if env.shape[0] >= nn:
        return env[:nn], n
    ne = math.isqrt(env.shape[0])
    if ne < 1 or ne * ne != env.shape[0]:
        raise GlbError(f"{where}: environment has {env.shape[0]} coefficients: neither the "
                       f"object's {nn} nor a square n_e² < {nn}")
    return env, ne


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


# ----------------------------------------------------------------------------------------------
# PNG decoding (RGBA8, the lightmap textures of §10)
# ----------------------------------------------------------------------------------------------
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"


def decode_png(data, what):
    """(H, W, 4) uint8 texels of a PNG: 8-bit RGBA (colour type 6), not interlaced, filter
    types 0–4 (None, Sub, Up, Average, Paeth; ISO/IEC 15948 §9). Chunk CRCs are checked, the
    IDAT chunks are concatenated and inflated, and the inflated size must be exactly
    H·(1 + 4W). Anything else raises GlbError naming `what` (the image)."""
    def bad(msg):
        return GlbError(f"{what}: {msg}")

    data = bytes(data)
    if data[:8] != PNG_SIGNATURE:
        raise bad("not a PNG (bad signature)")
    pos, ihdr, idat, iend = 8, None, [], False
    while pos < len(data):
        if pos + 12 > len(data):
            raise bad(f"truncated chunk header at byte {pos}")
        length, ctype = struct.unpack_from(">I4s", data, pos)
        name = ctype.decode("latin-1")
        if length > 0x7FFFFFFF or pos + 12 + length > len(data):
            raise bad(f"chunk {name!r} at byte {pos} runs past the end (truncated)")
        body = data[pos + 8:pos + 8 + length]
        (crc,) = struct.unpack_from(">I", data, pos + 8 + length)
        if zlib.crc32(ctype + body) & 0xFFFFFFFF != crc:
            raise bad(f"CRC mismatch in chunk {name!r} at byte {pos}")
        pos += 12 + length
        if ihdr is None and ctype != b"IHDR":
            raise bad(f"first chunk is {name!r}, not IHDR")
        if ctype == b"IHDR":
            if ihdr is not None or length != 13:
                raise bad("second IHDR chunk or IHDR not 13 bytes")
            ihdr = struct.unpack(">IIBBBBB", body)
        elif ctype == b"IDAT":
            idat.append(body)
        elif ctype == b"IEND":
            iend = True
            break                                    # bytes after IEND are ignored
        elif ctype != b"PLTE" and not ctype[0] & 0x20:  # PLTE: a suggested palette, unused
            raise bad(f"unknown critical chunk {name!r}")
    if ihdr is None:
        raise bad("no IHDR chunk")
    if not iend:
        raise bad("no IEND chunk (truncated file)")
    width, height, depth, colour, comp, filt, interlace = ihdr
    if depth != 8 or colour != 6:
        raise bad(f"bit depth {depth}, colour type {colour}: only 8-bit RGBA (colour type 6) "
                  "is supported")
    if width == 0 or height == 0 or comp != 0 or filt != 0 or interlace != 0:
        raise bad(f"size {width}x{height}, compression {comp}, filter method {filt}, interlace "
                  f"{interlace}: need a non-empty image, 0, 0 and no interlace")
    if not idat:
        raise bad("no IDAT chunk")
    inflater = zlib.decompressobj()
    try:
        raw = inflater.decompress(b"".join(idat)) + inflater.flush()
    except zlib.error as exc:
        raise bad(f"IDAT does not inflate ({exc})") from None
    if not inflater.eof:
        raise bad("IDAT zlib stream is truncated")
    if inflater.unused_data:
        raise bad(f"{len(inflater.unused_data)} bytes after the IDAT zlib stream")
    stride = 4 * width
    if len(raw) != height * (stride + 1):
        raise bad(f"IDAT inflates to {len(raw)} bytes, {width}x{height} RGBA8 needs "
                  f"{height * (stride + 1)}")
    rows = np.frombuffer(raw, dtype=np.uint8).reshape(height, stride + 1)
    out = np.zeros((height, stride), dtype=np.uint8)
    prior = np.zeros(stride, dtype=np.int64)
    for y in range(height):
        ftype, f = int(rows[y, 0]), rows[y, 1:].astype(np.int64)
        if ftype == 0:                                               # None
            cur = f
        elif ftype == 1:                                             # Sub: + left (4 bytes back)
            cur = np.cumsum(f.reshape(width, 4), axis=0).reshape(-1) % 256
        elif ftype == 2:                                             # Up: + above
            cur = (f + prior) % 256
        elif ftype in (3, 4):                                        # Average, Paeth: sequential
            fb, up, rec = f.tolist(), prior.tolist(), [0] * stride
            for i in range(stride):
                a = rec[i - 4] if i >= 4 else 0
                b = up[i]
                if ftype == 3:
                    pred = (a + b) >> 1
                else:
                    c = up[i - 4] if i >= 4 else 0
                    p = a + b - c
                    pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
                    pred = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
                rec[i] = (fb[i] + pred) & 0xFF
            cur = np.array(rec, dtype=np.int64)
        else:
            raise bad(f"row {y} has filter type {ftype} (PNG defines 0-4)")
        out[y] = cur
        prior = cur
    return out.reshape(height, width, 4)


# ----------------------------------------------------------------------------------------------
# Lightmapped objects (§10 "Per-texel (lightmap) bakes"; coverage as §3.1 defines it)
# ----------------------------------------------------------------------------------------------
def triangles_of(glb, prim, nv, where):
    """(T, 3) vertex indices of a TRIANGLES primitive."""
    if prim.get("mode", 4) != 4:
        raise GlbError(f"{where}: primitive mode {prim.get('mode')} is not TRIANGLES (4)")
    if "indices" in prim:
        idx = glb.accessor(prim["indices"], [(5125, "SCALAR"), (5123, "SCALAR"),
                                             (5121, "SCALAR")], where + " indices")
        idx = idx.reshape(-1).astype(np.int64)
    else:
        idx = np.arange(nv, dtype=np.int64)
    if idx.size % 3 or (idx.size and (idx.min() < 0 or idx.max() >= nv)):
        raise GlbError(f"{where}: {idx.size} indices (not a multiple of 3, or one past the "
                       f"{nv} vertices)")
    return idx.reshape(-1, 3)


def _nearest_on_triangle(p, tri):
    """For points p (M, 2) and one triangle tri (3, 2): (squared distance (M,), barycentric
    weights (M, 3)) of the triangle's point nearest to each p (inside: the point itself)."""
    a, b, c = tri
    den = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])
    best = np.full(len(p), np.inf)
    bary = np.zeros((len(p), 3))
    if den != 0.0:
        w1 = ((p[:, 0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[:, 1] - a[1])) / den
        w2 = ((b[0] - a[0]) * (p[:, 1] - a[1]) - (p[:, 0] - a[0]) * (b[1] - a[1])) / den
        w0 = 1.0 - w1 - w2
        inside = (w0 >= 0) & (w1 >= 0) & (w2 >= 0)
        best[inside] = 0.0
        bary[inside] = np.stack([w0, w1, w2], axis=1)[inside]
    for i, j in ((0, 1), (1, 2), (2, 0)):
        e = tri[j] - tri[i]
        ee = float(e @ e)
        s = np.clip(((p - tri[i]) @ e) / ee, 0.0, 1.0) if ee > 0 else np.zeros(len(p))
        q = tri[i] + s[:, None] * e
        d = np.sum((p - q) ** 2, axis=1)
        better = d < best
        best[better] = d[better]
        bw = np.zeros((len(p), 3))
        bw[:, i], bw[:, j] = 1.0 - s, s
        bary[better] = bw[better]
    return best, bary


def lightmap_coverage(uv, tris, width, height, points=False, closed=True):
    """Texels of a W×H lightmap that a UV triangle touches: §3.1's conservative rasterisation —
    texel (x, y) is the closed square [x/W, (x+1)/W] × [y/H, (y+1)/H] (glTF UVs, v down), and is
    covered when a triangle (closed) intersects it, decided exactly by separating axes in
    texel units (f32 UVs times W or H are exact in f64). With `closed` False a triangle must
    overlap the square's interior (touching along an edge or at a corner is not enough).
    Returns the (H·W,) boolean mask and, with `points`, per texel (triangle index or −1,
    barycentric weights (3,)) of its surface point: the texel centre when a triangle contains
    it, else the point nearest to the centre of the triangles touching the texel (§3.1; the
    first triangle wins a tie); for texels no triangle touches, the nearest point of any
    triangle. (The points always use the closed squares.)"""
    tex = np.stack([uv[:, 0] * width, uv[:, 1] * height], axis=1)
    ntex = width * height
    covered = np.zeros(ntex, dtype=bool)
    best_d, best_t = np.full(ntex, np.inf), np.full(ntex, -1)
    best_b = np.zeros((ntex, 3))
    for ti, corner in enumerate(tris):
        tri = tex[corner]                                              # (3, 2)
        lo, hi = tri.min(axis=0), tri.max(axis=0)
        x0, x1 = max(0, math.ceil(lo[0]) - 1), min(width - 1, math.floor(hi[0]))
        y0, y1 = max(0, math.ceil(lo[1]) - 1), min(height - 1, math.floor(hi[1]))
        if x0 > x1 or y0 > y1:
            continue
        xs, ys = np.meshgrid(np.arange(x0, x1 + 1, dtype=np.float64),
                             np.arange(y0, y1 + 1, dtype=np.float64))
        xs, ys = xs.reshape(-1), ys.reshape(-1)
        if closed:
            touch = np.ones(len(xs), dtype=bool)
        else:                                                       # the square's own axes
            touch = (xs < hi[0]) & (xs + 1 > lo[0]) & (ys < hi[1]) & (ys + 1 > lo[1])
        for i, j, k in ((0, 1, 2), (1, 2, 0), (2, 0, 1)):          # the edges' normals
            nx, ny = tri[i][1] - tri[j][1], tri[j][0] - tri[i][0]
            d_edge, d_opp = nx * tri[i][0] + ny * tri[i][1], nx * tri[k][0] + ny * tri[k][1]
            t_lo, t_hi = min(d_edge, d_opp), max(d_edge, d_opp)
            base = nx * xs + ny * ys
            b_lo, b_hi = base + min(0.0, nx) + min(0.0, ny), base + max(0.0, nx) + max(0.0, ny)
            if closed:
                touch &= ~((b_hi < t_lo) | (b_lo > t_hi))
            else:
                touch &= ~((b_hi <= t_lo) | (b_lo >= t_hi))
        cells = (ys * width + xs).astype(np.int64)[touch]
        covered[cells] = True
        if points and len(cells):
            centre = np.stack([xs[touch] + 0.5, ys[touch] + 0.5], axis=1)
            d, bary = _nearest_on_triangle(centre, tri)
            better = d < best_d[cells]
            best_d[cells[better]], best_t[cells[better]] = d[better], ti
            best_b[cells[better]] = bary[better]
    if points and not covered.all() and len(tris):
        rest = np.flatnonzero(~covered)
        centre = np.stack([rest % width + 0.5, rest // width + 0.5], axis=1).astype(np.float64)
        for ti, corner in enumerate(tris):
            d, bary = _nearest_on_triangle(centre, tex[corner])
            better = d < best_d[rest]
            best_d[rest[better]], best_t[rest[better]] = d[better], ti
            best_b[rest[better]] = bary[better]
    return (covered, best_t, best_b) if points else covered


def relight_lightmap(glb, mesh_name, prim, texels="all", mag_out=None, quant_out=None,
                     log=sys.stderr):
    """(points, (P, 3) radiance) of a lightmapped primitive: every texel (`texels` "all") or
    the texels a UV triangle touches ("covered"), `points` their indices y·W + x. Diffuse only
    (§10.1: lightmapped objects have no view-dependent terms): per channel c,
    `albedo_c/π Σ_i t[c or 0][i] · environment[i][c]`, t = offset + scale·code/255 from the
    PNG textures. With lists `mag_out` / `quant_out`, appends the (P, 3) magnitudes (the sum
    with every factor's absolute value) and the bound Σ_i (scale/510)·|albedo_c/π·env[i][c]|
    on the radiance error due to quantisation."""
    where = f"mesh '{mesh_name}'"
    ext = need(need(prim, "extras", where), "prt", where + " extras")
    n, nch = need(ext, "order", where + " extras.prt"), need(ext, "channels", where)
    if not isinstance(n, int) or n < 1 or nch not in (1, 3):
        raise GlbError(f"{where}: bad order {n} or channels {nch}")
    nn, groups = n * n, (n * n + 3) // 4
    for key in ("specular", "diffuse_fresnel"):
        if ext.get(key) is not None:
            raise GlbError(f"{where}: lightmapped object with a non-null '{key}' (SPEC §10.1: "
                           "lightmapped objects carry the diffuse term only)")
    lw = where + " extras.prt.lightmap"
    lm = need(ext, "lightmap", where + " extras.prt")
    width, height = need(lm, "width", lw), need(lm, "height", lw)
    if not isinstance(width, int) or not isinstance(height, int) or width < 1 or height < 1:
        raise GlbError(f"{lw}: bad size {width}x{height}")
    ntex = width * height
    textures = need(lm, "textures", lw)
    if not isinstance(textures, list) or len(textures) != nch or any(
            not isinstance(row, list) or len(row) != groups for row in textures):
        raise GlbError(f"{lw}: textures must be [{nch}][{groups}] texture indices")
    offset = floats(need(lm, "offset", lw), (nch, None), lw + " offset")
    scale = floats(need(lm, "scale", lw), (nch, None), lw + " scale")
    if offset.shape[1] < nn or scale.shape[1] < nn:
        raise GlbError(f"{lw}: offset/scale have {offset.shape[1]}/{scale.shape[1]} "
                       f"coefficients per channel, need {nn}")
    offset, scale = offset[:, :nn], scale[:, :nn]
    if not (np.all(np.isfinite(offset)) and np.all(np.isfinite(scale)) and np.all(scale >= 0)):
        raise GlbError(f"{lw}: offset/scale not finite, or a negative scale")
    ncov = need(lm, "covered_texels", lw)
    if not isinstance(ncov, int) or isinstance(ncov, bool) or not 0 <= ncov <= ntex:
        raise GlbError(f"{lw}: covered_texels {ncov!r} is not an integer in 0..{ntex}")

    codes = np.zeros((nch, ntex, 4 * groups), dtype=np.uint8)
    for c in range(nch):
        for g in range(groups):
            ti = textures[c][g]
            what = f"{where} lightmap texture [{c}][{g}]"
            tex = glb._item("textures", ti)
            src = need(tex, "source", f"texture {ti}")
            img = glb._item("images", src)
            label = f" {img['name']!r}" if isinstance(img, dict) and "name" in img else ""
            what = f"{what} (texture {ti}, image {src}{label})"
            if need(img, "mimeType", what) != "image/png" or "bufferView" not in img:
                raise GlbError(f"{what}: not an embedded image/png (bufferView + mimeType)")
            px = decode_png(glb.view_bytes(img["bufferView"], what), what)
            if px.shape[:2] != (height, width):
                raise GlbError(f"{what}: PNG is {px.shape[1]}x{px.shape[0]}, the lightmap is "
                               f"{width}x{height}")
            codes[c, :, 4 * g:4 * g + 4] = px.reshape(ntex, 4)

    light, _ = environment(ext, n, where)
    ne = light.shape[0]
    pos = attribute(glb, prim, "POSITION", "VEC3", None, where)
    nv = pos.shape[0]
    alb = need(ext, "albedo", where)
    need_points = isinstance(alb, str)
    sel = np.arange(ntex)
    if texels == "covered" or need_points:
        uvname = lm.get("uv", "TEXCOORD_0")
        if not isinstance(uvname, str):
            raise GlbError(f"{lw}: uv is not an attribute name")
        uv = attribute(glb, prim, uvname, "VEC2", nv, where)
        tris = triangles_of(glb, prim, nv, where)
        cov = lightmap_coverage(uv, tris, width, height, points=need_points)
        if need_points:
            cov, tri_of, bary = cov
        if int(cov.sum()) != ncov:
            # §3.1 does not say whether touching along an edge or at a corner counts: when
            # only the stricter reading agrees with covered_texels, take it.
            strict = lightmap_coverage(uv, tris, width, height, closed=False)
            if int(strict.sum()) == ncov:
                print(f"gltf_relight: {where}: {uvname}'s triangles touch {int(cov.sum())} "
                      f"texels, {ncov} (= covered_texels) not counting edge/corner contacts: "
                      "using the latter", file=log)
                cov = strict
            else:
                print(f"gltf_relight: {where}: conservative rasterisation of {uvname} covers "
                      f"{int(cov.sum())} texels ({int(strict.sum())} without edge/corner "
                      f"contacts), extras.prt.lightmap.covered_texels says {ncov}", file=log)
        if texels == "covered":
            sel = np.flatnonzero(cov)
    if need_points:
        # The albedo per vertex (§10: `_PRT_ALBEDO`), interpolated at each texel's surface
        # point; the SPEC does not say what albedo prt shades a texel with.
        av = attribute(glb, prim, alb, "VEC3", nv, where)
        tri_sel = tri_of[sel]
        if np.any(tri_sel < 0):
            raise GlbError(f"{where}: no triangle to take the albedo of a texel from")
        albedo = np.einsum("pk,pkc->pc", bary[sel], av[tris[tri_sel]])
    else:
        albedo = np.broadcast_to(floats(alb, (3,), where + " albedo"), (len(sel), 3))
    # Per channel and coefficient (t never held whole: a big map of high order would not fit).
    rad, mag, quant = (np.zeros((len(sel), 3)) for _ in range(3))
    for c in range(3):
        cc = c if nch == 3 else 0
        for i in range(ne):
            ti = offset[cc, i] + scale[cc, i] * codes[cc, sel, i] / 255.0
            rad[:, c] += ti * light[i, c]
            mag[:, c] += np.abs(ti) * abs(light[i, c])
            quant[:, c] += scale[cc, i] / 510.0 * abs(light[i, c])
    alb_pi = albedo / math.pi
    if mag_out is not None:
        mag_out.append(np.abs(alb_pi) * mag)
    if quant_out is not None:
        quant_out.append(np.abs(alb_pi) * quant)
    return sel, alb_pi * rad


def relight_file(path, eye=None, specular=True, fresnel=True, log=sys.stderr, mags=None,
                 quant=None, texels="all", storages=None):
    """[(mesh name, points, (P, 3) radiance)] for every mesh of a .glb: per-vertex meshes have
    P = their vertices (points 0 … nv−1; storage "vertex" or "vertex_texture"), lightmapped
    ones the texels of `texels` ("all" or "covered"). With lists `mags` / `quant`, also
    appends [(mesh name, points, (P, 3))] of the magnitudes (see relight_primitive /
    relight_lightmap) and of the quantisation bound (0 for per-vertex meshes, which are not
    quantised); with a dict `storages`, records each mesh's `extras.prt.storage` under its
    name."""
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError as exc:
        raise GlbError(f"cannot read: {exc.strerror}") from None
    glb = Glb(data)
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
        m = [] if mags is not None else None
        q = [] if quant is not None else None
        if storage == "lightmap":
            pts, rad = relight_lightmap(glb, name, prims[0], texels, m, q, log)
        elif storage in ("vertex", "vertex_texture"):
            if eye is None:
                cam = need(need(need(glb.json, "extras", "the root"), "prt", "root extras"),
                           "camera", "root extras.prt")
                eye = need(cam, "eye", "extras.prt.camera")
            eye = floats(eye, (3,), "camera eye")
            rad = relight_primitive(glb, name, prims[0], eye, specular, fresnel, m)
            pts = np.arange(rad.shape[0])
            if q is not None:
                q.append(np.zeros_like(rad))
        else:
            raise GlbError(f"mesh '{name}': unknown storage {storage!r}")
        out.append((name, pts, rad))
        if storages is not None:
            storages[name] = storage
        if mags is not None:
            mags.append((name, pts, m[0]))
        if quant is not None:
            quant.append((name, pts, q[0]))
    return out


def write_csv(path, results):
    with open(path, "w") as fh:
        fh.write("object,point,r,g,b\n")
        for name, pts, rad in results:
            for i, (r, g, b) in zip(pts.tolist(), rad.tolist()):
                fh.write(f"{name},{i},{r!r},{g!r},{b!r}\n")


def compare(results, ref_path, worst=3, lightmapped=()):
    """Max over objects of max |ours − ref| / (max |ref| per channel). Points must match one
    to one, except for lightmapped objects (names in `lightmapped`): those are compared on the
    texels both hold, our texels missing from the reference are only counted, and reference
    texels missing from ours must be 0 (a texel no triangle touches has zero transfer, §3.11)."""
    ref = {}
    with open(ref_path) as fh:
        next(fh)
        for line in fh:
            name, idx, r, g, b = line.rstrip("\n").rsplit(",", 4)
            ref.setdefault(name, {})[int(idx)] = (float(r), float(g), float(b))
    overall = 0.0
    for name, pts, rad in results:
        rn = ref.get(name, {})
        ours = dict(zip(pts.tolist(), range(len(pts))))
        both = [p for p in pts.tolist() if p in rn]
        extra = [p for p in rn if p not in ours]
        kind = "texels" if name in lightmapped else "vertices"
        if name in lightmapped:
            ok = bool(both) and all(v == (0.0, 0.0, 0.0) for p in extra for v in [rn[p]])
        else:
            ok = len(rn) == len(pts) and len(both) == len(pts)
        if not ok:
            print(f"  {name}: {len(pts)} {kind}, reference has {len(rn)} ({len(both)} shared"
                  + (", a reference texel we lack is not 0)" if extra else ")"))
            overall = math.inf
            continue
        mine = rad[[ours[p] for p in both]]
        rr = np.array([rn[p] for p in both])
        peak = np.maximum(np.abs(rr).max(axis=0), 1e-300)
        rel = np.abs(mine - rr) / peak                               # (P, 3)
        per = rel.max(axis=1)
        overall = max(overall, per.max())
        note = ""
        if len(both) != len(pts) or extra:
            note = (f" [{len(both)} compared; {len(pts) - len(both)} of ours not in the "
                    f"reference, {len(extra)} zero reference texels not in ours]")
        print(f"  {name}: {len(pts)} {kind}, max rel diff r/g/b = "
              + "/".join(f"{v:.2e}" for v in rel.max(axis=0)) + f" (peak {peak.max():.4g})"
              + note)
        for v in np.argsort(-per)[:worst]:
            print(f"    {kind[:-1] if kind == 'texels' else 'vertex'} {both[v]}: "
                  f"ours {mine[v].tolist()} prt {rr[v].tolist()}")
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


def png_chunk(tag, body):
    return (struct.pack(">I", len(body)) + tag + body
            + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF))


def png_encode(img, filters=0, depth=8, colour=6, idat_parts=1, deflate=None, iend=True):
    """A minimal PNG encoder for the self-test: (H, W, 4) uint8 RGBA, one filter type per row
    (an int: the same for every row), the encoder side of the five filters; `deflate` replaces
    zlib.compress (to make broken streams), `idat_parts` splits the stream over IDAT chunks."""
    h, w = img.shape[:2]
    rows = img.reshape(h, 4 * w).astype(int).tolist()
    types = [filters] * h if isinstance(filters, int) else list(filters)
    stream = bytearray()
    for y, line in enumerate(rows):
        above = rows[y - 1] if y else [0] * len(line)
        stream.append(types[y])
        for i, value in enumerate(line):
            left = line[i - 4] if i >= 4 else 0
            up, up_left = above[i], (above[i - 4] if i >= 4 else 0)
            if types[y] == 0:
                pred = 0
            elif types[y] == 1:
                pred = left
            elif types[y] == 2:
                pred = up
            elif types[y] == 3:
                pred = (left + up) // 2
            elif types[y] == 4:                        # Paeth: the neighbour nearest a+b−c
                est = left + up - up_left
                dists = [abs(est - left), abs(est - up), abs(est - up_left)]
                pred = [left, up, up_left][dists.index(min(dists))]   # ties: a, then b, then c
            else:
                pred = 0
            stream.append((value - pred) % 256)
    z = (deflate or (lambda b: zlib.compress(b, 9)))(bytes(stream))
    cut = [len(z) * k // idat_parts for k in range(idat_parts + 1)]
    out = PNG_SIGNATURE + png_chunk(b"IHDR", struct.pack(">IIBBBBB", w, h, depth, colour,
                                                         0, 0, 0))
    out += b"".join(png_chunk(b"IDAT", z[cut[k]:cut[k + 1]]) for k in range(idat_parts))
    return out + (png_chunk(b"IEND", b"") if iend else b"")


def glb_of(meshes, pngs=(), root_prt=None):
    """A .glb from meshes [(name, {attribute: float array (N, k)}, uint32 indices or None,
    extras.prt)] and embedded PNG images (texture i = image i). An
    `extras.prt.transfer_texture` whose `accessor` is a float array (W·H, 4) gets it written
    as a FLOAT VEC4 accessor (§10.2)."""
    binary, views, accs = bytearray(), [], []

    def view(data):
        views.append({"buffer": 0, "byteOffset": len(binary), "byteLength": len(data)})
        binary.extend(data)
        binary.extend(b"\0" * (-len(binary) % 4))
        return len(views) - 1

    def accessor(arr, ctype):
        arr = np.ascontiguousarray(arr, dtype="<f4" if ctype == F else "<u4")
        width = 1 if arr.ndim == 1 else arr.shape[1]
        accs.append({"bufferView": view(arr.tobytes()), "componentType": ctype,
                     "count": arr.shape[0], "type": "SCALAR" if width == 1 else f"VEC{width}"})
        return len(accs) - 1

    gl_meshes = []
    for name, attrs, indices, prt in meshes:
        tt = prt.get("transfer_texture")
        if isinstance(tt, dict) and isinstance(tt.get("accessor"), np.ndarray):
            prt = dict(prt, transfer_texture=dict(tt, accessor=accessor(tt["accessor"], F)))
        prim = {"attributes": {k: accessor(v, F) for k, v in attrs.items()},
                "extras": {"prt": prt}}
        if indices is not None:
            prim["indices"] = accessor(np.asarray(indices).reshape(-1), 5125)
        gl_meshes.append({"name": name, "primitives": [prim]})
    doc = {"asset": {"version": "2.0"},
           "extras": {"prt": root_prt or {"camera": {"eye": [0, 0, 2.0]}}},
           "meshes": gl_meshes}
    if pngs:
        doc["images"] = [{"bufferView": view(p), "mimeType": "image/png"} for p in pngs]
        doc["samplers"] = [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071,
                            "wrapT": 33071}]
        doc["textures"] = [{"source": i, "sampler": 0} for i in range(len(pngs))]
    doc["buffers"] = [{"byteLength": len(binary)}]
    doc["bufferViews"], doc["accessors"] = views, accs
    return doc, make_glb(doc, bytes(binary))


def self_test_channels(check, rng):
    """A 3-channel (bounced) per-vertex object with a Phong lobe, against a closed form: per
    channel the light is a_c + b_c z + d_c x and the visibility p + q z, so the truncated
    product (order 2) is (a p + b q/3) + (a q + b p) z + d p x, and with A_0 = 1,
    A_1 = (e+1)/(e+2): S_c = ks_c (e+2)/(e+1) c_o [(a p + b q/3) + A_1 ((a q + b p) r_z
    + d p r_x)]."""
    s4pi, s4pi3 = 2.0 * math.sqrt(math.pi), math.sqrt(FOUR_PI / 3.0)
    a_c, b_c, d_c = np.array([0.9, 1.3, 0.4]), np.array([0.5, -0.2, 0.3]), np.array([-.4, .1, .6])
    env = np.zeros((4, 3))
    env[0], env[2], env[3] = a_c * s4pi, b_c * s4pi3, -d_c * s4pi3     # x = −√(4π/3) y_1^1
    pos = np.array([[0, 0, 0], [1, 0, 0.2], [0, 1, -0.1], [0.5, 0.5, 0]], dtype=np.float64)
    nrm = np.array([[0, 0, 1], [0.3, -0.2, 1], [-0.4, 0.1, 0.8], [0, 0.2, -1]])  # last faces away
    pq = np.array([[1.0, 0.0], [0.7, 0.3], [0.4, -0.5], [0.6, 0.2]])             # V = p + q z
    vis = np.zeros((4, 4))
    vis[:, 0], vis[:, 2] = pq[:, 0] * s4pi, pq[:, 1] * s4pi3
    t = rng.uniform(-0.5, 1.0, size=(3, 4, 4))
    alb = rng.uniform(0.2, 0.9, size=(4, 3))
    e, ks, eye = 5.0, np.array([0.3, 0.6, 0.9]), np.array([0.4, 0.3, 2.5])
    el, va = [0.0, 1.2], [0.05, 0.25]
    attrs = {"POSITION": pos, "NORMAL": nrm, "_PRT_V_0": vis, "_PRT_ALBEDO": alb}
    attrs.update({f"_PRT_C{c}_0": t[c] for c in range(3)})
    prt = {"order": 2, "channels": 3, "storage": "vertex", "environment": env.tolist(),
           "albedo": "_PRT_ALBEDO", "lightmap": None,
           "attributes": ["_PRT_C0_0", "_PRT_C1_0", "_PRT_C2_0"],
           "diffuse_fresnel": {"elevations": el, "values": va},
           "specular": {"model": "phong", "exponent": e, "specular": ks.tolist(),
                        "bands": [1.0, (e + 1) / (e + 2)],
                        "visibility_attributes": ["_PRT_V_0"]}}
    doc, data = glb_of([("bounced", attrs, [0, 1, 2, 0, 2, 3], prt)])
    prim = doc["meshes"][0]["primitives"][0]
    rad = relight_primitive(Glb(data), "bounced", prim, eye)
    # Stored as f32: recompute the closed form from the stored values.
    pos32, nrm32, vis32 = pos.astype("<f4"), nrm.astype("<f4"), vis.astype("<f4")
    t32, alb32 = t.astype("<f4"), alb.astype("<f4")
    want = np.zeros((4, 3))
    for v in range(4):
        nh = nrm32[v].astype(float) / np.linalg.norm(nrm32[v].astype(float))
        wo = eye - pos32[v]
        wo = wo / np.linalg.norm(wo)
        co = float(nh @ wo)
        th = min(math.acos(max(-1.0, min(1.0, co))), math.pi / 2)
        kd = 1.0 - (va[0] + (va[1] - va[0]) * min(th, el[1]) / el[1])
        r = 2 * co * nh - wo
        p, q = float(vis32[v, 0]) / s4pi, float(vis32[v, 2]) / s4pi3
        for c in range(3):
            dsum = sum(float(t32[c, v, i]) * env[i, c] for i in range(4))
            want[v, c] = float(alb32[v, c]) * kd / math.pi * dsum
            if co > 0:
                a, b, d = a_c[c], b_c[c], d_c[c]
                want[v, c] += ks[c] * (e + 2) / (e + 1) * co * (
                    (a * p + b * q / 3) + (e + 1) / (e + 2) * ((a * q + b * p) * r[2]
                                                               + d * p * r[0]))
    check(np.abs(rad - want).max() < 1e-12, f"3-channel phong vs closed form "
          f"({np.abs(rad - want).max():.2e})")
    check(rad[3].tolist() == want[3].tolist() or np.abs(rad[3] - want[3]).max() < 1e-14,
          "3-channel: back-facing vertex has no specular")
    # One visibility channel whatever the channels: a second visibility group would be refused.
    prt["specular"]["visibility_attributes"] = ["_PRT_V_0", "_PRT_V_1"]
    attrs["_PRT_V_1"] = vis
    doc, data = glb_of([("bounced", attrs, [0, 1, 2, 0, 2, 3], prt)])
    try:
        relight_primitive(Glb(data), "bounced", doc["meshes"][0]["primitives"][0], eye)
        check(False, "3-channel: visibility with too many groups accepted")
    except GlbError:
        check(True, "")
    prt["specular"]["visibility_attributes"] = ["_PRT_V_0"]
    del attrs["_PRT_V_1"]
    c2 = attrs.pop("_PRT_C2_0")
    doc, data = glb_of([("bounced", attrs, None, prt)])
    try:
        relight_primitive(Glb(data), "bounced", doc["meshes"][0]["primitives"][0], eye)
        check(False, "3-channel: missing _PRT_C2_0 accepted")
    except GlbError as exc:
        check("_PRT_C2_0" in str(exc), f"3-channel: missing attribute named ({exc})")
    attrs["_PRT_C2_0"] = c2
    # An environment of order 2 for an order-3 object (§10): sums over 4 coefficients and the
    # lobe at order 2, i.e. the same radiance as the order-2 object with t's first 4 values.
    attrs3 = dict(attrs)
    for c in range(3):
        t9 = np.concatenate([t[c], rng.normal(size=(4, 8))], axis=1)
        attrs3.update({f"_PRT_C{c}_{g}": t9[:, 4 * g:4 * g + 4] for g in range(3)})
    prt3 = dict(prt, order=3)
    doc, data = glb_of([("o3", attrs3, None, prt3)])
    rad3 = relight_primitive(Glb(data), "o3", doc["meshes"][0]["primitives"][0], eye)
    check(np.abs(rad3 - want).max() < 1e-12, "order-3 object, order-2 environment")
    prt3["environment"] = env.tolist()[:3]
    doc, data = glb_of([("o3", attrs3, None, prt3)])
    try:
        relight_primitive(Glb(data), "o3", doc["meshes"][0]["primitives"][0], eye)
        check(False, "environment of 3 rows accepted")
    except GlbError:
        check(True, "")


def vertex_texture_of(t, vis, limit=2048, ids=None):
    """§10.2's layout written from its formulas: (texels (W·H, 4), transfer_texture) for the
    transfer t (C, V, n²) and visibility (V, n²) or None; vertex v's block is at v·P, so a
    row whose `_PRT_VERTEX_ID` is ids[r] reads t[:, r] when the texel block ids[r] holds it."""
    nch, nv, nn = t.shape
    ids = np.arange(nv) if ids is None else ids
    g = (nn + 3) // 4
    p = nch * g + (g if vis is not None else 0)
    w = min(limit, nv * p)
    h = -(-nv * p // w)
    tex = np.zeros((h, w, 4))
    for r in range(nv):
        v = int(ids[r])
        for i in range(nn):
            for c in range(nch):
                k = v * p + c * g + i // 4
                tex[k // w, k % w, i % 4] = t[c, r, i]
            if vis is not None:
                k = v * p + nch * g + i // 4
                tex[k // w, k % w, i % 4] = vis[r, i]
    return tex.reshape(w * h, 4), {
        "accessor": None, "format": "RGBA32F", "width": w, "height": h,
        "texels_per_vertex": p, "groups": g, "channel_texels": [c * g for c in range(nch)],
        "visibility_texel": nch * g if vis is not None else None,
        "vertex_id": "_PRT_VERTEX_ID", "layout": "informative"}


def self_test_vertex_texture(check, rng):
    """§10.2: the same per-vertex data in the §10 attribute layout and in a data texture
    (written above from the SPEC's formulas) relights identically — radiance and magnitudes,
    1 and 3 channels, without a lobe, with Phong and fitted lobes (visibility from the
    texture), an environment of lower order; W = 2048 < V·P with padding texels and rows
    that split a vertex's block (2048 mod P ≠ 0), and W = V·P. Malformed layouts are refused
    with a message naming the mesh."""
    nv = 700
    pos = rng.uniform(-1, 1, size=(nv, 3))
    nrm = rng.normal(size=(nv, 3))
    nrm[:, 2] = np.abs(nrm[:, 2]) + 0.2                 # mostly facing the eye, a few not
    nrm[:40, 2] = -nrm[:40, 2]
    eye = np.array([0.3, -0.2, 3.0])

    def fitted(n):
        return {"model": "fitted", "elevations": [0.0, 0.7, 1.6], "roughness_levels": [0.3],
                "axis": rng.uniform(0, 0.5, size=(1, 3, 2)).tolist(),
                "bands": rng.uniform(0, 1, size=(1, 3, 2, n + 1)).tolist(),
                "bands_b": rng.uniform(0, 1, size=(1, 3, 2, n + 1)).tolist(),
                "colour_a": [0.04, 0.05, 0.06], "colour_b": "_PRT_SPEC_B", "roughness": 0.3}

    def phong(n):
        return {"model": "phong", "exponent": 6.0, "specular": [0.3, 0.5, 0.7],
                "bands": phong_bands(6.0, n).tolist()}

    cases = [(1, 3, None, 9, 2048), (1, 3, phong, 9, 2048), (3, 3, None, 9, 2048),
             (3, 3, fitted, 9, 2048), (3, 3, phong, 4, 2048), (1, 2, phong, 4, 10 ** 6),
             (3, 4, fitted, 16, 4096)]
    for nch, n, lobe, n_env, limit in cases:
        nn, g = n * n, (n * n + 3) // 4
        label = (f"vertex_texture {nch} ch order {n}, {lobe.__name__ if lobe else 'no lobe'}"
                 f", env {n_env} rows, limit {limit}")
        t = rng.uniform(-0.5, 1.0, size=(nch, nv, nn)).astype("<f4").astype(float)
        vis = rng.uniform(-1, 1, size=(nv, nn)).astype("<f4").astype(float) if lobe else None
        albedo = rng.uniform(0.1, 0.9, size=(nv, 3))
        spec_b = rng.uniform(0.2, 0.9, size=(nv, 3))
        base = {"order": n, "channels": nch, "environment":
                rng.uniform(-1, 1, size=(n_env, 3)).tolist(), "albedo": "_PRT_ALBEDO",
                "lightmap": None, "specular": lobe(n) if lobe else None,
                "diffuse_fresnel": {"elevations": [0.0, 1.0, 1.5], "values": [0.05, 0.1, 0.3]}}
        common = {"POSITION": pos, "NORMAL": nrm, "_PRT_ALBEDO": albedo, "_PRT_SPEC_B": spec_b}
        attrs_v = dict(common)
        pad = np.zeros((nv, 4 * g - nn))
        for c in range(nch):
            tc = np.concatenate([t[c], pad], axis=1)
            attrs_v.update({f"_PRT_C{c}_{k}": tc[:, 4 * k:4 * k + 4] for k in range(g)})
        prt_v = dict(base, storage="vertex",
                     attributes=[f"_PRT_C{c}_{k}" for c in range(nch) for k in range(g)])
        if lobe:
            vc = np.concatenate([vis, pad], axis=1)
            attrs_v.update({f"_PRT_V_{k}": vc[:, 4 * k:4 * k + 4] for k in range(g)})
            prt_v["specular"] = dict(base["specular"],
                                     visibility_attributes=[f"_PRT_V_{k}" for k in range(g)])
        texels, tt = vertex_texture_of(t, vis, limit)
        p = tt["texels_per_vertex"]
        attrs_t = dict(common, _PRT_VERTEX_ID=np.arange(nv, dtype=float))
        prt_t = dict(base, storage="vertex_texture", attributes=[],
                     transfer_texture=dict(tt, accessor=texels))
        if lobe:
            prt_t["specular"] = dict(base["specular"], visibility_attributes=[])
        meshes = [("attr", attrs_v, None, prt_v), ("tex", attrs_t, None, prt_t)]
        _, data = glb_of(meshes, root_prt={"camera": {"eye": eye.tolist()}})
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "vt.glb")
            with open(path, "wb") as fh:
                fh.write(data)
            mags, storages = [], {}
            res = relight_file(path, mags=mags, storages=storages)
            check(storages == {"attr": "vertex", "tex": "vertex_texture"}, label + ": storages")
            check(np.array_equal(res[0][1], res[1][1]) and np.array_equal(res[0][2], res[1][2])
                  and np.abs(res[1][2]).max() > 0, label + ": radiance = the attribute layout's")
            check(np.array_equal(mags[0][2], mags[1][2]), label + ": magnitudes equal")
            res_ns = relight_file(path, specular=False)
            check(np.array_equal(res_ns[0][2], res_ns[1][2]) and (
                lobe is None or not np.array_equal(res_ns[1][2], res[1][2])),
                  label + ": --no-specular equal (and differs when there is a lobe)")
            if limit == 2048:
                check(tt["width"] == 2048 and tt["height"] * 2048 > nv * p and 2048 % p,
                      f"{label}: layout has padding texels and split blocks ({tt})")
            else:
                check(tt["height"] == 1 or limit == 4096, f"{label}: W = V·P")
        if nch != 3 or lobe is not fitted or limit != 2048:
            continue
        # The command line: CSVs of the two layouts hold the same rows (but the name).
        with tempfile.TemporaryDirectory() as tmp:
            path = os.path.join(tmp, "vt.glb")
            with open(path, "wb") as fh:
                fh.write(data)
            out = {k: os.path.join(tmp, k + ".csv") for k in ("c", "m", "q", "ref")}
            quiet = open(os.devnull, "w")
            saved = sys.stdout, sys.stderr
            sys.stdout = sys.stderr = quiet
            try:
                rc = main([path, "--colours", out["c"], "--magnitudes", out["m"],
                           "--quantisation", out["q"]])
                with open(out["ref"], "w") as fh:     # the reference: attr's rows for both
                    rows = open(out["c"]).read().splitlines()
                    attr_rows = [r for r in rows[1:] if r.startswith("attr,")]
                    fh.write("\n".join([rows[0]] + attr_rows
                                       + ["tex," + r[5:] for r in attr_rows]) + "\n")
                rc_cmp = main([path, "--compare", out["ref"]])
            finally:
                sys.stdout, sys.stderr = saved
                quiet.close()
            check((rc, rc_cmp) == (0, 0), f"vertex_texture CLI exit codes {(rc, rc_cmp)}")
            for k in ("c", "m"):
                rows = open(out[k]).read().splitlines()[1:]
                a = [r[5:] for r in rows if r.startswith("attr,")]
                b = [r[4:] for r in rows if r.startswith("tex,")]
                check(len(a) == nv and a == b, f"vertex_texture CSV {k}: same rows as attr")
            check(all(r.endswith(",0.0,0.0,0.0") for r in open(out["q"]).read().splitlines()[1:]),
                  "vertex_texture quantisation rows are 0")
        # Vertices index the texture by their id: ids permuted with the blocks, same result.
        perm = rng.permutation(nv)
        ptex, _ = vertex_texture_of(t, vis, limit, ids=perm)
        prt_p = dict(prt_t, transfer_texture=dict(tt, accessor=ptex))
        _, pdata = glb_of([("tex", dict(attrs_t, _PRT_VERTEX_ID=perm.astype(float)), None,
                            prt_p)], root_prt={"camera": {"eye": eye.tolist()}})
        pdoc_prim = Glb(pdata).json["meshes"][0]["primitives"][0]
        got = relight_primitive(Glb(pdata), "tex", pdoc_prim, eye)
        check(np.array_equal(got, res[1][2]), "vertex_texture: rows read the block of their id")

        # Malformed: each refused with a message naming the mesh and the problem.
        def refused(prt_x, attrs_x, needle, what):
            _, bad = glb_of([("broken", attrs_x, None, prt_x)])
            gb = Glb(bad)
            try:
                relight_primitive(gb, "broken", gb.json["meshes"][0]["primitives"][0], eye)
                check(False, f"vertex_texture: {what} accepted")
            except GlbError as exc:
                check("mesh 'broken'" in str(exc) and needle in str(exc),
                      f"vertex_texture: {what} refused as: {exc}")

        def tex_with(**kw):
            return dict(prt_t, transfer_texture=dict(prt_t["transfer_texture"], **kw))

        refused(tex_with(accessor=texels[:-1]), attrs_t, "W·H", "accessor count W·H − 1")
        refused(tex_with(accessor=np.concatenate([texels, texels[:1]])), attrs_t, "W·H",
                "accessor count W·H + 1")
        ids = np.arange(nv, dtype=float)
        ids[5] = 4.5
        refused(prt_t, dict(attrs_t, _PRT_VERTEX_ID=ids), "4.5", "non-integer vertex id")
        ids[5] = nv
        refused(prt_t, dict(attrs_t, _PRT_VERTEX_ID=ids), "not an integer vertex index",
                "vertex id past the vertices")
        ids[5] = -1
        refused(prt_t, dict(attrs_t, _PRT_VERTEX_ID=ids), "not an integer vertex index",
                "negative vertex id")
        refused(prt_t, {k: v for k, v in attrs_t.items() if k != "_PRT_VERTEX_ID"},
                "_PRT_VERTEX_ID", "missing _PRT_VERTEX_ID")
        refused({k: v for k, v in prt_t.items() if k != "transfer_texture"}, attrs_t,
                "transfer_texture", "missing transfer_texture")
        refused(dict(prt_t, transfer_texture=None), attrs_t, "transfer_texture",
                "null transfer_texture")
        refused(tex_with(texels_per_vertex=p + 1), attrs_t, "texels_per_vertex",
                "texels_per_vertex off by one")
        refused(tex_with(groups=g + 1), attrs_t, "groups", "groups off by one")
        refused(tex_with(channel_texels=[0, g, g + 1]), attrs_t, "channel_texels",
                "channel_texels not c·G")
        refused(tex_with(channel_texels=[0, g]), attrs_t, "channel_texels",
                "channel_texels of 2 channels")
        refused(tex_with(visibility_texel=None), attrs_t, "visibility_texel",
                "lobe without visibility_texel")
        refused(tex_with(visibility_texel=0), attrs_t, "visibility_texel",
                "visibility_texel on channel 0's texels")
        refused(dict(prt_t, specular=None), attrs_t, "visibility_texel",
                "visibility_texel without a lobe")
        refused(tex_with(format="RGBA16F"), attrs_t, "format", "format RGBA16F")
        refused(tex_with(width=1024, height=2 * tt["height"]), attrs_t, "ceil",
                "W·H = V·P + padding but H != ceil(V·P/W)")
        refused(tex_with(width=tt["width"] // 2), attrs_t, "ceil", "too few texels")
        dirty = texels.copy()
        dirty[-1, 3] = 1.0
        refused(tex_with(accessor=dirty), attrs_t, "past the last vertex",
                "non-zero padding texel")
        dirty = texels.copy()
        dirty[3 * p + g - 1, 3] = 1.0                  # vertex 3, channel 0: component 11 > n²
        refused(tex_with(accessor=dirty), attrs_t, "past coefficient", "non-zero component")
        refused(prt_t, dict(attrs_t, _PRT_C0_0=attrs_v["_PRT_C0_0"]), "_PRT_C0_0",
                "a _PRT_C attribute too")
        refused(dict(prt_t, specular=dict(prt_t["specular"], visibility_attributes=["_PRT_V_0"])),
                attrs_t, "visibility_attributes", "non-empty visibility_attributes")


def self_test_png(check, rng):
    """Decoder round trips for every filter type, and refusals of broken PNGs."""
    base = rng.integers(0, 256, size=(5, 3, 4), dtype=np.uint8)
    gy, gx = np.mgrid[0:6, 0:7]
    smooth = np.stack([gx * 30 + gy * 3, 200 - gy * 25, (gx * gy * 7) % 256,
                       np.full_like(gx, 255)], axis=-1).astype(np.uint8)   # Paeth ties
    noisy = (smooth.astype(int) + rng.integers(-3, 4, size=smooth.shape)).clip(0, 255)
    # Paeth's ties that change the prediction: (a, b, c) = (12, 6, 10) ties b with c (b
    # wins), (6, 12, 10) ties a with c (a wins); an a–b tie only arises with a = b.
    ties = np.zeros((2, 2, 4), dtype=np.uint8)
    ties[0, 0], ties[0, 1], ties[1, 0] = [10, 10, 0, 9], [6, 12, 0, 9], [12, 6, 0, 9]
    ties[1, 1] = [200, 100, 50, 9]
    cases = [(ties, [0, 4], "Paeth ties")]
    cases += [(img, f, f"filter {f} {img.shape[1]}x{img.shape[0]}")
             for img in (base, smooth, noisy.astype(np.uint8)) for f in range(5)]
    cases += [(smooth[:5], [0, 1, 2, 3, 4], "mixed filters"),
              (base[:, :1], [4, 3, 1, 2, 4], "width 1"), (base[:1], 4, "height 1")]
    for img, f, what in cases:
        got = decode_png(png_encode(img, f), what)
        check(got.shape == img.shape and np.array_equal(got, img), f"PNG round trip, {what}")
    got = decode_png(png_encode(smooth, 4, idat_parts=3), "three IDATs")
    check(np.array_equal(got, smooth), "PNG round trip, three IDAT chunks")
    good = png_encode(smooth, 3)
    bad = [
        (png_encode(smooth, 3, deflate=lambda b: zlib.compress(b)[:len(zlib.compress(b)) // 2]),
         "truncated"),
        (png_encode(smooth, 3, deflate=lambda b: zlib.compress(b[:-1])), "inflates to"),
        (png_encode(smooth, 3, deflate=lambda b: zlib.compress(b) + b"xx"), "after the IDAT"),
        (good[:-20], "truncated"),                        # the IEND and part of IDAT cut off
        (png_encode(smooth, 3, iend=False), "IEND"),
        (good[:40] + bytes([good[40] ^ 1]) + good[41:], "CRC"),
        (b"\x89PNG\r\n\x1a\r" + good[8:], "signature"),
        (png_encode(smooth, [0, 1, 5, 0, 0, 0]), "filter type 5"),
        (png_encode(smooth, 0, colour=2), "colour type 2"),
        (png_encode(smooth, 0, depth=16), "bit depth 16"),
        (png_encode(smooth, 0)[:33] + png_chunk(b"ZZZZ", b"") + png_encode(smooth, 0)[33:],
         "critical chunk"),
    ]
    for data, needle in bad:
        try:
            decode_png(data, "image 'probe'")
            check(False, f"broken PNG accepted ({needle})")
        except GlbError as exc:
            check("image 'probe'" in str(exc) and needle in str(exc),
                  f"broken PNG ({needle}) refused as: {exc}")
    # An ancillary chunk is skipped.
    tEXt = png_chunk(b"tEXt", b"Comment\0prt")
    check(np.array_equal(decode_png(good[:33] + tEXt + good[33:], "x"), smooth),
          "ancillary chunk skipped")


def self_test_lightmaps(check, rng):
    """Two lightmapped objects on a 4×3 map: order 3 with one channel (three PNGs, the last
    group holding coefficient 8 then zeros), and order 2 with three channels and a per-vertex
    albedo. Texels are checked by hand: decoding, dequantisation, relighting, coverage."""
    W, H = 4, 3
    # Texel units (U, V) = (u W, v H): triangle A touches texels (0,0) (1,0) (0,1) (1,1) (its
    # hypotenuse passes below the corner (1, 1)), triangle B only (3, 2), triangle C (2,0)
    # (3,0) (2,1) but not (3,1), which its bounding box overlaps (its hypotenuse passes
    # through (3, 0.9), above the corner (3, 1)).
    tex = np.array([[0.2, 0.3], [1.8, 0.3], [0.2, 1.8], [3.2, 2.2], [3.8, 2.2], [3.2, 2.8],
                    [2.2, 0.2], [3.8, 0.2], [2.2, 1.6]])
    uv = tex / [W, H]
    pos = np.concatenate([uv, np.zeros((9, 1))], axis=1)
    nrm = np.tile([0.0, 0.0, 1.0], (9, 1))
    covered = [0, 1, 2, 3, 4, 5, 6, 11]
    env = rng.uniform(-1, 1, size=(9, 3))
    codes1 = rng.integers(0, 256, size=(3, H, W, 4), dtype=np.uint8)
    codes1[2, :, :, 1:] = 0                              # past n² = 9: zeros
    off1, sc1 = rng.uniform(-1, 1, size=9), rng.uniform(0, 2, size=9)
    sc1[4] = 0.0                                         # a constant coefficient
    codes3 = rng.integers(0, 256, size=(3, H, W, 4), dtype=np.uint8)
    off3, sc3 = rng.uniform(-1, 1, size=(3, 4)), rng.uniform(0, 2, size=(3, 4))
    alb_v = rng.uniform(0.1, 0.9, size=(9, 3))
    pngs = [png_encode(codes1[g], [g % 5, (g + 2) % 5, 4]) for g in range(3)]
    pngs += [png_encode(codes3[c], 1 + c) for c in range(3)]

    def lm(textures, off, sc, n_cov=len(covered)):
        return {"width": W, "height": H, "uv": "TEXCOORD_0", "textures": textures,
                "offset": np.atleast_2d(off).tolist(), "scale": np.atleast_2d(sc).tolist(),
                "covered_texels": n_cov, "layout": "informative"}

    albedo1 = [0.8, 0.6, 0.3]
    prt1 = {"order": 3, "channels": 1, "storage": "lightmap", "attributes": [],
            "lightmap": lm([[0, 1, 2]], off1, sc1), "albedo": albedo1,
            "environment": env.tolist(), "diffuse_fresnel": None, "specular": None}
    prt3 = {"order": 2, "channels": 3, "storage": "lightmap", "attributes": [],
            "lightmap": lm([[3], [4], [5]], off3, sc3), "albedo": "_PRT_ALBEDO",
            "environment": env.tolist(), "diffuse_fresnel": None, "specular": None}
    attrs = {"POSITION": pos, "NORMAL": nrm, "TEXCOORD_0": uv}
    meshes = [("floor", attrs, list(range(9)), prt1),
              ("bounced", dict(attrs, _PRT_ALBEDO=alb_v), list(range(9)), prt3)]
    doc, data = glb_of(meshes, pngs)
    glb = Glb(data)
    p1, p3 = (doc["meshes"][k]["primitives"][0] for k in range(2))
    uv32 = uv.astype("<f4").astype(float) * [W, H]
    alb32 = alb_v.astype("<f4").astype(float)

    def by_hand_t(x, y, nch, c, n):
        out = []
        for i in range(n * n):
            g, j = divmod(i, 4)
            if nch == 1:
                out.append(off1[i] + sc1[i] * int(codes1[g, y, x, j]) / 255.0)
            else:
                out.append(off3[c, i] + sc3[c, i] * int(codes3[c, y, x, j]) / 255.0)
        return out

    mags, quant = [], []
    pts, rad = relight_lightmap(glb, "floor", p1, "all", mags, quant)
    check(pts.tolist() == list(range(W * H)), "lightmap 'all': every texel")
    for x, y in ((1, 1), (3, 2), (3, 1)):                # covered, covered, dilated
        tt = by_hand_t(x, y, 1, 0, 3)
        for c in range(3):
            want = albedo1[c] / math.pi * sum(tt[i] * env[i, c] for i in range(9))
            wmag = albedo1[c] / math.pi * sum(abs(tt[i] * env[i, c]) for i in range(9))
            wq = sum(sc1[i] / 510 * abs(albedo1[c] / math.pi * env[i, c]) for i in range(9))
            k = y * W + x
            check(abs(rad[k, c] - want) < 1e-13, f"lightmap texel ({x},{y}) channel {c}")
            check(abs(mags[0][k, c] - wmag) < 1e-13, f"lightmap magnitude ({x},{y})")
            check(abs(quant[0][k, c] - wq) < 1e-13, f"lightmap quantisation bound ({x},{y})")
    log = []

    class Log:
        def write(self, s):
            log.append(s)

    pts, rad_c = relight_lightmap(glb, "floor", p1, "covered", log=Log())
    check(pts.tolist() == covered, f"lightmap coverage {pts.tolist()}")
    check(np.abs(rad_c - rad[covered]).max() < 1e-14, "covered texels = those of 'all'")
    check(not log, f"coverage count agrees with covered_texels ({''.join(log)})")
    prt1["lightmap"]["covered_texels"] = 6
    doc_bad, data_bad = glb_of(meshes, pngs)
    relight_lightmap(Glb(data_bad), "floor", doc_bad["meshes"][0]["primitives"][0], "covered",
                     log=Log())
    check(any("covers 8 texels" in s and "says 6" in s for s in log),
          "coverage count disagreement reported")
    prt1["lightmap"]["covered_texels"] = len(covered)
    # A triangle on texel boundaries (texel units (0,0) (2,0) (0,2) of a 4×4 map): closed
    # squares touch 6 texels, 3 of them only at a corner; covered_texels picks the reading.
    edge_uv = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.5]])
    edge_png = png_encode(rng.integers(0, 256, size=(4, 4, 4), dtype=np.uint8), 0)
    for n_cov, want_pts, noted in ((6, [0, 1, 2, 4, 5, 8], False), (3, [0, 1, 4], True)):
        eprt = {"order": 1, "channels": 1, "storage": "lightmap", "attributes": [],
                "lightmap": dict(lm([[0]], [0.1], [1.0], n_cov), width=4, height=4),
                "albedo": [1, 1, 1], "environment": [[1, 1, 1]], "diffuse_fresnel": None,
                "specular": None}
        edoc, edata = glb_of([("edge", {"POSITION": np.c_[edge_uv, np.zeros(3)],
                                        "NORMAL": nrm[:3], "TEXCOORD_0": edge_uv}, None, eprt)],
                             [edge_png])
        log.clear()
        pts, _ = relight_lightmap(Glb(edata), "edge", edoc["meshes"][0]["primitives"][0],
                                  "covered", log=Log())
        check(pts.tolist() == want_pts and any("using the latter" in s for s in log) == noted,
              f"boundary-aligned triangle, covered_texels {n_cov}: {pts.tolist()} {log}")

    # Three channels, albedo interpolated at each texel's surface point.
    pts, rad = relight_lightmap(glb, "bounced", p3, "covered")
    a, b, c_ = uv32[0], uv32[1], uv32[2]
    m = np.array([[b[0] - a[0], c_[0] - a[0]], [b[1] - a[1], c_[1] - a[1]]])
    w12 = np.linalg.solve(m, np.array([0.5, 0.5]) - a)   # texel (0, 0): centre inside A
    alb00 = (1 - w12.sum()) * alb32[0] + w12[0] * alb32[1] + w12[1] * alb32[2]
    cen, e = np.array([1.5, 1.5]), c_ - b                # texel (1, 1): nearest on B→C
    s = float((cen - b) @ e / (e @ e))
    alb11 = (1 - s) * alb32[1] + s * alb32[2]
    for (x, y), av in (((0, 0), alb00), ((1, 1), alb11)):
        k = covered.index(y * W + x)
        for c in range(3):
            tt = by_hand_t(x, y, 3, c, 2)
            want = av[c] / math.pi * sum(tt[i] * env[i, c] for i in range(4))
            check(abs(rad[k, c] - want) < 1e-12, f"3-channel lightmap texel ({x},{y}) ch {c}")

    # The command line: every option on a file with a per-vertex and two lightmapped objects.
    vert_prt = {"order": 1, "channels": 1, "storage": "vertex", "environment": env.tolist(),
                "albedo": [0.5, 0.5, 0.5], "lightmap": None, "diffuse_fresnel": None,
                "specular": None, "attributes": ["_PRT_C0_0"]}
    meshes.append(("tri", {"POSITION": pos[:3], "NORMAL": nrm[:3],
                           "_PRT_C0_0": np.tile([1.0, 0, 0, 0], (3, 1))}, None, vert_prt))
    doc, data = glb_of(meshes, pngs)
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "a.glb")
        with open(path, "wb") as fh:
            fh.write(data)
        out = {k: os.path.join(tmp, k + ".csv") for k in ("c", "m", "q", "c2")}
        quiet = open(os.devnull, "w")
        saved = sys.stdout, sys.stderr
        sys.stdout = sys.stderr = quiet
        try:
            rc = main([path, "--colours", out["c"], "--magnitudes", out["m"],
                       "--quantisation", out["q"], "--texels", "covered"])
            rc_cmp = main([path, "--compare", out["c"], "--texels", "covered"])
            rc_all = main([path, "--colours", out["c2"], "--compare", out["c"]])
            rows = open(out["c"]).read().splitlines()
            with open(out["c2"], "w") as fh:         # prt-style: every texel, 0 where uncovered
                fh.write(rows[0] + "\n")
                for line in rows[1:]:
                    fh.write(line + "\n")
                fh.write("floor,7,0.0,0.0,0.0\n")
            rc_zero = main([path, "--compare", out["c2"], "--texels", "covered"])
            with open(out["c2"], "a") as fh:         # …but a texel we lack must be 0 there
                fh.write("floor,9,0.5,0.0,0.0\n")
            rc_nonzero = main([path, "--compare", out["c2"], "--texels", "covered"])
            with open(out["c2"], "w") as fh:
                fh.write("\n".join(rows[:-1] + [rows[-1].rsplit(",", 1)[0] + ",9.0"]) + "\n")
            rc_diff = main([path, "--compare", out["c2"], "--texels", "covered"])
            with open(path, "wb") as fh:
                fh.write(data[:-8])
            rc_bad = main([path, "--colours", out["c2"]])
        finally:
            sys.stdout, sys.stderr = saved
            quiet.close()
        codes = (rc, rc_cmp, rc_all, rc_zero, rc_nonzero, rc_diff, rc_bad)
        check(codes == (0, 0, 0, 0, 2, 2, 1), f"exit codes {codes}")
        got = {tuple(ln.split(",")[:2]): [float(v) for v in ln.split(",")[2:]]
               for ln in open(out["c"]).read().splitlines()[1:]}
        pts, rad = relight_lightmap(Glb(data), "bounced", doc["meshes"][1]["primitives"][0],
                                    "covered")
        check(all(got[("bounced", str(p))] == rad[k].tolist() for k, p in enumerate(pts)),
              "CSV holds the texel radiance (repr round trip)")
        csv = {k: open(out[k]).read().splitlines() for k in ("c", "m", "q")}
        keys = [[ln.split(",")[:2] for ln in csv[k]] for k in ("c", "m", "q")]
        check(keys[0] == keys[1] == keys[2] and csv["c"][0] == "object,point,r,g,b",
              "colours, magnitudes and quantisation rows line up")
        want_keys = ([["floor", str(p)] for p in covered] + [["bounced", str(p)] for p in covered]
                     + [["tri", str(v)] for v in range(3)])
        check(keys[0][1:] == want_keys, "CSV rows: covered texels, then the vertices")
        check(all(ln.endswith(",0.0,0.0,0.0") for ln in csv["q"] if ln.startswith("tri,")),
              "per-vertex rows of the quantisation bound are 0")
    # A texture that is not a valid PNG, refused naming the image.
    broken = list(pngs)
    broken[1] = png_encode(codes1[1], 2, deflate=lambda b: zlib.compress(b)[:-9])
    doc, data = glb_of(meshes, broken)
    try:
        relight_lightmap(Glb(data), "floor", doc["meshes"][0]["primitives"][0])
        check(False, "lightmap with a truncated IDAT accepted")
    except GlbError as exc:
        check("texture [0][1]" in str(exc) and "image 1" in str(exc) and "truncated" in str(exc),
              f"truncated IDAT refused naming the image ({exc})")
    broken[1] = png_encode(codes1[1][:2], 0)                  # 4x2, the map is 4x3
    doc, data = glb_of(meshes, broken)
    try:
        relight_lightmap(Glb(data), "floor", doc["meshes"][0]["primitives"][0])
        check(False, "lightmap texture of the wrong size accepted")
    except GlbError:
        check(True, "")


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
    for part in (self_test_channels, self_test_png, self_test_lightmaps,
                 self_test_vertex_texture):
        try:
            part(check, rng)
        except Exception as exc:                       # a crash is a failed check, named
            check(False, f"{part.__name__} raised {type(exc).__name__}: {exc}")
    status = "PASS" if not fails else "FAIL (" + "; ".join(fails) + ")"
    print(f"gltf_relight self-test: {checks - len(fails)}/{checks} checks passed: {status}")
    return 0 if not fails else 1


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("glb", nargs="?")
    ap.add_argument("--colours", help="write per-vertex / per-texel radiance CSV here")
    ap.add_argument("--eye", help="X,Y,Z (default: root extras.prt.camera.eye)")
    ap.add_argument("--compare", help="prt's CSV to compare with")
    ap.add_argument("--magnitudes", help="write per-vertex / per-texel term magnitudes (same "
                    "CSV layout): the sums with every factor's absolute value, for float32 "
                    "error bounds")
    ap.add_argument("--quantisation", metavar="Q.csv", help="write per texel the bound "
                    "Σ_i (scale/510)·|albedo/π·env_i| on the radiance error due to the 8-bit "
                    "lightmap codes (same CSV layout; 0 for per-vertex objects)")
    ap.add_argument("--texels", choices=("all", "covered"), default="all",
                    help="lightmapped objects: every texel (default), or only the texels a "
                    "TEXCOORD_0 triangle touches (conservative rasterisation, SPEC §3.1)")
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
        quant = [] if args.quantisation else None
        storages = {}
        res = relight_file(args.glb, eye, not args.no_specular, not args.no_fresnel,
                           mags=mags, quant=quant, texels=args.texels, storages=storages)
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
    if args.quantisation:
        write_csv(args.quantisation, quant)
    if args.compare:
        print(f"{args.glb} vs {args.compare}:")
        worst = compare(res, args.compare, lightmapped={k for k, v in storages.items()
                                                         if v == "lightmap"})
        if worst >= 1e-3:
            print(f"gltf_relight: {args.glb}: differs from {args.compare} by {worst:.3g} "
                  "(relative, >= 1e-3)", file=sys.stderr)
            return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
