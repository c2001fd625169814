//! Live sensors (V4L2, by serial): only with the `v4l` feature, so a crate that builds stages
//! from scenes (the closed-loop trials) need not link the camera driver.

use unitac_core::Source;

/// Root of the sysfs tree live sensors are discovered in (`/` unless `UNITAC_SYSFS_ROOT` says
/// otherwise, e.g. a fixture tree in tests).
fn sysfs_root() -> std::path::PathBuf {
    std::env::var_os("UNITAC_SYSFS_ROOT")
        .map(std::path::PathBuf::from)
        .unwrap_or_else(|| "/".into())
}

/// A live GelSight Mini or DIGIT of kind `want` by serial (or the only one of that kind on the
/// bus). Per-serial calibration files are read from `UNITAC_CALIBRATION_DIR` when set. Errors
/// are one line and name the field they come from (`source.serial`, `source.sensor`).
pub fn open_v4l(
    want: unitac_core::SensorKind,
    serial: Option<&str>,
) -> Result<Box<dyn Source>, (&'static str, String)> {
    let root = sysfs_root();
    let name = serial
        .map(|s| format!("v4l:{s}"))
        .unwrap_or_else(|| "v4l".into());
    let found = unitac_driver::discover::discover(&root).map_err(|e| {
        (
            "source.serial",
            format!("{name}: cannot look for sensors: {e}"),
        )
    })?;
    let serial = match serial {
        Some(s) => s.to_string(),
        None => {
            let of_kind: Vec<&str> = found
                .sensors
                .iter()
                .filter(|s| s.kind == want)
                .map(|s| s.serial.as_str())
                .collect();
            match of_kind.as_slice() {
                [one] => one.to_string(),
                [] => {
                    return Err((
                        "source.serial",
                        format!(
                            "no {want} sensor found (`unitac devices` lists what is connected)"
                        ),
                    ));
                }
                many => {
                    return Err((
                        "source.serial",
                        format!(
                            "{} {want} sensors found ({}): name one with --sensor v4l:<serial>",
                            many.len(),
                            many.join(", ")
                        ),
                    ));
                }
            }
        }
    };
    if let Some(s) = found.sensors.iter().find(|s| s.serial == serial) {
        if s.kind != want {
            return Err((
                "source.sensor",
                format!(
                    "the scene is for a {want} but {serial} is a {}; use a scene for that sensor",
                    s.kind
                ),
            ));
        }
    }
    let cal_dir = std::env::var_os("UNITAC_CALIBRATION_DIR").map(std::path::PathBuf::from);
    let stream = unitac_driver::open_v4l(&root, &serial, cal_dir.as_deref())
        .map_err(|e| ("source.serial", format!("v4l:{serial}: {e}")))?;
    Ok(Box::new(stream))
}
