// Each hand as the server's status has it: a ball at its true position (the device, under the
// cursor), a dashed spring to the held vertex as drawn, and an arrow of the force on the part at
// that vertex with its value.
import * as THREE from 'three';
import { el } from './dom.js';
import { feltText, label } from './units.js';
import { state } from './state.js';
import { scene, screenOfPoint } from './viewport.js';

const hands = [];
// Scratch for the per-status update: nothing is allocated but what three.js allocates itself.
const drawnAt = new THREE.Vector3(), force = new THREE.Vector3(), dir = new THREE.Vector3(), tip = new THREE.Vector3();
const springEnds = [new THREE.Vector3(), new THREE.Vector3()];
const at = [0, 0];

function make(i) {
  const colourOf = i ? 0x5ee0ff : 0xffd45e;
  const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, colourOf);
  const tag = el('div', { className: 'forcelabel' });
  tag.style.color = `#${colourOf.toString(16)}`;
  document.body.appendChild(tag);
  const g = new THREE.BufferGeometry().setFromPoints(springEnds);
  const spring = new THREE.Line(g, new THREE.LineDashedMaterial({ color: colourOf, dashSize: 0.004 * state.diag, gapSize: 0.003 * state.diag }));
  const ball = new THREE.Mesh(new THREE.SphereGeometry(0.006 * state.diag, 16, 12), new THREE.MeshBasicMaterial({ color: colourOf }));
  scene.add(arrow, spring, ball);
  return { arrow, tag, spring, ball };
}

/** Hand `i` as status `h` has it. */
function update(i, h) {
  if (!hands[i]) hands[i] = make(i);
  const { arrow, tag, spring, ball } = hands[i];
  const s = state.spaces[state.active];
  if (s && h.vertex < s.vertices) drawnAt.fromBufferAttribute(s.geom.attributes.position, h.vertex);
  else drawnAt.set(...h.vertex_position);
  spring.visible = ball.visible = h.active;
  if (h.active) {
    ball.position.set(...h.target);
    springEnds[0].copy(drawnAt);
    springEnds[1].copy(ball.position);
    spring.geometry.setFromPoints(springEnds);
    spring.computeLineDistances();
  }
  force.set(...h.force).negate(); // the device's force is the part's, reversed
  const mag = force.length();
  arrow.visible = h.active && h.contact && mag > 0;
  tag.style.display = arrow.visible ? 'block' : 'none';
  if (!arrow.visible || !state.diag) return;
  const len = Math.max(0.02, Math.min(1, mag / state.hello.max_force)) * 0.25 * state.diag;
  dir.copy(force).normalize();
  arrow.position.copy(drawnAt);
  arrow.setDirection(dir);
  arrow.setLength(len, 0.25 * len, 0.12 * len);
  const [x, y] = screenOfPoint(tip.copy(drawnAt).addScaledVector(dir, len), at);
  tag.style.left = `${x + 8}px`;
  tag.style.top = `${y - 8}px`;
  const felt = feltText(h.felt_error);
  tag.textContent = `${label(mag, 'force', 'si')} on the part${felt ? ` (${felt})` : ''}`;
}

/** Every hand of a status (its `hands`). */
export function showHands(list) {
  list.forEach((h, i) => update(i, h));
}

/** No hands drawn (a new part: they are made again at its size); their GPU memory is freed. */
export function clearHands() {
  for (const h of hands) {
    if (!h) continue;
    scene.remove(h.arrow, h.spring, h.ball);
    h.arrow.dispose();
    for (const o of [h.spring, h.ball]) { o.geometry.dispose(); o.material.dispose(); }
    h.tag.remove();
  }
  hands.length = 0;
}
