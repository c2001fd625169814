//! The tactile reflex in the closed loop: the cup vtla_pred controller squeezes with the force
//! its (prior) stiffness gives, 3 N, too weak for a heavy cup once lifted. A small world here
//! closes the loop: fingers that follow the commands, a cup held by friction (it slides down
//! between the pads when twice the friction of the grip is below its weight, and is lost after
//! the pads' length), the marker slip stage's verdict (SlipState) and the contact state. Without
//! the reflex the cup slips out while lifting; with it the grip force rises, the lift waits, and
//! the cup is lifted.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::msg::{
    ContactState, GripperCommand, GripperMode, GripperStatus, Header, LatentSource, Msg,
    PolicyStatus, SlipState, TactileLatent, samples,
};
use unitac_core::{ManualClock, Stage, Stamp};
use unitac_policy::{PolicyParams, PolicyStage, ReflexCounters};

const P: i64 = 33_333_333;
const DIAMETER_M: f64 = 0.08;
/// The cup wall's stiffness across the grip \[N/m].
const WALL_N_PER_M: f64 = 500.0;
/// Friction coefficient pad / cup.
const MU: f64 = 0.8;
/// Cup mass \[kg]: 6.9 N, held by a grip of at least 4.3 N.
const MASS_KG: f64 = 0.7;
/// How far the cup may slide between the pads before it is lost \[m].
const PAD_M: f64 = 0.015;

/// The world the stage's commands act on.
#[derive(Debug, Default)]
struct World {
    opening_m: f64,
    /// How far the cup slid down between the pads \[m].
    slid_m: f64,
    dropped: bool,
    slipping: bool,
    /// Height of the cup's bottom above the table \[m].
    height_m: f64,
}

impl World {
    fn grip_n(&self) -> f64 {
        if self.dropped {
            return 0.0;
        }
        (WALL_N_PER_M * (DIAMETER_M - self.opening_m)).max(0.0)
    }

    /// One tick of the commands.
    fn step(&mut self, cmd: &GripperCommand, lift_m: f64) {
        if cmd.mode != GripperMode::Stop {
            let step = cmd.speed_m_s * P as f64 * 1e-9;
            let mut target = cmd.position_m;
            if cmd.mode == GripperMode::Force && !self.dropped {
                // Force mode: the fingers stop where the wall pushes back with the force.
                target = target.max(DIAMETER_M - cmd.force_n / WALL_N_PER_M);
            }
            self.opening_m += (target - self.opening_m).clamp(-step, step);
        }
        // Lifted: the weight hangs on the grip's friction; short of it, the fingers rise and
        // the cup stays, so it slides between the pads by what they rose.
        let weight = MASS_KG * 9.81;
        let holds = 2.0 * MU * self.grip_n() >= weight;
        let fingers_above = lift_m - (self.height_m + self.slid_m);
        self.slipping = false;
        if !self.dropped && fingers_above > 1e-12 {
            if holds {
                self.height_m = lift_m - self.slid_m;
            } else {
                self.slid_m += fingers_above;
                self.slipping = true;
                if self.slid_m > PAD_M {
                    self.dropped = true;
                    self.height_m = 0.0;
                }
            }
        }
    }

    fn touching(&self) -> bool {
        !self.dropped && self.opening_m <= DIAMETER_M
    }
}

struct Run {
    world: World,
    statuses: Vec<PolicyStatus>,
    commands: Vec<GripperCommand>,
    counters: ReflexCounters,
}

fn run(reflex: bool) -> Run {
    let p: PolicyParams = serde_yaml::from_str(&format!(
        "{{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m], reflex: {reflex}}}"
    ))
    .unwrap();
    let max_force = p.limits.max_force_n;
    let mut stage = PolicyStage::new("reflex", p).unwrap();
    let mut w = World {
        opening_m: 0.085,
        ..World::default()
    };
    let mut now = 1_000_000_000i64;
    let clock = ManualClock::new(Stamp(now));
    let header = |t: i64| Header::new(Stamp(t), "gripper");
    stage
        .process(
            &Msg::TactileLatent(TactileLatent {
                header: header(now),
                source: LatentSource::Predicted,
                shape: vec![1, 4],
                data: vec![0.5; 4],
                valid: true,
                guard_report: String::new(),
                object: String::new(),
                condition_sources: Vec::new(),
                condition_age_s: Vec::new(),
                ..samples::tactile_latent()
            }),
            &clock,
        )
        .unwrap();
    let (mut statuses, mut commands) = (Vec::new(), Vec::new());
    let mut lift = 0.0;
    for _ in 0..1500 {
        clock.set(Stamp(now));
        // What the contact and slip stages see this tick.
        let contact = ContactState {
            header: header(now),
            in_contact: w.touching(),
            area_m2: if w.touching() { 30e-6 } else { 0.0 },
            ..samples::contact_state()
        };
        let slip = SlipState {
            header: header(now),
            slip: w.slipping,
            slip_score: if w.slipping { 0.9 } else { 0.05 },
            valid: w.touching(),
            ..samples::slip_state()
        };
        stage.process(&Msg::ContactState(contact), &clock).unwrap();
        stage.process(&Msg::SlipState(slip), &clock).unwrap();
        let camera = Msg::VisualObservation(unitac_core::msg::VisualObservation {
            header: header(now),
            names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
            values: vec![0.45, 0.0, DIAMETER_M],
        });
        stage.process(&camera, &clock).unwrap();
        let g = GripperStatus {
            header: header(now),
            opening_m: w.opening_m,
            target_m: f64::NAN,
            force_n: w.grip_n(),
            current_a: f64::NAN,
            object_detected: w.grip_n() > 0.0,
            activation: "active".into(),
            motion: "stopped".into(),
            fault: String::new(),
        };
        let out = stage.process(&Msg::GripperStatus(g), &clock).unwrap();
        let [
            Msg::GripperCommand(c),
            Msg::ArmCommand(a),
            Msg::PolicyStatus(s),
        ] = out.as_slice()
        else {
            panic!("{out:?}");
        };
        assert!(c.force_n <= max_force && c.force_n.is_finite(), "{c:?}");
        lift = a.lift_m;
        w.step(c, lift);
        commands.push(c.clone());
        let done = s.phase == "done";
        statuses.push(s.clone());
        if done {
            break;
        }
        now += P;
    }
    assert_eq!(lift, 0.05, "the controller lifted to its height");
    Run {
        world: w,
        statuses,
        commands,
        counters: stage.reflex_counters(),
    }
}

#[test]
fn a_weak_grip_that_slips_without_the_reflex_holds_with_it() {
    let off = run(false);
    assert!(off.world.dropped, "without the reflex: {:?}", off.world);
    assert_eq!(off.counters, ReflexCounters::default());

    let on = run(true);
    assert!(!on.world.dropped, "with the reflex: {:?}", on.world);
    assert!(on.world.height_m > 0.03, "{:?}", on.world);
    assert!(on.world.slid_m < PAD_M, "{:?}", on.world);
    let c = on.counters;
    assert!(
        c.slip_ticks >= 1 && c.force_raises >= 1 && c.lift_stops_slip >= 1,
        "{c:?}"
    );
    // Every reflex action named in PolicyStatus, never a refusal.
    assert!(on.statuses.iter().all(|s| s.safety_ok));
    let named: Vec<&str> = on
        .statuses
        .iter()
        .filter(|s| s.message.starts_with("reflex: slip"))
        .map(|s| s.message.as_str())
        .collect();
    assert_eq!(named.len() as u64, c.slip_ticks, "{named:?}");
    assert!(
        named[0].contains("while lifting: grip force 3.0 -> 4.0 N")
            && named[0].contains("lift stopped at"),
        "{}",
        named[0]
    );
    // The raised force is kept to the end of the grasp.
    let last = on.commands.last().unwrap();
    assert!(last.force_n >= 4.3, "{last:?}");
    println!(
        "reflex off: cup {:?}; on: cup {:?}, counters {c:?}, first action: {}",
        off.world, on.world, named[0]
    );
}
