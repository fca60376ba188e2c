// Design loads made in the page: on the cantilever held at its root, "+ load on faces…" and a
// real click on the tip face (seen from +x) make a load of 1 kN into that face; its row turned
// to 2 kN along -z; "+ gravity" adds the part's weight. Compute solves both as static load
// cases, the load case list offers them, and choosing the force shows its stress and the
// supports' reaction. The saved scene comes back for `ves precompute` on the Rust side.
// Arguments: URL, the page's sources, the screenshot folder. Prints one JSON line.
import { launch, newPage, until } from './browser.mjs';

const [url, webDir, shots] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
const out = { errors };
try {
  const page = await newPage(browser, errors, { width: 1400, height: 900 });
  await page.goto(url);
  await until(page, () => {
    const s = window.ves.setup.state();
    return s && s.served && window.ves.ready && window.ves.status && !window.ves.status.computing;
  }, undefined, 600000);
  out.before = await page.evaluate(() => document.getElementById('loadsnote').textContent);
  out.firstLine = await page.evaluate(() => document.getElementById('progresstext').textContent);

  // The tip face, seen from +x, under the cursor: a click makes load1.
  await page.keyboard.press('x');
  await page.click('#pickload');
  const [x0, y0, x1, y1] = await page.evaluate(() => window.ves.drawnExtent());
  await page.mouse.move((x0 + x1) / 2, (y0 + y1) / 2);
  await until(page, () => window.ves.hoverFace != null, null, 10000);
  await page.mouse.click((x0 + x1) / 2, (y0 + y1) / 2);
  await page.click('#pickload');
  out.picked = await page.evaluate(() => JSON.parse(JSON.stringify(window.ves.setup.scene().load)));
  out.directions = await page.evaluate(() => [...document.querySelectorAll('#designloads .designload:first-child select:nth-of-type(2) option')].map((o) => o.textContent));

  // 2 kN along -z: the direction chosen, then the magnitude typed.
  await page.selectOption('#designloads .designload:first-child select:nth-of-type(2)', '-z');
  await page.fill('#designloads .designload:first-child input.magnitude', '2000');
  await page.press('#designloads .designload:first-child input.magnitude', 'Tab');
  await page.click('#addgravity');
  // The felt stiffness made exact (the static correction), as the computed line then says.
  await page.check('#exactfelt');
  out.scene = await page.evaluate(() => JSON.parse(JSON.stringify({ load: window.ves.setup.scene().load, gravity: window.ves.setup.scene().gravity })));
  await page.keyboard.press('h');

  await page.click('#compute');
  await until(page, () => {
    const s = window.ves.setup.state();
    const loads = window.ves.hello.spaces[0].loads || [];
    return s.history.length === 2 && !s.edited && !window.ves.status.computing && loads.length === 2;
  }, undefined, 600000);
  // The peaks' study follows the pullable part (the checks after it) and reaches the hello.
  await until(page, () => (window.ves.hello.spaces[0].loads || []).every((c) => c.peak), undefined, 120000);
  out.loads = await page.evaluate(() => window.ves.hello.spaces[0].loads);
  out.options = await page.evaluate(() => [...document.querySelectorAll('#loadcase option')].map((o) => o.textContent));
  out.line = await page.evaluate(() => document.getElementById('progresstext').textContent);
  out.corrected = await page.evaluate(() => window.ves.setup.scene().static_correction || null);

  // The force's case shown: its stress, safety factor line and the supports' reaction.
  const index = out.loads.findIndex((c) => c.name === 'load1');
  await page.selectOption('#loadcase', String(index));
  await until(page, () => window.ves.loadCase && window.ves.loadCase.name === 'load1', null, 60000);
  await page.waitForTimeout(300);
  out.note = await page.evaluate(() => document.getElementById('loadnote').textContent);
  await page.screenshot({ path: `${shots}/design_loads.png` });

  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#savescene')]);
  await download.saveAs(`${shots}/saved.toml`);
  const [report] = await Promise.all([page.waitForEvent('download'), page.click('#report')]);
  await report.saveAs(`${shots}/report.md`);
  out.reportName = report.suggestedFilename();
} catch (e) {
  out.failure = String(e && e.stack || e);
}
await browser.close();
console.log(JSON.stringify(out));
