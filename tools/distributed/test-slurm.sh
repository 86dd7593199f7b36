#!/usr/bin/env bash
# The distributed bake on a real Slurm, with faults (issue 36). Installs Debian's slurm-wlm
# and munge when they are missing (needs root), starts munged, slurmctld and slurmd on this
# machine (one node with this machine's CPUs, a generated slurm.conf, its own ports and munge
# socket, everything under a temporary directory), then:
#   1. a per-vertex and a per-pixel 2-bounce bake through slurm-bake.sh (real sbatch job
#      arrays, squeue), each byte for byte the unsharded local bake;
#   2. faults, each ending in the unsharded bake's bytes: scancel of one array element
#      mid-pass and kill -9 of one task's prt process (per vertex in pass 0, and per pixel in
#      the pixel-tracing last pass); the node taken down mid-pass (scontrol update
#      state=down) and brought back (state=resume); a task that runs twice (scontrol requeue
#      of a finished task: same bytes again); a truncated and a corrupted shard file left in
#      the output directory (per vertex in pass 0, per pixel in the last pass: named, re-run,
#      the rest kept);
#   3. the scheduler's overhead: the clean per-vertex run against run-local.sh's same passes.
# Tears everything down and exits 0 only if every check held.
#
#   tools/distributed/test-slurm.sh [PRT]        (PRT: the prt binary, default target/release/prt)
set -euo pipefail
root="$(cd "$(dirname "$0")/../.." && pwd)"
prt=$(realpath "${1:-$root/target/release/prt}")
driver="$root/tools/distributed/slurm-bake.sh"
failures=0
say() { printf '[test-slurm %4ds] %s\n' "$SECONDS" "$*"; }
fail() { say "FAIL: $*"; failures=$((failures + 1)); }

if ! command -v slurmctld >/dev/null || ! command -v munged >/dev/null; then
    say "installing slurm-wlm and munge"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq && apt-get install -y -qq slurm-wlm munge >/dev/null
fi

work=$(mktemp -d /tmp/prt-slurm.XXXXXX)
chmod 700 "$work"
pids=()
teardown() {
    set +e
    [ -n "${SLURM_CONF:-}" ] && scancel --user="$(id -un)" >/dev/null 2>&1
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
    sleep 1
    for p in "${pids[@]}"; do kill -9 "$p" 2>/dev/null; done
    rm -rf "$work"
}
trap teardown EXIT

# --- the daemons -------------------------------------------------------------------------
read -r port_ctl port_d < <(python3 -c '
import socket
s = [socket.socket() for _ in range(2)]
for x in s: x.bind(("127.0.0.1", 0))
print(*[x.getsockname()[1] for x in s])')
host=$(hostname -s)
dd if=/dev/urandom of="$work/munge.key" bs=1024 count=1 status=none
chmod 600 "$work/munge.key"
mkdir -p "$work"/{state,spool,log}
munged --force --socket="$work/munge.sock" --key-file="$work/munge.key" \
    --pid-file="$work/munged.pid" --log-file="$work/log/munged.log" --seed-file="$work/munged.seed"
pids+=("$(cat "$work/munged.pid")")
cat >"$work/slurm.conf" <<EOF
ClusterName=prttest
SlurmctldHost=$host
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$work/munge.sock
CredType=cred/munge
SlurmctldPort=$port_ctl
SlurmdPort=$port_d
StateSaveLocation=$work/state
SlurmdSpoolDir=$work/spool
SlurmctldPidFile=$work/slurmctld.pid
SlurmdPidFile=$work/slurmd.pid
SlurmctldLogFile=$work/log/slurmctld.log
SlurmdLogFile=$work/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SchedulerType=sched/backfill
# Launch jobs as soon as they are submitted or their predecessors end (a test waits on every
# job; the defaults batch scheduling over seconds, which suits a busy cluster).
SchedulerParameters=sched_min_interval=0,batch_sched_delay=0,default_queue_depth=100
SelectType=select/cons_tres
SelectTypeParameters=CR_CPU
ReturnToService=1
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
SlurmdTimeout=30
NodeName=$host CPUs=$(nproc) State=UNKNOWN
PartitionName=main Nodes=ALL Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$work/slurm.conf"
slurmctld -D -i >"$work/log/slurmctld.out" 2>&1 &
pids+=($!)
slurmd -D >"$work/log/slurmd.out" 2>&1 &
pids+=($!)
for ((t = 0; ; t++)); do
    state=$(sinfo -h -n "$host" -o %T 2>/dev/null || true)
    [ "$state" = idle ] && break
    if [ "$t" -ge 60 ]; then
        say "the node did not come up (state '$state')"
        tail -20 "$work/log/slurmctld.log" "$work/log/slurmd.log" >&2 || true
        exit 1
    fi
    sleep 1
done
say "slurm $(sinfo -V | cut -d' ' -f2) up: node $host, $(nproc) CPUs"

# --- bakes -------------------------------------------------------------------------------
scene="$root/scenes/hard/figure_on_quad.toml"
light=(--bounces 2 --rays 64 --order 4 --seed 3)
pixel=(--bounces 2 --rays 64 --order 4 --seed 3 --per-pixel --pixel-samples 1)
# Pass 0 shard tasks of about 3 s each on one CPU: time to inject a fault into a running task.
heavy=(--bounces 2 --rays 16384 --order 4 --seed 3)
# Likewise for the pixel-tracing last pass of a per-pixel bake (`prt bake --plan-shards 3`
# --threads 1: 24 s per shard at 4096 rays, so about 3 s at 512).
pixel_heavy=(--bounces 2 --rays 512 --order 4 --seed 3 --per-pixel --pixel-samples 1)
local_bake() { # NAME OPTIONS...: the unsharded bake, the reference bytes
    local name=$1
    shift
    "$prt" bake "$scene" "$@" --out "$work/$name.prtb" >/dev/null 2>&1
}
local_bake light "${light[@]}"
local_bake pixel "${pixel[@]}"
local_bake heavy "${heavy[@]}"
local_bake pixel_heavy "${pixel_heavy[@]}"

# Runs the driver: NAME OUTDIR OPTIONS... (in the foreground; its output in OUTDIR.log).
drive() {
    local out=$2
    shift 2
    PRT="$prt" CPUS=1 POLL=0.5 PASS_TIMEOUT=600 bash "$driver" "$scene" 3 "$out" "$@" \
        >"$out.log" 2>&1
}
same() { # NAME OUTDIR: the driver's final bake is the unsharded bake's bytes
    if cmp -s "$work/$1.prtb" "$2/bake.prtb"; then
        say "ok: $3: byte-identical to the unsharded bake"
    else
        fail "$3: $2/bake.prtb differs from the unsharded bake"
        cat "$2.log" >&2 || true
    fi
}
# The job id of pass K's first array, from a running driver's log.
array_of() {
    local log=$1 k=$2 job=""
    for ((t = 0; t < 600; t++)); do
        job=$(sed -n "s/^pass $k: job array \([0-9]*\),.*/\1/p" "$log" | head -1)
        [ -n "$job" ] && break
        sleep 0.1
    done
    echo "$job"
}
# Waits until array task JOB_I is running.
running() {
    for ((t = 0; t < 600; t++)); do
        [ "$(squeue -h -j "$1" -o %T 2>/dev/null)" = RUNNING ] && return 0
        sleep 0.1
    done
    return 1
}

# Cancels task TASK of pass K (the driver's first array of it, from LOG) while it runs.
cancel_running() { # LOG K TASK WHAT
    local job
    job=$(array_of "$1" "$2")
    if [ -n "$job" ] && running "${job}_$3"; then
        scancel "${job}_$3"
        say "cancelled task ${job}_$3 ($4) while it ran"
    else
        fail "scancel ($4): task $3 of pass $2 never ran"
    fi
}
# Kills (SIGKILL) the prt process of shard I of pass K of the run writing to OUTDIR.
kill_running() { # OUTDIR K I WHAT
    local victim=""
    for ((t = 0; t < 600; t++)); do
        victim=$(pgrep -f -- "--shard $3/3 --pass $2 .*$1/" | head -1 || true)
        [ -n "$victim" ] && break
        sleep 0.1
    done
    if [ -n "$victim" ] && kill -9 "$victim"; then
        say "killed prt (pid $victim) of pass $2 shard $3 ($4) with SIGKILL"
    else
        fail "kill -9 ($4): the prt process of pass $2 shard $3 was never seen"
    fi
}

start=$(date +%s.%N)
drive light "$work/v" "${light[@]}" || fail "per-vertex run: the driver failed"
slurm_s=$(python3 -c "print($(date +%s.%N) - $start)")
same light "$work/v" "per-vertex 2-bounce bake, 3 shards"
drive pixel "$work/p" "${pixel[@]}" || fail "per-pixel run: the driver failed"
same pixel "$work/p" "per-pixel 2-bounce bake, 3 shards"

# scancel of one array element while it runs.
drive heavy "$work/cancel" "${heavy[@]}" &
d=$!
cancel_running "$work/cancel.log" 0 1 "per vertex"
wait "$d" || fail "scancel run: the driver failed"
grep -q "pass 0 shard 1: .* missing" "$work/cancel.log" || fail "scancel: the driver did not re-run shard 1"
same heavy "$work/cancel" "one task cancelled (scancel), re-run by the driver"

# kill -9 of one task's prt process.
drive heavy "$work/kill" "${heavy[@]}" &
d=$!
kill_running "$work/kill" 0 2 "per vertex"
wait "$d" || fail "kill -9 run: the driver failed"
grep -q "pass 0 shard 2: .* missing" "$work/kill.log" || fail "kill -9: the driver did not re-run shard 2"
same heavy "$work/kill" "one task's prt killed (SIGKILL), re-run by the driver"

# Both in the pixel-tracing last pass of a per-pixel bake: task 1 cancelled, shard 0's prt
# killed.
drive pixel_heavy "$work/pfault" "${pixel_heavy[@]}" &
d=$!
cancel_running "$work/pfault.log" 2 1 "per pixel, last pass"
kill_running "$work/pfault" 2 0 "per pixel, last pass"
wait "$d" || fail "per-pixel fault run: the driver failed"
grep -q "pass 2 shard 1: .* missing" "$work/pfault.log" || fail "per-pixel: shard 1 not re-run"
grep -q "pass 2 shard 0: .* missing" "$work/pfault.log" || fail "per-pixel: shard 0 not re-run"
same pixel_heavy "$work/pfault" "per-pixel last pass: one task cancelled, one killed, both re-run"

# The node goes down while pass 0 runs, and comes back.
drive heavy "$work/down" "${heavy[@]}" &
d=$!
job=$(array_of "$work/down.log" 0)
if [ -n "$job" ] && running "${job}_0"; then
    scontrol update nodename="$host" state=down reason="prt fault test"
    say "node $host $(sinfo -h -n "$host" -o %T) while ${job}_0 ran"
    sleep 3
    squeue -h -o '%i %T %r' | sed 's/^/[test-slurm]   queue: /'
    scontrol update nodename="$host" state=resume
    say "node $host $(sinfo -h -n "$host" -o %T) again"
    # Slurm holds a requeued job back for a while (BeginTime, about two minutes); let it go now.
    scontrol update jobid="$job" StartTime=now || true
else
    fail "node down: pass 0 never ran"
fi
wait "$d" || fail "node-down run: the driver failed"
same heavy "$work/down" "the node down mid-pass and back"

# A task that runs twice: requeue a finished pass-0 task of the clean run; its second run
# writes the same bytes, and merging again gives the same bake.
cp "$work/v/pass0-shard1.prtb" "$work/first-run.prtb"
job=$(array_of "$work/v.log" 0)
if scontrol requeue "${job}_1" 2>"$work/requeue.err"; then
    scontrol update jobid="${job}_1" StartTime=now || true
    for ((t = 0; t < 600; t++)); do
        [ -z "$(squeue -h -j "${job}_1" -o %i 2>/dev/null)" ] && break
        sleep 0.2
    done
    if cmp -s "$work/first-run.prtb" "$work/v/pass0-shard1.prtb" &&
        [ "$(grep -c '"rays_traced"' "$work/v/logs/pass0-1.out")" -ge 2 ]; then
        say "ok: a task run twice (scontrol requeue ${job}_1) wrote the same bytes"
    else
        fail "task run twice: pass0-shard1.prtb differs or the task did not run again"
    fi
    "$prt" merge "$work"/v/pass0-shard*.prtb --out "$work/v/remerged.prtb" >/dev/null
    cmp -s "$work/v/remerged.prtb" "$work/v/pass0.prtb" || fail "task run twice: the re-merged pass differs"
else
    fail "scontrol requeue ${job}_1: $(cat "$work/requeue.err")"
fi

# A truncated and a corrupted shard file in the output directory: named, re-run, and only
# checked files merged; the intact shard is kept.
mkdir -p "$work/bad"
cp "$work/v/pass0-shard0.prtb" "$work/v/pass0-shard1.prtb" "$work/v/pass0-shard2.prtb" "$work/bad/"
truncate -s 1000 "$work/bad/pass0-shard0.prtb"
python3 -c '
import sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read()); b[len(b) // 2] ^= 0x40
open(p, "wb").write(b)' "$work/bad/pass0-shard1.prtb"
kept=$(stat -c %Y "$work/bad/pass0-shard2.prtb")
drive light "$work/bad" "${light[@]}" || fail "damaged-shards run: the driver failed"
grep -q "pass 0 shard 0: $work/bad/pass0-shard0.prtb damaged" "$work/bad.log" ||
    fail "truncated shard not named"
grep -q "pass 0 shard 1: $work/bad/pass0-shard1.prtb damaged" "$work/bad.log" ||
    fail "corrupted shard not named"
grep -q "shards 0,1 " "$work/bad.log" || fail "the driver did not re-run exactly shards 0 and 1"
[ "$(stat -c %Y "$work/bad/pass0-shard2.prtb")" = "$kept" ] || fail "the intact shard was not kept"
same light "$work/bad" "a truncated and a corrupted shard file, named and re-run"

# The same in the last pass of the per-pixel bake: the run resumes from the kept files of
# passes 0 and 1 and re-runs exactly the damaged shards.
mkdir -p "$work/pbad"
cp "$work"/p/pass*.prtb "$work/pbad/"
truncate -s 1000 "$work/pbad/pass2-shard2.prtb"
python3 -c '
import sys
p = sys.argv[1]; b = bytearray(open(p, "rb").read()); b[len(b) // 3] ^= 0x01
open(p, "wb").write(b)' "$work/pbad/pass2-shard0.prtb"
drive pixel "$work/pbad" "${pixel[@]}" || fail "per-pixel damaged-shards run: the driver failed"
grep -q "pass 1: $work/pbad/pass1.prtb is complete (kept)" "$work/pbad.log" ||
    fail "per-pixel resume: pass 1 was not kept"
grep -q "pass 2: job array [0-9]*, shards 0,2 " "$work/pbad.log" ||
    fail "per-pixel: the driver did not re-run exactly shards 0 and 2"
same pixel "$work/pbad" "per-pixel: a truncated and a corrupted last-pass shard, named and re-run"

# The scheduler's overhead: the same passes on this machine without Slurm.
start=$(date +%s.%N)
PRT="$prt" bash "$root/tools/distributed/run-local.sh" "$scene" 3 "$work/local.prtb" "${light[@]}" >/dev/null
local_s=$(python3 -c "print($(date +%s.%N) - $start)")
cmp -s "$work/local.prtb" "$work/light.prtb" || fail "run-local.sh differs from the unsharded bake"
say "$(printf 'overhead: the per-vertex bake took %.1f s under Slurm (submission to last merge) and %.1f s with run-local.sh' "$slurm_s" "$local_s")"

if [ "$failures" -eq 0 ]; then
    say "every check held"
else
    say "$failures checks failed (daemon logs: $work/log, kept)"
    trap - EXIT
    set +e
    scancel --user="$(id -un)" >/dev/null 2>&1
    for p in "${pids[@]}"; do kill "$p" 2>/dev/null; done
    exit 1
fi
