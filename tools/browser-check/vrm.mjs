// Loads VRM files in three.js with @pixiv/three-vrm (GLTFLoader + VRMLoaderPlugin) in headless
// Chromium and reports, as one JSON object on stdout, what three-vrm read from each and how its
// neutral frame looks (run by tests/integration/vrm.rs; the thresholds are judged there).
//
//   node vrm.mjs --out DIR [--size WxH] [--expression NAME] A.vrm [B.vrm ...]
//
// Each file: the VRM meta version and name, the expression names (presets and custom) and
// whether setting each to 1 moves any morph target, the humanoid bones, the largest morph target
// count of a mesh, and its neutral frame (no animation, every weight at rest) rendered to
// DIR/<k>.png: a fixed camera framing the first file's head (its bounding box, a 30 degree view,
// looking at the face along -Z), a fixed ambient and directional light, a grey background. With
// more than one file, `mean_abs_diff[k]` is the mean absolute difference per channel (0-255) of
// file k's frame from the first's; with --expression, `expression_diff` is the same measure of
// the first file's frame with that expression at 1 (what a visible change scores).
//
// The files are served to the page by page.route on http://mimic.test/ (no socket), three and
// three-vrm from node_modules. Chromium: /usr/bin/chromium (or $MIMIC_CHROMIUM), WebGL2 on the
// CPU through SwiftShader.
import { chromium } from 'playwright-core';
import { readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

const argv = process.argv.slice(2);
function arg(name, fallback) {
  const k = argv.indexOf(`--${name}`);
  if (k < 0) return fallback;
  const v = argv[k + 1];
  argv.splice(k, 2);
  return v;
}
const out = arg('out', '.');
const [width, height] = arg('size', '512x512').split('x').map(Number);
const timeout = Number(arg('timeout-ms', '120000'));
const expression = arg('expression');
const files = argv;
if (files.length === 0) {
  console.error('usage: node vrm.mjs --out DIR [--size WxH] A.vrm [B.vrm ...]');
  process.exit(2);
}

const here = dirname(fileURLToPath(import.meta.url));
const modules = join(here, 'node_modules');
const PAGE = `<!doctype html><html><head><style>html,body{margin:0;background:#808080}</style>
<script type="importmap">{"imports":{
  "three": "/node_modules/three/build/three.module.js",
  "three/addons/": "/node_modules/three/examples/jsm/",
  "@pixiv/three-vrm": "/node_modules/@pixiv/three-vrm/lib/three-vrm.module.js"}}</script>
</head><body><canvas id="c" width="${width}" height="${height}"></canvas>
<script type="module">
import * as THREE from 'three';
import { GLTFLoader } from 'three/addons/loaders/GLTFLoader.js';
import { VRMLoaderPlugin } from '@pixiv/three-vrm';

const canvas = document.getElementById('c');
const renderer = new THREE.WebGLRenderer({ canvas, antialias: false, preserveDrawingBuffer: true });
renderer.setPixelRatio(1);
renderer.setSize(${width}, ${height}, false);
renderer.setClearColor(0x808080, 1);

/** Loads the VRM at url, reports what three-vrm read, renders its neutral frame with camera
 * (made from this file's head when null) and returns the report, the camera and the pixels. */
async function one(url, camera, expression) {
  const loader = new GLTFLoader();
  loader.register((parser) => new VRMLoaderPlugin(parser));
  const gltf = await loader.loadAsync(url);
  const vrm = gltf.userData.vrm;
  if (!vrm) throw new Error(url + ': three-vrm found no VRM');
  vrm.update(0);
  const scene = new THREE.Scene();
  scene.add(vrm.scene);
  scene.add(new THREE.AmbientLight(0xffffff, 0.8));
  const sun = new THREE.DirectionalLight(0xffffff, 2.0);
  sun.position.set(0.5, 1.0, 2.0);
  scene.add(sun);
  vrm.scene.updateMatrixWorld(true);

  let morphTargets = 0;
  const meshes = [];
  vrm.scene.traverse((o) => {
    if (o.isMesh) {
      meshes.push(o);
      morphTargets = Math.max(morphTargets, o.morphTargetInfluences?.length ?? 0);
    }
  });
  const influence = () => meshes.reduce((s, m) => s + (m.morphTargetInfluences ?? []).reduce((a, b) => a + Math.abs(b), 0), 0);
  const em = vrm.expressionManager;
  const expressions = (em?.expressions ?? []).map((e) => e.expressionName);
  const drives = {};
  for (const name of expressions) {
    em.resetValues();
    em.update();
    const rest = influence();
    em.setValue(name, 1);
    em.update();
    drives[name] = influence() > rest + 1e-6;
  }
  em?.resetValues();
  if (expression) em?.setValue(expression, 1);
  em?.update();
  const bones = Object.entries(vrm.humanoid?.rawHumanBones ?? {})
    .filter(([, b]) => b?.node)
    .map(([name]) => name)
    .sort();

  if (!camera) {
    const head = vrm.humanoid?.getRawBoneNode('head');
    // The head's meshes: those under the head bone or skinned to it; else the whole scene.
    const box = new THREE.Box3();
    for (const m of meshes) {
      let under = false;
      for (let p = m; p; p = p.parent) if (p === head) under = true;
      if (under || m.skeleton?.bones.includes(head)) box.expandByObject(m);
    }
    if (box.isEmpty()) box.setFromObject(vrm.scene);
    const centre = box.getCenter(new THREE.Vector3());
    const size = box.getSize(new THREE.Vector3());
    const fov = 30;
    const fit = Math.max(size.x, size.y) / 2 / Math.tan((fov / 2) * Math.PI / 180) * 1.1;
    camera = new THREE.PerspectiveCamera(fov, ${width} / ${height}, fit / 100, fit * 10);
    camera.position.set(centre.x, centre.y, centre.z + size.z / 2 + fit);
    camera.lookAt(centre);
  }
  renderer.render(scene, camera);
  const gl = renderer.getContext();
  const px = new Uint8Array(${width} * ${height} * 4);
  gl.readPixels(0, 0, ${width}, ${height}, gl.RGBA, gl.UNSIGNED_BYTE, px);
  const png = canvas.toDataURL('image/png').split(',')[1];
  return {
    report: {
      meta_version: vrm.meta?.metaVersion ?? null,
      meta_name: vrm.meta?.name ?? vrm.meta?.title ?? null,
      expressions,
      drives,
      bones,
      morph_targets: morphTargets,
      meshes: meshes.length,
    },
    camera,
    px,
    png,
  };
}

window.runAll = async (count, expression) => {
  const reports = [];
  const diffs = [];
  let camera = null;
  let first = null;
  for (let k = 0; k < count; k++) {
    const r = await one('/file/' + k, camera);
    camera = r.camera;
    let sum = 0;
    let drawn = 0;
    for (let i = 0; i < r.px.length; i += 4) {
      if (Math.abs(r.px[i] - 128) + Math.abs(r.px[i + 1] - 128) + Math.abs(r.px[i + 2] - 128) > 24) drawn++;
      if (first) for (let c = 0; c < 3; c++) sum += Math.abs(r.px[i + c] - first[i + c]);
    }
    if (!first) first = r.px;
    diffs.push(sum / (3 * r.px.length / 4));
    reports.push({ ...r.report, drawn_share: drawn / (r.px.length / 4), png: r.png });
  }
  // The first file again with the expression at 1: how far a change moves the measure.
  let expressionDiff = null;
  if (expression) {
    const r = await one('/file/0', camera, expression);
    let sum = 0;
    for (let i = 0; i < r.px.length; i += 4) for (let c = 0; c < 3; c++) sum += Math.abs(r.px[i + c] - first[i + c]);
    expressionDiff = sum / (3 * r.px.length / 4);
  }
  return { reports, diffs, expressionDiff, webgl: renderer.getContext().getParameter(renderer.getContext().VERSION) };
};
window.ready = true;
</script></body></html>`;

const browser = await chromium.launch({
  executablePath: process.env.MIMIC_CHROMIUM ?? '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const consoleErrors = [];
const pageErrors = [];
let result;
try {
  const page = await browser.newPage({ viewport: { width, height } });
  page.on('console', (m) => {
    if (m.type() === 'error') consoleErrors.push(m.text());
  });
  page.on('pageerror', (e) => pageErrors.push(String(e)));
  await page.route('http://mimic.test/**', async (route) => {
    const path = decodeURIComponent(new URL(route.request().url()).pathname);
    const type = (p) => (p.endsWith('.js') ? 'text/javascript' : 'application/octet-stream');
    try {
      if (path === '/' || path === '/index.html') {
        return route.fulfill({ status: 200, contentType: 'text/html', body: PAGE });
      }
      const file = path.match(/^\/file\/(\d+)$/);
      if (file && files[Number(file[1])]) {
        return route.fulfill({ status: 200, contentType: 'model/gltf-binary', body: readFileSync(files[Number(file[1])]) });
      }
      if (path.startsWith('/node_modules/') && !path.includes('..')) {
        return route.fulfill({ status: 200, contentType: type(path), body: readFileSync(join(modules, path.slice('/node_modules/'.length))) });
      }
    } catch (e) {
      return route.fulfill({ status: 404, body: String(e) });
    }
    return route.fulfill({ status: 404, body: 'not found' });
  });
  await page.goto('http://mimic.test/index.html');
  await page.waitForFunction(() => window.ready === true, null, { timeout });
  result = await page.evaluate(([n, e]) => window.runAll(n, e), [files.length, expression ?? null]);
} finally {
  await browser.close();
}
const reports = result.reports.map((r, k) => {
  const png = join(out, `${k}.png`);
  writeFileSync(png, Buffer.from(r.png, 'base64'));
  const { png: _, ...rest } = r;
  return { file: files[k], png, ...rest };
});
const report = {
  webgl: result.webgl,
  files: reports,
  mean_abs_diff: result.diffs,
  expression_diff: result.expressionDiff,
  console_errors: consoleErrors,
  page_errors: pageErrors,
};
writeFileSync(join(out, 'vrm-report.json'), JSON.stringify(report, null, 2));
console.log(JSON.stringify(report));
