//! What every UniTac node does the same way: create the node, read its parameters from
//! `--ros-args` (derive-based, `--params-file` included), keep the parameter services and the
//! /clock subscription (`use_sim_time`) served, stop on Ctrl-C, and publish /diagnostics.
//!
//! Parameters a node is given are checked by name before it starts: the node's own (its derived
//! `Params`), `use_sim_time`, and `<stage>.<key>` for the stages it runs (overrides of the scene
//! file's stage params, checked later against the stage's typed params). Anything else is an
//! error: r2r itself would keep an unknown or misspelt key silently.

use futures::executor::LocalPool;
use indexmap::IndexMap;
use r2r::diagnostic_msgs::msg::DiagnosticArray;
use r2r::{ParameterValue, QosProfile, RosParams};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

#[allow(missing_debug_implementations)] // r2r::Node is not Debug
pub struct NodeBase<P> {
    pub node: r2r::Node,
    pool: LocalPool,
    params: Arc<Mutex<P>>,
    stop: Arc<AtomicBool>,
    clock: Arc<Mutex<r2r::Clock>>,
    diagnostics: r2r::Publisher<DiagnosticArray>,
    overrides: Vec<(String, serde_yaml::Value)>,
}

impl<P: RosParams + Default + Clone + Send + 'static> NodeBase<P> {
    /// Create node `name`; parameters are read and checked before this returns. `stage_kinds`:
    /// the scene stages this node runs (their `<kind>.<key>` overrides are accepted).
    pub fn new(name: &str, stage_kinds: &[&str]) -> anyhow::Result<Self> {
        let Created {
            mut node,
            params,
            overrides,
            handler,
        } = create::<P>(name, stage_kinds)?;
        let pool = LocalPool::new();
        futures::task::LocalSpawnExt::spawn_local(&pool.spawner(), handler)?;
        let stop = Arc::new(AtomicBool::new(false));
        {
            let stop = stop.clone();
            ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))?;
        }
        let diagnostics = node.create_publisher("/diagnostics", QosProfile::default())?;
        let clock = node.get_ros_clock();
        let mut base = Self {
            node,
            pool,
            params,
            stop,
            clock,
            diagnostics,
            overrides,
        };
        base.pool.run_until_stalled();
        Ok(base)
    }

    /// The parameters as they are now.
    pub fn params(&self) -> anyhow::Result<P> {
        let g = self
            .params
            .lock()
            .map_err(|_| anyhow::anyhow!("parameter lock poisoned"))?;
        Ok(g.clone())
    }

    /// The `<stage>.<key>` parameters given, for `unitac_pipeline::overrides::apply`.
    pub fn stage_overrides(&self) -> &[(String, serde_yaml::Value)] {
        &self.overrides
    }

    /// Whether the node was asked to stop (SIGINT / SIGTERM through ctrlc).
    pub fn stopped(&self) -> bool {
        self.stop.load(Ordering::SeqCst)
    }

    /// Serve subscriptions, services and /clock for up to `d`.
    pub fn spin(&mut self, d: Duration) {
        self.node.spin_once(d);
        self.pool.run_until_stalled();
    }

    /// Now on the node's ROS clock: bag time from /clock under `use_sim_time`, else system time.
    pub fn now(&self) -> r2r::builtin_interfaces::msg::Time {
        ros_now(&self.clock)
    }

    /// Seconds from `stamp` (a capture time) to now on the node's clock.
    pub fn age_s(&self, stamp: unitac_core::Stamp) -> f64 {
        let now = crate::convert::stamp(&self.now());
        (now.0 - stamp.0) as f64 * 1e-9
    }

    pub fn publish_diagnostics(&self, a: &DiagnosticArray) -> anyhow::Result<()> {
        self.diagnostics.publish(a)?;
        Ok(())
    }

    /// Spin until `done()` holds or `timeout` passes; returns whether it held.
    pub fn spin_until(&mut self, timeout: Duration, mut done: impl FnMut() -> bool) -> bool {
        let t0 = std::time::Instant::now();
        while t0.elapsed() < timeout {
            if done() || self.stopped() {
                return done();
            }
            self.spin(Duration::from_millis(10));
        }
        done()
    }
}

/// Now on a node's ROS clock (`Node::get_ros_clock`): sim time from /clock under
/// `use_sim_time`, else system time.
pub fn ros_now(clock: &Mutex<r2r::Clock>) -> r2r::builtin_interfaces::msg::Time {
    let d = clock
        .lock()
        .ok()
        .and_then(|mut c| c.get_now().ok())
        .unwrap_or_default();
    r2r::Clock::to_builtin_time(&d)
}

/// A node created with its parameters read and checked, and the parameter handler to drive.
struct Created<P> {
    node: r2r::Node,
    params: Arc<Mutex<P>>,
    overrides: Vec<(String, serde_yaml::Value)>,
    handler: ParamHandler,
}

/// The parameter services' future (r2r's derived parameter handler).
pub type ParamHandler = std::pin::Pin<Box<dyn std::future::Future<Output = ()> + Send>>;

fn create<P: RosParams + Default + Clone + Send + 'static>(
    name: &str,
    stage_kinds: &[&str],
) -> anyhow::Result<Created<P>> {
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, name, "")?;
    let overrides = check_given_params(&node, &P::default(), stage_kinds)?;
    let params = Arc::new(Mutex::new(P::default()));
    let (handler, _events) = node.make_derived_parameter_handler(params.clone())?;
    Ok(Created {
        node,
        params,
        overrides,
        handler: Box::pin(handler),
    })
}

/// What a node on a tokio runtime starts from (the policy node): the node with its parameters
/// read and checked as [`NodeBase::new`] does, the parameter handler to spawn, the ROS clock and
/// the /diagnostics publisher. No signal handler: the node's own `select!` owns SIGINT and
/// SIGTERM (`tokio::signal`).
#[allow(missing_debug_implementations)] // r2r::Node is not Debug
pub struct AsyncNode<P> {
    pub node: r2r::Node,
    pub params: P,
    pub overrides: Vec<(String, serde_yaml::Value)>,
    /// Spawn it (`tokio::spawn`): it serves the parameter services while the node spins.
    pub param_handler: ParamHandler,
    pub clock: Arc<Mutex<r2r::Clock>>,
    pub diagnostics: r2r::Publisher<DiagnosticArray>,
}

impl<P: RosParams + Default + Clone + Send + 'static> AsyncNode<P> {
    /// Create node `name`; parameters are read and checked before this returns. `stage_kinds`:
    /// the scene stages this node runs (their `<kind>.<key>` overrides are accepted).
    pub fn new(name: &str, stage_kinds: &[&str]) -> anyhow::Result<Self> {
        let Created {
            mut node,
            params,
            overrides,
            handler,
        } = create::<P>(name, stage_kinds)?;
        let diagnostics = node.create_publisher("/diagnostics", QosProfile::default())?;
        let clock = node.get_ros_clock();
        let params = params
            .lock()
            .map_err(|_| anyhow::anyhow!("parameter lock poisoned"))?
            .clone();
        Ok(Self {
            node,
            params,
            overrides,
            param_handler: handler,
            clock,
            diagnostics,
        })
    }
}

/// Spin `node` on a blocking thread of the tokio runtime (as r2r's tokio examples do) until
/// `stop` is set; subscriptions, services and /clock are served there, the node's streams wake
/// the async side. The lock is held for one short spin at a time, so graph queries from the
/// async side wait at most that long.
pub fn spin_in_background(
    node: Arc<Mutex<r2r::Node>>,
    stop: Arc<AtomicBool>,
) -> tokio::task::JoinHandle<()> {
    tokio::task::spawn_blocking(move || {
        while !stop.load(Ordering::SeqCst) {
            match node.lock() {
                Ok(mut n) => n.spin_once(Duration::from_millis(2)),
                Err(_) => return,
            }
            // Let a graph query or publisher creation take the lock between spins.
            std::thread::yield_now();
        }
    })
}

/// A ROS parameter value as the YAML value a scene file would hold (`None`: not set).
pub fn yaml_value(v: &ParameterValue) -> Option<serde_yaml::Value> {
    use serde_yaml::Value as Y;
    let seq = |v: Vec<Y>| Some(Y::Sequence(v));
    match v {
        ParameterValue::NotSet => None,
        ParameterValue::Bool(b) => Some(Y::Bool(*b)),
        ParameterValue::Integer(i) => Some(Y::from(*i)),
        ParameterValue::Double(d) => Some(Y::from(*d)),
        ParameterValue::String(s) => Some(Y::String(s.clone())),
        ParameterValue::BoolArray(a) => seq(a.iter().map(|b| Y::Bool(*b)).collect()),
        ParameterValue::ByteArray(a) => seq(a.iter().map(|b| Y::from(*b)).collect()),
        ParameterValue::IntegerArray(a) => seq(a.iter().map(|i| Y::from(*i)).collect()),
        ParameterValue::DoubleArray(a) => seq(a.iter().map(|d| Y::from(*d)).collect()),
        ParameterValue::StringArray(a) => seq(a.iter().map(|s| Y::String(s.clone())).collect()),
    }
}

/// Every parameter given to `node` (command line, params files) must be one of `declared`'s,
/// `use_sim_time`, or a `<stage>.<key>` override for a stage in `stage_kinds`; returns the
/// overrides. One line naming the first unknown parameter and what is accepted otherwise.
fn check_given_params<P: RosParams + Clone>(
    node: &r2r::Node,
    declared: &P,
    stage_kinds: &[&str],
) -> anyhow::Result<Vec<(String, serde_yaml::Value)>> {
    let mut names = IndexMap::new();
    declared.clone().register_parameters("", None, &mut names)?;
    let given = node
        .params
        .lock()
        .map_err(|_| anyhow::anyhow!("parameter lock poisoned"))?
        .iter()
        .map(|(k, p)| (k.clone(), p.value.clone()))
        .collect::<Vec<_>>();
    let mut overrides = Vec::new();
    for (key, value) in given {
        if names.contains_key(&key) || key == "use_sim_time" {
            continue;
        }
        let stage = key.split_once('.').map(|(k, _)| k);
        if stage.is_some_and(|k| stage_kinds.contains(&k)) {
            if let Some(v) = yaml_value(&value) {
                overrides.push((key, v));
            }
            continue;
        }
        let mut known: Vec<String> = names.keys().cloned().collect();
        known.extend(stage_kinds.iter().map(|k| format!("{k}.<key>")));
        anyhow::bail!(
            "unknown parameter '{key}' (this node takes: {}, use_sim_time)",
            known.join(", ")
        );
    }
    Ok(overrides)
}

/// `main` of a node binary: run it, print the error on one line, exit 1 on failure.
pub fn main_of(name: &str, run: impl FnOnce() -> anyhow::Result<()>) -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("{name}: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
