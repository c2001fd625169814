//! Scripted inputs for the policy tests: a chain with the policy stage, fed GripperStatus ticks
//! at 30 Hz and whatever the script sends between them, through `unitac_core::chain`.
#![allow(dead_code, clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::msg::{
    ArmCommand, ContactState, GripperCommand, GripperMode, GripperStatus, Header, LatentSource,
    PolicyStatus, TactileLatent, samples,
};
use unitac_core::{Chain, Msg, Stamp};
use unitac_policy::{PolicyParams, PolicyStage};

pub const TICK_NS: i64 = 33_333_333;

/// What one tick produced.
#[derive(Debug, Clone)]
pub struct Tick {
    pub stamp: Stamp,
    pub cmd: GripperCommand,
    pub arm: ArmCommand,
    pub status: PolicyStatus,
}

pub fn params(yaml: &str) -> PolicyParams {
    serde_yaml::from_str(yaml).unwrap()
}

pub struct Rig {
    pub chain: Chain,
    pub now: i64,
    pub opening: f64,
    pub force_n: f64,
    pub object_detected: bool,
    pub motion: String,
    pub ticks: Vec<Tick>,
    /// A camera frame (names, values) sent before every tick, stamped then (None: none).
    pub camera: Option<(Vec<String>, Vec<f64>)>,
}

impl Rig {
    pub fn new(p: PolicyParams) -> Self {
        Self::with_stage(PolicyStage::new("test_scene", p).unwrap())
    }

    pub fn with_stage(stage: PolicyStage) -> Self {
        Self {
            chain: Chain::new(vec![Box::new(stage)]),
            now: 1_000_000_000,
            opening: 0.085,
            force_n: 0.0,
            object_detected: false,
            motion: "stopped".into(),
            ticks: Vec::new(),
            camera: None,
        }
    }

    /// Send the cup scenes' camera (an 80 mm cup at (0.45, 0)) before every tick.
    pub fn with_cup_camera(mut self) -> Self {
        self.camera = Some((
            vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
            vec![0.45, 0.0, 0.08],
        ));
        self
    }

    pub fn header(&self) -> Header {
        Header::new(Stamp(self.now), "gripper")
    }

    /// Send a non-tick input now.
    pub fn send(&mut self, m: Msg) {
        let out = self.chain.run(m);
        assert!(out.errors.is_empty(), "{:?}", out.errors);
        assert!(out.produced.is_empty(), "only GripperStatus ticks");
    }

    pub fn contact(&self, in_contact: bool, area_m2: f32) -> Msg {
        Msg::ContactState(ContactState {
            header: self.header(),
            in_contact,
            area_m2,
            ..samples::contact_state()
        })
    }

    pub fn latent(&self, source: LatentSource, data: Vec<f32>) -> Msg {
        Msg::TactileLatent(TactileLatent {
            header: self.header(),
            source,
            shape: vec![1, data.len() as u32],
            data,
            valid: true,
            guard_report: String::new(),
            object: String::new(),
            condition_sources: Vec::new(),
            condition_age_s: Vec::new(),
            ..samples::tactile_latent()
        })
    }

    /// One control tick: the GripperStatus now; returns what the stage sent.
    pub fn tick(&mut self) -> Tick {
        if let Some((names, values)) = self.camera.clone() {
            let m = Msg::VisualObservation(unitac_core::msg::VisualObservation {
                header: self.header(),
                names,
                values,
            });
            self.chain.run(m);
        }
        let g = GripperStatus {
            header: self.header(),
            opening_m: self.opening,
            target_m: f64::NAN,
            force_n: self.force_n,
            current_a: f64::NAN,
            object_detected: self.object_detected,
            activation: "active".into(),
            motion: self.motion.clone(),
            fault: String::new(),
        };
        let out = self.chain.run(Msg::GripperStatus(g));
        assert!(out.errors.is_empty(), "{:?}", out.errors);
        let [
            Msg::GripperCommand(cmd),
            Msg::ArmCommand(arm),
            Msg::PolicyStatus(status),
        ] = out.produced.as_slice()
        else {
            panic!("a tick gives command, arm, status: {:?}", out.produced);
        };
        let t = Tick {
            stamp: Stamp(self.now),
            cmd: cmd.clone(),
            arm: arm.clone(),
            status: status.clone(),
        };
        for v in [
            cmd.position_m,
            cmd.speed_m_s,
            cmd.force_n,
            arm.z_m,
            arm.lift_m,
        ] {
            assert!(v.is_finite(), "{t:?}");
        }
        self.ticks.push(t.clone());
        self.now += TICK_NS;
        t
    }

    /// Move the fingers one tick toward the last command at its speed (a plain gripper).
    pub fn follow(&mut self, cmd: &GripperCommand, stop_at: Option<f64>) {
        if cmd.mode == GripperMode::Stop {
            return;
        }
        let step = cmd.speed_m_s * TICK_NS as f64 * 1e-9;
        let mut target = cmd.position_m;
        if let Some(s) = stop_at {
            target = target.max(s);
        }
        let d = (target - self.opening).clamp(-step, step);
        self.opening += d;
        self.motion = if d.abs() > 1e-12 { "moving" } else { "stopped" }.into();
    }

    /// The comparison of the two fabric touches: A (episode 1) is rougher than B (episode 2).
    pub fn a_is_rougher(&self) -> Msg {
        Msg::PropertyComparison(unitac_core::msg::PropertyComparison {
            header: self.header(),
            property: "roughness".into(),
            episode_a: 1,
            label_a: "fabric_a".into(),
            episode_b: 2,
            label_b: "fabric_b".into(),
            winner: unitac_core::msg::Winner::A,
            score_a: 0.8,
            score_b: 0.2,
            margin: 0.6,
            confidence: 0.9,
            sentence: "A is rougher than B".into(),
        })
    }

    /// The phases in the order they first appeared.
    pub fn phases(&self) -> Vec<String> {
        let mut v: Vec<String> = Vec::new();
        for t in &self.ticks {
            if v.last() != Some(&t.status.phase) {
                v.push(t.status.phase.clone());
            }
        }
        v
    }
}
