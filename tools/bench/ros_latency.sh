#!/bin/bash
# Latency through ROS (issue 14): sfrt_ros on a stereo stream published live at 30 fps by
# tools/ros/publish_stereo.py (640x480 bgr8 frames of a `sfrt synth` sequence, stamped at
# publication), the default model at 96x128, against the pipeline alone (`sfrt run` replaying the
# same frames at 30 fps, same model, size and queues), in alternating rounds.
# Prints per run: windows, fps, the end to end p50/p99 (the node: header stamp to the end of the
# output stage, which publishes; the replay: end of the read to the end of the output stage), the
# node's stamp to publish of `flow` (ROS time) and its transport part (stamp to the callback).
# usage: tools/bench/ros_latency.sh [SECONDS] [ROUNDS] [OUTDIR]   (after a release build; idle
#        machine; roscore, rospy and numpy from Debian: tools/install-deps.sh)
set -u
root=$(cd "$(dirname "$0")/../.." && pwd)
seconds=${1:-20}
rounds=${2:-3}
out=$(mkdir -p "${3:-$root/out/ros-latency}" && cd "${3:-$root/out/ros-latency}" && pwd)
bin=$root/build/release/bin
model=$root/models/sceneednet-default.sfrt
for f in "$bin/sfrt" "$bin/sfrt_ros" "$model"; do
  [[ -e $f ]] || { echo "ros_latency.sh: $f is missing: build the release preset first" >&2; exit 2; }
done
frames=$(python3 -c "print(int($seconds * 30))")

seq_dir=$out/synth/frames_cleanpass/0000
if [[ ! -d $seq_dir ]]; then
  "$bin/sfrt" synth --out "$out/synth" --frames 30 --size 480x640 --seed 7 >/dev/null || exit 1
fi

port=$(/usr/bin/python3 -c "import socket; s=socket.socket(); s.bind(('127.0.0.1',0)); print(s.getsockname()[1])")
export ROS_MASTER_URI=http://127.0.0.1:$port ROS_IP=127.0.0.1 ROS_HOME=$out/ros_home
roscore -p "$port" >"$out/roscore.log" 2>&1 &
core=$!
trap 'kill -INT $core 2>/dev/null; wait $core 2>/dev/null' EXIT
for _ in $(seq 100); do
  rostopic list >/dev/null 2>&1 && break
  sleep 0.2
done

report() {  # summary.json -> one line
  /usr/bin/python3 - "$1" "$2" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
e = s["latency_ms"]["end_to_end"]
parts = s["latency_attribution_ms"]["parts"]
line = "%-5s windows %4d  fps %5.2f  drops %3d  end to end p50 %6.2f p99 %6.2f ms" % (
    sys.argv[2], s["frames"]["written"], s["fps"], sum(s["drops"].values()), e["p50"], e["p99"])
for sink in s.get("sinks", []):
    if sink.get("name") == "ros":
        st = sink["stamp_to_publish_ms"]
        line += "  stamp->publish p50 %6.2f p99 %6.2f ms" % (st["p50"], st["p99"])
        c = parts["capture_to_dequeue"]
        line += "  (transport p50 %5.2f p99 %5.2f)" % (c["p50"], c["p99"])
print(line)
PY
}

for r in $(seq "$rounds"); do
  sync
  node_out=$out/node_$r && rm -rf "$node_out" && mkdir -p "$node_out"
  "$bin/sfrt_ros" _model:="$model" _size:=96x128 _out:="$node_out" >"$node_out/node.log" 2>&1 &
  node=$!
  /usr/bin/python3 "$root/tools/ros/publish_stereo.py" --left "$seq_dir/left" \
    --right "$seq_dir/right" --fps 30 --seconds "$seconds" >"$node_out/publisher.log" 2>&1
  sleep 0.5
  kill -INT $node
  wait $node
  report "$node_out/summary.json" node
  sed 's/^/      /' "$node_out/publisher.log"

  sync
  run_out=$out/pipeline_$r && rm -rf "$run_out"
  "$bin/sfrt" run --model "$model" --replay-left "$seq_dir/left" --replay-right "$seq_dir/right" \
    --replay-fps 30 --size 96x128 --loop 1000 --max-frames "$frames" --queue newest-wins \
    --flow-format none --no-png --progress off --out "$run_out" >"$out/pipeline_$r.log" 2>&1
  report "$run_out/summary.json" alone
done
