//! Rigid motor and load: `J·dω/dt = τ − b·ω − T_c·sgn(ω)`, with the load at rest staying at
//! rest while `|τ| ≤ T_c` (stiction equal to the Coulomb friction).
//!
//! Integration is exact for a torque held over each step: between velocity sign changes the
//! equation is linear with constant input, so velocity and position follow closed-form
//! exponentials; when the velocity reaches zero inside a step the step is split there and
//! the stick condition decides the rest. No truncation error, whatever the step.

use crate::sim::config::MotorConfig;

/// The motor and load of one joint, in joint units (position in units, velocity in
/// units/s; torque in N·m on the motor shaft).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotorModel {
    /// Acceleration per N·m (units/s² per N·m).
    acceleration_per_torque: f64,
    /// Viscous decay rate b/J (1/s).
    decay_rate: f64,
    /// Coulomb friction as an acceleration (units/s²).
    coulomb_acceleration: f64,
    position: f64,
    velocity: f64,
    /// e^(−c·t) − 1 for the last full step length, which repeats every sub-step.
    cached_step: f64,
    cached_decay: f64,
}

impl MotorModel {
    /// A motor at rest at `position`; `units_per_revolution` maps the shaft to the joint.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(config: &MotorConfig, units_per_revolution: f64, position: f64) -> Self {
        let units_per_radian = units_per_revolution / (2.0 * std::f64::consts::PI);
        let acceleration_per_torque = units_per_radian / config.inertia;
        Self {
            acceleration_per_torque,
            decay_rate: config.viscous_friction / config.inertia,
            coulomb_acceleration: config.coulomb_friction * acceleration_per_torque,
            position,
            velocity: 0.0,
            cached_step: 0.0,
            cached_decay: 0.0,
        }
    }

    /// Position (units).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn position(&self) -> f64 {
        self.position
    }

    /// Velocity (units/s).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn velocity(&self) -> f64 {
        self.velocity
    }

    /// Puts the load at `position`, at rest (an ideal drive's move).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn place(&mut self, position: f64, velocity: f64) {
        self.position = position;
        self.velocity = velocity;
    }

    /// The constants of the linear part of the model: acceleration per N·m, viscous decay
    /// rate (1/s), Coulomb friction as an acceleration.
    pub(crate) fn linear_parts(&self) -> (f64, f64, f64) {
        (
            self.acceleration_per_torque,
            self.decay_rate,
            self.coulomb_acceleration,
        )
    }

    /// Advances by `step_s` seconds with `torque` (N·m) held.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn advance(&mut self, torque: f64, step_s: f64) {
        let drive = torque * self.acceleration_per_torque;
        let mut remaining = step_s;
        // At most two pieces: up to a stop, then from rest (which cannot reverse again).
        for _ in 0..2 {
            if remaining <= 0.0 {
                break;
            }
            let direction = if self.velocity > 0.0 {
                1.0
            } else if self.velocity < 0.0 {
                -1.0
            } else if drive.abs() <= self.coulomb_acceleration {
                return; // stuck
            } else {
                drive.signum()
            };
            let net = drive - direction * self.coulomb_acceleration;
            let stop_after = if self.keeps_direction(net, remaining) {
                f64::INFINITY
            } else {
                self.time_to_stop(net)
            };
            if stop_after < remaining {
                self.position += self.distance(net, stop_after).0;
                self.velocity = 0.0;
                remaining -= stop_after;
            } else {
                (self.position, self.velocity) = {
                    let (distance, velocity) = self.distance(net, remaining);
                    (self.position + distance, velocity)
                };
                remaining = 0.0;
            }
        }
    }

    /// Distance covered in `t` with constant net acceleration input `net`, and the
    /// velocity at its end.
    fn distance(&mut self, net: f64, t: f64) -> (f64, f64) {
        let c = self.decay_rate;
        if c > 0.0 {
            let terminal = net / c;
            // e^(−ct) − 1, accurate for small ct; the same step comes back every sub-step.
            if t != self.cached_step {
                self.cached_step = t;
                self.cached_decay = (-c * t).exp_m1();
            }
            let decay = self.cached_decay;
            let distance = terminal * t - (self.velocity - terminal) * decay / c;
            (distance, self.velocity + (self.velocity - terminal) * decay)
        } else {
            (
                self.velocity * t + 0.5 * net * t * t,
                self.velocity + net * t,
            )
        }
    }

    /// Whether the velocity clearly keeps its sign (and stays away from zero) for `t` under
    /// `net`: then the step needs no stop time, and the logarithm of
    /// [`time_to_stop`](Self::time_to_stop) is saved. This only answers "yes" with a margin
    /// far above rounding, where the stop time would certainly come out longer than `t`,
    /// so the result is the same as with the stop time.
    #[inline]
    fn keeps_direction(&self, net: f64, t: f64) -> bool {
        let v = self.velocity;
        let c = self.decay_rate;
        if v == 0.0 || net * v >= 0.0 {
            return true; // no stop at all (time_to_stop is infinite)
        }
        if c.is_nan() || c <= 0.0 || t != self.cached_step {
            return false;
        }
        let terminal = net / c;
        let change = (v - terminal) * self.cached_decay;
        let end = v + change;
        end * v > 0.0 && end.abs() > 1e-6 * v.abs().max(change.abs())
    }

    /// When the velocity would reach zero under `net` (infinite if it never does).
    fn time_to_stop(&self, net: f64) -> f64 {
        let v = self.velocity;
        // Only a net acceleration against the motion brings it to rest.
        if v == 0.0 || net * v >= 0.0 {
            return f64::INFINITY;
        }
        let c = self.decay_rate;
        if c > 0.0 {
            let terminal = net / c;
            // v(t) = terminal + (v − terminal)·e^(−ct) = 0
            ((v - terminal) / -terminal).ln() / c
        } else {
            -v / net
        }
    }
}
