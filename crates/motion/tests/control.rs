//! Analytic cases, on-line changes (override, hold, abort, quick stop), dwell, kinematics.

use crate::common::*;
use rtcnc_motion::{
    AXES, Axis, AxisLimits, JointLimits, MachineLimits, MotionState, Move, PathMode, Planner,
    TrivialKinematics,
};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// Closed-form time of a rest-to-rest S-curve over `d` that reaches the cruise speed `v`
/// with a constant-acceleration phase: T = d/v + v/a + a/j (valid when v ≥ a²/j and
/// d ≥ v (v/a + a/j)).
fn scurve_time(d: f64, v: f64, a: f64, j: f64) -> f64 {
    assert!(v >= a * a / j && d >= v * (v / a + a / j));
    d / v + v / a + a / j
}

#[test]
fn single_line_rest_to_rest_matches_the_closed_form_s_curve() {
    for (d, f) in [(20.0, 100.0), (50.0, 80.0), (12.5, 60.0)] {
        let lim = limits(V, A, J);
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
        let tr = run(
            &mut pl,
            &[Move::line(p3(d, 0.0, 0.0), f, PathMode::ExactStop, 1)],
            10_000,
        );
        assert_limits(&tr, V, A, J);
        let t_ref = scurve_time(d, f, A, J);
        let t = cycle_time(&tr);
        // An isolated line follows the time-optimal profile: its end falls in the period
        // after the optimum, or one later where the optimum is a whole number of periods
        // (the profile runs 1e-7 relative inside the limits, for the set-point check).
        assert!(t >= t_ref - 1e-9, "{t} < {t_ref}");
        assert!(
            t <= (t_ref / T).ceil() * T + T + 1e-9,
            "{t} vs closed form {t_ref}"
        );
        if (t_ref / T - (t_ref / T).round()).abs() > 1e-3 {
            assert!((t - (t_ref / T).ceil() * T).abs() < 1e-9, "{t} vs {t_ref}");
        }
        // The cruise speed is the feed.
        let peak = tr.speed.iter().cloned().fold(0.0, f64::max);
        assert!((peak - f).abs() <= 1e-6 * f, "peak {peak}");
    }
}

#[test]
fn diagonal_line_uses_the_projected_axis_limits() {
    // Along the XY diagonal each axis carries 1/√2 of the path quantities: the path may
    // accelerate at √2·a; the feed (120) is below √2·v.
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
    let tr = run(
        &mut pl,
        &[Move::line(
            p3(30.0, 30.0, 0.0),
            120.0,
            PathMode::ExactStop,
            1,
        )],
        10_000,
    );
    assert_limits(&tr, V, A, J);
    let s2 = 2f64.sqrt();
    let t_ref = scurve_time(30.0 * s2, 120.0, A * s2, J * s2);
    let t = cycle_time(&tr);
    assert!(
        t >= t_ref - T && t <= t_ref * 1.05 + 2.0 * T,
        "{t} vs {t_ref}"
    );
}

#[test]
fn arc_at_high_feed_runs_at_the_centripetal_limit() {
    // Full circle R = 5 in XY at F 200: v = sqrt(a R) = 70.71 mm/s binds (below the axis
    // velocity limit and the jerk bound (0.8 j R²)^(1/3) = 100).
    let r = 5.0;
    let mv = Move::arc(
        p3(r, 0.0, 0.0),
        [0.0, 0.0, 0.0],
        [0.0, 0.0, 1.0],
        1,
        200.0,
        PathMode::ExactStop,
        1,
    );
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(r, 0.0, 0.0), 64);
    let tr = run(&mut pl, &[mv], 20_000);
    assert_limits(&tr, V, A, J);
    let v_ref = (A * r).sqrt();
    // The path speed the controller aims at is sqrt(a R) (the per-axis check, not this
    // figure, enforces the limits; its corrections may move the speed by a hair).
    let peak = tr.speed.iter().cloned().fold(0.0, f64::max);
    assert!(
        peak <= v_ref * (1.0 + 1e-3),
        "peak {peak} above sqrt(a R) {v_ref}"
    );
    // Two full turns: most of the time is spent at the limit.
    let at_limit = tr.speed.iter().filter(|v| **v >= 0.99 * v_ref).count() as f64 * T;
    assert!(
        at_limit >= 0.5 * 2.0 * 2.0 * std::f64::consts::PI * r / v_ref,
        "only {at_limit} s at the limit"
    );
    assert!(dist(tr.pts.last().unwrap(), &p3(r, 0.0, 0.0)) <= 1e-9);
}

fn long_line_run(hook: impl FnMut(usize, &mut Planner<TrivialKinematics>)) -> Trace {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
    let moves = [
        Move::line(p3(100.0, 0.0, 0.0), 100.0, blend(0.01), 1),
        Move::line(p3(100.0, 40.0, 0.0), 100.0, blend(0.01), 2),
    ];
    let tr = run_with(&mut pl, &moves, 50_000, hook);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    tr
}

#[test]
fn feed_hold_stops_on_the_path_and_resume_finishes_it() {
    let tr = long_line_run(|n, pl| {
        if n == 200 {
            pl.hold();
        }
        if n == 800 {
            pl.resume();
        }
    });
    // Held: between the hold's deceleration and the resume the set-point does not move.
    let held = &tr.pts[3 + 500..3 + 800];
    assert!(held.iter().all(|p| p == &held[0]));
    assert!(tr.states[600] == MotionState::Holding);
    // Stopped on the programmed path (on the first line, y = 0).
    assert_eq!(held[0][1], 0.0);
    assert!(dist(tr.pts.last().unwrap(), &p3(100.0, 40.0, 0.0)) <= 1e-9);
}

#[test]
fn feed_override_changes_mid_segment_within_the_limits() {
    let tr = long_line_run(|n, pl| match n {
        150 => pl.set_feed_override(0.5),
        400 => pl.set_feed_override(1.7),
        600 => pl.set_feed_override(0.0),
        900 => pl.set_feed_override(1.0),
        _ => {}
    });
    // At 50 % the speed settles at 50 mm/s, at 0 % the machine stops on the path.
    assert!((tr.speed[390] - 50.0).abs() < 1e-4, "{}", tr.speed[390]);
    assert!(tr.speed[880] == 0.0);
    // 170 % of 100 mm/s is capped by the axis velocity limit (100 mm/s on X).
    assert!(
        tr.speed[590] <= 100.0 + 1e-9 && tr.speed[590] > 99.0,
        "{}",
        tr.speed[590]
    );
}

#[test]
fn abort_stops_on_the_path_and_drops_the_queue() {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
    let moves = [Move::line(p3(40.0, 0.0, 0.0), 100.0, blend(0.01), 1)];
    let tr = run_with(&mut pl, &moves, 50_000, |n, pl| {
        if n == 250 {
            pl.abort();
        }
    });
    assert_limits(&tr, V, A, J);
    let last = tr.pts.last().unwrap();
    assert!(
        last[0] < 40.0 && last[0] > 10.0 && last[1] == 0.0,
        "{last:?}"
    );
    assert_eq!(pl.window_len(), 0);
    // The planner takes new moves from where it stopped.
    pl.push(&Move::line(p3(0.0, 0.0, 0.0), 50.0, blend(0.01), 2))
        .unwrap();
    pl.flush();
    let tr2 = run(&mut pl, &[], 50_000);
    assert!(dist(tr2.pts.last().unwrap(), &p3(0.0, 0.0, 0.0)) <= 1e-9);
}

#[test]
fn quick_stop_uses_its_own_deceleration_and_jerk() {
    // Quick stop may use 3000 mm/s² and 200 000 mm/s³: it stops much shorter than a hold.
    let mut al = AxisLimits::new(V, A, J, -1000.0, 1000.0);
    al.quick_stop_acceleration = 3000.0;
    al.quick_stop_jerk = 200_000.0;
    let lim = MachineLimits::uniform(&[Axis::X, Axis::Y, Axis::Z], al);
    let stop_at = |quick: bool| {
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
        let moves = [Move::line(p3(60.0, 0.0, 0.0), 100.0, blend(0.01), 1)];
        let tr = run_with(&mut pl, &moves, 50_000, |n, pl| {
            if n == 300 {
                if quick { pl.quick_stop() } else { pl.abort() }
            }
        });
        assert_limits(
            &tr,
            V,
            if quick { 3000.0 } else { A },
            if quick { 200_000.0 } else { J },
        );
        tr.pts.last().unwrap()[0]
    };
    let (x_quick, x_abort) = (stop_at(true), stop_at(false));
    assert!(x_quick < x_abort - 1.0, "quick {x_quick} abort {x_abort}");
}

#[test]
fn dwell_waits_at_rest() {
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
    let moves = [
        Move::line(p3(5.0, 0.0, 0.0), 50.0, blend(0.01), 1),
        Move::dwell(0.25, 2),
        Move::line(p3(5.0, 5.0, 0.0), 50.0, blend(0.01), 3),
    ];
    let tr = run(&mut pl, &moves, 50_000);
    assert_limits(&tr, V, A, J);
    let dwelling = tr
        .states
        .iter()
        .filter(|s| **s == MotionState::Dwelling)
        .count();
    assert_eq!(dwelling, 250);
    let at = p3(5.0, 0.0, 0.0);
    assert!(tr.pts.iter().filter(|p| **p == at).count() >= 250);
}

#[test]
fn gantry_axis_drives_all_its_joints() {
    let lim = limits(V, A, J);
    let kin = TrivialKinematics::new(vec![
        (Axis::X, None),
        (Axis::X, None),
        (Axis::X, None),
        (Axis::X, None),
        (Axis::Y, None),
        (Axis::Z, None),
    ])
    .unwrap();
    let mut pl = Planner::new(&lim, kin, T, 64, p3(0.0, 0.0, 0.0)).unwrap();
    pl.push(&Move::line(p3(10.0, 5.0, 0.0), 80.0, blend(0.01), 1))
        .unwrap();
    pl.flush();
    let mut joints = [0.0; 6];
    loop {
        let st = pl.next(&mut joints);
        assert!(joints[..4].iter().all(|j| *j == st.axes[0]));
        assert_eq!(joints[4], st.axes[1]);
        if st.state == MotionState::Idle {
            break;
        }
    }
    assert_eq!(joints[0], 10.0);
}

#[test]
fn joint_velocity_limit_slows_the_axis_it_follows() {
    let lim = limits(V, A, J);
    let jl = JointLimits {
        max_velocity: 40.0,
        min_position: -100.0,
        max_position: 100.0,
    };
    let kin = TrivialKinematics::new(vec![(Axis::X, Some(jl)), (Axis::Y, None), (Axis::Z, None)])
        .unwrap();
    let mut pl = Planner::new(&lim, kin, T, 64, p3(0.0, 0.0, 0.0)).unwrap();
    let tr = run_gen(
        &mut pl,
        &[Move::line(p3(20.0, 0.0, 0.0), 100.0, blend(0.01), 1)],
    );
    let (rv, _, _) = ratios(&tr, 40.0, A, J);
    assert!(rv <= 1.0 + 1e-9 && rv > 0.99, "{rv}");
    // Its position range narrows the envelope.
    assert!(
        pl.push(&Move::line(p3(150.0, 0.0, 0.0), 100.0, blend(0.01), 2))
            .is_err()
    );
}

fn run_gen(pl: &mut Planner<TrivialKinematics>, moves: &[Move]) -> Trace {
    run(pl, moves, 50_000)
}

#[test]
fn rotary_and_extra_axes_move_linearly_along_a_line() {
    let mut lim = limits(V, A, J);
    lim.axes[Axis::A as usize] = Some(AxisLimits::new(360.0, 3600.0, 100_000.0, -1e6, 1e6));
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z, Axis::A]);
    let mut pl = Planner::new(&lim, kin, T, 64, [0.0; AXES]).unwrap();
    let mut end = p3(10.0, 0.0, 0.0);
    end[Axis::A as usize] = 90.0;
    pl.push(&Move::line(end, 50.0, blend(0.01), 1)).unwrap();
    pl.flush();
    let mut joints = [0.0; 4];
    loop {
        let st = pl.next(&mut joints);
        assert!((st.axes[3] - 9.0 * st.axes[0]).abs() < 1e-9);
        if st.state == MotionState::Idle {
            break;
        }
    }
    assert_eq!(joints[3], 90.0);
}

#[test]
fn hold_resume_and_override_on_a_curved_polyline_respect_the_limits() {
    // The 1 µm circle polyline (smoothing spans): override changes and a hold in the middle
    // of the curve, then resume.
    let verts = circle_polyline(10.0, 0.001, 1.0);
    let moves = lines(&verts, 100.0, blend(0.001));
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, verts[0], 2048);
    let tr = run_with(&mut pl, &moves, 50_000, |n, pl| match n {
        150 => pl.set_feed_override(0.3),
        260 => pl.set_feed_override(1.5),
        400 => pl.hold(),
        700 => pl.resume(),
        _ => {}
    });
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0);
    // Held on the curve: standing still between the stop and the resume, on the circle.
    let first_still = (400..700)
        .find(|k| tr.pts[3 + k] == tr.pts[3 + k + 1])
        .expect("no stop");
    let held = &tr.pts[3 + first_still..3 + 700];
    assert!(held.iter().all(|p| p == &held[0]));
    assert!(((held[0][0].powi(2) + held[0][1].powi(2)).sqrt() - 10.0).abs() < 0.0011);
    assert!(dist(tr.pts.last().unwrap(), verts.last().unwrap()) <= 1e-9);
    assert!(max_deviation(&tr, &verts) <= 0.001 * (1.0 + 1e-9));
}

#[test]
fn resume_during_the_last_steps_of_a_hold_keeps_the_limits() {
    // A resume requested while the hold's stop lands on its point (its last steps are
    // planned exactly to rest) waits for them to end: from inside them the speed policy was
    // left a state it could not continue from (a resume at period 674 here exceeded the
    // jerk limit by 9 %, two counted violations).
    let verts = circle_polyline(10.0, 0.001, 1.0);
    let moves = lines(&verts, 100.0, blend(0.001));
    let lim = limits(V, A, J);
    for resume_at in 664..=684 {
        let mut pl = planner(&lim, verts[0], 2048);
        let tr = run_with(&mut pl, &moves, 50_000, |n, pl| match n {
            150 => pl.set_feed_override(0.3),
            260 => pl.set_feed_override(1.5),
            450 => pl.hold(),
            n if n == resume_at => pl.resume(),
            _ => {}
        });
        assert_limits(&tr, V, A, J);
        assert_eq!(pl.stats().limit_violations, 0, "resume at {resume_at}");
        assert!(dist(tr.pts.last().unwrap(), verts.last().unwrap()) <= 1e-9);
    }
}

#[test]
fn quick_stop_on_a_curve_stays_on_the_path() {
    let verts = circle_polyline(10.0, 0.001, 1.0);
    let moves = lines(&verts, 100.0, blend(0.001));
    let lim = limits(V, A, J);
    let mut pl = planner(&lim, verts[0], 2048);
    let tr = run_with(&mut pl, &moves, 50_000, |n, pl| {
        if n == 300 {
            pl.quick_stop()
        }
    });
    assert_limits(&tr, V, A, J);
    assert!(max_deviation(&tr, &verts) <= 0.001 * (1.0 + 1e-9));
    assert_eq!(pl.window_len(), 0);
}

/// The seeds' experiment as a one-line program: 6 mm on one axis from rest to rest at up to
/// 50 mm/s, 1000 mm/s², 10 000 mm/s³, 1 ms period. ruckig's time-optimal profile takes
/// 267.773 ms and peaks at 44.814 mm/s: the set-points reach the end in the 268th period and
/// their largest one-period step is 44.81 mm/s (the profile's peak averaged over 1 ms).
#[test]
fn isolated_line_takes_the_time_optimal_s_curve_time() {
    let lim = limits(50.0, 1000.0, 10_000.0);
    for push_then_flush_later in [false, true] {
        let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
        let mv = Move::line(p3(6.0, 0.0, 0.0), 50.0, PathMode::ExactStop, 1);
        let mut joints = [0.0; 3];
        let mut pts = vec![p3(0.0, 0.0, 0.0); 3];
        pl.push(&mv).unwrap();
        if !push_then_flush_later {
            pl.flush();
        }
        for n in 0..1000 {
            if push_then_flush_later && n == 50 {
                pl.flush();
            }
            let st = pl.next(&mut joints);
            pts.push(st.axes);
            if st.state == MotionState::Idle && (n >= 50 || !push_then_flush_later) {
                break;
            }
        }
        let first = pts.iter().position(|p| p[0] != 0.0).unwrap();
        let last = pts
            .iter()
            .position(|p| p[0] == 6.0)
            .unwrap_or_else(|| panic!("end {:?}", &pts[pts.len() - 3..]));
        assert_eq!(
            last - (first - 1),
            268,
            "flush later: {push_then_flush_later}"
        );
        let peak = pts
            .windows(2)
            .map(|w| (w[1][0] - w[0][0]) / T)
            .fold(0.0, f64::max);
        assert!((peak - 44.814).abs() < 0.01, "peak {peak}");
        let tr = Trace {
            pts,
            states: Vec::new(),
            speed: Vec::new(),
        };
        assert_limits(&tr, 50.0, 1000.0, 10_000.0);
    }
}

#[test]
fn on_line_changes_never_alter_set_points_already_emitted() {
    // The generator runs ahead of emission; an override, a hold or a quick stop regenerates
    // only what was not emitted: the first 300 set-points are those of the run without a
    // change, and the change shows from the next period on.
    let plain = long_line_run(|_, _| {});
    for change in 0..3 {
        let changed = long_line_run(|n, pl| {
            if n == 300 {
                match change {
                    0 => pl.set_feed_override(0.5),
                    1 => pl.hold(),
                    _ => pl.quick_stop(),
                }
            }
            if n == 700 && change == 1 {
                pl.resume();
            }
        });
        // Three repeated start points, then period n's set-point at index n + 3.
        assert_eq!(plain.pts[..303], changed.pts[..303], "change {change}");
        assert_ne!(plain.pts[304], changed.pts[304], "change {change}");
    }
}

#[test]
fn the_generator_runs_one_longest_stop_ahead() {
    // Fastest path speed sqrt(3)·100 mm/s over the weakest axis's 1000 mm/s², plus A/J:
    // 0.1932 s, i.e. 194 periods of 1 ms.
    let pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 64);
    let t_stop = 3f64.sqrt() * V / A + A / J;
    assert!(pl.generation_depth() as f64 * T >= t_stop);
}

#[test]
fn on_line_changes_on_an_isolated_lines_s_curve_keep_the_limits() {
    // A line from rest to a stop follows the OTG's S-curve at the full limits. An override
    // replans it from the current state, a hold or quick stop whose stop would end beyond
    // the line keeps it: handing such a state over to the speed policy (whose stop model
    // keeps margins) used to exceed the limits at the stop.
    let lim = limits(V, A, J);
    let line = [Move::line(
        p3(30.0, 0.0, 0.0),
        145.0,
        PathMode::ExactStop,
        1,
    )];
    // The S-curve takes about 0.42 s: 200 is at speed, 330 brakes, 400 lands.
    for at in [200, 330, 400] {
        for change in 0..4 {
            let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
            let tr = run_with(&mut pl, &line, 10_000, |n, pl| {
                if n == at {
                    match change {
                        0 => pl.set_feed_override(0.5),
                        1 => pl.set_feed_override(1.5),
                        2 => pl.hold(),
                        _ => pl.quick_stop(),
                    }
                }
                if n == at + 400 && change == 2 {
                    pl.resume();
                }
            });
            assert_limits(&tr, V, A, J);
            assert_eq!(pl.stats().limit_violations, 0, "at {at} change {change}");
            if change < 3 {
                assert!(dist(tr.pts.last().unwrap(), &p3(30.0, 0.0, 0.0)) <= 1e-9);
            }
        }
    }
}
