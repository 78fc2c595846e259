//! Position interface, step one: the time-optimal profile from any state to a target
//! state, and the durations this axis cannot take (for synchronisation).
//!
//! After an optional brake pre-trajectory, the time-optimal profile has at most seven
//! phases with the jerk pattern `+j 0 -j 0 -j 0 +j` ("up-down-down-up", or its mirror
//! image for a downward move): a jerk ramp up, a hold at the acceleration limit, a ramp
//! down, a cruise at the velocity limit, a ramp down, a hold at the lower acceleration
//! limit and a ramp back. Which holds exist depends on which limits are reached, giving
//! the families solved below:
//!
//! | family | limits reached | unknowns | solved by |
//! |---|---|---|---|
//! | cruise | velocity (and maybe one or both accelerations) | none | closed form |
//! | `ACC0_ACC1` | both accelerations, not the velocity | hold times | quadratic |
//! | `ACC0` | upper acceleration only | ramp time | quartic |
//! | `ACC1` | lower acceleration only | ramp time | quartic |
//! | `NONE` | no limit | ramp time | quartic |
//!
//! The polynomial coefficients below come from `derive_polynomials.py` (sympy) next to this
//! file. Every family is solved for both directions; every root becomes a candidate that
//! [`check`] validates (durations, limits, target). The shortest valid candidate is the
//! time-optimal profile; the others bound the blocked duration intervals.

use super::brake::{Brake, position_brake};
use super::check::{Bounds, Problem, check};
use super::limits::{Which, check_target};
use super::profile::{Phase, Profile, travel};
use super::roots::real_roots_in;
use super::{Limits, OtgError, State};

/// Jerk signs of the seven phases of an upward time-optimal profile.
const UP_DOWN_DOWN_UP: [f64; 7] = [1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0];

/// Valid candidates kept. Only valid profiles are kept, and there are at most five distinct
/// ones (plus the same profile found by two neighbouring families); when full, a new one
/// replaces the longest if it is shorter.
const MAX_CANDIDATES: usize = 12;

/// One valid seven-phase profile (jerks signed for the real direction).
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Candidate {
    pub(crate) phases: [Phase; 7],
    pub(crate) duration: f64,
}

#[derive(Debug, Clone, Copy)]
struct Candidates {
    items: [Candidate; MAX_CANDIDATES],
    len: usize,
}

impl Candidates {
    fn new() -> Self {
        Self {
            items: [Candidate::default(); MAX_CANDIDATES],
            len: 0,
        }
    }

    /// Validates `t` as an up-down-down-up profile in the frame of `bounds` and keeps it.
    fn try_push(&mut self, problem: &Problem, bounds: &Bounds, sign: f64, mut t: [f64; 7]) {
        // A single `-j` ramp through zero acceleration is two phases of the seven-phase
        // pattern: split it where the cruise would sit, so phases read like ruckig's.
        if t[3] == 0.0 && t[4] == 0.0 {
            let a_top = problem.a0 + bounds.j * t[0];
            let a_bottom = a_top - bounds.j * t[2];
            if a_top > 0.0 && a_bottom < 0.0 {
                t[2] = a_top / bounds.j;
                t[4] = -a_bottom / bounds.j;
            }
        }
        let mut phases = [Phase::default(); 7];
        for (i, phase) in phases.iter_mut().enumerate() {
            *phase = Phase {
                duration: t[i],
                jerk: UP_DOWN_DOWN_UP[i] * bounds.j,
            };
        }
        if let Some(duration) = check(problem, bounds, &mut phases, true, 2) {
            for phase in &mut phases {
                phase.jerk *= sign;
            }
            let candidate = Candidate { phases, duration };
            if self.len < MAX_CANDIDATES {
                self.items[self.len] = candidate;
                self.len += 1;
            } else if let Some(longest) = self
                .items
                .iter_mut()
                .max_by(|x, y| x.duration.total_cmp(&y.duration))
                .filter(|c| c.duration > duration)
            {
                *longest = candidate;
            }
        }
    }
}

/// Durations an axis can take: `[t_min, ∞)` minus up to two open intervals.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Block {
    /// Minimum duration (brake pre-trajectory included).
    pub t_min: f64,
    /// Open intervals of durations no profile of this axis can take, `(left, right)`.
    pub blocked: [Option<(f64, f64)>; 2],
}

impl Block {
    /// Whether a profile of duration `t` exists for this axis.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_blocked(&self, t: f64) -> bool {
        t < self.t_min || self.blocked.iter().flatten().any(|&(l, r)| l < t && t < r)
    }
}

/// Result of step one for one axis.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Step1 {
    pub(crate) start: State,
    pub(crate) target: State,
    pub(crate) brake: Brake,
    pub(crate) best: Candidate,
    pub(crate) block: Block,
    /// The distinct valid profiles, shortest first: they bound the blocked intervals.
    pub(crate) extremal: [Candidate; 5],
    pub(crate) extremal_len: usize,
}

impl Step1 {
    pub(crate) fn brake_duration(&self) -> f64 {
        self.brake.phases.iter().map(|p| p.duration).sum()
    }

    /// State after the brake pre-trajectory.
    pub(crate) fn after_brake(&self) -> State {
        travel(self.start, &self.brake.phases)
    }

    pub(crate) fn extremal(&self) -> &[Candidate] {
        &self.extremal[..self.extremal_len]
    }

    /// Builds the full profile (brake + main phases) for a main part.
    pub(crate) fn profile_with(&self, main: &[Phase]) -> Profile {
        let mut all = [Phase::default(); 9];
        all[0] = self.brake.phases[0];
        all[1] = self.brake.phases[1];
        for (slot, phase) in all[2..].iter_mut().zip(main) {
            *slot = *phase;
        }
        Profile::from_phases(
            self.start,
            &all[..2 + main.len().min(7)],
            2,
            Some(self.target),
        )
    }

    pub(crate) fn profile(&self) -> Profile {
        self.profile_with(&self.best.phases)
    }
}

/// Time-optimal jerk-limited profile from `start` to `target` (position, velocity and
/// acceleration) within `limits`, like ruckig's position interface.
///
/// The start state may break the limits (a brake pre-trajectory brings it back first); the
/// target must lie inside them. Cost: all families in both directions, i.e. a handful of
/// quartic root isolations, a few microseconds; no allocation, bounded loops.
///
/// Real-time: yes (no allocation, no blocking).
pub fn position_profile(start: State, target: State, limits: &Limits) -> Result<Profile, OtgError> {
    Ok(solve_position(start, target, limits)?.profile())
}

/// The path planner's one-dimensional problem: along a path of `length`, from speed `v0`
/// and acceleration `a0` at `s = 0` to speed `v1` with zero acceleration at `s = length`,
/// time-optimally within `limits` (the velocity, acceleration and jerk limits projected onto
/// the path).
///
/// This is the general position interface with start `(0, v0, a0)` and target
/// `(length, v1, 0)`, so its cost is the same: every profile family in both directions,
/// about a microsecond (see the `otg` benchmark), no allocation. When `v0` is too high to
/// arrive at `v1` within `length`, the time-optimal profile overshoots and comes back;
/// [`Profile::position_extrema`] tells, and a planner should lower `v0` instead.
///
/// Real-time: yes (no allocation, no blocking).
pub fn along_path(
    length: f64,
    v0: f64,
    a0: f64,
    v1: f64,
    limits: &Limits,
) -> Result<Profile, OtgError> {
    position_profile(State::new(0.0, v0, a0), State::new(length, v1, 0.0), limits)
}

/// Minimum duration and blocked duration intervals of a move (what multi-axis
/// synchronisation needs), without building the profile.
///
/// Real-time: yes (no allocation, no blocking).
pub fn position_block(start: State, target: State, limits: &Limits) -> Result<Block, OtgError> {
    Ok(solve_position(start, target, limits)?.block)
}

pub(crate) fn validate(start: State, target: State, limits: &Limits) -> Result<(), OtgError> {
    limits.validate()?;
    start.check_finite(Which::Start)?;
    target.check_finite(Which::Target)?;
    check_target(target.v, target.a, limits)
}

pub(crate) fn solve_position(
    start: State,
    target: State,
    limits: &Limits,
) -> Result<Step1, OtgError> {
    validate(start, target, limits)?;
    let brake = position_brake(start.v, start.a, limits);
    let after = travel(start, &brake.phases);
    let problem = Problem {
        v0: after.v,
        a0: after.a,
        pd: target.p - after.p,
        vf: target.v,
        af: target.a,
    };
    let bounds = Bounds {
        v_max: limits.max_velocity,
        v_min: limits.min_velocity,
        a_max: limits.max_acceleration,
        a_min: limits.min_acceleration,
        j: limits.max_jerk,
    };
    let mut candidates = Candidates::new();
    if problem.pd == 0.0 && problem.v0 == problem.vf && problem.a0 == problem.af {
        candidates.items[0] = Candidate::default();
        candidates.len = 1;
    } else if problem.vf == 0.0 && problem.af == 0.0 {
        // Arriving at rest, the valid profile is unique and no duration is blocked (as in
        // ruckig): stop at the first one, trying the direction of the move first.
        let (first, second) = if problem.pd >= 0.0 {
            (1.0, -1.0)
        } else {
            (-1.0, 1.0)
        };
        for sign in [first, second] {
            let (pr, b) = oriented(&problem, &bounds, sign);
            if solve_oriented(&pr, &b, sign, &mut candidates, true) {
                break;
            }
        }
    } else {
        for sign in [1.0, -1.0] {
            let (pr, b) = oriented(&problem, &bounds, sign);
            solve_oriented(&pr, &b, sign, &mut candidates, false);
        }
    }
    let brake_duration: f64 = brake.phases.iter().map(|p| p.duration).sum();
    let items = &mut candidates.items[..candidates.len];
    items.sort_by(|x, y| x.duration.total_cmp(&y.duration));
    // The same profile may be found by two neighbouring families: keep one.
    let mut distinct = [Candidate::default(); 5];
    let mut n = 0;
    for c in items.iter() {
        let duplicate = n > 0 && {
            let last: &Candidate = &distinct[n - 1];
            (c.duration - last.duration).abs() <= 1e-9 * c.duration.max(1e-300)
        };
        if !duplicate && n < distinct.len() {
            distinct[n] = *c;
            n += 1;
        }
    }
    let best = *distinct
        .first()
        .filter(|_| n > 0)
        .ok_or(OtgError::NoProfileFound {
            distance: target.p - start.p,
        })?;
    let d = |i: usize| distinct[i].duration + brake_duration;
    let blocked = match n {
        1 => [None, None],
        3 => [Some((d(1), d(2))), None],
        5 => [Some((d(1), d(2))), Some((d(3), d(4)))],
        // An even count only happens when a boundary profile was lost to rounding: block
        // everything between the fastest and the slowest one, which is conservative.
        _ => [Some((d(0), d(n - 1))), None],
    };
    Ok(Step1 {
        start,
        target,
        brake,
        best,
        block: Block {
            t_min: best.duration + brake_duration,
            blocked,
        },
        extremal: distinct,
        extremal_len: n,
    })
}

/// The problem seen in the frame where the profile starts with `+j` (`sign` -1 mirrors it).
fn oriented(problem: &Problem, bounds: &Bounds, sign: f64) -> (Problem, Bounds) {
    if sign > 0.0 {
        (*problem, *bounds)
    } else {
        (problem.mirrored(), bounds.mirrored())
    }
}

type Family = fn(&Problem, &Bounds, f64, &mut Candidates);

/// Tries every candidate family in the frame where the profile starts with `+j`; with
/// `first_only`, stops at the first valid profile. Returns whether any was found.
fn solve_oriented(
    problem: &Problem,
    bounds: &Bounds,
    sign: f64,
    out: &mut Candidates,
    first_only: bool,
) -> bool {
    let before = out.len;
    // Cheapest first: closed form, quadratic, then the quartics.
    let families: [Family; 5] = [
        cruise_family,
        both_accelerations_family,
        no_limit_family,
        upper_acceleration_family,
        lower_acceleration_family,
    ];
    for family in families {
        family(problem, bounds, sign, out);
        if first_only && out.len > before {
            return true;
        }
    }
    out.len > before
}

/// Velocity limit reached: up-pulse to `v_max`, cruise, down-pulse to the target.
fn cruise_family(pr: &Problem, b: &Bounds, sign: f64, out: &mut Candidates) {
    let (j, v_max) = (b.j, b.v_max);
    let rise = j * (v_max - pr.v0) + 0.5 * pr.a0 * pr.a0;
    let fall = j * (v_max - pr.vf) + 0.5 * pr.af * pr.af;
    if rise < 0.0 || fall < 0.0 {
        return;
    }
    let mut peak = rise.sqrt();
    let mut hold0 = 0.0;
    if peak > b.a_max {
        peak = b.a_max;
        hold0 = ((v_max - pr.v0) - (2.0 * b.a_max * b.a_max - pr.a0 * pr.a0) / (2.0 * j)) / b.a_max;
    }
    let mut trough = -fall.sqrt();
    let mut hold1 = 0.0;
    if trough < b.a_min {
        trough = b.a_min;
        hold1 =
            ((v_max - pr.vf) - (2.0 * b.a_min * b.a_min - pr.af * pr.af) / (2.0 * j)) / -b.a_min;
    }
    let mut t = [
        (peak - pr.a0) / j,
        hold0,
        peak / j,
        0.0,
        -trough / j,
        hold1,
        (pr.af - trough) / j,
    ];
    let phase = |i: usize| Phase {
        duration: t[i],
        jerk: UP_DOWN_DOWN_UP[i] * j,
    };
    let rise = travel(
        State::new(0.0, pr.v0, pr.a0),
        &[phase(0), phase(1), phase(2)],
    );
    let fall = travel(State::new(0.0, v_max, 0.0), &[phase(4), phase(5), phase(6)]);
    t[3] = (pr.pd - rise.p - fall.p) / v_max;
    out.try_push(pr, b, sign, t);
}

/// `K = 2 j (vf - v0) + a0² - af²`: twice `j` times the velocity change the acceleration
/// ramps must produce, corrected for the start and end accelerations.
fn k_term(pr: &Problem, j: f64) -> f64 {
    2.0 * j * (pr.vf - pr.v0) + pr.a0 * pr.a0 - pr.af * pr.af
}

/// Both acceleration limits reached, no cruise: unknown hold times, a quadratic.
fn both_accelerations_family(pr: &Problem, b: &Bounds, sign: f64, out: &mut Candidates) {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let (j, a_max, a_min) = (b.j, b.a_max, b.a_min);
    let k = k_term(pr, j);
    let c = (k - 2.0 * a_max * a_max + 2.0 * a_min * a_min) / (2.0 * j);
    // Coefficients derived symbolically (position equation in the first hold time `h`).
    let c1 = (-a0.powi(2) + 2.0 * a_max.powi(2) - a_max * a_min + 2.0 * j * v0) / (a_max * j);
    let c0 = (3.0 * a0.powi(4) - 8.0 * a0.powi(3) * a_min - 12.0 * a0.powi(2) * a_max.powi(2)
        + 24.0 * a0.powi(2) * a_max * a_min
        - 6.0 * a0.powi(2) * a_min.powi(2)
        - 12.0 * a0.powi(2) * j * v0
        + 24.0 * a0 * a_min * j * v0
        + 12.0 * a_max.powi(4)
        - 24.0 * a_max.powi(3) * a_min
        + 12.0 * a_max.powi(2) * a_min.powi(2)
        + 24.0 * a_max.powi(2) * j * v0
        - 48.0 * a_max * a_min * j * v0
        - 6.0 * a_min.powi(2) * af.powi(2)
        + 12.0 * a_min.powi(2) * j * v0
        + 12.0 * a_min.powi(2) * j * vf
        + 8.0 * a_min * af.powi(3)
        - 24.0 * a_min * af * j * vf
        + 24.0 * a_min * j.powi(2) * pd
        - 3.0 * af.powi(4)
        + 12.0 * af.powi(2) * j * vf
        + 12.0 * j.powi(2) * v0.powi(2)
        - 12.0 * j.powi(2) * vf.powi(2))
        / (12.0 * a_max.powi(2) * j.powi(2) - 12.0 * a_max * a_min * j.powi(2));
    let roots = real_roots_in(&[1.0, c1, c0], f64::MIN, f64::MAX);
    for &h in roots.as_slice() {
        let h1 = (c - a_max * h) / a_min;
        let t = [
            (a_max - a0) / j,
            h,
            a_max / j,
            0.0,
            -a_min / j,
            h1,
            (af - a_min) / j,
        ];
        out.try_push(pr, b, sign, t);
    }
}

/// Interval of a ramp-time unknown, widened a little so that a root sitting on a family
/// boundary is not lost to rounding (the check clamps the tiny negative durations).
fn widened(lo: f64, hi: f64) -> (f64, f64) {
    let pad = 1e-9 * hi.abs().max(lo.abs());
    (lo - pad, hi + pad)
}

/// Upper acceleration limit reached, no cruise: unknown `t` = length of the `-j` ramp.
fn upper_acceleration_family(pr: &Problem, b: &Bounds, sign: f64, out: &mut Candidates) {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let (j, a_max) = (b.j, b.a_max);
    let k = k_term(pr, j);
    let c3 = -2.0 * a_max / j;
    let c2 = (a_max.powi(2) - af.powi(2) + 2.0 * j * vf) / j.powi(2);
    let c0 = (-3.0 * a0.powi(4) + 8.0 * a0.powi(3) * a_max - 6.0 * a0.powi(2) * a_max.powi(2)
        + 12.0 * a0.powi(2) * j * v0
        - 24.0 * a0 * a_max * j * v0
        + 6.0 * a_max.powi(2) * af.powi(2)
        + 12.0 * a_max.powi(2) * j * v0
        - 12.0 * a_max.powi(2) * j * vf
        - 8.0 * a_max * af.powi(3)
        + 24.0 * a_max * af * j * vf
        - 24.0 * a_max * j.powi(2) * pd
        + 3.0 * af.powi(4)
        - 12.0 * af.powi(2) * j * vf
        - 12.0 * j.powi(2) * v0.powi(2)
        + 12.0 * j.powi(2) * vf.powi(2))
        / (12.0 * j.powi(4));
    let (lo, hi) = widened(((a_max - af) / j).max(0.0), (a_max - b.a_min) / j);
    let roots = real_roots_in(&[1.0, c3, c2, 0.0, c0], lo, hi);
    for &t in roots.as_slice() {
        let a3 = a_max - j * t;
        let hold = (k - 2.0 * a_max * a_max + 2.0 * a3 * a3) / (2.0 * j * a_max);
        let times = [(a_max - a0) / j, hold, t, 0.0, 0.0, 0.0, (af - a3) / j];
        out.try_push(pr, b, sign, times);
    }
}

/// Lower acceleration limit reached, no cruise: unknown `t` = length of the first ramp.
fn lower_acceleration_family(pr: &Problem, b: &Bounds, sign: f64, out: &mut Candidates) {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let (j, a_min) = (b.j, b.a_min);
    let k = k_term(pr, j);
    let c3 = (4.0 * a0 - 2.0 * a_min) / j;
    let c2 = (5.0 * a0.powi(2) - 6.0 * a0 * a_min + a_min.powi(2) + 2.0 * j * v0) / j.powi(2);
    let c1 = (2.0 * a0.powi(3) - 4.0 * a0.powi(2) * a_min
        + 2.0 * a0 * a_min.powi(2)
        + 4.0 * a0 * j * v0
        - 4.0 * a_min * j * v0)
        / j.powi(3);
    let c0 = (3.0 * a0.powi(4) - 8.0 * a0.powi(3) * a_min
        + 6.0 * a0.powi(2) * a_min.powi(2)
        + 12.0 * a0.powi(2) * j * v0
        - 24.0 * a0 * a_min * j * v0
        - 6.0 * a_min.powi(2) * af.powi(2)
        + 12.0 * a_min.powi(2) * j * v0
        + 12.0 * a_min.powi(2) * j * vf
        + 8.0 * a_min * af.powi(3)
        - 24.0 * a_min * af * j * vf
        + 24.0 * a_min * j.powi(2) * pd
        - 3.0 * af.powi(4)
        + 12.0 * af.powi(2) * j * vf
        + 12.0 * j.powi(2) * v0.powi(2)
        - 12.0 * j.powi(2) * vf.powi(2))
        / (12.0 * j.powi(4));
    let (lo, hi) = widened(((a_min - a0) / j).max(0.0), (b.a_max - a0) / j);
    let roots = real_roots_in(&[1.0, c3, c2, c1, c0], lo, hi);
    for &t in roots.as_slice() {
        let a1 = a0 + j * t;
        let hold = (k - 2.0 * a1 * a1 + 2.0 * a_min * a_min) / (2.0 * j * a_min);
        let times = [t, 0.0, (a1 - a_min) / j, 0.0, 0.0, hold, (af - a_min) / j];
        out.try_push(pr, b, sign, times);
    }
}

/// No limit reached: three jerk ramps, unknown `t` = length of the `-j` ramp.
fn no_limit_family(pr: &Problem, b: &Bounds, sign: f64, out: &mut Candidates) {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let j = b.j;
    let k = k_term(pr, j);
    let c2 = (-2.0 * a0.powi(2) - 2.0 * af.powi(2) + 4.0 * j * v0 + 4.0 * j * vf) / j.powi(2);
    let c1 = (4.0 * a0.powi(3) - 12.0 * a0 * j * v0 - 4.0 * af.powi(3) + 12.0 * af * j * vf
        - 12.0 * j.powi(2) * pd)
        / (3.0 * j.powi(3));
    let c0 = -(k * k) / (4.0 * j.powi(4));
    let (lo, hi) = widened(((a0 - af) / j).max(0.0), (b.a_max - b.a_min) / j);
    let roots = real_roots_in(&[1.0, 0.0, c2, c1, c0], lo, hi);
    for &t in roots.as_slice() {
        if t <= 0.0 {
            continue;
        }
        let a1 = 0.5 * (j * t + k / (2.0 * j * t));
        let a3 = a1 - j * t;
        let times = [(a1 - a0) / j, 0.0, t, 0.0, 0.0, 0.0, (af - a3) / j];
        out.try_push(pr, b, sign, times);
    }
}
