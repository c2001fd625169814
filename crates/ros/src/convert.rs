//! Conversions between `unitac-core` messages and the generated `unitac_msgs` types.
//! Field names match one to one (msg/unitac_msgs is the source of truth for units).

use r2r::builtin_interfaces::msg::Time;
use r2r::std_msgs::msg::Header as RosHeader;
use r2r::unitac_msgs::msg as ros;
use unitac_core::Stamp;
use unitac_core::msg::{
    ContactEpisode, ContactState, GripperCommand, GripperMode, Header, LatentSource, PolicyStatus,
    PropertyComparison, TactileLatent, TactileProperties, Winner,
};

pub fn time(t: Stamp) -> Time {
    let (sec, nanosec) = t.to_sec_nanosec();
    Time { sec, nanosec }
}
pub fn stamp(t: &Time) -> Stamp {
    Stamp::from_sec_nanosec(t.sec, t.nanosec)
}
pub fn header(h: &Header) -> RosHeader {
    RosHeader {
        stamp: time(h.stamp),
        frame_id: h.frame_id.clone(),
    }
}
pub fn header_from(h: &RosHeader) -> Header {
    Header {
        stamp: stamp(&h.stamp),
        frame_id: h.frame_id.clone(),
    }
}

/// Fixed-size ROS arrays arrive as Vec; take exactly N or fail.
fn fixed<T: Copy + Default, const N: usize>(v: &[T], field: &str) -> Result<[T; N], String> {
    <[T; N]>::try_from(v).map_err(|_| format!("{field}: expected {N} elements, got {}", v.len()))
}

pub fn contact_state(m: &ContactState) -> ros::ContactState {
    ros::ContactState {
        header: header(&m.header),
        sensor_id: m.sensor_id.clone(),
        frame_seq: m.frame_seq,
        in_contact: m.in_contact,
        area_px: m.area_px,
        area_mm2: m.area_mm2,
        centroid_px: m.centroid_px.to_vec(),
        bbox_px: m.bbox_px.to_vec(),
        strength: m.strength,
        episode_id: m.episode_id,
        background_age_s: m.background_age_s,
    }
}

pub fn contact_state_from(m: &ros::ContactState) -> Result<ContactState, String> {
    Ok(ContactState {
        header: header_from(&m.header),
        sensor_id: m.sensor_id.clone(),
        frame_seq: m.frame_seq,
        in_contact: m.in_contact,
        area_px: m.area_px,
        area_mm2: m.area_mm2,
        centroid_px: fixed(&m.centroid_px, "centroid_px")?,
        bbox_px: fixed(&m.bbox_px, "bbox_px")?,
        strength: m.strength,
        episode_id: m.episode_id,
        background_age_s: m.background_age_s,
    })
}

pub fn contact_episode(m: &ContactEpisode) -> ros::ContactEpisode {
    ros::ContactEpisode {
        header: header(&m.header),
        sensor_id: m.sensor_id.clone(),
        episode_id: m.episode_id,
        start: time(m.start),
        end: time(m.end),
        frame_count: m.frame_count,
        peak_area_px: m.peak_area_px,
        peak_area_mm2: m.peak_area_mm2,
        peak_frame_seq: m.peak_frame_seq,
        label: m.label.clone(),
    }
}

pub fn tactile_properties(m: &TactileProperties) -> ros::TactileProperties {
    ros::TactileProperties {
        header: header(&m.header),
        sensor_id: m.sensor_id.clone(),
        episode_id: m.episode_id,
        label: m.label.clone(),
        hardness: m.hardness,
        hardness_std: m.hardness_std,
        roughness: m.roughness,
        roughness_std: m.roughness_std,
        texture: m.texture,
        texture_std: m.texture_std,
        model_id: m.model_id.clone(),
    }
}

pub fn property_comparison(m: &PropertyComparison) -> ros::PropertyComparison {
    ros::PropertyComparison {
        header: header(&m.header),
        property: m.property.clone(),
        episode_a: m.episode_a,
        label_a: m.label_a.clone(),
        episode_b: m.episode_b,
        label_b: m.label_b.clone(),
        winner: m.winner as u8,
        score_a: m.score_a,
        score_b: m.score_b,
        margin: m.margin,
        confidence: m.confidence,
        sentence: m.sentence.clone(),
    }
}

pub fn tactile_latent_from(m: &ros::TactileLatent) -> Result<TactileLatent, String> {
    let source = match m.source {
        0 => LatentSource::Real,
        1 => LatentSource::Predicted,
        s => return Err(format!("source: unknown value {s}")),
    };
    let n: u64 = m.shape.iter().map(|&d| u64::from(d)).product();
    if n != m.data.len() as u64 {
        return Err(format!(
            "shape {:?} needs {n} values, data has {}",
            m.shape,
            m.data.len()
        ));
    }
    Ok(TactileLatent {
        header: header_from(&m.header),
        source,
        sensor_id: m.sensor_id.clone(),
        shape: m.shape.clone(),
        data: m.data.clone(),
        model_id: m.model_id.clone(),
        solver: m.solver.clone(),
        steps: m.steps,
        guidance: m.guidance,
        elapsed_s: m.elapsed_s,
        valid: m.valid,
        guard_report: m.guard_report.clone(),
    })
}

pub fn tactile_latent(m: &TactileLatent) -> ros::TactileLatent {
    ros::TactileLatent {
        header: header(&m.header),
        source: m.source as u8,
        sensor_id: m.sensor_id.clone(),
        shape: m.shape.clone(),
        data: m.data.clone(),
        model_id: m.model_id.clone(),
        solver: m.solver.clone(),
        steps: m.steps,
        guidance: m.guidance,
        elapsed_s: m.elapsed_s,
        valid: m.valid,
        guard_report: m.guard_report.clone(),
    }
}

pub fn gripper_command_from(m: &ros::GripperCommand) -> Result<GripperCommand, String> {
    let mode = match m.mode {
        0 => GripperMode::Position,
        1 => GripperMode::Force,
        2 => GripperMode::Stop,
        x => return Err(format!("mode: unknown value {x}")),
    };
    Ok(GripperCommand {
        header: header_from(&m.header),
        mode,
        position_m: m.position_m,
        speed_m_s: m.speed_m_s,
        force_n: m.force_n,
        reason: m.reason.clone(),
    })
}

pub fn policy_status(m: &PolicyStatus) -> ros::PolicyStatus {
    ros::PolicyStatus {
        header: header(&m.header),
        scene: m.scene.clone(),
        mode: m.mode.clone(),
        phase: m.phase.clone(),
        safety_ok: m.safety_ok,
        message: m.message.clone(),
    }
}

/// Winner from its wire value.
pub fn winner_from(v: u8) -> Option<Winner> {
    match v {
        0 => Some(Winner::A),
        1 => Some(Winner::B),
        2 => Some(Winner::Tie),
        _ => None,
    }
}
