// The editor's drag in headless Chromium, client path against server path
// in one run; run by the `editor` experiment (experiments/editor.rs):
//
//   node experiments/editor_frames.mjs --frames 300 --drawn-frames 30 --out DIR MESH [MESH ...]
//
// For each mesh: `lse-deform scene MESH` (20 % fixed, a 2 % handle, as the
// groups "fixed" and "handle") with every target at rest,
// `lse-deform edit MESH --constraints …` (LSE_DEFORM_BIN), then in
// Chromium (CHROMIUM; SwiftShader, no GPU; playwright-core from
// tests/browser's npm install):
//   - the page with ?mode=client: window.editor.scriptedDrag('handle',
//     FRAMES) without drawing, then DRAWN frames with drawing (the same
//     circle in fewer steps: software drawing of a large mesh takes
//     seconds a frame), each frame uploading the group's transform to the
//     vertex shader's basis; the final transform POSTed at the end; the
//     shader's positions read back once (transform feedback) against the
//     server's f64 positions (GET /api/positions);
//   - the page with ?mode=server: the same drags, each frame POSTing the
//     transform and downloading the positions (f32);
//   - ARAP frames: `PUT /api/settings {"energy": "arap"}`, then a drag of
//     ARAP_FRAMES frames without drawing on the server path (ARAP has no
//     basis), each frame running the session's iterations per frame
//     warm-started from the last; the report's median time per iteration
//     (`arap.time_per_iteration_s`, what the page's HUD shows as
//     iterations/s).
// Bytes per frame are HTTP body bytes (Content-Length, both directions)
// over the drag including the final POST, divided by its frames. Writes
// DIR/frames.json (the measurements) and, per mesh, the page's screenshot,
// one with the page's former near plane (1e-6 of the bounding radius) and
// `lse-deform render`'s image of the same view (the page's yaw and pitch
// as render's azimuth and elevation; render is orthographic, the page
// perspective).
import { spawn, execFileSync } from 'node:child_process';
import { createInterface } from 'node:readline';
import { createRequire } from 'node:module';
import { mkdtempSync, mkdirSync, readFileSync, writeFileSync } from 'node:fs';
import { gunzipSync } from 'node:zlib';
import { tmpdir } from 'node:os';
import { basename, dirname, join, resolve } from 'node:path';
import { fileURLToPath } from 'node:url';

const here = dirname(fileURLToPath(import.meta.url));
const require = createRequire(join(here, '../tests/browser/package.json'));
const { chromium } = require('playwright-core');

const args = process.argv.slice(2);
const option = (name, fallback) => {
  const i = args.indexOf(name);
  if (i < 0) return fallback;
  const [, value] = args.splice(i, 2);
  return value;
};
const frames = Number(option('--frames', '300'));
const drawnFrames = Number(option('--drawn-frames', String(frames)));
const arapFrames = Number(option('--arap-frames', '60'));
const out = resolve(option('--out', '.'));
const meshes = args;
if (!meshes.length) throw new Error('usage: node experiments/editor_frames.mjs [--frames N] [--drawn-frames M] [--arap-frames K] [--out DIR] MESH [MESH ...]');
const bin = resolve(process.env.LSE_DEFORM_BIN || join(here, '../target/release/lse-deform'));
const work = mkdtempSync(join(tmpdir(), 'lse-frames-'));
// The page's default camera (view.js): yaw 0.6 rad, pitch 0.3 rad, y up.
const YAW = 0.6, PITCH = 0.3;

function restPositions(mesh) {
  const bytes = readFileSync(mesh);
  const text = (mesh.endsWith('.gz') ? gunzipSync(bytes) : bytes).toString('utf8');
  const p = [];
  for (const line of text.split('\n')) if (line.startsWith('v ')) p.push(line.trim().split(/\s+/).slice(1, 4).map(Number));
  return p;
}

// `lse-deform scene` writes the handle moved; the page's groups start at rest.
function sceneWithGroups(mesh, json) {
  execFileSync(bin, ['scene', mesh, '-o', `${json}.raw`]);
  const p = restPositions(mesh);
  const doc = JSON.parse(readFileSync(`${json}.raw`, 'utf8'));
  for (const c of doc.constraints) {
    if (c.group !== 'fixed' && c.group !== 'handle') throw new Error(`${mesh}: scene wrote a constraint outside the groups fixed and handle`);
    c.target = p[c.vertex];
  }
  writeFileSync(json, JSON.stringify(doc));
}

async function startEditor(mesh, constraints) {
  const server = spawn(bin, ['edit', mesh, '--constraints', constraints, '--port', '0'], { stdio: ['ignore', 'pipe', 'inherit'] });
  const url = await new Promise((ok, fail) => {
    createInterface({ input: server.stdout }).once('line', (line) => {
      const m = /^listening on (http:\/\/\S+)$/.exec(line);
      m ? ok(m[1]) : fail(new Error(`first line: ${line}`));
    });
    server.once('exit', (code) => fail(new Error(`server exited with ${code}`)));
  });
  return { server, url };
}

async function openPage(browser, url, mode) {
  const page = await browser.newPage({ viewport: { width: 1200, height: 800 } });
  page.on('pageerror', (e) => console.error('page error:', e.message));
  await page.goto(`${url}&mode=${mode}`);
  await page.waitForFunction(() => window.editor && window.editor.ready, null, { timeout: 1800000 });
  await page.evaluate(([yaw, pitch]) => { const v = window.editor.view; v.yaw = yaw; v.pitch = pitch; v.render(); }, [YAW, PITCH]);
  return page;
}

const drag = (page, render) => page.evaluate(([f, render]) => window.editor.scriptedDrag('handle', f, 0.25, 1, { render }), [render ? drawnFrames : frames, render]);

async function measure(browser, url, token, diag, name) {
  const api = async (path) => (await fetch(new URL(path, url), { headers: { authorization: `Bearer ${token}` } })).arrayBuffer();
  const rows = {};
  const client = await openPage(browser, url, 'client');
  await client.screenshot({ path: join(out, `${name}-page.png`) });
  // The former near plane (1e-6 of the radius): the speckles and stripes.
  await client.evaluate(() => {
    const v = window.editor.view, fixed = v.matrices.bind(v);
    v.matrices = () => {
      const m = fixed(), near = Math.max(1e-6 * v.radius, v.distance - 4 * v.radius), far = v.distance + 4 * v.radius;
      m.proj[10] = (far + near) / (near - far); m.proj[14] = (2 * far * near) / (near - far);
      return m;
    };
    v.render();
  });
  await client.screenshot({ path: join(out, `${name}-page-former-near-plane.png`) });
  await client.evaluate(() => { const v = window.editor.view; delete v.matrices; v.render(); });
  const onClient = await client.evaluate(() => window.editor.state.basisGroups !== null);
  if (!onClient) throw new Error(`${name}: the page did not take the client path`);
  rows.client = { without: await drag(client, false), with: await drag(client, true) };
  // The shader's positions at the final transform against the server's f64.
  const shown = await client.evaluate(() => Array.from(window.editor.displayedPositions()));
  const exact = new Float64Array(await api('api/positions?format=f64'));
  let err = 0;
  for (let i = 0; i < exact.length; i++) err = Math.max(err, Math.abs(shown[i] - exact[i]));
  rows.client.readbackError = err / diag;
  await client.close();
  const server = await openPage(browser, url, 'server');
  rows.server = { without: await drag(server, false), with: await drag(server, true) };
  const f32 = new Float32Array(await api('api/positions?format=f32'));
  const exact2 = new Float64Array(await api('api/positions?format=f64'));
  let err2 = 0;
  for (let i = 0; i < exact2.length; i++) err2 = Math.max(err2, Math.abs(f32[i] - exact2[i]));
  rows.server.readbackError = err2 / diag;
  await server.close();
  rows.arap = await arapFramesOf(browser, url, token);
  return rows;
}

// ARAP frames on the server path, after switching the session's energy.
async function arapFramesOf(browser, url, token) {
  const headers = { authorization: `Bearer ${token}`, 'content-type': 'application/json' };
  const put = await fetch(new URL('api/settings', url), { method: 'PUT', headers, body: JSON.stringify({ energy: 'arap' }) });
  if (!put.ok) throw new Error(`PUT /api/settings: ${put.status} ${await put.text()}`);
  const page = await openPage(browser, url, 'server');
  const without = await page.evaluate(([f]) => window.editor.scriptedDrag('handle', f, 0.25, 1, { render: false }), [arapFrames]);
  await page.close();
  const report = await (await fetch(new URL('api/report', url), { headers })).json();
  return {
    without,
    iterationsPerFrame: report.editor.settings.arap_iterations_per_frame,
    timePerIterationS: report.arap.time_per_iteration_s,
  };
}

mkdirSync(out, { recursive: true });
const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || 'chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync', '--use-angle=swiftshader', '--enable-unsafe-swiftshader'],
});
const results = [];
try {
  for (const mesh of meshes) {
    const name = basename(mesh).replace(/\.obj(\.gz)?$/, '');
    const constraints = join(work, `${name}.json`);
    sceneWithGroups(mesh, constraints);
    const { server, url } = await startEditor(mesh, constraints);
    try {
      const token = new URL(url).searchParams.get('token');
      const info = await (await fetch(new URL('api/mesh', url), { headers: { authorization: `Bearer ${token}` } })).json();
      const rows = await measure(browser, url, token, info.diagonal, name);
      results.push({ name, vertices: info.vertices, frames, drawnFrames, rows });
      console.log(JSON.stringify(results.at(-1)));
      execFileSync(bin, ['render', mesh, '-o', join(out, `${name}-render.png`), '--up', 'y',
        '--azimuth', String((YAW * 180) / Math.PI), '--elevation', String((PITCH * 180) / Math.PI), '--size', '900x800']);
    } finally {
      server.kill();
    }
  }
} finally {
  await browser.close();
}
writeFileSync(join(out, 'frames.json'), JSON.stringify(results, null, 1));
