// Per-frame compute passes: the morph P = P0 + sum_j B[i, j] d_j, then area-weighted vertex normals.
// `Frame` and its uniform at binding 0 are declared in frame.wgsl, which is prepended.

@group(0) @binding(1) var<storage, read> rest: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> basis: array<f32>;
@group(0) @binding(3) var<storage, read_write> morphed: array<vec4<f32>>;
// Control displacements d_j (xyz), j < control count: the per-frame upload, any count.
@group(0) @binding(9) var<storage, read> controls: array<vec4<f32>>;

@compute @workgroup_size(64)
fn morph(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let n = frame.modes.z;
    if (i >= n) {
        return;
    }
    let m = frame.modes.w;
    var u = vec3<f32>(0.0);
    let row = i * m;
    for (var j = 0u; j < m; j = j + 1u) {
        u = u + basis[row + j] * controls[j].xyz;
    }
    morphed[i] = vec4<f32>(rest[i].xyz + u, 1.0);
}

@group(0) @binding(4) var<storage, read> positions: array<vec4<f32>>;
@group(0) @binding(5) var<storage, read> triangles: array<u32>;
// Triangles around vertex i: incident[first[i] .. first[i + 1]], ascending.
@group(0) @binding(6) var<storage, read> first: array<u32>;
@group(0) @binding(7) var<storage, read> incident: array<u32>;
@group(0) @binding(8) var<storage, read_write> normals: array<vec4<f32>>;

@compute @workgroup_size(64)
fn vertex_normals(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    if (i + 1u >= arrayLength(&first)) {
        return;
    }
    var s = vec3<f32>(0.0);
    for (var k = first[i]; k < first[i + 1u]; k = k + 1u) {
        let t = incident[k] * 3u;
        let a = positions[triangles[t]].xyz;
        let b = positions[triangles[t + 1u]].xyz;
        let c = positions[triangles[t + 2u]].xyz;
        s = s + cross(b - a, c - a);
    }
    let len = length(s);
    var nrm = vec3<f32>(0.0);
    if (len > 0.0) {
        nrm = s / len;
    }
    normals[i] = vec4<f32>(nrm, 0.0);
}
