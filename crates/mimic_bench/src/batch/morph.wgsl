// Many sessions' morphs in one dispatch: P[s, i] = P0[i] + sum_j B[i, j] d[s, j], then the
// area-weighted vertex normals of each session's morphed surface (crates/mimic_bench/src/batch.rs).
//
// Only the rows of B that are not all zero are stored and computed ("moving rows"); the other
// vertices keep the rest positions and normals the buffers were filled with at setup.

struct Params {
    // Vertices of the mesh (the per-session stride of `positions` and `normals`).
    vertices: u32,
    // Moving rows (entries of `rows`).
    moving: u32,
    // Controls (columns of B).
    controls: u32,
    // Sessions in the dispatch.
    sessions: u32,
    // Vertices whose normal can change (entries of `normal_vertices`).
    normal_count: u32,
    pad0: u32,
    pad1: u32,
    pad2: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
// B over the moving rows, column-major: basis[j * moving + k] is B[rows[k], j], so the threads
// of a workgroup read consecutive words.
@group(0) @binding(1) var<storage, read> basis: array<f32>;
// Rest positions of the moving rows, in the order of `rows`.
@group(0) @binding(2) var<storage, read> rest: array<vec4<f32>>;
// Mesh vertex of each moving row.
@group(0) @binding(3) var<storage, read> rows: array<u32>;
// weights[(s * controls + j) * 3 + a]: control j's displacement along axis a in session s.
@group(0) @binding(4) var<storage, read> weights: array<f32>;
// positions[s * vertices + v]: vertex v of session s.
@group(0) @binding(5) var<storage, read_write> positions: array<vec4<f32>>;

@compute @workgroup_size(64)
fn morph(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    let s = id.y;
    if (k >= params.moving || s >= params.sessions) {
        return;
    }
    let m = params.controls;
    let w0 = s * m * 3u;
    var u = vec3<f32>(0.0);
    for (var j = 0u; j < m; j = j + 1u) {
        let b = basis[j * params.moving + k];
        let w = w0 + 3u * j;
        u = u + b * vec3<f32>(weights[w], weights[w + 1u], weights[w + 2u]);
    }
    positions[s * params.vertices + rows[k]] = vec4<f32>(rest[k].xyz + u, 1.0);
}

@group(0) @binding(6) var<storage, read> triangles: array<u32>;
// Vertices whose normal can change (corners of triangles with a moving vertex).
@group(0) @binding(7) var<storage, read> normal_vertices: array<u32>;
// Triangles around normal_vertices[k]: incident[first[k] .. first[k + 1]], ascending.
@group(0) @binding(8) var<storage, read> first: array<u32>;
@group(0) @binding(9) var<storage, read> incident: array<u32>;
@group(0) @binding(10) var<storage, read_write> normals: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read> morphed: array<vec4<f32>>;

@compute @workgroup_size(64)
fn vertex_normals(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    let s = id.y;
    if (k >= params.normal_count || s >= params.sessions) {
        return;
    }
    let base = s * params.vertices;
    var sum = vec3<f32>(0.0);
    for (var e = first[k]; e < first[k + 1u]; e = e + 1u) {
        let t = incident[e] * 3u;
        let a = morphed[base + triangles[t]].xyz;
        let b = morphed[base + triangles[t + 1u]].xyz;
        let c = morphed[base + triangles[t + 2u]].xyz;
        sum = sum + cross(b - a, c - a);
    }
    let len = length(sum);
    var nrm = vec3<f32>(0.0);
    if (len > 0.0) {
        nrm = sum / len;
    }
    normals[base + normal_vertices[k]] = vec4<f32>(nrm, 0.0);
}
