//! On-line changes (feed override, hold and resume, quick stop) at any period keep every
//! axis within its limits: the programs the random search of the `stress` example found
//! (each once exceeded a limit), and seeded random programs with changes at random periods.
//! 24 random programs in debug builds, 400 in release
//! (`cargo test --release -p rtcnc-motion --test online_changes`).

mod common;
#[path = "support/line_programs.rs"]
mod line_programs;
use common::*;
use line_programs::{Change, Lcg, parse_spec, random_changes, random_lines};
use rtcnc_motion::{MotionState, Move, Planner, TrivialKinematics};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// Runs `moves` with `changes` applied before the given periods; asserts the limits, no
/// counted violation and (without a quick stop) the exact end point.
fn run_changes(moves: &[Move], changes: &[(usize, Change)]) {
    let mut pl = planner(&limits(V, A, J), p3(0.0, 0.0, 0.0), 256);
    let apply = |n: usize, pl: &mut Planner<TrivialKinematics>| {
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
    };
    let tr = run_with(&mut pl, moves, 400_000, apply);
    assert_limits(&tr, V, A, J);
    assert_eq!(pl.stats().limit_violations, 0, "{:?}", pl.stats());
    assert_eq!(*tr.states.last().unwrap(), MotionState::Idle);
    // (A quick stop drops the program wherever the machine comes to rest.)
    if !changes.iter().any(|(_, c)| matches!(c, Change::QuickStop)) {
        let end = match moves.last().unwrap().kind {
            rtcnc_motion::MoveKind::Line { end, .. } => end,
            _ => unreachable!(),
        };
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
