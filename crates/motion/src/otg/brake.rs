//! Brake pre-trajectories: when the start state breaks a limit, or is bound to break one
//! whatever happens next (e.g. accelerating towards the velocity limit faster than the jerk
//! limit can stop), the motion first brakes with the largest allowed jerk until the state is
//! inside the limits again, then the time-optimal profile starts from there.
//!
//! The rules are those of ruckig (so durations agree with it): at most two phases, a jerk
//! ramp towards the acceleration limit and, if needed, a constant-acceleration phase.

use super::Limits;
use super::profile::Phase;

/// Up to two brake phases (zero-length phases mean "no brake").
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Brake {
    pub(crate) phases: [Phase; 2],
}

fn v_at_t(v0: f64, a0: f64, j: f64, t: f64) -> f64 {
    v0 + t * (a0 + 0.5 * j * t)
}

fn v_at_a_zero(v0: f64, a0: f64, j: f64) -> f64 {
    v0 + a0 * a0 / (2.0 * j)
}

/// Oriented limits: `j > 0` brakes a too-high state, `j < 0` (with the limits swapped)
/// brakes a too-low one.
#[derive(Clone, Copy)]
struct Oriented {
    v_max: f64,
    v_min: f64,
    a_max: f64,
    a_min: f64,
    j: f64,
}

impl Oriented {
    fn mirrored(self) -> Self {
        Self {
            v_max: self.v_min,
            v_min: self.v_max,
            a_max: self.a_min,
            a_min: self.a_max,
            j: -self.j,
        }
    }
}

/// Brake phases for the position interface.
pub(crate) fn position_brake(v0: f64, a0: f64, limits: &Limits) -> Brake {
    let up = Oriented {
        v_max: limits.max_velocity,
        v_min: limits.min_velocity,
        a_max: limits.max_acceleration,
        a_min: limits.min_acceleration,
        j: limits.max_jerk,
    };
    let j = up.j;
    if a0 > up.a_max {
        acceleration_brake(v0, a0, up)
    } else if a0 < up.a_min {
        acceleration_brake(v0, a0, up.mirrored())
    } else if (v0 > up.v_max && v_at_a_zero(v0, a0, -j) > up.v_min)
        || (a0 > 0.0 && v_at_a_zero(v0, a0, j) > up.v_max)
    {
        velocity_brake(v0, a0, up)
    } else if (v0 < up.v_min && v_at_a_zero(v0, a0, j) < up.v_max)
        || (a0 < 0.0 && v_at_a_zero(v0, a0, -j) < up.v_min)
    {
        velocity_brake(v0, a0, up.mirrored())
    } else {
        Brake::default()
    }
}

/// Brake phase for the velocity interface: only the acceleration limits matter.
pub(crate) fn velocity_brake_phase(a0: f64, limits: &Limits) -> Brake {
    let mut brake = Brake::default();
    let j = limits.max_jerk;
    if a0 > limits.max_acceleration {
        brake.phases[0] = Phase {
            duration: (a0 - limits.max_acceleration) / j,
            jerk: -j,
        };
    } else if a0 < limits.min_acceleration {
        brake.phases[0] = Phase {
            duration: (limits.min_acceleration - a0) / j,
            jerk: j,
        };
    }
    brake
}

fn acceleration_brake(v0: f64, a0: f64, o: Oriented) -> Brake {
    let j = o.j;
    let t_to_a_max = (a0 - o.a_max) / j;
    let t_to_a_zero = a0 / j;
    let v_at_a_max = v_at_t(v0, a0, -j, t_to_a_max);
    let v_at_zero = v_at_t(v0, a0, -j, t_to_a_zero);
    let mut brake = Brake::default();
    if (v_at_zero > o.v_max && j > 0.0) || (v_at_zero < o.v_max && j < 0.0) {
        return velocity_brake(v0, a0, o);
    }
    brake.phases[0] = Phase {
        duration: t_to_a_max,
        jerk: -j,
    };
    if (v_at_a_max < o.v_min && j > 0.0) || (v_at_a_max > o.v_min && j < 0.0) {
        let t_to_v_min = -(v_at_a_max - o.v_min) / o.a_max;
        let t_to_v_max = -o.a_max / (2.0 * j) - (v_at_a_max - o.v_max) / o.a_max;
        brake.phases[1] = Phase {
            duration: t_to_v_min.min(t_to_v_max).max(0.0),
            jerk: 0.0,
        };
    }
    brake
}

fn velocity_brake(v0: f64, a0: f64, o: Oriented) -> Brake {
    let j = o.j;
    let t_to_a_min = (a0 - o.a_min) / j;
    let t_to_v_max = a0 / j + (a0 * a0 + 2.0 * j * (v0 - o.v_max)).max(0.0).sqrt() / j.abs();
    let t_to_v_min = a0 / j + (0.5 * a0 * a0 + j * (v0 - o.v_min)).max(0.0).sqrt() / j.abs();
    let t_min_to_v_max = t_to_v_max.min(t_to_v_min);
    let mut brake = Brake::default();
    if t_to_a_min < t_min_to_v_max {
        let v_at_a_min = v_at_t(v0, a0, -j, t_to_a_min);
        let hold_to_v_max = -(v_at_a_min - o.v_max) / o.a_min;
        let hold_to_v_min = o.a_min / (2.0 * j) - (v_at_a_min - o.v_min) / o.a_min;
        brake.phases[0] = Phase {
            duration: t_to_a_min.max(0.0),
            jerk: -j,
        };
        brake.phases[1] = Phase {
            duration: hold_to_v_max.min(hold_to_v_min).max(0.0),
            jerk: 0.0,
        };
    } else {
        brake.phases[0] = Phase {
            duration: t_min_to_v_max.max(0.0),
            jerk: -j,
        };
    }
    brake
}
