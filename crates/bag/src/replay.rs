//! A bag as a frame source, and the replay loop behind `unitac replay`.
//!
//! [`BagSource`] picks one image topic (sensor_msgs/Image or CompressedImage: the one asked for,
//! else the first image topic met), decodes each message to an RGB8 frame stamped with the
//! message's header stamp (its log time when the header stamp is zero) and implements
//! [`unitac_core::Source`] for the runtime. Topics of types this crate does not know are skipped
//! with one warning each; the reader still hands out their raw bytes to whoever asks.
//!
//! [`replay`] drives stages synchronously, one frame at a time, through `unitac_core::Chain` (the
//! chain driver every transport uses: each stage's clock is its input's stamp; each stage sees
//! its input and the outputs of the stages before it) and paces with `unitac_core::Pacer`. Nothing in it reads the wall clock except the optional
//! pacing, which only decides when a frame is processed, never what comes out: two replays of a
//! bag give the same events and, with an output bag, the same bytes.

use crate::BagError;
use crate::image::{compressed_to_frame, image_to_frame};
use crate::read::{BagReader, ReadOptions, TopicInfo};
use crate::ros::{CompressedImageView, Image, ImageView, PointCloud2, RosMessage, is_known_type};
use crate::write::{BagWriter, TopicId};
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use unitac_core::msg::{
    ArmCommand, ContactEpisode, ContactState, GripperCommand, GripperStatus, PolicyStatus,
    PropertyComparison, SlipState, TactileLatent, TactileProperties, VisualObservation,
};
use unitac_core::{Chain, Frame, Msg, Pacer, Source, SourceError, Stamp};

const IMAGE: &str = "sensor_msgs/msg/Image";
const COMPRESSED: &str = "sensor_msgs/msg/CompressedImage";
/// Topic of the frames `unitac run --out` records.
pub const FRAME_TOPIC: &str = "/unitac/image_raw";
/// Where an output bag's point clouds go (with each depth map on `/unitac/depth`).
pub const POINTS_TOPIC: &str = "/unitac/points";

#[derive(Debug, Clone, Default, PartialEq)]
pub struct ReplayOptions {
    /// Image topic to replay; default: the first Image or CompressedImage topic in the bag.
    pub topic: Option<String>,
    /// Skip the first seconds of the image topic.
    pub start_s: f64,
    /// Start over at the end, stamps shifted so time keeps going forward.
    pub looped: bool,
    /// Sensor id of the frames; default: the header frame_id without `_optical_frame`.
    pub sensor_id: Option<String>,
}

/// One image message of the bag, decoded or not.
#[derive(Debug)]
pub struct ImageItem {
    pub topic: Arc<TopicInfo>,
    /// Log time in the bag, shifted by the loop offset \[ns].
    pub log_time: i64,
    /// The CDR payload as recorded (empty unless [`BagSource::keep_raw`] was set).
    pub raw: Vec<u8>,
    pub frame: Result<Frame, FrameError>,
}

/// Why an image message gave no frame.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error("{0}")]
    Cdr(#[from] crate::CdrError),
    #[error("{0}")]
    Image(#[from] crate::ImageError),
    #[error("message of {len} bytes is over the limit {max}: skipped unread")]
    TooLarge { len: u64, max: usize },
}

/// Why the bag source lost a frame or ended: the cause of its [`SourceError`].
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    #[error("{topic} at {log_time} ns: {error}")]
    Frame {
        topic: String,
        log_time: i64,
        error: FrameError,
    },
    #[error(
        "{}: no image messages (sensor_msgs/Image or CompressedImage){}",
        path.display(),
        topic.as_deref().map(|t| format!(" on {t}")).unwrap_or_default()
    )]
    NoImages {
        path: PathBuf,
        topic: Option<String>,
    },
}

/// A bag replayed as a stream of frames.
#[derive(Debug)]
pub struct BagSource {
    path: PathBuf,
    name: String,
    reader: BagReader,
    st: SourceState,
}

/// Everything but the reader, so the reader's borrowed-payload callback can update it.
#[derive(Debug)]
struct SourceState {
    opts: ReplayOptions,
    path: PathBuf,
    keep_raw: bool,
    topic: Option<String>,
    warned: BTreeSet<String>,
    first_log: Option<i64>,
    seq: u64,
    /// Added to stamps and log times in the current pass.
    offset: i64,
    pass_first: Option<i64>,
    pass_last: i64,
    pass_images: u64,
    last_gap: i64,
    truncated: BTreeSet<PathBuf>,
}

impl BagSource {
    pub fn open(path: &Path, opts: ReplayOptions) -> Result<Self, BagError> {
        let reader = BagReader::open(path, Self::read_opts(&opts))?;
        Ok(Self {
            path: path.to_path_buf(),
            name: format!("bag:{}", path.display()),
            reader,
            st: SourceState {
                topic: opts.topic.clone(),
                opts,
                path: path.to_path_buf(),
                keep_raw: false,
                warned: BTreeSet::new(),
                first_log: None,
                seq: 0,
                offset: 0,
                pass_first: None,
                pass_last: 0,
                pass_images: 0,
                last_gap: 1_000_000,
                truncated: BTreeSet::new(),
            },
        })
    }

    fn read_opts(opts: &ReplayOptions) -> ReadOptions {
        ReadOptions {
            topics: opts.topic.iter().cloned().collect(),
            ..ReadOptions::default()
        }
    }

    /// Keep each image message's CDR bytes in [`ImageItem::raw`] (for an output bag).
    pub fn keep_raw(&mut self, keep: bool) {
        self.st.keep_raw = keep;
    }
    /// The image topic being replayed (known after the first image).
    pub fn topic(&self) -> Option<&str> {
        self.st.topic.as_deref()
    }
    /// Topics skipped because their type is unknown here.
    pub fn skipped_topics(&self) -> impl Iterator<Item = &String> {
        self.st.warned.iter()
    }
    /// Storage files that were cut short (read up to their last complete record).
    pub fn truncated_files(&self) -> impl Iterator<Item = &PathBuf> {
        self.st.truncated.iter()
    }

    /// The next image message, decoded; `Ok(None)` at the end (of the last pass with `looped`).
    pub fn next_image(&mut self) -> Result<Option<ImageItem>, BagError> {
        loop {
            let st = &mut self.st;
            let read = self
                .reader
                .next_with(&mut |topic, log_time, data| st.visit(topic, log_time, data));
            let next = match read {
                Ok(n) => n,
                // Not read at all (sqlite): one error item if it is ours, and reading goes on.
                Err(BagError::TooLarge {
                    topic,
                    log_time,
                    len,
                    max,
                    ..
                }) => Some(self.st.accept(&topic, log_time).then(|| {
                    self.st.seq += 1;
                    ImageItem {
                        log_time: log_time.saturating_add(self.st.offset),
                        topic,
                        raw: Vec::new(),
                        frame: Err(FrameError::TooLarge { len, max }),
                    }
                })),
                Err(e) => return Err(e),
            };
            match next {
                Some(Some(item)) => return Ok(Some(item)),
                Some(None) => continue,
                None => {}
            }
            for t in self.reader.truncated() {
                self.st.truncated.insert(t.clone());
            }
            let st = &mut self.st;
            if !st.opts.looped || st.pass_images == 0 {
                return Ok(None);
            }
            // Next pass: shift time so it starts one frame interval after this one ended.
            let first = st.pass_first.unwrap_or(0);
            st.offset = st
                .offset
                .saturating_add(st.pass_last - first)
                .saturating_add(st.last_gap.max(1));
            st.pass_first = None;
            st.pass_images = 0;
            self.reader = BagReader::open(&self.path, Self::read_opts(&st.opts))?;
        }
    }
}

impl SourceState {
    /// One message of the bag: an image item, or None if it is not for us.
    fn visit(&mut self, topic: &Arc<TopicInfo>, log_time: i64, data: &[u8]) -> Option<ImageItem> {
        if !self.accept(topic, log_time) {
            return None;
        }
        // Sequence numbers count the topic's image messages from 0 (gaps: undecodable ones).
        let frame = self.decode(&topic.type_name, data, log_time);
        self.seq += 1;
        Some(ImageItem {
            topic: Arc::clone(topic),
            log_time: log_time.saturating_add(self.offset),
            raw: if self.keep_raw {
                data.to_vec()
            } else {
                Vec::new()
            },
            frame,
        })
    }

    /// Whether a message is an image of the replayed topic (after `start_s`); counts it in the
    /// pass if so.
    fn accept(&mut self, topic: &Arc<TopicInfo>, log_time: i64) -> bool {
        let ty = topic.type_name.as_str();
        if !is_known_type(ty) {
            if self.warned.insert(topic.name.clone()) {
                tracing::warn!(
                    "{}: topic {} has type '{}', unknown here: skipped",
                    self.path.display(),
                    topic.name,
                    ty
                );
            }
            return false;
        }
        if ty != IMAGE && ty != COMPRESSED {
            return false;
        }
        match &self.topic {
            None => self.topic = Some(topic.name.clone()),
            Some(t) if *t != topic.name => return false,
            Some(_) => {}
        }
        let first = *self.first_log.get_or_insert(log_time);
        if self.opts.start_s > 0.0
            && (log_time.saturating_sub(first) as f64) < self.opts.start_s * 1e9
        {
            return false;
        }
        self.pass_first.get_or_insert(log_time);
        if self.pass_images > 0 {
            let gap = log_time - self.pass_last;
            if gap > 0 {
                self.last_gap = gap;
            }
        }
        self.pass_last = log_time;
        self.pass_images += 1;
        true
    }

    fn sensor_id(&self, frame_id: &str) -> String {
        if let Some(s) = &self.opts.sensor_id {
            return s.clone();
        }
        let id = frame_id.strip_suffix("_optical_frame").unwrap_or(frame_id);
        if id.is_empty() {
            "bag".to_string()
        } else {
            id.to_string()
        }
    }

    fn decode(&self, ty: &str, data: &[u8], log_time: i64) -> Result<Frame, FrameError> {
        let mut f = if ty == IMAGE {
            let img = ImageView::from_cdr(data)?;
            image_to_frame(&img, &self.sensor_id(&img.header.frame_id), self.seq)?
        } else {
            let img = CompressedImageView::from_cdr(data)?;
            compressed_to_frame(&img, &self.sensor_id(&img.header.frame_id), self.seq)?
        };
        if f.stamp == Stamp::ZERO {
            f.stamp = Stamp(log_time);
        }
        f.stamp = f.stamp.saturating_add_nanos(self.offset);
        Ok(f)
    }
}

impl Source for BagSource {
    fn name(&self) -> &str {
        &self.name
    }
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError> {
        match self.next_image() {
            Ok(Some(item)) => item.frame.map(Some).map_err(|error| {
                SourceError::frame(ReplayError::Frame {
                    topic: item.topic.name.clone(),
                    log_time: item.log_time,
                    error,
                })
            }),
            // A bag that replays nothing is not a replay that ended well.
            Ok(None) if self.st.seq == 0 => Err(SourceError::fatal(ReplayError::NoImages {
                path: self.path.clone(),
                topic: self.st.opts.topic.clone(),
            })),
            Ok(None) => Ok(None),
            Err(e) => Err(SourceError::fatal(e)),
        }
    }
    fn is_replay(&self) -> bool {
        true
    }
}

// ---------------------------------------------------------------------------------------------
// The replay loop

/// What one image message gave.
#[derive(Debug)]
pub struct ImageResult {
    /// Frame stamp (log time when the frame could not be decoded) \[ns].
    pub stamp: i64,
    pub topic: Arc<TopicInfo>,
    /// Events the stages produced for this frame, in order.
    pub events: Vec<Msg>,
    /// Decode or stage error, if any.
    pub error: Option<String>,
}

#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct ReplayReport {
    pub images: u64,
    pub errors: u64,
    /// Events by kind, including those from the stages' `finish`.
    pub events: BTreeMap<String, u64>,
    pub topic: Option<String>,
    pub skipped_topics: Vec<String>,
    pub truncated_files: Vec<PathBuf>,
    pub stopped: bool,
}

/// Output topics of the events written to an output bag.
pub fn output_topic(m: &Msg) -> Option<(&'static str, &'static str)> {
    Some(match m {
        Msg::ContactState(_) => ("/unitac/contact_state", ContactState::TYPE),
        Msg::ContactEpisode(_) => ("/unitac/contact_episode", ContactEpisode::TYPE),
        Msg::TactileProperties(_) => ("/unitac/tactile_properties", TactileProperties::TYPE),
        Msg::PropertyComparison(_) => ("/unitac/property_comparison", PropertyComparison::TYPE),
        Msg::TactileLatent(_) => ("/unitac/tactile_latent", TactileLatent::TYPE),
        Msg::GripperCommand(_) => ("/unitac/gripper_command", GripperCommand::TYPE),
        Msg::PolicyStatus(_) => ("/unitac/policy_status", PolicyStatus::TYPE),
        Msg::GripperStatus(_) => ("/unitac/gripper_status", GripperStatus::TYPE),
        Msg::ArmCommand(_) => ("/unitac/arm_command", ArmCommand::TYPE),
        Msg::VisualObservation(_) => ("/unitac/visual_observation", VisualObservation::TYPE),
        Msg::SlipState(_) => ("/unitac/slip_state", SlipState::TYPE),
        // Also `/unitac/points` (PointCloud2), written with it.
        Msg::Depth(_) => ("/unitac/depth", IMAGE),
        Msg::ContactOverlay(_) => ("/unitac/contact_overlay", IMAGE),
        Msg::Frame(_) | Msg::ContactClip(_) | Msg::Background(_) => return None,
    })
}

/// Writes inputs and events to an output bag; topics are added in order of first use.
#[derive(Debug)]
pub struct OutputBag {
    writer: BagWriter,
    topics: BTreeMap<String, TopicId>,
}

impl OutputBag {
    pub fn new(writer: BagWriter) -> Self {
        Self {
            writer,
            topics: BTreeMap::new(),
        }
    }
    fn topic(&mut self, name: &str, ty: &str) -> Result<TopicId, BagError> {
        if let Some(&id) = self.topics.get(name) {
            return Ok(id);
        }
        let id = self.writer.add_topic(name, ty)?;
        self.topics.insert(name.to_string(), id);
        Ok(id)
    }
    /// Copy an input message as recorded.
    pub fn write_input(
        &mut self,
        topic: &TopicInfo,
        log_time: i64,
        raw: &[u8],
    ) -> Result<(), BagError> {
        let id = self.topic(&topic.name, &topic.type_name)?;
        self.writer.write_raw(id, log_time, raw)
    }
    /// Write a frame as a sensor_msgs/Image (rgb8) on `/unitac/image_raw`, stamped with its
    /// capture time (log time = capture time): what `unitac run --out` records.
    pub fn write_frame(&mut self, f: &Frame) -> Result<(), BagError> {
        let id = self.topic(FRAME_TOPIC, IMAGE)?;
        self.writer
            .write_raw(id, f.stamp.0, &Image::rgb8(f).to_cdr())
    }

    /// Write an event (frames and clips are not ROS messages and are skipped).
    pub fn write_event(&mut self, m: &Msg) -> Result<(), BagError> {
        let Some((name, ty)) = output_topic(m) else {
            return Ok(());
        };
        let id = self.topic(name, ty)?;
        let t = m.stamp().0;
        let data = match m {
            Msg::ContactState(x) => x.to_cdr(),
            Msg::ContactEpisode(x) => x.to_cdr(),
            Msg::TactileProperties(x) => x.to_cdr(),
            Msg::PropertyComparison(x) => x.to_cdr(),
            Msg::TactileLatent(x) => x.to_cdr(),
            Msg::GripperCommand(x) => x.to_cdr(),
            Msg::PolicyStatus(x) => x.to_cdr(),
            Msg::GripperStatus(x) => x.to_cdr(),
            Msg::ArmCommand(x) => x.to_cdr(),
            Msg::VisualObservation(x) => x.to_cdr(),
            Msg::SlipState(x) => x.to_cdr(),
            Msg::Depth(d) => {
                self.writer
                    .write_raw(id, t, &Image::depth32fc1(d).to_cdr())?;
                let points = self.topic(POINTS_TOPIC, PointCloud2::TYPE)?;
                self.writer
                    .write_raw(points, t, &PointCloud2::xyz(d).to_cdr())?;
                return Ok(());
            }
            Msg::ContactOverlay(f) => Image::rgb8(f).to_cdr(),
            Msg::Frame(_) | Msg::ContactClip(_) | Msg::Background(_) => return Ok(()),
        };
        self.writer.write_raw(id, t, &data)
    }
    pub fn finish(self) -> Result<PathBuf, BagError> {
        self.writer.finish()
    }
}

/// Replay `source` through `chain` (the one chain driver; each stage's clock is its input's
/// stamp), paced by `pacer`. `on_image` sees every image message with what it produced;
/// `on_finish` sees the events the stages emit when the input ends (e.g. an open episode).
/// With `out`, the replayed image messages and every event go into that bag.
#[allow(clippy::too_many_arguments)]
pub fn replay(
    source: &mut BagSource,
    chain: &mut Chain,
    mut out: Option<&mut OutputBag>,
    pacer: &mut Pacer,
    stop: &AtomicBool,
    mut on_image: impl FnMut(&ImageResult),
    mut on_finish: impl FnMut(&Msg),
) -> Result<ReplayReport, BagError> {
    let mut report = ReplayReport::default();
    source.keep_raw(out.is_some());
    while let Some(item) = source.next_image()? {
        if stop.load(Ordering::SeqCst) {
            report.stopped = true;
            break;
        }
        pacer.wait(Stamp(item.log_time), |d| {
            std::thread::sleep(d);
            !stop.load(Ordering::SeqCst)
        });
        report.images += 1;
        if let Some(o) = out.as_deref_mut() {
            // A message skipped unread has no bytes to copy.
            if !matches!(item.frame, Err(FrameError::TooLarge { .. })) {
                o.write_input(&item.topic, item.log_time, &item.raw)?;
            }
        }
        let result = match item.frame {
            Ok(frame) => {
                let stamp = frame.stamp.0;
                let r = chain.run(Msg::Frame(frame));
                ImageResult {
                    stamp,
                    topic: Arc::clone(&item.topic),
                    events: r.produced.into_iter().filter(|m| !m.is_frame()).collect(),
                    error: r
                        .errors
                        .first()
                        .map(|e| format!("{}: {}", e.stage, e.error)),
                }
            }
            Err(e) => ImageResult {
                stamp: item.log_time,
                topic: Arc::clone(&item.topic),
                events: Vec::new(),
                error: Some(e.to_string()),
            },
        };
        if result.error.is_some() {
            report.errors += 1;
        }
        for m in &result.events {
            *report.events.entry(m.kind().to_string()).or_default() += 1;
            if let Some(o) = out.as_deref_mut() {
                o.write_event(m)?;
            }
        }
        on_image(&result);
    }
    // Finish each stage in order; later stages see what earlier ones flushed.
    let end = chain.finish();
    for e in &end.errors {
        tracing::warn!("{e}");
        report.errors += 1;
    }
    for m in end.produced.iter().filter(|m| !m.is_frame()) {
        *report.events.entry(m.kind().to_string()).or_default() += 1;
        if let Some(o) = out.as_deref_mut() {
            o.write_event(m)?;
        }
        on_finish(m);
    }
    report.topic = source.topic().map(str::to_string);
    report.skipped_topics = source.skipped_topics().cloned().collect();
    report.truncated_files = source.truncated_files().cloned().collect();
    Ok(report)
}
