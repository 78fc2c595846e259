//! A program started while the machine logic asks for a feed hold: found by the kernel fuzz
//! target (fuzz/defects/kernel/door-opened-as-a-program-starts), where the door opened as
//! the program started, nothing moved and the state said `running`, with no word of why.
//! The machine must not move while the request stands, the state must say held by the
//! machine logic, and the program goes on by itself when the request falls (a hold input
//! is level-triggered, as LinuxCNC's feed-hold input). The mill's logic also asks for a
//! hold for a few scans after a reset, when scripts start their program: that start must
//! run through at any servo period.

use crate::common::*;
use rtcnc_kernel::{Command, HoldCause, MachineState, Urgent};

const PROGRAM: &str = "G21 G90 G61.1\nG1 X10 F1200\nM2\n";

fn set_door(m: &Machine, open: bool) {
    m.handle_machine(|machine| machine.set_door_open(open).unwrap());
}

#[test]
fn a_program_started_as_the_door_opens_is_held_by_the_logic_and_goes_on_when_it_is_closed() {
    let cfg = config("sim-mill.toml");
    // The start in the door's period and in each of the next ones: the logic scans every
    // fourth period, so its request rises before, with or after the start.
    for start_after in 0..=9 {
        let mut m = Machine::new(&cfg, Some(program(PROGRAM, "door-start.ngc")));
        m.power_on();
        set_door(&m, true);
        m.cycles(start_after);
        m.command(Command::Start { from_line: 0 });
        let from = m.samples.len();
        m.cycles(300);
        let s = m.status();
        assert_eq!(s.state, MachineState::Held, "start {start_after}: {s:?}");
        assert_eq!(s.hold, Some(HoldCause::MachineLogic), "start {start_after}");
        assert_eq!(
            s.state_text(),
            "held: machine logic requests a feed hold (door open?)"
        );
        // Nothing moved since the start.
        assert!(
            m.samples[from..].iter().all(|p| p.axes[0] == 0.0),
            "start {start_after}"
        );
        // A resume is refused while the door is open.
        assert!(m.sim.handle().urgent(Urgent::Resume));
        m.cycles(50);
        assert_eq!(m.status().state, MachineState::Held, "start {start_after}");
        assert_eq!(m.status().axes[0], 0.0, "start {start_after}");
        // Closed: the program goes on by itself (G1 X10 at 20 mm/s: about 0.5 s).
        set_door(&m, false);
        assert!(
            m.until(3.0, |s| s.program_ended && s.state == MachineState::Idle),
            "start {start_after}: {:?}",
            m.status()
        );
        assert_eq!(m.status().axes[0], 10.0, "start {start_after}");
        assert_eq!(m.status().hold, None, "start {start_after}");
        assert!(m.faults.is_empty(), "start {start_after}: {:?}", m.faults);
    }
}

#[test]
fn an_mdi_line_sent_with_the_door_open_is_held_by_the_logic_until_it_is_closed() {
    let cfg = config("sim-mill.toml");
    let mut m = Machine::new(&cfg, None);
    m.power_on();
    set_door(&m, true);
    m.cycles(10);
    m.command(Command::Mdi(rtcnc_kernel::FixedText::truncated("G0 X5")));
    m.cycles(200);
    assert_eq!(m.status().state, MachineState::Held);
    assert_eq!(m.status().hold, Some(HoldCause::MachineLogic));
    assert_eq!(m.status().axes[0], 0.0);
    set_door(&m, false);
    assert!(m.until(2.0, |s| s.axes[0] == 5.0 && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
}

#[test]
fn a_program_started_as_soon_as_the_drives_are_ready_runs_at_every_servo_period() {
    // The mill's logic asks for a hold until its e-stop chain closes, a few scans after
    // the reset: a program started once the drives are ready (as `rtcnc run` and scripts
    // do) waits for that and then runs by itself.
    for period_us in [100, 250, 500, 1000, 2000, 4000] {
        let cfg = config_at_period("sim-mill.toml", period_us);
        let mut m = Machine::new(&cfg, Some(program(PROGRAM, "after-reset.ngc")));
        m.power_on();
        m.command(Command::Start { from_line: 0 });
        assert!(
            m.until(3.0, |s| s.program_ended && s.state == MachineState::Idle),
            "{period_us} µs: {:?}",
            m.status()
        );
        assert_eq!(m.status().axes[0], 10.0, "{period_us} µs");
        assert!(m.faults.is_empty(), "{period_us} µs: {:?}", m.faults);
    }
}
