//! A viewer's outgoing queue: control messages kept, frames bounded with the oldest dropped.

use crate::counter::Counter;
use std::collections::VecDeque;
use std::sync::{Arc, Mutex, PoisonError};
use tokio::sync::Notify;

/// One encoded viewer message, shared by every viewer that gets it.
pub type Message = Arc<Vec<u8>>;

/// Messages in order; `true` marks a frame (droppable), `false` a control message.
#[derive(Debug, Default)]
struct Inner {
    items: VecDeque<(bool, Message)>,
    frames: usize,
    closed: bool,
}

/// Bounded queue between a session (producer, never waits) and a viewer's writer task.
#[derive(Debug)]
pub struct ViewerQueue {
    inner: Mutex<Inner>,
    notify: Notify,
    capacity: usize,
    /// Frames dropped because the queue was full.
    pub dropped: Counter,
    /// Frames handed to the writer.
    pub sent: Counter,
}

impl ViewerQueue {
    /// A queue holding at most `capacity` frames (at least 1).
    pub fn new(capacity: usize) -> Self {
        Self {
            inner: Mutex::new(Inner::default()),
            notify: Notify::new(),
            capacity: capacity.max(1),
            dropped: Counter::default(),
            sent: Counter::default(),
        }
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Inner> {
        self.inner.lock().unwrap_or_else(PoisonError::into_inner)
    }

    /// Queues a frame, dropping the oldest queued frame when full; never waits.
    pub fn push_frame(&self, m: Message) {
        let mut q = self.lock();
        if q.closed {
            return;
        }
        if q.frames >= self.capacity
            && let Some(i) = q.items.iter().position(|(frame, _)| *frame)
        {
            q.items.remove(i);
            q.frames -= 1;
            self.dropped.bump();
        }
        q.items.push_back((true, m));
        q.frames += 1;
        drop(q);
        self.notify.notify_one();
    }

    /// Queues a control message (session, rig, end) in order with the frames; control messages
    /// are never dropped. A new session start also discards frames still queued.
    pub fn push_control(&self, m: Message, clear_frames: bool) {
        let mut q = self.lock();
        if q.closed {
            return;
        }
        if clear_frames {
            let before = q.items.len();
            q.items.retain(|(frame, _)| !frame);
            self.dropped.add((before - q.items.len()) as u64);
            q.frames = 0;
        }
        q.items.push_back((false, m));
        drop(q);
        self.notify.notify_one();
    }

    /// No more messages: the writer drains what is queued and stops.
    pub fn close(&self) {
        self.lock().closed = true;
        self.notify.notify_one();
    }

    /// Drops everything and closes (the viewer went away).
    pub fn abandon(&self) {
        let mut q = self.lock();
        q.closed = true;
        q.items.clear();
        q.frames = 0;
        drop(q);
        self.notify.notify_one();
    }

    /// Frames waiting now.
    pub fn queued(&self) -> usize {
        self.lock().frames
    }

    /// The next message in order, waiting for one; `None` once closed and drained.
    pub async fn pop(&self) -> Option<Message> {
        loop {
            {
                let mut q = self.lock();
                if let Some((frame, m)) = q.items.pop_front() {
                    if frame {
                        q.frames -= 1;
                        self.sent.bump();
                    }
                    return Some(m);
                }
                if q.closed {
                    return None;
                }
            }
            self.notify.notified().await;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg(k: u8) -> Message {
        Arc::new(vec![k])
    }

    #[tokio::test]
    async fn full_queue_drops_the_oldest_and_keeps_control() {
        let q = ViewerQueue::new(3);
        q.push_control(msg(100), false);
        for k in 0..10 {
            q.push_frame(msg(k));
        }
        q.push_control(msg(101), false);
        // 10 frames into 3 slots: 7 dropped, the newest 3 (7, 8, 9) kept in order, and the
        // control messages keep their places around them.
        assert_eq!(q.dropped.get(), 7);
        q.close();
        let mut got = Vec::new();
        while let Some(m) = q.pop().await {
            got.push(m[0]);
        }
        assert_eq!(got, vec![100, 7, 8, 9, 101]);
        assert_eq!(q.sent.get(), 3);
    }
}
