//! Modbus RTU frames: the requests and responses the grippers use (function codes 0x03, 0x04,
//! 0x06, 0x10, 0x17 and exceptions), their encoding, and a streaming decoder that cuts CRC-checked
//! frames out of a byte stream and resynchronises after garbage.
//!
//! The decoder holds at most [`MAX_BUFFER`] bytes whatever it is fed (older bytes are dropped and
//! counted), never panics on any input, and returns the earliest complete frame whose CRC checks.

use crate::crc::{append_crc, crc_ok};
use thiserror::Error;

/// Largest RTU frame (address + PDU of 253 bytes + CRC).
pub const MAX_ADU: usize = 256;
/// Bytes the decoder keeps at most.
pub const MAX_BUFFER: usize = 2 * MAX_ADU + 8;
/// Register counts allowed by the Modbus specification.
pub const MAX_READ_REGS: u16 = 125;
pub const MAX_WRITE_REGS: u16 = 123;
pub const MAX_RW_WRITE_REGS: u16 = 121;

pub const FC_READ_HOLDING: u8 = 0x03;
pub const FC_READ_INPUT: u8 = 0x04;
pub const FC_WRITE_SINGLE: u8 = 0x06;
pub const FC_WRITE_MULTIPLE: u8 = 0x10;
pub const FC_READ_WRITE: u8 = 0x17;

#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum FrameError {
    #[error("register count {qty} out of range 1..={max} for function 0x{function:02X}")]
    Quantity { function: u8, qty: usize, max: u16 },
    #[error("unsupported function code 0x{0:02X}")]
    Function(u8),
    #[error("malformed {what} PDU (function 0x{function:02X}, {len} bytes)")]
    Malformed {
        what: &'static str,
        function: u8,
        len: usize,
    },
    #[error("reply does not match the request: {0}")]
    Mismatch(String),
}

/// A request (client -> device).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Request {
    ReadHolding {
        addr: u16,
        qty: u16,
    },
    ReadInput {
        addr: u16,
        qty: u16,
    },
    WriteSingle {
        addr: u16,
        value: u16,
    },
    WriteMultiple {
        addr: u16,
        values: Vec<u16>,
    },
    /// Write `values` at `write_addr`, then read `read_qty` registers at `read_addr`, in one frame.
    ReadWrite {
        read_addr: u16,
        read_qty: u16,
        write_addr: u16,
        values: Vec<u16>,
    },
}

/// A response (device -> client).
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Response {
    /// Registers read by 0x03, 0x04 or 0x17.
    Registers(Vec<u16>),
    WriteSingle {
        addr: u16,
        value: u16,
    },
    WriteMultiple {
        addr: u16,
        qty: u16,
    },
    Exception {
        function: u8,
        code: u8,
    },
}

fn be(b: &[u8], i: usize) -> Option<u16> {
    Some(u16::from_be_bytes([*b.get(i)?, *b.get(i + 1)?]))
}

fn regs(b: &[u8]) -> Vec<u16> {
    b.chunks_exact(2)
        .map(|c| u16::from_be_bytes([c[0], c[1]]))
        .collect()
}

fn check_qty(function: u8, qty: usize, max: u16) -> Result<(), FrameError> {
    if qty == 0 || qty > usize::from(max) {
        return Err(FrameError::Quantity { function, qty, max });
    }
    Ok(())
}

impl Request {
    pub fn function(&self) -> u8 {
        match self {
            Request::ReadHolding { .. } => FC_READ_HOLDING,
            Request::ReadInput { .. } => FC_READ_INPUT,
            Request::WriteSingle { .. } => FC_WRITE_SINGLE,
            Request::WriteMultiple { .. } => FC_WRITE_MULTIPLE,
            Request::ReadWrite { .. } => FC_READ_WRITE,
        }
    }

    /// The RTU frame (address, PDU, CRC).
    pub fn encode(&self, slave: u8) -> Result<Vec<u8>, FrameError> {
        let f = self.function();
        let mut out = vec![slave, f];
        match self {
            Request::ReadHolding { addr, qty } | Request::ReadInput { addr, qty } => {
                check_qty(f, usize::from(*qty), MAX_READ_REGS)?;
                out.extend_from_slice(&addr.to_be_bytes());
                out.extend_from_slice(&qty.to_be_bytes());
            }
            Request::WriteSingle { addr, value } => {
                out.extend_from_slice(&addr.to_be_bytes());
                out.extend_from_slice(&value.to_be_bytes());
            }
            Request::WriteMultiple { addr, values } => {
                check_qty(f, values.len(), MAX_WRITE_REGS)?;
                out.extend_from_slice(&addr.to_be_bytes());
                out.extend_from_slice(&(values.len() as u16).to_be_bytes());
                out.push((values.len() * 2) as u8);
                values
                    .iter()
                    .for_each(|v| out.extend_from_slice(&v.to_be_bytes()));
            }
            Request::ReadWrite {
                read_addr,
                read_qty,
                write_addr,
                values,
            } => {
                check_qty(f, usize::from(*read_qty), MAX_READ_REGS)?;
                check_qty(f, values.len(), MAX_RW_WRITE_REGS)?;
                out.extend_from_slice(&read_addr.to_be_bytes());
                out.extend_from_slice(&read_qty.to_be_bytes());
                out.extend_from_slice(&write_addr.to_be_bytes());
                out.extend_from_slice(&(values.len() as u16).to_be_bytes());
                out.push((values.len() * 2) as u8);
                values
                    .iter()
                    .for_each(|v| out.extend_from_slice(&v.to_be_bytes()));
            }
        }
        append_crc(&mut out);
        Ok(out)
    }

    /// Parse a request frame's PDU (device side).
    pub fn decode(frame: &RawFrame) -> Result<Request, FrameError> {
        let p = &frame.data;
        let f = frame.function;
        let bad = || FrameError::Malformed {
            what: "request",
            function: f,
            len: p.len(),
        };
        let w = |i| be(p, i).ok_or_else(bad);
        let req = match f {
            FC_READ_HOLDING | FC_READ_INPUT => {
                let (addr, qty) = (w(0)?, w(2)?);
                check_qty(f, usize::from(qty), MAX_READ_REGS)?;
                if f == FC_READ_HOLDING {
                    Request::ReadHolding { addr, qty }
                } else {
                    Request::ReadInput { addr, qty }
                }
            }
            FC_WRITE_SINGLE => Request::WriteSingle {
                addr: w(0)?,
                value: w(2)?,
            },
            FC_WRITE_MULTIPLE => {
                let (addr, qty) = (w(0)?, w(2)?);
                let values = regs(p.get(5..).ok_or_else(bad)?);
                let count = usize::from(*p.get(4).ok_or_else(bad)?);
                if values.len() != usize::from(qty) || count != 2 * usize::from(qty) {
                    return Err(bad());
                }
                check_qty(f, values.len(), MAX_WRITE_REGS)?;
                Request::WriteMultiple { addr, values }
            }
            FC_READ_WRITE => {
                let (read_addr, read_qty, write_addr, qty) = (w(0)?, w(2)?, w(4)?, w(6)?);
                let values = regs(p.get(9..).ok_or_else(bad)?);
                let count = usize::from(*p.get(8).ok_or_else(bad)?);
                if values.len() != usize::from(qty) || count != 2 * usize::from(qty) {
                    return Err(bad());
                }
                check_qty(f, usize::from(read_qty), MAX_READ_REGS)?;
                check_qty(f, values.len(), MAX_RW_WRITE_REGS)?;
                Request::ReadWrite {
                    read_addr,
                    read_qty,
                    write_addr,
                    values,
                }
            }
            other => return Err(FrameError::Function(other)),
        };
        Ok(req)
    }
}

impl Response {
    /// The RTU frame answering a request with function code `function`.
    pub fn encode(&self, slave: u8, function: u8) -> Vec<u8> {
        let mut out = vec![slave];
        match self {
            Response::Registers(r) => {
                let r = &r[..r.len().min(usize::from(MAX_READ_REGS))];
                out.push(function);
                out.push((r.len() * 2) as u8);
                r.iter()
                    .for_each(|v| out.extend_from_slice(&v.to_be_bytes()));
            }
            Response::WriteSingle { addr, value } => {
                out.push(FC_WRITE_SINGLE);
                out.extend_from_slice(&addr.to_be_bytes());
                out.extend_from_slice(&value.to_be_bytes());
            }
            Response::WriteMultiple { addr, qty } => {
                out.push(FC_WRITE_MULTIPLE);
                out.extend_from_slice(&addr.to_be_bytes());
                out.extend_from_slice(&qty.to_be_bytes());
            }
            Response::Exception { function, code } => {
                out.push(function | 0x80);
                out.push(*code);
            }
        }
        append_crc(&mut out);
        out
    }

    /// Interpret a CRC-checked frame as the reply to `req` (client side): the function code, byte
    /// count and echoed fields must match.
    pub fn decode_for(req: &Request, frame: &RawFrame) -> Result<Response, FrameError> {
        let p = &frame.data;
        let f = req.function();
        if frame.function == f | 0x80 {
            let code = p.first().copied().unwrap_or(0);
            return Ok(Response::Exception { function: f, code });
        }
        if frame.function != f {
            return Err(FrameError::Mismatch(format!(
                "function 0x{:02X}, expected 0x{f:02X}",
                frame.function
            )));
        }
        let bad = || FrameError::Malformed {
            what: "response",
            function: f,
            len: p.len(),
        };
        match req {
            Request::ReadHolding { qty, .. }
            | Request::ReadInput { qty, .. }
            | Request::ReadWrite { read_qty: qty, .. } => {
                let n = usize::from(*p.first().ok_or_else(bad)?);
                if n != usize::from(*qty) * 2 || p.len() != n + 1 {
                    return Err(FrameError::Mismatch(format!(
                        "{n} data bytes, expected {}",
                        usize::from(*qty) * 2
                    )));
                }
                Ok(Response::Registers(regs(&p[1..])))
            }
            Request::WriteSingle { addr, value } => {
                let (a, v) = (be(p, 0).ok_or_else(bad)?, be(p, 2).ok_or_else(bad)?);
                if (a, v) != (*addr, *value) {
                    return Err(FrameError::Mismatch(format!(
                        "echo {a:#06x}={v:#06x}, wrote {addr:#06x}={value:#06x}"
                    )));
                }
                Ok(Response::WriteSingle { addr: a, value: v })
            }
            Request::WriteMultiple { addr, values } => {
                let (a, q) = (be(p, 0).ok_or_else(bad)?, be(p, 2).ok_or_else(bad)?);
                if a != *addr || usize::from(q) != values.len() {
                    return Err(FrameError::Mismatch(format!(
                        "echo {a:#06x} x{q}, wrote {addr:#06x} x{}",
                        values.len()
                    )));
                }
                Ok(Response::WriteMultiple { addr: a, qty: q })
            }
        }
    }
}

/// Which side of the line a decoder listens on (frame lengths differ).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Direction {
    /// Decode requests (a device).
    Requests,
    /// Decode responses (a client).
    Responses,
}

/// A CRC-checked frame: slave address, function code, the data after the function code.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawFrame {
    pub slave: u8,
    pub function: u8,
    pub data: Vec<u8>,
}

/// What the head of a byte slice can be.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Head {
    /// No frame of this direction starts with these bytes.
    Invalid,
    /// Too few bytes to know the length.
    Unknown,
    /// A frame of this many bytes (CRC included) would start here.
    Len(usize),
}

/// Length of the frame starting at `b[0]`, from its function code (and byte count).
pub fn frame_len(dir: Direction, b: &[u8]) -> Head {
    let Some(&f) = b.get(1) else {
        return Head::Unknown;
    };
    let counted = |i: usize, fixed: usize| match b.get(i) {
        Some(&n) => Head::Len(fixed + usize::from(n)),
        None => Head::Unknown,
    };
    match dir {
        Direction::Responses => match f {
            _ if f & 0x80 != 0 => Head::Len(5),
            FC_READ_HOLDING | FC_READ_INPUT | FC_READ_WRITE => counted(2, 5),
            FC_WRITE_SINGLE | FC_WRITE_MULTIPLE => Head::Len(8),
            _ => Head::Invalid,
        },
        Direction::Requests => match f {
            FC_READ_HOLDING | FC_READ_INPUT | FC_WRITE_SINGLE => Head::Len(8),
            FC_WRITE_MULTIPLE => counted(6, 9),
            FC_READ_WRITE => counted(10, 13),
            // Functions no gripper here serves, framed so that a device can refuse them with an
            // exception: read coils / discrete inputs, write single coil (fixed 8 bytes), write
            // multiple coils (counted), mask write register (10 bytes).
            0x01 | 0x02 | 0x05 => Head::Len(8),
            0x0F => counted(6, 9),
            0x16 => Head::Len(10),
            _ => Head::Invalid,
        },
    }
}

/// Streaming RTU frame decoder with a bounded buffer.
#[derive(Debug, Clone)]
pub struct Decoder {
    dir: Direction,
    buf: Vec<u8>,
    dropped: u64,
}

impl Decoder {
    pub fn new(dir: Direction) -> Self {
        Self {
            dir,
            buf: Vec::with_capacity(MAX_BUFFER),
            dropped: 0,
        }
    }

    /// Add received bytes. The buffer never grows past [`MAX_BUFFER`]: the oldest bytes go.
    pub fn push(&mut self, bytes: &[u8]) {
        let bytes = if bytes.len() > MAX_BUFFER {
            self.dropped += (bytes.len() - MAX_BUFFER) as u64;
            &bytes[bytes.len() - MAX_BUFFER..]
        } else {
            bytes
        };
        let over = (self.buf.len() + bytes.len()).saturating_sub(MAX_BUFFER);
        if over > 0 {
            self.buf.drain(..over);
            self.dropped += over as u64;
        }
        self.buf.extend_from_slice(bytes);
    }

    /// The earliest complete frame whose CRC checks; the bytes before it are dropped (counted).
    pub fn next_frame(&mut self) -> Option<RawFrame> {
        // Leading bytes that cannot start a frame whatever follows (an unknown function code, or
        // a complete frame whose CRC fails) are garbage now.
        let lead = (0..self.buf.len())
            .find(|&i| {
                let rest = &self.buf[i..];
                match frame_len(self.dir, rest) {
                    Head::Invalid => false,
                    Head::Unknown => true,
                    Head::Len(n) => n > rest.len() || crc_ok(&rest[..n]),
                }
            })
            .unwrap_or(self.buf.len());
        if lead > 0 {
            self.buf.drain(..lead);
            self.dropped += lead as u64;
        }
        for i in 0..self.buf.len() {
            let rest = &self.buf[i..];
            let Head::Len(n) = frame_len(self.dir, rest) else {
                continue;
            };
            if n > rest.len() || !crc_ok(&rest[..n]) {
                continue;
            }
            let frame = RawFrame {
                slave: rest[0],
                function: rest[1],
                data: rest[2..n - 2].to_vec(),
            };
            self.buf.drain(..i + n);
            self.dropped += i as u64;
            return Some(frame);
        }
        None
    }

    /// Bytes buffered (a frame still arriving, or garbage).
    pub fn buffered(&self) -> usize {
        self.buf.len()
    }

    /// Length the frame at the head of the buffer would have, when known.
    pub fn head_len(&self) -> Option<usize> {
        match frame_len(self.dir, &self.buf) {
            Head::Len(n) => Some(n),
            _ => None,
        }
    }

    /// Forget buffered bytes (counted as dropped).
    pub fn clear(&mut self) {
        self.dropped += self.buf.len() as u64;
        self.buf.clear();
    }

    /// Bytes discarded so far while resynchronising.
    pub fn dropped(&self) -> u64 {
        self.dropped
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn request_roundtrip_through_the_decoder() {
        let reqs = [
            Request::ReadInput {
                addr: 0x07D0,
                qty: 3,
            },
            Request::ReadHolding {
                addr: 0x0200,
                qty: 3,
            },
            Request::WriteSingle {
                addr: 0x0103,
                value: 500,
            },
            Request::WriteMultiple {
                addr: 0x03E8,
                values: vec![0x0900, 0, 0xFFFF],
            },
            Request::ReadWrite {
                read_addr: 0x07D0,
                read_qty: 3,
                write_addr: 0x03E8,
                values: vec![0x0900, 0x00FF, 0xFF80],
            },
        ];
        let mut d = Decoder::new(Direction::Requests);
        for r in &reqs {
            let adu = r.encode(9).unwrap();
            // Garbage before, and the frame split in two writes.
            d.push(&[0xFF, 0x09]);
            d.push(&adu[..3]);
            assert_eq!(d.next_frame(), None);
            d.push(&adu[3..]);
            let f = d.next_frame().unwrap();
            assert_eq!(f.slave, 9);
            assert_eq!(&Request::decode(&f).unwrap(), r);
        }
        assert_eq!(d.dropped(), 2 * reqs.len() as u64);
        assert_eq!(d.buffered(), 0);
    }

    #[test]
    fn responses_are_checked_against_the_request() {
        let req = Request::ReadWrite {
            read_addr: 0x07D0,
            read_qty: 3,
            write_addr: 0x03E8,
            values: vec![0x0900, 0, 0],
        };
        let ok = Response::Registers(vec![0xF100, 0x0000, 0xE316]).encode(9, FC_READ_WRITE);
        assert_eq!(ok.len(), 11);
        let mut d = Decoder::new(Direction::Responses);
        d.push(&ok);
        let f = d.next_frame().unwrap();
        assert_eq!(
            Response::decode_for(&req, &f).unwrap(),
            Response::Registers(vec![0xF100, 0x0000, 0xE316])
        );
        // Two registers where three were asked for: a mismatch, not a panic.
        d.push(&Response::Registers(vec![1, 2]).encode(9, FC_READ_WRITE));
        let f = d.next_frame().unwrap();
        assert!(matches!(
            Response::decode_for(&req, &f),
            Err(FrameError::Mismatch(_))
        ));
        // A corrupted CRC is never a frame.
        let mut bad = ok.clone();
        bad[10] ^= 0x55;
        d.push(&bad);
        assert_eq!(d.next_frame(), None);
        // Exception frames decode as exceptions.
        d.push(
            &Response::Exception {
                function: FC_READ_WRITE,
                code: 2,
            }
            .encode(9, FC_READ_WRITE),
        );
        let f = d.next_frame().unwrap();
        assert_eq!(
            Response::decode_for(&req, &f).unwrap(),
            Response::Exception {
                function: FC_READ_WRITE,
                code: 2
            }
        );
    }

    #[test]
    fn quantities_are_bounded() {
        let r = Request::ReadInput { addr: 0, qty: 126 };
        assert!(matches!(r.encode(1), Err(FrameError::Quantity { .. })));
        let r = Request::WriteMultiple {
            addr: 0,
            values: vec![],
        };
        assert!(matches!(r.encode(1), Err(FrameError::Quantity { .. })));
    }
}
