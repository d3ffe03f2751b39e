//! Whether a mesh's eyes are open holes or closed skin, which picks a generated rig's solver.
//!
//! Heads made for animation (ICT-FaceKit, game and VTuber avatars) have lids around an opening,
//! with the eyeball (and often a socket) behind it: going over the skin from the upper lid to the
//! lower one means going round the eye corner, about twice their straight distance. Morphable
//! face models (the Surrey Face Model, the Basel Face Model) are masks whose eye is one sheet of
//! skin: the path goes straight across. The two kinds want different solvers (docs/rigging.md,
//! "Which solver"): across an opening the thin shell carries a blink into the brow, which the
//! RBF's lid / brow split prevents; on a mask the shell's smooth field is the better fit.

use crate::landmarks::Landmarks;
use glam::Vec3;
use mimic_solve::geodesic::EdgeGraph;

/// iBUG pairs across each eye: upper lid over lower lid (right eye 37/41, 38/40; left eye
/// 43/47, 44/46).
pub const LID_PAIRS: [(usize, usize); 4] = [(37, 41), (38, 40), (43, 47), (44, 46)];

/// Surface over straight distance across the eyes above which the eyes count as open.
pub const OPEN_RATIO: f64 = 1.5;

/// What was measured across the eyes.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct EyeOpening {
    /// Median over the lid pairs of the edge-path distance over the straight distance.
    pub ratio: f64,
    /// How many lid pairs were measured (pairs with a landmark missing are skipped).
    pub pairs: usize,
}

impl EyeOpening {
    /// Whether the eyes are open holes (ratio above [`OPEN_RATIO`]).
    pub fn open(&self) -> bool {
        self.ratio > OPEN_RATIO
    }
}

/// Measures the lid pairs of `marks` over the mesh (`positions`, `triangles`); `None` when no
/// pair has both landmarks. Lids on one position count as closed (ratio 1).
pub fn eye_opening(
    positions: &[Vec3],
    triangles: &[[u32; 3]],
    marks: &Landmarks,
) -> Option<EyeOpening> {
    let pairs: Vec<(usize, usize)> = LID_PAIRS
        .iter()
        .filter_map(|&(a, b)| Some((marks.get(a)? as usize, marks.get(b)? as usize)))
        .filter(|&(a, b)| a < positions.len() && b < positions.len())
        .collect();
    if pairs.is_empty() {
        return None;
    }
    let graph = EdgeGraph::new(positions, triangles);
    let mut ratios: Vec<f64> = pairs
        .iter()
        .map(|&(a, b)| {
            let straight = f64::from((positions[a] - positions[b]).length());
            // Lids on one position (or one vertex) meet: closed, whatever the path.
            if straight > 0.0 {
                graph.distances_from(a)[b] / straight
            } else {
                1.0
            }
        })
        .collect();
    Some(EyeOpening {
        ratio: mimic_solve::stats::median(&mut ratios),
        pairs: ratios.len(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An `n x n` grid of unit cells; with `hole`, the cells of columns 3..7 on row 4 are left
    /// out: a slit, like an eye opening.
    fn grid(n: usize, hole: bool) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let positions = (0..n * n)
            .map(|k| Vec3::new((k % n) as f32, (k / n) as f32, 0.0))
            .collect();
        let mut triangles = Vec::new();
        for j in 0..n - 1 {
            for i in 0..n - 1 {
                if hole && j == 4 && (3..7).contains(&i) {
                    continue;
                }
                let a = (j * n + i) as u32;
                let (b, c, d) = (a + 1, a + n as u32, a + n as u32 + 1);
                triangles.push([a, b, d]);
                triangles.push([a, d, c]);
            }
        }
        (positions, triangles)
    }

    /// Lid pairs straight across the slit: vertex (i, 5) over (i, 4) for i = 4, 5, 4, 5.
    fn marks(n: usize) -> Landmarks {
        let mut m = Landmarks {
            vertex: [None; crate::IBUG_POINTS],
        };
        for (k, &(up, low)) in LID_PAIRS.iter().enumerate() {
            let i = 4 + k % 2;
            m.vertex[up] = Some((5 * n + i) as u32);
            m.vertex[low] = Some((4 * n + i) as u32);
        }
        m
    }

    #[test]
    fn a_slit_between_the_lids_is_open_and_skin_is_closed() {
        let n = 10;
        let (p, t) = grid(n, false);
        let closed = eye_opening(&p, &t, &marks(n)).unwrap();
        // One edge straight across: the path is the straight line.
        assert_eq!(closed.pairs, 4);
        assert!((closed.ratio - 1.0).abs() < 1e-9, "{closed:?}");
        assert!(!closed.open());
        let (p, t) = grid(n, true);
        let open = eye_opening(&p, &t, &marks(n)).unwrap();
        // The slit removes the edges across it at columns 4..=6: from (4, 5) to (4, 4) the
        // path goes round column 3 (1 + 1 + 1 = 3), from (5, 5) round column 3 or 7 (2 + 1 + 2
        // = 5); the median of 3, 5, 3, 5 is 4.
        assert!((open.ratio - 4.0).abs() < 1e-9, "{open:?}");
        assert!(open.open());
    }

    #[test]
    fn missing_lid_landmarks_give_no_measure_and_meeting_lids_are_closed() {
        let n = 10;
        let (p, t) = grid(n, false);
        let mut m = marks(n);
        for (a, _) in LID_PAIRS {
            m.vertex[a] = None;
        }
        assert_eq!(eye_opening(&p, &t, &m), None);
        m.vertex[37] = Some(0);
        m.vertex[41] = Some(0);
        let e = eye_opening(&p, &t, &m).unwrap();
        assert_eq!(
            (e.pairs, e.ratio),
            (1, 1.0),
            "lids on one vertex are closed"
        );
        assert!(!e.open());
    }
}
