// The viewer's binary messages (little-endian; written by runtime/src/view/protocol.rs, which
// documents the layout) and the colour scale.

const MESH = 0, FRAME = 1, MODE = 2, STRESS = 3;
export const KINDS = { MESH, FRAME, MODE, STRESS };

/** Kind 0: one space's surface: u32 kind, space, nv, nt; f32 rest[3nv]; u32 triangles[3nt]. */
export function decodeMesh(buf) {
  const [, space, nv, nt] = new Uint32Array(buf, 0, 4);
  return {
    space, vertices: nv,
    rest: new Float32Array(buf, 16, 3 * nv),
    triangles: new Uint32Array(buf, 16 + 12 * nv, 3 * nt),
  };
}

/**
 * Kind 1: a drawn frame: u32 kind, space, nv, flags (1: the space has stress, 2: alarm), seq,
 * hand_seq[2]; f32 time, pose[7] (position, quaternion w x y z); f32 positions[3nv], |u|[nv].
 */
export function decodeFrame(buf) {
  const h = new Uint32Array(buf, 0, 7);
  const [, space, nv, flags, seq] = h;
  const f = new Float32Array(buf, 28, 8);
  let at = 60;
  const positions = new Float32Array(buf, at, 3 * nv); at += 12 * nv;
  const umag = new Float32Array(buf, at, nv);
  return { space, vertices: nv, hasStress: (flags & 1) !== 0, alarm: (flags & 2) !== 0, seq, handSeq: [h[5], h[6]], time: f[0], pose: Array.from(f.subarray(1, 8)), positions, umag };
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

// Moreland's cool-warm diverging map, sampled at five points, linear in between.
const STOPS = [[0.23, 0.3, 0.75], [0.55, 0.69, 1.0], [0.87, 0.87, 0.87], [0.96, 0.6, 0.48], [0.71, 0.02, 0.15]];
export function colourMap(t) {
  const x = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (STOPS.length - 1);
  const i = Math.min(STOPS.length - 2, Math.floor(x));
  const u = x - i;
  return STOPS[i].map((a, k) => a + u * (STOPS[i + 1][k] - a));
}

/** A value with an SI prefix: 1.23e-4 m -> "123 µm", 2.5e8 Pa -> "250 MPa". */
export function siLabel(v, unit) {
  if (!Number.isFinite(v)) return `— ${unit}`;
  if (v === 0) return `0 ${unit}`;
  const prefixes = [[1e9, 'G'], [1e6, 'M'], [1e3, 'k'], [1, ''], [1e-3, 'm'], [1e-6, 'µ'], [1e-9, 'n']];
  const a = Math.abs(v);
  const [f, p] = prefixes.find(([f]) => a >= f * 0.9995) || prefixes[prefixes.length - 1];
  return `${(v / f).toPrecision(3)} ${p}${unit}`;
}
