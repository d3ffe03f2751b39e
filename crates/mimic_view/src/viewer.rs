//! What the window shows, apart from the window: a local replay through the retargeter or a live
//! feed, the camera, the toggles, and the readout. The window ([`crate::window`]) and the
//! headless loop ([`crate::headless`]) drive the same [`Viewer`].

use crate::ViewError;
use crate::client::{Event, Live};
use crate::expressions::{Expressions, extend_basis};
use crate::hud::{Hud, HudState, status_label};
use crate::keys::Action;
use crate::look::{Look, LookFor, upload_with_look};
use crate::orbit::Orbit;
use crate::playback::Playback;
use crate::readout::{Readout, Status, write_title};
use glam::{Mat4, Quat, Vec3};
use mimic_render::{Deform, Overlay, Renderer, RigGpu, Shading, View};
use mimic_retarget::{FrameLoop, RetargetSettings, Retargeter};
use mimic_solve::{Basis, build_basis};
use mimic_types::{LandmarkFrame, Layout, MorphTarget, Rig, SolverKind, SolverSettings};
use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Options shared by both sources.
#[derive(Clone, Copy, Debug, Default)]
pub struct Options {
    /// Start with the head turned by the performer's head rotation.
    pub pose: bool,
    /// Start with the heat map on.
    pub heat: bool,
    /// Displacement shown hottest, rig units (default: 5% of the rig's diagonal).
    pub heat_scale: Option<f32>,
    /// Build the other solver's basis in the foreground when toggled (headless runs: reproducible).
    pub blocking_builds: bool,
    /// Headless images carry the overlay too (the window always draws it).
    pub headless_overlay: bool,
}

/// A local replay: recording frames, the rig and one retargeter per solver.
pub struct LocalSetup {
    /// The rig.
    pub rig: Rig,
    /// The source layout.
    pub layout: Layout,
    /// Pipeline settings.
    pub settings: RetargetSettings,
    /// The solver to start with and its basis, already built.
    pub first: (SolverSettings, Basis),
    /// The solver the `s` key switches to (built on first use).
    pub other: SolverSettings,
    /// The recording's accepted frames.
    pub frames: Vec<LandmarkFrame>,
    /// Colours and hidden parts.
    pub look: Look,
    /// The rig's morph targets: the first nine go on the number keys (may be empty).
    pub expressions: Vec<MorphTarget>,
}

impl LocalSetup {
    /// The solver the `s` key switches to from `first`: the RBF and the Laplacian swap, the
    /// thin shell goes to the RBF.
    pub fn other_solver(first: &SolverSettings) -> SolverSettings {
        let mut other = *first;
        other.kind = match first.kind {
            SolverKind::Rbf => SolverKind::Laplacian,
            SolverKind::Laplacian | SolverKind::Shell => SolverKind::Rbf,
        };
        other
    }
}

/// One solver of a local replay: its retargeter, its GPU rig and what it computed so far.
struct Slot {
    settings: SolverSettings,
    /// The frame loop (its retargeter), once the basis is built.
    frames: Option<FrameLoop>,
    building: Option<mpsc::Receiver<Result<Retargeter, String>>>,
    gpu: Option<RigGpu>,
    /// `d` of every frame stepped so far, frame-major (`frames x m`).
    history: Vec<Vec3>,
    rotations: Vec<Quat>,
    /// Each stepped frame's state: its FRAME status byte, or 4 for a frame the gate held.
    states: Vec<u8>,
    stepped: usize,
}

impl Slot {
    fn new(settings: SolverSettings) -> Self {
        Self {
            settings,
            frames: None,
            building: None,
            gpu: None,
            history: Vec::new(),
            rotations: Vec::new(),
            states: Vec::new(),
            stepped: 0,
        }
    }

    fn ready(&mut self, retargeter: Retargeter, frames: usize) {
        let m = retargeter.basis().control_count();

        self.history = vec![Vec3::ZERO; frames * m];
        self.rotations = vec![Quat::IDENTITY; frames];
        self.states = vec![0; frames];
        self.frames = Some(FrameLoop::landmarks(retargeter, None).untimed());
    }

    /// Steps the pipeline through `frame` (the filters and the neutral need every frame before
    /// it); returns true if it stepped.
    fn ensure(&mut self, frame: usize, frames: &[LandmarkFrame]) -> bool {
        let Some(fl) = self.frames.as_mut() else {
            return false;
        };
        let Some(m) = fl.retargeter().map(|r| r.basis().control_count()) else {
            return false;
        };
        let stepped = self.stepped <= frame;
        while self.stepped <= frame && self.stepped < frames.len() {
            let k = self.stepped;
            // No outputs are added, so the step cannot fail.
            let _ = fl.step(&frames[k], None);
            let out = fl.output();
            self.history[k * m..(k + 1) * m].copy_from_slice(&out.displacements);
            self.rotations[k] = out.target_rotation;
            let gated = out.status == mimic_retarget::FrameStatus::Tracked
                && fl
                    .retargeter()
                    .is_some_and(|r| r.gate_reading().reason.is_some());
            self.states[k] = if gated {
                4
            } else {
                mimic_wire::status_byte(out.status)
            };
            self.stepped += 1;
        }
        stepped
    }
}

struct Local {
    rig: Rig,
    layout: Layout,
    settings: RetargetSettings,
    frames: Vec<LandmarkFrame>,
    look: Look,
    /// The morph targets on the number keys (their deltas become extra basis columns).
    targets: Vec<MorphTarget>,
    slots: [Slot; 2],
    active: usize,
    clock: Playback,
    blocking: bool,
}

struct LiveRig {
    name: String,
    gpu: RigGpu,
    lo: Vec3,
    hi: Vec3,
    controls: usize,
}

struct LiveState {
    live: Live,
    session: String,
    look_for: LookFor,
    rig: Option<LiveRig>,
    closed: bool,
}

enum Source {
    Local(Box<Local>),
    Live(Box<LiveState>),
}

/// The viewer's state: source, shown frame, camera, toggles, readout.
pub struct Viewer {
    source: Source,
    /// The camera (mouse drags and the wheel move it).
    pub orbit: Orbit,
    heat: bool,
    pose: bool,
    heat_scale: Option<f32>,
    headless_overlay: bool,
    playing: bool,
    bounds: (Vec3, Vec3),
    shown_d: Vec<Vec3>,
    /// `shown_d` and three displacements per expression on a key: what the GPU morphs.
    drawn_d: Vec<Vec3>,
    expressions: Expressions,
    shown_rotation: Quat,
    shown_frame: u64,
    /// When the shown data became ready (stepped, or read off the socket), until presented.
    fresh_since: Option<Instant>,
    new_frames: u64,
    last_tick: Option<Instant>,
    readout: Readout,
    title: String,
    note: String,
    quit: bool,
    /// The shown data must be refreshed even if the frame did not change (solver switched).
    dirty: bool,
    /// What is drawn over the head, and its toggles.
    hud: Hud,
    /// The shown frame's state, for the readout.
    state: Option<&'static str>,
    /// The rig's length unit (the legend's labels).
    units: String,
    /// Morph targets whose weights are known (the number keys', or a weights session's).
    weight_names: Vec<String>,
    /// Their weights now.
    weights: Vec<f32>,
}

fn bounds_of(points: &[Vec3]) -> (Vec3, Vec3) {
    let lo = points
        .iter()
        .copied()
        .fold(Vec3::splat(f32::MAX), Vec3::min);
    let hi = points
        .iter()
        .copied()
        .fold(Vec3::splat(f32::MIN), Vec3::max);
    if lo.x > hi.x {
        (Vec3::splat(-1.0), Vec3::splat(1.0))
    } else {
        (lo, hi)
    }
}

impl Viewer {
    fn with_source(source: Source, bounds: (Vec3, Vec3), options: Options) -> Self {
        Self {
            source,
            orbit: Orbit::default(),
            heat: options.heat,
            pose: options.pose,
            heat_scale: options.heat_scale,
            headless_overlay: options.headless_overlay,
            playing: true,
            bounds,
            shown_d: Vec::new(),
            drawn_d: Vec::new(),
            expressions: Expressions::default(),
            shown_rotation: Quat::IDENTITY,
            shown_frame: 0,
            fresh_since: None,
            new_frames: 0,
            last_tick: None,
            readout: Readout::new(),
            title: String::new(),
            note: String::new(),
            quit: false,
            dirty: true,
            hud: Hud::new(),
            state: None,
            units: String::new(),
            weight_names: Vec::new(),
            weights: Vec::new(),
        }
    }

    /// A local replay of `setup.frames` at their recorded pace.
    pub fn local(mut setup: LocalSetup, options: Options) -> Result<Self, ViewError> {
        if setup.frames.is_empty() {
            return Err(ViewError::NoFrames);
        }
        let (first_settings, basis) = setup.first;
        let retargeter = Retargeter::new(&setup.rig, &setup.layout, basis, setup.settings.clone())
            .map_err(|e| ViewError::Solver(e.to_string()))?;
        let mut first = Slot::new(first_settings);
        first.ready(retargeter, setup.frames.len());
        let times: Vec<i64> = setup.frames.iter().map(|f| f.timestamp_us).collect();
        let bounds = bounds_of(&setup.rig.mesh.positions);
        let n = setup.rig.mesh.vertex_count();
        setup.expressions.retain(|t| t.vertex_count() == n);
        setup.expressions.truncate(crate::expressions::MAX_KEYS);
        let names: Vec<String> = setup.expressions.iter().map(|t| t.name.clone()).collect();
        let units = setup.rig.units.clone();
        let local = Local {
            clock: Playback::new(&times),
            slots: [first, Slot::new(setup.other)],
            active: 0,
            rig: setup.rig,
            layout: setup.layout,
            settings: setup.settings,
            frames: setup.frames,
            look: setup.look,
            targets: setup.expressions,
            blocking: options.blocking_builds,
        };
        let mut viewer = Self::with_source(Source::Local(Box::new(local)), bounds, options);
        viewer.expressions = Expressions::new(names);
        viewer.weight_names = viewer.expressions.names().to_vec();
        viewer.weights = vec![0.0; viewer.weight_names.len()];
        viewer.units = units;
        Ok(viewer)
    }

    /// A live feed from [`crate::client::connect`].
    pub fn live(live: Live, session: &str, look_for: LookFor, options: Options) -> Self {
        let state = LiveState {
            live,
            session: session.to_string(),
            look_for,
            rig: None,
            closed: false,
        };
        let mut v = Self::with_source(
            Source::Live(Box::new(state)),
            (Vec3::splat(-1.0), Vec3::splat(1.0)),
            options,
        );
        v.note = format!("waiting for session {session}");
        v
    }

    /// A viewer following `session` of the `mimic serve` at `addr` (with `token`, if any):
    /// [`crate::client::connect`], then [`Viewer::live`] waiting for the session there.
    pub fn connect(
        addr: &str,
        session: &str,
        token: Option<&str>,
        look_for: LookFor,
        options: Options,
    ) -> Result<Self, ViewError> {
        let live =
            crate::client::connect(addr, session, token).map_err(|cause| ViewError::Connect {
                addr: addr.to_string(),
                cause,
            })?;
        Ok(Self::live(live, session, look_for, options).with_address(addr))
    }

    /// The waiting note with the server's address: `waiting for session X on ADDR`.
    pub fn with_address(mut self, addr: &str) -> Self {
        if let Source::Live(s) = &self.source {
            self.note = format!("waiting for session {} on {addr}", s.session);
        }
        self
    }

    /// True while there is nothing to draw: a live viewer before its session's rig came (or
    /// after its connection closed). The window redraws slowly then.
    pub fn idle(&self) -> bool {
        matches!(&self.source, Source::Live(s) if s.rig.is_none() || s.closed)
    }

    /// True once the user asked to quit.
    pub fn should_quit(&self) -> bool {
        self.quit
    }

    /// Frames with new data shown so far (stepped locally, or received live).
    pub fn new_frames(&self) -> u64 {
        self.new_frames
    }

    /// Index of the frame shown (local: in the recording; live: the session's `seq`).
    pub fn shown_frame(&self) -> u64 {
        self.shown_frame
    }

    /// The control displacements `d` shown.
    pub fn shown_displacements(&self) -> &[Vec3] {
        &self.shown_d
    }

    /// The solver shown (`live` for a live feed).
    pub fn solver(&self) -> &'static str {
        match &self.source {
            Source::Local(l) => l.slots[l.active].settings.kind.name(),
            Source::Live(_) => "live",
        }
    }

    /// True when the heat map is on.
    pub fn heat(&self) -> bool {
        self.heat
    }

    /// The note shown in the title (waiting, session ended, errors).
    pub fn note(&self) -> &str {
        &self.note
    }

    /// True when a live connection has ended.
    pub fn closed(&self) -> bool {
        matches!(&self.source, Source::Live(s) if s.closed)
    }

    /// Applies a key's action.
    pub fn action(&mut self, action: Action) -> Result<(), ViewError> {
        match action {
            Action::PlayPause => {
                self.playing = !self.playing;
                if let Source::Local(l) = &mut self.source {
                    l.clock.toggle();
                }
            }
            Action::Step(by) => {
                if let Source::Local(l) = &mut self.source {
                    l.clock.step(by);
                }
            }
            Action::Restart => {
                if let Source::Local(l) = &mut self.source {
                    l.clock.seek(0);
                }
            }
            Action::ToggleSolver => self.toggle_solver()?,
            Action::ToggleHeat => self.heat = !self.heat,
            Action::TogglePose => self.pose = !self.pose,
            Action::ResetCamera => self.orbit = Orbit::default(),
            Action::Expression(k) => {
                if self.expressions.toggle(k) {
                    self.dirty = true;
                } else {
                    self.note = format!("no morph target on key {}", k + 1);
                }
            }
            Action::ToggleHelp => self.hud.show_help = !self.hud.show_help,
            Action::ToggleWeights => self.hud.show_weights = !self.hud.show_weights,
            Action::ToggleLegend => self.hud.show_legend = !self.hud.show_legend,
            Action::Quit => self.quit = true,
        }
        Ok(())
    }

    /// A scrub drag: the frame at `fraction` (0..=1) of the recording (local replays).
    pub fn scrub_to(&mut self, fraction: f64) {
        if let Source::Local(l) = &mut self.source {
            l.clock.seek_fraction(fraction);
        }
    }

    fn toggle_solver(&mut self) -> Result<(), ViewError> {
        let Source::Local(l) = &mut self.source else {
            self.note = "the solver of a live session is the server's".into();
            return Ok(());
        };
        let other = 1 - l.active;
        if l.slots[other].frames.is_some() {
            l.active = other;
            self.note.clear();
            self.dirty = true;
            return Ok(());
        }
        if l.slots[other].building.is_some() {
            return Ok(());
        }
        let settings = l.slots[other].settings;
        let (rig, layout, retarget) = (l.rig.clone(), l.layout.clone(), l.settings.clone());
        let build = move || -> Result<Retargeter, String> {
            let basis = build_basis(&rig, &settings)
                .map_err(|e| format!("building the {} basis: {e}", settings.kind.name()))?;
            Retargeter::new(&rig, &layout, basis, retarget).map_err(|e| e.to_string())
        };
        if l.blocking {
            let r = build().map_err(ViewError::Solver)?;
            l.slots[other].ready(r, l.frames.len());
            l.active = other;
            self.dirty = true;
        } else {
            // One result, sent once: a queue of one.
            let (tx, rx) = mpsc::sync_channel(1);
            std::thread::Builder::new()
                .name("mimic-view-basis".into())
                .spawn(move || {
                    // The viewer may have closed meanwhile: nothing to deliver to then.
                    let _ = tx.send(build());
                })
                .map_err(|e| ViewError::Solver(format!("cannot start the basis thread: {e}")))?;
            l.slots[other].building = Some(rx);
            self.note = format!("building the {} basis", settings.kind.name());
        }
        Ok(())
    }

    /// Advances to `now`: moves the playback clock and steps the retargeter (local), or takes the
    /// newest frame and any session events (live); uploads rigs to `renderer` as they come.
    pub fn update(&mut self, now: Instant, renderer: &Renderer) -> Result<(), ViewError> {
        let dt = self
            .last_tick
            .map_or(Duration::ZERO, |t| now.saturating_duration_since(t));
        self.last_tick = Some(now);
        match &mut self.source {
            Source::Local(l) => {
                // A basis built in the background: switch to it.
                let other = 1 - l.active;
                if let Some(rx) = &l.slots[other].building {
                    match rx.try_recv() {
                        Ok(Ok(r)) => {
                            l.slots[other].building = None;
                            l.slots[other].ready(r, l.frames.len());
                            l.active = other;
                            self.note.clear();
                            self.dirty = true;
                        }
                        Ok(Err(e)) => {
                            l.slots[other].building = None;
                            self.note = e;
                        }
                        Err(mpsc::TryRecvError::Empty) => {}
                        Err(mpsc::TryRecvError::Disconnected) => {
                            l.slots[other].building = None;
                            self.note = "the basis build stopped".into();
                        }
                    }
                }
                let frame = l.clock.advance(dt);
                let slot = &mut l.slots[l.active];
                if slot.gpu.is_none()
                    && let Some(r) = slot.frames.as_ref().and_then(FrameLoop::retargeter)
                {
                    // The expressions on the number keys: three more columns each.
                    let extended = extend_basis(r.basis(), &l.targets);
                    let gpu = upload_with_look(
                        renderer,
                        &l.rig.mesh.positions,
                        &l.rig.mesh.triangles,
                        Some(extended.as_ref().unwrap_or(r.basis())),
                        &l.look,
                    )?;
                    slot.gpu = Some(gpu);
                }
                let started = Instant::now();
                let stepped = slot.ensure(frame, &l.frames);
                let m = slot
                    .frames
                    .as_ref()
                    .and_then(FrameLoop::retargeter)
                    .map_or(0, |r| r.basis().control_count());
                let eased = self.expressions.advance(dt.as_secs_f32());
                let changed = stepped
                    || eased
                    || frame as u64 != self.shown_frame
                    || self.shown_d.len() != m
                    || self.dirty;
                if changed && let Some(d) = slot.history.get(frame * m..(frame + 1) * m) {
                    self.shown_d.clear();
                    self.shown_d.extend_from_slice(d);
                    self.shown_rotation = slot.rotations[frame];
                    self.state = slot.states.get(frame).map(|&b| status_label(b));
                    self.shown_frame = frame as u64;
                    self.fresh_since = Some(started);
                    self.new_frames += 1;
                    self.dirty = false;
                }
                self.playing = l.clock.playing();
                self.expressions.extend_d(&self.shown_d, &mut self.drawn_d);
                for (k, w) in self.weights.iter_mut().enumerate() {
                    *w = self.expressions.eased(k);
                }
            }
            Source::Live(s) => {
                while let Ok(event) = s.live.events.try_recv() {
                    match event {
                        Event::Session(v) => {
                            self.note = format!(
                                "session {} ({})",
                                v["session"].as_str().unwrap_or(&s.session),
                                v["rig"].as_str().unwrap_or("?")
                            );
                        }
                        Event::Rig(msg) => {
                            let name = msg.meta["name"].as_str().unwrap_or("live").to_string();
                            let n = msg.rest.len();
                            let basis = Basis::from_row_major(n, msg.controls, msg.basis)
                                .ok_or_else(|| ViewError::BadRig(name.clone()))?;
                            let look = (s.look_for)(&name, n);
                            let gpu = upload_with_look(
                                renderer,
                                &msg.rest,
                                &msg.triangles,
                                Some(&basis),
                                &look,
                            )?;
                            let (lo, hi) = bounds_of(&msg.rest);
                            self.bounds = (lo, hi);
                            self.units = msg.meta["units"].as_str().unwrap_or("").to_string();
                            // A weights session's d holds w_k along each axis (three columns
                            // per target, mimic_solve::morph_basis): its weights are known.
                            self.weight_names.clear();
                            if msg.meta["mode"] == "weights"
                                && let Some(names) = msg.meta["targets"].as_array()
                                && names.len() * 3 == msg.controls
                            {
                                self.weight_names
                                    .extend(names.iter().map(|n| n.as_str().unwrap_or("?").into()));
                            }
                            self.weights.clear();
                            self.weights.resize(self.weight_names.len(), 0.0);
                            self.shown_d.clear();
                            self.shown_d.resize(msg.controls, Vec3::ZERO);
                            self.shown_rotation = Quat::IDENTITY;
                            s.rig = Some(LiveRig {
                                name,
                                gpu,
                                lo,
                                hi,
                                controls: msg.controls,
                            });
                        }
                        Event::End(v) => {
                            self.note = format!(
                                "session ended ({}), waiting for the next",
                                v["reason"].as_str().unwrap_or("?")
                            );
                        }
                        Event::ServerError(v) => {
                            self.note = format!(
                                "server: {} {}",
                                v["code"].as_str().unwrap_or("error"),
                                v["message"].as_str().unwrap_or("")
                            );
                        }
                        Event::Closed(why) => {
                            s.closed = true;
                            if self.note.starts_with("server:") {
                                self.note = format!("{}; {why}", self.note);
                            } else {
                                self.note = why;
                            }
                        }
                    }
                }
                // Always drain, so resuming shows the newest frame, not a stale one.
                let newest = s.live.frames.take_latest();
                if let (true, Some(a), Some(rig)) = (self.playing, newest, &s.rig)
                    && a.frame.displacements.len() == rig.controls
                {
                    self.shown_d.copy_from_slice(&a.frame.displacements);
                    self.shown_rotation = a.frame.target_rotation;
                    self.shown_frame = a.frame.seq;
                    self.state = Some(status_label(a.frame.status));
                    for (w, d) in self.weights.iter_mut().zip(self.shown_d.chunks_exact(3)) {
                        *w = d[0].x;
                    }
                    self.fresh_since = Some(a.at);
                    self.new_frames += 1;
                    if self.note.starts_with("waiting") || self.note.starts_with("session ended") {
                        self.note.clear();
                    }
                }
                self.expressions.extend_d(&self.shown_d, &mut self.drawn_d);
            }
        }
        Ok(())
    }

    /// The rig, deformation and view to draw now, for an image of `aspect` (width / height);
    /// `None` while there is no rig yet (live, before RIG).
    pub fn scene(&self, aspect: f32) -> Option<(&RigGpu, Deform<'_>, View)> {
        let (gpu, (lo, hi)) = match &self.source {
            Source::Local(l) => (l.slots[l.active].gpu.as_ref()?, self.bounds),
            Source::Live(s) => {
                let r = s.rig.as_ref()?;
                (&r.gpu, (r.lo, r.hi))
            }
        };
        if self.drawn_d.len() != gpu.control_count() {
            return None;
        }
        let mut camera = self.orbit.camera(lo, hi);
        // Keep the rig framed vertically whatever the window's shape: widen the field of view
        // of a tall window so the head still fits side to side.
        if aspect < 1.0 {
            camera.fov_y = 2.0 * ((camera.fov_y * 0.5).tan() / aspect.max(0.05)).atan();
        }
        let mut view = View::lit(camera);
        if self.heat {
            view.shading = Shading::Displacement {
                full_scale: self.full_scale(lo, hi),
            };
        }
        if self.pose {
            view.model = View::head_rotation(self.shown_rotation, (lo + hi) * 0.5);
        } else {
            view.model = Mat4::IDENTITY;
        }
        Some((gpu, Deform::Controls(&self.drawn_d), view))
    }

    /// Rebuilds what is drawn over the head for a `screen` (width, height) image: the readout, the
    /// waiting message, the legend, the weights and the key help ([`crate::hud`]).
    pub fn build_overlay(&mut self, screen: (u32, u32)) -> &Overlay {
        let (rig, count): (&str, Option<usize>) = match &self.source {
            Source::Local(l) => (&l.rig.name, Some(l.frames.len())),
            Source::Live(s) => (s.rig.as_ref().map_or("-", |r| r.name.as_str()), None),
        };
        let session = match &self.source {
            Source::Local(_) => None,
            Source::Live(s) => Some(s.session.as_str()),
        };
        let heat = self.heat.then(|| {
            let (lo, hi) = match &self.source {
                Source::Live(s) => s.rig.as_ref().map_or(self.bounds, |r| (r.lo, r.hi)),
                Source::Local(_) => self.bounds,
            };
            self.full_scale(lo, hi)
        });
        let state = HudState {
            rig,
            solver: self.solver(),
            session,
            frame: (self.shown_frame, count),
            playing: self.playing,
            figures: self.readout.shown,
            state: self.state,
            note: &self.note,
            idle: self.idle(),
            heat,
            units: &self.units,
            weight_names: &self.weight_names,
            weights: &self.weights,
        };
        self.hud.build(&state, screen)
    }

    /// Whether headless images carry the overlay ([`Options::headless_overlay`]).
    pub fn headless_overlay(&self) -> bool {
        self.headless_overlay
    }

    /// The overlay last built by [`Viewer::build_overlay`].
    pub fn overlay(&self) -> &Overlay {
        self.hud.overlay()
    }

    /// The morph targets whose weights are known and their weights now (the bars of `w`).
    pub fn weights(&self) -> (&[String], &[f32]) {
        (&self.weight_names, &self.weights)
    }

    /// The heat map's hottest displacement for a rig spanning `lo..hi`: `--heat-scale`, else 5%
    /// of its diagonal.
    fn full_scale(&self, lo: Vec3, hi: Vec3) -> f32 {
        self.heat_scale.unwrap_or(0.05 * (hi - lo).length())
    }

    /// Records a presented frame; returns the new window title when the readout refreshed.
    pub fn presented(&mut self) -> Option<&str> {
        let now = Instant::now();
        let latency = self
            .fresh_since
            .take()
            .map(|t| now.saturating_duration_since(t));
        if !self.readout.presented(now, latency) {
            return None;
        }
        Some(self.title())
    }

    /// The window title now.
    pub fn title(&mut self) -> &str {
        let (rig, count): (&str, Option<usize>) = match &self.source {
            Source::Local(l) => (&l.rig.name, Some(l.frames.len())),
            Source::Live(s) => (s.rig.as_ref().map_or("-", |r| r.name.as_str()), None),
        };
        let status = Status {
            rig,
            solver: self.solver(),
            frame: (self.shown_frame, count),
            playing: self.playing,
            heat: self.heat,
            note: &self.note,
        };
        write_title(&mut self.title, &status, &self.readout.shown);
        if !self.expressions.is_empty() {
            self.title.push_str(" | ");
            self.title.push_str(&self.expressions.label());
        }
        &self.title
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounds_span_the_points() {
        let (lo, hi) = bounds_of(&[Vec3::new(1.0, -2.0, 0.0), Vec3::new(-1.0, 3.0, 5.0)]);
        assert_eq!(
            (lo, hi),
            (Vec3::new(-1.0, -2.0, 0.0), Vec3::new(1.0, 3.0, 5.0))
        );
        assert_eq!(bounds_of(&[]), (Vec3::splat(-1.0), Vec3::splat(1.0)));
    }
}
