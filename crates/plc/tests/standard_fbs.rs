//! Standard function blocks at exact scans. Scan k (1-based) runs at t = (k - 1) * 4 ms;
//! the expected tables follow the timing diagrams of IEC 61131-3 (3rd edition, 6.6.3.5).

use crate::common::*;
use rtcnc_plc::Value;

/// Runs `fb(IN := input[k], PT := T#20ms)` for every k and returns (Q, ET ms) per scan.
fn timer(kind: &str, input: &[bool]) -> Vec<(bool, f64)> {
    let src = format!(
        "PROGRAM P VAR x : BOOL; t : {kind}; q : BOOL; et : TIME; END_VAR
         t(IN := x, PT := T#20ms, Q => q, ET => et);
         END_PROGRAM"
    );
    let mut rt = plc(&src);
    let mut out = Vec::new();
    for (k, &i) in input.iter().enumerate() {
        set(&mut rt, "x", Value::Bool(i));
        rt.scan(ms(4 * k as u64)).unwrap();
        out.push((boolean(&rt, "q"), time_ms(&rt, "et")));
    }
    out
}

#[test]
fn ton_q_rises_on_the_scan_where_et_reaches_pt() {
    // IN TRUE from scan 1 (t = 0): ET = 0, 4, 8, 12, 16, 20 ms; Q rises on scan 6.
    let r = timer("TON", &[true; 8]);
    let expected = [
        (false, 0.0),
        (false, 4.0),
        (false, 8.0),
        (false, 12.0),
        (false, 16.0),
        (true, 20.0),
        (true, 20.0),
        (true, 20.0),
    ];
    assert_eq!(r, expected);
}

#[test]
fn ton_resets_when_in_falls_before_pt() {
    // IN TRUE on scans 1-3, FALSE on 4, TRUE from 5 (t = 16 ms): restart, Q on scan 10.
    let input = [true, true, true, false, true, true, true, true, true, true];
    let r = timer("TON", &input);
    assert_eq!(r[2], (false, 8.0));
    assert_eq!(r[3], (false, 0.0));
    assert_eq!(r[4], (false, 0.0));
    assert_eq!(r[8], (false, 16.0));
    assert_eq!(r[9], (true, 20.0));
}

#[test]
fn tof_q_falls_pt_after_in_falls() {
    // IN TRUE on scans 1-3, falls on scan 4 (t = 12 ms): Q stays TRUE until ET reaches
    // 20 ms on scan 9 (t = 32 ms); ET then holds PT.
    let mut input = vec![true; 3];
    input.extend([false; 8]);
    let r = timer("TOF", &input);
    let expected = [
        (true, 0.0),
        (true, 0.0),
        (true, 0.0),
        (true, 0.0),
        (true, 4.0),
        (true, 8.0),
        (true, 12.0),
        (true, 16.0),
        (false, 20.0),
        (false, 20.0),
        (false, 20.0),
    ];
    assert_eq!(r, expected);
}

#[test]
fn tof_in_rising_again_cancels_the_delay() {
    let input = [true, false, false, true, true];
    let r = timer("TOF", &input);
    assert_eq!(r[2], (true, 4.0));
    assert_eq!(r[3], (true, 0.0));
}

#[test]
fn tp_pulse_has_fixed_length_and_ignores_retrigger() {
    // IN: TRUE, TRUE, FALSE, TRUE (ignored, pulse running), FALSE...
    let input = [true, true, false, true, false, false, false];
    let r = timer("TP", &input);
    let expected = [
        (true, 0.0),
        (true, 4.0),
        (true, 8.0),
        (true, 12.0),
        (true, 16.0),
        (false, 20.0),
        (false, 0.0),
    ];
    assert_eq!(r, expected);
}

#[test]
fn tp_et_holds_pt_while_in_stays_true() {
    let r = timer("TP", &[true; 9]);
    assert_eq!(r[5], (false, 20.0));
    assert_eq!(r[8], (false, 20.0));
}

#[test]
fn ctu_counts_rising_edges_and_resets() {
    let src = "PROGRAM P VAR cu : BOOL; r : BOOL; c : CTU; END_VAR c(CU := cu, R := r, PV := 3); END_PROGRAM";
    let mut rt = plc(src);
    // CU toggles TRUE/FALSE: rising edges on scans 1, 3, 5.
    let mut cv = Vec::new();
    let mut q = Vec::new();
    for k in 0..6 {
        set(&mut rt, "cu", Value::Bool(k % 2 == 0));
        rt.scan(ms(4 * k)).unwrap();
        cv.push(int(&rt, "c.CV"));
        q.push(boolean(&rt, "c.Q"));
    }
    assert_eq!(cv, [1, 1, 2, 2, 3, 3]);
    assert_eq!(q, [false, false, false, false, true, true]);
    set(&mut rt, "r", Value::Bool(true));
    set(&mut rt, "cu", Value::Bool(true));
    rt.scan(ms(24)).unwrap();
    // R dominates CU.
    assert_eq!(int(&rt, "c.CV"), 0);
    assert!(!boolean(&rt, "c.Q"));
}

#[test]
fn ctd_loads_and_counts_down_below_zero() {
    let src = "PROGRAM P VAR cd : BOOL; ld : BOOL := TRUE; c : CTD; END_VAR c(CD := cd, LD := ld, PV := 2); ld := FALSE; END_PROGRAM";
    let mut rt = plc(src);
    let mut cv = Vec::new();
    let mut q = Vec::new();
    // Scan 1 loads PV = 2; CD rises on scans 2, 4, 6.
    for k in 0..6 {
        set(&mut rt, "cd", Value::Bool(k % 2 == 1));
        rt.scan(ms(4 * k)).unwrap();
        cv.push(int(&rt, "c.CV"));
        q.push(boolean(&rt, "c.Q"));
    }
    assert_eq!(cv, [2, 1, 1, 0, 0, -1]);
    assert_eq!(q, [false, false, false, true, true, true]);
}

#[test]
fn ctud_up_down_reset_load() {
    let src = "PROGRAM P VAR cu : BOOL; cd : BOOL; r : BOOL; ld : BOOL; c : CTUD; END_VAR
        c(CU := cu, CD := cd, R := r, LD := ld, PV := 2); END_PROGRAM";
    let mut rt = plc(src);
    let run = |rt: &mut rtcnc_plc::Runtime, cu, cd, r, ld| {
        for (n, v) in [("cu", cu), ("cd", cd), ("r", r), ("ld", ld)] {
            set(rt, n, Value::Bool(v));
        }
        rt.scan(ms(0)).unwrap();
        (int(rt, "c.CV"), boolean(rt, "c.QU"), boolean(rt, "c.QD"))
    };
    assert_eq!(run(&mut rt, true, false, false, false), (1, false, false));
    assert_eq!(run(&mut rt, false, false, false, false), (1, false, false));
    assert_eq!(run(&mut rt, true, false, false, false), (2, true, false));
    // Both edges on one scan: no change.
    assert_eq!(run(&mut rt, false, false, false, false), (2, true, false));
    assert_eq!(run(&mut rt, true, true, false, false), (2, true, false));
    assert_eq!(run(&mut rt, false, false, false, false), (2, true, false));
    assert_eq!(run(&mut rt, false, true, false, false), (1, false, false));
    assert_eq!(run(&mut rt, false, false, true, false), (0, false, true));
    assert_eq!(run(&mut rt, false, false, false, true), (2, true, false));
}

#[test]
fn edge_detectors() {
    let src = "PROGRAM P VAR clk : BOOL; r : R_TRIG; f : F_TRIG; END_VAR r(CLK := clk); f(CLK := clk); END_PROGRAM";
    let mut rt = plc(src);
    let clk = [false, true, true, false, true, false, false];
    let mut rq = Vec::new();
    let mut fq = Vec::new();
    for c in clk {
        set(&mut rt, "clk", Value::Bool(c));
        rt.scan(ms(0)).unwrap();
        rq.push(boolean(&rt, "r.Q"));
        fq.push(boolean(&rt, "f.Q"));
    }
    assert_eq!(rq, [false, true, false, false, true, false, false]);
    // F_TRIG gives no edge for a FALSE input on its first call.
    assert_eq!(fq, [false, false, false, true, false, true, false]);
}

#[test]
fn r_trig_fires_on_a_true_first_input() {
    let rt = eval("r : R_TRIG; q : BOOL;", "r(CLK := TRUE); q := r.Q;");
    assert!(boolean(&rt, "q"));
}

#[test]
fn bistables_sr_set_dominant_rs_reset_dominant() {
    let src = "PROGRAM P VAR s : BOOL; r : BOOL; sr : SR; rs : RS; END_VAR sr(S1 := s, R := r); rs(S := s, R1 := r); END_PROGRAM";
    let mut rt = plc(src);
    let step = |rt: &mut rtcnc_plc::Runtime, s, r| {
        set(rt, "s", Value::Bool(s));
        set(rt, "r", Value::Bool(r));
        rt.scan(ms(0)).unwrap();
        (boolean(rt, "sr.Q1"), boolean(rt, "rs.Q1"))
    };
    assert_eq!(step(&mut rt, true, true), (true, false));
    assert_eq!(step(&mut rt, false, false), (true, false));
    assert_eq!(step(&mut rt, true, false), (true, true));
    assert_eq!(step(&mut rt, false, false), (true, true));
    assert_eq!(step(&mut rt, false, true), (false, false));
}

#[test]
fn timers_in_arrays_keep_independent_state() {
    let src = "PROGRAM P VAR t : ARRAY[1..3] OF TON; i : INT; go : ARRAY[1..3] OF BOOL; END_VAR
        FOR i := 1 TO 3 DO t[i](IN := go[i], PT := T#8ms); END_FOR; END_PROGRAM";
    let mut rt = plc(src);
    set(&mut rt, "go[2]", Value::Bool(true));
    for k in 0..3 {
        rt.scan(ms(4 * k)).unwrap();
    }
    assert!(boolean(&rt, "t[2].Q"));
    assert!(!boolean(&rt, "t[1].Q"));
    assert_eq!(time_ms(&rt, "t[2].ET"), 8.0);
}
