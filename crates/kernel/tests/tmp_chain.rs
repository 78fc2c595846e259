//! temporary
mod common;
use common::*;
use rtcnc_kernel::{Command, MachineState};

fn go(text: &str) {
    let cfg = config("sim-lathe.toml");
    let mut m = Machine::new(&cfg, Some(program(text, "t.ngc")));
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ok = m.until(60.0, |s| s.program_ended && s.state == MachineState::Idle);
    let st = m.status();
    eprintln!(
        "ok {ok} state {:?} x {} z {} faults {:?} err {:?}",
        st.state,
        st.axes[0],
        st.axes[2],
        m.faults,
        m.sim.handle().error_text()
    );
    let mut stats = rtcnc_kernel::report::RunStats::new();
    for s in &m.samples {
        stats.add(s, 0.001);
    }
    eprintln!(
        "v {:?} a {:?} j {:?}",
        &stats.max_velocity[..3],
        &stats.max_acceleration[..3],
        &stats.max_jerk[..3]
    );
}

#[test]
fn chain() {
    go("G18 G21 G90 G7\nG0 X20 Z5\nS600 M3\nG33 Z-10 K1.5\nG33 X26 Z-16 K1.5\nG0 X30\nM5\nM2\n");
    go(
        "G18 G21 G90 G7\nG0 X22 Z5\nS600 M3\nG76 P1.5 Z-20 I-1 J0.3 K0.9 Q0 H1 E1 L3\nG0 X30\nM5\nM2\n",
    );
    go(&std::fs::read_to_string(repo().join("examples/gcode/thread.ngc")).unwrap());
}
