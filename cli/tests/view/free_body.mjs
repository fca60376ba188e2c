// `ves view` on a free body in a real headless Chromium: a hand drags the free beam away, the
// deformation scale goes to 200, and the page must still draw the body where its rigid motion
// puts it (the elastic part alone is magnified). Then the server is restarted by the Rust test
// (this script prints "RESTART" and waits) and the page must reconnect by itself. Last, a
// 420 px wide window must leave the part visible. Prints one JSON object as its last line.
//
// usage: node free_body.mjs URL WEB_DIR SCREENSHOT_DIR
import { handAt, launch, newPage, rendered, until } from './browser.mjs';

const [url, webDir, shots] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
const ready = (p) => p.waitForFunction(() => window.ves && window.ves.ready, null, { timeout: 40000 });
try {
  const page = await newPage(browser, errors);
  await page.goto(url);
  await ready(page);
  // Grab the beam's free end and carry it 0.2 m up and 0.1 m sideways in 20 steps (each at the
  // server before the next), then hold until the body has followed the hand.
  const start = await page.evaluate(() => {
    const s = window.ves.spaces[0];
    const v = window.ves.nearestVertex(0, [1.0, 0.05, 0.05]);
    return Array.from(s.rest.subarray(3 * v, 3 * v + 3));
  });
  for (let k = 0; k <= 20; k++) {
    const t = k / 20;
    await page.evaluate((p) => window.ves.drive(0, p), [start[0], start[1] + 0.1 * t, start[2] + 0.2 * t]);
    await handAt(page, 0);
  }
  await until(page, () => {
    const q = window.ves.spaces[0].pose, c = window.ves.hello.center;
    return q && Math.hypot(q[0] - c[0], q[1] - c[1], q[2] - c[2]) > 0.1;
  });
  await page.evaluate(() => window.ves.setScale(200));
  await page.waitForFunction(() => window.ves.drawnScale === 200 && !window.ves.dirty, null, { timeout: 10000 });
  // The drawn centroid against the rigid motion alone, computed here from the pose the page drew
  // with: x + R(mean(rest) − c).
  const body = await page.evaluate(() => {
    const s = window.ves.spaces[0];
    const p = window.ves.drawnPositions(0);
    const mean = (a) => [0, 1, 2].map((k) => { let t = 0; for (let i = k; i < a.length; i += 3) t += a[i]; return t / (a.length / 3); });
    return { drawn: mean(p), rest: mean(s.rest), pose: s.drawnPose, center: window.ves.hello.center, scale: window.ves.drawnScale };
  });
  const [px, py, pz, w, x, y, z] = body.pose;
  const d = body.rest.map((v, k) => v - body.center[k]);
  // Rotate d by the unit quaternion (w, x, y, z): d + 2w(q×d) + 2q×(q×d).
  const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]];
  const q = [x, y, z];
  const t1 = cross(q, d).map((v) => 2 * v);
  const t2 = cross(q, t1);
  const rotated = d.map((v, k) => v + w * t1[k] + t2[k]);
  body.expected = [px, py, pz].map((v, k) => v + rotated[k]);
  body.miss = Math.hypot(...body.drawn.map((v, k) => v - body.expected[k]));
  body.moved = Math.hypot(px - body.center[0], py - body.center[1], pz - body.center[2]);
  await page.screenshot({ path: `${shots}/free_body_scale200.png` });

  // The server goes away and comes back on the same port: the page reconnects by itself.
  const before = await page.evaluate(() => window.ves.reconnects);
  console.log('RESTART');
  await page.waitForFunction(() => !window.ves.connected, null, { timeout: 20000 });
  const down = await page.evaluate(() => document.getElementById('conn').textContent);
  await page.waitForFunction((n) => window.ves.reconnects > n && window.ves.ready, before, { timeout: 60000 });
  const after = await page.evaluate(() => ({ reconnects: window.ves.reconnects, conn: document.getElementById('conn').textContent, frames: window.ves.frames, warn: document.getElementById('warn').textContent, tab: document.title }));

  // A 420 px wide window: the panels fold and the middle of the part is not under any of them.
  const small = await newPage(browser, errors, { width: 420, height: 760 });
  await small.goto(url);
  await ready(small);
  await rendered(small);
  const narrow = await small.evaluate(() => {
    const [x0, y0, x1, y1] = window.ves.drawnExtent();
    const probes = [[0.5, 0.5], [0.25, 0.5], [0.75, 0.5]].map(([a, b]) => [x0 + a * (x1 - x0), y0 + b * (y1 - y0)]);
    return { extent: [x0, y0, x1, y1], visible: probes.map(([x, y]) => document.elementFromPoint(x, y)?.id === 'view') };
  });
  await small.screenshot({ path: `${shots}/narrow_420px.png` });
  console.log(JSON.stringify({ body, down, after, before, narrow, errors }));
} finally {
  await browser.close();
}
