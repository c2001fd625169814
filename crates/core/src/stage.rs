//! The stage and source interfaces: logic with an injected clock and no transport.
//!
//! A stage is a plain struct. The embedded runtime (crates/runtime) and the ROS nodes
//! (crates/ros) are two thin drivers that feed it messages; neither adds logic. Same inputs and
//! same clock readings give the same outputs.

use crate::clock::{Clock, Stamp};
use crate::frame::{Frame, FrameError};
use crate::msg::Msg;
use thiserror::Error;

/// What a stage or source error wraps: the typed error of the crate that found the fault, kept
/// whole (a caller matches the variant, then `downcast_ref`s to that crate's type; `source()`
/// walks its chain). A plain message converts too (`"...".into()`), for a fault no type names.
pub type Cause = Box<dyn std::error::Error + Send + Sync + 'static>;

/// A per-message failure. The runtime counts it, logs it once and goes on with the next message;
/// the stage's state must be as it was before the bad input.
#[derive(Debug, Error)]
pub enum StageError {
    /// The message breaks the stage's input contract (a frame of another size, an empty clip, a
    /// setting out of range): the cause is the stage crate's own error.
    #[error("bad input: {0}")]
    BadInput(Cause),
    #[error(transparent)]
    Frame(#[from] FrameError),
    /// A model failed or gave what it must not (missing outputs, non-finite values).
    #[error("model: {0}")]
    Model(Cause),
    /// State the stage keeps outside the process (e.g. a saved background) could not be read or
    /// written; `what` says which and what for.
    #[error("{what}: {source}")]
    Storage {
        what: &'static str,
        #[source]
        source: Box<dyn std::error::Error + Send + Sync>,
    },
}

pub trait Stage: Send {
    /// Name in counters, logs and tracing spans (the scene's stage kind).
    fn name(&self) -> &str;

    /// Handle one message. Messages the stage does not use are ignored (return nothing): the
    /// runtime forwards every input downstream itself, so later stages still see it.
    fn process(&mut self, input: &Msg, clock: &dyn Clock) -> Result<Vec<Msg>, StageError>;

    /// The input ended (source finished or shutdown): emit what is still pending, e.g. an open
    /// contact episode.
    fn finish(&mut self, _clock: &dyn Clock) -> Result<Vec<Msg>, StageError> {
        Ok(Vec::new())
    }

    /// How often the stage wants [`Stage::timer`] called \[ns]; None (the default): never. A
    /// stage that must act when an input does not come (the policy's watchdog) asks for one.
    fn timer_period_ns(&self) -> Option<i64> {
        None
    }

    /// The timer hook: called by the transport every [`Stage::timer_period_ns`] with its time
    /// `now` (the same time line as the inputs' stamps: sim time under a sim clock). What it
    /// returns goes downstream like any output. Default: nothing.
    fn timer(&mut self, _now: Stamp) -> Result<Vec<Msg>, StageError> {
        Ok(Vec::new())
    }

    /// The inputs whose producer must be alive now (message kinds or input names the stage
    /// documents); a transport that can see producers (ROS publishers) watches them and reports
    /// through [`Stage::set_input_lost`]. Default: none.
    fn awaited_inputs(&self) -> Vec<&'static str> {
        Vec::new()
    }

    /// A transport's word that the producer of input `name` is gone (`Some(why)`) or back
    /// (`None`). Default: ignored.
    fn set_input_lost(&mut self, _name: &str, _why: Option<String>) -> Result<(), StageError> {
        Ok(())
    }
}

impl StageError {
    /// A bad input whose cause is `e` (typically `map_err(StageError::bad_input)`).
    pub fn bad_input(e: impl Into<Cause>) -> Self {
        StageError::BadInput(e.into())
    }

    /// A model failure whose cause is `e`.
    pub fn model(e: impl Into<Cause>) -> Self {
        StageError::Model(e.into())
    }
}

/// A source's failure; each variant keeps the driver's or reader's own error as its [`Cause`].
#[derive(Debug, Error)]
pub enum SourceError {
    /// This frame is lost (corrupt buffer, decode error); the source goes on.
    #[error("frame dropped: {0}")]
    Frame(Cause),
    /// The device is gone; the source may come back (reconnect) or end.
    #[error("device unavailable: {0}")]
    Unavailable(Cause),
    /// Nothing more can come from this source.
    #[error("source failed: {0}")]
    Fatal(Cause),
}

impl SourceError {
    /// A lost frame whose cause is `e`.
    pub fn frame(e: impl Into<Cause>) -> Self {
        SourceError::Frame(e.into())
    }

    /// An unavailable device whose cause is `e`.
    pub fn unavailable(e: impl Into<Cause>) -> Self {
        SourceError::Unavailable(e.into())
    }

    /// A source that ended on `e`.
    pub fn fatal(e: impl Into<Cause>) -> Self {
        SourceError::Fatal(e.into())
    }
}

/// Where frames come from: a V4L2 sensor, the mock sensor, a bag.
pub trait Source: Send {
    fn name(&self) -> &str;
    /// The next frame, blocking until it is captured (live) or produced (mock, bag).
    /// `Ok(None)` is the end of the source.
    fn next_frame(&mut self) -> Result<Option<Frame>, SourceError>;
    /// True for sources whose stamps are their own (mock, bag): the runtime may pace them to
    /// real time and drives stage clocks from the stamps. False for live sensors.
    fn is_replay(&self) -> bool;
}
