//! `unitac-lab bench policy`: the policy stage's control tick (observation -> command), embedded.
//!
//! For each scene x mode (`launch/scenes/<task>_<mode>.yaml`, `unitac_pipeline::tasks`) the scene's own policy stage
//! is built from the scene file and ticked through `unitac_core::chain` at the control rate, as
//! every transport drives it. Its inputs are scripted from a sim task world (a training cup, 60 to
//! 70 mm: the unseen 90 mm cup blocks the arm, since the policy bounds the opening to 85 mm; or
//! two fabrics): the gripper's status and the camera's estimate come from the world through the
//! trials bridge (`unitac_trials::bridge`), the commands move the world, and what the tactile
//! stages would publish (contact state, the latent after the first touch or before any, the
//! comparison once both fabrics were touched) is scripted from the world's contact. Those inputs
//! only make the controllers walk through their phases; nothing here judges a trial.
//!
//! Per tick, timed: the GripperStatus into the chain until its GripperCommand, ArmCommand and
//! PolicyStatus are out (the observation is assembled, the watchdog, controller and safety layer
//! run inside). A second pass adds an ONNX policy's `act` to the same tick (the test MLP of
//! crates/policy's tests, or `--policy DIR`): it infers every `n_action_steps` ticks and plays
//! its plan in between. A third runs that tick in real time, paced by `unitac_core::Pacer` at the
//! control rate, and reports the achieved period. Side by side: the same ONNX policy in Python
//! (onnxruntime + numpy, the loop a LeRobot user runs) and a `time.sleep`-paced Python loop, each
//! right after the same work in Rust (`onnx act`, `onnx act, paced`).

use anyhow::{Context, bail};
use std::path::{Path, PathBuf};
use std::time::Instant;
use unitac_core::SensorKind;
use unitac_core::msg::{
    ContactState, LatentSource, PropertyComparison, TactileLatent, Winner, samples,
};
use unitac_core::{Chain, Msg, Pacer, Stamp, period_jitter, tail};
use unitac_pipeline::StageConfig;
use unitac_policy::bench::TickRow;
use unitac_policy::onnx::{NamedInputs, OnnxPolicy, RuntimeConfig};
use unitac_policy::{Mode, PolicyParams, PolicyStage};
use unitac_sim::task::{Split, TaskConfig, TaskKind, TaskTruth, TaskWorld, trial_rng};
use unitac_sim::{MockConfig, MockSensor, Scenario};
use unitac_trials::TrialGripper;
use unitac_trials::bridge;
use unitac_trials::stepper::WorldStepper;

/// Every scene per task and mode (`<task>_<mode>` in the scene directories), by task, then in
/// the modes' order.
pub fn scenes() -> Vec<String> {
    unitac_pipeline::tasks(None)
        .iter()
        .flat_map(|(task, modes)| modes.iter().map(|m| unitac_pipeline::mode_scene(task, *m)))
        .collect()
}

/// Longest unpaced episode \[ticks] (60 s at 30 Hz); an episode also ends at `done` or `failed`.
const MAX_EPISODE_TICKS: usize = 1800;
/// The world seed of the scripted episodes (episode `i` is trial `i` of it).
const SEED: u64 = 1;

#[derive(Debug, Clone)]
pub struct Options {
    /// Unpaced episodes per scene and pass.
    pub episodes: usize,
    /// Ticks of the real-time paced loop per scene (0: none).
    pub paced_ticks: usize,
    pub python: bool,
    /// An ONNX policy directory (manifest.json + model); None: generate the test MLP.
    pub policy: Option<PathBuf>,
}

#[derive(Debug, Clone, Copy, serde::Serialize)]
pub struct Ratios {
    pub p50: f64,
    pub p99: f64,
    pub inferred_p50: f64,
}

#[derive(Debug, serde::Serialize)]
pub struct PolicyBench {
    pub rows: Vec<TickRow>,
    /// The ONNX policy's id and where it came from.
    pub onnx_policy: String,
    /// Python's `act` over ours, when the baseline ran: p50 and p99 over every tick, p50 over
    /// the ticks that inferred.
    pub python_over_rust: Option<Ratios>,
    pub python_versions: String,
    pub note: String,
}

/// What the tactile stages and the camera would publish, scripted from a task world, and the
/// world moved by the policy's commands.
struct Script {
    world: WorldStepper,
    truth: TaskTruth,
    mode: Mode,
    decides: bool,
    latent_len: usize,
    gel_indent_m_per_m2: f64,
    objects: Vec<String>,
    visual_names: Vec<String>,
    in_contact: bool,
    touching: String,
    touched: Vec<String>,
    latent_sent: bool,
    comparison_sent: bool,
}

impl Script {
    fn new(p: &PolicyParams, kind: TaskKind, episode: u32) -> anyhow::Result<Self> {
        // A task that decides between objects gets the comparison once both were touched.
        let decides = kind.decides();
        let cfg = TaskConfig::new(kind, Split::Train);
        let world = TaskWorld::reset(&cfg, SEED, episode);
        let truth = world.truth();
        // The tactile stages are scripted from the world (no frames are rendered); the sensor
        // only completes the stepper.
        let sensor = MockSensor::new(
            MockConfig::new(SensorKind::GELSIGHT_MINI, SEED),
            Scenario::idle(1.0),
        );
        let world = WorldStepper::new(
            world,
            sensor,
            trial_rng(SEED ^ 0x5EED, episode),
            TrialGripper::InProcess,
            (SEED, episode),
            1.0 / p.control_rate_hz,
        )?;
        Ok(Script {
            truth,
            world,
            mode: p.mode,
            decides,
            latent_len: p.latent_len,
            gel_indent_m_per_m2: p.gel_indent_m_per_m2,
            objects: p.limits.objects.clone(),
            visual_names: p.visual_names.clone(),
            in_contact: false,
            touching: String::new(),
            touched: Vec::new(),
            latent_sent: false,
            comparison_sent: false,
        })
    }

    fn stamp(&self) -> Stamp {
        bridge::stamp_at(self.truth.t_s)
    }

    fn latent(&self, source: LatentSource) -> Msg {
        let n = self.latent_len.max(1);
        Msg::TactileLatent(TactileLatent {
            header: unitac_core::msg::Header::new(self.stamp(), "gel"),
            source,
            shape: vec![1, n as u32],
            data: vec![0.1; n],
            valid: true,
            guard_report: String::new(),
            object: String::new(),
            condition_sources: Vec::new(),
            condition_age_s: Vec::new(),
            ..samples::tactile_latent()
        })
    }

    /// The messages the scene's other stages and the camera publish before this tick.
    fn inputs(&mut self) -> Vec<Msg> {
        let mut out = Vec::new();
        if self.mode == Mode::Vla || !self.visual_names.is_empty() {
            out.push(self.visual());
        }
        if self.mode == Mode::Vla {
            return out;
        }
        let c = &self.truth.contact;
        let now_in = !c.object.is_empty() && c.penetration_m > 0.0;
        // The gel's contact area grows with its indentation (the inverse of the cup
        // controller's own estimate).
        let area = if now_in {
            10e-6 + c.penetration_m / self.gel_indent_m_per_m2.max(1e-12)
        } else {
            0.0
        };
        if now_in && !self.in_contact {
            self.touching = c.object.clone();
        }
        let episode_ended = self.in_contact && !now_in;
        if episode_ended {
            self.touched.push(std::mem::take(&mut self.touching));
        }
        self.in_contact = now_in;
        out.push(Msg::ContactState(ContactState {
            header: unitac_core::msg::Header::new(self.stamp(), "gel"),
            in_contact: now_in,
            area_m2: area as f32,
            ..samples::contact_state()
        }));
        match (self.mode, self.decides) {
            // The sampler predicts once the sensor prior (the background) is known: at once.
            (Mode::VtlaPred, _) if !self.latent_sent => {
                self.latent_sent = true;
                out.push(self.latent(LatentSource::Predicted));
            }
            // The encoder's latent of the cup's probe touch, when its episode ends.
            (Mode::VtlaReal, false) if episode_ended && !self.latent_sent => {
                self.latent_sent = true;
                out.push(self.latent(LatentSource::Real));
            }
            _ => {}
        }
        let both = self
            .objects
            .iter()
            .take(2)
            .all(|o| self.touched.contains(o));
        if self.decides && both && !self.comparison_sent {
            self.comparison_sent = true;
            out.push(self.comparison());
        }
        out
    }

    /// The camera's estimate with the values the scene names, under the bridge's message names
    /// (NaN for a name the sim camera does not give).
    fn visual(&mut self) -> Msg {
        let cam = self.world.visual();
        let mut msg = bridge::visual_message(&cam);
        let values = self
            .visual_names
            .iter()
            .map(|n| msg.get(n).unwrap_or(f64::NAN))
            .collect();
        msg.values = values;
        msg.names = self.visual_names.clone();
        Msg::VisualObservation(msg)
    }

    /// The compare stage's answer: the rougher of the two fabrics wins "roughness".
    fn comparison(&self) -> Msg {
        let (a, b) = (
            self.objects.first().cloned().unwrap_or_default(),
            self.objects.get(1).cloned().unwrap_or_default(),
        );
        let a_smoother = self.world.world().spec().smoother() == a;
        Msg::PropertyComparison(PropertyComparison {
            header: unitac_core::msg::Header::new(self.stamp(), "gel"),
            property: "roughness".into(),
            episode_a: 1,
            label_a: a,
            episode_b: 2,
            label_b: b,
            winner: if a_smoother { Winner::B } else { Winner::A },
            score_a: if a_smoother { 0.2 } else { 0.8 },
            score_b: if a_smoother { 0.8 } else { 0.2 },
            margin: 0.6,
            confidence: 0.9,
            sentence: String::new(),
        })
    }

    /// The gripper's status now: the tick.
    fn status(&mut self) -> anyhow::Result<Msg> {
        Ok(Msg::GripperStatus(self.world.status()?))
    }

    /// The tick's commands move the world one control period.
    fn apply(&mut self, produced: &[Msg]) -> anyhow::Result<()> {
        let (Some(g), Some(a)) = (
            produced.iter().find_map(|m| match m {
                Msg::GripperCommand(c) => Some(c),
                _ => None,
            }),
            produced.iter().find_map(|m| match m {
                Msg::ArmCommand(a) => Some(a),
                _ => None,
            }),
        ) else {
            bail!("a control tick sent no gripper or arm command: {produced:?}");
        };
        let cmd = self.world.command(g, a)?;
        self.truth = self.world.step(Some(cmd))?;
        Ok(())
    }
}

/// A scene's policy stage as its file configures it: params, scene name and the stiffness model
/// it names (the fitted readout, an ONNX inference in the tick that reads k).
struct ScenePolicy {
    params: PolicyParams,
    kind: TaskKind,
    scene: String,
    model: Option<std::path::PathBuf>,
}

impl ScenePolicy {
    fn stage(&self) -> anyhow::Result<PolicyStage> {
        PolicyStage::load(&self.scene, self.params.clone(), self.model.as_deref())
            .map_err(|e| anyhow::anyhow!("{e}"))
    }
}

/// The policy stage of a scene file.
fn scene_policy(name: &str) -> anyhow::Result<ScenePolicy> {
    let scene = unitac_pipeline::load_scene(name, None).map_err(|e| anyhow::anyhow!("{e}"))?;
    let cfgs = unitac_pipeline::stage_configs(&scene).map_err(|e| anyhow::anyhow!("{e}"))?;
    let kind = unitac_trials::scene::scene_kind(&scene, &[])?;
    cfgs.into_iter()
        .find_map(|c| match c {
            StageConfig::Policy {
                params,
                scene,
                model,
            } => Some(ScenePolicy {
                params: *params,
                kind,
                scene,
                model,
            }),
            _ => None,
        })
        .with_context(|| format!("scene {name} has no policy stage"))
}

/// The ONNX policy's inputs: each input of the manifest, sized from its shape (batch 1), with
/// fixed values (an MLP's time does not depend on them).
fn onnx_inputs(policy: &OnnxPolicy) -> Vec<(String, Vec<f32>)> {
    policy
        .manifest()
        .inputs
        .iter()
        .enumerate()
        .map(|(i, spec)| {
            let n: i64 = spec
                .shape
                .iter()
                .skip(1)
                .map(|d| match d {
                    unitac_infer::bundle::Dim::Fixed(v) => *v,
                    unitac_infer::bundle::Dim::Symbolic(_) => 1,
                })
                .product();
            let values = unitac_infer::flow::noise(i as u64 + 1, n.max(0) as usize)
                .iter()
                .map(|v| v * 0.1)
                .collect();
            (spec.name.clone(), values)
        })
        .collect()
}

/// An ONNX policy's inputs by name.
type Inputs = [(String, Vec<f32>)];

fn named(inputs: &Inputs) -> NamedInputs<'_> {
    inputs
        .iter()
        .fold(NamedInputs::new(), |n, (k, v)| n.with(k, v))
}

/// One pass's samples.
#[derive(Default)]
struct Samples {
    tick_s: Vec<f64>,
    inferred_s: Vec<f64>,
    act_s: Vec<f64>,
    act_inferred_s: Vec<f64>,
    starts_s: Vec<f64>,
    phases: Vec<String>,
}

/// Tick a scene's policy stage on scripted inputs: `episodes` unpaced episodes (or, paced, one
/// episode of `paced_ticks` ticks in real time), with `onnx` run in each tick when given.
fn run_pass(
    sp: &ScenePolicy,
    episodes: usize,
    paced_ticks: Option<usize>,
    mut onnx: Option<(&mut OnnxPolicy, &Inputs)>,
) -> anyhow::Result<Samples> {
    let mut s = Samples::default();
    let origin = Instant::now();
    for episode in 0..episodes {
        let (params, scene) = (&sp.params, &sp.scene);
        let stage = sp.stage()?;
        let mut chain = Chain::new(vec![Box::new(stage)]);
        let mut script = Script::new(params, sp.kind, episode as u32)?;
        if let Some((p, _)) = onnx.as_mut() {
            p.reset();
        }
        let mut pacer = Pacer::real_time();
        let ticks = paced_ticks.unwrap_or(MAX_EPISODE_TICKS);
        for _ in 0..ticks {
            for m in script.inputs() {
                let out = chain.run(m);
                if let Some(e) = out.errors.first() {
                    bail!("{scene}: scripted input rejected: {e}");
                }
            }
            let status = script.status()?;
            let stamp = status.stamp();
            if paced_ticks.is_some() {
                pacer.wait(stamp, |d| {
                    std::thread::sleep(d);
                    true
                });
                s.starts_s.push(origin.elapsed().as_secs_f64());
            }
            let t0 = Instant::now();
            let out = chain.run(status);
            let mut act_s = None;
            if let Some((p, inputs)) = onnx.as_mut() {
                let named = named(inputs);
                let t1 = Instant::now();
                let chunk = p
                    .act(&named, stamp)
                    .with_context(|| format!("{scene}: onnx act"))?;
                let dt = t1.elapsed().as_secs_f64();
                act_s = Some((dt, chunk.inferred));
            }
            let tick_s = t0.elapsed().as_secs_f64();
            if let Some(e) = out.errors.first() {
                bail!("{scene}: the policy stage rejected a tick: {e}");
            }
            s.tick_s.push(tick_s);
            if let Some((dt, inferred)) = act_s {
                s.act_s.push(dt);
                if inferred {
                    s.inferred_s.push(tick_s);
                    s.act_inferred_s.push(dt);
                }
            }
            let phase = out.produced.iter().find_map(|m| match m {
                Msg::PolicyStatus(st) => Some(st.phase.clone()),
                _ => None,
            });
            let phase = phase.unwrap_or_default();
            if s.phases.last() != Some(&phase) && !s.phases.contains(&phase) {
                s.phases.push(phase.clone());
            }
            script.apply(&out.produced)?;
            if paced_ticks.is_none() && matches!(phase.as_str(), "done" | "failed") {
                break;
            }
        }
    }
    Ok(s)
}

/// The ONNX policy alone in a loop paced at its control rate by `Pacer` (the same work as the
/// Python baseline's paced loop).
fn paced_act(onnx: &mut OnnxPolicy, inputs: &Inputs, ticks: usize) -> anyhow::Result<TickRow> {
    onnx.reset();
    let period = onnx.period_ns();
    let mut pacer = Pacer::real_time();
    let origin = Instant::now();
    let (mut starts, mut all, mut inferred) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..ticks {
        let stamp = Stamp(k as i64 * period);
        pacer.wait(stamp, |d| {
            std::thread::sleep(d);
            true
        });
        let t0 = Instant::now();
        starts.push(t0.duration_since(origin).as_secs_f64());
        let chunk = onnx
            .act(&named(inputs), stamp)
            .context("onnx act (paced)")?;
        let dt = t0.elapsed().as_secs_f64();
        all.push(dt);
        if chunk.inferred {
            inferred.push(dt);
        }
    }
    Ok(TickRow {
        transport: "embedded".into(),
        scene: "-".into(),
        mode: "-".into(),
        what: "onnx act, paced".into(),
        tick: tail(all),
        inferred: Some(tail(inferred)),
        period: Some(period_jitter(&starts, period as f64 * 1e-9)),
        phases: Vec::new(),
    })
}

/// The ONNX policy: `dir`, or the test MLP generated by tests/policy/make_policy.py.
fn load_onnx(dir: Option<&Path>) -> anyhow::Result<(OnnxPolicy, String, Option<PathBuf>)> {
    let (dir, generated) = match dir {
        Some(d) => (d.to_path_buf(), None),
        None => {
            let (python, root) = crate::bench::project_python()?;
            let d = crate::scratch::new_dir("bench-policy")?;
            let st = std::process::Command::new(python)
                .arg(root.join("tests/policy/make_policy.py"))
                .arg(&d)
                .status()
                .context("running tests/policy/make_policy.py")?;
            if !st.success() {
                bail!("tests/policy/make_policy.py failed ({st})");
            }
            (d.clone(), Some(d))
        }
    };
    // A bundle given that does not load is bad configuration (exit 2), found before any work;
    // the generated test MLP failing to load is the work failing.
    let p = OnnxPolicy::load(&dir, &RuntimeConfig::default()).map_err(|e| {
        // One line: the numbered problems joined.
        let text: Vec<String> = e
            .to_string()
            .lines()
            .map(|l| l.trim().to_string())
            .collect();
        let msg = format!("--policy {}: {}", dir.display(), text.join(" "));
        match generated {
            None => anyhow::Error::new(unitac_cli::ConfigError(msg)),
            Some(_) => anyhow::anyhow!(msg),
        }
    })?;
    let what = match &generated {
        Some(_) => format!(
            "{} (tests/policy/make_policy.py: MLP {} inputs -> chunk {} x {}, every {} ticks)",
            p.id(),
            p.input_names().join(", "),
            p.manifest().chunk_size,
            p.action_names().len(),
            p.manifest().n_action_steps
        ),
        None => format!(
            "{} ({}; chunk {}, every {} ticks)",
            p.id(),
            dir.display(),
            p.manifest().chunk_size,
            p.manifest().n_action_steps
        ),
    };
    Ok((p, what, generated))
}

fn python_rows(
    dir: &Path,
    ticks: usize,
    paced: usize,
) -> anyhow::Result<(TickRow, Option<TickRow>, String)> {
    let j = crate::bench::run_python_baseline(
        "policy_baseline.py",
        &[
            dir.as_os_str().to_owned(),
            ticks.to_string().into(),
            paced.to_string().into(),
        ],
    )?;
    let samples = |k: &str| -> Vec<f64> {
        j[k].as_array()
            .map(|a| a.iter().filter_map(|v| v.as_f64()).collect())
            .unwrap_or_default()
    };
    let act = TickRow {
        transport: "python".into(),
        scene: "-".into(),
        mode: "-".into(),
        what: "onnx act".into(),
        tick: tail(samples("act_s")),
        inferred: Some(tail(samples("inferred_s"))),
        period: None,
        phases: Vec::new(),
    };
    let starts = samples("paced_starts_s");
    let paced_row = (starts.len() > 1).then(|| TickRow {
        transport: "python".into(),
        scene: "-".into(),
        mode: "-".into(),
        what: "onnx act, sleep-paced".into(),
        tick: tail(samples("paced_act_s")),
        inferred: None,
        period: Some(period_jitter(
            &starts,
            j["period_s"].as_f64().unwrap_or(f64::NAN),
        )),
        phases: Vec::new(),
    });
    let versions = format!(
        "python {} onnxruntime {} numpy {}",
        j["python"], j["onnxruntime"], j["numpy"]
    );
    Ok((act, paced_row, versions))
}

/// Most ticks of a paced loop (`--ticks`): 55 min per scene at 30 Hz.
pub const MAX_PACED_TICKS: usize = 100_000;

pub fn bench_policy(opts: &Options) -> anyhow::Result<PolicyBench> {
    if opts.paced_ticks > MAX_PACED_TICKS {
        return Err(anyhow::Error::new(unitac_cli::ConfigError(format!(
            "--ticks {} is outside 0..={MAX_PACED_TICKS}",
            opts.paced_ticks
        ))));
    }
    let (mut onnx, onnx_what, generated) = load_onnx(opts.policy.as_deref())?;
    let result = (|| {
        let inputs = onnx_inputs(&onnx);
        // Warm-up (the first runs allocate), as the Python baseline does: 20 ticks.
        for i in 0..20 {
            onnx.act(&named(&inputs), Stamp(i * onnx.period_ns()))
                .context("onnx act (warm-up)")?;
        }
        onnx.reset();
        let mut rows = Vec::new();
        let mut act_all = Vec::new();
        let mut act_inferred = Vec::new();
        for name in scenes() {
            let sp = scene_policy(&name)?;
            let (params, scene) = (&sp.params, &sp.scene);
            let period_s = 1.0 / params.control_rate_hz;
            let row = |what: &str, s: &Samples, inferred: bool| TickRow {
                transport: "embedded".into(),
                scene: scene.clone(),
                mode: params.mode.as_str().into(),
                what: what.into(),
                tick: tail(s.tick_s.clone()),
                inferred: inferred.then(|| tail(s.inferred_s.clone())),
                period: (s.starts_s.len() > 1).then(|| period_jitter(&s.starts_s, period_s)),
                phases: s.phases.clone(),
            };
            let plain = run_pass(&sp, opts.episodes, None, None)?;
            rows.push(row("controller", &plain, false));
            let with = run_pass(&sp, opts.episodes, None, Some((&mut onnx, &inputs)))?;
            rows.push(row("controller + onnx act", &with, true));
            act_all.extend(with.act_s.iter().copied());
            act_inferred.extend(with.act_inferred_s.iter().copied());
            if opts.paced_ticks > 1 {
                let paced = run_pass(&sp, 1, Some(opts.paced_ticks), Some((&mut onnx, &inputs)))?;
                rows.push(row("controller + onnx, paced", &paced, true));
            }
        }
        // The ONNX policy alone, every tick of the scenes above.
        let act_ticks = act_all.len();
        let ours = TickRow {
            transport: "embedded".into(),
            scene: "-".into(),
            mode: "-".into(),
            what: "onnx act".into(),
            tick: tail(act_all),
            inferred: Some(tail(act_inferred)),
            period: None,
            phases: Vec::new(),
        };
        rows.push(ours.clone());
        // And paced: the same work as the Python baseline's paced loop, just before it.
        if opts.paced_ticks > 1 {
            rows.push(paced_act(&mut onnx, &inputs, opts.paced_ticks)?);
        }
        let mut versions = String::new();
        let mut ratios = None;
        if opts.python {
            let dir = match (&generated, &opts.policy) {
                (Some(d), _) | (None, Some(d)) => d.clone(),
                (None, None) => bail!("no policy directory"),
            };
            let paced = if opts.paced_ticks > 1 {
                opts.paced_ticks
            } else {
                0
            };
            let (act, paced_row, v) = python_rows(&dir, act_ticks.max(1), paced)?;
            let inf = |r: &TickRow| r.inferred.map_or(f64::NAN, |t| t.p50_s);
            ratios = Some(Ratios {
                p50: act.tick.p50_s / ours.tick.p50_s.max(1e-12),
                p99: act.tick.p99_s / ours.tick.p99_s.max(1e-12),
                inferred_p50: inf(&act) / inf(&ours).max(1e-12),
            });
            rows.push(act);
            rows.extend(paced_row);
            versions = v;
        }
        Ok(PolicyBench {
            rows,
            onnx_policy: onnx_what.clone(),
            python_over_rust: ratios,
            python_versions: versions,
            note: "tick = GripperStatus into the chain until GripperCommand + ArmCommand + \
                   PolicyStatus are out (observation, watchdog, controller, safety layer), with \
                   the ONNX policy's act in the same tick where named; inputs scripted from a sim \
                   task world (training cups: the unseen 90 mm cup does not pass between fingers bounded to \
                   85 mm; two fabrics); one core; paced: unitac_core::Pacer in \
                   real time at the scene's control rate"
                .into(),
        })
    })();
    if let Some(d) = generated {
        std::fs::remove_dir_all(d).ok();
    }
    result
}

impl PolicyBench {
    pub fn text(&self) -> String {
        let mut s = format!(
            "policy tick, observation -> command, at the scenes' control rate (30 Hz); ONNX \
             policy: {}\n",
            self.onnx_policy
        );
        s += &TickRow::header();
        for r in &self.rows {
            s += &r.line();
        }
        if let Some(r) = self.python_over_rust {
            s += &format!(
                "onnx act, Python ({}) over unitac: p50 {:.1}x, p99 {:.1}x, inferring ticks p50 \
                 {:.1}x\n",
                self.python_versions, r.p50, r.p99, r.inferred_p50
            );
        }
        s += &format!("{}\n", self.note);
        s
    }
}
