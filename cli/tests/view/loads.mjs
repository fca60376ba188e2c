// `ves view` on a basis with static load cases, in a real headless Chromium: the page offers
// them; choosing one draws the part deformed by its stored displacement (× the page's scale)
// and coloured by its von Mises stress; the hands are off meanwhile; requests for unknown cases
// are dropped and counted; "none" brings the live part back. Prints one JSON object; the Rust
// test compares it with the file.
//
// usage: node loads.mjs URL WEB_DIR SCREENSHOT_DIR CASE
import { launch, newPage, rendered, statuses, until } from './browser.mjs';

const [url, webDir, shots, wanted] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
try {
  const page = await newPage(browser, errors);
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready && window.ves.frames > 3 && window.ves.status, null, { timeout: 30000 });
  const offered = await page.evaluate(() => ({
    hidden: document.getElementById('loadbox').hidden,
    options: [...document.getElementById('loadcase').options].map((o) => ({ value: o.value, text: o.textContent })),
    loads: window.ves.hello.spaces[0].loads,
  }));
  const index = offered.loads.findIndex((c) => c.name === wanted);
  if (index < 0) throw new Error(`no load case ${wanted} offered: ${JSON.stringify(offered)}`);

  // The user's way: the select.
  await page.selectOption('#loadcase', String(index));
  await page.waitForFunction((n) => window.ves.loadCase && window.ves.legend && window.ves.legend.load === n && !window.ves.dirty, wanted, { timeout: 10000 });
  const shown = await page.evaluate(() => {
    const c = window.ves.loadCase, s = window.ves.spaces[0];
    // The drawn vertex the case moves most, and one near the middle of the beam.
    let far = 0;
    for (let i = 0; i < s.vertices; i++) {
      if (Math.hypot(c.u[3 * i], c.u[3 * i + 1], c.u[3 * i + 2]) > Math.hypot(c.u[3 * far], c.u[3 * far + 1], c.u[3 * far + 2])) far = i;
    }
    const mid = window.ves.nearestVertex(0, [0.5, 0.05, 0.05]);
    const at = (v) => ({ vertex: v, rest: Array.from(s.rest.subarray(3 * v, 3 * v + 3)), drawn: window.ves.drawnOf(0, v) });
    return {
      name: c.name, index: c.index, maxDisplacement: c.maxDisplacement, maxVonMises: c.maxVonMises,
      scale: window.ves.drawnScale, auto: window.ves.scaleAuto, diag: s.size,
      far: at(far), mid: at(mid),
      legend: window.ves.legend,
      legendHi: document.getElementById('hi').textContent,
      legendNote: document.getElementById('legendnote').textContent,
      note: document.getElementById('loadnote').textContent,
      scaleText: document.getElementById('scaleshown').textContent,
      colourDisabled: document.getElementById('colour').disabled,
    };
  });
  await page.screenshot({ path: `${shots}/load_case.png` });

  // The hands are off: a drag on the part orbits (the camera moves), the page sends no hand
  // message (its last target stays) and the server's status, two after the drag, has no hand.
  const [x, y] = await page.evaluate((v) => window.ves.screenOf(0, v), shown.far.vertex);
  const sent = await page.evaluate(() => JSON.stringify(window.ves.lastTarget ?? null));
  await page.mouse.move(x, y);
  await page.mouse.down();
  await page.mouse.move(x, y + 40, { steps: 6 });
  await rendered(page);
  await statuses(page);
  const orbited = await page.evaluate(([v, a, b]) => { const [p, q] = window.ves.screenOf(0, v); return Math.hypot(p - a, q - b); }, [shown.far.vertex, x, y]);
  const sentDuring = await page.evaluate((s) => JSON.stringify(window.ves.lastTarget ?? null) !== s, sent);
  const handsDuring = await page.evaluate(() => window.ves.status.hands.map((h) => h.active));
  await page.mouse.up();

  // Hostile load requests through a socket of its own: an unknown name, another space, a
  // mistyped name, an extra field, an oversized one. All five dropped and counted; the server
  // goes on (frames keep coming). A good one after them is answered (kind 4), and last a mode
  // request: the server reads a socket in order, so its answer (kind 2) means every request
  // before it was handled and answered if it was to be.
  const framesBefore = await page.evaluate(() => window.ves.frames);
  const droppedBefore = await page.evaluate(() => window.ves.status.messages_dropped);
  const replies = await page.evaluate((name) => {
    const ws = new WebSocket(`ws://${location.host}/ws`);
    ws.binaryType = 'arraybuffer';
    const kinds = [];
    return new Promise((done) => {
      ws.onmessage = (ev) => {
        if (typeof ev.data === 'string') return;
        const kind = window.ves.kindOf(ev.data);
        if (kind === 2) { ws.close(); done(kinds.filter((k) => k === 4).length); } else kinds.push(kind);
      };
      ws.onopen = () => {
        ws.send(JSON.stringify({ type: 'load', space: 0, name: 'no_such_case' }));
        ws.send(JSON.stringify({ type: 'load', space: 5, name }));
        ws.send(JSON.stringify({ type: 'load', space: 0, name: 12 }));
        ws.send(JSON.stringify({ type: 'load', space: 0, name, all: true }));
        ws.send(JSON.stringify({ type: 'load', space: 0, name: 'x'.repeat(40000) }));
        // And a good one: answered on this socket alone, as kind 4.
        ws.send(JSON.stringify({ type: 'load', space: 0, name }));
        ws.send(JSON.stringify({ type: 'mode', space: 0, index: 0 }));
      };
    });
  }, wanted);
  await statuses(page);
  await until(page, ([n, d]) => window.ves.frames > n && window.ves.status.messages_dropped >= d + 5, [framesBefore, droppedBefore]);
  const after = await page.evaluate(() => ({ frames: window.ves.frames, dropped: window.ves.status.messages_dropped }));

  // "none": the live part again, with its own legend; the hands work again.
  await page.selectOption('#loadcase', '');
  await page.waitForFunction(() => !window.ves.loadCase && !window.ves.dirty && window.ves.legend && !window.ves.legend.load, null, { timeout: 10000 });
  const back = await page.evaluate(() => ({ legend: window.ves.legend, colourDisabled: document.getElementById('colour').disabled, note: document.getElementById('loadnote').textContent }));
  // The tip as drawn now (at rest, and the view was orbited meanwhile).
  const mid = await page.evaluate(() => window.ves.nearestVertex(0, [0.75, 0.05, 0.05]));
  const [x3, y3] = await page.evaluate((v) => window.ves.screenOf(0, v), mid);
  await page.mouse.move(x3, y3);
  await page.mouse.down();
  await page.mouse.move(x3, y3 + 30, { steps: 6 });
  await until(page, () => window.ves.status.hands[0].active);
  const handsAfter = await page.evaluate(() => window.ves.status.hands.map((h) => h.active));
  await page.mouse.up();

  console.log(JSON.stringify({ offered, shown, orbited, sentDuring, handsDuring, framesBefore, droppedBefore, after, goodReplies: replies, back, handsAfter, errors }));
} finally {
  await browser.close();
}
