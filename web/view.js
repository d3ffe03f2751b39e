// The browser viewer of one live session (docs/browser.md): loads the session's rig once as a GLB
// (three.js GLTFLoader, its materials kept), then applies the newest frame's `d` (or weights) as
// morph-target influences and its head rotation, at the browser's frame rate.
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { parseFrame, STATUS } from '/static/wire.js';

const params = new URLSearchParams(location.search);
const token = params.get('token');
const q = token ? `?token=${encodeURIComponent(token)}` : '';
// `?pose=0`: keep the head still (as `mimic render` without --pose).
const usePose = params.get('pose') !== '0';
const session = decodeURIComponent(location.pathname.split('/').pop() ?? '');
document.title = `mimic: ${session}`;

const readout = document.getElementById('readout');
const weightsBox = document.getElementById('weights');
const message = document.getElementById('message');

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
  const radius = box.getSize(new THREE.Vector3()).length() / 2;
  camera.near = Math.max(distance - radius * 1.01, distance * 0.01);
  camera.far = distance + radius * 1.01;
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
    if (o.morphTargetInfluences) meshes.push(o);
  });
  const head = root.getObjectByName('head') ?? root;
  scene.add(root);
  root.updateMatrixWorld(true);
  frame(restBox(root));
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
  buildBars(info.mode === 'weights' ? info.target_names ?? [] : []);
  loading = loadRig(info).catch((e) => fail(`cannot load the rig: ${e.message}`));
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

function apply(f) {
  if (!model || !sessionInfo) return false;
  const weights = sessionInfo.mode === 'weights';
  const s = sessionInfo.metres_per_unit ?? 1;
  for (const mesh of model.meshes) {
    const inf = mesh.morphTargetInfluences;
    if (weights) {
      for (let j = 0; j < inf.length && j < f.k; j++) inf[j] = f.weights[j];
    } else {
      for (let i = 0; i < inf.length && i < f.d.length; i++) inf[i] = f.d[i] * s;
    }
  }
  if (usePose) model.head.quaternion.set(f.rotation[0], f.rotation[1], f.rotation[2], f.rotation[3]);
  for (let j = 0; j < bars.length && j < f.k; j++) bars[j].style.width = `${Math.max(0, Math.min(1, f.weights[j])) * 100}%`;
  state.status = STATUS[f.status] ?? String(f.status);
  return true;
}

function tick() {
  requestAnimationFrame(tick);
  const f = pending;
  const shown = f && apply(f);
  renderer.render(scene, camera);
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
  ].join('\n');
  readout.dataset.frames = String(state.framesReceived);
}

connect();
requestAnimationFrame(tick);
