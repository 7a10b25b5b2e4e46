"use strict";
// Reads an MCAP file with implementations sfrt did not write: @mcap/core's indexed reader (which
// needs a valid summary, chunk indexes and CRCs) and its stream reader (every record front to
// back), decoding each message with @foxglove/rosmsg2-serialization from the file's own ros2msg
// schemas. Prints one JSON object: the header's profile, the statistics, and per message its
// topic, schema, log time and decoded fields (byte arrays as base64).
//
// usage: node read_bag2.cjs FILE.mcap     (NODE_PATH: the oracles, tests/npm)
const fs = require("node:fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const { parse } = require("@foxglove/rosmsg");
const { MessageReader } = require("@foxglove/rosmsg2-serialization");
const zstd = require("@foxglove/wasm-zstd");
const lz4 = require("@foxglove/wasm-lz4");

function plain(value) {
  if (value instanceof Uint8Array) return { base64: Buffer.from(value).toString("base64") };
  if (typeof value === "bigint") return value.toString();
  if (Array.isArray(value)) return value.map(plain);
  if (value !== null && typeof value === "object") {
    return Object.fromEntries(Object.entries(value).map(([k, v]) => [k, plain(v)]));
  }
  return value;
}

async function main() {
  const path = process.argv[2];
  await zstd.isLoaded;
  await lz4.isLoaded;
  const decompressHandlers = {
    zstd: (data, size) => zstd.decompress(data, Number(size)),
    lz4: (data, size) => lz4(data, Number(size)),
  };
  const bytes = fs.readFileSync(path);
  const readable = {
    size: async () => BigInt(bytes.length),
    read: async (offset, size) => bytes.subarray(Number(offset), Number(offset + size)),
  };
  const reader = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  const decoders = new Map();
  const messages = [];
  for await (const m of reader.readMessages({ validateCrcs: true })) {
    const channel = reader.channelsById.get(m.channelId);
    const schema = reader.schemasById.get(channel.schemaId);
    if (!decoders.has(schema.id)) {
      const text = new TextDecoder().decode(schema.data);
      decoders.set(schema.id, new MessageReader(parse(text, { ros2: true })));
    }
    messages.push({ topic: channel.topic, schema: schema.name, schema_encoding: schema.encoding,
                    message_encoding: channel.messageEncoding, log_time: m.logTime.toString(),
                    publish_time: m.publishTime.toString(), sequence: m.sequence,
                    message: plain(decoders.get(schema.id).readMessage(m.data)) });
  }
  // The stream reader checks every record in order, the data section's CRC included.
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(bytes);
  let records = 0;
  for (let r; (r = stream.nextRecord()) !== undefined;) records++;
  if (!stream.done()) throw new Error("the stream reader did not reach the end of the file");
  console.log(JSON.stringify({ profile: reader.header.profile, library: reader.header.library,
                               statistics: plain(reader.statistics), records, messages }));
}

main().catch((e) => { console.error(`read_bag2.cjs: ${e.stack ?? e}`); process.exit(1); });
