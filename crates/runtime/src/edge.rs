//! A bounded queue between two stages with an explicit policy for frames.

use std::collections::VecDeque;
use std::sync::{Condvar, Mutex, MutexGuard};
use unitac_core::Msg;

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum FramePolicy {
    /// A full edge drops its oldest queued frame to make room for a new one (counted).
    DropOldest,
    /// A full edge blocks the producer (replay as fast as possible; deterministic).
    Lossless,
}

#[derive(Debug, Default)]
struct State {
    queue: VecDeque<Msg>,
    frames: usize,
    closed: bool,
    dropped: u64,
}

/// Multi-producer single-consumer bounded queue. Frames: at most `frame_capacity` queued.
/// Events: at most `event_capacity` queued; a full edge blocks the producer, never drops.
#[derive(Debug)]
pub struct Edge {
    state: Mutex<State>,
    readable: Condvar,
    writable: Condvar,
    frame_capacity: usize,
    event_capacity: usize,
    policy: FramePolicy,
}

impl Edge {
    pub fn new(frame_capacity: usize, event_capacity: usize, policy: FramePolicy) -> Self {
        Self {
            state: Mutex::new(State::default()),
            readable: Condvar::new(),
            writable: Condvar::new(),
            frame_capacity: frame_capacity.max(1),
            event_capacity: event_capacity.max(1),
            policy,
        }
    }

    fn lock(&self) -> MutexGuard<'_, State> {
        // A poisoned lock only means another stage thread panicked; the queue is still valid.
        self.state.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Queue a message. Returns false if the edge was closed (the consumer is gone).
    pub fn push(&self, msg: Msg) -> bool {
        let mut s = self.lock();
        loop {
            if s.closed {
                return false;
            }
            let is_frame = msg.is_frame();
            let events = s.queue.len() - s.frames;
            let full = if is_frame {
                s.frames >= self.frame_capacity
            } else {
                events >= self.event_capacity
            };
            if !full {
                break;
            }
            if is_frame && self.policy == FramePolicy::DropOldest {
                if let Some(pos) = s.queue.iter().position(Msg::is_frame) {
                    s.queue.remove(pos);
                    s.frames -= 1;
                    s.dropped += 1;
                    break;
                }
            }
            s = self.writable.wait(s).unwrap_or_else(|p| p.into_inner());
        }
        if msg.is_frame() {
            s.frames += 1;
        }
        s.queue.push_back(msg);
        drop(s);
        self.readable.notify_one();
        true
    }

    /// Next message in order; None once the edge is closed and empty.
    pub fn pop(&self) -> Option<Msg> {
        let mut s = self.lock();
        loop {
            if let Some(m) = s.queue.pop_front() {
                if m.is_frame() {
                    s.frames -= 1;
                }
                drop(s);
                self.writable.notify_all();
                return Some(m);
            }
            if s.closed {
                return None;
            }
            s = self.readable.wait(s).unwrap_or_else(|p| p.into_inner());
        }
    }

    /// No more messages will come; the consumer drains what is queued.
    pub fn close(&self) {
        self.lock().closed = true;
        self.readable.notify_all();
        self.writable.notify_all();
    }

    /// Frames dropped so far by the drop-oldest policy.
    pub fn dropped(&self) -> u64 {
        self.lock().dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;
    use unitac_core::msg::{Header, PolicyStatus};
    use unitac_core::{Frame, Stamp};

    fn frame(seq: u64) -> Msg {
        Msg::Frame(Frame::new("s", seq, Stamp(seq as i64), 1, 1, vec![0, 0, 0]).unwrap())
    }
    fn event(n: i64) -> Msg {
        Msg::PolicyStatus(PolicyStatus {
            header: Header::new(Stamp(n), ""),
            scene: String::new(),
            mode: String::new(),
            phase: String::new(),
            safety_ok: true,
            message: String::new(),
            clamped: Vec::new(),
        })
    }

    #[test]
    fn drop_oldest_keeps_events_and_order() {
        let e = Edge::new(2, 10, FramePolicy::DropOldest);
        assert!(e.push(frame(1)));
        assert!(e.push(event(100)));
        assert!(e.push(frame(2)));
        assert!(e.push(frame(3))); // drops frame 1
        assert!(e.push(frame(4))); // drops frame 2
        e.close();
        let got: Vec<i64> = std::iter::from_fn(|| e.pop())
            .map(|m| m.stamp().0)
            .collect();
        assert_eq!(got, vec![100, 3, 4]);
        assert_eq!(e.dropped(), 2);
    }

    #[test]
    fn lossless_blocks_until_consumed() {
        let e = Arc::new(Edge::new(1, 1, FramePolicy::Lossless));
        let p = {
            let e = Arc::clone(&e);
            std::thread::spawn(move || {
                for i in 0..200 {
                    assert!(e.push(frame(i)));
                    assert!(e.push(event(1000 + i as i64)));
                }
                e.close();
            })
        };
        let got: Vec<i64> = std::iter::from_fn(|| e.pop())
            .map(|m| m.stamp().0)
            .collect();
        p.join().unwrap();
        assert_eq!(got.len(), 400);
        assert_eq!(e.dropped(), 0);
        assert_eq!(&got[..4], &[0, 1000, 1, 1001]);
    }

    #[test]
    fn push_after_close_is_refused() {
        let e = Edge::new(1, 1, FramePolicy::DropOldest);
        e.close();
        assert!(!e.push(event(1)));
        assert!(e.pop().is_none());
    }
}
