// Debian's headless Chromium with software WebGL, driven by playwright-core from view/web's
// lockfile (no browser download): shared by the viewer's browser tests.
import { pathToFileURL } from 'node:url';

/** Launches the browser (VES_CHROMIUM overrides /usr/bin/chromium). */
export async function launch(webDir) {
  const { chromium } = await import(pathToFileURL(`${webDir}/node_modules/playwright-core/index.mjs`).href);
  return chromium.launch({
    executablePath: process.env.VES_CHROMIUM || '/usr/bin/chromium',
    args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--disable-background-networking',
      '--disable-component-update', '--disable-sync', '--no-first-run'],
  });
}

/** A new page of `viewport` (default 1200 × 800) whose uncaught errors are pushed to `errors`. */
export async function newPage(browser, errors, viewport = { width: 1200, height: 800 }, options = {}) {
  const page = await browser.newPage({ viewport, ...options });
  page.on('pageerror', (e) => errors.push(e.message));
  return page;
}

// Every wait below waits on the page's own state (polled, with a deadline), never on a clock: a
// loaded machine makes them slower, not wrong.

/** Waits until `fn(arg)` holds in the page, at most `ms`; returns whether it did. A wait whose
 * outcome the Rust test asserts does not throw: the page's state is reported and asserted
 * there, with its message. */
export async function until(page, fn, arg, ms = 20000) {
  try {
    await page.waitForFunction(fn, arg, { timeout: ms });
    return true;
  } catch (e) {
    if (e.name === 'TimeoutError') return false;
    throw e;
  }
}

/** Waits until the page has rendered `n` more times: what input changed (the camera after a
 * key or the wheel, a click's effect) is on screen and in the camera's matrices. */
export async function rendered(page, n = 2) {
  const r0 = await page.evaluate(() => window.ves.renders || 0);
  await page.waitForFunction(([r, k]) => (window.ves.renders || 0) >= r + k, [r0, n], { timeout: 20000 });
}

/** Waits until the server's status shows hand `h` driven by this page at the position the
 * page sent last (the server has the message). */
export async function handAt(page, h) {
  await page.waitForFunction((i) => {
    const v = window.ves, s = v.status && v.status.hands[i], t = v.lastTarget;
    return s && t && s.active && s.owner === v.hello.client && s.target.every((x, k) => Math.abs(x - t[k]) <= 1e-12 * (1 + Math.abs(t[k])));
  }, h, { timeout: 20000 });
}

/** Waits until `n` more status messages have come: everything the server had applied when the
 * call began is in the page's status. */
export async function statuses(page, n = 2) {
  await page.evaluate(() => {
    if (window.__statusWatch) return;
    window.__statusWatch = true;
    window.__statuses = 0;
    let last = window.ves.status;
    const look = () => { if (window.ves.status !== last) { last = window.ves.status; window.__statuses += 1; } requestAnimationFrame(look); };
    look();
  });
  const s0 = await page.evaluate(() => window.__statuses);
  await page.waitForFunction(([s, k]) => window.__statuses >= s + k, [s0, n], { timeout: 20000 });
}

/** Holds until the true displacement magnitude of vertex `v` is steady: over the last 60 frames
 * received (about 1 s at the server's visual rate) within 0.2 % of each other. */
export async function steady(page, v, ms = 30000) {
  await page.evaluate(() => { window.__steady = { seen: -1, values: [] }; });
  await page.waitForFunction((i) => {
    const w = window.__steady, s = window.ves.spaces[0];
    if (window.ves.frames === w.seen) return false;
    w.seen = window.ves.frames;
    w.values.push(s.umag[i]);
    if (w.values.length > 60) w.values.shift();
    const [lo, hi] = [Math.min(...w.values), Math.max(...w.values)];
    return w.values.length === 60 && hi > 0 && hi - lo < 2e-3 * hi;
  }, v, { polling: 'raf', timeout: ms });
}
