#!/usr/bin/env bash
# Submits a distributed bounced bake to Slurm, pass by pass: for each pass K = 0..B a job array
# of N shard tasks (`prt bake --shard I/N --pass K --previous pass(K-1).prtb`), then a merge job
# that starts only when every task of the array succeeded (`--dependency=afterok:ARRAY`); the
# next pass's array waits for that merge. Everything is submitted at once; Slurm runs it in
# order. The final bake is OUTDIR/bake.prtb.
#
#   tools/distributed/slurm-bake.sh SCENE N OUTDIR --bounces B [other prt bake options...]
#
# OUTDIR and SCENE must be on a file system every node sees. Environment: PRT (the prt binary
# on the nodes, default `prt`), CPUS (cpus per shard task, default 8), SBATCH (default
# `sbatch`; any command with its options and output, e.g. a wrapper adding --account).
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,13p' "$0" >&2
    exit 2
fi
scene=$1 n=$2 dir=$3
shift 3
prt=${PRT:-prt}
cpus=${CPUS:-8}
sbatch=${SBATCH:-sbatch}
bounces=""
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
    if [ "${args[$i]}" = "--bounces" ]; then bounces=${args[$((i + 1))]}; fi
done
if [ -z "$bounces" ]; then
    echo "slurm-bake.sh: give --bounces B explicitly (the passes are 0..=B)" >&2
    exit 2
fi
mkdir -p "$dir/logs"
options=$(printf ' %q' "$@")
dependency=()
for ((k = 0; k <= bounces; k++)); do
    previous=""
    [ "$k" -gt 0 ] && previous="--previous $(printf %q "$dir/pass$((k - 1)).prtb")"
    # Single quotes keep $SLURM_* for the task's shell.
    task="$(printf %q "$prt") bake $(printf %q "$scene")$options --threads \$SLURM_CPUS_PER_TASK"
    task+=" --shard \$SLURM_ARRAY_TASK_ID/$n --pass $k $previous --json"
    # Later passes read each shard's own hit records from its pass-0 file.
    [ "$k" -gt 0 ] && task+=" --hits $(printf %q "$dir")/pass0-shard\$SLURM_ARRAY_TASK_ID.prtb"
    task+=" --out $(printf %q "$dir")/pass$k-shard\$SLURM_ARRAY_TASK_ID.prtb"
    array=$($sbatch --parsable --job-name="prt-pass$k" --array="0-$((n - 1))" \
        --cpus-per-task="$cpus" "${dependency[@]}" \
        --output="$dir/logs/pass$k-%a.out" --wrap "$task")
    out="$dir/pass$k.prtb"
    [ "$k" -eq "$bounces" ] && out="$dir/bake.prtb"
    merge=$($sbatch --parsable --job-name="prt-merge$k" --dependency="afterok:$array" \
        --output="$dir/logs/merge$k.out" \
        --wrap "$(printf %q "$prt") merge $(printf %q "$dir")/pass$k-shard*.prtb --out $(printf %q "$out")")
    echo "pass $k: shard array $array, merge $merge"
    dependency=(--dependency="afterok:$merge")
done
echo "the final bake will be $dir/bake.prtb (after job $merge)"
