//! M codes in their order of execution: I/O (M62-M68), tool change (M6, M61), spindle and
//! state save/restore (M3-M5, M19, M70-M73), coolant (M7-M9), overrides (M48-M53), user codes
//! (M100-M199).

use crate::block::{Block, mg};
use crate::canon::{CanonCommand as C, Pose, SpindleDirection, WaitMode};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::Interpreter;
use crate::params::sys;

type Res<T> = Result<T, GcodeError>;

impl Interpreter {
    /// Executes the M codes of a block, one modal group after another in LinuxCNC's order
    /// of execution.
    pub(crate) fn m_codes(&mut self, b: &Block) -> Res<()> {
        // Read once: M72 may restore a state, but the block is checked against the state it
        // started in.
        let comp_on = self.state.cutter.is_some();
        self.m_io(b, comp_on)?;
        self.m_tool_change(b, comp_on)?;
        self.m_spindle_and_state(b)?;
        self.m_coolant(b);
        self.m_overrides(b, comp_on)?;
        self.m_user(b)
    }

    /// Group 5: digital outputs (M62-M65), waits on inputs (M66) and analog outputs
    /// (M67, M68).
    fn m_io(&mut self, b: &Block, comp_on: bool) -> Res<()> {
        let io = b.m[mg::IO];
        if io == -1 {
            return Ok(());
        }
        if comp_on {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::State,
                format!("M{io} is not allowed with cutter radius compensation on"),
            ));
        }
        match io {
            62..=65 => self.m_digital_output(b, io),
            66 => self.m66(b),
            _ => self.m_analog_output(b, io),
        }
    }

    /// M62/M63 switch an output with the next motion, M64/M65 at once.
    fn m_digital_output(&mut self, b: &Block, io: i32) -> Res<()> {
        let Some(p) = b.get(b'p') else {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::MissingWord,
                format!("M{io} needs a P word (output number)"),
            ));
        };
        if p.round() < 0.0 {
            return Err(self.err(
                b,
                b'p',
                ErrorKind::BadValue,
                format!("negative output number with M{io}"),
            ));
        }
        let index = round_index(p);
        self.emit(C::SetDigitalOutput {
            index,
            on: io == 62 || io == 64,
            synchronized: io <= 63,
        });
        Ok(())
    }

    /// M67 sets an analog output with the next motion, M68 at once.
    fn m_analog_output(&mut self, b: &Block, io: i32) -> Res<()> {
        let e = b.get(b'e').map(f64::round);
        let Some(e) = e.filter(|e| *e >= 0.0) else {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::MissingWord,
                format!("M{io} needs an E word (output number)"),
            ));
        };
        self.emit(C::SetAnalogOutput {
            index: e as u32,
            // LinuxCNC sends -1 when Q is missing.
            value: b.get(b'q').unwrap_or(-1.0),
            synchronized: io == 67,
        });
        Ok(())
    }

    /// Group 6: tool change (M6) and setting the tool number without a change (M61).
    fn m_tool_change(&mut self, b: &Block, comp_on: bool) -> Res<()> {
        match b.m[mg::TOOL] {
            6 => self.m6_change_tool(b, comp_on),
            61 => self.m61_set_tool_number(b),
            _ => Ok(()),
        }
    }

    fn m6_change_tool(&mut self, b: &Block, comp_on: bool) -> Res<()> {
        if self.state.selected_pocket < 0 {
            return Err(self.m_err(
                b,
                mg::TOOL,
                ErrorKind::State,
                "M6 needs a tool prepared with T first",
            ));
        }
        if comp_on {
            return Err(self.m_err(
                b,
                mg::TOOL,
                ErrorKind::State,
                "cannot change tools with cutter radius compensation on",
            ));
        }
        self.emit(C::StartChange);
        self.emit(C::StopSpindle { spindle: 0 });
        self.state.spindle = None;
        self.emit(C::ChangeTool(self.state.selected_pocket));
        self.state.current_tool = self.state.selected_tool.max(0);
        self.state.current_pocket = self.state.selected_pocket;
        self.set_tool_params();
        Ok(())
    }

    fn m61_set_tool_number(&mut self, b: &Block) -> Res<()> {
        let q = b.get(b'q').unwrap_or(-1.0);
        let t = self.whole(b, b'q', q)?;
        if t < 0 {
            return Err(self.m_err(
                b,
                mg::TOOL,
                ErrorKind::MissingWord,
                "M61 needs a Q word with a tool number of 0 or more",
            ));
        }
        let pocket = self.find_pocket(b, b'q', t)?;
        self.state.current_tool = t;
        self.state.current_pocket = pocket;
        self.emit(C::ChangeToolNumber(pocket));
        self.set_tool_params();
        Ok(())
    }

    /// Group 7: spindle (M3-M5, M19) and modal state save/restore (M70-M73).
    fn m_spindle_and_state(&mut self, b: &Block) -> Res<()> {
        match b.m[mg::SPINDLE] {
            3 | 4 => self.m3_m4_start_spindle(b)?,
            5 => {
                self.state.spindle = None;
                self.emit(C::StopSpindle { spindle: 0 });
            }
            19 => self.m19_orient_spindle(b)?,
            70 => self.save_state(false),
            73 => self.save_state(true),
            71 => self.invalidate_state(),
            72 => {
                let Some(saved) = self.saved_state() else {
                    return Err(self.m_err(
                        b,
                        mg::SPINDLE,
                        ErrorKind::State,
                        "M72 with no state saved by M70 or M73 at this call level",
                    ));
                };
                self.restore_state(&saved)?;
            }
            _ => {}
        }
        Ok(())
    }

    fn m3_m4_start_spindle(&mut self, b: &Block) -> Res<()> {
        if let Some(d) = b.dollar {
            if d != 0.0 {
                return Err(self.m_err(
                    b,
                    mg::SPINDLE,
                    ErrorKind::BadValue,
                    "spindle ($) number out of range: this machine has spindle 0 only",
                ));
            }
        }
        let direction = if b.m[mg::SPINDLE] == 3 {
            SpindleDirection::Clockwise
        } else {
            SpindleDirection::CounterClockwise
        };
        self.emit(C::StartSpindle {
            spindle: 0,
            direction,
        });
        self.state.spindle = Some(direction);
        Ok(())
    }

    /// M19 stops the spindle at an angle (R, P the direction) and may wait Q seconds for it.
    fn m19_orient_spindle(&mut self, b: &Block) -> Res<()> {
        self.state.spindle = None;
        if b.has(b'r') || b.has(b'p') {
            self.emit(C::OrientSpindle {
                spindle: 0,
                angle: b.get(b'r').unwrap_or(0.0),
                mode: b.get(b'p').map_or(0, |p| p.round() as i32),
            });
        }
        if let Some(q) = b.get(b'q') {
            if q <= 0.0 {
                return Err(self.err(
                    b,
                    b'q',
                    ErrorKind::BadValue,
                    "Q word with M19 needs a value > 0",
                ));
            }
            self.emit(C::WaitOrientComplete {
                spindle: 0,
                timeout: q,
            });
        }
        Ok(())
    }

    /// Group 8: coolant, mist (M7), flood (M8), both off (M9).
    fn m_coolant(&mut self, b: &Block) {
        match b.m[mg::COOLANT] {
            7 => {
                self.emit(C::MistOn);
                self.state.mist = true;
            }
            8 => {
                self.emit(C::FloodOn);
                self.state.flood = true;
            }
            9 => {
                self.emit(C::MistOff);
                self.state.mist = false;
                self.emit(C::FloodOff);
                self.state.flood = false;
            }
            _ => {}
        }
    }

    /// Group 9: feed and speed overrides (M48-M51), adaptive feed (M52), feed hold (M53).
    fn m_overrides(&mut self, b: &Block, comp_on: bool) -> Res<()> {
        let ov = b.m[mg::OVERRIDE];
        if ov == -1 {
            return Ok(());
        }
        if comp_on {
            return Err(self.m_err(
                b,
                mg::OVERRIDE,
                ErrorKind::State,
                "cannot change overrides with cutter radius compensation on",
            ));
        }
        // As in LinuxCNC, a missing P counts as -1: on.
        let on = b.get(b'p').unwrap_or(-1.0) != 0.0;
        match ov {
            48 | 49 => {
                let on = ov == 48;
                self.emit(C::FeedOverride(on));
                self.state.feed_override = on;
                self.emit(C::SpeedOverride {
                    spindle: 0,
                    enable: on,
                });
                self.state.speed_override = on;
            }
            50 => {
                self.emit(C::FeedOverride(on));
                self.state.feed_override = on;
            }
            51 => {
                self.emit(C::SpeedOverride {
                    spindle: 0,
                    enable: on,
                });
                self.state.speed_override = on;
            }
            52 => {
                self.emit(C::AdaptiveFeed(on));
                self.state.adaptive_feed = on;
            }
            _ => {
                self.emit(C::FeedHold(on));
                self.state.feed_hold = on;
            }
        }
        Ok(())
    }

    /// Group 10: user M codes (M100-M199), handed on to the machine logic, and
    /// tool-centre-point control on (M428) and off (M429), LinuxCNC's codes of its
    /// switchable 5-axis kinematics.
    fn m_user(&mut self, b: &Block) -> Res<()> {
        let user = b.m[mg::USER];
        match user {
            -1 => {}
            428 | 429 => {
                if b.has_axis() || b.has_polar() {
                    return Err(self.m_err(
                        b,
                        mg::USER,
                        ErrorKind::Conflict,
                        format!("M{user} takes no axis words: put the move on a line of its own"),
                    ));
                }
                if self.state.cutter.is_some() {
                    return Err(self.m_err(
                        b,
                        mg::USER,
                        ErrorKind::State,
                        format!("M{user} with cutter radius compensation on: G40 first"),
                    ));
                }
                let on = user == 428;
                self.state.tool_centre_point = on;
                self.emit(C::SetToolCentrePoint(on));
            }
            _ => self.emit(C::UserMCode {
                code: user as u16,
                p: b.get(b'p'),
                q: b.get(b'q'),
            }),
        }
        Ok(())
    }

    pub(crate) fn m66(&mut self, b: &Block) -> Res<()> {
        let p = b.get(b'p');
        let e = b.get(b'e');
        let l = b.get(b'l').map(f64::round);
        let q = b.get(b'q').unwrap_or(0.0);
        if p.is_some() && e.is_some() {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::Conflict,
                "M66 cannot wait on a digital (P) and an analog (E) input at once",
            ));
        }
        if q <= 0.0 && l.is_some_and(|l| l > 0.0) {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::MissingWord,
                "M66 with a wait mode other than L0 needs a Q timeout > 0",
            ));
        }
        if e.is_some() && l.is_some_and(|l| l != 0.0) {
            return Err(self.m_err(
                b,
                mg::IO,
                ErrorKind::BadValue,
                "M66 on an analog input (E) allows only L0",
            ));
        }
        let (digital, index) = match (p, e) {
            (Some(p), _) if p.round() >= 0.0 => (true, p.round() as u32),
            (_, Some(e)) if e.round() >= 0.0 => (false, e.round() as u32),
            _ => {
                return Err(self.m_err(
                    b,
                    mg::IO,
                    ErrorKind::MissingWord,
                    "M66 needs a valid P (digital) or E (analog) input number",
                ));
            }
        };
        let mode = match l.unwrap_or(0.0) as i64 {
            0 => WaitMode::Immediate,
            1 => WaitMode::Rise,
            2 => WaitMode::Fall,
            3 => WaitMode::High,
            4 => WaitMode::Low,
            _ => return Err(self.err(b, b'l', ErrorKind::BadValue, "M66 L must be 0..4")),
        };
        self.emit(C::WaitInput {
            digital,
            index,
            mode,
            timeout: if digital && q > 0.0 { q } else { 0.0 },
        });
        // Without a machine the input reads 0.
        self.params.set(sys::INPUT, 0.0);
        self.waiting = self.settings.wait_for_machine;
        Ok(())
    }

    /// #5400.. from the tool now in the spindle.
    pub(crate) fn set_tool_params(&mut self) {
        let t = self.state.current_tool;
        let tool = self.tools.get(t).cloned();
        self.params.set(sys::TOOL, f64::from(t));
        let off = tool.as_ref().map_or(Pose::ZERO, |t| t.offset).to_array();
        for (i, v) in off.iter().enumerate() {
            self.params.set(sys::TOOL_OFFSET + i, *v);
        }
        self.params
            .set(5410, tool.as_ref().map_or(0.0, |t| t.diameter));
        self.params
            .set(5411, tool.as_ref().map_or(0.0, |t| t.front_angle));
        self.params
            .set(5412, tool.as_ref().map_or(0.0, |t| t.back_angle));
        self.params.set(
            5413,
            tool.as_ref().map_or(0.0, |t| f64::from(t.orientation)),
        );
    }
}

/// An output number from a P word (negative values select output 0).
fn round_index(v: f64) -> u32 {
    let r = v.round();
    if r <= 0.0 {
        0
    } else {
        r.min(f64::from(u32::MAX)) as u32
    }
}
