// The editor page: selection (brush, lasso) into named groups, dragging a
// group (move, rotate), switches, report.
//
// Two paths for a drag. Client (`?mode=client`, the default when the
// server has a response basis: Laplacian energy, an exact method): the
// page downloads X₀ and the basis once (GET /api/basis), evaluates every
// frame in the vertex shader in f32 and tells the server the group's
// transform on release (POST /api/transform), after which the server holds
// the exact f64 positions (GET /api/positions, "save deformed mesh").
// Server (`?mode=server`, ARAP, the penalty method, a group outside the
// basis): every frame POSTs the transform and downloads the positions as
// f32.
import { getJson, send, getF32, getF64, getU32, getBasis, download, hasToken, traffic } from '/api.js';
import { View } from '/view.js';

const $ = (id) => document.getElementById(id);
const view = new View($('canvas'));
const COLORS = [[0.35, 0.55, 0.95], [0.95, 0.45, 0.25], [0.3, 0.8, 0.4], [0.85, 0.75, 0.2], [0.7, 0.4, 0.85], [0.3, 0.8, 0.8]];
const BASE = [0.78, 0.78, 0.76];
const CONFLICT = [1.0, 0.1, 0.1];

const state = {
  mesh: null, rest: null, faces: null,
  groups: new Map(),   // name -> Set(vertex), position constraints at rest
  extra: [],           // loaded constraints the page does not draw (other kinds)
  tool: 'orbit', group: 'fixed',
  transforms: new Map(), // name -> {t: [3], angle, axis, centre}
  report: null, conflicting: new Set(),
  frames: [], inflight: false, pending: null,
  mode: new URLSearchParams(location.search).get('mode') === 'server' ? 'server' : 'client',
  basisGroups: null,   // the groups of the basis the view evaluates, or null
};
window.editor = { state, view, traffic, stats: { framesShown: 0, fps: 0, serverFrameMs: [] } };

function showError(e) { $('error').textContent = e ? String(e.message || e) : ''; }

function groupNames() {
  const names = ['fixed', ...[...state.groups.keys()].filter((g) => g !== 'fixed')];
  if (!names.includes(state.group)) names.push(state.group);
  return names;
}

function refreshGroupSelect() {
  const sel = $('group');
  sel.innerHTML = '';
  for (const g of groupNames()) {
    const o = document.createElement('option');
    o.textContent = g; o.value = g; o.selected = g === state.group;
    sel.appendChild(o);
  }
}

function recolor() {
  const c = new Float32Array(state.mesh.vertices * 3);
  for (let i = 0; i < state.mesh.vertices; i++) c.set(BASE, 3 * i);
  groupNames().forEach((g, k) => {
    const col = COLORS[k % COLORS.length];
    for (const v of state.groups.get(g) || []) c.set(col, 3 * v);
  });
  for (const v of state.conflicting) c.set(CONFLICT, 3 * v);
  view.setColors(c);
}

// The constraints file the page sends: position constraints of the groups
// at their rest positions, then the loaded ones of other kinds.
function constraintsJson() {
  const out = [];
  for (const [g, set] of state.groups) {
    for (const v of [...set].sort((a, b) => a - b)) {
      out.push({ type: 'position', vertex: v, target: [0, 1, 2].map((c) => state.restF64[3 * v + c]), group: g });
    }
  }
  return JSON.stringify({ constraints: [...out, ...state.extra] });
}

function readConstraints(json) {
  state.groups = new Map();
  state.extra = [];
  for (const c of json.constraints || []) {
    if (c.type === 'position' && c.group && c.weight === undefined) {
      if (!state.groups.has(c.group)) state.groups.set(c.group, new Set());
      state.groups.get(c.group).add(c.vertex);
    } else {
      state.extra.push(c);
    }
  }
  state.order = JSON.parse(JSON.stringify(json.constraints || []));
}

async function pollProgress() {
  const box = $('progress');
  for (;;) {
    const p = await getJson('/api/progress');
    if (!p.busy) { box.style.display = 'none'; return; }
    box.style.display = 'block';
    box.textContent = `${p.stage} … ${(p.elapsed_s || 0).toFixed(1)} s`;
    await new Promise((r) => setTimeout(r, 200));
  }
}

async function withProgress(promise) {
  let done = false;
  const poll = (async () => { await new Promise((r) => setTimeout(r, 150)); while (!done) { await pollProgress(); await new Promise((r) => setTimeout(r, 150)); } })();
  try { return await promise; } finally { done = true; await poll; $('progress').style.display = 'none'; }
}

async function applyConstraints() {
  showError(null);
  try {
    const body = constraintsJson();
    const report = await withProgress(send('PUT', '/api/constraints', body));
    state.transforms.clear();
    const json = JSON.parse(body);
    state.order = json.constraints;
    setReport(report);
    await loadPositions();
  } catch (e) { showError(e); }
}

async function loadPositions() {
  view.setPositions(await getF32('/api/positions?format=f32'));
  state.basisGroups = null;
  showPath();
  await syncBasis();
  view.render();
}

// Client mode: the basis downloaded once per precompute when the server
// has one that describes the positions and the method is exact.
async function syncBasis() {
  const r = state.report || {}, e = r.editor || {}, b = e.basis;
  const exact = e.settings && e.settings.energy === 'laplacian' && e.settings.method !== 'penalty';
  if (state.mode !== 'client' || !b || b.stale || !exact) return;
  const { head, texels } = await getBasis();
  if (head.generation !== e.generation) return; // changed meanwhile: stay on the server path
  view.setBasis(texels, head.groups.length);
  state.basisGroups = head.groups;
  view.setTransforms(basisMatrices());
  renderReport();
  showPath();
}

// The HUD's line: frames per second, the path, what is displayed and saved.
function showPath() {
  const where = state.basisGroups ? 'client: f32 basis in the shader' : `server: f32 positions ${window.editor.stats.serverFrameMs.at(-1)?.toFixed(2) ?? '–'} ms`;
  $('hud').textContent = `${window.editor.stats.fps.toFixed(1)} fps · ${where}${arapRate()} · saved mesh exact f64`;
}

// ARAP's iterations per second on the server (the median iteration of the
// last report), or nothing for the Laplacian energy.
function arapRate() {
  const t = state.report?.arap?.time_per_iteration_s;
  return t > 0 ? ` · ARAP ${(1 / t).toFixed(0)} iterations/s` : '';
}

// The transforms of the basis groups, in its order (identity if unmoved).
function basisMatrices() {
  return state.basisGroups.map((g) => (state.transforms.has(g) ? matrixOf(state.transforms.get(g)) : [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]));
}

// Whether a drag of `name` is drawn by the page alone.
function clientPath(name) {
  return state.basisGroups !== null && state.basisGroups.includes(name) && !state.report?.editor?.basis?.stale;
}

function setReport(report) {
  state.report = report;
  state.conflicting = new Set();
  const conflicts = Array.isArray(report.conflicting) ? report.conflicting : [];
  for (const c of conflicts) {
    const k = state.order && state.order[c.index];
    if (!k) continue;
    for (const v of [k.vertex, ...(k.vertices || [])]) if (v !== undefined) state.conflicting.add(v);
  }
  recolor();
  renderReport();
}

function fmt(x, d = 3) { return x === null || x === undefined ? "–" : (typeof x === "number" && !Number.isInteger(x) ? x.toPrecision(d) : String(x)); }

function renderReport() {
  const r = state.report || {};
  const e = r.editor || {};
  const t = (e.timings_s) || {};
  const conflicts = Array.isArray(r.conflicting) ? r.conflicting : [];
  const lines = [
    `method      ${r.method || '–'}  laplacian ${r.laplacian || '–'}`,
    `constraints ${r.constraints ?? '–'} (hard ${r.hard_constraints ?? '–'}, soft ${r.soft_constraints ?? '–'})`,
    `rank        ${fmt(r.rank)}`,
    `redundant   ${Array.isArray(r.redundant) ? r.redundant.length : fmt(r.redundant)}`,
    `<span class="${conflicts.length ? 'bad' : ''}">conflicting ${Array.isArray(r.conflicting) ? conflicts.length : fmt(r.conflicting)}${conflicts.length ? ' (red on the mesh)' : ''}</span>`,
    `max hard residual  ${fmt(r.max_constraint_residual_relative)} × diag`,
    `least squares res. ${fmt(r.least_squares_residual_relative)} (relative)`,
    `forward error est. ${fmt(r.forward_error_estimate)} × diag`,
    `set-up      ${fmt(t.setup_s)} s`,
    `precompute  ${fmt(t.precompute_s)} s`,
    `basis       ${fmt(t.basis_s)} s`,
    `frame (server, median) ${e.frame_median_s ? (1e3 * e.frame_median_s).toFixed(2) + ' ms' : '–'}`,
    `frames shown/s ${window.editor.stats.fps.toFixed(1)}`,
    ...(state.basisGroups
      ? ['display     f32 (basis in the shader)']
      : ['display     f32 (server positions)']),
    'saved mesh  exact f64 (server)',
    ...(r.warnings || []).map((w) => `<span class="bad">warning: ${w.replace(/</g, '&lt;')}</span>`),
  ];
  if (r.arap) lines.push(`ARAP        ${r.arap.iterations} iterations, energy ${fmt(r.arap.energies?.at(-1))},${arapRate().replace(' · ARAP', '')} (median)`);
  $('report').innerHTML = lines.join('\n');
}

// --- picking -------------------------------------------------------------

function facingVertices() {
  // Vertices whose screen position is in the region; among them those
  // within a slab of the nearest depth (the visible side).
  return view.projector();
}

function pickInside(test) {
  const project = facingVertices();
  const hits = [];
  let nearest = Infinity;
  for (let i = 0; i < state.mesh.vertices; i++) {
    const [x, y, d] = project(i);
    if (d > 0 && test(x, y)) { hits.push([i, d]); nearest = Math.min(nearest, d); }
  }
  const slab = 0.15 * view.radius;
  return hits.filter(([, d]) => d <= nearest + slab).map(([i]) => i);
}

function paint(x, y, add) {
  const r = Number($('radius').value);
  const picked = pickInside((px, py) => (px - x) ** 2 + (py - y) ** 2 <= r * r);
  changeGroup(picked, add);
}

function changeGroup(vertices, add) {
  if (!state.groups.has(state.group)) state.groups.set(state.group, new Set());
  const set = state.groups.get(state.group);
  for (const v of vertices) {
    if (add) {
      for (const [g, other] of state.groups) if (g !== state.group) other.delete(v);
      set.add(v);
    } else set.delete(v);
  }
  recolor();
  view.render();
}

function pointInPolygon(poly, x, y) {
  let inside = false;
  for (let i = 0, j = poly.length - 1; i < poly.length; j = i++) {
    const [xi, yi] = poly[i], [xj, yj] = poly[j];
    if ((yi > y) !== (yj > y) && x < ((xj - xi) * (y - yi)) / (yj - yi) + xi) inside = !inside;
  }
  return inside;
}

// --- dragging a group ------------------------------------------------------

function groupCentre(name) {
  const set = state.groups.get(name);
  const c = [0, 0, 0];
  if (!set || !set.size) return c;
  for (const v of set) for (let k = 0; k < 3; k++) c[k] += state.restF64[3 * v + k];
  return c.map((s) => s / set.size);
}

function transformOf(name) {
  if (!state.transforms.has(name)) state.transforms.set(name, { t: [0, 0, 0], angle: 0, axis: [0, 0, 1], centre: groupCentre(name) });
  return state.transforms.get(name);
}

// 3 × 4 row-major: rotation by `angle` about `axis` through `centre`, then `t`.
function matrixOf(tr) {
  const [x, y, z] = tr.axis, c = Math.cos(tr.angle), s = Math.sin(tr.angle), k = 1 - c;
  const R = [[c + x * x * k, x * y * k - z * s, x * z * k + y * s], [y * x * k + z * s, c + y * y * k, y * z * k - x * s], [z * x * k - y * s, z * y * k + x * s, c + z * z * k]];
  return R.map((row, i) => {
    const rc = row[0] * tr.centre[0] + row[1] * tr.centre[1] + row[2] * tr.centre[2];
    return [...row, tr.centre[i] - rc + tr.t[i]];
  });
}

// One frame of a drag of `name`: drawn from the basis on the client path,
// else sent to the server.
function dragFrame(name) {
  if (!clientPath(name)) { sendFrame(name); return; }
  view.setTransforms(basisMatrices());
  view.render();
  countFrame();
}

// The end of a drag: the server is told the final transform (then its
// positions are the exact f64 ones) and the report refreshed.
async function release(name) {
  if (clientPath(name)) {
    state.inflight = true;
    try { await send('POST', '/api/transform', { group: name, matrix: matrixOf(transformOf(name)) }); } catch (e) { showError(e); } finally { state.inflight = false; }
  }
  await refreshReport();
  // After a drag on the server path the basis is taken up again when it
  // describes the positions once more.
  if (state.basisGroups === null) { try { await syncBasis(); view.render(); } catch (e) { showError(e); } }
}

// Sends the group's transform; while a frame is in flight only the latest
// request waits (frames are dropped, never queued).
async function sendFrame(name) {
  const matrix = matrixOf(transformOf(name));
  if (state.inflight) { state.pending = name; return; }
  state.inflight = true;
  try {
    const answer = await send('POST', '/api/transform', { group: name, matrix });
    window.editor.stats.serverFrameMs.push(1e3 * answer.compute_s);
    view.setPositions(await getF32('/api/positions?format=f32'));
    if (state.basisGroups) { state.basisGroups = null; renderReport(); }
    view.render();
    countFrame();
  } catch (e) { showError(e); } finally {
    state.inflight = false;
    if (state.pending) { const p = state.pending; state.pending = null; sendFrame(p); }
  }
}

function countFrame() {
  const now = performance.now();
  state.frames.push(now);
  while (state.frames.length && state.frames[0] < now - 1000) state.frames.shift();
  window.editor.stats.framesShown += 1;
  window.editor.stats.fps = state.frames.length > 1 ? (1000 * (state.frames.length - 1)) / (now - state.frames[0]) : 0;
  showPath();
}

// A scripted drag of `frames` frames (tests, figures): translates `group`
// along `turn` of a circle of radius `amplitude` × the bounding-box radius.
// Client path (the basis on the GPU): each frame uploads the transforms and
// draws, and the final transform is POSTed at the end (the release).
// Server path: each frame POSTs the transform and waits for the positions
// (f32). Each drawn frame waits for one pixel read back (the frame
// finished). With `render: false` nothing is drawn: on the server path the
// frame rate of the server and the transfer alone, on the client path the
// page's own work per frame. Returns the frame rate, the medians of each
// phase (ms) and the HTTP body bytes per frame.
window.editor.scriptedDrag = async (group, frames, amplitude = 0.3, turn = 1, { render = true } = {}) => {
  const tr = transformOf(group);
  const client = clientPath(group);
  // One pixel read back: returns when the GPU (or SwiftShader, which
  // returns from finish() at once) has drawn the frame.
  const pixel = new Uint8Array(4);
  const drawn = () => view.gl.readPixels(0, 0, 1, 1, view.gl.RGBA, view.gl.UNSIGNED_BYTE, pixel);
  // The page yields to the event loop between frames, as a drag does.
  const channel = new MessageChannel();
  const yieldNow = () => new Promise((r) => { channel.port1.onmessage = r; channel.port2.postMessage(0); });
  if (render) { view.render(); drawn(); } // shader compile and texture upload before the clock
  const sent0 = traffic.sent, received0 = traffic.received;
  const t0 = performance.now();
  // Per frame: the page's synchronous JavaScript (matrices, upload, draw
  // call), the upload alone, and until the GPU (or SwiftShader) is done;
  // on the server path also the server's compute (its own clock), the POST
  // round trip and the positions' download.
  const phases = { js: [], upload: [], render: [], server: [], request: [], post: [], download: [] };
  for (let f = 1; f <= frames; f++) {
    const a = (2 * Math.PI * turn * f) / frames;
    tr.t = [amplitude * view.radius * Math.sin(a), amplitude * view.radius * (1 - Math.cos(a)), 0];
    let positions = null;
    const t1 = performance.now();
    if (!client) {
      const answer = await send('POST', '/api/transform', { group, matrix: matrixOf(tr) });
      phases.server.push(1e3 * answer.compute_s);
      phases.request.push(1e3 * answer.request_s);
      window.editor.stats.serverFrameMs.push(1e3 * answer.compute_s);
      const t2 = performance.now();
      positions = await getF32('/api/positions?format=f32');
      phases.post.push(t2 - t1);
      phases.download.push(performance.now() - t2);
    }
    const t3 = performance.now();
    if (client) view.setTransforms(basisMatrices());
    else if (render) { view.setPositions(positions); state.basisGroups = null; }
    const t4 = performance.now();
    if (render) view.render();
    const t5 = performance.now();
    if (render) drawn();
    const t6 = performance.now();
    phases.upload.push(t4 - t3);
    phases.js.push(t5 - t3);
    phases.render.push(t6 - t3);
    countFrame();
    if (client) await yieldNow();
  }
  if (client) await send('POST', '/api/transform', { group, matrix: matrixOf(tr) });
  const seconds = (performance.now() - t0) / 1000;
  const bytes = { sent: traffic.sent - sent0, received: traffic.received - received0 };
  await refreshReport();
  const median = (xs) => (xs.length ? [...xs].sort((a, b) => a - b)[xs.length >> 1] : null);
  // performance.now() is coarse (0.1 ms in Chromium): the means too.
  const mean = (xs) => (xs.length ? xs.reduce((a, b) => a + b, 0) / xs.length : null);
  return {
    frames,
    path: client ? 'client' : 'server',
    seconds,
    fps: frames / seconds,
    rendered: render,
    bytesPerFrame: (bytes.sent + bytes.received) / frames,
    bytes,
    jsMedianMs: median(phases.js),
    jsMeanMs: mean(phases.js),
    uploadMeanMs: mean(phases.upload),
    renderMeanMs: mean(phases.render),
    uploadMedianMs: median(phases.upload),
    renderMedianMs: median(phases.render),
    serverFrameMedianMs: median(phases.server),
    serverRequestMedianMs: median(phases.request),
    postMedianMs: median(phases.post),
    downloadMedianMs: median(phases.download),
  };
};

// The 3 × 4 transform of group `name` as the page holds it (tests).
window.editor.matrixOf = (name) => matrixOf(transformOf(name));

// The positions the page displays (f32, n × 3): on the client path read
// back from the vertex shader (transform feedback), else the server's.
window.editor.displayedPositions = () => (state.basisGroups ? view.readBack() : view.positions);

// --- events ----------------------------------------------------------------

function setupEvents() {
  const canvas = $('canvas');
  const lasso = $('lasso');
  let drag = null;
  canvas.addEventListener('contextmenu', (e) => e.preventDefault());
  canvas.addEventListener('pointerdown', (e) => {
    canvas.setPointerCapture(e.pointerId);
    const tool = e.button === 2 ? 'orbit' : state.tool;
    drag = { tool, x: e.offsetX, y: e.offsetY, poly: [[e.offsetX, e.offsetY]], shift: e.shiftKey };
    if (tool === 'brush' || tool === 'erase') paint(e.offsetX, e.offsetY, tool === 'brush');
    if (tool === 'move' || tool === 'rotate') {
      const tr = transformOf(state.group);
      drag.start = { t: [...tr.t], angle: tr.angle };
      const { f } = view.frame();
      // Rotation about the view axis: a new axis starts from the current pose.
      if (tool === 'rotate' && tr.angle === 0) tr.axis = f.map((v) => -v);
    }
  });
  canvas.addEventListener('pointermove', (e) => {
    if (!drag) return;
    const dx = e.offsetX - drag.x, dy = e.offsetY - drag.y;
    if (drag.tool === 'orbit') {
      view.yaw -= 0.01 * (e.offsetX - (drag.lx ?? drag.x));
      view.pitch = Math.max(-1.5, Math.min(1.5, view.pitch + 0.01 * (e.offsetY - (drag.ly ?? drag.y))));
      drag.lx = e.offsetX; drag.ly = e.offsetY;
      view.render();
    } else if (drag.tool === 'brush' || drag.tool === 'erase') {
      paint(e.offsetX, e.offsetY, drag.tool === 'brush');
    } else if (drag.tool === 'lasso') {
      drag.poly.push([e.offsetX, e.offsetY]);
      const ctx = lasso.getContext('2d');
      lasso.width = canvas.clientWidth; lasso.height = canvas.clientHeight;
      ctx.strokeStyle = '#ff0'; ctx.beginPath();
      drag.poly.forEach(([x, y], i) => (i ? ctx.lineTo(x, y) : ctx.moveTo(x, y)));
      ctx.stroke();
    } else if (drag.tool === 'move') {
      const { r, u } = view.frame();
      const scale = (2 * view.distance * Math.tan(0.4)) / canvas.clientHeight;
      const tr = transformOf(state.group);
      tr.t = [0, 1, 2].map((c) => drag.start.t[c] + scale * (dx * r[c] - dy * u[c]));
      dragFrame(state.group);
    } else if (drag.tool === 'rotate') {
      const tr = transformOf(state.group);
      tr.angle = drag.start.angle + 0.01 * dx;
      dragFrame(state.group);
    }
  });
  canvas.addEventListener('pointerup', () => {
    if (!drag) return;
    const d = drag;
    drag = null;
    if (d.tool === 'lasso') {
      lasso.getContext('2d').clearRect(0, 0, lasso.width, lasso.height);
      if (d.poly.length > 2) changeGroup(pickInside((x, y) => pointInPolygon(d.poly, x, y)), !d.shift);
      applyConstraints();
    } else if (d.tool === 'brush' || d.tool === 'erase') {
      applyConstraints();
    } else if (d.tool === 'move' || d.tool === 'rotate') {
      release(state.group);
    }
  });
  canvas.addEventListener('wheel', (e) => {
    e.preventDefault();
    view.distance *= Math.exp(0.001 * e.deltaY);
    view.render();
  }, { passive: false });
  for (const b of document.querySelectorAll('#tools button')) {
    b.addEventListener('click', () => {
      state.tool = b.dataset.tool;
      for (const o of document.querySelectorAll('#tools button')) o.classList.toggle('on', o === b);
    });
  }
  $('group').addEventListener('change', (e) => { state.group = e.target.value; });
  $('newgroup').addEventListener('click', () => {
    let k = 1;
    while (state.groups.has(`handle ${k}`)) k++;
    state.group = `handle ${k}`;
    state.groups.set(state.group, new Set());
    refreshGroupSelect();
  });
  $('clear').addEventListener('click', () => { state.groups.delete(state.group); recolor(); applyConstraints(); });
  $('reset').addEventListener('click', () => { state.transforms.clear(); applyConstraints(); });
  const settings = async (change) => {
    showError(null);
    try { setReport(await withProgress(send('PUT', '/api/settings', change))); state.transforms.clear(); await loadPositions(); } catch (e) { showError(e); }
  };
  for (const id of ['energy', 'laplacian', 'method', 'refine', 'ordering', 'threads']) {
    $(id).addEventListener('change', (e) => settings({ [id]: e.target.value }));
  }
  $('weight').addEventListener('change', (e) => { $('wval').textContent = e.target.value; settings({ weight: 10 ** Number(e.target.value) }); });
  $('arapiters').addEventListener('change', (e) => settings({ arap_iterations_per_frame: Number(e.target.value) }));
  $('saveconstraints').addEventListener('click', () => download('/api/constraints', 'constraints.json').catch(showError));
  $('savemesh').addEventListener('click', () => download('/api/deformed.obj', 'deformed.obj').catch(showError));
  $('load').addEventListener('change', async (e) => {
    const file = e.target.files[0];
    if (!file) return;
    showError(null);
    try {
      const text = await file.text();
      setReport(await withProgress(send('PUT', '/api/constraints', text)));
      readConstraints(await getJson('/api/constraints'));
      refreshGroupSelect(); recolor(); await loadPositions();
    } catch (err) { showError(err); }
  });
}

async function refreshReport() {
  try { setReport(await getJson('/api/report')); } catch (e) { showError(e); }
}

async function main() {
  if (!hasToken) throw new Error('no session token: open the URL with ?token=… that lse-deform edit printed');
  state.mesh = await getJson('/api/mesh');
  $('meshinfo').textContent = `${state.mesh.name}: ${state.mesh.vertices} vertices, ${state.mesh.faces} triangles`;
  const [rest, faces] = await Promise.all([getF32('/api/rest-positions'), getU32('/api/faces')]);
  state.restF64 = await getF64('/api/rest-positions?format=f64');
  view.setMesh(rest, faces, state.mesh.bbox);
  readConstraints(await getJson('/api/constraints'));
  refreshGroupSelect();
  setupEvents();
  await refreshReport();
  await loadPositions();
  const s = state.report?.editor?.settings;
  if (s) for (const id of ['energy', 'laplacian', 'method', 'refine', 'ordering', 'threads']) $(id).value = String(s[id]);
  window.addEventListener('resize', () => view.render());
  window.editor.ready = true;
}

main().catch(showError);
