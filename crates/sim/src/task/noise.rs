//! Every noise and measurement figure of a task world, with what its source is: a datasheet
//! (or other published figure), a measurement of ours, or a modelling choice. A modelling choice
//! is a value we picked because nothing here measures it; the camera's are swept x0.5 / x1 / x2
//! by `unitac-lab trials --sweep`, so no table rests on one value of them.

use serde::Serialize;

use super::TaskConfig;

/// What a figure's value rests on.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum SourceKind {
    /// A manufacturer's datasheet or manual, or another published figure (named in the text).
    Datasheet,
    /// Measured by us on a real device (the text says how).
    Measured,
    /// Chosen for the model, not measured (the text says why this value).
    ModellingChoice,
}

/// A noise or measurement figure of the world and where it comes from.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct NoiseFigure {
    pub name: &'static str,
    pub value: f64,
    pub unit: &'static str,
    pub kind: SourceKind,
    /// The source: the document, or the reason for the chosen value, and whether it is swept.
    pub source: &'static str,
}

const CAMERA: &str = "not measured: a table camera's error of a few mm; swept x0.5 / x1 / x2 by `unitac-lab trials --sweep`";

impl TaskConfig {
    /// Every noise and measurement figure of this world with its source.
    pub fn noise_figures(&self) -> Vec<NoiseFigure> {
        use SourceKind::{Datasheet, ModellingChoice};
        let v = &self.vision;
        let s = &self.sensing;
        let fig = |name, value, unit, kind, source| NoiseFigure {
            name,
            value,
            unit,
            kind,
            source,
        };
        vec![
            fig(
                "camera position bias (per trial, sd)",
                v.position_bias_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera position noise (per frame, sd)",
                v.position_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera size bias (per trial, sd)",
                v.size_bias_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera size noise (per frame, sd)",
                v.size_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera fabric edge height bias (per trial, sd)",
                v.edge_bias_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera fabric edge height noise (per frame, sd)",
                v.edge_m,
                "m",
                ModellingChoice,
                CAMERA,
            ),
            fig(
                "camera fabric roughness bias (per trial, sd)",
                v.roughness_bias_m,
                "m",
                ModellingChoice,
                "not measured: the population sd of the five nominal fabric types' Ra, i.e. a camera \
                 modelled as knowing only which set a fabric comes from (it cannot resolve the \
                 texture); as large as the Ra gaps between unseen pairs, so the camera ranks them \
                 near chance by this choice; swept with the camera",
            ),
            fig(
                "camera fabric roughness noise (per frame, sd)",
                v.roughness_m,
                "m",
                ModellingChoice,
                "not measured: a quarter of that spread (image noise on an appearance cue); swept \
                 with the camera",
            ),
            fig(
                "gripper current resolution",
                s.current_step_a,
                "A",
                Datasheet,
                "Robotiq 2F-85/2F-140 manual: gCU, about 10 mA per count",
            ),
            fig(
                "gripper current noise (sd)",
                s.current_noise_a,
                "A",
                ModellingChoice,
                "not measured: half a count of the current register",
            ),
            fig(
                "gripper force constant (nominal)",
                s.force_per_amp,
                "N/A",
                ModellingChoice,
                "not measured: puts a 2F-140's 10-125 N grip range inside its current register",
            ),
            fig(
                "gripper force constant error (per trial, sd)",
                s.gain_error_sd,
                "relative",
                ModellingChoice,
                "not measured: screw-drive friction makes force from current a rough estimate \
                 (grippers quote force ranges, not accuracies)",
            ),
            fig(
                "gripper opening resolution",
                s.opening_step_m,
                "m",
                ModellingChoice,
                "not measured: a typical encoder step",
            ),
            fig(
                "gel pad half width across the closing axis",
                self.gripper.pad_half_width_m,
                "m",
                Datasheet,
                "GelSight Mini datasheet: 18.6 x 14.3 mm sensing area",
            ),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::task::Split;

    #[test]
    fn every_figure_says_what_its_source_is_and_chosen_camera_figures_are_swept() {
        for cfg in [
            TaskConfig::cup(Split::Unseen),
            TaskConfig::fabric(Split::Unseen),
        ] {
            let figs = cfg.noise_figures();
            assert!(figs.len() >= 14, "{}", figs.len());
            for f in &figs {
                assert!(f.value.is_finite() && f.value > 0.0, "{f:?}");
                // A chosen value says it was not measured; a datasheet names its document.
                match f.kind {
                    SourceKind::ModellingChoice => {
                        assert!(f.source.starts_with("not measured"), "{f:?}")
                    }
                    SourceKind::Datasheet => assert!(
                        f.source.contains("manual") || f.source.contains("datasheet"),
                        "{f:?}"
                    ),
                    SourceKind::Measured => assert!(f.source.contains("measured"), "{f:?}"),
                }
                if f.name.starts_with("camera") {
                    assert_eq!(f.kind, SourceKind::ModellingChoice, "{f:?}");
                    assert!(f.source.contains("swept"), "{f:?}");
                }
            }
        }
    }
}
