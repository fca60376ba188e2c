// The Show panel's controls and the keys: the colouring, units, colour range lock, deformation
// scale, supports and markers, load case, views, reset, pictures; and the panels' folding.
import { $ } from './dom.js';
import * as capture from './capture.js';
import { askFields } from './drawing.js';
import { dragging, endDrags, letGo } from './interaction.js';
import { clearPins, showLimit } from './hud.js';
import { chooseLoad } from './loadcases.js';
import { setScale } from './scale.js';
import { showEdges, showSupports } from './spaces.js';
import { state } from './state.js';
import { send } from './connection.js';
import { canvas, fitView, homeView, viewAlong } from './viewport.js';

/** The part back to rest and every hand let go (this page's drags end). */
export function resetSimulation() {
  endDrags();
  send({ type: 'reset' });
}

/** A hello: the stress colourings are offered only when a space has stress, the safety factor
 * only with a yield strength. */
export function offerColours(hello) {
  for (const o of $('colour').options) o.disabled = o.value !== 'displacement' && !hello.spaces.some((s) => s.has_stress);
  if (hello.yield_strength == null) $('colour').querySelector('option[value=safety]').disabled = true;
  if ($('colour').selectedOptions[0].disabled) { $('colour').value = 'displacement'; state.colour = 'displacement'; }
}

// What the pictures carry besides the view: the labels drawn over it and the readout.
/** The labels over the view and the readout lines, for a picture. */
export function overlay() {
  const labels = [...document.querySelectorAll('.forcelabel, .marker')].flatMap((e) => (e instanceof HTMLElement && e.style.display !== 'none' && e.textContent
    ? [{ text: e.textContent, x: parseFloat(e.style.left) || 0, y: parseFloat(e.style.top) || 0, colour: getComputedStyle(e).color }] : []));
  const warn = $('warn').textContent;
  return { labels, lines: [$('title').textContent, $('handinfo').textContent, warn], warn: Boolean(warn) };
}

const pictureName = () => (state.hello ? state.hello.name : 'ves');

$('fit').onclick = () => { if (!dragging()) fitView(); };
$('home').onclick = () => { if (!dragging()) homeView(); };
$('resetsim').onclick = resetSimulation;
$('clearpins').onclick = clearPins;
for (const b of document.querySelectorAll('[data-axis]')) {
  if (b instanceof HTMLElement) b.onclick = () => viewAlong(b.dataset.axis, Number(b.dataset.sign));
}
$('shot').onclick = () => capture.screenshot(canvas, state.legend, pictureName(), overlay());
$('record').onclick = () => {
  try {
    const on = capture.toggleRecording(canvas, state.legend, pictureName(), overlay());
    $('record').textContent = on ? '■ stop' : '● record';
  } catch (e) { $('warn').textContent = e.message; }
};

window.addEventListener('keydown', (ev) => {
  if (ev.target instanceof HTMLInputElement || ev.target instanceof HTMLSelectElement || ev.ctrlKey || ev.metaKey || ev.altKey) return;
  const k = ev.key.length === 1 ? ev.key.toLowerCase() : ev.key;
  // The view stays while a hand is dragged: the drag plane is the camera's.
  const moving = ['f', 'h', 'Home', 'x', 'y', 'z'].includes(k);
  if (moving && dragging()) return;
  if (k === 'f') fitView();
  else if (k === 'h' || k === 'Home') homeView();
  else if (k === 'x' || k === 'y' || k === 'z') viewAlong(k, ev.shiftKey ? -1 : 1);
  else if (k === 'r') resetSimulation();
  else if (k === 'p') $('shot').click();
  else if (k === 'e') $('showedges').click();
  else return;
  ev.preventDefault();
});

$('scale').addEventListener('change', (ev) => {
  const v = Number(ev.target.value);
  if (Number.isFinite(v) && v >= 0) setScale(v); else ev.target.value = String(state.drawnScale);
});
$('scaleauto').addEventListener('change', (ev) => setScale(ev.target.checked ? 'auto' : state.drawnScale));
$('loadcase').addEventListener('change', (ev) => chooseLoad(ev.target.value, letGo));
$('colour').addEventListener('change', (ev) => { state.colour = ev.target.value; state.dirty = true; askFields(); });
$('units').addEventListener('change', (ev) => { state.units = ev.target.value; state.dirty = true; if (state.hello) showLimit(); });
$('lock').addEventListener('change', (ev) => {
  const l = state.legend;
  state.locked = ev.target.checked && l && !l.atRest && Number.isFinite(l.lo) ? { colour: state.colour, lo: l.lo, hi: l.hi } : null;
  if (ev.target.checked && !state.locked) $('legendnote').textContent = 'nothing to lock: the part is at rest (lock while it is loaded, e.g. hold with the wheel)';
  ev.target.checked = state.locked !== null;
  state.dirty = true;
});
$('showsupports').addEventListener('change', () => { state.dirty = true; showSupports(); });
$('showedges').addEventListener('change', () => { state.dirty = true; showEdges(); });
$('showmarkers').addEventListener('change', () => { state.dirty = true; });

// Panels fold to their title. On a small window (narrower than 1000 px or lower than 700 px)
// they overlap when open: they start folded so the part stays visible, and opening one folds
// the others (at 800 × 600 the readout and the set-up panel, at 420 px every panel, overlapped).
const small = () => window.innerWidth < 1000 || window.innerHeight < 700;
const foldable = [...document.querySelectorAll('.panel[data-fold]')].filter((p) => p instanceof HTMLElement);
/** @param {HTMLElement} p @param {boolean} folded */
function fold(p, folded) {
  p.classList.toggle('folded', folded);
  const b = p.querySelector('.fold');
  if (b) b.textContent = folded ? '+' : '−';
}
for (const p of foldable) {
  const b = /** @type {HTMLElement} */ (p.querySelector('.fold'));
  b.onclick = () => {
    const opening = p.classList.contains('folded');
    fold(p, !opening);
    if (opening && small()) for (const q of foldable) if (q !== p) fold(q, true);
  };
  fold(p, p.dataset.fold === 'always' || (small() && p.dataset.fold === 'small'));
}

// The set-up panel sits under the readout and ends above the legend (and, in a narrow window,
// above the Show panel at the bottom), whatever their heights: at fixed places the readout,
// opened on a short window, ran under it.
function placeSetup() {
  const setup = $('setup'), hud = $('hud').getBoundingClientRect();
  const top = Math.round(hud.bottom + 8);
  const narrow = window.innerWidth < 700;
  const below = Math.min($('legend').getBoundingClientRect().top, narrow ? $('controls').getBoundingClientRect().top : Infinity);
  setup.style.top = `${top}px`;
  setup.style.maxHeight = `${Math.max(120, Math.round(below - 8 - top))}px`;
}
const watchSizes = new ResizeObserver(placeSetup);
for (const id of ['hud', 'legend', 'controls']) watchSizes.observe($(id));
window.addEventListener('resize', placeSetup);
