//! `mimic_view`: the window of `mimic view`, replaying a recording through the retargeter or
//! following a live `mimic serve` session, drawn with `mimic_render`'s GPU morph.
//!
//! The logic that needs no window lives in plain modules with unit tests: the orbit camera
//! ([`orbit`]), the playback clock ([`playback`]), key bindings ([`keys`]), the fps and latency
//! readout ([`readout`]) and what is drawn over the head ([`hud`]), the newest-wins frame queue ([`latest`]), the live client ([`client`])
//! and the viewer state ([`viewer`]). [`window`] is the winit event loop around it, and
//! [`headless`] the same loop into an offscreen target (`mimic view --headless-frames N`).
//! [`stills`] draws chosen frames of a replay to images (`mimic render`).

pub mod client;
mod error;
pub mod expressions;
pub mod headless;
pub mod hud;
pub mod keys;
pub mod latest;
pub mod look;
pub mod orbit;
pub mod playback;
pub mod readout;
pub mod stills;
pub mod viewer;
pub mod window;

pub use error::ViewError;
pub use headless::{HeadlessReport, run_headless};
pub use keys::{Action, HELP};
pub use look::{Look, LookFor, load_look, upload_with_look};
pub use viewer::{LocalSetup, Options, Viewer};
pub use window::run_window;
