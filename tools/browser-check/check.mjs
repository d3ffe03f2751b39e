// Opens mimic serve's browser viewer in headless Chromium and reports, as one JSON object on
// stdout (and in OUT/browser-report.json), what it drew: the page's readout and state, the
// browser console's errors, and pixel counts of screenshots (run by tests/integration/browser.rs;
// the thresholds are judged there).
//
//   node check.mjs --url http://127.0.0.1:PORT/view/SESSION --out DIR [--frames N] [--size WxH]
//     two screenshots N frames apart (default 20): pixels that differ from the background in
//     each, pixels that differ between them
//   node check.mjs --url ... --out DIR --at-end [--compare render.png]
//     waits for the session to end, takes one screenshot of its last frame and, with
//     --compare, the mean absolute difference (per channel, 0-255) from PNG (e.g. `mimic
//     render` of the same frame at the same size)
//
// Chromium: /usr/bin/chromium (or $MIMIC_CHROMIUM), WebGL2 on the CPU through SwiftShader.
import { chromium } from 'playwright-core';
import { readFileSync, writeFileSync } from 'node:fs';
import { join } from 'node:path';

function arg(name, fallback) {
  const k = process.argv.indexOf(`--${name}`);
  return k > 0 ? process.argv[k + 1] : fallback;
}
const url = arg('url');
const out = arg('out', '.');
const apart = Number(arg('frames', '20'));
const [width, height] = arg('size', '480x480').split('x').map(Number);
const timeout = Number(arg('timeout-ms', '120000'));
const atEnd = process.argv.includes('--at-end');
const compare = arg('compare');
if (!url) {
  console.error('usage: node check.mjs --url URL --out DIR [--frames N | --at-end [--compare PNG]]');
  process.exit(2);
}

const HIDE = '#readout, #weights, #message { visibility: hidden; }';
const SHOW = '#readout, #weights, #message { visibility: visible; }';

/** Decodes PNGs (base64) in the page with a 2D canvas: [{ w, h, px }]. */
function decode(page, pngs) {
  return page.evaluate(async (list) => {
    const out = [];
    for (const b64 of list) {
      const img = new Image();
      img.src = `data:image/png;base64,${b64}`;
      await img.decode();
      const c = document.createElement('canvas');
      c.width = img.width;
      c.height = img.height;
      const g = c.getContext('2d');
      g.drawImage(img, 0, 0);
      out.push({ w: img.width, h: img.height, px: Array.from(g.getImageData(0, 0, c.width, c.height).data) });
    }
    return out;
  }, pngs.map((p) => p.toString('base64')));
}

/** Largest channel difference of pixel i between two RGBA arrays (or from an RGB colour). */
const diff = (a, i, b, j) => Math.max(Math.abs(a[i] - b[j]), Math.abs(a[i + 1] - b[j + 1]), Math.abs(a[i + 2] - b[j + 2]));

/** Pixels of each shot that differ from the background (the top-left pixel) by more than 16
 * levels, and pixels that differ between the two by more than 16. */
function counts(a, b) {
  const bg = a.px.slice(0, 3);
  const n = a.w * a.h;
  let drawnA = 0;
  let drawnB = 0;
  let changed = 0;
  let sum = 0;
  for (let i = 0; i < 4 * n; i += 4) {
    if (diff(a.px, i, bg, 0) > 16) drawnA++;
    if (diff(b.px, i, bg, 0) > 16) drawnB++;
    if (diff(a.px, i, b.px, i) > 16) changed++;
    for (let c = 0; c < 3; c++) sum += Math.abs(a.px[i + c] - b.px[i + c]);
  }
  return { pixels: n, background: bg, drawn: [drawnA, drawnB], changed, mean_abs_diff: sum / (3 * n) };
}

/** Mean absolute difference per channel over all pixels and over the pixels where either
 * image is not background (the reference's top-left pixel). */
function meanAbsDiff(a, ref) {
  if (a.w !== ref.w || a.h !== ref.h) return { error: `sizes ${a.w}x${a.h} and ${ref.w}x${ref.h}` };
  const bg = ref.px.slice(0, 3);
  let sum = 0;
  let face = 0;
  let faceSum = 0;
  for (let i = 0; i < a.px.length; i += 4) {
    let d = 0;
    for (let c = 0; c < 3; c++) d += Math.abs(a.px[i + c] - ref.px[i + c]);
    sum += d;
    if (diff(a.px, i, bg, 0) > 16 || diff(ref.px, i, bg, 0) > 16) {
      face++;
      faceSum += d;
    }
  }
  const n = a.px.length / 4;
  return { pixels: n, mean_abs_diff: sum / (3 * n), face_pixels: face, face_mean_abs_diff: faceSum / (3 * Math.max(face, 1)) };
}

async function shot(page, report, name) {
  const seq = await page.evaluate(() => window.mimicViewer.lastSeq);
  const path = join(out, name);
  const png = await page.screenshot({ path });
  report.shots.push({ path, seq });
  return png;
}

/** Two screenshots `apart` frames apart, then one with the readout. */
async function moving(page, report) {
  await page.waitForFunction(() => window.mimicViewer?.framesShown >= 5, null, { timeout });
  await page.addStyleTag({ content: HIDE });
  const a = await shot(page, report, 'browser-1.png');
  await page.waitForFunction((s) => window.mimicViewer.lastSeq >= s, report.shots[0].seq + apart, { timeout });
  const b = await shot(page, report, 'browser-2.png');
  await page.addStyleTag({ content: SHOW });
  await page.screenshot({ path: join(out, 'browser-readout.png') });
  const [da, db] = await decode(page, [a, b]);
  report.pixels = counts(da, db);
}

/** The session's last frame, once it has ended, optionally against a reference picture. */
async function lastFrame(page, report) {
  await page.waitForFunction(() => window.mimicViewer?.ended && window.mimicViewer.framesShown > 0 && !window.mimicViewer.pending, null, { timeout });
  await page.addStyleTag({ content: HIDE });
  // Two display frames more, so the last frame is the one on screen.
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
  const png = await shot(page, report, 'browser-end.png');
  if (compare) {
    const [a, ref] = await decode(page, [png, readFileSync(compare)]);
    report.compare = meanAbsDiff(a, ref);
  }
}

const browser = await chromium.launch({
  executablePath: process.env.MIMIC_CHROMIUM ?? '/usr/bin/chromium',
  args: ['--no-sandbox', '--use-angle=swiftshader', '--enable-unsafe-swiftshader', '--ignore-gpu-blocklist'],
});
const report = { url, console_errors: [], page_errors: [], shots: [] };
try {
  const page = await browser.newPage({ viewport: { width, height } });
  page.on('console', (m) => {
    if (m.type() === 'error') report.console_errors.push(m.text());
  });
  page.on('pageerror', (e) => report.page_errors.push(String(e)));
  await page.goto(url);
  report.webgl = await page.evaluate(() => {
    const gl = document.createElement('canvas').getContext('webgl2');
    if (!gl) return null;
    const info = gl.getExtension('WEBGL_debug_renderer_info');
    return info ? gl.getParameter(info.UNMASKED_RENDERER_WEBGL) : gl.getParameter(gl.RENDERER);
  });
  await (atEnd ? lastFrame(page, report) : moving(page, report));
  report.readout = await page.evaluate(() => document.getElementById('readout').textContent);
  report.state = await page.evaluate(() => window.mimicViewer);
} catch (e) {
  report.failure = String(e);
} finally {
  await browser.close();
}
writeFileSync(join(out, 'browser-report.json'), JSON.stringify(report, null, 2));
console.log(JSON.stringify(report));
process.exit(report.failure ? 1 : 0);
