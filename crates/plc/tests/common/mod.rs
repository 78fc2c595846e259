#![allow(dead_code)]

use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{Runtime, Value, compile};

/// Compiles `src` (panicking with the compiler's message on error).
pub fn plc(src: &str) -> Runtime {
    match compile(src, "test.st") {
        Ok(p) => Runtime::new(Arc::new(p)),
        Err(e) => panic!("compile failed:\n{e}"),
    }
}

/// Wraps statements in a PROGRAM with the given declarations, runs one scan.
pub fn eval(decls: &str, body: &str) -> Runtime {
    let src = format!("PROGRAM P\nVAR\n{decls}\nEND_VAR\n{body}\nEND_PROGRAM\n");
    let mut rt = plc(&src);
    if let Err(f) = rt.scan(Duration::ZERO) {
        panic!("scan faulted: {f}");
    }
    rt
}

pub fn get(rt: &Runtime, name: &str) -> Value {
    rt.read_name(name).unwrap_or_else(|e| panic!("{name}: {e}"))
}

pub fn set(rt: &mut Runtime, name: &str, v: Value) {
    let r = rt.resolve(name).unwrap_or_else(|e| panic!("{name}: {e}"));
    rt.write(&r, &v).unwrap_or_else(|e| panic!("{name}: {e}"));
}

pub fn int(rt: &Runtime, name: &str) -> i64 {
    match get(rt, name) {
        Value::Int(v) => v,
        Value::UInt(v) => v as i64,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn uint(rt: &Runtime, name: &str) -> u64 {
    match get(rt, name) {
        Value::UInt(v) => v,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn real(rt: &Runtime, name: &str) -> f64 {
    match get(rt, name) {
        Value::Real(v) => v,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn boolean(rt: &Runtime, name: &str) -> bool {
    match get(rt, name) {
        Value::Bool(v) => v,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn time_ms(rt: &Runtime, name: &str) -> f64 {
    match get(rt, name) {
        Value::Time(ns) => ns as f64 / 1e6,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn string(rt: &Runtime, name: &str) -> String {
    match get(rt, name) {
        Value::String(s) => s,
        v => panic!("{name} is {v:?}"),
    }
}

pub fn ms(n: u64) -> Duration {
    Duration::from_millis(n)
}

/// The first compile error of `src`: (line, column, code).
pub fn compile_error(src: &str) -> (u32, u32, &'static str, String) {
    match compile(src, "bad.st") {
        Ok(_) => panic!("expected a compile error"),
        Err(e) => {
            let f = e.first().expect("one error").clone();
            (f.pos.line, f.pos.col, f.code(), f.message)
        }
    }
}

/// Compiles `src` and runs one scan at time 0.
pub fn plc_scanned(src: &str) -> Runtime {
    let mut rt = plc(src);
    if let Err(f) = rt.scan(Duration::ZERO) {
        panic!("scan faulted: {f}");
    }
    rt
}
