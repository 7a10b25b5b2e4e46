#!/usr/bin/env bash
# sfrt against its peers on one ONNX model, in the same run: ONNX Runtime float32 and int8
# (onnxruntime-node, tools/bench/ort_bench.mjs), OpenCV DNN (sfrt_opencv_dnn_bench) and PyTorch
# bf16/float32 (tools/bench/torch_bench.py). Exports MODEL.onnx to .sfrt (once per
# --sfrt-precision), then for each thread count alternates `sfrt bench` of each precision and
# each peer (one configuration per process, so peak resident memory is one session's), round
# after round, and prints per thread count every median (over all rounds' runs), effective
# GFLOP/s and peak resident memory, and the ratio sfrt / peer for each sfrt precision and peer
# with its per-round spread. The peers read the same seeded input (ort_bench.mjs's LCG);
# `sfrt bench` its own seeded input (no kernel's time depends on the values).
#
# Usage: bash tools/bench/compare_peers.sh [--peers LIST] [--sfrt-precision fp32,bf16,int8]
#          [--calibration CAL.npy] [--opencv-model FILE.onnx] [--json FILE] MODEL.onnx HxW
#          [THREADS=1,2] [ROUNDS=3] [RUNS=2]
# --peers: any of ort, ort-int8, opencv, torch-bf16, torch-fp32 (default ort,opencv). The
#   strongest on x86: --peers ort,ort-int8,torch-bf16. At full width 540x960, 2 threads, one
#   run takes seconds: about 2 s (ort), 1-2 s (ort-int8, torch-bf16), 3 s (opencv).
#   ort-int8: MODEL turned into a QDQ int8 ONNX by make_qdq_onnx.py (int8 weights per channel,
#   uint8 activations, ranges from the calibration frames); before the rounds one profiled run
#   (ORT's profiler) must show QLinearConv and no float Conv, and prints its error against ort.
#   torch-bf16: the network in PyTorch eager bfloat16, channels_last; before the rounds one run
#   with oneDNN verbose must show every convolution in bf16 (e.g. brgconv:avx512_core_bf16).
#   torch-fp32: the same in float32. The torch peers run with OMP_WAIT_POLICY=PASSIVE unless it
#   is set: on a shared 2-core machine spinning OpenMP threads made 2-thread runs up to 20x
#   slower (270x480, 1/8 width) and far more variable.
# --sfrt-precision: any of fp32, bf16, int8 (default fp32), one row each; bf16 is exported with
#   `sfrt export MODEL.onnx --precision bf16`, int8 with `sfrt export MODEL.onnx --precision int8
#   --calibration CAL.npy` (its error is printed).
# --calibration: float32 .npy (N,H,W,12) network inputs for sfrt int8 and ort-int8 alike
#   (default: 2 seeded frames of integers 0..255 at 96x128; percentile:99.99 for both).
# --json: also write the summary to FILE: per thread count, each configuration's median_ms,
#   gflops and peak_rss_mib, and each sfrt precision's ratio to each peer (the ratio of medians
#   and its per-round lowest and highest).
# --opencv-model: the ONNX file OpenCV DNN runs instead of MODEL. OpenCV DNN 4.6 cannot parse
#   the tf-padding exports (their Pad amounts come from a Clip with min/max inputs); give it the
#   torch-padding export of the same network (gen_sceneednet.py --padding torch: same shapes
#   and MACs, symmetric instead of asymmetric padding).
# Environment: SFRT=path/to/sfrt (default build/release/bin/sfrt), SFRT_BENCH_ISA (default best),
# SFRT_OPENCV_DNN_BENCH (default: sfrt_opencv_dnn_bench next to $SFRT).
# If tools/bench/node_modules lacks onnxruntime-node, this script installs it with npm
# (ONNXRUNTIME_NODE_INSTALL=skip: the CPU library ships in the package) and says so.
# The ort-int8 and torch peers need Debian's /usr/bin/python3 with python3-torch and python3-onnx.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "${here}/../.." && pwd)"
me="$(basename "$0" .sh)"

usage() { awk 'NR > 1 && /^#/ { sub(/^# ?/, ""); print; next } NR > 1 { exit }' "${here}/compare_peers.sh"; }
peers="ort,opencv"
precisions="fp32"
calibration=""
opencv_model=""
json_out=""
while [[ $# -gt 0 ]]; do
  case "$1" in
    --peers | --sfrt-precision | --calibration | --opencv-model | --json)
      [[ $# -ge 2 ]] || { echo "${me}: $1 needs a value" >&2; exit 2; }
      case "$1" in
        --peers) peers="$2" ;;
        --sfrt-precision) precisions="$2" ;;
        --calibration) calibration="$2" ;;
        --opencv-model) opencv_model="$2" ;;
        --json) json_out="$2" ;;
      esac
      shift 2 ;;
    --peers=*) peers="${1#--peers=}"; shift ;;
    --sfrt-precision=*) precisions="${1#--sfrt-precision=}"; shift ;;
    --calibration=*) calibration="${1#--calibration=}"; shift ;;
    --opencv-model=*) opencv_model="${1#--opencv-model=}"; shift ;;
    --json=*) json_out="${1#--json=}"; shift ;;
    *) break ;;
  esac
done
if [[ $# -ge 1 && ( "$1" == "-h" || "$1" == "--help" ) ]]; then
  usage
  exit 0
fi
if [[ $# -lt 2 ]]; then
  usage >&2
  exit 2
fi
known_peers="ort ort-int8 opencv torch-bf16 torch-fp32"
IFS=',' read -r -a peer_list <<<"${peers}"
[[ ${#peer_list[@]} -gt 0 ]] || { echo "${me}: --peers is empty" >&2; exit 2; }
declare -A use=()
for p in "${peer_list[@]}"; do
  [[ " ${known_peers} " == *" ${p} "* ]] ||
    { echo "${me}: --peers: unknown peer '${p}' (known: ${known_peers// /, })" >&2; exit 2; }
  [[ -z "${use[${p}]:-}" ]] || { echo "${me}: --peers: '${p}' given twice" >&2; exit 2; }
  use[${p}]=1
done
IFS=',' read -r -a precision_list <<<"${precisions}"
[[ ${#precision_list[@]} -gt 0 ]] || { echo "${me}: --sfrt-precision is empty" >&2; exit 2; }
declare -A seen_precision=()
for q in "${precision_list[@]}"; do
  [[ "${q}" == fp32 || "${q}" == bf16 || "${q}" == int8 ]] ||
    { echo "${me}: --sfrt-precision: unknown precision '${q}' (known: fp32, bf16, int8)" >&2
      exit 2; }
  [[ -z "${seen_precision[${q}]:-}" ]] ||
    { echo "${me}: --sfrt-precision: '${q}' given twice" >&2; exit 2; }
  seen_precision[${q}]=1
done
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
[[ "${threads_list}" =~ ^[1-9][0-9]*(,[1-9][0-9]*)*$ ]] ||
  { echo "${me}: THREADS must be a list like 1,2, got '${threads_list}'" >&2; exit 2; }
[[ "${rounds}" =~ ^[1-9][0-9]*$ && "${runs}" =~ ^[1-9][0-9]*$ ]] ||
  { echo "${me}: ROUNDS and RUNS must be >= 1, got '${rounds}' '${runs}'" >&2; exit 2; }
[[ -f "${model}" ]] || { echo "${me}: no model file '${model}'" >&2; exit 1; }
opencv_model="${opencv_model:-${model}}"
if [[ -n "${use[opencv]:-}" && ! -f "${opencv_model}" ]]; then
  echo "${me}: no model file '${opencv_model}' (--opencv-model)" >&2
  exit 1
fi
if [[ -n "${calibration}" && ! -f "${calibration}" ]]; then
  echo "${me}: no calibration file '${calibration}' (--calibration)" >&2
  exit 1
fi
[[ -x "${sfrt}" ]] || { echo "${me}: no sfrt binary at ${sfrt} (build it or set SFRT=)" >&2; exit 1; }
if [[ -n "${use[opencv]:-}" && ! -x "${opencv_bench}" ]]; then
  echo "${me}: no sfrt_opencv_dnn_bench at ${opencv_bench} (build target sfrt_opencv_dnn_bench," \
       "needs libopencv-dnn-dev; or set SFRT_OPENCV_DNN_BENCH=, or --peers ort)" >&2
  exit 1
fi
python=/usr/bin/python3
[[ -x "${python}" ]] || { echo "${me}: ${python} not found (Debian python3)" >&2; exit 1; }

if [[ -n "${use[ort]:-}${use[ort-int8]:-}" ]]; then
  command -v node >/dev/null || { echo "${me}: node not found (apt-get install nodejs npm)" >&2; exit 1; }
  if [[ ! -d "${here}/node_modules/onnxruntime-node" ]]; then
    echo "${me}: onnxruntime-node is missing; installing it now:" \
         "(cd ${here} && ONNXRUNTIME_NODE_INSTALL=skip npm install)"
    (cd "${here}" && ONNXRUNTIME_NODE_INSTALL=skip npm install --no-audit --no-fund)
  fi
fi
if [[ -n "${use[ort-int8]:-}${use[torch-bf16]:-}${use[torch-fp32]:-}" ]]; then
  "${python}" -c 'import torch, onnx, numpy' 2>/dev/null ||
    { echo "${me}: ort-int8 and torch-* need ${python} with torch, onnx and numpy" \
           "(apt-get install python3-torch python3-onnx python3-numpy)" >&2; exit 1; }
fi

torch_omp="${OMP_WAIT_POLICY:-PASSIVE}"  # PyTorch's OpenMP threads only (--help)
work="$(mktemp -d)"
trap 'rm -rf "${work}"' EXIT
IFS=',' read -r -a thread_counts <<<"${threads_list}"
echo "model ${model} at ${height}x${width}; sfrt isa ${isa}, precision ${precisions};" \
     "peers ${peers}; ${rounds} rounds x ${runs} runs, alternating (load now:" \
     "$(cut -d' ' -f1-3 /proc/loadavg))"

# Calibration frames, shared by sfrt int8 and ort-int8.
if [[ -z "${calibration}" && ( -n "${seen_precision[int8]:-}" || -n "${use[ort-int8]:-}" ) ]]; then
  calibration="${work}/calibration.npy"
  "${python}" -c '
import sys, numpy as np
rng = np.random.default_rng(20240601)
np.save(sys.argv[1], rng.integers(0, 256, size=(2, 96, 128, 12)).astype(np.float32))
' "${calibration}"
  echo "calibration: 2 seeded frames of integers 0..255 at 96x128"
elif [[ -n "${calibration}" ]]; then
  echo "calibration: ${calibration}"
fi

for q in "${precision_list[@]}"; do
  if [[ "${q}" == fp32 ]]; then
    "${sfrt}" export "${model}" -o "${work}/model-fp32.sfrt" >/dev/null
  elif [[ "${q}" == bf16 ]]; then
    "${sfrt}" export "${model}" -o "${work}/model-bf16.sfrt" --precision bf16 >/dev/null
  else
    if ! "${sfrt}" export "${model}" -o "${work}/model-int8.sfrt" --precision int8 \
        --calibration "${calibration}" >"${work}/export-int8.txt" 2>&1; then
      tail -n 5 "${work}/export-int8.txt" >&2
      echo "${me}: sfrt export --precision int8 failed" >&2
      exit 1
    fi
    echo "sfrt-int8: $(grep -m1 -E '^ +error ' "${work}/export-int8.txt" |
      sed -E 's/^ +//; s/ +/ /g')"
  fi
done

# One untimed check run per peer that must prove what it ran (first thread count).
t0="${thread_counts[0]}"
if [[ -n "${use[ort-int8]:-}" ]]; then
  qdq="${work}/model-qdq.onnx"
  "${python}" "${here}/make_qdq_onnx.py" "${model}" -o "${qdq}" --calibration "${calibration}" \
    >"${work}/qdq.txt" || { echo "${me}: make_qdq_onnx.py failed" >&2; exit 1; }
  node "${here}/ort_bench.mjs" --profile="${work}/ort-int8-profile" --reference="${model}" \
    "${qdq}" "${height}" "${width}" "${t0}" 1 0 >"${work}/ort-int8-check.json" \
    || { echo "${me}: ort_bench.mjs failed on the QDQ model" >&2; exit 1; }
  "${python}" - "${work}/ort-int8-check.json" <<'PY' ||
import json, sys
j = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
ops = j["ops"]
print("ort-int8: ORT profile, node types run (nodes, kernel ms): " + ", ".join(
    f"{k} {v['nodes']} ({v['ms']:.1f})"
    for k, v in sorted(ops.items(), key=lambda kv: -kv[1]["ms"])))
r = j["vs_reference"]
print(f"ort-int8: error against ort (float32) on the bench input: output max {r['max_rel']:.2e},"
      f" rms {r['rms_rel']:.2e} relative")
float_convs = sorted(k for k in ops if k in ("Conv", "FusedConv", "NhwcFusedConv"))
if float_convs or "QLinearConv" not in ops:
    sys.exit(f"ort-int8: ONNX Runtime ran {', '.join(float_convs) or 'no QLinearConv'}: the QDQ"
             f" model did not run int8 convolutions")
PY
    { echo "${me}: ort-int8 check failed" >&2; exit 1; }
fi
for dtype in bf16 fp32; do
  [[ -n "${use[torch-${dtype}]:-}" ]] || continue
  OMP_WAIT_POLICY="${torch_omp}" "${python}" "${here}/torch_bench.py" --dtype "${dtype}" \
    --verbose-kernels "${model}" "${height}" "${width}" "${t0}" 1 0 \
    >"${work}/torch-${dtype}-check.json" 2>"${work}/torch.err" ||
    { tail -n 5 "${work}/torch.err" >&2; echo "${me}: torch_bench.py failed" >&2; exit 1; }
  "${python}" - "${work}/torch-${dtype}-check.json" "${dtype}" <<'PY' ||
import json, sys
j = json.loads(open(sys.argv[1]).read().strip().splitlines()[-1])
impls, dtype = j.get("conv_impls", {}), sys.argv[2]
print(f"torch-{dtype}: oneDNN convolutions per run: "
      + ", ".join(f"{k} x{n}" for k, n in impls.items()))
if dtype == "bf16" and (sum(impls.values()) != 11 or any("src_bf16" not in k for k in impls)):
    sys.exit("torch-bf16: not every one of the 11 convolutions ran in bf16 through oneDNN")
PY
    { echo "${me}: torch-${dtype} check failed" >&2; exit 1; }
done
if [[ -n "${use[opencv]:-}" && "${opencv_model}" != "${model}" ]]; then
  echo "OpenCV DNN runs ${opencv_model}"
fi

for round in $(seq 1 "${rounds}"); do
  for t in "${thread_counts[@]}"; do
    for q in "${precision_list[@]}"; do
      "${sfrt}" bench --model "${work}/model-${q}.sfrt" --size "${height}x${width}" --isa "${isa}" \
        --threads "${t}" --warmup 1 --runs "${runs}" \
        --json "${work}/sfrt-${q}_t${t}_r${round}.json" >/dev/null
    done
    for p in "${peer_list[@]}"; do
      out="${work}/${p}_t${t}_r${round}.json"
      case "${p}" in
        ort | ort-int8)
          [[ "${p}" == ort ]] && onnx="${model}" || onnx="${qdq}"
          node "${here}/ort_bench.mjs" "${onnx}" "${height}" "${width}" "${t}" "${runs}" 1 >"${out}" ;;
        torch-*)
          OMP_WAIT_POLICY="${torch_omp}" "${python}" "${here}/torch_bench.py" --dtype "${p#torch-}" \
            "${model}" "${height}" "${width}" "${t}" "${runs}" 1 >"${out}" ;;
        opencv)
          if ! "${opencv_bench}" "${opencv_model}" "${height}" "${width}" "${t}" "${runs}" 1 \
            >"${out}" 2>"${work}/opencv.err"; then
            tail -n 5 "${work}/opencv.err" >&2
            echo "${me}: OpenCV DNN failed on ${opencv_model} (tf-padding files need" \
                 "--opencv-model with the torch-padding export; or --peers ort)" >&2
            exit 1
          fi ;;
      esac
    done
  done
done

"${python}" - "${work}" "${threads_list}" "${precisions}" "${peers}" "${json_out}" <<'PY'
import glob, json, os, statistics, sys
work, threads = sys.argv[1], [int(t) for t in sys.argv[2].split(',')]
sfrts = ["sfrt-" + q for q in sys.argv[3].split(',')]
peers = sys.argv[4].split(',')
json_out = sys.argv[5]
summary = {"threads": {}}

def last_json(path):
    return json.loads(open(path).read().strip().splitlines()[-1])

def files(config, t):
    return sorted(glob.glob(f"{work}/{config}_t{t}_r*.json"),
                  key=lambda f: int(f.rsplit("_r", 1)[1].split(".")[0]))

w = max(len(c) for c in sfrts + peers) + 2
for t in threads:
    macs = json.load(open(files(sfrts[0], t)[0]))["macs"]
    median, per_round, mib = {}, {}, {}
    for c in sfrts:
        s = [json.load(open(f)) for f in files(c, t)]
        median[c] = statistics.median([r["median_ms"] for j in s for r in j["results"]])
        per_round[c] = [j["results"][0]["median_ms"] for j in s]
        mib[c] = max(j["peak_rss_mib"] for j in s)
    for p in peers:
        o = [last_json(f) for f in files(p, t)]
        median[p] = statistics.median([j["median_ms"] for j in o])
        per_round[p] = [j["median_ms"] for j in o]
        mib[p] = max(j["peak_rss_mib"] for j in o)
    print(f"threads {t}")
    print(f"  {'':<{w}} {'median ms':>10} {'GF/s':>8} {'peak MiB':>9}")
    entry = summary["threads"][str(t)] = {"configurations": {}, "ratios": {}}
    for c in sfrts + peers:
        print(f"  {c:<{w}} {median[c]:>10.1f} {2 * macs / median[c] / 1e6:>8.1f} {mib[c]:>9.1f}")
        entry["configurations"][c] = {"median_ms": median[c], "gflops": 2 * macs / median[c] / 1e6,
                                      "peak_rss_mib": mib[c]}
    print((f"  {'sfrt/peer':<{w}}" + "".join(f" {p:<21}" for p in peers)).rstrip())
    for c in sfrts:
        cells = ""
        for p in peers:
            # Per-round ratios show how noisy the machine was.
            ratios = [a / b for a, b in zip(per_round[c], per_round[p])]
            cell = f"{median[c] / median[p]:.3f} ({min(ratios):.3f}-{max(ratios):.3f})"
            entry["ratios"].setdefault(c, {})[p] = {
                "ratio": median[c] / median[p], "lowest": min(ratios), "highest": max(ratios)}
            cells += f" {cell:<21}"
        print(f"  {c:<{w}}{cells}".rstrip())
print("median ms: median over all rounds' runs; GF/s: effective GFLOP/s (2 x the model's MACs /"
      " median, whatever the arithmetic); peak MiB: peak resident memory of one process (one"
      " session); sfrt/peer: ratio of medians (per-round lowest-highest).")
if json_out:
    tmp = json_out + ".tmp"
    with open(tmp, "w") as f:
        json.dump(summary, f, indent=1)
    os.replace(tmp, json_out)
PY
