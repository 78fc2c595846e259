//! On-line use: a set-point generator that advances one servo period at a time and accepts a
//! new target at any moment. A new target is planned from the current set-point (position,
//! velocity and acceleration), so a target change mid-move stays time-optimal and
//! jerk-limited: this is the "on-line target change" of jogging, homing, independent axes
//! and quick stops.

use super::limits::Which;
use super::{
    Limits, OtgError, Profile, Sample, State, Synchronized, position_profile, synchronize,
    synchronize_on_period, synchronize_straight, velocity_profile,
};

/// One axis under on-line control.
///
/// [`OnlineAxis::step`] is real-time safe (no allocation, bounded work). Setting a target
/// computes a new profile: bounded work of a few microseconds, no allocation, so it may run
/// in a real-time task too. If planning fails the old motion continues and the error is
/// returned.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OnlineAxis {
    limits: Limits,
    profile: Profile,
    time: f64,
}

impl OnlineAxis {
    /// An axis at `state`. A state at rest stands still; a moving one is brought to rest as
    /// fast as the limits allow until a target is set (a set-point generator must not keep
    /// accelerating on its own).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(state: State, limits: Limits) -> Result<Self, OtgError> {
        limits.validate()?;
        state.check_finite(Which::Start)?;
        let profile = if state.v == 0.0 && state.a == 0.0 {
            Profile::hold(state)
        } else {
            velocity_profile(state, 0.0, 0.0, &limits)?
        };
        Ok(Self {
            limits,
            profile,
            time: 0.0,
        })
    }

    /// Current set-point.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn sample(&self) -> Sample {
        self.profile.at(self.time)
    }

    fn current_state(&self) -> State {
        let s = self.sample();
        State::new(s.p, s.v, s.a)
    }

    /// Replaces the limits used by the next target (the current motion is not replanned).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_limits(&mut self, limits: Limits) -> Result<(), OtgError> {
        limits.validate()?;
        self.limits = limits;
        Ok(())
    }

    /// Limits in use.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    /// Moves to `target` time-optimally from the current set-point.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_target(&mut self, target: State) -> Result<(), OtgError> {
        let profile = position_profile(self.current_state(), target, &self.limits)?;
        self.start(profile);
        Ok(())
    }

    /// Reaches velocity `v` with acceleration `a` time-optimally, position free (jogging,
    /// feed override).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_velocity(&mut self, v: f64, a: f64) -> Result<(), OtgError> {
        let profile = velocity_profile(self.current_state(), v, a, &self.limits)?;
        self.start(profile);
        Ok(())
    }

    /// Stops as fast as the acceleration and jerk limits allow (velocity and acceleration
    /// zero; the position is where it ends up).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn stop(&mut self) -> Result<(), OtgError> {
        self.set_velocity(0.0, 0.0)
    }

    fn start(&mut self, profile: Profile) {
        self.profile = profile;
        self.time = 0.0;
    }

    /// Advances the clock by `dt` (a servo period) and returns the new set-point. A NaN or
    /// negative `dt` does not move the clock.
    ///
    /// Real-time: yes (no allocation, no blocking).
    #[inline]
    pub fn step(&mut self, dt: f64) -> Sample {
        self.time = advance_clock(self.time, dt, self.profile.duration());
        self.sample()
    }

    /// The time since the current profile started: the clock [`OnlineAxis::step`]
    /// advances.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Puts the clock of the current profile back (or on) to `time`, as returned by
    /// [`OnlineAxis::time`]: a generator that computed set-points ahead goes back to one of
    /// them. A NaN, infinite or negative `time` leaves the clock as it is.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_time(&mut self, time: f64) {
        if time.is_finite() && time >= 0.0 {
            self.time = time;
        }
    }

    /// Whether the current profile has reached its target.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_finished(&self) -> bool {
        self.time >= self.profile.duration()
    }

    /// The profile being followed, and the time since it started.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn profile(&self) -> (&Profile, f64) {
        (&self.profile, self.time)
    }
}

/// Several axes under on-line control whose position targets are reached together.
#[derive(Debug, Clone, Copy)]
pub struct OnlineGroup<const N: usize> {
    limits: [Limits; N],
    motion: Synchronized<N>,
    time: f64,
    period: Option<f64>,
}

impl<const N: usize> OnlineGroup<N> {
    /// Axes at `states`. Axes at rest stand still; moving ones are brought to rest as fast
    /// as their limits allow until targets are set (each on its own: the group's duration is
    /// the longest stop).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(states: [State; N], limits: [Limits; N]) -> Result<Self, OtgError> {
        let mut profiles = [Profile::hold(State::default()); N];
        for (i, slot) in profiles.iter_mut().enumerate() {
            *slot = OnlineAxis::new(states[i], limits[i])?.profile;
        }
        Ok(Self {
            limits,
            motion: Synchronized { profiles },
            time: 0.0,
            period: None,
        })
    }

    /// Rounds the duration of every following move up to a whole number of servo
    /// `period`s, so that moves end exactly on a tick (`None`: no rounding).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_period(&mut self, period: Option<f64>) -> Result<(), OtgError> {
        if let Some(p) = period {
            if !(p.is_finite() && p > 0.0) {
                return Err(OtgError::InvalidLimit {
                    name: "period",
                    requirement: "greater than zero",
                    value: p,
                });
            }
        }
        self.period = period;
        Ok(())
    }

    /// Current set-points.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn sample(&self) -> [Sample; N] {
        self.motion.at(self.time)
    }

    /// Moves every axis to its target from the current set-points, all arriving together.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_targets(&mut self, targets: &[State; N]) -> Result<(), OtgError> {
        let now = self.sample().map(|s| State::new(s.p, s.v, s.a));
        self.motion = match self.period {
            Some(period) => synchronize_on_period(&now, targets, &self.limits, period)?,
            None => synchronize(&now, targets, &self.limits)?,
        };
        self.time = 0.0;
        Ok(())
    }

    /// Moves every axis to its target along the straight line between the current and the
    /// target positions (phase synchronisation; no period rounding). The current motion must
    /// be at rest or along that line, else [`OtgError::NotCollinear`] and nothing changes.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn set_targets_straight(&mut self, targets: &[State; N]) -> Result<(), OtgError> {
        let now = self.sample().map(|s| State::new(s.p, s.v, s.a));
        self.motion = synchronize_straight(&now, targets, &self.limits)?;
        self.time = 0.0;
        Ok(())
    }

    /// Advances the clock by `dt` and returns the new set-points.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn step(&mut self, dt: f64) -> [Sample; N] {
        self.time = advance_clock(self.time, dt, self.motion.duration());
        self.sample()
    }

    /// Whether every axis has reached its target.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn is_finished(&self) -> bool {
        self.time >= self.motion.duration()
    }

    /// Common duration of the current motion.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn duration(&self) -> f64 {
        self.motion.duration()
    }
}

/// Moves the clock on by `dt` (ignored unless positive). A sum of periods that lands within
/// rounding of the end of the motion is the end: a move planned to end on a tick ends on
/// that tick, not one period later.
fn advance_clock(time: f64, dt: f64, end: f64) -> f64 {
    if dt.is_nan() || dt <= 0.0 {
        return time;
    }
    let next = time + dt;
    if (next - end).abs() <= 1e-6 * dt {
        end
    } else {
        next
    }
}
