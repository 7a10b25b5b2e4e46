// Times an ONNX file with ONNX Runtime (npm onnxruntime-node, CPU execution provider) the way
// `sfrt bench` times a .sfrt: warm-up, then N runs, median / p90 / min, printed as one JSON line.
// Install once: cd tools/bench && ONNXRUNTIME_NODE_INSTALL=skip npm install
// Usage: node tools/bench/ort_bench.mjs [--profile=PREFIX] [--reference=FLOAT.onnx] [--seed=N]
//          MODEL.onnx HEIGHT WIDTH [THREADS=1] [RUNS=5] [WARMUP=1]
// The input is float32 NCHW (1, 12, H, W), seeded values in [0, 255): the generator
// seed = seed * 1103515245 + 12345 mod 2^32 from --seed (default 1), each value seed / 2^32 * 255,
// as torch_bench.py's lcg_input makes it.
// --profile: ORT's profiler on (enableProfiling; it slows the runs); the profile is written to
//   PREFIX_<date>.json and the JSON line gets "ops": per node type ran, the nodes and their
//   kernel time (ms, all runs), e.g. QLinearConv (int8) rather than Conv / FusedConv (float).
// --reference: also runs FLOAT.onnx once on the same input and adds "vs_reference": RMS(out -
//   ref) / RMS(ref) and max |out - ref| / max |ref| (e.g. a QDQ int8 model against its float one).
import fs from 'node:fs';
import { createRequire } from 'node:module';
import path from 'node:path';
import { performance } from 'node:perf_hooks';

const require = createRequire(import.meta.url);
const ort = require('onnxruntime-node');

const usage = 'usage: node ort_bench.mjs [--profile=PREFIX] [--reference=FLOAT.onnx] ' +
  '[--seed=N] MODEL.onnx HEIGHT WIDTH [THREADS] [RUNS] [WARMUP]';
const flags = {};
const positional = [];
for (const arg of process.argv.slice(2)) {
  const m = /^--(profile|reference|seed)=(.+)$/.exec(arg);
  if (m) flags[m[1]] = m[2];
  else if (arg.startsWith('--')) {
    console.error(`ort_bench.mjs: unknown option ${arg}\n${usage}`);
    process.exit(2);
  }
  else positional.push(arg);
}
const [model, h, w, threadsArg, runsArg, warmupArg] = positional;
if (!model || !h || !w) {
  console.error(usage);
  process.exit(2);
}
const height = Number(h), width = Number(w);
const threads = Number(threadsArg ?? 1), runs = Number(runsArg ?? 5), warmup = Number(warmupArg ?? 1);

const session = await ort.InferenceSession.create(model, {
  executionProviders: ['cpu'],
  intraOpNumThreads: threads,
  interOpNumThreads: 1,
  graphOptimizationLevel: 'all',
  ...(flags.profile ? { enableProfiling: true, profileFilePrefix: flags.profile } : {}),
});
const data = new Float32Array(12 * height * width);
const seedText = flags.seed ?? '1';
if (!/^[0-9]+$/.test(seedText) || Number(seedText) >= 2 ** 32) {
  console.error(`ort_bench.mjs: --seed must be an integer in [0, 2^32), got ${seedText}`);
  process.exit(2);
}
let seed = Number(seedText);
for (let i = 0; i < data.length; ++i) {
  // Math.imul: the product's low 32 bits exactly (a double product past 2^53 would lose them,
  // and the sequence would fall into a short cycle).
  seed = (Math.imul(seed, 1103515245) + 12345) >>> 0;
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
const extra = {};
if (flags.profile) {
  session.endProfiling();
  // The file is PREFIX_<date>.json; take the newest such file.
  const dir = path.dirname(path.resolve(flags.profile)), base = path.basename(flags.profile) + '_';
  const files = fs.readdirSync(dir).filter((f) => f.startsWith(base) && f.endsWith('.json'))
    .map((f) => path.join(dir, f)).sort((a, b) => fs.statSync(b).mtimeMs - fs.statSync(a).mtimeMs);
  if (files.length === 0) {
    console.error(`ort_bench.mjs: no profile ${flags.profile}_*.json was written`);
    process.exit(1);
  }
  const ops = {};
  for (const e of JSON.parse(fs.readFileSync(files[0], 'utf8'))) {
    if (e.cat !== 'Node' || !e.name.endsWith('_kernel_time') || !e.args?.op_name) continue;
    const o = (ops[e.args.op_name] ??= { nodes: new Set(), ms: 0 });
    o.nodes.add(e.name);
    o.ms += e.dur / 1000;
  }
  extra.profile = files[0];
  extra.ops = Object.fromEntries(
    Object.entries(ops).map(([k, v]) => [k, { nodes: v.nodes.size, ms: v.ms }]));
}
if (flags.reference) {
  const out = (await session.run(feeds))[session.outputNames[0]].data;
  const refSession = await ort.InferenceSession.create(flags.reference, {
    executionProviders: ['cpu'], intraOpNumThreads: threads, interOpNumThreads: 1,
  });
  const ref = (await refSession.run({ [refSession.inputNames[0]]: feeds[session.inputNames[0]] }))[
    refSession.outputNames[0]].data;
  if (ref.length !== out.length) {
    console.error(`ort_bench.mjs: output sizes differ: ${out.length} vs reference ${ref.length}`);
    process.exit(1);
  }
  let se = 0, sr = 0, me = 0, mr = 0;
  for (let i = 0; i < ref.length; ++i) {
    const d = out[i] - ref[i];
    se += d * d; sr += ref[i] * ref[i];
    me = Math.max(me, Math.abs(d)); mr = Math.max(mr, Math.abs(ref[i]));
  }
  extra.vs_reference = { model: flags.reference, rms_rel: Math.sqrt(se / sr), max_rel: me / mr };
}
ms.sort((a, b) => a - b);
const pct = (q) => {
  const pos = q * (ms.length - 1), lo = Math.floor(pos), hi = Math.min(lo + 1, ms.length - 1);
  return ms[lo] + (ms[hi] - ms[lo]) * (pos - lo);
};
console.log(JSON.stringify({
  peer: 'onnxruntime-node', version: ort.env.versions?.common ?? 'unknown', model, height, width,
  threads, runs, median_ms: pct(0.5), p90_ms: pct(0.9), min_ms: ms[0],
  peak_rss_mib: process.resourceUsage().maxRSS / 1024, ...extra,
}));
