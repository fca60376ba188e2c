// Design loads in the set-up panel: a force or a pressure on CAD faces, and gravity, written to
// the scene as `[[load]]` entries and `[gravity]` (docs/scene.md, service loads). Compute solves
// each as a static load case beside the modes; the load case list then shows it deformed and
// coloured by its von Mises stress, with its safety factor and reactions.
//
// The scene holds the force as a vector: the direction a row shows is read back from it (into
// or out of the first face when it is flat, along an axis, or typed), so nothing but the scene
// needs to be kept.
import { el } from './dom.js';
import { plain } from './units.js';

const MPA = 1e6;
/** @type {[string, number[]][]} */
const AXES = [['+x', [1, 0, 0]], ['-x', [-1, 0, 0]], ['+y', [0, 1, 0]], ['-y', [0, -1, 0]], ['+z', [0, 0, 1]], ['-z', [0, 0, -1]]];
const norm = (v) => Math.hypot(...v);
const scaled = (v, k) => v.map((x) => x * k);

/**
 * The loads' part of the panel.
 * @param {{ scene: () => any, edit: () => void, faceMode: Function, faceOf: (tag: number) => any,
 *   pickStarted: () => void, relight: () => void, note: (text: string) => void, list: HTMLElement, status: HTMLElement,
 *   pickButton: HTMLButtonElement }} ctx
 */
export function designLoads(ctx) {
  /** @type {any} the entry whose faces are being picked, or null */
  let picking = null;

  /** The directions a force on `entry` may take: into and out of its first face when that face
   * is flat (the hello's faces give its outward normal), and the six axes. */
  function directions(entry) {
    const out = [];
    const first = (entry.faces || []).map(ctx.faceOf).find((f) => f && f.kind === 'plane' && f.normal);
    if (first) {
      out.push([`into face ${first.tag}`, scaled(first.normal, -1 / norm(first.normal))]);
      out.push([`out of face ${first.tag}`, scaled(first.normal, 1 / norm(first.normal))]);
    }
    return out.concat(AXES);
  }

  /** A new force's direction: into `entry`'s first face when that face is flat, else down (-z). */
  function pushing(entry) {
    const d = directions(entry);
    return d.length > AXES.length ? d[0][1] : [0, 0, -1];
  }

  /** The area of `entry`'s faces (m²), when the page knows every one. */
  function area(entry) {
    const faces = (entry.faces || []).map(ctx.faceOf);
    return faces.length && faces.every((f) => f && f.area_m2 > 0) ? faces.reduce((s, f) => s + f.area_m2, 0) : null;
  }

  /** The name of a new load: load1, load2 … the first not taken. */
  function freshName(loads) {
    for (let k = 1; ; k += 1) if (!loads.some((l) => l.name === `load${k}`)) return `load${k}`;
  }

  function row(entry, i, loads) {
    const where = entry.faces ? `faces ${entry.faces.join(', ')}`
      : entry.plane ? `plane ${entry.plane.axis} = ${plain(entry.plane.value * 1e3)} mm` : 'box';
    const region = el('button', { textContent: where, title: entry.faces ? 'click to add or take faces' : '' });
    region.disabled = !entry.faces;
    region.onclick = () => startPicking(entry);
    const kind = el('select', { title: 'force: a total force spread over the faces by area · pressure: along the inward normal, positive pushes in' },
      ...['force', 'pressure'].map((k) => el('option', { value: k, textContent: k, selected: (entry.pressure !== undefined ? 'pressure' : 'force') === k })));
    const isForce = entry.pressure === undefined;
    const dirs = directions(entry);
    const f = entry.force || [0, 0, -1];
    const fn = norm(f) || 1;
    const shown = dirs.find(([, d]) => d.every((x, k) => Math.abs(f[k] / fn - x) < 1e-9));
    const magnitude = el('input', { type: 'number', step: 'any', min: '0', className: 'magnitude',
      value: plain(isForce ? norm(f) : Math.abs(entry.pressure) / MPA) });
    const unit = el('span', { textContent: isForce ? ' N ' : ' MPa' });
    const dir = el('select', { title: 'direction of the force' },
      ...dirs.map(([name]) => el('option', { value: name, textContent: name, selected: shown && shown[0] === name })),
      el('option', { value: 'typed', textContent: 'typed', selected: !shown }));
    const typed = ['x', 'y', 'z'].map((a, k) => el('input', { type: 'number', step: 'any', className: 'component', title: `F${a}, N`, value: plain(f[k]) }));
    const typedBox = el('span', { className: 'typed' }, ' [', typed[0], ', ', typed[1], ', ', typed[2], '] N');
    dir.hidden = !isForce;
    typedBox.hidden = !isForce || Boolean(shown);
    const unitOf = () => {
      const d = dirs.find(([name]) => name === dir.value);
      return d ? d[1] : scaled(entry.force, 1 / (norm(entry.force) || 1));
    };
    magnitude.onchange = () => {
      const m = Math.abs(Number(magnitude.value));
      if (entry.pressure !== undefined) entry.pressure = Math.sign(entry.pressure || 1) * m * MPA;
      else entry.force = scaled(unitOf(), m);
      changed();
    };
    dir.onchange = () => { if (dir.value !== 'typed') entry.force = scaled(unitOf(), norm(entry.force)); changed(); };
    typed.forEach((input, k) => {
      input.onchange = () => { entry.force = entry.force.slice(); entry.force[k] = Number(input.value); changed(); };
    });
    // Force ↔ pressure keeps the total when the faces' area is known (a pressure of F/A).
    kind.onchange = () => {
      const a = area(entry);
      if (kind.value === 'pressure') {
        const total = norm(entry.force || [0, 0, 0]);
        delete entry.force;
        entry.pressure = a && total > 0 ? total / a : MPA;
      } else {
        const p = entry.pressure;
        delete entry.pressure;
        entry.force = scaled(pushing(entry), a ? Math.abs(p) * a : 1000);
      }
      changed();
    };
    const del = el('button', { textContent: '×', title: 'remove' });
    del.onclick = () => { if (picking === entry) stopPicking(); loads.splice(i, 1); draw(); ctx.edit(); };
    return el('div', { className: 'designload' }, `${entry.name}: `, region, ' ', kind, ' ', magnitude, unit, dir, typedBox, ' ', del);
  }

  function gravityRow(scene) {
    const g = scene.gravity.acceleration;
    const gn = norm(g) || 9.81;
    const shown = AXES.find(([, d]) => d.every((x, k) => Math.abs(g[k] / gn - x) < 1e-9));
    const magnitude = el('input', { type: 'number', step: 'any', min: '0', className: 'magnitude', value: plain(gn) });
    const dir = el('select', { title: 'direction of the acceleration' },
      ...AXES.map(([name]) => el('option', { value: name, textContent: name, selected: shown && shown[0] === name })),
      ...(shown ? [] : [el('option', { value: 'typed', textContent: `[${g.map(plain).join(', ')}]`, selected: true })]));
    const set = () => {
      const d = AXES.find(([name]) => name === dir.value);
      const m = Math.abs(Number(magnitude.value));
      scene.gravity = { acceleration: d ? scaled(d[1], m) : scaled(g, m / gn) };
      changed();
    };
    magnitude.onchange = set;
    dir.onchange = set;
    const del = el('button', { textContent: '×', title: 'remove' });
    del.onclick = () => { delete scene.gravity; draw(); ctx.edit(); };
    return el('div', { className: 'designload' }, 'gravity: ', magnitude, ' m/s² ', dir, ' ', del);
  }

  /** An edit made in a row: the list redrawn from the scene, the scene sent. */
  function changed() {
    draw();
    ctx.edit();
  }

  /** The list as the scene says. */
  function draw() {
    const scene = ctx.scene();
    if (!scene) return;
    const loads = scene.load || [];
    const rows = loads.map((entry, i) => row(entry, i, loads));
    if (scene.gravity) rows.push(gravityRow(scene));
    ctx.list.replaceChildren(...rows);
    ctx.relight();
    const any = rows.length > 0;
    ctx.status.textContent = !any ? 'none' : (scene.fixed || []).length ? ''
      : 'a load needs the part held: add a support (a free body has no static answer)';
  }

  /** Clicks on faces add them to (or take them from) `entry`'s; a new load when null. */
  function startPicking(entry) {
    ctx.pickStarted();
    picking = entry || 'new';
    ctx.pickButton.textContent = 'done';
    ctx.note(entry ? `click the faces ${entry.name} acts on (again to take one away), then done`
      : 'click the faces the load acts on (again to take one away), then done');
    ctx.faceMode(true, toggle);
  }

  function stopPicking() {
    if (!picking) return false;
    picking = null;
    ctx.pickButton.textContent = '+ load on faces…';
    ctx.note('');
    ctx.faceMode(false, null);
    return true;
  }

  function toggle(tag) {
    const scene = ctx.scene();
    const loads = (scene.load ||= []);
    if (picking === 'new') {
      // A new load: 1 kN into its first face when that face is flat, else down.
      const entry = { name: freshName(loads), faces: [tag] };
      entry.force = scaled(pushing(entry), 1000);
      loads.push(entry);
      picking = entry;
    } else {
      const i = picking.faces.indexOf(tag);
      if (i >= 0) picking.faces.splice(i, 1); else picking.faces.push(tag);
      if (!picking.faces.length) {
        loads.splice(loads.indexOf(picking), 1);
        picking = 'new';
      }
    }
    if (!loads.length) delete scene.load;
    draw();
    ctx.edit();
    ctx.faceMode(true, toggle);
  }

  return {
    draw,
    stopPicking,
    /** "+ load on faces…": starts picking a new load, or ends the picking. */
    pickClicked() { if (!stopPicking()) startPicking(null); },
    /** "+ gravity": the part's weight along -z (9.81 m/s²), once. */
    addGravity() {
      const scene = ctx.scene();
      if (!scene.gravity) scene.gravity = { acceleration: [0, 0, -9.81] };
      draw();
      ctx.edit();
    },
  };
}
