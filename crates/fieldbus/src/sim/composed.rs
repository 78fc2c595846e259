//! A velocity drive's whole cycle in one step, where its sub-steps are linear.
//!
//! Within a cycle of `n` sub-steps a velocity-mode drive in operation enabled runs
//!
//! ```text
//! e = (v_cmd − v)/r          τ = K_p·e + I          I ← I + K_i·e·h
//! v ← v + (v − a/c)·(e^(−ch) − 1)    with a = g·τ − s·f   (s = sgn v, f Coulomb)
//! ```
//!
//! (the motor's exact solution for the held torque, see [`MotorModel`](super::MotorModel)).
//! As long as the torque stays inside its limit (no clamping, no anti-windup) and the
//! velocity keeps its sign (the Coulomb term is a constant), every sub-step is an affine
//! map of the state `(v, I)` and the inputs `(v_cmd before the command delay, v_cmd after
//! it, s·f)`, and so is their composition: each sub-step's velocity and torque and the
//! cycle's end position are fixed linear combinations of
//! `b = (v₀, I₀, v_cmd,prev, v_cmd, s·f)`. [`ComposedCycle`] holds those combinations,
//! built once per sub-step length by running the sub-step formulas on coefficient vectors.
//!
//! A cycle then costs dot products with no dependency from one sub-step to the next,
//! instead of a chain of sub-steps each waiting on the last one's divisions. The conditions
//! are checked on every sub-step's velocity and torque (the velocity is monotonic within a
//! sub-step under a held torque, so equal signs at both ends mean no stop inside it); when
//! one fails the caller runs the sub-steps one by one. The results are those of the
//! sub-steps up to rounding (a few units in the last place).
//!
//! Most cycles are far from either condition's edge, and bounds over all the sub-steps
//! settle them without the two dot products per sub-step. The bounds are taken in the
//! inputs `(v₀, I₀, v_cmd,prev − v₀, v_cmd − v₀, s·f)`, in which a velocity is `v₀` times a
//! coefficient near 1 plus small terms and a torque is small terms only (in `b` the
//! commands and the velocity are large and nearly cancel). They carry a margin far above
//! any rounding of the dot products, so a cycle they settle is one the dot products settle
//! the same way; near an edge they cannot tell, and the dot products decide.

/// The longest cycle, in sub-steps, that is composed (16 at the default 62.5 µs sub-step
/// and 1 ms period; longer cycles run sub-step by sub-step).
pub(crate) const MAX_COMPOSED_SUBSTEPS: usize = 32;

/// Coefficients over `b = (v₀, I₀, v_cmd,prev, v_cmd, s·f)`.
type Coefficients = [f64; 5];

/// The drive's and motor's constants a composition depends on.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct LinearDrive {
    /// Units per radian `r`.
    pub units_per_radian: f64,
    /// Proportional gain `K_p` (N·m per rad/s).
    pub velocity_gain: f64,
    /// Integral gain `K_i` (N·m per rad).
    pub velocity_integral_gain: f64,
    /// Acceleration per torque `g`.
    pub acceleration_per_torque: f64,
    /// Viscous decay rate `c` (1/s).
    pub decay_rate: f64,
}

/// The state after a composed cycle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct ComposedResult {
    pub displacement: f64,
    pub velocity: f64,
    pub velocity_integral: f64,
    /// The torque of the last sub-step.
    pub torque: f64,
}

/// The linear combinations of one cycle shape (sub-step length, count, delayed sub-steps).
#[derive(Debug, Clone)]
pub(crate) struct ComposedCycle {
    step_s: f64,
    substeps: usize,
    delayed: usize,
    /// Velocity at the end of sub-step k (k = 0..substeps).
    velocity: [Coefficients; MAX_COMPOSED_SUBSTEPS],
    /// Torque of sub-step k (k = 0..substeps).
    torque: [Coefficients; MAX_COMPOSED_SUBSTEPS],
    integral: Coefficients,
    displacement: Coefficients,
    bounds: LinearityBounds,
}

/// A margin, relative to the size of the terms, that covers every rounding of the dot
/// products and of the bounds themselves (those are some 1e-15 of it) many times over.
const ROUNDING_MARGIN: f64 = 1e-9;

/// Bounds over a cycle's sub-steps on the coefficients of their velocities and torques, in
/// the inputs `d = (v₀, I₀, v_cmd,prev − v₀, v_cmd − v₀, s·f)`, where the coefficients of
/// `b`'s `(c₀, c₁, c₂, c₃, c₄)` are `(c₀ + c₂ + c₃, c₁, c₂, c₃, c₄)`.
#[derive(Debug, Clone, Copy)]
struct LinearityBounds {
    /// The least coefficient of `v₀` in a velocity (a command held at `v₀` keeps it there,
    /// up to the friction terms: about 1).
    velocity_floor: f64,
    /// The largest magnitude of each other input's coefficient in a velocity (0 for `v₀`).
    velocity_spread: Coefficients,
    /// The largest magnitude of each input's coefficient in a torque.
    torque_reach: Coefficients,
    /// The largest sum of magnitudes each input meets in a dot product over `b`
    /// (`|c₀| + |c₂| + |c₃|` for `v₀`): the size of the terms, which bounds the rounding.
    term_size: Coefficients,
}

impl LinearityBounds {
    /// No bounds: no cycle is settled by them.
    const NONE: Self = Self {
        velocity_floor: f64::NAN,
        velocity_spread: [f64::NAN; 5],
        torque_reach: [f64::NAN; 5],
        term_size: [f64::NAN; 5],
    };

    /// The bounds over the first `substeps` sub-steps.
    fn over(velocities: &[Coefficients], torques: &[Coefficients], substeps: usize) -> Self {
        let in_d = |c: &Coefficients| [c[0] + c[2] + c[3], c[1], c[2], c[3], c[4]];
        let size = |c: &Coefficients| {
            [
                c[0].abs() + c[2].abs() + c[3].abs(),
                c[1].abs(),
                c[2].abs(),
                c[3].abs(),
                c[4].abs(),
            ]
        };
        // `min` and `max` would pass over a NaN: a coefficient that is not finite makes its
        // bound infinite, which settles nothing.
        let widen = |bound: &mut f64, c: f64| {
            *bound = if c.is_finite() {
                bound.max(c)
            } else {
                f64::INFINITY
            };
        };
        let mut bounds = Self {
            velocity_floor: f64::INFINITY,
            velocity_spread: [0.0; 5],
            torque_reach: [0.0; 5],
            term_size: [0.0; 5],
        };
        let velocities = &velocities[..substeps.min(velocities.len())];
        let torques = &torques[..substeps.min(torques.len())];
        for velocity in velocities {
            let c = in_d(velocity);
            bounds.velocity_floor = if c[0].is_finite() {
                bounds.velocity_floor.min(c[0])
            } else {
                f64::NEG_INFINITY
            };
            for (spread, c) in bounds.velocity_spread.iter_mut().zip(c).skip(1) {
                widen(spread, c.abs());
            }
        }
        for torque in torques {
            for (reach, c) in bounds.torque_reach.iter_mut().zip(in_d(torque)) {
                widen(reach, c.abs());
            }
        }
        for c in velocities.iter().chain(torques) {
            for (term, c) in bounds.term_size.iter_mut().zip(size(c)) {
                widen(term, c);
            }
        }
        bounds
    }

    /// Whether every sub-step surely keeps the velocity's sign and its torque strictly
    /// inside `torque_limit` for `b`; false when the bounds cannot tell.
    fn surely_linear(&self, b: &Coefficients, torque_limit: f64) -> bool {
        let d = [
            b[0].abs(),
            b[1].abs(),
            (b[2] - b[0]).abs(),
            (b[3] - b[0]).abs(),
            b[4].abs(),
        ];
        let margin = ROUNDING_MARGIN * dot(&self.term_size, &d);
        // Terms that large could overflow in a dot product.
        if margin.is_nan() || margin >= 1e290 {
            return false;
        }
        // The sign of the velocity's term in v₀ is v₀'s where its coefficient is positive;
        // the other terms may take either sign.
        let slowest = self.velocity_floor * d[0] - dot(&self.velocity_spread, &d) - margin;
        let strongest = dot(&self.torque_reach, &d) + margin;
        slowest > 0.0 && strongest < torque_limit
    }
}

fn axpy(a: f64, x: &Coefficients, y: &Coefficients) -> Coefficients {
    std::array::from_fn(|i| a * x[i] + y[i])
}

fn dot(x: &Coefficients, b: &Coefficients) -> f64 {
    // Two chains, so the additions overlap.
    (x[0] * b[0] + x[2] * b[2] + x[4] * b[4]) + (x[1] * b[1] + x[3] * b[3])
}

impl ComposedCycle {
    /// An empty composition (matches no cycle until [`prepare`](Self::prepare)).
    pub(crate) fn new() -> Self {
        ComposedCycle {
            step_s: f64::NAN,
            substeps: 0,
            delayed: 0,
            velocity: [[0.0; 5]; MAX_COMPOSED_SUBSTEPS],
            torque: [[0.0; 5]; MAX_COMPOSED_SUBSTEPS],
            integral: [0.0; 5],
            displacement: [0.0; 5],
            bounds: LinearityBounds::NONE,
        }
    }

    /// Makes the composition fit `substeps` sub-steps of `step_s`, the first `delayed` of
    /// them under the previous command. Returns false when the cycle is too long to
    /// compose. Rebuilding costs one pass over the sub-steps; it happens only when the
    /// shape changes, so the check that it has not is inlined into every cycle.
    #[inline]
    pub(crate) fn prepare(
        &mut self,
        drive: &LinearDrive,
        step_s: f64,
        substeps: usize,
        delayed: usize,
    ) -> bool {
        if substeps == 0 || substeps > MAX_COMPOSED_SUBSTEPS || !step_s.is_finite() {
            return false;
        }
        if step_s != self.step_s || substeps != self.substeps || delayed != self.delayed {
            self.rebuild(drive, step_s, substeps, delayed);
        }
        true
    }

    /// Builds the composition of `substeps` (1 to [`MAX_COMPOSED_SUBSTEPS`]) sub-steps of
    /// `step_s`, the first `delayed` of them under the previous command.
    #[inline(never)]
    fn rebuild(&mut self, drive: &LinearDrive, step_s: f64, substeps: usize, delayed: usize) {
        let unit =
            |i: usize| -> Coefficients { std::array::from_fn(|j| f64::from(u8::from(i == j))) };
        let mut v = unit(0);
        let mut integral = unit(1);
        let mut displacement = [0.0; 5];
        let coulomb = unit(4);
        let c = drive.decay_rate;
        let decay = (-c * step_s).exp_m1();
        for k in 0..substeps {
            let command = if k < delayed { unit(2) } else { unit(3) };
            let error: Coefficients =
                std::array::from_fn(|i| (command[i] - v[i]) / drive.units_per_radian);
            let torque = axpy(drive.velocity_gain, &error, &integral);
            integral = axpy(drive.velocity_integral_gain * step_s, &error, &integral);
            let net: Coefficients =
                std::array::from_fn(|i| torque[i] * drive.acceleration_per_torque - coulomb[i]);
            if c > 0.0 {
                let terminal: Coefficients = std::array::from_fn(|i| net[i] / c);
                let towards: Coefficients = std::array::from_fn(|i| v[i] - terminal[i]);
                displacement = std::array::from_fn(|i| {
                    displacement[i] + terminal[i] * step_s - towards[i] * decay / c
                });
                v = std::array::from_fn(|i| v[i] + towards[i] * decay);
            } else {
                displacement = std::array::from_fn(|i| {
                    displacement[i] + v[i] * step_s + 0.5 * net[i] * step_s * step_s
                });
                v = std::array::from_fn(|i| v[i] + net[i] * step_s);
            }
            self.torque[k] = torque;
            self.velocity[k] = v;
        }
        self.integral = integral;
        self.displacement = displacement;
        self.bounds = LinearityBounds::over(&self.velocity, &self.torque, substeps);
        self.step_s = step_s;
        self.substeps = substeps;
        self.delayed = delayed;
    }

    /// The cycle from velocity `v0` (not zero) and integral `integral0` under the commands,
    /// the Coulomb friction acceleration `coulomb` and the torque limit; `None` when a
    /// sub-step would clamp its torque or bring the velocity to zero or past it (then the
    /// sub-steps must run one by one).
    #[inline]
    pub(crate) fn run(
        &self,
        v0: f64,
        integral0: f64,
        previous_command: f64,
        command: f64,
        coulomb: f64,
        torque_limit: f64,
    ) -> Option<ComposedResult> {
        let direction = if v0 > 0.0 {
            1.0
        } else if v0 < 0.0 {
            -1.0
        } else {
            return None;
        };
        let b = [
            v0,
            integral0,
            previous_command,
            command,
            direction * coulomb,
        ];
        if !b.iter().all(|x| x.is_finite()) {
            return None;
        }
        let n = self.substeps.min(MAX_COMPOSED_SUBSTEPS);
        if n == 0 {
            return None;
        }
        if !self.bounds.surely_linear(&b, torque_limit) {
            let mut ok = true;
            for (velocity, torque) in self.velocity.iter().zip(&self.torque).take(n) {
                // No early exit: the checks vectorise, and failures are rare.
                ok &= dot(velocity, &b) * direction > 0.0;
                ok &= dot(torque, &b).abs() < torque_limit;
            }
            if !ok {
                return None;
            }
        }
        Some(ComposedResult {
            displacement: dot(&self.displacement, &b),
            velocity: dot(&self.velocity[n - 1], &b),
            velocity_integral: dot(&self.integral, &b),
            torque: dot(&self.torque[n - 1], &b),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drive of 5 mm per revolution, 1e-4 kg·m², 0.002 N·m·s viscous friction, velocity
    /// loop at 400 Hz.
    fn drive() -> LinearDrive {
        let inertia = 1e-4;
        let bandwidth = 2.0 * std::f64::consts::PI * 400.0;
        let units_per_radian = 5.0 / (2.0 * std::f64::consts::PI);
        LinearDrive {
            units_per_radian,
            velocity_gain: inertia * bandwidth,
            velocity_integral_gain: inertia * bandwidth * bandwidth / 4.0,
            acceleration_per_torque: units_per_radian / inertia,
            decay_rate: 0.002 / inertia,
        }
    }

    /// The sub-steps one by one, straight from the model's equations (no stop, no clamp).
    fn stepwise(
        d: &LinearDrive,
        step_s: f64,
        substeps: usize,
        delayed: usize,
        b: [f64; 5],
    ) -> ComposedResult {
        let (mut v, mut integral, mut x, mut torque) = (b[0], b[1], 0.0, 0.0);
        let c = d.decay_rate;
        for k in 0..substeps {
            let command = if k < delayed { b[2] } else { b[3] };
            let e = (command - v) / d.units_per_radian;
            torque = d.velocity_gain * e + integral;
            integral += d.velocity_integral_gain * e * step_s;
            let terminal = (torque * d.acceleration_per_torque - b[4]) / c;
            let decay = (-c * step_s).exp();
            x += terminal * step_s + (v - terminal) * (1.0 - decay) / c;
            v = terminal + (v - terminal) * decay;
        }
        ComposedResult {
            displacement: x,
            velocity: v,
            velocity_integral: integral,
            torque,
        }
    }

    fn close(a: f64, b: f64, scale: f64) -> bool {
        (a - b).abs() <= 1e-12 * scale.max(a.abs()).max(b.abs())
    }

    #[test]
    fn a_composed_cycle_equals_its_sub_steps() {
        let d = drive();
        let coulomb = 0.05 * d.acceleration_per_torque;
        for (substeps, delayed) in [(16, 0), (16, 4), (2, 1), (32, 0), (1, 0)] {
            let step_s = 1e-3 / substeps as f64;
            let mut cycle = ComposedCycle::new();
            assert!(cycle.prepare(&d, step_s, substeps, delayed));
            for (v0, i0, previous, command) in [
                (50.0, 0.01, 50.0, 51.0),
                (-20.0, -0.02, -20.5, -21.0),
                (3.0, 0.0, 3.0, 2.5),
            ] {
                let composed = cycle
                    .run(v0, i0, previous, command, coulomb, 10.0)
                    .expect("no stop, no clamp");
                let s = v0.signum() * coulomb;
                let reference = stepwise(
                    &d,
                    step_s,
                    substeps,
                    delayed,
                    [v0, i0, previous, command, s],
                );
                assert!(
                    close(composed.velocity, reference.velocity, 1.0),
                    "{composed:?} {reference:?}"
                );
                assert!(close(composed.displacement, reference.displacement, 1e-3));
                assert!(close(
                    composed.velocity_integral,
                    reference.velocity_integral,
                    1e-3
                ));
                assert!(close(composed.torque, reference.torque, 1e-3));
            }
        }
    }

    #[test]
    fn the_bounds_settle_a_cycle_only_as_its_sub_steps_would() {
        let d = drive();
        let coulomb = 0.05 * d.acceleration_per_torque;
        let torque_limit = 3.8;
        let mut seed = 0x853c_49e6_748f_ea9b_u64;
        let mut unit = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            (seed >> 11) as f64 / (1u64 << 53) as f64
        };
        for (substeps, delayed) in [(16, 0), (16, 4), (2, 1), (32, 0), (1, 0)] {
            let mut cycle = ComposedCycle::new();
            assert!(cycle.prepare(&d, 1e-3 / substeps as f64, substeps, delayed));
            let (mut settled, mut linear) = (0, 0);
            for _ in 0..20_000 {
                // Speeds from a crawl to a rapid, either way; commands near the speed and
                // sometimes far from it; integrals up to the friction and beyond.
                let v0 = (unit() - 0.5) * 10f64.powf(unit() * 6.0 - 2.0);
                let spread = 10f64.powf(unit() * 4.0 - 3.0);
                let previous = v0 + (unit() - 0.5) * spread;
                let command = v0 + (unit() - 0.5) * spread;
                let integral0 = (unit() - 0.5) * 0.6;
                let direction = v0.signum();
                let b = [v0, integral0, previous, command, direction * coulomb];
                let every_substep = cycle
                    .velocity
                    .iter()
                    .zip(&cycle.torque)
                    .take(substeps)
                    .all(|(v, t)| dot(v, &b) * direction > 0.0 && dot(t, &b).abs() < torque_limit);
                let surely = cycle.bounds.surely_linear(&b, torque_limit);
                assert!(!surely || every_substep, "{substeps} {delayed} {b:?}");
                settled += usize::from(surely);
                linear += usize::from(every_substep);
            }
            // The bounds are there to settle most linear cycles: about 70 % of these random
            // ones, many of them near a stop or the torque limit.
            assert!(settled * 3 > linear * 2, "{settled} of {linear}");
        }
    }

    #[test]
    fn a_cycle_that_clamps_its_torque_or_stops_is_not_composed() {
        let d = drive();
        let mut cycle = ComposedCycle::new();
        assert!(cycle.prepare(&d, 62.5e-6, 16, 0));
        // 100 mm/s of step in the command asks for far more than 0.1 N·m.
        assert_eq!(cycle.run(10.0, 0.0, 10.0, 110.0, 0.0, 0.1), None);
        // Commanded to reverse: the velocity passes through zero within the cycle.
        assert_eq!(cycle.run(0.5, 0.0, -50.0, -50.0, 0.0, 100.0), None);
        // At rest the direction of the friction is not known.
        assert_eq!(cycle.run(0.0, 0.0, 1.0, 1.0, 0.0, 100.0), None);
        // Too many sub-steps to compose.
        assert!(!cycle.prepare(&d, 1e-6, MAX_COMPOSED_SUBSTEPS + 1, 0));
    }
}
