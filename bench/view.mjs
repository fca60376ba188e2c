// Measures `ves view` as a user meets it: pointer-to-frame latency while dragging, frames per
// second received and drawn with 1 and with 20 clients, and the server's resident memory after
// 20 clients connect and vanish (dropped without a close). Run by bench/view.sh, which starts
// the server; prints one JSON object.
//
// usage: node bench/view.mjs URL SERVER_PID WEB_DIR
import { readFileSync } from 'node:fs';
import { pathToFileURL } from 'node:url';

const [url, pid, webDir] = process.argv.slice(2);
const mod = (p) => import(pathToFileURL(`${webDir}/node_modules/${p}`).href);
const { chromium } = await mod('playwright-core/index.mjs');
const { default: WebSocket } = await mod('ws/wrapper.mjs');
const { KINDS, kindOf } = await import(pathToFileURL(`${webDir}/src/protocol.js`).href);
const rss = () => Number(/VmRSS:\s+(\d+)/.exec(readFileSync(`/proc/${pid}/status`, 'utf8'))[1]) * 1024;
const sleep = (ms) => new Promise((r) => setTimeout(r, ms));
const quantile = (a, q) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[Math.min(s.length - 1, Math.floor(q * s.length))] : null; };

// Plain WebSocket clients counting the frames they receive.
function client() {
  // The server takes WebSockets from its own page only; a browser sends this Origin itself.
  const c = { frames: 0, ws: new WebSocket(url.replace('http', 'ws') + 'ws', { origin: new URL(url).origin }) };
  c.ws.on('message', (data, binary) => { if (binary && kindOf(new Uint8Array(data).buffer) === KINDS.FRAME) c.frames += 1; });
  c.open = new Promise((r) => c.ws.on('open', r));
  return c;
}
async function receivedRate(clients, seconds) {
  const f0 = clients.map((c) => c.frames);
  await sleep(seconds * 1000);
  return clients.map((c, i) => (c.frames - f0[i]) / seconds);
}

const browser = await chromium.launch({
  executablePath: process.env.VES_CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--no-first-run'],
});
const out = { rss_bytes_start: rss() };
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready && window.ves.frames > 3, null, { timeout: 60000 });
  out.vertices = await page.evaluate(() => window.ves.spaces[0].vertices);
  const pageRate = async (seconds) => {
    const f0 = await page.evaluate(() => window.ves.frames);
    await sleep(seconds * 1000);
    return ((await page.evaluate(() => window.ves.frames)) - f0) / seconds;
  };
  const drawnFps = () => page.evaluate(() => window.ves.framesPerSecond);

  // Drag: grab the vertex drawn nearest the middle of the screen, then move 6 s.
  const [x, y] = await page.evaluate(() => {
    const s = window.ves.spaces[0];
    let best = [600, 400], bd = Infinity;
    for (let v = 0; v < s.vertices; v += 7) {
      const p = window.ves.screenOf(0, v);
      const d = (p[0] - 600) ** 2 + (p[1] - 400) ** 2;
      if (d < bd) { bd = d; best = p; }
    }
    return best;
  });
  await page.mouse.move(x, y);
  await page.mouse.down();
  const t0 = Date.now();
  let k = 0;
  while (Date.now() - t0 < 6000) {
    k += 1;
    await page.mouse.move(x + 20 * Math.sin(k / 10), y + 20 * Math.cos(k / 13));
    await sleep(16);
  }
  const lat = await page.evaluate(() => window.ves.latency.splice(0));
  out.latency_ms = { events: lat.length, median: quantile(lat, 0.5), p95: quantile(lat, 0.95), max: Math.max(...lat) };
  await page.mouse.up();
  // The same path without the browser's input pipeline: the page itself sends a hand message
  // every 16 ms for 6 s (window.ves.drive), moving a grabbed vertex in a small circle.
  out.latency_scripted_ms = await page.evaluate(async () => {
    const v = window.ves;
    const s = v.spaces[0];
    const i = s.vertices >> 1;
    const p0 = [s.rest[3 * i], s.rest[3 * i + 1], s.rest[3 * i + 2]];
    const r = 0.002 * v.diag;
    v.latency.length = 0;
    for (let k = 0; k < 375; k++) {
      v.drive(0, [p0[0] + r * Math.sin(k / 10), p0[1] + r * Math.cos(k / 10), p0[2]]);
      await new Promise((ok) => setTimeout(ok, 16));
    }
    v.release(0);
    await new Promise((ok) => setTimeout(ok, 300));
    const l = v.latency.slice().sort((a, b) => a - b);
    return { events: l.length, median: l[l.length >> 1], p95: l[Math.floor(0.95 * l.length)], max: l[l.length - 1] };
  });
  out.one_client = { received_fps: await pageRate(4), drawn_fps: await drawnFps() };

  // Nineteen more clients: 20 in all.
  const others = Array.from({ length: 19 }, client);
  await Promise.all(others.map((c) => c.open));
  await sleep(1000);
  const [pageFps, otherFps] = await Promise.all([pageRate(4), receivedRate(others, 4)]);
  out.twenty_clients = {
    page_received_fps: pageFps,
    page_drawn_fps: await drawnFps(),
    others_received_fps: { min: Math.min(...otherFps), median: quantile(otherFps, 0.5), max: Math.max(...otherFps) },
    rss_bytes: rss(),
  };
  // They vanish: sockets destroyed without a WebSocket close, as a crashed or disconnected tab.
  for (const c of others) c.ws.terminate();
  // And 20 more come and go the same way, twice.
  for (let round = 0; round < 2; round++) {
    const burst = Array.from({ length: 20 }, client);
    await Promise.all(burst.map((c) => c.open));
    await sleep(500);
    for (const c of burst) c.ws.terminate();
  }
  await sleep(3000);
  out.after_vanish = { rss_bytes: rss(), page_received_fps: await pageRate(3), clients: await page.evaluate(() => window.ves.status.clients) };
} finally {
  await browser.close();
}
console.log(JSON.stringify(out));
