//! The exit-code table of crates/cli/README.md for every subcommand: each command `unitac --help`
//! lists (and each of theirs, recursively, and each value of a target positional) is run with a
//! bad value (an out-of-range number, NaN, a missing file), and must end at once with exit 2 and
//! one line on stderr starting `unitac:`, no panic. `unitac-lab`'s: crates/lab/tests/exit_codes.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

/// One bad value per command: the command (its subcommand path and target, as the walk names
/// it) and the arguments after `unitac`. `{tmp}` is a fresh directory.
const CASES: &[(&str, &[&str])] = &[
    (
        "run",
        &["run", "--scene", "cup_deformation_vla", "--max-frames", "0"],
    ),
    (
        "contact",
        &[
            "contact",
            "--sensor",
            "gelsight-mini",
            "--background",
            "{tmp}/missing.png",
            "{tmp}/f.png",
        ],
    ),
    ("replay", &["replay", "{tmp}/missing_bag", "--rate", "NaN"]),
    (
        "bag repair",
        &["bag", "repair", "{tmp}/missing_bag", "{tmp}/out_bag"],
    ),
    (
        "calibrate depth",
        &[
            "calibrate",
            "depth",
            "--sensor",
            "gelsight-mini",
            "--ball-radius-m",
            "NaN",
            "--background",
            "{tmp}/bg.png",
            "--out",
            "{tmp}/cal.json",
            "{tmp}/p.png",
        ],
    ),
    (
        "calibrate mock-presses",
        &[
            "calibrate",
            "mock-presses",
            "--noise-dn",
            "NaN",
            "--out",
            "{tmp}/mock",
        ],
    ),
    ("devices", &["devices", "--json=maybe"]),
    (
        "gripper activate",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_tty",
            "--model",
            "robotiq_2f85",
            "activate",
        ],
    ),
    (
        "gripper open",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "NaN",
            "open",
        ],
    ),
    (
        "gripper close",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--force",
            "-1",
            "close",
        ],
    ),
    (
        "gripper status",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_tty",
            "--model",
            "robotiq_2f85",
            "status",
        ],
    ),
    (
        "gripper bench",
        &[
            "gripper",
            "--port",
            "sim",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "1e12",
            "bench",
        ],
    ),
    (
        "gripper simulate",
        &[
            "gripper",
            "--port",
            "{tmp}/missing_dir/tty",
            "--model",
            "robotiq_2f85",
            "--seconds",
            "1",
            "simulate",
        ],
    ),
    ("scenes", &["scenes", "--scene-dir", "{tmp}/missing_dir"]),
];

#[test]
fn every_subcommand_refuses_a_bad_value_with_exit_2_and_one_line() {
    common::shared::every_command_refuses_a_bad_value(
        env!("CARGO_BIN_EXE_unitac"),
        "unitac",
        CASES,
    );
}
