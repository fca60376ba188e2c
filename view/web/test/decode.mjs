// Decodes binary viewer messages with the page's own protocol.js and prints them as one JSON
// object: the layout constants, then each file's kind and decoded fields (typed arrays as
// plain arrays; NaN and infinities as strings, which JSON lacks). Run by
// view/tests/protocol_js.rs on messages encoded by view/src/protocol.rs.
//
// usage: node decode.mjs MESSAGE.bin…
import { readFileSync } from 'node:fs';
import { HEADER, LAYOUT, MAGIC, ProtocolError, VERSION, decode, helloMismatch } from '../src/protocol.js';

const plain = (v) => (ArrayBuffer.isView(v) ? Array.from(v) : v);
const messages = process.argv.slice(2).map((path) => {
  const bytes = readFileSync(path);
  // A fresh ArrayBuffer holding exactly the file, as a WebSocket delivers one.
  const buf = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  try {
    const { kind, message } = decode(buf);
    return { kind, ...Object.fromEntries(Object.entries(message || {}).map(([k, v]) => [k, plain(v)])) };
  } catch (e) {
    return { error: e.message, refused: e instanceof ProtocolError, foreign: Boolean(e.foreign) };
  }
});
const hello = { current: helloMismatch({ protocol: VERSION }), other: helloMismatch({ protocol: VERSION + 1 }), none: helloMismatch({}) };
const text = JSON.stringify({ magic: MAGIC, version: VERSION, header: HEADER, layout: LAYOUT, hello, messages },
  (_, v) => (typeof v === 'number' && !Number.isFinite(v) ? String(v) : v));
process.stdout.write(`${text}\n`);
