//! A bounded queue between the socket thread and the window: the newest frames win.

use std::collections::VecDeque;
use std::sync::{Mutex, PoisonError};

/// Frames from a producer thread to the render loop: at most `capacity` wait; pushing onto a
/// full queue drops the oldest, and the consumer takes only the newest, dropping the rest.
#[derive(Debug)]
pub struct Latest<T> {
    state: Mutex<State<T>>,
}

#[derive(Debug)]
struct State<T> {
    items: VecDeque<T>,
    capacity: usize,
    dropped: u64,
    pushed: u64,
}

impl<T> Latest<T> {
    /// An empty queue holding at most `capacity` items (at least 1).
    pub fn new(capacity: usize) -> Self {
        let capacity = capacity.max(1);
        Self {
            state: Mutex::new(State {
                items: VecDeque::with_capacity(capacity),
                capacity,
                dropped: 0,
                pushed: 0,
            }),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, State<T>> {
        // A panic elsewhere cannot leave the queue half-changed: use it as it is.
        self.state.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Adds an item; a full queue drops its oldest.
    pub fn push(&self, item: T) {
        let mut s = self.lock();
        if s.items.len() == s.capacity {
            s.items.pop_front();
            s.dropped += 1;
        }
        s.items.push_back(item);
        s.pushed += 1;
    }

    /// The newest item, if any; older waiting items are dropped (counted).
    pub fn take_latest(&self) -> Option<T> {
        let mut s = self.lock();
        let newest = s.items.pop_back();
        s.dropped += s.items.len() as u64;
        s.items.clear();
        newest
    }

    /// Items pushed so far and items dropped (never shown) so far.
    pub fn counts(&self) -> (u64, u64) {
        let s = self.lock();
        (s.pushed, s.dropped)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newest_wins_and_drops_are_counted() {
        let q = Latest::new(2);
        assert_eq!(q.take_latest(), None::<u32>);
        for k in 1..=5 {
            q.push(k);
        }
        // 1, 2, 3 were pushed out by the bound; 4 is skipped by taking the newest.
        assert_eq!(q.counts(), (5, 3));
        assert_eq!(q.take_latest(), Some(5));
        assert_eq!(q.counts(), (5, 4));
        assert_eq!(q.take_latest(), None);
        q.push(6);
        assert_eq!(q.take_latest(), Some(6));
        assert_eq!(q.counts(), (6, 4));
    }

    #[test]
    fn works_across_threads() {
        let q = std::sync::Arc::new(Latest::new(4));
        let p = q.clone();
        std::thread::Builder::new()
            .name("latest-producer".into())
            .spawn(move || (0..1000).for_each(|k| p.push(k)))
            .unwrap()
            .join()
            .unwrap();
        assert_eq!(q.take_latest(), Some(999));
        let (pushed, dropped) = q.counts();
        assert_eq!((pushed, dropped), (1000, 999));
    }
}
