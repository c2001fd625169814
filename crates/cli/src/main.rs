//! `unitac`: the command line of the UniTac robot stack (embedded runtime, no ROS): the robot's
//! commands (run, contact, replay, bag, calibrate, devices, gripper, scenes). The lab's
//! evaluations, benchmarks, reports, datasets, demonstrations and trials are `unitac-lab`'s
//! (crates/lab).
//!
//! Exit codes (the table in crates/cli/README.md): 0 success; 1 the run failed or produced
//! errors (the source died, a bag is corrupt past its start, images failed, stdout closed or
//! full); 2 bad usage or configuration (unknown scene, unknown stage, missing model, bad value,
//! a file or bag that cannot be opened). The reason is one line on stderr.

mod depth;
mod devices;
mod gripper;
mod images;
mod replay;

use anyhow::Context;
use clap::{Parser, Subcommand};
use std::io::Write;
use std::path::PathBuf;
use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use unitac_cli::{ConfigError, args, emit, emit_report};
use unitac_core::Msg;
use unitac_core::scene::SensorArg;
use unitac_runtime::RunOptions;

#[derive(Parser, Debug)]
#[command(
    name = "unitac",
    version,
    about = "UniTac robot stack: tactile sensing, contact, inference, policy"
)]
struct Cli {
    #[command(subcommand)]
    cmd: Cmd,
}

#[derive(Subcommand, Debug)]
enum Cmd {
    /// Run a scene (launch/scenes/NAME.yaml) in one process, without ROS.
    Run {
        /// Scene name (looked up in the scene directories) or path to a scene file.
        #[arg(long)]
        scene: String,
        /// Frame source, overriding the scene's: mock | v4l | v4l:SERIAL | bag:PATH.
        #[arg(long)]
        sensor: Option<SensorArg>,
        /// Print the summary as one JSON object instead of text.
        #[arg(long)]
        json: bool,
        /// Also print every event (contact states, episodes, ...) as a JSON line on stdout.
        #[arg(long)]
        events: bool,
        /// Replay sources as fast as possible (lossless, deterministic) instead of in real time.
        #[arg(long)]
        fast: bool,
        /// Stop after this many frames.
        #[arg(long, value_parser = args::int_in(1u64, u64::MAX))]
        max_frames: Option<u64>,
        /// Extra directory to look for scenes in (searched first).
        #[arg(long)]
        scene_dir: Option<PathBuf>,
        /// Record the frames and every event into this MCAP bag (a rosbag2 directory, or a bare
        /// file if it ends in .mcap): replay it with `unitac replay --scene` or the ROS sensor
        /// node. With --fast every frame of the source is recorded.
        #[arg(long, value_name = "OUT_BAG")]
        out: Option<PathBuf>,
        /// Print each stage's effective parameters (one line per stage, exactly as the stages
        /// are built) and exit without running.
        #[arg(long)]
        print_params: bool,
    },
    /// Detect contact in image files against a background image: one line per frame (JSON with
    /// --json). Coordinates are in the input image's pixels. A bad file gets an error line and the
    /// others still run; exit code 2 if any file failed.
    Contact {
        /// Sensor kind: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS (sets marker masking and mm per pixel).
        #[arg(long)]
        sensor: unitac_core::SensorKind,
        /// Image of the gel without contact.
        #[arg(long)]
        background: PathBuf,
        /// Frames to check (PNG or JPEG, same size as the background).
        #[arg(required = true)]
        frames: Vec<PathBuf>,
        /// One JSON object per frame instead of a text line.
        #[arg(long)]
        json: bool,
        /// A depth calibration (`unitac calibrate depth`) of this sensor: the gel's depth from it
        /// rather than from the sensor kind's default photometric model (its profile's
        /// `photometric`, fitted on real presses of other units). With a model each line has the
        /// depth (penetration, and the half-depth contour's area and centroid), and the contact
        /// region is that contour (`--region`).
        #[arg(long)]
        depth_calibration: Option<PathBuf>,
        /// Where the contact region comes from (the contact stage's `region`): auto (the depth's
        /// half-depth contour with --depth-calibration, else the colour residual), depth (from
        /// the calibration, else the sensor kind's default photometric model, else a linear model
        /// fitted on each frame's press: `depth.model` self-calibrated, no penetration), or
        /// residual.
        #[arg(long, default_value = "auto")]
        region: unitac_contact::RegionRule,
        /// Write `<frame>.overlay.png` per frame into this directory: the frame with the contact
        /// outline and centroid, and beside it the depth colour map (with a depth model).
        /// Frames of one file name in several directories are told apart by their path
        /// (`0/gelsight.png` -> `0_gelsight.overlay.png`).
        #[arg(long)]
        overlay: Option<PathBuf>,
        /// Keep the skirt's flank: the residual's region at its half-level contour alone (the
        /// contact stage's `peel_skirt: false`), not ended at the press's ridge.
        #[arg(long)]
        no_peel_skirt: bool,
    },
    /// Replay a rosbag2 bag (directory with metadata.yaml + .mcap/.db3, or a bare .mcap) through
    /// the contact stage. With --json: one line per image message {stamp, contact (null while the
    /// background is learned), area_px, centroid, episode_id}.
    Replay {
        /// The bag: a rosbag2 directory (metadata.yaml + .mcap or .db3) or a bare .mcap file.
        bag: PathBuf,
        /// Image topic (sensor_msgs/Image or CompressedImage); default: the first one in the bag.
        #[arg(long)]
        topic: Option<String>,
        /// Replay speed against the bag's stamps (1 = real time, the default).
        #[arg(long, conflicts_with = "fast",
              value_parser = args::f64_in(unitac_core::pace::RATE_RANGE.0, unitac_core::pace::RATE_RANGE.1))]
        rate: Option<f64>,
        /// As fast as possible.
        #[arg(long)]
        fast: bool,
        /// Start over at the end (stamps keep increasing).
        #[arg(long = "loop")]
        looped: bool,
        /// Skip the first SECONDS of the image topic.
        #[arg(long, default_value_t = 0.0, value_name = "SECONDS",
              value_parser = args::f64_in(0.0, 1e9))]
        start: f64,
        /// Write the replayed images and everything the pipeline produced to this MCAP bag
        /// (a directory, or a bare file if it ends in .mcap).
        #[arg(long, value_name = "OUT_BAG")]
        out: Option<PathBuf>,
        /// One JSON line per image message instead of the text summary.
        #[arg(long)]
        json: bool,
        /// Sensor kind of the bag's images: a profile of sensors/ (gelsight-mini, digit, generic, ...) or of $UNITAC_SENSORS (without --scene).
        #[arg(long, default_value = "gelsight-mini")]
        sensor: unitac_core::SensorKind,
        /// Run this scene's stages (name or path; its sensor kind) instead of the default contact
        /// stage: the same stages and params `unitac run` and the ROS nodes build.
        #[arg(long)]
        scene: Option<String>,
        /// Print every event the stages produce as a JSON line (as `unitac run --events`)
        /// instead of one line per image message.
        #[arg(long, conflicts_with = "json")]
        events: bool,
    },
    /// Bag tools: `bag repair IN OUT` rewrites a cut recording (recorder killed, disk full) into
    /// a bag that ros2 bag, rosbags and Foxglove open, with every message that can be recovered.
    Bag {
        #[command(subcommand)]
        cmd: BagCmd,
    },
    /// Calibrations: `calibrate depth` (a sensor's photometric depth calibration from ball
    /// presses), `calibrate mock-presses` (mock ball presses to try it on).
    Calibrate {
        #[command(subcommand)]
        cmd: depth::CalibrateCmd,
    },
    /// List the tactile sensors on the USB bus: model, serial, firmware, V4L2 node, modes.
    Devices {
        /// Print the devices as one JSON object instead of text.
        #[arg(long)]
        json: bool,
    },
    /// Bring-up of a serial gripper: `gripper --port P --model M
    /// activate|open|close|status|bench|simulate` (simulate: serve a simulated one at P).
    Gripper(gripper::GripperArgs),
    /// List the scenes: every `<name>.yaml` in the scene directories (`--scene-dir`,
    /// `$UNITAC_SCENES`, `$UNITAC_ROOT/launch/scenes`, `./launch/scenes`, the source tree's), one
    /// name a line, sorted. The one list the tests, the scripts and `unitac-lab trials` take
    /// scenes from.
    Scenes {
        /// Extra directory to look for scenes in (searched first).
        #[arg(long)]
        scene_dir: Option<PathBuf>,
    },
}

#[derive(Subcommand, Debug)]
enum BagCmd {
    /// Copy every readable message of IN into a new bag OUT (IN is not modified). Exit 1 if a
    /// corrupt record stopped the copy early (what came before it is in OUT).
    Repair {
        /// The bag to read: a rosbag2 directory or a bare .mcap file (not modified).
        input: PathBuf,
        /// New bag: a directory, or a bare file if it ends in .mcap. Never overwritten.
        output: PathBuf,
    },
}

/// The command line's grammar: [`Cli`] ([`unitac_cli::command`]).
fn command() -> clap::Command {
    unitac_cli::command::<Cli>()
}

/// When `main` began: `unitac run` reports how long it took to have its stages built.
static STARTED: std::sync::OnceLock<std::time::Instant> = std::sync::OnceLock::new();

#[allow(clippy::too_many_arguments)] // one per flag of `unitac run`
fn cmd_run(
    scene: &str,
    sensor: Option<SensorArg>,
    json: bool,
    events: bool,
    fast: bool,
    max_frames: Option<u64>,
    scene_dir: Option<PathBuf>,
    out_bag: Option<PathBuf>,
    print_params: bool,
) -> anyhow::Result<bool> {
    let cfg = |e: unitac_core::SceneError| anyhow::Error::new(ConfigError(e.to_string()));
    let scene = unitac_pipeline::load_scene(scene, scene_dir).map_err(cfg)?;
    if scene.stages.is_empty() {
        return Err(anyhow::Error::new(ConfigError(format!(
            "{}: stages: the list is empty; a scene runs at least one stage",
            scene.path.display()
        ))));
    }
    if print_params {
        for line in unitac_pipeline::effective_params(&scene).map_err(cfg)? {
            emit(format_args!("{line}\n"))?;
        }
        return Ok(true);
    }
    let stages = unitac_pipeline::build_stages(&scene).map_err(cfg)?;
    let source = unitac_pipeline::build_source(&scene, sensor.as_ref()).map_err(cfg)?;
    // main() -> scene loaded and checked, every stage built (models loaded), source opened.
    let built_s = STARTED.get().map(|t| t.elapsed().as_secs_f64());

    let stop = Arc::new(AtomicBool::new(false));
    {
        let stop = Arc::clone(&stop);
        // A second Ctrl-C while draining is ignored; the drain is short.
        ctrlc::set_handler(move || stop.store(true, Ordering::SeqCst))
            .context("installing the Ctrl-C handler")?;
    }
    let opts = RunOptions {
        realtime: !fast,
        max_frames,
        stop,
    };
    let mut bag = match &out_bag {
        Some(p) => Some(unitac_bag::replay::OutputBag::new(
            unitac_bag::BagWriter::create(p, unitac_bag::WriteOptions::default())
                .map_err(|e| anyhow::Error::new(ConfigError(format!("--out: {e}"))))?,
        )),
        None => None,
    };
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let (mut write_err, mut bag_err) = (None, None);
    let report = unitac_runtime::run(&scene, source, stages, &opts, |m| {
        if let (Some(b), None) = (bag.as_mut(), &bag_err) {
            let r = match m {
                Msg::Frame(f) => b.write_frame(f),
                other => b.write_event(other),
            };
            bag_err = r.err();
        }
        if events && !m.is_frame() && write_err.is_none() {
            if let Err(e) = writeln!(out, "{}", m.to_json()) {
                write_err = Some(e);
            }
        }
    });
    if let Some(e) = write_err {
        return Err(e).context("writing events to stdout");
    }
    if let Some(e) = bag_err {
        return Err(e).context("recording the output bag");
    }
    if let Some(b) = bag {
        b.finish().context("finishing the output bag")?;
    }
    if json {
        let mut v = serde_json::to_value(&report)?;
        v["built_s"] = serde_json::json!(built_s);
        writeln!(out, "{v}")?;
    } else {
        write!(out, "{}", report.text())?;
        if let Some(b) = built_s {
            writeln!(out, "built in {b:.3} s (scene, stages and models, source)")?;
        }
    }
    // The summary goes to stdout; the reason a run failed also goes to stderr, one line.
    if let Some(reason) = report.ended.strip_prefix("source_failed: ") {
        eprintln!("unitac: {}: {reason}", report.source);
        return Ok(false);
    }
    if report.frames == 0 {
        eprintln!(
            "unitac: {} gave no frame ({}): nothing was run",
            report.source, report.ended
        );
        return Ok(false);
    }
    Ok(true)
}

/// `unitac contact`'s optional depth and overlay.
struct ContactExtras<'a> {
    depth_calibration: Option<&'a std::path::Path>,
    overlay: Option<&'a std::path::Path>,
    peel_skirt: bool,
    region: unitac_contact::RegionRule,
}

/// One frame's line of `unitac contact`: JSON or text, with the depth's reading where there is
/// a photometric model (`model`: "calibration" or "kind default").
fn contact_line(
    file: &str,
    json: bool,
    m: &unitac_contact::Measurement,
    d: Option<(&unitac_contact::depth::DepthSummary, &str)>,
    noise_dn: [f32; 3],
) -> String {
    let contact = m.contact;
    let region = if m.from_depth { "depth" } else { "residual" };
    let dj = d.map(|(d, model)| {
        serde_json::json!({
            "contact": d.contact, "penetration_m": d.penetration_m,
            "area_px": d.area_px, "area_m2": d.area_m2, "centroid": d.centroid_px,
            "model": model,
        })
    });
    if json {
        let mut v = serde_json::json!({
            "file": file, "contact": contact, "area_px": m.area_px,
            "centroid": m.centroid, "bbox": m.bbox, "score": m.strength,
            "region": region, "noise_dn": noise_dn,
        });
        if let Some(dj) = dj {
            v["depth"] = dj;
        }
        v.to_string()
    } else {
        let mut t = format!(
            "{file}: contact {} area {:.0} px ({region}) centroid ({:.1}, {:.1}) bbox {:?} score {:.2} noise {:?} DN",
            if contact { "yes" } else { "no" },
            m.area_px,
            m.centroid[0],
            m.centroid[1],
            m.bbox,
            m.strength,
            noise_dn
        );
        if let Some((d, _)) = d {
            t += &format!(
                "; depth: penetration {:.3} mm area {:.2} mm^2 centroid ({:.1}, {:.1})",
                f64::from(d.penetration_m) * 1e3,
                d.area_m2 * 1e6,
                d.centroid_px[0],
                d.centroid_px[1]
            );
        }
        t
    }
}

fn cmd_contact(
    sensor: unitac_core::SensorKind,
    background: &std::path::Path,
    frames: &[PathBuf],
    json: bool,
    extra: &ContactExtras<'_>,
) -> anyhow::Result<bool> {
    use unitac_contact::{ContactDetector, ContactParams};
    // Each frame's overlay file is named after it (`images::output_file`).
    let overlay_files = match extra.overlay {
        Some(_) => images::output_files(&images::distinct_names(frames), "overlay.png")
            .map_err(|e| args::usage(format!("--overlay: {e:#}")))?,
        None => vec![String::new(); frames.len()],
    };
    let bg = images::read_frame(background, sensor.as_str(), 0, None)
        .map_err(|e| anyhow::Error::new(ConfigError(format!("background {e:#}"))))?;
    let params = ContactParams {
        peel_skirt: extra.peel_skirt,
        region: extra.region,
        ..ContactParams::default()
    };
    let mut det = ContactDetector::new(params, sensor.spec())
        .map_err(|e| anyhow::Error::new(ConfigError(e.to_string())))?;
    // The depth of every frame, from the unit's calibration or the kind's default.
    if let Some(p) = extra.depth_calibration {
        let cal = depth::contact_calibration(p, sensor, &bg)
            .map_err(|e| anyhow::Error::new(ConfigError(format!("--depth-calibration {e:#}"))))?;
        det.set_depth_calibration(cal, true);
    }
    det.estimate_depth_every_frame(true);
    det.set_background_frame(&bg);
    // (A background the model does not fit was warned about by the detector: no depth.)
    let depth_model = det.depth_model().unwrap_or_default();
    // Camera noise per channel [DN] from the difference of two single frames, per pixel.
    let stride = det.geometry_for(bg.width, bg.height).stride as f32;
    let noise_dn = |m: &unitac_contact::Measurement| {
        m.noise
            .map(|s| (s * stride / std::f32::consts::SQRT_2 * 100.0).round() / 100.0)
    };
    let size = (bg.width, bg.height);
    if let Some(d) = extra.overlay {
        std::fs::create_dir_all(d).map_err(|e| {
            anyhow::Error::new(ConfigError(format!("--overlay {}: {e}", d.display())))
        })?;
    }
    // The overlay's marker arrows (a marker gel): each image's markers from rest, image files
    // being independent presses.
    let slip = unitac_contact::SlipParams::default();
    let mut markers = None;
    if extra.overlay.is_some() && slip.check_for(sensor).is_ok() {
        let mut field = unitac_contact::MarkerField::default();
        match field.learn(&bg, &slip) {
            Ok(()) => markers = Some(field),
            Err(e) => args::warn(format_args!("--overlay: no marker arrows: {e}")),
        }
    }
    let stdout = std::io::stdout();
    let mut out = stdout.lock();
    let mut all_ok = true;
    for (i, (path, overlay_file)) in frames.iter().zip(&overlay_files).enumerate() {
        let file = path.display().to_string();
        let result =
            images::read_frame(path, sensor.as_str(), i as u64 + 1, Some(size)).and_then(|f| {
                let m = det
                    .measure(&f)
                    .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
                let d = det.depth().and_then(|(_, s)| s);
                if let Some(dir) = extra.overlay {
                    let depth_m = det.depth_map_m();
                    let d = match (det.depth(), &depth_m) {
                        (Some((e, _)), Some(m)) => Some((m.as_slice(), e.mask())),
                        _ => None,
                    };
                    let arrows = match markers.as_mut() {
                        Some(field) if m.contact => {
                            field.reset();
                            match field.follow(&f, &slip) {
                                Ok(_) => field.displacements(),
                                Err(_) => Vec::new(),
                            }
                        }
                        _ => Vec::new(),
                    };
                    let file = dir.join(overlay_file);
                    depth::overlay_png(&f, &det.mask_px(), m.centroid, &arrows, d, &file)?;
                }
                Ok((m, d))
            });
        let line = match result {
            Ok((m, d)) => contact_line(
                &file,
                json,
                &m,
                d.as_ref().map(|d| (d, depth_model)),
                noise_dn(&m),
            ),
            Err(e) => {
                all_ok = false;
                let msg = format!("{e:#}");
                if json {
                    serde_json::json!({ "file": file, "error": msg }).to_string()
                } else {
                    format!("{file}: error: {msg}")
                }
            }
        };
        writeln!(out, "{line}")?;
    }
    Ok(all_ok)
}

fn main() -> ExitCode {
    STARTED.get_or_init(std::time::Instant::now);
    unitac_cli::init_logging();
    let cli: Cli = match unitac_cli::parse(command()) {
        Ok(c) => c,
        Err(code) => return code,
    };
    // `unitac contact` exits 2 when a file failed (after every other file was processed).
    let failed = if matches!(cli.cmd, Cmd::Contact { .. }) {
        2
    } else {
        1
    };
    unitac_cli::exit_code(dispatch(cli.cmd), failed)
}

/// One command: Ok(false) when it ran but something in it failed (exit 1; 2 for `contact`).
fn dispatch(cmd: Cmd) -> anyhow::Result<bool> {
    match cmd {
        Cmd::Run {
            scene,
            sensor,
            json,
            events,
            fast,
            max_frames,
            scene_dir,
            out,
            print_params,
        } => cmd_run(
            &scene,
            sensor,
            json,
            events,
            fast,
            max_frames,
            scene_dir,
            out,
            print_params,
        ),
        Cmd::Contact {
            sensor,
            background,
            frames,
            json,
            depth_calibration,
            region,
            overlay,
            no_peel_skirt,
        } => {
            let extra = ContactExtras {
                depth_calibration: depth_calibration.as_deref(),
                overlay: overlay.as_deref(),
                peel_skirt: !no_peel_skirt,
                region,
            };
            cmd_contact(sensor, &background, &frames, json, &extra)
        }
        Cmd::Replay {
            bag,
            topic,
            rate,
            fast,
            looped,
            start,
            out,
            json,
            sensor,
            scene,
            events,
        } => replay::cmd_replay(replay::Args {
            bag,
            topic,
            rate,
            fast,
            looped,
            start,
            out,
            json,
            sensor,
            scene,
            events,
        }),
        Cmd::Bag {
            cmd: BagCmd::Repair { input, output },
        } => replay::cmd_repair(&input, &output),
        Cmd::Calibrate {
            cmd: depth::CalibrateCmd::Depth(a),
        } => depth::calibrate_depth(&a),
        Cmd::Calibrate {
            cmd: depth::CalibrateCmd::MockPresses(a),
        } => depth::mock_presses(&a),
        Cmd::Devices { json } => {
            let root = std::env::var_os("UNITAC_SYSFS_ROOT")
                .map(PathBuf::from)
                .unwrap_or_else(|| PathBuf::from("/"));
            emit_report(Ok(devices::devices(&root)), json, |r| r.text())
        }
        Cmd::Gripper(args) => gripper::run(args),
        Cmd::Scenes { scene_dir } => match scene_dir {
            Some(d) if !d.is_dir() => Err(args::usage(format!(
                "--scene-dir {}: not a directory",
                d.display()
            ))),
            scene_dir => emit(
                unitac_pipeline::scene_names(scene_dir)
                    .iter()
                    .map(|n| format!("{n}\n"))
                    .collect::<String>(),
            )
            .map(|()| true),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use unitac_cli::grammar;

    /// Every subcommand, option and positional of every `--help` page has a description, and so
    /// has every value of a subcommand's target (`eval contact|slip|depth`, ...).
    #[test]
    fn every_command_and_argument_has_a_description() {
        let cli = command();
        assert!(
            grammar::count(&cli) > 10,
            "{} commands",
            grammar::count(&cli)
        );
        let missing = grammar::undescribed(&cli);
        assert!(missing.is_empty(), "no description: {missing:#?}");
    }

    /// A command whose target is a positional (`bench contact`, ...) names each target in its
    /// summary, as `<command> <target>`.
    #[test]
    fn summaries_name_every_target() {
        let missing = grammar::targets_not_in_summaries(&command());
        assert!(missing.is_empty(), "not in the summary: {missing:?}");
    }

    /// Help texts are plain text: no markdown escapes (`\[mm]`) printed literally.
    #[test]
    fn help_texts_have_no_escapes() {
        let found = grammar::escaped_texts(&command());
        assert!(found.is_empty(), "{found:#?}");
    }
}
