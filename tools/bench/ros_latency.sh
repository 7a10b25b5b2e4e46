#!/bin/bash
# Latency through ROS (issues 14 and 39): the nodes on a stereo stream published live at 30 fps
# (640x480 bgr8 frames of a `sfrt synth` sequence, stamped at publication), the default model at
# 96x128, in alternating rounds:
#   ros1   sfrt_ros, the frames from tools/ros/publish_stereo.py over roscore (TCPROS);
#   ros2   sfrt_ros2 (qos sensor_data), the same frames from sfrt_cyclone_peer publish-stereo
#          --stamp now over Cyclone DDS on loopback (best effort, keep last 5, as a ROS 2 camera
#          driver publishes), when the build has them;
#   alone  the pipeline alone (`sfrt run` replaying the same frames at 30 fps, same model, size
#          and queues).
# Prints per run: windows, fps, the end to end p50/p99 (the nodes: header stamp to the end of the
# output stage, which publishes; the replay: end of the read to the end of the output stage), the
# node's stamp to publish of `flow` (wall clock) and its transport part (stamp to the callback).
# usage: tools/bench/ros_latency.sh [SECONDS] [ROUNDS] [OUTDIR]   (after a release build; idle
#        machine; roscore, rospy, numpy and Cyclone DDS from Debian: tools/install-deps.sh)
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

# The ROS 2 round's publisher reads raw bgr8 files listed in an index (tests/ros2/cyclone_peer.cc).
ros2=0
if [[ -x $bin/sfrt_ros2 && -x $bin/sfrt_cyclone_peer ]]; then
  ros2=1
  bgr_dir=$out/bgr
  if [[ ! -f $bgr_dir/index.txt ]]; then
    mkdir -p "$bgr_dir"
    /usr/bin/python3 - "$seq_dir" "$bgr_dir" <<'PY' || exit 1
import os, sys
import numpy as np
from PIL import Image
seq, out = sys.argv[1:3]
names = sorted(os.listdir(os.path.join(seq, "left")))
with open(os.path.join(out, "index.txt"), "w") as index:
    for i, name in enumerate(names):
        for side in ("left", "right"):
            rgb = np.asarray(Image.open(os.path.join(seq, side, name)).convert("RGB"))
            rgb[:, :, ::-1].tofile(os.path.join(out, "%s%d.bgr" % (side[0], i)))
        index.write("0 0 %d %d l%d.bgr r%d.bgr\n" % (rgb.shape[0], rgb.shape[1], i, i))
PY
  fi
  export ROS_DOMAIN_ID=$((100 + $$ % 100))
  # Cyclone configurations, each a ros2 round: loopback only, with a socket receive buffer that
  # holds a burst of 900 KiB images (the ROS 2 documentation's advice for large messages on
  # Cyclone; the kernel caps it at net.core.rmem_max; without it best-effort images are lost), and
  # then also with 62 KB fragments instead of Cyclone's 1344 B ones (loopback's MTU is 64 KiB; a
  # single-host robot's tuning). Another configuration: SFRT_BENCH_CYCLONEDDS_URI.
  dds_head='<CycloneDDS><Domain Id="any"><General><Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces><AllowMulticast>false</AllowMulticast>'
  dds_tail='</General><Internal><SocketReceiveBufferSize min="default" max="4MB"/></Internal><Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>'
  if [[ -n ${SFRT_BENCH_CYCLONEDDS_URI:-} ]]; then
    dds_labels=(ros2) dds_uris=("$SFRT_BENCH_CYCLONEDDS_URI")
  else
    dds_labels=(ros2 ros2/64k)
    dds_uris=("$dds_head$dds_tail"
              "$dds_head<MaxMessageSize>65500B</MaxMessageSize><FragmentSize>62000B</FragmentSize>$dds_tail")
  fi
else
  echo "ros_latency.sh: no sfrt_ros2 or sfrt_cyclone_peer in $bin: the ros2 rounds are left out" >&2
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
line = "%-8s windows %4d  fps %5.2f  drops %3d  end to end p50 %6.2f p99 %6.2f ms" % (
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
  report "$node_out/summary.json" ros1
  sed 's/^/      /' "$node_out/publisher.log"

  for (( c = 0; ros2 && c < ${#dds_labels[@]}; ++c )); do
    sync
    node2_out=$out/node2_${r}_$c && rm -rf "$node2_out" && mkdir -p "$node2_out"
    CYCLONEDDS_URI=${dds_uris[c]} "$bin/sfrt_ros2" --ros-args -p model:="$model" \
      -p size:=96x128 -p out:="$node2_out" >"$node2_out/node.log" 2>&1 &
    node2=$!
    CYCLONEDDS_URI=${dds_uris[c]} "$bin/sfrt_cyclone_peer" publish-stereo \
      --domain "$ROS_DOMAIN_ID" --left-topic rt/left/image_rect \
      --right-topic rt/right/image_rect --frames "$bgr_dir" --rate-hz 30 --stamp now \
      --loops "$(( frames / 30 > 0 ? frames / 30 : 1 ))" --reliability best-effort --depth 5 \
      --linger-ms 0 >"$node2_out/publisher.log" 2>&1
    sleep 0.5
    kill -INT $node2
    wait $node2
    report "$node2_out/summary.json" "${dds_labels[c]}"
    sed 's/^/      /' "$node2_out/publisher.log"
  done

  sync
  run_out=$out/pipeline_$r && rm -rf "$run_out"
  "$bin/sfrt" run --model "$model" --replay-left "$seq_dir/left" --replay-right "$seq_dir/right" \
    --replay-fps 30 --size 96x128 --loop 1000 --max-frames "$frames" --queue newest-wins \
    --flow-format none --no-png --progress off --out "$run_out" >"$out/pipeline_$r.log" 2>&1
  report "$run_out/summary.json" alone
done
