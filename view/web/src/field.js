// What the part is coloured by, read from the latest frame: the values, their range and the
// legend. A range spreads only over what is above the field's round-off: a part at rest says so
// instead of spreading the scale over noise.
import { sequential, diverging, safetyRamp, DANGER, NEUTRAL } from './colours.js';
import { label, plain } from './units.js';

/** Safety factors from the minimum up to this many times it get the logarithmic ramp. */
export const SAFETY_SPAN = 100;
/** A displacement below what this force (N) gives at the part's most compliant point is rest. */
export const REST_FORCE = 1e-3;

function extremes(values) {
  let hi = -Infinity, lo = Infinity, at = -1, lowAt = -1;
  for (let i = 0; i < values.length; i++) {
    const v = values[i];
    if (v > hi) { hi = v; at = i; }
    if (v < lo) { lo = v; lowAt = i; }
  }
  return { hi, lo, at, lowAt };
}

/**
 * A field as coloured (the properties after `values` are set as it is worked out).
 * @typedef {object} Field
 * @property {string} title the legend's title
 * @property {string} quantity 'length', 'stress' or 'ratio' (units.js `label`)
 * @property {string} scale the colour scale: 'magnitude', 'signed', 'safety' or 'neutral'
 * @property {Float32Array|null} values per vertex (null: computed, the safety factor)
 * @property {boolean} [atRest] no displacement above round-off: nothing to colour
 * @property {{vertex: number, text: string}[]} [markers] the extremes to mark
 * @property {(i: number, out: number[]) => number[]} [colourOf] vertex i's colour
 * @property {(i: number) => number} [valueAt] vertex i's value
 * @property {string[]} [ticks] the legend's three labels
 * @property {number} [lo] the range's low end
 * @property {number} [hi] the range's high end
 * @property {string} [summary] the note under the legend
 */

/**
 * The field of space `s` for colouring `colour` ('displacement', 'vonmises', 'principal',
 * 'safety'): `{ title, quantity, scale, values, lo, hi, atRest, markers, colourOf(i, out), ticks }`
 * (`colourOf` writes vertex i's colour into `out` and returns it, or returns a shared constant).
 * `ctx`: `{ hello, restLevel, units, locked }` (`locked`: `{lo, hi}` to keep a range).
 */
export function fieldOf(colour, s, ctx) {
  const { hello, units } = ctx;
  const fmt = (q) => (v) => label(v, q, units);
  const { hi: umax } = extremes(s.umag);
  const atRest = !(umax > ctx.restLevel);
  /** @type {Field} */
  let f;
  if (colour === 'vonmises' && s.vm) {
    f = { title: 'von Mises stress', quantity: 'stress', scale: 'magnitude', values: s.vm };
  } else if (colour === 'principal' && s.p1) {
    f = { title: 'largest principal stress (tension > 0)', quantity: 'stress', scale: 'signed', values: s.p1 };
  } else if (colour === 'safety' && s.vm && hello.yield_strength) {
    f = { title: `safety factor (yield ${label(hello.yield_strength, 'stress', units)} / von Mises), log scale`, quantity: 'ratio', scale: 'safety', values: null };
  } else {
    f = { title: 'displacement magnitude (true, not scaled)', quantity: 'length', scale: 'magnitude', values: s.umag };
  }
  f.atRest = atRest;
  f.markers = [];
  if (atRest) {
    f.title = `${f.title}: at rest`;
    f.scale = 'neutral';
    f.colourOf = () => NEUTRAL;
    f.ticks = ['', 'no load on the part', ''];
    f.valueAt = (i) => (f.values ? f.values[i] : Infinity);
    return f;
  }
  if (f.scale === 'safety') return safety(f, s, ctx);
  const e = extremes(f.values);
  let [lo, hi] = f.scale === 'signed' ? [-Math.max(Math.abs(e.lo), Math.abs(e.hi)), Math.max(Math.abs(e.lo), Math.abs(e.hi))] : [0, e.hi];
  if (ctx.episode) {
    // The range since the part was last at rest (kept while it rings down after a release).
    ctx.episode.lo = Math.min(ctx.episode.lo, lo); ctx.episode.hi = Math.max(ctx.episode.hi, hi);
    [lo, hi] = [ctx.episode.lo, ctx.episode.hi];
  }
  if (ctx.locked) {
    [lo, hi] = [ctx.locked.lo, ctx.locked.hi];
    if (e.hi > hi || e.lo < lo) f.summary = `locked range: values beyond it (${fmt(f.quantity)(e.lo < lo ? e.lo : e.hi)}) drawn in the end colour`;
  }
  f.lo = lo; f.hi = hi;
  const span = hi - lo > 0 ? hi - lo : 1;
  const map = f.scale === 'signed' ? diverging : sequential;
  f.colourOf = (i, out) => map((f.values[i] - lo) / span, out);
  f.valueAt = (i) => f.values[i];
  const w = fmt(f.quantity);
  f.ticks = [w(lo), w((lo + hi) / 2), w(hi)];
  f.markers.push({ vertex: e.at, text: `max ${w(e.hi)}` });
  if (f.scale === 'signed') f.markers.push({ vertex: e.lowAt, text: `min ${w(e.lo)}` });
  return f;
}

// Safety factor yield/σvM: red below the minimum, a logarithmic ramp from the minimum to
// SAFETY_SPAN times it, and the ramp's end beyond (a part far from yielding is not "hot").
function safety(f, s, ctx) {
  const ys = ctx.hello.yield_strength;
  const min = ctx.hello.min_safety_factor > 0 ? ctx.hello.min_safety_factor : 1;
  const cap = min * SAFETY_SPAN;
  const sf = (i) => ys / Math.max(s.vm[i], 1e-300);
  f.valueAt = sf;
  f.colourOf = (i, out) => {
    const v = sf(i);
    return v < min ? DANGER : safetyRamp(Math.log(v / min) / Math.log(SAFETY_SPAN), out);
  };
  const e = extremes(s.vm);
  const lowest = sf(e.at);
  f.lo = lowest; f.hi = cap;
  f.ticks = [`< ${plain(min)} yields`, plain(min * Math.sqrt(SAFETY_SPAN)), `≥ ${plain(cap)}`];
  f.markers.push({ vertex: e.at, text: `lowest safety ${plain(lowest)}` });
  f.summary = lowest >= cap ? `every point ≥ ${plain(cap)}` : `lowest ${plain(lowest)}`;
  return f;
}
