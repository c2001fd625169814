//! The fixtures: presses under smooth shading (0-40 DN) and camera noise (1-8 DN per
//! channel), light, medium, large and near the border, on GelSight Mini and DIGIT at 320x240 and
//! 640x480, each against a single background frame (as `unitac contact` runs). Plus the same
//! shading and noise with no press at all.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::SensorKind;
use unitac_sim::degrade::{Degrade, idle_fixture, press_fixture};
use unitac_sim::{MockConfig, Object, Scenario};

/// (shading DN, noise DN) pairs: clean, strong shading, both moderate, both at the maximum.
const CONDITIONS: [(f64, f64); 4] = [(0.0, 1.0), (40.0, 1.0), (20.0, 4.0), (40.0, 8.0)];

/// (name, object, depth mm, shift in 320x240 px; multiples of the 24 px marker spacing).
fn presses() -> Vec<(&'static str, Object, f64, (i32, i32))> {
    vec![
        ("light", Object::sphere("p", 4.0), 0.1, (0, 0)),
        ("medium", Object::sphere("p", 6.0), 0.4, (48, -24)),
        ("large", Object::sphere("p", 12.0), 1.0, (0, 0)),
        ("border", Object::sphere("p", 6.0), 0.4, (-120, 72)),
    ]
}

#[derive(Default, Debug)]
struct Tally {
    presses: usize,
    found: usize,
    /// Centroid within 0.3 radius of the true contact.
    centred: usize,
    /// Area within a factor 1.5 of the true contact disc (DIGIT's large press included: its
    /// contact covers 60 % of the gel, a 121 px radius disc on a 320x240 frame).
    sized: usize,
    idle: usize,
    false_contacts: usize,
    failures: Vec<String>,
}

/// Mean residual of the detector's last frame in rings around the true centroid, in units of the
/// true contact radius (inner edges in `RINGS`), as "mean/cells" per ring.
const RINGS: [f64; 9] = [0.0, 0.25, 0.5, 0.75, 1.0, 1.25, 1.5, 2.0, 2.5];

fn profile(det: &ContactDetector, centre: [f64; 2], radius: f64) -> String {
    let Some((g, resid)) = det.residual_cells() else {
        return String::new();
    };
    let mut sum = [(0f64, 0u32); RINGS.len()];
    let st = f64::from(g.stride);
    for (i, &r) in resid.iter().enumerate() {
        let (x, y) = (
            (i % g.gw) as f64 * st + (st - 1.0) / 2.0,
            (i / g.gw) as f64 * st + (st - 1.0) / 2.0,
        );
        let d = (x - centre[0]).hypot(y - centre[1]) / radius;
        if let Some(k) = RINGS.iter().rposition(|&e| d >= e) {
            if k + 1 < RINGS.len() {
                sum[k].0 += f64::from(r);
                sum[k].1 += 1;
            }
        }
    }
    let rings: Vec<String> = sum[..RINGS.len() - 1]
        .iter()
        .zip(RINGS)
        .map(|(&(s, n), e)| format!("{e:.2}r:{:.1}", s / f64::from(n.max(1))))
        .collect();
    rings.join(" ")
}

fn check(kind: SensorKind, scale: u32, profile_of: SensorKind, t: &mut Tally) {
    let profile_kind = profile_of;
    let spec = kind.spec().scaled(scale);
    let cfg = MockConfig::new(kind, 40 + u64::from(scale));
    for (ci, &(shading_dn, noise_dn)) in CONDITIONS.iter().enumerate() {
        let seed = 1000 * u64::from(scale) + ci as u64;
        for (name, obj, depth, (dx, dy)) in presses() {
            let d = Degrade {
                shading_dn,
                noise_dn,
                shift: (dx * scale as i32, dy * scale as i32),
                seed,
            };
            let fx = press_fixture(&cfg, spec, &Scenario::held(&obj, depth, 1.0), "p", d).unwrap();
            let mut det =
                ContactDetector::new(ContactParams::default(), profile_kind.spec()).unwrap();
            det.set_background_frame(&fx.background);
            let m = det.measure(&fx.frame).unwrap();
            t.presses += 1;
            let err = f64::from(m.centroid[0] - fx.centroid[0] as f32)
                .hypot(f64::from(m.centroid[1] - fx.centroid[1] as f32));
            let ratio = f64::from(m.area_px) / f64::from(fx.contact_px);
            let label = format!(
                "{kind} {}x{} as {profile_kind}, shading {shading_dn} noise {noise_dn}, {name}: \
                 contact {} area {:.0} vs {} (x{ratio:.2}), centroid off {:.2} r, noise {:?}, \
                 smoothing {}, shading fit left out {:.2}",
                spec.width,
                spec.height,
                m.contact,
                m.area_px,
                fx.contact_px,
                err / fx.radius_px,
                m.noise,
                m.smoothing,
                m.rejected
            );
            println!("{label}");
            println!(
                "    residual by ring (threshold {:.1}): {}",
                m.threshold,
                profile(&det, fx.centroid, fx.radius_px)
            );
            if !m.contact {
                t.failures.push(label);
                continue;
            }
            t.found += 1;
            let centred = err <= 0.3 * fx.radius_px;
            let sized = (1.0 / 1.5..=1.5).contains(&ratio);
            t.centred += usize::from(centred);
            t.sized += usize::from(sized);
            if !(centred && sized) {
                t.failures.push(label);
            }
        }
        let d = Degrade {
            shading_dn,
            noise_dn,
            shift: (0, 0),
            seed: seed + 77,
        };
        let (bg, frame) = idle_fixture(&cfg, spec, d).unwrap();
        let mut det = ContactDetector::new(ContactParams::default(), profile_kind.spec()).unwrap();
        det.set_background_frame(&bg);
        let m = det.measure(&frame).unwrap();
        t.idle += 1;
        if m.contact {
            t.false_contacts += 1;
            t.failures.push(format!(
                "{kind} {}x{} idle shading {shading_dn} noise {noise_dn}: {m:?}",
                spec.width, spec.height
            ));
        }
    }
}

/// The goal, for one sensor at one size: no false contact, every press found, centroid
/// within 0.3 r and area within x1.5 of the true disc each on >= 95 % of the presses.
fn assert_tally(t: &Tally) {
    assert_eq!(t.false_contacts, 0, "false contacts: {:#?}", t.failures);
    assert_eq!(t.found, t.presses, "missed presses: {:#?}", t.failures);
    assert!(
        t.centred as f64 >= 0.95 * t.presses as f64,
        "centred {} of {}: {:#?}",
        t.centred,
        t.presses,
        t.failures
    );
    assert!(
        t.sized as f64 >= 0.95 * t.presses as f64,
        "area within x1.5 on {} of {}: {:#?}",
        t.sized,
        t.presses,
        t.failures
    );
}

/// One sensor (with a profile) at both sizes, each size held to the goal on its own.
fn check_sizes(kind: SensorKind, profile_of: SensorKind) {
    let tallies: Vec<Tally> = [1, 2]
        .into_iter()
        .map(|scale| {
            let mut t = Tally::default();
            check(kind, scale, profile_of, &mut t);
            t
        })
        .collect();
    for (scale, t) in [1, 2].into_iter().zip(&tallies) {
        println!(
            "{kind} x{scale} as {profile_of}: found {}/{}, centred {}, area within x1.5 {}/{}, \
             false contacts {}/{}",
            t.found, t.presses, t.centred, t.sized, t.presses, t.false_contacts, t.idle
        );
    }
    tallies.iter().for_each(assert_tally);
}

#[test]
fn gelsight_mini_presses_under_shading_and_noise() {
    check_sizes(SensorKind::GELSIGHT_MINI, SensorKind::GELSIGHT_MINI);
}

#[test]
fn digit_presses_under_shading_and_noise() {
    check_sizes(SensorKind::DIGIT, SensorKind::DIGIT);
}

/// An unprofiled GelSight-type sensor: the generic profile on GelSight Mini frames.
#[test]
fn generic_profile_on_gelsight_frames_at_both_sizes() {
    check_sizes(SensorKind::GELSIGHT_MINI, SensorKind::GENERIC);
}
