//! The touch ablation's swap: what the tactile stages send the policy stage carries the donor
//! trial's values with this trial's stamps; without a donor a trial is the plain one.
#![allow(clippy::unwrap_used, clippy::panic)]

use unitac_core::msg::Msg;
use unitac_sim::task::{Split, TaskConfig, TaskKind};
use unitac_trials::{TouchSwap, TrialGripper, TrialOptions, run_trial_swapped};

fn contacts(msgs: &[unitac_trials::ChainMessage]) -> Vec<&unitac_core::msg::ContactState> {
    msgs.iter()
        .filter(|m| !m.input)
        .filter_map(|m| match &m.msg {
            Msg::ContactState(c) if c.in_contact => Some(c),
            _ => None,
        })
        .collect()
}

fn latents(msgs: &[unitac_trials::ChainMessage]) -> Vec<&unitac_core::msg::TactileLatent> {
    msgs.iter()
        .filter(|m| !m.input)
        .filter_map(|m| match &m.msg {
            Msg::TactileLatent(l) => Some(l),
            _ => None,
        })
        .collect()
}

#[test]
fn a_swapped_trial_reads_the_donors_latent_at_its_own_stamp() {
    let scene = unitac_pipeline::load_scene("cup_deformation_vtla_real", None).unwrap();
    let task = TaskConfig::new(TaskKind::CUP, Split::Train);
    let mut opts = TrialOptions::for_task(TaskKind::CUP);
    opts.keep_messages = true;
    opts.max_s = 6.0;
    let run = |trial, swap| {
        run_trial_swapped(
            &scene,
            &task,
            1,
            trial,
            &opts,
            TrialGripper::InProcess,
            swap,
        )
        .unwrap()
    };
    let own = run(0, TouchSwap::default());
    let donor = run(1, TouchSwap::default());
    let (o, d) = (latents(&own.messages), latents(&donor.messages));
    assert!(!o.is_empty() && !d.is_empty());
    assert_ne!(o[0].data, d[0].data, "two cups, two latents");
    // The record keeps the trial's own touch: its latents and in-contact states.
    let kept = |r: &unitac_trials::TrialRecord| {
        r.touch
            .iter()
            .filter(|m| matches!(m, Msg::TactileLatent(_)))
            .count()
    };
    assert_eq!(kept(&own), o.len());
    assert!(own.touch.len() > o.len());
    let swapped = run(0, TouchSwap::new(donor.touch.clone()));
    let s = latents(&swapped.messages);
    assert_eq!(s[0].data, d[0].data);
    assert_eq!(s[0].header.stamp, o[0].header.stamp);
    // What the stages made is still this trial's.
    match swapped
        .touch
        .iter()
        .find(|m| matches!(m, Msg::TactileLatent(_)))
    {
        Some(Msg::TactileLatent(l)) => assert_eq!(l.data, o[0].data),
        m => panic!("{m:?}"),
    }
    // The contact's geometry is the donor's, its stamp and its start this trial's.
    let (oc, dc, sc) = (
        contacts(&own.messages),
        contacts(&donor.messages),
        contacts(&swapped.messages),
    );
    assert!(!oc.is_empty() && !dc.is_empty() && !sc.is_empty());
    assert_eq!(sc[0].header.stamp, oc[0].header.stamp);
    assert_eq!(
        (sc[0].area_m2, sc[0].bbox_px, sc[0].strength),
        (dc[0].area_m2, dc[0].bbox_px, dc[0].strength)
    );
    assert_ne!(oc[0].area_m2, dc[0].area_m2, "two cups, two first contacts");
    // Up to the latent's arrival the trial is the plain one.
    let upto = |r: &unitac_trials::TrialRecord| {
        r.trace
            .iter()
            .filter(|t| t.t_s < o[0].header.stamp.0 as f64 * 1e-9)
            .map(|t| (t.opening_m, t.force_n))
            .collect::<Vec<_>>()
    };
    assert_eq!(upto(&swapped), upto(&own));
}
