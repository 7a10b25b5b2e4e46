#!/usr/bin/env bash
# Builds the `fuzz` preset (clang-14, libFuzzer + ASan + UBSan), generates the seed corpora and
# runs every fuzz target of tests/fuzz for SECONDS each (default 60), one after another.
# Prints executions and crashes per target; exits 1 if any target crashed, leaked or hung.
#
# Usage: tools/fuzz.sh [SECONDS] [TARGET...]
#   Targets: model_load model_session onnx_import keras_import pfm npy calibration (default all).
# Output under build/fuzz/fuzz-out/<target>/: corpus/ (seeds + what libFuzzer found, the seeds
# are copied in), log.txt, and crash-*/leak-*/timeout-*/oom-* reproducers. Reproduce one with
#   build/fuzz/bin/fuzz_<target> FILE
# and add it to tests/fuzz/regression/<target>/ once fixed (the test suite replays that folder).
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
if [[ $# -gt 0 ]]; then shift; fi
targets=("$@")
if [[ ${#targets[@]} -eq 0 ]]; then
  targets=(model_load model_session onnx_import keras_import pfm npy calibration)
fi
if ! [[ $seconds =~ ^[0-9]+$ ]] || [[ $seconds -lt 1 ]]; then
  echo "usage: tools/fuzz.sh [SECONDS] [TARGET...]" >&2
  exit 2
fi

bash tools/install-deps.sh
build=build/fuzz
cmake --preset fuzz >/dev/null
cmake --build "$build" -j2 --target sfrt_fuzz_make_model_seeds \
  $(printf 'fuzz_%s ' "${targets[@]}")

seeds=$build/fuzz-seeds
/usr/bin/python3 tests/fuzz/make_seeds.py --out-dir "$seeds" \
  --model-seeds "$build/bin/sfrt_fuzz_make_model_seeds" >/dev/null

out=$build/fuzz-out
status=0
summary=()
for t in "${targets[@]}"; do
  dir=$out/$t
  mkdir -p "$dir/corpus"
  cp -n "$seeds/$t"/* "$dir/corpus/" 2>/dev/null || true
  cp -n tests/fuzz/regression/"$t"/* "$dir/corpus/" 2>/dev/null || true
  echo "== $t: ${seconds}s"
  # -rss_limit_mb: the model targets plan real arenas; 2 GB is libFuzzer's default, kept explicit.
  set +e
  ASAN_OPTIONS=detect_leaks=1:allocator_may_return_null=1 \
  LSAN_OPTIONS=suppressions=$PWD/tests/fuzz/lsan.supp \
  UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1 \
    "$build/bin/fuzz_$t" -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$dir/" "$dir/corpus" >"$dir/log.txt" 2>&1
  rc=$?
  set -e
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$dir/log.txt" | tail -1)
  found=$(ls "$dir" | grep -cE '^(crash|leak|timeout|oom|slow-unit)-' || true)
  line=$(printf '%-14s %10s executions in %ss, %s crash/leak/timeout/oom files, exit %s' \
    "$t" "${execs:-?}" "$seconds" "$found" "$rc")
  summary+=("$line")
  echo "$line"
  if [[ $rc -ne 0 ]]; then
    status=1
    grep -m1 -E 'ERROR: (AddressSanitizer|LeakSanitizer|libFuzzer)|runtime error|Test unit written' \
      "$dir/log.txt" || true
  fi
done
echo
echo "== summary (${seconds}s per target)"
printf '%s\n' "${summary[@]}"
exit $status
