//! What a UDP intake holds besides its sessions, all bounded: the blocks of keys (faces,
//! subjects) that have no session yet ([`Pending`], at most [`PENDING_KEYS`] keys of at most a
//! few blocks each), and the refusal counts it logs at most once a second ([`RefusalLog`]).

use std::collections::{HashMap, VecDeque};
use std::hash::Hash;
use std::net::SocketAddr;
use std::time::{Duration, Instant};

/// Keys without a session held at once; past it, the one silent longest is forgotten.
pub(crate) const PENDING_KEYS: usize = 64;

/// A key's pending blocks from one source stay this long after its last one.
pub(crate) const PENDING_STALE: Duration = Duration::from_secs(1);

/// Valid blocks of one key from one source, oldest first, waiting to open (or take over) its
/// session: each one's time after the previous one's.
#[derive(Debug)]
pub(crate) struct Pending<U> {
    /// The source they came from.
    pub(crate) source: SocketAddr,
    /// The blocks and their arrivals.
    pub(crate) units: VecDeque<(U, Instant)>,
    /// The last block's time (tracker seconds), when it had one.
    last_time: Option<f64>,
    /// The last block's arrival.
    pub(crate) last: Instant,
}

impl<U> Pending<U> {
    /// Nothing yet from `source`.
    pub(crate) fn new(source: SocketAddr, now: Instant) -> Self {
        Self {
            source,
            units: VecDeque::new(),
            last_time: None,
            last: now,
        }
    }

    /// Adds a block with tracker time `time` (seconds, if it has one); keeps at most `keep`
    /// blocks. A block whose time is not after the previous one's starts the run over. Returns
    /// how many blocks were let go (to be counted as refused).
    pub(crate) fn push(
        &mut self,
        unit: U,
        time: Option<f64>,
        arrival: Instant,
        keep: usize,
    ) -> usize {
        let mut dropped = 0;
        let in_order = match (self.last_time, time) {
            (Some(a), Some(b)) => b > a,
            (_, Some(b)) => b.is_finite(),
            _ => true,
        };
        if !in_order {
            dropped += self.units.len();
            self.units.clear();
        }
        self.units.push_back((unit, arrival));
        while self.units.len() > keep.max(1) {
            self.units.pop_front();
            dropped += 1;
        }
        self.last_time = time;
        self.last = arrival;
        dropped
    }

    /// Blocks held.
    pub(crate) fn len(&self) -> usize {
        self.units.len()
    }
}

/// The pending blocks of keys without a session, at most [`PENDING_KEYS`] keys.
#[derive(Debug)]
pub(crate) struct PendingKeys<K, U> {
    keys: HashMap<K, Pending<U>>,
}

impl<K: Clone + Eq + Hash, U> Default for PendingKeys<K, U> {
    fn default() -> Self {
        Self {
            keys: HashMap::new(),
        }
    }
}

/// Where a block of a key without a session goes.
pub(crate) enum Slot<'a, U> {
    /// Into this run (`dropped` blocks of others were let go to make room).
    Run(&'a mut Pending<U>, usize),
    /// Refused: another source is sending for the key.
    OtherSource,
}

impl<K: Clone + Eq + Hash, U> PendingKeys<K, U> {
    /// The run of `key` from `source`: a new one (forgetting the key silent longest when full),
    /// the one under way, or a stale one of another source replaced.
    pub(crate) fn slot(&mut self, key: &K, source: SocketAddr, now: Instant) -> Slot<'_, U> {
        let mut dropped = 0;
        if let Some(p) = self.keys.get(key)
            && p.source != source
        {
            if now.duration_since(p.last) < PENDING_STALE {
                return Slot::OtherSource;
            }
            dropped += self.keys.remove(key).map_or(0, |p| p.len());
        }
        if !self.keys.contains_key(key) && self.keys.len() >= PENDING_KEYS {
            let oldest = self
                .keys
                .iter()
                .min_by_key(|(_, p)| p.last)
                .map(|(k, _)| k.clone());
            if let Some(k) = oldest {
                dropped += self.keys.remove(&k).map_or(0, |p| p.len());
            }
        }
        let run = self
            .keys
            .entry(key.clone())
            .or_insert_with(|| Pending::new(source, now));
        Slot::Run(run, dropped)
    }

    /// Takes the run of `key` out.
    pub(crate) fn take(&mut self, key: &K) -> Option<Pending<U>> {
        self.keys.remove(key)
    }
}

/// Why a datagram (or block) was refused.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Why {
    /// Its source is not on the `--udp-allow` list.
    NotAllowed,
    /// Its key's session (or pending run) is bound to another source.
    WrongSource,
    /// The UDP session budget (`--max-udp-sessions`) is taken.
    Budget,
    /// The session could not be opened (e.g. the server's session limit).
    NotOpened,
    /// A pending run let it go (out of order, replaced, or no room).
    Dropped,
}

/// Refusal counts since the last log line; logged at most once a second.
#[derive(Debug, Default)]
pub(crate) struct RefusalLog {
    counts: [u64; 5],
    last_log: Option<Instant>,
    example: Option<String>,
}

/// Names of [`Why`] in the log line, in its order.
const WHY_NAMES: [&str; 5] = [
    "source not on --udp-allow",
    "bound to another source",
    "--max-udp-sessions reached",
    "session not opened",
    "superseded before its session opened",
];

impl RefusalLog {
    /// Counts `n` refusals for `why` (`what` says the last one, for the log).
    pub(crate) fn note(&mut self, why: Why, n: usize, what: impl FnOnce() -> String) {
        if n == 0 {
            return;
        }
        self.counts[why as usize] += n as u64;
        if self.example.is_none() {
            self.example = Some(what());
        }
    }

    /// Logs (warn level) the counts since the last line, at most once a second.
    pub(crate) fn flush(&mut self, intake: &str, now: Instant) {
        let total: u64 = self.counts.iter().sum();
        if total == 0
            || self
                .last_log
                .is_some_and(|t| now.duration_since(t) < Duration::from_secs(1))
        {
            return;
        }
        let parts: Vec<String> = self
            .counts
            .iter()
            .zip(WHY_NAMES)
            .filter(|(n, _)| **n > 0)
            .map(|(n, name)| format!("{n} {name}"))
            .collect();
        let example = self.example.take().unwrap_or_default();
        tracing::warn!(
            "{intake}: refused {total} packets since the last such line ({}); e.g. {example}",
            parts.join(", ")
        );
        self.counts = [0; 5];
        self.last_log = Some(now);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_run_keeps_its_newest_blocks_in_time_order() {
        let src: SocketAddr = "127.0.0.1:9".parse().unwrap();
        let t = Instant::now();
        let mut p = Pending::new(src, t);
        assert_eq!(p.push(1, Some(1.0), t, 3), 0);
        assert_eq!(p.push(2, Some(2.0), t, 3), 0);
        // Back in time: the run starts over.
        assert_eq!(p.push(3, Some(0.5), t, 3), 2);
        assert_eq!(p.len(), 1);
        for k in 0..3 {
            p.push(10 + k, Some(1.0 + f64::from(k)), t, 3);
        }
        assert_eq!(p.len(), 3);
        assert_eq!(p.units.front().map(|u| u.0), Some(10));
    }

    #[test]
    fn pending_keys_are_bounded_and_bound_to_their_source() {
        let a: SocketAddr = "127.0.0.1:9".parse().unwrap();
        let b: SocketAddr = "127.0.0.2:9".parse().unwrap();
        let t = Instant::now();
        let mut keys: PendingKeys<u32, u8> = PendingKeys::default();
        for k in 0..(PENDING_KEYS as u32 + 10) {
            let at = t + Duration::from_millis(u64::from(k));
            if let Slot::Run(p, _) = keys.slot(&k, a, at) {
                p.push(1, None, at, 3);
            }
        }
        assert_eq!(keys.keys.len(), PENDING_KEYS);
        // The oldest keys went.
        assert!(!keys.keys.contains_key(&0));
        let k = PENDING_KEYS as u32;
        assert!(matches!(keys.slot(&k, b, t), Slot::OtherSource));
        let later = t + Duration::from_secs(5);
        assert!(matches!(keys.slot(&k, b, later), Slot::Run(_, 1)));
    }
}
