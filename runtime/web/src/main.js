// The ves view page: draws what the server's runtime computes and is its device. The mouse ray
// picks a surface vertex; its drag moves a hand; the server's haptic loop couples the hand to the
// part and sends back drawn frames (binary, little-endian f32) and a status (JSON).
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { decodeFrame, decodeMesh, decodeMode, decodeStress, colourMap, siLabel } from './protocol.js';

const $ = (id) => document.getElementById(id);
const canvas = $('view');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: true, preserveDrawingBuffer: true });
renderer.setPixelRatio(window.devicePixelRatio);
const scene = new THREE.Scene();
scene.background = new THREE.Color(0x1d2126);
const camera = new THREE.PerspectiveCamera(35, 1, 1e-4, 1e4);
camera.up.set(0, 0, 1);
scene.add(new THREE.HemisphereLight(0xffffff, 0x404850, 1.6));
const sun = new THREE.DirectionalLight(0xffffff, 1.6);
scene.add(sun);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = false;

// Everything the page knows, open to tests and to the console.
const state = {
  ready: false, hello: null, spaces: [], active: 0, frames: 0, framesSkipped: 0, lastSeq: -1,
  status: null, scale: 1, colour: 'displacement', mode: null, framesPerSecond: 0,
  latency: [], // ms from a pointer event to the first frame computed after the server got it
};
window.ves = state;

let ws;
const pending = []; // [time sent, hand message sequence] awaiting a frame that reflects them
let handSeq = 0;

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { $('conn').textContent = 'connected'; };
  ws.onclose = () => { $('conn').textContent = 'disconnected'; state.ready = false; state.meshesIn = false; };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') onText(JSON.parse(ev.data));
    else onBinary(ev.data);
  };
}

function onText(msg) {
  if (msg.type === 'hello') {
    state.hello = msg;
    $('title').textContent = `VES view — ${msg.name}`;
    $('limit').textContent = `device force limit ${msg.max_force.toPrecision(3)} N · coupling ${siLabel(msg.stiffness, 'N/m')}`
      + (msg.free_body ? ` · free body, gravity ${Math.hypot(...(msg.gravity || [0, 0, 0])).toPrecision(3)} m/s²` : '');
    buildModeList(msg.spaces[0]);
    if (!msg.spaces.some((s) => s.has_stress)) {
      for (const o of $('colour').options) if (o.value !== 'displacement') o.disabled = true;
    }
    if (msg.yield_strength == null) $('colour').querySelector('option[value=safety]').disabled = true;
    askFields();
  } else if (msg.type === 'status') {
    state.status = msg;
    showStatus(msg);
  }
}

function onBinary(buf) {
  const kind = new Uint32Array(buf, 0, 1)[0];
  if (kind === 0) addSpace(decodeMesh(buf));
  else if (kind === 1) onFrame(decodeFrame(buf));
  else if (kind === 2) startMode(decodeMode(buf));
  else if (kind === 3) onStress(decodeStress(buf));
}

function addSpace(m) {
  const geom = new THREE.BufferGeometry();
  const pos = new Float32Array(m.rest);
  geom.setAttribute('position', new THREE.BufferAttribute(pos, 3).setUsage(THREE.DynamicDrawUsage));
  const col = new Float32Array(3 * m.vertices).fill(0.8);
  geom.setAttribute('color', new THREE.BufferAttribute(col, 3).setUsage(THREE.DynamicDrawUsage));
  geom.setIndex(new THREE.BufferAttribute(m.triangles, 1));
  geom.computeVertexNormals();
  geom.computeBoundingBox();
  // Flat shading: an FE surface has sharp edges that averaged normals would smear.
  const mat = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.6, metalness: 0.1, side: THREE.DoubleSide, flatShading: true });
  const mesh = new THREE.Mesh(geom, mat);
  mesh.visible = m.space === state.active;
  scene.add(mesh);
  const info = state.hello.spaces[m.space];
  let box = null;
  if (info.voi) {
    box = new THREE.Box3Helper(new THREE.Box3(new THREE.Vector3(...info.voi[0]), new THREE.Vector3(...info.voi[1])), 0x66ccff);
    scene.add(box);
  }
  state.spaces[m.space] = { ...m, geom, mesh, box, positions: new Float32Array(m.rest), umag: new Float32Array(m.vertices), vm: null };
  if (m.space === 0) frameCamera(geom.boundingBox);
  // Ready once every space is in and has been drawn with the framed camera (see loop).
  if (state.spaces.filter(Boolean).length === state.hello.spaces.length) state.meshesIn = true;
}

function frameCamera(box) {
  const c = box.getCenter(new THREE.Vector3());
  const d = box.getSize(new THREE.Vector3()).length();
  state.diag = d;
  controls.target.copy(c);
  camera.position.set(c.x + 0.25 * d, c.y - 1.45 * d, c.z + 0.7 * d);
  camera.near = d / 1000; camera.far = d * 100;
  camera.updateProjectionMatrix();
  sun.position.set(c.x + d, c.y - d, c.z + 2 * d);
  controls.update();
}

function onFrame(f) {
  const s = state.spaces[f.space];
  if (!s) return;
  if (state.lastSeq >= 0 && f.seq > state.lastSeq + 1) state.framesSkipped += f.seq - state.lastSeq - 1;
  state.lastSeq = f.seq;
  state.frames += 1;
  if (f.space !== state.active) {
    for (const t of state.spaces) if (t) t.mesh.visible = false;
    state.active = f.space;
    buildModeList(state.hello.spaces[f.space]);
  }
  s.mesh.visible = true;
  s.positions.set(f.positions);
  s.umag.set(f.umag);

  s.pose = f.pose;
  s.alarm = f.alarm;
  s.frameTime = f.time;
  state.dirty = true;
  // Latency: from a pointer event to the first frame drawn from a state in which the haptic
  // loop had read that event's hand message (the frame says which message each hand read last).
  while (pending.length && f.handSeq[pending[0][2]] >= pending[0][1]) {
    const [t0] = pending.shift();
    state.latency.push(performance.now() - t0);
    if (state.latency.length > 500) state.latency.shift();
  }
}

// Stress arrives apart, only while this page colours by it (the server computes it only then).
function onStress(m) {
  const s = state.spaces[m.space];
  if (!s) return;
  s.vm = m.vonMises;
  s.p1 = m.principal;
  state.dirty = true;
}

const STRESS_COLOURS = new Set(['vonmises', 'principal', 'safety']);
function askFields() {
  if (ws && ws.readyState === 1) ws.send(JSON.stringify({ type: 'fields', stress: STRESS_COLOURS.has(state.colour) }));
}

// The drawn positions: posed rest plus the deformation times the scale (1 = true size).
function draw(s) {
  const p = s.geom.attributes.position.array;
  const k = state.scale;
  const rest = posedRest(s);
  for (let i = 0; i < p.length; i++) p[i] = rest[i] + k * (s.positions[i] - rest[i]);
  s.geom.attributes.position.needsUpdate = true;
  s.geom.computeBoundingSphere();
  colour(s);
}

function posedRest(s) {
  const q = s.pose;
  if (!q || (q[0] === 0 && q[1] === 0 && q[2] === 0 && q[3] === 1 && q[4] === 0 && q[5] === 0 && q[6] === 0)) return s.rest;
  if (!s.posed) s.posed = new Float32Array(s.rest.length);
  const rot = new THREE.Quaternion(q[4], q[5], q[6], q[3]);
  const v = new THREE.Vector3();
  for (let i = 0; i < s.vertices; i++) {
    v.set(s.rest[3 * i], s.rest[3 * i + 1], s.rest[3 * i + 2]).applyQuaternion(rot);
    s.posed[3 * i] = v.x + q[0]; s.posed[3 * i + 1] = v.y + q[1]; s.posed[3 * i + 2] = v.z + q[2];
  }
  return s.posed;
}

function colour(s) {
  const c = s.geom.attributes.color.array;
  const n = s.vertices;
  const ys = state.hello.yield_strength;
  let values = s.umag, unit = 'm', title = 'displacement magnitude';
  if (state.colour === 'vonmises' && s.vm) { values = s.vm; unit = 'Pa'; title = 'von Mises stress'; }
  let signed = false;
  if (state.colour === 'principal' && s.p1) { values = s.p1; unit = 'Pa'; title = 'largest principal stress (tension > 0)'; signed = true; }
  if (state.colour === 'safety' && s.vm && ys) {
    title = 'safety factor (yield / von Mises), capped at 10';
    values = new Float32Array(n);
    for (let i = 0; i < n; i++) values[i] = Math.min(10, ys / Math.max(s.vm[i], 1e-30));
    unit = '';
  }
  let hi = 0, lo = Infinity;
  for (let i = 0; i < n; i++) { hi = Math.max(hi, values[i]); lo = Math.min(lo, values[i]); }
  if (unit !== '' && !signed) lo = 0;
  // A signed field is centred on zero: blue compression, red tension.
  if (signed) { const m = Math.max(Math.abs(lo), Math.abs(hi)); lo = -m; hi = m; }
  const span = hi - lo > 0 ? hi - lo : 1;
  const reverse = unit === ''; // a low safety factor is the hot colour
  for (let i = 0; i < n; i++) {
    let t = (values[i] - lo) / span;
    if (reverse) t = 1 - t;
    const [r, g, b] = colourMap(t);
    c[3 * i] = r; c[3 * i + 1] = g; c[3 * i + 2] = b;
  }
  s.geom.attributes.color.needsUpdate = true;
  $('legendtitle').textContent = title;
  const fmt = (v) => (unit === '' ? v.toPrecision(3) : siLabel(v, unit));
  const [a, b] = reverse ? [hi, lo] : [lo, hi];
  $('lo').textContent = fmt(a); $('mid').textContent = fmt((a + b) / 2); $('hi').textContent = fmt(b);
}

function showStatus(m) {
  const sp = state.hello.spaces[m.space];
  $('space').textContent = `space ${sp.name}${sp.voi ? ' (volume of interest)' : ''} · ${sp.vertices} vertices · ${m.clients} client(s)`;
  // Times the part was actually redrawn (the loop below), over the last 60.
  const t = state.drawTimes || [];
  const fps = t.length > 1 ? (1000 * (t.length - 1)) / (t.at(-1) - t[0]) : 0;
  state.framesPerSecond = fps;
  $('rates').textContent = `haptic ${m.haptic_hz.toFixed(0)} Hz · visual ${m.visual_hz.toFixed(0)} Hz · drawn here ${fps.toFixed(0)} fps`;
  const lines = [];
  const warn = [];
  m.hands.forEach((h, i) => {
    updateArrow(i, h);
    if (!h.active) return;
    const f = Math.hypot(...h.force);
    lines.push(`hand ${i + 1}: ${f.toPrecision(3)} N${h.clamped ? ' (at the limit)' : ''}${h.button ? '' : ' pressing'}`
      + (h.von_mises > 0 ? ` · σvM ${siLabel(h.von_mises, 'Pa')} · σ1 ${siLabel(h.principal_stress, 'Pa')} · ε1 ${h.principal_strain.toExponential(2)}` : '')
      + (h.safety_factor != null && h.von_mises > 0 ? ` · safety ${h.safety_factor.toPrecision(3)}` : ''));
    if (h.strain_exceeded) warn.push(`hand ${i + 1}: strain ${h.strain.toPrecision(2)} beyond the linear model's limit`);
    if (h.stress_exceeded) warn.push(`hand ${i + 1}: safety factor ${h.safety_factor.toPrecision(2)} below the minimum`);
  });
  if (m.alarm) warn.push(`the part's safety factor is below ${state.hello.min_safety_factor}: it would yield`);
  $('handinfo').textContent = lines.join(' · ');
  $('warn').textContent = warn.join(' · ');
}

// Force arrows at each hand's vertex, with the value in newtons.
const arrows = [];
function updateArrow(i, h) {
  if (!arrows[i]) {
    const a = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, i ? 0x5ee0ff : 0xffd45e);
    const label = document.createElement('div');
    label.className = 'forcelabel';
    document.body.appendChild(label);
    scene.add(a);
    arrows[i] = { a, label };
  }
  const { a, label } = arrows[i];
  if (!arrows[i].spring) {
    const g = new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]);
    arrows[i].spring = new THREE.Line(g, new THREE.LineDashedMaterial({ color: i ? 0x5ee0ff : 0xffd45e, dashSize: 0.004 * state.diag, gapSize: 0.003 * state.diag }));
    arrows[i].handball = new THREE.Mesh(new THREE.SphereGeometry(0.006 * state.diag, 16, 12), new THREE.MeshBasicMaterial({ color: i ? 0x5ee0ff : 0xffd45e }));
    scene.add(arrows[i].spring, arrows[i].handball);
  }
  const { spring, handball } = arrows[i];
  // Anchored at the vertex as drawn (which the deformation scale moves); the spring's stretch
  // (hand target − vertex) is the true one.
  const s = state.spaces[state.active];
  const drawnAt = s && h.vertex < s.vertices
    ? new THREE.Vector3().fromBufferAttribute(s.geom.attributes.position, h.vertex) : new THREE.Vector3(...h.vertex_position);
  spring.visible = handball.visible = h.active;
  if (h.active) {
    const hand = drawnAt.clone().add(new THREE.Vector3(...h.target).sub(new THREE.Vector3(...h.vertex_position)));
    handball.position.copy(hand);
    spring.geometry.setFromPoints([drawnAt, hand]);
    spring.computeLineDistances();
  }
  const f = new THREE.Vector3(...h.force);
  const mag = f.length();
  a.visible = h.active && h.contact;
  label.style.display = a.visible ? 'block' : 'none';
  if (!a.visible || !state.diag) return;
  const at = drawnAt;
  const len = Math.max(0.02, Math.min(1, mag / state.hello.max_force)) * 0.25 * state.diag;
  a.position.copy(at);
  a.setDirection(mag > 0 ? f.clone().normalize() : new THREE.Vector3(0, 0, 1));
  a.setLength(len, 0.25 * len, 0.12 * len);
  const tip = at.clone().addScaledVector(a.getWorldDirection(new THREE.Vector3()), 0).project(camera);
  label.style.left = `${((tip.x + 1) / 2) * canvas.clientWidth + 8}px`;
  label.style.top = `${((1 - tip.y) / 2) * canvas.clientHeight - 8}px`;
  label.textContent = `${mag.toPrecision(3)} N`;
}

// Mode browser: the frequencies of the active space; a click animates that mode's shape.
function buildModeList(space) {
  const box = $('modes');
  box.textContent = '';
  space.frequencies_hz.forEach((f, j) => {
    const b = document.createElement('button');
    b.textContent = `mode ${j + 1}: ${f.toPrecision(5)} Hz`;
    b.onclick = () => {
      if (state.mode && state.mode.mode === j) { state.mode = null; state.dirty = true; b.classList.remove('on'); return; }
      ws.send(JSON.stringify({ type: 'mode', space: state.active, index: j }));
    };
    box.appendChild(b);
  });
}

function startMode(m) {
  for (const b of $('modes').children) b.classList.remove('on');
  const b = $('modes').children[m.mode];
  if (b) b.classList.add('on');
  state.mode = { ...m, start: performance.now() };
}

function animateMode() {
  const m = state.mode;
  const s = state.spaces[m.space];
  const amp = 0.08 * state.diag * Math.sin((2 * Math.PI * (performance.now() - m.start)) / 1500);
  const p = s.geom.attributes.position.array;
  const c = s.geom.attributes.color.array;
  for (let i = 0; i < s.vertices; i++) {
    const mag = Math.hypot(m.phi[3 * i], m.phi[3 * i + 1], m.phi[3 * i + 2]);
    const [r, g, b] = colourMap(mag);
    for (let k = 0; k < 3; k++) p[3 * i + k] = s.rest[3 * i + k] + amp * m.phi[3 * i + k];
    c[3 * i] = r; c[3 * i + 1] = g; c[3 * i + 2] = b;
  }
  s.geom.attributes.position.needsUpdate = true;
  s.geom.attributes.color.needsUpdate = true;
  s.geom.computeBoundingSphere();
  $('legendtitle').textContent = `mode ${m.mode + 1}, ${m.frequency.toPrecision(5)} Hz: relative amplitude (shape only)`;
  $('lo').textContent = '0'; $('mid').textContent = '0.5'; $('hi').textContent = '1';
}

// Hands: a pointer that goes down on the part drives a hand (left or touch: hand 1, right or a
// second touch: hand 2); its drag moves the hand in the plane facing the camera through the
// picked vertex, the wheel moves it along the view ray.
const drags = new Map(); // pointerId -> {hand, start, depth, press, vertex}
const raycaster = new THREE.Raycaster();

function ndc(ev) {
  const r = canvas.getBoundingClientRect();
  return new THREE.Vector2(((ev.clientX - r.left) / r.width) * 2 - 1, -((ev.clientY - r.top) / r.height) * 2 + 1);
}

function freeHand(preferred) {
  const used = new Set([...drags.values()].map((d) => d.hand));
  const others = state.status ? state.status.hands.map((h) => h.active && h.owner !== state.hello.client) : [];
  for (const h of [preferred, 1 - preferred]) if (!used.has(h) && !others[h]) return h;
  return -1;
}

canvas.addEventListener('pointerdown', (ev) => {
  if (!state.ready || state.mode) return;
  const s = state.spaces[state.active];
  camera.updateMatrixWorld();
  raycaster.setFromCamera(ndc(ev), camera);
  const hit = raycaster.intersectObject(s.mesh)[0];
  if (!hit) return; // orbit
  const hand = freeHand(ev.button === 2 || drags.size > 0 ? 1 : 0);
  if (hand < 0) return;
  ev.stopImmediatePropagation();
  controls.enabled = false;
  canvas.setPointerCapture(ev.pointerId);
  const f = hit.face;
  const p = s.geom.attributes.position;
  let vertex = f.a, best = Infinity;
  for (const v of [f.a, f.b, f.c]) {
    const d = new THREE.Vector3().fromBufferAttribute(p, v).distanceToSquared(hit.point);
    if (d < best) { best = d; vertex = v; }
  }
  const shown = new THREE.Vector3().fromBufferAttribute(p, vertex);
  const truePos = new THREE.Vector3(s.positions[3 * vertex], s.positions[3 * vertex + 1], s.positions[3 * vertex + 2]);
  const normal = camera.getWorldDirection(new THREE.Vector3());
  drags.set(ev.pointerId, { hand, vertex, shown, truePos, normal, depth: 0, press: ev.shiftKey, offset: new THREE.Vector3() });
  sendHand(drags.get(ev.pointerId), true);
}, { capture: true });

canvas.addEventListener('pointermove', (ev) => {
  const d = drags.get(ev.pointerId);
  if (!d) return;
  raycaster.setFromCamera(ndc(ev), camera);
  const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(d.normal, d.shown);
  const at = raycaster.ray.intersectPlane(plane, new THREE.Vector3());
  if (!at) return;
  d.offset.copy(at).sub(d.shown).divideScalar(state.scale > 0 ? state.scale : 1);
  sendHand(d, true);
});

function endDrag(ev) {
  const d = drags.get(ev.pointerId);
  if (!d) return;
  drags.delete(ev.pointerId);
  sendHand(d, false);
  if (drags.size === 0) controls.enabled = true;
}
canvas.addEventListener('pointerup', endDrag);
canvas.addEventListener('pointercancel', endDrag);
canvas.addEventListener('contextmenu', (ev) => ev.preventDefault());
canvas.addEventListener('wheel', (ev) => {
  if (drags.size === 0) return;
  ev.preventDefault();
  ev.stopImmediatePropagation();
  for (const d of drags.values()) {
    d.depth += Math.sign(ev.deltaY) * 0.005 * state.diag;
    sendHand(d, true);
  }
}, { capture: true, passive: false });

function handTarget(d) {
  return d.truePos.clone().add(d.offset).addScaledVector(d.normal, d.depth);
}

function sendHand(d, active) {
  const p = handTarget(d);
  sendTarget(d.hand, [p.x, p.y, p.z], !d.press, active);
}

// One hand message; its time is kept until a frame shows the haptic loop read it (latency).
function sendTarget(hand, position, button, active) {
  if (!ws || ws.readyState !== 1) return;
  handSeq += 1;
  ws.send(JSON.stringify({ type: 'hand', hand, active, button, position, seq: handSeq }));
  pending.push([performance.now(), handSeq, hand]);
  if (pending.length > 1000) pending.shift();
  state.lastTarget = position;
}

// Drives a hand without a pointer (scripts, the console, the benchmark): grab at `position`
// (m, part frame) or move there; `release` lets go.
state.drive = (hand, position, button = true) => sendTarget(hand, position, button, true);
state.release = (hand) => sendTarget(hand, state.lastTarget || [0, 0, 0], true, false);

$('scale').addEventListener('change', (ev) => {
  const v = Number(ev.target.value);
  if (Number.isFinite(v) && v >= 0) state.scale = v; else ev.target.value = String(state.scale);
  state.dirty = true;
});
$('colour').addEventListener('change', (ev) => { state.colour = ev.target.value; state.dirty = true; askFields(); });

// Helpers for tests and the console: where a vertex is drawn on the screen (CSS pixels), and the
// vertex nearest a point (m, part frame).
state.screenOf = (space, vertex) => {
  const s = state.spaces[space];
  camera.updateMatrixWorld();
  const v = new THREE.Vector3().fromBufferAttribute(s.geom.attributes.position, vertex).project(camera);
  const r = canvas.getBoundingClientRect();
  return [r.left + ((v.x + 1) / 2) * r.width, r.top + ((1 - v.y) / 2) * r.height];
};
state.nearestVertex = (space, p) => {
  const s = state.spaces[space];
  let best = -1, bd = Infinity;
  for (let i = 0; i < s.vertices; i++) {
    const d = (s.rest[3 * i] - p[0]) ** 2 + (s.rest[3 * i + 1] - p[1]) ** 2 + (s.rest[3 * i + 2] - p[2]) ** 2;
    if (d < bd) { bd = d; best = i; }
  }
  return best;
};

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

function loop() {
  // The part is redrawn when something changed (a frame, its stress, the scale, the colouring),
  // not at every animation frame: 19.5k vertices' positions and colours cost the page's time.
  if (state.mode) animateMode();
  else if (state.dirty && state.spaces[state.active]) {
    draw(state.spaces[state.active]);
    state.dirty = false;
    state.drawTimes = (state.drawTimes || []).concat(performance.now()).slice(-60);
  }
  controls.update();
  renderer.render(scene, camera);
  if (state.meshesIn && !state.ready && state.frames > 0) state.ready = true;
  requestAnimationFrame(loop);
}
connect();
loop();
