// The ves view page: draws what the server's runtime computes and is its device. The mouse ray
// picks a surface vertex; its drag moves a hand in true units; the server's haptic loop couples
// the hand to the part and sends back frames (the elastic displacement, f32, and the pose) and
// a status (JSON). Only the drawing is magnified, by the deformation scale.
//
// This file wires the modules together: what each server message does, and the render loop.
// The state they share is state.js's; the tests see it through facade.js.
import { $ } from './dom.js';
import * as capture from './capture.js';
import { connect, frameShows, send } from './connection.js';
import { askFields, draw } from './drawing.js';
import { facade } from './facade.js';
import { clearHands, showHands } from './hands.js';
import { keptPins, placeTags, showLimit, showStatus } from './hud.js';
import { dropDrags, faceMode, faceOf, requestPick } from './interaction.js';
import { buildLoadList, drawLoad, hideLoad, loadsChecked, onLoad } from './loadcases.js';
import { animateMode, buildModeList, startMode } from './modes.js';
import { offerColours, overlay } from './panels.js';
import { KINDS } from './protocol.js';
import { setupPanel } from './setup.js';
import { downloadReport } from './report.js';
import { addSpace, clearSpaces, lightSetup, onFrame, onStress } from './spaces.js';
import { DRAW_WINDOW, state } from './state.js';
import { canvas, renderIfNeeded } from './viewport.js';

const setup = setupPanel(send, requestPick, faceMode, faceOf, lightSetup);
$('report').onclick = () => downloadReport(setup.last(), setup.materialName);
/** @type {any} */ (window).ves = facade(setup);

/** The modes of `space` listed (asking for one puts a load case away). */
const listModes = (space) => buildModeList(space, hideLoad);

function onHello(msg) {
  const again = state.hello !== null;
  const samePart = again && state.hello.name === msg.name;
  if (again) { state.reconnects += 1; clearSpaces(); clearHands(); }
  document.body.classList.remove('stale');
  state.hello = msg;
  // Another part: the probes this browser pinned on it before (a reload, or reopened).
  if (!samePart) state.pins = keptPins();
  state.lastSeq = -1;
  state.active = 0;
  state.keepView = samePart;
  state.episodePeak = 0;
  state.framesAtHello = state.frames;
  $('title').textContent = `VES view — ${msg.name}`;
  // The browser's tab follows the part served (it kept "VES view" whatever was open).
  document.title = `${msg.name} — VES view`;
  showLimit();
  if (msg.spaces.length) listModes(msg.spaces[0]); else $('modes').textContent = '';
  hideLoad();
  buildLoadList(msg.spaces[0]);
  setup.hello(msg);
  offerColours(msg);
  askFields();
}

function onText(msg) {
  if (msg.type === 'status') {
    state.status = msg;
    setup.computing(msg.computing, msg.checking);
    // Hands are drawn on a part: none before a basis is served.
    if (state.hello.spaces[msg.space]) showHands(msg.hands);
    showStatus(msg);
  } else if (msg.type === 'setup') {
    setup.state(msg);
  } else if (msg.type === 'load_error') {
    if (state.loadWanted) hideLoad();
    $('loadnote').textContent = `the load case could not be read: ${msg.message}`;
  } else if (msg.type === 'progress' || msg.type === 'computed' || msg.type === 'checked' || msg.type === 'compute_error') {
    if (msg.type === 'checked' && msg.loads) loadsChecked(msg.loads);
    state.notes.push(msg);
    if (state.notes.length > 200) state.notes.shift();
    setup.note(msg);
  }
}

function onBinary(kind, m) {
  if (kind === KINDS.MESH) addSpace(m, setup.litFaces());
  else if (kind === KINDS.FRAME) {
    // A frame of the basis before a swap may arrive after the new part's mesh: not this part's.
    if (!state.spaces[m.space] || m.vertices !== state.spaces[m.space].vertices) return;
    if (onFrame(m)) {
      // Another space is active: its modes and load cases are offered.
      const info = state.hello.spaces[m.space];
      listModes(info);
      hideLoad();
      buildLoadList(info);
    }
    frameShows(m.handSeq);
  } else if (kind === KINDS.MODE) startMode(m);
  else if (kind === KINDS.STRESS) onStress(m);
  else if (kind === KINDS.LOAD) onLoad(m);
}

function loop() {
  // The part is redrawn when something changed (a frame, its stress, the scale, the colouring),
  // not at every animation frame: 19.5k vertices' positions and colours cost the page's time.
  let drew = false;
  const s = state.spaces[state.active];
  if (state.mode) {
    animateMode();
    drew = true;
  } else if (state.dirty && s) {
    if (state.loadCase && state.loadCase.space === state.active) drawLoad(s, state.loadCase); else draw(s);
    state.dirty = false;
    drew = true;
    state.drawTimes[state.draws % DRAW_WINDOW] = performance.now();
    state.draws += 1;
  }
  if (renderIfNeeded(drew, capture.recording())) placeTags();
  if (capture.recording() && state.legend) capture.draw(canvas, state.legend, overlay());
  if (state.meshesIn && !state.ready && state.frames > state.framesAtHello && !state.dirty) state.ready = true;
  requestAnimationFrame(loop);
}

connect({ hello: onHello, text: onText, binary: onBinary, closed: dropDrags });
loop();
