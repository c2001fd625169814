//! Write mock frames as PNG: `cargo run -p unitac-sim --example frames -- SCENARIO SENSOR T_S... `
//! (files go to the current directory as `<scenario>_<sensor>_<t>.png`).
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use unitac_core::SensorKind;
use unitac_sim::{MockConfig, MockSensor, Scenario};

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let scenario = Scenario::by_name(&args[0]).unwrap();
    let kind: SensorKind = args[1].parse().unwrap();
    let s = MockSensor::new(MockConfig::new(kind, 1), scenario.clone());
    for t in &args[2..] {
        let ts: f64 = t.parse().unwrap();
        let (f, truth) = s.render((ts * s.config().fps).round() as u64);
        let name = format!("{}_{}_{}.png", args[0], args[1], t);
        image::save_buffer(&name, f.data(), f.width, f.height, image::ColorType::Rgb8).unwrap();
        println!(
            "{name}: {} penetration {:.3} mm, {} contact px",
            truth.label, truth.penetration_mm, truth.contact_px
        );
    }
}
