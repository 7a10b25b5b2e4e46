#!/usr/bin/env bash
# The aarch64 stage: cross-builds the runtime and the tests that need only the runtime (the
# `aarch64` preset: cmake/toolchains/aarch64-linux-gnu.cmake, exporter and tools off) and runs
# them under qemu-aarch64, so the NEON kernels are checked against the reference.
# Needs g++-aarch64-linux-gnu and qemu-user (tools/install-deps.sh installs them).
# Usage: bash tools/test-aarch64.sh
set -euo pipefail
cd "$(dirname "$0")/.."

for tool in aarch64-linux-gnu-g++ qemu-aarch64; do
  if ! command -v "${tool}" >/dev/null; then
    echo "test-aarch64: ${tool} not found (install g++-aarch64-linux-gnu and qemu-user)" >&2
    exit 1
  fi
done
start=${SECONDS}
echo "== aarch64: configure and build (cross, $(aarch64-linux-gnu-g++ -dumpversion))"
cmake --preset aarch64 >/dev/null
cmake --build --preset aarch64 -- --no-print-directory -s
echo "== aarch64: test (qemu-aarch64)"
ctest --preset aarch64
echo "== aarch64: done in $((SECONDS - start)) s"
