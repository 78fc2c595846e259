//! Machine limits per axis, validated once at construction.

use crate::axes::{AXES, Axis};
use crate::error::MotionError;

/// Limits of one axis (mm, mm/s, mm/s², mm/s³; degrees for rotary axes).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct AxisLimits {
    /// Maximum |velocity|.
    pub max_velocity: f64,
    /// Maximum |acceleration|.
    pub max_acceleration: f64,
    /// Maximum |jerk|.
    pub max_jerk: f64,
    /// Lower soft limit (machine coordinates).
    pub min_position: f64,
    /// Upper soft limit.
    pub max_position: f64,
    /// Deceleration allowed for a quick stop (e-stop), ≥ `max_acceleration` typically.
    pub quick_stop_acceleration: f64,
    /// Jerk allowed for a quick stop.
    pub quick_stop_jerk: f64,
}

impl AxisLimits {
    /// Limits with a symmetric envelope and quick-stop values equal to the normal ones.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn new(
        max_velocity: f64,
        max_acceleration: f64,
        max_jerk: f64,
        min: f64,
        max: f64,
    ) -> Self {
        AxisLimits {
            max_velocity,
            max_acceleration,
            max_jerk,
            min_position: min,
            max_position: max,
            quick_stop_acceleration: max_acceleration,
            quick_stop_jerk: max_jerk,
        }
    }
}

/// Limits of the machine: one entry per canonical axis; `None` for an axis the machine lacks
/// (a move that changes it is refused).
#[derive(Debug, Clone, PartialEq)]
pub struct MachineLimits {
    /// Per axis, in [`crate::Axis`] order.
    pub axes: [Option<AxisLimits>; AXES],
}

impl MachineLimits {
    /// A machine with the given axes, all with the same limits.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn uniform(axes: &[Axis], limits: AxisLimits) -> Self {
        let mut m = MachineLimits { axes: [None; AXES] };
        for a in axes {
            m.axes[*a as usize] = Some(limits);
        }
        m
    }

    /// Checks every value; the first bad one is returned as an error.
    ///
    /// Real-time: no (set-up: a refusal allocates its message).
    pub fn validate(&self) -> Result<(), MotionError> {
        for (i, l) in self.axes.iter().enumerate() {
            let Some(l) = l else { continue };
            let name = Axis::ALL[i].letter();
            let positive = [
                ("velocity", l.max_velocity),
                ("acceleration", l.max_acceleration),
                ("jerk", l.max_jerk),
                ("quick-stop acceleration", l.quick_stop_acceleration),
                ("quick-stop jerk", l.quick_stop_jerk),
            ];
            for (what, v) in positive {
                if !(v.is_finite() && v > 0.0) {
                    return Err(MotionError::InvalidLimit {
                        what: format!("axis {name} {what}"),
                        value: v,
                    });
                }
            }
            for (what, v) in [
                ("min position", l.min_position),
                ("max position", l.max_position),
            ] {
                if !v.is_finite() {
                    return Err(MotionError::InvalidLimit {
                        what: format!("axis {name} {what}"),
                        value: v,
                    });
                }
            }
            if l.min_position > l.max_position {
                return Err(MotionError::InvalidLimit {
                    what: format!("axis {name} envelope (min > max)"),
                    value: l.min_position,
                });
            }
        }
        if self.axes.iter().all(|a| a.is_none()) {
            return Err(MotionError::InvalidLimit {
                what: "machine has no axis".into(),
                value: 0.0,
            });
        }
        Ok(())
    }
}

/// The shortest jerk phase the planner plans, in servo periods: an axis's jerk (and
/// quick-stop jerk) is planned no higher than its acceleration over this many periods,
/// since set-points one period apart cannot shape a shorter phase.
pub const MIN_JERK_PHASE_PERIODS: f64 = 2.0;

/// The per-axis numbers the planner works with (absent axes have zero limits).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Lim {
    pub present: [bool; AXES],
    pub v: [f64; AXES],
    pub a: [f64; AXES],
    pub j: [f64; AXES],
    pub min: [f64; AXES],
    pub max: [f64; AXES],
    pub qa: [f64; AXES],
    pub qj: [f64; AXES],
    /// The present axes in axis order (the first `n_present`): the per-axis loops of the
    /// look-ahead run over these only.
    axes: [usize; AXES],
    n_present: usize,
}

impl Lim {
    /// Real-time: yes (no allocation, no blocking).
    pub fn from(m: &MachineLimits) -> Lim {
        let mut l = Lim {
            present: [false; AXES],
            v: [0.0; AXES],
            a: [0.0; AXES],
            j: [0.0; AXES],
            min: [0.0; AXES],
            max: [0.0; AXES],
            qa: [0.0; AXES],
            qj: [0.0; AXES],
            axes: [0; AXES],
            n_present: 0,
        };
        for i in 0..AXES {
            if let Some(a) = m.axes[i] {
                l.present[i] = true;
                l.axes[l.n_present] = i;
                l.n_present += 1;
                l.v[i] = a.max_velocity;
                l.a[i] = a.max_acceleration;
                l.j[i] = a.max_jerk;
                l.min[i] = a.min_position;
                l.max[i] = a.max_position;
                l.qa[i] = a.quick_stop_acceleration;
                l.qj[i] = a.quick_stop_jerk;
            }
        }
        l
    }

    /// Jerk limits no higher than set-points one `servo_period` apart can follow: an axis's
    /// jerk phase (its acceleration over its jerk) lasts at least [`MIN_JERK_PHASE_PERIODS`]
    /// periods, normal and quick-stop limits alike. A higher jerk limit (10^7 mm/s³ against
    /// 1 000 mm/s² at 1 ms, a phase of 0.1 ms) let the planner's stop model brake later than
    /// whole periods allow, and a path then exceeded the acceleration 7 × or stood still.
    /// Lowering the jerk keeps every limit and costs at most a period per speed change.
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn resolve_jerk_at(&mut self, servo_period: f64) {
        let shortest_phase = MIN_JERK_PHASE_PERIODS * servo_period;
        for &i in &self.axes[..self.n_present] {
            self.j[i] = self.j[i].min(self.a[i] / shortest_phase);
            self.qj[i] = self.qj[i].min(self.qa[i] / shortest_phase);
        }
    }

    /// Every axis present, without limits (for checks of a path's shape alone).
    ///
    /// Real-time: yes (no allocation, no blocking).
    pub fn unbounded() -> Lim {
        let mut l = Lim::from(&MachineLimits { axes: [None; AXES] });
        for i in 0..AXES {
            l.present[i] = true;
            l.axes[i] = i;
            l.v[i] = f64::INFINITY;
            l.a[i] = f64::INFINITY;
            l.j[i] = f64::INFINITY;
            l.min[i] = f64::NEG_INFINITY;
            l.max[i] = f64::INFINITY;
            l.qa[i] = f64::INFINITY;
            l.qj[i] = f64::INFINITY;
        }
        l.n_present = AXES;
        l
    }

    /// Indices of the present axes, in axis order.
    ///
    /// Real-time: yes (no allocation, no blocking).
    #[inline]
    pub fn present_axes(&self) -> &[usize] {
        &self.axes[..self.n_present]
    }
}
