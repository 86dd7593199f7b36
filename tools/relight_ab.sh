#!/usr/bin/env bash
# A/B timing of adaptive relighting between two builds of the relight_timing example.
# Usage: tools/relight_ab.sh BIN_A BIN_B SCENE BAKE ORDER T [ROUNDS] [extra relight_timing options]
# Build each side with `cargo build --release -p prt-report --example relight_timing` and copy
# target/release/examples/relight_timing aside. The two binaries run alternately ROUNDS times
# (default 4), adaptive frames only; each run prints the fastest of its medians, and the script
# prints per binary the minimum and the median over rounds (machines drift by ±10–30 % over
# minutes: alternate, and compare minima).
set -euo pipefail
a=$1; b=$2; scene=$3; bake=$4; order=$5; t=$6; rounds=${7:-4}; shift $(( $# < 7 ? $# : 7 ))
for _ in $(seq "$rounds"); do
  for bin in "$a" "$b"; do
    echo "$bin $("$bin" "$scene" "$bake" "$order" "$t" --reps 2 --adaptive-only "$@" | awk '{print $4}')"
  done
done | python3 -c "
import sys, collections
d = collections.OrderedDict()
for line in sys.stdin:
    b, v = line.split(); d.setdefault(b, []).append(float(v))
for b, v in d.items():
    s = sorted(v)
    print(f'{b}: min {s[0]:.2f} ms  median {s[len(s)//2]:.2f} ms  runs ' + ' '.join(f'{x:.2f}' for x in v))
"
