//! PLCopen Motion Control part 1 blocks on an auxiliary axis, following the PLCopen state
//! diagram and its timing diagrams. The axis: 100 units/s, 1000 units/s², 100 000
//! units/s³, software limits -10..200; scans every 4 ms. Expected times and positions are
//! worked out from the jerk-limited profile in closed form: reaching 100 units/s takes
//! a/j + v/a = 0.01 + 0.1 = 0.11 s and 5.5 units (the profile is symmetric, so the mean
//! velocity is v/2); a move of 90 is 0.11 + 0.79 + 0.11 = 1.01 s.

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{AxisState, PlcConfig, Runtime, Value, compile, motion_error_id};

const CELL: &str = "
VAR_GLOBAL carousel : AXIS_REF; END_VAR
PROGRAM Cell
VAR
  power : MC_Power;
  move1, move2 : MC_MoveAbsolute;
  rel : MC_MoveRelative;
  add : MC_MoveAdditive;
  vel : MC_MoveVelocity;
  stop : MC_Stop;
  halt : MC_Halt;
  home : MC_Home;
  reset : MC_Reset;
  pos : MC_ReadActualPosition;
  status : MC_ReadStatus;
  axerr : MC_ReadAxisError;
  en, x1, x2, xr, xa, xv, xs, xh, xhome, xreset : BOOL;
  p1 : LREAL := 90.0;
  p2 : LREAL := 20.0;
  dist : LREAL := 10.0;
  v : LREAL := 100.0;
END_VAR
power(Axis := carousel, Enable := en);
move1(Axis := carousel, Execute := x1, Position := p1, Velocity := v);
move2(Axis := carousel, Execute := x2, Position := p2, Velocity := v);
rel(Axis := carousel, Execute := xr, Distance := dist, Velocity := v);
add(Axis := carousel, Execute := xa, Distance := dist, Velocity := v);
vel(Axis := carousel, Execute := xv, Velocity := v);
stop(Axis := carousel, Execute := xs, Deceleration := 500.0);
halt(Axis := carousel, Execute := xh);
home(Axis := carousel, Execute := xhome, Position := 5.0);
reset(Axis := carousel, Execute := xreset);
pos(Axis := carousel, Enable := TRUE);
status(Axis := carousel, Enable := TRUE);
axerr(Axis := carousel, Enable := TRUE);
END_PROGRAM";

const AXES: &str = "
[axes.carousel]
velocity = 100.0
acceleration = 1000.0
jerk = 100000.0
min_position = -10.0
max_position = 200.0
";

struct Cell {
    rt: Runtime,
    k: u64,
}

impl Cell {
    fn new() -> Cell {
        let mut rt = Runtime::new(Arc::new(compile(CELL, "cell.st").unwrap()));
        let cfg: PlcConfig = toml::from_str(AXES).unwrap();
        rt.configure(&cfg).unwrap();
        Cell { rt, k: 0 }
    }
    fn set(&mut self, name: &str, on: bool) {
        let r = self.rt.resolve(&format!("Cell.{name}")).unwrap();
        self.rt.write(&r, &Value::Bool(on)).unwrap();
    }
    fn set_real(&mut self, name: &str, x: f64) {
        let r = self.rt.resolve(&format!("Cell.{name}")).unwrap();
        self.rt.write(&r, &Value::Real(x)).unwrap();
    }
    /// Runs scans up to and including scan `k` (at k × 4 ms).
    fn run_to(&mut self, k: u64) {
        while self.k <= k {
            self.rt.scan(Duration::from_millis(4 * self.k)).unwrap();
            self.k += 1;
        }
    }
    fn flag(&self, path: &str) -> bool {
        match self.rt.read_name(&format!("Cell.{path}")).unwrap() {
            Value::Bool(b) => b,
            v => panic!("{path} is {v:?}"),
        }
    }
    fn word(&self, path: &str) -> u64 {
        match self.rt.read_name(&format!("Cell.{path}")).unwrap() {
            Value::UInt(x) => x,
            v => panic!("{path} is {v:?}"),
        }
    }
    fn position(&self) -> f64 {
        match self.rt.read_name("Cell.pos.Position").unwrap() {
            Value::Real(x) => x,
            v => panic!("position is {v:?}"),
        }
    }
    fn state(&self) -> AxisState {
        self.rt.axis("carousel").unwrap().state
    }
    /// (Done, Busy, Active, CommandAborted, Error) of a block.
    fn outputs(&self, fb: &str) -> (bool, bool, bool, bool, bool) {
        let first = if fb == "vel" { "InVelocity" } else { "Done" };
        (
            self.flag(&format!("{fb}.{first}")),
            self.flag(&format!("{fb}.Busy")),
            self.flag(&format!("{fb}.Active")),
            self.flag(&format!("{fb}.CommandAborted")),
            self.flag(&format!("{fb}.Error")),
        )
    }
}

const BUSY: (bool, bool, bool, bool, bool) = (false, true, true, false, false);
const DONE: (bool, bool, bool, bool, bool) = (true, false, false, false, false);
const ABORTED: (bool, bool, bool, bool, bool) = (false, false, false, true, false);
const ERROR: (bool, bool, bool, bool, bool) = (false, false, false, false, true);
const IDLE: (bool, bool, bool, bool, bool) = (false, false, false, false, false);

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() < 1e-9
}

#[test]
fn power_and_an_absolute_move_follow_the_timing_diagram() {
    let mut c = Cell::new();
    c.run_to(0);
    assert_eq!(c.state(), AxisState::Disabled);
    assert!(c.flag("status.Disabled"));
    c.set("en", true);
    c.run_to(1);
    assert!(c.flag("power.Status") && c.flag("power.Valid"));
    assert!(c.flag("status.Standstill"));
    // Execute rises at 100 ms (scan 25).
    c.run_to(24);
    c.set("x1", true);
    c.run_to(25);
    assert_eq!(c.outputs("move1"), BUSY);
    assert!(c.flag("status.DiscreteMotion"));
    // 0.5 s into the move: 5.5 units of acceleration, then 0.39 s at 100 units/s.
    c.run_to(150);
    assert!(close(c.position(), 44.5), "{}", c.position());
    // The move takes 1.01 s: done on the first scan at or after 1.110 s, i.e. 1.112 s.
    c.run_to(277);
    assert_eq!(c.outputs("move1"), BUSY);
    c.run_to(278);
    assert_eq!(c.outputs("move1"), DONE);
    assert!(close(c.position(), 90.0));
    assert_eq!(c.state(), AxisState::Standstill);
    // Done stays while Execute stays TRUE, and goes with it.
    c.run_to(290);
    assert_eq!(c.outputs("move1"), DONE);
    c.set("x1", false);
    c.run_to(291);
    assert_eq!(c.outputs("move1"), IDLE);
}

#[test]
fn a_move_aborted_by_another() {
    let mut c = Cell::new();
    c.set("en", true);
    c.run_to(24);
    c.set("x1", true);
    c.run_to(99);
    c.set("x2", true); // at 0.4 s, towards 20 while moving towards 90
    c.run_to(100);
    assert_eq!(c.outputs("move2"), BUSY);
    // move1 runs before move2 in the program: it sees the abort on its next call.
    assert_eq!(c.outputs("move1"), BUSY);
    c.run_to(101);
    assert_eq!(c.outputs("move1"), ABORTED);
    assert_eq!(c.outputs("move2"), BUSY);
    c.run_to(1000);
    assert_eq!(c.outputs("move2"), DONE);
    assert_eq!(c.outputs("move1"), ABORTED); // while its Execute stays TRUE
    assert!(close(c.position(), 20.0));
    let st = c.rt.axis("carousel").unwrap();
    assert!(st.velocity == 0.0 && st.acceleration == 0.0);
}

#[test]
fn mc_stop_during_a_velocity_move_then_standstill_when_released() {
    let mut c = Cell::new();
    c.set("en", true);
    c.run_to(24);
    c.set("xv", true);
    c.run_to(25); // starts at 0.1 s
    // 100 units/s is reached 0.11 s later: first seen at 0.212 s.
    c.run_to(52);
    assert_eq!(c.outputs("vel"), BUSY);
    c.run_to(53);
    assert_eq!(c.outputs("vel"), (true, true, true, false, false));
    assert_eq!(c.state(), AxisState::ContinuousMotion);
    // MC_Stop at 0.4 s (position 5.5 + 100 × 0.19 = 24.5), decelerating at 500 units/s²:
    // 100/500 + 500/100000 = 0.205 s and 100 × 0.205 / 2 = 10.25 units.
    c.run_to(99);
    c.set("xs", true);
    c.run_to(100);
    assert_eq!(c.outputs("stop"), BUSY);
    assert_eq!(c.state(), AxisState::Stopping);
    c.run_to(101);
    assert_eq!(c.outputs("vel"), ABORTED);
    c.run_to(151);
    assert_eq!(c.outputs("stop"), BUSY);
    c.run_to(152);
    assert_eq!(c.outputs("stop"), DONE);
    assert!(close(c.position(), 34.75), "{}", c.position());
    // While MC_Stop's Execute is TRUE the axis stays in Stopping and refuses motion.
    c.run_to(159);
    c.set("x1", true);
    c.run_to(160);
    assert_eq!(c.outputs("move1"), ERROR);
    assert_eq!(c.word("move1.ErrorID"), motion_error_id::STOPPING as u64);
    assert!(c.flag("status.Stopping"));
    c.run_to(169);
    c.set("xs", false);
    c.run_to(170);
    assert_eq!(c.state(), AxisState::Standstill);
    assert!(c.flag("status.Standstill"));
    c.set("x1", false);
    c.run_to(171);
    assert_eq!(c.outputs("move1"), IDLE);
    c.set("x1", true);
    c.run_to(172);
    assert_eq!(c.outputs("move1"), BUSY);
}

#[test]
fn a_command_on_a_disabled_axis_is_an_error_of_the_block_only() {
    let mut c = Cell::new();
    c.set("x1", true);
    c.run_to(5);
    assert_eq!(c.outputs("move1"), ERROR);
    assert_eq!(c.word("move1.ErrorID"), motion_error_id::DISABLED as u64);
    assert_eq!(c.state(), AxisState::Disabled);
    assert_eq!(c.word("axerr.AxisErrorID"), 0);
    c.run_to(6);
    assert_eq!(c.outputs("move1"), ERROR); // held while Execute is TRUE
    c.set("x1", false);
    c.run_to(7);
    assert_eq!(c.outputs("move1"), IDLE);
    assert_eq!(c.word("move1.ErrorID"), 0);
}

#[test]
fn software_limits_refuse_targets_and_stop_a_velocity_move_in_error_stop() {
    let mut c = Cell::new();
    c.set("en", true);
    c.set_real("p1", 300.0);
    c.set("x1", true);
    c.run_to(5);
    assert_eq!(c.outputs("move1"), ERROR);
    assert_eq!(
        c.word("move1.ErrorID"),
        motion_error_id::OUTSIDE_LIMITS as u64
    );
    assert_eq!(c.state(), AxisState::Standstill);
    // A velocity move from 0 at 24 ms (scan 6) passes 200 when 5.5 + 100 (t - 0.11) =
    // 200: t = 2.055 s after its start, 2.079 s, first seen at 2.080 s (scan 520).
    c.set("xv", true);
    c.run_to(519);
    assert_eq!(c.state(), AxisState::ContinuousMotion);
    c.run_to(520);
    assert_eq!(c.state(), AxisState::ErrorStop);
    assert_eq!(c.outputs("vel"), ERROR);
    assert_eq!(c.word("vel.ErrorID"), motion_error_id::LIMIT_REACHED as u64);
    assert_eq!(
        c.word("axerr.AxisErrorID"),
        motion_error_id::LIMIT_REACHED as u64
    );
    assert!(c.flag("status.ErrorStop"));
    // MC_Reset takes ErrorStop back to Standstill once the axis has stopped.
    c.set("xv", false);
    c.run_to(700);
    assert_eq!(c.rt.axis("carousel").unwrap().velocity, 0.0);
    c.set("xreset", true);
    c.run_to(701);
    assert!(c.flag("reset.Done"));
    assert_eq!(c.state(), AxisState::Standstill);
    assert_eq!(c.word("axerr.AxisErrorID"), 0);
}

#[test]
fn home_relative_additive_and_halt() {
    let mut c = Cell::new();
    c.set("en", true);
    c.run_to(0);
    c.set("xhome", true);
    c.run_to(1);
    assert_eq!(c.outputs("home"), BUSY);
    assert!(c.flag("status.Homing"));
    c.run_to(2);
    assert_eq!(c.outputs("home"), DONE);
    assert!(close(c.position(), 5.0));
    assert!(c.rt.axis("carousel").unwrap().homed);
    // Relative: 10 from where the axis is.
    c.run_to(9);
    c.set("xr", true);
    c.run_to(400);
    assert_eq!(c.outputs("rel"), DONE);
    assert!(close(c.position(), 15.0));
    // Additive during a move to 90: the target becomes 90 + 10.
    c.run_to(409);
    c.set("x1", true);
    c.run_to(419);
    c.set("xa", true);
    c.run_to(420);
    assert_eq!(c.outputs("add"), BUSY);
    c.run_to(421);
    assert_eq!(c.outputs("move1"), ABORTED);
    c.run_to(1000);
    assert_eq!(c.outputs("add"), DONE);
    assert!(close(c.position(), 100.0));
    // Halt during a move back to 0: DiscreteMotion while braking, then Standstill and
    // Done.
    c.set("x1", false);
    c.set("xa", false);
    c.set_real("p1", 0.0);
    c.run_to(1001);
    c.set("x1", true);
    c.run_to(1099);
    c.set("xh", true);
    c.run_to(1100);
    assert_eq!(c.outputs("halt"), BUSY);
    assert_eq!(c.state(), AxisState::DiscreteMotion);
    c.run_to(1300);
    assert_eq!(c.outputs("halt"), DONE);
    assert_eq!(c.outputs("move1"), ABORTED);
    assert_eq!(c.state(), AxisState::Standstill);
    // At the halt, 0.392 s into the move: 100 - (5.5 + 100 × 0.282) = 66.3; braking at the
    // axis's own 1000 units/s² takes another 100 × 0.11 / 2 = 5.5.
    assert!(close(c.position(), 60.8), "{}", c.position());
}

#[test]
fn power_off_aborts_the_move_and_an_unbound_axis_is_an_error() {
    let mut c = Cell::new();
    c.set("en", true);
    c.set("x1", true);
    c.run_to(50);
    c.set("en", false);
    c.run_to(51);
    assert_eq!(c.state(), AxisState::Disabled);
    c.run_to(52);
    assert_eq!(c.outputs("move1"), ABORTED);
    assert!(!c.flag("power.Status"));

    // Without an [axes] entry the AXIS_REF holds no axis.
    let mut rt = Runtime::new(Arc::new(compile(CELL, "cell.st").unwrap()));
    let r = rt.resolve("Cell.x1").unwrap();
    rt.write(&r, &Value::Bool(true)).unwrap();
    rt.scan(Duration::ZERO).unwrap();
    assert_eq!(
        rt.read_name("Cell.move1.ErrorID").unwrap(),
        Value::UInt(motion_error_id::NO_AXIS as u64)
    );
    // An [axes] entry must name an AXIS_REF.
    let cfg: PlcConfig =
        toml::from_str(&AXES.replace("axes.carousel", "axes.\"Cell.en\"")).unwrap();
    let err = rt.configure(&cfg).unwrap_err();
    assert_eq!(err.to_string(), "axis 'Cell.en': is BOOL, not an AXIS_REF");
}

#[test]
fn the_carousel_example_turns_to_the_requested_pocket() {
    let src = include_str!("../../../examples/plc/carousel.st");
    let cfg: PlcConfig =
        toml::from_str(include_str!("../../../examples/plc/carousel.toml")).unwrap();
    let mut rt = Runtime::new(Arc::new(compile(src, "carousel.st").unwrap()));
    rt.configure(&cfg).unwrap();
    let set = |rt: &mut Runtime, name: &str, v: Value| {
        let r = rt.resolve(name).unwrap();
        rt.write(&r, &v).unwrap();
    };
    set(&mut rt, "Carousel.machine_on", Value::Bool(true));
    set(&mut rt, "Carousel.tool_number", Value::Int(4));
    let done =
        |rt: &Runtime| rt.read_name("Carousel.tool_change_done").unwrap() == Value::Bool(true);
    // Scan 0 powers the axis, 1 starts homing, 2 sees it homed. The request comes at scan
    // 10; scan 11 starts the 90 degree turn (1.01 s, as in the tests above), seen done on
    // the first scan at or after 0.044 + 1.01 s: scan 264.
    for k in 0..=263u64 {
        if k == 10 {
            set(&mut rt, "Carousel.tool_change_request", Value::Bool(true));
        }
        rt.scan(Duration::from_millis(4 * k)).unwrap();
        assert!(!done(&rt), "scan {k}");
    }
    rt.scan(Duration::from_millis(4 * 264)).unwrap();
    assert!(done(&rt));
    let axis = rt.axis("turret").unwrap();
    assert!(close(axis.position, 90.0) && axis.homed);
    assert_eq!(rt.read_name("Carousel.pocket").unwrap(), Value::Int(4));
    // The kernel drops the request; the PLC drops done.
    set(&mut rt, "Carousel.tool_change_request", Value::Bool(false));
    rt.scan(Duration::from_millis(4 * 265)).unwrap();
    assert!(!done(&rt));
}

/// A drive under the axis, as the kernel's auxiliary joints give it: enabled while the
/// axis asks for power, at the set-point of the last period (one period of delay).
#[test]
fn an_axis_on_a_drive_waits_for_it_reads_it_and_stops_on_its_fault() {
    use rtcnc_plc::DriveFeedback;
    let mut c = Cell::new();
    let axis = c.rt.axis_index("carousel").unwrap();
    let mut drive = DriveFeedback {
        position: 3.0,
        enabled: false,
        faulted: false,
    };
    let scan = |c: &mut Cell, drive: &mut DriveFeedback, k: u64| {
        while c.k <= k {
            c.rt.set_axis_drive(axis, *drive);
            c.rt.scan(Duration::from_millis(4 * c.k)).unwrap();
            let s = c.rt.axis_at(axis).unwrap();
            drive.enabled = s.power_requested && !drive.faulted;
            if drive.enabled {
                drive.position = s.drive_position;
            }
            c.k += 1;
        }
    };
    scan(&mut c, &mut drive, 0);
    // A disabled drive: the set-point follows it.
    assert!(close(c.rt.axis_at(axis).unwrap().position, 3.0));
    c.set("en", true);
    scan(&mut c, &mut drive, 1);
    // Enable asked; the drive comes on after this scan, the axis with it on the next.
    assert!(!c.flag("power.Status"));
    assert_eq!(c.state(), AxisState::Disabled);
    scan(&mut c, &mut drive, 2);
    assert!(c.flag("power.Status"));
    assert_eq!(c.state(), AxisState::Standstill);
    // Homing at 5: the drive stays at 3, the axis counts 2 more.
    c.set("xhome", true);
    scan(&mut c, &mut drive, 4);
    assert!(c.flag("home.Done"));
    let s = c.rt.axis_at(axis).unwrap();
    assert!(close(s.position, 5.0) && close(s.drive_position, 3.0));
    assert!(close(s.actual_position, 5.0) && close(c.position(), 5.0));
    // To 90 (drive 88): the move of 85 takes 0.11 + 0.74 + 0.11 = 0.96 s.
    c.set("x1", true);
    scan(&mut c, &mut drive, 300);
    assert_eq!(c.outputs("move1"), DONE);
    assert!(close(drive.position, 88.0) && close(c.position(), 90.0));
    // Back to 20; 0.5 s in, the drive faults.
    c.set("x2", true);
    scan(&mut c, &mut drive, 424);
    assert_eq!(c.outputs("move2"), BUSY);
    drive.faulted = true;
    scan(&mut c, &mut drive, 425);
    assert_eq!(c.state(), AxisState::ErrorStop);
    assert_eq!(c.outputs("move2"), ERROR);
    assert_eq!(c.word("move2.ErrorID"), u64::from(motion_error_id::DRIVE));
    assert_eq!(
        c.word("axerr.AxisErrorID"),
        u64::from(motion_error_id::DRIVE)
    );
    // The set-point stands where the drive stopped (its last position plus the offset).
    let stopped = drive.position + 2.0;
    scan(&mut c, &mut drive, 430);
    assert!(close(c.rt.axis_at(axis).unwrap().position, stopped));
    // The fault cleared, MC_Reset: Standstill there (the drive comes back with power).
    drive.faulted = false;
    c.set("xreset", true);
    scan(&mut c, &mut drive, 433);
    assert_eq!(c.state(), AxisState::Standstill);
    assert!(close(c.position(), stopped));
}

/// A modulo axis of 360 (a rotary table) at 100 units/s: MC_MoveAbsolute's Direction
/// picks the way round, given as the predefined MC_DIRECTION or as an integer.
#[test]
fn a_modulo_axis_goes_the_way_direction_says() {
    let src = "
VAR_GLOBAL table : AXIS_REF; END_VAR
PROGRAM Rot
VAR
  power : MC_Power;
  move : MC_MoveAbsolute;
  pos : MC_ReadActualPosition;
  x : BOOL;
  target : LREAL;
  dir : MC_DIRECTION := mcShortestWay;
  way : INT;
  use_int : BOOL;
END_VAR
power(Axis := table, Enable := TRUE);
IF use_int THEN
  move(Axis := table, Execute := x, Position := target, Velocity := 100.0, Direction := way,
       BufferMode := mcAborting);
ELSE
  move(Axis := table, Execute := x, Position := target, Velocity := 100.0, Direction := dir);
END_IF
pos(Axis := table, Enable := TRUE);
END_PROGRAM";
    let mut rt = Runtime::new(Arc::new(compile(src, "rot.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(
        "[axes.table]\nvelocity = 100.0\nacceleration = 1000.0\njerk = 100000.0\nmodulo = 360.0\n",
    )
    .unwrap();
    rt.configure(&cfg).unwrap();
    let mut k = 0u64;
    let mut set = |rt: &mut Runtime, name: &str, v: Value| {
        let r = rt.resolve(&format!("Rot.{name}")).unwrap();
        rt.write(&r, &v).unwrap();
    };
    // Runs one move to `target` and returns (lowest, highest) unwrapped set-point on the
    // way and the position read at the end.
    let mut go = |rt: &mut Runtime, set: &mut dyn FnMut(&mut Runtime, &str, Value)| {
        set(rt, "x", Value::Bool(true));
        let (mut lo, mut hi) = (f64::MAX, f64::MIN);
        for _ in 0..1500 {
            rt.scan(Duration::from_millis(4 * k)).unwrap();
            k += 1;
            let s = rt.axis("table").unwrap();
            lo = lo.min(s.drive_position);
            hi = hi.max(s.drive_position);
        }
        set(rt, "x", Value::Bool(false));
        rt.scan(Duration::from_millis(4 * k)).unwrap();
        k += 1;
        let Value::Real(p) = rt.read_name("Rot.pos.Position").unwrap() else {
            panic!()
        };
        (lo, hi, p)
    };
    // 0 -> 350 the shortest way: 10 back, through 0 (unwrapped down to -10).
    set(&mut rt, "target", Value::Real(350.0));
    let (lo, hi, p) = go(&mut rt, &mut set);
    assert!(
        close(lo, -10.0) && close(hi, 0.0) && close(p, 350.0),
        "{lo} {hi} {p}"
    );
    // 350 -> 10 in the positive direction (mcPositiveDirection): 20 up, to 10 unwrapped.
    set(&mut rt, "dir", Value::Int(1));
    set(&mut rt, "target", Value::Real(10.0));
    let (lo, hi, p) = go(&mut rt, &mut set);
    assert!(
        close(lo, -10.0) && close(hi, 10.0) && close(p, 10.0),
        "{lo} {hi} {p}"
    );
    // 10 -> 20 in the negative direction, given as CODESYS's -1: 350 down, to -340.
    set(&mut rt, "use_int", Value::Bool(true));
    set(&mut rt, "way", Value::Int(-1));
    set(&mut rt, "target", Value::Real(20.0));
    let (lo, hi, p) = go(&mut rt, &mut set);
    assert!(
        close(lo, -340.0) && close(hi, 10.0) && close(p, 20.0),
        "{lo} {hi} {p}"
    );
    // An unknown direction is an invalid parameter.
    set(&mut rt, "way", Value::Int(7));
    set(&mut rt, "x", Value::Bool(true));
    rt.scan(Duration::from_millis(4 * k)).unwrap();
    let Value::UInt(id) = rt.read_name("Rot.move.ErrorID").unwrap() else {
        panic!()
    };
    assert_eq!(id, u64::from(motion_error_id::INVALID_PARAMETER));
}

#[test]
fn a_modulo_axis_has_no_software_limits() {
    let mut rt = Runtime::new(Arc::new(compile(CELL, "cell.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(&format!("{AXES}modulo = 360.0\n")).unwrap();
    let err = rt.configure(&cfg).unwrap_err().to_string();
    assert!(
        err.contains("a modulo axis has no software limits"),
        "{err}"
    );
}
