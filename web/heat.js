// The displacement heat map (`h`, docs/browser.md): each vertex coloured by |P - P0|, the length
// of its morphed position minus its rest position, computed in the vertex shader (patched into
// the GLB's materials with onBeforeCompile) and lit as the skin is; the same ramp and default
// full scale as `mimic view` and `mimic render --heat displacement`
// (crates/mimic_render/src/shaders/ramp.wgsl's `ramp`, shared by render.wgsl), with a colour legend on screen.

/** The ramp's stops, linear RGB, at 0, 1/4, 1/2, 3/4 and 1 (ramp.wgsl's `ramp`). */
export const RAMP_STOPS = [
  [0.05, 0.1, 0.6],
  [0.0, 0.65, 0.9],
  [0.15, 0.8, 0.25],
  [0.98, 0.85, 0.1],
  [0.85, 0.08, 0.05],
];

/** Full scale of the heat map as a share of the rest mesh's bounding-box diagonal (as
 * `mimic view` and `mimic render` without `--heat-scale`). */
export const DEFAULT_SCALE_OF_DIAGONAL = 0.05;

/** The ramp at t (clamped to [0, 1]), linear RGB: piecewise linear between the stops. */
export function ramp(t) {
  const x = Math.min(Math.max(t, 0), 1) * 4;
  const k = Math.min(Math.floor(x), 3);
  const f = x - k;
  const a = RAMP_STOPS[k];
  const b = RAMP_STOPS[k + 1];
  return [0, 1, 2].map((c) => a[c] + (b[c] - a[c]) * f);
}

/** A linear channel in [0, 1] as an sRGB byte. */
export function srgbByte(c) {
  const v = c <= 0.0031308 ? 12.92 * c : 1.055 * c ** (1 / 2.4) - 0.055;
  return Math.round(Math.min(Math.max(v, 0), 1) * 255);
}

const vec3 = (c) => `vec3(${c.map((v) => v.toFixed(4)).join(', ')})`;

const GLSL_RAMP = `
varying float vMimicHeat;
uniform float mimicHeatOn;
vec3 mimicRamp(float t) {
  float x = clamp(t, 0.0, 1.0) * 4.0;
  float k = min(floor(x), 3.0);
  float f = x - k;
  vec3 s[5] = vec3[5](${RAMP_STOPS.map(vec3).join(', ')});
  int ki = int(k);
  return mix(s[ki], s[ki + 1], f);
}
`;

/**
 * Shared uniforms of every patched material: `on` (1 shows the heat map) and `scale` (the
 * displacement, in the GLB's metres, at the top of the ramp).
 */
export const heatUniforms = {
  mimicHeatOn: { value: 0 },
  mimicHeatScale: { value: 1 },
};

const patched = new WeakSet();

/**
 * Patches `material` (a three.js built-in lit material) to colour by the heat map while
 * `heatUniforms.mimicHeatOn` is 1: the vertex shader measures |transformed - position| after
 * the morph targets (rest-relative in glTF, so `position` is P0), the fragment shader puts the
 * ramp in place of the albedo (and its texture) before lighting, as render.wgsl does.
 */
export function patchHeat(material) {
  if (patched.has(material)) return;
  patched.add(material);
  material.onBeforeCompile = (shader) => {
    shader.uniforms.mimicHeatOn = heatUniforms.mimicHeatOn;
    shader.uniforms.mimicHeatScale = heatUniforms.mimicHeatScale;
    shader.vertexShader = shader.vertexShader
      .replace('#include <common>', '#include <common>\nvarying float vMimicHeat;\nuniform float mimicHeatScale;')
      .replace(
        '#include <morphtarget_vertex>',
        '#include <morphtarget_vertex>\nvMimicHeat = length(transformed - position) / max(mimicHeatScale, 1e-12);',
      );
    shader.fragmentShader = shader.fragmentShader
      .replace('#include <common>', `#include <common>\n${GLSL_RAMP}`)
      .replace(
        '#include <color_fragment>',
        '#include <color_fragment>\nif (mimicHeatOn > 0.5) diffuseColor.rgb = mimicRamp(vMimicHeat);',
      );
  };
  material.customProgramCacheKey = () => 'mimic-heat';
  material.needsUpdate = true;
}

/** A number for the legend: 3 significant digits, no trailing zeros. */
const fmt = (v) => (v === 0 ? '0' : String(Number(v.toPrecision(3))));

/**
 * The colour legend in `box`: the ramp as a bar drawn pixel by pixel (each pixel column the
 * ramp at its centre, sRGB-encoded, no CSS interpolation), ticks at 0, 1/4, ..., 1 of the full
 * scale in the rig's units, and the full scale in cm (`defaulted`: it is the default, 5% of the
 * rest mesh's bounding-box diagonal).
 */
export function drawLegend(box, { scaleMetres, metresPerUnit, units, defaulted }) {
  box.replaceChildren();
  const title = document.createElement('div');
  title.textContent = `|P - P0| (${units})`;
  const bar = document.createElement('canvas');
  bar.id = 'legend-bar';
  const width = 200;
  bar.width = width;
  bar.height = 1;
  bar.style.width = `${width}px`;
  const g = bar.getContext('2d');
  const img = g.createImageData(width, 1);
  for (let x = 0; x < width; x++) {
    const c = ramp((x + 0.5) / width);
    for (let ch = 0; ch < 3; ch++) img.data[4 * x + ch] = srgbByte(c[ch]);
    img.data[4 * x + 3] = 255;
  }
  g.putImageData(img, 0, 0);
  const ticks = document.createElement('div');
  ticks.className = 'ticks';
  const full = scaleMetres / metresPerUnit;
  for (let q = 0; q <= 4; q++) {
    const t = document.createElement('span');
    t.textContent = fmt((full * q) / 4);
    ticks.appendChild(t);
  }
  const cm = document.createElement('div');
  const inCm = units === 'cm' ? '' : ` = ${fmt(scaleMetres * 100)} cm`;
  cm.textContent = `full scale ${fmt(full)} ${units}${inCm}${defaulted ? ' (5% of the head)' : ''}`;
  box.append(title, bar, ticks, cm);
  box.dataset.fullScale = String(full);
  box.dataset.fullScaleCm = String(scaleMetres * 100);
}
