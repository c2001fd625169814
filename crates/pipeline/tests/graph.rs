//! The stage graph (launch/stage_graph.yaml) against the stages as built: it declares exactly
//! the stage kinds the registry builds, and on the shipped mock scenes every stage produces only
//! kinds its entry declares (a stage that started making something new without saying so would
//! have no topic in the generic ROS node and no place in the scene check).
#![allow(clippy::unwrap_used, clippy::panic)]

use std::collections::{BTreeMap, BTreeSet};
use unitac_core::{Msg, StageRunner};
use unitac_pipeline::registry::graph;
use unitac_pipeline::{KNOWN_STAGES, build_source, build_stages, load_scene};

#[test]
fn the_graph_declares_exactly_the_stages_the_registry_builds() {
    unitac_core::graph::StageGraph::shipped().unwrap();
    let declared: BTreeSet<&str> = graph().stages.keys().map(String::as_str).collect();
    let built: BTreeSet<&str> = KNOWN_STAGES.iter().copied().collect();
    assert_eq!(declared, built);
}

#[test]
fn every_stage_produces_only_what_its_entry_declares() {
    for name in ["fabric_selection", "cup_deformation"] {
        let scene = load_scene(name, None).unwrap();
        let mut source = build_source(&scene, None).unwrap();
        let mut runners: Vec<StageRunner> = build_stages(&scene)
            .unwrap()
            .into_iter()
            .map(StageRunner::new)
            .collect();
        let kinds: Vec<String> = scene.stages.iter().map(|s| s.kind.clone()).collect();
        let mut made: BTreeMap<String, BTreeSet<&'static str>> = BTreeMap::new();
        let mut frames = 0;
        while let Some(f) = source.next_frame().unwrap() {
            // Stage by stage, as the chain feeds them: each one's outputs, then its input, go on.
            let mut inputs = vec![Msg::Frame(f)];
            for (runner, kind) in runners.iter_mut().zip(&kinds) {
                let mut next = Vec::new();
                for m in inputs {
                    let mut emitted = Vec::new();
                    runner.feed(m, &mut |o| emitted.push(o));
                    // The last one emitted is the input passed on; the rest are the stage's.
                    let input = emitted.pop().unwrap();
                    for o in &emitted {
                        made.entry(kind.clone()).or_default().insert(o.kind());
                    }
                    next.extend(emitted);
                    next.push(input);
                }
                inputs = next;
            }
            frames += 1;
        }
        assert!(frames > 100, "{name}: {frames}");
        for (kind, produced) in &made {
            let io = graph().stage(kind).unwrap();
            let declared: BTreeSet<&str> = io.produces().collect();
            assert!(
                produced.iter().all(|k| declared.contains(k)),
                "{name}: {kind} made {produced:?}, declares {declared:?}"
            );
            assert!(
                produced
                    .iter()
                    .all(|k| graph().kinds.iter().any(|g| g == k)),
                "{name}: {kind} made a kind the graph does not list: {produced:?}"
            );
        }
        // Not vacuous: the contact stage made its states and episodes, the encoder its latents.
        assert!(
            made["contact"].contains("contact_episode"),
            "{name}: {made:?}"
        );
        if name == "fabric_selection" {
            assert!(made["encoder"].contains("tactile_latent"), "{made:?}");
            assert!(made["compare"].contains("property_comparison"), "{made:?}");
        }
    }
}
