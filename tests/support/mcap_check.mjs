// mcap_check.mjs FILE.mcap: reads an MCAP file with independent readers from npm and prints what
// it found as JSON, for tests/recorder/mcap_export_test.cpp to compare with the recording:
//   @mcap/core McapIndexedReader   footer, summary, chunk indexes, message indexes, chunk CRCs
//   @mcap/core McapStreamReader    every record from the magic to the magic, chunk CRCs
//   @foxglove/rosmsg               parses every schema (ros2msg) into definitions
//   @foxglove/rosmsg2-serialization decodes every message with its schema (CDR), no trailing bytes
// fzstd (pure JS) decompresses the zstd chunks. Run from the folder where these are installed
// (the test copies this file there). Image data is summarised by its FNV-1a 32-bit hash.
import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { decompress } from "fzstd";
import { open, readFile } from "node:fs/promises";

const file = process.argv[2];
const decompressHandlers = {
  zstd: (buffer, decompressedSize) => {
    const out = decompress(buffer);
    if (BigInt(out.length) !== decompressedSize) throw new Error(`zstd: ${out.length} bytes, expected ${decompressedSize}`);
    return out;
  },
};

function fnv1a(bytes) {
  let h = 0x811c9dc5;
  for (let i = 0; i < bytes.length; i++) h = Math.imul(h ^ bytes[i], 0x01000193) >>> 0;
  return h;
}

const ns = (t) => BigInt(t.sec) * 1000000000n + BigInt(t.nanosec);

// A message as JSON the C++ test reads: images by size, encoding and hash; the rest as decoded.
function summarise(type, msg) {
  const out = {};
  if (msg.header) {
    out.stamp_ns = ns(msg.header.stamp).toString();
    out.frame_id = msg.header.frame_id;
  }
  if (type === "sensor_msgs/msg/Image") {
    Object.assign(out, { width: msg.width, height: msg.height, encoding: msg.encoding, step: msg.step,
                         bytes: msg.data.length, fnv1a: fnv1a(msg.data) });
  } else if (type === "sensor_msgs/msg/CameraInfo") {
    Object.assign(out, { width: msg.width, height: msg.height, distortion_model: msg.distortion_model,
                         d: Array.from(msg.d), k: Array.from(msg.k), p: Array.from(msg.p) });
  } else if (type === "tf2_msgs/msg/TFMessage") {
    out.transforms = msg.transforms.map((t) => ({
      stamp_ns: ns(t.header.stamp).toString(), parent: t.header.frame_id, child: t.child_frame_id,
      t: [t.transform.translation.x, t.transform.translation.y, t.transform.translation.z],
      q: [t.transform.rotation.x, t.transform.rotation.y, t.transform.rotation.z, t.transform.rotation.w],
    }));
  } else if (type === "geometry_msgs/msg/PoseWithCovarianceStamped") {
    const p = msg.pose.pose;
    Object.assign(out, { t: [p.position.x, p.position.y, p.position.z],
                         q: [p.orientation.x, p.orientation.y, p.orientation.z, p.orientation.w],
                         covariance: Array.from(msg.pose.covariance) });
  } else {
    for (const [k, v] of Object.entries(msg)) {
      if (k === "header") continue;
      out[k] = typeof v === "bigint" ? v.toString() : v;
    }
  }
  return out;
}

const result = { file, ok: true, errors: [] };
try {
  // --- Indexed reading: footer, summary, chunk indexes, message indexes.
  const handle = await open(file, "r");
  const readable = {
    size: async () => BigInt((await handle.stat()).size),
    read: async (offset, size) => {
      const buf = new Uint8Array(Number(size));
      const { bytesRead } = await handle.read(buf, 0, Number(size), Number(offset));
      if (bytesRead !== Number(size)) throw new Error(`short read at ${offset}`);
      return buf;
    },
  };
  const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
  result.profile = indexed.header.profile;
  result.library = indexed.header.library;
  result.chunk_indexes = indexed.chunkIndexes.length;
  result.chunk_compression = [...new Set(indexed.chunkIndexes.map((c) => c.compression))];
  result.message_indexed_chunks = indexed.chunkIndexes.filter((c) => c.messageIndexOffsets.size > 0).length;
  result.summary_offset_opcodes = [...indexed.summaryOffsetsByOpcode.keys()].sort((a, b) => a - b);
  result.statistics = {
    message_count: indexed.statistics.messageCount.toString(),
    chunk_count: indexed.statistics.chunkCount,
    channel_count: indexed.statistics.channelCount,
    schema_count: indexed.statistics.schemaCount,
    metadata_count: indexed.statistics.metadataCount,
    start_ns: indexed.statistics.messageStartTime.toString(),
    end_ns: indexed.statistics.messageEndTime.toString(),
  };
  result.metadata = [];
  for await (const m of indexed.readMetadata()) result.metadata.push({ name: m.name, keys: [...m.metadata.keys()] });

  const readers = new Map();  // schema id -> MessageReader
  result.schemas = {};
  result.channels = {};
  for (const [id, ch] of indexed.channelsById) {
    const schema = indexed.schemasById.get(ch.schemaId);
    if (!readers.has(schema.id)) {
      const text = new TextDecoder().decode(schema.data);
      readers.set(schema.id, new MessageReader(parse(text, { ros2: true })));
      result.schemas[schema.name] = { encoding: schema.encoding, text };
    }
    result.channels[ch.topic] = { type: schema.name, message_encoding: ch.messageEncoding,
                                  qos: ch.metadata.get("offered_qos_profiles") ?? null };
    result.statistics[`count ${ch.topic}`] = (indexed.statistics.channelMessageCounts.get(id) ?? 0n).toString();
  }
  result.topics = {};
  const indexedList = [];
  for await (const m of indexed.readMessages({ validateCrcs: true })) {
    const ch = indexed.channelsById.get(m.channelId);
    const schema = indexed.schemasById.get(ch.schemaId);
    const reader = readers.get(schema.id);
    const msg = reader.readMessage(m.data);
    if (reader.lastReadHadTrailingBytes()) throw new Error(`${ch.topic}: trailing bytes after decoding`);
    const t = (result.topics[ch.topic] ??= { messages: [] });
    t.messages.push({ log_time: m.logTime.toString(), publish_time: m.publishTime.toString(), sequence: m.sequence,
                      ...summarise(schema.name, msg) });
    indexedList.push(`${m.channelId}:${m.logTime}:${fnv1a(m.data)}`);
  }
  await handle.close();

  // --- Streaming: every record from start to end, chunk CRCs checked.
  const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  stream.append(await readFile(file));
  const streamed = [];
  const records = {};
  for (let r; (r = stream.nextRecord()); ) {
    records[r.type] = (records[r.type] ?? 0) + 1;
    if (r.type === "Message") streamed.push(`${r.channelId}:${r.logTime}:${fnv1a(r.data)}`);
  }
  result.stream_done = stream.done();
  result.stream_records = records;
  // The indexed reader yields by log time; the stream in file order: the same set of messages.
  result.stream_matches_indexed = streamed.length === indexedList.length &&
                                   JSON.stringify([...streamed].sort()) === JSON.stringify([...indexedList].sort());
} catch (e) {
  result.ok = false;
  result.errors.push(String(e && e.stack ? e.stack : e));
}
process.stdout.write(JSON.stringify(result, (k, v) => (typeof v === "bigint" ? v.toString() : v)) + "\n");
// exitCode, not exit(): exit() would cut a long write to a pipe short (at 64 KiB or so).
process.exitCode = result.ok ? 0 : 1;
