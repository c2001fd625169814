//! The mock gel the depth commands press balls into: `calibrate mock-presses` (presses to try a
//! calibration on), and the lab's `eval depth` and `bench depth` (a calibration from mock presses,
//! then depth against their truth).

use unitac_core::SensorKind;
use unitac_sim::MockConfig;

/// A mock `sensor` without markers (calibration gels are marker-free; gs_sdk's calibration does
/// the same), seed 11.
pub fn calibration_gel(sensor: SensorKind) -> MockConfig {
    let mut c = MockConfig::new(sensor, 11);
    c.markers = false;
    c
}
