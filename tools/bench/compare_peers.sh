#!/usr/bin/env bash
# sfrt against its peers on one ONNX model, in the same run: ONNX Runtime (onnxruntime-node,
# tools/bench/ort_bench.mjs) and OpenCV DNN (sfrt_opencv_dnn_bench, cv::dnn::readNetFromONNX).
# Exports MODEL.onnx to .sfrt, then for each thread count alternates `sfrt bench` and each peer
# (one configuration per process, so peak resident memory is one session's), round after round,
# and prints every median (over all rounds' runs), the ratios sfrt / peer, effective GFLOP/s
# and peak resident memories. The peers read the same seeded input (ort_bench.mjs's LCG);
# `sfrt bench` its own seeded input (no kernel's time depends on the values).
#
# Usage: bash tools/bench/compare_peers.sh [--peers ort,opencv] [--opencv-model FILE.onnx]
#                                          MODEL.onnx HxW [THREADS=1,2] [ROUNDS=3] [RUNS=2]
# --peers: any of ort, opencv (default both; OpenCV DNN takes ~3 s a run at full width 540x960).
# --opencv-model: the ONNX file OpenCV DNN runs instead of MODEL. OpenCV DNN 4.6 cannot parse
#   the tf-padding exports (their Pad amounts come from a Clip with min/max inputs); give it the
#   torch-padding export of the same network (gen_sceneednet.py --padding torch: same shapes
#   and MACs, symmetric instead of asymmetric padding).
# Environment: SFRT=path/to/sfrt (default build/release/bin/sfrt), SFRT_BENCH_ISA (default best),
# SFRT_OPENCV_DNN_BENCH (default: sfrt_opencv_dnn_bench next to $SFRT).
# If tools/bench/node_modules lacks onnxruntime-node, this script installs it with npm
# (ONNXRUNTIME_NODE_INSTALL=skip: the CPU library ships in the package) and says so.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "${here}/../.." && pwd)"
me="$(basename "$0" .sh)"

usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "${here}/compare_peers.sh"; }
peers="ort,opencv"
opencv_model=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --peers | --opencv-model)
      [[ $# -ge 2 ]] || { echo "${me}: $1 needs a value" >&2; exit 2; }
      [[ "$1" == "--peers" ]] && peers="$2" || opencv_model="$2"
      shift 2 ;;
    --peers=*) peers="${1#--peers=}"; shift ;;
    --opencv-model=*) opencv_model="${1#--opencv-model=}"; shift ;;
    *) break ;;
  esac
done
if [[ $# -lt 2 || "$1" == "-h" || "$1" == "--help" ]]; then
  usage
  [[ $# -ge 2 ]] && exit 0 || exit 2
fi
use_ort=0
use_opencv=0
IFS=',' read -r -a peer_list <<<"${peers}"
for p in "${peer_list[@]}"; do
  case "${p}" in
    ort) use_ort=1 ;;
    opencv) use_opencv=1 ;;
    *) echo "${me}: --peers: unknown peer '${p}' (known: ort, opencv)" >&2; exit 2 ;;
  esac
done
[[ ${use_ort} == 1 || ${use_opencv} == 1 ]] || { echo "${me}: --peers is empty" >&2; exit 2; }
model="$1"
size="$2"
threads_list="${3:-1,2}"
rounds="${4:-3}"
runs="${5:-2}"
sfrt="${SFRT:-${root}/build/release/bin/sfrt}"
opencv_bench="${SFRT_OPENCV_DNN_BENCH:-$(dirname "${sfrt}")/sfrt_opencv_dnn_bench}"
isa="${SFRT_BENCH_ISA:-best}"
if [[ ! "${size}" =~ ^([0-9]+)x([0-9]+)$ ]]; then
  echo "${me}: size must be HxW, got '${size}'" >&2
  exit 2
fi
height="${BASH_REMATCH[1]}"
width="${BASH_REMATCH[2]}"
[[ -f "${model}" ]] || { echo "${me}: no model file '${model}'" >&2; exit 1; }
opencv_model="${opencv_model:-${model}}"
if [[ ${use_opencv} == 1 && ! -f "${opencv_model}" ]]; then
  echo "${me}: no model file '${opencv_model}' (--opencv-model)" >&2
  exit 1
fi
[[ -x "${sfrt}" ]] || { echo "${me}: no sfrt binary at ${sfrt} (build it or set SFRT=)" >&2; exit 1; }
if [[ ${use_opencv} == 1 && ! -x "${opencv_bench}" ]]; then
  echo "${me}: no sfrt_opencv_dnn_bench at ${opencv_bench} (build target sfrt_opencv_dnn_bench," \
       "needs libopencv-dnn-dev; or set SFRT_OPENCV_DNN_BENCH=, or --peers ort)" >&2
  exit 1
fi
python=/usr/bin/python3

if [[ ${use_ort} == 1 ]]; then
  command -v node >/dev/null || { echo "${me}: node not found (apt-get install nodejs npm)" >&2; exit 1; }
  if [[ ! -d "${here}/node_modules/onnxruntime-node" ]]; then
    echo "${me}: onnxruntime-node is missing; installing it now:" \
         "(cd ${here} && ONNXRUNTIME_NODE_INSTALL=skip npm install)"
    (cd "${here}" && ONNXRUNTIME_NODE_INSTALL=skip npm install --no-audit --no-fund)
  fi
fi

work="$(mktemp -d)"
trap 'rm -rf "${work}"' EXIT
sfrt_model="${work}/model.sfrt"
"${sfrt}" export "${model}" -o "${sfrt_model}" >/dev/null
echo "model ${model} at ${height}x${width}; sfrt isa ${isa}; peers ${peers}; ${rounds} rounds x" \
     "${runs} runs, alternating (load now: $(cut -d' ' -f1-3 /proc/loadavg))"
if [[ ${use_opencv} == 1 && "${opencv_model}" != "${model}" ]]; then
  echo "OpenCV DNN runs ${opencv_model}"
fi

IFS=',' read -r -a thread_counts <<<"${threads_list}"
for round in $(seq 1 "${rounds}"); do
  for t in "${thread_counts[@]}"; do
    "${sfrt}" bench --model "${sfrt_model}" --size "${height}x${width}" --isa "${isa}" \
      --threads "${t}" --warmup 1 --runs "${runs}" --json "${work}/sfrt_t${t}_r${round}.json" \
      >/dev/null
    if [[ ${use_ort} == 1 ]]; then
      node "${here}/ort_bench.mjs" "${model}" "${height}" "${width}" "${t}" "${runs}" 1 \
        >"${work}/ort_t${t}_r${round}.json"
    fi
    if [[ ${use_opencv} == 1 ]]; then
      if ! "${opencv_bench}" "${opencv_model}" "${height}" "${width}" "${t}" "${runs}" 1 \
        >"${work}/opencv_t${t}_r${round}.json" 2>"${work}/opencv.err"; then
        tail -n 5 "${work}/opencv.err" >&2
        echo "${me}: OpenCV DNN failed on ${opencv_model} (tf-padding files need" \
             "--opencv-model with the torch-padding export; or --peers ort)" >&2
        exit 1
      fi
    fi
  done
done

"${python}" - "${work}" "${threads_list}" "${peers}" <<'PY'
import glob, json, statistics, sys
work, threads = sys.argv[1], [int(t) for t in sys.argv[2].split(',')]
names = {"ort": "ORT", "opencv": "OpenCV"}
peers = [p for p in ("ort", "opencv") if p in sys.argv[3].split(',')]

def last_json(path):
    return json.loads(open(path).read().strip().splitlines()[-1])

head = f"{'threads':>7} {'sfrt ms':>9}"
for p in peers:
    n = names[p]
    head += f" {n + ' ms':>10} {'sfrt/' + n:>11} {'spread':>11}"
head += f" {'sfrt GF/s':>9}" + "".join(f" {names[p] + ' GF/s':>11}" for p in peers)
head += f" {'sfrt MiB':>8}" + "".join(f" {names[p] + ' MiB':>10}" for p in peers)
print(head)
for t in threads:
    s = [json.load(open(f)) for f in sorted(glob.glob(f"{work}/sfrt_t{t}_r*.json"))]
    macs = s[0]["macs"]
    sm = statistics.median([r["median_ms"] for j in s for r in j["results"]])
    line = f"{t:>7} {sm:>9.1f}"
    gf = f" {2 * macs / sm / 1e6:>9.1f}"
    mib = f" {max(j['peak_rss_mib'] for j in s):>8.1f}"
    for p in peers:
        o = [last_json(f) for f in sorted(glob.glob(f"{work}/{p}_t{t}_r*.json"))]
        om = statistics.median([j["median_ms"] for j in o])
        # Per-round ratios show how noisy the machine was.
        ratios = [a["results"][0]["median_ms"] / b["median_ms"] for a, b in zip(s, o)]
        line += f" {om:>10.1f} {sm / om:>11.3f} {min(ratios):>5.3f}-{max(ratios):.3f}"
        gf += f" {2 * macs / om / 1e6:>11.1f}"
        mib += f" {max(j['peak_rss_mib'] for j in o):>10.1f}"
    print(line + gf + mib)
print("sfrt/peer: ratio of medians over all rounds; spread: lowest-highest per-round ratio;"
      " GF/s: effective GFLOP/s (2 x the model's MACs / median); MiB: peak resident memory of"
      " one process (one session).")
PY
