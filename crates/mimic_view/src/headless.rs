//! `mimic view --headless-frames N`: the window's loop into an offscreen target, for tests and
//! machines without a display. Local replays run on a simulated clock (one frame interval per
//! iteration), so a run is reproducible; a live feed draws as frames arrive.

use crate::ViewError;
use crate::keys::Action;
use crate::viewer::Viewer;
use mimic_render::{Image, Renderer};
use std::time::{Duration, Instant};

/// What a headless run did.
#[derive(Debug)]
pub struct HeadlessReport {
    /// Images drawn.
    pub drawn: usize,
    /// Frames with new data among them.
    pub new_frames: u64,
    /// Frame shown last (local: index in the recording; live: `seq`).
    pub last_frame: u64,
    /// Solver shown last.
    pub solver: &'static str,
    /// The last image, if any was drawn.
    pub image: Option<Image>,
    /// The title the window would show at the end.
    pub title: String,
}

impl HeadlessReport {
    /// The two lines `mimic view --headless-frames` ends with: the counts, then the title.
    pub fn summary(&self) -> String {
        format!(
            "mimic view: {} images, {} new frames, last frame {}, solver {}\n{}",
            self.drawn, self.new_frames, self.last_frame, self.solver, self.title
        )
    }
}

/// Runs the viewer's loop for `frames` images (local), or until `frames` live frames were drawn or
/// the connection closed (live, polling every `poll`): at iteration k (from 1) the k-th of `keys`
/// is applied first. `step` is the simulated time between iterations of a local replay; a live
/// run also stops after `give_up` of wall time. With [`crate::Options::headless_overlay`] the
/// images carry what the window draws over the head (readout, legend, weights, help; [`crate::hud`]).
pub fn run_headless(
    viewer: &mut Viewer,
    renderer: &Renderer,
    frames: usize,
    keys: &[Action],
    step: Duration,
    live: bool,
    give_up: Duration,
) -> Result<HeadlessReport, ViewError> {
    let overlay = viewer.headless_overlay();
    let (w, h) = renderer.size();
    let aspect = w as f32 / h as f32;
    let start = Instant::now();
    let mut image = None;
    let mut drawn = 0usize;
    let mut k = 0usize;
    loop {
        if live {
            if viewer.new_frames() >= frames as u64 || viewer.closed() || start.elapsed() > give_up
            {
                break;
            }
        } else if drawn >= frames {
            break;
        }
        if k >= 1
            && let Some(a) = keys.get(k - 1)
        {
            viewer.action(*a)?;
        }
        if viewer.should_quit() {
            break;
        }
        let now = if live {
            Instant::now()
        } else {
            start + step * k as u32
        };
        let before = viewer.new_frames();
        viewer.update(now, renderer)?;
        k += 1;
        if live && viewer.new_frames() == before {
            std::thread::sleep(Duration::from_millis(2));
            continue;
        }
        if overlay {
            viewer.build_overlay((w, h));
        }
        if let Some((rig, deform, view)) = viewer.scene(aspect) {
            let drawn_over = overlay.then(|| viewer.overlay());
            image = Some(renderer.render_with(rig, deform, &view, drawn_over)?);
            drawn += 1;
            viewer.presented();
        }
    }
    Ok(HeadlessReport {
        drawn,
        new_frames: viewer.new_frames(),
        last_frame: viewer.shown_frame(),
        solver: viewer.solver(),
        image,
        title: viewer.title().to_string(),
    })
}
