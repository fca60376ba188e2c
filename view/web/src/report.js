// A report of what is served, as an engineer files it: the part and its set-up (material,
// supports, loads, mesh), the computed line (the frequency estimate, the felt check), the
// warnings, each space's frequencies, and each load case's figures — its largest displacement,
// its peak stress with the peak's error or the note that it is singular, the safety factor and
// what the supports carry; the probes pinned on the part with their values as shown. Markdown,
// downloaded under the part's name.
import { download } from './capture.js';
import { state } from './state.js';
import { fieldWords, label, plain, quantityWords } from './units.js';

const row = (cells) => `| ${cells.join(' | ')} |`;

/** A support as the scene says it, in words. */
function supportText(f) {
  const where = f.faces ? `faces ${f.faces.join(', ')}`
    : f.plane ? `plane ${f.plane.axis} = ${plain(f.plane.value)} m`
      : f.box ? `box [${f.box.min.map(plain).join(', ')}]–[${f.box.max.map(plain).join(', ')}] m` : 'a region';
  // The scene's own keys (docs/scene.md): `kind`, `located`, `stiffness`, `components`.
  const how = f.kind === 'elastic' ? `elastic, ${plain(f.stiffness)} N/m³`
    : f.kind === 'bearing' ? (f.located ? 'located bearing' : 'bearing (floating)')
      : f.kind && f.kind !== 'clamped' ? f.kind : f.components ? `along ${f.components.join(', ')}` : 'clamped';
  return `${where}: ${how}`;
}

/** A load as the scene says it, in words. */
function loadText(l) {
  const where = l.faces ? `faces ${l.faces.join(', ')}` : l.plane ? `plane ${l.plane.axis} = ${plain(l.plane.value)} m` : 'a box';
  const what = l.pressure !== undefined ? `pressure ${plain(l.pressure)} Pa` : `force [${(l.force || []).map(plain).join(', ')}] N`;
  return `${l.name}: ${what} on ${where}`;
}

/** A studied peak's value with its error, or that it is singular. */
function peakText(p, w) {
  if (!p) return '';
  if (p.verdict === 'singular') {
    return `singular point (${w(p.value)} → ${w(p.refined[0])} → ${w(p.refined[1])} with the mesh there halved twice: no converged value)`;
  }
  if (p.error != null) return `± ${plain((100 * p.error) / p.value)} % (${p.verdict})`;
  return `unsettled (${w(p.value)} → ${w(p.refined[0])} → ${w(p.refined[1])}): no error stated`;
}

/** The report's Markdown, from the hello and the set-up the server keeps (`setup`: its last
 * message, or null without a set-up panel; `materialName`: a preset material's name).
 * @param {any} setup @param {(m: any) => string|null} [materialName] */
export function reportText(setup, materialName = (_m) => null) {
  const h = state.hello;
  if (!h) return '';
  const u = state.units, w = (v) => label(v, 'stress', u), len = (v) => label(v, 'length', u), force = (v) => label(v, 'force', 'si');
  const served = setup && setup.served;
  const out = [`# ${h.name}`, '', `Written by \`ves view\` on ${new Date().toISOString()}.`, ''];
  if (served) {
    const m = served.material || {};
    out.push('## Set-up', '',
      `- Geometry: ${(served.geometry || {}).step || h.name}`,
      `- Material: ${materialName(m) ? `${materialName(m)} — ` : ''}E ${plain(m.young / 1e9)} GPa, ν ${plain(m.poisson)}, ρ ${plain(m.density)} kg/m³${m.yield_strength ? `, yield ${w(m.yield_strength)}` : ''}`,
      `- Mesh: ${(served.mesh || {}).order === 1 ? '4' : '10'}-node tets, ${served.mesh && served.mesh.target_error !== undefined ? `until the error estimate is ${plain(100 * served.mesh.target_error)} %` : `element size ${len((served.mesh || {}).size)}`}; ${(served.modes || {}).count} modes${served.static_correction ? '; static correction (exact felt stiffness)' : ''}`,
      `- Held by: ${(served.fixed || []).length ? (served.fixed || []).map(supportText).join('; ') : 'nothing (a free body)'}`);
    const loads = (served.load || []).map(loadText);
    if (served.gravity) loads.push(`gravity: [${served.gravity.acceleration.map(plain).join(', ')}] m/s²`);
    if (loads.length) out.push(`- Loads: ${loads.join('; ')}`);
    out.push('');
  }
  if (setup && setup.summary) out.push('## Computed', '', setup.summary, '');
  if (setup && (setup.warnings || []).length) out.push('## Warnings', '', ...setup.warnings.map((t) => `- ${t}`), '');
  for (const s of h.spaces) {
    out.push(`## Space ${s.name}: frequencies`, '', row(['mode', 'frequency (Hz)']), row(['---', '---']));
    s.frequencies_hz.forEach((f, i) => out.push(row([String(i + 1), f.toPrecision(6)])));
    out.push('');
    if (!(s.loads || []).length) continue;
    out.push(`## Space ${s.name}: load cases`, '',
      row(['case', 'kind', 'total force', 'largest displacement', 'peak von Mises', 'its error', 'safety factor', 'support reaction']),
      row(Array(8).fill('---')));
    const ys = h.yield_strength;
    for (const c of s.loads) {
      const sf = ys && c.max_von_mises > 0 ? plain(ys / c.max_von_mises) + (c.peak && c.peak.verdict === 'singular' ? ' (from a singular peak)' : '') : '—';
      out.push(row([c.name, c.kind, force(Math.hypot(...c.total_force)), len(c.max_displacement), w(c.max_von_mises),
        peakText(c.peak, w) || '—', sf, `[${c.reaction.map(force).join(', ')}]`]));
    }
    const away = s.loads.filter((c) => c.regular_peak);
    if (away.length) {
      out.push('', 'Away from the singular points:', '');
      for (const c of away) {
        const r = c.regular_peak;
        out.push(`- ${c.name}: von Mises ${w(r.value)} ${peakText(r, w)} at (${r.position.map((x) => len(x)).join(', ')})`
          + (ys && r.value > 0 ? `, safety factor ${plain(ys / r.value)}` : ''));
      }
    }
    out.push('');
  }
  const pins = state.pins.filter((p) => p.space === state.active && p.vertex >= 0);
  if (pins.length && state.field && state.legend) {
    // The field's name without the legend's state ("…: at rest").
    const what = state.legend.title.replace(/: at rest$/, '');
    const live = !state.mode && !state.loadCase;
    const extremeOf = (p) => {
      const e = p.extremes[state.colour];
      return e === undefined ? '—' : quantityWords(state.field.quantity, e, u);
    };
    out.push(`## Probes pinned: ${what}`, '',
      live ? `Now, and the extreme (${state.colour === 'safety' ? 'lowest' : 'largest'}) over the part's last motion.` : 'As shown when the report was written.', '',
      row(['probe', 'vertex', 'position (part at rest)', 'now', ...(live ? ['extreme, last motion'] : [])]),
      row(Array(live ? 5 : 4).fill('---')));
    for (const p of pins) {
      out.push(row([`P${p.n}`, String(p.vertex), `(${p.rest.map(len).join(', ')})`, fieldWords(state.field, p.vertex, u),
        ...(live ? [extremeOf(p)] : [])]));
    }
    out.push('');
  }
  return out.join('\n');
}

/** Downloads the report as `NAME-report.md`.
 * @param {any} setup @param {(m: any) => string|null} [materialName] */
export function downloadReport(setup, materialName) {
  const name = (setup && setup.served && setup.served.name) || ((state.hello && state.hello.name) || 'part').replace(/\.[^.]*$/, '');
  download(new Blob([reportText(setup, materialName)], { type: 'text/markdown' }), `${name}-report.md`);
}
