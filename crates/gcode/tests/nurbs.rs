//! G5.2/G5.3 NURBS blocks beyond what rs274 shows (it prints only the number of control
//! points): the control points, weights and order of the canonical curve, worked out by
//! hand from the LinuxCNC manual and interp_convert.cc, and the words refused on purpose.

use rtcnc_gcode::canon::{CanonCommand, Nurbs, NurbsPoint, Units};
use rtcnc_gcode::{ErrorKind, GcodeError, Interpreter, Parameters, Settings, ToolTable};

fn run(text: &str) -> (Vec<CanonCommand>, Option<GcodeError>) {
    let mut it = Interpreter::new(Settings::default(), ToolTable::new(), Parameters::new());
    it.open_text("nurbs.ngc", text).unwrap();
    let mut out = Vec::new();
    for c in &mut it {
        match c {
            Ok(c) => out.push(c.command),
            Err(e) => return (out, Some(e)),
        }
    }
    (out, None)
}

fn curves(out: &[CanonCommand]) -> Vec<Nurbs> {
    out.iter()
        .filter_map(|c| match c {
            CanonCommand::NurbsFeed(n) => Some(n.clone()),
            _ => None,
        })
        .collect()
}

fn p(x: f64, y: f64, weight: f64) -> NurbsPoint {
    NurbsPoint { x, y, weight }
}

#[test]
fn the_manual_example_gives_its_five_weighted_points_from_the_current_point() {
    let (out, err) =
        run("G0 X0 Y0\nF10\nG5.2 P1 L3\nX0 Y1 P1\nX2 Y2 P1\nX2 Y0 P1\nX0 Y0 P2\nG5.3\nG1 X1\nM2\n");
    assert_eq!(err, None);
    let c = curves(&out);
    assert_eq!(
        c,
        vec![Nurbs {
            order: 3,
            points: vec![
                p(0.0, 0.0, 1.0),
                p(0.0, 1.0, 1.0),
                p(2.0, 2.0, 1.0),
                p(2.0, 0.0, 1.0),
                p(0.0, 0.0, 2.0),
            ],
        }]
    );
    // G1 after G5.3 starts from the last control point.
    assert!(out.contains(&CanonCommand::StraightFeed(rtcnc_gcode::Pose {
        x: 1.0,
        ..rtcnc_gcode::Pose::ZERO
    })));
}

#[test]
fn p_alone_weights_the_start_and_incremental_points_are_relative_to_the_start() {
    // G91: the position moves only at G5.3, so every point is relative to (5, 5).
    let (out, err) = run(
        "G21 G91 F100\nG0 X5 Y5\nG5.2 P3 L4\nX1 Y1 P1\nX2 Y2 P0.5\nX3 Y0 P2\nG5.3\nG1 X1\nM2\n",
    );
    assert_eq!(err, None);
    assert_eq!(
        curves(&out),
        vec![Nurbs {
            order: 4,
            points: vec![
                p(5.0, 5.0, 3.0),
                p(6.0, 6.0, 1.0),
                p(7.0, 7.0, 0.5),
                p(8.0, 5.0, 2.0),
            ],
        }]
    );
    assert!(out.contains(&CanonCommand::StraightFeed(rtcnc_gcode::Pose {
        x: 9.0,
        y: 5.0,
        ..rtcnc_gcode::Pose::ZERO
    })));
}

#[test]
fn an_order_of_three_or_less_keeps_the_order_in_force() {
    let (out, err) = run("F100\nG5.2 X1 Y1 P1 L5\nX2 Y1 P1\nX3 Y2 P1 L2\nX4 Y2 P1\nG5.3\nM2\n");
    assert_eq!(err, None);
    assert_eq!(curves(&out)[0].order, 5);
}

#[test]
fn a_point_on_the_g52_line_without_p_weighs_one_as_the_manual_says() {
    // LinuxCNC 2.9's code takes -1 there; its manual says the default weight is 1.
    let (out, err) = run("F100\nG5.2 X1 Y1\nX2 Y0 P1\nG5.3\nM2\n");
    assert_eq!(err, None);
    assert_eq!(curves(&out)[0].points[1], p(1.0, 1.0, 1.0));
}

#[test]
fn words_linuxcnc_would_drop_are_refused() {
    for (text, letter) in [
        ("F100\nG5.2 X1 Y1 P1 Z2\nX2 Y0 P1\nG5.3\nM2\n", "Z"),
        ("F100\nG5.2 X1 Y1 P1\nX2 Y0 P1 A3\nG5.3\nM2\n", "A"),
        ("F100\nG5.2 X1 Y1 P0\nX2 Y0 P1\nG5.3\nM2\n", "weight"),
    ] {
        let (out, err) = run(text);
        let err = err.unwrap_or_else(|| panic!("{text}: no error"));
        assert!(err.message.contains(letter), "{err}");
        assert!(curves(&out).is_empty());
    }
}

#[test]
fn a_nurbs_with_cutter_compensation_on_is_refused() {
    let (_, err) = run("G21 F100 G0 X0 Y0\nG41.1 D2\nG1 X5\nG5.2 X6 Y1 P1\nX7 Y0 P1\nG5.3\nM2\n");
    let err = err.unwrap();
    assert_eq!(err.kind, ErrorKind::State);
    assert_eq!(err.line, 4);
}

#[test]
fn the_curve_prints_as_rs274_does_and_converts_to_mm() {
    let curve = CanonCommand::NurbsFeed(Nurbs {
        order: 3,
        points: vec![p(0.0, 0.0, 1.0), p(1.0, 2.0, 0.5), p(2.0, 0.0, 1.0)],
    });
    let mut v = Vec::new();
    rtcnc_gcode::Canon {
        source: Default::default(),
        command: curve.clone(),
    }
    .write_rs274(&mut v, false);
    assert_eq!(String::from_utf8(v).unwrap(), "NURBS_FEED(3, ...)\n");
    assert_eq!(
        curve.to_mm(Units::Inches),
        CanonCommand::NurbsFeed(Nurbs {
            order: 3,
            points: vec![p(0.0, 0.0, 1.0), p(25.4, 50.8, 0.5), p(50.8, 0.0, 1.0)],
        })
    );
}
