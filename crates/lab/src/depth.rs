//! `unitac-lab eval depth` (depth from one image against the mock's exact depth) and
//! `unitac-lab bench depth` (per frame, beside the Python path a GelSight user runs), both on a
//! calibration from mock ball presses.

use anyhow::Context;
use serde::Serialize;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;
use unitac_cli::args::usage;
use unitac_cli::mock::calibration_gel;
use unitac_contact::depth::{
    DepthCalibration, DepthEstimator, DepthParams, Fit, Prep, Terms, find_circle, prepare,
};
use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::{Frame, SensorKind, SensorSpec, Timing, timing};
use unitac_sim::MM_PER_M;
use unitac_sim::ballpress::{BallPress, PressNoise, random_presses, render_presses};

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
        Terms::All,
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

/// `unitac-lab eval depth`: calibrate from mock presses, then depth against the truth at several
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

/// `unitac-lab bench depth`: 320x240 and 640x480 (the 320x240 calibration at twice the size).
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
