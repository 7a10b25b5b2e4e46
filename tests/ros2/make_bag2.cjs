// Writes a rosbag2 MCAP bag with implementations sfrt did not write: @mcap/core (the format's
// authors' writer) and @foxglove/rosmsg2-serialization (a ROS 2 CDR codec), from a plan that
// make_bag2.py lays out. Also saves each message's CDR bytes, for the .db3 bags make_bag2.py
// builds from them.
//
// usage: node make_bag2.cjs PLAN.json OUT.mcap [--compression zstd|none] [--no-chunks]
//                                               [--payloads DIR]
// PLAN.json: {"messages": [{"topic", "type": "Image"|"CompressedImage", "stamp_ns" (string),
//   "frame_id", "encoding" (Image) | "format" (CompressedImage), "height", "width", "step",
//   "blob": path of the pixel or file bytes}, ...]} in the order to write them.
"use strict";
// CommonJS, so that NODE_PATH finds the oracles installed in the build tree (tests/npm).
const fs = require("node:fs");
const { McapWriter } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageWriter } = require("@foxglove/rosmsg2-serialization");
const zstd = require("@foxglove/wasm-zstd");

// The ROS 2 message definitions (ros2/common_interfaces, rcl_interfaces), as rosbag2 stores them:
// the type's own fields, then each dependency after a line of '=' and "MSG: <type>".
const SEPARATOR = "=".repeat(80);
const HEADER = `MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
${SEPARATOR}
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec`;
const DEFINITIONS = {
  Image: `std_msgs/Header header
uint32 height
uint32 width
string encoding
uint8 is_bigendian
uint32 step
uint8[] data
${SEPARATOR}
${HEADER}`,
  CompressedImage: `std_msgs/Header header
string format
uint8[] data
${SEPARATOR}
${HEADER}`,
};

function argument(name, fallback) {
  const i = process.argv.indexOf(name);
  return i >= 0 ? process.argv[i + 1] : fallback;
}

async function main() {
  const [planPath, outPath] = process.argv.slice(2, 4);
  if (!planPath || !outPath) throw new Error("usage: node make_bag2.cjs PLAN.json OUT.mcap ...");
  const plan = JSON.parse(fs.readFileSync(planPath, "utf8"));
  const compression = argument("--compression", "zstd");
  const payloads = argument("--payloads", null);
  await zstd.isLoaded;
  const chunks = [];
  const writer = new McapWriter({
    writable: { position: () => BigInt(chunks.reduce((n, c) => n + c.length, 0)),
                write: async (data) => { chunks.push(Buffer.from(data)); } },
    useChunks: !process.argv.includes("--no-chunks"),
    chunkSize: 64 * 1024,
    compressChunk: compression === "zstd"
      ? (data) => ({ compression: "zstd", compressedData: zstd.compress(data, 3) })
      : undefined,
  });
  await writer.start({ profile: "ros2", library: "make_bag2.cjs (@mcap/core)" });
  const schemas = {};
  const channels = {};
  const writers = {};
  for (const type of Object.keys(DEFINITIONS)) {
    writers[type] = new MessageWriter(parse(DEFINITIONS[type], { ros2: true }));
  }
  if (payloads) fs.mkdirSync(payloads, { recursive: true });
  const sequence = {};
  for (const [i, m] of plan.messages.entries()) {
    const fullType = `sensor_msgs/msg/${m.type}`;
    if (schemas[fullType] === undefined) {
      schemas[fullType] = await writer.registerSchema({
        name: fullType, encoding: "ros2msg",
        data: new TextEncoder().encode(DEFINITIONS[m.type]) });
    }
    if (channels[m.topic] === undefined) {
      channels[m.topic] = await writer.registerChannel({
        topic: m.topic, schemaId: schemas[fullType], messageEncoding: "cdr",
        metadata: new Map([["offered_qos_profiles", ""]]) });
      sequence[m.topic] = 0;
    }
    const stamp = BigInt(m.stamp_ns);
    const header = { stamp: { sec: Number(stamp / 1000000000n), nanosec: Number(stamp % 1000000000n) },
                     frame_id: m.frame_id };
    const data = new Uint8Array(fs.readFileSync(m.blob));
    const message = m.type === "Image"
      ? { header, height: m.height, width: m.width, encoding: m.encoding, is_bigendian: 0,
          step: m.step, data }
      : { header, format: m.format, data };
    const bytes = writers[m.type].writeMessage(message);
    if (payloads) fs.writeFileSync(`${payloads}/${i}.cdr`, bytes);
    await writer.addMessage({ channelId: channels[m.topic], sequence: sequence[m.topic]++,
                              logTime: stamp, publishTime: stamp, data: bytes });
  }
  await writer.end();
  fs.writeFileSync(outPath, Buffer.concat(chunks));
}

main().catch((e) => { console.error(`make_bag2.cjs: ${e.stack ?? e}`); process.exit(1); });
