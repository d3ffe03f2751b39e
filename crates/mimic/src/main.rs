//! `mimic`: replay tracked faces onto target heads. One file per subcommand under `cmd/`.

mod cmd;

use clap::{Parser, Subcommand};
use std::process::ExitCode;

/// Performance-capture retargeting: drive a target head mesh with a tracked face.
#[derive(Parser, Debug)]
#[command(name = "mimic", version, about, long_about = None)]
struct Cli {
    /// Log filter (tracing syntax), e.g. `info` or `mimic=debug`; RUST_LOG works too.
    #[arg(long, global = true, default_value = "warn")]
    log: String,
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand, Debug)]
enum Command {
    /// Validate a recording, layout or rig and print a summary.
    Info(cmd::info::Args),
    /// Replay a recording onto a rig and write the deformed frames.
    Replay(cmd::replay::Args),
    /// Measure a solver against real expression meshes of the rig.
    Eval(cmd::eval::Args),
    /// Time the per-frame pipeline on a rig, stage by stage.
    Bench(cmd::bench::Args),
    /// Convert another tracker's file into a v1 recording.
    #[command(subcommand)]
    Import(cmd::import::ImportCommand),
    /// Export a rig's morph targets as a morph data file, or check one against the rig.
    #[command(subcommand)]
    Morph(cmd::morph::MorphCommand),
    /// Serve live sessions: trackers in over TCP/UDP, viewers out (docs/protocol.md).
    Serve(Box<cmd::serve::Args>),
    /// Replay a recording into `mimic serve` at its recorded pace, as a tracker would.
    Send(cmd::send::Args),
    /// Render frames of a recording on a rig to PNG (headless wgpu), or a contact sheet.
    Render(cmd::render::Args),
    /// Make a rig for a face mesh from its landmarks, check a rig (docs/rigging.md), or export one
    /// as a GLB (docs/gltf.md).
    #[command(subcommand)]
    Rig(cmd::rig::RigCommand),
    /// Watch a recording replayed on a rig, or a live `mimic serve` session, in a window.
    View(cmd::view::Args),
    /// Step live sessions for `mimic serve --nats` front doors, over NATS (docs/cluster.md).
    Worker(cmd::worker::Args),
}

fn main() -> ExitCode {
    // Behave like other command-line tools when stdout is a closed pipe (`mimic ... | head`):
    // end quietly instead of panicking on the failed write.
    #[cfg(unix)]
    // SAFETY: restoring the default disposition of SIGPIPE before any thread exists.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
    let cli = Cli::parse();
    let filter = std::env::var("RUST_LOG").unwrap_or_else(|_| cli.log.clone());
    tracing_subscriber::fmt()
        .with_env_filter(tracing_subscriber::EnvFilter::new(filter))
        .with_writer(std::io::stderr)
        .init();
    let result = match cli.command {
        Command::Info(a) => cmd::info::run(a),
        Command::Replay(a) => cmd::replay::run(a),
        Command::Bench(a) => cmd::bench::run(a),
        Command::Import(c) => cmd::import::run(c),
        Command::Morph(c) => cmd::morph::run(c),
        Command::Eval(a) => cmd::eval::run(a),
        Command::Rig(c) => cmd::rig::run(c),
        Command::Serve(a) => cmd::serve::run(*a),
        Command::Send(a) => cmd::send::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::View(a) => cmd::view::run(a),
        Command::Worker(a) => cmd::worker::run(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
