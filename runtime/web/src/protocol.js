// The viewer's binary messages (little-endian; written by runtime/src/view/protocol.rs, which
// documents the layout).

const MESH = 0, FRAME = 1, MODE = 2, STRESS = 3, LOAD = 4;
export const KINDS = { MESH, FRAME, MODE, STRESS, LOAD };

/** Kind 0: one space's surface: u32 kind, space, nv, nt; f32 rest[3nv]; u32 triangles[3nt];
 * u8 fixed[nv] (bit c: component c supported); zero bytes to a multiple of 4; when the basis
 * has them, u32 faces[nt] (each triangle's CAD face tag). */
export function decodeMesh(buf) {
  const [, space, nv, nt] = new Uint32Array(buf, 0, 4);
  const at = 16 + 12 * nv + 12 * nt;
  const facesAt = Math.ceil((at + nv) / 4) * 4;
  return {
    space, vertices: nv,
    rest: new Float32Array(buf, 16, 3 * nv),
    triangles: new Uint32Array(buf, 16 + 12 * nv, 3 * nt),
    fixed: buf.byteLength >= at + nv ? new Uint8Array(buf, at, nv) : new Uint8Array(nv),
    faces: buf.byteLength >= facesAt + 4 * nt && nt > 0 ? new Uint32Array(buf, facesAt, nt) : null,
  };
}

/**
 * Kind 1: a drawn frame: u32 kind, space, nv, flags (1: the space has stress, 2: alarm), seq,
 * hand_seq[2], vertex of the largest von Mises stress (2^32−1: none); f64 time, pose[7]
 * (centre of mass position, quaternion w x y z; zeros: supported), largest von Mises (NaN:
 * none); f32 u[3nv], the elastic displacement (part frame).
 */
export function decodeFrame(buf) {
  const h = new Uint32Array(buf, 0, 8);
  const [, space, nv, flags, seq] = h;
  const d = new Float64Array(buf, 32, 9);
  const pose = Array.from(d.subarray(1, 8));
  return {
    space, vertices: nv, hasStress: (flags & 1) !== 0, alarm: (flags & 2) !== 0, seq,
    handSeq: [h[5], h[6]], peakVertex: h[7] === 0xffffffff ? -1 : h[7], peakVonMises: d[8],
    time: d[0], pose: pose.some((v) => v !== 0) ? pose : null,
    u: new Float32Array(buf, 104, 3 * nv),
  };
}

/** Kind 3: a frame's stress (sent after `{"type":"fields","stress":true}`): u32 kind, space, nv,
 * seq; f32 von Mises[nv], largest principal stress[nv]. */
export function decodeStress(buf) {
  const [, space, nv, seq] = new Uint32Array(buf, 0, 4);
  return { space, seq, vonMises: new Float32Array(buf, 16, nv), principal: new Float32Array(buf, 16 + 4 * nv, nv) };
}

/** Kind 2: a mode shape: u32 kind, space, mode, nv; f32 frequency (Hz); f32 phi[3nv] (max |φ| = 1). */
export function decodeMode(buf) {
  const [, space, mode, nv] = new Uint32Array(buf, 0, 4);
  return { space, mode, vertices: nv, frequency: new Float32Array(buf, 16, 1)[0], phi: new Float32Array(buf, 20, 3 * nv) };
}

/** Kind 4: a static load case (sent after `{"type":"load","space":s,"name":…}`): u32 kind, space,
 * nv, index (in the hello's `spaces[s].loads`); f64 largest displacement (m), largest von Mises
 * (Pa) of the whole part; f32 u[3nv] (m), von Mises[nv] (Pa). */
export function decodeLoad(buf) {
  const [, space, nv, index] = new Uint32Array(buf, 0, 4);
  const [maxDisplacement, maxVonMises] = new Float64Array(buf, 16, 2);
  return {
    space, index, vertices: nv, maxDisplacement, maxVonMises,
    u: new Float32Array(buf, 32, 3 * nv), vm: new Float32Array(buf, 32 + 12 * nv, nv),
  };
}
