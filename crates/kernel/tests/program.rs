mod common;
use common::*;
use rtcnc_kernel::{Command, MachineState};

#[test]
fn bracket_runs_to_the_end() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(
        &cfg,
        Some(
            std::path::PathBuf::from(
                std::env::var("PROG").unwrap_or("examples/bracket.ngc".into()),
            )
            .canonicalize()
            .unwrap_or(repo().join("examples/bracket.ngc")),
        ),
    );
    m.power_on();
    m.command(Command::Start { from_line: 0 });
    let ended = m.until(120.0, |s| s.program_ended && s.state == MachineState::Idle);
    for f in &m.faults {
        eprintln!("{}", m.sim.handle().describe(f));
    }
    eprintln!("{:?}", m.sim.handle().error_text());
    let st = m.status();
    eprintln!(
        "ended {ended} t={:?} state {:?} axes {:?} samples {}",
        m.sim.now(),
        st.state,
        &st.axes[..3],
        m.samples.len()
    );
    assert!(ended);
}
