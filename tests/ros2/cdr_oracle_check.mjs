// sfrt's ROS 2 CDR codec against an independent one: Foxglove's @foxglove/rosmsg2-serialization
// (MessageWriter / MessageReader), driven by message definitions that @foxglove/rosmsg parses
// from sfrt's own ros2msg definition texts (`cdr_tool definition TYPE`).
//
// For every type sfrt supports (`cdr_tool types`) and a set of values (all defaults, empty and
// odd-length strings and data, every field set, and seeded random ones):
//   1. sfrt's bytes (`cdr_tool encode`) EQUAL the oracle's bytes, byte for byte;
//   2. sfrt decodes the oracle's bytes to the same value (`cdr_tool decode`);
//   3. sfrt decodes them again with rmw_cyclonedds-style end padding to a multiple of 4;
//   4. the oracle decodes sfrt's bytes to the same value.
// Strings are ASCII: the oracle's CdrWriter sizes strings in UTF-16 code units, so it cannot be
// the reference for other text (messages_test.cc covers UTF-8).
//
// Usage: node cdr_oracle_check.mjs --tool PATH/cdr_tool --work DIR
// with NODE_PATH naming a node_modules that holds tests/npm/package.json's packages. Each case's
// two encodings are written under DIR (<type>.<case>.{sfrt,oracle}.cdr) for inspection.
// Exit status: 0 all equal; 1 any mismatch (each is listed); 2 usage or setup.
import { spawnSync } from "node:child_process";
import { mkdirSync, writeFileSync } from "node:fs";
import { createRequire } from "node:module";
import { join } from "node:path";

// ESM imports ignore NODE_PATH; CommonJS require honours it.
const require = createRequire(import.meta.url);

function die(message) {
  console.error(`cdr_oracle_check: ${message}`);
  process.exit(2);
}

function parseArgs(argv) {
  const args = {};
  for (let i = 0; i < argv.length; i += 2) {
    if (!["--tool", "--work"].includes(argv[i]) || argv[i + 1] === undefined) {
      die(`usage: node cdr_oracle_check.mjs --tool CDR_TOOL --work DIR (got ${argv.join(" ")})`);
    }
    args[argv[i].slice(2)] = argv[i + 1];
  }
  if (!args.tool || !args.work) die("both --tool and --work are required");
  return args;
}

function loadOracle() {
  try {
    const { parse } = require("@foxglove/rosmsg");
    const { MessageWriter, MessageReader } = require("@foxglove/rosmsg2-serialization");
    return { parse, MessageWriter, MessageReader };
  } catch (error) {
    die(`cannot load the oracle (${error.message}); set NODE_PATH to a node_modules holding ` +
        "tests/npm/package.json's packages (npm ci in a copy of tests/npm)");
  }
}

// Runs cdr_tool; returns stdout (a Buffer) or throws with its stderr.
function runTool(tool, args, input) {
  const result = spawnSync(tool, args, { input, maxBuffer: 1 << 26 });
  if (result.error) throw new Error(`cannot run ${tool}: ${result.error.message}`);
  if (result.status !== 0) {
    throw new Error(`cdr_tool ${args.join(" ")} exited ${result.status}: ` +
                    `${result.stderr.toString().trim()}`);
  }
  return result.stdout;
}

// ---------------------------------------------------------------------------------------------
// Values. A seeded generator, so a failure is reproducible.

function makeRandom(seed) {
  let state = seed >>> 0;
  const next = () => {  // xorshift32
    state ^= state << 13;
    state >>>= 0;
    state ^= state >>> 17;
    state ^= state << 5;
    state >>>= 0;
    return state;
  };
  return {
    u32: () => next(),
    i32: () => next() | 0,
    below: (n) => next() % n,
    bool: () => (next() & 1) === 1,
    // ASCII, length 0..max: every padding remainder after a string occurs.
    text: (max) => Array.from({ length: next() % (max + 1) },
                              () => String.fromCharCode(32 + (next() % 95))).join(""),
    bytes: (max) => Array.from({ length: next() % (max + 1) }, () => next() & 0xff),
    // Finite doubles over the whole exponent range (JSON has no NaN or infinity), and -0.
    f64: () => {
      if (next() % 16 === 0) return -0;
      const mantissa = (next() / 2 ** 32 - 0.5) * 2;
      return mantissa * 10 ** ((next() % 600) - 300);
    },
  };
}

const time = (r) => ({ sec: r.i32(), nanosec: r.u32() });
const header = (r) => ({ stamp: time(r), frame_id: r.text(9) });
const keyValue = (r) => ({ key: r.text(7), value: r.text(7) });
const roi = (r) => ({ x_offset: r.u32(), y_offset: r.u32(), height: r.u32(), width: r.u32(),
                      do_rectify: r.bool() });
const status = (r) => ({ level: r.below(256), name: r.text(9), message: r.text(9),
                         hardware_id: r.text(9),
                         values: Array.from({ length: r.below(4) }, () => keyValue(r)) });
const floats = (r, n) => Array.from({ length: n }, () => r.f64());

const RANDOM = {
  "builtin_interfaces/msg/Time": time,
  "std_msgs/msg/Header": header,
  "sensor_msgs/msg/Image": (r) => ({ header: header(r), height: r.u32(), width: r.u32(),
                                     encoding: r.text(9), is_bigendian: r.below(256),
                                     step: r.u32(), data: r.bytes(23) }),
  "sensor_msgs/msg/CompressedImage": (r) => ({ header: header(r), format: r.text(9),
                                               data: r.bytes(23) }),
  "sensor_msgs/msg/RegionOfInterest": roi,
  "sensor_msgs/msg/CameraInfo": (r) => ({ header: header(r), height: r.u32(), width: r.u32(),
                                          distortion_model: r.text(13),
                                          d: floats(r, r.below(9)), k: floats(r, 9),
                                          r: floats(r, 9), p: floats(r, 12),
                                          binning_x: r.u32(), binning_y: r.u32(), roi: roi(r) }),
  "diagnostic_msgs/msg/KeyValue": keyValue,
  "diagnostic_msgs/msg/DiagnosticStatus": status,
  "diagnostic_msgs/msg/DiagnosticArray": (r) => ({
    header: header(r), status: Array.from({ length: r.below(4) }, () => status(r)) }),
};

// Hand-picked values: all defaults (empty strings and sequences), and odd lengths.
const zeroTime = { sec: 0, nanosec: 0 };
const emptyHeader = { stamp: zeroTime, frame_id: "" };
const oddHeader = { stamp: { sec: -1, nanosec: 999999999 }, frame_id: "ab" };
const zeroRoi = { x_offset: 0, y_offset: 0, height: 0, width: 0, do_rectify: false };
const zeros = (n) => Array.from({ length: n }, () => 0);
const FIXED = {
  "builtin_interfaces/msg/Time": [["zero", zeroTime],
                                  ["extremes", { sec: -2147483648, nanosec: 4294967295 }]],
  "std_msgs/msg/Header": [["empty", emptyHeader], ["odd_frame_id", oddHeader]],
  "sensor_msgs/msg/Image": [
    ["empty", { header: emptyHeader, height: 0, width: 0, encoding: "", is_bigendian: 0,
                step: 0, data: [] }],
    ["odd", { header: oddHeader, height: 1, width: 5, encoding: "mono8", is_bigendian: 1,
              step: 5, data: [1, 2, 3, 4, 5] }],
  ],
  "sensor_msgs/msg/CompressedImage": [
    ["empty", { header: emptyHeader, format: "", data: [] }],
    ["odd", { header: oddHeader, format: "jpeg", data: [0xff, 0xd8, 0xff] }],
  ],
  "sensor_msgs/msg/RegionOfInterest": [["zero", zeroRoi],
                                       ["set", { x_offset: 1, y_offset: 2, height: 3,
                                                 width: 4, do_rectify: true }]],
  "sensor_msgs/msg/CameraInfo": [
    ["empty", { header: emptyHeader, height: 0, width: 0, distortion_model: "", d: [],
                k: zeros(9), r: zeros(9), p: zeros(12), binning_x: 0, binning_y: 0,
                roi: zeroRoi }],
    ["plumb_bob", { header: oddHeader, height: 480, width: 640, distortion_model: "plumb_bob",
                    d: [-0.28, 0.07, 0.0001, -0.00002, 0],
                    k: [525, 0, 319.5, 0, 525, 239.5, 0, 0, 1], r: [1, 0, 0, 0, 1, 0, 0, 0, 1],
                    p: [525, 0, 319.5, 0, 0, 525, 239.5, 0, 0, 0, 1, 0], binning_x: 1,
                    binning_y: 1, roi: zeroRoi }],
  ],
  "diagnostic_msgs/msg/KeyValue": [["empty", { key: "", value: "" }],
                                   ["odd", { key: "a", value: "abc" }]],
  "diagnostic_msgs/msg/DiagnosticStatus": [
    ["empty", { level: 0, name: "", message: "", hardware_id: "", values: [] }],
    ["stale", { level: 3, name: "n", message: "odd", hardware_id: "hw", values: [
      { key: "", value: "x" }] }],
  ],
  "diagnostic_msgs/msg/DiagnosticArray": [
    ["empty", { header: emptyHeader, status: [] }],
    ["two", { header: oddHeader, status: [
      { level: 1, name: "sfrt", message: "late", hardware_id: "", values: [] },
      { level: 2, name: "", message: "e", hardware_id: "gpu0",
        values: [{ key: "k", value: "" }, { key: "kk", value: "vvv" }] }] }],
  ],
};

const RANDOM_CASES_PER_TYPE = 8;

// ---------------------------------------------------------------------------------------------
// Comparison.

// Typed arrays to plain arrays, so values from JSON and from MessageReader compare.
function normalise(value) {
  if (ArrayBuffer.isView(value)) return Array.from(value);
  if (Array.isArray(value)) return value.map(normalise);
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, normalise(v)]));
  }
  return value;
}

// First difference between a and b (Object.is for numbers: -0 differs from 0), or null.
function difference(a, b, path = "") {
  if (Array.isArray(a) || Array.isArray(b)) {
    if (!Array.isArray(a) || !Array.isArray(b)) return `${path}: array vs non-array`;
    if (a.length !== b.length) return `${path}: length ${a.length} vs ${b.length}`;
    for (let i = 0; i < a.length; ++i) {
      const d = difference(a[i], b[i], `${path}[${i}]`);
      if (d) return d;
    }
    return null;
  }
  if (a !== null && typeof a === "object" && b !== null && typeof b === "object") {
    const keys = [...new Set([...Object.keys(a), ...Object.keys(b)])].sort();
    for (const key of keys) {
      const d = difference(a[key], b[key], path ? `${path}.${key}` : key);
      if (d) return d;
    }
    return null;
  }
  return Object.is(a, b) ? null
                         : `${path}: ${JSON.stringify(a)} vs ${JSON.stringify(b)}`;
}

// JSON.stringify writes -0 as 0; cdr_tool must get -0.0 to encode the sign bit the oracle does.
function toJson(value) {
  const marker = "\u0000negative zero\u0000";
  return JSON.stringify(value, (_, v) => (Object.is(v, -0) ? marker : v))
      .replaceAll(JSON.stringify(marker), "-0.0");
}

function firstByteDifference(a, b) {
  const n = Math.min(a.length, b.length);
  for (let i = 0; i < n; ++i) if (a[i] !== b[i]) return `byte ${i}: ${a[i]} vs ${b[i]}`;
  return `lengths ${a.length} vs ${b.length}`;
}

// ---------------------------------------------------------------------------------------------

function checkCase(context, type, name, value) {
  const { tool, work, writer, reader } = context;
  const failures = [];
  const label = `${type} ${name}`;
  const oracleBytes = Buffer.from(writer.writeMessage(value));
  const sfrtBytes = runTool(tool, ["encode", type], toJson(value));
  const stem = join(work, `${type.replaceAll("/", "_")}.${name}`);
  writeFileSync(`${stem}.oracle.cdr`, oracleBytes);
  writeFileSync(`${stem}.sfrt.cdr`, sfrtBytes);

  if (!sfrtBytes.equals(oracleBytes)) {
    failures.push(`${label}: sfrt's encoding differs from the oracle's ` +
                  `(${firstByteDifference(sfrtBytes, oracleBytes)}; see ${stem}.*.cdr)`);
  }
  const decoded = JSON.parse(runTool(tool, ["decode", type], oracleBytes).toString());
  const d1 = difference(decoded, normalise(value));
  if (d1) failures.push(`${label}: sfrt decodes the oracle's bytes differently (${d1})`);

  const padded = Buffer.concat([oracleBytes, Buffer.alloc((4 - (oracleBytes.length % 4)) % 4)]);
  const decodedPadded = JSON.parse(runTool(tool, ["decode", type], padded).toString());
  const d2 = difference(decodedPadded, normalise(value));
  if (d2) failures.push(`${label}: sfrt decodes the end-padded bytes differently (${d2})`);

  const back = normalise(reader.readMessage(new Uint8Array(sfrtBytes)));
  const d3 = difference(back, normalise(value));
  if (d3) failures.push(`${label}: the oracle decodes sfrt's bytes differently (${d3})`);
  return failures;
}

function checkType(context, type) {
  const definition = runTool(context.tool, ["definition", type]).toString();
  let parsed;
  try {
    parsed = context.oracle.parse(definition, { ros2: true });
  } catch (error) {
    return [`${type}: the oracle cannot parse sfrt's ros2msg definition: ${error.message}`];
  }
  const typeContext = { ...context, writer: new context.oracle.MessageWriter(parsed),
                        reader: new context.oracle.MessageReader(parsed) };
  const cases = [...(FIXED[type] ?? [])];
  const random = makeRandom(0x5f3759df ^ type.length * 2654435761);
  for (let i = 0; i < RANDOM_CASES_PER_TYPE; ++i) cases.push([`random${i}`, RANDOM[type](random)]);
  const failures = [];
  for (const [name, value] of cases) failures.push(...checkCase(typeContext, type, name, value));
  console.log(`${failures.length ? "FAIL" : "ok  "} ${type}: ${cases.length} values`);
  return failures;
}

function main() {
  const args = parseArgs(process.argv.slice(2));
  const oracle = loadOracle();
  mkdirSync(args.work, { recursive: true });
  const types = runTool(args.tool, ["types"]).toString().trim().split("\n")
                    .map((line) => line.split(" ")[0]);
  const missing = types.filter((type) => !RANDOM[type]);
  if (missing.length) die(`no test values for ${missing.join(", ")}: add them to this script`);
  const context = { tool: args.tool, work: args.work, oracle };
  const failures = types.flatMap((type) => checkType(context, type));
  if (failures.length) {
    console.error(`cdr_oracle_check: ${failures.length} mismatches:\n  ${failures.join("\n  ")}`);
    process.exit(1);
  }
  console.log(`cdr_oracle_check: ${types.length} types, sfrt and the oracle agree`);
}

try {
  main();
} catch (error) {
  console.error(`cdr_oracle_check: ${error.message}`);
  process.exit(1);
}
