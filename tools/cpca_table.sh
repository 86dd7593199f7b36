#!/usr/bin/env bash
# Speed, size and accuracy of clustered-PCA compression (prt compress) against the
# uncompressed bake, one Markdown row per (clusters, components) setting:
#
#   tools/cpca_table.sh SCENE BAKE "K1 K2 ..." "M1 M2 ..." [OUTDIR]
#
# For each setting: the compressed file's size, the transfer's relative L2 error, the relit
# image's PSNR (8-bit view) against the uncompressed bake's relit image, and the shading time
# of one frame (prt relight --json shade_ms: median of 5 frames) with the uncompressed time
# measured in the same run. PRT selects the binary (default target/release/prt).
set -euo pipefail
scene=$1 bake=$2 clusters=$3 components=$4 out=${5:-$(mktemp -d)}
prt=${PRT:-target/release/prt}
mkdir -p "$out"
ms() { "$prt" relight "$scene" --bake "$1" --out "$2" --json 2>/dev/null | python3 -c 'import json,sys; print(json.load(sys.stdin)["shade_ms"])'; }
full_ms=$(ms "$bake" "$out/full.exr")
full_size=$(stat -c %s "$bake")
echo "| clusters | components | file (bytes) | size ratio | transfer rel. L2 | relit PSNR vs uncompressed | shade ms (uncompressed $full_ms) | speed-up |"
echo "|---:|---:|---:|---:|---:|---:|---:|---:|"
for k in $clusters; do
  for m in $components; do
    f="$out/k${k}_m${m}.prtb"
    err=$("$prt" compress "$bake" --out "$f" --clusters "$k" --components "$m" --json |
      python3 -c 'import json,sys; b=json.load(sys.stdin)["blocks"]; print("%.2f %%" % (100*max(r["rel_error"] for r in b)))')
    c_ms=$(ms "$f" "$out/k${k}_m${m}.exr")
    psnr=$("$prt" compare "$out/k${k}_m${m}.exr" "$out/full.exr" --json | python3 -c 'import json,sys; print(round(json.load(sys.stdin)["psnr_ldr"],2))')
    size=$(stat -c %s "$f")
    python3 -c "print(f'| $k | $m | $size | {$full_size/$size:.1f}× | $err | $psnr dB | $c_ms | {$full_ms/$c_ms:.2f}× |')"
  done
done
