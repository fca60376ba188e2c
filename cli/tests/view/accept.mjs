// A refinement that stopped short of its target, and its advice taken in one click: the page
// served a scene whose refinement `max_dofs` stopped shows the warning with an "accept X %"
// button; a real click on it sets the target and computes, and the basis served then meets it.
// Arguments: URL, the page's sources, the screenshot folder. Prints one JSON line.
import { launch, newPage, until } from './browser.mjs';

const [url, webDir, shots] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
const out = { errors };
const shown = (page) => page.evaluate(() => ({
  warnings: document.getElementById('computewarnings').textContent,
  target: /** @type {HTMLInputElement} */ (document.getElementById('target')).value,
  byError: /** @type {HTMLInputElement} */ (document.getElementById('byerror')).checked,
  buttons: [...document.querySelectorAll('#computewarnings button')].map((b) => b.textContent),
  f: window.ves.hello.spaces[0].frequencies_hz,
  served: window.ves.setup.state().served,
  history: window.ves.setup.state().history.length,
}));
try {
  const page = await newPage(browser, errors, { width: 1400, height: 900 });
  await page.goto(url);
  out.served = await until(page, () => {
    const s = window.ves.setup.state();
    return s && s.served && window.ves.status && !window.ves.status.computing && document.querySelector('#computewarnings button');
  }, undefined, 600000);
  out.before = await shown(page);
  await page.screenshot({ path: `${shots}/accept_stopped.png` });
  await page.click('#computewarnings button');
  out.computed = await until(page, () => {
    const s = window.ves.setup.state();
    return s.history.length === 2 && !s.edited && !window.ves.status.computing;
  }, undefined, 600000);
  out.after = await shown(page);
} catch (e) {
  out.failure = String(e && e.stack || e);
}
await browser.close();
console.log(JSON.stringify(out));
