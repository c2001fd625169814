//! One value of every generated message, every field set to something other than its default,
//! for the codec and conversion tests of crates/bag and crates/ros (they round-trip each message
//! through `for_each_message!`, so a new message without a sample here does not compile there).
//! The function names are the messages' snake-case names, as in `for_each_message!`.

use super::*;

fn header() -> Header {
    Header::new(Stamp(1_700_000_000_123_456_789), "gs_optical_frame")
}

pub fn contact_state() -> ContactState {
    ContactState {
        header: header(),
        sensor_id: "gs".into(),
        frame_seq: 5,
        in_contact: true,
        area_px: 1.5,
        area_m2: 0.25e-6,
        centroid_px: [3.0, 4.0],
        bbox_px: [1, 2, 3, 4],
        strength: 0.5,
        episode_id: 2,
        background_age_s: 1.25,
    }
}

pub fn contact_episode() -> ContactEpisode {
    ContactEpisode {
        header: header(),
        sensor_id: "gs".into(),
        episode_id: 3,
        start: Stamp(5),
        end: Stamp(1_000_000_007),
        frame_count: 9,
        peak_area_px: 10.5,
        peak_area_m2: 0.5e-6,
        peak_frame_seq: 4,
        label: "fabric_a".into(),
    }
}

pub fn tactile_properties() -> TactileProperties {
    TactileProperties {
        header: header(),
        sensor_id: "gs".into(),
        episode_id: 3,
        label: "cup".into(),
        hardness: 0.1,
        hardness_std: 0.2,
        roughness: 0.3,
        roughness_std: 0.4,
        texture: 0.5,
        texture_std: 0.6,
        model_id: "m@12ab".into(),
    }
}

pub fn property_comparison() -> PropertyComparison {
    PropertyComparison {
        header: header(),
        property: "roughness".into(),
        episode_a: 1,
        label_a: "a".into(),
        episode_b: 2,
        label_b: "b".into(),
        winner: Winner::Tie,
        score_a: 0.5,
        score_b: 0.5,
        margin: 0.0,
        confidence: 0.5,
        sentence: "A and B are as rough".into(),
    }
}

pub fn tactile_latent() -> TactileLatent {
    TactileLatent {
        header: header(),
        source: LatentSource::Predicted,
        sensor_id: "gs".into(),
        shape: vec![2, 3],
        data: vec![0.5, -1.0, 2.25, 3.0, -0.125, 8.0],
        model_id: "m".into(),
        solver: "heun".into(),
        steps: 8,
        guidance: 1.5,
        elapsed_s: 0.01,
        valid: true,
        guard_report: "ok".into(),
        object: String::new(),
        condition_sources: Vec::new(),
        condition_age_s: Vec::new(),
    }
}

pub fn gripper_command() -> GripperCommand {
    GripperCommand {
        header: header(),
        mode: GripperMode::Force,
        position_m: 0.02,
        speed_m_s: 0.05,
        force_n: 4.5,
        reason: "press".into(),
    }
}

pub fn policy_status() -> PolicyStatus {
    PolicyStatus {
        header: header(),
        scene: "cup_deformation".into(),
        mode: "vtla_real".into(),
        phase: "press".into(),
        safety_ok: true,
        message: "force limit".into(),
        clamped: vec!["gripper.force_n".into()],
    }
}

pub fn gripper_status() -> GripperStatus {
    GripperStatus {
        header: header(),
        opening_m: 0.0425,
        target_m: 0.03,
        force_n: 6.5,
        current_a: 0.25,
        object_detected: true,
        activation: "active".into(),
        motion: "stopped".into(),
        fault: "overtemp".into(),
    }
}

pub fn arm_command() -> ArmCommand {
    ArmCommand {
        header: header(),
        target: "fabric_b".into(),
        x_m: 0.45,
        y_m: -0.125,
        z_m: 0.004,
        lift_m: 0.05,
        reason: "grasp the smoother".into(),
    }
}

pub fn visual_observation() -> VisualObservation {
    VisualObservation {
        header: header(),
        names: vec!["cup_width_m".into(), "cup_x_m".into()],
        values: vec![0.081, -0.125],
    }
}

pub fn slip_state() -> SlipState {
    SlipState {
        header: header(),
        sensor_id: "gs".into(),
        shear_x_m: 1.5e-4,
        shear_y_m: -2.5e-4,
        rotation_rad: 0.03,
        residual_px: 0.4,
        slip_score: 0.2,
        slip: true,
        markers_tracked: 11,
        valid: true,
    }
}
