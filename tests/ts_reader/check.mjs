// Independent check of armstereo recordings with the TypeScript MCAP reader Foxglove uses.
//
// usage: node check.mjs [--allow-unindexed] FILE...
//
// Opens each file with @mcap/core's McapIndexedReader (zstd via fzstd, lz4 via lz4js), decodes
// every protobuf message with the FileDescriptorSet stored in its Schema record (protobufjs) and
// every JSON message, and checks: protobuf schemas are published foxglove.* types, JSON channels
// are armstereo's two JSON-Schema channels with their required keys, RawImage sizes,
// CompressedImage signatures, CameraCalibration array lengths, unit quaternions, PointCloud
// layout, message counts against the Statistics record, and the "armstereo" metadata record.
// A file without an index is read with McapStreamReader and counts as a problem unless
// --allow-unindexed is given (then only bytes after the last complete record are a problem). Exit status: 0 all good, 1 problems found, 2 usage error.

import { open } from "node:fs/promises";

import { McapIndexedReader, McapStreamReader } from "@mcap/core";
import { FileHandleReadable } from "@mcap/nodejs";
import { decompress as zstdDecompress } from "fzstd";
import lz4 from "lz4js";
import protobuf from "protobufjs";
import "protobufjs/ext/descriptor.js";

const JSON_SCHEMAS = new Set(["armstereo.JointStates", "armstereo.CaptureEvent"]);
const RAW_BYTES_PER_PIXEL = { "32FC1": 4, mono8: 1, mono16: 2, rgb8: 3, bgr8: 3, rgba8: 4 };
const NUMERIC_SIZE = { 1: 1, 2: 1, 3: 2, 4: 2, 5: 4, 6: 4, 7: 4, 8: 8 };
const QUATERNION_TOLERANCE = 1e-6;

const decompressHandlers = {
  zstd: (buffer, size) => zstdDecompress(buffer, new Uint8Array(Number(size))),
  lz4: (buffer, size) => lz4.decompress(buffer, Number(size)),
};

class Checker {
  constructor(file) {
    this.file = file;
    this.problems = [];
    this.counts = new Map(); // channel id -> messages decoded
    this.types = new Map(); // schema id -> protobuf Type
    this.jsonSchemas = new Map(); // schema id -> parsed JSON Schema
    this.firstProblemPerKind = new Set();
  }

  problem(kind, text) {
    // One line per kind of problem and channel, so a bad file does not flood the output.
    if (this.firstProblemPerKind.has(kind)) return;
    this.firstProblemPerKind.add(kind);
    this.problems.push(text);
  }

  message(channel, schema, data) {
    this.counts.set(channel.id, (this.counts.get(channel.id) ?? 0) + 1);
    const where = `${channel.topic}`;
    if (!schema) {
      this.problem(`noschema:${where}`, `${where}: channel has no schema`);
      return;
    }
    try {
      if (channel.messageEncoding === "protobuf" && schema.encoding === "protobuf") {
        this.protobufMessage(where, schema, data);
      } else if (channel.messageEncoding === "json" && schema.encoding === "jsonschema") {
        this.jsonMessage(where, schema, data);
      } else {
        this.problem(`enc:${where}`, `${where}: unexpected encoding ` +
          `${channel.messageEncoding}/${schema.encoding}`);
      }
    } catch (err) {
      this.problem(`decode:${where}`, `${where}: cannot decode a message: ${err.message}`);
    }
  }

  protobufMessage(where, schema, data) {
    if (!schema.name.startsWith("foxglove.")) {
      this.problem(`fox:${where}`, `${where}: schema ${schema.name} is not a published ` +
        "foxglove schema");
    }
    let type = this.types.get(schema.id);
    if (!type) {
      const root = protobuf.Root.fromDescriptor(schema.data, { keepCase: true });
      type = root.lookupType(schema.name);
      this.types.set(schema.id, type);
    }
    const msg = type.toObject(type.decode(data), { defaults: true, longs: Number });
    const check = PROTOBUF_CHECKS[schema.name];
    if (check) check(msg, (text) => this.problem(`${schema.name}:${where}`, `${where}: ${text}`));
  }

  jsonMessage(where, schema, data) {
    if (!JSON_SCHEMAS.has(schema.name)) {
      this.problem(`json:${where}`, `${where}: unexpected JSON schema ${schema.name}`);
    }
    let jsonSchema = this.jsonSchemas.get(schema.id);
    if (!jsonSchema) {
      jsonSchema = JSON.parse(new TextDecoder().decode(schema.data));
      this.jsonSchemas.set(schema.id, jsonSchema);
    }
    const msg = JSON.parse(new TextDecoder().decode(data));
    const branch = jsonSchema.oneOf
      ? jsonSchema.oneOf.find((b) => b.properties?.event?.const === msg.event)
      : jsonSchema;
    if (!branch) {
      this.problem(`jsonkind:${where}`, `${where}: event kind ${msg.event} is not in the schema`);
      return;
    }
    for (const key of branch.required ?? []) {
      if (!(key in msg)) this.problem(`req:${where}:${key}`, `${where}: missing key "${key}"`);
    }
    if (schema.name === "armstereo.JointStates" && msg.names.length !== msg.positions.length) {
      this.problem(`joints:${where}`, `${where}: ${msg.names.length} names but ` +
        `${msg.positions.length} positions`);
    }
  }

  finish(reader) {
    const stats = reader?.statistics;
    if (stats) {
      for (const [id, expected] of stats.channelMessageCounts) {
        const got = this.counts.get(id) ?? 0;
        if (BigInt(got) !== expected) {
          this.problem(`count:${id}`, `channel ${id}: statistics say ${expected} messages, ` +
            `read ${got}`);
        }
      }
    }
  }
}

const PROTOBUF_CHECKS = {
  "foxglove.CompressedImage": (m, bad) => {
    const d = m.data;
    const png = d.length > 8 && d[0] === 0x89 && d[1] === 0x50 && d[2] === 0x4e && d[3] === 0x47;
    const jpeg = d.length > 2 && d[0] === 0xff && d[1] === 0xd8;
    if (!((m.format === "png" && png) || (m.format === "jpeg" && jpeg))) {
      bad(`format "${m.format}" does not match the data (${d.length} bytes)`);
    }
    if (!m.frame_id) bad("empty frame_id");
  },
  "foxglove.RawImage": (m, bad) => {
    const bpp = RAW_BYTES_PER_PIXEL[m.encoding];
    if (!bpp) bad(`unknown encoding ${m.encoding}`);
    if (m.width < 1 || m.height < 1 || m.step < m.width * (bpp ?? 1) ||
        m.data.length !== m.step * m.height) {
      bad(`${m.width}x${m.height} step ${m.step} does not fit ${m.data.length} data bytes`);
    }
  },
  "foxglove.CameraCalibration": (m, bad) => {
    if (m.K.length !== 9 || m.R.length !== 9 || m.P.length !== 12) {
      bad(`K/R/P have ${m.K.length}/${m.R.length}/${m.P.length} values, expected 9/9/12`);
    }
    const need = { plumb_bob: 5, rational_polynomial: 8 }[m.distortion_model];
    if (need === undefined || m.D.length < need) {
      bad(`distortion model "${m.distortion_model}" with ${m.D.length} coefficients`);
    }
    if (m.width < 1 || m.height < 1 || m.K[8] !== 1) bad("bad image size or K[2][2] != 1");
  },
  "foxglove.FrameTransforms": (m, bad) => {
    if (m.transforms.length === 0) bad("no transforms");
    for (const t of m.transforms) {
      const q = t.rotation;
      const norm = Math.hypot(q.x, q.y, q.z, q.w);
      if (Math.abs(norm - 1) > QUATERNION_TOLERANCE) {
        bad(`${t.parent_frame_id}->${t.child_frame_id} quaternion norm ${norm}`);
      }
      if (!t.parent_frame_id || !t.child_frame_id) bad("transform without frame ids");
    }
  },
  "foxglove.PointCloud": (m, bad) => {
    const stride = m.point_stride;
    if (stride < 1 || m.data.length % stride !== 0) {
      bad(`stride ${stride} does not divide ${m.data.length} data bytes`);
    }
    for (const f of m.fields) {
      if (f.offset + (NUMERIC_SIZE[f.type] ?? 99) > stride) bad(`field ${f.name} exceeds stride`);
    }
  },
};

async function checkIndexed(file, checker) {
  const handle = await open(file, "r");
  try {
    const reader = await McapIndexedReader.Initialize({
      readable: new FileHandleReadable(handle), decompressHandlers,
    });
    for await (const message of reader.readMessages({ validateCrcs: true })) {
      const channel = reader.channelsById.get(message.channelId);
      checker.message(channel, reader.schemasById.get(channel.schemaId), message.data);
    }
    let metadata = 0;
    for await (const record of reader.readMetadata({ name: "armstereo" })) {
      metadata += 1;
      if (!record.metadata.has("format_version")) {
        checker.problem("meta", 'metadata "armstereo" has no format_version');
      }
    }
    if (metadata !== 1) checker.problem("meta1", `${metadata} "armstereo" metadata records`);
    checker.finish(reader);
    return { reader, library: reader.header.library };
  } finally {
    await handle.close();
  }
}

async function checkStreaming(file, checker, allowUnfinished) {
  const handle = await open(file, "r");
  const bytes = new Uint8Array((await handle.stat()).size);
  await handle.read(bytes, 0, bytes.length, 0);
  await handle.close();
  const reader = new McapStreamReader({ decompressHandlers, validateCrcs: true });
  reader.append(bytes);
  const schemas = new Map();
  const channels = new Map();
  let library = "";
  try {
    for (let r; (r = reader.nextRecord()); ) {
      if (r.type === "Header") library = r.library;
      else if (r.type === "Schema") schemas.set(r.id, r);
      else if (r.type === "Channel") channels.set(r.id, r);
      else if (r.type === "Message") {
        const channel = channels.get(r.channelId);
        checker.message(channel, schemas.get(channel.schemaId), r.data);
      }
    }
  } catch (err) {
    checker.problem("stream", `streaming stopped: ${err.message}`);
  }
  // An unfinished file (writer killed after a flush) ends cleanly at a record boundary.
  if (!reader.done() && (!allowUnfinished || reader.bytesRemaining() > 0)) {
    checker.problem("footer", `no footer: ${reader.bytesRemaining()} unparsed bytes at the end`);
  }
  return { reader: undefined, library, channels, schemas };
}

async function main(argv) {
  const allowUnindexed = argv.includes("--allow-unindexed");
  const files = argv.filter((a) => !a.startsWith("--"));
  if (files.length === 0) {
    console.error("usage: node check.mjs [--allow-unindexed] FILE...");
    return 2;
  }
  let failed = false;
  for (const file of files) {
    let checker = new Checker(file);
    let result;
    try {
      await (await open(file, "r")).close();
    } catch (err) {
      console.log(`${file}: cannot open: ${err.message}`);
      failed = true;
      continue;
    }
    try {
      result = await checkIndexed(file, checker);
    } catch (err) {
      checker = new Checker(file); // start over: the indexed pass may have stopped half way
      if (!allowUnindexed) checker.problem("index", `McapIndexedReader: ${err.message}`);
      result = await checkStreaming(file, checker, allowUnindexed);
    }
    const channels = result.reader ? result.reader.channelsById : result.channels;
    const schemas = result.reader ? result.reader.schemasById : result.schemas;
    console.log(`${file}: written by "${result.library}"`);
    for (const [id, ch] of channels ?? []) {
      const schema = schemas.get(ch.schemaId);
      console.log(`  ${ch.topic}  ${schema?.name ?? "-"}  ${ch.messageEncoding}  ` +
        `${checker.counts.get(id) ?? 0} messages decoded`);
    }
    if (checker.problems.length) {
      failed = true;
      for (const p of checker.problems) console.log(`  PROBLEM: ${p}`);
    } else {
      console.log("  OK");
    }
  }
  return failed ? 1 : 0;
}

process.exitCode = await main(process.argv.slice(2));
