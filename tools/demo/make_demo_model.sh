#!/usr/bin/env bash
# Regenerates the bundled demo model tools/demo/sceneednet-w16-demo.sfrt: SceneEDNet at 1/16 of
# the published widths with seeded, untrained weights, built in PyTorch, exported to ONNX and
# converted by `sfrt export`. Run after a model-format change. Needs a release build.
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 tests/fixtures/gen_sceneednet.py --out-dir "$work" --name demo \
  --width-div 16 --height 128 --width 224 --seed 2026
build/release/bin/sfrt export "$work/demo.onnx" -o tools/demo/sceneednet-w16-demo.sfrt \
  --name sceneednet-w16-untrained-demo
