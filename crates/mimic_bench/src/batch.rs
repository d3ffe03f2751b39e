//! Many sessions' morphs in one GPU dispatch, what `mimic bench --gpu` times: one basis `B` (its moving
//! rows, column-major) in a storage buffer, `sessions x controls x 3` weights in another, and per
//! session the morphed positions `P0 + B d` and, in a second pass over each vertex's triangles,
//! the area-weighted vertex normals (`morph.wgsl`).
//!
//! [`BatchMorph::new`] uploads the rig once; [`BatchMorph::run`] uploads the weights and runs both
//! passes; [`BatchMorph::read_positions`] / [`BatchMorph::read_normals`] read one session back;
//! [`BatchMorph::time`] times whole dispatches, by GPU timestamps where the adapter has
//! `TIMESTAMP_QUERY`, and always by the wall clock around upload, submit and wait.

use glam::Vec3;
use mimic_render::RenderError;
use mimic_solve::Basis;
use std::sync::mpsc;
use std::time::Instant;

mod setup;

/// Threads per workgroup (matches `@workgroup_size` in morph.wgsl).
const WORKGROUP: u32 = 64;

/// What can go wrong setting up or running a batch of sessions on the GPU.
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// No adapter, no device, or a failed readback (see [`RenderError`]).
    #[error(transparent)]
    Render(#[from] RenderError),
    /// The sessions' positions do not fit in one storage binding of this device.
    #[error(
        "{sessions} sessions x {vertices} vertices need {bytes} bytes of positions; this device binds at most {max} bytes in one buffer (use fewer sessions)"
    )]
    TooLarge {
        /// Sessions asked for.
        sessions: usize,
        /// Vertices of the mesh.
        vertices: usize,
        /// Bytes the positions (or normals) would take.
        bytes: u64,
        /// The device's largest storage binding.
        max: u64,
    },
    /// No sessions, or more than one dispatch dimension holds.
    #[error("{sessions} sessions: one dispatch holds 1..={max}")]
    BadSessions {
        /// Sessions asked for.
        sessions: usize,
        /// Most one dispatch holds.
        max: usize,
    },
}

/// How [`BatchMorph::time`] measured the GPU's own time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GpuTimes {
    /// Median of the morph pass, microseconds.
    pub morph_us: f64,
    /// Median of the normals pass, microseconds.
    pub normals_us: f64,
    /// Median of both passes, first start to last end, microseconds.
    pub total_us: f64,
}

/// Medians of [`BatchMorph::time`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct BatchTiming {
    /// Sessions in each dispatch.
    pub sessions: usize,
    /// Dispatches timed.
    pub iterations: usize,
    /// Median wall time of one dispatch: weight upload, encode, submit and wait (and, with
    /// timestamps, the readback of the 32 timestamp bytes), microseconds.
    pub wall_us: f64,
    /// GPU timestamps of the passes, where the adapter has `TIMESTAMP_QUERY`.
    pub gpu: Option<GpuTimes>,
}

impl BatchTiming {
    /// The per-dispatch time the session count at 60 fps is based on: the GPU's own time of
    /// both passes where timestamps exist, else the wall time.
    pub fn per_dispatch_us(&self) -> f64 {
        self.gpu.map_or(self.wall_us, |g| g.total_us)
    }

    /// Sessions whose morph (and normals) fit in one 60 fps frame (16.67 ms), at this dispatch's
    /// cost per session: `sessions * 16 667 us / per_dispatch_us`.
    pub fn sessions_at_60fps(&self) -> f64 {
        let t = self.per_dispatch_us();
        if t > 0.0 {
            self.sessions as f64 * (1e6 / 60.0) / t
        } else {
            0.0
        }
    }
}

/// Timestamp queries of one dispatch: morph begin/end, normals begin/end.
struct Timestamps {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
}

/// A rig uploaded once for `sessions` independent sessions morphed in one dispatch.
pub struct BatchMorph {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: String,
    vertex_count: usize,
    control_count: usize,
    sessions: usize,
    moving: u32,
    normal_count: u32,
    weights: wgpu::Buffer,
    positions: wgpu::Buffer,
    normals: wgpu::Buffer,
    morph: wgpu::ComputePipeline,
    vertex_normals: wgpu::ComputePipeline,
    morph_group: wgpu::BindGroup,
    normals_group: wgpu::BindGroup,
    timestamps: Option<Timestamps>,
    /// The weights as f32 for the upload, kept between calls.
    staging: Vec<f32>,
}

impl BatchMorph {
    /// Creates a device on the first adapter wgpu finds (a GPU, or Mesa's lavapipe) and uploads
    /// the rig: rest `positions`, `triangles` (normals are recomputed from these), the moving rows
    /// of `basis`, and the rest positions and normals of every session.
    pub fn new(
        basis: &Basis,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        sessions: usize,
    ) -> Result<Self, BatchError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Self::on_adapter(&adapter, basis, positions, triangles, sessions)
    }

    fn on_adapter(
        adapter: &wgpu::Adapter,
        basis: &Basis,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        sessions: usize,
    ) -> Result<Self, BatchError> {
        let n = positions.len();
        let m = basis.control_count();
        if basis.vertex_count() != n {
            return Err(RenderError::SizeMismatch {
                what: "basis rows vs mesh vertices",
                got: basis.vertex_count(),
                expected: n,
            }
            .into());
        }
        let info = adapter.get_info();
        let (device, queue, stamps) = setup::open_device(adapter, sessions, n)?;
        let plan = setup::MorphPlan::new(basis, positions, triangles)?;
        let gpu = setup::upload(&device, &plan, positions, sessions, m);
        let timestamps = stamps.then(|| setup::timestamps(&device, &queue));
        Ok(Self {
            adapter: format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend),
            vertex_count: n,
            control_count: m,
            sessions,
            moving: plan.rows.len() as u32,
            normal_count: plan.normal_vertices.len() as u32,
            weights: gpu.weights,
            positions: gpu.positions,
            normals: gpu.normals,
            morph: gpu.morph,
            vertex_normals: gpu.vertex_normals,
            morph_group: gpu.morph_group,
            normals_group: gpu.normals_group,
            timestamps,
            staging: Vec::with_capacity(sessions * m * 3),
            device,
            queue,
        })
    }

    /// Name, type and backend of the adapter, e.g. `llvmpipe (LLVM 19.1.1, 256 bits) (Cpu, Vulkan)`.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// Sessions per dispatch.
    pub fn sessions(&self) -> usize {
        self.sessions
    }

    /// Rows of the basis the morph pass computes (those not all zero).
    pub fn moving_count(&self) -> usize {
        self.moving as usize
    }

    /// Vertices whose normal the normals pass recomputes.
    pub fn normal_count(&self) -> usize {
        self.normal_count as usize
    }

    /// Whether [`BatchMorph::time`] reads GPU timestamps (the adapter has `TIMESTAMP_QUERY`).
    pub fn has_timestamps(&self) -> bool {
        self.timestamps.is_some()
    }

    /// Uploads `d` (session-major: `d[s * controls + j]` is control `j` of session `s`) and
    /// encodes both passes; `stamps` adds the timestamp writes and their readback copy.
    fn encode(&mut self, d: &[Vec3], stamps: bool) -> Result<wgpu::CommandBuffer, BatchError> {
        let want = self.sessions * self.control_count;
        if d.len() != want {
            return Err(RenderError::SizeMismatch {
                what: "weights (sessions x controls) vs the batch",
                got: d.len(),
                expected: want,
            }
            .into());
        }
        self.staging.clear();
        self.staging.extend(d.iter().flat_map(|v| [v.x, v.y, v.z]));
        if !self.staging.is_empty() {
            self.queue
                .write_buffer(&self.weights, 0, bytemuck::cast_slice(&self.staging));
        }
        let ts = self.timestamps.as_ref().filter(|_| stamps);
        let writes = |begin: u32| {
            ts.map(|t| wgpu::ComputePassTimestampWrites {
                query_set: &t.set,
                beginning_of_pass_write_index: Some(begin),
                end_of_pass_write_index: Some(begin + 1),
            })
        };
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let sessions = self.sessions as u32;
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("batch morph"),
                timestamp_writes: writes(0),
            });
            pass.set_pipeline(&self.morph);
            pass.set_bind_group(0, &self.morph_group, &[]);
            pass.dispatch_workgroups(self.moving.div_ceil(WORKGROUP), sessions, 1);
        }
        {
            let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                label: Some("batch normals"),
                timestamp_writes: writes(2),
            });
            pass.set_pipeline(&self.vertex_normals);
            pass.set_bind_group(0, &self.normals_group, &[]);
            pass.dispatch_workgroups(self.normal_count.div_ceil(WORKGROUP), sessions, 1);
        }
        if let Some(t) = ts {
            encoder.resolve_query_set(&t.set, 0..4, &t.resolve, 0);
            encoder.copy_buffer_to_buffer(&t.resolve, 0, &t.readback, 0, t.resolve.size());
        }
        Ok(encoder.finish())
    }

    /// Morphs every session: `d[s * controls + j]` is control `j`'s displacement in session `s`;
    /// positions `P0 + B d_s` and their normals land in the session's part of the GPU buffers.
    /// Waits for the GPU.
    pub fn run(&mut self, d: &[Vec3]) -> Result<(), BatchError> {
        let commands = self.encode(d, false)?;
        self.queue.submit([commands]);
        self.wait()
    }

    /// Times `iterations` dispatches of `d` (as [`BatchMorph::run`]) after one untimed warm-up;
    /// returns the medians.
    pub fn time(&mut self, d: &[Vec3], iterations: usize) -> Result<BatchTiming, BatchError> {
        self.run(d)?;
        let iterations = iterations.max(1);
        let mut wall = Vec::with_capacity(iterations);
        let mut gpu: Vec<[f64; 3]> = Vec::with_capacity(iterations);
        for _ in 0..iterations {
            let t = Instant::now();
            let commands = self.encode(d, true)?;
            self.queue.submit([commands]);
            let stamps = match &self.timestamps {
                Some(ts) => Some(map_read(&self.device, &ts.readback)?),
                None => {
                    self.wait()?;
                    None
                }
            };
            wall.push(t.elapsed().as_secs_f64() * 1e6);
            if let (Some(bytes), Some(ts)) = (stamps, &self.timestamps) {
                let ticks: &[u64] = bytemuck::try_cast_slice(&bytes)
                    .map_err(|e| RenderError::Readback(e.to_string()))?;
                if let [a, b, c, e] = ticks {
                    let us =
                        |from: u64, to: u64| to.saturating_sub(from) as f64 * ts.period_ns / 1e3;
                    gpu.push([us(*a, *b), us(*c, *e), us(*a, *e)]);
                }
            }
        }
        let gpu = (!gpu.is_empty()).then(|| GpuTimes {
            morph_us: median(gpu.iter().map(|g| g[0]).collect()),
            normals_us: median(gpu.iter().map(|g| g[1]).collect()),
            total_us: median(gpu.iter().map(|g| g[2]).collect()),
        });
        Ok(BatchTiming {
            sessions: self.sessions,
            iterations,
            wall_us: median(wall),
            gpu,
        })
    }

    /// Session `s`'s positions after the last [`BatchMorph::run`] (rest before the first).
    pub fn read_positions(&self, s: usize) -> Result<Vec<Vec3>, BatchError> {
        self.read_session(&self.positions, s)
    }

    /// Session `s`'s normals after the last [`BatchMorph::run`] (rest normals before the first).
    pub fn read_normals(&self, s: usize) -> Result<Vec<Vec3>, BatchError> {
        self.read_session(&self.normals, s)
    }

    fn read_session(&self, src: &wgpu::Buffer, s: usize) -> Result<Vec<Vec3>, BatchError> {
        if s >= self.sessions {
            return Err(RenderError::SizeMismatch {
                what: "session index vs sessions",
                got: s,
                expected: self.sessions,
            }
            .into());
        }
        let size = (self.vertex_count.max(1) * 16) as u64;
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("session readback"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let offset = (s * self.vertex_count * 16) as u64;
        encoder.copy_buffer_to_buffer(src, offset, &staging, 0, size);
        self.queue.submit([encoder.finish()]);
        let bytes = map_read(&self.device, &staging)?;
        let floats: &[f32] =
            bytemuck::try_cast_slice(&bytes).map_err(|e| RenderError::Readback(e.to_string()))?;
        Ok(floats
            .chunks_exact(4)
            .take(self.vertex_count)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// Waits until the GPU has finished everything submitted.
    fn wait(&self) -> Result<(), BatchError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| RenderError::Readback(e.to_string()))?;
        Ok(())
    }
}

/// Median of `v` (0 for none).
fn median(mut v: Vec<f64>) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

/// Waits for the queue, maps `buffer` and copies it out.
fn map_read(device: &wgpu::Device, buffer: &wgpu::Buffer) -> Result<Vec<u8>, BatchError> {
    let (tx, rx) = mpsc::sync_channel(1);
    buffer.map_async(wgpu::MapMode::Read, .., move |r| {
        // The receiver outlives the poll below; a failed send only means it is gone.
        let _ = tx.send(r);
    });
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    rx.recv()
        .map_err(|e| RenderError::Readback(e.to_string()))?
        .map_err(|e| RenderError::Readback(e.to_string()))?;
    let bytes = buffer
        .get_mapped_range(..)
        .map_err(|e| RenderError::Readback(e.to_string()))?
        .to_vec();
    buffer.unmap();
    Ok(bytes)
}
