//! Named weights onto a rig's morph targets ([`WeightMap`]): the names face-capture apps send
//! (ARKit's), matched to a rig's target names with the other side convention and case folded.

/// Longest weight name [`WeightMap::apply`] looks up.
const MAX_NAME: usize = 64;

/// Maps named weights, as face-capture apps send them (ARKit names, values in [0, 1]), onto a
/// rig's targets.
///
/// Besides each target's own name it accepts the other side convention (`mouthSmile_L` <->
/// `mouthSmileLeft`), a name whose `_L` and `_R` halves are both targets drives both
/// (ARKit's single `browInnerUp` -> ICT's `browInnerUp_L` and `browInnerUp_R`), and ICT's halves
/// drive a target without a side (`browInnerUp_L`, `browInnerUp_R` -> ARKit's `browInnerUp`, the
/// larger weight winning). Names match regardless of ASCII case.
#[derive(Clone, Debug)]
pub struct WeightMap {
    targets: usize,
    index: std::collections::HashMap<String, Vec<usize>>,
}

impl WeightMap {
    /// The map for targets named `names`, in weight order.
    pub fn new(names: &[String]) -> Self {
        let mut index: std::collections::HashMap<String, Vec<usize>> = Default::default();
        let mut add = |key: String, k: usize| {
            let slot = index.entry(key.to_ascii_lowercase()).or_default();
            if !slot.contains(&k) {
                slot.push(k);
            }
        };
        for (k, name) in names.iter().enumerate() {
            add(name.clone(), k);
            for (short, long) in [("_L", "Left"), ("_R", "Right")] {
                if let Some(base) = name.strip_suffix(short) {
                    add(format!("{base}{long}"), k);
                    add(base.to_string(), k);
                } else if let Some(base) = name.strip_suffix(long) {
                    add(format!("{base}{short}"), k);
                    add(base.to_string(), k);
                }
            }
            if !["_L", "_R", "Left", "Right"]
                .iter()
                .any(|s| name.ends_with(s))
            {
                add(format!("{name}_L"), k);
                add(format!("{name}_R"), k);
            }
        }
        // A base name stands for both halves only where no target carries it exactly.
        for (k, name) in names.iter().enumerate() {
            index.insert(name.to_ascii_lowercase(), vec![k]);
        }
        Self {
            targets: names.len(),
            index,
        }
    }

    /// Writes `pairs` into `out` in target order: known names get their value clamped to [0, 1]
    /// (non-finite values count as 0; a target two names reach gets the larger), targets not
    /// named get 0. Returns how many pairs named no target. Allocates nothing.
    ///
    /// # Panics
    /// If `out` is not one weight per target.
    pub fn apply<'a>(
        &self,
        pairs: impl IntoIterator<Item = (&'a str, f32)>,
        out: &mut [f32],
    ) -> usize {
        assert_eq!(out.len(), self.targets, "one weight per target");
        out.fill(0.0);
        let mut unknown = 0;
        for (name, value) in pairs {
            let v = if value.is_finite() {
                value.clamp(0.0, 1.0)
            } else {
                0.0
            };
            // Case-insensitive (Live Link Face writes `JawOpen`), without allocating.
            let mut buf = [0u8; MAX_NAME];
            let key = buf
                .get_mut(..name.len())
                .map(|b| {
                    b.copy_from_slice(name.as_bytes());
                    b.make_ascii_lowercase();
                    &*b
                })
                .and_then(|b| std::str::from_utf8(b).ok());
            match key.and_then(|k| self.index.get(k)) {
                Some(ks) => ks.iter().for_each(|&k| out[k] = out[k].max(v)),
                None => unknown += 1,
            }
        }
        unknown
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn map(names: &[&str]) -> WeightMap {
        WeightMap::new(&names.iter().map(|s| s.to_string()).collect::<Vec<_>>())
    }

    #[test]
    fn ict_style_names_drive_arkit_named_targets() {
        let m = map(&[
            "eyeBlinkLeft",
            "browInnerUp",
            "cheekPuff",
            "jawLeft",
            "mouthLeft",
        ]);
        let mut w = [9.0f32; 5];
        let unknown = m.apply(
            [
                ("eyeBlink_L", 0.5),
                ("browInnerUp_L", 0.25),
                ("browInnerUp_R", 0.75),
                ("cheekPuff_R", 0.4),
                ("jawLeft", 0.3),
                ("mouthLeft", 0.2),
                ("eyeBlink_R", 1.0),
            ],
            &mut w,
        );
        assert_eq!(w, [0.5, 0.75, 0.4, 0.3, 0.2]);
        assert_eq!(unknown, 1);
        // A target carrying a half's name exactly keeps it.
        let m = map(&["browInnerUp", "browInnerUp_L"]);
        let mut w = [0.0f32; 2];
        m.apply([("browInnerUp_L", 0.5)], &mut w);
        assert_eq!(w, [0.0, 0.5]);
    }
}
