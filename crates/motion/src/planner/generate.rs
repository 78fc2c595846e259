//! The set-point generator: one servo period from a generator state, verified against every
//! axis's finite-difference box, and the rollback on a dead end.
//!
//! Per period: exact bounds of the path acceleration and jerk at the current point, then the
//! largest path jerk whose end state passes the speed model (stop distance, the braking
//! curve at the end of the period and along a jerk-limited probe onto the curve's slope),
//! found by a short bisection around the last period's jerk; then the set-point is computed
//! once and checked against the box of every axis. A point outside is replaced by the
//! nearest admissible point on the path (the state then follows that point, so nothing is
//! moved after the fact); when the path has no admissible point, the generator is at a dead
//! end and rolls back.

use super::*;
use crate::geometry::Shape;
use crate::otg::{Limits as OtgLimits, State as OtgState, position_profile};
use crate::piece::jerk_stop_speed;
use crate::scurve::{over_brakes, stop_advance};

/// Share of the projected axis limits the speed policy uses (the set-point check allows the
/// rest; the margin absorbs the rounding of the check).
pub(super) const CONTROL_SHARE: f64 = 0.9999;
/// Share of the stop model's deceleration the policy plans its stops with.
pub(super) const STOP_SHARE: f64 = 0.97;
/// The same for the jerk: the discrete landing on a stop needs a little more jerk than the
/// continuous profile it follows.
pub(super) const STOP_JERK_SHARE: f64 = 0.9;

/// The distance of the stop model (`am`, `jm`) from (v, a). A state that already brakes so
/// hard that the model's jerk cannot release the deceleration before the speed is zero
/// stops with the path's full jerk `j_full` instead: the model's distance ends at zero
/// speed with the deceleration still on, a point no jerk-limited set-point can land on (a
/// quick stop aimed there met a dead end and ended 1.7 × over the jerk limit).
pub(super) fn stop_reach(v: f64, a: f64, am: f64, jm: f64, j_full: f64) -> f64 {
    let j = if over_brakes(v, a, jm) {
        j_full.max(jm)
    } else {
        jm
    };
    stop(v, a, am, j).0
}
/// Speed-model scale per rollback attempt at the same dead end (deceleration, jerk and the
/// braking-curve cap all shrink by this factor per attempt). The restart state is on the
/// curve, so the cap puts it above the stricter one and it brakes as hard as the path
/// allows until under it; a step of 10 % often took it to a near stop where less was
/// needed (three adaptive clearing programs 0.3 % slower than with 5 %).
const STRICT_FACTOR: f64 = 0.95;
/// Longest stop, in periods, that the generator follows on the time-optimal profile under
/// one period's bounds of the path when the stop model has lost the state (the bounds
/// change along the path; over a few tens of milliseconds little).
const EXACT_STOP_PERIODS: usize = 64;
/// Pieces [`Planner::release_jerk`] looks at, at most.
const RELEASE_PIECES: usize = 16;
/// Set-points dropped by the first rollback at a dead end (doubling per attempt).
const ROLLBACK_FIRST: usize = 4;
/// Buffered entries a rollback looks at, at most, for a state that fits the stricter model.
const RESTART_CHECKS: usize = 32;
/// Resolution of the jerk search, relative to the width of the admissible range: the
/// chosen jerk is within this of the largest the model accepts (about 100 mm/s³ for an
/// axis jerk of 50 000 mm/s³: 5e-5 mm/s of speed left unused over a 1 ms period).
const JERK_RESOLUTION: f64 = 1.0 / 1024.0;

/// Points of the probe's ramp onto the braking curve's slope at which it must be under the
/// curve (evenly spaced, besides where its acceleration crosses zero). The curve bends
/// sharply where it leaves a level stretch for a valley: with two points, the ramp passed
/// above the bend between them, and the state, already too fast, braked as hard as the path
/// allows and fell far below the valley (engrave-text-inch's corners, 0.7 % slower).
const PROBE_POINTS: usize = 8;

/// What the speed model needs for one period.
struct Model {
    t: f64,
    v: f64,
    a: f64,
    at: f64,
    idx: usize,
    rem: f64,
    stop_at: f64,
    a_lo: f64,
    a_hi: f64,
    a_stop: f64,
    j_stop: f64,
    /// Jerk and deceleration of the probe onto the braking curve.
    jb: f64,
    d_nom: f64,
    /// Cap on the braking curve (1 unless a rollback made the policy stricter).
    cap: f64,
    quick: bool,
    /// Lowest braking-curve speed within the farthest reach of this period's probes: a
    /// probe whose speed stays under it needs no lookups.
    w_floor: f64,
}

/// Why a path jerk is refused by the model.
#[derive(Clone, Copy, PartialEq)]
enum Verdict {
    Safe,
    /// Overshoots the stop (or the hold point), or brakes harder than the path allows.
    Stop,
    /// Its stop from the end of the period (a releasable one) ends beyond the stop or
    /// hold point; so does every larger jerk's (the stop distance grows with the jerk).
    Overshoot,
    /// Exceeds the braking curve.
    Curve,
    /// Ends the period above the path's acceleration bound; so does every larger jerk.
    AccelBound,
}

impl Verdict {
    /// Refused for the stop (either way).
    fn is_stop(self) -> bool {
        matches!(self, Verdict::Stop | Verdict::Overshoot)
    }
}

/// What every part of one period of the speed policy shares.
struct Period {
    /// The piece the period starts on.
    idx: usize,
    /// Path position of the next stop of the path.
    stop_at: f64,
    /// A quick stop is in progress (the axes' quick-stop limits apply).
    quick: bool,
    /// Strictness of the braking curve and of the stop model ([`Planner::strictness`]).
    f: f64,
    f_stop: f64,
}

/// A stop the period brakes for: the way left to it, and the deceleration and jerk of its
/// model (before the shares and the strictness).
#[derive(Clone, Copy)]
struct StopGoal {
    rem: f64,
    a: f64,
    j: f64,
}

/// Bounds of the path acceleration and jerk for one period.
struct PeriodBounds {
    a_lo: f64,
    a_hi: f64,
    j_lo: f64,
    j_hi: f64,
    /// The lowest jerk the model may choose: the hardest braking the bounds allow.
    j_min: f64,
    /// The axes' acceleration and jerk limits projected on the path here, with the
    /// policy's share (the bounds never exceed them).
    a_full: f64,
    jm: f64,
}

/// The landing on a stop a few periods away.
struct Landing {
    /// This period's step of the landing sequence, when there is one.
    step: Option<f64>,
    /// Steps in that sequence, this one included (0: none).
    n: usize,
    /// This period ends at the stop (or the machine is already at rest there).
    lands: bool,
}

/// The step the policy chose for one period, before the set-point check.
struct Step {
    /// Path step aimed at (never beyond the stop).
    ds: f64,
    /// The model's own step before it was clamped to the way left; NaN for a landing.
    model_ds: f64,
    /// Path jerk of a constant-jerk step (0 for a landing and the stop profile).
    j: f64,
    /// Speed and acceleration at the end of the period when the model's step does not
    /// give them (the stop profile, or the hard brake that replaces it).
    exact: Option<(f64, f64)>,
}

impl Step {
    /// A step of a landing: its state follows from the steps themselves.
    fn landing(ds: f64) -> Step {
        Step {
            ds,
            model_ds: f64::NAN,
            j: 0.0,
            exact: None,
        }
    }
}

impl<K: Kinematics> Planner<K> {
    /// One generator step from the buffer's front; a dead end rolls back instead.
    pub(super) fn generate_one(&mut self, front: &GenState) {
        self.stats.generated += 1;
        match self.step(front, false) {
            Some(st) => {
                self.leave_strict(&st);
                trace!(
                    self.trace,
                    "GEN at={} v={} a={} ds={:?} land={} state={:?}",
                    st.at,
                    st.v,
                    st.a,
                    st.ds_hist,
                    st.land_n,
                    st.state
                );
                self.ahead.push(st);
            }
            None if self.ahead.len == 0 => {
                // Nothing left to roll back: the nearest point is emitted (and counted).
                let st = self.step(front, true).unwrap_or_else(|| still(*front));
                self.leave_strict(&st);
                self.ahead.push(st);
            }
            None => self.rollback(front),
        }
    }

    /// A step that always gives a set-point: at a dead end the nearest point on the path,
    /// counted in `limit_violations`.
    pub(super) fn generate_forced(&mut self, front: &GenState) -> GenState {
        self.stats.generated += 1;
        let st = self.step(front, true).unwrap_or_else(|| still(*front));
        self.leave_strict(&st);
        st
    }

    /// Ends a rollback's stricter model once `st` is past its dead end: a little past it
    /// (one just after it is the same one), or at rest at the stop it braked for (a dead
    /// end on the way into a stop: the next piece starts where it was, and the stricter
    /// model there kept the machine at rest for ever). A state at rest short of the stop
    /// keeps it (a dead end at rest is met again from there). The model is kept aside
    /// until the emitted set-point has passed it too ([`Planner::strict_passed`]): set-points
    /// regenerated before it (a push re-runs the braking curve back to the last real stop
    /// and drops what saw it) take it again, and a dead end met there continues its
    /// escalation instead of starting from the first attempt (a trochoid loop into a
    /// corner met the same dead end at every push, each time with fewer set-points left
    /// to roll back, until none were left and one 158 × over the jerk limit was emitted).
    fn leave_strict(&mut self, st: &GenState) {
        if let Some(s) = self.strict
            && (st.at > s.until + 8.0 * st.v * self.period + 1e-9
                || (st.v <= 0.0 && st.a == 0.0 && st.at >= s.until && st.at >= s.stop_at))
        {
            self.strict_passed = Some(s);
            self.strict = None;
        }
    }

    /// Drops the last set-points and makes the model stricter until the dead end is passed
    /// (braking-curve cap, probe jerk and deceleration × `STRICT_FACTOR` per attempt at the
    /// same place; the stop model too when the dead end was on the way into a stop, and
    /// there no weaker before it than at the dead end). At least 4, 8, 16, ... entries are
    /// dropped, and more until the newest kept one fits (`restart_fits`): on or under the
    /// braking curve, able to stop with the stricter stop model. A restart state that is a
    /// dead end under the stricter model itself only cascades: the rollbacks would reach
    /// the emitted set-point. When no buffered entry fits, generation restarts from the
    /// emitted state, with the stop model only as strict as that state allows.
    fn rollback(&mut self, front: &GenState) {
        self.stats.rollbacks += 1;
        let reach = 8.0 * front.v * self.period + 1e-9;
        let prev = self
            .strict
            .or(self.strict_passed)
            .filter(|s| front.at <= s.until + reach);
        let attempt = prev.map_or(0, |s| s.attempt + 1);
        let until = prev.map_or(front.at, |s| s.until.max(front.at));
        let f = STRICT_FACTOR.powi(attempt as i32 + 1);
        // The stop model is made stricter only for a dead end on the way into a stop (and
        // then no weaker anywhere before it than where the dead end was); elsewhere a weaker
        // stop model only makes the states that brake for a later stop dead ends too.
        let (mut stop_at, mut a_stop, mut j_stop) = match prev {
            Some(s) => (s.stop_at, s.a_stop, s.j_stop),
            None => (f64::NAN, f64::INFINITY, f64::INFINITY),
        };
        if self.braking_for_stop(front)
            && let Some((_, p)) = self.moving_piece(front)
        {
            let (a, j) = self.stop_model(p, front.at);
            if p.stop_ahead.0 != stop_at {
                (a_stop, j_stop) = (f64::INFINITY, f64::INFINITY);
            }
            stop_at = p.stop_ahead.0;
            a_stop = a_stop.min(a);
            j_stop = j_stop.min(j);
        }
        let stop = stop_at.is_finite();
        let mut f_stop = if stop { f } else { 1.0 };
        // The region's rules apply to the restart search already.
        let from = self.last_stop_before(front);
        let from = prev.map_or(from, |s| s.from.min(from));
        self.strict = Some(Strict {
            from,
            until,
            attempt,
            f,
            f_stop,
            stop_at,
            a_stop,
            j_stop,
        });
        let k = ROLLBACK_FIRST << attempt.min(16);
        let keep = self.restart_keep(self.ahead.len.saturating_sub(k), f_stop);
        if keep == 0 {
            let st = self.cur;
            f_stop = self.stop_strictness_needed(&st, f_stop).unwrap_or(1.0);
        }
        let dropped = self.ahead.drop_back(self.ahead.len - keep);
        self.stats.rolled_back += dropped as u64;
        trace!(
            self.trace,
            "ROLLBACK at={} v={} a={} attempt={attempt} dropped={dropped} kept={keep} f={f} f_stop={f_stop}",
            front.at,
            front.v,
            front.a
        );
        if let Some(s) = &mut self.strict {
            s.f_stop = f_stop;
        }
    }

    /// Path position of the end of the last stop of the path before `st` (the end of the
    /// nearest piece behind its own that ends in a stop), looking back no further than the
    /// emitted set-point's piece: -∞ when there is none.
    fn last_stop_before(&self, st: &GenState) -> f64 {
        let (Some(i), Some(first)) = (self.q.index(st.id), self.q.index(self.cur.id)) else {
            return f64::NEG_INFINITY;
        };
        (first..i)
            .rev()
            .map(|k| self.q.get(k))
            .find(|p| p.stop_at_end)
            .map_or(f64::NEG_INFINITY, |p| p.cum_start + p.len)
    }

    /// Whether `st` brakes for the next stop: its stop (with the model's shares) takes
    /// half of the way there or more.
    pub(super) fn braking_for_stop(&self, st: &GenState) -> bool {
        let Some((_, p)) = self.moving_piece(st) else {
            return false;
        };
        let (a_stop, j_stop) = self.stop_model(p, st.at);
        let rem = self.to_stop(st, p);
        let (d, _) = stop(st.v, st.a, STOP_SHARE * a_stop, STOP_JERK_SHARE * j_stop);
        2.0 * d >= rem
    }

    /// Deceleration and jerk of the stop model at path position `at` on piece `p` (before
    /// the shares and the strictness): the piece's own, and within a rollback's region no
    /// more than the dead end met on the way into the same stop (a piece nearer the stop
    /// may allow less than the pieces before it assumed).
    fn stop_model(&self, p: &Piece, at: f64) -> (f64, f64) {
        // A piece far from the stop keeps no model (`Planner::backward`): from its end every
        // state under the braking curve can stop with the model of the pieces after it, and
        // its own deceleration and jerk keep the stop profile within what it allows here.
        let mut a_stop = if p.a_to_stop.is_finite() && p.a_to_stop > 1e-3 * self.a_min {
            p.a_to_stop
        } else {
            // Its own deceleration at the braking curve is nearly 0 where a curve holds
            // the speed at its centripetal limit: a model with it overshoots any stop,
            // however far, and a whole curve in the window with tight loops at its ends
            // (an epitrochoid's) braked in vain and emitted set-points up to 9000 × the
            // jerk limit. Far from the stop the braking curve governs: at least half the
            // weakest axis's deceleration.
            p.a_sub[0]
                .max(0.5 * self.a_min)
                .min(self.a_min * BRAKE_SHARE_STRAIGHT)
        };
        let mut j_stop = if p.j_to_stop.is_finite() {
            p.j_to_stop
        } else {
            p.j_brake
        };
        if let Some(s) = self.strict
            && at <= s.until
            && s.stop_at == p.stop_ahead.0
        {
            a_stop = a_stop.min(s.a_stop);
            j_stop = j_stop.min(s.j_stop);
        }
        (a_stop, j_stop)
    }

    /// The jerk a deceleration `a` at speed `v` is released with from path position `at`
    /// (on piece `idx` or later): `jr`, at most the braking jerk of every piece the release
    /// reaches (it ends within v·|a|/jr). Bounded: at most `RELEASE_PIECES` pieces.
    fn release_jerk(&self, idx: usize, at: f64, v: f64, a: f64, jr: f64) -> f64 {
        if !(jr > 0.0) {
            return jr;
        }
        let end = at + v.max(0.0) * (-a).max(0.0) / jr;
        let mut j = jr;
        let mut i = idx;
        while i < self.q.len && i < idx + RELEASE_PIECES {
            let p = self.q.get(i);
            j = j.min(p.j_brake);
            if p.cum_start + p.len >= end || p.stop_at_end {
                break;
            }
            i += 1;
        }
        j
    }

    /// How many buffered entries to keep so that generation restarts from a state that
    /// fits (`restart_fits`): at most `keep`, fewer while the newest kept entry does not
    /// (bounded: at most `RESTART_CHECKS` entries are looked at, evenly spaced); 0 when
    /// none does.
    fn restart_keep(&self, keep: usize, f_stop: f64) -> usize {
        let stride = keep.div_ceil(RESTART_CHECKS).max(1);
        let mut n = keep;
        while n > 0 {
            match self.ahead.get(n - 1) {
                Some(st) if !self.restart_fits(st, f_stop) => n = n.saturating_sub(stride),
                _ => return n,
            }
        }
        0
    }

    /// Whether generation can restart from `st`: it is on or under the braking curve (up
    /// to ½·J·T² at the braking jerk: states that follow the curve overshoot it by about
    /// that), and it can still stop at the next stop with the stop model scaled by
    /// `f_stop`. A state above the curve was generated after the model had already lost
    /// it, and the stricter model would only lose it again.
    fn restart_fits(&self, st: &GenState, f_stop: f64) -> bool {
        let Some((idx, p)) = self.moving_piece(st) else {
            return true;
        };
        let (w, _) = self.w_abs(idx, st.at, p.stop_ahead.0);
        let t = self.period;
        st.v <= w + 0.5 * p.j_brake * t * t && self.stop_fits(st, f_stop)
    }

    /// Path length from `st` on piece `p` to the next stop: the rest of the piece, exact
    /// (local arc lengths), plus the pieces from its end to the stop (none when the piece
    /// ends in it). The last step onto a stop then lands on the piece's end exactly,
    /// wherever the piece is on the path (the difference of two path positions is only as
    /// fine as their size: a step that fell short of the end by that much and found
    /// nothing left to go left the machine at rest for ever).
    pub(super) fn to_stop(&self, st: &GenState, p: &Piece) -> f64 {
        let rest = p.len - st.s;
        let ends_in_stop = p.stop_at_end || self.q.index(st.id).is_none_or(|i| i + 1 >= self.q.len);
        if ends_in_stop {
            rest
        } else {
            rest + (p.stop_ahead.0 - (p.cum_start + p.len))
        }
    }

    /// The piece `st` moves on (none at rest, in a dwell or on an isolated line's S-curve:
    /// any model fits there).
    pub(super) fn moving_piece(&self, st: &GenState) -> Option<(usize, &Piece)> {
        if st.prof_t.is_some() || (st.v <= 0.0 && st.a <= 0.0) {
            return None;
        }
        let idx = self.q.index(st.id)?;
        let p = self.q.get(idx);
        (p.len > 0.0).then_some((idx, p))
    }

    /// Whether `st` can still stop at the next stop (and release its deceleration before
    /// the speed reaches zero, at the path's braking jerk where the model's is too low)
    /// with the stop model scaled by `f`. Always during a hold (its
    /// stop is not scaled, and a rollback cannot reach before the request).
    pub(super) fn stop_fits(&self, st: &GenState, f: f64) -> bool {
        self.hold.is_some() || self.path_stop_fits(st, f)
    }

    /// [`stop_fits`](Self::stop_fits) with the path's own stop model, whether or not a
    /// hold is in force.
    pub(super) fn path_stop_fits(&self, st: &GenState, f: f64) -> bool {
        let Some((idx, p)) = self.moving_piece(st) else {
            return true;
        };
        let (a_stop, j_stop) = self.stop_model(p, st.at);
        let (am, jm) = (STOP_SHARE * a_stop * f, STOP_JERK_SHARE * j_stop * f);
        let v = st.v.max(0.0);
        // The model's own tolerances (`judge`).
        let rem = self.to_stop(st, p);
        let jr = if st.a < 0.0 && st.a * st.a > 2.0 * jm * v {
            self.release_jerk(idx, st.at, v, st.a, 0.8 * p.j_brake * f)
        } else {
            0.0
        };
        release_and_stop(v, st.a, am, jm, jr).is_some_and(|d| d <= rem * (1.0 + 1e-12) + 1e-12)
    }

    /// The strictest factor of the stop model, down to `f_min`, with which `st` can still
    /// stop (bisection, 12 steps); None when even the unscaled model does not fit.
    fn stop_strictness_needed(&self, st: &GenState, f_min: f64) -> Option<f64> {
        if self.stop_fits(st, f_min) {
            return Some(f_min);
        }
        if !self.stop_fits(st, 1.0) {
            return None;
        }
        let (mut lo, mut hi) = (f_min, 1.0);
        for _ in 0..12 {
            let mid = 0.5 * (lo + hi);
            if self.stop_fits(st, mid) {
                hi = mid;
            } else {
                lo = mid;
            }
        }
        Some(hi)
    }

    /// One period from `prev`: releases finished stops and dwells, then moves. None at a
    /// dead end (unless `force`).
    fn step(&mut self, prev: &GenState, force: bool) -> Option<GenState> {
        let st = self.step_unchecked(prev, force)?;
        if st.hist[0] == prev.hist[0] && st.hist[1] == prev.hist[0] {
            // A period at rest is a set-point too: coming to rest must keep the box.
            let quick =
                self.quick_rest || matches!(self.hold, Some(h) if h.kind == StopKind::Quick);
            if prev.hist.iter().all(|h| *h == prev.hist[0]) {
                self.quick_rest = false;
            }
            let (lo, hi) = self.fd_box(&prev.hist, quick);
            if !inside(&self.lim, &st.hist[0], &lo, &hi) {
                if !force {
                    trace!(
                        self.trace,
                        "DEAD END at rest at={} v={} a={}", prev.at, prev.v, prev.a
                    );
                    return None;
                }
                self.stats.limit_violations += 1;
            }
        }
        Some(st)
    }

    fn step_unchecked(&mut self, prev: &GenState, force: bool) -> Option<GenState> {
        let t = self.period;
        let mut st = *prev;
        st.stopped = false;
        for _ in 0..=self.q.cap() {
            if let Some(h) = self.hold
                && st.v <= 0.0
                && st.a.abs() <= 1e-9
            {
                st.v = 0.0;
                st.a = 0.0;
                st.prof_t = None;
                st.land_n = 0;
                if h.kind == StopKind::Hold {
                    st.state = MotionState::Holding;
                } else {
                    st.stopped = true;
                    st.state = MotionState::Idle;
                }
                return Some(still(st));
            }
            let Some(idx) = self.q.index(st.id) else {
                st.v = 0.0;
                st.a = 0.0;
                st.s = 0.0;
                st.at = self.cum_end;
                st.prof_t = None;
                st.land_n = 0;
                st.line = 0;
                st.state = MotionState::Idle;
                return Some(still(st));
            };
            let p = self.q.get(idx);
            st.line = p.line;
            if p.len <= 0.0 {
                let left = st.dwell_left.unwrap_or(p.dwell) - t;
                if left <= 1e-12 {
                    st.dwell_left = None;
                    st.id += 1;
                    st.s = 0.0;
                    st.at = p.cum_start;
                    if p.dwell > 0.0 {
                        st.state = MotionState::Dwelling;
                        return Some(still(st));
                    }
                    continue;
                }
                st.dwell_left = Some(left);
                st.state = MotionState::Dwelling;
                return Some(still(st));
            }
            let at_end = st.s >= p.len - 1e-12;
            if at_end && st.v <= 0.0 && (p.stop_at_end || idx + 1 == self.q.len) {
                st.v = 0.0;
                st.a = 0.0;
                st.id += 1;
                st.s = 0.0;
                st.at = p.cum_start + p.len;
                st.land_n = 0;
                st.prof_t = None;
                continue;
            }
            st.state = MotionState::Moving;
            if let Some(next) = self.follow_line_profile(&st, idx) {
                return Some(next);
            }
            return self.control(st, idx, force);
        }
        Some(still(st))
    }

    /// The strictness factors (braking curve, stop model) at path position `at` (1 outside
    /// a rollback's region).
    fn strictness(&self, at: f64) -> (f64, f64) {
        match self.strict {
            Some(s) if at <= s.until && at >= s.from => (s.f, s.f_stop),
            _ => (1.0, 1.0),
        }
    }

    /// An isolated straight line (starting at rest, ending in a stop, no hold or stop in
    /// progress) follows the time-optimal rest-to-rest S-curve of the OTG under the feed and
    /// the axis limits projected on the line: its duration is the optimum, and every period
    /// samples the continuous profile, so the finite differences stay within the limits.
    /// None when the speed policy decides (also when a sample fails the set-point check:
    /// the policy then takes over from the profile's state).
    fn follow_line_profile(&mut self, st: &GenState, idx: usize) -> Option<GenState> {
        let t = self.period;
        let head = self.q.get(idx);
        let id = st.id;
        if st.prof_t.is_none() {
            let straight = head.stop_at_end
                && (0..=head.ns).all(|k| head.smp[k].k.iter().all(|c| *c == 0.0))
                && (0..head.ns).all(|k| head.smp[k].t == head.smp[k + 1].t);
            if !(straight
                && self.hold.is_none()
                && self.strict.is_none()
                && st.s == 0.0
                && st.v == 0.0
                && st.a == 0.0)
            {
                return None;
            }
        }
        let profile = match self.profile_of(id) {
            Some(pr) => pr,
            None => {
                // Not planned yet, or evicted (then it was planned from rest as well).
                let rest = OtgState {
                    p: 0.0,
                    v: 0.0,
                    a: 0.0,
                };
                let pr = self.line_profile_from(idx, rest)?;
                self.keep_profile(id, pr);
                pr
            }
        };
        let head = self.q.get(idx);
        let elapsed = st.prof_t.unwrap_or(0.0) + t;
        let rem = head.len - st.s;
        let (ds, v, a, done) = if elapsed >= profile.duration() {
            (rem, 0.0, 0.0, true)
        } else {
            let smp = profile.at(elapsed);
            (clampf(smp.p - st.s, 0.0, rem), smp.v, smp.a, false)
        };
        let x = if done { head.end } else { head.pos(st.s + ds) };
        let (lo, hi) = self.fd_box(&st.hist, false);
        if !inside(&self.lim, &x, &lo, &hi) {
            return None;
        }
        let mut n = *st;
        n.adjusted = false;
        n.prof_t = if done { None } else { Some(elapsed) };
        n.v = v;
        n.a = a;
        n.j_last = 0.0;
        n.ds_hist = [st.ds_hist[1], ds];
        n.s = if done {
            head.len
        } else {
            (st.s + ds).min(head.len)
        };
        n.at = head.cum_start + n.s;
        n.hist = [x, st.hist[0], st.hist[1]];
        Some(n)
    }

    /// The time-optimal S-curve of the straight piece `idx` from `from` (local arc length,
    /// speed, acceleration) to rest at its end, under the feed (with the overrides) and the
    /// axis limits projected on the line, a hair inside them: 1e-7, and more where the
    /// set-point check's allowance for the rounding of the coordinates (16 ulp of the
    /// three positions it differences) eats into the jerk step J·T³ (the profile runs at
    /// its limits exactly; from about 400 mm from the origin at 50 000 mm/s³ and 1 ms the
    /// 1e-7 alone no longer covered it, the profile's samples failed the check while
    /// braking and the speed policy, handed a state at the full limits, could not follow).
    /// From a moving state (an override changed the feed) the profile must not reverse: when
    /// slowing down to the new feed first would overshoot the line's end, the speed limit
    /// stays at the current speed (the stop at the end binds anyway). None when no
    /// monotonic profile exists.
    pub(super) fn line_profile_from(&self, idx: usize, from: OtgState) -> Option<Profile> {
        let head = self.q.get(idx);
        let vmax = (0..=head.ns)
            .map(|k| head.vlc_span(k, self.fo, self.ro))
            .fold(f64::INFINITY, f64::min);
        let t = self.period;
        // Shares of the speed, acceleration and jerk limits.
        let mut share: [f64; 3] = [1.0 - 1e-7; 3];
        for &i in self.lim.present_axes() {
            // The coordinates the check differences, the profile's own position along the
            // line, and their evaluation, each within a few ulp, against the steps v·T,
            // a·T², j·T³.
            let size = head.start[i].abs().max(head.end[i].abs()) + head.len + 1.0;
            let rounding = 64.0 * f64::EPSILON * size;
            let steps = [
                self.lim.v[i] * t,
                self.lim.a[i] * t * t,
                self.lim.j[i] * t * t * t,
            ];
            for (sh, step) in share.iter_mut().zip(steps) {
                *sh = sh.min(1.0 - 1e-7 - rounding / step).max(0.5);
            }
        }
        let end = OtgState {
            p: head.len,
            v: 0.0,
            a: 0.0,
        };
        if !(vmax > 1e-9) {
            // An override of 0 %: the speed policy brings the machine to rest on the path.
            return None;
        }
        for v_lim in [
            share[0] * vmax,
            (share[0] * vmax).max(from.v * (1.0 + 1e-9)),
        ] {
            let limits =
                OtgLimits::symmetric(v_lim, share[1] * head.a_proj[0], share[2] * head.j_proj[0]);
            let Ok(profile) = position_profile(from, end, &limits) else {
                continue;
            };
            // Monotonic along the path, checked at every period (bounded: the profile is
            // at most a line's S-curve long).
            let n = ((profile.duration() / t).ceil() as usize).min(1 << 20);
            if (0..=n).all(|k| profile.at(k as f64 * t).v >= -1e-9) {
                return Some(profile);
            }
        }
        None
    }

    /// Piece index and local arc length `ds` ahead of (`idx`, `s`), never beyond the next
    /// stop (at path position `stop_at`), where it is the stop's exact end.
    #[inline]
    fn locate(&self, idx: usize, s: f64, at: f64, ds: f64, stop_at: f64) -> (usize, f64) {
        let p = self.q.get(idx);
        if s + ds <= p.len {
            return (idx, (s + ds).max(0.0));
        }
        if p.stop_at_end || idx + 1 >= self.q.len {
            return (idx, p.len);
        }
        self.find(idx, at + ds, stop_at)
    }

    /// The piece containing path position `target` (binary search over the window from
    /// `from`), never beyond the stop at `stop_at`.
    pub(super) fn find(&self, from: usize, target: f64, stop_at: f64) -> (usize, f64) {
        let clamped = target >= stop_at;
        let target = target.min(stop_at);
        // Most targets lie within a few pieces: gallop from `from` (strides 1, 2, 4, ...)
        // to bracket the target, then bisect the bracket.
        let mut lo = from;
        let mut hi = self.q.len.saturating_sub(1).max(from);
        let mut stride = 1;
        while lo + stride <= hi {
            if self.q.get(lo + stride).cum_start < target {
                lo += stride;
                stride *= 2;
            } else {
                hi = lo + stride - 1;
                break;
            }
        }
        while lo < hi {
            let mid = (lo + hi).div_ceil(2);
            if self.q.get(mid).cum_start < target {
                lo = mid;
            } else {
                hi = mid - 1;
            }
        }
        let p = self.q.get(lo);
        if clamped && p.cum_start + p.len >= stop_at - 1e-9 {
            return (lo, p.len);
        }
        (lo, (target - p.cum_start).clamp(0.0, p.len))
    }

    /// Braking-curve speed and slope at path position `target`.
    #[inline]
    fn w_abs(&self, from: usize, target: f64, stop_at: f64) -> (f64, f64) {
        if target > stop_at {
            return (0.0, 0.0);
        }
        let (i, sl) = self.find(from, target, stop_at);
        self.q.get(i).w_at(sl)
    }

    /// The model's verdict on path jerk `j` for this period.
    fn judge(&self, m: &Model, j: f64) -> Verdict {
        let (ds, v1, a1) = advance(0.0, m.v, m.a, j, m.t);
        if v1 < -1e-9 || ds < 0.0 || ds > m.rem + 1e-12 || a1 < m.a_lo.min(-1e-9) - 1e-9 {
            return Verdict::Stop;
        }
        if a1 > m.a_hi.max(0.0) + 1e-9 {
            return Verdict::AccelBound;
        }
        let v1 = v1.max(0.0);
        // A deceleration the stop model's jerk cannot release before the speed is gone is
        // released with the braking jerk of the pieces the release reaches.
        let jr = if a1 < 0.0 && a1 * a1 > 2.0 * m.j_stop * v1 {
            self.release_jerk(m.idx, m.at + ds, v1, a1, m.jb)
        } else {
            m.jb
        };
        let Some(dst) = release_and_stop(v1, a1, m.a_stop, m.j_stop, jr) else {
            // The speed would reach zero before the deceleration can be released: no
            // smooth stop.
            return Verdict::Stop;
        };
        if ds + dst > m.rem * (1.0 + 1e-12) + 1e-12 {
            return Verdict::Overshoot;
        }
        let at1 = m.at + ds;
        // The highest speed of the probe below (where its acceleration crosses zero).
        let v_peak = v1 + a1.max(0.0) * a1.max(0.0) / (2.0 * m.jb);
        let quiet = a1 <= 0.0 || self.q.get(m.idx).straight;
        if v_peak <= m.cap * m.w_floor && quiet {
            return Verdict::Safe;
        }
        let (w1, _) = self.w_abs(m.idx, at1, m.stop_at);
        if v1 > m.cap * w1 * (1.0 + 1e-12) + 1e-12 {
            return Verdict::Curve;
        }
        // Probe: ramp the acceleration down to the nominal deceleration with the braking
        // jerk; the speed must stay under the curve where the acceleration crosses zero and
        // along the ramp. The nominal deceleration also where the curve descends more
        // gently: a ramp that ends on the curve's slope falls short of where the curve
        // leaves that slope for a steeper one (a shallow valley just before a deep one), and
        // the state met that bend too fast, braked as hard as the path allows and fell far
        // below the deep valley.
        let dd = m.d_nom;
        let tau0 = a1.max(0.0) / m.jb;
        let tau = (a1 + dd) / m.jb;
        if tau <= 0.0 {
            return Verdict::Safe;
        }
        // While the acceleration is still positive, it must also fit the path bound where
        // the probe is (on a curve the centripetal load leaves less as the speed grows).
        let np = PROBE_POINTS;
        for n in 0..np + 2 {
            let tk = match n {
                0 => 0.5 * tau0,
                1 => tau0,
                _ => tau0 + (tau - tau0) * (n - 1) as f64 / np as f64,
            };
            if tk <= 0.0 {
                continue;
            }
            let (dp, vp, ap) = advance(0.0, v1, a1, -m.jb, tk);
            if vp <= 0.0 {
                break;
            }
            let target = at1 + dp.max(0.0);
            if target > m.stop_at {
                return Verdict::Curve;
            }
            let (i, sl) = self.find(m.idx, target, m.stop_at);
            let p = self.q.get(i);
            let (wp, _) = p.w_at(sl);
            if vp > m.cap * wp * (1.0 + 1e-12) + 1e-12 {
                return Verdict::Curve;
            }
            if ap > 0.0 && !p.straight {
                let (_, a_hi) = accel_bounds(&self.lim, &p.geo_at(sl), vp, m.quick);
                if ap > a_hi {
                    return Verdict::Curve;
                }
            }
        }
        Verdict::Safe
    }

    /// Lowest braking-curve speed from the current point to the farthest point a probe of
    /// this period can reach (pieces' `w_low`, and the stop's jerk-limited shape there).
    #[inline(always)]
    fn w_floor(&self, m: &Model, j_hi: f64) -> f64 {
        let t = m.t;
        let a1 = m.a.max(0.0) + j_hi.max(0.0) * t;
        let v1 = m.v + m.a.max(0.0) * t + 0.5 * j_hi.max(0.0) * t * t;
        let v_peak = v1 + a1 * a1 / (2.0 * m.jb);
        let reach = v1 * t + v_peak * (a1 + m.d_nom) / m.jb;
        let end = (m.at + reach).min(m.stop_at);
        let mut floor = f64::INFINITY;
        let mut i = m.idx;
        // Bounded by the window; the reach of one probe covers a few pieces.
        while i < self.q.len {
            let p = self.q.get(i);
            floor = floor.min(p.w_low);
            if p.cum_start + p.len >= end || p.stop_at_end {
                break;
            }
            i += 1;
        }
        let (stop_pos, sa, sj) = self.q.get(m.idx).stop_ahead;
        if stop_pos.is_finite() && sa > 0.0 && sj > 0.0 {
            floor = floor.min(jerk_stop_speed((stop_pos - end).max(0.0), sa, sj).0);
        }
        floor
    }

    /// One period of the path-speed policy from `st` (moving, on piece `idx`): the stop it
    /// brakes for and the path's bounds here, the speed model, the step (a landing on the
    /// stop, the model's jerk, or the stop profile when no jerk keeps the stop), the
    /// set-point check, and the state that reaches the set-point. None at a dead end
    /// (unless `force`).
    fn control(&mut self, st: GenState, idx: usize, force: bool) -> Option<GenState> {
        let t = self.period;
        let head = self.q.get(idx);
        let quick = matches!(self.hold, Some(h) if h.kind == StopKind::Quick);
        let (f, f_stop) = self.strictness(st.at);
        let pd = Period {
            idx,
            stop_at: head.stop_ahead.0,
            quick,
            f,
            f_stop,
        };
        // The stop this period brakes for: the path's next stop, or a hold's point before it.
        let path_stop = self.path_stop(&st, head);
        let j_full = CONTROL_SHARE * head.j_proj[quick as usize];
        let (mut goal, mut hold_at) = self.hold_stop(&st, path_stop, quick, f, j_full);
        let b = self.period_bounds(&st, &pd);
        trace!(
            self.trace,
            "CTRL at={} v={} a={} a_lo={} a_hi={} j_lo={} j_hi={} rem={} w={}",
            st.at,
            st.v,
            st.a,
            b.a_lo,
            b.a_hi,
            b.j_lo,
            b.j_hi,
            goal.rem,
            self.w_abs(idx, st.at, pd.stop_at).0
        );
        // Whether the stop ahead is a hold's (its point is soft and moves on, see
        // `hold_stop`).
        let mut soft = hold_at.is_finite() && hold_at - st.at < pd.stop_at - st.at;
        let mut model = self.speed_model(&st, &pd, &b, goal, soft);
        // A hold whose gentler stop cannot follow from here waits, and the path's own model
        // decides this period.
        let mut hold_deferred = false;
        if soft && let Some(path_model) = self.deferred_hold_model(&st, &pd, &b, &model, path_stop)
        {
            model = path_model;
            goal = path_stop;
            soft = false;
            hold_deferred = true;
        }
        // A stop a few periods away is landed on with exact steps; else the model chooses.
        let landing = self.landing(&st, quick, &b, goal);
        let step = if landing.lands {
            Step::landing(goal.rem)
        } else if let Some(d1) = landing.step {
            Step::landing(d1)
        } else {
            self.policy_step(&st, &b, &model, goal, soft, &mut hold_at)
        };
        let (ds, x, k, sl) =
            self.checked_setpoint(&st, &pd, &step, goal.rem, landing.lands, force)?;
        if ds != step.ds {
            self.stats.adjusted += 1;
        }
        trace!(
            self.trace,
            "  chose ds_t={} ds={ds} model_ds={} j={} land={} landing={:?}",
            step.ds,
            step.model_ds,
            step.j,
            landing.lands,
            landing.step
        );
        // The state follows the set-point that passed the check, which may not be the one
        // aimed at.
        let mut n = self.moved_to(&st, ds, x, k, sl);
        n.adjusted = ds != step.ds;
        n.hold_at = hold_at;
        n.land_n = if ds == step.ds { landing.n } else { 0 };
        let rem0 = goal.rem.max(0.0);
        (n.v, n.a, n.j_last) = self.speed_after(&st, ds, rem0, &step, &landing, &b);
        if let (true, Some(h)) = (hold_deferred, self.hold) {
            // The hold point moves to where the hold's stop from here ends.
            let d_need = stop_reach(
                n.v,
                n.a.max(-h.a),
                STOP_SHARE * h.a,
                STOP_JERK_SHARE * h.j,
                j_full,
            );
            n.hold_at = n.hold_at.max(n.at + d_need + n.v * t);
        }
        Some(n)
    }

    /// The path's own next stop from `st` on `head`.
    fn path_stop(&self, st: &GenState, head: &Piece) -> StopGoal {
        let rem = self.to_stop(st, head);
        let (a, j) = self.stop_model(head, st.at);
        StopGoal { rem, a, j }
    }

    /// The stop this period brakes for, and the hold point: during a hold, the hold point
    /// with the hold's deceleration and jerk when it comes before the path's stop, else
    /// the path's stop.
    fn hold_stop(
        &self,
        st: &GenState,
        path: StopGoal,
        quick: bool,
        f: f64,
        j_full: f64,
    ) -> (StopGoal, f64) {
        let mut goal = path;
        let mut hold_at = st.hold_at;
        if let Some(h) = self.hold {
            // A hold point is soft: when the axes cannot brake as the stop model assumes (on a
            // curve at speed), it moves on to where the machine can stop from here.
            let jm = STOP_JERK_SHARE * h.j * f;
            let d_need = stop_reach(st.v, st.a.max(-h.a), STOP_SHARE * h.a * f, jm, j_full);
            // A quick stop's landing in progress is planned with the axes' own quick-stop
            // jerk, beyond the stop model's: the point it lands on stays.
            let landing_quick = quick && st.land_n >= 2;
            if !landing_quick && st.at + d_need > hold_at && hold_at - st.at > 0.0 {
                hold_at = st.at + d_need;
            } else if st.land_n == 0
                && st.a >= -h.a
                && !over_brakes(st.v, st.a, jm)
                && hold_at - st.at - d_need - h.slack > 2.0 * st.v * self.period
            {
                // The point is also no farther than a stop requested now would end: the
                // machine may be far slower than the model assumed when the stop began
                // (the path braked harder, for a slow line ahead). Kept out there, the
                // point let the speed policy cruise at that line's feed to it: a feed
                // hold in a canned cycle's rapid to its R plane drilled on at 1.35 mm/s
                // for over a second (the kernel fuzz target,
                // fuzz/defects/kernel/z-moves-at-1.35-mm-s-in-a-feed-hold). Not while the
                // state brakes harder than the model's jerk can release: pulled in to the
                // model's distance there, an abort in a hold's stop had no landing and
                // stopped X from 5.4 mm/s in one period
                // (fuzz/defects/kernel/abort-pulls-a-holds-point-where-no-stop-lands).
                let slack = if quick { 0.0 } else { st.v * self.period };
                hold_at = st.at + d_need + slack;
            }
            let hr = hold_at - st.at;
            if hr < goal.rem {
                goal = StopGoal {
                    rem: hr.max(0.0),
                    a: h.a,
                    j: h.j,
                };
            }
        }
        (goal, hold_at)
    }

    /// Exact bounds of the path acceleration and jerk at the current point, and of the
    /// acceleration at the point the period is expected to end at (the centripetal load
    /// turns and grows along a curve: the state at the end of the period must fit there),
    /// within the axes' limits projected on the path.
    fn period_bounds(&self, st: &GenState, pd: &Period) -> PeriodBounds {
        let t = self.period;
        let (idx, quick) = (pd.idx, pd.quick);
        let head = self.q.get(idx);
        let jm = CONTROL_SHARE * head.j_proj[quick as usize];
        let (v, a) = (st.v, st.a);
        let (a_lo0, a_hi0, j_lo, j_hi) = path_bounds(&self.lim, &head.geo_at(st.s), v, a, quick);
        let ds_pred = (v * t + 0.5 * a * t * t).max(0.0);
        let v_pred = (v + a * t).max(0.0);
        let (k1, s1) = self.locate(idx, st.s, st.at, ds_pred, pd.stop_at);
        // On the same line the bounds do not depend on the place or the speed.
        let (a_lo1, a_hi1) = if k1 == idx && matches!(head.shape, Shape::Line { .. }) {
            (a_lo0, a_hi0)
        } else {
            let geo1 = self.q.get(k1).geo_at(s1);
            accel_bounds(&self.lim, &geo1, v_pred, quick)
        };
        let (mut a_lo, mut a_hi) = (a_lo0.max(a_lo1), a_hi0.min(a_hi1));
        let a_full = CONTROL_SHARE * head.a_proj[quick as usize];
        if !(a_lo < a_hi) {
            (a_lo, a_hi) = (a_lo0, a_hi0);
        }
        if !(a_lo < a_hi) {
            (a_lo, a_hi) = (-a_full, a_full);
        }
        let (j_lo, j_hi) = if j_lo < j_hi { (j_lo, j_hi) } else { (-jm, jm) };
        let (a_lo, a_hi) = (a_lo.max(-a_full), a_hi.min(a_full));
        let (j_lo, j_hi) = (j_lo.max(-jm), j_hi.min(jm));
        PeriodBounds {
            a_lo,
            a_hi,
            j_lo,
            j_hi,
            j_min: j_lo.max((a_lo - a) / t).min(j_hi),
            a_full,
            jm,
        }
    }

    /// The speed model of this period for the stop `goal` (a hold's stop is `soft`).
    // Inlined, with `w_floor`, as they were when `control` was one function: outlined, a
    // period took about 0.7 % more instructions (bench/motion-period-cost.sh).
    #[inline(always)]
    fn speed_model(
        &self,
        st: &GenState,
        pd: &Period,
        b: &PeriodBounds,
        goal: StopGoal,
        soft: bool,
    ) -> Model {
        let head = self.q.get(pd.idx);
        let f = pd.f;
        let mut model = Model {
            t: self.period,
            v: st.v,
            a: st.a,
            at: st.at,
            idx: pd.idx,
            rem: goal.rem,
            stop_at: pd.stop_at,
            a_lo: b.a_lo,
            a_hi: b.a_hi,
            // A rollback cannot reach before the hold request, so a stricter model does not
            // help a hold's stop; it does for a stop of the path.
            a_stop: STOP_SHARE * goal.a * if soft { 1.0 } else { pd.f_stop },
            j_stop: STOP_JERK_SHARE * goal.j * if soft { 1.0 } else { pd.f_stop },
            jb: head.j_brake.min(0.8 * (-b.j_lo).max(0.1 * b.jm)) * f,
            d_nom: (0.95 * (-b.a_lo).max(0.1 * b.a_full)).min(b.a_full) * f,
            cap: f,
            quick: pd.quick,
            w_floor: 0.0,
        };
        model.w_floor = self.w_floor(&model, b.j_hi);
        model
    }

    /// The path's own model for this period when a hold's stop cannot follow from here
    /// (None while it can). The hold's gentler stop may not follow: when the path brakes
    /// harder for a slow stretch ahead than the hold's jerk can release, every jerk
    /// overshoots the hold's model. Then the path's own model decides this period (it keeps
    /// the braking curve) and the hold point moves on; the hold takes over once its stop
    /// fits.
    fn deferred_hold_model(
        &self,
        st: &GenState,
        pd: &Period,
        b: &PeriodBounds,
        hold_model: &Model,
        path: StopGoal,
    ) -> Option<Model> {
        let (v, a) = (st.v, st.a);
        let braking_harder = matches!(self.hold, Some(h) if a < -h.a);
        if !braking_harder
            || self
                .choose_jerk(hold_model, b.j_min, b.j_hi, st.j_last)
                .is_ok()
        {
            return None;
        }
        let path_model = Model {
            rem: path.rem,
            a_stop: STOP_SHARE * path.a * pd.f_stop,
            j_stop: STOP_JERK_SHARE * path.j * pd.f_stop,
            ..*hold_model
        };
        let bj = clampf(
            brake_jerk(v, a, -b.a_lo, path.j, self.period),
            b.j_lo,
            b.j_hi,
        );
        let path_can = self
            .choose_jerk(&path_model, b.j_min, b.j_hi, st.j_last)
            .is_ok()
            || [b.j_min, bj]
                .into_iter()
                .any(|c| !self.judge(&path_model, c).is_stop());
        trace!(
            self.trace,
            "HOLD DEFERRED at={} v={v} a={a} path_can={path_can}", st.at
        );
        path_can.then_some(path_model)
    }

    /// Landing: when the stop is a few periods away, the last steps are planned exactly
    /// (the smoothest sequence of steps that ends at the stop and stays there).
    fn landing(&self, st: &GenState, quick: bool, b: &PeriodBounds, goal: StopGoal) -> Landing {
        let t = self.period;
        let (v, a) = (st.v, st.a);
        let (rem, a_stop, j_stop) = (goal.rem, goal.a, goal.j);
        let (dst0, tst0) = stop(v, a, a_stop, j_stop);
        let tiny = 0.3 * if quick { self.qj_min } else { self.j_min } * t * t * t;
        let (jl, al) = if quick {
            (
                (-b.j_lo).min(b.j_hi).max(0.0),
                (-b.a_lo).min(b.a_hi).max(0.0),
            )
        } else {
            (
                j_stop.min(-b.j_lo).min(b.j_hi).max(0.0),
                a_stop.min(-b.a_lo).min(b.a_hi).max(0.0),
            )
        };
        let (js, as_) = (jl * t * t * t, al * t * t);
        // A landing in progress continues with one step fewer (the tail of the smoothest
        // sequence is the smoothest for what is left).
        let mut landing = if st.land_n >= 2 && rem >= 0.0 {
            land_steps(st.ds_hist, rem, st.land_n - 1, js, as_).map(|d| (d, st.land_n - 1))
        } else {
            None
        };
        if landing.is_none() && rem >= 0.0 && tst0 <= 5.0 * t && dst0 <= rem * 1.5 + tiny {
            let n0 = ((tst0 / t).ceil() as usize).clamp(1, LAND_MAX);
            landing = (n0..=LAND_MAX)
                .find_map(|n| land_steps(st.ds_hist, rem, n, js, as_).map(|d| (d, n)));
        }
        let step = landing.map(|(d, _)| d);
        Landing {
            step,
            n: landing.map_or(0, |(_, n)| n),
            lands: step.is_some_and(|d1| d1 == rem)
                || (v.abs() <= 1e-9 && a.abs() <= 1e-6 && rem <= tiny && rem >= 0.0),
        }
    }

    /// The step of the speed model: the constant jerk it chooses (or an emergency brake),
    /// else the stop profile followed exactly.
    fn policy_step(
        &mut self,
        st: &GenState,
        b: &PeriodBounds,
        model: &Model,
        goal: StopGoal,
        soft: bool,
        hold_at: &mut f64,
    ) -> Step {
        match self.model_jerk(st, b, model, goal) {
            Some(j) => {
                let (ds, _, _) = advance(0.0, st.v, st.a, j, self.period);
                Step {
                    ds: clampf(ds, 0.0, goal.rem.max(0.0)),
                    model_ds: ds,
                    j,
                    exact: None,
                }
            }
            None => self.stop_profile_step(st, b, model, goal, soft, hold_at),
        }
    }

    /// The largest path jerk the model accepts; when nothing passes, the hardest braking
    /// the path allows while the deceleration can still be released before the speed
    /// reaches zero (counted in `emergency_brakes`). None when even that misses the stop.
    fn model_jerk(
        &mut self,
        st: &GenState,
        b: &PeriodBounds,
        model: &Model,
        goal: StopGoal,
    ) -> Option<f64> {
        let v_min = match self.choose_jerk(model, b.j_min, b.j_hi, st.j_last) {
            Ok(j) => return Some(j),
            Err(v_min) => v_min,
        };
        self.stats.emergency_brakes += 1;
        trace!(self.trace, {
            let name = |v: Verdict| match v {
                Verdict::Safe => "safe",
                Verdict::Stop => "stop",
                Verdict::Overshoot => "overshoot",
                Verdict::Curve => "curve",
                Verdict::AccelBound => "acceleration",
            };
            eprintln!(
                "  EMERGENCY j_min={}:{} 0:{} j_hi={}:{} a_stop={} j_stop={}",
                b.j_min,
                name(self.judge(model, b.j_min)),
                name(self.judge(model, 0.0)),
                b.j_hi,
                name(self.judge(model, b.j_hi)),
                model.a_stop,
                model.j_stop
            );
        });
        let bj = clampf(
            brake_jerk(st.v, st.a, -b.a_lo, goal.j, self.period),
            b.j_lo,
            b.j_hi,
        );
        if !v_min.is_stop() {
            Some(b.j_min)
        } else if !self.judge(model, bj).is_stop() {
            Some(bj)
        } else {
            None
        }
    }

    /// No constant jerk over the period keeps the stop: the step follows the stop profile
    /// exactly (a switch of its jerk falls inside the period). The model's profile while
    /// it fits, else with the full stop capability (the model's shares are the margin); a
    /// hold point moves back to where that stop ends, so that the machine does not creep
    /// up to it after coming to rest.
    fn stop_profile_step(
        &self,
        st: &GenState,
        b: &PeriodBounds,
        model: &Model,
        goal: StopGoal,
        soft: bool,
        hold_at: &mut f64,
    ) -> Step {
        let t = self.period;
        let (v, a) = (st.v, st.a);
        let (rem, a_stop, j_stop) = (goal.rem, goal.a, goal.j);
        let mut j_used = 0.0;
        let (mut ds, mut v1, mut a1) = stop_advance(v, a, model.a_stop, model.j_stop, t);
        let fits =
            |ds: f64, v1: f64, a1: f64| ds + stop(v1, a1, model.a_stop, model.j_stop).0 <= rem;
        let releasable = !over_brakes(v, a, model.j_stop);
        // A hold's jerk is a soft choice: a deceleration that would outlast the speed under
        // it is released with the path's own jerk bound.
        let j_full = if soft && over_brakes(v, a, j_stop) {
            j_stop.max(0.99 * b.j_hi.min(b.jm))
        } else {
            j_stop
        };
        if !(releasable && fits(ds, v1, a1)) {
            (ds, v1, a1) = stop_advance(v, a, a_stop, j_full, t);
        }
        if soft {
            let end = st.at + ds + stop(v1, a1, a_stop, j_full).0;
            *hold_at = hold_at.min(end);
        }
        let full_releasable = !over_brakes(v, a, j_full);
        let full_stop_fits = full_releasable && ds + stop(v1, a1, a_stop, j_full).0 <= rem;
        if !soft && !full_stop_fits {
            // Even the full stop model overshoots, or cannot release the deceleration
            // before the speed is gone (it would come to rest short of the stop): its
            // deceleration (the lowest on the last stretch before the stop) is below what
            // the axes have here, and the state came from a model that knew better (an
            // override moved the braking curve: on a curve, a higher feed lowers the
            // deceleration the braking curve counts on). The stop follows the time-optimal
            // profile onto the stop under this period's bounds of the path, recomputed
            // every period (on an arc into a stop they grow as the speed falls); without
            // one, the axes brake as hard as the path allows. The model takes over again
            // once it fits.
            let jp = b.j_hi.min(-b.j_lo).min(b.jm);
            let overshoots = ds + stop(v1, a1, a_stop, j_full).0 > rem;
            let exact = self.exact_stop_step(v, a, (-b.a_lo).max(0.0), jp, rem);
            if let Some((ds1, v2, a2)) = exact {
                trace!(
                    self.trace,
                    "  EXACT STOP at={} v={v} a={a} rem={rem}", st.at
                );
                (ds, v1, a1) = (ds1, v2, a2);
            } else if overshoots {
                trace!(
                    self.trace,
                    "  BRAKE HARD at={} v={v} a={a} rem={rem}", st.at
                );
                let bj = clampf(brake_jerk(v, a, -b.a_lo, jp, t), b.j_lo, b.j_hi);
                j_used = bj;
                (ds, v1, a1) = advance(0.0, v, a, bj, t);
                v1 = v1.max(0.0);
            } else if !full_releasable {
                // The stop is far, but the deceleration cannot be released at the model's
                // jerk before the speed is gone: the model's profile would come to rest
                // on the way (an override left a state braking at -900 mm/s² 94 mm before
                // the stop; it stood at a dead end and left with 7 × the jerk). Release
                // it at the path's own jerk bound instead.
                let jr = b.j_hi.min(b.jm).min(-a / t).max(0.0);
                trace!(
                    self.trace,
                    "  RELEASE at={} v={v} a={a} rem={rem} j={jr}", st.at
                );
                j_used = jr;
                (ds, v1, a1) = advance(0.0, v, a, jr, t);
                v1 = v1.max(0.0);
            }
        }
        Step {
            ds: clampf(ds, 0.0, rem.max(0.0)),
            model_ds: ds,
            j: j_used,
            exact: Some((v1, a1)),
        }
    }

    /// One period of the time-optimal stop at `rem` ahead from speed `v` and acceleration
    /// `a`, within deceleration `am` and jerk `jm` (and never faster than now): the step,
    /// speed and acceleration at the end of the period. None when no such stop exists, it
    /// reverses along the path, or it takes longer than `EXACT_STOP_PERIODS`. A few
    /// microseconds (`position_profile`); taken only when the stop model has lost the state.
    fn exact_stop_step(
        &self,
        v: f64,
        a: f64,
        am: f64,
        jm: f64,
        rem: f64,
    ) -> Option<(f64, f64, f64)> {
        let t = self.period;
        if !(v > 0.0 && am > 0.0 && jm > 0.0 && rem > 0.0) {
            return None;
        }
        let limits = OtgLimits::symmetric(v * (1.0 + 1e-9), am, jm);
        let from = OtgState { p: 0.0, v, a };
        let to = OtgState {
            p: rem,
            v: 0.0,
            a: 0.0,
        };
        let profile = position_profile(from, to, &limits).ok()?;
        let duration = profile.duration();
        // The bounds are this period's: further along the path they may be lower.
        if !(duration <= EXACT_STOP_PERIODS as f64 * t) {
            return None;
        }
        let n = (duration / t).ceil() as usize;
        if !(0..=n).all(|k| profile.at(k as f64 * t).v >= -1e-9) {
            return None;
        }
        if duration <= t {
            return Some((rem, 0.0, 0.0));
        }
        let end = profile.at(t);
        Some((clampf(end.p, 0.0, rem), end.v.max(0.0), end.a))
    }

    /// The set-point of `step`, checked against every axis's finite-difference box
    /// ([`Planner::verify`]: the nearest admissible point on the path when it is outside).
    /// None at a dead end (no admissible point), unless `force`: then the nearest point,
    /// counted in `limit_violations`. `rem` and `lands` only inform the diagnostics.
    fn checked_setpoint(
        &mut self,
        st: &GenState,
        pd: &Period,
        step: &Step,
        rem: f64,
        lands: bool,
        force: bool,
    ) -> Option<(f64, AxisVec, usize, f64)> {
        let rem0 = rem.max(0.0);
        match self.verify(st, pd.idx, step.ds, rem0, pd.stop_at, pd.quick) {
            Ok(r) => Some(r),
            Err(r) if force => {
                self.stats.limit_violations += 1;
                trace!(self.trace, "VIOLATION at={} v={} a={}", st.at, st.v, st.a);
                Some(r)
            }
            Err(_) => {
                trace!(
                    self.trace,
                    "DEAD END at={} v={} a={} rem={rem} ds_t={} land={lands}",
                    st.at,
                    st.v,
                    st.a,
                    step.ds
                );
                trace!(self.trace, { self.dump_dead_end(st, pd, step.ds) });
                None
            }
        }
    }

    /// Diagnostics of a dead end: the box and the point tried.
    fn dump_dead_end(&self, st: &GenState, pd: &Period, ds_target: f64) {
        let (idx, stop_at) = (pd.idx, pd.stop_at);
        let (lo, hi) = self.fd_box(&st.hist, pd.quick);
        let (k, sl) = self.locate(idx, st.s, st.at, ds_target, stop_at);
        let x = self.q.get(k).pos(sl);
        eprintln!(
            "  hist={:?}\n  x={:?}\n  lo={:?}\n  hi={:?} ds_hist={:?} land_n={}",
            &st.hist.map(|h| [h[0], h[1], h[2]]),
            &x[..3],
            &lo[..3],
            &hi[..3],
            st.ds_hist,
            st.land_n
        );
        let hp = self.q.get(idx);
        eprintln!(
            "  idx={idx} qlen={} len={} s={} cum_start={} stop_at={stop_at} stop_end={} k={k} sl={sl}",
            self.q.len, hp.len, st.s, hp.cum_start, hp.stop_at_end
        );
    }

    /// `st` moved on to the set-point `x`, `ds` along the path at local arc length `sl` on
    /// piece `k` (speed and acceleration still `st`'s).
    fn moved_to(&self, st: &GenState, ds: f64, x: AxisVec, k: usize, sl: f64) -> GenState {
        let p = self.q.get(k);
        let mut n = *st;
        n.prof_t = None;
        n.id = self.q.head_id + k as u64;
        // The line of the move the set-point lies on (the period may have crossed into it).
        n.line = p.line;
        n.s = sl;
        n.at = p.cum_start + sl;
        n.ds_hist = [st.ds_hist[1], ds];
        n.hist = [x, st.hist[0], st.hist[1]];
        n
    }

    /// Path speed, acceleration and jerk at the end of a period that stepped `ds` from
    /// `st` (`rem0`: the way that was left to the stop).
    fn speed_after(
        &self,
        st: &GenState,
        ds: f64,
        rem0: f64,
        step: &Step,
        landing: &Landing,
        b: &PeriodBounds,
    ) -> (f64, f64, f64) {
        let t = self.period;
        let (v, a) = (st.v, st.a);
        if landing.lands && ds == rem0 {
            (0.0, 0.0, 0.0)
        } else if landing.step.is_some() {
            // Speed and acceleration of the step sequence (backward differences).
            (ds / t, (ds - st.ds_hist[1]) / (t * t), 0.0)
        } else if let (Some((v1, a1)), true) = (step.exact, ds == step.model_ds) {
            (v1, a1, 0.0)
        } else if ds == step.model_ds && step.exact.is_none() {
            let (_, v1, a1) = advance(0.0, v, a, step.j, t);
            (v1.max(0.0), a1, step.j)
        } else {
            // The set-point check chose another point: the state is the constant-jerk step
            // that reaches it (within twice the jerk bound, so that a far move cannot throw
            // the state off), and the model continues from where the axes are. Except where
            // the reconstruction swings: right after another moved point, with a step that
            // needs more than the path's jerk bound and reverses the last step's jerk. Then
            // the state is the cubic through the last four set-points along the path (exact
            // on a constant-jerk stretch). The constant-jerk step from a state that itself
            // reached a moved point carries that state's error on, 3.7 × per period with
            // alternating sign: where the check binds period after period (braking at an
            // axis's acceleration limit on an arc after an override), the state's
            // acceleration swung ±2 jerk steps around the axes', and the policy, braking
            // for a state that was not the axes', brought the machine to rest 169 mm
            // before its stop. (The cubic lags a jerk change by two thirds of a jerk step:
            // after every moved point it made curves of the benchmark families up to 3.7 %
            // slower; without the reversal condition the bracket at 100 µs took 12.6 ms
            // more than at 250 µs.)
            let j_step = 6.0 * (ds - v * t - 0.5 * a * t * t) / (t * t * t);
            if !st.adjusted || j_step.abs() <= b.jm || j_step * st.j_last >= 0.0 {
                let j_eff = clampf(j_step, -2.0 * b.jm, 2.0 * b.jm);
                let (_, v1, a1) = advance(0.0, v, a, j_eff, t);
                return (v1.max(0.0), a1, clampf(j_eff, b.j_lo, b.j_hi));
            }
            let (d2, d1, d0) = (st.ds_hist[0], st.ds_hist[1], ds);
            let v1 = (11.0 * d0 - 7.0 * d1 + 2.0 * d2) / (6.0 * t);
            let a1 = (2.0 * d0 - 3.0 * d1 + d2) / (t * t);
            let j1 = (d0 - 2.0 * d1 + d2) / (t * t * t);
            (v1.max(0.0), a1, clampf(j1, b.j_lo, b.j_hi))
        }
    }

    /// The largest path jerk in [`j_min`, `j_hi`] the model accepts. Tried first: the jerk
    /// that brings the acceleration to its bound (anything above fails the model's first
    /// test), then the jerk that brings the speed onto the braking curve at the end of the
    /// period (the test that binds while the path runs at its limit), taken when it passes
    /// and one [`JERK_RESOLUTION`] above it fails; else a bisection warm-started next to
    /// the last period's jerk. Err when even `j_min` fails, with its verdict.
    fn choose_jerk(&self, m: &Model, j_min: f64, j_hi: f64, j_last: f64) -> Result<f64, Verdict> {
        let safe = |j: f64| self.judge(m, j) == Verdict::Safe;
        // The jerk that brings the acceleration to its bound (any above fails the model).
        let top = clampf((m.a_hi.max(0.0) - m.a) / m.t, j_min, j_hi);
        match self.judge(m, top) {
            Verdict::Safe => return Ok(top),
            // Nothing from `j_min` on passes.
            Verdict::AccelBound if top == j_min => return Err(Verdict::AccelBound),
            _ => {}
        }
        let tol = JERK_RESOLUTION * (j_hi - j_min);
        if let Some(g) = self.curve_jerk(m, clampf(j_last, j_min, top))
            && g > j_min
            && g < top
            && safe(g)
            && (g + tol >= top || !safe(g + tol))
        {
            return Ok(g);
        }
        let step = 0.02 * (j_hi - j_min).max(0.0);
        let j_prev = clampf(j_last, j_min, top);
        let (mut lo, mut hi, iters) = if safe(j_prev) {
            let up = (j_prev + step).min(top);
            if step > 0.0 && !safe(up) {
                (j_prev, up, 5)
            } else {
                (up, top, 9)
            }
        } else {
            match self.judge(m, j_min) {
                Verdict::Safe => (j_min, j_prev, 9),
                // Every larger jerk overshoots too.
                Verdict::Overshoot => return Err(Verdict::Overshoot),
                v_min => {
                    // The hardest braking fails too: braking must be released before the
                    // speed reaches zero, so the admissible jerks start above `j_min`. The
                    // fastest stop's jerk is the lowest of them; else the largest safe
                    // point of a coarse grid.
                    let bj = clampf(brake_jerk(m.v, m.a, m.a_stop, m.j_stop, m.t), j_min, j_hi);
                    let lo = if safe(bj) {
                        bj
                    } else {
                        let n = 8;
                        let grid = (1..n)
                            .rev()
                            .map(|k| j_min + (j_hi - j_min) * k as f64 / n as f64);
                        match grid.into_iter().find(|j| safe(*j)) {
                            Some(j) => j,
                            None => return Err(v_min),
                        }
                    };
                    (lo, j_hi, 9)
                }
            }
        };
        for _ in 0..iters {
            let mid = 0.5 * (lo + hi);
            if safe(mid) {
                lo = mid;
            } else {
                hi = mid;
            }
        }
        Ok(lo)
    }

    /// The jerk that brings the speed onto the braking curve at the end of the period (the
    /// curve linearised along its slope around the point jerk `j0` reaches); None where
    /// the curve is zero there.
    fn curve_jerk(&self, m: &Model, j0: f64) -> Option<f64> {
        let t = m.t;
        let (ds0, _, _) = advance(0.0, m.v, m.a, j0, t);
        let (w, slope) = self.w_abs(m.idx, m.at + ds0, m.stop_at);
        if !(w > 0.0) {
            return None;
        }
        // v + a t + j t²/2 = cap (w - slope/w (j - j0) t³/6)
        let k = m.cap * slope / w * t * t * t / 6.0;
        let j = (m.cap * w + k * j0 - m.v - m.a * t) / (0.5 * t * t + k);
        j.is_finite().then_some(j)
    }

    /// Box of the next set-point per axis: every finite difference with the last three
    /// set-points within the axis's v·T, a·T², j·T³ (shrunk by 1e-10 relative and the
    /// rounding of the differences).
    fn fd_box(&self, hist: &[AxisVec; 3], quick: bool) -> (AxisVec, AxisVec) {
        let (p0, p1, p2) = (&hist[0], &hist[1], &hist[2]);
        let steps = &self.steps;
        let q = quick as usize;
        // Axes without limits stay where they are.
        let (mut lo, mut hi) = (*p0, *p0);
        let mut m = steps.present;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let round = 16.0 * f64::EPSILON * (p0[i].abs() + p1[i].abs() + p2[i].abs() + 1.0);
            let rv = steps.v[i] - round;
            let ra = steps.a[q][i] - round;
            let rj = steps.j[q][i] - round;
            let cv = p0[i];
            let ca = 2.0 * p0[i] - p1[i];
            let cj = 3.0 * p0[i] - 3.0 * p1[i] + p2[i];
            lo[i] = (cv - rv).max(ca - ra).max(cj - rj);
            hi[i] = (cv + rv).min(ca + ra).min(cj + rj);
        }
        (lo, hi)
    }

    /// The set-point `ds0` ahead of `st`, or the nearest point on the path inside the box
    /// (linearised steps along the tangent). Err carries the last point tried (outside).
    #[allow(clippy::type_complexity)]
    fn verify(
        &self,
        st: &GenState,
        idx: usize,
        ds0: f64,
        rem: f64,
        stop_at: f64,
        quick: bool,
    ) -> Result<(f64, AxisVec, usize, f64), (f64, AxisVec, usize, f64)> {
        let (lo, hi) = self.fd_box(&st.hist, quick);
        let mut ds = ds0;
        for _ in 0..6 {
            let (k, sl) = self.locate(idx, st.s, st.at, ds, stop_at);
            let piece = self.q.get(k);
            let x = piece.pos(sl);
            if inside(&self.lim, &x, &lo, &hi) {
                return Ok((ds, x, k, sl));
            }
            let (_, tan) = piece.pos_tangent(sl);
            let (mut dlo, mut dhi) = (-ds, rem - ds);
            for i in 0..AXES {
                if !self.lim.present[i] {
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
        let (k, sl) = self.locate(idx, st.s, st.at, ds, stop_at);
        let x = self.q.get(k).pos(sl);
        if inside(&self.lim, &x, &lo, &hi) {
            Ok((ds, x, k, sl))
        } else {
            Err((ds, x, k, sl))
        }
    }
}

/// Largest set-point steps per axis (first, second and third differences at the servo
/// period, from the velocity, acceleration and jerk limits, normal and quick-stop, shrunk
/// by 1e-10 relative), computed once for [`Planner::fd_box`].
#[derive(Debug, Clone, Copy)]
pub(super) struct StepLimits {
    /// Axes with limits, one bit each.
    present: u16,
    v: AxisVec,
    a: [AxisVec; 2],
    j: [AxisVec; 2],
}

impl StepLimits {
    pub(super) fn new(lim: &Lim, t: f64) -> StepLimits {
        let shrink = 1.0 - 1e-10;
        let mut sl = StepLimits {
            present: 0,
            v: [0.0; AXES],
            a: [[0.0; AXES]; 2],
            j: [[0.0; AXES]; 2],
        };
        for i in 0..AXES {
            if !lim.present[i] {
                continue;
            }
            sl.present |= 1 << i;
            sl.v[i] = lim.v[i] * t * shrink;
            for (q, (am, jm)) in [(lim.a[i], lim.j[i]), (lim.qa[i], lim.qj[i])]
                .into_iter()
                .enumerate()
            {
                sl.a[q][i] = am * t * t * shrink;
                sl.j[q][i] = jm * t * t * t * shrink;
            }
        }
        sl
    }
}

/// Bounds of the path acceleration and jerk where the path has tangent, curvature vector
/// and its derivative `geo`, at speed `v` and acceleration `a`, from every axis: |T a + K v²| ≤ A and |T j + 3 K v a + K' v³| ≤ J, with
/// the 3·K·v·a term kept within half of what the curvature change leaves (so that the
/// acceleration can always be ramped back with the other half). Infinite where no axis
/// bounds it.
fn path_bounds(
    lim: &Lim,
    geo: &(AxisVec, AxisVec, AxisVec),
    v: f64,
    a: f64,
    quick: bool,
) -> (f64, f64, f64, f64) {
    bounds::<true>(lim, geo, v, a, quick)
}

/// The acceleration bounds of [`path_bounds`] alone (the same numbers, without the jerk's).
fn accel_bounds(lim: &Lim, geo: &(AxisVec, AxisVec, AxisVec), v: f64, quick: bool) -> (f64, f64) {
    let (a_lo, a_hi, _, _) = bounds::<false>(lim, geo, v, 0.0, quick);
    (a_lo, a_hi)
}

#[inline]
fn bounds<const JERK: bool>(
    lim: &Lim,
    geo: &(AxisVec, AxisVec, AxisVec),
    v: f64,
    a: f64,
    quick: bool,
) -> (f64, f64, f64, f64) {
    let (tan, kv, kp) = geo;
    let (mut a_lo, mut a_hi) = (f64::NEG_INFINITY, f64::INFINITY);
    let (mut j_lo, mut j_hi) = (f64::NEG_INFINITY, f64::INFINITY);
    for i in 0..AXES {
        if !lim.present[i] || tan[i].abs() < 1e-9 {
            continue;
        }
        let (am, jmx) = if quick {
            (lim.qa[i], lim.qj[i])
        } else {
            (lim.a[i], lim.j[i])
        };
        let (am, jmx) = (CONTROL_SHARE * am, CONTROL_SHARE * jmx);
        let ca = kv[i] * v * v;
        let (x0, x1) = ((-am - ca) / tan[i], (am - ca) / tan[i]);
        a_lo = a_lo.max(x0.min(x1));
        a_hi = a_hi.min(x0.max(x1));
        let k3v = 3.0 * kv[i].abs() * v;
        if k3v > 0.0 {
            let room = (jmx - (kp[i] * v * v * v).abs()).max(0.0);
            let a_cap = 0.5 * room / k3v;
            a_lo = a_lo.max(-a_cap);
            a_hi = a_hi.min(a_cap);
        }
        if JERK {
            let cj = 3.0 * kv[i] * v * a + kp[i] * v * v * v;
            let (y0, y1) = ((-jmx - cj) / tan[i], (jmx - cj) / tan[i]);
            j_lo = j_lo.max(y0.min(y1));
            j_hi = j_hi.min(y0.max(y1));
        }
    }
    (a_lo, a_hi, j_lo, j_hi)
}

/// `x` inside the box on every present axis.
#[inline]
fn inside(lim: &Lim, x: &AxisVec, lo: &AxisVec, hi: &AxisVec) -> bool {
    (0..AXES).all(|i| !lim.present[i] || (x[i] >= lo[i] && x[i] <= hi[i]))
}

/// A period at rest: the set-point repeats.
fn still(mut st: GenState) -> GenState {
    st.adjusted = false;
    st.hist = [st.hist[0], st.hist[0], st.hist[1]];
    st.ds_hist = [st.ds_hist[1], 0.0];
    st
}

/// Distance of the stop from speed `v` and acceleration `a` with the stop model's
/// deceleration `am` and jerk `jm`; a deceleration that model's jerk cannot release before
/// the speed is gone is first released with the path's braking jerk `jb` (when larger),
/// and the model's stop follows from the speed left. None when neither releases it.
///
/// The stop model's jerk is the lowest on the stop's own low-speed stretch (a 0.5 mm arc's
/// there), not what the path allows on the way: braking for a slow stretch far before the
/// stop, at the deceleration the braking curve asks for, is released as the braking curve
/// assumes, with the braking jerk. Refusing such decelerations made the policy follow the
/// model's stop profile instead of the curve, and the path met the slow stretch too fast.
fn release_and_stop(v: f64, a: f64, am: f64, jm: f64, jb: f64) -> Option<f64> {
    let releasable = |j: f64| !(a < 0.0 && a * a > 2.0 * j * v * (1.0 + 1e-9) + 1e-12);
    if releasable(jm) {
        return Some(stop(v, a, am, jm).0);
    }
    if !(jb > jm && releasable(jb)) {
        return None;
    }
    let tr = -a / jb;
    let (dr, vr, _) = advance(0.0, v, a, jb, tr);
    Some(dr.max(0.0) + stop(vr.max(0.0), 0.0, am, jm).0)
}
