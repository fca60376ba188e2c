// `ves view` on a nonlinear basis (the soft cantilever) in a real headless Chromium: the hello
// says the part is nonlinear, the automatic scale draws it at true size (×1), and a hand that
// grabs the tip and carries it 0.25 m down draws the tip down and in along the beam (an arc).
// Prints one JSON object as its last line.
//
// usage: node nonlinear.mjs URL WEB_DIR SCREENSHOT_DIR
import { handAt, launch, newPage, until } from './browser.mjs';

const [url, webDir, shots] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
try {
  const page = await newPage(browser, errors);
  await page.goto(url);
  await page.waitForFunction(() => window.ves && window.ves.ready, null, { timeout: 40000 });
  const atRest = await page.evaluate(() => ({
    nonlinear: window.ves.hello.spaces[0].nonlinear,
    scale: window.ves.drawnScale,
    auto: window.ves.scaleAuto,
    shown: document.getElementById('scale').value,
  }));
  const tip = await page.evaluate(() => window.ves.nearestVertex(0, [1.0, 0.05, 0.05]));
  const start = await page.evaluate((v) => window.ves.trueOf(0, v), tip);
  for (let k = 0; k <= 25; k++) {
    await page.evaluate((p) => window.ves.drive(0, p), [start[0], start[1], start[2] - 0.01 * k]);
    await handAt(page, 0);
  }
  await until(page, (v) => window.ves.trueOf(0, v)[2] < window.ves.spaces[0].rest[3 * v + 2] - 0.2, tip);
  await page.waitForFunction(() => !window.ves.dirty, null, { timeout: 10000 });
  const pulled = await page.evaluate((v) => ({
    drawn: window.ves.drawnOf(0, v),
    true: window.ves.trueOf(0, v),
    scale: window.ves.drawnScale,
  }), tip);
  pulled.rest = start;
  await page.screenshot({ path: `${shots}/nonlinear_pull.png` });
  console.log(JSON.stringify({ errors, atRest, pulled }));
} finally {
  await browser.close();
}
