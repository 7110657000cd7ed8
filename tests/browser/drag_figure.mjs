// A scripted drag in headless Chromium against a running `lse-deform edit`
// (the figure of results/editor/README.md): waits for the page, runs
// window.editor.scriptedDrag('handle 1', FRAMES) — each frame POSTs the
// transform, fetches the positions (f32) and renders — once without
// drawing and once with, and prints the page's frame rates and the medians
// of each phase as JSON.
// Usage: node drag_figure.mjs URL FRAMES SCREENSHOT_PREFIX, where URL is
// the one `lse-deform edit` prints, with its `?token=`.
import { chromium } from 'playwright-core';

const [url, frames = '300', prefix = 'drag'] = process.argv.slice(2);
const token = new URL(url).searchParams.get('token');
if (!token) throw new Error(`${url}: no ?token= (give the URL that lse-deform edit printed)`);
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  page.on('pageerror', (e) => console.error('page error:', e.message));
  // The server path, whose figure this is (experiments/editor_frames.mjs
  // compares it with the client path).
  await page.goto(`${url}&mode=server`);
  await page.waitForFunction(() => window.editor && window.editor.ready, null, { timeout: 600000 });
  await page.screenshot({ path: `${prefix}-rest.png` });
  // The same drag without drawing: what the server and the transfer allow.
  const withoutRendering = await page.evaluate(
    (f) => window.editor.scriptedDrag('handle 1', f, 0.25, 1, { render: false }), Number(frames));
  const result = await page.evaluate((f) => window.editor.scriptedDrag('handle 1', f, 0.25), Number(frames));
  // Stop at a quarter of the circle for the picture.
  await page.evaluate(() => window.editor.scriptedDrag('handle 1', 4, 0.25, 0.25));
  await page.screenshot({ path: `${prefix}-dragged.png` });
  const report = await (await fetch(new URL('/api/report', url), { headers: { authorization: `Bearer ${token}` } })).json();
  console.log(JSON.stringify({ url: new URL('/', url).href, ...result, withoutRendering, serverReport: report.editor }, null, 1));
} finally {
  await browser.close();
}
