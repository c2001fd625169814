//! The help pages as printed: plain text (no markdown escapes such as `\[mm]`), with the texts
//! they promise. (That every option has a description, and that each command's summary names
//! every target it takes, is checked on clap's command tree, in main.rs.) `unitac-lab`'s pages:
//! crates/lab/tests/help.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

#[test]
fn help_pages_are_plain_text() {
    let mut all = Vec::new();
    common::shared::help_pages(env!("CARGO_BIN_EXE_unitac"), Vec::new(), &mut all);
    assert!(all.len() > 10, "{} pages", all.len());
    let page = |p: &str| {
        all.iter()
            .find(|(path, _)| path.join(" ") == p)
            .map(|(_, t)| t.clone())
            .unwrap()
    };
    assert!(
        page("calibrate depth")
            .contains("Radius of the ball pressed into the gel, in m (a 4 mm ball: 0.002)")
    );
}
