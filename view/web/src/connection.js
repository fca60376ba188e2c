// The WebSocket to the server: connects, reconnects with a back-off when the server goes away,
// checks the protocol version (hello and every binary header), hands each message to the
// page's handlers, and sends the page's messages. Hand messages are timed until a frame shows
// that the haptic loop read them (the latency).
import { $ } from './dom.js';
import { ProtocolError, decode, helloMismatch } from './protocol.js';
import { state } from './state.js';

/** What the page says while the server is away. */
const GONE = 'the server is gone: what you see is no longer live';

/** @type {WebSocket|null} */
let ws = null;
let retry = 0;
/** What the page does with the server's messages. */
let handlers = {
  /** A hello, checked. @type {(msg: any) => void} */
  hello: () => {},
  /** Any other text message. @type {(msg: any) => void} */
  text: () => {},
  /** A binary message, decoded (protocol.js `decode`). @type {(kind: number, message: any) => void} */
  binary: () => {},
  /** The connection is gone (the page will try again). @type {() => void} */
  closed: () => {},
};

/** Connects (again after every close, unless refused), handing messages to `h` (see `handlers`). */
export function connect(h) {
  handlers = h;
  open();
}

function open() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    state.connected = true; retry = 0; $('conn').textContent = 'connected';
    // No longer true: said beside "connected · computing", it contradicted the status line.
    if ($('warn').textContent === GONE) $('warn').textContent = '';
  };
  ws.onclose = () => {
    state.connected = false; state.ready = false; state.meshesIn = false;
    if (state.refused) return; // the server speaks another protocol: a reload, not a retry
    handlers.closed();
    // Back off to one try every 5 s: a restarted server is found again without a reload.
    document.body.classList.add('stale');
    $('handinfo').textContent = '';
    $('warn').textContent = GONE;
    const wait = Math.min(5000, 250 * 2 ** retry++);
    $('conn').textContent = `disconnected — trying again in ${(wait / 1000).toFixed(1)} s`;
    setTimeout(open, wait);
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data === 'string') onText(JSON.parse(ev.data));
    else onBinary(ev.data);
  };
}

// A server of another protocol version (updated while this page was open): said once, and the
// page stops listening to it.
function refuse(why) {
  state.refused = why;
  $('warn').textContent = why;
  $('conn').textContent = 'refused';
  document.body.classList.add('stale');
  ws.close();
}

function onText(msg) {
  if (msg.type === 'hello') {
    const mismatch = helloMismatch(msg);
    if (mismatch) refuse(mismatch);
    else handlers.hello(msg);
  } else {
    handlers.text(msg);
  }
}

function onBinary(buf) {
  let got;
  try {
    got = decode(buf);
  } catch (e) {
    if (!(e instanceof ProtocolError)) throw e;
    if (e.foreign) refuse(e.message); else $('warn').textContent = `dropped ${e.message}`;
    return;
  }
  handlers.binary(got.kind, got.message);
}

/** The connection is open. */
export const isOpen = () => ws !== null && ws.readyState === 1;

/** Sends `msg` (JSON) if the connection is open. */
export function send(msg) {
  if (isOpen()) ws.send(JSON.stringify(msg));
}

// [time sent, hand message sequence, hand] awaiting a frame that reflects them.
const pending = [];
let handSeq = 0;

/** One hand message (`position`: m, part frame); its time is kept until a frame shows the haptic
 * loop read it (latency). */
export function sendTarget(hand, position, button, active) {
  if (!isOpen()) return;
  handSeq += 1;
  ws.send(JSON.stringify({ type: 'hand', hand, active, button, position, seq: handSeq }));
  pending.push([performance.now(), handSeq, hand]);
  if (pending.length > 1000) pending.shift();
  state.lastTarget = position;
}

/** A frame came whose state the haptic loop computed after reading, per hand, the hand
 * message `handSeq[h]`: the messages it shows are timed. */
export function frameShows(handSeq) {
  while (pending.length && handSeq[pending[0][2]] >= pending[0][1]) {
    const [t0] = pending.shift();
    state.latency.push(performance.now() - t0);
    if (state.latency.length > 500) state.latency.shift();
  }
}
