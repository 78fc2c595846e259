//! The program's outputs (M62-M65 digital, M67/M68 analogue) as each set-point carries
//! them to the drives, so that an output changes in the exchange of the set-point it
//! belongs to however far ahead interpolation computes.
//!
//! LinuxCNC's split, kept here: M64/M65/M68 wait for the motion before them and act at
//! once; M62/M63/M67 do not stop the path: they change the output at the start of the next
//! move (LinuxCNC's motion controller attaches them to its next trajectory segment). The
//! look-ahead stages a synchronised change until the next path move is in the planner,
//! then arms it on that move's first piece; interpolation applies it in the first
//! set-point on that piece (after the corner blend into it, which belongs to the move
//! before, as LinuxCNC's blend arcs do). Every change goes through one log in program
//! order, each entry with the set-point or the piece from which it applies; a set-point
//! keeps how many entries it has applied, so that a take-back goes back over them exactly.

use crate::config::MAX_PROGRAM_IO;

/// The program outputs' state that one set-point carries to the drives.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProgramOutputs {
    /// Bit n: program digital output n (M62-M65 P n).
    pub digital: u64,
    /// Program analogue outputs by number (M67/M68 E n).
    pub analog: [f64; MAX_PROGRAM_IO],
}

impl Default for ProgramOutputs {
    fn default() -> Self {
        ProgramOutputs {
            digital: 0,
            analog: [0.0; MAX_PROGRAM_IO],
        }
    }
}

/// One change of a program output.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) enum OutputChange {
    /// Digital output `index` (below 64) on or off.
    Digital { index: u32, on: bool },
    /// Analogue output `slot` (a mapped one) to `value`.
    Analog { slot: usize, value: f64 },
}

impl OutputChange {
    pub(super) fn apply(self, to: &mut ProgramOutputs) {
        match self {
            OutputChange::Digital { index, on } if index < 64 => {
                if on {
                    to.digital |= 1 << index;
                } else {
                    to.digital &= !(1 << index);
                }
            }
            OutputChange::Digital { .. } => {}
            OutputChange::Analog { slot, value } => {
                if let Some(v) = to.analog.get_mut(slot) {
                    *v = value;
                }
            }
        }
    }
}

/// From which set-point a logged change applies.
#[derive(Debug, Clone, Copy, PartialEq)]
enum From {
    /// The set-point with this number and the ones after it (an immediate change).
    Setpoint(u64),
    /// The first set-point on the planner's piece with this id or a later one (a
    /// synchronised change, armed on the first piece of the move after it).
    Piece(u64),
}

/// Changes logged at most between the oldest set-point a take-back may go back to and the
/// newest armed change: the look-ahead waits for room beyond it.
const LOG: usize = 256;
/// Synchronised changes staged at most until the next move arms them; beyond, a change
/// waits for the path to stand and acts at once.
const STAGED: usize = 32;

/// The log of output changes and the state as after the last produced set-point.
#[derive(Debug, Clone)]
pub(super) struct OutputLog {
    /// The state carried by the last produced set-point.
    pub(super) state: ProgramOutputs,
    /// Changes logged so far (the next entry's number).
    logged: u64,
    /// Changes the last produced set-point has applied.
    pub(super) applied: u64,
    log: [(From, OutputChange); LOG],
    /// Synchronised changes waiting for the next move.
    staged: [OutputChange; STAGED],
    staged_len: usize,
}

impl OutputLog {
    pub(super) fn new() -> OutputLog {
        let none = (
            From::Setpoint(0),
            OutputChange::Digital {
                index: 64,
                on: false,
            },
        );
        OutputLog {
            state: ProgramOutputs::default(),
            logged: 0,
            applied: 0,
            log: [none; LOG],
            staged: [none.1; STAGED],
            staged_len: 0,
        }
    }

    /// Stages a synchronised change for the next move; false when the stage is full.
    pub(super) fn stage(&mut self, change: OutputChange) -> bool {
        match self.staged.get_mut(self.staged_len) {
            Some(slot) => {
                *slot = change;
                self.staged_len += 1;
                true
            }
            None => false,
        }
    }

    /// Changes staged for the next move.
    pub(super) fn staged(&self) -> usize {
        self.staged_len
    }

    /// Whether `n` more changes fit in the log while set-points back to one that had
    /// applied `oldest_applied` changes may still be taken back.
    pub(super) fn has_room(&self, n: usize, oldest_applied: u64) -> bool {
        let live = self.logged.saturating_sub(oldest_applied);
        live.saturating_add(n as u64) <= LOG as u64
    }

    /// Arms the staged changes on piece `id` (the first piece of the move just pushed).
    /// The caller has checked the room ([`has_room`](Self::has_room)).
    pub(super) fn arm_staged(&mut self, id: u64) {
        for i in 0..self.staged_len {
            let change = self.staged[i];
            self.log(From::Piece(id), change);
        }
        self.staged_len = 0;
    }

    /// Logs the staged changes and `change` (if any) to apply from set-point `number`: an
    /// immediate change, or synchronised ones whose next move is not a planner move (a
    /// probing or threading move, the program's end). Without room the oldest unapplied
    /// entries would be overwritten, so the change is then applied by the caller's
    /// fallback: it returns false.
    pub(super) fn log_from_setpoint(
        &mut self,
        number: u64,
        change: Option<OutputChange>,
        oldest_applied: u64,
    ) -> bool {
        let n = self.staged_len + usize::from(change.is_some());
        if !self.has_room(n, oldest_applied) {
            return false;
        }
        for i in 0..self.staged_len {
            let staged = self.staged[i];
            self.log(From::Setpoint(number), staged);
        }
        self.staged_len = 0;
        if let Some(c) = change {
            self.log(From::Setpoint(number), c);
        }
        true
    }

    fn log(&mut self, from: From, change: OutputChange) {
        self.log[(self.logged % LOG as u64) as usize] = (from, change);
        self.logged += 1;
    }

    /// Applies, in program order, the logged changes due at set-point `number`, which lies
    /// on planner piece `piece` (`None`: on no piece, or not the planner's set-point).
    pub(super) fn advance(&mut self, number: u64, piece: Option<u64>) {
        while self.applied < self.logged {
            let (from, change) = self.log[(self.applied % LOG as u64) as usize];
            let due = match from {
                From::Setpoint(n) => number >= n,
                From::Piece(id) => piece.is_some_and(|p| p >= id),
            };
            if !due {
                return;
            }
            change.apply(&mut self.state);
            self.applied += 1;
        }
    }

    /// Goes back to the state of a set-point taken back to (its state, its count).
    pub(super) fn restore(&mut self, state: ProgramOutputs, applied: u64) {
        self.state = state;
        self.applied = applied.min(self.logged);
    }

    /// Drops the staged and the not yet applied changes (abort, fault, a new run): they
    /// belong to motion that will not run.
    pub(super) fn drop_pending(&mut self) {
        self.staged_len = 0;
        self.logged = self.applied;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_synchronised_change_waits_for_its_piece_and_goes_back_with_a_take_back() {
        let mut log = OutputLog::new();
        assert!(log.stage(OutputChange::Digital { index: 3, on: true }));
        log.advance(1, Some(0));
        assert_eq!(
            log.state.digital, 0,
            "staged: not applied before a move arms it"
        );
        log.arm_staged(5);
        log.advance(2, Some(4));
        assert_eq!(log.state.digital, 0);
        let before = (log.state, log.applied);
        log.advance(3, Some(5));
        assert_eq!(log.state.digital, 1 << 3);
        // Taken back to set-point 2: the change is applied again when piece 5 comes.
        log.restore(before.0, before.1);
        assert_eq!(log.state.digital, 0);
        log.advance(3, Some(5));
        assert_eq!(log.state.digital, 1 << 3);
    }

    #[test]
    fn changes_apply_in_program_order_and_pending_ones_are_dropped() {
        let mut log = OutputLog::new();
        log.stage(OutputChange::Analog {
            slot: 1,
            value: 2.0,
        });
        log.arm_staged(10);
        assert!(log.log_from_setpoint(4, Some(OutputChange::Digital { index: 0, on: true }), 0));
        // The immediate entry is due from set-point 4, but comes after the armed one.
        log.advance(6, Some(9));
        assert_eq!(log.state, ProgramOutputs::default());
        log.advance(7, Some(10));
        assert_eq!(log.state.analog[1], 2.0);
        assert_eq!(log.state.digital, 1);
        log.stage(OutputChange::Digital {
            index: 0,
            on: false,
        });
        log.arm_staged(20);
        log.drop_pending();
        log.advance(8, Some(30));
        assert_eq!(log.state.digital, 1, "dropped: never applied");
    }

    #[test]
    fn the_log_refuses_what_would_overwrite_an_entry_still_needed() {
        let mut log = OutputLog::new();
        for _ in 0..LOG {
            log.stage(OutputChange::Digital { index: 1, on: true });
            log.arm_staged(1);
        }
        assert!(!log.has_room(1, 0));
        assert!(!log.log_from_setpoint(
            1,
            Some(OutputChange::Digital {
                index: 1,
                on: false
            }),
            0
        ));
        assert!(log.has_room(1, 1));
    }
}
