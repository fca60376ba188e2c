// What the page writes over the view: the readout (space, rates, device, hands, warnings), the
// legend, the markers at the field's extremes and the probe under the cursor.
import * as THREE from 'three';
import { $, el } from './dom.js';
import { gradient } from './colours.js';
import { feltText, fieldWords, label, plain } from './units.js';
import { DRAW_WINDOW, state } from './state.js';
import { scene, screenOfPoint } from './viewport.js';

/** The device's limit and coupling, in the units chosen. */
export function showLimit() {
  const h = state.hello;
  $('limit').textContent = `device force limit ${plain(h.max_force)} N · coupling ${label(h.stiffness, 'stiffness', state.units)}`
    + (h.free_body ? ` · ${freeness(h.free_motions)}, gravity ${plain(Math.hypot(...(h.gravity || [0, 0, 0])))} m/s²` : '');
}

/** How the part may move as a whole: a free body, or the rigid motions its supports leave. */
function freeness(count) {
  if (count == null || count >= 6) return 'free body';
  return `held, free along ${count} rigid motion${count === 1 ? '' : 's'} its supports leave`;
}

/** Redraws per second over the last DRAW_WINDOW redraws. */
function drawnRate() {
  const n = Math.min(state.draws, DRAW_WINDOW);
  if (n < 2) return 0;
  const newest = state.drawTimes[(state.draws - 1) % DRAW_WINDOW], oldest = state.drawTimes[(state.draws - n) % DRAW_WINDOW];
  return (1000 * (n - 1)) / (newest - oldest);
}

/** A status: the space, the rates, each hand's force and stress, and the warnings. */
export function showStatus(m) {
  const sp = state.hello.spaces[m.space];
  if (!sp) { $('space').textContent = m.computing ? 'computing the basis…' : 'no basis yet: set the part up and compute'; return; }
  $('space').textContent = `space ${sp.name}${sp.voi ? ' (volume of interest, yellow box)' : ''} · ${sp.vertices} vertices · ${m.clients} client(s)`;
  const fps = drawnRate();
  state.framesPerSecond = fps;
  $('rates').textContent = `haptic ${m.haptic_hz.toFixed(0)} Hz · visual ${m.visual_hz.toFixed(0)} Hz · drawn here ${fps.toFixed(0)} fps`;
  const u = state.units, min = state.hello.min_safety_factor, ys = state.hello.yield_strength;
  const lines = [];
  const warn = [];
  m.hands.forEach((h, i) => {
    if (!h.active) return;
    const f = Math.hypot(...h.force);
    lines.push(`hand ${i + 1}: ${label(f, 'force', 'si')} on the part${h.clamped ? ' (device limit)' : ''}${h.button ? '' : ', pressing'}`
      + (h.von_mises > 0 ? ` · σvM ${label(h.von_mises, 'stress', u)} · σ1 ${label(h.principal_stress, 'stress', u)} · ε1 ${h.principal_strain.toExponential(2)}` : '')
      + (h.safety_factor != null && h.von_mises > 0 ? ` · safety ${plain(h.safety_factor)}` : '')
      + (h.contact && feltText(h.felt_error) ? ` · ${feltText(h.felt_error)} here` : ''));
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
  showSupports(m);
}

// What each held face carries, beside its centre: the status's `supports` (force and moment of
// the drawn state per `[[fixed]]` entry) at the hello's `support_centres`.
const supportTags = [];
const supportPoint = new THREE.Vector3();

/** Writes each support's force and moment into its label (shown with the supports). */
function showSupports(m) {
  const centres = state.hello?.support_centres || [];
  const list = (m.supports || []).slice(0, centres.length);
  while (supportTags.length < list.length) {
    const tag = el('div', { className: 'marker supportlabel' });
    document.body.appendChild(tag);
    supportTags.push(tag);
  }
  const shown = $('showsupports').checked;
  const share = modalShare(m, list);
  // At rest a support carries nothing, or the last of a released pull's decay (1e-187 N): no
  // label below a millionth of the device's force limit (its moment: of that force across the
  // part).
  const tiny = 1e-6 * (state.hello?.max_force || 1);
  supportTags.forEach((tag, k) => {
    const on = shown && k < list.length
      && (Math.hypot(...list[k].force_n) > tiny || Math.hypot(...list[k].moment_nm) > tiny * (state.diag || 1));
    tag.style.display = on ? 'block' : 'none';
    tag.dataset.support = String(k);
    if (!on) return;
    const f = list[k].force_n, mo = list[k].moment_nm;
    tag.textContent = `support ${k + 1} carries ${label(Math.hypot(...f), 'force', 'si')} · ${plain(Math.hypot(...mo))} N·m`
      + (k === 0 && share ? ` (the modes kept carry ${share})` : '');
  });
}

/** The supports' reactions come from the modes kept (Φq): short of the hands' load by what the
 * truncation leaves out (the hand's own force is exact with the static correction). When the
 * hands hold steady (the share as at the last status, within 0.5 %: a moving part's inertia
 * is no truncation) and it differs from theirs by more than 1 %, that share in words. */
let lastShare = NaN;
function modalShare(m, list) {
  const hands = (m.hands || []).filter((h) => h.active);
  const load = [0, 1, 2].map((c) => hands.reduce((a, h) => a + h.force[c], 0));
  // What the supports carry (the part's force on them) is the hands' load when all is held.
  const carried = [0, 1, 2].map((c) => list.reduce((a, s) => a + s.force_n[c], 0));
  const f = Math.hypot(...load);
  const along = hands.length && list.length && f > 0 ? carried.reduce((a, v, c) => a + v * load[c], 0) / (f * f) : NaN;
  const steady = Math.abs(along - lastShare) < 0.005;
  lastShare = along;
  return steady && Math.abs(along - 1) > 0.01 ? `${plain(100 * along)} % of the hands' ${label(f, 'force', 'si')}` : '';
}

const at = [0, 0];
/** Moves the markers' labels to where their dots are drawn, and the supports' to their
 * centres (after a render). */
export function placeTags() {
  // Probes pinned close together would write over each other: a label that would cover another
  // probe's dot or a label placed before it goes a line lower.
  const pins = pinMarks.filter((m) => m.dot.visible).map((m) => [m, screenOfPoint(m.dot.position, [0, 0])]);
  const taken = pins.map(([, [x, y]]) => ({ left: x - 5, top: y - 5, w: 10, h: 10 }));
  for (const [m, [x, y]] of pins) {
    const w = m.tag.offsetWidth, h = m.tag.offsetHeight || 16, left = x + 8;
    let top = y - 8;
    const clash = (r) => top < r.top + r.h && r.top < top + h && left < r.left + r.w && r.left < left + w;
    while (taken.some(clash)) top += h;
    taken.push({ left, top, w, h });
    m.tag.style.left = `${left}px`; m.tag.style.top = `${top}px`;
  }
  for (const m of markers) {
    if (!m.dot.visible) continue;
    const [x, y] = screenOfPoint(m.dot.position, at);
    m.tag.style.left = `${x + 8}px`; m.tag.style.top = `${y - 8}px`;
  }
  const centres = state.hello?.support_centres || [];
  for (const tag of supportTags) {
    const c = centres[Number(tag.dataset.support)];
    if (tag.style.display === 'none' || !c) continue;
    supportPoint.set(c[0], c[1], c[2]);
    const [x, y] = screenOfPoint(supportPoint, at);
    tag.style.left = `${x + 8}px`; tag.style.top = `${y + 8}px`;
  }
}

/** The legend: its title, colour scale ('magnitude', 'signed', 'safety', 'neutral'), the three
 * tick labels and the note under it. */
export function showLegend(title, scale, ticks, note) {
  $('legendtitle').textContent = title;
  $('bar').style.background = gradient(scale);
  [$('lo').textContent, $('mid').textContent, $('hi').textContent] = ticks;
  if (note !== undefined) $('legendnote').textContent = note;
}

/** The deformation scale as drawn ("×5000, auto"). */
export function showScale(k) {
  $('scaleshown').textContent = `×${plain(k)}${state.scaleAuto ? ', auto' : ''}`;
}

// Markers at the field's extremes, and the pinned probes: a dot on the part and its value beside
// it. Made once and reused: a redraw only moves them.
const markers = [], pinMarks = [];
const pinPoint = new THREE.Vector3();
const markerGeometry = new THREE.SphereGeometry(1, 12, 8);

/** Places the markers of `list` ({vertex, text}) on space `s` as drawn. */
export function placeMarkers(s, list) {
  placeDots(markers, s, list, $('showmarkers').checked, 'marker', 0xffffff);
}

/** Most probes pinned at once (a further one replaces the oldest). */
export const MOST_PINS = 12;

/** Places the pinned probes of space `s` (the active one) with the values of the field drawn. */
export function placePins(s) {
  const f = state.field;
  if (f && !state.mode && !state.loadCase) keepExtremes(f);
  const list = f ? state.pins.filter((p) => p.space === state.active && p.vertex >= 0 && p.vertex < s.vertices)
    .map((p) => ({ vertex: p.vertex, text: `P${p.n} ${fieldWords(f, p.vertex, state.units)}` })) : [];
  placeDots(pinMarks, s, list, true, 'marker pin', 0xffd24a);
  $('pinrow').hidden = state.pins.length === 0;
}

/** Each pin's extreme of the live colouring over the last motion (from when the part left rest
 * to now, kept once it is at rest again: the report after a pull has the pull's): the largest
 * magnitude, the lowest safety factor. @param {any} f */
function keepExtremes(f) {
  const moving = state.episodePeak > 0;
  for (const p of state.pins) {
    if (p.space !== state.active) continue;
    if (moving && !p.moving) p.extremes = {};
    p.moving = moving;
    if (!moving) continue;
    const v = f.valueAt(p.vertex), e = p.extremes[state.colour];
    if (!Number.isFinite(v)) continue;
    if (e === undefined || (state.colour === 'safety' ? v < e : Math.abs(v) > Math.abs(e))) p.extremes[state.colour] = v;
  }
}

/** Pins a probe at `vertex` of the active space, or unpins the one there (or drawn within
 * `near` CSS px of screen point `xy`). */
export function togglePin(vertex, xy, near) {
  const mine = state.pins.filter((p) => p.space === state.active);
  const s = state.spaces[state.active];
  const hit = mine.find((p) => {
    if (p.vertex === vertex) return true;
    const [x, y] = screenOfPoint(pinPoint.fromBufferAttribute(s.geom.attributes.position, p.vertex), at);
    return Math.hypot(x - xy[0], y - xy[1]) <= near;
  });
  if (hit) state.pins = state.pins.filter((p) => p !== hit);
  else {
    if (state.pins.length >= MOST_PINS) state.pins.shift();
    const rest = Array.from(s.rest.subarray(3 * vertex, 3 * vertex + 3));
    state.pins.push({ space: state.active, vertex, rest, n: state.pins.reduce((m, p) => Math.max(m, p.n), 0) + 1, extremes: {}, moving: false });
  }
  keepPins();
  state.dirty = true;
}

/** Every pinned probe let go. */
export function clearPins() { state.pins = []; keepPins(); state.dirty = true; }

// The pins outlive a reload: kept in this browser's storage under the part's name (where they
// are, not their values), found again by position when its meshes come.
const pinKey = () => `ves.pins.${state.hello ? state.hello.name : ''}`;
function keepPins() {
  try {
    localStorage.setItem(pinKey(), JSON.stringify(state.pins.map((p) => ({ space: p.space, rest: p.rest, n: p.n }))));
  } catch { /* storage off or full: the pins last as long as the page */ }
}

/** The pins this browser kept for the part the hello serves (none if unreadable). */
export function keptPins() {
  try {
    const kept = JSON.parse(localStorage.getItem(pinKey()) || '[]');
    if (!Array.isArray(kept)) return [];
    return kept.slice(0, MOST_PINS).filter((p) => p && Number.isInteger(p.space) && Number.isInteger(p.n)
      && Array.isArray(p.rest) && p.rest.length === 3 && p.rest.every(Number.isFinite))
      .map((p) => ({ space: p.space, vertex: -1, rest: p.rest, n: p.n, extremes: {}, moving: false }));
  } catch { return []; }
}

/** `list`'s dots and tags from `pool` on space `s` as drawn (hidden unless `shown`). */
function placeDots(pool, s, list, shown, className, colour) {
  while (pool.length < list.length) {
    const dot = new THREE.Mesh(markerGeometry, new THREE.MeshBasicMaterial({ color: colour, depthTest: false }));
    dot.renderOrder = 2;
    const tag = el('div', { className });
    document.body.appendChild(tag);
    scene.add(dot);
    pool.push({ dot, tag });
  }
  pool.forEach((m, i) => {
    const on = i < list.length && list[i].vertex >= 0 && shown;
    m.dot.visible = on;
    m.tag.style.display = on ? 'block' : 'none';
    if (!on) return;
    m.dot.position.fromBufferAttribute(s.geom.attributes.position, list[i].vertex);
    m.dot.scale.setScalar(0.006 * state.diag);
    m.vertex = list[i].vertex;
    m.tag.textContent = list[i].text;
  });
}


/** The probe: the coloured value at vertex `v` and where it is, beside the cursor (x, y). */
export function showProbe(v, x, y) {
  const f = state.field, s = state.spaces[state.active];
  if (!f || !s || v >= s.vertices) return;
  const shown = fieldWords(f, v, state.units);
  // Coordinates to 1e-5 of the part's size: f32 round-off is not a position.
  const q = 1e-5 * state.diag;
  const where = Array.from(s.truePos.subarray(3 * v, 3 * v + 3)).map((c) => label(Math.round(c / q) * q, 'length', state.units)).join(', ');
  const tip = $('probe');
  tip.textContent = `${shown} · vertex ${v} at (${where})`;
  tip.style.left = `${x + 14}px`; tip.style.top = `${y + 22}px`;
  tip.style.display = 'block';
  state.probe.text = tip.textContent;
}

/** The probe shows `text` (a face's tag) beside the cursor, or hides (null). */
export function showTip(text, x, y) {
  const tip = $('probe');
  tip.style.display = text === null ? 'none' : 'block';
  if (text === null) return;
  tip.textContent = text;
  tip.style.left = `${x + 14}px`; tip.style.top = `${y + 22}px`;
}

/** No probe. */
export function hideProbe() { state.probe = null; $('probe').style.display = 'none'; }
