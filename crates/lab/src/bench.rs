//! `unitac-lab bench contact`: per-frame time of the contact detector, side by side in one run with
//! the Python pipeline users run today (numpy + OpenCV, as in the GelSight SDK), on the same
//! frames, plus the floor: one read pass over the frame.

use anyhow::{Context, bail};
use serde::Serialize;
use std::hint::black_box;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;
use unitac_contact::{ContactDetector, ContactParams, RegionRule};
use unitac_core::{Frame, SensorKind, Timing, timing};
use unitac_sim::{MockConfig, MockSensor, Scenario};

/// One frame size of `unitac-lab bench contact`.
#[derive(Debug, Serialize)]
pub struct ContactBench {
    pub frame: String,
    pub frames_timed: usize,
    /// The detector with its default params (the colour residual's region without a depth
    /// calibration).
    pub rust: Timing,
    /// The Python pipeline users run today for that output: gs_sdk's residual.
    pub python: Option<Timing>,
    pub ratio_median: Option<f64>,
    /// One read pass over the frame's bytes.
    pub floor: Timing,
    /// Rust median over the floor median: how far from "just reading the frame".
    pub over_floor: f64,
    /// The sensor's frame rate, and the share of one core the detector's mean time takes at it.
    pub fps: f64,
    pub core_share: f64,
    /// The same detector with `region: depth` (the region from the GelSight Mini profile's
    /// default photometric model, a Poisson solve on each frame with a deformation), timed on
    /// the same frames in the same loop; its share of one core at `fps`.
    pub depth_region: Timing,
    pub depth_core_share: f64,
    /// The Python pipeline for that output: gs_sdk's residual, and on frames with contact the
    /// depth by the same linear model, gs_sdk's Poisson solve and the half-depth region; its
    /// median over the Rust median.
    pub python_depth: Option<Timing>,
    pub depth_ratio_median: Option<f64>,
    /// Frames with a deformation (where the depth is estimated) among those timed.
    pub deformed_frames: usize,
    /// `region: depth` on the same frames read as `generic` (no model: one fitted on each
    /// deformed frame, `depth::selfcal`), its share of one core, and the Python depth
    /// pipeline's median over its median.
    pub selfcal_region: Timing,
    pub selfcal_core_share: f64,
    pub selfcal_ratio_median: Option<f64>,
}

/// `unitac-lab bench contact`: 320x240 and 640x480 in one run.
#[derive(Debug, Serialize)]
pub struct ContactBenches {
    pub sizes: Vec<ContactBench>,
    pub python_versions: String,
    pub note: String,
}

/// The project's Python (`$UNITAC_VENV/bin/python`) and the source tree (`$UNITAC_ROOT`), as
/// scripts/unitac sets them.
pub fn project_python() -> anyhow::Result<(PathBuf, PathBuf)> {
    let venv = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .context("UNITAC_VENV is not set (use scripts/unitac)")?;
    let root = std::env::var_os("UNITAC_ROOT")
        .map(PathBuf::from)
        .context("UNITAC_ROOT is not set")?;
    Ok((venv.join("bin/python"), root))
}

/// Run `bench/<script>` with the project's Python on one thread (as a user would run the
/// baseline, at its best: OpenBLAS core-type overrides removed) and parse its JSON line.
pub fn run_python_baseline(
    script: &str,
    args: &[std::ffi::OsString],
) -> anyhow::Result<serde_json::Value> {
    let (python, root) = project_python()?;
    let out = Command::new(python)
        .arg(root.join("bench").join(script))
        .args(args)
        .env("OMP_NUM_THREADS", "1")
        .env("OPENBLAS_NUM_THREADS", "1")
        .env_remove("OPENBLAS_CORETYPE")
        .env_remove("OPENBLAS_L2_SIZE")
        .output()
        .context("running the Python baseline")?;
    if !out.status.success() {
        bail!(
            "Python baseline failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}

fn frames(n: usize) -> anyhow::Result<Vec<Frame>> {
    frames_at(n, 1)
}

/// Mock GelSight Mini frames of the fabric scene at `scale` x 320x240.
fn frames_at(n: usize, scale: u32) -> anyhow::Result<Vec<Frame>> {
    let spec = SensorKind::GELSIGHT_MINI.spec().scaled(scale);
    let mut s = MockSensor::with_spec(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 5),
        spec,
        Scenario::fabric_selection(),
    )?;
    Ok(std::iter::from_fn(|| s.next_with_truth().map(|(f, _)| f))
        .take(n)
        .collect())
}

/// A new temporary directory ([`crate::scratch::new_dir`]) holding `frames` (rgb8, one after the
/// other) as `frames.raw` and `bg` as `bg.raw`, for a Python baseline to read.
pub(crate) fn raw_frames_dir(
    tag: &str,
    frames: &[Frame],
    bg: &Frame,
) -> anyhow::Result<std::path::PathBuf> {
    let dir = crate::scratch::new_dir(tag)?;
    let raw: Vec<u8> = frames
        .iter()
        .flat_map(|f| f.data().iter().copied())
        .collect();
    std::fs::write(dir.join("frames.raw"), raw)?;
    std::fs::write(dir.join("bg.raw"), bg.data())?;
    Ok(dir)
}

/// The timing a Python baseline printed (`min_s`, `median_s`, `mean_s`, `p90_s`).
pub(crate) fn python_timing(j: &serde_json::Value) -> Timing {
    let f = |k: &str| j[k].as_f64().unwrap_or(f64::NAN);
    Timing {
        min_s: f("min_s"),
        median_s: f("median_s"),
        mean_s: f("mean_s"),
        p90_s: f("p90_s"),
    }
}

/// The Python baselines' timings: the residual alone, and with the region from depth.
struct PythonContact {
    residual: Timing,
    depth: Timing,
    versions: String,
}

fn python_baseline(
    frames: &[Frame],
    bg: &Frame,
    repeat: usize,
    slope_per_dn: [[f32; 3]; 2],
) -> anyhow::Result<PythonContact> {
    let dir = raw_frames_dir("bench", frames, bg)?;
    std::fs::write(
        dir.join("slope.json"),
        serde_json::to_string(&slope_per_dn)?,
    )?;
    let args = [
        dir.join("frames.raw").into_os_string(),
        dir.join("bg.raw").into_os_string(),
        bg.width.to_string().into(),
        bg.height.to_string().into(),
        repeat.to_string().into(),
        dir.join("slope.json").into_os_string(),
    ];
    let j = run_python_baseline("contact_baseline.py", &args);
    std::fs::remove_dir_all(&dir).ok();
    let j = j?;
    Ok(PythonContact {
        residual: python_timing(&j["residual"]),
        depth: python_timing(&j["depth"]),
        versions: format!(
            "numpy {} opencv {}, Poisson by {}",
            j["numpy"], j["opencv"], j["poisson"]
        ),
    })
}

fn bench_contact_at(
    n: usize,
    repeat: usize,
    with_python: bool,
    scale: u32,
) -> anyhow::Result<(ContactBench, String)> {
    let frames = frames_at(n.max(20), scale)?;
    let bg = frames.first().context("no frames")?.clone();
    let kind = SensorKind::GELSIGHT_MINI;
    let spec = kind.spec();
    let slope_per_dn = kind
        .profile()
        .photometric
        .context("the GelSight Mini profile has no photometric model")?
        .slope_per_dn;
    let mut det =
        ContactDetector::new(ContactParams::default(), spec).map_err(anyhow::Error::msg)?;
    let depth_params = ContactParams {
        region: RegionRule::Depth,
        ..ContactParams::default()
    };
    let mut det_depth =
        ContactDetector::new(depth_params.clone(), spec).map_err(anyhow::Error::msg)?;
    let mut det_self = ContactDetector::new(depth_params, SensorKind::GENERIC.spec())
        .map_err(anyhow::Error::msg)?;
    det.set_background_frame(&bg);
    det_depth.set_background_frame(&bg);
    det_self.set_background_frame(&bg);
    // Warm-up, then time each step (detection, hysteresis, episodes, background update).
    for f in frames.iter().take(10) {
        let _ = black_box(det.step(f));
        let _ = black_box(det_depth.step(f));
        let _ = black_box(det_self.step(f));
    }
    let mut rust = Vec::with_capacity(frames.len() * repeat);
    let mut depth = Vec::with_capacity(frames.len() * repeat);
    let mut selfcal = Vec::with_capacity(frames.len() * repeat);
    let mut floor = Vec::with_capacity(frames.len() * repeat);
    let mut deformed_frames = 0;
    for _ in 0..repeat {
        for f in &frames {
            let t0 = Instant::now();
            let _ = black_box(det.step(black_box(f)));
            rust.push(t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            let _ = black_box(det_depth.step(black_box(f)));
            depth.push(t0.elapsed().as_secs_f64());
            deformed_frames += usize::from(det_depth.depth().is_some_and(|(_, s)| s.is_some()));
            let t0 = Instant::now();
            let _ = black_box(det_self.step(black_box(f)));
            selfcal.push(t0.elapsed().as_secs_f64());
            let t0 = Instant::now();
            let s: u64 = black_box(f.data()).iter().map(|&b| u64::from(b)).sum();
            black_box(s);
            floor.push(t0.elapsed().as_secs_f64());
        }
    }
    let rust = timing(rust);
    let depth = timing(depth);
    let selfcal = timing(selfcal);
    let floor = timing(floor);
    let python = if with_python {
        Some(python_baseline(&frames, &bg, repeat, slope_per_dn)?)
    } else {
        None
    };
    let over = |p: Option<&Timing>, r: &Timing| p.map(|p| p.median_s / r.median_s);
    let fps = spec.fps;
    Ok((
        ContactBench {
            frame: format!(
                "{}x{} RGB8 (GelSight Mini mock, fabric scene)",
                bg.width, bg.height
            ),
            frames_timed: frames.len() * repeat,
            over_floor: rust.median_s / floor.median_s.max(1e-9),
            fps,
            core_share: rust.mean_s * fps,
            ratio_median: over(python.as_ref().map(|p| &p.residual), &rust),
            depth_core_share: depth.mean_s * fps,
            depth_ratio_median: over(python.as_ref().map(|p| &p.depth), &depth),
            deformed_frames,
            depth_region: depth,
            selfcal_core_share: selfcal.mean_s * fps,
            selfcal_ratio_median: over(python.as_ref().map(|p| &p.depth), &selfcal),
            selfcal_region: selfcal,
            rust,
            python: python.as_ref().map(|p| p.residual),
            python_depth: python.as_ref().map(|p| p.depth),
            floor,
        },
        python.map(|p| p.versions).unwrap_or_default(),
    ))
}

pub fn bench_contact(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<ContactBenches> {
    let mut sizes = Vec::new();
    let mut versions = String::new();
    for scale in [1, 2] {
        let (b, v) = bench_contact_at(n, repeat, with_python, scale)?;
        sizes.push(b);
        versions = v;
    }
    Ok(ContactBenches {
        sizes,
        python_versions: versions,
        note: "Rust does more per frame than the baseline: drift and shading compensation, \
               noise estimated from each frame, marker masking, coherent components, hysteresis, \
               episodes, background EMA"
            .into(),
    })
}

/// One row of the contact bench's text: median and mean, the share of one core, and the speed-up
/// over a Python row (medians; and means, `python`'s mean over `t`'s: with the depth estimated
/// only on frames with a deformation, the median frame of a run with half of them deformed may
/// be one without).
fn row(
    what: &str,
    t: &Timing,
    core_share: Option<f64>,
    ratio: Option<f64>,
    python: Option<&Timing>,
) -> String {
    let mut s = format!(
        "  {what:<40} median {:>8.1} us  mean {:>8.1} us",
        t.median_s * 1e6,
        t.mean_s * 1e6,
    );
    if let Some(c) = core_share {
        s += &format!("  {:.2} % of one core", c * 100.0);
    }
    if let Some(r) = ratio {
        s += &format!("  speed-up (median): {r:.1}x");
    }
    if let Some(p) = python {
        s += &format!(", (mean): {:.1}x", p.mean_s / t.mean_s);
    }
    s + "\n"
}

impl ContactBenches {
    pub fn text(&self) -> String {
        let mut s = String::new();
        for b in &self.sizes {
            s += &format!(
                "contact detection per {} frame, one core, {} frames ({} with a deformation, \
                 where region: depth estimates the depth); shares of one core at {} fps (mean \
                 time x frame rate)\n",
                b.frame, b.frames_timed, b.deformed_frames, b.fps
            );
            s += &row(
                "unitac, default (residual)",
                &b.rust,
                Some(b.core_share),
                b.ratio_median,
                b.python.as_ref(),
            );
            if let Some(p) = &b.python {
                s += &row("numpy + OpenCV (gs_sdk), residual", p, None, None, None);
            }
            s += &row(
                "unitac, region: depth (kind's model)",
                &b.depth_region,
                Some(b.depth_core_share),
                b.depth_ratio_median,
                b.python_depth.as_ref(),
            );
            s += &row(
                "unitac, region: depth, self-calibrated",
                &b.selfcal_region,
                Some(b.selfcal_core_share),
                b.selfcal_ratio_median,
                b.python_depth.as_ref(),
            );
            if let Some(p) = &b.python_depth {
                s += &row("numpy + OpenCV + scipy, depth", p, None, None, None);
            }
            s += &format!(
                "  {:<40} median {:>8.1} us  (the default is {:.1}x the floor)\n",
                "floor (one read pass)",
                b.floor.median_s * 1e6,
                b.over_floor
            );
        }
        if !self.python_versions.is_empty() {
            s += &format!("Python: {}\n", self.python_versions);
        }
        s
    }
}

// ---------------------------------------------------------------------------------------------
// `unitac-lab bench replay`

#[derive(Debug, Serialize)]
pub struct ReplayBench {
    pub bag: String,
    pub frames_per_pass: usize,
    pub passes: usize,
    /// Read + CDR decode + RGB frame + contact detection, median pass.
    pub rust_fps: f64,
    pub rust_pass_s: f64,
    /// Read only (the floor): reader + CDR decode + frame, no detection.
    pub rust_read_fps: f64,
    pub python_fps: Option<f64>,
    pub python_pass_s: Option<f64>,
    pub python_versions: String,
    pub ratio: Option<f64>,
}

/// Write the mock fabric frames as an uncompressed rgb8 MCAP bag (rosbag2's default: no
/// compression).
fn bench_bag(dir: &std::path::Path, frames: &[Frame]) -> anyhow::Result<std::path::PathBuf> {
    use unitac_bag::{BagWriter, Compression, Image, WriteOptions};
    let path = dir.join("bench_replay");
    let mut w = BagWriter::create(
        &path,
        WriteOptions {
            compression: Compression::None,
            chunk_size: 4 << 20,
        },
    )?;
    let t = w.add_topic("/gs/image_raw", "sensor_msgs/msg/Image")?;
    for f in frames {
        w.write(t, f.stamp.0, &Image::rgb8(f))?;
    }
    Ok(w.finish()?)
}

fn rust_pass(bag: &std::path::Path, detect: bool) -> anyhow::Result<(usize, f64)> {
    use unitac_bag::{BagSource, ReplayOptions};
    let t0 = Instant::now();
    let mut src = BagSource::open(bag, ReplayOptions::default())?;
    let mut det: Option<ContactDetector> = None;
    let mut n = 0;
    while let Some(item) = src.next_image()? {
        let f = item.frame?;
        if detect {
            let d = match &mut det {
                Some(d) => d,
                None => {
                    let mut d = ContactDetector::new(
                        ContactParams::default(),
                        SensorKind::GELSIGHT_MINI.spec(),
                    )
                    .map_err(anyhow::Error::msg)?;
                    d.set_background_frame(&f);
                    det.insert(d)
                }
            };
            let _ = black_box(d.step(&f));
        } else {
            black_box(f.data());
        }
        n += 1;
    }
    Ok((n, t0.elapsed().as_secs_f64()))
}

pub fn bench_replay(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<ReplayBench> {
    let frames = frames(n.max(20))?;
    let (w, h) = frames
        .first()
        .map(|f| (f.width, f.height))
        .context("no frames")?;
    let dir = crate::scratch::new_dir("bench-replay")?;
    let result = (|| {
        let bag = bench_bag(&dir, &frames)?;
        rust_pass(&bag, true)?; // warm-up (page cache)
        let mut full = Vec::new();
        let mut read = Vec::new();
        let mut count = 0;
        for _ in 0..repeat {
            let (k, s) = rust_pass(&bag, true)?;
            full.push(s);
            count = k;
            read.push(rust_pass(&bag, false)?.1);
        }
        let rust_pass_s = timing(full).median_s;
        let (python_fps, python_pass_s, versions) = if with_python {
            let (fps, pass, v) = python_replay(&bag, repeat)?;
            (Some(fps), Some(pass), v)
        } else {
            (None, None, String::new())
        };
        let rust_fps = count as f64 / rust_pass_s;
        Ok(ReplayBench {
            bag: format!(
                "{count} rgb8 {w}x{h} frames, MCAP, uncompressed (GelSight Mini mock, fabric scene)"
            ),
            frames_per_pass: count,
            passes: repeat,
            rust_fps,
            rust_pass_s,
            rust_read_fps: count as f64 / timing(read).median_s,
            python_fps,
            python_pass_s,
            python_versions: versions,
            ratio: python_fps.map(|p| rust_fps / p),
        })
    })();
    std::fs::remove_dir_all(&dir).ok();
    result
}

fn python_replay(bag: &std::path::Path, repeat: usize) -> anyhow::Result<(f64, f64, String)> {
    let j = run_python_baseline(
        "replay_baseline.py",
        &[bag.as_os_str().to_owned(), repeat.to_string().into()],
    )?;
    Ok((
        j["fps"].as_f64().unwrap_or(f64::NAN),
        j["pass_s"].as_f64().unwrap_or(f64::NAN),
        format!(
            "rosbags {} numpy {} opencv {}",
            j["rosbags"], j["numpy"], j["opencv"]
        ),
    ))
}

impl ReplayBench {
    pub fn text(&self) -> String {
        let mut s = format!(
            "bag replay: read + decode + contact detection, one core, {}; median of {} passes\n",
            self.bag, self.passes
        );
        s += &format!(
            "  unitac (Rust)                {:>8.0} frames/s  ({:.3} s per pass)\n",
            self.rust_fps, self.rust_pass_s
        );
        if let (Some(f), Some(p)) = (self.python_fps, self.python_pass_s) {
            s += &format!(
                "  rosbags + numpy + OpenCV     {:>8.0} frames/s  ({:.3} s per pass)  [{}]\n",
                f, p, self.python_versions
            );
        }
        s += &format!(
            "  floor (Rust read + decode)   {:>8.0} frames/s\n",
            self.rust_read_fps
        );
        if let Some(r) = self.ratio {
            s += &format!("  speed-up: {r:.1}x\n");
        }
        s
    }
}
