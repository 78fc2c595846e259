//! Probing (G38.2-G38.5): once the path stands, an exact-stop line at the programmed
//! feed, with every axis joint's touch-probe latch armed (CiA 402 0x60B8) for the edge the
//! move looks for. In the first period in which the probe input changes so, the move is
//! stopped along the path; the position is the drives' latch (the load's position at the
//! edge's instant, reported some periods later), or, from a bus whose drives report no
//! latch within `LATCH_WAIT_S`, the feedback of that period (as LinuxCNC takes it, up to a
//! period's travel late). The interpreter gets where the probe changed and where the
//! machine stopped.

use rtcnc_gcode::canon::ProbeKind;
use rtcnc_motion::{AXES, MotionError, Move};

use super::MotionCore;
use super::state::Event;
use crate::fault::{FaultCode, ProbeFailure};
use crate::messages::MachineResult;
use crate::shared::{Feedback, Shared};

/// How long after the probe input changed the drives' latch may come (their latency); a
/// drive that reports none by then (its probe input not wired) is given up on.
const LATCH_WAIT_S: f64 = 0.1;

/// The probing move in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Probe {
    kind: ProbeKind,
    /// The axis position where the probe changed, once it has, from the feedback of the
    /// period in which it was seen, and the set-point number then.
    tripped_at: Option<([f64; AXES], u64)>,
    /// The joints whose touch-probe latch is armed.
    latches: u32,
}

/// Whether the move looks for the probe to close (G38.2/3), else to open (G38.4/5).
fn toward(kind: ProbeKind) -> bool {
    matches!(kind, ProbeKind::TowardError | ProbeKind::Toward)
}

impl MotionCore {
    /// Starts a probing move: refused without a probe input, or when the probe already is
    /// where the move looks for (LinuxCNC's "probe is already tripped" / "not tripped").
    pub(super) fn start_probe(&mut self, shared: &Shared, mv: Move, kind: ProbeKind) {
        let contact = self.interface.feedback.get().digital_inputs & self.io.probe_bit != 0;
        let refused = if self.io.probe_bit == 0 {
            Some(ProbeFailure::NoProbeInput)
        } else if contact == toward(kind) {
            Some(if toward(kind) {
                ProbeFailure::AlreadyTripped
            } else {
                ProbeFailure::AlreadyClear
            })
        } else {
            None
        };
        if let Some(failure) = refused {
            self.fire(Event::Fail {
                code: FaultCode::ProbeFailed,
                line: mv.line,
                value: failure.value(),
            });
            return;
        }
        let probing = Event::Probe {
            kind,
            line: mv.line,
        };
        let mut latches = 0u32;
        for j in 0..self.machine.joint_count {
            if self.machine.joints[j].axis.is_some() {
                latches |= 1 << j;
            }
        }
        let started = Probe {
            kind,
            tripped_at: None,
            latches,
        };
        self.before_new_motion();
        // Armed from the move's first set-point. The edge looked for cannot be latched
        // still from an earlier probe: the probe is not in the state this move looks for
        // (checked above), so since that edge it has changed back, by a probing move of the
        // other edge (another request: re-armed) or by other motion (set-points without a
        // request: re-armed).
        self.out.latch.probe = latches;
        self.out.latch.probe_rising = toward(kind);
        match self.path.planner.push(&mv) {
            Ok(()) => {
                self.path.planner.flush();
                self.probe = Some(started);
                self.fire(probing);
            }
            // Already there: the probe did not change.
            Err(MotionError::ZeroLength { .. }) => {
                self.probe = Some(started);
                self.fire(probing);
            }
            Err(e) => {
                self.fire(Event::Fail {
                    code: FaultCode::MotionError,
                    line: e.line().unwrap_or(mv.line),
                    value: 0.0,
                });
                *shared.motion_error.lock() = Some(e);
            }
        }
    }

    /// During a probing move, every period: where the probe changes, remember the axis
    /// position (from the feedback, as LinuxCNC) and stop the move.
    pub(super) fn probe_step(&mut self, feedback: &Feedback) {
        let Some(Probe {
            kind,
            tripped_at: None,
            latches,
        }) = self.probe
        else {
            return;
        };
        let contact = feedback.digital_inputs & self.io.probe_bit != 0;
        if contact != toward(kind) {
            return;
        }
        let mut at = self.out.now().target.setpoints.axes;
        for i in 0..AXES {
            if let Some(j) = self.machine.axis_joint[i] {
                at[i] = feedback.position[j] + self.out.offsets[j];
            }
        }
        self.probe = Some(Probe {
            kind,
            tripped_at: Some((at, self.now())),
            latches,
        });
        self.take_back();
        self.path.planner.abort();
    }

    /// Look-ahead, once the probing move stands: the result to the interpreter, or the
    /// program stopped when G38.2/G38.4 ended without the change.
    pub(super) fn probing_done(&mut self, shared: &Shared, kind: ProbeKind, line: u32) -> bool {
        if self.moving() {
            return false;
        }
        let Some(probe) = self.probe else {
            return self.fire(Event::Proceed);
        };
        let tripped_at = match probe.tripped_at {
            Some((seen, cycle)) => match self.latched_position(probe.latches) {
                Some(at) => Some(at),
                None if self.now() < cycle.saturating_add(self.periods(LATCH_WAIT_S)) => {
                    return false;
                }
                None => Some(seen),
            },
            None => None,
        };
        self.probe = None;
        self.out.latch.probe = 0;
        let must_change = matches!(kind, ProbeKind::TowardError | ProbeKind::AwayError);
        if tripped_at.is_none() && must_change {
            let failure = if toward(kind) {
                ProbeFailure::NoContact
            } else {
                ProbeFailure::ContactNotBroken
            };
            return self.fire(Event::Fail {
                code: FaultCode::ProbeFailed,
                line,
                value: failure.value(),
            });
        }
        self.send_result(
            shared,
            MachineResult::Probe {
                tripped: tripped_at.is_some(),
                at: tripped_at.unwrap_or(self.out.now().target.setpoints.axes),
                stopped: self.out.now().target.setpoints.axes,
            },
        );
        self.fire(Event::Proceed)
    }

    /// The axis position the armed joints' touch-probe latches caught, once every one has
    /// reported it.
    fn latched_position(&mut self, latches: u32) -> Option<[f64; AXES]> {
        let feedback = self.interface.feedback.get();
        if latches == 0 || feedback.latched & latches != latches {
            return None;
        }
        let mut at = self.out.now().target.setpoints.axes;
        for i in 0..AXES {
            if let Some(j) = self.machine.axis_joint[i] {
                at[i] = feedback.latch_position[j] + self.out.offsets[j];
            }
        }
        Some(at)
    }

    /// Servo periods in `seconds`, rounded up.
    fn periods(&self, seconds: f64) -> u64 {
        (seconds / self.machine.period_s).ceil() as u64
    }
}
