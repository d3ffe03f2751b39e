//! Coarticulation ([`curves`]): each phone pulls the mouth towards its viseme's weights with a
//! dominance that is full over a hold around its centre and decays exponentially before it
//! (attack) and after it (release); the mouth at a time is the dominance-weighted mean of the
//! phones' weights (Cohen and Massaro's blending), sampled at [`FPS`] frames a second.

use crate::timeline::Phone;
use crate::visemes::VisemeTable;

/// Output frames per second.
pub const FPS: f64 = 60.0;
/// Phones further than this many decay times from a sample are left out of its sum.
const REACH: f64 = 8.0;

/// One phone's dominance at `t` (s).
fn dominance(p: &Phone, v: &crate::visemes::Viseme, t: f64) -> f64 {
    let centre = 0.5 * (p.start_s + p.end_s);
    let half_hold = 0.5 * v.hold * (p.end_s - p.start_s);
    let d = t - centre;
    let tau = if d < 0.0 { v.attack_s } else { v.release_s };
    let past = (d.abs() - half_hold).max(0.0);
    if past > REACH * tau {
        return 0.0;
    }
    v.dominance * (-past / tau).exp()
}

/// The weights (columns of `table.names`) at each of `frames` samples, `1 / FPS` apart from 0.
pub fn curves(phones: &[Phone], table: &VisemeTable, frames: usize) -> Vec<Vec<f32>> {
    let cols = table.names.len();
    let visemes: Vec<_> = phones.iter().map(|p| table.of(&p.name)).collect();
    let mut first = 0;
    (0..frames)
        .map(|k| {
            let t = k as f64 / FPS;
            // Phones are in time order: skip those long past.
            while first < phones.len() && phones[first].end_s + 1.0 < t {
                first += 1;
            }
            let mut sum = vec![0.0f64; cols];
            let mut total = 0.0;
            for (p, v) in phones[first..].iter().zip(&visemes[first..]) {
                if p.start_s > t + 1.0 {
                    break;
                }
                let d = dominance(p, v, t);
                if d > 0.0 {
                    total += d;
                    for (s, w) in sum.iter_mut().zip(&v.weights) {
                        *s += d * f64::from(*w);
                    }
                }
            }
            sum.iter()
                .map(|s| if total > 0.0 { (s / total) as f32 } else { 0.0 })
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ph(name: &str, a: f64, b: f64) -> Phone {
        Phone {
            name: name.into(),
            start_s: a,
            end_s: b,
        }
    }

    #[test]
    fn a_bilabial_closes_the_lips_at_its_centre_between_open_vowels() {
        let t = VisemeTable::shipped().unwrap();
        let jaw = t.column("jawOpen").unwrap();
        let press = t.column("mouthPressLeft").unwrap();
        // "ah-bah": AA 0.1-0.3, B 0.3-0.36, AA 0.36-0.56, silence around.
        let phones = [
            ph("SIL", 0.0, 0.1),
            ph("AA", 0.1, 0.3),
            ph("B", 0.3, 0.36),
            ph("AA", 0.36, 0.56),
            ph("SIL", 0.56, 0.8),
        ];
        let c = curves(&phones, &t, 48);
        let at = |s: f64| &c[(s * FPS).round() as usize];
        assert!(at(0.2)[jaw] > 0.45, "vowel open: {}", at(0.2)[jaw]);
        assert!(at(0.33)[press] >= 0.3, "lips pressed: {}", at(0.33)[press]);
        assert!(
            at(0.33)[jaw] < 0.4 * at(0.2)[jaw],
            "jaw up: {}",
            at(0.33)[jaw]
        );
        // Coarticulation: the jaw eases into and out of the closure, never a step.
        let steps = c.windows(2).map(|w| (w[1][jaw] - w[0][jaw]).abs());
        assert!(steps.fold(0.0f32, f32::max) < 0.3);
        // Silence closes the mouth.
        assert!(at(0.75)[jaw] < 0.02 && at(0.0)[jaw] < 0.05);
    }

    #[test]
    fn neighbours_blend_a_low_dominance_consonant_keeps_the_jaw_of_its_vowels() {
        let t = VisemeTable::shipped().unwrap();
        let jaw = t.column("jawOpen").unwrap();
        let phones = [
            ph("AA", 0.0, 0.2),
            ph("HH", 0.2, 0.25),
            ph("AA", 0.25, 0.45),
        ];
        let c = curves(&phones, &t, 27);
        let mid = c[(0.225 * FPS).round() as usize][jaw];
        assert!(mid > 0.4 && mid < 0.6, "{mid}");
    }
}
