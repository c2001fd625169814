//! The one chain driver: how a stage is fed, whoever feeds it.
//!
//! Every transport (the embedded runtime's stage threads, bag replay, the ROS nodes) drives its
//! stages through a [`StageRunner`], so the rules below hold everywhere:
//! - **Order**: a stage's outputs for an input go downstream first, then the input itself, so a
//!   later stage sees everything upstream produced, in the order it was produced.
//! - **Clock**: a stage sees the capture (or bag) time of its input: before each call the runner's
//!   clock is set to the input's stamp, never moving backwards. Live runs, replays and ROS nodes
//!   under `use_sim_time` therefore give a stage the same clock readings for the same inputs,
//!   which is what makes outputs byte-identical across transports.
//! - **Errors**: a rejected input is counted (and its message kept for the first few) and still
//!   passed on; the stage's state is as it was before the bad input.
//!
//! [`Chain`] is the synchronous form (stages in order in one thread: bag replay, ROS nodes); the
//! runtime runs one [`StageRunner`] per thread with bounded edges between them.

use crate::clock::{Clock, ManualClock, Stamp};
use crate::msg::Msg;
use crate::stage::{Stage, StageError};
use std::time::Instant;

/// Rejections whose message is kept per runner (the count goes on).
const KEPT_ERRORS: usize = 10;

/// What a runner counted.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct RunnerStats {
    /// Messages in (frames and events).
    pub input: u64,
    /// Messages the stage produced (including those from `finish`).
    pub output: u64,
    /// Inputs the stage rejected (and a failed `finish`).
    pub errors: u64,
    /// Wall time inside `process`/`finish` \[ns]: total and the longest call.
    pub busy_ns: u64,
    pub max_ns: u64,
}

/// One stage with its clock (the input-stamp rule) and counters.
pub struct StageRunner {
    stage: Box<dyn Stage>,
    name: String,
    clock: ManualClock,
    last: Stamp,
    stats: RunnerStats,
    /// The first rejections: (input kind, input stamp, error).
    recent_errors: Vec<String>,
}

impl std::fmt::Debug for StageRunner {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StageRunner")
            .field("name", &self.name)
            .field("stats", &self.stats)
            .finish_non_exhaustive()
    }
}

/// A rejected input, as the runner reports it.
#[derive(Debug, Clone, PartialEq)]
pub struct Rejection {
    pub stage: String,
    pub input_kind: &'static str,
    pub stamp: Stamp,
    pub error: String,
}

impl std::fmt::Display for Rejection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "{}: {} at {} ns rejected: {}",
            self.stage, self.input_kind, self.stamp.0, self.error
        )
    }
}

impl StageRunner {
    pub fn new(stage: Box<dyn Stage>) -> Self {
        let name = stage.name().to_string();
        Self {
            stage,
            name,
            clock: ManualClock::default(),
            last: Stamp::ZERO,
            stats: RunnerStats::default(),
            recent_errors: Vec::new(),
        }
    }

    pub fn name(&self) -> &str {
        &self.name
    }
    pub fn stats(&self) -> &RunnerStats {
        &self.stats
    }
    /// The clock reading the stage saw last (the latest input stamp).
    pub fn now(&self) -> Stamp {
        self.last
    }
    /// The first rejections, one line each.
    pub fn recent_errors(&self) -> &[String] {
        &self.recent_errors
    }

    fn timed<T>(&mut self, f: impl FnOnce(&mut dyn Stage, &dyn Clock) -> T) -> T {
        let t0 = Instant::now();
        let r = f(self.stage.as_mut(), &self.clock);
        let ns = u64::try_from(t0.elapsed().as_nanos()).unwrap_or(u64::MAX);
        self.stats.busy_ns = self.stats.busy_ns.saturating_add(ns);
        self.stats.max_ns = self.stats.max_ns.max(ns);
        r
    }

    fn reject(&mut self, input_kind: &'static str, stamp: Stamp, error: String) -> Rejection {
        self.stats.errors += 1;
        let r = Rejection {
            stage: self.name.clone(),
            input_kind,
            stamp,
            error,
        };
        if self.recent_errors.len() < KEPT_ERRORS {
            self.recent_errors.push(r.to_string());
        }
        r
    }

    /// Feed one message: `emit` gets the stage's outputs, then `input` itself. Returns the
    /// rejection if the stage refused the input (the input is passed on all the same).
    pub fn feed(&mut self, input: Msg, emit: &mut dyn FnMut(Msg)) -> Option<Rejection> {
        self.stats.input += 1;
        self.last = self.last.max(input.stamp());
        self.clock.set(self.last);
        let result = {
            let _span =
                tracing::trace_span!("process", stage = %self.name, kind = input.kind()).entered();
            self.timed(|s, c| s.process(&input, c))
        };
        let rejected = match result {
            Ok(outs) => {
                self.stats.output += outs.len() as u64;
                outs.into_iter().for_each(&mut *emit);
                None
            }
            Err(e) => Some(self.reject(input.kind(), input.stamp(), e.to_string())),
        };
        emit(input);
        rejected
    }

    /// The stage's timer hook at the transport's time `now` (the clock moves to it, never
    /// back): `emit` gets what the stage sends.
    pub fn timer(&mut self, now: Stamp, emit: &mut dyn FnMut(Msg)) -> Option<Rejection> {
        self.last = self.last.max(now);
        self.clock.set(self.last);
        match self.timed(|s, _| s.timer(now)) {
            Ok(outs) => {
                self.stats.output += outs.len() as u64;
                outs.into_iter().for_each(emit);
                None
            }
            Err(e) => Some(self.reject("timer", now, e.to_string())),
        }
    }

    /// The stage's timer period \[ns] (None: it has no timer).
    pub fn timer_period_ns(&self) -> Option<i64> {
        self.stage.timer_period_ns()
    }

    /// The inputs whose producer the stage needs alive now.
    pub fn awaited_inputs(&self) -> Vec<&'static str> {
        self.stage.awaited_inputs()
    }

    /// Tell the stage the producer of input `name` is gone (`Some(why)`) or back (`None`).
    pub fn set_input_lost(&mut self, name: &str, why: Option<String>) -> Result<(), StageError> {
        self.stage.set_input_lost(name, why)
    }

    /// The input ended: `emit` gets what the stage still holds (e.g. an open episode), on the
    /// clock of the last input.
    pub fn finish(&mut self, emit: &mut dyn FnMut(Msg)) -> Option<Rejection> {
        match self.timed(|s, c| s.finish(c)) {
            Ok(outs) => {
                self.stats.output += outs.len() as u64;
                outs.into_iter().for_each(emit);
                None
            }
            Err(e) => Some(self.reject("finish", self.last, e.to_string())),
        }
    }
}

/// What one input (or the finish) produced in a [`Chain`].
#[derive(Debug, Default)]
pub struct ChainOutput {
    /// Every message the stages made, in order (the input itself is not repeated).
    pub produced: Vec<Msg>,
    /// Inputs a stage rejected; the later stages still ran.
    pub errors: Vec<Rejection>,
}

/// Stages in order in one thread.
#[derive(Debug, Default)]
pub struct Chain {
    runners: Vec<StageRunner>,
}

impl Chain {
    pub fn new(stages: Vec<Box<dyn Stage>>) -> Self {
        Self {
            runners: stages.into_iter().map(StageRunner::new).collect(),
        }
    }
    pub fn is_empty(&self) -> bool {
        self.runners.is_empty()
    }
    pub fn runners(&self) -> &[StageRunner] {
        &self.runners
    }

    /// Push `input` through every stage.
    pub fn run(&mut self, input: Msg) -> ChainOutput {
        let mut out = ChainOutput::default();
        let mut queue = vec![input];
        Self::pass(&mut self.runners, &mut queue, &mut out.errors);
        // The original input is the last element: everything before it was produced.
        queue.pop();
        out.produced = queue;
        out
    }

    /// [`Chain::run`], every message between the first `at` stages and the rest passed through
    /// `map` (`at` beyond the stages: after the last one).
    pub fn run_mapped(
        &mut self,
        input: Msg,
        at: usize,
        map: &mut dyn FnMut(Msg) -> Msg,
    ) -> ChainOutput {
        let mut out = ChainOutput::default();
        let mut queue = vec![input];
        let at = at.min(self.runners.len());
        let (first, rest) = self.runners.split_at_mut(at);
        Self::pass(first, &mut queue, &mut out.errors);
        let mut queue: Vec<Msg> = queue.into_iter().map(&mut *map).collect();
        Self::pass(rest, &mut queue, &mut out.errors);
        queue.pop();
        out.produced = queue;
        out
    }

    /// `queue` through `runners`, in place.
    fn pass(runners: &mut [StageRunner], queue: &mut Vec<Msg>, errors: &mut Vec<Rejection>) {
        for r in runners.iter_mut() {
            let mut next = Vec::with_capacity(queue.len() + 2);
            for m in queue.drain(..) {
                errors.extend(r.feed(m, &mut |o| next.push(o)));
            }
            *queue = next;
        }
    }

    /// Every stage's `finish` in order; what a stage flushes passes through the later stages.
    pub fn finish(&mut self) -> ChainOutput {
        self.each(|r, emit| r.finish(emit))
    }

    /// The timer hook of every stage that has a timer, in order, at the transport's time `now`;
    /// what a stage sends passes through the later stages. A transport calls it every
    /// [`Chain::timer_period_ns`].
    pub fn timer(&mut self, now: Stamp) -> ChainOutput {
        self.each(|r, emit| {
            r.timer_period_ns()
                .is_some()
                .then(|| r.timer(now, emit))
                .flatten()
        })
    }

    /// The shortest timer period any stage asks for \[ns] (None: no stage has a timer).
    pub fn timer_period_ns(&self) -> Option<i64> {
        self.runners
            .iter()
            .filter_map(StageRunner::timer_period_ns)
            .min()
    }

    /// The inputs whose producer some stage needs alive now.
    pub fn awaited_inputs(&self) -> Vec<&'static str> {
        let mut all: Vec<&'static str> = Vec::new();
        for r in &self.runners {
            for i in r.awaited_inputs() {
                if !all.contains(&i) {
                    all.push(i);
                }
            }
        }
        all
    }

    /// Tell every stage the producer of input `name` is gone (`Some(why)`) or back (`None`);
    /// the first stage that refuses the word answers.
    pub fn set_input_lost(&mut self, name: &str, why: Option<String>) -> Result<(), StageError> {
        for r in &mut self.runners {
            r.set_input_lost(name, why.clone())?;
        }
        Ok(())
    }

    /// `hook` on every runner in order, each one's outputs through the later runners.
    fn each(
        &mut self,
        mut hook: impl FnMut(&mut StageRunner, &mut dyn FnMut(Msg)) -> Option<Rejection>,
    ) -> ChainOutput {
        let mut out = ChainOutput::default();
        for i in 0..self.runners.len() {
            let (this, later) = self.runners.split_at_mut(i + 1);
            let Some(r) = this.last_mut() else { continue };
            let mut sent = Vec::new();
            out.errors.extend(hook(r, &mut |m| sent.push(m)));
            Self::pass(later, &mut sent, &mut out.errors);
            out.produced.extend(sent);
        }
        out
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;
    use crate::msg::{Header, PolicyStatus};
    use crate::stage::StageError;

    fn status(text: &str, t: i64) -> Msg {
        Msg::PolicyStatus(PolicyStatus {
            header: Header::new(Stamp(t), ""),
            scene: String::new(),
            mode: String::new(),
            phase: String::new(),
            safety_ok: true,
            message: text.into(),
            clamped: Vec::new(),
        })
    }
    fn text(m: &Msg) -> &str {
        match m {
            Msg::PolicyStatus(s) => &s.message,
            _ => panic!("{m:?}"),
        }
    }

    /// Tags every message it sees with the clock reading; rejects "bad*"; flushes "<tag>:end".
    struct Tag(&'static str);
    impl Stage for Tag {
        fn name(&self) -> &str {
            self.0
        }
        fn process(&mut self, m: &Msg, c: &dyn Clock) -> Result<Vec<Msg>, StageError> {
            if text(m).starts_with("bad") {
                return Err(StageError::bad_input(text(m).to_string()));
            }
            Ok(vec![status(
                &format!("{}({})@{}", self.0, text(m), c.now().0),
                m.stamp().0,
            )])
        }
        fn finish(&mut self, c: &dyn Clock) -> Result<Vec<Msg>, StageError> {
            Ok(vec![status(&format!("{}:end@{}", self.0, c.now().0), 0)])
        }
    }

    #[test]
    fn each_stage_sees_the_input_and_what_earlier_stages_made() {
        let mut ch = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
        let out = ch.run(status("x", 5));
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        assert_eq!(got, ["b(a(x)@5)@5", "a(x)@5", "b(x)@5"]);
        assert!(out.errors.is_empty());
        assert_eq!(ch.runners()[1].stats().input, 2);
        assert_eq!(ch.runners()[1].stats().output, 2);
    }

    #[test]
    fn a_map_between_stages_changes_what_the_later_ones_see_and_only_that() {
        let mut ch = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
        let mut upper = |m: Msg| match m {
            Msg::PolicyStatus(mut s) => {
                s.message = s.message.to_uppercase();
                Msg::PolicyStatus(s)
            }
            m => m,
        };
        let out = ch.run_mapped(status("x", 5), 1, &mut upper);
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        assert_eq!(got, ["b(A(X)@5)@5", "A(X)@5", "b(X)@5"]);
        // The identity at any split is the plain run.
        for at in 0..4 {
            let mut a = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
            let mut b = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
            assert_eq!(
                a.run_mapped(status("y", 7), at, &mut |m| m).produced,
                b.run(status("y", 7)).produced
            );
        }
    }

    #[test]
    fn the_clock_is_the_input_stamp_and_never_goes_back() {
        let mut ch = Chain::new(vec![Box::new(Tag("a"))]);
        assert_eq!(text(&ch.run(status("x", 10)).produced[0]), "a(x)@10");
        // An older input does not move the clock back.
        assert_eq!(text(&ch.run(status("y", 3)).produced[0]), "a(y)@10");
        let end = ch.finish();
        assert_eq!(text(&end.produced[0]), "a:end@10");
    }

    #[test]
    fn a_rejected_input_is_reported_and_still_passed_on() {
        let mut ch = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
        let out = ch.run(status("bad", 1));
        assert!(out.produced.is_empty());
        assert_eq!(out.errors.len(), 2, "{:?}", out.errors);
        assert_eq!(out.errors[0].stage, "a");
        assert_eq!(ch.runners()[0].stats().errors, 1);
        assert_eq!(ch.runners()[0].recent_errors().len(), 1);
    }

    /// A stage that only acts on its timer, asking for one every 100 ns.
    struct Every;
    impl Stage for Every {
        fn name(&self) -> &str {
            "every"
        }
        fn process(&mut self, _m: &Msg, _c: &dyn Clock) -> Result<Vec<Msg>, StageError> {
            Ok(Vec::new())
        }
        fn timer_period_ns(&self) -> Option<i64> {
            Some(100)
        }
        fn timer(&mut self, now: Stamp) -> Result<Vec<Msg>, StageError> {
            Ok(vec![status(&format!("t@{}", now.0), now.0)])
        }
    }

    #[test]
    fn the_timer_hook_sends_through_later_stages_on_the_transports_time() {
        let mut ch = Chain::new(vec![
            Box::new(Tag("a")),
            Box::new(Every),
            Box::new(Tag("b")),
        ]);
        assert_eq!(ch.timer_period_ns(), Some(100));
        assert_eq!(Chain::new(vec![Box::new(Tag("a"))]).timer_period_ns(), None);
        ch.run(status("x", 10));
        let out = ch.timer(Stamp(250));
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        // Tags have no timer: only Every's message, and b's answer to it on b's clock.
        assert_eq!(got, ["b(t@250)@250", "t@250"]);
        // The timer moved Every's clock; a later input stamped earlier does not move it back.
        assert_eq!(ch.runners()[1].now(), Stamp(250));
        assert_eq!(ch.runners()[0].now(), Stamp(10));
    }

    #[test]
    fn finish_flushes_through_later_stages() {
        let mut ch = Chain::new(vec![Box::new(Tag("a")), Box::new(Tag("b"))]);
        let out = ch.finish();
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        // Runtime order: what b made of a's flush, then the flush itself, then b's own.
        assert_eq!(got, ["b(a:end@0)@0", "a:end@0", "b:end@0"]);
    }
}
