#!/usr/bin/env bash
# The whole test suite from a fresh clone: installs dependencies, builds the release and asan
# presets and runs every test in each (the asan run is the leak/UB/bounds check), then the
# aarch64 stage (tools/test-aarch64.sh: cross build, NEON tests under qemu).
# Usage: bash tools/test.sh [preset ...]   (default: release asan, then aarch64; named presets only)
set -euo pipefail
cd "$(dirname "$0")/.."

stage() { echo "== $1 (${SECONDS} s since the start)"; }
bash tools/install-deps.sh
presets=("$@")
[[ ${#presets[@]} -gt 0 ]] || presets=(release asan)
for preset in "${presets[@]}"; do
  stage "${preset}: configure and build"
  cmake --preset "${preset}" >/dev/null
  cmake --build --preset "${preset}" -- --no-print-directory -s
  stage "${preset}: test"
  ctest --preset "${preset}"
done
# Third stage of the default run: the aarch64 cross build, NEON tests under qemu.
if [[ $# -eq 0 ]]; then
  stage "aarch64"
  bash tools/test-aarch64.sh
fi
stage "done"
