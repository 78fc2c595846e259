//! A move built apart from the planner (`Planner::prepare`, `PreparedMove::build`,
//! `Planner::push_prepared`) is the move `Planner::push` takes: the same set-points bit for
//! bit, the same errors; a build taken before the planner's geometry changed is refused and
//! leaves the planner as it was.

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, MachineLimits, MotionError, MotionState, Move, PathMode,
    Planner, Preparation, PreparedMove, TrivialKinematics,
};

fn p2(x: f64, y: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p
}

fn planner(window: usize) -> Planner<TrivialKinematics> {
    let lim = AxisLimits::new(100.0, 1000.0, 50_000.0, -100.0, 300.0);
    Planner::new(
        &MachineLimits::uniform(&[Axis::X, Axis::Y], lim),
        TrivialKinematics::identity(&[Axis::X, Axis::Y]),
        1e-3,
        window,
        [0.0; AXES],
    )
    .unwrap()
}

/// The bracket's outline (examples/bracket.ngc) at F 20 mm/s in G64 P0.01: lines into
/// tangent arcs (the curvature steps, blended), a sharp corner (blended), and a line.
fn outline() -> Vec<Move> {
    let mode = PathMode::Blend {
        tolerance: 0.01,
        merge_tolerance: 0.0,
    };
    let z = [0.0, 0.0, 1.0];
    vec![
        Move::line(p2(60.0, 0.0), 20.0, mode, 1),
        Move::arc(p2(65.0, 5.0), [60.0, 5.0, 0.0], z, 0, 20.0, mode, 2),
        Move::line(p2(65.0, 40.0), 20.0, mode, 3),
        Move::arc(p2(60.0, 45.0), [60.0, 40.0, 0.0], z, 0, 20.0, mode, 4),
        Move::line(p2(5.0, 45.0), 20.0, mode, 5),
        Move::line(p2(0.0, 0.0), 20.0, mode, 6),
    ]
}

fn run_out(pl: &mut Planner<TrivialKinematics>) -> Vec<[u64; 2]> {
    pl.flush();
    let mut j = [0.0; 2];
    let mut out = Vec::new();
    for _ in 0..100_000 {
        let st = pl.next(&mut j);
        out.push([st.axes[0].to_bits(), st.axes[1].to_bits()]);
        if st.state == MotionState::Idle {
            return out;
        }
    }
    panic!("not at rest after 100 s");
}

/// Prepares, builds and appends `mv` as the kernel's look-ahead does.
fn push_built(
    pl: &mut Planner<TrivialKinematics>,
    staging: &mut PreparedMove,
    mv: &Move,
    key: u64,
) -> Result<(), MotionError> {
    assert_eq!(pl.preparation(staging, key), Preparation::Stale);
    pl.prepare(mv, key, staging);
    assert_eq!(pl.preparation(staging, key), Preparation::Copied);
    assert!(staging.build_due());
    staging.build();
    assert!(!staging.build_due());
    assert_eq!(pl.preparation(staging, key), Preparation::Built);
    pl.push_prepared(staging)
}

#[test]
fn a_move_built_apart_runs_as_the_same_move_pushed() {
    let mut pushed = planner(256);
    for mv in &outline() {
        pushed.push(mv).unwrap();
    }
    let mut built = planner(256);
    let mut staging = PreparedMove::new();
    for (key, mv) in outline().iter().enumerate() {
        push_built(&mut built, &mut staging, mv, key as u64).unwrap();
    }
    // The outline has blends at its junctions (else the test would not build any).
    assert!(
        pushed.geometry_stats().blends >= 3,
        "{:?}",
        pushed.geometry_stats()
    );
    assert_eq!(built.geometry_stats(), pushed.geometry_stats());
    assert_eq!(run_out(&mut built), run_out(&mut pushed));
}

#[test]
fn a_build_taken_before_the_geometry_changed_is_refused() {
    let moves = outline();
    let mut reference = planner(256);
    let mut pl = planner(256);
    let mut staging = PreparedMove::new();
    reference.push(&moves[0]).unwrap();
    pl.push(&moves[0]).unwrap();
    // The copy for the arc is taken, then another move is pushed before it is appended.
    pl.prepare(&moves[1], 1, &mut staging);
    staging.build();
    reference.push(&moves[2]).unwrap();
    pl.push(&moves[2]).unwrap();
    assert_eq!(pl.preparation(&staging, 1), Preparation::Stale);
    assert!(matches!(
        pl.push_prepared(&mut staging),
        Err(MotionError::Busy(_))
    ));
    // Likewise after a flush.
    pl.prepare(&moves[3], 3, &mut staging);
    staging.build();
    reference.flush();
    pl.flush();
    assert!(matches!(
        pl.push_prepared(&mut staging),
        Err(MotionError::Busy(_))
    ));
    assert_eq!(pl.window_len(), reference.window_len());
    assert_eq!(run_out(&mut pl), run_out(&mut reference));
}

#[test]
fn a_bad_move_built_apart_gives_the_error_push_gives() {
    let mode = PathMode::ExactStop;
    let mut pl = planner(256);
    let mut staging = PreparedMove::new();
    for (key, mv) in [
        Move::line(p2(400.0, 0.0), 20.0, mode, 7),
        Move::line(p2(f64::NAN, 0.0), 20.0, mode, 8),
        Move::line(p2(0.0, 0.0), 20.0, mode, 9),
    ]
    .iter()
    .enumerate()
    {
        let expected = planner(256).push(mv).unwrap_err();
        let got = push_built(&mut pl, &mut staging, mv, key as u64).unwrap_err();
        assert_eq!(got.code(), expected.code(), "{got} / {expected}");
        assert_eq!(got.line(), expected.line());
    }
    // Nothing was taken: the planner is where it started.
    assert_eq!(pl.window_len(), 0);
    pl.push(&Move::line(p2(10.0, 0.0), 20.0, mode, 10)).unwrap();
    let mut reference = planner(256);
    reference
        .push(&Move::line(p2(10.0, 0.0), 20.0, mode, 10))
        .unwrap();
    assert_eq!(run_out(&mut pl), run_out(&mut reference));
}

#[test]
fn a_build_refused_for_a_full_window_stays_valid() {
    let mode = PathMode::ExactStop;
    let mut pl = planner(8);
    let mut key = 0u64;
    let mut x = 0.0;
    let mut staging = PreparedMove::new();
    // Fill the window with short moves until one no longer fits.
    let full_x = loop {
        x += 1.0;
        key += 1;
        let mv = Move::line(p2(x, 0.0), 20.0, mode, key as u32);
        match push_built(&mut pl, &mut staging, &mv, key) {
            Ok(()) => assert!(key < 100, "the window never filled"),
            Err(MotionError::QueueFull) => break x,
            Err(e) => panic!("{e}"),
        }
    };
    assert_eq!(pl.preparation(&staging, key), Preparation::Built);
    let mut j = [0.0; 2];
    let mut taken = false;
    for _ in 0..100_000 {
        pl.next(&mut j);
        match pl.push_prepared(&mut staging) {
            Ok(()) => {
                taken = true;
                break;
            }
            Err(MotionError::QueueFull) => {}
            Err(e) => panic!("{e}"),
        }
    }
    assert!(taken, "the window never freed");
    // The refused move runs once taken: the path ends where it does.
    let last = *run_out(&mut pl).last().unwrap();
    assert_eq!(last, [full_x.to_bits(), 0f64.to_bits()]);
}
