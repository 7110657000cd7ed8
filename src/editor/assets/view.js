// WebGL2 view: the mesh flat-shaded (normals from screen-space derivatives,
// so moved positions need no normal update), per-vertex colours, an orbit
// camera, and the projection used for picking.
//
// Two ways to get positions: a buffer of f32 positions (the server's, the
// fallback path), or the response basis evaluated in the vertex shader,
// X = X₀ + Σ_g M_g r_g per vertex (GET /api/basis: one RGBA32F texel of X₀
// and one per group of R_g's row, fetched by gl_VertexID; the groups'
// 3 × 4 transforms in a G × 3 RGBA32F texture, the only upload per frame).

const VS = `#version 300 es
layout(location = 0) in vec3 pos; layout(location = 1) in vec3 col;
uniform mat4 mv; uniform mat4 proj;
out vec3 vpos; out vec3 vcol;
void main() { vec4 p = mv * vec4(pos, 1.0); vpos = p.xyz; vcol = col; gl_Position = proj * p; }`;
// The basis evaluated per vertex, in f32 (what the page displays).
const DEFORMED = `
uniform highp sampler2D basis; uniform highp sampler2D xf;
uniform int groups; uniform int width;
vec4 texel(int i) { return texelFetch(basis, ivec2(i % width, i / width), 0); }
vec3 deformed() {
  int base = gl_VertexID * (groups + 1);
  vec3 p = texel(base).xyz;
  for (int g = 0; g < groups; g++) {
    vec4 r = texel(base + 1 + g);
    p += vec3(dot(texelFetch(xf, ivec2(0, g), 0), r), dot(texelFetch(xf, ivec2(1, g), 0), r), dot(texelFetch(xf, ivec2(2, g), 0), r));
  }
  return p;
}`;
const VS_BASIS = `#version 300 es
precision highp float; precision highp int;
layout(location = 1) in vec3 col;
uniform mat4 mv; uniform mat4 proj;
out vec3 vpos; out vec3 vcol;${DEFORMED}
void main() { vec4 p = mv * vec4(deformed(), 1.0); vpos = p.xyz; vcol = col; gl_Position = proj * p; }`;
// Transform feedback of the same evaluation: the displayed positions read
// back (tests, experiments).
const VS_READBACK = `#version 300 es
precision highp float; precision highp int;
out vec3 xfb;${DEFORMED}
void main() { xfb = deformed(); gl_Position = vec4(0.0); }`;
const FS_NONE = `#version 300 es
precision highp float; out vec4 color; void main() { color = vec4(0.0); }`;
const FS = `#version 300 es
precision highp float;
in vec3 vpos; in vec3 vcol; out vec4 color;
void main() {
  vec3 n = normalize(cross(dFdx(vpos), dFdy(vpos)));
  float l = 0.2 + 0.8 * abs(n.z);
  color = vec4(vcol * l, 1.0);
}`;

function compile(gl, type, src) {
  const s = gl.createShader(type);
  gl.shaderSource(s, src);
  gl.compileShader(s);
  if (!gl.getShaderParameter(s, gl.COMPILE_STATUS)) throw new Error(gl.getShaderInfoLog(s));
  return s;
}

function link(gl, vs, fs, varyings) {
  const p = gl.createProgram();
  gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, vs));
  gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, fs));
  if (varyings) gl.transformFeedbackVaryings(p, varyings, gl.SEPARATE_ATTRIBS);
  gl.linkProgram(p);
  if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
  return p;
}

function floatTexture(gl, width, height, data) {
  const t = gl.createTexture();
  gl.bindTexture(gl.TEXTURE_2D, t);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MIN_FILTER, gl.NEAREST);
  gl.texParameteri(gl.TEXTURE_2D, gl.TEXTURE_MAG_FILTER, gl.NEAREST);
  gl.texImage2D(gl.TEXTURE_2D, 0, gl.RGBA32F, width, height, 0, gl.RGBA, gl.FLOAT, data);
  return t;
}

export class View {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error('WebGL2 is not available in this browser');
    this.gl = gl;
    this.program = link(gl, VS, FS);
    this.basisProgram = link(gl, VS_BASIS, FS);
    this.readbackProgram = link(gl, VS_READBACK, FS_NONE, ['xfb']);
    this.basis = null;
    this.vao = gl.createVertexArray();
    this.posBuf = gl.createBuffer();
    this.colBuf = gl.createBuffer();
    this.idxBuf = gl.createBuffer();
    this.yaw = 0.6; this.pitch = 0.3; this.distance = 3; this.center = [0, 0, 0]; this.radius = 1;
  }

  setMesh(positions, faces, bbox) {
    const gl = this.gl;
    this.n = positions.length / 3;
    this.count = faces.length;
    gl.bindVertexArray(this.vao);
    gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, this.idxBuf);
    gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, faces, gl.STATIC_DRAW);
    this.setPositions(positions);
    gl.bindBuffer(gl.ARRAY_BUFFER, this.posBuf);
    const lp = 0;
    gl.enableVertexAttribArray(lp);
    gl.vertexAttribPointer(lp, 3, gl.FLOAT, false, 0, 0);
    this.setColors(new Float32Array(this.n * 3).fill(0.8));
    gl.bindBuffer(gl.ARRAY_BUFFER, this.colBuf);
    const lc = 1;
    gl.enableVertexAttribArray(lc);
    gl.vertexAttribPointer(lc, 3, gl.FLOAT, false, 0, 0);
    this.center = [0, 1, 2].map((c) => 0.5 * (bbox.min[c] + bbox.max[c]));
    this.radius = 0.5 * Math.hypot(...[0, 1, 2].map((c) => bbox.max[c] - bbox.min[c]));
    this.distance = 2.6 * this.radius;
  }

  // The basis of GET /api/basis (`texels`: n × (1 + G) RGBA f32 texels)
  // and the groups' count: drawn by the vertex shader from now on, until
  // setPositions or clearBasis.
  setBasis(texels, groups) {
    const gl = this.gl;
    this.clearBasis();
    const perVertex = groups + 1, count = this.n * perVertex;
    const width = Math.min(gl.getParameter(gl.MAX_TEXTURE_SIZE), 4096), height = Math.ceil(count / width);
    const padded = new Float32Array(4 * width * height);
    padded.set(texels.subarray(0, 4 * count));
    this.basis = { texels, groups, width, texture: floatTexture(gl, width, height, padded) };
    this.basis.xf = floatTexture(gl, 3, Math.max(1, groups), null);
    const identity = [];
    for (let g = 0; g < groups; g++) identity.push([[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 1, 0]]);
    this.setTransforms(identity);
  }

  clearBasis() {
    if (!this.basis) return;
    this.gl.deleteTexture(this.basis.texture);
    this.gl.deleteTexture(this.basis.xf);
    this.basis = null;
  }

  // The groups' 3 × 4 transforms (row-major, in the basis's group order):
  // 48 bytes per group uploaded, nothing else per frame. Returns the bytes.
  setTransforms(matrices) {
    const gl = this.gl, b = this.basis;
    b.matrices = matrices;
    b.cpu = null;
    const data = new Float32Array(12 * b.groups);
    matrices.forEach((m, g) => m.forEach((row, i) => data.set(row, 12 * g + 4 * i)));
    gl.bindTexture(gl.TEXTURE_2D, b.xf);
    gl.texSubImage2D(gl.TEXTURE_2D, 0, 0, 0, 3, b.groups, gl.RGBA, gl.FLOAT, data);
    return data.byteLength;
  }

  // The positions of the basis at the current transforms, evaluated on the
  // CPU when picking needs them (not per frame).
  basisPositions() {
    const b = this.basis;
    if (b.cpu) return b.cpu;
    const n = this.n, k = b.groups + 1, t = b.texels, out = new Float32Array(3 * n);
    for (let v = 0; v < n; v++) {
      const base = 4 * k * v;
      for (let c = 0; c < 3; c++) {
        let x = t[base + c];
        for (let g = 0; g < b.groups; g++) {
          const r = base + 4 * (g + 1), m = b.matrices[g][c];
          x += m[0] * t[r] + m[1] * t[r + 1] + m[2] * t[r + 2] + m[3] * t[r + 3];
        }
        out[3 * v + c] = x;
      }
    }
    b.cpu = out;
    return out;
  }

  bindBasis(program) {
    const gl = this.gl, b = this.basis;
    gl.useProgram(program);
    gl.activeTexture(gl.TEXTURE0);
    gl.bindTexture(gl.TEXTURE_2D, b.texture);
    gl.activeTexture(gl.TEXTURE1);
    gl.bindTexture(gl.TEXTURE_2D, b.xf);
    gl.uniform1i(gl.getUniformLocation(program, 'basis'), 0);
    gl.uniform1i(gl.getUniformLocation(program, 'xf'), 1);
    gl.uniform1i(gl.getUniformLocation(program, 'groups'), b.groups);
    gl.uniform1i(gl.getUniformLocation(program, 'width'), b.width);
  }

  // The positions the vertex shader evaluates (f32, n × 3), read back by
  // transform feedback.
  readBack() {
    const gl = this.gl, n = this.n;
    this.bindBasis(this.readbackProgram);
    const buffer = gl.createBuffer();
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, buffer);
    gl.bufferData(gl.TRANSFORM_FEEDBACK_BUFFER, 12 * n, gl.STATIC_READ);
    const tf = gl.createTransformFeedback();
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, tf);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, buffer);
    gl.bindVertexArray(null);
    gl.enable(gl.RASTERIZER_DISCARD);
    gl.beginTransformFeedback(gl.POINTS);
    gl.drawArrays(gl.POINTS, 0, n);
    gl.endTransformFeedback();
    gl.disable(gl.RASTERIZER_DISCARD);
    gl.bindBufferBase(gl.TRANSFORM_FEEDBACK_BUFFER, 0, null);
    gl.bindTransformFeedback(gl.TRANSFORM_FEEDBACK, null);
    const out = new Float32Array(3 * n);
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, buffer);
    gl.getBufferSubData(gl.TRANSFORM_FEEDBACK_BUFFER, 0, out);
    gl.bindBuffer(gl.TRANSFORM_FEEDBACK_BUFFER, null);
    gl.deleteBuffer(buffer);
    gl.deleteTransformFeedback(tf);
    return out;
  }

  setPositions(positions) {
    const gl = this.gl;
    this.clearBasis();
    this.positions = positions;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.posBuf);
    gl.bufferData(gl.ARRAY_BUFFER, positions, gl.DYNAMIC_DRAW);
  }

  setColors(colors) {
    const gl = this.gl;
    gl.bindBuffer(gl.ARRAY_BUFFER, this.colBuf);
    gl.bufferData(gl.ARRAY_BUFFER, colors, gl.DYNAMIC_DRAW);
  }

  // Camera frame: eye position and the right/up/forward axes.
  frame() {
    const cy = Math.cos(this.yaw), sy = Math.sin(this.yaw), cp = Math.cos(this.pitch), sp = Math.sin(this.pitch);
    const f = [-cp * sy, -sp, -cp * cy]; // forward (towards the centre)
    const r = [cy, 0, -sy];
    const u = [r[1] * f[2] - r[2] * f[1], r[2] * f[0] - r[0] * f[2], r[0] * f[1] - r[1] * f[0]];
    const eye = [0, 1, 2].map((c) => this.center[c] - this.distance * f[c]);
    return { eye, r, u, f };
  }

  matrices() {
    const { eye, r, u, f } = this.frame();
    const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    // Column-major view matrix.
    const mv = [r[0], u[0], -f[0], 0, r[1], u[1], -f[1], 0, r[2], u[2], -f[2], 0, -dot(r, eye), -dot(u, eye), dot(f, eye), 1];
    const aspect = this.canvas.width / Math.max(1, this.canvas.height);
    // The near plane as far out as the model allows: a 24-bit depth buffer
    // resolves about z² / (near · 2²⁴) at depth z, so a near plane at
    // 1e-6 of the radius (as before) merged depths 0.4 radius apart and let
    // back faces through as speckles and stripes. Anything closer than
    // twice the bounding radius in front of the centre is clipped (a drag
    // that far towards the camera); when zoomed in, a twentieth of the
    // distance.
    const near = Math.max(0.05 * this.distance, this.distance - 2 * this.radius), far = this.distance + 4 * this.radius;
    const t = 1 / Math.tan(0.4);
    const proj = [t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
    return { mv, proj };
  }

  // Screen coordinates (CSS pixels) and view depth of vertex i.
  projector() {
    const { mv, proj } = this.matrices();
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight;
    const p = this.basis ? this.basisPositions() : this.positions;
    return (i) => {
      const x = p[3 * i], y = p[3 * i + 1], z = p[3 * i + 2];
      const vx = mv[0] * x + mv[4] * y + mv[8] * z + mv[12];
      const vy = mv[1] * x + mv[5] * y + mv[9] * z + mv[13];
      const vz = mv[2] * x + mv[6] * y + mv[10] * z + mv[14];
      const cx = proj[0] * vx, cy = proj[5] * vy, cw = -vz;
      return [(0.5 + 0.5 * cx / cw) * w, (0.5 - 0.5 * cy / cw) * h, cw];
    };
  }

  render() {
    const gl = this.gl, c = this.canvas;
    const dpr = window.devicePixelRatio || 1;
    const w = Math.round(c.clientWidth * dpr), h = Math.round(c.clientHeight * dpr);
    if (c.width !== w || c.height !== h) { c.width = w; c.height = h; }
    gl.viewport(0, 0, w, h);
    gl.clearColor(0.12, 0.12, 0.14, 1);
    gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
    if (!this.count) return;
    gl.enable(gl.DEPTH_TEST);
    const program = this.basis ? this.basisProgram : this.program;
    if (this.basis) this.bindBasis(program); else gl.useProgram(program);
    const { mv, proj } = this.matrices();
    gl.uniformMatrix4fv(gl.getUniformLocation(program, 'mv'), false, mv);
    gl.uniformMatrix4fv(gl.getUniformLocation(program, 'proj'), false, proj);
    gl.bindVertexArray(this.vao);
    gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_INT, 0);
  }
}
