//! `unitac replay`: a bag through the contact stage, one JSON line per image message.
//! The logic is unitac_bag::replay; this file parses flags and formats lines.

use crate::ConfigError;
use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use unitac_bag::replay::{ImageResult, OutputBag, Pace, replay};
use unitac_bag::{BagError, BagSource, BagWriter, ReplayOptions, WriteOptions};
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::{Msg, SensorKind, Stage};

#[derive(Debug)]
pub struct Args {
    pub bag: PathBuf,
    pub topic: Option<String>,
    pub rate: Option<f64>,
    pub fast: bool,
    pub looped: bool,
    pub start: f64,
    pub out: Option<PathBuf>,
    pub json: bool,
    pub sensor: SensorKind,
}

fn config(msg: String) -> anyhow::Error {
    anyhow::Error::new(ConfigError(msg))
}

/// The JSON line of one image message.
pub fn line(r: &ImageResult) -> serde_json::Value {
    let state = r.events.iter().find_map(|m| match m {
        Msg::Contact(c) => Some(c),
        _ => None,
    });
    let mut v = match state {
        Some(c) => serde_json::json!({
            "stamp": r.stamp, "contact": c.in_contact, "area_px": c.area_px,
            "centroid": c.centroid_px, "episode_id": c.episode_id,
        }),
        None => serde_json::json!({
            "stamp": r.stamp, "contact": null, "area_px": null, "centroid": null,
            "episode_id": null,
        }),
    };
    if let (Some(e), Some(obj)) = (&r.error, v.as_object_mut()) {
        obj.insert("error".into(), e.clone().into());
    }
    v
}

fn open_error(path: &Path, e: BagError) -> anyhow::Error {
    match e {
        BagError::Io { .. }
        | BagError::NotABag(_)
        | BagError::Metadata { .. }
        | BagError::Unsupported { .. } => config(e.to_string()),
        other => anyhow::Error::new(other).context(format!("reading {}", path.display())),
    }
}

pub fn cmd_replay(a: Args) -> anyhow::Result<bool> {
    let pace = match (a.fast, a.rate) {
        (true, _) => Pace::Fast,
        (false, Some(r)) if r.is_finite() && r > 0.0 => Pace::Rate(r),
        (false, Some(r)) => return Err(config(format!("--rate {r}: must be > 0"))),
        (false, None) => Pace::Rate(1.0),
    };
    if !(a.start.is_finite() && a.start >= 0.0) {
        return Err(config(format!("--start {}: must be >= 0 seconds", a.start)));
    }
    let mut source = BagSource::open(
        &a.bag,
        ReplayOptions {
            topic: a.topic.clone(),
            start_s: a.start,
            looped: a.looped,
            sensor_id: None,
        },
    )
    .map_err(|e| open_error(&a.bag, e))?;
    let stage = ContactStage::new(ContactParams::default(), a.sensor.spec())
        .map_err(|e| config(e.to_string()))?;
    let mut stages: Vec<Box<dyn Stage>> = vec![Box::new(stage)];
    let mut out = match &a.out {
        Some(p) => Some(OutputBag::new(
            BagWriter::create(p, WriteOptions::default()).map_err(|e| config(e.to_string()))?,
        )),
        None => None,
    };
    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = Arc::clone(&stop);
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("installing the Ctrl-C handler")?;
    }
    let stdout = std::io::stdout();
    let mut w = stdout.lock();
    let mut write_err = None;
    let mut episodes = Vec::new();
    let mut flushed = Vec::new();
    let report = replay(
        &mut source,
        &mut stages,
        out.as_mut(),
        pace,
        &stop,
        |r| {
            if a.json && write_err.is_none() {
                if let Err(e) = writeln!(w, "{}", line(r)) {
                    write_err = Some(e);
                    stop.store(true, Ordering::SeqCst);
                }
            }
            episodes.extend(r.events.iter().filter_map(|m| match m {
                Msg::Episode(e) => Some(e.clone()),
                _ => None,
            }));
        },
        |m| {
            if let Msg::Episode(e) = m {
                flushed.push(e.clone());
            }
        },
    )
    .with_context(|| format!("replaying {}", a.bag.display()))?;
    episodes.extend(flushed);
    if let Some(e) = write_err {
        return Err(e).context("writing to stdout");
    }
    let written = match out {
        Some(o) => Some(o.finish().context("finishing the output bag")?),
        None => None,
    };
    if !a.json {
        writeln!(
            w,
            "replayed {} image messages from {} ({}), {} errors",
            report.images,
            a.bag.display(),
            report.topic.as_deref().unwrap_or("-"),
            report.errors
        )?;
        for e in &episodes {
            writeln!(
                w,
                "  episode {} {:.3}-{:.3} s  {} frames  peak {:.0} px",
                e.episode_id,
                e.start.as_secs_f64(),
                e.end.as_secs_f64(),
                e.frame_count,
                e.peak_area_px
            )?;
        }
        for (k, n) in &report.events {
            writeln!(w, "  {k}: {n}")?;
        }
        if let Some(p) = written {
            writeln!(w, "  wrote {}", p.display())?;
        }
    }
    for t in &report.truncated_files {
        eprintln!(
            "unitac: warning: {} was cut short; replayed up to its last complete record",
            t.display()
        );
    }
    if report.images == 0 {
        eprintln!(
            "unitac: no image messages (sensor_msgs/Image or CompressedImage){} in {}",
            a.topic
                .as_deref()
                .map(|t| format!(" on {t}"))
                .unwrap_or_default(),
            a.bag.display()
        );
        return Ok(false);
    }
    Ok(true)
}
