//! A counter that many tasks may bump (sessions', viewers' and the server's counts).

use std::sync::atomic::{AtomicU64, Ordering};

/// A counter that many tasks may bump.
#[derive(Debug, Default)]
pub struct Counter(AtomicU64);

impl Counter {
    /// Adds one.
    pub fn bump(&self) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }
    /// Adds `k`.
    pub fn add(&self, k: u64) {
        self.0.fetch_add(k, Ordering::Relaxed);
    }
    /// Current value.
    pub fn get(&self) -> u64 {
        self.0.load(Ordering::Relaxed)
    }
}
