//! Gel depth on the command line: `calibrate depth` (a sensor's photometric calibration from
//! ball presses, with review PNGs and corrected circles), `calibrate mock-presses` (presses to
//! try it on), and `contact --depth-calibration` / `--overlay` (the depth and the overlay
//! picture per frame). The lab's `eval depth` and `bench depth` are in crates/lab.

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};
use unitac_contact::depth::{Circle, DepthCalibration, Fit, Prep, Terms, find_circle, prepare};
use unitac_core::{Frame, SensorKind};
use unitac_sim::MM_PER_M;
use unitac_sim::ballpress::{PressNoise, random_presses, render_presses};

use crate::images::{distinct_names, output_files, read_frame};
use unitac_cli::args::{f64_in, int_in, usage};
use unitac_cli::mock::calibration_gel;

/// Most press images one calibration reads.
const MAX_PRESSES: usize = 500;
/// Ball radii `calibrate depth` takes \[m].
const BALL_RADIUS_M: (f64, f64) = (1e-4, 0.1);
/// Ball radii `calibrate mock-presses` renders \[m]: the largest one's contact disc at a 1 mm
/// approach still fits the mock sensor's frame.
const MOCK_BALL_RADIUS_M: (f64, f64) = (5e-4, 0.01);
/// Gel-surface metres per pixel `calibrate depth --m-per-px` takes.
const M_PER_PX: (f64, f64) = (1e-6, 1e-3);

/// `unitac calibrate ...`
#[derive(clap::Subcommand, Debug)]
pub enum CalibrateCmd {
    /// Fit a sensor's depth calibration from presses of a ball of known radius: finds each
    /// press's contact circle (review PNGs and circles.json in --review; correct circles there
    /// and pass the file back with --circles), fits colour + position -> gel slope, and writes
    /// the calibration file (sensor, serial, image size, metres per pixel).
    Depth(CalibrateDepthArgs),
    /// Write mock ball presses (PNG) and a background to try `calibrate depth` on, with their
    /// truth (truth.json: centre, ball radius, approach per press).
    MockPresses(MockPressesArgs),
}

#[derive(clap::Args, Debug)]
pub struct CalibrateDepthArgs {
    /// Sensor kind: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS.
    #[arg(long)]
    sensor: SensorKind,
    /// Radius of the ball pressed into the gel, in m (a 4 mm ball: 0.002).
    #[arg(long, value_parser = f64_in(BALL_RADIUS_M.0, BALL_RADIUS_M.1))]
    ball_radius_m: f64,
    /// Image of the gel without contact (same size as the presses).
    #[arg(long)]
    background: PathBuf,
    /// Press images (PNG or JPEG): 30-50 presses all over the gel, none touching the border.
    #[arg(required = true)]
    presses: Vec<PathBuf>,
    /// The calibration file to write.
    #[arg(long)]
    out: PathBuf,
    /// The sensor's serial (a calibration is refused for frames of another serial).
    #[arg(long, default_value = "")]
    serial: String,
    /// Gel-surface metres per pixel at the images' size (default: the sensor kind's, scaled to
    /// the images' width). Measure it with a ruler pressed on the gel for a real sensor.
    #[arg(long, value_parser = f64_in(M_PER_PX.0, M_PER_PX.1))]
    m_per_px: Option<f64>,
    /// Circles to use instead of the ones found: the circles.json that --review wrote, edited
    /// (x, y, r in pixels per file; "skip": true leaves a press out). Each circle's centre lies
    /// in the image and its radius is at most half the image's shorter side.
    #[arg(long)]
    circles: Option<PathBuf>,
    /// Directory for one PNG per press with its circle drawn, and circles.json.
    #[arg(long)]
    review: Option<PathBuf>,
    /// Fit the colour change's three linear terms alone (no position or products): a model
    /// that carries to other units of the kind, for a sensor profile's `photometric` (printed
    /// as the profile's line).
    #[arg(long)]
    linear: bool,
}

#[derive(clap::Args, Debug)]
pub struct MockPressesArgs {
    /// Sensor kind: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS (the frames' size and mm per pixel).
    #[arg(long, default_value = "gelsight-mini")]
    sensor: SensorKind,
    /// Radius of the pressed ball, in m.
    #[arg(long, default_value_t = 0.002,
          value_parser = f64_in(MOCK_BALL_RADIUS_M.0, MOCK_BALL_RADIUS_M.1))]
    ball_radius_m: f64,
    /// Presses to write.
    #[arg(long, default_value_t = 40, value_parser = int_in(1usize, MAX_PRESSES))]
    count: usize,
    /// Camera noise per channel, in DN (digital numbers, 0-255 per channel).
    #[arg(long, default_value_t = 1.0, value_parser = f64_in(0.0, 64.0))]
    noise_dn: f64,
    /// Smooth shading on each press, in DN summed over the channels.
    #[arg(long, default_value_t = 0.0, value_parser = f64_in(0.0, 255.0))]
    shading_dn: f64,
    /// Seed of the presses' places, depths and noise.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Directory for the presses, background.png and truth.json (created if missing).
    #[arg(long)]
    out: PathBuf,
}

/// One press's circle in circles.json.
#[derive(Debug, Clone, Serialize, Deserialize)]
struct CircleEntry {
    file: String,
    #[serde(default)]
    x: f64,
    #[serde(default)]
    y: f64,
    #[serde(default)]
    r: f64,
    /// Found by the calibration (false: none found; give one or skip the press).
    #[serde(default)]
    found: bool,
    #[serde(default)]
    skip: bool,
}

/// The circles of `path` for presses of `width` x `height`: each one not skipped has its centre
/// in the image and a radius above 0 and at most half the image's shorter side (a larger circle
/// cannot lie in the image).
fn read_circles(path: &Path, width: u32, height: u32) -> anyhow::Result<Vec<CircleEntry>> {
    let meta = std::fs::metadata(path).with_context(|| format!("{}", path.display()))?;
    if meta.len() > 4 << 20 {
        bail!("{}: {} bytes, more than 4 MiB", path.display(), meta.len());
    }
    let text = std::fs::read_to_string(path).with_context(|| format!("{}", path.display()))?;
    let v: Vec<CircleEntry> =
        serde_json::from_str(&text).with_context(|| format!("{}", path.display()))?;
    let (w, h) = (f64::from(width), f64::from(height));
    let r_max = w.min(h) / 2.0;
    for c in v.iter().filter(|c| !c.skip) {
        let inside = c.x.is_finite() && c.y.is_finite() && (0.0..w).contains(&c.x);
        let inside = inside && (0.0..h).contains(&c.y);
        let radius = c.r.is_finite() && c.r > 0.0 && c.r <= r_max;
        if !inside || !radius {
            bail!(
                "{}: circle of {} (x {}, y {}, r {}) is not a circle in the {width}x{height} \
                 image (centre inside it, radius above 0 and at most {r_max} px)",
                path.display(),
                c.file,
                c.x,
                c.y,
                c.r
            );
        }
    }
    Ok(v)
}

/// The press frame with its circle (red) and centre (a cross) drawn.
fn review_png(frame: &Frame, c: Option<Circle>, path: &Path) -> anyhow::Result<()> {
    let (w, h) = (frame.width as i64, frame.height as i64);
    let mut data = frame.data().to_vec();
    let mut put = |x: i64, y: i64, rgb: [u8; 3]| {
        if x >= 0 && y >= 0 && x < w && y < h {
            let i = ((y * w + x) * 3) as usize;
            data[i..i + 3].copy_from_slice(&rgb);
        }
    };
    if let Some(c) = c {
        // Bounded whatever the circle: a circle's pixels in a frame are at most 4 (w + h).
        let n = (c.r * 8.0).ceil().clamp(16.0, 4.0 * (w + h + 4) as f64) as usize;
        for k in 0..n {
            let t = std::f64::consts::TAU * k as f64 / n as f64;
            put(
                (c.x + c.r * t.cos()).round() as i64,
                (c.y + c.r * t.sin()).round() as i64,
                [255, 0, 0],
            );
        }
        for d in -3..=3 {
            put(c.x.round() as i64 + d, c.y.round() as i64, [255, 0, 0]);
            put(c.x.round() as i64, c.y.round() as i64 + d, [255, 0, 0]);
        }
    }
    image::RgbImage::from_raw(frame.width, frame.height, data)
        .context("image buffer")?
        .save(path)
        .with_context(|| format!("{}", path.display()))
}

/// `unitac calibrate depth`.
pub fn calibrate_depth(a: &CalibrateDepthArgs) -> anyhow::Result<bool> {
    // Everything given is checked before any press is read: exit 2.
    if a.presses.len() > MAX_PRESSES {
        return Err(usage(format!(
            "{} press images, at most {MAX_PRESSES}",
            a.presses.len()
        )));
    }
    let bg = read_frame(&a.background, "calibration", 0, None)
        .map_err(|e| usage(format!("--background {e:#}")))?;
    let (w, h) = (bg.width as usize, bg.height as usize);
    let spec = a.sensor.spec();
    let m_per_px = match a.m_per_px {
        Some(v) => v,
        None => spec.m_per_px() * f64::from(spec.width) / f64::from(bg.width),
    };
    let given = match &a.circles {
        Some(p) => Some(
            read_circles(p, bg.width, bg.height).map_err(|e| usage(format!("--circles {e:#}")))?,
        ),
        None => None,
    };
    if let Some(dir) = &a.review {
        std::fs::create_dir_all(dir)
            .map_err(|e| usage(format!("--review {}: {e}", dir.display())))?;
    }
    // A press's key in circles.json and its review file: its file name, or its path where
    // several presses share one (a calibration set laid out as `N/gelsight.png`).
    let keys = distinct_names(&a.presses);
    let review_files =
        output_files(&keys, "review.png").map_err(|e| usage(format!("--review: {e:#}")))?;
    let mut prep = Prep::default();
    let mut fit = Fit::default();
    let mut entries = Vec::new();
    let mut failed = 0usize;
    for (k, (path, key)) in a.presses.iter().zip(&keys).enumerate() {
        let review_file = &review_files[k];
        let frame = match read_frame(path, "calibration", k as u64, Some((bg.width, bg.height))) {
            Ok(f) => f,
            Err(e) => {
                eprintln!("unitac: {e:#}");
                failed += 1;
                continue;
            }
        };
        prepare(&mut prep, &frame, &bg)?;
        let found = find_circle(&prep.diff, w, h);
        let chosen = match given
            .as_ref()
            .and_then(|g| g.iter().find(|c| &c.file == key))
        {
            Some(c) if c.skip => None,
            Some(c) => Some(Circle {
                x: c.x,
                y: c.y,
                r: c.r,
            }),
            None => found,
        };
        if let Some(dir) = &a.review {
            review_png(&frame, chosen, &dir.join(review_file))?;
        }
        let skip = given
            .as_ref()
            .and_then(|g| g.iter().find(|c| &c.file == key))
            .is_some_and(|c| c.skip);
        entries.push(CircleEntry {
            file: key.clone(),
            x: chosen.map_or(0.0, |c| c.x),
            y: chosen.map_or(0.0, |c| c.y),
            r: chosen.map_or(0.0, |c| c.r),
            found: found.is_some(),
            skip,
        });
        match chosen {
            Some(c) => fit.add_press(&prep.diff, w, h, c, a.ball_radius_m, m_per_px),
            None if skip => {}
            None => unitac_cli::args::warn(format_args!(
                "{key}: no press found (give its circle in --circles, or skip it)"
            )),
        }
    }
    if let Some(dir) = &a.review {
        let p = dir.join("circles.json");
        std::fs::write(&p, serde_json::to_string_pretty(&entries)? + "\n")
            .with_context(|| format!("{}", p.display()))?;
    }
    let terms = if a.linear { Terms::Linear } else { Terms::All };
    let cal = fit.finish(
        terms,
        a.sensor,
        &a.serial,
        (bg.width, bg.height),
        m_per_px,
        a.ball_radius_m,
    )?;
    cal.save(&a.out)?;
    eprintln!(
        "{}: {} presses, {}x{}, {:.4} mm/px, fit RMS slope {:.4}",
        a.out.display(),
        cal.presses_used,
        cal.width,
        cal.height,
        cal.m_per_px * MM_PER_M,
        cal.fit_rms_slope
    );
    if let Some(s) = cal.model.slope_per_dn().filter(|_| a.linear) {
        // Four significant digits: the fit's own spread between press sets is larger.
        let row = |r: [f32; 3]| r.map(|k| format!("{k:.3e}")).join(", ");
        println!(
            "photometric: {{slope_per_dn: [[{}], [{}]]}}",
            row(s[0]),
            row(s[1])
        );
    }
    Ok(failed == 0)
}

fn save_png(frame: &Frame, path: &Path) -> anyhow::Result<()> {
    image::RgbImage::from_raw(frame.width, frame.height, frame.data().to_vec())
        .context("image buffer")?
        .save(path)
        .with_context(|| format!("{}", path.display()))
}

/// `unitac calibrate mock-presses`.
pub fn mock_presses(a: &MockPressesArgs) -> anyhow::Result<bool> {
    // The numbers were checked by their value parsers.
    let spec = a.sensor.spec();
    let presses = random_presses(
        spec,
        a.count,
        a.ball_radius_m * MM_PER_M,
        (0.3, 1.0),
        a.seed,
    );
    let noise = PressNoise {
        noise_dn: a.noise_dn,
        shading_dn: a.shading_dn,
        seed: a.seed,
    };
    let (bg, rendered) = render_presses(&calibration_gel(a.sensor), spec, &presses, noise)
        .context("rendering presses")?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("{}", a.out.display()))?;
    save_png(&bg, &a.out.join("background.png"))?;
    let mut truth = Vec::new();
    for (k, p) in rendered.iter().enumerate() {
        let name = format!("press_{k:03}.png");
        save_png(&p.frame, &a.out.join(&name))?;
        truth.push(serde_json::json!({
            "file": name,
            "x": p.press.center_px[0],
            "y": p.press.center_px[1],
            "contact_radius_px": p.press.contact_radius_mm() / MM_PER_M / spec.m_per_px(),
            "ball_radius_m": p.press.radius_mm / MM_PER_M,
            "approach_m": p.press.approach_mm / MM_PER_M,
        }));
    }
    std::fs::write(
        a.out.join("truth.json"),
        serde_json::to_string_pretty(&truth)? + "\n",
    )?;
    Ok(true)
}

/// `unitac contact --depth-calibration`: the calibration, checked against the sensor kind and
/// the background's size.
pub fn contact_calibration(
    path: &Path,
    sensor: SensorKind,
    bg: &Frame,
) -> anyhow::Result<DepthCalibration> {
    let cal = DepthCalibration::load(path)?;
    if cal.sensor != sensor {
        bail!(
            "{} is a calibration of a {}, the frames are from a {sensor}",
            path.display(),
            cal.sensor
        );
    }
    cal.m_per_px_at(bg.width, bg.height)?;
    Ok(cal)
}

/// The overlay file `path`: the picture of `unitac_contact::overlay` (the contact stage's
/// `contact_overlay` is the same one): the frame with the contact region's outline and centroid,
/// the markers' displacements (rest, now) as arrows, and with a depth, beside it the depth colour
/// map (`ContactDetector::depth_map_m`: NaN where unknown) with the depth's contact outline.
pub fn overlay_png(
    frame: &Frame,
    mask: &[bool],
    centroid: [f32; 2],
    arrows: &[([f32; 2], [f32; 2])],
    depth: Option<(&[f32], &[bool])>,
    path: &Path,
) -> anyhow::Result<()> {
    use unitac_contact::overlay::{DepthPanel, Overlay, draw};
    let o = Overlay {
        contact: mask,
        centroid: (centroid != [0.0, 0.0]).then_some(centroid),
        arrows,
        depth: depth.map(|(depth_m, mask)| DepthPanel { depth_m, mask }),
    };
    let img = draw(frame, &o)?;
    let img = image::RgbImage::from_raw(img.width, img.height, img.data().to_vec())
        .context("overlay buffer")?;
    img.save(&path)
        .with_context(|| format!("{}", path.display()))
}
