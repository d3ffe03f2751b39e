// The overlay: screen-space quads (text glyphs, panels, the legend's ramp) drawn over the
// resolved image, six vertices per quad, one instance per quad. `ramp` comes from ramp.wgsl,
// which is prepended. Mirrors `Quad` in overlay/mod.rs.

struct Quad {
    // left, top, right, bottom (pixels, y down)
    rect: vec4<f32>,
    // linear RGBA
    color: vec4<f32>,
    // x: kind (0 solid, 1 glyph, 2 ramp), y/z: glyph rows 0-3 / 4-7 (bit 0 leftmost), w: scale
    info: vec4<u32>,
}

@group(0) @binding(0) var<storage, read> quads: array<Quad>;
// xy: target size in pixels
@group(0) @binding(1) var<uniform> screen: vec4<f32>;

struct OverlayOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) quad: u32,
}

@vertex
fn vs_overlay(@builtin(vertex_index) v: u32, @builtin(instance_index) i: u32) -> OverlayOut {
    var corners = array<vec2<f32>, 6>(
        vec2<f32>(0.0, 0.0), vec2<f32>(1.0, 0.0), vec2<f32>(0.0, 1.0),
        vec2<f32>(0.0, 1.0), vec2<f32>(1.0, 0.0), vec2<f32>(1.0, 1.0),
    );
    let q = quads[i];
    let px = mix(q.rect.xy, q.rect.zw, corners[v]);
    var out: OverlayOut;
    out.clip = vec4<f32>(px.x / screen.x * 2.0 - 1.0, 1.0 - px.y / screen.y * 2.0, 0.0, 1.0);
    out.quad = i;
    return out;
}

@fragment
fn fs_overlay(in: OverlayOut) -> @location(0) vec4<f32> {
    let q = quads[in.quad];
    if (q.info.x == 1u) {
        // The font pixel under this pixel's centre.
        let s = f32(max(q.info.w, 1u));
        let cell = min(vec2<u32>(max((in.clip.xy - q.rect.xy) / s, vec2<f32>(0.0))), vec2<u32>(7u));
        let bit = cell.y * 8u + cell.x;
        var word = q.info.y;
        if (bit >= 32u) {
            word = q.info.z;
        }
        if (((word >> (bit % 32u)) & 1u) == 0u) {
            discard;
        }
        return q.color;
    }
    if (q.info.x == 2u) {
        let t = (q.rect.w - in.clip.y) / max(q.rect.w - q.rect.y, 1.0);
        return vec4<f32>(ramp(t), q.color.a);
    }
    return q.color;
}
