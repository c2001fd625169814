#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]
//! CI smoke of the fuzz targets (crates/driver/fuzz): the same entry functions over the seeded
//! corpus and mutations of it, because cargo-fuzz (nightly + libFuzzer) is not part of the CI
//! toolchain; the inputs cargo fuzz found, replayed; and the writer of the seeds.

use unitac_driver::fuzzing;

fn root() -> std::path::PathBuf {
    std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz")
}

/// SplitMix64: deterministic mutations.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n.max(1) as u64) as usize
    }
}

/// A few byte flips, a cut, a duplicated or dropped range, or a changed size field.
fn mutate(rng: &mut Rng, seed: &[u8]) -> Vec<u8> {
    let mut v = seed.to_vec();
    for _ in 0..1 + rng.below(4) {
        if v.is_empty() {
            break;
        }
        let i = rng.below(v.len());
        match rng.below(6) {
            0 => v[i] ^= 1 << rng.below(8),
            1 => v[i] = [0x00, 0xFF, 0xD9, 0xDA, 0x7F, 0x80][rng.below(6)],
            2 => v.truncate(i),
            3 => {
                let j = (i + 1 + rng.below(64)).min(v.len());
                let dup = v[i..j].to_vec();
                v.splice(i..i, dup);
            }
            4 => {
                let j = (i + 1 + rng.below(64)).min(v.len());
                v.drain(i..j);
            }
            _ => {
                // A size-like 16-bit field set to an extreme.
                if i + 1 < v.len() {
                    let x = [0u16, 1, 0x1fff, 0x2000, 0xffff][rng.below(5)];
                    v[i..i + 2].copy_from_slice(&x.to_be_bytes());
                }
            }
        }
    }
    v
}

fn seeds(target: &str) -> Vec<Vec<u8>> {
    let dir = root().join("corpus").join(target);
    let mut names: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    names.sort();
    let v: Vec<Vec<u8>> = names.iter().map(|p| std::fs::read(p).unwrap()).collect();
    assert!(v.len() >= 4, "{}: {} seeds", dir.display(), v.len());
    v
}

/// Seconds one input may take (crates/driver/fuzz/run.sh gives libFuzzer the same -timeout).
const SMOKE_TIMEOUT_S: u64 = 5;

#[test]
fn fuzz_smoke_seeded_corpus() {
    let limit = std::time::Duration::from_secs(SMOKE_TIMEOUT_S);
    let timed = |target: &str, f: fn(&[u8]), input: &[u8]| {
        let t0 = std::time::Instant::now();
        f(input);
        let took = t0.elapsed();
        if took > limit {
            let p = std::env::temp_dir().join(format!("unitac-driver-fuzz-slow-{target}"));
            std::fs::write(&p, input).unwrap();
            panic!(
                "{target}: one input took {took:?} (> {limit:?}); saved to {}",
                p.display()
            );
        }
    };
    let mut rng = Rng(0x5eed);
    for (target, f) in [
        ("mjpeg", fuzzing::mjpeg as fn(&[u8])),
        ("still", fuzzing::still),
    ] {
        let corpus = seeds(target);
        for s in &corpus {
            timed(target, f, s);
        }
        for i in 0..1500 {
            timed(target, f, &mutate(&mut rng, &corpus[i % corpus.len()]));
        }
    }
}

/// Inputs cargo fuzz found (crates/driver/fuzz/regressions), through both targets.
#[test]
fn fuzz_regressions() {
    let dir = root().join("regressions");
    for e in std::fs::read_dir(&dir).unwrap() {
        let p = e.unwrap().path();
        if p.extension().is_some_and(|x| x == "md") {
            continue;
        }
        let data = std::fs::read(&p).unwrap();
        fuzzing::mjpeg(&data);
        fuzzing::still(&data);
    }
}

fn gel(w: u32, h: u32) -> Vec<u8> {
    let mut v = Vec::new();
    for y in 0..h {
        for x in 0..w {
            v.extend([
                (40 + 5 * x + 3 * y) as u8,
                (200 - 4 * y) as u8,
                ((x * y) % 251) as u8,
            ]);
        }
    }
    v
}

fn jpeg(
    w: u32,
    h: u32,
    f: impl Fn(&mut jpeg_encoder::Encoder<&mut Vec<u8>>),
    gray: bool,
) -> Vec<u8> {
    let mut out = Vec::new();
    let mut enc = jpeg_encoder::Encoder::new(&mut out, 75);
    f(&mut enc);
    let rgb = gel(w, h);
    if gray {
        let g: Vec<u8> = rgb.chunks(3).map(|p| p[1]).collect();
        enc.encode(&g, w as u16, h as u16, jpeg_encoder::ColorType::Luma)
            .unwrap();
    } else {
        enc.encode(&rgb, w as u16, h as u16, jpeg_encoder::ColorType::Rgb)
            .unwrap();
    }
    out
}

fn png(w: u32, h: u32, color: image::ColorType) -> Vec<u8> {
    let img = image::DynamicImage::ImageRgb8(image::RgbImage::from_raw(w, h, gel(w, h)).unwrap());
    let img = match color {
        image::ColorType::L8 => image::DynamicImage::ImageLuma8(img.to_luma8()),
        image::ColorType::Rgba16 => image::DynamicImage::ImageRgba16(img.to_rgba16()),
        _ => img,
    };
    let mut out = Vec::new();
    img.write_to(&mut std::io::Cursor::new(&mut out), image::ImageFormat::Png)
        .unwrap();
    out
}

/// Writes the seed corpus (crates/driver/fuzz/corpus/{mjpeg,still}): tiny JPEGs of each kind
/// the decoders handle (4:2:0, 4:4:4 with restart markers, gray, progressive, no Huffman tables'
/// worth of detail) and PNGs (RGB, gray, 16-bit RGBA), each a few hundred bytes.
/// `UNITAC_FUZZ_SEED_DIR=crates/driver/fuzz/corpus cargo test -p unitac-driver --test fuzz_smoke write_fuzz_seeds -- --ignored`
#[test]
#[ignore = "writes the fuzz seeds into UNITAC_FUZZ_SEED_DIR"]
fn write_fuzz_seeds() {
    let Some(dir) = std::env::var_os("UNITAC_FUZZ_SEED_DIR") else {
        return;
    };
    let dir = std::path::PathBuf::from(dir);
    use jpeg_encoder::SamplingFactor;
    let jpegs = [
        (
            "420.jpg",
            jpeg(
                40,
                24,
                |e| e.set_sampling_factor(SamplingFactor::F_2_2),
                false,
            ),
        ),
        (
            "444_restarts.jpg",
            jpeg(
                24,
                16,
                |e| {
                    e.set_sampling_factor(SamplingFactor::F_1_1);
                    e.set_restart_interval(2);
                },
                false,
            ),
        ),
        (
            "420_restarts.jpg",
            jpeg(
                48,
                32,
                |e| {
                    e.set_sampling_factor(SamplingFactor::F_2_2);
                    e.set_restart_interval(1);
                },
                false,
            ),
        ),
        ("gray.jpg", jpeg(16, 16, |_| {}, true)),
        (
            "progressive.jpg",
            jpeg(24, 16, |e| e.set_progressive(true), false),
        ),
    ];
    let pngs = [
        ("rgb8.png", png(12, 8, image::ColorType::Rgb8)),
        ("gray8.png", png(12, 8, image::ColorType::L8)),
        ("rgba16.png", png(6, 4, image::ColorType::Rgba16)),
    ];
    for (name, bytes) in &jpegs {
        std::fs::write(dir.join("mjpeg").join(name), bytes).unwrap();
        std::fs::write(dir.join("still").join(name), bytes).unwrap();
    }
    for (name, bytes) in &pngs {
        std::fs::write(dir.join("still").join(name), bytes).unwrap();
    }
}
