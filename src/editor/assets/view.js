// WebGL2 view: the mesh flat-shaded (normals from screen-space derivatives,
// so moved positions need no normal update), per-vertex colours, an orbit
// camera, and the projection used for picking.

const VS = `#version 300 es
in vec3 pos; in vec3 col;
uniform mat4 mv; uniform mat4 proj;
out vec3 vpos; out vec3 vcol;
void main() { vec4 p = mv * vec4(pos, 1.0); vpos = p.xyz; vcol = col; gl_Position = proj * p; }`;
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

export class View {
  constructor(canvas) {
    this.canvas = canvas;
    const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
    if (!gl) throw new Error('WebGL2 is not available in this browser');
    this.gl = gl;
    const p = gl.createProgram();
    gl.attachShader(p, compile(gl, gl.VERTEX_SHADER, VS));
    gl.attachShader(p, compile(gl, gl.FRAGMENT_SHADER, FS));
    gl.linkProgram(p);
    if (!gl.getProgramParameter(p, gl.LINK_STATUS)) throw new Error(gl.getProgramInfoLog(p));
    this.program = p;
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
    const lp = gl.getAttribLocation(this.program, 'pos');
    gl.enableVertexAttribArray(lp);
    gl.vertexAttribPointer(lp, 3, gl.FLOAT, false, 0, 0);
    this.setColors(new Float32Array(this.n * 3).fill(0.8));
    gl.bindBuffer(gl.ARRAY_BUFFER, this.colBuf);
    const lc = gl.getAttribLocation(this.program, 'col');
    gl.enableVertexAttribArray(lc);
    gl.vertexAttribPointer(lc, 3, gl.FLOAT, false, 0, 0);
    this.center = [0, 1, 2].map((c) => 0.5 * (bbox.min[c] + bbox.max[c]));
    this.radius = 0.5 * Math.hypot(...[0, 1, 2].map((c) => bbox.max[c] - bbox.min[c]));
    this.distance = 2.6 * this.radius;
  }

  setPositions(positions) {
    const gl = this.gl;
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
    const near = Math.max(1e-6 * this.radius, this.distance - 4 * this.radius), far = this.distance + 4 * this.radius;
    const t = 1 / Math.tan(0.4);
    const proj = [t / aspect, 0, 0, 0, 0, t, 0, 0, 0, 0, (far + near) / (near - far), -1, 0, 0, (2 * far * near) / (near - far), 0];
    return { mv, proj };
  }

  // Screen coordinates (CSS pixels) and view depth of vertex i.
  projector() {
    const { mv, proj } = this.matrices();
    const w = this.canvas.clientWidth, h = this.canvas.clientHeight, p = this.positions;
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
    gl.useProgram(this.program);
    const { mv, proj } = this.matrices();
    gl.uniformMatrix4fv(gl.getUniformLocation(this.program, 'mv'), false, mv);
    gl.uniformMatrix4fv(gl.getUniformLocation(this.program, 'proj'), false, proj);
    gl.bindVertexArray(this.vao);
    gl.drawElements(gl.TRIANGLES, this.count, gl.UNSIGNED_INT, 0);
  }
}
