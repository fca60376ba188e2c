// Static load cases (the basis's `loads`): a select offers the active space's; choosing one asks
// the server for it (its displacement and von Mises stress, sent only then) and shows the part
// deformed by it and coloured by its stress instead of the live part. The hands are let go and
// off meanwhile: what is drawn is the static answer to that load alone, which a hand's pull
// would not change; "none" brings the live part back.
import { $, el } from './dom.js';
import { sequential } from './colours.js';
import { hideProbe, placeMarkers, placePins, showLegend, showScale } from './hud.js';
import { label, plain } from './units.js';
import { AUTO_FRACTION, nice } from './scale.js';
import { supportsFollow } from './spaces.js';
import { stopMode } from './modes.js';
import { state } from './state.js';
import { send, isOpen } from './connection.js';

/** Offers the load cases of `space` (the hello's), or hides the select when it has none. */
export function buildLoadList(space) {
  const sel = $('loadcase');
  while (sel.options.length > 1) sel.remove(1);
  const cases = (space && space.loads) || [];
  cases.forEach((c, i) => {
    sel.appendChild(el('option', { value: String(i), textContent: `${c.name}: ${c.kind}, ${label(Math.hypot(...c.total_force), 'force', 'si')}` }));
  });
  sel.value = '';
  $('loadbox').hidden = !cases.length && !(space && space.loads_error);
  $('loadnote').textContent = space && space.loads_error ? `load cases not offered: ${space.loads_error}` : '';
}

/** The checks after a compute listed the cases again (their peaks studied): the hello takes
 * them, the list is rebuilt, and the case shown, if still there, is drawn with its new figures. */
export function loadsChecked(lists) {
  if (!state.hello) return;
  lists.forEach((cases, i) => { if (state.hello.spaces[i]) state.hello.spaces[i].loads = cases; });
  const shown = state.loadCase;
  buildLoadList(state.hello.spaces[state.active]);
  if (!shown) return;
  const info = (state.hello.spaces[shown.space].loads || [])[shown.index];
  if (info && info.name === shown.name) {
    state.loadCase = { ...shown, ...info };
    $('loadcase').value = String(shown.index);
    state.dirty = true;
  } else hideLoad();
}

/** Shows load case `value` (its index in the active space's list; '' for none). `letGo` ends
 * this page's drags and lets go of its hands first. */
export function chooseLoad(value, letGo) {
  if (value === '' || value == null) { hideLoad(); state.dirty = true; return; }
  const i = Number(value);
  const info = state.hello.spaces[state.active].loads[i];
  if (!info || !isOpen()) return;
  letGo();
  stopMode();
  hideProbe();
  state.loadWanted = { space: state.active, index: i };
  $('loadcase').value = String(i);
  $('loadnote').textContent = `reading load case ${info.name}…`;
  send({ type: 'load', space: state.active, name: info.name });
}

/** A decoded load case (protocol.js) came: shown if it is the one asked for. */
export function onLoad(m) {
  const w = state.loadWanted;
  if (!w || w.space !== m.space || w.index !== m.index || !state.spaces[m.space]) return;
  state.loadWanted = null;
  state.loadCase = { ...m, ...state.hello.spaces[m.space].loads[m.index] };
  // A load case is coloured by its von Mises stress (the legend says so): no other choice shown.
  $('colour').disabled = true;
  $('colourbox').hidden = $('lockbox').hidden = true;
  state.dirty = true;
}

/** The live part again (the case shown or asked for is put away). */
export function hideLoad() {
  const was = state.loadCase || state.loadWanted;
  state.loadCase = null;
  state.loadWanted = null;
  $('colour').disabled = false;
  $('colourbox').hidden = $('lockbox').hidden = false;
  if ($('loadcase').value !== '') $('loadcase').value = '';
  if (was) { $('loadnote').textContent = ''; state.dirty = true; }
}

const rgb = [0, 0, 0];

/** What the study of a peak on meshes refined around it says of its value (the file's
 * `peak_*`): its error, that it is singular (no converged value), or nothing settled. */
function peakError(p, w) {
  if (!p) return '';
  const steps = `${w(p.value)} → ${w(p.refined[0])} → ${w(p.refined[1])} with the mesh there halved twice`;
  if (p.verdict === 'singular') return ` at a singular point (${steps}: no converged value)`;
  if (p.error != null) return ` ± ${plain((100 * p.error) / p.value)} %`;
  return ` (unsettled: ${steps}; no error stated)`;
}

/** The peak's study in a word or two, for the legend. */
function shortPeak(p) {
  if (!p) return '';
  if (p.verdict === 'singular') return ' (singular point)';
  return p.error != null ? ` ± ${plain((100 * p.error) / p.value)} %` : '';
}

/** When the largest peak is singular, the largest studied one that is not: the stress to judge
 * the part by, with its own safety factor. */
function awayFrom(c, w, ys) {
  const r = c.regular_peak;
  if (!r) return '';
  return ` · away from it ${w(r.value)}${peakError(r, w)}${ys && r.value > 0 ? `, safety factor ${plain(ys / r.value)}` : ''}`;
}
/** Draws load case `c` on space `s`: rest + k·u with the page's scale (automatic: the case's
 * largest displacement at AUTO_FRACTION of the part), coloured by its von Mises stress from zero
 * to the case's largest (the whole part's, from the file). */
export function drawLoad(s, c) {
  const k = state.scaleAuto ? nice((AUTO_FRACTION * s.size) / c.maxDisplacement) : state.scale;
  if (state.scaleAuto) $('scale').value = String(k);
  state.drawnScale = k;
  showScale(k);
  const p = s.geom.attributes.position.array;
  for (let i = 0; i < p.length; i++) p[i] = s.rest[i] + k * c.u[i];
  s.truePos.set(s.rest);
  for (let i = 0; i < p.length; i++) s.truePos[i] += c.u[i];
  s.geom.attributes.position.needsUpdate = true;
  s.geom.computeBoundingSphere();
  supportsFollow(s, p);
  const u = state.units, hi = c.maxVonMises, ys = state.hello.yield_strength, min = state.hello.min_safety_factor;
  const span = hi > 0 ? hi : 1;
  const col = s.geom.attributes.color.array;
  let top = -1;
  for (let i = 0; i < s.vertices; i++) {
    const v = sequential(c.vm[i] / span, rgb);
    col[3 * i] = v[0]; col[3 * i + 1] = v[1]; col[3 * i + 2] = v[2];
    if (top < 0 || c.vm[i] > c.vm[top]) top = i;
  }
  s.geom.attributes.color.needsUpdate = true;
  const w = (v) => label(v, 'stress', u);
  const sf = ys && hi > 0 ? ys / hi : null;
  const singular = c.peak?.verdict === 'singular';
  const safety = sf === null ? '' : ` · safety factor ${plain(sf)}${singular ? ' from a singular peak' : ''}${sf < min ? ` below the minimum ${plain(min)}: it would yield` : ''} (yield ${w(ys)})`;
  const title = `von Mises stress, load case ${c.name} (static)`;
  // The legend keeps to one short line (it sits beside the set-up panel); the note says more.
  const summary = `max ${w(hi)}${shortPeak(c.peak)}${safety}`;
  state.field = { quantity: 'stress', valueAt: (i) => c.vm[i] };
  const caption = `load case ${c.name}: ${c.kind}, ${label(Math.hypot(...c.total_force), 'force', 'si')} · deformation drawn ${$('scaleshown').textContent} · ${summary}`;
  const ticks = [w(0), w(hi / 2), w(hi)];
  state.legend = { title, scale: 'magnitude', ticks, caption, atRest: false, lo: 0, hi, load: c.name };
  showLegend(title, 'magnitude', ticks, summary);
  placeMarkers(s, [{ vertex: top, text: `max on the surface ${w(c.vm[top])}${singular ? ' (singular)' : ''}` }]);
  placePins(s);
  // The supports' reaction balances the load: what is left of the sum says how well.
  const load = Math.hypot(...c.total_force);
  const left = Math.hypot(...c.total_force.map((f, i) => f + c.reaction[i]));
  const reaction = `the supports react ${label(Math.hypot(...c.reaction), 'force', 'si')}`
    + ` [${c.reaction.map((f) => label(f, 'force', 'si')).join(', ')}]`
    + (load > 0 ? `, balancing the load to ${(100 * left / load).toExponential(1)} %` : '');
  $('loadnote').replaceChildren(
    `${c.name}: ${c.kind}, total ${label(load, 'force', 'si')}, largest displacement `
      + `${label(c.maxDisplacement, 'length', u)} drawn ×${plain(k)}${state.scaleAuto ? ` (auto: the largest at ${Math.round(100 * AUTO_FRACTION)} % of the part's size)` : ''}; ${reaction}. `
      + (c.peak ? `Peak von Mises ${w(hi)}${peakError(c.peak, w)}${awayFrom(c, w, ys)}. ` : ''),
    el('b', { textContent: 'Hands are off while a load case is shown' }),
    ' (a drag orbits); choose "none" to pull the part again.',
  );
}
