//! Depth repair of a GFE capture (`docs/gate.md`, "Depth holes"): every point with a pixel gets
//! its depth from the head's depth plane in that frame and the point's own relief; no point keeps
//! a depth the sensor took off the face, and none is left without one.
//!
//! The Kinect v1 tracker gives each point's pixel from the colour image and samples the depth
//! map under it. The pixels are the tracker's; the depths are not: a point on the face's contour
//! or at the mouth often lands on the background (hundreds of mm behind) or on no depth at all
//! (0), and every depth carries several mm of quantisation noise, which the head pose and the
//! controls turn into centimetre jumps. Per frame the head is a plane in depth
//! (`z = a + b·(u − ū) + c·(v − v̄)`: its distance, yaw and pitch), fitted by least squares to the
//! measured depths minus the points' reliefs; a point's relief is its median depth off that plane
//! over the take. A measured depth further than [`OUTLIER_IOD`] inter-ocular distances from
//! plane plus relief is off the face and takes no part in either. Each point's depth is then plane +
//! relief at its pixel: the measurement decides the plane (from some 90 points) and the relief
//! (from the whole take), never one point's depth in one frame. Motion in the image plane (a
//! jaw opening, a smile, brows) is the tracker's; what is lost is expression depth (lips pushed
//! forward), which this sensor's noise buries anyway.

use glam::DVec2;
use mimic_capture::Imported;
use mimic_capture::RecordedFrame;

use super::{FOCAL_PX, FramePixels, back_project};

/// A depth further than this many inter-ocular distances (in depth) from the head plane plus
/// the point's relief is taken as off the face (about 2.5 cm for an adult face).
pub const OUTLIER_IOD: f64 = 0.4;
/// Before the reliefs are known, a depth this many IODs from the frame's median depth is off
/// the face (the background, 10 cm and more behind a face at arm's length).
pub const BACKGROUND_IOD: f64 = 1.5;
/// Fewest points with a usable depth for a frame's head plane; with fewer the frame is kept as
/// measured.
pub const MIN_PLANE_POINTS: usize = 12;
/// Plane / relief refinement rounds.
const ROUNDS: usize = 4;
/// GFE points whose pixel distance gives the face's inter-ocular distance: the eye corners
/// (0, 4: one eye; 8, 12: the other).
const EYE_CORNERS: [usize; 4] = [0, 4, 8, 12];

/// What [`repair_depth`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct DepthRepair {
    /// Points that had a pixel but no depth (0) and were given one.
    pub holes_filled: usize,
    /// Points whose measured depth was off the face and was replaced.
    pub outliers_replaced: usize,
    /// Frames kept as measured (too few depths for a head plane).
    pub frames_kept: usize,
}

/// One frame's head plane in depth (mm) over pixels.
#[derive(Clone, Copy, Debug)]
struct Plane {
    centre: DVec2,
    a: f64,
    b: f64,
    c: f64,
    /// Tolerance (mm): [`OUTLIER_IOD`] of this frame's face.
    tolerance: f64,
}

impl Plane {
    fn at(&self, p: DVec2) -> f64 {
        let q = p - self.centre;
        self.a + self.b * q.x + self.c * q.y
    }
}

/// Repairs the depths of a GFE import (`pixels` its per-frame pixels, from
/// [`super::import_gfe_with_pixels`]) in place and says so in its header's description; points
/// without a pixel stay invalid.
pub fn repair_depth(imported: &mut Imported, pixels: &[FramePixels]) -> DepthRepair {
    let r = repair_frames(&mut imported.frames, pixels);
    if let Some(d) = &mut imported.header.description {
        d.push_str(&format!(
            "; depths repaired (docs/gate.md, depth holes): {} holes filled, {} off-face depths \
             replaced, every depth = the frame's head plane + the point's relief",
            r.holes_filled, r.outliers_replaced
        ));
    }
    r
}

/// [`repair_depth`] on the frames.
fn repair_frames(frames: &mut [RecordedFrame], pixels: &[FramePixels]) -> DepthRepair {
    let mut report = DepthRepair::default();
    let n = frames.len().min(pixels.len());
    let p_count = pixels.first().map_or(0, Vec::len);
    // Measured depth (mm, positive), NaN where there is none.
    let depth: Vec<Vec<f64>> = (0..n)
        .map(|t| {
            (0..p_count)
                .map(|p| {
                    let f = &frames[t].frame;
                    match (f.points.get(p), f.is_valid(p), pixels[t][p]) {
                        (Some(q), true, Some(_)) => -f64::from(q.z) * 1e3,
                        _ => f64::NAN,
                    }
                })
                .collect()
        })
        .collect();
    let mut relief = vec![0.0f64; p_count];
    let mut planes: Vec<Option<Plane>> = vec![None; n];
    let mut inlier: Vec<Vec<bool>> = (0..n)
        .map(|t| background_mask(&depth[t], pixels_iod(&depth[t], &pixels[t])))
        .collect();
    for round in 0..ROUNDS {
        for t in 0..n {
            planes[t] = fit_plane(&depth[t], &pixels[t], &relief, &inlier[t]);
        }
        // Each point's relief: its median depth off the plane over its usable frames.
        let mut off = Vec::with_capacity(n);
        for (p, r) in relief.iter_mut().enumerate() {
            off.clear();
            for t in 0..n {
                if let (Some(pl), Some(px)) = (planes[t], pixels[t][p])
                    && inlier[t][p]
                {
                    off.push(depth[t][p] - pl.at(px));
                }
            }
            if let Some(m) = median(&mut off) {
                *r = m;
            }
        }
        if round + 1 < ROUNDS {
            for t in 0..n {
                let Some(pl) = planes[t] else { continue };
                for p in 0..p_count {
                    inlier[t][p] = match pixels[t][p] {
                        Some(px) if depth[t][p].is_finite() => {
                            (depth[t][p] - pl.at(px) - relief[p]).abs() <= pl.tolerance
                        }
                        _ => false,
                    };
                }
            }
        }
    }
    for t in 0..n {
        let Some(pl) = planes[t] else {
            report.frames_kept += 1;
            continue;
        };
        let frame = &mut frames[t].frame;
        for p in 0..p_count {
            let Some(px) = pixels[t][p] else { continue };
            let z = pl.at(px) + relief[p];
            let Some(q) = back_project(px.x, px.y, z.max(1.0)) else {
                continue;
            };
            if !depth[t][p].is_finite() {
                report.holes_filled += 1;
            } else if (depth[t][p] - z).abs() > pl.tolerance {
                report.outliers_replaced += 1;
            }
            if let Some(slot) = frame.points.get_mut(p) {
                *slot = q;
            }
            if let Some(v) = frame.valid.get_mut(p) {
                *v = true;
            }
        }
    }
    report
}

/// The frame's inter-ocular distance in mm (pixel distance of the eye centres × depth / f), or
/// NaN without the eye corners.
fn pixels_iod(depth: &[f64], pixels: &[Option<DVec2>]) -> f64 {
    let corner = |i: usize| pixels.get(i).copied().flatten();
    let (Some(a), Some(b), Some(c), Some(d)) = (
        corner(EYE_CORNERS[0]),
        corner(EYE_CORNERS[1]),
        corner(EYE_CORNERS[2]),
        corner(EYE_CORNERS[3]),
    ) else {
        return f64::NAN;
    };
    let px = ((a + b) * 0.5).distance((c + d) * 0.5);
    let mut z: Vec<f64> = depth.iter().copied().filter(|z| z.is_finite()).collect();
    median(&mut z).map_or(f64::NAN, |z| px * z / FOCAL_PX)
}

/// Depths within [`BACKGROUND_IOD`] of the frame's median depth.
fn background_mask(depth: &[f64], iod: f64) -> Vec<bool> {
    let mut z: Vec<f64> = depth.iter().copied().filter(|z| z.is_finite()).collect();
    let Some(m) = median(&mut z) else {
        return vec![false; depth.len()];
    };
    let limit = if iod.is_finite() {
        BACKGROUND_IOD * iod
    } else {
        f64::INFINITY
    };
    depth
        .iter()
        .map(|z| z.is_finite() && (z - m).abs() <= limit)
        .collect()
}

/// Least-squares head plane of `depth − relief` over the inliers; `None` with too few, or
/// without the eye corners (no face size).
fn fit_plane(
    depth: &[f64],
    pixels: &[Option<DVec2>],
    relief: &[f64],
    inlier: &[bool],
) -> Option<Plane> {
    let iod = pixels_iod(depth, pixels);
    if !iod.is_finite() || iod <= 0.0 {
        return None;
    }
    let used: Vec<(DVec2, f64)> = (0..depth.len())
        .filter(|&p| inlier[p])
        .filter_map(|p| pixels[p].map(|px| (px, depth[p] - relief[p])))
        .collect();
    if used.len() < MIN_PLANE_POINTS {
        return None;
    }
    let k = used.len() as f64;
    let centre = used.iter().map(|(px, _)| *px).sum::<DVec2>() / k;
    // Normal equations of z = a + b x + c y with centred x, y: a is the mean, (b, c) a 2×2 solve.
    let mean = used.iter().map(|(_, z)| z).sum::<f64>() / k;
    let (mut sxx, mut sxy, mut syy, mut sxz, mut syz) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for (px, z) in &used {
        let q = *px - centre;
        let dz = z - mean;
        sxx += q.x * q.x;
        sxy += q.x * q.y;
        syy += q.y * q.y;
        sxz += q.x * dz;
        syz += q.y * dz;
    }
    let det = sxx * syy - sxy * sxy;
    let (b, c) = if det.abs() > 1e-9 * (sxx * syy).max(1e-12) {
        ((syy * sxz - sxy * syz) / det, (sxx * syz - sxy * sxz) / det)
    } else {
        (0.0, 0.0)
    };
    Some(Plane {
        centre,
        a: mean,
        b,
        c,
        tolerance: OUTLIER_IOD * iod,
    })
}

/// Median of `v` (reordered), `None` when empty.
fn median(v: &mut [f64]) -> Option<f64> {
    if v.is_empty() {
        return None;
    }
    v.sort_unstable_by(f64::total_cmp);
    let m = v.len() / 2;
    Some(if v.len() % 2 == 1 {
        v[m]
    } else {
        0.5 * (v[m - 1] + v[m])
    })
}

/// The camera-space point of pixel `px` at depth `z_mm` (for tests).
#[cfg(test)]
fn point(px: DVec2, z_mm: f64) -> glam::Vec3 {
    back_project(px.x, px.y, z_mm).unwrap_or(glam::Vec3::NAN)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;
    use mimic_types::LandmarkFrame;

    /// A synthetic face: 100 points on a grid of pixels, eye corners 30 px apart in pairs, at
    /// depth `plane + relief` with a yaw slope.
    fn face(frames: usize) -> (Vec<RecordedFrame>, Vec<FramePixels>, Vec<Vec<f64>>) {
        let mut fr = Vec::new();
        let mut px_all = Vec::new();
        let mut truth = Vec::new();
        for t in 0..frames {
            let mut pts = Vec::new();
            let mut pxs = Vec::new();
            let mut zs = Vec::new();
            for p in 0..100 {
                let px = match p {
                    0 => DVec2::new(290.0, 220.0),
                    4 => DVec2::new(280.0, 220.0),
                    8 => DVec2::new(320.0, 220.0),
                    12 => DVec2::new(330.0, 220.0),
                    _ => DVec2::new(270.0 + (p % 10) as f64 * 8.0, 200.0 + (p / 10) as f64 * 8.0),
                };
                let relief = ((p * 37) % 23) as f64 - 11.0;
                let z = 1000.0 + 2.0 * t as f64 + 0.3 * (px.x - 300.0) + relief;
                pts.push(point(px, z));
                pxs.push(Some(px));
                zs.push(z);
            }
            fr.push(RecordedFrame::unlabelled(LandmarkFrame::new(
                t as i64 * 62_000,
                pts,
            )));
            px_all.push(pxs);
            truth.push(zs);
        }
        (fr, px_all, truth)
    }

    #[test]
    fn holes_and_background_samples_get_the_faces_depth() {
        let (mut frames, pixels, truth) = face(20);
        // Frame 7: point 57 has no depth, point 77 hit the background 400 mm behind.
        frames[7].frame.valid[57] = false;
        frames[7].frame.points[57] = Vec3::NAN;
        let px77 = pixels[7][77].unwrap();
        frames[7].frame.points[77] = point(px77, truth[7][77] + 400.0);
        let report = repair_frames(&mut frames, &pixels);
        assert_eq!(report.holes_filled, 1);
        assert_eq!(report.outliers_replaced, 1);
        assert_eq!(report.frames_kept, 0);
        // The synthetic depths are exactly plane + relief: every repaired depth is the truth
        // (to f32 rounding of metres: 1e-4 mm, well under 1e-3 mm).
        for (t, (f, zs)) in frames.iter().zip(&truth).enumerate() {
            for (p, want) in zs.iter().enumerate() {
                assert!(f.frame.is_valid(p));
                let z = -f64::from(f.frame.points[p].z) * 1e3;
                assert!((z - want).abs() < 1e-3, "t {t} p {p}: {z} vs {want}");
            }
        }
    }

    #[test]
    fn a_point_without_a_pixel_stays_invalid_and_one_noisy_depth_is_not_kept() {
        let (mut frames, mut pixels, truth) = face(20);
        pixels[3][50] = None;
        frames[3].frame.valid[50] = false;
        frames[3].frame.points[50] = Vec3::NAN;
        // One frame's depth of point 60 is 10 mm off (noise under the outlier bound): the point
        // takes the plane's depth; what is left is its pull on that frame's least-squares plane,
        // its leverage (under 0.05 for a corner of this 100-point grid) times 10 mm, and its
        // share of the point's take-long median relief (none: the median of 20 ignores one).
        let px = pixels[10][60].unwrap();
        frames[10].frame.points[60] = point(px, truth[10][60] + 10.0);
        repair_frames(&mut frames, &pixels);
        assert!(!frames[3].frame.is_valid(50));
        let z = -f64::from(frames[10].frame.points[60].z) * 1e3;
        assert!(
            (z - truth[10][60]).abs() < 0.05 * 10.0,
            "{z} vs {}",
            truth[10][60]
        );
    }
}
