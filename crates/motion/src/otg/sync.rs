//! Profiles of a prescribed duration (position interface, step two) and the time
//! synchronisation of several axes: all axes start together and reach their targets at the
//! same instant, the earliest instant every axis can make.
//!
//! The common duration is the smallest duration at least every axis's minimum that no axis
//! has blocked (step one reports each axis's blocked intervals, as in ruckig). Each axis then
//! needs a profile of exactly that duration:
//! 1. the axis's own extremal profile, if the duration is one of them;
//! 2. a "cruise" profile: the time-optimal velocity change to a cruise velocity `vc`, a
//!    cruise at `vc` and the time-optimal velocity change to the target, `vc` solved so that
//!    the distance comes out right (covers every long enough duration);
//! 3. profiles that never pass zero acceleration: two same-direction acceleration pulses,
//!    or up-down-up with a hold at a peak or trough acceleration below the limits (each
//!    searched over one acceleration, both directions).
//!
//! If none of these has a profile of the exact duration, the common duration is lengthened
//! step by step until every axis has one: conservative (slower than ruckig), never wrong,
//! since every profile is validated against the limits and the target before it is used.
//! On 12 600 random three-axis cases against ruckig this fallback was never needed.

use super::check::{Bounds, Problem, check};
use super::position::{Step1, solve_position};
use super::profile::{Phase, Profile, Sample, travel};
use super::velocity::velocity_change;
use super::{Limits, OtgError, State};

const GRID: usize = 48;

/// Relative tolerance for "this duration is that profile's duration".
const SAME_DURATION: f64 = 1e-12;

/// A profile for one axis of exactly `duration` (brake pre-trajectory included), from
/// `start` to `target`; `duration` must be one the axis can take (see
/// [`position_block`](super::position_block)).
///
/// Real-time: yes (no allocation, no blocking).
pub fn position_profile_with_duration(
    start: State,
    target: State,
    limits: &Limits,
    duration: f64,
) -> Result<Profile, OtgError> {
    if !duration.is_finite() {
        return Err(OtgError::NonFiniteInput {
            name: "duration",
            value: duration,
        });
    }
    let step = solve_position(start, target, limits)?;
    if duration < step.block.t_min * (1.0 - SAME_DURATION) {
        return Err(OtgError::DurationTooShort {
            requested: duration,
            minimum: step.block.t_min,
        });
    }
    profile_of_duration(&step, limits, duration)
        .ok_or(OtgError::SynchronizationFailed { axis: 0, duration })
}

pub(crate) fn profile_of_duration(step: &Step1, limits: &Limits, duration: f64) -> Option<Profile> {
    let brake = step.brake_duration();
    for candidate in step.extremal() {
        let t = candidate.duration + brake;
        if (t - duration).abs() <= SAME_DURATION * duration.max(f64::MIN_POSITIVE) {
            return Some(step.profile_with(&candidate.phases));
        }
    }
    let main = cruise_profile(step, limits, duration - brake)
        .or_else(|| other_profiles(step, limits, duration - brake))?;
    Some(step.profile_with(&main))
}

/// Jerk signs of a profile made of two upward acceleration pulses (no cruise between).
const UP_DOWN_UP_DOWN: [f64; 7] = [1.0, 0.0, -1.0, 0.0, 1.0, 0.0, -1.0];

/// Two acceleration pulses of the same direction meeting at the acceleration `a_m`, lasting
/// `duration` in total, in the frame of `b` (upward pulses). `branch` picks which pulse gets
/// the higher peak. A peak above the acceleration limit becomes a hold at the limit.
/// Returns the phases (durations may be negative: the caller's check rejects those) and the
/// position error at the end.
fn two_pulses(
    pr: &Problem,
    b: &Bounds,
    duration: f64,
    a_m: f64,
    branch: bool,
) -> Option<([Phase; 7], f64)> {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let (j, a_max) = (b.j, b.a_max);
    let dv2j = 2.0 * j * (vf - v0);
    // Ramp times add up to the duration, velocity gains add up to the velocity change.
    let s = 0.5 * (j * duration + a0 + 2.0 * a_m + af);
    let q = 0.5 * (dv2j + a0 * a0 + 2.0 * a_m * a_m + af * af);
    let disc = 2.0 * q - s * s;
    if disc < 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let (mut p1, mut p2) = if branch {
        (0.5 * (s + root), 0.5 * (s - root))
    } else {
        (0.5 * (s - root), 0.5 * (s + root))
    };
    let (mut h1, mut h2) = (0.0, 0.0);
    if p1 > a_max || p2 > a_max {
        if p1 > a_max && p2 > a_max {
            return None;
        }
        let r = j * duration - 2.0 * a_max + a0 + 2.0 * a_m + af;
        let e = 0.5
            * (2.0 * a_max * a_max - a0 * a0 - 2.0 * a_m * a_m - af * af + 2.0 * a_max * r - dv2j);
        let d = a_max * a_max - e;
        if d < 0.0 {
            return None;
        }
        let free = a_max - d.sqrt();
        if p1 > a_max {
            p1 = a_max;
            p2 = free;
            h1 = (r - 2.0 * free) / j;
        } else {
            p2 = a_max;
            p1 = free;
            h2 = (r - 2.0 * free) / j;
        }
    }
    let t = [
        (p1 - a0) / j,
        h1,
        (p1 - a_m) / j,
        0.0,
        (p2 - a_m) / j,
        h2,
        (p2 - af) / j,
    ];
    let phases: [Phase; 7] = std::array::from_fn(|i| Phase {
        duration: t[i],
        jerk: UP_DOWN_UP_DOWN[i] * j,
    });
    let end = travel(State::new(0.0, v0, a0), &phases);
    Some((phases, end.p - pd))
}

/// A step-two family: phases and end-position error for a parameter value, in the frame of
/// the given problem and bounds.
type Family = fn(&Problem, &Bounds, f64, f64) -> Option<([Phase; 7], f64)>;

/// Profiles of the prescribed duration that the cruise family cannot represent, in both
/// directions, searched over one acceleration parameter each:
/// * two same-direction acceleration pulses (up-down-up-down), over the acceleration where
///   they meet;
/// * up-down-up with a hold at the peak acceleration, over the peak;
/// * up-down-up with a hold at the trough acceleration, over the trough.
///
/// Holds at accelerations below the limits are what make a longer duration possible for a
/// move that never passes zero acceleration.
fn other_profiles(step: &Step1, limits: &Limits, duration: f64) -> Option<[Phase; 7]> {
    if duration.is_nan() || duration < 0.0 {
        return None;
    }
    let after = step.after_brake();
    let target = step.target;
    let problem = Problem {
        v0: after.v,
        a0: after.a,
        pd: target.p - after.p,
        vf: target.v,
        af: target.a,
    };
    let bounds = bounds_of(limits);
    let families: [Family; 4] = [
        |pr, b, t, a_m| two_pulses(pr, b, t, a_m, false),
        |pr, b, t, a_m| two_pulses(pr, b, t, a_m, true),
        hold_at_peak,
        hold_at_trough,
    ];
    for (pr, b, sign) in [
        (problem, bounds, 1.0),
        (problem.mirrored(), bounds.mirrored(), -1.0),
    ] {
        for (index, family) in families.iter().enumerate() {
            let (lo, hi) = if index < 2 {
                // Going down from a0 to the meeting point and back up to af must fit in
                // the duration, and the meeting point cannot be above a peak.
                (
                    b.a_min.max(0.5 * (pr.a0 + pr.af - b.j * duration)),
                    b.a_max.min(pr.a0.min(pr.af) + b.j * duration),
                )
            } else {
                (b.a_min, b.a_max)
            };
            if lo > hi {
                continue;
            }
            let eval = |x: f64| family(&pr, &b, duration, x);
            if let Some(mut phases) = search(&eval, lo, hi, |phases| {
                check(&pr, &b, phases, true, 3).is_some()
            }) {
                for phase in &mut phases {
                    phase.jerk *= sign;
                }
                return Some(phases);
            }
        }
    }
    None
}

/// Grid search with root refinement: the first root of the residual in `[lo, hi]` whose
/// phases `accept` takes.
fn search(
    eval: &dyn Fn(f64) -> Option<([Phase; 7], f64)>,
    lo: f64,
    hi: f64,
    accept: impl Fn(&mut [Phase; 7]) -> bool,
) -> Option<[Phase; 7]> {
    // A uniform grid, plus points crowding geometrically towards both ends: just above an
    // axis's minimum duration the solution sits a hair away from a limit acceleration, in a
    // band far narrower than the grid spacing.
    const CROWD: usize = 11;
    let mut grid = [0.0; GRID + 2 * CROWD];
    for (i, slot) in grid.iter_mut().take(GRID).enumerate() {
        *slot = lo + (hi - lo) * i as f64 / (GRID - 1) as f64;
    }
    for k in 0..CROWD {
        let offset = (hi - lo) * 10f64.powi(-2 - k as i32);
        grid[GRID + 2 * k] = lo + offset;
        grid[GRID + 2 * k + 1] = hi - offset;
    }
    grid.sort_by(f64::total_cmp);
    let mut previous: Option<(f64, f64)> = None;
    for &x in &grid {
        let Some((_, residual)) = eval(x) else {
            previous = None;
            continue;
        };
        if let Some((prev_x, prev_r)) = previous {
            if prev_r.signum() != residual.signum() || residual == 0.0 {
                if let Some(mut phases) = refine(eval, (prev_x, prev_r), (x, residual)) {
                    if accept(&mut phases) {
                        return Some(phases);
                    }
                }
            }
        }
        previous = Some((x, residual));
    }
    None
}

/// `+j` to the peak `a1`, hold at `a1`, `-j` to `a3`, `+j` to the target acceleration.
/// Given the peak, the duration and the velocity change fix the hold and `a3`.
fn hold_at_peak(pr: &Problem, b: &Bounds, duration: f64, a1: f64) -> Option<([Phase; 7], f64)> {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let j = b.j;
    // hold = T - (2 a1 - a0 - 2 a3 + af) / j; the velocity equation is then a quadratic
    // in a3 with a3 <= a1.
    let c = (2.0 * a1 * a1 - a0 * a0 + af * af) / (2.0 * j) + a1 * duration
        - a1 * (2.0 * a1 - a0 + af) / j
        - (vf - v0);
    let disc = a1 * a1 + j * c;
    if disc < 0.0 {
        return None;
    }
    let a3 = a1 - disc.sqrt();
    let hold = duration - (2.0 * a1 - a0 - 2.0 * a3 + af) / j;
    let t = [
        (a1 - a0) / j,
        hold,
        (a1 - a3) / j,
        0.0,
        0.0,
        0.0,
        (af - a3) / j,
    ];
    with_residual(pr, b, t, pd)
}

/// `+j` to `a1`, `-j` to the trough `a3`, hold at `a3`, `+j` to the target acceleration.
fn hold_at_trough(pr: &Problem, b: &Bounds, duration: f64, a3: f64) -> Option<([Phase; 7], f64)> {
    let Problem { v0, a0, pd, vf, af } = *pr;
    let j = b.j;
    let d = (-a0 * a0 - 2.0 * a3 * a3 + af * af) / (2.0 * j)
        + a3 * duration
        + a3 * (a0 + 2.0 * a3 - af) / j
        - (vf - v0);
    let disc = a3 * a3 - j * d;
    if disc < 0.0 {
        return None;
    }
    let a1 = a3 + disc.sqrt();
    let hold = duration - (2.0 * a1 - a0 - 2.0 * a3 + af) / j;
    let t = [
        (a1 - a0) / j,
        0.0,
        (a1 - a3) / j,
        0.0,
        0.0,
        hold,
        (af - a3) / j,
    ];
    with_residual(pr, b, t, pd)
}

fn with_residual(pr: &Problem, b: &Bounds, t: [f64; 7], pd: f64) -> Option<([Phase; 7], f64)> {
    const UP_DOWN_DOWN_UP: [f64; 7] = [1.0, 0.0, -1.0, 0.0, -1.0, 0.0, 1.0];
    let phases: [Phase; 7] = std::array::from_fn(|i| Phase {
        duration: t[i],
        jerk: UP_DOWN_DOWN_UP[i] * b.j,
    });
    let end = travel(State::new(0.0, pr.v0, pr.a0), &phases);
    Some((phases, end.p - pd))
}

/// Refines a root of a continuous residual between two parameters of opposite sign.
fn refine(
    eval: &dyn Fn(f64) -> Option<([Phase; 7], f64)>,
    left: (f64, f64),
    right: (f64, f64),
) -> Option<[Phase; 7]> {
    let x = illinois(&|x| eval(x).map(|(_, r)| r), left, right)?;
    eval(x).map(|(phases, _)| phases)
}

/// Root of a continuous function between two points where it has opposite signs, by the
/// Illinois variant of regula falsi: superlinear, never leaves the bracket, at most 100
/// evaluations. Returns the bracket end with the smaller residual.
fn illinois(f: &dyn Fn(f64) -> Option<f64>, left: (f64, f64), right: (f64, f64)) -> Option<f64> {
    let (mut a, mut b) = (left, right);
    let tol = 4.0 * f64::EPSILON * a.0.abs().max(b.0.abs()) + 1e-15 * (b.0 - a.0).abs();
    let mut side = 0;
    for _ in 0..100 {
        if a.1 == 0.0 {
            return Some(a.0);
        }
        if b.1 == 0.0 {
            return Some(b.0);
        }
        if (b.0 - a.0).abs() <= tol {
            break;
        }
        let mut x = (a.0 * b.1 - b.0 * a.1) / (b.1 - a.1);
        if !(x > a.0.min(b.0) && x < a.0.max(b.0)) {
            x = 0.5 * (a.0 + b.0);
        }
        let fx = f(x)?;
        if fx.signum() == b.1.signum() {
            b = (x, fx);
            if side == -1 {
                a.1 *= 0.5;
            }
            side = -1;
        } else {
            a = (x, fx);
            if side == 1 {
                b.1 *= 0.5;
            }
            side = 1;
        }
    }
    Some(if a.1.abs() < b.1.abs() { a.0 } else { b.0 })
}

fn bounds_of(limits: &Limits) -> Bounds {
    Bounds {
        v_max: limits.max_velocity,
        v_min: limits.min_velocity,
        a_max: limits.max_acceleration,
        a_min: limits.min_acceleration,
        j: limits.max_jerk,
    }
}

#[derive(Clone, Copy, Default)]
struct CruiseSample {
    vc: f64,
    cruise: f64,
    residual: f64,
}

/// Phases and distance error of the cruise profile through `vc` lasting `duration`.
fn cruise_through(
    after: State,
    target: State,
    limits: &Limits,
    duration: f64,
    vc: f64,
) -> Option<([Phase; 7], CruiseSample)> {
    let (a_max, a_min, j) = (
        limits.max_acceleration,
        limits.min_acceleration,
        limits.max_jerk,
    );
    let up = velocity_change(after.v, after.a, vc, 0.0, a_max, a_min, j)?;
    let down = velocity_change(vc, 0.0, target.v, target.a, a_max, a_min, j)?;
    let cruise = duration - up.duration() - down.duration();
    let mut phases = [Phase::default(); 7];
    phases[..3].copy_from_slice(&up.phases);
    phases[3] = Phase {
        duration: cruise.max(0.0),
        jerk: 0.0,
    };
    phases[4..].copy_from_slice(&down.phases);
    // A negative cruise is not a profile; its residual still guides the search.
    let residual = travel(after, &phases).p + vc * cruise.min(0.0) - target.p;
    Some((
        phases,
        CruiseSample {
            vc,
            cruise,
            residual,
        },
    ))
}

/// The cruise family, searched on a coarse grid first (enough almost always), then on a
/// fine one.
fn cruise_profile(step: &Step1, limits: &Limits, duration: f64) -> Option<[Phase; 7]> {
    if duration.is_nan() || duration < 0.0 {
        return None;
    }
    cruise_profile_on(step, limits, duration, 12)
        .or_else(|| cruise_profile_on(step, limits, duration, GRID))
}

fn cruise_profile_on(
    step: &Step1,
    limits: &Limits,
    duration: f64,
    points: usize,
) -> Option<[Phase; 7]> {
    let points = points.clamp(2, GRID);
    let after = step.after_brake();
    let target = step.target;
    let eval = |vc: f64| cruise_through(after, target, limits, duration, vc);
    let (lo, hi) = (limits.min_velocity, limits.max_velocity);
    // Samples over the cruise velocity range, with the edges of the region where the cruise
    // time is not negative refined in between.
    let mut samples = [CruiseSample::default(); 3 * GRID];
    let mut n = 0;
    let mut previous: Option<CruiseSample> = None;
    // A uniform grid plus the velocities where the profile is shortest (the start and end
    // velocities reached by ramping the acceleration to zero): a short duration leaves a
    // narrow band of cruise velocities around them that a coarse grid would miss.
    let j = limits.max_jerk;
    let mut grid = [0.0; GRID + 4];
    for (i, slot) in grid.iter_mut().take(points).enumerate() {
        *slot = lo + (hi - lo) * i as f64 / (points - 1) as f64;
    }
    let natural_start = after.v + after.a * after.a.abs() / (2.0 * j);
    let natural_end = target.v - target.a * target.a.abs() / (2.0 * j);
    grid[points] = natural_start.clamp(lo, hi);
    grid[points + 1] = natural_end.clamp(lo, hi);
    grid[points + 2] = (0.5 * (natural_start + natural_end)).clamp(lo, hi);
    grid[points + 3] = after.v.clamp(lo, hi);
    let grid = &mut grid[..points + 4];
    grid.sort_by(f64::total_cmp);
    for &vc in grid.iter() {
        let (_, s) = eval(vc)?;
        if let Some(prev) = previous {
            if (prev.cruise >= 0.0) != (s.cruise >= 0.0) && n + 2 < samples.len() {
                let cruise = |vc: f64| eval(vc).map(|(_, c)| c.cruise);
                let edge = illinois(&cruise, (prev.vc, prev.cruise), (s.vc, s.cruise))?;
                let (_, e) = eval(edge)?;
                samples[n] = CruiseSample {
                    cruise: e.cruise.max(0.0),
                    ..e
                };
                n += 1;
            }
        }
        if n < samples.len() {
            samples[n] = s;
            n += 1;
        }
        previous = Some(s);
    }
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
    for pair in samples[..n].windows(2) {
        let (l, r) = (pair[0], pair[1]);
        if l.cruise < 0.0 || r.cruise < 0.0 {
            continue;
        }
        if l.residual.signum() == r.residual.signum() && l.residual != 0.0 && r.residual != 0.0 {
            continue;
        }
        let residual = |vc: f64| eval(vc).map(|(_, c)| c.residual);
        let root = illinois(&residual, (l.vc, l.residual), (r.vc, r.residual))?;
        let (mut phases, s) = eval(root)?;
        if s.cruise < -SAME_DURATION * duration {
            continue;
        }
        let relative = Problem {
            pd: problem.pd,
            ..problem
        };
        if check(&relative, &bounds, &mut phases, true, 3).is_some() {
            return Some(phases);
        }
    }
    None
}

/// Profiles of several axes that start together and reach their targets at the same time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Synchronized<const N: usize> {
    /// One profile per axis, all of the same duration.
    pub profiles: [Profile; N],
}

impl<const N: usize> Synchronized<N> {
    /// Common duration of all axes (the longest, should they differ).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn duration(&self) -> f64 {
        self.profiles
            .iter()
            .map(Profile::duration)
            .fold(0.0, f64::max)
    }

    /// Every axis's sample at time `t`.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn at(&self, t: f64) -> [Sample; N] {
        let mut out = [Sample::default(); N];
        for (slot, profile) in out.iter_mut().zip(&self.profiles) {
            *slot = profile.at(t);
        }
        out
    }
}

/// Time-synchronised profiles: every axis goes from `start[i]` to `target[i]` within
/// `limits[i]`, all arriving at the same time, as early as the slowest axis allows.
///
/// Cost: step one for every axis, then for each axis that is not the slowest a
/// one-dimensional search (some tens of closed-form evaluations); no allocation.
///
/// Real-time: yes (no allocation, no blocking).
pub fn synchronize<const N: usize>(
    start: &[State; N],
    target: &[State; N],
    limits: &[Limits; N],
) -> Result<Synchronized<N>, OtgError> {
    synchronize_with(start, target, limits, None)
}

/// As [`synchronize`], with the common duration rounded up to a whole number of servo
/// `period`s, so that the motion ends exactly on a servo tick (ruckig's "discrete"
/// duration). With one axis this is the single-axis move ending on a tick.
///
/// Real-time: yes (no allocation, no blocking).
pub fn synchronize_on_period<const N: usize>(
    start: &[State; N],
    target: &[State; N],
    limits: &[Limits; N],
    period: f64,
) -> Result<Synchronized<N>, OtgError> {
    if !(period.is_finite() && period > 0.0) {
        return Err(OtgError::InvalidLimit {
            name: "period",
            requirement: "greater than zero",
            value: period,
        });
    }
    synchronize_with(start, target, limits, Some(period))
}

fn synchronize_with<const N: usize>(
    start: &[State; N],
    target: &[State; N],
    limits: &[Limits; N],
    period: Option<f64>,
) -> Result<Synchronized<N>, OtgError> {
    let mut steps = [Step1::default(); N];
    for (i, slot) in steps.iter_mut().enumerate() {
        *slot = solve_position(start[i], target[i], &limits[i])?;
    }
    let blocked = |t: f64| steps.iter().any(|s| s.block.is_blocked(t));
    // Up to a whole number of periods; a duration a rounding hair above a multiple stays on
    // that multiple.
    let on_grid = |t: f64| match period {
        Some(p) => ((t / p) - 1e-9).ceil().max(0.0) * p,
        None => t,
    };
    // The next duration from `t` on that no axis has blocked (on the grid if there is one).
    let next_free = |t: f64| {
        let mut t = on_grid(t);
        for _ in 0..1000 {
            if !blocked(t) {
                return Some(t);
            }
            match period {
                Some(p) => t += p,
                None => return None,
            }
        }
        None
    };
    let t_lower = steps.iter().map(|s| s.block.t_min).fold(0.0, f64::max);
    // Candidate durations: the slowest minimum, then the right ends of blocked intervals.
    let mut candidates = [f64::INFINITY; 64];
    let mut n = 0;
    let mut push = |t: f64| {
        if t >= t_lower && n < candidates.len() {
            candidates[n] = t;
            n += 1;
        }
    };
    push(t_lower);
    for step in &steps {
        for &(_, right) in step.block.blocked.iter().flatten() {
            push(right);
        }
    }
    candidates[..n].sort_by(f64::total_cmp);
    let mut last = on_grid(t_lower);
    for &candidate in &candidates[..n] {
        let Some(t) = next_free(candidate) else {
            continue;
        };
        if let Ok(profiles) = try_duration(&steps, limits, t) {
            return Ok(Synchronized { profiles });
        }
        last = t;
    }
    // Conservative fallback: lengthen the duration until every axis has a profile.
    let mut failed_axis = 0;
    for k in 0..40 {
        let t = match period {
            Some(p) => last + p * f64::from(1 + k),
            None => last * (1.0 + 1e-9 * 2f64.powi(k)),
        };
        if blocked(t) {
            continue;
        }
        match try_duration(&steps, limits, t) {
            Ok(profiles) => return Ok(Synchronized { profiles }),
            Err(axis) => failed_axis = axis,
        }
    }
    Err(OtgError::SynchronizationFailed {
        axis: failed_axis,
        duration: last,
    })
}

fn try_duration<const N: usize>(
    steps: &[Step1; N],
    limits: &[Limits; N],
    t: f64,
) -> Result<[Profile; N], usize> {
    let mut profiles = [Profile::hold(State::default()); N];
    for (i, slot) in profiles.iter_mut().enumerate() {
        *slot = profile_of_duration(&steps[i], &limits[i], t).ok_or(i)?;
    }
    Ok(profiles)
}
