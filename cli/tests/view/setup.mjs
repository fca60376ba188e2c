// The set-up page end to end in a real headless Chromium: `ves view PART.step` computes the part
// as a free body; the page holds it by its two end faces (clicked in views along ±x), picks aluminium,
// computes, and the mouse pulls a vertex; the scene is saved for the Rust test to recompute with
// `ves precompute` and replay with `ves session`. Then one support is removed and the part
// computed again (the session moves to the new basis), a compute is cancelled, and a garbage
// file and a .geo are opened: one line each in the page, the server still serving.
// Prints one JSON object.
//
// usage: node setup.mjs URL WEB_DIR OUT_DIR
import { handAt, launch, newPage, rendered, steady, until } from './browser.mjs';
import { writeFileSync } from 'node:fs';

const [url, webDir, out] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
// A compute ends with its converged basis or an error; an instant basis (live: "instant") comes
// before the converged one when only supports, material or modes changed.
const ends = (page) => page.evaluate(() => window.ves.notes.filter((n) => (n.type === 'computed' && n.live !== 'instant') || n.type === 'compute_error').length);
// Deadlines, not waits: a compute runs at a lower priority than everything else on the machine.
const waitEnd = async (page, n) => {
  if (!await until(page, (k) => window.ves.notes.filter((x) => (x.type === 'computed' && x.live !== 'instant') || x.type === 'compute_error').length > k, n, 900000)) {
    throw new Error(`no compute ended in 15 min; the last notes: ${JSON.stringify(await page.evaluate(() => window.ves.notes.slice(-3)))}`);
  }
};
try {
  const page = await newPage(browser, errors, { width: 1280, height: 860 }, { acceptDownloads: true });
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready, null, { timeout: 900000 });
  // A first look (the first mesh) may be served while the refinement runs: set up after it ends.
  await page.waitForFunction(() => window.ves.status && !window.ves.status.computing, null, { timeout: 900000 });
  const free = await page.evaluate(() => ({ free: window.ves.hello.free_body, f: window.ves.hello.spaces[0].frequencies_hz }));

  // Two faces by "pick a plane": the −x end seen from −x (flat: the plane through it), then the
  // +x end seen from +x (a cylinder 0.5 mm proud: held as its CAD face, since a plane through
  // its crest would hold a line), each clicked in the middle.
  const supports = () => page.evaluate(() => window.ves.setup.scene().fixed?.length ?? 0);
  const holdFace = async (key) => {
    await page.keyboard.press(key);
    await rendered(page);
    await page.click('#pickplane');
    const [x0, y0, x1, y1] = await page.evaluate(() => window.ves.drawnExtent());
    const n = await supports();
    await page.mouse.click((x0 + x1) / 2, (y0 + y1) / 2);
    await page.waitForFunction((k) => (window.ves.setup.scene().fixed?.length ?? 0) > k, n, { timeout: 10000 });
    return page.evaluate(() => document.getElementById('setuperror').textContent);
  };
  const picked = [await holdFace('Shift+X'), await holdFace('x')];
  // The support kinds: an elastic mount with its stiffness goes into the scene; back to clamped.
  const holdBy = page.locator('#supportlist .support').first().locator('select').nth(1);
  await holdBy.selectOption('elastic');
  await page.locator('#supportlist .support').first().locator('input[type=number]').nth(1).fill('2e9');
  await page.locator('#supportlist .support').first().locator('input[type=number]').nth(1).dispatchEvent('change');
  const kinds = { elastic: await page.evaluate(() => window.ves.setup.scene().fixed[0]) };
  await holdBy.selectOption('bearing');
  kinds.bearing = await page.evaluate(() => window.ves.setup.scene().fixed[0]);
  await holdBy.selectOption('located');
  kinds.located = await page.evaluate(() => window.ves.setup.scene().fixed[0]);
  await holdBy.selectOption('x,y,z');
  kinds.clamped = await page.evaluate(() => window.ves.setup.scene().fixed[0]);
  await page.selectOption('#material', { label: 'aluminium 6061-T6' });
  await page.fill('#modecount', '10');
  const asked = await page.evaluate(() => window.ves.setup.scene());
  // The supports as the panel shows them (a plane in mm, a face by its tag).
  asked.shown = await page.evaluate(() => [...document.querySelectorAll('#supportlist .support')].map((r) => (
    r.querySelector('input[type=number]:not([title])')
      ? { axis: r.querySelector('select').value, value: r.querySelector('input[type=number]').value }
      : { text: r.textContent })));
  asked.picked = picked;
  let n = await ends(page);
  await page.click('#compute');
  await waitEnd(page, n);
  await page.waitForFunction(() => window.ves.ready && !window.ves.hello.free_body, null, { timeout: 60000 });
  const held = await page.evaluate(() => ({ notes: window.ves.notes.filter((x) => x.type !== 'progress'), f: window.ves.hello.spaces[0].frequencies_hz,
    stages: [...new Set(window.ves.notes.filter((x) => x.type === 'progress').map((x) => x.stage))] }));
  await page.keyboard.press('h');
  // The mesh solved, its edges over the part (E).
  held.edgesBefore = await page.evaluate(() => window.ves.edgesShown());
  await page.keyboard.press('e');
  await rendered(page);
  held.edges = await page.evaluate(() => window.ves.edgesShown());
  // The mesh's tets by shape quality, as the set-up panel shows them.
  held.meshQuality = await page.evaluate(() => ({
    text: document.getElementById('meshqualitytext').textContent,
    shown: !document.getElementById('meshquality').hidden,
    bars: [...document.querySelectorAll('#meshqualitybars rect')].map((r) => Number(r.getAttribute('height'))),
  }));
  await page.screenshot({ path: `${out}/setup_held.png` });

  // Pull the vertex nearest the middle of the top: by script, so the hand path is known exactly.
  const grab = await page.evaluate(() => {
    const s = window.ves.spaces[0];
    let lo = [Infinity, Infinity, Infinity], hi = [-Infinity, -Infinity, -Infinity];
    for (let i = 0; i < s.vertices; i++) for (let k = 0; k < 3; k++) { lo[k] = Math.min(lo[k], s.rest[3 * i + k]); hi[k] = Math.max(hi[k], s.rest[3 * i + k]); }
    const v = window.ves.nearestVertex(0, [(lo[0] + hi[0]) / 2, (lo[1] + hi[1]) / 2, hi[2]]);
    return { v, rest: Array.from(s.rest.subarray(3 * v, 3 * v + 3)), size: Math.hypot(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]) };
  });
  const target = [grab.rest[0], grab.rest[1], grab.rest[2] + 0.05];
  await page.evaluate((p) => window.ves.drive(0, p), grab.rest);
  await handAt(page, 0);
  await page.evaluate((p) => window.ves.drive(0, p), target);
  await handAt(page, 0);
  await steady(page, grab.v, 60000);
  // The checks after the part is pullable state what the hand feels wrong at its vertex.
  await page.waitForFunction(() => window.ves.notes.some((x) => x.type === 'checked'), null, { timeout: 120000 });
  await page.waitForFunction(() => Number.isFinite(window.ves.status.hands[0].felt_error), null, { timeout: 10000 }).catch(() => {});
  const pulled = await page.evaluate((v) => ({
    felt: window.ves.status.hands[0].felt_error, handText: document.getElementById('handinfo').textContent,
    tag: [...document.querySelectorAll('.forcelabel')].map((t) => t.textContent).join(' | '),
    hand: window.ves.status.hands[0], u: Array.from(window.ves.spaces[0].u.subarray(3 * v, 3 * v + 3)),
    position: window.ves.trueOf(0, v), drawn: window.ves.drawnOf(0, v), scale: window.ves.drawnScale,
    scaleText: document.getElementById('scaleshown').textContent,
  }), grab.v);
  await page.screenshot({ path: `${out}/setup_pulled.png` });
  await page.evaluate(() => window.ves.release(0));

  // Save the scene (the page's download) for the Rust side.
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#savescene')]);
  await download.saveAs(`${out}/saved.toml`);

  // Hold it by one CAD face only (+ faces…, the +x end face lit and clicked), the planes
  // removed: compute again, the session moves to the new basis.
  while (await page.locator('#supportlist .support').count()) await page.click('#supportlist .support:first-child button');
  await page.keyboard.press('x');
  await rendered(page);
  await page.click('#pickfaces');
  const [fx0, fy0, fx1, fy1] = await page.evaluate(() => window.ves.drawnExtent());
  await page.mouse.move((fx0 + fx1) / 2, (fy0 + fy1) / 2);
  await until(page, () => window.ves.hoverFace != null, null, 10000);
  const hovered = await page.evaluate(() => window.ves.hoverFace);
  // The tip under the cursor says what the face is, as `ves faces` does.
  const tip = await page.evaluate(() => document.getElementById('probe').textContent);
  await page.mouse.click((fx0 + fx1) / 2, (fy0 + fy1) / 2);
  await page.click('#pickfaces');
  const faced = await page.evaluate(() => window.ves.setup.scene().fixed);
  await page.keyboard.press('h');
  n = await ends(page);
  await page.click('#compute');
  await waitEnd(page, n);
  await page.waitForFunction(() => window.ves.ready, null, { timeout: 60000 });
  const one = await page.evaluate(() => ({ f: window.ves.hello.spaces[0].frequencies_hz, fixed: window.ves.setup.scene().fixed.length, last: window.ves.notes.at(-1) }));
  one.hovered = hovered; one.faced = faced; one.tip = tip;
  await page.screenshot({ path: `${out}/setup_face_held.png` });

  // Cancel: the compute stops at its next stage; the part shown stays. 4-node tets: a change
  // of mesh, so no instant basis is served before the cancel arrives.
  await page.selectOption('#order', '1');
  n = await ends(page);
  await page.click('#compute');
  await page.click('#cancel');
  await waitEnd(page, n);
  const cancelled = await page.evaluate(() => ({ last: window.ves.notes.at(-1), f: window.ves.hello.spaces[0].frequencies_hz, error: document.getElementById('setuperror').textContent }));

  // Garbage and a .geo through "open a part…": one line in the page; the server goes on.
  const opened = {};
  for (const [name, body] of [['junk.step', 'this is not a STEP file\n'], ['box.geo', 'Box(1) = {0,0,0,1,1,1};\n']]) {
    await page.setInputFiles('#partfile', { name, mimeType: 'application/octet-stream', buffer: Buffer.from(body) });
    await page.waitForFunction(() => document.getElementById('setuperror').textContent !== '', null, { timeout: 10000 });
    opened[name] = await page.evaluate(() => document.getElementById('setuperror').textContent);
    await page.evaluate(() => { document.getElementById('setuperror').textContent = ''; });
  }
  const before = await page.evaluate(() => window.ves.frames);
  const alive = await until(page, (b) => window.ves.frames > b && window.ves.connected, before);
  writeFileSync(`${out}/page.json`, JSON.stringify({ free, kinds, asked, held, grab, target, pulled, one, cancelled, opened, alive, errors }));
  console.log('done');
} finally {
  await browser.close();
}
