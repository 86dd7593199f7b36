#!/usr/bin/env bash
# The inverse-lighting table of README.md ("Inverse lighting", issue 35): `prt fit-lighting`
# on 1024-spp path-traced images of a Lambertian and of a Phong "probe" (nine spheres of
# radius 0.4 around a 120°-field camera, so that the visible normals cover most of the sphere
# and the spheres shadow each other little; one view of one object sees only the normals
# facing the camera) under three maps.
#
# For each material × map: render (with --aovs: the variance weights the fit), bake per pixel
# (order 12, 4096 rays, no bounces, as rendered), project the map (`prt sh project`, the
# truth), fit, relight the fit at a new rotation (60°) and compare it, and the truth's
# relighting at the same order, with a path-traced render at that rotation (object pixels).
#
# RADIUS (default 0.4) sets the spheres' radius and WIDTH (default 320; 160 for the README's first
# rows) the image width (4:3).
# With MAX_OCCLUSION=F in the environment the fit keeps only the pixels with at most that
# fraction of their hemisphere blocked (`prt fit-lighting --max-occlusion F`), and with
# ONLY=lambert (or phong) only that material's rows run; the relit comparisons stay on every
# object pixel away from silhouettes (the mask of a fit without the occlusion limit).
# SOURCES=N sets how many compact sources the fit may find beside the SH lighting (`prt
# fit-lighting --sources N`; unset: the command's default, 16; SOURCES=0: the SH-only rows of
# the README before 2026-12-07's fourth session).
# PHONG_MODEL (default fitted; or frozen-cosine) is the forward model of the Phong lobe, in the
# fit (`prt fit-lighting --phong-model`) and in the truth's relighting alike.
#
# Usage: tools/inverse_table.sh WORKDIR [PRT]   (about 40 minutes on 2 cores at the defaults)
set -euo pipefail
work=${1:?usage: tools/inverse_table.sh WORKDIR [PRT]}
prt=${2:-target/release/prt}
repo=$(cd "$(dirname "$0")/.." && pwd)
prt=$(cd "$(dirname "$prt")" && pwd)/$(basename "$prt")
mkdir -p "$work"
cd "$work"

# A UV sphere of unit radius with its normals (64 × 32 quads), and the scenes.
python3 - "$repo" "${RADIUS:-0.4}" "${WIDTH:-320}" <<'EOF'
import math, sys
repo, radius, width = sys.argv[1], float(sys.argv[2]), int(sys.argv[3])
nu, nv = 64, 32
verts = []
for j in range(nv + 1):
    th = math.pi * j / nv
    for i in range(nu + 1):
        ph = 2 * math.pi * i / nu
        verts.append((math.sin(th) * math.cos(ph), math.cos(th), math.sin(th) * math.sin(ph)))
idx = lambda i, j: j * (nu + 1) + i + 1
with open("sphere.obj", "w") as f:
    for v in verts:
        f.write("v %.6f %.6f %.6f\n" % v)
    for v in verts:
        f.write("vn %.6f %.6f %.6f\n" % v)
    for j in range(nv):
        for i in range(nu):
            a, b, c, d = idx(i, j), idx(i + 1, j), idx(i + 1, j + 1), idx(i, j + 1)
            if j > 0:
                f.write("f %d//%d %d//%d %d//%d\n" % (a, a, c, c, b, b))
            if j < nv - 1:
                f.write("f %d//%d %d//%d %d//%d\n" % (a, a, d, d, c, c))
mats = {
    "lambert": 'type = "lambert"\nalbedo = [0.8, 0.7, 0.6]',
    "phong": 'type = "phong"\nalbedo = [0.3, 0.25, 0.2]\nspecular = [0.5, 0.5, 0.5]\nexponent = 10.0',
}
objs = ""
for yaw in (-48, 0, 48):
    for pitch in (-38, 0, 38):
        y, p = math.radians(yaw), math.radians(pitch)
        c = (3 * math.sin(y) * math.cos(p), 3 * math.sin(p), -3 * math.cos(y) * math.cos(p))
        objs += ('[[objects]]\nmesh = "sphere.obj"\nmaterial = "m"\nscale = %g\n'
                 'translate = [%.4f, %.4f, %.4f]\n\n' % ((radius,) + c))
for m, mat in mats.items():
    for env in ("courtyard", "studio", "sunrise"):
        for rot in (0, 60):
            open(f"{m}_{env}_{rot}.toml", "w").write(f'''[camera]
eye = [0.0, 0.0, 0.0]
target = [0.0, 0.0, -1.0]
fov_y = 120.0
resolution = [{width}, {width * 3 // 4}]

[environment]
file = "{repo}/scenes/maps/{env}.exr"
rotation_y = {rot}.0

[materials.m]
{mat}

{objs}[render]
spp = 1024
bounces = 0
seed = 0
''')
EOF

db() { "$prt" compare "$1" "$2" --mask "$3" --json | python3 -c 'import json,sys; print("%.2f" % json.load(sys.stdin)["masked_psnr_hdr"])'; }
echo "| object | map | fitted order | well-determined bands | rel. L2 (well-determined) | by band | condition by band | gain by band | residual | model residual | relit 60°: fit dB | truth dB |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|"
for m in ${ONLY:-lambert phong}; do
  order=$([ "$m" = lambert ] && echo 3 || echo 6)
  for env in courtyard studio sunrise; do
    s0=${m}_${env}_0.toml
    [ -f "${m}_${env}_0.exr" ] || "$prt" render "$s0" --aovs --out "${m}_${env}_0.exr" 2>/dev/null >/dev/null
    [ -f "${m}_${env}_60.exr" ] || "$prt" render "${m}_${env}_60.toml" --out "${m}_${env}_60.exr" 2>/dev/null >/dev/null
    [ -f "${m}_${env}.prtb" ] || "$prt" bake "$s0" --per-pixel --order 12 --rays 4096 --bounces 0 --out "${m}_${env}.prtb" 2>/dev/null >/dev/null
    [ -f "true_${env}.json" ] || "$prt" sh project "$repo/scenes/maps/${env}.exr" --order 12 --json 2>/dev/null > "true_${env}.json"
    python3 - "true_${env}.json" "$order" > "true_${env}_${order}.json" <<'EOF'
import json, sys
j = json.load(open(sys.argv[1])); n = int(sys.argv[2])
print(json.dumps({"order": n, "coefficients": j["coefficients"][:n * n]}))
EOF
    [ -f "mask_${m}.png" ] || "$prt" fit-lighting "${m}_${env}_0.exr" --scene "$s0" \
      --bake "${m}_${env}.prtb" --order 1 --model-order 1 --mask-out "mask_${m}.png" >/dev/null
    "$prt" fit-lighting "${m}_${env}_0.exr" --scene "$s0" --bake "${m}_${env}.prtb" --order "$order" \
      --truth "true_${env}.json" --relight-out "fit_${m}_${env}_60.exr" --rotate-y 60 \
      ${MAX_OCCLUSION:+--max-occlusion "$MAX_OCCLUSION"} ${ROBUST:+--robust} ${SOURCES:+--sources "$SOURCES"} --phong-model "${PHONG_MODEL:-fitted}" \
      --json 2>/dev/null > "fit_${m}_${env}.json"
    # The truth's relighting at the fitted order: the bake relit under the projection's
    # first order² coefficients (fit-lighting's exactness: its own relit image fits back).
    "$prt" relight "$s0" --bake "${m}_${env}.prtb" --order "$order" --rotate-y 60 \
      --phong-model "${PHONG_MODEL:-fitted}" --out "truth_${m}_${env}_60.exr" 2>/dev/null >/dev/null
    fit_db=$(db "fit_${m}_${env}_60.exr" "${m}_${env}_60.exr" "mask_${m}.png")
    truth_db=$(db "truth_${m}_${env}_60.exr" "${m}_${env}_60.exr" "mask_${m}.png")
    python3 - "fit_${m}_${env}.json" "$m" "$env" "$fit_db" "$truth_db" <<'EOF'
import json, sys
j = json.load(open(sys.argv[1])); t = j["truth"]
f = lambda xs, p: " ".join(p % x for x in xs)
print(f"| {sys.argv[2]} | {sys.argv[3]} | {j['order']} | {j['well_determined']} | "
      f"{100 * t['rel_l2_well_determined']:.2f} % | {f([100 * x for x in t['rel_l2_by_band']], '%.1f')} % | "
      f"{f(j['condition_by_band'], '%.0f')} | {f(j['gain_by_band'], '%.3f')} | "
      f"{100 * j['relative_residual']:.2f} % | {100 * t['model_residual']:.2f} % | {sys.argv[4]} | {sys.argv[5]} |")
EOF
  done
done
