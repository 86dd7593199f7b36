#!/usr/bin/env python3
"""Ray throughput of prt's tracer next to Mitsuba 3's (Embree, driven by Dr.Jit's LLVM
backend) on exactly the same rays and mesh, the two alternated in one run.

  tools/.venv/bin/python tools/ray_peer_probe.py [--mesh scenes/meshes/bunny.obj]
      [--rays 1048576] [--repeats 5] [--rounds 3] [--prt-example target/release/examples/trace_rays]

The batches on the mesh (the first three as `cargo bench -p prt-tracer --bench trace -- rays`
builds them):
- `coherent`: a pinhole camera's rays through the pixel centres of a square grid (40° field of
  view, from 2.5 bounding radii in front of the mesh and 0.3 above, row by row), closest hit;
- `incoherent`: random rays (origins on a sphere of twice the bounding radius around the mesh's
  centre, aimed at random points within half the radius of it), closest hit;
- `shadow`: the incoherent rays as occlusion queries (any hit), unbounded;
- `from the surface`: the rays a renderer's hit samples trace (and a bake's): from points drawn
  uniformly by area on the mesh, moved 10⁻⁴ of the bounding radius off the surface along the
  face normal, in cosine-distributed directions about it (a Lambert BRDF sample), as any-hit and
  closest-hit queries.

prt traces them with `examples/trace_rays.rs` (`Accel::closest_hit`, which also builds the full
hit record with f64 barycentrics and normals, and `Accel::occluded`), one ray at a time per
thread, on every core; the camera batch also in packets of eight consecutive rays
(`Accel::closest_hits`, as the renderer traces a pixel's camera rays). The same program
traces them through plain obvhs too (a CWBVH over the same triangles with obvhs' own
traversals and f32 triangle test, the library `Accel` is built on), so the table shows
whether obvhs is the ceiling. Mitsuba (`llvm_ad_rgb`) traces each batch as one wavefront with
`Scene.ray_intersect_preliminary` (the camera batch with `coherent=True`, Embree's coherent
mode) and `Scene.ray_test`, on Dr.Jit's default thread pool (every core), after one untimed
warm-up (JIT compilation). Each side reports the fastest of `--repeats` passes, per round; the
table gives the best and median round in Mrays/s and the ratios of prt's and obvhs' time to
Mitsuba's. prt and obvhs must each give Mitsuba's hit or miss on all but 0.1 % of each batch
(rays grazing an edge or a vertex), or the script stops.

Build the example first: `cargo build --release -p prt-tracer --example trace_rays`.
"""
import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_compare as mc  # noqa: E402

# The table's rows: (row, batch, trace_rays' prt kind, its plain-obvhs kind, Mitsuba's query).
ROWS = (
    ("coherent", "coherent", "closest", "obvhs_closest", "closest"),
    ("coherent, prt in packets of 8", "coherent", "closest_packets", None, "closest"),
    ("incoherent", "incoherent", "closest", "obvhs_closest", "closest"),
    ("shadow", "incoherent", "occluded", "obvhs_occluded", "any"),
    ("from the surface, any hit", "surface", "occluded", "obvhs_occluded", "any"),
    ("from the surface, closest hit", "surface", "closest", "obvhs_closest", "closest"),
)


def surface_rays(n, positions, faces, radius, seed=11):
    """Rays leaving the mesh's surface: points uniform by area, moved `1e-4 · radius` along
    their face normal, directions cosine-distributed about it."""
    rng = np.random.default_rng(seed)
    a, b, c = (positions[faces[:, k]] for k in range(3))
    cross = np.cross(b - a, c - a)
    area = np.linalg.norm(cross, axis=1)
    keep = area > 0.0
    a, b, c, cross, area = a[keep], b[keep], c[keep], cross[keep], area[keep]
    pick = rng.choice(len(area), size=n, p=area / area.sum())
    r1, r2 = np.sqrt(rng.uniform(0.0, 1.0, n))[:, None], rng.uniform(0.0, 1.0, n)[:, None]
    p = a[pick] * (1.0 - r1) + b[pick] * (r1 * (1.0 - r2)) + c[pick] * (r1 * r2)
    normal = cross[pick] / area[pick][:, None]
    o = p + normal * (1e-4 * radius)
    # Cosine-distributed direction in the frame (t, s, normal).
    helper = np.where(np.abs(normal[:, :1]) < 0.9, [[1.0, 0.0, 0.0]], [[0.0, 1.0, 0.0]])
    t = np.cross(helper, normal)
    t /= np.linalg.norm(t, axis=1, keepdims=True)
    s_ = np.cross(normal, t)
    u, v = rng.uniform(0.0, 1.0, n), rng.uniform(0.0, 1.0, n)
    r, phi = np.sqrt(v), 2.0 * math.pi * u
    z = np.sqrt(np.maximum(0.0, 1.0 - v))
    d = t * (r * np.cos(phi))[:, None] + s_ * (r * np.sin(phi))[:, None] + normal * z[:, None]
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def bounds_sphere(positions):
    """Centre and radius (half the diagonal) of the positions' bounding box."""
    lo, hi = positions.min(axis=0), positions.max(axis=0)
    return (lo + hi) / 2.0, float(np.linalg.norm(hi - lo)) / 2.0


def camera_rays(eye, target, size, fov_deg=40.0):
    """Rays from `eye` through the pixel centres of a `size`×`size` pinhole grid looking at
    `target` (up +y), row 0 at the top, row by row."""
    forward = (target - eye) / np.linalg.norm(target - eye)
    right = np.cross(forward, [0.0, 1.0, 0.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, forward)
    half = math.tan(math.radians(fov_deg) / 2.0)
    c = (np.arange(size) + 0.5) / size * 2.0 - 1.0
    x, y = np.meshgrid(c * half, -c * half)
    d = forward + x.reshape(-1, 1) * right + y.reshape(-1, 1) * up
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    return np.broadcast_to(eye, d.shape).copy(), d


def unit_vectors(rng, n):
    """`n` directions uniform on the sphere."""
    z = rng.uniform(-1.0, 1.0, n)
    phi = rng.uniform(0.0, 2.0 * math.pi, n)
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


def random_rays(n, center, radius, seed=7):
    """Origins on the sphere of radius 2·`radius` around `center`, each aimed at a random point
    within 0.5·`radius` of it."""
    rng = np.random.default_rng(seed)
    o = center + unit_vectors(rng, n) * (2.0 * radius)
    t = center + unit_vectors(rng, n) * (0.5 * radius * rng.uniform(0.0, 1.0, n))[:, None]
    d = t - o
    return o, d / np.linalg.norm(d, axis=1, keepdims=True)


def write_rays(path, o, d):
    """The file `trace_rays` reads: six little-endian f32 per ray. `+ 0.0` turns −0 into +0."""
    np.concatenate([o, d + 0.0], axis=1).astype("<f4").tofile(path)


def prt_trace(example, mesh, rays_path, repeats, threads, hits_path):
    """`trace_rays` on one batch: {kind: Mrays/s} and {kind: hit flags}."""
    run = subprocess.run([example, mesh, rays_path, str(threads), str(repeats), hits_path],
                         capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"trace_rays failed: {run.stderr.strip()}")
    kinds = [json.loads(line) for line in run.stdout.splitlines()]
    flags = np.fromfile(hits_path, dtype=np.uint8).reshape(len(kinds), -1).astype(bool)
    return ({k["kind"]: k["mrays_per_s"] for k in kinds},
            {k["kind"]: f for k, f in zip(kinds, flags)})


def mitsuba_trace(mi, dr, scene, o, d, query, coherent, repeats):
    """Mrays/s of the fastest of `repeats` passes of Mitsuba's `query` ("closest" or "any")
    over the batch, and its answers."""
    ray = mi.Ray3f(mi.Point3f(*[o[:, i].astype(np.float32) for i in range(3)]),
                   mi.Vector3f(*[d[:, i].astype(np.float32) for i in range(3)]))
    dr.eval(ray)

    def once():
        if query == "any":
            hit = scene.ray_test(ray)
        else:
            hit = scene.ray_intersect_preliminary(ray, coherent=coherent).is_valid()
        dr.eval(hit)
        dr.sync_thread()
        return hit

    once()  # warm-up: tracing and compiling the kernel
    best = math.inf
    for _ in range(repeats):
        t = time.perf_counter()
        hit = once()
        best = min(best, time.perf_counter() - t)
    return len(o) / best / 1e6, np.array(hit, dtype=bool)


def check_agreement(row, hits, peer_hits):
    """The number of rays on which a tracer's answers `hits` and Mitsuba's disagree; stops
    above 0.1 % of the batch."""
    disagree = int(np.count_nonzero(hits != peer_hits))
    if disagree * 1000 > len(hits):
        sys.exit(f"{row}: the answers and Mitsuba's disagree on {disagree} of {len(hits)} rays")
    return disagree


def print_table(rates, disagree, sizes, args):
    """Per row: best / median Mrays/s of each tracer over the rounds, and prt's and obvhs'
    time over Mitsuba's (of the best rounds / of the medians)."""
    print(f"Mrays/s on {os.path.basename(args.mesh)}, {args.rounds} rounds of the best of "
          f"{args.repeats} passes (best / median round), {sizes['coherent']} camera rays, "
          f"{sizes['incoherent']} random and as many surface rays; load average "
          f"{os.getloadavg()[0]:.2f}")
    print("| rays | prt | plain obvhs | Mitsuba (Embree) | prt time / Mitsuba time | "
          "obvhs time / Mitsuba time | hit/miss disagreements with Mitsuba (prt, obvhs) |")
    print("|---|---|---|---|---|---|---|")
    for row, *_ in ROWS:
        m = rates[(row, "mitsuba")]
        best_m, med_m = max(m), statistics.median(m)
        cells = [row]
        ratios = []
        for who in ("prt", "obvhs"):
            r = rates[(row, who)]
            if not r:
                cells.append("–")
                ratios.append("–")
                continue
            cells.append(f"{max(r):.2f} / {statistics.median(r):.2f}")
            ratios.append(f"{best_m / max(r):.2f} / {med_m / statistics.median(r):.2f}")
        cells.append(f"{best_m:.2f} / {med_m:.2f}")
        d = disagree[row]
        cells += ratios + [f"{d['prt']}, {d.get('obvhs', '–')}"]
        print("| " + " | ".join(cells) + " |")


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--mesh", default=os.path.join(mc.ROOT, "scenes", "meshes", "bunny.obj"))
    ap.add_argument("--rays", type=int, default=1 << 20, help="rays in the random batch and in the surface batch")
    ap.add_argument("--camera", type=int, default=1024, help="camera grid size (square)")
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--prt-example", default=os.path.join(
        mc.ROOT, "target", "release", "examples", "trace_rays"))
    args = ap.parse_args()
    positions, faces = mc.read_obj(args.mesh)
    if len(positions) == 0 or len(faces) == 0:
        sys.exit(f"{args.mesh}: no triangles")
    if not os.path.exists(args.prt_example):
        sys.exit(f"{args.prt_example} is missing: cargo build --release -p prt-tracer "
                 "--example trace_rays")
    if mc.llvm_library():
        os.environ["DRJIT_LIBLLVM_PATH"] = mc.llvm_library()
    import drjit as dr
    import mitsuba as mi
    mi.set_variant("llvm_ad_rgb")
    scene = mi.load_dict({"type": "scene",
                          "mesh": {"type": "obj", "filename": args.mesh, "face_normals": True}})
    center, radius = bounds_sphere(positions)
    eye = center + np.array([0.0, 0.3 * radius, 2.5 * radius])
    batches = {"coherent": camera_rays(eye, center, args.camera),
               "incoherent": random_rays(args.rays, center, radius),
               "surface": surface_rays(args.rays, positions, faces, radius)}
    threads = os.cpu_count()
    rates = {(row[0], who): [] for row in ROWS for who in ("prt", "obvhs", "mitsuba")}
    disagree = {row[0]: {} for row in ROWS}
    with tempfile.TemporaryDirectory() as tmp:
        for name, (o, d) in batches.items():
            write_rays(os.path.join(tmp, f"{name}.f32"), o, d)
        for _ in range(args.rounds):
            for name, (o, d) in batches.items():
                prt, flags = prt_trace(args.prt_example, args.mesh,
                                       os.path.join(tmp, f"{name}.f32"), args.repeats,
                                       threads, os.path.join(tmp, f"{name}.hits"))
                peer = {}
                for row, batch, prt_kind, obvhs_kind, query in ROWS:
                    if batch != name:
                        continue
                    if query not in peer:
                        peer[query] = mitsuba_trace(mi, dr, scene, o, d, query,
                                                    name == "coherent", args.repeats)
                    rate, peer_hits = peer[query]
                    rates[(row, "mitsuba")].append(rate)
                    for who, kind in (("prt", prt_kind), ("obvhs", obvhs_kind)):
                        if kind is not None:
                            rates[(row, who)].append(prt[kind])
                            disagree[row][who] = check_agreement(f"{row} ({who})",
                                                                 flags[kind], peer_hits)
    print_table(rates, disagree, {"coherent": args.camera ** 2, "incoherent": args.rays}, args)


if __name__ == "__main__":
    main()
