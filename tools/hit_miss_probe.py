#!/usr/bin/env python3
"""Where prt's time per sample differs from Mitsuba 3's: the suite's `sphere` scene and two
variants of it, timed side by side in one process, alternating the two renderers.

  tools/.venv/bin/python tools/hit_miss_probe.py [--prt target/release/prt] [--spp 256]
      [--rounds 3] [--scalar] [--threads N] [--prt-arg=--split-lobes=none ...]

- `suite`: the suite's sphere as `mitsuba_compare.py --suite` renders it (about a third of the
  camera samples hit the sphere, the rest see the environment directly);
- `hit`: the camera moved to 1.9 units, so every camera sample hits the sphere (a camera ray,
  an environment sample with its shadow ray, a BRDF sample with its ray, the lookups);
- `miss`: the sphere moved 100 units up, out of view, so every sample is a camera ray that
  escapes and one environment lookup.

Both renderers get the scene `mitsuba_compare.py` writes (same meshes, map, camera; Mitsuba
`llvm_ad_rgb` with its `multijitter` sampler, the best peer of the suite, `max_depth` 2; prt
`--sampler single`). Times are render only: prt's own printed render time, Mitsuba's
`mi.render` after one warm-up render (JIT compilation excluded). Both use every core (Dr.Jit's
default thread pool and prt's), or `--threads N` each (prt's `--threads`, Dr.Jit's
`set_thread_count`): run it with 1 and with every core to compare how each renderer scales.
With `--scalar`, Mitsuba's `scalar_rgb` variant too (the same
scene and sampler, one sample at a time on every core, Embree for its rays as in `llvm_ad_rgb`),
alternated with the other two: how much of the gap is Dr.Jit running many samples per
instruction rather than the cost of one sample's work. Per variant and renderer the minimum and the median over the
rounds, in nanoseconds per sample, and the ratio prt / Mitsuba of each. Keep `--spp` at 256 or
more: at 64 spp a single round gave Mitsuba 258 ns per sample on `suite` against 67–70 at 256
(its fixed cost per render, and the first round's, dominate a short render). Needs the peers' set-up
(tools/requirements-peers.txt, libllvm19) and the suite's work files (run
`mitsuba_compare.py --suite` once, or this script writes them).
"""
import argparse
import copy
import os
import statistics
import subprocess
import sys
import time

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import mitsuba_compare as mc  # noqa: E402

VARIANTS = ("suite", "hit", "miss")

# Mitsuba's variants the probe can time: (column name, Mitsuba variant).
MITSUBA = {"mitsuba": "llvm_ad_rgb", "scalar": "scalar_rgb"}


def variant_spec(spec, name):
    """The suite's sphere spec changed for variant `name`."""
    s = copy.deepcopy(spec)
    if name == "hit":
        s["camera"]["eye"] = [0.0, 0.0, 1.9]
    elif name == "miss":
        s["objects"][0]["translate"] = [0.0, 100.0, 0.0]
    return s


def prt_seconds(prt, toml, spp, extra):
    run = subprocess.run([prt, "render", toml, "--spp", str(spp), "--sampler", "single", "--quiet",
                          "--out", toml[:-5] + "_probe.exr"] + extra, capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"prt render failed on {toml}: {run.stderr}")
    return mc.parse_prt_render_seconds(run.stderr)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--prt", default=os.path.join(mc.ROOT, "target", "release", "prt"))
    ap.add_argument("--spp", type=int, default=256)
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--width", type=int, default=160)
    ap.add_argument("--height", type=int, default=120)
    ap.add_argument("--work", default=os.path.join(mc.ROOT, "out", "mitsuba_compare"))
    ap.add_argument("--prt-arg", action="append", default=[],
                    help="one more argument for prt render (repeatable)")
    ap.add_argument("--scalar", action="store_true",
                    help="also time Mitsuba's scalar_rgb variant")
    ap.add_argument("--threads", type=int, default=None,
                    help="threads for both renderers (default: every core): prt --threads, "
                         "Dr.Jit's thread pool")
    args = ap.parse_args()
    work = os.path.join(args.work, "suite")
    os.makedirs(work, exist_ok=True)
    if mc.llvm_library():
        os.environ["DRJIT_LIBLLVM_PATH"] = mc.llvm_library()
    import mitsuba as mi
    peers = ["mitsuba"] + (["scalar"] if args.scalar else [])
    mi.set_variant("llvm_ad_rgb")
    mc.write_suite_meshes(work)
    mc.write_env(mi, work, 16, mc.SUITE_UPSAMPLE_NAME)
    base = mc.suite_specs(work)["sphere"]
    scenes = {}
    for name in VARIANTS:
        spec = variant_spec(base, name)
        toml = os.path.join(work, f"probe_{name}.toml")
        mc.write_prt_toml(toml, spec, args)
        scenes[(name, "prt")] = toml
        for peer in peers:
            scenes[(name, peer)] = mitsuba_scene(mi, peer, spec, work, args)
    if args.threads is not None:
        # Only now, after the scene files are written: Mitsuba 3.9.1's EXR writing
        # (`write_env`) hung with a one-thread pool.
        import drjit as dr
        dr.set_thread_count(args.threads)
        args.prt_arg = args.prt_arg + ["--threads", str(args.threads)]
    times = {key: [] for key in scenes}
    for k in range(args.rounds):
        for name in VARIANTS:
            for peer in peers:
                mi.set_variant(MITSUBA[peer])
                t = time.perf_counter()
                np.array(mi.render(scenes[(name, peer)], seed=1 + k, spp=args.spp))
                times[(name, peer)].append(time.perf_counter() - t)
            times[(name, "prt")].append(
                prt_seconds(args.prt, scenes[(name, "prt")], args.spp, args.prt_arg))
    print_table(times, peers, args)


def mitsuba_scene(mi, peer, spec, work, args):
    """The Mitsuba scene of `spec` in `peer`'s variant, rendered once (JIT tracing and
    compilation, caches), its sampler's sample count checked."""
    mi.set_variant(MITSUBA[peer])
    scene = mc.build_mitsuba_scene(mi, mc.mitsuba_desc(spec, work, args), args.spp, "multijitter")
    np.array(mi.render(scene, seed=0, spp=args.spp))
    count = int(scene.sensors()[0].sampler().sample_count())
    if count != args.spp:  # multijitter rounds to what it can stratify
        sys.exit(f"Mitsuba's multijitter takes {count} samples per pixel, not {args.spp}")
    return scene


def print_table(times, peers, args):
    """Min / median ns per sample of each renderer and prt's ratio to each peer."""
    n = args.width * args.height * args.spp
    ns = lambda xs: (min(xs) / n * 1e9, statistics.median(xs) / n * 1e9)
    heads = {"mitsuba": "Mitsuba llvm multijitter", "scalar": "Mitsuba scalar multijitter"}
    threads = "every core" if args.threads is None else f"{args.threads} thread(s)"
    print(f"ns per sample, {args.width}x{args.height} at {args.spp} spp, {args.rounds} rounds "
          f"(min / median), {threads}; load average {os.getloadavg()[0]:.2f}."
          + mc.host_line(mc.host()))
    cols = ["variant", "prt"]
    for peer in peers:
        cols += [heads[peer], f"prt / {heads[peer].rsplit(' ', 1)[0]}"]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for name in VARIANTS:
        pmin, pmed = ns(times[(name, "prt")])
        row = [name, f"{pmin:.0f} / {pmed:.0f}"]
        for peer in peers:
            mmin, mmed = ns(times[(name, peer)])
            row += [f"{mmin:.0f} / {mmed:.0f}", f"{pmin / mmin:.2f} / {pmed / mmed:.2f}"]
        print("| " + " | ".join(row) + " |")


if __name__ == "__main__":
    main()
