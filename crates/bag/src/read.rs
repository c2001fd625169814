//! Reading rosbag2 bags: a directory (metadata.yaml + .mcap or .db3 files), a bare .mcap or a
//! bare .db3, as one stream of raw messages in file order.
//!
//! MCAP is read with the `mcap` crate's sans-io linear reader, which streams records from the
//! file; each chunk record (at most [`MAX_RECORD_BYTES`]) is decompressed here (zstd, lz4 or
//! none) after checking its claimed size against the same limit, and the records inside are
//! walked with bounds checks, so memory stays bounded whatever the file says. (The reader's own
//! in-chunk walk underflows on a record longer than its chunk: the fuzz smoke found it.) The summary section
//! is never needed: a file a recorder could not finish (killed, disk full) is read up to its last
//! complete record and flagged [`BagReader::truncated`]. sqlite3 (Humble's default) is read with
//! rusqlite from the `topics` and `messages` tables, in pages ordered by (timestamp, id).
//!
//! Messages of every topic come out with their raw CDR bytes, whatever their type; decoding is the
//! caller's choice (see [`crate::ros::is_known_type`]).

use crate::BagError;
use crate::cdr::MAX_IMAGE_BYTES;
use crate::metadata;
use mcap::sans_io::linear_reader::{LinearReadEvent, LinearReader, LinearReaderOptions};
use std::collections::{BTreeMap, VecDeque};
use std::io::Read;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// Longest MCAP record (and decompressed chunk) accepted: the largest image plus headroom.
pub const MAX_RECORD_BYTES: usize = MAX_IMAGE_BYTES + (1 << 20);
/// Largest single read from a file.
const READ_BLOCK: usize = 1 << 20;
/// sqlite rows fetched per query.
const SQLITE_PAGE: i64 = 64;

/// A callback that sees one message with its payload borrowed: (topic, log time \[ns], CDR).
pub type Visit<'f, R> = dyn FnMut(&Arc<TopicInfo>, i64, &[u8]) -> R + 'f;

/// A topic as the bag declares it.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TopicInfo {
    pub name: String,
    /// e.g. `sensor_msgs/msg/Image` (empty if the file gives none).
    pub type_name: String,
    /// Serialization format / message encoding, `cdr` for ROS 2.
    pub encoding: String,
}

/// One message, undecoded.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct RawMessage {
    pub topic: Arc<TopicInfo>,
    /// Receive time in the bag [ns since the epoch].
    pub log_time: i64,
    /// Serialized payload (CDR with its 4-byte encapsulation header).
    pub data: Vec<u8>,
}

/// Which messages to return.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReadOptions {
    /// Only these topics (all when empty).
    pub topics: Vec<String>,
    /// Only messages with `log_time >= start_ns`.
    pub start_ns: Option<i64>,
    /// Only messages with `log_time < end_ns`.
    pub end_ns: Option<i64>,
}

impl ReadOptions {
    fn wants(&self, topic: &str, t: i64) -> bool {
        (self.topics.is_empty() || self.topics.iter().any(|x| x == topic))
            && self.start_ns.is_none_or(|s| t >= s)
            && self.end_ns.is_none_or(|e| t < e)
    }
}

/// A bag opened for reading: an iterator over its messages.
#[derive(Debug)]
pub struct BagReader {
    path: PathBuf,
    files: VecDeque<PathBuf>,
    current: Option<Storage>,
    opts: ReadOptions,
    declared: Vec<TopicInfo>,
    truncated: Vec<PathBuf>,
    failed: bool,
}

#[derive(Debug)]
enum Storage {
    Mcap(Box<McapFile>),
    Sqlite(Box<SqliteFile>),
}

impl BagReader {
    /// Open a bag directory, a bare `.mcap` or a bare `.db3`.
    pub fn open(path: &Path, opts: ReadOptions) -> Result<Self, BagError> {
        let io = |e| BagError::Io {
            path: path.to_path_buf(),
            source: e,
        };
        let meta = std::fs::metadata(path).map_err(io)?;
        let mut declared = Vec::new();
        let files: Vec<PathBuf> = if meta.is_file() {
            if storage_kind(path).is_none() {
                return Err(BagError::NotABag(path.to_path_buf()));
            }
            vec![path.to_path_buf()]
        } else {
            let mpath = path.join("metadata.yaml");
            if mpath.is_file() {
                let text = read_bounded(&mpath, metadata::MAX_METADATA_BYTES)?;
                let info = metadata::parse(&text).map_err(|msg| BagError::Metadata {
                    path: mpath.clone(),
                    msg,
                })?;
                if !info.compression_mode.is_empty() || !info.compression_format.is_empty() {
                    return Err(BagError::Unsupported {
                        path: path.to_path_buf(),
                        msg: format!(
                            "rosbag2 {} compression '{}' (decompress with `ros2 bag convert`; \
                             MCAP chunk compression is supported)",
                            info.compression_mode, info.compression_format
                        ),
                    });
                }
                declared = info
                    .topics_with_message_count
                    .iter()
                    .map(|t| TopicInfo {
                        name: t.topic_metadata.name.clone(),
                        type_name: t.topic_metadata.type_name.clone(),
                        encoding: t.topic_metadata.serialization_format.clone(),
                    })
                    .collect();
                let listed: Vec<PathBuf> = info
                    .relative_file_paths
                    .iter()
                    .map(|p| path.join(p))
                    .collect();
                // A recording that died before writing its final metadata lists no files.
                if listed.is_empty() {
                    storage_files_in(path)?
                } else {
                    listed
                }
            } else {
                storage_files_in(path)?
            }
        };
        if files.is_empty() {
            return Err(BagError::NotABag(path.to_path_buf()));
        }
        for f in &files {
            if storage_kind(f).is_none() {
                return Err(BagError::Unsupported {
                    path: f.clone(),
                    msg: "storage file is neither .mcap nor .db3".into(),
                });
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            files: files.into(),
            current: None,
            opts,
            declared,
            truncated: Vec::new(),
            failed: false,
        })
    }

    pub fn path(&self) -> &Path {
        &self.path
    }
    /// Topics listed in metadata.yaml (empty for a bare file).
    pub fn declared_topics(&self) -> &[TopicInfo] {
        &self.declared
    }
    /// Storage files that ended before their end (no footer, cut record): read up to there.
    pub fn truncated(&self) -> &[PathBuf] {
        &self.truncated
    }

    /// The next message, its payload borrowed for the call of `f` (no copy for MCAP chunks).
    /// `Ok(None)` at the end.
    pub fn next_with<R>(&mut self, f: &mut Visit<'_, R>) -> Result<Option<R>, BagError> {
        if self.failed {
            return Ok(None);
        }
        let r = self.next_with_inner(f);
        if let Err(e) = &r {
            if !matches!(e, BagError::TooLarge { .. }) {
                self.failed = true;
            }
        }
        r
    }

    fn next_with_inner<R>(&mut self, f: &mut Visit<'_, R>) -> Result<Option<R>, BagError> {
        loop {
            if self.current.is_none() {
                let Some(p) = self.files.pop_front() else {
                    return Ok(None);
                };
                self.current = Some(match storage_kind(&p) {
                    Some(Kind::Sqlite) => Storage::Sqlite(Box::new(SqliteFile::open(&p)?)),
                    _ => Storage::Mcap(Box::new(McapFile::open(&p)?)),
                });
            }
            let next = match &mut self.current {
                Some(Storage::Mcap(m)) => {
                    let r = m.next_with(&self.opts, f);
                    if m.truncated && !self.truncated.contains(&m.path) {
                        tracing::warn!(
                            "{}: file ends before its end record; read up to the last complete record",
                            m.path.display()
                        );
                        self.truncated.push(m.path.clone());
                    }
                    r
                }
                Some(Storage::Sqlite(s)) => s
                    .next(&self.opts)
                    .map(|o| o.map(|m| f(&m.topic, m.log_time, &m.data))),
                None => Ok(None),
            }?;
            match next {
                Some(m) => return Ok(Some(m)),
                None => self.current = None,
            }
        }
    }
}

impl Iterator for BagReader {
    type Item = Result<RawMessage, BagError>;
    /// After an error that leaves the file unreadable (corrupt MCAP record, sqlite failure) the
    /// iterator ends; a message over the size limit is one error and reading goes on.
    fn next(&mut self) -> Option<Self::Item> {
        self.next_with(&mut |topic, log_time, data| RawMessage {
            topic: Arc::clone(topic),
            log_time,
            data: data.to_vec(),
        })
        .transpose()
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Mcap,
    Sqlite,
}

fn storage_kind(p: &Path) -> Option<Kind> {
    match p.extension()?.to_str()? {
        "mcap" => Some(Kind::Mcap),
        "db3" => Some(Kind::Sqlite),
        _ => None,
    }
}

fn storage_files_in(dir: &Path) -> Result<Vec<PathBuf>, BagError> {
    let io = |e| BagError::Io {
        path: dir.to_path_buf(),
        source: e,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(io)?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file() && storage_kind(p).is_some())
        .collect();
    // rosbag2 names split files <bag>_0, <bag>_1, ...: order by that index, then by name.
    files.sort_by_key(|p| {
        let stem = p
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default()
            .to_string();
        let idx = stem
            .rsplit_once('_')
            .and_then(|(_, n)| n.parse::<u64>().ok())
            .unwrap_or(0);
        (idx, stem)
    });
    Ok(files)
}

fn read_bounded(p: &Path, max: usize) -> Result<String, BagError> {
    let io = |e| BagError::Io {
        path: p.to_path_buf(),
        source: e,
    };
    let f = std::fs::File::open(p).map_err(io)?;
    let mut s = String::new();
    f.take(max as u64 + 1).read_to_string(&mut s).map_err(io)?;
    Ok(s)
}

// ---------------------------------------------------------------------------------------------
// MCAP

struct McapFile {
    path: PathBuf,
    file: Box<dyn Read + Send>,
    reader: LinearReader,
    state: McapState,
    eof: bool,
    done: bool,
    truncated: bool,
}

/// What the records so far defined, and the chunk being read.
struct McapState {
    schemas: BTreeMap<u16, String>,
    channels: BTreeMap<u16, Arc<TopicInfo>>,
    /// Decompressed records of the current chunk, and where the next one starts.
    chunk: Vec<u8>,
    chunk_pos: usize,
    end: bool,
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
    fn take(&mut self, n: u64) -> Result<&'a [u8], String> {
        let end = usize::try_from(n)
            .ok()
            .and_then(|n| self.pos.checked_add(n))
            .filter(|&e| e <= self.data.len())
            .ok_or_else(|| {
                format!(
                    "record 0x{:02x}: field of {n} bytes at {} overruns the record ({} bytes)",
                    self.opcode,
                    self.pos,
                    self.data.len()
                )
            })?;
        let s = &self.data[self.pos..end];
        self.pos = end;
        Ok(s)
    }
    fn array<const N: usize>(&mut self) -> Result<[u8; N], String> {
        let mut a = [0u8; N];
        a.copy_from_slice(self.take(N as u64)?);
        Ok(a)
    }
    fn u16(&mut self) -> Result<u16, String> {
        self.array::<2>().map(u16::from_le_bytes)
    }
    fn u32(&mut self) -> Result<u32, String> {
        self.array::<4>().map(u32::from_le_bytes)
    }
    fn u64(&mut self) -> Result<u64, String> {
        self.array::<8>().map(u64::from_le_bytes)
    }
    fn string(&mut self) -> Result<String, String> {
        let n = self.u32()?;
        if n as usize > MAX_NAME {
            return Err(format!(
                "record 0x{:02x}: string of {n} bytes, over the limit {MAX_NAME}",
                self.opcode
            ));
        }
        let b = self.take(u64::from(n))?;
        String::from_utf8(b.to_vec())
            .map_err(|_| format!("record 0x{:02x}: string is not UTF-8", self.opcode))
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
    /// Handle one record from the file or from a chunk. Errors are one line, for the user.
    fn handle(
        &mut self,
        opcode: u8,
        data: &[u8],
        opts: &ReadOptions,
        in_chunk: bool,
    ) -> Result<Option<Found>, String> {
        if opcode == OP_CHUNK && in_chunk {
            return Err("chunk inside a chunk".into());
        }
        if opcode == OP_MESSAGE {
            // Parsed here, not by parse_record: the payload stays where it is (no copy).
            let head = data
                .get(..MESSAGE_HEADER)
                .ok_or_else(|| format!("message record of {} bytes", data.len()))?;
            let channel = u16::from_le_bytes([head[0], head[1]]);
            let mut t = [0u8; 8];
            t.copy_from_slice(&head[6..14]);
            let t = i64::try_from(u64::from_le_bytes(t)).unwrap_or(i64::MAX);
            let topic = self.channels.get(&channel).ok_or_else(|| {
                format!("message on channel {channel} that was not defined before it")
            })?;
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
                self.schemas.insert(id, name);
            }
            OP_CHANNEL => {
                let id = r.u16()?;
                let schema_id = r.u16()?;
                let topic = r.string()?;
                let encoding = r.string()?;
                let type_name = if schema_id == 0 {
                    String::new()
                } else {
                    self.schemas.get(&schema_id).cloned().ok_or_else(|| {
                        format!(
                            "channel {id} ({topic}) uses schema {schema_id} that was not defined before it"
                        )
                    })?
                };
                self.channels.insert(
                    id,
                    Arc::new(TopicInfo {
                        name: topic,
                        type_name,
                        encoding,
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
                let body = r.take(len)?;
                // Into the previous chunk's buffer: no allocation (and no fresh pages to fault
                // in) per chunk.
                self.chunk_pos = 0;
                decompress_chunk(&header, body, &mut self.chunk)?;
            }
            // The summary repeats what the data section said.
            OP_DATA_END | OP_FOOTER => self.end = true,
            _ => {}
        }
        Ok(None)
    }

    /// The next record inside the current chunk: (opcode, body range).
    fn next_in_chunk(&mut self) -> Result<Option<(u8, std::ops::Range<usize>)>, String> {
        let rest = self.chunk.len().saturating_sub(self.chunk_pos);
        if rest == 0 {
            return Ok(None);
        }
        let p = self.chunk_pos;
        let head = self
            .chunk
            .get(p..p + 9)
            .ok_or_else(|| format!("chunk ends inside a record header ({rest} bytes left)"))?;
        let opcode = head[0];
        let mut len = [0u8; 8];
        len.copy_from_slice(&head[1..9]);
        let len = u64::from_le_bytes(len);
        let body = p + 9;
        let end = usize::try_from(len)
            .ok()
            .and_then(|l| body.checked_add(l))
            .filter(|&e| e <= self.chunk.len())
            .ok_or_else(|| {
                format!(
                    "record 0x{opcode:02x} of {len} bytes overruns its chunk ({rest} bytes left)"
                )
            })?;
        self.chunk_pos = end;
        Ok(Some((opcode, body..end)))
    }
}

/// Decompress a chunk's records into `out` (its allocation reused), refusing sizes over the
/// limit before allocating. On error `out` is left empty.
fn decompress_chunk(h: &ChunkHeader, data: &[u8], out: &mut Vec<u8>) -> Result<(), String> {
    out.clear();
    let size = usize::try_from(h.uncompressed_size)
        .ok()
        .filter(|&n| n <= MAX_RECORD_BYTES)
        .ok_or_else(|| {
            format!(
                "chunk claims {} uncompressed bytes, over the limit {MAX_RECORD_BYTES}",
                h.uncompressed_size
            )
        })?;
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
                .map_err(|e| format!("zstd chunk: {e}"))
        }
        "lz4" => lz4::Decoder::new(data)
            .and_then(|d| d.take(size as u64 + 1).read_to_end(out))
            .map(|_| ())
            .map_err(|e| format!("lz4 chunk: {e}")),
        other => Err(format!("chunk compression '{other}' is not supported")),
    };
    let check = r.and_then(|()| {
        if out.len() != size {
            return Err(format!(
                "chunk holds {} bytes after decompression, its header says {size}",
                out.len()
            ));
        }
        if h.uncompressed_crc != 0 {
            let crc = crc32fast::hash(out);
            if crc != h.uncompressed_crc {
                return Err(format!(
                    "chunk CRC {crc:08x} does not match its header ({:08x})",
                    h.uncompressed_crc
                ));
            }
        }
        Ok(())
    });
    if check.is_err() {
        out.clear();
    }
    check
}

impl McapFile {
    fn open(path: &Path) -> Result<Self, BagError> {
        let file = std::fs::File::open(path).map_err(|e| BagError::Io {
            path: path.to_path_buf(),
            source: e,
        })?;
        Ok(Self::from_reader(path, Box::new(file)))
    }

    fn from_reader(path: &Path, file: Box<dyn Read + Send>) -> Self {
        // Whole chunk records come to us (bounded by the record limit); we decompress them.
        let opts = LinearReaderOptions::default()
            .with_record_length_limit(MAX_RECORD_BYTES)
            .with_emit_chunks(true);
        Self {
            path: path.to_path_buf(),
            file,
            reader: LinearReader::new_with_options(opts),
            state: McapState {
                schemas: BTreeMap::new(),
                channels: BTreeMap::new(),
                chunk: Vec::new(),
                chunk_pos: 0,
                end: false,
            },
            eof: false,
            done: false,
            truncated: false,
        }
    }

    fn err(&mut self, msg: String) -> BagError {
        self.done = true;
        BagError::Mcap {
            path: self.path.clone(),
            msg,
        }
    }

    fn next_with<R>(
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
            let event = match self.reader.next_event() {
                None => {
                    self.done = true;
                    return Ok(None);
                }
                Some(Err(e)) => {
                    if self.eof {
                        // The file stops inside a record or before its footer.
                        self.done = true;
                        self.truncated = true;
                        return Ok(None);
                    }
                    return Err(self.err(e.to_string()));
                }
                Some(Ok(ev)) => ev,
            };
            match event {
                LinearReadEvent::ReadRequest(n) => {
                    let buf = self.reader.insert(n.clamp(1, READ_BLOCK));
                    let got = loop {
                        match self.file.read(buf) {
                            Ok(k) => break k,
                            Err(e) if e.kind() == std::io::ErrorKind::Interrupted => {}
                            Err(e) => {
                                let path = self.path.clone();
                                self.done = true;
                                return Err(BagError::Io { path, source: e });
                            }
                        }
                    };
                    if got == 0 {
                        self.eof = true;
                    }
                    self.reader.notify_read(got);
                }
                LinearReadEvent::Record { opcode, data } => {
                    let r = self
                        .state
                        .handle(opcode, data, opts, false)
                        .map(|found| found.map(|m| f(&m.topic, m.log_time, &data[m.offset..])));
                    match r {
                        Ok(Some(m)) => return Ok(Some(m)),
                        Ok(None) => {}
                        Err(e) => return Err(self.err(e)),
                    }
                }
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

// ---------------------------------------------------------------------------------------------
// sqlite3

struct SqliteFile {
    path: PathBuf,
    conn: rusqlite::Connection,
    topics: BTreeMap<i64, Arc<TopicInfo>>,
    page: VecDeque<RawMessage>,
    /// (timestamp, id) of the last row fetched.
    cursor: Option<(i64, i64)>,
    /// An oversized row met while filling the page: reported after the rows before it.
    pending: Option<BagError>,
    done: bool,
}

impl std::fmt::Debug for SqliteFile {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SqliteFile")
            .field("path", &self.path)
            .field("topics", &self.topics)
            .finish_non_exhaustive()
    }
}

impl SqliteFile {
    fn open(path: &Path) -> Result<Self, BagError> {
        let err = |e: rusqlite::Error| BagError::Sqlite {
            path: path.to_path_buf(),
            msg: e.to_string(),
        };
        let conn = rusqlite::Connection::open_with_flags(
            path,
            rusqlite::OpenFlags::SQLITE_OPEN_READ_ONLY | rusqlite::OpenFlags::SQLITE_OPEN_NO_MUTEX,
        )
        .map_err(err)?;
        let mut topics = BTreeMap::new();
        {
            let mut st = conn
                .prepare("SELECT id, name, type, serialization_format FROM topics ORDER BY id")
                .map_err(err)?;
            let rows = st
                .query_map([], |r| {
                    Ok((
                        r.get::<_, i64>(0)?,
                        TopicInfo {
                            name: r.get(1)?,
                            type_name: r.get(2)?,
                            encoding: r.get(3)?,
                        },
                    ))
                })
                .map_err(err)?;
            for row in rows {
                let (id, t) = row.map_err(err)?;
                if topics.len() >= metadata::MAX_TOPICS {
                    return Err(BagError::Sqlite {
                        path: path.to_path_buf(),
                        msg: format!("more than {} topics", metadata::MAX_TOPICS),
                    });
                }
                topics.insert(id, Arc::new(t));
            }
        }
        Ok(Self {
            path: path.to_path_buf(),
            conn,
            topics,
            page: VecDeque::new(),
            cursor: None,
            pending: None,
            done: false,
        })
    }

    fn fill(&mut self, opts: &ReadOptions) -> Result<(), BagError> {
        let path = self.path.clone();
        let err = |e: rusqlite::Error| BagError::Sqlite {
            path: path.clone(),
            msg: e.to_string(),
        };
        let (t0, id0) = self.cursor.unwrap_or((i64::MIN, i64::MIN));
        let mut st = self
            .conn
            .prepare_cached(
                "SELECT id, topic_id, timestamp, data FROM messages \
                 WHERE timestamp > ?1 OR (timestamp = ?1 AND id > ?2) \
                 ORDER BY timestamp, id LIMIT ?3",
            )
            .map_err(err)?;
        let mut rows = st
            .query(rusqlite::params![t0, id0, SQLITE_PAGE])
            .map_err(err)?;
        let mut n = 0;
        let mut too_large = None;
        while let Some(r) = rows.next().map_err(err)? {
            n += 1;
            let id: i64 = r.get(0).map_err(err)?;
            let topic_id: i64 = r.get(1).map_err(err)?;
            let t: i64 = r.get(2).map_err(err)?;
            self.cursor = Some((t, id));
            let Some(topic) = self.topics.get(&topic_id) else {
                return Err(BagError::Sqlite {
                    path: path.clone(),
                    msg: format!("message {id} names topic id {topic_id}, which is not in topics"),
                });
            };
            if !opts.wants(&topic.name, t) {
                continue;
            }
            let blob = r.get_ref(3).map_err(err)?;
            let data = blob.as_blob().map_err(|e| BagError::Sqlite {
                path: path.clone(),
                msg: format!("message {id}: {e}"),
            })?;
            if data.len() > MAX_RECORD_BYTES {
                too_large = Some(BagError::TooLarge {
                    path: path.clone(),
                    topic: topic.name.clone(),
                    len: data.len(),
                    max: MAX_RECORD_BYTES,
                });
                break;
            }
            self.page.push_back(RawMessage {
                topic: Arc::clone(topic),
                log_time: t,
                data: data.to_vec(),
            });
        }
        if n == 0 {
            self.done = true;
        }
        self.pending = too_large;
        Ok(())
    }

    fn next(&mut self, opts: &ReadOptions) -> Result<Option<RawMessage>, BagError> {
        loop {
            if let Some(m) = self.page.pop_front() {
                return Ok(Some(m));
            }
            if let Some(e) = self.pending.take() {
                return Err(e);
            }
            if self.done {
                return Ok(None);
            }
            self.fill(opts)?;
        }
    }
}
