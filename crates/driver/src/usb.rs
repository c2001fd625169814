//! USB access through libusb (`rusb`): the software replug and hotplug events.
//!
//! A GelSight Mini that stops streaming while still on the bus is usually fixed by pulling the
//! cable. [`Usb::reset_port`] does the same in software: `libusb_reset_device` on the sensor's
//! USB device (found by the sysfs port name discovery reports, e.g. `3-1.4`), after which the
//! device re-enumerates and the stream re-opens it by serial. [`Usb::wait_event`] blocks on
//! libusb hotplug events (arrival / removal of any USB device) so a reconnect can start as soon
//! as a sensor comes back instead of polling sysfs on a backoff; where libusb has no hotplug
//! support it returns `None` and the caller polls as before.
//!
//! Needs write access to `/dev/bus/usb/BBB/DDD` (the udev rule in `udev/` gives it to group
//! `plugdev`). The only module besides `v4l_backend` that touches hardware.

use crate::capture::DeviceError;
use rusb::UsbContext;
use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// A sysfs USB device name (`<bus>-<port>[.<port>...]`, e.g. `3-1.4`) as bus number and port
/// chain. `None` for root hubs (`usb3`), interfaces (`3-1:1.0`) and anything malformed.
pub fn parse_port(name: &str) -> Option<(u8, Vec<u8>)> {
    let (bus, chain) = name.split_once('-')?;
    if chain.contains(':') {
        return None;
    }
    let bus: u8 = bus.parse().ok()?;
    let ports: Vec<u8> = chain
        .split('.')
        .map(|p| p.parse().ok())
        .collect::<Option<_>>()?;
    // USB allows at most 7 tiers (libusb_get_port_numbers fills at most 7).
    (!ports.is_empty() && ports.len() <= 7).then_some((bus, ports))
}

fn usb_err(what: &str, e: rusb::Error) -> DeviceError {
    match e {
        rusb::Error::NoDevice | rusb::Error::NotFound => DeviceError::Gone(format!("{what}: {e}")),
        rusb::Error::Access => DeviceError::Io(format!(
            "{what}: {e} (no write access to /dev/bus/usb: install the udev rule, see the driver README)"
        )),
        rusb::Error::NotSupported => DeviceError::Unsupported(format!("{what}: {e}")),
        other => DeviceError::Io(format!("{what}: {other}")),
    }
}

/// Counts hotplug events (any USB device arriving or leaving).
struct Counter(Arc<AtomicU64>);

impl rusb::Hotplug<rusb::Context> for Counter {
    fn device_arrived(&mut self, _device: rusb::Device<rusb::Context>) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }
    fn device_left(&mut self, _device: rusb::Device<rusb::Context>) {
        self.0.fetch_add(1, Ordering::Relaxed);
    }
}

/// A libusb context with an optional hotplug registration.
pub struct Usb {
    ctx: rusb::Context,
    events: Arc<AtomicU64>,
    seen: u64,
    registration: Option<rusb::Registration<rusb::Context>>,
}

impl std::fmt::Debug for Usb {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Usb")
            .field("hotplug", &self.registration.is_some())
            .finish_non_exhaustive()
    }
}

impl Usb {
    /// Open a libusb context; register for hotplug events where libusb supports them.
    pub fn new() -> Result<Self, DeviceError> {
        let ctx = rusb::Context::new().map_err(|e| usb_err("libusb init", e))?;
        let events = Arc::new(AtomicU64::new(0));
        let registration = if rusb::has_hotplug() {
            rusb::HotplugBuilder::new()
                .enumerate(false)
                .register(&ctx, Box::new(Counter(events.clone())))
                .map_err(|e| tracing::info!("libusb hotplug unavailable ({e}): polling sysfs"))
                .ok()
        } else {
            None
        };
        Ok(Self {
            ctx,
            events,
            seen: 0,
            registration,
        })
    }

    /// USB reset of the device at this sysfs port (`3-1.4`): the software replug. The device
    /// re-enumerates afterwards (libusb may report that as "not found": that is success here).
    pub fn reset_port(&self, port: &str) -> Result<(), DeviceError> {
        let Some((bus, chain)) = parse_port(port) else {
            return Err(DeviceError::Unsupported(format!("USB port name {port:?}")));
        };
        let list = self
            .ctx
            .devices()
            .map_err(|e| usb_err("USB device list", e))?;
        for dev in list.iter() {
            if dev.bus_number() != bus || dev.port_numbers().ok().as_ref() != Some(&chain) {
                continue;
            }
            let handle = dev.open().map_err(|e| usb_err("USB open", e))?;
            return match handle.reset() {
                Ok(()) | Err(rusb::Error::NotFound) | Err(rusb::Error::NoDevice) => Ok(()),
                Err(e) => Err(usb_err("USB reset", e)),
            };
        }
        Err(DeviceError::Gone(format!("no USB device at port {port}")))
    }

    /// Wait at most `max` for a hotplug event: `Some(true)` when one came, `Some(false)` when
    /// none did, `None` without hotplug support.
    pub fn wait_event(&mut self, max: Duration) -> Option<bool> {
        self.registration.as_ref()?;
        let deadline = Instant::now() + max;
        loop {
            let n = self.events.load(Ordering::Relaxed);
            if n != self.seen {
                self.seen = n;
                return Some(true);
            }
            let now = Instant::now();
            if now >= deadline {
                return Some(false);
            }
            if let Err(e) = self.ctx.handle_events(Some(deadline - now)) {
                tracing::debug!("libusb events: {e}");
                std::thread::sleep(deadline.saturating_duration_since(Instant::now()));
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    #[test]
    fn sysfs_port_names_parse_to_bus_and_chain() {
        assert_eq!(parse_port("3-1.4"), Some((3, vec![1, 4])));
        assert_eq!(parse_port("1-2"), Some((1, vec![2])));
        assert_eq!(
            parse_port("2-1.2.3.4.5.6.7"),
            Some((2, vec![1, 2, 3, 4, 5, 6, 7]))
        );
        for bad in [
            "usb3",
            "3-1:1.0",
            "3-",
            "-1",
            "x-1",
            "3-1.x",
            "3-1..2",
            "300-1",
            "2-1.2.3.4.5.6.7.8",
        ] {
            assert_eq!(parse_port(bad), None, "{bad}");
        }
    }
}
