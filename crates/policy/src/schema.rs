//! The policies' data layout, written once in schema/policy.json and generated into constants
//! here at build time (crates/policy/build.rs); the Python dataset writer and trainers read the
//! same file (python/unitac_tools/schema.py). A feature `id` in the file is the constant `ID` (its
//! LeRobot key), `ID_NAMES`, `ID_UNITS` and `ID_LEN` where its values are fixed; the modes'
//! stage inputs and learned features, the command actions, the stiffness readout and the
//! manifest's fixed fields follow.
//!
//! Change a layout in the file, not here: `cargo test -p unitac-policy --test schema` checks the
//! Rust stages and the Python side against it.

include!(concat!(env!("OUT_DIR"), "/schema_generated.rs"));

/// The stage inputs `mode` reads in `task` (None: no such mode or task in the schema).
pub fn mode_inputs(mode: &str, task: &str) -> Option<&'static [&'static str]> {
    MODE_INPUTS
        .iter()
        .find(|(m, t, _)| *m == mode && *t == task)
        .map(|(_, _, v)| *v)
}

/// The feature keys the learned policy of `mode` reads.
pub fn learned_features(mode: &str) -> Option<&'static [&'static str]> {
    LEARNED_FEATURES
        .iter()
        .find(|(m, _)| *m == mode)
        .map(|(_, v)| *v)
}

/// The feature key of the stage input `name`.
pub fn input_feature(name: &str) -> Option<&'static str> {
    STAGE_INPUTS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, k)| *k)
}
