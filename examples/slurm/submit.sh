#!/bin/bash
# Submits a sharded `sfrt eval` (JOB=eval, the default) or `sfrt run` replay (JOB=run) to Slurm:
# SHARDS array tasks, then the merge once all succeeded. The lines to change are the six below
# (or set them in the environment).
#
#   SFRT=/opt/sfrt/bin/sfrt MODEL=models/sceneednet-default.sfrt DATASET=/data/heldout \
#     OUT=/scratch/$USER/eval SHARDS=8 bash examples/slurm/submit.sh
#
# Prints the two job IDs; results in $OUT/merged.json (JOB=run: the flow files in
# $OUT/replay/shard-*-of-*/), each task's log in $OUT/*.out. Extra options: SFRT_EVAL_ARGS,
# SFRT_RUN_ARGS.
set -euo pipefail
SFRT=${SFRT:-sfrt}                     # the sfrt command on the compute nodes
MODEL=${MODEL:?set MODEL to the .sfrt file}
DATASET=${DATASET:?set DATASET to the dataset root}
OUT=${OUT:?set OUT to a folder every node can write}
SHARDS=${SHARDS:-4}
JOB=${JOB:-eval}                       # eval (score against ground truth) or run (replay)
case "$JOB" in
  eval | run) ;;
  *) echo "submit.sh: JOB is '$JOB'; give eval or run" >&2; exit 2 ;;
esac
here=$(cd "$(dirname "$0")" && pwd)
mkdir -p "$OUT"
export SFRT MODEL DATASET OUT JOB SFRT_EVAL_ARGS="${SFRT_EVAL_ARGS:-}" \
  SFRT_RUN_ARGS="${SFRT_RUN_ARGS:-}"
shards=$(sbatch --parsable --array=0-$((SHARDS - 1)) --chdir "$OUT" \
  --output "$OUT/${JOB}_%A_%a.out" "$here/${JOB}_shard.sbatch")
merge=$(sbatch --parsable --dependency=afterok:"$shards" --chdir "$OUT" \
  --output "$OUT/merge_%j.out" "$here/merge.sbatch")
echo "shards $shards merge $merge"
