//! Straight-line moves of several axes (ruckig's "phase synchronisation"): every axis
//! follows the same one-dimensional profile scaled by its share of the displacement, so the
//! tool moves along the straight line between the positions, as a machinist expects of a
//! multi-axis point-to-point move (no dog-leg).
//!
//! The move is solved once along the line: the path coordinate `s` runs from 0 to the
//! length `L` of the displacement `d`, axis `i` is at `p0_i + u_i s` with `u = d / L`, so
//! its velocity, acceleration and jerk are `u_i` times those of `s`. The limits of `s` are
//! the tightest of every axis's limits divided by `|u_i|`, which keeps every axis inside its
//! own. This is time-optimal for the straight line (and equals ruckig's duration when one
//! axis limits velocity, acceleration and jerk alike; where different axes limit different
//! quantities ruckig falls back to a non-straight move, this one stays straight).

use super::limits::Which;
use super::position::position_profile;
use super::profile::{Phase, Profile};
use super::sync::Synchronized;
use super::{Limits, OtgError, State};

/// Straight-line profiles: all axes go from `start` to `target` along the straight line
/// between the positions and arrive together, time-optimally within every axis's limits.
///
/// The start and target velocities and accelerations must lie along the line (at rest is
/// always fine); otherwise [`OtgError::NotCollinear`] is returned and
/// [`synchronize`](super::synchronize) is the alternative. Cost: one single-axis profile.
///
/// Real-time: yes (no allocation, no blocking).
pub fn synchronize_straight<const N: usize>(
    start: &[State; N],
    target: &[State; N],
    limits: &[Limits; N],
) -> Result<Synchronized<N>, OtgError> {
    for i in 0..N {
        limits[i].validate()?;
        start[i].check_finite(Which::Start)?;
        target[i].check_finite(Which::Target)?;
    }
    let length = (0..N)
        .map(|i| (target[i].p - start[i].p).powi(2))
        .sum::<f64>()
        .sqrt();
    if !length.is_finite() {
        return Err(OtgError::NonFiniteInput {
            name: "move length",
            value: length,
        });
    }
    if length == 0.0 {
        // No line to move along: only a standstill is straight.
        for i in 0..N {
            if start[i] != target[i] || start[i].v != 0.0 || start[i].a != 0.0 {
                return Err(OtgError::NotCollinear { axis: i });
            }
        }
        return Ok(Synchronized {
            profiles: std::array::from_fn(|i| Profile::hold(start[i])),
        });
    }
    let u: [f64; N] = std::array::from_fn(|i| (target[i].p - start[i].p) / length);
    let along = |f: fn(&State) -> f64, states: &[State; N]| -> Result<f64, OtgError> {
        let s: f64 = (0..N).map(|i| f(&states[i]) * u[i]).sum();
        let scale = (0..N).map(|i| f(&states[i]).abs()).fold(0.0, f64::max);
        for i in 0..N {
            if (f(&states[i]) - s * u[i]).abs() > 1e-9 * scale {
                return Err(OtgError::NotCollinear { axis: i });
            }
        }
        Ok(s)
    };
    let (v0, a0) = (along(|s| s.v, start)?, along(|s| s.a, start)?);
    let (vf, af) = (along(|s| s.v, target)?, along(|s| s.a, target)?);
    let mut line = Limits {
        max_velocity: f64::INFINITY,
        min_velocity: f64::NEG_INFINITY,
        max_acceleration: f64::INFINITY,
        min_acceleration: f64::NEG_INFINITY,
        max_jerk: f64::INFINITY,
    };
    for i in 0..N {
        let (ui, l) = (u[i], &limits[i]);
        if ui == 0.0 {
            continue;
        }
        // Moving along +u, axis i moves along sign(u_i): its upper limit bounds s from
        // above when u_i > 0 and from below when u_i < 0.
        let (v_hi, v_lo, a_hi, a_lo) = if ui > 0.0 {
            (
                l.max_velocity / ui,
                l.min_velocity / ui,
                l.max_acceleration / ui,
                l.min_acceleration / ui,
            )
        } else {
            (
                l.min_velocity / ui,
                l.max_velocity / ui,
                l.min_acceleration / ui,
                l.max_acceleration / ui,
            )
        };
        line.max_velocity = line.max_velocity.min(v_hi);
        line.min_velocity = line.min_velocity.max(v_lo);
        line.max_acceleration = line.max_acceleration.min(a_hi);
        line.min_acceleration = line.min_acceleration.max(a_lo);
        line.max_jerk = line.max_jerk.min(l.max_jerk / ui.abs());
    }
    let path = position_profile(State::new(0.0, v0, a0), State::new(length, vf, af), &line)?;
    let phases: [Phase; 9] = {
        let mut all = [Phase::default(); 9];
        for (slot, phase) in all.iter_mut().zip(path.phases()) {
            *slot = phase;
        }
        all
    };
    let count = path.phase_count();
    let brake_count = path.brake_phase_count();
    let profiles = std::array::from_fn(|i| {
        let scaled: [Phase; 9] = std::array::from_fn(|k| Phase {
            duration: phases[k].duration,
            jerk: phases[k].jerk * u[i],
        });
        Profile::from_phases(start[i], &scaled[..count], brake_count, Some(target[i]))
    });
    Ok(Synchronized { profiles })
}
