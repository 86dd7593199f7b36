#!/usr/bin/env bash
# Runs a distributed bounced bake on Kubernetes, pass by pass: the Indexed Job of pass K
# (pass-job.yaml), `kubectl wait` for it to complete, the merge Job (merge-job.yaml), wait, then
# pass K+1 with --previous the merged file. The final bake is /data/bake.prtb on the volume.
#
#   tools/distributed/k8s/k8s-bake.sh SHARDS BOUNCES "OTHER PRT BAKE OPTIONS"
#
# e.g. k8s-bake.sh 16 2 "--rays 1024 --seed 0". Needs kubectl and envsubst (gettext).
# TIMEOUT (default 24h) bounds each wait.
set -euo pipefail
if [ $# -lt 3 ]; then
    sed -n '2,9p' "$0" >&2
    exit 2
fi
here=$(cd "$(dirname "$0")" && pwd)
export SHARDS=$1 BOUNCES=$2
export BAKE_OPTIONS="--bounces $2 $3"
timeout=${TIMEOUT:-24h}
export PREVIOUS=""
for ((k = 0; k <= BOUNCES; k++)); do
    export PASS=$k
    export MERGED=/data/passes/pass$k.prtb
    [ "$k" -eq "$BOUNCES" ] && MERGED=/data/bake.prtb
    export HITS=""
    [ "$k" -gt 0 ] && HITS='--hits /data/passes/pass0-shard$JOB_COMPLETION_INDEX.prtb'
    envsubst '${PASS} ${SHARDS} ${PREVIOUS} ${HITS} ${BAKE_OPTIONS}' <"$here/pass-job.yaml" | kubectl apply -f -
    kubectl wait --for=condition=complete "job/prt-pass$k" --timeout="$timeout"
    envsubst '${PASS} ${MERGED}' <"$here/merge-job.yaml" | kubectl apply -f -
    kubectl wait --for=condition=complete "job/prt-merge$k" --timeout="$timeout"
    PREVIOUS="--previous $MERGED"
done
echo "final bake: /data/bake.prtb"
