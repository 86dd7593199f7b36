#!/usr/bin/env bash
# SHA-256 of what prt writes, for checking that a code move changes no output (issue 31).
#
#   tools/layout_hashes.sh OUT_DIR > hashes.txt      (before the move)
#   tools/layout_hashes.sh OUT_DIR2 | diff hashes.txt -   (after: no line may differ)
#
# Runs the release `prt` (PRT=path/to/prt to choose another) on the bundled scenes at small
# settings, so that the whole run takes a few minutes on 2 cores: per-vertex bakes at 0 and 1
# bounce, a per-pixel and a per-texel bake, full-order, adaptive and glossy relighting (EXR
# and per-vertex CSV), the glTF export of per-vertex and per-texel bakes, a clustered-PCA
# compression, a reflectance field relit with every reconstruction and a wavelet, and a small
# report whose report.json is hashed with its timing fields removed (report.csv, which has
# timings, is not hashed). Everything is seeded,
# so two runs of the same build print the same lines.
set -euo pipefail
out=${1:?usage: tools/layout_hashes.sh OUT_DIR}
root="$(cd "$(dirname "$0")/.." && pwd)"
prt=${PRT:-$root/target/release/prt}
# A fresh directory: the report caches its reference and bakes there, and says so in
# report.json (`cached`), which would differ from a first run.
if [ -e "$out" ] && [ -n "$(ls -A "$out")" ]; then
    echo "$out is not empty: give a new directory" >&2
    exit 2
fi
mkdir -p "$out"
cd "$out"
q() { "$prt" "$@" >/dev/null 2>&1 || { echo "failed: prt $*" >&2; exit 1; }; }

for s in default glossy bunny_glossy hard_shadow box_textured bunny_pbr; do
    scene="$root/scenes/$s.toml"
    q bake "$scene" --rays 64 --order 6 --bounces 0 --out "$s.b0.prtb"
    q bake "$scene" --rays 32 --order 4 --bounces 1 --out "$s.b1.prtb"
    q relight "$scene" --bake "$s.b0.prtb" --out "$s.full.exr" --vertex-colours "$s.full.csv"
    q relight "$scene" --bake "$s.b0.prtb" --adaptive --threshold 0.02 --out "$s.adaptive.exr"
    q relight "$scene" --bake "$s.b1.prtb" --rotate-y 40 --out "$s.b1.exr"
    q export "$scene" --bake "$s.b0.prtb" --out "$s.b0.glb"
    q export "$scene" --bake "$s.b1.prtb" --out "$s.b1.glb"
done
q relight "$root/scenes/bunny_glossy.toml" --bake bunny_glossy.b0.prtb --glossy hybrid \
    --out bunny_glossy.hybrid.exr
q bake "$root/scenes/hard_shadow.toml" --per-pixel --pixel-samples 2 --rays 32 --order 4 \
    --out hard_shadow.pixel.prtb
q relight "$root/scenes/hard_shadow.toml" --bake hard_shadow.pixel.prtb --out hard_shadow.pixel.exr
quad="$root/scenes/hard/figure_on_quad.toml"
q bake "$quad" --per-texel 32 --rays 32 --order 3 --bounces 1 --out quad.texel.prtb
q relight "$quad" --bake quad.texel.prtb --out quad.texel.exr --vertex-colours quad.texel.csv
q export "$quad" --bake quad.texel.prtb --out quad.texel.glb
q compress default.b0.prtb --clusters 4 --out default.cpca.prtb
q compress default.b0.prtb --error 0.02 --out default.cpca-auto.prtb
# --target-psnr: met per vertex (25 dB), met by falling back to per pixel (30 dB), and not met
# (the refusal's words are hashed).
q bake "$quad" --target-psnr 25 --rays 64 --out quad.target25.prtb
q bake "$quad" --target-psnr 30 --rays 64 --out quad.target30.prtb
if "$prt" bake "$root/scenes/hard_shadow.toml" --target-psnr 30 --rays 32 --out unmet.prtb \
    2>unmet.log >/dev/null; then
    echo "hard_shadow at --target-psnr 30 was met: pick a harder target" >&2
    exit 1
fi
grep '^error' unmet.log > hard_shadow.target.error
rm unmet.log
q relight "$root/scenes/default.toml" --bake default.cpca.prtb --out default.cpca.exr

sun="$root/scenes/hard/figure_on_quad_sun.toml"
q reflectance "$sun" --directions 16x8 --pixel-samples 1 --bounces 0 --out field.prtb
for r in nearest linear cdf97 idw biquadric sh25 bspline; do
    q relight "$sun" --bake field.prtb --reconstruct "$r" --fine 32x16 --out "field.$r.exr"
done
q relight "$sun" --bake field.prtb --reconstruct linear --fine 32x16 --wavelet cdf97 \
    --coefficients 64 --out field.wavelet.exr

q report "$root/scenes/default.toml" --out report --orders 2,4 --reference-spp 16 \
    --reference-psnr 0 --rays 32 --frames 1 --no-budget --target-psnr 0
python3 - report/report.json > report.numbers.json <<'EOF'
import json, sys
TIMING = ("ms", "_s", "time", "seconds", "speed", "busy", "load", "fps", "date", "version")
def strip(v):
    if isinstance(v, dict):
        return {k: strip(x) for k, x in sorted(v.items())
                if not any(t in k.lower() for t in TIMING)}
    if isinstance(v, list):
        return [strip(x) for x in v]
    return v
json.dump(strip(json.load(open(sys.argv[1]))), sys.stdout, indent=1, sort_keys=True)
EOF

# OpenEXR files: the header's attributes sorted by name before hashing, then the rest of the
# file as it is. prt writes them sorted since commit 67d0382; builds before it wrote them in a
# hash map's order that changed from process to process, and this lets them be compared too.
find . -type f ! -path './report/cache/*' ! -name report.json ! -name report.csv ! -name '*.md' ! -name '*.html' \
    ! -name '*.png' | sort | python3 -c '
import hashlib, struct, sys
def canonical(b):
    at, attrs = 8, []
    while b[at] != 0:
        name_end = b.index(0, at); type_end = b.index(0, name_end + 1)
        size = struct.unpack_from("<i", b, type_end + 1)[0]
        end = type_end + 5 + size
        attrs.append(b[at:end]); at = end
    return b[:8] + b"".join(sorted(attrs)) + b[at:]
for path in sys.stdin.read().split("\n"):
    if path:
        b = open(path, "rb").read()
        if path.endswith(".exr"):
            b = canonical(b)
        print(hashlib.sha256(b).hexdigest() + "  " + path)
'
