//! Operator messages: `(MSG,...)` and `(DEBUG,...)` reach the operator when the machine
//! reaches their block, in order with the motion, not when the interpreter reads them.

use crate::common::*;
use rtcnc_kernel::{Command, MachineState};

/// Three 10 mm feed moves at F600 on the benchmark machine (a = 1000 mm/s², j = 50 000
/// mm/s³, 1 ms) with a message after the first and a DEBUG after the second.
const PROGRAM: &str = "G21 G90 G64 P0.01
G1 X10 F600
(MSG,at X10)
G1 X20
#1 = 7
(DEBUG,X is #5420, count #1)
G1 X30
M2
";

#[test]
fn messages_show_when_the_motion_before_them_is_done() {
    let cfg = config("bench-xyz.toml");
    let mut m = Machine::started(&cfg, PROGRAM, "messages.ngc");
    // While the first move runs the interpreter has long read the whole program, yet no
    // message has been shown.
    m.cycles(500);
    assert!(m.sim.handle().take_messages().is_empty());
    assert!(m.until(10.0, |s| s.program_ended && s.state == MachineState::Idle));
    assert!(m.faults.is_empty(), "{:?}", m.faults);
    let messages = m.sim.handle().take_messages();
    assert_eq!(messages.len(), 2, "{messages:?}");

    // Each 10 mm move at 10 mm/s is a rest-to-rest S-curve: the acceleration peaks at
    // sqrt(v·j) = 707 mm/s² < 1000, so there is no constant-acceleration phase and the
    // move takes T = L/v + 2·sqrt(v/j) = 1 + 0.028284 s. The planner reaches the end in
    // the period after T: ceil(T / 1 ms) = 1029 periods after the last set-point at the
    // start. The message is shown in the period after that (the planner reports the path
    // finished one period after its last set-point), and the next move leaves in the
    // period after the message.
    let t = 10.0 / 10.0 + 2.0 * (10.0f64 / 50_000.0).sqrt();
    let n = (t / 0.001).ceil() as u64;
    assert_eq!(n, 1029);
    let last_at = |x: f64| m.samples.iter().rfind(|s| s.axes[0] == x).unwrap().cycle;
    let first_at = |x: f64| m.samples.iter().find(|s| s.axes[0] == x).unwrap().cycle;
    let start = last_at(0.0);
    assert_eq!(first_at(10.0), start + n);
    assert_eq!(messages[0].cycle, start + n + 1);
    assert_eq!(last_at(10.0), messages[0].cycle);
    assert_eq!(first_at(20.0), messages[0].cycle + n);
    assert_eq!(messages[1].cycle, messages[0].cycle + n + 1);
    assert_eq!(last_at(20.0), messages[1].cycle);

    // Times are those of the set-points (1 ms periods), lines and texts as written; DEBUG
    // has its parameters substituted (#5420: the current X).
    for msg in &messages {
        let sample = m.samples.iter().find(|s| s.cycle == msg.cycle).unwrap();
        assert_eq!(msg.time_ns, sample.time_ns);
        assert_eq!(msg.time_ns, msg.cycle * 1_000_000);
    }
    assert_eq!((messages[0].line, messages[0].text.as_str()), (3, "at X10"));
    assert_eq!(
        (messages[1].line, messages[1].text.as_str()),
        (6, "X is 20.000000, count 7.000000")
    );
}

#[test]
fn an_aborted_run_leaves_no_stale_message_for_the_next() {
    let cfg = config("bench-xyz.toml");
    let text = "G21 G90\nG1 X10 F600\n(MSG,first run only)\nG1 X0\n(MSG,second)\nM2\n";
    let mut m = Machine::started(&cfg, text, "abort-messages.ngc");
    m.cycles(300);
    assert!(m.sim.handle().urgent(rtcnc_kernel::Urgent::Abort));
    assert!(m.until(2.0, |s| s.state == MachineState::Idle));
    assert!(m.sim.handle().take_messages().is_empty());
    // The texts the interpreter had read ahead are still queued; an MDI message after
    // the abort shows its own text.
    m.command(Command::Mdi(
        rtcnc_kernel::FixedText::new("(MSG,from MDI)").unwrap(),
    ));
    m.cycles(2);
    assert!(m.until(1.0, |s| s.state == MachineState::Idle));
    let texts = m.take_message_texts();
    assert_eq!(texts, ["from MDI"]);
}
