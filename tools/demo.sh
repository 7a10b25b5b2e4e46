#!/usr/bin/env bash
# The main demo: installs dependencies, builds the release preset's product (`sfrt`, `sfrt_ros`,
# the installable libraries; target sfrt_product), synthesises a short
# held-out stereo sequence with exact ground truth (a robot's 0.12 m rig driving through a room;
# seed 4242, never used in training), replays it through the trained default model
# models/sceneednet-default.sfrt with `sfrt run`, evaluates the model against the ground truth
# beside the zero-flow and classical baselines with `sfrt eval`, measures latency with
# `sfrt bench`, and evaluates and times the same model in int8 (models/sceneednet-default-int8.sfrt)
# beside it. Everything lands in out/demo/ (see the summary printed at the end).
set -euo pipefail
cd "$(dirname "$0")/.."

bash tools/install-deps.sh
# SFRT_DEMO_BUILD=DIR builds into DIR instead of the release preset's build/release.
if [[ -n "${SFRT_DEMO_BUILD:-}" ]]; then
  cmake -S . -B "$SFRT_DEMO_BUILD" -DCMAKE_BUILD_TYPE=Release >/dev/null
  cmake --build "$SFRT_DEMO_BUILD" --target sfrt_product -j2 -- --no-print-directory -s
  sfrt=$SFRT_DEMO_BUILD/bin/sfrt
else
  cmake --preset release >/dev/null
  # sfrt_product: the tool, the ROS node, the installed libraries and the fake camera shim, so
  # every command the README shows works after the demo (cmake --install included).
  cmake --build --preset release --target sfrt_product -- --no-print-directory -s
  sfrt=build/release/bin/sfrt
fi
model=models/sceneednet-default.sfrt
out=out/demo
# The training camera (models/README.md): rendered at 192x256, f 180 px, baseline 0.12 m; the
# model runs at half that size (96x128, f 90 px), as it was trained.
size=96x128
rm -rf "$out"
mkdir -p "$out"

echo "== 1/5 synthesise a held-out sequence (seed 4242, 12 frames) -> $out/data"
"$sfrt" synth --out "$out/data" --scene robot --seed 4242 --sequences 1 --frames 12 \
  --size 192x256 --focal 180 --baseline 0.12 --objects 8 --threads 2 >"$out/synth.log"
tail -n 1 "$out/synth.log"

# Paced at 10 fps, as a camera would deliver the frames: its end to end is then a latency
# (an unpaced replay's windows wait in the queues, which measures throughput instead).
echo "== 2/5 replay it through $model with sfrt run at 10 fps, like a camera -> $out/run"
"$sfrt" run --model "$model" --replay "$out/data" --size "$size" --out "$out/run" \
  --replay-fps 10 --video "$out/run/flow.avi" --video-fps 5 --threads 2 >"$out/run.log" 2>&1 || {
  cat "$out/run.log" >&2
  exit 1
}
tail -n 4 "$out/run.log"

echo "== 3/5 evaluate against the ground truth with sfrt eval -> $out/eval.txt, $out/eval.json"
"$sfrt" eval --model "$model" --dataset "$out/data" --size "$size" --json "$out/eval.json" \
  >"$out/eval.txt"
cat "$out/eval.txt"

echo "== 4/5 latency with sfrt bench -> $out/bench.json"
"$sfrt" bench --model "$model" --size "$size" --threads 1,2 --json "$out/bench.json" \
  >"$out/bench.txt"
grep -m 3 -i "median\|ms" "$out/bench.txt" || true

model8=models/sceneednet-default-int8.sfrt
echo "== 5/5 the same model in int8 ($model8): sfrt eval and sfrt bench -> $out/int8/"
mkdir -p "$out/int8"
"$sfrt" eval --model "$model8" --dataset "$out/data" --size "$size" --json "$out/int8/eval.json" \
  >"$out/int8/eval.txt"
"$sfrt" bench --model "$model8" --size "$size" --threads 1,2 --json "$out/int8/bench.json" \
  >"$out/int8/bench.txt"
grep -m 1 "^note:" "$out/int8/bench.txt" || true

# Three-line summary from the JSON reports.
python3 - "$out" <<'EOF'
import json, sys
out = sys.argv[1]
ev = json.load(open(f"{out}/eval.json"))
ov = ev.get("overall", ev)
def epe(m):
    return ov[m]["epe3d"]
run = json.load(open(f"{out}/run/summary.json"))
def find(d, key):
    if isinstance(d, dict):
        if key in d:
            return d[key]
        for v in d.values():
            r = find(v, key)
            if r is not None:
                return r
    return None
print(f"demo: mean 3D EPE on the held-out sequence {epe('sfrt'):.4f} m (zero flow "
      f"{epe('zero_flow'):.4f}, ratio {epe('sfrt') / epe('zero_flow'):.2f}; classical "
      f"{epe('classical'):.4f})")
e2e = find(run, "end_to_end")
p50 = e2e.get("p50") if isinstance(e2e, dict) else None
print(f"demo: {run['frames']['written']} frames through sfrt run at 10 fps"
      + (f", capture-to-output latency p50 {p50:.1f} ms" if isinstance(p50, (int, float)) else "")
      + f"; outputs in {out}/ (run/ flow .pfm + .png + flow.avi, eval.txt/.json, "
        f"bench.json, run/summary.json, int8/)")
ev8 = json.load(open(f"{out}/int8/eval.json"))
epe8 = ev8.get("overall", ev8)["sfrt"]["epe3d"]
def best(path):  # the median of the last configuration (best ISA, most threads)
    r = json.load(open(path))["results"][-1]
    return r["median_ms"], r["isa"], r["threads"]
ms32, isa, threads = best(f"{out}/bench.json")
ms8, _, _ = best(f"{out}/int8/bench.json")
print(f"demo: int8 model EPE {epe8:.4f} m ({100 * (epe8 / epe('sfrt') - 1):+.1f}% against "
      f"float32); latency median {ms8:.2f} ms against {ms32:.2f} ms float32 ({isa}, "
      f"{threads} threads)")
EOF
