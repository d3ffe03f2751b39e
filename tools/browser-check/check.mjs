// Opens mimic serve's browser viewer in headless Chromium and reports, as one JSON object on
// stdout, what it drew: the page's readout and state, the browser console's errors, and pixel
// counts of two screenshots taken some frames apart (run by tests/integration/browser.rs; the
// thresholds are judged there).
//
//   node check.mjs --url http://127.0.0.1:PORT/view/SESSION --out DIR [--frames N] [--size WxH]
//
// Chromium: /usr/bin/chromium (or $MIMIC_CHROMIUM), WebGL2 on the CPU through SwiftShader.
import { chromium } from 'playwright-core';
import { writeFileSync } from 'node:fs';
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
if (!url) {
  console.error('usage: node check.mjs --url URL --out DIR');
  process.exit(2);
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
  // The rig is loaded and frames are being shown.
  await page.waitForFunction(() => window.mimicViewer?.framesShown >= 5, null, { timeout });
  // Overlays off for the pixel counts (the readout is read from the DOM instead).
  await page.addStyleTag({ content: '#readout, #weights, #message { visibility: hidden; }' });
  const shot = async (name) => {
    const seq = await page.evaluate(() => window.mimicViewer.lastSeq);
    const path = join(out, name);
    const png = await page.screenshot({ path });
    report.shots.push({ path, seq });
    return png;
  };
  const a = await shot('browser-1.png');
  const seq0 = report.shots[0].seq;
  await page.waitForFunction((s) => window.mimicViewer.lastSeq >= s, seq0 + apart, { timeout });
  const b = await shot('browser-2.png');
  await page.addStyleTag({ content: '#readout, #weights, #message { visibility: visible; }' });
  await page.screenshot({ path: join(out, 'browser-readout.png') });
  report.readout = await page.evaluate(() => document.getElementById('readout').textContent);
  report.state = await page.evaluate(() => window.mimicViewer);
  // Pixels: decoded by the browser itself (a 2D canvas), counted here.
  report.pixels = await page.evaluate(
    async ([a, b]) => {
      const load = async (b64) => {
        const img = new Image();
        img.src = `data:image/png;base64,${b64}`;
        await img.decode();
        const c = document.createElement('canvas');
        c.width = img.width;
        c.height = img.height;
        const g = c.getContext('2d');
        g.drawImage(img, 0, 0);
        return g.getImageData(0, 0, c.width, c.height).data;
      };
      const [pa, pb] = [await load(a), await load(b)];
      // The background is the top-left pixel (the face is framed in the middle).
      const bg = [pa[0], pa[1], pa[2]];
      const n = pa.length / 4;
      let drawnA = 0;
      let drawnB = 0;
      let changed = 0;
      let sumAbs = 0;
      for (let i = 0; i < n; i++) {
        let da = 0;
        let db = 0;
        let dab = 0;
        for (let c = 0; c < 3; c++) {
          da = Math.max(da, Math.abs(pa[4 * i + c] - bg[c]));
          db = Math.max(db, Math.abs(pb[4 * i + c] - bg[c]));
          const d = Math.abs(pa[4 * i + c] - pb[4 * i + c]);
          dab = Math.max(dab, d);
          sumAbs += d;
        }
        if (da > 16) drawnA++;
        if (db > 16) drawnB++;
        if (dab > 16) changed++;
      }
      return { pixels: n, background: bg, drawn: [drawnA, drawnB], changed, mean_abs_diff: sumAbs / (3 * n) };
    },
    [a.toString('base64'), b.toString('base64')],
  );
} catch (e) {
  report.failure = String(e);
} finally {
  await browser.close();
}
writeFileSync(join(out, 'browser-report.json'), JSON.stringify(report, null, 2));
console.log(JSON.stringify(report));
process.exit(report.failure ? 1 : 0);
