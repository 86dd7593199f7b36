#!/usr/bin/env bash
# Reflectance fields against per-pixel SH and the path tracer (issue 16; crates/relight/README.md,
# "Reflectance fields"): the figure on the coarse floor under a map (default: the sunrise map,
# whose sun holds 59 % of the energy in 0.1 % of its texels), bounces 0.
#   - the reference: prt render to a 45 dB noise ceiling (with the depth AOV for the masks);
#   - prt reflectance at DIRS directions, 16 footprint samples per pixel (f16 file);
#   - relit with each reconstruction (nearest, linear, cdf97 onto 256×128), and compressed to
#     K coefficients per pixel and channel with each wavelet (linear reconstruction);
#   - per-pixel SH bakes at order 16 (256 coefficients) with the same 16 footprint samples.
# One Markdown row each: shading ms, mean coefficients, rf_rel_l2, and relative L2 / mean /
# PSNR (8-bit view) over the object, floor and bunny pixels.
# Needs python3 with numpy and OpenEXR (tools/.venv). Compressing takes minutes per wavelet.
# Usage: tools/reflectance_table.sh [SCENE] [OUTDIR] [DIRS] [K]
set -euo pipefail
scene=${1:-scenes/hard/figure_on_quad_sun.toml}
out=${2:-/tmp/reflectance_table}; dirs=${3:-64x32}; k=${4:-256}
prt=${PRT:-target/release/prt}
py=${PY:-tools/.venv/bin/python}
mkdir -p "$out"
"$prt" render "$scene" --bounces 0 --target-psnr-ldr 45 --aovs --out "$out/ref.exr" >/dev/null 2>&1
# The bunny's pixels: the scene without its floor (the floor, below, never hides the bunny).
python3 - "$scene" "$out/bunny_only.toml" <<'PY'
import os, re, sys
src, dst = sys.argv[1:]
text = open(src).read()
base = os.path.dirname(os.path.abspath(src))
text = re.sub(r'"(\.\./[^"]+|[^"/]+\.(obj|exr|hdr|glb|gltf))"',
              lambda m: '"%s"' % os.path.normpath(os.path.join(base, m.group(1))), text)
blocks = text.split("[[objects]]")
keep = [blocks[0]] + ["[[objects]]" + b for b in blocks[1:] if "quad.obj" not in b.split("[render]")[0]]
text = "".join(keep)
if "[render]" not in text:
    text += "\n[render]\n"
open(dst, "w").write(text)
PY
"$prt" render "$out/bunny_only.toml" --spp 1 --bounces 0 --aovs --out "$out/bunny_depth.exr" >/dev/null 2>&1
"$prt" reflectance "$scene" --directions "$dirs" --bounces 0 --pixel-samples 16 --f16 --out "$out/rf.prtb" >/dev/null 2>&1
"$prt" bake "$scene" --bounces 0 --per-pixel --pixel-samples 16 --order 16 --out "$out/sh16.prtb" >/dev/null 2>&1
row() { # label image json
  "$py" - "$1" "$2" "$3" "$out/ref.exr" "$out/bunny_depth.exr" <<'PY'
import json, sys
import numpy as np, OpenEXR, Imath
label, img, js, ref, bunny = sys.argv[1:]
def read(path, chans):
    f = OpenEXR.InputFile(path); dw = f.header()['dataWindow']
    w, h = dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1
    t = Imath.PixelType(Imath.PixelType.FLOAT)
    return np.stack([np.frombuffer(f.channel(c, t), dtype=np.float32).reshape(h, w) for c in chans], -1)
a, r = read(img, "RGB"), read(ref, "RGB")
hit = lambda d: np.isfinite(d) & (d > 0) & (d < 1e30)
obj = hit(read(ref, ["depth.Z"])[..., 0]); bun = hit(read(bunny, ["depth.Z"])[..., 0]) & obj
floor = obj & ~bun
def srgb8(x):
    x = np.clip(x, 0, 1); y = np.where(x <= 0.0031308, 12.92 * x, 1.055 * x ** (1 / 2.4) - 0.055)
    return np.round(y * 255)
def stats(m):
    d = a[m] - r[m]
    mse = ((srgb8(a[m]) - srgb8(r[m])) ** 2).mean()
    return (100 * np.sqrt((d ** 2).sum() / (r[m] ** 2).sum()), 100 * (a[m].mean() / r[m].mean() - 1),
            10 * np.log10(255 ** 2 / mse))
j = json.loads(js)
k = j.get("mean_coefficients") or "—"
e = j.get("rf_rel_l2"); e = f"{100 * e:.2f} %" if e is not None else "—"
cells = [label, f"{j['shade_ms']:.1f}", str(k if k == "—" else round(k, 1)), e]
for m in (obj, floor, bun):
    s = stats(m); cells.append(f"{s[0]:.2f} % / {s[1]:+.2f} % / {s[2]:.2f} dB")
print("| " + " | ".join(cells) + " |")
PY
}
echo "| method | shade ms | coefficients | rf_rel_l2 | object rel. L2 / mean / PSNR | floor | bunny |"
echo "|---|---:|---:|---:|---|---|---|"
j=$("$prt" relight "$scene" --bake "$out/sh16.prtb" --json --out "$out/sh16.exr" 2>/dev/null)
row "per-pixel SH, order 16 (256 coefficients)" "$out/sh16.exr" "$j"
for r in nearest linear cdf97; do
  j=$("$prt" relight "$scene" --bake "$out/rf.prtb" --reconstruct "$r" --json --out "$out/$r.exr" 2>/dev/null)
  row "field $dirs, $r onto 256×128" "$out/$r.exr" "$j"
done
for w in haar legall53 cdf97; do
  j=$("$prt" relight "$scene" --bake "$out/rf.prtb" --wavelet "$w" --coefficients "$k" --json --out "$out/w_$w.exr" 2>/dev/null)
  row "field $dirs, linear, $w K = $k" "$out/w_$w.exr" "$j"
done
