//! Property tests of the RTU frame decoder and the client on arbitrary bytes: no panic, memory
//! bounded, frames embedded in garbage found. Deterministic (seeded), many cases per run.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::io;
use std::time::Duration;
use unitac_gripper::client::{ClientConfig, Link, RtuClient};
use unitac_gripper::frame::{Decoder, Direction, MAX_BUFFER, Request, Response};
use unitac_sim::SplitMix64;

fn bytes(rng: &mut SplitMix64, n: usize) -> Vec<u8> {
    (0..n).map(|_| rng.next_u64() as u8).collect()
}

fn below(rng: &mut SplitMix64, n: usize) -> usize {
    (rng.next_u64() % n.max(1) as u64) as usize
}

/// Feed `data` in random chunk sizes; return the frames and check the bound after every push.
fn feed(rng: &mut SplitMix64, dec: &mut Decoder, data: &[u8]) -> Vec<(u8, u8, Vec<u8>)> {
    let mut out = Vec::new();
    let mut i = 0;
    while i < data.len() {
        let n = 1 + below(rng, 700);
        let end = (i + n).min(data.len());
        dec.push(&data[i..end]);
        assert!(dec.buffered() <= MAX_BUFFER, "buffer {}", dec.buffered());
        while let Some(f) = dec.next_frame() {
            // Every frame handed out re-encodes to a frame whose CRC checks.
            let mut raw = vec![f.slave, f.function];
            raw.extend_from_slice(&f.data);
            unitac_gripper::crc::append_crc(&mut raw);
            assert!(unitac_gripper::crc::crc_ok(&raw));
            out.push((f.slave, f.function, f.data));
        }
        i = end;
    }
    out
}

#[test]
fn arbitrary_bytes_never_panic_and_stay_bounded() {
    let mut rng = SplitMix64::new(0x5EED_0001);
    for case in 0..3000 {
        let n = below(&mut rng, if case % 300 == 0 { 100_000 } else { 1_500 });
        let data = bytes(&mut rng, n);
        for dir in [Direction::Requests, Direction::Responses] {
            let mut d = Decoder::new(dir);
            for (slave, function, data) in feed(&mut rng, &mut d, &data) {
                // Whatever came out must not panic in the typed parsers either.
                let f = unitac_gripper::frame::RawFrame {
                    slave,
                    function,
                    data,
                };
                let _ = Request::decode(&f);
                let _ = Response::decode_for(
                    &Request::ReadInput {
                        addr: 0x07D0,
                        qty: 3,
                    },
                    &f,
                );
            }
            assert!(d.buffered() <= MAX_BUFFER);
        }
    }
}

#[test]
fn frames_between_garbage_are_all_found_in_order() {
    let mut rng = SplitMix64::new(0x5EED_0002);
    for _ in 0..500 {
        let mut stream = Vec::new();
        let mut sent = Vec::new();
        for _ in 0..1 + below(&mut rng, 8) {
            let n = below(&mut rng, 40);
            stream.extend(bytes(&mut rng, n));
            let qty = 1 + below(&mut rng, 10) as u16;
            let regs: Vec<u16> = (0..qty).map(|_| rng.next_u64() as u16).collect();
            let slave = 1 + below(&mut rng, 247) as u8;
            let adu = Response::Registers(regs.clone()).encode(slave, 0x04);
            stream.extend_from_slice(&adu);
            sent.push((slave, adu[2..adu.len() - 2].to_vec()));
        }
        let mut d = Decoder::new(Direction::Responses);
        let got = feed(&mut rng, &mut d, &stream);
        // Each sent frame appears, in order (garbage may add a rare accidental frame, never hide
        // a real one that follows it completely).
        let mut it = got.iter();
        for (slave, data) in &sent {
            assert!(
                it.any(|(s, f, d)| s == slave && *f == 0x04 && d == data),
                "frame from slave {slave} lost in {stream:02X?}"
            );
        }
    }
}

/// A link that answers every request with random bytes.
struct Noise(SplitMix64);

impl Link for Noise {
    fn write_all(&mut self, _: &[u8]) -> io::Result<()> {
        Ok(())
    }
    fn read(&mut self, buf: &mut [u8], _: Duration) -> io::Result<usize> {
        let n = below(&mut self.0, buf.len().min(64) + 1);
        for b in &mut buf[..n] {
            *b = self.0.next_u64() as u8;
        }
        Ok(n)
    }
    fn clear_input(&mut self) -> io::Result<()> {
        Ok(())
    }
}

#[test]
fn client_on_noise_returns_errors_not_panics() {
    let cfg = ClientConfig {
        timeout: Duration::from_millis(2),
        retries: 1,
        ..ClientConfig::new(9, 115_200)
    };
    let mut c = RtuClient::new(Noise(SplitMix64::new(7)), cfg);
    let req = Request::ReadWrite {
        read_addr: 0x07D0,
        read_qty: 3,
        write_addr: 0x03E8,
        values: vec![0x0900, 0, 0],
    };
    let mut errors = 0;
    for _ in 0..200 {
        if c.call(&req).is_err() {
            errors += 1;
        }
    }
    assert!(errors > 150, "noise is not a reply: {errors} errors of 200");
    assert!(c.stats().dropped_bytes > 0);
}
