//! Turns the committed object split (`objects/split.yaml`) into Rust constants
//! (`task::split::SPLIT`), so a bad split file fails the build instead of a trial.

use serde::Deserialize;
use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::PathBuf;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Split {
    cups: Cups,
    fabrics: Fabrics,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Cups {
    train: CupRange,
    unseen: CupRange,
    stiffness_factor: [f64; 2],
    mass_kg: [f64; 2],
    friction: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct CupRange {
    diameter_m: [f64; 2],
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct Fabrics {
    train_types: Vec<String>,
    unseen_types: Vec<String>,
    types: BTreeMap<String, FabricType>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct FabricType {
    roughness_m: [f64; 2],
    period_m: [f64; 2],
    bump_m: [f64; 2],
    bump_density: [f64; 2],
    hardness: [f64; 2],
    layer_m: [f64; 2],
    k_n_per_m: [f64; 2],
    friction: [f64; 2],
    mass_kg: [f64; 2],
    layers: [u32; 2],
}

/// A range of the split outside its allowed span, or upside down.
#[derive(Debug, thiserror::Error)]
#[error("{name} = {r:?}: needs {min} <= low <= high <= {max}")]
struct RangeError {
    name: String,
    r: [f64; 2],
    min: f64,
    max: f64,
}

fn range(name: &str, r: [f64; 2], min: f64, max: f64) -> Result<String, RangeError> {
    if !(r[0].is_finite() && r[1].is_finite() && min <= r[0] && r[0] <= r[1] && r[1] <= max) {
        return Err(RangeError {
            name: name.to_string(),
            r,
            min,
            max,
        });
    }
    Ok(format!("Uniform({:?}, {:?})", r[0], r[1]))
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR")?);
    let path = manifest.join("../../objects/split.yaml");
    println!("cargo::rerun-if-changed={}", path.display());
    let text = std::fs::read_to_string(&path)?;
    let s: Split = serde_yaml::from_str(&text).map_err(|e| format!("{}: {e}", path.display()))?;
    let bad = |e: String| format!("{}: {e}", path.display());
    let c = &s.cups;
    let mut out = String::new();
    writeln!(
        out,
        "/// The committed object split (generated from objects/split.yaml)."
    )?;
    writeln!(out, "pub const SPLIT: ObjectSplit = ObjectSplit {{")?;
    writeln!(out, "    cups: CupSplit {{")?;
    writeln!(
        out,
        "        train_diameter_m: {},",
        range("cups.train.diameter_m", c.train.diameter_m, 0.020, 0.200)
            .map_err(|e| bad(e.to_string()))?
    )?;
    writeln!(
        out,
        "        unseen_diameter_m: {},",
        range("cups.unseen.diameter_m", c.unseen.diameter_m, 0.020, 0.200)
            .map_err(|e| bad(e.to_string()))?
    )?;
    for (k, v, lo, hi) in [
        ("stiffness_factor", c.stiffness_factor, 0.01, 100.0),
        ("mass_kg", c.mass_kg, 0.0, 5.0),
        ("friction", c.friction, 0.01, 5.0),
    ] {
        writeln!(
            out,
            "        {k}: {},",
            range(&format!("cups.{k}"), v, lo, hi).map_err(|e| bad(e.to_string()))?
        )?;
    }
    writeln!(out, "    }},")?;
    let f = &s.fabrics;
    for (which, list) in [
        ("train_types", &f.train_types),
        ("unseen_types", &f.unseen_types),
    ] {
        if list.len() < 2 {
            return Err(bad(format!(
                "fabrics.{which}: a trial pairs two types, give at least two"
            ))
            .into());
        }
        for t in list {
            if !f.types.contains_key(t) {
                return Err(bad(format!(
                    "fabrics.{which}: no type '{t}' under fabrics.types"
                ))
                .into());
            }
        }
    }
    if let Some(t) = f.train_types.iter().find(|t| f.unseen_types.contains(t)) {
        return Err(bad(format!(
            "fabric type '{t}' is both a training and an unseen type"
        ))
        .into());
    }
    writeln!(out, "    fabrics: FabricSplit {{")?;
    writeln!(out, "        train_types: &{:?},", f.train_types)?;
    writeln!(out, "        unseen_types: &{:?},", f.unseen_types)?;
    writeln!(out, "        types: &[")?;
    for (name, t) in &f.types {
        writeln!(out, "            FabricType {{")?;
        writeln!(out, "                name: {name:?},")?;
        for (k, v, lo, hi) in [
            ("roughness_m", t.roughness_m, 0.0, 1e-3),
            ("period_m", t.period_m, 5e-5, 0.010),
            ("bump_m", t.bump_m, 0.0, 0.002),
            ("bump_density", t.bump_density, 0.0, 1e7),
            ("hardness", t.hardness, 0.05, 1.0),
            ("layer_m", t.layer_m, 1e-4, 0.010),
            ("k_n_per_m", t.k_n_per_m, 10.0, 1e5),
            ("friction", t.friction, 0.01, 5.0),
            ("mass_kg", t.mass_kg, 0.001, 5.0),
        ] {
            let r = range(&format!("fabrics.types.{name}.{k}"), v, lo, hi)
                .map_err(|e| bad(e.to_string()))?;
            writeln!(out, "                {k}: {r},")?;
        }
        let [l0, l1] = t.layers;
        if !(1 <= l0 && l0 <= l1 && l1 <= 20) {
            return Err(bad(format!(
                "fabrics.types.{name}.layers = {:?}: needs 1 <= low <= high <= 20",
                t.layers
            ))
            .into());
        }
        writeln!(out, "                layers: ({l0}, {l1}),")?;
        writeln!(out, "            }},")?;
    }
    writeln!(out, "        ],")?;
    writeln!(out, "    }},")?;
    writeln!(out, "}};")?;
    let dest = PathBuf::from(std::env::var("OUT_DIR")?).join("split.rs");
    std::fs::write(dest, out)?;
    Ok(())
}
