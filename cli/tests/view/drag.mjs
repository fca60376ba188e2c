// End-to-end check of `ves view` in a real headless Chromium (Debian's, driven by playwright-core
// from view/web's lockfile): open the page, grab the cantilever's tip with the mouse, pull it,
// hold, and report what the page itself shows. Then send malformed messages over the page's own
// WebSocket and check that frames still arrive. Prints one JSON object; the Rust test asserts.
//
// usage: node drag.mjs URL WEB_DIR SCREENSHOT.png
import { handAt, launch, newPage, rendered, statuses, steady, until } from './browser.mjs';

const [url, webDir, shot] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
try {
  const page = await newPage(browser, errors);
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready && window.ves.frames > 3, null, { timeout: 30000 });

  // At rest the legend says so instead of spreading its colours over round-off.
  const atRest = await page.evaluate(() => ({ legend: window.ves.legend, scale: window.ves.drawnScale, auto: window.ves.scaleAuto }));

  // The tip's top edge, middle: where a user would grab a cantilever to pull it down.
  const vertex = await page.evaluate(() => window.ves.nearestVertex(0, [1.0, 0.05, 0.05]));
  const root = await page.evaluate(() => window.ves.nearestVertex(0, [0.0, 0.05, 0.05]));
  const [x, y] = await page.evaluate((v) => window.ves.screenOf(0, v), vertex);
  const [rx, ry] = await page.evaluate((v) => window.ves.screenOf(0, v), root);

  // Probes pinned by double-clicks: one at mid-span stays, one near the root is pinned and
  // unpinned by a second double-click on it.
  const midSpan = await page.evaluate(() => window.ves.nearestVertex(0, [0.5, 0.05, 0.05]));
  const nearRoot = await page.evaluate(() => window.ves.nearestVertex(0, [0.2, 0.05, 0.05]));
  for (const v of [midSpan, nearRoot, nearRoot]) {
    const [px, py] = await page.evaluate((w) => window.ves.screenOf(0, w), v);
    await page.mouse.dblclick(px, py);
    await until(page, () => !window.ves.status.hands[0].active);
    await rendered(page);
  }
  const pinnedAtRest = await page.evaluate(() => window.ves.pins);
  await page.mouse.move(x, y);
  await page.mouse.down();
  const pixels = 60;
  // Each step of the drag reaches the server before the next.
  for (let k = 1; k <= 12; k++) {
    await page.mouse.move(x, y + (pixels * k) / 12);
    await handAt(page, 0);
  }
  // Held until the grabbed vertex's true displacement is steady.
  await steady(page, vertex);
  const [x2, y2] = await page.evaluate((v) => window.ves.screenOf(0, v), vertex);
  const held = await page.evaluate((v) => {
    const s = window.ves.spaces[0];
    const h = window.ves.status.hands[0];
    return {
      target: window.ves.lastTarget,
      hand: h,
      // What the clamped root carries, from the same status, and its label beside the root.
      supports: window.ves.status.supports,
      supportLabel: [...document.querySelectorAll('.supportlabel')].filter((t) => t.style.display !== 'none').map((t) => t.textContent),
      rest: Array.from(s.rest.subarray(3 * v, 3 * v + 3)),
      // Read back as drawn: the true position (k = 1) and the magnified one.
      position: window.ves.trueOf(0, v),
      u: Array.from(s.u.subarray(3 * v, 3 * v + 3)),
      drawn: window.ves.drawnOf(0, v),
      scale: window.ves.drawnScale,
      drawnPose: s.drawnPose,
      umag: s.umag[v],
      legend: window.ves.legend,
      scaleText: document.getElementById('scaleshown').textContent,
      handText: document.getElementById('handinfo').textContent,
      latency_ms: window.ves.latency.slice(),
      frames: window.ves.frames,
      // The pinned probes as drawn in the same frame: vertex, |u| there, the label.
      pins: window.ves.pins,
      pinU: window.ves.pins.map((p) => Array.from(s.u.subarray(3 * p.vertex, 3 * p.vertex + 3))),
    };
  }, vertex);
  held.screenMoved = Math.hypot(x2 - x, y2 - y);
  held.screenLength = Math.hypot(x - rx, y - ry);
  await page.screenshot({ path: shot });
  // The same moment coloured by von Mises stress: the clamped root is the hot spot.
  await page.selectOption('#colour', 'vonmises');
  await page.waitForFunction(() => window.ves.spaces[0].vm && window.ves.legend.title === 'von Mises stress' && !window.ves.dirty, null, { timeout: 20000 });
  await rendered(page);
  const vonMisesLegend = await page.evaluate(() => [document.getElementById('legendtitle').textContent, document.getElementById('hi').textContent]);
  await page.screenshot({ path: shot.replace(/\.png$/, '_von_mises.png') });
  await page.selectOption('#colour', 'displacement');

  // A second client shares the session: it may drive the other hand, not the one held here.
  const other = await newPage(browser, errors);
  await other.goto(url);
  await other.waitForFunction(() => window.ves && window.ves.ready && window.ves.status, null, { timeout: 30000 });
  const mid = await other.evaluate(() => window.ves.nearestVertex(0, [0.5, 0.05, 0.05]));
  const [mx, my] = await other.evaluate((v) => window.ves.screenOf(0, v), mid);
  await other.mouse.move(mx, my);
  await other.mouse.down();
  await other.mouse.move(mx, my + 20, { steps: 5 });
  await handAt(other, 1);
  const second = await other.evaluate(() => ({ client: window.ves.hello.client, hands: window.ves.status.hands }));
  await other.mouse.up();
  await other.close();

  await page.mouse.up();
  await until(page, () => !window.ves.status.hands[0].active);
  const released = await page.evaluate(() => window.ves.status.hands[0].active);
  // The report after the pull: the pinned probe's value now and its extreme over the pull.
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#report')]);
  const reportPath = shot.replace(/\.png$/, '_report.md');
  await download.saveAs(reportPath);
  const report = (await import('node:fs')).readFileSync(reportPath, 'utf8');
  const probes = report.slice(report.indexOf('## Probes pinned'));

  // Malformed input through a socket of its own: text garbage, binary, oversized, a non-finite
  // position (JSON has no NaN: null), a hand that does not exist. All five must be dropped. A
  // good mode request last: the server reads a socket in order, so its answer means all six
  // were handled.
  const before = await page.evaluate(() => window.ves.frames);
  const droppedBefore = await page.evaluate(() => window.ves.status.messages_dropped);
  await page.evaluate(() => {
    const ws = new WebSocket(`ws://${location.host}/ws`);
    ws.binaryType = 'arraybuffer';
    return new Promise((done) => {
      ws.onmessage = (ev) => { if (typeof ev.data !== 'string' && window.ves.kindOf(ev.data) === 2) { ws.close(); done(); } };
      ws.onopen = () => {
        ws.send('garbage');
        ws.send(new Uint8Array([1, 2, 3]));
        ws.send(JSON.stringify({ type: 'mode', space: 0, index: 0, pad: 'x'.repeat(5000) }));
        ws.send(JSON.stringify({ type: 'hand', hand: 0, active: true, button: true, position: [null, 0, 0] }));
        ws.send(JSON.stringify({ type: 'hand', hand: 7, active: true, button: true, position: [1, 0, 0] }));
        ws.send(JSON.stringify({ type: 'mode', space: 0, index: 0 }));
      };
    });
  });
  // The count as the server has it now, and frames still coming to this page.
  await statuses(page);
  await until(page, ([n, d]) => window.ves.frames > n && window.ves.status.messages_dropped >= d + 5, [before, droppedBefore]);
  const after = await page.evaluate(() => ({ frames: window.ves.frames, dropped: window.ves.status.messages_dropped }));

  // Lost in space: a wild orbit (dragged off the part) and a deep zoom, then F fits the view.
  await page.mouse.move(600, 730);
  await page.mouse.down();
  await page.mouse.move(700, 400, { steps: 10 });
  await page.mouse.up();
  for (let k = 0; k < 12; k++) { await page.mouse.move(600, 400); await page.mouse.wheel(0, -400); await rendered(page, 1); }
  await rendered(page);
  const lost = await page.evaluate(() => window.ves.drawnExtent());
  await page.keyboard.press('f');
  await rendered(page);
  const fitted = await page.evaluate(() => window.ves.drawnExtent());

  // The mode browser: click mode 1 and check the page animates its shape.
  await page.click('#modebox summary');
  await page.click('#modes button:first-child');
  await page.waitForFunction(() => window.ves.mode !== null, null, { timeout: 5000 });
  const mode = await page.evaluate(() => ({ mode: window.ves.mode.mode, frequency: window.ves.mode.frequency }));

  // A reload keeps the probe pinned (this browser's storage), at the same vertex.
  await page.reload();
  await page.waitForFunction(() => window.ves && window.ves.ready && window.ves.frames > 3, null, { timeout: 30000 });
  await rendered(page);
  const pinsAfterReload = await page.evaluate(() => window.ves.pins.map((p) => [p.n, p.vertex, p.text]));

  console.log(JSON.stringify({ vertex, pixels, atRest, midSpan, pinnedAtRest, probes, pinsAfterReload, lost, fitted, viewport: [1200, 800], held, vonMisesLegend, second, released, framesBefore: before, after, mode, errors }));
} finally {
  await browser.close();
}
