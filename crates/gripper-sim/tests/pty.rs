//! The real driver against simulated Robotiq 2F-85 and DH AG-95 devices on pseudo-terminals,
//! paced at 115200 baud: activation, commands, object detection, every injected fault, restart
//! and re-plug. No timing is asserted except "the caller's methods return at once" while the
//! device is stalled for much longer than that.

#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

use std::path::PathBuf;
use std::time::{Duration, Instant};
use unitac_gripper::{
    Activation, DriverConfig, Fault, Gripper, GripperSetpoint, Model, Motion, SerialGripper,
};
use unitac_gripper_sim::device::physics::SimObject;
use unitac_gripper_sim::device::{DeviceConfig, SimDevice};

const WAIT: Duration = Duration::from_secs(10);

fn wait_for(what: &str, g: &SerialGripper, mut ok: impl FnMut(&SerialGripper) -> bool) {
    let t0 = Instant::now();
    while t0.elapsed() < WAIT {
        if ok(g) {
            return;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    panic!(
        "timed out waiting for {what}: state {:?}, stats {:?}",
        g.state(),
        g.stats()
    );
}

fn device(model: Model, active: bool, object: Option<f64>) -> SimDevice {
    let mut cfg = DeviceConfig::new(model);
    cfg.start_active = active;
    cfg.activation_s = 0.2;
    cfg.object = object.map(|w| SimObject {
        width_m: w,
        stiffness_n_per_m: 20_000.0,
    });
    SimDevice::spawn(cfg).unwrap()
}

fn driver(dev: &SimDevice, model: Model) -> SerialGripper {
    let mut cfg = DriverConfig::new(dev.path(), model);
    cfg.rate_hz = 200.0;
    cfg.timeout = Duration::from_millis(30);
    cfg.retries = 2;
    cfg.reopen_after = 1000;
    SerialGripper::start(cfg).unwrap()
}

fn cmd(opening_m: f64, force_n: f64) -> GripperSetpoint {
    GripperSetpoint {
        opening_m,
        speed_m_s: 0.15,
        force_n,
    }
}

/// At `opening_m` within half a millimetre, motion finished.
fn reached(opening_m: f64) -> impl FnMut(&SerialGripper) -> bool {
    move |g| {
        let s = g.state();
        s.motion == Motion::Reached && s.opening_m.is_some_and(|o| (o - opening_m).abs() < 0.0005)
    }
}

fn updates_after(g: &SerialGripper, n: u64) -> impl FnMut(&SerialGripper) -> bool + use<> {
    let start = g.state().updates;
    move |g| g.state().updates >= start + n
}

#[test]
fn robotiq_activation_position_and_force() {
    let dev = device(Model::named("robotiq_2f85").unwrap(), false, Some(0.05));
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("the first status", &g, |g| {
        g.state().activation == Activation::Inactive
    });
    g.activate().unwrap();
    wait_for("activation", &g, |g| {
        g.state().activation == Activation::Active
    });
    assert_eq!(dev.snapshot().activations, 1);
    assert_eq!(dev.snapshot().deactivations, 0);

    // Position: 70 mm, no object in the way.
    g.command(cmd(0.070, 50.0)).unwrap();
    wait_for("70 mm", &g, reached(0.070));
    // 15 mm closed of 85 mm over 227 counts (the assumed calibration): count 40.
    assert_eq!(g.state().raw_position, Some(40));

    // Close on the 50 mm object at 100 N: stops where the contact force is 100 N (45 mm).
    g.command(cmd(0.0, 100.0)).unwrap();
    wait_for("caught", &g, |g| g.state().motion == Motion::Caught);
    let s = dev.snapshot();
    assert_eq!(s.object, 2, "gOBJ = 2");
    let f100 = s.fingers.force_n;
    assert!((f100 - 100.0).abs() < 10.0, "force {f100}");
    let o100 = g.state().opening_m.unwrap();
    assert!((o100 - 0.045).abs() < 0.0008, "opening {o100}");

    // A lower force limit: a wider opening, less force.
    g.command(cmd(0.0, 40.0)).unwrap();
    wait_for("re-caught", &g, |g| {
        g.state().motion == Motion::Caught && g.state().opening_m.unwrap() > o100 + 0.001
    });
    assert!(dev.snapshot().fingers.force_n < 60.0);
    assert!(g.state().current_a.unwrap() > 0.0);
    assert_eq!(dev.snapshot().deactivations, 0);

    // Everything so far was within the model's range: nothing clamped. A touch speed below the
    // 2F-85's minimum is clamped to it, counted and said.
    assert_eq!(g.stats().clamped_commands, 0);
    let min = g.limits().min_speed_m_s;
    for _ in 0..2 {
        g.command(GripperSetpoint {
            speed_m_s: 0.001,
            ..cmd(0.0, 40.0)
        })
        .unwrap();
    }
    let st = g.stats();
    assert_eq!(st.clamped_commands, 2);
    let said = st.last_clamp.unwrap();
    assert_eq!(said, format!("speed 0.001 -> {min:.3} m/s"));
}

#[test]
fn restart_while_holding_keeps_the_object_held() {
    let dev = device(Model::named("robotiq_2f85").unwrap(), true, Some(0.04));
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("active", &g, |g| g.state().activation == Activation::Active);
    g.command(cmd(0.0, 80.0)).unwrap();
    wait_for("caught", &g, |g| g.state().motion == Motion::Caught);
    let held = dev.snapshot();
    drop(g);

    // A new driver, even one asked to activate, reads first and writes nothing.
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    g.activate().unwrap();
    wait_for("status after restart", &g, |g| g.state().updates >= 20);
    let s = g.state();
    assert_eq!(s.activation, Activation::Active);
    assert_eq!(s.motion, Motion::Caught);
    let now = dev.snapshot();
    assert_eq!(now.deactivations, 0, "rACT = 0 was written");
    assert_eq!(now.activations, held.activations);
    assert!((now.fingers.force_n - held.fingers.force_n).abs() < 1e-9);
    assert!(now.fingers.force_n > 70.0);
}

#[test]
fn link_faults_are_retried_or_reported_and_never_block() {
    let dev = device(Model::named("robotiq_2f85").unwrap(), true, None);
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("active", &g, |g| g.state().activation == Activation::Active);

    // One-off faults: recovered by the retry, the state stays fault-free.
    type Inject = fn(&mut unitac_gripper_sim::device::Faults);
    let one_offs: [(&str, Inject); 5] = [
        ("no reply", |f| f.no_reply = 1),
        ("half frame", |f| f.half_frame = 1),
        ("corrupted CRC", |f| f.corrupt_crc = 1),
        ("other slave id", |f| f.wrong_slave = 1),
        ("garbage before the reply", |f| f.garbage_before = 3),
    ];
    for (what, inject) in one_offs {
        let before = g.stats().link;
        dev.faults(inject);
        wait_for(what, &g, updates_after(&g, 10));
        let after = g.stats().link;
        assert!(
            after.retries > before.retries || after.dropped_bytes > before.dropped_bytes,
            "{what}: no retry seen ({before:?} -> {after:?})"
        );
        assert_eq!(g.state().fault, None, "{what}");
    }

    // Persistent faults: a clear link fault naming the cause; the caller is never held up.
    type Check = fn(&str) -> bool;
    let persistent: [(&str, Inject, Check); 4] = [
        ("mute", |f| f.mute = true, |m| m.contains("no reply")),
        (
            "half frames",
            |f| f.half_frame = u32::MAX,
            |m| m.contains("incomplete reply") && m.contains("of 11 bytes"),
        ),
        (
            "bad CRCs",
            |f| f.corrupt_crc = u32::MAX,
            |m| m.contains("garbled"),
        ),
        (
            "wrong slave",
            |f| f.wrong_slave = u32::MAX,
            |m| m.contains("slave 10, expected slave 9"),
        ),
    ];
    for (what, inject, check) in persistent {
        dev.faults(inject);
        wait_for(
            what,
            &g,
            |g| matches!(&g.state().fault, Some(Fault::Link { what }) if check(what)),
        );
        let t = Instant::now();
        for _ in 0..100 {
            let _ = g.state();
            g.command(cmd(0.08, 50.0)).unwrap();
        }
        // A blocking call would wait for at least one 30 ms exchange: 100 calls, >= 3 s.
        assert!(
            t.elapsed() < Duration::from_secs(1),
            "{what}: calls blocked"
        );
        dev.faults(|f| *f = Default::default());
        wait_for("recovery", &g, |g| g.state().fault.is_none());
    }

    // A slow device (replies 15 ms after the 30 ms timeout): a link fault while it lasts.
    dev.faults(|f| f.delay = Duration::from_millis(45));
    wait_for("slow", &g, |g| {
        matches!(g.state().fault, Some(Fault::Link { .. }))
    });
    dev.faults(|f| f.delay = Duration::ZERO);
    wait_for("fast again", &g, |g| g.state().fault.is_none());
    g.command(cmd(0.030, 50.0)).unwrap();
    wait_for("30 mm", &g, reached(0.030));
}

#[test]
fn overcurrent_needs_clear_fault_and_is_the_only_ract_low() {
    let dev = device(Model::named("robotiq_2f85").unwrap(), true, None);
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("active", &g, |g| g.state().activation == Activation::Active);
    dev.overcurrent();
    wait_for("overcurrent", &g, |g| {
        matches!(g.state().fault, Some(Fault::Major { code: 0x0E, .. }))
    });
    // Commands do not clear it.
    g.command(cmd(0.02, 50.0)).unwrap();
    wait_for("still faulted", &g, updates_after(&g, 20));
    assert!(matches!(g.state().fault, Some(Fault::Major { .. })));
    assert_eq!(dev.snapshot().deactivations, 0);
    g.clear_fault().unwrap();
    wait_for("re-activated", &g, |g| {
        g.state().fault.is_none() && g.state().activation == Activation::Active
    });
    assert_eq!(dev.snapshot().deactivations, 1);
    // The command given during the fault runs after re-activation.
    wait_for("20 mm", &g, reached(0.020));
}

#[test]
fn one_second_without_communication_is_reported_then_cleared() {
    let dev = device(Model::named("robotiq_2f85").unwrap(), true, None);
    let g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("active", &g, |g| g.state().activation == Activation::Active);
    drop(g);
    std::thread::sleep(Duration::from_millis(1300));
    assert_eq!(dev.snapshot().fault, 0x09);
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("fault 0x09", &g, |g| {
        matches!(g.state().fault, Some(Fault::Minor { code: 0x09, .. }))
    });
    g.command(cmd(0.05, 50.0)).unwrap();
    wait_for("cleared by a command", &g, |g| g.state().fault.is_none());
}

#[test]
fn unplugged_adapter_is_reopened_by_its_stable_name() {
    let dir = std::env::temp_dir().join(format!("unitac-gripper-replug-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let link: PathBuf = dir.join("usb-Robotiq_sim-if00-port0");
    let mut cfg = DeviceConfig::new(Model::named("robotiq_2f85").unwrap());
    cfg.start_active = true;
    cfg.link = Some(link.clone());
    let dev = SimDevice::spawn(cfg).unwrap();
    let mut dcfg = DriverConfig::new(&link, Model::named("robotiq_2f85").unwrap());
    dcfg.timeout = Duration::from_millis(30);
    let g = SerialGripper::start(dcfg).unwrap();
    wait_for("active", &g, |g| g.state().activation == Activation::Active);
    let first = std::fs::read_link(&link).unwrap();
    dev.unplug();
    wait_for("link fault", &g, |g| {
        !g.stats().connected && matches!(g.state().fault, Some(Fault::Link { .. }))
    });
    dev.replug();
    wait_for("back", &g, |g| {
        g.stats().connected && g.state().fault.is_none()
    });
    assert!(g.stats().opens >= 2);
    // Another pty, same stable name; the gripper was never reset.
    let _ = first;
    assert_eq!(dev.snapshot().deactivations, 0);
    assert_eq!(g.state().activation, Activation::Active);
    drop(g);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn dh_initialise_move_and_catch() {
    let dev = device(Model::named("dh_ag95").unwrap(), false, Some(0.06));
    let mut g = driver(&dev, Model::named("dh_ag95").unwrap());
    wait_for("first status", &g, |g| {
        g.state().activation == Activation::Inactive
    });
    g.command(cmd(0.08, 100.0)).unwrap();
    wait_for("still inactive", &g, updates_after(&g, 10));
    assert_eq!(
        dev.snapshot().activations,
        0,
        "a command alone does not initialise"
    );
    g.activate().unwrap();
    wait_for("initialised", &g, |g| {
        g.state().activation == Activation::Active
    });
    wait_for("80 mm", &g, reached(0.080));
    g.command(cmd(0.0, 100.0)).unwrap();
    wait_for("caught", &g, |g| g.state().motion == Motion::Caught);
    let f = dev.snapshot().fingers.force_n;
    assert!((f - 100.0).abs() < 5.0, "force {f}");
    assert_eq!(dev.snapshot().activations, 1);
    // Restart: no re-initialisation of an initialised gripper.
    drop(g);
    let mut g = driver(&dev, Model::named("dh_ag95").unwrap());
    g.activate().unwrap();
    wait_for("status after restart", &g, |g| g.state().updates >= 10);
    assert_eq!(g.state().motion, Motion::Caught);
    assert_eq!(dev.snapshot().activations, 1);
}

#[test]
fn missing_port_is_a_link_fault_naming_the_port() {
    let g = SerialGripper::start(DriverConfig::new(
        "/dev/ttyUSB-unitac-none",
        Model::named("robotiq_2f85").unwrap(),
    ))
    .unwrap();
    wait_for(
        "fault",
        &g,
        |g| matches!(&g.state().fault, Some(Fault::Link { what }) if what.contains("/dev/ttyUSB-unitac-none: no such serial device")),
    );
}

#[test]
fn every_model_activates_and_reaches_a_position_in_si_units() {
    for model in Model::all() {
        let dev = device(model, false, None);
        let mut g = driver(&dev, model);
        g.activate().unwrap();
        wait_for("active", &g, |g| g.state().activation == Activation::Active);
        let half = g.limits().max_opening_m / 2.0;
        g.command(cmd(half, g.limits().max_force_n)).unwrap();
        wait_for(model.name(), &g, reached(half));
        assert_eq!(dev.snapshot().activations, 1, "{model}");
    }
}

/// The cup trial's swap: the same world gripper in-process and behind a simulated Robotiq on a
/// pty, closed on the same cup at the same force limit, end in the same place.
#[test]
fn sim_world_gripper_in_process_and_over_the_pty_agree() {
    use unitac_gripper_sim::sim_world::{SimWorldGripper, WorldFingers};
    use unitac_sim::{Cup, World, WorldConfig};
    let world = || World::new(WorldConfig::new(Cup::paper(0.060)));
    let limits = Model::named("robotiq_2f85").unwrap().calibration().limits;
    let close = GripperSetpoint {
        opening_m: 0.0,
        speed_m_s: 0.15,
        force_n: 20.0,
    };

    let mut local = SimWorldGripper::new(world(), limits);
    local.command(close).unwrap();
    for _ in 0..5000 {
        local.advance(0.002).unwrap();
    }
    let l = local.state();
    assert_eq!(l.motion, Motion::Caught);

    let mut cfg = DeviceConfig::new(Model::named("robotiq_2f85").unwrap());
    cfg.start_active = true;
    let fingers = WorldFingers::new(world(), limits.max_opening_m);
    let dev = SimDevice::spawn_with(cfg, Box::new(fingers)).unwrap();
    let mut g = driver(&dev, Model::named("robotiq_2f85").unwrap());
    wait_for("active", &g, |g| g.state().activation == Activation::Active);
    g.command(close).unwrap();
    wait_for("caught over the pty", &g, |g| {
        g.state().motion == Motion::Caught
    });
    std::thread::sleep(Duration::from_secs(2));
    let remote = dev.snapshot().fingers;
    let (lo, lf) = (l.opening_m.unwrap(), l.force_n.unwrap());
    assert!(
        (remote.opening_m - lo).abs() < 0.0005,
        "{} vs {lo}",
        remote.opening_m
    );
    assert!(
        (remote.force_n - lf).abs() < 1.0,
        "{} vs {lf}",
        remote.force_n
    );
    assert!((19.0..21.5).contains(&lf), "force {lf}");
}

#[test]
fn requests_no_gripper_serves_get_exception_replies_on_the_wire() {
    // Raw frames on the pty, as any Modbus master may send them.
    let dev = device(Model::named("robotiq_2f85").unwrap(), false, None);
    let mut port = unitac_gripper::port::open(&dev.path(), 115_200).unwrap();
    port.set_timeout(Duration::from_millis(500)).unwrap();
    let mut ask = |pdu: &[u8]| {
        let mut frame = vec![9];
        frame.extend_from_slice(pdu);
        unitac_gripper::crc::append_crc(&mut frame);
        std::io::Write::write_all(&mut port, &frame).unwrap();
        let mut reply = vec![0u8; 5];
        std::io::Read::read_exact(&mut port, &mut reply).unwrap();
        assert!(unitac_gripper::crc::crc_ok(&reply), "{reply:02X?}");
        (reply[1], reply[2])
    };
    // Read coils (FC 0x01): illegal function.
    assert_eq!(ask(&[0x01, 0x00, 0x00, 0x00, 0x08]), (0x81, 0x01));
    // A read of 0 registers: illegal data value.
    assert_eq!(ask(&[0x04, 0x07, 0xD0, 0x00, 0x00]), (0x84, 0x03));
    // A read past the status block: illegal data address.
    assert_eq!(ask(&[0x04, 0x07, 0xD2, 0x00, 0x02]), (0x84, 0x02));
}
