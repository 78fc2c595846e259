//! Program stops and ends (M0, M1, M2, M30, M60, M99) with the resets of M2, and the
//! M72/M73 restore of a saved modal state.

use crate::block::{Block, fmt_code, mg};
use crate::canon::{
    CanonCommand as C, CompensationSide, FeedMode, PathMode, Plane, Pose, SpindleDirection, Units,
};
use crate::error::GcodeError;
use crate::interp::{Interpreter, ModalState};
use crate::params::sys;

type Res<T> = Result<T, GcodeError>;

impl Interpreter {
    pub(crate) fn stop(&mut self, b: &Block) -> Res<bool> {
        match b.m[mg::STOP] {
            0 => self.emit(C::ProgramStop),
            1 => self.emit(C::OptionalProgramStop),
            60 => {
                self.emit(C::PalletShuttle);
                self.emit(C::ProgramStop);
            }
            99 if self.m99()? => return Ok(true),
            code => {
                self.program_end_reset(b);
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
    /// feed override on, compensation off, spindle off, G1, coolant off, tool-centre-point
    /// control off.
    pub(crate) fn program_end_reset(&mut self, b: &Block) {
        let machine = self.machine_position();
        self.state.origin_index = 1;
        self.params.set(sys::COORD_SYSTEM, 1.0);
        self.state.g5x = self.coord_system_from_params(1);
        self.state.rotation = self.params.get(sys::G54 + 9);
        self.state.position = self.program_from_machine(&machine);
        // TCP off (the machine's kinematics switches back at the end, as it sees it).
        self.state.tool_centre_point = false;
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
        // LinuxCNC keeps the F of the M2 block (the canonical feed rate goes to 0).
        self.state.feed_rate = b.get(b'f').unwrap_or(0.0);
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

    /// M72 (or return from a subroutine after M73): bring back a saved modal state the way
    /// LinuxCNC 2.9 does it, by executing the codes that differ: units first, then one line
    /// with F, S and the G codes (in its order of its modal table) to which the first M code
    /// is joined, then the other M codes one per line.
    pub(crate) fn restore_state(&mut self, saved: &ModalState) -> Res<()> {
        use std::fmt::Write;
        self.state.g92_applied = self.params.get(sys::G92_APPLIED) != 0.0;
        let cur = self.state.clone();
        if saved.units != cur.units {
            self.execute_text(if saved.units == Units::Inches {
                "G20"
            } else {
                "G21"
            })?;
        }
        let cur = self.state.clone();
        let mut cmd = String::new();
        if saved.feed_rate != cur.feed_rate {
            let _ = write!(cmd, " F{:.1}", saved.feed_rate);
        }
        if saved.speed != cur.speed {
            let _ = write!(cmd, " S{:.0}", saved.speed);
        }
        let (tol_s, tol_c) = (tolerance(saved.path_mode), tolerance(cur.path_mode));
        let mut g64_changed = tol_s != tol_c || saved.naivecam_tolerance != cur.naivecam_tolerance;
        let g = |st: &ModalState| -> [i32; 17] {
            let mut v = [-1; 17];
            v[3] = match st.plane {
                Plane::XY => 170,
                Plane::XZ => 180,
                Plane::YZ => 190,
                Plane::UV => 171,
                Plane::WU => 181,
                Plane::VW => 191,
            };
            v[4] = match st.cutter {
                None => 400,
                Some(CompensationSide::Left) => 410,
                Some(CompensationSide::Right) => 420,
            };
            v[6] = if st.absolute { 900 } else { 910 };
            v[7] = match st.feed_mode {
                FeedMode::InverseTime => 930,
                FeedMode::UnitsPerMinute => 940,
                FeedMode::UnitsPerRevolution => 950,
            };
            v[8] = match st.origin_index {
                i @ 1..=6 => 530 + 10 * i32::from(i),
                i => 584 + i32::from(i),
            };
            v[9] = if st.tool_offset == Pose::ZERO {
                490
            } else {
                430
            };
            v[10] = if st.retract_old_z { 980 } else { 990 };
            v[11] = match st.path_mode {
                PathMode::Continuous { .. } => 640,
                PathMode::ExactPath => 610,
                PathMode::ExactStop => 611,
            };
            v[13] = if st.css { 960 } else { 970 };
            v[14] = if st.ijk_absolute { 901 } else { 911 };
            v[15] = if st.lathe_diameter { 70 } else { 80 };
            v[16] = if st.g92_applied { 923 } else { 922 };
            v
        };
        let (gs, gc) = (g(saved), g(&cur));
        for i in [3, 4, 6, 7, 8, 9, 10, 11, 13, 14, 15, 16] {
            if gs[i] == gc[i] {
                continue;
            }
            if i == 11 && gs[i] == 640 {
                g64_changed = true;
            } else {
                let _ = write!(cmd, " G{}", fmt_code(gs[i]));
            }
        }
        if gs[11] == 640 && g64_changed {
            if tol_s < 0.0 {
                cmd.push_str(" G64");
            } else if saved.naivecam_tolerance < 0.0 {
                let _ = write!(cmd, " G64 P{tol_s:.6}");
            } else {
                let _ = write!(cmd, " G64 P{tol_s:.6} Q{:.6}", saved.naivecam_tolerance);
            }
        }
        // M codes as LinuxCNC lists its modal M state.
        let m = |st: &ModalState| -> [i32; 6] {
            [
                match st.spindle {
                    None => 5,
                    Some(SpindleDirection::Clockwise) => 3,
                    Some(SpindleDirection::CounterClockwise) => 4,
                },
                if st.mist {
                    7
                } else if st.flood {
                    -1
                } else {
                    9
                },
                if st.flood { 8 } else { -1 },
                match (st.feed_override, st.speed_override) {
                    (true, true) => 48,
                    (true, false) => 50,
                    (false, true) => 51,
                    (false, false) => 49,
                },
                if st.adaptive_feed { 52 } else { -1 },
                if st.feed_hold { 53 } else { -1 },
            ]
        };
        let (ms, mc) = (m(saved), m(&cur));
        for (s, c) in ms.iter().zip(mc) {
            if *s != c && *s != -1 {
                let _ = writeln!(cmd, "M{s}");
            }
        }
        for line in cmd.split('\n').filter(|l| !l.is_empty()) {
            self.execute_text(line)?;
        }
        Ok(())
    }

    /// Executes a block given as text (used to restore modal state).
    pub(crate) fn execute_text(&mut self, text: &str) -> Res<()> {
        let mut b = Block::default();
        if let Err(e) = crate::block::read_block(text.as_bytes(), &*self, &mut b) {
            return Err(self.error_at(e.kind, 0, format!("restoring state: {}", e.message)));
        }
        self.execute(&mut b).map(|_| ())
    }
}

/// The G64 tolerance of a path mode (-1 when not in G64, as LinuxCNC records it).
fn tolerance(mode: PathMode) -> f64 {
    match mode {
        PathMode::Continuous { tolerance } => tolerance,
        _ => -1.0,
    }
}
