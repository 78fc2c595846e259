//! The planner: look-ahead window with its braking curve, the path-speed controller and the
//! interpolator that gives one set-point per servo period.

use crate::axes::{AXES, AxisVec, norm};
use crate::builder::{Builder, GeometryStats, KINK};
use crate::error::MotionError;
use crate::input::Move;
use crate::kinematics::Kinematics;
use crate::limits::{Lim, MachineLimits};
use crate::otg::{Limits as OtgLimits, Profile, State as OtgState, position_profile};
use crate::piece::{BRAKE_SHARE_STRAIGHT, JERK_SHARE_JUMP, Piece};
use crate::scurve::{advance, stop, stop_advance};

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
    /// Servo periods computed.
    pub periods: u64,
    /// Periods in which no set-point satisfying every limit was found (should stay 0).
    pub limit_violations: u64,
    /// Periods in which the speed controller found no safe choice and braked as hard as it could.
    pub emergency_brakes: u64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum StopKind {
    Hold,
    Abort,
    Quick,
}

#[derive(Debug, Clone, Copy)]
struct Hold {
    /// Distance of the hold point from the start of the head piece.
    cum: f64,
    a: f64,
    j: f64,
    kind: StopKind,
}

/// Diagnostic dump of one piece: length, braking curve, axis-speed and curvature bounds.
#[doc(hidden)]
pub type PieceDump = (f64, Vec<f64>, Vec<f64>, Vec<f64>, Vec<f64>);

/// Fixed-capacity ring of pieces.
struct Ring {
    buf: Vec<Piece>,
    head: usize,
    len: usize,
}

impl Ring {
    fn new(cap: usize) -> Ring {
        let dummy = Piece::dwell([0.0; AXES], 0.0, 0);
        Ring {
            buf: vec![dummy; cap],
            head: 0,
            len: 0,
        }
    }
    #[inline]
    fn cap(&self) -> usize {
        self.buf.len()
    }
    #[inline]
    fn get(&self, i: usize) -> &Piece {
        &self.buf[(self.head + i) % self.cap()]
    }
    #[inline]
    fn get_mut(&mut self, i: usize) -> &mut Piece {
        let c = self.cap();
        &mut self.buf[(self.head + i) % c]
    }
    fn push(&mut self, p: Piece) {
        let c = self.cap();
        self.buf[(self.head + self.len) % c] = p;
        self.len += 1;
    }
    fn pop(&mut self) {
        if self.len > 0 {
            self.head = (self.head + 1) % self.cap();
            self.len -= 1;
        }
    }
    fn clear(&mut self) {
        self.len = 0;
    }
}

/// Share of the projected axis limits the speed controller itself uses (the per-sample
/// check allows the rest; the margin absorbs the rounding of the check).
const CONTROL_SHARE: f64 = 0.9999;

/// Share of the stop model's deceleration and jerk the controller plans its stops with.
const STOP_CHECK_SHARE: f64 = 0.95;
/// The same for the jerk: the discrete landing on the stop needs more jerk than the
/// continuous profile it follows.
const STOP_CHECK_JERK_SHARE: f64 = 0.8;

/// Pieces one move can produce at most (line span, blend, dwell after a flush; a spline
/// and a dwell after it).
const PIECES_PER_MOVE: usize = 4;
/// Pieces a flush can produce at most (the held move: a line's two spans, a spline's
/// pieces): [`Planner::free`] keeps room for them, so that a flush never overruns the window.
const FLUSH_PIECES: usize = crate::spline::SPLINE_PIECES;

/// Jerk-limited, look-ahead path planner and interpolator. See the crate documentation.
pub struct Planner<K: Kinematics> {
    kin: K,
    lim: Lim,
    period: f64,
    q: Ring,
    builder: Builder,
    scratch: Vec<Piece>,
    s: f64,
    v: f64,
    a: f64,
    hist: [AxisVec; 3],
    fo: f64,
    ro: f64,
    stop_idx: usize,
    stop_cum: f64,
    hold: Option<Hold>,
    dwell_left: Option<f64>,
    stats: RunStats,
    a_min: f64,
    j_min: f64,
    qa_min: f64,
    qj_min: f64,
    /// Path length from the program start to the end of the window.
    cum_end: f64,
    /// The last two path steps (oldest first), for the landing on a stop.
    ds_hist: [f64; 2],
    /// Steps left in the landing on a stop in progress.
    land_n: Option<usize>,
    /// Path jerk of the last period (warm start of the next search).
    j_last: f64,
    /// Start of each piece ahead, from the head piece's start (rebuilt every period).
    starts: Vec<f64>,
    /// Time-optimal S-curve of an isolated straight line (rest to rest) and the time spent
    /// on it: such a move follows the OTG's profile instead of the period-by-period search.
    line_profile: Option<(Profile, f64)>,
    /// Diagnostic trace of the speed controller on stderr (`RTCNC_MOTION_TRACE` set when
    /// the planner is built); never enable on a real-time thread.
    trace: bool,
}

impl<K: Kinematics> Planner<K> {
    /// A planner for a machine with `limits` and `kinematics`, a servo period in seconds, a
    /// look-ahead window of `window` pieces (at least 8; memory is fixed at construction),
    /// starting at rest at axis position `start`.
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
        let pick = |x: &[f64; AXES]| {
            (0..AXES)
                .filter(|i| lim.present[*i])
                .fold(f64::INFINITY, |m, i| m.min(x[i]))
        };
        let (a_min, j_min, qa_min, qj_min) =
            (pick(&lim.a), pick(&lim.j), pick(&lim.qa), pick(&lim.qj));
        let window = window.max(8);
        Ok(Planner {
            kin: kinematics,
            lim,
            period: servo_period,
            q: Ring::new(window),
            builder: Builder::new(start),
            scratch: Vec::with_capacity(PIECES_PER_MOVE * 2),
            s: 0.0,
            v: 0.0,
            a: 0.0,
            hist: [start; 3],
            fo: 1.0,
            ro: 1.0,
            stop_idx: 0,
            stop_cum: 0.0,
            hold: None,
            dwell_left: None,
            stats: RunStats::default(),
            a_min,
            j_min,
            qa_min,
            qj_min,
            cum_end: 0.0,
            ds_hist: [0.0; 2],
            land_n: None,
            j_last: 0.0,
            starts: Vec::with_capacity(window),
            line_profile: None,
            trace: std::env::var_os("RTCNC_MOTION_TRACE").is_some(),
        })
    }

    /// Moves that can be pushed now without [`MotionError::QueueFull`].
    pub fn free(&self) -> usize {
        (self.q.cap() - self.q.len).saturating_sub(FLUSH_PIECES) / PIECES_PER_MOVE
    }

    /// Adds a move to the look-ahead window. Errors (bad input, soft limits) carry the move's
    /// line; the move is then not taken and the planner state is unchanged. `QueueFull`: try
    /// again after some periods.
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
            if let Err(e) = self.builder.push(mv, &self.lim, &mut self.scratch) {
                result = Err(e);
                break;
            }
            self.append_scratch(false);
            taken += 1;
        }
        if self.q.len > first_new {
            self.backward(first_new);
        }
        result.map(|()| taken)
    }

    /// Emits the moves held back for blending; the path then ends with a stop. Call at
    /// program end and before anything that waits for the machine to stop.
    pub fn flush(&mut self) {
        self.scratch.clear();
        self.builder.flush(&self.lim, &mut self.scratch);
        self.append_scratch(true);
    }

    /// Feed override, 0..=2 (clamped). Takes effect at once with a jerk-limited speed change.
    pub fn set_feed_override(&mut self, f: f64) {
        let f = if f.is_finite() {
            f.clamp(0.0, 2.0)
        } else {
            0.0
        };
        if f != self.fo {
            self.fo = f;
            self.line_profile = None;
            self.backward(0);
        }
    }

    /// Rapid override, 0..=1 (clamped).
    pub fn set_rapid_override(&mut self, f: f64) {
        let f = if f.is_finite() {
            f.clamp(0.0, 1.0)
        } else {
            0.0
        };
        if f != self.ro {
            self.ro = f;
            self.line_profile = None;
            self.backward(0);
        }
    }

    /// Feed hold: decelerate along the path and stay there until [`Planner::resume`].
    pub fn hold(&mut self) {
        if self.hold.is_none() {
            self.start_stop(StopKind::Hold);
        }
    }

    /// Resume after a feed hold, from where the machine stopped.
    pub fn resume(&mut self) {
        if matches!(self.hold, Some(h) if h.kind == StopKind::Hold) {
            self.hold = None;
        }
    }

    /// Abort: decelerate along the path, then drop every queued move.
    pub fn abort(&mut self) {
        self.start_stop(StopKind::Abort);
    }

    /// Quick stop (e-stop): decelerate along the path with the quick-stop deceleration and
    /// jerk, then drop every queued move.
    pub fn quick_stop(&mut self) {
        self.start_stop(StopKind::Quick);
    }

    /// Current set-point in axis space.
    pub fn position(&self) -> AxisVec {
        self.hist[0]
    }

    /// Counters.
    pub fn stats(&self) -> RunStats {
        self.stats
    }

    /// Geometry counters (merges, blends, smoothing, stops).
    pub fn geometry_stats(&self) -> GeometryStats {
        self.builder.stats
    }

    /// Pieces in the look-ahead window.
    pub fn window_len(&self) -> usize {
        self.q.len
    }

    /// Diagnostics: per piece of the window, (length, braking curve, axis-speed bound,
    /// curvature bound) at its samples.
    #[doc(hidden)]
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

    /// The kinematics.
    pub fn kinematics(&self) -> &K {
        &self.kin
    }

    /// Computes the next servo period: writes the joint positions (`joints.len()` should be
    /// the kinematics' joint count) and returns the status. Allocation-free, bounded time.
    pub fn next(&mut self, joints: &mut [f64]) -> Status {
        let (x, state) = self.step();
        self.kin.axes_to_joints(&x, joints);
        Status {
            state,
            axes: x,
            path_speed: self.v,
            line: if self.q.len > 0 {
                self.q.get(0).line
            } else {
                0
            },
        }
    }

    // ---------------------------------------------------------------- window

    fn append_scratch(&mut self, update: bool) {
        let first_new = self.q.len;
        let n = self.scratch.len();
        for k in 0..n {
            let mut p = self.scratch[k];
            p.sample(&self.lim);
            p.j_brake = p.jerk_available(&self.lim);
            if self.q.len > 0 {
                let last_idx = self.q.len - 1;
                let period = self.period;
                let lim = self.lim;
                let last = self.q.get_mut(last_idx);
                if !last.stop_at_end {
                    junction(last, &mut p, &lim, period);
                }
            }
            p.cum_start = self.cum_end;
            self.cum_end += p.len;
            if self.q.len == 0 {
                self.stop_idx = 0;
                self.stop_cum = p.len - self.s;
                self.s = 0.0;
                self.stop_cum = p.len;
            } else if !self.q.get(self.stop_idx).stop_at_end {
                self.stop_idx = self.q.len;
                self.stop_cum += p.len;
            }
            self.q.push(p);
        }
        if n > 0 && update {
            self.backward(first_new);
        }
    }

    fn pop_head(&mut self) {
        let len = self.q.get(0).len;
        self.q.pop();
        self.stop_cum -= len;
        if let Some(h) = &mut self.hold {
            h.cum -= len;
        }
        if self.stop_idx == 0 {
            self.recompute_stop();
        } else {
            self.stop_idx -= 1;
            if self.stop_idx == 0 {
                // Exact once the stop is in the head piece: the running sum drifts by
                // rounding over a long path (1e-11 after 1000 mm), more than the 1e-12 at
                // which the head counts as reached, and the path would halt short of it.
                self.stop_cum = self.q.get(0).len;
            }
        }
    }

    fn recompute_stop(&mut self) {
        let mut cum = 0.0;
        self.stop_idx = 0;
        for i in 0..self.q.len {
            let p = self.q.get(i);
            cum += p.len;
            self.stop_idx = i;
            if p.stop_at_end {
                break;
            }
        }
        self.stop_cum = cum;
    }

    /// Backward pass of the braking curve from the end of the window; stops early once
    /// pieces before `first_new` no longer change.
    fn backward(&mut self, first_new: usize) {
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
                    let vl = p.vlc(k, fo, ro).min(p.vlc(k + 1, fo, ro));
                    let w1 = p.w[k + 1];
                    let d1 = p
                        .decel_available(k, w1, &lim)
                        .min(p.decel_available(k + 1, w1, &lim));
                    let west = vl.min((w1 * w1 + 2.0 * h * d1).sqrt());
                    let d2 =
                        p.decel_available(k, west, &lim)
                            .min(p.decel_available(k + 1, west, &lim));
                    let acc = d1.min(d2);
                    p.a_sub[k] = acc;
                    let wfull = (w1 * w1 + 2.0 * h * acc).sqrt();
                    p.w[k] = vl.min(wfull);
                    // A braking section that ends at sample k+1 on a limit (not at a stop).
                    let braking_here = wfull < vl;
                    if braking_here && !next_braking && w1 > 0.0 {
                        let sv = h * (k + 1) as f64;
                        p.valley_in = Some((sv, w1, acc, p.j_brake));
                        valley = Some((p.cum_start + sv, w1, acc, p.j_brake));
                    }
                    next_braking = braking_here;
                    // The stop model of the controller (constant deceleration, jerk-limited
                    // ends) matters where the stop is jerk-dominated, at low speed; above, the
                    // braking curve with its varying deceleration governs.
                    if w1 <= v_jerk {
                        run_a = run_a.min(acc);
                        run_j = run_j.min(p.j_brake);
                    } else if w1 > 2.0 * v_jerk {
                        // Far from the stop: the braking curve governs; keeping the value
                        // local also keeps the backward pass short when moves are appended.
                        run_a = f64::INFINITY;
                        run_j = f64::INFINITY;
                    }
                }
            }
            p.a_to_stop = run_a;
            p.j_to_stop = run_j;
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
        if self.trace {
            eprintln!("BACKWARD n={n} first_new={first_new} lowest={lowest}");
        }
        // Forward pass: a rise of the curve is capped by the acceleration available, so that
        // the curve has no notches finer than the controller can follow.
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
                    let acc =
                        p.accel_available(k, w0, &lim)
                            .min(p.accel_available(k + 1, w0, &lim));
                    p.acc_sub[k] = acc;
                    p.w[k + 1] = p.w[k + 1].min((w0 * w0 + 2.0 * h * acc).sqrt());
                }
            }
            wf = p.w[ns];
        }
    }

    fn start_stop(&mut self, kind: StopKind) {
        self.line_profile = None;
        let (a, j) = match kind {
            StopKind::Quick => (self.qa_min, self.qj_min),
            _ => (0.5 * self.a_min, 0.5 * self.j_min),
        };
        let (a, j) = match kind {
            StopKind::Quick => (a * BRAKE_SHARE_STRAIGHT, j * BRAKE_SHARE_STRAIGHT),
            _ => (a, j),
        };
        // The hold point is where the controller's own (softer) stop check ends, plus one
        // period's travel of slack for the discrete landing.
        let (d, _) = stop(
            self.v,
            self.a.max(-a),
            STOP_CHECK_SHARE * a,
            STOP_CHECK_JERK_SHARE * j,
        );
        // A quick stop brakes from its first period on (no slack to coast in); the hold
        // point moves on if the discrete landing needs more room.
        let d = if kind == StopKind::Quick {
            d
        } else {
            d + self.v * self.period
        };
        self.hold = Some(Hold {
            cum: self.s + d,
            a,
            j,
            kind,
        });
    }

    // ---------------------------------------------------------------- runtime

    fn step(&mut self) -> (AxisVec, MotionState) {
        self.stats.periods += 1;
        let state = self.settle();
        let x = if state == MotionState::Moving || (state == MotionState::Holding && self.v > 0.0) {
            self.control()
        } else {
            self.ds_hist = [self.ds_hist[1], 0.0];
            self.hist[0]
        };
        self.hist = [x, self.hist[0], self.hist[1]];
        let state = match (state, self.hold) {
            (MotionState::Moving, Some(h)) if h.kind == StopKind::Hold => MotionState::Holding,
            (MotionState::Moving, Some(_)) => MotionState::Stopping,
            (s, _) => s,
        };
        (x, state)
    }

    /// Releases finished pieces and dwells; returns what this period does.
    fn settle(&mut self) -> MotionState {
        for _ in 0..=self.q.cap() {
            if let Some(h) = self.hold {
                if self.v <= 0.0 && self.a.abs() <= 1e-9 {
                    self.v = 0.0;
                    self.a = 0.0;
                    if h.kind != StopKind::Hold {
                        self.q.clear();
                        self.builder.clear(self.hist[0]);
                        self.hold = None;
                        self.dwell_left = None;
                        self.s = 0.0;
                        self.stop_cum = 0.0;
                        self.stop_idx = 0;
                        return MotionState::Idle;
                    }
                    return MotionState::Holding;
                }
            }
            if self.q.len == 0 {
                self.v = 0.0;
                self.a = 0.0;
                self.s = 0.0;
                return MotionState::Idle;
            }
            let head = *self.q.get(0);
            if head.len <= 0.0 {
                let left = self.dwell_left.unwrap_or(head.dwell) - self.period;
                if left <= 1e-12 {
                    self.dwell_left = None;
                    self.pop_head();
                    self.s = 0.0;
                    if head.dwell > 0.0 {
                        return MotionState::Dwelling;
                    }
                    continue;
                }
                self.dwell_left = Some(left);
                return MotionState::Dwelling;
            }
            let at_end = self.s >= head.len - 1e-12;
            if at_end && self.v <= 0.0 && (head.stop_at_end || self.q.len == 1) {
                self.v = 0.0;
                self.a = 0.0;
                self.pop_head();
                self.s = 0.0;
                continue;
            }
            return MotionState::Moving;
        }
        MotionState::Idle
    }

    /// Piece index and local arc length at distance `d` ahead of the current position,
    /// never beyond the next stop.
    #[inline]
    fn locate(&self, d: f64) -> (usize, f64) {
        let target = self.s + d;
        // Table of piece starts built at the start of the period (binary search).
        let m = self.starts.len();
        let (mut i, mut sl) = if m > 0 {
            let k = self
                .starts
                .partition_point(|x| *x <= target)
                .saturating_sub(1);
            (k, target - self.starts[k])
        } else {
            (0, target)
        };
        loop {
            let p = self.q.get(i);
            if sl <= p.len || p.stop_at_end || i + 1 >= self.q.len {
                return (i, sl.min(p.len));
            }
            sl -= p.len;
            i += 1;
        }
    }

    /// Fills the table of piece starts (distance from the head piece's start) up to the next
    /// stop, for `locate`. Bounded by the window; no allocation (capacity reserved).
    fn build_starts(&mut self) {
        self.starts.clear();
        let mut cum = 0.0;
        for i in 0..self.q.len.min(self.starts.capacity()) {
            self.starts.push(cum);
            let p = self.q.get(i);
            if p.stop_at_end {
                break;
            }
            cum += p.len;
        }
    }

    fn w_ahead(&self, d: f64) -> (f64, f64, f64) {
        let (i, sl) = self.locate(d);
        let p = self.q.get(i);
        let (w, aw) = p.w_at(sl, self.fo, self.ro);
        (w, aw, p.j_brake)
    }

    /// Whether the speed controller, from (`v1`, `a1`) at distance `d1` ahead, can follow the
    /// braking curve: ramps the acceleration with jerk `jb` towards the curve's slope where
    /// it is and checks the speed against the curve at the end of each chunk.
    #[allow(clippy::too_many_arguments)]
    fn join_ok(&self, d1: f64, v1: f64, a1: f64, jb: f64, a_full: f64, t: f64, rem: f64) -> bool {
        let horizon = (a1.max(0.0) + a_full) / jb + 2.0 * t;
        let dt = (horizon / 8.0).max(0.5 * t);
        let (mut d, mut v, mut a) = (d1, v1, a1);
        let mut time = 0.0;
        while time < horizon {
            // Aim at the steepest slope the curve takes within one full ramp's travel, so
            // that a kink where the curve starts to fall is anticipated.
            let reach = v.max(0.0) * (a.max(0.0) + a_full) / jb;
            let mut aw = 0.0f64;
            for f in [0.0, 0.5, 1.0] {
                aw = aw.max(self.w_ahead(d + f * reach).1);
            }
            let target = -aw;
            let j = clampf((target - a) / dt, -jb, jb);
            let (dd, v2, a2) = advance(0.0, v, a, j, dt);
            // Discrete-time lag of the ramp (the jerk changes only at period boundaries).
            let lag = 0.5 * (a - target).max(0.0) * t;
            let vmax = v.max(v2);
            let d_prev = d;
            d += dd;
            v = v2;
            a = a2;
            time += dt;
            // Reaching the stop (or the speed zero) ends the check: the stop check covers it.
            if v <= 0.0 || d >= rem {
                return true;
            }
            let w = self.w_min_between(d_prev, d);
            if vmax.max(v + lag) > w * (1.0 + 1e-12) + 1e-12 {
                return false;
            }
        }
        true
    }

    /// Whether ramping the path acceleration `a1` back to zero with jerk `jr`, from speed
    /// `v1` at distance `d1` ahead, keeps every axis's acceleration within its limit and the
    /// acceleration within the share the curvature leaves it (checked at five points of the
    /// ramp): the curvature may rise ahead faster than the acceleration can follow.
    fn accel_ramp_ok(&self, d1: f64, v1: f64, a1: f64, jr: f64, quick: bool) -> bool {
        let tau = a1.abs() / jr;
        let jerk = -a1.signum() * jr;
        for k in 1..=5 {
            let (dd, vk, ak) = advance(0.0, v1, a1, jerk, tau * k as f64 / 5.0);
            let vk = vk.max(0.0);
            let (i, sl) = self.locate(d1 + dd.max(0.0));
            let (tan, kv, kp) = self.q.get(i).geo_at(sl);
            for ax in 0..AXES {
                if !self.lim.present[ax] {
                    continue;
                }
                let (am, jm) = if quick {
                    (self.lim.qa[ax], self.lim.qj[ax])
                } else {
                    (self.lim.a[ax], self.lim.j[ax])
                };
                if (tan[ax] * ak + kv[ax] * vk * vk).abs() > CONTROL_SHARE * am {
                    return false;
                }
                let room = (CONTROL_SHARE * jm - (kp[ax] * vk * vk * vk).abs()).max(0.0);
                if 3.0 * kv[ax].abs() * vk * ak.abs() > 0.5 * room * 1.05 {
                    return false;
                }
            }
        }
        true
    }

    /// Smallest braking-curve speed between distances `d0` and `d1` ahead (the curve is
    /// non-increasing inside each sub-interval, so its minimum lies at `d1` or at a sample).
    fn w_min_between(&self, d0: f64, d1: f64) -> f64 {
        let (mut i, s0) = self.locate(d0);
        let (i1, s1) = self.locate(d1);
        let mut m = self.q.get(i1).w_at(s1, self.fo, self.ro).0;
        let mut sl = s0;
        while i <= i1 {
            let p = self.q.get(i);
            let end = if i == i1 { s1 } else { p.len };
            if p.len > 0.0 {
                let h = p.len / p.ns as f64;
                let mut k = (sl / h) as usize + 1;
                while k <= p.ns && h * k as f64 <= end {
                    // Left limit of W at the sample: the end of sub-interval k-1.
                    m = m.min(p.w[k].min(p.vlc(k - 1, self.fo, self.ro)));
                    k += 1;
                }
            }
            i += 1;
            sl = 0.0;
        }
        m
    }

    /// An isolated straight line (starting at rest, ending in a stop, no hold or stop in
    /// progress) follows the time-optimal rest-to-rest S-curve of the OTG under the feed and
    /// the axis limits projected on the line: its duration is the optimum, and every period
    /// samples the continuous profile, so the finite differences stay within the limits.
    /// Returns the set-point of this period, or None when the controller decides.
    fn follow_line_profile(&mut self) -> Option<AxisVec> {
        let t = self.period;
        let head = *self.q.get(0);
        if self.line_profile.is_none() {
            let straight = head.len > 0.0
                && head.stop_at_end
                && (0..=head.ns).all(|k| head.smp[k].k.iter().all(|c| *c == 0.0))
                && (0..head.ns).all(|k| head.smp[k].t == head.smp[k + 1].t);
            if !(straight && self.hold.is_none() && self.s == 0.0 && self.v == 0.0 && self.a == 0.0)
            {
                return None;
            }
            let vmax = (0..=head.ns)
                .map(|k| head.vlc(k, self.fo, self.ro))
                .fold(f64::INFINITY, f64::min);
            // A hair (1e-7) inside the limits: the set-point check shrinks them by 1e-10 relative
            // plus rounding, and the profile runs at them exactly.
            let share = 1.0 - 1e-7;
            let limits = OtgLimits::symmetric(
                share * vmax,
                share * head_accel(&head, &self.lim, false),
                share * head_jerk(&head, &self.lim, false),
            );
            let rest = |p: f64| OtgState { p, v: 0.0, a: 0.0 };
            let profile = position_profile(rest(0.0), rest(head.len), &limits).ok()?;
            if self.trace {
                eprintln!("PROFILE len={} duration={}", head.len, profile.duration());
            }
            self.line_profile = Some((profile, 0.0));
        }
        let (profile, elapsed) = self.line_profile?;
        let elapsed = elapsed + t;
        let rem = head.len - self.s;
        let (ds, v, a) = if elapsed >= profile.duration() {
            self.line_profile = None;
            (rem, 0.0, 0.0)
        } else {
            self.line_profile = Some((profile, elapsed));
            let smp = profile.at(elapsed);
            (clampf(smp.p - self.s, 0.0, rem), smp.v, smp.a)
        };
        let (ds_done, mut x) = self.exact(ds, rem, false);
        if ds_done == rem {
            // Exactly on the end point (s + rem may round below the piece's length).
            x = head.pos(head.len);
        }
        if ds_done != ds && self.trace {
            eprintln!("PROFILE handover el={elapsed} ds={ds} done={ds_done} v={v} a={a}");
        }
        if ds_done != ds {
            // The set-point check had to move the point: the controller takes over.
            self.line_profile = None;
        }
        self.v = v;
        self.a = a;
        self.ds_hist = [self.ds_hist[1], ds_done];
        self.s += ds_done;
        if self.s > head.len {
            self.s = head.len;
        }
        Some(x)
    }

    /// One period of the path-speed controller: chooses the path jerk, checks the resulting
    /// set-point against every axis limit and commits it.
    fn control(&mut self) -> AxisVec {
        self.build_starts();
        if let Some(x) = self.follow_line_profile() {
            return x;
        }
        let t = self.period;
        let head = *self.q.get(0);
        let quick = matches!(self.hold, Some(h) if h.kind == StopKind::Quick);
        let mut rem = self.stop_cum - self.s;
        let mut a_stop = if head.a_to_stop.is_finite() && head.a_to_stop > 1e-3 * self.a_min {
            head.a_to_stop
        } else {
            head.a_sub[0].min(self.a_min * BRAKE_SHARE_STRAIGHT)
        };
        let mut j_stop = if head.j_to_stop.is_finite() {
            head.j_to_stop
        } else {
            head.j_brake
        };
        let mut real_stop = true;
        if let Some(h) = &mut self.hold {
            // A hold point is soft: when the axes cannot brake as the stop model assumes (on a
            // curve at speed), it moves on to where the machine can stop from here.
            let (d_need, _) = stop(
                self.v,
                self.a.max(-h.a),
                STOP_CHECK_SHARE * h.a,
                STOP_CHECK_JERK_SHARE * h.j,
            );
            if self.s + d_need > h.cum && h.cum - self.s > 0.0 {
                h.cum = self.s + d_need;
            }
        }
        let hold = self.hold;
        if let Some(h) = hold {
            let hr = h.cum - self.s;
            if hr < rem {
                rem = hr.max(0.0);
                a_stop = h.a;
                j_stop = h.j;
                real_stop = false;
            }
        }
        let jm = CONTROL_SHARE * head_jerk(&head, &self.lim, quick);
        let (v, a) = (self.v, self.a);
        // Exact bounds of the path acceleration and jerk at the current point: every axis's
        // |T a + K v²| ≤ A and |T j + 3 K v a + K' v³| ≤ J.
        let (tan, kv, kp) = head.geo_at(self.s);
        let (mut a_lo, mut a_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        let (mut j_lo, mut j_hi) = (f64::NEG_INFINITY, f64::INFINITY);
        for i in 0..AXES {
            if !self.lim.present[i] || tan[i].abs() < 1e-9 {
                continue;
            }
            let (am, jmx) = if quick {
                (self.lim.qa[i], self.lim.qj[i])
            } else {
                (self.lim.a[i], self.lim.j[i])
            };
            let (am, jmx) = (CONTROL_SHARE * am, CONTROL_SHARE * jmx);
            let ca = kv[i] * v * v;
            let cj = 3.0 * kv[i] * v * a + kp[i] * v * v * v;
            let (x0, x1) = ((-am - ca) / tan[i], (am - ca) / tan[i]);
            a_lo = a_lo.max(x0.min(x1));
            a_hi = a_hi.min(x0.max(x1));
            // The 3·K·v·a term of the jerk grows with the acceleration: keep it within half
            // of what the curvature change leaves, so that the acceleration can always be
            // ramped back with the other half.
            let k3v = 3.0 * kv[i].abs() * v;
            if k3v > 0.0 {
                let room = (jmx - (kp[i] * v * v * v).abs()).max(0.0);
                let a_cap = 0.5 * room / k3v;
                a_lo = a_lo.max(-a_cap);
                a_hi = a_hi.min(a_cap);
            }
            let (y0, y1) = ((-jmx - cj) / tan[i], (jmx - cj) / tan[i]);
            j_lo = j_lo.max(y0.min(y1));
            j_hi = j_hi.min(y0.max(y1));
        }
        let a_full = CONTROL_SHARE * head_accel(&head, &self.lim, quick);
        if !(a_lo < a_hi) {
            (a_lo, a_hi) = (-a_full, a_full);
        }
        if !(j_lo < j_hi) {
            (j_lo, j_hi) = (-jm, jm);
        }
        let (a_lo, a_hi) = (a_lo.max(-a_full), a_hi.min(a_full));
        let (j_lo, j_hi) = (j_lo.max(-jm), j_hi.min(jm));
        let jr = 0.5 * (-j_lo).max(0.1 * jm);
        let jr_down = 0.8 * (-j_lo).max(0.1 * jm);
        let jr_up = 0.5 * j_hi.max(0.1 * jm);
        // Distance to the next valley of the braking curve and its speed.
        let valley_dist = match head.valley_in {
            Some((sv, vm, av, jv)) if sv > self.s => Some((sv - self.s, vm, av, jv)),
            _ => head
                .valley_next
                .map(|(c, vm, av, jv)| (c - head.cum_start - self.s, vm, av, jv)),
        }
        .filter(|(d, ..)| *d > 0.0);
        // Lowest braking-curve speed within the travel of the longest possible ramp.
        let w_floor = {
            let jb_min = 0.5 * (-j_lo).max(0.1 * jm);
            let reach =
                (v + a.abs() * t + a_full * t) * (a.max(0.0) + a_full) / jb_min * 2.0 + v * 4.0 * t;
            self.w_min_between(0.0, reach.min(rem))
        };
        // 0: safe; 1: violates the stop (distance or undershoot); 2: violates the braking curve.
        let check_detail = |j: f64| -> u8 {
            let (ds, v1, a1) = advance(0.0, v, a, j, t);
            if v1 < -1e-9 || ds < 0.0 || ds > rem + 1e-12 || a1 < a_lo.min(-1e-9) - 1e-9 {
                return 1;
            }
            if a1 > a_hi.max(0.0) + 1e-9 {
                return 20;
            }
            // Bringing a positive acceleration back to zero must keep every axis's acceleration
            // (tangential plus centripetal, which grows with speed and turns with the path)
            // within its limit.
            if a1 != 0.0
                && !self.accel_ramp_ok(ds, v1, a1, if a1 > 0.0 { jr } else { jr_up }, quick)
            {
                return 21;
            }
            // A state that decelerates so hard that the speed would reach zero before the
            // deceleration can be released cannot stop smoothly.
            if a1 < 0.0 && a1 * a1 > 2.0 * j_stop * v1.max(0.0) * (1.0 + 1e-9) + 1e-12 {
                return 1;
            }
            // The check uses a softer stop than the fallback follows, so that the fallback
            // regains the margin when the per-sample limits slowed the braking down.
            let (dst, _) = stop(
                v1,
                a1,
                STOP_CHECK_SHARE * a_stop,
                STOP_CHECK_JERK_SHARE * j_stop,
            );
            if ds + dst > rem * (1.0 + 1e-12) + 1e-12 {
                return 1;
            }
            if hold.is_some() && !real_stop {
                return 0;
            }
            // The next valley of the braking curve: arrive there with the deceleration
            // released (the speed profile is the valley speed plus a stop profile).
            if let Some((dv, vm, av, jv)) = valley_dist {
                if v1 > vm {
                    let rel = v1 - vm;
                    if a1 < 0.0 && a1 * a1 > 2.0 * jv * rel * (1.0 + 1e-9) + 1e-12 {
                        return 22;
                    }
                    let (dst, tst) =
                        stop(rel, a1, STOP_CHECK_SHARE * av, STOP_CHECK_JERK_SHARE * jv);
                    if ds + dst + vm * tst > dv {
                        return 23;
                    }
                }
            }
            let (_, _, jb) = self.w_ahead(ds);
            // The jerk left for ramping the acceleration down once the curvature terms
            // (3·K·v·a + K'·v³) took their share.
            let jb = jb.min(jr_down);
            // Against the lowest point of the curve over this period, so that a short piece
            // with a low limit is not jumped over.
            if v1 > self.w_min_between(0.0, ds) * (1.0 + 1e-12) + 1e-12 {
                return 24;
            }
            // Bringing the acceleration to zero must not exceed the curve anywhere before.
            if a1 > 0.0 {
                let tau = a1 / jb;
                let (dp, mut vp, _) = advance(0.0, v1, a1, -jb, tau);
                vp += 0.5 * a1 * t;
                if vp > self.w_min_between(ds, ds + dp) * (1.0 + 1e-12) + 1e-12 {
                    return 25;
                }
            }
            // Joining the braking curve: simulate the jerk-limited ramp of the acceleration
            // towards the curve's local slope, in chunks, over the time the longest ramp takes.
            // Skipped when even the highest speed the ramp could reach stays under the curve's
            // lowest point within the longest ramp's travel.
            let v_peak = v1 + a1.max(0.0) * (a1.max(0.0) / (2.0 * jb) + t);
            if v_peak > w_floor && !self.join_ok(ds, v1, a1, jb, a_full, t, rem) {
                return 26;
            }
            0
        };
        let check = |j: f64| -> u8 {
            match check_detail(j) {
                0 => 0,
                1 => 1,
                _ => 2,
            }
        };
        let safe = |j: f64| check(j) == 0;

        // Landing on a stop: the remaining stop takes less than a period.
        let (dst0, tst0) = stop(v, a, a_stop, j_stop);
        let tiny = 0.3 * if quick { self.qj_min } else { self.j_min } * t * t * t;
        // Landing: when the stop is a few periods away, plan the last steps exactly (the
        // smoothest sequence of steps that ends at the stop and stays there).
        let jl = j_stop.min(-j_lo).min(j_hi).max(0.0);
        let al = a_stop.min(-a_lo).min(a_hi).max(0.0);
        let (js, as_) = (jl * t * t * t, al * t * t);
        // A landing in progress continues with one step fewer (the tail of the smoothest
        // sequence is the smoothest for what is left).
        let mut landing = match self.land_n {
            Some(n) if n >= 2 && rem >= 0.0 => {
                land_steps(self.ds_hist, rem, n - 1, js, as_).map(|d| (d, n - 1))
            }
            _ => None,
        };
        if landing.is_none() && rem >= 0.0 && tst0 <= 5.0 * t && dst0 <= rem * 1.5 + tiny {
            let n0 = ((tst0 / t).ceil() as usize).clamp(1, LAND_MAX);
            landing = (n0..=LAND_MAX)
                .find_map(|n| land_steps(self.ds_hist, rem, n, js, as_).map(|d| (d, n)));
        }
        let new_land_n = landing.map(|(_, n)| n);
        let landing = landing.map(|(d, _)| d);
        let land = landing.is_some_and(|d1| d1 == rem)
            || (v.abs() <= 1e-9 && a.abs() <= 1e-6 && rem <= tiny && rem >= 0.0);
        let mut emergency = false;
        // Model state at the end of the period, when it is not the constant-jerk one.
        let mut model: Option<(f64, f64)> = None;
        let ds_target = if land {
            rem
        } else if let Some(d1) = landing {
            d1
        } else {
            let mut choice = None;
            // Warm start: the jerk of the last period is usually close to this one's, so
            // the search starts from a narrow bracket around it.
            let j_prev = clampf(self.j_last, j_lo, j_hi);
            let step = 0.02 * (j_hi - j_lo).max(0.0);
            if safe(j_hi) {
                choice = Some(j_hi);
            } else if step > 0.0 && safe(j_prev) && !safe((j_prev + step).min(j_hi)) {
                let (mut lo, mut hi) = (j_prev, (j_prev + step).min(j_hi));
                for _ in 0..6 {
                    let mid = 0.5 * (lo + hi);
                    if safe(mid) {
                        lo = mid;
                    } else {
                        hi = mid;
                    }
                }
                choice = Some(lo);
            } else {
                let mut lo = j_lo.max((a_lo - a) / t).min(j_hi);
                if !safe(lo) {
                    lo = brake_jerk(v, a, a_stop, j_stop, t);
                }
                if safe(lo) {
                    let mut hi = j_hi;
                    for _ in 0..10 {
                        let mid = 0.5 * (lo + hi);
                        if safe(mid) {
                            lo = mid;
                        } else {
                            hi = mid;
                        }
                    }
                    choice = Some(lo);
                }
            }
            if choice.is_none() {
                // Behind the braking curve but not the stop: brake as hard as allowed while
                // the deceleration can still be released before the speed reaches zero.
                let lo = j_lo.max((a_lo - a) / t).min(j_hi);
                let bj = clampf(brake_jerk(v, a, -a_lo, j_stop, t), j_lo, j_hi);
                for cand in [lo, bj] {
                    if choice.is_none() && check(cand) == 2 {
                        choice = Some(cand);
                        emergency = true;
                    }
                }
            }
            match choice {
                Some(j) => {
                    let (ds, _, _) = advance(0.0, v, a, j, t);
                    clampf(ds, 0.0, rem.max(0.0))
                }
                None => {
                    if self.trace {
                        let lo = j_lo.max((a_lo - a) / t).min(j_hi);
                        eprintln!(
                            "FALLBACK v={v} a={a} j_lo={j_lo} j_hi={j_hi} a_lo={a_lo} a_hi={a_hi} check(lo)={} check(0)={} check(hi)={}",
                            check(lo),
                            check(0.0),
                            check(j_hi)
                        );
                    }
                    // No constant jerk over the period is safe (a switch of the stop
                    // profile falls inside the period): follow the stop profile exactly.
                    let (ds, v1, a1) = stop_advance(v, a, a_stop, j_stop, t);
                    let (dst, _) = stop(v1, a1, a_stop, j_stop);
                    if ds + dst > rem * (1.0 + 1e-9) + 1e-9 {
                        emergency = true;
                    }
                    model = Some((v1, a1));
                    clampf(ds, 0.0, rem.max(0.0))
                }
            }
        };
        if emergency {
            if self.trace {
                eprintln!(
                    "EMERG detail lo={} 0={} hi={}",
                    check_detail(j_lo.max((a_lo - a) / t)),
                    check_detail(0.0),
                    check_detail(j_hi)
                );
                let (dst, tst) = stop(v, a, a_stop, j_stop);
                eprintln!(
                    "EMERG v={v} a={a} rem={rem} dst={dst} tst={tst} A={a_stop} J={j_stop} jm={jm} afull={a_full}"
                );
            }
            self.stats.emergency_brakes += 1;
        }
        let (ds, x) = self.exact(ds_target, rem.max(0.0), quick);
        self.land_n = if ds == ds_target { new_land_n } else { None };
        if self.trace {
            eprintln!(
                "CTRL v={v:.4} a={a:.2} rem={rem:.6} land={land} model={model:?} ds_t={ds_target:.9} ds={ds:.9} A={a_stop} J={j_stop}"
            );
        }
        if land && ds == rem {
            self.v = 0.0;
            self.a = 0.0;
        } else if landing.is_some() {
            // Speed and acceleration of the step sequence (backward differences).
            self.v = ds / t;
            self.a = (ds - self.ds_hist[1]) / (t * t);
        } else if let (Some((v1, a1)), true) = (model, ds == ds_target) {
            self.v = v1;
            self.a = a1;
        } else {
            // The set-point check may have moved the point: the model follows, within its
            // own jerk bound.
            let j_eff = clampf(
                6.0 * (ds - v * t - 0.5 * a * t * t) / (t * t * t),
                -2.0 * jm,
                2.0 * jm,
            );
            self.j_last = j_eff;
            let (_, v1, a1) = advance(0.0, v, a, j_eff, t);
            self.v = v1.max(0.0);
            self.a = a1;
        }
        // Commit the position.
        self.ds_hist = [self.ds_hist[1], ds];
        self.s += ds;
        let mut guard = 0;
        while self.q.len > 1 && guard < self.q.cap() {
            let p = self.q.get(0);
            if self.s > p.len && !p.stop_at_end {
                self.s -= p.len;
                self.pop_head();
                guard += 1;
            } else {
                break;
            }
        }
        let p = self.q.get(0);
        if self.s > p.len {
            self.s = p.len;
        }
        x
    }

    /// Finds the set-point at distance `ds` (adjusted if needed) such that the finite
    /// differences of the last set-points satisfy every axis's |v|, |a|, |j| limit.
    fn exact(&mut self, ds0: f64, rem: f64, quick: bool) -> (f64, AxisVec) {
        let t = self.period;
        let lim = &self.lim;
        let (p0, p1, p2) = (self.hist[0], self.hist[1], self.hist[2]);
        let mut lo = [f64::NEG_INFINITY; AXES];
        let mut hi = [f64::INFINITY; AXES];
        for i in 0..AXES {
            if !lim.present[i] {
                lo[i] = p0[i];
                hi[i] = p0[i];
                continue;
            }
            let (am, jm) = if quick {
                (lim.qa[i], lim.qj[i])
            } else {
                (lim.a[i], lim.j[i])
            };
            let round = 16.0 * f64::EPSILON * (p0[i].abs() + p1[i].abs() + p2[i].abs() + 1.0);
            let shrink = 1.0 - 1e-10;
            let rv = lim.v[i] * t * shrink - round;
            let ra = am * t * t * shrink - round;
            let rj = jm * t * t * t * shrink - round;
            let cv = p0[i];
            let ca = 2.0 * p0[i] - p1[i];
            let cj = 3.0 * p0[i] - 3.0 * p1[i] + p2[i];
            lo[i] = (cv - rv).max(ca - ra).max(cj - rj);
            hi[i] = (cv + rv).min(ca + ra).min(cj + rj);
        }
        let inside =
            |x: &AxisVec| (0..AXES).all(|i| !lim.present[i] || (x[i] >= lo[i] && x[i] <= hi[i]));
        let mut ds = ds0;
        for _ in 0..5 {
            let (k, sl) = self.locate(ds);
            let piece = self.q.get(k);
            let x = piece.pos(sl);
            if inside(&x) {
                return (ds, x);
            }

            let (_, tan) = piece.pos_tangent(sl);
            let (mut dlo, mut dhi) = (-ds, rem - ds);
            for i in 0..AXES {
                if !lim.present[i] {
                    continue;
                }
                let ti = tan[i];
                if ti.abs() > 1e-12 {
                    let (a, b) = ((lo[i] - x[i]) / ti, (hi[i] - x[i]) / ti);
                    dlo = dlo.max(a.min(b));
                    dhi = dhi.min(a.max(b));
                }
            }
            let delta = if dlo <= dhi {
                // Aim slightly inside the admissible interval against the curve's bending.
                let m = 1e-3 * (dhi - dlo);
                clampf(0.0, dlo + m, dhi - m)
            } else {
                0.5 * (dlo + dhi)
            };
            ds = clampf(ds + delta, 0.0, rem);
        }
        let (k, sl) = self.locate(ds);
        let x = self.q.get(k).pos(sl);
        if !inside(&x) {
            self.stats.limit_violations += 1;
            if self.trace {
                eprintln!(
                    "VIOL period={} ds0={ds0} ds={ds} rem={rem} x={:?} lo={:?} hi={:?}",
                    self.stats.periods,
                    &x[..3],
                    &lo[..3],
                    &hi[..3]
                );
            }
        }
        (ds, x)
    }
}

/// Largest tangential acceleration the model may use on a piece (axis limits projected on
/// the tangent, ignoring centripetal load; the per-sample check enforces the rest).
fn head_accel(p: &Piece, lim: &Lim, quick: bool) -> f64 {
    let mut am = f64::INFINITY;
    for k in 0..=p.ns {
        for i in 0..AXES {
            if lim.present[i] {
                let ti = p.smp[k].t[i].abs();
                let ai = if quick { lim.qa[i] } else { lim.a[i] };
                if ti > 1e-12 {
                    am = am.min(ai / ti);
                }
            }
        }
    }
    if am.is_finite() { am } else { 1.0 }
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

/// The first of `n` path steps that end exactly `rem` further and at rest, after the steps
/// `hist` (oldest first): the sequence with the smallest sum of squared third differences
/// (jerk). None when a third difference exceeds `j_step` (J·T³), a second difference
/// exceeds `a_step` (A·T²) or a step is negative.
fn land_steps(hist: [f64; 2], rem: f64, n: usize, j_step: f64, a_step: f64) -> Option<f64> {
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
        if (d[m] - 2.0 * d[m - 1] + d[m - 2]).abs() > j_step || (d[m] - d[m - 1]).abs() > a_step {
            return None;
        }
    }
    Some(if n == 1 { rem } else { x[0] })
}

/// Largest tangential jerk on a piece (axis jerk limits projected on the tangent).
fn head_jerk(p: &Piece, lim: &Lim, quick: bool) -> f64 {
    let mut jm = f64::INFINITY;
    for k in 0..=p.ns {
        for i in 0..AXES {
            if lim.present[i] {
                let ti = p.smp[k].t[i].abs();
                let ji = if quick { lim.qj[i] } else { lim.j[i] };
                if ti > 1e-12 {
                    jm = jm.min(ji / ti);
                }
            }
        }
    }
    if jm.is_finite() { jm } else { 1.0 }
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
    a.smp[ea].v_curve = a.smp[ea].v_curve.min(vj);
    b.smp[0].v_curve = b.smp[0].v_curve.min(vj);
}

impl<K: Kinematics> Planner<K> {
    /// Places the planner at rest at axis position `position`, dropping every queued move and
    /// any hold: for a kernel whose machine was moved by other means (jog, homing, a stop
    /// outside the path). Allocation-free. Refuses a non-finite position.
    pub fn reset_at(&mut self, position: AxisVec) -> Result<(), MotionError> {
        if !position.iter().all(|x| x.is_finite()) {
            return Err(MotionError::InvalidLimit {
                what: "start position".into(),
                value: f64::NAN,
            });
        }
        self.q.clear();
        self.builder.clear(position);
        self.line_profile = None;
        self.hold = None;
        self.dwell_left = None;
        self.s = 0.0;
        self.v = 0.0;
        self.a = 0.0;
        self.stop_cum = 0.0;
        self.stop_idx = 0;
        self.hist = [position; 3];
        Ok(())
    }
}
