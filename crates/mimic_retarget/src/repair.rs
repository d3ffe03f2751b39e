//! The mouth and chin held to what faces do (issue 45 item 2, `docs/gate.md`, "Tears"): a raw
//! capture's chin and lip controls can move in ways no face does (a depth sample off the chin, a
//! lip point that slid under the other lip), and passed through they tear the mesh. Per accepted
//! frame, before the jitter filter, the displacements of the rig's bottom-region controls are
//! fitted by bounded least squares (weights in [0, 1], `mimic_solve::morph_fit`) onto a plausible
//! subspace: ICT-FaceKit's expression shapes read at the MPEG-4 feature points, carried to the
//! rig by the similarity between ICT's and the rig's controls (so any rig whose controls name
//! those points, in any units and axes). Where what the fit leaves over is longer than
//! `GateSettings::max_mouth_residual` IODs at a control, that control's leftover is shrunk to
//! the bound (the other controls are left as they are). A frame within the bound passes bit for bit.
//! Nothing is allocated per frame.

use glam::Vec3;
use mimic_solve::morph_fit::{MorphFit, MorphScratch};
use mimic_types::{Fdp, Region};

/// ICT-FaceKit's expression shapes at its rig's feature points (module docs), written by
/// `cargo test -p mimic_retarget --test raw_repair` with `MIMIC_BLESS=1` from
/// `configs/meshes/ict-facekit/expressions.shapes` and `configs/rigs/ict-face.toml`: a line
/// `fdps` naming the points, a line `rest` with their rest positions, then one line per shape
/// (its name, then the displacement of every point), lengths in ICT's inter-ocular distances.
pub const ICT_AT_FDPS: &str = include_str!("repair/ict_at_fdps.txt");

/// The bounds `[lips, chin]` (IOD) leave-one-out over the shipped Kinect captures picked
/// (docs/gate.md, "Tears"): set `GateSettings::max_mouth_residual` and `max_chin_residual` to
/// them to turn the repair on (it is off by default, which keeps every shipped golden).
pub const CHOSEN: [f32; 2] = [0.15, 0.1];

/// ARKit's `mouthClose` is a face only with at least as much `jawOpen` (alone it pushes the
/// lower lip 3 cm up through the upper), a condition a box-bounded fit cannot hold on two
/// weights; so the fit's shape is `mouthClose + jawOpen` (lips closed over an open jaw), and
/// `a jawOpen + b (mouthClose + jawOpen)` with `a, b >= 0` is every blend with
/// `mouthClose <= jawOpen`.
const RIDES_ON: (&str, &str) = ("mouthClose", "jawOpen");

/// Ridge of the fit, relative to the mean squared length of the shapes' columns: keeps the
/// system positive definite (the shapes overlap at a few controls) without pulling weights.
const RIDGE: f64 = 1e-4;

/// The parsed table: feature points, rest positions and shapes (IOD units).
#[derive(Debug)]
pub struct Subspace {
    /// The feature points, in table order.
    pub fdps: Vec<Fdp>,
    /// Their rest positions on ICT's head.
    pub rest: Vec<Vec3>,
    /// Per shape: its name and the displacement of every feature point.
    pub shapes: Vec<(String, Vec<Vec3>)>,
}

/// Why the table cannot be read (a build-time file: a test reads it too).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("plausible subspace table, line {line}: {what}")]
pub struct SubspaceError {
    /// 1-based line.
    pub line: usize,
    /// What is wrong.
    pub what: String,
}

impl Subspace {
    /// Reads a table in [`ICT_AT_FDPS`]'s format.
    pub fn parse(text: &str) -> Result<Self, SubspaceError> {
        let mut lines = text
            .lines()
            .enumerate()
            .filter(|(_, l)| !l.trim().is_empty());
        let err = |line: usize, what: &str| SubspaceError {
            line: line + 1,
            what: what.to_string(),
        };
        let (n0, head) = lines.next().ok_or_else(|| err(0, "empty"))?;
        let mut words = head.split_whitespace();
        if words.next() != Some("fdps") {
            return Err(err(n0, "the first line must be `fdps ...`"));
        }
        let fdps = words
            .map(|w| {
                w.parse::<Fdp>()
                    .map_err(|_| err(n0, &format!("`{w}` is no FDP")))
            })
            .collect::<Result<Vec<_>, _>>()?;
        let vectors = |n: usize, rest: &mut dyn Iterator<Item = &str>| {
            let v: Vec<f32> = rest
                .map(|w| {
                    w.parse::<f32>()
                        .map_err(|_| err(n, &format!("`{w}` is no number")))
                })
                .collect::<Result<_, _>>()?;
            if v.len() != 3 * fdps.len() || v.iter().any(|x| !x.is_finite()) {
                return Err(err(n, &format!("{} finite numbers wanted", 3 * fdps.len())));
            }
            Ok::<Vec<Vec3>, SubspaceError>(v.chunks_exact(3).map(Vec3::from_slice).collect())
        };
        let (n1, rest_line) = lines.next().ok_or_else(|| err(n0 + 1, "no `rest` line"))?;
        let mut words = rest_line.split_whitespace();
        if words.next() != Some("rest") {
            return Err(err(n1, "the second line must be `rest ...`"));
        }
        let rest = vectors(n1, &mut words)?;
        let mut shapes = Vec::new();
        for (n, l) in lines {
            let mut words = l.split_whitespace();
            let name = words.next().unwrap_or_default().to_string();
            shapes.push((name, vectors(n, &mut words)?));
        }
        Ok(Self { fdps, rest, shapes })
    }

    /// The shipped table ([`ICT_AT_FDPS`]).
    pub fn ict() -> &'static Subspace {
        static ICT: std::sync::OnceLock<Subspace> = std::sync::OnceLock::new();
        ICT.get_or_init(|| {
            Subspace::parse(ICT_AT_FDPS)
                .unwrap_or_else(|e| unreachable!("the shipped table is checked by a test: {e}"))
        })
    }
}

/// Whether `f` is one of the chin's points (2.1 and the jaw line's 2.10-2.14).
fn is_chin(f: Fdp) -> bool {
    f.group == 2 && (f.index == 1 || (10..=14).contains(&f.index))
}

/// The per-frame repair of one retargeter (module docs).
#[derive(Debug, Clone)]
pub(crate) struct MouthRepair {
    /// The rig's controls it repairs.
    controls: Vec<usize>,
    /// Shape-major: `shapes[s * n + k]`, the displacement of shape `s` at repaired control `k`
    /// (target units).
    shapes: Vec<Vec3>,
    fit: MorphFit,
    scratch: MorphScratch,
    weights: Vec<f32>,
    /// Scratch: the frame's displacements of the repaired controls, and the fit's.
    d: Vec<Vec3>,
    fitted: Vec<Vec3>,
    /// Per repaired control, the residual's bound, target units.
    bounds: Vec<f32>,
}

/// What the repair did to a frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RepairReading {
    /// The fit's largest residual over the repaired controls, IOD.
    pub residual: f32,
    /// Whether the frame was repaired (the residual was over the bound).
    pub repaired: bool,
}

impl MouthRepair {
    /// The repair `gate` asks for on `rig` (its controls standing for `fdps`, face size `face`):
    /// `None` with the gate or the repair off, or a rig it cannot read.
    pub(crate) fn of_rig(
        gate: &crate::GateSettings,
        fdps: &[Option<Fdp>],
        rig: &mimic_types::Rig,
        face: f32,
    ) -> Option<Self> {
        if !gate.enabled {
            return None;
        }
        let regions: Vec<Region> = rig.controls.iter().map(|c| c.region).collect();
        let bounds = [gate.max_mouth_residual, gate.max_chin_residual];
        Self::new(fdps, &regions, &rig.control_positions(), face, bounds)
    }

    /// The repair of a rig whose controls stand for `fdps` (one per control), in `regions`, at
    /// rest at `target` (target units, face size `face`), with the residual bounds `[lips, chin]`
    /// (IOD; a chin bound of 0 is the lips');
    /// `None` when fewer than three bottom controls name a feature point of the table, or the
    /// two faces' points do not fit.
    pub(crate) fn new(
        fdps: &[Option<Fdp>],
        regions: &[Region],
        target: &[Vec3],
        face: f32,
        [lips, chin]: [f32; 2],
    ) -> Option<Self> {
        let table = Subspace::ict();
        let chin = if chin > 0.0 { chin } else { lips };
        if !(lips > 0.0 && lips.is_finite() && chin.is_finite() && face.is_finite()) {
            return None;
        }
        // Every control that names a table point aligns the two faces; the bottom ones are repaired.
        let pairs: Vec<(usize, usize)> = fdps
            .iter()
            .enumerate()
            .filter_map(|(j, f)| Some((j, table.fdps.iter().position(|t| Some(*t) == *f)?)))
            .collect();
        let controls: Vec<(usize, usize)> = pairs
            .iter()
            .copied()
            .filter(|(j, _)| regions[*j] == Region::Bottom)
            .collect();
        if controls.len() < 3 || pairs.len() < 3 {
            return None;
        }
        let src: Vec<Vec3> = pairs.iter().map(|(_, t)| table.rest[*t]).collect();
        let dst: Vec<Vec3> = pairs.iter().map(|(j, _)| target[*j]).collect();
        let pose = mimic_solve::kabsch::fit_similarity(&src, &dst, true)?;
        // Table lengths are ICT IODs; the similarity's scale is target units per IOD, near `face`.
        let per_shape: Vec<Vec<Vec3>> = table
            .shapes
            .iter()
            .map(|(name, s)| {
                let base = (name == RIDES_ON.0)
                    .then(|| table.shapes.iter().find(|(n, _)| n == RIDES_ON.1))
                    .flatten();
                controls
                    .iter()
                    .map(|(_, t)| {
                        let v = s[*t] + base.map_or(Vec3::ZERO, |(_, b)| b[*t]);
                        pose.rotation * v * pose.scale
                    })
                    .collect::<Vec<Vec3>>()
            })
            .filter(|s| s.iter().any(|v| v.length() > 1e-3 * face))
            .collect();
        if per_shape.is_empty() {
            return None;
        }
        let n = controls.len();
        let mean2 = per_shape
            .iter()
            .flatten()
            .map(|v| f64::from(v.length_squared()))
            .sum::<f64>()
            / per_shape.len() as f64;
        let fit = MorphFit::new(&per_shape, RIDGE * mean2).ok()?;
        Some(Self {
            controls: controls.iter().map(|(j, _)| *j).collect(),
            shapes: per_shape.iter().flatten().copied().collect(),
            scratch: fit.scratch(),
            weights: vec![0.0; per_shape.len()],
            fit,
            d: vec![Vec3::ZERO; n],
            fitted: vec![Vec3::ZERO; n],
            bounds: controls
                .iter()
                .map(|(_, t)| face * if is_chin(table.fdps[*t]) { chin } else { lips })
                .collect(),
        })
    }

    /// Repairs `d` (one displacement per rig control, target units) in place; says what it
    /// measured, the residual in IODs of `face`.
    pub(crate) fn apply(&mut self, d: &mut [Vec3], face: f32) -> RepairReading {
        for (x, j) in self.d.iter_mut().zip(&self.controls) {
            *x = d[*j];
        }
        // A fresh start every frame: the result depends on this frame alone (a checkpoint
        // carries no fit state).
        self.scratch.reset();
        self.fit.fit(&self.d, &mut self.scratch, &mut self.weights);
        let n = self.controls.len();
        self.fitted.iter_mut().for_each(|v| *v = Vec3::ZERO);
        for (s, w) in self.weights.iter().enumerate() {
            if *w == 0.0 {
                continue;
            }
            for (f, v) in self.fitted.iter_mut().zip(&self.shapes[s * n..(s + 1) * n]) {
                *f += *v * *w;
            }
        }
        // Only the controls past their bound move: each keeps the bound's length of its
        // leftover, in its own direction.
        let mut reading = RepairReading::default();
        for (((j, x), f), bound) in self
            .controls
            .iter()
            .zip(&self.d)
            .zip(&self.fitted)
            .zip(&self.bounds)
        {
            let r2 = x.distance_squared(*f);
            reading.residual = reading.residual.max(r2);
            if r2 > bound * bound {
                d[*j] = *f + (*x - *f) * (bound / r2.sqrt());
                reading.repaired = true;
            }
        }
        reading.residual = reading.residual.sqrt() / face;
        reading
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Quat;

    /// A rig's controls: their FDPs, regions and rest positions, its face size, and the turn and
    /// scale from the table's axes and units.
    type TestRig = (Vec<Option<Fdp>>, Vec<Region>, Vec<Vec3>, f32, Quat, f32);

    /// A rig made of the table's own points: ICT's head in cm (IOD 6.303), turned and moved
    /// when `turned` (another rig's axes and units), with its bottom controls marked.
    fn rig(turned: bool) -> TestRig {
        let t = Subspace::ict();
        let (q, s) = if turned {
            (
                Quat::from_rotation_y(0.7) * Quat::from_rotation_x(-0.3),
                0.02,
            )
        } else {
            (Quat::IDENTITY, 6.303)
        };
        let target: Vec<Vec3> = t.rest.iter().map(|p| q * *p * s + Vec3::X).collect();
        let regions = t
            .fdps
            .iter()
            .map(|f| {
                if matches!(f.group, 2 | 8) {
                    Region::Bottom
                } else {
                    Region::Top
                }
            })
            .collect();
        let fdps = t.fdps.iter().copied().map(Some).collect();
        let face = crate::face_size(&t.fdps, &target).unwrap();
        (fdps, regions, target, face, q, s)
    }

    /// `sum_k w_k shape_k` at every table point, in the rig's axes and units.
    fn blend(w: &[(usize, f32)], q: Quat, s: f32) -> Vec<Vec3> {
        let t = Subspace::ict();
        (0..t.fdps.len())
            .map(|j| {
                w.iter()
                    .map(|(k, x)| q * t.shapes[*k].1[j] * (s * *x))
                    .sum()
            })
            .collect()
    }

    #[test]
    fn icts_own_shapes_pass_bit_for_bit_in_any_axes_and_units() {
        let t = Subspace::ict();
        for turned in [false, true] {
            let (fdps, regions, target, face, q, s) = rig(turned);
            let mut r = MouthRepair::new(&fdps, &regions, &target, face, [0.15, 0.1]).unwrap();
            let mut seed = 7u64;
            let mut next = || {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (seed >> 40) as f32 / (1u64 << 24) as f32
            };
            // Each shape but mouthClose at full weight, and 200 blends of three of them with
            // weights in [0, 1].
            let close = t.shapes.iter().position(|(n, _)| n == RIDES_ON.0).unwrap();
            let open = t.shapes.iter().position(|(n, _)| n == RIDES_ON.1).unwrap();
            let kept: Vec<usize> = (0..t.shapes.len()).filter(|k| *k != close).collect();
            let mut cases: Vec<Vec<(usize, f32)>> = kept.iter().map(|k| vec![(*k, 1.0)]).collect();
            for _ in 0..200 {
                let n = kept.len() as f32;
                cases.push(
                    (0..3)
                        .map(|_| (kept[(next() * n) as usize], next()))
                        .collect(),
                );
            }
            // mouthClose alone drives the lower lip up through the upper: repaired.
            let mut lips = blend(&[(close, 1.0)], q, s);
            assert!(r.apply(&mut lips, face).repaired);
            // ARKit's mouthClose as it is used: with at least as much jawOpen.
            cases.push(vec![(open, 1.0), (close, 1.0)]);
            cases.push(vec![(open, 0.6), (close, 0.3), (kept[5], 0.5)]);
            for w in cases {
                let d = blend(&w, q, s);
                let mut out = d.clone();
                let reading = r.apply(&mut out, face);
                assert!(!reading.repaired, "{w:?}: {reading:?}");
                assert_eq!(out, d);
            }
        }
    }

    #[test]
    fn a_chin_pushed_back_alone_is_pulled_to_the_bound() {
        let (fdps, regions, target, face, q, s) = rig(true);
        let bound = 0.15;
        let mut r = MouthRepair::new(&fdps, &regions, &target, face, [bound, 0.0]).unwrap();
        let t = Subspace::ict();
        let chin = t.fdps.iter().position(|f| f.to_string() == "2.1").unwrap();
        let brow = t.fdps.iter().position(|f| f.to_string() == "4.1").unwrap();
        // A smile, with the chin pushed 0.5 IOD straight back (no face moves its chin so) and
        // a brow raised: the chin is repaired, the brow (not a mouth control) is not.
        let smile = t
            .shapes
            .iter()
            .position(|(n, _)| n == "mouthSmile_L")
            .unwrap();
        let mut d = blend(&[(smile, 0.8)], q, s);
        d[chin] += q * Vec3::NEG_Z * (0.5 * face);
        d[brow] += q * Vec3::Y * (0.3 * face);
        let before = d.clone();
        let reading = r.apply(&mut d, face);
        assert!(reading.repaired && reading.residual > 0.3, "{reading:?}");
        assert_eq!(d[brow], before[brow]);
        // The chin moved back toward the plausible: by at least the residual past the bound.
        let moved = d[chin].distance(before[chin]) / face;
        assert!(
            moved >= reading.residual - bound - 1e-4,
            "{moved} {reading:?}"
        );
        // Fitted again, the repaired frame is far closer to the subspace (the fit itself moves
        // with the data, so not exactly within the bound).
        let again = r.apply(&mut d, face);
        assert!(
            again.residual < 0.5 * reading.residual,
            "{again:?} after {reading:?}"
        );
    }
}
