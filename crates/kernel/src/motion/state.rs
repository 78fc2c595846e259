//! The machine's motion state: one state at a time, changed only by
//! [`MotionCore::fire`](super::MotionCore::fire), which asks [`transition`], the one list
//! of every transition. The parts of the core decide what happened (an [`Event`]); the
//! table decides where that leads. A state's own data (the homing group's steps, the last
//! level of an input M66 waits on) changes in place.
//!
//! Feed holds are not states: a hold is latched over whatever the machine does (see
//! `hold.rs`), and the states wait on it where the next move would start.

use rtcnc_gcode::canon::ProbeKind;
use rtcnc_motion::{AXES, Move};

use super::homing::Homing;
use crate::fault::FaultCode;
use crate::messages::{Aux, WaitCondition};

/// What the machine is doing.
#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
pub(super) enum State {
    /// Power-up: the self-test has not passed yet.
    Starting,
    /// Drives off (at power-up, or once the quick stop after an e-stop or fault stands);
    /// a reset enables them.
    Off,
    /// An e-stop or fault: the quick stop of whatever moved; the drives go off when it
    /// stands.
    Stopping,
    /// Drives on, no program and no homing: jog, handwheel and independent joints may move.
    Idle,
    /// Homing, the group of joints in progress.
    Homing(Homing),
    /// A program or an MDI line runs: the sequencer's step.
    Program(Step),
}

/// Where the program is.
#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
pub(super) enum Step {
    /// Moving blocks into the planner.
    Feeding,
    /// Waiting for the path to stand, then doing `then` for `line`.
    Draining { then: Then, line: u32 },
    /// Waiting for the machine logic's answer to `aux`; `released`: the request has been
    /// answered and dropped, the answer must drop too.
    Logic { aux: Aux, line: u32, released: bool },
    /// Paused at M0/M1/single block until the start count moves on.
    Paused { start_count: u32 },
    /// G33: the spindle-synchronised move runs.
    Synced,
    /// G38.x: the probing move runs (it stops where the probe changes).
    Probing { kind: ProbeKind, line: u32 },
    /// M19 Q: waiting for the spindle to report oriented until `deadline`.
    WaitOrient { deadline: u64, line: u32 },
    /// M66: waiting for a digital input until `deadline` (an interpolation cycle).
    WaitInput {
        bit: u64,
        condition: WaitCondition,
        deadline: u64,
        previous: bool,
    },
}

/// What the sequencer does once the path stands.
#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
pub(super) enum Then {
    /// A spindle-synchronised line to the end point, pitch mm per revolution; a rigid tap
    /// (with its speed factor out) comes back.
    Synced([f64; AXES], f64, Option<f64>),
    Probe(Move, ProbeKind),
    Aux(Aux),
    /// Stop the program with this fault and value (the fault's `value`: what failed, for
    /// the codes that say so, e.g. [`ProbeFailure`](crate::fault::ProbeFailure)).
    Error(FaultCode, f64),
    End,
    MdiDone,
    SingleBlockPause,
}

/// What moves the state.
#[derive(Debug, Clone, Copy, PartialEq)]
// Plain data held in place: boxing the larger variant would allocate on the real-time path.
#[allow(clippy::large_enum_variant)]
pub(super) enum Event {
    /// The power-up self-test passed.
    SelfTestPassed,
    /// The operator's reset.
    Reset,
    /// An e-stop, or a fault that stops the machine.
    Fault,
    /// The quick stop stands.
    Stood,
    /// A program or an MDI line starts.
    Begin,
    /// Homing starts with this group (none: every joint is homed where it stands).
    Home(Option<Homing>),
    /// The homing group is done: the next one, if any.
    GroupHomed(Option<Homing>),
    /// A feed hold (homing cannot go on from where it stops: it is given up).
    Hold,
    /// The operator's abort.
    Abort,
    /// A block that needs the path standing: flush the planner, then `then`.
    Drain { then: Then, line: u32 },
    /// The program cannot go on: stop it with `code` at `line` once the path stands.
    Fail {
        code: FaultCode,
        line: u32,
        value: f64,
    },
    /// A machine function waits for the logic's answer.
    HandShake { aux: Aux, line: u32 },
    /// The logic answered a tool change or user M code; its request is dropped.
    Answered,
    /// M0, M1 or a single block's end.
    Pause { start_count: u32 },
    /// M19 Q.
    WaitOrient { deadline: u64, line: u32 },
    /// M66 on a digital input.
    WaitInput {
        bit: u64,
        condition: WaitCondition,
        deadline: u64,
        previous: bool,
    },
    /// A probing move starts.
    Probe { kind: ProbeKind, line: u32 },
    /// A spindle-synchronised move starts.
    Synced,
    /// The program goes on with its next block.
    Proceed,
    /// The program or MDI line ended (its end, or an error that stopped it).
    Finish,
}

/// Every transition: the state `event` leads to from `from`, or `None` when `from` does not
/// take it (a command refused, or nothing to do).
pub(super) fn transition(from: &State, event: Event) -> Option<State> {
    use Event as E;
    use State as S;
    use Step as P;
    let program = |step| Some(S::Program(step));
    match (*from, event) {
        (S::Starting, E::SelfTestPassed) => Some(S::Off),
        (S::Off, E::Reset) => Some(S::Idle),
        (S::Idle | S::Homing(_) | S::Program(_), E::Reset) => Some(*from),
        (S::Stopping | S::Idle | S::Homing(_) | S::Program(_), E::Fault) => Some(S::Stopping),
        (S::Stopping, E::Stood) => Some(S::Off),
        (S::Idle, E::Begin) => program(P::Feeding),
        (S::Idle, E::Home(Some(group))) => Some(S::Homing(group)),
        (S::Idle, E::Home(None)) => Some(S::Idle),
        (S::Homing(_), E::GroupHomed(Some(group))) => Some(S::Homing(group)),
        (S::Homing(_), E::GroupHomed(None)) => Some(S::Idle),
        (S::Homing(_), E::Hold) => Some(S::Idle),
        (S::Idle | S::Program(_), E::Hold) => Some(*from),
        (S::Homing(_) | S::Program(_), E::Abort) => Some(S::Idle),
        (S::Starting | S::Off | S::Stopping | S::Idle, E::Abort) => Some(*from),
        (S::Program(P::Feeding), E::Drain { then, line }) => program(P::Draining { then, line }),
        (
            S::Program(P::Feeding | P::Draining { .. } | P::Probing { .. } | P::WaitOrient { .. }),
            E::Fail { code, line, value },
        ) => program(P::Draining {
            then: Then::Error(code, value),
            line,
        }),
        (S::Program(P::Draining { .. }), E::HandShake { aux, line }) => program(P::Logic {
            aux,
            line,
            released: false,
        }),
        (
            S::Program(P::Logic {
                aux,
                line,
                released: false,
            }),
            E::Answered,
        ) => program(P::Logic {
            aux,
            line,
            released: true,
        }),
        (S::Program(P::Draining { .. }), E::Pause { start_count }) => {
            program(P::Paused { start_count })
        }
        (S::Program(P::Draining { .. }), E::WaitOrient { deadline, line }) => {
            program(P::WaitOrient { deadline, line })
        }
        (
            S::Program(P::Draining { .. }),
            E::WaitInput {
                bit,
                condition,
                deadline,
                previous,
            },
        ) => program(P::WaitInput {
            bit,
            condition,
            deadline,
            previous,
        }),
        (S::Program(P::Draining { .. }), E::Probe { kind, line }) => {
            program(P::Probing { kind, line })
        }
        (S::Program(P::Draining { .. }), E::Synced) => program(P::Synced),
        (
            S::Program(
                P::Draining { .. }
                | P::Logic { .. }
                | P::Paused { .. }
                | P::Synced
                | P::Probing { .. }
                | P::WaitOrient { .. }
                | P::WaitInput { .. },
            ),
            E::Proceed,
        ) => program(P::Feeding),
        (S::Program(P::Draining { .. }), E::Finish) => Some(S::Idle),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    //! The transition table against the machine's behaviour as docs/kernel.md describes
    //! it: every transition listed in `TABLE` leads where its row says, with the event's
    //! data; every pair of state and event not listed is not taken.

    use super::*;

    /// from, event, to. `program` stands for every step of a program; `=`: the state
    /// stays as it is (the event is taken, nothing changes).
    const TABLE: &str = "
        starting        self-test-passed  off
        starting        abort             =
        off             reset             idle
        off             abort             =
        stopping        fault             stopping
        stopping        stood             off
        stopping        abort             =
        idle            reset             =
        idle            fault             stopping
        idle            begin             feeding
        idle            home              homing
        idle            home-none         idle
        idle            hold              =
        idle            abort             =
        homing          reset             =
        homing          fault             stopping
        homing          group-homed       homing
        homing          group-homed-none  idle
        homing          hold              idle
        homing          abort             idle
        program         reset             =
        program         fault             stopping
        program         hold              =
        program         abort             idle
        feeding         drain             draining
        feeding         fail              draining
        draining        fail              draining
        probing         fail              draining
        wait-orient     fail              draining
        draining        hand-shake        logic
        draining        pause             paused
        draining        wait-orient       wait-orient
        draining        wait-input        wait-input
        draining        probe             probing
        draining        synced            synced
        draining        finish            idle
        logic           answered          logic-answered
        draining        proceed           feeding
        logic           proceed           feeding
        logic-answered  proceed           feeding
        paused          proceed           feeding
        synced          proceed           feeding
        probing         proceed           feeding
        wait-orient     proceed           feeding
        wait-input      proceed           feeding
    ";

    const AUX: Aux = Aux::ToolChange { tool: 2 };

    fn group(sequence: u8) -> Homing {
        Homing::of_sequence(sequence)
    }

    fn states() -> Vec<(&'static str, State)> {
        let program = |step| State::Program(step);
        vec![
            ("starting", State::Starting),
            ("off", State::Off),
            ("stopping", State::Stopping),
            ("idle", State::Idle),
            ("homing", State::Homing(group(0))),
            ("feeding", program(Step::Feeding)),
            (
                "draining",
                program(Step::Draining {
                    then: Then::End,
                    line: 7,
                }),
            ),
            (
                "logic",
                program(Step::Logic {
                    aux: AUX,
                    line: 7,
                    released: false,
                }),
            ),
            (
                "logic-answered",
                program(Step::Logic {
                    aux: AUX,
                    line: 7,
                    released: true,
                }),
            ),
            ("paused", program(Step::Paused { start_count: 1 })),
            ("synced", program(Step::Synced)),
            (
                "probing",
                program(Step::Probing {
                    kind: ProbeKind::Toward,
                    line: 7,
                }),
            ),
            (
                "wait-orient",
                program(Step::WaitOrient {
                    deadline: 100,
                    line: 7,
                }),
            ),
            (
                "wait-input",
                program(Step::WaitInput {
                    bit: 1,
                    condition: WaitCondition::High,
                    deadline: 100,
                    previous: false,
                }),
            ),
        ]
    }

    fn events() -> Vec<(&'static str, Event)> {
        vec![
            ("self-test-passed", Event::SelfTestPassed),
            ("reset", Event::Reset),
            ("fault", Event::Fault),
            ("stood", Event::Stood),
            ("begin", Event::Begin),
            ("home", Event::Home(Some(group(1)))),
            ("home-none", Event::Home(None)),
            ("group-homed", Event::GroupHomed(Some(group(2)))),
            ("group-homed-none", Event::GroupHomed(None)),
            ("hold", Event::Hold),
            ("abort", Event::Abort),
            (
                "drain",
                Event::Drain {
                    then: Then::Aux(AUX),
                    line: 9,
                },
            ),
            (
                "fail",
                Event::Fail {
                    code: FaultCode::ProbeFailed,
                    line: 9,
                    value: 0.0,
                },
            ),
            ("hand-shake", Event::HandShake { aux: AUX, line: 9 }),
            ("answered", Event::Answered),
            ("pause", Event::Pause { start_count: 3 }),
            (
                "wait-orient",
                Event::WaitOrient {
                    deadline: 50,
                    line: 9,
                },
            ),
            (
                "wait-input",
                Event::WaitInput {
                    bit: 4,
                    condition: WaitCondition::Rise,
                    deadline: 50,
                    previous: true,
                },
            ),
            (
                "probe",
                Event::Probe {
                    kind: ProbeKind::AwayError,
                    line: 9,
                },
            ),
            ("synced", Event::Synced),
            ("proceed", Event::Proceed),
            ("finish", Event::Finish),
        ]
    }

    fn name(state: &State) -> &'static str {
        match state {
            State::Starting => "starting",
            State::Off => "off",
            State::Stopping => "stopping",
            State::Idle => "idle",
            State::Homing(_) => "homing",
            State::Program(step) => match step {
                Step::Feeding => "feeding",
                Step::Draining { .. } => "draining",
                Step::Logic {
                    released: false, ..
                } => "logic",
                Step::Logic { released: true, .. } => "logic-answered",
                Step::Paused { .. } => "paused",
                Step::Synced => "synced",
                Step::Probing { .. } => "probing",
                Step::WaitOrient { .. } => "wait-orient",
                Step::WaitInput { .. } => "wait-input",
            },
        }
    }

    /// The table's rows with `program` expanded: (from, event) → to.
    fn rows() -> Vec<(&'static str, &'static str, &'static str)> {
        let program_steps: Vec<&str> = states()
            .into_iter()
            .filter(|(_, s)| matches!(s, State::Program(_)))
            .map(|(n, _)| n)
            .collect();
        let mut rows = Vec::new();
        for line in TABLE.lines().filter(|l| !l.trim().is_empty()) {
            let cells: Vec<&str> = line.split_whitespace().collect();
            assert_eq!(cells.len(), 3, "{line}");
            let froms = if cells[0] == "program" {
                program_steps.clone()
            } else {
                vec![cells[0]]
            };
            for from in froms {
                let to = if cells[2] == "=" { from } else { cells[2] };
                rows.push((from, cells[1], to));
            }
        }
        rows
    }

    #[test]
    fn every_pair_of_state_and_event_leads_where_the_table_says() {
        let rows = rows();
        let states = states();
        let events = events();
        for (n, s) in &states {
            assert_eq!(name(s), *n);
        }
        for (from, _, to) in &rows {
            assert!(
                states.iter().any(|(n, _)| n == from),
                "unknown state {from}"
            );
            assert!(states.iter().any(|(n, _)| n == to), "unknown state {to}");
        }
        for (_, event, _) in &rows {
            assert!(
                events.iter().any(|(n, _)| n == event),
                "unknown event {event}"
            );
        }
        let mut taken = 0;
        for (from_name, from) in &states {
            for (event_name, event) in &events {
                let listed: Vec<_> = rows
                    .iter()
                    .filter(|(f, e, _)| f == from_name && e == event_name)
                    .map(|(_, _, to)| *to)
                    .collect();
                assert!(listed.len() <= 1, "{from_name} {event_name}: listed twice");
                let got = transition(from, *event);
                assert_eq!(
                    got.as_ref().map(name),
                    listed.first().copied(),
                    "{from_name} --{event_name}-->"
                );
                taken += usize::from(got.is_some());
            }
        }
        assert_eq!(taken, rows.len());
    }

    #[test]
    fn a_transition_carries_the_events_data_into_the_state() {
        let feeding = State::Program(Step::Feeding);
        let draining = State::Program(Step::Draining {
            then: Then::End,
            line: 3,
        });
        let then = Then::Aux(AUX);
        assert_eq!(
            transition(&feeding, Event::Drain { then, line: 9 }),
            Some(State::Program(Step::Draining { then, line: 9 }))
        );
        assert_eq!(
            transition(
                &draining,
                Event::Fail {
                    code: FaultCode::AuxRefused,
                    line: 3,
                    value: 0.0,
                }
            ),
            Some(State::Program(Step::Draining {
                then: Then::Error(FaultCode::AuxRefused, 0.0),
                line: 3
            }))
        );
        let logic = transition(&draining, Event::HandShake { aux: AUX, line: 3 });
        assert_eq!(
            logic,
            Some(State::Program(Step::Logic {
                aux: AUX,
                line: 3,
                released: false
            }))
        );
        assert_eq!(
            transition(&logic.unwrap(), Event::Answered),
            Some(State::Program(Step::Logic {
                aux: AUX,
                line: 3,
                released: true
            }))
        );
        assert_eq!(
            transition(&State::Idle, Event::Home(Some(group(4)))),
            Some(State::Homing(group(4)))
        );
        assert_eq!(
            transition(&State::Homing(group(4)), Event::GroupHomed(Some(group(5)))),
            Some(State::Homing(group(5)))
        );
        assert_eq!(
            transition(&draining, Event::Pause { start_count: 8 }),
            Some(State::Program(Step::Paused { start_count: 8 }))
        );
    }
}
