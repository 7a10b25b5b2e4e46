#!/usr/bin/env bash
# Kept for old command lines: sfrt against ONNX Runtime only. Same arguments as
# tools/bench/compare_peers.sh (which also runs OpenCV DNN), with --peers ort.
# Usage: bash tools/bench/compare_ort.sh MODEL.onnx HxW [THREADS=1,2] [ROUNDS=3] [RUNS=2]
exec bash "$(dirname "$0")/compare_peers.sh" --peers ort "$@"
