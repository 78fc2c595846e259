//! One-dimensional jerk-limited kinematics used by the path-speed controller: exact
//! integration of a constant-jerk step and the time-optimal stop from any (v, a).

/// State after `t` seconds of constant jerk `j` from (s, v, a).
#[inline]
pub(crate) fn advance(s: f64, v: f64, a: f64, j: f64, t: f64) -> (f64, f64, f64) {
    (
        s + t * (v + t * (0.5 * a + t * j / 6.0)),
        v + t * (a + 0.5 * j * t),
        a + j * t,
    )
}

/// Whether a state decelerates so hard that the speed reaches zero before the jerk `jmax`
/// can bring the acceleration back to zero (a < 0, a² > 2·jmax·v): no stop without a
/// reversal follows from it at that jerk.
#[inline]
pub(crate) fn over_brakes(v: f64, a: f64, jmax: f64) -> bool {
    a < 0.0 && a * a > 2.0 * jmax * v.max(0.0)
}

/// The time-optimal stop from speed `v` ≥ 0 and acceleration `a` to rest under |acc| ≤ `amax`
/// and |jerk| ≤ `jmax`, without reversing. Returns (distance, duration). When the state
/// already decelerates so hard that the speed reaches zero before the acceleration can be
/// brought back to zero (a < 0, a² > 2·jmax·v), the distance is the one covered until the
/// speed is zero with jerk +jmax (the best possible; the caller treats it as a stop).
pub(crate) fn stop(v: f64, a: f64, amax: f64, jmax: f64) -> (f64, f64) {
    let v = v.max(0.0);
    if over_brakes(v, a, jmax) {
        // v + a t + J t²/2 = 0, smallest root.
        let disc = (a * a - 2.0 * jmax * v).max(0.0);
        let t = ((-a - disc.sqrt()) / jmax).max(0.0);
        let (d, _, _) = advance(0.0, v, a, jmax, t);
        return (d.max(0.0), t);
    }
    let ap2 = jmax * v + 0.5 * a * a;
    let (mut s, mut vv, mut aa, mut time) = (0.0, v, a, 0.0);
    if ap2.sqrt() <= amax {
        let ap = -ap2.sqrt();
        let t1 = ((a - ap) / jmax).max(0.0);
        (s, vv, aa) = advance(s, vv, aa, -jmax, t1);
        let t3 = (-aa / jmax).max(0.0);
        (s, _, _) = advance(s, vv, aa, jmax, t3);
        time += t1 + t3;
        return (s.max(0.0), time);
    }
    // Phase 1 towards -amax (from above with -J, from below with +J).
    let (j1, t1) = if a >= -amax {
        (-jmax, (a + amax) / jmax)
    } else {
        (jmax, (-amax - a) / jmax)
    };
    (s, vv, _) = advance(s, vv, aa, j1, t1);
    aa = -amax;
    let t3 = amax / jmax;
    let dv3 = amax * amax / (2.0 * jmax);
    let t2 = ((vv - dv3) / amax).max(0.0);
    (s, vv, aa) = advance(s, vv, aa, 0.0, t2);
    (s, _, _) = advance(s, vv, aa, jmax, t3);
    time += t1 + t2 + t3;
    (s.max(0.0), time)
}

/// State after following the time-optimal stop of [`stop`] for `t` seconds (at rest
/// afterwards). Returns (distance, v, a).
pub(crate) fn stop_advance(v: f64, a: f64, amax: f64, jmax: f64, t: f64) -> (f64, f64, f64) {
    let v0 = v.max(0.0);
    // Phases (jerk, duration) of the stop profile.
    let mut phases = [(0.0, 0.0); 3];
    if over_brakes(v0, a, jmax) {
        let disc = (a * a - 2.0 * jmax * v0).max(0.0);
        phases[0] = (jmax, ((-a - disc.sqrt()) / jmax).max(0.0));
    } else {
        let ap2 = jmax * v0 + 0.5 * a * a;
        if ap2.sqrt() <= amax {
            let ap = -ap2.sqrt();
            phases[0] = (-jmax, ((a - ap) / jmax).max(0.0));
            phases[2] = (jmax, -ap / jmax);
        } else {
            let (j1, t1) = if a >= -amax {
                (-jmax, (a + amax) / jmax)
            } else {
                (jmax, (-amax - a) / jmax)
            };
            let (_, v1, _) = advance(0.0, v0, a, j1, t1);
            let dv3 = amax * amax / (2.0 * jmax);
            phases[0] = (j1, t1);
            phases[1] = (0.0, ((v1 - dv3) / amax).max(0.0));
            phases[2] = (jmax, amax / jmax);
        }
    }
    let (mut s, mut vv, mut aa) = (0.0, v0, a);
    let mut left = t;
    for (j, d) in phases.iter() {
        if left <= 0.0 {
            break;
        }
        let dt = d.min(left);
        (s, vv, aa) = advance(s, vv, aa, *j, dt);
        left -= dt;
    }
    if left > 0.0 {
        return (s, 0.0, 0.0);
    }
    (s, vv.max(0.0), aa)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Stop from cruise at v with a = 0: closed form d = v (v/A + A/J) / 2 when v ≥ A²/J.
    #[test]
    fn stop_from_cruise_matches_closed_form() {
        let (v, amax, jmax) = (100.0, 1000.0, 50_000.0);
        let (d, t) = stop(v, 0.0, amax, jmax);
        let t_ref = v / amax + amax / jmax;
        assert!((t - t_ref).abs() < 1e-12, "{t} {t_ref}");
        assert!((d - v * t_ref / 2.0).abs() < 1e-12, "{d}");
    }

    /// Stop without a constant-deceleration phase: v < A²/J, time 2 sqrt(v/J), distance v·t/2.
    #[test]
    fn short_stop_is_pure_jerk() {
        let (v, amax, jmax) = (10.0, 1000.0, 50_000.0);
        let (d, t) = stop(v, 0.0, amax, jmax);
        let t_ref = 2.0 * (v / jmax).sqrt();
        assert!((t - t_ref).abs() < 1e-12);
        assert!((d - v * t_ref / 2.0).abs() < 1e-12);
    }
}
