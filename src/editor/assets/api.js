// The editor's HTTP API (see the README, "Interactive editing").

async function check(response) {
  if (!response.ok) {
    let message = `${response.status} ${response.statusText}`;
    try { message = (await response.json()).error || message; } catch (_) { /* not JSON */ }
    throw new Error(message);
  }
  return response;
}

export async function getJson(path) {
  return (await check(await fetch(path))).json();
}

export async function send(method, path, body) {
  const text = typeof body === 'string' ? body : JSON.stringify(body);
  return (await check(await fetch(path, { method, body: text, headers: { 'content-type': 'application/json' } }))).json();
}

export async function getF32(path) {
  return new Float32Array(await (await check(await fetch(path))).arrayBuffer());
}

export async function getU32(path) {
  return new Uint32Array(await (await check(await fetch(path))).arrayBuffer());
}
