//! The standard function blocks of IEC 61131-3 (timers, counters, edge detectors and
//! bistables), run natively on the instance's cells. The PLC's time is the scan time
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

/// The cells of one standard block's instance, 8 bytes each in PLC memory, holding
/// register values (BOOL 0 or 1, integers sign- or zero-extended, LREAL bits): a member
/// read at its own width from the start of its cell reads the same value.
pub(crate) struct Cells<'a>(pub(crate) &'a mut [u8]);

impl Cells<'_> {
    /// Number of cells.
    #[inline(always)]
    pub(crate) fn len(&self) -> usize {
        self.0.len() / 8
    }
    /// Cell `i`; 0 past the end.
    #[inline(always)]
    pub(crate) fn get(&self, i: usize) -> u64 {
        self.0
            .get(8 * i..8 * i + 8)
            .and_then(|b| b.try_into().ok())
            .map_or(0, u64::from_le_bytes)
    }
    /// Sets cell `i`; nothing past the end.
    #[inline(always)]
    pub(crate) fn set(&mut self, i: usize, v: u64) {
        if let Some(b) = self.0.get_mut(8 * i..8 * i + 8) {
            b.copy_from_slice(&v.to_le_bytes());
        }
    }
}

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
    /// Has an input of a signed integer narrower than 8 bytes or a REAL, which the
    /// program writes at its own width and the block reads widened.
    #[inline]
    pub(crate) fn has_narrow_inputs(self) -> bool {
        use StdFb::*;
        if matches!(self, Ton | Tof | Tp | RTrig | FTrig | Sr | Rs) {
            return false;
        }
        self.members().iter().any(|(_, e, d)| {
            *d == Dir::In && matches!(e, Elem::SInt | Elem::Int | Elem::DInt | Elem::Real)
        })
    }
    /// A PLCopen motion block (run by the runtime, which owns the axes).
    #[inline]
    pub fn is_motion(self) -> bool {
        use StdFb::*;
        // Every variant of MOTION: a test on the variant, not a search of the table, as
        // every call of a standard block asks.
        matches!(
            self,
            McPower
                | McHome
                | McReset
                | McStop
                | McHalt
                | McMoveAbsolute
                | McMoveRelative
                | McMoveAdditive
                | McMoveVelocity
                | McReadActualPosition
                | McReadStatus
                | McReadAxisError
        )
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

    /// Runs the block on its instance cells at scan time `now` (nanoseconds).
    #[inline]
    pub(crate) fn run(self, s: &mut Cells, now: i64) {
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
                let clk = s.get(0) & 1;
                s.set(1, clk & !s.get(2) & 1);
                s.set(2, clk);
            }
            StdFb::FTrig => {
                let nclk = !s.get(0) & 1;
                s.set(1, nclk & !s.get(2) & 1);
                s.set(2, nclk);
            }
            StdFb::Sr => s.set(2, (s.get(0) | (!s.get(1) & s.get(2))) & 1),
            StdFb::Rs => s.set(2, (!s.get(1) & (s.get(0) | s.get(2))) & 1),
            // Motion blocks need the axes: the VM runs them (`plcopen::run`).
            _ if self.is_motion() => {}
            StdFb::Ctu => {
                let edge = s.get(0) & !s.get(5) & 1 != 0;
                s.set(5, s.get(0) & 1);
                let mut cv = s.get(4) as i64;
                let pv = s.get(2) as i64;
                if s.get(1) & 1 != 0 {
                    cv = 0;
                } else if edge && cv < i16::MAX as i64 {
                    cv += 1;
                }
                s.set(4, cv as u64);
                s.set(3, (cv >= pv) as u64);
            }
            StdFb::Ctd => {
                let edge = s.get(0) & !s.get(5) & 1 != 0;
                s.set(5, s.get(0) & 1);
                let mut cv = s.get(4) as i64;
                let pv = s.get(2) as i64;
                if s.get(1) & 1 != 0 {
                    cv = pv;
                } else if edge && cv > i16::MIN as i64 {
                    cv -= 1;
                }
                s.set(4, cv as u64);
                s.set(3, (cv <= 0) as u64);
            }
            StdFb::Ctud => {
                let up = s.get(0) & !s.get(8) & 1 != 0;
                let down = s.get(1) & !s.get(9) & 1 != 0;
                s.set(8, s.get(0) & 1);
                s.set(9, s.get(1) & 1);
                let mut cv = s.get(7) as i64;
                let pv = s.get(4) as i64;
                if s.get(2) & 1 != 0 {
                    cv = 0;
                } else if s.get(3) & 1 != 0 {
                    cv = pv;
                } else if !(up && down) {
                    if up && cv < i16::MAX as i64 {
                        cv += 1;
                    } else if down && cv > i16::MIN as i64 {
                        cv -= 1;
                    }
                }
                s.set(7, cv as u64);
                s.set(5, (cv >= pv) as u64);
                s.set(6, (cv <= 0) as u64);
            }
            _ => {}
        }
    }
}

// Timer cells: 0 IN, 1 PT, 2 Q, 3 ET, 4 start time, 5 running, 6 previous IN.

fn elapsed(s: &Cells, now: i64) -> i64 {
    let pt = (s.get(1) as i64).max(0);
    now.saturating_sub(s.get(4) as i64).clamp(0, pt)
}

fn ton(s: &mut Cells, now: i64) {
    if s.get(0) & 1 == 0 {
        s.set(2, 0);
        s.set(3, 0);
        s.set(5, 0);
        return;
    }
    if s.get(5) == 0 {
        s.set(4, now as u64);
        s.set(5, 1);
    }
    let et = elapsed(s, now);
    s.set(3, et as u64);
    s.set(2, (et >= (s.get(1) as i64).max(0)) as u64);
}

fn tof(s: &mut Cells, now: i64) {
    if s.get(0) & 1 != 0 {
        s.set(2, 1);
        s.set(3, 0);
        s.set(5, 0);
        return;
    }
    if s.get(2) & 1 != 0 {
        if s.get(5) == 0 {
            s.set(4, now as u64);
            s.set(5, 1);
        }
        let et = elapsed(s, now);
        s.set(3, et as u64);
        if et >= (s.get(1) as i64).max(0) {
            s.set(2, 0);
        }
    }
}

fn tp(s: &mut Cells, now: i64) {
    let input = s.get(0) & 1 != 0;
    let rising = input && s.get(6) & 1 == 0;
    s.set(6, input as u64);
    if s.get(2) & 1 == 0 {
        if rising {
            s.set(2, 1);
            s.set(4, now as u64);
        } else if !input {
            s.set(3, 0);
            return;
        } else {
            return;
        }
    }
    let et = elapsed(s, now);
    s.set(3, et as u64);
    if et >= (s.get(1) as i64).max(0) {
        s.set(2, 0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn narrow_inputs_are_the_signed_and_real_ones() {
        let basic = [
            "TON", "TOF", "TP", "CTU", "CTD", "CTUD", "R_TRIG", "F_TRIG", "SR", "RS",
        ];
        let names = basic.iter().copied().chain(MOTION.iter().map(|(_, n)| *n));
        for n in names {
            let fb = StdFb::from_name(n).expect(n);
            assert!(fb.members().len() <= fb.size() as usize, "{n}");
            let narrow = fb.members().iter().any(|(_, e, d)| {
                *d == Dir::In && matches!(e, Elem::SInt | Elem::Int | Elem::DInt | Elem::Real)
            });
            assert_eq!(fb.has_narrow_inputs(), narrow, "{n}");
        }
        // The counters' PV is an INT.
        assert!(StdFb::Ctu.has_narrow_inputs());
        assert!(!StdFb::Ton.has_narrow_inputs());
    }

    #[test]
    fn the_motion_blocks_are_those_of_the_motion_table() {
        let basic = [
            "TON", "TOF", "TP", "CTU", "CTD", "CTUD", "R_TRIG", "F_TRIG", "SR", "RS",
        ];
        for n in basic {
            assert!(!StdFb::from_name(n).expect(n).is_motion(), "{n}");
        }
        for (fb, n) in MOTION {
            assert!(fb.is_motion(), "{n}");
        }
    }
}
