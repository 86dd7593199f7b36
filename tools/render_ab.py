#!/usr/bin/env python3
"""A/B timing of `prt render` between builds, alternating them on a noisy machine.

Usage: tools/render_ab.py SCENE.toml SPP ROUNDS THREADS BIN_A BIN_B [BIN_C ...]

Each round runs every binary once on the scene (in the order given) and reads the render-only
seconds that `prt render` prints (`… in S s (…)`, BVH build and loading excluded). Prints per
binary the minimum and the median over rounds and both as a ratio to the first binary. This
machine drifts by ±10–30 % over minutes: only alternated rounds compare builds, and a few per
cent is only decided by minima over many rounds. Copy each build aside first, e.g.
`cp target/release/prt /tmp/prt_a`.
"""
import os
import re
import statistics
import subprocess
import sys
import tempfile


def render_seconds(binary, scene, spp, threads, out):
    run = subprocess.run(
        [binary, "render", scene, "--spp", spp, "--threads", threads, "--out", out],
        capture_output=True, text=True)
    if run.returncode != 0:
        sys.exit(f"{binary} failed on {scene}: {run.stderr.strip()}")
    m = re.search(r" in ([0-9.]+) s \(", run.stderr)
    if not m:
        sys.exit(f"{binary}: no render time in its output: {run.stderr.strip()}")
    return float(m.group(1))


def main():
    if len(sys.argv) < 7:
        sys.exit(__doc__)
    scene, spp, rounds, threads, bins = (sys.argv[1], sys.argv[2], int(sys.argv[3]),
                                         sys.argv[4], sys.argv[5:])
    times = {b: [] for b in bins}
    with tempfile.TemporaryDirectory() as tmp:
        out = os.path.join(tmp, "ab.exr")
        for _ in range(rounds):
            for b in bins:
                times[b].append(render_seconds(b, scene, spp, threads, out))
    base_min, base_med = min(times[bins[0]]), statistics.median(times[bins[0]])
    for b in bins:
        lo, med = min(times[b]), statistics.median(times[b])
        print(f"{os.path.basename(b):16s} min {lo:.3f} s  median {med:.3f} s  "
              f"min/first {lo / base_min:.3f}  median/first {med / base_med:.3f}")


if __name__ == "__main__":
    main()
