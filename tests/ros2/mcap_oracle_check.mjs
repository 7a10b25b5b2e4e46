// Cross-check of sfrt's MCAP reader and writer (ros2/src/mcap.h) against @mcap/core, the MCAP
// authors' TypeScript implementation, in both directions:
//   A. @mcap/core's McapWriter writes recordings (chunked zstd, chunked lz4, chunked
//      uncompressed, unchunked, chunked without any summary); `mcap_tool dump` (sfrt's Reader)
//      must list exactly the messages, schemas, channels and statistics that were written, in
//      order, with and without a channel filter.
//   B. `mcap_tool write` (sfrt's Writer) writes the same recordings (zstd, lz4, uncompressed,
//      big chunks, unchunked); @mcap/core's McapIndexedReader (summary, chunk and message
//      indexes, summary and chunk CRCs) and McapStreamReader (every record in order, chunk
//      CRCs) must read back every message, and the DataEnd CRC must match the file.
// The recordings look like rosbag2's: profile "ros2", ros2msg schemas, cdr channels with
// offered_qos_profiles metadata, messages of 0 bytes to 150 KB (patterned and random), times
// above 2^53, log times with small inversions, and a "rosbag2" Metadata record.
//
// Usage: NODE_PATH=<npm ci of tests/npm>/node_modules \
//          node tests/ros2/mcap_oracle_check.mjs --tool <mcap_tool> --work <scratch dir> [--seed N]
// Exit status 0 when everything matches; 1, with every mismatch listed, otherwise.
import { execFileSync } from "node:child_process";
import fs from "node:fs";
import { createRequire } from "node:module";
import path from "node:path";

// ESM imports ignore NODE_PATH; require() honours it.
const require = createRequire(import.meta.url);
let McapWriter, McapIndexedReader, McapStreamReader, zstd, lz4Decompress;
try {
  ({ McapWriter, McapIndexedReader, McapStreamReader } = require("@mcap/core"));
  zstd = require("@foxglove/wasm-zstd");
  lz4Decompress = require("@foxglove/wasm-lz4");
} catch (error) {
  console.error(`mcap_oracle_check: cannot load the oracle packages (${error.message}).\n` +
    "Install tests/npm (npm ci) and point NODE_PATH at its node_modules.");
  process.exit(1);
}

// ---------------------------------------------------------------- arguments, reporting

function parseArgs(argv) {
  const args = { seed: 20240601 };
  for (let i = 0; i < argv.length; i += 2) {
    const key = argv[i].replace(/^--/, "");
    if (!["tool", "work", "seed"].includes(key) || argv[i + 1] === undefined) {
      console.error("usage: mcap_oracle_check.mjs --tool MCAP_TOOL --work DIR [--seed N]");
      process.exit(2);
    }
    args[key] = key === "seed" ? Number(argv[i + 1]) : argv[i + 1];
  }
  if (!args.tool || !args.work) {
    console.error("usage: mcap_oracle_check.mjs --tool MCAP_TOOL --work DIR [--seed N]");
    process.exit(2);
  }
  return args;
}

const failures = [];
let checks = 0;
function check(condition, what) {
  ++checks;
  if (!condition) failures.push(what);
  return condition;
}
function checkEqual(got, want, what) {
  if (Array.isArray(got) && Array.isArray(want) && got.length > 8) {
    const at = got.findIndex((g, i) => g !== want[i]);
    const first = at < 0 ? Math.min(got.length, want.length) : at;
    return check(got.length === want.length && at < 0, `${what}: ${got.length} items, want ` +
      `${want.length}; first difference at ${first}: got ${String(got[first]).slice(0, 120)}, ` +
      `want ${String(want[first]).slice(0, 120)}`);
  }
  const g = typeof got === "bigint" ? got.toString() : JSON.stringify(got);
  const w = typeof want === "bigint" ? want.toString() : JSON.stringify(want);
  return check(g === w, `${what}: got ${g.slice(0, 200)}, want ${w.slice(0, 200)}`);
}

// ---------------------------------------------------------------- recordings

// mulberry32: a small deterministic generator, so a failure reproduces with its --seed.
function makeRandom(seed) {
  let a = seed >>> 0;
  return () => {
    a = (a + 0x6d2b79f5) >>> 0;
    let t = a;
    t = Math.imul(t ^ (t >>> 15), t | 1);
    t ^= t + Math.imul(t ^ (t >>> 7), t | 61);
    return ((t ^ (t >>> 14)) >>> 0) / 4294967296;
  };
}

const kImageMsg = "std_msgs/Header header\nuint32 height\nuint32 width\nstring encoding\n" +
  "uint8 is_bigendian\nuint32 step\nuint8[] data\n" + "=".repeat(80) +
  "\nMSG: std_msgs/Header\nbuiltin_interfaces/Time stamp\nstring frame_id\n" + "=".repeat(80) +
  "\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n";
const kCompressedImageMsg = "std_msgs/Header header\nstring format\nuint8[] data\n";
const kQos = "- history: 3\n  depth: 0\n  reliability: 1\n  durability: 2\n  deadline:\n" +
  "    sec: 9223372036\n    nsec: 854775807\n  liveliness: 1\n";

// What a recording holds; channels refer to schemas and messages to channels by index.
function makeRecording(seed, count) {
  const random = makeRandom(seed);
  const encoder = new TextEncoder();
  const schemas = [
    { name: "sensor_msgs/msg/Image", encoding: "ros2msg", data: encoder.encode(kImageMsg) },
    { name: "sensor_msgs/msg/CompressedImage", encoding: "ros2msg",
      data: encoder.encode(kCompressedImageMsg) },
  ];
  const channels = [
    { schema: 0, topic: "/stereo/left/image_raw", messageEncoding: "cdr",
      metadata: new Map([["offered_qos_profiles", kQos], ["topic_type_hash", "RIHS01_ab"]]) },
    { schema: 1, topic: "/stereo/left/image_raw/compressed", messageEncoding: "cdr",
      metadata: new Map([["offered_qos_profiles", kQos]]) },
    { schema: 0, topic: "/stereo/right/image_raw", messageEncoding: "cdr", metadata: new Map() },
  ];
  const messages = [];
  const sequences = [0xfffffff0, 0, 7];
  const base = 1_717_000_000_123_456_789n;  // above 2^53: must survive as an integer
  for (let i = 0; i < count; ++i) {
    const channel = Math.floor(random() * channels.length);
    const size = i % 23 === 0 ? 0 : i % 9 === 0 ? Math.floor(random() * 150_000)
      : Math.floor(random() * 3000);
    const data = new Uint8Array(size);
    const patterned = random() < 0.7;
    for (let k = 0; k < size; ++k) {
      data[k] = patterned ? (k >> 4) * 31 + (k & 3) : Math.floor(random() * 256);
    }
    const logTime = base + BigInt(i) * 1_000_000n + BigInt(Math.floor(random() * 3_000_000));
    messages.push({ channel, sequence: sequences[channel]++ >>> 0, logTime,
      publishTime: logTime - BigInt(Math.floor(random() * 1000)), data });
    sequences[channel] >>>= 0;
  }
  const metadata = { name: "rosbag2",
    metadata: new Map([["serialized_metadata", "rosbag2_bagfile_information:\n  version: 9\n"]]) };
  return { schemas, channels, messages, metadata };
}

const hex = (bytes) => Buffer.from(bytes).toString("hex");

// ---------------------------------------------------------------- codecs and CRC

const kCrcTable = (() => {
  const table = new Uint32Array(256);
  for (let i = 0; i < 256; ++i) {
    let c = i;
    for (let k = 0; k < 8; ++k) c = c & 1 ? (c >>> 1) ^ 0xedb88320 : c >>> 1;
    table[i] = c >>> 0;
  }
  return table;
})();
function crc32(bytes) {
  let c = 0xffffffff;
  for (const b of bytes) c = kCrcTable[(c ^ b) & 0xff] ^ (c >>> 8);
  return (c ^ 0xffffffff) >>> 0;
}

// XXH32, for the LZ4 frame's header and content checksums.
function xxh32(bytes, seed = 0) {
  const P1 = 2654435761, P2 = 2246822519, P3 = 3266489917, P4 = 668265263, P5 = 374761393;
  const rotl = (x, r) => ((x << r) | (x >>> (32 - r))) >>> 0;
  const u32 = (p) =>
    (bytes[p] | (bytes[p + 1] << 8) | (bytes[p + 2] << 16) | (bytes[p + 3] << 24)) >>> 0;
  const round = (acc, lane) => Math.imul(rotl((acc + Math.imul(lane, P2)) >>> 0, 13), P1) >>> 0;
  const n = bytes.length;
  let p = 0, h;
  if (n >= 16) {
    let v1 = (seed + P1 + P2) >>> 0, v2 = (seed + P2) >>> 0;
    let v3 = seed >>> 0, v4 = (seed - P1) >>> 0;
    for (; p + 16 <= n; p += 16) {
      v1 = round(v1, u32(p)); v2 = round(v2, u32(p + 4));
      v3 = round(v3, u32(p + 8)); v4 = round(v4, u32(p + 12));
    }
    h = (rotl(v1, 1) + rotl(v2, 7) + rotl(v3, 12) + rotl(v4, 18)) >>> 0;
  } else {
    h = (seed + P5) >>> 0;
  }
  h = (h + n) >>> 0;
  for (; p + 4 <= n; p += 4) h = Math.imul(rotl((h + Math.imul(u32(p), P3)) >>> 0, 17), P4) >>> 0;
  for (; p < n; ++p) h = Math.imul(rotl((h + Math.imul(bytes[p], P5)) >>> 0, 11), P1) >>> 0;
  h = Math.imul(h ^ (h >>> 15), P2) >>> 0;
  h = Math.imul(h ^ (h >>> 13), P3) >>> 0;
  return (h ^ (h >>> 16)) >>> 0;
}

// One LZ4 block, greedy matching (the wasm package only decompresses, so the oracle brings its
// own compressor; every frame it makes is checked with the wasm decompressor before use).
function lz4Block(src) {
  const out = [];
  const length = (n) => { for (; n >= 255; n -= 255) out.push(255); out.push(n); };
  const emit = (anchor, end, offset, matchLength) => {
    const literals = end - anchor;
    const m = matchLength === 0 ? 0 : matchLength - 4;
    out.push((Math.min(literals, 15) << 4) | Math.min(m, 15));
    if (literals >= 15) length(literals - 15);
    for (let k = anchor; k < end; ++k) out.push(src[k]);
    if (matchLength === 0) return;
    out.push(offset & 0xff, offset >> 8);
    if (m >= 15) length(m - 15);
  };
  const table = new Int32Array(1 << 16).fill(-1);
  const word = (p) => (src[p] | (src[p + 1] << 8) | (src[p + 2] << 16) | (src[p + 3] << 24)) >>> 0;
  let anchor = 0;
  // A match starts at least 12 bytes before the end and ends at least 5 before it (spec).
  for (let i = 0; i + 12 <= src.length;) {
    const h = Math.imul(word(i), 2654435761) >>> 16;
    const ref = table[h];
    table[h] = i;
    if (ref >= 0 && i - ref <= 65535 && word(ref) === word(i)) {
      let matchLength = 4;
      while (i + matchLength < src.length - 5 && src[ref + matchLength] === src[i + matchLength]) {
        ++matchLength;
      }
      emit(anchor, i, i - ref, matchLength);
      i += matchLength;
      anchor = i;
    } else {
      ++i;
    }
  }
  emit(anchor, src.length, 0, 0);
  return Uint8Array.from(out);
}

// An LZ4 frame: 64 KiB independent blocks (stored raw when they do not shrink), content checksum.
function lz4Frame(data) {
  const parts = [];
  const u32 = (v) => { const b = Buffer.alloc(4); b.writeUInt32LE(v >>> 0); return b; };
  const descriptor = Uint8Array.from([0x64, 0x40]);  // version 01, independent, checksum; 64 KiB
  parts.push(u32(0x184d2204), descriptor, Uint8Array.from([(xxh32(descriptor) >>> 8) & 0xff]));
  for (let at = 0; at < data.length; at += 65536) {
    const block = data.subarray(at, Math.min(at + 65536, data.length));
    const packed = lz4Block(block);
    if (packed.length < block.length) parts.push(u32(packed.length), packed);
    else parts.push(u32(0x80000000 | block.length), block);
  }
  parts.push(u32(0), u32(xxh32(data)));
  const frame = Buffer.concat(parts);
  const back = lz4Decompress(frame, data.length);
  if (Buffer.compare(Buffer.from(back), Buffer.from(data)) !== 0) {
    throw new Error("the oracle's own LZ4 encoder produced a frame that does not round-trip");
  }
  return frame;
}

const decompressHandlers = {
  zstd: (buffer, size) => zstd.decompress(buffer, Number(size)),
  lz4: (buffer, size) => lz4Decompress(buffer, Number(size)),
};

// ---------------------------------------------------------------- A: @mcap/core writes

class MemoryWritable {
  #parts = [];
  #position = 0n;
  async write(buffer) {
    this.#parts.push(Buffer.from(buffer));  // copied: the writer reuses its buffer
    this.#position += BigInt(buffer.byteLength);
  }
  position() { return this.#position; }
  bytes() { return Buffer.concat(this.#parts); }
}

async function writeWithMcapCore(recording, variant) {
  const writable = new MemoryWritable();
  const noSummary = variant.summary === false;
  const writer = new McapWriter({
    writable, useChunks: variant.chunked, chunkSize: 65536,
    compressChunk: variant.compress, useStatistics: !noSummary, useSummaryOffsets: !noSummary,
    repeatSchemas: !noSummary, repeatChannels: !noSummary, useChunkIndex: !noSummary,
    useMetadataIndex: !noSummary, useAttachmentIndex: !noSummary,
  });
  await writer.start({ profile: "ros2", library: "@mcap/core oracle" });
  const schemaIds = [];
  for (const s of recording.schemas) schemaIds.push(await writer.registerSchema(s));
  const channelIds = [];
  for (const c of recording.channels) {
    channelIds.push(await writer.registerChannel({ schemaId: schemaIds[c.schema], topic: c.topic,
      messageEncoding: c.messageEncoding, metadata: c.metadata }));
  }
  const half = Math.floor(recording.messages.length / 2);
  for (const [i, m] of recording.messages.entries()) {
    if (i === half) await writer.addMetadata(recording.metadata);
    await writer.addMessage({ channelId: channelIds[m.channel], sequence: m.sequence,
      logTime: m.logTime, publishTime: m.publishTime, data: m.data });
  }
  await writer.end();
  return { bytes: writable.bytes(), schemaIds, channelIds, statistics: writer.statistics };
}

function dump(tool, file, channelIds) {
  const args = ["dump", file];
  if (channelIds) args.push(channelIds.join(","));
  let output;
  try {
    output = execFileSync(tool, args, { maxBuffer: 1 << 30, encoding: "utf8" });
  } catch (error) {
    return { error: `${error.message}\n${error.stdout ?? ""}`.slice(0, 2000) };
  }
  const lines = output.trim().split("\n").map((line) => JSON.parse(line));
  return { lines, byType: (type) => lines.filter((l) => l.type === type) };
}

function compareDumpedMessages(got, want, channelIds, what) {
  if (!checkEqual(got.length, want.length, `${what}: message count`)) return;
  want.forEach((m, i) => {
    const g = got[i];
    check(g.channel_id === channelIds[m.channel] && g.sequence === m.sequence &&
      g.log_time === m.logTime.toString() && g.publish_time === m.publishTime.toString() &&
      g.data === hex(m.data),
    `${what}: message ${i} differs (channel ${g.channel_id}, sequence ${g.sequence}, ` +
      `log_time ${g.log_time}, ${g.data.length / 2} bytes)`);
  });
}

function compareDumpedSummary(result, recording, written, variant, what) {
  const header = result.byType("header")[0];
  checkEqual([header.profile, header.library], ["ros2", "@mcap/core oracle"], `${what}: header`);
  const schemas = result.byType("schema");
  checkEqual(schemas.length, recording.schemas.length, `${what}: schema count`);
  recording.schemas.forEach((s, i) => {
    const g = schemas.find((x) => x.id === written.schemaIds[i]);
    check(g && g.name === s.name && g.encoding === s.encoding && g.data === hex(s.data),
      `${what}: schema ${written.schemaIds[i]} differs`);
  });
  const channels = result.byType("channel");
  checkEqual(channels.length, recording.channels.length, `${what}: channel count`);
  recording.channels.forEach((c, i) => {
    const g = channels.find((x) => x.id === written.channelIds[i]);
    check(g && g.topic === c.topic && g.message_encoding === c.messageEncoding &&
      g.schema_id === written.schemaIds[c.schema] &&
      JSON.stringify(g.metadata) === JSON.stringify(Object.fromEntries([...c.metadata].sort())),
    `${what}: channel ${written.channelIds[i]} differs: ${JSON.stringify(g)}`);
  });
  const statistics = result.byType("statistics");
  if (variant.summary === false) {
    checkEqual(statistics.length, 0, `${what}: no Statistics without a summary`);
    return;
  }
  const want = written.statistics;
  const g = statistics[0] ?? {};
  checkEqual([g.message_count, g.schema_count, g.channel_count, g.metadata_count, g.chunk_count,
    g.message_start_time, g.message_end_time],
  [want.messageCount.toString(), want.schemaCount, want.channelCount, want.metadataCount,
    want.chunkCount, want.messageStartTime.toString(), want.messageEndTime.toString()],
  `${what}: statistics`);
  const counts = Object.fromEntries(
    [...want.channelMessageCounts].map(([k, v]) => [k, v.toString()]));
  checkEqual(g.channel_message_counts, counts, `${what}: channel_message_counts`);
}

async function checkReadsMcapCoreFiles(args, recording) {
  const variants = [
    { name: "chunked-zstd", chunked: true,
      compress: (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) }) },
    { name: "chunked-lz4", chunked: true,
      compress: (data) => ({ compression: "lz4", compressedData: lz4Frame(data) }) },
    { name: "chunked-uncompressed", chunked: true },
    { name: "unchunked", chunked: false },
    { name: "chunked-zstd-no-summary", chunked: true, summary: false,
      compress: (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 1) }) },
  ];
  for (const variant of variants) {
    const what = `A/${variant.name}`;
    const written = await writeWithMcapCore(recording, variant);
    const file = path.join(args.work, `mcapcore-${variant.name}.mcap`);
    fs.writeFileSync(file, written.bytes);
    const result = dump(args.tool, file);
    if (!check(!result.error, `${what}: sfrt's reader failed: ${result.error}`)) continue;
    compareDumpedMessages(result.byType("message"), recording.messages, written.channelIds, what);
    compareDumpedSummary(result, recording, written, variant, what);
    const picked = [written.channelIds[0], written.channelIds[2]];
    const filtered = dump(args.tool, file, picked);
    if (!check(!filtered.error, `${what}: filtered read failed: ${filtered.error}`)) continue;
    compareDumpedMessages(filtered.byType("message"),
      recording.messages.filter((m) => m.channel !== 1), written.channelIds, `${what} filtered`);
    console.log(`${what}: ${written.bytes.length} bytes read by sfrt`);
  }
}

// ---------------------------------------------------------------- B: sfrt writes

function specLine(fields) {
  return fields.map((f) => (typeof f === "string" ? f : f.length === 0 ? "-" : hex(f))).join(" ");
}
const text = (s) => new TextEncoder().encode(s);
const mapFields = (map) => [String(map.size), ...[...map].flatMap(([k, v]) => [text(k), text(v)])];

function writeSpec(recording, variant) {
  const lines = [specLine(["options", text(variant.compression), String(variant.chunkSize), "1",
    text("ros2"), text("sfrt oracle")])];
  recording.schemas.forEach((s, i) =>
    lines.push(specLine(["schema", String(i + 1), text(s.name), text(s.encoding), s.data])));
  recording.channels.forEach((c, i) => lines.push(specLine(["channel", String(i + 1),
    String(c.schema + 1), text(c.topic), text(c.messageEncoding), ...mapFields(c.metadata)])));
  const half = Math.floor(recording.messages.length / 2);
  recording.messages.forEach((m, i) => {
    if (i === half) {
      lines.push(specLine(["metadata", text(recording.metadata.name),
        ...mapFields(recording.metadata.metadata)]));
    }
    lines.push(specLine(["message", String(m.channel + 1), String(m.sequence),
      m.logTime.toString(), m.publishTime.toString(), m.data]));
  });
  return lines.join("\n") + "\n";
}

const messageKey = (channelId, sequence, logTime, publishTime, data) =>
  `${logTime}|${channelId}|${sequence}|${publishTime}|${hex(data)}`;
const expectedKeys = (messages) =>
  messages.map((m) => messageKey(m.channel + 1, m.sequence, m.logTime, m.publishTime, m.data));

async function checkIndexedReader(bytes, recording, variant, what) {
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  checkEqual([reader.header.profile, reader.header.library], ["ros2", "sfrt oracle"],
    `${what}: header`);
  check(reader.footer.summaryCrc !== 0, `${what}: the Footer carries a summary CRC`);
  recording.schemas.forEach((s, i) => {
    const g = reader.schemasById.get(i + 1);
    check(g && g.name === s.name && g.encoding === s.encoding && hex(g.data) === hex(s.data),
      `${what}: summary schema ${i + 1}`);
  });
  recording.channels.forEach((c, i) => {
    const g = reader.channelsById.get(i + 1);
    check(g && g.topic === c.topic && g.schemaId === c.schema + 1 &&
      JSON.stringify([...g.metadata].sort()) === JSON.stringify([...c.metadata].sort()),
    `${what}: summary channel ${i + 1}`);
  });
  const s = reader.statistics;
  const chunks = variant.chunkSize === 0 ? 0 : reader.chunkIndexes.length;
  const times = recording.messages.map((m) => m.logTime);
  const min = times.reduce((a, b) => (b < a ? b : a));
  const max = times.reduce((a, b) => (b > a ? b : a));
  checkEqual([s.messageCount, s.schemaCount, s.channelCount, s.metadataCount, s.chunkCount,
    s.messageStartTime, s.messageEndTime].map(String),
  [recording.messages.length, 2, 3, 1, chunks, min, max].map(String), `${what}: statistics`);
  recording.channels.forEach((c, i) => checkEqual(String(s.channelMessageCounts.get(i + 1)),
    String(recording.messages.filter((m) => m.channel === i).length), `${what}: count ${i + 1}`));
  if (variant.chunkSize !== 0) {
    check(reader.chunkIndexes.some((ci) => ci.compression === variant.compression),
      `${what}: some chunk compressed with "${variant.compression}"`);
  }
  const metadata = [];
  for await (const m of reader.readMetadata({ name: "rosbag2" })) metadata.push(m);
  check(metadata.length === 1 &&
    metadata[0].metadata.get("serialized_metadata") ===
      recording.metadata.metadata.get("serialized_metadata"), `${what}: rosbag2 metadata`);
  if (variant.chunkSize === 0) return;  // the indexed reader only reads chunked messages
  const keys = [];
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    keys.push(messageKey(m.channelId, m.sequence, m.logTime, m.publishTime, m.data));
  }
  checkEqual(keys.sort(), expectedKeys(recording.messages).sort(), `${what}: indexed messages`);
  const topic = recording.channels[1].topic, picked = [];
  for await (const m of reader.readMessages({ topics: [topic], validateCrcs: true })) {
    picked.push(messageKey(m.channelId, m.sequence, m.logTime, m.publishTime, m.data));
  }
  checkEqual(picked.sort(), expectedKeys(recording.messages.filter((m) => m.channel === 1)).sort(),
    `${what}: indexed messages of ${topic}`);
}

function checkStreamReader(bytes, recording, what) {
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(bytes);
  const keys = [], types = [];
  let record, dataEnd;
  while ((record = reader.nextRecord())) {
    types.push(record.type);
    if (record.type === "Message") {
      keys.push(messageKey(record.channelId, record.sequence, record.logTime, record.publishTime,
        record.data));
    } else if (record.type === "DataEnd") {
      dataEnd = record;
    }
  }
  check(reader.done(), `${what}: the stream reader reached the end`);
  checkEqual(keys, expectedKeys(recording.messages), `${what}: streamed messages in file order`);
  check(types.includes("Statistics") && types.includes("SummaryOffset"),
    `${what}: summary records`);
  // The DataEnd CRC covers every byte before the DataEnd record (13 bytes, right before the
  // summary, whose start the Footer gives).
  const footer = bytes.length - 8 - 29;
  const dataEndOffset = Number(bytes.readBigUInt64LE(footer + 9)) - 13;
  check(dataEnd && dataEnd.dataSectionCrc !== 0 &&
    dataEnd.dataSectionCrc === crc32(bytes.subarray(0, dataEndOffset)),
  `${what}: data-section CRC`);
}

async function checkMcapCoreReadsSfrtFiles(args, recording) {
  const variants = [
    { name: "zstd", compression: "zstd", chunkSize: 65536 },
    { name: "lz4", compression: "lz4", chunkSize: 65536 },
    { name: "uncompressed", compression: "", chunkSize: 65536 },
    { name: "zstd-big-chunks", compression: "zstd", chunkSize: 4 << 20 },
    { name: "unchunked", compression: "zstd", chunkSize: 0 },
  ];
  for (const variant of variants) {
    const what = `B/${variant.name}`;
    const spec = path.join(args.work, `sfrt-${variant.name}.txt`);
    const file = path.join(args.work, `sfrt-${variant.name}.mcap`);
    fs.writeFileSync(spec, writeSpec(recording, variant));
    try {
      execFileSync(args.tool, ["write", file, spec], { stdio: ["ignore", "ignore", "pipe"] });
    } catch (error) {
      check(false, `${what}: sfrt's writer failed: ${error.stderr}`);
      continue;
    }
    const bytes = fs.readFileSync(file);
    try {
      await checkIndexedReader(bytes, recording, variant, what);
    } catch (error) {
      check(false, `${what}: McapIndexedReader refused the file: ${error.message}`);
    }
    try {
      checkStreamReader(bytes, recording, what);
    } catch (error) {
      check(false, `${what}: McapStreamReader refused the file: ${error.message}`);
    }
    console.log(`${what}: ${bytes.length} bytes read by @mcap/core`);
  }
}

// ---------------------------------------------------------------- main

const args = parseArgs(process.argv.slice(2));
fs.mkdirSync(args.work, { recursive: true });
await zstd.isLoaded;
await lz4Decompress.isLoaded;
const recording = makeRecording(args.seed, 600);
console.log(`seed ${args.seed}: ${recording.messages.length} messages, ` +
  `${recording.messages.reduce((n, m) => n + m.data.length, 0)} bytes of data`);
await checkReadsMcapCoreFiles(args, recording);
await checkMcapCoreReadsSfrtFiles(args, recording);
if (failures.length > 0) {
  console.error(`\n${failures.length} of ${checks} checks FAILED:`);
  for (const f of failures.slice(0, 40)) console.error(`  - ${f}`);
  process.exit(1);
}
console.log(`all ${checks} checks passed`);
