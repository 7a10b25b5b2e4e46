#!/usr/bin/env bash
# Times one model with two sfrt binaries (e.g. the previous commit's and this one's) in the same
# run, alternating which goes first each round, and prints each round's medians and the ratio
# NEW/OLD of the medians over all rounds (below 1: the new binary is faster).
# Usage: tools/bench/compare_binaries.sh OLD_SFRT NEW_SFRT MODEL SIZE [THREADS] [ROUNDS] [RUNS]
#   SIZE HxW; THREADS default 2; ROUNDS default 6; RUNS per bench call, default 30.
set -euo pipefail
if [[ $# -lt 4 ]]; then
  sed -n '2,7p' "$0" >&2
  exit 2
fi
old=$1 new=$2 model=$3 size=$4 threads=${5:-2} rounds=${6:-6} runs=${7:-30}
for bin in "$old" "$new"; do
  [[ -x "$bin" ]] || { echo "compare_binaries: '$bin' is not an executable" >&2; exit 2; }
done
[[ -f "$model" ]] || { echo "compare_binaries: model '$model' does not exist" >&2; exit 2; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median_of() {  # the median_ms of a bench JSON
  /usr/bin/python3 -c 'import json,sys; print(json.load(open(sys.argv[1]))["results"][0]["median_ms"])' "$1"
}
bench() {  # bench BIN OUT.json
  "$1" bench --model "$model" --size "$size" --threads "$threads" --runs "$runs" --json "$2" >/dev/null
}

echo "round  first  old_ms    new_ms"
for ((r = 1; r <= rounds; r++)); do
  if ((r % 2)); then
    bench "$old" "$work/old$r.json"; bench "$new" "$work/new$r.json"; first=old
  else
    bench "$new" "$work/new$r.json"; bench "$old" "$work/old$r.json"; first=new
  fi
  printf "%5d  %-5s  %-8.3f  %-8.3f\n" "$r" "$first" "$(median_of "$work/old$r.json")" \
    "$(median_of "$work/new$r.json")"
done
/usr/bin/python3 - "$work" "$rounds" <<'PY'
import json, statistics, sys
work, rounds = sys.argv[1], int(sys.argv[2])
old = [json.load(open(f"{work}/old{r}.json"))["results"][0]["median_ms"] for r in range(1, rounds + 1)]
new = [json.load(open(f"{work}/new{r}.json"))["results"][0]["median_ms"] for r in range(1, rounds + 1)]
ratios = [n / o for n, o in zip(new, old)]
print(f"median over rounds: old {statistics.median(old):.3f} ms, new {statistics.median(new):.3f} ms, "
      f"new/old {statistics.median(new) / statistics.median(old):.3f} "
      f"(per-round {min(ratios):.3f}-{max(ratios):.3f})")
PY
