// From "Compute" to a pullable part in the set-up page, and the haptic loop beside a compute.
// Run by bench/setup.sh (which starts `ves view SCENE.toml` with an empty mesh cache): the
// page waits for the first compute (cold: nothing cached), then changes only the supports
// (the mesh is cached) and clicks Compute; each time from the click (or the first compute's
// start) to the page drawing the new part. Prints one JSON object.
//
// usage: node bench/setup.mjs URL WEB_DIR
import { launch } from '../pipeline/tests/view/browser.mjs';

const [url, webDir] = process.argv.slice(2);
const browser = await launch(webDir);
const ends = (page) => page.evaluate(() => window.ves.notes.filter((n) => n.type === 'computed' || n.type === 'compute_error').length);
try {
  // A small window: without a GPU the browser rasterises on the cores the compute needs.
  const page = await browser.newPage({ viewport: { width: 800, height: 540 } });
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready, null, { timeout: 600000 });
  // The error estimate follows the swap (a fixed mesh size): each run waits for it too.
  const checked = (n) => page.waitForFunction((n) => window.ves.notes.filter((x) => x.type === 'checked').length > n, n, { timeout: 600000 });
  const nChecked = () => page.evaluate(() => window.ves.notes.filter((x) => x.type === 'checked').length);
  await checked(0);
  const cold = await page.evaluate(() => ({ ...window.ves.notes.find((n) => n.type === 'computed'), checked: window.ves.notes.find((n) => n.type === 'checked') }));
  const runs = [];
  for (let k = 0; k < 3; k++) {
    // Supports only: every support held along z only, then clamped again, alternately.
    await page.evaluate((k) => {
      for (const s of document.querySelectorAll('#supportlist .support select:last-of-type')) s.value = k % 2 ? 'x,y,z' : 'z';
      for (const s of document.querySelectorAll('#supportlist .support select:last-of-type')) s.dispatchEvent(new Event('change'));
    }, k);
    const n = await ends(page);
    const c = await nChecked();
    const t0 = Date.now();
    await page.click('#compute');
    await page.waitForFunction((n) => window.ves.notes.filter((x) => x.type === 'computed' || x.type === 'compute_error').length > n, n, { timeout: 600000 });
    await page.waitForFunction(() => window.ves.ready, null, { timeout: 60000 });
    const pullable = (Date.now() - t0) / 1000;
    const last = await page.evaluate(() => window.ves.notes.filter((x) => x.type === 'computed' || x.type === 'compute_error').at(-1));
    await checked(c);
    const est = await page.evaluate(() => window.ves.notes.filter((x) => x.type === 'checked').at(-1));
    runs.push({ click_to_pullable_s: pullable, server_s: last.seconds, summary: last.summary || last.message,
      click_to_estimate_s: (Date.now() - t0) / 1000, estimate: est.summary || est.error });
  }
  console.log(JSON.stringify({ cold: { server_s: cold.seconds, summary: cold.summary, estimate_s: cold.checked.seconds, estimate: cold.checked.summary || cold.checked.error }, supports_changed: runs }));
} finally {
  await browser.close();
}
