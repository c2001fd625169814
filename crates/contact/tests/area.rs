//! Areas in m^2 follow the frame size: a sensor's mm per pixel is for its published size
//! (320x240), and the same gel streamed at 640x480 has half the mm per pixel.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::msg::{ContactEpisode, ContactState};
use unitac_core::{Msg, SensorKind, Stamp};
use unitac_sim::degrade::{Degrade, press_fixture};
use unitac_sim::{MockConfig, Object, Scenario};

/// The medium press of the fixtures at `scale` x the spec's size: the contact states of three
/// pressed frames, then the episode of the release.
fn press(kind: SensorKind, scale: u32) -> (Vec<ContactState>, ContactEpisode, f64) {
    let spec = kind.spec().scaled(scale);
    let cfg = MockConfig::new(kind, 7);
    let d = Degrade {
        shading_dn: 0.0,
        noise_dn: 1.0,
        shift: (0, 0),
        seed: 3,
    };
    let scenario = Scenario::held(&Object::sphere("p", 6.0), 0.4, 1.0);
    let fx = press_fixture(&cfg, spec, &scenario, "p", d).unwrap();
    // Built with the sensor's spec as the pipeline builds it (its published 320x240).
    let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    det.set_background_frame(&fx.background);
    let mut states = Vec::new();
    let mut episode = None;
    for i in 0..8i64 {
        let mut f = if i < 4 {
            fx.frame.clone()
        } else {
            fx.background.clone()
        };
        f.stamp = Stamp(1_000_000_000 + i * 40_000_000);
        for m in det.step(&f).unwrap() {
            match m {
                Msg::ContactState(c) if c.in_contact || i < 4 => states.push(c),
                Msg::ContactEpisode(e) => episode = Some(e),
                _ => {}
            }
        }
    }
    // The true contact disc in m^2.
    let m_per_px = kind.spec().m_per_px() / f64::from(scale);
    let truth_m2 = f64::from(fx.contact_px) * m_per_px * m_per_px;
    (states, episode.expect("an episode on release"), truth_m2)
}

#[test]
fn area_in_m2_follows_the_frame_size() {
    for kind in [SensorKind::GELSIGHT_MINI, SensorKind::DIGIT] {
        for scale in [1, 2] {
            let (states, ep, truth_m2) = press(kind, scale);
            let m_per_px = kind.spec().m_per_px() / f64::from(scale);
            let last = states.iter().rfind(|c| c.area_px > 0.0).unwrap();
            let per_px = f64::from(last.area_m2) / f64::from(last.area_px);
            assert!(
                (per_px / (m_per_px * m_per_px) - 1.0).abs() < 1e-4,
                "{kind} x{scale}: {per_px} m^2 per px, expected {}",
                m_per_px * m_per_px
            );
            // The same press reads the same physical area at either size.
            let ratio = f64::from(last.area_m2) / truth_m2;
            assert!(
                (1.0 / 1.5..=1.5).contains(&ratio),
                "{kind} x{scale}: {} m^2 against the true {truth_m2:e} m^2",
                last.area_m2
            );
            let peak = states.iter().map(|c| c.area_m2).fold(0.0f32, f32::max);
            assert!(
                (ep.peak_area_m2 / peak - 1.0).abs() < 1e-3,
                "{kind} x{scale}: episode peak {} m^2, states' peak {peak}",
                ep.peak_area_m2
            );
        }
    }
}
