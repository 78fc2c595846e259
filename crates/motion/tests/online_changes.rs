//! On-line changes (feed override, hold and resume, quick stop) at any period keep every
//! axis within its limits: the programs the random search of the `stress` example found
//! (each once exceeded a limit), and seeded random programs with changes at random periods.
//! 24 random programs in debug builds, 400 in release
//! (`cargo test --release -p rtcnc-motion --test suite online_changes::`); of the random arc
//! family, 24 and 3 000 of one seed, 8 and 8 000 of a second.

use crate::common::*;
use crate::line_programs::{Change, Lcg, parse_spec, random_changes, random_lines};
use rtcnc_motion::{
    AxisLimits, AxisVec, MachineLimits, MotionState, Move, PathMode, Planner, TrivialKinematics,
};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// The end point of a line or an arc.
fn end_of(m: &Move) -> [f64; rtcnc_motion::AXES] {
    match m.kind {
        rtcnc_motion::MoveKind::Line { end, .. } | rtcnc_motion::MoveKind::Arc { end, .. } => end,
        _ => unreachable!("lines and arcs only"),
    }
}

/// Runs `moves` with `changes` applied before the given periods; asserts the limits, no
/// counted violation and (without a quick stop) the exact end point.
fn run_changes(moves: &[Move], changes: &[(usize, Change)]) {
    run_changes_from(p3(0.0, 0.0, 0.0), moves, changes);
}

/// [`run_changes`] from `start`.
fn run_changes_from(start: AxisVec, moves: &[Move], changes: &[(usize, Change)]) {
    run_changes_on(&limits(V, A, J), start, moves, changes);
}

/// [`run_changes_from`] on a machine with `lim` (whose X and Y have the limits V, A, J).
fn run_changes_on(
    lim: &MachineLimits,
    start: AxisVec,
    moves: &[Move],
    changes: &[(usize, Change)],
) {
    let mut pl = planner(lim, start, 256);
    let trace = std::env::var_os("RTCNC_MOTION_TRACE").is_some();
    let apply = |n: usize, pl: &mut Planner<TrivialKinematics>| {
        for (at, c) in changes {
            if *at == n {
                if trace {
                    eprintln!("CHANGE before period {n}: {c:?}");
                }
                match *c {
                    Change::Override(f) => pl.set_feed_override(f),
                    Change::Hold => pl.hold(),
                    Change::Resume => pl.resume(),
                    Change::QuickStop => pl.quick_stop(),
                }
            }
        }
    };
    let tr = run_with(&mut pl, moves, 400_000, apply);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0, "{:?}", pl.stats());
    assert_eq!(*tr.states.last().unwrap(), MotionState::Idle);
    // (A quick stop drops the program wherever the machine comes to rest.)
    if !changes.iter().any(|(_, c)| matches!(c, Change::QuickStop)) {
        let end = end_of(moves.last().unwrap());
        assert!(dist(tr.pts.last().unwrap(), &end) <= 1e-9);
    }
}

#[test]
fn a_resume_just_before_rest_lets_the_stop_land_first() {
    // The hold's last periods are an exact discrete landing (0.21 mm/s at -112 mm/s² at the
    // resume): continuing from there with the speed policy's continuous model left no step
    // that keeps the jerk without reversing.
    let moves = parse_spec(
        "-11.05939791701751 1.7720575729222716 14.215952633063253 117.87214481210776 B 0.01; \
         -5.669142789383397 17.322000091211663 -2.6237503647520626 65.7173828661654 B 0.01; \
         6.187385463863926 -16.738407791252094 -6.707205899325048 138.82925608346156 B 0.001",
    );
    run_changes(
        &moves,
        &[
            (369, Change::Override(1.3118586469115425)),
            (727, Change::Hold),
            (1027, Change::Resume),
        ],
    );
}

#[test]
fn a_quick_stop_during_a_holds_landing_lands_it() {
    let moves = parse_spec(
        "-15.798187292511674 -8.697943969329462 10.308475147023984 84.49317317543357 B 0.001; \
         -4.515947119169063 -5.241582101050648 10.308475147023984 69.22662487945013 B 0.1; \
         9.580193616699244 -9.862055030926138 -11.535084982427101 50.56978930981912 E",
    );
    run_changes(&moves, &[(96, Change::Hold), (281, Change::QuickStop)]);
}

#[test]
fn an_override_while_braking_into_a_stop_keeps_the_limits() {
    // At 103 mm/s, 10.5 mm before an exact stop, the override (113 %) lowers the stop
    // model's deceleration (the blend before the slow last move is taken faster): no stop
    // of the model fits any more, and the axes brake as hard as the line allows instead.
    let moves = parse_spec(
        "-5.061029839671431 -15.337215203479374 8.8546785252748 120.41617667610315 B 0.001; \
         -17.5743040011449 -16.089841238937677 -2.1049714829773727 103.91190466237782 B 0.1; \
         -17.989797960134624 -14.688368091075766 -2.1049714829773727 17.56834096346271 S; \
         -13.752922543351254 15.929116819272608 -8.470458253081393 95.04937285204362 B 0.1; \
         -14.504440759449855 16.722330314841606 12.364635278812315 43.926737722669806 E",
    );
    run_changes(&moves, &[(395, Change::Override(1.1292126014962487))]);
}

#[test]
fn a_hold_while_braking_hard_for_a_slow_corner_keeps_the_braking_curve() {
    // The hold comes while the path brakes at the full limit (-1441 mm/s²) towards a 7 mm/s
    // corner: the hold's own stop (half the jerk) cannot release that deceleration in time,
    // so the path's braking decides until the hold's stop fits.
    let moves = parse_spec(
        "9.095694287339903 2.94994381672279 -16.055117702342447 65.79200688359077 E; \
         14.440660356435636 -6.748907451193173 -7.509376648792099 120.5966093431584 B 0.01; \
         17.4402321751868 -19.154261735170337 -7.509376648792099 7.3814820653927455 B 0.1; \
         -6.353886109863836 -5.295401321161858 11.617311440417502 97.9037758267827 B 0.1; \
         2.3103102425139213 8.67275154821597 11.617311440417502 103.51491793779431 B 0.01; \
         -8.291432871390448 -18.297487874954157 -14.478305911146489 58.108746805518 S; \
         -18.007085679386158 -12.322169711614368 -13.29577004934309 11.716095385062445 B 0.01",
    );
    run_changes(&moves, &[(504, Change::Hold), (804, Change::Resume)]);
}

#[test]
fn random_programs_with_random_on_line_changes_keep_every_limit() {
    // The `stress` example's programs and changes (`STRESS_ONLINE=1`) of seed 101, the first
    // seed past those of the documented stress runs.
    let n = if cfg!(debug_assertions) { 24 } else { 400 };
    let mut rng = Lcg(101);
    for case in 0..n {
        let (spec, moves) = random_lines(&mut rng);
        let changes = random_changes(&mut rng);
        let result = std::panic::catch_unwind(|| run_changes(&moves, &changes));
        assert!(result.is_ok(), "case {case}: SPEC=\"{spec}\" {changes:?}");
    }
}

/// A line from the origin, then one to four arcs in the XY plane (radius 0.5-15 mm, a
/// quarter to nearly a whole turn, either way, some helical), each blended into the next or
/// ending in an exact stop, the last in the program's stop; feeds 5-150 mm/s.
fn random_arcs(rng: &mut Lcg) -> Vec<Move> {
    let mut pos = [0.0; rtcnc_motion::AXES];
    pos[0] = 5.0 + rng.f() * 10.0;
    pos[1] = rng.f() * 10.0;
    let feed = |rng: &mut Lcg| 5.0 + rng.f() * 145.0;
    let mut moves = vec![Move::line(pos, feed(rng), blend(0.01), 1)];
    let mut heading = (pos[1]).atan2(pos[0]);
    for i in 0..1 + (rng.f() * 4.0) as usize {
        let r = 0.5 + rng.f() * 14.5;
        let ccw = rng.f() < 0.5;
        let side = if ccw { 1.0 } else { -1.0 };
        // The centre lies to the left of the heading for a counter-clockwise arc: the arc
        // starts tangent to the path so far.
        let normal_angle = heading + side * std::f64::consts::FRAC_PI_2;
        let centre = [
            pos[0] + r * normal_angle.cos(),
            pos[1] + r * normal_angle.sin(),
            0.0,
        ];
        let sweep = (0.25 + rng.f() * 0.7) * std::f64::consts::TAU;
        let start_angle = (pos[1] - centre[1]).atan2(pos[0] - centre[0]);
        let end_angle = start_angle + side * sweep;
        let mut end = pos;
        end[0] = centre[0] + r * end_angle.cos();
        end[1] = centre[1] + r * end_angle.sin();
        if rng.f() < 0.3 {
            end[2] = pos[2] + rng.f() * 4.0 - 2.0;
        }
        let mode = if rng.f() < 0.3 {
            PathMode::ExactStop
        } else {
            blend(0.01)
        };
        let normal = [0.0, 0.0, side];
        moves.push(Move::arc(
            end,
            centre,
            normal,
            0,
            feed(rng),
            mode,
            i as u32 + 2,
        ));
        heading = end_angle + side * std::f64::consts::FRAC_PI_2;
        pos = end;
    }
    moves
}

#[test]
fn an_override_raised_while_braking_for_an_arc_end_keeps_the_limits() {
    // Found by the kernel fuzz target (fuzz/defects/kernel/arc-end-reached-at-8-mm-s): 34 ms
    // before the end of a half circle of 1.35 mm radius that ends in a stop, braking at
    // 23 mm/s, the override went from 42 % to 51 %. The braking curve under the new feed
    // lies lower (its deceleration is estimated at higher speeds, where the curve leaves
    // less of it), so no stop of the model fitted, and the policy braked at the model's
    // constant deceleration: the arc's end came at 8 mm/s. The axes had more (the
    // tangential deceleration grows as the speed falls and the tangent turns): they brake
    // as hard as the arc allows.
    let arc = Move::arc(
        [12.0, 5.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [10.65, 5.4, 0.0],
        [0.0, 0.0, -1.0],
        0,
        4000.0 / 60.0,
        PathMode::ExactStop,
        2,
    );
    let lead_in = Move::line(
        [9.3, 5.4, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        4000.0 / 60.0,
        PathMode::ExactStop,
        1,
    );
    let moves = [lead_in, arc];
    // The lead-in's stop, then the arc at 42 %; the override is raised at every period
    // of the arc's last 60 ms in turn.
    let plain = {
        let mut pl = planner(&limits(V, A, J), p3(9.3, 0.0, 0.0), 256);
        run_with(&mut pl, &moves, 100_000, |n, pl| {
            if n == 0 {
                pl.set_feed_override(0.424)
            }
        })
    };
    let periods = plain.states.len();
    for raise_at in periods.saturating_sub(60)..periods {
        let changes = [
            (0, Change::Override(0.424)),
            (raise_at, Change::Override(0.51)),
        ];
        let result =
            std::panic::catch_unwind(|| run_changes_from(p3(9.3, 0.0, 0.0), &moves, &changes));
        assert!(
            result.is_ok(),
            "override raised at period {raise_at} of {periods}"
        );
    }
}

/// A program and its on-line changes.
type ArcCase = (Vec<Move>, Vec<(usize, Change)>);

/// The first `n` programs of the seeded random arc family with their on-line changes: two
/// overrides at random periods (20-170 %), the second often while the first's change of
/// speed is under way, and in one program of three a hold and its resume.
fn random_arc_cases(seed: u64, n: usize) -> Vec<ArcCase> {
    let mut rng = Lcg(seed);
    (0..n)
        .map(|_| {
            let moves = random_arcs(&mut rng);
            let first = 30 + (rng.f() * 1500.0) as usize;
            let mut changes = vec![
                (first, Change::Override(0.2 + rng.f() * 1.5)),
                (
                    first + 1 + (rng.f() * 200.0) as usize,
                    Change::Override(0.2 + rng.f() * 1.5),
                ),
            ];
            if rng.f() < 0.33 {
                let hold = 30 + (rng.f() * 1500.0) as usize;
                changes.push((hold, Change::Hold));
                changes.push((hold + 300, Change::Resume));
            }
            (moves, changes)
        })
        .collect()
}

#[test]
fn random_arcs_with_random_overrides_keep_every_limit() {
    // 171 of 6 000 exceeded the speed or the acceleration (up to 62 ×) before the planner
    // braked as hard as an arc allows when the stop model had lost the state; then 12 of
    // these 3 000 the jerk (up to 9.6 ×) before a stop's generated set-points were kept
    // through an override that made the state lose it, and 4 (up to 7 ×) before a
    // deceleration the model could not release was released at the path's own jerk.
    let n = if cfg!(debug_assertions) { 24 } else { 3000 };
    for (case, (moves, changes)) in random_arc_cases(20_261_127, n).iter().enumerate() {
        let result = std::panic::catch_unwind(|| run_changes(moves, changes));
        assert!(result.is_ok(), "case {case}: {moves:?} {changes:?}");
    }
}

#[test]
fn random_arcs_of_a_second_seed_keep_every_limit() {
    // Seed 7: 4 of its first 20 000 programs exceeded the jerk (up to 15 ×); they are the
    // "Seed 7, program ..." tests below.
    let n = if cfg!(debug_assertions) {
        8
    } else {
        RELEASE_SEED_7_PROGRAMS
    };
    for (case, (moves, changes)) in random_arc_cases(7, n).iter().enumerate() {
        let result = std::panic::catch_unwind(|| run_changes(moves, changes));
        assert!(result.is_ok(), "case {case}: {moves:?} {changes:?}");
    }
}

/// Programs of seed 7 run in release builds (about 45 s on two cores).
const RELEASE_SEED_7_PROGRAMS: usize = 8_000;

#[test]
fn two_overrides_while_braking_into_the_programs_end_keep_the_limits() {
    // Seed 7, program 3870. 0.89 mm before the program's end, braking at 32 mm/s, the
    // override falls to 51 % (a stronger stop model: the braking is released) and 4 ms
    // later, 0.76 mm before the end, rises to 108 %: from there not even the axes' full
    // limits stop within the way left, and the end was passed at 0.6 mm/s with 15 × the
    // jerk. The raise now takes effect at the end.
    let moves = [
        Move::line(
            p3(14.608691214086903, 0.047598055908477654, 0.0),
            106.42289722035329,
            blend(0.01),
            1,
        ),
        Move::arc(
            p3(10.363287826666959, -2.065332643502562, 0.5546933514327703),
            [14.626143990828817, -5.308970009418982, 0.0],
            [0.0, 0.0, -1.0],
            0,
            103.66502053950428,
            blend(0.01),
            2,
        ),
        Move::arc(
            p3(33.52915208363884, -10.234699707647358, 0.5546933514327703),
            [20.631410509885576, -9.878419721858243, 0.0],
            [0.0, 0.0, -1.0],
            0,
            116.8970251032698,
            blend(0.01),
            3,
        ),
    ];
    run_changes(
        &moves,
        &[
            (785, Change::Hold),
            (1085, Change::Resume),
            (1252, Change::Override(0.5092759114104941)),
            (1256, Change::Override(1.0783452200462917)),
        ],
    );
}

#[test]
fn an_override_raised_before_an_exact_stop_between_arcs_keeps_the_limits() {
    // Seed 7, program 11844: the raise from 44 % to 68 % comes at 47 mm/s, 35 mm before
    // an exact stop at the end of an arc; the stop model under the new feed (a higher
    // feed lowers its deceleration on arcs) cannot stop there from the emitted state, and
    // the path left 4.2 × over the jerk limit. The raise takes effect at that stop.
    let moves = [
        Move::line(
            p3(6.579718403125165, 6.482333247759574, 0.0),
            103.28660030222517,
            blend(0.01),
            1,
        ),
        Move::arc(
            p3(-9.795686087079616, 5.887183023383097, 0.0),
            [-1.9328281474594267, 15.122765181076076, 0.0],
            [0.0, 0.0, 1.0],
            0,
            105.75772190145393,
            blend(0.01),
            2,
        ),
        Move::arc(
            p3(-7.429994770214218, 7.072568412656725, 0.0),
            [-8.864128499328114, 6.981375071919187, 0.0],
            [0.0, 0.0, 1.0],
            0,
            21.48170479723613,
            blend(0.01),
            3,
        ),
        Move::arc(
            p3(-14.981015246732461, 3.095971702981925, 0.0),
            [-12.096340267859397, 6.775845989686615, 0.0],
            [0.0, 0.0, 1.0],
            0,
            108.10045666184575,
            PathMode::ExactStop,
            4,
        ),
        Move::arc(
            p3(-2.3085584108024664, 21.17469852047668, 0.0),
            [-8.160896506395403, 11.796147552478716, 0.0],
            [0.0, 0.0, 1.0],
            0,
            24.372505720105824,
            PathMode::ExactStop,
            5,
        ),
    ];
    run_changes(
        &moves,
        &[
            (917, Change::Override(0.440640493043002)),
            (1006, Change::Override(0.6809286256810609)),
        ],
    );
}

#[test]
fn braking_at_an_axis_limit_after_an_override_drop_follows_the_axes() {
    // Seed 7, program 2158. After the drop to 56 %, the path brakes at X's acceleration
    // limit on the first arc and the set-point check moves the point in every period. The
    // state taken as the constant-jerk step that reaches each moved point swung ±2 jerk
    // steps around the axes' acceleration (its error grows 3.7 × per period); braking for
    // that state brought the machine to rest 169 mm before its stop, at a dead end it
    // left 13 × over the jerk limit.
    let moves = [
        Move::line(
            p3(6.93387356133781, 2.0547255026630626, 0.0),
            69.32557772129111,
            blend(0.01),
            1,
        ),
        Move::arc(
            p3(15.127052521635191, -18.772495046973184, 0.0),
            [10.125275518342168, -8.714974695535615, 0.0],
            [0.0, 0.0, -1.0],
            0,
            119.33079143689557,
            blend(0.01),
            2,
        ),
        Move::arc(
            p3(20.865025674214152, -13.564500565603694, 0.0),
            [8.785173001718611, -6.020310714098523, 0.0],
            [0.0, 0.0, -1.0],
            0,
            46.076416541129916,
            blend(0.01),
            3,
        ),
        Move::arc(
            p3(28.680470550518073, -17.865290075828828, 0.0),
            [24.653946673185345, -15.930782682079885, 0.0],
            [0.0, 0.0, 1.0],
            0,
            99.30196219344415,
            blend(0.01),
            4,
        ),
        Move::arc(
            p3(28.02703553550343, -20.456641714727173, 0.0),
            [34.7171535281035, -20.76556043548039, 0.0],
            [0.0, 0.0, -1.0],
            0,
            35.40775691662967,
            blend(0.01),
            5,
        ),
    ];
    run_changes(
        &moves,
        &[
            (66, Change::Override(1.398463623000704)),
            (119, Change::Override(0.5598759074543846)),
        ],
    );
}

#[test]
fn braking_for_a_tight_arc_far_before_the_stop_releases_at_the_braking_jerk() {
    // Seed 7, program 15590. After the raise to 144 %, the path must brake hard for the
    // 0.5 mm arc of line 2, 138 mm before the program's end. The stop model's jerk is that
    // arc's (8 100 mm/s³): decelerations it could not release before the speed was gone
    // were refused, the path followed the model's gentle stop profile instead of the
    // braking curve and met the arc too fast (1.18 × the jerk limit).
    let moves = [
        Move::line(
            p3(5.392037121737362, 3.193164490533654, 0.0),
            120.82596332613473,
            blend(0.01),
            1,
        ),
        Move::arc(
            p3(4.845069182021616, 4.0341063933151755, 0.0),
            [5.136226707095972, 3.6251307284028718, 0.0],
            [0.0, 0.0, 1.0],
            0,
            20.767988268161098,
            blend(0.01),
            2,
        ),
        Move::arc(
            p3(-9.385308505900197, 8.466227004953648, 0.0),
            [-0.5848197239671116, 11.661223106714765, 0.0],
            [0.0, 0.0, -1.0],
            0,
            37.48875616556571,
            blend(0.01),
            3,
        ),
        Move::arc(
            p3(0.11992137869049757, 2.695343831594494, 0.0),
            [-1.0418263144629414, 11.495307972760969, 0.0],
            [0.0, 0.0, -1.0],
            0,
            25.084892487369057,
            blend(0.01),
            4,
        ),
        Move::arc(
            p3(11.465175087046225, 11.306889671469428, 0.0),
            [-1.762539996194575, 16.95454373682869, 0.0],
            [0.0, 0.0, -1.0],
            0,
            50.47297662032122,
            PathMode::ExactStop,
            5,
        ),
    ];
    run_changes(
        &moves,
        &[
            (60, Change::Override(0.6344288003050724)),
            (141, Change::Override(1.4444721064663946)),
        ],
    );
}

#[test]
fn an_override_while_a_rollbacks_dead_end_is_ahead_keeps_the_limits() {
    // Seed 7, program 1854, with one more override (97 %) at each period from 430 to 450:
    // found by `sweep_an_override_over_dead_ends` (it adds the override in the periods
    // after each rollback). The path meets a dead end where it enters the 2.2 mm arc of
    // line 2 (at 24 mm/s, where the curve asks for 14.7); three rollbacks, each restarting
    // from the emitted set-point some 200 periods before it, passed it at the third
    // attempt (the braking curve capped at 0.86). At periods 438-444 the override dropped
    // the set-points generated past the dead end together with the rollback's stricter
    // model (`Planner::regenerate`): regenerated under the settings' own model from the
    // emitted set-point (generated under the stricter one, now some 50 periods before
    // the dead end), they met it again, the escalation began again at its first attempt,
    // and the emitted set-point went on along the attempts known to fail into a state
    // that no longer brakes for the curve (it follows the program end's stop profile at
    // 15 mm/s²): 1.08 × the jerk limit on the arc. The override now keeps the stricter
    // model while its dead end lies ahead (as pushes do). Its region starts after the
    // last stop of the path before the dead end: program 63 (below) has its dead end just
    // after a stop, and the kept model, capping the braking curve on the way into that
    // stop too, left no room to land on it (1.56 × the jerk limit).
    let b = blend(0.01);
    let moves = [
        Move::line(
            p3(7.262814795162408, 9.593064182479997, 0.0),
            83.7258096588795,
            b,
            1,
        ),
        Move::arc(
            p3(10.880106416890786, 7.182467073011314, 0.0),
            [8.998815135286232, 8.278755353223442, 0.0],
            [0.0, 0.0, -1.0],
            0,
            108.40951492043163,
            b,
            2,
        ),
        Move::arc(
            p3(3.082190358669646, 11.479012981953383, 0.0),
            [7.032771221378075, 9.424431688554986, 0.0],
            [0.0, 0.0, -1.0],
            0,
            10.457833697476538,
            b,
            3,
        ),
    ];
    for at in 430..=450 {
        let changes = [
            (at, Change::Override(0.97)),
            (1177, Change::Override(1.5999795566976023)),
            (1311, Change::Override(0.9110059025465491)),
        ];
        let result = std::panic::catch_unwind(|| run_changes(&moves, &changes));
        assert!(result.is_ok(), "override of 97 % at period {at}");
    }
}

#[test]
fn an_override_before_a_stop_with_a_dead_end_after_it_keeps_the_limits() {
    // Seed 7, program 63, with one more override (97 % of the one in force: 73.47 %) at
    // periods 885-910, found by `sweep_an_override_over_dead_ends`. A rollback met a dead
    // end 2.3 mm after the stop at the end of line 3 (accelerating at 66 mm/s out of it),
    // and passed it at its first attempt. The override comes 0.03 mm before that stop, at
    // 3.5 mm/s on its braking curve. An override that kept the rollback's stricter model
    // over the whole way up to its dead end capped the braking curve on the way into the
    // stop as well: the state, above the capped curve that close to the stop, braked as
    // hard as the path allows, came to rest short of it at a dead end, and at 891, 899 and
    // 903 left up to 1.56 × over the jerk limit. The stricter model is in force after the
    // last stop before its dead end only.
    let b = blend(0.01);
    let moves = [
        Move::line(
            p3(11.205117506298885, 0.29879781381029646, 0.0),
            145.81028333881315,
            b,
            1,
        ),
        Move::arc(
            p3(
                18.686045478614197,
                -10.012750566007924,
                -0.34359897704993614,
            ),
            [11.410982935427683, -7.421293221853523, 0.0],
            [0.0, 0.0, -1.0],
            0,
            37.798647104794746,
            b,
            2,
        ),
        Move::arc(
            p3(
                19.131464507638515,
                -10.713291412835321,
                -0.34359897704993614,
            ),
            [19.181869839629595, -10.189368660235498, 0.0],
            [0.0, 0.0, 1.0],
            0,
            109.59276164249589,
            b,
            3,
        ),
        Move::arc(
            p3(12.949255579494213, -14.610587852113632, 1.4835941530313153),
            [18.559533086938558, -16.658057023832058, 0.0],
            [0.0, 0.0, -1.0],
            0,
            140.19621306412526,
            PathMode::ExactStop,
            4,
        ),
    ];
    for at in 885..=910 {
        let changes = [
            (245, Change::Override(0.7701362378270622)),
            (358, Change::Override(0.7574200278023)),
            (at, Change::Override(0.7346974269682309)),
        ];
        let result = std::panic::catch_unwind(|| run_changes(&moves, &changes));
        assert!(result.is_ok(), "override of 73.47 % at period {at}");
    }
}

#[test]
fn an_override_after_a_rollback_past_a_tight_arc_keeps_the_limits() {
    // Seed 7, program 18200. With the braking curve of 8057963 the path met a dead end
    // 0.29 mm before the end of line 2's 0.64 mm arc (17.6 mm/s, braking at -193 mm/s²);
    // five rollbacks passed it (the curve capped at 0.59). The override to 96 % at period
    // 516, before the emitted set-point got there, dropped those set-points and the
    // rollback's stricter model: regenerated, they met the same dead end 57 periods ahead
    // of the emitted one, the escalation began again at its first attempt, no buffered
    // state fitted by the fifth, and from the emitted state the path could not avoid it:
    // 1.4 × the jerk limit. The braking curve since (b445d46, valleys inside
    // sub-intervals) meets no dead end there: the program keeps every limit. Keeping the
    // stricter model through the override also fixed it on 8057963's curve (see
    // `an_override_while_a_rollbacks_dead_end_is_ahead_keeps_the_limits`).
    let b = blend(0.01);
    let moves = [
        Move::line(
            p3(14.850401447407094, 1.2894282673584467, 0.0),
            44.74027781214412,
            b,
            1,
        ),
        Move::arc(
            p3(14.419277856656718, 1.0672152637617625, 0.0),
            [14.90567251222521, 0.6528690094664281, 0.0],
            [0.0, 0.0, -1.0],
            0,
            45.172948236086384,
            b,
            2,
        ),
        Move::arc(
            p3(26.256957192780728, -3.81438766210094, 0.0),
            [19.544272383959473, -3.2986268797750276, 0.0],
            [0.0, 0.0, -1.0],
            0,
            61.396859317386394,
            b,
            3,
        ),
        Move::arc(
            p3(43.84791036004072, 2.8468955855247717, 0.0),
            [36.61503995863475, -4.610238059201817, 0.0],
            [0.0, 0.0, 1.0],
            0,
            98.68995133300945,
            PathMode::ExactStop,
            4,
        ),
        Move::arc(
            p3(37.478924648090235, -14.560656335053018, 0.0),
            [36.78295496043851, -4.437116664801921, 0.0],
            [0.0, 0.0, 1.0],
            0,
            10.443050015562832,
            b,
            5,
        ),
    ];
    run_changes(
        &moves,
        &[
            (516, Change::Override(0.9590121361828143)),
            (690, Change::Override(1.5994443366590627)),
        ],
    );
}

/// One program of the random arc family, for diagnosis:
/// `ARC_SEED=7 ARC_INDEX=18200 cargo test --release -p rtcnc-motion --test suite
/// -- --ignored online_changes::one_random_arc_program --nocapture` (with `--features diagnostics` and
/// `RTCNC_MOTION_TRACE=1` for the generator's trace on stderr). `ARC_INDEX` may be a range
/// `FIRST..END`: every program in it is run and those exceeding a limit are listed.
#[test]
#[ignore = "a diagnosis tool: set ARC_SEED and ARC_INDEX"]
fn one_random_arc_program() {
    let seed: u64 = std::env::var("ARC_SEED").map_or(7, |s| s.parse().unwrap());
    let index = std::env::var("ARC_INDEX").unwrap_or_else(|_| "0".into());
    let (first, end) = match index.split_once("..") {
        Some((a, b)) => (a.parse::<usize>().unwrap(), b.parse::<usize>().unwrap()),
        None => {
            let i = index.parse::<usize>().unwrap();
            (i, i + 1)
        }
    };
    let mut cases = random_arc_cases(seed, end);
    // `ARC_EXTRA=PERIOD:OVERRIDE` adds an override to every program run.
    if let Ok(extra) = std::env::var("ARC_EXTRA") {
        let (at, f) = extra.split_once(':').unwrap();
        for (_, changes) in &mut cases {
            changes.push((at.parse().unwrap(), Change::Override(f.parse().unwrap())));
        }
    }
    let mut failed = Vec::new();
    for (case, (moves, changes)) in cases.iter().enumerate().skip(first) {
        if end - first == 1 {
            eprintln!("{moves:#?}\n{changes:?}");
        }
        let result = std::panic::catch_unwind(|| run_changes(moves, changes));
        if let Err(e) = result {
            let msg = panic_message(&*e);
            eprintln!("seed {seed} program {case}: {msg}");
            failed.push(case);
        }
    }
    eprintln!(
        "seed {seed}, programs {first}..{end}: {} exceed a limit: {failed:?}",
        failed.len()
    );
    assert!(failed.is_empty());
}

/// The text a failed assertion panicked with (empty when it carries none).
fn panic_message(e: &(dyn std::any::Any + Send)) -> String {
    e.downcast_ref::<String>()
        .cloned()
        .or_else(|| e.downcast_ref::<&str>().map(|s| s.to_string()))
        .unwrap_or_default()
}

/// The value of the feed override in force before period `n` under `changes`.
fn override_before(changes: &[(usize, Change)], n: usize) -> f64 {
    let mut f = 1.0;
    let mut sorted: Vec<_> = changes.iter().filter(|(at, _)| *at < n).collect();
    sorted.sort_by_key(|(at, _)| *at);
    for (_, c) in sorted {
        if let Change::Override(x) = c {
            f = *x;
        }
    }
    f
}

/// A search, for diagnosis: for each program of `ARC_SEED` in `ARC_INDEX` (`FIRST..END`)
/// whose run with its changes meets a dead end (a rollback), the run again with one more
/// override (`SWEEP_FACTOR` × the one in force, default 0.97) at each period from the one
/// the dead end was met in to `SWEEP_AFTER` (default 250) periods later: an override while
/// the set-points generated past a rollback's dead end are still ahead of the emitted one.
/// Lists the runs that exceed a limit. `SWEEP_MIN_ROLLBACKS=3` (periods that roll back in
/// the run) keeps to the programs whose dead ends took several rollbacks.
#[test]
#[ignore = "a diagnosis tool: set ARC_SEED and ARC_INDEX"]
fn sweep_an_override_over_dead_ends() {
    let seed: u64 = std::env::var("ARC_SEED").map_or(7, |s| s.parse().unwrap());
    let index = std::env::var("ARC_INDEX").unwrap_or_else(|_| "0..100".into());
    let after: usize = std::env::var("SWEEP_AFTER").map_or(250, |s| s.parse().unwrap());
    let (first, end) = index
        .split_once("..")
        .map(|(a, b)| (a.parse::<usize>().unwrap(), b.parse::<usize>().unwrap()))
        .unwrap();
    let cases = random_arc_cases(seed, end);
    let (mut runs, mut failed) = (0, 0);
    for (case, (moves, changes)) in cases.iter().enumerate().skip(first) {
        // The periods in which a rollback happened.
        let result = std::panic::catch_unwind(|| {
            let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
            let mut last = 0;
            let mut ev = Vec::new();
            run_with(&mut pl, moves, 400_000, |n, pl| {
                for (at, c) in changes {
                    if *at == n {
                        match *c {
                            Change::Override(f) => pl.set_feed_override(f),
                            Change::Hold => pl.hold(),
                            Change::Resume => pl.resume(),
                            Change::QuickStop => pl.quick_stop(),
                        }
                    }
                }
                let r = pl.stats().rollbacks;
                if r != last && ev.last() != Some(&n) {
                    ev.push(n);
                }
                last = r;
            });
            ev
        });
        let events = result.unwrap_or_default();
        // Only runs with `SWEEP_MIN_ROLLBACKS` periods that roll back or more (default 1).
        let min: usize = std::env::var("SWEEP_MIN_ROLLBACKS").map_or(1, |s| s.parse().unwrap());
        if events.len() < min {
            continue;
        }
        let factor: f64 = std::env::var("SWEEP_FACTOR").map_or(0.97, |s| s.parse().unwrap());
        let mut tried = std::collections::BTreeSet::new();
        for e in events {
            for p in e.saturating_sub(1)..e + after {
                if !tried.insert(p) || changes.iter().any(|(at, _)| *at == p) {
                    continue;
                }
                let mut ch = changes.clone();
                ch.push((p, Change::Override(factor * override_before(changes, p))));
                runs += 1;
                if let Err(e) = std::panic::catch_unwind(|| run_changes(moves, &ch)) {
                    failed += 1;
                    let msg = e.downcast_ref::<String>().cloned().unwrap_or_default();
                    let msg = msg.split("; first").next().unwrap_or_default();
                    eprintln!("FAIL seed {seed} program {case}: {ch:?}: {msg}");
                }
            }
        }
    }
    eprintln!("seed {seed}, programs {first}..{end}: {failed} of {runs} runs exceed a limit");
}

/// X and Y at V, A, J; Z weaker (configs/sim-mill.toml's): a hold's stop model (from the
/// weakest axis) then brakes harder than a tight arc's own stop model in X and Y.
fn weak_z() -> MachineLimits {
    let mut lim = limits(V, A, J);
    lim.axes[2] = Some(AxisLimits::new(50.0, 800.0, 40_000.0, -1000.0, 1000.0));
    lim
}

/// The periods at which the unchanged run of `moves` comes to rest (its stops and its end).
fn stop_periods(moves: &[Move]) -> Vec<usize> {
    let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
    let tr = run_with(&mut pl, moves, 400_000, |_, _| {});
    (1..tr.speed.len())
        .filter(|&n| tr.speed[n] == 0.0 && tr.speed[n - 1] > 0.0)
        .collect()
}

/// The first `n` programs of the random arc family, each run `runs` times with a hold in
/// the last 150 periods before one of its stops, resumed 1-20 periods later: a resume
/// while the hold's stop still brakes, often into the path's own stop.
fn random_arc_quick_resumes(seed: u64, n: usize, runs: usize) -> Vec<ArcCase> {
    let mut rng = Lcg(seed);
    let mut cases = Vec::new();
    for _ in 0..n {
        let moves = random_arcs(&mut rng);
        let stops = stop_periods(&moves);
        for _ in 0..runs {
            let stop = stops[((rng.f() * stops.len() as f64) as usize).min(stops.len() - 1)];
            let hold = stop.saturating_sub(1 + (rng.f() * 150.0) as usize);
            let resume = hold + 1 + (rng.f() * 20.0) as usize;
            cases.push((
                moves.clone(),
                vec![(hold, Change::Hold), (resume, Change::Resume)],
            ));
        }
    }
    cases
}

#[test]
#[ignore = "a diagnosis tool: set ARC_SEED and ARC_N"]
fn quick_resumes_of_random_arc_programs() {
    let seed: u64 = std::env::var("ARC_SEED").map_or(7, |s| s.parse().unwrap());
    let n: usize = std::env::var("ARC_N").map_or(1000, |s| s.parse().unwrap());
    let mut failed = Vec::new();
    let cases = random_arc_quick_resumes(seed, n, 20);
    let n = cases.len();
    for (case, (moves, changes)) in cases.iter().enumerate() {
        let result = std::panic::catch_unwind(|| {
            run_changes_on(&weak_z(), p3(0.0, 0.0, 0.0), moves, changes)
        });
        if let Err(e) = result {
            let msg = panic_message(&*e);
            eprintln!(
                "program {case} {changes:?}: {}",
                msg.lines().next().unwrap_or("")
            );
            failed.push(case);
        }
    }
    eprintln!(
        "seed {seed}: {} of {n} exceed a limit: {failed:?}",
        failed.len()
    );
    assert!(failed.is_empty());
}

/// The kernel fuzz target's fourth program (fuzz/defects/kernel/
/// acceleration-after-a-resume-on-a-tight-arc): a 2.54 mm circle and a half at F200 in/min,
/// ending in an exact stop, on a machine whose Z is weaker than X and Y.
fn tight_circle() -> [Move; 3] {
    let feed = 200.0 * 25.4 / 60.0;
    [
        Move::line(p3(5.08, 2.54, 0.0), feed, PathMode::ExactStop, 2),
        Move::arc(
            p3(10.16, 2.54, 0.0),
            [7.62, 2.54, 0.0],
            [0.0, 0.0, -1.0],
            1,
            feed,
            PathMode::ExactStop,
            3,
        ),
        Move::line(p3(0.0, 0.0, 0.0), 100.0, PathMode::ExactStop, 4),
    ]
}

#[test]
fn a_resume_while_the_hold_brakes_into_a_tight_arcs_end_keeps_the_limits() {
    // The hold's stop model is the weakest axis's (Z: 800 mm/s², half of it for a hold);
    // at the end of this arc the path's own model allows less, the centripetal load taking
    // most of X's and Y's 1000 mm/s². A resume 2-11 periods after a hold 46-59 periods
    // before the arc's end left the path's model no way to stop there: 14.5 × the jerk
    // limit (hold at 708, resume at 710). 86 of this block's 150 runs failed.
    let moves = tight_circle();
    let arc_end = 754;
    assert_eq!(
        stop_periods(&moves)[1],
        arc_end,
        "the arc ends where it did"
    );
    let mut failed = Vec::new();
    for hold in arc_end - 60..=arc_end - 46 {
        for gap in 2..=11 {
            let changes = [(hold, Change::Hold), (hold + gap, Change::Resume)];
            let run = || run_changes_on(&weak_z(), p3(0.0, 0.0, 0.0), &moves, &changes);
            if std::panic::catch_unwind(run).is_err() {
                failed.push((hold, gap));
            }
        }
    }
    assert!(failed.is_empty(), "holds and gaps over a limit: {failed:?}");
}

/// Runs of the random arc family that exceeded the jerk limit (up to 9.4 ×) when a resume
/// came while the hold's stop braked harder than the path's model could go on from:
/// [`random_arc_quick_resumes`] of seed 7, 500 programs, runs 1292, 4817 and 5312.
const QUICK_RESUME_RUNS_OVER: [usize; 3] = [1292, 4817, 5312];

#[test]
fn random_arcs_with_quick_resumes_keep_every_limit() {
    // 3 of the 10 000 runs of release builds exceeded the jerk before a resume waited
    // for the path's own stop model to fit; debug builds run those 3 and the first 160.
    let programs = if cfg!(debug_assertions) { 266 } else { 500 };
    let cases = random_arc_quick_resumes(7, programs, 20);
    let runs: Vec<usize> = if cfg!(debug_assertions) {
        (0..160).chain(QUICK_RESUME_RUNS_OVER).collect()
    } else {
        (0..cases.len()).collect()
    };
    for run in runs {
        let (moves, changes) = &cases[run];
        let result = std::panic::catch_unwind(|| {
            run_changes_on(&weak_z(), p3(0.0, 0.0, 0.0), moves, changes)
        });
        assert!(result.is_ok(), "run {run}: {moves:?} {changes:?}");
    }
}

/// A search, for diagnosis: the random line programs of `ARC_SEED` (default 11), `ARC_N`
/// of them (default 500), each run 20 times with a hold in the last 150 periods before one
/// of its stops and a resume 1-20 periods later (`AFTER_REST=1`: 400 periods later), on a
/// machine whose Z is weaker (`UNIFORM=1`: the same limits on every axis).
#[test]
#[ignore = "a diagnosis tool: set ARC_SEED and ARC_N"]
fn quick_resumes_of_random_line_programs() {
    let n: usize = std::env::var("ARC_N").map_or(500, |s| s.parse().unwrap());
    let weak = std::env::var_os("UNIFORM").is_none();
    let lim = if weak { weak_z() } else { limits(V, A, J) };
    let mut rng = Lcg(std::env::var("ARC_SEED").map_or(11, |s| s.parse().unwrap()));
    let (mut runs, mut failed) = (0, 0);
    for case in 0..n {
        let (spec, moves) = random_lines(&mut rng);
        let stops = stop_periods(&moves);
        for _ in 0..20 {
            let stop = stops[((rng.f() * stops.len() as f64) as usize).min(stops.len() - 1)];
            let hold = stop.saturating_sub(1 + (rng.f() * 150.0) as usize);
            let mut resume = hold + 1 + (rng.f() * 20.0) as usize;
            if std::env::var_os("AFTER_REST").is_some() {
                resume = hold + 400;
            }
            let changes = [(hold, Change::Hold), (resume, Change::Resume)];
            runs += 1;
            if std::panic::catch_unwind(|| {
                run_changes_on(&lim, p3(0.0, 0.0, 0.0), &moves, &changes)
            })
            .is_err()
            {
                failed += 1;
                eprintln!("FAIL case {case} SPEC=\"{spec}\" {changes:?}");
            }
        }
    }
    eprintln!("lines, weak Z {weak}: {failed} of {runs} exceed a limit");
    assert_eq!(failed, 0);
}

/// Seed 11's random line program 290 ([`quick_resumes_of_random_line_programs`]): a
/// 4.08 mm line at 141.7 mm/s after a blend at 76 mm/s, ending the program.
fn line_program_290() -> Vec<Move> {
    parse_spec(
        "6.750932878029321 6.8128517202837955 -13.45608887130863 119.3800055703978 S; \
         -0.9320629179615771 0.3443021124420227 -11.561758106969023 52.064192649969385 B 0.01; \
         -13.330160221738044 13.741882743805157 -11.561758106969023 76.05314259099404 B 0.1; \
         -16.50685063406287 16.297241013142703 -11.561758106969023 141.70990181600695 E",
    )
}

#[test]
fn a_hold_before_a_programs_end_keeps_the_limits() {
    // The generator, braking for the program's end, meets a dead end
    // (its landing cannot release the deceleration in time) and rolls back under a
    // stricter model. A hold requested 3.5-4.8 mm before the end (its own stop reaches
    // past the end, so the path's stop is the hold's) dropped that model: the same dead
    // end came back with nothing generated before it to roll back to, and the end was
    // reached at up to 4.3 x the acceleration and 86 x the jerk limit (6.4 x and 128 x
    // with a resume 1-4 periods after the hold). 59 of these 105 runs exceeded a limit,
    // 17 of the 21 holds resumed only at rest. The hold now keeps the model while its
    // dead end lies ahead.
    let moves = line_program_290();
    let mut failed = Vec::new();
    for hold in 780..=800 {
        for resume_after in [1, 2, 3, 4, 400] {
            let changes = [(hold, Change::Hold), (hold + resume_after, Change::Resume)];
            if std::panic::catch_unwind(|| run_changes(&moves, &changes)).is_err() {
                failed.push((hold, resume_after));
            }
        }
    }
    assert!(
        failed.is_empty(),
        "holds and resumes over a limit: {failed:?}"
    );
}

#[test]
fn an_abort_or_a_quick_stop_before_a_programs_end_keeps_the_limits() {
    // As the hold above: their stops reach past the program's end, whose dead end came
    // back when they dropped the rollback's model. Before they kept it, 25 of these 31
    // aborts and 3 of the 31 quick stops exceeded a limit.
    let moves = line_program_290();
    let mut failed = Vec::new();
    for at in 770..=800 {
        for quick in [false, true] {
            let run = || {
                let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
                let tr = run_with(&mut pl, &moves, 400_000, |n, pl| {
                    if n == at {
                        if quick { pl.quick_stop() } else { pl.abort() }
                    }
                });
                assert_limits(&tr, V, A, J);
                assert_eq!(pl.stats().limit_violations, 0, "{:?}", pl.stats());
            };
            if std::panic::catch_unwind(run).is_err() {
                failed.push((at, if quick { "quick stop" } else { "abort" }));
            }
        }
    }
    assert!(failed.is_empty(), "stops over a limit: {failed:?}");
}

/// The stops of [`a_stop_in_a_fast_line_before_a_slow_one_keeps_its_profile`].
#[derive(Debug, Clone, Copy, PartialEq)]
enum StopRequest {
    Hold,
    Abort,
    Quick,
}

/// The longest a stop may take from path speed `v` and acceleration `a`: the acceleration
/// brought down to 0 at the stop's jerk while the speed still grows, that speed braked at
/// the stop's deceleration with its jerk ramping in and out, plus 20 periods for the
/// landing. A hold and an abort brake with half the axes' deceleration and jerk, a quick
/// stop with their quick-stop values at 99 % (here the same as the normal ones), each
/// planned at 97 % and 90 % of them (docs/motion.md).
fn stop_time_bound(kind: StopRequest, v: f64, a: f64) -> f64 {
    let share = if kind == StopRequest::Quick {
        0.99
    } else {
        0.5
    };
    let (ah, jh) = (0.97 * share * A, 0.9 * share * J);
    let a = a.max(0.0);
    a / jh + (v + a * a / (2.0 * jh)) / ah + ah / jh + 20.0 * T
}

#[test]
fn a_stop_in_a_fast_line_before_a_slow_one_keeps_its_profile() {
    // A short fast line (a rapid to a canned cycle's R plane) runs on into a slow one (its
    // feed below R); held while the fast line still accelerates, the hold's own stop
    // reached past the junction while the path braked harder for the slow line's feed.
    // The hold's point stayed out there and the slow line fed on to it: at 1.35 mm/s for
    // over a second on the mill (crates/kernel/tests/hold_in_a_canned_cycle.rs). Random
    // directions, lengths and feeds, collinear or turned by up to 30°; held, or aborted
    // (the same stop), or quick-stopped, at every period of the fast line. Before the fix,
    // 3 848 of the 13 968 holds and aborts (in release builds; 366 of 1 280 in debug
    // builds) came to rest later than the bound, some after more than 1.3 s; 9 quick stops
    // (of case 20: `a_quick_stop_braking_hard_into_a_slow_line_keeps_the_jerk_limit`) went
    // over the jerk limit.
    let mut rng = Lcg(20_261_128);
    let cases = if cfg!(debug_assertions) { 6 } else { 60 };
    let mut late = Vec::new();
    let mut over = Vec::new();
    let mut runs = 0;
    for case in 0..cases {
        let dir = {
            let u = [rng.f() - 0.5, rng.f() - 0.5, rng.f() - 0.5];
            let n = (u[0] * u[0] + u[1] * u[1] + u[2] * u[2]).sqrt().max(1e-3);
            u.map(|c| c / n)
        };
        let first = 0.3 + 4.7 * rng.f();
        let second = 2.0 + 6.0 * rng.f();
        let fast = 20.0 + 80.0 * rng.f();
        let slow = 0.5 + 19.5 * rng.f();
        let turn = if rng.f() < 0.5 { 0.0 } else { 0.5 * rng.f() };
        let bent = [dir[0] + turn * dir[1], dir[1] - turn * dir[0], dir[2]];
        let end1 = dir.map(|c| c * first);
        let end2 = [0, 1, 2].map(|i| end1[i] + bent[i] * second);
        let line =
            |e: [f64; 3], f: f64, mode: PathMode| Move::line(p3(e[0], e[1], e[2]), f, mode, 2);
        let moves = [
            line(end1, fast, blend(0.01)),
            line(end2, slow, PathMode::ExactPath),
        ];
        // The fast line's length in periods, from a run without a hold.
        let plain = {
            let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
            run_with(&mut pl, &moves, 400_000, |_, _| {})
        };
        let fast_periods = plain
            .pts
            .iter()
            .position(|p| dist(p, &p3(end1[0], end1[1], end1[2])) < 0.01)
            .unwrap_or(plain.pts.len());
        let kinds = [StopRequest::Hold, StopRequest::Abort, StopRequest::Quick];
        for (hold, kind) in (1..fast_periods.min(200)).flat_map(|n| kinds.map(|k| (n, k))) {
            runs += 1;
            let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
            let mut resumed = false;
            let tr = run_with(&mut pl, &moves, 400_000, |n, pl| {
                if n == hold {
                    match kind {
                        StopRequest::Hold => pl.hold(),
                        StopRequest::Abort => pl.abort(),
                        StopRequest::Quick => pl.quick_stop(),
                    }
                }
                // Resumed long after any stop within the bound, so that the run ends.
                if n == hold + 3000 && !resumed {
                    pl.resume();
                    resumed = true;
                }
            });
            let within = std::panic::catch_unwind(|| assert_limits(&tr, V, A, J)).is_ok();
            if !within || pl.stats().limit_violations > 0 {
                over.push(format!(
                    "case {case} (fast {fast:.1} mm/s over {first:.2} mm, slow {slow:.2} \
                     mm/s), {kind:?} at period {hold}: over a limit"
                ));
                continue;
            }
            // tr.speed[n] is the speed after period n; the stop acts from period `hold`.
            let (v, a) = if hold >= 2 {
                let v = tr.speed[hold - 1];
                (v, (v - tr.speed[hold - 2]) / T)
            } else {
                (tr.speed[hold - 1], A)
            };
            // The hold's rest: 50 periods at speed 0, before the resume.
            let held = (hold..tr.speed.len().min(hold + 3000))
                .find(|&n| {
                    tr.speed[n..(n + 50).min(tr.speed.len())]
                        .iter()
                        .all(|s| *s == 0.0)
                })
                .map_or(f64::INFINITY, |n| (n - hold) as f64 * T);
            let bound = stop_time_bound(kind, v, a);
            if held > bound {
                late.push(format!(
                    "case {case} (fast {fast:.1} mm/s over {first:.2} mm, slow {slow:.2} \
                     mm/s), {kind:?} at period {hold}: at rest after {held:.3} s, bound {bound:.3} s"
                ));
            }
        }
    }
    assert!(runs > 10 * cases, "{runs} stops");
    assert!(
        over.is_empty(),
        "{} of {runs} stops over a limit:\n{}",
        over.len(),
        over[..over.len().min(20)].join("\n")
    );
    assert!(
        late.is_empty(),
        "{} of {runs} stops late:\n{}",
        late.len(),
        late[..late.len().min(20)].join("\n")
    );
}

#[test]
fn a_quick_stop_braking_hard_into_a_slow_line_keeps_the_jerk_limit() {
    // Case 20 of the family above: a 1.57 mm line at 60.7 mm/s into one at 0.99 mm/s. A
    // quick stop while the path brakes at up to 900 mm/s² for the slow line: its stop model
    // (90 % of the jerk) cannot release that deceleration before the speed is zero, and the
    // stop point it gave (where the speed reaches zero, the deceleration still on) could
    // not be landed on: a dead end, rollbacks, and the jerk 1.68 × over its limit. The
    // point is now where the path's full jerk brings both to zero. Before the fix 21 of
    // these 75 stops went over a limit.
    let dir = [
        -0.753927615785071,
        -0.5212924212041232,
        -0.39980915666325295,
    ];
    let (first, fast, slow, turn) = (
        1.5741969514298764,
        60.73267708384555,
        0.9863932360858281,
        0.03115573463631577,
    );
    let bent = [dir[0] + turn * dir[1], dir[1] - turn * dir[0], dir[2]];
    let end1 = dir.map(|c| c * first);
    let mut over = Vec::new();
    for second in [2.0, 4.0, 8.0] {
        let end2 = [0, 1, 2].map(|i| end1[i] + bent[i] * second);
        let moves = [
            Move::line(p3(end1[0], end1[1], end1[2]), fast, blend(0.01), 2),
            Move::line(p3(end2[0], end2[1], end2[2]), slow, PathMode::ExactPath, 3),
        ];
        for stop_at in 70..95 {
            let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
            let tr = run_with(&mut pl, &moves, 400_000, |n, pl| {
                if n == stop_at {
                    pl.quick_stop()
                }
            });
            let within = std::panic::catch_unwind(|| assert_limits(&tr, V, A, J)).is_ok();
            if !within || pl.stats().limit_violations > 0 {
                over.push((second, stop_at));
            }
        }
    }
    assert!(
        over.is_empty(),
        "quick stops over a limit (second line, period): {over:?}"
    );
}
