//! The 38 controls from the iBUG landmarks: 25 are iBUG points, 13 are placed by rules written
//! once, relative to the landmarks in the face frame (the notes of `configs/rigs/ict-face.toml`).

use crate::landmarks::Landmarks;
use glam::{Vec2, Vec3};
use mimic_types::{Fdp, Region};

/// How one control is found.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Rule {
    /// The vertex of this iBUG point.
    Ibug(usize),
    /// The skin vertex nearest to the mean of two iBUG points (lid centres, outer-lip midpoints).
    Mean(usize, usize),
    /// Cheek centre: the frontmost skin vertex at the height of this mouth corner and
    /// [`CHEEK_OUT`] half mouth widths from the midline.
    Cheek(usize),
    /// Cheek bone: the frontmost skin vertex halfway between the eye centre and this outer eye
    /// corner across, halfway between the nose base (iBUG 33) and the nose bridge (iBUG 28) in
    /// height (MPEG-4's constraints on 5.3/5.4).
    CheekBone {
        /// Outer corner of that eye.
        outer: usize,
        /// Inner corner of that eye.
        inner: usize,
    },
    /// Chin boss: on the midline profile between the lower lip (iBUG 57) and the menton (iBUG 8),
    /// the frontmost point below the labiomental fold (the profile's deepest point in its upper
    /// half).
    ChinBoss,
}

/// Cheek centres sit this many half mouth widths from the midline (CANDIDE-3 vertices 90/91).
pub const CHEEK_OUT: f32 = 1.45;

/// The 38 controls: FDP, region, rule.
pub const CONTROLS: [((u8, u8), Region, Rule); 38] = {
    use Region::{Bottom, Middle, Top};
    use Rule::{Cheek, CheekBone, ChinBoss, Ibug, Mean};
    [
        ((4, 1), Top, Ibug(22)),
        ((4, 2), Top, Ibug(21)),
        ((4, 3), Top, Ibug(24)),
        ((4, 4), Top, Ibug(19)),
        ((4, 5), Top, Ibug(26)),
        ((4, 6), Top, Ibug(17)),
        ((3, 1), Top, Mean(43, 44)),
        ((3, 2), Top, Mean(37, 38)),
        ((3, 3), Top, Mean(46, 47)),
        ((3, 4), Top, Mean(40, 41)),
        ((3, 7), Top, Ibug(45)),
        ((3, 8), Top, Ibug(39)),
        ((3, 11), Top, Ibug(42)),
        ((3, 12), Top, Ibug(36)),
        ((9, 3), Middle, Ibug(30)),
        ((9, 4), Middle, Ibug(31)),
        ((9, 5), Middle, Ibug(35)),
        ((9, 15), Middle, Ibug(33)),
        ((5, 1), Middle, Cheek(54)),
        ((5, 2), Middle, Cheek(48)),
        (
            (5, 3),
            Middle,
            CheekBone {
                outer: 45,
                inner: 42,
            },
        ),
        (
            (5, 4),
            Middle,
            CheekBone {
                outer: 36,
                inner: 39,
            },
        ),
        ((8, 1), Bottom, Ibug(51)),
        ((8, 2), Bottom, Ibug(57)),
        ((8, 3), Bottom, Ibug(54)),
        ((8, 4), Bottom, Ibug(48)),
        ((8, 5), Bottom, Mean(52, 53)),
        ((8, 6), Bottom, Mean(49, 50)),
        ((8, 7), Bottom, Mean(55, 56)),
        ((8, 8), Bottom, Mean(58, 59)),
        ((2, 2), Bottom, Ibug(62)),
        ((2, 3), Bottom, Ibug(66)),
        ((2, 4), Bottom, Ibug(64)),
        ((2, 5), Bottom, Ibug(60)),
        ((2, 1), Bottom, Ibug(8)),
        ((2, 10), Bottom, ChinBoss),
        ((2, 11), Bottom, Ibug(9)),
        ((2, 12), Bottom, Ibug(7)),
    ]
};

/// The FDP of a [`CONTROLS`] entry.
pub fn fdp_of(id: (u8, u8)) -> Fdp {
    Fdp {
        group: id.0,
        index: id.1,
    }
}

/// iBUG points a rule needs.
pub fn rule_needs(rule: Rule) -> Vec<usize> {
    match rule {
        Rule::Ibug(n) => vec![n],
        Rule::Mean(a, b) => vec![a, b],
        Rule::Cheek(c) => vec![48, 54, c],
        Rule::CheekBone { outer, inner } => vec![outer, inner, 28, 33],
        Rule::ChinBoss => vec![8, 57],
    }
}

/// One placed control.
#[derive(Clone, Debug, PartialEq)]
pub struct Placed {
    /// The feature point.
    pub fdp: Fdp,
    /// The mesh vertex carrying it.
    pub vertex: u32,
    /// Its region.
    pub region: Region,
    /// How it was found (written as the control's `note`).
    pub note: String,
}

/// What the placement rules look at: face coordinates of every vertex and which are skin.
pub struct Surface<'a> {
    /// Face coordinates (IOD units) per vertex.
    pub face: &'a [Vec3],
    /// Vertices a rule may pick (the skin piece: the connected piece with the most landmarks).
    pub skin: &'a [bool],
    /// The landmark vertices.
    pub landmarks: &'a Landmarks,
}

impl Surface<'_> {
    fn at(&self, n: usize) -> Vec3 {
        self.landmarks
            .get(n)
            .map_or(Vec3::ZERO, |v| self.face[v as usize])
    }

    /// Skin vertex nearest to `q` (face coordinates); ties go to the lower index.
    fn nearest(&self, q: Vec3) -> Option<(u32, f32)> {
        let mut best: Option<(u32, f32)> = None;
        for (i, p) in self.face.iter().enumerate() {
            if !self.skin[i] {
                continue;
            }
            let d = p.distance_squared(q);
            if best.is_none_or(|(_, b)| d < b) {
                best = Some((i as u32, d));
            }
        }
        best.map(|(i, d)| (i, d.sqrt()))
    }

    /// The skin vertex where a ray along -z (face frame) through `xy` first meets the skin:
    /// of the skin vertices within a face-plane distance of `xy` (0.05 IOD, doubled until
    /// some are that close), those within 0.05 IOD of the frontmost one's depth are the front
    /// surface, and the one of them nearest to the ray is taken.
    fn frontmost(&self, xy: Vec2) -> Option<u32> {
        let mut tol = 0.05f32;
        for _ in 0..6 {
            let near: Vec<(u32, Vec3)> = self
                .face
                .iter()
                .enumerate()
                .filter(|(i, p)| self.skin[*i] && p.truncate().distance_squared(xy) <= tol * tol)
                .map(|(i, p)| (i as u32, *p))
                .collect();
            if let Some(front) = near.iter().map(|(_, p)| p.z).reduce(f32::max) {
                return near
                    .iter()
                    .filter(|(_, p)| p.z >= front - 0.05)
                    .min_by(|a, b| {
                        let da = a.1.truncate().distance_squared(xy);
                        let db = b.1.truncate().distance_squared(xy);
                        da.total_cmp(&db).then(a.0.cmp(&b.0))
                    })
                    .map(|p| p.0);
            }
            tol *= 2.0;
        }
        None
    }

    /// The chin boss vertex (see [`Rule::ChinBoss`]): the midline strip's skin vertices within
    /// 0.1 IOD of the chord from the lower lip to the menton (not the mouth socket behind),
    /// the fold the deepest of them in the upper half, the boss the frontmost below the fold.
    fn chin_boss(&self) -> Option<u32> {
        let (lip, menton) = (self.at(57), self.at(8));
        let (top, bottom) = (lip.y, menton.y);
        if top <= bottom {
            return None;
        }
        let chord = Vec2::new(menton.y - lip.y, menton.z - lip.z);
        let len = chord.length();
        let off = |p: &Vec3| {
            let v = Vec2::new(p.y - lip.y, p.z - lip.z);
            (chord.x * v.y - chord.y * v.x) / len
        };
        let strip: Vec<(u32, Vec3)> = self
            .face
            .iter()
            .enumerate()
            .filter(|(i, p)| {
                self.skin[*i]
                    && p.x.abs() <= 0.02
                    && p.y <= top
                    && p.y >= bottom
                    && off(p).abs() <= 0.1
            })
            .map(|(i, p)| (i as u32, *p))
            .collect();
        let half = (top + bottom) * 0.5;
        let fold = strip
            .iter()
            .filter(|(_, p)| p.y >= half)
            .min_by(|a, b| a.1.z.total_cmp(&b.1.z).then(a.0.cmp(&b.0)))?
            .1
            .y;
        strip
            .iter()
            .filter(|(_, p)| p.y < fold)
            .max_by(|a, b| a.1.z.total_cmp(&b.1.z).then(b.0.cmp(&a.0)))
            .map(|p| p.0)
    }

    /// Places one control; `None` when the rule finds no vertex.
    pub fn place(&self, rule: Rule) -> Option<(u32, String)> {
        match rule {
            Rule::Ibug(n) => {
                let v = self.landmarks.get(n)?;
                Some((v, format!("iBUG {n} (landmark vertex {v})")))
            }
            Rule::Mean(a, b) => {
                let (v, d) = self.nearest((self.at(a) + self.at(b)) * 0.5)?;
                Some((
                    v,
                    format!("nearest skin vertex to the mean of iBUG {a}/{b} ({d:.3} IOD away)"),
                ))
            }
            Rule::Cheek(c) => {
                let (l, r) = (self.at(54), self.at(48));
                let mid = (l.x + r.x) * 0.5;
                let half = (l.x - r.x).abs() * 0.5;
                let corner = self.at(c);
                let side = if corner.x >= mid { 1.0 } else { -1.0 };
                let x = mid + side * CHEEK_OUT * half;
                let v = self.frontmost(Vec2::new(x, corner.y))?;
                Some((
                    v,
                    format!(
                        "frontmost skin vertex at the height of the mouth corner (iBUG {c}) and {CHEEK_OUT} half mouth widths from the midline"
                    ),
                ))
            }
            Rule::CheekBone { outer, inner } => {
                let (o, i) = (self.at(outer), self.at(inner));
                let centre = (o + i) * 0.5;
                let x = (centre.x + o.x) * 0.5;
                let y = (self.at(33).y + self.at(28).y) * 0.5;
                let v = self.frontmost(Vec2::new(x, y))?;
                Some((
                    v,
                    format!(
                        "frontmost skin vertex halfway between the eye centre and the outer corner (iBUG {outer}) across, halfway between the nose base (iBUG 33) and bridge (iBUG 28) in height"
                    ),
                ))
            }
            Rule::ChinBoss => {
                let v = self.chin_boss()?;
                Some((
                    v,
                    "chin boss: frontmost midline vertex below the labiomental fold (deepest midline point between iBUG 57 and 8, upper half)".into(),
                ))
            }
        }
    }
}
