//! Program stops and ends (M0, M1, M2, M30, M60, M99) with the resets of M2, and the
//! M72/M73 restore of a saved modal state.

use crate::block::{Block, fmt_code, mg};
use crate::canon::{CanonCommand as C, FeedMode, PathMode, Plane, SpindleDirection, Units};
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
    /// feed override on, compensation off, spindle off, G1, coolant off.
    pub(crate) fn program_end_reset(&mut self, b: &Block) {
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
    pub(crate) fn execute_text(&mut self, text: &str) -> Res<()> {
        let mut b = Block::default();
        if let Err(e) = crate::block::read_block(text.as_bytes(), &*self, &mut b) {
            return Err(self.error_at(e.kind, 0, format!("restoring state: {}", e.message)));
        }
        self.execute(&mut b).map(|_| ())
    }
}
