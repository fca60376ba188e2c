// The viewer's binary messages, decoded: the layout of docs/view.md, "The WebSocket protocol"
// (encoded by view/src/protocol.rs; view/tests/protocol_js.rs has this file decode
// what that one encodes). Little-endian; every offset below is in bytes from the message's start.

/** "VESV" in ASCII, the first word of every binary message. */
export const MAGIC = 0x56534556;
/** The layout version this page reads; the hello's `protocol` must be the same. */
export const VERSION = 2;
/** The header every binary message starts with: u32 magic, version, kind. */
export const HEADER = 12;

/** What a binary message carries (the header's third word). */
export const KINDS = Object.freeze({ MESH: 0, FRAME: 1, MODE: 2, STRESS: 3, LOAD: 4 });

/** Where each kind's fields are (after the header). Arrays follow at the last offset. */
export const LAYOUT = Object.freeze({
  // u32 space, nv, nt; f32 rest[3nv]; u32 triangles[3nt]; u8 fixed[nv] (bit c: component c
  // supported); zero bytes to a multiple of 4; when the basis has them, u32 faces[nt].
  mesh: Object.freeze({ space: 12, vertices: 16, triangles: 20, rest: 24 }),
  // u32 space, nv, flags (1: the space has stress, 2: alarm), seq, hand_seq[2], vertex of the
  // largest von Mises stress (2^32−1: none); f64 time, pose[7] (centre of mass position,
  // quaternion w x y z; zeros: supported), largest von Mises (NaN: none); f32 u[3nv].
  frame: Object.freeze({ space: 12, vertices: 16, flags: 20, seq: 24, handSeq: 28, peakVertex: 36, time: 40, pose: 48, peakVonMises: 104, u: 112 }),
  // u32 space, mode, nv; f32 frequency (Hz), phi[3nv] (max |φ| = 1).
  mode: Object.freeze({ space: 12, mode: 16, vertices: 20, frequency: 24, phi: 28 }),
  // u32 space, nv, seq; f32 von Mises[nv], largest principal stress[nv].
  stress: Object.freeze({ space: 12, vertices: 16, seq: 20, vonMises: 24 }),
  // u32 space, nv, index (in the hello's spaces[s].loads); f64 largest displacement (m), largest
  // von Mises (Pa) of the whole part; f32 u[3nv] (m), von Mises[nv] (Pa).
  load: Object.freeze({ space: 12, vertices: 16, index: 20, maxDisplacement: 24, maxVonMises: 32, u: 40 }),
});

/** A message this page cannot read: `foreign` when it is of another protocol or version (every
 * message after it will be too), else one cut short. */
export class ProtocolError extends Error {
  constructor(message, foreign = false) {
    super(message);
    this.name = 'ProtocolError';
    this.foreign = foreign;
  }
}

/** Why a hello cannot be served by this page (another protocol version), or null. */
export function helloMismatch(hello) {
  const v = hello && hello.protocol;
  if (v === VERSION) return null;
  return `the server speaks version ${v === undefined ? 1 : String(v)} of the viewer protocol and this page version ${VERSION}: reload the page`;
}

/** The kind of binary message `buf` (an ArrayBuffer), after checking its header. */
export function kindOf(buf) {
  if (!(buf instanceof ArrayBuffer) || buf.byteLength < HEADER) throw new ProtocolError(`a binary message of ${buf.byteLength} bytes, shorter than its header`, true);
  const [magic, version, kind] = new Uint32Array(buf, 0, 3);
  if (magic !== MAGIC) throw new ProtocolError('a binary message that is not the viewer\'s (wrong magic)', true);
  if (version !== VERSION) throw new ProtocolError(`a binary message of version ${version} of the viewer protocol; this page reads version ${VERSION}: reload the page`, true);
  return kind;
}

/** Typed views of `n` elements at `at`, or a ProtocolError naming the message if `buf` is short. */
function view(Type, buf, at, n, what) {
  if (at + n * Type.BYTES_PER_ELEMENT > buf.byteLength) throw new ProtocolError(`a ${what} message cut short (${buf.byteLength} bytes)`);
  return new Type(buf, at, n);
}

const u32 = (buf, at, what) => view(Uint32Array, buf, at, 1, what)[0];

/** Kind 0: one space's surface. */
export function decodeMesh(buf) {
  const L = LAYOUT.mesh;
  const space = u32(buf, L.space, 'mesh'), nv = u32(buf, L.vertices, 'mesh'), nt = u32(buf, L.triangles, 'mesh');
  const tris = L.rest + 12 * nv;
  const fixedAt = tris + 12 * nt;
  const facesAt = Math.ceil((fixedAt + nv) / 4) * 4;
  return {
    space, vertices: nv,
    rest: view(Float32Array, buf, L.rest, 3 * nv, 'mesh'),
    triangles: view(Uint32Array, buf, tris, 3 * nt, 'mesh'),
    fixed: buf.byteLength >= fixedAt + nv ? new Uint8Array(buf, fixedAt, nv) : new Uint8Array(nv),
    faces: buf.byteLength >= facesAt + 4 * nt && nt > 0 ? new Uint32Array(buf, facesAt, nt) : null,
  };
}

/** Kind 1: a drawn frame (the elastic displacement in the part frame, and the pose). */
export function decodeFrame(buf) {
  const L = LAYOUT.frame;
  const h = view(Uint32Array, buf, L.space, 7, 'frame');
  const [space, nv, flags, seq, hand0, hand1, peak] = h;
  const d = view(Float64Array, buf, L.time, 9, 'frame');
  const pose = Array.from(d.subarray(1, 8));
  return {
    space, vertices: nv, hasStress: (flags & 1) !== 0, alarm: (flags & 2) !== 0, seq,
    handSeq: [hand0, hand1], peakVertex: peak === 0xffffffff ? -1 : peak, peakVonMises: d[8],
    time: d[0], pose: pose.some((v) => v !== 0) ? pose : null,
    u: view(Float32Array, buf, L.u, 3 * nv, 'frame'),
  };
}

/** Kind 3: a frame's stress (sent after `{"type":"fields","stress":true}`). */
export function decodeStress(buf) {
  const L = LAYOUT.stress;
  const space = u32(buf, L.space, 'stress'), nv = u32(buf, L.vertices, 'stress'), seq = u32(buf, L.seq, 'stress');
  return {
    space, seq,
    vonMises: view(Float32Array, buf, L.vonMises, nv, 'stress'),
    principal: view(Float32Array, buf, L.vonMises + 4 * nv, nv, 'stress'),
  };
}

/** Kind 2: a mode shape. */
export function decodeMode(buf) {
  const L = LAYOUT.mode;
  const space = u32(buf, L.space, 'mode'), mode = u32(buf, L.mode, 'mode'), nv = u32(buf, L.vertices, 'mode');
  return {
    space, mode, vertices: nv,
    frequency: view(Float32Array, buf, L.frequency, 1, 'mode')[0],
    phi: view(Float32Array, buf, L.phi, 3 * nv, 'mode'),
  };
}

/** Kind 4: a static load case (sent after `{"type":"load","space":s,"name":…}`). */
export function decodeLoad(buf) {
  const L = LAYOUT.load;
  const space = u32(buf, L.space, 'load'), nv = u32(buf, L.vertices, 'load'), index = u32(buf, L.index, 'load');
  const [maxDisplacement, maxVonMises] = view(Float64Array, buf, L.maxDisplacement, 2, 'load');
  return {
    space, index, vertices: nv, maxDisplacement, maxVonMises,
    u: view(Float32Array, buf, L.u, 3 * nv, 'load'), vm: view(Float32Array, buf, L.u + 12 * nv, nv, 'load'),
  };
}

const DECODERS = {
  [KINDS.MESH]: decodeMesh, [KINDS.FRAME]: decodeFrame, [KINDS.MODE]: decodeMode, [KINDS.STRESS]: decodeStress, [KINDS.LOAD]: decodeLoad,
};

/** The binary message `buf`: `{ kind, message }` (message null for a kind this page does not
 * know); a ProtocolError if it is not one this page can read. */
export function decode(buf) {
  const kind = kindOf(buf);
  const decoder = DECODERS[kind];
  return { kind, message: decoder ? decoder(buf) : null };
}
