// The page as the device. A pointer that goes down on the part drives a hand (left or touch: hand
// 1; right, a second touch, or the right button pressed while the left holds: hand 2). The drag
// moves the hand in the plane facing the camera through the picked vertex, in true units
// whatever the deformation scale; the wheel moves it along the view ray; with Shift the hand
// presses into the part along the view ray, the further the harder. Off the part the pointer
// orbits. Hovering shows the probe (or, while the set-up panel picks faces, lights the face under
// the cursor): its ray cast runs at most once per animation frame.
import * as THREE from 'three';
import { hideProbe, showProbe, showTip, togglePin } from './hud.js';
import { HOVER, lightFaces } from './spaces.js';
import { state } from './state.js';
import { label } from './units.js';
import { sendTarget } from './connection.js';
import { camera, canvas, controls, ndc } from './viewport.js';

const drags = new Map(); // key (pointer id, or id:2 for a chorded right button) -> drag
const raycaster = new THREE.Raycaster();
const pointer = new THREE.Vector2();
const corner = new THREE.Vector3();
const dragPlane = new THREE.Plane(), dragAt = new THREE.Vector3();

/** A drag is on: the view stays (the drag plane is the camera's). */
export const dragging = () => drags.size > 0;

function freeHand(preferred) {
  const used = new Set([...drags.values()].map((d) => d.hand));
  const others = state.status ? state.status.hands.map((h) => h.active && h.owner !== state.hello.client) : [];
  for (const h of [preferred, 1 - preferred]) if (!used.has(h) && !others[h]) return h;
  return -1;
}

/** The first hit of the pointer's ray on space `s`'s mesh, or undefined. */
function hitOn(s, ev) {
  camera.updateMatrixWorld();
  raycaster.setFromCamera(ndc(ev, pointer), camera);
  return raycaster.intersectObject(s.mesh)[0];
}

/** The corner of the hit triangle nearest the hit point, on space `s` as drawn. */
function nearestCorner(s, hit) {
  const p = s.geom.attributes.position;
  let vertex = hit.face.a, best = Infinity;
  for (const v of [hit.face.a, hit.face.b, hit.face.c]) {
    const d = corner.fromBufferAttribute(p, v).distanceToSquared(hit.point);
    if (d < best) { best = d; vertex = v; }
  }
  return vertex;
}

/** The largest (`sign` > 0) or smallest rest coordinate `k` over the vertices of CAD face `tag`
 * of space `s`. @param {any} s @param {number} tag @param {number} k @param {number} sign */
function outermost(s, tag, k, sign) {
  const index = s.geom.index;
  let best = sign > 0 ? -Infinity : Infinity;
  for (let t = 0; t < s.faces.length; t++) {
    if (s.faces[t] !== tag) continue;
    for (let c = 0; c < 3; c++) {
      const x = s.rest[3 * index.getX(3 * t + c) + k];
      best = sign > 0 ? Math.max(best, x) : Math.min(best, x);
    }
  }
  return Number.isFinite(best) ? best : null;
}

/** The vertex under the pointer (the nearest corner of the hit triangle), or null. */
function pick(ev) {
  const s = state.spaces[state.active];
  if (!s) return null;
  const hit = hitOn(s, ev);
  return hit ? { s, vertex: nearestCorner(s, hit) } : null;
}

function startDrag(key, ev, hand, press) {
  const got = pick(ev);
  if (!got || hand < 0) return false;
  const { s, vertex } = got;
  const shown = new THREE.Vector3().fromBufferAttribute(s.geom.attributes.position, vertex);
  const truePos = new THREE.Vector3(s.truePos[3 * vertex], s.truePos[3 * vertex + 1], s.truePos[3 * vertex + 2]);
  const normal = camera.getWorldDirection(new THREE.Vector3());
  hideProbe();
  // The cursor drives the newest hand; an older one stays where it was and keeps holding.
  for (const d of drags.values()) d.frozen = true;
  drags.set(key, { hand, vertex, shown, truePos, normal, depth: 0, press, offset: new THREE.Vector3(), frozen: false, maxPress: press ? pressLimit(s, shown, normal) : Infinity });
  controls.enabled = false;
  sendHand(drags.get(key), true);
  return true;
}

// How deep a press may push: no deeper than 45 % of the wall it entered (measured along the view
// ray: past half the wall the nearest surface is the far face, and the force would flip) and
// than the coupling needs for the device's force limit.
function pressLimit(s, from, dir) {
  const r = new THREE.Raycaster(from.clone().addScaledVector(dir, 1e-6 * state.diag), dir);
  const far = r.intersectObject(s.mesh).find((h) => h.distance > 1e-5 * state.diag);
  const wall = far ? far.distance : Infinity;
  return Math.min(0.45 * wall, 1.2 * state.hello.max_force / state.hello.stiffness);
}

function endDrag(key) {
  const d = drags.get(key);
  if (!d) return;
  drags.delete(key);
  sendHand(d, false);
  const rest = [...drags.values()];
  if (rest.length) rest.at(-1).frozen = false;
  else controls.enabled = true;
}

/** Every drag of this page ends (its hands let go). */
export function endDrags() {
  for (const key of [...drags.keys()]) endDrag(key);
}

/** Every drag ends and every hand this page drives is let go (a load case is shown). */
export function letGo() {
  endDrags();
  for (const h of [0, 1]) if (state.status && state.status.hands[h].active && state.status.hands[h].owner === state.hello.client) release(h);
}

/** The connection is gone: the drags are forgotten (nothing can be sent) and the view orbits. */
export function dropDrags() {
  drags.clear();
  controls.enabled = true;
}

function handTarget(d) {
  if (d.press) return d.truePos.clone().addScaledVector(d.normal, Math.min(d.depth + d.offset.length(), d.maxPress));
  return d.truePos.clone().add(d.offset).addScaledVector(d.normal, d.depth);
}

function sendHand(d, active) {
  const p = handTarget(d);
  sendTarget(d.hand, [p.x, p.y, p.z], !d.press, active);
}

/** Drives hand `hand` without a pointer (scripts, the benchmark): grab at `position` (m, part
 * frame) or move there. */
export const drive = (hand, position, button = true) => sendTarget(hand, position, button, true);
/** Lets go of hand `hand`. */
export const release = (hand) => sendTarget(hand, state.lastTarget || [0, 0, 0], true, false);

// The set-up panel asks for one click on the part (a face to hold): that click is not a grab.
let picking = null;
/** The next click on the part calls `done({point, normal})` (the hit's nearest corner at rest,
 * and the triangle's normal) instead of grabbing. */
export function requestPick(done) { picking = done; }

// Faces: while the set-up panel picks them, the face under the cursor is lit and a click calls
// the panel back with its tag.
let facePick = null;
/** The hello's record of CAD face `tag` (`kind`: plane, cylinder, other; as `ves faces`), or null.
 * @param {number | null} tag @returns {any} */
export function faceOf(tag) {
  const space = state.hello && state.hello.spaces[state.active];
  return tag != null && space && Array.isArray(space.faces) ? space.faces.find((/** @type {any} */ x) => x.tag === tag) || null : null;
}

/** What the page knows of face `tag` (the hello's `faces`, as `ves faces` lists them):
 * "face 24 · cylinder r 3.25 mm, concave · 34.6 mm²", with the STEP file's name of the face
 * after its number where the file gives one ("face 3 “mounting face” · plane · …"). */
export function faceWords(tag) {
  const f = faceOf(tag);
  if (!f) return `face ${tag}`;
  const u = state.units;
  const a = f.area_m2;
  const area = u === 'mm' ? `${(a * 1e6).toPrecision(3)} mm²` : `${a < 1e-2 ? a.toExponential(2) : a.toPrecision(3)} m²`;
  const kind = f.kind === 'cylinder'
    ? `cylinder r ${label(f.radius_m, 'length', u)}${f.concave ? ', concave' : ''}`
    : f.kind;
  // The STEP file's name, cut for the tooltip (`ves faces --json` has it whole).
  const named = typeof f.name === 'string' ? f.name : '';
  const name = named ? ` “${named.length > 60 ? `${named.slice(0, 59)}…` : named}”` : '';
  return `face ${tag}${name} · ${kind} · ${area}`;
}

/** Face picking on (`onClick(tag)` for each click on a face) or off. */
export function faceMode(on, onClick) {
  facePick = on ? onClick : null;
  if (!on) { lightFaces('hover', [], 0); state.hoverFace = null; }
}

/** The CAD face under the pointer (space 0), or null. */
function faceAt(ev) {
  const s = state.spaces[0];
  if (!s || !s.faces || state.active !== 0) return null;
  const hit = hitOn(s, ev);
  return hit ? s.faces[hit.faceIndex] : null;
}

// Hover: the latest pointer position, handled at the next animation frame (one ray cast per
// frame however fast the pointer moves).
let hover = null;
function hoverLater(ev) {
  if (hover === null) requestAnimationFrame(hoverNow);
  hover = ev;
}
function hoverNow() {
  const ev = hover;
  hover = null;
  if (ev === null) return;
  if (facePick) {
    const tag = faceAt(ev);
    if (tag !== state.hoverFace) { state.hoverFace = tag; lightFaces('hover', tag === null ? [] : [tag], HOVER); }
    showTip(tag === null ? null : faceWords(tag), ev.clientX, ev.clientY);
    return;
  }
  if (drags.size || !state.ready || state.mode) return;
  const got = pick(ev);
  if (!got) { hideProbe(); return; }
  state.probe = { vertex: got.vertex, x: ev.clientX, y: ev.clientY };
  showProbe(got.vertex, ev.clientX, ev.clientY);
}

canvas.addEventListener('pointerdown', (ev) => {
  if (facePick && state.ready) {
    const tag = faceAt(ev);
    if (tag === null) return; // off the part: orbit
    ev.stopImmediatePropagation();
    facePick(tag);
    return;
  }
  if (picking && state.ready) {
    const s = state.spaces[state.active];
    const hit = hitOn(s, ev);
    if (!hit) return;
    ev.stopImmediatePropagation();
    const done = picking;
    picking = null;
    // The part frame's point: the rest position of the hit triangle's nearest corner; and the
    // CAD face hit, whose outermost point a plane pick snaps to.
    const v = nearestCorner(s, hit);
    const tag = s.faces && state.active === 0 ? s.faces[hit.faceIndex] : null;
    done({
      point: new THREE.Vector3(s.rest[3 * v], s.rest[3 * v + 1], s.rest[3 * v + 2]),
      normal: hit.face.normal.clone(),
      outermost: (k, sign) => (tag == null ? null : outermost(s, tag, k, sign)),
      face: faceOf(tag),
      faceWords: tag == null ? '' : faceWords(tag),
    });
    return;
  }
  // No hand while a static load case is shown (the drag orbits): its drawing is not the live part.
  if (!state.ready || state.mode || state.loadCase || state.loadWanted) return;
  const hand = freeHand(ev.button === 2 || drags.size > 0 ? 1 : 0);
  if (!startDrag(ev.pointerId, ev, hand, ev.shiftKey)) return; // off the part: orbit
  ev.stopImmediatePropagation();
  canvas.setPointerCapture(ev.pointerId);
}, { capture: true });

canvas.addEventListener('pointermove', (ev) => {
  // A button pressed or released while another is held comes as a move (a chord).
  if (ev.button === 2 && drags.has(ev.pointerId)) {
    const key = `${ev.pointerId}:2`;
    if (ev.buttons & 2) startDrag(key, ev, freeHand(1), ev.shiftKey);
    else endDrag(key);
    return;
  }
  // The left button let go while the right still holds: the left's hand lets go.
  if (ev.button === 0 && !(ev.buttons & 1) && drags.has(ev.pointerId)) {
    endDrag(ev.pointerId);
    return;
  }
  if (facePick || !drags.size) { hoverLater(ev); return; }
  // A drag answers every move at once (the hand's latency): a plane, not the mesh, is hit.
  for (const [key, d] of drags) {
    if (d.frozen || !ofPointer(key, ev)) continue;
    raycaster.setFromCamera(ndc(ev, pointer), camera);
    dragPlane.setFromNormalAndCoplanarPoint(d.normal, d.shown);
    const at = raycaster.ray.intersectPlane(dragPlane, dragAt);
    if (!at) continue;
    d.offset.copy(at).sub(d.shown);
    sendHand(d, true);
  }
});

const ofPointer = (key, ev) => key === ev.pointerId || key === `${ev.pointerId}:2`;
function endPointer(ev) {
  for (const key of [...drags.keys()]) if (ofPointer(key, ev)) endDrag(key);
}
canvas.addEventListener('pointerup', endPointer);
canvas.addEventListener('pointercancel', endPointer);
canvas.addEventListener('pointerleave', () => { if (!drags.size) { hover = null; hideProbe(); } });
canvas.addEventListener('contextmenu', (ev) => ev.preventDefault());
// A double-click on the part pins a probe there (or unpins the one clicked): its value stays on
// the part and follows it while a hand pulls, where the hover probe is off.
canvas.addEventListener('dblclick', (ev) => {
  if (facePick || picking || !state.ready || state.mode) return;
  const got = pick(ev);
  if (got) togglePin(got.vertex, [ev.clientX, ev.clientY], 10);
});
canvas.addEventListener('wheel', (ev) => {
  if (drags.size === 0) return;
  ev.preventDefault();
  ev.stopImmediatePropagation();
  for (const d of drags.values()) {
    if (d.frozen) continue;
    d.depth += Math.sign(ev.deltaY) * 0.005 * state.diag;
    sendHand(d, true);
  }
}, { capture: true, passive: false });
