//! Counters of sessions and viewers, and a fixed-bucket latency histogram.

use serde::Serialize;

/// Width of a latency bucket (µs).
pub const LATENCY_BUCKET_US: u64 = 5;
/// Buckets; latencies past the last one (20 ms) land in it.
const BUCKETS: usize = 4000;

/// Latencies in 5 µs buckets up to 20 ms (anything longer counts as 20 ms).
#[derive(Clone, Debug)]
pub struct LatencyHistogram {
    counts: Vec<u64>,
    total: u64,
    max_us: u64,
}

impl Default for LatencyHistogram {
    fn default() -> Self {
        Self {
            counts: vec![0; BUCKETS],
            total: 0,
            max_us: 0,
        }
    }
}

impl LatencyHistogram {
    /// Adds one sample (µs).
    pub fn record(&mut self, us: u64) {
        let b = ((us / LATENCY_BUCKET_US) as usize).min(BUCKETS - 1);
        if let Some(c) = self.counts.get_mut(b) {
            *c += 1;
        }
        self.total += 1;
        self.max_us = self.max_us.max(us);
    }

    /// Adds another histogram's samples.
    pub fn merge(&mut self, other: &LatencyHistogram) {
        for (a, b) in self.counts.iter_mut().zip(&other.counts) {
            *a += *b;
        }
        self.total += other.total;
        self.max_us = self.max_us.max(other.max_us);
    }

    /// Samples recorded.
    pub fn count(&self) -> u64 {
        self.total
    }

    /// Upper edge (µs) of the bucket holding the `q` quantile (0 when empty).
    pub fn quantile_us(&self, q: f64) -> u64 {
        if self.total == 0 {
            return 0;
        }
        let rank = ((self.total as f64 * q).ceil() as u64).clamp(1, self.total);
        let mut seen = 0;
        for (b, c) in self.counts.iter().enumerate() {
            seen += c;
            if seen >= rank {
                return (b as u64 + 1) * LATENCY_BUCKET_US;
            }
        }
        self.max_us
    }

    /// p50, p99 and max as a summary.
    pub fn summary(&self) -> LatencySummary {
        LatencySummary {
            count: self.total,
            p50_us: self.quantile_us(0.5),
            p99_us: self.quantile_us(0.99),
            max_us: self.max_us,
        }
    }
}

/// Latency quantiles (bucket upper edges, µs).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize)]
pub struct LatencySummary {
    /// Samples.
    pub count: u64,
    /// Median.
    pub p50_us: u64,
    /// 99th percentile.
    pub p99_us: u64,
    /// Largest sample.
    pub max_us: u64,
}

/// Counters of one viewer, as served by the stats request.
#[derive(Clone, Debug, Default, PartialEq, Eq, Serialize)]
pub struct ViewerSnapshot {
    /// Viewer id (connection order).
    pub id: u64,
    /// Session it watches.
    pub session: String,
    /// Whether it asked for positions.
    pub positions: bool,
    /// Frames written to it.
    pub frames_sent: u64,
    /// Frames dropped from its queue (oldest first) because it did not keep up.
    pub frames_dropped: u64,
    /// Frames waiting in its queue now.
    pub queued: u64,
    /// Still connected.
    pub connected: bool,
}

/// Counters of one tracker session, as served by the stats request.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SessionSnapshot {
    /// Session id (also the UDP session id).
    pub id: u32,
    /// Session name.
    pub name: String,
    /// Rig driven.
    pub rig: String,
    /// Landmark layout of the tracker.
    pub layout: String,
    /// Tracker still connected.
    pub active: bool,
    /// Why it ended, once it has.
    pub end_reason: Option<String>,
    /// Frames accepted and retargeted (TCP and UDP).
    pub frames: u64,
    /// Of those, frames that came over UDP.
    pub udp_frames: u64,
    /// Frames retargeted as tracked / calibrating / lost.
    pub tracked: u64,
    /// Frames used to build the neutral.
    pub calibrating: u64,
    /// Frames with lost tracking.
    pub lost: u64,
    /// Tracked frames the plausibility gate held like lost ones (`docs/gate.md`).
    pub gated: u64,
    /// Frames where some output control moved more than the jump bound from the previous frame.
    pub jumps: u64,
    /// Frames dropped because their timestamp was not after the last accepted one (late or out of order).
    pub late: u64,
    /// Frames dropped because their timestamp ran ahead of the last accepted one by more than
    /// the wall-clock time between their arrivals plus the allowed jump (answered on TCP).
    pub future: u64,
    /// Malformed messages (answered with an error on TCP).
    pub malformed: u64,
    /// UDP frames dropped because the session's queue was full.
    pub udp_queue_dropped: u64,
    /// Error replies not sent because the tracker did not read them.
    pub replies_dropped: u64,
    /// Weights sessions: weight names that matched no morph target, summed over frames.
    pub unknown_weights: u64,
    /// Times the tracker's clock started again (a new run of the tracker: a frame well behind
    /// the last accepted one after a pause, or a UDP source taking over a silent session); the
    /// session clock was re-anchored each time (`timing.rs`).
    pub restarts: u64,
    /// The session's recording file, when the server records (`--record`).
    pub recording: Option<String>,
    /// Accepted frames written and flushed to the recording.
    pub recorded: u64,
    /// Accepted frames that could not be recorded (file not created or a write failed).
    pub record_lost: u64,
    /// Accepted frames that found the recording queue full: the session waited for the disk.
    pub record_waits: u64,
    /// Datagrams forwarded (`--forward`, a hello's `"forward"`): one per frame and target.
    pub forwarded: u64,
    /// Datagrams not forwarded: the socket would have blocked (or the send failed).
    pub forward_dropped: u64,
    /// Arrival (line or packet read) to broadcast (pushed to every viewer queue).
    pub latency: LatencySummary,
    /// Viewers that watch this session now and the last 16 that left (older ones are only
    /// counted in the totals below), by id.
    pub viewers: Vec<ViewerSnapshot>,
    /// Viewers that ever watched this session.
    pub viewers_total: u64,
    /// Frames written to its viewers, over every viewer that ever watched.
    pub viewer_frames_sent: u64,
    /// Frames dropped from its viewers' queues, over every viewer that ever watched.
    pub viewer_frames_dropped: u64,
    /// Where it is stepped, when a placement (`mimic serve --nats`) steps it: the worker and
    /// the frames sent, retargeted and lost (absent for a session stepped here).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cluster: Option<crate::placement::ClusterSnapshot>,
}

/// Counters of the whole server, as served by the stats request.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct ServerStats {
    /// Seconds since the server started.
    pub uptime_s: f64,
    /// Connections accepted.
    pub connections: u64,
    /// Connections refused (hello errors, limits).
    pub refused: u64,
    /// Tracker sessions connected now.
    pub sessions_active: u64,
    /// Viewers connected now.
    pub viewers_active: u64,
    /// UDP packets that were not valid frame packets for a live session.
    pub udp_bad_packets: u64,
    /// Of those, frame packets for a live session with the wrong key (dropped).
    pub udp_wrong_key: u64,
    /// Of those, frame packets with the right key from another address than the tracker's
    /// (its TCP hello's address, then the source of its first accepted packet; dropped).
    pub udp_wrong_source: u64,
    /// UDP tracker intakes (OpenSeeFace, Live Link): datagrams refused: from a source the
    /// `--udp-allow` list lacks, for a face or subject bound to another source, or for one that
    /// found no session (`--max-udp-sessions` reached, or the session refused).
    pub udp_refused: u64,
    /// Browser endpoint (`--http`): connections refused at accept (the per-address cap or the
    /// connection budget) and requests refused for their `Host` or `Origin`.
    pub http_refused: u64,
    /// Browser endpoint: connections open now.
    pub http_connections: u64,
    /// Latency over every session listed.
    pub latency: LatencySummary,
    /// Frames dropped from viewer queues, over every session listed.
    pub viewer_frames_dropped: u64,
    /// Live sessions and the most recent ended ones.
    pub sessions: Vec<SessionSnapshot>,
}

impl ServerStats {
    /// The line `mimic serve` ends with: connections, sessions, latency, dropped frames.
    pub fn summary(&self) -> String {
        format!(
            "mimic serve: {} connections, {} sessions; latency p50 {} us, p99 {} us; {} frames dropped for slow viewers",
            self.connections,
            self.sessions.len(),
            self.latency.p50_us,
            self.latency.p99_us,
            self.viewer_frames_dropped
        )
    }

    /// The line on the frames recorded in `dir` (`--record`), over every session listed.
    pub fn record_summary(&self, dir: &std::path::Path) -> String {
        let recorded: u64 = self.sessions.iter().map(|s| s.recorded).sum();
        let lost: u64 = self.sessions.iter().map(|s| s.record_lost).sum();
        format!(
            "mimic serve: {recorded} frames recorded in {} ({lost} not recorded)",
            dir.display()
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_of_a_uniform_spread() {
        let mut h = LatencyHistogram::default();
        // 1..=1000 µs: the q quantile is q * 1000 µs, reported as its 5 µs bucket's upper edge.
        for us in 1..=1000 {
            h.record(us);
        }
        assert_eq!(h.count(), 1000);
        assert_eq!(h.quantile_us(0.5), 500 + LATENCY_BUCKET_US);
        assert_eq!(h.quantile_us(0.99), 990 + LATENCY_BUCKET_US);
        assert_eq!(h.summary().max_us, 1000);
        let mut g = LatencyHistogram::default();
        g.record(1_000_000);
        h.merge(&g);
        assert_eq!(h.quantile_us(1.0), 20_000);
        assert_eq!(h.summary().max_us, 1_000_000);
    }
}
