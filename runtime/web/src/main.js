// The ves view page: draws what the server's runtime computes and is its device. The mouse ray
// picks a surface vertex; its drag moves a hand in true units; the server's haptic loop couples
// the hand to the part and sends back frames (the elastic displacement, f32, and the pose) and
// a status (JSON). Only the drawing is magnified, by the deformation scale.
import * as THREE from 'three';
import { OrbitControls } from 'three/examples/jsm/controls/OrbitControls.js';
import { KINDS, ProtocolError, decode, helloMismatch, kindOf } from './protocol.js';
import { fieldOf, REST_FORCE } from './field.js';
import { gradient, sequential } from './colours.js';
import { label, plain } from './units.js';
import * as views from './camera.js';
import * as capture from './capture.js';
import { setupPanel } from './setup.js';

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
// Lit from over the viewer's shoulder whatever the view: the light rides with the camera.
const sunTarget = new THREE.Object3D();
sunTarget.position.set(0, 0, -1);
sun.position.set(0.5, 1, 0.2);
sun.target = sunTarget;
camera.add(sun, sunTarget);
scene.add(camera);
const controls = new OrbitControls(camera, canvas);
controls.enableDamping = false;

/** The automatic scale draws the largest displacement since the part was last at rest at this
 * fraction of the part's bounding-box diagonal, magnifying at most AUTO_CAP times what the
 * device's full force at the most compliant point would need (numerical motion of a part at
 * rest is never blown up). */
const AUTO_FRACTION = 0.08;
const AUTO_CAP = 10;

// Everything the page knows, open to tests and to the console.
const state = {
  ready: false, connected: false, reconnects: 0, hello: null, spaces: [], active: 0, frames: 0,
  framesSkipped: 0, lastSeq: -1, status: null, scale: 1, scaleAuto: true, autoScale: 1,
  colour: 'displacement', units: 'si', locked: null, mode: null,
  loadCase: null, // the static load case shown instead of the live part (see showLoad)
  loadWanted: null, // the one asked for, until it comes
  framesPerSecond: 0, legend: null, probe: null, notes: [],
  latency: [], // ms from a pointer event to the first frame computed after the server got it
};
window.ves = state;
// Tests' own sockets read the kind of what they receive as the page does.
state.kindOf = kindOf;

let ws;
let retry = 0;
const pending = []; // [time sent, hand message sequence, hand] awaiting a frame that reflects them
let handSeq = 0;

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => { state.connected = true; retry = 0; $('conn').textContent = 'connected'; };
  ws.onclose = () => {
    state.connected = false; state.ready = false; state.meshesIn = false;
    if (state.refused) return; // the server speaks another protocol: a reload, not a retry
    for (const d of drags.values()) d.ended = true;
    drags.clear();
    controls.enabled = true;
    // Back off to one try every 5 s: a restarted server is found again without a reload.
    document.body.classList.add('stale');
    $('handinfo').textContent = '';
    $('warn').textContent = 'the server is gone: what you see is no longer live';
    const wait = Math.min(5000, 250 * 2 ** retry++);
    $('conn').textContent = `disconnected — trying again in ${(wait / 1000).toFixed(1)} s`;
    setTimeout(connect, wait);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') onText(JSON.parse(ev.data));
    else onBinary(ev.data);
  };
}

// A server of another protocol version (updated while this page was open): said once, and the
// page stops listening to it.
function refuse(why) {
  state.refused = why;
  $('warn').textContent = why;
  $('conn').textContent = 'refused';
  document.body.classList.add('stale');
  ws.close();
}

function onText(msg) {
  if (msg.type === 'hello') {
    const mismatch = helloMismatch(msg);
    if (mismatch) { refuse(mismatch); return; }
    const again = state.hello !== null;
    const samePart = again && state.hello.name === msg.name;
    if (again) { state.reconnects += 1; clearSpaces(); clearHands(); }
    document.body.classList.remove('stale');
    state.hello = msg;
    state.lastSeq = -1;
    state.active = 0;
    state.keepView = samePart;
    state.episodePeak = 0;
    state.framesAtHello = state.frames;
    $('title').textContent = `VES view — ${msg.name}`;
    showLimit();
    if (msg.spaces.length) buildModeList(msg.spaces[0]); else $('modes').textContent = '';
    hideLoad();
    buildLoadList(msg.spaces[0]);
    setup.hello(msg);
    for (const o of $('colour').options) o.disabled = o.value !== 'displacement' && !msg.spaces.some((s) => s.has_stress);
    if (msg.yield_strength == null) $('colour').querySelector('option[value=safety]').disabled = true;
    if ($('colour').selectedOptions[0].disabled) { $('colour').value = 'displacement'; state.colour = 'displacement'; }
    askFields();
  } else if (msg.type === 'status') {
    state.status = msg;
    setup.computing(msg.computing, msg.checking);
    showStatus(msg);
  } else if (msg.type === 'load_error') {
    if (state.loadWanted) hideLoad();
    $('loadnote').textContent = `the load case could not be read: ${msg.message}`;
  } else if (msg.type === 'progress' || msg.type === 'computed' || msg.type === 'checked' || msg.type === 'compute_error') {
    state.notes.push(msg);
    if (state.notes.length > 200) state.notes.shift();
    setup.note(msg);
  }
}

function showLimit() {
  const h = state.hello;
  $('limit').textContent = `device force limit ${plain(h.max_force)} N · coupling ${label(h.stiffness, 'stiffness', state.units)}`
    + (h.free_body ? ` · free body, gravity ${plain(Math.hypot(...(h.gravity || [0, 0, 0])))} m/s²` : '');
}

function onBinary(buf) {
  let got;
  try {
    got = decode(buf);
  } catch (e) {
    if (!(e instanceof ProtocolError)) throw e;
    if (e.foreign) refuse(e.message); else $('warn').textContent = `dropped ${e.message}`;
    return;
  }
  const { kind, message } = got;
  if (kind === KINDS.MESH) addSpace(message);
  else if (kind === KINDS.FRAME) onFrame(message);
  else if (kind === KINDS.MODE) startMode(message);
  else if (kind === KINDS.STRESS) onStress(message);
  else if (kind === KINDS.LOAD) onLoad(message);
}

function clearSpaces() {
  lightFaces('held', [], 0);
  lightFaces('hover', [], 0);
  for (const s of state.spaces) {
    if (!s) continue;
    for (const o of [s.mesh, s.box, s.supports]) if (o) { scene.remove(o); o.geometry && o.geometry.dispose(); }
  }
  state.spaces = [];
  state.mode = null;
}

function addSpace(m) {
  const geom = new THREE.BufferGeometry();
  geom.setAttribute('position', new THREE.BufferAttribute(new Float32Array(m.rest), 3).setUsage(THREE.DynamicDrawUsage));
  const col = new Float32Array(3 * m.vertices).fill(0.8);
  geom.setAttribute('color', new THREE.BufferAttribute(col, 3).setUsage(THREE.DynamicDrawUsage));
  geom.setIndex(new THREE.BufferAttribute(m.triangles, 1));
  geom.computeBoundingBox();
  // Flat shading: an FE surface has sharp edges that averaged normals would smear.
  const mat = new THREE.MeshStandardMaterial({ vertexColors: true, roughness: 0.6, metalness: 0.1, side: THREE.DoubleSide, flatShading: true });
  const mesh = new THREE.Mesh(geom, mat);
  mesh.visible = m.space === state.active;
  scene.add(mesh);
  const info = state.hello.spaces[m.space];
  let box = null;
  if (info.voi) {
    box = new THREE.Box3Helper(new THREE.Box3(new THREE.Vector3(...info.voi[0]), new THREE.Vector3(...info.voi[1])), 0x5a7a8c);
    scene.add(box);
  }
  // Supports: the vertices with a fixed component, as green points over the part.
  const fixedIdx = [];
  m.fixed.forEach((b, i) => { if (b) fixedIdx.push(i); });
  let supports = null;
  if (fixedIdx.length) {
    const g = new THREE.BufferGeometry();
    g.setAttribute('position', new THREE.BufferAttribute(new Float32Array(3 * fixedIdx.length), 3));
    supports = new THREE.Points(g, new THREE.PointsMaterial({ color: 0x3ddc84, size: 4, sizeAttenuation: false, depthTest: true }));
    supports.visible = mesh.visible && $('showsupports').checked;
    scene.add(supports);
  }
  const size = geom.boundingBox.getSize(new THREE.Vector3()).length();
  state.spaces[m.space] = {
    ...m, geom, mesh, box, supports, fixedIdx, size,
    u: new Float32Array(3 * m.vertices), umag: new Float32Array(m.vertices),
    truePos: new Float32Array(m.rest), pose: null, vm: null, p1: null,
  };
  if (m.space === 0) {
    // The same part again (a reconnect): the user's view stays; another part is framed.
    const same = state.keepView && state.diag && Math.abs(size - state.diag) <= 1e-6 * size;
    state.diag = size;
    state.autoScale = autoScale();
    if (!same) homeView();
  }
  highlightBoxes();
  if (m.space === 0) lightFaces('held', setup.heldFaces(), 0x3ddc84);
  // Ready once every space is in and a frame has been drawn (see loop).
  if (state.spaces.filter(Boolean).length === state.hello.spaces.length) state.meshesIn = true;
}

/** Rounded down to 1, 2 or 5 times a power of ten, so the number can be read; never below 1. */
function nice(k) {
  if (!(k > 1) || !Number.isFinite(k)) return 1;
  const p = 10 ** Math.floor(Math.log10(k));
  return [5, 2, 1].map((m) => m * p).find((v) => v <= k);
}

/** The automatic scale at rest: the device's full force at the most compliant surface point
 * would draw AUTO_FRACTION of the part's size. */
function autoScale() {
  const c = state.hello.spaces[0].largest_compliance;
  return nice((AUTO_FRACTION * state.diag) / (state.hello.max_force * c));
}

function highlightBoxes() {
  state.spaces.forEach((s, i) => {
    if (!s || !s.box) return;
    const on = i === state.active;
    s.box.material.color.set(on ? 0xffd45e : 0x5a7a8c);
    s.box.material.opacity = on ? 1 : 0.5;
    s.box.material.transparent = !on;
  });
}

function onFrame(f) {
  const s = state.spaces[f.space];
  if (!s) return;
  if (state.lastSeq >= 0 && f.seq > state.lastSeq + 1) state.framesSkipped += f.seq - state.lastSeq - 1;
  state.lastSeq = f.seq;
  state.frames += 1;
  // Frames keep coming at rest: one that moves no drawn point by a millionth of the part (nor
  // the pose, the alarm or the peak) is not redrawn, so a part at rest costs the page nothing.
  const switched = f.space !== state.active;
  let change = 0;
  for (let i = 0; i < f.u.length; i++) change = Math.max(change, Math.abs(f.u[i] - s.u[i]));
  const still = !switched && change * (state.drawnScale || 0) <= 1e-6 * (state.diag || 0)
    && (!s.pose || !f.pose || f.pose.every((x, i) => x === s.pose[i]))
    && s.alarm === f.alarm && s.peak && s.peak.vertex === f.peakVertex && s.peak.vonMises === f.peakVonMises;
  if (f.space !== state.active) {
    for (const t of state.spaces) if (t) { t.mesh.visible = false; if (t.supports) t.supports.visible = false; }
    state.active = f.space;
    buildModeList(state.hello.spaces[f.space]);
    hideLoad();
    buildLoadList(state.hello.spaces[f.space]);
    highlightBoxes();
  }
  s.mesh.visible = true;
  if (s.supports) s.supports.visible = $('showsupports').checked;
  s.u.set(f.u);
  for (let i = 0; i < s.vertices; i++) s.umag[i] = Math.hypot(f.u[3 * i], f.u[3 * i + 1], f.u[3 * i + 2]);
  s.pose = f.pose;
  s.alarm = f.alarm;
  s.peak = { vertex: f.peakVertex, vonMises: f.peakVonMises };
  s.frameTime = f.time;
  // A load case shown stays as it is: the live frames are kept for when it is put away.
  if (!still && !state.loadCase) state.dirty = true;
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

function restLevel(s) {
  const c = state.hello.spaces[state.active].largest_compliance;
  return Math.max(c > 0 ? c * REST_FORCE : 0, 1e-12 * s.size);
}

// Positions: rest + k·u, posed for a free body (x + R(rest + k·u − c)). The drawn ones use the
// deformation scale; the true ones (k = 1) are where the hands act.
function place(s, k, out) {
  const q = s.pose;
  const u = s.u, r = s.rest;
  if (!q) {
    for (let i = 0; i < out.length; i++) out[i] = r[i] + k * u[i];
    return;
  }
  const m = new THREE.Matrix4().makeRotationFromQuaternion(new THREE.Quaternion(q[4], q[5], q[6], q[3])).elements;
  const c = state.hello.center || [0, 0, 0];
  for (let i = 0; i < out.length; i += 3) {
    const x = r[i] + k * u[i] - c[0], y = r[i + 1] + k * u[i + 1] - c[1], z = r[i + 2] + k * u[i + 2] - c[2];
    out[i] = q[0] + m[0] * x + m[4] * y + m[8] * z;
    out[i + 1] = q[1] + m[1] * x + m[5] * y + m[9] * z;
    out[i + 2] = q[2] + m[2] * x + m[6] * y + m[10] * z;
  }
}

// The automatic scale follows the largest displacement since the part was last at rest (a load
// episode): it only comes down while the load grows, so a pull is drawn at a steady size and
// the ringing after a release shrinks as it really does.
function drawScale(s) {
  let umax = 0;
  for (let i = 0; i < s.vertices; i++) umax = Math.max(umax, s.umag[i]);
  if (!(umax > restLevel(s))) state.episodePeak = 0;
  else state.episodePeak = Math.max(state.episodePeak || 0, umax);
  let k = state.scale;
  if (state.scaleAuto) {
    k = state.episodePeak > 0 ? Math.min(AUTO_CAP * state.autoScale, nice((AUTO_FRACTION * s.size) / state.episodePeak)) : state.autoScale;
    $('scale').value = String(k);
  }
  state.drawnScale = k;
  $('scaleshown').textContent = `×${plain(k)}${state.scaleAuto ? ', auto' : ''}`;
  return k;
}

function draw(s) {
  if (state.loadCase && state.loadCase.space === state.active) { drawLoad(s, state.loadCase); return; }
  const k = drawScale(s);
  place(s, k, s.geom.attributes.position.array);
  place(s, 1, s.truePos);
  s.drawnPose = s.pose; // what the drawing used (a newer frame may have come since)
  s.geom.attributes.position.needsUpdate = true;
  s.geom.computeBoundingSphere();
  if (s.supports) {
    const p = s.supports.geometry.attributes.position.array, d = s.geom.attributes.position.array;
    s.fixedIdx.forEach((v, j) => { p[3 * j] = d[3 * v]; p[3 * j + 1] = d[3 * v + 1]; p[3 * j + 2] = d[3 * v + 2]; });
    s.supports.geometry.attributes.position.needsUpdate = true;
    s.supports.geometry.computeBoundingSphere();
  }
  colour(s);
}

function colour(s) {
  const locked = state.locked && state.locked.colour === state.colour ? state.locked : null;
  const f = fieldOf(state.colour, s, { hello: state.hello, restLevel: restLevel(s), units: state.units, locked, episode: episodeRange(s) });
  state.field = f;
  const c = s.geom.attributes.color.array;
  for (let i = 0; i < s.vertices; i++) {
    const [r, g, b] = f.colourOf(i);
    c[3 * i] = r; c[3 * i + 1] = g; c[3 * i + 2] = b;
  }
  s.geom.attributes.color.needsUpdate = true;
  const caption = `deformation drawn ${$('scaleshown').textContent}${f.summary ? ` · ${f.summary}` : ''}`;
  state.legend = { title: f.title, scale: f.scale, ticks: f.ticks, caption, atRest: f.atRest, lo: f.lo, hi: f.hi };
  $('legendtitle').textContent = f.title;
  $('bar').style.background = gradient(f.scale);
  [$('lo').textContent, $('mid').textContent, $('hi').textContent] = f.ticks;
  $('legendnote').textContent = f.summary || '';
  placeMarkers(s, f.markers);
  if (state.probe) showProbe(state.probe.vertex, state.probe.x, state.probe.y);
}

// The colour range keeps the largest values since the part was last at rest (per colouring), so
// a part ringing after a release does not look as loaded as it was.
function episodeRange(s) {
  if (!(state.episodePeak > 0)) { state.episodes = {}; return null; }
  state.episodes = state.episodes || {};
  return state.episodes[state.colour] || (state.episodes[state.colour] = { lo: 0, hi: 0 });
}

// Markers at the field's extremes: a dot on the part and its value beside it.
const markers = [];
function placeMarkers(s, list) {
  while (markers.length < list.length) {
    const dot = new THREE.Mesh(new THREE.SphereGeometry(1, 12, 8), new THREE.MeshBasicMaterial({ color: 0xffffff, depthTest: false }));
    dot.renderOrder = 2;
    const tag = document.createElement('div');
    tag.className = 'marker';
    document.body.appendChild(tag);
    scene.add(dot);
    markers.push({ dot, tag });
  }
  markers.forEach((m, i) => {
    const on = i < list.length && list[i].vertex >= 0 && $('showmarkers').checked;
    m.dot.visible = on;
    m.tag.style.display = on ? 'block' : 'none';
    if (!on) return;
    m.dot.position.fromBufferAttribute(s.geom.attributes.position, list[i].vertex);
    m.dot.scale.setScalar(0.006 * state.diag);
    m.vertex = list[i].vertex;
    m.tag.textContent = list[i].text;
  });
}

function placeTags() {
  for (const m of markers) {
    if (!m.dot.visible) continue;
    const [x, y] = screenOfPoint(m.dot.position);
    m.tag.style.left = `${x + 8}px`; m.tag.style.top = `${y - 8}px`;
  }
}

function screenOfPoint(p) {
  const v = p.clone().project(camera);
  const r = canvas.getBoundingClientRect();
  return [r.left + ((v.x + 1) / 2) * r.width, r.top + ((1 - v.y) / 2) * r.height];
}

function showStatus(m) {
  const sp = state.hello.spaces[m.space];
  if (!sp) { $('space').textContent = m.computing ? 'computing the basis…' : 'no basis yet: set the part up and compute'; return; }
  $('space').textContent = `space ${sp.name}${sp.voi ? ' (volume of interest, yellow box)' : ''} · ${sp.vertices} vertices · ${m.clients} client(s)`;
  // Times the part was actually redrawn (the loop below), over the last 60.
  const t = state.drawTimes || [];
  const fps = t.length > 1 ? (1000 * (t.length - 1)) / (t.at(-1) - t[0]) : 0;
  state.framesPerSecond = fps;
  $('rates').textContent = `haptic ${m.haptic_hz.toFixed(0)} Hz · visual ${m.visual_hz.toFixed(0)} Hz · drawn here ${fps.toFixed(0)} fps`;
  const u = state.units, min = state.hello.min_safety_factor, ys = state.hello.yield_strength;
  const lines = [];
  const warn = [];
  m.hands.forEach((h, i) => {
    updateHand(i, h);
    if (!h.active) return;
    const f = Math.hypot(...h.force);
    lines.push(`hand ${i + 1}: ${label(f, 'force', 'si')} on the part${h.clamped ? ' (device limit)' : ''}${h.button ? '' : ', pressing'}`
      + (h.von_mises > 0 ? ` · σvM ${label(h.von_mises, 'stress', u)} · σ1 ${label(h.principal_stress, 'stress', u)} · ε1 ${h.principal_strain.toExponential(2)}` : '')
      + (h.safety_factor != null && h.von_mises > 0 ? ` · safety ${plain(h.safety_factor)}` : ''));
    if (h.strain_exceeded) {
      warn.push(`hand ${i + 1}: surface strain ${(100 * h.strain).toPrecision(2)} % at the held point is past the linear model's limit of ${(100 * state.hello.strain_limit).toPrecision(2)} %: the result there is not valid`);
    }
    // The hand's own criterion; when only the whole part is below the minimum, the part's line says so.
    if (h.stress_exceeded && h.safety_factor != null && h.safety_factor < min) {
      warn.push(`hand ${i + 1}: at the held point von Mises ${label(h.von_mises, 'stress', u)}, safety factor ${plain(h.safety_factor)} below the minimum ${plain(min)} (yield ${label(ys, 'stress', u)})`);
    }
  });
  const s = state.spaces[m.space];
  if (m.alarm && s && s.peak && s.peak.vertex >= 0) {
    const p = Array.from(s.truePos.subarray(3 * s.peak.vertex, 3 * s.peak.vertex + 3)).map((v) => label(v, 'length', u)).join(', ');
    warn.push(`part: von Mises ${label(s.peak.vonMises, 'stress', u)} at (${p}), safety factor ${plain(ys / s.peak.vonMises)} below the minimum ${plain(min)}: it would yield there`);
  } else if (m.alarm) {
    warn.push(`part: safety factor below the minimum ${plain(min)}: it would yield`);
  }
  $('handinfo').textContent = lines.join(' · ');
  $('warn').textContent = warn.join(' · ');
}

function clearHands() {
  for (const h of hands) {
    if (!h) continue;
    scene.remove(h.arrow, h.spring, h.ball);
    h.tag.remove();
  }
  hands.length = 0;
}

// Each hand: a ball at its true position (the device, under the cursor), a dashed spring to the
// held vertex as drawn, and an arrow of the force on the part at that vertex with its value.
const hands = [];
function updateHand(i, h) {
  const colourOf = i ? 0x5ee0ff : 0xffd45e;
  if (!hands[i]) {
    const arrow = new THREE.ArrowHelper(new THREE.Vector3(0, 0, 1), new THREE.Vector3(), 1, colourOf);
    const tag = document.createElement('div');
    tag.className = 'forcelabel';
    tag.style.color = `#${colourOf.toString(16)}`;
    document.body.appendChild(tag);
    const g = new THREE.BufferGeometry().setFromPoints([new THREE.Vector3(), new THREE.Vector3()]);
    const spring = new THREE.Line(g, new THREE.LineDashedMaterial({ color: colourOf, dashSize: 0.004 * state.diag, gapSize: 0.003 * state.diag }));
    const ball = new THREE.Mesh(new THREE.SphereGeometry(0.006 * state.diag, 16, 12), new THREE.MeshBasicMaterial({ color: colourOf }));
    scene.add(arrow, spring, ball);
    hands[i] = { arrow, tag, spring, ball };
  }
  const { arrow, tag, spring, ball } = hands[i];
  const s = state.spaces[state.active];
  const drawnAt = s && h.vertex < s.vertices
    ? new THREE.Vector3().fromBufferAttribute(s.geom.attributes.position, h.vertex) : new THREE.Vector3(...h.vertex_position);
  spring.visible = ball.visible = h.active;
  if (h.active) {
    ball.position.set(...h.target);
    spring.geometry.setFromPoints([drawnAt, ball.position]);
    spring.computeLineDistances();
  }
  const f = new THREE.Vector3(...h.force).negate(); // the device's force is the part's, reversed
  const mag = f.length();
  arrow.visible = h.active && h.contact && mag > 0;
  tag.style.display = arrow.visible ? 'block' : 'none';
  if (!arrow.visible || !state.diag) return;
  const len = Math.max(0.02, Math.min(1, mag / state.hello.max_force)) * 0.25 * state.diag;
  arrow.position.copy(drawnAt);
  arrow.setDirection(f.clone().normalize());
  arrow.setLength(len, 0.25 * len, 0.12 * len);
  const [x, y] = screenOfPoint(drawnAt.clone().addScaledVector(f.normalize(), len));
  tag.style.left = `${x + 8}px`;
  tag.style.top = `${y - 8}px`;
  tag.textContent = `${label(mag, 'force', 'si')} on the part`;
}

// Mode browser: the frequencies of the active space; a click animates that mode's shape.
function buildModeList(space) {
  const box = $('modes');
  box.textContent = '';
  space.frequencies_hz.forEach((f, j) => {
    const b = document.createElement('button');
    b.textContent = `mode ${j + 1}: ${f.toPrecision(5)} Hz`;
    b.onclick = () => {
      if (state.mode && state.mode.mode === j) { stopMode(); return; }
      hideLoad();
      ws.send(JSON.stringify({ type: 'mode', space: state.active, index: j }));
    };
    box.appendChild(b);
  });
}

function stopMode() {
  state.mode = null;
  state.dirty = true;
  for (const b of $('modes').children) b.classList.remove('on');
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
  if (!s) { state.mode = null; return; }
  const amp = 0.08 * state.diag * Math.sin((2 * Math.PI * (performance.now() - m.start)) / 1500);
  const p = s.geom.attributes.position.array;
  const c = s.geom.attributes.color.array;
  for (let i = 0; i < s.vertices; i++) {
    const mag = Math.hypot(m.phi[3 * i], m.phi[3 * i + 1], m.phi[3 * i + 2]);
    const [r, g, b] = sequential(mag);
    for (let k = 0; k < 3; k++) p[3 * i + k] = s.rest[3 * i + k] + amp * m.phi[3 * i + k];
    c[3 * i] = r; c[3 * i + 1] = g; c[3 * i + 2] = b;
  }
  s.geom.attributes.position.needsUpdate = true;
  s.geom.attributes.color.needsUpdate = true;
  s.geom.computeBoundingSphere();
  $('legendtitle').textContent = `mode ${m.mode + 1}, ${m.frequency.toPrecision(5)} Hz: relative amplitude (shape only)`;
  $('bar').style.background = gradient('magnitude');
  $('lo').textContent = '0'; $('mid').textContent = '0.5'; $('hi').textContent = '1';
}

// Static load cases (the basis's `loads`): a select offers the active space's; choosing one asks
// the server for it (its displacement and von Mises stress, sent only then) and shows the part
// deformed by it and coloured by its stress instead of the live part. The hands are let go and
// off meanwhile: what is drawn is the static answer to that load alone, which a hand's pull
// would not change; "none" brings the live part back.
function buildLoadList(space) {
  const sel = $('loadcase');
  while (sel.options.length > 1) sel.remove(1);
  const cases = (space && space.loads) || [];
  cases.forEach((c, i) => {
    const o = document.createElement('option');
    o.value = String(i);
    o.textContent = `${c.name}: ${c.kind}, ${label(Math.hypot(...c.total_force), 'force', 'si')}`;
    sel.appendChild(o);
  });
  sel.value = '';
  $('loadbox').hidden = !cases.length && !(space && space.loads_error);
  $('loadnote').textContent = space && space.loads_error ? `load cases not offered: ${space.loads_error}` : '';
}

function chooseLoad(value) {
  if (value === '' || value == null) { hideLoad(); state.dirty = true; return; }
  const i = Number(value);
  const info = state.hello.spaces[state.active].loads[i];
  if (!info || !ws || ws.readyState !== 1) return;
  for (const key of [...drags.keys()]) endDrag(key);
  for (const h of [0, 1]) if (state.status && state.status.hands[h].active && state.status.hands[h].owner === state.hello.client) state.release(h);
  stopMode();
  hideProbe();
  state.loadWanted = { space: state.active, index: i };
  $('loadcase').value = String(i);
  $('loadnote').textContent = `reading load case ${info.name}…`;
  ws.send(JSON.stringify({ type: 'load', space: state.active, name: info.name }));
}

function onLoad(m) {
  const w = state.loadWanted;
  if (!w || w.space !== m.space || w.index !== m.index || !state.spaces[m.space]) return;
  state.loadWanted = null;
  state.loadCase = { ...m, ...state.hello.spaces[m.space].loads[m.index] };
  // A load case is coloured by its von Mises stress (the legend says so): no other choice shown.
  $('colour').disabled = true;
  $('colourbox').hidden = $('lockbox').hidden = true;
  state.dirty = true;
}

function hideLoad() {
  const was = state.loadCase || state.loadWanted;
  state.loadCase = null;
  state.loadWanted = null;
  $('colour').disabled = false;
  $('colourbox').hidden = $('lockbox').hidden = false;
  if ($('loadcase').value !== '') $('loadcase').value = '';
  if (was) { $('loadnote').textContent = ''; state.dirty = true; }
}

// A load case drawn: rest + k·u with the page's scale (automatic: the case's largest
// displacement at AUTO_FRACTION of the part), coloured by its von Mises stress from zero to the
// case's largest (the whole part's, from the file).
function drawLoad(s, c) {
  const k = state.scaleAuto ? nice((AUTO_FRACTION * s.size) / c.maxDisplacement) : state.scale;
  if (state.scaleAuto) $('scale').value = String(k);
  state.drawnScale = k;
  $('scaleshown').textContent = `×${plain(k)}${state.scaleAuto ? ', auto' : ''}`;
  const p = s.geom.attributes.position.array;
  for (let i = 0; i < p.length; i++) p[i] = s.rest[i] + k * c.u[i];
  s.truePos.set(s.rest);
  for (let i = 0; i < p.length; i++) s.truePos[i] += c.u[i];
  s.geom.attributes.position.needsUpdate = true;
  s.geom.computeBoundingSphere();
  if (s.supports) {
    const q = s.supports.geometry.attributes.position.array;
    s.fixedIdx.forEach((v, j) => { q[3 * j] = p[3 * v]; q[3 * j + 1] = p[3 * v + 1]; q[3 * j + 2] = p[3 * v + 2]; });
    s.supports.geometry.attributes.position.needsUpdate = true;
    s.supports.geometry.computeBoundingSphere();
  }
  const u = state.units, hi = c.maxVonMises, ys = state.hello.yield_strength, min = state.hello.min_safety_factor;
  const span = hi > 0 ? hi : 1;
  const col = s.geom.attributes.color.array;
  let top = -1;
  for (let i = 0; i < s.vertices; i++) {
    const [r, g, b] = sequential(c.vm[i] / span);
    col[3 * i] = r; col[3 * i + 1] = g; col[3 * i + 2] = b;
    if (top < 0 || c.vm[i] > c.vm[top]) top = i;
  }
  s.geom.attributes.color.needsUpdate = true;
  const w = (v) => label(v, 'stress', u);
  const sf = ys && hi > 0 ? ys / hi : null;
  const safety = sf === null ? '' : ` · safety factor ${plain(sf)}${sf < min ? ` below the minimum ${plain(min)}: it would yield` : ''} (yield ${w(ys)})`;
  const title = `von Mises stress, load case ${c.name} (static)`;
  const summary = `max ${w(hi)}${safety}`;
  state.field = { quantity: 'stress', valueAt: (i) => c.vm[i] };
  const caption = `load case ${c.name}: ${c.kind}, ${label(Math.hypot(...c.total_force), 'force', 'si')} · deformation drawn ${$('scaleshown').textContent} · ${summary}`;
  const ticks = [w(0), w(hi / 2), w(hi)];
  state.legend = { title, scale: 'magnitude', ticks, caption, atRest: false, lo: 0, hi, load: c.name };
  $('legendtitle').textContent = title;
  $('bar').style.background = gradient('magnitude');
  [$('lo').textContent, $('mid').textContent, $('hi').textContent] = ticks;
  $('legendnote').textContent = summary;
  placeMarkers(s, [{ vertex: top, text: `max on the surface ${w(c.vm[top])}` }]);
  $('loadnote').innerHTML = '';
  const b = document.createElement('b');
  b.textContent = 'Hands are off while a load case is shown';
  $('loadnote').append(`${c.name}: ${c.kind}, total ${label(Math.hypot(...c.total_force), 'force', 'si')}, largest displacement `
    + `${label(c.maxDisplacement, 'length', u)} drawn ×${plain(k)}${state.scaleAuto ? ` (auto: the largest at ${Math.round(100 * AUTO_FRACTION)} % of the part's size)` : ''}. `, b,
  ' (a drag orbits); choose "none" to pull the part again.');
}
state.chooseLoad = chooseLoad;

// Hands: a pointer that goes down on the part drives a hand (left or touch: hand 1; right, a
// second touch, or the right button pressed while the left holds: hand 2). The drag moves the
// hand in the plane facing the camera through the picked vertex, in true units whatever the
// deformation scale; the wheel moves it along the view ray; with Shift the hand presses into
// the part along the view ray, the further the harder.
const drags = new Map(); // key (pointer id, or id:2 for a chorded right button) -> drag
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

/** The vertex under the pointer (the nearest corner of the hit triangle), or null. */
function pick(ev) {
  const s = state.spaces[state.active];
  if (!s) return null;
  camera.updateMatrixWorld();
  raycaster.setFromCamera(ndc(ev), camera);
  const hit = raycaster.intersectObject(s.mesh)[0];
  if (!hit) return null;
  const p = s.geom.attributes.position;
  let vertex = hit.face.a, best = Infinity;
  for (const v of [hit.face.a, hit.face.b, hit.face.c]) {
    const d = new THREE.Vector3().fromBufferAttribute(p, v).distanceToSquared(hit.point);
    if (d < best) { best = d; vertex = v; }
  }
  return { s, vertex };
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

// The set-up panel asks for one click on the part (a face to hold): that click is not a grab.
let picking = null;
const setup = setupPanel((m) => { if (ws && ws.readyState === 1) ws.send(JSON.stringify(m)); }, (done) => { picking = done; }, faceMode);
state.setup = setup;

// Faces: each CAD face's triangles, lit when the cursor is over it (yellow) or held (green).
let facePick = null; // the set-up panel's callback while picking faces
const faceLights = { hover: null, held: null };
function faceOverlay(s, tags, colour) {
  const want = new Set(tags);
  const idx = [];
  for (let t = 0; t < s.faces.length; t++) if (want.has(s.faces[t])) idx.push(s.triangles[3 * t], s.triangles[3 * t + 1], s.triangles[3 * t + 2]);
  const g = new THREE.BufferGeometry();
  g.setAttribute('position', s.geom.attributes.position);
  g.setIndex(idx);
  const m = new THREE.Mesh(g, new THREE.MeshBasicMaterial({ color: colour, transparent: true, opacity: 0.55, side: THREE.DoubleSide,
    polygonOffset: true, polygonOffsetFactor: -2, polygonOffsetUnits: -2, depthWrite: false }));
  m.renderOrder = 1;
  return m;
}
function lightFaces(kind, tags, colour) {
  const s = state.spaces[0];
  if (faceLights[kind]) { scene.remove(faceLights[kind]); faceLights[kind].geometry.setIndex(null); faceLights[kind] = null; }
  if (!s || !s.faces || !tags.length) return;
  faceLights[kind] = faceOverlay(s, tags, colour);
  scene.add(faceLights[kind]);
}
function faceMode(on, onClick, held) {
  facePick = on ? onClick : null;
  lightFaces('held', held || [], 0x3ddc84);
  if (!on) { lightFaces('hover', [], 0); state.hoverFace = null; }
}
/** The CAD face under the pointer (space 0), or null. */
function faceAt(ev) {
  const s = state.spaces[0];
  if (!s || !s.faces || state.active !== 0) return null;
  camera.updateMatrixWorld();
  raycaster.setFromCamera(ndc(ev), camera);
  const hit = raycaster.intersectObject(s.mesh)[0];
  return hit ? s.faces[hit.faceIndex] : null;
}
state.faceAt = (x, y) => faceAt({ clientX: x, clientY: y });

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
    camera.updateMatrixWorld();
    raycaster.setFromCamera(ndc(ev), camera);
    const hit = raycaster.intersectObject(s.mesh)[0];
    if (!hit) return;
    ev.stopImmediatePropagation();
    const done = picking;
    picking = null;
    // The part frame's point: the rest position of the hit triangle's nearest corner.
    const p = s.geom.attributes.position;
    const v = [hit.face.a, hit.face.b, hit.face.c].reduce((a, b) => (new THREE.Vector3().fromBufferAttribute(p, a).distanceToSquared(hit.point)
      <= new THREE.Vector3().fromBufferAttribute(p, b).distanceToSquared(hit.point) ? a : b));
    done({ point: new THREE.Vector3(s.rest[3 * v], s.rest[3 * v + 1], s.rest[3 * v + 2]), normal: hit.face.normal.clone() });
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
  if (facePick) {
    const tag = faceAt(ev);
    if (tag !== state.hoverFace) { state.hoverFace = tag; lightFaces('hover', tag === null ? [] : [tag], 0xffd45e); }
    $('probe').style.display = tag === null ? 'none' : 'block';
    if (tag !== null) { $('probe').textContent = `face ${tag}`; $('probe').style.left = `${ev.clientX + 14}px`; $('probe').style.top = `${ev.clientY + 22}px`; }
    return;
  }
  if (!drags.size) { probe(ev); return; }
  for (const [key, d] of drags) {
    if (d.frozen || !ofPointer(key, ev)) continue;
    raycaster.setFromCamera(ndc(ev), camera);
    const plane = new THREE.Plane().setFromNormalAndCoplanarPoint(d.normal, d.shown);
    const at = raycaster.ray.intersectPlane(plane, new THREE.Vector3());
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
canvas.addEventListener('pointerleave', () => { if (!drags.size) hideProbe(); });
canvas.addEventListener('contextmenu', (ev) => ev.preventDefault());
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

function handTarget(d) {
  if (d.press) return d.truePos.clone().addScaledVector(d.normal, Math.min(d.depth + d.offset.length(), d.maxPress));
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

// The probe: the coloured value under the cursor.
let probeQueued = null;
function probe(ev) {
  if (!state.ready || state.mode) return;
  if (probeQueued) { probeQueued = ev; return; }
  probeQueued = ev;
  requestAnimationFrame(() => {
    const e = probeQueued;
    probeQueued = null;
    const got = pick(e);
    if (!got) { hideProbe(); return; }
    state.probe = { vertex: got.vertex, x: e.clientX, y: e.clientY };
    showProbe(got.vertex, e.clientX, e.clientY);
  });
}

function showProbe(v, x, y) {
  const f = state.field, s = state.spaces[state.active];
  if (!f || !s || v >= s.vertices) return;
  const value = f.valueAt(v);
  const shown = f.quantity === 'ratio' ? (Number.isFinite(value) ? plain(value) : 'no stress') : label(value, f.quantity, state.units);
  // Coordinates to 1e-5 of the part's size: f32 round-off is not a position.
  const q = 1e-5 * state.diag;
  const at = Array.from(s.truePos.subarray(3 * v, 3 * v + 3)).map((c) => label(Math.round(c / q) * q, 'length', state.units)).join(', ');
  const tip = $('probe');
  tip.textContent = `${shown} · vertex ${v} at (${at})`;
  tip.style.left = `${x + 14}px`; tip.style.top = `${y + 22}px`;
  tip.style.display = 'block';
  state.probe.text = tip.textContent;
}

function hideProbe() { state.probe = null; $('probe').style.display = 'none'; }

// Views: home, fit, along the axes. The fit takes what is drawn now (deformed, posed).
function homeView() { fitView(views.HOME); }
function fitView(direction) {
  const s = state.spaces[state.active];
  if (!s) return;
  s.geom.computeBoundingSphere();
  const dir = direction || camera.getWorldDirection(new THREE.Vector3());
  views.fit(camera, controls, s.geom.boundingSphere, dir);
}
function resetSimulation() {
  for (const key of [...drags.keys()]) endDrag(key);
  if (ws && ws.readyState === 1) ws.send(JSON.stringify({ type: 'reset' }));
}
state.fit = () => fitView();
state.home = homeView;
state.viewAlong = (axis, sign) => fitView(views.along(axis, sign));
state.reset = resetSimulation;
state.setScale = (k) => {
  state.scaleAuto = k === 'auto';
  if (!state.scaleAuto) state.scale = k;
  $('scaleauto').checked = state.scaleAuto;
  $('scale').value = String(state.scaleAuto ? state.autoScale : k);
  state.dirty = true;
};

$('fit').onclick = () => { if (!drags.size) fitView(); };
$('home').onclick = () => { if (!drags.size) homeView(); };
$('resetsim').onclick = resetSimulation;
for (const b of document.querySelectorAll('[data-axis]')) b.onclick = () => state.viewAlong(b.dataset.axis, Number(b.dataset.sign));
// What the pictures carry besides the view: the labels drawn over it and the readout.
function overlay() {
  const labels = [...document.querySelectorAll('.forcelabel, .marker')]
    .filter((e) => e.style.display !== 'none' && e.textContent)
    .map((e) => ({ text: e.textContent, x: parseFloat(e.style.left) || 0, y: parseFloat(e.style.top) || 0, colour: getComputedStyle(e).color }));
  const warn = $('warn').textContent;
  return { labels, lines: [$('title').textContent, $('handinfo').textContent, warn], warn: Boolean(warn) };
}
$('shot').onclick = () => capture.screenshot(canvas, state.legend, state.hello ? state.hello.name : 'ves', overlay());
$('record').onclick = () => {
  try {
    const on = capture.toggleRecording(canvas, state.legend, state.hello ? state.hello.name : 'ves', overlay());
    $('record').textContent = on ? '■ stop' : '● record';
  } catch (e) { $('warn').textContent = e.message; }
};

window.addEventListener('keydown', (ev) => {
  if (ev.target instanceof HTMLInputElement || ev.target instanceof HTMLSelectElement || ev.ctrlKey || ev.metaKey || ev.altKey) return;
  const k = ev.key.length === 1 ? ev.key.toLowerCase() : ev.key;
  // The view stays while a hand is dragged: the drag plane is the camera's.
  const moving = ['f', 'h', 'Home', 'x', 'y', 'z'].includes(k);
  if (moving && drags.size) return;
  if (k === 'f') fitView();
  else if (k === 'h' || k === 'Home') homeView();
  else if (k === 'x' || k === 'y' || k === 'z') state.viewAlong(k, ev.shiftKey ? -1 : 1);
  else if (k === 'r') resetSimulation();
  else if (k === 'p') $('shot').click();
  else return;
  ev.preventDefault();
});

$('scale').addEventListener('change', (ev) => {
  const v = Number(ev.target.value);
  if (Number.isFinite(v) && v >= 0) state.setScale(v); else ev.target.value = String(state.drawnScale);
});
$('scaleauto').addEventListener('change', (ev) => state.setScale(ev.target.checked ? 'auto' : state.drawnScale));
$('loadcase').addEventListener('change', (ev) => chooseLoad(ev.target.value));
$('colour').addEventListener('change', (ev) => { state.colour = ev.target.value; state.dirty = true; askFields(); });
$('units').addEventListener('change', (ev) => { state.units = ev.target.value; state.dirty = true; if (state.hello) showLimit(); });
$('lock').addEventListener('change', (ev) => {
  const l = state.legend;
  state.locked = ev.target.checked && l && !l.atRest && Number.isFinite(l.lo) ? { colour: state.colour, lo: l.lo, hi: l.hi } : null;
  if (ev.target.checked && !state.locked) $('legendnote').textContent = 'nothing to lock: the part is at rest (lock while it is loaded, e.g. hold with the wheel)';
  ev.target.checked = state.locked !== null;
  state.dirty = true;
});
$('showsupports').addEventListener('change', () => { state.dirty = true; for (const s of state.spaces) if (s && s.supports) s.supports.visible = s.mesh.visible && $('showsupports').checked; });
$('showmarkers').addEventListener('change', () => { state.dirty = true; });

// Panels fold to their title; on a small window they start folded so the part stays visible.
for (const p of document.querySelectorAll('.panel[data-fold]')) {
  const b = p.querySelector('.fold');
  const set = (folded) => { p.classList.toggle('folded', folded); b.textContent = folded ? '+' : '−'; };
  b.onclick = () => set(!p.classList.contains('folded'));
  set(p.dataset.fold === 'always' || (window.innerWidth < 1000 && p.dataset.fold === 'small'));
}

// Helpers for tests and the console: where a vertex is drawn on the screen (CSS pixels), its
// true position, and the vertex nearest a point (m, part frame).
state.screenOf = (space, vertex) => {
  const s = state.spaces[space];
  camera.updateMatrixWorld();
  return screenOfPoint(new THREE.Vector3().fromBufferAttribute(s.geom.attributes.position, vertex));
};
state.trueOf = (space, vertex) => Array.from(state.spaces[space].truePos.subarray(3 * vertex, 3 * vertex + 3));
state.drawnOf = (space, vertex) => Array.from(state.spaces[space].geom.attributes.position.array.subarray(3 * vertex, 3 * vertex + 3));
state.nearestVertex = (space, p) => {
  const s = state.spaces[space];
  let best = -1, bd = Infinity;
  for (let i = 0; i < s.vertices; i++) {
    const d = (s.rest[3 * i] - p[0]) ** 2 + (s.rest[3 * i + 1] - p[1]) ** 2 + (s.rest[3 * i + 2] - p[2]) ** 2;
    if (d < bd) { bd = d; best = i; }
  }
  return best;
};
/** Screen rectangle (CSS px) of every drawn vertex of the active space: [xmin, ymin, xmax, ymax]. */
state.drawnExtent = () => {
  const s = state.spaces[state.active];
  camera.updateMatrixWorld();
  const v = new THREE.Vector3(), r = canvas.getBoundingClientRect();
  let box = [Infinity, Infinity, -Infinity, -Infinity];
  for (let i = 0; i < s.vertices; i++) {
    v.fromBufferAttribute(s.geom.attributes.position, i).project(camera);
    const x = r.left + ((v.x + 1) / 2) * r.width, y = r.top + ((1 - v.y) / 2) * r.height;
    box = [Math.min(box[0], x), Math.min(box[1], y), Math.max(box[2], x), Math.max(box[3], y)];
  }
  return box;
};

function resize() {
  const w = canvas.clientWidth, h = canvas.clientHeight;
  renderer.setSize(w, h, false);
  camera.aspect = w / h;
  camera.updateProjectionMatrix();
}
window.addEventListener('resize', resize);
resize();

// The scene is rendered when something may have changed on screen: the part redrawn, a mode
// animated, the user's input in the last second (camera, picks, hover, panels), a recording; and
// at least every RENDER_IDLE_MS whatever happens. A part at rest then costs the browser (and,
// without a GPU, the cores a compute beside it needs) almost nothing.
const RENDER_IDLE_MS = 1000;
let lastInput = 0, lastRender = 0;
const woken = () => { lastInput = performance.now(); };
for (const ev of ['pointermove', 'pointerdown', 'pointerup', 'wheel', 'keydown', 'keyup', 'resize', 'change', 'input', 'click']) {
  window.addEventListener(ev, woken, { passive: true, capture: true });
}
controls.addEventListener('change', woken);

function loop() {
  // The part is redrawn when something changed (a frame, its stress, the scale, the colouring),
  // not at every animation frame: 19.5k vertices' positions and colours cost the page's time.
  let drew = false;
  if (state.mode) {
    animateMode();
    drew = true;
  } else if (state.dirty && state.spaces[state.active]) {
    draw(state.spaces[state.active]);
    state.dirty = false;
    drew = true;
    state.drawTimes = (state.drawTimes || []).concat(performance.now()).slice(-60);
  }
  controls.update();
  const now = performance.now();
  if (drew || now - lastInput < 1000 || now - lastRender >= RENDER_IDLE_MS || capture.recording()) {
    renderer.render(scene, camera);
    placeTags();
    lastRender = now;
    state.renders = (state.renders || 0) + 1;
  }
  if (capture.recording() && state.legend) capture.draw(canvas, state.legend, overlay());
  if (state.meshesIn && !state.ready && state.frames > state.framesAtHello && !state.dirty) state.ready = true;
  requestAnimationFrame(loop);
}
connect();
loop();
