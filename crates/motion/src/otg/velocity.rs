//! Velocity interface: reach a target velocity and acceleration as fast as possible, with no
//! position target (jogging, feed override, quick stops). Its time-optimal velocity change
//! is also the building block of the cruise profiles of time synchronisation.

use super::brake::{Brake, velocity_brake_phase};
use super::check::{Bounds, Problem, check};
use super::limits::{Which, check_target};
use super::profile::{Phase, Profile, travel};
use super::roots::real_roots_in;
use super::sync::Synchronized;
use super::{Limits, OtgError, State};

/// A time-optimal change of velocity: a jerk ramp, a hold, a ramp with the opposite jerk.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct VelocityChange {
    pub(crate) phases: [Phase; 3],
}

impl VelocityChange {
    pub(crate) fn duration(&self) -> f64 {
        self.phases.iter().map(|p| p.duration).sum()
    }
}

/// The time-optimal way from `(v0, a0)` to `(vf, af)` under acceleration limits
/// `[a_min, a_max]` and jerk `j`, ignoring velocity limits: an upward pulse
/// (`+j`, hold at the peak, `-j`) or a downward one, whichever is valid and shorter.
pub(crate) fn velocity_change(
    v0: f64,
    a0: f64,
    vf: f64,
    af: f64,
    a_max: f64,
    a_min: f64,
    j: f64,
) -> Option<VelocityChange> {
    match velocity_changes(v0, a0, vf, af, a_max, a_min, j) {
        (Some(up), Some(down)) => Some(if down.duration() < up.duration() {
            down
        } else {
            up
        }),
        (up, down) => up.or(down),
    }
}

/// Both pulse directions of a velocity change, where they exist: `(upward, downward)`.
/// When both do, the longer one bounds a duration interval no velocity change can take.
pub(crate) fn velocity_changes(
    v0: f64,
    a0: f64,
    vf: f64,
    af: f64,
    a_max: f64,
    a_min: f64,
    j: f64,
) -> (Option<VelocityChange>, Option<VelocityChange>) {
    let half_sq = 0.5 * (a0 * a0 + af * af);
    let tol = 1e-12 * (a_max - a_min);
    let mut up: Option<VelocityChange> = None;
    let mut down: Option<VelocityChange> = None;
    // Upward pulse.
    let peak_sq = j * (vf - v0) + half_sq;
    if peak_sq >= 0.0 {
        let mut peak = peak_sq.sqrt();
        let mut hold = 0.0;
        if peak > a_max {
            peak = a_max;
            hold = ((vf - v0) - (2.0 * a_max * a_max - a0 * a0 - af * af) / (2.0 * j)) / a_max;
        }
        if peak >= a0.max(af) - tol {
            up = Some(VelocityChange {
                phases: [
                    Phase {
                        duration: ((peak - a0) / j).max(0.0),
                        jerk: j,
                    },
                    Phase {
                        duration: hold.max(0.0),
                        jerk: 0.0,
                    },
                    Phase {
                        duration: ((peak - af) / j).max(0.0),
                        jerk: -j,
                    },
                ],
            });
        }
    }
    // Downward pulse.
    let trough_sq = j * (v0 - vf) + half_sq;
    if trough_sq >= 0.0 {
        let mut trough = -trough_sq.sqrt();
        let mut hold = 0.0;
        if trough < a_min {
            trough = a_min;
            hold = ((v0 - vf) - (2.0 * a_min * a_min - a0 * a0 - af * af) / (2.0 * j)) / -a_min;
        }
        if trough <= a0.min(af) + tol {
            down = Some(VelocityChange {
                phases: [
                    Phase {
                        duration: ((a0 - trough) / j).max(0.0),
                        jerk: -j,
                    },
                    Phase {
                        duration: hold.max(0.0),
                        jerk: 0.0,
                    },
                    Phase {
                        duration: ((af - trough) / j).max(0.0),
                        jerk: j,
                    },
                ],
            });
        }
    }
    (up, down)
}

/// Time-optimal profile from `start` to the target velocity `vf` and acceleration `af`
/// (position free), within the acceleration and jerk limits.
///
/// The velocity limits are not used on the way (a velocity change is monotone apart from
/// the overshoot an initial acceleration forces), but the target velocity must lie inside
/// them. A start acceleration outside the limits is first brought back with the largest
/// jerk. Cost: closed form, a few hundred nanoseconds.
///
/// Real-time: yes (no allocation, no blocking).
pub fn velocity_profile(
    start: State,
    vf: f64,
    af: f64,
    limits: &Limits,
) -> Result<Profile, OtgError> {
    let step = velocity_step(start, vf, af, limits)?;
    Ok(step.profile(&step.change.phases))
}

/// Velocity changes of several axes that end together: axis `i` goes from `start[i]` to
/// velocity `vf[i]` and acceleration `af[i]`, all finishing when the slowest can (time
/// synchronisation of the velocity interface, e.g. axes jogged together that should reach
/// their speeds, or stop, at the same moment).
///
/// The others get a velocity change of exactly that duration: a ramp to a peak (or trough)
/// acceleration below the limit, a hold, a ramp to the target acceleration, solved in closed
/// form. Should none exist the common duration is lengthened slightly (not seen in tests).
///
/// Real-time: yes (no allocation, no blocking).
pub fn synchronize_velocity<const N: usize>(
    start: &[State; N],
    vf: &[f64; N],
    af: &[f64; N],
    limits: &[Limits; N],
) -> Result<Synchronized<N>, OtgError> {
    let mut steps = [VelocityStep::default(); N];
    for (i, slot) in steps.iter_mut().enumerate() {
        *slot = velocity_step(start[i], vf[i], af[i], &limits[i])?;
    }
    let t_lower = steps.iter().map(VelocityStep::duration).fold(0.0, f64::max);
    // Candidate durations: the slowest minimum and the right ends of blocked intervals.
    let mut candidates = [f64::INFINITY; 16];
    let mut n = 0;
    for t in std::iter::once(t_lower).chain(steps.iter().filter_map(|s| s.blocked().map(|b| b.1))) {
        if t >= t_lower && n < candidates.len() {
            candidates[n] = t;
            n += 1;
        }
    }
    candidates[..n].sort_by(f64::total_cmp);
    let mut failed = 0;
    let mut last = t_lower;
    let tries = candidates[..n]
        .iter()
        .copied()
        .chain((1..40).map(|k| last_or(t_lower, &candidates[..n]) * (1.0 + 1e-9 * 2f64.powi(k))));
    for t in tries {
        if steps.iter().any(|s| s.is_blocked(t)) {
            continue;
        }
        last = t;
        let mut profiles = [Profile::hold(State::default()); N];
        let mut all = true;
        for (i, slot) in profiles.iter_mut().enumerate() {
            match steps[i].profile_lasting(&limits[i], t) {
                Some(profile) => *slot = profile,
                None => {
                    all = false;
                    failed = i;
                    break;
                }
            }
        }
        if all {
            return Ok(Synchronized { profiles });
        }
    }
    Err(OtgError::SynchronizationFailed {
        axis: failed,
        duration: last,
    })
}

/// The largest candidate duration (where the lengthening fallback starts).
fn last_or(t_lower: f64, candidates: &[f64]) -> f64 {
    candidates.iter().copied().fold(t_lower, f64::max)
}

/// Brake phase, the state after it and the time-optimal change from there.
#[derive(Debug, Clone, Copy, Default)]
struct VelocityStep {
    start: State,
    brake: Brake,
    v: f64,
    a: f64,
    vf: f64,
    af: f64,
    change: VelocityChange,
    /// The other pulse direction, when it is valid too and longer: durations strictly
    /// between the two are blocked (as in ruckig).
    other: Option<VelocityChange>,
}

impl VelocityStep {
    fn brake_duration(&self) -> f64 {
        self.brake.phases.iter().map(|p| p.duration).sum()
    }

    fn duration(&self) -> f64 {
        self.brake_duration() + self.change.duration()
    }

    /// Durations this axis cannot take: between its two valid pulses.
    fn blocked(&self) -> Option<(f64, f64)> {
        self.other
            .map(|o| (self.duration(), self.brake_duration() + o.duration()))
    }

    fn is_blocked(&self, t: f64) -> bool {
        t < self.duration() || self.blocked().is_some_and(|(l, r)| l < t && t < r)
    }

    fn profile(&self, change: &[Phase; 3]) -> Profile {
        let all = [
            self.brake.phases[0],
            self.brake.phases[1],
            change[0],
            change[1],
            change[2],
        ];
        let profile = Profile::from_phases(self.start, &all, 2, None);
        let end = profile.end();
        profile.with_end(State::new(end.p, self.vf, self.af))
    }

    /// A profile of exactly `t`: one of the two pulses if `t` is its duration, else a
    /// change with a hold below the limits.
    fn profile_lasting(&self, limits: &Limits, t: f64) -> Option<Profile> {
        let same = |d: f64| (t - d).abs() <= 1e-12 * t.max(f64::MIN_POSITIVE);
        if same(self.duration()) {
            return Some(self.profile(&self.change.phases));
        }
        if let Some(other) = self
            .other
            .filter(|o| same(self.brake_duration() + o.duration()))
        {
            return Some(self.profile(&other.phases));
        }
        let phases = velocity_change_lasting(self, limits, t - self.brake_duration())?;
        Some(self.profile(&phases))
    }

    fn problem(&self) -> Problem {
        Problem {
            v0: self.v,
            a0: self.a,
            pd: 0.0,
            vf: self.vf,
            af: self.af,
        }
    }
}

fn velocity_step(
    start: State,
    vf: f64,
    af: f64,
    limits: &Limits,
) -> Result<VelocityStep, OtgError> {
    limits.validate()?;
    start.check_finite(Which::Start)?;
    State::new(0.0, vf, af).check_finite(Which::Target)?;
    check_target(vf, af, limits)?;
    let brake = velocity_brake_phase(start.a, limits);
    let after = travel(start, &brake.phases);
    let (v, mut a) = (after.v, after.a);
    if let Some(ph) = brake.phases.first().filter(|ph| ph.duration > 0.0) {
        // Land exactly on the limit the brake ramp aims at.
        a = if ph.jerk < 0.0 {
            limits.max_acceleration
        } else {
            limits.min_acceleration
        };
    }
    let (a_max, a_min, j) = (
        limits.max_acceleration,
        limits.min_acceleration,
        limits.max_jerk,
    );
    let problem = Problem {
        v0: v,
        a0: a,
        pd: 0.0,
        vf,
        af,
    };
    let bounds = velocity_bounds(limits);
    let valid = |change: Option<VelocityChange>| {
        change.and_then(|mut c| check(&problem, &bounds, &mut c.phases, false, 0).map(|_| c))
    };
    let (up, down) = velocity_changes(v, a, vf, af, a_max, a_min, j);
    let (change, other) = match (valid(up), valid(down)) {
        (Some(u), Some(d)) => {
            let (short, long) = if d.duration() < u.duration() {
                (d, u)
            } else {
                (u, d)
            };
            let distinct = long.duration() > short.duration() * (1.0 + 1e-9);
            (short, distinct.then_some(long))
        }
        (Some(c), None) | (None, Some(c)) => (c, None),
        (None, None) => return Err(OtgError::NoProfileFound { distance: 0.0 }),
    };
    Ok(VelocityStep {
        start,
        brake,
        v,
        a,
        vf,
        af,
        change,
        other,
    })
}

fn velocity_bounds(limits: &Limits) -> Bounds {
    Bounds {
        v_max: f64::INFINITY,
        v_min: f64::NEG_INFINITY,
        a_max: limits.max_acceleration,
        a_min: limits.min_acceleration,
        j: limits.max_jerk,
    }
}

/// A velocity change of exactly `duration`: a ramp from the start acceleration to `a_p`,
/// a hold at `a_p`, a ramp to the target acceleration, with `a_p` below the limits. For each
/// ordering of `a_p` against the start and target accelerations the velocity gained is a
/// quadratic in `a_p`.
fn velocity_change_lasting(
    step: &VelocityStep,
    limits: &Limits,
    duration: f64,
) -> Option<[Phase; 3]> {
    if duration.is_nan() || duration < 0.0 {
        return None;
    }
    let (a0, af, j) = (step.a, step.af, limits.max_jerk);
    let dv = step.vf - step.v;
    let problem = step.problem();
    let bounds = velocity_bounds(limits);
    for (s1, s2) in [(1.0, 1.0), (-1.0, -1.0), (1.0, -1.0), (-1.0, 1.0)] {
        // Range of a_p for this ordering: above or below each end acceleration.
        let lo = (if s1 > 0.0 {
            a0
        } else {
            limits.min_acceleration
        })
        .max(if s2 > 0.0 {
            af
        } else {
            limits.min_acceleration
        })
        .max(limits.min_acceleration);
        let hi = (if s1 < 0.0 {
            a0
        } else {
            limits.max_acceleration
        })
        .min(if s2 < 0.0 {
            af
        } else {
            limits.max_acceleration
        })
        .min(limits.max_acceleration);
        if lo > hi {
            continue;
        }
        let qa = 1.0 / (2.0 * s1 * j) + 1.0 / (2.0 * s2 * j) - (s1 + s2) / j;
        let qb = duration + (s1 * a0 + s2 * af) / j;
        let qc = -a0 * a0 / (2.0 * s1 * j) - af * af / (2.0 * s2 * j) - dv;
        let pad = 1e-12 * (limits.max_acceleration - limits.min_acceleration);
        let roots = real_roots_in(&[qa, qb, qc], lo - pad, hi + pad);
        for &a_p in roots.as_slice() {
            let hold = duration - s1 * (a_p - a0) / j - s2 * (a_p - af) / j;
            let mut phases = [
                Phase {
                    duration: s1 * (a_p - a0) / j,
                    jerk: s1 * j,
                },
                Phase {
                    duration: hold,
                    jerk: 0.0,
                },
                Phase {
                    duration: s2 * (a_p - af) / j,
                    jerk: -s2 * j,
                },
            ];
            if check(&problem, &bounds, &mut phases, false, 0).is_some() {
                return Some(phases);
            }
        }
    }
    None
}
