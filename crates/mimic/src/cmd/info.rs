//! `mimic info`: validate a recording, layout, rig or avatar file and summarise it (the summaries
//! are `mimic_rig::summary`, `mimic_rig::avatar_summary` and `mimic_capture::summarize_reader`).

use anyhow::Context;
use mimic_assets::{ConfigDirs, load_layout, load_rig};
use mimic_rig::{LayoutSummary, RigSummary};
use mimic_stream::wire::{escape_untrusted, plain_lines};
use serde_json::Value;
use std::path::{Path, PathBuf};

/// Arguments of `mimic info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A recording (.jsonl), layout (configs/layouts/*.toml), rig (configs/rigs/*.toml) or avatar
    /// (.glb, .gltf, .vrm).
    pub file: PathBuf,
    /// Print the summary as JSON.
    #[arg(long)]
    pub json: bool,
    /// Config directory holding `layouts/` (default: ./configs or $MIMIC_CONFIGS).
    #[arg(long)]
    pub configs: Option<PathBuf>,
}

/// What kind of file `path` is, judged by extension and, for TOML, by its keys.
enum Kind {
    Recording,
    Layout,
    Rig,
    Avatar,
}

fn kind_of(path: &Path) -> anyhow::Result<Kind> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("jsonl") | Some("json") => Ok(Kind::Recording),
        _ if mimic_gltf::avatar::is_avatar_path(path) => Ok(Kind::Avatar),
        Some("toml") => {
            let text = mimic_types::limits::read_capped(path, &mimic_types::limits::RIG_FILE)
                .with_context(|| path.display().to_string())?;
            let is_rig = text.lines().any(|l| l.trim_start().starts_with("mesh"));
            Ok(if is_rig { Kind::Rig } else { Kind::Layout })
        }
        _ => anyhow::bail!(
            "{}: unknown kind of file (expected .jsonl recording, .toml layout or rig, or .glb, .gltf or .vrm avatar)",
            path.display()
        ),
    }
}

/// Runs `mimic info`. Text from the file (a recording's header strings, names) is printed with
/// control characters and escape codes escaped, also in errors.
pub fn run(args: Args) -> anyhow::Result<()> {
    summarise(args).map_err(|e| anyhow::anyhow!("{}", escape_untrusted(&format!("{e:#}"))))
}

fn summarise(args: Args) -> anyhow::Result<()> {
    let summary = match kind_of(&args.file)? {
        Kind::Layout => serde_json::to_value(LayoutSummary::of(&load_layout(&args.file)?))?,
        Kind::Rig => {
            let rig = load_rig(&args.file)?;
            // Each morph target must match the mesh, or `--mode blendshapes` fails later.
            let targets = mimic_assets::load_morph_targets(&args.file, &rig)?;
            let summary = RigSummary::of(&rig).with_morph_targets(&targets);
            for w in &summary.warnings {
                eprintln!("warning: {w}");
            }
            serde_json::to_value(summary)?
        }
        Kind::Avatar => {
            serde_json::to_value(mimic_rig::avatar_summary::AvatarSummary::of(&args.file)?)?
        }
        Kind::Recording => {
            let configs = ConfigDirs::locate(args.configs.as_deref());
            recording_summary(&args.file, &configs)?
        }
    };
    let text = if args.json {
        serde_json::to_string_pretty(&summary)? + "\n"
    } else {
        plain_lines(&summary)
    };
    // A closed pipe (e.g. `| head`) is not an error of ours.
    let _ = std::io::Write::write_all(&mut std::io::stdout(), text.as_bytes());
    Ok(())
}

/// Validates a recording strictly (the first rejected frame is the error) and returns its summary.
///
/// The layout named in the header is loaded from the config directory when it exists there, so
/// frames are checked against the layout's point count; otherwise against the header's.
fn recording_summary(path: &Path, configs: &ConfigDirs) -> anyhow::Result<Value> {
    let mut reader = mimic_capture::RecordingReader::open(path, None)?;
    let layout = configs.load_layout_named(&reader.header().layout).ok();
    if let Some(l) = &layout {
        reader.expect_points(l.point_count)?;
    }
    let summary = mimic_capture::summarize_reader(reader, true)?;
    let mut v = serde_json::to_value(&summary)?;
    if let Value::Object(map) = &mut v {
        map.insert("kind".into(), "recording".into());
        map.insert("layout_found".into(), Value::Bool(layout.is_some()));
    }
    Ok(v)
}
