//! Contact episodes: hysteresis (enter / exit area) and debounce on the per-frame contact area,
//! episode ids, start/end stamps, the peak frame and a bounded clip of the episode's frames for
//! the encoder. Knows nothing about images beyond keeping the frames it is given.

use crate::params::ContactParams;
use std::collections::VecDeque;
use unitac_core::msg::{ContactClip, ContactEpisode, Header};
use unitac_core::{Frame, Msg, Stamp};

#[derive(Debug, Clone)]
struct Episode {
    id: u64,
    start: Stamp,
    last: Stamp,
    frames: u32,
    peak_area: f32,
    peak_seq: u64,
}

/// The episode state machine of one sensor.
#[derive(Debug)]
pub(crate) struct Episodes {
    in_contact: bool,
    streak: u32,
    next_episode: u64,
    episode: Option<Episode>,
    last_episode: u64,
    clip: VecDeque<Frame>,
    peak_frame: Option<Frame>,
}

impl Default for Episodes {
    fn default() -> Self {
        Self {
            in_contact: false,
            streak: 0,
            next_episode: 1,
            episode: None,
            last_episode: 0,
            clip: VecDeque::new(),
            peak_frame: None,
        }
    }
}

impl Episodes {
    pub fn in_contact(&self) -> bool {
        self.in_contact
    }

    /// Id of the latest episode (0 before the first).
    pub fn last_episode(&self) -> u64 {
        self.last_episode
    }

    /// Drop the open episode without emitting it (the background is learned again). Episode
    /// numbering goes on.
    pub fn reset(&mut self) {
        self.in_contact = false;
        self.streak = 0;
        self.episode = None;
        self.clip.clear();
        self.peak_frame = None;
    }

    /// One measured frame: returns whether this frame's area alone says "contact" (before
    /// debounce) and the messages of an episode that just ended. The enter and exit areas are
    /// multiplied by `area_scale` (frames larger than the parameters' reference size).
    /// `background` gives the non-contact frame for a clip; it is called only when a clip is
    /// emitted.
    #[allow(clippy::too_many_arguments)]
    pub fn update(
        &mut self,
        f: &Frame,
        area_px: f32,
        area_scale: f32,
        p: &ContactParams,
        m2_per_px: f64,
        background: impl FnOnce() -> Option<Frame>,
    ) -> (bool, Vec<Msg>) {
        let raw = if self.in_contact {
            area_px >= p.exit_area_px * area_scale
        } else {
            area_px >= p.enter_area_px * area_scale
        };
        let mut out = Vec::new();
        if raw != self.in_contact {
            self.streak += 1;
            let needed = if raw {
                p.debounce_frames
            } else {
                p.exit_debounce_frames
            };
            if self.streak >= needed.max(1) {
                self.streak = 0;
                self.in_contact = raw;
                if raw {
                    let id = self.next_episode;
                    self.next_episode += 1;
                    self.last_episode = id;
                    self.episode = Some(Episode {
                        id,
                        start: f.stamp,
                        last: f.stamp,
                        frames: 0,
                        peak_area: 0.0,
                        peak_seq: f.seq,
                    });
                    self.clip.clear();
                    self.peak_frame = None;
                } else {
                    out = self.close(&f.sensor_id, p, m2_per_px, background);
                }
            }
        } else {
            self.streak = 0;
        }
        if let (true, Some(ep)) = (self.in_contact, self.episode.as_mut()) {
            ep.frames += 1;
            ep.last = f.stamp;
            let cap = p.clip_frames as usize;
            if area_px > ep.peak_area {
                ep.peak_area = area_px;
                ep.peak_seq = f.seq;
                if cap > 0 {
                    self.peak_frame = Some(f.clone());
                }
            }
            if cap > 0 {
                if self.clip.len() == cap {
                    self.clip.pop_front();
                }
                self.clip.push_back(f.clone());
            }
        }
        (raw, out)
    }

    /// Close the open episode (release or end of input): its ContactEpisode and, with
    /// `clip_frames` > 0, its clip.
    pub fn close(
        &mut self,
        sensor_id: &str,
        p: &ContactParams,
        m2_per_px: f64,
        background: impl FnOnce() -> Option<Frame>,
    ) -> Vec<Msg> {
        self.in_contact = false;
        let Some(ep) = self.episode.take() else {
            return Vec::new();
        };
        let label = usize::try_from(ep.id.saturating_sub(1))
            .ok()
            .and_then(|i| p.episode_labels.get(i))
            .cloned()
            .unwrap_or_default();
        let mut out = vec![Msg::ContactEpisode(ContactEpisode {
            header: Header::optical(ep.last, sensor_id),
            sensor_id: sensor_id.to_string(),
            episode_id: ep.id,
            start: ep.start,
            end: ep.last,
            frame_count: ep.frames,
            peak_area_px: ep.peak_area,
            peak_area_m2: (f64::from(ep.peak_area) * m2_per_px) as f32,
            peak_frame_seq: ep.peak_seq,
            label: label.clone(),
        })];
        if p.clip_frames > 0 {
            if let Some(clip) = self.take_clip(sensor_id, &ep, label, p.clip_frames, background) {
                out.push(Msg::ContactClip(clip));
            }
        }
        out
    }

    /// Up to `cap` frames centred on the peak: the peak frame plus the kept frames around it (if
    /// the peak is older than the kept window, the peak frame then the latest frames).
    fn take_clip(
        &mut self,
        sensor_id: &str,
        ep: &Episode,
        label: String,
        cap: u32,
        background: impl FnOnce() -> Option<Frame>,
    ) -> Option<ContactClip> {
        let peak = self.peak_frame.take()?;
        let cap = cap as usize;
        let mut frames: Vec<Frame> = self.clip.drain(..).collect();
        let peak_index = match frames.iter().position(|f| f.seq == peak.seq) {
            Some(i) => {
                let start = i
                    .saturating_sub(cap / 2)
                    .min(frames.len().saturating_sub(cap));
                frames = frames.into_iter().skip(start).take(cap).collect();
                i - start
            }
            None => {
                frames.insert(0, peak);
                frames.truncate(cap);
                0
            }
        };
        Some(ContactClip {
            sensor_id: sensor_id.to_string(),
            episode_id: ep.id,
            label,
            peak_index,
            frames,
            background: background(),
        })
    }
}
