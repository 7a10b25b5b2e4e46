// Times an ONNX file with ONNX Runtime (npm onnxruntime-node, CPU execution provider) the way
// `sfrt bench` times a .sfrt: warm-up, then N runs, median / p90 / min, printed as one JSON line.
// Install once: cd tools/bench && ONNXRUNTIME_NODE_INSTALL=skip npm install
// Usage: node tools/bench/ort_bench.mjs MODEL.onnx HEIGHT WIDTH [THREADS=1] [RUNS=5] [WARMUP=1]
// The input is float32 NCHW (1, 12, H, W), seeded values in [0, 255).
import { createRequire } from 'node:module';
import { performance } from 'node:perf_hooks';

const require = createRequire(import.meta.url);
const ort = require('onnxruntime-node');

const [model, h, w, threadsArg, runsArg, warmupArg] = process.argv.slice(2);
if (!model || !h || !w) {
  console.error('usage: node ort_bench.mjs MODEL.onnx HEIGHT WIDTH [THREADS] [RUNS] [WARMUP]');
  process.exit(2);
}
const height = Number(h), width = Number(w);
const threads = Number(threadsArg ?? 1), runs = Number(runsArg ?? 5), warmup = Number(warmupArg ?? 1);

const session = await ort.InferenceSession.create(model, {
  executionProviders: ['cpu'],
  intraOpNumThreads: threads,
  interOpNumThreads: 1,
  graphOptimizationLevel: 'all',
});
const data = new Float32Array(12 * height * width);
let seed = 1;
for (let i = 0; i < data.length; ++i) {
  seed = (seed * 1103515245 + 12345) >>> 0;
  data[i] = (seed / 4294967296) * 255;
}
const feeds = { [session.inputNames[0]]: new ort.Tensor('float32', data, [1, 12, height, width]) };
for (let i = 0; i < warmup; ++i) await session.run(feeds);
const ms = [];
for (let i = 0; i < runs; ++i) {
  const t0 = performance.now();
  await session.run(feeds);
  ms.push(performance.now() - t0);
}
ms.sort((a, b) => a - b);
const pct = (q) => {
  const pos = q * (ms.length - 1), lo = Math.floor(pos), hi = Math.min(lo + 1, ms.length - 1);
  return ms[lo] + (ms[hi] - ms[lo]) * (pos - lo);
};
console.log(JSON.stringify({
  peer: 'onnxruntime-node', version: ort.env.versions?.common ?? 'unknown', model, height, width,
  threads, runs, median_ms: pct(0.5), p90_ms: pct(0.9), min_ms: ms[0],
  peak_rss_mib: process.resourceUsage().maxRSS / 1024,
}));
