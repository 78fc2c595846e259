//! Executing one block in the RS274/NGC order of execution: comment, feed mode, F, S, T,
//! I/O, tool change, spindle, state save/restore, coolant, overrides, user M codes, dwell,
//! plane, units, lathe mode, cutter compensation, tool length offset, coordinate system,
//! path mode, distance modes, retract mode, G10/G28/G30/G92, motion, stop.

use crate::block::{AXES, Block, CommentKind as Comment, fmt_code, gg, mg};
use crate::canon::{CanonCommand as C, FeedMode, PathMode, Plane, Pose, Units};
use crate::error::{ErrorKind, GcodeError};
use crate::interp::{Interpreter, rotate, substitute};
use crate::params::sys;

type Res<T> = Result<T, GcodeError>;

impl Interpreter {
    pub(crate) fn err(
        &self,
        b: &Block,
        letter: u8,
        kind: ErrorKind,
        msg: impl Into<String>,
    ) -> GcodeError {
        let col = if letter.is_ascii_lowercase() && b.has(letter) {
            b.column(letter) + 1
        } else {
            0
        };
        self.error_at(kind, col, msg)
    }

    pub(crate) fn g_err(
        &self,
        b: &Block,
        group: usize,
        kind: ErrorKind,
        msg: impl Into<String>,
    ) -> GcodeError {
        self.error_at(kind, usize::from(b.g_col[group]) + 1, msg)
    }

    pub(crate) fn m_err(
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
            self.comment(b)?;
        }
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
        if b.m[mg::TOOL] != -1 {
            self.resync_position();
        }
        if b.m[mg::STOP] != -1 {
            return self.stop(b);
        }
        Ok(true)
    }

    /// After M6 or M61 LinuxCNC stops reading ahead and takes its position back from
    /// the motion controller, whose end point has not moved since the last move: a tool
    /// length offset changed since then has not shifted it. The program position follows,
    /// so such an offset shows on the next move instead.
    fn resync_position(&mut self) {
        let new = self.state.tool_offset;
        let old = self.tool_at_last_move;
        if new != old {
            let (dx, dy) = rotate(new.x - old.x, new.y - old.y, -self.state.rotation);
            let mut p = self.state.position.to_array();
            let (o, n) = (old.to_array(), new.to_array());
            for i in 2..9 {
                p[i] += n[i] - o[i];
            }
            p[0] += dx;
            p[1] += dy;
            self.state.position = Pose::from_array(p);
        }
        self.tool_at_last_move = new;
    }

    /// Which motion the block makes (tenths), or -1 for none; with the axis-word checks of
    /// RS274/NGC.
    pub(crate) fn motion_to_be(&self, b: &Block) -> Res<i32> {
        if !b.has_polar() {
            return self.motion_of_words(b, b.has_axis());
        }
        let col = usize::from(b.polar_col) + 1;
        if self.state.plane != Plane::XY {
            return Err(self.error_at(
                ErrorKind::State,
                col,
                "polar coordinates (@, ^) can only be used in the G17 plane",
            ));
        }
        if b.has(b'x') || b.has(b'y') {
            return Err(self.error_at(
                ErrorKind::Conflict,
                col,
                "X or Y words cannot be given with polar coordinates",
            ));
        }
        if b.g[gg::NON_MODAL] == 530 {
            return Err(self.error_at(
                ErrorKind::Conflict,
                col,
                "polar coordinates cannot be used with G53",
            ));
        }
        if b.g[gg::NON_MODAL] != -1 && b.g[gg::NON_MODAL] != 40 {
            return Err(self.error_at(
                ErrorKind::UnusedWord,
                col,
                "polar coordinates can only be used for motion",
            ));
        }
        let motion = self.motion_of_words(b, true)?;
        if motion == -1 {
            return Err(self.error_at(
                ErrorKind::UnusedWord,
                col,
                "polar coordinates can only be used for motion",
            ));
        }
        Ok(motion)
    }

    fn motion_of_words(&self, b: &Block, axis: bool) -> Res<i32> {
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
                if !axis && matches!(mode0, 520 | 920) {
                    return Err(self.g_err(
                        b,
                        gg::NON_MODAL,
                        ErrorKind::MissingWord,
                        "G52 and G92 need at least one axis word",
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
            if !axis && !matches!(mode1, 0 | 10 | 20 | 30 | 52 | 700 | 710..=712 | 720..=722) {
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
            if !axis && matches!(mode0, 520 | 920) {
                return Err(self.g_err(
                    b,
                    gg::NON_MODAL,
                    ErrorKind::MissingWord,
                    "G52 and G92 need at least one axis word",
                ));
            }
            return Ok(-1);
        }
        if axis {
            // -1: no motion mode after a NURBS block (G5.3), as in LinuxCNC.
            if matches!(self.state.motion, 800 | -1) && !matches!(b.g[gg::LENGTH], 431 | 432) {
                let first = AXES.iter().find(|c| b.has(**c)).copied().unwrap_or(b'x');
                return Err(self.err(
                    b,
                    first,
                    ErrorKind::UnusedWord,
                    "axis word with no motion mode in effect (after G80 or G5.3): give G0, G1, ... first",
                ));
            }
            if matches!(b.g[gg::LENGTH], 431 | 432) {
                return Ok(-1);
            }
            return Ok(self.state.motion);
        }
        if (b.has(b'i') || b.has(b'j') || b.has(b'k')) && matches!(self.state.motion, 20 | 30) {
            return Ok(self.state.motion);
        }
        Ok(-1)
    }

    /// Refuses a block whose codes lack a word they need, or that has a word nothing on it
    /// uses, with rs274's message; the checks run in rs274's order, so the first refusal is
    /// the one it reports.
    pub(crate) fn check_words(&self, b: &Block, motion: i32) -> Res<()> {
        let on = WordUsers::of(b, motion);
        self.check_code_combinations(b, &on)?;
        self.check_letter_words(b, &on)?;
        self.check_p_word(b, &on)?;
        self.check_q_word(b, &on)?;
        self.check_r_word(b, &on)?;
        self.check_required_words(b, motion)?;
        self.check_dollar_word(b, motion)
    }

    /// G4 without P, G5.3 beside another motion, U or W on a lathe cycle, G53 outside G0/G1
    /// or in G91.
    fn check_code_combinations(&self, b: &Block, on: &WordUsers) -> Res<()> {
        let (mode0, motion, lathe_cycle) = (on.mode0, on.motion, on.lathe_cycle);
        if mode0 == 40 && !b.has(b'p') {
            return Err(self.g_err(
                b,
                gg::NON_MODAL,
                ErrorKind::MissingWord,
                "G4 needs a P word (seconds)",
            ));
        }
        if mode0 == 53 && b.g[gg::MOTION] != -1 && b.g[gg::MOTION] != 52 {
            return Err(self.g_err(
                b,
                gg::MOTION,
                ErrorKind::Conflict,
                "only G5.2 may be on a line with G5.3",
            ));
        }
        if lathe_cycle {
            // LinuxCNC 2.9 reads U and W on these lines as finishing allowances of a
            // machine with U and W axes only; rs274 refuses them.
            for l in [b'u', b'w'] {
                if b.has(l) {
                    return Err(self.err(
                        b,
                        l,
                        ErrorKind::UnusedWord,
                        format!(
                            "a {} word cannot be used with G{}",
                            l.to_ascii_uppercase() as char,
                            fmt_code(motion)
                        ),
                    ));
                }
            }
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
        Ok(())
    }

    /// A, B, C in a canned cycle; D, E, H, I, J, K, L with nothing on the block to use them.
    fn check_letter_words(&self, b: &Block, on: &WordUsers) -> Res<()> {
        let (motion, cycle, lathe_cycle, roughing, g10) =
            (on.motion, on.cycle, on.lathe_cycle, on.roughing, on.g10);
        let m = |g: usize, v: i32| b.m[g] == v;
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
            && !lathe_cycle
        {
            return Err(self.err(
                b,
                b'd',
                ErrorKind::UnusedWord,
                "D word with no G41, G41.1, G42, G42.1, G70, G71, G72 or G96 to use it",
            ));
        }
        if b.has(b'e')
            && !(motion == 760 || motion == 700 || m(mg::IO, 66) || m(mg::IO, 67) || m(mg::IO, 68))
        {
            return Err(self.err(
                b,
                b'e',
                ErrorKind::UnusedWord,
                "E word with no G70, G76, M66, M67 or M68 to use it",
            ));
        }
        if b.has(b'h') && !matches!(b.g[gg::LENGTH], 430 | 432) && motion != 760 {
            return Err(self.err(
                b,
                b'h',
                ErrorKind::UnusedWord,
                "H word with no G43 or G43.2 to use it",
            ));
        }
        if b.has(b'i')
            && !(matches!(motion, 20 | 30 | 50 | 51 | 331 | 760 | 870) || g10 || roughing)
        {
            return Err(self.err(
                b,
                b'i',
                ErrorKind::UnusedWord,
                "I word with no G2, G3, G5, G5.1, G10, G71, G72 or G87 to use it",
            ));
        }
        if b.has(b'j') && !(matches!(motion, 20 | 30 | 50 | 51 | 760 | 870) || g10) {
            return Err(self.err(
                b,
                b'j',
                ErrorKind::UnusedWord,
                "J word with no G2, G3, G5, G5.1, G10 or G87 to use it",
            ));
        }
        if b.has(b'k') && !matches!(motion, 20 | 30 | 330 | 331 | 760 | 870) {
            return Err(self.err(
                b,
                b'k',
                ErrorKind::UnusedWord,
                "K word with no G2, G3 or G87 to use it",
            ));
        }
        // As in LinuxCNC, G74 takes no L word (the other canned cycles do).
        if b.has(b'l')
            && !((cycle && motion != 740)
                || motion == 760
                || motion == 52
                || g10
                || matches!(b.g[gg::CUTTER], 410 | 420 | 411 | 421)
                || m(mg::IO, 66)
                || b.m98)
        {
            return Err(self.err(
                b,
                b'l',
                ErrorKind::UnusedWord,
                "L word with no G10, cutter compensation, canned cycle (but G74), G5.2, M66 or M98 to use it",
            ));
        }
        Ok(())
    }

    /// P with nothing to use it, or a P value M19, G2 or G3 cannot take.
    fn check_p_word(&self, b: &Block, on: &WordUsers) -> Res<()> {
        let (mode0, motion, g10, user_m) = (on.mode0, on.motion, on.g10, on.user_m);
        let m = |g: usize, v: i32| b.m[g] == v;
        if let Some(p) = b.get(b'p') {
            let ok = g10
                || mode0 == 40
                || b.g[gg::CONTROL] == 640
                || matches!(
                    motion,
                    820 | 860 | 880 | 890 | 50 | 52 | 20 | 30 | 700 | 740 | 840 | 760
                )
                || matches!(b.m[mg::OVERRIDE], 50..=53)
                || matches!(b.m[mg::IO], 62..=66)
                || m(mg::SPINDLE, 19)
                || user_m
                || b.m98;
            if !ok {
                return Err(self.err(b, b'p', ErrorKind::UnusedWord, "P word with no G2 G3 G4 G5 G5.2 G10 G64 G70 G74 G82 G84 G86 G88 G89, M50-M53, M62-M66, M19, M98 or user M code to use it"));
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
        Ok(())
    }

    /// Q with nothing to use it.
    fn check_q_word(&self, b: &Block, on: &WordUsers) -> Res<()> {
        let (motion, lathe_cycle, g10, user_m) = (on.motion, on.lathe_cycle, on.g10, on.user_m);
        let m = |g: usize, v: i32| b.m[g] == v;
        if b.has(b'q') {
            let ok = matches!(motion, 830 | 730 | 50 | 760)
                || lathe_cycle
                || user_m
                || matches!(b.m[mg::IO], 66..=68)
                || g10
                || m(mg::TOOL, 61)
                || b.g[gg::CONTROL] == 640
                || m(mg::SPINDLE, 19);
            if !ok {
                return Err(self.err(b, b'q', ErrorKind::UnusedWord, "Q word with no G5, G10, G64, G70, G71, G72, G73, G83, M19, M61, M66, M67, M68 or user M code that uses it"));
            }
        }
        Ok(())
    }

    /// R with nothing to use it, or an angle M19 cannot take.
    fn check_r_word(&self, b: &Block, on: &WordUsers) -> Res<()> {
        let (motion, cycle, roughing, g10) = (on.motion, on.cycle, on.roughing, on.g10);
        let m = |g: usize, v: i32| b.m[g] == v;
        if let Some(r) = b.get(b'r') {
            let ok = matches!(motion, 20 | 30 | 760)
                || cycle
                || roughing
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
        Ok(())
    }

    /// The words G33, G33.1, G76 and G96 cannot go without (and G33's refusal of F).
    fn check_required_words(&self, b: &Block, motion: i32) -> Res<()> {
        if motion == 330 || motion == 331 {
            if !b.has(b'k') {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "G33 and G33.1 need a K word (pitch)",
                ));
            }
            if b.has(b'f') {
                return Err(self.err(
                    b,
                    b'f',
                    ErrorKind::UnusedWord,
                    "F word cannot be used with G33 or G33.1",
                ));
            }
        }
        if motion == 760 {
            if !b.has(b'p') {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "G76 needs a P word (pitch)",
                ));
            }
            if !(b.has(b'i') && b.has(b'j') && b.has(b'k')) {
                return Err(self.g_err(
                    b,
                    gg::MOTION,
                    ErrorKind::MissingWord,
                    "G76 needs I, J and K words",
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
        Ok(())
    }

    /// `$` (the spindle) with nothing on the block that drives a spindle.
    fn check_dollar_word(&self, b: &Block, motion: i32) -> Res<()> {
        let m = |g: usize, v: i32| b.m[g] == v;
        if b.dollar.is_some()
            && !(b.has(b's')
                || matches!(b.m[mg::SPINDLE], 3 | 4 | 5 | 19)
                || b.g[gg::SPINDLE] != -1
                || b.g[gg::FEED_MODE] == 950
                || matches!(motion, 330 | 331 | 760)
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

    pub(crate) fn comment(&mut self, b: &Block) -> Res<()> {
        match b.comment_kind {
            // rs274 writes nothing for a block whose (last) comment is `()`; `( )` is an
            // empty COMMENT.
            Comment::Plain if b.comment.is_empty() => {}
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
            Comment::Log => {
                let t = substitute(&b.comment, self);
                self.emit(C::Log(t.into()));
            }
            Comment::LogOpen | Comment::LogAppend => self.emit(C::LogOpen {
                path: b.comment.clone().into(),
                append: b.comment_kind == Comment::LogAppend,
            }),
            Comment::LogClose => self.emit(C::LogClose),
            Comment::Abort => {
                let t = substitute(&b.comment, self);
                return Err(self.error_at(ErrorKind::State, 0, t));
            }
        }
        Ok(())
    }

    pub(crate) fn spindle_mode(&mut self, b: &Block) -> Res<()> {
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

    pub(crate) fn feed_mode(&mut self, code: i32) {
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

    pub(crate) fn whole(&self, b: &Block, letter: u8, v: f64) -> Res<i32> {
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
    pub(crate) fn find_pocket(&self, b: &Block, letter: u8, t: i32) -> Res<i32> {
        if t == 0 {
            return Ok(0);
        }
        match self.tools.get(t) {
            Some(tool) => Ok(tool.pocket),
            None if self.settings.accept_unknown_tools => Ok(t),
            None => Err(self.err(
                b,
                letter,
                ErrorKind::BadValue,
                format!("tool {t} is not in the tool table"),
            )),
        }
    }

    /// The block's G codes other than its motion, in the order RS274/NGC carries them out,
    /// then its motion.
    pub(crate) fn g_codes(&mut self, b: &mut Block, motion: i32) -> Res<()> {
        // Compensation as it was before this block's G40-G42: the checks below look at it.
        let comp_on = self.state.cutter.is_some();
        self.dwell(b)?;
        self.plane_selection(b, comp_on)?;
        self.units_and_lathe_mode(b);
        if b.g[gg::CUTTER] != -1 {
            self.cutter_comp(b)?;
        }
        if b.g[gg::LENGTH] != -1 {
            self.tool_length(b)?;
        }
        self.coordinate_system_selection(b, comp_on)?;
        self.path_control_mode(b, comp_on)?;
        self.distance_modes(b);
        self.retract_mode(b, comp_on)?;
        self.non_modal_codes(b, comp_on)?;
        if motion != -1 {
            self.motion(b, motion)?;
        }
        Ok(())
    }

    /// G4.
    fn dwell(&mut self, b: &Block) -> Res<()> {
        if b.g[gg::NON_MODAL] == 40 {
            let p = b.get(b'p').unwrap_or(0.0);
            if p < 0.0 {
                return Err(self.err(b, b'p', ErrorKind::BadValue, "negative dwell time"));
            }
            self.emit(C::Dwell(p));
        }
        Ok(())
    }

    /// G17-G19.1.
    fn plane_selection(&mut self, b: &Block, comp_on: bool) -> Res<()> {
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
        Ok(())
    }

    /// G20/G21 and G7/G8; in diameter mode the block's X is halved here.
    fn units_and_lathe_mode(&mut self, b: &mut Block) {
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
    }

    /// G54-G59.3.
    fn coordinate_system_selection(&mut self, b: &Block, comp_on: bool) -> Res<()> {
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
        Ok(())
    }

    /// G61, G61.1 and G64.
    fn path_control_mode(&mut self, b: &Block, comp_on: bool) -> Res<()> {
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
        Ok(())
    }

    /// G90/G91 and G90.1/G91.1.
    fn distance_modes(&mut self, b: &Block) {
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
    }

    /// G98/G99.
    fn retract_mode(&mut self, b: &Block, comp_on: bool) -> Res<()> {
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
        Ok(())
    }

    /// G10, G28/G30 and their .1, G52/G92 and its kin, G5.3 (G4 is `dwell`).
    fn non_modal_codes(&mut self, b: &Block, comp_on: bool) -> Res<()> {
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
            520 | 920..=923 => self.g92(b)?,
            53 => self.nurbs_end(b)?,
            _ => {}
        }
        Ok(())
    }

    pub(crate) fn set_path_mode(&mut self, mode: PathMode, naive: Option<f64>) {
        self.emit(C::SetMotionControlMode(mode));
        self.state.path_mode = mode;
        if let Some(q) = naive {
            self.state.naivecam_tolerance = q;
            self.emit(C::SetNaivecamTolerance(q));
        }
    }
}

/// What on a block can use a word, as [`Interpreter::check_words`] asks it.
struct WordUsers {
    /// The non-modal code (G4 as 40, G10 as 100, G53 as 530, ...), -1 without one.
    mode0: i32,
    /// The motion in force for the block.
    motion: i32,
    /// A canned cycle (G73, G74, G81..G89).
    cycle: bool,
    /// A lathe cycle (G70, G71.., G72..).
    lathe_cycle: bool,
    /// A roughing lathe cycle (G71.., G72..), which takes I and R.
    roughing: bool,
    /// G10.
    g10: bool,
    /// A user M code (M100-M199).
    user_m: bool,
}

impl WordUsers {
    fn of(b: &Block, motion: i32) -> WordUsers {
        let mode0 = b.g[gg::NON_MODAL];
        let lathe_cycle = matches!(motion, 700 | 710..=712 | 720..=722);
        WordUsers {
            mode0,
            motion,
            cycle: matches!(motion, 730 | 740 | 810..=890),
            lathe_cycle,
            roughing: lathe_cycle && motion != 700,
            g10: mode0 == 100,
            user_m: b.m[mg::USER] != -1,
        }
    }
}
