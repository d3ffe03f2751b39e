//! Quick expression switching: number keys 1-9 blend the rig's first nine morph targets in and
//! out over [`EASE_SECONDS`], on top of the retargeted face.
//!
//! The GPU morphs `P = P0 + B d`; a morph target `dP_k` becomes three more columns of `B` (its x,
//! y and z deltas as scalar weights, [`extend_basis`]) driven by `w_k` along each axis
//! ([`Expressions::extend_d`]), so `P = P0 + B d + sum_k w_k dP_k` is drawn by the same passes.

use glam::Vec3;
use mimic_solve::Basis;
use mimic_types::MorphTarget;

/// Seconds a number key takes to blend an expression fully in or out.
pub const EASE_SECONDS: f32 = 0.25;
/// Most expressions on keys (1-9).
pub const MAX_KEYS: usize = 9;

/// The weights of the expressions on the number keys, each easing towards 0 or 1.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Expressions {
    names: Vec<String>,
    target: Vec<f32>,
    weight: Vec<f32>,
}

impl Expressions {
    /// Expressions named `names` (the first [`MAX_KEYS`] are kept), all off.
    pub fn new(names: impl IntoIterator<Item = String>) -> Self {
        let names: Vec<String> = names.into_iter().take(MAX_KEYS).collect();
        let n = names.len();
        Self {
            names,
            target: vec![0.0; n],
            weight: vec![0.0; n],
        }
    }

    /// Number of expressions on keys.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Names of the expressions on keys, key 1 first.
    pub fn names(&self) -> &[String] {
        &self.names
    }

    /// Whether no expression is on a key.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// Key `k` (0-based: key 1 is 0) pressed: its expression blends in if it was off or going
    /// out, else out. Returns false when no expression is on that key.
    pub fn toggle(&mut self, k: usize) -> bool {
        let Some(t) = self.target.get_mut(k) else {
            return false;
        };
        *t = if *t > 0.5 { 0.0 } else { 1.0 };
        true
    }

    /// Moves each weight towards its target by `dt / EASE_SECONDS` (linear in time, smoothed by
    /// [`Expressions::eased`] when drawn); returns whether any weight changed.
    pub fn advance(&mut self, dt: f32) -> bool {
        let step = (dt / EASE_SECONDS).max(0.0);
        let mut changed = false;
        for (w, t) in self.weight.iter_mut().zip(&self.target) {
            let next = if *w < *t {
                (*w + step).min(*t)
            } else {
                (*w - step).max(*t)
            };
            changed |= next != *w;
            *w = next;
        }
        changed
    }

    /// The drawn weight of expression `k`: smoothstep of its linear progress (0 and 1 exact).
    pub fn eased(&self, k: usize) -> f32 {
        let x = self.weight.get(k).copied().unwrap_or(0.0).clamp(0.0, 1.0);
        x * x * (3.0 - 2.0 * x)
    }

    /// Writes `d` followed by three displacements per expression (`w_k` along x, y and z) into
    /// `out`, the displacements of the basis [`extend_basis`] made.
    pub fn extend_d(&self, d: &[Vec3], out: &mut Vec<Vec3>) {
        out.clear();
        out.extend_from_slice(d);
        for k in 0..self.len() {
            let w = self.eased(k);
            out.extend([
                Vec3::new(w, 0.0, 0.0),
                Vec3::new(0.0, w, 0.0),
                Vec3::new(0.0, 0.0, w),
            ]);
        }
    }

    /// The readout's part: the expressions blended in, with their weights, or the keys' hint.
    pub fn label(&self) -> String {
        let on: Vec<String> = (0..self.len())
            .filter(|&k| self.eased(k) > 0.0)
            .map(|k| format!("{} {} {:.2}", k + 1, self.names[k], self.eased(k)))
            .collect();
        if on.is_empty() {
            format!("keys 1-{}: expressions", self.len())
        } else {
            on.join(", ")
        }
    }
}

/// `basis` (n x m) with three more columns per target: column `m + 3k + a` holds axis `a` of
/// target `k`'s delta at each vertex. `None` when a target's vertex count is not the basis's.
pub fn extend_basis(basis: &Basis, targets: &[MorphTarget]) -> Option<Basis> {
    let (n, m) = (basis.vertex_count(), basis.control_count());
    if targets.iter().any(|t| t.position_deltas.len() != n) {
        return None;
    }
    let cols = m + 3 * targets.len();
    let src = basis.as_slice();
    let mut data = Vec::with_capacity(n * cols);
    for i in 0..n {
        data.extend_from_slice(&src[i * m..(i + 1) * m]);
        for t in targets {
            data.extend(t.position_deltas[i].to_array());
        }
    }
    Basis::from_row_major(n, cols, data)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_key_eases_its_expression_in_and_out_over_a_quarter_second() {
        let mut e = Expressions::new(["smile".to_string(), "blink".to_string()]);
        assert_eq!(e.len(), 2);
        assert_eq!(e.label(), "keys 1-2: expressions");
        assert!(e.toggle(0));
        assert!(!e.toggle(5));
        // Half the time: linear progress 0.5, smoothstep 0.5; all the time: exactly 1.
        assert!(e.advance(EASE_SECONDS / 2.0));
        assert!((e.eased(0) - 0.5).abs() < 1e-6);
        assert!((e.eased(1)).abs() < 1e-9);
        // A quarter of the way: smoothstep(0.25) = 0.15625.
        let mut q = Expressions::new(["smile".to_string()]);
        q.toggle(0);
        q.advance(EASE_SECONDS / 4.0);
        assert!((q.eased(0) - 0.156_25).abs() < 1e-6);
        e.advance(EASE_SECONDS);
        assert_eq!(e.eased(0), 1.0);
        assert!(!e.advance(0.1), "settled");
        assert_eq!(e.label(), "1 smile 1.00");
        // Pressed again: back out.
        e.toggle(0);
        e.advance(EASE_SECONDS * 2.0);
        assert_eq!(e.eased(0), 0.0);
        // At most nine keys.
        let many = Expressions::new((0..12).map(|k| format!("t{k}")));
        assert_eq!(many.len(), MAX_KEYS);
    }

    #[test]
    fn the_extended_basis_adds_each_weighted_target_to_b_d() {
        // Two vertices, one control; one target.
        let basis = Basis::from_row_major(2, 1, vec![0.5, 2.0]).unwrap();
        let target = MorphTarget {
            name: "t".into(),
            position_deltas: vec![Vec3::new(1.0, 2.0, 3.0), Vec3::new(-1.0, 0.0, 0.5)],
            normal_deltas: Vec::new(),
        };
        let ext = extend_basis(&basis, std::slice::from_ref(&target)).unwrap();
        assert_eq!(ext.control_count(), 4);
        let mut e = Expressions::new(["t".to_string()]);
        e.toggle(0);
        e.advance(EASE_SECONDS / 2.0);
        let w = e.eased(0);
        let d = [Vec3::new(0.1, 0.2, 0.3)];
        let mut dd = Vec::new();
        e.extend_d(&d, &mut dd);
        let mut u = vec![Vec3::ZERO; 2];
        ext.apply(&dd, &mut u);
        for i in 0..2 {
            let want = d[0] * [0.5, 2.0][i] + target.position_deltas[i] * w;
            assert!((u[i] - want).length() < 1e-6, "{i}: {} vs {want}", u[i]);
        }
        let short = MorphTarget {
            position_deltas: vec![Vec3::ZERO],
            ..target
        };
        assert!(extend_basis(&basis, &[short]).is_none());
    }
}
