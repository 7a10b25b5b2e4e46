#!/usr/bin/env bash
# Regenerates the bundled demo model tools/demo/sceneednet-w16-demo.sfrt: SceneEDNet at 1/16 of
# the published widths with seeded, untrained weights, built in PyTorch, exported to ONNX and
# converted by `sfrt export`, marked untrained (so that sfrt run/infer/eval/inspect say so). Needs
# a release build. After a model-format change, prefer rewriting the committed file in place,
# which keeps its weights bit for bit whatever the PyTorch version:
#   build/release/bin/sfrt export tools/demo/sceneednet-w16-demo.sfrt \
#     -o tools/demo/sceneednet-w16-demo.sfrt --training-state untrained
set -euo pipefail
cd "$(dirname "$0")/../.."
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
/usr/bin/python3 tests/fixtures/gen_sceneednet.py --out-dir "$work" --name demo \
  --width-div 16 --height 128 --width 224 --seed 2026
build/release/bin/sfrt export "$work/demo.onnx" -o tools/demo/sceneednet-w16-demo.sfrt \
  --name sceneednet-w16-untrained-demo --training-state untrained
