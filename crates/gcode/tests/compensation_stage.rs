//! The compensation stage on hand-built streams, against hand-computed geometry.

use proptest::prelude::*;
use rtcnc_gcode::canon::{
    Arc, Canon, CanonCommand as C, CompensationSide, Plane, Pose, ProbeKind, Source, Spline, Units,
};
use rtcnc_gcode::compensation::{CompError, CompErrorKind, Compensate, Compensator};

const EPS: f64 = 1e-9;

fn at(line: u32, command: C) -> Canon {
    Canon {
        source: Source {
            file: 0,
            line,
            n: None,
        },
        command,
    }
}

fn xy(x: f64, y: f64) -> Pose {
    Pose { x, y, ..Pose::ZERO }
}

fn feed(x: f64, y: f64) -> C {
    C::StraightFeed(xy(x, y))
}

fn start(side: CompensationSide, radius: f64) -> C {
    C::StartCutterRadiusCompensation {
        side,
        radius,
        orientation: 0,
    }
}

fn arc(end: [f64; 2], centre: [f64; 2], rotation: i32) -> C {
    C::ArcFeed(Arc {
        first_end: end[0],
        second_end: end[1],
        first_axis: centre[0],
        second_axis: centre[1],
        rotation,
        axis_end_point: 0.0,
        a: 0.0,
        b: 0.0,
        c: 0.0,
        u: 0.0,
        v: 0.0,
        w: 0.0,
    })
}

/// Runs a stream (line numbers 1, 2, ...) through a stage; the output and the error.
fn run(commands: Vec<C>) -> (Vec<Canon>, Option<CompError>) {
    let mut stage = Compensator::new();
    let mut out = Vec::new();
    for (i, c) in commands.into_iter().enumerate() {
        let r = stage.push(at(i as u32 + 1, c));
        out.extend(std::iter::from_fn(|| stage.pop()));
        if let Err(e) = r {
            return (out, Some(e));
        }
    }
    stage.finish();
    out.extend(std::iter::from_fn(|| stage.pop()));
    (out, None)
}

/// The motion commands of an output.
fn moves(out: &[Canon]) -> Vec<C> {
    out.iter()
        .map(|c| c.command.clone())
        .filter(|c| {
            matches!(
                c,
                C::StraightFeed(_) | C::StraightTraverse(_) | C::ArcFeed(_)
            )
        })
        .collect()
}

#[track_caller]
fn assert_feed(c: &C, x: f64, y: f64) {
    match c {
        C::StraightFeed(p) => assert!(
            (p.x - x).abs() < EPS && (p.y - y).abs() < EPS,
            "feed to ({}, {}), expected ({x}, {y})",
            p.x,
            p.y
        ),
        other => panic!("expected a feed to ({x}, {y}), got {other:?}"),
    }
}

#[track_caller]
fn assert_arc(c: &C, end: [f64; 2], centre: [f64; 2], rotation: i32) {
    match c {
        C::ArcFeed(a) => assert!(
            (a.first_end - end[0]).abs() < EPS
                && (a.second_end - end[1]).abs() < EPS
                && (a.first_axis - centre[0]).abs() < EPS
                && (a.second_axis - centre[1]).abs() < EPS
                && a.rotation == rotation,
            "arc {a:?}, expected end {end:?} centre {centre:?} turn {rotation}"
        ),
        other => panic!("expected an arc, got {other:?}"),
    }
}

#[test]
fn entry_move_ends_one_radius_to_the_side_of_the_programmed_end() {
    // From (0, 0) along +X with the tool on the left (+Y), radius 2.
    let (out, err) = run(vec![start(CompensationSide::Left, 2.0), feed(10.0, 0.0)]);
    assert!(err.is_none());
    let m = moves(&out);
    assert_eq!(m.len(), 1);
    assert_feed(&m[0], 10.0, 2.0);
    // A diagonal entry: the offset is perpendicular to the move, on the right.
    let (out, _) = run(vec![
        start(CompensationSide::Right, 2.0_f64.sqrt()),
        feed(5.0, 5.0),
    ]);
    assert_feed(&moves(&out)[0], 6.0, 4.0);
}

#[test]
fn entry_starts_from_the_position_the_stage_is_given() {
    let mut stage = Compensator::new();
    stage.set_position(xy(10.0, -10.0));
    stage
        .push(at(1, start(CompensationSide::Left, 1.0)))
        .expect("start");
    stage.push(at(2, feed(10.0, 0.0))).expect("entry");
    stage.finish();
    let m = moves(&std::iter::from_fn(|| stage.pop()).collect::<Vec<_>>());
    // Moving +Y from (10, -10): the left side is -X.
    assert_feed(&m[0], 9.0, 0.0);
}

#[test]
fn convex_corner_gets_an_arc_around_the_programmed_corner() {
    // Tool on the right, path +X then +Y: a left turn with the tool outside.
    let (out, err) = run(vec![
        start(CompensationSide::Right, 1.0),
        feed(10.0, 0.0),
        feed(10.0, 10.0),
    ]);
    assert!(err.is_none());
    let m = moves(&out);
    assert_eq!(m.len(), 3);
    assert_feed(&m[0], 10.0, -1.0);
    // Centre on the corner, from (10, -1) counter-clockwise to (11, 0).
    assert_arc(&m[1], [11.0, 0.0], [10.0, 0.0], 1);
    assert_feed(&m[2], 11.0, 10.0);
    // The corner arc belongs to the block of the move that turns the corner.
    let arc_line = out
        .iter()
        .find(|c| matches!(c.command, C::ArcFeed(_)))
        .map(|c| c.source.line);
    assert_eq!(arc_line, Some(3));
}

#[test]
fn concave_corner_meets_at_the_intersection_of_the_offset_lines() {
    // Tool on the left, path +X then +Y: the tool is inside the corner; y = 1 meets x = 9.
    let (out, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        feed(10.0, 10.0),
    ]);
    assert!(err.is_none());
    let m = moves(&out);
    assert_eq!(m.len(), 2);
    assert_feed(&m[0], 9.0, 1.0);
    assert_feed(&m[1], 9.0, 10.0);
    // A 60 degree concave corner: the previous end moves back r·tan(30°).
    let (out, _) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        feed(15.0, 5.0 * 3.0_f64.sqrt()),
    ]);
    let back = (30.0_f64).to_radians().tan();
    assert_feed(&moves(&out)[0], 10.0 - back, 1.0);
}

#[test]
fn arc_radius_shrinks_inside_and_grows_outside_by_the_tool_radius() {
    // A tangent arc after the entry line, counter-clockwise around (10, 5): with the tool on
    // the left it runs inside (radius 5 - 1), same centre.
    let (out, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        arc([10.0, 10.0], [10.0, 5.0], 1),
    ]);
    assert!(err.is_none());
    let m = moves(&out);
    assert_eq!(m.len(), 2);
    assert_feed(&m[0], 10.0, 1.0);
    assert_arc(&m[1], [10.0, 9.0], [10.0, 5.0], 1);
    // Clockwise around (10, -5): the tool on the left runs outside (radius 5 + 1).
    let (out, _) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        arc([10.0, -10.0], [10.0, -5.0], -1),
    ]);
    assert_arc(&moves(&out)[1], [10.0, -11.0], [10.0, -5.0], -1);
}

#[test]
fn exit_move_goes_to_the_programmed_point() {
    let (out, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        C::StopCutterRadiusCompensation,
        feed(20.0, -5.0),
    ]);
    assert!(err.is_none());
    let m = moves(&out);
    assert_feed(&m[0], 10.0, 1.0);
    assert_feed(&m[1], 20.0, -5.0);
}

#[test]
fn tool_length_offset_passes_through_and_is_not_applied() {
    let offset = Pose {
        z: 12.5,
        ..Pose::ZERO
    };
    let (out, err) = run(vec![
        C::UseToolLengthOffset(offset),
        C::StraightFeed(Pose {
            x: 5.0,
            y: 5.0,
            z: -1.0,
            ..Pose::ZERO
        }),
    ]);
    assert!(err.is_none());
    assert_eq!(out[0].command, C::UseToolLengthOffset(offset));
    assert_eq!(
        out[1].command,
        C::StraightFeed(Pose {
            x: 5.0,
            y: 5.0,
            z: -1.0,
            ..Pose::ZERO
        })
    );
}

#[test]
fn feed_rate_waits_behind_a_held_move_and_a_message_passes_it() {
    let (out, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        C::SetFeedRate(100.0),
        C::Message("hello".into()),
        feed(20.0, 0.0),
    ]);
    assert!(err.is_none());
    let kinds: Vec<&C> = out.iter().map(|c| &c.command).collect();
    assert!(matches!(kinds[0], C::StartCutterRadiusCompensation { .. }));
    assert!(matches!(kinds[1], C::Message(_)), "{kinds:?}");
    assert!(matches!(kinds[2], C::StraightFeed(_)));
    assert_eq!(kinds[3], &C::SetFeedRate(100.0));
    assert!(matches!(kinds[4], C::StraightFeed(_)));
}

#[test]
fn zero_radius_and_negative_radius() {
    // Radius 0: the path is not changed.
    let (out, _) = run(vec![
        start(CompensationSide::Left, 0.0),
        feed(10.0, 0.0),
        feed(10.0, 10.0),
    ]);
    let m = moves(&out);
    assert_feed(&m[0], 10.0, 0.0);
    assert_feed(&m[1], 10.0, 10.0);
    // A negative radius (a tool smaller than the nominal one) works on the other side.
    let (out, _) = run(vec![start(CompensationSide::Left, -1.0), feed(10.0, 0.0)]);
    assert_feed(&moves(&out)[0], 10.0, -1.0);
}

#[test]
fn lathe_plane_offsets_in_z_and_x() {
    // G18: the plane's first axis is Z, the second X. From Z0 X0 to Z-10 with the tool on
    // the right of the travel (in the Z-X frame): right of -Z is +X.
    let (out, err) = run(vec![
        C::SelectPlane(Plane::XZ),
        start(CompensationSide::Right, 0.5),
        C::StraightFeed(Pose {
            z: -10.0,
            ..Pose::ZERO
        }),
    ]);
    assert!(err.is_none());
    match &moves(&out)[0] {
        C::StraightFeed(p) => {
            assert!((p.z + 10.0).abs() < EPS && (p.x - 0.5).abs() < EPS, "{p:?}");
        }
        other => panic!("{other:?}"),
    }
}

#[test]
fn errors_carry_linuxcnc_messages_codes_and_lines() {
    let (_, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        C::StopCutterRadiusCompensation,
        arc([20.0, 10.0], [20.0, 0.0], 1),
    ]);
    let err = err.expect("arc after G40");
    assert_eq!(err.kind, CompErrorKind::ArcAfterCompensationOff);
    assert_eq!(err.code(), "C-EXIT");
    assert_eq!(err.at.line, 4);
    assert_eq!(
        err.message(),
        "The move just after exiting cutter compensation mode must be straight, not an arc"
    );
    let (_, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        start(CompensationSide::Left, 1.0),
    ]);
    assert_eq!(err.map(|e| e.kind), Some(CompErrorKind::AlreadyOn));
    let (_, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        C::SelectPlane(Plane::XZ),
    ]);
    assert_eq!(err.map(|e| e.kind), Some(CompErrorKind::PlaneChange));
    let (_, err) = run(vec![
        C::SelectPlane(Plane::YZ),
        start(CompensationSide::Left, 1.0),
    ]);
    assert_eq!(err.map(|e| e.kind), Some(CompErrorKind::WrongPlane));
    let (_, err) = run(vec![start(CompensationSide::Left, f64::NAN)]);
    assert_eq!(err.map(|e| e.kind), Some(CompErrorKind::BadRadius));
}

#[test]
fn buffer_is_bounded() {
    let mut stage = Compensator::with_capacity(8);
    stage
        .push(at(1, start(CompensationSide::Left, 1.0)))
        .expect("start");
    stage.push(at(2, feed(10.0, 0.0))).expect("entry");
    while stage.pop().is_some() {}
    let mut err = None;
    for i in 0..20 {
        if let Err(e) = stage.push(at(3 + i, C::Comment("waits".into()))) {
            err = Some(e);
            break;
        }
    }
    let err = err.expect("the buffer fills");
    assert_eq!(err.kind, CompErrorKind::BufferFull);
    assert_eq!(stage.held(), 0, "held commands are dropped after an error");
    assert!(!stage.is_active());
}

#[test]
fn program_stop_releases_the_held_move_and_a_concave_corner_after_it_is_refused() {
    let (out, err) = run(vec![
        start(CompensationSide::Left, 1.0),
        feed(10.0, 0.0),
        C::ProgramStop,
        feed(10.0, 10.0),
    ]);
    assert!(matches!(out[1].command, C::StraightFeed(_)));
    assert_eq!(out[2].command, C::ProgramStop);
    assert_eq!(err.map(|e| e.kind), Some(CompErrorKind::ConcaveAfterStop));
}

#[test]
fn closing_percent_releases_the_last_move() {
    // rs274 prints FINISH() and drops the held move; the stage keeps it.
    let (out, err) = run(vec![
        start(CompensationSide::Left, 2.0),
        feed(10.0, 0.0),
        C::Finish,
    ]);
    assert!(err.is_none());
    assert_feed(&out[1].command, 10.0, 2.0);
    assert_eq!(out[2].command, C::Finish);
}

#[test]
fn adapter_yields_in_order_and_maps_errors() {
    let input: Vec<Result<Canon, String>> = vec![
        Ok(at(1, start(CompensationSide::Left, 1.0))),
        Ok(at(2, feed(10.0, 0.0))),
        Err("interpreter error".to_string()),
        Ok(at(4, C::StopCutterRadiusCompensation)),
        Ok(at(5, arc([20.0, 10.0], [20.0, 0.0], 1))),
        Ok(at(6, feed(30.0, 0.0))),
    ];
    let out: Vec<Result<Canon, String>> =
        Compensate::new(input.into_iter(), |e: CompError| e.code().to_string()).collect();
    let summary: Vec<String> = out
        .iter()
        .map(|r| match r {
            Ok(c) => format!("{}", c.source.line),
            Err(e) => e.clone(),
        })
        .collect();
    // The start passes, the held entry move waits behind the upstream error, G40 releases
    // it, the arc after G40 is refused, the stream goes on.
    assert_eq!(summary, ["1", "interpreter error", "2", "4", "C-EXIT", "6"]);
}

fn any_command() -> impl Strategy<Value = C> {
    let coord = -50.0f64..50.0;
    prop_oneof![
        4 => (coord.clone(), coord.clone(), -5.0f64..5.0).prop_map(|(x, y, z)| C::StraightFeed(
            Pose { x, y, z, ..Pose::ZERO }
        )),
        1 => (coord.clone(), coord.clone()).prop_map(|(x, y)| C::StraightTraverse(xy(x, y))),
        3 => (coord.clone(), coord.clone(), coord.clone(), coord.clone(), -2i32..3)
            .prop_map(|(a, b, c, d, r)| arc([a, b], [c, d], r)),
        // Consistent arcs: end on the circle through the start is not required of the stage,
        // but arcs whose end is on the circle exercise the corner code more.
        2 => (coord.clone(), coord.clone(), 0.1f64..20.0, 0.0f64..6.3, prop::bool::ANY)
            .prop_map(|(cx, cy, r, t, ccw)| arc(
                [cx + r * t.cos(), cy + r * t.sin()],
                [cx, cy],
                if ccw { 1 } else { -1 }
            )),
        1 => (prop::bool::ANY, -3.0f64..10.0, 0i32..10).prop_map(|(left, r, o)| {
            C::StartCutterRadiusCompensation {
                side: if left { CompensationSide::Left } else { CompensationSide::Right },
                radius: r,
                orientation: o,
            }
        }),
        1 => Just(C::StopCutterRadiusCompensation),
        1 => prop_oneof![Just(Plane::XY), Just(Plane::XZ), Just(Plane::YZ)].prop_map(C::SelectPlane),
        1 => prop_oneof![Just(Units::Mm), Just(Units::Inches)].prop_map(C::UseLengthUnits),
        1 => (0.0f64..1000.0).prop_map(C::SetFeedRate),
        1 => Just(C::ProgramStop),
        1 => Just(C::ProgramEnd),
        1 => (coord.clone(), coord).prop_map(|(x, y)| C::SetG92Offset(xy(x, y))),
        1 => (-5.0f64..5.0).prop_map(|z| C::UseToolLengthOffset(Pose { z, ..Pose::ZERO })),
        1 => Just(C::Comment("c".into())),
        1 => prop_oneof![
            Just(C::Finish),
            Just(C::OnReset),
            Just(C::OptionalProgramStop),
            Just(C::PalletShuttle),
            Just(C::TurnProbeOn),
            Just(C::FeedOverride(false)),
            Just(C::Message("m".into())),
            Just(C::Dwell(0.5)),
            Just(C::SetNaivecamTolerance(0.01)),
            Just(C::SetXyRotation(30.0)),
            Just(C::SetG5xOffset { index: 1, offset: xy(1.0, 2.0) }),
            Just(C::SplineFeed(Spline { order: 3, p1: [1.0, 1.0], p2: [1.0, 1.0], end: [2.0, 0.0] })),
            Just(C::StraightProbe { end: xy(3.0, 3.0), kind: ProbeKind::Toward }),
            Just(C::SetDigitalOutput { index: 1, on: true, synchronized: true }),
        ],
        // Degenerate numbers: the stage may refuse them, never panic.
        1 => prop_oneof![Just(f64::NAN), Just(f64::INFINITY), Just(0.0), Just(1e300)]
            .prop_map(|v| C::StraightFeed(xy(v, -v))),
        1 => prop_oneof![Just(f64::NAN), Just(0.0), Just(1e-300)]
            .prop_map(|v| arc([v, v], [0.0, 0.0], 1)),
    ]
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: if cfg!(debug_assertions) { 256 } else { 4096 },
        ..ProptestConfig::default()
    })]

    /// Whatever the stream, the stage never panics, never holds more than its capacity and
    /// releases everything it holds at the end.
    #[test]
    fn stage_never_panics(commands in prop::collection::vec(any_command(), 0..60)) {
        let mut stage = Compensator::with_capacity(16);
        for (i, c) in commands.into_iter().enumerate() {
            let _ = stage.push(at(i as u32, c));
            prop_assert!(stage.held() <= 16);
            while stage.pop().is_some() {}
        }
        stage.finish();
        while stage.pop().is_some() {}
        prop_assert_eq!(stage.held(), 0);
    }
}

proptest! {
    #![proptest_config(ProptestConfig {
        cases: if cfg!(debug_assertions) { 128 } else { 2048 },
        ..ProptestConfig::default()
    })]

    /// Without G41/G42 the stage is transparent: every command comes out unchanged, in order,
    /// at once.
    #[test]
    fn stage_is_transparent_without_compensation(
        commands in prop::collection::vec(
            // A compensation start becomes a comment (filtering would reject too many).
            any_command().prop_map(|c| match c {
                C::StartCutterRadiusCompensation { .. } => C::Comment("no start".into()),
                other => other,
            }),
            0..60,
        )
    ) {
        let mut stage = Compensator::new();
        for (i, c) in commands.into_iter().enumerate() {
            let canon = at(i as u32, c);
            prop_assert!(stage.push(canon.clone()).is_ok());
            // Compared as text: NaN coordinates must come out as NaN too.
            prop_assert_eq!(format!("{:?}", stage.pop()), format!("{:?}", Some(canon)));
            prop_assert_eq!(stage.pop(), None);
        }
    }
}

#[test]
fn a_long_contour_streams_through_one_held_move() {
    // 20 000 moves, every corner alternately convex and concave: the stage never holds more
    // than the move whose end the next move decides, and releases each move once.
    let mut stage = Compensator::with_capacity(4);
    stage
        .push(at(0, start(CompensationSide::Left, 0.5)))
        .expect("start");
    let mut released = 0usize;
    for i in 0..20_000u32 {
        let t = f64::from(i) * std::f64::consts::TAU / 50.0;
        let r = if i % 2 == 0 { 50.0 } else { 47.0 };
        stage
            .push(at(i + 1, feed(r * t.cos(), r * t.sin())))
            .expect("compensable contour");
        assert!(stage.held() <= 1, "holds {}", stage.held());
        released += std::iter::from_fn(|| stage.pop())
            .filter(|c| matches!(c.command, C::StraightFeed(_)))
            .count();
    }
    stage.finish();
    released += std::iter::from_fn(|| stage.pop())
        .filter(|c| matches!(c.command, C::StraightFeed(_)))
        .count();
    assert_eq!(released, 20_000);
}
