//! Fingers integrated somewhere else: a [`Physics`] that only relays.
//!
//! A simulated device steps its physics on wall time (about every millisecond). A caller that
//! integrates the fingers itself, in its own time (a trial loop stepping a task world in sim
//! time), puts a [`Relay`] in the device instead: each device tick records the drive the device's
//! controller decoded from its registers (target, speed and force as the raw registers hold them,
//! so quantized to the model's ranges) and returns the fingers the caller last published through
//! the [`RelayHandle`]. Nothing here depends on how long a tick was, so the caller's outcome does
//! not depend on wall time.

use super::physics::{Drive, Fingers, Physics};
use std::sync::{Arc, Mutex, MutexGuard};

#[derive(Debug, Default)]
struct Shared {
    fingers: Fingers,
    drive: Option<Drive>,
    ticks: u64,
}

fn lock(m: &Mutex<Shared>) -> MutexGuard<'_, Shared> {
    // Plain values: a panic elsewhere cannot leave them half-written.
    m.lock().unwrap_or_else(|p| p.into_inner())
}

/// The device's side: give it to [`super::SimDevice::spawn_with`].
#[derive(Debug)]
pub struct Relay {
    shared: Arc<Mutex<Shared>>,
}

/// The integrator's side: publish the fingers, read the drive.
#[derive(Debug, Clone)]
pub struct RelayHandle {
    shared: Arc<Mutex<Shared>>,
}

/// A relay whose fingers start as `fingers`, and its handle.
pub fn relay(fingers: Fingers) -> (Relay, RelayHandle) {
    let shared = Arc::new(Mutex::new(Shared {
        fingers,
        ..Shared::default()
    }));
    (
        Relay {
            shared: shared.clone(),
        },
        RelayHandle { shared },
    )
}

impl Physics for Relay {
    fn step(&mut self, _dt: f64, drive: Drive) -> Fingers {
        let mut s = lock(&self.shared);
        s.drive = Some(drive);
        s.ticks += 1;
        s.fingers
    }
    fn fingers(&self) -> Fingers {
        lock(&self.shared).fingers
    }
}

impl RelayHandle {
    /// The fingers the device reports from now on.
    pub fn publish(&self, fingers: Fingers) {
        lock(&self.shared).fingers = fingers;
    }
    /// The drive of the device's latest tick (None before its first).
    pub fn drive(&self) -> Option<Drive> {
        lock(&self.shared).drive
    }
    /// Device ticks so far.
    pub fn ticks(&self) -> u64 {
        lock(&self.shared).ticks
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_the_drive_and_returns_what_was_published_whatever_the_tick_length() {
        let start = Fingers {
            opening_m: 0.14,
            ..Fingers::default()
        };
        let (mut r, h) = relay(start);
        assert_eq!((h.drive(), h.ticks()), (None, 0));
        let d = Drive {
            enabled: true,
            target_m: 0.05,
            speed_m_s: 0.03,
            force_n: 10.0,
        };
        assert_eq!(r.step(0.001, d), start);
        assert_eq!(r.step(5.0, d), start);
        assert_eq!((h.drive(), h.ticks()), (Some(d), 2));
        let held = Fingers {
            opening_m: 0.08,
            force_n: 12.0,
            stalled: true,
            closing: true,
        };
        h.publish(held);
        assert_eq!(r.fingers(), held);
        assert_eq!(r.step(0.5, d), held);
    }
}
