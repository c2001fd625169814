//! Benchmark (not a test): frame publish -> ContactState received, over DDS on this machine.
//! Publishes 320x240 rgb8 Images (a press every other second) at a fixed rate into `image`,
//! stamped with the send time, and matches each ContactState by its header stamp (the contact
//! node keeps the capture stamp). Run a contact node in the same namespace first, or use
//! scripts/bench-ros-latency, which does both.
//!
//! usage: unitac_ros_latency RATE_HZ COUNT  (prints one JSON line: p50, p99, max (ms), received)

use futures::{FutureExt, StreamExt};
use r2r::QosProfile;
use std::collections::HashMap;
use std::time::{Duration, Instant};
use unitac_core::{Clock, Frame, SystemClock};
use unitac_ros::{image, spin_until};

fn frame(k: u64, stamp: unitac_core::Stamp) -> anyhow::Result<Frame> {
    let (w, h) = (320u32, 240u32);
    let press = (k / 25) % 2 == 1;
    let mut d = vec![128u8; (w * h * 3) as usize];
    if press {
        for y in 90..150usize {
            for x in 130..190usize {
                let i = (y * w as usize + x) * 3;
                d[i..i + 3].copy_from_slice(&[170, 160, 150]);
            }
        }
    }
    Ok(Frame::new("bench", k, stamp, w, h, d)?)
}

fn run() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args()
        .skip(1)
        .take_while(|a| a != "--ros-args")
        .collect();
    let rate: f64 = args.first().map(|s| s.parse()).transpose()?.unwrap_or(25.0);
    let count: u64 = args.get(1).map(|s| s.parse()).transpose()?.unwrap_or(250);
    anyhow::ensure!(
        rate > 0.0 && rate <= 1000.0 && count > 0 && count <= 100_000,
        "bad rate or count"
    );
    let ctx = r2r::Context::create()?;
    let mut node = r2r::Node::create(ctx, "unitac_latency", "")?;
    let publisher =
        node.create_publisher::<r2r::sensor_msgs::msg::Image>("image", QosProfile::default())?;
    let mut states = node
        .subscribe::<r2r::unitac_msgs::msg::ContactState>("contact_state", QosProfile::default())?;
    if !spin_until(&mut node, Duration::from_secs(30), || {
        publisher
            .get_inter_process_subscription_count()
            .unwrap_or(0)
            > 0
    }) {
        anyhow::bail!("no contact node subscribed to 'image' within 30 s");
    }
    spin_until(&mut node, Duration::from_millis(500), || false);
    let mut sent: HashMap<(i32, u32), Instant> = HashMap::new();
    let mut lat = Vec::new();
    let t0 = Instant::now();
    let period = Duration::from_secs_f64(1.0 / rate);
    for k in 0..count {
        let due = period * k as u32;
        while t0.elapsed() < due {
            node.spin_once(Duration::from_micros(200));
            while let Some(Some(s)) = states.next().now_or_never() {
                if let Some(t) = sent.remove(&(s.header.stamp.sec, s.header.stamp.nanosec)) {
                    lat.push(t.elapsed().as_secs_f64());
                }
            }
        }
        let stamp = SystemClock.now();
        let img = image::from_frame(&frame(k, stamp)?);
        sent.insert(
            (img.header.stamp.sec, img.header.stamp.nanosec),
            Instant::now(),
        );
        publisher.publish(&img)?;
    }
    let end = Instant::now();
    while end.elapsed() < Duration::from_secs(1) {
        node.spin_once(Duration::from_millis(1));
        while let Some(Some(s)) = states.next().now_or_never() {
            if let Some(t) = sent.remove(&(s.header.stamp.sec, s.header.stamp.nanosec)) {
                lat.push(t.elapsed().as_secs_f64());
            }
        }
    }
    lat.sort_by(f64::total_cmp);
    let q = |p: f64| {
        lat.get(((lat.len() as f64 - 1.0) * p).round() as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    println!(
        "{}",
        serde_json::json!({"rate_hz": rate, "sent": count, "received": lat.len(),
            "p50_s": q(0.5), "p99_s": q(0.99), "max_s": q(1.0)})
    );
    Ok(())
}

fn main() -> std::process::ExitCode {
    match run() {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("unitac_ros_latency: {e:#}");
            std::process::ExitCode::from(1)
        }
    }
}
