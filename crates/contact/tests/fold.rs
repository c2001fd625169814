//! A fabric's folded edge on the gel: the contact detector finds the press cut off at the
//! fold's top, and the top of its bounding box follows where the fold crosses the gel.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::msg::ContactState;
use unitac_core::{Msg, SensorKind, Stamp};
use unitac_sim::{FoldEdge, MockConfig, MockSensor, Object, Scenario};

/// A fabric over the fingertip (as the task world's fabrics: radius 6 mm), its fold's top
/// `edge_mm` above the contact centre, layers `layer_mm` thick, pressed `depth_mm`: the
/// detector's state on the third pressed frame, the truth mask's top row and pixel count.
fn fold_press(
    edge_mm: f64,
    layer_mm: f64,
    depth_mm: f64,
    hardness: f64,
) -> (ContactState, usize, u32) {
    let kind = SensorKind::GELSIGHT_MINI;
    let sensor = MockSensor::new(MockConfig::new(kind, 5), Scenario::idle(1.0));
    let fabric = Object::new("fabric_a", 6.0, 0.03, 0.7)
        .with_hardness(hardness)
        .with_fold(FoldEdge { edge_mm, layer_mm });
    let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
    let (bg, _) = sensor.render_press(0, None, 0.0, 0.0);
    det.set_background_frame(&bg);
    let mut last = None;
    let mut truth = None;
    for i in 1..4u64 {
        let (mut f, g) = sensor.render_press(i, Some((&fabric, depth_mm)), 0.0, 0.0);
        f.stamp = Stamp(1_000_000_000 + i as i64 * 33_000_000);
        for m in det.step(&f).unwrap() {
            if let Msg::ContactState(c) = m {
                last = Some(c);
            }
        }
        truth = Some(g);
    }
    let g = truth.unwrap();
    let w = kind.spec().width as usize;
    let top = g.mask.iter().position(|&m| m).map_or(usize::MAX, |p| p / w);
    (last.unwrap(), top, g.contact_px)
}

#[test]
fn the_detected_contact_stops_at_the_fold_and_follows_it() {
    let spec = SensorKind::GELSIGHT_MINI.spec();
    let centre = f64::from(spec.height) / 2.0;
    let px_per_mm = 1.0 / spec.mm_per_px;
    for (depth, hardness) in [(0.3, 0.85), (0.6, 0.5), (0.83, 0.8)] {
        let mut tops = Vec::new();
        for edge_mm in [0.3, 0.7, 1.2] {
            let (c, truth_top, truth_px) = fold_press(edge_mm, 0.7, depth, hardness);
            assert!(c.in_contact, "d {depth} h {hardness} e {edge_mm}");
            // The box's top is the fold (within 2 px of the truth mask's top, which is at most
            // the rim's radius below the fold's row).
            let top = c.bbox_px[1] as usize;
            assert!(
                top.abs_diff(truth_top) <= 2,
                "d {depth} e {edge_mm}: {top} vs {truth_top}"
            );
            let fold_row = centre - edge_mm * px_per_mm;
            assert!(
                (top as f64 - fold_row).abs() <= 0.35 * px_per_mm + 2.0,
                "d {depth} e {edge_mm}: {top} vs the fold's row {fold_row}"
            );
            // The detected area is the cut disc's, within a third.
            let ratio = f64::from(c.area_px) / f64::from(truth_px);
            assert!(
                (0.67..=1.33).contains(&ratio),
                "d {depth} e {edge_mm}: {ratio}"
            );
            tops.push(top);
        }
        // A fold higher above the centre: the contact reaches higher.
        assert!(tops.windows(2).all(|w| w[1] < w[0]), "{tops:?}");
        // A fold far above the disc: the whole disc, its top as far above the centre as its
        // bottom is below.
        let (c, _, _) = fold_press(8.0, 0.7, depth, hardness);
        let (above, below) = (
            centre - f64::from(c.bbox_px[1]),
            f64::from(c.bbox_px[3]) - centre,
        );
        assert!(
            (above - below).abs() <= 4.0,
            "d {depth}: {above} vs {below}"
        );
    }
}
