#!/usr/bin/env bash
# Submits a sharded wipdr eval or sweep to Slurm: the array job, then the merge as a job that
# runs only when every array task succeeded (--dependency=afterok). Prints both job ids.
#
#   docs/cluster/submit.sh eval 8     # WIPDR_FLOORS, WIPDR_OUT (, WIPDR_CACHE_DIR) set
#   docs/cluster/submit.sh sweep 16   # WIPDR_SWEEP too
#
# Extra sbatch options (partition, account, time) go in SBATCH_* variables, which sbatch
# reads itself (SBATCH_PARTITION, SBATCH_ACCOUNT, SBATCH_TIMELIMIT).
set -euo pipefail
kind=${1:?usage: submit.sh eval|sweep SHARDS}
shards=${2:?usage: submit.sh eval|sweep SHARDS}
case "$kind" in eval | sweep) ;; *) echo "usage: submit.sh eval|sweep SHARDS" >&2; exit 2 ;; esac
[ "$shards" -ge 1 ] 2>/dev/null || { echo "SHARDS must be a whole number >= 1" >&2; exit 2; }
here=$(cd "$(dirname "$0")" && pwd)
array=$(sbatch --parsable --array="0-$((shards - 1))" "$here/$kind-array.sbatch")
array=${array%%;*}
merge=$(sbatch --parsable --dependency="afterok:$array" --kill-on-invalid-dep=yes \
    --export="ALL,WIPDR_KIND=$kind" "$here/merge.sbatch")
merge=${merge%%;*}
echo "$array $merge"
