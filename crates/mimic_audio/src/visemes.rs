//! The viseme table ([`VisemeTable`]): mouth shapes as ARKit weights, the phones that make each
//! and how each blends with its neighbours; kept as data in `configs/visemes.toml` (compiled in
//! as [`VisemeTable::shipped`]; [`VisemeTable::parse`] reads another).

use crate::error::AudioError;
use mimic_types::arkit::{ARKIT_NAMES, arkit_name};
use serde::Deserialize;
use std::collections::BTreeMap;

/// The shipped table's text.
pub const SHIPPED: &str = include_str!("../../../configs/visemes.toml");

/// One mouth shape.
#[derive(Clone, Debug, PartialEq)]
pub struct Viseme {
    /// Its name in the table.
    pub name: String,
    /// Weights in the table's column order ([`VisemeTable::names`]).
    pub weights: Vec<f32>,
    /// How strongly it pulls the mouth against its neighbours.
    pub dominance: f64,
    /// The share of its duration held at full dominance, around its centre.
    pub hold: f64,
    /// Decay time of its dominance before its centre (s).
    pub attack_s: f64,
    /// Decay time of its dominance after its centre (s).
    pub release_s: f64,
}

/// The table (module docs).
#[derive(Clone, Debug, PartialEq)]
pub struct VisemeTable {
    /// The ARKit names with a weight in some viseme, in ARKit's order.
    pub names: Vec<&'static str>,
    /// The visemes.
    pub visemes: Vec<Viseme>,
    /// Phone -> index into `visemes`.
    pub phone: BTreeMap<String, usize>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawViseme {
    name: String,
    phones: Vec<String>,
    dominance: f64,
    hold: f64,
    attack_ms: f64,
    release_ms: f64,
    weights: BTreeMap<String, f32>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawTable {
    viseme: Vec<RawViseme>,
}

impl VisemeTable {
    /// The table in `configs/visemes.toml`.
    pub fn shipped() -> Result<Self, AudioError> {
        Self::parse(SHIPPED, "configs/visemes.toml")
    }

    /// Parses a table's TOML; `what` names it in errors.
    pub fn parse(text: &str, what: &str) -> Result<Self, AudioError> {
        let bad = |reason: String| AudioError::Table {
            what: what.to_string(),
            reason,
        };
        let raw: RawTable = toml::from_str(text).map_err(|e| bad(e.message().to_string()))?;
        let mut used = [false; ARKIT_NAMES.len()];
        for v in &raw.viseme {
            for (name, w) in &v.weights {
                let a = arkit_name(name)
                    .ok_or_else(|| bad(format!("`{}`: `{name}` is no ARKit name", v.name)))?;
                if !(0.0..=1.0).contains(w) {
                    return Err(bad(format!("`{}`: {name} = {w} is outside 0..1", v.name)));
                }
                if let Some(i) = ARKIT_NAMES.iter().position(|n| *n == a) {
                    used[i] = true;
                }
            }
            let positive = [v.dominance, v.attack_ms, v.release_ms];
            if positive.iter().any(|x| !(x.is_finite() && *x > 0.0))
                || !(0.0..=1.0).contains(&v.hold)
            {
                return Err(bad(format!(
                    "`{}`: dominance, attack_ms and release_ms must be above 0, hold in 0..1",
                    v.name
                )));
            }
        }
        let names: Vec<&'static str> = ARKIT_NAMES
            .iter()
            .zip(used)
            .filter(|(_, u)| *u)
            .map(|(n, _)| *n)
            .collect();
        let mut phone = BTreeMap::new();
        let mut visemes = Vec::new();
        for (k, v) in raw.viseme.into_iter().enumerate() {
            for p in &v.phones {
                if phone.insert(p.to_ascii_uppercase(), k).is_some() {
                    return Err(bad(format!("phone `{p}` is in two visemes")));
                }
            }
            let weights = names
                .iter()
                .map(|n| {
                    v.weights
                        .iter()
                        .find(|(k, _)| arkit_name(k) == Some(n))
                        .map_or(0.0, |(_, w)| *w)
                })
                .collect();
            visemes.push(Viseme {
                name: v.name,
                weights,
                dominance: v.dominance,
                hold: v.hold,
                attack_s: v.attack_ms / 1000.0,
                release_s: v.release_ms / 1000.0,
            });
        }
        for need in [crate::timeline::SIL, crate::timeline::REST] {
            if !phone.contains_key(need) {
                return Err(bad(format!("no viseme has phone `{need}`")));
            }
        }
        Ok(Self {
            names,
            visemes,
            phone,
        })
    }

    /// The viseme of `phone` (`REST` for a phone the table lacks).
    pub fn of(&self, phone: &str) -> &Viseme {
        let k = self
            .phone
            .get(phone)
            .or_else(|| self.phone.get(crate::timeline::REST))
            .copied()
            .unwrap_or(0);
        &self.visemes[k]
    }

    /// The column of ARKit name `name`, if the table has it.
    pub fn column(&self, name: &str) -> Option<usize> {
        self.names.iter().position(|n| n.eq_ignore_ascii_case(name))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_shipped_table_covers_the_recogniser_phones() {
        let t = VisemeTable::shipped().unwrap();
        // pocketsphinx en-US's 39 phones.
        for p in "AA AE AH AO AW AY B CH D DH EH ER EY F G HH IH IY JH K L M N NG OW OY P R S SH \
                  T TH UH UW V W Y Z ZH"
            .split_whitespace()
        {
            assert!(t.phone.contains_key(p), "{p} has no viseme");
        }
        assert!(t.column("jawOpen").is_some() && t.column("mouthPressLeft").is_some());
        assert!(t.of("SIL").weights.iter().all(|w| *w == 0.0));
    }

    #[test]
    fn bad_tables_are_refused_with_the_reason() {
        let row = |w: &str| {
            format!(
                "[[viseme]]\nname = \"x\"\nphones = [\"SIL\", \"REST\"]\ndominance = 1.0\nhold = 0.5\n\
                 attack_ms = 10.0\nrelease_ms = 10.0\nweights = {{ {w} }}\n"
            )
        };
        assert!(VisemeTable::parse(&row("jawOpen = 0.5"), "t").is_ok());
        let e = VisemeTable::parse(&row("jawOpn = 0.5"), "t").unwrap_err();
        assert!(e.to_string().contains("`jawOpn` is no ARKit name"), "{e}");
        let e = VisemeTable::parse(&row("jawOpen = 1.5"), "t").unwrap_err();
        assert!(e.to_string().contains("outside 0..1"), "{e}");
    }
}
