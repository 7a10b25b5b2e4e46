#!/usr/bin/env bash
# Valgrind memcheck of the two product paths a deployment runs most: `sfrt infer` on the bundled
# demo model and frames, and a short `sfrt run` file replay (6 frame pairs, 5 inferences, flow
# PFMs + PNGs + summary.json). Each runs under
#   valgrind --tool=memcheck --error-exitcode=1 --leak-check=full
# (definite and possible leaks count as errors) and gets a one-line verdict; the script exits 1
# if either is not clean.
#
# Usage: tools/valgrind.sh [--sfrt PATH]
#   --sfrt PATH  check this sfrt binary (built WITHOUT sanitizers); default: configure and build
#                build/valgrind (RelWithDebInfo: -O2 -g, so valgrind's reports have lines).
# Environment: SFRT_VALGRIND_BUILD_DIR overrides build/valgrind.
# Valgrind 3.19 does not emulate AVX-512; under it the CPUID sfrt sees has none, so the runtime's
# own dispatch picks AVX2 (or the reference kernels on a CPU without AVX2). Where valgrind cannot
# run sfrt at all (an instruction it does not emulate while the libraries load; see below), the
# script says so and checks the runtime and image decoding through the fuzz replay binaries.
# Logs: <out>/infer.valgrind.txt and <out>/run.valgrind.txt, <out> = a fresh temporary directory
# (printed; kept when a check fails).
set -euo pipefail
sfrt=""
while [[ $# -gt 0 ]]; do
  case $1 in
    --sfrt) sfrt=$(realpath -m "${2:?--sfrt needs a path}"); shift 2 ;;
    *) echo "usage: tools/valgrind.sh [--sfrt PATH]" >&2; exit 2 ;;
  esac
done
cd "$(dirname "$0")/.."
root=$PWD
if ! command -v valgrind >/dev/null; then
  echo "tools/valgrind.sh: valgrind is not installed (apt-get install valgrind; tools/install-deps.sh)" >&2
  exit 1
fi
if [[ -z $sfrt ]]; then
  build=${SFRT_VALGRIND_BUILD_DIR:-build/valgrind}
  cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
  cmake --build "$build" -j2 --target sfrt -- --no-print-directory -s
  sfrt=$build/bin/sfrt
fi
[[ -x $sfrt ]] || { echo "tools/valgrind.sh: no executable $sfrt" >&2; exit 1; }

model=$root/tools/demo/sceneednet-w16-demo.sfrt
frames=$root/tools/demo/frames
out=$(mktemp -d "${TMPDIR:-/tmp}/sfrt-valgrind-XXXXXX")
# Six pairs for the replay: the two demo pairs three times (sorted by name: f0 f1 f2 ...).
mkdir -p "$out/left" "$out/right"
for i in 0 1 2 3 4 5; do
  cp "$frames/left$((i % 2)).png" "$out/left/f$i.png"
  cp "$frames/right$((i % 2)).png" "$out/right/f$i.png"
done

vg=(valgrind --tool=memcheck --error-exitcode=1 --leak-check=full --show-leak-kinds=definite,possible
    --errors-for-leak-kinds=definite,possible --track-origins=yes --num-callers=30)
status=0
# check NAME CMD...: runs CMD under memcheck and prints one verdict line.
check() {
  local name=$1
  shift
  local log=$out/$name.valgrind.txt start end rc
  start=$(date +%s)
  set +e
  "${vg[@]}" --log-file="$log" "$@" >"$out/$name.stdout.txt" 2>&1
  rc=$?
  set -e
  end=$(date +%s)
  local errors leaks
  errors=$(sed -n 's/.*ERROR SUMMARY: \([0-9]*\) errors.*/\1/p' "$log" | tail -1)
  leaks=$(sed -n 's/.*definitely lost: \([0-9,]*\) bytes.*/\1/p' "$log" | tail -1)
  if [[ $rc -eq 0 && ${errors:-x} == 0 ]]; then
    echo "valgrind $name: CLEAN (0 errors, definitely lost ${leaks:-0} bytes, exit 0, $((end - start))s)"
  else
    echo "valgrind $name: NOT CLEAN (${errors:-?} errors, definitely lost ${leaks:-?} bytes," \
      "exit $rc, $((end - start))s; log $log)"
    tail -5 "$out/$name.stdout.txt" | sed 's/^/  | /'
    status=1
  fi
}

# Valgrind 3.19 does not emulate RDTSCP on a CPU that does not advertise it (some VMs do not),
# and libhwy, which OpenCV videoio loads (through ffmpeg and libjxl), executes it while loading:
# sfrt then stops with SIGILL under valgrind before its main. On such a machine the script says
# so and checks what it can: the runtime (model load, session plan and run) and image decoding
# through the fuzz replay binaries beside sfrt, which do not load OpenCV videoio.
probe=$out/probe.valgrind.txt
if ! (valgrind --tool=none --log-file="$probe" "$sfrt" --version >/dev/null 2>&1; exit $?) 2>/dev/null &&
  grep -q 'Unrecognised instruction' "$probe"; then
  where=$(grep -m1 -o 'at 0x[0-9A-F]*: .*' "$probe" | sed 's/^at 0x[0-9A-F]*: //')
  echo "valgrind cannot run $sfrt on this CPU: it stops at an instruction valgrind does not" \
    "emulate while loading (${where:-see $probe}); checking the runtime and image decoding" \
    "through the fuzz replay binaries instead"
  bin=$(dirname "$sfrt")
  check model_session "$bin/sfrt_fuzz_model_session_replay" "$model" \
    "$root/models/sceneednet-default-int8.sfrt" "$root/models/sceneednet-default.sfrt"
  check image "$bin/sfrt_fuzz_image_replay" "$frames/left0.png" "$frames/right0.png"
  [[ $status -eq 0 ]] && rm -rf "$out" || echo "logs kept in $out"
  exit $status
fi

check infer "$sfrt" infer --model "$model" \
  --left0 "$frames/left0.png" --right0 "$frames/right0.png" \
  --left1 "$frames/left1.png" --right1 "$frames/right1.png" -o "$out/infer-flow.pfm"
check run "$sfrt" run --model "$model" --replay-left "$out/left" --replay-right "$out/right" \
  --out "$out/run" --progress off --threads 2

if [[ $status -eq 0 ]]; then
  rm -rf "$out"
else
  echo "logs kept in $out"
fi
exit $status
