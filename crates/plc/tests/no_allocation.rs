//! A scan allocates nothing: a counting global allocator watches the mill logic, string
//! functions, user functions and function blocks, faults, forcing and signals.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::sync::Arc;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Duration;

use rtcnc_plc::{PlcConfig, Runtime, Signal, Value, compile};

struct Counting;

thread_local! {
    // Only the thread under test counts: tests run in parallel threads.
    static COUNTING: Cell<bool> = const { Cell::new(false) };
}
static ALLOCATIONS: AtomicUsize = AtomicUsize::new(0);

fn counting() -> bool {
    COUNTING.try_with(|c| c.get()).unwrap_or(false)
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        if counting() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.alloc(layout) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.dealloc(ptr, layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        if counting() {
            ALLOCATIONS.fetch_add(1, Ordering::Relaxed);
        }
        // SAFETY: forwarded unchanged to the system allocator.
        unsafe { System.realloc(ptr, layout, new_size) }
    }
}

#[global_allocator]
static GLOBAL: Counting = Counting;

/// Allocations made by `f` on this thread.
fn allocations(f: impl FnOnce()) -> usize {
    static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
    let _g = LOCK.lock().unwrap_or_else(|e| e.into_inner());
    ALLOCATIONS.store(0, Ordering::SeqCst);
    COUNTING.with(|c| c.set(true));
    f();
    COUNTING.with(|c| c.set(false));
    ALLOCATIONS.load(Ordering::SeqCst)
}

const MILL: &str = include_str!("../../../examples/plc/mill.st");
const MILL_TOML: &str = include_str!("../../../examples/plc/mill.toml");

#[test]
fn mill_scans_signals_and_forces_allocate_nothing() {
    let mut rt = Runtime::new(Arc::new(compile(MILL, "mill.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(MILL_TOML).unwrap();
    rt.configure(&cfg).unwrap();
    let door = rt.resolve("door_closed").unwrap();
    rt.input_image_mut()[0] = 0b0000_1101;
    let mut snapshot = rt.retain_snapshot();
    let n = allocations(|| {
        rt.update_retain_snapshot(&mut snapshot);
        rt.force(&door, &Value::Bool(true)).unwrap();
        rt.set_signal_bool(Signal::EstopReset, true);
        rt.set_signal_bool(Signal::MachineOnRequest, true);
        rt.set_signal_bool(Signal::SpindleOn, true);
        rt.set_signal(Signal::SpindleSpeedCommand, 800.0);
        rt.set_signal(Signal::ToolNumber, 4.0);
        rt.set_signal_bool(Signal::ToolChangeRequest, true);
        rt.set_signal(Signal::MCodeNumber, 100.0);
        rt.set_signal(Signal::MCodeP, 0.02);
        rt.set_signal_bool(Signal::MCodeRequest, true);
        for k in 0..2000u64 {
            rt.scan(Duration::from_millis(4 * k)).unwrap();
            let _ = rt.signal_bool(Signal::FeedHoldRequest);
        }
        rt.unforce(&door);
    });
    assert_eq!(n, 0);
    // The tool change timed out (no clamp feedback) inside the counted scans.
    assert!(rt.signal_bool(Signal::MachineFault));
}

#[test]
fn string_and_call_heavy_scans_and_faults_allocate_nothing() {
    let src = "
        FUNCTION Label : STRING[40] VAR_INPUT n : INT; END_VAR
          Label := CONCAT('tool ', INT_TO_STRING(n), ' / ', REAL_TO_STRING(INT_TO_REAL(n) * 0.5));
        END_FUNCTION
        FUNCTION_BLOCK Counter VAR_INPUT up : BOOL; END_VAR VAR_OUTPUT n : INT; text : STRING; END_VAR VAR e : R_TRIG; END_VAR
          e(CLK := up); IF e.Q THEN n := n + 1; END_IF; text := Label(n);
        END_FUNCTION_BLOCK
        PROGRAM P VAR c : ARRAY[1..4] OF Counter; i : INT; k : INT; s : STRING; pos : INT; d : INT := 1; END_VAR
          k := k + 1;
          FOR i := 1 TO 4 DO c[i](up := (k + i) MOD 2 = 0); END_FOR;
          s := INSERT(LEFT(c[1].text, 6), MID(c[2].text, 3, 2), 2);
          pos := FIND(s, 'ol') + LEN(REPLACE(s, 'xy', 1, 1)) + LEN(DELETE(s, 2, 1));
          IF k = 500 THEN d := d - 1; k := k / d; END_IF;
        END_PROGRAM";
    let mut rt = Runtime::new(Arc::new(compile(src, "s.st").unwrap()));
    let mut fault = None;
    let n = allocations(|| {
        for k in 0..600u64 {
            if let Err(f) = rt.scan(Duration::from_millis(k)) {
                fault = Some(f);
                break;
            }
        }
    });
    assert_eq!(n, 0);
    let fault = fault.expect("division by zero on scan 500");
    assert_eq!(fault.scan, 500);
    // c[1] sees a rising edge on every odd k: 250 of them in k = 1..499.
    assert_eq!(
        rt.read_name("c[1].text").unwrap(),
        Value::String("tool 250 / 125".into())
    );
}

#[test]
fn wstring_scans_allocate_nothing() {
    let src = "
        PROGRAM P VAR k : INT; w : WSTRING(40); s : STRING; n : INT; END_VAR
          k := k + 1;
          w := CONCAT(\"Grüße \", INT_TO_WSTRING(k), \" €\");
          s := WSTRING_TO_STRING(w);
          w := INSERT(LEFT(STRING_TO_WSTRING(s), 6), MID(w, 2, 3), 2);
          n := FIND(w, \"ü\") + LEN(REPLACE(w, \"xy\", 1, 1)) + LEN(DELETE(w, 2, 1))
               + WSTRING_TO_INT(RIGHT(INT_TO_WSTRING(k), 1));
        END_PROGRAM";
    let mut rt = Runtime::new(Arc::new(compile(src, "w.st").unwrap()));
    let n = allocations(|| {
        for k in 0..100u64 {
            rt.scan(Duration::from_millis(k)).unwrap();
        }
    });
    assert_eq!(n, 0);
    // Scan 100: w = "Grüße 100 €"; MID(w, L := 2, P := 3) = "üß" inserted after the
    // second character of LEFT(.., 6) = "Grüße ": "Grüßüße ".
    assert_eq!(rt.read_name("w").unwrap(), Value::String("Grüßüße ".into()));
}

#[test]
fn method_and_interface_heavy_scans_allocate_nothing() {
    const STATIONS: &str = include_str!("../../../examples/plc/stations.st");
    let mut rt = Runtime::new(Arc::new(compile(STATIONS, "stations.st").unwrap()));
    let n = allocations(|| {
        for k in 0..2000u64 {
            rt.scan(Duration::from_millis(4 * k)).unwrap();
        }
    });
    assert_eq!(n, 0);
    // A single station works 40 ms: a cycle is one scan to start, ten 4 ms scans of work
    // and one to count its part, so 2000 scans make 166 parts. A double station works
    // 40 + 20 ms (SUPER^.Duration() + T#20ms): 17 scans, 117 cycles of 2 parts = 234.
    // 25 of each: 25 * (166 + 234).
    assert_eq!(rt.read_name("Cell.total").unwrap(), Value::Int(10_000));
    assert_eq!(
        rt.read_name("Cell.single[3].parts_").unwrap(),
        Value::Int(166)
    );
}

#[test]
fn plcopen_motion_scans_allocate_nothing() {
    const CAROUSEL: &str = include_str!("../../../examples/plc/carousel.st");
    const CAROUSEL_TOML: &str = include_str!("../../../examples/plc/carousel.toml");
    let mut rt = Runtime::new(Arc::new(compile(CAROUSEL, "carousel.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(CAROUSEL_TOML).unwrap();
    rt.configure(&cfg).unwrap();
    rt.set_signal_bool(Signal::MachineOnRequest, true);
    rt.set_signal(Signal::ToolNumber, 7.0);
    let n = allocations(|| {
        for k in 0..1300u64 {
            // Requests toggle every 300 scans: each turn plans a new profile.
            rt.set_signal_bool(Signal::ToolChangeRequest, (k / 300) % 2 == 0 && k > 5);
            if k == 600 {
                rt.set_signal(Signal::ToolNumber, 2.0);
            }
            rt.scan(Duration::from_millis(4 * k)).unwrap();
        }
    });
    assert_eq!(n, 0);
    // Tool 7 at 180 degrees, then tool 2 at 30 (150 degrees: 1.61 s from scan 600).
    let p = rt.axis("turret").unwrap().position;
    assert!((p - 30.0).abs() < 1e-9, "{p}");
}

#[test]
fn an_axis_on_a_drive_allocates_nothing_between_and_in_scans() {
    use rtcnc_plc::DriveFeedback;
    const CAROUSEL: &str = include_str!("../../../examples/plc/carousel.st");
    const CAROUSEL_TOML: &str = include_str!("../../../examples/plc/carousel.toml");
    let mut rt = Runtime::new(Arc::new(compile(CAROUSEL, "carousel.st").unwrap()));
    let cfg: PlcConfig = toml::from_str(CAROUSEL_TOML).unwrap();
    rt.configure(&cfg).unwrap();
    let axis = rt.axis_index("turret").unwrap();
    rt.set_signal_bool(Signal::MachineOnRequest, true);
    rt.set_signal(Signal::ToolNumber, 7.0);
    let mut drive = DriveFeedback::default();
    let n = allocations(|| {
        // The kernel's pattern: the drive's report and the set-points every 1 ms, a scan
        // every 4 ms.
        for k in 0..3000u64 {
            rt.set_axis_drive(axis, drive);
            let now = Duration::from_millis(k);
            rt.set_signal_bool(Signal::ToolChangeRequest, k > 20);
            if k % 4 == 0 {
                rt.scan(now).unwrap();
            } else {
                rt.advance_axes(now);
            }
            let s = rt.axis_at(axis).unwrap();
            drive.enabled = s.power_requested;
            drive.position = s.drive_position;
        }
    });
    assert_eq!(n, 0);
    // Tool 7 is at 180 degrees: 0.11 + 1.69 + 0.11 s from about 28 ms, within the 3 s.
    let p = rt.axis("turret").unwrap().position;
    assert!((p - 180.0).abs() < 1e-9, "{p}");
}
