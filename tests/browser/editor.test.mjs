// End-to-end test of `lse-deform edit` in Debian's headless Chromium
// (playwright-core, executablePath /usr/bin/chromium): load the page, brush
// a fixed region and a handle with the mouse, drag the handle with the move
// tool, and check through GET /api/positions that the handle moved and the
// fixed region did not; saves a screenshot.
//
// The drag takes the client path (the page's default when the server has a
// response basis): the positions the vertex shader displayed, read back,
// put every hard-constrained vertex within f32 rounding (1e-6 of the
// bounding-box diagonal) of its target, and the saved mesh ("save deformed
// mesh") equals the server's f64 positions exactly and `lse-deform deform`'s
// full solve of the moved targets to 1e-9 of the diagonal.
//
// The server prints `listening on http://HOST:PORT/?token=T`: the page
// takes the token from its URL (and drops it from the address bar), node's
// own requests send `Authorization: Bearer T`.
//
// Environment: LSE_DEFORM_BIN (default ../../target/release/lse-deform),
// EDITOR_MESH (default: a generated 4k-vertex grid), SCREENSHOT (default
// e2e.png in a fresh temporary directory; the `editor` experiment sets it
// to results/editor/e2e.png), DRAG_FRAMES (default 0: when > 0, a
// scripted drag of that many frames is timed afterwards and printed as
// JSON).
import { spawn, execFileSync } from 'node:child_process';
import { createInterface } from 'node:readline';
import { mkdtempSync, mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { tmpdir } from 'node:os';
import { dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';
import assert from 'node:assert/strict';
import { chromium } from 'playwright-core';

const here = dirname(fileURLToPath(import.meta.url));
const bin = resolve(process.env.LSE_DEFORM_BIN || join(here, '../../target/release/lse-deform'));
const screenshot = resolve(
  process.env.SCREENSHOT || join(mkdtempSync(join(tmpdir(), 'lse-editor-shot-')), 'e2e.png'),
);
const dragFrames = Number(process.env.DRAG_FRAMES || 0);

let mesh = process.env.EDITOR_MESH;
if (!mesh) {
  mesh = join(mkdtempSync(join(tmpdir(), 'lse-editor-')), 'grid.obj');
  execFileSync(bin, ['generate', 'grid', '--vertices', '4000', '-o', mesh]);
}

const server = spawn(bin, ['edit', mesh, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
// The first line: `listening on http://HOST:PORT/?token=T`; the page is
// opened with it, node's own requests send the token as a Bearer header.
const url = await new Promise((ok, fail) => {
  const lines = createInterface({ input: server.stdout });
  lines.once('line', (line) => {
    const m = /^listening on (http:\/\/\S+\/\?token=[0-9a-f]{64})$/.exec(line);
    m ? ok(m[1]) : fail(new Error(`first line: ${line}`));
  });
  server.once('exit', (code) => fail(new Error(`server exited with ${code}`)));
});
const base = new URL('/', url).href;
const token = new URL(url).searchParams.get('token');
const api = (path) => fetch(new URL(path, base), { headers: { authorization: `Bearer ${token}` } });

async function positions() {
  const b = await (await api('api/positions?format=f64')).arrayBuffer();
  return new Float64Array(b);
}

// The vertex shader's positions against the targets (f32 rounding), the
// saved mesh against the server's f64 positions (exact) and a full solve.
async function checkClientPath(page, groups, serverF64) {
  const { shown, matrix, rest } = await page.evaluate(() => ({
    shown: Array.from(window.editor.displayedPositions()),
    matrix: window.editor.matrixOf('handle 1'),
    rest: Array.from(window.editor.state.restF64),
  }));
  const diag = (await (await api('api/mesh')).json()).diagonal;
  const moved = (v) => matrix.map((row) => row[0] * rest[3 * v] + row[1] * rest[3 * v + 1] + row[2] * rest[3 * v + 2] + row[3]);
  let worst = 0;
  for (const [group, target] of [['fixed', (v) => rest.slice(3 * v, 3 * v + 3)], ['handle 1', moved]]) {
    for (const v of groups[group]) {
      const t = target(v);
      worst = Math.max(worst, ...[0, 1, 2].map((c) => Math.abs(shown[3 * v + c] - t[c]) / diag));
    }
  }
  console.log(JSON.stringify({ shaderVsTargets: worst }));
  assert.ok(worst <= 1e-6, `a hard-constrained vertex is ${worst} of the diagonal from its target in the shader`);
  const [saved] = await Promise.all([page.waitForEvent('download'), page.click('#savemesh')]);
  const obj = readFileSync(await saved.path(), 'utf8').split('\n').filter((l) => l.startsWith('v '))
    .flatMap((l) => l.trim().split(/\s+/).slice(1, 4).map(Number));
  assert.deepEqual(obj, Array.from(serverF64), 'the saved mesh is the server\'s f64 positions');
  // An independent full solve of the moved targets.
  const dir = mkdtempSync(join(tmpdir(), 'lse-solve-'));
  const constraints = [];
  for (const v of groups.fixed) constraints.push({ type: 'position', vertex: v, target: rest.slice(3 * v, 3 * v + 3) });
  for (const v of groups['handle 1']) constraints.push({ type: 'position', vertex: v, target: moved(v) });
  writeFileSync(join(dir, 'moved.json'), JSON.stringify({ constraints }));
  execFileSync(bin, ['deform', mesh, '-c', join(dir, 'moved.json'), '-o', join(dir, 'solved.obj')]);
  const solved = readFileSync(join(dir, 'solved.obj'), 'utf8').split('\n').filter((l) => l.startsWith('v '))
    .flatMap((l) => l.trim().split(/\s+/).slice(1, 4).map(Number));
  let gap = 0;
  for (let i = 0; i < solved.length; i++) gap = Math.max(gap, Math.abs(solved[i] - obj[i]) / diag);
  console.log(JSON.stringify({ savedVsFullSolve: gap }));
  assert.ok(gap <= 1e-9, `the saved mesh is ${gap} of the diagonal from lse-deform deform's solve`);
}

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader',
    // evil.example resolves to this machine: a DNS rebinding, simulated.
    '--host-resolver-rules=MAP evil.example 127.0.0.1'],
});
let failed = false;
try {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  page.on('pageerror', (e) => { console.error('page error:', e.message); failed = true; });
  await page.goto(url);
  await page.waitForFunction(() => window.editor && window.editor.ready, null, { timeout: 120000 });
  // The page took the token from its URL and removed it from the address bar.
  assert.equal(new URL(page.url()).search, '', `the address bar still shows ${page.url()}`);
  // Without the token the API refuses.
  assert.equal((await fetch(new URL('api/mesh', base))).status, 401);
  const n = await page.evaluate(() => window.editor.state.mesh.vertices);

  // The screen position of the vertex extreme along the longest axis (min or max).
  const extreme = (which) => page.evaluate((which) => {
    const s = window.editor.state, p = s.restF64, n = s.mesh.vertices;
    const ext = [0, 1, 2].map((c) => s.mesh.bbox.max[c] - s.mesh.bbox.min[c]);
    const axis = ext.indexOf(Math.max(...ext));
    let best = 0;
    for (let i = 1; i < n; i++) if (which === 'min' ? p[3 * i + axis] < p[3 * best + axis] : p[3 * i + axis] > p[3 * best + axis]) best = i;
    const canvas = document.getElementById('canvas').getBoundingClientRect();
    const project = window.editor.view.projector();
    const [x, y] = project(best);
    return { vertex: best, x: x + canvas.left, y: y + canvas.top };
  }, which);

  const stroke = async (from) => {
    await page.mouse.move(from.x, from.y);
    await page.mouse.down();
    for (let k = 1; k <= 5; k++) await page.mouse.move(from.x + 4 * k, from.y + 2 * k);
    await page.mouse.up();
    await page.waitForFunction(() => document.getElementById('progress').style.display === 'none');
  };
  const applied = (count) => page.waitForFunction((count) => (window.editor.state.report?.constraints || 0) >= count && window.editor.state.report?.rank != null, count, { timeout: 120000 });

  await page.click('button[data-tool=brush]');
  const low = await extreme('min');
  await stroke(low);
  // Brushing only the fixed group pins the mesh: the report arrives.
  await applied(1);
  await page.click('#newgroup');
  const high = await extreme('max');
  await stroke(high);
  const groups = await page.evaluate(() => Object.fromEntries([...window.editor.state.groups].map(([g, s]) => [g, [...s]])));
  assert.ok(groups.fixed?.length > 0, 'the brush put vertices in "fixed"');
  assert.ok(groups['handle 1']?.length > 0, 'the brush put vertices in "handle 1"');
  await applied(groups.fixed.length + groups['handle 1'].length);
  const before = await positions();

  // The basis is downloaded after the report and the positions arrive, so
  // wait for it (a slow machine may still be downloading); if it never comes,
  // say what the page showed.
  const onClient = await page
    .waitForFunction(() => window.editor.state.basisGroups?.includes('handle 1'), null, { timeout: 60000 })
    .then(() => true, () => false);
  const why = onClient ? '' : await page.evaluate(() => JSON.stringify({ error: document.getElementById('error').textContent, basis: window.editor.state.report?.editor?.basis ?? null, settings: window.editor.state.report?.editor?.settings ?? null }));
  assert.ok(onClient, `the page took the client path ${why}`);
  const sentBefore = await page.evaluate(() => window.editor.traffic.requests);
  await page.click('button[data-tool=move]');
  await page.mouse.move(high.x, high.y);
  await page.mouse.down();
  for (let k = 1; k <= 20; k++) await page.mouse.move(high.x + 3 * k, high.y - 6 * k);
  await page.mouse.up();
  await page.waitForFunction(() => !window.editor.state.inflight);
  await page.waitForTimeout(300);
  const after = await positions();
  // The drag's 20 frames: one request (the transform on release) and the report.
  const sentDuring = (await page.evaluate(() => window.editor.traffic.requests)) - sentBefore;
  assert.ok(sentDuring <= 2, `${sentDuring} requests during a client-path drag`);
  await checkClientPath(page, groups, after);

  const moved = (v) => Math.hypot(...[0, 1, 2].map((c) => after[3 * v + c] - before[3 * v + c]));
  const diag = (await (await api('api/mesh')).json()).diagonal;
  const handleMove = Math.min(...groups['handle 1'].map(moved));
  const fixedMove = Math.max(...groups.fixed.map(moved));
  // The surface between the groups follows the handle: the largest move of
  // a vertex in neither group (the handle's own vertices do not count).
  const grouped = new Set([...groups.fixed, ...groups['handle 1']]);
  let freeMove = 0;
  for (let v = 0; v < n; v++) if (!grouped.has(v)) freeMove = Math.max(freeMove, moved(v));
  console.log(JSON.stringify({ vertices: n, fixed: groups.fixed.length, handle: groups['handle 1'].length, handleMove: handleMove / diag, fixedMove: fixedMove / diag }));
  assert.ok(handleMove > 0.05 * diag, `the handle moved by ${handleMove / diag} of the diagonal`);
  assert.ok(freeMove > 0.25 * handleMove, `the free surface moved by ${freeMove / diag} of the diagonal, the handle by ${handleMove / diag}`);
  assert.ok(fixedMove <= 1e-9 * diag, `the fixed region moved by ${fixedMove / diag} of the diagonal`);
  mkdirSync(dirname(screenshot), { recursive: true });
  await page.screenshot({ path: screenshot });

  // Saving goes through the API with the token too.
  const [saved] = await Promise.all([page.waitForEvent('download'), page.click('#saveconstraints')]);
  const file = JSON.parse(readFileSync(await saved.path(), 'utf8'));
  assert.equal(file.constraints.length, groups.fixed.length + groups['handle 1'].length, 'the saved constraints');

  // Another origin cannot drive the editor, even knowing the token: a
  // simple (no-cors, text/plain) POST from a page at http://localhost:PORT
  // — this same server, another origin than http://127.0.0.1:PORT — gets
  // 403 and moves nothing; and a page reached through a rebound name
  // (evil.example -> 127.0.0.1) gets 403 itself.
  const settled = await positions();
  const evil = await browser.newPage();
  const port = new URL(base).port;
  await evil.goto(`http://localhost:${port}/api.js`);
  const target = new URL(`api/transform?token=${token}`, base).href;
  const [answer] = await Promise.all([
    evil.waitForResponse((r) => r.url() === target),
    evil.evaluate(async (target) => {
      const body = JSON.stringify({ group: 'handle 1', matrix: [[1, 0, 0, 0.5], [0, 1, 0, 0.5], [0, 0, 1, 0.5]] });
      await fetch(target, { method: 'POST', mode: 'no-cors', headers: { 'content-type': 'text/plain' }, body });
    }, target),
  ]);
  assert.equal(answer.status(), 403, 'a cross-origin POST');
  assert.deepEqual(await positions(), settled, 'a cross-origin POST moved the mesh');
  const rebound = await evil.goto(`http://evil.example:${port}/?token=${token}`);
  assert.equal(rebound.status(), 403, 'a page under a foreign Host');
  await evil.close();

  // The server path: asked for with ?mode=server, and taken by the penalty
  // method (not exact) in the default mode; each frame then downloads the
  // positions.
  const serverPage = await browser.newPage();
  await serverPage.goto(`${url}&mode=server`);
  await serverPage.waitForFunction(() => window.editor && window.editor.ready, null, { timeout: 120000 });
  const onServer = await serverPage.evaluate(() => window.editor.scriptedDrag('handle 1', 3, 0.1, 1, { render: false }));
  assert.equal(onServer.path, 'server', '?mode=server');
  assert.ok(onServer.bytes.received >= 3 * 12 * n, `${onServer.bytes.received} bytes received in 3 server frames`);
  await serverPage.close();
  await page.selectOption('#method', 'penalty');
  await page.waitForFunction(() => window.editor.state.report?.method === 'penalty' && document.getElementById('progress').style.display === 'none', null, { timeout: 120000 });
  await page.waitForTimeout(300);
  const penalty = await page.evaluate(() => window.editor.scriptedDrag('handle 1', 2, 0.1, 1, { render: false }));
  assert.equal(penalty.path, 'server', 'the penalty method');
  // The ordering and threads menus reach the factorisation: the report
  // after the new precompute says what was used.
  await page.selectOption('#ordering', 'natural');
  await page.waitForFunction(() => window.editor.state.report?.ordering === 'natural' && document.getElementById('progress').style.display === 'none', null, { timeout: 120000 });
  await page.selectOption('#threads', '1');
  await page.waitForFunction(() => window.editor.state.report?.threads === 1 && window.editor.state.report?.editor?.settings?.threads === 1, null, { timeout: 120000 });

  if (dragFrames > 0) {
    const figure = await page.evaluate((f) => window.editor.scriptedDrag('handle 1', f), dragFrames);
    console.log(JSON.stringify({ scriptedDrag: figure }));
    await page.screenshot({ path: screenshot.replace(/\.png$/, '-drag.png') });
  }
} catch (e) {
  console.error(e);
  failed = true;
} finally {
  await browser.close();
  server.kill();
}
console.log(failed ? '0 passed, 1 failed' : '1 passed, 0 failed');
process.exit(failed ? 1 : 0);
