//! Stages run in order inside one node, wired the way the embedded runtime wires them: each
//! stage sees every message that reaches it (the node's input and what earlier stages made), its
//! own outputs first, then what it was given.

use unitac_core::{Clock, Msg, Stage};

/// What one input produced.
#[derive(Debug, Default)]
pub struct ChainOutput {
    /// Every message the stages made, in order (the input itself is not repeated).
    pub produced: Vec<Msg>,
    /// (stage name, error) for each input a stage rejected; the others still ran.
    pub errors: Vec<(String, String)>,
    /// (stage name, seconds inside `process`) for each stage that was called.
    pub timings: Vec<(String, f64)>,
}

/// Run `input` through `stages`.
pub fn run(stages: &mut [Box<dyn Stage>], input: Msg, clock: &dyn Clock) -> ChainOutput {
    let mut out = ChainOutput::default();
    let mut queue = vec![input];
    for stage in stages.iter_mut() {
        let mut next = Vec::with_capacity(queue.len() + 2);
        let mut busy = 0.0;
        for m in queue {
            let t0 = std::time::Instant::now();
            let r = stage.process(&m, clock);
            busy += t0.elapsed().as_secs_f64();
            match r {
                Ok(v) => next.extend(v),
                Err(e) => out.errors.push((stage.name().to_string(), e.to_string())),
            }
            next.push(m);
        }
        out.timings.push((stage.name().to_string(), busy));
        queue = next;
    }
    // The original input is the last element: everything before it was produced.
    queue.pop();
    out.produced = queue;
    out
}

/// Every stage's `finish` (flushing what it holds), passing its outputs through the later stages.
pub fn finish(stages: &mut [Box<dyn Stage>], clock: &dyn Clock) -> ChainOutput {
    let mut out = ChainOutput::default();
    for i in 0..stages.len() {
        let flushed = match stages[i].finish(clock) {
            Ok(v) => v,
            Err(e) => {
                out.errors
                    .push((stages[i].name().to_string(), e.to_string()));
                continue;
            }
        };
        for m in flushed {
            let later = run(&mut stages[i + 1..], m.clone(), clock);
            out.produced.push(m);
            out.produced.extend(later.produced);
            out.errors.extend(later.errors);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::panic)]
    use super::*;
    use unitac_core::msg::{Header, PolicyStatus};
    use unitac_core::{ManualClock, StageError};

    fn status(text: &str) -> Msg {
        Msg::Status(PolicyStatus {
            header: Header {
                stamp: unitac_core::Stamp::ZERO,
                frame_id: String::new(),
            },
            scene: String::new(),
            mode: String::new(),
            phase: String::new(),
            safety_ok: true,
            message: text.into(),
        })
    }
    fn text(m: &Msg) -> &str {
        match m {
            Msg::Status(s) => &s.message,
            _ => panic!("{m:?}"),
        }
    }

    /// Tags every message it sees; rejects messages that start with "bad"; flushes "<tag>:end".
    struct Tag(&'static str);
    impl Stage for Tag {
        fn name(&self) -> &str {
            self.0
        }
        fn process(&mut self, m: &Msg, _: &dyn Clock) -> Result<Vec<Msg>, StageError> {
            if text(m).starts_with("bad") {
                return Err(StageError::BadInput(text(m).into()));
            }
            Ok(vec![status(&format!("{}({})", self.0, text(m)))])
        }
        fn finish(&mut self, _: &dyn Clock) -> Result<Vec<Msg>, StageError> {
            Ok(vec![status(&format!("{}:end", self.0))])
        }
    }

    #[test]
    fn each_stage_sees_the_input_and_what_earlier_stages_made() {
        let mut st: Vec<Box<dyn Stage>> = vec![Box::new(Tag("a")), Box::new(Tag("b"))];
        let out = run(&mut st, status("x"), &ManualClock::default());
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        assert_eq!(got, ["b(a(x))", "a(x)", "b(x)"]);
        assert!(out.errors.is_empty());
        assert_eq!(out.timings.len(), 2);
    }

    #[test]
    fn a_rejected_input_is_reported_and_still_passed_on() {
        let mut st: Vec<Box<dyn Stage>> = vec![Box::new(Tag("a")), Box::new(Tag("b"))];
        let out = run(&mut st, status("bad"), &ManualClock::default());
        assert!(out.produced.is_empty());
        assert_eq!(out.errors.len(), 2, "{:?}", out.errors);
        assert_eq!(out.errors[0].0, "a");
    }

    #[test]
    fn finish_flushes_through_later_stages() {
        let mut st: Vec<Box<dyn Stage>> = vec![Box::new(Tag("a")), Box::new(Tag("b"))];
        let out = finish(&mut st, &ManualClock::default());
        let got: Vec<&str> = out.produced.iter().map(text).collect();
        assert_eq!(got, ["a:end", "b(a:end)", "b:end"]);
    }
}
