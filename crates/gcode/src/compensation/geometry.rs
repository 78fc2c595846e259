//! Plane-agnostic geometry of cutter radius compensation.
//!
//! Compensation works in the coordinates of the selected plane: `u` is the plane's first axis,
//! `v` its second and `w` the axis normal to it (X Y Z in G17, Z X Y in G18), so that one set
//! of formulas serves the mill and the lathe, exactly as the arguments of `ARC_FEED` do.

use std::f64::consts::{FRAC_PI_2, PI, TAU};

use crate::canon::{CompensationSide, Plane, Pose};

/// A point of the plane.
pub(crate) type P2 = [f64; 2];

/// Angle below which two directions count as the same, and the tolerance of the
/// concave / convex decision (radians; LinuxCNC's `TOLERANCE_CONCAVE_CORNER`).
pub(crate) const CORNER_TOLERANCE: f64 = 0.05;

/// `cos` of the triangle angle below which the entry arc has no usable centre
/// (LinuxCNC's `TOLERANCE_EQUAL`).
pub(crate) const EQUAL_TOLERANCE: f64 = 0.0001;

/// Direction (radians) from `from` to `to`.
pub(crate) fn direction(from: P2, to: P2) -> f64 {
    (to[1] - from[1]).atan2(to[0] - from[0])
}

/// Distance between two points.
pub(crate) fn distance(a: P2, b: P2) -> f64 {
    (b[0] - a[0]).hypot(b[1] - a[1])
}

/// The point `length` away from `p` in direction `angle`.
pub(crate) fn polar(p: P2, length: f64, angle: f64) -> P2 {
    [p[0] + length * angle.cos(), p[1] + length * angle.sin()]
}

/// +π/2 for the left side, -π/2 for the right: the angle from the direction of travel to
/// the side the tool keeps to.
pub(crate) fn side_angle(side: CompensationSide) -> f64 {
    match side {
        CompensationSide::Left => FRAC_PI_2,
        CompensationSide::Right => -FRAC_PI_2,
    }
}

/// True when the tool runs on the inside of an arc turning `turn` (positive CCW).
pub(crate) fn tool_inside_arc(side: CompensationSide, turn: i32) -> bool {
    (side == CompensationSide::Left && turn > 0) || (side == CompensationSide::Right && turn < 0)
}

/// Signed sweep (radians, positive CCW) of an arc from `start` to `end` around `centre`
/// with `turn` turns (LinuxCNC's `find_turn`; 0 for `turn` 0).
pub(crate) fn sweep(start: P2, centre: P2, turn: i32, end: P2) -> f64 {
    if turn == 0 {
        return 0.0;
    }
    let mut alpha = direction(centre, start);
    let mut beta = direction(centre, end);
    if turn > 0 {
        if beta <= alpha {
            beta += TAU;
        }
        beta - alpha + f64::from(turn - 1) * TAU
    } else {
        if alpha <= beta {
            alpha += TAU;
        }
        beta - alpha + f64::from(turn + 1) * TAU
    }
}

/// Where the compensated path of a straight line from `from` to `to` ends: `radius` to the
/// tool's side of `to`, perpendicular to the line.
pub(crate) fn line_offset_end(from: P2, to: P2, radius: f64, side: CompensationSide) -> P2 {
    polar(to, radius, direction(from, to) + side_angle(side))
}

/// How far back along the compensated previous line its end moves at a concave line-line
/// corner whose `beta` (see the corner classification) is given: `r / tan((β + π) / 2)`.
pub(crate) fn concave_retreat(radius: f64, beta: f64) -> f64 {
    radius / ((beta + PI) / 2.0).tan()
}

/// Maps a pose to plane coordinates `(u, v, w)`.
pub(crate) fn to_plane(plane: Plane, p: &Pose) -> [f64; 3] {
    match plane {
        Plane::XZ => [p.z, p.x, p.y],
        _ => [p.x, p.y, p.z],
    }
}

/// Writes plane coordinates `(u, v, w)` back into a pose.
pub(crate) fn from_plane(plane: Plane, uvw: [f64; 3], pose: &mut Pose) {
    match plane {
        Plane::XZ => {
            pose.z = uvw[0];
            pose.x = uvw[1];
            pose.y = uvw[2];
        }
        _ => {
            pose.x = uvw[0];
            pose.y = uvw[1];
            pose.z = uvw[2];
        }
    }
}

/// Shift from the point compensation controls (the centre of the tool nose radius) to the
/// origin of a lathe tool of `orientation` 1-8, in plane coordinates `(Z, X)` (0 and 9 and
/// milling tools: none). The origin is the imaginary tool tip, `radius` off the centre
/// in X and/or Z.
pub(crate) fn lathe_origin_shift(orientation: i32, radius: f64) -> P2 {
    let dx = match orientation {
        1 | 2 | 6 => -radius,
        3 | 4 | 8 => radius,
        _ => 0.0,
    };
    let dz = match orientation {
        2 | 3 | 7 => -radius,
        1 | 4 | 5 => radius,
        _ => 0.0,
    };
    [dz, dx]
}

#[cfg(test)]
mod tests {
    use super::*;

    const EPS: f64 = 1e-12;

    fn close(a: P2, b: P2) -> bool {
        (a[0] - b[0]).abs() < EPS && (a[1] - b[1]).abs() < EPS
    }

    #[test]
    fn line_offset_is_perpendicular_on_the_tool_side() {
        // A line along +X: left is +Y, right is -Y.
        let l = line_offset_end([0.0, 0.0], [10.0, 0.0], 3.0, CompensationSide::Left);
        assert!(close(l, [10.0, 3.0]), "{l:?}");
        let r = line_offset_end([0.0, 0.0], [10.0, 0.0], 3.0, CompensationSide::Right);
        assert!(close(r, [10.0, -3.0]), "{r:?}");
        // A diagonal line (1, 1): left normal is (-1, 1)/sqrt 2.
        let d = line_offset_end(
            [0.0, 0.0],
            [5.0, 5.0],
            2.0_f64.sqrt(),
            CompensationSide::Left,
        );
        assert!(close(d, [4.0, 6.0]), "{d:?}");
    }

    #[test]
    fn sweep_counts_turns_and_direction() {
        let c = [0.0, 0.0];
        // Quarter circle CCW from +X to +Y.
        assert!((sweep([1.0, 0.0], c, 1, [0.0, 1.0]) - FRAC_PI_2).abs() < EPS);
        // The same points CW: three quarters, negative.
        assert!((sweep([1.0, 0.0], c, -1, [0.0, 1.0]) + 1.5 * PI).abs() < EPS);
        // Full circle CCW (start == end), and two turns.
        assert!((sweep([1.0, 0.0], c, 1, [1.0, 0.0]) - TAU).abs() < EPS);
        assert!((sweep([1.0, 0.0], c, 2, [1.0, 0.0]) - 2.0 * TAU).abs() < EPS);
        assert_eq!(sweep([1.0, 0.0], c, 0, [0.0, 1.0]), 0.0);
    }

    #[test]
    fn concave_retreat_of_a_right_angle_is_the_radius() {
        // Left turn of 90 degrees with the tool on the left: beta = -pi/2.
        assert!((concave_retreat(3.0, -FRAC_PI_2) - 3.0).abs() < EPS);
        // A 60 degree left turn: r tan(30 deg).
        let r = concave_retreat(2.0, -PI / 3.0);
        assert!((r - 2.0 * (PI / 6.0).tan()).abs() < EPS);
    }

    #[test]
    fn inside_of_an_arc_depends_on_side_and_direction() {
        assert!(tool_inside_arc(CompensationSide::Left, 1));
        assert!(!tool_inside_arc(CompensationSide::Left, -1));
        assert!(tool_inside_arc(CompensationSide::Right, -2));
        assert!(!tool_inside_arc(CompensationSide::Right, 1));
    }

    #[test]
    fn plane_coordinates_round_trip() {
        let p = Pose {
            x: 1.0,
            y: 2.0,
            z: 3.0,
            ..Pose::ZERO
        };
        assert_eq!(to_plane(Plane::XY, &p), [1.0, 2.0, 3.0]);
        assert_eq!(to_plane(Plane::XZ, &p), [3.0, 1.0, 2.0]);
        let mut q = Pose::ZERO;
        from_plane(Plane::XZ, [3.0, 1.0, 2.0], &mut q);
        assert_eq!(q, p);
    }

    #[test]
    fn lathe_tool_origins() {
        // Orientation 2 (a typical back-turning tool): tip at -X, -Z of the nose centre.
        assert_eq!(lathe_origin_shift(2, 0.4), [-0.4, -0.4]);
        // Orientation 6: only X.
        assert_eq!(lathe_origin_shift(6, 0.4), [0.0, -0.4]);
        assert_eq!(lathe_origin_shift(9, 0.4), [0.0, 0.0]);
        assert_eq!(lathe_origin_shift(0, 0.4), [0.0, 0.0]);
    }
}
