#!/usr/bin/env bash
# The aarch64 stage: cross-builds the runtime and the tests that need only the runtime (the
# `aarch64` preset: cmake/toolchains/aarch64-linux-gnu.cmake, exporter and tools off; whole-model
# tests build their models with the writer alone) and runs them under qemu-aarch64, so the NEON
# kernels are checked against the reference, layer by layer and on the whole model.
# Needs g++-aarch64-linux-gnu and qemu-user (tools/install-deps.sh installs them).
# Usage: bash tools/test-aarch64.sh [BUILD_DIR]   (default build/aarch64, the preset's; also
#        SFRT_AARCH64_BUILD_DIR). Extra ctest arguments: SFRT_CTEST_ARGS, e.g. "-R session_isa".
set -euo pipefail
cd "$(dirname "$0")/.."

for tool in aarch64-linux-gnu-g++ qemu-aarch64; do
  if ! command -v "${tool}" >/dev/null; then
    echo "test-aarch64: ${tool} not found (install g++-aarch64-linux-gnu and qemu-user)" >&2
    exit 1
  fi
done
build_dir="${1:-${SFRT_AARCH64_BUILD_DIR:-build/aarch64}}"
start=${SECONDS}
echo "== aarch64: configure and build in ${build_dir} (cross, $(aarch64-linux-gnu-g++ -dumpversion))"
cmake --preset aarch64 -B "${build_dir}" >/dev/null
cmake --build "${build_dir}" -j2 -- --no-print-directory -s
echo "== aarch64: test (qemu-aarch64)"
# The `aarch64` test preset's settings, for any build directory.
# shellcheck disable=SC2086
ctest --test-dir "${build_dir}" --output-on-failure -j2 -LE fixtures -E '^style\.' \
  ${SFRT_CTEST_ARGS:-}
echo "== aarch64: done in $((SECONDS - start)) s"
