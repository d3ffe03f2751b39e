// The per-frame uniform shared by the compute and draw shaders (mirrors `FrameUniform` in
// renderer.rs); concatenated in front of compute.wgsl and render.wgsl.

struct Frame {
    view_proj: mat4x4<f32>,
    model: mat4x4<f32>,
    // xyz: direction towards the light (world), w: ambient term.
    light: vec4<f32>,
    // x: heat-map full-scale displacement (target units).
    params: vec4<f32>,
    // x: shading mode, y: control for the weight heat map, z: vertex count, w: control count.
    modes: vec4<u32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
