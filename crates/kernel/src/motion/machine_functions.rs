//! Machine functions, once the path stands at their block: the M/S/T hand-shakes with the
//! machine logic (a request, the logic's answer, and for a tool change or a user M code the
//! request dropped and the answer awaited falling), program I/O (M62-M68: outputs set,
//! inputs waited for or read, the result handed to the interpreter), spindle orientation
//! (M19), the program's say over the overrides (M48-M53), pauses (M0, M1) and operator
//! messages.

use super::MotionCore;
use super::program_outputs::OutputChange;
use super::state::{Event, State, Step};
use crate::config::{MAX_PROGRAM_IO, MachineConfig};
use crate::fault::FaultCode;
use crate::messages::{Aux, MachineResult, WaitCondition};
use crate::shared::Shared;

/// The map from the program's I/O numbers to the machine's image points.
#[derive(Debug, Clone, Copy)]
pub(super) struct ProgramIo {
    /// M66 `P n`: digital input point of program input n.
    inputs: [usize; 16],
    input_count: usize,
    /// M66 `E n`: analogue input point of program input n.
    analog_inputs: [usize; MAX_PROGRAM_IO],
    analog_input_count: usize,
    /// M67/M68 `E n` that are mapped (position control maps them to points).
    analog_output_count: usize,
    /// Bit of the probe in the digital inputs (0: none).
    pub(super) probe_bit: u64,
    /// Bit of the feed stop switch in the digital inputs (0: none).
    pub(super) feed_stop_bit: u64,
    /// The adaptive-feed analogue input (M52).
    pub(super) adaptive_feed_point: Option<usize>,
}

impl ProgramIo {
    pub(super) fn new(config: &MachineConfig) -> ProgramIo {
        let io = &config.io;
        let mut inputs = [0usize; 16];
        for (slot, &i) in inputs.iter_mut().zip(&io.program_inputs) {
            *slot = i;
        }
        let mut analog_inputs = [0usize; MAX_PROGRAM_IO];
        for (slot, &i) in analog_inputs.iter_mut().zip(&io.program_analog_inputs) {
            *slot = i;
        }
        ProgramIo {
            inputs,
            input_count: io.program_inputs.len().min(16),
            analog_inputs,
            analog_input_count: io.program_analog_inputs.len().min(MAX_PROGRAM_IO),
            analog_output_count: io.program_analog_outputs.len().min(MAX_PROGRAM_IO),
            probe_bit: io.probe_input.map_or(0, |i| 1u64 << i.min(63)),
            feed_stop_bit: io.feed_stop_input.map_or(0, |i| 1u64 << i.min(63)),
            adaptive_feed_point: io.adaptive_feed_input.filter(|&i| i < MAX_PROGRAM_IO),
        }
    }

    /// The digital input point of program input `index`, if the machine maps it.
    fn input(&self, index: u32) -> Option<usize> {
        usize::try_from(index)
            .ok()
            .filter(|&i| i < self.input_count)
            .map(|i| self.inputs[i])
            .filter(|&p| p < 64)
    }

    /// The slot of program analogue output `index` (M67/M68 E), if the machine maps it.
    pub(super) fn analog_output(&self, index: u32) -> Option<usize> {
        usize::try_from(index)
            .ok()
            .filter(|&i| i < self.analog_output_count)
    }

    /// The analogue input point of program input `index`, if the machine maps it.
    fn analog_input(&self, index: u32) -> Option<usize> {
        usize::try_from(index)
            .ok()
            .filter(|&i| i < self.analog_input_count)
            .map(|i| self.analog_inputs[i])
    }
}

impl MotionCore {
    /// Starts the machine function the path stopped for; what comes next is the logic's
    /// answer, a wait, a pause, or the next block.
    pub(super) fn start_aux(&mut self, shared: &Shared, aux: Aux, line: u32) {
        self.program.aux_cycle = self.now();
        let hand_shake = Event::HandShake { aux, line };
        let refused = Event::Fail {
            code: FaultCode::AuxRefused,
            line,
            value: 0.0,
        };
        let next = match aux {
            Aux::SpindleOn { .. }
            | Aux::SpindleOff
            | Aux::SpindleSpeed { .. }
            | Aux::ConstantSurfaceSpeed { .. }
            | Aux::SurfaceSpeed { .. } => {
                self.command_spindle(aux);
                hand_shake
            }
            // The S number in force becomes the rpm; not waited for (an S word usually
            // follows at once, and that is waited for).
            Aux::SurfaceSpeedOff => {
                self.command_spindle(aux);
                Event::Proceed
            }
            // Orientation goes to the spindle drive at once; M19 Q waits for it.
            Aux::SpindleOrient { angle, mode } => {
                self.spindle.on = false;
                let mi = self.requests_mut();
                mi.spindle_on = false;
                mi.spindle_orient = true;
                mi.spindle_orient_angle = angle;
                mi.spindle_orient_mode = mode;
                self.program.orient_cycle = self.now();
                Event::Proceed
            }
            Aux::WaitOrient { timeout } => Event::WaitOrient {
                deadline: self.deadline_after(timeout),
                line,
            },
            Aux::Mist(on) => {
                self.requests_mut().mist = on;
                hand_shake
            }
            Aux::Flood(on) => {
                self.requests_mut().flood = on;
                hand_shake
            }
            Aux::ToolChange { tool } => {
                let mi = self.requests_mut();
                mi.tool_number = tool;
                mi.tool_change_request = true;
                hand_shake
            }
            Aux::UserM { code, p, q } => {
                let mi = self.requests_mut();
                mi.m_code = code;
                mi.m_p = p;
                mi.m_q = q;
                mi.m_code_request = true;
                hand_shake
            }
            // M64/M65, or an M62/M63 the path stopped for (no room to stage it).
            Aux::DigitalOutput { index, on, .. } => {
                self.change_output_now(Some(OutputChange::Digital { index, on }));
                Event::Proceed
            }
            Aux::WaitInput {
                index,
                condition,
                timeout,
            } => match self.io.input(index) {
                Some(point) => {
                    let deadline = self.deadline_after(timeout);
                    let bit = 1u64 << point;
                    let previous = self.interface.feedback.get().digital_inputs & bit != 0;
                    Event::WaitInput {
                        bit,
                        condition,
                        deadline,
                        previous,
                    }
                }
                // An input the machine does not map: the program cannot wait on it.
                None => refused,
            },
            Aux::ReadAnalogInput { index } => {
                let value = self
                    .io
                    .analog_input(index)
                    .and_then(|p| self.interface.feedback.get().analog_inputs.get(p).copied());
                match value {
                    Some(v) => {
                        self.send_result(shared, MachineResult::Input(v));
                        Event::Proceed
                    }
                    None => refused,
                }
            }
            Aux::AnalogOutput { index, value, .. } => match self.io.analog_output(index) {
                Some(slot) => {
                    self.change_output_now(Some(OutputChange::Analog { slot, value }));
                    Event::Proceed
                }
                None => refused,
            },
            Aux::FeedOverrideEnable(on) => {
                self.overrides.feed_enabled = on;
                self.apply_feed_overrides();
                Event::Proceed
            }
            Aux::SpindleOverrideEnable(on) => {
                self.overrides.spindle_enabled = on;
                if self.interface.requests.spindle_on {
                    let rpm = self.spindle_command();
                    self.requests_mut().spindle_rpm = rpm;
                }
                Event::Proceed
            }
            Aux::FeedStopEnable(on) => {
                self.overrides.feed_stop_enabled = on;
                Event::Proceed
            }
            Aux::AdaptiveFeed(on) => {
                if self.set_adaptive_feed(on) {
                    Event::Proceed
                } else {
                    refused
                }
            }
            Aux::ProgramStop => Event::Pause {
                start_count: self.program.start_count,
            },
            Aux::OptionalStop if self.program.optional_stop => Event::Pause {
                start_count: self.program.start_count,
            },
            Aux::OptionalStop => Event::Proceed,
            Aux::Message { seq } => {
                self.show_message(shared, seq, line);
                Event::Proceed
            }
        };
        self.fire(next);
    }

    /// The change of a synchronised output (M62/M63/M67) to stage for the next move:
    /// `None` for every other function, and for an analogue output the machine does not
    /// map (the path stops there and the function is refused).
    pub(super) fn synchronized_change(&self, aux: Aux) -> Option<OutputChange> {
        match aux {
            Aux::DigitalOutput {
                index,
                on,
                synchronized: true,
            } => Some(OutputChange::Digital { index, on }),
            Aux::AnalogOutput {
                index,
                value,
                synchronized: true,
            } => self
                .io
                .analog_output(index)
                .map(|slot| OutputChange::Analog { slot, value }),
            _ => None,
        }
    }

    /// Changes the program outputs from the next exchange (the path stands): `change`, and
    /// before it any synchronised change still staged (its next move is not the planner's:
    /// a probing or threading move, or the end). The set-points computed ahead at rest are
    /// taken back, so that the change acts at once rather than after the lead.
    pub(super) fn change_output_now(&mut self, change: Option<OutputChange>) {
        if change.is_none() && self.outputs.staged() == 0 {
            return;
        }
        self.before_new_motion();
        let number = self.now() + u64::from(!self.out.interpolating);
        let oldest = self.outputs_oldest_applied();
        if !self.outputs.log_from_setpoint(number, change, oldest) {
            // Not reached with the path standing (every change before was applied), but
            // the output must not be lost: applied to the set-points from the next one.
            if let Some(c) = change {
                c.apply(&mut self.outputs.state);
            }
        }
    }

    /// Output changes applied by the oldest set-point a take-back may still go back to
    /// (the one position control took last): the log keeps every entry after it.
    pub(super) fn outputs_oldest_applied(&self) -> u64 {
        self.out.at(self.now().saturating_sub(1)).outputs_applied
    }

    /// Whether the machine logic acknowledged `aux`; drops hand-shake requests once done.
    pub(super) fn logic_done(&mut self, aux: Aux, released: bool) -> bool {
        let answers = *self.interface.logic.get();
        let done = match aux {
            Aux::SpindleOn { .. }
            | Aux::SpindleSpeed { .. }
            | Aux::ConstantSurfaceSpeed { .. }
            | Aux::SurfaceSpeed { .. }
            | Aux::SurfaceSpeedOff => {
                // The logic's at-speed answers the new command only after the drives have
                // had it (one exchange) and the logic has scanned again.
                !self.interface.requests.spindle_on
                    || (answers.spindle_at_speed && self.now() >= self.program.aux_cycle + 2)
            }
            Aux::SpindleOff => true,
            Aux::Mist(on) => answers.out_mist == on,
            Aux::Flood(on) => answers.out_flood == on,
            // Two steps: the request stands until the logic answers done, then the
            // request drops and the hand-shake ends when the answer drops too.
            Aux::ToolChange { tool } => {
                if !released {
                    if answers.tool_change_done {
                        self.requests_mut().tool_change_request = false;
                        self.tool = tool;
                        self.fire(Event::Answered);
                    }
                    false
                } else {
                    !answers.tool_change_done
                }
            }
            Aux::UserM { .. } => {
                if !released {
                    if answers.m_code_done {
                        self.requests_mut().m_code_request = false;
                        self.fire(Event::Answered);
                    }
                    false
                } else {
                    !answers.m_code_done
                }
            }
            Aux::DigitalOutput { .. }
            | Aux::ProgramStop
            | Aux::OptionalStop
            | Aux::Message { .. }
            | Aux::SpindleOrient { .. }
            | Aux::WaitOrient { .. }
            | Aux::FeedOverrideEnable(_)
            | Aux::SpindleOverrideEnable(_)
            | Aux::FeedStopEnable(_)
            | Aux::AdaptiveFeed(_)
            | Aux::ReadAnalogInput { .. }
            | Aux::AnalogOutput { .. }
            | Aux::WaitInput { .. } => true,
        };
        if done {
            self.fire(Event::Proceed);
        }
        done
    }

    /// M19 Q: the program goes on once the spindle reports oriented, or stops at the
    /// deadline.
    pub(super) fn waiting_for_orient(&mut self, deadline: u64, line: u32) -> bool {
        // The feedback answers the orientation only after the drive had it.
        let oriented = self.interface.feedback.get().spindle_oriented
            && self.now() >= self.program.orient_cycle + 2;
        if oriented {
            self.fire(Event::Proceed)
        } else if self.now() >= deadline {
            self.fire(Event::Fail {
                code: FaultCode::SpindleOrientTimeout,
                line,
                value: 0.0,
            })
        } else {
            false
        }
    }

    /// M66 on a digital input: the program goes on when the condition is met or at the
    /// deadline; the interpreter gets the input's level, or -1 on a time-out (#5399, as
    /// LinuxCNC).
    pub(super) fn waiting_for_input(
        &mut self,
        shared: &Shared,
        bit: u64,
        condition: WaitCondition,
        deadline: u64,
        previous: bool,
    ) -> bool {
        let now = self.interface.feedback.get().digital_inputs & bit != 0;
        let met = match condition {
            WaitCondition::Immediate => true,
            WaitCondition::Rise => now && !previous,
            WaitCondition::Fall => !now && previous,
            WaitCondition::High => now,
            WaitCondition::Low => !now,
        };
        if met || self.now() >= deadline {
            let value = match (met, now) {
                (false, _) => -1.0,
                (true, true) => 1.0,
                (true, false) => 0.0,
            };
            self.send_result(shared, MachineResult::Input(value));
            self.fire(Event::Proceed)
        } else {
            // The level this period, for the edge the next one may see.
            if let State::Program(Step::WaitInput { previous, .. }) = &mut self.state {
                *previous = now;
            }
            false
        }
    }
}
