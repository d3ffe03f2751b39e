// The heat map's colour ramp, shared by render.wgsl (the mesh) and overlay.wgsl (the legend);
// `RAMP_STOPS` in overlay/legend.rs holds the same stops for the CPU.

// Piecewise-linear blue -> cyan -> green -> yellow -> red ramp over [0, 1].
fn ramp(t: f32) -> vec3<f32> {
    let x = clamp(t, 0.0, 1.0) * 4.0;
    let k = min(floor(x), 3.0);
    let f = x - k;
    var stops = array<vec3<f32>, 5>(
        vec3<f32>(0.05, 0.10, 0.60),
        vec3<f32>(0.00, 0.65, 0.90),
        vec3<f32>(0.15, 0.80, 0.25),
        vec3<f32>(0.98, 0.85, 0.10),
        vec3<f32>(0.85, 0.08, 0.05),
    );
    let ki = u32(k);
    return mix(stops[ki], stops[ki + 1u], f);
}
