//! Probing (G38.2-G38.5): once the path stands, an exact-stop line at the programmed
//! feed; in the first period in which the probe input changes as the move looks for, the
//! axis position is taken from the feedback (as LinuxCNC does) and the move is stopped
//! along the path. The interpreter gets where the probe changed and where the machine
//! stopped.

use rtcnc_gcode::canon::ProbeKind;
use rtcnc_motion::{AXES, MotionError, Move};

use super::MotionCore;
use super::state::Event;
use crate::fault::{FaultCode, ProbeFailure};
use crate::messages::MachineResult;
use crate::shared::{Feedback, Shared};

/// The probing move in progress.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Probe {
    kind: ProbeKind,
    /// The axis position where the probe changed, once it has.
    tripped_at: Option<[f64; AXES]>,
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
        let started = Probe {
            kind,
            tripped_at: None,
        };
        self.before_new_motion();
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
            tripped_at: Some(at),
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
        let tripped_at = self.probe.take().and_then(|p| p.tripped_at);
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
}
