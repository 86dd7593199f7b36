#!/usr/bin/env bash
# Speed against error of adaptive relighting over rotations of the environment (one frame per
# rotation, as `prt relight --rotate-y DEG` shades it).
# Usage: tools/relight_rotations.sh SCENE BAKE ORDER "DEGREES" "ADAPTIVE OPTIONS" [OUTDIR] [RUNS] [UNIFORM_ORDER]
# For each angle: `prt relight` at full order ORDER (the reference image), then RUNS times the
# adaptive relighting with the given options (the fastest run's shading time and the full-order
# time of the same frame, each the median of 5 frames), `prt compare` of the adaptive image
# against the full-order one, and (if UNIFORM_ORDER is given) the full-order image at that lower
# order against the same reference. One Markdown row per angle.
set -euo pipefail
scene=$1; bake=$2; order=$3; degrees=$4; opts=$5; out=${6:-/tmp/relight_rotations}; runs=${7:-3}
uniform=${8:-}
prt=${PRT:-target/release/prt}
mkdir -p "$out"
echo "| rotate-y | full ms | adaptive ms | speed-up | psnr_ldr adaptive vs full | work | mean order d / s |${uniform:+ psnr_ldr order $uniform vs full | order $uniform ms |}"
echo "|---:|---:|---:|---:|---:|---:|---:|${uniform:+---:|---:|}"
for deg in $degrees; do
  "$prt" relight "$scene" --bake "$bake" --order "$order" --rotate-y "$deg" --out "$out/full$deg.exr" >/dev/null 2>&1
  js=()
  for _ in $(seq "$runs"); do
    # shellcheck disable=SC2086
    js+=("$("$prt" relight "$scene" --bake "$bake" --order "$order" --rotate-y "$deg" --adaptive $opts --json --out "$out/ad$deg.exr" 2>/dev/null)")
  done
  c=$("$prt" compare "$out/ad$deg.exr" "$out/full$deg.exr" --json)
  u=null; ums=null
  if [ -n "$uniform" ]; then
    ums=$("$prt" relight "$scene" --bake "$bake" --order "$uniform" --rotate-y "$deg" --json --out "$out/uni$deg.exr" 2>/dev/null)
    u=$("$prt" compare "$out/uni$deg.exr" "$out/full$deg.exr" --json)
  fi
  python3 - "$deg" "$c" "$u" "$ums" "${js[@]}" <<'PY'
import json, sys
deg = sys.argv[1]; c = json.loads(sys.argv[2]); u = json.loads(sys.argv[3]); ums = json.loads(sys.argv[4])
js = [json.loads(a) for a in sys.argv[5:]]
full = min(x["full_shade_ms"] for x in js); ad = min(x["shade_ms"] for x in js)
fmt = lambda p: "∞" if p is None or p > 1e300 else f"{p:.2f}"
j = js[0]
row = (f"| {deg} | {full:.2f} | {ad:.2f} | {full / ad:.2f}× | {fmt(c['psnr_ldr'])} | "
       f"{j['work_fraction']:.3f} | {j['mean_order_diffuse']:.2f} / {j['mean_order_specular']:.2f} |")
if u is not None:
    row += f" {fmt(u['psnr_ldr'])} | {ums['shade_ms']:.2f} |"
print(row)
PY
done
