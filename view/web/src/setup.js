// The set-up panel: the part's material, mesh, modes and supports. The server owns the set-up:
// each edit goes to it and comes back to every page (a reload or a second tab shows the same
// set-up), with undo, redo and the history of computes. Compute sends the scene to the server,
// which runs the pipeline (meshing in its own process) and reports its stages here; when the
// basis is ready the live session moves to it and the page redraws the new mesh.
import { $, el } from './dom.js';
import { designLoads } from './designloads.js';
import { plain } from './units.js';
import { state } from './state.js';

/** Face `tag`'s name in the part's STEP file, as the hello lists it (cut to 30 characters), in
 * quotes after a space; '' when it has none.
 * @param {number} tag @returns {string} */
function faceName(tag) {
  const space = state.hello && state.hello.spaces && state.hello.spaces[0];
  const f = space && Array.isArray(space.faces) ? space.faces.find((/** @type {any} */ x) => x.tag === tag) : null;
  if (!f || typeof f.name !== 'string' || !f.name) return '';
  return ` “${f.name.length > 30 ? `${f.name.slice(0, 29)}…` : f.name}”`;
}

const MM = 1e-3;
// A preset is the material when its constants match to the fields' rounding.
const close = (a, b) => Math.abs(a - b) <= 1e-6 * Math.abs(b);
const isPreset = (p, m) => close(m.young, p.young) && close(m.poisson, p.poisson) && close(m.density, p.density);
// JSON with its keys sorted: the server's scenes come back in its order, not the page's.
const canon = (v) => JSON.stringify(v, (k, x) => (x && typeof x === 'object' && !Array.isArray(x)
  ? Object.fromEntries(Object.keys(x).sort().map((key) => [key, x[key]])) : x));
// The CLI's advice in the page's words: its scene key is this panel's box.
const inPage = (summary) => summary.replace('[static_correction] makes it exact', 'tick "exact felt stiffness" to make it exact');
const when = (t) => new Date(1000 * t).toLocaleString([], { month: 'short', day: 'numeric', hour: '2-digit', minute: '2-digit' });

/** Wires the panel to `send` (a JSON message to the server), `pick` (asks for one click on
 * the part: calls back with {point, normal}), `faceMode` (face picking on or off), `faceOf`
 * (the hello's record of a CAD face) and `light` (lights the faces held and loaded). Returns
 * handlers for the server's messages. */
export function setupPanel(send, pick, faceMode, faceOf, light) {
  let scene = null; // the scene being edited: the TOML's tables as JSON
  let geometry = null;
  let materials = [];
  let saved = null; // the TOML of the last basis computed
  let ready = null; // the summary of the basis in use while its checks run
  let sent = null; // the last scene sent or received (canonical JSON)
  // This page's edits are numbered on each connection; the server's set-up messages say the last
  // it had applied (`ack`): while a later one is on its way, a message does not refill the
  // panel over it (its own message follows).
  let seq = 0;
  let client = null;
  let told = false; // the server has said what the set-up is
  let busy = false; // a compute runs
  let last = null; // the server's last set-up message
  const panel = $('setup');

  // A part becomes held: "exact felt stiffness" goes on, unless the user chose for this part —
  // the kept modes alone make a held part feel stiffer than it is (on chunky parts 50–100×:
  // docs/accuracy.md, "The error of what is felt").
  let held = false; // the scene last filled or edited had supports
  let feltChosen = false; // the user ticked or unticked "exact felt stiffness"
  $('exactfelt').addEventListener('change', () => { feltChosen = true; showFeltNote(); });
  function showFeltNote() {
    const auto = !feltChosen && $('exactfelt').checked && !$('exactfelt').disabled;
    $('feltnote').textContent = auto ? ' (on for a held part: the modes alone feel too stiff; untick for a faster compute)' : '';
  }

  // An edit: the scene as the fields say goes to the server, which sends it to every page.
  function edit() {
    if (!scene) return;
    const nowHeld = (scene.fixed || []).length > 0;
    if (nowHeld && !held && !feltChosen) $('exactfelt').checked = true;
    held = nowHeld;
    showFeltNote();
    const now = read();
    const text = canon(now);
    if (text === sent) return;
    sent = text;
    seq += 1;
    send({ type: 'edit', scene: now, seq });
  }

  // Forces, pressures and gravity (designloads.js); picking their faces ends the supports'.
  const loads = designLoads({
    scene: () => scene,
    edit,
    faceMode,
    faceOf,
    pickStarted: () => stopPickingSupports(),
    relight: () => light(litFaces()),
    note: (text) => { problem(text); },
    list: $('designloads'),
    status: $('loadsnote'),
    pickButton: $('pickload'),
  });

  function fill() {
    const m = scene.material || {};
    const i = materials.findIndex((p) => isPreset(p, m));
    $('material').value = i >= 0 ? String(i) : 'custom';
    $('young').value = plain((m.young || 0) / 1e9);
    $('poisson').value = plain(m.poisson || 0);
    $('density').value = plain(m.density || 0);
    $('yield').value = m.yield_strength ? plain(m.yield_strength / 1e6) : '';
    $('unit').value = (scene.geometry || {}).unit === 'm' ? 'm' : 'mm';
    const mesh = scene.mesh || {};
    $('order').value = String(mesh.order || 2);
    const byError = mesh.target_error !== undefined;
    $('byerror').checked = byError; $('bysize').checked = !byError;
    $('target').value = byError ? plain(100 * mesh.target_error) : '5';
    $('localref').checked = mesh.refinement === 'local';
    $('size').value = mesh.size ? plain(mesh.size / MM) : '';
    $('modecount').value = String((scene.modes || {}).count || 12);
    $('stressfield').checked = Boolean((scene.stress || {}).enabled);
    $('exactfelt').checked = Boolean(scene.static_correction);
    held = (scene.fixed || []).length > 0;
    drawSupports();
    showFeltNote();
  }

  function drawSupports() {
    const list = $('supportlist');
    list.textContent = '';
    const fixed = scene.fixed || [];
    $('supportsnote').textContent = fixed.length ? '' : 'nothing: a free body';
    fixed.forEach((f, i) => {
      const row = document.createElement('div');
      row.className = 'support';
      if (f.plane) {
        const axis = el('select', {}, ...['x', 'y', 'z'].map((a) => el('option', { textContent: a, selected: a === f.plane.axis })));
        const value = el('input', { type: 'number', step: 'any', value: plain(f.plane.value / MM) });
        axis.onchange = () => { f.plane.axis = axis.value; };
        value.onchange = () => { f.plane.value = Number(value.value) * MM; };
        row.append('plane ', axis, ' = ', value, ' mm');
      } else if (f.box) {
        row.textContent = `box ${f.box.min.map((v) => plain(v / MM)).join(', ')} … ${f.box.max.map((v) => plain(v / MM)).join(', ')} mm`;
      } else if (f.faces) {
        row.textContent = `faces ${f.faces.map((t) => `${t}${faceName(t)}`).join(', ')}`;
      }
      // How it holds (docs/scene.md, support kinds): all components, one, or a kind with its own
      // FE counterpart — sliding (the face's normal only), bearing (a cylindrical face: radial,
      // free to turn), elastic (springs of a stiffness per area).
      const how = f.kind === 'bearing' && f.located ? 'located'
        : f.kind && f.kind !== 'clamped' ? f.kind : (f.components || ['x', 'y', 'z']).join(',');
      const held = el('select', {}, ...[['x,y,z', 'clamped'], ['x', 'x only'], ['y', 'y only'], ['z', 'z only'],
        ['sliding', 'sliding'], ['bearing', 'bearing'], ['located', 'located bearing'], ['elastic', 'elastic']]
        .map(([v, t]) => el('option', { value: v, textContent: t, selected: how === v })));
      // Short names keep the row one line wide at 280 px; what each does is in the tooltip.
      held.title = 'clamped: every component held · x/y/z only · sliding: the face\'s normal only · '
        + 'bearing: a cylindrical face held radially, free to turn, tilt and slide along its axis (floating) · '
        + 'located bearing: held along its axis too, still free to turn and tilt · '
        + 'elastic: a mount of the stiffness beside it (N/m³)';
      const stiffness = el('input', { type: 'number', step: 'any', min: '0', title: 'stiffness per area of the mount, N/m³',
        value: plain(f.stiffness || 1e9) });
      const unit = el('span', { textContent: ' N/m³' });
      const showStiffness = () => { stiffness.style.display = unit.style.display = held.value === 'elastic' ? '' : 'none'; };
      held.onchange = () => {
        delete f.components; delete f.kind; delete f.stiffness; delete f.located;
        if (['sliding', 'bearing', 'elastic'].includes(held.value)) f.kind = held.value;
        else if (held.value === 'located') { f.kind = 'bearing'; f.located = true; }
        else if (held.value !== 'x,y,z') f.components = held.value.split(',');
        if (held.value === 'elastic') f.stiffness = Number(stiffness.value);
        showStiffness();
      };
      // Only an elastic mount has a stiffness (the input's change can come after the choice).
      stiffness.onchange = () => { if (held.value === 'elastic') f.stiffness = Number(stiffness.value); };
      showStiffness();
      const del = document.createElement('button');
      del.textContent = '×';
      del.title = 'remove';
      del.onclick = () => { fixed.splice(i, 1); drawSupports(); edit(); };
      row.append(' ', held, stiffness, unit, ' ', del);
      list.appendChild(row);
    });
    // The static correction needs a held part (a free body's K is singular).
    $('exactfelt').disabled = !fixed.length;
    // Whether the loads have supports to react them.
    loads.draw();
  }

  // The fields back into the scene, in SI.
  function read() {
    const num = (id, k = 1) => Number($(id).value) * k;
    scene.material = { young: num('young', 1e9), poisson: num('poisson'), density: num('density') };
    if ($('yield').value.trim() !== '') scene.material.yield_strength = num('yield', 1e6);
    const mesh = { ...(scene.mesh || {}) };
    mesh.order = Number($('order').value);
    delete mesh.size; delete mesh.target_error; delete mesh.refinement;
    if ($('byerror').checked) {
      mesh.target_error = num('target', 0.01);
      if ($('localref').checked) mesh.refinement = 'local';
    } else mesh.size = num('size', MM);
    scene.mesh = mesh;
    scene.modes = { ...(scene.modes || {}), count: Math.round(num('modecount')) };
    scene.stress = { enabled: $('stressfield').checked };
    if ($('exactfelt').checked && (scene.fixed || []).length) scene.static_correction = { region: 'surface' };
    else delete scene.static_correction;
    // Only a BREP file's numbers need a unit: a STEP or IGES file states its own.
    const g = { ...(scene.geometry || {}) };
    if (/\.brep$/i.test(geometry || '')) g.unit = $('unit').value; else delete g.unit;
    scene.geometry = g;
    return scene;
  }

  $('material').onchange = (e) => {
    const p = materials[Number(e.target.value)];
    if (!p) return;
    $('young').value = plain(p.young / 1e9); $('poisson').value = plain(p.poisson);
    $('density').value = plain(p.density); $('yield').value = plain(p.yield_strength / 1e6);
  };
  for (const id of ['young', 'poisson', 'density', 'yield']) $(id).oninput = () => { $('material').value = 'custom'; };
  // Faces: while on, the face under the cursor is lit and a click adds it to (or takes it from)
  // the faces held; Done ends it.
  let picking = false;
  const heldFaces = () => (scene.fixed || []).filter((f) => f.faces).flatMap((f) => f.faces);
  const litFaces = () => ({ held: heldFaces(), loaded: (scene.load || []).filter((l) => l.faces).flatMap((l) => l.faces) });
  /** The scene's `faces` support, made when there is none. */
  const facesEntry = () => {
    const fixed = (scene.fixed ||= []);
    let entry = fixed.find((f) => f.faces);
    if (!entry) { entry = { faces: [] }; fixed.push(entry); }
    return entry;
  };
  const toggleFace = (tag) => {
    const fixed = (scene.fixed ||= []);
    const entry = facesEntry();
    const i = entry.faces.indexOf(tag);
    if (i >= 0) entry.faces.splice(i, 1); else entry.faces.push(tag);
    if (!entry.faces.length) fixed.splice(fixed.indexOf(entry), 1);
    drawSupports();
    edit();
    faceMode(true, toggleFace);
  };
  const stopPickingSupports = () => {
    if (!picking) return;
    picking = false;
    $('pickfaces').textContent = '+ faces…';
    faceMode(false, toggleFace);
  };
  $('pickfaces').onclick = () => {
    loads.stopPicking();
    picking = !picking;
    $('pickfaces').textContent = picking ? 'done' : '+ faces…';
    hint(picking ? 'click the faces that are held (again to let one go), then done' : '');
    faceMode(picking, toggleFace);
  };
  $('pickload').onclick = () => loads.pickClicked();
  $('addgravity').onclick = () => loads.addGravity();
  $('addplane').onclick = () => { (scene.fixed ||= []).push({ plane: { axis: 'x', value: 0 } }); drawSupports(); edit(); };
  $('pickplane').onclick = () => {
    hint('click a flat face of the part: the plane through it is held');
    pick(({ point, normal, outermost, face, faceWords }) => {
      // The axis the face faces most.
      const m = [normal.x, normal.y, normal.z];
      const n = m.map(Math.abs);
      const k = n.indexOf(Math.max(...n));
      const axis = 'xyz'[k];
      // A CAD face that is curved (the corpus block's +x end is a cylinder of 25 mm radius,
      // 0.5 mm proud) or slanted: a plane x, y or z = … through it holds only a line of nodes,
      // a singular support whose frequencies fall with every finer mesh. The face is what was meant.
      if (face && (face.kind !== 'plane' || n[k] < 0.99)) {
        const entry = facesEntry();
        if (!entry.faces.includes(face.tag)) entry.faces.push(face.tag);
        problem(`${faceWords} is ${face.kind !== 'plane' ? 'not flat' : `not square to ${axis}`}: `
          + 'held as that face (a plane through it would hold only a line of nodes)');
        drawSupports();
        edit();
        return;
      }
      // The plane through the clicked point, or through the CAD face's outermost point when that
      // is near: a click near a hole's rim would otherwise put the plane through whichever vertex
      // is nearest, holding a ring of nodes instead of the face.
      let value = [point.x, point.y, point.z][k];
      const out = outermost(k, Math.sign(m[k]));
      if (out !== null && Math.abs(out - value) <= 0.05 * state.diag) value = out;
      // A face through the origin: its f32 vertices read ±1e-16 m, shown as "1.11e-13 mm".
      if (Math.abs(value) <= 1e-7 * state.diag) value = 0;
      (scene.fixed ||= []).push({ plane: { axis, value } });
      problem(n[k] < 0.99 ? `that face is not square to ${axis}: the plane ${axis} = … through the point holds only what lies on it` : '');
      drawSupports();
      edit();
    });
  };
  $('compute').onclick = () => {
    problem('');
    const now = read();
    sent = canon(now);
    seq += 1;
    send({ type: 'compute', scene: now, seq });
  };
  // Cancel stops the compute and the server returns the set-up to the scene served.
  $('cancel').onclick = () => send({ type: 'cancel' });
  // Any field or choice changed (its own handler has run at the target first).
  panel.addEventListener('change', (e) => { if (e.target.id !== 'partfile') edit(); });
  $('undo').onclick = () => send({ type: 'undo' });
  $('redo').onclick = () => send({ type: 'redo' });
  $('revert').onclick = () => send({ type: 'revert' });
  // Ctrl+Z, Ctrl+Y and Ctrl+Shift+Z, outside a text field (where they edit the text).
  window.addEventListener('keydown', (e) => {
    if (panel.hidden || !(e.ctrlKey || e.metaKey) || /^(INPUT|SELECT|TEXTAREA)$/.test(document.activeElement?.tagName || '')) return;
    const k = e.key.toLowerCase();
    if (k === 'z' && !e.shiftKey) send({ type: 'undo' });
    else if (k === 'y' || (k === 'z' && e.shiftKey)) send({ type: 'redo' });
    else return;
    e.preventDefault();
  });

  /** What went wrong, in the panel's error line (red). */
  function problem(text) {
    $('setuperror').classList.remove('hint');
    $('setuperror').textContent = text;
    // In sight, whatever the panel's scroll (a trial missed "cancelled" below its fold).
    if (text) $('setuperror').scrollIntoView({ block: 'nearest' });
  }
  /** What to do next, in the same line (not red: an instruction is no error). */
  function hint(text) { $('setuperror').classList.add('hint'); $('setuperror').textContent = text; }

  /** The mesh solved, by its tets' shape quality: a bar per tenth of [0, 1] (those below 0.2
   * amber) and a line saying how many are poor and the worst. @param {any} mesh */
  function showMeshQuality(mesh) {
    // Ten counts, or nothing drawn (a project file brings them back: it is read as any input).
    const h = mesh && mesh.quality_histogram;
    const bins = Array.isArray(h) && h.length === 10 && h.every((n) => Number.isInteger(n) && n >= 0) ? h : null;
    $('meshquality').hidden = !bins;
    if (!bins) return;
    const total = bins.reduce((a, b) => a + b, 0), most = Math.max(1, ...bins);
    const poor = bins[0] + bins[1];
    $('meshqualitytext').textContent = `${total} tets by shape quality (0 flat … 1 regular): ${poor} below 0.2`
      + `${total ? ` (${plain((100 * poor) / total)} %)` : ''}, worst ${plain(mesh.worst_quality)}`;
    const ns = 'http://www.w3.org/2000/svg';
    $('meshqualitybars').replaceChildren(...bins.map((n, k) => {
      const r = document.createElementNS(ns, 'rect');
      // A bin with any tet shows at least a sliver: the poor tail is what matters.
      const h = n > 0 ? Math.max(1.5, (22 * n) / most) : 0;
      r.setAttribute('x', String(10 * k + 0.5)); r.setAttribute('width', '9');
      r.setAttribute('y', String(24 - h)); r.setAttribute('height', String(h));
      r.setAttribute('fill', k < 2 ? '#e0a030' : '#5fa8e8');
      const t = document.createElementNS(ns, 'title');
      t.textContent = `${plain(k / 10)}–${plain((k + 1) / 10)}: ${n} tets`;
      r.appendChild(t);
      return r;
    }));
  }

  // A warning as a line; a refinement that stopped short of its target (memory, max_dofs)
  // advises the target that accepts its mesh: one click sets it and computes again (the mesh
  // is remembered for this part, so the compute is one solve). A uniform one is also offered
  // to refine where the error is instead (`mesh.refinement = "local"`: on the ribplate it got
  // below 1 % where uniform refinement stopped at max_dofs; docs/accuracy.md).
  function warningRow(w) {
    const row = el('div', { textContent: `⚠ ${w}` });
    const m = /set mesh\.target_error = ([0-9.eE+-]+) to accept this one/.exec(w);
    const t = m ? Number(m[1]) : NaN;
    if (t > 0 && t <= 0.5) {
      const b = el('button', { textContent: `accept ${plain(100 * t)} %`, className: 'accept',
        title: `set the target error to ${plain(100 * t)} % and compute: the mesh it stopped on is kept` });
      b.onclick = () => {
        $('byerror').checked = true; $('bysize').checked = false;
        $('target').value = plain(100 * t);
        edit();
        $('compute').click();
      };
      const choices = [b];
      if (!$('localref').checked) {
        const local = el('button', { textContent: 'refine locally', className: 'accept',
          title: 'keep the target and refine only where the error is (mesh.refinement = "local"): fewer unknowns where the error sits at corners, fillets and junctions' });
        local.onclick = () => {
          $('localref').checked = true;
          edit();
          $('compute').click();
        };
        choices.push(local);
      }
      // First in its line: a long warning scrolls, the choices stay in view.
      row.prepend(...choices.flatMap((c) => [c, ' ']));
    }
    return row;
  }

  // What the panel says about the set-up: edits not computed, undo and redo, the history.
  function showState() {
    if (!last) return;
    const m = last;
    $('undo').disabled = m.undo === 0;
    $('redo').disabled = m.redo === 0;
    $('undo').title = `undo (Ctrl+Z): ${m.undo} step${m.undo === 1 ? '' : 's'}`;
    $('redo').title = `redo (Ctrl+Y): ${m.redo} step${m.redo === 1 ? '' : 's'}`;
    $('revert').disabled = !(m.edited && m.served);
    const edited = m.edited && m.served;
    $('edited').hidden = !edited;
    $('edited').textContent = busy ? 'edited since the part shown: being computed'
      : 'edited since the part shown, not computed: Compute applies the edits, revert drops them';
    panel.classList.toggle('edited', Boolean(edited));
    $('project').textContent = m.project ? `kept in ${m.project}` : 'not kept on disk';
    const h = m.history || [];
    $('historycount').textContent = String(h.length);
    $('historylist').replaceChildren(...h.slice().reverse().map((e) => el('div', {
      className: `entry ${e.outcome}`,
      textContent: `${when(e.unix_time)} · ${e.outcome}${e.changed.length ? ` (${e.changed.join(', ')})` : ''} · ${e.seconds.toFixed(1)} s${e.summary ? ` · ${e.summary}` : ''}`,
    })));
  }
  $('openpart').onclick = () => $('partfile').click();
  $('partfile').onchange = async (e) => {
    const file = e.target.files[0];
    e.target.value = '';
    if (!file) return;
    problem('');
    $('progresstext').textContent = `sending ${file.name}…`;
    try {
      const r = await fetch(`/open?name=${encodeURIComponent(file.name)}`, { method: 'POST', body: file });
      const answer = await r.json().catch(() => ({ error: `the server answered ${r.status}` }));
      if (answer.error) { problem(answer.error); $('progresstext').textContent = ''; }
      // Its project on the server was resumed: its basis is served as it was left, no compute.
      else if (typeof answer.resumed === 'number') {
        const n = answer.resumed;
        $('progresstext').textContent = `opened ${file.name}: its project resumed (${n} compute${n === 1 ? '' : 's'} before), nothing computed`;
      }
    } catch (err) {
      problem(`could not send ${file.name}: ${err.message}`);
    }
  };
  $('savescene').onclick = () => {
    if (!saved) return;
    const a = document.createElement('a');
    a.href = URL.createObjectURL(new Blob([saved], { type: 'application/toml' }));
    a.download = `${scene.name || 'part'}.toml`;
    a.click();
    setTimeout(() => URL.revokeObjectURL(a.href), 10000);
  };

  return {
    /** A hello: the panel shows when the server can compute; the fields are filled once per part. */
    hello(msg) {
      const s = msg.setup;
      // A new connection numbers its edits from 1 again.
      if (msg.client !== client) { client = msg.client; seq = 0; }
      panel.hidden = !s;
      if (!s) return;
      materials = s.materials;
      $('material').replaceChildren(...materials.map((m, i) => el('option', { value: String(i), textContent: m.name })),
        el('option', { value: 'custom', textContent: 'custom' }));
      // The set-up itself comes from the server's `setup` message; the starting scene only
      // until it does.
      if (geometry !== s.geometry || !scene) {
        geometry = s.geometry;
        $('geomname').textContent = geometry || '';
        $('geomname').title = geometry || '';
        // A STEP or IGES file states its unit: the choice is only for a BREP file.
        $('unitrow').hidden = !/\.brep$/i.test(geometry || '');
        if (!told || !scene) {
          scene = JSON.parse(JSON.stringify(s.scene));
          fill();
        }
      } else {
        read();
        const m = scene.material;
        const i = materials.findIndex((p) => isPreset(p, m));
        $('material').value = i >= 0 ? String(i) : 'custom';
      }
      $('savebasis').download = `${scene.name || 'part'}.h5`;
      $('savebasis').hidden = msg.spaces.length === 0;
    },
    /** The set-up every page shows: the draft fills the panel unless it is this page's own
     * edit coming back; the scene served is what "save scene" gives. */
    state(msg) {
      told = true;
      last = msg;
      const text = canon(msg.draft);
      // Refilled only when the draft is not what this page last sent or was sent: a field
      // changed here and not yet sent (typed, no change event yet) is not taken back.
      if ((msg.ack || 0) >= seq) {
        if (!scene || text !== sent) {
          scene = JSON.parse(JSON.stringify(msg.draft));
          fill();
        }
        sent = text;
      }
      saved = msg.served_toml || null;
      $('savescene').disabled = !saved;
      // The served basis's warnings (a thin wall, an estimate above its target, a refinement
      // stopped by memory …), as the CLI prints them: not only on the server's stderr.
      $('computewarnings').replaceChildren(...(msg.warnings || []).map(warningRow));
      // A page opened (or reloaded) after the compute: what is served, not an empty line.
      if (msg.summary && !$('progresstext').textContent) $('progresstext').textContent = `computed: ${inPage(msg.summary)}`;
      showMeshQuality(msg.mesh);
      // A part opened in the page and not computed yet: the panel is its set-up, the drawing
      // still the part before (put back if the new one does not compute).
      $('geomname').textContent = msg.opening ? `opening ${msg.opening}… (${geometry || 'the part'} shown)` : geometry || '';
      showState();
    },
    /** Compute progress, its end, or why it failed. */
    note(msg) {
      if (msg.type === 'progress') {
        // A new compute: the last one's error or "cancelled" no longer stands under it.
        if (msg.stage === 'starting') { ready = null; problem(''); }
        $('progressbar').style.width = `${(100 * msg.fraction).toFixed(0)}%`;
        // After the swap the part is in use while its error estimate is made.
        $('progresstext').textContent = (ready ? `ready: ${ready} · ` : '') + `${msg.stage} — ${(100 * msg.fraction).toFixed(0)} %`;
      } else if (msg.type === 'computed') {
        ready = msg.summary;
        problem('');
        $('progressbar').style.width = '100%';
        $('progresstext').textContent = `computed: ${inPage(msg.summary)}`;
        showMeshQuality(msg.mesh);
        saved = msg.scene;
        $('savescene').disabled = false;
      } else if (msg.type === 'checked') {
        ready = null;
        $('progressbar').style.width = '100%';
        $('progresstext').textContent = msg.error ? `computed; its checks did not finish: ${msg.error}` : `computed: ${inPage(msg.summary)}`;
      } else if (msg.type === 'compute_error') {
        $('progresstext').textContent = '';
        $('progressbar').style.width = '0';
        problem(msg.message);
      }
    },
    /** The status says whether a compute runs, and whether only its checks remain (the part is
     * in use: Compute stops them and starts again). */
    computing(on, checking) {
      $('compute').disabled = on && !checking;
      $('cancel').disabled = !on;
      if (busy !== (on && !checking)) { busy = on && !checking; showState(); }
    },
    /** The faces held and the ones loaded (tags), for drawing them. */
    litFaces: () => (scene ? litFaces() : { held: [], loaded: [] }),
    /** The scene being edited (tests and the console). */
    scene: () => read(),
    saved: () => saved,
    /** The server's last set-up message. */
    last: () => last,
    /** The name of the preset material `m` is (E, ν, ρ), or null for a custom one. */
    materialName: (m) => (m && materials.find((p) => isPreset(p, m))?.name) || null,
  };
}
