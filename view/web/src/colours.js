// Colour scales: sequential for magnitudes (0 = blue, largest = red, the CAE convention),
// diverging around zero for signed values, and the safety factor's own: red only below the
// minimum, then a logarithmic ramp up to a cap.

const SEQUENTIAL = [[0.13, 0.27, 0.8], [0.1, 0.7, 0.85], [0.35, 0.78, 0.3], [0.98, 0.82, 0.15], [0.86, 0.12, 0.1]];
// Moreland's cool-warm, blue compression to red tension.
const DIVERGING = [[0.23, 0.3, 0.75], [0.55, 0.69, 1.0], [0.87, 0.87, 0.87], [0.96, 0.6, 0.48], [0.71, 0.02, 0.15]];
// From just above the minimum (amber) to safe (blue-green).
const SAFETY = [[0.96, 0.55, 0.15], [0.93, 0.85, 0.45], [0.55, 0.8, 0.7], [0.2, 0.55, 0.75]];
/** Below the minimum safety factor. */
export const DANGER = [0.85, 0.05, 0.1];
/** A part at rest: no colour to read. */
export const NEUTRAL = [0.72, 0.74, 0.76];

// The colour at t (0..1) of a scale, into `out` (a new array if none: a redraw passes one it
// reuses for every vertex).
function sample(stops, t, out = [0, 0, 0]) {
  const x = Math.min(1, Math.max(0, Number.isFinite(t) ? t : 0)) * (stops.length - 1);
  const i = Math.min(stops.length - 2, Math.floor(x));
  const u = x - i;
  const a = stops[i], b = stops[i + 1];
  for (let k = 0; k < 3; k++) out[k] = a[k] + u * (b[k] - a[k]);
  return out;
}

/** The sequential scale's colour at t (0..1), into `out` if given. */
export const sequential = (t, out) => sample(SEQUENTIAL, t, out);
/** The diverging scale's colour at t (0..1), into `out` if given. */
export const diverging = (t, out) => sample(DIVERGING, t, out);
/** The safety ramp's colour at t (0..1), into `out` if given. */
export const safetyRamp = (t, out) => sample(SAFETY, t, out);

const css = (c) => `rgb(${c.map((v) => Math.round(255 * v)).join(',')})`;
/** CSS gradient of a scale, for the legend bar. */
export function gradient(kind) {
  if (kind === 'neutral') return css(NEUTRAL);
  if (kind === 'safety') {
    const stops = SAFETY.map((c, i) => `${css(c)} ${(12 + (88 * i) / (SAFETY.length - 1)).toFixed(0)}%`);
    return `linear-gradient(to right, ${css(DANGER)} 0%, ${css(DANGER)} 12%, ${stops.join(', ')})`;
  }
  const stops = kind === 'signed' ? DIVERGING : SEQUENTIAL;
  return `linear-gradient(to right, ${stops.map(css).join(', ')})`;
}
