// The softfem playground in a web browser: instantiates the wasm module (plain `extern "C"`
// exports of web/src/exports.rs, no imports), steps it once per animation frame and draws the
// bodies' boundary surfaces (positions and normals read straight from the module's memory) and
// the colliders with WebGL2. z is up, lengths in metres.
//
// Two scenes: the playground (separate bodies on the colliders, the default) and the pile (balls
// in one World, in contact with each other, in a box of walls); the Scene control switches.
//
// Query parameters: `wasm=URL` loads the module from elsewhere (default: the release build in
// the repository's target/ folder, for a server started at the repository root); `manual` runs
// no animation loop, for the browser test, which steps and draws with `playground.advance(n)`;
// `scene=pile` starts with the pile.

const params = new URLSearchParams(location.search);
const WASM_URL = params.get('wasm') ?? '../target/wasm32-unknown-unknown/release/softfem_web.wasm';
const MANUAL = params.has('manual');
const START_SCENE = params.get('scene') === 'pile' ? 1 : 0;

// The order of web/src/exports.rs's STATS.
const STATS = ['steps', 'time', 'tets', 'vertices', 'convergedShare', 'kinetic', 'gravity',
  'elastic', 'finite', 'grabbing', 'errorCode', 'grabX', 'grabY', 'grabZ', 'bodies',
  'contactPairs', 'scene'];
const COLLIDER_LEN = 11;
const BODY_COLOURS = [[0.93, 0.55, 0.25], [0.25, 0.7, 0.72], [0.62, 0.45, 0.85],
  [0.85, 0.35, 0.45], [0.45, 0.75, 0.35], [0.9, 0.8, 0.3]];
const PLAYGROUND = 0;
const PILE = 1;

const canvas = document.getElementById('view');
const readout = document.getElementById('readout');
const errorBox = document.getElementById('error');
const note = document.getElementById('note');
const controls = Object.fromEntries(['scene', 'model', 'young', 'poisson', 'stepper', 'frame',
  'pause', 'restart'].map((id) => [id, document.getElementById(id)]));

let wasm; // the module's exports
const pageErrors = [];
function report(message) {
  pageErrors.push(String(message));
  errorBox.textContent = pageErrors.at(-1);
}
window.addEventListener('error', (event) => report(event.message));
window.addEventListener('unhandledrejection', (event) => report(event.reason));

// ---- the module ----------------------------------------------------------------------------

function f32(ptr, len) { return new Float32Array(wasm.memory.buffer, ptr, len); }
function f64(ptr, len) { return new Float64Array(wasm.memory.buffer, ptr, len); }
function u32(ptr, len) { return new Uint32Array(wasm.memory.buffer, ptr, len); }

function lastError() {
  const bytes = new Uint8Array(wasm.memory.buffer, wasm.sf_error_ptr(), wasm.sf_error_len());
  return new TextDecoder().decode(bytes);
}

function check(status, what) {
  if (status !== 0) report(`${what}: ${lastError()} (status ${status})`);
  return status === 0;
}

function stats() {
  const values = f64(wasm.sf_stats(), STATS.length);
  return Object.fromEntries(STATS.map((name, k) => [name, values[k]]));
}

function settings() {
  const [model, stepper, young, poisson, frameTime] = f32(wasm.sf_settings(), 5);
  return { model, stepper, young, poisson, frameTime };
}

// ---- matrices (column-major, as WebGL reads them) --------------------------------------------

function multiply(a, b) {
  const out = new Float32Array(16);
  for (let c = 0; c < 4; c++) {
    for (let r = 0; r < 4; r++) {
      let sum = 0;
      for (let k = 0; k < 4; k++) sum += a[k * 4 + r] * b[c * 4 + k];
      out[c * 4 + r] = sum;
    }
  }
  return out;
}

function perspective(fovy, aspect, near, far) {
  const f = 1 / Math.tan(fovy / 2);
  const out = new Float32Array(16);
  out[0] = f / aspect; out[5] = f; out[10] = (far + near) / (near - far); out[11] = -1;
  out[14] = (2 * far * near) / (near - far);
  return out;
}

const sub = (a, b) => [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
const add = (a, b) => [a[0] + b[0], a[1] + b[1], a[2] + b[2]];
const scale = (a, s) => [a[0] * s, a[1] * s, a[2] * s];
const dot = (a, b) => a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
const cross = (a, b) => [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2],
  a[0] * b[1] - a[1] * b[0]];
const normalize = (a) => scale(a, 1 / Math.hypot(...a));

function lookAt(eye, target, up) {
  const z = normalize(sub(eye, target));
  const x = normalize(cross(up, z));
  const y = cross(z, x);
  return new Float32Array([x[0], y[0], z[0], 0, x[1], y[1], z[1], 0, x[2], y[2], z[2], 0,
    -dot(x, eye), -dot(y, eye), -dot(z, eye), 1]);
}

// The pose of a collider record: translation, unit quaternion (x, y, z, w), scale.
function pose(p, q, s = [1, 1, 1]) {
  const [x, y, z, w] = q;
  const m = [
    1 - 2 * (y * y + z * z), 2 * (x * y + z * w), 2 * (x * z - y * w),
    2 * (x * y - z * w), 1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
    2 * (x * z + y * w), 2 * (y * z - x * w), 1 - 2 * (x * x + y * y),
  ];
  return new Float32Array([m[0] * s[0], m[1] * s[0], m[2] * s[0], 0, m[3] * s[1], m[4] * s[1],
    m[5] * s[1], 0, m[6] * s[2], m[7] * s[2], m[8] * s[2], 0, p[0], p[1], p[2], 1]);
}

// ---- the camera ------------------------------------------------------------------------------

// Each scene's view (the playground's colliders 1.6 m across, the pile's box 28 cm) and the
// radius of the ball that marks where the pointer holds a body (m); the wheel zooms between
// `nearest` and 8 m.
const VIEWS = [
  { azimuth: -1.75, elevation: 0.38, distance: 2.8, target: [-0.3, 0, 0.35], marker: 0.015,
    nearest: 0.8 },
  { azimuth: -1.75, elevation: 0.85, distance: 0.62, target: [0, 0.02, 0.04], marker: 0.006,
    nearest: 0.3 },
];
const camera = { ...VIEWS[PLAYGROUND] };

function eye() {
  const c = Math.cos(camera.elevation);
  return add(camera.target, scale([c * Math.cos(camera.azimuth), c * Math.sin(camera.azimuth),
    Math.sin(camera.elevation)], camera.distance));
}

function viewProjection() {
  const aspect = canvas.width / Math.max(canvas.height, 1);
  return multiply(perspective(0.8, aspect, 0.05, 50), lookAt(eye(), camera.target, [0, 0, 1]));
}

// The ray through the client point (x, y): origin (the eye) and unit direction.
function ray(clientX, clientY) {
  const rect = canvas.getBoundingClientRect();
  const ndcX = ((clientX - rect.left) / rect.width) * 2 - 1;
  const ndcY = 1 - ((clientY - rect.top) / rect.height) * 2;
  const origin = eye();
  const forward = normalize(sub(camera.target, origin));
  const right = normalize(cross(forward, [0, 0, 1]));
  const up = cross(right, forward);
  const t = Math.tan(0.4);
  const aspect = rect.width / Math.max(rect.height, 1);
  const direction = normalize(add(forward, add(scale(right, ndcX * t * aspect),
    scale(up, ndcY * t))));
  return { origin, direction, forward };
}

// The client point a world point is drawn at.
function screenOf(point) {
  const m = viewProjection();
  const [x, y, z] = point;
  const clip = [0, 1, 2, 3].map((r) => m[r] * x + m[4 + r] * y + m[8 + r] * z + m[12 + r]);
  const rect = canvas.getBoundingClientRect();
  return [rect.left + ((clip[0] / clip[3] + 1) / 2) * rect.width,
    rect.top + ((1 - clip[1] / clip[3]) / 2) * rect.height];
}

// ---- WebGL2 ----------------------------------------------------------------------------------

const gl = canvas.getContext('webgl2', { antialias: true, preserveDrawingBuffer: true });
if (!gl) report('WebGL2 is not available');

const VERTEX = `#version 300 es
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
uniform mat4 viewProjection;
uniform mat4 model;
out vec3 worldNormal;
out vec3 world;
void main() {
  vec4 w = model * vec4(position, 1.0);
  world = w.xyz;
  worldNormal = mat3(model) * normal;
  gl_Position = viewProjection * w;
}`;

const FRAGMENT = `#version 300 es
precision highp float;
in vec3 worldNormal;
in vec3 world;
uniform vec3 colour;
uniform vec3 eye;
uniform int checker;
out vec4 outColour;
void main() {
  float len = length(worldNormal);
  vec3 n = len > 1e-6 ? worldNormal / len : vec3(0.0, 0.0, 1.0);
  if (!gl_FrontFacing) n = -n;
  vec3 light = normalize(vec3(0.5, -0.7, 1.0));
  vec3 v = normalize(eye - world);
  float diffuse = max(dot(n, light), 0.0);
  float sky = 0.5 + 0.5 * n.z;
  float specular = pow(max(dot(n, normalize(light + v)), 0.0), 48.0) * 0.25;
  vec3 c = colour;
  if (checker == 1) {
    float k = mod(floor(world.x * 4.0) + floor(world.y * 4.0), 2.0);
    c *= 0.8 + 0.2 * k;
    c *= exp(-0.08 * dot(world.xy, world.xy));
  }
  vec3 lit = c * (0.3 * sky + 0.75 * diffuse) + specular;
  outColour = vec4(pow(lit, vec3(1.0 / 2.2)), 1.0);
}`;

function compile(type, source) {
  const shader = gl.createShader(type);
  gl.shaderSource(shader, source);
  gl.compileShader(shader);
  if (!gl.getShaderParameter(shader, gl.COMPILE_STATUS)) report(gl.getShaderInfoLog(shader));
  return shader;
}

const program = gl.createProgram();
gl.attachShader(program, compile(gl.VERTEX_SHADER, VERTEX));
gl.attachShader(program, compile(gl.FRAGMENT_SHADER, FRAGMENT));
gl.linkProgram(program);
if (!gl.getProgramParameter(program, gl.LINK_STATUS)) report(gl.getProgramInfoLog(program));
const uniform = Object.fromEntries(['viewProjection', 'model', 'colour', 'eye', 'checker']
  .map((name) => [name, gl.getUniformLocation(program, name)]));

// A mesh of interleaved positions and normals (six floats a vertex) and u32 indices.
function mesh(vertices, indices, usage = gl.STATIC_DRAW) {
  const vao = gl.createVertexArray();
  gl.bindVertexArray(vao);
  const vbo = gl.createBuffer();
  gl.bindBuffer(gl.ARRAY_BUFFER, vbo);
  gl.bufferData(gl.ARRAY_BUFFER, vertices, usage);
  gl.enableVertexAttribArray(0);
  gl.vertexAttribPointer(0, 3, gl.FLOAT, false, 24, 0);
  gl.enableVertexAttribArray(1);
  gl.vertexAttribPointer(1, 3, gl.FLOAT, false, 24, 12);
  const ibo = gl.createBuffer();
  gl.bindBuffer(gl.ELEMENT_ARRAY_BUFFER, ibo);
  gl.bufferData(gl.ELEMENT_ARRAY_BUFFER, indices, gl.STATIC_DRAW);
  gl.bindVertexArray(null);
  return { vao, vbo, ibo, count: indices.length };
}

// The unit sphere; with `stretch`, its halves moved to z = +-stretch (a capsule of radius 1).
function sphereMesh(stretch = 0, rings = 16, segments = 24) {
  const vertices = [];
  const indices = [];
  for (let i = 0; i <= rings; i++) {
    const theta = (i / rings) * Math.PI;
    const shift = i <= rings / 2 ? stretch : -stretch;
    for (let j = 0; j <= segments; j++) {
      const phi = (j / segments) * 2 * Math.PI;
      const n = [Math.sin(theta) * Math.cos(phi), Math.sin(theta) * Math.sin(phi),
        Math.cos(theta)];
      vertices.push(n[0], n[1], n[2] + shift, ...n);
    }
    if (stretch > 0 && i === rings / 2) {
      // The cylinder: the equator once more, on the other half.
      for (let j = 0; j <= segments; j++) {
        const phi = (j / segments) * 2 * Math.PI;
        const n = [Math.cos(phi), Math.sin(phi), 0];
        vertices.push(n[0], n[1], -stretch, ...n);
      }
    }
  }
  const rows = vertices.length / 6 / (segments + 1);
  for (let i = 0; i < rows - 1; i++) {
    for (let j = 0; j < segments; j++) {
      const a = i * (segments + 1) + j;
      const b = a + segments + 1;
      indices.push(a, b, a + 1, a + 1, b, b + 1);
    }
  }
  return mesh(new Float32Array(vertices), new Uint32Array(indices));
}

// The cube [-1, 1]^3 with flat faces.
function cubeMesh() {
  const vertices = [];
  const indices = [];
  for (let axis = 0; axis < 3; axis++) {
    for (const sign of [-1, 1]) {
      const n = [0, 0, 0];
      n[axis] = sign;
      const u = [0, 0, 0];
      u[(axis + 1) % 3] = 1;
      const v = cross(n, u);
      const base = vertices.length / 6;
      for (const [a, b] of [[-1, -1], [1, -1], [1, 1], [-1, 1]]) {
        const p = add(n, add(scale(u, a), scale(v, b)));
        vertices.push(...p, ...n);
      }
      indices.push(base, base + 1, base + 2, base, base + 2, base + 3);
    }
  }
  return mesh(new Float32Array(vertices), new Uint32Array(indices));
}

const groundMesh = mesh(new Float32Array([-8, -8, 0, 0, 0, 1, 8, -8, 0, 0, 0, 1, 8, 8, 0, 0, 0,
  1, -8, 8, 0, 0, 0, 1]), new Uint32Array([0, 1, 2, 0, 2, 3]));
const unitSphere = sphereMesh();
const unitCube = cubeMesh();
const capsules = new Map(); // capsule meshes by their half length over radius
let bodies = null; // the bodies' mesh, rebuilt at each restart

function buildBodies() {
  const count = wasm.sf_render_len();
  const indices = u32(wasm.sf_index_ptr(), wasm.sf_index_len()).slice();
  const s = stats();
  const layout = u32(wasm.sf_layout_ptr(), 4 * s.bodies).slice();
  bodies = { ...mesh(f32(wasm.sf_render_ptr(), 6 * count), indices, gl.DYNAMIC_DRAW), layout,
    count };
}

function uploadBodies() {
  gl.bindBuffer(gl.ARRAY_BUFFER, bodies.vbo);
  gl.bufferSubData(gl.ARRAY_BUFFER, 0, f32(wasm.sf_render_ptr(), 6 * bodies.count));
}

const IDENTITY = pose([0, 0, 0], [0, 0, 0, 1]);

function drawMesh(m, model, colour, first = 0, count = m.count, checker = 0) {
  gl.bindVertexArray(m.vao);
  gl.uniformMatrix4fv(uniform.model, false, model);
  gl.uniform3fv(uniform.colour, colour);
  gl.uniform1i(uniform.checker, checker);
  gl.drawElements(gl.TRIANGLES, count, gl.UNSIGNED_INT, first * 4);
}

let dragTarget = null; // where the pointer holds a grabbed body (m), drawn as a small ball

function draw() {
  const width = Math.round(canvas.clientWidth * devicePixelRatio);
  const height = Math.round(canvas.clientHeight * devicePixelRatio);
  if (canvas.width !== width || canvas.height !== height) {
    canvas.width = width;
    canvas.height = height;
  }
  gl.viewport(0, 0, canvas.width, canvas.height);
  gl.clearColor(0.11, 0.13, 0.15, 1);
  gl.clear(gl.COLOR_BUFFER_BIT | gl.DEPTH_BUFFER_BIT);
  gl.enable(gl.DEPTH_TEST);
  gl.useProgram(program);
  gl.uniformMatrix4fv(uniform.viewProjection, false, viewProjection());
  gl.uniform3fv(uniform.eye, eye());
  const records = f32(wasm.sf_colliders(), COLLIDER_LEN * wasm.sf_collider_count()).slice();
  for (let k = 0; k < records.length; k += COLLIDER_LEN) {
    const [kind, x, y, z, qx, qy, qz, qw, a, b, c] = records.subarray(k, k + COLLIDER_LEN);
    const p = [x, y, z];
    const q = [qx, qy, qz, qw];
    const grey = [0.62, 0.64, 0.67];
    if (kind === 0) drawMesh(groundMesh, pose(p, q), [0.5, 0.53, 0.56], 0, 6, 1);
    else if (kind === 1) drawMesh(unitSphere, pose(p, q, [a, a, a]), grey);
    else if (kind === 2) {
      const key = (a / b).toFixed(4);
      if (!capsules.has(key)) capsules.set(key, sphereMesh(a / b));
      drawMesh(capsules.get(key), pose(p, q, [b, b, b]), grey);
    } else if (kind === 3) drawMesh(unitCube, pose(p, q, [a, b, c]), [0.75, 0.7, 0.55]);
  }
  if (bodies) {
    uploadBodies();
    for (let k = 0; k * 4 < bodies.layout.length; k++) {
      const [, , first, count] = bodies.layout.subarray(4 * k, 4 * k + 4);
      drawMesh(bodies, IDENTITY, BODY_COLOURS[k % BODY_COLOURS.length], first, count);
    }
  }
  if (dragTarget) {
    const r = camera.marker;
    drawMesh(unitSphere, pose(dragTarget, [0, 0, 0, 1], [r, r, r]), [1, 0.9, 0.3]);
  }
}

// ---- stepping and the readout ----------------------------------------------------------------

const recent = []; // milliseconds of the last steps
let failed = false;

function frame() {
  if (failed) return false;
  const started = performance.now();
  const status = wasm.sf_step();
  const elapsed = performance.now() - started;
  if (!check(status, 'step')) {
    failed = true;
    return false;
  }
  recent.push(elapsed);
  if (recent.length > 30) recent.shift();
  wasm.sf_update_render();
  return true;
}

function msPerStep() {
  return recent.length ? recent.reduce((a, b) => a + b, 0) / recent.length : NaN;
}

function updateReadout() {
  const s = stats();
  readout.textContent = [
    `ms per step   ${msPerStep().toFixed(1)}`,
    `tetrahedra    ${s.tets}`,
    `converged     ${(100 * s.convergedShare).toFixed(1)} %`,
    `contact pairs ${s.scene === PILE ? s.contactPairs : '- (bodies apart)'}`,
    `steps         ${s.steps}  (t = ${s.time.toFixed(2)} s)`,
    `wasm          ${api.simd()}`,
  ].join('\n');
}

function restart(defaults = 0) {
  failed = false;
  errorBox.textContent = '';
  recent.length = 0;
  dragTarget = null;
  if (check(wasm.sf_restart(defaults), 'restart')) buildBodies();
  showSettings();
}

// Switches to the scene numbered `kind` (PLAYGROUND or PILE) at t = 0 with the settings in
// force (the pile takes Newton for VBD), and to its view.
function switchScene(kind) {
  failed = false;
  errorBox.textContent = '';
  recent.length = 0;
  dragTarget = null;
  if (check(wasm.sf_scene(kind), 'scene')) buildBodies();
  Object.assign(camera, VIEWS[kind]);
  showSettings();
}

function showSettings() {
  const s = settings();
  const pile = stats().scene === PILE;
  controls.scene.value = String(pile ? PILE : PLAYGROUND);
  // The pile's World refuses Vertex Block Descent: its option is off there, with the note.
  controls.stepper.querySelector('option[value="3"]').disabled = pile;
  note.hidden = !pile;
  controls.model.value = String(s.model);
  controls.stepper.value = String(s.stepper);
  controls.young.value = String(Math.log10(s.young));
  controls.poisson.value = String(s.poisson);
  let nearest = controls.frame.options[0];
  for (const option of controls.frame.options) {
    if (Math.abs(option.value - s.frameTime) < Math.abs(nearest.value - s.frameTime)) {
      nearest = option;
    }
  }
  controls.frame.value = nearest.value;
  controls.young.title = `${s.young.toPrecision(3)} Pa`;
  controls.young.parentElement.firstChild.textContent = `E ${(s.young / 1e3).toFixed(0)} kPa `;
  controls.poisson.parentElement.firstChild.textContent = `Poisson ${s.poisson.toFixed(2)} `;
}

function configure() {
  const status = wasm.sf_configure(Number(controls.model.value), Number(controls.stepper.value),
    10 ** Number(controls.young.value), Number(controls.poisson.value),
    Number(controls.frame.value));
  if (check(status, 'settings')) {
    failed = false;
    errorBox.textContent = '';
    recent.length = 0;
  }
  dragTarget = null;
  showSettings();
}

// ---- the pointer -----------------------------------------------------------------------------

let pointer = null; // { mode: 'grab' | 'turn', ... }

canvas.addEventListener('pointerdown', (event) => {
  if (!wasm) return;
  canvas.setPointerCapture(event.pointerId);
  const { origin, direction, forward } = ray(event.clientX, event.clientY);
  if (event.button === 0 && wasm.sf_grab(...origin, ...direction) === 1) {
    const s = stats();
    const point = [s.grabX, s.grabY, s.grabZ];
    // The drag moves the point in the plane through it facing the camera.
    pointer = { mode: 'grab', point, normal: forward };
    dragTarget = point;
  } else {
    pointer = { mode: 'turn', x: event.clientX, y: event.clientY };
  }
});

canvas.addEventListener('pointermove', (event) => {
  if (!pointer) return;
  if (pointer.mode === 'grab') {
    const { origin, direction } = ray(event.clientX, event.clientY);
    const along = dot(pointer.normal, direction);
    if (Math.abs(along) < 1e-6) return;
    const t = dot(pointer.normal, sub(pointer.point, origin)) / along;
    if (t <= 0) return;
    const target = add(origin, scale(direction, t));
    target[2] = Math.max(target[2], 0.02); // not into the ground
    dragTarget = target;
    wasm.sf_drag(...target);
  } else {
    camera.azimuth -= (event.clientX - pointer.x) * 0.008;
    camera.elevation = Math.min(1.45, Math.max(0.05,
      camera.elevation + (event.clientY - pointer.y) * 0.008));
    pointer.x = event.clientX;
    pointer.y = event.clientY;
  }
});

function letGo() {
  if (pointer?.mode === 'grab') wasm.sf_release();
  pointer = null;
  dragTarget = null;
}
canvas.addEventListener('pointerup', letGo);
canvas.addEventListener('pointercancel', letGo);
canvas.addEventListener('wheel', (event) => {
  event.preventDefault();
  camera.distance = Math.min(8, Math.max(camera.nearest,
    camera.distance * Math.exp(event.deltaY * 0.001)));
}, { passive: false });

// ---- start -----------------------------------------------------------------------------------

function loop() {
  if (!controls.pause.checked) frame();
  draw();
  updateReadout();
  requestAnimationFrame(loop);
}

// What the browser test reads and drives (web/test/browser.mjs).
const api = {
  stats,
  // The SIMD width of softfem's batched kernels in this module: 'scalar' or 'simd128' (groups of
  // four, in a module built with SIMD128).
  simd: () => (wasm.sf_simd_width?.() > 0 ? 'simd128' : 'scalar'),
  settings,
  errors: pageErrors,
  screenOf,
  // Steps `n` frames as the animation loop does, then draws once; returns the statistics.
  advance(n) {
    for (let k = 0; k < n && frame(); k++);
    draw();
    updateReadout();
    return stats();
  },
  // Every position of the render buffer (all vertices of all bodies) is finite.
  positionsFinite() {
    const values = f32(wasm.sf_render_ptr(), 6 * wasm.sf_render_len());
    return values.length > 0 && values.every(Number.isFinite);
  },
  // The positions of the render buffer, for the test's choice of a point to grab.
  positions() {
    const values = f32(wasm.sf_render_ptr(), 6 * wasm.sf_render_len());
    const out = [];
    for (let k = 0; k < values.length; k += 6) out.push([values[k], values[k + 1], values[k + 2]]);
    return out;
  },
  // Mean and variance of the drawn picture's luminance (0 to 255).
  pixels() {
    draw();
    const { width, height } = canvas;
    const data = new Uint8Array(width * height * 4);
    gl.readPixels(0, 0, width, height, gl.RGBA, gl.UNSIGNED_BYTE, data);
    let sum = 0;
    let squares = 0;
    for (let k = 0; k < data.length; k += 4) {
      const y = 0.2126 * data[k] + 0.7152 * data[k + 1] + 0.0722 * data[k + 2];
      sum += y;
      squares += y * y;
    }
    const n = width * height;
    return { width, height, mean: sum / n, variance: squares / n - (sum / n) ** 2 };
  },
  // The positions' digest (16 hex digits, as web-timing prints it) after `steps` steps of the
  // scene numbered `scene` (default the playground) at the default settings with the stepper
  // numbered `stepper`. Leaves that scene restarted with the default settings.
  digest(steps, stepper, scene = PLAYGROUND) {
    if (!start(scene)) return null;
    const s = settings();
    if (!check(wasm.sf_configure(s.model, stepper, s.young, s.poisson, s.frameTime),
      'settings')) return null;
    for (let k = 0; k < steps; k++) if (!check(wasm.sf_step(), 'step')) return null;
    const digest = BigInt.asUintN(64, wasm.sf_digest()).toString(16).padStart(16, '0');
    restart(1);
    return digest;
  },
  // `steps` steps of the scene numbered `scene` (default the playground) from t = 0 with the
  // stepper numbered `stepper` (default the scene's default one), timed around each `sf_step`
  // call; returns the milliseconds per step. Leaves that scene restarted with the defaults.
  bench(steps, stepper, scene = PLAYGROUND) {
    if (!start(scene)) return NaN;
    const s = settings();
    if (!check(wasm.sf_configure(s.model, stepper ?? s.stepper, s.young, s.poisson,
      s.frameTime), 'settings')) return NaN;
    let total = 0;
    for (let k = 0; k < steps; k++) {
      const started = performance.now();
      const status = wasm.sf_step();
      total += performance.now() - started;
      if (!check(status, 'step')) return NaN;
    }
    restart(1);
    return total / steps;
  },
  restart,
  // Switches to the scene numbered `kind` (0 the playground, 1 the pile), as the control does.
  scene: switchScene,
};

// The scene numbered `kind` at t = 0 with the default settings (as the scene admits them).
function start(kind) {
  if (stats().scene !== kind) switchScene(kind);
  restart(1);
  return stats().scene === kind && stats().errorCode === 0;
}
window.playground = api;

api.ready = (async () => {
  const response = await fetch(WASM_URL);
  if (!response.ok) throw new Error(`cannot load ${WASM_URL}: ${response.status}`);
  const { instance } = await WebAssembly.instantiateStreaming(response, {});
  wasm = instance.exports;
  restart(1);
  if (START_SCENE !== PLAYGROUND) switchScene(START_SCENE);
  for (const id of ['model', 'young', 'poisson', 'stepper', 'frame']) {
    controls[id].addEventListener('change', configure);
  }
  controls.scene.addEventListener('change', () => switchScene(Number(controls.scene.value)));
  controls.restart.addEventListener('click', () => restart(0));
  // In manual mode nothing runs between the test's calls: `advance` steps and draws, and an
  // idle page rendering with SwiftShader would take a core from the native timing beside it.
  if (MANUAL) {
    draw();
    updateReadout();
  } else {
    requestAnimationFrame(loop);
  }
  return true;
})().catch((error) => {
  report(error);
  throw error;
});
