//! The generated ladder program of the benchmark compiles and behaves like a ladder.

use crate::generated;
use std::sync::Arc;
use std::time::Duration;

use rtcnc_plc::{Runtime, Value, compile};

#[test]
fn generated_ladder_compiles_and_seals_in() {
    // The full 2000 rungs in release builds, fewer in debug builds to keep CI fast.
    let rungs = if cfg!(debug_assertions) { 400 } else { 2000 };
    let src = generated::ladder_program(rungs);
    let program = compile(&src, "ladder.st").unwrap_or_else(|e| panic!("{e}"));
    let mut rt = Runtime::new(Arc::new(program));
    // Rung 0: c0 := (in0 OR c0) AND NOT in3 AND NOT t0.Q. Pulse in0, keep in3 off.
    rt.input_image_mut()[0] = 0b0000_0001;
    rt.scan(Duration::ZERO).unwrap();
    assert_eq!(rt.read_name("c0").unwrap(), Value::Bool(true));
    rt.input_image_mut()[0] = 0;
    rt.scan(Duration::from_millis(4)).unwrap();
    // Sealed in by its own contact.
    assert_eq!(rt.read_name("c0").unwrap(), Value::Bool(true));
    // in3 breaks the seal.
    rt.input_image_mut()[0] = 0b0000_1000;
    rt.scan(Duration::from_millis(8)).unwrap();
    assert_eq!(rt.read_name("c0").unwrap(), Value::Bool(false));
}
