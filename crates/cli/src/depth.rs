//! Gel depth on the command line: `calibrate depth` (a sensor's photometric calibration from
//! ball presses, with review PNGs and corrected circles), `calibrate mock-presses` (presses to
//! try it on), `eval depth` (accuracy against the mock's exact depth) and `bench depth` (per
//! frame, beside the Python path a GelSight user runs).

use anyhow::{Context, bail};
use serde::{Deserialize, Serialize};
use std::hint::black_box;
use std::path::{Path, PathBuf};
use std::time::Instant;
use unitac_contact::depth::{
    Circle, DepthCalibration, DepthEstimator, DepthParams, Fit, Prep, find_circle, prepare,
};
use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::{Frame, SensorKind, SensorSpec, Timing, timing};
use unitac_sim::MM_PER_M;
use unitac_sim::ballpress::{BallPress, PressNoise, random_presses, render_presses};

use crate::images::read_frame;
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
    /// Sensor kind: gelsight-mini | digit | generic (sensors/), or a profile of $UNITAC_SENSORS.
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
}

#[derive(clap::Args, Debug)]
pub struct MockPressesArgs {
    /// Sensor kind: gelsight-mini | digit | generic (sensors/), or a profile of $UNITAC_SENSORS (the frames' size and mm per pixel).
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

fn file_key(p: &Path) -> String {
    p.file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_default()
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
    let mut prep = Prep::default();
    let mut fit = Fit::default();
    let mut entries = Vec::new();
    let mut failed = 0usize;
    for (k, path) in a.presses.iter().enumerate() {
        let key = file_key(path);
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
            .and_then(|g| g.iter().find(|c| c.file == key))
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
            let stem = path
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_else(|| format!("press_{k}"));
            review_png(&frame, chosen, &dir.join(format!("{stem}.review.png")))?;
        }
        let skip = given
            .as_ref()
            .and_then(|g| g.iter().find(|c| c.file == key))
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
    let cal = fit.finish(
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

/// A calibration from `n` mock presses of a 2 mm ball at noise 1 DN (what `eval depth` and
/// `bench depth` use).
fn mock_calibration(spec: SensorSpec, n: usize) -> anyhow::Result<DepthCalibration> {
    let presses = random_presses(spec, n, EVAL_BALL_M * MM_PER_M, (0.3, 1.0), 5);
    let noise = PressNoise {
        noise_dn: 1.0,
        shading_dn: 0.0,
        seed: 9,
    };
    let (bg, rendered) = render_presses(&calibration_gel(spec.kind), spec, &presses, noise)
        .context("rendering presses")?;
    let (w, h) = (spec.width as usize, spec.height as usize);
    let mut prep = Prep::default();
    let mut fit = Fit::default();
    for p in &rendered {
        prepare(&mut prep, &p.frame, &bg)?;
        if let Some(c) = find_circle(&prep.diff, w, h) {
            fit.add_press(&prep.diff, w, h, c, EVAL_BALL_M, spec.m_per_px());
        }
    }
    Ok(fit.finish(
        spec.kind,
        "MOCK",
        (spec.width, spec.height),
        spec.m_per_px(),
        EVAL_BALL_M,
    )?)
}

/// The ball `eval depth` and `bench depth` press \[m].
const EVAL_BALL_M: f64 = 0.002;

/// One row of `eval depth`.
#[derive(Debug, Serialize)]
pub struct DepthRow {
    /// The ball's approach into the gel \[m].
    pub approach_m: f64,
    pub noise_dn: f64,
    pub shading_dn: f64,
    pub presses: usize,
    /// RMS depth error over every pixel of the frames \[m].
    pub rmse_m: f64,
    /// Mean and largest |penetration - approach| \[m].
    pub penetration_err_mean_m: f64,
    pub penetration_err_max_m: f64,
    /// Depth's contact area over the Hertz disc pi R d, and over the geometric one.
    pub area_over_hertz: f64,
    pub area_over_geometric: f64,
    /// The contact detector's area (its contact region) over the Hertz disc.
    pub detector_area_over_hertz: f64,
}

#[derive(Debug, Serialize)]
pub struct DepthEval {
    pub sensor: String,
    pub ball_radius_m: f64,
    pub calibration_presses: u32,
    pub fit_rms_slope: f64,
    pub rows: Vec<DepthRow>,
    pub pngs: Vec<String>,
}

impl DepthEval {
    pub fn text(&self) -> String {
        let mut s = format!(
            "depth on mock ball presses ({}, ball R {} mm, calibrated from {} presses, fit RMS slope {:.4})\n",
            self.sensor,
            self.ball_radius_m * MM_PER_M,
            self.calibration_presses,
            self.fit_rms_slope
        );
        s += "approach mm | noise DN | shading DN | RMSE mm | pen. err mean / max mm | area / Hertz disc | area / geometric | detector area / Hertz\n";
        for r in &self.rows {
            s += &format!(
                "{:>11.2} | {:>8.1} | {:>10.1} | {:>7.4} | {:>9.4} / {:.4} | {:>17.3} | {:>16.3} | {:>21.3}\n",
                r.approach_m * MM_PER_M,
                r.noise_dn,
                r.shading_dn,
                r.rmse_m * MM_PER_M,
                r.penetration_err_mean_m * MM_PER_M,
                r.penetration_err_max_m * MM_PER_M,
                r.area_over_hertz,
                r.area_over_geometric,
                r.detector_area_over_hertz
            );
        }
        for p in &self.pngs {
            s += &format!("wrote {p}\n");
        }
        s
    }
}

/// Frame | estimated depth \[m] | the renderer's true depth \[mm], one colour scale (0 to 1 mm).
fn depth_png(frame: &Frame, est_m: &[f32], truth_mm: &[f32], path: &Path) -> anyhow::Result<()> {
    let (w, h) = (frame.width as usize, frame.height as usize);
    let mut img = image::RgbImage::new((w * 3) as u32, h as u32);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let p = frame.data().get(i * 3..i * 3 + 3).unwrap_or(&[0, 0, 0]);
            img.put_pixel(x as u32, y as u32, image::Rgb([p[0], p[1], p[2]]));
            img.put_pixel(
                (w + x) as u32,
                y as u32,
                image::Rgb(unitac_contact::overlay::ramp(est_m[i] * MM_PER_M as f32)),
            );
            img.put_pixel(
                (2 * w + x) as u32,
                y as u32,
                image::Rgb(unitac_contact::overlay::ramp(truth_mm[i])),
            );
        }
    }
    img.save(path)
        .with_context(|| format!("{}", path.display()))
}

/// `unitac eval depth`: calibrate from mock presses, then depth against the truth at several
/// approaches, noise and shading levels (three presses each); PNGs of a few into `out`.
pub fn eval_depth(out: Option<&Path>) -> anyhow::Result<DepthEval> {
    let spec = SensorKind::GELSIGHT_MINI.spec();
    if let Some(d) = out {
        std::fs::create_dir_all(d).map_err(|e| usage(format!("--out {}: {e}", d.display())))?;
    }
    let cal = mock_calibration(spec, 40)?;
    let mut rows = Vec::new();
    let mut pngs = Vec::new();
    let places = [[110.0, 95.0], [210.0, 140.0], [160.0, 120.0]];
    for approach in [0.2e-3, 0.4e-3, 0.6e-3, 0.8e-3, 1.0e-3] {
        for (noise_dn, shading_dn) in [(1.0, 0.0), (4.0, 0.0), (1.0, 20.0), (4.0, 20.0)] {
            let presses: Vec<BallPress> = places
                .iter()
                .map(|c| BallPress {
                    center_px: *c,
                    radius_mm: EVAL_BALL_M * MM_PER_M,
                    approach_mm: approach * MM_PER_M,
                })
                .collect();
            let noise = PressNoise {
                noise_dn,
                shading_dn,
                seed: 77,
            };
            let (bg, rendered) = render_presses(&calibration_gel(spec.kind), spec, &presses, noise)
                .context("rendering presses")?;
            let mut est = DepthEstimator::new(cal.clone(), bg.clone(), DepthParams::default())?;
            let mut det =
                ContactDetector::new(ContactParams::default(), spec).map_err(anyhow::Error::msg)?;
            det.set_background_frame(&bg);
            let (mut se, mut n) = (0f64, 0usize);
            let (mut pe_sum, mut pe_max) = (0f64, 0f64);
            let (mut ah, mut ag, mut dh) = (0f64, 0f64, 0f64);
            for (k, p) in rendered.iter().enumerate() {
                let s = est.estimate(&p.frame)?;
                for (a, b) in est.depth_m().iter().zip(&p.depth_mm) {
                    se += (f64::from(*a) - f64::from(*b) / MM_PER_M).powi(2);
                    n += 1;
                }
                let pe = (f64::from(s.penetration_m) - approach).abs();
                pe_sum += pe;
                pe_max = pe_max.max(pe);
                let hertz = std::f64::consts::PI * (p.press.contact_radius_mm() / MM_PER_M).powi(2);
                let geo = std::f64::consts::PI * (p.press.geometric_radius_mm() / MM_PER_M).powi(2);
                ah += s.area_m2 / hertz;
                ag += s.area_m2 / geo;
                let m = det.measure(&p.frame).map_err(anyhow::Error::msg)?;
                dh += f64::from(m.area_px) * spec.m2_per_px() / hertz;
                if let Some(d) = out {
                    if k == 0 && noise_dn == 4.0 && shading_dn == 20.0 {
                        let path = d.join(format!(
                            "depth_{:.1}mm_noise4_shading20.png",
                            approach * MM_PER_M
                        ));
                        depth_png(&p.frame, est.depth_m(), &p.depth_mm, &path)?;
                        pngs.push(path.display().to_string());
                    }
                }
            }
            let m = rendered.len().max(1) as f64;
            rows.push(DepthRow {
                approach_m: approach,
                noise_dn,
                shading_dn,
                presses: rendered.len(),
                rmse_m: (se / n.max(1) as f64).sqrt(),
                penetration_err_mean_m: pe_sum / m,
                penetration_err_max_m: pe_max,
                area_over_hertz: ah / m,
                area_over_geometric: ag / m,
                detector_area_over_hertz: dh / m,
            });
        }
    }
    Ok(DepthEval {
        sensor: spec.kind.to_string(),
        ball_radius_m: EVAL_BALL_M,
        calibration_presses: cal.presses_used,
        fit_rms_slope: cal.fit_rms_slope,
        rows,
        pngs,
    })
}

/// One frame size of `bench depth`.
#[derive(Debug, Serialize)]
pub struct DepthBench {
    pub frame: String,
    pub frames_timed: usize,
    pub rust: Timing,
    pub python: Option<Timing>,
    pub ratio_median: Option<f64>,
    pub floor: Timing,
    pub over_floor: f64,
    /// Share of one core the Rust path takes at 25 frames per second (median).
    pub core_share_at_25fps: f64,
}

#[derive(Debug, Serialize)]
pub struct DepthBenches {
    pub sizes: Vec<DepthBench>,
    pub python: String,
    pub note: String,
}

impl DepthBenches {
    pub fn text(&self) -> String {
        let mut s = String::new();
        for b in &self.sizes {
            s += &format!(
                "depth per {} frame, one core, {} frames\n",
                b.frame, b.frames_timed
            );
            s += &format!(
                "  unitac (Rust)      median {:>9.1} us  min {:>9.1} us  p90 {:>9.1} us  ({:.1} % of one core at 25 fps)\n",
                b.rust.median_s * 1e6,
                b.rust.min_s * 1e6,
                b.rust.p90_s * 1e6,
                b.core_share_at_25fps * 100.0
            );
            if let (Some(p), Some(r)) = (&b.python, b.ratio_median) {
                s += &format!(
                    "  Python (gs_sdk)    median {:>9.1} us  min {:>9.1} us  p90 {:>9.1} us  Rust is {r:.1}x faster\n",
                    p.median_s * 1e6,
                    p.min_s * 1e6,
                    p.p90_s * 1e6
                );
            }
            s += &format!(
                "  floor (read pass)  median {:>9.1} us  Rust / floor {:.1}x\n",
                b.floor.median_s * 1e6,
                b.over_floor
            );
        }
        s += &format!("Python: {}\n{}\n", self.python, self.note);
        s
    }
}

fn python_depth(
    frames: &[Frame],
    bg: &Frame,
    cal: &DepthCalibration,
    repeat: usize,
) -> anyhow::Result<(Timing, String)> {
    let dir = crate::bench::raw_frames_dir("bench-depth", frames, bg)?;
    cal.save(&dir.join("cal.json"))?;
    let m_per_px = cal.m_per_px_at(bg.width, bg.height)?;
    let args = [
        dir.join("frames.raw").into_os_string(),
        dir.join("bg.raw").into_os_string(),
        dir.join("cal.json").into_os_string(),
        bg.width.to_string().into(),
        bg.height.to_string().into(),
        m_per_px.to_string().into(),
        repeat.to_string().into(),
    ];
    let j = crate::bench::run_python_baseline("depth_baseline.py", &args);
    std::fs::remove_dir_all(&dir).ok();
    let j = j?;
    Ok((
        crate::bench::python_timing(&j),
        format!("numpy {}, Poisson by {}", j["numpy"], j["poisson"]),
    ))
}

/// `unitac bench depth`: 320x240 and 640x480 (the 320x240 calibration at twice the size).
pub fn bench_depth(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<DepthBenches> {
    let base = SensorKind::GELSIGHT_MINI.spec();
    let cal = mock_calibration(base, 40)?;
    let mut sizes = Vec::new();
    let mut python = String::from("not run");
    for scale in [1u32, 2] {
        let spec = base.scaled(scale);
        let presses = random_presses(
            spec,
            n.clamp(1, 200),
            EVAL_BALL_M * MM_PER_M,
            (0.2, 1.0),
            21,
        );
        let noise = PressNoise {
            noise_dn: 1.0,
            shading_dn: 0.0,
            seed: 4,
        };
        let (bg, rendered) = render_presses(&calibration_gel(spec.kind), spec, &presses, noise)
            .context("rendering presses")?;
        let frames: Vec<Frame> = rendered.into_iter().map(|p| p.frame).collect();
        let mut est = DepthEstimator::new(cal.clone(), bg.clone(), DepthParams::default())?;
        for f in frames.iter().take(5) {
            black_box(est.estimate(f)?);
        }
        let (mut rust, mut floor) = (Vec::new(), Vec::new());
        for _ in 0..repeat {
            for f in &frames {
                let t0 = Instant::now();
                black_box(est.estimate(black_box(f))?);
                rust.push(t0.elapsed().as_secs_f64());
                let t0 = Instant::now();
                let s: u64 = black_box(f.data()).iter().map(|&b| u64::from(b)).sum();
                black_box(s);
                floor.push(t0.elapsed().as_secs_f64());
            }
        }
        let (rust, floor) = (timing(rust), timing(floor));
        let py = if with_python {
            let (t, v) = python_depth(&frames, &bg, &cal, repeat)?;
            python = v;
            Some(t)
        } else {
            None
        };
        sizes.push(DepthBench {
            frame: format!(
                "{}x{} RGB8 (GelSight Mini mock ball presses)",
                spec.width, spec.height
            ),
            frames_timed: frames.len() * repeat,
            ratio_median: py.as_ref().map(|p| p.median_s / rust.median_s),
            python: py,
            over_floor: rust.median_s / floor.median_s.max(1e-9),
            core_share_at_25fps: rust.median_s * 25.0,
            rust,
            floor,
        });
    }
    Ok(DepthBenches {
        sizes,
        python,
        note: "both sides: difference to the background, 3x3 box mean, the same 18-feature \
               gradient model per pixel, a DCT Poisson solve (Python: gs_sdk's, scipy fftpack \
               in float64), zero level from the border, penetration; Rust also removes the \
               smooth shading and finds the contact region"
            .into(),
    })
}

/// `unitac contact --depth-calibration`: the calibration, checked against the sensor kind and
/// the background's size, and its estimator on that background.
pub fn contact_depth(
    path: &Path,
    sensor: SensorKind,
    bg: &Frame,
) -> anyhow::Result<DepthEstimator> {
    let cal = DepthCalibration::load(path)?;
    if cal.sensor != sensor {
        bail!(
            "{} is a calibration of a {}, the frames are from a {sensor}",
            path.display(),
            cal.sensor
        );
    }
    Ok(DepthEstimator::new(
        cal,
        bg.clone(),
        DepthParams::default(),
    )?)
}

/// The overlay file of frame `source`: `<its file stem>.overlay.png`.
pub fn overlay_name(source: &Path) -> String {
    let stem = source
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "frame".into());
    format!("{stem}.overlay.png")
}

/// `<frame stem>.overlay.png` in `dir`: the picture of `unitac_contact::overlay` (the contact
/// stage's `contact_overlay` is the same one): the frame with the contact region's outline and
/// centroid, the markers' displacements (rest, now) as arrows, and with a depth estimator,
/// beside it the depth colour map with the depth's contact outline (the depth unknown under the
/// `unknown` pixels, the marker dots).
pub fn overlay_png(
    frame: &Frame,
    mask: &[bool],
    centroid: [f32; 2],
    arrows: &[([f32; 2], [f32; 2])],
    depth: Option<(&DepthEstimator, &[bool])>,
    dir: &Path,
    source: &Path,
) -> anyhow::Result<()> {
    use unitac_contact::overlay::{DepthPanel, Overlay, draw};
    let depth_m: Option<Vec<f32>> = depth.map(|(d, unknown)| {
        d.depth_m()
            .iter()
            .enumerate()
            .map(|(i, v)| {
                if unknown.get(i).copied().unwrap_or(false) {
                    f32::NAN
                } else {
                    *v
                }
            })
            .collect()
    });
    let o = Overlay {
        contact: mask,
        centroid: (centroid != [0.0, 0.0]).then_some(centroid),
        arrows,
        depth: match (&depth_m, depth) {
            (Some(depth_m), Some((d, _))) => Some(DepthPanel {
                depth_m,
                mask: d.mask(),
            }),
            _ => None,
        },
    };
    let img = draw(frame, &o)?;
    let img = image::RgbImage::from_raw(img.width, img.height, img.data().to_vec())
        .context("overlay buffer")?;
    let path = dir.join(overlay_name(source));
    img.save(&path)
        .with_context(|| format!("{}", path.display()))
}
