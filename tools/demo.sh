#!/usr/bin/env bash
# The main job on the bundled default: installs dependencies, builds the release preset and runs
# SceneEDNet on the bundled stereo frames, writing the scene flow to out/demo/flow.pfm.
# The bundled model (tools/demo/sceneednet-w16-demo.sfrt) has 1/16 of the published widths and
# seeded, UNTRAINED weights: it shows the pipeline working, not real scene flow (issue #7 brings
# a trained default model).
set -euo pipefail
cd "$(dirname "$0")/.."

bash tools/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release -- --no-print-directory -s

model=tools/demo/sceneednet-w16-demo.sfrt
frames=tools/demo/frames
mkdir -p out/demo
build/release/bin/sfrt inspect "$model" --size 128x224
build/release/bin/sfrt infer --model "$model" \
  --left0 "$frames/left0.png" --right0 "$frames/right0.png" \
  --left1 "$frames/left1.png" --right1 "$frames/right1.png" \
  -o out/demo/flow.pfm
echo "demo: scene flow written to out/demo/flow.pfm"
