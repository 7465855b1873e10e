// Reads an MCAP file with @mcap/core's indexed and streaming readers; prints message counts per topic.
const fs = require("fs");
const { McapIndexedReader, McapStreamReader } = require("@mcap/core");
const zstd = require("@foxglove/wasm-zstd");

async function main() {
  await zstd.isLoaded;
  const decompressHandlers = {
    zstd: (buffer, size) => new Uint8Array(zstd.decompress(buffer, Number(size))),
  };
  const out = {};
  for (const path of process.argv.slice(2)) {
    const bytes = fs.readFileSync(path);
    const readable = {
      size: async () => BigInt(bytes.length),
      read: async (offset, length) => new Uint8Array(bytes.buffer, bytes.byteOffset + Number(offset), Number(length)),
    };
    const indexed = await McapIndexedReader.Initialize({ readable, decompressHandlers });
    const byIndex = {};
    for (const ch of indexed.channelsById.values()) byIndex[ch.topic] = 0;
    for await (const m of indexed.readMessages()) {
      const topic = indexed.channelsById.get(m.channelId).topic;
      byIndex[topic] += 1;
    }
    const stream = new McapStreamReader({ decompressHandlers, validateCrcs: true });
    stream.append(bytes);
    const channels = new Map();
    const byStream = {};
    let metadata = [];
    let rec;
    while ((rec = stream.nextRecord()) !== undefined) {
      if (rec.type === "Channel") { channels.set(rec.id, rec.topic); byStream[rec.topic] ??= 0; }
      if (rec.type === "Message") byStream[channels.get(rec.channelId)] += 1;
      if (rec.type === "Metadata") metadata.push(rec.name);
    }
    out[path] = { indexed: byIndex, stream: byStream, done: stream.done(), metadata };
  }
  process.stdout.write(JSON.stringify(out));
}
main().catch((e) => { process.stderr.write(String(e && e.stack || e) + "\n"); process.exit(1); });
