//! [`BatchMorph`](super::BatchMorph)'s set-up: the device, the CPU-side plan of the moving rows
//! and each normal's triangles, the buffers and pipelines, and the timestamp queries.

use super::{BatchError, Timestamps};
use glam::Vec3;
use mimic_render::RenderError;
use mimic_solve::Basis;
use wgpu::util::DeviceExt;

/// Size of the uniform `Params` of morph.wgsl.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    vertices: u32,
    moving: u32,
    controls: u32,
    sessions: u32,
    normal_count: u32,
    pad: [u32; 3],
}

/// Checks that `sessions` of `n` vertices fit the adapter's limits and opens a device; the bool
/// says whether it has timestamp queries.
pub(super) fn open_device(
    adapter: &wgpu::Adapter,
    sessions: usize,
    n: usize,
) -> Result<(wgpu::Device, wgpu::Queue, bool), BatchError> {
    let have = adapter.limits();
    let max_sessions = have.max_compute_workgroups_per_dimension as usize;
    if sessions == 0 || sessions > max_sessions {
        return Err(BatchError::BadSessions {
            sessions,
            max: max_sessions,
        });
    }
    let bytes = (sessions * n.max(1) * 16) as u64;
    let max = have
        .max_storage_buffer_binding_size
        .min(have.max_buffer_size);
    if bytes > max {
        return Err(BatchError::TooLarge {
            sessions,
            vertices: n,
            bytes,
            max,
        });
    }
    let stamps = adapter.features().contains(wgpu::Features::TIMESTAMP_QUERY);
    let limits = wgpu::Limits {
        max_storage_buffer_binding_size: have.max_storage_buffer_binding_size,
        max_buffer_size: have.max_buffer_size,
        max_compute_workgroups_per_dimension: have.max_compute_workgroups_per_dimension,
        ..wgpu::Limits::default()
    };
    let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        label: Some("mimic_bench batch morph"),
        required_features: if stamps {
            wgpu::Features::TIMESTAMP_QUERY
        } else {
            wgpu::Features::empty()
        },
        required_limits: limits,
        ..Default::default()
    }))
    .map_err(|e| RenderError::NoDevice(e.to_string()))?;
    Ok((device, queue, stamps))
}

/// What the GPU is given, computed on the CPU: the moving rows of `B` (column-major) with their
/// rest positions, and the vertices whose normal can change with their triangles.
pub(super) struct MorphPlan {
    /// Mesh vertex of each moving row (rows of `B` not all zero).
    pub(super) rows: Vec<u32>,
    /// `B` over the moving rows, column-major.
    columns: Vec<f32>,
    /// Rest positions of the moving rows, `w` = 1.
    rest_rows: Vec<[f32; 4]>,
    /// Vertices with a moving vertex in one of their triangles.
    pub(super) normal_vertices: Vec<u32>,
    /// `incident[first[k]..first[k + 1]]`: the triangles of normal vertex `k`, ascending.
    first: Vec<u32>,
    /// Triangle numbers, per normal vertex.
    incident: Vec<u32>,
    /// The triangles' corners, flat.
    flat: Vec<u32>,
    /// Normals of the rest shape, every vertex.
    rest_normals: Vec<Vec3>,
}

impl MorphPlan {
    /// The plan of `basis` over a mesh of `positions` and `triangles`.
    pub(super) fn new(
        basis: &Basis,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
    ) -> Result<Self, BatchError> {
        let (n, m) = (positions.len(), basis.control_count());
        let rows: Vec<u32> = (0..n)
            .filter(|&i| basis.row(i).iter().any(|w| *w != 0.0))
            .map(|i| i as u32)
            .collect();
        let mut columns = Vec::with_capacity(rows.len() * m);
        for j in 0..m {
            columns.extend(rows.iter().map(|&i| basis.row(i as usize)[j]));
        }
        let rest_rows = rows
            .iter()
            .map(|&i| {
                let p = positions[i as usize];
                [p.x, p.y, p.z, 1.0]
            })
            .collect();
        let normal_vertices = normal_set(&rows, n, triangles)?;
        let (first, incident) = incidence(&normal_vertices, n, triangles);
        // Every session starts at the rest shape with its normals.
        let mut rest_normals = vec![Vec3::ZERO; n];
        mimic_solve::vertex_normals(positions, triangles, &mut rest_normals);
        Ok(Self {
            rows,
            columns,
            rest_rows,
            normal_vertices,
            first,
            incident,
            flat: triangles.iter().flatten().copied().collect(),
            rest_normals,
        })
    }
}

/// Vertices whose normal can change: the corners of every triangle with a moving corner,
/// ascending; fails on a corner past the mesh.
fn normal_set(rows: &[u32], n: usize, triangles: &[[u32; 3]]) -> Result<Vec<u32>, BatchError> {
    let mut moving = vec![false; n];
    rows.iter().for_each(|&i| moving[i as usize] = true);
    let mut in_normal_set = vec![false; n];
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            if v as usize >= n {
                return Err(RenderError::BadIndex {
                    triangle: t,
                    vertex: v,
                    vertex_count: n,
                }
                .into());
            }
        }
        if tri.iter().any(|&v| moving[v as usize]) {
            tri.iter().for_each(|&v| in_normal_set[v as usize] = true);
        }
    }
    Ok((0..n as u32)
        .filter(|&v| in_normal_set[v as usize])
        .collect())
}

/// Each normal vertex's triangles (ascending, as the CPU sums them) as offsets `first` into
/// `incident`.
fn incidence(normal_vertices: &[u32], n: usize, triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<u32>) {
    let mut local = vec![u32::MAX; n];
    for (k, &v) in normal_vertices.iter().enumerate() {
        local[v as usize] = k as u32;
    }
    let mut first = vec![0u32; normal_vertices.len() + 1];
    for tri in triangles {
        for &v in tri {
            if let Some(&k) = local.get(v as usize).filter(|k| **k != u32::MAX) {
                first[k as usize + 1] += 1;
            }
        }
    }
    for k in 0..normal_vertices.len() {
        first[k + 1] += first[k];
    }
    let mut fill = first.clone();
    let mut incident = vec![0u32; first[normal_vertices.len()] as usize];
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            if let Some(&k) = local.get(v as usize).filter(|k| **k != u32::MAX) {
                incident[fill[k as usize] as usize] = t as u32;
                fill[k as usize] += 1;
            }
        }
    }
    (first, incident)
}

/// The buffers, pipelines and bind groups a [`BatchMorph`](super::BatchMorph) keeps.
pub(super) struct Uploaded {
    pub(super) weights: wgpu::Buffer,
    pub(super) positions: wgpu::Buffer,
    pub(super) normals: wgpu::Buffer,
    pub(super) morph: wgpu::ComputePipeline,
    pub(super) vertex_normals: wgpu::ComputePipeline,
    pub(super) morph_group: wgpu::BindGroup,
    pub(super) normals_group: wgpu::BindGroup,
}

/// Uploads `plan` for `sessions` sessions of `m` controls (every session at the rest shape) and
/// builds both passes.
pub(super) fn upload(
    device: &wgpu::Device,
    plan: &MorphPlan,
    positions: &[Vec3],
    sessions: usize,
    m: usize,
) -> Uploaded {
    let per_session = |v: &[Vec3], w: f32| -> Vec<[f32; 4]> {
        let one: Vec<[f32; 4]> = v.iter().map(|p| [p.x, p.y, p.z, w]).collect();
        let mut all = Vec::with_capacity(one.len() * sessions);
        for _ in 0..sessions {
            all.extend_from_slice(&one);
        }
        all
    };
    let storage = wgpu::BufferUsages::STORAGE;
    let init = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
        // Zero-sized bindings are invalid: pad empty buffers to one vec4.
        let padded = [0u8; 16];
        let contents = if bytes.is_empty() { &padded[..] } else { bytes };
        device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some(label),
            contents,
            usage,
        })
    };
    let params = Params {
        vertices: positions.len() as u32,
        moving: plan.rows.len() as u32,
        controls: m as u32,
        sessions: sessions as u32,
        normal_count: plan.normal_vertices.len() as u32,
        pad: [0; 3],
    };
    let uniform = wgpu::BufferUsages::UNIFORM;
    let params_buf = init("params", bytemuck::bytes_of(&params), uniform);
    let basis_buf = init(
        "basis columns",
        bytemuck::cast_slice(&plan.columns),
        storage,
    );
    let rest_buf = init("rest rows", bytemuck::cast_slice(&plan.rest_rows), storage);
    let rows_buf = init("rows", bytemuck::cast_slice(&plan.rows), storage);
    let weights = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("weights"),
        size: (sessions * m.max(1) * 12).next_multiple_of(16) as u64,
        usage: storage | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let rw = storage | wgpu::BufferUsages::COPY_SRC;
    let rest = per_session(positions, 1.0);
    let positions_buf = init("positions", bytemuck::cast_slice(&rest), rw);
    let rest = per_session(&plan.rest_normals, 0.0);
    let normals_buf = init("normals", bytemuck::cast_slice(&rest), rw);
    let triangles_buf = init("triangles", bytemuck::cast_slice(&plan.flat), storage);
    let normal_vertices = bytemuck::cast_slice(&plan.normal_vertices);
    let normal_vertices_buf = init("normal vertices", normal_vertices, storage);
    let first_buf = init("first", bytemuck::cast_slice(&plan.first), storage);
    let incident_buf = init("incident", bytemuck::cast_slice(&plan.incident), storage);
    let (morph, vertex_normals) = pipelines(device);
    let morph_group = bind(
        device,
        &morph,
        &[
            (0, &params_buf),
            (1, &basis_buf),
            (2, &rest_buf),
            (3, &rows_buf),
            (4, &weights),
            (5, &positions_buf),
        ],
    );
    let normals_group = bind(
        device,
        &vertex_normals,
        &[
            (0, &params_buf),
            (6, &triangles_buf),
            (7, &normal_vertices_buf),
            (8, &first_buf),
            (9, &incident_buf),
            (10, &normals_buf),
            (11, &positions_buf),
        ],
    );
    Uploaded {
        weights,
        positions: positions_buf,
        normals: normals_buf,
        morph,
        vertex_normals,
        morph_group,
        normals_group,
    }
}

/// The two passes of morph.wgsl: `morph` and `vertex_normals`.
fn pipelines(device: &wgpu::Device) -> (wgpu::ComputePipeline, wgpu::ComputePipeline) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("morph.wgsl"),
        source: wgpu::ShaderSource::Wgsl(include_str!("morph.wgsl").into()),
    });
    let pipeline = |entry: &str| {
        device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
            label: Some(entry),
            layout: None,
            module: &module,
            entry_point: Some(entry),
            compilation_options: Default::default(),
            cache: None,
        })
    };
    (pipeline("morph"), pipeline("vertex_normals"))
}

/// A bind group of `p`'s group 0 with each `(binding, buffer)` bound whole.
fn bind(
    device: &wgpu::Device,
    p: &wgpu::ComputePipeline,
    entries: &[(u32, &wgpu::Buffer)],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = entries
        .iter()
        .map(|(binding, b)| wgpu::BindGroupEntry {
            binding: *binding,
            resource: b.as_entire_binding(),
        })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: None,
        layout: &p.get_bind_group_layout(0),
        entries: &entries,
    })
}

/// The timestamp queries of one dispatch (morph begin/end, normals begin/end) and their buffers.
pub(super) fn timestamps(device: &wgpu::Device, queue: &wgpu::Queue) -> Timestamps {
    let size = 4 * u64::from(wgpu::QUERY_SIZE);
    Timestamps {
        set: device.create_query_set(&wgpu::QuerySetDescriptor {
            label: Some("batch timestamps"),
            ty: wgpu::QueryType::Timestamp,
            count: 4,
        }),
        resolve: device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamps resolve"),
            size,
            usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        }),
        readback: device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("timestamps readback"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        }),
        period_ns: f64::from(queue.get_timestamp_period()),
    }
}
