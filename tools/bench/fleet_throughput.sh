#!/usr/bin/env bash
# What a fleet replay costs (docs/scale.md): frames per second of `sfrt run` over a synthesised
# sequence recorded at the size the model runs at, 96x128 and 540x960 (the default model), with no
# file outputs and with the default ones (flow .pfm and a picture per window), on one core
# (taskset -c 0, --threads 1) and on all of this machine's cores (--threads 0), ROUNDS rounds
# each, the median printed. Reading and decoding the recorded PNGs is part of the cost.
# usage: tools/bench/fleet_throughput.sh [SFRT] [FRAMES] [ROUNDS]
set -euo pipefail
sfrt=${1:-build/release/bin/sfrt}
frames=${2:-41}
rounds=${3:-3}
model=models/sceneednet-default.sfrt
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for size in 96x128 540x960; do
  "$sfrt" synth --out "$work/data_$size" --scene robot --seed 5 --sequences 1 --frames "$frames" \
    --size "$size" --focal "$([[ $size == 96x128 ]] && echo 90 || echo 506.25)" --baseline 0.12 \
    --objects 6 --threads "$(nproc)" >/dev/null
done
fps() {  # size outputs cores -> fps of one run
  local size=$1 outputs=$2 cores=$3 pin=() threads=0 extra=(--flow-format none --no-png)
  [[ $cores == 1 ]] && pin=(taskset -c 0) && threads=1
  [[ $outputs == with ]] && extra=()
  rm -rf "$work/out"
  "${pin[@]}" "$sfrt" run --model "$model" --replay "$work/data_$size" --size "$size" --threads "$threads" \
    --out "$work/out" --progress off --no-summary "${extra[@]}" 2>/dev/null | awk '/^throughput/ {print $2}'
}
printf "%-8s %-9s %6s %10s %14s\n" size outputs cores "fps" "fps per core"
for size in 96x128 540x960; do
  for outputs in without with; do
    for cores in 1 "$(nproc)"; do
      runs=()
      for ((r = 0; r < rounds; ++r)); do runs+=("$(fps "$size" "$outputs" "$cores")"); done
      median=$(printf "%s\n" "${runs[@]}" | sort -g | awk '{a[NR]=$1} END {print a[int((NR+1)/2)]}')
      awk -v s="$size" -v o="$outputs" -v c="$cores" -v f="$median" \
        'BEGIN {printf "%-8s %-9s %6d %10.1f %14.1f\n", s, o, c, f, f / c}'
    done
  done
done
echo "($((frames - 1)) windows per run, median of $rounds runs; $(grep -m1 'model name' /proc/cpuinfo | cut -d: -f2 | xargs))"
