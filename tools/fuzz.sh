#!/usr/bin/env bash
# Builds the `fuzz` preset (clang-14, libFuzzer + ASan + UBSan), generates the seed corpora and
# runs every fuzz target of tests/fuzz for SECONDS each (default 60).
# Prints per target: executions, duration, executions per second and crash files found; exits 1
# if any target crashed, leaked, hung or ran out of memory.
#
# Usage: tools/fuzz.sh [SECONDS] [TARGET...]
#   Targets: model_load model_session onnx_import keras_import pfm npy calibration image profile
#            cdr_decoder mcap_reader
#   (default all).
# Environment:
#   SFRT_FUZZ_BUILD_DIR  build directory (default build/fuzz, the preset's)
#   SFRT_FUZZ_JOBS       targets run at the same time (default 1; each uses one core)
#   SFRT_FUZZ_NO_BUILD=1 run the programs already built (no install-deps, configure or build)
# Output under <build>/fuzz-out/<target>/: corpus/ (seeds + what libFuzzer found, the seeds are
# copied in), log.txt, result.txt, and crash-*/leak-*/timeout-*/oom-* reproducers. Reproduce one
# with <build>/bin/fuzz_<target> FILE and add it to tests/fuzz/regression/<target>/ once fixed
# (the test suite replays that folder).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
if [[ $# -gt 0 ]]; then shift; fi
targets=("$@")
all=(model_load model_session onnx_import keras_import pfm npy calibration image profile cdr_decoder mcap_reader)
if [[ ${#targets[@]} -eq 0 ]]; then targets=("${all[@]}"); fi
jobs=${SFRT_FUZZ_JOBS:-1}
if ! [[ $seconds =~ ^[0-9]+$ ]] || [[ $seconds -lt 1 ]] || ! [[ $jobs =~ ^[1-9][0-9]*$ ]]; then
  echo "usage: tools/fuzz.sh [SECONDS] [TARGET...]  (SFRT_FUZZ_JOBS: a positive number)" >&2
  exit 2
fi
for t in "${targets[@]}"; do
  if ! [[ " ${all[*]} " == *" $t "* ]]; then
    echo "tools/fuzz.sh: unknown target '$t' (targets: ${all[*]})" >&2
    exit 2
  fi
done

build=${SFRT_FUZZ_BUILD_DIR:-build/fuzz}
if [[ ${SFRT_FUZZ_NO_BUILD:-0} != 1 ]]; then
  bash tools/install-deps.sh
  cmake --preset fuzz -B "$build" >/dev/null
  cmake --build "$build" -j2 --target sfrt_fuzz_make_model_seeds \
    $(printf 'fuzz_%s ' "${targets[@]}")
fi

seeds=$build/fuzz-seeds
/usr/bin/python3 tests/fuzz/make_seeds.py --out-dir "$seeds" \
  --model-seeds "$build/bin/sfrt_fuzz_make_model_seeds" >/dev/null

out=$build/fuzz-out
# run_target T: fuzzes T for $seconds and writes one result line to $out/T/result.txt.
run_target() {
  local t=$1 dir=$out/$1
  mkdir -p "$dir/corpus"
  rm -f "$dir/result.txt"
  cp -n "$seeds/$t"/* "$dir/corpus/" 2>/dev/null || true
  cp -n tests/fuzz/regression/"$t"/* "$dir/corpus/" 2>/dev/null || true
  local before_files
  before_files=$(ls "$dir" | grep -cE '^(crash|leak|timeout|oom|slow-unit)-' || true)
  local start end rc
  start=$(date +%s)
  # -rss_limit_mb: the model targets plan real arenas; 2 GB is libFuzzer's default, kept explicit.
  set +e
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 \
  LSAN_OPTIONS=suppressions=$PWD/tests/fuzz/lsan.supp \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/bin/fuzz_$t" -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$dir/" "$dir/corpus" >"$dir/log.txt" 2>&1
  rc=$?
  set -e
  end=$(date +%s)
  local execs dur found rate
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$dir/log.txt" | tail -1)
  dur=$((end - start))
  found=$(( $(ls "$dir" | grep -cE '^(crash|leak|timeout|oom|slow-unit)-' || true) - before_files ))
  rate=$(( ${execs:-0} / (dur > 0 ? dur : 1) ))
  printf '%-14s %11s executions  %5ss  %7s exec/s  %s crashes  exit %s\n' \
    "$t" "${execs:-?}" "$dur" "$rate" "$found" "$rc" >"$dir/result.txt"
  cat "$dir/result.txt"
  if [[ $rc -ne 0 ]]; then
    grep -m1 -E 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error|Test unit written' \
      "$dir/log.txt" || true
  fi
}

echo "== ${#targets[@]} targets, ${seconds}s each, $jobs at a time; logs under $out/<target>/"
running=0
for t in "${targets[@]}"; do
  run_target "$t" &
  running=$((running + 1))
  if [[ $running -ge $jobs ]]; then
    wait -n || true
    running=$((running - 1))
  fi
done
wait || true

echo
echo "== summary (${seconds}s per target; crashes = new crash/leak/timeout/oom files)"
status=0
for t in "${targets[@]}"; do
  if [[ -f $out/$t/result.txt ]]; then
    cat "$out/$t/result.txt"
    grep -qE ' 0 crashes  exit 0$' "$out/$t/result.txt" || status=1
  else
    echo "$t: no result (the run did not finish)"
    status=1
  fi
done
exit $status
