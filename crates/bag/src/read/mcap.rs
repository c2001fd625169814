//! MCAP storage files, streamed with bounded memory.
//!
//! The data section is a flat sequence of records (opcode u8, length u64, body), so it is read
//! here record by record: the 9-byte header, the length checked against [`MAX_RECORD_BYTES`],
//! then the body straight from the file into a buffer reused across records (no zero fill per
//! read, no staging copy). A chunk record (zstd, lz4 or none) is decompressed after checking its
//! claimed size against the same limit; an uncompressed chunk's records are walked where they
//! were read, without a copy. Either way the chunk CRC is checked and the records inside are
//! walked with bounds checks. (The `mcap` crate's linear reader was used before: it zero-filled
//! its buffer before every read and its in-chunk walk underflows on a record longer than its
//! chunk, which the fuzz smoke found; `mcap::parse_record` reserves a string's claimed length
//! before checking the bytes exist: cargo fuzz found it.) The summary section is never needed: a
//! file a recorder could not finish is read up to its last complete record and flagged
//! `truncated`.

use super::{MAX_RECORD_BYTES, RawMessage, ReadOptions, TopicInfo, Visit};
use crate::BagError;
use std::collections::BTreeMap;
use std::io::{BufReader, Read};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use thiserror::Error;

/// Buffer for record headers and small records; reads at least this long go from the file
/// straight into the record buffer.
const READ_BUFFER: usize = 8 << 10;
/// The magic bytes an MCAP file starts with (and ends with).
const MAGIC: &[u8; 8] = b"\x89MCAP0\r\n";

/// Why an MCAP stream could not be read further (one line each).
#[derive(Debug, Error)]
pub enum McapError {
    #[error(
        "record 0x{opcode:02x}: field of {len} bytes at {at} overruns the record ({record} bytes)"
    )]
    FieldOverrun {
        opcode: u8,
        len: u64,
        at: usize,
        record: usize,
    },
    #[error("record 0x{opcode:02x}: string of {len} bytes, over the limit {MAX_NAME}")]
    LongString { opcode: u8, len: u32 },
    #[error("schemas and channels take more than {MAX_DEFINITIONS} bytes")]
    TooManyDefinitions,
    #[error("schema of {len} bytes, over the limit {MAX_SCHEMA}")]
    LongSchema { len: u32 },
    #[error("record 0x{opcode:02x}: string is not UTF-8")]
    NotUtf8 { opcode: u8 },
    #[error("chunk inside a chunk")]
    NestedChunk,
    #[error("message record of {0} bytes")]
    ShortMessage(usize),
    #[error("message on channel {0} that was not defined before it")]
    UnknownChannel(u16),
    #[error("channel {channel} ({topic}) uses schema {schema} that was not defined before it")]
    UnknownSchema {
        channel: u16,
        topic: String,
        schema: u16,
    },
    #[error("chunk ends inside a record header ({rest} bytes left)")]
    CutRecordHeader { rest: usize },
    #[error("record 0x{opcode:02x} of {len} bytes overruns its chunk ({rest} bytes left)")]
    RecordOverrun { opcode: u8, len: u64, rest: usize },
    #[error("chunk claims {0} uncompressed bytes, over the limit {MAX_RECORD_BYTES}")]
    ChunkTooLarge(u64),
    #[error("{codec} chunk: {source}")]
    Decompress {
        codec: &'static str,
        source: std::io::Error,
    },
    #[error("chunk compression '{0}' is not supported")]
    Compression(String),
    #[error("chunk holds {got} bytes after decompression, its header says {want}")]
    ChunkSize { got: usize, want: usize },
    #[error("chunk CRC {crc:08x} does not match its header ({want:08x})")]
    ChunkCrc { crc: u32, want: u32 },
    #[error("{0}")]
    Stream(::mcap::McapError),
}

pub(super) struct McapFile {
    pub(super) path: PathBuf,
    file: BufReader<Box<dyn Read + Send>>,
    /// Whether the magic bytes were read.
    started: bool,
    /// Body of the last top-level record.
    record: Vec<u8>,
    state: McapState,
    done: bool,
    pub(super) truncated: bool,
}

/// What the records so far defined, and the chunk being read.
struct McapState {
    /// Schema id -> (type name, ros2msg text).
    schemas: BTreeMap<u16, (String, String)>,
    channels: BTreeMap<u16, Arc<TopicInfo>>,
    /// Records of the current chunk: `chunk[chunk_pos..chunk_end]` is still to be walked (the
    /// decompressed records, or an uncompressed chunk's record body as it was read).
    chunk: Vec<u8>,
    chunk_pos: usize,
    chunk_end: usize,
    /// Set by an uncompressed chunk: where its records lie in the record body just handled
    /// (checked, CRC included); the caller then takes that body as the current chunk.
    in_place: Option<std::ops::Range<usize>>,
    end: bool,
    /// Bytes of names and schemas kept so far.
    defined: usize,
}

impl std::fmt::Debug for McapFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("McapFile")
            .field("path", &self.path)
            .field("channels", &self.state.channels)
            .finish_non_exhaustive()
    }
}

/// Opcodes this reader acts on (MCAP spec).
const OP_CHUNK: u8 = 0x06;
const OP_MESSAGE: u8 = 0x05;
const OP_FOOTER: u8 = 0x02;
const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_DATA_END: u8 = 0x0f;
/// Longest topic, type or encoding name accepted in a record.
const MAX_NAME: usize = 64 * 1024;
/// Longest schema accepted (a ros2msg text with all its dependencies is a few KiB).
const MAX_SCHEMA: usize = 1 << 20;
/// Most bytes of names and schemas kept for one file (ids are u16: 65 536 channels of 64 KiB
/// names each would be 4 GiB otherwise).
const MAX_DEFINITIONS: usize = 64 << 20;

struct ChunkHeader {
    uncompressed_size: u64,
    uncompressed_crc: u32,
    compression: String,
}

/// Little-endian fields of one record body, every read bounds-checked.
struct Fields<'a> {
    data: &'a [u8],
    pos: usize,
    opcode: u8,
}

impl<'a> Fields<'a> {
    fn new(data: &'a [u8], opcode: u8) -> Self {
        Self {
            data,
            pos: 0,
            opcode,
        }
    }
    fn take(&mut self, n: u64) -> Result<&'a [u8], McapError> {
        let end = usize::try_from(n)
            .ok()
            .and_then(|n| self.pos.checked_add(n))
            .filter(|&e| e <= self.data.len())
            .ok_or(McapError::FieldOverrun {
                opcode: self.opcode,
                len: n,
                at: self.pos,
                record: self.data.len(),
            })?;
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], McapError> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N as u64)?);
        Ok(a)
    }
    fn u16(&mut self) -> Result<u16, McapError> {
        self.array::<2>().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Result<u32, McapError> {
        self.array::<4>().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, McapError> {
        self.array::<8>().map(u64::from_le_bytes)
    }
    fn string(&mut self) -> Result<String, McapError> {
        let n = self.u32()?;
        if n as usize > MAX_NAME {
            return Err(McapError::LongString {
                opcode: self.opcode,
                len: n,
            });
        }
        let b = self.take(u64::from(n))?;
        String::from_utf8(b.to_vec()).map_err(|_| McapError::NotUtf8 {
            opcode: self.opcode,
        })
    }
}
/// channel_id u16, sequence u32, log_time u64, publish_time u64.
const MESSAGE_HEADER: usize = 22;

/// A wanted message: its payload is the record body from `offset` on.
struct Found {
    topic: Arc<TopicInfo>,
    log_time: i64,
    offset: usize,
}

impl McapState {
    /// Count `n` more bytes of definitions against [`MAX_DEFINITIONS`].
    fn defined(&mut self, n: usize) -> Result<(), McapError> {
        self.defined = self.defined.saturating_add(n);
        if self.defined > MAX_DEFINITIONS {
            return Err(McapError::TooManyDefinitions);
        }
        Ok(())
    }

    /// Handle one record from the file or from a chunk. Errors are one line, for the user.
    fn handle(
        &mut self,
        opcode: u8,
        data: &[u8],
        opts: &ReadOptions,
        in_chunk: bool,
    ) -> Result<Option<Found>, McapError> {
        if opcode == OP_CHUNK && in_chunk {
            return Err(McapError::NestedChunk);
        }
        if opcode == OP_MESSAGE {
            // Parsed here, not by parse_record: the payload stays where it is (no copy).
            let head = data
                .get(..MESSAGE_HEADER)
                .ok_or(McapError::ShortMessage(data.len()))?;
            let channel = u16::from_le_bytes([head[0], head[1]]);
            let mut t = [0u8; 8];
            t.copy_from_slice(&head[6..14]);
            let t = i64::try_from(u64::from_le_bytes(t)).unwrap_or(i64::MAX);
            let topic = self
                .channels
                .get(&channel)
                .ok_or(McapError::UnknownChannel(channel))?;
            if opts.wants(&topic.name, t) {
                return Ok(Some(Found {
                    topic: Arc::clone(topic),
                    log_time: t,
                    offset: MESSAGE_HEADER,
                }));
            }
            return Ok(None);
        }
        // Records are parsed here with bounds checks, not by mcap::parse_record: its string
        // reader reserves the claimed length (up to 4 GiB) before checking the bytes exist
        // (found by cargo fuzz). Records we do not need are not parsed at all.
        let mut r = Fields::new(data, opcode);
        match opcode {
            OP_SCHEMA => {
                let id = r.u16()?;
                let name = r.string()?;
                let encoding = r.string()?;
                let len = r.u32()?;
                if len as usize > MAX_SCHEMA {
                    return Err(McapError::LongSchema { len });
                }
                let data = r.take(u64::from(len))?;
                // Only ros2msg text is kept (what a rewritten bag needs); others stay unread.
                let text = match (encoding.as_str(), std::str::from_utf8(data)) {
                    ("ros2msg", Ok(t)) => t.to_string(),
                    _ => String::new(),
                };
                self.defined(name.len() + text.len())?;
                self.schemas.insert(id, (name, text));
            }
            OP_CHANNEL => {
                let id = r.u16()?;
                let schema_id = r.u16()?;
                let topic = r.string()?;
                let encoding = r.string()?;
                let (type_name, schema) = if schema_id == 0 {
                    (String::new(), String::new())
                } else {
                    self.schemas.get(&schema_id).cloned().ok_or_else(|| {
                        McapError::UnknownSchema {
                            channel: id,
                            topic: topic.clone(),
                            schema: schema_id,
                        }
                    })?
                };
                self.defined(topic.len() + encoding.len() + type_name.len() + schema.len())?;
                self.channels.insert(
                    id,
                    Arc::new(TopicInfo {
                        name: topic,
                        type_name,
                        encoding,
                        schema,
                    }),
                );
            }
            OP_CHUNK => {
                let _start = r.u64()?;
                let _end = r.u64()?;
                let header = ChunkHeader {
                    uncompressed_size: r.u64()?,
                    uncompressed_crc: r.u32()?,
                    compression: r.string()?,
                };
                let len = r.u64()?;
                let start = r.pos;
                let body = r.take(len)?;
                self.chunk_pos = 0;
                self.chunk_end = 0;
                if header.compression.is_empty() && !in_chunk {
                    // Walked where it lies: the caller keeps this record's buffer as the chunk.
                    check_stored(&header, body)?;
                    self.in_place = Some(start..start + body.len());
                } else {
                    // Into the previous chunk's buffer: no allocation (and no fresh pages to
                    // fault in) per chunk.
                    decompress_chunk(&header, body, &mut self.chunk)?;
                    self.chunk_end = self.chunk.len();
                }
            }
            // The summary repeats what the data section said.
            OP_DATA_END | OP_FOOTER => self.end = true,
            _ => {}
        }
        Ok(None)
    }

    /// The next record inside the current chunk: (opcode, body range).
    fn next_in_chunk(&mut self) -> Result<Option<(u8, std::ops::Range<usize>)>, McapError> {
        let records = self.chunk.get(..self.chunk_end).unwrap_or_default();
        let rest = records.len().saturating_sub(self.chunk_pos);
        if rest == 0 {
            return Ok(None);
        }
        let p = self.chunk_pos;
        let head = records
            .get(p..p + 9)
            .ok_or(McapError::CutRecordHeader { rest })?;
        let opcode = head[0];
        let mut len = [0u8; 8];
        len.copy_from_slice(&head[1..9]);
        let len = u64::from_le_bytes(len);
        let body = p + 9;
        let end = usize::try_from(len)
            .ok()
            .and_then(|l| body.checked_add(l))
            .filter(|&e| e <= records.len())
            .ok_or(McapError::RecordOverrun { opcode, len, rest })?;
        self.chunk_pos = end;
        Ok(Some((opcode, body..end)))
    }
}

/// Decompress a chunk's records into `out` (its allocation reused), refusing sizes over the
/// limit before allocating. On error `out` is left empty.
fn decompress_chunk(h: &ChunkHeader, data: &[u8], out: &mut Vec<u8>) -> Result<(), McapError> {
    out.clear();
    let size = usize::try_from(h.uncompressed_size)
        .ok()
        .filter(|&n| n <= MAX_RECORD_BYTES)
        .ok_or(McapError::ChunkTooLarge(h.uncompressed_size))?;
    let r = match h.compression.as_str() {
        "" => {
            out.extend_from_slice(data);
            Ok(())
        }
        "zstd" => {
            out.reserve(size);
            zstd::bulk::Decompressor::new()
                .and_then(|mut d| d.decompress_to_buffer(data, out))
                .map(|_| ())
                .map_err(|source| McapError::Decompress {
                    codec: "zstd",
                    source,
                })
        }
        "lz4" => lz4::Decoder::new(data)
            .and_then(|d| d.take(size as u64 + 1).read_to_end(out))
            .map(|_| ())
            .map_err(|source| McapError::Decompress {
                codec: "lz4",
                source,
            }),
        other => Err(McapError::Compression(other.to_string())),
    };
    if let Err(e) = r {
        out.clear();
        return Err(e);
    }
    if let Err(e) = check_stored(h, out) {
        out.clear();
        return Err(e);
    }
    Ok(())
}

/// A chunk's records against its header: the uncompressed size and (when it is not 0) the CRC.
fn check_stored(h: &ChunkHeader, records: &[u8]) -> Result<(), McapError> {
    let size = usize::try_from(h.uncompressed_size)
        .ok()
        .filter(|&n| n <= MAX_RECORD_BYTES)
        .ok_or(McapError::ChunkTooLarge(h.uncompressed_size))?;
    if records.len() != size {
        return Err(McapError::ChunkSize {
            got: records.len(),
            want: size,
        });
    }
    if h.uncompressed_crc != 0 {
        let crc = crc32fast::hash(records);
        if crc != h.uncompressed_crc {
            return Err(McapError::ChunkCrc {
                crc,
                want: h.uncompressed_crc,
            });
        }
    }
    Ok(())
}

impl McapFile {
    pub(super) fn open(path: &Path) -> Result<Self, BagError> {
        let file = std::fs::File::open(path).map_err(|e| BagError::Io {
            path: path.to_path_buf(),
            error: e,
        })?;
        Ok(Self::from_reader(path, Box::new(file)))
    }

    fn from_reader(path: &Path, file: Box<dyn Read + Send>) -> Self {
        Self {
            path: path.to_path_buf(),
            file: BufReader::with_capacity(READ_BUFFER, file),
            started: false,
            record: Vec::new(),
            state: McapState {
                schemas: BTreeMap::new(),
                channels: BTreeMap::new(),
                chunk: Vec::new(),
                chunk_pos: 0,
                chunk_end: 0,
                in_place: None,
                end: false,
                defined: 0,
            },
            done: false,
            truncated: false,
        }
    }

    fn err(&mut self, error: McapError) -> BagError {
        self.done = true;
        BagError::Mcap {
            path: self.path.clone(),
            error,
        }
    }

    /// The next top-level record: its opcode (the body in `self.record`), or `None` when the
    /// file ends first (flagged truncated).
    fn next_record(&mut self) -> Result<Option<u8>, BagError> {
        let mut head = [0u8; 9];
        if !self.started {
            let mut magic = [0u8; 8];
            if !self.read_into(&mut magic)? {
                return Ok(None);
            }
            if &magic != MAGIC {
                return Err(self.err(McapError::Stream(::mcap::McapError::BadMagic)));
            }
            self.started = true;
        }
        if !self.read_into(&mut head)? {
            return Ok(None);
        }
        let opcode = head[0];
        let mut len = [0u8; 8];
        len.copy_from_slice(&head[1..]);
        let len = u64::from_le_bytes(len);
        let Some(n) = usize::try_from(len).ok().filter(|&n| n <= MAX_RECORD_BYTES) else {
            return Err(
                self.err(McapError::Stream(::mcap::McapError::RecordTooLarge {
                    opcode,
                    len,
                })),
            );
        };
        // Into the buffer's spare capacity (reused across records: no allocation and no zero
        // fill per record).
        self.record.clear();
        self.record.reserve(n);
        let got = (&mut self.file)
            .take(len)
            .read_to_end(&mut self.record)
            .map_err(|error| {
                self.done = true;
                BagError::Io {
                    path: self.path.clone(),
                    error,
                }
            })?;
        if got < n {
            return Ok(None);
        }
        Ok(Some(opcode))
    }

    /// [`read_or_eof`] into a small buffer, with the file's path on an error.
    fn read_into(&mut self, buf: &mut [u8]) -> Result<bool, BagError> {
        read_or_eof(&mut self.file, buf).map_err(|error| {
            self.done = true;
            BagError::Io {
                path: self.path.clone(),
                error,
            }
        })
    }

    pub(super) fn next_with<R>(
        &mut self,
        opts: &ReadOptions,
        f: &mut Visit<'_, R>,
    ) -> Result<Option<R>, BagError> {
        while !self.done {
            // Records of the current chunk first.
            match self.state.next_in_chunk() {
                Ok(Some((opcode, range))) => {
                    let chunk = std::mem::take(&mut self.state.chunk);
                    let body = &chunk[range];
                    let r = self
                        .state
                        .handle(opcode, body, opts, true)
                        .map(|found| found.map(|m| f(&m.topic, m.log_time, &body[m.offset..])));
                    self.state.chunk = chunk;
                    match r {
                        Ok(Some(m)) => return Ok(Some(m)),
                        Ok(None) => continue,
                        Err(e) => return Err(self.err(e)),
                    }
                }
                Ok(None) => {}
                Err(e) => return Err(self.err(e)),
            }
            if self.state.end {
                self.done = true;
                break;
            }
            let Some(opcode) = self.next_record()? else {
                // The file stops inside a record or before the end of its data section.
                self.done = true;
                self.truncated = true;
                return Ok(None);
            };
            let data = self.record.as_slice();
            let r = self
                .state
                .handle(opcode, data, opts, false)
                .map(|found| found.map(|m| f(&m.topic, m.log_time, &data[m.offset..])));
            if let Some(records) = self.state.in_place.take() {
                // An uncompressed chunk: its body becomes the chunk, the old chunk's buffer
                // the next record's.
                std::mem::swap(&mut self.record, &mut self.state.chunk);
                self.state.chunk_pos = records.start;
                self.state.chunk_end = records.end;
            }
            match r {
                Ok(Some(m)) => return Ok(Some(m)),
                Ok(None) => {}
                Err(e) => return Err(self.err(e)),
            }
        }
        Ok(None)
    }

    fn next(&mut self, opts: &ReadOptions) -> Result<Option<RawMessage>, BagError> {
        self.next_with(opts, &mut |topic, log_time, data| RawMessage {
            topic: Arc::clone(topic),
            log_time,
            data: data.to_vec(),
        })
    }
}

/// Fill `buf` from `r`; `Ok(false)` when the stream ends first.
fn read_or_eof(r: &mut impl Read, buf: &mut [u8]) -> std::io::Result<bool> {
    match r.read_exact(buf) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Ok(false),
        Err(e) => Err(e),
    }
}

/// Every message of an MCAP stream in memory (fuzzing and tests): stops at the first error.
pub fn read_mcap_bytes(data: &[u8]) -> Result<(Vec<RawMessage>, bool), BagError> {
    let mut f = McapFile::from_reader(
        Path::new("<memory>"),
        Box::new(std::io::Cursor::new(data.to_vec())),
    );
    let mut out = Vec::new();
    while let Some(m) = f.next(&ReadOptions::default())? {
        out.push(m);
    }
    Ok((out, f.truncated))
}
