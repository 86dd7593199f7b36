#!/usr/bin/env python3
"""Writes the meshes of scenes/hard/ (deterministic; standard library only).

Each mesh is a hard case for a naive renderer or baker; the scene files beside them say which
and the test `tests/hard_cases.rs` pins the right behaviour.
"""
import math
import os

OUT = os.path.join(os.path.dirname(__file__), "..", "scenes", "hard")


def write(name, verts, faces, normals=None, header="", uvs=None):
    with open(os.path.join(OUT, name), "w") as f:
        f.write(f"# {header}\n# Written by tools/make_hard_scenes.py.\n")
        for v in verts:
            f.write("v %.9g %.9g %.9g\n" % v)
        if uvs:
            for t in uvs:
                f.write("vt %.9g %.9g\n" % t)
            for n in normals:
                f.write("vn %.9g %.9g %.9g\n" % n)
            for tri in faces:
                f.write("f " + " ".join(f"{i+1}/{i+1}/{i+1}" for i in tri) + "\n")
        elif normals:
            for n in normals:
                f.write("vn %.9g %.9g %.9g\n" % n)
            for a, b, c in faces:
                f.write(f"f {a+1}//{a+1} {b+1}//{b+1} {c+1}//{c+1}\n")
        else:
            for a, b, c in faces:
                f.write(f"f {a+1} {b+1} {c+1}\n")


def uv_sphere(n_lat, n_lon, flip_every=0):
    verts, faces, normals = [], [], []
    for i in range(n_lat + 1):
        th = math.pi * i / n_lat
        for j in range(n_lon):
            ph = 2 * math.pi * j / n_lon
            p = (math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph))
            verts.append(p)
            normals.append(p)
    for i in range(n_lat):
        for j in range(n_lon):
            a = i * n_lon + j
            b = i * n_lon + (j + 1) % n_lon
            c = a + n_lon
            d = b + n_lon
            tris = [(a, b, d), (a, d, c)]
            for k, t in enumerate(tris):
                if flip_every and (len(faces) % flip_every == 0):
                    t = (t[0], t[2], t[1])
                faces.append(t)
    return verts, faces, normals


def main():
    os.makedirs(OUT, exist_ok=True)
    v, f, n = uv_sphere(32, 64)
    write("sphere.obj", v, f, n, "Unit UV sphere with exact vertex normals (radius 1, centre origin).")
    # Inconsistent winding (every third triangle reversed) and inward normals: a loader/shader
    # that trusts either blindly gets black or inside-out shading.
    v, f, n = uv_sphere(24, 48, flip_every=3)
    write("sphere_flipped.obj", v, f, [(-a, -b, -c) for a, b, c in n],
          "UV sphere with inverted normals and every third triangle's winding reversed.")
    # A disc whose centre vertex is shared by 4096 triangles, no normals in the file.
    k = 4096
    verts = [(0.0, 0.0, 0.0)] + [(math.cos(2 * math.pi * i / k), 0.0, math.sin(2 * math.pi * i / k)) for i in range(k)]
    faces = [(0, 1 + (i + 1) % k, 1 + i) for i in range(k)]
    write("fan.obj", verts, faces, None, "Unit disc in y = 0 facing +Y: one vertex shared by 4096 triangles; no normals.")
    # Thin shell: two coplanar, overlapping quads (z-fighting) and a slab 1e-4 thick.
    verts = [(-1, 0, -1), (1, 0, -1), (1, 0, 1), (-1, 0, 1),
             (-0.5, 0, -0.5), (1.5, 0, -0.5), (1.5, 0, 1.5), (-0.5, 0, 1.5),
             (-0.3, 0.2, -0.3), (0.3, 0.2, -0.3), (0.3, 0.2, 0.3), (-0.3, 0.2, 0.3),
             (-0.3, 0.2001, -0.3), (0.3, 0.2001, -0.3), (0.3, 0.2001, 0.3), (-0.3, 0.2001, 0.3)]
    faces = [(0, 2, 1), (0, 3, 2), (4, 6, 5), (4, 7, 6),
             (8, 9, 10), (8, 10, 11),      # slab bottom, facing -Y
             (12, 14, 13), (12, 15, 14)]   # slab top, facing +Y
    write("thin_shell.obj", verts, faces, None,
          "Two coplanar overlapping quads at y = 0 and a slab 1e-4 thick at y = 0.2 (open sides).")
    # An open box (bowl): concave, needs several bounces.
    n = 8
    verts, faces = [], []
    def quad_grid(o, u, w):
        base = len(verts)
        for j in range(n + 1):
            for i in range(n + 1):
                verts.append(tuple(o[c] + u[c] * i / n + w[c] * j / n for c in range(3)))
        for j in range(n):
            for i in range(n):
                a = base + j * (n + 1) + i
                # (u/n) × ((u+w)/n) ∝ u × w: counter-clockwise about the inward normal.
                faces.append((a, a + 1, a + n + 2))
                faces.append((a, a + n + 2, a + n + 1))
    # (origin, u, w) with u × w pointing into the box.
    quad_grid((-1, -1, -1), (0, 0, 2), (2, 0, 0))   # floor, normal +Y
    quad_grid((-1, -1, -1), (2, 0, 0), (0, 2, 0))   # back z=-1, normal +Z
    quad_grid((-1, -1, 1), (0, 2, 0), (2, 0, 0))    # front z=+1, normal -Z
    quad_grid((-1, -1, -1), (0, 2, 0), (0, 0, 2))   # left x=-1, normal +X
    quad_grid((1, -1, -1), (0, 0, 2), (0, 2, 0))    # right x=+1, normal -X
    write("open_box.obj", verts, faces, None, "Open box [-1,1]^3 without its top, faces pointing inward: concave.")
    # The coarsest possible floor: two triangles spanning [-1,1]^2 at y = 0, facing +Y (scaled
    # to tens of metres in the mixed-scale scenes, its triangles are as large as the scene).
    # Its UVs map the square onto the unit square (u = (x+1)/2, vt = (1-z)/2): a lightmap for
    # per-texel bakes (`prt bake --per-texel SIZE`).
    quad = [(-1, 0, -1), (-1, 0, 1), (1, 0, 1), (1, 0, -1)]
    write("quad.obj", quad, [(0, 1, 2), (0, 2, 3)], [(0, 1, 0)] * 4,
          "Two-triangle square [-1,1]^2 at y = 0, facing +Y, with planar UVs.",
          uvs=[((x + 1) / 2, (1 - z) / 2) for x, _, z in quad])


def write_hdr(name, w, h, f):
    """Radiance .hdr with flat (uncompressed) RGBE scanlines."""
    with open(os.path.join(OUT, name), "wb") as fp:
        fp.write(b"#?RADIANCE\n# Written by tools/make_hard_scenes.py (flat RGBE scanlines).\nFORMAT=32-bit_rle_rgbe\n\n")
        fp.write(f"-Y {h} +X {w}\n".encode())
        for y in range(h):
            for x in range(w):
                r, g, b = f(x, y)
                m = max(r, g, b)
                if m < 1e-32:
                    fp.write(bytes([0, 0, 0, 0]))
                    continue
                e = math.frexp(m)[1]
                sc = 256.0 / (2.0 ** e)
                fp.write(bytes([int(r * sc), int(g * sc), int(b * sc), e + 128]))


def maps():
    write_hdr("uniform.hdr", 8, 4, lambda x, y: (1.0, 1.0, 1.0))
    # A smooth sky: brightness varies with elevation only (rows), 64×32.
    write_hdr("gradient_sky.hdr", 64, 32,
              lambda x, y: (0.2 + 0.8 * (1 - y / 31), 0.3 + 0.7 * (1 - y / 31), 0.5 + 0.5 * (1 - y / 31)))
    # Light from above the horizon only (rows 0-15), varying with azimuth; black below, so a
    # floor's size cannot change what a part standing on it receives (mixed-scale scenes).
    write_hdr("upper_sky.hdr", 64, 32,
              lambda x, y: (0.0, 0.0, 0.0) if y >= 16 else
              tuple(c * (0.8 + 0.4 * math.sin(2 * math.pi * (x + 0.5) / 64) ** 2) for c in (1.0, 0.95, 0.85)))


if __name__ == "__main__":
    maps()
    main()
