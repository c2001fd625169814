//! Baseline JPEG decoded at 1/8 scale from the DC coefficients only.
//!
//! At 1/8 scale every 8x8 block becomes one pixel whose value is the block's DC coefficient
//! (dequantised, /8, +128): the AC coefficients still have to be Huffman-parsed to find the next
//! block, but they are skipped (no value extension, no dequantisation, no IDCT). This is where
//! a general decoder spends its time even when asked for 1/8 scale, so this path is several times
//! faster on a 3280x2464 GelSight Mini frame. Supported: baseline / extended sequential Huffman,
//! 8-bit, one interleaved scan, 1 or 3 components, sampling factors 1 or 2, restart intervals.
//! Anything else returns [`DcError::Unsupported`] and the caller falls back to `jpeg-decoder`.
//! MJPEG frames without Huffman tables get the standard tables of ITU T.81 Annex K.3.

use std::sync::Arc;
use thiserror::Error;

#[derive(Debug, Error, PartialEq, Eq)]
pub enum DcError {
    #[error("unsupported JPEG: {0}")]
    Unsupported(String),
    #[error("corrupt JPEG: {0}")]
    Corrupt(String),
}

fn corrupt<T>(m: &str) -> Result<T, DcError> {
    Err(DcError::Corrupt(m.to_string()))
}

/// The entropy-coded data ended before the last MCU (of the scan or of a restart interval).
fn truncated<T>() -> Result<T, DcError> {
    corrupt("truncated: the data ends before the last MCU")
}

/// True if an EOI marker follows `from` (entropy-coded data holds no 0xFF but stuffed 0xFF 0x00
/// and RSTn markers, so the first 0xFF 0xD9 after the scan's start is its end).
fn eoi_after(data: &[u8], from: usize) -> bool {
    data.get(from..)
        .is_some_and(|d| d.windows(2).any(|w| w == [0xFF, 0xD9]))
}

/// Annex K.3 standard tables (BITS, HUFFVAL), used when an MJPEG frame has no DHT.
const STD_DC_BITS: [u8; 16] = [0, 1, 5, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0, 0, 0];
const STD_DC_VALS: [u8; 12] = [0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11];
const STD_DC_CHROMA_BITS: [u8; 16] = [0, 3, 1, 1, 1, 1, 1, 1, 1, 1, 1, 0, 0, 0, 0, 0];
const STD_AC_LUMA_BITS: [u8; 16] = [0, 2, 1, 3, 3, 2, 4, 3, 5, 5, 4, 4, 0, 0, 1, 0x7d];
const STD_AC_LUMA_VALS: [u8; 162] = [
    0x01, 0x02, 0x03, 0x00, 0x04, 0x11, 0x05, 0x12, 0x21, 0x31, 0x41, 0x06, 0x13, 0x51, 0x61, 0x07,
    0x22, 0x71, 0x14, 0x32, 0x81, 0x91, 0xa1, 0x08, 0x23, 0x42, 0xb1, 0xc1, 0x15, 0x52, 0xd1, 0xf0,
    0x24, 0x33, 0x62, 0x72, 0x82, 0x09, 0x0a, 0x16, 0x17, 0x18, 0x19, 0x1a, 0x25, 0x26, 0x27, 0x28,
    0x29, 0x2a, 0x34, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48, 0x49,
    0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68, 0x69,
    0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x83, 0x84, 0x85, 0x86, 0x87, 0x88, 0x89,
    0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5, 0xa6, 0xa7,
    0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3, 0xc4, 0xc5,
    0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda, 0xe1, 0xe2,
    0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf1, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];
const STD_AC_CHROMA_BITS: [u8; 16] = [0, 2, 1, 2, 4, 4, 3, 4, 7, 5, 4, 4, 0, 1, 2, 0x77];
const STD_AC_CHROMA_VALS: [u8; 162] = [
    0x00, 0x01, 0x02, 0x03, 0x11, 0x04, 0x05, 0x21, 0x31, 0x06, 0x12, 0x41, 0x51, 0x07, 0x61, 0x71,
    0x13, 0x22, 0x32, 0x81, 0x08, 0x14, 0x42, 0x91, 0xa1, 0xb1, 0xc1, 0x09, 0x23, 0x33, 0x52, 0xf0,
    0x15, 0x62, 0x72, 0xd1, 0x0a, 0x16, 0x24, 0x34, 0xe1, 0x25, 0xf1, 0x17, 0x18, 0x19, 0x1a, 0x26,
    0x27, 0x28, 0x29, 0x2a, 0x35, 0x36, 0x37, 0x38, 0x39, 0x3a, 0x43, 0x44, 0x45, 0x46, 0x47, 0x48,
    0x49, 0x4a, 0x53, 0x54, 0x55, 0x56, 0x57, 0x58, 0x59, 0x5a, 0x63, 0x64, 0x65, 0x66, 0x67, 0x68,
    0x69, 0x6a, 0x73, 0x74, 0x75, 0x76, 0x77, 0x78, 0x79, 0x7a, 0x82, 0x83, 0x84, 0x85, 0x86, 0x87,
    0x88, 0x89, 0x8a, 0x92, 0x93, 0x94, 0x95, 0x96, 0x97, 0x98, 0x99, 0x9a, 0xa2, 0xa3, 0xa4, 0xa5,
    0xa6, 0xa7, 0xa8, 0xa9, 0xaa, 0xb2, 0xb3, 0xb4, 0xb5, 0xb6, 0xb7, 0xb8, 0xb9, 0xba, 0xc2, 0xc3,
    0xc4, 0xc5, 0xc6, 0xc7, 0xc8, 0xc9, 0xca, 0xd2, 0xd3, 0xd4, 0xd5, 0xd6, 0xd7, 0xd8, 0xd9, 0xda,
    0xe2, 0xe3, 0xe4, 0xe5, 0xe6, 0xe7, 0xe8, 0xe9, 0xea, 0xf2, 0xf3, 0xf4, 0xf5, 0xf6, 0xf7, 0xf8,
    0xf9, 0xfa,
];

/// Bits of the one-step code lookup (codes up to this length decode in one table read).
const LOOKAHEAD: u32 = 9;
/// Bits of the DC lookup that yields code and value in one read.
const DC_BITS: u32 = 11;
/// Bits of the AC lookup that skips as many whole (code, value) symbols as fit in one read.
const AC_BITS: u32 = 12;

/// A Huffman table with the lookups the DC-only walk needs.
#[derive(Debug, Clone)]
struct Huffman {
    /// (length, symbol) for every LOOKAHEAD-bit prefix; length 0 = longer code.
    lut: Vec<(u8, u8)>,
    /// DC: for every DC_BITS prefix, (code + value bits, value); 0 bits = slow path.
    fast_dc: Vec<(u8, i16)>,
    /// AC: for every AC_BITS prefix, the whole symbols it holds: bits (0..=7), coefficient
    /// positions advanced (8..=15), ends with end-of-block (16); 0 = slow path.
    multi_ac: Vec<u32>,
    maxcode: [i32; 17],
    valoffset: [i32; 17],
    vals: Vec<u8>,
}

/// EXTEND (T.81 F.2.2.1): `v` read in `s` bits to a signed value.
#[inline(always)]
fn extend(v: i32, s: u32) -> i32 {
    if s == 0 {
        0
    } else if v < (1 << (s - 1)) {
        v - (1 << s) + 1
    } else {
        v
    }
}

impl Huffman {
    fn new(bits: &[u8; 16], vals: &[u8]) -> Result<Self, DcError> {
        let total: usize = bits.iter().map(|&b| usize::from(b)).sum();
        if total > 256 || total > vals.len() {
            return corrupt("Huffman table counts");
        }
        let mut lut = vec![(0u8, 0u8); 1 << LOOKAHEAD];
        let mut maxcode = [-1i32; 17];
        let mut valoffset = [0i32; 17];
        let mut code: u32 = 0;
        let mut k = 0usize;
        for len in 1..=16u32 {
            let n = u32::from(bits[len as usize - 1]);
            valoffset[len as usize] = k as i32 - code as i32;
            for _ in 0..n {
                if code >= (1 << len) {
                    return corrupt("Huffman code space overflow");
                }
                if len <= LOOKAHEAD {
                    let shift = LOOKAHEAD - len;
                    let start = (code << shift) as usize;
                    for e in lut.iter_mut().skip(start).take(1 << shift) {
                        *e = (len as u8, vals[k]);
                    }
                }
                code += 1;
                k += 1;
            }
            if n > 0 {
                maxcode[len as usize] = code as i32 - 1;
            }
            code <<= 1;
        }
        let mut h = Self {
            lut,
            fast_dc: Vec::new(),
            multi_ac: Vec::new(),
            maxcode,
            valoffset,
            vals: vals[..total].to_vec(),
        };
        h.fast_dc = (0..1u32 << DC_BITS)
            .map(|i| match h.symbol_at(i, DC_BITS) {
                Some((len, s)) if s <= 11 && len + u32::from(s) <= DC_BITS => {
                    let s = u32::from(s);
                    let v = (i >> (DC_BITS - len - s)) & ((1 << s) - 1);
                    ((len + s) as u8, extend(v as i32, s) as i16)
                }
                _ => (0, 0),
            })
            .collect();
        h.multi_ac = (0..1u32 << AC_BITS).map(|i| h.multi_entry(i)).collect();
        Ok(h)
    }

    /// The code at the top of a `width`-bit window: (code length, symbol), if it fits.
    fn symbol_at(&self, window: u32, width: u32) -> Option<(u32, u8)> {
        for len in 1..=width.min(16) {
            let c = (window >> (width - len)) as i32;
            if c <= self.maxcode[len as usize] {
                let i = usize::try_from(c + self.valoffset[len as usize]).ok()?;
                return self.vals.get(i).map(|&v| (len, v));
            }
        }
        None
    }

    /// Whole AC symbols (code and value bits) at the top of an AC_BITS window, stopping after
    /// an end-of-block.
    fn multi_entry(&self, window: u32) -> u32 {
        let (mut used, mut adv) = (0u32, 0u32);
        while used < AC_BITS {
            let rest = AC_BITS - used;
            let w = window & ((1 << rest) - 1);
            let Some((len, rs)) = self.symbol_at(w, rest) else {
                break;
            };
            let (r, s) = (u32::from(rs >> 4), u32::from(rs & 15));
            if len + s > rest {
                break;
            }
            used += len + s;
            if s == 0 && r != 15 {
                return used | adv << 8 | 1 << 16;
            }
            adv += if s == 0 { 16 } else { r + 1 };
            if adv >= 64 {
                break;
            }
        }
        if adv == 0 { 0 } else { used | adv << 8 }
    }
}

/// Tables built from the last frames' DHT segments (MJPEG repeats the same ones every frame).
#[derive(Debug, Default, Clone)]
struct TableCache {
    entries: Vec<(Vec<u8>, Arc<Huffman>)>,
}

impl TableCache {
    const MAX: usize = 8;
    /// `key` = class/id byte, BITS, HUFFVAL of one table.
    fn get(&mut self, key: &[u8], bits: &[u8; 16], vals: &[u8]) -> Result<Arc<Huffman>, DcError> {
        if let Some((_, t)) = self.entries.iter().find(|(k, _)| k == key) {
            return Ok(t.clone());
        }
        let t = Arc::new(Huffman::new(bits, vals)?);
        if self.entries.len() >= Self::MAX {
            self.entries.remove(0);
        }
        self.entries.push((key.to_vec(), t.clone()));
        Ok(t)
    }
}

struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    acc: u64,
    n: u32,
    marker: bool,
    /// Zero bits put in after the data ended or a marker came; those still in `acc` are its
    /// lowest bits, so the walk read past the scan's real data once `fill > n`.
    fill: u32,
}

impl<'a> Bits<'a> {
    fn new(data: &'a [u8], pos: usize) -> Self {
        Self {
            data,
            pos,
            acc: 0,
            n: 0,
            marker: false,
            fill: 0,
        }
    }
    /// True once a code was read from the zero bits past the end of the entropy-coded data: the
    /// scan (or restart interval) ended before the MCU being decoded (a truncated frame).
    #[inline(always)]
    fn overran(&self) -> bool {
        self.fill > self.n
    }
    /// Fill the accumulator to at least 57 bits: eight bytes at once when none of them is 0xFF
    /// (no stuffing, no marker), byte by byte otherwise; zeros after a marker or the end.
    #[inline(always)]
    fn refill(&mut self) {
        if !self.marker
            && let Some(w) = self.data.get(self.pos..self.pos + 8)
        {
            let mut b = [0u8; 8];
            b.copy_from_slice(w);
            let w = u64::from_be_bytes(b);
            let inv = !w;
            let has_ff = inv.wrapping_sub(0x0101_0101_0101_0101) & w & 0x8080_8080_8080_8080;
            if has_ff == 0 {
                let bytes = (64 - self.n) >> 3;
                // The bits of a partly taken byte are the stream's own: the next refill ORs
                // the same bits at the same place.
                self.acc |= w >> self.n;
                self.n += bytes * 8;
                self.pos += bytes as usize;
                return;
            }
        }
        while self.n <= 56 {
            let mut b = 0u8;
            if !self.marker {
                match self.data.get(self.pos) {
                    Some(&0xFF) => match self.data.get(self.pos + 1) {
                        Some(&0x00) => {
                            b = 0xFF;
                            self.pos += 2;
                        }
                        _ => self.marker = true,
                    },
                    Some(&x) => {
                        b = x;
                        self.pos += 1;
                    }
                    None => self.marker = true,
                }
            }
            if self.marker {
                self.fill = self.fill.saturating_add(8);
            }
            // Clear what a previous 8-byte read left below the valid bits, then put the byte.
            let shift = 56 - self.n;
            self.acc = (self.acc & !(0xFFu64 << shift)) | u64::from(b) << shift;
            self.n += 8;
        }
    }
    #[inline(always)]
    fn consume(&mut self, k: u32) {
        self.acc <<= k;
        self.n -= k;
    }
    #[inline(always)]
    fn decode(&mut self, h: &Huffman) -> Result<u8, DcError> {
        if self.n < 16 {
            self.refill();
        }
        let look = (self.acc >> (64 - LOOKAHEAD)) as usize;
        let (len, sym) = h.lut[look];
        if len > 0 {
            self.consume(u32::from(len));
            return Ok(sym);
        }
        let code16 = (self.acc >> 48) as i32;
        for len in (LOOKAHEAD + 1)..=16 {
            let c = code16 >> (16 - len);
            if c <= h.maxcode[len as usize] {
                self.consume(len);
                let i = c + h.valoffset[len as usize];
                return match usize::try_from(i).ok().and_then(|i| h.vals.get(i)) {
                    Some(&v) => Ok(v),
                    None => corrupt("Huffman value index"),
                };
            }
        }
        corrupt("bad Huffman code")
    }
    /// Read `s` (<= 16) bits as a signed coefficient.
    #[inline(always)]
    fn receive(&mut self, s: u8) -> i32 {
        if s == 0 {
            return 0;
        }
        if self.n < 16 {
            self.refill();
        }
        let s = u32::from(s.min(16));
        let v = (self.acc >> (64 - s)) as i32;
        self.consume(s);
        extend(v, s)
    }
    #[inline(always)]
    fn skip(&mut self, s: u8) {
        if s == 0 {
            return;
        }
        if self.n < 16 {
            self.refill();
        }
        self.consume(u32::from(s.min(16)));
    }
    /// Next DC difference.
    #[inline(always)]
    fn dc_diff(&mut self, h: &Huffman) -> Result<i32, DcError> {
        if self.n < 32 {
            self.refill();
        }
        let (t, v) = h.fast_dc[(self.acc >> (64 - DC_BITS)) as usize];
        if t > 0 {
            self.consume(u32::from(t));
            return Ok(i32::from(v));
        }
        let s = self.decode(h)?;
        if s > 11 {
            return corrupt("DC magnitude");
        }
        Ok(self.receive(s))
    }
    /// Walk the AC codes of one block without keeping them.
    #[inline(always)]
    fn skip_ac(&mut self, h: &Huffman) -> Result<(), DcError> {
        let mut k = 1u32;
        loop {
            if self.n < 32 {
                self.refill();
            }
            let e = h.multi_ac[(self.acc >> (64 - AC_BITS)) as usize];
            if e != 0 {
                let nk = k + (e >> 8 & 0xFF);
                if e >> 16 != 0 {
                    if nk <= 64 {
                        self.consume(e & 0xFF);
                        return Ok(());
                    }
                } else if nk < 64 {
                    self.consume(e & 0xFF);
                    k = nk;
                    continue;
                } else if nk == 64 {
                    self.consume(e & 0xFF);
                    return Ok(());
                }
            }
            // One symbol at a time (long codes, or a block that ends inside the window).
            let rs = self.decode(h)?;
            let (r, s) = (u32::from(rs >> 4), rs & 15);
            if s == 0 {
                if r != 15 {
                    return Ok(());
                }
                k += 16;
            } else {
                k += r + 1;
                self.skip(s);
            }
            if k >= 64 {
                return Ok(());
            }
        }
    }
    /// At a restart interval: drop the buffered bits and step over the RSTn marker.
    fn restart(&mut self) -> Result<(), DcError> {
        if self.overran() {
            return truncated();
        }
        self.acc = 0;
        self.n = 0;
        self.marker = false;
        self.fill = 0;
        while self.pos + 1 < self.data.len() {
            if self.data[self.pos] == 0xFF && (0xD0..=0xD7).contains(&self.data[self.pos + 1]) {
                self.pos += 2;
                return Ok(());
            }
            self.pos += 1;
        }
        corrupt("missing restart marker")
    }
}
#[derive(Debug, Clone, Copy, Default)]
struct Comp {
    id: u8,
    h: usize,
    v: usize,
    tq: usize,
    td: usize,
    ta: usize,
}

/// The image at 1/8 scale: `ceil(w/8)` x `ceil(h/8)` RGB8, and the full size from the header.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct DcImage {
    pub full_width: u32,
    pub full_height: u32,
    pub width: u32,
    pub height: u32,
    pub rgb: Vec<u8>,
}

fn u16_at(d: &[u8], i: usize) -> Result<usize, DcError> {
    match (d.get(i), d.get(i + 1)) {
        (Some(&a), Some(&b)) => Ok(usize::from(a) << 8 | usize::from(b)),
        _ => corrupt("truncated header"),
    }
}

/// A region of the 1/8-scale image in its pixels (one pixel per 8x8 block), ends exclusive.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct BlockRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

/// What the last [`DcDecoder::decode`] did.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct DcStats {
    /// Restart intervals in the frame (0: no restart markers).
    pub restart_intervals: u32,
    /// Intervals stepped over without entropy decoding (wholly outside the region asked for).
    pub intervals_skipped: u32,
    /// Threads that entropy-decoded (2 only with restart markers).
    pub threads: u32,
    /// MCUs entropy-decoded.
    pub mcus_decoded: u32,
}

/// The decoded 1/8-scale image, borrowed from the decoder (valid until the next decode).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct DcFrame<'a> {
    pub full_width: u32,
    pub full_height: u32,
    pub width: u32,
    pub height: u32,
    /// `width * height * 3` bytes; only the region asked for is guaranteed filled.
    pub rgb: &'a [u8],
}

#[derive(Debug, Clone)]
struct ScanComp {
    h: usize,
    v: usize,
    q: i32,
    dc: Arc<Huffman>,
    ac: Arc<Huffman>,
}

#[derive(Debug)]
struct Header {
    width: usize,
    height: usize,
    comps: Vec<ScanComp>,
    hmax: usize,
    vmax: usize,
    mcux: usize,
    mcuy: usize,
    restart_interval: usize,
    scan_start: usize,
}

/// Reusable DC-only decoder: keeps its Huffman tables (built once per distinct DHT), its
/// coefficient planes and its output between frames, so a stream allocates nothing per frame.
#[derive(Debug, Default, Clone)]
pub struct DcDecoder {
    cache: TableCache,
    /// One plane set per decoding thread (with restart markers the second thread writes its
    /// own set; the colour conversion takes each MCU from the set that decoded it).
    planes: [Vec<Vec<u8>>; 2],
    rgb: Vec<u8>,
    marks: Vec<usize>,
    /// Use a second thread when restart markers allow it (default on).
    pub single_thread: bool,
    pub stats: DcStats,
}

/// A DQT segment: the DC quantiser (the first value) of each table it defines, into `q0`.
fn parse_dqt(seg: &[u8], q0: &mut [i32; 4]) -> Result<(), DcError> {
    let mut i = 0;
    while i < seg.len() {
        let pq = seg[i] >> 4;
        let tq = usize::from(seg[i] & 15);
        if tq > 3 {
            return corrupt("DQT id");
        }
        let n = if pq == 0 { 64 } else { 128 };
        let t = seg
            .get(i + 1..i + 1 + n)
            .ok_or_else(|| DcError::Corrupt("DQT".into()))?;
        q0[tq] = if pq == 0 {
            i32::from(t[0])
        } else {
            i32::from(t[0]) << 8 | i32::from(t[1])
        };
        i += 1 + n;
    }
    Ok(())
}

/// A baseline SOF segment: width, height (each within `max_side`) and the components (1 or 3,
/// sampling 1 or 2 each way).
fn parse_sof(seg: &[u8], max_side: u32) -> Result<(usize, usize, Vec<Comp>), DcError> {
    if seg.first() != Some(&8) {
        return Err(DcError::Unsupported("precision is not 8 bits".into()));
    }
    let height = u16_at(seg, 1)?;
    let width = u16_at(seg, 3)?;
    let nc = usize::from(*seg.get(5).unwrap_or(&0));
    if width == 0 || height == 0 || width > max_side as usize || height > max_side as usize {
        return corrupt("frame size");
    }
    if nc != 1 && nc != 3 {
        return Err(DcError::Unsupported(format!("{nc} components")));
    }
    let mut comps = Vec::with_capacity(nc);
    for c in 0..nc {
        let s = seg
            .get(6 + 3 * c..9 + 3 * c)
            .ok_or_else(|| DcError::Corrupt("SOF".into()))?;
        let (h, v) = (usize::from(s[1] >> 4), usize::from(s[1] & 15));
        if !(1..=2).contains(&h) || !(1..=2).contains(&v) || s[2] > 3 {
            return Err(DcError::Unsupported(format!("sampling {h}x{v}")));
        }
        comps.push(Comp {
            id: s[0],
            h,
            v,
            tq: usize::from(s[2]),
            ..Comp::default()
        });
    }
    Ok((width, height, comps))
}

impl DcDecoder {
    pub fn new() -> Self {
        Self::default()
    }

    /// Decode at 1/8 scale. With `roi`, only the MCUs that hold it are decoded where the stream
    /// allows: decoding stops after its last MCU row, and with restart markers the intervals
    /// wholly outside it are stepped over and the rest split between two threads.
    pub fn decode(
        &mut self,
        data: &[u8],
        max_side: u32,
        roi: Option<BlockRect>,
    ) -> Result<DcFrame<'_>, DcError> {
        let hd = self.header(data, max_side)?;
        let (ow, oh) = (hd.width.div_ceil(8), hd.height.div_ceil(8));
        let roi = roi.map_or((0, 0, ow, oh), |r| {
            let x1 = (r.x1 as usize).min(ow);
            let y1 = (r.y1 as usize).min(oh);
            ((r.x0 as usize).min(x1), (r.y0 as usize).min(y1), x1, y1)
        });
        // MCU rows and columns that hold the region.
        let (mc0, mc1) = (roi.0 / hd.hmax, roi.2.div_ceil(hd.hmax).min(hd.mcux));
        let (mr0, mr1) = (roi.1 / hd.vmax, roi.3.div_ceil(hd.vmax).min(hd.mcuy));
        // Sized, not cleared: only blocks decoded in this frame are read back (the region's
        // MCUs are always decoded), so no per-frame memset. The second set only with restarts.
        let sets = if hd.restart_interval > 0 { 2 } else { 1 };
        for set in self.planes.iter_mut().take(sets) {
            set.resize(hd.comps.len(), Vec::new());
            for (p, c) in set.iter_mut().zip(&hd.comps) {
                p.resize(hd.mcux * c.h * hd.mcuy * c.v, 0);
            }
        }
        self.stats = DcStats {
            threads: 1,
            ..DcStats::default()
        };
        let total = hd.mcux * hd.mcuy;
        let mut split = total;
        if hd.restart_interval > 0 && self.find_restarts(data, &hd, total) {
            let ri = hd.restart_interval;
            let needed: Vec<usize> = (0..self.marks.len())
                .filter(|&i| {
                    let (a, b) = (i * ri, ((i + 1) * ri).min(total));
                    (a / hd.mcux..=(b - 1) / hd.mcux).any(|r| {
                        let c0 = if r == a / hd.mcux { a % hd.mcux } else { 0 };
                        let c1 = if r == (b - 1) / hd.mcux {
                            (b - 1) % hd.mcux
                        } else {
                            hd.mcux - 1
                        };
                        (mr0..mr1).contains(&r) && c0 < mc1 && c1 >= mc0
                    })
                })
                .collect();
            self.stats.restart_intervals = self.marks.len() as u32;
            self.stats.intervals_skipped = (self.marks.len() - needed.len()) as u32;
            let half = if self.single_thread || needed.len() < 2 {
                needed.len()
            } else {
                needed.len() / 2
            };
            let (first, second) = needed.split_at(half);
            if let Some(&i) = second.first() {
                split = i * ri;
            }
            let marks = &self.marks;
            let [p0, p1] = &mut self.planes;
            let run = |list: &[usize], planes: &mut Vec<Vec<u8>>| -> Result<u32, DcError> {
                let mut n = 0;
                for &i in list {
                    let (a, b) = (i * ri, ((i + 1) * ri).min(total));
                    let mut bits = Bits::new(data, marks[i]);
                    decode_mcus(&hd, &mut bits, a, b, planes)?;
                    n += (b - a) as u32;
                }
                Ok(n)
            };
            let (n0, n1) = if second.is_empty() {
                (run(first, p0)?, 0)
            } else {
                self.stats.threads = 2;
                std::thread::scope(|s| {
                    let other = s.spawn(|| run(second, p1));
                    let mine = run(first, p0);
                    let theirs = other
                        .join()
                        .unwrap_or_else(|_| corrupt("decoder thread failed"));
                    Ok::<_, DcError>((mine?, theirs?))
                })?
            };
            self.stats.mcus_decoded = n0 + n1;
            // The last interval, if stepped over: as in the walk without restarts, decoded when
            // no EOI marker follows its start.
            let last = self.marks.len().saturating_sub(1);
            if let Some(&at) = self.marks.get(last)
                && !needed.contains(&last)
                && !eoi_after(data, at)
            {
                let mut bits = Bits::new(data, at);
                decode_mcus(&hd, &mut bits, last * ri, total, &mut self.planes[0])?;
                self.stats.mcus_decoded += (total - last * ri) as u32;
            }
        } else {
            // No restart markers: every MCU before the region's last row must be parsed.
            let end = (mr1 * hd.mcux).min(total);
            let mut bits = Bits::new(data, hd.scan_start);
            decode_mcus(&hd, &mut bits, 0, end, &mut self.planes[0])?;
            self.stats.mcus_decoded = end as u32;
            // The rows after the region are not decoded when an EOI marker shows the scan goes
            // on to its end; without one (a cut frame, or a camera that leaves EOI out) they are
            // walked too, so a frame that ends before its last MCU is an error on every path.
            if end < total && !eoi_after(data, bits.pos) {
                decode_mcus(&hd, &mut bits, end, total, &mut self.planes[0])?;
                self.stats.mcus_decoded = total as u32;
            }
        }
        self.rgb.resize(ow * oh * 3, 0);
        to_rgb(&hd, &self.planes, split, roi, &mut self.rgb);
        Ok(DcFrame {
            full_width: hd.width as u32,
            full_height: hd.height as u32,
            width: ow as u32,
            height: oh as u32,
            rgb: &self.rgb,
        })
    }

    /// Start offsets of all restart intervals in `marks`; false if the markers do not match the
    /// interval count (the sequential walk then reports the error).
    fn find_restarts(&mut self, data: &[u8], hd: &Header, total: usize) -> bool {
        let want = total.div_ceil(hd.restart_interval);
        self.marks.clear();
        self.marks.push(hd.scan_start);
        let mut i = hd.scan_start;
        while self.marks.len() < want {
            // Eight bytes at a time while none is 0xFF.
            while let Some(w) = data.get(i..i + 8) {
                let mut b = [0u8; 8];
                b.copy_from_slice(w);
                let w = u64::from_ne_bytes(b);
                if (!w).wrapping_sub(0x0101_0101_0101_0101) & w & 0x8080_8080_8080_8080 != 0 {
                    break;
                }
                i += 8;
            }
            match (data.get(i), data.get(i + 1)) {
                (Some(0xFF), Some(0xD0..=0xD7)) => {
                    i += 2;
                    self.marks.push(i);
                }
                (Some(0xFF), Some(0xD9)) | (_, None) => return false,
                _ => i += 1,
            }
        }
        true
    }

    fn header(&mut self, data: &[u8], max_side: u32) -> Result<Header, DcError> {
        if data.get(..2) != Some(&[0xFF, 0xD8][..]) {
            return corrupt("no SOI");
        }
        let mut pos = 2;
        let mut q0 = [0i32; 4];
        let mut dc_tabs: [Option<Arc<Huffman>>; 4] = [None, None, None, None];
        let mut ac_tabs: [Option<Arc<Huffman>>; 4] = [None, None, None, None];
        let mut comps: Vec<Comp> = Vec::new();
        let (mut width, mut height) = (0usize, 0usize);
        let mut restart_interval = 0usize;
        loop {
            while data.get(pos) == Some(&0xFF) && data.get(pos + 1) == Some(&0xFF) {
                pos += 1;
            }
            let (Some(&0xFF), Some(&m)) = (data.get(pos), data.get(pos + 1)) else {
                return corrupt("marker expected");
            };
            if m == 0xD9 {
                return corrupt("EOI before scan");
            }
            let len = u16_at(data, pos + 2)?;
            let seg = data
                .get(pos + 4..pos + 2 + len)
                .ok_or_else(|| DcError::Corrupt("truncated segment".into()))?;
            match m {
                0xDB => parse_dqt(seg, &mut q0)?,
                0xC4 => {
                    let mut i = 0;
                    while i < seg.len() {
                        let class = seg[i] >> 4;
                        let id = usize::from(seg[i] & 15);
                        let bits: [u8; 16] = seg
                            .get(i + 1..i + 17)
                            .and_then(|b| b.try_into().ok())
                            .ok_or_else(|| DcError::Corrupt("DHT".into()))?;
                        let n: usize = bits.iter().map(|&b| usize::from(b)).sum();
                        let vals = seg
                            .get(i + 17..i + 17 + n)
                            .ok_or_else(|| DcError::Corrupt("DHT values".into()))?;
                        let t = self.cache.get(&seg[i..i + 17 + n], &bits, vals)?;
                        match (class, id) {
                            (0, 0..=3) => dc_tabs[id] = Some(t),
                            (1, 0..=3) => ac_tabs[id] = Some(t),
                            _ => return corrupt("DHT class/id"),
                        }
                        i += 17 + n;
                    }
                }
                0xC0 | 0xC1 => (width, height, comps) = parse_sof(seg, max_side)?,
                0xC2 | 0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF => {
                    return Err(DcError::Unsupported(format!("SOF{}", m - 0xC0)));
                }
                0xDD => restart_interval = u16_at(seg, 0)?,
                0xDA => {
                    let ns = usize::from(*seg.first().unwrap_or(&0));
                    if comps.is_empty() || ns != comps.len() {
                        return Err(DcError::Unsupported("not one interleaved scan".into()));
                    }
                    for k in 0..ns {
                        let s = seg
                            .get(1 + 2 * k..3 + 2 * k)
                            .ok_or_else(|| DcError::Corrupt("SOS".into()))?;
                        let c = comps
                            .iter_mut()
                            .find(|c| c.id == s[0])
                            .ok_or_else(|| DcError::Corrupt("SOS component".into()))?;
                        c.td = usize::from(s[1] >> 4).min(3);
                        c.ta = usize::from(s[1] & 15).min(3);
                    }
                    pos += 2 + len;
                    break;
                }
                _ => {}
            }
            pos += 2 + len;
        }
        // MJPEG (AVI1) frames may carry no Huffman tables: use the standard ones.
        if dc_tabs[0].is_none() {
            dc_tabs[0] = Some(self.std_table(0x00, &STD_DC_BITS, &STD_DC_VALS)?);
            dc_tabs[1] = Some(self.std_table(0x01, &STD_DC_CHROMA_BITS, &STD_DC_VALS)?);
        }
        if ac_tabs[0].is_none() {
            ac_tabs[0] = Some(self.std_table(0x10, &STD_AC_LUMA_BITS, &STD_AC_LUMA_VALS)?);
            ac_tabs[1] = Some(self.std_table(0x11, &STD_AC_CHROMA_BITS, &STD_AC_CHROMA_VALS)?);
        }
        if comps.len() == 1 {
            comps[0].h = 1;
            comps[0].v = 1;
        }
        let hmax = comps.iter().map(|c| c.h).max().unwrap_or(1);
        let vmax = comps.iter().map(|c| c.v).max().unwrap_or(1);
        let mut scan = Vec::with_capacity(comps.len());
        for c in &comps {
            let (Some(dc), Some(ac)) = (dc_tabs[c.td].clone(), ac_tabs[c.ta].clone()) else {
                return corrupt("scan uses a missing Huffman table");
            };
            scan.push(ScanComp {
                h: c.h,
                v: c.v,
                q: q0[c.tq],
                dc,
                ac,
            });
        }
        Ok(Header {
            width,
            height,
            comps: scan,
            hmax,
            vmax,
            mcux: width.div_ceil(8 * hmax),
            mcuy: height.div_ceil(8 * vmax),
            restart_interval,
            scan_start: pos,
        })
    }

    fn std_table(&mut self, tc: u8, bits: &[u8; 16], vals: &[u8]) -> Result<Arc<Huffman>, DcError> {
        let mut key = vec![tc];
        key.extend_from_slice(bits);
        key.extend_from_slice(vals);
        self.cache.get(&key, bits, vals)
    }
}

/// Entropy-decode MCUs `from..to` (one restart interval, or the whole scan with its restarts),
/// storing each block's DC value (dequantised, /8, +128) in `planes`.
fn decode_mcus(
    hd: &Header,
    bits: &mut Bits<'_>,
    from: usize,
    to: usize,
    planes: &mut [Vec<u8>],
) -> Result<(), DcError> {
    let mut pred = [0i32; 3];
    let ri = hd.restart_interval;
    for m in from..to {
        if ri > 0 && m > from && m % ri == 0 {
            bits.restart()?;
            pred = [0; 3];
        }
        let (my, mx) = (m / hd.mcux, m % hd.mcux);
        for (ci, c) in hd.comps.iter().enumerate() {
            let pw = hd.mcux * c.h;
            for by in 0..c.v {
                for bx in 0..c.h {
                    pred[ci] += bits.dc_diff(&c.dc)?;
                    bits.skip_ac(&c.ac)?;
                    let v = ((pred[ci] * c.q + 4) >> 3) + 128;
                    let idx = (my * c.v + by) * pw + mx * c.h + bx;
                    if let Some(p) = planes[ci].get_mut(idx) {
                        *p = v.clamp(0, 255) as u8;
                    }
                }
            }
        }
        if bits.overran() {
            return truncated();
        }
    }
    Ok(())
}

/// YCbCr planes (MCU `< split` from set 0, the rest from set 1) to RGB8 inside `roi`.
fn to_rgb(
    hd: &Header,
    planes: &[Vec<Vec<u8>>; 2],
    split: usize,
    roi: (usize, usize, usize, usize),
    rgb: &mut [u8],
) {
    let ow = hd.width.div_ceil(8);
    let (x0, y0, x1, y1) = roi;
    for y in y0..y1 {
        let row_mcu = y / hd.vmax * hd.mcux;
        let xs = split.saturating_sub(row_mcu).min(hd.mcux) * hd.hmax;
        let line = &mut rgb[(y * ow + x0) * 3..(y * ow + x1) * 3];
        if hd.comps.len() == 1 {
            for (x, d) in (x0..x1).zip(line.chunks_exact_mut(3)) {
                let g = planes[usize::from(x >= xs)][0][y * hd.mcux + x];
                d.copy_from_slice(&[g, g, g]);
            }
            continue;
        }
        let (cy, cb, cr) = (&hd.comps[0], &hd.comps[1], &hd.comps[2]);
        let row = |c: &ScanComp| y * c.v / hd.vmax * hd.mcux * c.h;
        let (ry, rb, rr) = (row(cy), row(cb), row(cr));
        for (x, d) in (x0..x1).zip(line.chunks_exact_mut(3)) {
            let p = &planes[usize::from(x >= xs)];
            let l = i32::from(p[0][ry + x * cy.h / hd.hmax]) << 16;
            let b = i32::from(p[1][rb + x * cb.h / hd.hmax]) - 128;
            let r = i32::from(p[2][rr + x * cr.h / hd.hmax]) - 128;
            let px = |v: i32| ((v + 32_768) >> 16).clamp(0, 255) as u8;
            d[0] = px(l + 91_881 * r);
            d[1] = px(l - 22_554 * b - 46_802 * r);
            d[2] = px(l + 116_130 * b);
        }
    }
}

/// True if an EOI marker follows the first scan's start (markers are walked segment by segment
/// up to SOS, so an EOI inside an EXIF thumbnail does not count).
pub fn has_eoi(data: &[u8]) -> bool {
    scan_start(data).is_some_and(|at| eoi_after(data, at))
}

/// Offset of the first byte after the first SOS segment.
fn scan_start(data: &[u8]) -> Option<usize> {
    if data.get(..2) != Some(&[0xFF, 0xD8][..]) {
        return None;
    }
    let mut pos = 2;
    loop {
        while data.get(pos) == Some(&0xFF) && data.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        if *data.get(pos)? != 0xFF {
            return None;
        }
        let m = *data.get(pos + 1)?;
        if m == 0xD9 {
            return None;
        }
        let len = u16_at(data, pos + 2).ok()?;
        if len < 2 {
            return None;
        }
        pos += 2 + len;
        if m == 0xDA {
            return Some(pos);
        }
    }
}

/// Decode a whole frame at 1/8 scale (one pixel per 8x8 block) with a fresh decoder.
pub fn decode_dc(data: &[u8], max_side: u32) -> Result<DcImage, DcError> {
    let mut d = DcDecoder::new();
    let f = d.decode(data, max_side, None)?;
    Ok(DcImage {
        full_width: f.full_width,
        full_height: f.full_height,
        width: f.width,
        height: f.height,
        rgb: f.rgb.to_vec(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
    use super::*;

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        for d in [
            &[][..],
            &[0xFF, 0xD8][..],
            &[0xFF, 0xD8, 0xFF, 0xC0, 0x00][..],
            &[0xFF, 0xD8, 0xFF, 0xDA, 0x00, 0x02][..],
            &[0xFF; 64][..],
        ] {
            assert!(decode_dc(d, 8192).is_err());
        }
    }

    #[test]
    fn standard_tables_are_complete() {
        assert_eq!(
            STD_AC_LUMA_BITS
                .iter()
                .map(|&b| usize::from(b))
                .sum::<usize>(),
            162
        );
        assert_eq!(
            STD_AC_CHROMA_BITS
                .iter()
                .map(|&b| usize::from(b))
                .sum::<usize>(),
            162
        );
        assert_eq!(
            STD_DC_BITS.iter().map(|&b| usize::from(b)).sum::<usize>(),
            12
        );
        assert_eq!(
            STD_DC_CHROMA_BITS
                .iter()
                .map(|&b| usize::from(b))
                .sum::<usize>(),
            12
        );
        Huffman::new(&STD_AC_LUMA_BITS, &STD_AC_LUMA_VALS).unwrap();
        Huffman::new(&STD_AC_CHROMA_BITS, &STD_AC_CHROMA_VALS).unwrap();
    }
}
