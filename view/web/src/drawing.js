// The live part drawn from the latest frame: positions rest + k·u (posed for a free body) and
// colours of the field chosen, with its legend and markers. Runs only when something changed;
// it reuses its scratch objects and allocates nothing per vertex.
import * as THREE from 'three';
import { $ } from './dom.js';
import { fieldOf } from './field.js';
import { placeMarkers, placePins, showLegend, showProbe } from './hud.js';
import { drawScale, restLevel } from './scale.js';
import { supportsFollow } from './spaces.js';
import { state } from './state.js';
import { send } from './connection.js';

const STRESS_COLOURS = new Set(['vonmises', 'principal', 'safety']);

/** Tells the server whether this page colours by stress (it computes and sends it only then). */
export function askFields() {
  send({ type: 'fields', stress: STRESS_COLOURS.has(state.colour) });
}

const rotation = new THREE.Matrix4(), turn = new THREE.Quaternion();

// Positions: rest + k·u, posed for a free body (x + R(rest + k·u − c)). The drawn ones use the
// deformation scale; the true ones (k = 1) are where the hands act.
function place(s, k, out) {
  const q = s.pose;
  const u = s.u, r = s.rest;
  if (!q) {
    for (let i = 0; i < out.length; i++) out[i] = r[i] + k * u[i];
    return;
  }
  const m = rotation.makeRotationFromQuaternion(turn.set(q[4], q[5], q[6], q[3])).elements;
  const c = state.hello.center || [0, 0, 0];
  for (let i = 0; i < out.length; i += 3) {
    const x = r[i] + k * u[i] - c[0], y = r[i + 1] + k * u[i + 1] - c[1], z = r[i + 2] + k * u[i + 2] - c[2];
    out[i] = q[0] + m[0] * x + m[4] * y + m[8] * z;
    out[i + 1] = q[1] + m[1] * x + m[5] * y + m[9] * z;
    out[i + 2] = q[2] + m[2] * x + m[6] * y + m[10] * z;
  }
}

/** Draws space `s` as its latest frame has it. */
export function draw(s) {
  const k = drawScale(s);
  const drawn = s.geom.attributes.position.array;
  place(s, k, drawn);
  place(s, 1, s.truePos);
  s.drawnPose = s.pose; // what the drawing used (a newer frame may have come since)
  s.geom.attributes.position.needsUpdate = true;
  s.geom.computeBoundingSphere();
  supportsFollow(s, drawn);
  colour(s);
}

// The colour range keeps the largest values since the part was last at rest (per colouring), so
// a part ringing after a release does not look as loaded as it was.
function episodeRange() {
  if (!(state.episodePeak > 0)) { state.episodes = {}; return null; }
  return state.episodes[state.colour] || (state.episodes[state.colour] = { lo: 0, hi: 0 });
}

const rgb = [0, 0, 0];
function colour(s) {
  const locked = state.locked && state.locked.colour === state.colour ? state.locked : null;
  const f = fieldOf(state.colour, s, { hello: state.hello, restLevel: restLevel(s), units: state.units, locked, episode: episodeRange() });
  state.field = f;
  const c = s.geom.attributes.color.array;
  for (let i = 0; i < s.vertices; i++) {
    const v = f.colourOf(i, rgb);
    c[3 * i] = v[0]; c[3 * i + 1] = v[1]; c[3 * i + 2] = v[2];
  }
  s.geom.attributes.color.needsUpdate = true;
  const caption = `deformation drawn ${$('scaleshown').textContent}${f.summary ? ` · ${f.summary}` : ''}`;
  state.legend = { title: f.title, scale: f.scale, ticks: f.ticks, caption, atRest: f.atRest, lo: f.lo, hi: f.hi };
  showLegend(f.title, f.scale, f.ticks, f.summary || '');
  placeMarkers(s, f.markers);
  placePins(s);
  if (state.probe) showProbe(state.probe.vertex, state.probe.x, state.probe.y);
}
