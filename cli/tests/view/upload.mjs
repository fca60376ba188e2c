// A part opened in the page keeps a project of its own (issue 44): "first" opens PART through
// "open a part…" (the file chooser), waits for its compute and types one edit (6 modes);
// "again", on a server started afresh, opens the same file: its project is resumed — the set-up
// with the edit not computed, the basis served without a compute.
// In "first", a file that starts as STEP but is cut short (BAD) is opened before PART: its
// compute fails, and the part before stays the part set up (its set-up, project and title).
// In "again", the command-line part's own file (OWN) opened in the page last goes back to its
// project beside it. Arguments: URL, the page's sources, the screenshot folder, "first" |
// "again", PART's path, BAD's path, OWN's path.
// Prints one JSON line of what the page showed.
import { launch, newPage, until } from './browser.mjs';

const [url, webDir, shots, phase, part, bad, own] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
const out = { phase, errors };

const state = (page) => page.evaluate(() => {
  const s = window.ves.setup.state();
  return {
    modes: /** @type {HTMLInputElement} */ (document.getElementById('modecount')).value,
    edited: !document.getElementById('edited').hidden,
    progress: document.getElementById('progresstext').textContent,
    project: s ? s.project : null,
    served: s && s.served ? { name: s.served.name, modes: s.served.modes.count } : null,
    draftModes: s && s.draft ? s.draft.modes.count : null,
    history: s ? s.history.length : null,
    title: document.title,
  };
});

try {
  const page = await newPage(browser, errors, { width: 1400, height: 900 });
  await page.goto(url);
  // The command-line part served, nothing computing.
  out.started = await until(page, () => { const s = window.ves.setup.state(); return s && s.served && window.ves.status && !window.ves.status.computing; }, undefined, 600000);
  out.before = await state(page);
  /** A real click on "open a part…" and the file chooser it opens, given `file`. */
  const open = async (file) => {
    const [chooser] = await Promise.all([page.waitForEvent('filechooser'), page.click('#openpart')]);
    await chooser.setFiles(file);
  };
  if (phase === 'first') {
    const notes = await page.evaluate(() => window.ves.notes.length);
    await open(bad);
    out.badFailed = await until(page, (n) => window.ves.notes.slice(n).some((m) => m.type === 'compute_error'), notes, 600000);
    out.afterBad = await state(page);
    out.badError = await page.evaluate(() => document.getElementById('setuperror').textContent);
  }
  await open(part);
  // The opened part served (its name in the served scene) and its compute over (in its
  // history: the status's "computing" may be older than the served scene).
  out.opened = await until(page, () => {
    const s = window.ves.setup.state();
    return s && s.served && s.served.name !== 'cantilever' && s.project && s.history.length >= 1 && window.ves.status && !window.ves.status.computing;
  }, undefined, 600000);
  if (phase === 'first') {
    await page.click('#modecount', { clickCount: 3 });
    await page.keyboard.type('6');
    await page.keyboard.press('Tab');
    out.edited = await until(page, () => window.ves.setup.state().draft.modes.count === 6, undefined, 20000);
  } else {
    out.told = await until(page, () => /resumed/.test(document.getElementById('progresstext').textContent), undefined, 20000);
    await page.screenshot({ path: `${shots}/upload_resumed.png` });
  }
  out.after = await state(page);
  if (phase === 'again') {
    // The command-line part's own file opened in the page: back to its project beside it.
    await open(own);
    out.back = await until(page, () => {
      const s = window.ves.setup.state();
      return s && s.project && s.project.endsWith('cantilever.ves') && s.served && s.served.name === 'cantilever';
    }, undefined, 60000);
    out.backState = await state(page);
  }
} catch (e) {
  out.failure = String(e && e.stack || e);
}
await browser.close();
console.log(JSON.stringify(out));
