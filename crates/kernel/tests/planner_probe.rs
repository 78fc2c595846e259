use rtcnc_motion::*;
#[test]
fn probe() {
    let mut lim = MachineLimits { axes: [None; AXES] };
    let mk = |v, a, j, min, max, qa, qj| AxisLimits { max_velocity: v, max_acceleration: a, max_jerk: j, min_position: min, max_position: max, quick_stop_acceleration: qa, quick_stop_jerk: qj };
    lim.axes[0] = Some(mk(100.0, 1000.0, 50000.0, -5.0, 300.0, 2000.0, 100000.0));
    lim.axes[1] = Some(mk(100.0, 1000.0, 50000.0, -5.0, 200.0, 2000.0, 100000.0));
    lim.axes[2] = Some(mk(50.0, 800.0, 40000.0, -100.0, 5.0, 1600.0, 80000.0));
    let kin = TrivialKinematics::identity(&[Axis::X, Axis::Y, Axis::Z]);
    let mut p = Planner::new(&lim, kin, 0.001, 256, [0.0; AXES]).unwrap();
    let mode = PathMode::Blend { tolerance: 0.01, merge_tolerance: 0.0 };
    let mut e = [0.0; AXES]; e[0] = -5.0; e[1] = -5.0; e[2] = 5.0;
    p.push(&Move::rapid(e, mode, 7)).unwrap();
    let mut j = [0.0; 3];
    let mut prev = 0.0;
    for k in 0..400 {
        if k == 5 { let mut e2 = e; e2[2] = -2.0; p.push(&Move::line(e2, 10.0, mode, 8)).unwrap(); p.flush(); }
        let st = p.next(&mut j);
        if k > 150 && k < 330 { eprintln!("{k} x {:.5} z {:.5} dx {:.5} {:?}", j[0], j[2], j[0]-prev, st.state); }
        prev = j[0];
    }
}
