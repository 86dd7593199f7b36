#!/usr/bin/env bash
# Runs a distributed bounced bake on this machine, pass by pass: N `prt bake --shard I/N --pass K`
# processes at once, then `prt merge`, then the next pass. Prints each pass's wall time and
# rays, and leaves the final bake at OUT. The same sequence slurm-bake.sh runs on a cluster,
# for testing a setup or measuring scaling on one machine.
#
#   tools/distributed/run-local.sh SCENE N OUT.prtb --bounces B [other prt bake options...]
#
# Options go to every pass unchanged (pass --seed and --bounces explicitly). PRT selects the
# binary (default: prt on the PATH, else target/release/prt). Work files go to OUT.passes/.
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,11p' "$0" >&2
    exit 2
fi
scene=$1 n=$2 out=$3
shift 3
prt=${PRT:-$(command -v prt || echo target/release/prt)}
bounces="" per_pixel=0
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
    if [ "${args[$i]}" = "--bounces" ]; then bounces=${args[$((i + 1))]}; fi
    if [ "${args[$i]}" = "--per-pixel" ]; then per_pixel=1; fi
done
if [ -z "$bounces" ]; then
    echo "run-local.sh: give --bounces B explicitly (the passes are 0..=B)" >&2
    exit 2
fi
work="$out.passes"
mkdir -p "$work"
previous=()
for ((k = 0; k <= bounces; k++)); do
    start=$(date +%s.%N)
    pids=()
    for ((i = 0; i < n; i++)); do
        hits=()
        # Every pass but the last of a per-pixel bake gathers at vertices from the shard's hits.
        if [ "$k" -gt 0 ] && { [ "$per_pixel" -eq 0 ] || [ "$k" -lt "$bounces" ]; }; then
            hits=(--hits "$work/pass0-shard$i.prtb")
        fi
        "$prt" bake "$scene" "$@" --shard "$i/$n" --pass "$k" "${previous[@]}" "${hits[@]}" --json \
            --out "$work/pass$k-shard$i.prtb" >"$work/pass$k-shard$i.json" 2>"$work/pass$k-shard$i.log" &
        pids+=($!)
    done
    for i in "${!pids[@]}"; do
        if ! wait "${pids[$i]}"; then
            echo "pass $k shard $i/$n failed:" >&2
            cat "$work/pass$k-shard$i.log" >&2
            exit 1
        fi
    done
    traced=$(python3 -c 'import json,sys; print(sum(json.load(open(f))["rays_traced"] for f in sys.argv[1:]))' \
        "$work"/pass$k-shard*.json)
    merged="$work/pass$k.prtb"
    [ "$k" -eq "$bounces" ] && merged="$out"
    "$prt" merge "$work"/pass$k-shard*.prtb --out "$merged" >/dev/null
    end=$(date +%s.%N)
    printf 'pass %d: %d shards, %.2f s wall (with merge), %s rays, merged file %s bytes\n' \
        "$k" "$n" "$(python3 -c "print($end - $start)")" "$traced" "$(stat -c %s "$merged")"
    previous=(--previous "$merged")
done
