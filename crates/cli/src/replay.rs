//! `unitac replay`: a bag through the contact stage (or a scene's stages), one JSON line per
//! image message (or per event), and `unitac bag repair`. The logic is
//! unitac_bag::{replay, repair}; this file parses flags and formats lines.

use anyhow::Context;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use unitac_bag::replay::{ImageResult, OutputBag, ReplayReport, replay};
use unitac_bag::{BagError, BagSource, BagWriter, ReplayOptions, WriteOptions};
use unitac_cli::ConfigError;
use unitac_contact::{ContactParams, ContactStage};
use unitac_core::msg::ContactEpisode;
use unitac_core::{Chain, Msg, Pacer, SensorKind, Stage};

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
    pub scene: Option<String>,
    pub events: bool,
}

fn config(msg: String) -> anyhow::Error {
    anyhow::Error::new(ConfigError(msg))
}

/// The JSON line of one image message.
pub fn line(r: &ImageResult) -> serde_json::Value {
    let state = r.events.iter().find_map(|m| match m {
        Msg::ContactState(c) => Some(c),
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

/// Episodes listed in the text summary; the rest are counted (`--loop` runs forever).
const MAX_LISTED_EPISODES: usize = 100;
/// Image errors printed on stderr one per line; the rest are counted.
const MAX_ERROR_LINES: u64 = 20;

/// The bag rule: a bag that cannot be opened (missing, not a bag, bad metadata.yaml, a listed
/// file missing, unsupported) is exit 2 like any bad argument; what goes wrong while reading is
/// exit 1. Either way the reason is one line on stderr.
fn open_error(path: &Path, e: BagError) -> anyhow::Error {
    match e {
        BagError::Io { .. }
        | BagError::NotABag(_)
        | BagError::Metadata { .. }
        | BagError::MissingFile(_)
        | BagError::Unsupported { .. } => config(e.to_string()),
        other => anyhow::Error::new(other).context(format!("reading {}", path.display())),
    }
}

/// The stages a replay runs: the `--scene`'s, or the contact stage for `--sensor`.
fn replay_stages(a: &Args) -> anyhow::Result<Vec<Box<dyn Stage>>> {
    Ok(match &a.scene {
        Some(name) => {
            let scene =
                unitac_pipeline::load_scene(name, None).map_err(|e| config(e.to_string()))?;
            unitac_pipeline::build_stages(&scene).map_err(|e| config(e.to_string()))?
        }
        None => vec![Box::new(
            ContactStage::new(ContactParams::default(), a.sensor.spec())
                .map_err(|e| config(e.to_string()))?,
        )],
    })
}

/// The text summary of a replay: messages, errors, the episodes (at most
/// [`MAX_LISTED_EPISODES`] listed), event counts and the bag written.
fn write_summary(
    w: &mut impl Write,
    a: &Args,
    report: &ReplayReport,
    episodes: &[ContactEpisode],
    episode_count: u64,
    written: Option<&Path>,
) -> std::io::Result<()> {
    writeln!(
        w,
        "replayed {} image messages from {} ({}), {} errors",
        report.images,
        a.bag.display(),
        report.topic.as_deref().unwrap_or("-"),
        report.errors
    )?;
    for e in episodes {
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
    if episode_count > episodes.len() as u64 {
        writeln!(
            w,
            "  ... and {} more episodes",
            episode_count - episodes.len() as u64
        )?;
    }
    for (k, n) in &report.events {
        writeln!(w, "  {k}: {n}")?;
    }
    if let Some(p) = written {
        writeln!(w, "  wrote {}", p.display())?;
    }
    Ok(())
}

/// The replay's warnings and errors on stderr, and whether it succeeded: some images, and at
/// most half of them failed.
fn verdict(a: &Args, report: &ReplayReport, error_lines: u64, first_error: Option<String>) -> bool {
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
        return false;
    }
    if report.errors > 0 {
        if error_lines > MAX_ERROR_LINES {
            eprintln!(
                "unitac: ... {} more image errors",
                error_lines - MAX_ERROR_LINES
            );
        }
        eprintln!(
            "unitac: {} of {} image messages failed{}",
            report.errors,
            report.images,
            first_error
                .map(|e| format!(" (first: {e})"))
                .unwrap_or_default()
        );
        // A few rejected frames (a resolution change, a corrupt buffer) are reported above; a
        // replay where most images failed produced nothing useful and exits 1.
        return report.errors.saturating_mul(2) <= report.images;
    }
    true
}

pub fn cmd_replay(a: Args) -> anyhow::Result<bool> {
    let mut pacer = match (a.fast, a.rate) {
        (true, _) => Pacer::fast(),
        (false, r) => Pacer::new(Some(r.unwrap_or(1.0))).map_err(|e| config(format!("--{e}")))?,
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
    let mut chain = Chain::new(replay_stages(&a)?);
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
    let mut episode_count = 0u64;
    let mut flushed = Vec::new();
    let mut error_lines = 0u64;
    let mut first_error = None;
    let report = replay(
        &mut source,
        &mut chain,
        out.as_mut(),
        &mut pacer,
        &stop,
        |r| {
            if write_err.is_none() {
                let written = if a.events {
                    r.events
                        .iter()
                        .try_for_each(|m| writeln!(w, "{}", m.to_json()))
                } else if a.json {
                    writeln!(w, "{}", line(r))
                } else {
                    Ok(())
                };
                if let Err(e) = written {
                    write_err = Some(e);
                    stop.store(true, Ordering::SeqCst);
                }
            }
            if let Some(e) = &r.error {
                first_error.get_or_insert_with(|| e.clone());
                error_lines += 1;
                if error_lines <= MAX_ERROR_LINES {
                    eprintln!("unitac: error: {} at {} ns: {e}", r.topic.name, r.stamp);
                }
            }
            for m in &r.events {
                if let Msg::ContactEpisode(e) = m {
                    episode_count += 1;
                    if episodes.len() < MAX_LISTED_EPISODES {
                        episodes.push(e.clone());
                    }
                }
            }
        },
        |m| flushed.push(m.clone()),
    )
    .with_context(|| format!("replaying {}", a.bag.display()))?;
    for m in &flushed {
        if a.events && write_err.is_none() {
            write_err = writeln!(w, "{}", m.to_json()).err();
        }
        if let Msg::ContactEpisode(e) = m {
            episode_count += 1;
            if episodes.len() < MAX_LISTED_EPISODES {
                episodes.push(e.clone());
            }
        }
    }
    if let Some(e) = write_err {
        return Err(e).context("writing to stdout");
    }
    let written = match out {
        Some(o) => Some(o.finish().context("finishing the output bag")?),
        None => None,
    };
    if !a.json && !a.events {
        write_summary(
            &mut w,
            &a,
            &report,
            &episodes,
            episode_count,
            written.as_deref(),
        )?;
    }
    Ok(verdict(&a, &report, error_lines, first_error))
}

/// `unitac bag repair IN OUT`.
pub fn cmd_repair(input: &Path, output: &Path) -> anyhow::Result<bool> {
    if output.exists() {
        return Err(config(format!(
            "{}: already exists; not overwriting a bag",
            output.display()
        )));
    }
    let r = unitac_bag::repair(input, output).map_err(|e| match e {
        BagError::Write { .. } => anyhow::Error::new(e),
        other => open_error(input, other),
    })?;
    let mut w = std::io::stdout().lock();
    writeln!(
        w,
        "repaired {} -> {}: {} messages",
        input.display(),
        r.output.display(),
        r.messages()
    )?;
    for (t, n) in &r.topics {
        writeln!(w, "  {t}: {n}")?;
    }
    for f in &r.truncated {
        writeln!(
            w,
            "  {} was cut short: copied up to its last complete record",
            f.display()
        )?;
    }
    for t in &r.skipped_topics {
        eprintln!("unitac: warning: {t}: no schema in the bag or here; topic left out");
    }
    if r.skipped_messages > 0 {
        eprintln!(
            "unitac: warning: {} messages over the size limit left out",
            r.skipped_messages
        );
    }
    if let Some(e) = &r.stopped_by {
        eprintln!("unitac: {e}: stopped there; everything before it is in the repaired bag");
        return Ok(false);
    }
    Ok(true)
}
