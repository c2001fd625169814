//! Hostile input and faults at the command line: closed and full stdout, oversized
//! images, bad configuration, corrupt and cut bags, full disks, endless replays. Each test failed
//! on the code before the fix it guards. `unitac-lab`'s: crates/lab/tests/hostile.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use unitac_bag::ros::Image;
use unitac_bag::{BagWriter, WriteOptions};
use unitac_core::{SensorKind, Source};
use unitac_sim::{MockConfig, MockSensor, Scenario};

mod common;

fn unitac(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .env("RUST_LOG", "warn")
        .output()
        .unwrap()
}

fn tmpdir(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("unitac-hostile-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

/// Exit `code`, exactly one line on stderr containing `needle`, no panic.
fn assert_one_line(o: &Output, code: i32, needle: &str) {
    let e = stderr(o);
    assert_eq!(o.status.code(), Some(code), "stderr: {e}");
    assert_eq!(e.trim_end().lines().count(), 1, "one line: {e}");
    assert!(e.contains(needle), "expected '{needle}' in: {e}");
    assert!(!e.contains("panicked"), "{e}");
}

/// The mock fabric scene's first `n` frames as an rgb8 MCAP bag (a directory or a bare file).
fn mock_bag(path: &Path, n: usize, opts: WriteOptions) {
    let mut s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 7),
        Scenario::fabric_selection(),
    );
    let mut w = BagWriter::create(path, opts).unwrap();
    let t = w
        .add_topic("/gs/image_raw", "sensor_msgs/msg/Image")
        .unwrap();
    for _ in 0..n {
        let Some(f) = s.next_frame().unwrap() else {
            break;
        };
        w.write(t, f.stamp.0, &Image::rgb8(&f)).unwrap();
    }
    w.finish().unwrap();
}

// ---------------------------------------------------------------------------------------------
// Stdout closed or full

#[test]
fn closed_or_full_stdout_is_exit_1_one_line() {
    // `unitac scenes | head -0`: the reader is gone before the first write. Its end of the pipe
    // is closed before the child starts (closing it after the spawn races the child's first
    // write, which a loaded machine lets the child win: the write fits the pipe's buffer).
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .arg("scenes")
        .stdout(writer)
        .stderr(Stdio::piped())
        .output()
        .unwrap();
    assert_one_line(&o, 1, "writing to stdout");
    for args in [&["devices"][..], &["devices", "--json"], &["scenes"]] {
        let o = Command::new(env!("CARGO_BIN_EXE_unitac"))
            .args(args)
            .env("UNITAC_SYSFS_ROOT", "/nonexistent")
            .stdout(std::fs::File::create("/dev/full").unwrap())
            .output()
            .unwrap();
        assert_one_line(&o, 1, "No space left on device");
    }
}

// ---------------------------------------------------------------------------------------------
// Image dimensions before decoding

/// A valid 1-bit grayscale PNG of `w` x `h` zeros, stored (uncompressed) deflate: small to
/// build, and a decoder that trusts it allocates w*h*3 bytes for the RGB copy.
fn zero_png(path: &Path, w: u32, h: u32) {
    fn crc32(data: &[u8]) -> u32 {
        let mut c = !0u32;
        for &b in data {
            c ^= u32::from(b);
            for _ in 0..8 {
                c = if c & 1 != 0 {
                    (c >> 1) ^ 0xedb8_8320
                } else {
                    c >> 1
                };
            }
        }
        !c
    }
    fn chunk(out: &mut Vec<u8>, kind: &[u8], data: &[u8]) {
        out.extend_from_slice(&(data.len() as u32).to_be_bytes());
        let mut body = kind.to_vec();
        body.extend_from_slice(data);
        out.extend_from_slice(&body);
        out.extend_from_slice(&crc32(&body).to_be_bytes());
    }
    let row = 1 + w.div_ceil(8) as usize;
    let raw = vec![0u8; row * h as usize];
    // zlib: header, stored blocks of <= 65535 bytes, adler32 (of zeros: a = 1, b = len mod p).
    let mut z = vec![0x78, 0x01];
    let blocks: Vec<&[u8]> = raw.chunks(65_535).collect();
    for (i, b) in blocks.iter().enumerate() {
        z.push(u8::from(i + 1 == blocks.len()));
        let n = b.len() as u16;
        z.extend_from_slice(&n.to_le_bytes());
        z.extend_from_slice(&(!n).to_le_bytes());
        z.extend_from_slice(b);
    }
    let b = (raw.len() as u64 % 65_521) as u32;
    z.extend_from_slice(&((b << 16) | 1).to_be_bytes());
    let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
    let mut ihdr = Vec::new();
    ihdr.extend_from_slice(&w.to_be_bytes());
    ihdr.extend_from_slice(&h.to_be_bytes());
    ihdr.extend_from_slice(&[1, 0, 0, 0, 0]);
    chunk(&mut png, b"IHDR", &ihdr);
    chunk(&mut png, b"IDAT", &z);
    chunk(&mut png, b"IEND", &[]);
    std::fs::write(path, png).unwrap();
}

/// `unitac contact` under an address-space limit of 512 MiB: decoding an 8192 x 8192 image to
/// RGB needs more than that, checking its header does not.
fn contact_limited(args: &[&str]) -> Output {
    Command::new("bash")
        .arg("-c")
        .arg("ulimit -v 524288 && exec \"$0\" contact --sensor gelsight-mini \"$@\"")
        .arg(env!("CARGO_BIN_EXE_unitac"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn image_dimensions_are_checked_before_decoding() {
    let d = tmpdir("bigimg");
    let (bg, big) = (d.join("bg.png"), d.join("big.png"));
    zero_png(&bg, 64, 48);
    zero_png(&big, 8192, 8192);
    let o = contact_limited(&["--background", bg.to_str().unwrap(), big.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains(
            "image is 8192x8192: the limit is 1..=8192 pixels a side and 16777216 pixels in all"
        ),
        "{out}"
    );
    // A frame within the budget but not the background's size: refused before decoding too.
    let mid = d.join("mid.png");
    zero_png(&mid, 4096, 4096);
    let o = contact_limited(&["--background", bg.to_str().unwrap(), mid.to_str().unwrap()]);
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        out.contains("frame is 4096x4096, the background is 64x48"),
        "{out}"
    );
    // An oversized background is a configuration error.
    let o = contact_limited(&["--background", big.to_str().unwrap(), bg.to_str().unwrap()]);
    assert_one_line(&o, 2, "pixels a side and 16777216 pixels in all");
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------
// Configuration that must be refused at load

fn scene_error(name: &str, text: &str, needle: &str) {
    let d = tmpdir(&format!("cfg-{name}"));
    let p = d.join("s.yaml");
    std::fs::write(&p, text).unwrap();
    let o = unitac(&["run", "--scene", p.to_str().unwrap(), "--fast"]);
    assert_one_line(&o, 2, needle);
    assert!(o.stdout.is_empty(), "{name}");
    std::fs::remove_dir_all(&d).ok();
}

#[test]
fn bad_configuration_is_one_line_exit_2() {
    const SRC: &str = "scene: fabric_selection\nsource: {kind: mock, seed: 7}\n";
    let models = "models:\n  unitac: ${UNITAC_MODELS}/touch/manifest.json\n";
    scene_error(
        "debounce",
        &format!(
            "{SRC}stages: [{{kind: contact, params: {{exit_debounce_frames: 4294967295}}}}]\n"
        ),
        "exit_debounce_frames 4294967295 is outside 0..=1000",
    );
    scene_error(
        "bgdir",
        &format!("{SRC}stages: [{{kind: contact, params: {{background_dir: /nonexistent/bg}}}}]\n"),
        "background_dir /nonexistent/bg is not a directory",
    );
    scene_error(
        "fps",
        "scene: fabric_selection\nsource: {kind: mock, fps: 0.001}\nstages: [{kind: contact}]\n",
        "source.fps: 0.001 is outside [1, 1000]",
    );
    scene_error(
        "empty",
        &format!("{SRC}stages: []\n"),
        "stages: the list is empty",
    );
    scene_error(
        "order",
        &format!(
            "{SRC}{models}stages:\n  - {{kind: encoder, models: [unitac]}}\n  - {{kind: contact}}\n"
        ),
        "encoder needs contact_clip, which a contact stage makes: it must come before it",
    );
    for (name, params, needle) in [
        ("nan", "guidance: .nan", "guidance must be in [0, 100]"),
        (
            "objects",
            "objects: [bottle]",
            "object 'bottle' is of category 'bottle'",
        ),
        ("budget", "budget_s: 1e308", "budget_s 1e308 is outside"),
        ("cuda", "providers: cuda", "provider cuda is not available"),
    ] {
        scene_error(
            name,
            &format!(
                "{SRC}{models}stages:\n  - {{kind: contact}}\n  - {{kind: sampler, models: [unitac], params: {{{params}}}}}\n"
            ),
            needle,
        );
    }
}

#[test]
fn deep_yaml_is_refused_quickly() {
    // 100 000 levels took 30 s before the bound; the bound answers at once.
    let deep = format!(
        "scene: x\nsource: {{kind: mock}}\nstages: [{{kind: contact, params: {{a: {}{}}}}}]\n",
        "[".repeat(100_000),
        "]".repeat(100_000)
    );
    let t0 = std::time::Instant::now();
    scene_error("deep", &deep, "nested more than 64 deep at line 3");
    // A hang guard, not a benchmark: the old parser took 30 s here.
    assert!(t0.elapsed().as_secs() < 10, "{:?}", t0.elapsed());
}

// ---------------------------------------------------------------------------------------------
// One rule for bag errors

#[test]
fn bag_errors_follow_one_rule() {
    let d = tmpdir("bagrule");
    // Missing bag: exit 2, the cause once.
    let missing = d.join("missing");
    for args in [
        vec!["replay", missing.to_str().unwrap(), "--fast"],
        vec![
            "run",
            "--scene",
            "fabric_selection",
            "--fast",
            "--sensor",
            &format!("bag:{}", missing.display()),
        ],
    ] {
        let o = unitac(&args.iter().map(|s| &**s).collect::<Vec<_>>());
        assert_one_line(&o, 2, "No such file or directory");
        assert_eq!(
            stderr(&o).matches("No such file").count(),
            1,
            "{}",
            stderr(&o)
        );
    }
    // A listed data file missing: also a bag that cannot be opened, exit 2.
    let nodata = d.join("nodata");
    mock_bag(&nodata, 3, WriteOptions::default());
    std::fs::remove_file(nodata.join("nodata_0.mcap")).unwrap();
    let o = unitac(&["replay", nodata.to_str().unwrap(), "--fast"]);
    assert_one_line(&o, 2, "listed in metadata.yaml, but there is no such file");
    // The same file listed 50 times.
    let dup = d.join("dup");
    mock_bag(&dup, 3, WriteOptions::default());
    let meta = std::fs::read_to_string(dup.join("metadata.yaml")).unwrap();
    let many = format!("[{}]", vec!["'dup_0.mcap'"; 50].join(", "));
    let meta = meta.replace(
        "relative_file_paths:\n    - 'dup_0.mcap'",
        &format!("relative_file_paths: {many}"),
    );
    std::fs::write(dup.join("metadata.yaml"), meta).unwrap();
    let o = unitac(&["replay", dup.to_str().unwrap(), "--fast"]);
    assert_one_line(&o, 2, "file 'dup_0.mcap' is listed more than once");
    // Corrupt data past the start: exit 1, the reason on stderr (not only in the summary).
    let bad = d.join("bad.mcap");
    mock_bag(
        &bad,
        20,
        WriteOptions {
            chunk_size: 1,
            ..WriteOptions::default()
        },
    );
    let mut bytes = std::fs::read(&bad).unwrap();
    let at = bytes.len() / 2;
    bytes[at..at + 64].fill(0xff);
    std::fs::write(&bad, bytes).unwrap();
    let o = unitac(&[
        "run",
        "--scene",
        "fabric_selection",
        "--fast",
        "--sensor",
        &format!("bag:{}", bad.display()),
    ]);
    assert_one_line(&o, 1, "MCAP");
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------
// Failed images make a non-zero exit; oversized sqlite rows are skipped

#[test]
fn replay_with_failed_images_exits_1_and_says_how_many() {
    let d = tmpdir("failed");
    let p = d.join("b.mcap");
    let mut w = BagWriter::create(&p, WriteOptions::default()).unwrap();
    let t = w
        .add_topic("/gs/image_raw", "sensor_msgs/msg/Image")
        .unwrap();
    let mut s = MockSensor::new(
        MockConfig::new(SensorKind::GELSIGHT_MINI, 7),
        Scenario::fabric_selection(),
    );
    for i in 0..5 {
        let f = s.next_frame().unwrap().unwrap();
        let mut img = Image::rgb8(&f);
        if i > 0 {
            img.encoding = "bayer_rggb8".into();
        }
        w.write(t, f.stamp.0, &img).unwrap();
    }
    w.finish().unwrap();
    let o = unitac(&["replay", p.to_str().unwrap(), "--fast"]);
    assert_eq!(o.status.code(), Some(1), "{}", stderr(&o));
    let e = stderr(&o);
    assert!(e.contains("4 of 5 image messages failed"), "{e}");
    assert_eq!(
        e.matches("bayer_rggb8").count(),
        5,
        "one line per error, and the summary: {e}"
    );
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------
// An endless replay keeps bounded state

/// Messages on `topic` counted in a bag's metadata.yaml (rewritten after every flushed chunk).
fn metadata_count(bag: &Path, topic: &str) -> u64 {
    let meta = std::fs::read_to_string(bag.join("metadata.yaml")).unwrap_or_default();
    let mut lines = meta
        .lines()
        .skip_while(|l| !l.contains(&format!("name: '{topic}'")));
    lines
        .find_map(|l| l.trim().strip_prefix("message_count: "))
        .map(|n| n.parse().unwrap())
        .unwrap_or(0)
}

/// Wait (up to 5 minutes: CI machines are shared) until `bag` counts `n` messages on `topic`.
fn wait_for(bag: &Path, topic: &str, n: u64) {
    let t0 = std::time::Instant::now();
    while metadata_count(bag, topic) < n {
        assert!(t0.elapsed().as_secs() < 300, "{topic} never reached {n}");
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
}

/// An 80 x 60 rgb8 image: a flat textured gel, pressed (a bright 30 x 30 square) or not.
fn gel(i: i64, pressed: bool) -> Image {
    let (w, h) = (80u32, 60u32);
    let mut data = Vec::with_capacity((w * h * 3) as usize);
    for y in 0..h {
        for x in 0..w {
            let v = 100 + ((x * 7 + y * 13) % 5) as u8;
            let v = if pressed && (25..55).contains(&x) && (15..45).contains(&y) {
                v + 60
            } else {
                v
            };
            data.extend_from_slice(&[v, v, v]);
        }
    }
    Image {
        header: unitac_core::msg::Header::new(
            unitac_core::Stamp(1_000_000_000 + i * 33_333_333),
            "gs_optical_frame",
        ),
        height: h,
        width: w,
        encoding: "rgb8".into(),
        is_bigendian: 0,
        step: w * 3,
        data,
    }
}

#[test]
fn looped_replay_lists_a_bounded_number_of_episodes() {
    let d = tmpdir("loop");
    let p = d.join("b.mcap");
    // One press per pass: 12 idle frames (the first pass learns the background), 6 pressed, 6
    // idle.
    let mut w = BagWriter::create(&p, WriteOptions::default()).unwrap();
    let t = w
        .add_topic("/gs/image_raw", "sensor_msgs/msg/Image")
        .unwrap();
    for i in 0..24i64 {
        let img = gel(i, (12..18).contains(&i));
        w.write(t, img.header.stamp.0, &img).unwrap();
    }
    w.finish().unwrap();
    // The output bag's metadata tells how far the endless replay got.
    let out = d.join("out");
    let child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args([
            "replay",
            p.to_str().unwrap(),
            "--fast",
            "--loop",
            "--sensor",
            "generic",
        ])
        .arg("--out")
        .arg(&out)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    wait_for(&out, "/unitac/contact_episode", 110);
    let ok = Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(ok.success());
    let o = child.wait_with_output().unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    let listed = out.lines().filter(|l| l.starts_with("  episode ")).count();
    let total: u64 = out
        .lines()
        .find_map(|l| l.trim().strip_prefix("contact_episode: "))
        .map(|n| n.parse().unwrap())
        .unwrap_or(0);
    assert!(total >= 110, "{out}");
    assert_eq!(listed, 100, "{out}");
    assert!(
        out.contains(&format!("... and {} more episodes", total - 100)),
        "{out}"
    );
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------
// A full disk under --out

#[test]
fn full_disk_under_out_names_the_cause() {
    let d = tmpdir("full");
    let p = d.join("b.mcap");
    mock_bag(&p, 40, WriteOptions::default());
    let mnt = d.join("mnt");
    std::fs::create_dir_all(&mnt).unwrap();
    // A 256 KiB tmpfs in a private mount namespace (as root; CI runs ROS tests the same way).
    let o = Command::new("unshare")
        .args(["-m", "--", "bash", "-c"])
        .arg("mount -t tmpfs -o size=256k none \"$1\" && exec \"$0\" replay \"$2\" --fast --out \"$1/out\"")
        .arg(env!("CARGO_BIN_EXE_unitac"))
        .arg(&mnt)
        .arg(&p)
        .output()
        .unwrap();
    assert_one_line(&o, 1, "No space left on device");
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------
// A recording killed with SIGKILL, repaired, read by rosbags

fn python() -> PathBuf {
    let root = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..");
    root.join(".venv/bin/python")
}

#[test]
fn killed_recording_is_repaired_and_rosbags_reads_every_recovered_frame() {
    let d = tmpdir("killed");
    let input = d.join("in.mcap");
    mock_bag(&input, 140, WriteOptions::default());
    // A real recorder: `unitac replay --out` in real time (5.6 s for the bag), killed with
    // SIGKILL once a few 1 MiB chunks (about 4 frames each) are on disk.
    let rec = d.join("rec");
    let mut child = Command::new(env!("CARGO_BIN_EXE_unitac"))
        .args(["replay", input.to_str().unwrap(), "--rate", "1", "--out"])
        .arg(&rec)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    wait_for(&rec, "/gs/image_raw", 12);
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    // What `unitac replay` recovers from the cut recording.
    let o = unitac(&["replay", rec.to_str().unwrap(), "--fast", "--json"]);
    assert!(stderr(&o).contains("cut short"), "{}", stderr(&o));
    let recovered: Vec<i64> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .map(|l| {
            serde_json::from_str::<serde_json::Value>(l).unwrap()["stamp"]
                .as_i64()
                .unwrap()
        })
        .collect();
    assert!(
        recovered.len() >= 12 && recovered.len() < 140,
        "{} frames recovered",
        recovered.len()
    );
    // rosbags cannot read the cut recording ...
    let read = |bag: &Path| {
        Command::new(python())
            .arg(PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../tests/bag/read_bag.py"))
            .arg(bag)
            .output()
            .unwrap()
    };
    assert!(!read(&rec).status.success());
    // ... and reads the repaired one, with every frame replay recovered.
    let fixed = d.join("fixed");
    let o = unitac(&[
        "bag",
        "repair",
        rec.to_str().unwrap(),
        fixed.to_str().unwrap(),
    ]);
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    let o = read(&fixed);
    assert!(o.status.success(), "{}", stderr(&o));
    let frames: Vec<i64> = String::from_utf8_lossy(&o.stdout)
        .lines()
        .skip(1)
        .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap())
        .filter(|m| m["topic"] == "/gs/image_raw")
        .map(|m| {
            let s = &m["msg"]["header"]["stamp"];
            s["sec"].as_i64().unwrap() * 1_000_000_000 + s["nanosec"].as_i64().unwrap()
        })
        .collect();
    assert_eq!(frames, recovered);
    // The metadata written as chunks were flushed already counts what is on disk.
    let meta = std::fs::read_to_string(rec.join("metadata.yaml")).unwrap();
    let count: u64 = meta
        .lines()
        .find_map(|l| l.strip_prefix("  message_count: "))
        .unwrap()
        .parse()
        .unwrap();
    assert!(count >= recovered.len() as u64, "{meta}");
    std::fs::remove_dir_all(&d).ok();
}

// ---------------------------------------------------------------------------------------------

/// Numbers out of range are refused (exit 2, one line naming the flag and its inclusive
/// range), never clamped or replaced by a default; bad values of `calibrate depth` are exit 2
/// like everywhere else. (`unitac-lab`'s flags: crates/lab/tests/hostile.rs.)
#[test]
fn numbers_out_of_range_are_refused_not_clamped() {
    for (args, needle) in [
        (
            &["run", "--scene", "fabric_selection", "--max-frames", "0"][..],
            "--max-frames <MAX_FRAMES>': 0 is outside 1 to 18446744073709551615 (inclusive)",
        ),
        (
            &["replay", "missing_bag", "--start", "NaN"],
            "--start <SECONDS>': NaN is outside 0 to 1000000000 (inclusive)",
        ),
    ] {
        assert_one_line(&unitac(args), 2, needle);
    }
    let d = tmpdir("bad-values");
    let (missing, cal) = (d.join("missing.png"), d.join("cal.json"));
    let mut args = common::calibrate_depth_args("0.002", &missing, &cal);
    args.push(missing.to_str().unwrap());
    assert_one_line(&unitac(&args), 2, "--background");
    std::fs::remove_dir_all(&d).ok();
}
