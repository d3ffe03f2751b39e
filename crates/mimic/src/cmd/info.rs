//! `mimic info`: validate a recording, layout or rig and summarise it.

use anyhow::Context;
use mimic_assets::{ConfigDirs, load_layout, load_rig};
use mimic_stream::wire::escape_untrusted;
use mimic_types::{Layout, Region, Rig};
use serde_json::{Value, json};
use std::path::{Path, PathBuf};

/// Arguments of `mimic info`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// A recording (.jsonl), layout (configs/layouts/*.toml) or rig (configs/rigs/*.toml).
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
}

fn kind_of(path: &Path) -> anyhow::Result<Kind> {
    match path.extension().and_then(|e| e.to_str()) {
        Some("jsonl") | Some("json") => Ok(Kind::Recording),
        Some("toml") => {
            let text = mimic_types::limits::read_capped(path, &mimic_types::limits::RIG_FILE)
                .with_context(|| path.display().to_string())?;
            let is_rig = text.lines().any(|l| l.trim_start().starts_with("mesh"));
            Ok(if is_rig { Kind::Rig } else { Kind::Layout })
        }
        _ => anyhow::bail!(
            "{}: unknown kind of file (expected .jsonl recording, or .toml layout or rig)",
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
        Kind::Layout => layout_summary(&load_layout(&args.file)?),
        Kind::Rig => rig_summary(&load_rig(&args.file)?),
        Kind::Recording => {
            let configs = ConfigDirs::locate(args.configs.as_deref());
            recording_summary(&args.file, &configs)?
        }
    };
    let text = if args.json {
        serde_json::to_string_pretty(&summary)? + "\n"
    } else {
        let mut text = String::new();
        plain(&summary, 0, &mut text);
        text
    };
    // A closed pipe (e.g. `| head`) is not an error of ours.
    let _ = std::io::Write::write_all(&mut std::io::stdout(), text.as_bytes());
    Ok(())
}

/// Renders a JSON object as indented `key: value` lines.
fn plain(v: &Value, indent: usize, out: &mut String) {
    use std::fmt::Write as _;
    let pad = "  ".repeat(indent);
    if let Value::Object(map) = v {
        for (k, val) in map {
            let _ = match val {
                Value::Object(_) => {
                    let _ = writeln!(out, "{pad}{}:", escape_untrusted(k));
                    plain(val, indent + 1, out);
                    Ok(())
                }
                Value::String(s) => {
                    writeln!(out, "{pad}{}: {}", escape_untrusted(k), escape_untrusted(s))
                }
                other => writeln!(
                    out,
                    "{pad}{}: {}",
                    escape_untrusted(k),
                    escape_untrusted(&other.to_string())
                ),
            };
        }
    }
}

fn layout_summary(l: &Layout) -> Value {
    let by_region = |r: Region| l.controls.iter().filter(|c| c.region == r).count();
    json!({
        "kind": "layout",
        "name": l.name,
        "points": l.point_count,
        "controls": l.controls.len(),
        "controls_by_region": {
            "top": by_region(Region::Top),
            "middle": by_region(Region::Middle),
            "bottom": by_region(Region::Bottom),
        },
        "stable_points": l.stable.len(),
        "undocumented_points": l.undocumented.len(),
        "fdps": l.controls.iter().map(|c| c.fdp.to_string()).collect::<Vec<_>>().join(" "),
    })
}

fn rig_summary(r: &Rig) -> Value {
    let movable = r.frozen.iter().filter(|f| !**f).count();
    let mut region_vertices = [0usize; 3];
    for (p, frozen) in r.mesh.positions.iter().zip(&r.frozen) {
        if !frozen {
            region_vertices[r.regions.region_at(p.y).index()] += 1;
        }
    }
    let (lo, hi) = r.mesh.bounds().unwrap_or_default();
    let warnings: Vec<String> = r
        .coincident_controls()
        .into_iter()
        .map(|(a, b)| {
            format!(
                "controls {a} and {b} share one rest position: an RBF solve merges them into one \
                 centre driven by their mean, so they cannot move apart (use --solver laplacian, or \
                 put them on different vertices)"
            )
        })
        .collect();
    for w in &warnings {
        eprintln!("warning: {w}");
    }
    json!({
        "kind": "rig",
        "name": r.name,
        "units": r.units,
        "vertices": r.mesh.vertex_count(),
        "triangles": r.mesh.triangles.len(),
        "textured": !r.mesh.uvs.is_empty(),
        "controls": r.controls.len(),
        "frozen_vertices": r.mesh.vertex_count() - movable,
        "movable_vertices_by_region": {
            "top": region_vertices[0],
            "middle": region_vertices[1],
            "bottom": region_vertices[2],
        },
        "bounds_min": [lo.x, lo.y, lo.z],
        "bounds_max": [hi.x, hi.y, hi.z],
        "solver": serde_json::to_value(r.solver).unwrap_or(Value::Null),
        "warnings": warnings,
    })
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
