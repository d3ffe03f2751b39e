//! The overlay's GPU pass: one instanced draw of [`Quad`]s (six vertices each) over the resolved
//! image, alpha-blended, no depth; the quads go up per frame into a buffer sized for
//! [`MAX_QUADS`], so drawing an overlay allocates no GPU memory.

use super::{MAX_QUADS, Overlay, Quad};

/// Pipeline, quad buffer and screen-size uniform of the overlay pass.
pub(crate) struct OverlayPass {
    pipeline: wgpu::RenderPipeline,
    quads: wgpu::Buffer,
    screen: wgpu::Buffer,
    group: wgpu::BindGroup,
}

impl OverlayPass {
    /// The pass for targets of `format`.
    pub(crate) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Self {
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("overlay.wgsl"),
            source: wgpu::ShaderSource::Wgsl(
                concat!(
                    include_str!("../shaders/ramp.wgsl"),
                    include_str!("../shaders/overlay.wgsl")
                )
                .into(),
            ),
        });
        let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some("overlay"),
            layout: None,
            vertex: wgpu::VertexState {
                module: &module,
                entry_point: Some("vs_overlay"),
                compilation_options: Default::default(),
                buffers: &[],
            },
            primitive: wgpu::PrimitiveState::default(),
            depth_stencil: None,
            multisample: wgpu::MultisampleState::default(),
            fragment: Some(wgpu::FragmentState {
                module: &module,
                entry_point: Some("fs_overlay"),
                compilation_options: Default::default(),
                targets: &[Some(wgpu::ColorTargetState {
                    format,
                    // Colour: src * a + dst * (1 - a); alpha: a + dst * (1 - a), so an opaque
                    // image stays opaque.
                    blend: Some(wgpu::BlendState {
                        color: wgpu::BlendComponent {
                            src_factor: wgpu::BlendFactor::SrcAlpha,
                            dst_factor: wgpu::BlendFactor::OneMinusSrcAlpha,
                            operation: wgpu::BlendOperation::Add,
                        },
                        alpha: wgpu::BlendComponent::OVER,
                    }),
                    write_mask: wgpu::ColorWrites::ALL,
                })],
            }),
            multiview_mask: None,
            cache: None,
        });
        let quads = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("overlay quads"),
            size: (MAX_QUADS * std::mem::size_of::<Quad>()) as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let screen = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("overlay screen"),
            size: 16,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("overlay"),
            layout: &pipeline.get_bind_group_layout(0),
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: quads.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: screen.as_entire_binding(),
                },
            ],
        });
        Self {
            pipeline,
            quads,
            screen,
            group,
        }
    }

    /// Uploads `overlay`'s quads and encodes their draw over `target` (`width x height`); nothing
    /// for an empty overlay.
    pub(crate) fn encode(
        &self,
        queue: &wgpu::Queue,
        overlay: &Overlay,
        size: (u32, u32),
        target: &wgpu::TextureView,
        encoder: &mut wgpu::CommandEncoder,
    ) {
        let quads = overlay.quads();
        if quads.is_empty() {
            return;
        }
        queue.write_buffer(&self.quads, 0, bytemuck::cast_slice(quads));
        let screen = [size.0 as f32, size.1 as f32, 0.0, 0.0];
        queue.write_buffer(&self.screen, 0, bytemuck::cast_slice(&screen));
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("overlay"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.group, &[]);
        pass.draw(0..6, 0..quads.len() as u32);
    }
}
