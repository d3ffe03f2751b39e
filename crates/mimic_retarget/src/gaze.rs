//! Gaze per eye from a layout's pupil, eye-corner and lid points ([`GazeTracker`]), and ARKit's
//! eight `eyeLook*` weights from it ([`eye_look_weights`]).
//!
//! # Method
//! Everything is measured in the neutral's head frame: each frame's points are first mapped by
//! `back` (the inverse of the frame's rigid head pose), so head motion does not read as gaze.
//!
//! - **Axes** (fixed at [`GazeTracker::set_neutral`], from the neutral): *lateral* `L` from the
//!   subject's right outer eye corner to the left one; *up* `U` the sum of both eyes' lid vectors
//!   (upper-lid middle minus lower-lid middle), made perpendicular to `L`; *forward* `F = L x U`,
//!   flipped if needed so that it points toward the camera (+z in a recording's space: x image
//!   right, y up, z toward the camera; the neutral faces the camera), so the estimate does not
//!   depend on the source's handedness (a mirrored camera). The labels left/right come from the layout, so a yaw toward the
//!   subject's left is positive whatever the source's handedness.
//! - **Eyeball** (per eye): radius `R = 0.45 w`, `w` the neutral's corner-to-corner distance. On
//!   MediaPipe's life-size canonical model (its iris is 1.2 cm across, a human iris 11.7 mm) `w`
//!   is 2.66 cm, so `R` = 1.2 cm, the radius of a human eyeball (axial length about 24 mm). The
//!   centre is taken to lie `R` behind the neutral pupil along `F` (the neutral looks straight
//!   ahead, which is what "relative to the neutral" means) and is carried by the eye corners: it
//!   is stored as an offset from their midpoint, so in each frame the centre is the corners'
//!   midpoint plus that offset.
//! - **Direction**: the pupil's depth is the weakest coordinate of a camera tracker, so it is
//!   not used: the pupil is taken where the camera sees it, on the line through the tracked pupil
//!   along the camera's depth axis (the recording convention's z, toward the camera, mapped by
//!   `back`), at that line's intersection with the eyeball nearer the camera (where the line
//!   misses the eyeball, the eyeball's point nearest it). With `d` = that point - centre and
//!   `a = d.L`, `b = d.U`, `f = d.F`: `yaw = atan2(a, f)`, `pitch = atan2(b, sqrt(a^2 + f^2))`.
//!   So the gaze direction is `(sin yaw cos pitch, sin pitch, cos yaw cos pitch)` in (L, U, F)
//!   ([`EyeGaze::direction`]): the eye turned by `pitch` up about the lateral axis, then by `yaw`
//!   about the up axis (Fick's gimbal). The neutral reads (0, 0) exactly.
//! - **Trust**: an eye's reading is trusted when its corners, lids and every pupil point are valid
//!   and its openness (lid gap along `U` over `w`) is at least [`GazeSettings::closed_below`]
//!   (0.5) of the neutral's. A closing lid drags the tracked pupil down (MediaPipe's iris does),
//!   so a blink would read as looking down; an untrusted eye is not read at all. One eye trusted
//!   (a wink, or one pupil lost): both eyes take its gaze. Neither: both hold the last gaze.
//!   Both: each keeps its own (vergence), drawn toward their mean by [`GazeSettings::binocular`].
//! - **Limits**: yaw within +-35 degrees, pitch within -30 (down) .. +25 (up) degrees, the range a
//!   human eye turns in its orbit (about 35-45 degrees horizontally, 25 up and 35 down at most;
//!   the ends are kept a little inside it, since a tracker's wildest readings are its errors).
//! - **Filter**: each of the four angles is smoothed by the crate's One Euro filter
//!   ([`GazeSettings::filter`], radians and radians per second).
//!
//! [`eye_look_weights`]: each ARKit weight is the angle in its direction over a full-scale angle
//! ([`LOOK_FULL_SCALE_HORIZONTAL`] 30 degrees, [`LOOK_FULL_SCALE_VERTICAL`] 25 degrees: about
//! where a person's eye turns comfortably, past which a person turns the head instead), clamped to
//! [0, 1].

use crate::{OneEuro, OneEuroSettings, OneEuroStep};
use glam::{Affine3A, Vec3};
use mimic_types::{EyePoints, LandmarkFrame, Layout};

/// The subject's left eye's index in `[EyeGaze; 2]` and the like.
pub const LEFT: usize = 0;
/// The subject's right eye's index.
pub const RIGHT: usize = 1;

/// Eyeball radius over the eye's corner-to-corner distance (see the module doc).
pub const RADIUS_PER_WIDTH: f32 = 0.45;

/// Full-scale horizontal angle of the ARKit `eyeLookIn*`/`eyeLookOut*` weights (radians, 30 degrees).
pub const LOOK_FULL_SCALE_HORIZONTAL: f32 = 30.0 * std::f32::consts::PI / 180.0;
/// Full-scale vertical angle of the ARKit `eyeLookUp*`/`eyeLookDown*` weights (radians, 25 degrees).
pub const LOOK_FULL_SCALE_VERTICAL: f32 = 25.0 * std::f32::consts::PI / 180.0;

/// ARKit's eight gaze weights, in the order [`eye_look_weights`] writes them; "Left" is the
/// subject's left eye, "In" toward the nose.
pub const EYE_LOOK_NAMES: [&str; 8] = [
    "eyeLookDownLeft",
    "eyeLookInLeft",
    "eyeLookOutLeft",
    "eyeLookUpLeft",
    "eyeLookDownRight",
    "eyeLookInRight",
    "eyeLookOutRight",
    "eyeLookUpRight",
];

/// One eye's gaze in radians, relative to the neutral's (which looks straight ahead).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct EyeGaze {
    /// Turn about the head's up axis; > 0 toward the subject's left.
    pub yaw: f32,
    /// Turn about the head's lateral axis; > 0 looks up.
    pub pitch: f32,
}

impl EyeGaze {
    /// This gaze with both angles scaled by `k`.
    fn scaled(self, k: f32) -> EyeGaze {
        EyeGaze {
            yaw: self.yaw * k,
            pitch: self.pitch * k,
        }
    }

    /// The unit gaze direction in (lateral, up, forward) coordinates of the head frame:
    /// `(sin yaw cos pitch, sin pitch, cos yaw cos pitch)`.
    pub fn direction(self) -> Vec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        Vec3::new(sy * cp, sp, cy * cp)
    }
}

/// A layout's eye points, resolved from its `[gaze]` table: `[left, right]`.
#[derive(Clone, Debug, PartialEq)]
pub struct GazePoints {
    eyes: [EyePoints; 2],
}

impl GazePoints {
    /// The eyes of `layout`; `None` when it has no `[gaze]` table (no pupils).
    pub fn of(layout: &Layout) -> Option<GazePoints> {
        let g = layout.gaze.as_ref()?;
        Some(GazePoints {
            eyes: [g.left.clone(), g.right.clone()],
        })
    }

    /// The points of eye `e` ([`LEFT`] or [`RIGHT`]).
    pub fn eye(&self, e: usize) -> Option<&EyePoints> {
        self.eyes.get(e)
    }
}

/// Knobs of [`GazeTracker`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct GazeSettings {
    /// One Euro filter on each angle (radians); `None` turns it off.
    pub filter: Option<OneEuroSettings>,
    /// An eye whose openness is under this fraction of the neutral's is closed: not read.
    pub closed_below: f32,
    /// How far each eye's gaze is drawn toward the two eyes' mean when both are read: 0 keeps
    /// each eye's own (vergence), 1 gives both the mean (less noise, no vergence).
    pub binocular: f32,
    /// Largest yaw either way (radians).
    pub yaw_limit: f32,
    /// Largest pitch up (radians).
    pub pitch_up_limit: f32,
    /// Largest pitch down (radians, positive).
    pub pitch_down_limit: f32,
}

impl Default for GazeSettings {
    fn default() -> Self {
        let deg = std::f32::consts::PI / 180.0;
        Self {
            // Gaze jitters less than a lip corner but moves in fast saccades (up to ~500 deg/s,
            // 9 rad/s): a lower rest cutoff than the controls' 3 Hz, and a beta that opens the
            // cutoff to ~10 Hz in a saccade.
            filter: Some(OneEuroSettings {
                min_cutoff: 1.5,
                beta: 1.0,
                derivative_cutoff: 1.0,
            }),
            closed_below: 0.5,
            binocular: 0.0,
            yaw_limit: 35.0 * deg,
            pitch_up_limit: 25.0 * deg,
            pitch_down_limit: 30.0 * deg,
        }
    }
}

/// The head-frame axes of [`GazeTracker`] (module doc): lateral, up, forward.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Axes {
    lateral: Vec3,
    up: Vec3,
    forward: Vec3,
}

/// One eye's neutral references.
#[derive(Clone, Copy, Debug, PartialEq)]
struct EyeRef {
    /// Eyeball centre minus the corners' midpoint (head frame).
    offset: Vec3,
    /// Eyeball radius `R`.
    radius: f32,
    /// Neutral lid gap over eye width.
    openness: f32,
}

/// One eye's reading of one frame.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
struct Reading {
    /// Openness relative to the neutral's (NaN when unknown).
    openness: f32,
    /// The gaze, when the pupil was read and the eye is open.
    gaze: Option<EyeGaze>,
}

/// Per-eye gaze from landmark frames (module doc): neutral references, filter state and the
/// last gaze; [`GazeTracker::step`] allocates nothing.
#[derive(Clone, Debug)]
pub struct GazeTracker {
    points: GazePoints,
    settings: GazeSettings,
    axes: Option<Axes>,
    eyes: [Option<EyeRef>; 2],
    /// The last unfiltered gaze (what an untrusted frame holds).
    target: [EyeGaze; 2],
    /// Yaw and pitch filters per eye.
    filters: [[OneEuro; 2]; 2],
    /// The last gaze returned.
    last: [EyeGaze; 2],
    /// Whether each eye was read in the last step.
    trusted: [bool; 2],
    /// Each eye's openness relative to the neutral in the last step (NaN when unknown).
    openness: [f32; 2],
}

/// The mean of `points` mapped by `back`, `None` unless every one is valid in `frame`.
fn mean_mapped(points: &[usize], frame: &LandmarkFrame, back: &Affine3A) -> Option<Vec3> {
    let mut sum = Vec3::ZERO;
    for &p in points {
        if !frame.is_valid(p) {
            return None;
        }
        sum += back.transform_point3(frame.points[p]);
    }
    (!points.is_empty()).then(|| sum / points.len() as f32)
}

/// The mean of `points` of a neutral, `None` unless every one is valid.
fn mean_neutral(points: &[usize], neutral: &[Vec3], valid: &[bool]) -> Option<Vec3> {
    let mut sum = Vec3::ZERO;
    for &p in points {
        let q = *neutral.get(p)?;
        if !(valid.get(p).copied().unwrap_or(false) && q.is_finite()) {
            return None;
        }
        sum += q;
    }
    (!points.is_empty()).then(|| sum / points.len() as f32)
}

/// The point of the sphere of radius `radius` about the origin that the pupil at `w` (relative to
/// the eyeball's centre) is seen as along the camera's depth axis `view` (head frame, toward the
/// camera): the intersection of the line `w + t view` with the sphere nearer the camera, or where
/// the line misses the sphere, the sphere's point nearest it. Relative to the centre.
fn on_sphere(w: Vec3, view: Vec3, radius: f32) -> Vec3 {
    let Some(v) = view.try_normalize() else {
        return w;
    };
    let wv = w.dot(v);
    let across = w - wv * v;
    let disc = radius * radius - across.length_squared();
    if disc >= 0.0 {
        across + disc.sqrt() * v
    } else {
        across.normalize_or_zero() * radius
    }
}

/// An eye's corners, lid middles and pupil in one frame of reference.
struct EyeAt {
    outer: Vec3,
    inner: Vec3,
    upper: Vec3,
    lower: Vec3,
    pupil: Option<Vec3>,
}

impl EyeAt {
    /// Eye `e`'s points of `frame` mapped by `back`; `None` unless its corners and lids are
    /// valid (the pupil is `None` unless every pupil point is).
    fn mapped(e: &EyePoints, frame: &LandmarkFrame, back: &Affine3A) -> Option<EyeAt> {
        let one = |p: usize| mean_mapped(std::slice::from_ref(&p), frame, back);
        Some(EyeAt {
            outer: one(e.outer)?,
            inner: one(e.inner)?,
            upper: mean_mapped(&e.upper, frame, back)?,
            lower: mean_mapped(&e.lower, frame, back)?,
            pupil: mean_mapped(&e.pupil, frame, back),
        })
    }

    /// Corners' midpoint.
    fn mid(&self) -> Vec3 {
        0.5 * (self.outer + self.inner)
    }
    /// Corner-to-corner distance.
    fn width(&self) -> f32 {
        self.outer.distance(self.inner)
    }
    /// Lid gap along `up` over the width.
    fn openness(&self, up: Vec3) -> f32 {
        (self.upper - self.lower).dot(up) / self.width()
    }
}

impl GazeTracker {
    /// A tracker of `points`, with no neutral yet (every step reads nothing until
    /// [`GazeTracker::set_neutral`]).
    pub fn new(points: GazePoints, settings: GazeSettings) -> Self {
        Self {
            points,
            settings,
            axes: None,
            eyes: [None; 2],
            target: [EyeGaze::default(); 2],
            filters: [[OneEuro::default(); 2]; 2],
            last: [EyeGaze::default(); 2],
            trusted: [false; 2],
            openness: [f32::NAN; 2],
        }
    }

    /// The tracker's settings.
    pub fn settings(&self) -> &GazeSettings {
        &self.settings
    }

    /// Sets the neutral (the face looking straight ahead, in the head frame that `back` maps
    /// frames into) and forgets the filter state. An eye whose corners, lids or pupil are invalid
    /// there, or whose lids are closed, is never read; without both outer corners nothing is.
    pub fn set_neutral(&mut self, neutral: &[Vec3], valid: &[bool]) {
        self.reset();
        self.axes = None;
        self.eyes = [None; 2];
        let at = |e: &EyePoints| -> Option<EyeAt> {
            let one = |p: usize| mean_neutral(std::slice::from_ref(&p), neutral, valid);
            Some(EyeAt {
                outer: one(e.outer)?,
                inner: one(e.inner)?,
                upper: mean_neutral(&e.upper, neutral, valid)?,
                lower: mean_neutral(&e.lower, neutral, valid)?,
                pupil: mean_neutral(&e.pupil, neutral, valid),
            })
        };
        let eyes = [at(&self.points.eyes[LEFT]), at(&self.points.eyes[RIGHT])];
        let (Some(l), Some(r)) = (&eyes[LEFT], &eyes[RIGHT]) else {
            return;
        };
        let Some(lateral) = (l.outer - r.outer).try_normalize() else {
            return;
        };
        let lids = (l.upper - l.lower) + (r.upper - r.lower);
        let Some(up) = (lids - lids.dot(lateral) * lateral).try_normalize() else {
            return;
        };
        let mut forward = lateral.cross(up);
        // The neutral faces the camera, which is toward +z in a recording's space.
        if forward.z < 0.0 {
            forward = -forward;
        }
        self.axes = Some(Axes {
            lateral,
            up,
            forward,
        });
        for (slot, eye) in self.eyes.iter_mut().zip(&eyes) {
            *slot = eye.as_ref().and_then(|e| {
                let width = e.width();
                let openness = e.openness(up);
                let pupil = e.pupil?;
                let radius = RADIUS_PER_WIDTH * width;
                (width > 0.0 && openness > 0.0 && radius.is_finite()).then(|| EyeRef {
                    offset: pupil - radius * forward - e.mid(),
                    radius,
                    openness,
                })
            });
        }
    }

    /// Whether a neutral is set that lets at least one eye be read.
    pub fn has_neutral(&self) -> bool {
        self.axes.is_some() && self.eyes.iter().any(Option::is_some)
    }

    /// One eye's reading of `frame`.
    fn read(&self, e: usize, frame: &LandmarkFrame, back: &Affine3A) -> Reading {
        let none = Reading {
            openness: f32::NAN,
            gaze: None,
        };
        let (Some(axes), Some(r)) = (self.axes, self.eyes[e]) else {
            return none;
        };
        let Some(at) = EyeAt::mapped(&self.points.eyes[e], frame, back) else {
            return none;
        };
        let openness = at.openness(axes.up) / r.openness;
        let open = openness >= self.settings.closed_below;
        let gaze = at.pupil.filter(|_| open).and_then(|p| {
            let view = back.transform_vector3(Vec3::Z);
            let d = on_sphere(p - (at.mid() + r.offset), view, r.radius);
            let (a, b, f) = (d.dot(axes.lateral), d.dot(axes.up), d.dot(axes.forward));
            let s = &self.settings;
            let g = EyeGaze {
                yaw: a.atan2(f).clamp(-s.yaw_limit, s.yaw_limit),
                pitch: b
                    .atan2((a * a + f * f).sqrt())
                    .clamp(-s.pitch_down_limit, s.pitch_up_limit),
            };
            (g.yaw.is_finite() && g.pitch.is_finite()).then_some(g)
        });
        Reading { openness, gaze }
    }

    /// One tracked frame, `dt_s` seconds after the previous one: reads both eyes, applies the
    /// wink and blink rules, filters, and returns `[left, right]` (also [`GazeTracker::last`]).
    /// A frame that is not `tracked` reads nothing (as if both eyes were closed). Allocates nothing.
    pub fn step(&mut self, frame: &LandmarkFrame, back: &Affine3A, dt_s: f32) -> [EyeGaze; 2] {
        let readings = if frame.tracked {
            [self.read(LEFT, frame, back), self.read(RIGHT, frame, back)]
        } else {
            [Reading {
                openness: f32::NAN,
                gaze: None,
            }; 2]
        };
        self.openness = [readings[LEFT].openness, readings[RIGHT].openness];
        self.trusted = [
            readings[LEFT].gaze.is_some(),
            readings[RIGHT].gaze.is_some(),
        ];
        self.target = match (readings[LEFT].gaze, readings[RIGHT].gaze) {
            (Some(l), Some(r)) => {
                let k = self.settings.binocular.clamp(0.0, 1.0);
                let mean = EyeGaze {
                    yaw: 0.5 * (l.yaw + r.yaw),
                    pitch: 0.5 * (l.pitch + r.pitch),
                };
                let mix = |g: EyeGaze| EyeGaze {
                    yaw: (1.0 - k) * g.yaw + k * mean.yaw,
                    pitch: (1.0 - k) * g.pitch + k * mean.pitch,
                };
                [mix(l), mix(r)]
            }
            (Some(g), None) | (None, Some(g)) => [g, g],
            (None, None) => self.target,
        };
        let step = self
            .settings
            .filter
            .map(|s| (s, OneEuroStep::new(&s, dt_s)));
        for (e, out) in self.last.iter_mut().enumerate() {
            let t = self.target[e];
            *out = match &step {
                Some((s, st)) => EyeGaze {
                    yaw: self.filters[e][0].filter_step(s, st, t.yaw),
                    pitch: self.filters[e][1].filter_step(s, st, t.pitch),
                },
                None => t,
            };
        }
        self.last
    }

    /// A lost or held frame: scales the last gaze by `k` (clamped to [0, 1]; 1 holds it, 0 looks
    /// straight ahead) and returns it; the filters continue from there.
    pub fn hold(&mut self, k: f32) -> [EyeGaze; 2] {
        let k = if k.is_nan() { 1.0 } else { k.clamp(0.0, 1.0) };
        for e in 0..2 {
            self.last[e] = self.last[e].scaled(k);
            self.target[e] = self.last[e];
            for (f, v) in self.filters[e]
                .iter_mut()
                .zip([self.last[e].yaw, self.last[e].pitch])
            {
                if f.primed {
                    f.value = v;
                    f.derivative = 0.0;
                }
            }
        }
        self.trusted = [false; 2];
        self.openness = [f32::NAN; 2];
        self.last
    }

    /// Forgets the filter state and the last gaze (straight ahead); keeps the neutral.
    pub fn reset(&mut self) {
        self.target = [EyeGaze::default(); 2];
        self.last = [EyeGaze::default(); 2];
        self.filters = [[OneEuro::default(); 2]; 2];
        self.trusted = [false; 2];
        self.openness = [f32::NAN; 2];
    }

    /// The last gaze returned, `[left, right]`.
    pub fn last(&self) -> [EyeGaze; 2] {
        self.last
    }

    /// Whether each eye's pupil was read in the last step (open, valid), `[left, right]`.
    pub fn trusted(&self) -> [bool; 2] {
        self.trusted
    }

    /// Each eye's openness in the last step relative to the neutral's (1 = as open as the
    /// neutral; NaN when not measured), `[left, right]`.
    pub fn openness(&self) -> [f32; 2] {
        self.openness
    }
}

/// ARKit's eight `eyeLook*` weights of gaze `g` (`[left, right]`) into `out`, in the order of
/// [`EYE_LOOK_NAMES`]: each the angle in its direction over its full scale
/// ([`LOOK_FULL_SCALE_HORIZONTAL`], [`LOOK_FULL_SCALE_VERTICAL`]), clamped to [0, 1]. The left
/// eye looks in (toward the nose) at yaw < 0, the right eye at yaw > 0.
pub fn eye_look_weights(g: [EyeGaze; 2], out: &mut [f32; 8]) {
    let w = |angle: f32, full: f32| {
        let x = angle / full;
        if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) }
    };
    let (h, v) = (LOOK_FULL_SCALE_HORIZONTAL, LOOK_FULL_SCALE_VERTICAL);
    for (e, chunk) in out.chunks_exact_mut(4).enumerate() {
        let gz = g[e];
        // Toward the nose: the subject's right for the left eye, the left for the right eye.
        let inward = if e == LEFT { -gz.yaw } else { gz.yaw };
        chunk[0] = w(-gz.pitch, v);
        chunk[1] = w(inward, h);
        chunk[2] = w(-inward, h);
        chunk[3] = w(gz.pitch, v);
    }
}

#[cfg(test)]
mod tests;
