// The browser viewer of one live session (docs/browser.md): loads the session's rig once as a GLB
// (three.js GLTFLoader, its materials kept), then applies the newest frame's `d` (or weights) as
// morph-target influences and its head rotation, at the browser's frame rate. Orbit controls
// (drag, wheel, `r`), number keys that blend the rig's morph targets in and out, a heat map of
// |P - P0| with its legend (`h`), and a pause that holds the frame on screen (space).
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { OrbitControls } from 'three/addons/controls/OrbitControls.js';
import { parseFrame, STATUS } from '/static/wire.js';
import { Expressions } from '/static/expressions.js';
import { DEFAULT_SCALE_OF_DIAGONAL, drawLegend, heatUniforms, patchHeat } from '/static/heat.js';
import { actionFor, HELP } from '/static/keys.js';

const params = new URLSearchParams(location.search);
const token = params.get('token');
const q = token ? `?token=${encodeURIComponent(token)}` : '';
// `?pose=0`: keep the head still (as `mimic render` without --pose).
let usePose = params.get('pose') !== '0';
// `?heat_scale=X`: the heat map's full scale in rig units (as `--heat-scale`); default 5% of the
// rest mesh's bounding-box diagonal.
const heatScaleParam = Number(params.get('heat_scale'));
const session = decodeURIComponent(location.pathname.split('/').pop() ?? '');
document.title = `mimic: ${session}`;

const readout = document.getElementById('readout');
const weightsBox = document.getElementById('weights');
const message = document.getElementById('message');
const legend = document.getElementById('legend');
const help = document.getElementById('help');
help.textContent = HELP.join('\n');

/** The browser clock, ms since the Unix epoch (high resolution). */
const nowMs = () => performance.timeOrigin + performance.now();

// What the page shows and the test reads (window.mimicViewer).
const state = {
  session,
  connected: false,
  live: false,
  rig: null,
  mode: null,
  framesReceived: 0,
  framesShown: 0,
  pending: false,
  lastSeq: -1,
  missed: 0,
  status: '-',
  gated: 0,
  gatedNow: false,
  fps: 0,
  latencyMs: null,
  clockOffsetMs: null,
  clockErrorMs: null,
  errors: [],
  ended: null,
  // The keys' state: held frame, heat map, head pose, the number keys' eased weights.
  paused: false,
  heat: false,
  pose: usePose,
  heatScaleUnits: null,
  expressionNames: [],
  expressionTargets: [],
  expressionWeights: [],
  expressionsSettled: true,
  renders: 0,
};
window.mimicViewer = state;

// --- three.js scene -------------------------------------------------------------------------
const container = document.getElementById('view');
const renderer = new THREE.WebGLRenderer({ antialias: true });
renderer.setPixelRatio(window.devicePixelRatio);
renderer.setSize(container.clientWidth, container.clientHeight);
container.appendChild(renderer.domElement);
const scene = new THREE.Scene();
// mimic render's background (linear 0.02, 0.025, 0.035).
scene.background = new THREE.Color().setRGB(0.02, 0.025, 0.035, THREE.LinearSRGBColorSpace);
const camera = new THREE.PerspectiveCamera(30, container.clientWidth / container.clientHeight, 0.01, 100);
scene.add(camera);
// mimic render's light: a quarter ambient, the rest from the camera's upper left (camera axes).
scene.add(new THREE.AmbientLight(0xffffff, 0.25 * Math.PI));
const sun = new THREE.DirectionalLight(0xffffff, 0.75 * Math.PI);
sun.position.set(-0.4, 0.5, 1.0);
camera.add(sun);
camera.add(sun.target);

// Drag to orbit about the rest mesh's centre, wheel to zoom, right drag to pan; `r` resets to
// the framing below. No damping: the view stops where the mouse leaves it.
const controls = new OrbitControls(camera, renderer.domElement);
controls.enableDamping = false;
let framedRadius = 1;
controls.addEventListener('change', clip);

window.addEventListener('resize', () => {
  camera.aspect = container.clientWidth / container.clientHeight;
  camera.updateProjectionMatrix();
  renderer.setSize(container.clientWidth, container.clientHeight);
});

/**
 * mimic render's front view (`mimic_render::Camera::front`): 20 degrees to the subject's left,
 * 8 above, backed off until the box's corners fit a 30 degree view with a 4% margin.
 */
function frame(box) {
  const target = box.getCenter(new THREE.Vector3());
  const yaw = THREE.MathUtils.degToRad(20);
  const pitch = THREE.MathUtils.degToRad(8);
  const dir = new THREE.Vector3(Math.sin(yaw) * Math.cos(pitch), Math.sin(pitch), Math.cos(yaw) * Math.cos(pitch));
  const right = new THREE.Vector3(0, 1, 0).cross(dir).normalize();
  const up = dir.clone().cross(right);
  const tan = Math.tan(THREE.MathUtils.degToRad(15)) / 1.04 * Math.min(1, camera.aspect);
  let distance = 0;
  for (let k = 0; k < 8; k++) {
    const c = new THREE.Vector3(
      k & 1 ? box.max.x : box.min.x,
      k & 2 ? box.max.y : box.min.y,
      k & 4 ? box.max.z : box.min.z,
    ).sub(target);
    const lateral = Math.max(Math.abs(c.dot(right)), Math.abs(c.dot(up)));
    distance = Math.max(distance, c.dot(dir) + lateral / tan);
  }
  camera.position.copy(target).addScaledVector(dir, distance);
  camera.lookAt(target);
  framedRadius = box.getSize(new THREE.Vector3()).length() / 2;
  controls.target.copy(target);
  controls.minDistance = framedRadius * 0.3;
  controls.maxDistance = distance * 10;
  controls.update();
  controls.saveState();
  clip();
}

/** Near and far planes around the rest mesh's sphere from where the camera is now. */
function clip() {
  const distance = camera.position.distanceTo(controls.target);
  camera.near = Math.max(distance - framedRadius * 1.01, distance * 0.01);
  camera.far = distance + framedRadius * 1.01;
  camera.updateProjectionMatrix();
}

/**
 * The box of the rest mesh, every vertex (as `mimic render` frames the rig's whole mesh). Not
 * `Box3.setFromObject`: three.js grows a geometry's box by its morph targets' full deltas, and
 * a basis column's deltas are weights per metre of control motion, not positions.
 */
function restBox(root) {
  const box = new THREE.Box3();
  const p = new THREE.Vector3();
  root.traverse((o) => {
    const pos = o.isMesh ? o.geometry.attributes.position : null;
    if (!pos) return;
    for (let i = 0; i < pos.count; i++) box.expandByPoint(p.fromBufferAttribute(pos, i).applyMatrix4(o.matrixWorld));
  });
  return box;
}

let model = null; // { root, head, meshes, key }
let pending = null; // the newest frame not yet shown
let loading = null;

function fail(what) {
  state.errors.push(what);
  message.textContent = what;
  console.warn(what);
}

async function loadRig(info) {
  const key = `${info.rig}/${info.mode ?? 'landmarks'}`;
  if (model?.key === key) return;
  message.textContent = `loading rig ${info.rig}…`;
  const gltf = await new GLTFLoader().loadAsync(`${info.glb}${q}`);
  if (model) scene.remove(model.root);
  const root = gltf.scene;
  const meshes = [];
  root.traverse((o) => {
    if (!o.isMesh) return;
    // Parts the rig's look hides are written fully transparent: not drawn at all (each drawn
    // primitive holds its own copy of the morph targets on the GPU).
    const mats = Array.isArray(o.material) ? o.material : [o.material];
    if (mats.every((m) => m.transparent && m.opacity === 0)) {
      o.visible = false;
      return;
    }
    for (const m of mats) patchHeat(m);
    if (o.morphTargetInfluences) meshes.push(o);
  });
  const head = root.getObjectByName('head') ?? root;
  scene.add(root);
  root.updateMatrixWorld(true);
  const box = restBox(root);
  frame(box);
  // The heat map's full scale, in the GLB's metres.
  const s = info.metres_per_unit ?? 1;
  const diagonal = box.getSize(new THREE.Vector3()).length();
  const scaleMetres = heatScaleParam > 0 ? heatScaleParam * s : DEFAULT_SCALE_OF_DIAGONAL * diagonal;
  heatUniforms.mimicHeatScale.value = scaleMetres;
  state.heatScaleUnits = scaleMetres / s;
  drawLegend(legend, { scaleMetres, metresPerUnit: s, units: info.rig_units ?? 'rig units', defaulted: !(heatScaleParam > 0) });
  model = { root, head, meshes, key };
  message.textContent = '';
}

// --- the session's messages -----------------------------------------------------------------
let sessionInfo = null;

function onSession(info) {
  sessionInfo = info;
  state.live = true;
  state.ended = null;
  state.rig = info.rig;
  state.mode = info.mode ?? 'landmarks';
  state.lastSeq = -1;
  expressions = new Expressions(info.expressions?.names ?? []);
  expressionsFrom = info.expressions?.first_target ?? 0;
  state.expressionNames = expressions.names;
  buildBars(info.mode === 'weights' ? info.target_names ?? [] : []);
  loading = loadRig(info)
    .then(mapExpressions)
    .catch((e) => fail(`cannot load the rig: ${e.message}`));
}

let expressions = new Expressions([]);
let expressionsFrom = 0;

/** The GLB target each number key drives (its name in the mesh's morphTargetDictionary), for the
 * readout's state and the test; a key past the mesh's targets drives none. */
function mapExpressions() {
  const dict = model?.meshes[0]?.morphTargetDictionary ?? {};
  const byIndex = Object.fromEntries(Object.entries(dict).map(([name, j]) => [j, name]));
  state.expressionTargets = expressions.names.map((_, k) => byIndex[expressionsFrom + k] ?? null);
}

let bars = [];
function buildBars(names) {
  weightsBox.replaceChildren();
  bars = names.map((name) => {
    const row = document.createElement('div');
    row.className = 'bar';
    const label = document.createElement('span');
    label.textContent = name;
    const track = document.createElement('div');
    const fill = document.createElement('i');
    track.appendChild(fill);
    row.append(label, track);
    weightsBox.appendChild(row);
    return fill;
  });
}

function onFrame(buf) {
  let f;
  try {
    f = parseFrame(buf);
  } catch (e) {
    fail(e.message);
    return;
  }
  state.framesReceived++;
  if (state.lastSeq >= 0 && f.seq > state.lastSeq + 1) state.missed += f.seq - state.lastSeq - 1;
  state.gatedNow = state.lastSeq >= 0 && f.gated > state.gated;
  state.gated = f.gated;
  state.lastSeq = f.seq;
  pending = f; // only the newest frame is kept
  state.pending = true;
}

// Clock offset (server - browser), NTP-style from the clock replies: the sample with the
// smallest round trip of the last 16, error at most half that round trip.
const clockSamples = [];
function onClock(reply) {
  const t1 = nowMs();
  const rtt = t1 - reply.client_ms;
  const offset = reply.server_us / 1000 - (reply.client_ms + rtt / 2);
  clockSamples.push({ rtt, offset });
  if (clockSamples.length > 16) clockSamples.shift();
  const best = clockSamples.reduce((a, b) => (b.rtt < a.rtt ? b : a));
  state.clockOffsetMs = best.offset;
  state.clockErrorMs = best.rtt / 2;
}

let ws = null;
function connect() {
  const scheme = location.protocol === 'https:' ? 'wss' : 'ws';
  ws = new WebSocket(`${scheme}://${location.host}/ws/${encodeURIComponent(session)}${q}`);
  ws.binaryType = 'arraybuffer';
  ws.onopen = () => {
    state.connected = true;
    ping();
  };
  ws.onmessage = (ev) => {
    if (typeof ev.data !== 'string') {
      onFrame(ev.data);
      return;
    }
    const msg = JSON.parse(ev.data);
    switch (msg.type) {
      case 'hello':
        state.live = msg.live;
        if (!msg.live) message.textContent = `waiting for session ${session} to start…`;
        break;
      case 'session':
        onSession(msg);
        break;
      case 'end':
        state.live = false;
        state.ended = msg.reason;
        message.textContent = `session ended (${msg.reason}, ${msg.frames} frames); waiting for it to start again…`;
        break;
      case 'clock':
        onClock(msg);
        break;
      case 'error':
        fail(`server: ${msg.code}: ${msg.message}`);
        break;
      default:
        break;
    }
  };
  ws.onclose = () => {
    state.connected = false;
    if (!state.errors.length) message.textContent = 'the server closed the connection; reload to reconnect';
  };
}

function ping() {
  if (ws?.readyState === WebSocket.OPEN) ws.send(JSON.stringify({ type: 'clock', client_ms: nowMs() }));
}
setInterval(ping, 2000);

// --- per display frame ----------------------------------------------------------------------
const latencies = [];
let fpsCount = 0;
let fpsSince = performance.now();

/** Sets the morph-target influences from frame `f` (`d` in metres, or the weights), the number
 * keys' expressions added on top, and the head's rotation. */
function apply(f) {
  if (!model || !sessionInfo) return false;
  const weights = sessionInfo.mode === 'weights';
  const s = sessionInfo.metres_per_unit ?? 1;
  for (const mesh of model.meshes) {
    const inf = mesh.morphTargetInfluences;
    inf.fill(0);
    if (weights) {
      for (let j = 0; j < inf.length && j < f.k; j++) inf[j] = f.weights[j];
    } else {
      for (let i = 0; i < inf.length && i < f.d.length; i++) inf[i] = f.d[i] * s;
    }
    for (let k = 0; k < expressions.names.length && expressionsFrom + k < inf.length; k++) {
      inf[expressionsFrom + k] += expressions.eased(k);
    }
  }
  if (usePose) model.head.quaternion.set(f.rotation[0], f.rotation[1], f.rotation[2], f.rotation[3]);
  else model.head.quaternion.identity();
  for (let j = 0; j < bars.length && j < f.k; j++) bars[j].style.width = `${Math.max(0, Math.min(1, f.weights[j])) * 100}%`;
  state.status = STATUS[f.status] ?? String(f.status);
  return true;
}

let held = null; // the frame on screen (kept while paused, re-applied as expressions ease)
let lastTick = performance.now();

function tick() {
  requestAnimationFrame(tick);
  const t = performance.now();
  expressions.advance((t - lastTick) / 1000);
  lastTick = t;
  state.expressionWeights = expressions.names.map((_, k) => expressions.eased(k));
  state.expressionsSettled = expressions.settled();
  const f = state.paused ? null : pending;
  const shown = f && apply(f);
  if (shown) held = f;
  else if (held) apply(held);
  renderer.render(scene, camera);
  state.renders++;
  if (shown) {
    pending = null;
    state.pending = false;
    state.framesShown++;
    // Tracker arrival (server clock) to this render (browser clock, moved onto the server's).
    if (state.clockOffsetMs !== null) {
      const lat = nowMs() + state.clockOffsetMs - f.arrivalUs / 1000;
      latencies.push(lat);
      if (latencies.length > 60) latencies.shift();
      const sorted = [...latencies].sort((a, b) => a - b);
      state.latencyMs = sorted[Math.floor(sorted.length / 2)];
    }
  }
  fpsCount++;
  const now = performance.now();
  if (now - fpsSince >= 1000) {
    state.fps = (fpsCount * 1000) / (now - fpsSince);
    fpsCount = 0;
    fpsSince = now;
  }
  showReadout();
}

function showReadout() {
  const lat = state.latencyMs === null ? '-' : `${state.latencyMs.toFixed(1)} ms`;
  const err = state.clockErrorMs === null ? '' : ` (clock ±${state.clockErrorMs.toFixed(1)} ms)`;
  readout.textContent = [
    `session ${session}${state.rig ? ` · rig ${state.rig}` : ''}${state.live ? '' : ' · not live'}`,
    `fps ${state.fps.toFixed(0)} · latency ${lat}${err}`,
    `frames ${state.framesReceived} · shown ${state.framesShown} · missed ${state.missed}`,
    `status ${state.status}${state.gatedNow ? ' · GATED' : ''} · gated ${state.gated}`,
    `${state.paused ? 'PAUSED (space) · ' : ''}${expressions.label()}`,
  ].join('\n');
  readout.dataset.frames = String(state.framesReceived);
}

// --- keys ---------------------------------------------------------------------------------
function onKey(ev) {
  if (ev.ctrlKey || ev.metaKey || ev.altKey || ev.repeat) return;
  const a = actionFor(ev.key);
  if (!a) return;
  ev.preventDefault();
  switch (a.action) {
    case 'expression':
      expressions.toggle(a.index);
      break;
    case 'pause':
      state.paused = !state.paused;
      break;
    case 'heat':
      state.heat = !state.heat;
      heatUniforms.mimicHeatOn.value = state.heat ? 1 : 0;
      legend.hidden = !state.heat;
      break;
    case 'pose':
      usePose = !usePose;
      state.pose = usePose;
      break;
    case 'reset':
      controls.reset();
      clip();
      break;
    case 'help':
      help.hidden = !help.hidden;
      break;
    default:
      break;
  }
}
window.addEventListener('keydown', onKey);

connect();
requestAnimationFrame(tick);
