#!/usr/bin/env bash
# Runs a distributed bounced bake on Slurm and sees it through, pass by pass (K = 0..B):
#   1. a job array of the shards pass K still needs (`prt bake --shard I/N --pass K
#      [--previous pass(K-1).prtb --hits pass0-shardI.prtb]`, submitted with --requeue so that
#      Slurm requeues them when their node fails);
#   2. waits until the array has left the queue (squeue), however often Slurm requeued it;
#   3. checks every shard file (`prt inspect`: structure and CRC-32 of every section): a
#      missing file (the task failed, was cancelled or killed) or a damaged one is named and
#      its shard re-run, up to TRIES submissions per pass;
#   4. a merge job (`prt merge`), whose output is checked the same way; the final pass's is
#      OUTDIR/bake.prtb.
# Outputs are written to a temporary name and renamed, so a killed task never leaves a
# half-written file, and a task that runs twice writes the same bytes. Running the script
# again on the same OUTDIR resumes: shard and pass files that check out are kept.
#
#   tools/distributed/slurm-bake.sh SCENE N OUTDIR --bounces B [other prt bake options...]
#
# OUTDIR and SCENE must be on a file system every node sees; run the script where `sbatch` and
# `squeue` work (a login node, in tmux, or as a one-CPU job of its own). Environment: PRT (the
# prt binary on the nodes, default `prt`), CPUS (cpus per shard task, default 8), TRIES
# (submissions per pass before giving up, default 3), POLL (seconds between squeue calls,
# default 2), PASS_TIMEOUT (seconds a pass may take, default 86400), SBATCH_OPTIONS (more
# sbatch options, e.g. "--partition=bake --account=lab"). Exit status 0 when OUTDIR/bake.prtb
# is complete and checked, 1 when a pass still failed after TRIES submissions.
set -euo pipefail
if [ $# -lt 4 ]; then
    sed -n '2,29p' "$0" >&2
    exit 2
fi
scene=$1 n=$2 dir=$3
shift 3
prt=${PRT:-prt}
cpus=${CPUS:-8}
tries=${TRIES:-3}
poll=${POLL:-2}
pass_timeout=${PASS_TIMEOUT:-86400}
read -r -a sbatch_options <<<"${SBATCH_OPTIONS:-}"
bounces="" per_pixel=0
args=("$@")
for ((i = 0; i < ${#args[@]}; i++)); do
    if [ "${args[$i]}" = "--bounces" ]; then bounces=${args[$((i + 1))]}; fi
    if [ "${args[$i]}" = "--per-pixel" ]; then per_pixel=1; fi
done
if [ -z "$bounces" ]; then
    echo "slurm-bake.sh: give --bounces B explicitly (the passes are 0..=B)" >&2
    exit 2
fi
mkdir -p "$dir/logs"
options=$(printf ' %q' "$@")
q() { printf %q "$1"; }

# Whether FILE is a complete, intact bake file (prt inspect reads and checks every section).
# Prints the reason when it is not.
check() {
    if [ ! -e "$1" ]; then
        echo "missing"
        return 1
    fi
    local why
    if ! why=$("$prt" inspect "$1" 2>&1 >/dev/null); then
        echo "damaged: ${why//$'\n'/ }"
        return 1
    fi
}

# Waits until job JOB (an array or a single job) has left Slurm's queue.
wait_job() {
    local job=$1 start=$SECONDS
    while [ -n "$(squeue -h -j "$job" -o %i 2>/dev/null || true)" ]; do
        if ((SECONDS - start > pass_timeout)); then
            echo "slurm-bake.sh: job $job still queued after ${pass_timeout}s; cancelling it" >&2
            scancel "$job" || true
            return 1
        fi
        sleep "$poll"
    done
}

# Submits the shard tasks of pass K for the shard indices in the comma list ARRAY; prints the
# array's job id.
submit_pass() {
    local k=$1 array=$2 previous="" task
    [ "$k" -gt 0 ] && previous="--previous $(q "$dir/pass$((k - 1)).prtb")"
    # Single quotes keep $SLURM_* for the task's shell.
    task="$(q "$prt") bake $(q "$scene")$options --threads \$SLURM_CPUS_PER_TASK"
    task+=" --shard \$SLURM_ARRAY_TASK_ID/$n --pass $k $previous --json"
    # Passes that gather bounces at vertices read each shard's own hit records from its pass-0
    # file (all but the last of a per-pixel bake, which traces its pixels instead).
    if [ "$k" -gt 0 ] && { [ "$per_pixel" -eq 0 ] || [ "$k" -lt "$bounces" ]; }; then
        task+=" --hits $(q "$dir")/pass0-shard\$SLURM_ARRAY_TASK_ID.prtb"
    fi
    task+=" --out $(q "$dir")/pass$k-shard\$SLURM_ARRAY_TASK_ID.prtb"
    sbatch --parsable --requeue --job-name="prt-pass$k" --array="$array" \
        --cpus-per-task="$cpus" "${sbatch_options[@]}" --open-mode=append \
        --output="$dir/logs/pass$k-%a.out" --wrap "$task" | cut -d';' -f1
}

# Runs pass K's shards until every shard file checks out (TRIES submissions at most).
run_shards() {
    local k=$1 try todo i why job
    for ((try = 1; ; try++)); do
        todo=()
        for ((i = 0; i < n; i++)); do
            if ! why=$(check "$dir/pass$k-shard$i.prtb"); then
                [ "$try" -gt 1 ] || [ "$why" != missing ] &&
                    echo "pass $k shard $i: $dir/pass$k-shard$i.prtb $why"
                rm -f "$dir/pass$k-shard$i.prtb"
                todo+=("$i")
            fi
        done
        [ ${#todo[@]} -eq 0 ] && return 0
        if [ "$try" -gt "$tries" ]; then
            echo "slurm-bake.sh: pass $k: shards ${todo[*]} still failing after $tries submissions (logs: $dir/logs/pass$k-*.out)" >&2
            return 1
        fi
        local list
        list=$(IFS=,; echo "${todo[*]}")
        job=$(submit_pass "$k" "$list")
        echo "pass $k: job array $job, shards $list (submission $try of $tries)"
        wait_job "$job" || true
    done
}

# Merges pass K's shards into OUT with a Slurm job; the output must check out.
run_merge() {
    local k=$1 out=$2 try job why
    for ((try = 1; try <= tries; try++)); do
        check "$out" >/dev/null && return 0
        job=$(sbatch --parsable --job-name="prt-merge$k" "${sbatch_options[@]}" \
            --output="$dir/logs/merge$k.out" --open-mode=append \
            --wrap "$(q "$prt") merge $(q "$dir")/pass$k-shard*.prtb --out $(q "$out")" | cut -d';' -f1)
        echo "pass $k: merge job $job"
        wait_job "$job" || true
        if why=$(check "$out"); then
            return 0
        fi
        echo "pass $k: merged file $out $why (log: $dir/logs/merge$k.out)"
        # A shard damaged after its check is found again by run_shards.
        run_shards "$k" || return 1
    done
    echo "slurm-bake.sh: pass $k: the merge failed $tries times (log: $dir/logs/merge$k.out)" >&2
    return 1
}

for ((k = 0; k <= bounces; k++)); do
    out="$dir/pass$k.prtb"
    [ "$k" -eq "$bounces" ] && out="$dir/bake.prtb"
    if check "$out" >/dev/null; then
        echo "pass $k: $out is complete (kept)"
        continue
    fi
    run_shards "$k" || exit 1
    run_merge "$k" "$out" || exit 1
done
echo "the final bake is $dir/bake.prtb"
