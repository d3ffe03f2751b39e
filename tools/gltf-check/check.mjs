// Checks a GLB written by mimic (tests/integration/gltf.rs runs this; docs/gltf.md):
//   node check.mjs FILE.glb [EXPECT.json]
// 1. The Khronos glTF validator: 0 errors and 0 warnings.
// 2. With EXPECT.json (written by the Rust test from mimic's own deformed meshes): three.js's
//    GLTFLoader parses the file; its one animation lasts `duration_s`; at the time of each listed
//    frame the morphed position of each sample vertex (base + sum of the influences that three's
//    AnimationMixer samples, times the target deltas) is within `tolerance_m` of mimic's.
import { readFileSync } from 'node:fs';
import validator from 'gltf-validator';
import * as THREE from 'three';
import { GLTFLoader } from 'three/examples/jsm/loaders/GLTFLoader.js';

const [file, expectFile] = process.argv.slice(2);
if (!file) {
  console.error('usage: node check.mjs FILE.glb [EXPECT.json]');
  process.exit(2);
}
const bytes = readFileSync(file);
let failed = false;

const report = await validator.validateBytes(new Uint8Array(bytes), { maxIssues: 100 });
const { numErrors, numWarnings, numInfos, numHints } = report.issues;
console.log(`${file}: validator ${report.validatorVersion}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos, ${numHints} hints`);
for (const m of report.issues.messages) {
  if (m.severity <= 1) console.log(`  [${m.severity === 0 ? 'error' : 'warning'}] ${m.code} ${m.pointer ?? ''}: ${m.message}`);
}
if (numErrors > 0 || numWarnings > 0) failed = true;

if (expectFile) {
  const expect = JSON.parse(readFileSync(expectFile, 'utf8'));
  const ab = bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.byteLength);
  const gltf = await new Promise((resolve, reject) => new GLTFLoader().parse(ab, '', resolve, reject));
  let mesh = null;
  gltf.scene.traverse((o) => {
    if (!mesh && o.isMesh && o.geometry.morphAttributes.position) mesh = o;
  });
  if (!mesh) throw new Error('no mesh with morph targets');
  if (gltf.animations.length !== 1) {
    console.log(`  FAIL: ${gltf.animations.length} animations, want 1`);
    failed = true;
  }
  const clip = gltf.animations[0];
  const durTol = 1e-5 * Math.max(1, expect.duration_s);
  console.log(`  animation "${clip.name}": ${clip.duration.toFixed(6)} s (recording ${expect.duration_s.toFixed(6)} s), ${clip.tracks.length} tracks`);
  if (Math.abs(clip.duration - expect.duration_s) > durTol) {
    console.log(`  FAIL: duration differs by more than ${durTol}`);
    failed = true;
  }
  // GLTFLoader copies mesh.extras to the mesh's userData and names the influences by them.
  const names = mesh.userData.targetNames;
  const dict = mesh.morphTargetDictionary;
  if (!names || names.length !== mesh.morphTargetInfluences.length || names.some((n, i) => dict[n] !== i)) {
    console.log(`  FAIL: mesh.extras.targetNames missing, of the wrong length, or not the influences' names`);
    failed = true;
  } else {
    console.log(`  ${names.length} targets: ${names.slice(0, 3).join(', ')}, ...`);
  }
  const mixer = new THREE.AnimationMixer(gltf.scene);
  const action = mixer.clipAction(clip);
  action.setLoop(THREE.LoopOnce, 1);
  action.clampWhenFinished = true;
  action.play();
  const base = mesh.geometry.attributes.position;
  const morphs = mesh.geometry.morphAttributes.position;
  if (!mesh.geometry.morphTargetsRelative) throw new Error('glTF targets are relative');
  let worst = 0;
  let checked = 0;
  for (const f of expect.frames) {
    mixer.setTime(f.t);
    const w = mesh.morphTargetInfluences;
    f.vertices.forEach((v, k) => {
      for (let a = 0; a < 3; a++) {
        let p = base.getComponent(v, a);
        for (let t = 0; t < morphs.length; t++) {
          if (w[t] !== 0) p += w[t] * morphs[t].getComponent(v, a);
        }
        worst = Math.max(worst, Math.abs(p - f.positions[k][a]));
      }
      checked++;
    });
  }
  console.log(`  ${checked} vertex positions over ${expect.frames.length} frames: worst difference ${worst.toExponential(3)} m, tolerance ${expect.tolerance_m.toExponential(3)} m`);
  if (!(worst <= expect.tolerance_m)) {
    console.log('  FAIL: morphed positions differ from mimic\'s');
    failed = true;
  }
}
process.exit(failed ? 1 : 0);
