#!/usr/bin/env bash
# sfrt against ONNX Runtime on one ONNX model, in the same run: exports MODEL.onnx to .sfrt,
# then for each thread count alternates `sfrt bench` (one configuration per process, so its
# peak resident memory is one session's) and tools/bench/ort_bench.mjs (onnxruntime-node, CPU),
# round after round, and prints both medians (over all rounds' runs), the ratio sfrt / ORT,
# effective GFLOP/s and both peak resident memories.
#
# Usage: bash tools/bench/compare_ort.sh MODEL.onnx HxW [THREADS=1,2] [ROUNDS=3] [RUNS=2]
# Environment: SFRT=path/to/sfrt (default build/release/bin/sfrt), SFRT_BENCH_ISA (default best).
# If tools/bench/node_modules lacks onnxruntime-node, this script installs it with npm
# (ONNXRUNTIME_NODE_INSTALL=skip: the CPU library ships in the package) and says so.
set -euo pipefail
here="$(cd "$(dirname "$0")" && pwd)"
root="$(cd "${here}/../.." && pwd)"

if [[ $# -lt 2 || "$1" == "-h" || "$1" == "--help" ]]; then
  sed -n '2,12p' "$0" | sed 's/^# \{0,1\}//'
  [[ $# -ge 2 ]] && exit 0 || exit 2
fi
model="$1"
size="$2"
threads_list="${3:-1,2}"
rounds="${4:-3}"
runs="${5:-2}"
sfrt="${SFRT:-${root}/build/release/bin/sfrt}"
isa="${SFRT_BENCH_ISA:-best}"
if [[ ! "${size}" =~ ^([0-9]+)x([0-9]+)$ ]]; then
  echo "compare_ort: size must be HxW, got '${size}'" >&2
  exit 2
fi
height="${BASH_REMATCH[1]}"
width="${BASH_REMATCH[2]}"
[[ -f "${model}" ]] || { echo "compare_ort: no model file '${model}'" >&2; exit 1; }
[[ -x "${sfrt}" ]] || { echo "compare_ort: no sfrt binary at ${sfrt} (build it or set SFRT=)" >&2; exit 1; }
command -v node >/dev/null || { echo "compare_ort: node not found (apt-get install nodejs npm)" >&2; exit 1; }
python=/usr/bin/python3

if [[ ! -d "${here}/node_modules/onnxruntime-node" ]]; then
  echo "compare_ort: onnxruntime-node is missing; installing it now:" \
       "(cd ${here} && ONNXRUNTIME_NODE_INSTALL=skip npm install)"
  (cd "${here}" && ONNXRUNTIME_NODE_INSTALL=skip npm install --no-audit --no-fund)
fi

work="$(mktemp -d)"
trap 'rm -rf "${work}"' EXIT
sfrt_model="${work}/model.sfrt"
"${sfrt}" export "${model}" -o "${sfrt_model}" >/dev/null
echo "model ${model} at ${height}x${width}; sfrt isa ${isa}; ${rounds} rounds x ${runs} runs," \
     "sfrt and ORT alternating (load now: $(cut -d' ' -f1-3 /proc/loadavg))"

IFS=',' read -r -a thread_counts <<<"${threads_list}"
for round in $(seq 1 "${rounds}"); do
  for t in "${thread_counts[@]}"; do
    "${sfrt}" bench --model "${sfrt_model}" --size "${height}x${width}" --isa "${isa}" \
      --threads "${t}" --warmup 1 --runs "${runs}" --json "${work}/sfrt_t${t}_r${round}.json" \
      >/dev/null
    node "${here}/ort_bench.mjs" "${model}" "${height}" "${width}" "${t}" "${runs}" 1 \
      >"${work}/ort_t${t}_r${round}.json"
  done
done

"${python}" - "${work}" "${threads_list}" <<'PY'
import glob, json, statistics, sys
work, threads = sys.argv[1], [int(t) for t in sys.argv[2].split(',')]
print(f"{'threads':>7} {'sfrt ms':>10} {'ORT ms':>10} {'sfrt/ORT':>9} {'sfrt GFLOP/s':>13}"
      f" {'ORT GFLOP/s':>12} {'sfrt MiB':>9} {'ORT MiB':>8} {'spread':>12}")
for t in threads:
    s = [json.load(open(f)) for f in sorted(glob.glob(f"{work}/sfrt_t{t}_r*.json"))]
    o = [json.loads(open(f).read().strip().splitlines()[-1])
         for f in sorted(glob.glob(f"{work}/ort_t{t}_r*.json"))]
    macs = s[0]["macs"]
    s_ms = [r["median_ms"] for j in s for r in j["results"]]
    o_ms = [j["median_ms"] for j in o]
    sm, om = statistics.median(s_ms), statistics.median(o_ms)
    # Per-round ratios show how noisy the machine was.
    ratios = [a["results"][0]["median_ms"] / b["median_ms"] for a, b in zip(s, o)]
    print(f"{t:>7} {sm:>10.1f} {om:>10.1f} {sm / om:>9.3f} {2 * macs / sm / 1e6:>13.1f}"
          f" {2 * macs / om / 1e6:>12.1f} {max(j['peak_rss_mib'] for j in s):>9.1f}"
          f" {max(j['peak_rss_mib'] for j in o):>8.1f}"
          f" {min(ratios):>5.3f}-{max(ratios):.3f}")
print("sfrt/ORT: ratio of medians over all rounds; spread: lowest-highest per-round ratio;"
      " MiB: peak resident memory of one process (one session).")
PY
