//! `Planner::move_end`: where the executing program line ends (the status' distance to go).

use crate::common::*;
use rtcnc_motion::{MotionState, Move, PathMode};

#[test]
fn move_end_is_the_programmed_end_of_the_executing_line() {
    let lim = limits(100.0, 1000.0, 50_000.0);
    let mut pl = planner(&lim, p3(0.0, 0.0, 0.0), 64);
    assert_eq!(pl.move_end(), None, "nothing planned");
    let ends = [p3(20.0, 0.0, 0.0), p3(20.0, 10.0, -2.0), p3(0.0, 0.0, 0.0)];
    for (k, e) in ends.iter().enumerate() {
        pl.push(&Move::line(*e, 60.0, PathMode::ExactStop, 10 + k as u32))
            .unwrap();
    }
    pl.flush();
    let mut joints = [0.0; 3];
    let mut seen = [0usize; 3];
    for _ in 0..20_000 {
        let st = pl.next(&mut joints);
        if st.state == MotionState::Idle {
            break;
        }
        let k = (st.line - 10) as usize;
        let end = pl.move_end().expect("a line is executing");
        // Exact stops: the line's pieces end at the programmed point.
        for a in 0..3 {
            assert!(
                (end[a] - ends[k][a]).abs() < 1e-9,
                "line {} end {:?}",
                st.line,
                &end[..3]
            );
        }
        seen[k] += 1;
    }
    assert!(seen.iter().all(|&n| n > 100), "every line ran: {seen:?}");
}
