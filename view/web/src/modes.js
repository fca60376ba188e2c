// The mode browser: the frequencies of the active space; a click asks the server for that mode's
// shape, which is then animated instead of the live part until clicked again.
import { $, el } from './dom.js';
import { sequential } from './colours.js';
import { placeMarkers, placePins, showLegend } from './hud.js';
import { state } from './state.js';
import { send } from './connection.js';

/** A frequency to five significant digits, without an exponent ("116620", not "1.1662e+5"). */
const hertz = (f) => String(Number(f.toPrecision(5)));

/** Lists the modes of `space` (the hello's) as buttons; `onAsk` runs before a mode is asked for. */
export function buildModeList(space, onAsk) {
  const box = $('modes');
  box.textContent = '';
  space.frequencies_hz.forEach((f, j) => {
    const b = el('button', { textContent: `mode ${j + 1}: ${hertz(f)} Hz` });
    b.onclick = () => {
      if (state.mode && state.mode.mode === j) { stopMode(); return; }
      onAsk();
      send({ type: 'mode', space: state.active, index: j });
    };
    box.appendChild(b);
  });
}

/** The live part again. */
export function stopMode() {
  state.mode = null;
  state.dirty = true;
  for (const b of $('modes').children) b.classList.remove('on');
}

/** A decoded mode shape (protocol.js) came: it is animated from now. */
export function startMode(m) {
  for (const b of $('modes').children) b.classList.remove('on');
  const b = $('modes').children[m.mode];
  if (b) b.classList.add('on');
  state.mode = { ...m, start: performance.now() };
  // The probes pinned read the shape's relative amplitude |φ| while it is shown.
  state.field = { quantity: 'ratio', valueAt: (i) => Math.hypot(m.phi[3 * i], m.phi[3 * i + 1], m.phi[3 * i + 2]) };
  showLegend(`mode ${m.mode + 1}, ${hertz(m.frequency)} Hz: relative amplitude (shape only)`, 'magnitude', ['0', '0.5', '1']);
}

const rgb = [0, 0, 0];
/** Draws the mode shape at this moment: rest + a·sin(2πt/1.5 s)·φ, coloured by |φ|. */
export function animateMode() {
  const m = state.mode;
  const s = state.spaces[m.space];
  if (!s) { state.mode = null; return; }
  const amp = 0.08 * state.diag * Math.sin((2 * Math.PI * (performance.now() - m.start)) / 1500);
  const p = s.geom.attributes.position.array;
  const c = s.geom.attributes.color.array;
  for (let i = 0; i < s.vertices; i++) {
    const mag = Math.hypot(m.phi[3 * i], m.phi[3 * i + 1], m.phi[3 * i + 2]);
    const v = sequential(mag, rgb);
    for (let k = 0; k < 3; k++) p[3 * i + k] = s.rest[3 * i + k] + amp * m.phi[3 * i + k];
    c[3 * i] = v[0]; c[3 * i + 1] = v[1]; c[3 * i + 2] = v[2];
  }
  s.geom.attributes.position.needsUpdate = true;
  s.geom.attributes.color.needsUpdate = true;
  s.geom.computeBoundingSphere();
  // The live part's extremes are not this shape's; the pins move with it.
  placeMarkers(s, []);
  placePins(s);
}
