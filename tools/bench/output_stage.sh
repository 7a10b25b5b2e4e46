#!/usr/bin/env bash
# What the default outputs of `sfrt run` (a flow .pfm and a visualisation .png per window) cost a
# frame, measured as summary.json reports it: the output stage's p50 (the flow file, and the
# picture when it is written on the output stage) and, where the pictures run behind their own
# queue, the encoder's p50 per window and the pictures dropped. Issue #38's bar: at most 4 ms a
# frame at 96x128 on 2 cores.
#
# Each round replays one synthesised sequence (192x256 frames, the default model at the 96x128 it
# records) with every binary given, alternating which goes first, in two modes:
#   unpaced   as fast as the pipeline goes (pictures on the output stage, all written)
#   paced     --replay-fps 30, like a camera (pictures behind a dropping queue by default)
# and prints each run's figures, then the medians over the rounds per binary and mode.
#
# Usage: tools/bench/output_stage.sh [--rounds N] [--frames N] [--size HxW] SFRT [OTHER_SFRT ...]
#   e.g. tools/bench/output_stage.sh --rounds 5 --size 96x128 old/bin/sfrt build/release/bin/sfrt
#   --rounds default 5; --frames default 60 (windows per run: frames - 1); --size: passed to
#   sfrt run (default: none, each binary's own default input size).
set -euo pipefail
cd "$(dirname "$0")/../.."
rounds=5 frames=60 size=""
bins=()
while [[ $# -gt 0 ]]; do
  case $1 in
    --rounds) rounds=$2; shift 2 ;;
    --frames) frames=$2; shift 2 ;;
    --size) size=$2; shift 2 ;;
    -h|--help) sed -n '2,17p' "$0"; exit 0 ;;
    *) bins+=("$1"); shift ;;
  esac
done
if [[ ${#bins[@]} -eq 0 ]]; then sed -n '2,17p' "$0" >&2; exit 2; fi
for b in "${bins[@]}"; do
  [[ -x $b ]] || { echo "output_stage: '$b' is not an executable" >&2; exit 2; }
done
if ! [[ $rounds =~ ^[1-9][0-9]*$ && $frames =~ ^[1-9][0-9]*$ && $frames -ge 3 ]]; then
  echo "output_stage: --rounds must be >= 1 and --frames >= 3" >&2
  exit 2
fi
model=models/sceneednet-default.sfrt
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"${bins[-1]}" synth --out "$work/data" --scene robot --seed 4242 --frames "$frames" \
  --size 192x256 --focal 180 --baseline 0.12 --objects 8 --threads 2 >/dev/null

run() {  # run BIN_INDEX MODE ROUND: one replay, its summary kept as $work/<i>_<mode>_<round>.json
  local i=$1 mode=$2 r=$3 extra=()
  [[ $mode == paced ]] && extra=(--replay-fps 30)
  [[ -n $size ]] && extra+=(--size "$size")
  rm -rf "$work/out"
  "${bins[$i]}" run --model "$model" --replay "$work/data" --out "$work/out" --progress off \
    "${extra[@]}" >/dev/null 2>&1
  cp "$work/out/summary.json" "$work/${i}_${mode}_${r}.json"
}

echo "binaries: ${bins[*]}; input size: ${size:-the default of each binary}"
echo "round  binary  mode      output_p50_ms  pictures_p50_ms  pictures_dropped  windows"
for ((r = 1; r <= rounds; r++)); do
  order=()
  for ((i = 0; i < ${#bins[@]}; i++)); do order+=("$i"); done
  if ((r % 2 == 0)); then  # alternate which binary goes first
    mapfile -t order < <(printf '%s\n' "${order[@]}" | tac)
  fi
  for mode in unpaced paced; do
    for i in "${order[@]}"; do
      run "$i" "$mode" "$r"
      /usr/bin/python3 - "$work/${i}_${mode}_${r}.json" "$r" "$i" "$mode" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
pictures = [x for x in s["sinks"] if x["name"] == "pictures"]
p50 = pictures[0].get("write_ms", {}).get("p50", float("nan")) if pictures else float("nan")
dropped = pictures[0].get("dropped", 0) if pictures else 0
print("%5s  %6s  %-8s  %13.2f  %15.2f  %16d  %7d" % (sys.argv[2], sys.argv[3], sys.argv[4],
      s["latency_ms"]["output"]["p50"], p50, dropped, s["frames"]["written"]))
PY
    done
  done
done
/usr/bin/python3 - "$work" "$rounds" "${bins[@]}" <<'PY'
import json, math, statistics, sys
work, rounds, bins = sys.argv[1], int(sys.argv[2]), sys.argv[3:]
print("\nmedians over %d rounds (output stage p50; pictures p50 where queued)" % rounds)
for i, b in enumerate(bins):
    for mode in ("unpaced", "paced"):
        out, pic = [], []
        for r in range(1, rounds + 1):
            s = json.load(open("%s/%d_%s_%d.json" % (work, i, mode, r)))
            out.append(s["latency_ms"]["output"]["p50"])
            q = [x for x in s["sinks"] if x["name"] == "pictures"]
            if q and "write_ms" in q[0]:
                pic.append(q[0]["write_ms"]["p50"])
        line = "%-40s %-8s output %.2f ms" % (b, mode, statistics.median(out))
        if pic:
            line += ", pictures %.2f ms off the output stage" % statistics.median(pic)
        print(line)
PY
