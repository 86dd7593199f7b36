#!/usr/bin/env bash
# The coarse-floor table (issue 15; crates/bake/README.md, "Coarse floors"): the bunny on a
# 2-triangle floor (scenes/hard/figure_on_quad.toml, 1 bounce) baked per vertex, with adaptive
# subdivision and per texel at several lightmap sizes, each also compressed by clustered PCA
# (prt compress, default 1 % error target), relit and compared with a path-traced reference
# rendered to a 45 dB noise ceiling. One Markdown row per bake: points, bake time, file size,
# shading time (prt relight --json shade_ms, median of 5 frames), and over the object pixels,
# the floor's pixels and the bunny's: relative L2 error, error of the mean, PSNR (8-bit view).
# Needs python3 with numpy, OpenEXR and Pillow (e.g. tools/.venv).
# Usage: tools/coarse_floor_table.sh [OUTDIR] [RAYS] ["SIZES"]
set -euo pipefail
out=${1:-/tmp/coarse_floor}; rays=${2:-1024}; sizes=${3:-"32 64 128 256"}
prt=${PRT:-target/release/prt}
py=${PY:-tools/.venv/bin/python}
scene=scenes/hard/figure_on_quad.toml
mkdir -p "$out"
# Reference and masks: the object pixels from the render's depth AOV; the bunny's from a render
# of the scene without its floor (the floor, below the bunny, never hides it).
"$prt" render "$scene" --target-psnr-ldr 45 --aovs --out "$out/ref.exr" 2>/dev/null >/dev/null
python3 - "$scene" "$out/bunny_only.toml" <<'PY'
import os, sys, tomllib
src, dst = sys.argv[1:]
s = tomllib.load(open(src, "rb"))
base = os.path.dirname(os.path.abspath(src))
def path(p): return p if os.path.isabs(p) else os.path.join(base, p)
s["environment"]["file"] = path(s["environment"]["file"])
s["objects"] = [o for o in s["objects"] if "quad" not in o["mesh"]]
for o in s["objects"]: o["mesh"] = path(o["mesh"])
s["render"] = {"spp": 1, "bounces": 0}
def val(v):
    if isinstance(v, str): return '"%s"' % v
    if isinstance(v, bool): return str(v).lower()
    if isinstance(v, list): return "[" + ", ".join(val(x) for x in v) + "]"
    return repr(v)
with open(dst, "w") as f:
    for k, t in s.items():
        for item in (t if isinstance(t, list) else [t]):
            f.write(("[[%s]]" if isinstance(t, list) else "[%s]") % k + "\n")
            for kk, vv in item.items():
                if isinstance(vv, dict):
                    continue
                f.write(f"{kk} = {val(vv)}\n")
        for kk, vv in (t.items() if isinstance(t, dict) else []):
            if isinstance(vv, dict):
                f.write(f"[{k}.{kk}]\n" + "".join(f"{a} = {val(b)}\n" for a, b in vv.items()))
PY
"$prt" render "$out/bunny_only.toml" --aovs --out "$out/bunny_depth.exr" 2>/dev/null >/dev/null
# name | bake arguments
bakes=("per vertex|")
bakes+=("subdivided (5 levels)|--subdivide")
for s in $sizes; do bakes+=("per texel ${s}²|--per-texel $s"); done
echo "| bake | floor points | all points | bake s | file MB | shade ms | object rel. L2 | object mean | object PSNR | floor rel. L2 | floor mean | floor PSNR | bunny rel. L2 |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
i=0
for b in "${bakes[@]}"; do
  name=${b%%|*}; args=${b#*|}
  f="$out/b$i.prtb"
  t0=$(date +%s.%N)
  # shellcheck disable=SC2086
  "$prt" bake "$scene" --rays "$rays" $args --json --out "$f" > "$out/b$i.json" 2>/dev/null
  t1=$(date +%s.%N)
  "$prt" compress "$f" --out "$out/c$i.prtb" >/dev/null 2>&1
  for v in b c; do
    g="$out/$v$i.prtb"
    label=$name; [ "$v" = c ] && label="$name, compressed"
    j=$("$prt" relight "$scene" --bake "$g" --json --out "$out/$v$i.exr" 2>/dev/null)
    bake_s=$(python3 -c "print(f'{$t1 - $t0:.1f}')")
    "$py" - "$label" "$out/b$i.json" "$j" "$g" "$out/$v$i.exr" "$out/ref.exr" "$out/bunny_depth.exr" "$bake_s" <<'PY'
import json, os, sys
import numpy as np, OpenEXR, Imath
label, bake_json, relight_json, prtb, img, ref, bunny, bake_s = sys.argv[1:]
def read(path, chans):
    f = OpenEXR.InputFile(path); dw = f.header()['dataWindow']
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    t = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, t), dtype=np.float32).reshape(h, w) for c in chans], -1)
a, r = read(img, "RGB"), read(ref, "RGB")
hit = lambda d: np.isfinite(d) & (d > 0) & (d < 1e30)
obj = hit(read(ref, ["depth.Z"])[..., 0]); bun = hit(read(bunny, ["depth.Z"])[..., 0])
floor = obj & ~bun
def srgb8(x):
    x = np.clip(x, 0, 1); y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.round(y * 255)
def stats(m):
    d = a[m] - r[m]
    rel = np.sqrt((d ** 2).sum() / (r[m] ** 2).sum()); mean = a[m].mean() / r[m].mean() - 1
    mse = ((srgb8(a[m]) - srgb8(r[m])) ** 2).mean()
    return rel, mean, 10 * np.log10(255 ** 2 / mse)
b = json.load(open(bake_json)); j = json.loads(relight_json)
objs = {o["name"]: o["points"] for o in b["objects"]}
fp = objs.get("quad.obj", 0); allp = sum(objs.values())
o, f, u = stats(obj), stats(floor), stats(bun)
mb = os.path.getsize(prtb) / 1e6
n = lambda v: f"{v:,}".replace(",", " ")
print(f"| {label} | {n(fp)} | {n(allp)} | {bake_s} | {mb:.2f} | {j['shade_ms']:.2f} | {100*o[0]:.2f} % | {100*o[1]:+.2f} % | {o[2]:.2f} dB | {100*f[0]:.2f} % | {100*f[1]:+.2f} % | {f[2]:.2f} dB | {100*u[0]:.2f} % |")
PY
  done
  i=$((i + 1))
done
