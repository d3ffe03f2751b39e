//! Live lip sync ([`LiveLipSync`], `mimic serve`'s audio sessions, docs/audio.md): causal, so a
//! mouth frame needs no audio after its time. The samples (any rate in [`crate::wav::RATES`],
//! mono) are cut into sub-blocks of 1/240 s; after each, the last [`WINDOW_SUBS`] of them
//! (16.7 ms) give the level and the spectrum's shape (the share of energy under 800 Hz and over
//! 3 kHz, zero crossings a second), which pick a target mouth from the viseme table: silence
//! closed; voiced speech the `open` vowel (AA) opened by the level under the loudest speech so
//! far, rounded (OW) when the energy sits low and loud, a nasal murmur (low and quiet) or a
//! closure inside a word (a stop) the lips together (the bilabial viseme, softened); hiss (S).
//! The mouth follows the target with time constants [`ATTACK_S`] / [`RELEASE_S`], and a frame
//! goes out every fourth sub-block ([`crate::coart::FPS`] a second). No allocation per sample or
//! frame.

use crate::error::AudioError;
use crate::visemes::VisemeTable;

/// Sub-blocks a second (four to an output frame).
pub const SUBS_PER_S: u64 = 240;
/// Sub-blocks per output frame.
pub const SUBS_PER_FRAME: u64 = 4;
/// Sub-blocks in the analysis window (16.7 ms).
pub const WINDOW_SUBS: usize = 4;
/// A window is speech when its level is within this many dB of the loudest speech so far...
pub const SPEECH_DB: f32 = 30.0;
/// ...and this many dB over the noise floor (the quietest window lately)...
pub const OVER_FLOOR_DB: f32 = 12.0;
/// ...and over this level (dBFS; digital silence and dither never are).
pub const FLOOR_DBFS: f32 = -70.0;
/// How fast the loudest-speech level falls back (dB a second), and the floor rises.
const PEAK_FALL_DB_S: f32 = 1.0;
const FLOOR_RISE_DB_S: f32 = 1.0;
/// The jaw is fully the vowel's at this many dB under the loudest speech, shut at `OPEN_LOW_DB`.
const OPEN_HIGH_DB: f32 = 8.0;
const OPEN_LOW_DB: f32 = 30.0;
/// Time constant of the mouth opening towards its target (s).
pub const ATTACK_S: f64 = 0.010;
/// Time constant of the mouth closing towards its target (s).
pub const RELEASE_S: f64 = 0.014;
/// A quiet window this soon after speech is a closure inside a word (s).
const CLOSURE_S: f64 = 0.08;
/// How much of the bilabial viseme a closure or a nasal murmur takes.
const CLOSURE_SHARE: f32 = 0.6;

/// Energy and zero crossings of one sub-block.
#[derive(Clone, Copy, Debug, Default)]
struct Sub {
    n: u32,
    e: f32,
    low: f32,
    high: f32,
    crossings: u32,
}

/// The shapes a target is mixed from, columns as the table's names.
#[derive(Clone, Debug)]
struct Shapes {
    open: Vec<f32>,
    rounded: Vec<f32>,
    sibilant: Vec<f32>,
    closure: Vec<f32>,
}

/// What one window says (for tests and the docs' figures).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Window {
    /// Level, dBFS.
    pub level_db: f32,
    /// Whether it is speech.
    pub speech: bool,
    /// Share of its energy under 800 Hz.
    pub low: f32,
    /// Share of its energy over 3 kHz.
    pub high: f32,
    /// Zero crossings a second.
    pub crossings_s: f32,
}

/// Causal speech-to-mouth (module docs).
#[derive(Clone, Debug)]
pub struct LiveLipSync {
    rate: u64,
    names: Vec<&'static str>,
    shapes: Shapes,
    /// Samples taken so far.
    n: u64,
    /// Sub-blocks completed so far.
    subs: u64,
    cur: Sub,
    ring: [Sub; WINDOW_SUBS],
    // Filters: a DC blocker, a low-pass at 800 Hz and a high-pass at 3 kHz.
    dc_x: f32,
    dc_y: f32,
    dc_r: f32,
    low: Biquad,
    high: Biquad,
    positive: bool,
    peak_db: f32,
    floor_db: f32,
    /// Sub-blocks since the last speech window (`u64::MAX`: none yet).
    since_speech: u64,
    last: Window,
    target: Vec<f32>,
    mouth: Vec<f32>,
    k_attack: f32,
    k_release: f32,
}

/// `x` from 0 at `a` to 1 at `b`, smoothly.
fn smoothstep(a: f32, b: f32, x: f32) -> f32 {
    let t = ((x - a) / (b - a)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// A second-order Butterworth filter (RBJ's cookbook), transposed direct form II.
#[derive(Clone, Copy, Debug)]
struct Biquad {
    b: [f32; 3],
    a: [f32; 2],
    z: [f32; 2],
}

impl Biquad {
    /// Low-pass (`high` false) or high-pass at `hz` for `rate`.
    fn new(hz: f64, rate: u64, high: bool) -> Self {
        let w0 = std::f64::consts::TAU * hz / rate as f64;
        let (cos, alpha) = (w0.cos(), w0.sin() / std::f64::consts::SQRT_2);
        let a0 = 1.0 + alpha;
        let b = if high {
            [(1.0 + cos) / 2.0, -(1.0 + cos), (1.0 + cos) / 2.0]
        } else {
            [(1.0 - cos) / 2.0, 1.0 - cos, (1.0 - cos) / 2.0]
        };
        Self {
            b: b.map(|x| (x / a0) as f32),
            a: [(-2.0 * cos / a0) as f32, ((1.0 - alpha) / a0) as f32],
            z: [0.0; 2],
        }
    }

    fn step(&mut self, x: f32) -> f32 {
        let y = self.b[0] * x + self.z[0];
        self.z[0] = self.b[1] * x - self.a[0] * y + self.z[1];
        self.z[1] = self.b[2] * x - self.a[1] * y;
        y
    }
}

impl LiveLipSync {
    /// A stream of mono samples at `rate` Hz, mouths from `table`'s visemes.
    pub fn new(rate: u32, table: &VisemeTable) -> Result<Self, AudioError> {
        if !crate::wav::RATES.contains(&rate) {
            return Err(AudioError::Stream(format!(
                "sample rate {rate} Hz is outside {}-{} Hz",
                crate::wav::RATES.start(),
                crate::wav::RATES.end()
            )));
        }
        let rate = u64::from(rate);
        let shape = |phone: &str| table.of(phone).weights.clone();
        let closure = shape("P").iter().map(|w| w * CLOSURE_SHARE).collect();
        let k = table.names.len();
        let dt = 1.0 / SUBS_PER_S as f64;
        Ok(Self {
            rate,
            names: table.names.clone(),
            shapes: Shapes {
                open: shape("AA"),
                rounded: shape("OW"),
                sibilant: shape("S"),
                closure,
            },
            n: 0,
            subs: 0,
            cur: Sub::default(),
            ring: [Sub::default(); WINDOW_SUBS],
            dc_x: 0.0,
            dc_y: 0.0,
            dc_r: (-std::f64::consts::TAU * 20.0 / rate as f64).exp() as f32,
            low: Biquad::new(800.0, rate, false),
            high: Biquad::new(3000.0, rate, true),
            positive: false,
            peak_db: -120.0,
            floor_db: 0.0,
            since_speech: u64::MAX,
            last: Window::default(),
            target: vec![0.0; k],
            mouth: vec![0.0; k],
            k_attack: (1.0 - (-dt / ATTACK_S).exp()) as f32,
            k_release: (1.0 - (-dt / RELEASE_S).exp()) as f32,
        })
    }

    /// The ARKit names of the weights, in frame order.
    pub fn names(&self) -> &[&'static str] {
        &self.names
    }

    /// The stream's sample rate (Hz).
    pub fn rate(&self) -> u32 {
        u32::try_from(self.rate).unwrap_or(u32::MAX)
    }

    /// Samples taken so far.
    pub fn samples(&self) -> u64 {
        self.n
    }

    /// The last window's reading.
    pub fn last_window(&self) -> Window {
        self.last
    }

    /// The time of output frame `k` (µs after the stream's first sample): `k / FPS` s. Frame
    /// `k` holds the mouth after the audio up to that time, and none after it.
    pub fn frame_t_us(k: u64) -> i64 {
        i64::try_from(k.saturating_mul(1_000_000) / crate::coart::FPS as u64).unwrap_or(i64::MAX)
    }

    /// Takes `samples` (mono, -1..1), calling `emit(k, weights)` for each output frame `k`
    /// (from 1) whose time they reach.
    pub fn push(&mut self, samples: &[f32], mut emit: impl FnMut(u64, &[f32])) {
        for &x in samples {
            let x = if x.is_finite() {
                x.clamp(-1.0, 1.0)
            } else {
                0.0
            };
            // DC blocker, then the bands.
            let y = x - self.dc_x + self.dc_r * self.dc_y;
            self.dc_x = x;
            self.dc_y = y;
            let (lo, hi) = (self.low.step(y), self.high.step(y));
            let c = &mut self.cur;
            c.n += 1;
            c.e += y * y;
            c.low += lo * lo;
            c.high += hi * hi;
            if (y > 0.0) != self.positive {
                self.positive = y > 0.0;
                c.crossings += 1;
            }
            self.n += 1;
            // Sub-block j ends at sample floor((j + 1) rate / 240).
            if self.n >= (self.subs + 1) * self.rate / SUBS_PER_S {
                self.end_sub();
                if self.subs.is_multiple_of(SUBS_PER_FRAME) {
                    emit(self.subs / SUBS_PER_FRAME, &self.mouth);
                }
            }
        }
    }

    /// Closes a sub-block: the window's reading, the target, the mouth's step.
    fn end_sub(&mut self) {
        self.ring[(self.subs % WINDOW_SUBS as u64) as usize] = self.cur;
        self.cur = Sub::default();
        self.subs += 1;
        let mut w = Sub::default();
        for s in &self.ring {
            w.n += s.n;
            w.e += s.e;
            w.low += s.low;
            w.high += s.high;
            w.crossings += s.crossings;
        }
        let dt = 1.0 / SUBS_PER_S as f32;
        let n = w.n.max(1) as f32;
        let level_db = 10.0 * (w.e / n + 1e-12).log10();
        if self.subs == 1 || level_db < self.floor_db {
            self.floor_db = level_db;
        } else {
            self.floor_db += FLOOR_RISE_DB_S * dt;
        }
        let threshold = FLOOR_DBFS
            .max(self.floor_db + OVER_FLOOR_DB)
            .max(self.peak_db - SPEECH_DB);
        let speech = level_db > threshold;
        self.peak_db -= PEAK_FALL_DB_S * dt;
        if speech {
            self.peak_db = self.peak_db.max(level_db);
        }
        let e = w.e.max(1e-12);
        self.last = Window {
            level_db,
            speech,
            low: (w.low / e).min(1.0),
            high: (w.high / e).min(1.0),
            crossings_s: w.crossings as f32 * self.rate as f32 / n,
        };
        self.since_speech = if speech {
            0
        } else {
            self.since_speech.saturating_add(1)
        };
        self.set_target();
        for (m, t) in self.mouth.iter_mut().zip(&self.target) {
            let k = if *t > *m {
                self.k_attack
            } else {
                self.k_release
            };
            *m += (*t - *m) * k;
        }
    }

    /// The target mouth of the last window (module docs).
    fn set_target(&mut self) {
        let w = self.last;
        let s = &self.shapes;
        if !w.speech {
            let closure = (self.since_speech as f64) < CLOSURE_S * SUBS_PER_S as f64;
            let share = if closure { 1.0 } else { 0.0 };
            for (t, c) in self.target.iter_mut().zip(&s.closure) {
                *t = share * c;
            }
            return;
        }
        let rel = self.peak_db - w.level_db;
        let open = 1.0 - smoothstep(OPEN_HIGH_DB, OPEN_LOW_DB, rel);
        let hiss = smoothstep(0.25, 0.5, w.high) * smoothstep(2500.0, 4500.0, w.crossings_s);
        let low = smoothstep(0.8, 0.95, w.low) * (1.0 - hiss);
        // Low and loud: a rounded vowel; low and quiet: a nasal murmur.
        let loud = smoothstep(18.0, 10.0, rel);
        let rounded = low * loud;
        let nasal = low * (1.0 - loud);
        let voiced = (1.0 - hiss) * (1.0 - nasal);
        for (j, t) in self.target.iter_mut().enumerate() {
            let vowel = (1.0 - rounded) * s.open[j] + rounded * s.rounded[j];
            *t = voiced * open * vowel + hiss * s.sibilant[j] + nasal * s.closure[j];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn run(pcm: &[f32], rate: u32) -> (LiveLipSync, Vec<Vec<f32>>) {
        let t = VisemeTable::shipped().unwrap();
        let mut l = LiveLipSync::new(rate, &t).unwrap();
        let mut frames = Vec::new();
        for chunk in pcm.chunks(rate as usize / 50) {
            l.push(chunk, |k, w| {
                assert_eq!(k as usize, frames.len() + 1);
                frames.push(w.to_vec());
            });
        }
        (l, frames)
    }

    /// A vowel-like buzz: harmonics of 120 Hz with a formant-ish fall-off.
    fn buzz(rate: u32, secs: f64, amp: f32) -> Vec<f32> {
        let n = (secs * f64::from(rate)) as usize;
        (0..n)
            .map(|i| {
                let t = i as f32 / rate as f32;
                let s: f32 = (1..=20)
                    .map(|h| (std::f32::consts::TAU * 120.0 * h as f32 * t).sin() / h as f32)
                    .sum();
                amp * s / 2.0
            })
            .collect()
    }

    #[test]
    fn a_vowel_opens_the_jaw_within_a_frame_or_two_and_silence_shuts_it_as_fast() {
        for rate in [8_000u32, 16_000, 22_050, 44_100, 48_000] {
            let sil = |s: f64| vec![0.0f32; (s * f64::from(rate)) as usize];
            let mut pcm = sil(0.5);
            pcm.extend(buzz(rate, 0.3, 0.3));
            pcm.extend(sil(0.5));
            let (l, f) = run(&pcm, rate);
            let jaw = l.names().iter().position(|n| *n == "jawOpen").unwrap();
            let at = |s: f64| f[(s * crate::coart::FPS).round() as usize - 1][jaw];
            assert!(at(0.45) <= 0.01, "{rate}: silence {}", at(0.45));
            // Onset at 0.5 s: open by the second frame after it (33 ms).
            let first = (1..f.len()).find(|&k| f[k - 1][jaw] >= 0.15).unwrap();
            let delay = first as f64 / crate::coart::FPS - 0.5;
            assert!(
                delay > 0.0 && delay <= 2.0 / crate::coart::FPS,
                "{rate}: {delay}"
            );
            assert!(at(0.7) >= 0.4, "{rate}: vowel {}", at(0.7));
            // Offset at 0.8 s: shut (<= 0.05) within 3 frames.
            assert!(at(0.8 + 3.0 / crate::coart::FPS) <= 0.05, "{rate}");
            assert_eq!(f.len() as u64, l.samples() * 60 / u64::from(rate));
        }
    }

    #[test]
    fn hiss_stretches_instead_of_opening() {
        let rate = 16_000;
        // Deterministic white-ish noise (an LCG), loud: a sibilant.
        let mut s = 12345u32;
        let mut pcm = vec![0.0f32; 8000];
        pcm.extend((0..4800).map(|_| {
            s = s.wrapping_mul(1_664_525).wrapping_add(1_013_904_223);
            (s >> 8) as f32 / (1u32 << 24) as f32 * 0.6 - 0.3
        }));
        let (l, f) = run(&pcm, rate);
        let col = |n: &str| l.names().iter().position(|x| *x == n).unwrap();
        let last = f.last().unwrap();
        let w = l.last_window();
        assert!(w.speech && w.high > 0.4, "{w:?}");
        assert!(last[col("jawOpen")] < 0.1, "{}", last[col("jawOpen")]);
        assert!(last[col("mouthStretchLeft")] > 0.2);
    }

    #[test]
    fn a_bad_rate_is_refused() {
        let t = VisemeTable::shipped().unwrap();
        let e = LiveLipSync::new(4000, &t).unwrap_err().to_string();
        assert!(e.contains("4000 Hz"), "{e}");
    }
}
