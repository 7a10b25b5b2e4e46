#!/bin/bash
# Submits a sharded `sfrt eval` to Slurm: SHARDS array tasks, then the merge once all succeeded.
# The lines to change are the five below (or set them in the environment).
#
#   SFRT=/opt/sfrt/bin/sfrt MODEL=models/sceneednet-default.sfrt DATASET=/data/heldout \
#     OUT=/scratch/$USER/eval SHARDS=8 bash examples/slurm/submit.sh
#
# Prints the two job IDs; results in $OUT/merged.json, each task's log in $OUT/*.out.
set -euo pipefail
SFRT=${SFRT:-sfrt}                     # the sfrt command on the compute nodes
MODEL=${MODEL:?set MODEL to the .sfrt file}
DATASET=${DATASET:?set DATASET to the dataset root}
OUT=${OUT:?set OUT to a folder every node can write}
SHARDS=${SHARDS:-4}
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT"
export SFRT MODEL DATASET OUT SFRT_EVAL_ARGS="${SFRT_EVAL_ARGS:-}"
shards=$(sbatch --parsable --array=0-$((SHARDS - 1)) --chdir "$OUT" \
  --output "$OUT/eval_%A_%a.out" "$here/eval_shard.sbatch")
merge=$(sbatch --parsable --dependency=afterok:"$shards" --chdir "$OUT" \
  --output "$OUT/merge_%j.out" "$here/merge.sbatch")
echo "shards $shards merge $merge"
