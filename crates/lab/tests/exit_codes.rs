//! The exit-code table of crates/cli/README.md for every subcommand of `unitac-lab`: each command
//! `unitac-lab --help` lists (and each of theirs, recursively, and each value of a target
//! positional such as `bench contact|replay|...`) is run with a bad value (an out-of-range number,
//! NaN, a directory that cannot be made), and must end at once with exit 2 and one line on stderr
//! starting `unitac-lab:`, no panic. `unitac`'s: crates/cli/tests/exit_codes.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

/// One bad value per command: the command (its subcommand path and target, as the walk names
/// it) and the arguments after `unitac-lab`. `{tmp}` is a fresh directory.
const CASES: &[(&str, &[&str])] = &[
    (
        "eval contact",
        &["eval", "contact", "--idle-minutes", "1e12"],
    ),
    ("eval slip", &["eval", "slip", "--idle-minutes", "NaN"]),
    ("eval depth", &["eval", "depth", "--out", "/dev/null/depth"]),
    ("bench contact", &["bench", "contact", "--frames", "0"]),
    ("bench replay", &["bench", "replay", "--repeat", "0"]),
    ("bench sampler", &["bench", "sampler", "--repeat", "NaN"]),
    ("bench render", &["bench", "render", "--repeat", "1001"]),
    ("bench decode", &["bench", "decode", "--frames", "-3"]),
    ("bench policy", &["bench", "policy", "--repeat", "0"]),
    (
        "bench policy",
        &[
            "bench",
            "policy",
            "--no-python",
            "--policy",
            "{tmp}/missing_policy",
        ],
    ),
    ("bench depth", &["bench", "depth", "--frames", "1e9"]),
    ("report sampler", &["report", "sampler", "--repeat", "0"]),
    (
        "report sim",
        &["report", "sim", "--out", "/dev/null/report"],
    ),
    (
        "dataset fabrics",
        &[
            "dataset", "fabrics", "--train", "0", "--test", "0", "--out", "{tmp}/ds",
        ],
    ),
    (
        "dataset touch",
        &["dataset", "touch", "--trials", "0", "--out", "{tmp}/ds"],
    ),
    (
        "demos",
        &[
            "demos",
            "--scene",
            "cup_deformation_vla",
            "--trials",
            "NaN",
            "--out",
            "{tmp}/demos",
        ],
    ),
    (
        "trials",
        &["trials", "--scene", "cup_deformation", "--trials", "0"],
    ),
];

#[test]
fn every_subcommand_refuses_a_bad_value_with_exit_2_and_one_line() {
    common::shared::every_command_refuses_a_bad_value(common::EXE, "unitac-lab", CASES);
}
