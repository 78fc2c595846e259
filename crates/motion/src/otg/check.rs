//! Validation of a candidate list of phases: durations not negative, limits kept, target
//! reached. Every solver family builds candidates and lets this one judge them, so a wrong
//! root or a rounding mishap can only lose a candidate, never produce a wrong profile.

use super::profile::{Phase, integrate};

/// Limits in the frame of the candidate (already mirrored for "downward" candidates).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Bounds {
    pub(crate) v_max: f64,
    pub(crate) v_min: f64,
    pub(crate) a_max: f64,
    pub(crate) a_min: f64,
    pub(crate) j: f64,
}

impl Bounds {
    /// The same limits seen in a frame where position, velocity and acceleration are negated.
    pub(crate) fn mirrored(self) -> Self {
        Self {
            v_max: -self.v_min,
            v_min: -self.v_max,
            a_max: -self.a_min,
            a_min: -self.a_max,
            j: self.j,
        }
    }
}

/// Start (relative position 0) and target of one move, position relative to the start.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Problem {
    pub(crate) v0: f64,
    pub(crate) a0: f64,
    pub(crate) pd: f64,
    pub(crate) vf: f64,
    pub(crate) af: f64,
}

impl Problem {
    pub(crate) fn mirrored(self) -> Self {
        Self {
            v0: -self.v0,
            a0: -self.a0,
            pd: -self.pd,
            vf: -self.vf,
            af: -self.af,
        }
    }
}

/// Relative tolerance for "this limit is kept".
const LIMIT_TOL: f64 = 1e-10;
/// Relative tolerance for "this target is reached" (in units of the move's own scale).
const TARGET_TOL: f64 = 1e-9;
/// Relative tolerance for "this phase duration is zero, not negative".
const TIME_TOL: f64 = 1e-12;

/// Clamps tiny negative durations to zero and checks the phases. Returns the total duration
/// if the candidate is valid. `check_target_position` is off for pure velocity changes.
///
/// When the start state is outside the velocity limits or bound to leave them (possible
/// right after a brake pre-trajectory), the velocity limits are not checked during the
/// first `velocity_free` phases, which are bringing it back (as in ruckig). From a safe
/// start every phase is checked.
pub(crate) fn check(
    problem: &Problem,
    bounds: &Bounds,
    phases: &mut [Phase],
    check_target_position: bool,
    velocity_free: usize,
) -> Option<f64> {
    let total: f64 = phases.iter().map(|ph| ph.duration.abs()).sum();
    if !total.is_finite() {
        return None;
    }
    for phase in phases.iter_mut() {
        if phase.duration.is_nan() {
            return None;
        }
        if phase.duration < 0.0 {
            if phase.duration > -TIME_TOL * total.max(f64::MIN_POSITIVE) {
                phase.duration = 0.0;
            } else {
                return None;
            }
        }
    }
    let v_scale = [
        bounds.v_max,
        -bounds.v_min,
        problem.v0.abs(),
        problem.vf.abs(),
    ]
    .into_iter()
    .filter(|x| x.is_finite())
    .fold(0.0, f64::max);
    let a_scale = bounds
        .a_max
        .max(-bounds.a_min)
        .max(problem.a0.abs())
        .max(problem.af.abs());
    let a_lim_tol = LIMIT_TOL * a_scale;
    let v_lim_tol = LIMIT_TOL * v_scale;
    let settled = problem.v0 + problem.a0 * problem.a0.abs() / (2.0 * bounds.j);
    let inside = |v: f64| v <= bounds.v_max + v_lim_tol && v >= bounds.v_min - v_lim_tol;
    let velocity_free = if inside(problem.v0) && inside(settled) {
        0
    } else {
        velocity_free
    };
    let snap = snap_tolerance(problem.a0, phases);
    let (mut p, mut v, mut a) = (0.0, problem.v0, problem.a0);
    for (index, phase) in phases.iter().enumerate() {
        if phase.duration == 0.0 {
            continue;
        }
        let j = phase.jerk;
        if j == 0.0 && a.abs() <= snap {
            a = 0.0;
        }
        let check_velocity = index >= velocity_free;
        if j != 0.0 && check_velocity {
            let tz = -a / j;
            if tz > 0.0 && tz < phase.duration {
                let v_ext = v - 0.5 * a * a / j;
                if v_ext > bounds.v_max + v_lim_tol || v_ext < bounds.v_min - v_lim_tol {
                    return None;
                }
            }
        }
        (p, v, a) = integrate(p, v, a, j, phase.duration);
        if a > bounds.a_max + a_lim_tol || a < bounds.a_min - a_lim_tol {
            return None;
        }
        if check_velocity && (v > bounds.v_max + v_lim_tol || v < bounds.v_min - v_lim_tol) {
            return None;
        }
    }
    let duration: f64 = phases.iter().map(|ph| ph.duration).sum();
    let a_tol = TARGET_TOL * (a_scale + bounds.j * duration);
    let v_tol = TARGET_TOL * (v_scale + a_scale * duration + bounds.j * duration * duration);
    let p_tol = TARGET_TOL * (problem.pd.abs() + v_scale * duration);
    let reached = (a - problem.af).abs() <= a_tol
        && (v - problem.vf).abs() <= v_tol
        && (!check_target_position || (p - problem.pd).abs() <= p_tol);
    reached.then_some(duration)
}

/// Below this magnitude the acceleration at the start of a constant-acceleration phase is
/// rounding noise of a ramp meant to end at zero: a cruise. Left alone it would make the
/// velocity drift over a long cruise; the profile builder snaps it to zero the same way.
pub(crate) fn snap_tolerance(a0: f64, phases: &[Phase]) -> f64 {
    let swing: f64 = phases.iter().map(|p| (p.jerk * p.duration).abs()).sum();
    1e-12 * (a0.abs() + swing)
}
