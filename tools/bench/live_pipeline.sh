#!/bin/bash
# Live pipeline measurements of issue 13 on the fake V4L2 pair (30 fps, 640x480 YUYV, the
# LD_PRELOAD shim of the test build), the default model at 96x128, no file outputs:
#   1 and 2 inference threads, 3 runs each; then the x86 profile's stage priorities (SCHED_FIFO
#   50/45/40, mlockall; needs root or CAP_SYS_NICE) with three CPU-bound processes beside it.
# Prints per run: fps, drops, misses, end-to-end p50/p99 and its parts (summary.json
# latency_attribution_ms), and the acceptance limits. Run it on an otherwise idle machine.
# usage: tools/bench/live_pipeline.sh [FRAMES] [OUTDIR]   (after `cmake --build --preset release`)
set -u
root=$(cd "$(dirname "$0")/../.." && pwd)
frames=${1:-600}
out=$(mkdir -p "${2:-$root/out/live-pipeline}" && cd "${2:-$root/out/live-pipeline}" && pwd)
sfrt=$root/build/release/bin/sfrt
shim=$root/build/release/tests/camera/v4l2/libsfrt_fake_v4l2_preload.so
for f in "$sfrt" "$shim"; do
  [[ -e $f ]] || { echo "live_pipeline.sh: $f is missing: build the release preset first" >&2; exit 2; }
done
cat > "$out/live-x86.yaml" <<YAML
# firmware-cfg/x86-avx512-usb-stereo.yaml adapted to the fake V4L2 pair (issue 13's measurement):
# YUYV, /dev/video0 + /dev/video1, no calibration, budget 20 ms, no file outputs.
version: 1
name: live-x86-fake
camera:
  mode: stereo
  left_device: /dev/video0
  right_device: /dev/video1
  pixel_format: YUYV
  width: 640
  height: 480
  fps: 30
  buffer_count: 4
  pair_tolerance_ms: 8
model:
  file: $root/models/sceneednet-default.sfrt
  input_height: 96
  input_width: 128
stages:
  source:     {threads: 1, cpus: [0], priority: 50}
  preprocess: {threads: 1, cpus: [0], priority: 45}
  infer:      {threads: 2, cpus: [0, 1], priority: 40}
  output:     {threads: 1, cpus: [1], priority: none}
memory:
  mlockall: true
  prefault_arena: true
  cap_mib: 512
latency:
  budget_ms: 20
  percentile: 99
  on_miss: count-only
outputs:
  dir: $out/x86-out
  flow: false
  visualisation: false
  video: false
  summary: true
logging:
  level: warn
YAML
export SFRT_FAKE_V4L2='/dev/video0:side=0;/dev/video1:side=1,phase_ms=2'
summ() {
  python3 - "$1" <<'PY'
import json,sys
j=json.load(open(sys.argv[1]))
a=j["latency_attribution_ms"]["parts"]; e=j["latency_ms"]["end_to_end"]
work=sum(a[k]["p50"] for k in ("capture_to_dequeue","preprocess","infer","output"))
print("fps %.2f written %d drops %s misses %d e2e p50 %.2f p99 %.2f max %.2f | c2d %.2f partner %.2f convert %.2f handoff %.2f qpre %.2f pre %.2f qinf %.2f inf %.2f qout %.2f out %.2f | c2d+pre+inf+out+2 = %.2f, p50+5 = %.2f" % (
 j["fps"], j["frames"]["written"], j["drops"], j["deadline"]["misses"], e["p50"], e["p99"], e["max"],
 a["capture_to_dequeue"]["p50"], a["stereo_partner"]["p50"], a["convert"]["p50"], a["source_handoff"]["p50"],
 a["queue_preprocess"]["p50"], a["preprocess"]["p50"], a["queue_infer"]["p50"], a["infer"]["p50"],
 a["queue_output"]["p50"], a["output"]["p50"], work + 2, e["p50"] + 5))
PY
}
for threads in 1 2; do
  for r in 1 2 3; do
    d=$out/t$threads-r$r; rm -rf $d; mkdir -p $d
    LD_PRELOAD="$shim" "$sfrt" run --model $root/models/sceneednet-default.sfrt \
      --camera /dev/video0,/dev/video1 --size 96x128 --threads $threads --flow-format none \
      --no-png --max-frames $frames --out $d --progress off > $d/stdout.txt 2>&1
    echo "threads $threads run $r: $(summ $d/summary.json)"
  done
done
# Under load: the x86 profile's SCHED_FIFO priorities and three CPU-bound processes.
for r in 1 2 3; do
  d=$out/x86-out; rm -rf $d; mkdir -p $d
  for i in 1 2 3; do (while :; do :; done) & done
  LD_PRELOAD="$shim" "$sfrt" run --config $out/live-x86.yaml --max-frames $frames \
    --progress off > $out/x86-r$r.txt 2>&1
  kill $(jobs -p) 2>/dev/null; wait 2>/dev/null
  cp $d/summary.json $out/x86-r$r.json
  python3 - $out/x86-r$r.json <<'PY'
import json,sys
j=json.load(open(sys.argv[1]))
print("x86 profile + 3 hogs: fps %.2f written %d misses %d (%.2f%% over 20 ms) e2e p50 %.2f p99 %.2f drops %s" % (
  j["fps"], j["frames"]["written"], j["deadline"]["misses"], 100.0*j["deadline"]["misses"]/max(1,j["frames"]["written"]),
  j["latency_ms"]["end_to_end"]["p50"], j["latency_ms"]["end_to_end"]["p99"], j["drops"]))
PY
done
