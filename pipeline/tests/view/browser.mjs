// Debian's headless Chromium with software WebGL, driven by playwright-core from runtime/web's
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
