//! The planner: look-ahead window with its braking curve, the set-point generator that runs
//! ahead of the servo period into a fixed buffer (with exact verification and rollback), and
//! the emission of one set-point per servo period.

mod generate;
mod prepared;

use generate::{STOP_JERK_SHARE, STOP_SHARE, StepLimits, stop_reach};
pub use prepared::{Preparation, PreparedMove};

use crate::axes::{AXES, AxisVec, norm};
use crate::builder::{Builder, GeometryStats, KINK};
use crate::error::MotionError;
use crate::geometry::Shape;
use crate::input::Move;
use crate::kinematics::Kinematics;
use crate::limits::{Lim, MachineLimits};
use crate::otg::{Profile, State as OtgState};
use crate::piece::{BRAKE_SHARE_STRAIGHT, JERK_SHARE_JUMP, Piece};
use crate::scurve::{advance, stop};

/// What the interpolator is doing.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum MotionState {
    /// Nothing to do: the queue is empty (moves may be held back until more arrive or
    /// [`Planner::flush`] is called).
    Idle,
    /// Moving along the path.
    Moving,
    /// Dwelling at rest.
    Dwelling,
    /// Feed hold: decelerating or stopped on the path, waiting for [`Planner::resume`].
    Holding,
    /// Abort or quick stop in progress (decelerating along the path).
    Stopping,
}

/// One servo period's result besides the joint positions.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Status {
    /// State after this period.
    pub state: MotionState,
    /// Axis position of the set-point.
    pub axes: AxisVec,
    /// Path speed (mm/s, 9-axis length per second) of the speed controller.
    pub path_speed: f64,
    /// Program line of the move being executed (0 when idle).
    pub line: u32,
}

/// Counters for diagnostics and tests.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct RunStats {
    /// Servo periods emitted.
    pub periods: u64,
    /// Emitted set-points whose finite differences exceed a limit (should stay 0): only when
    /// every rollback failed and nothing admissible was left to emit.
    pub limit_violations: u64,
    /// Generator steps in which no path jerk passed the speed model and the generator braked
    /// as hard as the path bounds allow (the set-point itself was still verified).
    pub emergency_brakes: u64,
    /// Set-points generated ahead (more than `periods` by the rollbacks' regeneration).
    pub generated: u64,
    /// Dead ends met by the generator: each dropped some not yet emitted set-points and
    /// regenerated them with a stricter speed policy.
    pub rollbacks: u64,
    /// Set-points dropped by rollbacks.
    pub rolled_back: u64,
    /// Generated set-points the finite-difference box moved away from the speed policy's
    /// choice (the state then follows the moved point).
    pub adjusted: u64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum StopKind {
    Hold,
    Abort,
    Quick,
}

/// Feed and rapid overrides that take effect once the machine is at rest or has passed
/// the piece `until` (the one ending in the stop it was braking for).
#[derive(Debug, Clone, Copy)]
struct PendingOverride {
    fo: f64,
    ro: f64,
    until: u64,
}

#[derive(Debug, Clone, Copy)]
struct Hold {
    /// Deceleration and jerk of the stop.
    a: f64,
    j: f64,
    kind: StopKind,
    /// Travel added beyond the stop model's distance when the stop began (one period at
    /// its speed, for the discrete landing; none for a quick stop).
    slack: f64,
}

/// Diagnostic dump of one piece: length, braking curve, axis-speed and curvature bounds.
#[cfg(feature = "diagnostics")]
pub type PieceDump = (f64, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Fixed-capacity ring of pieces. Pieces carry an id (count since construction): the piece
/// at ring position `i` has id `head_id + i`, so generator states keep their piece across
/// the release of pieces behind the emitted position.
struct Ring {
    buf: Vec<Piece>,
    head: usize,
    len: usize,
    head_id: u64,
}

impl Ring {
    fn new(cap: usize) -> Ring {
        let dummy = Piece::dwell([0.0; AXES], 0.0, 0);
        Ring {
            buf: vec![dummy; cap],
            head: 0,
            len: 0,
            head_id: 0,
        }
    }
    #[inline]
    fn cap(&self) -> usize {
        self.buf.len()
    }
    /// Buffer slot of ring position `i` (a subtraction instead of a division: the lookups
    /// of every servo period go through here).
    #[inline]
    fn slot(&self, i: usize) -> usize {
        let (c, j) = (self.cap(), self.head + i);
        if j < c {
            j
        } else if j - c < c {
            j - c
        } else {
            j % c
        }
    }
    #[inline]
    fn get(&self, i: usize) -> &Piece {
        &self.buf[self.slot(i)]
    }
    #[inline]
    fn get_mut(&mut self, i: usize) -> &mut Piece {
        let j = self.slot(i);
        &mut self.buf[j]
    }
    /// Ring position of piece `id`, if it is in the window.
    #[inline]
    fn index(&self, id: u64) -> Option<usize> {
        let i = id.checked_sub(self.head_id)?;
        if i < self.len as u64 {
            Some(i as usize)
        } else {
            None
        }
    }
    fn push(&mut self, p: &Piece) {
        let c = self.cap();
        self.buf[(self.head + self.len) % c] = *p;
        self.len += 1;
    }
    fn pop(&mut self) {
        if self.len > 0 {
            self.head = (self.head + 1) % self.cap();
            self.len -= 1;
            self.head_id += 1;
        }
    }
    fn clear(&mut self) {
        self.head_id += self.len as u64;
        self.len = 0;
    }
}

/// Isolated-line S-curves kept at once (the emitted line's and those the generator reached
/// ahead of it; one evicted is recomputed from rest when needed again).
const PROFILE_SLOTS: usize = 4;

/// Pieces one move can produce at most (line span, blend, dwell after a flush; a spline
/// and a dwell after it).
const PIECES_PER_MOVE: usize = 4;
/// Pieces a flush can produce at most (the held move: a line's two spans, a spline's
/// pieces): [`Planner::free`] keeps room for them, so that a flush never overruns the window.
/// A push that ends a compressor run passes on the lines it held as well (each a line's
/// pieces), and a flush passes them on before the held move.
const FLUSH_PIECES: usize =
    PIECES_PER_MOVE * (crate::builder::COMPRESSOR_LOOK + 1) + crate::spline::SPLINE_PIECES;

/// Smallest look-ahead window (pieces): a flush's pieces and one move's.
const MIN_WINDOW: usize = FLUSH_PIECES + PIECES_PER_MOVE + 1;

/// Generator steps `next` may spend in one period beyond the one it emits (refilling the
/// buffer after an on-line change, regenerating after a rollback).
const GEN_BUDGET: usize = 12;

/// An on-line change lets a stop end when rest is at most this many set-points ahead (see
/// `Planner::regenerate`).
const FINISH_STOP: usize = 16;
/// Generator steps [`Planner::settle_for_change`] may take (rollbacks included).
const SETTLE_STEPS: usize = 8 * FINISH_STOP;

/// Path length (mm) after which the origin of path positions moves to the emitted piece
/// (`Planner::rebase`): positions stay under a few times this plus the window's length.
const REBASE_AFTER: f64 = 1024.0;

/// Everything one set-point is generated from: where on the path, the path speed and
/// acceleration, the last set-points (for the finite-difference box) and the controller's
/// modes. A copy is kept with every buffered set-point, so that generation can resume from
/// any of them.
#[derive(Debug, Clone, Copy)]
struct GenState {
    /// Piece id and local arc length of the set-point.
    id: u64,
    s: f64,
    /// Path position (piece start plus `s`; the window end once past the last piece).
    /// Path positions count from an origin that moves forward with the emitted set-point
    /// (`Planner::rebase`), not from the program start.
    at: f64,
    v: f64,
    a: f64,
    /// The last three set-points, newest first (`hist[0]` is this entry's set-point).
    hist: [AxisVec; 3],
    /// The last two path steps (oldest first), for the landing on a stop.
    ds_hist: [f64; 2],
    /// Steps left in the landing on a stop in progress (0: none).
    land_n: usize,
    dwell_left: Option<f64>,
    /// Time spent on the isolated line's S-curve (the profile itself is the planner's).
    prof_t: Option<f64>,
    /// Path jerk of the last step (warm start of the next search).
    j_last: f64,
    /// Hold point (path position); infinite without a hold.
    hold_at: f64,
    state: MotionState,
    line: u32,
    /// An abort or quick stop came to rest here: emitting this entry drops the window.
    stopped: bool,
    /// The set-point check moved this entry's point off the step the policy chose.
    adjusted: bool,
}

impl GenState {
    fn rest(at_pos: AxisVec, id: u64, at: f64) -> GenState {
        GenState {
            id,
            s: 0.0,
            at,
            v: 0.0,
            a: 0.0,
            hist: [at_pos; 3],
            ds_hist: [0.0; 2],
            land_n: 0,
            dwell_left: None,
            prof_t: None,
            j_last: 0.0,
            hold_at: f64::INFINITY,
            state: MotionState::Idle,
            line: 0,
            stopped: false,
            adjusted: false,
        }
    }
}

/// Fixed-capacity queue of generated, not yet emitted set-points.
struct GenBuffer {
    buf: Vec<GenState>,
    head: usize,
    len: usize,
}

impl GenBuffer {
    fn new(cap: usize, fill: GenState) -> GenBuffer {
        GenBuffer {
            buf: vec![fill; cap],
            head: 0,
            len: 0,
        }
    }
    #[inline]
    fn cap(&self) -> usize {
        self.buf.len()
    }
    fn back(&self) -> Option<&GenState> {
        if self.len == 0 {
            None
        } else {
            Some(&self.buf[(self.head + self.len - 1) % self.cap()])
        }
    }
    fn push(&mut self, st: GenState) {
        if self.len < self.cap() {
            let c = self.cap();
            self.buf[(self.head + self.len) % c] = st;
            self.len += 1;
        }
    }
    /// Puts `st` in front of the oldest entry; the newest is dropped when full.
    fn push_front(&mut self, st: GenState) {
        let c = self.cap();
        if self.len == c {
            self.len -= 1;
        }
        self.head = (self.head + c - 1) % c;
        self.buf[self.head] = st;
        self.len += 1;
    }
    /// Removes and returns the newest entry.
    fn pop_back(&mut self) -> Option<GenState> {
        let st = *self.back()?;
        self.len -= 1;
        Some(st)
    }
    fn pop_front(&mut self) -> Option<GenState> {
        if self.len == 0 {
            return None;
        }
        let st = self.buf[self.head];
        self.head = (self.head + 1) % self.cap();
        self.len -= 1;
        Some(st)
    }
    /// Index of the first entry at rest (speed and acceleration zero) among the first `n`.
    fn rest_within(&self, n: usize) -> Option<usize> {
        (0..n).find(|&i| self.get(i).is_some_and(|st| st.v == 0.0 && st.a == 0.0))
    }
    fn for_each(&mut self, mut f: impl FnMut(&mut GenState)) {
        let c = self.cap();
        for i in 0..self.len {
            f(&mut self.buf[(self.head + i) % c]);
        }
    }
    /// The `i`-th entry from the front (the oldest is 0).
    fn get(&self, i: usize) -> Option<&GenState> {
        if i < self.len {
            Some(&self.buf[(self.head + i) % self.cap()])
        } else {
            None
        }
    }
    /// Drops up to `k` entries from the back; returns how many.
    fn drop_back(&mut self, k: usize) -> usize {
        let k = k.min(self.len);
        self.len -= k;
        k
    }
}

/// A dead end met by the generator: until the path position `until` is passed, generation
/// uses a stricter policy (attempt 0, 1, ...; see `generate`).
#[derive(Debug, Clone, Copy)]
struct Strict {
    /// Start of the region: the end of the last stop of the path before the dead end
    /// (where the machine is at rest whatever came before; -∞ when none is in the window).
    /// Set-points before it keep the settings' own model: a stricter one there cannot help
    /// the dead end after it.
    from: f64,
    until: f64,
    attempt: u32,
    /// Scale of the braking curve, the braking jerk and deceleration of the probe.
    f: f64,
    /// Scale of the stop model's deceleration and jerk (1 unless the dead end was on the
    /// way into a stop).
    f_stop: f64,
    /// The stop the dead end was on the way into (NaN: none), and the deceleration and jerk
    /// of the stop model there: the model before it in the region uses no more.
    stop_at: f64,
    a_stop: f64,
    j_stop: f64,
}

/// Jerk-limited, look-ahead path planner and interpolator. See the crate documentation.
pub struct Planner<K: Kinematics> {
    kin: K,
    lim: Lim,
    /// The set-point check's largest steps per axis, from `lim` and `period`.
    steps: StepLimits,
    period: f64,
    q: Ring,
    builder: Builder,
    /// Changes with every change of `builder` (push, flush, stop, reset): a
    /// [`PreparedMove`] copied before one is out of date.
    geometry_generation: u64,
    scratch: Vec<Piece>,
    fo: f64,
    ro: f64,
    /// Overrides requested while the machine brakes into a stop that the new settings'
    /// model cannot stop at from the emitted state: they take effect there
    /// ([`Planner::change_overrides`]).
    override_pending: Option<PendingOverride>,
    hold: Option<Hold>,
    /// A resume requested while the hold's stop brakes harder than the path's own stop
    /// model could continue: the hold's stop goes on until that model fits
    /// ([`Planner::resume`]).
    resume_waits: bool,
    stats: RunStats,
    a_min: f64,
    j_min: f64,
    qa_min: f64,
    qj_min: f64,
    /// A quick stop has just come to rest: its landing's last steps, still in the
    /// set-point history, were planned with the quick-stop limits.
    quick_rest: bool,
    /// Path position of the end of the window.
    cum_end: f64,
    /// State of the last emitted set-point.
    cur: GenState,
    /// Set-points generated ahead, not yet emitted.
    ahead: GenBuffer,
    /// How far ahead (periods) the generator runs: the longest stop of the machine.
    depth: usize,
    strict: Option<Strict>,
    /// A rollback's model the generator has passed, kept until the emitted set-point has
    /// passed it too (see `leave_strict`).
    strict_passed: Option<Strict>,
    /// Time-optimal S-curve of an isolated straight line (rest to rest) with the id of its
    /// piece: such a move follows the OTG's profile instead of the period-by-period policy.
    line_profiles: [Option<(u64, Profile)>; PROFILE_SLOTS],
    /// Diagnostic trace of the generator on stderr: the `diagnostics` feature and
    /// `RTCNC_MOTION_TRACE` set when the planner is built (see `trace!`).
    trace: bool,
    /// The last emitted states, newest last (the newest is `cur`), so that emission can go
    /// back over them ([`Planner::unemit`]); empty capacity: no history. The pieces they
    /// are on stay in the window.
    emitted: GenBuffer,
}

/// Why [`Planner::unemit`] could not go back.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum RewindError {
    /// Further back than the history kept ([`Planner::with_history`]), or past the end of
    /// a stop or a reset, which drop the path.
    #[error("cannot go back {asked} set-points: {kept} are kept")]
    NotKept {
        /// Set-points asked to go back over.
        asked: usize,
        /// Set-points that can be gone back over now.
        kept: usize,
    },
    /// The state to go back to follows an isolated line's S-curve evicted since.
    #[error("the line profile of the state to go back to has been evicted")]
    ProfileEvicted,
}

impl RewindError {
    /// Stable code.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn code(&self) -> &'static str {
        match self {
            RewindError::NotKept { .. } => "motion.rewind_not_kept",
            RewindError::ProfileEvicted => "motion.rewind_profile_evicted",
        }
    }
}

impl<K: Kinematics> Planner<K> {
    /// A planner for a machine with `limits` and `kinematics`, a servo period in seconds, a
    /// look-ahead window of `window` pieces (at least 16; memory is fixed at construction),
    /// starting at rest at axis position `start`.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn new(
        limits: &MachineLimits,
        kinematics: K,
        servo_period: f64,
        window: usize,
        start: AxisVec,
    ) -> Result<Self, MotionError> {
        limits.validate()?;
        if !(servo_period.is_finite() && servo_period > 0.0) {
            return Err(MotionError::InvalidLimit {
                what: "servo period".into(),
                value: servo_period,
            });
        }
        if !start.iter().all(|x| x.is_finite()) {
            return Err(MotionError::InvalidLimit {
                what: "start position".into(),
                value: f64::NAN,
            });
        }
        let mut lim = Lim::from(limits);
        // Trivial kinematics only: fold joint limits into the axes they follow.
        for jn in 0..kinematics.joint_count() {
            let Some(axis) = kinematics.joint_axis(jn) else {
                return Err(MotionError::Kinematics(
                    "non-trivial kinematics needs joint limits projected through the Jacobian, which is not implemented".into(),
                ));
            };
            let i = axis as usize;
            if !lim.present[i] {
                return Err(MotionError::Kinematics(format!(
                    "joint {jn} follows axis {} which has no limits",
                    axis.letter()
                )));
            }
            if let Some(jl) = kinematics.joint_limits(jn) {
                lim.v[i] = lim.v[i].min(jl.max_velocity);
                lim.min[i] = lim.min[i].max(jl.min_position);
                lim.max[i] = lim.max[i].min(jl.max_position);
                if lim.min[i] > lim.max[i] {
                    return Err(MotionError::Kinematics(format!(
                        "joint {jn}: empty position range"
                    )));
                }
            }
        }
        lim.resolve_jerk_at(servo_period);
        let pick = |x: &[f64; AXES]| {
            (0..AXES)
                .filter(|i| lim.present[*i])
                .fold(f64::INFINITY, |m, i| m.min(x[i]))
        };
        let (a_min, j_min, qa_min, qj_min) =
            (pick(&lim.a), pick(&lim.j), pick(&lim.qa), pick(&lim.qj));
        // Room for the pieces a flush adds and one move's.
        let window = window.max(MIN_WINDOW);
        // The generator runs one longest stop ahead (fastest path speed, weakest axis), so
        // that a dead end can be undone by regenerating set-points not yet emitted.
        let v_path = (0..AXES)
            .filter(|i| lim.present[*i])
            .map(|i| lim.v[i] * lim.v[i])
            .sum::<f64>()
            .sqrt();
        let t_stop = v_path / a_min + a_min / j_min;
        let depth = ((t_stop / servo_period).ceil() as usize + 8).clamp(16, 2048);
        let cur = GenState::rest(start, 0, 0.0);
        Ok(Planner {
            kin: kinematics,
            steps: StepLimits::new(&lim, servo_period),
            lim,
            period: servo_period,
            q: Ring::new(window),
            builder: Builder::new(start),
            geometry_generation: 0,
            scratch: Vec::with_capacity(PIECES_PER_MOVE + FLUSH_PIECES),
            fo: 1.0,
            ro: 1.0,
            override_pending: None,
            hold: None,
            resume_waits: false,
            stats: RunStats::default(),
            a_min,
            j_min,
            qa_min,
            qj_min,
            quick_rest: false,
            cum_end: 0.0,
            cur,
            ahead: GenBuffer::new(depth + 1, cur),
            depth,
            strict: None,
            strict_passed: None,
            line_profiles: [None; PROFILE_SLOTS],
            trace: cfg!(feature = "diagnostics")
                && std::env::var_os("RTCNC_MOTION_TRACE").is_some(),
            emitted: GenBuffer::new(0, cur),
        })
    }

    /// Moves that can be pushed now without [`MotionError::QueueFull`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn free(&self) -> usize {
        (self.q.cap() - self.q.len).saturating_sub(FLUSH_PIECES) / PIECES_PER_MOVE
    }

    /// Adds a move to the look-ahead window. Errors (bad input, soft limits) carry the move's
    /// line; the move is then not taken and the planner state is unchanged. `QueueFull`: try
    /// again after some periods.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn push(&mut self, mv: &Move) -> Result<(), MotionError> {
        self.push_all(std::slice::from_ref(mv)).and_then(|n| {
            if n == 1 {
                Ok(())
            } else {
                Err(MotionError::QueueFull)
            }
        })
    }

    /// Adds as many of `moves` as there is room for and returns how many were taken; the
    /// braking curve is updated once for all of them (cheaper than one [`Planner::push`]
    /// each). Stops at the first bad move and returns its error (the moves before it are
    /// taken).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn push_all(&mut self, moves: &[Move]) -> Result<usize, MotionError> {
        if matches!(self.hold, Some(h) if h.kind != StopKind::Hold) {
            return Err(MotionError::Busy("stopping"));
        }
        let first_new = self.q.len;
        let mut taken = 0;
        let mut result = Ok(());
        for mv in moves {
            if self.free() == 0 {
                break;
            }
            self.scratch.clear();
            self.geometry_generation = self.geometry_generation.wrapping_add(1);
            if let Err(e) = self.builder.push(mv, &self.lim, &mut self.scratch) {
                result = Err(e);
                break;
            }
            self.append_scratch(false);
            taken += 1;
        }
        if self.q.len > first_new {
            self.update_curve(first_new);
        }
        result.map(|()| taken)
    }

    /// Emits the moves held back for blending; the path then ends with a stop. Call at
    /// program end and before anything that waits for the machine to stop.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn flush(&mut self) {
        self.scratch.clear();
        self.geometry_generation = self.geometry_generation.wrapping_add(1);
        self.builder.flush(&self.lim, &mut self.scratch);
        self.append_scratch(true);
    }

    /// Feed override, 0..=2 (clamped). Takes effect at once with a jerk-limited speed change;
    /// during a hold, an abort or a quick stop, from the resume or the stop's end.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_feed_override(&mut self, f: f64) {
        let f = if f.is_finite() {
            f.clamp(0.0, 2.0)
        } else {
            0.0
        };
        let (_, ro) = self.overrides_requested();
        self.change_overrides(f, ro);
    }

    /// Rapid override, 0..=1 (clamped).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_rapid_override(&mut self, f: f64) {
        let f = if f.is_finite() {
            f.clamp(0.0, 1.0)
        } else {
            0.0
        };
        let (fo, _) = self.overrides_requested();
        self.change_overrides(fo, f);
    }

    /// Feed hold: decelerate along the path and stay there until [`Planner::resume`].
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn hold(&mut self) {
        self.resume_waits = false;
        if self.hold.is_none() {
            self.start_stop(StopKind::Hold);
        }
    }

    /// Resume after a feed hold, from where the machine stopped. Requested during the last
    /// steps of the hold's stop, it takes effect when they end (see `regenerate`).
    /// Requested while the hold's stop brakes into the path's own next stop harder than
    /// the path's stop model could go on from (the hold's model is the weakest axis's
    /// deceleration, the path's on a tight arc can be lower), it takes effect once that
    /// model fits again, at the latest at rest: continued by the path's model, the state
    /// had no way left to land and reached the stop at 1.2 mm/s, 1.05 × over the
    /// acceleration limit (the kernel fuzz target,
    /// fuzz/defects/kernel/acceleration-after-a-resume-on-a-tight-arc).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn resume(&mut self) {
        if matches!(self.hold, Some(h) if h.kind == StopKind::Hold) {
            let c = self.cur;
            if !self.path_stop_fits(&c, 1.0) {
                self.resume_waits = true;
                return;
            }
            self.resume_waits = false;
            self.settle_for_change();
            self.hold = None;
            self.cur.hold_at = f64::INFINITY;
            self.regenerate();
            trace!(
                self.trace,
                "RESUME at={} v={} a={} kept={}",
                self.cur.at,
                self.cur.v,
                self.cur.a,
                self.ahead.len
            );
            self.ahead.for_each(|st| st.hold_at = f64::INFINITY);
            if let Some(p) = self.override_pending {
                self.change_overrides(p.fo, p.ro);
            }
        }
    }

    /// Abort: decelerate along the path, then drop every queued move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn abort(&mut self) {
        self.start_stop(StopKind::Abort);
    }

    /// Quick stop (e-stop): decelerate along the path with the quick-stop deceleration and
    /// jerk, then drop every queued move.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn quick_stop(&mut self) {
        self.start_stop(StopKind::Quick);
    }

    /// Current set-point in axis space.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn position(&self) -> AxisVec {
        self.cur.hist[0]
    }

    /// Where the path ends: the end of the last move pushed, or where the planner was
    /// reset or stopped (the start of the next move).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn path_end(&self) -> AxisVec {
        self.builder.pos
    }

    /// Counters.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn stats(&self) -> RunStats {
        self.stats
    }

    /// Geometry counters (merges, blends, smoothing, stops).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn geometry_stats(&self) -> GeometryStats {
        self.builder.stats
    }

    /// Pieces in the look-ahead window (with those kept behind the emitted set-point for
    /// [`unemit`](Self::unemit)).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn window_len(&self) -> usize {
        self.q.len
    }

    /// Pieces from the emitted set-point's on: the path still to run.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn pieces_ahead(&self) -> usize {
        let behind = self.cur.id.saturating_sub(self.q.head_id);
        self.q
            .len
            .saturating_sub(usize::try_from(behind).unwrap_or(usize::MAX))
    }

    /// Where the program line of the emitted set-point ends, as far as the window holds its
    /// path: the end of the last of the consecutive pieces of that line from the emitted
    /// one on (a line's span and its corner blend, or every piece of a spline). `None` when
    /// the emitted set-point is on no piece. No allocation: for the status of every period.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn move_end(&self) -> Option<AxisVec> {
        let mut i = self.q.index(self.cur.id)?;
        let line = self.q.get(i).line;
        while i + 1 < self.q.len && self.q.get(i + 1).line == line {
            i += 1;
        }
        Some(self.q.get(i).end)
    }

    /// Id of the piece the emitted set-point lies on, `None` when it lies on none (at rest
    /// past the window's end). Pieces are numbered along the path from the planner's
    /// construction, so a caller can tell when the path reaches a piece it noted with
    /// [`next_piece_id`](Self::next_piece_id).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn emitted_piece(&self) -> Option<u64> {
        self.q.index(self.cur.id).map(|_| self.cur.id)
    }

    /// Id the next piece appended to the window will have. Right after a move is pushed
    /// this is the id of that move's first piece: the builder holds the move back until
    /// the next one decides the junction, and what the push appended is the path before
    /// it, up to and with the junction (a corner blend belongs to the move before).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn next_piece_id(&self) -> u64 {
        self.q.head_id + self.q.len as u64
    }

    /// How many servo periods the generator runs ahead of the emitted set-point at most
    /// (the machine's longest stop; the buffer is allocated at construction).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn generation_depth(&self) -> usize {
        self.depth
    }

    /// Diagnostics: per piece of the window, (length, braking curve, axis-speed bound,
    /// curvature bound) at its samples. A debugging aid (feature `diagnostics`); allocates.
    ///
    /// Real-time: no (allocates; a debugging aid).
    #[cfg(feature = "diagnostics")]
    pub fn debug_window(&self) -> Vec<PieceDump> {
        (0..self.q.len)
            .map(|i| {
                let p = self.q.get(i);
                (
                    p.len,
                    p.w[..=p.ns].to_vec(),
                    p.smp[..=p.ns].iter().map(|s| s.v_axis).collect(),
                    p.smp[..=p.ns].iter().map(|s| s.v_curve).collect(),
                    p.smp[..=p.ns]
                        .iter()
                        .map(|s| crate::axes::norm(&s.k))
                        .collect(),
                )
            })
            .collect()
    }

    /// One line per piece of the window, for diagnosis: kind, program line, length,
    /// flags and, at each sample, the braking curve and the speed bounds.
    ///
    /// Real-time: no (allocates; a debugging aid).
    #[doc(hidden)]
    pub fn debug_pieces(&self) -> Vec<String> {
        (0..self.q.len)
            .map(|i| {
                let p = self.q.get(i);
                let kind = match (&p.shape, p.corner_blend) {
                    (crate::geometry::Shape::Line { .. }, _) => "line",
                    (crate::geometry::Shape::Helix(_), _) => "arc",
                    (_, true) => "blend",
                    _ => "poly",
                };
                let f = |v: &mut dyn Iterator<Item = f64>| {
                    v.map(|x| format!("{x:.1}")).collect::<Vec<_>>().join(",")
                };
                format!(
                    "{kind:5} l{} from ({:.4},{:.4}) len={:.3} stop={} feed={:.1} w=[{}] va=[{}] vc=[{}] vp=[{}] k=[{}]",
                    p.line,
                    p.start[0],
                    p.start[1],
                    p.len,
                    p.stop_at_end as u8,
                    p.feed,
                    f(&mut p.w[..=p.ns].iter().copied()),
                    f(&mut p.smp[..=p.ns].iter().map(|s| s.v_axis)),
                    f(&mut p.smp[..=p.ns].iter().map(|s| s.v_curve)),
                    f(&mut p.smp[..=p.ns].iter().map(|s| s.v_point)),
                    p.smp[..=p.ns]
                        .iter()
                        .map(|s| format!("{:.2}", crate::axes::norm(&s.k)))
                        .collect::<Vec<_>>()
                        .join(","),
                )
            })
            .collect()
    }

    /// The kinematics.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn kinematics(&self) -> &K {
        &self.kin
    }

    /// Computes the next servo period: writes the joint positions (`joints.len()` should be
    /// the kinematics' joint count) and returns the status. Allocation-free, bounded time:
    /// one buffered set-point is emitted and the buffer is topped up with at most
    /// `1 + GEN_BUDGET` (13) generator steps, plus one forced step when nothing is buffered.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn next(&mut self, joints: &mut [f64]) -> Status {
        self.stats.periods += 1;
        self.top_up();
        let st = match self.ahead.pop_front() {
            Some(st) => st,
            None => {
                // Nothing buffered (the generator is at a dead end with nothing left to
                // roll back): the forced step emits the nearest point and counts it.
                let front = self.cur;
                self.generate_forced(&front)
            }
        };
        self.emit(st);
        if self.resume_waits {
            self.resume();
        }
        self.apply_pending_override();
        let x = self.cur.hist[0];
        self.kin.axes_to_joints(&x, joints);
        let state = match (self.cur.state, self.hold) {
            (MotionState::Moving, Some(h)) if h.kind == StopKind::Hold => MotionState::Holding,
            (MotionState::Moving, Some(_)) => MotionState::Stopping,
            (s, _) => s,
        };
        Status {
            state,
            axes: x,
            path_speed: self.cur.v,
            line: self.cur.line,
        }
    }

    /// Takes `st` as the emitted state: releases the pieces behind it and finishes an abort.
    fn emit(&mut self, st: GenState) {
        self.cur = st;
        if self.emitted.cap() > 0 {
            if self.emitted.len == self.emitted.cap() {
                self.emitted.pop_front();
            }
            self.emitted.push(st);
        }
        if let Some(s) = self.strict_passed
            && st.at > s.until
            && !(st.at < s.stop_at)
        {
            self.strict_passed = None;
        }
        self.release_behind();
        if st.stopped {
            // The quick stop's landing was planned with the quick-stop limits down to rest:
            // the periods at rest that follow are checked with them too.
            self.quick_rest = matches!(self.hold, Some(h) if h.kind == StopKind::Quick);
            self.q.clear();
            self.builder.clear(st.hist[0]);
            self.geometry_generation = self.geometry_generation.wrapping_add(1);
            self.hold = None;
            self.resume_waits = false;
            self.ahead.len = 0;
            self.strict = None;
            self.strict_passed = None;
            self.line_profiles = [None; PROFILE_SLOTS];
            self.cur.stopped = false;
            self.cur.id = self.q.head_id;
            self.cur.s = 0.0;
            self.cur.at = self.cum_end;
            self.cur.hold_at = f64::INFINITY;
            self.cur.dwell_left = None;
            self.cur.prof_t = None;
            self.cur.land_n = 0;
            self.restart_history();
        }
        self.rebase();
    }

    /// Moves the origin of path positions to the start of the emitted piece once that is
    /// [`REBASE_AFTER`] from it, so that positions stay as fine as near the program start
    /// on a path of any length (the spacing of doubles passes the 1e-12 mm within which
    /// a piece's end counts as reached at 8 192 mm). The positions are computed again as
    /// they were built: piece starts as the running sum of the lengths, stops as their
    /// piece's start plus length, a generator state's position as its piece's start plus
    /// its local arc length, so that every equality between them holds as before (a state
    /// at a stop is exactly there). Hold points and a rollback's region, which are compared
    /// by order only, move by the same amount. Bounded work (the window and the buffer),
    /// once per [`REBASE_AFTER`] of path.
    fn rebase(&mut self) {
        let base = if self.q.len > 0 {
            self.q.get(0).cum_start
        } else {
            self.cum_end
        };
        if !(base >= REBASE_AFTER) {
            return;
        }
        let old_stops = [self.strict, self.strict_passed].map(|s| s.map(|s| s.stop_at));
        let mut new_stops = [None; 2];
        let mut c = 0.0;
        for i in 0..self.q.len {
            let p = self.q.get_mut(i);
            p.cum_start = c;
            c += p.len;
        }
        self.cum_end = c;
        // Stops (and the valleys, compared by order only) backward from the window's end.
        let mut stop = (f64::INFINITY, f64::INFINITY);
        for i in (0..self.q.len).rev() {
            let last = i + 1 == self.q.len;
            let p = self.q.get_mut(i);
            if p.stop_at_end || last {
                stop = (p.stop_ahead.0, p.cum_start + p.len);
            }
            if p.stop_ahead.0 == stop.0 {
                for (old, new) in old_stops.iter().zip(new_stops.iter_mut()) {
                    if *old == Some(p.stop_ahead.0) {
                        *new = Some(stop.1);
                    }
                }
                p.stop_ahead.0 = stop.1;
            } else {
                p.stop_ahead.0 -= base;
            }
            if let Some(v) = &mut p.valley_next {
                v.0 -= base;
            }
        }
        let q = &self.q;
        let cum_end = self.cum_end;
        let place = |st: &mut GenState| {
            st.at = match q.index(st.id) {
                Some(i) => q.get(i).cum_start + st.s,
                None if st.id >= q.head_id => cum_end,
                None => st.at - base,
            };
            st.hold_at -= base;
        };
        place(&mut self.cur);
        self.ahead.for_each(place);
        // The history too: a set-point gone back to must be in the new frame.
        self.emitted.for_each(place);
        for (s, new_stop) in [&mut self.strict, &mut self.strict_passed]
            .into_iter()
            .zip(new_stops)
        {
            if let Some(s) = s {
                s.from -= base;
                s.until -= base;
                s.stop_at = new_stop.unwrap_or(s.stop_at - base);
            }
        }
    }

    /// Releases the pieces behind the emitted set-point, except those the history is on.
    fn release_behind(&mut self) {
        let keep_from = self.emitted.get(0).map_or(self.cur.id, |oldest| oldest.id);
        while self.q.len > 0 && self.q.head_id < keep_from.min(self.cur.id) {
            self.q.pop();
        }
    }

    /// The history starts again at the emitted state (the path behind it was dropped).
    fn restart_history(&mut self) {
        self.emitted.len = 0;
        let cur = self.cur;
        self.emitted.push(cur);
    }

    /// Keeps the last `periods` emitted set-points so that [`unemit`](Self::unemit) can go
    /// back over them, for a caller that computes set-points ahead of the period they are
    /// applied in and must still let an on-line change act at once. The pieces they are on
    /// stay in the window meanwhile and take room in it ([`free`](Self::free)). Allocates:
    /// call at set-up.
    ///
    /// Real-time: no (set-up: allocates).
    pub fn with_history(mut self, periods: usize) -> Self {
        self.emitted = GenBuffer::new(periods + 1, self.cur);
        self.restart_history();
        self
    }

    /// Set-points [`unemit`](Self::unemit) can go back over now.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn unemittable(&self) -> usize {
        self.emitted.len.saturating_sub(1)
    }

    /// Goes back over the last `n` emitted set-points: the next [`next`](Self::next) emits
    /// the first of them again, exactly as before unless an on-line change (hold, override,
    /// abort, quick stop) is made in between, which then acts from there on, as if it had
    /// come when that set-point was due. A change made after those set-points were emitted
    /// cannot be undone this way: go back before making a change, not after. Allocation-free;
    /// refused, with nothing changed, beyond the history ([`with_history`](Self::with_history))
    /// or across the end of a stop or a reset.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn unemit(&mut self, n: usize) -> Result<(), RewindError> {
        if n == 0 {
            return Ok(());
        }
        let kept = self.unemittable();
        if n > kept {
            return Err(RewindError::NotKept { asked: n, kept });
        }
        let Some(&back_to) = self.emitted.get(self.emitted.len - 1 - n) else {
            return Err(RewindError::NotKept { asked: n, kept });
        };
        if back_to.prof_t.is_some() && self.profile_of(back_to.id).is_none() {
            return Err(RewindError::ProfileEvicted);
        }
        for _ in 0..n {
            if let Some(st) = self.emitted.pop_back() {
                self.ahead.push_front(st);
            }
        }
        self.cur = back_to;
        self.stats.periods = self.stats.periods.saturating_sub(n as u64);
        Ok(())
    }

    /// Fills the buffer up to the generation depth with bounded work.
    fn top_up(&mut self) {
        // The emitted period itself needs one step; the budget is for refilling.
        let mut work = 0;
        while self.ahead.len < self.depth && work <= GEN_BUDGET {
            let front = *self.ahead.back().unwrap_or(&self.cur);
            // At rest with nothing to do: one entry ahead is enough (a push or resume
            // regenerates anyway).
            let resting = matches!(front.state, MotionState::Idle | MotionState::Holding)
                && front.v == 0.0
                && front.a == 0.0;
            if resting && self.ahead.len >= 1 {
                break;
            }
            if front.stopped {
                break;
            }
            work += 1;
            self.generate_one(&front);
        }
    }

    /// After an override change while the emitted set-point follows an isolated line's
    /// S-curve: a new time-optimal S-curve from the emitted state to the line's end under
    /// the new feed. (Handing over to the speed policy there would leave it a state that
    /// brakes at the full limits, which its stop model, with its margins, cannot follow.)
    fn replan_line_profile(&mut self) {
        let c = self.cur;
        let kept = self.profile_of(c.id).filter(|_| c.prof_t.is_some());
        let on_profile = kept.is_some();
        // Every other S-curve was planned with the old feed.
        self.line_profiles = [None; PROFILE_SLOTS];
        let Some(idx) = self.q.index(c.id).filter(|_| on_profile) else {
            self.cur.prof_t = None;
            return;
        };
        // A stop (hold, abort, quick stop) whose S-curve is the stop (it ends at the line's
        // end, braking at the full limits): the override changes nothing of a stop in
        // progress, and the speed policy could not follow that braking (at 0 % it ran past
        // the line's end, whose set-point stood still from a speed of 5 mm/s).
        let line_end = self.q.get(idx).cum_start + self.q.get(idx).len;
        if let Some(profile) = kept
            && self.hold.is_some()
            && c.hold_at >= line_end
        {
            self.keep_profile(c.id, profile);
            return;
        }
        let from = OtgState {
            p: c.s,
            v: c.v,
            a: c.a,
        };
        match self.line_profile_from(idx, from) {
            Some(profile) => {
                self.keep_profile(c.id, profile);
                self.cur.prof_t = Some(0.0);
            }
            // None under the new feed (0 %): the speed policy stops along the path, unless
            // the S-curve already brakes for the line's end or the end comes before the
            // policy could stop (with the weakest axis's limits): the S-curve, which stops
            // there within the limits, goes on (the policy ran past the end, where the
            // set-point stood still from speed).
            None => {
                let (d, _) = stop(
                    c.v,
                    c.a.max(-self.a_min),
                    STOP_SHARE * self.a_min,
                    STOP_JERK_SHARE * self.j_min,
                );
                let brakes_for_its_end =
                    |p: &Profile| c.a < 0.0 && c.prof_t.is_some_and(|t| p.only_slows_after(t));
                match kept {
                    Some(profile) if brakes_for_its_end(&profile) || line_end <= c.at + d => {
                        self.keep_profile(c.id, profile);
                    }
                    _ => self.cur.prof_t = None,
                }
            }
        }
    }

    /// The S-curve kept for piece `id`.
    fn profile_of(&self, id: u64) -> Option<Profile> {
        self.line_profiles
            .iter()
            .flatten()
            .find(|(pid, _)| *pid == id)
            .map(|(_, p)| *p)
    }

    /// Keeps the S-curve of piece `id`, in its own slot, a free one, or the one of a piece
    /// already passed, else the one farthest ahead (never the emitted piece's: it may have
    /// been replanned from a moving state).
    fn keep_profile(&mut self, id: u64, profile: Profile) {
        let cur = self.cur.id;
        // A piece the history is on may be gone back to: not passed yet in that sense.
        let passed_before = self.emitted.get(0).map_or(cur, |oldest| oldest.id.min(cur));
        let slots = &self.line_profiles;
        let pick = slots
            .iter()
            .position(|e| matches!(e, Some((pid, _)) if *pid == id))
            .or_else(|| slots.iter().position(|e| e.is_none()))
            .or_else(|| {
                slots
                    .iter()
                    .position(|e| matches!(e, Some((pid, _)) if *pid < passed_before))
            })
            .or_else(|| {
                (0..PROFILE_SLOTS)
                    .filter(|i| matches!(slots[*i], Some((pid, _)) if pid != cur))
                    .max_by_key(|i| slots[*i].map_or(0, |(pid, _)| pid))
            });
        if let Some(i) = pick {
            self.line_profiles[i] = Some((id, profile));
        }
    }

    /// The overrides in force, or those waiting for the stop the machine brakes into.
    fn overrides_requested(&self) -> (f64, f64) {
        self.override_pending
            .map_or((self.fo, self.ro), |p| (p.fo, p.ro))
    }

    /// Sets the overrides and regenerates from the emitted set-point, unless the emitted
    /// state, braking into a stop, can no longer stop there under the new settings: then
    /// they take effect once the machine is at rest (or has passed that stop's piece, when
    /// pushed moves removed the stop), and the set-points go on as generated. A higher
    /// feed can lower the braking curve and the stop model on a curve, whose deceleration
    /// is estimated at the speeds the feed allows: a state braking into a stop then lost
    /// the model. Braking as hard as the path allows recovered from some of those, not
    /// from all: with two overrides 4 ms apart 0.76 mm before the end of an arc, the first
    /// (lower feed, a stronger model) released the braking and the second (higher) left a
    /// state that even the axes' full limits could not stop within the way left, and it
    /// passed the stop at 0.6 mm/s, 15 × over the jerk limit. The path stops there anyway.
    fn change_overrides(&mut self, fo: f64, ro: f64) {
        if fo == self.fo && ro == self.ro {
            self.override_pending = None;
            return;
        }
        // A hold, abort or quick stop brakes as its own stop says; an override given
        // meanwhile waits for the resume. Regenerated at a feed of 5.2 %, a hold's stop on
        // an arc went on at that feed, held, for more than half a second (the kernel fuzz
        // target, fuzz/defects/kernel/hold-at-5-percent-override-on-a-tight-arc).
        if self.hold.is_some() {
            self.override_pending = Some(PendingOverride {
                fo,
                ro,
                until: u64::MAX,
            });
            return;
        }
        self.settle_for_change();
        let (generated, strict, strict_passed) = (self.ahead.len, self.strict, self.strict_passed);
        let old = (self.fo, self.ro);
        (self.fo, self.ro) = (fo, ro);
        self.update_curve(0);
        let c = self.cur;
        if self.hold.is_none()
            && let Some((idx, p)) = self.moving_piece(&c)
            && !self.stop_fits(&c, 1.0)
            && self.braking_for_stop(&c)
        {
            // The stop's piece, before the curve goes back (the stop stays where it is).
            let stop_at = p.stop_ahead.0;
            let rem = self.to_stop(&c, p);
            let (k, _) = self.find(idx, stop_at, stop_at);
            let until = self.q.head_id + k as u64;
            (self.fo, self.ro) = old;
            self.update_curve(0);
            // What the update dropped was generated under these settings: it stands.
            (self.ahead.len, self.strict, self.strict_passed) = (generated, strict, strict_passed);
            self.override_pending = Some(PendingOverride { fo, ro, until });
            trace!(
                self.trace,
                "OVERRIDE DEFERRED at={} v={} a={} rem={rem} until={until}", c.at, c.v, c.a
            );
            return;
        }
        self.override_pending = None;
        self.replan_line_profile();
        self.regenerate();
    }

    /// Applies the overrides that waited for a stop, once the emitted state is at rest or
    /// past the stop's piece.
    fn apply_pending_override(&mut self) {
        if let Some(p) = self.override_pending
            && ((self.cur.v == 0.0 && self.cur.a == 0.0) || self.cur.id > p.until)
        {
            self.override_pending = None;
            self.change_overrides(p.fo, p.ro);
        }
    }

    /// Drops the generated set-points: generation restarts from the emitted state (after
    /// an on-line change). Except when the machine comes to rest a few set-points ahead:
    /// the last periods of a stop are an exact discrete landing that the speed policy
    /// cannot continue from (releasing the deceleration at its jerk would reverse the path
    /// within the period), so the landing ends and generation restarts from rest.
    ///
    /// A rollback's stricter model whose dead end still lies ahead of where generation
    /// restarts stays in force, as it does through pushes (`truncate_from`):
    /// the set-points it had generated past its dead end are dropped, and without it the
    /// regenerated ones met the same dead end again, now only a few tens of periods ahead
    /// of the emitted set-point, with the escalation back at its first attempt; the
    /// emitted set-point went on along the attempts known to fail and the rollbacks could
    /// no longer reach a state that avoids it (seed 7, program 1854 of `online_changes.rs`'s
    /// arc family with an override of 97 % some 50 periods before its dead end: 1.08 × the
    /// jerk limit; program 18200 on an earlier braking curve: 1.4 ×). A stricter model
    /// than the new settings need only costs speed up to the dead end, and only after the
    /// last stop of the path before it (`Strict::from`): capping the braking curve on the
    /// way into a stop the dead end lies beyond left a state on that curve no room to land
    /// (program 63: 1.56 ×). A hold, an abort and a quick stop keep it too: where their
    /// own stop reaches past the path's next stop, the path's stop is theirs, and without
    /// the model its dead end came back with nothing generated before it to roll back to
    /// (`online_changes.rs`: a hold 3.5-4.8 mm or an abort 3.5-5.5 mm before a program's
    /// end at 76 mm/s; the end reached at up to 4.3 × the acceleration and 86 × the jerk
    /// limit).
    fn regenerate(&mut self) {
        let c = &self.cur;
        // At rest there is no landing to finish: generation restarts from here.
        self.ahead.len = if c.v == 0.0 && c.a == 0.0 {
            0
        } else {
            self.ahead.rest_within(FINISH_STOP).map_or(0, |k| k + 1)
        };
        let region = self.strict.or(self.strict_passed);
        let from = self.ahead.back().map_or(self.cur.at, |b| b.at);
        (self.strict, self.strict_passed) = match region {
            // Generated again before its dead end: in force from the restart on.
            Some(s) if from <= s.until => (Some(s), None),
            // Just past it: a dead end met there continues its escalation (`rollback`).
            Some(s) => (None, Some(s)),
            None => (None, None),
        };
    }

    /// Before an on-line change: the set-points up to a rest within `FINISH_STOP` periods
    /// (a landing the change lets end) are generated under the settings before it, so that
    /// what [`regenerate`](Self::regenerate) keeps does not depend on how far generation
    /// had happened to run ahead (after [`unemit`](Self::unemit) it has run further).
    fn settle_for_change(&mut self) {
        // Bounded: a dead end in the landing rolls back to the emitted state, and the same
        // steps can meet it again for ever (a rapid at a 0 % override stopping short of its
        // end did). Nothing is emitted here, so the dead end is left to `next`, whose
        // rollbacks escalate between emitted set-points.
        for _ in 0..SETTLE_STEPS {
            if self.ahead.len >= FINISH_STOP {
                break;
            }
            let front = *self.ahead.back().unwrap_or(&self.cur);
            if front.stopped || (front.v == 0.0 && front.a == 0.0) {
                break;
            }
            self.generate_one(&front);
        }
    }

    /// After the braking curve changed from path position `from` on: drops the generated
    /// set-points that may have seen the change (their stop reaches past it).
    fn truncate_from(&mut self, from: f64) {
        let (amax, jmax) = (self.a_min, self.j_min);
        while let Some(b) = self.ahead.back() {
            let (d, _) = stop(b.v, b.a.max(-amax), 0.5 * amax, 0.5 * jmax);
            if b.at + d + 4.0 * b.v * self.period >= from {
                self.ahead.len -= 1;
            } else {
                break;
            }
        }
        // A rollback's stricter model stays in force where set-points are generated again
        // before its dead end, also where the braking curve changed (moves appended far
        // ahead re-run the pass back to the last real stop, the curve at the dead end
        // being the same): dropping it restarted its escalation from the first attempt at
        // every push (see `leave_strict`). A model stricter than the new curve needs only
        // costs speed up to the dead end.
        let back = self.ahead.back().map_or(self.cur.at, |b| b.at);
        if self.strict.is_none()
            && let Some(s) = self.strict_passed
            && back <= s.until
        {
            self.strict = Some(s);
            self.strict_passed = None;
        }
    }

    // ---------------------------------------------------------------- window

    fn append_scratch(&mut self, update: bool) {
        let first_new = self.q.len;
        let n = self.scratch.len();
        let lim = self.lim;
        for p in self.scratch.iter_mut() {
            // (In place: a piece is a few kB, copied once, into the window.)
            if !p.sampled {
                p.sample(&lim);
            }
            p.set_tangent_limits(&lim);
            if self.q.len > 0 {
                let last = self.q.get_mut(self.q.len - 1);
                if !last.stop_at_end {
                    junction(last, p, &lim, self.period);
                }
            }
            p.cum_start = self.cum_end;
            self.cum_end += p.len;
            self.q.push(p);
        }
        if n > 0 && update {
            self.update_curve(first_new);
        }
    }

    /// Re-runs the braking curve from piece `first_new` backwards and drops the generated
    /// set-points that saw the changed part.
    fn update_curve(&mut self, first_new: usize) {
        let lowest = self.backward(first_new);
        let from = if lowest < self.q.len {
            self.q.get(lowest).cum_start
        } else {
            self.cum_end
        };
        // The window's old end was a stop: whatever saw it is regenerated.
        self.truncate_from(from.min(if first_new > 0 {
            let p = self.q.get(first_new - 1);
            p.cum_start + p.len
        } else {
            from
        }));
    }
    /// Backward pass of the braking curve from the end of the window; stops early once
    /// pieces before `first_new` no longer change. Then the forward pass over the pieces it
    /// reached, whose first it returns.
    fn backward(&mut self, first_new: usize) -> usize {
        let n = self.q.len;
        let (fo, ro) = (self.fo, self.ro);
        let lim = self.lim;
        let mut next_w: f64 = 0.0;
        let mut run_a = f64::INFINITY;
        let mut run_j = f64::INFINITY;
        let v_jerk = 2.0 * self.a_min * self.a_min / self.j_min;
        let mut lowest = n;
        // Whether the curve at the sample after the current one is braking-determined, and
        // the nearest valley ahead.
        let mut next_braking = true;
        let mut valley: Option<(f64, f64, f64, f64)> = None;
        let mut stop_ahead = (f64::INFINITY, 0.0, 0.0);
        // Whether the backward run has left the stop's own low-speed stretch (the braking
        // curve rose above twice the jerk-dominated speed): from there on the stop model's
        // deceleration and jerk are frozen, not reset, so that it never falls between two
        // pieces on the way into the stop (see `a_to_stop`).
        let mut zone_done = false;
        let t = self.period;
        for i in (0..n).rev() {
            let p = self.q.get_mut(i);
            let is_stop = p.stop_at_end || i + 1 == n;
            if is_stop {
                // Braking into the stop: the deceleration of its last sub-interval at rest.
                let ns_last = p.ns;
                let a_end = if p.len > 0.0 {
                    p.decel_available(ns_last, 0.0, &lim).min(p.decel_available(
                        ns_last.saturating_sub(1),
                        0.0,
                        &lim,
                    ))
                } else {
                    0.0
                };
                stop_ahead = (p.cum_start + p.len, a_end, p.j_brake);
                next_w = 0.0;
                run_a = f64::INFINITY;
                run_j = f64::INFINITY;
                zone_done = false;
                next_braking = true;
                valley = None;
            }
            let old = (p.w[0], p.a_to_stop);
            let old_valley = p.valley_next;
            let ns = p.ns;
            p.valley_next = valley;
            p.valley_in = None;
            p.stop_ahead = stop_ahead;
            p.w[ns] = next_w.min(p.vlc(ns, fo, ro));
            if p.len <= 0.0 {
                for k in 0..ns {
                    p.w[k] = p.w[ns];
                    p.a_sub[k] = f64::INFINITY;
                }
            } else {
                let h = p.len / ns as f64;
                for k in (0..ns).rev() {
                    let vl = p.vlc_span(k, fo, ro).min(p.vlc_span(k + 1, fo, ro));
                    let w1 = p.w[k + 1];
                    let d1 = p.decel_available_pair(k, w1, &lim);
                    let west = vl.min((w1 * w1 + 2.0 * h * d1).sqrt());
                    let d2 = p.decel_available_pair(k, west, &lim);
                    let acc = d1.min(d2);
                    p.a_sub[k] = acc;
                    let wfull = (w1 * w1 + 2.0 * h * acc).sqrt();
                    p.w[k] = vl.min(wfull).min(p.smp[k].v_point);
                    // A braking section that ends at sample k+1 on a limit (not at a stop).
                    // It may begin inside this sub-interval (a line's only one, long enough
                    // to rise to its limit and brake again): the curve is below the limit at
                    // k+1 and level after it.
                    let braking_here = wfull < vl;
                    if w1 < vl && !next_braking && w1 > 0.0 {
                        let sv = h * (k + 1) as f64;
                        p.valley_in = Some((sv, w1, acc, p.j_brake));
                        valley = Some((p.cum_start + sv, w1, acc, p.j_brake));
                    }
                    next_braking = braking_here;
                    // The stop model of the controller (constant deceleration, jerk-limited
                    // ends) matters where the stop is jerk-dominated, at low speed; above, the
                    // braking curve with its varying deceleration governs.
                    if w1 <= v_jerk && !zone_done {
                        run_a = run_a.min(acc);
                        run_j = run_j.min(p.j_brake);
                    } else if w1 > 2.0 * v_jerk {
                        zone_done = true;
                    }
                }
            }
            // Far from the stop the braking curve governs: a piece from whose end every
            // state under the curve (accelerating at most as hard as the path allows) can
            // still stop with the stop's own model keeps none (the generator takes the
            // piece's own deceleration and jerk), which also keeps the backward pass short
            // when moves are appended. Nearer pieces keep the frozen model, so that a state
            // that enters them fits it: they used to lose it once the curve rose above
            // 2·v_jerk inside them and take their first sub-interval's deceleration (a
            // spline's tight bend: 240 mm/s² after 530 on the piece before), under which
            // a state that fitted the piece before could not stop.
            let free = zone_done && run_a.is_finite() && {
                let v_end = p.w[ns] + 0.5 * run_j * t * t;
                let (d, _) = stop(
                    v_end,
                    p.a_proj[0],
                    STOP_SHARE * run_a,
                    STOP_JERK_SHARE * run_j,
                );
                d <= stop_ahead.0 - (p.cum_start + p.len)
            };
            (p.a_to_stop, p.j_to_stop) = if free {
                (f64::INFINITY, f64::INFINITY)
            } else {
                (run_a, run_j)
            };
            next_w = p.w[0];
            lowest = i;
            if i < first_new
                && (p.w[0] - old.0).abs() <= 1e-12
                && p.a_to_stop == old.1
                && p.valley_next == old_valley
            {
                break;
            }
        }
        trace!(
            self.trace,
            "BACKWARD n={n} first_new={first_new} lowest={lowest}"
        );
        self.forward_cap(lowest);
        self.refresh_stop_ahead(lowest);
        lowest
    }

    /// Forward pass of the braking curve over the pieces from `lowest` (those the backward
    /// pass changed): a rise of the curve is capped by the acceleration available, so that
    /// the curve has no notches finer than the controller can follow; then each piece's
    /// lowest speed (`w_low`).
    fn forward_cap(&mut self, lowest: usize) {
        let n = self.q.len;
        let lim = self.lim;
        let mut wf = if lowest > 0 {
            let p = self.q.get(lowest - 1);
            p.w[p.ns]
        } else {
            f64::INFINITY
        };
        for i in lowest..n {
            let p = self.q.get_mut(i);
            let ns = p.ns;
            p.w[0] = p.w[0].min(wf);
            if p.len > 0.0 {
                let h = p.len / ns as f64;
                for k in 0..ns {
                    let w0 = p.w[k];
                    let acc = p.accel_available_pair(k, w0, &lim);
                    p.acc_sub[k] = acc;
                    p.w[k + 1] = p.w[k + 1].min((w0 * w0 + 2.0 * h * acc).sqrt());
                }
            }
            wf = p.w[ns];
            // Within a sub-interval the curve lies above both samples and the speed
            // limit's lower sample (see `Piece::w_at`).
            let mut low = p.w[0];
            for k in 0..ns {
                let vl = p
                    .vlc_span(k, self.fo, self.ro)
                    .min(p.vlc_span(k + 1, self.fo, self.ro));
                p.vl_sub[k] = vl;
                low = low.min(p.w[k + 1]).min(vl);
            }
            // The jerk-limited approach to a valley after the piece is lowest at its end.
            if let Some((dist, v0, a, j)) = p.valley_ahead(p.len)
                && !crate::piece::jerk_valley_speed_is_above(dist, v0, a, j, low)
            {
                low = low.min(crate::piece::jerk_valley_speed(dist, v0, a, j).0);
            }
            p.w_low = low;
        }
    }

    /// Pieces before the backward pass's early break keep their curve, but the next stop
    /// may have moved (the window's old end was one): refreshes it back to the previous
    /// real stop.
    fn refresh_stop_ahead(&mut self, lowest: usize) {
        if lowest > 0 {
            let sa = self.q.get(lowest).stop_ahead;
            for i in (0..lowest).rev() {
                let p = self.q.get_mut(i);
                if p.stop_at_end || p.stop_ahead == sa {
                    break;
                }
                p.stop_ahead = sa;
            }
        }
    }

    fn start_stop(&mut self, kind: StopKind) {
        self.resume_waits = false;
        self.settle_for_change();
        let (a, j) = match kind {
            StopKind::Quick => (self.qa_min, self.qj_min),
            _ => (0.5 * self.a_min, 0.5 * self.j_min),
        };
        let (a, j) = match kind {
            StopKind::Quick => (a * BRAKE_SHARE_STRAIGHT, j * BRAKE_SHARE_STRAIGHT),
            _ => (a, j),
        };
        // The hold point is where the generator's stop model ends, plus one period's travel
        // of slack for the discrete landing (none for a quick stop: it brakes at once; the
        // hold point moves on when the path does not let the axes brake that hard).
        let c = self.cur;
        let j_full = self.q.index(c.id).map_or(j, |i| {
            let quick = kind == StopKind::Quick;
            generate::CONTROL_SHARE * self.q.get(i).j_proj[quick as usize]
        });
        let d = stop_reach(
            c.v,
            c.a.max(-a),
            STOP_SHARE * a,
            STOP_JERK_SHARE * j,
            j_full,
        );
        let slack = if kind == StopKind::Quick {
            0.0
        } else {
            c.v * self.period
        };
        // An abort during a hold's (or an abort's) stop brakes as that stop does: it keeps
        // the point the machine already brakes for when that comes first. Recomputed from
        // the braking state, the point could fall past the path's next stop, which then
        // became the goal under the path's own model: at the end of a tight arc that
        // model had no stop left from the hold's state, and the set-points reached the
        // arc's end at 1 mm/s, up to 22 × over the jerk limit (the kernel fuzz target's
        // corpus, with the jerk checked).
        let braking_for = match self.hold {
            Some(h) if h.kind != StopKind::Quick && kind != StopKind::Quick => {
                Some((self.cur.hold_at, h.slack))
            }
            _ => None,
        };
        let (hold_at, slack) = match braking_for {
            Some((at, kept_slack)) if at.is_finite() && at > c.at && at < c.at + d + slack => {
                (at, kept_slack.max(slack))
            }
            _ => (c.at + d + slack, slack),
        };
        self.hold = Some(Hold { a, j, kind, slack });
        self.cur.hold_at = hold_at;
        // On an isolated line's S-curve whose end comes before this stop would, or which
        // already brakes for it (slowing down to rest at the line's end, not to a lower
        // speed after an override): the S-curve (which stops there at the full limits) is
        // the stop. Else (accelerating, cruising, or slowing to cruise, with room) the
        // speed policy takes over from the S-curve's state. An S-curve slowing to a lower
        // override's speed was taken as the stop once: an e-stop then ran on to the line's
        // end at that speed.
        let profile = c.prof_t.and_then(|t| self.profile_of(c.id).map(|p| (p, t)));
        let brakes_for_its_end = profile.is_some_and(|(p, t)| c.a < 0.0 && p.only_slows_after(t));
        let line_end = self.q.index(c.id).map_or(f64::INFINITY, |i| {
            self.q.get(i).cum_start + self.q.get(i).len
        });
        if profile.is_some() && (line_end <= c.at + d || brakes_for_its_end) {
            self.cur.hold_at = line_end;
        } else {
            self.line_profiles = [None; PROFILE_SLOTS];
            self.cur.prof_t = None;
        }
        trace!(
            self.trace,
            "STOP {kind:?} at={} v={} a={} hold_at={}", c.at, c.v, c.a, self.cur.hold_at
        );
        self.regenerate();
    }
}

/// `x` limited to [lo, hi]; never panics: an empty range gives its middle, NaN gives `lo`
/// (or 0 when both bounds are NaN).
#[inline]
fn clampf(x: f64, lo: f64, hi: f64) -> f64 {
    if !(lo <= hi) {
        let m = 0.5 * (lo + hi);
        return if m.is_nan() {
            if lo.is_nan() { 0.0 } else { lo }
        } else {
            m
        };
    }
    if x.is_nan() { lo } else { x.max(lo).min(hi) }
}

/// Most steps the landing on a stop plans ahead.
const LAND_MAX: usize = 8;

/// The landing's optimality (KKT) system for `n` steps: `[2 MᵀM  1; 1ᵀ 0] [x; λ] = [-2 Mᵀc;
/// rem]`, where `d = Mx + c` are the third differences of the positions. Its matrix depends
/// on `n` alone, so it is eliminated once, at compile time; a landing then carries only its
/// right-hand side through the same operations (the same bits as eliminating it whole, at
/// a tenth of the work: this was a tenth of the planner's time near stops).
#[derive(Clone, Copy)]
struct LandingSystem {
    /// The elimination met a zero pivot (no landing of this length).
    singular: bool,
    /// M: row r holds the weights of x in the r-th third difference.
    m: [[f64; LAND_MAX]; LAND_MAX + 2],
    /// The row swapped into place at each column (partial pivoting).
    pivot: [usize; LAND_MAX + 1],
    /// `factor[col][r]`: the multiple of row `col` taken from row `r` at column `col`.
    factor: [[f64; LAND_MAX + 1]; LAND_MAX + 1],
    /// The diagonal left after the elimination.
    diagonal: [f64; LAND_MAX + 1],
}

impl LandingSystem {
    const fn eliminated(n: usize) -> LandingSystem {
        const M: usize = LAND_MAX + 1;
        let mut sys = LandingSystem {
            singular: false,
            m: [[0.0; LAND_MAX]; LAND_MAX + 2],
            pivot: [0; M],
            factor: [[0.0; M]; M],
            diagonal: [0.0; M],
        };
        // Steps: hist[0], hist[1], x_1..x_n, 0, 0; d_m = D[m] - 2 D[m-1] + D[m-2].
        let len = n + 4;
        let rows = n + 2;
        let weights = [1.0, -2.0, 1.0];
        let mut m = 2;
        while m < len {
            let mut off = 0;
            while off < 3 {
                let idx = m - off;
                if idx >= 2 && idx < 2 + n {
                    sys.m[m - 2][idx - 2] += weights[off];
                }
                off += 1;
            }
            m += 1;
        }
        let mut k = [[0.0; M]; M];
        let mut i = 0;
        while i < n {
            let mut j = 0;
            while j < n {
                // As `Iterator::sum` adds: from -0.0, in row order.
                let mut sum = -0.0;
                let mut r = 0;
                while r < rows {
                    sum += sys.m[r][i] * sys.m[r][j];
                    r += 1;
                }
                k[i][j] = 2.0 * sum;
                j += 1;
            }
            k[i][n] = 1.0;
            k[n][i] = 1.0;
            i += 1;
        }
        let size = n + 1;
        let mut col = 0;
        while col < size {
            // The largest magnitude, the last of equals (as `Iterator::max_by` picks).
            let mut piv = col;
            let mut r = col + 1;
            while r < size {
                if k[r][col].abs() >= k[piv][col].abs() {
                    piv = r;
                }
                r += 1;
            }
            if k[piv][col].abs() < 1e-300 {
                sys.singular = true;
                return sys;
            }
            sys.pivot[col] = piv;
            let row = k[col];
            k[col] = k[piv];
            k[piv] = row;
            let mut r = 0;
            while r < size {
                if r != col {
                    let f = k[r][col] / k[col][col];
                    sys.factor[col][r] = f;
                    let mut cc = col;
                    while cc < size {
                        k[r][cc] -= f * k[col][cc];
                        cc += 1;
                    }
                }
                r += 1;
            }
            col += 1;
        }
        let mut i = 0;
        while i < size {
            sys.diagonal[i] = k[i][i];
            i += 1;
        }
        sys
    }
}

/// `LANDING_SYSTEMS[n]` for n = 1..=LAND_MAX (index 0 unused).
const LANDING_SYSTEMS: [LandingSystem; LAND_MAX + 1] = {
    let mut systems = [LandingSystem::eliminated(1); LAND_MAX + 1];
    let mut n = 2;
    while n <= LAND_MAX {
        systems[n] = LandingSystem::eliminated(n);
        n += 1;
    }
    systems
};

/// The first of `n` path steps that end exactly `rem` further and at rest, after the steps
/// `hist` (oldest first): the sequence with the smallest sum of squared third differences
/// (jerk). None when a third difference exceeds `j_step` (J·T³), a second difference
/// exceeds `a_step` (A·T²) or a step is negative.
fn land_steps(hist: [f64; 2], rem: f64, n: usize, j_step: f64, a_step: f64) -> Option<f64> {
    let sys = LANDING_SYSTEMS.get(n).filter(|_| n >= 1)?;
    if sys.singular {
        return None;
    }
    let len = n + 4;
    let rows = n + 2;
    // d = Mx + c: c holds the history's part of the first two third differences.
    let mut c = [0.0; LAND_MAX + 2];
    // In the order the whole elimination summed them (the same zeros' signs).
    c[0] += -2.0 * hist[1];
    c[0] += 1.0 * hist[0];
    c[1] += 1.0 * hist[1];
    let mut rhs = [0.0; LAND_MAX + 1];
    for i in 0..n {
        rhs[i] = -2.0 * (0..rows).map(|r| sys.m[r][i] * c[r]).sum::<f64>();
    }
    rhs[n] = rem;
    let size = n + 1;
    for col in 0..size {
        rhs.swap(col, sys.pivot[col]);
        for r in 0..size {
            if r != col {
                rhs[r] -= sys.factor[col][r] * rhs[col];
            }
        }
    }
    let mut x = [0.0; LAND_MAX];
    for i in 0..n {
        x[i] = rhs[i] / sys.diagonal[i];
    }
    if x[..n].iter().any(|v| !(*v >= 0.0)) {
        return None;
    }
    let mut d = [0.0; LAND_MAX + 4];
    d[0] = hist[0];
    d[1] = hist[1];
    d[2..2 + n].copy_from_slice(&x[..n]);
    for m in 2..len {
        if (d[m] - 2.0 * d[m - 1] + d[m - 2]).abs() > j_step || (d[m] - d[m - 1]).abs() > a_step {
            return None;
        }
    }
    Some(if n == 1 { rem } else { x[0] })
}

/// Jerk of the fastest stop: brake with -J until the speed left equals what releasing the
/// deceleration costs, then release.
fn brake_jerk(v: f64, a: f64, amax: f64, jmax: f64, t: f64) -> f64 {
    let f = |j: f64| {
        let (_, v1, a1) = advance(0.0, v, a, j, t);
        let a1c = a1.min(0.0);
        v1 - a1c * a1c / (2.0 * jmax)
    };
    let lo_bound = (-jmax).max((-amax - a) / t);
    if f(lo_bound) >= 0.0 {
        return lo_bound;
    }
    let (mut lo, mut hi) = (lo_bound, jmax);
    if f(hi) < 0.0 {
        return hi;
    }
    for _ in 0..30 {
        let mid = 0.5 * (lo + hi);
        if f(mid) >= 0.0 {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    hi
}

/// The highest speed at which a step `dt` of the unit tangent and `dk` of the curvature
/// vector can be passed between two servo periods: the step shows up in the sampled jerk of
/// each axis as v·|ΔT|/T² + v²·|ΔK|/T, which may take `JERK_SHARE_JUMP` of its jerk limit.
pub(crate) fn junction_speed(dt: &AxisVec, dk: &AxisVec, lim: &Lim, period: f64) -> f64 {
    let mut vj = f64::INFINITY;
    for i in 0..AXES {
        if !lim.present[i] {
            continue;
        }
        let c = JERK_SHARE_JUMP * lim.j[i];
        let qa = dk[i].abs() / period;
        let qb = dt[i].abs() / (period * period);
        let v = if qa > 0.0 {
            (-qb + (qb * qb + 4.0 * qa * c).sqrt()) / (2.0 * qa)
        } else if qb > 0.0 {
            c / qb
        } else {
            f64::INFINITY
        };
        vj = vj.min(v);
    }
    vj
}

/// Speed bound at a junction between two pieces that join without a stop: a step of the
/// tangent or of the curvature vector shows up in the sampled jerk as v·|ΔT|/T² + v²·|ΔK|/T.
fn junction(a: &mut Piece, b: &mut Piece, lim: &Lim, period: f64) {
    let ea = a.ns;
    let mut dt = [0.0; AXES];
    let mut dk = [0.0; AXES];
    for i in 0..AXES {
        dt[i] = b.smp[0].t[i] - a.smp[ea].t[i];
        dk[i] = b.smp[0].k[i] - a.smp[ea].k[i];
    }
    if b.len > 0.0 && a.len > 0.0 && norm(&dt) > 4.0 * KINK {
        a.stop_at_end = true;
        return;
    }
    let vj = junction_speed(&dt, &dk, lim, period);
    // Where a line meets an arc (a CAM profile's rounded corners), the line is capped at
    // the junction's point only and the arc over its sub-interval next to it: the braking
    // curve then has a plateau on the arc that the jerk-limited speed settles on. Elsewhere
    // both sides are capped over their sub-intervals: a cap at a point alone on both sides
    // is a V-shaped dip the speed cannot follow (set-points 1000 × over the jerk limit at
    // the tangent junctions of a G5 chain), and next to a spline's short last sub-interval
    // even a line's point cap was lost (5 ×, random programs of lines and splines).
    let arc = |p: &Piece| matches!(p.shape, Shape::Helix(_));
    let (point_a, point_b) = match (a.straight && arc(b), arc(a) && b.straight) {
        (true, _) => (true, false),
        (_, true) => (false, true),
        _ => (false, false),
    };
    for (sm, point) in [(&mut a.smp[ea], point_a), (&mut b.smp[0], point_b)] {
        if point {
            sm.v_point = sm.v_point.min(vj);
        } else {
            sm.v_curve = sm.v_curve.min(vj);
        }
    }
}

impl<K: Kinematics> Planner<K> {
    /// Places the planner at rest at axis position `position`, dropping every queued move and
    /// any hold: for a kernel whose machine was moved by other means (jog, homing, a stop
    /// outside the path). Allocation-free. Refuses a non-finite position.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset_at(&mut self, position: AxisVec) -> Result<(), MotionError> {
        if !position.iter().all(|x| x.is_finite()) {
            return Err(MotionError::InvalidLimit {
                what: "start position".into(),
                value: f64::NAN,
            });
        }
        self.q.clear();
        self.builder.clear(position);
        self.geometry_generation = self.geometry_generation.wrapping_add(1);
        self.line_profiles = [None; PROFILE_SLOTS];
        self.hold = None;
        self.resume_waits = false;
        self.quick_rest = false;
        self.strict = None;
        self.strict_passed = None;
        self.ahead.len = 0;
        self.cur = GenState::rest(position, self.q.head_id, self.cum_end);
        self.restart_history();
        Ok(())
    }
}

#[cfg(test)]
mod rebase_tests {
    use super::*;
    use crate::axes::Axis;
    use crate::input::PathMode;
    use crate::kinematics::TrivialKinematics;
    use crate::limits::AxisLimits;

    /// Path positions stay within the rebase threshold plus the window's length however far
    /// the program goes, and the stop positions the pieces hold stay exactly the ends of
    /// their stop pieces (the subtraction of the origin is exact).
    #[test]
    fn path_positions_stay_small_and_exact_on_a_long_program() {
        let lim = MachineLimits::uniform(
            &[Axis::X, Axis::Y],
            AxisLimits::new(1e4, 1e5, 5e6, -1000.0, 1000.0),
        );
        let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y]);
        let mut pl = Planner::new(&lim, kin, 1e-3, 64, [0.0; AXES]).unwrap();
        let mode = PathMode::Blend {
            tolerance: 0.01,
            merge_tolerance: 0.0,
        };
        // A zigzag of 200 mm lines (blended, the reversals stop): 4·10^4 mm of path.
        let moves: Vec<Move> = (0..200)
            .map(|k| {
                let mut p = [0.0; AXES];
                p[0] = if k % 2 == 0 { 190.0 } else { -10.0 };
                p[1] = if k % 4 < 2 { 20.0 } else { 0.0 };
                Move::line(p, 5e3, mode, k + 1)
            })
            .collect();
        let mut k = 0;
        let mut joints = [0.0; 2];
        let mut largest: f64 = 0.0;
        for _ in 0..200_000 {
            while k < moves.len() && pl.free() > 0 {
                pl.push(&moves[k]).unwrap();
                k += 1;
            }
            if k == moves.len() {
                pl.flush();
            }
            let st = pl.next(&mut joints);
            largest = largest.max(pl.cur.at);
            for i in 0..pl.q.len {
                let p = pl.q.get(i);
                if p.stop_at_end || i + 1 == pl.q.len {
                    assert_eq!(
                        p.stop_ahead.0,
                        p.cum_start + p.len,
                        "{i} {} {} {} {}",
                        pl.q.len,
                        p.stop_at_end,
                        p.len,
                        pl.cum_end
                    );
                }
            }
            if k == moves.len() && st.state == MotionState::Idle {
                break;
            }
        }
        assert_eq!(k, moves.len());
        assert!(pl.cur.hist[0][0] == -10.0, "{:?}", pl.cur.hist[0]);
        // 64 pieces of at most about 200 mm ahead of an origin at most REBASE_AFTER behind.
        assert!(largest < REBASE_AFTER + 64.0 * 210.0, "{largest}");
        assert!(largest < 2e4);
    }
}

#[cfg(test)]
mod landing_tests {
    use super::*;

    /// The landing as it was computed before its matrix was eliminated at compile time:
    /// the whole KKT system built and eliminated on every call.
    /// The first of `n` path steps that end exactly `rem` further and at rest, after the steps
    /// `hist` (oldest first): the sequence with the smallest sum of squared third differences
    /// (jerk). None when a third difference exceeds `j_step` (J·T³), a second difference
    /// exceeds `a_step` (A·T²) or a step is negative.
    fn land_steps_eliminated_whole(
        hist: [f64; 2],
        rem: f64,
        n: usize,
        j_step: f64,
        a_step: f64,
    ) -> Option<f64> {
        const M: usize = LAND_MAX + 1;
        // Steps: hist[0], hist[1], x_1..x_n, 0, 0. Third differences of positions are second
        // differences of steps: d_m = D[m] - 2 D[m-1] + D[m-2], m = 2..n+3.
        let len = n + 4;
        let rows = n + 2;
        // d = Mx + c.
        let mut mm = [[0.0; LAND_MAX]; LAND_MAX + 2];
        let mut c = [0.0; LAND_MAX + 2];
        for (r, m) in (2..len).enumerate() {
            for (off, w) in [(0usize, 1.0), (1, -2.0), (2, 1.0)] {
                let idx = m - off;
                if idx < 2 {
                    c[r] += w * hist[idx];
                } else if idx < 2 + n {
                    mm[r][idx - 2] += w;
                }
            }
        }
        // KKT system: [2 MᵀM  1; 1ᵀ 0] [x; λ] = [-2 Mᵀc; rem].
        let mut k = [[0.0; M + 1]; M];
        for i in 0..n {
            for j in 0..n {
                k[i][j] = 2.0 * (0..rows).map(|r| mm[r][i] * mm[r][j]).sum::<f64>();
            }
            k[i][n] = 1.0;
            k[i][n + 1] = -2.0 * (0..rows).map(|r| mm[r][i] * c[r]).sum::<f64>();
        }
        for j in 0..n {
            k[n][j] = 1.0;
        }
        k[n][n] = 0.0;
        k[n][n + 1] = rem;
        // Gaussian elimination with partial pivoting on the (n+1) x (n+2) matrix.
        let sz = n + 1;
        for col in 0..sz {
            let piv = (col..sz).max_by(|a, b| k[*a][col].abs().total_cmp(&k[*b][col].abs()))?;
            if k[piv][col].abs() < 1e-300 {
                return None;
            }
            k.swap(col, piv);
            for r in 0..sz {
                if r != col {
                    let f = k[r][col] / k[col][col];
                    for cc in col..=sz {
                        k[r][cc] -= f * k[col][cc];
                    }
                }
            }
        }
        let mut x = [0.0; LAND_MAX];
        for i in 0..n {
            x[i] = k[i][sz] / k[i][i];
        }
        if x[..n].iter().any(|v| !(*v >= 0.0)) {
            return None;
        }
        let mut d = [0.0; LAND_MAX + 4];
        d[0] = hist[0];
        d[1] = hist[1];
        d[2..2 + n].copy_from_slice(&x[..n]);
        for m in 2..len {
            if (d[m] - 2.0 * d[m - 1] + d[m - 2]).abs() > j_step || (d[m] - d[m - 1]).abs() > a_step
            {
                return None;
            }
        }
        Some(if n == 1 { rem } else { x[0] })
    }

    /// The precomputed elimination gives the same bits (and the same refusals) as the whole
    /// one, over random histories, distances, lengths and bounds.
    #[test]
    fn the_precomputed_landing_is_the_whole_elimination_bit_for_bit() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut unit = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 11) as f64 / (1u64 << 53) as f64
        };
        let mut landed = 0;
        for case in 0..200_000 {
            let scale = 10f64.powi((unit() * 8.0) as i32 - 6);
            let hist = [unit() * scale, unit() * scale];
            let rem = match case % 7 {
                0 => 0.0,
                1 => -unit() * scale,
                _ => unit() * scale * 4.0,
            };
            let n = 1 + (unit() * LAND_MAX as f64) as usize % LAND_MAX;
            let (j_step, a_step) = (unit() * scale, unit() * scale * 2.0);
            let fast = land_steps(hist, rem, n, j_step, a_step);
            let whole = land_steps_eliminated_whole(hist, rem, n, j_step, a_step);
            assert_eq!(
                fast.map(f64::to_bits),
                whole.map(f64::to_bits),
                "{hist:?} {rem} {n} {j_step} {a_step}"
            );
            landed += usize::from(fast.is_some());
        }
        // Both outcomes are reached often.
        assert!(landed > 10_000 && landed < 190_000, "{landed} landings");
    }
}

#[cfg(test)]
mod valley_tests {
    use super::*;
    use crate::axes::Axis;
    use crate::input::PathMode;
    use crate::kinematics::TrivialKinematics;
    use crate::limits::AxisLimits;

    /// A line long enough to rise to its feed between two slow corners brakes into the
    /// second within its single sub-interval. Its braking curve there is the jerk-limited
    /// deceleration that arrives at the corner's speed v0 with none left: τ before the
    /// corner (τ within the jerk phase, τ ≤ a/J) the speed is v0 + J·τ²/2 at the distance
    /// v0·τ + J·τ³/6. (Read as a braking section that does not end on a limit, the
    /// acceleration-limited curve arrived still braking, and the controller fell to a
    /// near stop at such corners of a CAM program's polylines.)
    #[test]
    fn a_line_that_brakes_inside_its_sub_interval_arrives_at_the_corner_with_no_deceleration() {
        let lim = MachineLimits::uniform(
            &[Axis::X, Axis::Y],
            AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0),
        );
        let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y]);
        let mut pl = Planner::new(&lim, kin, 1e-3, 64, [0.0; AXES]).unwrap();
        let mode = PathMode::Blend {
            tolerance: 0.01,
            merge_tolerance: 0.0,
        };
        let at = |x: f64, y: f64| {
            let mut p = [0.0; AXES];
            p[0] = x;
            p[1] = y;
            p
        };
        let (s1, c1) = 15f64.to_radians().sin_cos();
        let (s2, c2) = 30f64.to_radians().sin_cos();
        let moves = [
            Move::line(at(5.0, 0.0), 50.0, mode, 1),
            // Two turns of 15°.
            Move::line(at(5.0 + 6.0 * c1, 6.0 * s1), 50.0, mode, 2),
            Move::line(
                at(5.0 + 6.0 * c1 + 5.0 * c2, 6.0 * s1 + 5.0 * s2),
                50.0,
                mode,
                3,
            ),
        ];
        assert_eq!(pl.push_all(&moves).unwrap(), moves.len());
        pl.flush();
        // The middle line (the corners' blends trimmed from it) and the blend after it.
        let i = (0..pl.q.len)
            .find(|&i| {
                let p = pl.q.get(i);
                p.straight && p.line == 2 && p.len > 2.0
            })
            .unwrap();
        let (line, corner) = (pl.q.get(i), pl.q.get(i + 1));
        assert!(corner.corner_blend);
        let v0 = corner.w[0];
        let (a, j) = (line.a_sub[0], line.j_brake);
        // The curve rises to the feed inside the line and brakes again before its end.
        assert!(
            v0 < 20.0 && line.w[1] == v0 && line.vl_sub[0] == 50.0,
            "{v0}"
        );
        for frac in [0.1, 0.5, 0.9] {
            let tau = frac * a / j;
            let d = v0 * tau + j * tau * tau * tau / 6.0;
            let (w, decel) = line.w_at(line.len - d);
            let expect = v0 + 0.5 * j * tau * tau;
            assert!((w - expect).abs() <= 1e-9 * expect, "{frac}: {w} {expect}");
            assert!(
                (decel - j * tau).abs() <= 1e-6 * a,
                "{frac}: {decel} {}",
                j * tau
            );
        }
    }

    /// FreeCAD's adaptive clearing (`examples/cam-corpus/adaptive-profile-8mm.ngc` lines
    /// 905-915, G64 P0.02, F2000): a rapid link, then a corner blend whose braking curve
    /// levels off at a shallow valley (13.7 mm/s) just before it falls again to a deeper
    /// one on the next smoothing span. The controller follows the curve down without
    /// falling far below it: on line 910 not under 60 % of the curve's lowest speed there.
    /// (A probe that ramped only to the curve's slope on the way into the shallow valley
    /// did not reach the bend after it; the state met the bend too fast, braked as hard as
    /// the path allows and fell to 3.9 mm/s.)
    #[test]
    fn a_shallow_valley_just_before_a_deep_one_is_left_in_time() {
        let lim = MachineLimits::uniform(
            &[Axis::X, Axis::Y],
            AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0),
        );
        let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y]);
        let at = |x: f64, y: f64| {
            let mut p = [0.0; AXES];
            p[0] = x;
            p[1] = y;
            p
        };
        let mut pl = Planner::new(&lim, kin, 1e-3, 256, at(115.750, 50.344)).unwrap();
        let mode = PathMode::Blend {
            tolerance: 0.02,
            merge_tolerance: 0.02,
        };
        // (x, y, rapid) of lines 905..=915.
        let program = [
            (115.694, 50.450, false),
            (115.625, 50.538, false),
            (115.537, 50.619, true),
            (115.338, 50.731, true),
            (110.888, 52.294, true),
            (110.750, 52.337, false),
            (110.481, 52.431, false),
            (110.350, 52.456, false),
            (110.225, 52.469, false),
            (110.100, 52.456, false),
            (109.981, 52.419, false),
        ];
        let moves: Vec<Move> = program
            .iter()
            .zip(905..)
            .map(|(&(x, y, rapid), line)| {
                if rapid {
                    Move::rapid(at(x, y), mode, line)
                } else {
                    Move::line(at(x, y), 2000.0 / 60.0, mode, line)
                }
            })
            .collect();
        assert_eq!(pl.push_all(&moves).unwrap(), moves.len());
        pl.flush();
        let low = (0..pl.q.len)
            .map(|i| pl.q.get(i))
            .filter(|p| p.line == 910)
            .fold(f64::INFINITY, |m, p| m.min(p.w_low));
        let mut joints = [0.0; 2];
        let mut slowest = f64::INFINITY;
        for _ in 0..100_000 {
            let st = pl.next(&mut joints);
            if st.state == MotionState::Idle {
                break;
            }
            if st.line == 910 {
                slowest = slowest.min(st.path_speed);
            }
        }
        assert_eq!(pl.stats().limit_violations, 0);
        assert!(low > 5.0 && slowest >= 0.6 * low, "{slowest} {low}");
    }
}

#[cfg(test)]
mod override_tests {
    use super::*;
    use crate::axes::Axis;
    use crate::input::PathMode;
    use crate::kinematics::TrivialKinematics;
    use crate::limits::AxisLimits;

    fn at(x: f64, y: f64) -> AxisVec {
        let mut p = [0.0; AXES];
        p[0] = x;
        p[1] = y;
        p
    }

    /// An override keeps a rollback's stricter model whose dead end lies ahead of the
    /// emitted set-point: dropping it with the set-points generated past the dead end
    /// (seed 7, program 18200 of `tests/online_changes.rs`'s arc family, on an earlier
    /// braking curve) had the regenerated set-points meet that dead end again, too close to
    /// the emitted one for any rollback to avoid it (1.4 × the jerk limit). The program and
    /// its overrides are that one's; a third override (3 % lower) comes in the period
    /// after the first rollback (on this braking curve, after the raise to 160 %).
    #[test]
    fn an_override_keeps_the_stricter_model_of_a_dead_end_ahead() {
        let lim = MachineLimits::uniform(
            &[Axis::X, Axis::Y, Axis::Z],
            AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0),
        );
        let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
        let mut pl = Planner::new(&lim, kin, 1e-3, 256, [0.0; AXES]).unwrap();
        let b = PathMode::Blend {
            tolerance: 0.01,
            merge_tolerance: 0.0,
        };
        let cw = [0.0, 0.0, -1.0];
        let ccw = [0.0, 0.0, 1.0];
        let moves = [
            Move::line(
                at(14.850401447407094, 1.2894282673584467),
                44.74027781214412,
                b,
                1,
            ),
            Move::arc(
                at(14.419277856656718, 1.0672152637617625),
                [14.90567251222521, 0.6528690094664281, 0.0],
                cw,
                0,
                45.172948236086384,
                b,
                2,
            ),
            Move::arc(
                at(26.256957192780728, -3.81438766210094),
                [19.544272383959473, -3.2986268797750276, 0.0],
                cw,
                0,
                61.396859317386394,
                b,
                3,
            ),
            Move::arc(
                at(43.84791036004072, 2.8468955855247717),
                [36.61503995863475, -4.610238059201817, 0.0],
                ccw,
                0,
                98.68995133300945,
                PathMode::ExactStop,
                4,
            ),
            Move::arc(
                at(37.478924648090235, -14.560656335053018),
                [36.78295496043851, -4.437116664801921, 0.0],
                ccw,
                0,
                10.443050015562832,
                b,
                5,
            ),
        ];
        assert_eq!(pl.push_all(&moves).unwrap(), moves.len());
        pl.flush();
        let mut joints = [0.0; 3];
        let mut kept = None;
        for n in 0..100_000 {
            match n {
                516 => pl.set_feed_override(0.9590121361828143),
                690 => pl.set_feed_override(1.5994443366590627),
                _ => {}
            }
            if kept.is_none() && pl.stats().rollbacks > 0 {
                let region = pl.strict.or(pl.strict_passed).expect("a rollback's region");
                assert!(pl.cur.at < region.until);
                pl.set_feed_override(0.97 * 1.5994443366590627);
                let after = pl
                    .strict
                    .or(pl.strict_passed)
                    .expect("kept by the override");
                assert_eq!((after.until, after.attempt), (region.until, region.attempt));
                kept = Some(after);
            }
            if pl.next(&mut joints).state == MotionState::Idle && n > 1000 {
                break;
            }
        }
        assert!(
            kept.is_some(),
            "no rollback: the test no longer covers the case"
        );
        assert_eq!(pl.stats().limit_violations, 0);
    }
}
