// The set-up the server owns (issue 44), with a real mouse and keyboard: two edits in one page, a
// second page and a reload show them, undo returns the first, Compute serves it; or, with
// "resumed", a server restarted on the same part shows the set-up and the basis it left.
// Arguments: URL, the page's sources, the screenshot folder, "first" | "resumed".
// Prints one JSON line of what each page showed.
import { launch, newPage, until } from './browser.mjs';

const [url, webDir, shots, phase] = process.argv.slice(2);
const browser = await launch(webDir);
const errors = [];
const out = { phase, errors };

/** What a page's set-up panel shows, and the server's last set-up message it got. */
const panel = (page) => page.evaluate(() => {
  const v = (id) => /** @type {HTMLInputElement} */ (document.getElementById(id)).value;
  const s = window.ves.setup.state();
  return {
    modes: v('modecount'), young: v('young'), target: v('target'),
    edited: !document.getElementById('edited').hidden,
    editedText: document.getElementById('edited').textContent,
    undo: !(/** @type {HTMLButtonElement} */ (document.getElementById('undo')).disabled),
    progress: document.getElementById('progresstext').textContent,
    warnings: document.getElementById('computewarnings').textContent,
    history: s ? s.history.map((e) => ({ outcome: e.outcome, changed: e.changed })) : null,
    served: s && s.served ? { modes: s.served.modes.count, young: s.served.material.young } : null,
    project: s ? s.project : null,
    computing: window.ves.status ? window.ves.status.computing : null,
  };
});
/** The server's set-up message holds `fn` in page `p`. */
const told = (p, fn, ms = 600000) => until(p, fn, undefined, ms);
/** Types `text` into field `id` as a user does (select what is there, type, Tab away). */
async function type(page, id, text) {
  await page.click(`#${id}`, { clickCount: 3 });
  await page.keyboard.type(text);
  await page.keyboard.press('Tab');
}

try {
  const a = await newPage(browser, errors, { width: 1400, height: 900 });
  await a.goto(url);
  // The first compute (or the project's basis) served, nothing computing.
  out.servedA = await told(a, () => { const s = window.ves.setup.state(); return s && s.served && window.ves.status && !window.ves.status.computing; });
  out.start = await panel(a);
  if (phase === 'first') {
    await type(a, 'modecount', '6');
    out.edit1 = await told(a, () => window.ves.setup.state().draft.modes.count === 6, 20000);
    await type(a, 'young', '70');
    out.edit2 = await told(a, () => window.ves.setup.state().draft.material.young === 70e9, 20000);
    out.afterEdits = await panel(a);
    // A second page shows the server's set-up, not the part's starting scene.
    const b = await newPage(browser, errors, { width: 1400, height: 900 });
    await b.goto(url);
    out.toldB = await told(b, () => window.ves.setup.state() !== null, 20000);
    out.b = await panel(b);
    await a.screenshot({ path: `${shots}/studio_edited.png` });
    // Undo (a real click) after two edits: the first edit stays, in both pages.
    await a.click('#undo');
    out.undone = await told(b, () => window.ves.setup.state().draft.material.young !== 70e9, 20000);
    out.bUndone = await panel(b);
    await b.reload();
    out.toldReload = await told(b, () => window.ves.setup.state() !== null, 20000);
    out.bReloaded = await panel(b);
    // Compute the first edit; both pages then show it served, nothing edited.
    await a.click('#compute');
    out.computed = await told(a, () => {
      const s = window.ves.setup.state();
      return s.served.modes.count === 6 && s.history.length === 2 && !s.edited && !window.ves.status.computing;
    });
    out.afterCompute = await panel(a);
    out.bAfterCompute = await panel(b);
  } else {
    out.resumed = out.start;
  }
} catch (e) {
  out.failure = String(e && e.stack || e);
}
await browser.close();
console.log(JSON.stringify(out));
