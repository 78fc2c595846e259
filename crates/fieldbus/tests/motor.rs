//! The motor and load model against closed-form solutions of J·dω/dt = τ − b·ω − T_c·sgn(ω).
//! With `units_per_revolution` = 2π the joint unit is the radian, so the formulas read
//! directly.

use std::f64::consts::PI;

use rtcnc_fieldbus::sim::{MotorConfig, MotorModel};

const STEP: f64 = 62.5e-6;

fn motor(inertia: f64, viscous: f64, coulomb: f64) -> MotorModel {
    let config = MotorConfig {
        inertia,
        viscous_friction: viscous,
        coulomb_friction: coulomb,
        torque_limit: 10.0,
    };
    MotorModel::new(&config, 2.0 * PI, 0.0)
}

fn close(actual: f64, expected: f64) -> bool {
    (actual - expected).abs() <= 1e-12 + 1e-9 * expected.abs()
}

#[test]
fn viscous_friction_under_constant_torque_gives_the_exact_exponential() {
    let (j, b, torque) = (2e-4, 1e-3, 0.5);
    let mut m = motor(j, b, 0.0);
    let (terminal, rate) = (torque / b, b / j);
    for k in 1..=8000 {
        m.advance(torque, STEP);
        let t = k as f64 * STEP;
        let omega = terminal * (1.0 - (-rate * t).exp());
        let theta = terminal * (t - (1.0 - (-rate * t).exp()) / rate);
        assert!(
            close(m.velocity(), omega),
            "t {t}: ω {} expected {omega}",
            m.velocity()
        );
        assert!(
            close(m.position(), theta),
            "t {t}: θ {} expected {theta}",
            m.position()
        );
    }
}

#[test]
fn the_result_does_not_depend_on_the_step() {
    let (j, b, torque) = (2e-4, 1e-3, 0.5);
    let (mut fine, mut coarse) = (motor(j, b, 0.0), motor(j, b, 0.0));
    for _ in 0..1000 {
        fine.advance(torque, 1e-5);
    }
    coarse.advance(torque, 1e-2);
    assert!(close(fine.velocity(), coarse.velocity()));
    assert!(close(fine.position(), coarse.position()));
}

#[test]
fn coulomb_friction_holds_the_load_until_the_torque_exceeds_it() {
    let (j, coulomb) = (1e-4, 0.2);
    let mut m = motor(j, 0.0, coulomb);
    for _ in 0..1000 {
        m.advance(0.199_999, STEP);
        m.advance(-0.2, STEP);
    }
    assert_eq!((m.position(), m.velocity()), (0.0, 0.0));
    let torque = 0.25;
    for k in 1..=1000 {
        m.advance(torque, STEP);
        let t = k as f64 * STEP;
        let acceleration = (torque - coulomb) / j;
        assert!(close(m.velocity(), acceleration * t));
        assert!(close(m.position(), acceleration * t * t / 2.0));
    }
}

#[test]
fn coulomb_friction_stops_a_coasting_load_mid_step_and_it_stays() {
    let (j, coulomb, v0) = (1e-4, 0.2, 7.0);
    let mut m = motor(j, 0.0, coulomb);
    m.place(0.0, v0);
    let deceleration = coulomb / j; // 2000 rad/s²: stops after 3.5 ms
    for _ in 0..10 {
        m.advance(0.0, 1e-3);
    }
    assert_eq!(m.velocity(), 0.0);
    assert!(close(m.position(), v0 * v0 / (2.0 * deceleration)));
}

#[test]
fn viscous_and_coulomb_friction_stop_a_coasting_load_at_the_analytic_point() {
    // ω(t) = −T_c/b + (ω0 + T_c/b)·e^(−bt/J) reaches zero at t* = (J/b)·ln(1 + bω0/T_c).
    let (j, b, coulomb, v0) = (1e-4, 2e-3, 0.1, 30.0);
    let mut m = motor(j, b, coulomb);
    m.place(0.0, -v0);
    let floor = coulomb / b;
    let rate = b / j;
    let stop_time = (1.0 + v0 / floor).ln() / rate;
    let distance = (v0 + floor) * (1.0 - (-rate * stop_time).exp()) / rate - floor * stop_time;
    let mut t = 0.0;
    while t < stop_time - STEP {
        m.advance(0.0, STEP);
        t += STEP;
        let omega = floor - (v0 + floor) * (-rate * t).exp();
        assert!(close(m.velocity(), omega), "t {t}");
    }
    for _ in 0..100 {
        m.advance(0.0, STEP);
    }
    assert_eq!(m.velocity(), 0.0);
    assert!(
        close(m.position(), -distance),
        "{} vs {}",
        m.position(),
        -distance
    );
}

#[test]
fn a_torque_above_friction_reverses_the_load_through_zero() {
    // Moving at +1 rad/s against −0.3 N·m with 0.1 N·m Coulomb friction, no viscous:
    // decelerates at 0.4/J to rest, then accelerates backwards at 0.2/J.
    let (j, coulomb) = (1e-4, 0.1);
    let mut m = motor(j, 0.0, coulomb);
    m.place(0.0, 1.0);
    m.advance(-0.3, 1e-3);
    let stop = 1.0 / (0.4 / j); // 0.25 ms
    let back = 1e-3 - stop;
    assert!(close(m.velocity(), -0.2 / j * back));
    let expected = 1.0 * stop / 2.0 - 0.2 / j * back * back / 2.0;
    assert!(close(m.position(), expected));
}
