//! The stage graph (launch/stage_graph.yaml): the message kinds each stage kind consumes and
//! produces, and the ROS node group that runs it. A scene is checked against it as a graph (every
//! needed input made by the outside or by an earlier stage); a ROS stage node derives its topics
//! from it; the launch planner reads the same file.

use serde::Deserialize;
use std::collections::BTreeMap;
use thiserror::Error;

/// The shipped graph, as the stages of this build declare it.
pub const STAGE_GRAPH_YAML: &str = include_str!("../../../launch/stage_graph.yaml");

/// What one stage kind consumes and produces.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageIo {
    /// The ROS node group that runs it (a key of [`StageGraph::groups`]).
    pub group: String,
    /// Inputs it cannot work without.
    #[serde(default)]
    pub needs: Vec<String>,
    /// Inputs it reads when they come.
    #[serde(default)]
    pub takes: Vec<String>,
    /// What it produces.
    #[serde(default)]
    pub makes: Vec<String>,
    /// What it produces only when its params ask for it.
    #[serde(default)]
    pub may_make: Vec<String>,
}

impl StageIo {
    /// Every kind it consumes: needs, then takes.
    pub fn consumes(&self) -> impl Iterator<Item = &str> {
        self.needs.iter().chain(&self.takes).map(String::as_str)
    }
    /// Every kind it may produce: makes, then may_make.
    pub fn produces(&self) -> impl Iterator<Item = &str> {
        self.makes.iter().chain(&self.may_make).map(String::as_str)
    }
}

/// A ROS node group: the generic stage node, or an executable of its own.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Group {
    pub executable: Option<String>,
}

/// The stage graph.
#[derive(Debug, Clone, Default, PartialEq, Eq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StageGraph {
    /// Every message kind, in the order a node hands over what it received in one spin.
    pub kinds: Vec<String>,
    /// Kinds that come from outside the stages (sensor, camera, gripper).
    pub external: Vec<String>,
    pub groups: BTreeMap<String, Group>,
    pub stages: BTreeMap<String, StageIo>,
}

/// A graph file that does not hold together, or a scene whose stages do not.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum GraphError {
    #[error("stage graph: {0}")]
    Parse(String),
    #[error("stage graph: {stage}: unknown message kind '{kind}'")]
    UnknownKind { stage: String, kind: String },
    #[error("stage graph: {stage}: unknown group '{group}'")]
    UnknownGroup { stage: String, group: String },
    #[error("stage graph: external kind '{0}' is not a kind")]
    UnknownExternal(String),
    #[error(
        "{stage} needs {kind}, which {}",
        if makers.is_empty() { "no stage makes".to_string() } else {
            format!("a {} stage makes: it must come before it", makers.join(" or "))
        }
    )]
    MissingProducer {
        stage: String,
        kind: String,
        makers: Vec<String>,
    },
}

impl StageGraph {
    /// The shipped graph ([`STAGE_GRAPH_YAML`]).
    pub fn shipped() -> Result<Self, GraphError> {
        Self::parse(STAGE_GRAPH_YAML)
    }

    /// A graph from its YAML, every name checked.
    pub fn parse(text: &str) -> Result<Self, GraphError> {
        let g: Self = serde_yaml::from_str(text).map_err(|e| GraphError::Parse(e.to_string()))?;
        let known = |k: &str| g.kinds.iter().any(|x| x == k);
        if let Some(e) = g.external.iter().find(|k| !known(k)) {
            return Err(GraphError::UnknownExternal(e.clone()));
        }
        for (stage, io) in &g.stages {
            if !g.groups.contains_key(&io.group) {
                return Err(GraphError::UnknownGroup {
                    stage: stage.clone(),
                    group: io.group.clone(),
                });
            }
            if let Some(k) = io.consumes().chain(io.produces()).find(|k| !known(k)) {
                return Err(GraphError::UnknownKind {
                    stage: stage.clone(),
                    kind: k.to_string(),
                });
            }
        }
        Ok(g)
    }

    /// The declaration of stage kind `kind`.
    pub fn stage(&self, kind: &str) -> Option<&StageIo> {
        self.stages.get(kind)
    }

    /// Stage kinds that may make message kind `kind`, in name order.
    pub fn makers(&self, kind: &str) -> Vec<&str> {
        self.stages
            .iter()
            .filter(|(_, io)| io.produces().any(|k| k == kind))
            .map(|(s, _)| s.as_str())
            .collect()
    }

    /// Stage kinds in order, checked as a graph: each stage's needed inputs come from outside or
    /// from a stage before it. Kinds the graph does not declare are left to the caller.
    /// Returns the index of the first stage that fails, with why.
    pub fn check_order(&self, stages: &[&str]) -> Result<(), (usize, GraphError)> {
        for (i, st) in stages.iter().enumerate() {
            let Some(io) = self.stage(st) else { continue };
            for need in &io.needs {
                if self.external.contains(need) {
                    continue;
                }
                let made = stages[..i]
                    .iter()
                    .filter_map(|s| self.stage(s))
                    .any(|p| p.produces().any(|k| k == need));
                if !made {
                    let makers = self.makers(need).iter().map(|s| s.to_string()).collect();
                    return Err((
                        i,
                        GraphError::MissingProducer {
                            stage: st.to_string(),
                            kind: need.clone(),
                            makers,
                        },
                    ));
                }
            }
        }
        Ok(())
    }

    /// Stage kind -> the stage kind that makes what it needs (one pair per needed kind that comes
    /// from a stage), for checks that follow a chain back to its source.
    pub fn stage_needs(&self) -> Vec<(&str, &str)> {
        let mut out = Vec::new();
        for (stage, io) in &self.stages {
            for need in io.needs.iter().filter(|k| !self.external.contains(k)) {
                for m in self.makers(need) {
                    out.push((stage.as_str(), m));
                }
            }
        }
        out
    }

    /// Kinds a node running `stages` (a subset of a scene's, in scene order) receives from
    /// outside: what they consume and none of them makes, in [`Self::kinds`] order.
    pub fn inputs_of(&self, stages: &[&str]) -> Vec<&str> {
        let ios: Vec<&StageIo> = stages.iter().filter_map(|s| self.stage(s)).collect();
        self.kinds
            .iter()
            .map(String::as_str)
            .filter(|k| ios.iter().any(|io| io.consumes().any(|c| c == *k)))
            .filter(|k| !ios.iter().any(|io| io.produces().any(|p| p == *k)))
            .collect()
    }

    /// Kinds a node running `stages` may publish: everything they may make, in [`Self::kinds`]
    /// order.
    pub fn outputs_of(&self, stages: &[&str]) -> Vec<&str> {
        let ios: Vec<&StageIo> = stages.iter().filter_map(|s| self.stage(s)).collect();
        self.kinds
            .iter()
            .map(String::as_str)
            .filter(|k| ios.iter().any(|io| io.produces().any(|p| p == *k)))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn shipped_graph_parses_and_orders_the_chain() {
        let g = StageGraph::shipped().unwrap();
        assert!(
            g.check_order(&["contact", "slip", "encoder", "compare"])
                .is_ok()
        );
        // An encoder before the contact stage never sees a clip.
        let (i, e) = g.check_order(&["encoder", "contact"]).unwrap_err();
        assert_eq!(i, 0);
        assert_eq!(
            e.to_string(),
            "encoder needs contact_clip, which a contact stage makes: it must come before it"
        );
        // Compare with no encoder: nothing makes properties.
        let (i, _) = g.check_order(&["contact", "compare"]).unwrap_err();
        assert_eq!(i, 1);
        // The policy needs only the gripper, from outside.
        assert!(g.check_order(&["policy"]).is_ok());
        let needs = g.stage_needs();
        assert!(needs.contains(&("compare", "encoder")));
        assert!(needs.contains(&("encoder", "contact")));
        assert!(!needs.iter().any(|(s, _)| *s == "policy"));
    }

    #[test]
    fn a_node_subscribes_to_what_its_stages_consume_and_do_not_make() {
        let g = StageGraph::shipped().unwrap();
        assert_eq!(g.inputs_of(&["contact", "slip"]), ["frame"]);
        assert_eq!(
            g.inputs_of(&["encoder", "compare", "sampler"]),
            ["background", "visual_observation", "contact_clip"]
        );
        // Compare alone listens for the properties the encoder publishes.
        assert_eq!(g.inputs_of(&["compare"]), ["tactile_properties"]);
        // Everything in one node: only the outside.
        assert_eq!(
            g.inputs_of(&["contact", "encoder", "compare", "sampler"]),
            ["visual_observation", "frame"]
        );
        assert_eq!(
            g.outputs_of(&["encoder", "sampler"]),
            ["tactile_properties", "tactile_latent"]
        );
    }

    #[test]
    fn a_bad_graph_is_one_line() {
        let bad =
            "kinds: [a]\nexternal: [a]\ngroups: {g: {}}\nstages: {s: {group: g, needs: [b]}}\n";
        assert_eq!(
            StageGraph::parse(bad).unwrap_err().to_string(),
            "stage graph: s: unknown message kind 'b'"
        );
        let bad = "kinds: [a]\nexternal: []\ngroups: {}\nstages: {s: {group: h}}\n";
        assert!(matches!(
            StageGraph::parse(bad),
            Err(GraphError::UnknownGroup { .. })
        ));
        assert!(matches!(
            StageGraph::parse("kinds: 3"),
            Err(GraphError::Parse(_))
        ));
    }
}
