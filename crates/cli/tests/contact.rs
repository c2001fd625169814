//! `unitac contact`: the command-line contract of DESIGN.md on mock-sensor images.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use unitac_core::SensorKind;
use unitac_sim::{MockConfig, MockSensor, Scenario};

fn dir() -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-contact-cli-{}", std::process::id()));
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn save_rgb(path: &Path, f: &unitac_core::Frame) {
    image::RgbImage::from_raw(f.width, f.height, f.data().to_vec())
        .unwrap()
        .save(path)
        .unwrap();
}

/// A frame as a JPEG at quality 95.
fn jpeg(f: &unitac_core::Frame) -> Vec<u8> {
    let img = image::RgbImage::from_raw(f.width, f.height, f.data().to_vec()).unwrap();
    let mut out = Vec::new();
    image::codecs::jpeg::JpegEncoder::new_with_quality(&mut out, 95)
        .encode_image(&img)
        .unwrap();
    out
}

fn run(args: &[&str]) -> (Option<i32>, Vec<Value>, String) {
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .output()
        .unwrap();
    let lines = String::from_utf8(o.stdout)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (
        o.status.code(),
        lines,
        String::from_utf8_lossy(&o.stderr).into_owned(),
    )
}

/// `unitac contact --sensor <sensor> --background <background> --json <files>`.
fn contact_json(
    sensor: &str,
    background: &Path,
    files: &[&Path],
) -> (Option<i32>, Vec<Value>, String) {
    let mut args = vec![
        "contact",
        "--sensor",
        sensor,
        "--background",
        background.to_str().unwrap(),
        "--json",
    ];
    args.extend(files.iter().map(|p| p.to_str().unwrap()));
    run(&args)
}

/// `unitac replay <bag> --fast --json --sensor digit`, which must succeed: its JSON lines and
/// its stderr.
fn replay_digit(bag: &Path) -> (Vec<Value>, String) {
    let (code, lines, stderr) = run(&[
        "replay",
        bag.to_str().unwrap(),
        "--fast",
        "--json",
        "--sensor",
        "digit",
    ]);
    assert_eq!(code, Some(0), "{stderr}");
    (lines, stderr)
}

#[test]
fn contract_on_good_and_bad_files() {
    let d = dir();
    let s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 3),
        Scenario::fabric_selection(),
    );
    let hold = (Scenario::fabric_selection()
        .first_hold_time("fabric_a")
        .unwrap()
        * 25.0) as u64;
    let (bg, press, idle) = (d.join("bg.png"), d.join("press.png"), d.join("idle.jpg"));
    save_rgb(&bg, &s.render(0).0);
    save_rgb(&press, &s.render(hold).0);
    // JPEG at high quality: compression noise must not read as contact.
    std::fs::write(&idle, jpeg(&s.render(3).0)).unwrap();

    // Truncated PNG, zero-byte file, grayscale and 16-bit versions of the press, a 1x1 image.
    let truncated = d.join("truncated.png");
    let bytes = std::fs::read(&press).unwrap();
    std::fs::write(&truncated, &bytes[..bytes.len() / 2]).unwrap();
    let empty = d.join("empty.png");
    std::fs::write(&empty, b"").unwrap();
    let rgb = image::open(&press).unwrap();
    let gray = d.join("gray.png");
    rgb.to_luma8().save(&gray).unwrap();
    let deep = d.join("deep16.png");
    image::DynamicImage::ImageRgb16(rgb.to_rgb16())
        .save(&deep)
        .unwrap();
    let tiny = d.join("tiny.png");
    image::RgbImage::from_pixel(1, 1, image::Rgb([10, 20, 30]))
        .save(&tiny)
        .unwrap();
    let missing = d.join("missing.png");

    let files = [
        &press, &idle, &truncated, &empty, &gray, &deep, &tiny, &missing,
    ];
    let paths: Vec<&Path> = files.iter().map(|p| p.as_path()).collect();
    let (code, lines, stderr) = contact_json("gelsight-mini", &bg, &paths);
    assert_eq!(code, Some(2), "some files failed: exit 2 ({stderr})");
    assert_eq!(lines.len(), files.len(), "one line per file, in order");
    for (l, f) in lines.iter().zip(files) {
        assert_eq!(l["file"], f.to_str().unwrap());
    }
    let by = |p: &PathBuf| &lines[files.iter().position(|f| *f == p).unwrap()];

    let p = by(&press);
    assert_eq!(p["contact"], true);
    let c: Vec<f64> = p["centroid"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        (c[0] - 160.0).abs() < 4.0 && (c[1] - 120.0).abs() < 4.0,
        "{p}"
    );
    let b: Vec<u64> = p["bbox"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_u64().unwrap())
        .collect();
    assert!(
        b[0] < 160 && b[2] > 160 && b[2] <= 320 && b[3] <= 240,
        "{p}"
    );
    assert!(p["area_px"].as_f64().unwrap() > 2000.0 && p["score"].as_f64().unwrap() > 0.0);
    assert_eq!(by(&idle)["contact"], false, "{}", by(&idle));
    // 16-bit PNG: same picture, same answer.
    assert_eq!(by(&deep)["contact"], true);
    assert_eq!(by(&deep)["area_px"], p["area_px"]);
    // Grayscale is converted and processed (a grey image is far from the tinted background).
    assert!(by(&gray).get("contact").is_some(), "{}", by(&gray));
    for (f, needle) in [
        (&truncated, "decode"),
        (&empty, "empty"),
        (&tiny, "1x1"),
        (&missing, "missing.png"),
    ] {
        let e = by(f)["error"]
            .as_str()
            .unwrap_or_else(|| panic!("{}", by(f)));
        assert!(e.contains(needle), "{e}");
    }
}

#[test]
fn all_good_files_exit_0_and_bad_background_exits_2() {
    let d = dir().join("ok");
    std::fs::create_dir_all(&d).unwrap();
    let s = MockSensor::new(MockConfig::new(SensorKind::DIGIT, 1), Scenario::idle(1.0));
    let (bg, f) = (d.join("bg.png"), d.join("f.png"));
    save_rgb(&bg, &s.render(0).0);
    save_rgb(&f, &s.render(1).0);
    let (code, lines, _) = contact_json("digit", &bg, &[&f]);
    assert_eq!(code, Some(0));
    assert_eq!(lines[0]["contact"], false);
    assert_eq!(lines[0]["area_px"], 0.0);
    // The camera noise is estimated from the two frames (the mock renders 1 DN per channel).
    let noise: Vec<f64> = lines[0]["noise_dn"]
        .as_array()
        .unwrap()
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert!(
        noise.len() == 3 && noise.iter().all(|n| (0.7..1.4).contains(n)),
        "{noise:?}"
    );
    let (code, lines, stderr) = run(&[
        "contact",
        "--sensor",
        "digit",
        "--background",
        "/nonexistent.png",
        f.to_str().unwrap(),
    ]);
    assert_eq!(code, Some(2));
    assert!(
        lines.is_empty() && stderr.contains("background") && stderr.trim().lines().count() == 1,
        "{stderr}"
    );
    // A 1x1 background with 1x1 frames runs (the grid shrinks), no panic.
    let (t1, t2) = (d.join("t1.png"), d.join("t2.png"));
    image::RgbImage::from_pixel(1, 1, image::Rgb([100, 100, 100]))
        .save(&t1)
        .unwrap();
    image::RgbImage::from_pixel(1, 1, image::Rgb([200, 100, 100]))
        .save(&t2)
        .unwrap();
    let (code, lines, _) = contact_json("generic", &t1, &[&t2]);
    assert_eq!(code, Some(0));
    assert_eq!(
        lines[0]["contact"], false,
        "one pixel is below the minimum contact area"
    );
}

/// A cut JPEG (the file ends part-way through the scan) is an error for that frame, not a
/// frame whose missing half is filled with grey (a false contact of thousands of pixels); as
/// the background it is exit 2. The same picture whole still reads as it should.
#[test]
fn truncated_jpeg_is_a_frame_error_and_a_bad_background() {
    let d = dir().join("cutjpeg");
    std::fs::create_dir_all(&d).unwrap();
    let s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 5),
        Scenario::fabric_selection(),
    );
    let bg_bytes = jpeg(&s.render(0).0);
    let idle_bytes = jpeg(&s.render(2).0);
    let (bg, idle, cut, cut_bg) = (
        d.join("bg.jpg"),
        d.join("idle.jpg"),
        d.join("cut.jpg"),
        d.join("cut_bg.jpg"),
    );
    std::fs::write(&bg, &bg_bytes).unwrap();
    std::fs::write(&idle, &idle_bytes).unwrap();
    std::fs::write(&cut, &idle_bytes[..idle_bytes.len() / 2]).unwrap();
    std::fs::write(&cut_bg, &bg_bytes[..bg_bytes.len() / 2]).unwrap();
    let (code, lines, stderr) = contact_json("gelsight-mini", &bg, &[&idle, &cut]);
    assert_eq!(code, Some(2), "a bad frame: exit 2 ({stderr})");
    assert_eq!(lines.len(), 2);
    assert_eq!(lines[0]["contact"], false, "{}", lines[0]);
    assert_eq!(lines[1]["file"], cut.to_str().unwrap());
    let e = lines[1]["error"]
        .as_str()
        .unwrap_or_else(|| panic!("a cut JPEG read as a frame: {}", lines[1]));
    assert!(e.contains("cut.jpg") && e.contains("truncated"), "{e}");
    assert!(lines[1].get("contact").is_none(), "{}", lines[1]);

    let (code, lines, stderr) = contact_json("gelsight-mini", &cut_bg, &[&idle]);
    assert_eq!(code, Some(2), "{lines:?}");
    assert!(
        lines.is_empty()
            && stderr.starts_with("unitac:")
            && stderr.contains("background")
            && stderr.contains("truncated")
            && stderr.trim().lines().count() == 1,
        "{stderr}"
    );
}

/// A header over the image size limit names the limit it broke: per side and in all.
#[test]
fn oversized_image_header_states_the_limit() {
    let d = dir().join("huge");
    std::fs::create_dir_all(&d).unwrap();
    let bg = d.join("bg.png");
    image::RgbImage::from_pixel(8, 8, image::Rgb([90, 90, 90]))
        .save(&bg)
        .unwrap();
    let mut files = Vec::new();
    let sizes = [(16_777_216u32, 1u32), (8193, 2), (4097, 4097)];
    for (w, h) in sizes {
        // A PNG header alone (no pixel data) claiming w x h.
        let mut png = b"\x89PNG\r\n\x1a\n\0\0\0\x0dIHDR".to_vec();
        png.extend_from_slice(&w.to_be_bytes());
        png.extend_from_slice(&h.to_be_bytes());
        png.extend_from_slice(&[8, 2, 0, 0, 0]);
        let c = crc32(&png[12..]);
        png.extend_from_slice(&c.to_be_bytes());
        for chunk in [&b"IDAT"[..], b"IEND"] {
            png.extend_from_slice(&[0, 0, 0, 0]);
            png.extend_from_slice(chunk);
            png.extend_from_slice(&crc32(chunk).to_be_bytes());
        }
        let p = d.join(format!("{w}x{h}.png"));
        std::fs::write(&p, png).unwrap();
        files.push(p);
    }
    let paths: Vec<&Path> = files.iter().map(PathBuf::as_path).collect();
    let (code, lines, _) = contact_json("generic", &bg, &paths);
    assert_eq!(code, Some(2));
    for ((w, h), l) in sizes.iter().zip(&lines) {
        let e = l["error"].as_str().unwrap();
        assert!(
            e.ends_with(&format!(
                "image is {w}x{h}: the limit is 1..=8192 pixels a side and 16777216 pixels in all"
            )),
            "{e}"
        );
    }
}

fn crc32(data: &[u8]) -> u32 {
    let mut c = 0xFFFF_FFFFu32;
    for &b in data {
        c ^= u32::from(b);
        for _ in 0..8 {
            c = if c & 1 != 0 {
                0xEDB8_8320 ^ (c >> 1)
            } else {
                c >> 1
            };
        }
    }
    !c
}

/// A bag whose CompressedImage messages include a cut JPEG: replay reports that message as a
/// failed image message (an error line), not a contact state.
#[test]
fn replay_counts_a_cut_jpeg_message_as_a_failed_image() {
    use unitac_bag::{BagWriter, CompressedImage, WriteOptions};
    let d = dir().join("cutbag");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let s = MockSensor::new(MockConfig::new(SensorKind::DIGIT, 6), Scenario::idle(2.0));
    let mut w = BagWriter::create(&d.join("bag"), WriteOptions::default()).unwrap();
    let t = w
        .add_topic(
            "/digit/image_raw/compressed",
            "sensor_msgs/msg/CompressedImage",
        )
        .unwrap();
    let n = 30;
    let cut_at = 20;
    for k in 0..n {
        let f = s.render(k).0;
        let mut data = jpeg(&f);
        if k == cut_at {
            data.truncate(data.len() / 2);
        }
        let msg = CompressedImage {
            header: unitac_core::msg::Header::new(f.stamp, "digit_optical_frame"),
            format: "jpeg".into(),
            data,
        };
        w.write(t, f.stamp.0, &msg).unwrap();
    }
    let path = w.finish().unwrap();
    let (lines, stderr) = replay_digit(&path);
    assert_eq!(lines.len(), n as usize);
    let errors: Vec<usize> = (0..lines.len())
        .filter(|&i| lines[i].get("error").is_some())
        .collect();
    assert_eq!(errors, vec![cut_at as usize], "{lines:?}");
    assert!(
        !lines[cut_at as usize]["contact"].is_boolean(),
        "{}",
        lines[cut_at as usize]
    );
    assert!(lines.iter().all(|l| l["contact"] != true), "{lines:?}");
    assert!(stderr.contains("1 of 30"), "{stderr}");
}

/// A sensor that changes resolution: a bag whose first image is 32x24 and the next 60
/// are 64x48. The odd first frame does not lock the stage: the new size is learned after a few
/// frames, and contact states come out for the rest.
#[test]
fn replay_learns_a_new_frame_size() {
    use unitac_bag::{BagWriter, Image, WriteOptions};
    let d = dir().join("resize");
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    let bag = d.join("bag");
    let spec = |w, h| unitac_core::SensorSpec {
        width: w,
        height: h,
        mm_per_px: 0.0405 * 320.0 / f64::from(w),
        ..SensorKind::DIGIT.spec()
    };
    let small = MockSensor::with_spec(
        MockConfig::new(SensorKind::DIGIT, 4),
        spec(32, 24),
        Scenario::idle(1.0),
    )
    .unwrap();
    let large = MockSensor::with_spec(
        MockConfig::new(SensorKind::DIGIT, 4),
        spec(64, 48),
        Scenario::idle(2.0),
    )
    .unwrap();
    let mut w = BagWriter::create(&bag, WriteOptions::default()).unwrap();
    let t = w
        .add_topic("/digit/image_raw", "sensor_msgs/msg/Image")
        .unwrap();
    let first = small.render(0).0;
    w.write(t, first.stamp.0, &Image::rgb8(&first)).unwrap();
    for k in 1..=60 {
        let f = large.render(k).0;
        w.write(t, f.stamp.0, &Image::rgb8(&f)).unwrap();
    }
    let path = w.finish().unwrap();
    let (lines, _) = replay_digit(&path);
    assert_eq!(lines.len(), 61);
    let errors = lines.iter().filter(|l| l.get("error").is_some()).count();
    let states = lines.iter().filter(|l| l["contact"].is_boolean()).count();
    // new_size_frames (5) in a row re-learn: 4 rejected, then 10 learning frames.
    assert_eq!((errors, states), (4, 60 - 4 - 10), "{lines:?}");
    assert!(lines.iter().all(|l| l["contact"] != true));
}

/// The fixtures through the command line: DIGIT's large press (60 % of the gel) and a
/// light one under 40 DN of shading and 8 DN of noise at 640x480, and the same with no press,
/// each against one background image. `unitac contact` says what the library's detector says
/// (same area, centroid and contact, so the same code path), the press's area is within x1.5 of
/// the true disc, and the idle frame is no contact.
#[test]
fn degraded_presses_read_as_the_detector_reads_them() {
    use unitac_contact::{ContactDetector, ContactParams};
    use unitac_sim::Object;
    use unitac_sim::degrade::{Degrade, idle_fixture, press_fixture};
    let d = dir().join("degraded");
    std::fs::create_dir_all(&d).unwrap();
    let kind = SensorKind::DIGIT;
    let spec = kind.spec().scaled(2);
    let cfg = MockConfig::new(kind, 42);
    let deg = |seed| Degrade {
        shading_dn: 40.0,
        noise_dn: 8.0,
        shift: (0, 0),
        seed,
    };
    let mut cases = Vec::new();
    for (name, obj, depth) in [
        ("large", Object::sphere("p", 12.0), 1.0),
        ("light", Object::sphere("p", 4.0), 0.1),
    ] {
        let fx = press_fixture(&cfg, spec, &Scenario::held(&obj, depth, 1.0), "p", deg(7)).unwrap();
        cases.push((name, fx.background, fx.frame, Some(fx.contact_px)));
    }
    let (bg, idle) = idle_fixture(&cfg, spec, deg(8)).unwrap();
    cases.push(("idle", bg, idle, None));
    for (name, bg, frame, truth) in cases {
        let (bp, fp) = (
            d.join(format!("{name}-bg.png")),
            d.join(format!("{name}.png")),
        );
        save_rgb(&bp, &bg);
        save_rgb(&fp, &frame);
        let (code, lines, stderr) = contact_json("digit", &bp, &[&fp]);
        assert_eq!(code, Some(0), "{name}: {stderr}");
        let l = &lines[0];
        let mut det = ContactDetector::new(ContactParams::default(), kind.spec()).unwrap();
        det.set_background_frame(&bg);
        let m = det.measure(&frame).unwrap();
        assert_eq!(l["contact"], m.contact, "{name}: {l} vs {m:?}");
        assert_eq!(
            l["area_px"].as_f64().unwrap(),
            f64::from(m.area_px),
            "{name}: {l}"
        );
        assert_eq!(
            l["centroid"][0].as_f64().unwrap(),
            f64::from(m.centroid[0]),
            "{name}"
        );
        match truth {
            Some(px) => {
                let ratio = f64::from(m.area_px) / f64::from(px);
                assert!(
                    m.contact && (1.0 / 1.5..=1.5).contains(&ratio),
                    "{name}: x{ratio:.2}"
                );
            }
            None => assert!(!m.contact, "{name}: {l}"),
        }
    }
}

/// Ball presses on the finite-element skirt (`unitac calibrate mock-presses`): the contact
/// region ends at each press's ridge, near the Hertz disc the renderer draws; with
/// `--no-peel-skirt` the residual's half-level contour takes the skirt's flank in, larger.
#[test]
fn ball_presses_read_near_the_hertz_disc_and_larger_without_the_peel() {
    let d = dir().join("ball");
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(["calibrate", "mock-presses", "--count", "8", "--seed", "3"])
        .arg("--out")
        .arg(&d)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let truth: Vec<Value> =
        serde_json::from_str(&std::fs::read_to_string(d.join("truth.json")).unwrap()).unwrap();
    let bg = d.join("background.png");
    let files: Vec<String> = truth
        .iter()
        .map(|t| d.join(t["file"].as_str().unwrap()).display().to_string())
        .collect();
    let read = |extra: &[&str]| {
        let mut args = vec![
            "contact",
            "--sensor",
            "gelsight-mini",
            "--json",
            "--background",
            bg.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        args.extend(files.iter().map(String::as_str));
        let (code, lines, err) = run(&args);
        assert_eq!(code, Some(0), "{err}");
        assert_eq!(lines.len(), truth.len());
        lines
    };
    let (peeled, half) = (read(&[]), read(&["--no-peel-skirt"]));
    for ((t, p), h) in truth.iter().zip(&peeled).zip(&half) {
        let r = t["contact_radius_px"].as_f64().unwrap();
        let disc = std::f64::consts::PI * r * r;
        let (ap, ah) = (
            p["area_px"].as_f64().unwrap(),
            h["area_px"].as_f64().unwrap(),
        );
        assert!(
            (0.85..=1.35).contains(&(ap / disc)),
            "{t} {p}: {}",
            ap / disc
        );
        assert!(ah > 1.25 * ap, "{t}: half-level {ah} px, peeled {ap} px");
        let c = &p["centroid"];
        let off = (c[0].as_f64().unwrap() - t["x"].as_f64().unwrap())
            .hypot(c[1].as_f64().unwrap() - t["y"].as_f64().unwrap());
        assert!(off < 0.2 * r, "{t} {p}");
    }
}

/// Without a calibration, depth comes from the kind's default photometric model where it has one
/// (GelSight Mini: `depth.model` says so), not for a kind without one (DIGIT), and frames of
/// another aspect ratio than the model's get a warning and no depth, the contact line as ever.
#[test]
fn depth_without_a_calibration_comes_from_the_kinds_model_where_it_has_one() {
    let d = dir().join("kind-depth");
    std::fs::create_dir_all(&d).unwrap();
    let s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 3),
        Scenario::fabric_selection(),
    );
    let (bg, press) = (d.join("bg.png"), d.join("press.png"));
    save_rgb(&bg, &s.render(0).0);
    save_rgb(&press, &s.render(40).0);
    let (code, lines, _) = contact_json("gelsight-mini", &bg, &[&press]);
    assert_eq!(code, Some(0));
    assert_eq!(lines[0]["depth"]["model"], "kind default", "{}", lines[0]);
    let (code, lines, _) = contact_json("digit", &bg, &[&press]);
    assert_eq!(code, Some(0));
    assert!(lines[0].get("depth").is_none(), "{}", lines[0]);
    // A portrait frame (the GelSight Mini model is for 4:3 landscape).
    let turn = |src: &Path, dst: &Path| {
        let img = image::open(src).unwrap().rotate90();
        img.save(dst).unwrap();
    };
    let (bg_t, press_t) = (d.join("bg_t.png"), d.join("press_t.png"));
    turn(&bg, &bg_t);
    turn(&press, &press_t);
    let (code, lines, err) = contact_json("gelsight-mini", &bg_t, &[&press_t]);
    assert_eq!(code, Some(0), "{err}");
    assert!(lines[0].get("depth").is_none(), "{}", lines[0]);
    assert!(lines[0]["area_px"].as_f64().unwrap() > 0.0, "{}", lines[0]);
    assert!(
        err.matches("no depth from the gelsight-mini profile's photometric model")
            .count()
            == 1,
        "{err}"
    );
    std::fs::remove_dir_all(&d).ok();
}
