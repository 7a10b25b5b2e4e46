#!/usr/bin/env bash
# Issue 12's accuracy bars on the PyTorch test fixtures: for every case of the fixture suite
# (tests/fixtures/gen_sceneednet.py --suite: random-weight SceneEDNet, SceneEDNet-U and the
# reference networks), exports the ONNX file to float32, bf16 and int8 (calibrated on the
# fixture's own input) with `sfrt export`, runs each on that input with `sfrt infer`, and prints
# each precision's largest error against PyTorch's float32 output, relative to that output's
# largest |value| (the bars: bf16 2e-2, int8 5e-2), and whether it is within its bar.
#
# Usage: bash tools/bench/fixture_precision_sweep.sh [--method M] [--engine E] [--bias-correction]
#          [--auto] [--cases REGEX] FIXTURE_DIR
#   FIXTURE_DIR: where the suite was generated (build/release/fixtures after ctest has run, or
#   `/usr/bin/python3 tests/fixtures/gen_sceneednet.py --suite --out-dir DIR`).
#   --method: sfrt export's --calibration-method for int8 (default percentile:99.99, its default).
#   --engine: sfrt export's --calibration-engine, session (its default) or reference.
#   --bias-correction: int8 exported with sfrt export --bias-correction.
#   --auto: also --precision auto with the int8 bar as its budget on the largest error
#     (--accuracy-metric max --accuracy-budget 5e-2), and how many convolutions stayed int8.
#   --cases: only the cases whose name matches this extended regular expression.
# Environment: SFRT=path/to/sfrt (default build/release/bin/sfrt). Work files go to a temporary
# directory that is removed at exit. Needs Debian's /usr/bin/python3 with numpy.
set -euo pipefail

method="percentile:99.99"
engine="session"
cases_re="."
auto=0
int8_flags=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --method) method="$2"; shift 2 ;;
    --engine) engine="$2"; shift 2 ;;
    --auto) auto=1; shift ;;
    --bias-correction) int8_flags+=(--bias-correction); shift ;;
    --cases) cases_re="$2"; shift 2 ;;
    -h|--help) awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "$0"; exit 0 ;;
    -*) echo "fixture_precision_sweep.sh: unknown option $1 (see --help)" >&2; exit 2 ;;
    *) break ;;
  esac
done
if [[ $# -ne 1 ]]; then
  echo "usage: bash tools/bench/fixture_precision_sweep.sh [--method M] [--engine E] [--bias-correction] [--auto] [--cases REGEX] FIXTURE_DIR" >&2
  exit 2
fi
fixtures="$1"
root="$(cd "$(dirname "$0")/../.." && pwd)"
sfrt="${SFRT:-$root/build/release/bin/sfrt}"
if [[ ! -f "$fixtures/cases.txt" ]]; then
  echo "fixture_precision_sweep.sh: $fixtures/cases.txt not found: generate the suite first (--help)" >&2
  exit 2
fi
if [[ ! -x "$sfrt" ]]; then
  echo "fixture_precision_sweep.sh: $sfrt is not an executable sfrt; build it or set SFRT" >&2
  exit 2
fi
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

echo "fixtures $fixtures, int8 calibration method $method${int8_flags[*]:+ with ${int8_flags[*]}} on the $engine engine (on each fixture's own input)"
precisions=(bf16 int8)
header="$(printf '%-32s %13s %13s' "case" "bf16 max" "int8 max")"
if [[ $auto == 1 ]]; then
  precisions+=(auto)
  header+="$(printf ' %13s  %s' "auto max" "auto's convolutions (budget 5e-2 on the largest error)")"
fi
echo "$header"
within=(0 0 0)
total=0
while read -r name _h _w; do
  [[ "$name" =~ $cases_re ]] || continue
  in="$fixtures/$name.input.npy"
  "$sfrt" export "$fixtures/$name.onnx" -o "$work/$name.sfrt" > "$work/log" 2>&1 ||
    { echo "$name: sfrt export failed:"; cat "$work/log"; exit 1; }
  "$sfrt" export "$work/$name.sfrt" -o "$work/$name-bf16.sfrt" --precision bf16 > "$work/log" 2>&1 ||
    { echo "$name: bf16 export failed:"; cat "$work/log"; exit 1; }
  "$sfrt" export "$work/$name.sfrt" -o "$work/$name-int8.sfrt" --precision int8 \
    --calibration "$in" --calibration-method "$method" --calibration-engine "$engine" \
    "${int8_flags[@]}" > "$work/log" 2>&1 ||
    { echo "$name: int8 export failed:"; cat "$work/log"; exit 1; }
  mix=""
  if [[ $auto == 1 ]]; then
    "$sfrt" export "$work/$name.sfrt" -o "$work/$name-auto.sfrt" --precision auto \
      --accuracy-metric max --accuracy-budget 5e-2 --calibration "$in" \
      --calibration-method "$method" --calibration-engine "$engine" > "$work/log" 2>&1 ||
      { echo "$name: auto export failed:"; cat "$work/log"; exit 1; }
    # "  precision   int8, all 11 convolutions (..." or "  precision   9 of 11 convolutions int8, ..."
    mix="$(sed -n 's/^  precision *\([^(]*\) (.*/\1/p' "$work/log" | head -1)"
  fi
  paths=()
  for p in "${precisions[@]}"; do
    "$sfrt" infer --model "$work/$name-$p.sfrt" --input-npy "$in" -o "$work/$name-$p.npy" \
      > "$work/log" 2>&1 || { echo "$name: $p infer failed:"; cat "$work/log"; exit 1; }
    paths+=("$work/$name-$p.npy")
  done
  line="$(/usr/bin/python3 - "$fixtures/$name.output.npy" "${paths[@]}" <<'EOF'
import sys
import numpy as np
ref = np.load(sys.argv[1]).astype(np.float64)
largest = np.abs(ref).max()
errs = []
for path, bar in zip(sys.argv[2:], (2e-2, 5e-2, 5e-2)):
    y = np.load(path).astype(np.float64).reshape(ref.shape)
    e = np.abs(y - ref).max() / largest
    errs.append(f"{e:.2e} {'ok' if e <= bar else 'over'}")
print(" ".join(errs))
EOF
)"
  read -r -a fields <<< "$line"
  row="$(printf '%-32s' "$name")"
  for k in "${!precisions[@]}"; do
    row+="$(printf ' %8s %-4s' "${fields[2 * k]}" "${fields[2 * k + 1]}")"
    [[ "${fields[2 * k + 1]}" == ok ]] && within[k]=$((within[k] + 1))
  done
  [[ $auto == 1 ]] && row+="  $mix"
  echo "$row"
  total=$((total + 1))
done < "$fixtures/cases.txt"
summary="within the bar: bf16 ${within[0]} of $total (2e-2), int8 ${within[1]} of $total (5e-2)"
[[ $auto == 1 ]] && summary+=", auto ${within[2]} of $total (5e-2)"
echo "$summary"
