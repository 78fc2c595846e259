//! Runtime services: tasks from the CONFIGURATION, I/O images, on-line monitoring and
//! forcing, signal mapping, retained variables.

use crate::common::*;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{ConfigError, MonitorError, PlcConfig, Restart, Runtime, Signal, Value, compile};

const TASKS: &str = "
    PROGRAM Fast VAR n : INT; END_VAR n := n + 1; END_PROGRAM
    PROGRAM Slow VAR n : INT; END_VAR n := n + 1; END_PROGRAM
    PROGRAM Free VAR n : INT; END_VAR n := n + 1; END_PROGRAM
    CONFIGURATION Cell
      VAR_GLOBAL shared : INT; END_VAR
      RESOURCE Cpu ON PLC
        TASK T_slow (INTERVAL := T#10ms, PRIORITY := 5);
        TASK T_fast (INTERVAL := T#2ms, PRIORITY := 1);
        PROGRAM f1 WITH T_fast : Fast;
        PROGRAM s1 WITH T_slow : Slow;
        PROGRAM free1 : Free;
      END_RESOURCE
    END_CONFIGURATION";

#[test]
fn configuration_tasks_are_described_for_the_executive() {
    let p = compile(TASKS, "cell.st").unwrap();
    let t = p.tasks();
    assert_eq!(t.len(), 3);
    assert_eq!(
        (t[0].name.as_str(), t[0].interval, t[0].priority),
        ("T_FAST", Some(Duration::from_millis(2)), 1)
    );
    assert_eq!(t[0].programs, ["F1"]);
    assert_eq!(
        (t[1].name.as_str(), t[1].interval, t[1].priority),
        ("T_SLOW", Some(Duration::from_millis(10)), 5)
    );
    assert_eq!(t[1].programs, ["S1"]);
    assert_eq!((t[2].name.as_str(), t[2].interval), ("DEFAULT", None));
    assert_eq!(t[2].programs, ["FREE1"]);
}

#[test]
fn scan_runs_each_task_when_it_is_due() {
    let mut rt = Runtime::new(Arc::new(compile(TASKS, "cell.st").unwrap()));
    // 1 ms scans for 20 ms: the 2 ms task runs 10 times, the 10 ms task twice, the
    // default task every scan.
    for k in 0..20 {
        rt.scan(ms(k)).unwrap();
    }
    assert_eq!(int(&rt, "f1.n"), 10);
    assert_eq!(int(&rt, "s1.n"), 2);
    assert_eq!(int(&rt, "free1.n"), 20);
}

#[test]
fn a_scan_is_due_only_when_a_cyclic_task_comes_round() {
    let only_cyclic = TASKS.replace("PROGRAM free1 : Free;", "");
    let mut rt = Runtime::new(Arc::new(compile(&only_cyclic, "cell.st").unwrap()));
    // 1 ms calls for 20 ms, scanning only when due: the 2 ms task's times.
    let mut due = Vec::new();
    for k in 0..20 {
        if rt.is_due(ms(k)) {
            due.push(k);
            rt.scan(ms(k)).unwrap();
        }
    }
    assert_eq!(due, [0, 2, 4, 6, 8, 10, 12, 14, 16, 18]);
    assert_eq!(int(&rt, "f1.n"), 10);
    assert_eq!(int(&rt, "s1.n"), 2);
    // A task without an interval makes every scan due.
    let mut rt = Runtime::new(Arc::new(compile(TASKS, "cell.st").unwrap()));
    rt.scan(ms(0)).unwrap();
    assert!(rt.is_due(ms(1)));
}

#[test]
fn run_task_runs_one_task_only() {
    let mut rt = Runtime::new(Arc::new(compile(TASKS, "cell.st").unwrap()));
    rt.run_task(1, ms(0)).unwrap();
    rt.run_task(1, ms(10)).unwrap();
    assert_eq!(int(&rt, "s1.n"), 2);
    assert_eq!(int(&rt, "f1.n"), 0);
}

#[test]
fn located_variables_follow_the_images_little_endian() {
    let src = "PROGRAM P VAR
        b0 AT %IX0.0 : BOOL; b7 AT %IX0.7 : BOOL; w AT %IW1 : INT; d AT %ID1 : DINT; r AT %ID2 : REAL;
        ob AT %QX0.3 : BOOL; ow AT %QW1 : WORD; oreal AT %QD1 : REAL; mark AT %MW0 : INT;
        copy_b : BOOL; copy_w : INT; copy_d : DINT; copy_r : REAL; direct : BOOL;
        END_VAR
        copy_b := b0 AND b7; copy_w := w; copy_d := d; copy_r := r; direct := %IX0.7;
        ob := TRUE; ow := 16#1234; oreal := 1.5; mark := mark + 1; %QX0.4 := TRUE;
        END_PROGRAM";
    let mut rt = plc(src);
    {
        let img = rt.input_image_mut();
        assert_eq!(img.len(), 12);
        img[0] = 0x81;
        img[2..4].copy_from_slice(&(-2i16).to_le_bytes());
        img[4..8].copy_from_slice(&(-70000i32).to_le_bytes());
        img[8..12].copy_from_slice(&2.5f32.to_le_bytes());
    }
    rt.scan(ms(0)).unwrap();
    assert!(boolean(&rt, "copy_b"));
    assert!(boolean(&rt, "direct"));
    assert_eq!(int(&rt, "copy_w"), -2);
    assert_eq!(int(&rt, "copy_d"), -70000);
    assert_eq!(real(&rt, "copy_r"), 2.5);
    let out = rt.output_image();
    assert_eq!(out[0], 0b1_1000);
    assert_eq!(&out[2..4], &[0x34, 0x12]);
    assert_eq!(&out[4..8], &1.5f32.to_le_bytes());
    rt.scan(ms(4)).unwrap();
    // The marker image carries %M variables across scans.
    assert_eq!(&rt.marker_image()[0..2], &2i16.to_le_bytes());
}

#[test]
fn monitoring_reads_members_of_instances_by_name() {
    let src = "PROGRAM Mill VAR spindle_timer : TON; go : BOOL := TRUE; axes : ARRAY[1..2] OF STRUCT pos : LREAL; END_STRUCT; w : WORD := 16#0004; END_VAR
        spindle_timer(IN := go, PT := T#1s); axes[2].pos := 12.5; END_PROGRAM";
    let mut rt = plc(src);
    rt.scan(ms(0)).unwrap();
    rt.scan(ms(300)).unwrap();
    assert_eq!(get(&rt, "spindle_timer.ET"), Value::Time(300_000_000));
    assert_eq!(get(&rt, "Mill.spindle_timer.ET"), Value::Time(300_000_000));
    assert_eq!(get(&rt, "mill.SPINDLE_TIMER.q"), Value::Bool(false));
    assert_eq!(get(&rt, "axes[2].pos"), Value::Real(12.5));
    assert_eq!(get(&rt, "w.2"), Value::Bool(true));
    assert_eq!(
        rt.read_name("nothing"),
        Err(MonitorError::Unknown("nothing".into()))
    );
    assert_eq!(
        rt.read_name("axes[3].pos"),
        Err(MonitorError::Unknown("axes[3].pos".into()))
    );
    assert!(matches!(
        rt.read_name("spindle_timer"),
        Err(MonitorError::NotScalar(_))
    ));
    assert!(matches!(
        rt.read_name("spindle_timer +"),
        Err(MonitorError::BadPath(_))
    ));
}

#[test]
fn forcing_an_input_overrides_the_image_until_unforced() {
    let src = "PROGRAM P VAR sw AT %IX0.0 : BOOL; lamp AT %QX0.0 : BOOL; seen : BOOL; END_VAR seen := sw; lamp := sw; END_PROGRAM";
    let mut rt = plc(src);
    let sw = rt.resolve("sw").unwrap();
    rt.force(&sw, &Value::Bool(true)).unwrap();
    rt.scan(ms(0)).unwrap();
    assert!(boolean(&rt, "seen"));
    assert_eq!(rt.output_image()[0], 1);
    assert_eq!(rt.forced_slots().count(), 1);
    rt.unforce(&sw);
    rt.scan(ms(4)).unwrap();
    assert!(!boolean(&rt, "seen"));
    assert_eq!(rt.output_image()[0], 0);
}

#[test]
fn forcing_an_output_holds_it_in_the_output_image() {
    let src = "PROGRAM P VAR lamp AT %QX0.0 : BOOL; END_VAR lamp := FALSE; END_PROGRAM";
    let mut rt = plc(src);
    let lamp = rt.resolve("lamp").unwrap();
    rt.force(&lamp, &Value::Bool(true)).unwrap();
    rt.scan(ms(0)).unwrap();
    assert_eq!(rt.output_image()[0], 1);
    rt.unforce_all();
    rt.scan(ms(4)).unwrap();
    assert_eq!(rt.output_image()[0], 0);
}

#[test]
fn force_values_are_checked() {
    let mut rt = plc("PROGRAM P VAR s : SINT; t : TON; END_VAR END_PROGRAM");
    let s = rt.resolve("s").unwrap();
    assert!(matches!(
        rt.force(&s, &Value::Int(300)),
        Err(MonitorError::Value { .. })
    ));
    let t = rt.resolve("t").unwrap();
    assert!(matches!(
        rt.force(&t, &Value::Bool(true)),
        Err(MonitorError::NotScalar(_))
    ));
    assert_eq!(rt.parse_value(&s, "-5"), Ok(Value::Int(-5)));
    assert!(rt.parse_value(&s, "x").is_err());
}

#[test]
fn signal_configuration_errors_are_reported() {
    let rt0 = || plc("PROGRAM P VAR b : BOOL; r : REAL; s : STRING; END_VAR END_PROGRAM");
    let cfg = |t: &str| -> PlcConfig { toml::from_str(t).unwrap() };
    let mut rt = rt0();
    let e = rt
        .configure(&cfg("[signals]\nwarp_drive = \"b\""))
        .unwrap_err();
    assert_eq!(e, ConfigError::UnknownSignal("warp_drive".into()));
    let e = rt
        .configure(&cfg("[signals]\nspindle_on = \"r\""))
        .unwrap_err();
    assert_eq!(e.code(), "signal-type");
    let e = rt
        .configure(&cfg("[signals]\nspindle_on = \"zz\""))
        .unwrap_err();
    assert_eq!(e.code(), "signal-variable");
    let e = rt
        .configure(&cfg("[safe_values]\nb = \"TRUE\""))
        .unwrap_err();
    assert_eq!(e.code(), "safe-value");
    assert!(toml::from_str::<PlcConfig>("[signal]\nx = \"b\"").is_err());
    rt.configure(&cfg(
        "[signals]\nspindle_on = \"b\"\nspindle_speed_command = \"r\"",
    ))
    .unwrap();
    rt.set_signal(Signal::SpindleSpeedCommand, 1234.5);
    rt.set_signal_bool(Signal::SpindleOn, true);
    assert_eq!(get(&rt, "r"), Value::Real(1234.5));
    assert_eq!(get(&rt, "b"), Value::Bool(true));
    assert!(rt.has_signal(Signal::SpindleOn));
    assert!(!rt.has_signal(Signal::ToolNumber));
    assert_eq!(rt.signal(Signal::ToolNumber), None);
}

#[test]
fn every_signal_has_a_unique_name() {
    let mut names: Vec<&str> = Signal::ALL.iter().map(|s| s.name()).collect();
    names.sort();
    names.dedup();
    assert_eq!(names.len(), Signal::ALL.len());
    for s in Signal::ALL {
        assert_eq!(Signal::from_name(s.name()), Some(*s));
    }
}

const RETAIN_SRC: &str = "
    VAR_GLOBAL RETAIN hours : LREAL; END_VAR
    PROGRAM P
      VAR RETAIN count : UDINT; name : STRING[16]; tools : ARRAY[1..3] OF INT; last : TIME; END_VAR
      VAR scratch : INT; END_VAR
      count := count + 1; hours := hours + 0.5; scratch := scratch + 1;
      IF count = 1 THEN name := 'it$'s $$ fine'; tools[2] := -7; last := T#1h2m; END_IF;
    END_PROGRAM";

#[test]
fn retained_variables_survive_a_restart_through_the_file() {
    let dir = std::env::temp_dir().join(format!("rtcnc-plc-retain-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("retain.txt");
    let program = Arc::new(compile(RETAIN_SRC, "r.st").unwrap());
    let mut a = Runtime::new(program.clone());
    for k in 0..3 {
        a.scan(ms(k)).unwrap();
    }
    a.save_retain(&path).unwrap();
    // No temporary file is left behind.
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(leftovers.len(), 1, "{leftovers:?}");

    let mut b = Runtime::new(program);
    let report = b.load_retain(&path).unwrap();
    assert_eq!(report.restored, 1 + 1 + 1 + 3 + 1);
    assert_eq!(report.skipped, 0);
    assert_eq!(get(&b, "count"), Value::UInt(3));
    assert_eq!(get(&b, "hours"), Value::Real(1.5));
    assert_eq!(get(&b, "name"), Value::String("it's $ fine".into()));
    assert_eq!(get(&b, "tools[2]"), Value::Int(-7));
    assert_eq!(get(&b, "last"), Value::Time(3_720_000_000_000));
    assert_eq!(get(&b, "scratch"), Value::Int(0));
    b.scan(ms(0)).unwrap();
    assert_eq!(get(&b, "count"), Value::UInt(4));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn retain_file_entries_that_no_longer_fit_are_skipped() {
    let dir = std::env::temp_dir().join(format!("rtcnc-plc-retain2-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("retain.txt");
    std::fs::write(
        &path,
        "# old\nP.count = 17\nP.removed = 3\nP.tools[1] = 99999\ngarbage\n",
    )
    .unwrap();
    let mut rt = Runtime::new(Arc::new(compile(RETAIN_SRC, "r.st").unwrap()));
    let report = rt.load_retain(&path).unwrap();
    assert_eq!((report.restored, report.skipped), (1, 3));
    assert_eq!(get(&rt, "count"), Value::UInt(17));
    let missing = rt.load_retain(&dir.join("none.txt")).unwrap();
    assert_eq!((missing.restored, missing.skipped), (0, 0));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn warm_restart_keeps_retain_cold_restart_does_not() {
    let mut rt = Runtime::new(Arc::new(compile(RETAIN_SRC, "r.st").unwrap()));
    rt.scan(ms(0)).unwrap();
    rt.scan(ms(1)).unwrap();
    rt.restart(Restart::Warm);
    assert_eq!(get(&rt, "count"), Value::UInt(2));
    assert_eq!(get(&rt, "scratch"), Value::Int(0));
    rt.restart(Restart::Cold);
    assert_eq!(get(&rt, "count"), Value::UInt(0));
}

#[test]
fn variables_are_listed_for_browsing() {
    let p = compile(RETAIN_SRC, "r.st").unwrap();
    let vars = p.variables();
    let paths: Vec<&str> = vars.iter().map(|v| v.path.as_str()).collect();
    assert_eq!(
        paths,
        [
            "HOURS",
            "P.COUNT",
            "P.NAME",
            "P.TOOLS[1]",
            "P.TOOLS[2]",
            "P.TOOLS[3]",
            "P.LAST",
            "P.SCRATCH"
        ]
    );
    assert_eq!(vars[2].type_name, "STRING[16]");
    assert!(vars[3].retain && !vars[7].retain);
    let rt = Runtime::new(Arc::new(p));
    for v in &vars {
        assert!(rt.read_name(&v.path).is_ok(), "{}", v.path);
    }
}

#[test]
fn retain_snapshot_is_taken_in_the_plc_task_and_written_elsewhere() {
    let dir = std::env::temp_dir().join(format!("rtcnc-plc-retain3-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("retain.txt");
    let program = Arc::new(compile(RETAIN_SRC, "r.st").unwrap());
    let mut rt = Runtime::new(program.clone());
    let mut snap = rt.retain_snapshot();
    for k in 0..5 {
        rt.scan(ms(k)).unwrap();
    }
    rt.update_retain_snapshot(&mut snap);
    rt.scan(ms(5)).unwrap();
    // The snapshot holds count = 5, taken before the sixth scan.
    let writer = std::thread::spawn(move || snap.save(&path).map(|_| path));
    let path = writer.join().unwrap().unwrap();
    let mut fresh = Runtime::new(program);
    fresh.load_retain(&path).unwrap();
    assert_eq!(get(&fresh, "count"), Value::UInt(5));
    assert_eq!(get(&fresh, "hours"), Value::Real(2.5));
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn event_task_runs_on_each_rising_edge_of_its_trigger() {
    let src = "
        PROGRAM OnEvent VAR n : INT; END_VAR n := n + 1; END_PROGRAM
        PROGRAM Cyclic VAR n : INT; END_VAR n := n + 1; END_PROGRAM
        CONFIGURATION C
          VAR_GLOBAL go : BOOL; END_VAR
          RESOURCE R ON PLC
            TASK Ev (SINGLE := go, PRIORITY := 0);
            TASK Cy (INTERVAL := T#1ms, PRIORITY := 2);
            PROGRAM e WITH Ev : OnEvent;
            PROGRAM c WITH Cy : Cyclic;
          END_RESOURCE
        END_CONFIGURATION";
    let program = compile(src, "ev.st").unwrap();
    assert_eq!(program.tasks()[0].trigger.as_deref(), Some("GO"));
    assert_eq!(program.tasks()[0].interval, None);
    let mut rt = Runtime::new(Arc::new(program));
    let go = rt.resolve("go").unwrap();
    // go: F T T F T F F T -> rising edges on scans 2, 5 and 8.
    for (k, v) in [false, true, true, false, true, false, false, true]
        .into_iter()
        .enumerate()
    {
        rt.write(&go, &Value::Bool(v)).unwrap();
        rt.scan(ms(k as u64)).unwrap();
    }
    assert_eq!(int(&rt, "e.n"), 3);
    assert_eq!(int(&rt, "c.n"), 8);
    // A task is cyclic or event-driven, not both; the trigger must be a BOOL global.
    let both = src.replace(
        "(SINGLE := go, PRIORITY := 0)",
        "(SINGLE := go, INTERVAL := T#1ms)",
    );
    assert!(compile(&both, "ev.st").is_err());
    let not_bool = src.replace("go : BOOL;", "go : INT;");
    assert!(compile(&not_bool, "ev.st").is_err());
}
