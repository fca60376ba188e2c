// The deformation scale: only the drawing is magnified, by k; hands, picks and every number shown
// are true. Automatic by default, or the number typed in.
import { $ } from './dom.js';
import { REST_FORCE } from './field.js';
import { showScale } from './hud.js';
import { state } from './state.js';

/** The automatic scale draws the largest displacement since the part was last at rest at this
 * fraction of the part's bounding-box diagonal, magnifying at most AUTO_CAP times what the
 * device's full force at the most compliant point would need (numerical motion of a part at
 * rest is never blown up). */
export const AUTO_FRACTION = 0.08;
export const AUTO_CAP = 10;

const NICE = [5, 2, 1];
/** Rounded down to 1, 2 or 5 times a power of ten, so the number can be read; never below 1. */
export function nice(k) {
  if (!(k > 1) || !Number.isFinite(k)) return 1;
  const p = 10 ** Math.floor(Math.log10(k));
  for (const m of NICE) if (m * p <= k) return m * p;
  return p;
}

/** The automatic scale at rest: the device's full force at the most compliant surface point
 * would draw AUTO_FRACTION of the part's size. */
export function autoScale() {
  // A nonlinear part is drawn at true size: its motion is visible, and a magnified large
  // deformation (rotations scaled up) would be a shape the part cannot take.
  if (state.hello.spaces[0].nonlinear) return 1;
  const c = state.hello.spaces[0].largest_compliance;
  return nice((AUTO_FRACTION * state.diag) / (state.hello.max_force * c));
}

/** Below this displacement (m) space `s` is at rest: what 1 mN gives at the most compliant point. */
export function restLevel(s) {
  const c = state.hello.spaces[state.active].largest_compliance;
  return Math.max(c > 0 ? c * REST_FORCE : 0, 1e-12 * s.size);
}

/** The scale `s` is drawn at now. The automatic one follows the largest displacement since the
 * part was last at rest (a load episode): it only comes down while the load grows, so a pull is
 * drawn at a steady size and the ringing after a release shrinks as it really does. */
export function drawScale(s) {
  let umax = 0;
  for (let i = 0; i < s.vertices; i++) umax = Math.max(umax, s.umag[i]);
  if (!(umax > restLevel(s))) state.episodePeak = 0;
  else state.episodePeak = Math.max(state.episodePeak || 0, umax);
  let k = state.scale;
  if (state.scaleAuto && state.hello.spaces[state.active].nonlinear) {
    k = 1;
    $('scale').value = '1';
  } else if (state.scaleAuto) {
    k = state.episodePeak > 0 ? Math.min(AUTO_CAP * state.autoScale, nice((AUTO_FRACTION * s.size) / state.episodePeak)) : state.autoScale;
    $('scale').value = String(k);
  }
  state.drawnScale = k;
  showScale(k);
  return k;
}

/** A fixed scale `k`, or 'auto'. */
export function setScale(k) {
  state.scaleAuto = k === 'auto';
  if (!state.scaleAuto) state.scale = k;
  $('scaleauto').checked = state.scaleAuto;
  $('scale').value = String(state.scaleAuto ? state.autoScale : k);
  state.dirty = true;
}
