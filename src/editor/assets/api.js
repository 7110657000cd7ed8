// The editor's HTTP API (docs/editor.md §6).
//
// Every API request carries the session's token as `Authorization: Bearer`.
// The page takes the token from its own URL (`/?token=T`, as
// `lse-deform edit` prints it), keeps it in sessionStorage so that a reload
// of this tab still works, and removes it from the address bar (and so from
// the history and from what a screenshot or a shoulder sees).
const KEY = 'lse-deform-token';
const fromUrl = new URLSearchParams(location.search).get('token');
if (fromUrl) {
  try { sessionStorage.setItem(KEY, fromUrl); } catch (_) { /* storage off: this load only */ }
  const rest = new URLSearchParams(location.search);
  rest.delete('token');
  const query = rest.toString();
  history.replaceState(null, '', location.pathname + (query ? `?${query}` : '') + location.hash);
}
let stored = null;
try { stored = sessionStorage.getItem(KEY); } catch (_) { /* storage off */ }
const token = fromUrl || stored || '';

export const hasToken = token !== '';

function authorised(init = {}) {
  return { ...init, headers: { ...(init.headers || {}), authorization: `Bearer ${token}` } };
}

async function check(response) {
  if (!response.ok) {
    let message = `${response.status} ${response.statusText}`;
    try { message = (await response.json()).error || message; } catch (_) { /* not JSON */ }
    if (response.status === 401) message += ' — open the URL with ?token=… that lse-deform edit printed';
    throw new Error(message);
  }
  return response;
}

// HTTP body bytes sent and received (Content-Length) since the page
// loaded: the experiments' bytes per frame.
export const traffic = { sent: 0, received: 0, requests: 0 };

export async function request(path, init) {
  const response = await check(await fetch(path, authorised(init)));
  traffic.requests += 1;
  traffic.sent += init && typeof init.body === 'string' ? new TextEncoder().encode(init.body).length : 0;
  traffic.received += Number(response.headers.get('content-length') || 0);
  return response;
}

export async function getJson(path) {
  return (await request(path)).json();
}

export async function send(method, path, body) {
  const text = typeof body === 'string' ? body : JSON.stringify(body);
  return (await request(path, { method, body: text, headers: { 'content-type': 'application/json' } })).json();
}

export async function getF32(path) {
  return new Float32Array(await (await request(path)).arrayBuffer());
}

export async function getF64(path) {
  return new Float64Array(await (await request(path)).arrayBuffer());
}

export async function getU32(path) {
  return new Uint32Array(await (await request(path)).arrayBuffer());
}

// Saves the answer of GET `path` as a file named `name` (a plain link
// could not send the token).
export async function download(path, name) {
  const blob = await (await request(path)).blob();
  const url = URL.createObjectURL(blob);
  const a = document.createElement('a');
  a.href = url;
  a.download = name;
  document.body.appendChild(a);
  a.click();
  a.remove();
  setTimeout(() => URL.revokeObjectURL(url), 10000);
}

// GET /api/basis: its JSON head and the n × (1 + G) RGBA f32 texels (the
// layout in docs/editor.md §6).
export async function getBasis() {
  const buffer = await (await request('/api/basis')).arrayBuffer();
  const h = new DataView(buffer).getUint32(0, true);
  const head = JSON.parse(new TextDecoder().decode(new Uint8Array(buffer, 4, h)));
  return { head, texels: new Float32Array(buffer, 4 + h) };
}
