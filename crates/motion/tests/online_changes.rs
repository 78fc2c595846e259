//! On-line changes (feed override, hold and resume, quick stop) at any period keep every
//! axis within its limits: the programs the random search of the `stress` example found
//! (each once exceeded a limit), and seeded random programs with changes at random periods.
//! 24 random programs in debug builds, 400 in release
//! (`cargo test --release -p rtcnc-motion --test online_changes`).

mod common;
use common::*;
use rtcnc_motion::{MotionState, Move, PathMode, Planner, TrivialKinematics};

const V: f64 = 100.0;
const A: f64 = 1000.0;
const J: f64 = 50_000.0;

/// Lines from the origin as `x y z feed mode;` (mode `S` exact stop, `E` exact path,
/// `B p` blend with tolerance p), the format the `stress` example prints.
fn program(spec: &str) -> Vec<Move> {
    spec.split(';')
        .filter(|m| !m.trim().is_empty())
        .enumerate()
        .map(|(i, m)| {
            let w: Vec<&str> = m.split_whitespace().collect();
            let x: Vec<f64> = w[..4].iter().map(|v| v.parse().unwrap()).collect();
            let mode = match w[4] {
                "S" => PathMode::ExactStop,
                "E" => PathMode::ExactPath,
                _ => blend(w[5].parse().unwrap()),
            };
            Move::line(p3(x[0], x[1], x[2]), x[3], mode, i as u32 + 1)
        })
        .collect()
}

#[derive(Clone, Copy, Debug)]
enum Change {
    Override(f64),
    Hold,
    Resume,
    QuickStop,
}

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
    let moves = program(
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
    let moves = program(
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
    let moves = program(
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
    let moves = program(
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

/// xorshift64: the programs are the same on every run.
struct Rng(u64);

impl Rng {
    fn f(&mut self) -> f64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        (self.0 >> 11) as f64 / (1u64 << 53) as f64
    }
}

#[test]
fn random_programs_with_random_on_line_changes_keep_every_limit() {
    let n = if cfg!(debug_assertions) { 24 } else { 400 };
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for case in 0..n {
        let k = 1 + (rng.f() * 8.0) as usize;
        let mut moves = Vec::new();
        let mut z = 0.0;
        for i in 0..k {
            let (x, y) = (rng.f() * 40.0 - 20.0, rng.f() * 40.0 - 20.0);
            if rng.f() >= 0.3 {
                z = rng.f() * 40.0 - 20.0;
            }
            let feed = 5.0 + rng.f() * 145.0;
            let r = rng.f();
            let mode = if r < 0.2 {
                PathMode::ExactStop
            } else if r < 0.4 {
                PathMode::ExactPath
            } else {
                blend([0.001, 0.01, 0.1][(rng.f() * 3.0) as usize % 3])
            };
            moves.push(Move::line(p3(x, y, z), feed, mode, i as u32 + 1));
        }
        let mut changes = vec![
            (
                30 + (rng.f() * 600.0) as usize,
                Change::Override(0.2 + rng.f() * 1.5),
            ),
            (30 + (rng.f() * 900.0) as usize, Change::Hold),
        ];
        changes.push((
            changes[1].0 + 5 + (rng.f() * 400.0) as usize,
            Change::Resume,
        ));
        if rng.f() < 0.1 {
            changes.push((30 + (rng.f() * 1500.0) as usize, Change::QuickStop));
        }
        let result = std::panic::catch_unwind(|| run_changes(&moves, &changes));
        assert!(result.is_ok(), "case {case}: {moves:?} {changes:?}");
    }
}
