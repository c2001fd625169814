//! Generates the Rust side of msg/unitac_msgs (see build/msggen.rs and the `msg` module docs).

#[path = "build/msggen.rs"]
mod msggen;

use std::path::PathBuf;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    let dir = manifest.join("../../msg/unitac_msgs/msg");
    println!("cargo::rerun-if-changed={}", dir.display());
    println!("cargo::rerun-if-changed=build/msggen.rs");
    let mut files = Vec::new();
    for entry in std::fs::read_dir(&dir)? {
        let path = entry?.path();
        if path.extension().is_some_and(|e| e == "msg") {
            println!("cargo::rerun-if-changed={}", path.display());
            let name = path
                .file_stem()
                .and_then(|s| s.to_str())
                .ok_or("a .msg file name is not UTF-8")?
                .to_string();
            files.push(msggen::MsgFile {
                name,
                text: std::fs::read_to_string(&path)?,
            });
        }
    }
    // Directory order is the file system's: sort for byte-identical output.
    files.sort_by(|a, b| a.name.cmp(&b.name));
    let code = msggen::generate(&files)?;
    let out = PathBuf::from(std::env::var("OUT_DIR")?).join("msg_generated.rs");
    std::fs::write(out, code)?;
    Ok(())
}
