//! Every fuzz target's seed corpus (`fuzz/corpus/<target>/`), and every prefix of each seed, run
//! through the target's body in the ordinary test run; and the fuzz crate's targets are exactly
//! [`mimic_fuzz::TARGETS`], each calling its body.

use std::collections::BTreeSet;
use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};

fn fuzz_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../fuzz")
}

#[test]
fn every_seed_and_its_prefixes_pass_through_its_target() {
    let mut failures = Vec::new();
    let mut inputs = 0usize;
    for &(name, body) in mimic_fuzz::TARGETS {
        let dir = fuzz_dir().join("corpus").join(name);
        let mut seeds: Vec<PathBuf> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.unwrap().path())
            .filter(|p| p.is_file())
            .collect();
        seeds.sort();
        assert!(
            !seeds.is_empty(),
            "{}: no seed for target {name}",
            dir.display()
        );
        for seed in seeds {
            let bytes = std::fs::read(&seed).unwrap();
            // The whole seed and up to 64 prefixes (cut lines, truncated packets).
            let step = (bytes.len() / 64).max(1);
            let cuts = (0..bytes.len()).step_by(step).chain([bytes.len()]);
            for cut in cuts {
                inputs += 1;
                let input = &bytes[..cut];
                if catch_unwind(AssertUnwindSafe(|| body(input))).is_err() {
                    failures.push(format!("{name}: {} cut at {cut} bytes", seed.display()));
                }
            }
        }
    }
    assert!(
        failures.is_empty(),
        "fuzz bodies panicked on: {failures:#?}"
    );
    assert!(inputs > mimic_fuzz::TARGETS.len(), "{inputs} inputs run");
}

#[test]
fn the_fuzz_crate_runs_exactly_these_targets_each_through_its_body() {
    let manifest = std::fs::read_to_string(fuzz_dir().join("Cargo.toml")).unwrap();
    let bins: BTreeSet<&str> = manifest
        .lines()
        .filter_map(|l| l.strip_prefix("name = \""))
        .filter_map(|l| l.strip_suffix('"'))
        .filter(|n| *n != "mimic-fuzz-targets")
        .collect();
    let ours: BTreeSet<&str> = mimic_fuzz::TARGETS.iter().map(|(n, _)| *n).collect();
    assert_eq!(
        bins, ours,
        "fuzz/Cargo.toml's [[bin]]s against mimic_fuzz::TARGETS"
    );
    for name in ours {
        let path = fuzz_dir().join("fuzz_targets").join(format!("{name}.rs"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(
            text.contains(&format!("mimic_fuzz::{name}(data)")),
            "{} does not call mimic_fuzz::{name}",
            path.display()
        );
    }
}
