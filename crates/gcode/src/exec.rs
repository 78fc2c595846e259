//! Executing one block in the RS274/NGC order of execution: comment, feed mode, F, S, T,
//! I/O, tool change, spindle, state save/restore, coolant, overrides, user M codes, dwell,
//! plane, units, lathe mode, cutter compensation, tool length offset, coordinate system,
//! path mode, distance modes, retract mode, G10/G28/G30/G92, motion, stop.

use crate::block::{Block, CommentKind as Comment, fmt_code, gg, mg};
use crate::canon::{
    Arc, CanonCommand as C, CompensationSide, FeedMode, PathMode, Plane, Pose, ProbeKind,
    SpindleDirection, Spline, ToolEntry, Units, WaitMode,
};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::{Interpreter, ModalState, rotate, substitute};
use crate::params::sys;

/// Internal radius tolerance of R-format arcs (inch), as LinuxCNC.
const RADIUS_TOLERANCE_INCH: f64 = 0.00005;
const SPIRAL_RELATIVE_TOLERANCE: f64 = 0.001;

type Res<T> = Result<T, GcodeError>;

/// Axis word letters in pose order.
const AXES: [u8; 9] = [b'x', b'y', b'z', b'a', b'b', b'c', b'u', b'v', b'w'];

impl Interpreter {
    fn err(&self, b: &Block, letter: u8, kind: ErrorKind, msg: impl Into<String>) -> GcodeError {
        let col = if letter.is_ascii_lowercase() && b.has(letter) {
            b.column(letter) + 1
        } else {
            0
        };
        self.error_at(kind, col, msg)
    }

    fn g_err(
        &self,
        b: &Block,
        group: usize,
        kind: ErrorKind,
        msg: impl Into<String>,
    ) -> GcodeError {
        self.error_at(kind, usize::from(b.g_col[group]) + 1, msg)
    }

    fn m_err(
        &self,
        b: &Block,
        group: usize,
        kind: ErrorKind,
        msg: impl Into<String>,
    ) -> GcodeError {
        self.error_at(kind, usize::from(b.m_col[group]) + 1, msg)
    }

    /// Executes a block. Returns false when the program ends (M2, M30, M99 at top level).
    pub(crate) fn execute(&mut self, b: &mut Block) -> Res<bool> {
        let motion = self.motion_to_be(b)?;
        self.check_words(b, motion)?;
        if b.has_comment {
            self.comment(b);
        }
        self.probe_pending = false;
        if b.g[gg::SPINDLE] != -1 {
            self.spindle_mode(b)?;
        }
        if b.g[gg::FEED_MODE] != -1 {
            self.feed_mode(b.g[gg::FEED_MODE]);
        }
        if let Some(f) = b.get(b'f') {
            if f < 0.0 {
                return Err(self.err(b, b'f', ErrorKind::BadValue, "negative F word"));
            }
            if self.state.feed_mode != FeedMode::InverseTime {
                self.state.feed_rate = f;
                self.emit(C::SetFeedRate(f));
            }
        }
        if let Some(s) = b.get(b's') {
            if s < 0.0 {
                return Err(self.err(b, b's', ErrorKind::BadValue, "negative spindle speed"));
            }
            if let Some(d) = b.dollar {
                if d != 0.0 {
                    return Err(self.error_at(
                        ErrorKind::BadValue,
                        0,
                        "invalid spindle ($) number: this machine has spindle 0 only",
                    ));
                }
            }
            self.state.speed = s;
            self.emit(C::SetSpindleSpeed {
                spindle: 0,
                speed: s,
            });
        }
        if let Some(t) = b.get(b't') {
            let t = self.whole(b, b't', t)?;
            if t < 0 {
                return Err(self.err(b, b't', ErrorKind::BadValue, "negative tool number"));
            }
            let pocket = self.find_pocket(b, b't', t)?;
            self.emit(C::SelectTool(t));
            self.state.selected_tool = t;
            self.state.selected_pocket = pocket;
        }
        self.m_codes(b)?;
        self.g_codes(b, motion)?;
        if b.m[mg::STOP] != -1 {
            return self.stop(b);
        }
        Ok(true)
    }

    /// Which motion the block makes (tenths), or -1 for none; with the axis-word checks of
    /// RS274/NGC.
    fn motion_to_be(&self, b: &Block) -> Res<i32> {
        let axis = b.has_axis();
        let mode0 = b.g[gg::NON_MODAL];
        let mode1 = b.g[gg::MOTION];
        let covets = matches!(mode0, 100 | 280 | 300 | 520 | 920);
        if mode1 != -1 {
            if mode1 == 800 {
                if axis && !covets {
                    return Err(self.g_err(
                        b,
                        gg::MOTION,
                        ErrorKind::UnusedWord,
                        "axis words cannot be used with G80",
                    ));
                }
                if !axis && mode0 == 920 {
                    return Err(self.g_err(
                        b,
                        gg::NON_MODAL,
                        ErrorKind::MissingWord,
                        "G92 needs at least one axis word",
                    ));
                }
                return Ok(800);
            }
            if covets {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::Conflict,
                    format!(
                        "G{} and G{} both use the axis words",
                        fmt_code(mode0),
                        fmt_code(mode1)
                    ),
                ));
            }
            if !axis && !matches!(mode1, 0 | 10 | 20 | 30) {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    format!("G{} needs at least one axis word", fmt_code(mode1)),
                ));
            }
            return Ok(mode1);
        }
        if covets {
            if !axis && mode0 == 920 {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::MissingWord,
                    "G92 needs at least one axis word",
                ));
            }
            return Ok(-1);
        }
        if axis {
            if self.state.motion == 800 && b.g[gg::LENGTH] != 431 {
                let first = AXES.iter().find(|c| b.has(**c)).copied().unwrap_or(b'x');
                return Err(self.err(
                    b,
                    first,
                    ErrorKind::UnusedWord,
                    "axis word with no motion mode in effect (G80): give G0, G1, ... first",
                ));
            }
            if b.g[gg::LENGTH] == 431 {
                return Ok(-1);
            }
            return Ok(self.state.motion);
        }
        if (b.has(b'i') || b.has(b'j') || b.has(b'k')) && matches!(self.state.motion, 20 | 30) {
            return Ok(self.state.motion);
        }
        Ok(-1)
    }

    /// Words present that nothing on the block uses.
    fn check_words(&self, b: &Block, motion: i32) -> Res<()> {
        let mode0 = b.g[gg::NON_MODAL];
        let cycle = matches!(motion, 730 | 810..=890);
        let g10 = mode0 == 100;
        let user_m = b.m[mg::USER] != -1;
        let m = |g: usize, v: i32| b.m[g] == v;
        if mode0 == 40 && !b.has(b'p') {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                "G4 needs a P word (seconds)",
            ));
        }
        if mode0 == 530 {
            if motion != 0 && motion != 10 {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::Conflict,
                    "G53 needs G0 or G1",
                ));
            }
            if b.g[gg::DISTANCE] == 910 || (b.g[gg::DISTANCE] != 900 && !self.state.absolute) {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::Conflict,
                    "G53 cannot be used in incremental mode (G91)",
                ));
            }
        }
        for (l, ok, name) in [
            (b'a', !cycle, "an A word cannot be used in a canned cycle"),
            (b'b', !cycle, "a B word cannot be used in a canned cycle"),
            (b'c', !cycle, "a C word cannot be used in a canned cycle"),
        ] {
            if b.has(l) && !ok {
                return Err(self.err(b, l, ErrorKind::UnusedWord, name));
            }
        }
        if b.has(b'd')
            && !matches!(b.g[gg::CUTTER], 410 | 420 | 411 | 421)
            && b.g[gg::SPINDLE] != 960
        {
            return Err(self.err(
                b,
                b'd',
                ErrorKind::UnusedWord,
                "D word with no G41, G41.1, G42, G42.1 or G96 to use it",
            ));
        }
        if b.has(b'e') && !(m(mg::IO, 66) || m(mg::IO, 67) || m(mg::IO, 68)) {
            return Err(self.err(
                b,
                b'e',
                ErrorKind::UnusedWord,
                "E word with no M66, M67 or M68 to use it",
            ));
        }
        if b.has(b'h') && b.g[gg::LENGTH] != 430 {
            return Err(self.err(
                b,
                b'h',
                ErrorKind::UnusedWord,
                "H word with no G43 to use it",
            ));
        }
        if b.has(b'i') && !(matches!(motion, 20 | 30 | 50 | 51 | 870) || g10) {
            return Err(self.err(
                b,
                b'i',
                ErrorKind::UnusedWord,
                "I word with no G2, G3, G5, G5.1, G10 or G87 to use it",
            ));
        }
        if b.has(b'j') && !(matches!(motion, 20 | 30 | 50 | 51 | 870) || g10) {
            return Err(self.err(
                b,
                b'j',
                ErrorKind::UnusedWord,
                "J word with no G2, G3, G5, G5.1, G10 or G87 to use it",
            ));
        }
        if b.has(b'k') && !matches!(motion, 20 | 30 | 870) {
            return Err(self.err(
                b,
                b'k',
                ErrorKind::UnusedWord,
                "K word with no G2, G3 or G87 to use it",
            ));
        }
        if b.has(b'l')
            && !(cycle
                || g10
                || matches!(b.g[gg::CUTTER], 410 | 420 | 411 | 421)
                || m(mg::IO, 66)
                || b.m98)
        {
            return Err(self.err(
                b,
                b'l',
                ErrorKind::UnusedWord,
                "L word with no G10, cutter compensation, canned cycle, M66 or M98 to use it",
            ));
        }
        if let Some(p) = b.get(b'p') {
            let ok = g10
                || mode0 == 40
                || b.g[gg::CONTROL] == 640
                || matches!(motion, 820 | 860 | 880 | 890 | 50 | 20 | 30 | 840)
                || matches!(b.m[mg::OVERRIDE], 50..=53)
                || matches!(b.m[mg::IO], 62..=66)
                || m(mg::SPINDLE, 19)
                || user_m
                || b.m98;
            if !ok {
                return Err(self.err(b, b'p', ErrorKind::UnusedWord, "P word with no G2 G3 G4 G5 G10 G64 G82 G84 G86 G88 G89, M50-M53, M62-M66, M19, M98 or user M code to use it"));
            }
            if (matches!(motion, 20 | 30) || m(mg::SPINDLE, 19)) && (p - p.round()).abs() > 0.001 {
                return Err(self.err(
                    b,
                    b'p',
                    ErrorKind::BadValue,
                    "P value not an integer with M19, G2 or G3",
                ));
            }
            if m(mg::SPINDLE, 19) && !(0.0..=2.0).contains(&p.round()) {
                return Err(self.err(
                    b,
                    b'p',
                    ErrorKind::BadValue,
                    "P value must be 0, 1 or 2 with M19",
                ));
            }
            if matches!(motion, 20 | 30) && p.round() < 1.0 {
                return Err(self.err(
                    b,
                    b'p',
                    ErrorKind::BadValue,
                    "P value should be 1 or greater with G2 or G3",
                ));
            }
        }
        if b.has(b'q') {
            let ok = matches!(motion, 830 | 730 | 50)
                || user_m
                || matches!(b.m[mg::IO], 66..=68)
                || g10
                || m(mg::TOOL, 61)
                || b.g[gg::CONTROL] == 640
                || m(mg::SPINDLE, 19);
            if !ok {
                return Err(self.err(b, b'q', ErrorKind::UnusedWord, "Q word with no G5, G10, G64, G73, G83, M19, M61, M66, M67, M68 or user M code that uses it"));
            }
        }
        if let Some(r) = b.get(b'r') {
            let ok = matches!(motion, 20 | 30)
                || cycle
                || g10
                || m(mg::SPINDLE, 19)
                || matches!(b.g[gg::CUTTER], 411 | 421);
            if !ok {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::UnusedWord,
                    "R word with no G code that uses it",
                ));
            }
            if m(mg::SPINDLE, 19) && !(0.0..=360.0).contains(&r) {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::BadValue,
                    "R value must be within 0..360 with M19",
                ));
            }
        }
        if b.g[gg::SPINDLE] == 960 && !b.has(b's') {
            return Err(self.g_err(
                b,
                gg::SPINDLE,
                ErrorKind::MissingWord,
                "G96 needs an S word (surface speed)",
            ));
        }
        if b.dollar.is_some()
            && !(b.has(b's')
                || matches!(b.m[mg::SPINDLE], 3 | 4 | 5 | 19)
                || b.g[gg::SPINDLE] != -1
                || b.g[gg::FEED_MODE] == 950
                || m(mg::OVERRIDE, 51))
        {
            return Err(self.error_at(
                ErrorKind::UnusedWord,
                0,
                "$ (spindle) word with no M3, M4, M5, M19, M51, G95, G96, G97 or S to use it",
            ));
        }
        Ok(())
    }

    fn comment(&mut self, b: &Block) {
        match b.comment_kind {
            Comment::Plain => {
                let t = b.comment.trim_start_matches([' ', '\t']).to_string();
                self.emit(C::Comment(t.into()));
            }
            Comment::Msg => self.emit(C::Message(b.comment.clone().into())),
            Comment::Debug => {
                if self.params.get(5599) > 0.0 {
                    let t = substitute(&b.comment, self);
                    self.emit(C::Message(t.into()));
                }
            }
            Comment::Print => {
                let t = substitute(&b.comment, self);
                self.emit(C::Print(t.into()));
            }
        }
    }

    fn spindle_mode(&mut self, b: &Block) -> Res<()> {
        if b.g[gg::SPINDLE] == 970 {
            self.state.css = false;
            self.state.css_max = 0.0;
            self.emit(C::SetSpindleMode {
                spindle: 0,
                max_rpm: 0.0,
                constant_surface_speed: false,
            });
        } else {
            self.state.css = true;
            let d = b.get(b'd').map_or(1e30, f64::abs);
            self.state.css_max = d;
            self.emit(C::SetSpindleMode {
                spindle: 0,
                max_rpm: d,
                constant_surface_speed: true,
            });
        }
        Ok(())
    }

    fn feed_mode(&mut self, code: i32) {
        let (note, mode) = match code {
            930 => (
                "interpreter: feed mode set to inverse time",
                FeedMode::InverseTime,
            ),
            940 => (
                "interpreter: feed mode set to units per minute",
                FeedMode::UnitsPerMinute,
            ),
            _ => (
                "interpreter: feed mode set to units per revolution",
                FeedMode::UnitsPerRevolution,
            ),
        };
        self.emit(C::Comment(note.into()));
        self.state.feed_mode = mode;
        self.emit(C::SetFeedMode { spindle: 0, mode });
        if mode != FeedMode::InverseTime {
            self.state.feed_rate = 0.0;
            self.emit(C::SetFeedRate(0.0));
        }
    }

    fn whole(&self, b: &Block, letter: u8, v: f64) -> Res<i32> {
        let r = v.round();
        if (v - r).abs() > 0.0001 || r.abs() > 1e9 {
            return Err(self.err(
                b,
                letter,
                ErrorKind::BadValue,
                format!(
                    "{} value must be a whole number",
                    letter.to_ascii_uppercase() as char
                ),
            ));
        }
        Ok(r as i32)
    }

    /// Pocket of tool `t` (0 = no tool).
    fn find_pocket(&self, b: &Block, letter: u8, t: i32) -> Res<i32> {
        if t == 0 {
            return Ok(0);
        }
        match self.tools.get(t) {
            Some(tool) => Ok(tool.pocket),
            None => Err(self.err(
                b,
                letter,
                ErrorKind::BadValue,
                format!("tool {t} is not in the tool table"),
            )),
        }
    }

    fn m_codes(&mut self, b: &Block) -> Res<()> {
        let comp_on = self.state.cutter.is_some();
        // Group 5: I/O.
        let io = b.m[mg::IO];
        if io != -1 {
            if comp_on {
                return Err(self.m_err(
                    b,
                    mg::IO,
                    ErrorKind::State,
                    format!("M{io} is not allowed with cutter radius compensation on"),
                ));
            }
            match io {
                62..=65 => {
                    let Some(p) = b.get(b'p') else {
                        return Err(self.m_err(
                            b,
                            mg::IO,
                            ErrorKind::MissingWord,
                            format!("M{io} needs a P word (output number)"),
                        ));
                    };
                    let index = round_index(p);
                    self.emit(C::SetDigitalOutput {
                        index,
                        on: io == 62 || io == 64,
                        synchronized: io <= 63,
                    });
                }
                66 => self.m66(b)?,
                _ => {
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
                        value: b.get(b'q').unwrap_or(0.0),
                        synchronized: io == 67,
                    });
                }
            }
        }
        // Group 6: tool change.
        match b.m[mg::TOOL] {
            6 => {
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
            }
            61 => {
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
            }
            _ => {}
        }
        // Group 7: spindle and modal state save/restore.
        match b.m[mg::SPINDLE] {
            3 | 4 => {
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
            }
            5 => {
                self.state.spindle = None;
                self.emit(C::StopSpindle { spindle: 0 });
            }
            19 => {
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
            }
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
        // Group 8: coolant.
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
        // Group 9: overrides.
        let ov = b.m[mg::OVERRIDE];
        if ov != -1 {
            if comp_on {
                return Err(self.m_err(
                    b,
                    mg::OVERRIDE,
                    ErrorKind::State,
                    "cannot change overrides with cutter radius compensation on",
                ));
            }
            let on = b.get(b'p').unwrap_or(0.0) != 0.0;
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
        }
        // Group 10: user M codes, handed on to the machine logic.
        let user = b.m[mg::USER];
        if user != -1 {
            self.emit(C::UserMCode {
                code: user as u16,
                p: b.get(b'p'),
                q: b.get(b'q'),
            });
        }
        Ok(())
    }

    fn m66(&mut self, b: &Block) -> Res<()> {
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
        Ok(())
    }

    /// #5400.. from the tool now in the spindle.
    fn set_tool_params(&mut self) {
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

    fn g_codes(&mut self, b: &mut Block, motion: i32) -> Res<()> {
        let comp_on = self.state.cutter.is_some();
        if b.g[gg::NON_MODAL] == 40 {
            let p = b.get(b'p').unwrap_or(0.0);
            if p < 0.0 {
                return Err(self.err(b, b'p', ErrorKind::BadValue, "negative dwell time"));
            }
            self.emit(C::Dwell(p));
        }
        if b.g[gg::PLANE] != -1 {
            let plane = match b.g[gg::PLANE] {
                170 => Plane::XY,
                180 => Plane::XZ,
                190 => Plane::YZ,
                171 => Plane::UV,
                181 => Plane::WU,
                _ => Plane::VW,
            };
            if comp_on && plane != self.state.plane {
                return Err(self.g_err(
                    b,
                    gg::PLANE,
                    ErrorKind::State,
                    "cannot change planes with cutter radius compensation on",
                ));
            }
            self.emit(C::SelectPlane(plane));
            self.state.plane = plane;
        }
        if b.g[gg::UNITS] != -1 {
            let units = if b.g[gg::UNITS] == 200 {
                Units::Inches
            } else {
                Units::Mm
            };
            self.set_units(units);
        }
        if b.g[gg::LATHE] != -1 {
            let diameter = b.g[gg::LATHE] == 70;
            if diameter != self.state.lathe_diameter {
                self.emit(C::Comment(
                    if diameter {
                        "interpreter: Lathe diameter mode changed to diameter"
                    } else {
                        "interpreter: Lathe diameter mode changed to radius"
                    }
                    .into(),
                ));
                self.state.lathe_diameter = diameter;
            }
        }
        if self.state.lathe_diameter && b.has(b'x') {
            b.words[(b'x' - b'a') as usize] /= 2.0;
        }
        if b.g[gg::CUTTER] != -1 {
            self.cutter_comp(b)?;
        }
        if b.g[gg::LENGTH] != -1 {
            self.tool_length(b)?;
        }
        if b.g[gg::COORD] != -1 {
            if comp_on {
                return Err(self.g_err(
                    b,
                    gg::COORD,
                    ErrorKind::State,
                    "cannot change coordinate systems with cutter radius compensation on",
                ));
            }
            let index = match b.g[gg::COORD] {
                c @ 540..=590 => ((c - 540) / 10 + 1) as u8,
                c => (c - 591 + 7) as u8,
            };
            self.select_coord_system(index);
        }
        if b.g[gg::CONTROL] != -1 {
            if comp_on {
                return Err(self.g_err(
                    b,
                    gg::CONTROL,
                    ErrorKind::State,
                    "cannot change path control mode with cutter radius compensation on",
                ));
            }
            match b.g[gg::CONTROL] {
                610 => self.set_path_mode(PathMode::ExactPath, None),
                611 => self.set_path_mode(PathMode::ExactStop, None),
                _ => {
                    let p = b.get(b'p').filter(|p| *p >= 0.0).unwrap_or(0.0);
                    let q = b
                        .get(b'q')
                        .filter(|q| *q >= 0.0)
                        .or(b.get(b'p').filter(|p| *p >= 0.0))
                        .unwrap_or(0.0);
                    self.set_path_mode(PathMode::Continuous { tolerance: p }, Some(q));
                }
            }
        }
        if b.g[gg::DISTANCE] != -1 {
            let abs = b.g[gg::DISTANCE] == 900;
            if abs != self.state.absolute {
                self.emit(C::Comment(
                    if abs {
                        "interpreter: distance mode changed to absolute"
                    } else {
                        "interpreter: distance mode changed to incremental"
                    }
                    .into(),
                ));
                self.state.absolute = abs;
            }
        }
        if b.g[gg::IJK] != -1 {
            let abs = b.g[gg::IJK] == 901;
            if abs != self.state.ijk_absolute {
                self.emit(C::Comment(
                    if abs {
                        "interpreter: IJK distance mode changed to absolute"
                    } else {
                        "interpreter: IJK distance mode changed to incremental"
                    }
                    .into(),
                ));
                self.state.ijk_absolute = abs;
            }
        }
        if b.g[gg::RETRACT] != -1 {
            if comp_on {
                return Err(self.g_err(
                    b,
                    gg::RETRACT,
                    ErrorKind::State,
                    "cannot change retract mode with cutter radius compensation on",
                ));
            }
            let old_z = b.g[gg::RETRACT] == 980;
            self.emit(C::Comment(
                if old_z {
                    "interpreter: retract mode set to old_z"
                } else {
                    "interpreter: retract mode set to r_plane"
                }
                .into(),
            ));
            self.state.retract_old_z = old_z;
        }
        match b.g[gg::NON_MODAL] {
            100 => self.g10(b)?,
            280 | 300 => self.go_home(b)?,
            281 | 301 => {
                if comp_on {
                    return Err(self.g_err(
                        b,
                        gg::NON_MODAL,
                        ErrorKind::State,
                        "cannot set a reference point with cutter radius compensation on",
                    ));
                }
                let m = self.machine_position();
                let base = if b.g[gg::NON_MODAL] == 281 {
                    sys::G28
                } else {
                    sys::G30
                };
                self.pose_to_params(base, &m);
            }
            920..=923 => self.g92(b)?,
            520 => {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::UnknownWord,
                    "G52 is not supported: use G92 or G10 L2",
                ));
            }
            _ => {}
        }
        if motion != -1 {
            self.motion(b, motion)?;
        }
        Ok(())
    }

    pub(crate) fn set_units(&mut self, units: Units) {
        self.emit(C::UseLengthUnits(units));
        if units == self.state.units {
            return;
        }
        let f = self.state.units.mm_per_unit() / units.mm_per_unit();
        let scale = |p: &mut Pose| {
            p.x *= f;
            p.y *= f;
            p.z *= f;
            p.u *= f;
            p.v *= f;
            p.w *= f;
        };
        let s = &mut self.state;
        scale(&mut s.position);
        scale(&mut s.g5x);
        scale(&mut s.g92);
        scale(&mut s.tool_offset);
        s.units = units;
    }

    fn set_path_mode(&mut self, mode: PathMode, naive: Option<f64>) {
        self.emit(C::SetMotionControlMode(mode));
        self.state.path_mode = mode;
        if let Some(q) = naive {
            self.state.naivecam_tolerance = q;
            self.emit(C::SetNaivecamTolerance(q));
        }
    }

    fn cutter_comp(&mut self, b: &Block) -> Res<()> {
        let code = b.g[gg::CUTTER];
        if code == 400 {
            self.emit(C::StopCutterRadiusCompensation);
            self.state.cutter = None;
            self.state.cutter_gcode = 400;
            return Ok(());
        }
        if self.state.plane != Plane::XY && self.state.plane != Plane::XZ {
            return Err(self.g_err(
                b,
                gg::CUTTER,
                ErrorKind::State,
                "cutter radius compensation is allowed only in the XY and XZ planes",
            ));
        }
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::CUTTER,
                ErrorKind::State,
                "cutter radius compensation is already on (give G40 first)",
            ));
        }
        let mut side = if code == 410 || code == 411 {
            CompensationSide::Left
        } else {
            CompensationSide::Right
        };
        let (mut radius, orientation) = if code == 411 || code == 421 {
            let Some(d) = b.get(b'd') else {
                return Err(self.g_err(
                    b,
                    gg::CUTTER,
                    ErrorKind::MissingWord,
                    format!("G{} needs a D word (tool diameter)", fmt_code(code)),
                ));
            };
            let orientation = match b.get(b'l') {
                Some(l) => {
                    if self.state.plane != Plane::XZ {
                        return Err(self.err(
                            b,
                            b'l',
                            ErrorKind::State,
                            format!("G{} with an L word needs the G18 plane", fmt_code(code)),
                        ));
                    }
                    l.round() as i32
                }
                None => 0,
            };
            (d / 2.0, orientation)
        } else {
            let tool = match b.get(b'd') {
                Some(d) => {
                    let t = self.whole(b, b'd', d)?;
                    if t < 0 {
                        return Err(self.err(
                            b,
                            b'd',
                            ErrorKind::BadValue,
                            "negative D word (tool number)",
                        ));
                    }
                    t
                }
                None => self.state.current_tool,
            };
            let entry = if tool == 0 && b.get(b'd').is_none() {
                self.tools.get(self.state.current_tool).cloned()
            } else {
                if tool != 0 && self.tools.get(tool).is_none() {
                    return Err(self.err(
                        b,
                        b'd',
                        ErrorKind::BadValue,
                        format!("tool {tool} is not in the tool table"),
                    ));
                }
                self.tools.get(tool).cloned()
            };
            let (dia, orientation) = entry.map_or((0.0, 0), |t| (t.diameter, t.orientation));
            if self.state.plane != Plane::XZ && orientation != 0 && orientation != 9 {
                return Err(self.g_err(
                    b,
                    gg::CUTTER,
                    ErrorKind::State,
                    format!("G{} with a lathe tool needs the G18 plane", fmt_code(code)),
                ));
            }
            (self.user_to_program(dia) / 2.0, orientation)
        };
        if radius < 0.0 {
            radius = -radius;
            side = match side {
                CompensationSide::Left => CompensationSide::Right,
                CompensationSide::Right => CompensationSide::Left,
            };
        }
        self.emit(C::StartCutterRadiusCompensation {
            side,
            radius,
            orientation,
        });
        self.state.cutter = Some(side);
        self.state.cutter_gcode = code;
        Ok(())
    }

    fn tool_length(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::LENGTH,
                ErrorKind::State,
                "cannot change the tool length offset with cutter radius compensation on",
            ));
        }
        let code = b.g[gg::LENGTH];
        let new = match code {
            490 => Pose::ZERO,
            430 => {
                let tool = match b.get(b'h') {
                    Some(h) => {
                        let t = self.whole(b, b'h', h)?;
                        if t < 0 {
                            return Err(self.err(b, b'h', ErrorKind::BadValue, "negative H word"));
                        }
                        if t != 0 && self.tools.get(t).is_none() {
                            return Err(self.err(
                                b,
                                b'h',
                                ErrorKind::BadValue,
                                format!("tool {t} is not in the tool table"),
                            ));
                        }
                        t
                    }
                    None => self.state.current_tool,
                };
                let off = self
                    .tools
                    .get(tool)
                    .map_or(Pose::ZERO, |t| t.offset)
                    .to_array();
                let mut v = [0.0; 9];
                for i in 0..9 {
                    v[i] = if (3..6).contains(&i) {
                        off[i]
                    } else {
                        self.user_to_program(off[i])
                    };
                }
                Pose::from_array(v)
            }
            _ => {
                // G43.1: offsets given directly.
                let mut v = self.state.tool_offset.to_array();
                for (i, l) in AXES.iter().enumerate() {
                    if let Some(x) = b.get(*l) {
                        v[i] = x;
                    }
                }
                Pose::from_array(v)
            }
        };
        self.emit(C::UseToolLengthOffset(new));
        let old = self.state.tool_offset;
        let (dx, dy) = rotate(old.x - new.x, old.y - new.y, -self.state.rotation);
        let mut p = self.state.position.to_array();
        let (o, n) = (old.to_array(), new.to_array());
        for i in 2..9 {
            p[i] += o[i] - n[i];
        }
        p[0] += dx;
        p[1] += dy;
        self.state.position = Pose::from_array(p);
        self.state.tool_offset = new;
        self.state.length_gcode = code;
        Ok(())
    }

    fn select_coord_system(&mut self, index: u8) {
        if index == self.state.origin_index {
            self.emit(C::Comment(
                "interpreter: continuing to use same coordinate system".into(),
            ));
            return;
        }
        let machine = self.machine_position();
        self.state.origin_index = index;
        self.params.set(sys::COORD_SYSTEM, f64::from(index));
        self.state.g5x = self.coord_system_from_params(index);
        self.state.rotation = self.params.get(sys::G54 + 20 * usize::from(index - 1) + 9);
        self.state.position = self.program_from_machine(&machine);
        self.emit(C::SetG5xOffset {
            index,
            offset: self.state.g5x,
        });
        self.emit(C::SetG92Offset(self.state.g92));
        self.emit(C::SetXyRotation(self.state.rotation));
    }

    fn g10(&mut self, b: &Block) -> Res<()> {
        let Some(l) = b.get(b'l') else {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                "G10 needs an L word (L1, L2, L10, L11 or L20)",
            ));
        };
        let l = l.round() as i32;
        let p = b.get(b'p').unwrap_or(0.0);
        let p_int = p.round() as i32;
        if (p - f64::from(p_int)).abs() > 0.0002 {
            return Err(self.err(
                b,
                b'p',
                ErrorKind::BadValue,
                "P value not an integer with G10",
            ));
        }
        match l {
            2 | 20 => {
                if !(0..=9).contains(&p_int) {
                    return Err(self.err(
                        b,
                        b'p',
                        ErrorKind::BadValue,
                        format!("P value out of range (0-9) with G10 L{l}"),
                    ));
                }
                self.g10_coord(b, l, p_int as u8)
            }
            1 | 10 | 11 => {
                if p_int < 1 {
                    return Err(self.err(
                        b,
                        b'p',
                        ErrorKind::BadValue,
                        format!("P value out of range with G10 L{l}"),
                    ));
                }
                self.g10_tool(b, l, p_int)
            }
            _ => Err(self.err(
                b,
                b'l',
                ErrorKind::BadValue,
                "G10 needs L1, L2, L10, L11 or L20",
            )),
        }
    }

    fn g10_coord(&mut self, b: &Block, l: i32, p: u8) -> Res<()> {
        if b.has(b'i') || b.has(b'j') {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::UnusedWord,
                "I and J words are not allowed with G10 L2",
            ));
        }
        let index = if p == 0 { self.state.origin_index } else { p };
        if self.state.cutter.is_some() && index == self.state.origin_index {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot change the active coordinate system with cutter radius compensation on",
            ));
        }
        let base = sys::G54 + 20 * usize::from(index - 1);
        // Current position as seen in that system.
        let machine = self.machine_position();
        let mut cur = self.coord_system_from_params(index);
        let rot_p = self.params.get(base + 9);
        {
            let s = &self.state;
            let mut c = machine.to_array();
            let off = cur.to_array();
            let g92 = s.g92.to_array();
            let tool = s.tool_offset.to_array();
            for i in 0..9 {
                c[i] -= off[i] + tool[i];
            }
            let (x, y) = rotate(c[0], c[1], -rot_p);
            c[0] = x;
            c[1] = y;
            for i in 0..9 {
                c[i] -= g92[i];
            }
            cur = Pose::from_array(c);
        }
        let r = if let Some(r) = b.get(b'r') {
            if l == 20 {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::UnusedWord,
                    "R is not allowed in G10 L20",
                ));
            }
            self.params.set(base + 9, r);
            r
        } else {
            rot_p
        };
        let mut off = self.pose_from_params(base).to_array();
        let cur_a = cur.to_array();
        if l == 20 {
            let (mut x, mut y) = (cur.x, cur.y);
            if let Some(v) = b.get(b'x') {
                x = v;
            }
            if let Some(v) = b.get(b'y') {
                y = v;
            }
            let (ox, oy) = rotate(cur.x, cur.y, r);
            let (nx, ny) = rotate(x, y, r);
            off[0] += ox - nx;
            off[1] += oy - ny;
            for (i, letter) in AXES.iter().enumerate().skip(2) {
                if let Some(v) = b.get(*letter) {
                    off[i] += cur_a[i] - v;
                }
            }
        } else {
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    off[i] = v;
                }
            }
        }
        let off = Pose::from_array(off);
        self.pose_to_params(base, &off);
        if index == self.state.origin_index {
            let machine = self.machine_position();
            self.state.g5x = off;
            self.state.rotation = r;
            self.state.position = self.program_from_machine(&machine);
            self.emit(C::SetG5xOffset { index, offset: off });
            self.emit(C::SetXyRotation(r));
        } else {
            self.emit(C::Comment(
                "interpreter: setting coordinate system origin".into(),
            ));
        }
        Ok(())
    }

    fn g10_tool(&mut self, b: &Block, l: i32, tool_no: i32) -> Res<()> {
        let Some(existing) = self.tools.get(tool_no).cloned() else {
            return Err(self.err(
                b,
                b'p',
                ErrorKind::BadValue,
                format!("tool {tool_no} is not in the tool table"),
            ));
        };
        if !(b.has_axis() || b.has(b'r') || b.has(b'q') || b.has(b'i') || b.has(b'j')) {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                format!("G10 L{l} without offsets has no effect"),
            ));
        }
        let mut tool = existing;
        let mut off = tool.offset.to_array();
        if l == 1 {
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    off[i] = if (3..6).contains(&i) {
                        v
                    } else {
                        self.program_to_user(v)
                    };
                }
            }
        } else {
            // L10: offset such that the current point would read the given value with this
            // tool's offset in force; L11: the same in G59.3 (LinuxCNC's fixture system).
            let system = if l == 11 { 9 } else { self.state.origin_index };
            let base = sys::G54 + 20 * usize::from(system - 1);
            let sys_off = self.coord_system_from_params(system).to_array();
            let mut t = self.machine_position().to_array();
            for i in 0..9 {
                t[i] -= sys_off[i];
            }
            let (x, y) = rotate(t[0], t[1], -self.params.get(base + 9));
            t[0] = x;
            t[1] = y;
            if l == 10 && self.params.get(sys::G92_APPLIED) != 0.0 {
                let g92 = self.pose_from_params(sys::G92).to_array();
                for i in 0..9 {
                    t[i] -= g92[i];
                }
            }
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    let o = t[i] - v;
                    off[i] = if (3..6).contains(&i) {
                        o
                    } else {
                        self.program_to_user(o)
                    };
                }
            }
        }
        tool.offset = Pose::from_array(off);
        if let Some(r) = b.get(b'r') {
            tool.diameter = self.program_to_user(r * 2.0);
        }
        if let Some(i) = b.get(b'i') {
            tool.front_angle = i;
        }
        if let Some(j) = b.get(b'j') {
            tool.back_angle = j;
        }
        if let Some(q) = b.get(b'q') {
            tool.orientation = q.round() as i32;
        }
        let entry = ToolEntry {
            pocket: tool.pocket,
            tool: tool.number,
            offset: tool.offset,
            diameter: tool.diameter,
            front_angle: tool.front_angle,
            back_angle: tool.back_angle,
            orientation: tool.orientation,
        };
        let loaded = tool.pocket == self.state.current_pocket;
        self.tools.set(tool);
        self.emit(C::SetToolTableEntry(entry));
        if loaded {
            // The spindle's copy (pocket 0) changes too.
            self.emit(C::SetToolTableEntry(ToolEntry { pocket: 0, ..entry }));
        }
        if tool_no == self.state.current_tool {
            self.set_tool_params();
        }
        Ok(())
    }

    fn go_home(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot use G28 or G30 with cutter radius compensation on",
            ));
        }
        let mid = self.find_ends(b);
        self.emit(C::StraightTraverse(mid));
        self.state.position = mid;
        let base = if b.g[gg::NON_MODAL] == 280 {
            sys::G28
        } else {
            sys::G30
        };
        let home_machine = {
            let mut v = [0.0; 9];
            for (i, x) in v.iter_mut().enumerate() {
                let p = self.params.get(base + i);
                *x = if (3..6).contains(&i) {
                    p
                } else {
                    self.user_to_program(p)
                };
            }
            Pose::from_array(v)
        };
        let home = self.program_from_machine(&home_machine).to_array();
        let mut end = mid.to_array();
        let any = b.has_axis();
        for (i, letter) in AXES.iter().enumerate() {
            if !any || b.has(*letter) {
                end[i] = home[i];
            }
        }
        let end = Pose::from_array(end);
        self.emit(C::StraightTraverse(end));
        self.state.position = end;
        Ok(())
    }

    fn g92(&mut self, b: &Block) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::State,
                "cannot change axis offsets with cutter radius compensation on",
            ));
        }
        let code = b.g[gg::NON_MODAL];
        let mut pos = self.state.position.to_array();
        let mut off = self.state.g92.to_array();
        match code {
            920 => {
                self.params.set(sys::G92_APPLIED, 1.0);
                for (i, letter) in AXES.iter().enumerate() {
                    if let Some(v) = b.get(*letter) {
                        off[i] += pos[i] - v;
                        pos[i] = v;
                    }
                }
            }
            921 | 922 => {
                self.params.set(sys::G92_APPLIED, 0.0);
                for i in 0..9 {
                    pos[i] += off[i];
                    off[i] = 0.0;
                }
                if code == 921 {
                    for i in 0..9 {
                        self.params.set(sys::G92 + i, 0.0);
                    }
                }
            }
            _ => {
                self.params.set(sys::G92_APPLIED, 1.0);
                let saved = self.pose_from_params(sys::G92).to_array();
                for i in 0..9 {
                    pos[i] += off[i] - saved[i];
                }
                off = saved;
            }
        }
        self.state.position = Pose::from_array(pos);
        self.state.g92 = Pose::from_array(off);
        self.emit(C::SetG92Offset(self.state.g92));
        if code == 920 {
            let g92 = self.state.g92;
            self.pose_to_params(sys::G92, &g92);
        }
        Ok(())
    }

    /// End point of a move from the axis words (absolute, incremental, or G53 machine).
    pub(crate) fn find_ends(&self, b: &Block) -> Pose {
        let s = &self.state;
        let cur = s.position.to_array();
        let mut end = cur;
        if b.g[gg::NON_MODAL] == 530 {
            let m = self.machine_position().to_array();
            let mut target = m;
            for (i, letter) in AXES.iter().enumerate() {
                if let Some(v) = b.get(*letter) {
                    target[i] = v;
                }
            }
            let p = self
                .program_from_machine(&Pose::from_array(target))
                .to_array();
            for (i, letter) in AXES.iter().enumerate() {
                if b.has(*letter) {
                    end[i] = p[i];
                }
            }
            // X and Y change together through the rotation.
            if s.rotation != 0.0 && (b.has(b'x') || b.has(b'y')) {
                end[0] = p[0];
                end[1] = p[1];
            }
            return Pose::from_array(end);
        }
        for (i, letter) in AXES.iter().enumerate() {
            if let Some(v) = b.get(*letter) {
                end[i] = if s.absolute { v } else { cur[i] + v };
            }
        }
        Pose::from_array(end)
    }

    fn motion(&mut self, b: &Block, motion: i32) -> Res<()> {
        match motion {
            0 | 10 => self.straight(b, motion),
            20 | 30 => self.arc(b, motion),
            50 | 51 => self.spline(b, motion),
            382..=385 => self.probe(b, motion),
            800 => {
                self.emit(C::Comment("interpreter: motion mode set to none".into()));
                self.state.motion = 800;
                self.cycle.initial_level = None;
                Ok(())
            }
            _ => self.canned_cycle(b, motion),
        }
    }

    fn straight(&mut self, b: &Block, motion: i32) -> Res<()> {
        if motion == 10 {
            match self.state.feed_mode {
                FeedMode::UnitsPerMinute if self.state.feed_rate == 0.0 => {
                    return Err(self.g_err(
                        b,
                        gg::MOTION,
                        ErrorKind::State,
                        "cannot do G1 with zero feed rate",
                    ));
                }
                FeedMode::UnitsPerRevolution => {
                    if self.state.feed_rate == 0.0 {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::State,
                            "cannot do G1 with zero feed rate",
                        ));
                    }
                    if self.state.speed == 0.0 {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::State,
                            "cannot feed with zero spindle speed in feed per revolution mode (G95)",
                        ));
                    }
                }
                FeedMode::InverseTime if !b.has(b'f') => {
                    return Err(self.g_err(
                        b,
                        gg::MOTION,
                        ErrorKind::MissingWord,
                        "F word missing with inverse time (G93) G1 move",
                    ));
                }
                _ => {}
            }
        }
        if self.state.motion != motion {
            self.cycle.initial_level = None;
        }
        self.state.motion = motion;
        let end = self.find_ends(b);
        if motion == 10 && self.state.feed_mode == FeedMode::InverseTime {
            let length = straight_length(&self.state.position, &end);
            let rate = (length * b.get(b'f').unwrap_or(0.0)).max(0.1);
            self.state.feed_rate = rate;
            self.emit(C::SetFeedRate(rate));
        }
        self.emit(if motion == 0 {
            C::StraightTraverse(end)
        } else {
            C::StraightFeed(end)
        });
        self.state.position = end;
        Ok(())
    }

    fn arc(&mut self, b: &Block, motion: i32) -> Res<()> {
        let s = &self.state;
        // Plane axes: first, second, normal (indices into the pose), and the IJK letters.
        let (a1, a2, a3, l1, l2, n1, n2) = match s.plane {
            Plane::XY => (0, 1, 2, b'x', b'y', b'i', b'j'),
            Plane::XZ => (2, 0, 1, b'z', b'x', b'k', b'i'),
            Plane::YZ => (1, 2, 0, b'y', b'z', b'j', b'k'),
            _ => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::State,
                    "arcs are not supported in the UV, UW and VW planes",
                ));
            }
        };
        let wrong_offset = match s.plane {
            Plane::XY => b'k',
            Plane::XZ => b'j',
            _ => b'i',
        };
        let r_word = b.get(b'r');
        if r_word.is_some() {
            if b.has(b'i') || b.has(b'j') || b.has(b'k') {
                return Err(self.err(
                    b,
                    b'r',
                    ErrorKind::Conflict,
                    "arc given with both R and I/J/K (mixed radius and centre format)",
                ));
            }
        } else {
            if !b.has(b'i') && !b.has(b'j') && !b.has(b'k') {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "R, I, J and K words all missing for the arc",
                ));
            }
            if b.has(wrong_offset) {
                return Err(self.err(
                    b,
                    wrong_offset,
                    ErrorKind::UnusedWord,
                    format!(
                        "{} word given for an arc in this plane",
                        wrong_offset.to_ascii_uppercase() as char
                    ),
                ));
            }
            if s.ijk_absolute {
                for n in [n1, n2] {
                    if !b.has(n) {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::MissingWord,
                            format!(
                                "{} word missing in absolute centre arc (G90.1)",
                                n.to_ascii_uppercase() as char
                            ),
                        ));
                    }
                }
            }
        }
        match s.feed_mode {
            FeedMode::InverseTime if !b.has(b'f') => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "F word missing with inverse time (G93) arc move",
                ));
            }
            FeedMode::InverseTime => {}
            _ if s.feed_rate == 0.0 => {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::State,
                    "cannot make an arc with zero feed rate",
                ));
            }
            _ => {}
        }
        if s.motion != motion {
            self.cycle.initial_level = None;
        }
        self.state.motion = motion;
        let end = self.find_ends(b);
        let cur = self.state.position.to_array();
        let e = end.to_array();
        let (c1, c2) = (cur[a1], cur[a2]);
        let (e1, e2) = (e[a1], e[a2]);
        let turns = b.get(b'p').map_or(1, |p| p.round() as i32);
        let rotation = if motion == 20 { -turns } else { turns };
        let inch = self.state.units == Units::Inches;
        let (center1, center2) = if let Some(r) = r_word {
            let tol = if inch {
                RADIUS_TOLERANCE_INCH
            } else {
                RADIUS_TOLERANCE_INCH * 25.4
            };
            if e1 == c1 && e2 == c2 {
                return Err(self.err(b, b'r', ErrorKind::Arc, "current point same as end point of arc: an R-format arc needs distinct end points"));
            }
            let abs_r = r.abs();
            let (m1, m2) = ((e1 + c1) / 2.0, (e2 + c2) / 2.0);
            let mut half = (m1 - e1).hypot(m2 - e2);
            if half - abs_r > tol {
                return Err(self.err(b, b'r', ErrorKind::Arc, format!("arc radius {abs_r} too small to reach the end point (half the chord is {half:.4})")));
            }
            if half / abs_r > 1.0 - 1e-12 {
                half = abs_r;
            }
            let theta = (e2 - c2).atan2(e1 - c1)
                + if (motion == 20 && r > 0.0) || (motion == 30 && r < 0.0) {
                    -std::f64::consts::FRAC_PI_2
                } else {
                    std::f64::consts::FRAC_PI_2
                };
            let turn2 = (half / abs_r).asin();
            let offset = abs_r * turn2.cos();
            (m1 + offset * theta.cos(), m2 + offset * theta.sin())
        } else {
            let o1 = b.get(n1).unwrap_or(0.0);
            let o2 = b.get(n2).unwrap_or(0.0);
            let (cc1, cc2) = if self.state.ijk_absolute {
                let mut o1 = o1;
                if self.state.lathe_diameter && n1 == b'i' {
                    o1 /= 1.0;
                }
                (o1, o2)
            } else {
                (c1 + o1, c2 + o2)
            };
            let r1 = (cc1 - c1).hypot(cc2 - c2);
            let r2 = (cc1 - e1).hypot(cc2 - e2);
            let min_r = if inch {
                RADIUS_TOLERANCE_INCH
            } else {
                RADIUS_TOLERANCE_INCH * 25.4
            };
            let (n1c, n2c) = (
                l1.to_ascii_uppercase() as char,
                l2.to_ascii_uppercase() as char,
            );
            if r1 < min_r || r2 < min_r {
                return Err(self.g_err(b, gg::MOTION, ErrorKind::Arc, format!(
                    "zero-radius arc: start=({n1c}{c1:.4},{n2c}{c2:.4}) center=({n1c}{cc1:.4},{n2c}{cc2:.4}) end=({n1c}{e1:.4},{n2c}{e2:.4}) r1={r1:.4} r2={r2:.4}"
                )));
            }
            let spiral_abs = if inch {
                self.settings.arc_radius_tolerance_inch
            } else {
                self.settings.arc_radius_tolerance_mm
            };
            let abs_err = (r1 - r2).abs();
            let rel_err = abs_err / r1.max(r2);
            if abs_err > spiral_abs * 100.0
                || (rel_err > SPIRAL_RELATIVE_TOLERANCE && abs_err > spiral_abs)
            {
                return Err(self.g_err(b, gg::MOTION, ErrorKind::Arc, format!(
                    "radius to end of arc differs from radius to start: start=({n1c}{c1:.4},{n2c}{c2:.4}) center=({n1c}{cc1:.4},{n2c}{cc2:.4}) end=({n1c}{e1:.4},{n2c}{e2:.4}) r1={r1:.4} r2={r2:.4} abs_err={abs_err:.4} rel_err={:.4}%",
                    rel_err * 100.0
                )));
            }
            (cc1, cc2)
        };
        if self.state.feed_mode == FeedMode::InverseTime {
            let length = arc_length(c1, c2, cur[a3], center1, center2, rotation, e1, e2, e[a3]);
            let rate = (length * b.get(b'f').unwrap_or(0.0)).max(0.1);
            self.state.feed_rate = rate;
            self.emit(C::SetFeedRate(rate));
        }
        self.emit(C::ArcFeed(Arc {
            first_end: e1,
            second_end: e2,
            first_axis: center1,
            second_axis: center2,
            rotation,
            axis_end_point: e[a3],
            a: end.a,
            b: end.b,
            c: end.c,
            u: end.u,
            v: end.v,
            w: end.w,
        }));
        self.state.position = end;
        Ok(())
    }

    fn spline(&mut self, b: &Block, motion: i32) -> Res<()> {
        if self.state.plane != Plane::XY {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "G5 and G5.1 need the XY plane (G17)",
            ));
        }
        if self.state.feed_rate == 0.0 && self.state.feed_mode != FeedMode::InverseTime {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot make a spline with zero feed rate",
            ));
        }
        let start = self.state.position;
        self.state.motion = motion;
        let end = self.find_ends(b);
        let spline = if motion == 50 {
            let ij = match (b.get(b'i'), b.get(b'j')) {
                (None, None) => match self.spline_last_pq {
                    Some(pq) => [-pq[0], -pq[1]],
                    None => {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::MissingWord,
                            "the first G5 of a spline needs I and J",
                        ));
                    }
                },
                (i, j) => {
                    if i.is_none() || j.is_none() {
                        return Err(self.g_err(
                            b,
                            gg::MOTION,
                            ErrorKind::MissingWord,
                            "G5 needs both I and J",
                        ));
                    }
                    [i.unwrap_or(0.0), j.unwrap_or(0.0)]
                }
            };
            let (Some(p), Some(q)) = (b.get(b'p'), b.get(b'q')) else {
                return Err(self.g_err(b, gg::MOTION, ErrorKind::MissingWord, "G5 needs P and Q"));
            };
            self.spline_last_pq = Some([p, q]);
            Spline {
                order: 4,
                p1: [start.x + ij[0], start.y + ij[1]],
                p2: [end.x + p, end.y + q],
                end: [end.x, end.y],
            }
        } else {
            let (Some(i), Some(j)) = (b.get(b'i'), b.get(b'j')) else {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "G5.1 needs I and J",
                ));
            };
            self.spline_last_pq = None;
            let p1 = [start.x + i, start.y + j];
            Spline {
                order: 3,
                p1,
                p2: p1,
                end: [end.x, end.y],
            }
        };
        self.emit(C::SplineFeed(spline));
        self.state.position = end;
        Ok(())
    }

    fn probe(&mut self, b: &Block, motion: i32) -> Res<()> {
        if self.state.cutter.is_some() {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe with cutter radius compensation on",
            ));
        }
        if self.state.feed_rate == 0.0 {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe with zero feed rate",
            ));
        }
        if self.state.feed_mode == FeedMode::UnitsPerRevolution {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::State,
                "cannot probe in feed per revolution mode (G95)",
            ));
        }
        let end = self.find_ends(b);
        let kind = match motion {
            382 => ProbeKind::TowardError,
            383 => ProbeKind::Toward,
            384 => ProbeKind::AwayError,
            _ => ProbeKind::Away,
        };
        let cur = self.state.position;
        if matches!(kind, ProbeKind::TowardError | ProbeKind::AwayError) && cur == end {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::BadValue,
                "start point too close to probe point",
            ));
        }
        self.emit(C::TurnProbeOn);
        self.emit(C::StraightProbe { end, kind });
        self.emit(C::TurnProbeOff);
        self.state.motion = motion;
        self.cycle.initial_level = None;
        // Without a machine the probe result is the programmed end (not tripped, #5070 = 0)
        // and the tool backs off a little from it, as LinuxCNC's stand-alone interpreter
        // models it; a machine reports the real result with `set_probe_result`.
        for (i, v) in end.to_array().iter().enumerate() {
            self.params.set(sys::PROBE + i, *v);
        }
        self.params.set(sys::PROBE_OK, 0.0);
        let (dx, dy, dz) = (cur.x - end.x, cur.y - end.y, cur.z - end.z);
        let dist = (dx * dx + dy * dy + dz * dz).sqrt();
        let mut after = end;
        if dist != 0.0 {
            let backoff = if self.state.units == Units::Mm {
                0.254
            } else {
                0.01
            };
            after.x = end.x + backoff * dx / dist;
            after.y = end.y + backoff * dy / dist;
            after.z = end.z + backoff * dz / dist;
        }
        self.state.position = after;
        self.probe_pending = true;
        Ok(())
    }

    fn stop(&mut self, b: &Block) -> Res<bool> {
        match b.m[mg::STOP] {
            0 => self.emit(C::ProgramStop),
            1 => self.emit(C::OptionalProgramStop),
            60 => {
                self.emit(C::PalletShuttle);
                self.emit(C::ProgramStop);
            }
            99 if self.m99()? => return Ok(true),
            code => {
                self.program_end_reset();
                if code == 30 {
                    self.emit(C::PalletShuttle);
                }
                self.emit(C::ProgramEnd);
                return Ok(false);
            }
        }
        Ok(true)
    }

    /// The resets of M2 / M30: G54 back in force, XY plane, absolute, units per minute,
    /// feed override on, compensation off, spindle off, G1, coolant off.
    fn program_end_reset(&mut self) {
        let machine = self.machine_position();
        self.state.origin_index = 1;
        self.params.set(sys::COORD_SYSTEM, 1.0);
        self.state.g5x = self.coord_system_from_params(1);
        self.state.rotation = self.params.get(sys::G54 + 9);
        self.state.position = self.program_from_machine(&machine);
        self.emit(C::SetG5xOffset {
            index: 1,
            offset: self.state.g5x,
        });
        self.emit(C::SetXyRotation(self.state.rotation));
        if self.state.plane != Plane::XY {
            self.emit(C::SelectPlane(Plane::XY));
            self.state.plane = Plane::XY;
        }
        self.state.absolute = true;
        self.state.feed_mode = FeedMode::UnitsPerMinute;
        self.emit(C::SetFeedMode {
            spindle: 0,
            mode: FeedMode::UnitsPerMinute,
        });
        self.state.feed_rate = self.block_f();
        self.emit(C::SetFeedRate(0.0));
        if !self.state.feed_override {
            self.emit(C::FeedOverride(true));
            self.state.feed_override = true;
        }
        self.state.cutter = None;
        self.state.cutter_gcode = 400;
        self.emit(C::StopSpindle { spindle: 0 });
        self.state.spindle = None;
        self.state.speed_override = true;
        self.emit(C::SetSpindleMode {
            spindle: 0,
            max_rpm: 0.0,
            constant_surface_speed: false,
        });
        self.state.css = false;
        self.state.motion = 10;
        if self.state.mist {
            self.emit(C::MistOff);
            self.state.mist = false;
        }
        if self.state.flood {
            self.emit(C::FloodOff);
            self.state.flood = false;
        }
    }

    fn block_f(&self) -> f64 {
        0.0
    }

    /// M72 (or return from a subroutine after M73): bring back a saved modal state the way
    /// LinuxCNC does it, by executing the codes that differ: units first, then one block
    /// with F, S and the G codes, then the M codes one per block.
    pub(crate) fn restore_state(&mut self, saved: &ModalState) -> Res<()> {
        use std::fmt::Write;
        let cur = self.state.clone();
        if saved.units != cur.units {
            self.execute_text(if saved.units == Units::Inches {
                "G20"
            } else {
                "G21"
            })?;
        }
        let mut cmd = String::new();
        if saved.feed_rate != cur.feed_rate {
            let _ = write!(cmd, " F{:.1}", saved.feed_rate);
        }
        if saved.speed != cur.speed {
            let _ = write!(cmd, " S{:.0}", saved.speed);
        }
        let plane = |p: Plane| match p {
            Plane::XY => "G17",
            Plane::XZ => "G18",
            Plane::YZ => "G19",
            Plane::UV => "G17.1",
            Plane::WU => "G18.1",
            Plane::VW => "G19.1",
        };
        if saved.plane != cur.plane {
            let _ = write!(cmd, " {}", plane(saved.plane));
        }
        if saved.cutter_gcode != cur.cutter_gcode {
            let _ = write!(cmd, " G{}", fmt_code(saved.cutter_gcode));
        }
        if saved.absolute != cur.absolute {
            cmd.push_str(if saved.absolute { " G90" } else { " G91" });
        }
        if saved.feed_mode != cur.feed_mode {
            cmd.push_str(match saved.feed_mode {
                FeedMode::InverseTime => " G93",
                FeedMode::UnitsPerMinute => " G94",
                FeedMode::UnitsPerRevolution => " G95",
            });
        }
        if saved.origin_index != cur.origin_index {
            let code = match saved.origin_index {
                i @ 1..=6 => 530 + 10 * i32::from(i),
                i => 590 + i32::from(i) - 6,
            };
            let _ = write!(cmd, " G{}", fmt_code(code));
        }
        if saved.length_gcode != cur.length_gcode {
            let _ = write!(cmd, " G{}", fmt_code(saved.length_gcode));
        }
        if saved.retract_old_z != cur.retract_old_z {
            cmd.push_str(if saved.retract_old_z { " G98" } else { " G99" });
        }
        if saved.css != cur.css {
            cmd.push_str(if saved.css { " G96" } else { " G97" });
        }
        if saved.ijk_absolute != cur.ijk_absolute {
            cmd.push_str(if saved.ijk_absolute {
                " G90.1"
            } else {
                " G91.1"
            });
        }
        if saved.lathe_diameter != cur.lathe_diameter {
            cmd.push_str(if saved.lathe_diameter { " G7" } else { " G8" });
        }
        match (saved.path_mode, cur.path_mode) {
            (a, b) if a == b && saved.naivecam_tolerance == cur.naivecam_tolerance => {}
            (PathMode::ExactPath, _) => cmd.push_str(" G61"),
            (PathMode::ExactStop, _) => cmd.push_str(" G61.1"),
            (PathMode::Continuous { tolerance }, _) => {
                let _ = write!(cmd, " G64 P{tolerance:.6} Q{:.6}", saved.naivecam_tolerance);
            }
        }
        if !cmd.is_empty() {
            self.execute_text(&cmd)?;
        }
        if saved.spindle != cur.spindle {
            self.execute_text(match saved.spindle {
                Some(SpindleDirection::Clockwise) => "M3",
                Some(SpindleDirection::CounterClockwise) => "M4",
                None => "M5",
            })?;
        }
        if saved.mist != cur.mist {
            self.execute_text(if saved.mist { "M7" } else { "M9" })?;
        }
        if saved.flood != cur.flood {
            self.execute_text(if saved.flood { "M8" } else { "M9" })?;
        }
        if saved.feed_override != cur.feed_override {
            self.execute_text(if saved.feed_override { "M48" } else { "M49" })?;
        }
        Ok(())
    }

    /// Executes a block given as text (used to restore modal state).
    fn execute_text(&mut self, text: &str) -> Res<()> {
        let mut b = Block::default();
        if let Err(e) = crate::block::read_block(text.as_bytes(), &*self, &mut b) {
            return Err(self.error_at(e.kind, 0, format!("restoring state: {}", e.message)));
        }
        self.execute(&mut b).map(|_| ())
    }
}

fn round_index(v: f64) -> u32 {
    let r = v.round();
    if r <= 0.0 {
        0
    } else {
        r.min(f64::from(u32::MAX)) as u32
    }
}

/// Length of a straight move for inverse time feed: XYZ(UVW) distance, or the rotary
/// distance when only rotary axes move.
fn straight_length(a: &Pose, b: &Pose) -> f64 {
    let d = |x: f64, y: f64| (x - y) * (x - y);
    let lin = d(a.x, b.x) + d(a.y, b.y) + d(a.z, b.z) + d(a.u, b.u) + d(a.v, b.v) + d(a.w, b.w);
    if lin > 0.0 {
        lin.sqrt()
    } else {
        (d(a.a, b.a) + d(a.b, b.b) + d(a.c, b.c)).sqrt()
    }
}

/// Length of a helical arc (LinuxCNC's find_arc_length).
#[allow(clippy::too_many_arguments)]
fn arc_length(
    x1: f64,
    y1: f64,
    z1: f64,
    cx: f64,
    cy: f64,
    turn: i32,
    x2: f64,
    y2: f64,
    z2: f64,
) -> f64 {
    let radius = (cx - x1).hypot(cy - y1);
    let theta = find_turn(x1, y1, cx, cy, turn, x2, y2);
    if z2 == z1 {
        radius * theta.abs()
    } else {
        (radius * theta).hypot(z2 - z1)
    }
}

fn find_turn(x1: f64, y1: f64, cx: f64, cy: f64, turn: i32, x2: f64, y2: f64) -> f64 {
    use std::f64::consts::TAU;
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = (y1 - cy).atan2(x1 - cx);
    let mut beta = (y2 - cy).atan2(x2 - cx);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(turn - 1) * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(turn + 1) * TAU
    }
}
