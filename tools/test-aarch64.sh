#!/usr/bin/env bash
# The aarch64 stage: cross-builds the runtime and the tests that need only the runtime (the
# `aarch64` preset: cmake/toolchains/aarch64-linux-gnu.cmake, exporter and tools off; whole-model
# tests build their models with the writer alone) and runs them under qemu-aarch64, so the NEON
# kernels are checked against the reference, layer by layer and on the whole model.
# The reference networks (SceneEDNet-U, FlowNetS-, DispNetS-style, pooling U-Net, depthwise
# separable) run under NEON too: the host's sfrt exports their odd-size PyTorch fixtures
# (37x53) and exported_model_parity_test compares the cross-built runtime's output with
# PyTorch's. So the release build and its fixtures come first (tools/test.sh's order).
# Needs g++-aarch64-linux-gnu and qemu-user (tools/install-deps.sh installs them).
# Usage: bash tools/test-aarch64.sh [BUILD_DIR]   (default build/aarch64, the preset's; also
#        SFRT_AARCH64_BUILD_DIR). Extra ctest arguments: SFRT_CTEST_ARGS, e.g. "-R session_isa".
#        The host's sfrt and fixtures: SFRT_HOST_SFRT (default build/release/bin/sfrt) and
#        SFRT_HOST_FIXTURES (default build/release/fixtures).
set -euo pipefail
cd "$(dirname "$0")/.."

for tool in aarch64-linux-gnu-g++ qemu-aarch64; do
  if ! command -v "${tool}" >/dev/null; then
    echo "test-aarch64: ${tool} not found (install g++-aarch64-linux-gnu and qemu-user)" >&2
    exit 1
  fi
done
build_dir="${1:-${SFRT_AARCH64_BUILD_DIR:-build/aarch64}}"
host_sfrt="${SFRT_HOST_SFRT:-build/release/bin/sfrt}"
host_fixtures="${SFRT_HOST_FIXTURES:-build/release/fixtures}"
start=${SECONDS}

# The reference networks at an odd size, one case each (tests/fixtures/gen_sceneednet.py).
reference_cases=(u16_torch_37x53_bn f16_torch_37x53_opset11 d16_torch_37x53_opset17
                 p16_torch_37x53_opset11 s16_torch_37x53_opset11)
if [[ ! -x "${host_sfrt}" || ! -f "${host_fixtures}/cases.txt" ]]; then
  echo "test-aarch64: the reference networks' check needs the host's sfrt and PyTorch fixtures" \
       "(${host_sfrt}, ${host_fixtures}/cases.txt): cmake --preset release &&" \
       "cmake --build build/release && ctest --preset release -R fixtures.generate" >&2
  exit 1
fi
exported="$(realpath -m "${build_dir}")/exported-models"
echo "== aarch64: export ${#reference_cases[@]} reference networks with ${host_sfrt} into ${exported}"
rm -rf "${exported}"
mkdir -p "${exported}"
for name in "${reference_cases[@]}"; do
  read -r _ height width < <(grep -E "^${name} " "${host_fixtures}/cases.txt") || {
    echo "test-aarch64: ${host_fixtures}/cases.txt has no case ${name}" >&2
    exit 1
  }
  "${host_sfrt}" export "${host_fixtures}/${name}.onnx" -o "${exported}/${name}.sfrt" >/dev/null
  cp "${host_fixtures}/${name}.input.npy" "${host_fixtures}/${name}.output.npy" "${exported}/"
  echo "${name} ${height} ${width}" >>"${exported}/cases.txt"
done

echo "== aarch64: configure and build in ${build_dir} (cross, $(aarch64-linux-gnu-g++ -dumpversion))"
cmake --preset aarch64 -B "${build_dir}" -DSFRT_TEST_EXPORTED_MODELS="${exported}" >/dev/null
cmake --build "${build_dir}" -j2 -- --no-print-directory -s
echo "== aarch64: test (qemu-aarch64)"
# The `aarch64` test preset's settings, for any build directory.
# shellcheck disable=SC2086
ctest --test-dir "${build_dir}" --output-on-failure -j2 -LE fixtures -E '^style\.' \
  ${SFRT_CTEST_ARGS:-}
echo "== aarch64: done in $((SECONDS - start)) s"
