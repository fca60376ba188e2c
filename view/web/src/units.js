// How values are written: SI with prefixes (123 µm, 250 MPa) or the engineer's fixed units
// (mm, MPa). Never a prefix and an exponent together ("7.41e-9 nm" was printed for 7e-18 m).

/** @type {[number, string][]} */
const PREFIXES = [[1e9, 'G'], [1e6, 'M'], [1e3, 'k'], [1, ''], [1e-3, 'm'], [1e-6, 'µ'], [1e-9, 'n'], [1e-12, 'p'], [1e-15, 'f']];

/** A value with an SI prefix: 1.23e-4 m -> "123 µm", 2.5e8 Pa -> "250 MPa"; beyond the
 * prefixes, an exponent on the bare unit ("3.1e-18 m"). */
export function siLabel(v, unit) {
  if (!Number.isFinite(v)) return `— ${unit}`;
  if (v === 0) return `0 ${unit}`;
  const a = Math.abs(v);
  if (a >= 999.5e9 || a < 0.9995e-15) return `${v.toExponential(2)} ${unit}`;
  const [f, p] = PREFIXES.find(([f]) => a >= f * 0.9995);
  return `${(v / f).toPrecision(3)} ${p}${unit}`;
}

/** Three significant digits, plain between 1e-3 and 1e6, else an exponent: "0.0140", "1.40e-5". */
export function plain(v) {
  if (!Number.isFinite(v)) return '—';
  if (v === 0) return '0';
  const a = Math.abs(v);
  return a >= 1e-3 && a < 1e6 ? Number(v.toPrecision(3)).toString() : v.toExponential(2);
}

// Quantities and how each unit system writes them.
const ENGINEERING = { length: [1e-3, 'mm'], stress: [1e6, 'MPa'], force: [1, 'N'], stiffness: [1e3, 'N/mm'] };
const SI = { length: 'm', stress: 'Pa', force: 'N', stiffness: 'N/m' };

/** `v` (SI) of `quantity` (length, stress, force, stiffness) in `system` ('si' or 'mm'). */
export function label(v, quantity, system) {
  if (quantity === 'ratio') return plain(v);
  if (system === 'mm' && ENGINEERING[quantity]) {
    const [f, u] = ENGINEERING[quantity];
    return `${plain(v / f)} ${u}`;
  }
  return siLabel(v, SI[quantity] || '');
}

/** What a hand feels wrong at its vertex (the status's `felt_error`: the share of the felt
 * compliance the modes and the mesh miss, both making the part too stiff), as how much too
 * stiff it feels: "felt ≤ 1.2 % too stiff"; '' when not stated. */
export function feltText(e) {
  if (e == null || !Number.isFinite(e)) return '';
  if (e >= 0.5) return 'felt over 2× too stiff (the mesh is coarser than the fingertip)';
  return `felt ≤ ${plain(100 * e / (1 - e))} % too stiff`;
}

/** A value of `quantity` in words, in `units` (a ratio bare; none where there is no stress). */
export function quantityWords(quantity, value, units) {
  return quantity === 'ratio' ? (Number.isFinite(value) ? plain(value) : 'no stress') : label(value, quantity, units);
}

/** Field `f`'s value at vertex `v` in words (see quantityWords).
 * @param {{quantity: string, valueAt: (i: number) => number}} f */
export function fieldWords(f, v, units) {
  return quantityWords(f.quantity, f.valueAt(v), units);
}
