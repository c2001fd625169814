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

/// Most frames a ContactClip may carry (the contact stage's clip_frames is far below this).
pub const MAX_CLIP_FRAMES: usize = 256;

pub fn contact_clip(m: &unitac_core::msg::EpisodeClip) -> ros::ContactClip {
    let last = m.frames.last();
    let mut header = RosHeader::default();
    if let Some(f) = last {
        header.stamp = time(f.stamp);
        header.frame_id = format!("{}_optical_frame", f.sensor_id);
    }
    ros::ContactClip {
        header,
        sensor_id: m.sensor_id.clone(),
        episode_id: m.episode_id,
        label: m.label.clone(),
        peak_index: u32::try_from(m.peak_index).unwrap_or(u32::MAX),
        frames: m.frames.iter().map(crate::image::from_frame).collect(),
        background: m
            .background
            .as_ref()
            .map(crate::image::from_frame)
            .unwrap_or_default(),
    }
}

/// A clip from the wire: frame count bounded, every image checked, peak index in range.
pub fn contact_clip_from(m: &ros::ContactClip) -> Result<unitac_core::msg::EpisodeClip, String> {
    if m.frames.is_empty() || m.frames.len() > MAX_CLIP_FRAMES {
        return Err(format!(
            "clip has {} frames (1..={MAX_CLIP_FRAMES})",
            m.frames.len()
        ));
    }
    let peak_index = m.peak_index as usize;
    if peak_index >= m.frames.len() {
        return Err(format!(
            "peak_index {peak_index} is outside the clip's {} frames",
            m.frames.len()
        ));
    }
    let frames = m
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| {
            crate::image::to_frame(f, &m.sensor_id, i as u64).map_err(|e| format!("frame {i}: {e}"))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let background = if m.background.width == 0 {
        None
    } else {
        Some(
            crate::image::to_frame(&m.background, &m.sensor_id, 0)
                .map_err(|e| format!("background: {e}"))?,
        )
    };
    Ok(unitac_core::msg::EpisodeClip {
        sensor_id: m.sensor_id.clone(),
        episode_id: m.episode_id,
        label: m.label.clone(),
        peak_index,
        frames,
        background,
    })
}
