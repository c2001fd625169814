//! `unitac-lab report sim`: the simulator's numerics report (unitac_sim::numerics: its
//! integrators on soft, stiff and extreme cups, the stability map), its tables or JSON, and its
//! PNG plots ([`crate::sim_charts`]).

use crate::progress;
use unitac_cli::{ConfigError, emit};

/// The report, its plots written into `out` (made if missing).
pub fn report_sim(json: bool, out: &std::path::Path) -> anyhow::Result<bool> {
    use unitac_sim::numerics::{NumericsOptions, report_steps, report_with_progress};
    std::fs::create_dir_all(out)
        .map_err(|e| anyhow::Error::new(ConfigError(format!("--out {}: {e}", out.display()))))?;
    let opts = NumericsOptions::default();
    let bar = progress::bar(report_steps(&opts), "integrator study");
    let r = report_with_progress(&opts, &mut |done, _| bar.set_position(done));
    bar.finish_and_clear();
    let files = crate::sim_charts::write_plots(&r, out)?;
    if json {
        let mut v = serde_json::to_value(&r)?;
        v["plots"] = serde_json::json!(files);
        emit(format_args!("{v}\n"))?;
    } else {
        emit(r.text())?;
        for f in &files {
            emit(format_args!("wrote {}\n", f.display()))?;
        }
    }
    Ok(true)
}
