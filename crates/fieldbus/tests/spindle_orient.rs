//! The simulated spindle's orientation (M19): it stops at its acceleration, then turns at
//! the orientation speed to the angle by the way the mode asks, and holds it. The number of
//! periods each orientation takes follows from the distance and the speed: at 60 rpm it
//! turns 0.36° per 1 ms period, reports oriented once within 0.5° (the first period k with
//! d − 0.36·k ≤ 0.5) and lands on the angle in period ⌈d / 0.36⌉.

use rtcnc_fieldbus::sim::{SimulatedMachine, SimulatedMachineConfig};
use rtcnc_fieldbus::{Fieldbus, ProcessInputs, ProcessOutputs};

/// No joints; the spindle's defaults: 8000 rpm/s, orientation at 60 rpm (360 °/s), 0.5°.
fn machine() -> SimulatedMachine {
    let config: SimulatedMachineConfig = toml::from_str("joints = []").unwrap();
    SimulatedMachine::new(&config).unwrap()
}

struct Rig {
    machine: SimulatedMachine,
    outputs: ProcessOutputs,
    inputs: ProcessInputs,
}

impl Rig {
    fn new() -> Rig {
        let machine = machine();
        let outputs = ProcessOutputs::new(machine.layout());
        let inputs = ProcessInputs::new(machine.layout());
        Rig {
            machine,
            outputs,
            inputs,
        }
    }

    /// Exchanges until the angle stands; the exchange that first reported oriented, the one
    /// in which the angle arrived and the angles seen.
    fn orient(&mut self, angle: f64, mode: u8) -> (usize, usize, Vec<f64>) {
        self.outputs.spindle.orient = true;
        self.outputs.spindle.orient_angle_deg = angle;
        self.outputs.spindle.orient_mode = mode;
        let mut angles: Vec<f64> = Vec::new();
        let mut oriented = None;
        for n in 1..=10_000 {
            self.machine
                .exchange(0.001, &self.outputs, &mut self.inputs)
                .unwrap();
            let a = self.inputs.spindle.position_deg;
            if self.inputs.spindle.oriented && oriented.is_none() {
                oriented = Some(n);
            }
            if let Some(first) = oriented.filter(|_| angles.last() == Some(&a)) {
                return (first, n - 1, angles);
            }
            angles.push(a);
        }
        panic!("not oriented");
    }
}

#[test]
fn an_orientation_turns_at_the_orientation_speed_the_way_the_mode_asks() {
    let mut rig = Rig::new();
    // From 0 to 90 the shorter way (clockwise): oriented in period ⌈89.5 / 0.36⌉ = 249,
    // at 90 in period 250.
    let (oriented, arrived, angles) = rig.orient(90.0, 0);
    assert_eq!((oriented, arrived), (249, 250));
    assert_eq!(*angles.last().unwrap(), 90.0);
    assert!(angles.windows(2).all(|w| w[1] > w[0]));
    // It holds the angle while the orientation stays commanded.
    let (oriented, arrived, _) = rig.orient(90.0, 0);
    assert_eq!((oriented, arrived), (1, 1));
    // From 90 to 0 always clockwise: 270°, through 180 and 270.
    let (oriented, arrived, angles) = rig.orient(0.0, 1);
    assert_eq!((oriented, arrived), (749, 750));
    assert_eq!(*angles.last().unwrap(), 0.0);
    assert!(angles.iter().any(|&a| a > 260.0 && a < 280.0));
    // From 0 to 315 the shorter way is counter-clockwise: 45°.
    let (oriented, arrived, angles) = rig.orient(315.0, 0);
    assert_eq!((oriented, arrived), (124, 125));
    assert!(angles.iter().all(|&a| a >= 315.0 || a == 0.0));
    // From 315 to 300 always counter-clockwise: 15°, ⌈14.5 / 0.36⌉ = 41, ⌈15 / 0.36⌉ = 42.
    let (oriented, arrived, _) = rig.orient(300.0, 2);
    assert_eq!((oriented, arrived), (41, 42));
    // From 300 to 310 always counter-clockwise: the long way, 350°.
    let (_, arrived, angles) = rig.orient(310.0, 2);
    assert_eq!(arrived, (350.0f64 / 0.36).ceil() as usize);
    assert!(angles.iter().any(|&a| a > 170.0 && a < 190.0));
}

#[test]
fn a_turning_spindle_stops_first_then_orients() {
    let mut rig = Rig::new();
    rig.outputs.spindle.enable = true;
    rig.outputs.spindle.speed_rpm = 800.0;
    // 800 rpm at 8000 rpm/s and 480 000 rpm/s² (the defaults): an S-curve of
    // 800/8000 + 8000/480000 = 0.1167 s, 117 periods to speed.
    for _ in 0..200 {
        rig.machine
            .exchange(0.001, &rig.outputs, &mut rig.inputs)
            .unwrap();
    }
    assert_eq!(rig.inputs.spindle.speed_rpm, 800.0);
    // Stopping takes 117 periods as well; the orientation then turns at most one
    // revolution (1000 periods), and never before the spindle stands.
    let (oriented, arrived, angles) = rig.orient(0.0, 0);
    assert!(
        oriented > 117 && arrived <= 117 + 1000,
        "{oriented} {arrived}"
    );
    assert_eq!(rig.inputs.spindle.speed_rpm, 0.0);
    assert_eq!(*angles.last().unwrap(), 0.0);
    // Dropping the orientation gives the spindle back to its speed command.
    rig.outputs.spindle.orient = false;
    rig.machine
        .exchange(0.001, &rig.outputs, &mut rig.inputs)
        .unwrap();
    assert!(!rig.inputs.spindle.oriented);
    // From rest the acceleration rises at the jerk: 480 000 · 0.001² / 2 rpm.
    assert!((rig.inputs.spindle.speed_rpm - 0.24).abs() < 1e-9);
}
