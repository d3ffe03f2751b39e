//! `mimic worker`: steps live sessions for `mimic serve --nats` front doors (docs/cluster.md).

use crate::cmd::setup::{PipelineArgs, RigArgs};
use std::io::Write;
use std::sync::Arc;

/// Arguments of `mimic worker`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The NATS server (started with JetStream, `nats-server -js`), e.g. nats://127.0.0.1:4222.
    #[arg(long, value_name = "URL")]
    pub nats: String,
    #[command(flatten)]
    pub rig: RigArgs,
    #[command(flatten)]
    pub pipeline: PipelineArgs,
    /// Further rigs sessions may drive (the front doors' `--also-rig`).
    #[arg(long = "also-rig")]
    pub also_rig: Vec<String>,
    /// Maximum sessions at once; past it, placements go to other workers.
    #[arg(long, default_value_t = 64)]
    pub max_sessions: usize,
    /// This worker's name in leases, logs and front doors' stats (default: `worker-<pid>`).
    #[arg(long)]
    pub name: Option<String>,
    /// Print the final counters as JSON on exit.
    #[arg(long)]
    pub json: bool,
}

/// Runs `mimic worker` until Ctrl-C.
pub fn run(args: Args) -> anyhow::Result<()> {
    // The same rigs and layouts as the front doors (same configs and rig flags).
    let catalog = Arc::new(crate::cmd::setup::build_catalog(&args.rig, &args.also_rig)?.0);
    let name = args
        .name
        .clone()
        .unwrap_or_else(|| format!("worker-{}", std::process::id()));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .enable_all()
        .build()?;
    let stats = runtime.block_on(async {
        let cluster = mimic_cluster::Cluster::connect(&args.nats, Default::default()).await?;
        let worker = mimic_cluster::Worker::new(
            cluster,
            catalog,
            args.pipeline.settings(),
            &name,
            args.max_sessions.max(1),
        );
        println!(
            "mimic worker: {name} nats {} max-sessions {}",
            mimic_cluster::redact(&args.nats),
            args.max_sessions
        );
        std::io::stdout().flush()?;
        let shutdown = async {
            let _ = tokio::signal::ctrl_c().await;
        };
        worker.run(shutdown).await?;
        anyhow::Ok(worker.stats())
    })?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&stats)?);
    } else {
        println!("{}", stats.summary());
    }
    Ok(())
}
