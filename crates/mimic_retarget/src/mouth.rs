//! The mouth from another source than the tracker (lip sync from speech, `replay --audio`):
//! a track of ARKit mouth weights in time, the control displacements each weight implies
//! (`D_k` at the rig's controls, target units), and a per-control mix. Per frame,
//! [`MouthDrive::apply`] replaces `d_j` by `(1 - m_j) d_j + m_j sum_k w_k(t) D_kj`: the mouth's
//! controls (`m_j = 1`) follow the weights, the rest (`m_j = 0`) the tracker, and the solver's
//! region blend carries the seam between them. Outside the track's time span the tracker keeps
//! the mouth. Nothing is allocated per frame.

use glam::Vec3;

/// Why a mouth drive cannot be set up.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MouthError {
    /// The sizes given do not agree.
    #[error("mouth drive: {0}")]
    Shape(String),
    /// No weight of the track has a shape, or no control is the mouth's.
    #[error("mouth drive: {0}")]
    Empty(String),
}

/// Weights in time that drive a rig's mouth controls.
#[derive(Clone, Debug)]
pub struct MouthDrive {
    /// Per control, how much of it the weights drive (0: the tracker's, 1: the weights').
    mix: Vec<f32>,
    /// Per track column with a shape: the column, and the shape's `D` at every control.
    columns: Vec<usize>,
    /// Shape-major: `shapes[s * m + j]` for driven column `s`, control `j`.
    shapes: Vec<Vec3>,
    /// Track names with no shape (left out).
    lacking: Vec<String>,
    /// The track's names (its columns).
    names: Vec<&'static str>,
    /// The track's weights at the last applied time, if it was inside the track.
    now: Vec<f32>,
    active: bool,
    /// Frame-major weights, `width` columns each.
    rows: Vec<f32>,
    width: usize,
    rate_hz: f64,
    /// Microseconds from the first frame at which the track's time 0 falls.
    offset_us: i64,
    /// Timestamp of the first frame seen.
    start_us: Option<i64>,
    /// The implied displacement of each control at the last applied time (scratch).
    implied: Vec<Vec3>,
}

impl MouthDrive {
    /// A drive of `mix.len()` controls: `names` are the track's columns, `rows` its weights per
    /// frame at `rate_hz` from time 0 (each `names.len()` long), `shapes` the displacement each
    /// name implies at every control (`None`: the rig has no such shape; left out and listed by
    /// [`MouthDrive::lacking`]); the track starts `offset_s` after the first frame it is given.
    pub fn new(
        mix: Vec<f32>,
        names: &[&'static str],
        shapes: &[Option<Vec<Vec3>>],
        rows: &[Vec<f32>],
        rate_hz: f64,
        offset_s: f64,
    ) -> Result<Self, MouthError> {
        let m = mix.len();
        if shapes.len() != names.len() {
            return Err(MouthError::Shape(format!(
                "{} names but {} shapes",
                names.len(),
                shapes.len()
            )));
        }
        if !(rate_hz.is_finite() && rate_hz > 0.0 && offset_s.is_finite()) {
            return Err(MouthError::Shape(format!(
                "rate {rate_hz} Hz and offset {offset_s} s must be finite, the rate positive"
            )));
        }
        if let Some((k, r)) = rows
            .iter()
            .enumerate()
            .find(|(_, r)| r.len() != names.len())
        {
            return Err(MouthError::Shape(format!(
                "frame {k} has {} weights for {} names",
                r.len(),
                names.len()
            )));
        }
        let (mut columns, mut flat, mut lacking) = (Vec::new(), Vec::new(), Vec::new());
        for (c, (name, shape)) in names.iter().zip(shapes).enumerate() {
            match shape {
                Some(s) if s.len() == m => {
                    columns.push(c);
                    flat.extend_from_slice(s);
                }
                Some(s) => {
                    return Err(MouthError::Shape(format!(
                        "shape `{name}` has {} controls, the rig {m}",
                        s.len()
                    )));
                }
                None => lacking.push((*name).to_string()),
            }
        }
        if columns.is_empty() {
            return Err(MouthError::Empty(format!(
                "the rig has none of the shapes {}",
                names.join(", ")
            )));
        }
        if !mix.iter().any(|w| *w > 0.0) {
            return Err(MouthError::Empty(
                "the rig has no mouth control (region bottom) to drive".into(),
            ));
        }
        Ok(Self {
            mix: mix.into_iter().map(|w| w.clamp(0.0, 1.0)).collect(),
            columns,
            shapes: flat,
            lacking,
            names: names.to_vec(),
            now: vec![0.0; names.len()],
            active: false,
            rows: rows.iter().flatten().copied().collect(),
            width: names.len(),
            rate_hz,
            offset_us: (offset_s * 1e6).round() as i64,
            start_us: None,
            implied: vec![Vec3::ZERO; m],
        })
    }

    /// The track's names the rig has no shape for.
    pub fn lacking(&self) -> &[String] {
        &self.lacking
    }

    /// How many of the rig's controls the weights drive (wholly or in part).
    pub fn driven_controls(&self) -> usize {
        self.mix.iter().filter(|w| **w > 0.0).count()
    }

    /// The track's names and weights at the last applied frame (every column, those with no
    /// shape too), or `None` when that frame fell outside the track.
    pub fn weights(&self) -> Option<(&[&'static str], &[f32])> {
        self.active.then_some((&self.names[..], &self.now[..]))
    }

    /// The track's frame position at frame time `t_us` (the first call fixes time 0), or
    /// `None` outside the track.
    fn position(&mut self, t_us: i64) -> Option<f64> {
        let start = *self.start_us.get_or_insert(t_us);
        let t = (t_us.saturating_sub(start).saturating_sub(self.offset_us)) as f64 * 1e-6;
        let frames = self.rows.len() / self.width.max(1);
        let x = t * self.rate_hz;
        (x >= 0.0 && frames > 0 && x <= (frames - 1) as f64).then_some(x)
    }

    /// Mixes the weights' displacements at frame time `t_us` into `d` (one per control).
    pub fn apply(&mut self, t_us: i64, d: &mut [Vec3]) {
        let Some(x) = self.position(t_us) else {
            self.active = false;
            return;
        };
        self.active = true;
        let m = self.mix.len();
        let k0 = x.floor() as usize;
        let frames = self.rows.len() / self.width;
        let k1 = (k0 + 1).min(frames - 1);
        let f = (x - k0 as f64) as f32;
        for (c, now) in self.now.iter_mut().enumerate() {
            let w0 = self.rows[k0 * self.width + c];
            *now = w0 + (self.rows[k1 * self.width + c] - w0) * f;
        }
        self.implied.iter_mut().for_each(|v| *v = Vec3::ZERO);
        for (s, &c) in self.columns.iter().enumerate() {
            let w = self.now[c];
            if w == 0.0 {
                continue;
            }
            let shape = &self.shapes[s * m..(s + 1) * m];
            for (v, dk) in self.implied.iter_mut().zip(shape) {
                *v += *dk * w;
            }
        }
        for ((dj, v), w) in d.iter_mut().zip(&self.implied).zip(&self.mix) {
            *dj += (*v - *dj) * *w;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drive(offset_s: f64) -> MouthDrive {
        // Two controls, the first the mouth's; shape `a` moves it down by 1, `b` forward by 2.
        let shapes = vec![
            Some(vec![Vec3::new(0.0, -1.0, 0.0), Vec3::new(9.0, 9.0, 9.0)]),
            None,
            Some(vec![Vec3::new(0.0, 0.0, 2.0), Vec3::ZERO]),
        ];
        let rows = vec![vec![0.0, 1.0, 0.0], vec![1.0, 1.0, 0.5]];
        MouthDrive::new(
            vec![1.0, 0.0],
            &["a", "tongueOut", "b"],
            &shapes,
            &rows,
            10.0,
            offset_s,
        )
        .unwrap()
    }

    #[test]
    fn the_mouth_follows_the_weights_and_the_rest_the_tracker() {
        let mut m = drive(0.0);
        assert_eq!(m.lacking(), ["tongueOut"]);
        assert_eq!(m.driven_controls(), 1);
        let tracker = [Vec3::new(0.3, 0.3, 0.3), Vec3::new(-1.0, 2.0, 0.5)];
        // First frame at t = 5 s is time 0: row 0, all zero: the mouth at rest.
        let mut d = tracker;
        m.apply(5_000_000, &mut d);
        assert_eq!(d, [Vec3::ZERO, tracker[1]]);
        // Halfway between the rows (0.05 s): w_a = 0.5, w_b = 0.25.
        let mut d = tracker;
        m.apply(5_050_000, &mut d);
        let want = Vec3::new(0.0, -0.5, 0.5);
        assert!(d[0].distance(want) <= 4.0 * f32::EPSILON, "{:?}", d[0]);
        assert_eq!(d[1], tracker[1]);
        let (names, w) = m.weights().unwrap();
        assert_eq!(names, ["a", "tongueOut", "b"]);
        assert_eq!(w, [0.5, 1.0, 0.25]);
        // Past the track's end the tracker keeps the mouth.
        let mut d = tracker;
        m.apply(5_200_000, &mut d);
        assert_eq!(d, tracker);
        assert!(m.weights().is_none());
    }

    #[test]
    fn an_offset_delays_the_track() {
        let mut m = drive(0.1);
        let tracker = [Vec3::ONE, Vec3::ONE];
        let mut d = tracker;
        m.apply(0, &mut d);
        assert_eq!(d, tracker, "before the track starts");
        let mut d = tracker;
        m.apply(200_000, &mut d);
        // 0.1 s into the track: row 1, w_a = 1, w_b = 0.5.
        assert!(d[0].distance(Vec3::new(0.0, -1.0, 1.0)) <= 4.0 * f32::EPSILON);
    }

    #[test]
    fn bad_set_ups_are_refused() {
        let rows = vec![vec![0.0]];
        let none = MouthDrive::new(vec![1.0], &["x"], &[None], &rows, 60.0, 0.0);
        assert!(matches!(none, Err(MouthError::Empty(_))));
        let no_mouth = MouthDrive::new(vec![0.0], &["x"], &[Some(vec![Vec3::X])], &rows, 60.0, 0.0);
        assert!(matches!(no_mouth, Err(MouthError::Empty(_))));
        let short = MouthDrive::new(
            vec![1.0],
            &["x"],
            &[Some(vec![Vec3::X])],
            &[vec![]],
            60.0,
            0.0,
        );
        assert!(matches!(short, Err(MouthError::Shape(_))));
    }
}
