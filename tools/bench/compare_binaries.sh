#!/usr/bin/env bash
# Times one model with two sfrt binaries (e.g. the previous commit's and this one's) in the same
# run, alternating which goes first each round, and prints each round's medians and the ratio
# NEW/OLD of the medians over all rounds (below 1: the new binary is faster).
# Usage: tools/bench/compare_binaries.sh [--steps] [--bench-args "ARGS"] OLD_SFRT NEW_SFRT MODEL SIZE
#                                        [THREADS] [ROUNDS] [RUNS]
#   SIZE HxW; THREADS default 2; ROUNDS default 6; RUNS per bench call, default 30.
#   --steps: also each step's median over the rounds for both binaries, and their ratio.
#   --bench-args: more arguments for both `sfrt bench` calls (e.g. "--quantized-input", "--isa avx2").
set -euo pipefail
usage() { sed -n '2,10p' "$0" >&2; exit 2; }
steps=0 bench_args=()
while [[ $# -gt 0 && $1 == --* ]]; do
  case $1 in
    --steps) steps=1; shift ;;
    --bench-args) [[ $# -ge 2 ]] || usage; read -r -a bench_args <<< "$2"; shift 2 ;;
    *) echo "compare_binaries: unknown option '$1'" >&2; usage ;;
  esac
done
[[ $# -ge 4 ]] || usage
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
  "$1" bench --model "$model" --size "$size" --threads "$threads" --runs "$runs" --json "$2" \
    ${bench_args[@]+"${bench_args[@]}"} >/dev/null
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
/usr/bin/python3 - "$work" "$rounds" "$steps" <<'PY'
import json, statistics, sys
work, rounds, steps = sys.argv[1], int(sys.argv[2]), sys.argv[3] == "1"
def results(which):
    return [json.load(open(f"{work}/{which}{r}.json"))["results"][0] for r in range(1, rounds + 1)]
old, new = results("old"), results("new")
o = [r["median_ms"] for r in old]
n = [r["median_ms"] for r in new]
ratios = [b / a for a, b in zip(o, n)]
print(f"median over rounds: old {statistics.median(o):.3f} ms, new {statistics.median(n):.3f} ms, "
      f"new/old {statistics.median(n) / statistics.median(o):.3f} "
      f"(per-round {min(ratios):.3f}-{max(ratios):.3f})")
if steps:
    def per_step(rs):  # layers -> the step's medians, one per round
        out = {}
        for r in rs:
            for s in r["steps"]:
                out.setdefault(s["layers"], []).append(s["median_ms"])
        return out
    a, b = per_step(old), per_step(new)
    print(f"{'step':<32} {'old_ms':>9} {'new_ms':>9} {'new/old':>8}")
    for layers in sorted(a, key=lambda k: -statistics.median(a[k])):
        ma = statistics.median(a[layers])
        if layers not in b:
            print(f"{layers:<32} {ma:9.3f} {'-':>9} {'-':>8}")
            continue
        mb = statistics.median(b[layers])
        ratio = f"{mb / ma:8.3f}" if ma > 0 else f"{'-':>8}"
        print(f"{layers:<32} {ma:9.3f} {mb:9.3f} {ratio}")
    for layers in b.keys() - a.keys():
        print(f"{layers:<32} {'-':>9} {statistics.median(b[layers]):9.3f} {'-':>8}")
PY
