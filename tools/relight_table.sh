#!/usr/bin/env bash
# Speed against error of adaptive relighting (crates/relight/README.md, "On a real bake").
# Usage: tools/relight_table.sh SCENE BAKE "ORDERS" "ADAPTIVE OPTIONS" [OUTDIR] [RUNS]
# For each order: `prt relight` at full order (the reference image), then RUNS times the
# adaptive relighting with the given options, whose JSON holds its own shading time and the
# full-order time of the same frame (each the median of 5 frames); the fastest of the RUNS is
# kept for each (the machine is shared; the minimum is the least disturbed estimate). Then
# `prt compare` of the adaptive image against the full-order one. One Markdown row per order.
set -euo pipefail
scene=$1; bake=$2; orders=$3; opts=$4; out=${5:-/tmp/relight_table}; runs=${6:-3}
prt=${PRT:-target/release/prt}
mkdir -p "$out"
echo "| SH level (lmax) | order | coeffs | full ms | adaptive ms | FPS full | FPS ours | speed-up | psnr_ldr adaptive vs full | ROI diffuse | ROI specular | mean order d / s | work |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in $orders; do
  "$prt" relight "$scene" --bake "$bake" --order "$n" --out "$out/full$n.exr" >/dev/null 2>&1
  js=()
  for _ in $(seq "$runs"); do
    # shellcheck disable=SC2086
    js+=("$("$prt" relight "$scene" --bake "$bake" --order "$n" --adaptive $opts --json --out "$out/ad$n.exr" 2>/dev/null)")
  done
  c=$("$prt" compare "$out/ad$n.exr" "$out/full$n.exr" --json)
  python3 - "$n" "$c" "${js[@]}" <<'PY'
import json, sys
n = int(sys.argv[1]); c = json.loads(sys.argv[2]); js = [json.loads(a) for a in sys.argv[3:]]
j = js[0]
full = min(x["full_shade_ms"] for x in js); ad = min(x["shade_ms"] for x in js)
p = c["psnr_ldr"]
ps = "∞" if p is None or p > 1e300 else f"{p:.2f}"
md, ms = j.get("mean_order_diffuse"), j.get("mean_order_specular")
mo = f"{md:.2f} / {ms:.2f}" if md is not None else "–"
wf = j.get("work_fraction")
print(f"| {n-1} | {n} | {n*n} | {full:.2f} | {ad:.2f} | {1000/full:.1f} | {1000/ad:.1f} | {full/ad:.2f}× | {ps} | "
      f"{100*j['roi_fraction_diffuse']:.1f} % | {100*j['roi_fraction_specular']:.1f} % | {mo} | {wf:.3f} |")
PY
done
