//! Velocity interface: reach a target velocity and acceleration as fast as possible, with no
//! position target (jogging, feed override, quick stops). Also the building block of the
//! position interface's cruise profiles and of time synchronisation.

use super::brake::velocity_brake_phase;
use super::check::{Bounds, Problem, check};
use super::limits::{Which, check_target};
use super::profile::{Phase, Profile, travel};
use super::{Limits, OtgError, State};

/// A time-optimal change of velocity: a jerk ramp, a hold, a ramp with the opposite jerk.
#[derive(Debug, Clone, Copy)]
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
    let half_sq = 0.5 * (a0 * a0 + af * af);
    let tol = 1e-12 * (a_max - a_min);
    let mut best: Option<VelocityChange> = None;
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
            best = Some(VelocityChange {
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
            let down = VelocityChange {
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
            };
            if best.is_none_or(|b| down.duration() < b.duration()) {
                best = Some(down);
            }
        }
    }
    best
}

/// Time-optimal profile from `start` to the target velocity `vf` and acceleration `af`
/// (position free), within the acceleration and jerk limits.
///
/// The velocity limits are not used on the way (a velocity change is monotone apart from
/// the overshoot an initial acceleration forces), but the target velocity must lie inside
/// them. A start acceleration outside the limits is first brought back with the largest
/// jerk. Cost: closed form, a few hundred nanoseconds.
pub fn velocity_profile(
    start: State,
    vf: f64,
    af: f64,
    limits: &Limits,
) -> Result<Profile, OtgError> {
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
    let change = velocity_change(
        v,
        a,
        vf,
        af,
        limits.max_acceleration,
        limits.min_acceleration,
        limits.max_jerk,
    )
    .ok_or(OtgError::NoProfileFound { distance: 0.0 })?;
    let mut phases = change.phases;
    let problem = Problem {
        v0: v,
        a0: a,
        pd: 0.0,
        vf,
        af,
    };
    let bounds = Bounds {
        v_max: f64::INFINITY,
        v_min: f64::NEG_INFINITY,
        a_max: limits.max_acceleration,
        a_min: limits.min_acceleration,
        j: limits.max_jerk,
    };
    check(&problem, &bounds, &mut phases, false, 0)
        .ok_or(OtgError::NoProfileFound { distance: 0.0 })?;
    let all = [
        brake.phases[0],
        brake.phases[1],
        phases[0],
        phases[1],
        phases[2],
    ];
    let profile = Profile::from_phases(start, &all, 2, None);
    let end = profile.end();
    Ok(profile.with_end(State::new(end.p, vf, af)))
}
