//! A small CDR (XCDR1, little endian) codec: exactly what ROS 2 messages on the wire and in bags use.
//!
//! Layout facts this relies on: a payload starts with the 4-byte encapsulation header `00 01 00 00`
//! (CDR, little endian, options 0); alignment of each primitive is to its own size, counted from
//! the end of that header; a string is a u32 length that counts the trailing NUL, the bytes, then
//! the NUL; a sequence is a u32 element count, then the elements; fixed arrays have no count.
//!
//! Every length read from a payload is checked twice before anything is allocated: against a
//! fixed limit (the `MAX_*` constants) and against the bytes that are actually left, so a hostile message
//! can make us allocate at most about its own size.

use thiserror::Error;

/// Encapsulation header of a little-endian plain CDR payload.
pub const CDR_LE_HEADER: [u8; 4] = [0x00, 0x01, 0x00, 0x00];

/// Longest string accepted in any message (bytes, NUL included).
pub const MAX_STRING: usize = 64 * 1024;
/// Most elements in any sequence other than image bytes.
pub const MAX_SEQUENCE: usize = 1 << 24;
/// Most bytes in an image's data (8192 x 8192 x 4 channels).
pub const MAX_IMAGE_BYTES: usize = 8192 * 8192 * 4;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum CdrError {
    #[error("CDR payload too short for its encapsulation header ({0} bytes)")]
    NoHeader(usize),
    #[error("unsupported CDR encapsulation {0:02x} {1:02x} (only little-endian plain CDR, 00 01)")]
    Encapsulation(u8, u8),
    #[error("CDR payload ends early reading {what} at byte {offset} (need {need}, have {have})")]
    Eof {
        what: &'static str,
        offset: usize,
        need: usize,
        have: usize,
    },
    #[error("{what}: length {len} is over the limit {max}")]
    TooLong {
        what: &'static str,
        len: usize,
        max: usize,
    },
    #[error("string {what} has no terminating NUL")]
    NoNul { what: &'static str },
    #[error("string {what} is not UTF-8")]
    Utf8 { what: &'static str },
    #[error("{what}: value {value} is not one of the message's constants")]
    BadEnum { what: &'static str, value: u8 },
    #[error("{0} trailing bytes after the message")]
    Trailing(usize),
    /// The fields decoded but break a rule of the message (e.g. a latent's shape vs its data).
    #[error(transparent)]
    Check(#[from] unitac_core::msg::MsgError),
}

/// Writes one CDR payload; starts with the encapsulation header.
#[derive(Debug, Clone)]
pub struct CdrWriter {
    buf: Vec<u8>,
}

impl Default for CdrWriter {
    fn default() -> Self {
        Self::new()
    }
}

impl CdrWriter {
    pub fn new() -> Self {
        Self::with_capacity(64)
    }
    pub fn with_capacity(n: usize) -> Self {
        let mut buf = Vec::with_capacity(n + 4);
        buf.extend_from_slice(&CDR_LE_HEADER);
        Self { buf }
    }
    fn align(&mut self, n: usize) {
        let pos = self.buf.len() - 4;
        let pad = (n - pos % n) % n;
        self.buf.resize(self.buf.len() + pad, 0);
    }
    pub fn u8(&mut self, v: u8) {
        self.buf.push(v);
    }
    pub fn bool(&mut self, v: bool) {
        self.buf.push(u8::from(v));
    }
    pub fn u32(&mut self, v: u32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn i32(&mut self, v: i32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn u64(&mut self, v: u64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f32(&mut self, v: f32) {
        self.align(4);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    pub fn f64(&mut self, v: f64) {
        self.align(8);
        self.buf.extend_from_slice(&v.to_le_bytes());
    }
    /// A count or string length; lengths beyond u32 cannot be written and saturate (callers keep
    /// their data far below that).
    fn len(&mut self, n: usize) {
        self.u32(u32::try_from(n).unwrap_or(u32::MAX));
    }
    pub fn string(&mut self, s: &str) {
        self.len(s.len() + 1);
        self.buf.extend_from_slice(s.as_bytes());
        self.buf.push(0);
    }
    /// `uint8[]`
    pub fn bytes(&mut self, b: &[u8]) {
        self.len(b.len());
        self.buf.extend_from_slice(b);
    }
    /// `uint32[]`
    pub fn seq_u32(&mut self, v: &[u32]) {
        self.len(v.len());
        for &x in v {
            self.u32(x);
        }
    }
    /// `float32[]`
    pub fn seq_f32(&mut self, v: &[f32]) {
        self.len(v.len());
        for &x in v {
            self.f32(x);
        }
    }
    /// `float64[]`
    pub fn seq_f64(&mut self, v: &[f64]) {
        self.len(v.len());
        for &x in v {
            self.f64(x);
        }
    }
    /// `string[]`
    pub fn seq_string(&mut self, v: &[String]) {
        self.len(v.len());
        for x in v {
            self.string(x);
        }
    }
    pub fn finish(self) -> Vec<u8> {
        self.buf
    }
}

/// Reads one CDR payload with bounds on every length.
#[derive(Debug, Clone)]
pub struct CdrReader<'a> {
    /// The payload after the encapsulation header.
    body: &'a [u8],
    pos: usize,
}

impl<'a> CdrReader<'a> {
    pub fn new(payload: &'a [u8]) -> Result<Self, CdrError> {
        let (head, body) = payload
            .split_at_checked(4)
            .ok_or(CdrError::NoHeader(payload.len()))?;
        if head[0] != 0 || head[1] != 1 {
            return Err(CdrError::Encapsulation(head[0], head[1]));
        }
        Ok(Self { body, pos: 0 })
    }
    pub fn remaining(&self) -> usize {
        self.body.len().saturating_sub(self.pos)
    }
    /// Up to seven bytes of padding at the end are allowed: writers pad to 4, and Fast-CDR
    /// (rmw_fastrtps) also aligns an empty `float64[]` at the end of a message to 8 (a real
    /// TactileLatent's empty condition ages: 4 bytes after their length).
    pub fn finish(&self) -> Result<(), CdrError> {
        let rest = self.remaining();
        if rest > 7 {
            return Err(CdrError::Trailing(rest));
        }
        Ok(())
    }
    fn align(&mut self, n: usize) {
        self.pos += (n - self.pos % n) % n;
    }
    fn take(&mut self, n: usize, what: &'static str) -> Result<&'a [u8], CdrError> {
        let end = self.pos.checked_add(n);
        match end.and_then(|e| self.body.get(self.pos..e)) {
            Some(s) => {
                self.pos += n;
                Ok(s)
            }
            None => Err(CdrError::Eof {
                what,
                offset: self.pos + 4,
                need: n,
                have: self.remaining(),
            }),
        }
    }
    fn array<const N: usize>(&mut self, what: &'static str) -> Result<[u8; N], CdrError> {
        self.align(N);
        let s = self.take(N, what)?;
        let mut a = [0u8; N];
        a.copy_from_slice(s);
        Ok(a)
    }
    pub fn u8(&mut self, what: &'static str) -> Result<u8, CdrError> {
        Ok(self.take(1, what)?[0])
    }
    pub fn bool(&mut self, what: &'static str) -> Result<bool, CdrError> {
        Ok(self.u8(what)? != 0)
    }
    pub fn u32(&mut self, what: &'static str) -> Result<u32, CdrError> {
        self.array::<4>(what).map(u32::from_le_bytes)
    }
    pub fn i32(&mut self, what: &'static str) -> Result<i32, CdrError> {
        self.array::<4>(what).map(i32::from_le_bytes)
    }
    pub fn u64(&mut self, what: &'static str) -> Result<u64, CdrError> {
        self.array::<8>(what).map(u64::from_le_bytes)
    }
    pub fn f32(&mut self, what: &'static str) -> Result<f32, CdrError> {
        self.array::<4>(what).map(f32::from_le_bytes)
    }
    pub fn f64(&mut self, what: &'static str) -> Result<f64, CdrError> {
        self.array::<8>(what).map(f64::from_le_bytes)
    }
    /// A count of elements of `elem` bytes each, checked against `max` and the bytes left.
    fn count(&mut self, what: &'static str, elem: usize, max: usize) -> Result<usize, CdrError> {
        let n = self.u32(what)? as usize;
        if n > max {
            return Err(CdrError::TooLong { what, len: n, max });
        }
        // The first element's padding aside, n elements need n * elem bytes.
        let need = n.saturating_mul(elem);
        if need > self.remaining() {
            return Err(CdrError::Eof {
                what,
                offset: self.pos + 4,
                need,
                have: self.remaining(),
            });
        }
        Ok(n)
    }
    pub fn string(&mut self, what: &'static str) -> Result<String, CdrError> {
        let n = self.count(what, 1, MAX_STRING)?;
        if n == 0 {
            // Some writers emit a zero length for "" (no NUL): accept it.
            return Ok(String::new());
        }
        let raw = self.take(n, what)?;
        let (last, text) = raw.split_last().ok_or(CdrError::NoNul { what })?;
        if *last != 0 {
            return Err(CdrError::NoNul { what });
        }
        std::str::from_utf8(text)
            .map(str::to_owned)
            .map_err(|_| CdrError::Utf8 { what })
    }
    /// `uint8[]` with its own limit.
    pub fn bytes(&mut self, what: &'static str, max: usize) -> Result<&'a [u8], CdrError> {
        let n = self.count(what, 1, max)?;
        self.take(n, what)
    }
    pub fn seq_u32(&mut self, what: &'static str, max: usize) -> Result<Vec<u32>, CdrError> {
        let n = self.count(what, 4, max)?;
        (0..n).map(|_| self.u32(what)).collect()
    }
    pub fn seq_f32(&mut self, what: &'static str, max: usize) -> Result<Vec<f32>, CdrError> {
        let n = self.count(what, 4, max)?;
        (0..n).map(|_| self.f32(what)).collect()
    }
    pub fn seq_f64(&mut self, what: &'static str, max: usize) -> Result<Vec<f64>, CdrError> {
        let n = self.count(what, 8, max)?;
        (0..n).map(|_| self.f64(what)).collect()
    }
    /// `string[]`: each string at least its 4-byte length.
    pub fn seq_string(&mut self, what: &'static str, max: usize) -> Result<Vec<String>, CdrError> {
        let n = self.count(what, 4, max)?;
        (0..n).map(|_| self.string(what)).collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layout_matches_ros() {
        // u8 then u32: 3 bytes of padding counted after the 4-byte header; string with NUL; the u64
        // at body offset 15 is padded to 16 (not to payload offset 24).
        let mut w = CdrWriter::new();
        w.u8(7);
        w.u32(0x0102_0304);
        w.string("ab");
        w.u64(9);
        let b = w.finish();
        assert_eq!(
            b,
            [
                0, 1, 0, 0, 7, 0, 0, 0, 4, 3, 2, 1, 3, 0, 0, 0, b'a', b'b', 0, 0, 9, 0, 0, 0, 0, 0,
                0, 0
            ]
        );
        let mut r = CdrReader::new(&b).unwrap();
        assert_eq!(r.u8("a").unwrap(), 7);
        assert_eq!(r.u32("b").unwrap(), 0x0102_0304);
        assert_eq!(r.string("c").unwrap(), "ab");
        assert_eq!(r.u64("d").unwrap(), 9);
        r.finish().unwrap();
    }

    #[test]
    fn hostile_lengths_are_errors_before_allocation() {
        let mut w = CdrWriter::new();
        w.u32(u32::MAX);
        let b = w.finish();
        let mut r = CdrReader::new(&b).unwrap();
        assert!(matches!(r.string("s"), Err(CdrError::TooLong { .. })));
        let mut r = CdrReader::new(&b).unwrap();
        assert!(matches!(
            r.bytes("data", MAX_IMAGE_BYTES),
            Err(CdrError::TooLong { .. })
        ));
        // Under the limit but more than what is left.
        let mut w = CdrWriter::new();
        w.u32(1000);
        let b = w.finish();
        let mut r = CdrReader::new(&b).unwrap();
        assert!(matches!(
            r.seq_f32("data", MAX_SEQUENCE),
            Err(CdrError::Eof { need: 4000, .. })
        ));
        assert!(matches!(
            CdrReader::new(&[0, 0, 0, 0]),
            Err(CdrError::Encapsulation(0, 0))
        ));
        assert!(matches!(
            CdrReader::new(&[0, 1]),
            Err(CdrError::NoHeader(2))
        ));
    }

    #[test]
    fn strings_need_nul_and_utf8() {
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2, 0, 0, 0, b'a', b'b']).unwrap();
        assert!(matches!(r.string("s"), Err(CdrError::NoNul { .. })));
        let mut r = CdrReader::new(&[0, 1, 0, 0, 2, 0, 0, 0, 0xff, 0]).unwrap();
        assert!(matches!(r.string("s"), Err(CdrError::Utf8 { .. })));
    }
}
