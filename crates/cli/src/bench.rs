//! `unitac bench contact`: per-frame time of the contact detector, side by side in one run with
//! the Python pipeline users run today (numpy + OpenCV, as in the GelSight SDK), on the same
//! frames, plus the floor: one read pass over the frame.

use anyhow::{Context, bail};
use serde::Serialize;
use std::hint::black_box;
use std::path::PathBuf;
use std::process::Command;
use std::time::Instant;
use unitac_contact::{ContactDetector, ContactParams};
use unitac_core::{Frame, SensorKind};
use unitac_sim::{MockConfig, MockSensor, Scenario};

#[derive(Debug, Serialize)]
pub struct Timing {
    pub median_us: f64,
    pub mean_us: f64,
}

#[derive(Debug, Serialize)]
pub struct ContactBench {
    pub frame: String,
    pub frames_timed: usize,
    pub rust: Timing,
    pub python: Option<Timing>,
    pub python_versions: String,
    pub ratio_median: Option<f64>,
    /// One read pass over the frame's bytes.
    pub floor: Timing,
    pub note: String,
}

fn timing(mut v: Vec<f64>) -> Timing {
    v.sort_by(f64::total_cmp);
    let mean = v.iter().sum::<f64>() / v.len().max(1) as f64;
    Timing {
        median_us: v.get(v.len() / 2).copied().unwrap_or(0.0),
        mean_us: mean,
    }
}

fn frames(n: usize) -> Vec<Frame> {
    let mut s = MockSensor::new(
        MockConfig::new(SensorKind::GelsightMini, 5),
        Scenario::fabric_selection(),
    );
    std::iter::from_fn(|| s.next_with_truth().map(|(f, _)| f))
        .take(n)
        .collect()
}

fn python_baseline(
    frames: &[Frame],
    bg: &Frame,
    repeat: usize,
) -> anyhow::Result<(Timing, String)> {
    let venv = std::env::var_os("UNITAC_VENV")
        .map(PathBuf::from)
        .context("UNITAC_VENV is not set (use scripts/unitac)")?;
    let root = std::env::var_os("UNITAC_ROOT")
        .map(PathBuf::from)
        .context("UNITAC_ROOT is not set")?;
    let dir = std::env::temp_dir().join(format!("unitac-bench-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let raw: Vec<u8> = frames
        .iter()
        .flat_map(|f| f.data().iter().copied())
        .collect();
    std::fs::write(dir.join("frames.raw"), raw)?;
    std::fs::write(dir.join("bg.raw"), bg.data())?;
    let out = Command::new(venv.join("bin/python"))
        .arg(root.join("bench/contact_baseline.py"))
        .arg(dir.join("frames.raw"))
        .arg(dir.join("bg.raw"))
        .args([
            bg.width.to_string(),
            bg.height.to_string(),
            repeat.to_string(),
        ])
        .env("OMP_NUM_THREADS", "1")
        .env("OPENBLAS_NUM_THREADS", "1")
        .env_remove("OPENBLAS_CORETYPE")
        .env_remove("OPENBLAS_L2_SIZE")
        .output()
        .context("running the Python baseline")?;
    std::fs::remove_dir_all(&dir).ok();
    if !out.status.success() {
        bail!(
            "Python baseline failed: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let j: serde_json::Value = serde_json::from_slice(&out.stdout)?;
    let t = Timing {
        median_us: j["median_us"].as_f64().unwrap_or(f64::NAN),
        mean_us: j["mean_us"].as_f64().unwrap_or(f64::NAN),
    };
    Ok((t, format!("numpy {} opencv {}", j["numpy"], j["opencv"])))
}

pub fn bench_contact(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<ContactBench> {
    let frames = frames(n.max(20));
    let bg = frames.first().context("no frames")?.clone();
    let mut det = ContactDetector::new(ContactParams::default(), SensorKind::GelsightMini.spec())
        .map_err(anyhow::Error::msg)?;
    det.set_background_frame(&bg);
    // Warm-up, then time each step (detection, hysteresis, episodes, background update).
    for f in frames.iter().take(10) {
        let _ = black_box(det.step(f));
    }
    let mut rust = Vec::with_capacity(frames.len() * repeat);
    let mut floor = Vec::with_capacity(frames.len() * repeat);
    for _ in 0..repeat {
        for f in &frames {
            let t0 = Instant::now();
            let _ = black_box(det.step(black_box(f)));
            rust.push(t0.elapsed().as_secs_f64() * 1e6);
            let t0 = Instant::now();
            let s: u64 = black_box(f.data()).iter().map(|&b| u64::from(b)).sum();
            black_box(s);
            floor.push(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    let rust = timing(rust);
    let (python, versions) = if with_python {
        let (t, v) = python_baseline(&frames, &bg, repeat)?;
        (Some(t), v)
    } else {
        (None, String::new())
    };
    let ratio = python.as_ref().map(|p| p.median_us / rust.median_us);
    Ok(ContactBench {
        frame: format!(
            "{}x{} RGB8 (GelSight Mini mock, fabric scene)",
            bg.width, bg.height
        ),
        frames_timed: frames.len() * repeat,
        rust,
        python,
        python_versions: versions,
        ratio_median: ratio,
        floor: timing(floor),
        note: "Rust does more per frame than the baseline: drift compensation, noise-adaptive \
               threshold, marker masking, components, hysteresis, episodes, background EMA"
            .into(),
    })
}

impl ContactBench {
    pub fn text(&self) -> String {
        let mut s = format!(
            "contact detection per {} frame, one core, {} frames\n",
            self.frame, self.frames_timed
        );
        s += &format!(
            "  unitac (Rust)          median {:>8.1} us  mean {:>8.1} us\n",
            self.rust.median_us, self.rust.mean_us
        );
        if let Some(p) = &self.python {
            s += &format!(
                "  numpy + OpenCV (gs_sdk) median {:>8.1} us  mean {:>8.1} us  [{}]\n",
                p.median_us, p.mean_us, self.python_versions
            );
        }
        s += &format!(
            "  floor (one read pass)  median {:>8.1} us\n",
            self.floor.median_us
        );
        if let Some(r) = self.ratio_median {
            s += &format!("  speed-up (median): {r:.1}x\n");
        }
        s
    }
}
