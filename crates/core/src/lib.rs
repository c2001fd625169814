//! Pure types shared by every stage and transport of the UniTac robot stack.
//!
//! Nothing here does I/O beyond reading a scene file, starts a thread, or reads the wall clock
//! except through [`clock::SystemClock`]. Stages take a `&dyn Clock` so the same code runs live,
//! in replay and in tests with identical output for identical input.

pub mod chain;
pub mod clock;
pub mod frame;
pub mod golden;
pub mod graph;
pub mod msg;
pub mod pace;
pub mod pixel;
pub mod profile;
pub mod scene;
pub mod sensor;
pub mod setpoint;
pub mod stage;
pub mod timing;
pub mod yaml;

pub use chain::{Chain, StageRunner};
pub use clock::{Clock, ManualClock, Stamp, SystemClock};
pub use frame::{Frame, FrameError, optical_frame_id, sensor_id_of};
pub use msg::Msg;
pub use pace::Pacer;
pub use scene::{Scene, SceneError};
pub use sensor::{Gel, Photometric, SensorKind, SensorSpec, UnknownSensorKind};
pub use setpoint::GripperSetpoint;
pub use stage::{Source, SourceError, Stage, StageError};
pub use timing::{PeriodJitter, Tail, Timing, period_jitter, tail, timing};
