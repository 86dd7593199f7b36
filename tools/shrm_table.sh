#!/usr/bin/env bash
# Glossy relighting by roughness, all four paths (crates/relight/README.md, "Spherical harmonic
# reflection maps"): the 37,706-vertex bunny under the courtyard map in a glTF `pbr` metal (gold
# at roughness 0.1–0.8, and copper at 0.4), baked per vertex at order 11 (1024 rays, bounces 0),
# relit by `prt relight --glossy fitted|hybrid|exact|shrm` (each the median of 5 timed frames;
# hybrid at the default --fit-error 0.1) and a Phong material's path for the time ratio, against
# `prt render` (bounces 0, SPP samples per pixel) on the object's pixels (mask from the render's
# depth AOV; needs python3 with numpy, Pillow and mitsuba, e.g. tools/.venv). Bakes and references
# already in OUTDIR are reused (delete them to redo).
# Usage: tools/shrm_table.sh [OUTDIR] [SPP]
set -euo pipefail
out=${1:-/tmp/shrm_table}; spp=${2:-1024}
prt=${PRT:-target/release/prt}
py=${PY:-tools/.venv/bin/python}
root=$(pwd)
mkdir -p "$out"
scene() { # name material-body
  cat > "$out/$1.toml" <<TOML
[camera]
eye = [0.0, 0.2, 2.2]
target = [0.0, 0.0, 0.0]
fov_y = 35.0
resolution = [320, 240]
[environment]
file = "$root/scenes/maps/courtyard.exr"
[materials.m]
$2
[[objects]]
mesh = "$root/scenes/meshes/bunny.obj"
material = "m"
[render]
spp = $spp
bounces = 0
TOML
  [ -f "$out/$1.prtb" ] || "$prt" bake "$out/$1.toml" --order 11 --rays 1024 --bounces 0 --out "$out/$1.prtb" >/dev/null 2>&1
}
relight() { # name path -> json
  "$prt" relight "$out/$1.toml" --bake "$out/$1.prtb" --glossy "$2" --json --out "$out/$1.$2.exr" 2>/dev/null
}
scene phong 'type = "phong"
albedo = [0.6, 0.6, 0.6]
specular = [0.3, 0.3, 0.3]
exponent = 20.0'
phong_ms=$(relight phong fitted | python3 -c "import json,sys; print(json.load(sys.stdin)['shade_ms'])")
rows=()
for r in 0.1 0.2 0.4 0.6 0.8; do rows+=("gold r=$r|gold$r|[1.0, 0.78, 0.34]|$r"); done
rows+=("copper r=0.4|copper0.4|[0.95, 0.64, 0.54]|0.4")
echo "Phong path (e=20, same mesh and bake settings): $phong_ms ms"
echo "| material | fitted dB (ms) | hybrid dB (ms) | exact dB (ms) | **SHRM** dB (ms) | SHRM / Phong time |"
echo "|---|---:|---:|---:|---:|---:|"
for row in "${rows[@]}"; do
  IFS='|' read -r label name colour rough <<<"$row"
  scene "$name" "type = \"pbr\"
base_color = $colour
metallic = 1.0
roughness = $rough"
  if [ ! -f "$out/$name.ref.exr" ]; then
    "$prt" render "$out/$name.toml" --aovs --out "$out/$name.ref.exr" >/dev/null 2>&1
  fi
  # The object mask from the render's depth AOV (read with Mitsuba's Bitmap, in tools/.venv).
  [ -f "$out/$name.mask.png" ] || "$py" - "$out/$name.ref.exr" "$out/$name.mask.png" <<'PY'
import sys, numpy as np, mitsuba as mi
mi.set_variant('scalar_rgb')
from PIL import Image
layers = dict(mi.Bitmap(sys.argv[1]).split())
d = np.array(layers['depth'], copy=False).astype(np.float32)
d = d[..., 0] if d.ndim == 3 else d
Image.fromarray(((np.isfinite(d) & (d > 0) & (d < 1e30)) * 255).astype(np.uint8)).save(sys.argv[2])
PY
  cells=()
  for path in fitted hybrid exact shrm; do
    j=$(relight "$name" "$path")
    c=$("$prt" compare "$out/$name.$path.exr" "$out/$name.ref.exr" --mask "$out/$name.mask.png" --json)
    cells+=("$(python3 -c "import json,sys; j=json.loads(sys.argv[1]); c=json.loads(sys.argv[2]); print(f\"{c['masked_psnr_ldr']:.2f} ({j['shade_ms']:.0f})|{j['shade_ms']}\")" "$j" "$c")")
  done
  python3 - "$label" "$phong_ms" "${cells[@]}" <<'PY'
import sys
label, phong = sys.argv[1], float(sys.argv[2])
cells = [c.split('|') for c in sys.argv[3:]]
shrm_ms = float(cells[3][1])
print(f"| {label} | {cells[0][0]} | {cells[1][0]} | {cells[2][0]} | **{cells[3][0]}** | {shrm_ms / phong:.2f}× |")
PY
done
