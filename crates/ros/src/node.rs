//! What every UniTac node does the same way: create the node, read its parameters from
//! `--ros-args` (derive-based, `--params-file` included), keep the parameter services and the
//! /clock subscription (`use_sim_time`) served, stop on Ctrl-C, and publish /diagnostics.

use futures::executor::LocalPool;
use r2r::diagnostic_msgs::msg::DiagnosticArray;
use r2r::{QosProfile, RosParams};
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
}

impl<P: RosParams + Default + Clone + Send + 'static> NodeBase<P> {
    /// Create node `name`; parameters are read before this returns.
    pub fn new(name: &str) -> anyhow::Result<Self> {
        let ctx = r2r::Context::create()?;
        let mut node = r2r::Node::create(ctx, name, "")?;
        let params = Arc::new(Mutex::new(P::default()));
        let (handler, _events) = node.make_derived_parameter_handler(params.clone())?;
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
        let d = self
            .clock
            .lock()
            .ok()
            .and_then(|mut c| c.get_now().ok())
            .unwrap_or_default();
        r2r::Clock::to_builtin_time(&d)
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
