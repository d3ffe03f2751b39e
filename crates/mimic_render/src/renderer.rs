//! The headless renderer: device, offscreen targets, pipelines, and the per-rig GPU buffers.

use crate::overlay::{Overlay, OverlayPass};
use crate::texture::Level;
use crate::{Camera, Image, RenderError};
use glam::{Mat4, Quat, Vec3};
use mimic_solve::Basis;
use mimic_types::{MeshTextures, TextureImage};
use std::sync::mpsc;
use wgpu::util::DeviceExt;

/// Most controls (basis columns) a rig may have: 1024, i.e. 341 morph targets at three columns
/// each; the displacements go up per frame in a storage buffer sized for the rig.
pub const MAX_CONTROLS: usize = 1024;

/// Colour format of the offscreen target (and of the bytes read back): sRGB-encoded RGBA8.
pub const COLOR_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;
/// Depth format.
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Samples per pixel of the multisampled target.
const SAMPLES: u32 = 4;
/// Threads per workgroup of the compute passes (matches `@workgroup_size` in compute.wgsl).
const WORKGROUP: u32 = 64;

/// How the surface is coloured.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shading {
    /// Skin albedo with per-pixel diffuse plus ambient light.
    Lit,
    /// Heat map of the displacement magnitude `|P_i - P0_i|`, computed in the shader; `full_scale`
    /// (rig units) maps to the top of the ramp.
    Displacement {
        /// Displacement shown as the hottest colour.
        full_scale: f32,
    },
    /// Heat map of one control's weight `B[i, control]` (0 cold, 1 hot).
    ControlWeight {
        /// Column of the basis.
        control: usize,
    },
}

/// What deforms the rig this frame.
#[derive(Clone, Copy, Debug)]
pub enum Deform<'a> {
    /// The rest shape.
    Rest,
    /// Control displacements `d` (one per basis column): the GPU computes `P = P0 + B d` and normals.
    Controls(&'a [Vec3]),
    /// Full vertex positions; normals too, or `None` to recompute them on the GPU.
    Positions {
        /// One position per vertex.
        positions: &'a [Vec3],
        /// One normal per vertex, or `None`.
        normals: Option<&'a [Vec3]>,
    },
}

/// Camera, head transform, shading and light of a frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct View {
    /// The camera.
    pub camera: Camera,
    /// Rig space to world (e.g. the head pose); identity for none.
    pub model: Mat4,
    /// How the surface is coloured.
    pub shading: Shading,
    /// Direction towards the light, in camera axes (x right, y up, z towards the viewer).
    pub light: Vec3,
    /// Ambient share of the light, 0..=1.
    pub ambient: f32,
    /// Background colour, linear RGBA.
    pub background: [f64; 4],
}

impl View {
    /// A lit view from `camera`, no head motion, light from the upper left of the camera.
    pub fn lit(camera: Camera) -> Self {
        Self {
            camera,
            model: Mat4::IDENTITY,
            shading: Shading::Lit,
            light: Vec3::new(-0.4, 0.5, 1.0),
            ambient: 0.25,
            background: [0.02, 0.025, 0.035, 1.0],
        }
    }

    /// The transform that turns the head by `rotation` about `pivot` (e.g. the rig's centre).
    pub fn head_rotation(rotation: Quat, pivot: Vec3) -> Mat4 {
        Mat4::from_translation(pivot) * Mat4::from_quat(rotation) * Mat4::from_translation(-pivot)
    }
}

/// The buffers and texture the draw pass binds.
struct DrawBuffers<'a> {
    uniform: &'a wgpu::Buffer,
    rest: &'a wgpu::Buffer,
    basis: &'a wgpu::Buffer,
    positions: &'a wgpu::Buffer,
    normals: &'a wgpu::Buffer,
    triangles: &'a wgpu::Buffer,
    albedo: &'a wgpu::Buffer,
    corners: &'a wgpu::Buffer,
    texture: &'a wgpu::TextureView,
}

/// The per-frame uniform, laid out as `Frame` in the shaders.
#[repr(C)]
#[derive(Clone, Copy, bytemuck::Pod, bytemuck::Zeroable)]
struct FrameUniform {
    view_proj: [[f32; 4]; 4],
    model: [[f32; 4]; 4],
    light: [f32; 4],
    params: [f32; 4],
    modes: [u32; 4],
}

/// A rig uploaded once: rest positions, the basis, triangles with their per-vertex incidence
/// lists, and the buffers the compute passes write (morphed positions, normals).
pub struct RigGpu {
    vertex_count: u32,
    control_count: u32,
    index_count: u32,
    uniform: wgpu::Buffer,
    controls: wgpu::Buffer,
    positions: wgpu::Buffer,
    normals: wgpu::Buffer,
    morph_group: wgpu::BindGroup,
    normals_group: wgpu::BindGroup,
    draw_group: wgpu::BindGroup,
    indices: wgpu::Buffer,
    albedo: wgpu::Buffer,
    rest: wgpu::Buffer,
    basis: wgpu::Buffer,
    /// Per drawn corner: uv, texture layer (negative: untextured); one untextured entry until
    /// [`Renderer::set_textures`].
    corners: wgpu::Buffer,
    texture: wgpu::TextureView,
    textured: bool,
}

/// Albedo of every vertex until [`Renderer::set_albedo`] says otherwise: skin (linear RGB).
pub const SKIN_ALBEDO: [f32; 3] = [0.80, 0.66, 0.58];

impl RigGpu {
    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.vertex_count as usize
    }

    /// Number of controls (basis columns).
    pub fn control_count(&self) -> usize {
        self.control_count as usize
    }

    /// Number of triangles drawn.
    pub fn triangle_count(&self) -> usize {
        self.index_count as usize / 3
    }

    /// Whether textures were set ([`Renderer::set_textures`]).
    pub fn is_textured(&self) -> bool {
        self.textured
    }
}

/// Renderer: its own device and a multisampled colour + depth target, resolved into an offscreen
/// image (read back by [`Renderer::render`]) or into a window's texture ([`Renderer::draw_to`]).
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: String,
    format: wgpu::TextureFormat,
    width: u32,
    height: u32,
    color: wgpu::TextureView,
    resolve: wgpu::Texture,
    resolve_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
    morph: wgpu::ComputePipeline,
    normals: wgpu::ComputePipeline,
    draw: wgpu::RenderPipeline,
    sampler: wgpu::Sampler,
    overlay: OverlayPass,
}

fn vec4s(v: &[Vec3], w: f32) -> Vec<[f32; 4]> {
    v.iter().map(|p| [p.x, p.y, p.z, w]).collect()
}

/// Writes `v` into `buffer` from offset 0 as vec4s with `w` as the fourth component, without a
/// heap allocation of ours (chunks go through a stack array into wgpu's staging view); an empty
/// `v` writes one zero vec4 (the rest pose of a rig with no controls).
fn write_vec4s(queue: &wgpu::Queue, buffer: &wgpu::Buffer, v: &[Vec3], w: f32) {
    const CHUNK: usize = 256;
    const VEC4: usize = std::mem::size_of::<[f32; 4]>();
    let len = v.len().max(1);
    let Some(size) = wgpu::BufferSize::new((len * VEC4) as u64) else {
        return;
    };
    // None only when validation fails (reported through the device's error handler).
    let Some(mut view) = queue.write_buffer_with(buffer, 0, size) else {
        return;
    };
    if v.is_empty() {
        view.slice(..)
            .copy_from_slice(bytemuck::bytes_of(&[0f32; 4]));
        return;
    }
    let mut chunk = [[0f32; 4]; CHUNK];
    for (i, part) in v.chunks(CHUNK).enumerate() {
        for (c, p) in chunk.iter_mut().zip(part) {
            *c = [p.x, p.y, p.z, w];
        }
        let start = i * CHUNK * VEC4;
        view.slice(start..start + part.len() * VEC4)
            .copy_from_slice(bytemuck::cast_slice(&chunk[..part.len()]));
    }
}

impl Renderer {
    /// Creates a device on the first adapter wgpu finds (a GPU, or Mesa's lavapipe) and a
    /// `width x height` target.
    pub fn new(width: u32, height: u32) -> Result<Self, RenderError> {
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter =
            pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions::default()))
                .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        Self::on_adapter(&adapter, width, height, COLOR_FORMAT)
    }

    /// Creates a device on an adapter that can present to `surface` and a `width x height` target
    /// in the surface's sRGB format; returns the renderer and the surface configuration to
    /// [`wgpu::Surface::configure`] with (done here once; again after a resize, with the new size).
    pub fn for_surface(
        instance: &wgpu::Instance,
        surface: &wgpu::Surface<'_>,
        width: u32,
        height: u32,
    ) -> Result<(Self, wgpu::SurfaceConfiguration), RenderError> {
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            compatible_surface: Some(surface),
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoAdapter(e.to_string()))?;
        let caps = surface.get_capabilities(&adapter);
        let format = caps
            .formats
            .iter()
            .copied()
            .find(wgpu::TextureFormat::is_srgb)
            .or_else(|| caps.formats.first().copied())
            .ok_or_else(|| RenderError::NoDevice("the surface offers no format".into()))?;
        let mut config = surface
            .get_default_config(&adapter, width.max(1), height.max(1))
            .ok_or_else(|| {
                RenderError::NoDevice("the adapter cannot present to the window".into())
            })?;
        config.format = format;
        // Fifo (vsync) is always supported and paces the loop at the display's rate.
        config.present_mode = wgpu::PresentMode::AutoVsync;
        let renderer = Self::on_adapter(&adapter, width.max(1), height.max(1), format)?;
        surface.configure(&renderer.device, &config);
        Ok((renderer, config))
    }

    fn on_adapter(
        adapter: &wgpu::Adapter,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
    ) -> Result<Self, RenderError> {
        let info = adapter.get_info();
        let max = adapter.limits().max_texture_dimension_2d;
        if width == 0 || height == 0 || width > max || height > max {
            return Err(RenderError::BadSize { width, height, max });
        }
        let limits = wgpu::Limits {
            max_storage_buffer_binding_size: adapter.limits().max_storage_buffer_binding_size,
            max_buffer_size: adapter.limits().max_buffer_size,
            max_texture_dimension_2d: max,
            ..wgpu::Limits::default()
        };
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("mimic_render"),
            required_limits: limits,
            ..Default::default()
        }))
        .map_err(|e| RenderError::NoDevice(e.to_string()))?;

        let compute_src = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("compute.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("shaders/frame.wgsl"),
                    include_str!("shaders/compute.wgsl")
                )
                .into(),
            ),
        });
        let render_src = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("render.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("shaders/frame.wgsl"),
                    include_str!("shaders/ramp.wgsl"),
                    include_str!("shaders/render.wgsl")
                )
                .into(),
            ),
        });
        let compute = |entry: &str| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &compute_src,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let morph = compute("morph");
        let normals = compute("vertex_normals");
        let draw = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("draw"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &render_src,
                entry_point: Some("vs_main"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState {
                topology: wgpu::PrimitiveTopology::TriangleList,
                front_face: wgpu::FrontFace::Ccw,
                // Inner surfaces (mouth, eye sockets) are seen from behind: two-sided lighting.
                cull_mode: None,
                ..Default::default()
            },
            depth_stencil: Some(wgpu::DepthStencilState {
                format: DEPTH_FORMAT,
                depth_write_enabled: Some(true),
                depth_compare: Some(wgpu::CompareFunction::Less),
                stencil: Default::default(),
                bias: Default::default(),
            }),
            multisample: wgpu::MultisampleState {
                count: SAMPLES,
                ..Default::default()
            },
            fragment: Some(wgpu::FragmentState {
                module: &render_src,
                entry_point: Some("fs_main"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    blend: None,
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });

        let t = Targets::new(&device, width, height, format);
        // Textures repeat outside 0..1 (as modelling tools show them), trilinear filtering.
        let sampler = device.create_sampler(&wgpu::SamplerDescriptor {
            label: Some("texture"),
            address_mode_u: wgpu::AddressMode::Repeat,
            address_mode_v: wgpu::AddressMode::Repeat,
            mag_filter: wgpu::FilterMode::Linear,
            min_filter: wgpu::FilterMode::Linear,
            mipmap_filter: wgpu::MipmapFilterMode::Linear,
            ..Default::default()
        });
        let overlay = OverlayPass::new(&device, format);
        Ok(Self {
            overlay,
            device,
            queue,
            adapter: format!("{} ({:?}, {:?})", info.name, info.device_type, info.backend),
            format,
            width,
            height,
            color: t.color,
            resolve: t.resolve,
            resolve_view: t.resolve_view,
            depth: t.depth,
            readback: t.readback,
            padded_row: t.padded_row,
            morph,
            normals,
            draw,
            sampler,
        })
    }

    /// Name, type and backend of the adapter in use, e.g. `llvmpipe (LLVM 19.1.1, 256 bits) (Cpu, Vulkan)`.
    pub fn adapter(&self) -> &str {
        &self.adapter
    }

    /// Image size `(width, height)`.
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Colour format of the target (of the window's surface, or [`COLOR_FORMAT`] headless).
    pub fn format(&self) -> wgpu::TextureFormat {
        self.format
    }

    /// The device (e.g. to configure a surface after a resize).
    pub fn device(&self) -> &wgpu::Device {
        &self.device
    }

    /// Presents a window's frame drawn with [`Renderer::draw_to`].
    pub fn present(&self, frame: wgpu::SurfaceTexture) {
        self.queue.present(frame);
    }

    /// Resizes the target (a window's new inner size); zero sides are clamped to 1.
    pub fn resize(&mut self, width: u32, height: u32) {
        let (width, height) = (width.max(1), height.max(1));
        if (width, height) == (self.width, self.height) {
            return;
        }
        let t = Targets::new(&self.device, width, height, self.format);
        self.width = width;
        self.height = height;
        self.color = t.color;
        self.resolve = t.resolve;
        self.resolve_view = t.resolve_view;
        self.depth = t.depth;
        self.readback = t.readback;
        self.padded_row = t.padded_row;
    }

    /// Sets the albedo (linear RGB) of every vertex, e.g. from the mesh's material colours.
    pub fn set_albedo(&self, rig: &RigGpu, colors: &[[f32; 3]]) -> Result<(), RenderError> {
        if colors.len() != rig.vertex_count() {
            return Err(RenderError::SizeMismatch {
                what: "vertex colours vs vertices",
                got: colors.len(),
                expected: rig.vertex_count(),
            });
        }
        let data: Vec<[f32; 4]> = colors.iter().map(|c| [c[0], c[1], c[2], 1.0]).collect();
        self.queue
            .write_buffer(&rig.albedo, 0, bytemuck::cast_slice(&data));
        Ok(())
    }

    /// Uploads a rig: rest `positions`, the `triangles` to draw (counter-clockwise from outside;
    /// normals are recomputed from these), and the basis (`None`: a rig that only takes full positions).
    pub fn upload_rig(
        &self,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        basis: Option<&Basis>,
    ) -> Result<RigGpu, RenderError> {
        let n = positions.len();
        if let Some(b) = basis
            && b.vertex_count() != n
        {
            return Err(RenderError::SizeMismatch {
                what: "basis rows vs mesh vertices",
                got: b.vertex_count(),
                expected: n,
            });
        }
        let m = basis.map_or(0, Basis::control_count);
        if m > MAX_CONTROLS {
            return Err(RenderError::TooManyControls {
                got: m,
                max: MAX_CONTROLS,
            });
        }
        // Triangles around each vertex, in triangle order (the order the CPU sums them in).
        let mut count = vec![0u32; n + 1];
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                if v as usize >= n {
                    return Err(RenderError::BadIndex {
                        triangle: t,
                        vertex: v,
                        vertex_count: n,
                    });
                }
                count[v as usize + 1] += 1;
            }
        }
        for i in 0..n {
            count[i + 1] += count[i];
        }
        let first = count;
        let mut fill = first.clone();
        let mut incident = vec![0u32; first[n] as usize];
        for (t, tri) in triangles.iter().enumerate() {
            for &v in tri {
                let at = &mut fill[v as usize];
                incident[*at as usize] = t as u32;
                *at += 1;
            }
        }
        let flat: Vec<u32> = triangles.iter().flatten().copied().collect();
        let rest = vec4s(positions, 1.0);
        let basis_data: &[f32] = basis.map_or(&[], Basis::as_slice);

        let storage = wgpu::BufferUsages::STORAGE;
        let init = |label: &str, bytes: &[u8], usage: wgpu::BufferUsages| {
            // Zero-sized bindings are invalid: pad empty buffers to one word.
            let padded;
            let contents = if bytes.is_empty() {
                padded = [0u8; 16];
                &padded[..]
            } else {
                bytes
            };
            self.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage,
                })
        };
        let uniform = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        // One vec4 per control, written each frame (at least one, as empty bindings are invalid).
        let controls = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("controls"),
            size: 16 * m.max(1) as u64,
            usage: storage | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let rest_buf = init("rest", bytemuck::cast_slice(&rest), storage);
        let basis_buf = init("basis", bytemuck::cast_slice(basis_data), storage);
        let rw = storage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC;
        let positions_buf = init("positions", bytemuck::cast_slice(&rest), rw);
        let normals_buf = init("normals", bytemuck::cast_slice(&vec![[0f32; 4]; n]), rw);
        let indices = init(
            "indices",
            bytemuck::cast_slice(&flat),
            storage | wgpu::BufferUsages::INDEX,
        );
        let first_buf = init("first", bytemuck::cast_slice(&first), storage);
        let [r, g, b] = SKIN_ALBEDO;
        let albedo = init(
            "albedo",
            bytemuck::cast_slice(&vec![[r, g, b, 1.0]; n]),
            storage | wgpu::BufferUsages::COPY_DST,
        );
        let incident_buf = init("incident", bytemuck::cast_slice(&incident), storage);

        let group = |layout: &wgpu::BindGroupLayout, entries: &[(u32, &wgpu::Buffer)]| {
            let entries: Vec<wgpu::BindGroupEntry> = entries
                .iter()
                .map(|(binding, b)| wgpu::BindGroupEntry {
                    binding: *binding,
                    resource: b.as_entire_binding(),
                })
                .collect();
            self.device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: None,
                layout,
                entries: &entries,
            })
        };
        let morph_group = group(
            &self.morph.get_bind_group_layout(0),
            &[
                (0, &uniform),
                (1, &rest_buf),
                (2, &basis_buf),
                (3, &positions_buf),
                (9, &controls),
            ],
        );
        let normals_group = group(
            &self.normals.get_bind_group_layout(0),
            &[
                (4, &positions_buf),
                (5, &indices),
                (6, &first_buf),
                (7, &incident_buf),
                (8, &normals_buf),
            ],
        );
        let corners = init(
            "corners",
            bytemuck::cast_slice(&[[0f32, 0.0, -1.0, 0.0]]),
            storage,
        );
        let texture = self.texture_array(&[], 1, 1)?;
        let draw_group = self.draw_group(DrawBuffers {
            uniform: &uniform,
            rest: &rest_buf,
            basis: &basis_buf,
            positions: &positions_buf,
            normals: &normals_buf,
            triangles: &indices,
            albedo: &albedo,
            corners: &corners,
            texture: &texture,
        });
        Ok(RigGpu {
            vertex_count: n as u32,
            control_count: m as u32,
            index_count: flat.len() as u32,
            uniform,
            controls,
            positions: positions_buf,
            normals: normals_buf,
            morph_group,
            normals_group,
            draw_group,
            indices,
            albedo,
            rest: rest_buf,
            basis: basis_buf,
            corners,
            texture,
            textured: false,
        })
    }

    /// The draw pass's bind group over a rig's buffers and texture array.
    fn draw_group(&self, b: DrawBuffers<'_>) -> wgpu::BindGroup {
        fn buffer(binding: u32, buf: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
            wgpu::BindGroupEntry {
                binding,
                resource: buf.as_entire_binding(),
            }
        }
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("draw"),
            layout: &self.draw.get_bind_group_layout(0),
            entries: &[
                buffer(0, b.uniform),
                buffer(1, b.rest),
                buffer(2, b.basis),
                buffer(3, b.positions),
                buffer(4, b.normals),
                buffer(5, b.triangles),
                buffer(10, b.albedo),
                buffer(11, b.corners),
                wgpu::BindGroupEntry {
                    binding: 12,
                    resource: wgpu::BindingResource::TextureView(b.texture),
                },
                wgpu::BindGroupEntry {
                    binding: 13,
                    resource: wgpu::BindingResource::Sampler(&self.sampler),
                },
            ],
        })
    }

    /// A texture array of `images` (sRGB), all resampled to the largest width and height among
    /// them (within the device's limit) with full mip chains; `images` empty: one white
    /// `width x height` layer.
    fn texture_array(
        &self,
        images: &[&TextureImage],
        width: u32,
        height: u32,
    ) -> Result<wgpu::TextureView, RenderError> {
        let max = self.device.limits().max_texture_dimension_2d;
        let (w, h) = images.iter().fold((width, height), |(w, h), i| {
            (w.max(i.width).min(max), h.max(i.height).min(max))
        });
        for image in images {
            let want = image.width as usize * image.height as usize * 4;
            if image.rgba.len() != want || image.width == 0 || image.height == 0 {
                return Err(RenderError::SizeMismatch {
                    what: "texture bytes vs width x height x 4",
                    got: image.rgba.len(),
                    expected: want,
                });
            }
        }
        let layers = images.len().max(1) as u32;
        if layers > self.device.limits().max_texture_array_layers {
            return Err(RenderError::SizeMismatch {
                what: "textures vs the device's texture array layers",
                got: layers as usize,
                expected: self.device.limits().max_texture_array_layers as usize,
            });
        }
        let mips = crate::texture::mip_count(w, h);
        let texture = self.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("textures"),
            size: wgpu::Extent3d {
                width: w,
                height: h,
                depth_or_array_layers: layers,
            },
            mip_level_count: mips,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: wgpu::TextureFormat::Rgba8UnormSrgb,
            usage: wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_DST,
            view_formats: &[],
        });
        for layer in 0..layers {
            let mut level = match images.get(layer as usize) {
                Some(image) => Level::from_image(image).resized(w, h),
                None => Level {
                    width: w,
                    height: h,
                    pixels: vec![[1.0; 4]; (w * h) as usize],
                },
            };
            for mip in 0..mips {
                if mip > 0 {
                    level = level.half();
                }
                self.queue.write_texture(
                    wgpu::TexelCopyTextureInfo {
                        texture: &texture,
                        mip_level: mip,
                        origin: wgpu::Origin3d {
                            x: 0,
                            y: 0,
                            z: layer,
                        },
                        aspect: wgpu::TextureAspect::All,
                    },
                    &level.to_srgb8(),
                    wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(level.width * 4),
                        rows_per_image: Some(level.height),
                    },
                    wgpu::Extent3d {
                        width: level.width,
                        height: level.height,
                        depth_or_array_layers: 1,
                    },
                );
            }
        }
        Ok(texture.create_view(&wgpu::TextureViewDescriptor {
            dimension: Some(wgpu::TextureViewDimension::D2Array),
            ..Default::default()
        }))
    }

    /// Textures the rig: `textures.triangles` parallel to the triangles uploaded (a hidden
    /// triangle left out of the upload is left out here too, [`MeshTextures::kept`]). A textured
    /// triangle is drawn in its texture's colour (sampled trilinearly, sRGB decoded) times the
    /// light, instead of its vertices' albedo; an untextured one as before. Heat maps ignore it.
    pub fn set_textures(
        &self,
        rig: &mut RigGpu,
        textures: &MeshTextures,
    ) -> Result<(), RenderError> {
        if textures.triangles.len() != rig.triangle_count() {
            return Err(RenderError::SizeMismatch {
                what: "textured triangles vs triangles drawn",
                got: textures.triangles.len(),
                expected: rig.triangle_count(),
            });
        }
        let mut corners: Vec<[f32; 4]> = Vec::with_capacity(textures.triangles.len() * 3);
        for (t, tri) in textures.triangles.iter().enumerate() {
            match tri {
                Some(tt) => {
                    if tt.texture as usize >= textures.textures.len() {
                        return Err(RenderError::NoSuchTexture {
                            triangle: t,
                            texture: tt.texture,
                            count: textures.textures.len(),
                        });
                    }
                    for uv in tt.uv {
                        corners.push([uv[0], uv[1], tt.texture as f32, 0.0]);
                    }
                }
                None => corners.extend([[0.0, 0.0, -1.0, 0.0]; 3]),
            }
        }
        if corners.is_empty() {
            corners.push([0.0, 0.0, -1.0, 0.0]);
        }
        let images: Vec<&TextureImage> = textures.textures.iter().collect();
        let texture = self.texture_array(&images, 1, 1)?;
        let corners = self
            .device
            .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("corners"),
                contents: bytemuck::cast_slice(&corners),
                usage: wgpu::BufferUsages::STORAGE,
            });
        rig.draw_group = self.draw_group(DrawBuffers {
            uniform: &rig.uniform,
            rest: &rig.rest,
            basis: &rig.basis,
            positions: &rig.positions,
            normals: &rig.normals,
            triangles: &rig.indices,
            albedo: &rig.albedo,
            corners: &corners,
            texture: &texture,
        });
        rig.corners = corners;
        rig.texture = texture;
        rig.textured = !textures.textures.is_empty();
        Ok(())
    }

    fn uniform(&self, rig: &RigGpu, view: Option<&View>) -> Result<FrameUniform, RenderError> {
        let mut u = FrameUniform {
            view_proj: Mat4::IDENTITY.to_cols_array_2d(),
            model: Mat4::IDENTITY.to_cols_array_2d(),
            light: [0.0, 0.0, 1.0, 0.25],
            params: [1.0, 0.0, 0.0, 0.0],
            modes: [0, 0, rig.vertex_count, rig.control_count],
        };
        if let Some(view) = view {
            let aspect = self.width as f32 / self.height as f32;
            u.view_proj = view.camera.view_proj(aspect).to_cols_array_2d();
            u.model = view.model.to_cols_array_2d();
            // Light given in camera axes: turn it into world axes with the inverse view rotation.
            let look = Mat4::look_at_rh(view.camera.eye, view.camera.target, Vec3::Y);
            let light = look
                .inverse()
                .transform_vector3(view.light)
                .normalize_or_zero();
            u.light = [light.x, light.y, light.z, view.ambient.clamp(0.0, 1.0)];
            match view.shading {
                Shading::Lit => {}
                Shading::Displacement { full_scale } => {
                    u.modes[0] = 1;
                    u.params[0] = full_scale;
                }
                Shading::ControlWeight { control } => {
                    if control >= rig.control_count() {
                        return Err(RenderError::NoSuchControl {
                            control,
                            count: rig.control_count(),
                        });
                    }
                    u.modes[0] = 2;
                    u.modes[1] = control as u32;
                }
            }
        }
        Ok(u)
    }

    /// Runs the deformation on the GPU (morph and/or normals passes, or uploads of full positions)
    /// into the rig's position and normal buffers, with `view`'s uniform for a following draw.
    fn deform_into(
        &self,
        rig: &RigGpu,
        deform: Deform<'_>,
        view: Option<&View>,
        encoder: &mut wgpu::CommandEncoder,
    ) -> Result<(), RenderError> {
        let n = rig.vertex_count();
        let check = |what, got: usize, expected: usize| {
            if got == expected {
                Ok(())
            } else {
                Err(RenderError::SizeMismatch {
                    what,
                    got,
                    expected,
                })
            }
        };
        let (d, morph, normals): (&[Vec3], bool, bool) = match deform {
            Deform::Rest => (&[], true, true),
            Deform::Controls(d) => {
                check(
                    "control displacements vs basis columns",
                    d.len(),
                    rig.control_count(),
                )?;
                (d, true, true)
            }
            Deform::Positions { positions, normals } => {
                check("positions vs vertices", positions.len(), n)?;
                write_vec4s(&self.queue, &rig.positions, positions, 1.0);
                if let Some(nrm) = normals {
                    check("normals vs vertices", nrm.len(), n)?;
                    write_vec4s(&self.queue, &rig.normals, nrm, 0.0);
                }
                (&[], false, normals.is_none())
            }
        };
        let u = self.uniform(rig, view)?;
        self.queue
            .write_buffer(&rig.uniform, 0, bytemuck::bytes_of(&u));
        if morph {
            // Rest: zero displacements (the buffer may hold the last frame's).
            if d.is_empty() && rig.control_count() > 0 {
                if let Some(size) = wgpu::BufferSize::new((rig.control_count() * 16) as u64)
                    && let Some(mut view) = self.queue.write_buffer_with(&rig.controls, 0, size)
                {
                    view.slice(..).fill(0);
                }
            } else {
                write_vec4s(&self.queue, &rig.controls, d, 0.0);
            }
        }
        let groups = rig.vertex_count.div_ceil(WORKGROUP);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("deform"),
            timestamp_writes: None,
        });
        if morph {
            pass.set_pipeline(&self.morph);
            pass.set_bind_group(0, &rig.morph_group, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        if normals {
            pass.set_pipeline(&self.normals);
            pass.set_bind_group(0, &rig.normals_group, &[]);
            pass.dispatch_workgroups(groups, 1, 1);
        }
        Ok(())
    }

    /// Deforms the rig on the GPU without drawing (its positions and normals can then be read back).
    pub fn deform(&self, rig: &RigGpu, deform: Deform<'_>) -> Result<(), RenderError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.deform_into(rig, deform, None, &mut encoder)?;
        self.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Deforms the rig and renders it; returns the image (sRGB RGBA8).
    pub fn render(
        &self,
        rig: &RigGpu,
        deform: Deform<'_>,
        view: &View,
    ) -> Result<Image, RenderError> {
        self.render_with(rig, deform, view, None)
    }

    /// [`Renderer::render`] with `overlay` (text, legend, bars) composited over the mesh.
    pub fn render_with(
        &self,
        rig: &RigGpu,
        deform: Deform<'_>,
        view: &View,
        overlay: Option<&Overlay>,
    ) -> Result<Image, RenderError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.deform_into(rig, deform, Some(view), &mut encoder)?;
        self.draw_pass(rig, view, &self.resolve_view, &mut encoder);
        if let Some(o) = overlay {
            self.overlay.encode(
                &self.queue,
                o,
                self.size(),
                &self.resolve_view,
                &mut encoder,
            );
        }
        encoder.copy_texture_to_buffer(
            wgpu::TexelCopyTextureInfo {
                texture: &self.resolve,
                mip_level: 0,
                origin: wgpu::Origin3d::ZERO,
                aspect: wgpu::TextureAspect::All,
            },
            wgpu::TexelCopyBufferInfo {
                buffer: &self.readback,
                layout: wgpu::TexelCopyBufferLayout {
                    offset: 0,
                    bytes_per_row: Some(self.padded_row),
                    rows_per_image: Some(self.height),
                },
            },
            wgpu::Extent3d {
                width: self.width,
                height: self.height,
                depth_or_array_layers: 1,
            },
        );
        self.queue.submit([encoder.finish()]);
        let bytes = self.map_read(&self.readback)?;
        let row = self.width as usize * 4;
        let mut rgba = Vec::with_capacity(row * self.height as usize);
        for r in bytes
            .chunks(self.padded_row as usize)
            .take(self.height as usize)
        {
            rgba.extend_from_slice(&r[..row]);
        }
        if matches!(
            self.format,
            wgpu::TextureFormat::Bgra8Unorm | wgpu::TextureFormat::Bgra8UnormSrgb
        ) {
            rgba.chunks_exact_mut(4).for_each(|p| p.swap(0, 2));
        }
        Ok(Image {
            width: self.width,
            height: self.height,
            rgba,
        })
    }

    /// Deforms the rig and draws it into `target` (a view of a texture in [`Renderer::format`] and
    /// of [`Renderer::size`], e.g. a window's surface texture); submits and returns without waiting.
    pub fn draw_to(
        &self,
        rig: &RigGpu,
        deform: Deform<'_>,
        view: &View,
        target: &wgpu::TextureView,
    ) -> Result<(), RenderError> {
        self.draw_to_with(rig, deform, view, target, None)
    }

    /// [`Renderer::draw_to`] with `overlay` composited over the mesh.
    pub fn draw_to_with(
        &self,
        rig: &RigGpu,
        deform: Deform<'_>,
        view: &View,
        target: &wgpu::TextureView,
        overlay: Option<&Overlay>,
    ) -> Result<(), RenderError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        self.deform_into(rig, deform, Some(view), &mut encoder)?;
        self.draw_pass(rig, view, target, &mut encoder);
        if let Some(o) = overlay {
            self.overlay
                .encode(&self.queue, o, self.size(), target, &mut encoder);
        }
        self.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Clears `target` (a view like [`Renderer::draw_to`]'s) to the lit view's background and
    /// submits: what a window shows while it has nothing to draw.
    pub fn clear_to(&self, target: &wgpu::TextureView) -> Result<(), RenderError> {
        self.clear_to_with(target, None)
    }

    /// [`Renderer::clear_to`] with `overlay` drawn on the background (e.g. a waiting message).
    pub fn clear_to_with(
        &self,
        target: &wgpu::TextureView,
        overlay: Option<&Overlay>,
    ) -> Result<(), RenderError> {
        let [r, g, b, a] = View::lit(Camera::front(Vec3::ZERO, Vec3::ONE)).background;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("clear"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        if let Some(o) = overlay {
            self.overlay
                .encode(&self.queue, o, self.size(), target, &mut encoder);
        }
        self.queue.submit([encoder.finish()]);
        Ok(())
    }

    /// Encodes the draw of the deformed rig into the multisampled target, resolved into `target`.
    fn draw_pass(
        &self,
        rig: &RigGpu,
        view: &View,
        target: &wgpu::TextureView,
        encoder: &mut wgpu::CommandEncoder,
    ) {
        let [r, g, b, a] = view.background;
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("draw"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &self.color,
                depth_slice: None,
                resolve_target: Some(target),
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color { r, g, b, a }),
                    store: wgpu::StoreOp::Discard,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &self.depth,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(1.0),
                    store: wgpu::StoreOp::Discard,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.draw);
        pass.set_bind_group(0, &rig.draw_group, &[]);
        // Not indexed: the vertex shader reads corner c's vertex from the triangles and its
        // texture coordinate from the corners (UV seams need no split vertices).
        pass.draw(0..rig.index_count, 0..1);
    }

    /// The rig's current GPU positions (after [`Renderer::deform`] or [`Renderer::render`]).
    pub fn read_positions(&self, rig: &RigGpu) -> Result<Vec<Vec3>, RenderError> {
        self.read_vec4s(&rig.positions, rig.vertex_count())
    }

    /// The rig's current GPU normals (after [`Renderer::deform`] or [`Renderer::render`]).
    pub fn read_normals(&self, rig: &RigGpu) -> Result<Vec<Vec3>, RenderError> {
        self.read_vec4s(&rig.normals, rig.vertex_count())
    }

    fn read_vec4s(&self, src: &wgpu::Buffer, n: usize) -> Result<Vec<Vec3>, RenderError> {
        let size = src.size();
        let staging = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("staging"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(src, 0, &staging, 0, size);
        self.queue.submit([encoder.finish()]);
        let bytes = self.map_read(&staging)?;
        let floats: &[f32] =
            bytemuck::try_cast_slice(&bytes).map_err(|e| RenderError::Readback(e.to_string()))?;
        Ok(floats
            .chunks_exact(4)
            .take(n)
            .map(|c| Vec3::new(c[0], c[1], c[2]))
            .collect())
    }

    /// Waits for the queue, maps `buffer` and copies it out.
    fn map_read(&self, buffer: &wgpu::Buffer) -> Result<Vec<u8>, RenderError> {
        let (tx, rx) = mpsc::sync_channel(1);
        buffer.map_async(wgpu::MapMode::Read, .., move |r| {
            // The receiver outlives the poll below; a failed send only means it is gone.
            let _ = tx.send(r);
        });
        self.device
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
}

/// The size-dependent textures: multisampled colour and depth, the resolve image and its readback.
struct Targets {
    color: wgpu::TextureView,
    resolve: wgpu::Texture,
    resolve_view: wgpu::TextureView,
    depth: wgpu::TextureView,
    readback: wgpu::Buffer,
    padded_row: u32,
}

impl Targets {
    fn new(device: &wgpu::Device, width: u32, height: u32, format: wgpu::TextureFormat) -> Self {
        let target = |label, format, samples, usage| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d {
                    width,
                    height,
                    depth_or_array_layers: 1,
                },
                mip_level_count: 1,
                sample_count: samples,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage,
                view_formats: &[],
            })
        };
        let color = target(
            "color",
            format,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&Default::default());
        let resolve = target(
            "resolve",
            format,
            1,
            wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
        );
        let resolve_view = resolve.create_view(&Default::default());
        let depth = target(
            "depth",
            DEPTH_FORMAT,
            SAMPLES,
            wgpu::TextureUsages::RENDER_ATTACHMENT,
        )
        .create_view(&Default::default());
        let align = wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
        let padded_row = (width * 4).div_ceil(align) * align;
        let readback = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("readback"),
            size: u64::from(padded_row) * u64::from(height),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Self {
            color,
            resolve,
            resolve_view,
            depth,
            readback,
            padded_row,
        }
    }
}
