//! The help pages as printed: plain text (no markdown escapes such as `\[mm]`), and each
//! command's summary names every target it takes (`bench contact`, ..., `bench depth`). (That
//! every option has a description is checked on clap's command tree, in main.rs.) `unitac`'s
//! pages: crates/cli/tests/help.rs.
#![allow(clippy::unwrap_used, clippy::expect_used, clippy::panic)]

mod common;

#[test]
fn help_pages_are_plain_text_and_name_every_target() {
    let mut all = Vec::new();
    common::shared::help_pages(common::EXE, Vec::new(), &mut all);
    assert!(all.len() > 6, "{} pages", all.len());
    let page = |p: &str| {
        all.iter()
            .find(|(path, _)| path.join(" ") == p)
            .map(|(_, t)| t.clone())
            .unwrap()
    };
    assert!(page("").starts_with("UniTac lab tools"), "{}", page(""));
    let bench = page("bench");
    let summary = bench.split("\n\n").next().unwrap();
    for target in [
        "contact", "replay", "sampler", "render", "decode", "policy", "depth",
    ] {
        assert!(summary.contains(&format!("`bench {target}`")), "{summary}");
    }
    assert!(bench.contains("Usage: unitac-lab bench"), "{bench}");
}
