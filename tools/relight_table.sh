#!/usr/bin/env bash
# Speed against error of adaptive relighting (crates/relight/README.md, "On a real bake").
# Usage: tools/relight_table.sh SCENE BAKE "ORDERS" "ADAPTIVE OPTIONS" [OUTDIR]
# For each order: `prt relight` at full order (image + timing), then adaptive with the given
# options (its JSON holds both its own and the full-order shading time of the same frame, each
# the fastest of 5), and `prt compare` of the adaptive image against the full-order one.
# Prints one Markdown row per order.
set -euo pipefail
scene=$1; bake=$2; orders=$3; opts=$4; out=${5:-/tmp/relight_table}
prt=${PRT:-target/release/prt}
mkdir -p "$out"
echo "| order | coeffs | full ms | adaptive ms | speed-up | psnr_ldr adaptive vs full | ROI diffuse | ROI specular | mean order d / s |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for n in $orders; do
  "$prt" relight "$scene" --bake "$bake" --order "$n" --out "$out/full$n.exr" >/dev/null
  # shellcheck disable=SC2086
  j=$("$prt" relight "$scene" --bake "$bake" --order "$n" --adaptive $opts --json --out "$out/ad$n.exr")
  c=$("$prt" compare "$out/ad$n.exr" "$out/full$n.exr" --json)
  python3 - "$n" "$j" "$c" <<'PY'
import json, sys
n = int(sys.argv[1]); j = json.loads(sys.argv[2]); c = json.loads(sys.argv[3])
p = c["psnr_ldr"]
ps = "∞" if p is None or p == float("inf") or p > 1e300 else f"{p:.2f}"
md = j.get("mean_order_diffuse"); ms = j.get("mean_order_specular")
mo = f"{md:.2f} / {ms:.2f}" if md is not None else "–"
print(f"| {n} | {n*n} | {j['full_shade_ms']:.2f} | {j['shade_ms']:.2f} | {j['full_shade_ms']/j['shade_ms']:.2f}× | {ps} | "
      f"{100*j['roi_fraction_diffuse']:.1f} % | {100*j['roi_fraction_specular']:.1f} % | {mo} |")
PY
done
