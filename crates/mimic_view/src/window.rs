//! The window: winit 0.30's event loop, a wgpu surface on it, input into the [`Viewer`].

use crate::ViewError;
use crate::keys::action_for;
use crate::viewer::Viewer;
use mimic_render::Renderer;
use std::sync::Arc;
use std::time::{Duration, Instant};
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{ElementState, MouseButton, MouseScrollDelta, WindowEvent};
use winit::event_loop::{ActiveEventLoop, ControlFlow, EventLoop};
use winit::window::{Window, WindowId};

/// Pixels of a pixel-delta wheel event that count as one line.
const PIXELS_PER_LINE: f32 = 40.0;
/// Redraw interval while there is nothing to show (waiting for a live session): 10 per second,
/// not as fast as the loop spins.
pub const IDLE_REDRAW: Duration = Duration::from_millis(100);

/// The window and what draws into it.
struct Gpu {
    window: Arc<Window>,
    surface: wgpu::Surface<'static>,
    config: wgpu::SurfaceConfiguration,
    renderer: Renderer,
}

impl Gpu {
    fn resize(&mut self, size: PhysicalSize<u32>) {
        if size.width == 0 || size.height == 0 {
            return;
        }
        self.config.width = size.width;
        self.config.height = size.height;
        self.surface.configure(self.renderer.device(), &self.config);
        self.renderer.resize(size.width, size.height);
    }
}

struct App {
    viewer: Viewer,
    size: (u32, u32),
    gpu: Option<Gpu>,
    error: Option<ViewError>,
    cursor: Option<(f64, f64)>,
    orbiting: bool,
    scrubbing: bool,
    print_readout: bool,
    /// When the last idle redraw was requested.
    idle_since: Option<Instant>,
    /// The note last printed to stderr (waiting, the server gone).
    said: String,
}

impl App {
    fn fail(&mut self, event_loop: &ActiveEventLoop, e: ViewError) {
        self.error = Some(e);
        event_loop.exit();
    }

    fn open(&mut self, event_loop: &ActiveEventLoop) -> Result<Gpu, ViewError> {
        let attributes = Window::default_attributes()
            .with_title("mimic view")
            .with_inner_size(PhysicalSize::new(self.size.0, self.size.1));
        let window = Arc::new(
            event_loop
                .create_window(attributes)
                .map_err(|e| ViewError::Window(e.to_string()))?,
        );
        let instance =
            wgpu::Instance::new(wgpu::InstanceDescriptor::new_with_display_handle_from_env(
                Box::new(event_loop.owned_display_handle()),
            ));
        let surface = instance
            .create_surface(window.clone())
            .map_err(|e| ViewError::Surface(e.to_string()))?;
        let size = window.inner_size();
        let (renderer, config) =
            Renderer::for_surface(&instance, &surface, size.width, size.height)?;
        eprintln!("mimic view: adapter {}", renderer.adapter());
        Ok(Gpu {
            window,
            surface,
            config,
            renderer,
        })
    }

    fn redraw(&mut self) -> Result<(), ViewError> {
        let Some(gpu) = &mut self.gpu else {
            return Ok(());
        };
        self.viewer.update(Instant::now(), &gpu.renderer)?;
        let texture = match gpu.surface.get_current_texture() {
            wgpu::CurrentSurfaceTexture::Success(t)
            | wgpu::CurrentSurfaceTexture::Suboptimal(t) => t,
            wgpu::CurrentSurfaceTexture::Timeout | wgpu::CurrentSurfaceTexture::Occluded => {
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Outdated | wgpu::CurrentSurfaceTexture::Lost => {
                let size = gpu.window.inner_size();
                gpu.resize(size);
                return Ok(());
            }
            wgpu::CurrentSurfaceTexture::Validation => {
                return Err(ViewError::Surface(
                    "validation error acquiring a frame".into(),
                ));
            }
        };
        let target = texture.texture.create_view(&wgpu::TextureViewDescriptor {
            format: Some(gpu.renderer.format()),
            ..Default::default()
        });
        let (w, h) = gpu.renderer.size();
        self.viewer.build_overlay((w, h));
        if let Some((rig, deform, view)) = self.viewer.scene(w as f32 / h as f32) {
            let overlay = Some(self.viewer.overlay());
            gpu.renderer
                .draw_to_with(rig, deform, &view, &target, overlay)?;
        } else {
            // Nothing to draw yet: the background with the note (waiting for session X on ADDR)
            // in the middle, and in the title and on stderr, once per change.
            gpu.renderer
                .clear_to_with(&target, Some(self.viewer.overlay()))?;
            let title = self.viewer.title().to_string();
            gpu.window.set_title(&title);
        }
        if self.viewer.note() != self.said {
            self.said = self.viewer.note().to_string();
            if !self.said.is_empty() {
                eprintln!("mimic view: {}", self.said);
            }
        }
        gpu.window.pre_present_notify();
        gpu.renderer.present(texture);
        if let Some(title) = self.viewer.presented() {
            gpu.window.set_title(title);
            if self.print_readout {
                eprintln!("{title}");
            }
        }
        Ok(())
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gpu.is_some() {
            return;
        }
        match self.open(event_loop) {
            Ok(gpu) => self.gpu = Some(gpu),
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(gpu) = &mut self.gpu {
                    gpu.resize(size);
                }
            }
            WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed => {
                if let Some(action) = action_for(&event.logical_key)
                    && let Err(e) = self.viewer.action(action)
                {
                    self.fail(event_loop, e);
                    return;
                }
                if self.viewer.should_quit() {
                    event_loop.exit();
                }
            }
            WindowEvent::MouseInput { state, button, .. } => {
                let down = state == ElementState::Pressed;
                match button {
                    MouseButton::Left => self.orbiting = down,
                    MouseButton::Right => self.scrubbing = down,
                    _ => {}
                }
            }
            WindowEvent::CursorMoved { position, .. } => {
                let (x, y) = (position.x, position.y);
                if let Some((px, py)) = self.cursor
                    && self.orbiting
                {
                    self.viewer.orbit.drag((x - px) as f32, (y - py) as f32);
                }
                if self.scrubbing
                    && let Some(gpu) = &self.gpu
                {
                    let width = f64::from(gpu.window.inner_size().width.max(1));
                    self.viewer.scrub_to(x / width);
                }
                self.cursor = Some((x, y));
            }
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseWheel { delta, .. } => {
                let lines = match delta {
                    MouseScrollDelta::LineDelta(_, y) => y,
                    MouseScrollDelta::PixelDelta(p) => p.y as f32 / PIXELS_PER_LINE,
                };
                self.viewer.orbit.wheel(lines);
            }
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw() {
                    self.fail(event_loop, e);
                }
            }
            _ => {}
        }
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        // The server went away: say so (the note, printed by the last redraw) and exit cleanly.
        if self.viewer.closed() {
            if self.viewer.note() != self.said {
                eprintln!("mimic view: {}", self.viewer.note());
            }
            event_loop.exit();
            return;
        }
        let Some(gpu) = &self.gpu else { return };
        if self.viewer.idle() {
            // Waiting: redraw at IDLE_REDRAW, sleeping in between.
            let now = Instant::now();
            let due = self.idle_since.map_or(now, |t| t + IDLE_REDRAW);
            if now >= due {
                self.idle_since = Some(now);
                gpu.window.request_redraw();
                event_loop.set_control_flow(ControlFlow::WaitUntil(now + IDLE_REDRAW));
            } else {
                event_loop.set_control_flow(ControlFlow::WaitUntil(due));
            }
            return;
        }
        // Draw continuously; the surface's vsync paces the loop.
        self.idle_since = None;
        event_loop.set_control_flow(ControlFlow::Poll);
        gpu.window.request_redraw();
    }
}

/// Opens a `width x height` window and runs the viewer in it until it is closed; with
/// `print_readout` the title line also goes to stderr at each refresh.
pub fn run_window(
    viewer: Viewer,
    width: u32,
    height: u32,
    print_readout: bool,
) -> Result<(), ViewError> {
    let event_loop = EventLoop::new().map_err(|e| ViewError::Window(e.to_string()))?;
    event_loop.set_control_flow(ControlFlow::Poll);
    let mut app = App {
        viewer,
        size: (width.max(64), height.max(64)),
        gpu: None,
        error: None,
        cursor: None,
        orbiting: false,
        scrubbing: false,
        print_readout,
        idle_since: None,
        said: String::new(),
    };
    event_loop
        .run_app(&mut app)
        .map_err(|e| ViewError::Window(e.to_string()))?;
    match app.error {
        Some(e) => Err(e),
        None => Ok(()),
    }
}
