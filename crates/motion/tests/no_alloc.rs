//! `Planner::push` (and a push built apart: `prepare`, `PreparedMove::build`,
//! `push_prepared`), `flush` and `next` allocate nothing on real programs: lines with G64 P
//! corner blends, smoothing of dense polylines and G64 Q merges, arcs, helices and spirals
//! blended into lines, G5/G5.1 splines (tangent chains, corners blended, near cusps cut at
//! their dips), dwells, rapids and exact stops, with overrides, a feed hold, a resume and
//! the set-point history that `unemit` goes back over, as the kernel drives them. A counting
//! allocator counts what the watching thread allocates while it pushes and steps the
//! planner (the tests of this file run on parallel threads; each counts its own).

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

use rtcnc_motion::{
    AXES, Axis, AxisLimits, AxisVec, Bezier, MachineLimits, MotionState, Move, PathMode, Planner,
    PreparedMove, TrivialKinematics,
};

#[path = "support/spline_programs.rs"]
mod spline_programs;

struct Counting;

thread_local! {
    /// Allocations of this thread while it watches (`None`: not watching).
    static WATCHED: Cell<Option<u64>> = const { Cell::new(None) };
}

fn count_one() {
    // `try_with`: the allocator also runs while thread-locals are torn down.
    let _ = WATCHED.try_with(|w| {
        if let Some(n) = w.get() {
            w.set(Some(n + 1));
        }
    });
}

// SAFETY: forwards to the system allocator; only counts.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same contract as ours.
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        count_one();
        // SAFETY: same contract as ours.
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: same contract as ours.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count_one();
        // SAFETY: same contract as ours.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns what it returned and how many allocations this thread made in it.
fn counted<R>(f: impl FnOnce() -> R) -> (R, u64) {
    WATCHED.with(|w| w.set(Some(0)));
    let r = f();
    let n = WATCHED.with(|w| w.replace(None)).unwrap_or(0);
    (r, n)
}

const PERIOD: f64 = 1e-3;

fn p3(x: f64, y: f64, z: f64) -> AxisVec {
    let mut p = [0.0; AXES];
    p[0] = x;
    p[1] = y;
    p[2] = z;
    p
}

fn blend(tolerance: f64, merge: f64) -> PathMode {
    PathMode::Blend {
        tolerance,
        merge_tolerance: merge,
    }
}

fn planner(start: AxisVec, history: usize) -> Planner<TrivialKinematics> {
    let limits = MachineLimits::uniform(
        &[Axis::X, Axis::Y, Axis::Z],
        AxisLimits::new(100.0, 1000.0, 50_000.0, -1000.0, 1000.0),
    );
    Planner::new(
        &limits,
        TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]),
        PERIOD,
        256,
        start,
    )
    .unwrap()
    .with_history(history)
}

/// What happens at a period of a run, besides pushing and stepping.
#[derive(Clone, Copy)]
enum Event {
    FeedOverride(f64),
    RapidOverride(f64),
    Hold,
    Resume,
    /// Goes back over this many set-points (as the kernel does when a change takes back
    /// the set-points position control has not taken).
    Unemit(usize),
}

/// Pushes `moves` while there is room (one push per period, as the kernel's look-ahead
/// feeds it; every other move built apart, as the kernel builds them all), flushes after the last, steps until the planner is idle with nothing left;
/// returns the periods run, the allocations made inside push, flush, next and the events,
/// and the planner's end position. The planner is built before counting (its memory is
/// fixed there).
fn run(
    moves: &[Move],
    start: AxisVec,
    events: &[(u64, Event)],
    max_periods: u64,
) -> (u64, u64, AxisVec, u64) {
    let mut pl = planner(start, 64);
    let mut staging = PreparedMove::new();
    let mut joints = [0.0; 3];
    let mut allocations = 0;
    let mut k = 0;
    let mut flushed = false;
    let mut period = 0;
    while period < max_periods {
        let (status, n) = counted(|| {
            if k < moves.len() && pl.free() > 0 {
                if k % 2 == 0 {
                    pl.push(&moves[k]).unwrap();
                } else {
                    pl.prepare(&moves[k], k as u64, &mut staging);
                    staging.build();
                    pl.push_prepared(&mut staging).unwrap();
                }
                k += 1;
            }
            if k == moves.len() && !flushed {
                pl.flush();
                flushed = true;
            }
            for &(at, event) in events {
                if at == period {
                    match event {
                        Event::FeedOverride(f) => pl.set_feed_override(f),
                        Event::RapidOverride(f) => pl.set_rapid_override(f),
                        Event::Hold => pl.hold(),
                        Event::Resume => pl.resume(),
                        Event::Unemit(n) => pl.unemit(n).unwrap(),
                    }
                }
            }
            pl.next(&mut joints)
        });
        allocations += n;
        period += 1;
        if flushed && status.state == MotionState::Idle {
            break;
        }
    }
    let violations = pl.stats().limit_violations;
    (period, allocations, pl.position(), violations)
}

/// Asserts the run ended at `end`, within the limits and without allocating.
fn check(name: &str, moves: &[Move], start: AxisVec, end: AxisVec, events: &[(u64, Event)]) {
    let (periods, allocations, at, violations) = run(moves, start, events, 2_000_000);
    assert!(periods < 2_000_000, "{name}: did not end");
    let off = (0..3).map(|i| (at[i] - end[i]).abs()).fold(0.0, f64::max);
    assert!(off < 1e-9, "{name}: ended {off} mm from its end point");
    assert_eq!(violations, 0, "{name}: limits exceeded");
    assert_eq!(
        allocations, 0,
        "{name}: {allocations} allocations in {periods} periods"
    );
}

/// A pocket-like polyline (a circle of chords) under G64 P with Q merges, corners of a
/// square blended, a rapid, a dwell and G61 exact stops.
fn lines_program() -> (Vec<Move>, AxisVec) {
    let mut moves = Vec::new();
    let mut line = 0;
    let mut next = || {
        line += 1;
        line
    };
    moves.push(Move::rapid(p3(10.0, 0.0, 5.0), PathMode::ExactPath, next()));
    moves.push(Move::line(
        p3(10.0, 0.0, -1.0),
        20.0,
        PathMode::ExactPath,
        next(),
    ));
    // 360 chords of a 10 mm circle, 0.17 mm each: smoothed through their vertices.
    for k in 1..=360 {
        let a = (k as f64).to_radians();
        moves.push(Move::line(
            p3(10.0 * a.cos(), 10.0 * a.sin(), -1.0),
            40.0,
            blend(0.01, 0.0),
            next(),
        ));
    }
    // Nearly collinear segments merged by Q, then a square's corners blended.
    for k in 1..=40 {
        let y = if k % 2 == 0 { 0.0 } else { 0.0005 };
        moves.push(Move::line(
            p3(10.0 + k as f64 * 0.5, y, -1.0),
            60.0,
            blend(0.02, 0.001),
            next(),
        ));
    }
    for p in [
        p3(30.0, 20.0, -1.0),
        p3(10.0, 20.0, -1.0),
        p3(10.0, 0.0, -1.0),
    ] {
        moves.push(Move::line(p, 60.0, blend(0.05, 0.0), next()));
    }
    moves.push(Move::dwell(0.25, next()));
    for p in [
        p3(12.0, 2.0, -1.0),
        p3(14.0, 2.0, -1.0),
        p3(14.0, 4.0, -1.0),
    ] {
        moves.push(Move::line(p, 30.0, PathMode::ExactStop, next()));
    }
    let end = p3(14.0, 4.0, 5.0);
    moves.push(Move::rapid(end, PathMode::ExactPath, next()));
    (moves, p3(0.0, 0.0, 5.0))
}

/// Arcs in three planes, a helix over two turns, a spiral (end radius 0.03 mm off),
/// blended into the lines around them.
fn arcs_program() -> (Vec<Move>, AxisVec) {
    let mode = blend(0.01, 0.0);
    let moves = vec![
        Move::line(p3(10.0, 0.0, 0.0), 50.0, mode, 1),
        Move::arc(
            p3(0.0, 10.0, 0.0),
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            0,
            50.0,
            mode,
            2,
        ),
        Move::line(p3(-5.0, 15.0, 0.0), 50.0, mode, 3),
        // XZ plane, clockwise about -Y.
        Move::arc(
            p3(-5.0, 15.0, -10.0),
            [-5.0, 15.0, -5.0],
            [0.0, -1.0, 0.0],
            0,
            40.0,
            mode,
            4,
        ),
        Move::line(p3(0.0, 15.0, -10.0), 50.0, mode, 5),
        // A helix: two more turns about Z, 4 mm down.
        Move::arc(
            p3(10.0, 15.0, -14.0),
            [5.0, 15.0, -10.0],
            [0.0, 0.0, 1.0],
            2,
            40.0,
            mode,
            6,
        ),
        // A spiral, its end 0.03 mm further from the centre than its start.
        Move::arc(
            p3(15.03, 20.0, -14.0),
            [10.0, 20.0, -14.0],
            [0.0, 0.0, -1.0],
            0,
            40.0,
            mode,
            7,
        )
        .with_radius_tolerance(0.05),
        Move::line(p3(15.03, 30.0, -14.0), 50.0, PathMode::ExactPath, 8),
    ];
    (moves, p3(0.0, 0.0, 0.0))
}

/// G5 chains and G5.1 curves: tangent, blended corners between splines, lines and arcs,
/// and a curve whose parametric speed dips (cut at the dip).
fn splines_program() -> (Vec<Move>, AxisVec) {
    let mode = blend(0.01, 0.0);
    let mut moves = vec![
        Move::line(p3(5.0, 0.0, 0.0), 40.0, mode, 1),
        // Tangent to the line, then a chain through its reflected control points.
        Move::spline(
            p3(15.0, 5.0, 0.0),
            Bezier::Cubic([p3(9.0, 0.0, 0.0), p3(12.0, 2.0, 0.0)]),
            40.0,
            mode,
            2,
        ),
        Move::spline(
            p3(25.0, 0.0, 0.0),
            Bezier::Cubic([p3(18.0, 8.0, 0.0), p3(22.0, 0.0, 0.0)]),
            40.0,
            mode,
            3,
        ),
        // A corner into a quadratic (G5.1), blended.
        Move::spline(
            p3(25.0, 10.0, 0.0),
            Bezier::Quadratic(p3(30.0, 5.0, 0.0)),
            40.0,
            mode,
            4,
        ),
        // A corner into an arc, and out of it into a spline.
        Move::arc(
            p3(15.0, 10.0, 0.0),
            [20.0, 10.0, 0.0],
            [0.0, 0.0, 1.0],
            0,
            40.0,
            mode,
            5,
        ),
        // A cubic whose parametric speed dips so far that its pieces are cut at the dip
        // (an S whose middle control point lies back behind the start).
        Move::spline(
            p3(20.0, 11.8, 0.0),
            Bezier::Cubic([p3(24.2, 12.8, 0.0), p3(13.8, 9.7, 0.0)]),
            30.0,
            mode,
            6,
        ),
        Move::spline(
            p3(0.0, 0.0, 0.0),
            Bezier::Cubic([p3(18.0, 16.0, 0.0), p3(2.0, 8.0, 0.0)]),
            30.0,
            PathMode::ExactPath,
            7,
        ),
    ];
    // The random chains of the spline tests (splines alone and with lines between), one
    // after the other from where the last ended.
    let mut rng = spline_programs::Rng(0x5eed_2024);
    let mut at = p3(0.0, 0.0, 0.0);
    let mut line = 100;
    for k in 0..24 {
        let (chain, end) = spline_programs::program(&mut rng, k % 2 == 1);
        // Chains with a (near) cusp are refused by `push` (as in `splines_random.rs`):
        // left out here, where every move must be taken.
        let mut trial = planner(p3(0.0, 0.0, 0.0), 0);
        if chain.iter().any(|mv| trial.push(mv).is_err()) {
            continue;
        }
        for mv in chain {
            let mut mv = mv;
            line += 1;
            mv.line = line;
            shift(&mut mv, &at);
            moves.push(mv);
        }
        for i in 0..3 {
            at[i] += end[i];
        }
    }
    (moves, p3(0.0, 0.0, 0.0))
}

/// Moves `mv` by `d` (the random chains start at the origin).
fn shift(mv: &mut Move, d: &AxisVec) {
    let add = |p: &mut AxisVec| {
        for i in 0..3 {
            p[i] += d[i];
        }
    };
    match &mut mv.kind {
        rtcnc_motion::MoveKind::Line { end, .. } => add(end),
        rtcnc_motion::MoveKind::Spline { end, control } => {
            add(end);
            match control {
                Bezier::Quadratic(c) => add(c),
                Bezier::Cubic([c1, c2]) => {
                    add(c1);
                    add(c2);
                }
            }
        }
        rtcnc_motion::MoveKind::Arc { end, centre, .. } => {
            add(end);
            for i in 0..3 {
                centre[i] += d[i];
            }
        }
        rtcnc_motion::MoveKind::Dwell { .. } => {}
    }
}

fn end_of(moves: &[Move]) -> AxisVec {
    moves
        .iter()
        .rev()
        .find_map(|mv| match mv.kind {
            rtcnc_motion::MoveKind::Line { end, .. }
            | rtcnc_motion::MoveKind::Arc { end, .. }
            | rtcnc_motion::MoveKind::Spline { end, .. } => Some(end),
            rtcnc_motion::MoveKind::Dwell { .. } => None,
        })
        .unwrap()
}

#[test]
fn lines_blends_merges_dwells_and_exact_stops_allocate_nothing() {
    let (moves, start) = lines_program();
    check("lines", &moves, start, end_of(&moves), &[]);
}

#[test]
fn arcs_helices_and_spirals_allocate_nothing() {
    let (moves, start) = arcs_program();
    check("arcs", &moves, start, end_of(&moves), &[]);
}

#[test]
fn splines_allocate_nothing() {
    let (moves, start) = splines_program();
    check("splines", &moves, start, end_of(&moves), &[]);
}

#[test]
fn overrides_hold_resume_and_going_back_allocate_nothing() {
    let (moves, start) = lines_program();
    let events = [
        (300, Event::FeedOverride(0.5)),
        (900, Event::Unemit(20)),
        (1_500, Event::FeedOverride(1.5)),
        (2_000, Event::Hold),
        (2_600, Event::Resume),
        (3_000, Event::Unemit(40)),
        (3_500, Event::RapidOverride(0.25)),
        (4_000, Event::FeedOverride(1.0)),
    ];
    check("lines with changes", &moves, start, end_of(&moves), &events);
    let (moves, start) = splines_program();
    check(
        "splines with changes",
        &moves,
        start,
        end_of(&moves),
        &events,
    );
}

/// The counter counts: a planner built inside the watch allocates (its window, its
/// buffers), and so does a `Vec`.
#[test]
fn the_counter_sees_allocations() {
    let ((), n) = counted(|| {
        let pl = planner(p3(0.0, 0.0, 0.0), 8);
        std::hint::black_box(&pl);
    });
    assert!(n >= 3, "{n}");
    let (v, n) = counted(|| vec![1u8; 10]);
    assert_eq!((v.len(), n), (10, 1));
}
