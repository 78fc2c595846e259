//! The interpreter's modal state as plain data (active G and M codes, feed, speed, offsets),
//! published by the interpreter task after every activation for the operator's surfaces.
//! It is the interpreter's, so in a program it runs ahead of the motion by the look-ahead
//! (as LinuxCNC's status reports it).

use rtcnc_gcode::ModalState;
use rtcnc_gcode::canon::{FeedMode, PathMode, Plane, SpindleDirection, Units};

/// Active G codes and the rest of the modal state.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ModalSnapshot {
    /// False until the interpreter ran once.
    pub valid: bool,
    /// Active G codes ×10 (G1 = 10, G54.1 = 541), -1 for unused entries.
    pub g_codes: [i32; 16],
    /// Active M codes, -1 for unused entries.
    pub m_codes: [i32; 8],
    /// F, program units.
    pub feed_rate: f64,
    /// S.
    pub speed: f64,
    /// mm per program unit.
    pub units_mm: f64,
    /// 1..=9: G54..G59.3.
    pub work_system: u8,
    /// Work offset in force, program units.
    pub work_offset: [f64; 9],
    /// G92 offset.
    pub g92_offset: [f64; 9],
    /// Tool length offset.
    pub tool_offset: [f64; 9],
    /// XY rotation, degrees.
    pub rotation: f64,
}

impl ModalSnapshot {
    /// The snapshot of an interpreter's modal state.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn of(m: &ModalState) -> ModalSnapshot {
        let mut g = [-1i32; 16];
        let origin = match m.origin_index {
            1..=6 => 530 + 10 * i32::from(m.origin_index),
            7 => 591,
            8 => 592,
            _ => 593,
        };
        let codes = [
            m.motion,
            match m.plane {
                Plane::XY => 170,
                Plane::XZ => 180,
                Plane::YZ => 190,
                Plane::UV => 171,
                Plane::WU => 181,
                Plane::VW => 191,
            },
            if m.lathe_diameter { 70 } else { 80 },
            match m.units {
                Units::Inches => 200,
                Units::Mm => 210,
            },
            m.cutter_gcode,
            m.length_gcode,
            origin,
            match m.path_mode {
                PathMode::ExactStop => 611,
                PathMode::ExactPath => 610,
                PathMode::Continuous { .. } => 640,
            },
            if m.absolute { 900 } else { 910 },
            if m.ijk_absolute { 901 } else { 911 },
            match m.feed_mode {
                FeedMode::InverseTime => 930,
                FeedMode::UnitsPerMinute => 940,
                FeedMode::UnitsPerRevolution => 950,
            },
            if m.retract_old_z { 980 } else { 990 },
            if m.css { 960 } else { 970 },
        ];
        g[..codes.len()].copy_from_slice(&codes);
        let mut mc = [-1i32; 8];
        let spindle = match m.spindle {
            Some(SpindleDirection::Clockwise) => 3,
            Some(SpindleDirection::CounterClockwise) => 4,
            None => 5,
        };
        let coolant = match (m.mist, m.flood) {
            (true, true) => [7, 8],
            (true, false) => [7, -1],
            (false, true) => [8, -1],
            (false, false) => [9, -1],
        };
        let overrides = if m.feed_override && m.speed_override {
            48
        } else {
            49
        };
        let list = [spindle, coolant[0], coolant[1], overrides];
        for (n, c) in list.into_iter().filter(|&c| c >= 0).enumerate() {
            mc[n] = c;
        }
        ModalSnapshot {
            valid: true,
            g_codes: g,
            m_codes: mc,
            feed_rate: m.feed_rate,
            speed: m.speed,
            units_mm: match m.units {
                Units::Inches => 25.4,
                Units::Mm => 1.0,
            },
            work_system: m.origin_index,
            work_offset: m.g5x.to_array(),
            g92_offset: m.g92.to_array(),
            tool_offset: m.tool_offset.to_array(),
            rotation: m.rotation,
        }
    }
}
