//! The CiA 402 state machine against the standard's tables (IEC 61800-7-201: statusword
//! state coding, device-control commands, transitions 1 to 16), then the simulated drive
//! walking it through the process image.

use rtcnc_fieldbus::cia402::error_code;
use rtcnc_fieldbus::sim::{
    InjectedFault, SimulatedJointConfig, SimulatedMachine, SimulatedMachineConfig,
};
use rtcnc_fieldbus::{
    Cia402State as S, ControlWord, DeviceCommand as C, DriveMode, Fieldbus, ProcessInputs,
    ProcessOutputs, StatusWord,
};

const ALL_STATES: [S; 8] = [
    S::NotReadyToSwitchOn,
    S::SwitchOnDisabled,
    S::ReadyToSwitchOn,
    S::SwitchedOn,
    S::OperationEnabled,
    S::QuickStopActive,
    S::FaultReactionActive,
    S::Fault,
];

#[test]
fn statusword_state_coding_follows_the_standard_table() {
    // (state, statusword pattern with every "don't care" bit set, with none set)
    let table = [
        (
            S::NotReadyToSwitchOn,
            0b1111_1111_1011_0000,
            0b0000_0000_0000_0000,
        ),
        (
            S::SwitchOnDisabled,
            0b1111_1111_1111_0000,
            0b0000_0000_0100_0000,
        ),
        (
            S::ReadyToSwitchOn,
            0b1111_1111_1011_0001,
            0b0000_0000_0010_0001,
        ),
        (S::SwitchedOn, 0b1111_1111_1011_0011, 0b0000_0000_0010_0011),
        (
            S::OperationEnabled,
            0b1111_1111_1011_0111,
            0b0000_0000_0010_0111,
        ),
        (
            S::QuickStopActive,
            0b1111_1111_1001_0111,
            0b0000_0000_0000_0111,
        ),
        (
            S::FaultReactionActive,
            0b1111_1111_1011_1111,
            0b0000_0000_0000_1111,
        ),
        (S::Fault, 0b1111_1111_1011_1000, 0b0000_0000_0000_1000),
    ];
    for (state, with_dont_cares, bare) in table {
        assert_eq!(
            StatusWord(with_dont_cares).state(),
            state,
            "{with_dont_cares:#018b}"
        );
        assert_eq!(StatusWord(bare).state(), state, "{bare:#06x}");
        assert_eq!(StatusWord(StatusWord::state_bits(state)).state(), state);
    }
}

#[test]
fn controlword_commands_follow_the_standard_table() {
    // Bits 3..0 of the standard's device-control command table; x bits both ways.
    let table = [
        (0b0110, C::Shutdown),
        (0b1110, C::Shutdown),
        (0b0111, C::SwitchOn),
        (0b1111, C::EnableOperation),
        (0b0000, C::DisableVoltage),
        (0b1101, C::DisableVoltage),
        (0b0101, C::DisableVoltage),
        (0b0010, C::QuickStop),
        (0b1011, C::QuickStop),
    ];
    for (bits, command) in table {
        assert_eq!(ControlWord(bits).command(), command, "{bits:#06b}");
    }
    assert_eq!(ControlWord::shutdown().0, 0x0006);
    assert_eq!(ControlWord::switch_on().0, 0x0007);
    assert_eq!(ControlWord::disable_operation().0, 0x0007);
    assert_eq!(ControlWord::enable_operation().0, 0x000F);
    assert_eq!(ControlWord::disable_voltage().0, 0x0000);
    assert_eq!(ControlWord::quick_stop().0, 0x0002);
    assert_eq!(ControlWord::fault_reset().0, 0x0080);
}

#[test]
fn commanded_transitions_follow_the_standard() {
    let transitions = [
        (2, S::SwitchOnDisabled, C::Shutdown, S::ReadyToSwitchOn),
        (3, S::ReadyToSwitchOn, C::SwitchOn, S::SwitchedOn),
        (3, S::ReadyToSwitchOn, C::EnableOperation, S::SwitchedOn),
        (4, S::SwitchedOn, C::EnableOperation, S::OperationEnabled),
        (5, S::OperationEnabled, C::SwitchOn, S::SwitchedOn),
        (6, S::SwitchedOn, C::Shutdown, S::ReadyToSwitchOn),
        (
            7,
            S::ReadyToSwitchOn,
            C::DisableVoltage,
            S::SwitchOnDisabled,
        ),
        (7, S::ReadyToSwitchOn, C::QuickStop, S::SwitchOnDisabled),
        (8, S::OperationEnabled, C::Shutdown, S::ReadyToSwitchOn),
        (
            9,
            S::OperationEnabled,
            C::DisableVoltage,
            S::SwitchOnDisabled,
        ),
        (10, S::SwitchedOn, C::DisableVoltage, S::SwitchOnDisabled),
        (10, S::SwitchedOn, C::QuickStop, S::SwitchOnDisabled),
        (11, S::OperationEnabled, C::QuickStop, S::QuickStopActive),
        (
            12,
            S::QuickStopActive,
            C::DisableVoltage,
            S::SwitchOnDisabled,
        ),
        (
            16,
            S::QuickStopActive,
            C::EnableOperation,
            S::OperationEnabled,
        ),
    ];
    let commands = [
        C::Shutdown,
        C::SwitchOn,
        C::EnableOperation,
        C::DisableVoltage,
        C::QuickStop,
    ];
    for state in ALL_STATES {
        for command in commands {
            let expected = transitions
                .iter()
                .find(|(_, from, with, _)| *from == state && *with == command)
                .map_or(state, |(_, _, _, to)| *to);
            assert_eq!(
                state.after_command(command),
                expected,
                "{state:?} + {command:?}"
            );
        }
    }
    // Transition 15, and no other state reacts to a fault reset.
    for state in ALL_STATES {
        let expected = if state == S::Fault {
            S::SwitchOnDisabled
        } else {
            state
        };
        assert_eq!(state.after_fault_reset(), expected);
    }
}

#[test]
fn enabling_walks_one_transition_per_step() {
    let mut state = S::SwitchOnDisabled;
    let mut path = vec![state];
    for _ in 0..5 {
        state = state.after_command(state.controlword_towards(true).command());
        path.push(state);
    }
    assert_eq!(
        path,
        [
            S::SwitchOnDisabled,
            S::ReadyToSwitchOn,
            S::SwitchedOn,
            S::OperationEnabled,
            S::OperationEnabled,
            S::OperationEnabled
        ]
    );
    assert_eq!(
        S::OperationEnabled.controlword_towards(false),
        ControlWord::disable_voltage()
    );
    assert_eq!(
        S::Fault.controlword_towards(true),
        ControlWord::disable_voltage()
    );
}

fn one_drive(drive: DriveMode) -> (SimulatedMachine, ProcessOutputs, ProcessInputs) {
    let config = SimulatedMachineConfig {
        joints: vec![SimulatedJointConfig::with_drive(drive)],
        ..toml::from_str("joints = []").unwrap()
    };
    let machine = SimulatedMachine::new(&config).unwrap();
    let outputs = ProcessOutputs::new(machine.layout());
    let inputs = ProcessInputs::new(machine.layout());
    (machine, outputs, inputs)
}

fn exchange_with(
    machine: &mut SimulatedMachine,
    outputs: &mut ProcessOutputs,
    inputs: &mut ProcessInputs,
    controlword: ControlWord,
) -> S {
    outputs.joints[0].controlword = controlword;
    machine.exchange(0.001, outputs, inputs).unwrap();
    inputs.joints[0].state()
}

#[test]
fn simulated_drive_powers_up_and_enables_through_the_controlword() {
    let (mut machine, mut outputs, mut inputs) = one_drive(DriveMode::Velocity);
    let mut cycle = |cw| exchange_with(&mut machine, &mut outputs, &mut inputs, cw);
    // Transition 1 happens by itself; then one commanded transition per cycle.
    assert_eq!(cycle(ControlWord::enable_operation()), S::SwitchOnDisabled);
    assert_eq!(
        cycle(ControlWord::enable_operation()),
        S::SwitchOnDisabled,
        "needs shutdown"
    );
    assert_eq!(cycle(ControlWord::shutdown()), S::ReadyToSwitchOn);
    assert_eq!(cycle(ControlWord::enable_operation()), S::SwitchedOn);
    assert_eq!(cycle(ControlWord::enable_operation()), S::OperationEnabled);
    assert_eq!(cycle(ControlWord::quick_stop()), S::QuickStopActive);
    assert_eq!(cycle(ControlWord::enable_operation()), S::OperationEnabled);
    assert_eq!(cycle(ControlWord::disable_operation()), S::SwitchedOn);
    assert_eq!(cycle(ControlWord::disable_voltage()), S::SwitchOnDisabled);
    let status = inputs.joints[0].statusword;
    assert!(status.has(StatusWord::REMOTE));
    assert!(!status.has(StatusWord::VOLTAGE_ENABLED));
}

#[test]
fn drive_fault_runs_the_fault_reaction_and_resets_only_on_a_rising_edge_once_cleared() {
    let (mut machine, mut outputs, mut inputs) = one_drive(DriveMode::Velocity);
    for _ in 0..4 {
        let cw = inputs.joints[0].state().controlword_towards(true);
        exchange_with(&mut machine, &mut outputs, &mut inputs, cw);
    }
    assert_eq!(inputs.joints[0].state(), S::OperationEnabled);
    let fault = InjectedFault::DriveFault {
        joint: 0,
        error_code: 0x2310,
    };
    machine.inject(fault).unwrap();
    let enable = ControlWord::enable_operation();
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, enable),
        S::FaultReactionActive
    ); // 13
    assert_eq!(inputs.joints[0].error_code, 0x2310);
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, enable),
        S::Fault
    ); // 14
    assert!(inputs.joints[0].statusword.has(StatusWord::FAULT));
    // The cause is still there: a reset does nothing.
    let reset = ControlWord::fault_reset();
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, reset),
        S::Fault
    );
    machine.clear(fault).unwrap();
    // Bit 7 is still high: no rising edge, no reset.
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, reset),
        S::Fault
    );
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, ControlWord(0)),
        S::Fault
    );
    assert_eq!(
        exchange_with(&mut machine, &mut outputs, &mut inputs, reset),
        S::SwitchOnDisabled
    ); // 15
    assert_eq!(inputs.joints[0].error_code, error_code::NONE);
}
