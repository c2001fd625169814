//! Truncated, corrupt and hostile inputs: clear errors, no panic, bounded memory. Also the CI
//! smoke of the fuzz targets (crates/bag/fuzz): the same entry functions over a seeded, mutated
//! corpus, because cargo-fuzz (nightly + libFuzzer) is not part of the CI toolchain.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

use common::*;
use std::path::Path;
use unitac_bag::read::read_mcap_bytes;
use unitac_bag::ros::{Image, RosMessage};
use unitac_bag::{BagError, BagReader, BagWriter, Compression, ReadOptions, WriteOptions, fuzzing};
use unitac_core::Stamp;
use unitac_core::msg::Header;

fn small_bag(path: &Path, n: usize, compression: Compression) -> Vec<u8> {
    let mut w = BagWriter::create(
        path,
        WriteOptions {
            compression,
            chunk_size: 300,
        },
    )
    .unwrap();
    let t = w.add_topic("/img", "sensor_msgs/msg/Image").unwrap();
    for i in 0..n {
        let img = Image {
            header: Header::new(Stamp(i as i64 + 1), "x"),
            height: 4,
            width: 8,
            encoding: "mono8".into(),
            is_bigendian: 0,
            step: 8,
            data: (0..32).map(|k| (k * 7 + i) as u8).collect(),
        };
        w.write(t, i as i64 + 1, &img).unwrap();
    }
    w.finish().unwrap();
    std::fs::read(path).unwrap()
}

#[test]
fn truncated_mcap_reads_up_to_the_last_complete_record() {
    let dir = tmpdir("trunc");
    for c in [Compression::None, Compression::Zstd, Compression::Lz4] {
        let full = small_bag(&dir.join(format!("full-{c:?}.mcap")), 40, c);
        let (all, truncated) = read_mcap_bytes(&full).unwrap();
        assert_eq!(all.len(), 40);
        assert!(!truncated);
        let mut last = 0;
        for cut in (0..full.len()).step_by(7) {
            let (msgs, truncated) = read_mcap_bytes(&full[..cut])
                .unwrap_or_else(|e| panic!("{c:?} cut at {cut}/{}: {e}", full.len()));
            // Cut before the end of the data section: flagged (after it, all messages are there).
            assert!(
                truncated || msgs.len() == all.len(),
                "cut at {cut} must be flagged"
            );
            // A prefix of the messages, never fewer than a shorter cut gave.
            assert!(msgs.len() >= last, "cut {cut}: {} < {last}", msgs.len());
            assert_eq!(msgs[..], all[..msgs.len()]);
            last = msgs.len();
        }
        assert!(
            last >= 35,
            "{c:?}: only {last} of 40 messages before the summary"
        );
        // The same through a file, a bag directory without metadata, and the replay source.
        let p = dir.join(format!("cut-{c:?}"));
        std::fs::create_dir_all(&p).unwrap();
        std::fs::write(p.join("cut_0.mcap"), &full[..full.len() / 3]).unwrap();
        let mut r = BagReader::open(&p, ReadOptions::default()).unwrap();
        let n = r.by_ref().inspect(|m| assert!(m.is_ok(), "{m:?}")).count();
        assert!(n > 5 && n < 40, "{n}");
        assert_eq!(r.truncated().len(), 1);
    }
    std::fs::remove_dir_all(&dir).ok();
}

#[test]
fn corrupt_and_hostile_files_are_clear_errors() {
    let dir = tmpdir("hostile");
    // A record claiming 2^40 bytes: refused before any allocation.
    let mut huge = b"\x89MCAP0\r\n".to_vec();
    huge.push(0x01);
    huge.extend_from_slice(&(1u64 << 40).to_le_bytes());
    huge.extend_from_slice(&[0; 64]);
    let e = read_mcap_bytes(&huge).unwrap_err();
    assert!(matches!(e, BagError::Mcap { .. }), "{e}");
    // Not MCAP at all.
    let e = read_mcap_bytes(b"hello world, this is not a bag").unwrap_err();
    assert!(e.to_string().contains("MCAP"), "{e}");
    // A flipped byte in a compressed chunk: an error (chunk CRC or zstd), no panic.
    let full = small_bag(&dir.join("ok.mcap"), 20, Compression::Zstd);
    let mut bad = full.clone();
    let mid = bad.len() / 3;
    bad[mid] ^= 0x55;
    let r = read_mcap_bytes(&bad);
    assert!(r.is_err() || r.as_ref().unwrap().0.len() < 20, "{r:?}");

    // Garbage .db3, a directory with nothing, an escaping metadata.yaml, rosbag2 file compression.
    std::fs::write(dir.join("junk.db3"), b"SQLite format 3\0 but not really").unwrap();
    let e = BagReader::open(&dir.join("junk.db3"), ReadOptions::default())
        .and_then(|mut r| r.next().transpose())
        .unwrap_err();
    assert!(matches!(e, BagError::Sqlite { .. }), "{e}");
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    assert!(matches!(
        BagReader::open(&empty, ReadOptions::default()),
        Err(BagError::NotABag(_))
    ));
    let esc = dir.join("esc");
    std::fs::create_dir_all(&esc).unwrap();
    std::fs::write(
        esc.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  relative_file_paths: ['../ok.mcap']\n",
    )
    .unwrap();
    let e = BagReader::open(&esc, ReadOptions::default()).unwrap_err();
    assert!(e.to_string().contains("not a relative path"), "{e}");
    std::fs::write(
        esc.join("metadata.yaml"),
        "rosbag2_bagfile_information:\n  version: 9\n  storage_identifier: mcap\n  relative_file_paths: ['x.mcap.zstd']\n  compression_mode: file\n  compression_format: zstd\n",
    )
    .unwrap();
    let e = BagReader::open(&esc, ReadOptions::default()).unwrap_err();
    assert!(matches!(e, BagError::Unsupported { .. }), "{e}");
    assert!(matches!(
        BagReader::open(&dir.join("nope"), ReadOptions::default()),
        Err(BagError::Io { .. })
    ));
}

/// An uncompressed chunk's records are walked where they were read: a flipped byte in an image
/// is still refused by the chunk CRC, after the messages of the chunks before it.
#[test]
fn uncompressed_chunk_is_checked_in_place() {
    let dir = tmpdir("inplace");
    let full = small_bag(&dir.join("none.mcap"), 40, Compression::None);
    let (all, _) = read_mcap_bytes(&full).unwrap();
    assert_eq!(all.len(), 40);
    // Message 20's pixels, as small_bag wrote them.
    let pixels: Vec<u8> = (0..32).map(|k| (k * 7 + 20) as u8).collect();
    let at = full
        .windows(pixels.len())
        .position(|w| w == pixels.as_slice())
        .unwrap();
    let mut bad = full.clone();
    bad[at + 5] ^= 0x10;
    let mut r =
        BagReader::open(&write_tmp(&dir, "bad.mcap", &bad), ReadOptions::default()).unwrap();
    let mut good = 0;
    let e = loop {
        match r.next() {
            Some(Ok(m)) => {
                assert_eq!(m, all[good]);
                good += 1;
            }
            Some(Err(e)) => break e,
            None => panic!("a corrupt chunk was read without an error"),
        }
    };
    assert!(e.to_string().contains("CRC"), "{e}");
    assert!(good < 20, "{good} messages before the corrupt one's chunk");
    std::fs::remove_dir_all(&dir).ok();
}

fn write_tmp(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn vm_hwm_kib() -> u64 {
    let s = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    s.lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap_or(0)
}

#[test]
fn hostile_lengths_do_not_allocate() {
    // An Image claiming 4 GiB of pixels, a string of 4 GiB, a latent of 2^32 floats, and an
    // MCAP chunk claiming a 16 GiB uncompressed size.
    let mut cdr = vec![0, 1, 0, 0];
    cdr.extend_from_slice(&[0; 8]); // stamp
    cdr.extend_from_slice(&u32::MAX.to_le_bytes()); // frame_id length
    let before = vm_hwm_kib();
    assert!(Image::from_cdr(&cdr).is_err());
    let mut img = Image {
        header: Header::new(Stamp(1), "x"),
        height: 8192,
        width: 8192,
        encoding: "rgba8".into(),
        is_bigendian: 0,
        step: 8192 * 4,
        data: vec![],
    }
    .to_cdr();
    let n = img.len();
    img[n - 4..].copy_from_slice(&0xffff_fff0u32.to_le_bytes());
    assert!(Image::from_cdr(&img).is_err());
    let mut chunk = b"\x89MCAP0\r\n".to_vec();
    // Header record (op 1): profile "", library "".
    chunk.push(0x01);
    chunk.extend_from_slice(&8u64.to_le_bytes());
    chunk.extend_from_slice(&[0; 8]);
    // Chunk record (op 6) with uncompressed_size 16 GiB and a tiny body.
    let mut body = Vec::new();
    body.extend_from_slice(&0u64.to_le_bytes());
    body.extend_from_slice(&0u64.to_le_bytes());
    body.extend_from_slice(&(16u64 << 30).to_le_bytes());
    body.extend_from_slice(&0u32.to_le_bytes());
    body.extend_from_slice(&4u32.to_le_bytes());
    body.extend_from_slice(b"zstd");
    body.extend_from_slice(&16u64.to_le_bytes());
    body.extend_from_slice(&[0x28, 0xb5, 0x2f, 0xfd, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0]);
    chunk.push(0x06);
    chunk.extend_from_slice(&(body.len() as u64).to_le_bytes());
    chunk.extend_from_slice(&body);
    let r = read_mcap_bytes(&chunk);
    assert!(r.is_err() || r.as_ref().unwrap().0.is_empty(), "{r:?}");
    let grew_mib = vm_hwm_kib().saturating_sub(before) / 1024;
    assert!(grew_mib < 64, "peak memory grew by {grew_mib} MiB");
}

/// xorshift64*: a fixed, seeded stream so CI failures reproduce.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_f491_4f6c_dd1d)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(8) {
        match rng.below(7) {
            6 => {
                // Deep nesting (YAML flow collections): quadratic in libyaml without the bound.
                let i = rng.below(v.len() + 1);
                let n = 1 + rng.below(100_000);
                v.splice(i..i, std::iter::repeat_n(b'[', n));
            }
            0 if !v.is_empty() => {
                let i = rng.below(v.len());
                v[i] ^= 1 << rng.below(8);
            }
            1 if !v.is_empty() => {
                let i = rng.below(v.len());
                v[i] = [0, 0xff, 0x7f, 0x80][rng.below(4)];
            }
            2 => {
                let cut = rng.below(v.len() + 1);
                v.truncate(cut);
            }
            3 if v.len() >= 4 => {
                // A length-like field set to something large.
                let i = rng.below(v.len() - 3);
                let x = [u32::MAX, 1 << 30, 65_537, 0x8000_0000][rng.below(4)];
                v[i..i + 4].copy_from_slice(&x.to_le_bytes());
            }
            4 => {
                let i = rng.below(v.len() + 1);
                let b = rng.next().to_le_bytes();
                v.splice(i..i, b);
            }
            _ => {
                if !v.is_empty() {
                    let i = rng.below(v.len());
                    let j = rng.below(v.len());
                    let (a, b) = (i.min(j), i.max(j));
                    v.drain(a..b.min(a + 64));
                }
            }
        }
    }
    v
}

/// Seconds one input may take in the smoke (crates/bag/fuzz/run.sh uses the same -timeout).
const SMOKE_TIMEOUT_S: u64 = 5;

#[test]
fn fuzz_smoke_seeded_corpus() {
    let dir = tmpdir("fuzzsmoke");
    let mcaps = [
        small_bag(&dir.join("a.mcap"), 5, Compression::None),
        small_bag(&dir.join("b.mcap"), 5, Compression::Zstd),
        small_bag(&dir.join("c.mcap"), 5, Compression::Lz4),
    ];
    let mut cdrs: Vec<Vec<u8>> = read_mcap_bytes(&mcaps[0])
        .unwrap()
        .0
        .into_iter()
        .map(|m| m.data)
        .collect();
    for f in [
        "contact_state.cdr",
        "tactile_latent.cdr",
        "compressed_image.cdr",
    ] {
        cdrs.push(std::fs::read(root().join("crates/bag/fuzz/corpus/cdr").join(f)).unwrap());
    }
    let meta = [
        std::fs::read(root().join("crates/bag/fuzz/corpus/metadata/rosbags_v9.yaml")).unwrap(),
        b"rosbag2_bagfile_information:\n  version: 5\n  storage_identifier: sqlite3\n  relative_file_paths: [a_0.db3]\n".to_vec(),
    ];
    let mut rng = Rng(0x5eed_u64);
    // Per-input time limit, as run.sh gives libFuzzer (-timeout): a hang guard, not a benchmark.
    // An input over it is written out so it can be replayed.
    let limit = std::time::Duration::from_secs(SMOKE_TIMEOUT_S);
    let timed = |target: &str, f: fn(&[u8]), input: Vec<u8>| {
        let t0 = std::time::Instant::now();
        f(&input);
        let took = t0.elapsed();
        if took > limit {
            let p = std::env::temp_dir().join(format!("unitac-fuzz-slow-{target}"));
            std::fs::write(&p, &input).unwrap();
            panic!(
                "{target}: one input took {took:?} (> {limit:?}); saved to {}",
                p.display()
            );
        }
    };
    for i in 0..3000 {
        timed("mcap", fuzzing::mcap, mutate(&mut rng, &mcaps[i % 3]));
        timed("cdr", fuzzing::cdr, mutate(&mut rng, &cdrs[i % cdrs.len()]));
        timed(
            "metadata",
            fuzzing::metadata,
            mutate(&mut rng, &meta[i % 2]),
        );
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// Writes the MCAP seeds of the fuzz corpus (crates/bag/fuzz/run.sh calls it).
#[test]
#[ignore = "writes fuzz seeds; run by crates/bag/fuzz/run.sh"]
fn write_fuzz_seeds() {
    let Some(dir) = std::env::var_os("UNITAC_FUZZ_SEED_DIR") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    for (name, c) in [
        ("none.mcap", Compression::None),
        ("zstd.mcap", Compression::Zstd),
        ("lz4.mcap", Compression::Lz4),
    ] {
        let tmp = tmpdir(&format!("seed-{name}"));
        let bytes = small_bag(&tmp.join(name), 3, c);
        std::fs::write(dir.join(name), bytes).unwrap();
        std::fs::remove_dir_all(&tmp).ok();
    }
}

/// Inputs cargo fuzz found (crates/bag/fuzz/regressions), run in a child process whose address
/// space is limited to 1 GiB (`ulimit -v`): a reservation of gigabytes (the first input made
/// mcap's record parser reserve 1.9 GB for a string) aborts it even if the pages are never
/// touched, which a resident-memory check would not see.
#[test]
fn fuzz_regressions() {
    let exe = std::env::current_exe().unwrap();
    let o = std::process::Command::new("bash")
        .arg("-c")
        .arg("ulimit -v 1048576 && exec \"$0\" --exact fuzz_regressions_child --ignored --test-threads=1")
        .arg(&exe)
        .env("UNITAC_FUZZ_REGRESSIONS", "1")
        .output()
        .unwrap();
    let out = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success() && out.contains("1 passed"),
        "{out}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
}

#[test]
#[ignore = "run by fuzz_regressions under an address-space limit"]
fn fuzz_regressions_child() {
    if std::env::var_os("UNITAC_FUZZ_REGRESSIONS").is_none() {
        return;
    }
    let dir = root().join("crates/bag/fuzz/regressions");
    let mut n = 0;
    for e in std::fs::read_dir(&dir).unwrap() {
        let data = std::fs::read(e.unwrap().path()).unwrap();
        fuzzing::mcap(&data);
        fuzzing::cdr(&data);
        fuzzing::metadata(&data);
        n += 1;
    }
    assert!(n >= 1);
}

/// An oversized sqlite message is not read (its length is checked in the
/// query), it is one error item, and the replay goes on to the next message.
#[test]
fn oversized_sqlite_message_is_skipped_unread() {
    use unitac_bag::read::MAX_RECORD_BYTES;
    use unitac_bag::replay::FrameError;
    let dir = tmpdir("bigrow");
    let db = dir.join("big.db3");
    {
        let c = rusqlite::Connection::open(&db).unwrap();
        c.execute_batch(
            "CREATE TABLE topics(id INTEGER PRIMARY KEY, name TEXT NOT NULL, type TEXT NOT NULL, \
             serialization_format TEXT NOT NULL, offered_qos_profiles TEXT NOT NULL);
             CREATE TABLE messages(id INTEGER PRIMARY KEY, topic_id INTEGER NOT NULL, \
             timestamp INTEGER NOT NULL, data BLOB NOT NULL);
             INSERT INTO topics VALUES (1, '/img', 'sensor_msgs/msg/Image', 'cdr', '');",
        )
        .unwrap();
        for i in 1..=3i64 {
            let img = Image {
                header: Header::new(Stamp(i), "x"),
                height: 4,
                width: 8,
                encoding: "mono8".into(),
                is_bigendian: 0,
                step: 8,
                data: vec![i as u8; 32],
            };
            if i == 2 {
                c.execute(
                    "INSERT INTO messages VALUES (?1, 1, ?1, zeroblob(?2))",
                    rusqlite::params![i, MAX_RECORD_BYTES as i64 + 1],
                )
                .unwrap();
            } else {
                c.execute(
                    "INSERT INTO messages VALUES (?1, 1, ?1, ?2)",
                    rusqlite::params![i, img.to_cdr()],
                )
                .unwrap();
            }
        }
    }
    let before = vm_hwm_kib();
    let mut src = unitac_bag::BagSource::open(&db, unitac_bag::ReplayOptions::default()).unwrap();
    let mut got = Vec::new();
    while let Some(item) = src.next_image().unwrap() {
        got.push(item.frame.map(|f| f.stamp.0));
    }
    let grew_mib = vm_hwm_kib().saturating_sub(before) / 1024;
    assert_eq!(got.len(), 3, "{got:?}");
    assert_eq!(got[0].as_ref().unwrap(), &1);
    assert!(
        matches!(&got[1], Err(FrameError::TooLarge { len, .. }) if *len == MAX_RECORD_BYTES as u64 + 1),
        "{:?}",
        got[1]
    );
    assert_eq!(got[2].as_ref().unwrap(), &3);
    assert!(grew_mib < 64, "peak memory grew by {grew_mib} MiB");
    std::fs::remove_dir_all(&dir).ok();
}

/// A metadata.yaml nested 100 000 deep inside offered_qos_profiles (200 KB)
/// took 30 s to refuse; the depth bound refuses it before parsing.
#[test]
fn deeply_nested_metadata_is_refused_before_parsing() {
    let dir = tmpdir("deepmeta");
    let bag = dir.join("deep");
    small_bag(&dir.join("deep.mcap"), 2, Compression::None);
    std::fs::create_dir_all(&bag).unwrap();
    std::fs::rename(dir.join("deep.mcap"), bag.join("deep_0.mcap")).unwrap();
    std::fs::write(
        bag.join("metadata.yaml"),
        format!(
            "rosbag2_bagfile_information:\n  version: 9\n  relative_file_paths: [deep_0.mcap]\n  \
             topics_with_message_count:\n    - topic_metadata: {{name: /img, type: sensor_msgs/msg/Image, \
             offered_qos_profiles: {}{}}}\n",
            "[".repeat(100_000),
            "]".repeat(100_000)
        ),
    )
    .unwrap();
    let t0 = std::time::Instant::now();
    let e = BagReader::open(&bag, ReadOptions::default()).unwrap_err();
    assert!(
        e.to_string().contains("nested more than 64 deep at line 5"),
        "{e}"
    );
    // A hang guard, not a benchmark: 30 s before the bound.
    assert!(t0.elapsed().as_secs() < 5, "{:?}", t0.elapsed());
    std::fs::remove_dir_all(&dir).ok();
}
