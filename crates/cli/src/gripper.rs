//! `unitac gripper`: bring-up of a serial gripper (Robotiq 2F, DH AG/PGE) from the command line.
//!
//! `--port sim` runs the action against a simulated device on a pseudo-terminal instead.

use anyhow::{Context, bail};
use std::path::PathBuf;
use std::time::{Duration, Instant};
use unitac_cli::ConfigError;
use unitac_cli::args::{f64_above, f64_in};
use unitac_gripper::bench::{self, BenchResult, Cycle};
use unitac_gripper::client::{CameBack, ClientConfig, RtuClient};
use unitac_gripper::{
    Activation, DriverConfig, Fault, Gripper, GripperSetpoint, GripperState, Model, Motion,
    SerialGripper,
};
use unitac_gripper_sim::device::physics::SimObject;
use unitac_gripper_sim::device::{DeviceConfig, SimDevice};

#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Action {
    /// Activate (Robotiq rACT, DH initialise) unless already active; wait until done.
    Activate,
    /// Open fully and wait until there.
    Open,
    /// Close (stops on an object at --force) and wait until stopped.
    Close,
    /// Print the state once.
    Status,
    /// Status round trips per second against the wire limit, and the simulated device on a pty
    /// paced and unpaced; reads only unless --allow-motion (then command -> status cycles).
    Bench,
    /// Run a simulated gripper for --seconds, reachable at --port (a symlink to its pty, like a
    /// /dev/serial/by-id name), for a driver or node in another process.
    Simulate,
}

/// A fault `simulate` starts with.
#[derive(clap::ValueEnum, Clone, Copy, Debug, PartialEq, Eq)]
pub enum Inject {
    Overcurrent,
    OvercurrentPersistent,
    /// Every reply with a corrupted CRC (line noise, a wrong termination).
    BadCrc,
}

#[derive(clap::Args, Debug)]
pub struct GripperArgs {
    /// Serial port, best its stable name (/dev/serial/by-id/...); `sim` for a simulated device.
    #[arg(long)]
    pub port: String,
    /// robotiq_2f85 | robotiq_2f140 | dh_ag95 | dh_pge50
    #[arg(long)]
    pub model: Model,
    /// Modbus slave id, 1 to 247 (default: the model's factory id, Robotiq 9, DH 1); 0 is the
    /// broadcast address, which no device answers.
    #[arg(long, value_parser = clap::value_parser!(u8).range(1..=247))]
    pub slave: Option<u8>,
    /// Line rate, 1200 to 4000000 baud (default: the model's, 115200).
    #[arg(long, value_parser = clap::value_parser!(u32).range(1200..=4_000_000))]
    pub baud: Option<u32>,
    /// Grip force limit for open/close, 0 to 10000 N, clamped to the model's range (default: the
    /// model's minimum).
    #[arg(long, value_parser = f64_in(0.0, 10_000.0))]
    pub force: Option<f64>,
    /// Finger speed for open/close, 0 to 10 m/s, clamped to the model's range (default: half the
    /// model's maximum).
    #[arg(long, value_parser = f64_in(0.0, 10.0))]
    pub speed: Option<f64>,
    /// How long to wait for the action (activate/open/close), to run the bench or to serve the
    /// simulated gripper: more than 0, at most 3600 s.
    #[arg(long, default_value_t = 5.0, value_parser = f64_above(0.0, 3600.0))]
    pub seconds: f64,
    /// Print the result (state, or the bench's rates) as one JSON object.
    #[arg(long)]
    pub json: bool,
    /// bench: write commands every cycle (they move the gripper: a Robotiq is activated and
    /// opened at full speed). Without it the bench reads status only.
    #[arg(long)]
    pub allow_motion: bool,
    /// simulate: start with this fault (overcurrent: active with Robotiq's major fault 0x0E,
    /// cleared by re-activation; overcurrent-persistent: back after every re-activation;
    /// bad-crc: every reply's CRC corrupted).
    #[arg(long, value_enum)]
    pub inject: Option<Inject>,
    /// What to do with the gripper.
    pub action: Action,
}

/// Why the serial port named could not be opened: a port that is not there or not ours is bad
/// configuration (exit 2); one that fails otherwise (busy, not a serial port) is a failed run
/// (exit 1).
fn port_error(e: unitac_gripper::port::PortError) -> anyhow::Error {
    use unitac_gripper::port::PortError;
    match e {
        PortError::NotFound { .. } | PortError::Permission { .. } => {
            anyhow::Error::new(ConfigError(e.to_string()))
        }
        e => e.into(),
    }
}

pub fn run(a: GripperArgs) -> anyhow::Result<bool> {
    if a.action == Action::Bench {
        return run_bench(&a);
    }
    if a.action == Action::Simulate {
        return simulate(&a);
    }
    let _sim;
    let port = if a.port == "sim" {
        let dev =
            SimDevice::spawn(sim_config(a.model)).context("starting the simulated gripper")?;
        let p = dev.path();
        _sim = Some(dev);
        p
    } else {
        _sim = None;
        PathBuf::from(&a.port)
    };
    let mut cfg = DriverConfig::new(&port, a.model);
    cfg.slave = a.slave.unwrap_or(cfg.slave);
    cfg.baud = a.baud.unwrap_or(cfg.baud);
    // Open once here so a wrong port or a permission problem is reported at once, as such.
    drop(unitac_gripper::port::open(&port, cfg.baud).map_err(port_error)?);
    let mut g = SerialGripper::start(cfg.clone())?;
    let deadline = Instant::now() + Duration::from_secs_f64(a.seconds);
    wait(&g, deadline, &cfg, |s| s.activation != Activation::Unknown)?;
    let lim = g.limits();
    let speed = a.speed.unwrap_or(lim.max_speed_m_s / 2.0);
    let force = a.force.unwrap_or(lim.min_force_n);
    match a.action {
        Action::Status | Action::Bench | Action::Simulate => {}
        Action::Activate => {
            if let Some(Fault::Major { code, what }) = g.state().fault {
                // The documented clear: an rACT rising edge (the driver writes rACT 0, then 1).
                eprintln!(
                    "{}: major fault 0x{code:02X} ({what}): clearing it by re-activation (rACT 0, \
                     then 1; the fingers move through their stroke)",
                    a.model
                );
                g.clear_fault()?;
                // Out of the faulted state (reset or activating), then active again.
                wait(&g, deadline, &cfg, |s| {
                    s.activation != Activation::Active
                        || !matches!(s.fault, Some(Fault::Major { .. }))
                })?;
            } else {
                g.activate()?;
            }
            wait(&g, deadline, &cfg, |s| s.activation == Activation::Active)?;
            // A fault that comes back at once (a blocked finger, a motor fault) persists.
            let n = g.state().updates;
            wait(&g, deadline, &cfg, |s| s.updates >= n + 10)?;
            if let Some(Fault::Major { code, what }) = g.state().fault {
                bail!(
                    "the major fault 0x{code:02X} ({what}) persists after re-activation (rACT 0 \
                     then 1): switch the gripper's power off, free the fingers of whatever blocks \
                     them (check the load and the force asked), power it on, then run \
                     `unitac gripper --port {} --model {} activate` again; if it still comes \
                     back, contact Robotiq support with the fault code",
                    a.port,
                    a.model
                );
            }
        }
        Action::Open | Action::Close => {
            if let Some(Fault::Major { code, what }) = g.state().fault {
                bail!(
                    "the gripper has a major fault 0x{code:02X} ({what}) and will not move: clear \
                     it with `unitac gripper --port {} --model {} activate` (rACT 0 then 1; the \
                     fingers move through their stroke)",
                    a.port,
                    a.model
                );
            }
            if g.state().activation != Activation::Active {
                bail!(
                    "the gripper is not activated ({:?}); run `unitac gripper ... activate` first",
                    g.state().activation
                );
            }
            let opening_m = if a.action == Action::Open {
                lim.max_opening_m
            } else {
                0.0
            };
            g.command(GripperSetpoint {
                opening_m,
                speed_m_s: speed,
                force_n: force,
            })?;
            let start = g.state().updates;
            wait(&g, deadline, &cfg, |s| {
                s.updates > start + 2
                    && matches!(
                        s.motion,
                        Motion::Reached | Motion::Caught | Motion::CaughtOpening | Motion::Dropped
                    )
            })?;
        }
    }
    let s = g.state();
    if a.json {
        println!("{}", serde_json::to_string(&s)?);
    } else {
        println!("{} on {}: {}", a.model, port.display(), describe(&s));
    }
    Ok(!matches!(s.fault, Some(Fault::Major { .. })))
}

/// The simulated device of `--port sim` and `simulate`: an object half the stroke wide.
fn sim_config(model: Model) -> DeviceConfig {
    let mut cfg = DeviceConfig::new(model);
    cfg.object = Some(SimObject {
        width_m: model.calibration().limits.max_opening_m * 0.5,
        stiffness_n_per_m: 20_000.0,
    });
    cfg
}

fn simulate(a: &GripperArgs) -> anyhow::Result<bool> {
    let mut cfg = sim_config(a.model);
    cfg.slave = a.slave.unwrap_or(cfg.slave);
    cfg.baud = a.baud.unwrap_or(cfg.baud);
    let link = PathBuf::from(&a.port);
    cfg.link = Some(link.clone());
    cfg.start_active |= matches!(
        a.inject,
        Some(Inject::Overcurrent | Inject::OvercurrentPersistent)
    );
    // The link goes only where nothing is, or over a stale simulator link
    // (unitac_gripper_sim::device::link): anything else at --port is refused before any work.
    let dev = match SimDevice::spawn(cfg.clone()) {
        Ok(d) => d,
        // Something at --port, or no directory (or no right) to make the link in: the port
        // named is the problem, before any work.
        Err(e)
            if matches!(
                e.kind(),
                std::io::ErrorKind::AlreadyExists
                    | std::io::ErrorKind::NotFound
                    | std::io::ErrorKind::PermissionDenied
            ) =>
        {
            return Err(anyhow::Error::new(ConfigError(format!(
                "--port {}: {e}",
                link.display()
            ))));
        }
        Err(e) => {
            return Err(anyhow::Error::new(e).context(format!(
                "starting the simulated gripper at {}",
                link.display()
            )));
        }
    };
    match a.inject {
        Some(Inject::Overcurrent) => dev.overcurrent(),
        Some(Inject::OvercurrentPersistent) => dev.overcurrent_persists(true),
        Some(Inject::BadCrc) => dev.faults(|f| f.corrupt_crc = u32::MAX),
        None => {}
    }
    println!(
        "simulated {} (slave {}, {} baud) at {}",
        a.model,
        cfg.slave,
        cfg.baud,
        unitac_gripper_sim::device::describe(&dev.path())
    );
    std::thread::sleep(Duration::from_secs_f64(a.seconds));
    // Stops the device and removes its link, if the link is still its own.
    drop(dev);
    Ok(true)
}

/// Wait for `done`, turning a silent or missing device into a message that says what to check.
fn wait(
    g: &SerialGripper,
    deadline: Instant,
    cfg: &DriverConfig,
    done: impl Fn(&GripperState) -> bool,
) -> anyhow::Result<()> {
    loop {
        let s = g.state();
        if done(&s) {
            return Ok(());
        }
        if Instant::now() >= deadline {
            let st = g.stats();
            if s.updates == 0 {
                bail!("{}", no_update(cfg, &st));
            }
            bail!("timed out: {}", describe(&s));
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

/// Why no exchange succeeded, from what came back: only a silent bus is "no reply".
fn no_update(cfg: &DriverConfig, st: &unitac_gripper::DriverStats) -> String {
    let last = st
        .last_error
        .clone()
        .unwrap_or_else(|| "nothing received".into());
    let on = format!(
        "slave {} on {} at {} baud",
        cfg.slave,
        st.port.display(),
        cfg.baud
    );
    match st.link.came_back() {
        CameBack::Nothing => format!(
            "no reply from {on} ({last}): check the gripper's power, the RS-485 wiring (A/B \
             swapped?), --slave and --baud"
        ),
        CameBack::Exceptions => format!(
            "{on} answered, with an exception reply ({last}; {} exception(s)): a device is there \
             and the line works, but it refused the {} requests: check --model (is it a {}?) \
             and --slave",
            st.link.exceptions, cfg.model, cfg.model
        ),
        CameBack::WrongReplies => format!(
            "{on} answered, but not to the request ({last}; {} such reply(ies)): a device is \
             there and the line works, but it does not speak the {} register map: check \
             --model and --slave",
            st.link.bad_replies, cfg.model
        ),
        CameBack::WrongSlave => format!(
            "a reply came from another slave than {} on {} ({last}): set --slave to the id that \
             answered, or take the second device off the bus",
            cfg.slave,
            st.port.display()
        ),
        CameBack::Garbled => format!(
            "bytes came back from {} but no valid frame ({last}; {} reply(ies) failed their \
             CRC): the line is connected; check --baud (a wrong rate garbles every frame, \
             8N1 expected), the RS-485 termination and ground",
            st.port.display(),
            st.link.garbled
        ),
        CameBack::Incomplete => format!(
            "only part of a reply came back from {on} ({last}): check --baud, the adapter and \
             the cable"
        ),
    }
}

fn describe(s: &GripperState) -> String {
    let mm = |m: Option<f64>| m.map_or("?".into(), |v| format!("{:.1} mm", v * 1e3));
    let mut out = format!(
        "{:?}, {:?}, opening {} (target {})",
        s.activation,
        s.motion,
        mm(s.opening_m),
        mm(s.target_m)
    )
    .to_lowercase();
    if let Some(c) = s.current_a {
        out += &format!(", current {c:.2} A");
    }
    if let Some(f) = s.force_n {
        out += &format!(", force {f:.1} N");
    }
    if let Some(n) = &s.out_of_range {
        out += &format!(", {n}");
    }
    out += &match &s.fault {
        None => ", no fault".into(),
        Some(Fault::Minor { code, what }) => format!(", minor fault 0x{code:02X}: {what}"),
        Some(Fault::Major { code, what }) => format!(
            ", MAJOR fault 0x{code:02X}: {what} (clear it by re-activation: `unitac gripper ... \
             activate` writes rACT 0 then 1)"
        ),
        Some(Fault::Link { what }) => format!(", link fault: {what}"),
    };
    out
}

fn run_bench(a: &GripperArgs) -> anyhow::Result<bool> {
    let baud = a.baud.unwrap_or(a.model.default_baud());
    let d = Duration::from_secs_f64(a.seconds);
    let kind = if a.allow_motion {
        Cycle::Motion
    } else {
        Cycle::StatusOnly
    };
    if kind == Cycle::Motion && a.port != "sim" {
        eprintln!("{} on {}: {}", a.model, a.port, kind.describe(a.model));
    }
    let mut results: Vec<BenchResult> = Vec::new();
    if a.port != "sim" {
        let p = unitac_gripper::port::open(&PathBuf::from(&a.port), baud).map_err(port_error)?;
        let mut c = RtuClient::new(
            p,
            ClientConfig {
                retries: 0,
                ..ClientConfig::new(a.slave.unwrap_or(a.model.default_slave()), baud)
            },
        );
        let label = format!("{} on {}", a.model, a.port);
        results.push(
            bench::run(&label, &mut c, a.model, kind, d)
                .with_context(|| format!("{label}: the device does not answer"))?,
        );
    }
    for paced in [true, false] {
        results.push(unitac_gripper_sim::bench::run_sim(
            a.model, kind, baud, paced, d,
        )?);
    }
    if a.json {
        println!("{}", serde_json::to_string(&results)?);
        return Ok(true);
    }
    println!(
        "{:<48} {:>9} {:>11} {:>7} {:>9} {:>9} {:>8}",
        "link", "cycles/s", "wire limit", "ratio", "p50 ms", "p99 ms", "failures"
    );
    for r in &results {
        let ms = |x: Option<f64>| x.map_or("-".into(), |v| format!("{:.3}", v * 1e3));
        println!(
            "{:<48} {:>9.1} {:>11.1} {:>6.1}% {:>9} {:>9} {:>8}",
            r.label,
            r.rate_hz,
            r.wire_limit_hz,
            100.0 * r.ratio,
            ms(r.rtt_p50_s),
            ms(r.rtt_p99_s),
            r.failures
        );
    }
    println!("each cycle: {}", kind.describe(a.model));
    println!(
        "wire limit: one cycle ({} frame(s)) at {baud} baud, 8N1, with a 3.5-character silence \
         after every frame; the unpaced row is the pty's own rate",
        bench::cycle(a.model, kind).len()
    );
    Ok(true)
}
