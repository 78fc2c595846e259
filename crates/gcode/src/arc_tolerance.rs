//! The tolerance on the radius of centre-format arcs: LinuxCNC 2.9's rule, defined once for
//! the interpreter (which refuses an arc outside it) and for whoever runs the arc (the
//! kernel passes [`ArcRadiusTolerance::largest_difference`] to the planner, which runs an
//! arc within it as a spiral and refuses one outside it).

use crate::canon::Units;

/// How far the distance from an arc's centre to its end point may differ from the distance
/// to its start point, in the program's units. LinuxCNC 2.9 (`interp_arc.cc`,
/// `interp_internal.hh`; checked against its `rs274`) refuses an arc when the difference
/// exceeds 100 × `absolute`, or when it exceeds `absolute` and `relative` × the larger of
/// the two radii. `absolute` is `CENTER_ARC_RADIUS_TOLERANCE_MM` (2·0.01·√2 mm) or
/// `_INCH` (2·0.001·√2 in), so that end points and centres rounded to 0.01 mm or 0.001 in
/// pass; `relative` is `SPIRAL_RELATIVE_TOLERANCE` (0.1 %). Within it the arc is a spiral:
/// its radius changes linearly with the angle from the start radius to the end radius.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcRadiusTolerance {
    /// Difference always accepted (program units).
    pub absolute: f64,
    /// Difference accepted relative to the larger radius, up to 100 × `absolute`.
    pub relative: f64,
}

impl ArcRadiusTolerance {
    /// LinuxCNC's default in millimetre programs (G21).
    pub const MM: ArcRadiusTolerance = ArcRadiusTolerance {
        absolute: 2.0 * 0.01 * std::f64::consts::SQRT_2,
        relative: SPIRAL_RELATIVE_TOLERANCE,
    };
    /// LinuxCNC's default in inch programs (G20).
    pub const INCH: ArcRadiusTolerance = ArcRadiusTolerance {
        absolute: 2.0 * 0.001 * std::f64::consts::SQRT_2,
        relative: SPIRAL_RELATIVE_TOLERANCE,
    };

    /// LinuxCNC's default for `units`.
    pub fn default_for(units: Units) -> ArcRadiusTolerance {
        match units {
            Units::Mm => ArcRadiusTolerance::MM,
            Units::Inches => ArcRadiusTolerance::INCH,
        }
    }

    /// Whether an arc whose start and end radii are `r1` and `r2` is accepted.
    pub fn accepts(&self, r1: f64, r2: f64) -> bool {
        (r1 - r2).abs() <= self.largest_difference(r1.max(r2))
    }

    /// The largest difference between the start and end radius accepted when the larger
    /// of them is `r_max`: `absolute`, or `relative` × `r_max` up to 100 × `absolute`.
    pub fn largest_difference(&self, r_max: f64) -> f64 {
        self.absolute
            .max((self.relative * r_max).min(ABSOLUTE_CAP * self.absolute))
    }
}

/// LinuxCNC's `SPIRAL_RELATIVE_TOLERANCE`.
const SPIRAL_RELATIVE_TOLERANCE: f64 = 0.001;
/// How many times the absolute tolerance the relative one may reach (LinuxCNC refuses any
/// difference beyond `100 * spiral_abs_tolerance`).
const ABSOLUTE_CAP: f64 = 100.0;

#[cfg(test)]
mod tests {
    use super::*;

    /// Boundary cases run through LinuxCNC 2.9's `rs274` (`G2 X.. Y0 I.. J0` from the
    /// origin): accepted or refused with "Radius to end of arc differs from radius to
    /// start".
    #[test]
    fn accepts_what_rs274_accepts() {
        // (units, start radius = I, end X, rs274 accepted)
        let cases = [
            (Units::Mm, 10.0, 20.02, true),     // 0.02 mm, 0.2 %
            (Units::Mm, 10.0, 20.028, true),    // 0.028 mm, under 0.0283
            (Units::Mm, 10.0, 20.03, false),    // 0.03 mm and 0.3 %
            (Units::Mm, 1000.0, 2000.5, true),  // 0.5 mm, 0.05 %
            (Units::Mm, 100.0, 200.05, true),   // 0.05 mm, 0.05 %
            (Units::Mm, 100.0, 200.25, false),  // 0.25 mm, 0.25 %
            (Units::Mm, 5000.0, 10002.8, true), // 2.8 mm, under 100 × 0.0283
            (Units::Mm, 5000.0, 10002.9, false),
            (Units::Mm, 0.02, 0.06, true), // r 0.02 -> 0.04: 0.02 mm, 50 %
            (Units::Inches, 10.0, 20.003, true), // 0.003 in, 0.03 %
            (Units::Inches, 10.0, 20.0028, true),
            (Units::Inches, 500.0, 1000.28, true), // 0.28 in, under 100 × 0.00283
            (Units::Inches, 500.0, 1000.29, false),
        ];
        for (units, r1, end, accepted) in cases {
            let r2 = end - r1;
            assert_eq!(
                ArcRadiusTolerance::default_for(units).accepts(r1, r2),
                accepted,
                "{units:?} r1 {r1} r2 {r2}"
            );
        }
    }

    #[test]
    fn the_largest_difference_is_the_boundary_of_acceptance() {
        let t = ArcRadiusTolerance::MM;
        for r in [1.0, 28.0, 100.0, 2828.0, 1e4] {
            let d = t.largest_difference(r);
            assert!(t.accepts(r, r - d * (1.0 - 1e-9)), "{r}");
            assert!(!t.accepts(r, r - d * (1.0 + 1e-9)), "{r}");
        }
        assert_eq!(t.largest_difference(1.0), t.absolute);
        assert_eq!(t.largest_difference(100.0), 0.1);
        assert_eq!(t.largest_difference(1e5), 100.0 * t.absolute);
    }
}
