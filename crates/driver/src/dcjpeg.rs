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

const LOOKAHEAD: u32 = 9;
const FAST_BITS: u32 = 11;

#[derive(Debug, Clone)]
struct Huffman {
    /// (length, symbol) for every 9-bit prefix; length 0 = longer code.
    lut: Vec<(u8, u8)>,
    /// AC only: for every FAST_BITS prefix, code and skipped value bits in one step:
    /// (total bits, coefficient positions advanced, end of block); total 0 = slow path.
    fast_ac: Vec<(u8, u8, bool)>,
    maxcode: [i32; 17],
    valoffset: [i32; 17],
    vals: Vec<u8>,
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
        // Fused AC entries: code length + value bits fit in FAST_BITS.
        let mut fast_ac = vec![(0u8, 0u8, false); 1 << FAST_BITS];
        let mut code: u32 = 0;
        let mut k = 0usize;
        for len in 1..=16u32 {
            for _ in 0..bits[len as usize - 1] {
                let rs = vals[k];
                let (r, sz) = (u32::from(rs >> 4), u32::from(rs & 15));
                let total = len + sz;
                if total <= FAST_BITS {
                    let entry = if sz == 0 && r == 0 {
                        (len as u8, 0, true)
                    } else if sz == 0 {
                        (len as u8, 16, false)
                    } else {
                        (total as u8, (r + 1) as u8, false)
                    };
                    let shift = FAST_BITS - len;
                    let start = (code << shift) as usize;
                    for e in fast_ac.iter_mut().skip(start).take(1 << shift) {
                        *e = entry;
                    }
                }
                code += 1;
                k += 1;
            }
            code <<= 1;
        }
        Ok(Self {
            lut,
            fast_ac,
            maxcode,
            valoffset,
            vals: vals[..total].to_vec(),
        })
    }
}

struct Bits<'a> {
    data: &'a [u8],
    pos: usize,
    acc: u64,
    n: u32,
    marker: bool,
}

impl<'a> Bits<'a> {
    fn new(data: &'a [u8], pos: usize) -> Self {
        Self {
            data,
            pos,
            acc: 0,
            n: 0,
            marker: false,
        }
    }
    #[inline(always)]
    fn refill(&mut self) {
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
            self.acc |= u64::from(b) << (56 - self.n);
            self.n += 8;
        }
    }
    #[inline(always)]
    fn decode(&mut self, h: &Huffman) -> Result<u8, DcError> {
        if self.n < 16 {
            self.refill();
        }
        let look = (self.acc >> (64 - LOOKAHEAD)) as usize;
        let (len, sym) = h.lut[look];
        if len > 0 {
            self.acc <<= len;
            self.n -= u32::from(len);
            return Ok(sym);
        }
        let code16 = (self.acc >> 48) as i32;
        for len in (LOOKAHEAD + 1)..=16 {
            let c = code16 >> (16 - len);
            if c <= h.maxcode[len as usize] {
                self.acc <<= len;
                self.n -= len;
                let i = c + h.valoffset[len as usize];
                return match usize::try_from(i).ok().and_then(|i| h.vals.get(i)) {
                    Some(&v) => Ok(v),
                    None => corrupt("Huffman value index"),
                };
            }
        }
        corrupt("bad Huffman code")
    }
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
        self.acc <<= s;
        self.n -= s;
        // EXTEND (F.2.2.1)
        if v < (1 << (s - 1)) {
            v - (1 << s) + 1
        } else {
            v
        }
    }
    #[inline(always)]
    fn skip(&mut self, s: u8) {
        if s == 0 {
            return;
        }
        if self.n < 16 {
            self.refill();
        }
        let s = u32::from(s.min(16));
        self.acc <<= s;
        self.n -= s;
    }
    /// At a restart interval: drop the buffered bits and step over the RSTn marker.
    fn restart(&mut self) -> Result<(), DcError> {
        self.acc = 0;
        self.n = 0;
        self.marker = false;
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

/// Read just the frame size (SOF) of a JPEG.
pub fn jpeg_size(data: &[u8]) -> Result<(u32, u32), DcError> {
    let mut pos = 2;
    if data.get(..2) != Some(&[0xFF, 0xD8][..]) {
        return corrupt("no SOI");
    }
    loop {
        while data.get(pos) == Some(&0xFF) && data.get(pos + 1) == Some(&0xFF) {
            pos += 1;
        }
        let (Some(&0xFF), Some(&m)) = (data.get(pos), data.get(pos + 1)) else {
            return corrupt("marker expected");
        };
        let len = u16_at(data, pos + 2)?;
        if matches!(m, 0xC0..=0xC3 | 0xC5..=0xC7 | 0xC9..=0xCB | 0xCD..=0xCF) {
            let h = u16_at(data, pos + 5)?;
            let w = u16_at(data, pos + 7)?;
            return Ok((w as u32, h as u32));
        }
        if m == 0xD9 || m == 0xDA {
            return corrupt("no frame header");
        }
        pos += 2 + len;
    }
}

/// Decode at 1/8 scale (one pixel per 8x8 block of the image).
pub fn decode_dc(data: &[u8], max_side: u32) -> Result<DcImage, DcError> {
    if data.get(..2) != Some(&[0xFF, 0xD8][..]) {
        return corrupt("no SOI");
    }
    let mut pos = 2;
    let mut q0 = [0i32; 4];
    let mut dc_tabs: [Option<Huffman>; 4] = [None, None, None, None];
    let mut ac_tabs: [Option<Huffman>; 4] = [None, None, None, None];
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
            0xDB => {
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
            }
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
                    let t = Huffman::new(&bits, vals)?;
                    match (class, id) {
                        (0, 0..=3) => dc_tabs[id] = Some(t),
                        (1, 0..=3) => ac_tabs[id] = Some(t),
                        _ => return corrupt("DHT class/id"),
                    }
                    i += 17 + n;
                }
            }
            0xC0 | 0xC1 => {
                if seg.first() != Some(&8) {
                    return Err(DcError::Unsupported("precision is not 8 bits".into()));
                }
                height = u16_at(seg, 1)?;
                width = u16_at(seg, 3)?;
                let nc = usize::from(*seg.get(5).unwrap_or(&0));
                if width == 0
                    || height == 0
                    || width > max_side as usize
                    || height > max_side as usize
                {
                    return corrupt("frame size");
                }
                if nc != 1 && nc != 3 {
                    return Err(DcError::Unsupported(format!("{nc} components")));
                }
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
            }
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
        dc_tabs[0] = Some(Huffman::new(&STD_DC_BITS, &STD_DC_VALS)?);
        dc_tabs[1] = Some(Huffman::new(&STD_DC_CHROMA_BITS, &STD_DC_VALS)?);
    }
    if ac_tabs[0].is_none() {
        ac_tabs[0] = Some(Huffman::new(&STD_AC_LUMA_BITS, &STD_AC_LUMA_VALS)?);
        ac_tabs[1] = Some(Huffman::new(&STD_AC_CHROMA_BITS, &STD_AC_CHROMA_VALS)?);
    }
    let single = comps.len() == 1;
    if single {
        comps[0].h = 1;
        comps[0].v = 1;
    }
    let hmax = comps.iter().map(|c| c.h).max().unwrap_or(1);
    let vmax = comps.iter().map(|c| c.v).max().unwrap_or(1);
    let mcux = width.div_ceil(8 * hmax);
    let mcuy = height.div_ceil(8 * vmax);
    let mut planes: Vec<Vec<u8>> = comps
        .iter()
        .map(|c| vec![0u8; mcux * c.h * mcuy * c.v])
        .collect();
    let mut tabs = Vec::with_capacity(comps.len());
    for c in &comps {
        let (Some(dc), Some(ac)) = (dc_tabs[c.td].as_ref(), ac_tabs[c.ta].as_ref()) else {
            return corrupt("scan uses a missing Huffman table");
        };
        tabs.push((dc, ac, q0[c.tq]));
    }
    let mut pred = vec![0i32; comps.len()];
    let mut bits = Bits::new(data, pos);
    let mut left = restart_interval;
    for my in 0..mcuy {
        for mx in 0..mcux {
            if restart_interval > 0 {
                if left == 0 {
                    bits.restart()?;
                    pred.iter_mut().for_each(|p| *p = 0);
                    left = restart_interval;
                }
                left -= 1;
            }
            for (ci, c) in comps.iter().enumerate() {
                let (dc, ac, q) = tabs[ci];
                let pw = mcux * c.h;
                for by in 0..c.v {
                    for bx in 0..c.h {
                        let s = bits.decode(dc)?;
                        if s > 11 {
                            return corrupt("DC magnitude");
                        }
                        pred[ci] += bits.receive(s);
                        let mut k = 1;
                        while k < 64 {
                            if bits.n < 16 {
                                bits.refill();
                            }
                            let (total, adv, eob) =
                                ac.fast_ac[(bits.acc >> (64 - FAST_BITS)) as usize];
                            if total > 0 {
                                bits.acc <<= total;
                                bits.n -= u32::from(total);
                                if eob {
                                    break;
                                }
                                k += usize::from(adv);
                                continue;
                            }
                            let rs = bits.decode(ac)?;
                            let (r, s) = (rs >> 4, rs & 15);
                            if s == 0 {
                                if r == 15 {
                                    k += 16;
                                    continue;
                                }
                                break;
                            }
                            k += usize::from(r) + 1;
                            bits.skip(s);
                        }
                        let v = ((pred[ci] * q + 4) >> 3) + 128;
                        let idx = (my * c.v + by) * pw + mx * c.h + bx;
                        if let Some(p) = planes[ci].get_mut(idx) {
                            *p = v.clamp(0, 255) as u8;
                        }
                    }
                }
            }
        }
    }
    let (ow, oh) = (width.div_ceil(8), height.div_ceil(8));
    let mut rgb = vec![0u8; ow * oh * 3];
    if single {
        let pw = mcux;
        for y in 0..oh {
            for x in 0..ow {
                let g = planes[0][y * pw + x];
                rgb[(y * ow + x) * 3..(y * ow + x) * 3 + 3].copy_from_slice(&[g, g, g]);
            }
        }
    } else {
        let (cy_, cb_, cr_) = (&comps[0], &comps[1], &comps[2]);
        let (pwy, pwb, pwr) = (mcux * cy_.h, mcux * cb_.h, mcux * cr_.h);
        for y in 0..oh {
            let yy = y * cy_.v / vmax;
            let yb = y * cb_.v / vmax;
            let yr = y * cr_.v / vmax;
            for x in 0..ow {
                let l = i32::from(planes[0][yy * pwy + x * cy_.h / hmax]) << 16;
                let cb = i32::from(planes[1][yb * pwb + x * cb_.h / hmax]) - 128;
                let cr = i32::from(planes[2][yr * pwr + x * cr_.h / hmax]) - 128;
                let o = (y * ow + x) * 3;
                let px = |v: i32| ((v + 32_768) >> 16).clamp(0, 255) as u8;
                rgb[o] = px(l + 91_881 * cr);
                rgb[o + 1] = px(l - 22_554 * cb - 46_802 * cr);
                rgb[o + 2] = px(l + 116_130 * cb);
            }
        }
    }
    Ok(DcImage {
        full_width: width as u32,
        full_height: height as u32,
        width: ow as u32,
        height: oh as u32,
        rgb,
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
