use crate::{ConfigError, FollowingErrorMonitor, PidConfig, PidGains, ServoFault, SetPoint};

/// The position loop of one joint whose drive takes a velocity command.
///
/// Per cycle, with `e` the position error after the deadband and `T` the period:
///
/// ```text
/// integral += e·T                  (clamped to ±integrator_limit; frozen while the output
///                                   is saturated in the direction e pushes)
/// out = bias + p·e + i·integral + d·(e − e_prev)/T
///     + velocity_ff·v_cmd + acceleration_ff·a_cmd
/// out = clamp(out, ±output_limit)
/// ```
///
/// The following error is checked on the raw error (before the deadband) first: a cycle
/// over the limit returns the fault and leaves the controller's state untouched.
#[derive(Debug, Clone)]
pub struct PidController {
    gains: PidGains,
    monitor: FollowingErrorMonitor,
    integral: f64,
    previous_error: Option<f64>,
    output: f64,
}

impl PidController {
    /// A controller for joint `joint`, or the first refused configuration field.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn new(joint: usize, config: &PidConfig) -> Result<Self, ConfigError> {
        config.validate()?;
        Ok(Self {
            gains: config.gains,
            monitor: FollowingErrorMonitor::new(joint, config.following_error),
            integral: 0.0,
            previous_error: None,
            output: 0.0,
        })
    }

    /// Clears the integrator and the derivative history (call when the drive is enabled or
    /// after a fault). The following-error maximum is kept.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn reset(&mut self) {
        self.integral = 0.0;
        self.previous_error = None;
        self.output = 0.0;
    }

    /// One servo cycle: the velocity command (units/s) for the drive, or the fault that
    /// stops the joint. `feedback` is the measured position, `period_s` the time since the
    /// previous cycle.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn update(
        &mut self,
        setpoint: SetPoint,
        feedback: f64,
        period_s: f64,
    ) -> Result<f64, ServoFault> {
        let joint = self.joint();
        if !setpoint.is_finite() {
            return Err(ServoFault::NonFiniteInput {
                joint,
                input: "set-point",
            });
        }
        if !feedback.is_finite() {
            return Err(ServoFault::NonFiniteInput {
                joint,
                input: "feedback",
            });
        }
        if !(period_s.is_finite() && period_s > 0.0) {
            return Err(ServoFault::InvalidPeriod { joint, period_s });
        }
        let raw_error = setpoint.position - feedback;
        self.monitor.check(raw_error, setpoint.velocity)?;

        let g = &self.gains;
        let error = apply_deadband(raw_error, g.deadband);
        let derivative = match self.previous_error {
            Some(previous) => (error - previous) / period_s,
            None => 0.0,
        };
        let mut integral = self.integral + error * period_s;
        if let Some(limit) = g.integrator_limit {
            integral = integral.clamp(-limit, limit);
        }
        let without_integral = g.bias
            + g.p * error
            + g.d * derivative
            + g.velocity_ff * setpoint.velocity
            + g.acceleration_ff * setpoint.acceleration;
        let mut unlimited = without_integral + g.i * integral;
        let mut output = limit_output(unlimited, g.output_limit);
        // Anti-windup: while saturated, do not integrate in the direction that deepens it.
        if output != unlimited && (unlimited - output) * error > 0.0 {
            integral = self.integral;
            unlimited = without_integral + g.i * integral;
            output = limit_output(unlimited, g.output_limit);
        }
        if !output.is_finite() || !integral.is_finite() {
            return Err(ServoFault::NonFiniteOutput { joint });
        }
        self.integral = integral;
        self.previous_error = Some(error);
        self.output = output;
        Ok(output)
    }

    /// The joint index this controller names in its faults.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn joint(&self) -> usize {
        self.monitor.joint()
    }

    /// The error integral (units·s).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn integral(&self) -> f64 {
        self.integral
    }

    /// The last output (units/s).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn output(&self) -> f64 {
        self.output
    }

    /// The following-error monitor (last error, maximum, limits).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn following_error(&self) -> &FollowingErrorMonitor {
        &self.monitor
    }

    /// The gains in force.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn gains(&self) -> &PidGains {
        &self.gains
    }

    /// Replaces the gains (validated), keeping the loop's state: for tuning while running.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn set_gains(&mut self, gains: PidGains) -> Result<(), ConfigError> {
        gains.validate().map_err(|e| e.within("gains"))?;
        self.gains = gains;
        Ok(())
    }
}

fn apply_deadband(error: f64, deadband: f64) -> f64 {
    if error > deadband {
        error - deadband
    } else if error < -deadband {
        error + deadband
    } else {
        0.0
    }
}

fn limit_output(value: f64, limit: Option<f64>) -> f64 {
    match limit {
        Some(limit) => value.clamp(-limit, limit),
        None => value,
    }
}
