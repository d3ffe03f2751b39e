// Opens mimic serve's browser viewer in headless Chromium and reports, as one JSON object on
// stdout (and in OUT/browser-report.json), what it drew: the page's readout and state, the
// browser console's errors, and pixel counts of screenshots (run by tests/integration/browser.rs;
// the thresholds are judged there).
//
//   node check.mjs --url http://127.0.0.1:PORT/view/SESSION --out DIR [--frames N] [--size WxH]
//     two screenshots N frames apart (default 20): pixels that differ from the background in
//     each, pixels that differ between them
//   node check.mjs --url ... --out DIR --frames N --interact
//     the same, then with the stream paused (space, the frame held): key 1 in and out, h on and
//     off, a mouse drag and r; pixel statistics of each screenshot in `interact` (the heat map's
//     colours judged against the ramp of crates/mimic_render/src/shaders/ramp.wgsl)
//   node check.mjs --url ... --out DIR --at-end [--compare render.png]
//     waits for the session to end, takes one screenshot of its last frame and, with
//     --compare, the mean absolute difference (per channel, 0-255) from PNG (e.g. `mimic
//     render` of the same frame at the same size)
//
// Chromium: /usr/bin/chromium (or $MIMIC_CHROMIUM), WebGL2 on the CPU through SwiftShader.
import { chromium } from 'playwright-core';
import { readFileSync, writeFileSync } from 'node:fs';
import { dirname, join } from 'node:path';
import { fileURLToPath } from 'node:url';

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
const interactToo = process.argv.includes('--interact');
const compare = arg('compare');
if (!url) {
  console.error('usage: node check.mjs --url URL --out DIR [--frames N | --at-end [--compare PNG]]');
  process.exit(2);
}

const HIDE = '#readout, #weights, #message, #help { visibility: hidden; }';
const SHOW = '#readout, #weights, #message, #help { visibility: visible; }';

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

/**
 * The heat map's ramp as the native renderer defines it: the five stops of `ramp` in
 * crates/mimic_render/src/shaders/ramp.wgsl (the truth the page's colours are judged by).
 */
function wgslRampStops() {
  const here = dirname(fileURLToPath(import.meta.url));
  const wgsl = readFileSync(join(here, '../../crates/mimic_render/src/shaders/ramp.wgsl'), 'utf8');
  const body = wgsl.slice(wgsl.indexOf('fn ramp('));
  const stops = [...body.slice(0, body.indexOf('return')).matchAll(/vec3<f32>\(([-\d.]+),\s*([-\d.]+),\s*([-\d.]+)\)/g)]
    .map((m) => [Number(m[1]), Number(m[2]), Number(m[3])]);
  if (stops.length !== 5) throw new Error(`ramp.wgsl's ramp has ${stops.length} stops, 5 expected`);
  return stops;
}

/** Waits until `cond` holds in the page, then two display frames more (so it is drawn). */
async function settle(page, cond, arg) {
  await page.waitForFunction(cond, arg, { timeout });
  await page.evaluate(() => new Promise((r) => requestAnimationFrame(() => requestAnimationFrame(r))));
}

/**
 * Statistics of screenshots, computed in the page (the PNGs decoded by its 2D canvas):
 * `pairs` [[i, j]] pixels changed between shots i and j; per shot the pixels that differ from
 * the background outside `exclude` (the legend's box) and their bounding box; with `ramp` the
 * share of those whose chromaticity lies on the heat ramp, and a histogram of their place on it;
 * with `bar` the largest channel difference along the legend's bar from the ramp's sRGB bytes.
 */
function analyse(page, pngs, spec) {
  return page.evaluate(async ({ list, spec }) => {
    const imgs = [];
    for (const b64 of list) {
      const img = new Image();
      img.src = `data:image/png;base64,${b64}`;
      await img.decode();
      const c = document.createElement('canvas');
      c.width = img.width;
      c.height = img.height;
      const g = c.getContext('2d');
      g.drawImage(img, 0, 0);
      imgs.push({ w: img.width, h: img.height, px: g.getImageData(0, 0, c.width, c.height).data });
    }
    const diff = (a, i, b, j) => Math.max(Math.abs(a[i] - b[j]), Math.abs(a[i + 1] - b[j + 1]), Math.abs(a[i + 2] - b[j + 2]));
    const lin = (v) => { const c = v / 255; return c <= 0.04045 ? c / 12.92 : ((c + 0.055) / 1.055) ** 2.4; };
    const srgb = (c) => Math.round(Math.min(Math.max(c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055, 0), 1) * 255);
    const ramp = (t) => {
      const x = Math.min(Math.max(t, 0), 1) * 4;
      const k = Math.min(Math.floor(x), 3);
      const f = x - k;
      return [0, 1, 2].map((c) => spec.stops[k][c] + (spec.stops[k + 1][c] - spec.stops[k][c]) * f);
    };
    // The ramp's chromaticities (each colour over its largest channel) at 257 places.
    const chroma = [];
    for (let q = 0; q <= 256; q++) {
      const c = ramp(q / 256);
      const m = Math.max(...c);
      chroma.push(c.map((v) => v / m));
    }
    const bg = imgs[0].px.slice(0, 3);
    const ex = spec.exclude;
    const inEx = (x, y) => ex && x >= ex.x && x < ex.x + ex.w && y >= ex.y && y < ex.y + ex.h;
    const shots = imgs.map((im) => {
      let drawn = 0;
      let onRamp = 0;
      let dark = 0;
      const hist = [0, 0, 0, 0, 0];
      let x0 = im.w, y0 = im.h, x1 = -1, y1 = -1;
      for (let y = 0; y < im.h; y++) {
        for (let x = 0; x < im.w; x++) {
          const i = 4 * (y * im.w + x);
          if (inEx(x, y) || diff(im.px, i, bg, 0) <= 16) continue;
          drawn++;
          x0 = Math.min(x0, x); y0 = Math.min(y0, y); x1 = Math.max(x1, x); y1 = Math.max(y1, y);
          const c = [lin(im.px[i]), lin(im.px[i + 1]), lin(im.px[i + 2])];
          const m = Math.max(...c);
          // Too dark to tell a hue (below 2% of full light: shadowed creases, edges).
          if (m < 0.02) { dark++; continue; }
          let best = Infinity;
          let at = 0;
          for (let q = 0; q <= 256; q++) {
            const r = chroma[q];
            const d = Math.max(Math.abs(c[0] / m - r[0]), Math.abs(c[1] / m - r[1]), Math.abs(c[2] / m - r[2]));
            if (d < best) { best = d; at = q / 256; }
          }
          if (best <= spec.rampTolerance) {
            onRamp++;
            hist[Math.min(Math.floor(at * 5), 4)]++;
          }
        }
      }
      return { drawn, dark, on_ramp: onRamp, ramp_histogram: hist, bbox: [x0, y0, x1, y1] };
    });
    const pairs = spec.pairs.map(([i, j]) => {
      const a = imgs[i].px;
      const b = imgs[j].px;
      let changed = 0;
      let sum = 0;
      let max = 0;
      for (let p = 0; p < a.length; p += 4) {
        const d = diff(a, p, b, p);
        if (d > 16) changed++;
        max = Math.max(max, d);
        for (let c = 0; c < 3; c++) sum += Math.abs(a[p + c] - b[p + c]);
      }
      return { shots: [i, j], changed, max_diff: max, mean_abs_diff: sum / (3 * (a.length / 4)) };
    });
    let bar = null;
    if (spec.bar) {
      const { x, y, w, h, shot } = spec.bar;
      const im = imgs[shot];
      const row = Math.floor(y + h / 2);
      let worst = 0;
      let samples = 0;
      for (let k = 0; k < w; k++) {
        const want = ramp((k + 0.5) / w).map(srgb);
        const i = 4 * (row * im.w + x + k);
        worst = Math.max(worst, diff(im.px, i, want, 0));
        samples++;
      }
      const at = (k) => Array.from(im.px.slice(4 * (row * im.w + x + k), 4 * (row * im.w + x + k) + 3));
      bar = { samples, max_diff: worst, left: at(0), middle: at(Math.floor(w / 2)), right: at(w - 1) };
    }
    return { pixels: imgs[0].w * imgs[0].h, background: Array.from(bg), shots, pairs, bar };
  }, { list: pngs.map((p) => p.toString('base64')), spec });
}

/**
 * The keys and the mouse, with the stream paused (space: the page holds the frame on screen):
 * 0 held frame; 1 key `1` (the rig's first morph target) eased in; 2 `h` on; 3 `h` off; 4 key
 * `1` eased out; 5 after a left drag; 6 after `r`.
 */
async function interact(page, report) {
  const shots = [];
  const take = async (name) => {
    const png = await page.screenshot({ path: join(out, name) });
    shots.push(png);
    return png;
  };
  const started = Date.now();
  await page.addStyleTag({ content: HIDE });
  await page.keyboard.press(' ');
  await settle(page, () => window.mimicViewer.paused);
  const shownAtPause = await page.evaluate(() => window.mimicViewer.framesShown);
  await take('keys-0-held.png');
  await page.keyboard.press('1');
  await settle(page, () => window.mimicViewer.expressionsSettled && window.mimicViewer.expressionWeights[0] === 1);
  await take('keys-1-expression.png');
  await page.keyboard.press('h');
  await settle(page, () => window.mimicViewer.heat);
  await take('keys-2-heat.png');
  const rect = (sel) => page.evaluate((s) => {
    const r = document.querySelector(s).getBoundingClientRect();
    const d = window.devicePixelRatio;
    return { x: Math.round(r.x * d), y: Math.round(r.y * d), w: Math.round(r.width * d), h: Math.round(r.height * d) };
  }, sel);
  const legendBox = await rect('#legend');
  const legendBar = await rect('#legend-bar');
  const legendText = await page.evaluate(() => document.getElementById('legend').innerText);
  const legendData = await page.evaluate(() => ({ ...document.getElementById('legend').dataset }));
  await page.keyboard.press('h');
  await settle(page, () => !window.mimicViewer.heat);
  await take('keys-3-heat-off.png');
  await page.keyboard.press('1');
  await settle(page, () => window.mimicViewer.expressionsSettled && window.mimicViewer.expressionWeights[0] === 0);
  await take('keys-4-expression-out.png');
  const { width: w, height: h } = page.viewportSize();
  await page.mouse.move(w / 2, h / 2);
  await page.mouse.down();
  for (let k = 1; k <= 5; k++) await page.mouse.move(w / 2 + 20 * k, h / 2);
  await page.mouse.up();
  await settle(page, () => true);
  await take('keys-5-orbit.png');
  await page.keyboard.press('r');
  await settle(page, () => true);
  await take('keys-6-reset.png');
  const state = await page.evaluate(() => window.mimicViewer);
  await page.keyboard.press(' ');
  const stats = await analyse(page, shots, {
    stops: wgslRampStops(),
    // A pixel is "on the ramp" when its colour over its largest channel is within 0.1 of the
    // ramp's (the lighting scales all three channels alike; 8-bit rounding of a 2%-lit pixel
    // moves a ratio by at most about 0.5 / (255 * 0.15) = 0.013).
    rampTolerance: 0.1,
    exclude: legendBox,
    pairs: [[0, 1], [1, 3], [0, 4], [4, 5], [0, 6], [2, 3]],
    bar: { ...legendBar, shot: 2 },
  });
  report.interact = {
    ms: Date.now() - started,
    legend: { box: legendBox, bar: legendBar, text: legendText, ...legendData },
    expression_names: state.expressionNames,
    expression_targets: state.expressionTargets,
    // Frames drawn when paused and at the last shot (the same: the frame was held).
    frames_shown: [shownAtPause, state.framesShown],
    frames_received: state.framesReceived,
    heat_scale_units: state.heatScaleUnits,
    ...stats,
  };
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
  if (interactToo && !atEnd) await interact(page, report);
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
