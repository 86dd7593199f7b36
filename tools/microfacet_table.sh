#!/usr/bin/env bash
# Speed and accuracy of glossy relighting per material and roughness (crates/relight/README.md,
# "Microfacet lobes"): the 37,706-vertex bunny of scenes/bunny_glossy.toml under the courtyard
# map, one material at a time, baked per vertex at order 11 (1024 rays, bounces 0), relit by
# `prt relight --glossy fitted` and `--glossy exact` (each the median of 5 timed frames) and by
# the Phong path for the phong row, against `prt render` (bounces 0, SPP samples per pixel) on
# the object's pixels (mask from the render's depth AOV; needs python3 with numpy, OpenEXR and
# Pillow, e.g. tools/.venv).
# Usage: tools/microfacet_table.sh [OUTDIR] [SPP]
set -euo pipefail
out=${1:-/tmp/microfacet_table}; spp=${2:-1024}
prt=${PRT:-target/release/prt}
py=${PY:-tools/.venv/bin/python}
root=$(pwd)
mkdir -p "$out"
materials=(
  'phong e=20|type = "phong"
albedo = [0.6, 0.6, 0.6]
specular = [0.3, 0.3, 0.3]
exponent = 20.0'
  'blinn_phong e=50|type = "blinn_phong"
albedo = [0.5, 0.5, 0.5]
specular = [0.4, 0.4, 0.4]
exponent = 50.0'
  'ward α=0.2|type = "ward"
albedo = [0.5, 0.5, 0.5]
specular = [0.4, 0.4, 0.4]
roughness = 0.2'
  'cook_torrance m=0.3|type = "cook_torrance"
albedo = [0.5, 0.5, 0.5]
specular = [0.5, 0.5, 0.5]
roughness = 0.3'
  'pbr gold r=0.4|type = "pbr"
base_color = [1.0, 0.78, 0.34]
metallic = 1.0
roughness = 0.4'
  'pbr gold r=0.6|type = "pbr"
base_color = [1.0, 0.78, 0.34]
metallic = 1.0
roughness = 0.6'
  'pbr red plastic r=0.5|type = "pbr"
base_color = [0.8, 0.1, 0.08]
metallic = 0.0
roughness = 0.5'
  'pbr grey r=0.8|type = "pbr"
base_color = [0.5, 0.5, 0.5]
metallic = 0.3
roughness = 0.8'
)
echo "| material | fitted ms | exact ms | Phong-path ms | fitted / Phong | psnr_ldr fitted vs path tracer | exact vs path tracer | fitted vs exact |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|"
i=0
for m in "${materials[@]}"; do
  name=${m%%|*}; body=${m#*|}
  s="$out/m$i.toml"
  cat > "$s" <<TOML
[camera]
eye = [0.0, 0.2, 2.2]
target = [0.0, 0.0, 0.0]
fov_y = 35.0
resolution = [320, 240]
[environment]
file = "$root/scenes/maps/courtyard.exr"
[materials.m]
$body
[[objects]]
mesh = "$root/scenes/meshes/bunny.obj"
material = "m"
[render]
spp = $spp
bounces = 0
TOML
  "$prt" bake "$s" --order 11 --rays 1024 --bounces 0 --out "$out/m$i.prtb" >/dev/null 2>&1
  "$prt" render "$s" --aovs --out "$out/ref$i.exr" >/dev/null 2>&1
  "$py" - "$out/ref$i.exr" "$out/mask.png" <<'PY'
import sys, numpy as np, OpenEXR, Imath
from PIL import Image
f = OpenEXR.InputFile(sys.argv[1]); dw = f.header()['dataWindow']
w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
d = np.frombuffer(f.channel('depth.Z', Imath.PixelType(Imath.PixelType.FLOAT)), dtype=np.float32).reshape(h, w)
Image.fromarray(((np.isfinite(d) & (d > 0) & (d < 1e30)) * 255).astype(np.uint8)).save(sys.argv[2])
PY
  jf=$("$prt" relight "$s" --bake "$out/m$i.prtb" --glossy fitted --json --out "$out/fit$i.exr" 2>/dev/null)
  je=$("$prt" relight "$s" --bake "$out/m$i.prtb" --glossy exact --json --out "$out/exact$i.exr" 2>/dev/null)
  cf=$("$prt" compare "$out/fit$i.exr" "$out/ref$i.exr" --mask "$out/mask.png" --json)
  ce=$("$prt" compare "$out/exact$i.exr" "$out/ref$i.exr" --mask "$out/mask.png" --json)
  cx=$("$prt" compare "$out/fit$i.exr" "$out/exact$i.exr" --mask "$out/mask.png" --json)
  # The Phong path's time on the same bake: the phong row's material, for the ratio.
  if [ "$i" = 0 ]; then phong_ms=$(python3 -c "import json,sys; print(json.loads(sys.argv[1])['shade_ms'])" "$jf"); fi
  python3 - "$name" "$jf" "$je" "$cf" "$ce" "$cx" "$phong_ms" "$i" <<'PY'
import json, sys
name = sys.argv[1]; jf, je, cf, ce, cx = (json.loads(a) for a in sys.argv[2:7])
phong = float(sys.argv[7]); first = sys.argv[8] == "0"
f = lambda c: f"{c['masked_psnr_ldr']:.2f}"
exact = "—" if first else f"{je['shade_ms']:.0f}"
ex = "—" if first else f(ce)
fx = "—" if first else f(cx)
print(f"| {name} | {jf['shade_ms']:.1f} | {exact} | {phong:.1f} | {jf['shade_ms'] / phong:.2f}× | {f(cf)} | {ex} | {fx} |")
PY
  i=$((i + 1))
done
