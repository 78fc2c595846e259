//! A jerk-limited motion profile: a short list of constant-jerk phases, evaluated in closed
//! form. Evaluation allocates nothing and scans at most [`MAX_PHASES`] phase starts.

use super::State;
use super::check::snap_tolerance;

/// Most phases a profile can have: a brake pre-trajectory of up to two phases followed by
/// up to seven phases (the classic jerk-limited "S-curve").
pub const MAX_PHASES: usize = 9;

/// One phase of constant jerk.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Phase {
    /// Length of the phase (> 0).
    pub duration: f64,
    /// Jerk during the phase: `+jmax`, `0` or `-jmax`.
    pub jerk: f64,
}

/// Position, velocity, acceleration and jerk at one instant.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Sample {
    /// Position.
    pub p: f64,
    /// Velocity.
    pub v: f64,
    /// Acceleration.
    pub a: f64,
    /// Jerk (the jerk of the phase that starts at or before this instant).
    pub j: f64,
}

/// A single-axis motion from a start state to an end state made of constant-jerk phases.
///
/// Times are relative to the start of the profile. Before `0` [`Profile::at`] returns the
/// start state; from [`Profile::duration`] on it returns the exact end (target) state, moved
/// on with its constant acceleration (as a target velocity/acceleration implies).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Profile {
    count: usize,
    brake_count: usize,
    /// Start time of every phase; `begin[count]` is the duration.
    begin: [f64; MAX_PHASES + 1],
    jerk: [f64; MAX_PHASES],
    p: [f64; MAX_PHASES],
    v: [f64; MAX_PHASES],
    a: [f64; MAX_PHASES],
    start: State,
    end: State,
}

impl Profile {
    /// A profile of zero duration that stays at `state` (moving on with its velocity and
    /// acceleration after time zero).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn hold(state: State) -> Self {
        Self {
            count: 0,
            brake_count: 0,
            begin: [0.0; MAX_PHASES + 1],
            jerk: [0.0; MAX_PHASES],
            p: [0.0; MAX_PHASES],
            v: [0.0; MAX_PHASES],
            a: [0.0; MAX_PHASES],
            start: state,
            end: state,
        }
    }

    /// Builds a profile from `start` through `phases` (phases of zero length are dropped).
    /// `brake_phases` says how many of the leading phases are the brake pre-trajectory. The
    /// end state is the integrated one unless `exact_end` gives the exact target, which then
    /// replaces the integrated end (they differ by rounding only).
    pub(crate) fn from_phases(
        start: State,
        phases: &[Phase],
        brake_phases: usize,
        exact_end: Option<State>,
    ) -> Self {
        let mut profile = Self::hold(start);
        let snap = snap_tolerance(start.a, phases);
        let (mut p, mut v, mut a, mut t) = (start.p, start.v, start.a, 0.0);
        for (index, phase) in phases.iter().take(MAX_PHASES).enumerate() {
            if phase.duration <= 0.0 {
                continue;
            }
            if phase.jerk == 0.0 && a.abs() <= snap {
                a = 0.0;
            }
            let i = profile.count;
            profile.begin[i] = t;
            profile.jerk[i] = phase.jerk;
            profile.p[i] = p;
            profile.v[i] = v;
            profile.a[i] = a;
            (p, v, a) = integrate(p, v, a, phase.jerk, phase.duration);
            t += phase.duration;
            profile.count += 1;
            if index < brake_phases {
                profile.brake_count += 1;
            }
        }
        profile.begin[profile.count] = t;
        profile.end = exact_end.unwrap_or(State { p, v, a });
        profile
    }

    /// The same profile with its end state replaced by the exact target it was built for.
    pub(crate) fn with_end(mut self, end: State) -> Self {
        self.end = end;
        self
    }

    /// Total duration (brake pre-trajectory included).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn duration(&self) -> f64 {
        self.begin[self.count]
    }

    /// Duration of the brake pre-trajectory (zero unless the start state broke a limit or
    /// was bound to break one).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn brake_duration(&self) -> f64 {
        self.begin[self.brake_count]
    }

    /// State at time zero.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn start(&self) -> State {
        self.start
    }

    /// State at the end of the profile (the target).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn end(&self) -> State {
        self.end
    }

    /// From time `t` to its end the profile only slows down: its acceleration is negative
    /// at every phase boundary after `t` (a braking S-curve reaches zero acceleration only
    /// at rest, at its end). A profile replanned to a lower speed brakes too, then cruises
    /// (zero acceleration at a boundary) or speeds up again: not this.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn only_slows_after(&self, t: f64) -> bool {
        let end = self.duration();
        let scale = self.at(t).a.abs().max(f64::MIN_POSITIVE);
        (1..self.count)
            .map(|k| self.begin[k])
            .filter(|&b| b > t && b < end)
            .all(|b| self.at(b).a < -1e-9 * scale)
    }

    /// The phases in order, brake phases first.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn phases(&self) -> impl Iterator<Item = Phase> + '_ {
        (0..self.count).map(|i| Phase {
            duration: self.begin[i + 1] - self.begin[i],
            jerk: self.jerk[i],
        })
    }

    pub(crate) fn brake_phase_count(&self) -> usize {
        self.brake_count
    }

    /// Number of phases (brake phases included, zero-length phases excluded).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn phase_count(&self) -> usize {
        self.count
    }

    /// Position, velocity, acceleration and jerk at time `t` (NaN reads as time zero, an
    /// infinite time as the end).
    ///
    /// Cheap and allocation-free: a scan over at most [`MAX_PHASES`] phase starts and a
    /// cubic polynomial. Suitable for every servo period.
    ///
    /// Real-time: yes (no allocation, no blocking).
    #[inline]
    pub fn at(&self, t: f64) -> Sample {
        // A NaN clock must not produce a NaN set-point: it reads as time zero.
        if t.is_nan() || t <= 0.0 {
            let jerk = if self.count > 0 { self.jerk[0] } else { 0.0 };
            return Sample {
                p: self.start.p,
                v: self.start.v,
                a: self.start.a,
                j: jerk,
            };
        }
        let duration = self.begin[self.count];
        if t >= duration {
            let dt = if t.is_finite() { t - duration } else { 0.0 };
            return self.after_end(dt);
        }
        let mut i = 0;
        while i + 1 < self.count && t >= self.begin[i + 1] {
            i += 1;
        }
        let dt = t - self.begin[i];
        let j = self.jerk[i];
        let (p, v, a) = integrate(self.p[i], self.v[i], self.a[i], j, dt);
        Sample { p, v, a, j }
    }

    fn after_end(&self, dt: f64) -> Sample {
        let e = self.end;
        Sample {
            p: e.p + dt * (e.v + 0.5 * e.a * dt),
            v: e.v + e.a * dt,
            a: e.a,
            j: 0.0,
        }
    }

    /// Largest |velocity|, |acceleration| and |jerk| over the whole profile, found exactly
    /// (a velocity extremum inside a phase, where the acceleration crosses zero, included).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn peaks(&self) -> (f64, f64, f64) {
        let mut vpk = self.start.v.abs().max(self.end.v.abs());
        let mut apk = self.start.a.abs().max(self.end.a.abs());
        let mut jpk: f64 = 0.0;
        for i in 0..self.count {
            let (v, a, j) = (self.v[i], self.a[i], self.jerk[i]);
            let d = self.begin[i + 1] - self.begin[i];
            vpk = vpk.max(v.abs());
            apk = apk.max(a.abs());
            jpk = jpk.max(j.abs());
            if j != 0.0 {
                let tz = -a / j;
                if tz > 0.0 && tz < d {
                    vpk = vpk.max((v - 0.5 * a * a / j).abs());
                }
            }
        }
        (vpk, apk, jpk)
    }
}

impl Profile {
    /// Lowest and highest position over the profile, found exactly (inside a phase the
    /// position has an extremum where the velocity crosses zero).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn position_extrema(&self) -> (f64, f64) {
        let mut lo = self.start.p.min(self.end.p);
        let mut hi = self.start.p.max(self.end.p);
        for i in 0..self.count {
            let (p, v, a, j) = (self.p[i], self.v[i], self.a[i], self.jerk[i]);
            let d = self.begin[i + 1] - self.begin[i];
            // v(t) = v + a t + j t²/2 = 0
            let mut roots = [f64::NAN; 2];
            if j != 0.0 {
                let disc = a * a - 2.0 * j * v;
                if disc >= 0.0 {
                    let s = disc.sqrt();
                    roots = [(-a + s) / j, (-a - s) / j];
                }
            } else if a != 0.0 {
                roots[0] = -v / a;
            }
            for t in roots {
                if t > 0.0 && t < d {
                    let (pe, _, _) = integrate(p, v, a, j, t);
                    lo = lo.min(pe);
                    hi = hi.max(pe);
                }
            }
        }
        (lo, hi)
    }
}

/// Moves a state on through a list of phases, snapping rounding-noise acceleration at the
/// start of a constant-acceleration phase to zero exactly as the profile builder and the
/// validator do (so a root found with this agrees with the profile that is built).
pub(crate) fn travel(state: State, phases: &[Phase]) -> State {
    let snap = snap_tolerance(state.a, phases);
    let (mut p, mut v, mut a) = (state.p, state.v, state.a);
    for phase in phases {
        if phase.jerk == 0.0 && phase.duration > 0.0 && a.abs() <= snap {
            a = 0.0;
        }
        (p, v, a) = integrate(p, v, a, phase.jerk, phase.duration);
    }
    State { p, v, a }
}

/// Moves a state on by `t` under constant jerk `j`.
#[inline]
pub(crate) fn integrate(p: f64, v: f64, a: f64, j: f64, t: f64) -> (f64, f64, f64) {
    (
        p + t * (v + t * (0.5 * a + t * (j / 6.0))),
        v + t * (a + 0.5 * j * t),
        a + j * t,
    )
}
