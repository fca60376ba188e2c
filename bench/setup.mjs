// From "Compute" to a pullable part in `ves view SCENE.toml`, and the haptic loop beside a
// compute. Run by bench/setup.sh (which starts the server with an empty mesh cache). A client
// speaks the page's protocol over the WebSocket — what the page sends on Compute, what it needs
// before the part can be pulled (the new hello and its meshes) — without a browser: this VM has
// no GPU, and headless Chromium's software GPU process (at nice −8 when run as root) keeps ~90 %
// of a core busy, which would measure the browser, not the server.
//
// It waits for the first compute (cold: nothing cached) and its error estimate, then changes only
// how the supports hold — every support along z only, along x and z, along y and z, then along
// z only once more and clamped as at first (set-ups computed before, served from their kept
// bases) — and asks for a compute; each time from the request to the new hello and meshes
// (pullable), and to the estimate. Prints one JSON object.
//
// usage: node --experimental-websocket bench/setup.mjs URL
import { KINDS, kindOf } from '../view/web/src/protocol.js';

const [url] = process.argv.slice(2);
const origin = new URL(url).origin;
const ws = new WebSocket(`${origin.replace('http', 'ws')}/ws`, { headers: { Origin: origin } });
ws.binaryType = 'arraybuffer';

const notes = [];
let hello = null, meshes = 0, waiters = [];
const settle = () => { waiters = waiters.filter(([test, done]) => !(test() && (done(), true))); };
const until = (test, what, seconds = 900) => new Promise((done, fail) => {
  if (test()) return done();
  const timer = setTimeout(() => fail(new Error(`no ${what} within ${seconds} s`)), seconds * 1000);
  waiters.push([test, () => { clearTimeout(timer); done(); }]);
});
ws.onmessage = (e) => {
  if (typeof e.data === 'string') {
    const m = JSON.parse(e.data);
    if (m.type === 'hello') { hello = m; meshes = 0; }
    else if (['progress', 'computed', 'checked', 'compute_error'].includes(m.type)) notes.push({ ...m, at: Date.now() });
  } else if (kindOf(e.data) === KINDS.MESH) meshes += 1;
  settle();
};
const count = (type) => notes.filter((n) => n.type === type).length;
const pullable = () => hello && hello.spaces.length > 0 && meshes >= hello.spaces.length;

try {
  await until(() => ws.readyState === 1, 'connection', 30);
  await until(() => count('checked') > 0 || count('compute_error') > 0, 'first compute and estimate');
  if (count('compute_error')) throw new Error(notes.find((n) => n.type === 'compute_error').message);
  const first = notes.find((n) => n.type === 'computed');
  const firstChecked = notes.find((n) => n.type === 'checked');
  const scene = JSON.parse(JSON.stringify(hello.setup.scene));
  const runs = [];
  const sets = [['z only', ['z']], ['x and z', ['x', 'z']], ['y and z', ['y', 'z']], ['z only again', ['z']],
    ['clamped again', null]];
  for (const [held, components] of sets) {
    for (const f of scene.fixed || []) {
      if (components) f.components = components; else delete f.components;
    }
    const [c0, k0] = [count('computed') + count('compute_error'), count('checked')];
    hello = null;
    const t0 = Date.now();
    ws.send(JSON.stringify({ type: 'compute', scene }));
    await until(() => count('computed') + count('compute_error') > c0, 'compute');
    const done = notes.filter((n) => n.type === 'computed' || n.type === 'compute_error').at(-1);
    if (done.type === 'compute_error') throw new Error(done.message);
    await until(pullable, 'new hello and meshes', 60);
    const ready = (Date.now() - t0) / 1000;
    await until(() => count('checked') > k0, 'estimate');
    const est = notes.filter((n) => n.type === 'checked').at(-1);
    // With an instant basis first (ves view's default), the converged one follows.
    const converged = notes.filter((n) => n.type === 'computed' && n.live !== 'instant' && n.at >= t0).at(0);
    runs.push({ held, first_live: done.live, request_to_pullable_s: ready, server_s: done.seconds,
      summary: done.summary, request_to_converged_s: converged ? (converged.at - t0) / 1000 : null,
      converged: converged ? converged.summary : null, request_to_estimate_s: (est.at - t0) / 1000, estimate: est.summary || est.error });
  }
  console.log(JSON.stringify({ cold: { server_s: first.seconds, summary: first.summary, estimate_s: firstChecked.seconds,
    estimate: firstChecked.summary || firstChecked.error }, supports_changed: runs }));
} finally {
  ws.close();
}
