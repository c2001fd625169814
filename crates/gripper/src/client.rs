//! Modbus RTU client: one request, one reply, with a per-request timeout, bounded retries, CRC
//! checking, resynchronisation after garbage and a drain of late bytes before a retry, so a reply
//! that arrives after its timeout is never taken for the answer to the next request.

use crate::frame::{Decoder, Direction, FrameError, Request, Response};
use serde::Serialize;
use std::io;
use std::time::{Duration, Instant};
use thiserror::Error;

/// A byte link to the bus (a serial port, a pseudo-terminal).
pub trait Link: Send {
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()>;
    /// Read what is there, waiting at most `timeout`; `Ok(0)` when nothing came.
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize>;
    /// Discard received bytes not read yet.
    fn clear_input(&mut self) -> io::Result<()>;
}

impl<P: serialport::SerialPort + ?Sized> Link for Box<P> {
    /// A tty write is unbuffered; no `flush` (serialport maps it to tcdrain, which on some USB
    /// adapters waits milliseconds longer than the bytes take).
    fn write_all(&mut self, bytes: &[u8]) -> io::Result<()> {
        io::Write::write_all(self.as_mut(), bytes)
    }
    fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
        self.set_timeout(timeout.max(Duration::from_micros(100)))?;
        match io::Read::read(self.as_mut(), buf) {
            Err(e) if e.kind() == io::ErrorKind::TimedOut => Ok(0),
            // A pseudo-terminal (and some USB adapters) report a vanished peer as 0 bytes read
            // immediately; poll said readable, so this is a hang-up, not a timeout.
            Ok(0) => Err(io::Error::new(
                io::ErrorKind::BrokenPipe,
                "serial device hung up",
            )),
            other => other,
        }
    }
    fn clear_input(&mut self) -> io::Result<()> {
        self.clear(serialport::ClearBuffer::Input)
            .map_err(io::Error::other)
    }
}

#[derive(Debug, Error)]
pub enum ModbusError {
    #[error("no reply from slave {slave} within {timeout_s} s")]
    NoReply { slave: u8, timeout_s: f64 },
    #[error(
        "incomplete reply from slave {slave}: got {got} of {expected} bytes within {timeout_s} s"
    )]
    Incomplete {
        slave: u8,
        got: usize,
        expected: usize,
        timeout_s: f64,
    },
    #[error("garbled reply: {bytes} bytes with no valid frame (CRC errors) within {timeout_s} s")]
    Garbled { bytes: usize, timeout_s: f64 },
    #[error(
        "reply from slave {got}, expected slave {expected} (wrong slave id or two devices on the bus)"
    )]
    WrongSlave { expected: u8, got: u8 },
    #[error("Modbus exception 0x{code:02X} for function 0x{function:02X}")]
    Exception { function: u8, code: u8 },
    #[error(transparent)]
    Frame(#[from] FrameError),
    #[error("serial I/O: {0}")]
    Io(#[from] io::Error),
}

impl ModbusError {
    /// Whether the link itself failed (re-open the port).
    pub fn is_link(&self) -> bool {
        matches!(self, ModbusError::Io(_))
    }
    fn retryable(&self) -> bool {
        !matches!(
            self,
            ModbusError::Io(_)
                | ModbusError::Exception { .. }
                | ModbusError::Frame(FrameError::Quantity { .. })
        )
    }
}

/// Client settings.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct ClientConfig {
    pub slave: u8,
    /// Time from the end of the request to the end of the reply before a try fails.
    pub timeout: Duration,
    /// Extra tries after a failed one (0 = one try only).
    pub retries: u8,
    /// Line rate (what a benchmark's wire limit is computed for).
    pub baud: u32,
}

impl ClientConfig {
    pub fn new(slave: u8, baud: u32) -> Self {
        Self {
            slave,
            timeout: Duration::from_millis(50),
            retries: 2,
            baud,
        }
    }
}

/// Round-trip times of recent successful exchanges and error counters.
#[derive(Debug, Clone, Default, PartialEq, Serialize)]
pub struct LinkStats {
    pub requests: u64,
    pub ok: u64,
    pub retries: u64,
    pub no_reply: u64,
    pub incomplete: u64,
    pub garbled: u64,
    pub wrong_slave: u64,
    pub exceptions: u64,
    /// Valid frames from the slave that do not answer the request (another function code, a
    /// wrong length or echo).
    pub bad_replies: u64,
    pub dropped_bytes: u64,
    #[serde(skip)]
    rtt: Vec<Duration>,
    #[serde(skip)]
    rtt_next: usize,
}

/// What came back from the bus for requests that failed, the most telling kind first: a device
/// that answered wrongly is there (power and wiring work), unlike a silent one.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum CameBack {
    /// Not a byte.
    Nothing,
    /// Modbus exception replies: the slave is there and refused the request.
    Exceptions,
    /// Valid frames from the slave that do not answer the request (another function code).
    WrongReplies,
    /// Replies from another slave id.
    WrongSlave,
    /// Bytes with no valid frame (CRC errors).
    Garbled,
    /// The start of a frame, never its end.
    Incomplete,
}

/// Round trips kept for the percentiles.
const RTT_WINDOW: usize = 1024;

impl LinkStats {
    /// What came back for the failed requests so far (see [`CameBack`]).
    pub fn came_back(&self) -> CameBack {
        if self.exceptions > 0 {
            CameBack::Exceptions
        } else if self.bad_replies > 0 {
            CameBack::WrongReplies
        } else if self.wrong_slave > 0 {
            CameBack::WrongSlave
        } else if self.garbled > 0 {
            CameBack::Garbled
        } else if self.incomplete > 0 {
            CameBack::Incomplete
        } else {
            CameBack::Nothing
        }
    }

    fn record_rtt(&mut self, d: Duration) {
        if self.rtt.len() < RTT_WINDOW {
            self.rtt.push(d);
        } else {
            self.rtt[self.rtt_next] = d;
        }
        self.rtt_next = (self.rtt_next + 1) % RTT_WINDOW;
    }
    /// Percentile `q` in [0, 1] of the recent round trips \[s] (None before the first).
    pub fn rtt_percentile(&self, q: f64) -> Option<f64> {
        if self.rtt.is_empty() {
            return None;
        }
        let mut v = self.rtt.clone();
        v.sort_unstable();
        let i = ((v.len() - 1) as f64 * q.clamp(0.0, 1.0)).round() as usize;
        v.get(i).map(Duration::as_secs_f64)
    }
}

/// A Modbus RTU client over a [`Link`].
#[derive(Debug)]
pub struct RtuClient<L> {
    link: L,
    cfg: ClientConfig,
    dec: Decoder,
    stats: LinkStats,
    buf: Vec<u8>,
}

impl<L: Link> RtuClient<L> {
    pub fn new(link: L, cfg: ClientConfig) -> Self {
        Self {
            link,
            cfg,
            dec: Decoder::new(Direction::Responses),
            stats: LinkStats::default(),
            buf: vec![0; 512],
        }
    }
    pub fn config(&self) -> &ClientConfig {
        &self.cfg
    }
    pub fn stats(&self) -> &LinkStats {
        &self.stats
    }

    /// Send `req` and return its reply, trying at most `1 + retries` times.
    pub fn call(&mut self, req: &Request) -> Result<Response, ModbusError> {
        let adu = req.encode(self.cfg.slave)?;
        self.stats.requests += 1;
        let mut attempt = 0;
        loop {
            let r = self.exchange(&adu, req);
            self.stats.dropped_bytes = self.dec.dropped();
            match r {
                Ok(Response::Exception { function, code }) => {
                    self.stats.exceptions += 1;
                    return Err(ModbusError::Exception { function, code });
                }
                Ok(resp) => {
                    self.stats.ok += 1;
                    return Ok(resp);
                }
                Err(e) => {
                    match &e {
                        ModbusError::NoReply { .. } => self.stats.no_reply += 1,
                        ModbusError::Incomplete { .. } => self.stats.incomplete += 1,
                        ModbusError::Garbled { .. } => self.stats.garbled += 1,
                        ModbusError::WrongSlave { .. } => self.stats.wrong_slave += 1,
                        ModbusError::Frame(_) => self.stats.bad_replies += 1,
                        _ => {}
                    }
                    if !e.retryable() || attempt >= self.cfg.retries {
                        return Err(e);
                    }
                    attempt += 1;
                    self.stats.retries += 1;
                    self.drain()?;
                }
            }
        }
    }

    /// Read and discard until the line has been quiet for one timeout (at most two), so a reply
    /// up to a timeout late is not taken for the answer to the retry. RTU has no transaction ids:
    /// a reply later than that can still be, which is why the timeout should exceed the device's
    /// worst latency.
    fn drain(&mut self) -> Result<(), ModbusError> {
        let quiet = self.cfg.timeout.max(Duration::from_millis(2));
        let end = Instant::now() + quiet * 2;
        while Instant::now() < end {
            if self.link.read(&mut self.buf, quiet)? == 0 {
                break;
            }
        }
        self.dec.clear();
        Ok(())
    }

    fn exchange(&mut self, adu: &[u8], req: &Request) -> Result<Response, ModbusError> {
        self.link.clear_input()?;
        self.dec.clear();
        let dropped0 = self.dec.dropped();
        self.link.write_all(adu)?;
        let t0 = Instant::now();
        let deadline = t0 + self.cfg.timeout;
        let mut received = 0usize;
        let mut wrong_slave = None;
        loop {
            while let Some(f) = self.dec.next_frame() {
                if f.slave != self.cfg.slave {
                    wrong_slave = Some(f.slave);
                    continue;
                }
                let resp = Response::decode_for(req, &f)?;
                self.stats.record_rtt(t0.elapsed());
                return Ok(resp);
            }
            let now = Instant::now();
            if now >= deadline {
                let timeout_s = self.cfg.timeout.as_secs_f64();
                let slave = self.cfg.slave;
                return Err(if let Some(got) = wrong_slave {
                    ModbusError::WrongSlave {
                        expected: slave,
                        got,
                    }
                } else if received == 0 {
                    ModbusError::NoReply { slave, timeout_s }
                } else if self.dec.dropped() > dropped0 || self.dec.head_len().is_none() {
                    ModbusError::Garbled {
                        bytes: received,
                        timeout_s,
                    }
                } else {
                    ModbusError::Incomplete {
                        slave,
                        got: self.dec.buffered(),
                        expected: self.dec.head_len().unwrap_or(0),
                        timeout_s,
                    }
                });
            }
            let n = self.link.read(&mut self.buf, deadline - now)?;
            received += n;
            self.dec.push(&self.buf[..n]);
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A link that answers every request with `reply` at once.
    struct Canned {
        reply: Vec<u8>,
        pending: bool,
    }

    impl Link for Canned {
        fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
            self.pending = true;
            Ok(())
        }
        fn read(&mut self, buf: &mut [u8], timeout: Duration) -> io::Result<usize> {
            if !std::mem::take(&mut self.pending) {
                std::thread::sleep(timeout.min(Duration::from_millis(1)));
                return Ok(0);
            }
            let n = self.reply.len().min(buf.len());
            buf[..n].copy_from_slice(&self.reply[..n]);
            Ok(n)
        }
        fn clear_input(&mut self) -> io::Result<()> {
            Ok(())
        }
    }

    fn client(reply: Vec<u8>) -> RtuClient<Canned> {
        let cfg = ClientConfig {
            timeout: Duration::from_millis(5),
            retries: 1,
            ..ClientConfig::new(9, 115_200)
        };
        RtuClient::new(
            Canned {
                reply,
                pending: false,
            },
            cfg,
        )
    }

    const READ: Request = Request::ReadInput {
        addr: 0x07D0,
        qty: 3,
    };

    #[test]
    fn what_came_back_is_told_apart_from_silence() {
        let mut silent = client(Vec::new());
        assert!(matches!(
            silent.call(&READ),
            Err(ModbusError::NoReply { .. })
        ));
        assert_eq!(silent.stats().came_back(), CameBack::Nothing);
        // A valid frame of another function (0x03 for a 0x04 read).
        let other = Response::Registers(vec![0, 0, 0]).encode(9, 0x03);
        let mut wrong = client(other);
        let e = wrong.call(&READ).unwrap_err();
        assert!(
            e.to_string().contains("function 0x03, expected 0x04"),
            "{e}"
        );
        assert_eq!(wrong.stats().bad_replies, 2);
        assert_eq!(wrong.stats().came_back(), CameBack::WrongReplies);
        // An exception reply.
        let exc = Response::Exception {
            function: 0x04,
            code: 0x02,
        }
        .encode(9, 0x04);
        let mut refused = client(exc);
        assert!(matches!(
            refused.call(&READ),
            Err(ModbusError::Exception { code: 0x02, .. })
        ));
        assert_eq!(refused.stats().came_back(), CameBack::Exceptions);
        // A reply with a corrupted CRC.
        let mut bad = Response::Registers(vec![0, 0, 0]).encode(9, 0x04);
        if let Some(b) = bad.last_mut() {
            *b ^= 0xA5;
        }
        let mut garbled = client(bad);
        assert!(garbled.call(&READ).is_err());
        assert_eq!(garbled.stats().came_back(), CameBack::Garbled);
    }
}
