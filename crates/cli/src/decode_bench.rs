//! `unitac bench decode`: GelSight Mini MJPEG 3280x2464 -> 320x240 RGB per frame, side by side in
//! one run with the vendor SDK's OpenCV pipeline (full-size imdecode, crop, resize; one thread),
//! on the same JPEGs; plus YUYV 320x240 -> RGB (DIGIT) against cv2.cvtColor.
//!
//! Wall time and CPU time are both reported: the JPEG decoder may hand colour conversion to
//! helper threads, so CPU time (all threads of the process) is the fair "share of one core".

use image::codecs::jpeg::JpegEncoder;
use serde::Serialize;
use std::hint::black_box;
use std::time::{Duration, Instant};
use unitac_driver::decode::{DecodeConfig, FrameDecoder, PixelFormat, yuyv_to_rgb};

const GS_W: u32 = 3280;
const GS_H: u32 = 2464;
const FPS: f64 = 25.0;

#[derive(Debug, Serialize)]
pub struct Timing {
    pub median_us: f64,
    pub mean_us: f64,
    pub cpu_median_us: f64,
    pub cpu_mean_us: f64,
}

#[derive(Debug, Serialize)]
pub struct DecodeBench {
    pub input: String,
    pub frames_timed: usize,
    pub jpeg_bytes_mean: usize,
    pub dct_scale: u32,
    pub rust: Timing,
    /// Same Rust pipeline with DCT-domain scaling off (full-size decode, then crop + resize).
    pub rust_full_decode: Timing,
    /// `max_upscale: 1.0` (never upsample): GelSight Mini at 1/4.
    pub rust_strict: Timing,
    pub strict_scale: u32,
    pub python: Option<Timing>,
    pub python_versions: String,
    /// Python median / Rust median, wall and CPU.
    pub ratio_median: Option<f64>,
    pub ratio_cpu_median: Option<f64>,
    /// Share of one core the Rust decode needs at 25 fps (CPU median x 25).
    pub core_share_at_25fps: f64,
    pub fits_25fps_in_quarter_core: bool,
    /// Python's share of one core at 25 fps.
    pub python_core_share_at_25fps: Option<f64>,
    /// Mean absolute difference, Rust output vs OpenCV output (frame 0, 0..255).
    pub mean_abs_diff_vs_opencv: Option<f64>,
    pub yuyv_rust: Timing,
    pub yuyv_python: Option<Timing>,
    pub yuyv_ratio_median: Option<f64>,
}

fn cpu_now() -> Duration {
    let t = rustix::time::clock_gettime(rustix::time::ClockId::ProcessCPUTime);
    Duration::new(
        u64::try_from(t.tv_sec).unwrap_or(0),
        u32::try_from(t.tv_nsec).unwrap_or(0),
    )
}

fn timing(wall: &mut Vec<f64>, cpu: &mut Vec<f64>) -> Timing {
    let (w, c) = (
        unitac_core::timing(std::mem::take(wall)),
        unitac_core::timing(std::mem::take(cpu)),
    );
    Timing {
        median_us: w.median_us,
        mean_us: w.mean_us,
        cpu_median_us: c.median_us,
        cpu_mean_us: c.mean_us,
    }
}

/// A lit gel as GelSight Mini shows it: smooth illumination gradient, a grid of dark marker
/// dots, two soft contacts that move from frame to frame, and sensor noise of about 1 DN.
fn gel_image(w: u32, h: u32, i: usize) -> Vec<u8> {
    let mut v = Vec::with_capacity(w as usize * h as usize * 3);
    let s = i as f32 * 0.07;
    let pitch = w / 24;
    let dot_r2 = (pitch / 8).pow(2) as i64;
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / w as f32, y as f32 / h as f32);
            let blob = |cx: f32, cy: f32, r: f32| {
                let d = ((fx - cx).powi(2) + (fy - cy).powi(2)).sqrt() / r;
                (1.0 - d).max(0.0) * 40.0
            };
            let b = blob(0.3 + s, 0.5, 0.12) + blob(0.7, 0.3 + s, 0.08);
            let (dx, dy) = (
                i64::from(x % pitch) - i64::from(pitch / 2),
                i64::from(y % pitch) - i64::from(pitch / 2),
            );
            let marker = if dx * dx + dy * dy < dot_r2 {
                70.0
            } else {
                0.0
            };
            let hash = (x.wrapping_mul(73_856_093) ^ y.wrapping_mul(19_349_663))
                .wrapping_add(i as u32 * 83_492_791);
            let noise = |k: u32| ((hash >> (k * 3 + 7)) % 3) as f32 - 1.0;
            let px = |base: f32, k: u32| (base - marker + noise(k)).clamp(0.0, 255.0) as u8;
            v.push(px(90.0 + 80.0 * fx + b, 0));
            v.push(px(70.0 + 90.0 * fy - b * 0.5, 1));
            v.push(px(150.0 - 40.0 * fx + b * 0.3, 2));
        }
    }
    v
}

fn jpeg(rgb: &[u8], w: u32, h: u32) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    JpegEncoder::new_with_quality(&mut out, 85).encode(
        rgb,
        w,
        h,
        image::ExtendedColorType::Rgb8,
    )?;
    Ok(out)
}

fn time_decoder(
    cfg: DecodeConfig,
    jpegs: &[Vec<u8>],
    repeat: usize,
) -> anyhow::Result<(Timing, Vec<u8>, u32)> {
    let mut d = FrameDecoder::new(cfg)?;
    let first = d.decode(PixelFormat::Mjpg, GS_W, GS_H, &jpegs[0])?.data;
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..repeat {
        for j in jpegs {
            let (t0, c0) = (Instant::now(), cpu_now());
            let out = d.decode(PixelFormat::Mjpg, GS_W, GS_H, black_box(j))?;
            black_box(out);
            cpu.push((cpu_now().saturating_sub(c0)).as_secs_f64() * 1e6);
            wall.push(t0.elapsed().as_secs_f64() * 1e6);
        }
    }
    Ok((timing(&mut wall, &mut cpu), first, d.last_jpeg_scale))
}

fn python_timing(j: &serde_json::Value) -> Timing {
    let f = |k: &str| j[k].as_f64().unwrap_or(f64::NAN);
    Timing {
        median_us: f("median_us"),
        mean_us: f("mean_us"),
        cpu_median_us: f("cpu_median_us"),
        cpu_mean_us: f("cpu_mean_us"),
    }
}

pub fn bench_decode(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<DecodeBench> {
    let n = n.clamp(1, 8);
    let jpegs: Vec<Vec<u8>> = (0..n)
        .map(|i| jpeg(&gel_image(GS_W, GS_H, i), GS_W, GS_H))
        .collect::<anyhow::Result<_>>()?;
    let cfg = DecodeConfig::gelsight_mini();
    let crop = cfg.crop.left;
    let (rust, rust_out, scale) = time_decoder(cfg, &jpegs, repeat)?;
    let mut full_cfg = cfg;
    full_cfg.dct_scaling = false;
    let (rust_full, _, _) = time_decoder(full_cfg, &jpegs, repeat.div_ceil(2))?;
    // The strict variant: never upsample (GelSight Mini then decodes at 1/4).
    let mut eighth_cfg = cfg;
    eighth_cfg.max_upscale = 1.0;
    let (rust_eighth, _, eighth_scale) = time_decoder(eighth_cfg, &jpegs, repeat)?;

    // YUYV 320x240 (DIGIT).
    let yuyv: Vec<u8> = (0..320 * 240 / 2)
        .flat_map(|i: u32| [(16 + i % 200) as u8, 110, (20 + i % 190) as u8, 150])
        .collect();
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..repeat * 50 {
        let (t0, c0) = (Instant::now(), cpu_now());
        black_box(yuyv_to_rgb(black_box(&yuyv), 320, 240)?);
        cpu.push((cpu_now().saturating_sub(c0)).as_secs_f64() * 1e6);
        wall.push(t0.elapsed().as_secs_f64() * 1e6);
    }
    let yuyv_rust = timing(&mut wall, &mut cpu);

    let mut py = None;
    let mut versions = String::new();
    let mut mad = None;
    if with_python {
        let dir = std::env::temp_dir().join(format!("unitac-bench-decode-{}", std::process::id()));
        std::fs::create_dir_all(&dir)?;
        for (i, j) in jpegs.iter().enumerate() {
            std::fs::write(dir.join(format!("frame_{i}.jpg")), j)?;
        }
        std::fs::write(dir.join("yuyv.raw"), &yuyv)?;
        let args: Vec<std::ffi::OsString> = vec![
            dir.clone().into_os_string(),
            n.to_string().into(),
            format!("{crop}").into(),
            cfg.out_width.to_string().into(),
            cfg.out_height.to_string().into(),
            "320".into(),
            "240".into(),
            repeat.to_string().into(),
        ];
        let j = crate::bench::run_python_baseline("decode_baseline.py", &args);
        let py_out = std::fs::read(dir.join("py_out.raw")).ok();
        std::fs::remove_dir_all(&dir).ok();
        let j = j?;
        versions = format!("numpy {} opencv {}", j["numpy"], j["opencv"]);
        if let Some(p) = py_out.filter(|p| p.len() == rust_out.len()) {
            let sum: f64 = p
                .iter()
                .zip(&rust_out)
                .map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs())
                .sum();
            mad = Some(sum / p.len() as f64);
        }
        py = Some((python_timing(&j["mjpeg"]), python_timing(&j["yuyv"])));
    }
    let share = rust.cpu_median_us * 1e-6 * FPS;
    Ok(DecodeBench {
        input: format!(
            "{n} distinct MJPEG {GS_W}x{GS_H} (quality 85, generated gel with markers, noise 1 DN) -> crop 1/7 per side -> {}x{} RGB8",
            cfg.out_width, cfg.out_height
        ),
        frames_timed: n * repeat,
        jpeg_bytes_mean: jpegs.iter().map(Vec::len).sum::<usize>() / n,
        dct_scale: scale,
        ratio_median: py.as_ref().map(|(p, _)| p.median_us / rust.median_us),
        ratio_cpu_median: py
            .as_ref()
            .map(|(p, _)| p.cpu_median_us / rust.cpu_median_us),
        python_core_share_at_25fps: py.as_ref().map(|(p, _)| p.cpu_median_us * 1e-6 * FPS),
        yuyv_ratio_median: py.as_ref().map(|(_, y)| y.median_us / yuyv_rust.median_us),
        core_share_at_25fps: share,
        fits_25fps_in_quarter_core: share <= 0.25,
        mean_abs_diff_vs_opencv: mad,
        rust,
        rust_full_decode: rust_full,
        rust_strict: rust_eighth,
        strict_scale: eighth_scale,
        python_versions: versions,
        yuyv_python: py.as_ref().map(|(_, y)| Timing { ..*y }),
        python: py.map(|(p, _)| p),
        yuyv_rust,
    })
}

impl DecodeBench {
    pub fn text(&self) -> String {
        let row = |name: &str, t: &Timing| {
            format!(
                "  {name:<34} median {:>9.1} us  mean {:>9.1} us  cpu median {:>9.1} us\n",
                t.median_us, t.mean_us, t.cpu_median_us
            )
        };
        let mut s = format!(
            "GelSight Mini decode per frame: {}\n  {} frames timed, JPEG {} kB mean\n",
            self.input,
            self.frames_timed,
            self.jpeg_bytes_mean / 1000
        );
        s += &row(
            &format!("unitac (DCT 1/{}, default)", self.dct_scale),
            &self.rust,
        );
        s += &row(
            &format!("unitac (DCT 1/{}, max_upscale 1.0)", self.strict_scale),
            &self.rust_strict,
        );
        s += &row("unitac, full-size decode", &self.rust_full_decode);
        if let Some(p) = &self.python {
            s += &row("OpenCV imdecode+crop+resize", p);
            s += &format!("  [{}]\n", self.python_versions);
        }
        if let (Some(r), Some(c)) = (self.ratio_median, self.ratio_cpu_median) {
            s += &format!("  speed-up (median): {r:.1}x wall, {c:.1}x CPU (goal >= 8x)\n");
        }
        s += &format!(
            "  25 fps needs {:.1} % of one core (budget 25 %): {}\n",
            self.core_share_at_25fps * 100.0,
            if self.fits_25fps_in_quarter_core {
                "fits"
            } else {
                "does not fit"
            }
        );
        if let Some(p) = self.python_core_share_at_25fps {
            s += &format!(
                "  OpenCV at 25 fps would need {:.0} % of one core\n",
                p * 100.0
            );
        }
        if let Some(m) = self.mean_abs_diff_vs_opencv {
            s += &format!("  mean |unitac - OpenCV| on frame 0: {m:.2} DN\n");
        }
        s += "YUYV 320x240 -> RGB8 per frame (DIGIT)\n";
        s += &row("unitac", &self.yuyv_rust);
        if let Some(y) = &self.yuyv_python {
            s += &row("cv2.cvtColor(YUV2RGB_YUYV)", y);
        }
        if let Some(r) = self.yuyv_ratio_median {
            s += &format!("  ratio (median): {r:.2}x\n");
        }
        s
    }
}
