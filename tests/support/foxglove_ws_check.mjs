// foxglove_ws_check.mjs URL FRAMES [--topics T1,T2,...] [--no-hash] [--timeout-ms N]: a live-view
// client built from independent implementations, for tests/net/foxglove_server_test.cpp:
//   ws                              the WebSocket (RFC 6455) client
//   @foxglove/ws-protocol           FoxgloveClient: serverInfo, advertise, subscribe, Message Data
//   @foxglove/rosmsg                parses each advertised ros2msg schema
//   @foxglove/rosmsg2-serialization decodes every message (CDR) with its channel's schema
// It subscribes to every advertised channel (or those of --topics), decodes every message, and
// stops after FRAMES messages on /augrig/occlusion_stats and, those in, once each coded topic
// subscribed to (.../compressed, .../h264: coded on the server's own threads, behind the rest) has
// given a message, or 5 s later (0: when the server closes the connection; the timeout in either
// case). It prints one JSON
// object: serverInfo, the channels, the statuses, and each message summarised (images by size,
// encoding and FNV-1a hash, unless --no-hash; the rest as decoded). Run from the folder where the
// packages are installed (the test copies this file there). Exit 0 when done, 2 on timeout.
import wsProtocol from "@foxglove/ws-protocol";  // CommonJS: its exports come as the default
import { parse } from "@foxglove/rosmsg";
import { MessageReader } from "@foxglove/rosmsg2-serialization";
import { WebSocket } from "ws";

const { FoxgloveClient } = wsProtocol;
const [url, framesArg, ...rest] = process.argv.slice(2);
const frames = Number(framesArg ?? "1");
let topics = null;
let hash = true;
let timeoutMs = 60000;
for (let i = 0; i < rest.length; i++) {
  if (rest[i] === "--topics") topics = new Set(rest[++i].split(","));
  else if (rest[i] === "--no-hash") hash = false;
  else if (rest[i] === "--timeout-ms") timeoutMs = Number(rest[++i]);
}

function fnv1a(bytes) {
  let h = 0x811c9dc5;
  for (let i = 0; i < bytes.length; i++) h = Math.imul(h ^ bytes[i], 0x01000193) >>> 0;
  return h;
}

const ns = (t) => BigInt(t.sec) * 1000000000n + BigInt(t.nanosec);

function summarise(type, msg) {
  const out = {};
  if (msg.header) {
    out.stamp_ns = ns(msg.header.stamp).toString();
    out.frame_id = msg.header.frame_id;
  }
  if (type === "sensor_msgs/msg/Image") {
    Object.assign(out, { width: msg.width, height: msg.height, encoding: msg.encoding, step: msg.step,
                         bytes: msg.data.length });
    if (hash) out.fnv1a = fnv1a(msg.data);
  } else if (type === "sensor_msgs/msg/CompressedImage") {
    Object.assign(out, { format: msg.format, bytes: msg.data.length, soi: [msg.data[0], msg.data[1]] });
  } else if (type === "foxglove_msgs/msg/CompressedVideo") {
    // The NAL unit types after each Annex B start code (7 SPS, 8 PPS, 5 IDR slice, 1 other slice).
    const nal = [];
    for (let i = 0; i + 3 < msg.data.length; i++)
      if (msg.data[i] === 0 && msg.data[i + 1] === 0 && msg.data[i + 2] === 1) { nal.push(msg.data[i + 3] & 0x1f); i += 2; }
    Object.assign(out, { stamp_ns: ns(msg.timestamp).toString(), frame_id: msg.frame_id, format: msg.format,
                         bytes: msg.data.length, nal });
  } else if (type === "sensor_msgs/msg/CameraInfo") {
    Object.assign(out, { width: msg.width, height: msg.height, distortion_model: msg.distortion_model,
                         d: Array.from(msg.d), k: Array.from(msg.k) });
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
  } else if (type === "diagnostic_msgs/msg/DiagnosticArray") {
    out.status = msg.status.map((s) => ({ level: s.level, name: s.name, message: s.message,
                                          hardware_id: s.hardware_id,
                                          values: s.values.map((kv) => [kv.key, kv.value]) }));
  } else {
    for (const [k, v] of Object.entries(msg)) {
      if (k === "header") continue;
      if (typeof v === "bigint") out[k] = v.toString();
      else if (v && typeof v === "object")
        out[k] = Object.fromEntries(Object.entries(v).map(([a, b]) => [a, typeof b === "bigint" ? b.toString() : b]));
      else out[k] = v;
    }
  }
  return out;
}

const result = { serverInfo: null, channels: [], statuses: [], messages: [], errors: [], closed: null };
const bySub = new Map();
let statsSeen = 0;
let finished = false;

const client = new FoxgloveClient({ ws: new WebSocket(url, [FoxgloveClient.SUPPORTED_SUBPROTOCOL]) });

function finish(code) {
  if (finished) return;
  finished = true;
  clearTimeout(timer);
  result.timeout = code === 2;
  process.stdout.write(JSON.stringify(result) + "\n");
  process.exitCode = code;
  client.close();
}

const timer = setTimeout(() => finish(2), timeoutMs);

client.on("serverInfo", (info) => { result.serverInfo = info; });
client.on("status", (s) => { result.statuses.push(s); });
client.on("error", (e) => { result.errors.push(String(e?.message ?? e)); });
client.on("close", (e) => {
  result.closed = { code: e?.code ?? null, reason: String(e?.reason ?? "") };
  if (frames === 0) finish(0);
  else finish(finished ? 0 : 2);
});
client.on("advertise", (channels) => {
  for (const ch of channels) {
    let reader = null;
    let schemaError = null;
    try {
      reader = new MessageReader(parse(ch.schema, { ros2: true }));
    } catch (e) {
      schemaError = String(e.message ?? e);
    }
    result.channels.push({ id: ch.id, topic: ch.topic, encoding: ch.encoding, schemaName: ch.schemaName,
                           schemaEncoding: ch.schemaEncoding, schema: ch.schema, schemaError });
    if (topics && !topics.has(ch.topic)) continue;
    if (!reader) continue;
    const sub = client.subscribe(ch.id);
    bySub.set(sub, { ch, reader });
  }
});
client.on("message", ({ subscriptionId, timestamp, data }) => {
  const s = bySub.get(subscriptionId);
  if (!s) {
    result.errors.push(`a message for the unknown subscription ${subscriptionId}`);
    return;
  }
  const entry = { topic: s.ch.topic, subscription: subscriptionId, log_time_ns: timestamp.toString(),
                  bytes: data.byteLength };
  try {
    entry.msg = summarise(s.ch.schemaName, s.reader.readMessage(data));
  } catch (e) {
    entry.decodeError = String(e.message ?? e);
  }
  result.messages.push(entry);
  if (s.ch.topic === "/augrig/occlusion_stats" && frames > 0 && ++statsSeen === frames) {
    setTimeout(() => finish(0), 5000);  // the coded topics' grace
  }
  if (frames > 0 && statsSeen >= frames && codedTopicsHeard()) finish(0);
});

// Each subscribed coded topic (the newest frame is always coded in the end) has given a message.
function codedTopicsHeard() {
  const heard = new Set(result.messages.map((m) => m.topic));
  for (const { ch } of bySub.values())
    if (/\/(compressed|h264)$/.test(ch.topic) && !heard.has(ch.topic)) return false;
  return true;
}
