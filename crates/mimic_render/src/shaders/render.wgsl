// Draws the morphed rig, not indexed: corner c of the draw is vertex triangles[c] of the morphed
// positions and normals; applies the head pose and the camera, and shades with diffuse + ambient
// light (over the vertex albedo or the corner's texture) or a heat map.
// `Frame` and its uniform at binding 0 are declared in frame.wgsl, and `ramp` (the heat map's
// colours) in ramp.wgsl, both prepended.

@group(0) @binding(1) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> basis: array<f32>;
@group(0) @binding(3) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> normals: array<vec4<f32>>;
// Per-vertex albedo (linear RGB; skin unless the material colours were set).
@group(0) @binding(10) var<storage, read> albedo: array<vec4<f32>>;
// The mesh's triangles, three vertex indices each (the draw's corners).
@group(0) @binding(5) var<storage, read> triangles: array<u32>;
// Per corner: xy texture coordinate (image convention), z texture layer (negative: untextured).
// Untextured rigs bind one entry: corners past the end are untextured.
@group(0) @binding(11) var<storage, read> corners: array<vec4<f32>>;
@group(0) @binding(12) var textures: texture_2d_array<f32>;
@group(0) @binding(13) var texture_sampler: sampler;

const MODE_LIT: u32 = 0u;
const MODE_HEAT_DISPLACEMENT: u32 = 1u;
const MODE_HEAT_CONTROL: u32 = 2u;

struct VsOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) normal: vec3<f32>,
    @location(1) heat: f32,
    @location(2) albedo: vec3<f32>,
    @location(3) uv: vec2<f32>,
    @location(4) @interpolate(flat) layer: i32,
}

@vertex
fn vs_main(@builtin(vertex_index) c: u32) -> VsOut {
    let i = triangles[c];
    let p = positions[i].xyz;
    let world = frame.model * vec4<f32>(p, 1.0);
    var out: VsOut;
    out.clip = frame.view_proj * world;
    out.normal = (frame.model * vec4<f32>(normals[i].xyz, 0.0)).xyz;
    var heat = 0.0;
    if (frame.modes.x == MODE_HEAT_DISPLACEMENT) {
        heat = length(p - rest[i].xyz) / max(frame.params.x, 1e-12);
    } else if (frame.modes.x == MODE_HEAT_CONTROL) {
        heat = basis[i * frame.modes.w + frame.modes.y];
    }
    out.heat = heat;
    out.albedo = albedo[i].xyz;
    var corner = vec4<f32>(0.0, 0.0, -1.0, 0.0);
    if (c < arrayLength(&corners)) {
        corner = corners[c];
    }
    out.uv = corner.xy;
    out.layer = i32(round(corner.z));
    return out;
}

@fragment
fn fs_main(in: VsOut, @builtin(front_facing) front: bool) -> @location(0) vec4<f32> {
    var n = in.normal;
    let len = length(n);
    if (len > 0.0) {
        n = n / len;
    }
    if (!front) {
        n = -n;
    }
    let diffuse = max(dot(n, normalize(frame.light.xyz)), 0.0);
    let ambient = frame.light.w;
    // Sampled in uniform control flow (derivatives); the sRGB texture format decodes to linear.
    let texel = textureSample(textures, texture_sampler, in.uv, max(in.layer, 0));
    var base = in.albedo;
    if (in.layer >= 0) {
        base = texel.rgb;
    }
    if (frame.modes.x != MODE_LIT) {
        base = ramp(in.heat);
    }
    let c = base * (ambient + (1.0 - ambient) * diffuse);
    return vec4<f32>(c, 1.0);
}
