//! The gripper's own reading as a policy input: what makes a GripperStatus unusable.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod rig;
use rig::*;

#[test]
fn the_policy_does_not_act_on_an_opening_outside_the_stroke() {
    // A Robotiq's gPO above the calibrated fully-closed count reads as a negative opening; the
    // stage holds with the reason instead of closing further on it.
    let mut rig = Rig::new(params(
        "{mode: vtla_pred, task: squeeze the cup by 1 cm, objects: [cup], latent_len: 4, \
         visual_names: [cup_x_m, cup_y_m, cup_width_m]}",
    ));
    let l = rig.latent(unitac_core::msg::LatentSource::Predicted, vec![0.5; 4]);
    rig.send(l);
    let camera = |rig: &Rig| {
        unitac_core::msg::Msg::VisualObservation(unitac_core::msg::VisualObservation {
            header: rig.header(),
            names: vec!["cup_x_m".into(), "cup_y_m".into(), "cup_width_m".into()],
            values: vec![0.45, 0.0, 0.08],
        })
    };
    rig.send(camera(&rig));
    assert!(rig.tick().status.safety_ok);
    rig.opening = -0.00112;
    rig.send(camera(&rig));
    let t = rig.tick();
    assert!(!t.status.safety_ok, "{:?}", t.status);
    assert!(
        t.status
            .message
            .contains("gripper: invalid (opening -0.00112 m outside the stroke [0, 0.14] m)"),
        "{}",
        t.status.message
    );
    assert!(t.cmd.position_m >= 0.0, "{:?}", t.cmd);
}
