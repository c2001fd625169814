//! `unitac-lab bench decode`: GelSight Mini MJPEG 3280x2464 -> 320x240 RGB per frame, side by side in
//! one run with the vendor SDK's OpenCV pipeline (full-size imdecode, crop, resize; one thread),
//! and with the fastest paths a Python user has (OpenCV IMREAD_REDUCED_COLOR_8 / _4, Pillow
//! draft 1/8: libjpeg-turbo's scaled decode), on the same JPEGs; the Rust alternatives
//! (jpeg-decoder, zune-jpeg); restart-marker frames; the floor; plus YUYV / UYVY 320x240 -> RGB
//! (DIGIT) against cv2.cvtColor.
//!
//! Wall time and CPU time are both reported: the JPEG decoder may hand colour conversion to
//! helper threads, so CPU time (all threads of the process) is the fair "share of one core".

use image::codecs::jpeg::JpegEncoder;
use serde::Serialize;
use std::hint::black_box;
use std::time::{Duration, Instant};
use unitac_core::pixel::{Yuv422, yuv422_to_rgb_into};
use unitac_driver::dcjpeg::{BlockRect, DcDecoder};
use unitac_driver::decode::{DecodeConfig, FrameDecoder, PixelFormat, Rgb, crop_resize};

const GS_W: u32 = 3280;
const GS_H: u32 = 2464;
const FPS: f64 = 25.0;

#[derive(Debug, Clone, Copy, Serialize)]
pub struct Timing {
    pub median_s: f64,
    pub mean_s: f64,
    pub cpu_median_s: f64,
    pub cpu_mean_s: f64,
}

/// One pipeline's per-frame time (JPEG bytes in, 320x240 RGB8 out unless said otherwise).
#[derive(Debug, Serialize)]
pub struct Row {
    pub name: String,
    #[serde(flatten)]
    pub t: Timing,
}

#[derive(Debug, Serialize)]
pub struct DecodeBench {
    pub input: String,
    pub frames_timed: usize,
    pub jpeg_bytes_mean: usize,
    /// Same frames re-encoded with a restart marker every MCU row (as many UVC encoders emit).
    pub restart_jpeg_bytes_mean: usize,
    pub dct_scale: u32,
    /// unitac's default path (DC-only 1/8, crop region only).
    pub rust: Timing,
    /// Every unitac / Rust row, the default first.
    pub rust_rows: Vec<Row>,
    /// Every Python row: the vendor pipeline first, then the fastest a Python user has.
    pub python_rows: Vec<Row>,
    pub python_versions: String,
    /// Vendor pipeline median / unitac median, wall and CPU.
    pub ratio_median: Option<f64>,
    pub ratio_cpu_median: Option<f64>,
    /// Fastest Python row (by median) / unitac median.
    pub best_python: Option<String>,
    pub ratio_vs_best_python: Option<f64>,
    /// Share of one core the default path needs at 25 fps (CPU median x 25).
    pub core_share_at_25fps: f64,
    pub fits_25fps_in_fifth_of_a_core: bool,
    /// The vendor pipeline's share of one core at 25 fps.
    pub python_core_share_at_25fps: Option<f64>,
    /// Mean absolute difference, unitac output vs the vendor pipeline's (frame 0, 0..255).
    pub mean_abs_diff_vs_opencv: Option<f64>,
    /// The floor: entropy decoding alone (DC walk over the MCUs the crop needs, no colour
    /// conversion or resize), and one read pass over the JPEG bytes.
    pub floor_entropy: Timing,
    pub floor_byte_pass: Timing,
    pub yuyv_rust: Timing,
    pub uyvy_rust: Timing,
    pub yuyv_python: Option<Timing>,
    pub uyvy_python: Option<Timing>,
    pub yuyv_ratio_median: Option<f64>,
    pub uyvy_ratio_median: Option<f64>,
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
        median_s: w.median_s,
        mean_s: w.mean_s,
        cpu_median_s: c.median_s,
        cpu_mean_s: c.mean_s,
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

/// Restart interval of one MCU row (4:2:0: 16 pixels per MCU), as many UVC encoders emit.
fn jpeg_with_restarts(rgb: &[u8], w: u32, h: u32) -> anyhow::Result<Vec<u8>> {
    let mut out = Vec::new();
    let mut enc = jpeg_encoder::Encoder::new(&mut out, 85);
    enc.set_sampling_factor(jpeg_encoder::SamplingFactor::F_2_2);
    enc.set_restart_interval(u16::try_from(w.div_ceil(16))?);
    enc.encode(
        rgb,
        u16::try_from(w)?,
        u16::try_from(h)?,
        jpeg_encoder::ColorType::Rgb,
    )?;
    Ok(out)
}

/// Time `f` on every JPEG, `repeat` times over.
fn time_each(
    jpegs: &[Vec<u8>],
    repeat: usize,
    mut f: impl FnMut(&[u8]) -> anyhow::Result<()>,
) -> anyhow::Result<Timing> {
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..repeat {
        for j in jpegs {
            let (t0, c0) = (Instant::now(), cpu_now());
            f(black_box(j))?;
            cpu.push((cpu_now().saturating_sub(c0)).as_secs_f64());
            wall.push(t0.elapsed().as_secs_f64());
        }
    }
    Ok(timing(&mut wall, &mut cpu))
}

fn time_decoder(
    cfg: DecodeConfig,
    single_thread: bool,
    jpegs: &[Vec<u8>],
    repeat: usize,
) -> anyhow::Result<(Timing, Vec<u8>, u32)> {
    let mut d = FrameDecoder::new(cfg)?;
    d.set_single_thread(single_thread);
    let first = d.decode(PixelFormat::Mjpg, GS_W, GS_H, &jpegs[0])?.data;
    let t = time_each(jpegs, repeat, |j| {
        black_box(d.decode(PixelFormat::Mjpg, GS_W, GS_H, j)?);
        Ok(())
    })?;
    Ok((t, first, d.last_jpeg_scale))
}

fn python_timing(j: &serde_json::Value) -> Timing {
    let f = |k: &str| j[k].as_f64().unwrap_or(f64::NAN);
    Timing {
        median_s: f("median_s"),
        mean_s: f("mean_s"),
        cpu_median_s: f("cpu_median_s"),
        cpu_mean_s: f("cpu_mean_s"),
    }
}

fn row(name: &str, t: Timing) -> Row {
    Row {
        name: name.to_string(),
        t,
    }
}

fn time_yuv(order: Yuv422, buf: &[u8], repeat: usize) -> anyhow::Result<Timing> {
    let mut out = vec![0u8; 320 * 240 * 3];
    let (mut wall, mut cpu) = (Vec::new(), Vec::new());
    for _ in 0..repeat * 50 {
        let (t0, c0) = (Instant::now(), cpu_now());
        yuv422_to_rgb_into(order, black_box(buf), 320, 240, 640, black_box(&mut out))?;
        cpu.push((cpu_now().saturating_sub(c0)).as_secs_f64());
        wall.push(t0.elapsed().as_secs_f64());
    }
    Ok(timing(&mut wall, &mut cpu))
}

/// The floors a decoder cannot beat: the DC walk over the MCUs the crop needs (the crop's
/// `crop_bottom` share of rows left out; no resize), and one pass reading every byte.
fn floors(jpegs: &[Vec<u8>], repeat: usize, crop_bottom: f64) -> anyhow::Result<(Timing, Timing)> {
    let mut dc = DcDecoder::new();
    let roi = BlockRect {
        x0: 0,
        y0: 0,
        x1: GS_W.div_ceil(8),
        y1: ((1.0 - crop_bottom) * f64::from(GS_H.div_ceil(8))).ceil() as u32 + 2,
    };
    let floor_entropy = time_each(jpegs, repeat, |j| {
        black_box(dc.decode(j, 8192, Some(roi))?);
        Ok(())
    })?;
    let floor_byte_pass = time_each(jpegs, repeat, |j| {
        black_box(j.iter().filter(|&&b| b == 0xFF).count());
        Ok(())
    })?;
    Ok((floor_entropy, floor_byte_pass))
}

/// One 320x240 frame (DIGIT's size) in YUYV and the same in UYVY.
fn yuv_frames() -> (Vec<u8>, Vec<u8>) {
    let yuyv: Vec<u8> = (0..320 * 240 / 2)
        .flat_map(|i: u32| [(16 + i % 200) as u8, 110, (20 + i % 190) as u8, 150])
        .collect();
    let uyvy: Vec<u8> = yuyv
        .chunks_exact(4)
        .flat_map(|q| [q[1], q[0], q[3], q[2]])
        .collect();
    (yuyv, uyvy)
}

/// What the Python baselines measured (`bench/decode_baseline.py`): a row per decoder, the YUYV
/// and UYVY timings, the package versions and the mean absolute difference of OpenCV's output
/// from ours.
#[derive(Default)]
struct PythonDecode {
    rows: Vec<Row>,
    yuv: Option<(Timing, Timing)>,
    versions: String,
    mad: Option<f64>,
}

/// The Python baselines on the same frames (written to a scratch directory, removed after).
fn python_decode(
    jpegs: &[Vec<u8>],
    yuyv: &[u8],
    (crop, tw, th): (f64, u32, u32),
    repeat: usize,
    rust_out: &[u8],
) -> anyhow::Result<PythonDecode> {
    let n = jpegs.len();
    let dir = crate::scratch::new_dir("bench-decode")?;
    for (i, j) in jpegs.iter().enumerate() {
        std::fs::write(dir.join(format!("frame_{i}.jpg")), j)?;
    }
    std::fs::write(dir.join("yuyv.raw"), yuyv)?;
    let args: Vec<std::ffi::OsString> = vec![
        dir.clone().into_os_string(),
        n.to_string().into(),
        format!("{crop}").into(),
        tw.to_string().into(),
        th.to_string().into(),
        "320".into(),
        "240".into(),
        repeat.to_string().into(),
    ];
    let j = crate::bench::run_python_baseline("decode_baseline.py", &args);
    let py_out = std::fs::read(dir.join("py_out.raw")).ok();
    std::fs::remove_dir_all(&dir).ok();
    let j = j?;
    let versions = format!(
        "numpy {} opencv {} pillow {}",
        j["numpy"], j["opencv"], j["pillow"]
    );
    let mut mad = None;
    if let Some(p) = py_out.filter(|p| p.len() == rust_out.len()) {
        let sum: f64 = p
            .iter()
            .zip(rust_out)
            .map(|(&a, &b)| (f64::from(a) - f64::from(b)).abs())
            .sum();
        mad = Some(sum / p.len() as f64);
    }
    let mut rows = Vec::new();
    for (k, name) in [
        ("mjpeg", "OpenCV imdecode full + crop + resize (vendor SDK)"),
        (
            "reduced8",
            "OpenCV imdecode REDUCED_COLOR_8 + crop + resize",
        ),
        (
            "reduced4",
            "OpenCV imdecode REDUCED_COLOR_4 + crop + resize",
        ),
        ("pillow_draft8", "Pillow draft 1/8 + crop + resize"),
    ] {
        rows.push(row(name, python_timing(&j[k])));
    }
    let yuv = Some((python_timing(&j["yuyv"]), python_timing(&j["uyvy"])));
    Ok(PythonDecode {
        rows,
        yuv,
        versions,
        mad,
    })
}

pub fn bench_decode(n: usize, repeat: usize, with_python: bool) -> anyhow::Result<DecodeBench> {
    let n = n.clamp(1, 8);
    let images: Vec<Vec<u8>> = (0..n).map(|i| gel_image(GS_W, GS_H, i)).collect();
    let jpegs: Vec<Vec<u8>> = images
        .iter()
        .map(|im| jpeg(im, GS_W, GS_H))
        .collect::<anyhow::Result<_>>()?;
    let rst_jpegs: Vec<Vec<u8>> = images
        .iter()
        .map(|im| jpeg_with_restarts(im, GS_W, GS_H))
        .collect::<anyhow::Result<_>>()?;
    drop(images);
    let cfg = DecodeConfig::gelsight_mini();
    let crop = cfg.crop.left;
    let (tw, th) = (cfg.out_width, cfg.out_height);
    let (rust, rust_out, scale) = time_decoder(cfg, false, &jpegs, repeat)?;
    let mut rows = vec![row(
        &format!("unitac DC-only 1/{scale} (default)"),
        Timing { ..rust },
    )];
    let (t, _, _) = time_decoder(cfg, false, &rst_jpegs, repeat)?;
    rows.push(row("unitac DC-only 1/8, restart markers, 2 threads", t));
    let (t, _, _) = time_decoder(cfg, true, &rst_jpegs, repeat)?;
    rows.push(row("unitac DC-only 1/8, restart markers, 1 thread", t));
    let mut strict = cfg;
    strict.max_upscale = 1.0;
    let (t, _, s4) = time_decoder(strict, false, &jpegs, repeat.div_ceil(2))?;
    rows.push(row(
        &format!("unitac jpeg-decoder 1/{s4} (max_upscale 1.0)"),
        t,
    ));
    let mut full_cfg = cfg;
    full_cfg.dct_scaling = false;
    let (t, _, _) = time_decoder(full_cfg, false, &jpegs, repeat.div_ceil(2))?;
    rows.push(row("unitac jpeg-decoder full size + crop + resize", t));
    let t = time_each(&jpegs, repeat.div_ceil(2), |j| {
        let opts = zune_jpeg::zune_core::options::DecoderOptions::default()
            .jpeg_set_out_colorspace(zune_jpeg::zune_core::colorspace::ColorSpace::RGB);
        let mut dec = zune_jpeg::JpegDecoder::new_with_options(std::io::Cursor::new(j), opts);
        let data = dec
            .decode()
            .map_err(|e| anyhow::anyhow!("zune-jpeg: {e:?}"))?;
        let full = Rgb {
            width: GS_W,
            height: GS_H,
            data,
        };
        black_box(crop_resize(&full, &cfg.crop, tw, th)?);
        Ok(())
    })?;
    rows.push(row("zune-jpeg full size + crop + resize", t));

    // The floor: the DC walk over the MCUs the crop needs (no resize), and one read pass.
    let (floor_entropy, floor_byte_pass) = floors(&jpegs, repeat, cfg.crop.bottom)?;

    // YUYV / UYVY 320x240 (DIGIT).
    let (yuyv, uyvy) = yuv_frames();
    let yuyv_rust = time_yuv(Yuv422::Yuyv, &yuyv, repeat)?;
    let uyvy_rust = time_yuv(Yuv422::Uyvy, &uyvy, repeat)?;

    let PythonDecode {
        rows: py_rows,
        yuv: py_yuv,
        versions,
        mad,
    } = if with_python {
        python_decode(&jpegs, &yuyv, (crop, tw, th), repeat, &rust_out)?
    } else {
        PythonDecode::default()
    };
    let share = rust.cpu_median_s * FPS;
    let vendor = py_rows.first().map(|r| Timing { ..r.t });
    let best = py_rows
        .iter()
        .min_by(|a, b| a.t.median_s.total_cmp(&b.t.median_s));
    Ok(DecodeBench {
        input: format!(
            "{n} distinct MJPEG {GS_W}x{GS_H} (quality 85, generated gel with markers, noise 1 DN) -> crop 1/7 per side -> {tw}x{th} RGB8"
        ),
        frames_timed: n * repeat,
        jpeg_bytes_mean: jpegs.iter().map(Vec::len).sum::<usize>() / n,
        restart_jpeg_bytes_mean: rst_jpegs.iter().map(Vec::len).sum::<usize>() / n,
        dct_scale: scale,
        ratio_median: vendor.as_ref().map(|p| p.median_s / rust.median_s),
        ratio_cpu_median: vendor.as_ref().map(|p| p.cpu_median_s / rust.cpu_median_s),
        python_core_share_at_25fps: vendor.as_ref().map(|p| p.cpu_median_s * FPS),
        best_python: best.map(|r| r.name.clone()),
        ratio_vs_best_python: best.map(|r| r.t.median_s / rust.median_s),
        core_share_at_25fps: share,
        fits_25fps_in_fifth_of_a_core: share < 0.20,
        mean_abs_diff_vs_opencv: mad,
        floor_entropy,
        floor_byte_pass,
        rust,
        rust_rows: rows,
        python_rows: py_rows,
        python_versions: versions,
        yuyv_ratio_median: py_yuv
            .as_ref()
            .map(|(y, _)| y.median_s / yuyv_rust.median_s),
        uyvy_ratio_median: py_yuv
            .as_ref()
            .map(|(_, u)| u.median_s / uyvy_rust.median_s),
        yuyv_python: py_yuv.as_ref().map(|(y, _)| Timing { ..*y }),
        uyvy_python: py_yuv.map(|(_, u)| u),
        yuyv_rust,
        uyvy_rust,
    })
}

impl DecodeBench {
    pub fn text(&self) -> String {
        let line = |name: &str, t: &Timing| {
            format!(
                "  {name:<52} median {:>8.1} us  mean {:>8.1} us  cpu median {:>8.1} us\n",
                t.median_s * 1e6,
                t.mean_s * 1e6,
                t.cpu_median_s * 1e6
            )
        };
        let mut s = format!(
            "GelSight Mini decode per frame: {}\n  {} frames timed, JPEG {} kB mean ({} kB with restart markers)\n",
            self.input,
            self.frames_timed,
            self.jpeg_bytes_mean / 1000,
            self.restart_jpeg_bytes_mean / 1000
        );
        for r in &self.rust_rows {
            s += &line(&r.name, &r.t);
        }
        for r in &self.python_rows {
            s += &line(&r.name, &r.t);
        }
        if !self.python_versions.is_empty() {
            s += &format!("  [{}]\n", self.python_versions);
        }
        s += &line(
            "floor: DC walk of the MCUs the crop needs, no resize",
            &self.floor_entropy,
        );
        s += &line(
            "floor: one read pass over the JPEG bytes",
            &self.floor_byte_pass,
        );
        if let (Some(r), Some(c)) = (self.ratio_median, self.ratio_cpu_median) {
            s += &format!(
                "  speed-up vs the vendor pipeline (median): {r:.1}x wall, {c:.1}x CPU (goal >= 8x)\n"
            );
        }
        if let (Some(b), Some(r)) = (&self.best_python, self.ratio_vs_best_python) {
            s += &format!("  speed-up vs the fastest Python row ({b}): {r:.2}x wall\n");
        }
        s += &format!(
            "  25 fps needs {:.1} % of one core (goal < 20 %): {}\n",
            self.core_share_at_25fps * 100.0,
            if self.fits_25fps_in_fifth_of_a_core {
                "fits"
            } else {
                "does not fit"
            }
        );
        if let Some(p) = self.python_core_share_at_25fps {
            s += &format!(
                "  the vendor pipeline at 25 fps would need {:.0} % of one core\n",
                p * 100.0
            );
        }
        if let Some(m) = self.mean_abs_diff_vs_opencv {
            s += &format!("  mean |unitac - vendor pipeline| on frame 0: {m:.2} DN\n");
        }
        s += "YUV 4:2:2 320x240 -> RGB8 per frame (DIGIT)\n";
        s += &line("unitac YUYV (unitac_core::pixel)", &self.yuyv_rust);
        if let Some(y) = &self.yuyv_python {
            s += &line("cv2.cvtColor(YUV2RGB_YUYV)", y);
        }
        s += &line("unitac UYVY", &self.uyvy_rust);
        if let Some(y) = &self.uyvy_python {
            s += &line("cv2.cvtColor(YUV2RGB_UYVY)", y);
        }
        if let (Some(a), Some(b)) = (self.yuyv_ratio_median, self.uyvy_ratio_median) {
            s += &format!("  OpenCV / unitac (median): YUYV {a:.2}x, UYVY {b:.2}x\n");
        }
        s
    }
}
