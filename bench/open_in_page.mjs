// Times opening a part in the page as a user does: `ves view PART.step` started with an empty
// mesh cache and no project, one WebSocket client (the page's protocol) connected as soon as
// the URL is printed; the part is pullable when the first basis's surface mesh arrives (after
// its `computed` note). Prints one JSON line: seconds from the server's start to the URL, to
// the first `computed` note (which basis: "instant" for the first look, "converged"), to its
// mesh, and to the converged basis when it comes within the time allowed.
//
// usage: node bench/open_in_page.mjs VES PART.step WEB_DIR [SECONDS]
import { spawn } from 'node:child_process';
import { mkdtempSync, copyFileSync, rmSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { basename, join } from 'node:path';
import { pathToFileURL } from 'node:url';

const [ves, part, webDir, limit = '240'] = process.argv.slice(2);
const mod = (p) => import(pathToFileURL(`${webDir}/node_modules/${p}`).href);
const { default: WebSocket } = await mod('ws/wrapper.mjs');
const { KINDS, kindOf } = await import(pathToFileURL(`${webDir}/src/protocol.js`).href);

const work = mkdtempSync(join(tmpdir(), 'ves-open-'));
const step = join(work, basename(part));
copyFileSync(part, step);
const t0 = performance.now();
const secs = () => Math.round(performance.now() - t0) / 1000;
const server = spawn(ves, ['view', step, '--port', '0', '--no-project'], {
  env: { ...process.env, VES_CACHE_DIR: join(work, 'cache') },
  stdio: ['ignore', 'pipe', 'ignore'],
});
const out = { part: basename(part) };
const done = (code) => {
  server.kill('SIGINT');
  rmSync(work, { recursive: true, force: true });
  console.log(JSON.stringify(out));
  process.exit(code);
};
setTimeout(() => { out.timeout_s = Number(limit); done(0); }, Number(limit) * 1000);
let text = '';
server.stdout.on('data', (d) => {
  text += d;
  const m = /http:\/\/[^\s]+/.exec(text);
  if (!m || out.url_s) return;
  out.url_s = secs();
  const url = m[0];
  const ws = new WebSocket(url.replace('http', 'ws') + 'ws', { origin: new URL(url).origin });
  // A basis comes as a hello, its surface mesh (binary), then its `computed` note.
  let lastMesh = null;
  ws.on('message', (data, binary) => {
    if (binary) {
      if (kindOf(new Uint8Array(data).buffer) === KINDS.MESH) lastMesh = secs();
      return;
    }
    const msg = JSON.parse(data.toString());
    if (msg.type === 'computed') {
      const live = msg.live || 'converged';
      if (out.pullable_s === undefined) {
        out.pullable_s = lastMesh;
        out.first_live = live;
        out.first_summary = msg.summary;
      }
      if (live === 'converged') {
        out.converged_pullable_s = lastMesh;
        out.converged_summary = msg.summary;
        done(0);
      }
    } else if (msg.type === 'compute_error') {
      out.error = msg.message;
      done(1);
    }
  });
});
