//! The standard function blocks of IEC 61131-3 (timers, counters, edge detectors and
//! bistables), run natively on the instance's slots. The PLC's time is the scan time
//! handed in by the caller, so they behave the same in virtual and real time.

use crate::types::Elem;

/// One of the standard function blocks.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StdFb {
    /// On-delay timer.
    Ton,
    /// Off-delay timer.
    Tof,
    /// Pulse timer.
    Tp,
    /// Up counter.
    Ctu,
    /// Down counter.
    Ctd,
    /// Up-down counter.
    Ctud,
    /// Rising edge detector.
    RTrig,
    /// Falling edge detector.
    FTrig,
    /// Set-dominant bistable.
    Sr,
    /// Reset-dominant bistable.
    Rs,
    /// PLCopen MC_Power.
    McPower,
    /// PLCopen MC_Home.
    McHome,
    /// PLCopen MC_Reset.
    McReset,
    /// PLCopen MC_Stop.
    McStop,
    /// PLCopen MC_Halt.
    McHalt,
    /// PLCopen MC_MoveAbsolute.
    McMoveAbsolute,
    /// PLCopen MC_MoveRelative.
    McMoveRelative,
    /// PLCopen MC_MoveAdditive.
    McMoveAdditive,
    /// PLCopen MC_MoveVelocity.
    McMoveVelocity,
    /// PLCopen MC_ReadActualPosition.
    McReadActualPosition,
    /// PLCopen MC_ReadStatus.
    McReadStatus,
    /// PLCopen MC_ReadAxisError.
    McReadAxisError,
}

const MOTION: [(StdFb, &str); 12] = [
    (StdFb::McPower, "MC_POWER"),
    (StdFb::McHome, "MC_HOME"),
    (StdFb::McReset, "MC_RESET"),
    (StdFb::McStop, "MC_STOP"),
    (StdFb::McHalt, "MC_HALT"),
    (StdFb::McMoveAbsolute, "MC_MOVEABSOLUTE"),
    (StdFb::McMoveRelative, "MC_MOVERELATIVE"),
    (StdFb::McMoveAdditive, "MC_MOVEADDITIVE"),
    (StdFb::McMoveVelocity, "MC_MOVEVELOCITY"),
    (StdFb::McReadActualPosition, "MC_READACTUALPOSITION"),
    (StdFb::McReadStatus, "MC_READSTATUS"),
    (StdFb::McReadAxisError, "MC_READAXISERROR"),
];

/// Most cells of any standard block's instance (the interpreter copies them to the stack
/// to run the block).
pub(crate) const MAX_CELLS: usize = 32;

/// Direction of a member of a standard FB.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Dir {
    In,
    Out,
}

type Member = (&'static str, Elem, Dir);

const TIMER: &[Member] = &[
    ("IN", Elem::Bool, Dir::In),
    ("PT", Elem::Time, Dir::In),
    ("Q", Elem::Bool, Dir::Out),
    ("ET", Elem::Time, Dir::Out),
];
const TRIG: &[Member] = &[("CLK", Elem::Bool, Dir::In), ("Q", Elem::Bool, Dir::Out)];
const SR: &[Member] = &[
    ("S1", Elem::Bool, Dir::In),
    ("R", Elem::Bool, Dir::In),
    ("Q1", Elem::Bool, Dir::Out),
];
const RS: &[Member] = &[
    ("S", Elem::Bool, Dir::In),
    ("R1", Elem::Bool, Dir::In),
    ("Q1", Elem::Bool, Dir::Out),
];
const CTU: &[Member] = &[
    ("CU", Elem::Bool, Dir::In),
    ("R", Elem::Bool, Dir::In),
    ("PV", Elem::Int, Dir::In),
    ("Q", Elem::Bool, Dir::Out),
    ("CV", Elem::Int, Dir::Out),
];
const CTD: &[Member] = &[
    ("CD", Elem::Bool, Dir::In),
    ("LD", Elem::Bool, Dir::In),
    ("PV", Elem::Int, Dir::In),
    ("Q", Elem::Bool, Dir::Out),
    ("CV", Elem::Int, Dir::Out),
];
const CTUD: &[Member] = &[
    ("CU", Elem::Bool, Dir::In),
    ("CD", Elem::Bool, Dir::In),
    ("R", Elem::Bool, Dir::In),
    ("LD", Elem::Bool, Dir::In),
    ("PV", Elem::Int, Dir::In),
    ("QU", Elem::Bool, Dir::Out),
    ("QD", Elem::Bool, Dir::Out),
    ("CV", Elem::Int, Dir::Out),
];

impl StdFb {
    /// Look up by upper-case name.
    pub fn from_name(n: &str) -> Option<StdFb> {
        Some(match n {
            "TON" => StdFb::Ton,
            "TOF" => StdFb::Tof,
            "TP" => StdFb::Tp,
            "CTU" => StdFb::Ctu,
            "CTD" => StdFb::Ctd,
            "CTUD" => StdFb::Ctud,
            "R_TRIG" => StdFb::RTrig,
            "F_TRIG" => StdFb::FTrig,
            "SR" => StdFb::Sr,
            "RS" => StdFb::Rs,
            _ => return MOTION.iter().find(|(_, x)| *x == n).map(|(f, _)| *f),
        })
    }
    /// IEC name.
    pub fn name(self) -> &'static str {
        match self {
            StdFb::Ton => "TON",
            StdFb::Tof => "TOF",
            StdFb::Tp => "TP",
            StdFb::Ctu => "CTU",
            StdFb::Ctd => "CTD",
            StdFb::Ctud => "CTUD",
            StdFb::RTrig => "R_TRIG",
            StdFb::FTrig => "F_TRIG",
            StdFb::Sr => "SR",
            StdFb::Rs => "RS",
            m => MOTION
                .iter()
                .find(|(f, _)| *f == m)
                .map_or("MC", |(_, n)| n),
        }
    }
    /// The IEC name of an input CODESYS and TwinCAT spell otherwise (`RESET` for `R`,
    /// `LOAD` for `LD`, `SET1`/`SET` for `S1`/`S`, `RESET1` for `R1`).
    pub(crate) fn iec_input_name(self, name: &str) -> Option<&'static str> {
        Some(match (self, name) {
            (StdFb::Ctu | StdFb::Ctud | StdFb::Sr, "RESET") => "R",
            (StdFb::Ctd | StdFb::Ctud, "LOAD") => "LD",
            (StdFb::Sr, "SET1") => "S1",
            (StdFb::Rs, "SET") => "S",
            (StdFb::Rs, "RESET1") => "R1",
            _ => return None,
        })
    }
    /// Public members in cell order (byte offset = 8 × index).
    pub(crate) fn members(self) -> &'static [Member] {
        match self {
            StdFb::Ton | StdFb::Tof | StdFb::Tp => TIMER,
            StdFb::RTrig | StdFb::FTrig => TRIG,
            StdFb::Sr => SR,
            StdFb::Rs => RS,
            StdFb::Ctu => CTU,
            StdFb::Ctd => CTD,
            StdFb::Ctud => CTUD,
            StdFb::McPower => crate::plcopen::POWER,
            StdFb::McHome => crate::plcopen::HOME,
            StdFb::McReset => crate::plcopen::RESET,
            StdFb::McStop => crate::plcopen::STOP,
            StdFb::McHalt => crate::plcopen::HALT,
            StdFb::McMoveAbsolute => crate::plcopen::MOVE_ABSOLUTE,
            StdFb::McMoveRelative | StdFb::McMoveAdditive => crate::plcopen::MOVE_DISTANCE,
            StdFb::McMoveVelocity => crate::plcopen::MOVE_VELOCITY,
            StdFb::McReadActualPosition => crate::plcopen::READ_POSITION,
            StdFb::McReadStatus => crate::plcopen::READ_STATUS,
            StdFb::McReadAxisError => crate::plcopen::READ_ERROR,
        }
    }
    /// A PLCopen motion block (run by the runtime, which owns the axes).
    pub fn is_motion(self) -> bool {
        MOTION.iter().any(|(f, _)| *f == self)
    }
    /// Cells (8 bytes each) of an instance: the public members, then the hidden state.
    /// Each member sits at the start of its cell, little-endian at its own width.
    pub(crate) fn size(self) -> u32 {
        self.members().len() as u32
            + match self {
                StdFb::Ton | StdFb::Tof | StdFb::Tp => 3,
                StdFb::RTrig | StdFb::FTrig | StdFb::Ctu | StdFb::Ctd => 1,
                StdFb::Ctud => 2,
                StdFb::Sr | StdFb::Rs => 0,
                _ => crate::plcopen::HIDDEN,
            }
    }
    /// Initial values of the hidden state (F_TRIG's memory starts TRUE, as the standard
    /// declares it, so a FALSE input on the first call gives no edge).
    pub(crate) fn init_hidden(self, inst: &mut [u8]) {
        if self == StdFb::FTrig {
            if let Some(m) = inst.get_mut(2 * 8) {
                *m = 1;
            }
        }
    }

    /// Runs the block on its instance slots at scan time `now` (nanoseconds).
    #[inline]
    pub(crate) fn run(self, s: &mut [u64], now: i64) {
        // The compiler sizes every instance with `size()`; a shorter slice is a bug and
        // the block then does nothing rather than panic.
        if s.len() < self.size() as usize {
            return;
        }
        match self {
            StdFb::Ton => ton(s, now),
            StdFb::Tof => tof(s, now),
            StdFb::Tp => tp(s, now),
            StdFb::RTrig => {
                let clk = s[0] & 1;
                s[1] = clk & !s[2] & 1;
                s[2] = clk;
            }
            StdFb::FTrig => {
                let nclk = !s[0] & 1;
                s[1] = nclk & !s[2] & 1;
                s[2] = nclk;
            }
            StdFb::Sr => s[2] = (s[0] | (!s[1] & s[2])) & 1,
            StdFb::Rs => s[2] = (!s[1] & (s[0] | s[2])) & 1,
            // Motion blocks need the axes: the VM runs them (`plcopen::run`).
            _ if self.is_motion() => {}
            StdFb::Ctu => {
                let edge = s[0] & !s[5] & 1 != 0;
                s[5] = s[0] & 1;
                let mut cv = s[4] as i64;
                let pv = s[2] as i64;
                if s[1] & 1 != 0 {
                    cv = 0;
                } else if edge && cv < i16::MAX as i64 {
                    cv += 1;
                }
                s[4] = cv as u64;
                s[3] = (cv >= pv) as u64;
            }
            StdFb::Ctd => {
                let edge = s[0] & !s[5] & 1 != 0;
                s[5] = s[0] & 1;
                let mut cv = s[4] as i64;
                let pv = s[2] as i64;
                if s[1] & 1 != 0 {
                    cv = pv;
                } else if edge && cv > i16::MIN as i64 {
                    cv -= 1;
                }
                s[4] = cv as u64;
                s[3] = (cv <= 0) as u64;
            }
            StdFb::Ctud => {
                let up = s[0] & !s[8] & 1 != 0;
                let down = s[1] & !s[9] & 1 != 0;
                s[8] = s[0] & 1;
                s[9] = s[1] & 1;
                let mut cv = s[7] as i64;
                let pv = s[4] as i64;
                if s[2] & 1 != 0 {
                    cv = 0;
                } else if s[3] & 1 != 0 {
                    cv = pv;
                } else if !(up && down) {
                    if up && cv < i16::MAX as i64 {
                        cv += 1;
                    } else if down && cv > i16::MIN as i64 {
                        cv -= 1;
                    }
                }
                s[7] = cv as u64;
                s[5] = (cv >= pv) as u64;
                s[6] = (cv <= 0) as u64;
            }
            _ => {}
        }
    }
}

// Timer slots: 0 IN, 1 PT, 2 Q, 3 ET, 4 start time, 5 running, 6 previous IN.

fn elapsed(s: &[u64], now: i64) -> i64 {
    let pt = (s[1] as i64).max(0);
    now.saturating_sub(s[4] as i64).clamp(0, pt)
}

fn ton(s: &mut [u64], now: i64) {
    if s[0] & 1 == 0 {
        s[2] = 0;
        s[3] = 0;
        s[5] = 0;
        return;
    }
    if s[5] == 0 {
        s[4] = now as u64;
        s[5] = 1;
    }
    let et = elapsed(s, now);
    s[3] = et as u64;
    s[2] = (et >= (s[1] as i64).max(0)) as u64;
}

fn tof(s: &mut [u64], now: i64) {
    if s[0] & 1 != 0 {
        s[2] = 1;
        s[3] = 0;
        s[5] = 0;
        return;
    }
    if s[2] & 1 != 0 {
        if s[5] == 0 {
            s[4] = now as u64;
            s[5] = 1;
        }
        let et = elapsed(s, now);
        s[3] = et as u64;
        if et >= (s[1] as i64).max(0) {
            s[2] = 0;
        }
    }
}

fn tp(s: &mut [u64], now: i64) {
    let input = s[0] & 1 != 0;
    let rising = input && s[6] & 1 == 0;
    s[6] = input as u64;
    if s[2] & 1 == 0 {
        if rising {
            s[2] = 1;
            s[4] = now as u64;
        } else if !input {
            s[3] = 0;
            return;
        } else {
            return;
        }
    }
    let et = elapsed(s, now);
    s[3] = et as u64;
    if et >= (s[1] as i64).max(0) {
        s[2] = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_standard_block_fits_the_cells_the_interpreter_copies() {
        let basic = [
            "TON", "TOF", "TP", "CTU", "CTD", "CTUD", "R_TRIG", "F_TRIG", "SR", "RS",
        ];
        let names = basic.iter().copied().chain(MOTION.iter().map(|(_, n)| *n));
        for n in names {
            let fb = StdFb::from_name(n).expect(n);
            assert!(fb.size() as usize <= MAX_CELLS, "{n}: {}", fb.size());
            assert!(fb.members().len() <= fb.size() as usize, "{n}");
        }
    }
}
