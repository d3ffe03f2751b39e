//! A Live Link Face take sent as a weights session (`mimic send --weights TAKE.csv`): its tracked
//! rows through a name map, paced by the take's `Timecode`; only the targets the session's rig
//! has are sent ([`TakeSender::lacking`] names the others).

use super::connection::{Connection, TcpSent, connect};
use super::error::SendError;
use super::options::{SendOptions, weights_hello};
use super::pace::Pacer;
use super::weights::{WeightRows, send_weight_frames};
use mimic_trackers::take::{Take, TakeWeights};
use serde_json::Value;
use std::io::Write;
use std::path::Path;
use std::time::Duration;

/// A take's weights session, open and welcomed, before its frames are sent.
pub struct TakeSender {
    take: Take,
    weights: TakeWeights,
    /// Take target indices the rig has.
    kept: Vec<usize>,
    conn: Connection,
    options: SendOptions,
    /// The rig the server's welcome names.
    pub rig: String,
    /// The take's names the rig has no morph target for (not sent).
    pub lacking: Vec<String>,
}

impl std::fmt::Debug for TakeSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("TakeSender")
            .field("rig", &self.rig)
            .field("lacking", &self.lacking)
            .finish_non_exhaustive()
    }
}

/// What a take's send did.
#[derive(Debug)]
pub struct TakeSent {
    /// The session's send.
    pub tcp: TcpSent,
    /// The take's rows.
    pub rows: usize,
    /// Rows with no face (not sent).
    pub untracked: usize,
    /// The take's length (s).
    pub duration_s: f64,
    /// Its timecode rate (fps).
    pub timecode_rate: u32,
    /// Seconds the sending took.
    pub paced_s: f64,
    /// When the last frame sent was due (s).
    pub last_due_s: f64,
}

impl TakeSender {
    /// Reads the take and the name map (`namemap`, default `configs/namemaps/arkit.toml`), opens
    /// the weights session and waits (up to 30 s) for its welcome, which names the rig's targets.
    pub fn open(csv: &Path, namemap: Option<&Path>, o: &SendOptions) -> Result<Self, SendError> {
        let take = mimic_trackers::take::read_take(csv)?;
        let map_path = namemap.map(Path::to_path_buf).unwrap_or_else(|| {
            mimic_assets::ConfigDirs::locate(None)
                .root
                .join("namemaps/arkit.toml")
        });
        let map = mimic_trackers::namemap::NameMap::load(&map_path)?;
        let weights = mimic_trackers::take::take_weights(&take, &map);
        let source = format!("Live Link Face take {} (mimic send)", csv.display());
        let hello = weights_hello(o, source, take.sample_rate_hz());
        let (welcome_tx, welcome_rx) = std::sync::mpsc::sync_channel(1);
        let mut conn = connect(&o.to, o.on_reply, Some(welcome_tx))?;
        conn.stream.write_all(format!("{hello}\n").as_bytes())?;
        let welcome = welcome_rx
            .recv_timeout(Duration::from_secs(30))
            .map_err(SendError::NoWelcome)?;
        let rig_targets: Vec<String> = welcome["targets"]
            .as_array()
            .map(|a| {
                a.iter()
                    .filter_map(|t| t.as_str().map(String::from))
                    .collect()
            })
            .unwrap_or_default();
        let rig_map = mimic_retarget::WeightMap::new(&rig_targets);
        let mut scratch = vec![0.0f32; rig_targets.len()];
        let (kept, lacking): (Vec<usize>, Vec<usize>) = (0..weights.targets.len())
            .partition(|&k| rig_map.apply([(weights.targets[k].as_str(), 0.0)], &mut scratch) == 0);
        Ok(Self {
            lacking: lacking
                .iter()
                .map(|&k| weights.targets[k].clone())
                .collect(),
            rig: welcome["rig"].as_str().unwrap_or("?").to_string(),
            kept,
            take,
            weights,
            conn,
            options: o.clone(),
        })
    }

    /// How many names the take has.
    pub fn names(&self) -> usize {
        self.weights.targets.len()
    }

    /// Sends the take's tracked rows at its pace and waits for the server's `bye`.
    pub fn send(self) -> Result<TakeSent, SendError> {
        let Self {
            take,
            weights: tw,
            kept,
            mut conn,
            options: o,
            ..
        } = self;
        let pace = Pacer::new(o.speed, o.fast);
        let frames: WeightRows = tw
            .frames
            .iter()
            .map(|(_, t, w)| {
                let weights = kept
                    .iter()
                    .map(|&k| (tw.targets[k].clone(), Value::from(f64::from(w[k]))))
                    .collect();
                (*t, weights)
            })
            .collect();
        // `--loop` shifts each pass by one frame of the take's rate.
        let gap = (1e6 / take.sample_rate_hz()).round().max(1.0) as i64;
        let (sent, last_due_s, write_failed) =
            send_weight_frames(&mut conn.stream, &pace, &o, &frames, 0, gap);
        let paced_s = pace.elapsed_s();
        let bye = conn.close()?;
        Ok(TakeSent {
            tcp: TcpSent {
                sent,
                bye,
                write_failed,
            },
            rows: take.rows.len(),
            untracked: tw.untracked,
            duration_s: take.duration_s(),
            timecode_rate: take.timecode_rate,
            paced_s,
            last_due_s,
        })
    }
}
